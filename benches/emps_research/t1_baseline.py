import numpy as np, time
from emps import *
est,val=runs()
p=base_params(95.11,203.5,20.39,-3.16)
for nsub in [1,2,5,10,20,50]:
    t0=time.time()
    qs=[sim(p,r,nsub=nsub)[0] for r in (est,val)]
    qc=[sim(p,r,nsub=nsub,closed=True) for r in (est,val)]
    print(nsub, 'open rmse mm', [round(rmse_open(q,r)*1e3,3) for q,r in zip(qs,(est,val))],
          'closed force %', [round(rel(r.force,c[1]),3) for c,r in zip(qc,(est,val))],
          'closed pos %', [round(rel(r.qm,c[0]),4) for c,r in zip(qc,(est,val))], round(time.time()-t0,3))

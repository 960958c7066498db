"""Look at the two EMPS runs: position, velocity, command."""
import numpy as np, scipy.io as sio
from matplotlib.figure import Figure
D='/work/shared/data/emps/'
fig=Figure(figsize=(14,10)); axs=fig.subplots(4,2)
for j,f in enumerate(['DATA_EMPS.mat','DATA_EMPS_PULSES.mat']):
    d=sio.loadmat(D+f); t=d['t'].ravel(); qm=d['qm'].ravel(); vir=d['vir'].ravel(); qg=d['qg'].ravel()
    v=np.gradient(qm,t)
    axs[0,j].plot(t,qm*1e3); axs[0,j].set_ylabel('qm (mm)')
    axs[1,j].plot(t,v); axs[1,j].set_ylabel('v (m/s)')
    axs[2,j].plot(t,vir*d['gtau'].item()); axs[2,j].set_ylabel('force (N)')
    axs[3,j].plot(t,(qg-qm)*1e6); axs[3,j].set_ylabel('qg-qm (um)')
    for a in axs[:,j]: a.set_xlabel('t (s)')
    axs[0,j].set_title(f)
fig.tight_layout(); fig.savefig('data.png',dpi=70)

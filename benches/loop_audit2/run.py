#!/usr/bin/env python
"""Second outside audit of `gmsfric loop`: generate the cases, run the tool as a black box, score.

    python run.py --out /tmp/audit2_main --jobs 2 [--seed 1] [--gmsfric "gmsfric"]
                  [--only ID ...] [--resume] [--rescore]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import statistics
import subprocess
import sys
import time
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

CATALOGUE = ["asymmetric_friction", "stribeck", "presliding_hysteresis", "position_dependent_friction",
             "position_dependent_force", "input_delay", "friction_drift", "heating", "compliance", "offset"]
OUTSIDE = ["drag", "drag", "drag", "ripple", "ripple", "ripple", "backlash", "backlash",
           "load_friction", "load_friction"]
SINGLE_EXTRA = ["stribeck", "presliding_hysteresis", "compliance", "position_dependent_force", "friction_drift"]


# ----------------------------------------------------------------------------------------------
# case list
# ----------------------------------------------------------------------------------------------
def build_cases(seed):
    rng = np.random.default_rng(seed * 7919 + 17)
    cases = []

    def add(cat, effects=(), outside=None, strength=None, baseline="reference", **kw):
        i = len(cases)
        name = "+".join(effects) if effects else (outside or "clean")
        cases.append(dict(id=f"{cat[0]}{i:03d}_{name}", category=cat, effects=list(effects), outside=outside,
                          strength=strength or {}, baseline=baseline, case_seed=int(seed * 100003 + i * 101),
                          **kw))

    # clean: 30, 5 of them with the rigid baseline
    for j in range(30):
        add("clean", baseline="rigid" if j % 6 == 5 else "reference")
    # singles: 5 per effect + 1 extra for five of them = 55, strengths graded weak -> strong
    for e in CATALOGUE:
        n = 5 + (1 if e in SINGLE_EXTRA else 0)
        for j in range(n):
            s = j / (n - 1)
            kw = {}
            if e == "position_dependent_force" and j % 3 == 2:
                kw["pg_kind"] = "gravity"
            add("single", [e], strength={e: s}, baseline="rigid" if e == "offset" else "reference", **kw)
    # pairs: 15 (one with the offset, rigid baseline)
    pool = [e for e in CATALOGUE if e != "offset"]
    pairs = set()
    while len(pairs) < 14:
        a, b = sorted(rng.choice(len(pool), 2, replace=False))
        pairs.add((pool[a], pool[b]))
    for a, b in sorted(pairs):
        add("pair", [a, b], strength={a: float(rng.uniform(0.35, 1.0)), b: float(rng.uniform(0.35, 1.0))})
    o = pool[int(rng.integers(0, len(pool)))]
    if o == "position_dependent_force":
        o = "stribeck"
    add("pair", sorted(["offset", o]), strength={"offset": 0.7, o: 0.8}, baseline="rigid")
    # outside the catalogue: 10
    for j, k in enumerate(OUTSIDE):
        add("outside", outside=k, strength={k: (j % 3) / 2 * 0.7 + 0.3})
    # robot-joint-like jittered logs on ~10 % of the cases (not on the rigid-baseline ones)
    cand = [c for c in cases if c["baseline"] == "reference" and c["category"] != "outside"]
    for c in rng.choice(len(cand), 11, replace=False):
        cand[int(c)]["jitter"] = True
    return cases


# ----------------------------------------------------------------------------------------------
# generation
# ----------------------------------------------------------------------------------------------
def _units(rng, rig, jitter):
    rot = rig["rotary"]
    tu = str(rng.choice(["s", "s", "s", "ms"]))
    if rot:
        pu = str(rng.choice(["rad", "rad", "deg"]))
        fu = str(rng.choice(["N m", "N m", "mN m"]))
    else:
        pu = str(rng.choice(["m", "m", "mm", "um"]))
        fu = str(rng.choice(["N", "N", "kN", "mN"]))
    cmd = bool(rng.random() < 0.25)
    gain = _lu(rng, 0.05, 200.0) * (rig["Fc"] / 10.0) if cmd else None
    return dict(time=tu, position=pu, force=fu, command=cmd, gain=gain)


def _lu(rng, a, b):
    return float(math.exp(rng.uniform(math.log(a), math.log(b))))


TSCALE = {"s": 1.0, "ms": 1e3}
PSCALE = {"m": 1.0, "mm": 1e3, "um": 1e6, "rad": 1.0, "deg": 180.0 / math.pi}
FSCALE = {"N": 1.0, "kN": 1e-3, "mN": 1e3, "N m": 1.0, "mN m": 1e3}


def write_csv(path, log, units, names, ref=None):
    t = log["t"] * TSCALE[units["time"]]
    q = log["q"] * PSCALE[units["position"]]
    if units["command"]:
        f = log["f"] / units["gain"]
    else:
        f = log["f"] * FSCALE[units["force"]]
    cols = [t, q, f]
    hdr = [names["time"], names["position"], names["force"]]
    if ref is not None:
        cols.append(ref * PSCALE[units["position"]])
        hdr.append("ref")
    with open(path, "w") as fh:
        fh.write(",".join(hdr) + "\n")
        np.savetxt(fh, np.column_stack(cols), delimiter=",", fmt="%.12g")


def generate(case, outdir):
    import rigs
    import truth

    d = os.path.join(outdir, case["id"])
    os.makedirs(d, exist_ok=True)
    t0 = time.time()
    attempts = []
    for attempt in range(6):
        seed = case["case_seed"] + 7 * attempt
        rng = np.random.default_rng(seed)
        spec = dict(effects=case["effects"], outside=case["outside"], strength=case["strength"],
                    jitter=case.get("jitter", False), pg_kind=case.get("pg_kind"))
        rig = rigs.draw_rig(rng, spec)
        k_est = str(rng.choice(rigs.TRAJ_KINDS))
        k_val = str(rng.choice([k for k in rigs.TRAJ_KINDS if k != k_est])) if rng.random() < 0.65 else k_est
        d_est, d_val = float(rng.uniform(6, 20)), float(rng.uniform(6, 20))
        s_est, s_val = seed + 1, seed + 2
        if rig["ctrl"]["saturation"]:
            # drive limit below the peak the unsaturated loop commands on the estimation run
            rig["P"]["umax"] = 0.0
            peak = float(np.max(np.abs(rigs.simulate(rig, k_est, d_est, s_est)["u"])))
            rig["P"]["umax"] = peak * float(rng.uniform(0.75, 0.95))
            rig["ctrl"]["umax"] = rig["P"]["umax"]
        sims, infos, ok = {}, {}, True
        for run, kind, dur, s in (("est", k_est, d_est, s_est), ("val", k_val, d_val, s_val)):
            sim = rigs.simulate(rig, kind, dur, s)
            good, info = rigs.sanity(rig, sim)
            sims[run] = sim
            infos[run] = info
            ok &= good
        attempts.append(dict(seed=seed, ok=bool(ok), est=infos["est"], val=infos["val"]))
        if ok:
            break
    logs = {run: rigs.log_run(rig, sims[run], s) for run, s in (("est", s_est), ("val", s_val))}
    urng = np.random.default_rng(case["case_seed"] + 99)
    units = _units(urng, rig, rig["jitter"])
    rot = rig["rotary"]
    names = dict(time=str(urng.choice(["t", "time", "timestamp"])),
                 position=str(urng.choice(["q", "pos", "enc"] if rot else ["x", "pos", "enc"])),
                 force=("cmd" if units["command"] else str(urng.choice(["tau", "torque"] if rot else ["F", "force"]))))
    with_ref = bool(urng.random() < 0.5)
    for run in ("est", "val"):
        sim = sims[run]
        ref = np.interp(logs[run]["t"], sim["t"], sim["r"]) if with_ref else None
        write_csv(os.path.join(d, f"{run}.csv"), logs[run], units, names, ref)
    det = truth.detectability(logs["est"], logs["val"], rig, case["baseline"])
    info = dict(case=case, rig=_jsonable(rig), units=units, columns=names,
                runs=dict(est=dict(kind=k_est, duration=d_est, seed=s_est, rows=len(logs["est"]["t"])),
                          val=dict(kind=k_val, duration=d_val, seed=s_val, rows=len(logs["val"]["t"]))),
                attempts=attempts, sane=bool(attempts[-1]["ok"]), truth=det, gen_seconds=time.time() - t0)
    with open(os.path.join(d, "truth.json"), "w") as fh:
        json.dump(info, fh, indent=1)
    return info


def _jsonable(o):
    if isinstance(o, dict):
        return {k: _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    return o


# ----------------------------------------------------------------------------------------------
# running the tool
# ----------------------------------------------------------------------------------------------
def cli_args(info, d, gm):
    u = info["units"]
    c = info["columns"]
    a = shlex.split(gm) + ["loop", os.path.join(d, "est.csv"), "--validate", os.path.join(d, "val.csv"),
                           "--time", c["time"], "--position", c["position"]]
    if u["command"]:
        a += ["--command", c["force"], "--gain", repr(u["gain"])]
    else:
        a += ["--force", c["force"], "--force-unit", u["force"]]
    a += ["--time-unit", u["time"], "--position-unit", u["position"]]
    if info["case"]["baseline"] == "rigid":
        a += ["--baseline", "rigid"]
    a += ["--json", os.path.join(d, "tool.json"), "--quiet"]
    return a


def run_case(case, outdir, gm, resume):
    d = os.path.join(outdir, case["id"])
    rpath = os.path.join(d, "result.json")
    if resume and os.path.exists(rpath):
        return case["id"], "skipped"
    info = generate(case, outdir)
    args = cli_args(info, d, gm)
    tj = os.path.join(d, "tool.json")
    if os.path.exists(tj):
        os.remove(tj)
    t0 = time.time()
    try:
        p = subprocess.run(args, capture_output=True, text=True, timeout=900)
        rc, err = p.returncode, p.stderr
    except subprocess.TimeoutExpired:
        rc, err = -9, "timeout after 900 s"
    secs = time.time() - t0
    res = dict(id=case["id"], rc=rc, seconds=secs, cmd=shlex.join(args), gen_seconds=info["gen_seconds"])
    lines = [ln for ln in (err or "").strip().splitlines() if ln.strip()]
    res["stderr_last"] = lines[-1] if lines else ""
    if rc == 0 and os.path.exists(tj):
        try:
            with open(tj) as fh:
                J = json.load(fh)
            res["effects"] = list(J["final"]["effects"])
            res["steps"] = [dict(round=s.get("round"), effect=s.get("effect"), accepted=s.get("accepted"),
                                 reason=s.get("reason")) for s in J.get("steps", [])]
            res["val_err_pct"] = [J.get("baseline", {}).get("validation_error_pct") if isinstance(J.get("baseline"), dict) else None,
                                  J["final"].get("validation_error_pct")]
        except Exception as ex:  # noqa: BLE001
            res["rc"] = -1
            res["stderr_last"] = f"unreadable JSON: {ex}"
    elif rc == 0:
        res["rc"] = -2
        res["stderr_last"] = "no JSON written"
    with open(rpath, "w") as fh:
        json.dump(res, fh, indent=1)
    return case["id"], f"rc={res['rc']} {secs:.1f}s effects={res.get('effects')}"


# ----------------------------------------------------------------------------------------------
# scoring
# ----------------------------------------------------------------------------------------------
def _reason(res, eff):
    st = [s for s in res.get("steps", []) if s.get("effect") == eff]
    if not st:
        return "(never tried)"
    acc = [s for s in st if s.get("accepted")]
    s = acc[-1] if acc else st[-1]
    return f"r{s.get('round')}: {s.get('reason')}"


def score(outdir, cases, wall):
    rows = []
    for c in cases:
        d = os.path.join(outdir, c["id"])
        try:
            with open(os.path.join(d, "truth.json")) as fh:
                T = json.load(fh)
            with open(os.path.join(d, "result.json")) as fh:
                R = json.load(fh)
        except FileNotFoundError:
            continue
        rows.append((c, T, R))
    L = []
    P = L.append
    n = len(rows)
    P(f"gmsfric loop -- second outside audit: {n} cases in {outdir}")
    fails = [(c, R) for c, T, R in rows if R["rc"] != 0]
    ok = [(c, T, R) for c, T, R in rows if R["rc"] == 0]
    P(f"failures (non-zero exit): {len(fails)}")
    for c, R in fails:
        P(f"  FAIL {c['id']}: rc={R['rc']} {R['stderr_last'][:200]}")
    insane = [c["id"] for c, T, R in rows if not T.get("sane", True)]
    if insane:
        P(f"cases whose simulation stayed outside the sanity bounds after 6 draws: {insane}")
    # ---- recall per effect
    P("")
    P("recall per catalogue effect (singles + pairs that plant it); det = detectable in principle on all rows")
    P(f"  {'effect':30s} {'n':>3s} {'found':>6s} | {'det':>4s} {'found':>6s} | {'undet':>5s} {'found':>6s} | {'det(moving)':>11s} {'found':>6s}")
    tot = Counter()
    for e in CATALOGUE:
        cs = [(c, T, R) for c, T, R in rows if e in c["effects"]]
        okc = [(c, T, R) for c, T, R in cs if R["rc"] == 0]
        found = sum(e in R.get("effects", []) for c, T, R in okc)
        det = [(c, T, R) for c, T, R in okc if T["truth"]["effects"][e]["detectable"]]
        und = [(c, T, R) for c, T, R in okc if not T["truth"]["effects"][e]["detectable"]]
        dm = [(c, T, R) for c, T, R in okc if T["truth"]["effects"][e]["detectable_moving"]]
        fd = sum(e in R["effects"] for c, T, R in det)
        fu = sum(e in R["effects"] for c, T, R in und)
        fm = sum(e in R["effects"] for c, T, R in dm)
        tot.update(n=len(cs), found=found, det=len(det), fd=fd, und=len(und), fu=fu, dm=len(dm), fm=fm)
        fl = len(cs) - len(okc)
        P(f"  {e:30s} {len(cs):3d} {found:6d} | {len(det):4d} {fd:6d} | {len(und):5d} {fu:6d} | {len(dm):11d} {fm:6d}"
          + (f"   ({fl} FAIL)" if fl else ""))
    P(f"  {'all':30s} {tot['n']:3d} {tot['found']:6d} | {tot['det']:4d} {tot['fd']:6d} | {tot['und']:5d} {tot['fu']:6d} | {tot['dm']:11d} {tot['fm']:6d}")
    if tot["det"]:
        P(f"  recall on planted effects detectable on all rows: {tot['fd']}/{tot['det']} = {tot['fd'] / tot['det']:.0%}")
    if tot["dm"]:
        P(f"  recall on planted effects detectable on moving rows: {tot['fm']}/{tot['dm']} = {tot['fm'] / tot['dm']:.0%}")
    if tot["n"]:
        P(f"  recall on all planted effects: {tot['found']}/{tot['n']} = {tot['found'] / tot['n']:.0%}")
    # ---- false effects
    P("")
    falses = []
    per_eff = Counter()
    by_cat = defaultdict(lambda: [0, 0])
    for c, T, R in ok:
        acc = R.get("effects", [])
        fl = [e for e in acc if e not in c["effects"]]
        by_cat[c["category"]][1] += 1
        if fl:
            by_cat[c["category"]][0] += 1
            falses.append((c, fl))
        per_eff.update(fl)
    nf = len(falses)
    P(f"false effects (accepted, not planted; outside cases: all accepted): cases with >= 1 false = {nf}/{len(ok)}"
      f" = {nf / max(len(ok), 1):.1%}")
    P("  by category: " + ", ".join(f"{k} {v[0]}/{v[1]}" for k, v in sorted(by_cat.items())))
    P("  by effect:   " + (", ".join(f"{k} {v}" for k, v in per_eff.most_common()) or "none"))
    for c, fl in falses:
        P(f"    {c['id']}: {', '.join(fl)}")
    # ---- clean
    cl = [(c, T, R) for c, T, R in ok if c["category"] == "clean"]
    none = sum(not R.get("effects") for c, T, R in cl)
    P("")
    P(f"clean cases ending with nothing added: {none}/{len(cl)}"
      + f"   (rigid baseline: {sum(not R.get('effects') for c, T, R in cl if c['baseline'] == 'rigid')}/"
        f"{sum(c['baseline'] == 'rigid' for c, T, R in cl)})")
    # ---- pairs
    pr = [(c, T, R) for c, T, R in ok if c["category"] == "pair"]
    both_det = [(c, T, R) for c, T, R in pr if all(T["truth"]["effects"][e]["detectable"] for e in c["effects"])]
    both_found = sum(all(e in R["effects"] for e in c["effects"]) for c, T, R in both_det)
    P(f"pairs: {len(pr)}; both detectable: {len(both_det)}; of those both found: {both_found};"
      f" any pair with both found: {sum(all(e in R['effects'] for e in c['effects']) for c, T, R in pr)}")
    for c, T, R in pr:
        g = ", ".join(f"{e} {T['truth']['effects'][e]['gain_all']:+.2f}{'*' if T['truth']['effects'][e]['detectable'] else ''}"
                      for e in c["effects"])
        P(f"    {c['id']}: truth gains {g} -> accepted {R['effects']}")
    # ---- confusion
    P("")
    P("confusion matrix (cases in the row that accepted the column's effect; singles split by detectability)")
    short = {"asymmetric_friction": "asym", "stribeck": "strib", "presliding_hysteresis": "presl",
             "position_dependent_friction": "pfric", "position_dependent_force": "pforc", "input_delay": "delay",
             "friction_drift": "drift", "heating": "heat", "compliance": "compl", "offset": "offs"}
    cols = CATALOGUE + ["none", "FAIL"]
    P("  " + f"{'planted':34s} {'n':>3s} " + " ".join(f"{short.get(k, k):>5s}" for k in cols))
    groups = []
    for e in CATALOGUE:
        for dflag in (True, False):
            groups.append((f"{e} {'det' if dflag else 'undet'}",
                           lambda c, T, e=e, dflag=dflag: c["category"] == "single" and c["effects"] == [e]
                           and T["truth"]["effects"][e]["detectable"] == dflag))
    groups.append(("pair", lambda c, T: c["category"] == "pair"))
    groups.append(("clean", lambda c, T: c["category"] == "clean"))
    for k in sorted(set(OUTSIDE)):
        groups.append((f"outside: {k}", lambda c, T, k=k: c["category"] == "outside" and c["outside"] == k))
    for name, fn in groups:
        members = [(c, T, R) for c, T, R in rows if fn(c, T)]
        if not members:
            continue
        cnt = Counter()
        for c, T, R in members:
            if R["rc"] != 0:
                cnt["FAIL"] += 1
            elif not R.get("effects"):
                cnt["none"] += 1
            else:
                cnt.update(R["effects"])
        P("  " + f"{name:34s} {len(members):3d} " + " ".join(f"{(cnt[k] if cnt[k] else '.'):>5}" for k in cols))
    # ---- misses and false effects with the tool's reason
    P("")
    P("misses (planted, not accepted) and false effects, with the reason of the tool's step for that effect:")
    for c, T, R in ok:
        for e in c["effects"]:
            if e not in R["effects"]:
                t = T["truth"]["effects"][e]
                P(f"  MISS  {c['id']:42s} {e:28s} truth gain all {t['gain_all']:+.3f} moving {t['gain_moving']:+.3f}"
                  f" {'DET' if t['detectable'] else 'undet'} | {_reason(R, e)[:300]}")
        for e in R["effects"]:
            if e not in c["effects"]:
                P(f"  FALSE {c['id']:42s} {e:28s} | {_reason(R, e)[:300]}")
    # ---- timing
    secs = [R["seconds"] for c, T, R in rows if "seconds" in R]
    gens = [R.get("gen_seconds", 0.0) for c, T, R in rows]
    P("")
    if wall is not None:
        P(f"wall time: {wall:.0f} s")
    if secs:
        P(f"CLI seconds: median {statistics.median(secs):.1f}, max {max(secs):.1f}, total {sum(secs):.0f};"
          f" generation+truth median {statistics.median(gens):.1f} s")
    # per-case table
    with open(os.path.join(outdir, "cases.tsv"), "w") as fh:
        fh.write("case\tcategory\tbaseline\tplanted\toutside\tgain_all\tgain_moving\tdetectable\taccepted\trc\tseconds"
                 "\trotary\tcontact\tcontroller\tlog_hz\tjitter\n")
        for c, T, R in rows:
            te = T["truth"]["effects"]
            fh.write("\t".join([
                c["id"], c["category"], c["baseline"], ",".join(c["effects"]), c["outside"] or "",
                ",".join(f"{te[e]['gain_all']:.3f}" for e in te), ",".join(f"{te[e]['gain_moving']:.3f}" for e in te),
                ",".join(str(int(te[e]["detectable"])) for e in te), ",".join(R.get("effects", [])), str(R["rc"]),
                f"{R.get('seconds', 0):.1f}", str(T["rig"]["rotary"]), T["rig"]["contact"], T["rig"]["ctrl"]["kind"],
                f"{T['rig']['log']['rate']:.0f}", str(T["rig"]["jitter"])]) + "\n")
    txt = "\n".join(L)
    with open(os.path.join(outdir, "summary.txt"), "w") as fh:
        fh.write(txt + "\n")
    print(txt)
    return txt


# ----------------------------------------------------------------------------------------------
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--gmsfric", default="gmsfric", help="command that runs the tool (default: gmsfric)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--only", nargs="+", default=None, help="case ids (or prefixes)")
    ap.add_argument("--resume", action="store_true", help="skip cases that already have a result")
    ap.add_argument("--rescore", action="store_true", help="only re-read the results and score")
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    cases = build_cases(a.seed)
    if a.only:
        cases = [c for c in cases if any(c["id"] == o or c["id"].startswith(o) for o in a.only)]
    wall = None
    meta_path = os.path.join(a.out, "run_meta.json")
    if not a.rescore:
        # warm the numba cache once before the workers start
        import rigs  # noqa: F401
        import truth  # noqa: F401
        rig = rigs.draw_rig(np.random.default_rng(0), dict(effects=["presliding_hysteresis"]))
        rigs.simulate(rig, "ptp", 1.0, 0)
        truth.maxwell_slip(np.zeros(3), np.ones(1), np.ones(1))
        t0 = time.time()
        if a.jobs > 1:
            with ProcessPoolExecutor(a.jobs) as ex:
                futs = [ex.submit(run_case, c, a.out, a.gmsfric, a.resume) for c in cases]
                for f in futs:
                    cid, msg = f.result()
                    print(f"{cid}: {msg}", flush=True)
        else:
            for c in cases:
                cid, msg = run_case(c, a.out, a.gmsfric, a.resume)
                print(f"{cid}: {msg}", flush=True)
        wall = time.time() - t0
        meta = []
        if os.path.exists(meta_path):
            with open(meta_path) as fh:
                meta = json.load(fh)
            if isinstance(meta, dict):
                meta = [meta]
        meta.append(dict(wall=wall, n=len(cases), full=not (a.only or a.resume), gmsfric=a.gmsfric, seed=a.seed,
                         jobs=a.jobs, argv=sys.argv, when=time.strftime("%Y-%m-%d %H:%M:%S")))
        with open(meta_path, "w") as fh:
            json.dump(meta, fh, indent=1)
    elif os.path.exists(meta_path):
        with open(meta_path) as fh:
            meta = json.load(fh)
        meta = [meta] if isinstance(meta, dict) else meta
        full = [m for m in meta if m.get("full", True)]
        wall = (full or meta)[-1].get("wall") if meta else None
    print()
    score(a.out, cases, wall)


if __name__ == "__main__":
    main()

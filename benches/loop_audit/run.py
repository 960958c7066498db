"""Audit `gmsfric loop` on closed-loop recordings simulated by rigs.py (independent of the
project's own generators).

    .venv/bin/python benches/loop_audit/run.py --seed 20261127 --out /tmp/loop_audit

generates the cases (estimation + validation CSV and the planted truth per case), runs the CLI
on each (one at a time), and writes results.jsonl and summary.txt into --out.  Re-running with
the same --out skips cases that already have a JSON (use --fresh to redo).  Every planted effect
is also scored against its true held-out gain (truth.py, cached in the case's detect.json): recall
at the strengths where it is detectable.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import rigs  # noqa: E402
from truth import DETECTABLE, cached_gains  # noqa: E402

EFFECTS = ["asymmetric_friction", "stribeck", "presliding_hysteresis",
           "position_dependent_friction", "position_dependent_force", "input_delay",
           "friction_drift", "compliance", "heating"]
N_SINGLE = {e: 6 for e in EFFECTS}
N_SINGLE["friction_drift"] = 5
N_SINGLE["heating"] = 5
N_CLEAN = 27
N_PAIR = 14
CLI = [str(Path(sys.executable).parent / "gmsfric")]  # the command that runs gmsfric (--gmsfric)


# ----------------------------------------------------------------------------- case design

def base_rig(rng, rotary):
    fs_log = float(rng.choice([500, 1000, 1250, 2500]))
    ctrl = str(rng.choice(["pid", "cascade"]))
    fb = float(rng.uniform(8, 25))
    ff = bool(rng.random() < 0.5)
    if not rotary:
        M = float(math.exp(rng.uniform(math.log(1), math.log(100))))
        Fc = float(rng.uniform(5, 50))
        vmax = float(rng.uniform(0.15, 0.5))
        travel = float(rng.uniform(0.3, 1.0))
        enc = float(rng.choice([0.1e-6, 0.5e-6, 1e-6]))
    else:
        M = float(math.exp(rng.uniform(math.log(0.001), math.log(0.1))))
        Fc = float(rng.uniform(0.05, 1.0))
        vmax = float(rng.uniform(5, 30))
        travel = float(rng.uniform(6, 30))
        enc = float(2 * math.pi / 2 ** int(rng.integers(16, 21)))
    Fv = float(rng.uniform(0.3, 1.5) * Fc / vmax)
    return rigs.Rig(rotary=rotary, M=M, Fc=Fc, Fv=Fv, offset=float(rng.uniform(-0.1, 0.1) * Fc),
                    enc=enc, noise=float(rng.uniform(0.005, 0.02) * Fc), vmax=vmax,
                    travel=travel, fs_log=fs_log, ctrl=ctrl, fb=fb, ff=ff, drive_limit=0.0)


def plant(rig: rigs.Rig, eff: str, rng, T):
    """Plant one effect; returns a dict describing its strength."""
    Fc = rig.Fc
    if eff == "asymmetric_friction":
        rig.asym = float(rng.uniform(0.3, 0.6))
        rig.Fv = max(rig.Fv, 0.4 * Fc / (rig.asym * rig.vmax))
        return dict(asym=rig.asym, dFv_at_half_vmax_over_Fc=rig.asym * rig.Fv * 0.5 * rig.vmax / Fc)
    if eff == "stribeck":
        rig.fs_ratio = float(rng.uniform(0.4, 0.8))
        rig.vs = float(rng.uniform(0.04, 0.12) * rig.vmax)
        return dict(Fs_over_Fc=1 + rig.fs_ratio, vs=rig.vs, vs_over_vmax=rig.vs / rig.vmax)
    if eff == "presliding_hysteresis":
        n = int(rng.integers(2, 4))
        if rig.rotary:
            lo, hi = max(5 * rig.enc, 1e-4), 1e-3
        else:
            lo, hi = max(5 * rig.enc, 5e-6), 50e-6
        d = np.sort(np.exp(rng.uniform(math.log(lo), math.log(hi), n)))
        share = float(rng.uniform(0.4, 0.7))
        w = rng.dirichlet(np.ones(n)) * share * Fc
        rig.ms_delta = [float(x) for x in d]
        rig.ms_force = [float(x) for x in w]
        return dict(delta=rig.ms_delta, delta_in_enc_steps=[x / rig.enc for x in d],
                    force_share_of_Fc=share)
    if eff == "position_dependent_friction":
        rig.pdf_amp = float(rng.uniform(0.3, 0.5))
        if rng.random() < 0.6:
            rig.pdf_kind = 1
            rig.pdf_period = float(rig.travel / rng.uniform(1.0, 3.0))
            rig.pdf_phase = float(rng.uniform(0, 2 * np.pi))
        else:
            rig.pdf_kind = 2
        return dict(kind=["", "sine", "ramp"][rig.pdf_kind], amp=rig.pdf_amp,
                    period=rig.pdf_period if rig.pdf_kind == 1 else None)
    if eff == "position_dependent_force":
        if rig.rotary and rng.random() < 0.6:
            rig.pf_kind = 3
            rig.pf_amp = float(rng.uniform(0.5, 1.0) * Fc)
            rig.pf_phase = float(rng.uniform(0, 2 * np.pi))
        elif rng.random() < 0.6:
            rig.pf_kind = 1
            rig.pf_amp = float(rng.uniform(0.3, 0.6) * Fc)
            rig.pf_period = float(2 * np.pi / rng.integers(4, 13)) if rig.rotary else \
                float(rig.travel * rng.uniform(0.03, 0.15))
            rig.pf_phase = float(rng.uniform(0, 2 * np.pi))
        else:
            rig.pf_kind = 2
            rig.pf_amp = float(rng.uniform(0.4, 0.8) * Fc)
        return dict(kind=["", "cogging", "spring", "gravity"][rig.pf_kind],
                    amp_over_Fc=rig.pf_amp / Fc, period=rig.pf_period if rig.pf_kind == 1 else None)
    if eff == "input_delay":
        if rig.fs_log < 1000:
            rig.fs_log = float(rng.choice([1000, 1250, 2500]))
        n = int(rng.integers(2, 9))
        rig.delay = n / rig.fs_log
        rig.fb = min(rig.fb, 0.06 / rig.delay)
        return dict(samples=n, delay_ms=rig.delay * 1e3)
    if eff == "friction_drift":
        rig.drift_amp = float(rng.choice([-1, 1]) * rng.uniform(0.3, 0.5))
        rig.drift_kind = int(rng.integers(1, 3))
        rig.drift_tau = float(rng.uniform(0.2, 0.5) * T)
        return dict(amp=rig.drift_amp, kind=["", "linear", "exp"][rig.drift_kind],
                    tau=rig.drift_tau if rig.drift_kind == 2 else None)
    if eff == "compliance":
        rig.comp_ratio = float(rng.uniform(0.1, 0.5))
        rig.comp_fn = float(rng.uniform(5, 30))
        rig.comp_zeta = float(rng.uniform(0.03, 0.1))
        return dict(load_over_motor=rig.comp_ratio, fn=rig.comp_fn, zeta=rig.comp_zeta)
    if eff == "heating":
        rig.heat_amp = float(rng.uniform(0.3, 0.5))
        rig.heat_tau = float(rng.uniform(1.5, 4.0))
        return dict(amp=rig.heat_amp, tau=rig.heat_tau,
                    note="friction x (1 - amp * LP(|v|)/(0.5 vmax))")
    raise ValueError(eff)


def strip(rig: rigs.Rig, eff: str) -> rigs.Rig:
    """The same rig without one planted effect (for the visibility measure)."""
    r = rigs.Rig(**rig.to_dict())
    if eff == "asymmetric_friction":
        r.asym = 0.0
    elif eff == "stribeck":
        r.fs_ratio = 0.0
    elif eff == "presliding_hysteresis":
        r.ms_delta, r.ms_force = [], []          # the break forces go back into the tanh Coulomb
    elif eff == "position_dependent_friction":
        r.pdf_kind, r.pdf_amp = 0, 0.0
    elif eff == "position_dependent_force":
        r.pf_kind, r.pf_amp = 0, 0.0
    elif eff == "input_delay":
        r.delay = 0.0
    elif eff == "friction_drift":
        r.drift_kind, r.drift_amp = 0, 0.0
    elif eff == "compliance":
        r.comp_ratio = 0.0                       # same total mass, rigid
    elif eff == "heating":
        r.heat_amp = 0.0
    return r


def design(seed):
    rng = np.random.default_rng(seed)
    plan = [[]] * N_CLEAN
    for e in EFFECTS:
        plan += [[e]] * N_SINGLE[e]
    k = 0
    while k < N_PAIR:
        a, b = rng.choice(len(EFFECTS), 2, replace=False)
        pair = sorted([EFFECTS[a], EFFECTS[b]])
        if pair == ["friction_drift", "heating"]:
            continue
        plan.append(pair)
        k += 1
    order = rng.permutation(len(plan))
    cases = []
    for i, j in enumerate(order):
        cases.append(dict(id=f"c{i:03d}", planted=plan[j], seed=int(rng.integers(1 << 31))))
    return cases


def build_case(case, outdir: Path):
    rng = np.random.default_rng(case["seed"])
    rotary = bool(rng.random() < 0.4)
    T = float(rng.uniform(8, 12))
    for attempt in range(6):
        rig = base_rig(rng, rotary)
        strengths = {e: plant(rig, e, rng, T) for e in case["planted"]}
        if rig.comp_ratio > 0:
            rig.fb = min(rig.fb, rig.comp_fn / 1.5)
        est_kind = "random" if rng.random() < 0.6 else "sweep"
        val_kind = "trapezoid" if rng.random() < 0.7 else "random"
        tr_e = rigs.make_traj(est_kind, rng, rig, T)
        tr_v = rigs.make_traj(val_kind, rng, rig, T)
        limited = rng.random() < 0.25
        se, sv = int(rng.integers(1 << 31)), int(rng.integers(1 << 31))
        if limited:
            d0 = rigs.simulate(rig, tr_e, T, se)
            rig.drive_limit = float(0.85 * np.percentile(np.abs(d0["u"]), 99.5))
        de = rigs.simulate(rig, tr_e, T, se)
        dv = rigs.simulate(rig, tr_v, T, sv)
        ok = True
        for d in (de, dv):
            err = np.sqrt(np.mean((d["ref"][:d["q"].size] - d["q"]) ** 2))
            if not np.all(np.isfinite(d["q"])) or err > 0.05 * rig.travel or \
                    d["t"].size < 0.99 * T * rig.fs_log:
                ok = False
        if ok:
            break
    # visibility: the same estimation run (same reference, seeds) without the effect; how much
    # the logged controller output changes, relative to Fc and to the force's own rms
    for e in case["planted"]:
        d0 = rigs.simulate(strip(rig, e), tr_e, T, se)
        m = min(d0["u"].size, de["u"].size)
        du = de["u"][:m] - d0["u"][:m]
        strengths[e]["vis_rms_over_Fc"] = float(np.sqrt(np.mean(du ** 2)) / rig.Fc)
        strengths[e]["vis_rms_over_frms"] = float(np.sqrt(np.mean(du ** 2) / np.mean(de["u"][:m] ** 2)))
        own = rigs.own_force(rig, e, de)
        if own is not None:
            strengths[e]["own_rms_over_Fc"] = float(np.sqrt(np.mean(own ** 2)) / rig.Fc)
            strengths[e]["own_p95_over_Fc"] = float(np.percentile(np.abs(own), 95) / rig.Fc)
    # motion richness of the estimation run
    v_e = np.gradient(de["q_true"], de["t"])
    mv = np.abs(v_e) > 0.02 * rig.vmax
    reversals = int(np.sum(np.diff(np.sign(v_e[mv])) != 0))
    # units: ~20 % of the cases logged in other units
    if not rotary:
        units = ("s", "m", "N") if rng.random() < 0.8 else \
            [("s", "mm", "N"), ("ms", "m", "N"), ("s", "m", "kN")][int(rng.integers(3))]
    else:
        units = ("s", "rad", "N m") if rng.random() < 0.8 else ("s", "deg", "N m")
    sc_t = {"s": 1.0, "ms": 1e3}[units[0]]
    sc_q = {"m": 1.0, "mm": 1e3, "rad": 1.0, "deg": 180 / math.pi}[units[1]]
    sc_f = {"N": 1.0, "kN": 1e-3, "N m": 1.0}[units[2]]
    cdir = outdir / case["id"]
    cdir.mkdir(parents=True, exist_ok=True)
    for name, d in (("est", de), ("val", dv)):
        np.savetxt(cdir / f"{name}.csv", np.c_[d["t"] * sc_t, d["q"] * sc_q, d["f"] * sc_f],
                   delimiter=",", header="t,q,f", comments="", fmt="%.10g")
    limit_frac = float(np.mean(np.abs(de["u"]) >= rig.drive_limit * 0.999)) if rig.drive_limit else 0.0
    truth = dict(case, rig=rig.to_dict(), strengths=strengths, T=T, est_traj=est_kind,
                 val_traj=val_kind, units=units, attempts=attempt + 1,
                 est_track_err_rms=float(np.sqrt(np.mean((de["ref"][:de["q"].size] - de["q"]) ** 2))),
                 est_frac_at_limit=limit_frac, est_reversals=reversals,
                 est_speed_max=float(np.abs(np.gradient(de["q_true"], de["t"])).max()))
    (cdir / "truth.json").write_text(json.dumps(truth, indent=1))
    return truth


# ----------------------------------------------------------------------------- run + score

def run_cli(truth, cdir: Path):
    u = truth["units"]
    cmd = CLI + ["loop", str(cdir / "est.csv"), "--validate", str(cdir / "val.csv"),
           "--time", "t", "--position", "q", "--force", "f", "--time-unit", u[0],
           "--position-unit", u[1], "--force-unit", u[2], "--json", str(cdir / "out.json"),
           "--quiet"]
    t0 = time.time()
    p = subprocess.run(cmd, capture_output=True, text=True)
    el = time.time() - t0
    msg = ""
    if p.returncode != 0:
        lines = [x for x in (p.stderr or p.stdout).strip().splitlines() if x.strip()]
        msg = lines[-1] if lines else "(no message)"
    return dict(rc=p.returncode, seconds=el, message=msg, cmd=" ".join(
        f'"{c}"' if " " in c else c for c in cmd))


def effect_names(final):
    out = []
    for e in final.get("effects", []):
        out.append(e if isinstance(e, str) else (e.get("name") or e.get("effect")))
    return out


def step_reason(js, eff):
    steps = [s for s in js.get("steps", []) if s.get("effect") == eff]
    if not steps:
        return "(never tried)"
    acc = [s for s in steps if s.get("accepted")]
    s = acc[-1] if acc else steps[-1]
    r = (s.get("reason") or "").replace("\n", " ")
    return f"round {s.get('round')} {'accepted' if s.get('accepted') else 'refused'}: {r[:300]}"


def score(rows):
    L = []
    n = len(rows)
    ok = [r for r in rows if r["rc"] == 0]
    fails = [r for r in rows if r["rc"] != 0]
    L.append(f"cases: {n}  (CLI ran OK on {len(ok)}, failures {len(fails)})")
    L.append("")
    # the columns after "named falsely" count only the planted effects that are detectable
    # (truth.py: true held-out gain >= 10 %), on all moving rows and on the rows clear of
    # reversals and stops
    L.append(f"{'effect':30s} {'planted':>7s} {'found':>6s} {'recall':>7s} {'named falsely':>14s}"
             f" {'detectable':>11s} {'found@det':>10s} {'recall@det':>11s} {'det(clear)':>11s} {'found':>6s}")
    for e in EFFECTS:
        pl = [r for r in ok if e in r["planted"]]
        fo = [r for r in pl if e in r["named"]]
        fa = [r for r in ok if e in r["named"] and e not in r["planted"]]
        rec = f"{len(fo) / len(pl):.2f}" if pl else "-"
        de = [r for r in pl if detectable(r, e)]
        dfo = [r for r in de if e in r["named"]]
        drec = f"{len(dfo) / len(de):.2f}" if de else "-"
        dc = [r for r in pl if detectable(r, e, clear=True)]
        L.append(f"{e:30s} {len(pl):7d} {len(fo):6d} {rec:>7s} {len(fa):14d}"
                 f" {len(de):11d} {len(dfo):10d} {drec:>11s} {len(dc):11d} {sum(e in r['named'] for r in dc):6d}")
    other = {}
    for r in ok:
        for x in r["named"]:
            if x not in EFFECTS:
                other[x] = other.get(x, 0) + 1
    if other:
        L.append(f"other names (not planted, not in list): {other}")
    nf = sum(len([x for x in r["named"] if x not in r["planted"]]) for r in ok)
    L.append("")
    L.append(f"false effects: {nf} over {len(ok)} cases = {nf / max(len(ok), 1):.3f} per case")
    for grp, sel in (("clean", lambda r: not r["planted"]), ("single", lambda r: len(r["planted"]) == 1),
                     ("pair", lambda r: len(r["planted"]) == 2)):
        g = [r for r in ok if sel(r)]
        f = sum(len([x for x in r["named"] if x not in r["planted"]]) for r in g)
        L.append(f"  on {grp:6s} cases: {f} false over {len(g)} = {f / max(len(g), 1):.3f} per case")
    cl = [r for r in ok if not r["planted"]]
    L.append(f"clean cases with nothing added: {sum(1 for r in cl if not r['named'])} / {len(cl)}")
    pr = [r for r in ok if len(r["planted"]) == 2]
    L.append(f"pairs with both found: {sum(1 for r in pr if all(e in r['named'] for e in r['planted']))} / {len(pr)}"
             f"  (at least one: {sum(1 for r in pr if any(e in r['named'] for e in r['planted']))})")
    pd = [r for r in pr if all(detectable(r, e) for e in r["planted"])]
    L.append(f"pairs with both detectable: {len(pd)} / {len(pr)}, both found among them: "
             f"{sum(1 for r in pd if all(e in r['named'] for e in r['planted']))} / {len(pd)}")
    tot = sum(len(r["planted"]) for r in ok)
    L.append(f"overall recall: {sum(len([e for e in r['planted'] if e in r['named']]) for r in ok)} / {tot}")
    dt = [(r, e) for r in ok for e in r["planted"] if detectable(r, e)]
    L.append(f"overall recall at detectable: {sum(1 for r, e in dt if e in r['named'])} / {len(dt)}"
             f"  (planted effects without a true gain: {sum(1 for r in ok for e in r['planted'] if e not in r.get('gain', {}))})")
    L.append(f"exact (named set == planted set): {sum(1 for r in ok if set(r['named']) == set(r['planted']))} / {len(ok)}")
    L.append(f"CLI seconds: median {np.median([r['seconds'] for r in rows]):.1f}, max {max(r['seconds'] for r in rows):.1f}")
    L.append("")
    L.append(f"CLI failures ({len(fails)}):")
    for r in fails:
        L.append(f"  {r['id']} planted={r['planted']} rc={r['rc']}: {r['message']}")
    L.append("")
    L.append("missed / false, one line each (the JSON step's reason for that effect):")
    for r in ok:
        for e in r["planted"]:
            if e not in r["named"]:
                L.append(f"  {r['id']} MISSED {e} [{r['strength_brief'].get(e, '')}] named={r['named']}: {r['reasons'].get(e, '')}"
                         f" [true gain {_fmt(r.get('gain', {}).get(e))}, clear {_fmt(r.get('gain_clear', {}).get(e))}]")
        for e in r["named"]:
            if e not in r["planted"]:
                L.append(f"  {r['id']} FALSE  {e} (planted={r['planted']}): {r['reasons'].get(e, '')}")
    return "\n".join(L)


def detectable(row, eff, clear=False):
    """Whether the planted ``eff`` of ``row`` is detectable (truth.py); False when unknown."""
    g = row.get("gain_clear" if clear else "gain", {}).get(eff)
    return g is not None and g >= DETECTABLE


def attach_truth(row, cdir: Path, fresh=False):
    """Add the planted effects' true held-out gains (truth.py, cached in ``cdir/detect.json``) to
    ``row``: ``gain``, ``gain_clear`` and ``detectable``, each by effect."""
    try:
        g = cached_gains(cdir, fresh)["effects"]
    except Exception as ex:  # noqa: BLE001 -- the audit goes on; the row says why it has none
        row["truth_error"] = f"{type(ex).__name__}: {ex}"
        return row
    row.pop("truth_error", None)
    row["gain"] = {e: g[e]["gain"] for e in row["planted"]}
    row["gain_clear"] = {e: g[e].get("gain_clear") for e in row["planted"]}
    row["detectable"] = {e: g[e]["detectable"] for e in row["planted"]}
    return row


def brief(strengths):
    out = {}
    for e, s in strengths.items():
        out[e] = ", ".join(f"{k}={_fmt(v)}" for k, v in s.items() if k != "note")
    return out


def _fmt(v):
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, list):
        return "[" + ",".join(_fmt(x) for x in v) + "]"
    return str(v)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=20261127)
    ap.add_argument("--out", default="/tmp/loop_audit")
    ap.add_argument("--only", nargs="*", help="case ids")
    ap.add_argument("--fresh", action="store_true")
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--gmsfric", default=None, help="command running gmsfric (default: the one next to this python)")
    a = ap.parse_args()
    if a.gmsfric:
        CLI[:] = shlex.split(a.gmsfric)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cases = design(a.seed)
    if a.only:
        cases = [c for c in cases if c["id"] in a.only]
    if a.limit:
        cases = cases[:a.limit]
    rows = []
    t_all = time.time()
    for c in cases:
        cdir = out / c["id"]
        rj = cdir / "row.json"
        if rj.exists() and not a.fresh:
            row = json.loads(rj.read_text())
            if "gain" not in row or not (cdir / "detect.json").exists():
                rj.write_text(json.dumps(attach_truth(row, cdir), indent=1))
            rows.append(row)
            continue
        t0 = time.time()
        truth = build_case(c, out)
        ts = time.time() - t0
        res = run_cli(truth, cdir)
        named, reasons = [], {}
        if res["rc"] == 0:
            js = json.loads((cdir / "out.json").read_text())
            named = effect_names(js["final"])
            for e in set(named) | set(c["planted"]):
                reasons[e] = step_reason(js, e)
            fin = js["final"]
            res["val_err_pct"] = fin.get("validation_error_pct")
            res["base_val_err_pct"] = js.get("baseline", {}).get("validation_error_pct") \
                if isinstance(js.get("baseline"), dict) else None
        row = dict(id=c["id"], planted=c["planted"], named=named, reasons=reasons,
                   strength_brief=brief(truth["strengths"]), sim_seconds=ts,
                   rotary=truth["rig"]["rotary"], fs_log=truth["rig"]["fs_log"],
                   units=truth["units"], **res)
        attach_truth(row, cdir, fresh=True)
        rj.write_text(json.dumps(row, indent=1))
        rows.append(row)
        print(f"{c['id']} {'R' if row['rotary'] else 'L'} {row['fs_log']:.0f}Hz planted={c['planted']} "
              f"named={named} rc={res['rc']} sim {ts:.1f}s cli {res['seconds']:.1f}s "
              f"[{time.time() - t_all:.0f}s]", flush=True)
    with open(out / "results.jsonl", "w") as fh:
        for r in rows:
            fh.write(json.dumps(r) + "\n")
    s = score(rows)
    (out / "summary.txt").write_text(s + "\n")
    print(s)


if __name__ == "__main__":
    main()

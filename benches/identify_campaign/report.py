"""Tables of an identification campaign from its ``results.jsonl`` (see run.py)."""

from __future__ import annotations

import json
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any, Iterable

import numpy as np

import sims

PARAMS = {"static": ["fc", "fs", "vs", "sigma", "delta"], "plant": ["a", "b", "c", "delay"], "presliding": ["k", "w"]}
Z95 = 1.959963984540054
BLOCK_TOL = 0.03


def load(path: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]


def backfill(recs: list[dict[str, Any]], json_dir: Path) -> list[dict[str, Any]]:
    """Add the accepted plateaus from the CLI's JSON files to records written without them."""
    for r in recs:
        if r.get("family") == "static-raw" and r.get("estimate") and "plateaus" not in r.get("info", {}):
            p = Path(json_dir) / f"{r['case']}-{r['variant']}-{r['units']}.json"
            if p.exists():
                r["info"]["plateaus"] = [[q["velocity"], q["force"]] for q in json.loads(p.read_text()).get("plateaus", [])]
    return recs


def bad_plateaus(rec: dict[str, Any], tol: float = 0.05) -> int:
    """Accepted plateaus (SI runs) whose mean force is off the true map by more than ``tol``:
    transients (acceleration ramps, settling) taken for steady motion."""
    pl = rec.get("info", {}).get("plateaus")
    if not pl or rec.get("units") != "si":
        return 0
    v, F = np.array(pl, dtype=float).T
    Ft = sims.stribeck_force(v, **rec["truth"])
    return int(np.sum(np.abs(F - Ft) > tol * np.abs(Ft)))


def alias_error(rec: dict[str, Any]) -> float:
    """Relative difference at 0.9 x the top of the excitation band between the exact sampled
    plant (what the data obey) and the continuous plant x zero-order hold x delay (the model
    ``identify plant`` fits): the bias floor of a continuous-model fit."""
    t, T, f = rec["truth"], 1.0 / rec["meta"]["rate"], 0.9 * rec["meta"]["band_hz"][1]
    Phi, G0, G1, n = sims.discretize_delayed(t["a"], t["b"], t["c"], t["delay"], T)
    z = np.exp(2j * np.pi * f * T)
    Hd = np.linalg.solve(z * np.eye(2) - Phi, G0 + G1 / z)[0] * z ** (-n)
    s = 2j * np.pi * f
    Hc = t["a"] / (s * s + t["b"] * s + t["c"]) * np.exp(-s * t["delay"]) * (1 - np.exp(-s * T)) / (s * T)
    return float(abs(Hd / Hc - 1))


def _blocks(params: dict[str, Any], truth: bool) -> list[tuple[float, float, float, float]]:
    """``(k, w, se_k, se_w)`` per block, sorted by break displacement ``w/k``."""
    out = []
    i = 1
    while f"k{i}" in params:
        if truth:
            k, w, sk, sw = params[f"k{i}"], params[f"w{i}"], np.nan, np.nan
        else:
            (k, sk), (w, sw) = params[f"k{i}"], params[f"w{i}"]
        f = lambda z: np.nan if z is None else float(z)  # noqa: E731
        out.append((f(k), f(w), f(sk), f(sw)))
        i += 1
    return sorted(out, key=lambda b: b[1] / b[0] if b[0] else np.inf)


def param_samples(rec: dict[str, Any]) -> list[tuple[str, float, float, float]]:
    """``(parameter, truth, estimate, stderr)`` of a successful run (blocks matched by sorting
    on break displacement; nothing when the block counts differ)."""
    est = rec.get("estimate")
    if not est:
        return []
    if rec["identifier"] == "presliding":
        tb, eb = _blocks(rec["truth"], True), _blocks(est, False)
        if len(tb) != len(eb):
            return []
        out = []
        for (kt, wt, _, _), (k, w, sk, sw) in zip(tb, eb):
            out += [("k", kt, k, sk), ("w", wt, w, sw)]
        return out
    f = lambda z: np.nan if z is None else float(z)  # noqa: E731
    return [(n, rec["truth"][n], f(est[n][0]), f(est[n][1])) for n in PARAMS[rec["identifier"]] if n in est]


def degenerate(rec: dict[str, Any]) -> str | None:
    """Why the result is degenerate (a block or parameter at zero, a non-physical order), or None."""
    est = rec.get("estimate")
    if not est:
        return None
    ident = rec["identifier"]
    val = {k: (np.nan if v[0] is None else v[0]) for k, v in est.items()}
    if ident == "presliding":
        tb = _blocks(rec["truth"], True)
        kmin, wmin = min(b[0] for b in tb), min(b[1] for b in tb)
        for k, w, _, _ in _blocks(est, False):
            if not (np.isfinite(k) and np.isfinite(w)) or k <= 1e-3 * kmin or w <= 1e-3 * wmin:
                return f"block k={k:.3g} w={w:.3g}"
        return None
    if ident == "static":
        if val["fs"] < val["fc"]:
            return "fs < fc"
        if not 0.2 * 1.01 < val["delta"] < 5 / 1.01:
            return f"delta at its bound ({val['delta']:.3g})"
        if min(val[k] for k in ("fc", "vs")) <= 0 or val["sigma"] < 0:
            return "non-positive parameter"
        return None
    if val["delay"] <= 1e-3 * rec["truth"]["delay"]:
        return f"delay at zero ({val['delay']:.3g} s)"
    if min(val["a"], val["b"], val["c"]) <= 0:
        return "non-positive a, b or c"
    return None


def _fmt_pct(x: float) -> str:
    return "-" if not np.isfinite(x) else f"{100 * x:.2g} %" if x >= 10 else f"{100 * x:.0f} %" if x >= 0.1 else f"{100 * x:.1f} %" if x >= 0.001 else f"{100 * x:.2g} %"


def _table(header: list[str], rows: Iterable[list[str]]) -> str:
    rows = list(rows)
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def coverage_rows(recs: list[dict[str, Any]], group: str) -> list[list[str]]:
    samples: dict[str, list[tuple[float, float, float]]] = defaultdict(list)
    for r in recs:
        for name, t, e, s in param_samples(r):
            samples[name].append((t, e, s))
    rows = []
    for name, vals in samples.items():
        a = np.array(vals, dtype=float)
        t, e, s = a[:, 0], a[:, 1], a[:, 2]
        ok = np.isfinite(s) & (s > 0)
        z = np.where(ok, (e - t) / np.where(ok, s, 1.0), np.inf)
        rel = np.abs(e - t) / np.abs(t)
        cov = float(np.mean(np.abs(z) <= Z95))
        flag = "" if 0.90 <= cov <= 0.98 else " (!)"
        zf = z[np.isfinite(z)]
        rows.append([group, name, str(len(vals)), _fmt_pct(cov) + flag, _fmt_pct(float(np.median(rel))), _fmt_pct(float(np.quantile(rel, 0.9))),
                     f"{float(np.median(np.abs(zf)) / 0.6745):.2g}" if zf.size else "-", str(int((~ok).sum()))])
    return rows


def build(recs: list[dict[str, Any]], campaign: dict[str, Any]) -> str:
    out = ["# Identification campaign report", ""]
    if campaign:
        out.append(f"seed {campaign.get('seed')}, {campaign.get('cases')} cases, {campaign.get('jobs')} jobs, "
                   f"wall {campaign.get('wall_s')} s; simulators: {campaign.get('selfcheck')}")
        out.append("")
    main = [r for r in recs if r.get("units") == "si" and r.get("variant") in ("fit", "fixed")]
    fams = sorted({r["family"] for r in recs}, key=lambda f: (f.split("-")[0], f))

    out += ["## Coverage of the 95 % interval (value +- 1.96 stderr), SI runs", "",
            "Presliding: `--blocks N_true`, blocks matched by break displacement, k and w of all blocks pooled. "
            "`z scale` = median |z| / 0.674 (1 when the stderr is right); `se null` = runs without a finite stderr "
            "(counted as not covered); (!) = outside 90-98 %.", ""]
    rows = []
    for fam in fams:
        rows += coverage_rows([r for r in main if r["family"] == fam], fam)
    for ident in ("static", "presliding", "plant"):
        sub = [r for r in main if r["identifier"] == ident]
        if len({r["family"] for r in sub}) > 1:
            rows += coverage_rows(sub, f"**{ident} (all)**")
    out.append(_table(["family", "param", "n", "coverage", "median rel err", "p90 rel err", "z scale", "se null"], rows))
    out.append("")

    out += ["## Failures, degenerate results, warnings", ""]
    rows = []
    for fam in fams:
        for variant in sorted({r.get("variant") for r in recs if r["family"] == fam}):
            sub = [r for r in recs if r["family"] == fam and r.get("variant") == variant]
            fails = [r for r in sub if r.get("rc") != 0 or "error" in r]
            errs = Counter((r.get("error") or "")[:110] for r in fails)
            degen = [d for d in (degenerate(r) for r in sub) if d]
            warned = sum(1 for r in sub if r.get("warnings") or r.get("diagnostics"))
            wall = [r["wall_s"] for r in sub if "wall_s" in r]
            rows.append([fam, variant, str(len(sub)), str(len(fails)), "; ".join(f"{n}x {e}" for e, n in errs.most_common(3)) or "-",
                         str(len(degen)), "; ".join(f"{n}x {e}" for e, n in Counter(d.split("(")[0].split("=")[0] for d in degen).most_common(2)) or "-",
                         str(warned), f"{np.median(wall):.1f}" if wall else "-"])
    out.append(_table(["family", "run", "runs", "failed", "errors (count x last line)", "degenerate", "kinds", "warned", "median CLI s"], rows))
    out.append("")

    raw = [r for r in main if r["family"] == "static-raw" and r.get("estimate")]
    if raw:
        bad = [r for r in raw if bad_plateaus(r) > 0]
        out += ["## Static map from raw runs: accepted plateaus off the true map", "",
                f"{len(bad)} of {len(raw)} fits used at least one plateau whose force is more than 5 % off the true map at its "
                f"velocity (a transient taken for steady motion: ramp of a heavy axis, settling); "
                f"{sum(bad_plateaus(r) for r in bad)} such plateaus of {sum(len(r['info'].get('plateaus', [])) for r in raw)}. "
                "Coverage of the fits without / with them:", ""]
        rows = coverage_rows([r for r in raw if bad_plateaus(r) == 0], "no bad plateau") + coverage_rows(bad, "with bad plateaus")
        out.append(_table(["subset", "param", "n", "coverage", "median rel err", "p90 rel err", "z scale", "se null"], rows))
        out.append("")

    pl = [r for r in main if r["identifier"] == "plant" and r.get("estimate")]
    if pl:
        out += ["## Plant by sample rate", "",
                "`alias` = median relative difference, at 0.9 x the top of the excitation band, between the exact sampled "
                "plant the data obey and the continuous plant x ZOH x delay that is fitted (a bias no stderr covers).", ""]
        rows = []
        for rate in sorted({r["meta"]["rate"] for r in pl}):
            sub = [r for r in pl if r["meta"]["rate"] == rate]
            cr = {row[1]: row[3] for row in coverage_rows(sub, "")}
            rows.append([f"{rate:g}", str(len(sub)), _fmt_pct(float(np.median([alias_error(r) for r in sub])))] + [cr.get(k, "-") for k in PARAMS["plant"]])
        out.append(_table(["rate Hz", "runs", "alias", *(f"coverage {k}" for k in PARAMS["plant"])], rows))
        out.append("")

    ps = [r for r in recs if r["identifier"] == "presliding" and r.get("units") == "si"]
    if ps:
        out += ["## Pre-sliding: block count (BIC, `--max-blocks 8`) and blocks within 3 %", "",
                "`reference` (where run): the direct force fit of reference.py, told the true block count and where every "
                "block is saturated: what the data allow, not a candidate identifier.", ""]
        rows = []
        for fam in sorted({r["family"] for r in ps}):
            for variant in ("bic", "fixed", "reference"):
                sub = [r for r in ps if r["family"] == fam and r["variant"] == variant]
                if not sub:
                    continue
                diffs = [int(r["info"].get("n_blocks", len(_blocks(r["estimate"], False)))) - r["meta"]["n_blocks"] for r in sub if r.get("estimate")]
                within = [r for r in sub if r.get("estimate") and _all_within(r)]
                four6 = [r for r in sub if 4 <= r["meta"]["n_blocks"] <= 6]
                within46 = [r for r in four6 if r.get("estimate") and _all_within(r)]
                rows.append([fam, variant, str(len(sub)),
                             _fmt_pct(np.mean([d == 0 for d in diffs])) if diffs and variant == "bic" else "-",
                             ", ".join(f"{k:+d}:{v}" for k, v in sorted(Counter(diffs).items())) if variant == "bic" else "-",
                             _fmt_pct(len(within) / len(sub)), f"{len(within46)}/{len(four6)}" if four6 else "-"])
        out.append(_table(["family", "run", "runs", "count right", "N_est - N_true: cases", "every block within 3 %", "4-6 blocks: every block within 3 %"], rows))
        out.append("")
        out.append("By number of true blocks (`--blocks N_true` runs, all pre-sliding families): every block within 3 % / coverage of k and w")
        out.append("")
        rows = []
        for nb in range(1, 9):
            sub = [r for r in ps if r["variant"] == "fixed" and r["meta"]["n_blocks"] == nb]
            if not sub:
                continue
            cr = {row[1]: row[3] for row in coverage_rows(sub, "")}
            rows.append([str(nb), str(len(sub)), _fmt_pct(np.mean([bool(r.get("estimate")) and _all_within(r) for r in sub])),
                         cr.get("k", "-"), cr.get("w", "-"), _fmt_pct(np.mean([degenerate(r) is not None for r in sub]))])
        out.append(_table(["N", "runs", "all within 3 %", "coverage k", "coverage w", "degenerate"], rows))
        out.append("")

    pairs = defaultdict(dict)
    for r in recs:
        if r.get("variant") in ("fit", "bic", "fixed"):
            pairs[(r["case"], r["variant"])][r["units"]] = r
    rows = []
    for fam in fams:
        ps_ = [(p["si"], p["alt"]) for (case, _), p in pairs.items() if "si" in p and "alt" in p and p["si"]["family"] == fam]
        if not ps_:
            continue
        same_rc = sum(a.get("rc") == b.get("rc") for a, b in ps_)
        counts, diffs = [], []
        for a, b in ps_:
            ea, eb = a.get("estimate"), b.get("estimate")
            if not (ea and eb):
                continue
            counts.append(set(ea) == set(eb))
            if set(ea) == set(eb):
                d = [abs(eb[k][0] - ea[k][0]) / abs(ea[k][0]) for k in ea if ea[k][0] not in (None, 0) and eb[k][0] is not None]
                diffs.append(max(d) if d else np.nan)
        units = ps_[0][1].get("units_used", {})
        notes = sorted({n for _, b in ps_ for n in b.get("unit_notes", [])})
        rows.append([fam, ", ".join(f"{k}={v}" for k, v in units.items()), str(len(ps_)), f"{same_rc}/{len(ps_)}",
                     f"{sum(counts)}/{len(counts)}", _fmt_pct(float(np.nanmedian(diffs))) if diffs else "-",
                     _fmt_pct(float(np.nanmax(diffs))) if diffs else "-", "; ".join(notes) or "-"])
    if rows:
        out += ["## Unit invariance (same data written in other units; SI values compared)", "",
                "Pre-sliding compares the BIC runs (block count and blocks).", ""]
        out.append(_table(["family", "other units", "pairs", "same exit", "same parameter set / block count", "median max rel diff", "worst max rel diff", "notes"], rows))
        out.append("")

    out += ["## Worst cases (largest |z| of an SI run; rerun one with `run.py --case ID --seed SEED`)", ""]
    rows = []
    for fam in fams:
        scored = []
        for r in main:
            if r["family"] != fam:
                continue
            zs = [(abs((e - t) / s) if np.isfinite(s) and s > 0 else np.inf, n, (e - t) / t) for n, t, e, s in param_samples(r)]
            if zs:
                z, n, rel = max(zs, key=lambda q: q[0])
                scored.append((z, r["case"], r["variant"], n, rel))
        for z, case, variant, n, rel in sorted(scored, reverse=True)[:3]:
            rows.append([fam, case, variant, n, f"{z:.3g}", f"{100 * rel:+.3g} %"])
    out.append(_table(["family", "case", "run", "param", "|z|", "rel err"], rows))
    out.append("")

    out += ["## Wall time of the CLI runs", ""]
    rows = []
    for ident in ("static", "presliding", "plant"):
        sub = [r for r in recs if r["identifier"] == ident and "wall_s" in r]
        if sub:
            w = np.array([r["wall_s"] for r in sub])
            rows.append([ident, str(len(sub)), f"{w.sum():.0f}", f"{np.median(w):.1f}", f"{w.max():.1f}"])
    out.append(_table(["identifier", "runs", "total s", "median s", "max s"], rows))
    out.append("")
    return "\n".join(out)


def _all_within(rec: dict[str, Any], tol: float = BLOCK_TOL) -> bool:
    tb, eb = _blocks(rec["truth"], True), _blocks(rec["estimate"], False)
    if len(tb) != len(eb):
        return False
    return all(abs(e[0] - t[0]) <= tol * t[0] and abs(e[1] - t[1]) <= tol * t[1] for t, e in zip(tb, eb))

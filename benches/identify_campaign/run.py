"""Randomised identification campaign: `gmsfric identify` on experiments it did not make.

    python benches/identify_campaign/run.py --subset ci                # a few fixed cases, seconds
    python benches/identify_campaign/run.py --n 120 --jobs 2           # the full campaign
    python benches/identify_campaign/run.py --only presliding --n 30   # one identifier
    python benches/identify_campaign/run.py --report-only --out DIR    # tables from DIR/results.jsonl

Each case is drawn from random true parameters (``generate.py``, simulators in ``sims.py``,
neither uses gmsfric), written as CSV under ``--out`` and identified by the CLI in subprocesses
(``gmsfric identify static-map|presliding|plant FILE ... --json OUT --quiet``), ``--jobs`` at a
time.  Every run appends one JSON line to ``OUT/results.jsonl`` (truth and estimates in SI, exit
code, error line, wall time); ``report.py`` turns them into ``OUT/report.md``.  See README.md.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import generate  # noqa: E402
import reference  # noqa: E402
import report  # noqa: E402
import sims  # noqa: E402

# share of the cases of an identifier that each family gets
SPLIT = {
    "static": {"static-points": 0.5, "static-raw": 0.5},
    "presliding": {"presliding-virgin": 0.35, "presliding-hyst": 0.35, "presliding-issue": 0.30},
    "plant": {"plant-open": 0.5, "plant-closed": 0.5},
}
CI_SEED = 20240613
CI_CASES = {"static-points": [0], "static-raw": [0], "presliding-hyst": [0], "presliding-issue": [0], "plant-open": [0], "plant-closed": [0]}
CI_UNITS = {"static-raw", "presliding-issue", "plant-open"}  # also run in other units
SUBCOMMAND = {"static": "static-map", "presliding": "presliding", "plant": "plant"}


def cli_options(exe: list[str]) -> dict[str, set[str]]:
    """The long options each ``identify`` subcommand accepts (the campaign adapts to the CLI)."""
    out = {}
    for ident, sub in SUBCOMMAND.items():
        text = subprocess.run([*exe, "identify", sub, "--help"], capture_output=True, text=True, env=_env()).stdout
        out[ident] = {tok.strip("[],") for tok in text.split() if tok.startswith("--") or tok.startswith("[--")}
        out[ident] = {o.lstrip("[") for o in out[ident]}
    return out


def _env() -> dict[str, str]:
    env = dict(os.environ)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "RAYON_NUM_THREADS"):
        env[var] = "1"  # one core per job: --jobs is the parallelism
    return env


def plan_units(case: generate.Case, alt: bool, opts: set[str]) -> tuple[dict[str, str], list[str], list[str]]:
    """Units to write ``case`` in, the CLI unit options that declare them, and notes on options
    the CLI lacks (that quantity then stays in SI, unless another option covers it)."""
    notes: list[str] = []
    units = dict(generate.ALT_UNITS[case.identifier]) if alt else {}
    used = {q: units.get(q, generate.SI_UNITS[q]) for q in case.roles.values()}
    flags: list[str] = []
    # a raw static-map run's velocity is position / time: --velocity-unit declares both when the
    # CLI has no --position-unit / --time-unit of its own
    via_velocity = case.family == "static-raw" and "--position-unit" not in opts and "--velocity-unit" in opts
    for quantity, unit in used.items():
        if quantity == "excitation_ref":
            continue  # in the output's unit
        flag = f"--{quantity}-unit"
        if flag in opts:
            flags += [flag, unit]
        elif via_velocity and quantity in ("position", "time"):
            continue
        elif unit != generate.SI_UNITS[quantity]:
            notes.append(f"CLI has no {flag}: {quantity} kept in {generate.SI_UNITS[quantity]}")
            used[quantity] = units[quantity] = generate.SI_UNITS[quantity]
    if via_velocity:
        flags += ["--velocity-unit", f"{used['position']}/{used['time']}"]
        notes.append("CLI has no --position-unit/--time-unit for static-map: declared through --velocity-unit")
    if "excitation_ref" in used:
        units["excitation_ref"] = used["excitation_ref"] = used["output"]
    return units, flags, notes


def cli_args(case: generate.Case, path: Path, variant: str) -> list[str]:
    r = {q: n for n, q in case.roles.items()}
    if case.identifier == "static":
        if case.family == "static-points":
            args = ["identify", "static-map", str(path), "--velocity", "v", "--force", "F"]
        else:
            args = ["identify", "static-map", str(path), "--time", "t", "--position", "x", "--force", "F"]
    elif case.identifier == "presliding":
        args = ["identify", "presliding", str(path), "--time", "t", "--position", "x", "--force", "F"]
        args += ["--blocks", str(case.meta["n_blocks"])] if variant == "fixed" else ["--max-blocks", "8"]
    else:
        args = ["identify", "plant", str(path), "--time", "t", "--input", "u", "--output", "y"]
        if "r" in r.values() or "r" in case.columns:
            args += ["--excitation", "r"]
    return args


def to_si(doc: dict[str, Any]) -> tuple[dict[str, list[float | None]], list[str]]:
    """Parameters of a JSON result in SI, by parsing its own unit strings."""
    out, notes = {}, []
    units = doc.get("units", {})
    for name, p in doc.get("parameters", {}).items():
        try:
            s = generate.unit_scale(units.get(name, "1"))
        except (KeyError, IndexError, ValueError) as exc:
            notes.append(f"unit of {name}: {exc}")
            s = float("nan")
        v, e = p.get("value"), p.get("stderr")
        out[name] = [None if v is None else v * s, None if e is None else e * s]
    return out, notes


def reference_record(case: generate.Case) -> dict[str, Any]:
    """The direct reference fit (reference.py) of a pre-sliding case, as a result record."""
    t0 = time.perf_counter()
    est = reference.direct_block_fit(case.columns["x"], case.columns["F"], case.meta["n_blocks"], case.meta["saturated_index"],
                                     case.meta["saturated_sign"], seed=case.index)
    return {"case": case.id, "family": case.family, "identifier": case.identifier, "index": case.index, "seed": case.seed,
            "variant": "reference", "units": "si", "rc": 0, "wall_s": round(time.perf_counter() - t0, 3), "truth": case.truth,
            "meta": case.meta, "estimate": est, "info": {"n_blocks": case.meta["n_blocks"]}, "command": "reference.direct_block_fit"}


def run_case(case_key: tuple[str, int], seed: int, small: bool, out: Path, exe: list[str], opts: dict[str, set[str]], alt: bool,
             timeout: float, keep: bool, sink, with_reference: bool = False, cli: bool = True) -> None:  # type: ignore[no-untyped-def]
    family, index = case_key
    t0 = time.perf_counter()
    case = generate.make_case(family, index, seed, small)
    gen_time = time.perf_counter() - t0
    if with_reference and case.identifier == "presliding":
        sink(reference_record(case))
    if not cli:
        return
    variants = ["fixed", "bic"] if case.identifier == "presliding" else ["fit"]
    runs = [(v, False) for v in variants]
    if alt:
        runs.append(("bic" if case.identifier == "presliding" else "fit", True))
    if small and case.identifier == "presliding" and not alt:
        runs = [r for r in runs if r[0] == "fixed"]  # CI: BIC only where its unit invariance is checked
    data_dir = out / "data"
    for variant, is_alt in runs:
        units, flags, notes = plan_units(case, is_alt, opts[case.identifier])
        path, used = generate.write_case(case, data_dir, units)
        jpath = out / "json" / f"{case.id}-{variant}-{'alt' if is_alt else 'si'}.json"
        jpath.parent.mkdir(parents=True, exist_ok=True)
        if jpath.exists():
            jpath.unlink()
        cmd = [*exe, *cli_args(case, path, variant), *flags, "--json", str(jpath), "--quiet"]
        t1 = time.perf_counter()
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=_env())
            rc, stdout, stderr = proc.returncode, proc.stdout, proc.stderr
        except subprocess.TimeoutExpired:
            rc, stdout, stderr = -9, "", f"timeout after {timeout:.0f} s"
        wall = time.perf_counter() - t1
        rec: dict[str, Any] = {
            "case": case.id, "family": family, "identifier": case.identifier, "index": index, "seed": seed, "variant": variant,
            "units": "alt" if is_alt else "si", "units_used": used, "unit_notes": notes, "rc": rc, "wall_s": round(wall, 3),
            "generate_s": round(gen_time, 3), "truth": case.truth, "meta": case.meta, "command": " ".join(cmd[len(exe):]),
        }
        err_lines = [ln for ln in stderr.strip().splitlines() if ln.strip()]
        rec["warnings"] = [ln for ln in err_lines if "Warning" in ln][:20]
        if rc != 0:
            rec["error"] = err_lines[-1] if err_lines else f"exit {rc}, no message"
        if rc == 0 and jpath.exists():
            doc = json.loads(jpath.read_text())
            rec["estimate"], conv_notes = to_si(doc)
            rec["unit_notes"] += conv_notes
            rec["diagnostics"] = doc.get("diagnostics", [])
            rec["info"] = {k: v for k, v in doc.items() if k in ("n_blocks", "n_plateaus", "n_rejected", "chi2_dof", "stderr_inflation", "rms_residual", "bic")}
            if "plateaus" in doc:  # the accepted plateaus, to check them against the true map
                rec["info"]["plateaus"] = [[p.get("velocity"), p.get("force")] for p in doc["plateaus"]]
        elif rc == 0:
            rec["error"] = "exit 0 but no JSON written"
        rec["table_tail"] = stdout.strip().splitlines()[-12:] if rc == 0 else []
        sink(rec)
        if not keep:
            path.unlink(missing_ok=True)


def selfcheck() -> dict[str, float]:
    """The simulators against references: the numpy blocks against
    ``gmsfric.simulate_friction(MaxwellSlip)`` on one case, the fractional-delay discretisation
    against a fine ODE solution."""
    from scipy.integrate import solve_ivp

    import gmsfric

    c = generate.make_case("presliding-virgin", 0, CI_SEED, small=False)
    nb = c.meta["n_blocks"]
    k = np.array([c.truth[f"k{i + 1}"] for i in range(nb)])
    w = np.array([c.truth[f"w{i + 1}"] for i in range(nb)])
    t = c.columns["t"]
    x = sims.virgin_sine_position(t, c.meta["amplitudes"], c.meta["frequency"], 2)
    f_own = sims.maxwell_slip_force(x, k, w)
    f_pkg = gmsfric.simulate_friction(gmsfric.MaxwellSlip(list(k), list(w)), t, x)
    a, b, cc, T, tau = 0.05, 30.0, 400.0, 1e-3, 2.4e-3
    u = np.random.default_rng(0).standard_normal(60)
    y = sims.simulate_plant_open(u, a, b, cc, tau, T)

    def rhs(tt: float, s: np.ndarray) -> list[float]:
        j = int(np.floor((tt - tau) / T + 1e-12))
        return [s[1], -cc * s[0] - b * s[1] + a * (u[j] if 0 <= j < u.size else 0.0)]

    sol = solve_ivp(rhs, (0, (u.size - 1) * T), [0.0, 0.0], t_eval=np.arange(u.size) * T, max_step=T / 50, rtol=1e-10, atol=1e-14)
    return {
        "maxwell_slip_blocks": nb,
        "maxwell_slip_max_rel_diff": float(np.abs(f_own - f_pkg).max() / w.sum()),
        "delay_plant_max_rel_diff": float(np.abs(sol.y[0] - y).max() / np.abs(y).max()),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=100, help="cases per identifier (split over its families)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--only", action="append", choices=list(SPLIT), help="identifier(s) to run (repeatable)")
    p.add_argument("--family", action="append", choices=list(generate.FAMILIES), help="restrict to these families")
    p.add_argument("--case", action="append", metavar="FAMILY-INDEX", help="run just this case (e.g. presliding-issue-0007), data kept")
    p.add_argument("--subset", choices=["ci"], help="ci: a few fixed short cases per identifier")
    p.add_argument("--jobs", type=int, default=2, help="CLI processes at a time (<= 2 on a shared machine)")
    p.add_argument("--out", default="/tmp/identify_campaign", help="data, JSON and results directory (outside git)")
    p.add_argument("--units-every", type=int, default=6, help="every k-th case also runs in other units (0: none)")
    p.add_argument("--timeout", type=float, default=600.0, help="seconds per CLI run")
    p.add_argument("--gmsfric", default=None, help="the gmsfric command (default: next to this Python)")
    p.add_argument("--keep", action="store_true", help="keep the generated CSV files")
    p.add_argument("--report-only", action="store_true", help="rebuild OUT/report.md from OUT/results.jsonl")
    p.add_argument("--reference", action="store_true", help="also the direct reference fit of each pre-sliding case (in-process, slow)")
    p.add_argument("--reference-only", action="store_true", help="only the reference fits, appended to an existing OUT/results.jsonl")
    args = p.parse_args(argv)
    out = Path(args.out)
    if args.report_only:
        text = report.build(report.backfill(report.load(out / "results.jsonl"), out / "json"), json.loads((out / "campaign.json").read_text()) if (out / "campaign.json").exists() else {})
        (out / "report.md").write_text(text)
        print(text)
        return 0
    if args.jobs < 1:
        p.error("--jobs must be at least 1")
    exe_path = args.gmsfric or str(Path(sys.executable).with_name("gmsfric"))
    exe = [exe_path] if Path(exe_path).exists() or shutil.which(exe_path) else [sys.executable, "-m", "gmsfric.cli"]
    idents = args.only or list(SPLIT)
    keys: list[tuple[str, int]] = []
    small = args.subset == "ci"
    seed = CI_SEED if small else args.seed
    if args.case:
        for c in args.case:
            fam, _, idx = c.rpartition("-")
            if fam not in generate.FAMILIES or not idx.isdigit():
                p.error(f"--case {c!r}: expected FAMILY-INDEX with FAMILY one of {', '.join(generate.FAMILIES)}")
            keys.append((fam, int(idx)))
        idents, args.keep = [], True
    for ident in idents:
        for fam, share in SPLIT[ident].items():
            if args.family and fam not in args.family:
                continue
            idx = CI_CASES.get(fam, []) if small else range(max(1, int(round(share * args.n))))
            keys += [(fam, int(i)) for i in idx]
    results = out / "results.jsonl"
    if not args.reference_only:
        if out.exists():
            for sub in ("json", "data"):
                shutil.rmtree(out / sub, ignore_errors=True)
        out.mkdir(parents=True, exist_ok=True)
        results.write_text("")
    elif not results.exists():
        p.error(f"--reference-only appends to {results}, which does not exist")
    opts = cli_options(exe)
    check = selfcheck()
    print(f"simulators: {check}", file=sys.stderr)
    lock = threading.Lock()
    done = [0]
    total = len(keys)

    def sink(rec: dict[str, Any]) -> None:
        with lock:
            with results.open("a") as fh:
                fh.write(json.dumps(rec) + "\n")

    t0 = time.perf_counter()
    # families interleaved, so partial results cover every family
    order = sorted(keys, key=lambda kv: (kv[1], kv[0]))
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futs = {pool.submit(run_case, key, seed, small, out, exe, opts, key[0] in CI_UNITS if small else (args.units_every > 0 and key[1] % args.units_every == 0),
                            args.timeout, args.keep, sink, args.reference or args.reference_only, not args.reference_only): key for key in order}
        for fut in as_completed(futs):
            key = futs[fut]
            done[0] += 1
            exc = fut.exception()
            if exc is not None:
                sink({"case": f"{key[0]}-{key[1]:04d}", "family": key[0], "identifier": generate.IDENTIFIER[key[0]], "index": key[1], "seed": seed,
                      "variant": "generate", "units": "si", "rc": -1, "error": f"campaign: {type(exc).__name__}: {exc}"})
            print(f"\r{done[0]}/{total} cases, {time.perf_counter() - t0:.0f} s", end="", file=sys.stderr, flush=True)
    wall = time.perf_counter() - t0
    print(file=sys.stderr)
    if args.reference_only:
        text = report.build(report.backfill(report.load(results), out / "json"), json.loads((out / "campaign.json").read_text()) if (out / "campaign.json").exists() else {})
        (out / "report.md").write_text(text)
        print(f"reference fits appended in {wall:.0f} s", file=sys.stderr)
        return 0
    campaign = {"seed": seed, "n": args.n, "subset": args.subset, "jobs": args.jobs, "wall_s": round(wall, 1), "cases": total,
                "command": " ".join(sys.argv), "cli": exe, "cli_options": {k: sorted(v) for k, v in opts.items()}, "selfcheck": check}
    (out / "campaign.json").write_text(json.dumps(campaign, indent=2) + "\n")
    text = report.build(report.load(results), campaign)
    (out / "report.md").write_text(text)
    print(text)
    if not args.keep:
        shutil.rmtree(out / "data", ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

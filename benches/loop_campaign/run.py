"""Run the evaluation campaign of ``gmsfric loop`` and print its confusion matrix and rates.

    python benches/loop_campaign/run.py                       # full campaign (~310 cases), 2 jobs
    python benches/loop_campaign/run.py --subset ci           # the 10 fixed CI cases
    python benches/loop_campaign/run.py --n 40 --only stribeck --out /tmp/lc-strib
    python benches/loop_campaign/run.py --truth-only          # generate data and ground truth only
    python benches/loop_campaign/run.py --report              # re-print the report of a finished run
    python benches/loop_campaign/run.py --check-sim           # own integrator vs the core on one axis

Each case: simulate (or plant on EMPS) an estimation and a validation run, write them as CSV or
.mat in the case's units, compute the ground truth, then call the CLI contract
``gmsfric loop EST --validate VAL --time .. --position .. (--force .. | --command .. --gain ..)
[--*-unit ..] [--baseline rigid] --json OUT --quiet`` in a subprocess and read ``final.effects``.
Outputs under ``--out`` (default ``/tmp/gmsfric-loop-campaign``): one folder per case (data,
``truth.json``, ``loop.json``, ``stderr.txt``), ``cases.json``, ``results.json``, ``report.txt``.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run as a script: make the package importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    __package__ = "loop_campaign"

import numpy as np  # noqa: E402

from .cases import CATALOGUE, ci_cases, make_cases  # noqa: E402
from .rigs import cli_args, cross_check, emps_dir, simulate_run, write_run  # noqa: E402
from .score import format_report, summarize  # noqa: E402
from .truth import ground_truth  # noqa: E402

DEFAULT_OUT = Path("/tmp/gmsfric-loop-campaign")


def gmsfric_command() -> list[str]:
    """The ``gmsfric`` entry point next to this interpreter (a venv), else on PATH."""
    exe = Path(sys.executable).parent / "gmsfric"
    if exe.exists():
        return [str(exe)]
    found = shutil.which("gmsfric")
    if found:
        return [found]
    return [sys.executable, "-m", "gmsfric.cli"]


def loop_command(case: dict[str, Any], est: Path, val: Path, out_json: Path, gmsfric: list[str]) -> list[str]:
    cmd = gmsfric + ["loop", str(est), "--validate", str(val)] + cli_args(case["fmt"])
    if case.get("baseline") == "rigid":
        cmd += ["--baseline", "rigid"]
    return cmd + ["--json", str(out_json), "--quiet"]


def _last_line(text: str) -> str:
    lines = [ln.strip() for ln in text.strip().splitlines() if ln.strip()]
    return lines[-1][:300] if lines else "(no message)"


def run_case(case: dict[str, Any], out: Path, gmsfric: list[str], timeout: float, truth_only: bool = False,
             resume: bool = False) -> dict[str, Any]:
    """Generate one case, compute its truth, run the loop on it; never raises."""
    d = out / case["id"]
    res_path = d / "result.json"
    if resume and res_path.exists():
        return json.loads(res_path.read_text())
    d.mkdir(parents=True, exist_ok=True)
    res: dict[str, Any] = {
        "id": case["id"], "group": case["group"], "planted": [e["name"] for e in case["effects"]],
        "grades": [e.get("grade") for e in case["effects"]], "outside": [e["name"] for e in case["outside"]],
        "native": [e["name"] for e in case["native"]], "accepted": [], "alignment": False,
    }
    t0 = time.perf_counter()
    try:
        est, val = simulate_run(case, "est"), simulate_run(case, "val")
        res["truth"] = ground_truth(case, est, val)
        res["sim_meta"] = {"est": est.meta, "val": val.meta}
        ext = case["fmt"]["ext"]
        fe, fv = d / f"est.{ext}", d / f"val.{ext}"
        write_run(est, case["fmt"], fe)
        write_run(val, case["fmt"], fv)
        (d / "truth.json").write_text(json.dumps(res["truth"], indent=1))
    except Exception as exc:  # a generator bug must not stop the campaign; it is reported
        res.update(status="generator_error", error=f"{type(exc).__name__}: {exc}", truth={"effects": {}})
        (d / "generator_error.txt").write_text(traceback.format_exc())
        return res
    res["gen_s"] = round(time.perf_counter() - t0, 2)
    if truth_only:
        res.update(status="truth_only", error="")
        return res
    out_json = d / "loop.json"
    cmd = loop_command(case, fe, fv, out_json, gmsfric)
    call_loop(cmd, d, out_json, res, timeout)
    res_path.write_text(json.dumps(res, indent=1))
    return res


def call_loop(cmd: list[str], d: Path, out_json: Path, res: dict[str, Any], timeout: float) -> None:
    """Run the loop command ``cmd`` (writing ``out_json``) for the case folder ``d`` and put its
    outcome into ``res``: status, accepted effects, alignment, unconfirmed delays, errors."""
    out_json.unlink(missing_ok=True)
    (d / "command.txt").write_text(shlex.join(cmd) + "\n")  # quoted: units such as "N m" hold a space
    t1 = time.perf_counter()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=dict(os.environ, MPLBACKEND="Agg"))
        code, stderr = p.returncode, p.stderr
    except subprocess.TimeoutExpired:
        code, stderr = -1, f"timeout after {timeout:.0f} s"
    res["loop_s"] = round(time.perf_counter() - t1, 2)
    (d / "stderr.txt").write_text(stderr)
    if code != 0 or not out_json.exists():
        res.update(status="fail", error=_last_line(stderr) + ("" if code else " (no JSON written)"))
        return
    o = json.loads(out_json.read_text())
    res.update(status="ok", error="", accepted=list(o["final"]["effects"]),
               alignment=bool(o.get("alignment", {}).get("applied", False)),
               unconfirmed=sorted({x["parameter"] for x in o.get("diagnostics", []) if x.get("code") == "unconfirmed"}),
               loop_errors={"baseline": [o["baseline"]["estimation_error_pct"], o["baseline"]["validation_error_pct"]],
                            "final": [o["final"]["estimation_error_pct"], o["final"]["validation_error_pct"]]})


def run_cases(cases: list[dict[str, Any]], out: Path, *, jobs: int = 2, gmsfric: list[str] | None = None,
              timeout: float = 600.0, truth_only: bool = False, resume: bool = False,
              progress: bool = True) -> tuple[list[dict[str, Any]], dict[str, Any], float]:
    """Run cases ``jobs`` at a time; write ``results.json`` and ``report.txt`` under ``out``.

    Returns the per-case results (sorted by id), the summary of :func:`score.summarize` (empty
    with ``truth_only``) and the wall time (s).  For a test: ``run_cases(ci_cases(), tmp_path)``.
    """
    out.mkdir(parents=True, exist_ok=True)
    (out / "cases.json").write_text(json.dumps(cases, indent=1))
    gms = gmsfric or gmsfric_command()
    t0 = time.perf_counter()
    results = []
    with ProcessPoolExecutor(max_workers=jobs, mp_context=get_context("fork")) as pool:
        futs = [pool.submit(run_case, c, out, gms, timeout, truth_only, resume) for c in cases]
        for k, fut in enumerate(as_completed(futs), 1):
            r = fut.result()
            results.append(r)
            if progress:
                mark = "" if r["status"] in ("ok", "truth_only") else f"  [{r['status']}] {r['error']}"
                print(f"[{k}/{len(cases)}] {r['id']}: {', '.join(r['accepted']) or '-'}{mark}", file=sys.stderr)
    wall = time.perf_counter() - t0
    results.sort(key=lambda r: r["id"])
    summary = {} if truth_only else summarize(results)
    (out / "results.json").write_text(json.dumps({"wall_s": wall, "summary": summary, "cases": results}, indent=1))
    if not truth_only:
        (out / "report.txt").write_text(format_report(results, summary, wall) + "\n")
    return results, summary, wall


def select_cases(args: argparse.Namespace) -> list[dict[str, Any]]:
    cases = ci_cases() if args.subset == "ci" else make_cases(args.seed, emps=not args.no_emps)
    if not args.no_emps and args.subset != "ci" and not (emps_dir() / "DATA_EMPS.mat").exists():
        print(f"EMPS data not found in {emps_dir()} (set GMSFRIC_EMPS_DIR); EMPS cases skipped", file=sys.stderr)
        cases = [c for c in cases if c["sim"] != "emps"]
    if args.only:
        cases = [c for c in cases if args.only in [e["name"] for e in c["effects"]] or args.only == c["group"]
                 or (args.only == "clean" and not c["effects"] and not c["outside"])]
    if args.n is not None and args.n < len(cases):
        order = np.random.default_rng(args.seed).permutation(len(cases))[: args.n]
        cases = [cases[i] for i in sorted(order)]
    return cases


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=None, help="run a seeded random sample of N cases")
    p.add_argument("--seed", type=int, default=2024, help="campaign seed (default 2024)")
    p.add_argument("--subset", choices=("full", "ci"), default="full")
    p.add_argument("--only", metavar="EFFECT", help=f"cases planting EFFECT ({', '.join(CATALOGUE)}), or a group: clean, pair, outside, robot, emps")
    p.add_argument("--jobs", type=int, default=2, help="cases at a time (default 2)")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    p.add_argument("--timeout", type=float, default=600.0, help="seconds per loop run")
    p.add_argument("--resume", action="store_true", help="reuse finished cases in --out")
    p.add_argument("--truth-only", action="store_true", help="generate data and ground truth, do not run the loop")
    p.add_argument("--no-emps", action="store_true", help="leave out the EMPS cases")
    p.add_argument("--gmsfric", default=None, help="command running gmsfric (default: the one next to this python)")
    p.add_argument("--report", action="store_true", help="only print the report of the results already in --out")
    p.add_argument("--check-sim", action="store_true", help="only compare the campaign's integrator with the core on one axis")
    args = p.parse_args(argv)
    if args.check_sim:
        print(json.dumps(cross_check(), indent=1))
        return 0
    if args.report:
        saved = json.loads((args.out / "results.json").read_text())
        results = saved["cases"]
        report = format_report(results, summarize(results), saved.get("wall_s"))
        (args.out / "report.txt").write_text(report + "\n")
        print(report)
        return 0
    if args.jobs < 1:
        p.error("--jobs must be >= 1")
    cases = select_cases(args)
    if not cases:
        p.error("no case matches")
    gms = args.gmsfric.split() if args.gmsfric else gmsfric_command()
    print(f"{len(cases)} cases -> {args.out} ({args.jobs} at a time, loop: {' '.join(gms)})", file=sys.stderr)
    results, summary, wall = run_cases(cases, args.out, jobs=args.jobs, gmsfric=gms, timeout=args.timeout,
                                       truth_only=args.truth_only, resume=args.resume)
    if args.truth_only:
        print(truth_table(results))
    else:
        print((args.out / "report.txt").read_text(), end="")
    return 0


def truth_table(results: list[dict[str, Any]]) -> str:
    """Detectable fraction per effect and grade (to check the grading, without the loop)."""
    rows: dict[tuple[str, Any], list[int]] = {}
    for r in results:
        for eff, t in r.get("truth", {}).get("effects", {}).items():
            gr = r["grades"][r["planted"].index(eff)]
            row = rows.setdefault((eff, gr), [0, 0])
            row[0] += t["detectable"]
            row[1] += 1
    lines = ["detectable per effect and grade (grade None: EMPS)"]
    for (eff, gr), (k, n) in sorted(rows.items(), key=lambda x: (x[0][0], -1 if x[0][1] is None else x[0][1])):
        lines.append(f"  {eff:30s} grade {gr!s:4s} {k}/{n}")
    errs = [f"  {r['id']}: {r['error']}" for r in results if r["status"] == "generator_error"]
    return "\n".join(lines + ([f"generator errors ({len(errs)}):"] + errs if errs else []))


if __name__ == "__main__":
    sys.exit(main())

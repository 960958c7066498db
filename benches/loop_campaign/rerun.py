"""Run the loop again on the data of a finished campaign, without simulating anything again.

    python benches/loop_campaign/rerun.py --from /tmp/lc87 --out /tmp/lc87-new
    python benches/loop_campaign/rerun.py --from /tmp/lc87 --out /tmp/lc87-new --ids single-039 pair-160
    python benches/loop_campaign/rerun.py --from /tmp/lc87 --out /tmp/lc87-new --changed-only

A change of the loop is measured on the very cases of a campaign: the data files and the truth of
``--from`` are reused (the truth does not depend on the loop), the CLI is called on them as
``run.py`` calls it, and the report is written under ``--out`` as by ``run.py``.  ``--gmsfric``
names another loop (e.g. ``"env PYTHONPATH=/path/to/checkout/python python3 -m gmsfric.cli"``).
``--ids`` takes case ids or their prefixes; cases not named keep their result from ``--from``,
so the report always covers the whole campaign.  ``--changed-only`` prints only the cases whose
accepted effects differ from ``--from``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import shlex
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run as a script: make the package importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    __package__ = "loop_campaign"

from .run import call_loop, gmsfric_command  # noqa: E402
from .score import format_report, summarize  # noqa: E402


def rerun_case(old: dict[str, Any], src: Path, out: Path, gmsfric: list[str], timeout: float) -> dict[str, Any]:
    """The loop run again on one case's data in ``src``; the result as ``run.run_case`` writes it."""
    d = out / old["id"]
    d.mkdir(parents=True, exist_ok=True)
    res = {k: v for k, v in old.items() if k not in ("accepted", "alignment", "unconfirmed", "loop_errors", "loop_s")}
    res.update(accepted=[], alignment=False)
    old_cmd = shlex.split((src / old["id"] / "command.txt").read_text())
    # the old command: <gmsfric ...> loop EST ... --json OUT --quiet; keep what follows "loop"
    tail = old_cmd[old_cmd.index("loop"):]
    out_json = d / "loop.json"
    tail[tail.index("--json") + 1] = str(out_json)
    call_loop(gmsfric + tail, d, out_json, res, timeout)
    (d / "result.json").write_text(json.dumps(res, indent=1))
    return res


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--from", dest="src", type=Path, required=True, help="a finished campaign's --out")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--ids", nargs="*", default=None, help="case ids (or prefixes) to run again; default all")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--timeout", type=float, default=600.0)
    p.add_argument("--gmsfric", default=None, help="command running gmsfric (default: the one next to this python)")
    p.add_argument("--changed-only", action="store_true", help="print only the cases whose accepted effects changed")
    args = p.parse_args(argv)
    if args.src.resolve() == args.out.resolve():
        p.error("--out must differ from --from (the campaign's results are kept)")
    saved = json.loads((args.src / "results.json").read_text())
    old = {r["id"]: r for r in saved["cases"]}
    ids = [i for i in old if args.ids is None or any(i.startswith(x) for x in args.ids)]
    todo = [old[i] for i in ids if old[i]["status"] in ("ok", "fail")]
    gms = args.gmsfric.split() if args.gmsfric else gmsfric_command()
    args.out.mkdir(parents=True, exist_ok=True)
    if (args.src / "cases.json").is_file():
        # the draw's specs travel with its results: pool.py and resolution.py read them there
        shutil.copyfile(args.src / "cases.json", args.out / "cases.json")
    print(f"{len(todo)} of {len(old)} cases again -> {args.out} (loop: {' '.join(gms)})", file=sys.stderr)
    t0 = time.perf_counter()
    new = dict(old)
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futs = [pool.submit(rerun_case, r, args.src, args.out, gms, args.timeout) for r in todo]
        for k, fut in enumerate(as_completed(futs), 1):
            r = fut.result()
            new[r["id"]] = r
            was = old[r["id"]]["accepted"]
            changed = sorted(was) != sorted(r["accepted"])
            if changed or not args.changed_only:
                mark = f"  (was: {', '.join(was) or '-'})" if changed else ""
                print(f"[{k}/{len(todo)}] {r['id']}: {', '.join(r['accepted']) or '-'}{mark}", file=sys.stderr)
    wall = time.perf_counter() - t0
    results = sorted(new.values(), key=lambda r: r["id"])
    summary = summarize(results)
    (args.out / "results.json").write_text(json.dumps({"wall_s": wall, "summary": summary, "cases": results, "rerun_of": str(args.src)}, indent=1))
    report = format_report(results, summary, wall)
    (args.out / "report.txt").write_text(report + "\n")
    print(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())

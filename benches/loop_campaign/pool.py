"""Pool finished campaigns: one report over several draws, with 95 % intervals on the rates.

One draw holds ~330 cases, so a rate near a target moves by a case or two between draws (a false
effect in 2 % of cases is 6.6 cases).  Pooling several draws of the *same* loop, each drawn with
its own seed, gives the rates with the precision the targets need::

    python benches/loop_campaign/pool.py /tmp/s119 /tmp/s121 /tmp/s123

Each DIR is a finished ``run.py --out`` (its ``results.json`` and ``cases.json``).  Case ids are
prefixed with the directory's name, the report is :func:`score.format_report` over all of them,
and a table of the targets' rates follows with Wilson score intervals (``scipy.stats.binomtest``),
per draw and pooled.  The intervals take the cases as independent, which the EMPS group's are not
across draws: most draws plant the same term on the same two real runs, and the loop decides the
same.  Such a repeat is pooled once (:func:`distinct`); a draw's own column keeps all its cases.
Only pool draws run with the same loop: the script does not check that.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from scipy import stats

if __package__ in (None, ""):  # run as a script: make the package importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    __package__ = "loop_campaign"

from .score import TARGETS, format_report, summarize  # noqa: E402


def named_twice(dirs: list[Path]) -> bool:
    """Whether a draw is named twice: the same directory, or two with the same name (case ids are
    prefixed with it)."""
    return len({d.resolve() for d in dirs}) < len(dirs) or len({d.name for d in dirs}) < len(dirs)


class UnreadableDraw(ValueError):
    """A campaign directory whose ``results.json`` or ``cases.json`` cannot be read as ``run.py``
    writes them."""


def read_draw(d: Path) -> tuple[list[dict[str, Any]], dict[str, dict[str, Any]]]:
    """A finished campaign's results and its case specs by id (none without ``cases.json``)."""
    try:
        results = json.loads((d / "results.json").read_text())["cases"]
        if not isinstance(results, list) or not all(isinstance(r, dict) and "id" in r and "status" in r for r in results):
            raise ValueError("its cases are not a list of results with an id and a status")
        specs = {c["id"]: c for c in json.loads((d / "cases.json").read_text())} if (d / "cases.json").is_file() else {}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise UnreadableDraw(f"{d}: not the files of a finished campaign ({type(exc).__name__}: {exc})") from None
    return results, specs


def load(dirs: list[Path]) -> list[tuple[str, list[dict[str, Any]]]]:
    """``(label, results)`` per finished campaign directory, ids prefixed with the label; each
    result carries its case's ``spec`` and ``experiment`` (:func:`experiment`) when ``cases.json``
    is there."""
    out = []
    for d in dirs:
        results, specs = read_draw(d)
        out.append((d.name, [dict(r, id=f"{d.name}/{r['id']}", spec=specs.get(r["id"]), experiment=experiment(specs.get(r["id"]))) for r in results]))
    return out


def experiment(spec: dict[str, Any] | None) -> str | None:
    """What makes a real-data case the same experiment in another draw: the runs, their roles and
    the planted terms (a simulated case is new in every draw: ``None``)."""
    if spec is None or spec.get("sim") != "emps":
        return None
    return json.dumps([spec.get("files"), spec.get("direction"), spec.get("baseline"), spec.get("effects")], sort_keys=True)


def distinct(draws: list[tuple[str, list[dict[str, Any]]]]) -> tuple[list[dict[str, Any]], int]:
    """Every draw's results, a real-data experiment an earlier draw holds left out; and how many."""
    seen: set[str] = set()
    out, repeats = [], 0
    for _, results in draws:
        for r in results:
            key = r.get("experiment")
            if key is not None and key in seen:
                repeats += 1
                continue
            if key is not None:
                seen.add(key)
            out.append(r)
    return out, repeats


def wilson(k: int, n: int) -> tuple[float, float]:
    """The 95 % Wilson score interval of the rate ``k / n`` (``n > 0``)."""
    ci = stats.binomtest(k, n).proportion_ci(0.95, method="wilson")
    return float(ci.low), float(ci.high)


def interval(k: int, n: int) -> str:
    """``k/n (p %, lo-hi)``, percentages, the interval :func:`wilson`'s."""
    if n == 0:
        return "-"
    lo, hi = wilson(k, n)
    return f"{k}/{n} ({100 * k / n:.1f} %, {100 * lo:.1f}-{100 * hi:.1f})"


def rates(s: dict[str, Any]) -> dict[str, tuple[int, int]]:
    """The targets' rates of one summary as ``(k, n)``."""
    out = {"false effect in a case (<= 2 %)": tuple(s["false_cases"]),
           "clean runs, nothing added (>= 98 %)": tuple(s["clean"][:2]),
           "pairs, both detectable, both found (>= 80 %)": tuple(s["pairs_both_detectable"][:2]),
           "pairs, both beyond the nulls, both found": tuple(s["pairs_both_detectable_beyond_null"][:2])}
    for eff, row in s["recall"].items():
        for key, what in (("det", "detectable"), ("det_moving", "det. moving"), ("det_null", "det. beyond null")):
            out[f"recall {eff}, {what}"] = tuple(row[key][:2])
    return out


def pooled_table(per_draw: list[tuple[str, dict[str, Any]]], pooled: dict[str, Any]) -> str:
    """The targets' rates per draw and pooled, with their intervals."""
    labels = [lab for lab, _ in per_draw]
    rows = {lab: rates(s) for lab, s in per_draw}
    lines = [f"Rates with 95 % Wilson intervals; targets: recall >= {TARGETS['recall']:.0%}, false <= {TARGETS['false']:.0%}, "
             f"clean >= {TARGETS['clean']:.0%}, pairs >= {TARGETS['pairs']:.0%}"]
    lines.append(f"  {'rate':52s} " + " ".join(f"{lab:>10s}" for lab in labels) + f"  {'pooled':>30s}")
    for name, (k, n) in rates(pooled).items():
        cells = " ".join(f"{rows[lab][name][0]:>4d}/{rows[lab][name][1]:<5d}" for lab in labels)
        lines.append(f"  {name:52s} {cells}  {interval(k, n):>30s}")
    return "\n".join(lines)


def markdown_table(per_draw: list[tuple[str, dict[str, Any]]], pooled: dict[str, Any]) -> str:
    """The targets' rates per draw and pooled as two Markdown tables (for docs/loop.md): the
    targets, then recall where the loop can see each effect (beyond the nulls only where that
    differs from the moving rows, i.e. for the effects tested against a null)."""
    labels = [lab for lab, _ in per_draw]
    rows = {lab: rates(s) for lab, s in per_draw}
    pooled_rates = rates(pooled)

    def table(title: str, names: list[str]) -> list[str]:
        head = f"| {title} |" if title else "| |"
        out = [f"{head} " + " | ".join(labels) + " | **pooled** (95 % interval) |", "|---|" + "---|" * (len(labels) + 1)]
        for name in names:
            cells = " | ".join(f"{rows[lab][name][0]}/{rows[lab][name][1]}" for lab in labels)
            out.append(f"| {name} | {cells} | **{interval(*pooled_rates[name])}** |")
        return out

    seen_by_loop = (", det. moving", ", det. beyond null")
    targets = [n for n in pooled_rates if not n.endswith(seen_by_loop)]
    visible = [n for n in pooled_rates if n.endswith(", det. moving")
               or (n.endswith(", det. beyond null") and pooled_rates[n] != pooled_rates[n.replace("beyond null", "moving")])]
    return "\n".join(table("", targets) + [""] + table("recall where the loop can see the effect (information)", visible))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("dirs", nargs="+", type=Path, help="finished campaign directories (run.py --out)")
    p.add_argument("--markdown", action="store_true", help="only the targets' table, in Markdown")
    args = p.parse_args(argv)
    for d in args.dirs:
        if not (d / "results.json").is_file():
            p.error(f"{d}: no results.json (not a finished campaign)")
    if named_twice(args.dirs):
        p.error("a draw is named twice (the same directory, or two with the same name): pooled twice, its cases would narrow the intervals")
    try:
        draws = load(args.dirs)
    except UnreadableDraw as exc:
        p.error(str(exc))
    for label, results in draws:
        if not any(r["status"] == "ok" for r in results):
            p.error(f"{label}: no completed case to pool")
    everything, repeats = distinct(draws)
    pooled = summarize(everything)
    if args.markdown:
        print(markdown_table([(lab, summarize(rs)) for lab, rs in draws], pooled))
        return 0
    print(format_report(everything, pooled))
    print()
    print(f"{repeats} real-data cases repeat an earlier draw's experiment (the same runs and planted term) and are pooled once.")
    print()
    print(pooled_table([(lab, summarize(rs)) for lab, rs in draws], pooled))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Recall of pre-sliding and input delay against the data's resolution, over finished draws.

    python benches/loop_campaign/resolution.py DIR [DIR ...]

Pre-sliding lives within the contact's elastic range and an input delay within the time the
force lags the motion; the data resolve neither below their own grain: the encoder step (the
position the blocks are driven by) and the log's sample period (the timing the loop's alignment
absorbs, the logger's own skew included).  For every case planting one of the two, with the
truth's verdicts (``detectable``, ``detectable_moving``, ``detectable_beyond_null``) and whether the loop named it, this
prints the recall per band of that grain: the contact's widest break displacement in encoder
steps, the delay in log samples.  A real-data experiment that several draws repeat counts once,
as ``pool.py`` pools it.  Information only: the campaign's targets are scored as ``score.py``
scores them.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run as a script: make the package importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    __package__ = "loop_campaign"

from .pool import UnreadableDraw, distinct, load, named_twice  # noqa: E402

#: Band edges: encoder steps for the widest block of a contact, log samples for a delay.
STEP_BANDS = (1.0, 3.0, 10.0)
SAMPLE_BANDS = (1.0, 2.0)


def widest_break(contact: dict[str, Any]) -> float | None:
    """The contact's widest break displacement (m or rad); ``None`` for a contact without one."""
    model = contact.get("model")
    if model == "maxwell":
        return max(w / k for k, w in zip(contact["k"], contact["w"]))
    if model == "gms":
        return max(contact["fc"] * a / k for k, a in zip(contact["k"], contact["alpha"]))
    if model == "lugre":
        return contact["fc"] / contact["sigma0"]
    return None


def band(x: float, edges: tuple[float, ...]) -> str:
    lo = 0.0
    for hi in edges:
        if x < hi:
            return f"{lo:g}-{hi:g}"
        lo = hi
    return f">= {lo:g}"


Row = tuple[str, str, str, bool, bool, bool, bool]


def rows(dirs: list[Path]) -> list[Row]:
    """``(case, effect, band, detectable, detectable on the moving rows, detectable beyond the
    null, named)`` per planted case."""
    out = []
    for r in distinct(load(dirs))[0]:
        spec, truth = r["spec"], r.get("truth", {}).get("effects", {})
        if r["status"] != "ok" or spec is None:
            continue
        for e in spec["effects"]:
            t = truth.get(e["name"])
            if t is None:
                continue
            if e["name"] == "presliding_hysteresis":
                brk = widest_break(spec["rig"]["contact"]) if "rig" in spec else None  # a real run's contact is unknown
                if brk is None:
                    continue
                where = band(brk / spec["rig"]["quant"], STEP_BANDS) + " steps"
            elif e["name"] == "input_delay":
                where = band(e["tau"] * r["truth"]["fs"], SAMPLE_BANDS) + " samples"
            else:
                continue
            out.append((r["id"], e["name"], where, bool(t["detectable"]), bool(t.get("detectable_moving")),
                        bool(t.get("detectable_beyond_null")), e["name"] in r["accepted"]))
    return out


def _rate(xs: list[bool]) -> str:
    return f"{sum(xs)}/{len(xs)}" if xs else "-"


def report(found: list[Row]) -> str:
    lines = [f"{'effect':24s} {'band':16s} {'planted':>8s} {'detectable: named':>18s} {'moving: named':>14s} {'beyond null: named':>19s}"]
    for name in ("presliding_hysteresis", "input_delay"):
        bands = sorted({b for _, n, b, *_ in found if n == name}, key=lambda b: float(b.split()[-2].split("-")[0]))
        for b in bands:
            sel = [x for x in found if x[1] == name and x[2] == b]
            named = [x[6] for x in sel]
            lines.append(f"{name:24s} {b:16s} {len(sel):8d} " + " ".join(
                f"{_rate([n for n, x in zip(named, sel) if x[k]]):>{w}s}" for k, w in ((3, 18), (4, 14), (5, 19))))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("dirs", type=Path, nargs="+", help="finished campaigns (run.py --out)")
    a = p.parse_args(argv)
    missing = [str(d) for d in a.dirs if not (d / "results.json").is_file() or not (d / "cases.json").is_file()]
    if missing:
        print(f"resolution: no results.json and cases.json in {', '.join(missing)}", file=sys.stderr)
        return 2
    if named_twice(a.dirs):
        print("resolution: a draw is named twice (the same directory, or two with the same name): its cases would count twice",
              file=sys.stderr)
        return 2
    try:
        print(report(rows(a.dirs)))
    except UnreadableDraw as exc:
        print(f"resolution: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

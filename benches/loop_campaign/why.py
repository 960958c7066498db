"""Why a finished campaign's misses were missed and its false effects named: the loop's own steps.

    python benches/loop_campaign/why.py DIR                  # every miss and false effect
    python benches/loop_campaign/why.py DIR --effect input_delay
    python benches/loop_campaign/why.py DIR --coulomb 2      # steps moving the Coulomb level beyond x2 (or below 1/2)

For each planted effect detectable by the campaign's truth that the loop did not name, the
truth's gains (all rows, moving rows, beyond the loop's null) and every step the loop tested for
that effect (round, held-out gain, t, p against the round's level, the reason); for each false
effect, the step that accepted it.  ``--coulomb R`` lists instead every tested step whose
baseline Coulomb level ratio (``evidence.baseline_parameters.Fc.ratio``) lies beyond ``R`` or
below ``1 / R``: the steps the plausibility guard on that level can decide.  Reads ``DIR/<id>/``
as ``run.py`` and ``rerun.py`` write it (``result.json`` with the truth, ``loop.json``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run as a script: make the package importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    __package__ = "loop_campaign"

from .score import false_effects  # noqa: E402


def _step_line(s: dict[str, Any], width: int) -> str:
    ev = s["evidence"]
    mark = "+" if s["accepted"] else "-"
    return (f"   r{s['round']} {mark} gain {ev.get('validation_gain')} t {ev.get('t_heldout')} p {ev.get('p_heldout')} "
            f"level {ev.get('level')}: {s['reason'][:width]}")


def cases(src: Path):
    """(id, result, loop JSON) of every completed case under ``src`` (the truth is the result's)."""
    for d in sorted(p for p in src.iterdir() if (p / "loop.json").exists() and (p / "result.json").exists()):
        yield d.name, json.loads((d / "result.json").read_text()), json.loads((d / "loop.json").read_text())


def misses_and_false(src: Path, effect: str | None, width: int) -> None:
    for cid, res, loop in cases(src):
        for name, v in res.get("truth", {}).get("effects", {}).items():
            if not v.get("detectable") or name in res["accepted"] or (effect and name != effect):
                continue
            print(f"== {cid}: missed {name} (true gain {v['gain']:.3f}, moving {v.get('gain_moving', float('nan')):.3f}, "
                  f"beyond the null {v.get('gain_beyond_null', float('nan')):.3f}); named {res['accepted']}")
            for s in loop["steps"]:
                if s["effect"] == name:
                    print(_step_line(s, width))
        for name in false_effects(res):
            if effect and name != effect:
                continue
            print(f"== {cid}: FALSE {name}; planted {res['planted']}")
            for s in loop["steps"]:
                if s["effect"] == name and s["accepted"]:
                    print(_step_line(s, width))


def coulomb_steps(src: Path, ratio: float, width: int) -> None:
    n = 0
    for cid, _, loop in cases(src):
        for s in loop["steps"]:
            r = s["evidence"].get("baseline_parameters", {}).get("Fc", {}).get("ratio")
            if r is None:
                continue
            n += 1
            if r > ratio or r < 1.0 / ratio:
                print(f"{cid}: r{s['round']} {s['effect']} {'accepted' if s['accepted'] else 'refused'}, Coulomb level x{r}: {s['reason'][:width]}")
    print(f"({n} tested steps report the level)")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("src", type=Path, help="a finished campaign's --out")
    p.add_argument("--effect", default=None, help="only this catalogue effect")
    p.add_argument("--coulomb", type=float, default=None, metavar="R", help="list the steps moving the Coulomb level beyond R (> 1)")
    p.add_argument("--width", type=int, default=300, help="characters of each reason shown")
    args = p.parse_args(argv)
    if not args.src.is_dir():
        p.error(f"{args.src} is not a campaign's output folder")
    if args.coulomb is not None:
        if not args.coulomb > 1.0:
            p.error("--coulomb must be > 1")
        coulomb_steps(args.src, args.coulomb, args.width)
    else:
        misses_and_false(args.src, args.effect, args.width)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""``gmsfric identify {static-map, presliding, plant}``: identification from measurement files."""

from __future__ import annotations

import argparse
import sys

from ..errors import DataError
from ..io import load_columns, read_table
from ..results import write_figures


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", metavar="FILE", help="CSV with a header row, or MATLAB .mat")
    p.add_argument("--json", metavar="OUT", help="write the parameters with standard errors as JSON")
    p.add_argument("--plot", metavar="DIR", help="save the figures (PNG) in DIR")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = subparsers.add_parser("identify", help="identify friction / plant parameters from a measurement file", description=__doc__)
    sub = p.add_subparsers(dest="what", metavar="WHAT", required=True)

    s = sub.add_parser("static-map", help="static friction map (eq. 2) from steady points or a raw constant-velocity run")
    _common(s)
    s.add_argument("--velocity", metavar="COL", help="column of steady velocities (table mode)")
    s.add_argument("--force", metavar="COL", required=True, help="column of (average) friction forces")
    s.add_argument("--time", metavar="COL", help="time column (raw-run mode)")
    s.add_argument("--position", metavar="COL", help="position column (raw-run mode)")
    s.add_argument("--per-direction", action="store_true", help="also fit each direction on its own")
    s.add_argument("--bootstrap", type=int, default=0, metavar="N", help="bootstrap resamples for a second standard error")
    s.add_argument("--velocity-unit", default="m/s")
    s.add_argument("--force-unit", default="N")
    s.set_defaults(func=_static_map)

    q = sub.add_parser("presliding", help="GMS blocks k_i, w_i from a virgin-curve test (small and large sinusoids)")
    _common(q)
    q.add_argument("--time", metavar="COL", required=True)
    q.add_argument("--position", metavar="COL", required=True)
    q.add_argument("--force", metavar="COL", required=True)
    q.add_argument("--blocks", type=int, metavar="N", help="number of blocks (default: chosen by BIC)")
    q.add_argument("--max-blocks", type=int, default=6, metavar="N")
    q.add_argument("--no-refine", action="store_true", help="stop at the virgin-curve fit")
    q.add_argument("--position-unit", default="m")
    q.add_argument("--force-unit", default="N")
    q.add_argument("--time-unit", default="s")
    q.set_defaults(func=_presliding)

    r = sub.add_parser("plant", help="plant A/(s^2+Bs+C) e^{-s tau} from a band-limited random excitation")
    _common(r)
    r.add_argument("--time", metavar="COL", required=True)
    r.add_argument("--input", metavar="COL", required=True, help="drive command column")
    r.add_argument("--output", metavar="COL", required=True, help="position column")
    r.add_argument("--excitation", metavar="COL", help="external excitation (closed-loop data)")
    r.add_argument("--fmin", type=float, default=0.0)
    r.add_argument("--fmax", type=float, default=float("inf"))
    r.add_argument("--nperseg", type=int)
    r.add_argument("--no-zoh", action="store_true", help="do not model the zero-order hold (lump it into the delay)")
    r.add_argument("--time-unit", default="s")
    r.add_argument("--input-unit", default="V")
    r.add_argument("--output-unit", default="m")
    r.add_argument("--force-gain", type=float, metavar="G",
                   help="force per input unit (motor constant; not identifiable from an FRF): needed for the JSON's model to be loadable as a Plant")
    r.add_argument("--force-gain-unit", metavar="UNIT", help="unit of --force-gain (default N per --input-unit, N m per input unit for an angle output)")
    r.set_defaults(func=_plant)


def _finish(res, args: argparse.Namespace) -> int:  # type: ignore[no-untyped-def]
    print(res.table())
    extra = {k: v for k, v in res.info.items() if isinstance(v, (int, float, str)) and not isinstance(v, bool)}
    if extra:
        print("  " + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in extra.items()))
    if args.json:
        res.to_json(args.json)
        print(f"wrote {args.json}")
    if args.plot:
        for path in write_figures(res.plot(), args.plot):
            print(f"wrote {path}")
    return 0


def _static_map(args: argparse.Namespace) -> int:
    from .static_map import fit_static_map, fit_static_map_from_run

    table = read_table(args.file)
    raw = args.time is not None or args.position is not None
    if raw and args.velocity is not None:
        raise DataError("give either --velocity (steady points) or --time and --position (raw run), not both")
    if raw:
        if args.time is None or args.position is None:
            raise DataError("a raw run needs both --time and --position (and --force)")
        cols = load_columns(table, {"time": args.time, "position": args.position, "force": args.force}, min_samples=50)
        res = fit_static_map_from_run(cols["time"], cols["position"], cols["force"], per_direction=args.per_direction, bootstrap=args.bootstrap,
                                      velocity_unit=args.velocity_unit, force_unit=args.force_unit, progress=not args.quiet)
    else:
        if args.velocity is None:
            raise DataError("give --velocity COL (steady points) or --time COL --position COL (raw run)")
        cols = load_columns(table, {"velocity": args.velocity, "force": args.force}, min_samples=2)
        res = fit_static_map(cols["velocity"], cols["force"], per_direction=args.per_direction, bootstrap=args.bootstrap,
                             velocity_unit=args.velocity_unit, force_unit=args.force_unit, progress=not args.quiet)
    return _finish(res, args)


def _presliding(args: argparse.Namespace) -> int:
    from .presliding import fit_presliding

    cols = load_columns(args.file, {"time": args.time, "position": args.position, "force": args.force}, min_samples=50)
    res = fit_presliding(cols["time"], cols["position"], cols["force"], n_blocks=args.blocks, max_blocks=args.max_blocks, refine=not args.no_refine,
                         position_unit=args.position_unit, force_unit=args.force_unit, time_unit=args.time_unit, progress=not args.quiet)
    return _finish(res, args)


def _plant(args: argparse.Namespace) -> int:
    from .frf import estimate_frf, fit_plant

    mapping = {"time": args.time, "input": args.input, "output": args.output}
    if args.excitation:
        mapping["excitation"] = args.excitation
    cols = load_columns(args.file, mapping, min_samples=256)
    frf = estimate_frf(cols["time"], cols["input"], cols["output"], excitation=cols.get("excitation"), nperseg=args.nperseg)
    res = fit_plant(frf, fmin=args.fmin, fmax=args.fmax, zoh=not args.no_zoh, time_unit=args.time_unit, input_unit=args.input_unit, output_unit=args.output_unit,
                    force_gain=args.force_gain, force_gain_unit=args.force_gain_unit)
    return _finish(res, args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(0)

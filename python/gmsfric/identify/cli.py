"""``gmsfric identify {static-map, presliding, plant}``: identification from measurement files;
``gmsfric paper``: the paper's identification replayed on the virtual rig."""

from __future__ import annotations

import argparse
from typing import Any

from ..cli import Run, declare_files, int_at_least, non_negative_float, non_negative_int, positive_float, positive_int, positive_or_inf
from ..errors import DataError
from ..io import load_columns, read_table
from .results import IdentificationResult


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", metavar="FILE", help="CSV with a header row, or MATLAB .mat")
    p.add_argument("--json", metavar="OUT", help="write the parameters with standard errors, and the SI model document, as JSON")
    p.add_argument("--plot", metavar="DIR", help="save the figures (PNG) in DIR")
    declare_files(p, inputs=("file",), outputs=("json",), output_dirs=("plot",))


def register(subparsers: Any) -> None:
    """Add the ``identify`` command (three subcommands) and the ``paper`` command."""
    p = subparsers.add_parser("identify", help="identify friction / plant parameters from a measurement file",
                              description="Identification from measurement files: static map, pre-sliding blocks, plant.")
    sub = p.add_subparsers(dest="what", metavar="WHAT", required=True)

    s = sub.add_parser("static-map", help="static friction map (eq. 2) from steady points or a raw constant-velocity run")
    _common(s)
    s.add_argument("--velocity", metavar="COL", help="column of steady velocities (table mode)")
    s.add_argument("--force", metavar="COL", required=True, help="column of (average) friction forces")
    s.add_argument("--time", metavar="COL", help="time column (raw-run mode)")
    s.add_argument("--position", metavar="COL", help="position column (raw-run mode)")
    s.add_argument("--per-direction", action="store_true", help="also fit each direction on its own")
    s.add_argument("--bootstrap", type=non_negative_int, default=0, metavar="N", help="bootstrap resamples for a second standard error")
    s.add_argument("--velocity-unit", default="m/s", help="unit of the velocities (raw run: position unit / time unit), e.g. mm/s, rad/s")
    s.add_argument("--force-unit", default="N", help="unit of the forces, e.g. N, mN, N m (rotary)")
    s.set_defaults(func=_static_map)

    q = sub.add_parser("presliding", help="GMS blocks k_i, w_i from a virgin-curve test (small and large sinusoids)")
    _common(q)
    q.add_argument("--time", metavar="COL", required=True)
    q.add_argument("--position", metavar="COL", required=True)
    q.add_argument("--force", metavar="COL", required=True)
    q.add_argument("--blocks", type=positive_int, metavar="N", help="number of blocks (default: chosen by BIC)")
    q.add_argument("--max-blocks", type=positive_int, default=6, metavar="N", help="most blocks BIC tries (default 6)")
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
    r.add_argument("--fmin", type=non_negative_float, default=0.0, help="lower end of the fitted band (frequency in 1/time unit)")
    r.add_argument("--fmax", type=positive_or_inf, default=float("inf"), help="upper end of the fitted band")
    r.add_argument("--nperseg", type=int_at_least(16), help="Welch segment length (samples, >= 16)")
    r.add_argument("--no-zoh", action="store_true", help="do not model the zero-order hold (lump it into the delay)")
    r.add_argument("--time-unit", default="s")
    r.add_argument("--input-unit", default="V")
    r.add_argument("--output-unit", default="m")
    r.add_argument("--force-gain", type=positive_float, metavar="G",
                   help="force per input unit (motor constant; not identifiable from an FRF): needed for the JSON's model to be loadable as a Plant")
    r.add_argument("--force-gain-unit", metavar="UNIT", help="unit of --force-gain (default N per --input-unit, N m per input unit for an angle output)")
    r.set_defaults(func=_plant)
    _register_paper(subparsers)


def _finish(res: IdentificationResult, args: argparse.Namespace, run: Run, columns: dict[str, Any], units: dict[str, str]) -> int:
    print(res.table())
    extra = {k: v for k, v in res.info.items() if isinstance(v, (int, float, str)) and not isinstance(v, bool)}
    if extra:
        print("  " + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in extra.items()))
    res.provenance = run.provenance(columns=columns, units=units)
    if args.json:
        run.write_json(args.json, res)
    if args.plot:
        run.write_figures(args.plot, res.plot())
    return 0


def _static_map(args: argparse.Namespace, run: Run) -> int:
    from .static_map import fit_static_map, fit_static_map_from_run, static_map_units

    static_map_units(args.velocity_unit, args.force_unit)
    raw = args.time is not None or args.position is not None
    if raw and args.velocity is not None:
        raise DataError("give either --velocity (steady points) or --time and --position (raw run), not both")
    if raw and (args.time is None or args.position is None):
        raise DataError("a raw run needs both --time and --position (and --force)")
    if not raw and args.velocity is None:
        raise DataError("give --velocity COL (steady points) or --time COL --position COL (raw run)")
    table = read_table(args.file)
    units = {"velocity": args.velocity_unit, "force": args.force_unit}
    if raw:
        columns = {"time": args.time, "position": args.position, "force": args.force}
        cols = load_columns(table, columns, min_samples=50)
        res = fit_static_map_from_run(cols["time"], cols["position"], cols["force"], per_direction=args.per_direction, bootstrap=args.bootstrap,
                                      velocity_unit=args.velocity_unit, force_unit=args.force_unit, progress=run.progress)
    else:
        columns = {"velocity": args.velocity, "force": args.force}
        cols = load_columns(table, columns, min_samples=2)
        res = fit_static_map(cols["velocity"], cols["force"], per_direction=args.per_direction, bootstrap=args.bootstrap,
                             velocity_unit=args.velocity_unit, force_unit=args.force_unit, progress=run.progress)
    return _finish(res, args, run, columns, units)


def _presliding(args: argparse.Namespace, run: Run) -> int:
    from .presliding import fit_presliding, presliding_units

    presliding_units(args.position_unit, args.force_unit, args.time_unit)
    columns = {"time": args.time, "position": args.position, "force": args.force}
    cols = load_columns(args.file, columns, min_samples=50)
    res = fit_presliding(cols["time"], cols["position"], cols["force"], n_blocks=args.blocks, max_blocks=args.max_blocks, refine=not args.no_refine,
                         position_unit=args.position_unit, force_unit=args.force_unit, time_unit=args.time_unit, progress=run.progress)
    return _finish(res, args, run, columns, {"time": args.time_unit, "position": args.position_unit, "force": args.force_unit})


def _plant(args: argparse.Namespace, run: Run) -> int:
    from .frf import estimate_frf, fit_plant, plant_units

    _, fg_unit = plant_units(args.time_unit, args.input_unit, args.output_unit, args.force_gain_unit)
    if args.fmin >= args.fmax:
        raise DataError(f"--fmin {args.fmin:g} must be below --fmax {args.fmax:g}")
    columns = {"time": args.time, "input": args.input, "output": args.output, "excitation": args.excitation}
    cols = load_columns(args.file, {k: v for k, v in columns.items() if v is not None}, min_samples=256)
    frf = estimate_frf(cols["time"], cols["input"], cols["output"], excitation=cols.get("excitation"), nperseg=args.nperseg)
    res = fit_plant(frf, fmin=args.fmin, fmax=args.fmax, zoh=not args.no_zoh, time_unit=args.time_unit, input_unit=args.input_unit, output_unit=args.output_unit,
                    force_gain=args.force_gain, force_gain_unit=args.force_gain_unit)
    units = {"time": args.time_unit, "input": args.input_unit, "output": args.output_unit}
    if args.force_gain is not None:
        units["force_gain"] = fg_unit
    return _finish(res, args, run, columns, units)


def _register_paper(subparsers: Any) -> None:
    from . import paper

    p = subparsers.add_parser("paper", help="replay the paper's identification on the virtual rig (true vs identified)", description=paper.__doc__)
    p.add_argument("--plot", "--out", dest="out", metavar="DIR", help="save the figures (Figs. 3-7, 10-13 equivalents) in DIR")
    p.add_argument("--json", metavar="OUT", help="write the tables and the identified models (gmsfric_model) as JSON")
    p.add_argument("--seed", type=non_negative_int, default=0)
    declare_files(p, outputs=("json",), output_dirs=("out",))
    p.set_defaults(func=_paper)


def _paper(args: argparse.Namespace, run: Run) -> int:
    from .paper import ReplaySettings, replay_paper

    rep = replay_paper(ReplaySettings(seed=args.seed), progress=run.progress)
    print("gmsfric paper: the paper's experiments replayed on the virtual rig (seed %d)" % args.seed)
    print("printed = the paper's number, true = the rig (PaperReading defaults), z = (identified - true) / stderr\n")
    print(rep.table())
    print(f"GMS blocks: {rep.presliding.info['n_blocks']} (the paper's choice; ReplaySettings(n_blocks=None) lets BIC choose)")
    print("Eq. 1 and the static-model Table 3 are biased on purpose: the rig's friction is GMS, whose pre-sliding")
    print("stiffness and damping a linear fit (or a static map) cannot represent; the GMS revision recovers the mechanics.")
    print(f"static-map plateaus used: {rep.static_map.info.get('n_plateaus')} (rejected {rep.static_map.info.get('n_rejected')})")
    rep.provenance = run.provenance(seed=args.seed)
    if args.json:
        run.write_json(args.json, rep)
    if args.out:
        run.write_figures(args.out, rep.plot())
    return 0

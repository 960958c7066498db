"""``gmsfric identify {static-map, presliding, plant}``: identification from measurement files;
``gmsfric paper``: the paper's identification replayed on the virtual rig."""

from __future__ import annotations

import argparse
import sys
import warnings
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import units as _units
from ..cli import Run, declare_files, int_at_least, non_negative_float, non_negative_int, positive_float, positive_int, positive_or_inf, units_as_flags
from ..errors import DataError, FitWarning
from ..io import Table, load_columns, read_table
from .diagnostics import format_block
from .results import IdentificationResult


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", metavar="FILE", help="CSV with a header row, or MATLAB .mat (a struct field as log.q, a matrix column as q(:,3))")
    p.add_argument("--json", metavar="OUT", help="write the parameters with standard errors, and the SI model document, as JSON ('-' = stdout, "
                   "the table then goes to stderr)")
    p.add_argument("--plot", metavar="DIR", help="save the figures (PNG) in DIR")
    declare_files(p, inputs=("file",), outputs=("json",), output_dirs=("plot",), stdout=("json",))


def _force_source(p: argparse.ArgumentParser) -> None:
    """``--force COL`` or, as in ``gmsfric loop``, ``--command COL --gain G``."""
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--force", metavar="COL", help="force column (in --force-unit)")
    g.add_argument("--command", dest="command_col", metavar="COL", help="drive command column: force = gain x command (needs --gain)")
    p.add_argument("--gain", metavar="G", help="drive gain, N per command unit: a number or a scalar name in the file")
    p.add_argument("--force-unit", default="N", help="unit of the force column and of the reported forces, e.g. N, mN, N m (rotary)")


def register(subparsers: Any) -> None:
    """Add the ``identify`` command (three subcommands) and the ``paper`` command."""
    p = subparsers.add_parser("identify", help="identify friction / plant parameters from a measurement file",
                              description="Identification from measurement files: static map, pre-sliding blocks, plant.  The data are "
                                          "converted to SI once (--*-unit); the tables and the JSON parameters are in the file's units, "
                                          "the JSON's model document in SI.")
    sub = p.add_subparsers(dest="what", metavar="WHAT", required=True)

    s = sub.add_parser("static-map", help="static friction map (eq. 2) from steady points or a raw constant-velocity run")
    _common(s)
    s.add_argument("--velocity", metavar="COL", help="column of steady velocities (table mode)")
    _force_source(s)
    s.add_argument("--time", metavar="COL", help="time column (raw-run mode)")
    s.add_argument("--position", metavar="COL", help="position column (raw-run mode)")
    s.add_argument("--per-direction", action="store_true", help="also fit each direction on its own")
    s.add_argument("--bootstrap", type=non_negative_int, default=0, metavar="N", help="bootstrap resamples for a second standard error")
    s.add_argument("--velocity-unit", default=None,
                   help="table mode: unit of the velocity column (default m/s); raw run: only the unit the velocities are reported in "
                   "(default position unit / time unit), the data are read in --position-unit and --time-unit")
    s.add_argument("--position-unit", default=None, help="unit of the position column (raw run, default m), e.g. mm, um, rad, deg")
    s.add_argument("--time-unit", default="s", help="unit of the time column (raw run), e.g. s, ms")
    s.set_defaults(func=_static_map)

    q = sub.add_parser("presliding", help="GMS blocks k_i, w_i from a record with reversals (virgin-curve test or hysteresis)")
    _common(q)
    q.add_argument("--time", metavar="COL", required=True)
    q.add_argument("--position", metavar="COL", required=True)
    _force_source(q)
    q.add_argument("--blocks", type=positive_int, metavar="N", help="number of blocks (default: chosen by BIC)")
    q.add_argument("--max-blocks", type=positive_int, default=6, metavar="N", help="most blocks BIC tries (default 6)")
    q.add_argument("--no-refine", action="store_true", help="stop at the virgin-curve fit")
    q.add_argument("--position-unit", default="m")
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
    r.add_argument("--no-zoh", action="store_true", help="fit the continuous response and lump the zero-order hold into the delay")
    r.add_argument("--time-unit", default="s")
    r.add_argument("--input-unit", default="V")
    r.add_argument("--output-unit", default="m")
    r.add_argument("--force-gain", type=positive_float, metavar="G",
                   help="force per input unit (motor constant; not identifiable from an FRF): needed for the JSON's model to be loadable as a Plant")
    r.add_argument("--force-gain-unit", metavar="UNIT", help="unit of --force-gain (default N per --input-unit, N m per input unit for an angle output)")
    r.set_defaults(func=_plant)
    _register_paper(subparsers)


def _finish(res: IdentificationResult, args: argparse.Namespace, run: Run, columns: dict[str, Any], units: dict[str, str], **extra: Any) -> int:
    out = sys.stderr if args.json == "-" else sys.stdout  # stdout carries the JSON alone
    print(res.table(), file=out)
    info = {k: v for k, v in res.info.items() if isinstance(v, (int, float, str)) and not isinstance(v, bool)}
    if info:
        print("  " + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in info.items()), file=out)
    block = format_block(res.diagnostics)
    if block:
        print(block, file=out)
    res.provenance = run.provenance(columns=columns, units=units, **extra)
    if args.json:
        run.write_json(args.json, res)
    if args.plot:
        run.write_figures(args.plot, res.plot())
    return 0


def _forces(args: argparse.Namespace, table: Table, cols: dict[str, NDArray[np.float64]]) -> NDArray[np.float64]:
    """The force column in ``--force-unit``: read, or ``gain x command`` (the gain in N per
    command unit, as in ``gmsfric loop``)."""
    if args.command_col is None:
        return cols["force"]
    gain = table.number(args.gain, role="gain")
    if gain == 0 or not np.isfinite(gain):
        raise DataError(f"{table.source}: drive gain {args.gain!r} is {gain}: it must be a non-zero finite number")
    return gain * cols["command"] / _units.factor(args.force_unit, "force", name="--force-unit")  # type: ignore[no-any-return]


def _check_force_source(args: argparse.Namespace) -> None:
    if args.command_col is not None and args.gain is None:
        raise DataError("--command needs --gain (a number or a scalar name in the file)")
    if args.command_col is None and args.gain is not None:
        raise DataError("--gain only goes with --command")


def _static_map(args: argparse.Namespace, run: Run) -> int:
    from .static_map import fit_static_map, fit_static_map_from_run, static_map_units

    _check_force_source(args)
    raw = args.time is not None or args.position is not None
    if raw and args.velocity is not None:
        raise DataError("give either --velocity (steady points) or --time and --position (raw run), not both")
    if raw and (args.time is None or args.position is None):
        raise DataError("a raw run needs both --time and --position (and --force or --command)")
    if not raw and args.velocity is None:
        raise DataError("give --velocity COL (steady points) or --time COL --position COL (raw run)")
    if not raw and args.position_unit is not None:
        raise DataError("--position-unit goes with a raw run (--time and --position)")
    force_col = {"force": args.force} if args.command_col is None else {"command": args.command_col}
    if raw:
        # The data's units come only from the data-unit flags (position default m, time default
        # s); --velocity-unit only chooses the unit velocities are reported in.
        pos_unit = "m" if args.position_unit is None else args.position_unit
        _units.check(args.time_unit, "time", name="--time-unit")
        rotary = _units.is_rotary(pos_unit, "position", name="--position-unit")
        vel_unit = args.velocity_unit or _units.ratio(pos_unit, args.time_unit)
        if _units.is_rotary(vel_unit, "velocity", name="--velocity-unit") != rotary:
            raise _units.UnitError(f"--velocity-unit {vel_unit!r} (the reporting unit) and --position-unit {pos_unit!r} (the data's unit"
                                   f"{', the default' if args.position_unit is None else ''}) are of different axes: "
                                   "an angle is never a length; give both for the same axis")
        _units.check(args.force_unit, "force", rotary=rotary, name="--force-unit")
        units = {"time": args.time_unit, "force": args.force_unit, "position": pos_unit, "velocity": vel_unit}
        table = read_table(args.file)
        columns = {"time": args.time, "position": args.position, **force_col}
        with units_as_flags():
            cols = load_columns(table, columns, min_samples=50, declared_units=_declared(units, "time", "position", "force"))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FitWarning)
            res = fit_static_map_from_run(cols["time"], cols["position"], _forces(args, table, cols), per_direction=args.per_direction,
                                          bootstrap=args.bootstrap, position_unit=pos_unit, time_unit=args.time_unit,
                                          velocity_unit=vel_unit, force_unit=args.force_unit, progress=run.progress)
    else:
        vel_unit = args.velocity_unit or "m/s"
        rotary = _units.is_rotary(vel_unit, "velocity", name="--velocity-unit")
        _units.check(args.force_unit, "force", rotary=rotary, name="--force-unit")
        with units_as_flags():
            static_map_units(vel_unit, args.force_unit)
        units = {"velocity": vel_unit, "force": args.force_unit}
        table = read_table(args.file)
        columns = {"velocity": args.velocity, **force_col}
        with units_as_flags():
            cols = load_columns(table, columns, min_samples=2, declared_units=_declared(units, "velocity", "force"))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FitWarning)
            res = fit_static_map(cols["velocity"], _forces(args, table, cols), per_direction=args.per_direction, bootstrap=args.bootstrap,
                                 velocity_unit=vel_unit, force_unit=args.force_unit, progress=run.progress)
    return _finish(res, args, run, columns, units, gain=args.gain)


def _declared(units: dict[str, str], *roles: str) -> dict[str, tuple[str, str, str]]:
    """The units the flags declare for ``roles``, as ``load_columns`` checks them against a file's
    units row: role -> (unit, quantity, argument)."""
    return {role: (units[role], role, f"{role}_unit") for role in roles}


def _presliding(args: argparse.Namespace, run: Run) -> int:
    from .presliding import fit_presliding, presliding_units

    _check_force_source(args)
    with units_as_flags():
        presliding_units(args.position_unit, args.force_unit, args.time_unit)
    table = read_table(args.file)
    columns = {"time": args.time, "position": args.position, **({"force": args.force} if args.command_col is None else {"command": args.command_col})}
    declared = {"time": args.time_unit, "position": args.position_unit, "force": args.force_unit}
    with units_as_flags():
        cols = load_columns(table, columns, min_samples=50, declared_units=_declared(declared, "time", "position", "force"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        res = fit_presliding(cols["time"], cols["position"], _forces(args, table, cols), n_blocks=args.blocks, max_blocks=args.max_blocks,
                             refine=not args.no_refine, position_unit=args.position_unit, force_unit=args.force_unit, time_unit=args.time_unit,
                             progress=run.progress)
    return _finish(res, args, run, columns, {"time": args.time_unit, "position": args.position_unit, "force": args.force_unit}, gain=args.gain)


def _plant(args: argparse.Namespace, run: Run) -> int:
    from .frf import estimate_frf, fit_plant, plant_units

    with units_as_flags():
        _, fg_unit = plant_units(args.time_unit, args.input_unit, args.output_unit, args.force_gain_unit)
    if args.fmin >= args.fmax:
        raise DataError(f"--fmin {args.fmin:g} must be below --fmax {args.fmax:g}")
    columns = {"time": args.time, "input": args.input, "output": args.output, "excitation": args.excitation}
    declared = {"time": (args.time_unit, "time", "time_unit"), "input": (args.input_unit, "drive", "input_unit"),
                "output": (args.output_unit, "position", "output_unit")}
    with units_as_flags():
        cols = load_columns(args.file, {k: v for k, v in columns.items() if v is not None}, min_samples=256, declared_units=declared)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        frf = estimate_frf(cols["time"], cols["input"], cols["output"], excitation=cols.get("excitation"), nperseg=args.nperseg)
        res = fit_plant(frf, fmin=args.fmin, fmax=args.fmax, zoh=not args.no_zoh, time_unit=args.time_unit, input_unit=args.input_unit,
                        output_unit=args.output_unit, force_gain=args.force_gain, force_gain_unit=args.force_gain_unit)
    units = {"time": args.time_unit, "input": args.input_unit, "output": args.output_unit}
    if args.force_gain is not None:
        units["force_gain"] = fg_unit
    return _finish(res, args, run, columns, units)


def _register_paper(subparsers: Any) -> None:
    from . import paper

    p = subparsers.add_parser("paper", help="replay the paper's identification on the virtual rig (true vs identified)", description=paper.__doc__)
    p.add_argument("--plot", "--out", dest="out", metavar="DIR", help="save the figures (Figs. 3-7, 10-13 equivalents) in DIR")
    p.add_argument("--json", metavar="OUT", help="write the tables and the identified models (gmsfric_model) as JSON ('-' = stdout)")
    p.add_argument("--seed", type=non_negative_int, default=0)
    declare_files(p, outputs=("json",), output_dirs=("out",), stdout=("json",))
    p.set_defaults(func=_paper)


def _paper(args: argparse.Namespace, run: Run) -> int:
    from .paper import ReplaySettings, replay_paper

    rep = replay_paper(ReplaySettings(seed=args.seed), progress=run.progress)
    out = sys.stderr if args.json == "-" else sys.stdout  # stdout carries the JSON alone
    print("gmsfric paper: the paper's experiments replayed on the virtual rig (seed %d)" % args.seed, file=out)
    print("printed = the paper's number, true = the rig (PaperReading defaults), z = (identified - true) / stderr\n", file=out)
    print(rep.table(), file=out)
    print(f"GMS blocks: {rep.presliding.info['n_blocks']} (the paper's choice; ReplaySettings(n_blocks=None) lets BIC choose)", file=out)
    print("Eq. 1 and the static-model Table 3 are biased on purpose: the rig's friction is GMS, whose pre-sliding", file=out)
    print("stiffness and damping a linear fit (or a static map) cannot represent; the GMS revision recovers the mechanics.", file=out)
    print(f"static-map plateaus used: {rep.static_map.info.get('n_plateaus')} (rejected {rep.static_map.info.get('n_rejected')})", file=out)
    rep.provenance = run.provenance(seed=args.seed)
    if args.json:
        run.write_json(args.json, rep)
    if args.out:
        run.write_figures(args.out, rep.plot())
    return 0

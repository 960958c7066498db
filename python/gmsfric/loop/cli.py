"""``gmsfric loop``: fit, study the residual, add justified effects, report before/after."""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
import warnings
from pathlib import Path
from typing import Any

from .. import units as _units
from ..cli import Run, declare_files, fraction, positive_float, units_as_flags
from ..errors import DataError, FitWarning
from ..identify.diagnostics import emit, format_block
from ..io import read_table
from ..system import Cascade
from .checks import check_closed_loop
from .closedloop import closed_loop_report
from .data import load_axis_data
from .idim import Preprocessing
from .select import LoopConfig, run_loop
from .simulation import add_simulation


def register(subparsers: Any) -> None:
    """Add the ``loop`` subcommand."""
    p = subparsers.add_parser(
        "loop",
        help="identify an axis from measured data: baseline, residual analysis, justified effects, before/after",
        description="Fit the EMPS-style inverse model, trace the residual to missing effects and add them one at a time "
        "while held-out data confirm it.  Units: time s, position m, force N (see --*-unit).",
    )
    p.add_argument("est", metavar="EST", help="estimation run (.csv with a header row, or .mat: name a struct field as log.q, a matrix column as q(:,3))")
    p.add_argument("--validate", metavar="VAL", help="validation run; without it, part of EST is held out")
    tg = p.add_mutually_exclusive_group(required=True)
    tg.add_argument("--time", metavar="COL")
    tg.add_argument("--sample-rate", type=positive_float, metavar="HZ", help="for a log without a time column: its rate, time from 0 "
                    "in steps of 1/HZ (the runs' --time-unit is then not used)")
    p.add_argument("--position", required=True, metavar="COL")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--force", metavar="COL", help="force column (in --force-unit): the drive is then the force itself, so the "
                   "closed-loop --kv is in N s/m, --drive-limit in N (N m s/rad, N m on a rotary axis), --disturbance in --force-unit")
    g.add_argument("--command", dest="command_col", metavar="COL", help="drive command column (needs --gain); the closed-loop gains, "
                   "--drive-limit and --disturbance are then in command units")
    p.add_argument("--gain", metavar="G", help="drive gain, N (N m on a rotary axis) per command unit: a number or a scalar name in the file")
    p.add_argument("--time-unit", default="s")
    p.add_argument("--position-unit", default="m")
    p.add_argument("--force-unit", default=None, help="unit of the force column (default N, or N m on a rotary axis)")
    p.add_argument("--json", metavar="OUT", help="write the report as JSON ('-' = stdout, the table then goes to stderr)")
    p.add_argument("--plot", metavar="DIR", help="write figures (PNG) into DIR")
    p.add_argument("--baseline", choices=("reference", "rigid"), default="reference",
                   help="reference: M qdd + Fv qd + Fc sign(qd) + offset (EMPS, default); rigid: without the offset, which becomes a candidate effect")
    p.add_argument("--holdout", type=fraction, default=None, help="fraction of EST held out when there is no --validate (default 0.3; "
                   "refused with --validate)")
    p.add_argument("--cutoff-hz", type=positive_float, default=None,
                   help="position filter cut-off (Hz); default min(100 Hz, fs/10), and below 1 kHz the best of 0.1, 0.2, 0.3 x fs by cross-validation on EST")
    cl = p.add_argument_group("closed-loop simulation (optional: needs a reference and a cascade controller)")
    cl.add_argument("--reference", metavar="COL", help="reference position column (with --kp and --kv)")
    cl.add_argument("--disturbance", metavar="COL", help="input disturbance column of the validation run, added to the controller "
                    "output: command units with --command (e.g. EMPS's pulses_N), --force-unit with --force; needs --validate")
    cl.add_argument("--kp", metavar="K", help="cascade position gain u = kv (kp (r - q) - qdot), in 1/s: number or scalar name")
    cl.add_argument("--kv", metavar="K", help="cascade velocity gain, per m/s (per rad/s on a rotary axis) whatever --position-unit: "
                    "command units per m/s with --command (EMPS: V s/m); with --force the drive is the force, so N s/m "
                    "(N m s/rad); number or scalar name")
    cl.add_argument("--drive-limit", type=positive_float, default=None, help="symmetric drive limit: command units with --command, "
                    "N (N m on a rotary axis) with --force")
    sim = p.add_argument_group("simulation error (optional)")
    sim.add_argument("--fit", choices=("inverse", "simulation"), default="inverse",
                     help="simulation: after the inverse-model selection, refine the baseline and final models by closed-loop "
                     "simulation error on EST (needs --reference --kp --kv); closed_loop then reports the refined models")
    sim.add_argument("--open-loop", action="store_true",
                     help="score both models by open-loop simulation: position from the measured command, RMSE after 20 samples (JSON open_loop)")
    declare_files(p, inputs=("est", "validate"), outputs=("json",), output_dirs=("plot",), stdout=("json",))
    p.set_defaults(func=_loop)


def _check_not_the_estimation_run(est: str, validate: str) -> None:
    """Refuse a validation run that is the estimation run (same file, or the same bytes): its
    "held-out" numbers would be estimation numbers."""
    a, b = Path(est), Path(validate)
    same = os.path.samefile(a, b)
    if not same and a.stat().st_size == b.stat().st_size:
        with a.open("rb") as fa, b.open("rb") as fb:
            same = hashlib.sha256(fa.read()).digest() == hashlib.sha256(fb.read()).digest()
    if same:
        raise DataError(f"--validate {validate} is the estimation run {est} ({'the same file' if os.path.samefile(a, b) else 'identical content'}): "
                        "its numbers would be estimation numbers, not held-out ones; give another run, or leave --validate out to hold out part of EST")


def _loop(args: argparse.Namespace, run: Run) -> int:
    """Run ``gmsfric loop`` (called by the runner of :mod:`gmsfric.cli`)."""
    _units.check(args.time_unit, "time", name="--time-unit")
    rotary = _units.is_rotary(args.position_unit, "position", name="--position-unit")
    if args.force_unit is None:
        args.force_unit = "N m" if rotary else "N"
    _units.check(args.force_unit, "force", rotary=rotary, name="--force-unit")
    if (args.kp is None) != (args.kv is None) or (args.kp is not None and not args.reference):
        raise DataError("the closed-loop simulation needs --reference, --kp and --kv together")
    if args.reference is not None and args.kp is None:
        raise DataError("--reference is only used by the closed-loop simulation: give --kp and --kv with it (or leave it out)")
    if args.holdout is not None and args.validate is not None:
        raise DataError("--holdout goes without --validate: with a validation run nothing of EST is held out")
    if args.disturbance is not None and args.validate is None:
        raise DataError("--disturbance names a column of the validation run: it needs --validate")
    if args.drive_limit is not None and args.kp is None:
        raise DataError("--drive-limit is only used by the closed-loop simulation: give --reference, --kp and --kv with it")
    if args.validate is not None:
        _check_not_the_estimation_run(args.est, args.validate)
    holdout = 0.3 if args.holdout is None else args.holdout
    if args.fit == "simulation" and not (args.reference and args.kp is not None):
        raise DataError("--fit simulation needs the closed-loop simulation: --reference, --kp and --kv")
    if args.command_col is not None and args.gain is None:
        raise DataError("--command needs --gain (a number or a scalar name in the file)")
    if args.force is not None and args.gain is not None:
        raise DataError("--gain only goes with --command")
    if args.sample_rate is not None and args.time_unit != "s":
        raise DataError("--time-unit goes with --time: with --sample-rate the time is in s from the rate")
    common = dict(time=args.time, sample_rate=args.sample_rate, position=args.position, force=args.force, command=args.command_col, gain=args.gain,
                  reference=args.reference, time_unit=args.time_unit, position_unit=args.position_unit, force_unit=args.force_unit)
    est_table = read_table(args.est)
    with units_as_flags():
        est = load_axis_data(est_table, **common)
        val = None if args.validate is None else load_axis_data(args.validate, disturbance=args.disturbance, **common)
    base = ("inertia", "viscous", "coulomb", "offset") if args.baseline == "reference" else ("inertia", "viscous", "coulomb")
    cfg = LoopConfig(preprocessing=Preprocessing(cutoff_hz=args.cutoff_hz), holdout_fraction=holdout, baseline=base, progress=run.progress)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)  # printed under the table instead
        result = run_loop(est, val, cfg)
    ctrl = None
    if args.reference and args.kp is not None and args.kv is not None:
        kp, kv = est_table.number(args.kp, "kp"), est_table.number(args.kv, "kv")
        lim = args.drive_limit
        ctrl = Cascade(kp, kv, -lim if lim else float("-inf"), lim if lim else float("inf"))
        if args.fit != "simulation":
            runs = {"estimation": result.split.est}
            if val is not None:
                runs["validation"] = result.split.val
            result.closed_loop, result.closed_loop_runs = closed_loop_report({"baseline": result.baseline, "final": result.final}, runs, ctrl)
    if args.fit == "simulation" or args.open_loop:
        result = add_simulation(result, ctrl, fit=args.fit == "simulation", open_loop=args.open_loop, progress=run.progress)
    if ctrl is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FitWarning)  # printed under the table instead
            emit(result, check_closed_loop(result, ctrl))
    out = sys.stderr if args.json == "-" else sys.stdout  # stdout carries the JSON alone
    print(result.table(), file=out)
    block = format_block(result.diagnostics)
    if block:
        print(block, file=out)
    columns = {"time": args.time, "position": args.position, "force": args.force, "command": args.command_col, "reference": args.reference,
               "disturbance": args.disturbance}
    result.provenance = run.provenance(columns=columns, units={"time": args.time_unit, "position": args.position_unit, "force": args.force_unit},
                                       gain=args.gain)
    if args.sample_rate is not None:
        result.provenance["sample_rate_hz"] = args.sample_rate
    if args.json:
        run.write_json(args.json, result)
    if args.plot:
        run.write_figures(args.plot, result.plot())
    return 0

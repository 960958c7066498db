"""``gmsfric glitch``: the paper's Section 4.2 scenario, the XY circle test and friction
compensation, as JSON (``--json``) and figures (``--plot``)."""

from __future__ import annotations

import argparse
from typing import Any, Sequence

from .. import presets
from .._validate import allocation
from ..cli import Run, declare_files, finite_float, log, non_negative_float, positive_float
from ..errors import DataError
from ..identify.diagnostics import fraction_at_limit
from ..model_io import load_model
from ..models import GMS, MaxwellSlip, StaticFriction, axis_name
from ..system import Plant
from .compensation import DOB_CUTOFF_HZ
from .results import GlitchStudy
from .scenario import DEFAULT_GAINS, PAPER_STATIC_V_LINEAR, scenario_controller, table3_plant

#: What each option needs, for messages about a file that holds something else.
_NEEDS = {
    "--plant": "a plant with a force gain (`gmsfric identify plant --force-gain G --json`, or a Plant saved with gmsfric.save_model)",
    "--friction": "a static map and/or pre-sliding blocks (`gmsfric identify static-map/presliding --json`, or models saved with gmsfric.save_model)",
}


def _models_in(path: str, option: str) -> tuple[list[Any], bool]:
    """The models of a model file and whether it is a bundle (several named models)."""
    from ..axis import AxisModel

    m = load_model(path)
    if isinstance(m, AxisModel):
        raise DataError(f"`{option}` {path} is an axis model (the JSON of `gmsfric loop`), not what glitch takes: {option} needs {_NEEDS[option]}")
    return (list(m.values()), True) if isinstance(m, dict) else ([m], False)


def _plant_from(path: str | None) -> Plant:
    if path is None:
        return presets.paper_plant()
    models, _ = _models_in(path, "--plant")
    plants = [m for m in models if isinstance(m, Plant)]
    if len(plants) != 1:
        held = ", ".join(sorted({axis_name(m) + " " + type(m).__name__ for m in models})) or "nothing"
        what = "several plants" if plants else f"no plant (it holds: {held})"
        raise DataError(f"`--plant` {path} holds {what}; --plant needs exactly one: {_NEEDS['--plant']}")
    return plants[0]


def _frictions_from(paths: Sequence[str]) -> tuple[StaticFriction, GMS]:
    """The static map and the GMS of the glitch studies from ``--friction`` files.

    A GMS file is used as it is; pre-sliding blocks (a Maxwell-slip model, e.g. from an older
    ``identify presliding`` file) go on a static map's Stribeck curve and viscous term with
    ``c = 1/Vs`` (paper eq. 6).  Given together with a static-map file, the blocks of either go on
    that map.  Without a static map file the paper's is used; without blocks, the paper's.
    Models of a rotary axis (N m, rad) are never mixed with linear ones, the paper's included."""
    static: StaticFriction | None = None
    gms: GMS | None = None
    blocks: tuple[list[float], list[float]] | None = None
    axes: dict[str, str] = {}
    for path in paths:
        models, bundle = _models_in(path, "--friction")
        if bundle:  # e.g. `gmsfric paper --json`: its friction models
            models = [m for m in models if isinstance(m, (StaticFriction, GMS, MaxwellSlip))]
            if not models:
                raise DataError(f"`--friction` {path} holds no friction model; --friction needs {_NEEDS['--friction']}")
        for m in models:
            if isinstance(m, StaticFriction):
                if static is not None:
                    raise DataError(f"`--friction` {path}: a second static map; give one")
                static = m
            elif isinstance(m, (GMS, MaxwellSlip)):
                if blocks is not None:
                    raise DataError(f"`--friction` {path}: a second pre-sliding model; give one")
                gms = m if isinstance(m, GMS) else None
                blocks = (list(m.k), list(m.break_forces if isinstance(m, GMS) else m.w))
            else:
                raise DataError(f"`--friction` {path} holds a {type(m).__name__} ({axis_name(m)} axis); --friction needs {_NEEDS['--friction']}")
            axes[path] = axis_name(m)
    if len(set(axes.values())) > 1:
        raise DataError("`--friction` files of different axes: " + ", ".join(f"{p} is {a}" for p, a in axes.items())
                        + "; an angle is never a length, a torque never a force")
    rotary = "rotary" in axes.values()
    if rotary and (blocks is None or (static is None and gms is None)):
        missing = "pre-sliding blocks" if blocks is None else "a static map"
        raise DataError(f"`--friction` of a rotary axis needs a static map and pre-sliding blocks (or a GMS): {missing} missing, and the "
                        "paper's (the default) are of a linear axis")
    if gms is not None and static is None:
        # a rotary GMS brings its own static map; the paper's is linear
        return (gms.static_map() if gms.rotary else presets.paper_static_friction()), gms
    static = presets.paper_static_friction() if static is None else static
    if blocks is None:
        ref = presets.paper_gms()
        if not paths:
            return static, ref
        return static, GMS(static.stribeck, ref.k, ref.alpha, 1.0 / static.stribeck.vs, static.sigma, ref.slip_law)
    return static, GMS.from_break_forces(blocks[0], blocks[1], 1.0 / static.stribeck.vs, stribeck=static.stribeck, sigma=static.sigma,
                                         rotary=static.rotary)


def _check_one_axis(args: argparse.Namespace, plant: Plant, static: StaticFriction, gms: GMS) -> bool:
    """Whether the studies run a rotary axis; plant and friction must be of one axis."""
    p_axis, f_axis = axis_name(plant), axis_name(static)
    if axis_name(gms) != f_axis:
        raise DataError(f"the static map is of a {f_axis} axis but the pre-sliding blocks of a {axis_name(gms)} one; give models of one axis")
    if p_axis != f_axis:
        plant_src = f"--plant {args.plant}" if args.plant else "the default plant (the paper's, linear)"
        fr_src = "--friction " + " ".join(args.friction) if args.friction else "the default friction (the paper's, linear)"
        raise DataError(f"{plant_src} is of a {p_axis} axis but {fr_src} of a {f_axis} one: an angle is never a length, a torque never a "
                        "force; give the plant and the friction of one axis")
    return p_axis == "rotary"


def register(subparsers: Any) -> None:
    """Add the ``glitch`` command to ``subparsers``."""
    p = subparsers.add_parser(
        "glitch",
        help="quadrant glitches: paper Sec. 4.2 sinusoid, XY circle test, friction feedforward",
        description="Simulate the paper's Section 4.2 scenario (10 mm, 0.01 Hz sinusoid) without friction, with the static "
        "map and with GMS; the XY circle (ballbar) test; and model-based friction feedforward. See docs/glitch.md.",
    )
    p.add_argument("--json", metavar="OUT", help="write the results as JSON to OUT ('-' = stdout)")
    p.add_argument("--plot", metavar="DIR", help="save the figures as PNG in DIR")
    p.add_argument("--plant", metavar="FILE", help="plant model file (`gmsfric identify plant --force-gain G --json`, or gmsfric.save_model); default eq. 1. "
                   "A rotary plant needs rotary --friction files (a static map and blocks): the studies then run in rad and report angles")
    p.add_argument("--table3", action="store_true", help="use Table 3's revised plant per friction model (docs/glitch.md); not with --plant")
    p.add_argument("--friction", metavar="FILE", action="append", default=[], help="friction model file (`gmsfric identify static-map/presliding --json`, or gmsfric.save_model): a static map and/or GMS "
                   "blocks; blocks given with a static map go on its Stribeck curve (c = 1/Vs); repeatable")
    p.add_argument("--amplitude", type=positive_float, default=0.01, help="sinusoid amplitude and circle radius (m; rad on a rotary axis), default 0.01")
    p.add_argument("--frequency", type=positive_float, default=0.01, help="sinusoid / circle frequency (Hz), default 0.01")
    p.add_argument("--kp", type=non_negative_float, default=DEFAULT_GAINS["kp"], help="PID proportional gain (V/m)")
    p.add_argument("--ki", type=non_negative_float, default=DEFAULT_GAINS["ki"], help="PID integral gain (V/(m s))")
    p.add_argument("--kd", type=non_negative_float, default=DEFAULT_GAINS["kd"], help="PID derivative gain (V s/m)")
    p.add_argument("--tf", type=non_negative_float, default=DEFAULT_GAINS["tf"], help="derivative filter time constant (s)")
    p.add_argument("--drive-limit", type=positive_float, default=presets.PaperReading().drive_limit, help="drive limit (V)")
    p.add_argument("--ff-gain", type=finite_float, default=1.0, help="feedforward gain (1 = model force)")
    p.add_argument("--ff-advance", type=finite_float, default=None, help="feedforward time advance (s); default the plant delay")
    p.add_argument("--dt", type=positive_float, default=1e-4, help="simulation step (s), default 1e-4")
    p.add_argument("--static-linear-region", type=non_negative_float, default=PAPER_STATIC_V_LINEAR, metavar="M_S",
                   help="linear-region velocity threshold (m/s) of the \"static\" map and of the static-map feedforward: "
                   "the paper's Simulink reading, default 1e-4 (Simscape's default); 0 = true stiction. The true-stiction map is "
                   "always reported as \"static_stiction\" too")
    p.add_argument("--dob-cutoff", type=positive_float, default=DOB_CUTOFF_HZ, metavar="HZ",
                   help=f"Q-filter cutoff (Hz) of the disturbance observer reported as compensation \"dob\", default {DOB_CUTOFF_HZ:g}")
    declare_files(p, inputs=("plant", "friction"), outputs=("json",), output_dirs=("plot",), stdout=("json",))
    p.set_defaults(func=_glitch)


def _memory_needed(frequency: float, dt: float, plants: Sequence[Plant], lead_deg: float = 55.0) -> float:
    """About how many bytes the three studies hold at once: ~8 float64 series per closed-loop run
    (10 sinusoid, 8 circle and 6 compensation runs) plus the delay line of each run."""
    n_sin = 1.0 / (frequency * dt)
    n_circle = (1.0 + lead_deg / 360.0) / (frequency * dt)
    n_delay = max(p.delay for p in plants) / dt
    return 8.0 * (8 * (16 * n_sin + 8 * n_circle) + 24 * n_delay)


#: Fewest simulation steps per sinusoid period: the reversal metrics need a resolved reversal.
MIN_STEPS_PER_PERIOD = 100

#: Share of samples at the drive limit above which a run is reported as saturated (the circle's
#: start from rest touches the limit for ~0.1 % of its samples: not a saturated study).
SATURATION_TOLERANCE = 0.01


def _check_settings(args: argparse.Namespace) -> None:
    """Refuse settings the studies cannot honour, before any work."""
    if args.table3 and args.plant is not None:
        raise DataError("--table3 replaces the plant of the static-map and GMS runs by Table 3's revised plants of the paper's axis; "
                        "it does not go with --plant FILE (give one of them)")
    steps = 1.0 / (args.frequency * args.dt)
    if steps < MIN_STEPS_PER_PERIOD:
        raise DataError(f"--dt {args.dt:g} s gives {steps:.3g} steps per period of --frequency {args.frequency:g} Hz; "
                        f"the reversals need at least {MIN_STEPS_PER_PERIOD} (a smaller --dt or a lower --frequency)")
    nyquist = 0.5 / args.dt
    if not args.dob_cutoff < nyquist:
        raise DataError(f"--dob-cutoff {args.dob_cutoff:g} Hz must lie below the Nyquist frequency {nyquist:g} Hz of --dt {args.dt:g} s")


def saturation(study: GlitchStudy, drive_limit: float) -> dict[str, Any]:
    """The share of samples each run spends at the drive limit (``|command| >= limit``)."""
    runs: dict[str, Any] = {}
    for name, r in study.sinusoid.runs.items():
        runs[f"sinusoid.{name}"] = r
    for axis, group in (("x", study.circle.x), ("y", study.circle.y)):
        for name, r in group.items():
            runs[f"circle.{name}.{axis}"] = r
    for name, r in study.compensation.runs.items():
        runs[f"compensation.{name}"] = r
    at_limit = {}
    for name, r in runs.items():
        if r.command is not None and r.command.size:
            at_limit[name] = fraction_at_limit(r.command, -drive_limit, drive_limit)
    worst = max(at_limit, key=at_limit.__getitem__) if at_limit else None
    return {"drive_limit": drive_limit, "fraction_at_limit": at_limit, "max_fraction": at_limit[worst] if worst else 0.0, "worst_run": worst}


def _glitch(args: argparse.Namespace, run: Run) -> int:
    """Run the three studies and write JSON / figures; returns the exit code."""
    from .circle import run_circle
    from .compensation import run_compensation
    from .scenario import run_sinusoid

    _check_settings(args)
    plant = _plant_from(args.plant)
    static, gms = _frictions_from(args.friction)
    rotary = _check_one_axis(args, plant, static, gms)
    ctrl = scenario_controller(args.kp, args.ki, args.kd, args.tf, args.drive_limit)
    plants = {"static": table3_plant("static"), "gms": table3_plant("gms")} if args.table3 else None
    allocation(f"the glitch studies at --dt {args.dt:g} s and --frequency {args.frequency:g} Hz (plant delay {plant.delay:g} s)",
               _memory_needed(args.frequency, args.dt, [plant, *(plants or {}).values()]))
    common = dict(amplitude=args.amplitude, frequency=args.frequency, dt=args.dt)
    vlin = args.static_linear_region
    sin = run_sinusoid(plant, static, gms, ctrl, plants=plants, static_v_linear=vlin, **common)  # type: ignore[arg-type]
    circ = run_circle(plant, static, gms, ctrl, radius=args.amplitude, frequency=args.frequency, dt=args.dt, static_v_linear=vlin)
    comp = run_compensation(plant, None, static, gms, ctrl, advance=args.ff_advance, ff_gain=args.ff_gain, static_v_linear=vlin,  # type: ignore[arg-type]
                            dob_cutoff_hz=args.dob_cutoff, **common)
    # a rotary axis: the same numbers in rad (the JSON's *_m fields become *_rad)
    x = "rad" if rotary else "m"
    parameters = {
        f"amplitude_{x}": args.amplitude, "frequency_hz": args.frequency, "dt_s": args.dt,
        "kp": args.kp, "ki": args.ki, "kd": args.kd, "tf_s": args.tf, "drive_limit_V": args.drive_limit,
        "ff_gain": args.ff_gain, "ff_advance_s": plant.delay if args.ff_advance is None else args.ff_advance,
        "plant": {"a": plant.a, "b": plant.b, "c": plant.c, "delay": plant.delay, "force_gain": plant.force_gain},
        "plant_source": "table3: Table 3's revised plants for the static-map and GMS runs, eq. 1 for the others" if args.table3
        else (f"file: {args.plant}" if args.plant else "default: the paper's eq. 1"),
        "table3": bool(args.table3),
        "axis": "rotary" if rotary else "linear",
        "position_unit": x,
        f"static_v_linear_{x}_s": vlin,
        "static_reading": f"\"static\": the static map with a linear region below static_v_linear_{x}_s (Simulink/Simscape "
        "friction block, cannot stick); \"static_stiction\": the same map set-valued at v = 0 (true stiction)",
        "dob_cutoff_hz": args.dob_cutoff,
        "peak_error_definition": "max |e - e_lin| in the window after each reversal (e_lin: frictionless error of the same loop)",
    }
    study = GlitchStudy(sin, circ, comp, parameters)
    sat = saturation(study, args.drive_limit)
    study.saturation = sat
    if sat["max_fraction"] > SATURATION_TOLERANCE:
        share = {k: v for k, v in sat["fraction_at_limit"].items() if v > SATURATION_TOLERANCE}
        study.diagnostics.append({
            "code": "saturation", "parameter": None, "fraction": sat["max_fraction"], "runs": share,
            "message": f"the drive is at its limit ({args.drive_limit:g} V) in {100 * sat['max_fraction']:.3g} % of the samples of "
                       f"{sat['worst_run']} ({len(share)} run(s) over {100 * SATURATION_TOLERANCE:g} %): the glitches are those of a "
                       "saturated loop, not of friction (a smaller --amplitude or gains, or a larger --drive-limit)",
        })
    units = {"amplitude": x, "frequency": "Hz", "dt": "s", "kp": f"V/{x}", "ki": f"V/({x} s)", "kd": f"V s/{x}", "tf": "s", "drive_limit": "V",
             "ff_advance": "s", "static_linear_region": f"{x}/s", "dob_cutoff": "Hz"}
    study.provenance = run.provenance(units=units)
    if args.json:
        run.write_json(args.json, study)
    if args.plot:
        run.write_figures(args.plot, study.plot())
    log.info("%s", study.table())
    for d in study.diagnostics:
        log.warning("  ! %s: %s", d["code"], d["message"])
    return 0


__all__ = ["register"]

"""``gmsfric glitch``: the paper's Section 4.2 scenario, the XY circle test and friction
compensation, as JSON (``--json``) and figures (``--plot``)."""

from __future__ import annotations

import argparse
from typing import Any, Sequence

from .. import presets
from .._validate import allocation
from ..cli import Run, declare_files, finite_float, log, non_negative_float, positive_float
from ..errors import DataError
from ..model_io import load_model
from ..models import GMS, MaxwellSlip, StaticFriction
from ..system import Plant
from .compensation import DOB_CUTOFF_HZ
from .results import GlitchStudy
from .scenario import DEFAULT_GAINS, PAPER_STATIC_V_LINEAR, scenario_controller, table3_plant

def _models_in(path: str) -> tuple[list[Any], bool]:
    """The models of a model file and whether it is a bundle (several named models)."""
    m = load_model(path)
    return (list(m.values()), True) if isinstance(m, dict) else ([m], False)


def _plant_from(path: str | None) -> Plant:
    if path is None:
        return presets.paper_plant()
    models, _ = _models_in(path)
    plants = [m for m in models if isinstance(m, Plant)]
    if len(plants) != 1:
        raise DataError(f"`--plant` file {path} holds {len(plants)} plants; it needs exactly one (a `gmsfric identify plant --force-gain G --json` "
                        "file, or one saved with gmsfric.save_model)")
    return plants[0]


def _frictions_from(paths: Sequence[str]) -> tuple[StaticFriction, GMS]:
    """The static map and the GMS of the glitch studies from ``--friction`` files.

    A GMS file is used as it is; pre-sliding blocks (a Maxwell-slip model, e.g. from an older
    ``identify presliding`` file) go on a static map's Stribeck curve and viscous term with
    ``c = 1/Vs`` (paper eq. 6).  Given together with a static-map file, the blocks of either go on
    that map.  Without a static map file the paper's is used; without blocks, the paper's."""
    static: StaticFriction | None = None
    gms: GMS | None = None
    blocks: tuple[list[float], list[float]] | None = None
    for path in paths:
        models, bundle = _models_in(path)
        if bundle:  # e.g. `gmsfric paper --json`: its friction models
            models = [m for m in models if isinstance(m, (StaticFriction, GMS, MaxwellSlip))]
            if not models:
                raise DataError(f"`--friction` {path} holds no friction model")
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
                raise DataError(f"`--friction` {path} holds a {type(m).__name__}; the glitch studies take a static map and GMS blocks")
    if gms is not None and static is None:
        return presets.paper_static_friction(), gms
    static = presets.paper_static_friction() if static is None else static
    if blocks is None:
        ref = presets.paper_gms()
        if not paths:
            return static, ref
        return static, GMS(static.stribeck, ref.k, ref.alpha, 1.0 / static.stribeck.vs, static.sigma, ref.slip_law)
    return static, GMS.from_break_forces(blocks[0], blocks[1], 1.0 / static.stribeck.vs, stribeck=static.stribeck, sigma=static.sigma)


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
    p.add_argument("--plant", metavar="FILE", help="plant model file (`gmsfric identify plant --force-gain G --json`, or gmsfric.save_model); default eq. 1")
    p.add_argument("--table3", action="store_true", help="use Table 3's revised plant per friction model (docs/glitch.md)")
    p.add_argument("--friction", metavar="FILE", action="append", default=[], help="friction model file (`gmsfric identify static-map/presliding --json`, or gmsfric.save_model): a static map and/or GMS "
                   "blocks; blocks given with a static map go on its Stribeck curve (c = 1/Vs); repeatable")
    p.add_argument("--amplitude", type=positive_float, default=0.01, help="sinusoid amplitude and circle radius (m), default 0.01")
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


def _glitch(args: argparse.Namespace, run: Run) -> int:
    """Run the three studies and write JSON / figures; returns the exit code."""
    from .circle import run_circle
    from .compensation import run_compensation
    from .scenario import run_sinusoid

    plant = _plant_from(args.plant)
    static, gms = _frictions_from(args.friction)
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
    parameters = {
        "amplitude_m": args.amplitude, "frequency_hz": args.frequency, "dt_s": args.dt,
        "kp": args.kp, "ki": args.ki, "kd": args.kd, "tf_s": args.tf, "drive_limit_V": args.drive_limit,
        "ff_gain": args.ff_gain, "ff_advance_s": plant.delay if args.ff_advance is None else args.ff_advance,
        "plant": {"a": plant.a, "b": plant.b, "c": plant.c, "delay": plant.delay, "force_gain": plant.force_gain},
        "table3": bool(args.table3),
        "static_v_linear_m_s": vlin,
        "static_reading": "\"static\": the static map with a linear region below static_v_linear_m_s (Simulink/Simscape "
        "friction block, cannot stick); \"static_stiction\": the same map set-valued at v = 0 (true stiction)",
        "dob_cutoff_hz": args.dob_cutoff,
        "peak_error_definition": "max |e - e_lin| in the window after each reversal (e_lin: frictionless error of the same loop)",
    }
    study = GlitchStudy(sin, circ, comp, parameters)
    study.provenance = run.provenance(units={"amplitude": "m", "frequency": "Hz", "dt": "s", "kp": "V/m", "ki": "V/(m s)", "kd": "V s/m",
                                             "tf": "s", "drive_limit": "V", "ff_advance": "s", "static_linear_region": "m/s", "dob_cutoff": "Hz"})
    if args.json == "-":
        print(study.to_json())
    elif args.json:
        run.write_json(args.json, study)
    if args.plot:
        run.write_figures(args.plot, study.plot())
    log.info("%s", study.table())
    return 0


__all__ = ["register"]

"""XY circle test (ballbar style, ISO 230-4): two decoupled axes, each its own plant, friction and
controller, tracking ``x = R cos(theta)``, ``y = R sin(theta)``, ``theta = 2 pi f t``.

X reverses at 0 and 180 deg, Y at 90 and 270 deg: the quadrant crossings where the glitches
appear.  The run starts ``lead_in`` degrees before 0 deg (after the start transient of the
integrators has died out) and ends ``lead_out`` degrees after 360 deg; the radial error is
``sqrt(x^2 + y^2) - R``, the glitch at a crossing is the peak of the radial error minus the
frictionless radial error in the window after it.
"""

from __future__ import annotations


import numpy as np

from .. import presets
from .._validate import non_negative, positive
from ..models import GMS, FrictionModel, StaticFriction
from ..system import PID, Cascade, Plant
from .compensation import _simulate_many
from .results import CircleResult
from .scenario import MODELS, PAPER_STATIC_V_LINEAR, STICTION, paper_static_map, scenario_controller

QUADRANTS = (0, 90, 180, 270)


def run_circle(
    plant: Plant | tuple[Plant, Plant] | None = None,
    static: StaticFriction | tuple[StaticFriction, StaticFriction] | None = None,
    gms: GMS | tuple[GMS, GMS] | None = None,
    controller: PID | Cascade | tuple[PID | Cascade, PID | Cascade] | None = None,
    *,
    radius: float = 0.01,
    frequency: float = 0.01,
    dt: float = 1e-4,
    lead_in: float = 45.0,
    lead_out: float = 10.0,
    window_deg: float = 30.0,
    static_v_linear: float | None = PAPER_STATIC_V_LINEAR,
    stiction: bool = True,
) -> CircleResult:
    """Circle test without friction, with the static map and with GMS on both axes.

    Parameters
    ----------
    plant, static, gms, controller : object or (x, y) pair, optional
        One value for both axes or an ``(x, y)`` pair; paper defaults and
        :func:`~gmsfric.glitch.scenario.scenario_controller`.
    radius : float
        Circle radius (m).
    frequency : float
        Revolutions per second (feed = 2 pi R f).
    dt : float
        Step (s).
    lead_in, lead_out : float
        Degrees simulated before 0 deg and after 360 deg.
    window_deg : float
        Width (deg) after each quadrant crossing searched for the glitch.
    static_v_linear : float or None
        Linear-region threshold (m/s) of the ``"static"`` map, as in
        :func:`~gmsfric.glitch.scenario.run_sinusoid` (default 1e-4, the Simulink reading).
    stiction : bool
        Also run the static map with true stiction as ``"static_stiction"``.

    Returns
    -------
    CircleResult
    """

    def pair(v: object) -> tuple[object, object]:
        return (v[0], v[1]) if isinstance(v, tuple) else (v, v)

    px, py = pair(presets.paper_plant() if plant is None else plant)
    sx0, sy0 = pair(presets.paper_static_friction() if static is None else static)
    sx, sy = paper_static_map(sx0, static_v_linear), paper_static_map(sy0, static_v_linear)  # type: ignore[arg-type]
    kx, ky = paper_static_map(sx0, 0.0), paper_static_map(sy0, 0.0)  # type: ignore[arg-type]
    models = MODELS + ((STICTION,) if stiction else ())
    gx, gy = pair(presets.paper_gms() if gms is None else gms)
    cx, cy = pair(scenario_controller() if controller is None else controller)
    radius = positive("radius", radius)
    frequency = positive("frequency", frequency)
    dt = positive("dt", dt)
    lead_in = non_negative("lead_in", lead_in)
    lead_out = non_negative("lead_out", lead_out)
    window_deg = positive("window_deg", window_deg)
    w = 2 * np.pi * frequency
    t0 = -np.deg2rad(lead_in) / w
    t1 = (2 * np.pi + np.deg2rad(lead_out)) / w
    n = int(round((t1 - t0) / dt)) + 1
    t = t0 + np.arange(n) * dt
    theta = w * t
    rx, ry = radius * np.cos(theta), radius * np.sin(theta)
    vx0, vy0 = -radius * w * np.sin(theta[0]), radius * w * np.cos(theta[0])
    fr: dict[str, tuple[FrictionModel | None, FrictionModel | None]] = {"none": (None, None), "static": (sx, sy), "gms": (gx, gy), STICTION: (kx, ky)}  # type: ignore[dict-item]
    jobs = []
    for m in models:
        jobs.append(dict(plant=px, friction=fr[m][0], controller=cx, reference=rx, dt=dt, initial_velocity=vx0))
        jobs.append(dict(plant=py, friction=fr[m][1], controller=cy, reference=ry, dt=dt, initial_velocity=vy0))
    res = _simulate_many(jobs)
    xs = {m: res[2 * i] for i, m in enumerate(models)}
    ys = {m: res[2 * i + 1] for i, m in enumerate(models)}
    radial = {m: np.hypot(xs[m].position, ys[m].position) - radius for m in models}
    glitch: dict[str, dict[int, float]] = {}
    win = np.deg2rad(window_deg)
    for m in models:
        g = radial[m] - radial["none"]
        q: dict[int, float] = {}
        for ang in QUADRANTS:
            a = np.deg2rad(ang)
            sel = (theta >= a) & (theta <= a + win)
            i = int(np.argmax(np.abs(g[sel])))
            q[ang] = float(g[sel][i])
        glitch[m] = q
    return CircleResult(t, theta, radius, xs, ys, radial, glitch)


__all__ = ["QUADRANTS", "CircleResult", "run_circle"]

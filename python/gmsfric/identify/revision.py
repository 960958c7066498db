"""Model revision (paper Section 4.1), automatic.

With the identified friction inserted in the loop (paper Fig. 9), the linear part ``A, B, C`` of
eq. 1 is re-estimated so that the FRF of the combined model matches the measured FRF.  The paper
revised A, B, C by hand until the Bode plots looked right; here a nonlinear least-squares fit does
it.  The combined model is simulated (Rust core) with the *recorded* drive input (open loop) or
the recorded excitation (closed loop), so the amplitude-dependent friction sees the same
excitation as the axis did, and its FRF is estimated with the same H1 settings as the measured one.
The residual is the coherence-weighted complex FRF error of :func:`~gmsfric.identify.fit_plant`;
standard errors come from the Jacobian.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from .._progress import Progress
from .._validate import measured_signal, positive, same_length
from ..errors import IdentificationError, InvalidInputError
from ..models import FrictionModel
from ..system import Controller, Plant, simulate_closed_loop
from .frf import FRF, estimate_frf
from .diagnostics import Findings, check_bounds, check_chi2, check_stderr, emit
from .results import IdentificationResult, covariance_from_jacobian, transform_covariance


def combined_frf(
    plant: Plant,
    friction: FrictionModel | None,
    drive: NDArray[np.float64],
    dt: float,
    *,
    controller: Controller | None = None,
    nperseg: int | None = None,
) -> tuple[FRF, NDArray[np.float64]]:
    """FRF of plant + friction (paper Fig. 9) driven by ``drive``.

    Open loop (``controller=None``): ``drive`` is the drive input.  Closed loop: ``drive`` is the
    excitation added to the controller output and the FRF is the joint input-output estimate.
    Returns the FRF and the simulated position.
    """
    if controller is None:
        r = simulate_closed_loop(plant, friction, None, None, dt, feedforward=drive, record=("position",))
        return estimate_frf(1.0 / dt, drive, r.position, nperseg=nperseg), r.position
    r = simulate_closed_loop(plant, friction, controller, np.zeros(drive.size), dt, input_disturbance=drive, record=("position", "command"))
    return estimate_frf(1.0 / dt, r.command, r.position, excitation=drive, nperseg=nperseg), r.position


def revise_plant(
    t: ArrayLike,
    drive: ArrayLike,
    output: ArrayLike,
    friction: FrictionModel | None,
    plant: Plant,
    *,
    controller: Controller | None = None,
    excitation: ArrayLike | None = None,
    fmin: float = 0.0,
    fmax: float = np.inf,
    min_coherence: float = 0.3,
    nperseg: int | None = None,
    fit_delay: bool = False,
    progress: bool = True,
) -> IdentificationResult:
    """Re-estimate ``a, b, c`` (and optionally the delay) of eq. 1 with ``friction`` in the loop so
    that the combined model's FRF matches the measured one.

    Parameters
    ----------
    t, drive, output : array_like
        The measured FRF experiment (SI: s, drive units, m): drive command and position.
    friction : friction model or None
        Identified friction (SI, N); enters the plant as ``F / plant.force_gain``.
    plant : Plant
        Start values (usually the linear fit of :func:`~gmsfric.identify.fit_plant`), the delay
        (held unless ``fit_delay``) and ``force_gain`` (the motor constant, N per drive unit).
    controller : PID or Cascade, optional
        For closed-loop data: the controller, with ``excitation`` the recorded excitation.
    fmin, fmax, min_coherence, nperseg
        FRF band and settings (as for the measured FRF).
    fit_delay : bool
        Also re-estimate the delay.

    Returns
    -------
    IdentificationResult
        ``model="revised_plant"``, parameters ``a b c delay`` (SI), ``model_object`` the revised
        Plant; ``data`` holds the measured, original-combined and revised-combined FRFs.
    """
    t = measured_signal("time", t, min_len=64)
    u = measured_signal("drive", drive)
    y = measured_signal("output", output)
    same_length("drive", u, "time", t.size)
    same_length("output", y, "time", t.size)
    if not isinstance(plant, Plant):
        raise InvalidInputError(f"`plant` must be a Plant, got {type(plant).__name__}")
    dt = float(np.mean(np.diff(t)))
    if controller is not None:
        if excitation is None:
            raise InvalidInputError("closed-loop revision needs the recorded `excitation`")
        exc = measured_signal("excitation", excitation)
        same_length("excitation", exc, "time", t.size)
        measured = estimate_frf(t, u, y, excitation=exc, nperseg=nperseg)
        sim_drive = exc
    else:
        measured = estimate_frf(t, u, y, nperseg=nperseg)
        sim_drive = u
    sel = (measured.f >= fmin) & (measured.f <= fmax) & (measured.coherence >= min_coherence)
    if sel.sum() < 8:
        raise IdentificationError(f"only {int(sel.sum())} usable FRF bins in the band for the revision")
    sd = measured.stderr[sel]
    Hm = measured.H[sel]
    nper = int(2 * (measured.f.size))  # same segment length as the measured FRF
    nper = nperseg or nper

    def make(q: NDArray[np.float64]) -> Plant:
        return Plant(float(np.exp(q[0])), float(q[1]), float(q[2]), float(q[3]) if fit_delay else plant.delay, plant.force_gain)

    with Progress("plant revision (combined-model FRF fit)", enabled=progress) as prog:

        def resid(q: NDArray[np.float64]) -> NDArray[np.float64]:
            frf, _ = combined_frf(make(q), friction, sim_drive, dt, controller=controller, nperseg=nper)
            prog.update()
            e = (frf.H[sel] - Hm) / sd
            return np.concatenate([e.real, e.imag])

        q0 = np.array([np.log(plant.a), plant.b, plant.c] + ([plant.delay] if fit_delay else []))
        lo = np.array([q0[0] - 5.0, 0.0, 0.0] + ([0.0] if fit_delay else []))
        hi = np.array([q0[0] + 5.0, np.inf, np.inf] + ([max(10 * plant.delay, 10 * dt)] if fit_delay else []))
        q0 = np.clip(q0, lo, hi)
        # the start may be far off (friction adds stiffness and damping): try a few b, c scalings
        starts = [q0]
        for fb, fc in ((0.1, 0.1), (0.1, 1.0), (1.0, 0.1), (0.01, 0.01)):
            qs = q0.copy()
            qs[1] *= fb
            qs[2] *= fc
            starts.append(qs)
        costs = [float(np.sum(resid(qs) ** 2)) for qs in starts]
        order = np.argsort(costs)
        best = None
        for i in order[:2]:
            r = least_squares(resid, starts[i], bounds=(lo, hi), method="trf", x_scale="jac", diff_step=1e-3, max_nfev=60)
            if best is None or r.cost < best.cost:
                best = r
    assert best is not None
    q = best.x
    cov = covariance_from_jacobian(best.jac, best.fun) * measured.bin_correlation
    se = np.sqrt(np.clip(np.diag(cov), 0, np.inf))
    revised = make(q)
    params = {
        "a": (revised.a, revised.a * se[0]),
        "b": (revised.b, float(se[1])),
        "c": (revised.c, float(se[2])),
        "delay": (revised.delay, float(se[3]) if fit_delay else 0.0),
    }
    units = {"a": "m/(V s^2)", "b": "1/s", "c": "1/s^2", "delay": "s", "force_gain": "N/V"}
    orig_frf, _ = combined_frf(plant, friction, sim_drive, dt, controller=controller, nperseg=nper)
    rev_frf, _ = combined_frf(revised, friction, sim_drive, dt, controller=controller, nperseg=nper)
    dof = max(best.fun.size - q.size, 1)
    info: dict[str, Any] = {
        "chi2_per_dof": float(2 * best.cost / dof),
        "chi2_per_dof_original": float(np.sum(np.concatenate([((orig_frf.H[sel] - Hm) / sd).real, ((orig_frf.H[sel] - Hm) / sd).imag]) ** 2) / dof),
        "original": {"a": plant.a, "b": plant.b, "c": plant.c, "delay": plant.delay},
        "force_gain": plant.force_gain,
        "friction": type(friction).__name__ if friction is not None else None,
    }
    jac_p = np.eye(4)[:, : cov.shape[0]] * np.array([revised.a, 1.0, 1.0, 1.0])[:, None]
    findings = Findings()
    for d in measured.checks.get("findings", []):
        findings.add(d.code, d.message, d.parameter)
    check_bounds(findings, "a", float(q[0]), float(lo[0]), float(hi[0]), what=" (log scale: the start was far off)")
    for j, name in ((1, "b"), (2, "c")):
        if q[j] <= 1e-9 * max(abs(q0[j]), 1.0):
            findings.add("at_bound", f"{name} is at its lower bound 0 with the friction in the loop (the friction model may carry "
                                     f"{'the damping' if name == 'b' else 'the stiffness'} the data show)", name)
    check_chi2(findings, float(best.fun @ best.fun), dof, what=" of the revised combined model")
    check_stderr(findings, {k: v for k, v in params.items() if k != "delay" or fit_delay}, skip={k for k, (v, _) in params.items() if v == 0})
    res = IdentificationResult(
        "revised_plant", params, units, info, covariance=(["a", "b", "c", "delay"], transform_covariance(cov, jac_p)),
        data={"measured": measured, "original_combined": orig_frf, "revised_combined": rev_frf, "original_plant": plant, "sel": sel},
        model_object=revised,
    )
    emit(res, findings)
    return res

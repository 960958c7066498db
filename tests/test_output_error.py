"""Output-error fitting against known truth: rigs where the inverse model is biased (heavy
position noise, a low sample rate), the batch Jacobian, diagnostics, covariance and errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import signal

import gmsfric as g
import gmsfric.output_error as oe
from gmsfric import InvalidInputError
from gmsfric.loop import AxisData, Signals, fit_baseline
from gmsfric.loop.axis_model import to_axis_model
from gmsfric.output_error import default_parameters, fit_output_error

TRUTH = {"mass": 60.0, "fv": 150.0, "fc": 15.0, "offset": -2.0}
GAIN = 30.0
PATHS = ["plant.a", "friction.sigma", "friction.stribeck.fc", "friction.offset"]
SI = {"friction.sigma": "fv", "friction.stribeck.fc": "fc", "friction.offset": "offset"}


def truth_model() -> g.AxisModel:
    friction = g.StaticFriction(g.Stribeck(TRUTH["fc"], TRUTH["fc"], 1.0), sigma=TRUTH["fv"], offset=TRUTH["offset"])
    return g.AxisModel(g.Plant.from_mass(TRUTH["mass"], force_gain=GAIN), friction)


def smooth_reference(n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
    """Random smooth moves over 15 cm with a small chirp, starting gently (as the loop's rigs)."""
    t = np.arange(n) * dt
    q = sum(rng.uniform(0.3, 1.0) * np.sin(2 * np.pi * rng.uniform(0.08, 0.6) * t + rng.uniform(0, 2 * np.pi)) for _ in range(4))
    q = (q - q.min()) / np.ptp(q) * 0.15
    q += 3e-4 * signal.chirp(t, 1.0, t[-1], min(20.0, 0.025 / dt), method="logarithmic") * np.sin(np.pi * t / t[-1]) ** 2
    return q[0] + (q - q[0]) * np.clip(t / 0.5, 0, 1)


def open_loop_run(fs: float, noise: float, seed: int, duration: float = 24.0, model: g.AxisModel | None = None) -> AxisData:
    """The truth driven by a known command, position measured with white noise (the core's sensor)."""
    rng = np.random.default_rng(seed)
    dt, n = 1.0 / fs, int(duration * fs)
    t = np.arange(n) * dt
    u = 3.0 * np.sin(2 * np.pi * 0.5 * t + rng.uniform(0, 6)) + 1.5 * np.sin(2 * np.pi * 1.7 * t + rng.uniform(0, 6)) + 0.5 * np.sin(2 * np.pi * 4.1 * t)
    res = (model or truth_model()).simulate(dt, command=u, measurement_noise=noise * rng.standard_normal(n), initial_position=0.0)
    return AxisData(res.t, res.measured, GAIN * u, command=u, gain=GAIN)


def closed_loop_run(fs: float, noise: float, seed: int, duration: float = 24.0) -> tuple[AxisData, g.Cascade]:
    """The truth under an EMPS-like cascade following a smooth reference; the controller sees the
    noisy position, and the command it computed is recorded."""
    rng = np.random.default_rng(seed)
    dt, n = 1.0 / fs, int(duration * fs)
    ctrl = g.Cascade(160.0, 2.56 * TRUTH["mass"])
    ref = smooth_reference(n, dt, rng)
    res = truth_model().simulate(dt, reference=ref, controller=ctrl, measurement_noise=noise * rng.standard_normal(n))
    return AxisData(res.t, res.measured, GAIN * res.command, command=res.command, gain=GAIN, reference=ref), ctrl


def z_scores(result: oe.OutputErrorResult) -> dict[str, float]:
    v, s = result.values, result.stderr
    out = {k: (v[k] - TRUTH[SI[k]]) / s[k] for k in SI}
    m = result.derived()["mass"]
    out["mass"] = (m["value"] - TRUTH["mass"]) / m["std"]
    return out


def inverse_model_start(d: AxisData) -> tuple[g.AxisModel, dict[str, dict[str, float]]]:
    s = Signals(d)
    m = fit_baseline(s)
    return to_axis_model(m, s, gain=d.gain), m.params()


@pytest.fixture(scope="module")
def open_fit():
    d = open_loop_run(200.0, 20e-6, seed=0)
    start, idim = inverse_model_start(d)
    return d, idim, fit_output_error(start, d.dt, d.position, command=d.command, parameters=PATHS, initial_position=0.0, initial_velocity=0.0)


def test_open_loop_recovers_truth_where_the_inverse_model_is_biased(open_fit):
    """200 Hz, 20 µm of position noise: the inverse model's mass is many of its own standard
    errors off; output error recovers every parameter within 3 stated standard errors and its
    residual is the sensor noise."""
    d, idim, r = open_fit
    assert abs(idim["M"]["value"] - TRUTH["mass"]) > 5 * idim["M"]["std"]
    z = z_scores(r)
    assert all(abs(v) < 3 for v in z.values()), z
    assert r.converged and r.mode == "open_loop"
    assert r.channels["position"]["rmse"] == pytest.approx(20e-6, rel=0.05)
    # white sensor noise: no correlation correction
    assert r.channels["position"]["inflation"] < 1.3


def test_closed_loop_recovers_truth_where_the_inverse_model_is_biased():
    """250 Hz under a cascade (the controller sees the noisy encoder): the inverse model's mass
    is biased by the low sample rate; position and command output error recover the truth."""
    d, ctrl = closed_loop_run(250.0, 2e-6, seed=1)
    start, idim = inverse_model_start(d)
    assert abs(idim["M"]["value"] - TRUTH["mass"]) > 5 * idim["M"]["std"]
    r = fit_output_error(start, d.dt, d.position, reference=d.reference, controller=ctrl, measured_command=d.command, parameters=PATHS)
    z = z_scores(r)
    assert all(abs(v) < 3 for v in z.values()), z
    assert set(r.channels) == {"position", "command"} and r.mode == "closed_loop"
    assert r.channels["command"]["relative_error_pct"] < r.channels["command"]["relative_error_start_pct"]


def test_one_batch_per_jacobian_recording_only_the_cost(monkeypatch):
    d = open_loop_run(200.0, 20e-6, seed=2, duration=8.0)
    calls: list[tuple[int, tuple[str, ...]]] = []
    real = oe.simulate_batch

    def counting(models, *args, **kw):
        calls.append((len(models), tuple(kw["record"])))
        return real(models, *args, **kw)

    monkeypatch.setattr(oe, "simulate_batch", counting)
    start = truth_model().with_parameters({"plant.a": 0.45, "friction.sigma": 170.0})
    r = fit_output_error(start, d.dt, d.position, command=d.command, parameters=PATHS, initial_position=0.0, initial_velocity=0.0)
    batches = [n for n, _ in calls if n > 1]
    assert len(batches) == r.njev >= 1 and all(n == len(PATHS) for n in batches)
    assert all(rec == ("position",) for _, rec in calls)
    assert r.n_simulations == sum(n for n, _ in calls)
    # open loop fits growing horizons: 1/8, 1/4, 1/2 of the run, then all of it
    assert r.nfev >= 4


def test_covariance_travels_with_the_model(open_fit, tmp_path):
    _, _, r = open_fit
    cov = r.model.covariance
    assert cov is not None and cov.names == tuple(PATHS)
    assert cov.stderr() == pytest.approx(r.stderr)
    path = tmp_path / "fit.json"
    r.to_json(path)
    back = g.load_model(path)
    assert back.parameters() == pytest.approx(r.model.parameters())
    assert back.covariance.names == cov.names and np.allclose(back.covariance.matrix, cov.matrix)
    d = json.loads(path.read_text())
    assert d["kind"] == "output_error" and d["parameters"]["friction.sigma"]["unit"] == "N s/m"
    assert d["parameters"]["plant.a"]["scale"] == "log" and d["derived"]["mass"]["unit"] == "kg"


def test_result_protocol(open_fit, tmp_path):
    _, _, r = open_fit
    text = r.table()
    assert all(p in text for p in PATHS) and "(mass)" in text
    figs = r.plot()
    assert set(figs) == {"simulation", "parameters"}
    labels = [ax.get_ylabel() for ax in figs["simulation"].axes] + [figs["simulation"].axes[-1].get_xlabel()]
    assert "position [mm]" in labels and "time [s]" in labels
    assert "[%]" in figs["parameters"].axes[0].get_xlabel()
    written = r.save(tmp_path)
    assert {p.name for p in written} == {"simulation.png", "parameters.png", "output_error.json"}


def test_force_input_is_the_command_through_the_gain():
    d = open_loop_run(200.0, 5e-6, seed=3, duration=6.0)
    start = truth_model().with_parameters({"friction.sigma": 160.0})
    kw = dict(parameters=["friction.sigma"], initial_position=0.0, initial_velocity=0.0)
    a = fit_output_error(start, d.dt, d.position, command=d.command, **kw)
    b = fit_output_error(start, d.dt, d.position, force=d.force, **kw)
    assert a.values["friction.sigma"] == pytest.approx(b.values["friction.sigma"], rel=1e-9)


def test_diagnostics_bound_nonconvergence_and_undetermined():
    d = open_loop_run(200.0, 20e-6, seed=4, duration=8.0)
    start = truth_model().with_parameters({"friction.sigma": 120.0})
    kw = dict(command=d.command, initial_position=0.0, initial_velocity=0.0)
    r = fit_output_error(start, d.dt, d.position, parameters=["friction.sigma"], bounds={"friction.sigma": (100.0, 140.0)}, **kw)
    assert r.values["friction.sigma"] == pytest.approx(140.0, rel=1e-6)
    assert r.parameters[0].at_bound and any(x["code"] == "at_bound" for x in r.diagnostics)
    r = fit_output_error(start, d.dt, d.position, parameters=["friction.sigma", "plant.a"], max_nfev=1, **kw)
    assert not r.converged and any(x["code"] == "not_converged" for x in r.diagnostics)
    # a flat Stribeck curve has no Stribeck velocity to find: infinite std, left out of the covariance
    r = fit_output_error(truth_model(), d.dt, d.position, parameters=["friction.sigma", "friction.stribeck.vs"], **kw)
    assert not np.isfinite(r.stderr["friction.stribeck.vs"])
    assert any(x["code"] == "undetermined" and x["parameter"] == "friction.stribeck.vs" for x in r.diagnostics)
    assert r.model.covariance.names == ("friction.sigma",)


def test_large_relative_error_is_flagged():
    """An offset the truth does not have: its estimate is noise around zero, flagged as more
    uncertain than its own size, and the truth (zero) lies within the stated error."""
    d = open_loop_run(200.0, 20e-6, seed=5, duration=8.0, model=truth_model().with_parameters({"friction.offset": 0.0}))
    start = truth_model().with_parameters({"friction.offset": 0.5})
    r = fit_output_error(start, d.dt, d.position, command=d.command, parameters=["friction.sigma", "friction.offset"],
                         initial_position=0.0, initial_velocity=0.0)
    off = r.parameters[1]
    assert abs(off.value) < 3 * off.std
    assert off.relative_std > 1 and any(x["code"] == "large_std" and x["parameter"] == "friction.offset" for x in r.diagnostics)
    assert r.parameters[0].relative_std < 0.01 and not any(x.get("parameter") == "friction.sigma" for x in r.diagnostics)


def test_flat_stribeck_stays_flat():
    d = open_loop_run(200.0, 5e-6, seed=6, duration=6.0)
    start = truth_model().with_parameters({"friction.stribeck.fc": 12.0, "friction.stribeck.fs": 12.0})
    r = fit_output_error(start, d.dt, d.position, command=d.command, parameters=["friction.stribeck.fc"], initial_position=0.0, initial_velocity=0.0)
    s = r.model.friction.stribeck
    assert s.fs == s.fc == pytest.approx(TRUTH["fc"], rel=1e-3)


def test_default_parameters():
    m = truth_model()
    assert default_parameters(m) == ["plant.a", "plant.delay", "friction.stribeck.fc", "friction.sigma", "friction.offset"]
    m2 = g.AxisModel(m.plant, g.StaticFriction(g.Stribeck(15.0, 10.0, 0.01), sigma=150.0, offset=-2.0), g.Effects(asymmetry=(0.5, -30.0)))
    p = default_parameters(m2)
    # the asymmetry's level is the offset while moving: only one of them is free
    assert "friction.stribeck.fs" in p and "friction.stribeck.vs" in p and "effects.asymmetry.1" in p and "effects.asymmetry.0" not in p


def test_progress_is_silent_off_a_terminal(capsys):
    d = open_loop_run(200.0, 5e-6, seed=7, duration=4.0)
    fit_output_error(truth_model(), d.dt, d.position, command=d.command, parameters=["friction.sigma"], initial_position=0.0, initial_velocity=0.0)
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(command="u", parameters=["plant.mass"]), "no parameter `plant.mass`"),
        (dict(command="u", force="f"), "exactly one input"),
        (dict(controller=g.Cascade(160.0, 150.0)), "needs the `reference`"),
        (dict(command="short"), "`command` has length"),
        (dict(force="f", parameters=["plant.force_gain"]), "cannot be fitted from a force input"),
        (dict(command="u", parameters=["plant.b"]), "give its typical size in `scales`"),
        (dict(command="u", weights={"velocity": 1.0}), "unknown channel 'velocity'"),
        (dict(command="u", weights={"position": 0.0}), "every output channel has weight 0"),
        (dict(command="u", bounds={"friction.sigma": (200.0, 300.0)}, parameters=["friction.sigma"]), "outside its bounds"),
        (dict(command="u", parameters=[]), "`parameters` is empty"),
        (dict(command="u", reference="u"), "need a `controller`"),
        (dict(command="u", horizons=[0.5]), "ending at 1"),
        (dict(command="u", horizons=[0.5, 0.25, 1.0]), "increasing fractions"),
    ],
)
def test_bad_input_is_refused_before_any_simulation(kwargs, message, monkeypatch):
    def no_simulation(*a, **k):  # pragma: no cover - reached only if validation is missing
        raise AssertionError("simulated before checking the input")

    monkeypatch.setattr(oe, "simulate_batch", no_simulation)
    n = 200
    arrays = {"u": np.ones(n), "f": np.full(n, GAIN), "short": np.ones(n - 1)}
    kw = {k: arrays[v] if isinstance(v, str) and v in arrays else v for k, v in kwargs.items()}
    with pytest.raises(InvalidInputError, match=message.replace("(", r"\(").replace("[", r"\[")):
        fit_output_error(truth_model(), 1e-3, np.zeros(n), **kw)

"""Every reproducer of the reliability trial: each gives a clean error naming the argument and the
problem (or the correct result). Calls that would abort, hang or ignore Ctrl-C if they regressed
run in a subprocess, so that a regression fails this test instead of killing pytest."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import textwrap
import time

import numpy as np
import pytest

import gmsfric as g
from gmsfric import batch, presets

ST = g.Stribeck(0.2, 0.25, 1e-3, 1.0)


def isolated(code: str, *, timeout: float = 120, memory: int | None = None) -> subprocess.CompletedProcess[str]:
    """Run ``code`` in a fresh interpreter (optionally under an address-space limit, bytes)."""
    prelude = "import numpy as np, gmsfric as g\nfrom gmsfric import batch\n"
    if memory is not None:
        prelude = f"import resource\nresource.setrlimit(resource.RLIMIT_AS, ({memory}, {memory}))\n" + prelude
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", RAYON_NUM_THREADS="2")
    return subprocess.run([sys.executable, "-c", prelude + textwrap.dedent(code)], capture_output=True, text=True, timeout=timeout, env=env)


def outcome(code: str, **kw: object) -> dict[str, str]:
    """The exception class (or "ok") and message of ``code``'s last expression, run isolated."""
    wrapped = f"""
import json
try:
    result = eval({textwrap.dedent(code).strip()!r})
    print(json.dumps({{"class": "ok", "mro": [], "message": repr(result)[:2000]}}))
except BaseException as exc:
    print(json.dumps({{"class": type(exc).__name__, "mro": [c.__name__ for c in type(exc).__mro__], "message": str(exc)}}))
"""
    proc = isolated(wrapped, **kw)  # type: ignore[arg-type]
    assert proc.returncode == 0, f"the process died ({proc.returncode}): {proc.stderr[-2000:]}"
    return json.loads(proc.stdout.strip().splitlines()[-1])


# -- aborts -------------------------------------------------------------------------------------


def test_an_8_tb_delay_line_is_capped_by_the_run_and_gives_the_correct_result():
    # 1e3 s of delay at 1e-9 s is 1e12 samples: nothing the controller sends arrives within 10
    # samples, so the axis stays where it starts (at the reference: zero error, zero command).
    res = outcome("g.simulate_closed_loop(g.Plant(1, 10, 0, delay=1e3), None, g.PID(100.0), np.ones(10), 1e-9).position.tolist()")
    assert res["class"] == "ok"
    assert json.loads(res["message"]) == [1.0] * 10


def test_a_batch_beyond_the_memory_limit_raises_memory_error_instead_of_aborting():
    # 1000 runs x 1e6 samples: 8 GB per recorded output, under a 2 GiB address-space limit.
    # Five outputs (40 GB) are refused against the machine's memory before allocating; one
    # (8 GB) may pass that check and then fail to allocate: both are a MemoryError naming the size.
    for extra in ("", ", record=('position',)"):
        code = f"batch.simulate_batch([g.Plant(1, 1, 0)] * 1000, None, g.PID(1.0), np.zeros(10**6), 1e-4{extra})"
        res = outcome(code, memory=2 * 1024**3)
        assert "MemoryError" in res["mro"] and "GmsfricError" in res["mro"], res
        assert re.search(r"would need (29.8|7.45) GiB", res["message"]), res


# -- panics and hangs ---------------------------------------------------------------------------


def test_an_observer_history_that_cannot_fit_is_refused_not_a_panic():
    with pytest.raises(g.ResourceError, match=r"`delay` would need 1e19 samples of observer history"):
        g.simulate_closed_loop(g.Plant(1, 1, 0), None, g.PIDDOB(g.PID(1.0), g.Plant(1, 1, 0, delay=1e10), 20.0), np.ones(10), 1e-9)


@pytest.mark.parametrize("b, c", [(1e44, 0.0), (0.0, 1e100)])
def test_a_plant_too_fast_for_the_step_is_refused_instead_of_squaring_forever(b, c):
    res = outcome(f"g.Plant(1, {b!r}, {c!r}).simulate(np.ones(3), 1e-3)", timeout=60)
    assert res["class"] == "InvalidInputError", res
    assert res["message"].startswith("`plant`: ") and "too fast for a step of 0.001 s" in res["message"]
    assert len(res["message"]) < 250  # 1e44 is written as 1e44, not as 45 digits


LONG_RUN = """
import os, signal, sys, threading, time
signal.signal(signal.SIGINT, signal.default_int_handler)  # a launcher may have started us with SIGINT ignored
n = 4_000_000
blocks = g.MaxwellSlip(np.full(4000, 1e6), np.full(4000, 1e-4))  # ~4000 block updates per step: minutes
ref = 1e-3 * np.sin(np.linspace(0, 50, n))
{trigger}
start = time.monotonic()
print("go", flush=True)
try:
    g.simulate_closed_loop(g.Plant(1, 10, 0), blocks, g.PID(100.0), ref, 1e-4, record={record}, every={every})
    print("finished", time.monotonic() - start)
except KeyboardInterrupt:
    print("interrupted", time.monotonic() - start)
"""


@pytest.mark.parametrize("record, every", [(("position",), 1000), (("position", "velocity", "command", "friction", "error"), 1)])
def test_ctrl_c_from_another_thread_interrupts_a_single_long_run(record, every):
    # Second case: 160 MB of outputs, which the waiting thread maps piece by piece between its
    # signal checks.
    trigger = "threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()"
    proc = isolated(LONG_RUN.format(trigger=trigger, record=record, every=every), timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    last = proc.stdout.split()[-2:]
    assert last[0] == "interrupted", proc.stdout
    # Stopped long before the run's end (minutes): the flag is polled during the run.
    assert float(last[1]) < 30.0, proc.stdout


def test_ctrl_c_from_another_process_interrupts_a_single_long_run():
    prelude = "import numpy as np, gmsfric as g\n"
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    child = subprocess.Popen([sys.executable, "-c", prelude + LONG_RUN.format(trigger="", record=("position",), every=1000)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, env=env)
    try:
        assert child.stdout is not None
        assert child.stdout.readline().strip() == "go"
        time.sleep(0.5)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=300)
        waited = time.monotonic() - sent
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == 0, err[-2000:]
    assert out.split()[0] == "interrupted", out
    assert waited < 30.0


# -- silently wrong -----------------------------------------------------------------------------


def test_a_delay_of_more_steps_than_a_counter_holds_never_arrives():
    # 1e20 s at 1 s is 1e20 steps (more than 2^64): the input never arrives, it does not wrap to
    # a line of length 1.
    t, y = g.Plant(1, 0, 0, delay=1e20).simulate(np.ones(5), 1.0)
    assert np.array_equal(y, np.zeros(5))
    assert g.Plant(1, 0, 0)._native.discretize(1.0)[4] == 0
    assert g.Plant(1, 0, 0, delay=1e20)._native.discretize(1.0)[4] == 2**52
    _, y_now = g.Plant(1, 0, 0).simulate(np.ones(5), 1.0)
    assert y_now[-1] > 0


# -- NaN or inf returned ------------------------------------------------------------------------


def test_a_derivative_gain_of_1e308_is_refused_or_reported():
    with pytest.raises(g.InvalidInputError, match=r"`kd`: the gain overflows at a step of 0.001 s"):
        g.simulate_closed_loop(g.Plant(1, 1, 0), None, g.PID(1, 0, 1e308), np.linspace(0, 1, 10), 1e-3)
    # At a step where the gain itself fits, the first overflowing command is named.
    with pytest.raises(g.SimulationError, match=r"non-finite command at step \d+ .*check the controller gains"):
        g.simulate_closed_loop(g.Plant(1, 1, 0), None, g.PID(1, 0, 1e308), np.linspace(0, 1, 10), 1.0)


def test_a_reference_of_1e308_gives_the_correct_result():
    # The axis starts on the reference and stays there: every output is finite (the sum of two
    # 1e308 values overflowing is not a divergence).
    res = g.simulate_closed_loop(g.Plant(1, 1, 0), None, g.PID(1.0), np.full(10, 1e308), 1e-3)
    assert np.all(res.position == 1e308) and np.all(res.command == 0) and np.all(res.error == 0)


def test_a_reference_that_overflows_the_error_is_reported_as_a_command():
    # The error 0 - 1.7e308 is finite, ten times it is not.
    with pytest.raises(g.SimulationError, match=r"non-finite command at step 0 \(t = 0 s\); check the controller gains, the reference"):
        g.simulate_closed_loop(g.Plant(1, 1, 0), None, g.PID(10.0), np.zeros(10), 1e-3, initial_position=1.7e308)


def test_subnormal_bristle_stiffness_and_steps_are_refused():
    with pytest.raises(g.InvalidInputError, match=r"`sigma0` must be > 0, got 5e-324"):
        g.LuGre(ST, 5e-324)
    with pytest.raises(g.InvalidInputError, match=r"`dt` must be > 0, got 5e-324"):
        g.simulate_closed_loop(g.Plant(1, 1, 0), None, g.PID(1), np.ones(10), 5e-324)
    with pytest.raises(g.InvalidInputError, match=r"`dt`"):
        g.Plant(1, 1, 0).simulate(np.ones(10), 1e-310)


def test_an_open_loop_driven_beyond_the_finite_range_names_the_quantity_and_step():
    with pytest.raises(g.SimulationError, match=r"non-finite velocity at step 1 \(t = 1 s\).*inputs too large"):
        g.Plant(1, 0, 0).simulate(np.full(100, 1e308), 1.0)


def test_memoryless_maps_and_responses_name_the_value_out_of_range():
    with pytest.raises(g.InvalidInputError, match=r"`v`: 1e308 m/s at index 0 gives a non-finite force"):
        g.StaticFriction(ST, 10).force([1e308])
    assert np.all(np.isfinite(g.StaticFriction(ST, 10).force([1e300, -1e300])))
    with pytest.raises(g.InvalidInputError, match=r"`f` = 1e\+308 Hz gives a non-finite response"):
        g.Plant(1, 1, 1).frequency_response([1e308])
    # The integrator's pole at 0 Hz: named, not returned as inf.
    with pytest.raises(g.InvalidInputError, match=r"`f` = 0 Hz gives a non-finite response"):
        g.PID(1.0, 1.0).frequency_response([0.0, 1.0], 1e-3)
    assert np.all(np.isfinite(g.PID(1.0, 1.0).frequency_response([1.0, 10.0], 1e-3)))


def test_tiny_linear_region_or_quantisation_blames_itself_not_the_gains():
    with pytest.raises(g.InvalidInputError, match=r"`v_linear`: 5e-324 m/s is too small"):
        g.StaticFriction(ST, 1, 0, 5e-324)
    with pytest.raises(g.InvalidInputError, match=r"`quantization`: 5e-324 m is too fine a resolution"):
        g.simulate_closed_loop(g.Plant(1, 1, 0), None, g.PID(1), np.linspace(0, 1e-3, 100), 1e-3, quantization=5e-324)


def test_a_force_gain_so_small_that_a_newton_overflows_is_refused():
    with pytest.raises(g.InvalidInputError, match=r"`force_gain`: 2.2250738585072014e-308 N per input unit is too small"):
        g.simulate_closed_loop(g.Plant(1e4, 0, 0, 0, 2.2250738585072014e-308), g.StaticFriction(ST), g.PID(1.0), np.ones(5), 1e-3)


def test_times_whose_step_overflows_are_refused():
    with pytest.raises(g.InvalidInputError, match=r"`t`: the step from element 0 \(-1.7e308\) to element 1 \(1.7e308\) overflows"):
        g.simulate_friction(g.StaticFriction(ST), [-1.7e308, 1.7e308], [0.0, 1.0])


# -- wrong exception types ----------------------------------------------------------------------


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: g.Stribeck(10**400, 1, 1), r"`fc` = an integer of 401 digits does not fit a double"),
        (lambda: g.simulate_friction(None, [0, 1], [0, 1]), r"`model` must be a gmsfric friction model"),
        (lambda: g.simulate_closed_loop(g.Plant(1, 1, 0), None, g.PID(1), np.ones(10), 1e-3, drive_limit=(1, 2, 3)),
         r"`drive_limit` must be a number or a \(low, high\) pair"),
        (lambda: batch.simulate_batch(g.Plant(1, 1, 0), None, g.PID(1), np.ones(10), 1e-3, threads=2**64), r"`threads` must be between 1 and 1024"),
        (lambda: batch.simulate_batch(g.Plant(1, 1, 0), None, g.PID(1), np.ones(10), 1e-3, threads=10**6), r"`threads` must be between 1 and 1024"),
        (lambda: g.AxisUnits(np.ones((2, 2))), r"`kind` must be one of 'linear', 'rotary', got an array of shape \(2, 2\)"),
        (lambda: g.Effects(asymmetry=1.0), r"`asymmetry` must be a \(d_level, d_viscous\) pair, got 1.0"),
        (lambda: g.Covariance(("plant.a",), "abc"), r"`matrix` must be a numeric matrix"),
        (lambda: g.Drift(3, 1.0), r"`shape` must be one of 'linear', 'exponential', got 3"),
        (lambda: g.PositionSeries(["legendre"]), r"`kind` must be one of 'legendre', 'fourier', 'table'"),
        (lambda: g.GMS.from_break_forces([1e5], [1.0], 1.0, scale=np.ones(2)), r"`scale` must be one of 'stribeck', 'sum'"),
        (lambda: g.GMS(ST, [1e5], [1.0], 1.0, slip_law=None), r"`slip_law` must be one of 'time', 'displacement', got None"),
        (lambda: g.PID(1.0).frequency_response([1.0], 0.0), r"`dt` must be > 0"),
        (lambda: g.simulate_closed_loop(g.Plant(1, 1, 0), None, g.PID(1), np.ones(4), 1e-3, record=np.float32(0)),
         r"`record` must be output names among"),
        (lambda: g.simulate_closed_loop(g.Plant(1, 1, 0), None, g.PID(1), np.ones(4), 1e-3, record=[np.ones(2)]),
         r"`record` has an unknown output an array of shape \(2,\)"),
        (lambda: g.simulate_closed_loop(g.Plant(1, 1, 0), None, g.PID(1), np.ones(4), 1e-3, every=10**60),
         r"`every` = an integer of 61 digits is too large"),
        (lambda: g.PositionSeries.fourier([1e-3], 2.4e160, [1.0, 2.0]), r"`harmonics` = an integer of 161 digits is too large"),
        (lambda: g.save_model(g.Plant(1, 1, 0), os.path.join(tempfile.gettempdir(), "gmsfric-unused.json"), provenance=1.5), r"`provenance` must be a dict, got 1.5"),
        (lambda: g.AxisModel(g.Plant(1, 1, 0)).with_parameters({"plant.a": None}), r"`plant.a` must be a number, got None"),
        (lambda: g.AxisModel(g.Plant(1, 1, 0)).with_parameters({1: 2.0}), r"`values` has a parameter path that is not a string: 1"),
        (lambda: g.AxisModel(g.Plant(1, 1, 0), covariance=g.Covariance(("plant.b",), [[1.0]])).sample(10**18),
         r"`n` must be between 1 and 1000000"),
        (lambda: g.AxisModel(g.Plant(1, 1, 0), covariance=g.Covariance(("plant.b",), [[1.0]])).sample(2, seed=0.5),
         r"`seed` must be an integer"),
        (lambda: g.Plant("1", 1, 0), r"`a` must be a real number, got '1'"),
        (lambda: g.simulate_closed_loop(g.Plant(1, 1, 0), None, None, None, "1", feedforward=np.ones(3)), r"`dt` must be a real number"),
        (lambda: batch.simulate_batch(g.Plant(1, 1, 0), None, None, None, "1", feedforward=np.ones(3)), r"`dt` must be a real number"),
        (lambda: g.model_io.model_to_dict(g.Plant(1, 1, 0), drive=np.array([])), r"`drive` must be one of 'V', 'A'"),
        (lambda: g.model_io.model_to_dict(g.Plant(1, 1, 0), rotary=np.ones(2)), r"`rotary` must be True, False or None"),
        (lambda: g.model_io.model_from_dict(g.model_io.model_to_dict({"p": g.Plant(1, 1, 0)}), part=["p"]), r"`part` must be the name"),
    ],
)
def test_bad_arguments_raise_invalid_input_naming_them(call, match):
    with pytest.raises(g.InvalidInputError, match=match):
        call()


def test_discrete_transfer_functions_take_any_positive_step_type():
    pytest.importorskip("control")
    tf = g.PID(1.0, 0.5).to_control(dt=np.int64(2))
    assert tf.dt == 2.0 and np.all(np.isfinite(tf.num[0][0]))


def test_model_documents_with_hostile_fields_are_format_errors():
    from gmsfric.model_io import ModelFormatError, model_from_dict, model_to_dict

    doc = model_to_dict(presets.paper_plant())
    for field, value in (("kind", {"value": 1.0}), ("kind", ["plant"]), ("kind", None), ("kind", np.array([]))):
        with pytest.raises(ModelFormatError, match=r"unknown model kind"):
            model_from_dict({**doc, field: value})
    axis = g.AxisModel(presets.paper_plant(), presets.paper_gms()).model_document()
    with pytest.raises(ModelFormatError, match=r'"axis" must be "linear" or "rotary", got an array'):
        model_from_dict({**doc, "axis": np.array(["linear", "rotary"])})
    for field, value in (("options", [1, 2]), ("provenance", "abc")):
        with pytest.raises(ModelFormatError, match=rf'"{field}" must be an object'):
            model_from_dict({**axis, field: value})
    with pytest.raises(ModelFormatError, match=r"unknown friction kind \['gms'\]"):
        model_from_dict({**axis, "options": {**axis["options"], "friction": ["gms"]}})


def test_the_wings_name_their_arguments():
    from gmsfric import identify, loop

    t = np.linspace(0, 1, 400)
    x = 1e-5 * np.sin(2 * np.pi * t)
    with pytest.raises(g.InvalidInputError, match=r"`max_blocks` must be a positive integer, got 0"):
        identify.fit_presliding(t, x, np.tanh(x * 1e5), max_blocks=0, progress=False)
    with pytest.raises(g.InvalidInputError, match=r"`holdout_fraction` must be finite, got nan"):
        loop.LoopConfig(holdout_fraction=float("nan"))

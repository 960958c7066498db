"""Glitch metrics on synthetic signals with known glitches, and argument checks."""

from __future__ import annotations

import numpy as np
import pytest

from gmsfric.errors import InvalidInputError
from gmsfric.glitch import find_reversals, glitch_metrics


def _synthetic(height: float = 2e-6, width: float = 0.4, delay: float = 0.2):
    """Reference with reversals at 25 s and 75 s; triangular glitches (base ``width``) starting
    ``delay`` after each, of sign opposite to the new direction, on a linear error ``1e-6 cos``."""
    dt = 1e-3
    t = np.arange(0.0, 100.0, dt)
    r = 0.01 * np.sin(2 * np.pi * 0.01 * t)
    lin = 1e-6 * np.cos(2 * np.pi * 0.01 * t)
    g = np.zeros_like(t)
    for tr, s in ((25.0, -1.0), (75.0, 1.0)):
        x = (t - tr - delay) / (width / 2)
        g += s * height * np.clip(1 - np.abs(x - 1), 0, None)
    return t, r, lin, lin + g


def test_find_reversals_of_a_sinusoid():
    t, r, _, _ = _synthetic()
    times, dirs = find_reversals(t, r)
    np.testing.assert_allclose(times, [25.0, 75.0], atol=2e-3)
    assert list(dirs) == [-1, 1]


def test_metrics_recover_known_triangles():
    h, w = 2e-6, 0.4
    t, r, lin, e = _synthetic(h, w)
    rep = glitch_metrics(t, e, r, baseline=lin)
    assert len(rep.events) == 2
    for ev, sign in zip(rep.events, (-1, 1)):
        assert ev.height == pytest.approx(h, rel=1e-3)
        assert np.sign(ev.signed_height) == sign
        assert ev.duration == pytest.approx(w / 2, abs=3e-3)  # full width at half height
        assert ev.area == pytest.approx(h * w / 2, rel=1e-2)
        assert ev.peak_time == pytest.approx(0.2 + w / 2, abs=2e-3)
    assert rep.height == pytest.approx(h, rel=1e-3)
    d = rep.to_dict()
    assert d["peak_error_m"] == pytest.approx(h, rel=1e-3) and len(d["reversals"]) == 2


def test_no_glitch_gives_zero_height_and_duration():
    t, r, lin, _ = _synthetic()
    rep = glitch_metrics(t, lin, r, baseline=lin)
    assert rep.height == 0.0 and rep.duration == 0.0 and rep.area == 0.0
    assert rep.raw_peak_error == pytest.approx(abs(np.interp(25.0, t, lin)), rel=1e-6)


def test_without_baseline_height_is_spike_above_reversal_error():
    t, r, _, _ = _synthetic()
    e = np.full_like(t, 3e-6)
    e[(t > 25.1) & (t < 25.3)] += 1e-6
    rep = glitch_metrics(t, e, r)
    assert rep.events[0].height == pytest.approx(1e-6, rel=1e-9)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(error=np.ones(10)), "error"),
        (dict(baseline=np.ones(5)), "baseline"),
        (dict(window=(0.0, -1.0)), "window"),
        (dict(fraction=1.5), "fraction"),
    ],
)
def test_bad_input_names_the_argument(kwargs, name):
    t, r, lin, e = _synthetic()
    args = dict(t=t, error=e, reference=r)
    args.update(kwargs)
    with pytest.raises(InvalidInputError, match=name):
        glitch_metrics(args.pop("t"), args.pop("error"), args.pop("reference"), **args)


def test_reversals_need_increasing_time():
    with pytest.raises(InvalidInputError, match="t"):
        find_reversals([0.0, 2.0, 1.0, 3.0], [0.0, 1.0, 0.0, 1.0])

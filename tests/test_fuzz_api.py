"""The API fuzz harness (``tests/api_fuzz.py``) in its short CI profile: generated calls over every
public constructor and simulation entry point, each run in a worker process; none may abort,
panic, hang, return NaN/inf or raise anything but a GmsfricError or MemoryError.

The profile is fixed (derandomised, ``GMSFRIC_FUZZ_EXAMPLES`` calls per family, 60 by default);
``benches/fuzz_api.py`` runs the long one and reports the counts.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

import api_fuzz

EXAMPLES = int(os.environ.get("GMSFRIC_FUZZ_EXAMPLES", "60"))


@pytest.fixture(scope="module")
def harness():
    h = api_fuzz.Harness()
    yield h
    h.close()


def _check(harness: api_fuzz.Harness, node: object) -> None:
    kind, detail = harness.run(node)
    assert kind not in api_fuzz.FAILURES, f"{kind}: {api_fuzz.describe(node)}\n-> {detail}"


PROFILE = settings(max_examples=EXAMPLES, derandomize=True, database=None, deadline=None,
                   suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much])


@pytest.mark.parametrize("family", sorted(api_fuzz.families()))
def test_generated_calls_end_cleanly(harness, family):
    @PROFILE
    @given(api_fuzz.families()[family])
    def run(node: object) -> None:
        _check(harness, node)

    run()


def test_the_harness_sees_every_kind_of_failure(harness):
    # The detectors themselves: a dead worker, a hang, a foreign exception and a NaN result are
    # reported as such, and the worker comes back afterwards.
    call = api_fuzz.call
    assert harness.run(call("Plant", 1.0, 1.0, 0.0))[0] == "ok"
    assert harness.run(call("Plant", -1.0, 1.0, 0.0))[0] == "error"
    assert api_fuzz.first_nonfinite({"a": [1.0, np.array([0.0, np.nan])]}) == "result['a'][1][flat 1] = nan"
    assert api_fuzz.first_nonfinite((np.ones(3), 2.0 + 0j)) is None
    short = api_fuzz.Harness(timeout=2.0)
    try:
        assert short.run(call("_test.sleep", 30.0))[0] == "hang"
        assert short.run(call("_test.abort"))[0] == "died"
        assert short.run(call("_test.raise", "ValueError"))[0] == "foreign"
        assert short.run(call("_test.raise", "TypeError"))[0] == "wrong"
        assert short.run(call("_test.nan"))[0] == "nonfinite"
        assert short.run(call("Plant", 1.0, 1.0, 0.0))[0] == "ok"
    finally:
        short.close()

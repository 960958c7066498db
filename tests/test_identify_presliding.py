"""GMS pre-sliding blocks from the virgin-curve test: round trips, BIC, other units."""

import numpy as np
import pytest

from gmsfric import GMS, PID, Plant, Stribeck, presets
from gmsfric.errors import IdentificationError, InvalidInputError
from gmsfric.identify import VirtualRig, build_virgin_curve, fit_presliding


def _rig(gms, **kw):
    return VirtualRig(Plant(1.0, 0.0, 0.0), gms, None, **kw)


def _sorted_truth(g: GMS):
    order = np.argsort(np.asarray(g.break_forces) / np.asarray(g.k))
    return np.asarray(g.k)[order], np.asarray(g.break_forces)[order]


def test_paper_blocks_round_trip_over_seeds():
    """Table 2 blocks (20 nm .. 13 um break displacements), 1 nm sensor, 0.2 mN force noise."""
    g = presets.paper_gms()
    k_true, w_true = _sorted_truth(g)
    inside, n = 0, 0
    for seed in range(3):
        d = _rig(g, dt=2e-3, encoder=1e-9, force_noise=2e-4).sinusoid_test([2e-6, 3e-5], 0.1, cycles=2, seed=seed)
        res = fit_presliding(d["t"], d["position"], d["force"], n_blocks=4, stribeck=g.stribeck, sigma=g.sigma, progress=False)
        for i in range(4):
            for name, true in ((f"k{i + 1}", k_true[i]), (f"w{i + 1}", w_true[i])):
                val, se = res.parameters[name]
                assert abs(val / true - 1) < 0.02  # tolerance: 2 % on every k_i, w_i
                inside += abs(val - true) <= 2.5 * se
                n += 1
    assert inside / n >= 0.85


def test_bic_chooses_the_number_of_blocks_and_other_units():
    """Three well separated blocks in mm / N, no Stribeck level given, different frequency."""
    g = GMS.from_break_forces([2e6, 2e5, 2e4], [2.0, 3.0, 4.0], 5e4)
    k_true, w_true = _sorted_truth(g)
    d = _rig(g, dt=1e-3, encoder=2e-9, force_noise=5e-3).sinusoid_test([3e-6, 5e-4], 0.5, cycles=2, seed=5)
    res = fit_presliding(d["t"], d["position"] * 1e3, d["force"], position_unit="mm", progress=False)
    assert res.info["n_blocks"] == 3
    for i in range(3):
        assert res.value(f"k{i + 1}") == pytest.approx(k_true[i] * 1e-3, rel=0.05)  # N/mm
        assert res.value(f"w{i + 1}") == pytest.approx(w_true[i], rel=0.03)
    assert res.units["k1"] == "N/mm" and res.units["w1"] == "N"
    js = res.to_dict()
    assert list(js["parameters"]) == ["k1", "k2", "k3", "w1", "w2", "w3"]


def test_virgin_curve_masing_matches_analytic():
    g = GMS.from_break_forces([1e6, 1e5], [1.0, 2.0], 1e5)
    d = _rig(g, dt=1e-3).sinusoid_test([1e-6, 4e-5], 1.0, cycles=2)
    vc = build_virgin_curve(d["t"], d["position"], d["force"])
    np.testing.assert_allclose(vc.g_bin, g.virgin_curve(vc.u_bin), rtol=0.02, atol=0.01)


def test_errors():
    t = np.arange(200) * 1e-3
    with pytest.raises(IdentificationError, match="turning points"):
        fit_presliding(t, 1e-6 * t, np.sin(t), progress=False)
    with pytest.raises(InvalidInputError, match="n_blocks"):
        fit_presliding(t, np.sin(t), np.sin(t), n_blocks=0, progress=False)


def test_a_collapsed_block_set_is_refused_not_returned():
    """A random-hysteresis record made by the independent campaign's simulator (6 blocks over one
    decade below 1 um, 500 Hz) on which a forced 6-block fit once collapsed to k ~ 1e-8 N/m: the
    fit is refused with a reason instead of a result that looks like one, and BIC moves on to a
    count the record supports."""
    import sys

    from conftest import REPO

    sys.path.insert(0, str(REPO / "benches" / "identify_campaign"))
    import generate

    case = generate.make_case("presliding-hyst", 4, 2)
    col = {q: name for name, q in case.roles.items()}
    t, x, f = (case.columns[col[q]] for q in ("time", "position", "force"))
    with pytest.raises(IdentificationError, match=r"do not support 6 blocks: the fit collapsed .*\(try fewer blocks\)"):
        fit_presliding(t, x, f, n_blocks=6, progress=False)
    # by BIC the next count is taken, and it holds
    res = fit_presliding(t, x, f, max_blocks=8, progress=False)
    k = np.array([res.value(f"k{i + 1}") for i in range(res.info["n_blocks"])])
    assert np.all(k > 1e3)


@pytest.mark.parametrize("which", ["position", "force"])
def test_a_record_that_never_changes_is_refused_before_the_fit(which):
    t = np.arange(300) * 1e-3
    x, F = 1e-6 * np.sin(2 * np.pi * 5 * t), 0.1 * np.cos(2 * np.pi * 5 * t)
    if which == "position":
        x = np.zeros_like(t)
    else:
        F = np.zeros_like(t)
    for fit in (lambda: fit_presliding(t, x, F, progress=False), lambda: build_virgin_curve(t, x, F)):
        with pytest.raises(IdentificationError, match=f"the {which} never changes"):
            fit()

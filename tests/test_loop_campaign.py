"""The evaluation campaign's fixed CI subset (benches/loop_campaign): ten small cases built
independently of the loop (two clean runs, seven strong single effects, one jittered rotary robot
log), judged only through the CLI contract.  Every planted effect is found, nothing else is added,
the clean runs end with nothing, and the jittered log runs end to end."""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
import pytest

from conftest import REPO

sys.path.insert(0, str(REPO / "benches"))

from loop_campaign import cases as campaign_cases  # noqa: E402
from loop_campaign import run as campaign_run  # noqa: E402
from loop_campaign.score import false_effects  # noqa: E402

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def ci_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("campaign")
    results, summary, _ = campaign_run.run_cases(campaign_cases.ci_cases(), out, jobs=2, progress=False)
    return results, summary, out


@pytest.fixture(scope="module")
def ci_results(ci_run):
    return ci_run[:2]


def test_every_ci_case_completes(ci_results):
    results, summary = ci_results
    assert summary["n_failed"] == 0, [(r["id"], r["error"]) for r in results if r["status"] != "ok"]
    assert len(results) == len(campaign_cases.CI_PLAN)


def test_planted_effects_are_found_and_nothing_else_is_added(ci_results):
    results, _ = ci_results
    for r in results:
        assert not false_effects(r), (r["id"], r["accepted"])
        for eff in r["planted"]:
            assert eff in r["accepted"], (r["id"], r["accepted"])


def test_clean_runs_end_with_nothing_added(ci_results):
    results, summary = ci_results
    clean = [r for r in results if not r["planted"]]
    assert len(clean) == 2 and all(r["accepted"] == [] for r in clean)
    assert summary["false_rate"] == 0.0


def test_pooled_draws_add_their_counts_and_narrow_the_interval(ci_run, tmp_path):
    import shutil

    from loop_campaign import pool

    _, summary, out = ci_run
    dirs = [tmp_path / "a", tmp_path / "b"]
    for d in dirs:
        d.mkdir()
        shutil.copy(out / "results.json", d / "results.json")
    draws = pool.load(dirs)
    ids = [r["id"] for _, rs in draws for r in rs]
    assert len(set(ids)) == len(ids) == 2 * summary["n_cases"]  # each draw's ids kept apart
    everything, repeats = pool.distinct(draws)
    assert repeats == 0 and len(everything) == len(ids)  # simulated cases are new in every draw
    pooled = pool.summarize(everything)
    one, two = pool.rates(summary), pool.rates(pooled)
    assert all(two[k] == (2 * one[k][0], 2 * one[k][1]) for k in one)
    k, n = one["clean runs, nothing added (>= 98 %)"]
    (lo1, hi1), (lo2, hi2) = pool.wilson(k, n), pool.wilson(2 * k, 2 * n)
    assert lo1 <= k / n <= hi1 and hi2 - lo2 < hi1 - lo1


def test_a_draw_named_twice_or_without_a_completed_case_is_refused(tmp_path, capsys):
    import json

    from loop_campaign import pool

    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "results.json").write_text(json.dumps({"cases": [{"id": "x", "status": "failed"}]}))
    for argv, why in (([str(empty), str(empty)], "named twice"), ([str(empty)], "no completed case")):
        with pytest.raises(SystemExit) as exit_:
            pool.main(argv)
        assert exit_.value.code == 2 and why in capsys.readouterr().err


def test_a_real_data_experiment_repeated_by_another_draw_is_pooled_once():
    from loop_campaign import pool

    emps = {"sim": "emps", "files": {"est": "DATA_EMPS.mat", "val": "DATA_EMPS_PULSES.mat"}, "direction": "forward",
            "baseline": "reference", "effects": [{"name": "offset", "f0": 5.0}]}
    a = [{"id": "a/emps-1", "experiment": pool.experiment(dict(emps, seed=1))}, {"id": "a/single-1", "experiment": None}]
    b = [{"id": "b/emps-1", "experiment": pool.experiment(dict(emps, seed=2))},  # another draw, the same experiment
         {"id": "b/emps-2", "experiment": pool.experiment(dict(emps, effects=[{"name": "offset", "f0": 9.0}]))},
         {"id": "b/single-1", "experiment": pool.experiment({"sim": "own"})}]
    kept, repeats = pool.distinct([("a", a), ("b", b)])
    assert repeats == 1 and [r["id"] for r in kept] == ["a/emps-1", "a/single-1", "b/emps-2", "b/single-1"]


def test_the_jittered_rotary_log_is_resampled_and_reported_in_rotary_units(ci_run):
    import json

    results, _, out = ci_run
    robot = [c for c in campaign_cases.ci_cases() if c["rig"].get("jitter") == "robot"]
    assert len(robot) == 1
    d = json.loads((out / robot[0]["id"] / "loop.json").read_text())
    est = d["timing"]["estimation"]
    assert est["resampled"] and est["irregular_steps_pct"] > 1.0 and est["max_step_s"] > 1.5 * est["median_step_s"]
    p = d["final"]["parameters"]
    assert p["Fv"]["unit"] == "N m s/rad" and p["M"]["unit"] == "kg m^2" and p["Fc"]["unit"] == "N m"
    assert d["standstill"]["rest_speed_unit"] == "rad/s"
    lim = d["detection_limits"]
    assert lim["presliding_hysteresis"]["unit"] == "rad" and lim["stribeck"]["unit"] == "rad/s"
    assert lim["input_delay"]["smallest_delay"] > est["median_step_s"]  # within a sample: the alignment


def test_a_case_command_can_be_pasted_into_a_shell(ci_run):
    """``command.txt`` reproduces a case by hand: split as a shell splits it, it parses as the
    loop command that ran, a unit with a space ("N m") as one word."""
    import shlex

    from gmsfric.cli import build_parser

    _, _, out = ci_run
    units = []
    for case in campaign_cases.ci_cases():
        words = shlex.split((out / case["id"] / "command.txt").read_text())
        loop = words[words.index("loop"):]
        args = build_parser(loop).parse_args(loop)
        assert args.json == str(out / case["id"] / "loop.json")
        units.append(args.force_unit)
    assert any(u is not None and " " in u for u in units), units


def test_a_clean_rigs_own_detectable_presliding_is_not_scored_false():
    """A clean rig whose Maxwell-slip contact has pre-sliding the truth's own column finds
    detectable (held-out gain >= 10 %) has that effect natively; below the rule it is false."""
    from loop_campaign.truth import DETECTABLE

    def result(latent: float) -> dict:
        return {"planted": [], "native": [], "accepted": ["presliding_hysteresis", "compliance"],
                "truth": {"effects": {}, "info": {"latent_presliding": latent}}}

    assert false_effects(result(DETECTABLE + 0.05)) == ["compliance"]
    assert false_effects(result(DETECTABLE - 0.05)) == ["presliding_hysteresis", "compliance"]
    assert false_effects({**result(0.3), "truth": {"effects": {}}}) == ["presliding_hysteresis", "compliance"]


def _campaign_runs(seed: int, case_id: str):
    from gmsfric.loop import AxisData
    from loop_campaign.rigs import emps_dir, simulate_run

    emps = case_id.startswith("emps-")
    if emps and not (emps_dir() / "DATA_EMPS.mat").exists():
        pytest.skip("EMPS data not found next to the repository")
    case = next(c for c in campaign_cases.make_cases(seed, emps=emps) if c["id"] == case_id)
    return tuple(AxisData(r.t, r.q, r.f, source=which) for which, r in (("est", simulate_run(case, "est")), ("val", simulate_run(case, "val"))))


def _recipe_filter(runs):
    """The recipe's position filter, ``min(100 Hz, fs/10)``, for runs logged below 1 kHz: the
    cut-off under which some of these guards were found (the loop now chooses one from the run)."""
    from gmsfric.loop import Preprocessing

    return Preprocessing(cutoff_hz=min(100.0, 0.1 / runs[0].dt))


def test_presliding_must_explain_more_than_a_switch_at_the_reversal(monkeypatch):
    """A LuGre contact at 250 Hz (bristles far below the resolution) switches its friction where the position
    reverses, which a block at the smallest break displacement fits better than sign(qd) of the
    blurred velocity; tested against the model with that switch, pre-sliding is refused, while a
    real Maxwell-slip contact's pre-sliding is still found (two cases of the campaign's seed 21)."""
    import dataclasses

    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop.effects import CATALOGUE

    only = LoopConfig(progress=False, effects=("presliding_hysteresis",))
    clean = _campaign_runs(21, "clean-228-clean")
    real = _campaign_runs(21, "single-048-presliding_hysteresis")
    assert run_loop(*clean, only).effects == []
    res = run_loop(*real, only)
    assert res.effects == ["presliding_hysteresis"]
    step = next(s for s in res.steps if s.accepted)
    assert "w_switch" in step.evidence["tested_against"]
    # tested against the model without the term, the switch alone passes as "pre-sliding"
    eff = CATALOGUE["presliding_hysteresis"]
    monkeypatch.setitem(CATALOGUE, eff.name, dataclasses.replace(eff, null=None))
    assert run_loop(*clean, only).effects == ["presliding_hysteresis"]


def test_a_contact_is_tested_on_the_chunks_where_its_blocks_hold(monkeypatch):
    """The campaign's seed 133 ``single-051``: a contact whose held-out run reverses five times.
    Each chunk holding a reversal gains 55-86 % of its error with the contact; the chunks
    between them, where every block has slipped, only carry the refitted baseline's difference
    (d = -0.05 to 0.15), and over all of them t = 2.3.  Tested also on the chunks where its
    blocks hold short of their break forces (the smaller p doubled) it is named; without that
    test, not."""
    import dataclasses

    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop.effects import CATALOGUE

    runs = _campaign_runs(133, "single-051-presliding_hysteresis")
    cfg = LoopConfig(progress=False, effects=("presliding_hysteresis",))
    res = run_loop(*runs, cfg)
    assert res.effects == ["presliding_hysteresis"]
    step = next(s for s in res.steps if s.accepted)
    assert step.evidence["t_heldout"] >= cfg.t_threshold and step.evidence["validation_gain"] >= cfg.min_gain
    eff = CATALOGUE["presliding_hysteresis"]
    monkeypatch.setitem(CATALOGUE, eff.name, dataclasses.replace(eff, acting=None))
    assert run_loop(*runs, cfg).effects == []


def test_presliding_narrower_than_the_filter_blur_is_found(monkeypatch):
    """A GMS contact whose elastic range (0.4-4 um) lies within the distance a reversal travels in
    the velocity filter's blur, but spans many encoder steps (50 nm): its blocks follow the raw
    position, so the loop finds it against the switch (campaign seed 27); with the grid starting
    at that blur, as it once did, the pre-sliding is missed."""
    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop import effects

    only = LoopConfig(progress=False, effects=("presliding_hysteresis",))
    runs = _campaign_runs(27, "single-055-presliding_hysteresis")
    res = run_loop(*runs, only)
    assert res.effects == ["presliding_hysteresis"]
    step = next(s for s in res.steps if s.accepted)
    assert "w_switch" in step.evidence["tested_against"] and step.evidence["t_heldout"] >= 3.0
    deltas = [v["value"] for k, v in step.parameters.items() if k.startswith("Delta_block")]
    assert min(deltas) < 4e-6  # within the blur, where the contact's blocks are

    blur_start = lambda s: (max(2 * s.resolution, 0.5 * float(np.sqrt(np.mean(s.rows["qdd"] ** 2))) * (0.5 / s.cutoff) ** 2),  # noqa: E731
                            effects.PRESLIDING_MAX_FRACTION * float(np.ptp(s.q)))
    monkeypatch.setattr(effects, "presliding_range", blur_start)
    assert run_loop(*runs, only).effects == []


def test_presliding_blocks_are_bounded_by_the_encoder_step_not_the_percentile(monkeypatch):
    """A Maxwell-slip contact of blocks 1-10 encoder steps wide (86-866 nm, 89 nm steps) behind a
    spring, logged at 2 kHz on fast moves: the 1st percentile of the position's changes is four
    steps, and a grid from two of those (715 nm) leaves only the widest block, which the spring's
    model absorbs (campaign seed 109).  Bounded by the step the log rests on, the contact is found
    beside the spring, its switch one step wide and a block below the percentile's grid."""
    from gmsfric.loop import LoopConfig, Signals, idim, run_loop

    runs = _campaign_runs(109, "pair-195-compliance+presliding_hysteresis")
    s = Signals(runs[0])
    assert s.contact_resolution == pytest.approx(8.94e-8, rel=0.01) and s.resolution > 3.5 * s.contact_resolution
    cfg = LoopConfig(progress=False, effects=("compliance", "presliding_hysteresis"))
    res = run_loop(*runs, cfg)
    assert sorted(res.effects) == ["compliance", "presliding_hysteresis"]
    step = next(st for st in res.steps if st.effect == "presliding_hysteresis" and st.accepted)
    deltas = {k: v["value"] for k, v in step.parameters.items() if k.startswith("Delta")}
    assert deltas["Delta_switch"] == pytest.approx(s.contact_resolution)
    assert min(v for k, v in deltas.items() if k != "Delta_switch") < 2 * s.resolution
    monkeypatch.setattr(idim, "contact_resolution", lambda raw, filtered, resolution, lattice: resolution)
    assert run_loop(*runs, cfg).effects == ["compliance"]


def test_presliding_blocks_that_cancel_each_other_are_refused(monkeypatch):
    """A clean Karnopp rig at 500 Hz (campaign seed 31, no pre-sliding): three blocks, one of them
    with a negative break force within two of its standard errors of zero, fitted the reversals
    with held-out t 3.8 against the switch.  A negative break force is refused as fitted, and no
    set of positive blocks gains: nothing is named.  With the two-standard-error rule the
    cancelling blocks pass the test against the switch, and only the second guard refuses them:
    the whole term predicts the held-out run no better than the model without it (on the moving
    rows, as found).  All of this with the recipe's 50 Hz position filter, under which the blocks were found: the cut-off the
    loop now chooses on this run (100 Hz) leaves them little to fit."""
    import dataclasses

    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop.effects import CATALOGUE

    runs = _campaign_runs(31, "clean-248-clean")
    assert run_loop(*runs, LoopConfig(progress=False, effects=("presliding_hysteresis",))).effects == []
    only = LoopConfig(progress=False, effects=("presliding_hysteresis",), preprocessing=_recipe_filter(runs))
    assert run_loop(*runs, only).effects == []

    def within_two_errors(p, s):
        bad = [n for n, v in p.items() if n.startswith(("w_block", "w_switch")) and v["value"] < -2 * v["std"]]
        return f"negative {bad[0]}" if bad else None

    eff = CATALOGUE["presliding_hysteresis"]
    monkeypatch.setitem(CATALOGUE, eff.name, dataclasses.replace(eff, physical=within_two_errors))
    # on the moving rows alone, as found: with the creeping rows the two-error rule refuses them too
    res = run_loop(*runs, dataclasses.replace(only, creep_fraction=only.rest_fraction))
    assert res.effects == []
    step = next(s for s in res.steps if s.effect == "presliding_hysteresis")
    assert step.evidence["t_heldout"] >= 3.0 and "no better than the current model" in step.reason
    assert min(v["value"] for n, v in step.parameters.items() if n.startswith("w_block")) < 0


def test_an_overdamped_fit_refuses_compliance(monkeypatch):
    """A rig with no resonance whose residual a heavily damped "load on a spring" fits (a lag,
    no peak): compliance is refused (a case of the campaign's seed 21, with the planted asymmetry
    found), by the overdamped probe on the grid or, once the best resonance is refined before it
    meets the probes (to zeta 0.21 here), by the held-out tests; without the probe and the
    damping band, and judged on the fast held-out rows alone, it is named.  The lag is the recipe's position
    filter against the force (the rig is logged at 500 Hz): with the cut-off the loop chooses on
    the run nothing is fitted to it, so the guards are shown under the recipe's."""
    import dataclasses

    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop.effects import CATALOGUE

    runs = _campaign_runs(21, "single-018-asymmetric_friction")
    chosen = run_loop(*runs, LoopConfig(progress=False, effects=("asymmetric_friction", "compliance")))
    assert chosen.effects == ["asymmetric_friction"]
    cfg = LoopConfig(progress=False, effects=("asymmetric_friction", "compliance"), preprocessing=_recipe_filter(runs))
    res = run_loop(*runs, cfg)
    assert res.effects == ["asymmetric_friction"]
    tried = [s for s in res.steps if s.effect == "compliance"]
    assert tried and not any(s.accepted for s in tried)
    assert all("no resonant peak" in s.reason or "held-out" in s.reason for s in tried)
    eff = CATALOGUE["compliance"]
    from gmsfric.loop import heldout

    # without the probe, the damping band leaves only resonant fits, and they gain nothing here
    monkeypatch.setitem(CATALOGUE, eff.name, dataclasses.replace(eff, probe=None))
    assert run_loop(*runs, cfg).effects == ["asymmetric_friction"]
    # with any damping taken for a load on a spring, and judged on the fast held-out rows alone,
    # the lag is named
    monkeypatch.setitem(CATALOGUE, eff.name, dataclasses.replace(eff, probe=None, physical=lambda p, s: None))
    monkeypatch.setattr(heldout, "settled_rows", lambda s: np.ones(s.n_rows, bool))
    assert run_loop(*runs, cfg).effects == ["asymmetric_friction", "compliance"]


def test_a_force_ripple_in_time_refuses_compliance(monkeypatch):
    """A force oscillating at one frequency whatever the motion does (a ripple in time, outside the
    catalogue; the campaign's seed 31) is fitted best by a resonance that never stops ringing: the
    refined damping goes below the band (< 0.01), and compliance is refused.  Without the band's
    lower end, the ripple is named a load on a spring."""
    import dataclasses

    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop import effects

    runs = _campaign_runs(31, "outside-215-ripple")
    cfg = LoopConfig(progress=False, effects=("compliance",))
    res = run_loop(*runs, cfg)
    assert res.effects == []
    assert any("rings on" in s.reason for s in res.steps if s.effect == "compliance")
    eff = effects.CATALOGUE["compliance"]

    def upper_only(p, s):
        return None if p["zeta"]["value"] <= effects.COMPLIANCE_MAX_ZETA else "no peak"

    # the tone in time, compliance's rival, would refuse it too: left out to show the band's part
    monkeypatch.setitem(effects.CATALOGUE, eff.name,
                        dataclasses.replace(eff, physical=upper_only, probe=lambda p, s: upper_only(p, s) is not None, rivals=None))
    res = run_loop(*runs, cfg)
    assert res.effects == ["compliance"]
    assert res.final.params()["zeta"]["value"] < effects.COMPLIANCE_MIN_ZETA


def test_a_force_ripple_fitted_by_a_damped_resonance_gives_way_to_a_tone_in_time(monkeypatch):
    """A force ripple of 0.15 N m at 5.78 Hz in time (outside the catalogue; the campaign's seed 105,
    a rotary rig logged at 250 Hz): the controller answers it, so the acceleration carries it, and
    a resonance at 5.9 Hz with a damping ratio of 0.01, inside the band, amplifies that and gains
    55 % held out (t = 8.2).  A sine and cosine of time at the residual's periodogram peak fit the
    estimation rows better: compliance is refused; without its rival, or against a rival that only
    ties, it is named."""
    import dataclasses

    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop import effects

    case_id = "outside-215-ripple"
    runs = _campaign_runs(105, case_id)
    ripple = next(c for c in campaign_cases.make_cases(105, emps=False) if c["id"] == case_id)["outside"][0]
    cfg = LoopConfig(progress=False, effects=("compliance",))
    res = run_loop(*runs, cfg)
    assert res.effects == []
    refused = [s.reason for s in res.steps if s.effect == "compliance" and "oscillating in time" in s.reason]
    assert refused
    f_tone = float(refused[0].split("oscillating in time at ")[1].split(" Hz")[0])
    assert abs(f_tone - ripple["freq"]) < 0.01 * ripple["freq"]
    eff = effects.CATALOGUE["compliance"]
    monkeypatch.setitem(effects.CATALOGUE, eff.name, dataclasses.replace(eff, rivals=None))
    assert run_loop(*runs, cfg).effects == ["compliance"]
    # a rival that only ties (here the chosen resonance itself) is no evidence against it
    monkeypatch.setitem(effects.CATALOGUE, eff.name, dataclasses.replace(eff, rivals=lambda model, chosen, s, r: [(chosen, "itself")]))
    assert run_loop(*runs, cfg).effects == ["compliance"]


def test_a_stribeck_dip_only_at_reversals_is_refused(monkeypatch):
    """A clean GMS contact (elastic range far below the encoder step; the campaign's seed 33) whose
    force, against the filtered velocity, looks lower at low speed: a Stribeck *dip* that gains
    only through reversals and is contradicted on the rows clear of them, so it is refused there;
    without that check it is named.  Under the recipe's position filter: the cut-off the loop
    chooses on this run leaves no dip to fit."""
    import dataclasses

    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop.effects import CATALOGUE

    runs = _campaign_runs(33, "clean-233-clean")
    assert run_loop(*runs, LoopConfig(progress=False, effects=("stribeck",))).effects == []
    cfg = LoopConfig(progress=False, effects=("stribeck",), preprocessing=_recipe_filter(runs))
    res = run_loop(*runs, cfg)
    assert res.effects == []
    refused = [s for s in res.steps if s.effect == "stribeck" and "not confirmed away from reversals" in s.reason]
    assert refused and refused[0].parameters["Fs_minus_Fc"]["value"] < 0
    eff = CATALOGUE["stribeck"]
    monkeypatch.setitem(CATALOGUE, eff.name, dataclasses.replace(eff, clear_of_reversals=None))
    res = run_loop(*runs, cfg)
    assert res.effects == ["stribeck"] and res.final.params()["Fs_minus_Fc"]["value"] < 0


@pytest.mark.parametrize("seed, case_id, margin, unguarded", [(23, "single-012-asymmetric_friction", "filters", "too_small_clear"),
                                                              (29, "single-003-asymmetric_friction", "decimation", "named")])
def test_a_delay_must_gain_where_the_filters_have_settled_after_reversals(monkeypatch, seed, case_id, margin, unguarded):
    """Clean-timing Karnopp rigs that stick at every reversal: around those sticks sign(qd) of the
    zero-phase filtered velocity switches at the wrong instant, the force steps ring through the
    filters, and a force shifted by a few samples makes up for it.  Seed 23 `single-012` (fast
    sweep) fitted 1.4 samples with held-out t 4.3, also on rows faster than the velocity filter's
    blur; seed 29 `single-003` (stiff P-PI cascade, 2 kHz) fitted 5 samples with t 4.4 even on rows
    the velocity filter had settled on, because the decimation filter rings for about 7 rows on
    either side.  On held-out rows clear of both the shift gains too little to pass the level a
    first-round test has with the whole catalogue, so no input delay is named.  Without the margin
    that settles the case (every row, or the velocity filter's margin alone) the test still holds
    because both models are fitted again on the rows it keeps; without that refit too (and
    without a freely timed switch of friction beside the delay), seed 29's delay is named, and
    seed 23's passes on all rows but not clear of reversals, the last guard left (on the delay
    grid, t 4.2 there but less than the minimum gain, 2.9 %; refined between the grid's points,
    t 2.5)."""
    import dataclasses

    from gmsfric.loop import CATALOGUE, LoopConfig, run_loop
    from gmsfric.loop import effects, heldout, select

    runs = _campaign_runs(seed, case_id)
    # the delay tested alone, at the level it has among the whole catalogue's candidates
    cfg = LoopConfig(progress=False, effects=("input_delay",), alpha=0.05 / len(CATALOGUE))
    res = run_loop(*runs, cfg)
    assert res.effects == []
    refused = [s for s in res.steps if s.effect == "input_delay"]
    assert refused and "not confirmed away from reversals" in refused[0].reason
    if margin == "filters":
        monkeypatch.setattr(heldout, "settled_rows", lambda s: np.ones(s.n_rows, bool))
    else:
        monkeypatch.setattr(effects, "decimation_settling_rows", lambda dec: 0)
    # each guard holds alone: fitted again on rows clear of the (narrower) margins, the
    # baseline needs no shift either
    assert run_loop(*runs, cfg).effects == []
    monkeypatch.setitem(CATALOGUE, "input_delay", dataclasses.replace(CATALOGUE["input_delay"], refit_clear_of_reversals=False))
    # tested against the switch of friction at the model's timing, as they were found (a freely
    # timed switch refuses these late filtered switches on its own)
    monkeypatch.setattr(select, "_with_switch_timing", lambda m, split, cfg: m)
    res = run_loop(*runs, cfg)
    if unguarded == "named":
        assert res.effects == ["input_delay"]
    else:
        (step,) = [s for s in res.steps if s.effect == "input_delay"]
        ev = step.evidence
        # on all rows the shift passes; clear of reversals it gains too little or too weakly
        assert res.effects == [] and ev["validation_gain"] >= cfg.min_gain and ev["t_heldout"] >= cfg.t_threshold
        assert ev["t_heldout_away_from_reversals"] < cfg.t_threshold or ev["validation_gain_away_from_reversals"] < cfg.min_gain, ev


def test_an_asymmetry_of_viscous_friction_leaves_the_coulomb_level_alone(monkeypatch):
    """A viscous friction that differs strongly between the directions (the campaign's seed 35,
    planted with a cogging force): ``dFv |qd|`` is even in the speed and does not change the
    sliding level both directions share, so the asymmetry is named with the Coulomb level near
    the rig's.  Projected on ``sign(qd)`` over a run that moves faster one way, it looked like the
    Coulomb level falling by a factor 3, and the asymmetry was refused as implausible."""
    from gmsfric.loop import LoopConfig, run_loop, select

    runs = _campaign_runs(35, "pair-153-asymmetric_friction+position_dependent_force")
    case = next(c for c in campaign_cases.make_cases(35, emps=False) if c["id"] == "pair-153-asymmetric_friction+position_dependent_force")
    cfg = LoopConfig(progress=False, effects=("asymmetric_friction",))
    res = run_loop(*runs, cfg)
    assert res.effects == ["asymmetric_friction"]
    p = res.final.params()
    assert p["Fc"]["value"] == pytest.approx(case["rig"]["Fc"], rel=0.3)
    assert p["dFv_asym"]["value"] == pytest.approx(case["effects"][0]["dFv"], rel=0.2)
    # projected with the friction and held to the level's guard, it would look like friction
    # explained away
    monkeypatch.setattr(select, "FRICTION_TERMS", select.FRICTION_TERMS | {"asymmetric_friction"})
    monkeypatch.setitem(select.CATALOGUE, "asymmetric_friction", replace(select.CATALOGUE["asymmetric_friction"], even_in_speed=False))
    res = run_loop(*runs, cfg)
    assert res.effects == []
    assert any("effective Coulomb level" in s.reason for s in res.steps if s.effect == "asymmetric_friction")
    # refused by the guard alone, every test of the data passed: the result says so
    held = [d for d in res.diagnostics if d["code"] == "held_back"]
    assert [d["parameter"] for d in held] == ["asymmetric_friction"] and "Coulomb level" in held[0]["message"]


def test_an_asymmetry_that_gives_back_the_level_the_baseline_took_is_named():
    """A strong viscous asymmetry on a run that moves faster one way (the campaign's seed 129,
    planted with a position friction): the baseline takes the asymmetry's share into its Coulomb
    level, more than twice the rig's, and an offset.  The asymmetry brings the level back to the
    rig's; a force even in the speed is not held to the level's fall, and the level it leaves is
    what the position friction after it is held to."""
    from gmsfric.loop import LoopConfig, run_loop

    case_id = "pair-190-position_dependent_friction+asymmetric_friction"
    runs = _campaign_runs(129, case_id)
    case = next(c for c in campaign_cases.make_cases(129, emps=False) if c["id"] == case_id)
    res = run_loop(*runs, LoopConfig(progress=False, effects=("asymmetric_friction", "position_dependent_friction")))
    assert res.baseline.params()["Fc"]["value"] > 2.0 * case["rig"]["Fc"]
    assert res.effects == ["asymmetric_friction", "position_dependent_friction"]
    p = res.final.params()
    assert p["Fc"]["value"] == pytest.approx(case["rig"]["Fc"], rel=0.2)
    dfv = next(e["dFv"] for e in case["effects"] if e["name"] == "asymmetric_friction")
    assert p["dFv_asym"]["value"] == pytest.approx(dfv, rel=0.1)
    first, second = [s for s in res.steps if s.accepted]
    assert first.evidence["baseline_parameters"]["Fc"]["ratio"] < 0.5
    assert second.evidence["baseline_parameters"]["Fc"]["ratio"] < 0.5  # against the baseline's: a level given back, not halved


def test_a_confounded_pair_is_chosen_again_together(monkeypatch):
    """A friction that decays over the run and one that depends on the position (the campaign's
    seed 37): fitted alone, the drift takes the slowest decay and drives the viscous coefficient
    negative, and the position friction loses on held-out data.  Their grid parameters chosen
    again together, the pair enters and the held-out error falls by three quarters; combined as
    each was fitted alone, the pair is implausible and nothing is named."""
    from gmsfric.loop import LoopConfig, run_loop, select

    runs = _campaign_runs(37, "pair-175-friction_drift+position_dependent_friction")
    cfg = LoopConfig(progress=False, effects=("friction_drift", "position_dependent_friction"))
    res = run_loop(*runs, cfg)
    assert sorted(res.effects) == ["friction_drift", "position_dependent_friction"]
    assert all("entered together" in s.reason for s in res.steps if s.accepted)
    e0, e1 = res.split.errors_moving(res.baseline)[1], res.split.errors_moving(res.final)[1]
    assert e1 < 0.5 * e0
    assert res.final.params()["Fv"]["value"] > 0
    monkeypatch.setattr(select, "_rechoose", lambda model, names, st, cfg: model)
    assert run_loop(*runs, cfg).effects == []


def test_a_pair_is_screened_on_its_joint_fit_not_on_its_members_alone():
    """A viscous asymmetry beside a position-dependent force on a rotary axis (the campaign's
    seed 117): fitted alone, the asymmetry absorbs part of the force the wrong way and raises the
    estimation run's cross-validated error, and the force alone gains at t = 1.6 on held-out data.
    Together they remove nine tenths of the held-out error.  A pair is screened on the
    cross-validated gain of its joint fit, so it is tried and enters."""
    from gmsfric.loop import LoopConfig, run_loop

    runs = _campaign_runs(117, "pair-154-asymmetric_friction+position_dependent_force")
    cfg = LoopConfig(progress=False, effects=("asymmetric_friction", "position_dependent_force", "friction_drift"))
    res = run_loop(*runs, cfg)
    alone = next(s for s in res.steps if s.effect == "asymmetric_friction" and s.round == 1)
    assert not alone.accepted and alone.evidence["cv_gain"] < 0
    assert sorted(res.effects) == ["asymmetric_friction", "position_dependent_force"]
    assert all("entered together" in s.reason for s in res.steps if s.accepted)
    e0, e1 = res.split.errors_moving(res.baseline)[1], res.split.errors_moving(res.final)[1]
    assert e1 < 0.1 * e0


def _audit_runs(name: str):
    """An outside audit's case kept in ``tests/data`` (``benches/loop_audit2/run.py --seed S --only
    ID`` writes it again, with numba): the encoder's steps and the logged torque (mN m, float32)
    of both runs, logged at a fixed period, as SI runs."""
    from gmsfric.loop import AxisData

    z = np.load(REPO / "tests" / "data" / f"{name}.npz")
    step, period = float(z["encoder_step_rad"]), float(z["sample_period_s"])
    runs = []
    for which in ("est", "val"):
        q = z[f"{which}_steps"].astype(float) * step
        runs.append(AxisData(np.arange(q.size) * period, q, z[f"{which}_torque_mNm"].astype(float) * 1e-3, source=which))
    return tuple(runs)


def test_a_pair_is_chosen_again_together_before_its_held_out_test():
    """An outside audit's rotary axis (seed 21, ``p091``): a friction that warms up over the run
    (time constant 4.2 s, by 54 %) and one that changes with the position, on an estimation run
    that ranges over the travel first and lingers in one part of it late, so that time and
    position are confounded there.  Each effect chosen alone absorbs the other the wrong way and
    the two combined as chosen predict the held-out run worse than the baseline; chosen again
    together they remove most of its error.  The pair is chosen again before its held-out test,
    so it enters, with the warm-up near the planted one."""
    from gmsfric.loop import LoopConfig, run_loop

    runs = _audit_runs("audit2_seed21_p091")
    res = run_loop(*runs, LoopConfig(progress=False, effects=("friction_drift", "position_dependent_friction")))
    assert sorted(res.effects) == ["friction_drift", "position_dependent_friction"]
    assert all("entered together" in s.reason for s in res.steps if s.accepted)
    e0, e1 = res.split.errors_moving(res.baseline)[1], res.split.errors_moving(res.final)[1]
    assert e1 < 0.2 * e0
    tau = res.final.params()["drift_tau_over_T"]["value"] * (runs[0].t[-1] - runs[0].t[0])
    assert abs(tau - 4.21) < 0.25 * 4.21


def test_a_position_basis_is_tested_within_the_estimation_travel(monkeypatch):
    """A Stribeck curve beside a position-dependent force (the campaign's seed 117): the held-out
    run travels four times as far as the estimation run, where the fitted polynomial in the
    position is a guess.  Within the estimation travel the pair removes most of the held-out
    error and enters; tested on every held-out row, each member loses given the other and
    nothing is named."""
    from gmsfric.loop import LoopConfig, heldout, run_loop

    runs = _campaign_runs(117, "pair-180-stribeck+position_dependent_force")
    cfg = LoopConfig(progress=False, effects=("stribeck", "position_dependent_force", "friction_drift"))
    res = run_loop(*runs, cfg)
    assert sorted(res.effects) == ["position_dependent_force", "stribeck"]
    entered = [s for s in res.steps if s.accepted]
    assert entered and all("within the estimation travel" in s.reason for s in entered)
    q_est = res.split.est.rows["q"][res.split.est_fit]
    q_val = res.split.val.rows["q"][res.split.val_test]
    assert np.mean(q_val > q_est.max()) > 0.1
    monkeypatch.setattr(heldout, "within_travel", lambda split, rows, chunk: rows)
    assert run_loop(*runs, cfg).effects == []


def test_accepted_effects_are_chosen_again_with_each_candidate(monkeypatch):
    """A transmission resonance and a friction drift (the campaign's seed 37): the resonance enters
    first, its frequency fitted 2.5 % high while the drift is missing, and that error hides the
    drift (held-out gain 1.7 %).  Chosen again with the drift as a candidate, the resonance comes
    back to the rig's frequency and the drift enters with a held-out t over 20; without choosing
    again, only the resonance is named."""
    import math

    from gmsfric.loop import LoopConfig, run_loop, select

    case_id = "pair-179-friction_drift+compliance"
    runs = _campaign_runs(37, case_id)
    spring = next(e for e in next(c for c in campaign_cases.make_cases(37, emps=False) if c["id"] == case_id)["effects"] if e["name"] == "compliance")
    fn = math.sqrt(spring["k2"] / spring["m2"]) / (2.0 * math.pi)
    cfg = LoopConfig(progress=False, effects=("compliance", "friction_drift"))
    res = run_loop(*runs, cfg)
    assert res.effects == ["compliance", "friction_drift"]
    assert res.final.params()["fn_hz"]["value"] == pytest.approx(fn, rel=0.01)
    monkeypatch.setattr(select, "_rechoose", lambda model, names, st, cfg: model)
    assert run_loop(*runs, cfg).effects == ["compliance"]


def test_the_joint_refit_runs_until_choosing_again_changes_nothing(monkeypatch):
    """A transmission resonance and a Maxwell-slip contact (the campaign's seed 37): pre-sliding
    enters with one block, then the timing alignment moves the force by one sample.  Given that
    shift, two blocks fit far better; a single pass of the joint refit, made before the shift,
    keeps one block and a cross-validated error 28 % higher.  Passes until nothing changes reach
    a model that choosing again no longer improves."""
    from gmsfric.loop import LoopConfig, run_loop, select

    runs = _campaign_runs(37, "pair-159-presliding_hysteresis+compliance")
    # on the moving rows, as found: with the creeping rows pre-sliding enters with three blocks
    cfg = LoopConfig(progress=False, effects=("compliance", "presliding_hysteresis"), creep_fraction=0.01)
    res = run_loop(*runs, cfg)
    assert res.effects == ["compliance", "presliding_hysteresis"]
    blocks = [n for n in res.final.params() if n.startswith("w_block")]
    cv = select._cv(res.final, res.split, cfg)
    monkeypatch.setattr(select, "JOINT_REFIT_PASSES", 1)
    once = run_loop(*runs, cfg)
    assert once.effects == res.effects
    assert len([n for n in once.final.params() if n.startswith("w_block")]) < len(blocks)
    assert cv < 0.8 * select._cv(once.final, once.split, cfg)


def test_a_stand_in_that_entered_first_is_exchanged(monkeypatch):
    """A friction that grows along the travel planted on a real EMPS run (the campaign's seed 39):
    a position-dependent force enters first, standing in for the axis' own friction asymmetry,
    and stays after the position friction enters (given the others it still gains 20 % on
    held-out data), keeping the asymmetry out.  Tried in its place, the asymmetry lowers the
    held-out error further and replaces it; without the exchange step the force stays."""
    from gmsfric.loop import LoopConfig, run_loop, select

    runs = _campaign_runs(39, "emps-307-position_dependent_friction")
    cfg = LoopConfig(progress=False)
    res = run_loop(*runs, cfg)
    assert "position_dependent_force" not in res.effects
    assert {"asymmetric_friction", "position_dependent_friction"} <= set(res.effects)
    made = [s for s in res.steps if s.accepted and s.evidence.get("replaces") == "position_dependent_force"]
    assert [s.effect for s in made] == ["asymmetric_friction"]
    replaced = next(s for s in res.steps if s.effect == "position_dependent_force" and "replaced_in_round" in s.evidence)
    assert not replaced.accepted
    monkeypatch.setattr(select, "_exchange_step", lambda *args: False)
    assert "position_dependent_force" in run_loop(*runs, cfg).effects


def test_a_heating_memory_as_long_as_the_run_is_a_drift(monkeypatch):
    """On the same rig, friction that drifts linearly in time: heating with a memory twice the run
    (the low-passed speed then grows with the distance travelled) gains slightly more on held-out
    data than the drift itself.  Two guards refuse it, each on its own: a memory as long as the
    run is a probe, and heating is tested against its own trend in time (the same memory driven
    by the run's mean speed).  With neither, heating is named instead of the drift."""
    import dataclasses

    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop.effects import CATALOGUE, HEATING_MIN_TAU_S

    runs = _campaign_runs(37, "pair-179-friction_drift+compliance")
    cfg = LoopConfig(progress=False, effects=("compliance", "friction_drift", "heating"))
    res = run_loop(*runs, cfg)
    assert res.effects == ["compliance", "friction_drift"]
    assert any("as long as the run" in s.reason for s in res.steps if s.effect == "heating")
    eff = CATALOGUE["heating"]
    any_slow_memory = dict(physical=lambda p, s: None if p["heating_tau_s"]["value"] >= HEATING_MIN_TAU_S else "fast",
                           probe=lambda p, s: p["heating_tau_s"]["value"] < HEATING_MIN_TAU_S)
    monkeypatch.setitem(CATALOGUE, eff.name, dataclasses.replace(eff, **any_slow_memory))
    assert run_loop(*runs, cfg).effects == ["compliance", "friction_drift"]
    monkeypatch.setitem(CATALOGUE, eff.name, dataclasses.replace(eff, null=None))
    assert run_loop(*runs, cfg).effects == ["compliance", "friction_drift"]
    monkeypatch.setitem(CATALOGUE, eff.name, dataclasses.replace(eff, null=None, **any_slow_memory))
    assert "heating" in run_loop(*runs, cfg).effects


def test_a_hump_the_viscous_slope_outweighs_needs_to_beat_the_drag_probes(monkeypatch):
    """A Stribeck hump at low speed on an axis with a steep viscous slope (the campaign's seed 37):
    its friction never falls out of rest, which a drag resembles, but it cross-validates 9 % better
    than the drag probes and is named.  On a drag rig (seed 35) the best such hump comes within
    0.1 % of the drag probe and Stribeck is refused; with no margin over the probes, the hump that
    never falls is never named."""
    from gmsfric.loop import LoopConfig, run_loop, select
    from gmsfric.loop.effects import stribeck_fall

    cfg = LoopConfig(progress=False, effects=("stribeck",))
    hump = _campaign_runs(37, "single-020-stribeck")
    res = run_loop(*hump, cfg)
    assert res.effects == ["stribeck"]
    p = res.final.params()
    assert p["Fs_minus_Fc"]["value"] > 0 and stribeck_fall(p, res.split.est.v_scale) < 0.1 * p["Fs_minus_Fc"]["value"]
    drag = _campaign_runs(35, "outside-200-drag")
    assert run_loop(*drag, cfg).effects == []
    monkeypatch.setattr(select, "CONTESTED_MARGIN", 0.0)
    assert run_loop(*hump, cfg).effects == []


def test_a_slow_log_gets_a_filter_cut_off_chosen_on_its_estimation_rows(monkeypatch):
    """A clean jittered robot log at 100 Hz (campaign seed 45, Karnopp contact, no delay): with
    the recipe's fs / 10 = 10 Hz the filtered position lags the unfiltered torque through the stick
    at reversals, and a 14 ms input delay fits that lag.  Each cut-off of 10, 20 and 30 Hz is tried
    and the one whose baseline cross-validates best on the estimation rows is kept: nothing is
    named.  At 1 kHz and above only the recipe's cut-off is tried, and a given one is kept.  With
    the recipe's cut-off the delay is also refused because it gains nothing clear of the stops once
    both models are fitted there, and because a switch of friction at a time of its own explains
    the lag as well; without either, it is named."""
    import dataclasses

    from gmsfric.loop import CATALOGUE, AxisData, LoopConfig, Preprocessing, run_loop, select
    from gmsfric.loop.select import make_split

    runs = _campaign_runs(45, "robot-277-clean")
    res = run_loop(*runs, LoopConfig(progress=False))
    pre = res.to_dict()["preprocessing"]
    assert pre["chosen_by"].startswith("cross-validated") and set(pre["cv_sse"]) == {"10", "20", "30"}
    assert pre["cutoff_hz"] > 10.0 and pre["cv_sse"]["10"] > pre["cv_sse"][f"{pre['cutoff_hz']:g}"]
    assert res.effects == []
    assert f"position filter: {pre['cutoff_hz']:.4g} Hz (cross-validated" in res.table()
    recipe = LoopConfig(progress=False, preprocessing=Preprocessing(cutoff_hz=10.0))
    fixed = run_loop(*runs, recipe)
    assert fixed.to_dict()["preprocessing"] == {"cutoff_hz": 10.0, "chosen_by": "given"}
    assert fixed.effects == []
    monkeypatch.setitem(CATALOGUE, "input_delay", dataclasses.replace(CATALOGUE["input_delay"], refit_clear_of_reversals=False))
    monkeypatch.setattr(select, "_with_switch_timing", lambda m, split, cfg: m)
    assert "input_delay" in run_loop(*runs, recipe).effects

    t = np.arange(0.0, 4.0, 1e-3)
    q = 0.01 * np.sin(2 * np.pi * 0.5 * t)
    fast = AxisData(t, q, 2.0 * np.gradient(np.gradient(q, t), t) + 3.0 * np.sign(np.cos(2 * np.pi * 0.5 * t)), source="est")
    split = make_split(fast, None, LoopConfig(progress=False))
    assert split.preprocessing["cutoff_hz"] == 100.0 and split.preprocessing["chosen_by"].startswith("the recipe")


def test_a_resonance_is_confirmed_away_from_reversals():
    """A transmission resonance on a trapezoid run (the campaign's seed 53): it gains 60 % on the
    held-out rows (t = 7.2).  On the rows clear of reversals and stops a trapezoid move excites it
    only in the few accelerations away from a stop; with the chunk length of all rows it reached
    only t = 2.7, p = 0.013 there, and cut by their rule applied to those rows it is confirmed
    with t = 3.3.  A resonance only has to agree there at the nominal level
    (``Effect.consistency_only``), as a check of a gain already found on all rows."""
    from gmsfric.loop import LoopConfig, run_loop

    runs = _campaign_runs(53, "single-140-compliance")
    cfg = LoopConfig(progress=False, effects=("compliance",))
    res = run_loop(*runs, cfg)
    assert res.effects == ["compliance"]
    step = next(s for s in res.steps if s.accepted)
    assert step.evidence["t_heldout"] >= cfg.t_threshold and step.evidence["t_heldout_away_from_reversals"] > 0


def test_a_delay_must_gain_clear_of_stops_when_both_models_are_fitted_there(monkeypatch):
    """A clean rotary rig whose friction is 2.6 times its largest inertial force (the campaign's
    seed 57): fitted on all moving rows, the baseline's inertia comes out 22 % high from what the
    filters make of the stops, and a 1.8 ms "delay" fitted with it gains on the held-out rows
    clear of the stops (t = 6.7) by undoing that bias.  Fitted where the filters have settled,
    the baseline needs no delay, and none is named; without that refit the false delay enters."""
    import dataclasses

    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop import effects

    runs = _campaign_runs(57, "clean-244-clean")
    cfg = LoopConfig(progress=False, effects=("input_delay",))
    res = run_loop(*runs, cfg)
    assert res.effects == []
    step = next(s for s in res.steps if s.effect == "input_delay")
    assert "not confirmed away from reversals" in step.reason and step.evidence["t_heldout"] >= cfg.t_threshold
    fitted_on_all = dataclasses.replace(effects.CATALOGUE["input_delay"], refit_clear_of_reversals=False)
    monkeypatch.setitem(effects.CATALOGUE, "input_delay", fitted_on_all)
    assert run_loop(*runs, cfg).effects == ["input_delay"]


def test_a_position_basis_is_chosen_where_the_folds_share_the_travel(monkeypatch):
    """A position force and a Maxwell-slip contact on a sweep whose first cycles are the widest
    (the campaign's seed 59).  Scored over whole folds, the cross-validation rewarded the basis
    that guessed the wide cycles best (three harmonics, 4.6 % held-out error) over a polynomial
    that fits (1.5 %), and against that residual the contact's blocks gained 4 %.  Scored inside
    the travel the other folds cover, the polynomial is chosen and the contact named too."""
    from gmsfric.loop import LoopConfig, run_loop, select

    runs = _campaign_runs(59, "pair-184-presliding_hysteresis+position_dependent_force")
    cfg = LoopConfig(progress=False)
    res = run_loop(*runs, cfg)
    assert set(res.effects) == {"position_dependent_force", "presliding_hysteresis"}
    assert any(n.startswith("Fq_P") for n in res.final.params())
    whole_folds = lambda m, split, c, by_travel=None: select._cv_sse(m.X(split.est)[split.est_fit], split.est.y[split.est_fit], c.inner_folds)  # noqa: E731
    monkeypatch.setattr(select, "_cv", whole_folds)
    assert run_loop(*runs, cfg).effects == ["position_dependent_force"]


def test_a_warm_up_is_tested_on_the_chunks_where_it_acts(monkeypatch):
    """Seed 89 ``single-112``: friction warming up with a time constant of 2.6 s in a 15 s run
    gains 35 % on held-out data.  Over every chunk where the two models differ (the refitted
    baseline differs from the null's after the warm-up has died out) t = 2.7, below the floor of
    3; over the chunks where the warm-up acts t = 4.9, p = 0.0043 against a level of 0.0083.
    Tested over every chunk, the drift is missed."""
    import dataclasses

    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop.effects import CATALOGUE

    runs = _campaign_runs(89, "single-112-friction_drift")
    cfg = LoopConfig(progress=False)
    assert run_loop(*runs, cfg).effects == ["friction_drift"]
    eff = CATALOGUE["friction_drift"]
    monkeypatch.setitem(CATALOGUE, eff.name, dataclasses.replace(eff, acting=None))
    assert "friction_drift" not in run_loop(*runs, cfg).effects


def test_a_delay_clear_of_reversals_is_tested_on_chunks_cut_for_those_rows(monkeypatch):
    """A delay of the campaign's seed 59 (``single-097``, a run that reverses often) gaining 32 %
    on held-out data: clear of reversals and stops it gains 28 % at t = 3.0 over the 6 chunks
    that the cut of all rows leaves there (p = 0.015 on 5 degrees of freedom); cut by the same
    rule applied to those rows, 13 chunks, t = 4.5, it passes at the family-wise level.  Cut
    coarsely, and with the level split over every candidate (not only those the estimation run
    admits), those rows confirm it only at the nominal level, and it enters on the size of its
    gain there (more than a third of its gain on all rows) beyond a freely timed switch."""
    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop import heldout, select

    runs = _campaign_runs(59, "single-097-input_delay")
    cfg = LoopConfig(progress=False)
    res = run_loop(*runs, cfg)
    assert "input_delay" in res.effects
    step = next(s for s in res.steps if s.effect == "input_delay" and s.accepted)
    assert step.evidence["t_heldout_away_from_reversals"] >= cfg.t_threshold and "clear_of_reversals" not in step.evidence
    cut_like_all_rows = heldout.chunk_rows
    monkeypatch.setattr(heldout, "chunk_rows", lambda split, n: cut_like_all_rows(split, int(split.val_test.sum())))
    monkeypatch.setattr(select, "_screened", lambda *args: True)
    res = run_loop(*runs, cfg)
    coarse = next(s for s in res.steps if s.effect == "input_delay" and s.accepted)
    ev = coarse.evidence
    assert ev["t_heldout_away_from_reversals"] < step.evidence["t_heldout_away_from_reversals"]
    assert "clear_of_reversals" in ev and ev["validation_gain_away_from_reversals"] >= ev["validation_gain"] / 3


def test_a_delay_must_also_pass_on_all_moving_rows():
    """A clean rig of the campaign's seed 69 (drawn fresh for this check): a delay gains there
    clear of reversals and stops (t = 4.6), but nothing on all moving rows (t = 2.1, p = 0.027).
    Judged on the rows clear of reversals with all rows asked only for the nominal level, the
    loop named it; asking all rows for the family-wise level as well, it ends with nothing."""
    from gmsfric.loop import LoopConfig, run_loop

    res = run_loop(*_campaign_runs(69, "clean-256-clean"), LoopConfig(progress=False))
    assert res.effects == []
    step = next(s for s in res.steps if s.effect == "input_delay")
    assert step.evidence["t_heldout_away_from_reversals"] >= 3.0 and step.evidence["p_heldout"] > step.evidence["level"]


def test_the_timing_a_run_prefers_is_the_planted_one_on_an_ideal_rig():
    """`delay_timing.py` measures the shift the true model fits best on each run (the ceiling of
    any delay chosen on the estimation run).  On a rig with a negligible encoder step and no force
    noise, driven by a sweep, both runs must prefer the planted delay plus the sampling hold, to
    within the grid's quarter sample."""
    from loop_campaign import delay_timing
    from loop_campaign.cases import make_cases

    case = next(c for c in make_cases(69) if c["id"] == "single-107-input_delay")
    assert case["traj"]["est"]["kind"] == "sweep"
    ideal = delay_timing.timing(delay_timing.idealised(case))
    assert ideal.true > 4.0  # several samples beyond the timing alignment
    assert abs(ideal.est - ideal.true) <= delay_timing.STEP and abs(ideal.val - ideal.true) <= delay_timing.STEP
    logged = delay_timing.timing(case)
    assert logged.gain >= 0.10 and logged.reach >= 0.10  # detectable beyond the alignment, and reachable


def test_an_effect_that_gives_back_the_coulomb_level_the_baseline_lost_enters():
    """Seed 73 `single-150`: an offset of 25 N on an axis sliding at 39 N, estimated with the rigid
    baseline (no offset in it).  The run moves more one way than the other, so the baseline
    absorbs the offset into a Coulomb level of 19 N and a viscous coefficient six times too
    large.  The offset doubles the effective Coulomb level back to the rig's: it gives friction
    back instead of explaining it away, and enters (a guard on the level either way held it
    back)."""
    import warnings

    from gmsfric.loop import LoopConfig, run_loop

    runs = _campaign_runs(73, "single-150-offset")
    cfg = LoopConfig(progress=False, baseline=("inertia", "viscous", "coulomb"), effects=("offset",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = run_loop(*runs, cfg)
    true_fc = 39.2
    assert res.baseline.params()["Fc"]["value"] < 0.6 * true_fc
    assert res.effects == ["offset"]
    step = next(s for s in res.steps if s.effect == "offset" and s.accepted)
    assert step.evidence["baseline_parameters"]["Fc"]["ratio"] > cfg.max_parameter_ratio
    assert abs(res.final.params()["Fc"]["value"] - true_fc) < 0.1 * true_fc
    assert not [d for d in res.diagnostics if d["code"] == "held_back"]


def test_a_cable_pull_that_gives_back_the_coulomb_level_enters_on_a_rotary_joint():
    """Seed 101 `pair-154`: a rotary joint sliding at 0.344 N m, with a viscous asymmetry and a
    cable's pull (a tanh of the angle) that opposes the joint's motion more one way than the
    other on the estimation run.  The baseline takes the pull for friction lost, a Coulomb level
    of about half the rig's; the position force gives the level back (more than doubles it) and
    enters, then the asymmetry, and the final level is the rig's."""
    import warnings

    from gmsfric.loop import LoopConfig, run_loop

    case_id = "pair-154-asymmetric_friction+position_dependent_force"
    true_fc = next(c for c in campaign_cases.make_cases(101, emps=False) if c["id"] == case_id)["rig"]["Fc"]
    runs = _campaign_runs(101, case_id)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = run_loop(*runs, LoopConfig(progress=False))
    assert res.baseline.params()["Fc"]["value"] < 0.6 * true_fc
    assert sorted(res.effects) == ["asymmetric_friction", "position_dependent_force"]
    step = next(s for s in res.steps if s.effect == "position_dependent_force" and s.accepted)
    assert step.evidence["baseline_parameters"]["Fc"]["ratio"] > 2.0
    assert abs(res.final.params()["Fc"]["value"] - true_fc) < 0.1 * true_fc


def _named_delay(seed: int, case_id: str):
    """A campaign case's runs, the loop's configuration (the delay alone) and the step that names
    the delay, checked to be the planted one plus the sampling hold (half a controller period)
    within one log sample."""
    from gmsfric.loop import LoopConfig, run_loop

    runs = _campaign_runs(seed, case_id)
    cfg = LoopConfig(progress=False, effects=("input_delay",))
    res = run_loop(*runs, cfg)
    assert res.effects == ["input_delay"]
    case = next(c for c in campaign_cases.make_cases(seed, emps=False) if c["id"] == case_id)
    planted = next(e["tau"] for e in case["effects"] if e["name"] == "input_delay") + 0.5 / case["rig"]["f_ctrl"]
    dt = float(np.median(np.diff(runs[0].t)))
    assert abs(res.final.params()["delay_s"]["value"] - planted) <= dt
    return runs, cfg, next(s for s in res.steps if s.effect == "input_delay" and s.accepted)


def test_a_delay_must_beat_a_freely_timed_switch_of_friction(monkeypatch):
    """A clean Karnopp rig on random moves (the campaign's seed 81, 5 kHz): the contact sticks at
    every reversal, and the filtered velocity's sign switches about 8 samples off the friction's
    switch while the inertia is timed right.  Shifting the whole force by 3-4 samples trades one
    for the other and gains 22 % held out (t = 7.2): a false delay.  With the switch of friction
    free to take a time of its own in both the delay's model and its null, the delay keeps no
    significant gain and none is named; without that comparison, it enters."""
    from gmsfric.loop import LoopConfig, run_loop, select

    runs = _campaign_runs(81, "clean-243-clean")
    cfg = LoopConfig(progress=False, effects=("input_delay",))
    res = run_loop(*runs, cfg)
    assert res.effects == []
    step = next(s for s in res.steps if s.effect == "input_delay")
    assert step.evidence["validation_gain"] >= cfg.min_gain and step.evidence["t_heldout"] >= cfg.t_threshold
    assert step.evidence["t_heldout_beyond_a_free_switch"] < cfg.t_threshold and "switch of friction" in step.reason
    monkeypatch.setattr(select, "_with_switch_timing", lambda m, split, cfg: m)
    assert run_loop(*runs, cfg).effects == ["input_delay"]


def test_a_freely_timed_switch_that_fails_on_the_held_out_run_is_no_rival_of_a_delay(monkeypatch):
    """A Karnopp rig built by the campaign (seed 133), a 1.6 ms delay at 1 kHz, estimated on
    trapezoid moves and held out on a sweep.  The switch's timing chosen on the trapezoid's stops
    predicts the sweep worse than no switch at all; a delay compared against it loses (both models
    fail there), and against the null without it gains with t >= 3, also clear of reversals.  With
    the switch refuted on the held-out run the delay is named within one sample of the planted
    shift; kept as a rival regardless, it is not."""
    from gmsfric.loop import run_loop, select

    runs, cfg, step = _named_delay(133, "single-101-input_delay")
    assert step.evidence["free_switch_refuted_on_held_out_data"] is True
    assert step.evidence["t_heldout_away_from_reversals"] >= cfg.t_threshold
    monkeypatch.setattr(select, "_switch_refuted", lambda *a: False)
    assert run_loop(*runs, cfg).effects == []


def test_a_real_delay_keeps_its_gain_beyond_a_freely_timed_switch():
    """The same kind of rig (Karnopp contact, seed 81) with a planted 0.8 ms delay on trapezoid
    moves: the delay times the inertia too, which no switch of friction does; it keeps its
    held-out gain beyond a freely timed switch and is named within one sample of the planted
    shift (delay plus the sampling hold)."""
    from gmsfric.loop import select

    _, _, step = _named_delay(81, "single-103-input_delay")
    assert step.evidence["validation_gain_beyond_a_free_switch"] >= 0.5 * step.evidence["validation_gain"]
    # its gain is spread over the motion's frequencies, not held by one line
    assert step.evidence["gain_share_in_one_line"] < 0.5 * select.TONE_GAIN_SHARE


def test_a_delay_that_explains_far_more_than_a_free_switch_needs_it_only_at_the_nominal_level(monkeypatch):
    """A planted 1.2 ms delay (seed 103, 1 kHz log) gains 89 % held out and 83 % on the rows clear
    of reversals (t = 17), and keeps 91 % beyond a freely timed switch of friction; but the
    held-out run's models differ in only six chunks, where that gain is t = 2.6 (p = 0.024, above
    the family-wise level and below alpha).  A switch that explained the gain would leave the
    delay little of it: keeping half or more, the comparison needs only the nominal level and the
    delay is named, within one sample of the planted delay plus the sampling hold.  Held to the
    family-wise level there, it is refused.  So it was on the delay grid (1.6 samples with the
    sampling hold); refined between the grid's points, the delay passes beyond the free switch at
    the family-wise level on its own (t = 6.3), and is named without the relaxed level."""
    from gmsfric.loop import LoopConfig, run_loop, select

    case_id = "single-101-input_delay"
    runs = _campaign_runs(103, case_id)
    cfg = LoopConfig(progress=False, effects=("input_delay",))
    refined = run_loop(*runs, cfg)
    assert refined.effects == ["input_delay"]
    ev = next(s for s in refined.steps if s.effect == "input_delay" and s.accepted).evidence
    assert ev["t_heldout_beyond_a_free_switch"] >= cfg.t_threshold
    # the mechanism, on the grid's delay as the case was found
    monkeypatch.setattr(select, "_refine_delay", lambda best, split, cfg: best)
    res = run_loop(*runs, cfg)
    assert res.effects == ["input_delay"]
    ev = next(s for s in res.steps if s.effect == "input_delay" and s.accepted).evidence
    assert ev["validation_gain_beyond_a_free_switch"] >= select.DELAY_SWITCH_SHARE * ev["validation_gain"]
    assert ev["t_heldout_beyond_a_free_switch"] < cfg.t_threshold
    case = next(c for c in campaign_cases.make_cases(103, emps=False) if c["id"] == case_id)
    planted = next(e["tau"] for e in case["effects"] if e["name"] == "input_delay") + 0.5 / case["rig"]["f_ctrl"]
    dt = float(np.median(np.diff(runs[0].t)))
    assert abs(res.final.params()["delay_s"]["value"] - planted) <= dt
    monkeypatch.setattr(select, "DELAY_SWITCH_SHARE", np.inf)
    assert run_loop(*runs, cfg).effects == []


def test_a_delay_that_fits_one_tone_of_a_force_ripple_is_refused(monkeypatch):
    """A rig outside the catalogue (the campaign's seed 93): a force ripple of 7 N at 9.0 Hz in
    time acts on the axis, and the controller answers it.  Shifting the whole force by 10 ms
    turns the phase of the answer at 9 Hz and gains 15 % held out (t = 9): a false delay.  Nearly
    all of that gain lies within 5 % of the ripple's frequency, where the motion has under 1 % of
    its power, so the delay is refused as a tone; without that test, it enters."""
    from gmsfric.loop import LoopConfig, run_loop, select

    runs = _campaign_runs(93, "outside-215-ripple")
    cfg = LoopConfig(progress=False, effects=("input_delay",))
    res = run_loop(*runs, cfg)
    assert res.effects == []
    step = next(s for s in res.steps if s.effect == "input_delay" and "gain_share_in_one_line" in s.evidence)
    assert step.evidence["gain_share_in_one_line"] >= select.TONE_GAIN_SHARE
    assert abs(step.evidence["line_hz"] - 9.0) <= 0.3 and "oscillating in time" in step.reason
    monkeypatch.setattr(select, "_a_single_tone", lambda split, before, after, chunk, level, ev: None)
    assert run_loop(*runs, cfg).effects == ["input_delay"]


def test_a_delay_the_rows_clear_of_reversals_confirm_only_nominally_enters_when_they_keep_its_share():
    """A planted 1.4 ms delay (seed 83, rotary, 1 kHz log) passes every held-out test on all moving
    rows and beats a freely timed switch of friction, but the rows clear of reversals confirm it
    only at the nominal level (p between the family-wise level and alpha).  Those rows keep more
    than a third of its gain, as a delay of the whole force does: it is added, within one sample
    of the planted delay plus the sampling hold."""
    from gmsfric.loop import LoopConfig, run_loop

    case_id = "single-101-input_delay"
    runs = _campaign_runs(83, case_id)
    res = run_loop(*runs, LoopConfig(progress=False, effects=("input_delay",)))
    assert res.effects == ["input_delay"]
    step = next(s for s in res.steps if s.effect == "input_delay" and s.accepted)
    ev = step.evidence
    assert "clear_of_reversals" in ev and ev["validation_gain_away_from_reversals"] >= ev["validation_gain"] / 3
    case = next(c for c in campaign_cases.make_cases(83, emps=False) if c["id"] == case_id)
    planted = next(e["tau"] for e in case["effects"] if e["name"] == "input_delay") + 0.5 / case["rig"]["f_ctrl"]
    dt = float(np.median(np.diff(runs[0].t)))
    assert abs(res.final.params()["delay_s"]["value"] - planted) <= dt


def test_a_delay_gaining_mostly_next_to_reversals_is_reported_not_added():
    """A clean rig (seed 83, static contact in the core, random moves with feedforward): a delay
    of 2.5 ms passes the held-out tests on all moving rows and beats a freely timed switch of
    friction, but the rows clear of reversals keep a fifth of its gain (the contact's sticking
    lag sits next to reversals).  Not added; reported as `unconfirmed` with the delay in ms."""
    from gmsfric.loop import LoopConfig, run_loop

    runs = _campaign_runs(83, "clean-269-clean")
    res = run_loop(*runs, LoopConfig(progress=False, effects=("input_delay",)))
    assert res.effects == []
    step = next(s for s in res.steps if s.effect == "input_delay")
    ev = step.evidence
    assert ev["unconfirmed_clear_of_reversals"] and ev["validation_gain_away_from_reversals"] < ev["validation_gain"] / 3
    flagged = [d for d in res.diagnostics if d["code"] == "unconfirmed"]
    assert len(flagged) == 1 and flagged[0]["parameter"] == "input_delay"
    assert f"{1e3 * step.parameters['delay_s']['value']:.3g} ms" in flagged[0]["message"]


def test_a_delay_no_better_than_a_freely_timed_switch_is_not_reported():
    """A clean rotary rig (seed 83, Karnopp contact of the campaign's own simulator) whose delay
    candidate fails only the rows clear of reversals, where it is consistent at the nominal level,
    but gains nothing beyond a freely timed switch of friction: neither added nor reported as
    unconfirmed."""
    from gmsfric.loop import LoopConfig, run_loop

    runs = _campaign_runs(83, "clean-275-clean")
    res = run_loop(*runs, LoopConfig(progress=False, effects=("input_delay",)))
    assert res.effects == []
    step = next(s for s in res.steps if s.effect == "input_delay")
    assert "t_heldout_beyond_a_free_switch" in step.evidence and not step.evidence.get("unconfirmed_clear_of_reversals")
    assert not [d for d in res.diagnostics if d["code"] == "unconfirmed"]


def test_a_delay_must_gain_the_minimum_gain_clear_of_reversals():
    """A position-force rig (seed 85, nothing delayed): after the position force enters, a delay
    of about 1.4 ms passes the held-out tests on all moving rows (gain about 8 %) and, at t near
    4, on the rows clear of reversals, where it removes only about 3 % of the error.  A delay of
    the whole force gains there as it does everywhere the axis accelerates (0.12-0.97 over the
    delays named on seeds 79-83): held to the minimum gain there too, it is not added."""
    from gmsfric.loop import LoopConfig, run_loop

    runs = _campaign_runs(85, "single-077-position_dependent_force")
    res = run_loop(*runs, LoopConfig(progress=False, effects=("position_dependent_force", "input_delay")))
    assert res.effects == ["position_dependent_force"]
    delay_steps = [s for s in res.steps if s.effect == "input_delay" and "validation_gain_away_from_reversals" in s.evidence]
    assert delay_steps and all(not s.accepted for s in delay_steps)
    assert any(s.evidence["validation_gain"] >= 0.05 and s.evidence["validation_gain_away_from_reversals"] < 0.05 for s in delay_steps)


def test_a_rounds_level_is_shared_only_by_candidates_the_estimation_run_admits(monkeypatch):
    """Seed 79 `single-117`: a friction drift gaining 5.2 % on held-out data at t = 3.3, p = 0.0043.
    Split over every catalogue effect tried in round one (level 0.0028) that refuses it, though
    all the others are refused on the estimation run alone (no physical fit, no cross-validated
    gain, no lower BIC) and could not have entered whatever the held-out run showed.  The level
    is split over the candidates that pass those checks, so the drift enters; counting every
    candidate again, it does not."""
    import warnings

    from gmsfric.loop import LoopConfig, run_loop, select

    runs = _campaign_runs(79, "single-117-friction_drift")
    cfg = LoopConfig(progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = run_loop(*runs, cfg)
    assert res.effects == ["friction_drift"]
    first = [s for s in res.steps if s.round == 1]
    estimation_only = ("no physically valid fit", "no cross-validated gain", "cross-validated error gain on estimation data",
                       "BIC does not decrease", "implausible baseline")
    admitted = [s for s in first if not any(why in s.reason for why in estimation_only)]
    drift = next(s for s in first if s.effect == "friction_drift")
    assert drift.accepted and 1 <= len(admitted) < len(first)
    assert drift.evidence["level_shared_by"] == len(admitted)
    assert drift.evidence["level"] == pytest.approx(cfg.level(1, len(admitted)), rel=1e-2)
    assert drift.evidence["p_heldout"] > cfg.level(1, len(first))
    monkeypatch.setattr(select, "_screened", lambda *args: True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert run_loop(*runs, cfg).effects == []


def test_an_effect_must_explain_the_run_it_was_fitted_on_too():
    """Seed 111 `clean-263` (a clean rig with a GMS contact): a resonance that lowers the
    estimation run's cross-validated error by 0.6 % lowers the held-out run's by 23 % at t = 6.3,
    what it resembles of the contact's frictional lag there.  The effect must explain the run it
    was fitted on by ``min_estimation_gain`` too, so nothing is added; asking only for a
    cross-validated gain, the resonance is named."""
    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop.select import error_gain

    runs = _campaign_runs(111, "clean-263-clean")
    cfg = LoopConfig(progress=False)
    res = run_loop(*runs, cfg)
    assert res.effects == []
    tried = next(s for s in res.steps if s.effect == "compliance" and s.round == 1)
    ev = tried.evidence
    assert "cross-validated error gain on estimation data" in tried.reason
    assert 0 < error_gain(ev["cv_gain"]) < cfg.min_estimation_gain
    assert ev["validation_gain"] >= 2 * cfg.min_gain and ev["t_heldout"] >= cfg.t_threshold
    assert run_loop(*runs, LoopConfig(progress=False, min_estimation_gain=0.0)).effects == ["compliance"]


def test_resolution_bands_place_each_contact_by_its_widest_block_and_each_delay_by_log_samples(tmp_path, capsys):
    """The resolution report (information beside the targets): a contact's widest break
    displacement in encoder steps, whatever model carries it, and a delay in log samples."""
    import json
    import math

    from loop_campaign import resolution

    rig = {"Fc": 4.0, "M": 2.0, "quant": 1e-6}
    rng = np.random.default_rng(3)
    for model in ("maxwell", "gms"):
        c = campaign_cases.contact(rig, rng, model, 2e-6)
        brk = [w / k for k, w in zip(c["k"], c.get("w", [rig["Fc"] * a for a in c.get("alpha", [])]))]
        assert math.isclose(resolution.widest_break(c), max(brk), rel_tol=1e-12)
        assert 2e-6 * 3.0 * 0.7 <= resolution.widest_break(c) <= 2e-6 * 3.0 * 1.4  # the widest of the three blocks
    assert math.isclose(resolution.widest_break(campaign_cases.contact(rig, rng, "lugre", 2e-6)), 2e-6)
    assert resolution.widest_break({"model": "karnopp"}) is None

    maxwell = {"model": "maxwell", "k": [4.0 / 2.5e-6], "w": [4.0]}  # 2.5 steps wide
    specs = [{"id": "p", "rig": dict(rig, contact=maxwell), "effects": [{"name": "presliding_hysteresis"}]},
             {"id": "d", "rig": dict(rig, contact={"model": "karnopp"}), "effects": [{"name": "input_delay", "tau": 0.0015}]},
             {"id": "x", "rig": dict(rig, contact={"model": "karnopp"}), "effects": [{"name": "offset"}]},
             {"id": "e", "effects": [{"name": "presliding_hysteresis"}]}]  # real runs: no contact known
    results = [{"id": "p", "status": "ok", "accepted": [], "truth": {"fs": 1000.0, "effects": {
                    "presliding_hysteresis": {"detectable": True, "detectable_moving": True, "detectable_beyond_null": False}}}},
               {"id": "d", "status": "ok", "accepted": ["input_delay"], "truth": {"fs": 1000.0, "effects": {
                    "input_delay": {"detectable": True, "detectable_beyond_null": True}}}},
               {"id": "x", "status": "ok", "accepted": ["offset"], "truth": {"fs": 1000.0, "effects": {"offset": {"detectable": True}}}},
               {"id": "e", "status": "ok", "accepted": [], "truth": {"fs": 1000.0, "effects": {"presliding_hysteresis": {"detectable": True}}}}]
    (tmp_path / "cases.json").write_text(json.dumps(specs))
    (tmp_path / "results.json").write_text(json.dumps({"cases": results}))
    found = resolution.rows([tmp_path])
    name = tmp_path.name
    assert found == [(f"{name}/p", "presliding_hysteresis", "1-3 steps", True, True, False, False),
                     (f"{name}/d", "input_delay", "1-2 samples", True, False, True, True)]
    assert resolution.main([str(tmp_path / "missing")]) == 2 and "no results.json" in capsys.readouterr().err
    assert resolution.main([str(tmp_path), str(tmp_path)]) == 2 and "named twice" in capsys.readouterr().err
    (tmp_path / "cases.json").write_text("not json")
    assert resolution.main([str(tmp_path)]) == 2 and "not the files of a finished campaign" in capsys.readouterr().err
    (tmp_path / "cases.json").write_text("[]")
    (tmp_path / "results.json").write_text('{"cases": 5}')
    assert resolution.main([str(tmp_path)]) == 2 and "not the files of a finished campaign" in capsys.readouterr().err

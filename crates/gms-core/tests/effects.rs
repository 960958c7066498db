//! Effects in feedback: each effect against a closed-form property of the mechanics it adds,
//! and the guards that keep hostile input from aborting, hanging or returning NaN.
use gms_core::reference;
use gms_core::*;
use std::sync::atomic::AtomicBool;

fn rigid(mass: f64) -> Plant {
    Plant::from_mass(mass, 0.0, 0.0, 0.0, 1.0).unwrap()
}

fn coulomb(level: f64, sigma: f64) -> FrictionModel {
    FrictionModel::Static(StaticElement::new(StaticFriction::new(Stribeck::constant(level).unwrap(), sigma).unwrap()))
}

#[test]
fn empty_effects_change_nothing() {
    let dt = 1e-4;
    let r = reference::paper_sine(20_000, dt, 2e-4, 2.0);
    let input = ClosedLoopInput::new(&r, dt);
    let ctrl = ControllerModel::Pid(reference::paper_pid());
    let gms = FrictionModel::Gms(reference::paper_gms());
    let plain = simulate(&reference::paper_plant(), Some(&gms), None, Some(&ctrl), &input).unwrap();
    let empty = simulate(&reference::paper_plant(), Some(&gms), Some(&Effects::default()), Some(&ctrl), &input).unwrap();
    assert_eq!(plain.position, empty.position);
    assert_eq!(plain.friction, empty.friction);
}

#[test]
fn position_force_is_a_spring_in_feedback() {
    // g(q) = k q on [-1, 1] (Legendre P1), mass m, no friction: free oscillation at sqrt(k/m).
    let (m, k, dt) = (2.0, 800.0, 1e-4);
    let effects = Effects { position_force: Some(PositionSeries::Legendre { lo: -1.0, hi: 1.0, coef: vec![0.0, k], linear_beyond: false }), ..Default::default() };
    let u = vec![0.0; 40_000];
    let mut input = ClosedLoopInput::open(&u, dt);
    input.initial_position = 1e-3;
    let out = simulate(&rigid(m), None, Some(&effects), None, &input).unwrap();
    let w = (k / m).sqrt();
    for (i, &x) in out.position.iter().enumerate().step_by(997) {
        let want = 1e-3 * (w * i as f64 * dt).cos();
        // The force over each step is the spring's at mid-step (linearised in the step's
        // displacement): no energy creeps in, the amplitude holds over these 4 s.
        assert!((x - want).abs() < 2e-6, "t = {}: {x} vs {want}", i as f64 * dt);
    }
}

#[test]
fn compliant_load_adds_its_mass_at_low_frequency_and_rings_at_the_two_mass_frequency() {
    let (m1, m2, fn_hz, dt) = (3.0, 1.0, 20.0, 1e-4);
    let comp = Compliance::new(m2, fn_hz, 0.0).unwrap();
    let effects = Effects { compliance: Some(comp), ..Default::default() };
    // A constant push: the mean acceleration is F / (m1 + m2).
    let f = vec![4.0; 50_000];
    let out = simulate(&rigid(m1), None, Some(&effects), None, &ClosedLoopInput::open(&f, dt)).unwrap();
    let t_end = (f.len() - 1) as f64 * dt;
    let v_mean = out.velocity.iter().sum::<f64>() / f.len() as f64;
    let a_est = 2.0 * v_mean / t_end;
    assert!((a_est - 1.0).abs() < 0.01, "mean acceleration {a_est}, expected 1.0");
    // The motor's velocity oscillates around the mean at the two-mass frequency
    // w = w_n sqrt(1 + m2 / m1) (the load on a spring behind a free motor).
    let w = 2.0 * std::f64::consts::PI * fn_hz * (1.0 + m2 / m1).sqrt();
    let detrended: Vec<f64> = out.velocity.iter().enumerate().map(|(i, v)| v - 1.0 * i as f64 * dt).collect();
    let crossings: Vec<usize> = (1..detrended.len()).filter(|&i| detrended[i - 1] < 0.0 && detrended[i] >= 0.0).collect();
    let period = (crossings[crossings.len() - 1] - crossings[0]) as f64 * dt / (crossings.len() - 1) as f64;
    let want = 2.0 * std::f64::consts::PI / w;
    assert!((period - want).abs() < 0.01 * want, "period {period} vs {want}");
}

#[test]
fn asymmetric_levels_hold_per_direction_at_steady_velocity() {
    // A viscous plant pushed open loop: at steady velocity, friction = push - b_plant v, and the
    // friction per direction is (fc +- d_level) + (sigma +- d_viscous) |v|.
    let (fc, sigma, dl, dv, dt) = (5.0, 20.0, 1.5, 4.0, 1e-3);
    let plant = Plant::from_mass(1.0, 0.0, 0.0, 0.0, 1.0).unwrap();
    let effects = Effects { asymmetry: Some(Asymmetry { d_level: dl, d_viscous: dv }), ..Default::default() };
    for push in [30.0, -30.0] {
        let u = vec![push; 20_000];
        let out = simulate(&plant, Some(&coulomb(fc, sigma)), Some(&effects), None, &ClosedLoopInput::open(&u, dt)).unwrap();
        let v = *out.velocity.last().unwrap();
        let dir: f64 = if push > 0.0 { 1.0 } else { -1.0 };
        let want = (push.abs() - (fc + dir * dl)) / (sigma + dir * dv);
        assert!((v.abs() - want).abs() < 1e-9 * want, "push {push}: |v| = {} vs {want}", v.abs());
    }
}

#[test]
fn drifting_friction_follows_its_time_law() {
    let (fc, dl, tau, dt) = (5.0, 2.0, 3.0, 1e-3);
    let plant = Plant::from_mass(1.0, 0.0, 0.0, 0.0, 1.0).unwrap();
    let effects = Effects { drift: Some(Drift { shape: DriftShape::Exponential { tau }, d_level: dl, d_viscous: 0.0 }), ..Default::default() };
    // Viscous friction makes the velocity settle fast on the slowly drifting level.
    let u = vec![40.0; 6000];
    let out = simulate(&plant, Some(&coulomb(fc, 100.0)), Some(&effects), None, &ClosedLoopInput::open(&u, dt)).unwrap();
    for k in [2000usize, 4000, 5999] {
        let level = fc + dl * (-(k as f64) * dt / tau).exp();
        let f_expected = level + 100.0 * out.velocity[k];
        assert!((out.friction[k] - f_expected).abs() < 0.02, "t = {}: {} vs {f_expected}", k as f64 * dt, out.friction[k]);
    }
}

#[test]
fn position_dependent_friction_sets_the_breakaway_level_where_the_axis_stands() {
    // Coulomb 2 N plus g(q) = 3 N at q = +1 (P1 on [-1, 1]): at q = 1 the contact holds 4.5 N,
    // at q = -1 it gives way to the same push.
    let effects = Effects { position_friction: Some(PositionSeries::Legendre { lo: -1.0, hi: 1.0, coef: vec![0.0, 3.0], linear_beyond: false }), ..Default::default() };
    let u = vec![4.5; 1000];
    for (q0, moves) in [(1.0, false), (-1.0, true)] {
        let mut input = ClosedLoopInput::open(&u, 1e-3);
        input.initial_position = q0;
        let out = simulate(&rigid(1.0), Some(&coulomb(2.0, 0.0)), Some(&effects), None, &input).unwrap();
        let moved = (out.position.last().unwrap() - q0).abs();
        assert_eq!(moved > 1e-6, moves, "q0 = {q0}: moved {moved}");
    }
}

#[test]
fn presliding_blocks_follow_their_virgin_curve_in_feedback() {
    // A slowly increasing push on a mass held by Coulomb friction (rigid stiction, 2 N) plus one
    // block (k, w = 1 N): nothing moves below 2 N, then the block alone deflects by
    // (push - 2 N) / k, and beyond 3 N the axis slides.
    let (k, w, dt) = (1e6, 1.0, 1e-4);
    let blocks = MaxwellSlip::new(vec![k], vec![w], 0.0).unwrap();
    let effects = Effects { blocks: Some(blocks), ..Default::default() };
    let n = 40_000;
    let u: Vec<f64> = (0..n).map(|i| 4.0 * i as f64 / n as f64).collect();
    let out = simulate(&rigid(0.5), Some(&coulomb(2.0, 0.0)), Some(&effects), None, &ClosedLoopInput::open(&u, dt)).unwrap();
    let at = |push: f64| out.position[(push / 4.0 * n as f64) as usize];
    assert!(at(1.5).abs() < 1e-15, "below the Coulomb level nothing moves: {}", at(1.5));
    for push in [2.3, 2.6, 2.9] {
        let want = (push - 2.0) / k;
        assert!((at(push) - want).abs() < 0.02 * want, "push {push}: x = {} vs {want}", at(push));
    }
    assert!(out.position[n - 1] > 1e-3, "beyond w + Fc the axis slides");
}

#[test]
fn level_shifts_need_a_static_map() {
    let effects = Effects { asymmetry: Some(Asymmetry { d_level: 1.0, d_viscous: 0.0 }), ..Default::default() };
    let err = Axis::new(reference::paper_plant(), Some(FrictionModel::Gms(reference::paper_gms())), Some(effects)).unwrap_err();
    assert!(matches!(err, CoreError::InvalidParameter { name: "effects", .. }), "{err}");
}

#[test]
fn hostile_inputs_give_typed_errors_not_aborts_or_nan() {
    // A delay of 1e12 steps on a 10-sample run: no 8 TB allocation, the input never arrives.
    let plant = Plant::new(1.0, 10.0, 0.0, 1e3, 1.0).unwrap();
    let r = vec![1.0; 10];
    let ctrl = ControllerModel::Pid(Pid::new(100.0, 0.0, 0.0, 0.0, f64::NEG_INFINITY, f64::INFINITY).unwrap());
    let out = simulate(&plant, None, None, Some(&ctrl), &ClosedLoopInput::new(&r, 1e-9)).unwrap();
    assert!(out.position.iter().all(|&x| x == 1.0), "nothing arrives through the delay");
    // A delay beyond 2^52 steps is "never", not a wrapped-around short delay.
    let huge = Plant::new(1.0, 10.0, 0.0, 1e30, 1.0).unwrap();
    let u = vec![1.0; 100];
    let (y, _) = simulate_open_loop(&huge, 1e-3, &u).unwrap();
    assert!(y.iter().all(|&x| x == 0.0));
    // Dynamics far faster than the step: refused at once (no endless squaring).
    for (b, c) in [(1e44, 0.0), (0.0, 1e100)] {
        let err = simulate_open_loop(&Plant::new(1.0, b, c, 0.0, 1.0).unwrap(), 1e-3, &[1.0; 3]).unwrap_err();
        assert!(matches!(err, CoreError::InvalidParameter { name: "plant", .. }), "{err}");
    }
    // An overflowing derivative gain: the non-finite command is named, with its step.
    let ctrl = ControllerModel::Pid(Pid::new(1.0, 0.0, 1e308, 0.0, f64::NEG_INFINITY, f64::INFINITY).unwrap());
    let r: Vec<f64> = (0..10).map(|k| k as f64).collect();
    let err = simulate(&reference::paper_plant(), None, None, Some(&ctrl), &ClosedLoopInput::new(&r, 1e-3)).unwrap_err();
    assert!(matches!(err, CoreError::NonFiniteOutput { .. } | CoreError::InvalidParameter { name: "kd", .. }), "{err}");
    // Subnormal steps and resolutions are refused before any work.
    assert!(matches!(reference::paper_plant().discretize(1e-310), Err(CoreError::NotPositive { name: "dt", .. })));
    let mut input = ClosedLoopInput::new(&r, 1e-3);
    input.quantization = 1e-320;
    assert!(matches!(input.validate(true), Err(CoreError::NotPositive { .. } | CoreError::InvalidParameter { .. })));
    // An impossible allocation is an error value.
    assert!(matches!(error::try_zeroed("outputs", usize::MAX / 4), Err(CoreError::TooLarge { .. })));
}

#[test]
fn a_set_cancel_flag_interrupts_a_long_run() {
    let dt = 1e-4;
    let r = vec![0.0; 1_000_000];
    let cancel = AtomicBool::new(true);
    let mut input = ClosedLoopInput::new(&r, dt);
    input.cancel = Some(&cancel);
    let ctrl = ControllerModel::Pid(reference::paper_pid());
    let err = simulate(&reference::paper_plant(), None, None, Some(&ctrl), &input).unwrap_err();
    assert_eq!(err, CoreError::Interrupted);
}

#[test]
fn recording_a_subset_with_decimation_gives_the_same_samples() {
    let dt = 1e-4;
    let r = reference::paper_sine(10_001, dt, 2e-4, 2.0);
    let input = ClosedLoopInput::new(&r, dt);
    let ctrl = ControllerModel::Pid(reference::paper_pid());
    let gms = FrictionModel::Gms(reference::paper_gms());
    let full = simulate(&reference::paper_plant(), Some(&gms), None, Some(&ctrl), &input).unwrap();
    let every = 7;
    let m = r.len().div_ceil(every);
    let (mut err, mut fric) = (vec![0.0; m], vec![0.0; m]);
    let out = ClosedLoopBuffers { error: Some(&mut err), friction: Some(&mut fric), every, ..Default::default() };
    simulate_into(&reference::paper_plant(), Some(&gms), None, Some(&ctrl), &input, out).unwrap();
    for (j, k) in (0..r.len()).step_by(every).enumerate() {
        assert_eq!(err[j], r[k] - full.position[k]);
        assert_eq!(fric[j], full.friction[k]);
    }
}

#[test]
fn the_cascade_starts_with_the_initial_velocity() {
    // Free mass coasting at v0 with a zero reference slope: a cascade that knows the motion
    // brakes from the first sample (its velocity feedback sees v0), one that starts from rest
    // reads zero velocity on the first sample.
    let (dt, v0) = (1e-3, 0.05);
    let r = vec![0.0; 3];
    let ctrl = ControllerModel::Cascade(Cascade::new(0.0, 10.0, f64::NEG_INFINITY, f64::INFINITY).unwrap());
    let mut input = ClosedLoopInput::new(&r, dt);
    input.initial_velocity = v0;
    let out = simulate(&rigid(1.0), None, None, Some(&ctrl), &input).unwrap();
    assert!((out.command[0] + 10.0 * v0).abs() < 1e-12, "first command {} vs {}", out.command[0], -10.0 * v0);
}

#[test]
fn heating_lowers_friction_with_the_low_passed_speed() {
    // Constant push on a viscous-dominated contact: the speed settles fast, the low-passed speed
    // m follows with tau, and the Coulomb level falls by d_level * m.
    let (fc, sigma, tau, dl, dt) = (5.0, 100.0, 2.0, -10.0, 1e-3);
    let effects = Effects { heating: Some(Heating { tau, d_level: dl, d_viscous: 0.0 }), ..Default::default() };
    let u = vec![40.0; 8000];
    let out = simulate(&rigid(1.0), Some(&coulomb(fc, sigma)), Some(&effects), None, &ClosedLoopInput::open(&u, dt)).unwrap();
    let mut m = 0.0;
    for k in 0..u.len() {
        if k > 100 && k % 1000 == 0 {
            let want = fc + dl * m + sigma * out.velocity[k];
            assert!((out.friction[k] - want).abs() < 0.02, "t = {}: {} vs {want}", k as f64 * dt, out.friction[k]);
        }
        let v = if k + 1 < u.len() { (out.position[k + 1] - out.position[k]) / dt } else { 0.0 };
        m = v.abs() + (m - v.abs()) * (-dt / tau).exp();
    }
    // At a constant push the total friction balances it: a lower level shows as a higher speed.
    assert!(out.velocity[7999] > out.velocity[500] + 0.02, "the axis speeds up as the contact warms");
}

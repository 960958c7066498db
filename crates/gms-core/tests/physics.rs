//! Physics properties of the friction models and the plant.

use gms_core::reference;
use gms_core::*;

fn ramp(n: usize, dt: f64, v: f64) -> (Vec<f64>, Vec<f64>) {
    let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
    let x = t.iter().map(|&tk| v * tk).collect();
    (t, x)
}

/// Piecewise-linear path through `points` (positions), `steps` samples per leg.
fn path(points: &[f64], steps: usize, dt: f64) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![points[0]];
    for w in points.windows(2) {
        for s in 1..=steps {
            x.push(w[0] + (w[1] - w[0]) * s as f64 / steps as f64);
        }
    }
    let t = (0..x.len()).map(|k| k as f64 * dt).collect();
    (t, x)
}

#[test]
fn gms_settles_on_stribeck_curve_at_constant_velocity() {
    let g = reference::paper_gms();
    let map = StaticFriction::new(g.stribeck, g.sigma).unwrap();
    for &v in &[2e-5, 1e-4, 4.5e-4, 2e-3, 3e-2, -1e-4, -5e-3] {
        let mut m = g.clone();
        let (t, x) = ramp(20_000, 1e-3, v);
        let f = simulate_position(&mut m, &t, &x).unwrap();
        let expected = map.force(v);
        let got = *f.last().unwrap();
        assert!((got - expected).abs() < 1e-9 * expected.abs().max(1.0), "v={v}: {got} vs {expected}");
    }
}

#[test]
fn slow_virgin_curve_is_sum_of_saturated_springs() {
    let g = reference::paper_gms();
    let fs = g.stribeck.fs;
    let (t, x) = path(&[0.0, 20e-6], 4000, 1.0); // 5 nm/s: quasi-static
    let mut m = g.clone();
    let f = simulate_position(&mut m, &t, &x).unwrap();
    for (xi, fi) in x.iter().zip(&f).step_by(50) {
        let virgin: f64 = g.k.iter().zip(&g.alpha).map(|(k, a)| (k * xi).min(a * fs)).sum();
        assert!((fi - virgin).abs() < 2e-4 * fs, "x={xi}: {fi} vs {virgin}");
    }
}

#[test]
fn reversal_branch_follows_masing_rule() {
    let ms = MaxwellSlip::new(vec![1e6, 2e5, 5e4], vec![0.1, 0.2, 0.3], 0.0).unwrap();
    let virgin = |x: f64| -> f64 { ms.k.iter().zip(&ms.w).map(|(k, w)| (k * x.abs()).min(*w)).sum::<f64>() * x.signum() };
    let xr = 4e-6;
    let (t, x) = path(&[0.0, xr, -xr], 2000, 1e-3);
    let mut m = ms.clone();
    let f = simulate_position(&mut m, &t, &x).unwrap();
    let fr = f[2000];
    assert!((fr - virgin(xr)).abs() < 1e-12);
    for k in (2000..x.len()).step_by(37) {
        let masing = fr - 2.0 * virgin((xr - x[k]) / 2.0);
        assert!((f[k] - masing).abs() < 1e-9, "k={k}: {} vs {}", f[k], masing);
    }
}

#[test]
fn inner_loops_close_and_memory_is_wiped_out() {
    // Outer branch up to xa, inner loop xa -> xb -> xa, then continue: the force must return to
    // its value at xa (closure), and continuing beyond xa follows the original branch.
    for model in [FrictionModel::Gms(reference::paper_gms()), FrictionModel::MaxwellSlip(MaxwellSlip::new(vec![1e6, 1e5, 1e4], vec![0.05, 0.05, 0.1], 0.0).unwrap())] {
        let (xa, xb, xc) = (3e-6, 1e-6, 6e-6);
        let dt = 1.0; // very slow: quasi-static
        let (t1, x1) = path(&[0.0, xa, xb, xa, xc], 3000, dt);
        let (t2, x2) = path(&[0.0, xa, xc], 3000, dt);
        let mut m1 = model.clone();
        let mut m2 = model.clone();
        let f1 = with_friction!(&mut m1, f => simulate_position(f, &t1, &x1)).unwrap();
        let f2 = with_friction!(&mut m2, f => simulate_position(f, &t2, &x2)).unwrap();
        let scale = f2.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        assert!((f1[3000] - f1[9000]).abs() < 1e-3 * scale, "inner loop does not close: {} vs {}", f1[3000], f1[9000]);
        assert!((f1.last().unwrap() - f2.last().unwrap()).abs() < 1e-3 * scale, "memory of the inner loop not wiped out");
        // the inner loop encloses area (it is a hysteresis loop, not a line)
        let loop_area: f64 = (3000..9000).map(|k| 0.5 * (f1[k] + f1[k + 1]) * (x1[k + 1] - x1[k])).sum();
        assert!(loop_area.abs() > 0.0);
    }
}

#[test]
fn closed_cycles_dissipate_energy() {
    for amplitude in [5e-9, 2e-7, 5e-6, 1e-3] {
        for model in [
            FrictionModel::Gms(reference::paper_gms()),
            FrictionModel::LuGre(LuGre::new(reference::paper_stribeck(), 1e6, 50.0, 5.0).unwrap()),
            FrictionModel::MaxwellSlip(MaxwellSlip::new(vec![1e6, 1e5], vec![0.1, 0.1], 1.0).unwrap()),
        ] {
            let n = 20_000;
            let dt = 1e-4;
            let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
            let x: Vec<f64> = t.iter().map(|&tk| amplitude * (2.0 * std::f64::consts::PI * 1.0 * tk).sin()).collect();
            let mut m = model.clone();
            let f = with_friction!(&mut m, f => simulate_position(f, &t, &x)).unwrap();
            // work done on the contact over the second cycle (the first is the virgin transient)
            let work: f64 = (n / 2..n - 1).map(|k| f[k + 1] * (x[k + 1] - x[k])).sum();
            assert!(work > 0.0, "amplitude {amplitude}: cycle work {work} must be > 0 (passivity)");
        }
    }
}

#[test]
fn gms_converges_with_step_and_is_accurate_at_coarse_steps() {
    let g = reference::paper_gms();
    let run = |dt: f64| -> f64 {
        // compare at t = 1 s along a sine of 20 µm at 1 Hz (pre-sliding and sliding)
        let n = (2.0 / dt).round() as usize + 1;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let x: Vec<f64> = t.iter().map(|&tk| 20e-6 * (2.0 * std::f64::consts::PI * tk).sin()).collect();
        let mut m = g.clone();
        let f = simulate_position(&mut m, &t, &x).unwrap();
        let i = ((1.3 / dt).round()) as usize;
        f[i]
    };
    let fine = run(1e-6);
    let e_ref = (run(1e-5) - fine).abs();
    let e_coarse = (run(1e-4) - fine).abs();
    let e_coarser = (run(1e-3) - fine).abs();
    let scale = g.stribeck.fs;
    assert!(e_ref <= e_coarse + 1e-12, "error must not grow as the step shrinks: {e_ref} vs {e_coarse}");
    assert!(e_coarse < 1e-2 * scale, "1e-4 s step error {e_coarse}");
    assert!(e_coarser < 5e-2 * scale, "10x coarser step error {e_coarser}");
}

#[test]
fn plant_step_response_matches_analytic() {
    let p = Plant::new(0.01985, 168.4, 176.8, 0.0, 1.0).unwrap();
    let dt = 1e-3;
    let u = vec![1.0; 3000];
    let (y, v) = simulate_open_loop(&p, dt, &u).unwrap();
    // roots of s^2 + b s + c
    let disc = (p.b * p.b - 4.0 * p.c).sqrt();
    let (r1, r2) = ((-p.b + disc) / 2.0, (-p.b - disc) / 2.0);
    let yinf = p.a / p.c;
    for k in (0..3000).step_by(97) {
        let t = k as f64 * dt;
        let exact = yinf * (1.0 + (r2 * (r1 * t).exp() - r1 * (r2 * t).exp()) / (r1 - r2));
        let vel = yinf * r1 * r2 * ((r1 * t).exp() - (r2 * t).exp()) / (r1 - r2);
        assert!((y[k] - exact).abs() < 1e-12 + 1e-9 * yinf, "t={t}: {} vs {exact}", y[k]);
        assert!((v[k] - vel).abs() < 1e-9 * yinf * 200.0, "t={t}: v {} vs {vel}", v[k]);
    }
}

#[test]
fn plant_sine_steady_state_matches_frequency_response() {
    let p = Plant::new(0.01985, 168.4, 176.8, 0.0, 1.0).unwrap();
    let dt = 1e-4;
    let f = 20.0;
    let w = 2.0 * std::f64::consts::PI * f;
    // Sample the input at mid-step so the ZOH approximates the sine to second order.
    let n = 250_000; // 25 s: the slow pole (-1.06 1/s) has decayed
    let u: Vec<f64> = (0..n).map(|k| (w * (k as f64 + 0.5) * dt).sin()).collect();
    let (y, _) = simulate_open_loop(&p, dt, &u).unwrap();
    // analytic steady-state amplitude and phase
    let den_re = p.c - w * w;
    let den_im = p.b * w;
    let mag = p.a / (den_re * den_re + den_im * den_im).sqrt();
    let phase = -den_im.atan2(den_re);
    for k in (n - 5000..n).step_by(111) {
        let t = k as f64 * dt;
        let exact = mag * (w * t + phase).sin();
        assert!((y[k] - exact).abs() < 2e-3 * mag, "t={t}: {} vs {exact}", y[k]);
    }
}

#[test]
fn fractional_delay_is_exact() {
    // A step delayed by 2.37 steps equals the undelayed analytic response shifted by the delay.
    let dt = 1e-3;
    let tau = 2.37e-3;
    let p = Plant::new(2.0, 3.0, 0.0, tau, 1.0).unwrap();
    let u = vec![1.0; 200];
    let (y, _) = simulate_open_loop(&p, dt, &u).unwrap();
    // y(t) for unit step into a/(s(s+b)): a/b (t - (1 - e^{-b t})/b)
    let resp = |t: f64| if t <= 0.0 { 0.0 } else { p.a / p.b * (t - (1.0 - (-p.b * t).exp()) / p.b) };
    for k in 0..200 {
        let t = k as f64 * dt;
        assert!((y[k] - resp(t - tau)).abs() < 1e-13, "k={k}: {} vs {}", y[k], resp(t - tau));
    }
    // whole-step delays too
    let p2 = Plant::new(2.0, 3.0, 0.0, 3.0 * dt, 1.0).unwrap();
    let (y2, _) = simulate_open_loop(&p2, dt, &u).unwrap();
    for k in 0..200 {
        assert!((y2[k] - resp(k as f64 * dt - 3.0 * dt)).abs() < 1e-13);
    }
}

#[test]
fn static_friction_sticks_below_breakaway_and_slides_above() {
    // A mass pushed by a constant drive input: below Fs it must not move at all.
    let plant = Plant::from_mass(10.0, 0.0, 0.0, 0.0, 1.0).unwrap();
    let map = StaticFriction::new(Stribeck::new(1.0, 1.5, 1e-3, 1.0).unwrap(), 0.0).unwrap();
    let dt = 1e-3;
    for (push, moves) in [(1.4, false), (1.6, true)] {
        // open loop: the command is the constant push
        let ff = vec![push; 2000];
        let input = ClosedLoopInput::open(&ff, dt);
        let fr = FrictionModel::Static(StaticElement::new(map));
        let out = simulate(&plant, Some(&fr), None, None, &input).unwrap();
        let last = *out.position.last().unwrap();
        if moves {
            assert!(last > 1e-3, "should slide: {last}");
        } else {
            assert!(last.abs() < 1e-12 && out.velocity[1999].abs() < 1e-12, "must stick: x = {last}");
            assert!((out.friction[1999] - push).abs() < 1e-12);
        }
    }
}

#[test]
fn pid_tracks_a_step_without_friction_and_with_gms() {
    let dt = 1e-4;
    let plant = reference::paper_plant();
    let r = vec![1e-4; 40_000];
    for fr in [None, Some(FrictionModel::Gms(reference::paper_gms()))] {
        let ctrl = ControllerModel::Pid(reference::paper_pid());
        let mut input = ClosedLoopInput::new(&r, dt);
        input.initial_position = 0.0;
        let out = simulate(&plant, fr.as_ref(), None, Some(&ctrl), &input).unwrap();
        let e = (r[0] - out.position.last().unwrap()).abs();
        assert!(e < 1e-8, "steady-state error {e}");
    }
}

#[test]
fn invalid_inputs_are_typed_errors() {
    let st = reference::paper_stribeck();
    assert!(matches!(Gms::new(st, vec![1.0, -1.0], vec![0.5, 0.5], 1.0, 0.0, SlipLaw::Time), Err(CoreError::NotPositive { name: "k", .. })));
    assert!(matches!(Gms::new(st, vec![1.0, 1.0], vec![0.5, 0.6], 1.0, 0.0, SlipLaw::Time), Err(CoreError::InvalidParameter { name: "alpha", .. })));
    assert!(matches!(Gms::new(st, vec![1.0], vec![0.5, 0.5], 1.0, 0.0, SlipLaw::Time), Err(CoreError::LengthMismatch { name: "alpha", .. })));
    assert!(matches!(Plant::from_mass(-1.0, 0.0, 0.0, 0.0, 1.0), Err(CoreError::NotPositive { name: "mass", .. })));
    assert!(matches!(Plant::new(1.0, 1.0, -1.0, 0.0, 1.0), Err(CoreError::Negative { name: "c", .. })));
    assert!(matches!(reference::paper_plant().discretize(0.0), Err(CoreError::NotPositive { name: "dt", .. })));
    let mut g = reference::paper_gms();
    assert!(matches!(simulate_position(&mut g, &[0.0, 1.0, 1.0], &[0.0, 0.0, 0.0]), Err(CoreError::NotIncreasing { name: "t", index: 2, .. })));
    assert!(matches!(simulate_position(&mut g, &[0.0, 1.0], &[0.0, f64::NAN]), Err(CoreError::NonFinite { name: "position", index: 1, .. })));
    assert!(matches!(simulate_position(&mut g, &[0.0, 1.0], &[0.0]), Err(CoreError::LengthMismatch { .. })));
    assert!(matches!(simulate_velocity(&mut g, 1e-3, &[]), Err(CoreError::Empty { .. })));
}

#[test]
fn static_map_with_linear_region_cannot_stick() {
    // Same push below break-away as in the stiction test: the regularised map creeps.
    let plant = Plant::from_mass(10.0, 0.0, 0.0, 0.0, 1.0).unwrap();
    let map = StaticFriction::new(Stribeck::new(1.0, 1.5, 1e-3, 1.0).unwrap(), 0.0).unwrap().with_linear_region(1e-4).unwrap();
    let dt = 1e-3;
    let ff = vec![1.4; 4000];
    let input = ClosedLoopInput::open(&ff, dt);
    let fr = FrictionModel::Static(StaticElement::new(map));
    let out = simulate(&plant, Some(&fr), None, None, &input).unwrap();
    // creeps at the velocity where the linear region balances the push: v = 1.4 / slope
    let slope = map.linear_region_slope();
    let v_end = *out.velocity.last().unwrap();
    assert!((v_end - 1.4 / slope).abs() < 1e-3 * v_end, "{v_end} vs {}", 1.4 / slope);
    assert!((map.force(0.5e-4) - 0.5 * map.force(1e-4)).abs() < 1e-12);
}

//! Batch simulation: equals the individual runs bit for bit, whatever the thread count; errors
//! name the failing run; progress counts every run; cancellation skips runs not started.
use gms_core::batch::{simulate_batch, simulate_batch_stacked, BatchOptions, Job};
use gms_core::reference;
use gms_core::{Axis, ClosedLoopInput, ControllerModel, CoreError, FrictionModel, Pid, Record};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

const DT: f64 = 1e-4;

fn jobs(r: &[f64], n: usize) -> Vec<Job<'_>> {
    (0..n)
        .map(|i| {
            let friction = match i % 3 {
                0 => None,
                1 => Some(FrictionModel::Gms(reference::gms_with_blocks(1 + i))),
                _ => Some(FrictionModel::Gms(reference::paper_gms())),
            };
            let kp = 5.0e5 * (1.0 + 0.1 * i as f64);
            let pid = Pid::new(kp, 2.5e6, 1.0e3, 5e-4, -10.0, 10.0).unwrap();
            Job { axis: Axis::new(reference::paper_plant(), friction, None).unwrap(), controller: Some(ControllerModel::Pid(pid)), input: ClosedLoopInput::new(r, DT) }
        })
        .collect()
}

fn reference() -> Vec<f64> {
    reference::paper_sine(3000, DT, 2e-4, 2.0)
}

#[test]
fn stacked_equals_individual_runs_for_any_thread_count() {
    let r = reference();
    let js = jobs(&r, 7);
    let single: Vec<_> = js.iter().map(|j| j.axis.simulate(j.controller.as_ref(), &j.input).unwrap()).collect();
    for threads in [None, Some(1), Some(2), Some(3)] {
        let progress = AtomicUsize::new(0);
        let out = simulate_batch_stacked(&js, &Record::ALL, &BatchOptions { threads, progress: Some(&progress), cancel: None }).unwrap();
        assert_eq!((out.n_runs, out.n_samples), (7, r.len()));
        assert_eq!(out.position.len(), 7 * r.len());
        assert_eq!(progress.load(Ordering::Relaxed), 7);
        for (i, s) in single.iter().enumerate() {
            assert_eq!(out.row(&out.position, i), &s.position[..], "run {i}, threads {threads:?}");
            assert_eq!(out.row(&out.velocity, i), &s.velocity[..]);
            assert_eq!(out.row(&out.measured, i), &s.measured[..]);
            assert_eq!(out.row(&out.command, i), &s.command[..]);
            assert_eq!(out.row(&out.friction, i), &s.friction[..]);
        }
        // The runs differ (the sweep is not trivially constant).
        assert_ne!(out.row(&out.position, 0), out.row(&out.position, 2));
    }
}

#[test]
fn per_run_results_keep_order_and_jobs_are_reusable() {
    let r = reference();
    let js = jobs(&r, 5);
    let a = simulate_batch(&js, &BatchOptions::default()).unwrap();
    let b = simulate_batch(&js, &BatchOptions { threads: Some(2), ..Default::default() }).unwrap();
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        let (x, y) = (x.as_ref().unwrap(), y.as_ref().unwrap());
        assert_eq!(x.position, y.position, "run {i}");
        assert_eq!(x.position, js[i].run().unwrap().position);
    }
}

#[test]
fn first_failing_run_is_reported() {
    let r = reference();
    let mut bad_ref = r.clone();
    bad_ref[10] = f64::NAN;
    let mut js = jobs(&r, 6);
    js[4].input = ClosedLoopInput::new(&bad_ref, DT);
    js[2].input.dt = -1.0;
    let _ = &mut js;
    let err = simulate_batch_stacked(&js, &Record::ALL, &BatchOptions { threads: Some(2), ..Default::default() }).unwrap_err();
    assert_eq!(err.run, 2);
    assert!(matches!(err.error, CoreError::NotPositive { name: "dt", .. }), "{err}");
    assert!(err.to_string().starts_with("run 2: "));

    let per_run = simulate_batch(&js, &BatchOptions::default()).unwrap();
    assert!(matches!(per_run[4], Err(CoreError::NonFinite { name: "reference", index: 10, .. })), "{:?}", per_run[4].as_ref().err());
    assert!(per_run[0].is_ok() && per_run[5].is_ok());
}

#[test]
fn divergence_and_length_mismatch_name_the_run() {
    let r = reference();
    let short = &r[..100];
    let mut js = jobs(&r, 3);
    js[1].input = ClosedLoopInput::new(short, DT);
    let err = simulate_batch_stacked(&js, &Record::ALL, &BatchOptions::default()).unwrap_err();
    assert_eq!(err.run, 1);
    assert!(matches!(err.error, CoreError::LengthMismatch { expected: 3000, got: 100, .. }));

    let mut js = jobs(&r, 3);
    // Absurd gain: unstable loop, the state overflows.
    js[1].controller = Some(ControllerModel::Pid(Pid::new(1e12, 0.0, 0.0, 0.0, f64::NEG_INFINITY, f64::INFINITY).unwrap()));
    let err = simulate_batch_stacked(&js, &Record::ALL, &BatchOptions::default()).unwrap_err();
    assert_eq!(err.run, 1);
    assert!(matches!(err.error, CoreError::NonFiniteOutput { .. }), "{err}");
}

#[test]
fn cancel_skips_runs_and_zero_threads_is_rejected() {
    let r = reference();
    let js = jobs(&r, 4);
    let cancel = AtomicBool::new(true);
    let progress = AtomicUsize::new(0);
    let res = simulate_batch(&js, &BatchOptions { threads: None, progress: Some(&progress), cancel: Some(&cancel) }).unwrap();
    assert!(res.iter().all(|r| r.as_ref().err() == Some(&CoreError::Interrupted)));
    assert_eq!(progress.load(Ordering::Relaxed), 0);

    let err = simulate_batch(&js, &BatchOptions { threads: Some(0), ..Default::default() }).unwrap_err();
    assert!(matches!(err, CoreError::NotPositive { name: "threads", .. }));
    // An empty batch is fine.
    let out = simulate_batch_stacked(&[], &Record::ALL, &BatchOptions::default()).unwrap();
    assert_eq!((out.n_runs, out.position.len()), (0, 0));
}

#[test]
fn friction_batch_equals_single_runs() {
    use gms_core::batch::simulate_position_batch;
    let t: Vec<f64> = (0..2000).map(|k| k as f64 * DT).collect();
    let x: Vec<f64> = t.iter().map(|&s| 1e-5 * (2.0 * std::f64::consts::PI * 3.0 * s).sin()).collect();
    let models = vec![
        FrictionModel::Gms(reference::paper_gms()),
        FrictionModel::Gms(reference::gms_with_blocks(8)),
        FrictionModel::Static(gms_core::StaticElement::new(reference::paper_static())),
    ];
    let out = simulate_position_batch(&models, &t, &[&x], &BatchOptions { threads: Some(2), ..Default::default() }).unwrap();
    for (i, m) in models.iter().enumerate() {
        let mut m = m.clone();
        let single = gms_core::with_friction!(&mut m, e => gms_core::simulate_position(e, &t, &x)).unwrap();
        assert_eq!(&out[i * t.len()..(i + 1) * t.len()], &single[..], "model {i}");
    }
    let mut bad = x.clone();
    bad[5] = f64::INFINITY;
    let err = simulate_position_batch(&models, &t, &[&x, &x, &bad], &BatchOptions::default()).unwrap_err();
    assert_eq!(err.run, 2);
}

/// A sweep of friction levels and gains: 9 runs of one structure, so 8 share a vector group
/// ([`gms_core::lanes::LANES`]) and one runs alone.
fn lane_jobs(r: &[f64]) -> Vec<Job<'_>> {
    (0..9)
        .map(|i| {
            let level = 0.5 + 0.125 * i as f64;
            let g = reference::paper_gms();
            let st = gms_core::Stribeck::new(g.stribeck.fc * level, g.stribeck.fs * level, g.stribeck.vs, 1.0).unwrap();
            let g = gms_core::Gms::new(st, g.k.clone(), g.alpha.clone(), g.c, g.sigma, g.slip_law).unwrap();
            let pid = Pid::new(5.0e5 * (1.0 + 0.05 * i as f64), 2.5e6, 1.0e3, 5e-4, -10.0, 10.0).unwrap();
            Job { axis: Axis::new(reference::paper_plant(), Some(FrictionModel::Gms(g)), None).unwrap(), controller: Some(ControllerModel::Pid(pid)), input: ClosedLoopInput::new(r, DT) }
        })
        .collect()
}

#[test]
fn runs_in_simd_lanes_match_single_runs_and_do_not_depend_on_threads() {
    let r = reference::paper_sine(40_000, DT, 2e-4, 2.0);
    let js = lane_jobs(&r);
    let record = Record { error: true, ..Record::ALL };
    let base = simulate_batch_stacked(&js, &record, &BatchOptions { threads: Some(1), ..Default::default() }).unwrap();
    let two = simulate_batch_stacked(&js, &record, &BatchOptions { threads: Some(2), ..Default::default() }).unwrap();
    for field in [|o: &gms_core::batch::BatchOutput| o.position.clone(), |o: &gms_core::batch::BatchOutput| o.friction.clone(), |o: &gms_core::batch::BatchOutput| o.error.clone()] {
        assert_eq!(field(&base), field(&two), "bit-identical across thread counts");
    }
    for (i, job) in js.iter().enumerate() {
        let single = job.run().unwrap();
        let worst = |a: &[f64], b: &[f64]| {
            let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / scale
        };
        let dp = worst(base.row(&base.position, i), &single.position);
        let df = worst(base.row(&base.friction, i), &single.friction);
        assert!(dp < 1e-12 && df < 1e-10, "run {i}: position {dp:e}, friction {df:e} of their ranges");
        let err: Vec<f64> = r.iter().zip(&single.position).map(|(r, x)| r - x).collect();
        assert!(worst(base.row(&base.error, i), &err) < 1e-9, "run {i}: error output");
    }
}

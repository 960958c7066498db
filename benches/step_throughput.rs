//! Step throughput of the core (criterion). Run: `cargo bench -p gms-core` (~2 min).
//!
//! Groups: `friction_only` (per model, 10^5 velocity samples; GMS with N = 1..64 blocks),
//! `closed_loop` (the paper's axis with a 4-block GMS, PID, 1.29 ms delay; N = 1..64 at 10^5
//! steps, and 10^4..10^6 steps at N = 4 to show the cost is linear in the step count).
//! Throughput is reported in elements = steps (samples) per second.
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use gms_core::reference;
use gms_core::{simulate_generic, simulate_velocity, ClosedLoopInput, LuGre, MaxwellSlip, StaticElement};
use std::hint::black_box;
use std::time::Duration;

const DT: f64 = 1e-4;

fn config() -> Criterion {
    Criterion::default().sample_size(10).warm_up_time(Duration::from_millis(300)).measurement_time(Duration::from_secs(1))
}

/// 0.2 mm, 0.5 Hz: the axis follows without saturating the drive (stick-slip at reversals).
fn closed_loop_reference(n: usize) -> Vec<f64> {
    reference::paper_sine(n, DT, 2e-4, 0.5)
}

fn friction_only(c: &mut Criterion) {
    let n = 100_000;
    let v: Vec<f64> = (0..n).map(|k| 1e-3 * (2.0 * std::f64::consts::PI * k as f64 * DT).sin()).collect();
    let mut g = c.benchmark_group("friction_only");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("static", |b| {
        let mut f = StaticElement::new(reference::paper_static());
        b.iter(|| simulate_velocity(&mut f, DT, black_box(&v)).unwrap())
    });
    g.bench_function("lugre", |b| {
        let mut f = LuGre::new(reference::paper_stribeck(), 1e5, 300.0, 6.98).unwrap();
        b.iter(|| simulate_velocity(&mut f, DT, black_box(&v)).unwrap())
    });
    g.bench_function("maxwell_slip4", |b| {
        let mut f = MaxwellSlip::new(vec![3.3e6, 8.9e3, 2.4e4, 2.6e3], vec![0.033, 0.057, 0.0132, 0.0026], 6.98).unwrap();
        b.iter(|| simulate_velocity(&mut f, DT, black_box(&v)).unwrap())
    });
    for blocks in [1usize, 2, 4, 8, 16, 32, 64] {
        g.bench_with_input(BenchmarkId::new("gms", blocks), &blocks, |b, &nb| {
            let mut f = reference::gms_with_blocks(nb);
            b.iter(|| simulate_velocity(&mut f, DT, black_box(&v)).unwrap())
        });
    }
    g.finish();
}

fn closed_loop(c: &mut Criterion) {
    let plant = reference::paper_plant();
    let mut g = c.benchmark_group("closed_loop");
    let n = 100_000;
    let r = closed_loop_reference(n);
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("gms4_paper", |b| {
        let mut f = reference::paper_gms();
        let mut ctrl = reference::paper_pid();
        let input = ClosedLoopInput::new(&r, DT);
        b.iter(|| simulate_generic(&plant, &mut f, &mut ctrl, black_box(&input)).unwrap())
    });
    for blocks in [1usize, 2, 4, 8, 16, 32, 64] {
        g.bench_with_input(BenchmarkId::new("gms_blocks", blocks), &blocks, |b, &nb| {
            let mut f = reference::gms_with_blocks(nb);
            let mut ctrl = reference::paper_pid();
            let input = ClosedLoopInput::new(&r, DT);
            b.iter(|| simulate_generic(&plant, &mut f, &mut ctrl, black_box(&input)).unwrap())
        });
    }
    g.finish();

    let mut g = c.benchmark_group("closed_loop_steps");
    for steps in [10_000usize, 100_000, 1_000_000] {
        let r = closed_loop_reference(steps);
        g.throughput(Throughput::Elements(steps as u64));
        g.bench_with_input(BenchmarkId::new("gms4_paper", steps), &steps, |b, _| {
            let mut f = reference::paper_gms();
            let mut ctrl = reference::paper_pid();
            let input = ClosedLoopInput::new(&r, DT);
            b.iter(|| simulate_generic(&plant, &mut f, &mut ctrl, black_box(&input)).unwrap())
        });
    }
    g.finish();
}

criterion_group! { name = benches; config = config(); targets = friction_only, closed_loop }
criterion_main!(benches);

//! Step throughput of the core (criterion). Run: `cargo bench -p gms-core`.
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use gms_core::reference;
use gms_core::{simulate_generic, simulate_velocity, ClosedLoopInput, StaticElement};
use std::hint::black_box;

fn friction_only(c: &mut Criterion) {
    let dt = 1e-4;
    let n = 100_000;
    let v: Vec<f64> = (0..n).map(|k| 1e-3 * (2.0 * std::f64::consts::PI * k as f64 * dt).sin()).collect();
    let mut g = c.benchmark_group("friction_only");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("static", |b| {
        let mut f = StaticElement::new(reference::paper_static());
        b.iter(|| simulate_velocity(&mut f, dt, black_box(&v)).unwrap())
    });
    for blocks in [1usize, 4, 16, 64] {
        g.bench_with_input(BenchmarkId::new("gms", blocks), &blocks, |b, &nb| {
            let mut f = reference::gms_with_blocks(nb);
            b.iter(|| simulate_velocity(&mut f, dt, black_box(&v)).unwrap())
        });
    }
    g.finish();
}

fn closed_loop(c: &mut Criterion) {
    let dt = 1e-4;
    let n = 100_000;
    let r = reference::paper_sine(n, dt, 0.01, 0.5);
    let plant = reference::paper_plant();
    let mut g = c.benchmark_group("closed_loop");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("gms4", |b| {
        let mut f = reference::paper_gms();
        let mut ctrl = reference::paper_pid(dt);
        let input = ClosedLoopInput::new(&r, dt);
        b.iter(|| simulate_generic(&plant, &mut f, &mut ctrl, black_box(&input)).unwrap())
    });
    g.finish();
}

criterion_group!(benches, friction_only, closed_loop);
criterion_main!(benches);

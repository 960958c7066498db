//! Core step rate of the closed loop with pre-touched output buffers (compute only, no page
//! faults): `cargo run --release -p gms-core --example steprate [steps]`.
use gms_core::reference;
use gms_core::*;
use std::time::Instant;

fn main() {
    let dt = 1e-4;
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(10_000_000);
    let r: Vec<f64> = (0..n).map(|k| 2e-4 * (2.0 * std::f64::consts::PI * 0.5 * k as f64 * dt).sin()).collect();
    let plant = reference::paper_plant();
    let input = ClosedLoopInput::new(&r, dt);
    let mut out = ClosedLoopOutput::zeros(n);
    let mut best = [f64::INFINITY; 3];
    for _ in 0..5 {
        let mut ctrl = reference::paper_pid();
        let t0 = Instant::now();
        simulate_generic_into(&plant, &mut NoFriction, &mut ctrl, &input, out.buffers()).unwrap();
        best[0] = best[0].min(t0.elapsed().as_secs_f64());
        let mut ctrl = reference::paper_pid();
        let mut g = reference::paper_gms();
        let t0 = Instant::now();
        simulate_generic_into(&plant, &mut g, &mut ctrl, &input, out.buffers()).unwrap();
        best[1] = best[1].min(t0.elapsed().as_secs_f64());
        let mut f = reference::paper_gms();
        let t0 = Instant::now();
        let fo = simulate_velocity(&mut f, dt, &out.velocity).unwrap();
        best[2] = best[2].min(t0.elapsed().as_secs_f64());
        std::hint::black_box(fo);
    }
    let ns = |s: f64| s / n as f64 * 1e9;
    println!("best of 5, {n} steps: closed loop without friction {:.1} ns/step, with GMS N=4 {:.1} ns/step ({:.2e} steps/s); friction-only GMS {:.1} ns/sample", ns(best[0]), ns(best[1]), 1.0 / ns(best[1]) * 1e9, ns(best[2]));
}

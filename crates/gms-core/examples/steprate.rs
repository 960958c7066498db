//! Core step rate of the closed loop with pre-touched output buffers (compute only, no page
//! faults), thread CPU time: `cargo run --release -p gms-core --example steprate [steps] [blocks] [amplitude] [freq]`
//! (default: 0.2 mm, 0.5 Hz sine; `numba_axis.py`'s task is `10000000 4 0.01 0.01`).
//!
//! Rows: no friction; GMS through the generic loop (`simulate_generic_into`); GMS through the
//! run entry (`simulate_into`: the latency-optimised kernel of `gms_core::fast`), all outputs and
//! the tracking error only. Interleaved repetitions, best of 5.
use gms_core::reference;
use gms_core::*;

/// Thread CPU time: robust to other processes taking the core (the machine may be shared).
#[derive(Clone, Copy)]
struct Instant(f64);
impl Instant {
    fn now() -> Self {
        let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
        // SAFETY: clock_gettime writes the timespec we pass.
        unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
        Self(ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9)
    }
    /// Process CPU time (a batch runs on pool threads).
    fn process() -> Self {
        let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
        // SAFETY: clock_gettime writes the timespec we pass.
        unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
        Self(ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9)
    }
    fn process_elapsed(&self) -> f64 {
        Self::process().0 - self.0
    }
    fn elapsed(&self) -> std::time::Duration {
        std::time::Duration::from_secs_f64(Self::now().0 - self.0)
    }
}

fn main() {
    let dt = 1e-4;
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(10_000_000);
    let blocks: usize = std::env::args().nth(2).and_then(|s| s.parse().ok()).unwrap_or(4);
    let amp: f64 = std::env::args().nth(3).and_then(|s| s.parse().ok()).unwrap_or(2e-4);
    let freq: f64 = std::env::args().nth(4).and_then(|s| s.parse().ok()).unwrap_or(0.5);
    let r: Vec<f64> = (0..n).map(|k| amp * (2.0 * std::f64::consts::PI * freq * k as f64 * dt).sin()).collect();
    let plant = reference::paper_plant();
    let input = ClosedLoopInput::new(&r, dt);
    let mut out = ClosedLoopOutput::zeros(n);
    let mut err = vec![0.0; n];
    let gms = if blocks == 4 { reference::paper_gms() } else { reference::gms_with_blocks(blocks) };
    let model = FrictionModel::Gms(gms.clone());
    let ctrl = ControllerModel::Pid(reference::paper_pid());
    let mut best = [f64::INFINITY; 4];
    for _ in 0..5 {
        let mut c = reference::paper_pid();
        let t0 = Instant::now();
        simulate_generic_into(&plant, &mut NoFriction, &mut c, &input, out.buffers()).unwrap();
        best[0] = best[0].min(t0.elapsed().as_secs_f64());
        let mut c = reference::paper_pid();
        let mut g = gms.clone();
        let t0 = Instant::now();
        simulate_generic_into(&plant, &mut g, &mut c, &input, out.buffers()).unwrap();
        best[1] = best[1].min(t0.elapsed().as_secs_f64());
        let t0 = Instant::now();
        simulate_into(&plant, Some(&model), None, Some(&ctrl), &input, out.buffers()).unwrap();
        best[2] = best[2].min(t0.elapsed().as_secs_f64());
        let t0 = Instant::now();
        let only_error = ClosedLoopBuffers { error: Some(&mut err), every: 1, ..Default::default() };
        simulate_into(&plant, Some(&model), None, Some(&ctrl), &input, only_error).unwrap();
        best[3] = best[3].min(t0.elapsed().as_secs_f64());
    }
    // A batch of NB runs of the same structure (friction levels x0.5..x1.5): one vector group
    // (LANES = 8) on one thread, against the same runs one at a time.
    const NB: usize = 8;
    let jobs: Vec<batch::Job<'_>> = (0..NB)
        .map(|i| {
            let x = 0.5 + i as f64 / (NB - 1) as f64;
            let st = Stribeck::new(gms.stribeck.fc * x, gms.stribeck.fs * x, gms.stribeck.vs, 1.0).unwrap();
            let g = Gms::new(st, gms.k.clone(), gms.alpha.clone(), gms.c, gms.sigma, gms.slip_law).unwrap();
            batch::Job { axis: Axis::new(plant, Some(FrictionModel::Gms(g)), None).unwrap(), controller: Some(ctrl.clone()), input }
        })
        .collect();
    let rec = Record { position: false, velocity: false, measured: false, command: false, friction: false, error: true, every: 1 };
    let mut bout = batch::BatchOutput::allocate(NB, n, &rec).unwrap();
    let (mut b_lanes, mut b_single) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..3 {
        let t0 = Instant::process();
        batch::simulate_batch_into(&jobs, &rec, &mut bout, &batch::BatchOptions { threads: Some(1), ..Default::default() }).unwrap();
        b_lanes = b_lanes.min(t0.process_elapsed());
        let t0 = Instant::process();
        for j in &jobs {
            let only_error = ClosedLoopBuffers { error: Some(&mut err), every: 1, ..Default::default() };
            j.run_into(only_error).unwrap();
        }
        b_single = b_single.min(t0.process_elapsed());
    }
    println!("batch of {NB} on one thread (process CPU time): {:.1} ns per run-step in lanes, {:.1} one run at a time: {:.2}x", b_lanes / (NB * n) as f64 * 1e9, b_single / (NB * n) as f64 * 1e9, b_single / b_lanes);
    // The same runs twice over (two vector groups) on one thread and on two: wall time.
    let jobs2: Vec<batch::Job<'_>> = jobs.iter().chain(&jobs).cloned().collect();
    let mut bout2 = batch::BatchOutput::allocate(2 * NB, n, &rec).unwrap();
    let mut wall = [f64::INFINITY; 2];
    for _ in 0..3 {
        for (slot, threads) in [(0, 1), (1, 2)] {
            let t0 = std::time::Instant::now();
            batch::simulate_batch_into(&jobs2, &rec, &mut bout2, &batch::BatchOptions { threads: Some(threads), ..Default::default() }).unwrap();
            wall[slot] = wall[slot].min(t0.elapsed().as_secs_f64());
        }
    }
    println!("batch of {} (two groups), wall, best of 3: 1 thread {:.2} ns per run-step, 2 threads {:.2}: {:.2}x", 2 * NB, wall[0] / (2 * NB * n) as f64 * 1e9, wall[1] / (2 * NB * n) as f64 * 1e9, wall[0] / wall[1]);
    let ns = |s: f64| s / n as f64 * 1e9;
    println!(
        "best of 5, {n} steps, GMS N={blocks}: no friction {:.1} ns/step; generic loop {:.1} ns/step; fast kernel {:.1} ns/step (all outputs), {:.1} ns/step (error only); generic / fast = {:.2}",
        ns(best[0]),
        ns(best[1]),
        ns(best[2]),
        ns(best[3]),
        best[1] / best[2]
    );
}

//! Measurements of the prototype against the current core (one process, interleaved repetitions,
//! pre-touched output buffers so page faults are not measured):
//!
//!     cargo run --release -- [steps] [repeats]
//!     RUSTFLAGS="-C target-cpu=native" cargo run --release --target-dir target-native -- ...
use gms_core::{reference, simulate_generic_into, ClosedLoopBuffers, ClosedLoopInput};
use lanes::dispatch;
use lanes::fexp::{exp_neg_poly, ExpTable};
use lanes::lanes::{run_lanes, LaneOut, LaneParams};
use lanes::setup::{Axis, GmsP, PidP};
use lanes::single::{run_v1, run_v3, Out};
use std::hint::black_box;

/// Thread CPU time: robust to other processes taking the core (the machine is shared); the
/// interleaving takes care of slower drifts (cache and memory-bandwidth contention).
#[derive(Clone, Copy)]
struct Instant(f64);
impl Instant {
    fn now() -> Self {
        let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
        unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
        Self(ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9)
    }
    fn elapsed(&self) -> std::time::Duration {
        std::time::Duration::from_secs_f64(Self::now().0 - self.0)
    }
}

const NATIVE_FMA: bool = cfg!(target_feature = "fma");
const DT: f64 = 1e-4;

struct Bufs {
    pos: Vec<f64>,
    vel: Vec<f64>,
    cmd: Vec<f64>,
    fric: Vec<f64>,
}

impl Bufs {
    fn new(n: usize) -> Self {
        // vec![1.0; n] writes every page: later runs measure compute, not page faults.
        Self { pos: vec![1.0; n], vel: vec![1.0; n], cmd: vec![1.0; n], fric: vec![1.0; n] }
    }
    fn out(&mut self) -> Out<'_> {
        Out { pos: &mut self.pos, vel: &mut self.vel, cmd: &mut self.cmd, fric: &mut self.fric }
    }
    fn core(&mut self) -> ClosedLoopBuffers<'_> {
        ClosedLoopBuffers { position: &mut self.pos, velocity: &mut self.vel, measured: None, command: &mut self.cmd, friction: &mut self.fric }
    }
}

fn ulps(a: f64, b: f64) -> u64 {
    (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

/// max |a - b| / max |b|
fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let d = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    d / b.iter().map(|x| x.abs()).fold(0.0, f64::max)
}

fn exp_accuracy() {
    let t = ExpTable::new();
    let (mut worst_t, mut worst_p, mut worst_rel) = (0u64, 0u64, 0.0f64);
    let count = 4_000_000;
    for i in 0..=count {
        // dense on the Stribeck range [0, 40], then sparse to 700
        let p = if i <= count / 2 { 40.0 * i as f64 / (count / 2) as f64 } else { 40.0 + 660.0 * (i - count / 2) as f64 / (count / 2) as f64 };
        let exact = (-p).exp();
        let a = t.exp_neg::<NATIVE_FMA>(p);
        let b = exp_neg_poly::<NATIVE_FMA>(p);
        worst_t = worst_t.max(ulps(a, exact));
        worst_p = worst_p.max(ulps(b, exact));
        worst_rel = worst_rel.max(((a - exact) / exact).abs());
    }
    let mut worst_tf = 0u64;
    for i in 0..=count / 4 {
        let p = 40.0 * i as f64 / (count / 4) as f64;
        worst_tf = worst_tf.max(ulps(t.exp_neg::<false>(p), (-p).exp()));
    }
    println!(
        "exp(-p) vs libm exp, p in [0, 700] ({} points): table exp max {} ulp (rel {:.2e}); table exp without FMA max {} ulp on [0, 40]; table-free poly exp max {} ulp",
        count + 1,
        worst_t,
        worst_rel,
        worst_tf,
        worst_p
    );
}

fn single_case<const NP: usize>(label: &str, gms: &gms_core::Gms, n: usize, reps: usize) {
    let plant = reference::paper_plant();
    let ax = Axis::new(&plant, DT);
    let pid = PidP::from_core(&reference::paper_pid(DT));
    let g = GmsP::from_core(gms, DT);
    let r: Vec<f64> = (0..n).map(|k| 2e-4 * (2.0 * std::f64::consts::PI * 0.5 * k as f64 * DT).sin()).collect();
    let input = ClosedLoopInput::new(&r, DT);
    let mut core_b = Bufs::new(n);
    let mut b = Bufs::new(n);
    let names = ["core (as-is)", "v1 branch-free, libm exp", "v1 + short exp", "v3 short chain, libm exp", "v3 short chain + short exp"];
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    let mut diffs = vec![(0.0f64, 0.0f64, true); names.len()];
    for rep in 0..reps {
        for (vi, t) in times.iter_mut().enumerate() {
            let t0 = Instant::now();
            if vi == 0 {
                let mut gm = gms.clone();
                gm.reset_state();
                let mut ctrl = reference::paper_pid(DT);
                simulate_generic_into(&plant, &mut gm, &mut ctrl, &input, core_b.core()).unwrap();
            } else {
                let res = match vi {
                    1 => run_v1::<NP, NATIVE_FMA, false>(&ax, &pid, &g, &r, b.out()),
                    2 => run_v1::<NP, NATIVE_FMA, true>(&ax, &pid, &g, &r, b.out()),
                    3 => run_v3::<NP, NATIVE_FMA, false>(&ax, &pid, &g, &r, b.out()),
                    _ => run_v3::<NP, NATIVE_FMA, true>(&ax, &pid, &g, &r, b.out()),
                };
                res.unwrap();
            }
            t.push(t0.elapsed().as_secs_f64() / n as f64 * 1e9);
            if rep == 0 && vi > 0 {
                let same = b.pos == core_b.pos && b.fric == core_b.fric && b.vel == core_b.vel && b.cmd == core_b.cmd;
                diffs[vi] = (rel_diff(&b.pos, &core_b.pos), rel_diff(&b.fric, &core_b.fric), same);
            }
            black_box(&b.pos);
        }
    }
    let core_med = median(&mut times[0].clone());
    for (vi, name) in names.iter().enumerate() {
        let med = median(&mut times[vi].clone());
        let (dp, df, same) = diffs[vi];
        let agree = if vi == 0 {
            "-".to_string()
        } else if same {
            "bit-identical".to_string()
        } else {
            format!("max|dpos|/max|pos| {dp:.1e}, max|dF|/max|F| {df:.1e}")
        };
        println!("| {label} | {name} | {:.1} | {med:.1} | {:.2} | {agree} |", min(&times[vi]), core_med / med);
    }
}

trait ResetState {
    fn reset_state(&mut self);
}
impl ResetState for gms_core::Gms {
    fn reset_state(&mut self) {
        use gms_core::FrictionElement;
        self.reset();
    }
}

fn lanes_case<const L: usize>(n: usize, reps: usize) {
    let plant = reference::paper_plant();
    let ax = Axis::new(&plant, DT);
    let base = reference::paper_gms();
    let levels: Vec<f64> = (0..L).map(|l| 0.5 + l as f64 / (L - 1) as f64).collect();
    let gms: Vec<GmsP> = levels.iter().map(|&x| GmsP::scaled(&base, x, DT)).collect();
    let core_gms: Vec<gms_core::Gms> = levels
        .iter()
        .map(|&x| {
            let st = gms_core::Stribeck::new(base.stribeck.fc * x, base.stribeck.fs * x, base.stribeck.vs, 1.0).unwrap();
            gms_core::Gms::new(st, base.k.clone(), base.alpha.clone(), base.c, base.sigma, base.slip_law).unwrap()
        })
        .collect();
    let pids: Vec<PidP> = (0..L).map(|_| PidP::from_core(&reference::paper_pid(DT))).collect();
    let lp: LaneParams<L, 4> = LaneParams::new(&pids, &gms);
    let r: Vec<f64> = (0..n).map(|k| 2e-4 * (2.0 * std::f64::consts::PI * 0.5 * k as f64 * DT).sin()).collect();
    let input = ClosedLoopInput::new(&r, DT);
    let mut singles: Vec<Bufs> = (0..L).map(|_| Bufs::new(n)).collect();
    let mut v3b = Bufs::new(n);
    let (mut lpos, mut lvel, mut lcmd, mut lfric) = (vec![1.0; L * n], vec![1.0; L * n], vec![1.0; L * n], vec![1.0; L * n]);
    let names = ["core, one run at a time", "v3 (short exp), one run at a time", "lanes (AVX2 via target-cpu/dispatch)", "in groups of 4 lanes"];
    let mut t: Vec<Vec<f64>> = vec![Vec::new(); 4];
    let groups: Vec<LaneParams<4, 4>> = gms.chunks(4).map(|c| LaneParams::new(&pids[..c.len()], c)).collect();
    let (mut gpos, mut gvel, mut gcmd, mut gfric) = (vec![1.0; 4 * n], vec![1.0; 4 * n], vec![1.0; 4 * n], vec![1.0; 4 * n]);
    for _ in 0..reps {
        let t0 = Instant::now();
        for (l, b) in singles.iter_mut().enumerate() {
            let mut gm = core_gms[l].clone();
            let mut ctrl = reference::paper_pid(DT);
            simulate_generic_into(&plant, &mut gm, &mut ctrl, &input, b.core()).unwrap();
        }
        t[0].push(t0.elapsed().as_secs_f64());
        let t0 = Instant::now();
        for g in &gms {
            run_v3::<4, NATIVE_FMA, true>(&ax, &pids[0], g, &r, v3b.out()).unwrap();
        }
        t[1].push(t0.elapsed().as_secs_f64());
        let t0 = Instant::now();
        let out = LaneOut { pos: &mut lpos, vel: &mut lvel, cmd: &mut lcmd, fric: &mut lfric };
        if L == 4 {
            // SAFETY of transmute-free dispatch: LaneParams<4,4> is exactly the type for L = 4.
            let p4: &LaneParams<4, 4> = unsafe { &*(&lp as *const LaneParams<L, 4> as *const LaneParams<4, 4>) };
            dispatch::lanes4_n4(&ax, p4, &r, out).unwrap();
        } else if L == 8 {
            let p8: &LaneParams<8, 4> = unsafe { &*(&lp as *const LaneParams<L, 4> as *const LaneParams<8, 4>) };
            dispatch::lanes8_n4(&ax, p8, &r, out).unwrap();
        } else {
            run_lanes::<L, 4, NATIVE_FMA>(&ax, &lp, &r, out).unwrap();
        }
        t[2].push(t0.elapsed().as_secs_f64());
        let t0 = Instant::now();
        for gp in &groups {
            let out = LaneOut { pos: &mut gpos, vel: &mut gvel, cmd: &mut gcmd, fric: &mut gfric };
            dispatch::lanes4_n4(&ax, gp, &r, out).unwrap();
        }
        t[3].push(t0.elapsed().as_secs_f64());
    }
    let total = (L * n) as f64;
    let core_med = median(&mut t[0].clone());
    let (mut worst, mut worst_f) = (0.0f64, 0.0f64);
    for (l, s) in singles.iter().enumerate() {
        let lane = |a: &[f64]| -> Vec<f64> { (0..n).map(|k| a[k * L + l]).collect() };
        worst = worst.max(rel_diff(&lane(&lpos), &s.pos));
        worst_f = worst_f.max(rel_diff(&lane(&lfric), &s.fric));
    }
    for (i, name) in names.iter().enumerate() {
        let med = median(&mut t[i].clone());
        let note = if i == 2 { format!("vs core single runs: max|dpos|/max|pos| {worst:.1e}, max|dF|/max|F| {worst_f:.1e}") } else { String::new() };
        println!("| {L} runs | {name} | {:.3e} | {:.3e} | {:.2} | {note} |", total / min(&t[i]).max(1e-12) / 1.0, total / med, core_med / med);
    }
}

fn dispatch_case(n: usize, reps: usize) {
    let plant = reference::paper_plant();
    let ax = Axis::new(&plant, DT);
    let pid = PidP::from_core(&reference::paper_pid(DT));
    let g = GmsP::from_core(&reference::paper_gms(), DT);
    let r: Vec<f64> = (0..n).map(|k| 2e-4 * (2.0 * std::f64::consts::PI * 0.5 * k as f64 * DT).sin()).collect();
    let input = ClosedLoopInput::new(&r, DT);
    let mut b = Bufs::new(n);
    let mut cb = Bufs::new(n);
    let names = ["core (this build)", "v3 dispatched", "v3 baseline path, a*b+c", "v3 baseline path, f64::mul_add", "v3 this build's native instantiation"];
    let mut t: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    let mut pos: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    for rep in 0..reps {
        for (i, ti) in t.iter_mut().enumerate() {
            let t0 = Instant::now();
            match i {
                0 => {
                    let mut gm = reference::paper_gms();
                    let mut ctrl = reference::paper_pid(DT);
                    simulate_generic_into(&plant, &mut gm, &mut ctrl, &input, cb.core()).unwrap();
                }
                1 => dispatch::v3_n4(&ax, &pid, &g, &r, b.out()).unwrap(),
                2 => dispatch::v3_n4_base(&ax, &pid, &g, &r, b.out()).unwrap(),
                3 => dispatch::v3_n4_base_mul_add(&ax, &pid, &g, &r, b.out()).unwrap(),
                _ => run_v3::<4, NATIVE_FMA, true>(&ax, &pid, &g, &r, b.out()).unwrap(),
            }
            ti.push(t0.elapsed().as_secs_f64() / n as f64 * 1e9);
            if rep == 0 {
                pos[i] = if i == 0 { cb.pos.clone() } else { b.pos.clone() };
            }
        }
    }
    // A checksum of the dispatched run's bits, to compare builds (portable vs native) by eye.
    let digest = pos[1].iter().fold(0u64, |h, x| h.rotate_left(5) ^ x.to_bits());
    println!("dispatcher takes the {} path on this CPU; this build: target fma = {}; bits digest of the dispatched run {digest:016x}", if dispatch::has_avx2_fma() { "avx2+fma" } else { "baseline" }, NATIVE_FMA);
    for (i, name) in names.iter().enumerate() {
        let med = median(&mut t[i].clone());
        let same_as_dispatched = pos[i] == pos[1];
        println!("| {name} | {:.1} | {med:.1} | max|dpos|/max|pos| vs core {:.1e}; identical to dispatched: {same_as_dispatched} |", min(&t[i]), rel_diff(&pos[i], &pos[0]));
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(2_000_000);
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(5);
    let what = args.get(3).map(String::as_str).unwrap_or("all");
    println!("# {n} steps, {reps} interleaved repetitions, thread CPU time, build target fma = {NATIVE_FMA}");
    if what == "all" || what == "exp" {
        exp_accuracy();
        let g = GmsP::from_core(&reference::paper_gms(), DT);
        let (fc, fs, c) = (g.fc, g.fs, g.c);
        let worst = (0..=100_000)
            .map(|i| i as f64 / 100_000.0)
            .map(|e| {
                let exact = (-(c / (fc + (fs - fc) * e)) * DT).exp();
                ((g.poly_e.eval::<NATIVE_FMA>(e) - exact) / exact).abs()
            })
            .fold(0.0, f64::max);
        println!("decay polynomial in E vs exp(-c dt / s): max relative error {worst:.2e}");
    }
    if what == "all" || what == "single" {
        println!("\n| GMS | kernel | ns/step min | ns/step median | core / kernel (median) | agreement with the core |");
        println!("|---|---|---|---|---|---|");
        single_case::<4>("N=1", &reference::gms_with_blocks(1), n, reps);
        single_case::<4>("paper N=4", &reference::paper_gms(), n, reps);
        single_case::<4>("N=4", &reference::gms_with_blocks(4), n, reps);
        single_case::<8>("N=8", &reference::gms_with_blocks(8), n, reps);
        single_case::<16>("N=16", &reference::gms_with_blocks(16), n, reps);
    }
    if what == "all" || what == "lanes" {
        println!("\n| batch | how | steps/s (best) | steps/s (median) | x core one at a time | |");
        println!("|---|---|---|---|---|---|");
        lanes_case::<4>(n, reps);
        lanes_case::<8>(n, reps);
    }
    if what == "all" || what == "dispatch" {
        println!("\n| paper N=4 | ns/step min | ns/step median | agreement |");
        println!("|---|---|---|---|");
        dispatch_case(n, reps);
    }
}

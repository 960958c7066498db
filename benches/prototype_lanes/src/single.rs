//! One closed-loop run (paper axis, PID, GMS with N blocks), written for step latency.
//!
//! `run_v1`: the core's dependency chain and operation order, with the N block updates
//! branch-free (selects) over fixed-size arrays padded to `NP` (a multiple of 4) with zero
//! blocks, the block sum as a tree, and the coupling reciprocal cached per direction (no division
//! unless a block changes mode). With `FAST = false` it keeps libm `exp` and the core's decay
//! memo: bit-identical to the core for N <= 4 (same summation order); for N > 4 only the order of
//! the block sum differs.
//!
//! `run_v3`: the same algorithm with a shorter chain per step:
//!  - the next step's coupling residual (`trial`) is formed directly from this step's slip decay
//!    with one fused multiply-add: `trial' = (Q - a1 sigma v - b C) - b G decay`, where the sums
//!    of block forces over the blocks slipping along / not slipping along the motion (`G`, `C`)
//!    come from the previous step's block arrays, off the chain. The plant terms of `Q` are
//!    known a step ahead (input delay >= 1 step). The exact per-block update still runs every
//!    step (vectorised, off the chain); if a block breaks away in the step (rare: start,
//!    reversals) the closed form is replaced by the exact block sum on a cold path;
//!  - the Stribeck exponential from a short inlined exponential (`FAST = true`) and the decay
//!    polynomial in `E` (not `2E - 1`);
//!  - `|v|/vs` as `|trial| * (1/(1 + gf0 K)) / (dt vs)` (one multiply on the chain).
//!    Results agree with the core to rounding (stated by the benchmark), not bit for bit.

use crate::fexp::{fma, ExpTable};
use crate::setup::{ring_len, Axis, GmsP, PidP};

/// Output arrays of one run (each as long as the reference).
pub struct Out<'a> {
    pub pos: &'a mut [f64],
    pub vel: &'a mut [f64],
    pub cmd: &'a mut [f64],
    pub fric: &'a mut [f64],
}

#[inline(always)]
fn hsum<const NP: usize>(a: &[f64; NP]) -> f64 {
    // Halve until four remain, then (a0 + a2) + (a1 + a3): the core's order for N <= 4.
    let mut w = *a;
    let mut len = NP;
    while len > 4 {
        len /= 2;
        for i in 0..len {
            w[i] += w[i + len];
        }
    }
    (w[0] + w[2]) + (w[1] + w[3])
}

#[inline(always)]
fn pad<const NP: usize>(v: &[f64]) -> [f64; NP] {
    assert!(v.len() <= NP);
    let mut a = [0.0; NP];
    a[..v.len()].copy_from_slice(v);
    a
}

struct PidState {
    integral: f64,
    deriv: f64,
    prev_e: f64,
}

impl PidState {
    #[inline(always)]
    fn update(&mut self, p: &PidP, e: f64) -> f64 {
        // The core's Pid::update, operation for operation (plain multiply and add: the core
        // writes no fma here).
        let de = e - self.prev_e;
        self.prev_e = e;
        self.deriv = p.d_keep * self.deriv + p.d_gain * de;
        let trial_integral = self.integral + p.ki_dt * e;
        let u = p.kp * e + trial_integral + self.deriv;
        let clamped = u.clamp(p.u_min, p.u_max);
        let winding_up = (u > p.u_max && e * p.ki > 0.0) || (u < p.u_min && e * p.ki < 0.0);
        if !winding_up {
            self.integral = trial_integral;
        }
        clamped
    }
}

/// Branch-free update of all blocks for motion `dx` in direction `dir`; returns (any mode
/// changed, any block broke away).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn update_blocks<const NP: usize, const F: bool>(
    f: &mut [f64; NP],
    m: &mut [f64; NP],
    k: &[f64; NP],
    a: &[f64; NP],
    dir: f64,
    dir_s: f64,
    decay: f64,
    dx: f64,
) -> (bool, bool) {
    let mut changed = 0u64;
    let mut broke = 0u64;
    for i in 0..NP {
        let f_old = f[i];
        let target = a[i] * dir_s;
        let relaxed = fma::<F>(f_old - target, decay, target);
        let stuck = fma::<F>(k[i], dx, f_old);
        let along = m[i] == dir;
        let breaks = (stuck - target) * dir >= 0.0;
        let beyond = (f_old - target) * dir >= 0.0;
        let nf = if along || (breaks && beyond) { relaxed } else if breaks { target } else { stuck };
        let nm = if along || breaks { dir } else { 0.0 };
        changed |= (nm != m[i]) as u64;
        broke |= (!along && breaks) as u64;
        f[i] = nf;
        m[i] = nm;
    }
    (changed != 0, broke != 0)
}

/// The core's `refresh_free_stiffness` (same order).
#[inline(always)]
fn free_stiffness<const NP: usize>(m: &[f64; NP], k: &[f64; NP]) -> (f64, f64) {
    let (mut kp, mut kn) = (0.0, 0.0);
    for i in 0..NP {
        kp += if m[i] == 1.0 { 0.0 } else { k[i] };
        kn += if m[i] == -1.0 { 0.0 } else { k[i] };
    }
    (kp, kn)
}

/// See the module doc. Returns `Err(step)` if the state became non-finite.
#[inline(always)]
pub fn run_v1<const NP: usize, const F: bool, const FAST: bool>(ax: &Axis, pid: &PidP, g: &GmsP, r: &[f64], out: Out<'_>) -> Result<(), usize> {
    let n = r.len();
    let (pos, vel, cmd, fric) = (&mut out.pos[..n], &mut out.vel[..n], &mut out.cmd[..n], &mut out.fric[..n]);
    let table = ExpTable::new();
    let k: [f64; NP] = pad(&g.k);
    let a: [f64; NP] = pad(&g.alpha);
    let mut f = [0.0f64; NP];
    let mut m = [0.0f64; NP];
    let len = ring_len(ax.m);
    let mask = len - 1;
    let mut buf = vec![0.0f64; len];
    let (mut xp, mut xv) = (r[0], 0.0);
    let mut pid_s = PidState { integral: 0.0, deriv: 0.0, prev_e: r[0] - xp };
    let inv_dt = ax.inv_dt;
    let sig_inv_dt = g.sigma * inv_dt;
    let inv_den = |kf: f64| 1.0 / (1.0 + ax.gf0 * (kf + sig_inv_dt));
    let (mut inv_pos, mut inv_neg) = (inv_den(g.total_k), inv_den(g.total_k));
    let pc_scale = inv_dt * g.inv_vs;
    let mut sum_f = 0.0f64;
    // The core's decay memo and steady-step counter (FAST = false only).
    let (mut memo_s, mut memo_d, mut calls) = (f64::NAN, 0.0f64, 0u32);
    for kk in 0..n {
        let e = r[kk] - xp;
        let u = pid_s.update(pid, e);
        buf[kk & mask] = u;
        let old = buf[kk.wrapping_sub(ax.m + 1) & mask];
        let new = buf[kk.wrapping_sub(ax.m) & mask];
        let free_p = fma::<F>(ax.p00, xp, fma::<F>(ax.p01, xv, fma::<F>(ax.go0, old, ax.gn0 * new)));
        let free_v = fma::<F>(ax.p11, xv, fma::<F>(ax.p10, xp, fma::<F>(ax.go1, old, ax.gn1 * new)));
        let trial = fma::<F>(-ax.gf0, sum_f, free_p - xp);
        let inv = if trial >= 0.0 { inv_pos } else { inv_neg };
        let dx = trial * inv;
        let force;
        if dx == 0.0 {
            let changed = m.iter().any(|&x| x != 0.0);
            m = [0.0; NP];
            if changed {
                inv_pos = inv_den(g.total_k);
                inv_neg = inv_pos;
            }
            force = sum_f;
        } else {
            let v = dx * inv_dt;
            let dir = if dx > 0.0 { 1.0 } else { -1.0 };
            let p = if FAST { (trial * (inv * pc_scale)).abs() } else { (v * g.inv_vs).abs() };
            let (s, e_str) = if p > g.p_cut {
                (g.fc, 0.0)
            } else {
                let e_str = if FAST { table.exp_neg::<F>(p.min(700.0)) } else { (-p).exp() };
                (fma::<F>(g.dip, e_str, g.fc), e_str)
            };
            let decay = if FAST {
                g.poly_e.eval::<F>(e_str)
            } else {
                if s != memo_s {
                    calls = (calls + 1).min(16);
                    memo_d = match (&g.poly_t, calls >= 16) {
                        (Some(poly), true) => poly.eval(e_str),
                        _ => (-(g.c / s.max(f64::MIN_POSITIVE)) * ax.dt).exp(),
                    };
                    memo_s = s;
                }
                memo_d
            };
            let (changed, _) = update_blocks::<NP, F>(&mut f, &mut m, &k, &a, dir, dir * s, decay, dx);
            sum_f = hsum(&f);
            if changed {
                let (kp, kn) = free_stiffness(&m, &k);
                inv_pos = inv_den(kp);
                inv_neg = inv_den(kn);
            }
            force = fma::<F>(g.sigma, v, sum_f);
        }
        pos[kk] = xp;
        vel[kk] = xv;
        cmd[kk] = u;
        fric[kk] = force;
        xp = fma::<F>(-ax.gf0, force, free_p);
        xv = fma::<F>(-ax.gf1, force, free_v);
        if !(xp + xv + force).is_finite() {
            return Err(kk);
        }
    }
    Ok(())
}

/// Per-direction sums of the blocks that slip along that direction (`*_sl`) and of the others
/// (`*_st`), index 0 for +1, 1 for -1.
struct DirSums {
    a_sl_signed: [f64; 2],
    k_st: [f64; 2],
    inv: [f64; 2],
    pc: [f64; 2],
}

#[inline(always)]
fn dir_sums<const NP: usize>(m: &[f64; NP], k: &[f64; NP], a: &[f64; NP], gf0: f64, sig_inv_dt: f64, pc_scale: f64) -> DirSums {
    let mut s = DirSums { a_sl_signed: [0.0; 2], k_st: [0.0; 2], inv: [0.0; 2], pc: [0.0; 2] };
    for (di, d) in [(0usize, 1.0f64), (1, -1.0)] {
        let (mut asl, mut kst) = (0.0, 0.0);
        for i in 0..NP {
            if m[i] == d {
                asl += a[i];
            } else {
                kst += k[i];
            }
        }
        s.a_sl_signed[di] = d * asl;
        s.k_st[di] = kst;
        s.inv[di] = 1.0 / (1.0 + gf0 * (kst + sig_inv_dt));
        s.pc[di] = s.inv[di] * pc_scale;
    }
    s
}

/// Masked sums of the block forces: (slipping along +1, not along +1, along -1, not along -1).
#[inline(always)]
fn force_sums<const NP: usize>(f: &[f64; NP], m: &[f64; NP]) -> [f64; 4] {
    let mut sp = [0.0; NP];
    let mut sn = [0.0; NP];
    for i in 0..NP {
        sp[i] = if m[i] == 1.0 { f[i] } else { 0.0 };
        sn[i] = if m[i] == -1.0 { f[i] } else { 0.0 };
    }
    let total = hsum(f);
    let (p, q) = (hsum(&sp), hsum(&sn));
    [p, total - p, q, total - q]
}

#[cold]
#[inline(never)]
fn exact_sum<const NP: usize>(f: &[f64; NP]) -> f64 {
    hsum(f)
}

/// See the module doc. Needs an input delay of at least one step.
#[inline(always)]
pub fn run_v3<const NP: usize, const F: bool, const FAST: bool>(ax: &Axis, pid: &PidP, g: &GmsP, r: &[f64], out: Out<'_>) -> Result<(), usize> {
    assert!(ax.m >= 1, "run_v3 needs an input delay of at least one step");
    let n = r.len();
    let (pos, vel, cmd, fric) = (&mut out.pos[..n], &mut out.vel[..n], &mut out.cmd[..n], &mut out.fric[..n]);
    let table = ExpTable::new();
    let k: [f64; NP] = pad(&g.k);
    let a: [f64; NP] = pad(&g.alpha);
    let mut f = [0.0f64; NP];
    let mut m = [0.0f64; NP];
    let len = ring_len(ax.m);
    let mask = len - 1;
    let mut buf = vec![0.0f64; len];
    let (mut xp, mut xv) = (r[0], 0.0);
    let mut pid_s = PidState { integral: 0.0, deriv: 0.0, prev_e: r[0] - xp };
    let inv_dt = ax.inv_dt;
    let sig_inv_dt = g.sigma * inv_dt;
    let pc_scale = inv_dt * g.inv_vs;
    // trial' = Q - a1 f - gf0 sum' with f = sum' + sigma v:  b = a1 + gf0.
    let pm1 = ax.p00 - 1.0;
    let a1 = fma::<F>(pm1, ax.gf0, ax.p01 * ax.gf1);
    let b = a1 + ax.gf0;
    let a1_sigma = a1 * g.sigma;
    let mut ds = dir_sums(&m, &k, &a, ax.gf0, sig_inv_dt, pc_scale);
    let mut fs = [0.0f64; 4];
    // Beyond 700 the table exponential's scale would underflow: E = 0 there (s = fc to rounding).
    let p_cut = g.p_cut.min(700.0);
    // Step 0's residual the core's way (the delayed inputs are still zero).
    let mut trial = {
        let free_p = fma::<F>(ax.p00, xp, fma::<F>(ax.p01, xv, 0.0));
        free_p - xp
    };
    for kk in 0..n {
        let e = r[kk] - xp;
        let u = pid_s.update(pid, e);
        buf[kk & mask] = u;
        let old = buf[kk.wrapping_sub(ax.m + 1) & mask];
        let new = buf[kk.wrapping_sub(ax.m) & mask];
        let new1 = buf[(kk + 1).wrapping_sub(ax.m) & mask];
        let free_p = fma::<F>(ax.p00, xp, fma::<F>(ax.p01, xv, fma::<F>(ax.go0, old, ax.gn0 * new)));
        let free_v = fma::<F>(ax.p11, xv, fma::<F>(ax.p10, xp, fma::<F>(ax.go1, old, ax.gn1 * new)));
        // Next step's free displacement without its friction: known now, off the chain.
        let q = fma::<F>(pm1, free_p, fma::<F>(ax.p01, free_v, fma::<F>(ax.go0, new, ax.gn0 * new1)));
        let force;
        if trial == 0.0 {
            // At rest: every block sticks and holds its force.
            let changed = m.iter().any(|&x| x != 0.0);
            m = [0.0; NP];
            if changed {
                ds = dir_sums(&m, &k, &a, ax.gf0, sig_inv_dt, pc_scale);
                fs = force_sums(&f, &m);
            }
            let sum_f = fs[1]; // nothing slips: all blocks are "not along +1"
            force = sum_f;
            trial = fma::<F>(-b, sum_f, q);
        } else {
            let di = if trial >= 0.0 { 0 } else { 1 };
            let dir = if trial >= 0.0 { 1.0 } else { -1.0 };
            let inv = ds.inv[di];
            let dx = trial * inv;
            let v = dx * inv_dt;
            // |trial| times the direction's factor without waiting for the direction: both
            // products in parallel, then one max (trial*pc0 >= 0 >= -trial*pc1 iff trial >= 0).
            let p = (trial * ds.pc[0]).max(-trial * ds.pc[1]);
            let e_str = if p > p_cut {
                0.0
            } else if FAST {
                // The exponential's first step straight from `trial` for both directions, then
                // a select: the multiply that forms `p` leaves the chain.
                let kd = if trial >= 0.0 { ExpTable::kd_for::<F>(trial, ds.pc[0]) } else { ExpTable::kd_for::<F>(-trial, ds.pc[1]) };
                table.exp_neg_kd::<F>(kd, -p)
            } else {
                (-p).exp()
            };
            let s = fma::<F>(g.dip, e_str, g.fc);
            let decay = g.poly_e.eval::<F>(e_str);
            let sasl = ds.a_sl_signed[di];
            let (f_sl, f_st) = (fs[2 * di], fs[2 * di + 1]);
            let gg = fma::<F>(-sasl, s, f_sl);
            let c = fma::<F>(sasl, s, fma::<F>(ds.k_st[di], dx, f_st));
            let qv = fma::<F>(-a1_sigma, v, q);
            let rr = fma::<F>(-b, c, qv);
            trial = fma::<F>(-b * gg, decay, rr);
            let mut sum_f = fma::<F>(decay, gg, c);
            let (changed, broke) = update_blocks::<NP, F>(&mut f, &mut m, &k, &a, dir, dir * s, decay, dx);
            if broke {
                sum_f = exact_sum(&f);
                trial = fma::<F>(-b, sum_f, qv);
            }
            if changed {
                ds = dir_sums(&m, &k, &a, ax.gf0, sig_inv_dt, pc_scale);
            }
            fs = force_sums(&f, &m);
            force = fma::<F>(g.sigma, v, sum_f);
        }
        pos[kk] = xp;
        vel[kk] = xv;
        cmd[kk] = u;
        fric[kk] = force;
        xp = fma::<F>(-ax.gf0, force, free_p);
        xv = fma::<F>(-ax.gf1, force, free_v);
        if !(xp + xv + force).is_finite() {
            return Err(kk);
        }
    }
    Ok(())
}

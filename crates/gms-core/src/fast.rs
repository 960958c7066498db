//! The closed loop with a GMS friction model, written for step latency (the common case of a
//! long single run: one step depends on the one before, so its time is the latency of that chain).
//!
//! Same model and the same exact per-step update as [`crate::friction::Gms`] with the linearly
//! implicit coupling of `simulate_generic_into`; results agree with the generic path to rounding
//! (tests: `fast_path_matches_the_generic_path`). What differs is how each step is evaluated:
//!
//! - **the next step's coupling residual in closed form.** The generic step forms the coupling
//!   residual `trial = free_dx - gf0 F_sum` from the new state. Here it comes straight from this
//!   step's Stribeck level and slip decay: with the blocks that slip along the motion (force sum
//!   `f_sl`, signed fractions `a_sl`) and the others (`f_st`, stiffness `k_st`), the block sum
//!   after the step is `f_st + k_st dx + a_sl w + f_sl d` with `w = s (1 - d)`, so
//!   `trial' = A + alpha w + beta d` where `A`, `alpha`, `beta` are known before the step's
//!   Stribeck evaluation (the plant's part of the next step is known a step ahead because the
//!   drive input is delayed by at least one step). The exact block update still runs every step,
//!   off the chain; a block breaking away (start, reversals) takes the exact block sum instead.
//! - **one table look-up instead of `exp`, a division and `exp`.** `s`, `w` and the slip decay
//!   `d = exp(-c dt / s)` are smooth functions of `p = |v| / vs`; on intervals of width 1/8 in `p`
//!   each is a degree-7 polynomial (Chebyshev interpolation, built on first use of an interval and
//!   checked against the exact formulas at nine points to [`TABLE_TOL`]). The three evaluate
//!   side by side in one vector; beyond the cut-off where `s == fc` exactly, constants.
//! - **slip regime**: while every block slips along the motion, each block follows
//!   `f_i' = d f_i + a_i dir w`, so their sum is one number and the step touches no block array;
//!   the residual's look-up row is predicted (it changes rarely), so the table load leaves the
//!   chain, and the last force enters the next residual through one multiply-add. When the motion
//!   stops or reverses, the blocks are rebuilt and the general step runs.
//! - general step: branch-free block updates over arrays padded to 4, 8 or 16 blocks;
//!   per-direction constants (coupling reciprocal, ...) recomputed only when a block changes mode.
//!
//! Each kernel is compiled twice, for the baseline x86-64 target and with AVX2 + FMA, and the
//! second is chosen at run time where the CPU has it ([`crate::numeric::has_avx2_fma`]).

use crate::closed_loop::{non_finite, CANCEL_CHECK_STEPS};
use crate::control::Controller;
use crate::error::{CoreError, Result};
use crate::friction::{Gms, SlipLaw};
use crate::numeric::fma_if;
use crate::plant::DiscretePlant;
use crate::ClosedLoopInput;
use std::sync::atomic::Ordering;

/// Interval width in `p` of the Stribeck table.
const H: f64 = 0.125;
const INV_H: f64 = 8.0;
/// Highest Stribeck exponent the table covers; models whose curve only settles to `fc` beyond it
/// (`fc` tiny against `fs - fc`) take the generic path.
const P_MAX: f64 = 64.0;
/// Accepted deviation of the table from the exact `s` (relative), `w` (relative to `s`) and `d`
/// (absolute) at the check points: a few units in the last place.
pub const TABLE_TOL: f64 = 1e-14;
/// `1.5 * 2^52`: adding it rounds to an integer held in the low mantissa bits.
const SHIFT: f64 = 6755399441055744.0;

/// `s(p) = fc + (fs - fc) exp(-p)`, `w = s (1 - d)` and `d = exp(-c dt / s)` as piecewise
/// polynomials in `r = p - j H`, one row of coefficients per interval `j`, built on first use.
#[derive(Debug, Clone)]
pub struct StribeckTable {
    fc: f64,
    dip: f64,
    c: f64,
    dt: f64,
    /// Beyond this `p`, `s == fc` exactly (the Stribeck curve's own cut-off).
    p_top: f64,
    jmax: usize,
    /// `rows[j][i] = [s_i, w_i, d_i, flag]`: monomial coefficients of degree `i`; `rows[j][0][3]`
    /// is NaN until the row is built. Row `jmax + 1` holds the constants beyond `p_top`.
    rows: Vec<[[f64; 4]; 8]>,
    /// `(s, w, d)` beyond `p_top`.
    beyond: [f64; 3],
}

impl StribeckTable {
    /// The (empty) table for a GMS model at step `dt`, or `None` where the fast path does not apply.
    pub fn new(g: &Gms, dt: f64) -> Option<Self> {
        let st = &g.stribeck;
        if g.slip_law != SlipLaw::Time || st.delta != 1.0 || !(st.fc > 0.0) {
            return None;
        }
        let p_top = st.settled_exponent();
        if !(p_top <= P_MAX) {
            return None;
        }
        let d_fc = (-(g.c / st.fc) * dt).exp();
        let jmax = if p_top >= 0.0 { (p_top * INV_H).ceil() as usize } else { 0 };
        // Rows 0..=jmax on demand; row jmax + 1: the constants beyond the cut-off.
        let mut rows = vec![[[0.0; 4]; 8]; jmax + 2];
        for r in rows.iter_mut() {
            r[0][3] = f64::NAN;
        }
        rows[jmax + 1][0] = [st.fc, st.fc * (1.0 - d_fc), d_fc, 0.0];
        Some(Self { fc: st.fc, dip: st.fs - st.fc, c: g.c, dt, p_top, jmax, rows, beyond: [st.fc, st.fc * (1.0 - d_fc), d_fc] })
    }

    /// Exact `(s, w, d)` at `p`, as the generic path evaluates them.
    fn exact(&self, p: f64) -> [f64; 3] {
        let s = crate::numeric::fma(self.dip, (-p).exp(), self.fc);
        let d = (-(self.c / s.max(f64::MIN_POSITIVE)) * self.dt).exp();
        [s, s * (1.0 - d), d]
    }

    /// Build row `j`; `false` if the polynomials miss the exact values by more than [`TABLE_TOL`].
    #[cold]
    #[inline(never)]
    fn build(&mut self, j: usize) -> bool {
        const N: usize = 8;
        let centre = j as f64 * H;
        let half = 0.5 * H;
        let angles: [f64; N] = std::array::from_fn(|k| std::f64::consts::PI * (k as f64 + 0.5) / N as f64);
        let values: [[f64; 3]; N] = std::array::from_fn(|k| self.exact(centre + half * angles[k].cos()));
        let mut row = [[0.0f64; 4]; 8];
        for q in 0..3 {
            // Chebyshev coefficients of the interpolant, then monomials in t = r / half ...
            let mut cheb = [0.0f64; N];
            for (m, c) in cheb.iter_mut().enumerate() {
                *c = angles.iter().zip(&values).map(|(&a, v)| v[q] * (m as f64 * a).cos()).sum::<f64>() * 2.0 / N as f64;
            }
            cheb[0] *= 0.5;
            let mut mono = [0.0f64; N];
            let (mut t_prev, mut t_cur) = ([0.0f64; N], [0.0f64; N]);
            t_prev[0] = 1.0;
            t_cur[1] = 1.0;
            for i in 0..N {
                mono[i] += cheb[0] * t_prev[i] + cheb[1] * t_cur[i];
            }
            for &cm in cheb.iter().skip(2) {
                let mut t_next = [0.0f64; N];
                for i in 0..N {
                    t_next[i] = if i > 0 { 2.0 * t_cur[i - 1] } else { 0.0 } - t_prev[i];
                }
                for i in 0..N {
                    mono[i] += cm * t_next[i];
                }
                t_prev = t_cur;
                t_cur = t_next;
            }
            // ... then in r: t^i = r^i / half^i.
            let mut scale = 1.0;
            for (i, r) in row.iter_mut().enumerate() {
                r[q] = mono[i] * scale;
                scale /= half;
            }
        }
        for i in 0..=8 {
            let r = half * (-1.0 + i as f64 / 4.0);
            let got = eval_row::<false>(&row, r, r * r);
            let want = self.exact(centre + r);
            let s = want[0].abs();
            let ok = (got[0] - want[0]).abs() <= TABLE_TOL * s && (got[1] - want[1]).abs() <= TABLE_TOL * s && (got[2] - want[2]).abs() <= TABLE_TOL;
            if !ok {
                return false;
            }
        }
        row[0][3] = 0.0;
        self.rows[j] = row;
        true
    }
}

/// The three polynomials of a row at `r` (Estrin: three multiply-add levels).
#[inline(always)]
fn eval_row<const F: bool>(c: &[[f64; 4]; 8], r: f64, r2: f64) -> [f64; 4] {
    let r4 = r2 * r2;
    std::array::from_fn(|q| {
        let a = fma_if::<F>(c[1][q], r, c[0][q]);
        let b = fma_if::<F>(c[3][q], r, c[2][q]);
        let e = fma_if::<F>(c[5][q], r, c[4][q]);
        let f = fma_if::<F>(c[7][q], r, c[6][q]);
        fma_if::<F>(fma_if::<F>(f, r2, e), r4, fma_if::<F>(b, r2, a))
    })
}

/// Output rows of one run (each `Record::samples` long), as in the generic loop.
pub(crate) struct Outs<'a> {
    pub pos: Option<&'a mut [f64]>,
    pub vel: Option<&'a mut [f64]>,
    pub meas: Option<&'a mut [f64]>,
    pub cmd: Option<&'a mut [f64]>,
    pub fric: Option<&'a mut [f64]>,
    pub err: Option<&'a mut [f64]>,
    pub every: usize,
}

/// How a fast run ended.
pub(crate) enum Outcome {
    Done,
    /// The table could not reach its tolerance somewhere along the run: rerun on the generic path.
    Fallback,
}

/// Whether a run can take the fast path: GMS with the time slip law, `delta = 1`, at most 16
/// blocks, an input delay of at least one whole step and shorter than the run.
pub(crate) fn eligible(g: &Gms, d: &DiscretePlant, n: usize) -> bool {
    g.slip_law == SlipLaw::Time && g.stribeck.delta == 1.0 && g.n_blocks() <= 16 && d.delay_steps >= 1 && d.delay_steps < n
}

/// Run the fast kernel for `g` (reset state) under `ctrl` (prepared, begun).
pub(crate) fn run<C: Controller + Clone>(g: &Gms, table: &mut StribeckTable, d: &DiscretePlant, ctrl: &mut C, input: &ClosedLoopInput<'_>, out: Outs<'_>) -> Result<Outcome> {
    // A run with a reference and nothing else per sample (the common case) gets a loop
    // without the per-sample optional inputs.
    let plain = input.reference.is_some()
        && input.feedforward.is_none()
        && input.input_disturbance.is_none()
        && input.load_force.is_none()
        && input.measurement_noise.is_none()
        && input.quantization == 0.0;
    macro_rules! go {
        ($np:literal, $plain:literal) => {{
            #[cfg(target_arch = "x86_64")]
            if crate::numeric::has_avx2_fma() {
                // SAFETY: the CPU has AVX2 and FMA (checked at run time just above).
                return unsafe { kernel_avx2::<$np, $plain, C>(g, table, d, ctrl, input, out) };
            }
            kernel::<$np, false, $plain, C>(g, table, d, ctrl, input, out)
        }};
    }
    match (g.n_blocks(), plain) {
        (0..=4, true) => go!(4, true),
        (0..=4, false) => go!(4, false),
        (5..=8, true) => go!(8, true),
        (5..=8, false) => go!(8, false),
        (_, true) => go!(16, true),
        (_, false) => go!(16, false),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn kernel_avx2<const NP: usize, const PLAIN: bool, C: Controller + Clone>(
    g: &Gms,
    table: &mut StribeckTable,
    d: &DiscretePlant,
    ctrl: &mut C,
    input: &ClosedLoopInput<'_>,
    out: Outs<'_>,
) -> Result<Outcome> {
    kernel::<NP, true, PLAIN, C>(g, table, d, ctrl, input, out)
}

#[inline(always)]
fn pad<const NP: usize>(v: &[f64]) -> [f64; NP] {
    let mut a = [0.0; NP];
    a[..v.len()].copy_from_slice(v);
    a
}

/// Sum of a padded array: halves until four remain, then `(a0 + a2) + (a1 + a3)`.
#[inline(always)]
pub(crate) fn hsum<const NP: usize>(a: &[f64; NP]) -> f64 {
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

/// Per-direction constants (index 0: motion in +, 1: in -), recomputed when a block changes mode.
#[derive(Clone, Copy)]
struct Dir {
    /// Coupling reciprocal `1 / (1 + gf0 (k_st + sigma / dt))`.
    inv: [f64; 2],
    /// `p = trial * pq` (`|v| / vs`, sign folded in).
    pq: [f64; 2],
    /// `kd = trial * kq + SHIFT` rounds `p / H` to the interval index.
    kq: [f64; 2],
    /// Signed sum of the fractions of the blocks slipping along the direction.
    a_sl: [f64; 2],
    /// `A = trial * sa + (q - b f_st)`.
    sa: [f64; 2],
    /// Force without the slipping blocks: `f_st + trial * sf`.
    sf: [f64; 2],
    /// `-b a_sl`.
    alpha: [f64; 2],
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn dir_consts<const NP: usize>(m: &[f64; NP], k: &[f64; NP], a: &[f64; NP], gf0: f64, sig_inv_dt: f64, pc_scale: f64, a1s_inv_dt: f64, b: f64) -> Dir {
    let mut out = Dir { inv: [0.0; 2], pq: [0.0; 2], kq: [0.0; 2], a_sl: [0.0; 2], sa: [0.0; 2], sf: [0.0; 2], alpha: [0.0; 2] };
    for (di, dir) in [(0usize, 1.0f64), (1, -1.0)] {
        let (mut asl, mut kst) = (0.0, 0.0);
        for i in 0..NP {
            if m[i] == dir {
                asl += a[i];
            } else {
                kst += k[i];
            }
        }
        let inv = 1.0 / (1.0 + gf0 * (kst + sig_inv_dt));
        out.inv[di] = inv;
        out.pq[di] = dir * inv * pc_scale;
        out.kq[di] = out.pq[di] * INV_H;
        out.a_sl[di] = dir * asl;
        out.sa[di] = -(inv * (a1s_inv_dt + b * kst));
        out.sf[di] = inv * (kst + sig_inv_dt);
        out.alpha[di] = -b * out.a_sl[di];
    }
    out
}

/// `(sum of forces of blocks slipping in +, in -, all)`.
#[inline(always)]
fn force_sums<const NP: usize>(f: &[f64; NP], m: &[f64; NP]) -> [f64; 3] {
    let sp: [f64; NP] = std::array::from_fn(|i| if m[i] == 1.0 { f[i] } else { 0.0 });
    let sn: [f64; NP] = std::array::from_fn(|i| if m[i] == -1.0 { f[i] } else { 0.0 });
    [hsum(&sp), hsum(&sn), hsum(f)]
}

#[inline(always)]
fn kernel<const NP: usize, const F: bool, const PLAIN: bool, C: Controller + Clone>(
    g: &Gms,
    table: &mut StribeckTable,
    d: &DiscretePlant,
    ctrl_out: &mut C,
    input: &ClosedLoopInput<'_>,
    out: Outs<'_>,
) -> Result<Outcome> {
    let fma = fma_if::<F>;
    // A local copy keeps the controller's state in registers; written back at the end.
    let mut ctrl_local = ctrl_out.clone();
    let ctrl = &mut ctrl_local;
    let n = input.len();
    let every = out.every.max(1);
    let samples = n.div_ceil(every);
    let Outs { pos, vel, meas, cmd, fric, err, .. } = out;
    // The recorded outputs as (slot, row): slots 0..6 are position, velocity, measured, command,
    // friction, error; a run that records one array pays for one store.
    let mut active: Vec<(usize, &mut [f64])> = [pos, vel, meas, cmd, fric, err].into_iter().enumerate().filter_map(|(i, o)| o.map(|b| (i, &mut b[..samples]))).collect();
    let k: [f64; NP] = pad(&g.k);
    let a: [f64; NP] = pad(&g.alpha);
    let mut f = [0.0f64; NP];
    let mut m = [0.0f64; NP];
    let (p00, p01, p10, p11) = (d.phi[(0, 0)], d.phi[(0, 1)], d.phi[(1, 0)], d.phi[(1, 1)]);
    let (go0, go1, gn0, gn1) = (d.gamma_old[0], d.gamma_old[1], d.gamma_new[0], d.gamma_new[1]);
    let (gf0, gf1) = (d.gamma_force[0], d.gamma_force[1]);
    let dt = input.dt;
    let inv_dt = 1.0 / dt;
    let sigma = g.sigma;
    let sig_inv_dt = sigma * inv_dt;
    let pc_scale = inv_dt / g.stribeck.vs;
    // trial' = q - a1 F - gf0 F_sum with F = F_sum + sigma v: b = a1 + gf0.
    let pm1 = p00 - 1.0;
    let a1 = fma(pm1, gf0, p01 * gf1);
    let b = a1 + gf0;
    let a1_sigma = a1 * sigma;
    let a1s_inv_dt = a1_sigma * inv_dt;
    let consts = |m: &[f64; NP]| dir_consts(m, &k, &a, gf0, sig_inv_dt, pc_scale, a1s_inv_dt, b);
    let mut dc = consts(&m);
    let mut fs = [0.0f64; 3];
    let (p_top, jmax, beyond) = (table.p_top, table.jmax, table.beyond);

    // Delay ring: u[k] at k & mask; slots not yet written hold 0 (the line starts empty).
    let delay = d.delay_steps;
    let len = (delay + 2).next_power_of_two();
    let mask = len - 1;
    let mut ring = vec![0.0f64; len];
    let (q_step, inv_q) = (input.quantization, if input.quantization > 0.0 { 1.0 / input.quantization } else { 0.0 });
    let (lo, hi) = (input.drive_min, input.drive_max);
    // Inputs cut to the run's length: the indexing below needs no bounds checks.
    fn cut(a: Option<&[f64]>, n: usize) -> Option<&[f64]> {
        a.map(|a| &a[..n])
    }
    let (reference, noise, feedforward, disturbance, load) =
        (cut(input.reference, n), cut(input.measurement_noise, n), cut(input.feedforward, n), cut(input.input_disturbance, n), cut(input.load_force, n));
    let zeros = [0.0f64; 0];
    let plain_ref = if PLAIN { reference.unwrap_or(&zeros) } else { &zeros };
    let load_at = |i: usize| load.map_or(0.0, |l| if i < n { l[i] } else { 0.0 });
    let (mut xp, mut xv) = (input.initial_position, input.initial_velocity);
    // Step 0's residual the generic way (the delayed inputs are still zero).
    let mut trial = {
        let free_p = fma(p00, xp, fma(p01, xv, fma(go0, 0.0, gn0 * 0.0))) - gf0 * load_at(0);
        free_p - xp
    };
    let (mut next_record, mut j_out) = (0usize, 0usize);
    // Slip regime: every block slips along `slip_dir`. Then each block follows
    // `f_i' = d f_i + a_i dir w`, so the blocks are `f_i = a_i A + f0_i acc_b` and their sum
    // one scalar: the step needs no block arrays (they are rebuilt when the regime ends).
    let asum: f64 = a.iter().sum();
    let (mut slip, mut slip_dir, mut slip_sum, mut acc_b) = (false, 0.0f64, 0.0f64, 1.0f64);
    // The blocks from the lumped sum: `sum = asum A + sum(f0) acc_b` gives `A`.
    let blocks_of = |slip_sum: f64, acc_b: f64, f0: &[f64; NP], f: &mut [f64; NP]| {
        let s0: f64 = f0.iter().sum();
        let big_a = (slip_sum - s0 * acc_b) / asum;
        for i in 0..NP {
            f[i] = fma(a[i], big_a, f0[i] * acc_b);
        }
    };
    let mut f0 = f;
    // The last step's free motion and force (the slip regime forms the next residual from them).
    let (mut lf_p, mut lf_v, mut lf_f) = (0.0f64, 0.0f64, 0.0f64);
    let c_p = fma(p00, gf0, p01 * gf1);
    let c_v = fma(p10, gf0, p11 * gf1);
    let c_q = fma(pm1, c_p, p01 * c_v);
    macro_rules! prologue {
        ($kk:ident, $r:ident, $y:ident, $u:ident, $old:ident, $new:ident, $new1:ident) => {
            let kk = $kk;
            let (r, y, u);
            if PLAIN {
                r = plain_ref[kk];
                y = xp;
                u = ctrl.update(r, y).clamp(lo, hi);
            } else {
                r = reference.map_or(0.0, |a| a[kk]);
                let mut ym = xp;
                if let Some(a) = noise {
                    ym += a[kk];
                }
                if q_step > 0.0 {
                    ym = (ym * inv_q).round() * q_step;
                }
                y = ym;
                let mut uu = ctrl.update(r, y);
                if let Some(a) = feedforward {
                    uu += a[kk];
                }
                if let Some(a) = disturbance {
                    uu += a[kk];
                }
                u = uu.clamp(lo, hi);
            }
            // SAFETY (here and below): indices are masked to the ring's power-of-two length.
            let (old, new, new1) = unsafe {
                *ring.get_unchecked_mut(kk & mask) = u;
                (*ring.get_unchecked(kk.wrapping_sub(delay + 1) & mask), *ring.get_unchecked(kk.wrapping_sub(delay) & mask), *ring.get_unchecked((kk + 1).wrapping_sub(delay) & mask))
            };
            let ($r, $y, $u, $old, $new, $new1) = (r, y, u, old, new, new1);
        };
    }
    // The plant's free motion over the step and the next step's residual without friction (known
    // now: the input is delayed), from the state.
    macro_rules! free_motion {
        ($kk:ident, $old:ident, $new:ident, $new1:ident, $free_p:ident, $free_v:ident, $q:ident) => {
            let (kk, old, new, new1) = ($kk, $old, $new, $new1);
            let mut free_p = fma(p00, xp, fma(p01, xv, fma(go0, old, gn0 * new)));
            let mut free_v = fma(p11, xv, fma(p10, xp, fma(go1, old, gn1 * new)));
            if let (false, Some(l)) = (PLAIN, load) {
                free_p -= gf0 * l[kk];
                free_v -= gf1 * l[kk];
            }
            let mut q = fma(pm1, free_p, fma(p01, free_v, fma(go0, new, gn0 * new1)));
            if !PLAIN && load.is_some() {
                q -= gf0 * load_at(kk + 1);
            }
            let ($free_p, $free_v, $q) = (free_p, free_v, q);
        };
    }
    macro_rules! epilogue {
        ($kk:ident, $r:ident, $y:ident, $u:ident, $free_p:ident, $free_v:ident, $force:ident) => {
            let (kk, r, y, u, free_p, free_v, force) = ($kk, $r, $y, $u, $free_p, $free_v, $force);
            if kk == next_record {
                let vals = [xp, xv, y, u, force, r - xp];
                for (slot, o) in active.iter_mut() {
                    // SAFETY: j_out = kk / every < samples = o.len() (kk < n).
                    unsafe { *o.get_unchecked_mut(j_out) = vals[*slot] };
                }
                j_out += 1;
                next_record += every;
            }
            xp = fma(-gf0, force, free_p);
            xv = fma(-gf1, force, free_v);
            if !(xp + xv + force + u + y).is_finite() {
                let quantity = if !u.is_finite() {
                    "command"
                } else if !y.is_finite() {
                    "measured position"
                } else if !force.is_finite() {
                    "friction"
                } else if !xv.is_finite() {
                    "velocity"
                } else {
                    "position"
                };
                return Err(non_finite(quantity, kk, dt));
            }
        };
    }
    let mut start = 0;
    while start < n {
        if input.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(CoreError::Interrupted);
        }
        let end = (start + CANCEL_CHECK_STEPS).min(n);
        let mut kk = start;
        while kk < end {
            if slip {
                let di = if slip_dir > 0.0 { 0 } else { 1 };
                let (kq, pq, inv, sa, alpha) = (dc.kq[di], dc.pq[di], dc.inv[di], dc.sa[di], dc.alpha[di]);
                let dir_asum = slip_dir * asum;
                let v_per_trial = inv * inv_dt;
                // The interval of the Stribeck table in use: its row is loaded before the index of
                // this step is known (the index changes rarely), so the look-up leaves the chain.
                let (mut key, mut centre) = (usize::MAX, 0.0f64);
                while kk < end && trial * slip_dir > 0.0 {
                    prologue!(kk, r, y, u, old, new, new1);
                    // The free motion and the next residual from the last step's free motion,
                    // with the last force entering through one multiply-add each (the same
                    // recurrence as through the state, in other variables).
                    let mut fp0 = fma(p00, lf_p, fma(p01, lf_v, fma(go0, old, gn0 * new)));
                    let mut fv0 = fma(p11, lf_v, fma(p10, lf_p, fma(go1, old, gn1 * new)));
                    if let (false, Some(l)) = (PLAIN, load) {
                        fp0 -= gf0 * l[kk];
                        fv0 -= gf1 * l[kk];
                    }
                    let mut q0 = fma(pm1, fp0, fma(p01, fv0, fma(go0, new, gn0 * new1)));
                    if !PLAIN && load.is_some() {
                        q0 -= gf0 * load_at(kk + 1);
                    }
                    let free_p = fma(-c_p, lf_f, fp0);
                    let free_v = fma(-c_v, lf_f, fv0);
                    let q = fma(-c_q, lf_f, q0);
                    let p = trial * pq;
                    let kd = fma(trial, kq, SHIFT);
                    let want = if p <= p_top { ((kd.to_bits() & 0xffff_ffff) as usize).min(jmax) } else { jmax + 1 };
                    if want != key {
                        if want <= jmax && unsafe { table.rows.get_unchecked(want) }[0][3].is_nan() && !table.build(want) {
                            return Ok(Outcome::Fallback);
                        }
                        key = want;
                        centre = if want <= jmax { -(want as f64) * H } else { -p_top };
                    }
                    // SAFETY: key <= jmax + 1 < rows.len().
                    let c = unsafe { table.rows.get_unchecked(key) };
                    let rr = fma(trial, pq, centre).min(H);
                    let r2 = rr * rr;
                    let r4 = r2 * r2;
                    let wd: [f64; 2] = std::array::from_fn(|i| {
                        let q = i + 1;
                        let x0 = fma(c[1][q], rr, c[0][q]);
                        let x1 = fma(c[3][q], rr, c[2][q]);
                        let x2 = fma(c[5][q], rr, c[4][q]);
                        let x3 = fma(c[7][q], rr, c[6][q]);
                        fma(fma(x3, r2, x2), r4, fma(x1, r2, x0))
                    });
                    let (w, dcy) = (wd[0], wd[1]);
                    let v = trial * v_per_trial;
                    let big_a = fma(trial, sa, q);
                    let next = fma(alpha, w, fma(-b * slip_sum, dcy, big_a));
                    slip_sum = fma(slip_sum, dcy, dir_asum * w);
                    acc_b *= dcy;
                    trial = next;
                    let force = fma(sigma, v, slip_sum);
                    epilogue!(kk, r, y, u, free_p, free_v, force);
                    (lf_p, lf_v, lf_f) = (free_p, free_v, force);
                    kk += 1;
                }
                if kk < end {
                    // The motion stops or reverses: back to the block arrays.
                    blocks_of(slip_sum, acc_b, &f0, &mut f);
                    m = [slip_dir; NP];
                    dc = consts(&m);
                    fs = force_sums(&f, &m);
                    slip = false;
                }
            } else {
                while kk < end {
                    prologue!(kk, r, y, u, old, new, new1);
                    free_motion!(kk, old, new, new1, free_p, free_v, q);
                    let (mut all_along, mut step_dir) = (false, 0.0f64);
            let force;
            if trial == 0.0 {
                // At rest: every block sticks and holds its force.
                if m.iter().any(|&x| x != 0.0) {
                    m = [0.0; NP];
                    dc = consts(&m);
                    fs = force_sums(&f, &m);
                }
                force = fs[2];
                trial = fma(-b, force, q);
            } else {
                let di = if trial >= 0.0 { 0 } else { 1 };
                let dir = if trial >= 0.0 { 1.0 } else { -1.0 };
                // Both directions' index in parallel, then a select: the direction test leaves
                // the chain.
                let kd0 = fma(trial, dc.kq[0], SHIFT);
                let kd1 = fma(trial, dc.kq[1], SHIFT);
                let kd = if trial >= 0.0 { kd0 } else { kd1 };
                let p = (trial * dc.pq[0]).max(trial * dc.pq[1]);
                let jf = kd - SHIFT;
                let rr = fma(jf, -H, p);
                let j = ((kd.to_bits() & 0xffff_ffff) as usize).min(jmax);
                let far = !(p <= p_top);
                // SAFETY: j <= jmax < rows.len() (the table has jmax + 1 rows).
                let row = unsafe { table.rows.get_unchecked(j) };
                if row[0][3].is_nan() && !far && !table.build(j) {
                    return Ok(Outcome::Fallback);
                }
                let vals = eval_row::<F>(unsafe { table.rows.get_unchecked(j) }, rr, rr * rr);
                let (s, w, dcy) = if far { (beyond[0], beyond[1], beyond[2]) } else { (vals[0], vals[1], vals[2]) };
                let (f_sl, f_st) = (fs[di], fs[2] - fs[di]);
                let a_sl = dc.a_sl[di];
                let dx = trial * dc.inv[di];
                let v = dx * inv_dt;
                // trial' = A + alpha w + beta d, F = B + a_sl w + f_sl d (see the module doc).
                let big_a = fma(trial, dc.sa[di], fma(-b, f_st, q));
                let big_b = fma(trial, dc.sf[di], f_st);
                let next = fma(dc.alpha[di], w, fma(-b * f_sl, dcy, big_a));
                let mut fr = fma(a_sl, w, fma(f_sl, dcy, big_b));
                // The exact block update, branch-free over the padded blocks.
                let dir_s = dir * s;
                let dir_w = dir * w;
                let (mut changed, mut broke) = (false, false);
                for i in 0..NP {
                    let f_old = f[i];
                    let target = a[i] * dir_s;
                    let relaxed = fma(f_old, dcy, a[i] * dir_w);
                    let stuck = fma(k[i], dx, f_old);
                    let along = m[i] == dir;
                    let breaks = (stuck - target) * dir >= 0.0;
                    let past = (f_old - target) * dir >= 0.0;
                    let nf = if along | (breaks & past) {
                        relaxed
                    } else if breaks {
                        target
                    } else {
                        stuck
                    };
                    let nm = if along | breaks { dir } else { 0.0 };
                    changed |= nm != m[i];
                    broke |= !along & breaks;
                    f[i] = nf;
                    m[i] = nm;
                }
                trial = next;
                if broke {
                    // A block reached its break force inside the step: the exact block sum.
                    let sum = hsum(&f);
                    fr = fma(sigma, v, sum);
                    trial = fma(-b, sum, fma(-a1_sigma, v, q));
                }
                if changed {
                    dc = consts(&m);
                }
                fs = force_sums(&f, &m);
                force = fr;
                all_along = m.iter().all(|&x| x == dir);
                step_dir = dir;
            }
                    epilogue!(kk, r, y, u, free_p, free_v, force);
                    (lf_p, lf_v, lf_f) = (free_p, free_v, force);
                    kk += 1;
                    if all_along {
                        slip = true;
                        slip_dir = step_dir;
                        slip_sum = fs[2];
                        f0 = f;
                        acc_b = 1.0;
                        break;
                    }
                }
            }
        }
        start = end;
    }
    let _ = (&f, &m, &f0, slip_sum, acc_b);
    *ctrl_out = ctrl_local;
    Ok(Outcome::Done)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::closed_loop::{simulate, simulate_generic};
    use crate::{reference, ControllerModel, FrictionModel, Pid, Stribeck};

    /// Worst difference of the fast path against the generic loop, relative to each output's range.
    fn compare(g: &Gms, r: &[f64], dt: f64, pid: Pid) -> (f64, f64, f64) {
        let plant = reference::paper_plant();
        let input = ClosedLoopInput::new(r, dt);
        let fast = simulate(&plant, Some(&FrictionModel::Gms(g.clone())), None, Some(&ControllerModel::Pid(pid.clone())), &input).unwrap();
        let exact = simulate_generic(&plant, &mut g.clone(), &mut pid.clone(), &input).unwrap();
        let worst = |a: &[f64], b: &[f64]| {
            let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / scale
        };
        (worst(&fast.position, &exact.position), worst(&fast.velocity, &exact.velocity), worst(&fast.friction, &exact.friction))
    }

    #[test]
    fn fast_path_matches_the_generic_path() {
        let dt = 1e-4;
        let r = reference::paper_sine(200_000, dt, 2e-4, 0.5);
        for n_blocks in [1, 4, 7, 16] {
            let g = reference::gms_with_blocks(n_blocks);
            for level in [0.6, 1.0, 1.4] {
                let st = Stribeck::new(g.stribeck.fc * level, g.stribeck.fs * level, g.stribeck.vs, 1.0).unwrap();
                let g = Gms::new(st, g.k.clone(), g.alpha.clone(), g.c, g.sigma, g.slip_law).unwrap();
                let (p, v, f) = compare(&g, &r, dt, reference::paper_pid());
                assert!(p < 1e-12 && v < 1e-10 && f < 1e-10, "N={n_blocks} level {level}: position {p:e}, velocity {v:e}, friction {f:e}");
            }
        }
    }
}

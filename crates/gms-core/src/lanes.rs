//! Batches in SIMD lanes: [`LANES`] closed-loop runs of the same structure (same plant and step,
//! GMS friction with the same padded block count, PID control, a reference and nothing else per
//! sample) advanced together, every per-run quantity a `[f64; LANES]` and every operation a loop
//! over the lanes that the compiler turns into vector instructions: one AVX-512 register holds
//! the 8 lanes, or two AVX2 registers (two independent chains, which also hides latency).
//! Branches become selects; block modes are resolved per lane. Compiled three times (baseline
//! x86-64, AVX2 + FMA, AVX-512), the CPU picks at run time.
//!
//! Each lane runs the generic loop's algorithm (linearly implicit coupling with the tangent
//! stiffness, the exact per-block update) with two evaluation differences: the Stribeck
//! exponential is a table-free polynomial exponential (within 2 ulp of libm's, no gathers across
//! lanes), and the slip decay `exp(-c dt / s)` is always the Chebyshev polynomial of the Stribeck
//! exponential (accepted at [`DECAY_TOL`]). Results agree with single runs to rounding (tested:
//! `tests/batch.rs`); they do not depend on the thread count or on which other runs share the
//! vector.

use crate::closed_loop::{non_finite, ClosedLoopBuffers, ClosedLoopInput, CANCEL_CHECK_STEPS};
use crate::control::{ControllerModel, Pid};
use crate::error::{CoreError, Result};
use crate::friction::{FrictionModel, Gms, SlipLaw};
use crate::numeric::{fma_if, UnitIntervalPoly};
use crate::plant::DiscretePlant;
use crate::Axis;
use std::sync::atomic::Ordering;

/// Runs per vector group (8: one AVX-512 register; 4 per AVX2 register measured 10 % slower per
/// run-step than two registers' worth).
pub const LANES: usize = 8;
/// Accepted relative error of the slip-decay polynomial in the lanes.
pub const DECAY_TOL: f64 = 1e-14;
/// Most blocks a lane run may have.
pub const MAX_BLOCKS: usize = 8;

/// What runs must share to go into one vector (aligned groups of [`LANES`] runs, see
/// [`crate::batch::simulate_batch_into`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaneKey {
    plant: [u64; 5],
    dt: u64,
    n: usize,
    np: usize,
    drive: [u64; 2],
}

/// The lane key of a run, or `None` if it must run on its own.
pub fn lane_key(axis: &Axis, controller: Option<&ControllerModel>, input: &ClosedLoopInput<'_>) -> Option<LaneKey> {
    let g = match (&axis.friction, &axis.effects) {
        (Some(FrictionModel::Gms(g)), None) => g,
        (Some(FrictionModel::Gms(g)), Some(e)) if e.is_empty() => g,
        _ => return None,
    };
    if !matches!(controller, Some(ControllerModel::Pid(_))) || !gms_fits(g) {
        return None;
    }
    let plain = input.reference.is_some()
        && input.feedforward.is_none()
        && input.input_disturbance.is_none()
        && input.load_force.is_none()
        && input.measurement_noise.is_none()
        && input.quantization == 0.0
        && input.initial_velocity == 0.0
        && input.cancel.is_none();
    if !plain || input.validate(true).is_err() {
        return None;
    }
    let p = &axis.plant;
    let d = p.discretize(input.dt).ok()?;
    if d.delay_steps < 1 || d.delay_steps >= input.len() {
        return None;
    }
    Some(LaneKey {
        plant: [p.a.to_bits(), p.b.to_bits(), p.c.to_bits(), p.delay.to_bits(), p.force_gain.to_bits()],
        dt: input.dt.to_bits(),
        n: input.len(),
        np: if g.n_blocks() <= 4 { 4 } else { 8 },
        drive: [input.drive_min.to_bits(), input.drive_max.to_bits()],
    })
}

fn gms_fits(g: &Gms) -> bool {
    g.slip_law == SlipLaw::Time && g.stribeck.delta == 1.0 && g.stribeck.fc > 0.0 && g.stribeck.fs > 0.0 && g.n_blocks() <= MAX_BLOCKS
}

/// Per-lane parameters of a group.
struct Params<const NP: usize> {
    kp: [f64; LANES],
    ki: [f64; LANES],
    ki_dt: [f64; LANES],
    d_keep: [f64; LANES],
    d_gain: [f64; LANES],
    u_min: [f64; LANES],
    u_max: [f64; LANES],
    fc: [f64; LANES],
    dip: [f64; LANES],
    inv_vs: [f64; LANES],
    p_cut: [f64; LANES],
    sigma: [f64; LANES],
    /// Decay polynomial coefficients (monomials in `t = 2E - 1`), one row per degree.
    coef: [[f64; LANES]; 16],
    k: [[f64; LANES]; NP],
    a: [[f64; LANES]; NP],
    x0: [f64; LANES],
}

impl<const NP: usize> Params<NP> {
    /// `None` if some lane's decay polynomial misses [`DECAY_TOL`].
    fn new(runs: &[(&Gms, &Pid, f64)], dt: f64) -> Option<Self> {
        let mut coef = [[0.0; LANES]; 16];
        let mut k = [[0.0; LANES]; NP];
        let mut a = [[0.0; LANES]; NP];
        let mut out = Self {
            kp: [0.0; LANES],
            ki: [0.0; LANES],
            ki_dt: [0.0; LANES],
            d_keep: [0.0; LANES],
            d_gain: [0.0; LANES],
            u_min: [0.0; LANES],
            u_max: [0.0; LANES],
            fc: [0.0; LANES],
            dip: [0.0; LANES],
            inv_vs: [0.0; LANES],
            p_cut: [0.0; LANES],
            sigma: [0.0; LANES],
            coef,
            k,
            a,
            x0: [0.0; LANES],
        };
        for (l, &(g, pid, x0)) in runs.iter().enumerate() {
            let st = &g.stribeck;
            let (fc, fs, c) = (st.fc, st.fs, g.c);
            let poly = UnitIntervalPoly::fit(|e| (-(c / crate::numeric::fma(fs - fc, e, fc)) * dt).exp(), DECAY_TOL)?;
            for (j, row) in coef.iter_mut().enumerate() {
                row[l] = poly.coefficients()[j];
            }
            for i in 0..NP {
                k[i][l] = g.k.get(i).copied().unwrap_or(0.0);
                a[i][l] = g.alpha.get(i).copied().unwrap_or(0.0);
            }
            // The PID's coefficients exactly as `Pid::prepare` computes them.
            let inv = 1.0 / (pid.tf + dt);
            out.kp[l] = pid.kp;
            out.ki[l] = pid.ki;
            out.ki_dt[l] = pid.ki * dt;
            out.d_keep[l] = pid.tf * inv;
            out.d_gain[l] = pid.kd * inv;
            out.u_min[l] = pid.u_min;
            out.u_max[l] = pid.u_max;
            out.fc[l] = fc;
            out.dip[l] = fs - fc;
            out.inv_vs[l] = 1.0 / st.vs;
            out.p_cut[l] = st.settled_exponent().min(700.0);
            out.sigma[l] = g.sigma;
            out.x0[l] = x0;
        }
        if !(out.d_gain.iter().chain(&out.ki_dt).all(|x| x.is_finite())) {
            return None;
        }
        out.coef = coef;
        out.k = k;
        out.a = a;
        Some(out)
    }
}

/// `exp(-p)` for `0 <= p <= 700` without a table (vectorises across lanes): reduction by `ln 2`
/// and a degree-13 polynomial; within 2 ulp of libm's `exp`.
#[inline(always)]
fn exp_neg<const F: bool>(p: f64) -> f64 {
    let fma = fma_if::<F>;
    const SHIFT: f64 = 6755399441055744.0;
    let x = -p;
    let kd = fma(x, std::f64::consts::LOG2_E, SHIFT);
    let ki = kd.to_bits();
    let kd = kd - SHIFT;
    let r = fma(kd, -6.93147180369123816490e-01, x);
    let r = fma(kd, -1.90821492927058770002e-10, r);
    // |r| <= ln2 / 2: Taylor to degree 13 (truncation 2e-17 relative), Estrin's scheme.
    const C: [f64; 14] = [
        1.0,
        1.0,
        0.5,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5040.0,
        1.0 / 40320.0,
        1.0 / 362880.0,
        1.0 / 3628800.0,
        1.0 / 39916800.0,
        1.0 / 479001600.0,
        1.0 / 6227020800.0,
    ];
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let q0 = fma(fma(C[3], r, C[2]), r2, fma(C[1], r, C[0]));
    let q1 = fma(fma(C[7], r, C[6]), r2, fma(C[5], r, C[4]));
    let q2 = fma(fma(C[11], r, C[10]), r2, fma(C[9], r, C[8]));
    let q3 = fma(C[13], r, C[12]);
    let poly = fma(fma(q3, r4, q2), r8, fma(q1, r4, q0));
    // 2^n from the exponent bits (n >= -1010 since p <= 700).
    let n = (ki as i64).wrapping_sub(SHIFT.to_bits() as i64);
    poly * f64::from_bits(((n + 1023) as u64) << 52)
}

#[inline(always)]
fn hsum_lanes<const NP: usize>(f: &[[f64; LANES]; NP]) -> [f64; LANES] {
    let mut w = *f;
    let mut len = NP;
    while len > 4 {
        len /= 2;
        for i in 0..len {
            for l in 0..LANES {
                w[i][l] += w[i + len][l];
            }
        }
    }
    std::array::from_fn(|l| (w[0][l] + w[2][l]) + (w[1][l] + w[3][l]))
}

/// Output rows of the lanes' runs.
pub(crate) type LaneRows<'a> = [ClosedLoopBuffers<'a>; LANES];

/// Run one group of [`LANES`] runs (equal [`LaneKey`]s) into their rows. `Ok(false)`: some lane
/// cannot run here (decay polynomial) or failed (non-finite): run the group's runs one by one.
pub(crate) fn run_group(axes: [&Axis; LANES], pids: [&Pid; LANES], inputs: [&ClosedLoopInput<'_>; LANES], out: &mut LaneRows<'_>, cancel: Option<&std::sync::atomic::AtomicBool>) -> Result<bool> {
    let dt = inputs[0].dt;
    let d = axes[0].plant.discretize(dt)?;
    let gms: [&Gms; LANES] = std::array::from_fn(|l| match &axes[l].friction {
        Some(FrictionModel::Gms(g)) => g,
        _ => unreachable!("lane_key admits GMS runs only"),
    });
    let runs: [(&Gms, &Pid, f64); LANES] = std::array::from_fn(|l| (gms[l], pids[l], inputs[l].initial_position));
    let refs: [&[f64]; LANES] = std::array::from_fn(|l| inputs[l].reference.expect("lane runs have a reference"));
    let n_max = gms.iter().map(|g| g.n_blocks()).max().unwrap_or(0);
    macro_rules! go {
        ($np:literal) => {{
            let Some(p) = Params::<$np>::new(&runs, dt) else { return Ok(false) };
            #[cfg(target_arch = "x86_64")]
            if crate::numeric::has_avx512() {
                // SAFETY: the CPU has AVX-512 F/VL/DQ, AVX2 and FMA (checked at run time).
                return unsafe { kernel_avx512::<$np>(&d, &p, refs, inputs[0], out, cancel) };
            }
            #[cfg(target_arch = "x86_64")]
            if crate::numeric::has_avx2_fma() {
                // SAFETY: the CPU has AVX2 and FMA (checked at run time just above).
                return unsafe { kernel_avx2::<$np>(&d, &p, refs, inputs[0], out, cancel) };
            }
            kernel::<$np, false>(&d, &p, refs, inputs[0], out, cancel)
        }};
    }
    if n_max <= 4 {
        go!(4)
    } else {
        go!(8)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn kernel_avx2<const NP: usize>(d: &DiscretePlant, p: &Params<NP>, refs: [&[f64]; LANES], input: &ClosedLoopInput<'_>, out: &mut LaneRows<'_>, cancel: Option<&std::sync::atomic::AtomicBool>) -> Result<bool> {
    kernel::<NP, true>(d, p, refs, input, out, cancel)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx2,fma")]
unsafe fn kernel_avx512<const NP: usize>(d: &DiscretePlant, p: &Params<NP>, refs: [&[f64]; LANES], input: &ClosedLoopInput<'_>, out: &mut LaneRows<'_>, cancel: Option<&std::sync::atomic::AtomicBool>) -> Result<bool> {
    kernel::<NP, true>(d, p, refs, input, out, cancel)
}

#[inline(always)]
fn kernel<const NP: usize, const F: bool>(d: &DiscretePlant, p: &Params<NP>, refs: [&[f64]; LANES], input: &ClosedLoopInput<'_>, out: &mut LaneRows<'_>, cancel: Option<&std::sync::atomic::AtomicBool>) -> Result<bool> {
    let fma = fma_if::<F>;
    const L: usize = LANES;
    let n = input.len();
    let refs: [&[f64]; L] = std::array::from_fn(|l| &refs[l][..n]);
    let every = out[0].every.max(1);
    let samples = n.div_ceil(every);
    let (p00, p01, p10, p11) = (d.phi[(0, 0)], d.phi[(0, 1)], d.phi[(1, 0)], d.phi[(1, 1)]);
    let (go0, go1, gn0, gn1) = (d.gamma_old[0], d.gamma_old[1], d.gamma_new[0], d.gamma_new[1]);
    let (gf0, gf1) = (d.gamma_force[0], d.gamma_force[1]);
    let (lo, hi, dt) = (input.drive_min, input.drive_max, input.dt);
    let inv_dt = 1.0 / dt;
    let m_delay = d.delay_steps;
    let len = (m_delay + 2).next_power_of_two();
    let mask = len - 1;
    let mut ring = vec![[0.0f64; L]; len];
    let mut xp = p.x0;
    let mut xv = [0.0f64; L];
    let mut integral = [0.0f64; L];
    let mut deriv = [0.0f64; L];
    // No derivative kick on the first sample (as `Pid::update`).
    let mut prev_e: [f64; L] = std::array::from_fn(|l| refs[l][0] - xp[l]);
    let mut sum_f = [0.0f64; L];
    let mut f = [[0.0f64; L]; NP];
    let mut m = [[0.0f64; L]; NP];
    let sig_inv_dt: [f64; L] = std::array::from_fn(|l| p.sigma[l] * inv_dt);
    // The recorded outputs as (slot, one row per lane); slots 0..6 are position, velocity,
    // measured, command, friction, error. A batch records the same outputs for every run.
    let mut cols: [[Option<&mut [f64]>; L]; 6] = std::array::from_fn(|_| std::array::from_fn(|_| None));
    for (l, o) in out.iter_mut().enumerate() {
        let bufs = [o.position.as_deref_mut(), o.velocity.as_deref_mut(), o.measured.as_deref_mut(), o.command.as_deref_mut(), o.friction.as_deref_mut(), o.error.as_deref_mut()];
        for (slot, b) in bufs.into_iter().enumerate() {
            cols[slot][l] = b.map(|b| &mut b[..samples]);
        }
    }
    debug_assert!(cols.iter().all(|c| c.iter().all(Option::is_some) || c.iter().all(Option::is_none)));
    let mut active: Vec<(usize, [&mut [f64]; L])> = cols.into_iter().enumerate().filter(|(_, c)| c.iter().all(Option::is_some)).map(|(slot, c)| (slot, c.map(|b| b.expect("checked")))).collect();
    let (mut next_record, mut j_out) = (0usize, 0usize);
    let asum: [f64; L] = std::array::from_fn(|l| (0..NP).map(|i| p.a[i][l]).sum());
    let inv_slip: [f64; L] = std::array::from_fn(|l| 1.0 / (1.0 + gf0 * (0.0 + sig_inv_dt[l])));
    let (mut slip, mut sdir, mut acc_a, mut acc_b) = (false, [0.0f64; L], [0.0f64; L], [1.0f64; L]);
    let mut f0 = f;
    let decay_poly = |e: f64, l: usize| {
        let c = &p.coef;
        let t = fma(2.0, e, -1.0);
        let t2 = t * t;
        let t4 = t2 * t2;
        let t8 = t4 * t4;
        let q = |i: usize| fma(c[i + 1][l], t, c[i][l]);
        let q0 = fma(q(2), t2, q(0));
        let q1 = fma(q(6), t2, q(4));
        let q2 = fma(q(10), t2, q(8));
        let q3 = fma(q(14), t2, q(12));
        fma(fma(q3, t4, q2), t8, fma(q1, t4, q0))
    };
    let mut start = 0;
    while start < n {
        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(CoreError::Interrupted);
        }
        let end = (start + CANCEL_CHECK_STEPS).min(n);
        for kk in start..end {
            let mut u = [0.0f64; L];
            // SAFETY: kk < end <= n = refs[l].len().
            let rk: [f64; L] = std::array::from_fn(|l| unsafe { *refs[l].get_unchecked(kk) });
            for l in 0..L {
                // `Pid::update` operation for operation (plain multiply and add, as there).
                let r = rk[l];
                let e = r - xp[l];
                let de = e - prev_e[l];
                prev_e[l] = e;
                deriv[l] = p.d_keep[l] * deriv[l] + p.d_gain[l] * de;
                let ti = integral[l] + p.ki_dt[l] * e;
                let uu = p.kp[l] * e + ti + deriv[l];
                // Bitwise `&`/`|` and plain compares keep the lane loops branch-free.
                let winding = ((uu > p.u_max[l]) & (e * p.ki[l] > 0.0)) | ((uu < p.u_min[l]) & (e * p.ki[l] < 0.0));
                integral[l] = if winding { integral[l] } else { ti };
                let c = if uu < p.u_min[l] { p.u_min[l] } else { uu };
                let c = if c > p.u_max[l] { p.u_max[l] } else { c };
                let c = if c < lo { lo } else { c };
                u[l] = if c > hi { hi } else { c };
            }
            ring[kk & mask] = u;
            let old = ring[kk.wrapping_sub(m_delay + 1) & mask];
            let new = ring[kk.wrapping_sub(m_delay) & mask];
            let mut free_p = [0.0; L];
            let mut free_v = [0.0; L];
            let mut trial = [0.0; L];
            for l in 0..L {
                free_p[l] = fma(p00, xp[l], fma(p01, xv[l], fma(go0, old[l], gn0 * new[l])));
                free_v[l] = fma(p11, xv[l], fma(p10, xp[l], fma(go1, old[l], gn1 * new[l])));
                trial[l] = fma(-gf0, sum_f[l], free_p[l] - xp[l]);
            }
            let mut v = [0.0; L];
            let mut dx = [0.0; L];
            let mut force = [0.0f64; L];
            let steady = slip && (0..L).fold(true, |ok, l| ok & (trial[l] * sdir[l] > 0.0));
            if steady {
                // Slip regime (every block of every lane slips along its lane's direction): the
                // blocks are `f_i = a_i acc_a + f0_i acc_b` and their sum one number per lane.
                for l in 0..L {
                    dx[l] = trial[l] * inv_slip[l];
                    v[l] = dx[l] * inv_dt;
                    let pp = (v[l] * p.inv_vs[l]).abs();
                    let e = exp_neg::<F>(if pp < 700.0 { pp } else { 700.0 });
                    let e = if pp > p.p_cut[l] { 0.0 } else { e };
                    let x = sdir[l] * fma(p.dip[l], e, p.fc[l]);
                    let decay = decay_poly(e, l);
                    let ax = asum[l] * x;
                    sum_f[l] = fma(sum_f[l] - ax, decay, ax);
                    acc_a[l] = fma(acc_a[l] - x, decay, x);
                    acc_b[l] *= decay;
                    force[l] = fma(p.sigma[l], v[l], sum_f[l]);
                }
            } else {
                if slip {
                    // Some lane stops or reverses: back to the block arrays.
                    for i in 0..NP {
                        for l in 0..L {
                            f[i][l] = fma(p.a[i][l], acc_a[l], f0[i][l] * acc_b[l]);
                            m[i][l] = sdir[l];
                        }
                    }
                    slip = false;
                }
                let mut kfree = [0.0; L];
                for i in 0..NP {
                    for l in 0..L {
                        let dir_t = if trial[l] >= 0.0 { 1.0 } else { -1.0 };
                        kfree[l] += if m[i][l] == dir_t { 0.0 } else { p.k[i][l] };
                    }
                }
                let mut dir = [0.0; L];
                let mut dir_s = [0.0; L];
                let mut decay = [0.0; L];
                for l in 0..L {
                    let inv = 1.0 / (1.0 + gf0 * (kfree[l] + sig_inv_dt[l]));
                    dx[l] = trial[l] * inv;
                    v[l] = dx[l] * inv_dt;
                    dir[l] = if dx[l] > 0.0 { 1.0 } else { -1.0 };
                    let pp = (v[l] * p.inv_vs[l]).abs();
                    let e = exp_neg::<F>(if pp < 700.0 { pp } else { 700.0 });
                    let e = if pp > p.p_cut[l] { 0.0 } else { e };
                    dir_s[l] = dir[l] * fma(p.dip[l], e, p.fc[l]);
                    decay[l] = decay_poly(e, l);
                }
                for i in 0..NP {
                    for l in 0..L {
                        let f_old = f[i][l];
                        let target = p.a[i][l] * dir_s[l];
                        let relaxed = fma(f_old - target, decay[l], target);
                        let stuck = fma(p.k[i][l], dx[l], f_old);
                        let along = m[i][l] == dir[l];
                        let breaks = (stuck - target) * dir[l] >= 0.0;
                        let beyond = (f_old - target) * dir[l] >= 0.0;
                        let nf = if along | (breaks & beyond) {
                            relaxed
                        } else if breaks {
                            target
                        } else {
                            stuck
                        };
                        let nm = if along | breaks { dir[l] } else { 0.0 };
                        // At rest every block sticks and holds its force.
                        let zero = dx[l] == 0.0;
                        m[i][l] = if zero { 0.0 } else { nm };
                        f[i][l] = if zero { f_old } else { nf };
                    }
                }
                sum_f = hsum_lanes(&f);
                let mut all_along = true;
                for l in 0..L {
                    force[l] = if dx[l] == 0.0 { sum_f[l] } else { fma(p.sigma[l], v[l], sum_f[l]) };
                    let mut along = dx[l] != 0.0;
                    for i in 0..NP {
                        along &= m[i][l] == dir[l];
                    }
                    all_along &= along;
                }
                if all_along {
                    slip = true;
                    sdir = dir;
                    f0 = f;
                    acc_a = [0.0; L];
                    acc_b = [1.0; L];
                }
            }
            let (xp_k, xv_k) = (xp, xv);
            let mut bad = false;
            for l in 0..L {
                xp[l] = fma(-gf0, force[l], free_p[l]);
                xv[l] = fma(-gf1, force[l], free_v[l]);
                bad |= !(xp[l] + xv[l] + force[l] + u[l]).is_finite();
            }
            if kk == next_record {
                let err: [f64; L] = std::array::from_fn(|l| rk[l] - xp_k[l]);
                let vals = [xp_k, xv_k, xp_k, u, force, err];
                for (slot, rows) in active.iter_mut() {
                    for (row, &val) in rows.iter_mut().zip(&vals[*slot]) {
                        // SAFETY: j_out = kk / every < samples = row.len().
                        unsafe { *row.get_unchecked_mut(j_out) = val };
                    }
                }
                j_out += 1;
                next_record += every;
            }
            if bad {
                // The failing run reports its own error when run on its own.
                let _ = non_finite("position", kk, dt);
                return Ok(false);
            }
        }
        start = end;
    }
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Worst distance of `exp_neg` from libm's `exp(-p)` in units in the last place, on a dense
    /// grid of `[0, 700]` (finer where the Stribeck exponent lives, `p < 50`).
    fn worst_ulp(f: impl Fn(f64) -> f64) -> f64 {
        let grid = (0..=200_000).map(|i| 50.0 * i as f64 / 200_000.0).chain((0..=100_000).map(|i| 50.0 + 650.0 * i as f64 / 100_000.0));
        grid.map(|p| {
            let want = (-p).exp();
            let ulp = f64::from_bits(want.to_bits() + 1) - want;
            (f(p) - want).abs() / ulp
        })
        .fold(0.0, f64::max)
    }

    #[test]
    fn the_lanes_exponential_is_within_two_ulp_of_libm() {
        let plain = worst_ulp(exp_neg::<false>);
        assert!(plain <= 2.0, "without FMA: {plain} ulp");
        #[cfg(target_arch = "x86_64")]
        if crate::numeric::has_avx2_fma() {
            #[target_feature(enable = "avx2,fma")]
            unsafe fn fused(p: f64) -> f64 {
                exp_neg::<true>(p)
            }
            // SAFETY: the CPU has AVX2 and FMA (checked just above).
            let fused_worst = worst_ulp(|p| unsafe { fused(p) });
            assert!(fused_worst <= 2.0, "with FMA: {fused_worst} ulp");
        }
    }
}

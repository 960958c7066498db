//! "Batch in lanes": `L` runs of the same structure (same plant and delay, same number of GMS
//! blocks; per-lane PID gains and friction parameters) advanced together, struct of arrays, every
//! per-run quantity a `[f64; L]` and every operation a loop over the lanes that LLVM turns into
//! SIMD (4 doubles per AVX2 register). Branches become selects; the block modes are resolved per
//! lane; the tangent stiffness and the coupling reciprocal are recomputed every step (a vector
//! division is cheap in throughput; caching them per lane, recomputed when some lane's modes
//! change, measured slower: LLVM then leaves parts of the step scalar); the Stribeck
//! exponential is the table-free `exp_neg_poly`.
//!
//! One run in a lane is the core's algorithm with the core's operation order except: the
//! exponential (`exp_neg_poly` vs libm), the decay polynomial in `E` (core: in `2E - 1`, with a
//! memo), the block-sum order for N > 4. Results agree with single runs to rounding.

use crate::fexp::{exp_neg_poly, fma};
use crate::setup::{ring_len, Axis, GmsP, PidP};

#[derive(Debug, Clone)]
pub struct LaneParams<const L: usize, const NP: usize> {
    pub kp: [f64; L],
    pub ki: [f64; L],
    pub ki_dt: [f64; L],
    pub d_keep: [f64; L],
    pub d_gain: [f64; L],
    pub u_min: [f64; L],
    pub u_max: [f64; L],
    pub fc: [f64; L],
    pub dip: [f64; L],
    pub inv_vs: [f64; L],
    pub p_cut: [f64; L],
    pub sigma: [f64; L],
    pub coef: [[f64; L]; 16],
    pub k: [[f64; L]; NP],
    pub a: [[f64; L]; NP],
}

impl<const L: usize, const NP: usize> LaneParams<L, NP> {
    pub fn new(pids: &[PidP], gms: &[GmsP]) -> Self {
        assert!(pids.len() == L && gms.len() == L);
        let lane = |f: &dyn Fn(usize) -> f64| -> [f64; L] { std::array::from_fn(f) };
        let mut coef = [[0.0; L]; 16];
        for (j, row) in coef.iter_mut().enumerate() {
            *row = lane(&|l| gms[l].poly_e.coef[j]);
        }
        let mut k = [[0.0; L]; NP];
        let mut a = [[0.0; L]; NP];
        for i in 0..NP {
            k[i] = lane(&|l| gms[l].k.get(i).copied().unwrap_or(0.0));
            a[i] = lane(&|l| gms[l].alpha.get(i).copied().unwrap_or(0.0));
        }
        Self {
            kp: lane(&|l| pids[l].kp),
            ki: lane(&|l| pids[l].ki),
            ki_dt: lane(&|l| pids[l].ki_dt),
            d_keep: lane(&|l| pids[l].d_keep),
            d_gain: lane(&|l| pids[l].d_gain),
            u_min: lane(&|l| pids[l].u_min),
            u_max: lane(&|l| pids[l].u_max),
            fc: lane(&|l| gms[l].fc),
            dip: lane(&|l| gms[l].dip),
            inv_vs: lane(&|l| gms[l].inv_vs),
            p_cut: lane(&|l| gms[l].p_cut),
            sigma: lane(&|l| gms[l].sigma),
            coef,
            k,
            a,
        }
    }
}

/// Step-major outputs: run `l`'s sample `k` at `[k * L + l]` (one vector store per output and
/// step; `[l * n + k]` measured slower).
pub struct LaneOut<'a> {
    pub pos: &'a mut [f64],
    pub vel: &'a mut [f64],
    pub cmd: &'a mut [f64],
    pub fric: &'a mut [f64],
}

#[inline(always)]
fn hsum_lanes<const L: usize, const NP: usize>(f: &[[f64; L]; NP]) -> [f64; L] {
    let mut w = *f;
    let mut len = NP;
    while len > 4 {
        len /= 2;
        for i in 0..len {
            for l in 0..L {
                w[i][l] += w[i + len][l];
            }
        }
    }
    std::array::from_fn(|l| (w[0][l] + w[2][l]) + (w[1][l] + w[3][l]))
}

/// Advance `L` runs over the reference `r`. Returns `Err(step)` if any lane became non-finite.
#[inline(always)]
pub fn run_lanes<const L: usize, const NP: usize, const F: bool>(ax: &Axis, p: &LaneParams<L, NP>, r: &[f64], out: LaneOut<'_>) -> Result<(), usize> {
    let n = r.len();
    assert!(out.pos.len() >= L * n && out.vel.len() >= L * n && out.cmd.len() >= L * n && out.fric.len() >= L * n);
    let len = ring_len(ax.m);
    let mask = len - 1;
    let mut buf = vec![[0.0f64; L]; len];
    let mut xp = [r[0]; L];
    let mut xv = [0.0f64; L];
    let mut integral = [0.0f64; L];
    let mut deriv = [0.0f64; L];
    let mut prev_e = [0.0f64; L];
    let mut sum_f = [0.0f64; L];
    let mut f = [[0.0f64; L]; NP];
    let mut m = [[0.0f64; L]; NP];
    let inv_dt = ax.inv_dt;
    let sig_inv_dt: [f64; L] = std::array::from_fn(|l| p.sigma[l] * inv_dt);
    for kk in 0..n {
        let rk = r[kk];
        let mut u = [0.0f64; L];
        for l in 0..L {
            let e = rk - xp[l];
            let de = e - prev_e[l];
            prev_e[l] = e;
            deriv[l] = p.d_keep[l] * deriv[l] + p.d_gain[l] * de;
            let ti = integral[l] + p.ki_dt[l] * e;
            let uu = p.kp[l] * e + ti + deriv[l];
            // Bitwise `&`/`|` on bools and plain compares (no short circuits, no NaN-aware
            // max/min) keep the lane loops free of branches, so LLVM vectorises them.
            let winding = ((uu > p.u_max[l]) & (e * p.ki[l] > 0.0)) | ((uu < p.u_min[l]) & (e * p.ki[l] < 0.0));
            integral[l] = if winding { integral[l] } else { ti };
            let lo = if uu < p.u_min[l] { p.u_min[l] } else { uu };
            u[l] = if lo > p.u_max[l] { p.u_max[l] } else { lo };
        }
        buf[kk & mask] = u;
        let old = buf[kk.wrapping_sub(ax.m + 1) & mask];
        let new = buf[kk.wrapping_sub(ax.m) & mask];
        let mut free_p = [0.0; L];
        let mut free_v = [0.0; L];
        let mut trial = [0.0; L];
                for l in 0..L {
            free_p[l] = fma::<F>(ax.p00, xp[l], fma::<F>(ax.p01, xv[l], fma::<F>(ax.go0, old[l], ax.gn0 * new[l])));
            free_v[l] = fma::<F>(ax.p11, xv[l], fma::<F>(ax.p10, xp[l], fma::<F>(ax.go1, old[l], ax.gn1 * new[l])));
            trial[l] = fma::<F>(-ax.gf0, sum_f[l], free_p[l] - xp[l]);
        }
        let mut kfree = [0.0; L];
        for i in 0..NP {
            for l in 0..L {
                let dir_t = if trial[l] >= 0.0 { 1.0 } else { -1.0 };
                kfree[l] += if m[i][l] == dir_t { 0.0 } else { p.k[i][l] };
            }
        }
        let mut dx = [0.0; L];
        let mut v = [0.0; L];
        let mut dir = [0.0; L];
        let mut dir_s = [0.0; L];
        let mut decay = [0.0; L];
        for l in 0..L {
            let inv = 1.0 / (1.0 + ax.gf0 * (kfree[l] + sig_inv_dt[l]));
            dx[l] = trial[l] * inv;
            v[l] = dx[l] * inv_dt;
            dir[l] = if dx[l] > 0.0 { 1.0 } else { -1.0 };
            let pp = (v[l] * p.inv_vs[l]).abs();
            let e = exp_neg_poly::<F>(if pp < 700.0 { pp } else { 700.0 });
            let e = if pp > p.p_cut[l] { 0.0 } else { e };
            let s = fma::<F>(p.dip[l], e, p.fc[l]);
            dir_s[l] = dir[l] * s;
            let c = &p.coef;
            let e2 = e * e;
            let e4 = e2 * e2;
            let e8 = e4 * e4;
            let q = |i: usize| fma::<F>(c[i + 1][l], e, c[i][l]);
            let q0 = fma::<F>(q(2), e2, q(0));
            let q1 = fma::<F>(q(6), e2, q(4));
            let q2 = fma::<F>(q(10), e2, q(8));
            let q3 = fma::<F>(q(14), e2, q(12));
            decay[l] = fma::<F>(fma::<F>(q3, e4, q2), e8, fma::<F>(q1, e4, q0));
        }
        for i in 0..NP {
            for l in 0..L {
                let f_old = f[i][l];
                let target = p.a[i][l] * dir_s[l];
                let relaxed = fma::<F>(f_old - target, decay[l], target);
                let stuck = fma::<F>(p.k[i][l], dx[l], f_old);
                let along = m[i][l] == dir[l];
                let breaks = (stuck - target) * dir[l] >= 0.0;
                let beyond = (f_old - target) * dir[l] >= 0.0;
                let relax = along | (breaks & beyond);
                let nf = if relax { relaxed } else if breaks { target } else { stuck };
                let nm = if along | breaks { dir[l] } else { 0.0 };
                let zero = dx[l] == 0.0;
                let nm = if zero { 0.0 } else { nm };
                f[i][l] = if zero { f_old } else { nf };
                m[i][l] = nm;
            }
        }

        sum_f = hsum_lanes(&f);
        let mut bad = false;
        for l in 0..L {
            let force = if dx[l] == 0.0 { sum_f[l] } else { fma::<F>(p.sigma[l], v[l], sum_f[l]) };
            let o = kk * L + l;
            out.pos[o] = xp[l];
            out.vel[o] = xv[l];
            out.cmd[o] = u[l];
            out.fric[o] = force;
            xp[l] = fma::<F>(-ax.gf0, force, free_p[l]);
            xv[l] = fma::<F>(-ax.gf1, force, free_v[l]);
            bad |= !(xp[l] + xv[l] + force).is_finite();
        }
        if bad {
            return Err(kk);
        }
    }
    Ok(())
}

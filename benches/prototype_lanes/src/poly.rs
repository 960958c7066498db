//! The slip decay `exp(-c dt / s)`, `s = fc + (fs - fc) E`, as a polynomial of the Stribeck
//! exponential `E` in `[0, 1]`. Same Chebyshev fit as the core's `UnitIntervalPoly` (copied), but
//! the monomials are in `E` itself rather than `t = 2E - 1`: one fused multiply-add less on the
//! step's chain. Accepted only if it matches to `tol` relative on a dense grid (as the core).

use crate::fexp::fma;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecayPoly {
    /// Monomial coefficients in `E`, lowest first.
    pub coef: [f64; 16],
}

impl DecayPoly {
    pub fn fit(f: impl Fn(f64) -> f64, tol: f64) -> Option<Self> {
        const N: usize = 16;
        let angles: Vec<f64> = (0..N).map(|k| std::f64::consts::PI * (k as f64 + 0.5) / N as f64).collect();
        let values: Vec<f64> = angles.iter().map(|&a| f(0.5 * (a.cos() + 1.0))).collect();
        if values.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let mut cheb = [0.0f64; N];
        for (j, c) in cheb.iter_mut().enumerate() {
            let s: f64 = angles.iter().zip(&values).map(|(&a, &v)| v * (j as f64 * a).cos()).sum();
            *c = s * 2.0 / N as f64;
        }
        cheb[0] *= 0.5;
        let scale = cheb.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        for c in cheb.iter_mut() {
            if c.abs() < 1e-16 * scale {
                *c = 0.0;
            }
        }
        // Chebyshev -> monomials in t (as the core) ...
        let mut coef_t = [0.0f64; N];
        let (mut t_prev, mut t_cur) = ([0.0f64; N], [0.0f64; N]);
        t_prev[0] = 1.0;
        t_cur[1] = 1.0;
        for (i, c) in coef_t.iter_mut().enumerate() {
            *c += cheb[0] * t_prev[i] + cheb[1] * t_cur[i];
        }
        for cj in cheb.iter().skip(2) {
            let mut t_next = [0.0f64; N];
            for i in 0..N {
                t_next[i] = if i > 0 { 2.0 * t_cur[i - 1] } else { 0.0 } - t_prev[i];
            }
            for (c, &tn) in coef_t.iter_mut().zip(&t_next) {
                *c += cj * tn;
            }
            t_prev = t_cur;
            t_cur = t_next;
        }
        // ... -> monomials in E: t^j = (2E - 1)^j = sum_i C(j,i) 2^i E^i (-1)^(j-i).
        let mut coef = [0.0f64; N];
        for (j, &a) in coef_t.iter().enumerate() {
            let mut binom = 1.0f64;
            for i in 0..=j {
                let sign = if (j - i) % 2 == 0 { 1.0 } else { -1.0 };
                coef[i] += a * binom * 2f64.powi(i as i32) * sign;
                binom = binom * (j - i) as f64 / (i + 1) as f64;
            }
        }
        let poly = Self { coef };
        let worst = (0..=4000)
            .map(|i| {
                let u = i as f64 / 4000.0;
                let exact = f(u);
                ((poly.eval::<true>(u) - exact) / exact).abs()
            })
            .fold(0.0f64, f64::max);
        (worst <= tol).then_some(poly)
    }

    /// Estrin's scheme in `E`: four multiply-add levels after `E`.
    #[inline(always)]
    pub fn eval<const F: bool>(&self, e: f64) -> f64 {
        let c = &self.coef;
        let e2 = e * e;
        let e4 = e2 * e2;
        let e8 = e4 * e4;
        let p = |i: usize| fma::<F>(c[i + 1], e, c[i]);
        let q0 = fma::<F>(p(2), e2, p(0));
        let q1 = fma::<F>(p(6), e2, p(4));
        let q2 = fma::<F>(p(10), e2, p(8));
        let q3 = fma::<F>(p(14), e2, p(12));
        let r0 = fma::<F>(q1, e4, q0);
        let r1 = fma::<F>(q3, e4, q2);
        fma::<F>(r1, e8, r0)
    }
}

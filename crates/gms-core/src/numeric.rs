//! Numerical helpers for the closed loop's per-step dependency chain: a fused multiply-add where
//! the CPU has one, run-time CPU detection for the kernels compiled more than once, and a checked
//! polynomial that replaces a division and an exponential.

/// `a * b + c` as one fused instruction where the build targets a CPU with FMA (a local
/// `target-cpu=native` build), as two operations otherwise (`f64::mul_add` without hardware FMA
/// is a slow library call). The hot kernels use [`fma_if`] under run-time dispatch instead.
#[inline(always)]
pub fn fma(a: f64, b: f64, c: f64) -> f64 {
    fma_if::<{ cfg!(target_feature = "fma") }>(a, b, c)
}

/// `a * b + c`, fused when `F` (only inside functions compiled with the `fma` target feature:
/// elsewhere `mul_add` is a library call), two roundings otherwise.
#[inline(always)]
pub fn fma_if<const F: bool>(a: f64, b: f64, c: f64) -> f64 {
    if F {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// A CPU capability, detected on first use and remembered in `state` (0: unknown, 1: no, 2: yes).
#[cfg(target_arch = "x86_64")]
#[inline]
fn remembered(state: &std::sync::atomic::AtomicU8, detect: impl FnOnce() -> bool) -> bool {
    use std::sync::atomic::Ordering;
    match state.load(Ordering::Relaxed) {
        1 => false,
        2 => true,
        _ => {
            let yes = detect();
            state.store(if yes { 2 } else { 1 }, Ordering::Relaxed);
            yes
        }
    }
}

/// Whether this CPU runs the AVX2 + FMA instantiations of the hot kernels (checked once; the
/// portable build runs everywhere and takes the fast path where it exists).
/// `GMSFRIC_NO_AVX2` in the environment turns it off (and AVX-512 with it).
#[inline]
pub fn has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static STATE: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(0);
        remembered(&STATE, || std::env::var_os("GMSFRIC_NO_AVX2").is_none() && is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"))
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether this CPU runs the AVX-512 instantiation of the batch lanes (one 512-bit register holds
/// a whole group of [`crate::lanes::LANES`] runs; with AVX2 a group takes two). Checked once;
/// `GMSFRIC_NO_AVX512` in the environment turns it off (tests compare the paths).
#[inline]
pub fn has_avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static STATE: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(0);
        remembered(&STATE, || {
            std::env::var_os("GMSFRIC_NO_AVX512").is_none()
                && has_avx2_fma()
                && is_x86_feature_detected!("avx512f")
                && is_x86_feature_detected!("avx512vl")
                && is_x86_feature_detected!("avx512dq")
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// A smooth function on `[0, 1]` replaced by a polynomial of degree at most 15, built by
/// Chebyshev interpolation and accepted only if it matches the function to `tol` (relative) on a
/// dense check grid. Evaluated with Estrin's scheme: about five fused multiply-adds deep, instead
/// of a chain of division and exponential.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitIntervalPoly {
    /// Monomial coefficients in `t = 2 u - 1`, lowest first.
    coef: [f64; 16],
}

impl UnitIntervalPoly {
    /// Fit `f` on `[0, 1]`; `None` if no degree up to 15 reaches `tol` relative accuracy.
    pub fn fit(f: impl Fn(f64) -> f64, tol: f64) -> Option<Self> {
        const N: usize = 16;
        // Chebyshev points of the first kind and the interpolant's Chebyshev coefficients.
        let angles: Vec<f64> = (0..N).map(|k| std::f64::consts::PI * (k as f64 + 0.5) / N as f64).collect();
        let values: Vec<f64> = angles.iter().map(|&a| f(0.5 * (a.cos() + 1.0))).collect();
        if values.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let mut cheb = [0.0f64; N];
        for (j, c) in cheb.iter_mut().enumerate() {
            // T_j(cos a) = cos(j a), from the exact angle (not acos of the rounded node).
            let s: f64 = angles.iter().zip(&values).map(|(&a, &v)| v * (j as f64 * a).cos()).sum();
            *c = s * 2.0 / N as f64;
        }
        cheb[0] *= 0.5;
        // Coefficients at the rounding level of the samples carry no information but would
        // pollute the monomial form: drop them.
        let scale = cheb.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        for c in cheb.iter_mut() {
            if c.abs() < 1e-16 * scale {
                *c = 0.0;
            }
        }
        // Monomial form: T_0 = 1, T_1 = t, T_{j+1} = 2 t T_j - T_{j-1}.
        let mut coef = [0.0f64; N];
        let (mut t_prev, mut t_cur) = ([0.0f64; N], [0.0f64; N]);
        t_prev[0] = 1.0;
        t_cur[1] = 1.0;
        for (i, c) in coef.iter_mut().enumerate() {
            *c += cheb[0] * t_prev[i] + cheb[1] * t_cur[i];
        }
        for cj in cheb.iter().skip(2) {
            let mut t_next = [0.0f64; N];
            for i in 0..N {
                t_next[i] = if i > 0 { 2.0 * t_cur[i - 1] } else { 0.0 } - t_prev[i];
            }
            for (c, &tn) in coef.iter_mut().zip(&t_next) {
                *c += cj * tn;
            }
            t_prev = t_cur;
            t_cur = t_next;
        }
        let poly = Self { coef };
        let worst = (0..=4000)
            .map(|i| {
                let u = i as f64 / 4000.0;
                let exact = f(u);
                ((poly.eval(u) - exact) / exact).abs()
            })
            .fold(0.0f64, f64::max);
        (worst <= tol).then_some(poly)
    }

    /// Monomial coefficients in `t = 2 u - 1`, lowest degree first.
    pub fn coefficients(&self) -> &[f64; 16] {
        &self.coef
    }

    /// The polynomial at `u` (meant for `u` in `[0, 1]`).
    #[inline(always)]
    pub fn eval(&self, u: f64) -> f64 {
        let c = &self.coef;
        let t = fma(2.0, u, -1.0);
        let t2 = t * t;
        let t4 = t2 * t2;
        let t8 = t4 * t4;
        let p = |i: usize| fma(c[i + 1], t, c[i]);
        let q0 = fma(p(2), t2, p(0));
        let q1 = fma(p(6), t2, p(4));
        let q2 = fma(p(10), t2, p(8));
        let q3 = fma(p(14), t2, p(12));
        let r0 = fma(q1, t4, q0);
        let r1 = fma(q3, t4, q2);
        fma(r1, t8, r0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decay_of_the_paper_gms_as_a_polynomial_of_the_stribeck_exponential() {
        // exp(-c dt / s) with s = fc + (fs - fc) E, E in [0, 1] (paper Table 1, c = 1/Vs, dt = 1e-4).
        let (fc, fs, c, dt) = (0.1826, 0.210, 1.0 / 0.45e-3, 1e-4);
        let g = |e: f64| (-c * dt / (fc + (fs - fc) * e)).exp();
        let p = UnitIntervalPoly::fit(g, 4e-15).expect("smooth enough");
        let worst = (0..=100_000).map(|i| i as f64 / 100_000.0).map(|e| ((p.eval(e) - g(e)) / g(e)).abs()).fold(0.0, f64::max);
        assert!(worst < 4e-15, "worst relative error {worst}");
        // A function with a singularity next to the interval is refused.
        assert!(UnitIntervalPoly::fit(|e| 1.0 / (e + 1e-3), 4e-15).is_none());
    }
}

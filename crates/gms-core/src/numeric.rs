//! `a * b + c` as one fused instruction where the CPU has it (the build targets the host CPU, see
//! `.cargo/config.toml`), and as two operations otherwise: `f64::mul_add` without hardware FMA is
//! a slow library call. Used on the per-step dependency chain of the closed loop.

/// `a * b + c`, fused when the target has FMA.
#[inline(always)]
pub fn fma(a: f64, b: f64, c: f64) -> f64 {
    if cfg!(target_feature = "fma") {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// `exp(x)` for `x` in a known narrow interval `[lo, hi]` (half-width at most 1/8): `exp(mid)`
/// times a degree-11 Taylor polynomial of `exp(x - mid)` (truncation error < 3e-20; a few ulp after
/// rounding). Shorter latency than a general `exp`, which matters on the closed loop's
/// per-step dependency chain (the GMS slip decay `exp(-c dt / s(v))` with `s` between `fc` and `fs`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExpOnInterval {
    lo: f64,
    hi: f64,
    mid: f64,
    exp_mid: f64,
}

impl ExpOnInterval {
    /// Largest half-width accepted.
    pub const MAX_HALF_WIDTH: f64 = 0.125;

    /// `None` when the interval is too wide (or not finite): use `f64::exp` then.
    pub fn new(lo: f64, hi: f64) -> Option<Self> {
        let (lo, hi) = (lo.min(hi), lo.max(hi));
        let mid = 0.5 * (lo + hi);
        if !(lo.is_finite() && hi.is_finite()) || hi - mid > Self::MAX_HALF_WIDTH || !mid.exp().is_normal() {
            return None;
        }
        Some(Self { lo, hi, mid, exp_mid: mid.exp() })
    }

    /// Whether `x` lies in the interval.
    #[inline(always)]
    pub fn contains(&self, x: f64) -> bool {
        x >= self.lo && x <= self.hi
    }

    /// `exp(x)`; `x` must lie in the interval (see [`contains`](Self::contains)).
    #[inline(always)]
    pub fn eval(&self, x: f64) -> f64 {
        let y = x - self.mid;
        let y2 = y * y;
        let y4 = y2 * y2;
        let y8 = y4 * y4;
        // Estrin's scheme on 1 + y + y^2/2! + ... + y^11/11!.
        let p01 = 1.0 + y;
        let p23 = fma(y, 1.0 / 6.0, 0.5);
        let p45 = fma(y, 1.0 / 120.0, 1.0 / 24.0);
        let p67 = fma(y, 1.0 / 5040.0, 1.0 / 720.0);
        let p89 = fma(y, 1.0 / 362_880.0, 1.0 / 40_320.0);
        let p1011 = fma(y, 1.0 / 39_916_800.0, 1.0 / 3_628_800.0);
        let q0 = fma(y2, p23, p01);
        let q1 = fma(y2, p67, p45);
        let q2 = fma(y2, p1011, p89);
        let r = fma(y4, q1, q0);
        self.exp_mid * fma(y8, q2, r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interval_exp_matches_libm() {
        for (lo, hi) in [(-1.217, -1.058), (-0.25, 0.0), (-30.1, -29.9), (2.0, 2.2)] {
            let e = ExpOnInterval::new(lo, hi).expect("narrow interval");
            let mut worst: f64 = 0.0;
            for i in 0..=10_000 {
                let x = lo + (hi - lo) * i as f64 / 10_000.0;
                assert!(e.contains(x));
                worst = worst.max(((e.eval(x) - x.exp()) / x.exp()).abs());
            }
            assert!(worst < 8e-16, "[{lo}, {hi}]: worst relative error {worst}"); // a few ulp
        }
        assert!(ExpOnInterval::new(-1.0, 0.0).is_none());
        assert!(ExpOnInterval::new(f64::NEG_INFINITY, 0.0).is_none());
    }
}

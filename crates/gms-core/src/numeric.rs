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

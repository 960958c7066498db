//! Runtime CPU dispatch: each kernel is `#[inline(always)]` and generic over `F` (fused
//! multiply-add or not); it is instantiated once for the build's baseline target (`F = false`:
//! `a * b + c`, since `f64::mul_add` there is a call into libm's software-or-ifunc `fma`) and once
//! inside a `#[target_feature(enable = "avx2,fma")]` function (`F = true`: `vfmadd`, AVX2 lanes),
//! chosen at run time with `is_x86_feature_detected!`. In a `target-cpu=native` build the two
//! instantiations are the same code.
use crate::lanes::{run_lanes, LaneOut, LaneParams};
use crate::setup::{Axis, GmsP, PidP};
use crate::single::{run_v3, Out};

/// Which path the dispatcher takes on this CPU.
pub fn has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

macro_rules! multiversion {
    ($name:ident, $avx:ident, $base:ident, $base_mul_add:ident, ($($arg:ident : $ty:ty),*), $body_true:expr, $body_false:expr) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        unsafe fn $avx($($arg: $ty),*) -> Result<(), usize> {
            $body_true
        }
        /// Baseline target, separate multiply and add.
        pub fn $base($($arg: $ty),*) -> Result<(), usize> {
            $body_false
        }
        /// Baseline target with `f64::mul_add` (what the core's helper would do without its
        /// `cfg!(target_feature = "fma")` guard).
        pub fn $base_mul_add($($arg: $ty),*) -> Result<(), usize> {
            $body_true
        }
        /// Dispatched at run time.
        pub fn $name($($arg: $ty),*) -> Result<(), usize> {
            #[cfg(target_arch = "x86_64")]
            if has_avx2_fma() {
                // SAFETY: the CPU has AVX2 and FMA (checked just above).
                return unsafe { $avx($($arg),*) };
            }
            $base($($arg),*)
        }
    };
}

multiversion!(v3_n4, v3_n4_avx2, v3_n4_base, v3_n4_base_mul_add, (ax: &Axis, pid: &PidP, g: &GmsP, r: &[f64], out: Out<'_>),
    run_v3::<4, true, true>(ax, pid, g, r, out), run_v3::<4, false, true>(ax, pid, g, r, out));
multiversion!(lanes4_n4, lanes4_n4_avx2, lanes4_n4_base, lanes4_n4_base_mul_add, (ax: &Axis, p: &LaneParams<4, 4>, r: &[f64], out: LaneOut<'_>),
    run_lanes::<4, 4, true>(ax, p, r, out), run_lanes::<4, 4, false>(ax, p, r, out));
multiversion!(lanes8_n4, lanes8_n4_avx2, lanes8_n4_base, lanes8_n4_base_mul_add, (ax: &Axis, p: &LaneParams<8, 4>, r: &[f64], out: LaneOut<'_>),
    run_lanes::<8, 4, true>(ax, p, r, out), run_lanes::<8, 4, false>(ax, p, r, out));

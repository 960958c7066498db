//! Typed errors of the core. Every public constructor and simulation entry point validates its
//! input up front and returns one of these before doing any work, so callers (the Python binding)
//! can map them to clear exceptions instead of panics or NaN output.

use thiserror::Error;

/// Everything that can go wrong in `gms-core`.
///
/// Each variant names the offending argument (`name`) so the message can point the user at it.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CoreError {
    /// An input array has no elements.
    #[error("`{name}` is empty: at least {min} element(s) are needed")]
    Empty { name: &'static str, min: usize },

    /// Two arrays that must be sampled together have different lengths.
    #[error("`{name}` has length {got} but `{other}` has length {expected}: they must match")]
    LengthMismatch {
        name: &'static str,
        other: &'static str,
        expected: usize,
        got: usize,
    },

    /// A NaN or infinite value in an input array or parameter.
    #[error("`{name}` has a non-finite value ({}) at index {index}", Num(*.value))]
    NonFinite {
        name: &'static str,
        index: usize,
        value: f64,
    },

    /// A quantity that must be strictly positive (time step, stiffness, mass-like gain ...).
    #[error("`{name}` must be > 0, got {}", Num(*.value))]
    NotPositive { name: &'static str, value: f64 },

    /// A quantity that must not be negative (viscous coefficient, Coulomb level ...).
    #[error("`{name}` must be >= 0, got {}", Num(*.value))]
    Negative { name: &'static str, value: f64 },

    /// A time vector that does not strictly increase.
    #[error("`{name}` must be strictly increasing, but element {index} ({}) is not larger than the one before it", Num(*.value))]
    NotIncreasing {
        name: &'static str,
        index: usize,
        value: f64,
    },

    /// Any other inconsistent parameter (fractions not summing to one, unknown option ...).
    #[error("`{name}`: {reason}")]
    InvalidParameter { name: &'static str, reason: String },

    /// A simulated quantity left the finite range (an unstable loop, an overflowing gain ...).
    #[error("simulation produced a non-finite {quantity} at step {step}{}; {hint}", At(*.time))]
    NonFiniteOutput { quantity: &'static str, step: usize, time: f64, hint: &'static str },

    /// A computation would need more memory (or more work) than is reasonable for its input.
    #[error("`{name}` would need {}{}: {reason}", Amount(*.requested, what), Limit(*.limit, what))]
    TooLarge { name: &'static str, requested: f64, limit: f64, what: &'static str, reason: &'static str },

    /// The caller asked the computation to stop (Ctrl-C).
    #[error("interrupted")]
    Interrupted,
}

/// A number as a message shows it: plain in the everyday range, in scientific notation beyond it
/// (`5e-324`, not 324 decimal places; `1e100`, not 101 digits).
#[derive(Debug, Clone, Copy)]
pub struct Num(pub f64);

impl std::fmt::Display for Num {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let a = self.0.abs();
        if a == 0.0 || !a.is_finite() || (1e-4..1e15).contains(&a) {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

/// A quantity with its unit; bytes in binary multiples (`7.45 GiB`).
struct Amount<'a>(f64, &'a str);

impl std::fmt::Display for Amount<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.1 != "bytes" || !self.0.is_finite() || self.0 < 1024.0 {
            return write!(f, "{} {}", Num(self.0), self.1);
        }
        let mut v = self.0;
        for unit in ["KiB", "MiB", "GiB", "TiB", "PiB", "EiB"] {
            v /= 1024.0;
            if v < 1024.0 || unit == "EiB" {
                // Three significant digits, as the Python side writes sizes.
                let decimals = (2 - v.log10().floor() as i32).max(0) as usize;
                let text = format!("{v:.decimals$}");
                let text = if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.') } else { &text };
                return write!(f, "{text} {unit}");
            }
        }
        unreachable!("the loop returns at EiB")
    }
}

/// `, more than the limit of ...`, left out when there is no stated limit (NaN: the allocation
/// itself failed).
struct Limit<'a>(f64, &'a str);

impl std::fmt::Display for Limit<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.is_nan() {
            Ok(())
        } else {
            write!(f, ", more than the limit of {}", Amount(self.0, self.1))
        }
    }
}

/// The ` (t = ... s)` of a non-finite output, left out when the time is unknown (NaN).
struct At(f64);

impl std::fmt::Display for At {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.is_nan() {
            Ok(())
        } else {
            write!(f, " (t = {} s)", Num(self.0))
        }
    }
}

/// Result alias used throughout the core.
pub type Result<T> = std::result::Result<T, CoreError>;

/// Input checks shared by every entry point.
pub mod check {
    use super::{CoreError, Num, Result};

    /// Reject NaN / inf parameters.
    pub fn finite(name: &'static str, value: f64) -> Result<f64> {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(CoreError::InvalidParameter { name, reason: format!("must be finite, got {}", Num(value)) })
        }
    }

    /// Strictly positive, finite and not subnormal (a subnormal stiffness or step makes its
    /// reciprocal overflow).
    pub fn positive(name: &'static str, value: f64) -> Result<f64> {
        finite(name, value)?;
        if value > 0.0 && value.is_normal() {
            Ok(value)
        } else {
            Err(CoreError::NotPositive { name, value })
        }
    }

    /// A time step: positive, normal, with a finite reciprocal.
    pub fn step(name: &'static str, value: f64) -> Result<f64> {
        positive(name, value)?;
        if (1.0 / value).is_finite() {
            Ok(value)
        } else {
            Err(CoreError::InvalidParameter { name, reason: format!("{} s is too small a step (its reciprocal overflows)", Num(value)) })
        }
    }

    /// A whole number of samples from a duration, without wrapping or saturating: `Ok(None)`
    /// when the count is at least `cap` (the caller treats that as "longer than the run").
    pub fn samples(name: &'static str, seconds: f64, dt: f64, cap: usize) -> Result<Option<usize>> {
        let steps = seconds / dt;
        if !steps.is_finite() || steps < 0.0 {
            return Err(CoreError::InvalidParameter { name, reason: format!("{} s at a step of {} s is not a usable number of samples", Num(seconds), Num(dt)) });
        }
        if steps >= cap as f64 {
            return Ok(None);
        }
        Ok(Some(steps as usize))
    }

    /// Non-negative and finite.
    pub fn non_negative(name: &'static str, value: f64) -> Result<f64> {
        finite(name, value)?;
        if value >= 0.0 {
            Ok(value)
        } else {
            Err(CoreError::Negative { name, value })
        }
    }

    /// Non-empty array of finite values.
    pub fn finite_array(name: &'static str, values: &[f64], min_len: usize) -> Result<()> {
        if values.len() < min_len.max(1) {
            return Err(CoreError::Empty { name, min: min_len.max(1) });
        }
        // Whole chunks tested without a branch per value (the compiler vectorises the fold); the
        // index is looked for only when some value is not finite.
        if values.chunks(512).all(|c| c.iter().fold(true, |ok, v| ok & v.is_finite())) {
            return Ok(());
        }
        match values.iter().position(|v| !v.is_finite()) {
            Some(index) => Err(CoreError::NonFinite { name, index, value: values[index] }),
            None => Ok(()),
        }
    }

    /// Same length as a reference array.
    pub fn same_len(name: &'static str, values: &[f64], other: &'static str, expected: usize) -> Result<()> {
        if values.len() == expected {
            Ok(())
        } else {
            Err(CoreError::LengthMismatch { name, other, expected, got: values.len() })
        }
    }

    /// Finite and strictly increasing (time vectors), with finite steps (two finite times can
    /// be further apart than the largest double).
    pub fn increasing(name: &'static str, values: &[f64], min_len: usize) -> Result<()> {
        finite_array(name, values, min_len)?;
        for i in 1..values.len() {
            if values[i] <= values[i - 1] {
                return Err(CoreError::NotIncreasing { name, index: i, value: values[i] });
            }
            if !(values[i] - values[i - 1]).is_finite() {
                return Err(CoreError::InvalidParameter {
                    name,
                    reason: format!("the step from element {} ({}) to element {i} ({}) overflows", i - 1, Num(values[i - 1]), Num(values[i])),
                });
            }
        }
        Ok(())
    }
}

/// A zeroed vector of `n` doubles, allocated fallibly (calloc: pages appear as they are written),
/// so that an impossible size becomes [`CoreError::TooLarge`] instead of an abort.
pub fn try_zeroed(name: &'static str, n: usize) -> Result<Vec<f64>> {
    let too_large = || CoreError::TooLarge { name, requested: n as f64 * 8.0, limit: f64::NAN, what: "bytes", reason: "the allocation failed (not enough memory)" };
    if n == 0 {
        return Ok(Vec::new());
    }
    let layout = std::alloc::Layout::array::<f64>(n).map_err(|_| too_large())?;
    // SAFETY: the layout has a non-zero size; a null pointer is handled; on success the block
    // holds `n` zeroed (hence valid) f64 values and is owned by the returned vector, which frees
    // it with the same layout (the global allocator, capacity n).
    unsafe {
        let ptr = std::alloc::alloc_zeroed(layout) as *mut f64;
        if ptr.is_null() {
            return Err(too_large());
        }
        Ok(Vec::from_raw_parts(ptr, n, n))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_write_numbers_and_sizes_briefly() {
        let e = CoreError::NotPositive { name: "dt", value: 5e-324 };
        assert_eq!(e.to_string(), "`dt` must be > 0, got 5e-324");
        assert_eq!(Num(1e44).to_string(), "1e44");
        assert_eq!(Num(0.001).to_string(), "0.001");
        assert_eq!(Num(-2.5).to_string(), "-2.5");
        let big = CoreError::TooLarge { name: "outputs", requested: 3.2e10, limit: 2.0e10, what: "bytes", reason: "record fewer outputs" };
        assert_eq!(big.to_string(), "`outputs` would need 29.8 GiB, more than the limit of 18.6 GiB: record fewer outputs");
        let failed = try_zeroed("position", usize::MAX / 16).unwrap_err();
        assert!(failed.to_string().starts_with("`position` would need 8 EiB: the allocation failed"), "{failed}");
        let lag = CoreError::TooLarge { name: "delay", requested: 1e19, limit: 16777216.0, what: "samples", reason: "too long" };
        assert_eq!(lag.to_string(), "`delay` would need 1e19 samples, more than the limit of 16777216 samples: too long");
        let nan_time = CoreError::NonFiniteOutput { quantity: "force", step: 3, time: f64::NAN, hint: "h" };
        assert_eq!(nan_time.to_string(), "simulation produced a non-finite force at step 3; h");
    }
}

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
    #[error("`{name}` has a non-finite value ({value}) at index {index}")]
    NonFinite {
        name: &'static str,
        index: usize,
        value: f64,
    },

    /// A quantity that must be strictly positive (time step, stiffness, mass-like gain ...).
    #[error("`{name}` must be > 0, got {value}")]
    NotPositive { name: &'static str, value: f64 },

    /// A quantity that must not be negative (viscous coefficient, Coulomb level ...).
    #[error("`{name}` must be >= 0, got {value}")]
    Negative { name: &'static str, value: f64 },

    /// A time vector that does not strictly increase.
    #[error("`{name}` must be strictly increasing, but element {index} ({value}) is not larger than the one before it")]
    NotIncreasing {
        name: &'static str,
        index: usize,
        value: f64,
    },

    /// Any other inconsistent parameter (fractions not summing to one, unknown option ...).
    #[error("`{name}`: {reason}")]
    InvalidParameter { name: &'static str, reason: String },

    /// The simulation state left the finite range (an unstable loop, for instance).
    #[error("simulation diverged at t = {time} s (state became non-finite); the closed loop is probably unstable at these gains or this step size")]
    Diverged { time: f64 },
}

/// Result alias used throughout the core.
pub type Result<T> = std::result::Result<T, CoreError>;

/// Input checks shared by every entry point.
pub mod check {
    use super::{CoreError, Result};

    /// Reject NaN / inf parameters.
    pub fn finite(name: &'static str, value: f64) -> Result<f64> {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(CoreError::NonFinite { name, index: 0, value })
        }
    }

    /// Strictly positive and finite.
    pub fn positive(name: &'static str, value: f64) -> Result<f64> {
        finite(name, value)?;
        if value > 0.0 {
            Ok(value)
        } else {
            Err(CoreError::NotPositive { name, value })
        }
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

    /// Finite and strictly increasing (time vectors).
    pub fn increasing(name: &'static str, values: &[f64], min_len: usize) -> Result<()> {
        finite_array(name, values, min_len)?;
        for i in 1..values.len() {
            if values[i] <= values[i - 1] {
                return Err(CoreError::NotIncreasing { name, index: i, value: values[i] });
            }
        }
        Ok(())
    }
}

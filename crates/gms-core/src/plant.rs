//! Second-order plant `Y/U = a / (s^2 + b s + c)` with an input delay (paper eq. 1), discretised
//! exactly under a zero-order hold, including delays that are not a whole number of steps.

use crate::error::{check, CoreError, Num, Result};
use nalgebra::{Matrix2, Matrix3, Vector2};

/// Continuous-time plant. State: position `y` and velocity `dy/dt`.
///
/// The drive input `u` (V, A, N ... whatever the user's input unit is) acts through the delay;
/// a force `F` acting on the mechanics (friction, disturbance) enters undelayed as the equivalent
/// input `F / force_gain`, where `force_gain` is the drive's force per unit input (N per unit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plant {
    pub a: f64,
    pub b: f64,
    pub c: f64,
    /// Input delay (s).
    pub delay: f64,
    /// Force per unit input (N/unit): converts forces into input units.
    pub force_gain: f64,
}

impl Plant {
    pub fn new(a: f64, b: f64, c: f64, delay: f64, force_gain: f64) -> Result<Self> {
        check::positive("a", a)?;
        check::non_negative("b", b)?;
        check::non_negative("c", c)?;
        check::non_negative("delay", delay)?;
        check::positive("force_gain", force_gain)?;
        Ok(Self { a, b, c, delay, force_gain })
    }

    /// Rigid body `m y'' + d y' + k y = force_gain * u(t - delay)`.
    pub fn from_mass(mass: f64, damping: f64, stiffness: f64, delay: f64, force_gain: f64) -> Result<Self> {
        check::positive("mass", mass)?;
        check::non_negative("damping", damping)?;
        check::non_negative("stiffness", stiffness)?;
        check::positive("force_gain", force_gain)?;
        Self::new(force_gain / mass, damping / mass, stiffness / mass, delay, force_gain)
    }

    /// Equivalent moving mass `force_gain / a` (kg when forces are in N and positions in m).
    pub fn mass(&self) -> f64 {
        self.force_gain / self.a
    }

    fn a_matrix(&self) -> Matrix2<f64> {
        Matrix2::new(0.0, 1.0, -self.c, -self.b)
    }

    /// `(Phi(h), Gamma(h))`: `exp(A h)` and `int_0^h exp(A s) ds B` via one 3x3 matrix exponential.
    ///
    /// Refuses plants whose dynamics are so much faster than `h` that the exponential's scaling
    /// would overflow (it would square without end): `|A h|` must stay below [`MAX_STIFFNESS_RATIO`].
    pub fn zoh(&self, h: f64) -> Result<(Matrix2<f64>, Vector2<f64>)> {
        if h == 0.0 {
            return Ok((Matrix2::identity(), Vector2::zeros()));
        }
        let a = self.a_matrix();
        let mut m = Matrix3::zeros();
        m.fixed_view_mut::<2, 2>(0, 0).copy_from(&(a * h));
        m[(1, 2)] = self.a * h;
        let ratio = (a * h).abs().max().max(self.a * h);
        if !(ratio <= MAX_STIFFNESS_RATIO) {
            return Err(CoreError::InvalidParameter {
                name: "plant",
                reason: format!(
                    "a/(s^2 + b s + c) with a = {}, b = {}, c = {} is too fast for a step of {} s (|A dt| = {ratio:.3e} > {MAX_STIFFNESS_RATIO:.0e}): its discretisation is not meaningful",
                    Num(self.a),
                    Num(self.b),
                    Num(self.c),
                    Num(h)
                ),
            });
        }
        let e = m.exp();
        if e.iter().any(|x| !x.is_finite()) {
            return Err(CoreError::InvalidParameter { name: "plant", reason: format!("the discretisation at a step of {} s overflows", Num(h)) });
        }
        Ok((e.fixed_view::<2, 2>(0, 0).into_owned(), Vector2::new(e[(0, 2)], e[(1, 2)])))
    }

    /// Exact discretisation at step `dt`. A delay of more steps than any run can have
    /// ([`MAX_DELAY_STEPS`]) is kept as "never arrives" rather than converted to an integer that
    /// could wrap.
    pub fn discretize(&self, dt: f64) -> Result<DiscretePlant> {
        check::step("dt", dt)?;
        let (whole, frac) = match check::samples("delay", self.delay, dt, MAX_DELAY_STEPS)? {
            None => (MAX_DELAY_STEPS, 0.0),
            Some(_) => {
                // Whole steps of delay and the fractional remainder (guarded against round-off so
                // that a delay of exactly m steps gives frac = 0).
                let mut whole = (self.delay / dt).floor();
                let mut frac = (self.delay - whole * dt).max(0.0);
                if frac > dt * (1.0 - 1e-9) {
                    whole += 1.0;
                    frac = 0.0;
                }
                if frac < dt * 1e-9 {
                    frac = 0.0;
                }
                (whole as usize, frac)
            }
        };
        let (phi, gamma) = self.zoh(dt)?;
        let (phi_rest, gamma_rest) = self.zoh(dt - frac)?;
        let (_, gamma_frac) = self.zoh(frac)?;
        let d = DiscretePlant { phi, gamma_old: phi_rest * gamma_frac, gamma_new: gamma_rest, gamma_force: gamma / self.force_gain, delay_steps: whole, dt };
        // A tiny force gain turns a newton into an overflowing input.
        if !d.gamma_force.iter().all(|g| g.is_finite()) {
            return Err(CoreError::InvalidParameter {
                name: "force_gain",
                reason: format!("{} N per input unit is too small: a force of 1 N would be an input of {} units", Num(self.force_gain), Num(1.0 / self.force_gain)),
            });
        }
        if !d.gamma_old.iter().chain(d.gamma_new.iter()).all(|g| g.is_finite()) {
            return Err(CoreError::InvalidParameter { name: "plant", reason: format!("the discretisation at a step of {} s overflows", Num(dt)) });
        }
        Ok(d)
    }
}

/// Largest `|A dt|` the discretisation accepts (dynamics 1e8 times faster than the step).
pub const MAX_STIFFNESS_RATIO: f64 = 1e8;

/// Delays of at least this many steps never reach any run (2^52: still exact as a double).
pub const MAX_DELAY_STEPS: usize = 1 << 52;

/// The plant discretised at `dt`: `x+ = Phi x + g_old u[k-m-1] + g_new u[k-m] - g_force F`.
#[derive(Debug, Clone, Copy)]
pub struct DiscretePlant {
    pub phi: Matrix2<f64>,
    /// Response to the input sample that is still acting during the first `frac` of the step.
    pub gamma_old: Vector2<f64>,
    /// Response to the input sample that acts during the rest of the step.
    pub gamma_new: Vector2<f64>,
    /// Response to a force (N) held over the whole step, already divided by `force_gain`.
    pub gamma_force: Vector2<f64>,
    /// Whole steps of delay `m`.
    pub delay_steps: usize,
    pub dt: f64,
}

/// Ring buffer of past drive inputs realising the (fractional) delay.
#[derive(Debug, Clone)]
pub struct DelayLine {
    buf: Vec<f64>,
    head: usize,
}

impl DelayLine {
    /// Holds the current input and the `delay_steps + 1` before it; for a run of `n` samples a
    /// longer line behaves like one of `n` (nothing pushed comes out), so the length is capped.
    pub fn new(delay_steps: usize, initial: f64, n: usize) -> Self {
        Self { buf: vec![initial; delay_steps.min(n) + 2], head: 0 }
    }

    /// [`DelayLine::new`], allocated fallibly: memory that cannot be had is
    /// [`CoreError::TooLarge`], not an abort.
    pub fn try_new(delay_steps: usize, initial: f64, n: usize) -> Result<Self> {
        let mut buf = crate::error::try_zeroed("delay", delay_steps.min(n).saturating_add(2))?;
        if initial != 0.0 {
            buf.fill(initial);
        }
        Ok(Self { buf, head: 0 })
    }

    /// Push `u[k]`, return `(u[k-m-1], u[k-m])`.
    #[inline(always)]
    pub fn push(&mut self, u: f64) -> (f64, f64) {
        let n = self.buf.len();
        self.head = if self.head + 1 == n { 0 } else { self.head + 1 };
        self.buf[self.head] = u;
        // Oldest slot is the one after head; the next-oldest the one after that.
        let oldest = if self.head + 1 == n { 0 } else { self.head + 1 };
        let next = if oldest + 1 == n { 0 } else { oldest + 1 };
        (self.buf[oldest], self.buf[next])
    }
}

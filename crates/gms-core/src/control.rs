//! Discrete controllers. The closed-loop simulator is generic over [`Controller`], so a new
//! controller plugs in by implementing one method; feedforward terms enter as sample arrays.

use crate::error::{check, CoreError, Result};

/// A discrete controller running at the simulation step.
pub trait Controller {
    /// Controller output for sample `k` from the reference and the measured position.
    fn update(&mut self, reference: f64, measured: f64) -> f64;
    /// Back to the initial state.
    fn reset(&mut self);
}

/// Parallel PID `u = kp e + ki int(e) + kd de/dt` on the error `e = r - y`, with an optional
/// first-order derivative filter (time constant `tf`), output limits and anti-windup by
/// conditional integration (the integrator stops while the output is saturated in the direction
/// the error pushes it).
#[derive(Debug, Clone)]
pub struct Pid {
    pub kp: f64,
    pub ki: f64,
    pub kd: f64,
    pub tf: f64,
    pub u_min: f64,
    pub u_max: f64,
    pub dt: f64,
    integral: f64,
    deriv: f64,
    prev_error: Option<f64>,
}

impl Pid {
    pub fn new(kp: f64, ki: f64, kd: f64, tf: f64, u_min: f64, u_max: f64, dt: f64) -> Result<Self> {
        check::finite("kp", kp)?;
        check::finite("ki", ki)?;
        check::finite("kd", kd)?;
        check::non_negative("tf", tf)?;
        check::positive("dt", dt)?;
        if u_min.is_nan() || u_max.is_nan() || u_min >= u_max {
            return Err(CoreError::InvalidParameter {
                name: "u_min",
                reason: format!("output limits must satisfy u_min < u_max, got [{u_min}, {u_max}]"),
            });
        }
        Ok(Self { kp, ki, kd, tf, u_min, u_max, dt, integral: 0.0, deriv: 0.0, prev_error: None })
    }
}

impl Controller for Pid {
    #[inline]
    fn update(&mut self, reference: f64, measured: f64) -> f64 {
        let e = reference - measured;
        let prev = self.prev_error.unwrap_or(e); // no derivative kick on the first sample
        self.prev_error = Some(e);
        let de = e - prev;
        // Backward-Euler filtered derivative: d_k = (tf d_{k-1} + kd (e_k - e_{k-1})) / (tf + dt).
        self.deriv = (self.tf * self.deriv + self.kd * de) / (self.tf + self.dt);
        let trial_integral = self.integral + self.ki * e * self.dt;
        let u = self.kp * e + trial_integral + self.deriv;
        let clamped = u.clamp(self.u_min, self.u_max);
        let winding_up = (u > self.u_max && e * self.ki > 0.0) || (u < self.u_min && e * self.ki < 0.0);
        if !winding_up {
            self.integral = trial_integral;
        }
        clamped
    }
    fn reset(&mut self) {
        self.integral = 0.0;
        self.deriv = 0.0;
        self.prev_error = None;
    }
}

/// The EMPS benchmark's cascade: `u = kp kv (r - q) - kv qdot` with the 2-tap FIR velocity
/// `qf(k) = (q(k) + q(k-1)) / 2`, `qdot(k) = (qf(k) - qf(k-1)) / dt`, and output limits.
#[derive(Debug, Clone)]
pub struct Cascade {
    pub kp: f64,
    pub kv: f64,
    pub u_min: f64,
    pub u_max: f64,
    pub dt: f64,
    prev_q: Option<f64>,
    prev_qf: f64,
}

impl Cascade {
    pub fn new(kp: f64, kv: f64, u_min: f64, u_max: f64, dt: f64) -> Result<Self> {
        check::finite("kp", kp)?;
        check::finite("kv", kv)?;
        check::positive("dt", dt)?;
        if u_min.is_nan() || u_max.is_nan() || u_min >= u_max {
            return Err(CoreError::InvalidParameter {
                name: "u_min",
                reason: format!("output limits must satisfy u_min < u_max, got [{u_min}, {u_max}]"),
            });
        }
        Ok(Self { kp, kv, u_min, u_max, dt, prev_q: None, prev_qf: 0.0 })
    }
}

impl Controller for Cascade {
    #[inline]
    fn update(&mut self, reference: f64, measured: f64) -> f64 {
        let q_prev = self.prev_q.unwrap_or(measured);
        let qf = 0.5 * (measured + q_prev);
        let qf_prev = if self.prev_q.is_some() { self.prev_qf } else { qf };
        let qdot = (qf - qf_prev) / self.dt;
        self.prev_q = Some(measured);
        self.prev_qf = qf;
        (self.kp * self.kv * (reference - measured) - self.kv * qdot).clamp(self.u_min, self.u_max)
    }
    fn reset(&mut self) {
        self.prev_q = None;
        self.prev_qf = 0.0;
    }
}

/// Any controller of the core, dispatched once outside the loop.
#[derive(Debug, Clone)]
pub enum ControllerModel {
    Pid(Pid),
    Cascade(Cascade),
}

/// Run `$body` with `$c` bound to the concrete controller inside a [`ControllerModel`].
#[macro_export]
macro_rules! with_controller {
    ($model:expr, $c:ident => $body:expr) => {
        match $model {
            $crate::control::ControllerModel::Pid($c) => $body,
            $crate::control::ControllerModel::Cascade($c) => $body,
        }
    };
}

impl ControllerModel {
    pub fn reset(&mut self) {
        with_controller!(self, c => c.reset())
    }
    /// The sample time the controller was built for.
    pub fn dt(&self) -> f64 {
        with_controller!(self, c => c.dt)
    }
}

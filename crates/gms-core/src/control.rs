//! Discrete controllers. The closed-loop simulator is generic over [`Controller`], so a new
//! controller plugs in by implementing three methods; feedforward terms enter as sample arrays.
//!
//! Controllers are built from their gains alone and learn the sample time from the simulation
//! ([`Controller::prepare`]): the step is given once, to the run.

use crate::error::{check, CoreError, Num, Result};

/// A discrete controller running at the simulation step.
pub trait Controller {
    /// Set the sample time before a run (coefficients that depend on it are computed here, and
    /// checked: a filter above the Nyquist frequency, an observer history that cannot fit).
    fn prepare(&mut self, dt: f64) -> Result<()>;
    /// Called once before a run, after `prepare` and `reset`, with the initial position and
    /// velocity: a controller that differentiates the position starts with the right velocity.
    fn begin(&mut self, _position: f64, _velocity: f64) {}
    /// Controller output for sample `k` from the reference and the measured position.
    fn update(&mut self, reference: f64, measured: f64) -> f64;
    /// Back to the initial state.
    fn reset(&mut self);
}

fn check_limits(u_min: f64, u_max: f64) -> Result<()> {
    if u_min.is_nan() || u_max.is_nan() || u_min >= u_max {
        return Err(CoreError::InvalidParameter {
            name: "u_min",
            reason: format!("output limits must satisfy u_min < u_max, got [{}, {}]", Num(u_min), Num(u_max)),
        });
    }
    Ok(())
}

/// No controller: the drive input is the run's feedforward (the command) alone (open loop).
#[derive(Debug, Clone, Copy, Default)]
pub struct OpenLoop;

impl Controller for OpenLoop {
    fn prepare(&mut self, _dt: f64) -> Result<()> {
        Ok(())
    }
    #[inline(always)]
    fn update(&mut self, _reference: f64, _measured: f64) -> f64 {
        0.0
    }
    fn reset(&mut self) {}
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
    integral: f64,
    deriv: f64,
    prev_error: Option<f64>,
    /// Derivative filter coefficients `tf / (tf + dt)` and `kd / (tf + dt)`, and `ki dt`
    /// (set by `prepare`).
    d_keep: f64,
    d_gain: f64,
    ki_dt: f64,
}

impl Pid {
    pub fn new(kp: f64, ki: f64, kd: f64, tf: f64, u_min: f64, u_max: f64) -> Result<Self> {
        check::finite("kp", kp)?;
        check::finite("ki", ki)?;
        check::finite("kd", kd)?;
        check::non_negative("tf", tf)?;
        check_limits(u_min, u_max)?;
        Ok(Self { kp, ki, kd, tf, u_min, u_max, integral: 0.0, deriv: 0.0, prev_error: None, d_keep: 0.0, d_gain: 0.0, ki_dt: 0.0 })
    }
}

impl Controller for Pid {
    fn prepare(&mut self, dt: f64) -> Result<()> {
        check::step("dt", dt)?;
        let inv = 1.0 / (self.tf + dt);
        self.d_keep = self.tf * inv;
        self.d_gain = self.kd * inv;
        self.ki_dt = self.ki * dt;
        for (name, v) in [("kd", self.d_gain), ("ki", self.ki_dt)] {
            if !v.is_finite() {
                return Err(CoreError::InvalidParameter { name, reason: format!("the gain overflows at a step of {} s", Num(dt)) });
            }
        }
        Ok(())
    }
    #[inline]
    fn update(&mut self, reference: f64, measured: f64) -> f64 {
        let e = reference - measured;
        let prev = self.prev_error.unwrap_or(e); // no derivative kick on the first sample
        self.prev_error = Some(e);
        let de = e - prev;
        // Backward-Euler filtered derivative: d_k = (tf d_{k-1} + kd (e_k - e_{k-1})) / (tf + dt).
        self.deriv = self.d_keep * self.deriv + self.d_gain * de;
        let trial_integral = self.integral + self.ki_dt * e;
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
    inv_dt: f64,
    prev_q: Option<f64>,
    prev_qf: f64,
}

impl Cascade {
    pub fn new(kp: f64, kv: f64, u_min: f64, u_max: f64) -> Result<Self> {
        check::finite("kp", kp)?;
        check::finite("kv", kv)?;
        check_limits(u_min, u_max)?;
        Ok(Self { kp, kv, u_min, u_max, inv_dt: 0.0, prev_q: None, prev_qf: 0.0 })
    }
}

impl Controller for Cascade {
    fn prepare(&mut self, dt: f64) -> Result<()> {
        self.inv_dt = 1.0 / check::step("dt", dt)?;
        Ok(())
    }
    /// A run that starts moving: the FIR's memory is set so that the first velocity it reports
    /// is the initial velocity (as if the axis had been moving before the first sample).
    fn begin(&mut self, position: f64, velocity: f64) {
        if velocity != 0.0 {
            let dt = 1.0 / self.inv_dt;
            self.prev_q = Some(position - velocity * dt);
            self.prev_qf = position - 1.5 * velocity * dt;
        }
    }
    #[inline]
    fn update(&mut self, reference: f64, measured: f64) -> f64 {
        let q_prev = self.prev_q.unwrap_or(measured);
        let qf = 0.5 * (measured + q_prev);
        let qf_prev = if self.prev_q.is_some() { self.prev_qf } else { qf };
        let qdot = (qf - qf_prev) * self.inv_dt;
        self.prev_q = Some(measured);
        self.prev_qf = qf;
        (self.kp * self.kv * (reference - measured) - self.kv * qdot).clamp(self.u_min, self.u_max)
    }
    fn reset(&mut self) {
        self.prev_q = None;
        self.prev_qf = 0.0;
    }
}

/// Second-order section `(n0 + n1 z^-1 + n2 z^-2) / (1 + d1 z^-1 + d2 z^-2)`, transposed direct
/// form II, from a continuous `(p2 s^2 + p1 s + p0) / (q2 s^2 + q1 s + q0)` by Tustin.
#[derive(Debug, Clone)]
struct Biquad {
    n: [f64; 3],
    d: [f64; 2],
    s: [f64; 2],
}

impl Biquad {
    fn tustin(num: [f64; 3], den: [f64; 3], dt: f64) -> Self {
        let k = 2.0 / dt;
        let poly = |p: [f64; 3]| {
            let (p2, p1, p0) = (p[0] * k * k, p[1] * k, p[2]);
            [p2 + p1 + p0, 2.0 * (p0 - p2), p2 - p1 + p0]
        };
        let (nz, dz) = (poly(num), poly(den));
        let g = dz[0];
        Self { n: [nz[0] / g, nz[1] / g, nz[2] / g], d: [dz[1] / g, dz[2] / g], s: [0.0; 2] }
    }
    #[inline]
    fn step(&mut self, x: f64) -> f64 {
        let y = self.n[0] * x + self.s[0];
        self.s[0] = self.n[1] * x - self.d[0] * y + self.s[1];
        self.s[1] = self.n[2] * x - self.d[1] * y;
        y
    }
    /// Put the state at the steady state of a constant input `x`.
    fn settle(&mut self, x: f64) {
        let y = x * (self.n[0] + self.n[1] + self.n[2]) / (1.0 + self.d[0] + self.d[1]);
        self.s[1] = self.n[2] * x - self.d[1] * y;
        self.s[0] = self.n[1] * x - self.d[0] * y + self.s[1];
    }
}

/// [`Pid`] plus a disturbance observer (DOB) on the input side.
///
/// With the nominal plant `P_n(s) = a / (s^2 + b s + c)` (the measured position responds to the
/// drive input delayed by `delay`, minus the input-equivalent disturbance `d`, e.g. friction /
/// force_gain), the observer estimates
/// `d_hat = Q(s) [exp(-s delay) u - P_n(s)^-1 y]` with the low-pass `Q(s) = 1 / (tau s + 1)^2`,
/// `tau = 1 / (2 pi dob_cutoff_hz)` (so `Q P_n^-1` is proper), both filters discretised by
/// Tustin, and adds it to the PID output: `u = clamp(u_pid + d_hat)`. The observer's `u` is this
/// controller's own (limited) output, delayed by `round(delay / dt + 1/2)` samples (at least one:
/// the zero-order hold); a feedforward added outside the controller is seen as a disturbance. On
/// the first sample the filters start at the steady state of the measured position.
#[derive(Debug, Clone)]
pub struct PidDob {
    pub pid: Pid,
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub delay: f64,
    pub dob_cutoff_hz: f64,
    q_inv_plant: Biquad,
    q_input: Biquad,
    u_hist: Vec<f64>,
    head: usize,
    started: bool,
    /// Last disturbance estimate (input units).
    pub estimate: f64,
}

/// Longest input history the observer keeps (its delay in steps): 2^24 samples, 128 MiB.
pub const MAX_OBSERVER_LAG: usize = 1 << 24;

impl PidDob {
    /// `pid` supplies the gains and limits; `a, b, c, delay` the nominal plant.
    pub fn new(pid: Pid, a: f64, b: f64, c: f64, delay: f64, dob_cutoff_hz: f64) -> Result<Self> {
        check::positive("a", a)?;
        check::finite("b", b)?;
        check::finite("c", c)?;
        check::non_negative("delay", delay)?;
        check::positive("dob_cutoff_hz", dob_cutoff_hz)?;
        let none = Biquad { n: [0.0; 3], d: [0.0; 2], s: [0.0; 2] };
        Ok(Self { pid, a, b, c, delay, dob_cutoff_hz, q_inv_plant: none.clone(), q_input: none, u_hist: Vec::new(), head: 0, started: false, estimate: 0.0 })
    }
}

impl Controller for PidDob {
    fn prepare(&mut self, dt: f64) -> Result<()> {
        self.pid.prepare(dt)?;
        if self.dob_cutoff_hz * dt >= 0.5 {
            return Err(CoreError::InvalidParameter {
                name: "dob_cutoff_hz",
                reason: format!("the Q-filter cutoff must lie below the Nyquist frequency {} Hz, got {}", Num(0.5 / dt), Num(self.dob_cutoff_hz)),
            });
        }
        let lag = match check::samples("delay", self.delay, dt, MAX_OBSERVER_LAG)? {
            Some(_) => ((self.delay / dt + 0.5).round() as usize).clamp(1, MAX_OBSERVER_LAG),
            None => {
                return Err(CoreError::TooLarge {
                    name: "delay",
                    requested: self.delay / dt,
                    limit: MAX_OBSERVER_LAG as f64,
                    what: "samples of observer history",
                    reason: "the observer's nominal delay is too long for this step",
                })
            }
        };
        let tau = 1.0 / (2.0 * std::f64::consts::PI * self.dob_cutoff_hz);
        let den = [tau * tau, 2.0 * tau, 1.0];
        self.q_inv_plant = Biquad::tustin([1.0 / self.a, self.b / self.a, self.c / self.a], den, dt);
        self.q_input = Biquad::tustin([0.0, 0.0, 1.0], den, dt);
        let coefficients = self.q_inv_plant.n.iter().chain(&self.q_inv_plant.d).chain(&self.q_input.n).chain(&self.q_input.d);
        if !coefficients.into_iter().all(|x| x.is_finite()) {
            return Err(CoreError::InvalidParameter {
                name: "nominal",
                reason: format!(
                    "the observer's filters overflow for a / (s^2 + b s + c) with a = {}, b = {}, c = {}, a cutoff of {} Hz and a step of {} s",
                    Num(self.a),
                    Num(self.b),
                    Num(self.c),
                    Num(self.dob_cutoff_hz),
                    Num(dt)
                ),
            });
        }
        self.u_hist = crate::error::try_zeroed("delay", lag)?;
        self.head = 0;
        Ok(())
    }
    #[inline]
    fn update(&mut self, reference: f64, measured: f64) -> f64 {
        if !self.started {
            let u0 = self.c / self.a * measured;
            self.q_inv_plant.settle(measured);
            self.q_input.settle(u0);
            self.u_hist.iter_mut().for_each(|u| *u = u0);
            self.started = true;
        }
        let u_delayed = self.u_hist[self.head]; // oldest entry: u[k - lag]
        self.estimate = self.q_input.step(u_delayed) - self.q_inv_plant.step(measured);
        let u_pid = self.pid.update(reference, measured);
        let u = (u_pid + self.estimate).clamp(self.pid.u_min, self.pid.u_max);
        self.u_hist[self.head] = u;
        self.head = (self.head + 1) % self.u_hist.len();
        u
    }
    fn reset(&mut self) {
        self.pid.reset();
        self.q_inv_plant.s = [0.0; 2];
        self.q_input.s = [0.0; 2];
        self.u_hist.iter_mut().for_each(|u| *u = 0.0);
        self.head = 0;
        self.started = false;
        self.estimate = 0.0;
    }
}

/// Any controller of the core, dispatched once outside the loop.
#[derive(Debug, Clone)]
pub enum ControllerModel {
    Pid(Pid),
    Cascade(Cascade),
    PidDob(PidDob),
}

/// Run `$body` with `$c` bound to the concrete controller inside a [`ControllerModel`].
#[macro_export]
macro_rules! with_controller {
    ($model:expr, $c:ident => $body:expr) => {
        match $model {
            $crate::control::ControllerModel::Pid($c) => $body,
            $crate::control::ControllerModel::Cascade($c) => $body,
            $crate::control::ControllerModel::PidDob($c) => $body,
        }
    };
}

impl ControllerModel {
    pub fn reset(&mut self) {
        with_controller!(self, c => c.reset())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::closed_loop::{simulate, ClosedLoopInput};
    use crate::reference;

    fn dob(pid: Pid, cutoff: f64) -> PidDob {
        let p = reference::paper_plant();
        PidDob::new(pid, p.a, p.b, p.c, p.delay, cutoff).unwrap()
    }

    #[test]
    fn dob_is_transparent_without_disturbance_and_rejects_a_load_step() {
        let dt = 1e-4;
        let n = 20_000;
        let plant = reference::paper_plant();
        let r: Vec<f64> = (0..n).map(|k| 1e-3 * (1.0 - (-(k as f64) * dt / 0.05).exp())).collect();
        let load: Vec<f64> = (0..n).map(|k| if k >= n / 2 { 0.5 } else { 0.0 }).collect();
        let pid = Pid::new(5e4, 0.0, 100.0, 5e-4, f64::NEG_INFINITY, f64::INFINITY).unwrap();
        let run = |ctrl: ControllerModel, load: Option<&[f64]>| {
            let mut input = ClosedLoopInput::new(&r, dt);
            input.load_force = load;
            simulate(&plant, None, None, Some(&ctrl), &input).unwrap()
        };
        // Nominal plant = true plant, no disturbance: the observer estimate stays ~0 (Tustin vs
        // exact ZOH and the half-sample delay rounding leave ~1e-4 of the 1 mm move).
        let a = run(ControllerModel::Pid(pid.clone()), None);
        let b = run(ControllerModel::PidDob(dob(pid.clone(), 20.0)), None);
        let dev = a.position.iter().zip(&b.position).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
        assert!(dev < 1e-6, "DOB changed the disturbance-free response by {dev}");
        // A load step: a P-D loop keeps a load-induced error load / (force_gain (kp + c / a)) (on
        // top of its type-0 tracking error); the DOB removes it.
        let load_effect = |ctrl: ControllerModel| {
            let with = run(ctrl.clone(), Some(&load));
            let without = run(ctrl, None);
            (with.position[n - 1] - without.position[n - 1]).abs()
        };
        let e_pid = load_effect(ControllerModel::Pid(pid.clone()));
        let e_dob = load_effect(ControllerModel::PidDob(dob(pid, 20.0)));
        let expected = 0.5 / (5e4 + plant.c / plant.a);
        assert!((e_pid - expected).abs() < 0.02 * expected, "P-D load error {e_pid} vs {expected}");
        assert!(e_dob < 0.01 * e_pid, "DOB load error {e_dob} vs {e_pid}");
    }

    #[test]
    fn dob_checks_its_parameters() {
        let pid = Pid::new(1.0, 0.0, 0.0, 0.0, -1.0, 1.0).unwrap();
        assert!(PidDob::new(pid.clone(), 0.0, 1.0, 1.0, 0.0, 10.0).is_err());
        assert!(PidDob::new(pid.clone(), 1.0, 1.0, 1.0, 0.0, 600.0).unwrap().prepare(1e-3).is_err(), "cutoff above Nyquist");
        assert!(PidDob::new(pid.clone(), 1.0, 1.0, 1.0, -1.0, 10.0).is_err());
        // A nominal delay of 1e10 s at 1 ns steps: refused, not a capacity-overflow panic.
        let err = PidDob::new(pid, 1.0, 1.0, 0.0, 1e10, 20.0).unwrap().prepare(1e-9).unwrap_err();
        assert!(matches!(err, CoreError::TooLarge { name: "delay", .. }), "{err}");
    }
}

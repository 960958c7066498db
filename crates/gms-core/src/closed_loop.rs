//! Closed-loop axis simulation (the paper's Fig. 9): reference -> controller (+ feedforward)
//! -> drive limit -> input delay -> plant, with friction acting on the mechanics.
//!
//! Time base: `t[k] = k dt`. At `t[k]` the controller reads the (quantised, noisy) position and
//! its output is held over `[t[k], t[k+1])`; the delayed input, the friction force and the load
//! force are integrated exactly over that interval (zero-order hold, fractional delay).

use crate::control::{Controller, ControllerModel};
use crate::error::{check, CoreError, Result};
use crate::friction::{Coupling, FrictionElement, FrictionModel};
use crate::plant::{DelayLine, Plant};
use crate::{with_controller, with_friction};
use nalgebra::Vector2;

/// No friction at all (the reference case of the paper's Fig. 14).
#[derive(Debug, Clone, Copy, Default)]
pub struct NoFriction;

impl FrictionElement for NoFriction {
    #[inline(always)]
    fn force(&self) -> f64 {
        0.0
    }
    #[inline(always)]
    fn advance(&mut self, _dx: f64, _dt: f64) -> f64 {
        0.0
    }
    #[inline(always)]
    fn tangent_stiffness(&self, _direction: f64, _dt: f64) -> f64 {
        0.0
    }
    fn reset(&mut self) {}
    #[inline(always)]
    fn advance_coupled(&mut self, _c: &Coupling, _dt: f64) -> f64 {
        0.0
    }
}

/// Inputs of one closed-loop run besides plant, friction and controller. Arrays are borrowed so
/// callers (numpy) need not copy them.
#[derive(Debug, Clone, Copy)]
pub struct ClosedLoopInput<'a> {
    /// Reference position per sample (m).
    pub reference: &'a [f64],
    /// Step (s); the controller runs at this rate.
    pub dt: f64,
    /// Added to the controller output before the drive limit (input units).
    pub feedforward: Option<&'a [f64]>,
    /// External input disturbance added before the drive limit (input units), e.g. EMPS pulses.
    pub input_disturbance: Option<&'a [f64]>,
    /// External force on the mechanics (N), e.g. a load or cutting force; opposes like friction.
    pub load_force: Option<&'a [f64]>,
    /// Additive measurement noise on the position (m).
    pub measurement_noise: Option<&'a [f64]>,
    /// Encoder resolution (m); 0 disables quantisation.
    pub quantization: f64,
    /// Drive input limits (input units).
    pub drive_min: f64,
    pub drive_max: f64,
    pub initial_position: f64,
    pub initial_velocity: f64,
}

impl<'a> ClosedLoopInput<'a> {
    /// Defaults: no feedforward, disturbance, load or noise; no quantisation; unlimited drive;
    /// start at rest at the first reference sample.
    pub fn new(reference: &'a [f64], dt: f64) -> Self {
        Self {
            reference,
            dt,
            feedforward: None,
            input_disturbance: None,
            load_force: None,
            measurement_noise: None,
            quantization: 0.0,
            drive_min: f64::NEG_INFINITY,
            drive_max: f64::INFINITY,
            initial_position: reference.first().copied().unwrap_or(0.0),
            initial_velocity: 0.0,
        }
    }

    fn validate(&self) -> Result<()> {
        check::positive("dt", self.dt)?;
        check::finite_array("reference", self.reference, 1)?;
        let n = self.reference.len();
        for (name, arr) in [
            ("feedforward", self.feedforward),
            ("input_disturbance", self.input_disturbance),
            ("load_force", self.load_force),
            ("measurement_noise", self.measurement_noise),
        ] {
            if let Some(a) = arr {
                check::same_len(name, a, "reference", n)?;
                check::finite_array(name, a, 1)?;
            }
        }
        check::non_negative("quantization", self.quantization)?;
        if self.drive_min.is_nan() || self.drive_max.is_nan() || self.drive_min >= self.drive_max {
            return Err(CoreError::InvalidParameter {
                name: "drive_limit",
                reason: format!("need drive_min < drive_max, got [{}, {}]", self.drive_min, self.drive_max),
            });
        }
        check::finite("initial_position", self.initial_position)?;
        check::finite("initial_velocity", self.initial_velocity)?;
        Ok(())
    }
}

/// Sampled result of a closed-loop run, all arrays of the reference's length.
#[derive(Debug, Clone, Default)]
pub struct ClosedLoopOutput {
    /// True position at `t[k]` (m).
    pub position: Vec<f64>,
    /// True velocity at `t[k]` (m/s).
    pub velocity: Vec<f64>,
    /// Position the controller saw (quantised, noisy) (m).
    pub measured: Vec<f64>,
    /// Drive input applied over `[t[k], t[k+1])`, after the limit (input units).
    pub command: Vec<f64>,
    /// Friction force over `[t[k], t[k+1])` (N).
    pub friction: Vec<f64>,
}

/// Simulate with concrete (monomorphised) friction and controller types.
pub fn simulate_generic<F: FrictionElement, C: Controller>(
    plant: &Plant,
    friction: &mut F,
    controller: &mut C,
    input: &ClosedLoopInput<'_>,
) -> Result<ClosedLoopOutput> {
    input.validate()?;
    let d = plant.discretize(input.dt)?;
    let n = input.reference.len();
    let mut out = ClosedLoopOutput {
        position: Vec::with_capacity(n),
        velocity: Vec::with_capacity(n),
        measured: Vec::with_capacity(n),
        command: Vec::with_capacity(n),
        friction: Vec::with_capacity(n),
    };
    let mut line = DelayLine::new(d.delay_steps, 0.0);
    let mut x = Vector2::new(input.initial_position, input.initial_velocity);
    let q = input.quantization;
    let at = |a: Option<&[f64]>, k: usize| a.map_or(0.0, |a| a[k]);
    for k in 0..n {
        let mut y = x[0] + at(input.measurement_noise, k);
        if q > 0.0 {
            y = (y / q).round() * q;
        }
        let u_ctrl = controller.update(input.reference[k], y);
        let u = (u_ctrl + at(input.feedforward, k) + at(input.input_disturbance, k)).clamp(input.drive_min, input.drive_max);
        let (old, new) = line.push(u);
        let free = d.phi * x + d.gamma_old * old + d.gamma_new * new - d.gamma_force * at(input.load_force, k);
        let coupling = Coupling {
            free_dx: free[0] - x[0],
            dx_per_newton: d.gamma_force[0],
            free_v: free[1],
            v_per_newton: d.gamma_force[1],
        };
        let f = friction.advance_coupled(&coupling, input.dt);
        out.position.push(x[0]);
        out.velocity.push(x[1]);
        out.measured.push(y);
        out.command.push(u);
        out.friction.push(f);
        x = free - d.gamma_force * f;
        if !(x[0].is_finite() && x[1].is_finite() && f.is_finite()) {
            return Err(CoreError::Diverged { time: (k + 1) as f64 * input.dt });
        }
    }
    Ok(out)
}

/// Simulate with models chosen at run time; dispatches once, then runs the monomorphised loop.
/// `friction = None` simulates the frictionless axis. Friction and controller start from their
/// initial state (they are reset first).
pub fn simulate(
    plant: &Plant,
    friction: Option<&mut FrictionModel>,
    controller: &mut ControllerModel,
    input: &ClosedLoopInput<'_>,
) -> Result<ClosedLoopOutput> {
    controller.reset();
    match friction {
        None => with_controller!(controller, c => simulate_generic(plant, &mut NoFriction, c, input)),
        Some(model) => {
            model.reset();
            with_friction!(model, f => with_controller!(&mut *controller, c => simulate_generic(plant, f, c, input)))
        }
    }
}

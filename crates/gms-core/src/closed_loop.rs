//! Closed-loop axis simulation (the paper's Fig. 9): reference -> controller (+ feedforward)
//! -> drive limit -> input delay -> plant, with friction acting on the mechanics.
//!
//! Time base: `t[k] = k dt`. At `t[k]` the controller reads the (quantised, noisy) position and
//! its output is held over `[t[k], t[k+1])`; the delayed input, the friction force and the load
//! force are integrated exactly over that interval (zero-order hold, fractional delay).

use crate::control::{Controller, ControllerModel};
use crate::error::{check, CoreError, Result};
use crate::friction::{Coupling, FrictionElement, FrictionModel};
use crate::numeric::fma;
use crate::plant::{DelayLine, Plant};
use crate::{with_controller, with_friction};

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

/// Mutable views of a run's output arrays (each as long as the reference), so callers can hand
/// in memory they own (numpy arrays from the binding) instead of receiving new vectors.
#[derive(Debug)]
pub struct ClosedLoopBuffers<'a> {
    pub position: &'a mut [f64],
    pub velocity: &'a mut [f64],
    /// `None` skips recording the measured position (when it equals the true one).
    pub measured: Option<&'a mut [f64]>,
    pub command: &'a mut [f64],
    pub friction: &'a mut [f64],
}

impl ClosedLoopOutput {
    /// Zeroed output vectors for `n` samples.
    pub fn zeros(n: usize) -> Self {
        Self { position: vec![0.0; n], velocity: vec![0.0; n], measured: vec![0.0; n], command: vec![0.0; n], friction: vec![0.0; n] }
    }

    /// Mutable views of every array.
    pub fn buffers(&mut self) -> ClosedLoopBuffers<'_> {
        ClosedLoopBuffers {
            position: &mut self.position,
            velocity: &mut self.velocity,
            measured: Some(&mut self.measured),
            command: &mut self.command,
            friction: &mut self.friction,
        }
    }
}

/// Simulate with concrete (monomorphised) friction and controller types.
pub fn simulate_generic<F: FrictionElement, C: Controller>(
    plant: &Plant,
    friction: &mut F,
    controller: &mut C,
    input: &ClosedLoopInput<'_>,
) -> Result<ClosedLoopOutput> {
    let mut out = ClosedLoopOutput::zeros(input.reference.len());
    simulate_generic_into(plant, friction, controller, input, out.buffers())?;
    Ok(out)
}

/// [`simulate_generic`] writing into caller-owned buffers.
pub fn simulate_generic_into<F: FrictionElement, C: Controller>(
    plant: &Plant,
    friction: &mut F,
    controller: &mut C,
    input: &ClosedLoopInput<'_>,
    out: ClosedLoopBuffers<'_>,
) -> Result<()> {
    input.validate()?;
    let d = plant.discretize(input.dt)?;
    let n = input.reference.len();
    for (name, buf) in [("position", &out.position), ("velocity", &out.velocity), ("command", &out.command), ("friction", &out.friction)] {
        check::same_len(name, buf, "reference", n)?;
    }
    if let Some(m) = &out.measured {
        check::same_len("measured", m, "reference", n)?;
    }
    // Re-slice to exactly n so the indexing below needs no bounds checks.
    let (pos, vel, cmd, fric) = (&mut out.position[..n], &mut out.velocity[..n], &mut out.command[..n], &mut out.friction[..n]);
    let mut meas = out.measured.map(|m| &mut m[..n]);
    let reference = &input.reference[..n];
    let mut line = DelayLine::new(d.delay_steps, 0.0);
    // Scalars instead of 2x2 matrix types: the loop body is a handful of FMAs.
    let (p00, p01, p10, p11) = (d.phi[(0, 0)], d.phi[(0, 1)], d.phi[(1, 0)], d.phi[(1, 1)]);
    let (go0, go1, gn0, gn1) = (d.gamma_old[0], d.gamma_old[1], d.gamma_new[0], d.gamma_new[1]);
    let (gf0, gf1) = (d.gamma_force[0], d.gamma_force[1]);
    let (mut xp, mut xv) = (input.initial_position, input.initial_velocity);
    let (q, inv_q) = (input.quantization, if input.quantization > 0.0 { 1.0 / input.quantization } else { 0.0 });
    let (lo, hi, dt) = (input.drive_min, input.drive_max, input.dt);
    for k in 0..n {
        let mut y = xp;
        if let Some(noise) = input.measurement_noise {
            y += noise[k];
        }
        if q > 0.0 {
            y = (y * inv_q).round() * q;
        }
        let mut u = controller.update(reference[k], y);
        if let Some(ff) = input.feedforward {
            u += ff[k];
        }
        if let Some(dist) = input.input_disturbance {
            u += dist[k];
        }
        let u = u.clamp(lo, hi);
        let (old, new) = line.push(u);
        // The state-dependent terms last: they are the ones waiting for the previous step.
        let mut free_p = fma(p00, xp, fma(p01, xv, fma(go0, old, gn0 * new)));
        let mut free_v = fma(p11, xv, fma(p10, xp, fma(go1, old, gn1 * new)));
        if let Some(load) = input.load_force {
            free_p -= gf0 * load[k];
            free_v -= gf1 * load[k];
        }
        let coupling = Coupling { free_dx: free_p - xp, dx_per_newton: gf0, free_v, v_per_newton: gf1 };
        let f = friction.advance_coupled(&coupling, dt);
        pos[k] = xp;
        vel[k] = xv;
        if let Some(m) = meas.as_deref_mut() {
            m[k] = y;
        }
        cmd[k] = u;
        fric[k] = f;
        xp = fma(-gf0, f, free_p);
        xv = fma(-gf1, f, free_v);
        // A NaN or inf anywhere makes the sum non-finite: one test per step.
        if !(xp + xv + f).is_finite() {
            return Err(CoreError::Diverged { time: (k + 1) as f64 * dt });
        }
    }
    Ok(())
}

/// [`simulate`] writing into caller-owned buffers.
pub fn simulate_into(
    plant: &Plant,
    friction: Option<&mut FrictionModel>,
    controller: &mut ControllerModel,
    input: &ClosedLoopInput<'_>,
    out: ClosedLoopBuffers<'_>,
) -> Result<()> {
    controller.reset();
    match friction {
        None => with_controller!(controller, c => simulate_generic_into(plant, &mut NoFriction, c, input, out)),
        Some(model) => {
            model.reset();
            with_friction!(model, f => with_controller!(&mut *controller, c => simulate_generic_into(plant, f, c, input, out)))
        }
    }
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

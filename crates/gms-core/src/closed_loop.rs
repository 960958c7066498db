//! Closed-loop (and open-loop) axis simulation (the paper's Fig. 9): reference -> controller
//! (+ feedforward) -> drive limit -> input delay -> plant, with friction acting on the mechanics.
//!
//! Time base: `t[k] = k dt`. At `t[k]` the controller reads the (quantised, noisy) position and
//! its output is held over `[t[k], t[k+1])`; the delayed input, the friction force and the load
//! force are integrated exactly over that interval (zero-order hold, fractional delay). Without a
//! controller ([`OpenLoop`]) the drive input is the feedforward (the command) alone.

use crate::control::{Controller, ControllerModel, OpenLoop};
use crate::error::{check, CoreError, Result};
use crate::friction::{Coupling, FrictionElement, FrictionModel};
use crate::numeric::fma;
use crate::plant::{DelayLine, Plant};
use crate::{with_controller, with_friction};
use std::sync::atomic::{AtomicBool, Ordering};

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

/// Steps between two looks at the cancel flag: rare enough to cost nothing (one relaxed load per
/// 4096 steps), frequent enough for Ctrl-C to stop within a second even when a step is slow
/// (0.3 s for a model with thousands of blocks, well under a millisecond for the usual ones).
pub(crate) const CANCEL_CHECK_STEPS: usize = 1 << 12;

/// Inputs of one run besides plant, friction and controller. Arrays are borrowed so callers
/// (numpy) need not copy them. This is the one description of a run's inputs: single runs,
/// batches and the Python binding all fill it.
#[derive(Debug, Clone, Copy)]
pub struct ClosedLoopInput<'a> {
    /// Reference position per sample (m); required with a controller, optional without.
    pub reference: Option<&'a [f64]>,
    /// Step (s); the controller runs at this rate.
    pub dt: f64,
    /// Added to the controller output before the drive limit (input units); without a
    /// controller, the drive command itself.
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
    /// When set (by another thread: Ctrl-C, a cancelled batch), the run stops with
    /// [`CoreError::Interrupted`] within [`CANCEL_CHECK_STEPS`] steps.
    pub cancel: Option<&'a AtomicBool>,
}

impl<'a> ClosedLoopInput<'a> {
    /// A closed-loop run following `reference`. Defaults: no feedforward, disturbance, load or
    /// noise; no quantisation; unlimited drive; start at rest at the first reference sample.
    pub fn new(reference: &'a [f64], dt: f64) -> Self {
        Self { reference: Some(reference), feedforward: None, initial_position: reference.first().copied().unwrap_or(0.0), ..Self::open(&[], dt) }
    }

    /// An open-loop run driven by `command` (input units), starting at rest at 0.
    pub fn open(command: &'a [f64], dt: f64) -> Self {
        Self {
            reference: None,
            dt,
            feedforward: Some(command),
            input_disturbance: None,
            load_force: None,
            measurement_noise: None,
            quantization: 0.0,
            drive_min: f64::NEG_INFINITY,
            drive_max: f64::INFINITY,
            initial_position: 0.0,
            initial_velocity: 0.0,
            cancel: None,
        }
    }

    /// Number of samples of the run.
    pub fn len(&self) -> usize {
        self.reference.or(self.feedforward).map_or(0, <[f64]>::len)
    }

    /// Whether the run has no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Check every input; `closed` says whether a controller will read the reference.
    pub fn validate(&self, closed: bool) -> Result<()> {
        check::step("dt", self.dt)?;
        if closed && self.reference.is_none() {
            return Err(CoreError::InvalidParameter { name: "reference", reason: "a closed-loop run needs a reference".into() });
        }
        let n = self.len();
        if n == 0 {
            return Err(CoreError::Empty { name: if self.reference.is_some() { "reference" } else { "feedforward" }, min: 1 });
        }
        if !(n as f64 * self.dt).is_finite() {
            return Err(CoreError::InvalidParameter { name: "dt", reason: "the run's duration overflows".into() });
        }
        if let Some(r) = self.reference {
            check::finite_array("reference", r, 1)?;
        }
        let reference_name = if self.reference.is_some() { "reference" } else { "feedforward" };
        for (name, arr) in [
            ("feedforward", self.feedforward),
            ("input_disturbance", self.input_disturbance),
            ("load_force", self.load_force),
            ("measurement_noise", self.measurement_noise),
        ] {
            if let Some(a) = arr {
                check::same_len(name, a, reference_name, n)?;
                check::finite_array(name, a, 1)?;
            }
        }
        check::non_negative("quantization", self.quantization)?;
        if self.quantization > 0.0 && !(1.0 / self.quantization).is_finite() {
            return Err(CoreError::InvalidParameter { name: "quantization", reason: format!("{} m is too fine a resolution (its reciprocal overflows)", crate::error::Num(self.quantization)) });
        }
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

/// Which outputs a run records, and how often. A run that needs one array does not write five.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Record {
    pub position: bool,
    pub velocity: bool,
    pub measured: bool,
    pub command: bool,
    pub friction: bool,
    /// Tracking error `reference - position` (m); zero reference in open loop.
    pub error: bool,
    /// Record every `every`-th sample (`t[0], t[every], ...`); 1 records all.
    pub every: usize,
}

impl Record {
    /// Position, velocity, measured position, command and friction at every sample.
    pub const ALL: Record = Record { position: true, velocity: true, measured: true, command: true, friction: true, error: false, every: 1 };

    /// Number of recorded samples of a run of `n` samples.
    pub fn samples(&self, n: usize) -> usize {
        n.div_ceil(self.every.max(1))
    }
}

/// Sampled result of a run, all arrays of the run's length.
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

/// Mutable views of a run's output arrays (each [`Record::samples`] long); `None` skips an
/// output. Callers hand in memory they own (numpy arrays from the binding, rows of a batch).
#[derive(Debug, Default)]
pub struct ClosedLoopBuffers<'a> {
    pub position: Option<&'a mut [f64]>,
    pub velocity: Option<&'a mut [f64]>,
    pub measured: Option<&'a mut [f64]>,
    pub command: Option<&'a mut [f64]>,
    pub friction: Option<&'a mut [f64]>,
    pub error: Option<&'a mut [f64]>,
    /// Record every `every`-th sample.
    pub every: usize,
}

impl ClosedLoopOutput {
    /// Zeroed output vectors for `n` samples.
    pub fn zeros(n: usize) -> Self {
        Self { position: vec![0.0; n], velocity: vec![0.0; n], measured: vec![0.0; n], command: vec![0.0; n], friction: vec![0.0; n] }
    }

    /// Mutable views of every array, every sample.
    pub fn buffers(&mut self) -> ClosedLoopBuffers<'_> {
        ClosedLoopBuffers {
            position: Some(&mut self.position),
            velocity: Some(&mut self.velocity),
            measured: Some(&mut self.measured),
            command: Some(&mut self.command),
            friction: Some(&mut self.friction),
            error: None,
            every: 1,
        }
    }
}

pub(crate) fn non_finite(quantity: &'static str, step: usize, dt: f64) -> CoreError {
    let hint = match quantity {
        "command" => "check the controller gains, the reference and the drive limits",
        "friction" => "check the friction parameters against the step size",
        "measured position" => "check the measurement noise and the quantisation",
        _ => "the axis left the finite range: an unstable loop (gains, step size) or inputs too large",
    };
    CoreError::NonFiniteOutput { quantity, step, time: step as f64 * dt, hint }
}

/// Every output buffer holds exactly the `m` recorded samples.
fn check_buffers(out: &ClosedLoopBuffers<'_>, m: usize) -> Result<()> {
    for (name, buf) in [
        ("position", &out.position),
        ("velocity", &out.velocity),
        ("measured", &out.measured),
        ("command", &out.command),
        ("friction", &out.friction),
        ("error", &out.error),
    ] {
        if let Some(b) = buf {
            check::same_len(name, b, "recorded samples", m)?;
        }
    }
    Ok(())
}

/// Simulate with concrete (monomorphised) friction and controller types, writing into `out`.
/// The elements are used as they are (not reset); see [`simulate_axis_into`] for the usual entry.
pub fn simulate_generic_into<F: FrictionElement, C: Controller>(
    plant: &Plant,
    friction: &mut F,
    controller: &mut C,
    input: &ClosedLoopInput<'_>,
    out: ClosedLoopBuffers<'_>,
) -> Result<()> {
    input.validate(false)?;
    let n = input.len();
    let every = out.every.max(1);
    let m = n.div_ceil(every);
    check_buffers(&out, m)?;
    let d = plant.discretize(input.dt)?;
    controller.prepare(input.dt)?;
    controller.begin(input.initial_position, input.initial_velocity);
    friction.begin(input.initial_position, input.initial_velocity);
    // Re-slice to exactly m so the indexing below needs no bounds checks.
    let ClosedLoopBuffers { position, velocity, measured, command, friction: fric_out, error, .. } = out;
    let (mut pos, mut vel, mut meas) = (position.map(|b| &mut b[..m]), velocity.map(|b| &mut b[..m]), measured.map(|b| &mut b[..m]));
    let (mut cmd, mut fric, mut err) = (command.map(|b| &mut b[..m]), fric_out.map(|b| &mut b[..m]), error.map(|b| &mut b[..m]));
    let mut line = DelayLine::try_new(d.delay_steps, 0.0, n)?;
    // Scalars instead of 2x2 matrix types: the loop body is a handful of FMAs.
    let (p00, p01, p10, p11) = (d.phi[(0, 0)], d.phi[(0, 1)], d.phi[(1, 0)], d.phi[(1, 1)]);
    let (go0, go1, gn0, gn1) = (d.gamma_old[0], d.gamma_old[1], d.gamma_new[0], d.gamma_new[1]);
    let (gf0, gf1) = (d.gamma_force[0], d.gamma_force[1]);
    let (mut xp, mut xv) = (input.initial_position, input.initial_velocity);
    let (q, inv_q) = (input.quantization, if input.quantization > 0.0 { 1.0 / input.quantization } else { 0.0 });
    let (lo, hi, dt) = (input.drive_min, input.drive_max, input.dt);
    let (mut next_record, mut j) = (0usize, 0usize);
    let mut start = 0;
    while start < n {
        if input.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(CoreError::Interrupted);
        }
        let end = (start + CANCEL_CHECK_STEPS).min(n);
        for k in start..end {
            let r = input.reference.map_or(0.0, |r| r[k]);
            let mut y = xp;
            if let Some(noise) = input.measurement_noise {
                y += noise[k];
            }
            if q > 0.0 {
                y = (y * inv_q).round() * q;
            }
            let mut u = controller.update(r, y);
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
            if k == next_record {
                if let Some(b) = pos.as_deref_mut() {
                    b[j] = xp;
                }
                if let Some(b) = vel.as_deref_mut() {
                    b[j] = xv;
                }
                if let Some(b) = meas.as_deref_mut() {
                    b[j] = y;
                }
                if let Some(b) = cmd.as_deref_mut() {
                    b[j] = u;
                }
                if let Some(b) = fric.as_deref_mut() {
                    b[j] = f;
                }
                if let Some(b) = err.as_deref_mut() {
                    b[j] = r - xp;
                }
                j += 1;
                next_record += every;
            }
            xp = fma(-gf0, f, free_p);
            xv = fma(-gf1, f, free_v);
            // A NaN or inf anywhere makes the sum non-finite: one test per step (the sum of
            // large finite values can overflow too: then every term is looked at).
            if !(xp + xv + f + u + y).is_finite() {
                let named = [(u, "command"), (y, "measured position"), (f, "friction"), (xv, "velocity"), (xp, "position")];
                if let Some(&(_, quantity)) = named.iter().find(|(v, _)| !v.is_finite()) {
                    return Err(non_finite(quantity, k, dt));
                }
            }
        }
        start = end;
    }
    Ok(())
}

/// One run of an axis: plant, optional friction (with optional effects), optional controller.
/// The models are cloned, so the caller's stay untouched, and start from their initial state.
pub fn simulate_into(
    plant: &Plant,
    friction: Option<&FrictionModel>,
    effects: Option<&crate::effects::Effects>,
    controller: Option<&ControllerModel>,
    input: &ClosedLoopInput<'_>,
    out: ClosedLoopBuffers<'_>,
) -> Result<()> {
    if controller.is_some() && input.reference.is_none() {
        return Err(CoreError::InvalidParameter { name: "reference", reason: "a closed-loop run needs a reference".into() });
    }
    let effects = effects.filter(|e| !e.is_empty());
    match friction.cloned() {
        None => with_effects(plant, NoFriction, effects, controller, input, out),
        Some(FrictionModel::Gms(mut g)) if effects.is_none() => {
            g.reset();
            with_gms(plant, g, controller, input, out)
        }
        Some(mut model) => {
            model.reset();
            with_friction!(model, f => with_effects(plant, f, effects, controller, input, out))
        }
    }
}

fn with_effects<F: FrictionElement>(
    plant: &Plant,
    friction: F,
    effects: Option<&crate::effects::Effects>,
    controller: Option<&ControllerModel>,
    input: &ClosedLoopInput<'_>,
    out: ClosedLoopBuffers<'_>,
) -> Result<()> {
    match effects {
        None => with_control(plant, friction, controller, input, out),
        Some(e) => {
            let mut element = crate::effects::EffectsElement::new(friction, e.clone())?;
            element.reset();
            let fail = |el: &crate::effects::EffectsElement<F>| el.error().cloned();
            let mut ctrl = controller.cloned();
            let result = match ctrl.as_mut() {
                None => simulate_generic_into(plant, &mut element, &mut OpenLoop, input, out),
                Some(c) => {
                    c.reset();
                    with_controller!(c, c => simulate_generic_into(plant, &mut element, c, input, out))
                }
            };
            match fail(&element) {
                Some(e) => Err(e),
                None => result,
            }
        }
    }
}

/// A GMS run without effects: the latency-optimised kernel ([`crate::fast`]) where it applies,
/// the generic loop otherwise (or if the kernel's table misses its tolerance somewhere).
fn with_gms(plant: &Plant, g: crate::friction::Gms, controller: Option<&ControllerModel>, input: &ClosedLoopInput<'_>, mut out: ClosedLoopBuffers<'_>) -> Result<()> {
    use crate::fast::{Outcome, Outs, StribeckTable};
    input.validate(false)?;
    let n = input.len();
    let d = plant.discretize(input.dt)?;
    let table = if crate::fast::eligible(&g, &d, n) { StribeckTable::new(&g, input.dt) } else { None };
    if let Some(mut table) = table {
        check_buffers(&out, n.div_ceil(out.every.max(1)))?;
        let outs = Outs {
            pos: out.position.as_deref_mut(),
            vel: out.velocity.as_deref_mut(),
            meas: out.measured.as_deref_mut(),
            cmd: out.command.as_deref_mut(),
            fric: out.friction.as_deref_mut(),
            err: out.error.as_deref_mut(),
            every: out.every,
        };
        let (x0, v0) = (input.initial_position, input.initial_velocity);
        let outcome = match controller.cloned() {
            None => {
                let mut c = OpenLoop;
                c.prepare(input.dt)?;
                crate::fast::run(&g, &mut table, &d, &mut c, input, outs)?
            }
            Some(mut c) => {
                c.reset();
                with_controller!(&mut c, c => {
                    c.prepare(input.dt)?;
                    c.begin(x0, v0);
                    crate::fast::run(&g, &mut table, &d, c, input, outs)?
                })
            }
        };
        if let Outcome::Done = outcome {
            return Ok(());
        }
    }
    with_control(plant, g, controller, input, out)
}

fn with_control<F: FrictionElement>(
    plant: &Plant,
    mut friction: F,
    controller: Option<&ControllerModel>,
    input: &ClosedLoopInput<'_>,
    out: ClosedLoopBuffers<'_>,
) -> Result<()> {
    match controller.cloned() {
        None => simulate_generic_into(plant, &mut friction, &mut OpenLoop, input, out),
        Some(mut c) => {
            c.reset();
            with_controller!(&mut c, c => simulate_generic_into(plant, &mut friction, c, input, out))
        }
    }
}

/// [`simulate_into`] returning owned vectors of every output at every sample.
pub fn simulate(
    plant: &Plant,
    friction: Option<&FrictionModel>,
    effects: Option<&crate::effects::Effects>,
    controller: Option<&ControllerModel>,
    input: &ClosedLoopInput<'_>,
) -> Result<ClosedLoopOutput> {
    let mut out = ClosedLoopOutput::zeros(input.len());
    simulate_into(plant, friction, effects, controller, input, out.buffers())?;
    Ok(out)
}

/// Simulate with concrete types from their current state, returning every output.
pub fn simulate_generic<F: FrictionElement, C: Controller>(plant: &Plant, friction: &mut F, controller: &mut C, input: &ClosedLoopInput<'_>) -> Result<ClosedLoopOutput> {
    let mut out = ClosedLoopOutput::zeros(input.len());
    friction.reset();
    controller.reset();
    simulate_generic_into(plant, friction, controller, input, out.buffers())?;
    Ok(out)
}

/// A simulated axis: plant (or rigid body), friction model, effects. Validated together (an
/// effect that shifts friction levels needs a static map).
#[derive(Debug, Clone)]
pub struct Axis {
    pub plant: Plant,
    pub friction: Option<FrictionModel>,
    pub effects: Option<crate::effects::Effects>,
}

impl Axis {
    pub fn new(plant: Plant, friction: Option<FrictionModel>, effects: Option<crate::effects::Effects>) -> Result<Self> {
        if let Some(e) = &effects {
            e.check()?;
            if e.shifts_levels() && !matches!(friction, Some(FrictionModel::Static(_))) {
                return Err(CoreError::InvalidParameter {
                    name: "effects",
                    reason: "asymmetric, position-dependent, drifting or heating friction levels need a static-map friction model".into(),
                });
            }
        }
        Ok(Self { plant, friction, effects })
    }

    /// One run (see [`simulate_into`]).
    pub fn simulate_into(&self, controller: Option<&ControllerModel>, input: &ClosedLoopInput<'_>, out: ClosedLoopBuffers<'_>) -> Result<()> {
        simulate_into(&self.plant, self.friction.as_ref(), self.effects.as_ref(), controller, input, out)
    }

    /// One run with every output (see [`simulate`]).
    pub fn simulate(&self, controller: Option<&ControllerModel>, input: &ClosedLoopInput<'_>) -> Result<ClosedLoopOutput> {
        simulate(&self.plant, self.friction.as_ref(), self.effects.as_ref(), controller, input)
    }
}

/// Open-loop response of the plant to an input sequence `u[k]` held over `[k dt, (k+1) dt)`
/// (no friction), starting at rest. Returns `(position, velocity)` at `t[k] = k dt`.
pub fn simulate_open_loop(plant: &Plant, dt: f64, u: &[f64]) -> Result<(Vec<f64>, Vec<f64>)> {
    let input = ClosedLoopInput::open(u, dt);
    input.validate(false)?;
    let n = u.len();
    let (mut y, mut v) = (vec![0.0; n], vec![0.0; n]);
    let out = ClosedLoopBuffers { position: Some(&mut y), velocity: Some(&mut v), every: 1, ..Default::default() };
    simulate_generic_into(plant, &mut NoFriction, &mut OpenLoop, &input, out)?;
    Ok((y, v))
}

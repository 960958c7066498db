//! Effects beyond the friction model, simulated in feedback: the loop's catalogue as physics.
//!
//! An [`EffectsElement`] wraps any friction element and adds, on the same contact:
//!
//! - a force that depends on position only ([`PositionSeries`]: cogging, springs, gravity);
//! - friction levels that depend on position, time (drift) and the direction of motion
//!   (asymmetry), as per-direction shifts of a static map's levels ([`LevelShift`]);
//! - extra pre-sliding blocks (Maxwell-slip) in parallel with the friction model;
//! - a compliant load ([`Compliance`]): a mass on a spring-damper behind the simulated mass.
//!
//! Position- and time-dependent terms are evaluated at the start of each step (the controller's
//! sampling instant); the elastic parts (blocks, compliance) are linear or linearised in the
//! step's displacement, and the friction model then sees the plant's coupling reduced by them, so
//! stiff blocks and a stiff load stay stable at the plant's step.

use crate::error::{check, CoreError, Num, Result};
use crate::friction::{Coupling, FrictionElement, MaxwellSlip};
use crate::stribeck::LevelShift;
use nalgebra::Matrix2;

/// A function of position `g(q)` (N), as a series or a table.
#[derive(Debug, Clone, PartialEq)]
pub enum PositionSeries {
    /// `sum_d coef[d] P_d(x)`, `x = 2 (q - lo) / (hi - lo) - 1` (Legendre polynomials over the
    /// travel `[lo, hi]`); beyond the travel constant at its edge value, or with `linear_beyond`
    /// its degree-1 term (the slope of its best straight line over the travel) goes on while the
    /// curved terms hold their edge values: a spring or a weight goes on growing, a bump does not.
    Legendre { lo: f64, hi: f64, coef: Vec<f64>, linear_beyond: bool },
    /// `sum_p sum_h (coef_sin sin(2 pi h q / p) + coef_cos cos(2 pi h q / p))`, `h = 1..=harmonics`,
    /// coefficients ordered period by period, harmonic by harmonic, sine before cosine.
    Fourier { periods: Vec<f64>, harmonics: usize, coef: Vec<f64> },
    /// Linear interpolation of `values` on the uniform grid `q0 + i dq`, constant beyond it.
    Table { q0: f64, dq: f64, values: Vec<f64> },
}

impl PositionSeries {
    /// Validate the parameters.
    pub fn check(&self) -> Result<()> {
        match self {
            PositionSeries::Legendre { lo, hi, coef, .. } => {
                check::finite("lo", *lo)?;
                check::finite("hi", *hi)?;
                if !(hi > lo) || !((hi - lo).is_normal()) {
                    return Err(CoreError::InvalidParameter { name: "hi", reason: format!("the travel [{}, {}] must have hi > lo", Num(*lo), Num(*hi)) });
                }
                check::finite_array("coef", coef, 1)?;
                if coef.len() > 64 {
                    return Err(CoreError::InvalidParameter { name: "coef", reason: format!("{} Legendre terms; at most 64", coef.len()) });
                }
            }
            PositionSeries::Fourier { periods, harmonics, coef } => {
                check::finite_array("periods", periods, 1)?;
                for &p in periods {
                    check::positive("periods", p)?;
                }
                if *harmonics == 0 || *harmonics > 64 {
                    return Err(CoreError::InvalidParameter { name: "harmonics", reason: format!("must be 1..=64, got {harmonics}") });
                }
                check::same_len("coef", coef, "2 * periods * harmonics", 2 * periods.len() * harmonics)?;
                check::finite_array("coef", coef, 1)?;
            }
            PositionSeries::Table { q0, dq, values } => {
                check::finite("q0", *q0)?;
                check::positive("dq", *dq)?;
                check::finite_array("values", values, 2)?;
                if !(q0 + dq * values.len() as f64).is_finite() {
                    return Err(CoreError::InvalidParameter { name: "dq", reason: "the table's grid overflows".into() });
                }
            }
        }
        Ok(())
    }

    /// `g(q)`.
    #[inline]
    pub fn eval(&self, q: f64) -> f64 {
        self.eval_with_slope(q).0
    }

    /// `(g(q), g'(q))`; the slope is zero where the series is held constant (beyond the travel
    /// or the table).
    #[inline]
    pub fn eval_with_slope(&self, q: f64) -> (f64, f64) {
        match self {
            PositionSeries::Legendre { lo, hi, coef, linear_beyond } => {
                let scale = 2.0 / (hi - lo);
                let raw = scale * (q - lo) - 1.0;
                let x = raw.clamp(-1.0, 1.0);
                // Bonnet's recursion (d + 1) P_{d+1} = (2d + 1) x P_d - d P_{d-1}, and
                // P'_{d+1} = P'_{d-1} + (2d + 1) P_d for the slope.
                let (mut p_prev, mut p) = (1.0, x);
                let (mut dp_prev, mut dp) = (0.0, 1.0);
                let (mut sum, mut slope) = (coef[0], 0.0);
                for (d, &c) in coef.iter().enumerate().skip(1) {
                    sum += c * p;
                    slope += c * dp;
                    let df = d as f64;
                    let next = ((2.0 * df + 1.0) * x * p - df * p_prev) / (df + 1.0);
                    let dnext = dp_prev + (2.0 * df + 1.0) * p;
                    (p_prev, p) = (p, next);
                    (dp_prev, dp) = (dp, dnext);
                }
                if raw.abs() <= 1.0 {
                    (sum, slope * scale)
                } else if *linear_beyond && coef.len() > 1 {
                    (sum + coef[1] * (raw - x), coef[1] * scale)
                } else {
                    (sum, 0.0)
                }
            }
            PositionSeries::Fourier { periods, harmonics, coef } => {
                let (mut sum, mut slope) = (0.0, 0.0);
                let mut i = 0;
                for &period in periods {
                    let w1 = 2.0 * std::f64::consts::PI / period;
                    let (s1, c1) = (w1 * q).sin_cos();
                    // Harmonics by the angle-addition recursion: one sin_cos per period.
                    let (mut s, mut c) = (s1, c1);
                    for h in 1..=*harmonics {
                        let w = w1 * h as f64;
                        sum += coef[i] * s + coef[i + 1] * c;
                        slope += w * (coef[i] * c - coef[i + 1] * s);
                        i += 2;
                        let s_next = s * c1 + c * s1;
                        c = c * c1 - s * s1;
                        s = s_next;
                    }
                }
                (sum, slope)
            }
            PositionSeries::Table { q0, dq, values } => {
                let raw = (q - q0) / dq;
                let u = raw.clamp(0.0, (values.len() - 1) as f64);
                let i = (u.floor() as usize).min(values.len() - 2);
                let w = u - i as f64;
                let step = values[i + 1] - values[i];
                (values[i] + w * step, if raw == u { step / dq } else { 0.0 })
            }
        }
    }
}

/// How friction levels change over a run (warm-up, lubricant): `h(t)` scales the shifts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DriftShape {
    /// `h(t) = t / duration - 1/2` (zero mean over `[0, duration]`).
    Linear { duration: f64 },
    /// `h(t) = exp(-t / tau)`.
    Exponential { tau: f64 },
}

/// Friction drift: Coulomb level `+ d_level h(t)`, viscous coefficient `+ d_viscous h(t)`, with
/// `t` the time since the run started.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drift {
    pub shape: DriftShape,
    pub d_level: f64,
    pub d_viscous: f64,
}

impl Drift {
    fn check(&self) -> Result<()> {
        check::finite("d_level", self.d_level)?;
        check::finite("d_viscous", self.d_viscous)?;
        match self.shape {
            DriftShape::Linear { duration } => check::positive("duration", duration).map(|_| ()),
            DriftShape::Exponential { tau } => check::positive("tau", tau).map(|_| ()),
        }
    }

    #[inline]
    fn h(&self, t: f64) -> f64 {
        match self.shape {
            DriftShape::Linear { duration } => t / duration - 0.5,
            DriftShape::Exponential { tau } => (-t / tau).exp(),
        }
    }
}

/// Friction that changes with the recent motion (a lubricant warming up, a temperature): the
/// speed low-passed with time constant `tau`, `m' = (|v| - m) / tau`, shifts the Coulomb level by
/// `d_level * m` and the viscous coefficient by `d_viscous * m` (both per m/s of `m`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Heating {
    pub tau: f64,
    pub d_level: f64,
    pub d_viscous: f64,
}

impl Heating {
    fn check(&self) -> Result<()> {
        check::positive("tau", self.tau)?;
        check::finite("d_level", self.d_level)?;
        check::finite("d_viscous", self.d_viscous).map(|_| ())
    }
}

/// Friction that differs with the direction of motion: moving in `+` the Coulomb level is
/// `+ d_level` and the viscous coefficient `+ d_viscous`; moving in `-`, minus the same.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Asymmetry {
    pub d_level: f64,
    pub d_viscous: f64,
}

/// A load of mass `mass` (kg) on a spring-damper (natural frequency `fn_hz`, damping ratio
/// `zeta`) behind the simulated mass: the force it exerts is `mass * q2''` with
/// `q2'' = w^2 (q - q2) + 2 zeta w (q' - q2')`. The simulated plant is then the motor side only.
#[derive(Debug, Clone, PartialEq)]
pub struct Compliance {
    pub mass: f64,
    pub fn_hz: f64,
    pub zeta: f64,
    /// Load position relative to the motor `r = q2 - q` and load velocity `q2'`.
    r: f64,
    v2: f64,
    /// `exp` of the relative dynamics over the current step: `(dt, phi)`.
    memo: Option<(f64, Matrix2<f64>)>,
}

impl Compliance {
    pub fn new(mass: f64, fn_hz: f64, zeta: f64) -> Result<Self> {
        check::positive("mass", mass)?;
        check::positive("fn_hz", fn_hz)?;
        check::non_negative("zeta", zeta)?;
        Ok(Self { mass, fn_hz, zeta, r: 0.0, v2: 0.0, memo: None })
    }

    fn phi(&mut self, dt: f64) -> Result<Matrix2<f64>> {
        match self.memo {
            Some((h, phi)) if h == dt => Ok(phi),
            _ => {
                let w = 2.0 * std::f64::consts::PI * self.fn_hz;
                let a = Matrix2::new(0.0, 1.0, -w * w, -2.0 * self.zeta * w) * dt;
                if !(a.abs().max() <= crate::plant::MAX_STIFFNESS_RATIO) {
                    return Err(CoreError::InvalidParameter { name: "fn_hz", reason: format!("a {} Hz load resonance is too fast for a step of {} s", Num(self.fn_hz), Num(dt)) });
                }
                let phi = a.exp();
                self.memo = Some((dt, phi));
                Ok(phi)
            }
        }
    }

    /// `(E0, K)`: the average force over a step of displacement `dx` is `E0 + K dx` (exact: the
    /// load is linear and the motor moves at constant velocity over the step).
    #[inline]
    fn linear(&self, phi: &Matrix2<f64>, dt: f64) -> (f64, f64) {
        let e0 = self.mass / dt * (phi[(1, 0)] * self.r + (phi[(1, 1)] - 1.0) * self.v2);
        let k = self.mass * (1.0 - phi[(1, 1)]) / (dt * dt);
        (e0, k)
    }

    #[inline]
    fn advance(&mut self, phi: &Matrix2<f64>, dx: f64, dt: f64) -> f64 {
        let v = dx / dt;
        let rd = self.v2 - v;
        let r_new = phi[(0, 0)] * self.r + phi[(0, 1)] * rd;
        let rd_new = phi[(1, 0)] * self.r + phi[(1, 1)] * rd;
        self.r = r_new;
        self.v2 = rd_new + v;
        self.mass * (rd_new - rd) / dt
    }
}

/// Everything the [`EffectsElement`] adds to a friction model. All optional.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Effects {
    pub asymmetry: Option<Asymmetry>,
    /// `g(q)` added to the force (N), independent of the direction of motion.
    pub position_force: Option<PositionSeries>,
    /// `g(q)` added to the Coulomb level (N): the friction level varies along the travel.
    pub position_friction: Option<PositionSeries>,
    pub drift: Option<Drift>,
    pub heating: Option<Heating>,
    /// Pre-sliding blocks in parallel with the friction model.
    pub blocks: Option<MaxwellSlip>,
    pub compliance: Option<Compliance>,
}

impl Effects {
    /// Validate every part.
    pub fn check(&self) -> Result<()> {
        if let Some(a) = &self.asymmetry {
            check::finite("d_level", a.d_level)?;
            check::finite("d_viscous", a.d_viscous)?;
        }
        for s in [&self.position_force, &self.position_friction].into_iter().flatten() {
            s.check()?;
        }
        if let Some(d) = &self.drift {
            d.check()?;
        }
        if let Some(h) = &self.heating {
            h.check()?;
        }
        Ok(())
    }

    /// Whether any part shifts the friction levels (needs a friction model that supports it).
    pub fn shifts_levels(&self) -> bool {
        self.asymmetry.is_some() || self.position_friction.is_some() || self.drift.is_some() || self.heating.is_some()
    }

    /// Nothing to add.
    pub fn is_empty(&self) -> bool {
        *self == Effects::default()
    }

    /// The level shift at position `q`, time `t` and low-passed speed `m`.
    #[inline]
    fn level_shift(&self, q: f64, t: f64, m: f64) -> LevelShift {
        let mut s = LevelShift::NONE;
        if let Some(a) = &self.asymmetry {
            s.level_pos += a.d_level;
            s.level_neg -= a.d_level;
            s.viscous_pos += a.d_viscous;
            s.viscous_neg -= a.d_viscous;
        }
        if let Some(g) = &self.position_friction {
            let v = g.eval(q);
            s.level_pos += v;
            s.level_neg += v;
        }
        if let Some(d) = &self.drift {
            let h = d.h(t);
            s.level_pos += d.d_level * h;
            s.level_neg += d.d_level * h;
            s.viscous_pos += d.d_viscous * h;
            s.viscous_neg += d.d_viscous * h;
        }
        if let Some(h) = &self.heating {
            s.level_pos += h.d_level * m;
            s.level_neg += h.d_level * m;
            s.viscous_pos += h.d_viscous * m;
            s.viscous_neg += h.d_viscous * m;
        }
        s
    }
}

/// A friction element with [`Effects`] on the same contact (see the module documentation).
#[derive(Debug, Clone)]
pub struct EffectsElement<F> {
    pub inner: F,
    pub effects: Effects,
    /// Position (m) and time since the start (s) at the start of the next step.
    q: f64,
    t: f64,
    q_start: f64,
    /// Low-passed speed of the heating effect (m/s) and its value at the start.
    m: f64,
    m_start: f64,
    /// Extra force (blocks + compliance + position force) of the last step.
    extra: f64,
    /// Set when a step could not be prepared (a compliance too fast for the step); reported
    /// by [`EffectsElement::error`] and turned into an error by the simulators.
    failed: Option<CoreError>,
}

impl<F: FrictionElement> EffectsElement<F> {
    /// Wrap `inner`; refuses level-shifting effects on a model that has no levels to shift.
    pub fn new(inner: F, effects: Effects) -> Result<Self> {
        effects.check()?;
        if effects.shifts_levels() && !inner.supports_level_shift() {
            return Err(CoreError::InvalidParameter {
                name: "effects",
                reason: "asymmetric, position-dependent, drifting or heating friction levels need a static-map friction model".into(),
            });
        }
        Ok(Self { inner, effects, q: 0.0, t: 0.0, q_start: 0.0, m: 0.0, m_start: 0.0, extra: 0.0, failed: None })
    }

    /// The first error met while stepping, if any.
    pub fn error(&self) -> Option<&CoreError> {
        self.failed.as_ref()
    }

    /// Prepare the step: shift the levels, return the position force at the step's start with
    /// its slope, and the compliance's transition matrix.
    #[inline]
    fn start_step(&mut self, dt: f64) -> ((f64, f64), Option<Matrix2<f64>>) {
        if self.effects.shifts_levels() {
            self.inner.set_level_shift(self.effects.level_shift(self.q, self.t, self.m));
        }
        let f_pos = self.effects.position_force.as_ref().map_or((0.0, 0.0), |g| g.eval_with_slope(self.q));
        let phi = match self.effects.compliance.as_mut().map(|c| c.phi(dt)) {
            None => None,
            Some(Ok(phi)) => Some(phi),
            Some(Err(e)) => {
                self.failed.get_or_insert(e);
                None
            }
        };
        (f_pos, phi)
    }

    #[inline]
    fn finish_step(&mut self, dx: f64, dt: f64, f_pos: (f64, f64), phi: Option<Matrix2<f64>>) -> f64 {
        // The position force over the step: at mid-step, to first order (a spring neither gains
        // nor loses energy).
        let mut extra = f_pos.0 + 0.5 * f_pos.1 * dx;
        if let Some(b) = self.effects.blocks.as_mut() {
            extra += b.advance(dx, dt);
        }
        if let (Some(c), Some(phi)) = (self.effects.compliance.as_mut(), phi) {
            extra += c.advance(&phi, dx, dt);
        }
        if let Some(h) = &self.effects.heating {
            // Exact for the speed held over the step.
            let speed = dx.abs() / dt;
            self.m = speed + (self.m - speed) * (-dt / h.tau).exp();
        }
        self.q += dx;
        self.t += dt;
        self.extra = extra;
        extra
    }
}

impl<F: FrictionElement> FrictionElement for EffectsElement<F> {
    fn force(&self) -> f64 {
        self.inner.force() + self.extra
    }

    fn advance(&mut self, dx: f64, dt: f64) -> f64 {
        let (f_pos, phi) = self.start_step(dt);
        let f = self.inner.advance(dx, dt);
        f + self.finish_step(dx, dt, f_pos, phi)
    }

    fn tangent_stiffness(&self, direction: f64, dt: f64) -> f64 {
        let mut k = self.inner.tangent_stiffness(direction, dt);
        if let Some(b) = &self.effects.blocks {
            k += b.tangent_stiffness(direction, dt);
        }
        if let Some(c) = &self.effects.compliance {
            if let Some((h, phi)) = c.memo {
                if h == dt {
                    k += c.linear(&phi, dt).1;
                }
            }
        }
        k
    }

    fn reset(&mut self) {
        self.inner.reset();
        if let Some(b) = self.effects.blocks.as_mut() {
            b.reset();
        }
        if let Some(c) = self.effects.compliance.as_mut() {
            c.r = 0.0;
            c.v2 = 0.0;
        }
        self.q = self.q_start;
        self.t = 0.0;
        self.m = self.m_start;
        self.extra = 0.0;
        self.failed = None;
    }

    fn begin(&mut self, position: f64, velocity: f64) {
        self.inner.begin(position, velocity);
        self.q_start = position;
        self.q = position;
        self.t = 0.0;
        // A run that starts moving has been moving: the low-passed speed starts at that speed.
        self.m_start = velocity.abs();
        self.m = self.m_start;
        if let Some(c) = self.effects.compliance.as_mut() {
            c.r = 0.0;
            c.v2 = velocity;
        }
    }

    fn initial_force(&self, v0: f64) -> f64 {
        self.inner.initial_force(v0)
    }

    /// Reduce the plant's coupling by the elastic parts (`E0 + K dx`), let the friction model
    /// take its step against that, then advance the elastic parts exactly with the resulting
    /// displacement.
    fn advance_coupled(&mut self, c: &Coupling, dt: f64) -> f64 {
        let (f_pos, phi) = self.start_step(dt);
        let mut e0 = f_pos.0;
        let mut k = 0.5 * f_pos.1;
        if let (Some(comp), Some(phi)) = (self.effects.compliance.as_ref(), phi.as_ref()) {
            let (e, kk) = comp.linear(phi, dt);
            e0 += e;
            k += kk;
        }
        if let Some(b) = self.effects.blocks.as_ref() {
            let f_b = b.force();
            let trial = c.free_dx - c.dx_per_newton * (self.inner.force() + e0 + f_b);
            let dir = if trial >= 0.0 { 1.0 } else { -1.0 };
            e0 += f_b;
            k += b.tangent_stiffness(dir, dt);
        }
        // A softening position force (negative slope) must not make the reduced coupling singular.
        if 1.0 + c.dx_per_newton * k < 0.5 {
            k = -0.5 / c.dx_per_newton;
        }
        let g = 1.0 / (1.0 + c.dx_per_newton * k);
        let free_dx = (c.free_dx - c.dx_per_newton * e0) * g;
        let reduced = Coupling {
            free_dx,
            dx_per_newton: c.dx_per_newton * g,
            free_v: c.free_v - c.v_per_newton * (e0 + k * free_dx),
            v_per_newton: c.v_per_newton * (1.0 - k * c.dx_per_newton * g),
        };
        let f = self.inner.advance_coupled(&reduced, dt);
        let dx = reduced.free_dx - reduced.dx_per_newton * f;
        f + self.finish_step(dx, dt, f_pos, phi)
    }

    fn supports_level_shift(&self) -> bool {
        self.inner.supports_level_shift()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legendre_matches_the_closed_forms() {
        let s = PositionSeries::Legendre { lo: -1.0, hi: 1.0, coef: vec![0.5, 2.0, -1.0, 0.25], linear_beyond: false };
        for &x in &[-1.0, -0.3, 0.0, 0.7, 1.0] {
            let p2 = 0.5 * (3.0 * x * x - 1.0);
            let p3 = 0.5 * (5.0 * x * x * x - 3.0 * x);
            let want = 0.5 + 2.0 * x - p2 + 0.25 * p3;
            assert!((s.eval(x) - want).abs() < 1e-14, "x = {x}");
        }
        // Constant beyond the travel.
        assert_eq!(s.eval(3.0), s.eval(1.0));
    }

    #[test]
    fn legendre_continues_its_straight_line_beyond_the_travel_when_asked() {
        // a spring fitted over the travel [0, 0.1] is a line in q, and stays one beyond it
        let line = PositionSeries::Legendre { lo: 0.0, hi: 0.1, coef: vec![1.0, 2.0], linear_beyond: true };
        let at = |q: f64| 1.0 + 2.0 * (20.0 * q - 1.0);
        for &q in &[-0.3, -0.01, 0.05, 0.13, 0.4] {
            assert!((line.eval(q) - at(q)).abs() < 1e-12, "q = {q}");
        }
        // a curved series: continuous at the edges, and beyond them the slope of its degree-1
        // term (2 per unit of x), not the steeper tangent of its curved terms
        let s = PositionSeries::Legendre { lo: -1.0, hi: 1.0, coef: vec![0.5, 2.0, -1.0, 0.25], linear_beyond: true };
        let (v1, d1) = s.eval_with_slope(1.0);
        assert!((s.eval(1.0 + 1e-9) - v1).abs() < 1e-8 && (d1 - 2.0).abs() > 0.5);
        assert!((s.eval(2.5) - (v1 + 1.5 * 2.0)).abs() < 1e-12);
        assert_eq!(s.eval_with_slope(2.5).1, 2.0);
        let v0 = s.eval(-1.0);
        assert!((s.eval(-3.0) - (v0 - 2.0 * 2.0)).abs() < 1e-12);
    }

    #[test]
    fn fourier_harmonics_by_recursion_match_sin_cos() {
        let p = 5e-3;
        let s = PositionSeries::Fourier { periods: vec![p], harmonics: 3, coef: vec![1.0, 0.5, -0.2, 0.3, 0.1, -0.4] };
        for &q in &[0.0, 1e-3, 2.7e-3, 0.0123] {
            let w = 2.0 * std::f64::consts::PI * q / p;
            let want = (w).sin() + 0.5 * w.cos() - 0.2 * (2.0 * w).sin() + 0.3 * (2.0 * w).cos() + 0.1 * (3.0 * w).sin() - 0.4 * (3.0 * w).cos();
            assert!((s.eval(q) - want).abs() < 1e-12, "q = {q}");
        }
    }

    #[test]
    fn slopes_match_finite_differences() {
        let series = [
            PositionSeries::Legendre { lo: -0.2, hi: 0.3, coef: vec![0.5, 2.0, -1.0, 0.25, 0.7], linear_beyond: false },
            PositionSeries::Legendre { lo: -0.2, hi: 0.3, coef: vec![0.5, 2.0, -1.0, 0.25, 0.7], linear_beyond: true },
            PositionSeries::Fourier { periods: vec![5e-3, 1.3e-2], harmonics: 2, coef: vec![1.0, 0.5, -0.2, 0.3, 0.1, -0.4, 0.2, 0.9] },
            PositionSeries::Table { q0: -0.1, dq: 0.05, values: vec![0.0, 2.0, 1.0, 1.5] },
        ];
        for s in &series {
            for &q in &[-0.47, -0.13, -0.02, 0.0123, 0.071, 0.24, 0.55] {
                let h = 1e-7;
                let fd = (s.eval(q + h) - s.eval(q - h)) / (2.0 * h);
                let (_, slope) = s.eval_with_slope(q);
                assert!((slope - fd).abs() < 1e-5 * (1.0 + fd.abs()), "{s:?} at {q}: {slope} vs {fd}");
            }
        }
    }

    #[test]
    fn table_interpolates_and_clamps() {
        let s = PositionSeries::Table { q0: 0.0, dq: 1.0, values: vec![0.0, 2.0, 1.0] };
        assert_eq!(s.eval(0.5), 1.0);
        assert_eq!(s.eval(1.5), 1.5);
        assert_eq!(s.eval(-4.0), 0.0);
        assert_eq!(s.eval(9.0), 1.0);
    }

    #[test]
    fn compliance_force_is_exactly_linear_in_the_step() {
        let mut c = Compliance::new(2.0, 15.0, 0.1).unwrap();
        let dt = 1e-3;
        let phi = c.phi(dt).unwrap();
        c.r = 1e-4;
        c.v2 = 0.02;
        let (e0, k) = c.linear(&phi, dt);
        for dx in [-3e-5, 0.0, 1e-5, 4e-5] {
            let mut cc = c.clone();
            let f = cc.advance(&phi, dx, dt);
            assert!((f - (e0 + k * dx)).abs() < 1e-9 * (1.0 + f.abs()), "dx = {dx}");
        }
    }
}

//! Dynamic friction elements and the common interface the simulators drive.
//!
//! Every element is advanced over one interval during which the contact moves by `dx` at the
//! constant velocity `v = dx / dt`. Under that (zero-order-hold) assumption every update below is
//! *exact*: sticking blocks move linearly, slipping blocks relax exponentially, and the instant a
//! block reaches its break force inside the interval is found analytically. That is why the stiff
//! GMS blocks (k ~ 1e6..1e7 N/m, a few nm of pre-sliding) are stable and accurate at any step.

use crate::error::{check, CoreError, Result};
use crate::numeric::{fma, UnitIntervalPoly};
use crate::stribeck::{check_fractions, LevelShift, StaticFriction, Stribeck};

/// How a plant step responds to a constant friction force `F` held over the step:
/// displacement `dx = free_dx - dx_per_newton * F`, end velocity `v = free_v - v_per_newton * F`.
#[derive(Debug, Clone, Copy)]
pub struct Coupling {
    pub free_dx: f64,
    pub dx_per_newton: f64,
    pub free_v: f64,
    pub v_per_newton: f64,
}

/// The interface shared by all friction models.
pub trait FrictionElement {
    /// Force (N) in the current state.
    fn force(&self) -> f64;

    /// Advance over an interval `dt` during which the contact moves by `dx`; returns the force at
    /// the end of the interval.
    fn advance(&mut self, dx: f64, dt: f64) -> f64;

    /// `dF/d(dx)` of [`advance`](Self::advance) about the current state for motion in
    /// `direction` (+1 / -1), used by the linearly implicit closed-loop coupling.
    fn tangent_stiffness(&self, direction: f64, dt: f64) -> f64;

    /// Return to the virgin (unloaded, sticking) state.
    fn reset(&mut self);

    /// Called once before a run, after [`reset`](Self::reset), with the initial position and
    /// velocity; elements whose force depends on where the axis is (position-dependent effects)
    /// start tracking from there.
    fn begin(&mut self, _position: f64, _velocity: f64) {}

    /// Whether [`set_level_shift`](Self::set_level_shift) changes the force (the static map's
    /// Coulomb and viscous levels can be shifted per direction; the other models have none).
    fn supports_level_shift(&self) -> bool {
        false
    }

    /// Shift the friction levels for the next step (position- and time-dependent friction,
    /// direction asymmetry); only meaningful when [`supports_level_shift`](Self::supports_level_shift).
    fn set_level_shift(&mut self, _shift: LevelShift) {}

    /// Force reported at the first sample of a trajectory that starts at velocity `v0`: the
    /// virgin state for models with memory, the map value for memoryless ones.
    fn initial_force(&self, _v0: f64) -> f64 {
        self.force()
    }

    /// One step coupled to a plant: find the displacement consistent with the friction it
    /// produces, advance, and return the force to hold over the step.
    ///
    /// The default is linearly implicit: `F(dx) ~ F + K dx` with the tangent stiffness `K`, which
    /// keeps stiff pre-sliding springs stable at the plant's step; the exact update then applies
    /// the slip limits.
    fn advance_coupled(&mut self, c: &Coupling, dt: f64) -> f64 {
        let f0 = self.force();
        let trial = c.free_dx - c.dx_per_newton * f0;
        let direction = if trial >= 0.0 { 1.0 } else { -1.0 };
        let k = self.tangent_stiffness(direction, dt);
        let dx = trial / (1.0 + c.dx_per_newton * k);
        self.advance(dx, dt)
    }
}

// ---------------------------------------------------------------------------------------------
// Static map
// ---------------------------------------------------------------------------------------------

/// The static map as a friction element: memoryless, except for the last force (for `force()`)
/// and the level shift of the current step.
#[derive(Debug, Clone)]
pub struct StaticElement {
    pub map: StaticFriction,
    last: f64,
    shift: LevelShift,
}

impl StaticElement {
    pub fn new(map: StaticFriction) -> Self {
        Self { map, last: map.offset, shift: LevelShift::NONE }
    }
}

impl FrictionElement for StaticElement {
    #[inline]
    fn force(&self) -> f64 {
        self.last
    }
    #[inline]
    fn advance(&mut self, dx: f64, dt: f64) -> f64 {
        self.last = self.map.force_shifted(dx / dt, &self.shift);
        self.last
    }
    fn tangent_stiffness(&self, _direction: f64, dt: f64) -> f64 {
        self.map.sigma / dt
    }
    fn reset(&mut self) {
        self.last = self.map.offset;
        self.shift = LevelShift::NONE;
    }
    fn initial_force(&self, v0: f64) -> f64 {
        self.map.force_shifted(v0, &self.shift)
    }
    fn supports_level_shift(&self) -> bool {
        true
    }
    fn set_level_shift(&mut self, shift: LevelShift) {
        self.shift = shift;
    }

    /// Set-valued stiction (an implicit Karnopp scheme): if the force needed to bring the mass to
    /// rest by the end of the step is within the break-away level of the direction it pushes,
    /// the contact sticks and supplies exactly that force; otherwise it slides with
    /// `sign(v) s_dir(v) + sigma_dir v`, solved implicitly in the end velocity. No chattering
    /// around zero velocity, whatever the step.
    ///
    /// With a linear region (`map.v_linear > 0`) the map is single-valued: inside the region the
    /// end velocity solves `v (1 + c_v slope) = free_v`; outside, the sliding branch below.
    fn advance_coupled(&mut self, c: &Coupling, _dt: f64) -> f64 {
        let m = &self.map;
        let sh = &self.shift;
        let free_v = c.free_v - c.v_per_newton * m.offset;
        let dir = if free_v >= 0.0 { 1.0 } else { -1.0 };
        if m.v_linear > 0.0 {
            let slope = m.linear_region_slope_shifted(dir, sh);
            let v = free_v / (1.0 + c.v_per_newton * slope);
            if v.abs() < m.v_linear {
                self.last = slope * v + m.offset;
                return self.last;
            }
        } else {
            let hold = free_v / c.v_per_newton;
            if hold.abs() <= m.breakaway_shifted(dir, sh) {
                self.last = hold + m.offset;
                return self.last;
            }
        }
        let (level_shift, sigma) = m.direction_levels(dir, sh);
        // v (1 + c_v sigma) = free_v - c_v dir s(v); s is evaluated at the current estimate of v.
        let mut v = free_v;
        for _ in 0..3 {
            let s = (m.stribeck.eval(v) + level_shift).max(0.0);
            v = (free_v - c.v_per_newton * dir * s) / (1.0 + c.v_per_newton * sigma);
            if v * dir < 0.0 {
                v = 0.0;
            }
        }
        self.last = dir * (m.stribeck.eval(v) + level_shift).max(0.0) + sigma * v + m.offset;
        self.last
    }
}

// ---------------------------------------------------------------------------------------------
// Generalized Maxwell-slip
// ---------------------------------------------------------------------------------------------

/// How a slipping GMS block relaxes towards `sign(v) alpha_i s(v)`.
///
/// The paper's eq. 4 is garbled; both readings of the standard form are offered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlipLaw {
    /// Al-Bender, Lampaert & Swevers (2005): `dF_i/dt = c (sign(v) alpha_i - F_i / s(v))`,
    /// i.e. relaxation at the rate `c / s(v)` (1/s); `c` in N/s.
    Time,
    /// Relaxation per unit sliding distance: `dF_i/dx = c (sign(v) alpha_i s(v) - F_i)`, rate
    /// `c |v|` (1/s); `c` in 1/m. Rate-independent in slip, like a Dahl curve.
    Displacement,
}

/// Generalized Maxwell-slip model with N parallel elasto-slip blocks.
///
/// Hot-path layout: block modes are `0.0` (sticking) or `+1.0` / `-1.0` (slipping in that
/// direction); the sum of block forces and the stiffness of the blocks that are not slipping in
/// each direction are kept up to date by `advance`, so the coupled step needs no extra pass.
#[derive(Debug, Clone)]
pub struct Gms {
    pub stribeck: Stribeck,
    /// Block stiffnesses `k_i` (N/m).
    pub k: Vec<f64>,
    /// Block fractions `alpha_i` (sum to 1): block `i` breaks at `alpha_i s(v)`.
    pub alpha: Vec<f64>,
    /// Slip attraction parameter (units per [`SlipLaw`]).
    pub c: f64,
    /// Viscous coefficient (N s/m).
    pub sigma: f64,
    pub slip_law: SlipLaw,
    forces: Vec<f64>,
    slip: Vec<f64>,
    total_k: f64,
    sum_forces: f64,
    k_free_pos: f64,
    k_free_neg: f64,
    /// `(dt, 1/dt)`: the step rarely changes, a multiply is cheaper than a divide.
    inv_dt: (f64, f64),
    /// `(s, dt, exp(-rate(s) dt))`: at speeds where the Stribeck curve has settled `s == fc`
    /// exactly, and the division and exponential are skipped (same inputs, same bits).
    decay_memo: (f64, f64, f64),
    /// `(K, dx_per_newton, 1 / (1 + dx_per_newton K))` for the coupled step.
    coupling_memo: (f64, f64, f64),
    /// `(dt, steps seen at this dt, polynomial)`: the slip decay `exp(-c dt / s)` as a polynomial
    /// of the Stribeck exponential `E` in `[0, 1]`, fitted (and checked to 4e-15 relative) once the
    /// step has been constant for a few calls; `None` falls back to division and `exp`.
    decay_fit: (f64, u32, Option<UnitIntervalPoly>),
}

impl Gms {
    pub fn new(stribeck: Stribeck, k: Vec<f64>, alpha: Vec<f64>, c: f64, sigma: f64, slip_law: SlipLaw) -> Result<Self> {
        check::finite_array("k", &k, 1)?;
        if let Some(&bad) = k.iter().find(|&&x| x <= 0.0) {
            return Err(CoreError::NotPositive { name: "k", value: bad });
        }
        check::same_len("alpha", &alpha, "k", k.len())?;
        check_fractions("alpha", &alpha)?;
        check::positive("c", c)?;
        check::non_negative("sigma", sigma)?;
        let n = k.len();
        let total_k = k.iter().sum();
        Ok(Self {
            stribeck,
            k,
            alpha,
            c,
            sigma,
            slip_law,
            forces: vec![0.0; n],
            slip: vec![0.0; n],
            total_k,
            sum_forces: 0.0,
            k_free_pos: total_k,
            k_free_neg: total_k,
            inv_dt: (f64::NAN, f64::NAN),
            decay_memo: (f64::NAN, f64::NAN, 0.0),
            coupling_memo: (f64::NAN, f64::NAN, 0.0),
            decay_fit: (f64::NAN, 0, None),
        })
    }

    /// Number of blocks.
    pub fn n_blocks(&self) -> usize {
        self.k.len()
    }

    /// Current block forces (N).
    pub fn block_forces(&self) -> &[f64] {
        &self.forces
    }

    /// Whether block `i` is slipping.
    pub fn is_slipping(&self, i: usize) -> bool {
        self.slip[i] != 0.0
    }

    /// Sum of block stiffnesses (the initial pre-sliding stiffness, N/m).
    pub fn total_stiffness(&self) -> f64 {
        self.total_k
    }

    fn refresh_free_stiffness(&mut self) {
        let (mut k_pos, mut k_neg) = (0.0, 0.0);
        for (&m, &ki) in self.slip.iter().zip(&self.k) {
            k_pos += if m == 1.0 { 0.0 } else { ki };
            k_neg += if m == -1.0 { 0.0 } else { ki };
        }
        self.k_free_pos = k_pos;
        self.k_free_neg = k_neg;
    }

    /// The decay polynomial for step `dt`, if the step is steady and the fit is accurate.
    #[inline(always)]
    fn decay_poly(&mut self, dt: f64) -> Option<UnitIntervalPoly> {
        const STEADY_CALLS: u32 = 16;
        if dt == self.decay_fit.0 {
            if self.decay_fit.1 < STEADY_CALLS {
                self.decay_fit.1 += 1;
                if self.decay_fit.1 == STEADY_CALLS {
                    self.decay_fit.2 = self.fit_decay(dt);
                }
            }
        } else {
            self.decay_fit = (dt, 1, None);
        }
        self.decay_fit.2
    }

    #[cold]
    fn fit_decay(&self, dt: f64) -> Option<UnitIntervalPoly> {
        let (fc, fs, c) = (self.stribeck.fc, self.stribeck.fs, self.c);
        if fc.min(fs) <= 0.0 {
            return None;
        }
        UnitIntervalPoly::fit(|e| (-(c / crate::numeric::fma(fs - fc, e, fc)) * dt).exp(), 4e-15)
    }

    #[inline(always)]
    fn inv_dt(&mut self, dt: f64) -> f64 {
        if dt != self.inv_dt.0 {
            self.inv_dt = (dt, 1.0 / dt);
        }
        self.inv_dt.1
    }

    #[inline(always)]
    fn decay(&mut self, s: f64, e: f64, dx: f64, dt: f64) -> f64 {
        match self.slip_law {
            SlipLaw::Time => {
                if s != self.decay_memo.0 || dt != self.decay_memo.1 {
                    let decay = match self.decay_poly(dt) {
                        // exp(-c dt / s) with s = fc + (fs - fc) E, as a polynomial in E: no
                        // division and no exponential on the step's dependency chain.
                        Some(poly) => poly.eval(e),
                        None => (-(self.c / s.max(f64::MIN_POSITIVE)) * dt).exp(),
                    };
                    self.decay_memo = (s, dt, decay);
                }
                self.decay_memo.2
            }
            // rate c |v| over dt = c |dx|
            SlipLaw::Displacement => (-(self.c * dx.abs())).exp(),
        }
    }
}

impl FrictionElement for Gms {
    #[inline]
    fn force(&self) -> f64 {
        // The viscous part depends on the last velocity only and is included by `advance`.
        self.sum_forces
    }

    #[inline]
    fn advance(&mut self, dx: f64, dt: f64) -> f64 {
        if dx == 0.0 {
            // At rest every block sticks and holds its force.
            self.slip.iter_mut().for_each(|m| *m = 0.0);
            self.k_free_pos = self.total_k;
            self.k_free_neg = self.total_k;
            return self.sum_forces;
        }
        let v = dx * self.inv_dt(dt);
        let dir = if dx > 0.0 { 1.0 } else { -1.0 };
        // One Stribeck evaluation and one exponential per step, shared by all blocks.
        let (s, e) = self.stribeck.eval_with_exp(v);
        let decay = self.decay(s, e, dx, dt);
        let dir_s = dir * s;
        // Two partial sums halve the serial add chain of the total force.
        let mut sums = [0.0f64; 2];
        let mut mode_changed = false;
        for (i, (((f, m), &ki), &ai)) in self.forces.iter_mut().zip(self.slip.iter_mut()).zip(&self.k).zip(&self.alpha).enumerate() {
            let target = ai * dir_s;
            let f_old = *f;
            if *m == dir {
                *f = fma(f_old - target, decay, target);
            } else {
                // Sticking (or reversing out of slip): elastic update, capped at the break force.
                let stuck = fma(ki, dx, f_old);
                if (stuck - target) * dir >= 0.0 {
                    *m = dir;
                    mode_changed = true;
                    // Reaching the break force inside the step puts the block on its target;
                    // a block already beyond a (lower) break force relaxes over the whole step.
                    *f = if (f_old - target) * dir >= 0.0 { fma(f_old - target, decay, target) } else { target };
                } else {
                    mode_changed |= *m != 0.0;
                    *m = 0.0;
                    *f = stuck;
                }
            }
            sums[i & 1] += *f;
        }
        let total = sums[0] + sums[1];
        self.sum_forces = total;
        if mode_changed {
            // Rare (break-away, reversals): refresh the stiffness of the non-slipping blocks.
            self.refresh_free_stiffness();
        }
        fma(self.sigma, v, total)
    }

    #[inline]
    fn tangent_stiffness(&self, direction: f64, dt: f64) -> f64 {
        let k = if direction > 0.0 { self.k_free_pos } else { self.k_free_neg };
        k + self.sigma / dt
    }

    fn reset(&mut self) {
        self.forces.iter_mut().for_each(|f| *f = 0.0);
        self.slip.iter_mut().for_each(|m| *m = 0.0);
        self.sum_forces = 0.0;
        self.k_free_pos = self.total_k;
        self.k_free_neg = self.total_k;
    }

    /// The default linearly implicit step, with the reciprocal of its denominator cached (the
    /// tangent stiffness only changes when a block changes mode).
    #[inline]
    fn advance_coupled(&mut self, c: &Coupling, dt: f64) -> f64 {
        let trial = fma(-c.dx_per_newton, self.sum_forces, c.free_dx);
        let inv_dt = self.inv_dt(dt);
        let k = if trial >= 0.0 { self.k_free_pos } else { self.k_free_neg } + self.sigma * inv_dt;
        if k != self.coupling_memo.0 || c.dx_per_newton != self.coupling_memo.1 {
            self.coupling_memo = (k, c.dx_per_newton, 1.0 / (1.0 + c.dx_per_newton * k));
        }
        self.advance(trial * self.coupling_memo.2, dt)
    }
}

// ---------------------------------------------------------------------------------------------
// Maxwell-slip (elasto-plastic blocks with constant break forces)
// ---------------------------------------------------------------------------------------------

/// Plain Maxwell-slip: N blocks with stiffness `k_i` that slip instantly at a constant `w_i` (N).
#[derive(Debug, Clone, PartialEq)]
pub struct MaxwellSlip {
    pub k: Vec<f64>,
    pub w: Vec<f64>,
    pub sigma: f64,
    forces: Vec<f64>,
}

impl MaxwellSlip {
    pub fn new(k: Vec<f64>, w: Vec<f64>, sigma: f64) -> Result<Self> {
        check::finite_array("k", &k, 1)?;
        if let Some(&bad) = k.iter().find(|&&x| x <= 0.0) {
            return Err(CoreError::NotPositive { name: "k", value: bad });
        }
        check::same_len("w", &w, "k", k.len())?;
        check::finite_array("w", &w, 1)?;
        if let Some(&bad) = w.iter().find(|&&x| x < 0.0) {
            return Err(CoreError::Negative { name: "w", value: bad });
        }
        check::non_negative("sigma", sigma)?;
        let n = k.len();
        Ok(Self { k, w, sigma, forces: vec![0.0; n] })
    }
}

impl FrictionElement for MaxwellSlip {
    fn force(&self) -> f64 {
        self.forces.iter().sum()
    }
    #[inline]
    fn advance(&mut self, dx: f64, dt: f64) -> f64 {
        let mut total = 0.0;
        for i in 0..self.k.len() {
            let f = (self.forces[i] + self.k[i] * dx).clamp(-self.w[i], self.w[i]);
            self.forces[i] = f;
            total += f;
        }
        total + self.sigma * dx / dt
    }
    fn tangent_stiffness(&self, direction: f64, dt: f64) -> f64 {
        let mut k = 0.0;
        for i in 0..self.k.len() {
            if self.forces[i] * direction < self.w[i] {
                k += self.k[i];
            }
        }
        k + self.sigma / dt
    }
    fn reset(&mut self) {
        self.forces.iter_mut().for_each(|f| *f = 0.0);
    }
}

// ---------------------------------------------------------------------------------------------
// LuGre
// ---------------------------------------------------------------------------------------------

/// LuGre model: `dz/dt = v - sigma0 |v| z / s(v)`, `F = sigma0 z + sigma1 dz/dt + sigma2 v`.
#[derive(Debug, Clone)]
pub struct LuGre {
    pub stribeck: Stribeck,
    /// Bristle stiffness (N/m).
    pub sigma0: f64,
    /// Bristle damping (N s/m).
    pub sigma1: f64,
    /// Viscous coefficient (N s/m).
    pub sigma2: f64,
    z: f64,
    last_force: f64,
}

impl LuGre {
    pub fn new(stribeck: Stribeck, sigma0: f64, sigma1: f64, sigma2: f64) -> Result<Self> {
        check::positive("sigma0", sigma0)?;
        check::non_negative("sigma1", sigma1)?;
        check::non_negative("sigma2", sigma2)?;
        if stribeck.fc <= 0.0 && stribeck.fs <= 0.0 {
            return Err(CoreError::InvalidParameter { name: "stribeck", reason: "LuGre needs a positive friction level (fc or fs > 0)".into() });
        }
        Ok(Self { stribeck, sigma0, sigma1, sigma2, z: 0.0, last_force: 0.0 })
    }

    /// Bristle deflection (m).
    pub fn deflection(&self) -> f64 {
        self.z
    }
}

impl FrictionElement for LuGre {
    fn force(&self) -> f64 {
        self.last_force
    }
    fn advance(&mut self, dx: f64, dt: f64) -> f64 {
        let v = dx / dt;
        let z0 = self.z;
        if v != 0.0 {
            // Linear in z at constant v: exact exponential approach to the steady deflection.
            let g = self.stribeck.eval(v).max(f64::MIN_POSITIVE);
            let z_ss = v.signum() * g / self.sigma0;
            let rate = self.sigma0 * v.abs() / g;
            self.z = z_ss + (z0 - z_ss) * (-rate * dt).exp();
        }
        let zdot_mean = (self.z - z0) / dt;
        self.last_force = self.sigma0 * self.z + self.sigma1 * zdot_mean + self.sigma2 * v;
        self.last_force
    }
    fn tangent_stiffness(&self, direction: f64, dt: f64) -> f64 {
        let g = self.stribeck.max_level().max(f64::MIN_POSITIVE);
        let dz_dx = (1.0 - direction * self.sigma0 * self.z / g).clamp(0.0, 1.0);
        (self.sigma0 + self.sigma1 / dt) * dz_dx + self.sigma2 / dt
    }
    fn reset(&mut self) {
        self.z = 0.0;
        self.last_force = 0.0;
    }
}

// ---------------------------------------------------------------------------------------------
// Model enum: dispatch once, outside the inner loops
// ---------------------------------------------------------------------------------------------

/// Any friction model of the core. Simulators `match` on this once and run a loop monomorphised
/// for the concrete type, so there is no dynamic dispatch per step.
#[derive(Debug, Clone)]
pub enum FrictionModel {
    Static(StaticElement),
    Gms(Gms),
    MaxwellSlip(MaxwellSlip),
    LuGre(LuGre),
}

/// Run `$body` with `$f` bound to the concrete element inside a [`FrictionModel`].
#[macro_export]
macro_rules! with_friction {
    ($model:expr, $f:ident => $body:expr) => {
        match $model {
            $crate::friction::FrictionModel::Static($f) => $body,
            $crate::friction::FrictionModel::Gms($f) => $body,
            $crate::friction::FrictionModel::MaxwellSlip($f) => $body,
            $crate::friction::FrictionModel::LuGre($f) => $body,
        }
    };
}

impl FrictionModel {
    pub fn reset(&mut self) {
        with_friction!(self, f => f.reset())
    }

    /// Elements updated per step (blocks of a multi-block model, 1 otherwise): the step's cost
    /// grows with it.
    pub fn elements(&self) -> usize {
        match self {
            FrictionModel::Gms(g) => g.n_blocks().max(1),
            FrictionModel::MaxwellSlip(m) => m.k.len().max(1),
            FrictionModel::Static(_) | FrictionModel::LuGre(_) => 1,
        }
    }
}

/// Friction force along a measured position trajectory `x(t)`.
///
/// `t` must increase strictly; `out[0]` is the force of the virgin state (the static map uses the
/// first interval's velocity), `out[k]` the force at `t[k]` after moving from `x[k-1]` to `x[k]`.
pub fn simulate_position<F: FrictionElement>(f: &mut F, t: &[f64], x: &[f64]) -> Result<Vec<f64>> {
    check::increasing("t", t, 2)?;
    check::same_len("position", x, "t", t.len())?;
    check::finite_array("position", x, 2)?;
    let mut out = Vec::with_capacity(t.len());
    out.push(first_force(f, t[1] - t[0], x[1] - x[0]));
    for k in 1..t.len() {
        out.push(f.advance(x[k] - x[k - 1], t[k] - t[k - 1]));
    }
    finite_forces(out, |k| t[k] - t[0])
}

/// The forces, or the first non-finite one as an error (a position step or a parameter beyond
/// the model's finite range).
fn finite_forces(out: Vec<f64>, time: impl Fn(usize) -> f64) -> Result<Vec<f64>> {
    match out.iter().position(|v| !v.is_finite()) {
        None => Ok(out),
        Some(step) => Err(CoreError::NonFiniteOutput { quantity: "friction force", step, time: time(step), hint: "the motion or the model's parameters are beyond its finite range" }),
    }
}

/// Friction force along a velocity trajectory sampled at a constant step `dt` (velocity held
/// constant over each step, zero-order hold).
pub fn simulate_velocity<F: FrictionElement>(f: &mut F, dt: f64, v: &[f64]) -> Result<Vec<f64>> {
    check::positive("dt", dt)?;
    check::finite_array("velocity", v, 1)?;
    let mut out = Vec::with_capacity(v.len());
    for &vk in v {
        out.push(f.advance(vk * dt, dt));
    }
    finite_forces(out, |k| k as f64 * dt)
}

fn first_force<F: FrictionElement>(f: &mut F, dt: f64, dx: f64) -> f64 {
    f.initial_force(dx / dt)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polynomial_slip_decay_matches_division_and_exp() {
        let dt = 1e-4;
        let mut fast = crate::reference::paper_gms();
        let mut exact = crate::reference::paper_gms();
        exact.decay_fit = (dt, u32::MAX, None); // steady step but no polynomial: exact path
        let (mut worst, mut scale) = (0.0f64, 0.0f64);
        let mut x_prev = 0.0;
        for k in 1..200_000 {
            let x = 30e-6 * (2.0 * std::f64::consts::PI * 2.0 * k as f64 * dt).sin();
            let (a, b) = (fast.advance(x - x_prev, dt), exact.advance(x - x_prev, dt));
            worst = worst.max((a - b).abs());
            scale = scale.max(b.abs());
            x_prev = x;
        }
        assert!(fast.decay_fit.2.is_some(), "the polynomial should be in use");
        assert!(worst <= 1e-13 * scale, "max difference {worst} on forces up to {scale}");
    }
}

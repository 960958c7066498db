//! Parameters of one closed-loop run, taken from the core's own types so that every kernel here
//! runs exactly the core's problem (plant discretised by `gms_core`, PID coefficients as the core
//! computes them, GMS Stribeck cut-off as the core computes it).

use crate::poly::DecayPoly;
use gms_core::numeric::UnitIntervalPoly;
use gms_core::{Pid, Plant};

#[derive(Debug, Clone, Copy)]
pub struct Axis {
    pub p00: f64,
    pub p01: f64,
    pub p10: f64,
    pub p11: f64,
    pub go0: f64,
    pub go1: f64,
    pub gn0: f64,
    pub gn1: f64,
    pub gf0: f64,
    pub gf1: f64,
    /// Whole steps of input delay.
    pub m: usize,
    pub dt: f64,
    pub inv_dt: f64,
}

impl Axis {
    pub fn new(plant: &Plant, dt: f64) -> Self {
        let d = plant.discretize(dt).expect("valid plant");
        Self {
            p00: d.phi[(0, 0)],
            p01: d.phi[(0, 1)],
            p10: d.phi[(1, 0)],
            p11: d.phi[(1, 1)],
            go0: d.gamma_old[0],
            go1: d.gamma_old[1],
            gn0: d.gamma_new[0],
            gn1: d.gamma_new[1],
            gf0: d.gamma_force[0],
            gf1: d.gamma_force[1],
            m: d.delay_steps,
            dt,
            inv_dt: 1.0 / dt,
        }
    }
}

/// PID coefficients exactly as `gms_core::Pid::new` derives them.
#[derive(Debug, Clone, Copy)]
pub struct PidP {
    pub kp: f64,
    pub ki: f64,
    pub ki_dt: f64,
    pub d_keep: f64,
    pub d_gain: f64,
    pub u_min: f64,
    pub u_max: f64,
}

impl PidP {
    pub fn from_core(p: &Pid) -> Self {
        let inv = 1.0 / (p.tf + p.dt);
        Self { kp: p.kp, ki: p.ki, ki_dt: p.ki * p.dt, d_keep: p.tf * inv, d_gain: p.kd * inv, u_min: p.u_min, u_max: p.u_max }
    }
}

/// GMS parameters (Stribeck shape delta = 1 only, time slip law only: the paper's model).
#[derive(Debug, Clone)]
pub struct GmsP {
    pub fc: f64,
    pub fs: f64,
    /// `fs - fc` (signed, as the core).
    pub dip: f64,
    pub inv_vs: f64,
    /// Stribeck exponent beyond which `s == fc` exactly (the core's `p_cut`).
    pub p_cut: f64,
    pub c: f64,
    pub sigma: f64,
    pub k: Vec<f64>,
    pub alpha: Vec<f64>,
    pub total_k: f64,
    /// The core's decay polynomial (monomials in `2E - 1`).
    pub poly_t: Option<UnitIntervalPoly>,
    /// The same fit with monomials in `E`.
    pub poly_e: DecayPoly,
}

impl GmsP {
    pub fn from_core(g: &gms_core::Gms, dt: f64) -> Self {
        let st = g.stribeck;
        assert_eq!(st.delta, 1.0, "prototype: delta = 1 only");
        assert_eq!(g.slip_law, gms_core::SlipLaw::Time, "prototype: time slip law only");
        let (fc, fs, c) = (st.fc, st.fs, g.c);
        let decay = |e: f64| (-(c / gms_core::numeric::fma(fs - fc, e, fc)) * dt).exp();
        Self {
            fc,
            fs,
            dip: fs - fc,
            inv_vs: 1.0 / st.vs,
            p_cut: exponent_cut(fc, fs),
            c,
            sigma: g.sigma,
            k: g.k.clone(),
            alpha: g.alpha.clone(),
            total_k: g.k.iter().sum(),
            poly_t: UnitIntervalPoly::fit(decay, 4e-15),
            // The core's 4e-15 acceptance is at the rounding level of the fit itself and fails for
            // some levels (fc x0.6 of the paper: the core then falls back to division + exp);
            // the lanes need a polynomial in every lane, so accept 1e-14 there.
            poly_e: DecayPoly::fit(decay, 4e-15).or_else(|| DecayPoly::fit(decay, 1e-14)).expect("decay polynomial in E within 1e-14"),
        }
    }

    /// The same model with the Stribeck levels scaled by `level` (a friction-level sweep).
    pub fn scaled(g: &gms_core::Gms, level: f64, dt: f64) -> Self {
        let st = gms_core::Stribeck::new(g.stribeck.fc * level, g.stribeck.fs * level, g.stribeck.vs, g.stribeck.delta).unwrap();
        let g2 = gms_core::Gms::new(st, g.k.clone(), g.alpha.clone(), g.c, g.sigma, g.slip_law).unwrap();
        Self::from_core(&g2, dt)
    }
}

/// Copy of `gms_core::Stribeck::exponent_cut` (private there).
pub fn exponent_cut(fc: f64, fs: f64) -> f64 {
    let dip = (fs - fc).abs();
    if dip == 0.0 {
        return f64::NEG_INFINITY;
    }
    if fc < f64::MIN_POSITIVE || !fc.is_finite() {
        return f64::INFINITY;
    }
    let ulp = f64::from_bits(fc.to_bits() + 1) - fc;
    (dip * 16.0 / ulp).ln()
}

/// Ring buffer length: a power of two holding the current input and the `m + 1` before it.
pub fn ring_len(m: usize) -> usize {
    (m + 2).next_power_of_two()
}

//! Stribeck curve and the static friction map (paper eq. 2).

use crate::error::{check, CoreError, Result};

/// Stribeck curve `s(v) = fc + (fs - fc) * exp(-|v / vs|^delta)` (N).
///
/// `s(0) = fs` is the break-away (static) level, `s(inf) = fc` the Coulomb level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stribeck {
    /// Coulomb level (N).
    pub fc: f64,
    /// Static (break-away) level (N).
    pub fs: f64,
    /// Stribeck velocity (m/s).
    pub vs: f64,
    /// Shape exponent (1 = exponential, 2 = Gaussian).
    pub delta: f64,
    inv_vs: f64,
    /// Beyond this exponent `(fs - fc) exp(-p)` is below a quarter of the spacing of doubles
    /// around `fc`, so `s = fc` exactly and the exponential can be skipped without changing a bit.
    p_cut: f64,
}

impl Stribeck {
    /// Validated constructor.
    pub fn new(fc: f64, fs: f64, vs: f64, delta: f64) -> Result<Self> {
        check::non_negative("fc", fc)?;
        check::non_negative("fs", fs)?;
        check::positive("vs", vs)?;
        check::positive("delta", delta)?;
        Ok(Self { fc, fs, vs, delta, inv_vs: 1.0 / vs, p_cut: Self::exponent_cut(fc, fs) })
    }

    /// The exponent `p` above which `fc + (fs - fc) exp(-p)` rounds to `fc` (with a factor-16
    /// margin for the rounding of `exp` and of the product); `inf` when `fc` is zero or subnormal.
    fn exponent_cut(fc: f64, fs: f64) -> f64 {
        let dip = (fs - fc).abs();
        if dip == 0.0 {
            return f64::NEG_INFINITY; // s(v) = fc + 0 * exp(-p) = fc for every finite p
        }
        if fc < f64::MIN_POSITIVE || !fc.is_finite() {
            return f64::INFINITY;
        }
        // Spacing of doubles just below fc is at least ulp(fc) / 2: a term below ulp(fc) / 4 is
        // lost in either direction under round-to-nearest. Require dip * exp(-p) <= ulp(fc) / 16.
        let ulp = f64::from_bits(fc.to_bits() + 1) - fc;
        (dip * 16.0 / ulp).ln()
    }

    /// A curve with no Stribeck dip: `s(v) = level` for every v.
    pub fn constant(level: f64) -> Result<Self> {
        Self::new(level, level, 1.0, 1.0)
    }

    /// `s(v)`.
    #[inline(always)]
    pub fn eval(&self, v: f64) -> f64 {
        self.eval_with_exp(v).0
    }

    /// `(s(v), E)` with `s = fc + (fs - fc) E` and `E = exp(-|v/vs|^delta)` (0 where it cannot
    /// change `s`). The common shapes delta = 1 and 2 avoid `powf`.
    #[inline(always)]
    pub fn eval_with_exp(&self, v: f64) -> (f64, f64) {
        let r = (v * self.inv_vs).abs();
        let p = if self.delta == 1.0 {
            r
        } else if self.delta == 2.0 {
            r * r
        } else {
            r.powf(self.delta)
        };
        if p > self.p_cut {
            return (self.fc, 0.0);
        }
        let e = (-p).exp();
        (crate::numeric::fma(self.fs - self.fc, e, self.fc), e)
    }

    /// The exponent `p = |v / vs|^delta` beyond which `s(v) == fc` exactly (`-inf` for a flat
    /// curve, `inf` when `fc` is zero).
    pub fn settled_exponent(&self) -> f64 {
        self.p_cut
    }

    /// The largest value of `s` (the level a sticking contact can hold).
    pub fn max_level(&self) -> f64 {
        self.fs.max(self.fc)
    }
}

/// Static friction map `F(v) = sign(v) s(v) + sigma v` (paper eq. 2), plus a constant `offset`
/// force that does not depend on motion (an unbalanced load, a drive offset).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticFriction {
    pub stribeck: Stribeck,
    /// Viscous coefficient (N s/m).
    pub sigma: f64,
    /// Motion-independent force (N) added to the map.
    pub offset: f64,
    /// Linear-region velocity threshold (m/s), as in Simulink/Simscape friction blocks: below it
    /// the map is replaced by the straight line through the origin and `F(v_linear)`, so the
    /// contact cannot stick. `0` (default) keeps the true set-valued stiction at `v = 0`.
    pub v_linear: f64,
}

impl StaticFriction {
    pub fn new(stribeck: Stribeck, sigma: f64) -> Result<Self> {
        check::non_negative("sigma", sigma)?;
        Ok(Self { stribeck, sigma, offset: 0.0, v_linear: 0.0 })
    }

    /// Same map with a constant force `offset` (N) added.
    pub fn with_offset(mut self, offset: f64) -> Result<Self> {
        self.offset = check::finite("offset", offset)?;
        Ok(self)
    }

    /// Same map regularised below `v_linear` (m/s), see [`StaticFriction::v_linear`].
    pub fn with_linear_region(mut self, v_linear: f64) -> Result<Self> {
        self.v_linear = check::non_negative("v_linear", v_linear)?;
        if v_linear > 0.0 && !self.linear_region_slope().is_finite() {
            return Err(CoreError::InvalidParameter {
                name: "v_linear",
                reason: format!("{} m/s is too small: the slope of the linear region, F(v_linear) / v_linear, overflows", crate::error::Num(v_linear)),
            });
        }
        Ok(self)
    }

    /// Slope of the linear region `F(v_linear) / v_linear` (N s/m), without the offset.
    pub fn linear_region_slope(&self) -> f64 {
        self.linear_region_slope_shifted(1.0, &LevelShift::NONE)
    }

    /// The linear region's slope for motion in direction `dir` under `shift`.
    pub fn linear_region_slope_shifted(&self, dir: f64, shift: &LevelShift) -> f64 {
        let (level, sigma) = self.direction_levels(dir, shift);
        ((self.stribeck.eval(self.v_linear) + level).max(0.0) + sigma * self.v_linear) / self.v_linear
    }

    /// The level a sticking contact holds against a push in direction `dir` (N): the curve at
    /// rest, `s(0) = fs` (below the Coulomb level when friction rises with speed).
    pub fn breakaway_shifted(&self, dir: f64, shift: &LevelShift) -> f64 {
        (self.stribeck.fs + self.direction_levels(dir, shift).0).max(0.0)
    }

    /// `(level shift, viscous coefficient)` for motion in direction `dir` (+1 / -1); the
    /// viscous coefficient never goes below zero (friction cannot push).
    #[inline(always)]
    pub fn direction_levels(&self, dir: f64, shift: &LevelShift) -> (f64, f64) {
        if dir >= 0.0 {
            (shift.level_pos, (self.sigma + shift.viscous_pos).max(0.0))
        } else {
            (shift.level_neg, (self.sigma + shift.viscous_neg).max(0.0))
        }
    }

    /// `F(v)`; zero velocity gives the offset only (the set-valued stiction is resolved by the
    /// closed-loop coupling, see [`crate::friction::FrictionElement::advance_coupled`]).
    #[inline(always)]
    pub fn force(&self, v: f64) -> f64 {
        self.force_shifted(v, &LevelShift::NONE)
    }

    /// `F(v)` with the Coulomb/viscous levels shifted per direction.
    #[inline(always)]
    pub fn force_shifted(&self, v: f64, shift: &LevelShift) -> f64 {
        if v == 0.0 {
            return self.offset;
        }
        let dir = if v > 0.0 { 1.0 } else { -1.0 };
        if v.abs() < self.v_linear {
            return self.linear_region_slope_shifted(dir, shift) * v + self.offset;
        }
        let (level, sigma) = self.direction_levels(dir, shift);
        dir * (self.stribeck.eval(v) + level).max(0.0) + sigma * v + self.offset
    }

    /// Evaluate the map on many velocities.
    pub fn force_many(&self, v: &[f64]) -> Result<Vec<f64>> {
        check::finite_array("v", v, 1)?;
        Ok(v.iter().map(|&x| self.force(x)).collect())
    }
}

/// Per-direction shifts of a static map's levels for one step: the Coulomb/Stribeck level of
/// motion in the positive (negative) direction becomes `s(v) + level_pos` (`s(v) + level_neg`),
/// the viscous coefficient `sigma + viscous_pos` (`sigma + viscous_neg`), each floored at zero.
/// Position- and time-dependent friction and direction asymmetry are expressed this way.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LevelShift {
    pub level_pos: f64,
    pub level_neg: f64,
    pub viscous_pos: f64,
    pub viscous_neg: f64,
}

impl LevelShift {
    pub const NONE: LevelShift = LevelShift { level_pos: 0.0, level_neg: 0.0, viscous_pos: 0.0, viscous_neg: 0.0 };
}

/// Validate that fractions are non-negative and sum to one (GMS `alpha`).
pub(crate) fn check_fractions(name: &'static str, alpha: &[f64]) -> Result<()> {
    check::finite_array(name, alpha, 1)?;
    if let Some(&a) = alpha.iter().find(|&&a| a < 0.0) {
        return Err(CoreError::Negative { name, value: a });
    }
    let sum: f64 = alpha.iter().sum();
    if (sum - 1.0).abs() > 1e-6 {
        return Err(CoreError::InvalidParameter {
            name,
            reason: format!("fractions must sum to 1, got {sum:.6} (scale break forces w_i by their sum to get fractions)"),
        });
    }
    Ok(())
}

//! `gmsfric._gmsfric`: the thin PyO3 layer over `gms-core`.
//!
//! It only extracts inputs (numpy arrays are borrowed, not copied), calls the core with the GIL
//! released, and converts results (vectors move into numpy arrays without a copy). No physics,
//! and no argument rules: every model is validated by the core's constructors, whose typed errors
//! become the package's exceptions in `errors.rs`.

mod errors;
mod run;

use errors::{to_pyerr, IntoPy};
use gms_core as core;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

/// Borrow a numpy array as a slice without copying (the Python layer makes arrays contiguous
/// float64 first, which is free when they already are).
fn slice<'a>(name: &'static str, a: &'a PyReadonlyArray1<'_, f64>) -> PyResult<&'a [f64]> {
    a.as_slice().map_err(|_| to_pyerr(core::CoreError::InvalidParameter { name, reason: "must be a contiguous float64 array".into() }))
}

fn stribeck(fc: f64, fs: f64, vs: f64, delta: f64) -> PyResult<core::Stribeck> {
    core::Stribeck::new(fc, fs, vs, delta).py()
}

/// A validated friction model of the core (opaque; built by the Python model classes).
#[pyclass(frozen, module = "gmsfric._gmsfric")]
#[derive(Clone)]
pub struct FrictionSpec {
    model: core::FrictionModel,
}

#[pymethods]
impl FrictionSpec {
    #[staticmethod]
    #[pyo3(signature = (fc, fs, vs, delta, sigma, offset=0.0, v_linear=0.0))]
    #[allow(clippy::too_many_arguments)]
    fn static_map(fc: f64, fs: f64, vs: f64, delta: f64, sigma: f64, offset: f64, v_linear: f64) -> PyResult<Self> {
        let map = core::StaticFriction::new(stribeck(fc, fs, vs, delta)?, sigma).py()?.with_offset(offset).py()?.with_linear_region(v_linear).py()?;
        Ok(Self { model: core::FrictionModel::Static(core::StaticElement::new(map)) })
    }

    #[staticmethod]
    #[pyo3(signature = (fc, fs, vs, delta, k, alpha, c, sigma, slip_law="time"))]
    #[allow(clippy::too_many_arguments)]
    fn gms(fc: f64, fs: f64, vs: f64, delta: f64, k: Vec<f64>, alpha: Vec<f64>, c: f64, sigma: f64, slip_law: &str) -> PyResult<Self> {
        let law = match slip_law {
            "time" => core::SlipLaw::Time,
            "displacement" => core::SlipLaw::Displacement,
            other => {
                return Err(core::CoreError::InvalidParameter { name: "slip_law", reason: format!("must be 'time' or 'displacement', got '{other}'") }).py()
            }
        };
        let g = core::Gms::new(stribeck(fc, fs, vs, delta)?, k, alpha, c, sigma, law).py()?;
        Ok(Self { model: core::FrictionModel::Gms(g) })
    }

    #[staticmethod]
    fn maxwell_slip(k: Vec<f64>, w: Vec<f64>, sigma: f64) -> PyResult<Self> {
        Ok(Self { model: core::FrictionModel::MaxwellSlip(core::MaxwellSlip::new(k, w, sigma).py()?) })
    }

    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn lugre(fc: f64, fs: f64, vs: f64, delta: f64, sigma0: f64, sigma1: f64, sigma2: f64) -> PyResult<Self> {
        Ok(Self { model: core::FrictionModel::LuGre(core::LuGre::new(stribeck(fc, fs, vs, delta)?, sigma0, sigma1, sigma2).py()?) })
    }

    /// The static map `F(v)` (memoryless) on an array of velocities (static maps only).
    fn static_force<'py>(&self, py: Python<'py>, v: PyReadonlyArray1<'py, f64>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let core::FrictionModel::Static(map) = &self.model else {
            return Err(core::CoreError::InvalidParameter { name: "model", reason: "the memoryless map F(v) exists for static maps only".into() }).py();
        };
        let v = slice("v", &v)?;
        let out = py.detach(|| map.map.force_many(v)).py()?;
        // A memoryless map has no run to blame: name the velocity that leaves the finite range.
        if let Some(i) = out.iter().position(|f| !f.is_finite()) {
            let reason = format!("{} m/s at index {i} gives a non-finite force (beyond the map's finite range)", core::error::Num(v[i]));
            return Err(core::CoreError::InvalidParameter { name: "v", reason }).py();
        }
        Ok(out.into_pyarray(py))
    }
}

/// A validated controller of the core (its gains; the sample time comes from the run).
#[pyclass(frozen, module = "gmsfric._gmsfric")]
#[derive(Clone)]
pub struct ControllerSpec {
    model: core::ControllerModel,
}

#[pymethods]
impl ControllerSpec {
    #[staticmethod]
    fn pid(kp: f64, ki: f64, kd: f64, tf: f64, u_min: f64, u_max: f64) -> PyResult<Self> {
        Ok(Self { model: core::ControllerModel::Pid(core::Pid::new(kp, ki, kd, tf, u_min, u_max).py()?) })
    }

    #[staticmethod]
    fn cascade(kp: f64, kv: f64, u_min: f64, u_max: f64) -> PyResult<Self> {
        Ok(Self { model: core::ControllerModel::Cascade(core::Cascade::new(kp, kv, u_min, u_max).py()?) })
    }

    /// PID plus a disturbance observer with the nominal plant `a / (s^2 + b s + c)`, input
    /// `delay` and a Q-filter `1 / (tau s + 1)^2` of cutoff `dob_cutoff_hz`.
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn pid_dob(kp: f64, ki: f64, kd: f64, tf: f64, u_min: f64, u_max: f64, a: f64, b: f64, c: f64, delay: f64, dob_cutoff_hz: f64) -> PyResult<Self> {
        let pid = core::Pid::new(kp, ki, kd, tf, u_min, u_max).py()?;
        Ok(Self { model: core::ControllerModel::PidDob(core::PidDob::new(pid, a, b, c, delay, dob_cutoff_hz).py()?) })
    }
}

/// A validated plant `a / (s^2 + b s + c)` with input delay and force gain.
#[pyclass(frozen, module = "gmsfric._gmsfric")]
#[derive(Clone)]
pub struct PlantSpec {
    plant: core::Plant,
}

#[pymethods]
impl PlantSpec {
    #[new]
    fn new(a: f64, b: f64, c: f64, delay: f64, force_gain: f64) -> PyResult<Self> {
        Ok(Self { plant: core::Plant::new(a, b, c, delay, force_gain).py()? })
    }

    /// Exact ZOH discretisation at `dt`: `(phi (2x2 row-major), gamma_old, gamma_new,
    /// gamma_force, delay_steps)`, the fractional delay split between the two input gains.
    fn discretize(&self, dt: f64) -> PyResult<(Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>, usize)> {
        let d = self.plant.discretize(dt).py()?;
        let phi = vec![d.phi[(0, 0)], d.phi[(0, 1)], d.phi[(1, 0)], d.phi[(1, 1)]];
        Ok((phi, d.gamma_old.as_slice().to_vec(), d.gamma_new.as_slice().to_vec(), d.gamma_force.as_slice().to_vec(), d.delay_steps))
    }
}

/// A position series `g(q)`: `kind` is "legendre" (`lo`, `hi`, `coef` from P0), "fourier"
/// (`periods`, `harmonics`, `coef` as (sin, cos) pairs) or "table" (`q0`, `dq`, `values`).
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
struct SeriesArgs {
    kind: String,
    #[pyo3(default)]
    lo: f64,
    #[pyo3(default)]
    hi: f64,
    #[pyo3(default)]
    coef: Vec<f64>,
    #[pyo3(default)]
    linear_beyond: bool,
    #[pyo3(default)]
    periods: Vec<f64>,
    #[pyo3(default)]
    harmonics: usize,
    #[pyo3(default)]
    q0: f64,
    #[pyo3(default)]
    dq: f64,
    #[pyo3(default)]
    values: Vec<f64>,
}

fn series(name: &'static str, a: Option<SeriesArgs>) -> PyResult<Option<core::PositionSeries>> {
    let Some(a) = a else { return Ok(None) };
    let s = match a.kind.as_str() {
        "legendre" => core::PositionSeries::Legendre { lo: a.lo, hi: a.hi, coef: a.coef, linear_beyond: a.linear_beyond },
        "fourier" => core::PositionSeries::Fourier { periods: a.periods, harmonics: a.harmonics, coef: a.coef },
        "table" => core::PositionSeries::Table { q0: a.q0, dq: a.dq, values: a.values },
        other => return Err(core::CoreError::InvalidParameter { name, reason: format!("unknown series kind '{other}' (legendre, fourier, table)") }).py(),
    };
    s.check().py()?;
    Ok(Some(s))
}

/// A validated axis: plant, friction model and effects, simulated together by the core.
#[pyclass(frozen, module = "gmsfric._gmsfric")]
#[derive(Clone)]
pub struct AxisSpec {
    axis: core::Axis,
}

#[pymethods]
impl AxisSpec {
    /// `asymmetry = (d_level, d_viscous)`; `drift = (shape, scale_s, d_level, d_viscous)` with
    /// shape "linear" (scale = the run's duration) or "exponential" (scale = tau);
    /// `heating = (tau, d_level, d_viscous)`; `blocks = (k, w)`; `compliance = (mass, fn_hz,
    /// zeta)`; series as [`SeriesArgs`].
    #[new]
    #[pyo3(signature = (plant, friction=None, *, asymmetry=None, position_force=None, position_friction=None, drift=None, heating=None, blocks=None, compliance=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        plant: &PlantSpec,
        friction: Option<&FrictionSpec>,
        asymmetry: Option<(f64, f64)>,
        position_force: Option<SeriesArgs>,
        position_friction: Option<SeriesArgs>,
        drift: Option<(String, f64, f64, f64)>,
        heating: Option<(f64, f64, f64)>,
        blocks: Option<(Vec<f64>, Vec<f64>)>,
        compliance: Option<(f64, f64, f64)>,
    ) -> PyResult<Self> {
        let drift = match drift {
            None => None,
            Some((shape, scale, d_level, d_viscous)) => {
                let shape = match shape.as_str() {
                    "linear" => core::DriftShape::Linear { duration: scale },
                    "exponential" => core::DriftShape::Exponential { tau: scale },
                    other => return Err(core::CoreError::InvalidParameter { name: "drift", reason: format!("unknown shape '{other}' (linear, exponential)") }).py(),
                };
                Some(core::Drift { shape, d_level, d_viscous })
            }
        };
        let effects = core::Effects {
            asymmetry: asymmetry.map(|(d_level, d_viscous)| core::Asymmetry { d_level, d_viscous }),
            position_force: series("position_force", position_force)?,
            position_friction: series("position_friction", position_friction)?,
            drift,
            heating: heating.map(|(tau, d_level, d_viscous)| core::Heating { tau, d_level, d_viscous }),
            blocks: blocks.map(|(k, w)| core::MaxwellSlip::new(k, w, 0.0)).transpose().py()?,
            compliance: compliance.map(|(m, f, z)| core::Compliance::new(m, f, z)).transpose().py()?,
        };
        let effects = (!effects.is_empty()).then_some(effects);
        Ok(Self { axis: core::Axis::new(plant.plant, friction.map(|f| f.model.clone()), effects).py()? })
    }
}

#[pymodule]
fn _gmsfric(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<FrictionSpec>()?;
    m.add_class::<ControllerSpec>()?;
    m.add_class::<PlantSpec>()?;
    m.add_class::<AxisSpec>()?;
    m.add_function(wrap_pyfunction!(run::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(run::simulate_friction, m)?)?;
    m.add_function(wrap_pyfunction!(reference_data, m)?)?;
    m.add_function(wrap_pyfunction!(reference_values, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("LANES", core::lanes::LANES)?;
    Ok(())
}

/// The reference data file (JSON text) that the core's reference problems are built from.
#[pyfunction]
fn reference_data() -> &'static str {
    core::reference::DATA
}

/// The core's reference problems as it builds them, for the test that the Python presets read
/// the same numbers: `{name: [values...]}`.
#[pyfunction]
fn reference_values() -> Vec<(&'static str, Vec<f64>)> {
    use core::reference as r;
    let st = r::paper_stribeck();
    let map = r::paper_static();
    let g = r::paper_gms();
    let p = r::paper_plant();
    let pid = r::paper_pid();
    let ep = r::emps_plant();
    let ef = r::emps_friction();
    let ec = r::emps_controller();
    vec![
        ("paper_stribeck", vec![st.fc, st.fs, st.vs, st.delta]),
        ("paper_sigma", vec![map.sigma]),
        ("paper_gms_k", g.k.clone()),
        ("paper_gms_alpha", g.alpha.clone()),
        ("paper_gms_c", vec![g.c]),
        ("paper_plant", vec![p.a, p.b, p.c, p.delay, p.force_gain]),
        ("paper_pid", vec![pid.kp, pid.ki, pid.kd, pid.tf, pid.u_min, pid.u_max]),
        ("emps_plant", vec![ep.a, ep.b, ep.c, ep.delay, ep.force_gain]),
        ("emps_friction", vec![ef.stribeck.fc, ef.stribeck.fs, ef.sigma, ef.offset]),
        ("emps_controller", vec![ec.kp, ec.kv, ec.u_min, ec.u_max]),
    ]
}

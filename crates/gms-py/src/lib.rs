//! `gmsfric._gmsfric`: the thin PyO3 layer over `gms-core`.
//!
//! It only extracts inputs (numpy arrays are borrowed, not copied), calls the core with the GIL
//! released, and converts results (vectors move into numpy arrays without a copy). No physics.

mod batch;
mod errors;

use errors::IntoPy;
use gms_core as core;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Borrow a numpy array as a slice without copying (the Python layer makes arrays contiguous
/// float64 first, which is free when they already are).
fn slice<'a>(name: &str, a: &'a PyReadonlyArray1<'_, f64>) -> PyResult<&'a [f64]> {
    a.as_slice().map_err(|_| PyValueError::new_err(format!("`{name}` must be a contiguous float64 array")))
}

fn opt_slice<'a>(name: &str, a: &'a Option<PyReadonlyArray1<'_, f64>>) -> PyResult<Option<&'a [f64]>> {
    a.as_ref().map(|a| slice(name, a)).transpose()
}

/// A zeroed output vector. Long ones are pre-faulted in one system call on Linux
/// (`MADV_POPULATE_WRITE`): mapping the pages in bulk costs a fraction of taking one page fault
/// per 4 KiB while the simulation writes them. Harmless where unsupported (older kernels).
fn zeroed_output(n: usize) -> Vec<f64> {
    let v = vec![0.0f64; n];
    #[cfg(target_os = "linux")]
    if n >= (1 << 16) {
        const MADV_POPULATE_WRITE: libc::c_int = 23;
        let page = 4096usize;
        let start = v.as_ptr() as usize;
        let aligned = start.div_ceil(page) * page;
        let end = start + n * std::mem::size_of::<f64>();
        if end > aligned {
            // SAFETY: the range lies inside the vector's allocation, which we own; the advice
            // only maps (zero) pages, it does not change the contents.
            unsafe {
                libc::madvise(aligned as *mut libc::c_void, (end - aligned) / page * page, MADV_POPULATE_WRITE);
            }
        }
    }
    v
}

/// Run a long core call with the GIL released (one helper for every long call).
fn detached<T: Send>(py: Python<'_>, f: impl FnOnce() -> core::Result<T> + Send) -> PyResult<T> {
    py.detach(f).py()
}

fn stribeck(fc: f64, fs: f64, vs: f64, delta: f64) -> PyResult<core::Stribeck> {
    core::Stribeck::new(fc, fs, vs, delta).py()
}

#[allow(clippy::too_many_arguments)]
fn static_friction(fc: f64, fs: f64, vs: f64, delta: f64, sigma: f64, offset: f64, v_linear: f64) -> PyResult<core::StaticFriction> {
    core::StaticFriction::new(stribeck(fc, fs, vs, delta)?, sigma).py()?.with_offset(offset).py()?.with_linear_region(v_linear).py()
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
        let map = static_friction(fc, fs, vs, delta, sigma, offset, v_linear)?;
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
                return Err(core::CoreError::InvalidParameter {
                    name: "slip_law",
                    reason: format!("must be 'time' or 'displacement', got '{other}'"),
                })
                .py()
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

    /// Friction force along a position trajectory `x(t)` (starts from the virgin state).
    fn simulate_position<'py>(&self, py: Python<'py>, t: PyReadonlyArray1<'py, f64>, x: PyReadonlyArray1<'py, f64>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (t, x) = (slice("t", &t)?, slice("position", &x)?);
        let mut model = self.model.clone();
        let out = detached(py, || core::with_friction!(&mut model, f => core::simulate_position(f, t, x)))?;
        Ok(out.into_pyarray(py))
    }

    /// Friction force along a velocity trajectory held constant over steps of `dt`.
    fn simulate_velocity<'py>(&self, py: Python<'py>, dt: f64, v: PyReadonlyArray1<'py, f64>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let v = slice("velocity", &v)?;
        let mut model = self.model.clone();
        let out = detached(py, || core::with_friction!(&mut model, f => core::simulate_velocity(f, dt, v)))?;
        Ok(out.into_pyarray(py))
    }
}

/// The static map `F(v)` (memoryless) evaluated on an array of velocities.
#[pyfunction]
#[pyo3(signature = (fc, fs, vs, delta, sigma, v, offset=0.0, v_linear=0.0))]
#[allow(clippy::too_many_arguments)]
fn static_map_force<'py>(py: Python<'py>, fc: f64, fs: f64, vs: f64, delta: f64, sigma: f64, v: PyReadonlyArray1<'py, f64>, offset: f64, v_linear: f64) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let map = static_friction(fc, fs, vs, delta, sigma, offset, v_linear)?;
    let v = slice("v", &v)?;
    Ok(detached(py, || map.force_many(v))?.into_pyarray(py))
}

/// A validated controller of the core.
#[pyclass(frozen, module = "gmsfric._gmsfric")]
#[derive(Clone)]
pub struct ControllerSpec {
    model: core::ControllerModel,
}

#[pymethods]
impl ControllerSpec {
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn pid(kp: f64, ki: f64, kd: f64, tf: f64, u_min: f64, u_max: f64, dt: f64) -> PyResult<Self> {
        Ok(Self { model: core::ControllerModel::Pid(core::Pid::new(kp, ki, kd, tf, u_min, u_max, dt).py()?) })
    }

    #[staticmethod]
    fn cascade(kp: f64, kv: f64, u_min: f64, u_max: f64, dt: f64) -> PyResult<Self> {
        Ok(Self { model: core::ControllerModel::Cascade(core::Cascade::new(kp, kv, u_min, u_max, dt).py()?) })
    }

    /// PID plus a disturbance observer with the nominal plant `a / (s^2 + b s + c)`, input
    /// `delay` and a Q-filter `1 / (tau s + 1)^2` of cutoff `dob_cutoff_hz`.
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn pid_dob(kp: f64, ki: f64, kd: f64, tf: f64, u_min: f64, u_max: f64, dt: f64, a: f64, b: f64, c: f64, delay: f64, dob_cutoff_hz: f64) -> PyResult<Self> {
        let pid = core::Pid::new(kp, ki, kd, tf, u_min, u_max, dt).py()?;
        Ok(Self { model: core::ControllerModel::PidDob(core::control::PidDob::new(pid, a, b, c, delay, dob_cutoff_hz).py()?) })
    }
}

fn plant(p: (f64, f64, f64, f64, f64)) -> PyResult<core::Plant> {
    core::Plant::new(p.0, p.1, p.2, p.3, p.4).py()
}

/// Closed-loop run; returns a dict of numpy arrays (position, velocity, measured, command,
/// friction). `plant` is `(a, b, c, delay, force_gain)`.
#[pyfunction]
#[pyo3(signature = (plant_params, friction, controller, reference, dt, feedforward=None, input_disturbance=None, load_force=None, measurement_noise=None, quantization=0.0, drive_min=f64::NEG_INFINITY, drive_max=f64::INFINITY, initial_position=None, initial_velocity=0.0))]
#[allow(clippy::too_many_arguments)]
fn simulate_closed_loop<'py>(
    py: Python<'py>,
    plant_params: (f64, f64, f64, f64, f64),
    friction: Option<&FrictionSpec>,
    controller: &ControllerSpec,
    reference: PyReadonlyArray1<'py, f64>,
    dt: f64,
    feedforward: Option<PyReadonlyArray1<'py, f64>>,
    input_disturbance: Option<PyReadonlyArray1<'py, f64>>,
    load_force: Option<PyReadonlyArray1<'py, f64>>,
    measurement_noise: Option<PyReadonlyArray1<'py, f64>>,
    quantization: f64,
    drive_min: f64,
    drive_max: f64,
    initial_position: Option<f64>,
    initial_velocity: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let p = plant(plant_params)?;
    let mut input = core::ClosedLoopInput::new(slice("reference", &reference)?, dt);
    input.feedforward = opt_slice("feedforward", &feedforward)?;
    input.input_disturbance = opt_slice("input_disturbance", &input_disturbance)?;
    input.load_force = opt_slice("load_force", &load_force)?;
    input.measurement_noise = opt_slice("measurement_noise", &measurement_noise)?;
    input.quantization = quantization;
    input.drive_min = drive_min;
    input.drive_max = drive_max;
    if let Some(x0) = initial_position {
        input.initial_position = x0;
    }
    input.initial_velocity = initial_velocity;
    let mut fric = friction.map(|f| f.model.clone());
    let mut ctrl = controller.model.clone();
    // The core writes into zeroed vectors (calloc: pages appear as they are written), which then
    // become the numpy arrays without a copy.
    // Without noise or quantisation the measured position is the true one: not recorded twice
    // (the dict then has `measured = None`).
    let record_measured = input.measurement_noise.is_some() || input.quantization > 0.0;
    let n = input.reference.len();
    let mut out = core::ClosedLoopOutput {
        position: zeroed_output(n),
        velocity: zeroed_output(n),
        measured: if record_measured { zeroed_output(n) } else { Vec::new() },
        command: zeroed_output(n),
        friction: zeroed_output(n),
    };
    let mut buffers = out.buffers();
    if !record_measured {
        buffers.measured = None;
    }
    detached(py, || core::simulate_into(&p, fric.as_mut(), &mut ctrl, &input, buffers))?;
    let d = PyDict::new(py);
    d.set_item("position", out.position.into_pyarray(py))?;
    d.set_item("velocity", out.velocity.into_pyarray(py))?;
    d.set_item("measured", if record_measured { Some(out.measured.into_pyarray(py)) } else { None })?;
    d.set_item("command", out.command.into_pyarray(py))?;
    d.set_item("friction", out.friction.into_pyarray(py))?;
    Ok(d)
}

/// Open-loop plant response to `u` held over steps of `dt`; returns `(position, velocity)`.
#[pyfunction]
fn simulate_open_loop<'py>(py: Python<'py>, plant_params: (f64, f64, f64, f64, f64), dt: f64, u: PyReadonlyArray1<'py, f64>) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>)> {
    let p = plant(plant_params)?;
    let u = slice("u", &u)?;
    let (y, v) = detached(py, || core::simulate_open_loop(&p, dt, u))?;
    Ok((y.into_pyarray(py), v.into_pyarray(py)))
}

/// Exact discretisation: `(phi (2x2 row-major list), gamma_old, gamma_new, gamma_force, delay_steps)`.
#[pyfunction]
fn discretize_plant(plant_params: (f64, f64, f64, f64, f64), dt: f64) -> PyResult<(Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>, usize)> {
    let d = plant(plant_params)?.discretize(dt).py()?;
    let phi = vec![d.phi[(0, 0)], d.phi[(0, 1)], d.phi[(1, 0)], d.phi[(1, 1)]];
    Ok((phi, d.gamma_old.as_slice().to_vec(), d.gamma_new.as_slice().to_vec(), d.gamma_force.as_slice().to_vec(), d.delay_steps))
}

#[pymodule]
fn _gmsfric(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<FrictionSpec>()?;
    m.add_class::<ControllerSpec>()?;
    m.add_function(wrap_pyfunction!(static_map_force, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_closed_loop, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_open_loop, m)?)?;
    m.add_function(wrap_pyfunction!(discretize_plant, m)?)?;
    m.add_function(wrap_pyfunction!(batch::simulate_closed_loop_batch, m)?)?;
    m.add_function(wrap_pyfunction!(batch::simulate_friction_batch, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

//! Batch simulation: many runs in one call, spread over all cores by the core (rayon), with the
//! GIL released. Inputs are borrowed 2-D arrays (one row per run, or a single row shared by all
//! runs); outputs are stacked `n_runs x n_samples` arrays moved into numpy without a copy.
//!
//! Progress: the core counts finished runs in an atomic; this thread sleeps (GIL released) and
//! re-attaches every `poll_interval` seconds only to call the Python `progress(done, total)`
//! callback and to check for Ctrl-C, which cancels the runs that have not started.

use crate::errors::to_pyerr;
use crate::{plant, ControllerSpec, FrictionSpec};
use gms_core as core;
use gms_core::batch::{BatchError, BatchOptions, Job};
use numpy::{IntoPyArray, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

/// Rows of a 2-D input: `rows == 1` (shared) or `rows == n_runs`, contiguous float64.
struct Rows<'a> {
    data: &'a [f64],
    rows: usize,
    cols: usize,
}

impl<'a> Rows<'a> {
    fn new(name: &'static str, a: &'a PyReadonlyArray2<'_, f64>, n_runs: usize) -> PyResult<Self> {
        let shape = a.shape();
        let (rows, cols) = (shape[0], shape[1]);
        let data = a.as_slice().map_err(|_| {
            to_pyerr(core::CoreError::InvalidParameter { name, reason: "must be a C-contiguous float64 array".into() })
        })?;
        if rows != 1 && rows != n_runs {
            return Err(to_pyerr(core::CoreError::LengthMismatch { name, other: "runs", expected: n_runs, got: rows }));
        }
        Ok(Self { data, rows, cols })
    }

    fn row(&self, i: usize) -> &'a [f64] {
        let r = if self.rows == 1 { 0 } else { i };
        &self.data[r * self.cols..(r + 1) * self.cols]
    }
}

fn opt_rows<'a>(name: &'static str, a: &'a Option<PyReadonlyArray2<'_, f64>>, n_runs: usize) -> PyResult<Option<Rows<'a>>> {
    a.as_ref().map(|a| Rows::new(name, a, n_runs)).transpose()
}

/// `BatchError` -> the Python exception of the run's error, message prefixed by the run index.
fn batch_err(py: Python<'_>, e: BatchError, n_runs: usize) -> PyErr {
    let base = to_pyerr(e.error);
    let msg = format!("run {} (of {n_runs}) failed: {}", e.run, base.value(py));
    PyErr::from_type(base.get_type(py), msg)
}

/// Run `work` on a helper thread with the GIL released; every `interval` re-attach briefly to
/// report `progress(done, total)` and check signals (an exception there sets `cancel`).
fn run_polled<T: Send>(
    py: Python<'_>,
    total: usize,
    counter: &AtomicUsize,
    cancel: &AtomicBool,
    progress: Option<Py<PyAny>>,
    interval: f64,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    let interval = Duration::from_secs_f64(if interval.is_finite() && interval > 0.0 { interval.max(0.005) } else { 0.2 });
    let mut py_err: Option<PyErr> = None;
    let out = py.detach(|| {
        std::thread::scope(|s| {
            let waiter = std::thread::current();
            let worker = s.spawn(move || {
                let r = work();
                waiter.unpark();
                r
            });
            let mut last = usize::MAX;
            while !worker.is_finished() {
                std::thread::park_timeout(interval);
                if worker.is_finished() || py_err.is_some() {
                    continue;
                }
                Python::attach(|py| {
                    let res = py.check_signals().and_then(|()| {
                        let done = counter.load(Ordering::Relaxed);
                        match &progress {
                            Some(cb) if done != last => {
                                last = done;
                                cb.call1(py, (done, total)).map(|_| ())
                            }
                            _ => Ok(()),
                        }
                    });
                    if let Err(e) = res {
                        cancel.store(true, Ordering::Relaxed);
                        py_err = Some(e);
                    }
                });
            }
            worker.join().unwrap_or_else(|p| std::panic::resume_unwind(p))
        })
    });
    match py_err {
        Some(e) => Err(e),
        None => Ok(out),
    }
}

/// Many closed-loop runs on all cores. `plant_params`, `frictions`, `controllers` have one entry
/// per run; `reference` and the optional inputs are 2-D (one row per run, or one shared row).
/// Returns a dict of `n_runs x n_samples` arrays (position, velocity, measured, command,
/// friction). `threads=None` uses every core (or `RAYON_NUM_THREADS`).
#[pyfunction]
#[pyo3(signature = (plant_params, frictions, controllers, reference, dt, feedforward=None, input_disturbance=None, load_force=None, measurement_noise=None, quantization=0.0, drive_min=f64::NEG_INFINITY, drive_max=f64::INFINITY, initial_position=None, initial_velocity=0.0, threads=None, progress=None, poll_interval=0.2))]
#[allow(clippy::too_many_arguments)]
pub fn simulate_closed_loop_batch<'py>(
    py: Python<'py>,
    plant_params: Vec<(f64, f64, f64, f64, f64)>,
    frictions: Vec<Option<PyRef<'py, FrictionSpec>>>,
    controllers: Vec<PyRef<'py, ControllerSpec>>,
    reference: PyReadonlyArray2<'py, f64>,
    dt: f64,
    feedforward: Option<PyReadonlyArray2<'py, f64>>,
    input_disturbance: Option<PyReadonlyArray2<'py, f64>>,
    load_force: Option<PyReadonlyArray2<'py, f64>>,
    measurement_noise: Option<PyReadonlyArray2<'py, f64>>,
    quantization: f64,
    drive_min: f64,
    drive_max: f64,
    initial_position: Option<f64>,
    initial_velocity: f64,
    threads: Option<usize>,
    progress: Option<Py<PyAny>>,
    poll_interval: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let n_runs = plant_params.len();
    for (name, len) in [("frictions", frictions.len()), ("controllers", controllers.len())] {
        if len != n_runs {
            return Err(to_pyerr(core::CoreError::LengthMismatch { name, other: "plant_params", expected: n_runs, got: len }));
        }
    }
    let reference = Rows::new("reference", &reference, n_runs)?;
    let ff = opt_rows("feedforward", &feedforward, n_runs)?;
    let dist = opt_rows("input_disturbance", &input_disturbance, n_runs)?;
    let load = opt_rows("load_force", &load_force, n_runs)?;
    let noise = opt_rows("measurement_noise", &measurement_noise, n_runs)?;
    let mut jobs = Vec::with_capacity(n_runs);
    for i in 0..n_runs {
        let p = plant(plant_params[i]).map_err(|e| PyErr::from_type(e.get_type(py), format!("run {i}: {}", e.value(py))))?;
        let mut input = core::ClosedLoopInput::new(reference.row(i), dt);
        input.feedforward = ff.as_ref().map(|r| r.row(i));
        input.input_disturbance = dist.as_ref().map(|r| r.row(i));
        input.load_force = load.as_ref().map(|r| r.row(i));
        input.measurement_noise = noise.as_ref().map(|r| r.row(i));
        input.quantization = quantization;
        input.drive_min = drive_min;
        input.drive_max = drive_max;
        if let Some(x0) = initial_position {
            input.initial_position = x0;
        }
        input.initial_velocity = initial_velocity;
        jobs.push(Job {
            plant: p,
            friction: frictions[i].as_ref().map(|f| f.model.clone()),
            controller: controllers[i].model.clone(),
            input,
        });
    }
    let (counter, cancel) = (AtomicUsize::new(0), AtomicBool::new(false));
    let opts = BatchOptions { threads, progress: Some(&counter), cancel: Some(&cancel) };
    let out = run_polled(py, n_runs, &counter, &cancel, progress, poll_interval, || core::batch::simulate_batch_stacked(&jobs, &opts))?
        .map_err(|e| batch_err(py, e, n_runs))?;
    let shape = [out.n_runs, out.n_samples];
    let d = PyDict::new(py);
    for (name, v) in [("position", out.position), ("velocity", out.velocity), ("measured", out.measured), ("command", out.command), ("friction", out.friction)] {
        let a: Bound<'py, PyArray2<f64>> = v.into_pyarray(py).reshape(shape)?;
        d.set_item(name, a)?;
    }
    Ok(d)
}

/// Friction-only simulation of many models along position trajectories at the shared times `t`
/// (`position` is 2-D: one row per model, or one row shared by all). Returns `n_models x len(t)`.
#[pyfunction]
#[pyo3(signature = (models, t, position, threads=None, progress=None, poll_interval=0.2))]
pub fn simulate_friction_batch<'py>(
    py: Python<'py>,
    models: Vec<PyRef<'py, FrictionSpec>>,
    t: PyReadonlyArray1<'py, f64>,
    position: PyReadonlyArray2<'py, f64>,
    threads: Option<usize>,
    progress: Option<Py<PyAny>>,
    poll_interval: f64,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n_runs = models.len();
    let t = crate::slice("t", &t)?;
    let x = Rows::new("position", &position, n_runs)?;
    let rows: Vec<&[f64]> = (0..x.rows).map(|i| x.row(i)).collect();
    let models: Vec<core::FrictionModel> = models.iter().map(|m| m.model.clone()).collect();
    let (counter, cancel) = (AtomicUsize::new(0), AtomicBool::new(false));
    let opts = BatchOptions { threads, progress: Some(&counter), cancel: Some(&cancel) };
    let out = run_polled(py, n_runs, &counter, &cancel, progress, poll_interval, || {
        core::batch::simulate_position_batch(&models, t, &rows, &opts)
    })?
    .map_err(|e| batch_err(py, e, n_runs))?;
    Ok(out.into_pyarray(py).reshape([n_runs, t.len()])?)
}

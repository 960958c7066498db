//! Runs: one entry point for single runs and batches (a single run is a batch of one), and one
//! for friction-only simulations. Inputs are borrowed 2-D arrays (one row per run, or a single
//! row shared by every run); outputs are stacked `n_runs x n_samples` arrays moved into numpy
//! without a copy.
//!
//! Short work runs on the calling thread with the GIL released. Longer work runs on a helper
//! thread while this one maps the output pages, then wakes every `poll_interval` seconds to
//! report `progress(done, total)` and to check for Ctrl-C, which sets the core's cancel flag:
//! running runs stop within a few thousand steps.

use crate::errors::{batch_err, to_pyerr, IntoPy};
use crate::{AxisSpec, ControllerSpec, FrictionSpec};
use gms_core as core;
use gms_core::batch::{BatchOptions, BatchOutput, Job};
use numpy::{IntoPyArray, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

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
        let data = a.as_slice().map_err(|_| to_pyerr(core::CoreError::InvalidParameter { name, reason: "must be a C-contiguous float64 array".into() }))?;
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

/// The inputs of the runs (a dict filled by `gmsfric.system`): the Python side of
/// [`core::ClosedLoopInput`], with arrays as rows.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub struct RunInputs<'py> {
    reference: Option<PyReadonlyArray2<'py, f64>>,
    feedforward: Option<PyReadonlyArray2<'py, f64>>,
    input_disturbance: Option<PyReadonlyArray2<'py, f64>>,
    load_force: Option<PyReadonlyArray2<'py, f64>>,
    measurement_noise: Option<PyReadonlyArray2<'py, f64>>,
    quantization: f64,
    drive_min: f64,
    drive_max: f64,
    initial_position: Option<f64>,
    initial_velocity: f64,
}

/// Outputs by name.
fn record_from(names: &[String], every: usize) -> PyResult<core::Record> {
    if every == 0 {
        return Err(to_pyerr(core::CoreError::NotPositive { name: "every", value: 0.0 }));
    }
    let mut r = core::Record { position: false, velocity: false, measured: false, command: false, friction: false, error: false, every };
    for name in names {
        match name.as_str() {
            "position" => r.position = true,
            "velocity" => r.velocity = true,
            "measured" => r.measured = true,
            "command" => r.command = true,
            "friction" => r.friction = true,
            "error" => r.error = true,
            other => {
                return Err(to_pyerr(core::CoreError::InvalidParameter {
                    name: "record",
                    reason: format!("unknown output '{other}' (position, velocity, measured, command, friction, error)"),
                }))
            }
        }
    }
    Ok(r)
}

/// Physical memory in bytes, where the system tells.
fn physical_memory() -> Option<f64> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: sysconf only reads system configuration values.
        let (pages, size) = unsafe { (libc::sysconf(libc::_SC_PHYS_PAGES), libc::sysconf(libc::_SC_PAGESIZE)) };
        if pages > 0 && size > 0 {
            return Some(pages as f64 * size as f64);
        }
    }
    None
}

/// Refuse outputs that could never fit in memory (with overcommit the allocation itself might
/// succeed and the process be killed later, writing them).
fn check_output_size(n_runs: usize, samples: usize, arrays: usize) -> PyResult<()> {
    let bytes = n_runs as f64 * samples as f64 * arrays as f64 * 8.0;
    if let Some(mem) = physical_memory() {
        if bytes > 0.8 * mem {
            return Err(to_pyerr(core::CoreError::TooLarge {
                name: "outputs",
                requested: bytes,
                limit: 0.8 * mem,
                what: "bytes",
                reason: "record fewer outputs (record=...), decimate (every=...) or split the run",
            }));
        }
    }
    Ok(())
}

/// The whole 4 KiB pages of a long output (an address range: it is mapped while the core writes
/// the output through its own borrow).
#[derive(Clone, Copy)]
struct Pages {
    start: usize,
    bytes: usize,
}

impl Pages {
    /// The pages of `v` if it is long enough to be worth a system call, asking for transparent
    /// huge pages for them (`MADV_HUGEPAGE`, as numpy does for its own large arrays; the system
    /// decides). One 4 KiB fault per page taken while the simulation writes costs several ns per
    /// recorded step in a virtual machine, more than any other tuning of the step gains.
    fn of(v: &mut [f64]) -> Option<Self> {
        const PAGE: usize = 4096;
        if v.len() < (1 << 16) {
            return None;
        }
        let start = (v.as_mut_ptr() as usize).div_ceil(PAGE) * PAGE;
        let end = (v.as_mut_ptr() as usize + std::mem::size_of_val(v)) / PAGE * PAGE;
        let pages = (end > start).then_some(Self { start, bytes: end - start })?;
        #[cfg(target_os = "linux")]
        // SAFETY: the range lies inside `v`'s allocation; the advice changes how pages not yet
        // mapped will be backed, not the contents.
        unsafe {
            libc::madvise(pages.start as *mut libc::c_void, pages.bytes, libc::MADV_HUGEPAGE);
        }
        Some(pages)
    }

    /// The pages in pieces of 64 MiB, for [`populate`] one at a time.
    fn pieces(self) -> impl Iterator<Item = Pages> {
        const PIECE: usize = 64 << 20;
        (0..self.bytes).step_by(PIECE).map(move |at| Pages { start: self.start + at, bytes: PIECE.min(self.bytes - at) })
    }
}

/// Map `pages` now (`MADV_POPULATE_WRITE`, one system call) instead of one fault at a time inside
/// the simulation. Harmless where unsupported (older kernels).
fn populate(pages: Pages) {
    #[cfg(target_os = "linux")]
    {
        const MADV_POPULATE_WRITE: libc::c_int = 23;
        // SAFETY: the range lies inside an output allocation that outlives the run; mapping fills
        // absent pages with zeros, which is what the zeroed allocation holds, and leaves present
        // pages (the core may have written them) unchanged.
        unsafe {
            libc::madvise(pages.start as *mut libc::c_void, pages.bytes, MADV_POPULATE_WRITE);
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = pages;
}

/// A non-finite value in an output becomes a `SimulationError` naming the quantity and index.
pub fn finite_output(_py: Python<'_>, quantity: &'static str, v: &[f64]) -> PyResult<()> {
    match v.iter().position(|x| !x.is_finite()) {
        None => Ok(()),
        Some(step) => Err(to_pyerr(core::CoreError::NonFiniteOutput { quantity, step, time: f64::NAN, hint: "the inputs are out of the model's finite range" })),
    }
}

/// Work of at most this many block-steps (samples x friction elements, summed over the runs)
/// runs on the calling thread: a few ms at most, so Ctrl-C can wait for it, while starting and
/// waking a helper thread can itself take a scheduler tick (~4 ms seen in a VM), more than a
/// short run costs. Optimisers and the loop call short runs thousands of times.
const INLINE_STEPS: usize = 200_000;

/// Run `work` (of `steps` block-steps) with the GIL released; short work on this thread, longer work on
/// a helper thread while this one maps the output `pages` piece by piece (so it overlaps the
/// computation on a second CPU) and, every `interval`, re-attaches briefly to report
/// `progress(done, total)` and check signals (an exception there sets `cancel`, stops the
/// mapping, and is what the caller gets).
#[allow(clippy::too_many_arguments)]
fn run_polled<T: Send>(
    py: Python<'_>,
    total: usize,
    steps: usize,
    counter: &AtomicUsize,
    cancel: &AtomicBool,
    progress: Option<Py<PyAny>>,
    interval: f64,
    pages: &[Pages],
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    if steps <= INLINE_STEPS && progress.is_none() {
        let out = py.detach(work);
        py.check_signals()?;
        return Ok(out);
    }
    let interval = Duration::from_secs_f64(if interval.is_finite() && interval > 0.0 { interval.clamp(0.005, 60.0) } else { 0.2 });
    let mut py_err: Option<PyErr> = None;
    // Set by the worker just before it wakes this thread: `is_finished` would still be false
    // for the moment the worker takes to exit, and this thread would sleep a whole interval.
    let done = AtomicBool::new(false);
    let out = py.detach(|| {
        std::thread::scope(|s| {
            let waiter = std::thread::current();
            let done = &done;
            let worker = s.spawn(move || {
                let r = work();
                done.store(true, Ordering::Release);
                waiter.unpark();
                r
            });
            let finished = || done.load(Ordering::Acquire);
            let mut to_map = pages.iter().flat_map(|p| p.pieces());
            let mut next_poll = Instant::now() + interval;
            let mut last = usize::MAX;
            while !finished() {
                match to_map.next() {
                    Some(piece) if py_err.is_none() => populate(piece),
                    _ => std::thread::park_timeout(next_poll.saturating_duration_since(Instant::now())),
                }
                if finished() || py_err.is_some() || Instant::now() < next_poll {
                    continue;
                }
                next_poll = Instant::now() + interval;
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

/// Run `axes[i]` under `controllers[i]` (`None`: open loop, the feedforward is the command) for
/// every `i`, on `threads` workers (`None`: every core). Returns a dict of `n_runs x samples`
/// arrays for the outputs named in `record`, every `every`-th sample.
#[pyfunction]
#[pyo3(signature = (axes, controllers, dt, inputs, record, every=1, threads=None, progress=None, poll_interval=0.2))]
#[allow(clippy::too_many_arguments)]
pub fn simulate<'py>(
    py: Python<'py>,
    axes: Vec<PyRef<'py, AxisSpec>>,
    controllers: Vec<Option<PyRef<'py, ControllerSpec>>>,
    dt: f64,
    inputs: RunInputs<'py>,
    record: Vec<String>,
    every: usize,
    threads: Option<usize>,
    progress: Option<Py<PyAny>>,
    poll_interval: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let n_runs = axes.len();
    if controllers.len() != n_runs {
        return Err(to_pyerr(core::CoreError::LengthMismatch { name: "controllers", other: "axes", expected: n_runs, got: controllers.len() }));
    }
    let rec = record_from(&record, every)?;
    let reference = opt_rows("reference", &inputs.reference, n_runs)?;
    let ff = opt_rows("feedforward", &inputs.feedforward, n_runs)?;
    let dist = opt_rows("input_disturbance", &inputs.input_disturbance, n_runs)?;
    let load = opt_rows("load_force", &inputs.load_force, n_runs)?;
    let noise = opt_rows("measurement_noise", &inputs.measurement_noise, n_runs)?;
    let mut jobs = Vec::with_capacity(n_runs);
    for (i, (axis, ctrl)) in axes.iter().zip(&controllers).enumerate() {
        let mut input = match (&reference, &ff) {
            (Some(r), _) => core::ClosedLoopInput::new(r.row(i), dt),
            (None, Some(f)) => core::ClosedLoopInput::open(f.row(i), dt),
            (None, None) => return Err(to_pyerr(core::CoreError::InvalidParameter { name: "reference", reason: "give a reference (closed loop) or a command (open loop)".into() })),
        };
        input.feedforward = ff.as_ref().map(|r| r.row(i));
        input.input_disturbance = dist.as_ref().map(|r| r.row(i));
        input.load_force = load.as_ref().map(|r| r.row(i));
        input.measurement_noise = noise.as_ref().map(|r| r.row(i));
        input.quantization = inputs.quantization;
        input.drive_min = inputs.drive_min;
        input.drive_max = inputs.drive_max;
        if let Some(x0) = inputs.initial_position {
            input.initial_position = x0;
        }
        input.initial_velocity = inputs.initial_velocity;
        jobs.push(Job { axis: axis.axis.clone(), controller: ctrl.as_ref().map(|c| c.model.clone()), input });
    }
    let n = jobs.first().map_or(0, |j| j.input.len());
    let arrays = [rec.position, rec.velocity, rec.measured, rec.command, rec.friction, rec.error].iter().filter(|&&b| b).count();
    check_output_size(n_runs, rec.samples(n), arrays)?;
    for (i, job) in jobs.iter().enumerate() {
        let got = job.input.len();
        if got != n {
            return Err(batch_err(py, core::batch::BatchError { run: i, error: core::CoreError::LengthMismatch { name: "reference", other: "reference of run 0", expected: n, got } }, n_runs));
        }
    }
    let mut out = BatchOutput::allocate(n_runs, rec.samples(n), &rec).py()?;
    let pages: Vec<Pages> = [&mut out.position, &mut out.velocity, &mut out.measured, &mut out.command, &mut out.friction, &mut out.error].into_iter().filter_map(|v| Pages::of(v)).collect();
    let (counter, cancel) = (AtomicUsize::new(0), AtomicBool::new(false));
    let opts = BatchOptions { threads, progress: Some(&counter), cancel: Some(&cancel) };
    let work = jobs.iter().map(|j| n.saturating_mul(j.axis.friction.as_ref().map_or(1, |f| f.elements()))).fold(0usize, usize::saturating_add);
    run_polled(py, n_runs, work, &counter, &cancel, progress, poll_interval, &pages, || core::batch::simulate_batch_into(&jobs, &rec, &mut out, &opts))?
        .map_err(|e| batch_err(py, e, n_runs))?;
    let shape = [out.n_runs, out.n_samples];
    let d = PyDict::new(py);
    for (name, on, v) in [
        ("position", rec.position, out.position),
        ("velocity", rec.velocity, out.velocity),
        ("measured", rec.measured, out.measured),
        ("command", rec.command, out.command),
        ("friction", rec.friction, out.friction),
        ("error", rec.error, out.error),
    ] {
        if on {
            let a: Bound<'py, PyArray2<f64>> = v.into_pyarray(py).reshape(shape)?;
            d.set_item(name, a)?;
        }
    }
    Ok(d)
}

/// Friction-only simulation of many models along position trajectories at the shared times `t`
/// (`position` is 2-D: one row per model, or one row shared by all). Returns `n_models x len(t)`.
#[pyfunction]
#[pyo3(signature = (models, t, position, threads=None, progress=None, poll_interval=0.2))]
pub fn simulate_friction<'py>(
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
    check_output_size(n_runs, t.len(), 1)?;
    let rows: Vec<&[f64]> = (0..x.rows).map(|i| x.row(i)).collect();
    let models: Vec<core::FrictionModel> = models.iter().map(|m| m.model.clone()).collect();
    let (counter, cancel) = (AtomicUsize::new(0), AtomicBool::new(false));
    let opts = BatchOptions { threads, progress: Some(&counter), cancel: Some(&cancel) };
    let work = models.iter().map(|m| t.len().saturating_mul(m.elements())).fold(0usize, usize::saturating_add);
    let out = run_polled(py, n_runs, work, &counter, &cancel, progress, poll_interval, &[], || core::batch::simulate_position_batch(&models, t, &rows, &opts))?
        .map_err(|e| batch_err(py, e, n_runs))?;
    finite_output(py, "friction force", &out)?;
    Ok(out.into_pyarray(py).reshape([n_runs, t.len()])?)
}

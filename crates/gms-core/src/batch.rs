//! Many closed-loop runs at once (parameter sweeps, Monte Carlo over identified uncertainties,
//! controller-gain sweeps), spread over all cores with rayon.
//!
//! Each [`Job`] is a complete run: plant, optional friction model, controller and its inputs
//! (arrays borrowed, so a shared reference is not copied per run). Runs are independent: every
//! job's models are cloned and reset before it runs, so results equal those of
//! [`crate::simulate`] bit for bit, whatever the number of threads or the order in which rayon
//! schedules the runs.
//!
//! Progress and cancellation are lock-free: the caller may pass an [`AtomicUsize`] that counts
//! finished runs (the Python binding polls it while the GIL is released) and an [`AtomicBool`]
//! that, once set, makes runs that have not started yet return at once.

use crate::closed_loop::{simulate, simulate_into, ClosedLoopBuffers, ClosedLoopInput, ClosedLoopOutput};
use crate::control::ControllerModel;
use crate::error::{CoreError, Result};
use crate::friction::FrictionModel;
use crate::plant::Plant;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// One run of a batch.
#[derive(Debug, Clone)]
pub struct Job<'a> {
    pub plant: Plant,
    /// `None`: the frictionless axis.
    pub friction: Option<FrictionModel>,
    pub controller: ControllerModel,
    pub input: ClosedLoopInput<'a>,
}

impl Job<'_> {
    /// Run this job from the initial state of its models (the job itself is not modified).
    pub fn run(&self) -> Result<ClosedLoopOutput> {
        let mut friction = self.friction.clone();
        let mut controller = self.controller.clone();
        simulate(&self.plant, friction.as_mut(), &mut controller, &self.input)
    }

    /// Run this job writing into caller-owned buffers.
    pub fn run_into(&self, out: ClosedLoopBuffers<'_>) -> Result<()> {
        let mut friction = self.friction.clone();
        let mut controller = self.controller.clone();
        simulate_into(&self.plant, friction.as_mut(), &mut controller, &self.input, out)
    }
}

/// How a batch runs. The default uses rayon's global pool (all cores, or `RAYON_NUM_THREADS`).
#[derive(Debug, Default, Clone, Copy)]
pub struct BatchOptions<'a> {
    /// Number of worker threads; `None` uses the global pool.
    pub threads: Option<usize>,
    /// Incremented once per finished run (successful or not).
    pub progress: Option<&'a AtomicUsize>,
    /// When set, runs that have not started return [`cancelled`] instead of running.
    pub cancel: Option<&'a AtomicBool>,
}

/// The error a run reports when the batch was cancelled before it started.
pub fn cancelled() -> CoreError {
    CoreError::InvalidParameter { name: "batch", reason: "cancelled before this run started".into() }
}

/// A failed run of a batch: its index and its error.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchError {
    pub run: usize,
    pub error: CoreError,
}

impl std::fmt::Display for BatchError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "run {}: {}", self.run, self.error)
    }
}

impl std::error::Error for BatchError {}

/// Stacked outputs of a batch: each array is `n_runs x n_samples`, row-major (run `i` occupies
/// `[i * n_samples, (i + 1) * n_samples)`), with the meaning of [`ClosedLoopOutput`]'s fields.
#[derive(Debug, Clone, Default)]
pub struct BatchOutput {
    pub n_runs: usize,
    pub n_samples: usize,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub measured: Vec<f64>,
    pub command: Vec<f64>,
    pub friction: Vec<f64>,
}

impl BatchOutput {
    /// Row `i` of `field` (one of the arrays of this struct).
    pub fn row<'s>(&self, field: &'s [f64], i: usize) -> &'s [f64] {
        &field[i * self.n_samples..(i + 1) * self.n_samples]
    }
}

/// Run `f` on a pool of `threads` workers (or on the global pool).
fn in_pool<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> Result<T> {
    match threads {
        None => Ok(f()),
        Some(0) => Err(CoreError::NotPositive { name: "threads", value: 0.0 }),
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| CoreError::InvalidParameter { name: "threads", reason: e.to_string() })?;
            Ok(pool.install(f))
        }
    }
}

/// Run `f` under the options' cancel flag and progress counter.
fn track<T>(opts: &BatchOptions<'_>, f: impl FnOnce() -> Result<T>) -> Result<T> {
    if opts.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
        return Err(cancelled());
    }
    let out = f();
    if let Some(p) = opts.progress {
        p.fetch_add(1, Ordering::Relaxed);
    }
    out
}

/// Run one job under the options' cancel flag and progress counter.
fn run_tracked(job: &Job<'_>, opts: &BatchOptions<'_>) -> Result<ClosedLoopOutput> {
    track(opts, || job.run())
}

/// Run every job in parallel; one result per job, in the order of `jobs`. Runs of different
/// lengths are fine. A failing run does not stop the others; setting `opts.cancel` skips the
/// runs that have not started yet (they return [`cancelled`]).
pub fn simulate_batch(jobs: &[Job<'_>], opts: &BatchOptions<'_>) -> Result<Vec<Result<ClosedLoopOutput>>> {
    in_pool(opts.threads, || jobs.par_iter().map(|job| run_tracked(job, opts)).collect())
}

/// Run every job in parallel and stack the outputs into `n_runs x n_samples` arrays. All runs
/// must have the same number of samples. Returns the first failing run (lowest index) otherwise;
/// after a failure, runs with a higher index that have not started yet are skipped (runs below
/// it still run, so the reported run is the lowest failing index whatever the scheduling).
pub fn simulate_batch_stacked(jobs: &[Job<'_>], opts: &BatchOptions<'_>) -> std::result::Result<BatchOutput, BatchError> {
    let n_runs = jobs.len();
    let n = jobs.first().map_or(0, |j| j.input.reference.len());
    for (i, job) in jobs.iter().enumerate() {
        let got = job.input.reference.len();
        if got == 0 {
            return Err(BatchError { run: i, error: CoreError::Empty { name: "reference", min: 1 } });
        }
        if got != n {
            return Err(BatchError {
                run: i,
                error: CoreError::LengthMismatch { name: "reference", other: "reference of run 0", expected: n, got },
            });
        }
    }
    let total = n_runs * n;
    let mut out = BatchOutput {
        n_runs,
        n_samples: n,
        // Zeroed allocations are lazily mapped: each page is touched first by the worker that
        // writes its row.
        position: vec![0.0; total],
        velocity: vec![0.0; total],
        measured: vec![0.0; total],
        command: vec![0.0; total],
        friction: vec![0.0; total],
    };
    if n_runs == 0 {
        return Ok(out);
    }
    let first_failure = AtomicUsize::new(usize::MAX);
    let rows: Vec<_> = out
        .position
        .chunks_mut(n)
        .zip(out.velocity.chunks_mut(n))
        .zip(out.measured.chunks_mut(n))
        .zip(out.command.chunks_mut(n))
        .zip(out.friction.chunks_mut(n))
        .collect();
    let results: Vec<Result<()>> = in_pool(opts.threads, || {
        rows.into_par_iter()
            .zip(jobs.par_iter())
            .enumerate()
            .map(|(i, (((((p, v), m), c), f), job))| {
                if i > first_failure.load(Ordering::Relaxed) {
                    return Err(cancelled());
                }
                // Each run writes straight into its rows of the stacked arrays.
                let buffers = ClosedLoopBuffers { position: p, velocity: v, measured: Some(m), command: c, friction: f };
                track(opts, || job.run_into(buffers)).inspect_err(|_| {
                    first_failure.fetch_min(i, Ordering::Relaxed);
                })
            })
            .collect()
    })
    .map_err(|error| BatchError { run: 0, error })?;
    // Report the lowest-index real failure; skipped runs are a consequence, not a cause (they
    // are reported only when the caller cancelled the batch).
    let cancel_err = cancelled();
    let first_real = results.iter().position(|r| matches!(r, Err(e) if *e != cancel_err));
    let first_any = results.iter().position(|r| r.is_err());
    if let Some(i) = first_real.or(first_any) {
        let error = results.into_iter().nth(i).and_then(|r| r.err()).expect("an error at i");
        return Err(BatchError { run: i, error });
    }
    Ok(out)
}

/// Friction-only simulation of many models along position trajectories sampled at the shared
/// times `t`, in parallel: run `i` uses `models[i]` on `positions[i]` (`positions` may also hold a
/// single trajectory shared by every model). Returns the forces stacked `n_runs x t.len()`.
pub fn simulate_position_batch(
    models: &[FrictionModel],
    t: &[f64],
    positions: &[&[f64]],
    opts: &BatchOptions<'_>,
) -> std::result::Result<Vec<f64>, BatchError> {
    let n = t.len();
    if positions.len() != 1 && positions.len() != models.len() {
        return Err(BatchError {
            run: 0,
            error: CoreError::LengthMismatch { name: "position rows", other: "models", expected: models.len(), got: positions.len() },
        });
    }
    let mut out = vec![0.0; models.len() * n];
    if models.is_empty() || n == 0 {
        crate::error::check::increasing("t", t, 2).map_err(|error| BatchError { run: 0, error })?;
        return Ok(out);
    }
    let results: Vec<Result<()>> = in_pool(opts.threads, || {
        out.par_chunks_mut(n)
            .zip(models.par_iter())
            .enumerate()
            .map(|(i, (row, model))| {
                if opts.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                    return Err(cancelled());
                }
                let x = positions[if positions.len() == 1 { 0 } else { i }];
                let mut m = model.clone();
                m.reset();
                let f = crate::with_friction!(&mut m, e => crate::friction::simulate_position(e, t, x));
                if let Some(p) = opts.progress {
                    p.fetch_add(1, Ordering::Relaxed);
                }
                row.copy_from_slice(&f?);
                Ok(())
            })
            .collect()
    })
    .map_err(|error| BatchError { run: 0, error })?;
    match results.into_iter().enumerate().find(|(_, r)| r.is_err()) {
        Some((run, Err(error))) => Err(BatchError { run, error }),
        _ => Ok(out),
    }
}

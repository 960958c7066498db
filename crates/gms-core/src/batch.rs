//! Many closed-loop runs at once (parameter sweeps, Monte Carlo over identified uncertainties,
//! controller-gain sweeps), spread over all cores with rayon.
//!
//! Each [`Job`] is a complete run: the axis (plant, friction, effects), an optional controller
//! and its inputs (arrays borrowed, so a shared reference is not copied per run). Runs are independent: every
//! job's models are cloned and reset before it runs, so results equal those of
//! [`crate::simulate`] bit for bit, whatever the number of threads or the order in which rayon
//! schedules the runs.
//!
//! Progress and cancellation are lock-free: the caller may pass an [`AtomicUsize`] that counts
//! finished runs (the Python binding polls it while the GIL is released) and an [`AtomicBool`]
//! that, once set, stops running runs within a few thousand steps and makes runs that have not
//! started return at once ([`CoreError::Interrupted`]).

use crate::closed_loop::{Axis, ClosedLoopBuffers, ClosedLoopInput, ClosedLoopOutput, Record};
use crate::control::ControllerModel;
use crate::error::{try_zeroed, CoreError, Result};
use crate::friction::FrictionModel;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// One run of a batch.
#[derive(Debug, Clone)]
pub struct Job<'a> {
    pub axis: Axis,
    /// `None`: open loop (the input's feedforward is the command).
    pub controller: Option<ControllerModel>,
    pub input: ClosedLoopInput<'a>,
}

impl Job<'_> {
    /// Run this job from the initial state of its models (the job itself is not modified).
    pub fn run(&self) -> Result<ClosedLoopOutput> {
        self.axis.simulate(self.controller.as_ref(), &self.input)
    }

    /// Run this job writing into caller-owned buffers.
    pub fn run_into(&self, out: ClosedLoopBuffers<'_>) -> Result<()> {
        self.axis.simulate_into(self.controller.as_ref(), &self.input, out)
    }
}

/// How a batch runs. The default uses rayon's global pool (all cores, or `RAYON_NUM_THREADS`).
#[derive(Debug, Default, Clone, Copy)]
pub struct BatchOptions<'a> {
    /// Number of worker threads; `None` uses the global pool.
    pub threads: Option<usize>,
    /// Incremented once per finished run (successful or not).
    pub progress: Option<&'a AtomicUsize>,
    /// When set, running runs stop and runs that have not started return
    /// [`CoreError::Interrupted`].
    pub cancel: Option<&'a AtomicBool>,
}

/// Most worker threads a batch may ask for (more than any machine has cores: the request is
/// a mistake, and spawning that many threads would take minutes).
pub const MAX_THREADS: usize = 1024;

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

/// Stacked outputs of a batch: each recorded array is `n_runs x n_samples`, row-major (run `i`
/// occupies `[i * n_samples, (i + 1) * n_samples)`), with the meaning of
/// [`ClosedLoopOutput`]'s fields; outputs not recorded are empty.
#[derive(Debug, Clone, Default)]
pub struct BatchOutput {
    pub n_runs: usize,
    /// Recorded samples per run.
    pub n_samples: usize,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub measured: Vec<f64>,
    pub command: Vec<f64>,
    pub friction: Vec<f64>,
    pub error: Vec<f64>,
}

impl BatchOutput {
    /// Zeroed arrays for the outputs `record` asks for, allocated fallibly: a size that cannot
    /// be had is [`CoreError::TooLarge`] (a `MemoryError` in Python), not an abort.
    pub fn allocate(n_runs: usize, n_samples: usize, record: &Record) -> Result<Self> {
        let total = n_runs.checked_mul(n_samples).ok_or(CoreError::TooLarge {
            name: "outputs",
            requested: n_runs as f64 * n_samples as f64,
            limit: usize::MAX as f64,
            what: "samples",
            reason: "runs x samples overflows",
        })?;
        let alloc = |on: bool, name| if on { try_zeroed(name, total) } else { Ok(Vec::new()) };
        Ok(Self {
            n_runs,
            n_samples,
            position: alloc(record.position, "position")?,
            velocity: alloc(record.velocity, "velocity")?,
            measured: alloc(record.measured, "measured")?,
            command: alloc(record.command, "command")?,
            friction: alloc(record.friction, "friction")?,
            error: alloc(record.error, "error")?,
        })
    }

    /// Row `i` of `field` (one of the arrays of this struct).
    pub fn row<'s>(&self, field: &'s [f64], i: usize) -> &'s [f64] {
        &field[i * self.n_samples..(i + 1) * self.n_samples]
    }

    /// Mutable row views of every recorded array, run by run.
    fn row_buffers(&mut self, every: usize) -> Vec<ClosedLoopBuffers<'_>> {
        let (n_runs, m) = (self.n_runs, self.n_samples);
        fn split(v: &mut [f64], n_runs: usize, m: usize) -> Vec<Option<&mut [f64]>> {
            if v.is_empty() || m == 0 {
                (0..n_runs).map(|_| None).collect()
            } else {
                v.chunks_mut(m).map(Some).collect()
            }
        }
        let mut pos = split(&mut self.position, n_runs, m).into_iter();
        let mut vel = split(&mut self.velocity, n_runs, m).into_iter();
        let mut meas = split(&mut self.measured, n_runs, m).into_iter();
        let mut cmd = split(&mut self.command, n_runs, m).into_iter();
        let mut fric = split(&mut self.friction, n_runs, m).into_iter();
        let mut err = split(&mut self.error, n_runs, m).into_iter();
        (0..n_runs)
            .map(|_| ClosedLoopBuffers {
                position: pos.next().flatten(),
                velocity: vel.next().flatten(),
                measured: meas.next().flatten(),
                command: cmd.next().flatten(),
                friction: fric.next().flatten(),
                error: err.next().flatten(),
                every,
            })
            .collect()
    }
}

/// Run `f` on a pool of `threads` workers (or on the global pool).
fn in_pool<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> Result<T> {
    match threads {
        None => Ok(f()),
        Some(0) => Err(CoreError::NotPositive { name: "threads", value: 0.0 }),
        Some(n) if n > MAX_THREADS => Err(CoreError::InvalidParameter { name: "threads", reason: format!("{n} threads; at most {MAX_THREADS}") }),
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| CoreError::InvalidParameter { name: "threads", reason: e.to_string() })?;
            Ok(pool.install(f))
        }
    }
}

/// `f` over `items`, results in the order of `items`: on the calling thread when one thread is
/// asked for (a pool of one costs a thread start and wake-up, which can exceed a short batch: ~4
/// ms seen in a VM, and optimisers call short batches thousands of times), else on a pool of
/// `threads` workers (or the global pool).
fn map_items<I: Send, R: Send>(threads: Option<usize>, items: Vec<I>, f: impl Fn(I) -> R + Sync + Send) -> Result<Vec<R>> {
    if threads == Some(1) {
        return Ok(items.into_iter().map(f).collect());
    }
    in_pool(threads, || items.into_par_iter().map(f).collect())
}

/// Run `f` under the options' cancel flag and progress counter.
fn track<T>(opts: &BatchOptions<'_>, f: impl FnOnce() -> Result<T>) -> Result<T> {
    if opts.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
        return Err(CoreError::Interrupted);
    }
    let out = f();
    if let Some(p) = opts.progress {
        p.fetch_add(1, Ordering::Relaxed);
    }
    out
}

/// The job's input with the batch's cancel flag (unless the job has its own).
fn input_of<'a>(job: &Job<'a>, opts: &BatchOptions<'a>) -> ClosedLoopInput<'a> {
    let mut input = job.input;
    input.cancel = input.cancel.or(opts.cancel);
    input
}

/// Run every job in parallel; one result per job, in the order of `jobs`. Runs of different
/// lengths are fine. A failing run does not stop the others; setting `opts.cancel` stops them.
pub fn simulate_batch(jobs: &[Job<'_>], opts: &BatchOptions<'_>) -> Result<Vec<Result<ClosedLoopOutput>>> {
    map_items(opts.threads, jobs.iter().collect(), |job| track(opts, || job.axis.simulate(job.controller.as_ref(), &input_of(job, opts))))
}

/// Run every job in parallel, writing the outputs `record` asks for into stacked
/// `n_runs x samples` arrays. All runs must have the same number of samples. Returns the first
/// failing run (lowest index) otherwise; after a failure, runs with a higher index that have not
/// started yet are skipped (runs below it still run, so the reported run is the lowest failing
/// index whatever the scheduling).
pub fn simulate_batch_stacked(jobs: &[Job<'_>], record: &Record, opts: &BatchOptions<'_>) -> std::result::Result<BatchOutput, BatchError> {
    let n = jobs.first().map_or(0, |j| j.input.len());
    for (i, job) in jobs.iter().enumerate() {
        let got = job.input.len();
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
    let mut out = BatchOutput::allocate(jobs.len(), record.samples(n), record).map_err(|error| BatchError { run: 0, error })?;
    simulate_batch_into(jobs, record, &mut out, opts)?;
    Ok(out)
}

/// [`simulate_batch_stacked`] into arrays the caller allocated with [`BatchOutput::allocate`].
///
/// Runs of the same structure ([`crate::lanes::lane_key`]: GMS friction, PID, same plant, step
/// and length, a reference and nothing else per sample) go in aligned groups of
/// [`crate::lanes::LANES`] (runs `8j .. 8j + 7`), one SIMD vector group each; the others run one
/// by one. Groups and single runs spread over the threads; which runs share a vector depends on
/// the jobs only, so the results do not depend on the thread count.
pub fn simulate_batch_into(jobs: &[Job<'_>], record: &Record, out: &mut BatchOutput, opts: &BatchOptions<'_>) -> std::result::Result<(), BatchError> {
    if jobs.is_empty() {
        return Ok(());
    }
    let first_failure = AtomicUsize::new(usize::MAX);
    let rows = out.row_buffers(record.every.max(1));
    let items = plan(jobs, rows);
    let run_one = |i: usize, buffers: ClosedLoopBuffers<'_>| -> Result<()> {
        if i > first_failure.load(Ordering::Relaxed) {
            return Err(CoreError::Interrupted);
        }
        let job = &jobs[i];
        // Each run writes straight into its rows of the stacked arrays.
        track(opts, || job.axis.simulate_into(job.controller.as_ref(), &input_of(job, opts), buffers)).inspect_err(|_| {
            first_failure.fetch_min(i, Ordering::Relaxed);
        })
    };
    let run_item = |item: Item<'_>| -> Vec<(usize, Result<()>)> {
        match item {
            Item::Single(i, buffers) => vec![(i, run_one(i, buffers))],
            Item::Lanes(group) => {
                let (idx, mut buffers) = *group;
                if idx[0] > first_failure.load(Ordering::Relaxed) {
                    return idx.iter().map(|&i| (i, Err(CoreError::Interrupted))).collect();
                }
                if opts.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                    return idx.iter().map(|&i| (i, Err(CoreError::Interrupted))).collect();
                }
                let pid = |i: usize| match &jobs[i].controller {
                    Some(ControllerModel::Pid(p)) => p,
                    _ => unreachable!("lane_key admits PID runs only"),
                };
                let done = crate::lanes::run_group(
                    idx.map(|i| &jobs[i].axis),
                    idx.map(pid),
                    idx.map(|i| &jobs[i].input),
                    &mut buffers,
                    opts.cancel,
                );
                match done {
                    Ok(true) => {
                        if let Some(p) = opts.progress {
                            p.fetch_add(idx.len(), Ordering::Relaxed);
                        }
                        idx.iter().map(|&i| (i, Ok(()))).collect()
                    }
                    Err(e) => idx.iter().map(|&i| (i, Err(e.clone()))).collect(),
                    // A lane cannot run in the vector (or failed): the runs one by one, which
                    // also reports the failing run's own error.
                    Ok(false) => idx.into_iter().zip(buffers).map(|(i, b)| (i, run_one(i, b))).collect(),
                }
            }
        }
    };
    let mut results: Vec<(usize, Result<()>)> =
        map_items(opts.threads, items, run_item).map_err(|error| BatchError { run: 0, error })?.into_iter().flatten().collect();
    results.sort_by_key(|(i, _)| *i);
    let results: Vec<Result<()>> = results.into_iter().map(|(_, r)| r).collect();
    // Report the lowest-index real failure; skipped runs are a consequence, not a cause (they
    // are reported only when the caller cancelled the batch).
    let first_real = results.iter().position(|r| matches!(r, Err(e) if *e != CoreError::Interrupted));
    let first_any = results.iter().position(|r| r.is_err());
    if let Some(i) = first_real.or(first_any) {
        let error = results.into_iter().nth(i).and_then(|r| r.err()).expect("an error at i");
        return Err(BatchError { run: i, error });
    }
    Ok(())
}

/// A unit of batch work: one run, or [`crate::lanes::LANES`] runs in one vector.
enum Item<'a> {
    Single(usize, ClosedLoopBuffers<'a>),
    /// Boxed: a group's row buffers are large beside a single run's.
    Lanes(Box<([usize; crate::lanes::LANES], [ClosedLoopBuffers<'a>; crate::lanes::LANES])>),
}

/// Runs `8j .. 8j + 7` ([`crate::lanes::LANES`]) with equal lane keys share a vector group; the rest run alone. Groups never
/// straddle a multiple of [`crate::lanes::LANES`], so a batch split into chunks of such sizes
/// (`gmsfric.batch`'s `executor=`) computes exactly what the whole batch computes.
fn plan<'a>(jobs: &[Job<'_>], rows: Vec<ClosedLoopBuffers<'a>>) -> Vec<Item<'a>> {
    use crate::lanes::{lane_key, LANES};
    let mut rows: Vec<Option<ClosedLoopBuffers<'a>>> = rows.into_iter().map(Some).collect();
    let mut items = Vec::new();
    for start in (0..jobs.len()).step_by(LANES) {
        if start + LANES > jobs.len() {
            break;
        }
        let idx: [usize; LANES] = std::array::from_fn(|l| start + l);
        let key = lane_key(&jobs[start].axis, jobs[start].controller.as_ref(), &jobs[start].input);
        if key.is_some() && idx.iter().all(|&j| lane_key(&jobs[j].axis, jobs[j].controller.as_ref(), &jobs[j].input) == key) {
            let bufs = idx.map(|j| rows[j].take().expect("each row once"));
            items.push(Item::Lanes(Box::new((idx, bufs))));
        }
    }
    for (i, row) in rows.iter_mut().enumerate() {
        if let Some(b) = row.take() {
            items.push(Item::Single(i, b));
        }
    }
    items
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
    let mut out = try_zeroed("forces", models.len().saturating_mul(n)).map_err(|error| BatchError { run: 0, error })?;
    if models.is_empty() || n == 0 {
        crate::error::check::increasing("t", t, 2).map_err(|error| BatchError { run: 0, error })?;
        return Ok(out);
    }
    let rows: Vec<(usize, (&mut [f64], &FrictionModel))> = out.chunks_mut(n).zip(models.iter()).enumerate().collect();
    let results: Vec<Result<()>> = map_items(opts.threads, rows, |(i, (row, model))| {
        if opts.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(CoreError::Interrupted);
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
    .map_err(|error| BatchError { run: 0, error })?;
    match results.into_iter().enumerate().find(|(_, r)| r.is_err()) {
        Some((run, Err(error))) => Err(BatchError { run, error }),
        _ => Ok(out),
    }
}

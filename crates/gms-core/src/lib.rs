//! # gms-core
//!
//! Friction models and servo-axis simulation for precision positioning, in SI units throughout
//! (m, m/s, N, s). No Python here: the `gms-py` crate is the thin binding.
//!
//! - [`stribeck`]: the Stribeck curve and the static friction map (Coulomb + viscous + Stribeck).
//! - [`friction`]: GMS, Maxwell-slip and LuGre elements with exact per-step updates, and
//!   friction-only simulation along measured trajectories.
//! - [`plant`]: `a / (s^2 + b s + c)` with an input delay, exact ZOH with fractional delays.
//! - [`control`]: PID and the EMPS cascade controller.
//! - [`effects`]: effects beyond the friction model, in feedback (position- and time-dependent
//!   friction and forces, asymmetry, extra pre-sliding blocks, a compliant load).
//! - [`closed_loop`]: the closed-loop (or open-loop) axis with friction and effects in the loop.
//! - [`fast`]: the latency-optimised closed loop with GMS friction (runtime CPU dispatch).
//! - [`lanes`]: batches of runs of the same structure advanced 4 per SIMD vector.
//! - [`batch`]: many closed-loop runs at once on all cores (sweeps, Monte Carlo), stacked outputs.
//! - [`reference`]: reference problems (the paper's axis, EMPS) shared by tests and benchmarks.

pub mod batch;
pub mod closed_loop;
pub mod control;
pub mod effects;
pub mod error;
pub mod fast;
pub mod lanes;
pub mod friction;
pub mod numeric;
pub mod plant;
pub mod reference;
pub mod stribeck;

pub use closed_loop::{simulate, simulate_open_loop, simulate_generic, simulate_generic_into, simulate_into, Axis, ClosedLoopBuffers, ClosedLoopInput, ClosedLoopOutput, NoFriction, Record};
pub use control::{Cascade, Controller, ControllerModel, OpenLoop, Pid, PidDob};
pub use effects::{Asymmetry, Compliance, Drift, DriftShape, Effects, EffectsElement, Heating, PositionSeries};
pub use error::{CoreError, Result};
pub use friction::{simulate_position, simulate_velocity, Coupling, FrictionElement, FrictionModel, Gms, LuGre, MaxwellSlip, SlipLaw, StaticElement};
pub use plant::{DelayLine, DiscretePlant, Plant};
pub use stribeck::{LevelShift, StaticFriction, Stribeck};

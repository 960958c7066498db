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
//! - [`closed_loop`]: the closed-loop axis with friction in the loop.
//! - [`batch`]: many closed-loop runs at once on all cores (sweeps, Monte Carlo), stacked outputs.
//! - [`reference`]: reference problems (the paper's axis, EMPS) shared by tests and benchmarks.

pub mod batch;
pub mod closed_loop;
pub mod control;
pub mod error;
pub mod friction;
pub mod numeric;
pub mod plant;
pub mod reference;
pub mod stribeck;

pub use closed_loop::{simulate, simulate_generic, simulate_generic_into, simulate_into, ClosedLoopBuffers, ClosedLoopInput, ClosedLoopOutput, NoFriction};
pub use control::{Cascade, Controller, ControllerModel, Pid};
pub use error::{CoreError, Result};
pub use friction::{simulate_position, simulate_velocity, Coupling, FrictionElement, FrictionModel, Gms, LuGre, MaxwellSlip, SlipLaw, StaticElement};
pub use plant::{simulate_open_loop, DelayLine, DiscretePlant, Plant};
pub use stribeck::{StaticFriction, Stribeck};

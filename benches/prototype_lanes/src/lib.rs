//! Prototype (not part of the gmsfric workspace): a shorter-latency closed-loop step, runs
//! batched in SIMD lanes, and runtime CPU dispatch for a portable build.
pub mod dispatch;
pub mod fexp;
pub mod lanes;
pub mod poly;
pub mod setup;
pub mod single;

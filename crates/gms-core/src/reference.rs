//! Reference problems shared by the tests and the criterion benchmarks (as diffsol's
//! `test_models`): the paper's axis under its "consistent units" reading, and the EMPS axis.
//! The Python presets (`gmsfric.presets`) document the readings in detail.

use crate::control::{Cascade, Pid};
use crate::friction::{Gms, SlipLaw};
use crate::plant::Plant;
use crate::stribeck::{StaticFriction, Stribeck};

/// Paper Table 1 read with consistent units: Fc = 0.1826 N, Fs = 0.210 N, Vs = 0.45 mm/s,
/// sigma = 6.9846 N s/m, delta = 1.
pub fn paper_stribeck() -> Stribeck {
    Stribeck::new(0.1826, 0.210, 0.45e-3, 1.0).expect("valid constants")
}

pub fn paper_static() -> StaticFriction {
    StaticFriction::new(paper_stribeck(), 6.9846).expect("valid constants")
}

/// Paper Table 2 blocks: k in N/m, alpha (printed in N) normalised to fractions.
pub fn paper_gms() -> Gms {
    let w = [0.0330, 0.0570, 0.0132, 0.0026];
    let sum: f64 = w.iter().sum();
    Gms::new(
        paper_stribeck(),
        vec![3264.7059e3, 8.8941e3, 23.7869e3, 2.6131e3],
        w.iter().map(|x| x / sum).collect(),
        1.0 / 0.45e-3,
        6.9846,
        SlipLaw::Time,
    )
    .expect("valid constants")
}

/// A GMS with `n` blocks spanning stiffnesses 1e4..1e7 N/m (benchmark scaling in N).
pub fn gms_with_blocks(n: usize) -> Gms {
    let k: Vec<f64> = (0..n).map(|i| 1e7 * 10f64.powf(-3.0 * i as f64 / n.max(1) as f64)).collect();
    let alpha = vec![1.0 / n as f64; n];
    Gms::new(paper_stribeck(), k, alpha, 1.0 / 0.45e-3, 6.9846, SlipLaw::Time).expect("valid constants")
}

/// Paper eq. 1 in SI: a = 19.85 mm/(V s^2) = 0.01985 m/(V s^2), b = 168.4 1/s, c = 176.8 1/s^2,
/// delay 1.29 ms, 1 N of friction per volt of drive input.
pub fn paper_plant() -> Plant {
    Plant::new(0.01985, 168.4, 176.8, 1.29e-3, 1.0).expect("valid constants")
}

/// A PID that closes the paper's axis at roughly 10 Hz with ~65 degrees of phase margin.
pub fn paper_pid(dt: f64) -> Pid {
    Pid::new(5.0e5, 2.5e6, 1.0e3, 5e-4, -10.0, 10.0, dt).expect("valid constants")
}

/// The paper's Section 4.2 reference: 10 mm amplitude, 0.01 Hz sine (starting at 0).
pub fn paper_sine(n: usize, dt: f64, amplitude: f64, freq: f64) -> Vec<f64> {
    (0..n).map(|k| amplitude * (2.0 * std::f64::consts::PI * freq * k as f64 * dt).sin()).collect()
}

/// EMPS rigid axis: M = 95.11 kg, Fv = 203.5 N s/m (as plant damping), gtau = 35.15 N/V.
pub fn emps_plant() -> Plant {
    Plant::from_mass(95.11, 0.0, 0.0, 0.0, 35.15).expect("valid constants")
}

/// EMPS controller at 1 kHz with the 10 V drive limit.
pub fn emps_controller() -> Cascade {
    Cascade::new(160.18, 243.45, -10.0, 10.0, 1e-3).expect("valid constants")
}

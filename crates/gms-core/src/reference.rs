//! Reference problems shared by the tests and the criterion benchmarks (as diffsol's
//! `test_models`): the paper's axis under its default reading, and the EMPS axis.
//!
//! The numbers come from `data/reference.json`, the one file that also feeds the Python presets
//! (`gmsfric.presets`, which documents every reading of the paper's garbled units): the two
//! sides cannot drift apart.

use crate::control::{Cascade, Pid};
use crate::friction::{Gms, SlipLaw};
use crate::plant::Plant;
use crate::stribeck::{StaticFriction, Stribeck};
use serde_json::Value;
use std::sync::OnceLock;

/// The reference data file, as text (the binding hands it to Python).
pub const DATA: &str = include_str!("../data/reference.json");

fn data() -> &'static Value {
    static PARSED: OnceLock<Value> = OnceLock::new();
    PARSED.get_or_init(|| serde_json::from_str(DATA).expect("data/reference.json is valid JSON (checked by the tests)"))
}

/// The number at a `/`-separated path of the data file.
pub fn number(path: &str) -> f64 {
    path.split('/')
        .fold(data(), |v, key| match key.parse::<usize>() {
            Ok(i) => &v[i],
            Err(_) => &v[key],
        })
        .as_f64()
        .unwrap_or_else(|| panic!("reference.json has no number at {path}"))
}

fn numbers(path: &str) -> Vec<f64> {
    let n = path.split('/').fold(data(), |v, key| &v[key]).as_array().map_or(0, Vec::len);
    (0..n).map(|i| number(&format!("{path}/{i}"))).collect()
}

/// Paper Table 1 under the default reading: Fc = 0.1826 N, Fs = 0.210 N, Vs = 0.45 mm/s,
/// sigma = 6.9846 N s/m, delta = 1.
pub fn paper_stribeck() -> Stribeck {
    let t = "paper/table1";
    Stribeck::new(
        number(&format!("{t}/fc_N")),
        number(&format!("{t}/fs_printed")) * number("paper/reading/fs_scale"),
        number(&format!("{t}/vs_printed_mm_per_s")) * 1e-3 * number("paper/reading/vs_scale"),
        number(&format!("{t}/delta")),
    )
    .expect("valid constants")
}

fn paper_sigma() -> f64 {
    number("paper/table1/sigma_printed_N_s_per_mm") * number("paper/reading/sigma_unit")
}

pub fn paper_static() -> StaticFriction {
    StaticFriction::new(paper_stribeck(), paper_sigma()).expect("valid constants")
}

/// Paper Table 2 blocks: k in N/m, alpha (printed in N) normalised to fractions; c = 1/Vs.
pub fn paper_gms() -> Gms {
    let w = numbers("paper/table2/w_N");
    let sum: f64 = w.iter().sum();
    let st = paper_stribeck();
    Gms::new(
        st,
        numbers("paper/table2/k_N_per_mm").iter().map(|k| k * 1e3).collect(),
        w.iter().map(|x| x / sum).collect(),
        1.0 / st.vs,
        paper_sigma(),
        SlipLaw::Time,
    )
    .expect("valid constants")
}

/// A GMS with `n` blocks spanning stiffnesses 1e4..1e7 N/m (benchmark scaling in N).
pub fn gms_with_blocks(n: usize) -> Gms {
    let k: Vec<f64> = (0..n).map(|i| 1e7 * 10f64.powf(-3.0 * i as f64 / n.max(1) as f64)).collect();
    let alpha = vec![1.0 / n as f64; n];
    let st = paper_stribeck();
    Gms::new(st, k, alpha, 1.0 / st.vs, paper_sigma(), SlipLaw::Time).expect("valid constants")
}

/// Paper eq. 1 in SI: a = 19.85 mm/(V s^2) = 0.01985 m/(V s^2), b = 168.4 1/s, c = 176.8 1/s^2,
/// delay 1.29 ms, the default reading's force per volt.
pub fn paper_plant() -> Plant {
    let e = "paper/eq1";
    Plant::new(
        number(&format!("{e}/a_mm_per_V_s2")) * 1e-3,
        number(&format!("{e}/b_per_s")),
        number(&format!("{e}/c_per_s2")),
        number(&format!("{e}/delay_s")),
        number("paper/reading/force_per_volt"),
    )
    .expect("valid constants")
}

/// The PID of the paper's axis (the paper gives none; see `gmsfric.presets.paper_pid`), limited
/// to the amplified drive range.
pub fn paper_pid() -> Pid {
    let lim = number("paper/reading/drive_limit_V");
    Pid::new(number("paper/pid/kp"), number("paper/pid/ki"), number("paper/pid/kd"), number("paper/pid/tf_s"), -lim, lim).expect("valid constants")
}

/// The paper's Section 4.2 reference: 10 mm amplitude, 0.01 Hz sine (starting at 0).
pub fn paper_sine(n: usize, dt: f64, amplitude: f64, freq: f64) -> Vec<f64> {
    (0..n).map(|k| amplitude * (2.0 * std::f64::consts::PI * freq * k as f64 * dt).sin()).collect()
}

/// EMPS rigid axis: M = 95.11 kg driven by gtau = 35.15 N/V (friction lives in the friction model).
pub fn emps_plant() -> Plant {
    Plant::from_mass(number("emps/reference_model/M_kg"), 0.0, 0.0, 0.0, number("emps/gtau_N_per_V")).expect("valid constants")
}

/// EMPS reference friction `Fv qd + Fc sign(qd) + offset`.
pub fn emps_friction() -> StaticFriction {
    let m = "emps/reference_model";
    let fc = number(&format!("{m}/Fc_N"));
    StaticFriction::new(Stribeck::constant(fc).expect("valid"), number(&format!("{m}/Fv_N_s_per_m")))
        .and_then(|f| f.with_offset(number(&format!("{m}/offset_N"))))
        .expect("valid constants")
}

/// EMPS cascade controller with its drive limit.
pub fn emps_controller() -> Cascade {
    let lim = number("emps/drive_limit_V");
    Cascade::new(number("emps/kp_per_s"), number("emps/kv_V_s_per_m"), -lim, lim).expect("valid constants")
}

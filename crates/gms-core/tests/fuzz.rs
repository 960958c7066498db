//! No input makes the core panic or return a non-finite number as a success.
//!
//! Property tests over the public constructors and simulators: parameters are drawn mostly from
//! physical ranges and, parameter by parameter, from the whole line of doubles (subnormal,
//! 1e308, -0.0, NaN, inf). Every call must either return an error or a result whose every
//! number is finite; a panic fails the test (proptest catches it and shrinks the input).
//!
//! `cargo test -p gms-core --test fuzz` runs a short profile (a few hundred cases per property);
//! `PROPTEST_CASES=20000 cargo test --release -p gms-core --test fuzz` a long one.

use gms_core::*;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed, TestRunner};

/// Doubles a hostile caller would pick.
const SPECIAL: [f64; 22] = [
    0.0,
    -0.0,
    5e-324,
    1e-310,
    f64::MIN_POSITIVE,
    1e-300,
    1e-30,
    1e-12,
    1e-9,
    1.0,
    -1.0,
    1e9,
    1e12,
    1e30,
    1e44,
    1e100,
    1e300,
    f64::MAX,
    -f64::MAX,
    f64::INFINITY,
    f64::NEG_INFINITY,
    f64::NAN,
];

/// `m 10^e`, mantissa in [1, 10).
fn log_uniform(lo: i32, hi: i32) -> impl Strategy<Value = f64> {
    (1.0f64..10.0, lo..=hi).prop_map(|(m, e)| m * 10f64.powi(e))
}

/// Any double: special values, log-uniform of either sign across the whole range, or raw bits.
fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        3 => proptest::sample::select(&SPECIAL[..]),
        3 => (log_uniform(-320, 307), any::<bool>()).prop_map(|(x, neg)| if neg { -x } else { x }),
        1 => any::<u64>().prop_map(f64::from_bits),
    ]
}

/// A positive physical value most of the time, any double sometimes.
fn pos() -> impl Strategy<Value = f64> {
    prop_oneof![6 => log_uniform(-4, 4), 1 => any_f64()]
}

/// Non-negative most of the time (zero included), any double sometimes.
fn nonneg() -> impl Strategy<Value = f64> {
    prop_oneof![2 => Just(0.0), 6 => log_uniform(-4, 4), 1 => any_f64()]
}

/// A signed physical value most of the time.
fn real() -> impl Strategy<Value = f64> {
    prop_oneof![6 => (log_uniform(-4, 4), any::<bool>()).prop_map(|(x, n)| if n { -x } else { x }), 1 => Just(0.0), 1 => any_f64()]
}

/// A time step: the usual ones, or anything.
fn step() -> impl Strategy<Value = f64> {
    prop_oneof![4 => proptest::sample::select(&[1e-4, 1e-3, 2.5e-4, 1e-5][..]), 1 => log_uniform(-12, 3), 1 => any_f64()]
}

/// A delay (s): none, a realistic one, or anything (1e300 s at a step of 1e-9 s...).
fn delay() -> impl Strategy<Value = f64> {
    prop_oneof![3 => Just(0.0), 3 => log_uniform(-5, -2), 1 => proptest::sample::select(&[1e3, 1e6, 1e10, 1e20, 1e300][..]), 1 => any_f64()]
}

/// A signal of `n` samples: mostly a scaled sine, sometimes with one hostile sample.
fn signal(n: usize) -> impl Strategy<Value = Vec<f64>> {
    (real(), 0.1f64..5.0, proptest::option::weighted(0.1, (0..n.max(1), any_f64()))).prop_map(move |(amp, cycles, bad)| {
        let mut v: Vec<f64> = (0..n).map(|k| amp * (2.0 * std::f64::consts::PI * cycles * k as f64 / n.max(2) as f64).sin()).collect();
        if let Some((i, x)) = bad {
            if i < v.len() {
                v[i] = x;
            }
        }
        v
    })
}

fn fractions(n: usize) -> impl Strategy<Value = Vec<f64>> {
    prop_oneof![
        4 => proptest::collection::vec(0.01f64..1.0, n).prop_map(|w| {
            let s: f64 = w.iter().sum();
            w.iter().map(|x| x / s).collect()
        }),
        1 => proptest::collection::vec(any_f64(), n),
    ]
}

fn stribeck() -> BoxedStrategy<Result<Stribeck>> {
    (nonneg(), nonneg(), pos(), prop_oneof![3 => Just(1.0), 1 => Just(2.0), 1 => pos()]).prop_map(|(fc, fs, vs, d)| Stribeck::new(fc, fs, vs, d))
    .boxed()
}

/// Any friction model the core can build from the drawn parameters (`Err`: the constructor refused).
fn friction() -> BoxedStrategy<Result<FrictionModel>> {
    prop_oneof![
        (stribeck(), nonneg(), real(), prop_oneof![3 => Just(0.0), 1 => pos()]).prop_map(|(s, sigma, offset, v_lin)| {
            let map = StaticFriction::new(s?, sigma)?.with_offset(offset)?.with_linear_region(v_lin)?;
            Ok(FrictionModel::Static(StaticElement::new(map)))
        }),
        (1usize..5).prop_flat_map(|n| (stribeck(), proptest::collection::vec(pos(), n), fractions(n), pos(), nonneg(), any::<bool>()))
            .prop_map(|(s, k, a, c, sigma, disp)| {
                let law = if disp { SlipLaw::Displacement } else { SlipLaw::Time };
                Ok(FrictionModel::Gms(Gms::new(s?, k, a, c, sigma, law)?))
            }),
        (1usize..5).prop_flat_map(|n| (proptest::collection::vec(pos(), n), proptest::collection::vec(nonneg(), n), nonneg()))
            .prop_map(|(k, w, sigma)| Ok(FrictionModel::MaxwellSlip(MaxwellSlip::new(k, w, sigma)?))),
        (stribeck(), pos(), nonneg(), nonneg()).prop_map(|(s, s0, s1, s2)| Ok(FrictionModel::LuGre(LuGre::new(s?, s0, s1, s2)?))),
    ]
    .boxed()
}

fn plant() -> BoxedStrategy<Result<Plant>> {
    prop_oneof![
        4 => (pos(), nonneg(), nonneg(), delay(), pos()).prop_map(|(a, b, c, d, g)| Plant::new(a, b, c, d, g)),
        1 => (pos(), nonneg(), nonneg(), delay(), pos()).prop_map(|(m, d, k, del, g)| Plant::from_mass(m, d, k, del, g)),
    ]
    .boxed()
}

fn pid() -> BoxedStrategy<Result<Pid>> {
    (real(), real(), real(), prop_oneof![2 => Just(0.0), 1 => pos()], proptest::option::weighted(0.25, (real(), real()))).prop_map(
        |(kp, ki, kd, tf, lim)| {
            let (lo, hi) = lim.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
            Pid::new(kp, ki, kd, tf, lo.min(hi), hi.max(lo))
        },
    )
    .boxed()
}

fn controller() -> BoxedStrategy<Option<Result<ControllerModel>>> {
    prop_oneof![
        1 => Just(None),
        3 => pid().prop_map(|p| Some(p.map(ControllerModel::Pid))),
        1 => (real(), real()).prop_map(|(kp, kv)| Some(Cascade::new(kp, kv, f64::NEG_INFINITY, f64::INFINITY).map(ControllerModel::Cascade))),
        1 => (pid(), pos(), nonneg(), nonneg(), delay(), pos())
            .prop_map(|(p, a, b, c, d, f)| Some(p.and_then(|p| PidDob::new(p, a, b, c, d, f)).map(ControllerModel::PidDob))),
    ]
    .boxed()
}

fn series() -> BoxedStrategy<PositionSeries> {
    prop_oneof![
        (real(), real(), proptest::collection::vec(real(), 1..5), proptest::bool::ANY)
            .prop_map(|(lo, hi, coef, linear_beyond)| PositionSeries::Legendre { lo, hi, coef, linear_beyond }),
        (proptest::collection::vec(pos(), 1..3), 0usize..4)
            .prop_flat_map(|(p, h)| {
                let n = 2 * p.len() * h.max(1);
                (Just(p), Just(h), proptest::collection::vec(real(), n))
            })
            .prop_map(|(periods, harmonics, coef)| PositionSeries::Fourier { periods, harmonics, coef }),
        (real(), pos(), proptest::collection::vec(real(), 1..6)).prop_map(|(q0, dq, values)| PositionSeries::Table { q0, dq, values }),
    ]
    .boxed()
}

fn effects() -> BoxedStrategy<Result<Effects>> {
    (
        proptest::option::of((real(), real())),
        proptest::option::of(series()),
        proptest::option::of(series()),
        proptest::option::of((any::<bool>(), pos(), real(), real())),
        proptest::option::of((pos(), real(), real())),
        proptest::option::of((1usize..3).prop_flat_map(|n| (proptest::collection::vec(pos(), n), proptest::collection::vec(nonneg(), n)))),
        proptest::option::of((pos(), pos(), nonneg())),
    )
        .prop_map(|(asym, pf, pfr, drift, heat, blocks, comp)| {
            Ok(Effects {
                asymmetry: asym.map(|(d_level, d_viscous)| Asymmetry { d_level, d_viscous }),
                position_force: pf,
                position_friction: pfr,
                drift: drift.map(|(lin, scale, d_level, d_viscous)| Drift {
                    shape: if lin { DriftShape::Linear { duration: scale } } else { DriftShape::Exponential { tau: scale } },
                    d_level,
                    d_viscous,
                }),
                heating: heat.map(|(tau, d_level, d_viscous)| Heating { tau, d_level, d_viscous }),
                blocks: blocks.map(|(k, w)| MaxwellSlip::new(k, w, 0.0)).transpose()?,
                compliance: comp.map(|(m, f, z)| Compliance::new(m, f, z)).transpose()?,
            })
        })
    .boxed()
}

/// The options of a run besides reference and step.
#[derive(Debug, Clone)]
struct Options {
    feedforward: Option<Vec<f64>>,
    disturbance: Option<Vec<f64>>,
    load: Option<Vec<f64>>,
    noise: Option<Vec<f64>>,
    quantization: f64,
    limits: (f64, f64),
    x0: Option<f64>,
    v0: f64,
    every: usize,
}

fn options(n: usize) -> impl Strategy<Value = Options> {
    let arr = move || proptest::option::weighted(0.25, signal(n));
    (
        (arr(), arr(), arr(), arr()),
        prop_oneof![4 => Just(0.0), 1 => Just(1e-6), 1 => any_f64()],
        prop_oneof![3 => Just((f64::NEG_INFINITY, f64::INFINITY)), 1 => (real(), real())],
        (proptest::option::weighted(0.2, real()), prop_oneof![4 => Just(0.0), 1 => real()], prop_oneof![4 => Just(1usize), 1 => 1usize..100]),
    )
        .prop_map(|((feedforward, disturbance, load, noise), quantization, limits, (x0, v0, every))| Options {
            feedforward,
            disturbance,
            load,
            noise,
            quantization,
            limits,
            x0,
            v0,
            every,
        })
}

fn assert_all_finite(what: &str, v: &[f64]) -> std::result::Result<(), TestCaseError> {
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(TestCaseError::fail(format!("{what}[{i}] = {} returned as Ok", v[i])));
    }
    Ok(())
}

/// Run the property `test` on 256 inputs from `strategy` (fixed seed; `PROPTEST_CASES` and
/// `PROPTEST_RNG_SEED` override) on a thread with a large stack
/// (the nested strategies of an unoptimised build need more than the default 2 MiB); a failure
/// reports the shrunk input.
fn check<S, F>(strategy: impl FnOnce() -> S + Send + 'static, test: F)
where
    S: Strategy,
    S::Value: std::fmt::Debug,
    F: Fn(S::Value) -> std::result::Result<(), TestCaseError> + Send + 'static,
{
    let runner = std::thread::Builder::new().stack_size(256 << 20).spawn(move || {
        let defaults = Config::default(); // reads PROPTEST_CASES and PROPTEST_RNG_SEED
        let seed = if std::env::var_os("PROPTEST_RNG_SEED").is_some() { defaults.rng_seed } else { RngSeed::Fixed(11) };
        let cases = if std::env::var_os("PROPTEST_CASES").is_some() { defaults.cases } else { 256 };
        let mut runner = TestRunner::new(Config { cases, rng_seed: seed, failure_persistence: None, ..defaults });
        runner.run(&strategy(), test).map_err(|e| e.to_string())
    });
    if let Err(message) = runner.expect("spawn the property thread").join().expect("the property thread panicked outside a case") {
        panic!("{message}");
    }
}

#[test]
fn plant_discretisation_is_finite_or_refused() {
    check(|| (plant(), step()), |(p, dt)| {
        if let Ok(p) = p {
            if let Ok(d) = p.discretize(dt) {
                assert_all_finite("phi", d.phi.as_slice())?;
                assert_all_finite("gamma_old", d.gamma_old.as_slice())?;
                assert_all_finite("gamma_new", d.gamma_new.as_slice())?;
                assert_all_finite("gamma_force", d.gamma_force.as_slice())?;
                prop_assert!(d.delay_steps <= plant::MAX_DELAY_STEPS);
            }
        }
        Ok(())
    });
}

#[test]
fn controllers_prepare_or_refuse() {
    check(|| (controller(), step(), signal(8), signal(8)), |(c, dt, r, y)| {
        if let Some(Ok(mut c)) = c {
            if with_controller!(&mut c, c => c.prepare(dt)).is_ok() {
                // A prepared controller's update is total (it may saturate or overflow: the
                // simulator checks every command).
                for (&r, &y) in r.iter().zip(&y) {
                    let _ = with_controller!(&mut c, c => c.update(r, y));
                }
            }
        }
        Ok(())
    });
}

#[test]
fn friction_along_a_trajectory_is_finite_or_refused() {
    let run = || (friction(), (2usize..80).prop_flat_map(|n| (proptest::collection::vec(step(), n), signal(n))));
    check(run, |(model, (steps, x))| {
        if let Ok(mut model) = model {
            // Times from the drawn steps (a non-positive or non-finite step must be refused).
            let t: Vec<f64> = steps.iter().scan(0.0, |acc, dt| { *acc += dt; Some(*acc) }).collect();
            let x: Vec<f64> = x.iter().map(|v| v * 1e-3).collect();
            if let Ok(f) = with_friction!(&mut model, f => simulate_position(f, &t, &x)) {
                assert_all_finite("force", &f)?;
            }
        }
        Ok(())
    });
}

#[test]
fn axis_construction_checks_the_effects() {
    check(|| (plant(), proptest::option::of(friction()), effects()), |(p, f, e)| {
        if let (Ok(p), Ok(e)) = (p, e) {
            let f = match f { Some(Ok(f)) => Some(f), Some(Err(_)) => return Ok(()), None => None };
            if Axis::new(p, f.clone(), Some(e.clone())).is_ok() {
                // What the axis accepts, the element accepts too.
                if let Some(f) = f {
                    prop_assert!(with_friction!(f, f => EffectsElement::new(f, e.clone()).map(|_| ())).is_ok() || !e.shifts_levels());
                }
            }
        }
        Ok(())
    });
}

#[test]
fn closed_loop_runs_are_finite_or_refused() {
    let run = || {
        let sizes = prop_oneof![4 => 1usize..64, 1 => Just(40_000usize)];
        (plant(), proptest::option::weighted(0.6, friction()), proptest::option::weighted(0.3, effects()), controller(), step(),
         sizes.prop_flat_map(|n| (signal(n), options(n))))
    };
    check(run, |(p, f, e, c, dt, (r, o))| {
        let Ok(p) = p else { return Ok(()) };
        let f = match f { Some(Ok(f)) => Some(f), Some(Err(_)) => return Ok(()), None => None };
        let e = match e { Some(Ok(e)) => Some(e), Some(Err(_)) => return Ok(()), None => None };
        let c = match c { Some(Ok(c)) => Some(c), Some(Err(_)) => return Ok(()), None => None };
        let Ok(axis) = Axis::new(p, f, e) else { return Ok(()) };
        let ff_open = o.feedforward.clone().unwrap_or_else(|| r.clone());
        let mut input = if c.is_some() { ClosedLoopInput::new(&r, dt) } else { ClosedLoopInput::open(&ff_open, dt) };
        if c.is_some() {
            input.feedforward = o.feedforward.as_deref();
        }
        input.input_disturbance = o.disturbance.as_deref();
        input.load_force = o.load.as_deref();
        input.measurement_noise = o.noise.as_deref();
        input.quantization = o.quantization;
        input.drive_min = o.limits.0;
        input.drive_max = o.limits.1;
        if let Some(x0) = o.x0 {
            input.initial_position = x0;
        }
        input.initial_velocity = o.v0;
        let full = axis.simulate(c.as_ref(), &input);
        if let Ok(out) = &full {
            assert_all_finite("position", &out.position)?;
            assert_all_finite("velocity", &out.velocity)?;
            assert_all_finite("measured", &out.measured)?;
            assert_all_finite("command", &out.command)?;
            assert_all_finite("friction", &out.friction)?;
        }
        // The same run recorded into decimated buffers: the same verdict, finite outputs.
        let m = input.len().div_ceil(o.every);
        let (mut pos, mut err) = (vec![0.0; m], vec![0.0; m]);
        let bufs = ClosedLoopBuffers { position: Some(&mut pos), error: Some(&mut err), every: o.every, ..Default::default() };
        let decimated = axis.simulate_into(c.as_ref(), &input, bufs);
        prop_assert_eq!(full.is_ok(), decimated.is_ok());
        if decimated.is_ok() {
            assert_all_finite("position (decimated)", &pos)?;
            assert_all_finite("error (decimated)", &err)?;
        }
        Ok(())
    });
}

#[test]
fn open_loop_plant_runs_are_finite_or_refused() {
    check(|| (plant(), step(), (1usize..64).prop_flat_map(signal)), |(p, dt, u)| {
        if let Ok(p) = p {
            if let Ok((y, v)) = simulate_open_loop(&p, dt, &u) {
                assert_all_finite("position", &y)?;
                assert_all_finite("velocity", &v)?;
            }
        }
        Ok(())
    });
}

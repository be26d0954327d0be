//! The half car on one road: road cancellation on the half car's physical
//! structure (12 parameters, `m1`, `m2`, `l1`, `l2` known) gives every one of the 28 non-zero
//! entries of the four unknown rows of `A` within 5 % after 20,000 samples, on at least 9 of
//! 10 seeds; the rows identifier ([`TwoAxleIdentifier`], method `Cancel`) beside it on the
//! same samples.
//!
//! The setting is the README's "Two axles on one road": the thesis' half car, a sample every
//! 0.3 m at 6 m/s (`d = 3 m / 0.3 m = 10`), white road σ_u 0.1 m, derivative noise σ_v 0.005.
//! `cargo test -p vehid-core --test integration half_one_road:: -- --nocapture` prints the per-seed worst
//! entries; `SEED0=70000 cargo test --release -p vehid-core --test integration
//! half_one_road::fresh_seeds -- --ignored --nocapture` measures on ten other seeds.

use crate::common::median;
use vehid_core::identify::{
    Identifier, TwoAxleConfig, TwoAxleIdentifier, TwoAxleStructuredConfig, TwoAxleStructuredKalman, WheelMethod,
};
use vehid_core::model::{HalfCar, PhysicalStructure};
use vehid_core::sim::{RoadConfig, RoadSimulator, SimConfig};
use vehid_core::structure::Structure;
use vehid_core::Error;

const SPACING: f64 = 0.3;
const SPEED: f64 = 6.0;
const D: usize = 10;
const ROAD_SIGMA: f64 = 0.1;
const DERIV_NOISE: f64 = 0.005;
const SAMPLES: usize = 20_000;

type Physical = TwoAxleStructuredKalman<f64, 4, 3, 16>;
type Rows = TwoAxleIdentifier<f64, 8, 16, 2, 16>;

/// The half car's physical structure with `m1`, `m2`, `l1`, `l2` known: 12 parameters.
fn physical_structure() -> PhysicalStructure<f64> {
    let c = HalfCar::<f64>::thesis().constants();
    let mut known = [None; 12];
    for i in 8..12 {
        known[i] = Some(c[i]);
    }
    HalfCar::structure(known).unwrap()
}

fn road_sim(seed: u64) -> RoadSimulator<f64, 8, 16> {
    let car = HalfCar::<f64>::thesis();
    let cfg = SimConfig::new(SPACING / SPEED).road_sigma(ROAD_SIGMA).deriv_noise(DERIV_NOISE);
    RoadSimulator::new(car.model(), cfg, RoadConfig::new(SPACING, car.wheelbase()), seed).unwrap()
}

fn physical(cfg: TwoAxleStructuredConfig<f64>) -> Physical {
    let car = HalfCar::<f64>::thesis();
    Physical::new(*physical_structure().structure(), &car.model(), D, cfg).unwrap()
}

fn rows_identifier() -> Rows {
    let car = HalfCar::<f64>::thesis();
    Rows::new(&car.model(), D, TwoAxleConfig::new(WheelMethod::Cancel, 1000.0, ROAD_SIGMA, DERIV_NOISE)).unwrap()
}

/// The largest relative error over the 28 non-zero entries of rows 1, 3, 5, 7 of `A`, given
/// the estimated rows `est` (`(row of A, its 8 entries)`).
fn worst_entry(est: &[(usize, [f64; 8])]) -> f64 {
    let a = *HalfCar::<f64>::thesis().model().a();
    let mut worst: f64 = 0.0;
    let mut count = 0;
    for (row, e) in est {
        for j in 0..8 {
            let t = a[(*row, j)];
            if t != 0.0 {
                worst = worst.max(((e[j] - t) / t).abs());
                count += 1;
            }
        }
    }
    assert_eq!(count, 28);
    worst
}

/// The physical identifier's rows of `A` (its equations' states: 5, 7, 1, 3).
fn physical_rows(id: &Physical) -> Vec<(usize, [f64; 8])> {
    let mut out = [0.0; 32];
    id.a_rows_into(&mut out).unwrap();
    id.rows().iter().enumerate().map(|(i, &r)| (r, out[8 * i..8 * i + 8].try_into().unwrap())).collect()
}

fn rows_rows(id: &Rows) -> Vec<(usize, [f64; 8])> {
    let t = id.theta::<4>().unwrap();
    (0..4).map(|i| (id.rows()[i], core::array::from_fn(|j| t[(i, j)]))).collect()
}

/// One seed: `n` samples fed to the physical identifier(s) configured by `cfgs` and to the
/// rows identifier; returns each one's worst entry error (the rows identifier's last).
fn run(seed: u64, n: usize, cfgs: &[TwoAxleStructuredConfig<f64>]) -> Vec<f64> {
    let mut sim = road_sim(seed);
    let mut ids: Vec<Physical> = cfgs.iter().map(|&c| physical(c)).collect();
    let mut rows = rows_identifier();
    let mut e = [0.0; 4];
    for _ in 0..n {
        let s = sim.next_sample(SPEED).unwrap();
        for id in ids.iter_mut() {
            id.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
        }
        rows.update(&s.r, &s.z).unwrap();
    }
    let mut out: Vec<f64> = ids.iter().map(|id| worst_entry(&physical_rows(id))).collect();
    out.push(worst_entry(&rows_rows(&rows)));
    out
}

/// Runs `f` on each seed, on two threads.
fn over_seeds<R: Send>(seeds: &[u64], f: impl Fn(u64) -> R + Sync) -> Vec<R> {
    let f = &f;
    std::thread::scope(|scope| {
        let (a, b) = seeds.split_at(seeds.len() / 2);
        let h = scope.spawn(move || a.iter().map(|&s| f(s)).collect::<Vec<_>>());
        let mut tail: Vec<R> = b.iter().map(|&s| f(s)).collect();
        let mut out = h.join().unwrap();
        out.append(&mut tail);
        out
    })
}

/// Per-seed worst entries of each variant, printed; returns them per variant.
fn table(seeds: &[u64], names: &[&str], cfgs: &[TwoAxleStructuredConfig<f64>]) -> Vec<Vec<f64>> {
    let runs = over_seeds(seeds, |s| run(s, SAMPLES, cfgs));
    let mut cols = vec![vec![]; names.len()];
    for (s, r) in seeds.iter().zip(&runs) {
        let cells: Vec<String> = r.iter().map(|v| format!("{:6.2} %", 100.0 * v)).collect();
        eprintln!("seed {s}: {}", cells.join("  "));
        for (c, v) in cols.iter_mut().zip(r) {
            c.push(*v);
        }
    }
    for (name, c) in names.iter().zip(&cols) {
        let within = c.iter().filter(|&&v| v <= 0.05).count();
        eprintln!(
            "{name:<40} worst entry after {SAMPLES} samples: median {:.2} %, worst {:.2} %, within 5 % on {within}/{}",
            100.0 * median(c),
            100.0 * c.iter().fold(0.0f64, |a, &b| a.max(b)),
            c.len()
        );
    }
    cols
}

fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

/// Development: variants of the physical identifier (exact start or a prior, with or
/// without the direct front equation) beside the rows identifier on seeds SEED0.. (SEEDS).
#[test]
#[ignore]
fn variants() {
    let seed0: u64 = env_or("SEED0", 1);
    let seeds: Vec<u64> = (seed0..seed0 + env_or("SEEDS", 10)).collect();
    let base = TwoAxleStructuredConfig::new(ROAD_SIGMA, DERIV_NOISE);
    let cfgs = [
        base,
        TwoAxleStructuredConfig { direct_front: false, ..base },
        TwoAxleStructuredConfig { p0: Some(1000.0), ..base },
        TwoAxleStructuredConfig { p0: Some(1000.0), direct_front: false, ..base },
        TwoAxleStructuredConfig { compensate: false, ..base },
        TwoAxleStructuredConfig { deriv_noise: 0.9 * DERIV_NOISE, ..base },
        TwoAxleStructuredConfig { deriv_noise: 1.1 * DERIV_NOISE, ..base },
    ];
    table(
        &seeds,
        &[
            "exact, direct front",
            "exact, no direct front",
            "p0 1000, direct front",
            "p0 1000, no direct front",
            "least squares (no compensation)",
            "σ_v assumed 10 % low",
            "σ_v assumed 10 % high",
            "rows (Cancel)",
        ],
        &cfgs,
    );
}

/// Must-show: every one of the 28 entries within 5 % after 20,000 samples on at
/// least 9 of 10 seeds (seeds 1–10, the ones the identifier was developed on; `fresh_seeds`
/// measures on others). The rows identifier's worst entries are printed beside it.
#[test]
fn every_entry_within_5_percent_on_9_of_10_seeds() {
    let seeds: Vec<u64> = (1..=10).collect();
    let cols = table(
        &seeds,
        &["physical structure (12 parameters)", "rows identifier (Cancel, 32 parameters)"],
        &[TwoAxleStructuredConfig::new(ROAD_SIGMA, DERIV_NOISE)],
    );
    let within = cols[0].iter().filter(|&&v| v <= 0.05).count();
    assert!(within >= 9, "physical structure: every entry within 5 % on {within}/10 seeds: {:?}", cols[0]);
}

/// The must-show on ten seeds never used in development: `SEED0=70000 cargo test --release
/// -p vehid-core --test integration half_one_road::fresh_seeds -- --ignored --nocapture`.
#[test]
#[ignore]
fn fresh_seeds() {
    let seed0: u64 = env_or("SEED0", 70000);
    let seeds: Vec<u64> = (seed0..seed0 + 10).collect();
    let cols = table(
        &seeds,
        &["physical structure (12 parameters)", "rows identifier (Cancel, 32 parameters)"],
        &[TwoAxleStructuredConfig::new(ROAD_SIGMA, DERIV_NOISE)],
    );
    let within = cols[0].iter().filter(|&&v| v <= 0.05).count();
    assert!(within >= 9, "physical structure: every entry within 5 % on {within}/10 seeds");
}

/// The 28 entries follow from the 12 parameters: at the true parameters
/// `Structure::linear_rows_into` gives rows 5, 7, 1, 3 of `A` exactly; and on noise-free
/// samples (σ_v = 0, the road still on) the identifier recovers them to rounding.
#[test]
fn rows_follow_from_the_parameters_and_are_exact_without_noise() {
    let ps = physical_structure();
    let car = HalfCar::<f64>::thesis();
    let a = *car.model().a();
    let mut p = [0.0; 12];
    ps.params_of(&car.constants(), &mut p).unwrap();
    let mut rows = [0.0; 32];
    ps.structure().linear_rows_into(&p, &mut rows).unwrap();
    for (i, r) in ps.structure().equation_states().enumerate() {
        for j in 0..8 {
            assert!((rows[8 * i + j] - a[(r, j)]).abs() < 1e-12 * a[(r, j)].abs().max(1.0), "row {r} col {j}");
        }
    }
    let cfg = SimConfig::new(SPACING / SPEED).road_sigma(ROAD_SIGMA);
    let mut sim =
        RoadSimulator::<f64, 8, 16>::new(car.model(), cfg, RoadConfig::new(SPACING, car.wheelbase()), 3).unwrap();
    let mut id = physical(TwoAxleStructuredConfig::new(ROAD_SIGMA, 0.0));
    let mut e = [0.0; 4];
    let mut out = [0.0; 32];
    for k in 0..300 {
        let s = sim.next_sample(SPEED).unwrap();
        let paired = id.update_at(s.r.as_slice(), s.z.as_slice(), &[], None, &mut e).unwrap();
        assert_eq!(paired, k >= D);
    }
    assert_eq!(id.paired(), 300 - D as u64);
    assert!(worst_entry(&physical_rows(&id)) < 1e-8);
    id.a_rows_into(&mut out).unwrap();
}

/// Samples `0..n` of seed 1's road.
fn samples(n: usize) -> Vec<vehid_core::sim::RoadSample<f64, 8>> {
    let mut sim = road_sim(1);
    (0..n).map(|_| sim.next_sample(SPEED).unwrap()).collect()
}

/// The identifier's state as JSON, without the scratch copy of the filters an update
/// overwrites before it plans (`backup`: not state).
fn snapshot(id: &Physical) -> String {
    let mut v = serde_json::to_value(id).unwrap();
    v.as_object_mut().unwrap().remove("backup");
    v.to_string()
}

/// A rejected sample changes nothing (the serialized state, bit for bit, and every later
/// estimate), whichever group it fails in; a saved identifier continues identically; a
/// corrupt save is an error.
#[test]
fn rejected_samples_change_nothing() {
    let data = samples(400);
    let mut id = physical(TwoAxleStructuredConfig::new(ROAD_SIGMA, DERIV_NOISE));
    let mut e = [0.0; 4];
    for s in &data[..200] {
        id.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
    }
    let before = snapshot(&id);
    let (x, z) = (data[200].r, data[200].z);
    let with = |v: nalgebra::SVector<f64, 8>, i: usize, val: f64| {
        let mut v = v;
        v[i] = val;
        v
    };
    let bad: Vec<(nalgebra::SVector<f64, 8>, nalgebra::SVector<f64, 8>)> = vec![
        (with(x, 0, f64::NAN), z),
        (x, with(z, 7, f64::INFINITY)),
        // Overflows in the heave group (the first: every state is in its regressor), and in
        // the wheel group (the last) through der(vb), der(om) in its regressor, after the
        // heave and pitch groups took the huge (finite) derivative as their output and
        // stepped: they must be restored.
        (with(x, 4, 1e300), z),
        (x, with(z, 5, 1e300)),
        (x, with(z, 7, 1e300)),
    ];
    for (k, (bx, bz)) in bad.iter().enumerate() {
        let mut e2 = [7.0; 4];
        let err = id.update_into(bx.as_slice(), bz.as_slice(), &[], &mut e2);
        assert!(err.is_err(), "bad sample {k} accepted");
        assert!(snapshot(&id) == before, "bad sample {k} changed the identifier");
    }
    assert!(matches!(
        id.update_at(x.as_slice(), z.as_slice(), &[], Some(199), &mut e),
        Err(Error::InvalidArgument { arg: "grid", .. })
    ));
    assert!(snapshot(&id) == before);
    // A saved copy, and the original after all those errors, continue as one that never saw
    // them.
    let saved_bytes = postcard::to_allocvec(&id).unwrap();
    let mut saved: Physical = postcard::from_bytes(&saved_bytes).unwrap();
    let mut clean = physical(TwoAxleStructuredConfig::new(ROAD_SIGMA, DERIV_NOISE));
    for s in &data[..200] {
        clean.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
    }
    for s in &data[200..] {
        for i in [&mut id, &mut saved, &mut clean] {
            i.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
        }
    }
    let params = |i: &Physical| {
        let mut p = [0.0; 12];
        i.params_into(&mut p).unwrap();
        p
    };
    assert_eq!(params(&id), params(&clean));
    assert_eq!(params(&saved), params(&clean));
    // A corrupt save: the delay beyond the ring.
    let json = serde_json::to_string(&id).unwrap();
    let corrupt = json.replacen("\"d\":10", "\"d\":17", 1);
    assert!(corrupt != json);
    assert!(serde_json::from_str::<Physical>(&corrupt).is_err());
}

/// Bad arguments are typed errors: shapes, non-finite values, settings, and structures that
/// are not the half car's.
#[test]
fn bad_inputs_are_typed_errors() {
    let car = HalfCar::<f64>::thesis();
    let model = car.model();
    let ps = *physical_structure().structure();
    let cfg = TwoAxleStructuredConfig::new(ROAD_SIGMA, DERIV_NOISE);
    // Structures that are not the half car's.
    let quarter =
        *vehid_core::model::QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap().structure();
    assert!(matches!(Physical::new(quarter, &model, D, cfg), Err(Error::Shape { arg: "structure (states)", .. })));
    let body_only = Structure::full_rows(8, &[5, 7]).unwrap();
    assert!(matches!(
        TwoAxleStructuredKalman::<f64, 8, 3, 16>::new(body_only, &model, D, cfg),
        Err(Error::InvalidArgument { arg: "structure", .. })
    ));
    let full = Structure::full_rows(8, &[1, 3, 5, 7]).unwrap();
    assert!(matches!(Physical::new(full, &model, D, cfg), Err(Error::Capacity { arg: "P", needed: 16, .. })));
    // Settings and storage.
    assert!(matches!(Physical::new(ps, &model, 0, cfg), Err(Error::InvalidArgument { arg: "d", .. })));
    assert!(matches!(
        TwoAxleStructuredKalman::<f64, 4, 3, 8>::new(ps, &model, D, cfg),
        Err(Error::Capacity { needed: 10, capacity: 8, .. })
    ));
    assert!(matches!(TwoAxleStructuredKalman::<f64, 4, 2, 16>::new(ps, &model, D, cfg), Err(Error::Shape { .. })));
    let neg = TwoAxleStructuredConfig { p0: Some(-1.0), ..cfg };
    assert!(matches!(Physical::new(ps, &model, D, neg), Err(Error::InvalidArgument { arg: "p0", .. })));
    let nan = TwoAxleStructuredConfig { deriv_noise: f64::NAN, ..cfg };
    assert!(matches!(Physical::new(ps, &model, D, nan), Err(Error::InvalidArgument { arg: "deriv_noise", .. })));
    // Samples.
    let mut id = physical(cfg);
    let (x, z, mut e) = ([0.1; 8], [0.2; 8], [0.0; 4]);
    assert!(matches!(id.update_into(&x[..7], &z, &[], &mut e), Err(Error::Shape { .. })));
    assert!(matches!(id.update_into(&x, &z, &[1.0], &mut e), Err(Error::Shape { .. })));
    assert!(matches!(id.update_into(&x, &z, &[], &mut e[..3]), Err(Error::Shape { .. })));
    let mut xn = x;
    xn[2] = f64::NAN;
    assert!(matches!(id.update_into(&xn, &z, &[], &mut e), Err(Error::NonFinite { arg: "r_k", index: 2 })));
    let mut zn = z;
    zn[5] = f64::NEG_INFINITY;
    assert!(matches!(id.update_into(&x, &zn, &[], &mut e), Err(Error::NonFinite { arg: "z_k", index: 5 })));
    // Reading: during the exact start, and with a wrong length.
    assert_eq!(id.samples(), 0);
    let mut rows = [0.0; 32];
    assert!(matches!(id.a_rows_into(&mut rows), Err(Error::RankDeficient { .. })));
    let data = samples(100);
    for s in &data {
        id.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
    }
    assert!(matches!(id.a_rows_into(&mut rows[..31]), Err(Error::Shape { arg: "out", .. })));
    assert!(matches!(id.params_into(&mut [0.0; 11]), Err(Error::Shape { arg: "out", .. })));
    assert!(matches!(id.covariance_into(&mut [0.0; 144]), Err(Error::Unsupported { .. })));
    assert!(matches!(ps.linear_rows_into(&[f64::NAN; 12], &mut rows), Err(Error::NonFinite { arg: "params", .. })));
}

/// The default configuration (compensate, σ_v > 0) and `compensate: false` on `st` (in `G`
/// groups) after the same 1000 samples: their estimates, and their covariances (the
/// compensated one's `None` when refused as unsupported).
fn with_and_without_compensation<const G: usize>(st: Structure<f64>) -> [(Vec<f64>, Option<Vec<f64>>); 2] {
    let car = HalfCar::<f64>::thesis();
    let base = TwoAxleStructuredConfig::new(ROAD_SIGMA, DERIV_NOISE);
    assert!(base.compensate && base.deriv_noise > 0.0);
    let plain = TwoAxleStructuredConfig { compensate: false, ..base };
    let mut ids = [base, plain].map(|c| TwoAxleStructuredKalman::<f64, 4, G, 16>::new(st, &car.model(), D, c).unwrap());
    let mut sim = road_sim(5);
    let mut e = [0.0; 4];
    for _ in 0..1000 {
        let s = sim.next_sample(SPEED).unwrap();
        for id in ids.iter_mut() {
            id.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
        }
    }
    let np = st.params();
    ids.map(|id| {
        let mut t = vec![0.0; np];
        id.params_into(&mut t).unwrap();
        let mut p = vec![0.0; np * np];
        let p = match id.covariance_into(&mut p) {
            Ok(()) => Some(p),
            Err(Error::Unsupported { .. }) => None,
            Err(e) => panic!("{e:?}"),
        };
        (t, p)
    })
}

/// Bias compensation acts only where a parameter multiplies a measured derivative. With M and J
/// known besides m1, m2, l1, l2, every `der(·)` term of the physical structure (the wheel
/// equations' `(M/m1) der(vb)`, `(J/m1) der(om)`, …) is known, so the default configuration
/// (compensate, σ_v > 0) is least squares: the same estimate, bit for bit, as
/// `compensate: false`, and its covariance is reported (the same matrix). With M and J
/// unknown, the same configuration compensates: another estimate, and no covariance.
#[test]
fn compensation_acts_only_where_a_parameter_multiplies_a_derivative() {
    let c = HalfCar::<f64>::thesis().constants();
    let mut known = [None; 12];
    for i in [0, 1, 8, 9, 10, 11] {
        known[i] = Some(c[i]);
    }
    let [(ta, pa), (tb, pb)] = with_and_without_compensation::<2>(*HalfCar::structure(known).unwrap().structure());
    assert_eq!(ta.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), tb.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
    let pb = pb.expect("least squares reports its covariance");
    assert!(pb.iter().any(|v| *v != 0.0));
    assert_eq!(pa, Some(pb), "M, J known: the covariance");
    let [(ta, pa), (tb, pb)] = with_and_without_compensation::<3>(*physical_structure().structure());
    assert_ne!(ta, tb, "M, J unknown: compensation should change the estimate");
    assert!(pa.is_none() && pb.is_some());
}

/// The direct front wheel equation is used exactly when `direct_front` is set: before the
/// first pair of samples one wheelbase apart (the first `d` samples, no cancelled equation
/// yet) nothing else informs the wheel group, so with `direct_front: false` its parameters
/// stay at the prior (`p0` 1000: zero) bit for bit, and with `direct_front: true` they move;
/// the other groups move either way.
#[test]
fn the_direct_front_equation_is_used_exactly_when_set() {
    for direct_front in [false, true] {
        let cfg = TwoAxleStructuredConfig {
            p0: Some(1000.0),
            direct_front,
            ..TwoAxleStructuredConfig::new(ROAD_SIGMA, DERIV_NOISE)
        };
        let mut id = physical(cfg);
        let mut sim = road_sim(5);
        let mut e = [0.0; 4];
        for _ in 0..D {
            let s = sim.next_sample(SPEED).unwrap();
            id.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
        }
        assert_eq!(id.paired(), 0);
        let (front, _) = id.wheel_equations();
        let np = id.dims().params;
        let (mut of_param, mut of_eq) = (vec![0usize; np], vec![0usize; id.dims().equations]);
        id.groups_into(&mut of_param, &mut of_eq).unwrap();
        let mut theta = vec![0.0; np];
        id.params_into(&mut theta).unwrap();
        let wheel = of_eq[front];
        let (ours, others): (Vec<_>, Vec<_>) = (0..np).partition(|&j| of_param[j] == wheel);
        assert!(!ours.is_empty() && !others.is_empty());
        let moved = |js: &[usize]| js.iter().any(|&j| theta[j] != 0.0);
        assert_eq!(
            moved(&ours),
            direct_front,
            "direct_front {direct_front}: the wheel group {:?}",
            ours.iter().map(|&j| theta[j]).collect::<Vec<_>>()
        );
        assert!(moved(&others), "direct_front {direct_front}: the other groups never moved");
    }
}

/// The front wheel equation's innovation is its prediction error `y − hᵀθ̂` (the structure's
/// regression, θ̂ before the sample) whether or not the equation updates (`direct_front`),
/// checked at every sample of three delays, also after the pairs have moved the wheel group.
#[test]
fn the_front_wheel_innovation_is_its_prediction_error() {
    for direct_front in [false, true] {
        let cfg = TwoAxleStructuredConfig {
            p0: Some(1000.0),
            direct_front,
            // The filters' own estimate (the innovations' θ̂), not the bias-compensated one.
            compensate: false,
            ..TwoAxleStructuredConfig::new(ROAD_SIGMA, DERIV_NOISE)
        };
        let mut id = physical(cfg);
        let st = *id.structure();
        let (front, _) = id.wheel_equations();
        let np = id.dims().params;
        let (mut theta, mut h) = (vec![0.0; np], vec![0.0; np]);
        let mut sim = road_sim(6);
        let mut e = [0.0; 4];
        let mut moved = 0;
        for k in 0..3 * D {
            let s = sim.next_sample(SPEED).unwrap();
            id.params_into(&mut theta).unwrap();
            let y = st.regression(front, s.r.as_slice(), s.z.as_slice(), &[], &mut h);
            let prediction: f64 = h.iter().zip(&theta).map(|(a, b)| a * b).sum();
            id.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
            let expect = y - prediction;
            assert!(
                (e[front] - expect).abs() <= 1e-9 * (1.0 + y.abs()),
                "direct_front {direct_front}, sample {k}: {} against y − hᵀθ̂ = {expect}",
                e[front]
            );
            moved += usize::from(prediction.abs() > 1e-6 * y.abs());
        }
        assert!(moved > D, "direct_front {direct_front}: the prediction stayed at zero ({moved} samples)");
    }
}

//! The AVX2 and the portable updates give the same bits (`crate::simd`'s promise), for every
//! form that has an AVX2 copy.
//!
//! Run with the other tests (`cargo test -p vehid-core --test simd_paths`). The promise does
//! not depend on the optimization level: Rust neither fuses a multiply and an add nor reorders
//! floating-point sums at any level, so the two paths agree when they compute the same
//! operations in the same order, which is what this test checks; `cargo test --release` runs it
//! on optimized code.
//!
//! Which updates have an AVX2 copy (`avx2_step!` in `identify/kalman/avx2.rs`): the decoupled
//! rows ([`KalmanRows`]) when a group of lanes fills a 256-bit register (`LANES ×
//! size_of::<T>() ≥ 32`: `Fixed<K ≥ 4>` and `Dynamic<4>` in `f64`, `Fixed<K ≥ 8>` and
//! `Dynamic<8>` in `f32`), and the shared form ([`KalmanShared`]) for more than 32 bytes of
//! state (`N ≥ 5` in `f64`, `N ≥ 9` in `f32`). The copy is the whole `step`, so every path
//! inside it runs in AVX2 there: the standard form without options, with exponential
//! forgetting, and the general path (Joseph's form, directional forgetting, drift, the outlier
//! gate and Huber weights, reinitialization, retiring rows), the square-root form, the exact
//! start, one group of lanes or several, and the refusal of a bad sample; and recursive IV on
//! full rows (`IvFilter::update_shared` and the full rows' whole sample, `f64` with four or
//! more parameters per group). Each is a case below
//! (the narrower forms, e.g. `f32` with four rows, never take the AVX2 copy: nothing to
//! compare). A case compares every innovation of every sample, which samples are refused, and
//! at the end θ̂, the whole covariance, `R`, the residual statistics, `tr P`, the counters of
//! reinitializations, samples and gated samples.

use rand::rngs::Xoshiro256PlusPlus;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use vehid_core::identify::{
    CovarianceForm, Dynamic, Fixed, Identifier, IvIdentifier, IvIdentifierVec, KalmanOptions, KalmanRows, KalmanShared,
    Store, StructuredPrior,
};
use vehid_core::model::{HalfCar, QuarterCar};
use vehid_core::sim::{SimConfig, Simulator};
use vehid_core::{simd, Real};

/// One sample: measured state and derivative.
type Sample<T> = (Vec<T>, Vec<T>);

/// The thesis' half car driven by road noise, with a disturbed start, and every 500th sample
/// made an outlier (its derivatives × 50: the gate and Huber weights act) and every 701st
/// unusable (a NaN: refused by every form, changing nothing).
fn half_car_run<T: Real>(n: usize, seed: u64) -> Vec<Sample<T>> {
    let car = HalfCar::<T>::thesis();
    let cfg =
        SimConfig::<T, 8, 2>::new(T::of(0.05)).road_sigma(T::of(0.1)).ic_sigma(T::of(0.1)).deriv_noise(T::of(0.005));
    let mut sim = Simulator::new(car.model(), cfg, seed).unwrap();
    (0..n)
        .map(|k| {
            let s = sim.next_sample();
            let (x, mut z) = (s.r.as_slice().to_vec(), s.z.as_slice().to_vec());
            if k % 500 == 499 {
                z.iter_mut().for_each(|v| *v *= T::of(50.0));
            }
            if k % 701 == 700 {
                z[3] = T::of(f64::NAN);
            }
            (x, z)
        })
        .collect()
}

/// The thesis' quarter car (4 states), as the half car above.
fn quarter_car_run(n: usize, seed: u64) -> Vec<Sample<f64>> {
    let car = QuarterCar::<f64>::thesis();
    let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(car.model(), cfg, seed).unwrap();
    (0..n)
        .map(|_| {
            let s = sim.next_sample();
            (s.r.as_slice().to_vec(), s.z.as_slice().to_vec())
        })
        .collect()
}

/// `N` correlated regressors (a random walk pulled back to 0) and `z = A x + noise` with a
/// fixed random `A`: a model wider than the cars (the shared form in `f32` needs `N ≥ 9`).
fn synthetic_run<T: Real, const N: usize>(n: usize, seed: u64) -> Vec<Sample<T>> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut normal = move || -> f64 { StandardNormal.sample(&mut rng) };
    let a: Vec<f64> = (0..N * N).map(|_| normal()).collect();
    let mut x = [0.0f64; N];
    (0..n)
        .map(|k| {
            for v in x.iter_mut() {
                *v = 0.9 * *v + normal();
            }
            let mut z: Vec<T> =
                (0..N).map(|i| T::of((0..N).map(|j| a[i * N + j] * x[j]).sum::<f64>() + 0.1 * normal())).collect();
            if k % 500 == 499 {
                z[0] *= T::of(50.0);
            }
            (x.iter().map(|&v| T::of(v)).collect(), z)
        })
        .collect()
}

/// Runs `id` over `data` and returns the bits of everything it computes: per sample whether
/// it was accepted and its innovations; at the end θ̂, covariance, `R`, residual statistics,
/// `tr P` and the counters (an error where a value is not available, e.g. during the exact
/// start, is recorded as such).
fn bits<T: Real>(mut id: impl Identifier<T>, data: &[Sample<T>]) -> Vec<u64> {
    let d = id.dims();
    let mut out = Vec::new();
    let mut e = vec![T::zero(); d.equations];
    let push = |out: &mut Vec<u64>, v: &[T]| out.extend(v.iter().map(|x| x.to_f64().to_bits()));
    for (x, z) in data {
        match id.update_into(x, z, &[], &mut e) {
            Ok(()) => {
                out.push(0);
                push(&mut out, &e);
            }
            Err(_) => out.push(1),
        }
    }
    let mut theta = vec![T::zero(); d.params];
    let mut p = vec![T::zero(); d.params * d.params];
    let mut r = vec![T::zero(); d.equations * d.equations];
    let (mut ssr, mut nobs) = (vec![T::zero(); d.equations], vec![T::zero(); d.equations]);
    for ok in [
        id.params_into(&mut theta).is_ok(),
        id.covariance_into(&mut p).is_ok(),
        id.noise_into(&mut r).is_ok(),
        id.residuals_into(&mut ssr, &mut nobs).is_ok(),
    ] {
        out.push(u64::from(ok));
    }
    for v in [&theta, &p, &r, &ssr, &nobs] {
        push(&mut out, v);
    }
    let mut gated = vec![0u64; d.equations];
    id.gated_into(&mut gated).unwrap();
    out.extend(gated);
    out.push(id.trace().map_or(u64::MAX, |t| t.to_f64().to_bits()));
    out.extend([u64::from(id.reinit_count()), id.samples()]);
    out
}

/// The options of one case: the form and what the general path adds.
fn opts<T: Real>(form: CovarianceForm, f: impl FnOnce(&mut KalmanOptions<T>)) -> KalmanOptions<T> {
    let mut o = KalmanOptions { form, ..KalmanOptions::default() };
    f(&mut o);
    o
}

/// The option sets of the decoupled rows: (name, options, exact start).
fn rows_variants<T: Real>() -> Vec<(&'static str, KalmanOptions<T>, bool)> {
    use CovarianceForm::{Joseph, Sqrt, Standard};
    vec![
        ("standard", opts(Standard, |_| {}), false),
        ("joseph", opts(Joseph, |_| {}), false),
        ("sqrt", opts(Sqrt, |_| {}), false),
        ("forgetting 0.999", opts(Standard, |o| o.forgetting = T::of(0.999)), false),
        ("sqrt, forgetting 0.999", opts(Sqrt, |o| o.forgetting = T::of(0.999)), false),
        (
            "directional forgetting 0.99",
            opts(Standard, |o| {
                o.forgetting = T::of(0.99);
                o.directional = true;
            }),
            false,
        ),
        ("drift 1e-6", opts(Standard, |o| o.drift = T::of(1e-6)), false),
        ("reinit (Eq 4.36)", opts(Standard, |o| o.reinit = true), false),
        ("joseph, reinit", opts(Joseph, |o| o.reinit = true), false),
        (
            "gate 3, huber 1.345",
            opts(Standard, |o| {
                o.gate = T::of(3.0);
                o.huber = T::of(1.345);
            }),
            false,
        ),
        ("sqrt, gate 3", opts(Sqrt, |o| o.gate = T::of(3.0)), false),
        ("retire below tr P 3", opts(Standard, |o| o.retire_below = T::of(3.0)), false),
        ("exact start", opts(Standard, |_| {}), true),
        ("exact start, sqrt", opts(Sqrt, |_| {}), true),
        ("exact start, forgetting 0.999", opts(Standard, |o| o.forgetting = T::of(0.999)), true),
    ]
}

/// The option sets of the shared form (no square root, no tracking, no Huber there).
fn shared_variants<T: Real>() -> Vec<(&'static str, KalmanOptions<T>)> {
    use CovarianceForm::{Joseph, Standard};
    vec![
        ("standard", opts(Standard, |_| {})),
        ("joseph", opts(Joseph, |_| {})),
        ("reinit (Eq 4.36)", opts(Standard, |o| o.reinit = true)),
        ("gate 3", opts(Standard, |o| o.gate = T::of(3.0))),
        ("joseph, gate 3", opts(Joseph, |o| o.gate = T::of(3.0))),
    ]
}

/// A case: its name and how to compute its bits (called once per path).
type Case = (String, Box<dyn Fn() -> Vec<u64>>);

/// Every rows variant on a store `S` (rows `rows` of an `N`-state model, `p0` and `r` per row).
fn rows_cases<T: Real, const N: usize, S: Store<T, N> + 'static>(
    what: &str,
    rows: &'static [usize],
    p0: T,
    r: &'static [T],
    data: std::rc::Rc<Vec<Sample<T>>>,
) -> Vec<Case> {
    rows_variants::<T>()
        .into_iter()
        .map(|(name, o, exact)| {
            let data = data.clone();
            let f = move || {
                let id = if exact {
                    KalmanRows::<T, N, S>::exact(rows, r, o).unwrap()
                } else {
                    KalmanRows::<T, N, S>::from_slices(rows, &[p0], r, o).unwrap()
                };
                bits(id, &data)
            };
            (format!("{what}, {name}"), Box::new(f) as Box<dyn Fn() -> Vec<u64>>)
        })
        .collect()
}

/// Every shared variant (rows `rows` of an `N`-state model, the same `r / p0` on every row).
fn shared_cases<T: Real, const N: usize>(
    what: &str,
    rows: &'static [usize],
    data: std::rc::Rc<Vec<Sample<T>>>,
) -> Vec<Case> {
    shared_variants::<T>()
        .into_iter()
        .map(|(name, o)| {
            let data = data.clone();
            let f = move || {
                let id = KalmanShared::<T, N, Dynamic>::from_slices(rows, &[T::of(1000.0)], &[T::of(0.3)], o).unwrap();
                bits(id, &data)
            };
            (format!("{what}, {name}"), Box::new(f) as Box<dyn Fn() -> Vec<u64>>)
        })
        .collect()
}

/// Whether an update takes the AVX2 copy, by the rule of the module doc (the code's `$wide`
/// conditions, restated): rows by lanes × element size, shared by state size.
fn rows_wide<T>(lanes: usize) -> bool {
    lanes * std::mem::size_of::<T>() >= 32
}
fn shared_wide<T>(n: usize) -> bool {
    n * std::mem::size_of::<T>() > 32
}

fn cases() -> Vec<Case> {
    use std::rc::Rc;
    const HALF_ROWS: &[usize] = &[1, 3, 5, 7];
    const ALL_8: &[usize] = &[0, 1, 2, 3, 4, 5, 6, 7];
    const HALF_R_F64: &[f64] = &[100.0, 100.0, 0.01, 0.01];
    const ALL_R_F64: &[f64] = &[0.01, 100.0, 0.01, 100.0, 0.01, 0.01, 0.01, 0.01];
    const ALL_R_F32: &[f32] = &[0.01, 100.0, 0.01, 100.0, 0.01, 0.01, 0.01, 0.01];
    const TWELVE: &[usize] = &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11];
    const TWELVE_R_F32: &[f32] = &[0.01; 12];
    assert!(rows_wide::<f64>(4) && rows_wide::<f32>(8) && !rows_wide::<f32>(4));
    assert!(shared_wide::<f64>(8) && shared_wide::<f32>(12) && !shared_wide::<f32>(8));
    let half64 = Rc::new(half_car_run::<f64>(3000, 17));
    let half32 = Rc::new(half_car_run::<f32>(3000, 17));
    let wide32 = Rc::new(synthetic_run::<f32, 12>(3000, 5));
    let quarter = Rc::new(quarter_car_run(3000, 21));
    let mut all = Vec::new();
    // f64, the half car's four unknown rows: Fixed<4> (one group of four lanes).
    all.extend(rows_cases::<f64, 8, Fixed<4>>("f64 rows Fixed<4>", HALF_ROWS, 1000.0, HALF_R_F64, half64.clone()));
    // f64, every row of the half car on the heap: two groups of four lanes (planned through
    // their scratch).
    all.extend(rows_cases::<f64, 8, Dynamic<4>>("f64 rows Dynamic<4> ×2", ALL_8, 1000.0, ALL_R_F64, half64.clone()));
    // f64 on the heap, the quarter car's two rows padded to four lanes.
    all.extend(rows_cases::<f64, 4, Dynamic<4>>(
        "f64 quarter rows Dynamic<4>",
        &[1, 3],
        1000.0,
        &[81.0, 2.5e-5],
        quarter.clone(),
    ));
    // f32, every row of the half car: eight lanes fill the register.
    all.extend(rows_cases::<f32, 8, Fixed<8>>("f32 rows Fixed<8>", ALL_8, 1000.0, ALL_R_F32, half32.clone()));
    all.extend(rows_cases::<f32, 8, Dynamic<8>>("f32 rows Dynamic<8>", ALL_8, 1000.0, ALL_R_F32, half32));
    // f32 in 12 states, two groups of eight lanes (the second half padding).
    all.extend(rows_cases::<f32, 12, Dynamic<8>>(
        "f32 12 states rows Dynamic<8>",
        TWELVE,
        1000.0,
        TWELVE_R_F32,
        wide32.clone(),
    ));
    // Recursive IV on full rows (one shared gain; the whole sample in the AVX2 copy for f64
    // and four or more parameters per group): the quarter car with a prior (fixed and heap
    // storage), the half car with the exact start (its outliers and refused NaN samples).
    let (q1, q2, h1) = (quarter.clone(), quarter.clone(), half64.clone());
    let iv: [Case; 3] = [
        (
            "f64 IV full rows, quarter car, prior".into(),
            Box::new(move || {
                let p0 = StructuredPrior::Scalar(1000.0);
                bits(IvIdentifier::<f64, 4, 2>::full_rows(4, &[1, 3], 1, p0, &[1.0]).unwrap(), &q1)
            }),
        ),
        (
            "f64 IV full rows, quarter car, heap, delay 2".into(),
            Box::new(move || {
                let p0 = StructuredPrior::Scalar(10.0);
                bits(IvIdentifierVec::<f64, 4>::full_rows(4, &[1, 3], 2, p0, &[0.5]).unwrap(), &q2)
            }),
        ),
        (
            "f64 IV full rows, half car, exact start".into(),
            Box::new(move || {
                let p0 = StructuredPrior::Exact;
                bits(IvIdentifier::<f64, 8, 4>::full_rows(8, HALF_ROWS, 1, p0, &[1.0]).unwrap(), &h1)
            }),
        ),
    ];
    all.extend(iv);
    // The shared form: the half car in f64, 12 states in f32.
    all.extend(shared_cases::<f64, 8>("f64 shared, half car", HALF_ROWS, half64));
    all.extend(shared_cases::<f32, 12>("f32 shared, 12 states", TWELVE, wide32));
    all
}

#[test]
fn vector_extensions_do_not_change_a_single_bit() {
    let cases = cases();
    simd::set_vector_extensions(false);
    assert_eq!(simd::vector_extensions(), "portable");
    let portable: Vec<Vec<u64>> = cases.iter().map(|(_, f)| f()).collect();
    simd::set_vector_extensions(true);
    let path = simd::vector_extensions();
    let vector: Vec<Vec<u64>> = cases.iter().map(|(_, f)| f()).collect();
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        assert_eq!(path, "avx2", "the AVX2 path is taken on a CPU that has it");
    }
    let values: usize = vector.iter().map(Vec::len).sum();
    eprintln!("compared the portable path with: {path} ({} cases, {values} values)", cases.len());
    let differ: Vec<String> = cases
        .iter()
        .zip(portable.iter().zip(&vector))
        .filter(|(_, (a, b))| a != b)
        .map(|((name, _), (a, b))| {
            let n = a.iter().zip(b.iter()).filter(|(x, y)| x != y).count() + a.len().abs_diff(b.len());
            format!("{name}: {n} of {} values", a.len())
        })
        .collect();
    assert!(
        differ.is_empty(),
        "{} of {} cases differ between the paths:\n  {}",
        differ.len(),
        cases.len(),
        differ.join("\n  ")
    );
}

#[test]
fn the_cases_exercise_their_paths() {
    // The comparison above is only as good as the paths the cases reach: the reinitialization,
    // the gate, retiring a row and the refusal of a bad sample must happen, and the exact
    // start must end (shown for the f64 half car; the other stores run the same data).
    let data = half_car_run::<f64>(3000, 17);
    let run = |o: KalmanOptions<f64>, exact: bool| {
        let mut id = if exact {
            KalmanRows::<f64, 8, Fixed<4>>::exact(&[1, 3, 5, 7], &[100.0, 100.0, 0.01, 0.01], o).unwrap()
        } else {
            KalmanRows::<f64, 8, Fixed<4>>::from_slices(&[1, 3, 5, 7], &[1000.0], &[100.0, 100.0, 0.01, 0.01], o)
                .unwrap()
        };
        let mut e = [0.0; 4];
        let refused = data.iter().filter(|(x, z)| id.update_into(x, z, &[], &mut e).is_err()).count();
        let mut gated = [0u64; 4];
        id.gated_into(&mut gated).unwrap();
        let mut theta = [0.0; 32];
        let retired = (0..4).filter(|&i| id.filter(i).retired()).count();
        (refused, id.reinit_count(), gated.iter().sum::<u64>(), id.params_into(&mut theta).is_ok(), retired)
    };
    let (refused, ..) = run(KalmanOptions::default(), false);
    assert_eq!(refused, 3000 / 701, "every NaN sample is refused");
    let (_, reinits, ..) = run(KalmanOptions { reinit: true, ..KalmanOptions::default() }, false);
    assert!(reinits > 0, "no reinitialization happened");
    let (_, _, gated, ..) = run(KalmanOptions { gate: 3.0, ..KalmanOptions::default() }, false);
    assert!(gated > 0, "the gate left nothing out");
    let (.., identified, _) = run(KalmanOptions::default(), true);
    assert!(identified, "the exact start did not end");
    let (.., retired) = run(KalmanOptions { retire_below: 3.0, ..KalmanOptions::default() }, false);
    assert!(retired > 0, "no row retired");
}

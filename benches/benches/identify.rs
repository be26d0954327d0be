//! ns per sample update of every identifier, quarter car (4 states) and half car (8 states),
//! f32 and f64, plus batch least squares per sample and the simulator's and the drives'
//! throughput.
//!
//! Run: `cargo bench -p vehid-benches --bench identify` (about 2 minutes). Inputs are seeded
//! simulations cycled through, so the filters see realistic, converging data.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::hint::black_box;
use std::time::Duration;
use vehid_core::identify::{
    BatchLeastSquares, CovarianceForm, FullKalmanIdentifier, Gain, Identifier, KalmanIdentifier, KalmanIdentifierVec,
    KalmanIdentifierVec2, KalmanOptions, LsAccumulator, SharedKalmanIdentifier, StochasticGradient, StructuredGradient,
    StructuredKalman, StructuredPrior,
};
use vehid_core::model::{FullCar, HalfCar, LinearModel, QuarterCar};
use vehid_core::nalgebra::SVector;
use vehid_core::sim::{
    DriveConfig, FullDrive, FullDriveConfig, HalfDrive, HalfDriveConfig, Method, QuarterDrive, SimConfig, Simulator,
};
use vehid_core::structure::Structure;
use vehid_core::Real;

const LEN: usize = 4096;

fn samples<T: Real, const N: usize, const M: usize>(
    model: LinearModel<T, N, M>,
) -> Vec<(SVector<T, N>, SVector<T, N>)> {
    let cfg = SimConfig::new(T::of(0.05)).road_sigma(T::of(0.1)).ic_sigma(T::of(0.1)).deriv_noise(T::of(0.005));
    let mut sim = Simulator::new(model, cfg, 42).unwrap();
    (0..LEN).map(|_| sim.next_sample()).map(|s| (s.r, s.z)).collect()
}

/// Benchmarks `update` over the cycled samples.
fn bench_updates<T: Real, const N: usize>(
    c: &mut Criterion,
    group: &str,
    data: &[(SVector<T, N>, SVector<T, N>)],
    mut update: impl FnMut(&SVector<T, N>, &SVector<T, N>),
    name: &str,
) {
    let mut g = c.benchmark_group(group);
    g.throughput(Throughput::Elements(1));
    let mut i = 0usize;
    g.bench_function(name, |b| {
        b.iter(|| {
            let (x, z) = &data[i];
            i = (i + 1) & (LEN - 1);
            update(black_box(x), black_box(z));
        })
    });
    g.finish();
}

macro_rules! kalman_benches {
    ($c:expr, $t:ty, $label:literal) => {{
        let q = QuarterCar::<$t>::thesis();
        let h = HalfCar::<$t>::thesis();
        let qd = samples(q.model());
        let hd = samples(h.model());
        let rq: [$t; 2] = q.model().row_noise_var(0.1 as $t, 0.005 as $t).unwrap();
        let rh: [$t; 4] = h.model().row_noise_var(0.1 as $t, 0.005 as $t).unwrap();
        let group = concat!("update_", $label);

        let mut id = KalmanIdentifier::<$t, 4, 2>::new(q.unknown_rows(), 1000.0, rq).unwrap();
        bench_updates(
            $c,
            group,
            &qd,
            |x, z| {
                let _ = black_box(id.update(x, z));
            },
            "quarter/kalman_rows",
        );
        let mut id = KalmanIdentifier::<$t, 8, 4>::new(h.unknown_rows(), 1000.0, rh).unwrap();
        bench_updates(
            $c,
            group,
            &hd,
            |x, z| {
                let _ = black_box(id.update(x, z));
            },
            "half/kalman_rows",
        );

        // The online forms: the square-root form, exponential forgetting, and the exact start
        // once it has ended (the first samples of the cycle identify the parameters).
        for (name, opts, exact) in [
            ("sqrt", KalmanOptions { form: CovarianceForm::Sqrt, ..KalmanOptions::default() }, false),
            ("forget", KalmanOptions { forgetting: 0.999 as $t, ..KalmanOptions::default() }, false),
            (
                "sqrt_forget",
                KalmanOptions { form: CovarianceForm::Sqrt, forgetting: 0.999 as $t, ..KalmanOptions::default() },
                false,
            ),
            ("exact", KalmanOptions::default(), true),
        ] {
            let mut id = if exact {
                KalmanIdentifier::<$t, 4, 2>::exact(&q.unknown_rows(), &rq, opts).unwrap()
            } else {
                KalmanIdentifier::<$t, 4, 2>::from_slices(&q.unknown_rows(), &[1000.0], &rq, opts).unwrap()
            };
            bench_updates(
                $c,
                group,
                &qd,
                |x, z| {
                    let _ = black_box(id.update(x, z));
                },
                &format!("quarter/kalman_rows_{name}"),
            );
            let mut id = if exact {
                KalmanIdentifier::<$t, 8, 4>::exact(&h.unknown_rows(), &rh, opts).unwrap()
            } else {
                KalmanIdentifier::<$t, 8, 4>::from_slices(&h.unknown_rows(), &[1000.0], &rh, opts).unwrap()
            };
            bench_updates(
                $c,
                group,
                &hd,
                |x, z| {
                    let _ = black_box(id.update(x, z));
                },
                &format!("half/kalman_rows_{name}"),
            );
        }

        // The heap forms the Python bindings use (two lanes for the quarter car's two rows).
        let mut id =
            KalmanIdentifierVec2::<$t, 4>::from_slices(&q.unknown_rows(), &[1000.0], &rq, KalmanOptions::default())
                .unwrap();
        let mut e = [0.0 as $t; 2];
        bench_updates(
            $c,
            group,
            &qd,
            |x, z| {
                let _ = black_box(id.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
            },
            "quarter/kalman_rows_vec",
        );
        let mut id =
            KalmanIdentifierVec::<$t, 8>::from_slices(&h.unknown_rows(), &[1000.0], &rh, KalmanOptions::default())
                .unwrap();
        let mut e = [0.0 as $t; 4];
        bench_updates(
            $c,
            group,
            &hd,
            |x, z| {
                let _ = black_box(id.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
            },
            "half/kalman_rows_vec",
        );

        let mut id = SharedKalmanIdentifier::<$t, 4, 2>::new(q.unknown_rows(), 1000.0, [1.0; 2]).unwrap();
        bench_updates(
            $c,
            group,
            &qd,
            |x, z| {
                let _ = black_box(id.update(x, z));
            },
            "quarter/kalman_shared",
        );
        let mut id = SharedKalmanIdentifier::<$t, 8, 4>::new(h.unknown_rows(), 1000.0, [1.0; 4]).unwrap();
        bench_updates(
            $c,
            group,
            &hd,
            |x, z| {
                let _ = black_box(id.update(x, z));
            },
            "half/kalman_shared",
        );

        let rfull = vehid_core::nalgebra::SMatrix::<$t, 2, 2>::from_diagonal(&rq.into());
        let mut id = FullKalmanIdentifier::<$t, 4, 2>::new(q.unknown_rows(), 1000.0, rfull).unwrap();
        bench_updates(
            $c,
            group,
            &qd,
            |x, z| {
                let _ = black_box(id.update(x, z));
            },
            "quarter/kalman_full",
        );
        let rfull = vehid_core::nalgebra::SMatrix::<$t, 4, 4>::from_diagonal(&rh.into());
        let mut id = FullKalmanIdentifier::<$t, 8, 4>::new(h.unknown_rows(), 1000.0, rfull).unwrap();
        bench_updates(
            $c,
            group,
            &hd,
            |x, z| {
                let _ = black_box(id.update(x, z));
            },
            "half/kalman_full",
        );

        for (gname, gain) in [
            ("venter", Gain::Venter { p: 0.51 as $t }),
            ("lyapunov", Gain::Lyapunov),
            ("ljung", Gain::Ljung { lambda0: 0.99 as $t, lambda_init: 0.95 as $t }),
        ] {
            let mut id = StochasticGradient::<$t, 4, 2>::new(q.unknown_rows(), gain, 0.4).unwrap();
            bench_updates(
                $c,
                group,
                &qd,
                |x, z| {
                    let _ = black_box(id.update(x, z));
                },
                &format!("quarter/sg_{gname}"),
            );
            let mut id = StochasticGradient::<$t, 8, 4>::new(h.unknown_rows(), gain, 0.4).unwrap();
            bench_updates(
                $c,
                group,
                &hd,
                |x, z| {
                    let _ = black_box(id.update(x, z));
                },
                &format!("half/sg_{gname}"),
            );
        }

        let mut acc = LsAccumulator::<$t, 4, vehid_core::identify::Fixed<2>>::new(q.unknown_rows()).unwrap();
        bench_updates(
            $c,
            group,
            &qd,
            |x, z| {
                let _ = black_box(acc.push(x, z));
            },
            "quarter/ls_accumulate",
        );
    }};
}

fn identifiers(c: &mut Criterion) {
    kalman_benches!(c, f64, "f64");
    kalman_benches!(c, f32, "f32");
}

/// Identifiers on a Structure against the plain rows update for the same parameters
/// (target: at most 1.5x): the quarter car's full rows as a structure (8 parameters in two
/// groups of 4), its physical structure with m known (4 parameters, two groups of 2), and the
/// stochastic gradient on the full-row structure.
fn structured(c: &mut Criterion) {
    let q = QuarterCar::<f64>::thesis();
    let data = samples(q.model());
    let r: [f64; 2] = q.model().row_noise_var(0.1, 0.005).unwrap();
    let opts = KalmanOptions::default();
    let full = Structure::<f64>::full_rows(4, &q.unknown_rows()).unwrap();
    let mut id = StructuredKalman::<f64, 4, 2>::new(full, StructuredPrior::Scalar(1000.0), None, &r, opts).unwrap();
    let mut e = [0.0; 2];
    bench_updates(
        c,
        "update_f64",
        &data,
        |x, z| {
            let _ = black_box(id.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
        },
        "quarter/structured_rows",
    );
    let ph = QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap();
    let mut id =
        StructuredKalman::<f64, 2, 2>::new(*ph.structure(), StructuredPrior::Scalar(1000.0), None, &[1.0], opts)
            .unwrap();
    bench_updates(
        c,
        "update_f64",
        &data,
        |x, z| {
            let _ = black_box(id.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
        },
        "quarter/structured_physical",
    );
    let mut sg = StructuredGradient::<f64, 8>::new(full, Gain::Venter { p: 0.51 }, &[0.4], None, 1).unwrap();
    bench_updates(
        c,
        "update_f64",
        &data,
        |x, z| {
            let _ = black_box(sg.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
        },
        "quarter/structured_sg_venter",
    );
}

/// Noisy state sensors: recursive IV on the quarter car's full rows (8 parameters
/// in two groups of 4: compare with `quarter/kalman_rows`), with the refined instruments'
/// predictor (6 lags: a 49-regressor least-squares predictor per sample), on the physical
/// structure, and the bias-compensated sums.
fn noisy_states(c: &mut Criterion) {
    use vehid_core::identify::{BiasCompensatedLs, IvIdentifier, StructuredPrior};
    let q = QuarterCar::<f64>::thesis();
    let data = samples(q.model());
    let mut e = [0.0; 2];
    let mut iv =
        IvIdentifier::<f64, 4, 2>::full_rows(4, &q.unknown_rows(), 1, StructuredPrior::Scalar(1000.0), &[1.0]).unwrap();
    let mut update = |x: &SVector<f64, 4>, z: &SVector<f64, 4>| {
        let _ = black_box(iv.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
    };
    bench_updates(c, "update_f64", &data, &mut update, "quarter/iv_rows");
    let mut iv = IvIdentifier::<f64, 4, 2, 49>::full_rows(4, &q.unknown_rows(), 1, StructuredPrior::Exact, &[1.0])
        .and_then(|id| id.with_lags(6))
        .unwrap();
    let mut update = |x: &SVector<f64, 4>, z: &SVector<f64, 4>| {
        let _ = black_box(iv.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
    };
    bench_updates(c, "update_f64", &data, &mut update, "quarter/iv_rows_refined6");
    let ph = QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap();
    let mut iv = IvIdentifier::<f64, 2, 2>::exact(*ph.structure(), 1).unwrap();
    let mut update = |x: &SVector<f64, 4>, z: &SVector<f64, 4>| {
        let _ = black_box(iv.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
    };
    bench_updates(c, "update_f64", &data, &mut update, "quarter/iv_physical");
    // The same on a coloured road: the samples quasi-differenced first (identify::Differenced).
    let s = *ph.structure();
    let inner = IvIdentifier::<f64, 2, 2>::exact(s, 1).unwrap();
    let road = vehid_core::identify::RoadModel::Shaped { cutoff: 0.01 };
    // Every sample differenced (min_spacing 0): the cost per differenced sample, its worst case.
    let mut id =
        vehid_core::identify::Differenced::new(inner, &s, road, vehid_core::identify::Travel::PerSample(0.075))
            .and_then(|d| d.with_min_spacing(0.0))
            .unwrap();
    let mut update = |x: &SVector<f64, 4>, z: &SVector<f64, 4>| {
        let _ = black_box(id.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
    };
    bench_updates(c, "update_f64", &data, &mut update, "quarter/iv_physical_road");
    let mut bc = BiasCompensatedLs::<f64, 4, 2>::full_rows(4, &q.unknown_rows(), &[6.4e-5]).unwrap();
    let mut update = |x: &SVector<f64, 4>, z: &SVector<f64, 4>| {
        let _ = black_box(bc.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
    };
    bench_updates(c, "update_f64", &data, &mut update, "quarter/bcls_rows");
    // The same behind Python's default outlier screen (`Screened`, gate 6, residual and
    // magnitude tests, refreshed as the samples grow by a quarter: count_updates' quarter_bcls_screened).
    let inner = BiasCompensatedLs::<f64, 4, 2>::full_rows(4, &q.unknown_rows(), &[6.4e-5]).unwrap();
    let full = vehid_core::structure::Structure::<f64>::full_rows(4, &q.unknown_rows()).unwrap();
    let mut sc =
        vehid_core::identify::Screened::new(inner, full, 6.0, vehid_core::identify::Refresh::Geometric).unwrap();
    let mut update = |x: &SVector<f64, 4>, z: &SVector<f64, 4>| {
        let _ = black_box(sc.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
    };
    bench_updates(c, "update_f64", &data, &mut update, "quarter/bcls_screened");
    // Instruments from the auxiliary model (SRIVC/RIVC) on a structure with a measured input:
    // the mass-spring-damper rig (3 parameters, one RK4 step per sample, refresh every 100
    // samples), past its start (as count_updates' msd_iv_model).
    let (s, rig) = vehid_benches::msd_rig(LEN);
    let mut iv = IvIdentifier::<f64, 3, 1>::exact(s, 1).unwrap().with_model_instruments(0.01, 1, 100, None).unwrap();
    let mut e1 = [0.0];
    for (x, z, u) in &rig[..400] {
        iv.update_into(x, z, u, &mut e1).unwrap();
    }
    let mut g = c.benchmark_group("update_f64");
    g.throughput(Throughput::Elements(1));
    let mut i = 400usize;
    g.bench_function("msd/iv_model", |b| {
        b.iter(|| {
            let (x, z, u) = &rig[i];
            i = if i + 1 == LEN { 400 } else { i + 1 };
            let _ = black_box(iv.update_into(black_box(x), black_box(z), black_box(u), &mut e1));
        })
    });
    g.finish();
    // The joint EKF (state, parameters and road together) on the physical structure, m known:
    // a prior 10 % off the truth (standard deviation half the guess), Σ_w for 8 % state
    // noise, the simulator's 5 RK4 sub-steps (as count_updates' quarter_ekf_physical).
    use vehid_core::identify::{EkfNoise, JointEkf};
    let ps = QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap();
    let mut guess = [0.0; 4];
    ps.params_of(&q.constants(), &mut guess).unwrap();
    guess.iter_mut().for_each(|g| *g *= 1.1);
    let var = guess.map(|g| 0.25 * g * g);
    let b = SVector::<f64, 4>::from_column_slice(q.model().b().as_slice());
    let noise = EkfNoise::from_sigmas(0.008, 0.005, b, 0.1);
    let mut ekf = JointEkf::<f64, 4, 9>::new(*ps.structure(), &guess, &var, 1.0, noise, 0.05, 5).unwrap();
    let mut update = |x: &SVector<f64, 4>, z: &SVector<f64, 4>| {
        let _ = black_box(ekf.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
    };
    bench_updates(c, "update_f64", &data, &mut update, "quarter/ekf_physical");
    // Σ_w estimated from the data: the bias-compensated sums beside a delayed-regressor IV
    // (count_updates' quarter_nebcls_rows); the noise fit runs when the estimate is read.
    let mut ne =
        vehid_core::identify::NoiseEstimatingBclsLs::<f64, 4, 2>::full_rows(4, &q.unknown_rows(), 1, 0).unwrap();
    let mut update = |x: &SVector<f64, 4>, z: &SVector<f64, 4>| {
        let _ = black_box(ne.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
    };
    bench_updates(c, "update_f64", &data, &mut update, "quarter/nebcls_rows");
}

/// Road cancellation on the half car's physical structure (as count_updates'
/// half_two_axle_physical): sampled every 0.3 m at 6 m/s, the rear axle 10 samples behind,
/// m1, m2, l1, l2 known (12 parameters), the exact start. Compare with
/// `half/kalman_rows` (32 parameters, no pairing).
fn two_axle(c: &mut Criterion) {
    use vehid_core::identify::{TwoAxleStructuredConfig, TwoAxleStructuredKalman};
    use vehid_core::sim::{RoadConfig, RoadSimulator};
    let car = HalfCar::<f64>::thesis();
    let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    let mut sim =
        RoadSimulator::<f64, 8, 16>::new(car.model(), cfg, RoadConfig::new(0.3, car.wheelbase()), 42).unwrap();
    let data: Vec<_> = (0..LEN).map(|_| sim.next_sample(6.0).map(|s| (s.r, s.z)).unwrap()).collect();
    let consts = car.constants();
    let mut known = [None; 12];
    for i in 8..12 {
        known[i] = Some(consts[i]);
    }
    let ps = HalfCar::structure(known).unwrap();
    let mut id = TwoAxleStructuredKalman::<f64, 4, 3, 16>::new(
        *ps.structure(),
        &car.model(),
        10,
        TwoAxleStructuredConfig::new(0.1, 0.005),
    )
    .unwrap();
    let mut e = [0.0; 4];
    let mut update = |x: &SVector<f64, 8>, z: &SVector<f64, 8>| {
        let _ = black_box(id.update_into(x.as_slice(), z.as_slice(), &[], &mut e));
    };
    bench_updates(c, "update_f64", &data, &mut update, "half/two_axle_physical");

    // The full car's rows on two tracks (as count_full_health's full_two_axle): the passenger
    // car on ISO 8608 class C at 20 m/s, 200 Hz (0.1 m: the rear wheels 31 samples behind),
    // true states; two 28-parameter joint filters and three body rows of 14, fixed storage.
    use vehid_core::identify::{TwoAxleConfig, TwoAxleIdentifier, WheelMethod};
    use vehid_core::sim::RoadClass;
    let full = FullCar::<f64>::passenger();
    let cfg = FullDriveConfig::new(DriveConfig::new(0.005).road(RoadClass::C).speed(20.0));
    let mut drive = FullDrive::new(full, cfg, 42).unwrap();
    let data: Vec<_> = (0..LEN).map(|_| drive.next_sample()).map(|s| (s.x, s.xdot)).collect();
    let cfg = TwoAxleConfig::new(WheelMethod::Cancel, 1000.0, 0.1, 0.005);
    let mut id = TwoAxleIdentifier::<f64, 14, 28, 3, 32, 4>::new(&full.model(), 31, cfg).unwrap();
    let mut e = [0.0; 7];
    let mut update = |x: &SVector<f64, 14>, z: &SVector<f64, 14>| {
        let _ = black_box(id.update_at(x, z, None, &mut e));
    };
    bench_updates(c, "update_f64", &data, &mut update, "full/two_axle_rows");
}

/// The realistic sensors' body-equation fit (`identify::StateFilterFit`, the Python
/// `RealisticIdentifier`): one sample `[a_body, a_wheel, deflection]` of a passenger car's drive
/// on an ISO class C road at 15 m/s (200 Hz), M known; blocks of 2 s close as they fill.
fn state_filter(c: &mut Criterion) {
    use vehid_core::identify::{StateFilterFit, DEFAULT_BANDWIDTH, DEFAULT_BLOCK};
    use vehid_core::sim::{DriveConfig, QuarterDrive};
    let car = QuarterCar::<f64>::passenger();
    let mut drive = QuarterDrive::new(car, DriveConfig::new(0.005).speed(15.0), 42).unwrap();
    let data: Vec<[f64; 3]> = (0..LEN)
        .map(|_| {
            let s = drive.next_sample();
            [s.y()[0], s.y()[1], s.y()[2]]
        })
        .collect();
    let ps = QuarterCar::realistic_structure([Some(car.constants()[0]), None, None, None, None]).unwrap();
    let mut fit = StateFilterFit::new(*ps.structure(), 0.005, DEFAULT_BANDWIDTH, DEFAULT_BLOCK).unwrap();
    let mut g = c.benchmark_group("update_f64");
    g.throughput(Throughput::Elements(1));
    let mut i = 0usize;
    g.bench_function("quarter/state_filter_realistic", |b| {
        b.iter(|| {
            let _ = black_box(fit.update(black_box(&data[i])));
            i = (i + 1) & (LEN - 1);
        })
    });
    g.finish();
}

/// The full car's realistic-sensor fit (`identify::CornerFilterFit`, the Python
/// `RealisticIdentifier(FullCar)`): one sample of the twelve channels of the passenger full
/// car's drive on ISO class C at 15 m/s (200 Hz); blocks of 2 s close as they fill.
fn corner_filter(c: &mut Criterion) {
    use vehid_core::identify::{CornerFilterFit, DEFAULT_BANDWIDTH, DEFAULT_BLOCK};
    use vehid_core::model::FullCar;
    use vehid_core::sim::{DriveConfig, FullDrive, FullDriveConfig};
    let car = FullCar::<f64>::passenger();
    let mut drive = FullDrive::new(car, FullDriveConfig::new(DriveConfig::new(0.005).speed(15.0)), 42).unwrap();
    let data: Vec<[f64; 12]> = (0..LEN)
        .map(|_| {
            let mut y = [0.0; 12];
            y.copy_from_slice(drive.next_sample().y());
            y
        })
        .collect();
    let mut fit = CornerFilterFit::new(0.005, DEFAULT_BANDWIDTH, DEFAULT_BLOCK).unwrap();
    let mut g = c.benchmark_group("update_f64");
    g.throughput(Throughput::Elements(1));
    let mut i = 0usize;
    g.bench_function("full/corner_filter_realistic", |b| {
        b.iter(|| {
            let _ = black_box(fit.update(black_box(&data[i])));
            i = (i + 1) & (LEN - 1);
        })
    });
    g.finish();
}

fn batch_least_squares(c: &mut Criterion) {
    let q = QuarterCar::<f64>::thesis();
    let data = samples(q.model());
    let mut g = c.benchmark_group("batch_ls_f64");
    for n in [1_000usize, 4_096] {
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::new("quarter/push_and_solve", n), &n, |b, &n| {
            b.iter(|| {
                let mut ls = BatchLeastSquares::<f64, 4>::new(&q.unknown_rows()).unwrap();
                for (x, z) in &data[..n] {
                    ls.push(x, z).unwrap();
                }
                black_box(ls.solve().unwrap())
            })
        });
    }
    g.finish();
}

fn simulator(c: &mut Criterion) {
    let mut g = c.benchmark_group("simulate_f64");
    g.throughput(Throughput::Elements(1));
    for (name, method) in [("rk4", Method::Rk4), ("exact", Method::Exact)] {
        let mut cfg = SimConfig::<f64, 4, 1>::new(0.05).road_sigma(0.1).deriv_noise(0.005);
        cfg.method = method;
        let mut sim = Simulator::new(QuarterCar::thesis().model(), cfg, 1).unwrap();
        g.bench_function(format!("quarter/{name}"), |b| b.iter(|| black_box(sim.next_sample())));
        let mut cfg = SimConfig::<f64, 8, 2>::new(0.05).road_sigma(0.1).deriv_noise(0.005);
        cfg.method = method;
        let mut sim = Simulator::new(HalfCar::thesis().model(), cfg, 1).unwrap();
        g.bench_function(format!("half/{name}"), |b| b.iter(|| black_box(sim.next_sample())));
    }
    // The drives (road in distance, ISO 8608 class C at 15 m/s, realistic sensors at 200 Hz):
    // one sample of each car's sensors, road generation and sensor noise included.
    let mut quarter = QuarterDrive::new(QuarterCar::passenger(), DriveConfig::new(0.005), 1).unwrap();
    g.bench_function("quarter/drive", |b| b.iter(|| black_box(quarter.next_sample())));
    let mut half = HalfDrive::new(HalfCar::passenger(), HalfDriveConfig::new(DriveConfig::new(0.005)), 1).unwrap();
    g.bench_function("half/drive", |b| b.iter(|| black_box(half.next_sample())));
    let mut full = FullDrive::new(FullCar::passenger(), FullDriveConfig::new(DriveConfig::new(0.005)), 1).unwrap();
    g.bench_function("full/drive", |b| b.iter(|| black_box(full.next_sample())));
    g.finish();
}

fn config() -> Criterion {
    Criterion::default()
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_millis(1200))
        .sample_size(30)
}

criterion_group! { name = benches; config = config(); targets = identifiers, structured, noisy_states, two_axle, state_filter, corner_filter, batch_least_squares, simulator }
criterion_main!(benches);

//! `identify::Differenced`: identification on a road that is not white (`identify/road.rs`).
//! References: least squares on samples differenced by the test itself (nalgebra's solver),
//! the car's true constants on drives of vehid's ISO 8608 road (seeds not used while the
//! method was developed), and the wrapper's own contract (transactional, persistence).

use nalgebra::{DMatrix, DVector};
use rand::{rngs::Xoshiro256PlusPlus, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use vehid_core::identify::KalmanOptions;
use vehid_core::identify::{
    Contact, Differenced, Identifier, IvIdentifier, RoadModel, StructuredKalman, StructuredPrior, Travel,
};
use vehid_core::model::QuarterCar;
use vehid_core::sim::{DriveConfig, QuarterDrive, SensorSet};
use vehid_core::structure::{Basis, Structure, Term, Var};
use vehid_core::Error;

/// `ż = a x + b y + 2 h`: `h` a random walk held constant between samples, `x` an AR(1)
/// process plus the road one sample earlier (correlated with `h`: least squares on the levels
/// is biased), `y` an AR(1) process. The differences' error `2 Δh` is independent of the
/// differenced regressors, so least squares on them is consistent.
fn random_walk_data(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>, [f64; 2]) {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
    let (a, b) = (-3.0, 1.5);
    let (mut x, mut y, mut h): (f64, f64, f64);
    (y, h) = (0.0, 0.0);
    let (mut xs, mut zs) = (vec![], vec![]);
    let mut ar = 0.0;
    for _ in 0..n {
        ar = 0.9 * ar + g();
        x = ar + h; // the state follows the road, one sample late
        y = 0.5 * y + g();
        h += 0.3 * g();
        xs.extend_from_slice(&[x, y]);
        zs.extend_from_slice(&[a * x + b * y + 2.0 * h, 0.0]);
    }
    (xs, zs, [a, b])
}

/// The structure `dx1 = a x0 + b x1` read as state 0's equation (a 2-state system whose
/// regressors are the two states).
fn two_param() -> Structure<f64> {
    let mut s = Structure::new(2, 0, 2).unwrap();
    let t = |p: u8, v: u8| Term { coef: 1.0, param: Some(p), basis: Basis::Var(Var::State(v)) };
    s.push_equation(0, &[t(0, 0), t(1, 1)]).unwrap();
    s
}

fn kalman(s: Structure<f64>) -> StructuredKalman<f64, 2, 1> {
    StructuredKalman::new(s, StructuredPrior::Exact, None, &[1.0], KalmanOptions::default()).unwrap()
}

#[test]
fn differenced_least_squares_is_least_squares_on_the_differences() {
    let (x, z, truth) = random_walk_data(3000, 11);
    let s = two_param();
    let mut id = Differenced::new(kalman(s), &s, RoadModel::RandomWalk, Travel::PerSample(1.0)).unwrap();
    let mut plain = kalman(s);
    let mut e = [0.0];
    for k in 0..3000 {
        id.update_into(&x[2 * k..2 * k + 2], &z[2 * k..2 * k + 2], &[], &mut e).unwrap();
        plain.update_into(&x[2 * k..2 * k + 2], &z[2 * k..2 * k + 2], &[], &mut e).unwrap();
    }
    // The reference: normal equations of the differences, formed here.
    let rows = 2999;
    let dx = DMatrix::from_fn(rows, 2, |k, j| x[2 * (k + 1) + j] - x[2 * k + j]);
    let dz = DVector::from_fn(rows, |k, _| z[2 * (k + 1)] - z[2 * k]);
    let want = (dx.transpose() * &dx).lu().solve(&(dx.transpose() * dz)).unwrap();
    let mut got = [0.0; 2];
    id.params_into(&mut got).unwrap();
    for j in 0..2 {
        assert!((got[j] - want[j]).abs() < 1e-9 * want[j].abs(), "θ{j}: {} against {}", got[j], want[j]);
        assert!((got[j] / truth[j] - 1.0).abs() < 0.02, "θ{j}: {} against the truth {}", got[j], truth[j]);
    }
    assert_eq!(id.samples(), 3000);
    assert_eq!(id.inner().samples(), 2999);
    // Without differencing the random walk makes least squares wander far off.
    let mut p = [0.0; 2];
    plain.params_into(&mut p).unwrap();
    assert!((0..2).any(|j| (p[j] / truth[j] - 1.0).abs() > 0.1), "plain least squares: {p:?}");
}

#[test]
fn odometer_at_constant_speed_is_the_per_sample_distance_and_weights_by_distance() {
    let (x, z, _) = random_walk_data(500, 12);
    let s = two_param();
    let road = RoadModel::Shaped { cutoff: 0.01 };
    let mut fixed = Differenced::new(kalman(s), &s, road, Travel::PerSample(0.075)).unwrap();
    let mut odo = Differenced::new(kalman(s), &s, road, Travel::Odometer { reference: 0.075 }).unwrap();
    assert_eq!(odo.dims().inputs, 1);
    let mut e = [0.0];
    for k in 0..500 {
        let (xk, zk) = (&x[2 * k..2 * k + 2], &z[2 * k..2 * k + 2]);
        fixed.update_into(xk, zk, &[], &mut e).unwrap();
        odo.update_into(xk, zk, &[0.075 * k as f64], &mut e).unwrap();
    }
    let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
    fixed.params_into(&mut a).unwrap();
    odo.params_into(&mut b).unwrap();
    for j in 0..2 {
        assert!((a[j] - b[j]).abs() < 1e-9 * a[j].abs(), "{a:?} against {b:?}");
    }
    // ρ and w themselves: with x = (1, 0.5) then (1, 0.5) and z = 0 then 1 over 8 m, the
    // differenced sample is x̃ = w (1 − ρ)(1, 0.5), z̃ = w (1, 0), w = √(2/8).
    let prior = || {
        StructuredKalman::<f64, 2, 1>::new(s, StructuredPrior::Scalar(10.0), None, &[1.0], KalmanOptions::default())
            .unwrap()
    };
    let mut one = Differenced::new(prior(), &s, road, Travel::Odometer { reference: 2.0 })
        .unwrap()
        .with_min_spacing(0.0)
        .unwrap();
    one.update_into(&[1.0, 0.5], &[0.0, 0.0], &[10.0], &mut e).unwrap();
    assert_eq!(e, [0.0], "the first sample only starts a difference");
    one.update_into(&[1.0, 0.5], &[1.0, 0.0], &[18.0], &mut e).unwrap();
    let rho = (-2.0 * std::f64::consts::PI * 0.01 * 8.0).exp();
    let (mut by_hand, mut d) = (prior(), [0.0]);
    let w = 0.5;
    by_hand.update_into(&[w * (1.0 - rho), w * 0.5 * (1.0 - rho)], &[w, 0.0], &[], &mut d).unwrap();
    assert_eq!(e, d, "the innovation of the sample differenced by hand");
    let (mut p1, mut p2) = ([0.0; 4], [0.0; 4]);
    by_hand.covariance_into(&mut p1).unwrap();
    one.covariance_into(&mut p2).unwrap();
    assert_eq!(p1, p2, "one differenced sample is the sample w (x − ρ x_prev)");
    // A vehicle standing still: the weight is capped at MAX_ROAD_WEIGHT.
    one.update_into(&[1.0, 0.5], &[2.0, 0.0], &[18.0], &mut e).unwrap();
    by_hand.update_into(&[0.0, 0.0], &[10.0, 0.0], &[], &mut d).unwrap();
    assert_eq!(e, d, "a sample over no distance weighs MAX_ROAD_WEIGHT = 10");
}

#[test]
fn samples_closer_than_min_spacing_are_skipped() {
    let (x, z, _) = random_walk_data(2000, 15);
    let s = two_param();
    let road = RoadModel::Shaped { cutoff: 0.01 };
    // 0.075 m per sample, at least 0.25 m apart: every fourth sample is differenced.
    let mut spaced = Differenced::new(kalman(s), &s, road, Travel::PerSample(0.075)).unwrap();
    assert_eq!(spaced.min_spacing(), vehid_core::identify::DEFAULT_MIN_SPACING);
    let mut every4 =
        Differenced::new(kalman(s), &s, road, Travel::PerSample(0.3)).unwrap().with_min_spacing(0.0).unwrap();
    let mut odo = Differenced::new(kalman(s), &s, road, Travel::Odometer { reference: 0.3 }).unwrap();
    let mut e = [0.0];
    for k in 0..2000 {
        let (xk, zk) = (&x[2 * k..2 * k + 2], &z[2 * k..2 * k + 2]);
        spaced.update_into(xk, zk, &[], &mut e).unwrap();
        odo.update_into(xk, zk, &[0.075 * k as f64], &mut e).unwrap();
        if k % 4 == 0 {
            every4.update_into(xk, zk, &[], &mut e).unwrap();
        } else {
            assert_eq!(e, [0.0], "a skipped sample has no innovation");
        }
    }
    let (mut a, mut b, mut c) = ([0.0; 2], [0.0; 2], [0.0; 2]);
    spaced.params_into(&mut a).unwrap();
    every4.params_into(&mut b).unwrap();
    odo.params_into(&mut c).unwrap();
    for j in 0..2 {
        assert!((a[j] - b[j]).abs() < 1e-12 * b[j].abs(), "{a:?} against every fourth sample {b:?}");
        assert!((c[j] - b[j]).abs() < 1e-9 * b[j].abs(), "odometer {c:?} against every fourth sample {b:?}");
    }
    assert_eq!((spaced.samples(), spaced.inner().samples()), (2000, 499));
    // A skipped sample is still checked.
    assert!(matches!(spaced.update_into(&[f64::NAN, 0.0], &[0.0, 0.0], &[], &mut e), Err(Error::NonFinite { .. })));
    assert!(Differenced::new(kalman(s), &s, road, Travel::PerSample(0.1)).unwrap().with_min_spacing(-1.0).is_err());
}

#[test]
fn lifted_samples_are_counted_and_used_as_any_other() {
    // Two states (read as wheel and body accelerations z[0], z[1] for the check): masses 1 and
    // 3, so a sample counts as lifted when z0 + 3 z1 < -4 g (1 - LIFT_OFF_LOAD).
    let (x, mut z, _) = random_walk_data(400, 16);
    let lifted_at = [57usize, 58, 200];
    for &k in &lifted_at {
        z[2 * k + 1] = -20.0; // z0 + 3 z1 well below the limit
    }
    let s = two_param();
    let contact = Contact { wheel: 0, body: 1, m_wheel: 1.0, m_body: 3.0 };
    let mk = || {
        Differenced::new(kalman(s), &s, RoadModel::RandomWalk, Travel::PerSample(1.0))
            .unwrap()
            .with_min_spacing(0.0)
            .unwrap()
    };
    let mut checked = mk().with_contact(contact).unwrap();
    let mut plain = mk();
    let mut e = [0.0];
    let lim = -4.0 * 9.80665 * (1.0 - vehid_core::identify::LIFT_OFF_LOAD);
    for k in 0..400 {
        let (xk, zk) = (&x[2 * k..2 * k + 2], &z[2 * k..2 * k + 2]);
        assert!(zk[0] + 3.0 * zk[1] >= lim || lifted_at.contains(&k), "sample {k} lifted by chance");
        checked.update_into(xk, zk, &[], &mut e).unwrap();
        plain.update_into(xk, zk, &[], &mut e).unwrap();
    }
    let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
    checked.params_into(&mut a).unwrap();
    plain.params_into(&mut b).unwrap();
    assert_eq!(a, b, "the check only counts");
    assert_eq!((checked.lifted(), checked.samples()), (3, 400));
    // A refused lifted sample is not counted.
    assert!(checked.update_into(&[f64::NAN, 0.0], &[0.0, -20.0], &[], &mut e).is_err());
    assert_eq!(checked.lifted(), 3);
    let bad = Contact { wheel: 2, ..contact };
    assert!(mk().with_contact(bad).is_err());
    assert!(mk().with_contact(Contact { m_body: 0.0, ..contact }).is_err());
    // Saved and restored, the check goes with it.
    let back: Differenced<f64, StructuredKalman<f64, 2, 1>> =
        postcard::from_bytes(&postcard::to_allocvec(&checked).unwrap()).unwrap();
    assert_eq!((back.contact(), back.lifted()), (Some(contact), 3));
}

#[test]
fn a_rejected_sample_changes_nothing() {
    let (x, z, _) = random_walk_data(300, 13);
    let s = two_param();
    let mut id = Differenced::new(kalman(s), &s, RoadModel::RandomWalk, Travel::Odometer { reference: 1.0 }).unwrap();
    let mut e = [0.0];
    for k in 0..100 {
        id.update_into(&x[2 * k..2 * k + 2], &z[2 * k..2 * k + 2], &[k as f64], &mut e).unwrap();
    }
    let bad: [(&[f64], &[f64], &[f64]); 4] = [
        (&[f64::NAN, 0.0], &[0.0, 0.0], &[100.0]),
        (&[0.0, 0.0], &[f64::INFINITY, 0.0], &[100.0]),
        (&[0.0, 0.0], &[0.0, 0.0], &[50.0]), // the odometer went back
        (&[1e308, -1e308], &[0.0, 0.0], &[100.0]),
    ];
    for (xk, zk, uk) in bad {
        let mut before = id.clone();
        assert!(id.update_into(xk, zk, uk, &mut e).is_err(), "{xk:?} {zk:?} {uk:?} was taken");
        // The same continuation from the copy taken before: the same bits.
        let mut after = id.clone();
        for k in 100..300 {
            let (xk, zk, uk) = (&x[2 * k..2 * k + 2], &z[2 * k..2 * k + 2], [k as f64]);
            before.update_into(xk, zk, &uk, &mut e).unwrap();
            after.update_into(xk, zk, &uk, &mut e).unwrap();
        }
        let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
        before.params_into(&mut a).unwrap();
        after.params_into(&mut b).unwrap();
        assert_eq!(a, b, "{xk:?} {zk:?} {uk:?}: a rejected sample changed the identifier");
        assert_eq!(before.samples(), after.samples());
    }
    assert!(matches!(id.update_into(&[0.0], &[0.0, 0.0], &[1.0], &mut e), Err(Error::Shape { .. })));
    assert!(matches!(id.update_into(&[0.0, 0.0], &[0.0, 0.0], &[], &mut e), Err(Error::Shape { .. })));
}

#[test]
fn equations_that_do_not_difference_are_refused() {
    let mut s = Structure::new(2, 0, 3).unwrap();
    let t = |p: u8, v: u8| Term { coef: 1.0, param: Some(p), basis: Basis::Var(Var::State(v)) };
    s.push_equation(0, &[t(0, 0), t(1, 1), Term { coef: 1.0, param: Some(2), basis: Basis::One }]).unwrap();
    let inner =
        StructuredKalman::<f64, 4, 1>::new(s, StructuredPrior::Exact, None, &[1.0], KalmanOptions::default()).unwrap();
    let err = Differenced::new(inner, &s, RoadModel::RandomWalk, Travel::PerSample(1.0)).unwrap_err();
    assert!(matches!(err, Error::NotIdentifiable { what } if what.contains("offset")), "{err}");

    let mut s = Structure::new(2, 0, 2).unwrap();
    let (start, len) = s.push_combination(&[(Var::State(1), 1.0)]).unwrap();
    s.push_equation(0, &[t(0, 0), Term { coef: 1.0, param: Some(1), basis: Basis::Sign { start, len } }]).unwrap();
    let inner =
        StructuredKalman::<f64, 2, 1>::new(s, StructuredPrior::Exact, None, &[1.0], KalmanOptions::default()).unwrap();
    let err = Differenced::new(inner, &s, RoadModel::RandomWalk, Travel::PerSample(1.0)).unwrap_err();
    assert!(matches!(err, Error::NotIdentifiable { what } if what.contains("sign")), "{err}");

    let s = two_param();
    for travel in [Travel::PerSample(0.0), Travel::PerSample(f64::NAN), Travel::Odometer { reference: -1.0 }] {
        let e = Differenced::new(kalman(s), &s, RoadModel::RandomWalk, travel).unwrap_err();
        assert!(matches!(e, Error::InvalidArgument { .. }), "{travel:?}: {e}");
    }
    let e = Differenced::new(kalman(s), &s, RoadModel::Shaped { cutoff: -0.01 }, Travel::PerSample(1.0)).unwrap_err();
    assert!(matches!(e, Error::InvalidArgument { arg: "road cutoff", .. }), "{e}");
    // An inner identifier of another structure.
    let other = Structure::full_rows(3, &[1]).unwrap();
    let e = Differenced::new(kalman(s), &other, RoadModel::RandomWalk, Travel::PerSample(1.0)).unwrap_err();
    assert!(matches!(e, Error::Shape { .. }), "{e}");
}

#[test]
fn a_restored_identifier_continues_bit_for_bit_and_corrupt_state_is_refused() {
    let (x, z, _) = random_walk_data(400, 14);
    let s = two_param();
    let mut id = Differenced::new(kalman(s), &s, RoadModel::Shaped { cutoff: 0.02 }, Travel::PerSample(0.1)).unwrap();
    let mut e = [0.0];
    for k in 0..200 {
        id.update_into(&x[2 * k..2 * k + 2], &z[2 * k..2 * k + 2], &[], &mut e).unwrap();
    }
    let bytes = postcard::to_allocvec(&id).unwrap();
    let mut back: Differenced<f64, StructuredKalman<f64, 2, 1>> = postcard::from_bytes(&bytes).unwrap();
    for k in 200..400 {
        id.update_into(&x[2 * k..2 * k + 2], &z[2 * k..2 * k + 2], &[], &mut e).unwrap();
        back.update_into(&x[2 * k..2 * k + 2], &z[2 * k..2 * k + 2], &[], &mut e).unwrap();
    }
    assert_eq!(postcard::to_allocvec(&id).unwrap(), postcard::to_allocvec(&back).unwrap());
    // The stored sample made NaN, a negative distance, a count below the inner one's.
    let json = serde_json::to_string(&id).unwrap();
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    for (path, bad) in [
        ("/state/prev/0", serde_json::json!(null)),
        ("/state/travel/PerSample", serde_json::json!(-0.1)),
        ("/state/seen", serde_json::json!(3)),
        ("/state/prev/40", serde_json::json!(1.0)),
    ] {
        let mut w = v.clone();
        *w.pointer_mut(path).unwrap_or_else(|| panic!("{path} in {json}")) = bad;
        let r: Result<Differenced<f64, StructuredKalman<f64, 2, 1>>, _> = serde_json::from_value(w);
        assert!(r.is_err(), "{path} corrupt but loaded");
    }
}

/// The passenger quarter car on an ISO 8608 road, true states: `(M, k1, k2, b)` from the
/// physical structure (wheel mass known), `differenced` or not, by IV with the regressors one
/// sample back as instruments.
fn constants(class: &str, speed: f64, seed: u64, n: usize, differenced: bool) -> [f64; 4] {
    let car = QuarterCar::<f64>::passenger();
    let dt = 0.005;
    let cfg = DriveConfig::new(dt).road(class.parse().unwrap()).speed(speed).sensors(SensorSet::State);
    let mut drive = QuarterDrive::new(car, cfg, seed).unwrap();
    let phys = QuarterCar::<f64>::structure([None, Some(40.0), None, None, None]).unwrap();
    let s = *phys.structure();
    let iv = IvIdentifier::<f64, 2, 2>::new(s, 1, StructuredPrior::Exact, None, &[1.0]).unwrap();
    let mut p = [0.0; 4];
    let mut e = [0.0; 2];
    if differenced {
        let road = RoadModel::Shaped { cutoff: 0.01 };
        let mut id = Differenced::new(iv, &s, road, Travel::PerSample(speed * dt)).unwrap();
        for _ in 0..n {
            let y = drive.next_sample();
            id.update_into(&y.y()[..4], &y.y()[4..], &[], &mut e).unwrap();
        }
        id.params_into(&mut p).unwrap();
    } else {
        let mut id = iv;
        for _ in 0..n {
            let y = drive.next_sample();
            id.update_into(&y.y()[..4], &y.y()[4..], &[], &mut e).unwrap();
        }
        id.params_into(&mut p).unwrap();
    }
    // p = (k2/M, b/M, M, k1)
    [p[2], p[3], p[0] * p[2], p[1] * p[2]]
}

#[test]
fn on_iso_roads_every_constant_within_five_percent_where_the_thesis_identifier_is_far_off() {
    let truth = [320.0, 200_000.0, 22_000.0, 1_500.0];
    let seeds = 7100..7106u64; // not used while the method was developed
    for (class, speed) in [("iso8608-C", 15.0), ("iso8608-E", 30.0)] {
        let mut good = 0;
        for seed in seeds.clone() {
            let c = constants(class, speed, seed, 40_000, true);
            let worst = (0..4).map(|j| (c[j] / truth[j] - 1.0).abs()).fold(0.0, f64::max);
            good += (worst < 0.05) as usize;
            if seed == 7100 {
                let plain = constants(class, speed, seed, 40_000, false);
                assert!((plain[0] / truth[0] - 1.0).abs() > 0.2, "{class}: without differencing M = {}", plain[0]);
            }
        }
        assert!(good >= 5, "{class} at {speed} m/s: {good} of 6 seeds within 5 %");
    }
}

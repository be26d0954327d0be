//! Tests of the models.

use super::*;

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-300)
}

#[cfg(feature = "alloc")]
fn assert_poles(got: &[nalgebra::Complex<f64>], printed: &[(f64, f64)], digits: i32) {
    // Printed to `digits` significant figures: agree within one unit of the last printed
    // digit (the thesis rounds most values but prints -0.6919 as -0.691).
    for (p, (re, im)) in got.iter().zip(printed) {
        let tol = |v: f64| 10f64.powi(v.abs().log10().floor() as i32 - digits + 1);
        assert!((p.re - re).abs() <= tol(*re), "pole {p} vs printed {re}{im:+}j");
        if *im != 0.0 {
            assert!((p.im - im).abs() <= tol(*im), "pole {p} vs printed {re}{im:+}j");
        } else {
            assert!(p.im.abs() < 1e-9, "pole {p} should be real");
        }
    }
}

#[cfg(feature = "alloc")]
#[test]
fn quarter_car_poles_match_eq_3_14() {
    let poles = QuarterCar::<f64>::thesis().model().poles().unwrap();
    // Eq 3.14, printed to three significant figures, sorted by real part.
    assert_poles(&poles, &[(-40.6, 0.0), (-1.90, 0.0), (-0.727, -2.30), (-0.727, 2.30)], 3);
}

#[cfg(feature = "alloc")]
#[test]
fn half_car_poles_match_eq_6_8() {
    let poles = HalfCar::<f64>::thesis().model().poles().unwrap();
    assert_poles(
        &poles,
        &[
            (-65.3, 0.0),
            (-61.5, 0.0),
            (-0.837, 0.0),
            (-0.738, 0.0),
            (-0.691, -2.08),
            (-0.691, 2.08),
            (-0.656, -3.11),
            (-0.656, 3.11),
        ],
        3,
    );
}

#[test]
fn quarter_car_round_trip_both_known_masses() {
    let car = QuarterCar::new(12.5, 1.3, 95.0, 47.0, 38.0).unwrap();
    for known in [QuarterKnown::WheelMass(1.3), QuarterKnown::BodyMass(12.5)] {
        let back = QuarterCar::from_theta(&car.theta(), known).unwrap();
        for (x, y) in [
            (back.m_body(), car.m_body()),
            (back.m_wheel(), car.m_wheel()),
            (back.k1(), car.k1()),
            (back.k2(), car.k2()),
            (back.b(), car.b()),
        ] {
            assert!(close(x, y, 1e-12), "{x} vs {y}");
        }
    }
}

#[test]
fn half_car_round_trip() {
    let p = HalfCarParams {
        k11: 110.0,
        k21: 95.0,
        k12: 42.0,
        k22: 37.0,
        b1: 61.0,
        b2: 55.0,
        m1: 1.1,
        m2: 0.9,
        m_body: 21.0,
        j: 58.0,
        l1: 1.8,
        l2: 1.2,
    };
    let car = HalfCar::new(p).unwrap();
    let b = car.model().b().clone_owned();
    let back = HalfCar::from_theta(&car.theta(), p.m1, p.m2, b[(1, 0)], b[(3, 1)]).unwrap();
    let q = back.params();
    for (x, y) in [
        (q.k11, p.k11),
        (q.k21, p.k21),
        (q.k12, p.k12),
        (q.k22, p.k22),
        (q.b1, p.b1),
        (q.b2, p.b2),
        (q.m_body, p.m_body),
        (q.j, p.j),
        (q.l1, p.l1),
        (q.l2, p.l2),
    ] {
        assert!(close(x, y, 1e-10), "{x} vs {y}");
    }
}

#[test]
fn physical_map_refuses_what_it_cannot_know() {
    let th = QuarterCar::<f64>::thesis().theta();
    assert!(matches!(
        QuarterCar::from_theta(&th, QuarterKnown::WheelMass(0.0)),
        Err(Error::InvalidArgument { arg: "m", .. })
    ));
    let zero = SMatrix::<f64, 2, 4>::zeros();
    assert!(matches!(QuarterCar::from_theta(&zero, QuarterKnown::WheelMass(1.0)), Err(Error::NotIdentifiable { .. })));
    let mut nan = th;
    nan[(0, 1)] = f64::NAN;
    assert!(matches!(
        QuarterCar::from_theta(&nan, QuarterKnown::WheelMass(1.0)),
        Err(Error::NonFinite { arg: "theta", index: 1 })
    ));
}

#[test]
fn constants_are_validated() {
    assert!(matches!(QuarterCar::new(10.0, 0.0, 90.0, 50.0, 40.0), Err(Error::InvalidArgument { arg: "m", .. })));
    assert!(matches!(QuarterCar::new(f64::NAN, 1.0, 90.0, 50.0, 40.0), Err(Error::InvalidArgument { arg: "M", .. })));
    let mut p = HalfCar::<f64>::thesis().params();
    p.j = -1.0;
    assert!(matches!(HalfCar::new(p), Err(Error::InvalidArgument { arg: "J", .. })));
}

#[test]
fn linear_model_validation_and_structure() {
    let car = QuarterCar::<f64>::thesis().model();
    assert_eq!(car.unknown_rows().as_slice(), &[1, 3]);
    assert_eq!(car.kinematic_source(0), Some(1));
    assert_eq!(car.kinematic_source(2), Some(3));
    assert_eq!(car.kinematic_source(1), None);
    let bad = LinearModel::new(*car.a(), *car.b(), &[1, 4]);
    assert!(matches!(bad, Err(Error::BadRow { row: 4, .. })));
    let dup = LinearModel::new(*car.a(), *car.b(), &[1, 1]);
    assert!(matches!(dup, Err(Error::BadRow { row: 1, .. })));
    let mut a = *car.a();
    a[(2, 3)] = f64::INFINITY;
    assert!(matches!(LinearModel::new(a, *car.b(), &[1]), Err(Error::NonFinite { arg: "a", index: 11 })));
    let half = HalfCar::<f64>::thesis().model();
    let zeros =
        (0..8).flat_map(|r| (0..8).map(move |c| (r, c))).filter(|&(r, c)| half.is_structural_zero(r, c)).count();
    assert_eq!(zeros, 4);
}

#[test]
fn row_noise_var_is_diag_of_rv_plus_b_ru_bt() {
    let car = QuarterCar::<f64>::thesis().model();
    let r: [f64; 2] = car.row_noise_var(0.1, 0.005).unwrap();
    // Row 1: (k1/m)^2 σ_u^2 + σ_v^2 = 8100 * 0.01 + 2.5e-5; row 3 has no input.
    assert!((r[0] - (90.0f64 * 90.0 * 0.01 + 0.005 * 0.005)).abs() < 1e-12);
    assert!((r[1] - 0.005 * 0.005).abs() < 1e-18);
    assert!(car.row_noise_var::<2>(-0.1, 0.0).is_err());
    assert!(car.row_noise_var::<3>(0.1, 0.0).is_err());
}

#[test]
fn f32_models_build() {
    let car = QuarterCar::<f32>::thesis();
    assert!((car.theta()[(0, 0)] + 140.0).abs() < 1e-5);
    let half = HalfCar::<f32>::thesis();
    assert!((half.theta()[(3, 7)] + (60.0 * 4.0 + 60.0) / 60.0).abs() < 1e-5);
}

/// `a_hat` puts `θ` (row-major, one unknown row of `A` after another) into the unknown rows
/// and keeps the known ones: the true rows give `A` back exactly, a changed entry moves only
/// its own place, and a `θ` of the wrong length or with a NaN is refused (written because
/// the length check's `k · N` survived mutation: nothing in Rust called `a_hat`).
#[test]
fn a_hat_fills_the_unknown_rows_row_major() {
    fn check<const N: usize, const M: usize>(model: &LinearModel<f64, N, M>) {
        let rows = model.unknown_rows();
        let k = rows.len();
        let theta: Vec<f64> = rows.as_slice().iter().flat_map(|&r| (0..N).map(move |j| model.a()[(r, j)])).collect();
        assert_eq!(theta.len(), k * N);
        assert_eq!(model.a_hat(&theta).unwrap(), *model.a(), "the true rows give A back");
        for (i, &r) in rows.as_slice().iter().enumerate() {
            for j in 0..N {
                let mut t = theta.clone();
                t[i * N + j] += 1.5;
                let got = model.a_hat(&t).unwrap();
                let mut want = *model.a();
                want[(r, j)] += 1.5;
                assert_eq!(got, want, "θ[{}] is A[({r}, {j})]", i * N + j);
            }
        }
        for bad in [k * N - 1, k * N + 1, N, 0] {
            let err = model.a_hat(&vec![0.0; bad]).unwrap_err();
            assert_eq!(err, Error::Shape { arg: "theta", expected: k * N, got: bad });
        }
        let mut t = theta.clone();
        t[k * N - 1] = f64::NAN;
        assert!(matches!(model.a_hat(&t), Err(Error::NonFinite { .. })));
    }
    check(&QuarterCar::<f64>::thesis().model());
    check(&HalfCar::<f64>::thesis().model());
}

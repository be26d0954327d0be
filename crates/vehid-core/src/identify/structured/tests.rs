use super::*;
use crate::identify::KalmanIdentifier;
use crate::model::QuarterCar;
use crate::sim::{SimConfig, Simulator};
use crate::structure::{Basis, Term, Var};
use rand::rngs::Xoshiro256PlusPlus;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

fn quarter_samples(n: usize, seed: u64) -> (Vec<[f64; 4]>, Vec<[f64; 4]>) {
    let car = QuarterCar::<f64>::thesis();
    let mut sim = Simulator::new(car.model(), SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005), seed).unwrap();
    (0..n)
        .map(|_| {
            let s = sim.next_sample();
            let (x, z) = (s.r, s.z);
            ([x[0], x[1], x[2], x[3]], [z[0], z[1], z[2], z[3]])
        })
        .unzip()
}

#[test]
fn full_rows_are_the_kalman_rows() {
    let (xs, zs) = quarter_samples(3000, 7);
    let s = Structure::<f64>::full_rows(4, &[1, 3]).unwrap();
    let opts = KalmanOptions::default();
    for p0 in [StructuredPrior::Exact, StructuredPrior::Scalar(1000.0)] {
        let r = [81.000025, 2.5e-5];
        let mut a = StructuredKalman::<f64, 4, 2>::new(s, p0, None, &r, opts).unwrap();
        let mut b = match p0 {
            StructuredPrior::Exact => KalmanIdentifier::<f64, 4, 2>::exact(&[1, 3], &r, opts).unwrap(),
            _ => KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r).unwrap(),
        };
        let (mut ea, mut eb) = ([0.0; 2], [0.0; 2]);
        for (x, z) in xs.iter().zip(&zs) {
            a.update_into(x, z, &[], &mut ea).unwrap();
            b.update_into(x, z, &[], &mut eb).unwrap();
            // The innovations (NaN during the exact start, in both).
            assert_eq!(ea.map(f64::to_bits), eb.map(f64::to_bits));
        }
        // Bit for bit: the plain step has the rows identifier's arithmetic.
        let (mut ta, mut tb) = ([0.0; 8], [0.0; 8]);
        a.params_into(&mut ta).unwrap();
        b.params_into(&mut tb).unwrap();
        assert_eq!(ta, tb);
        let (mut ca, mut cb) = ([0.0; 64], [0.0; 64]);
        a.covariance_into(&mut ca).unwrap();
        b.covariance_into(&mut cb).unwrap();
        assert_eq!(ca, cb);
        let (mut sa, mut na, mut sb, mut nb) = ([0.0; 2], [0.0; 2], [0.0; 2], [0.0; 2]);
        a.residuals_into(&mut sa, &mut na).unwrap();
        b.residuals_into(&mut sb, &mut nb).unwrap();
        assert_eq!((sa, na), (sb, nb));
    }
}

/// The plain step plans every group before it applies any: a sample the second group
/// refuses (its own regressor overflows `s`) leaves the first group unchanged too.
#[test]
fn plain_step_plans_every_group_before_applying() {
    // ẋ0 = a x0, ẋ1 = b x1: two groups, one equation each.
    let mut s = Structure::<f64>::new(2, 0, 2).unwrap();
    let t = |param, i| Term { coef: 1.0, param: Some(param), basis: Basis::Var(Var::State(i)) };
    s.push_equation(0, &[t(0, 0)]).unwrap();
    s.push_equation(1, &[t(1, 1)]).unwrap();
    let mut id =
        StructuredKalman::<f64, 1, 2>::new(s, StructuredPrior::Scalar(10.0), None, &[1.0], KalmanOptions::default())
            .unwrap();
    let mut e = [0.0; 2];
    for k in 0..50 {
        let x = [1.0 + (k % 7) as f64, 2.0 - (k % 5) as f64];
        id.update_into(&x, &[-2.0 * x[0], 0.5 * x[1]], &[], &mut e).unwrap();
    }
    assert!(id.filter(0).plain() && id.filter(1).plain(), "the fast path is the one tested");
    let before = id.clone();
    assert!(id.update_into(&[1.0, 1e200], &[-2.0, 0.0], &[], &mut e).is_err());
    assert_eq!((before.filter(0), before.filter(1)), (id.filter(0), id.filter(1)));
    assert_eq!((before.equation_ssr(0), before.equation_ssr(1)), (id.equation_ssr(0), id.equation_ssr(1)));
    assert_eq!(before.samples(), id.samples());
}

/// A structure with every kind of term, three groups of 3, 2 and 1 parameters (so two
/// groups of lanes, one lane padding): ẋ0 = a x0 + b u0 + c − 0.5 x1,
/// ẋ1 = d (x2 − x1) + f sign(x3), ẋ2 = g der(0); its equations pushed in the order
/// `order` (the parameters' numbering kept: with another order than `[0, 1, 2]` the
/// groups, numbered by parameter, come in another order than the equations, and the fast
/// path's lanes are out of the equations' order).
fn mixed_structure_in_order(order: [usize; 3]) -> Structure<f64> {
    let mut s = Structure::<f64>::new(4, 1, 6).unwrap();
    let (st, len) = s.push_combination(&[(Var::State(3), 1.0)]).unwrap();
    let t = |coef, param, basis| Term { coef, param, basis };
    let v = |i| Basis::Var(Var::State(i));
    for eq in order {
        match eq {
            0 => s.push_equation(
                0,
                &[
                    t(1.0, Some(0), v(0)),
                    t(1.0, Some(1), Basis::Var(Var::Input(0))),
                    t(1.0, Some(2), Basis::One),
                    t(0.5, None, v(1)),
                ],
            ),
            1 => s.push_equation(
                1,
                &[t(1.0, Some(3), v(2)), t(-1.0, Some(3), v(1)), t(2.0, Some(4), Basis::Sign { start: st, len })],
            ),
            _ => s.push_equation(2, &[t(1.0, Some(5), Basis::Var(Var::Deriv(0)))]),
        }
        .unwrap();
    }
    s
}

/// The fast path (the groups in lanes, the compiled regression) gives what the general
/// path (each group's `RowIdentifier::update` on the interpreted regression) gives, to
/// rounding, over many samples: innovations, estimate, covariance, statistics; with a
/// prior and after an exact start, on the mixed structure (the physical one below), its
/// equations in the groups' order and out of it.
#[test]
fn the_lanes_are_the_general_path() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
    let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
    let samples: Vec<([f64; 4], [f64; 4], [f64; 1])> = (0..3000)
        .map(|_| {
            let (x, u) = ([g(), g(), g(), g()], [g()]);
            let z0 = -2.0 * x[0] + 0.7 * u[0] + 0.3 - 0.5 * x[1] + 0.1 * g();
            let z = [z0, 1.5 * (x[2] - x[1]) - 0.4 * x[3].signum() + 0.2 * g(), 0.8 * z0 + 0.05 * g(), g()];
            (x, z, u)
        })
        .collect();
    let close = |a: f64, b: f64, what: &str| {
        assert!((a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-3), "{what}: {a} vs {b}");
    };
    let r = [0.01, 0.04, 0.0025];
    // The equations in the groups' order, and out of it (equation i in group (i + 2) % 3).
    for (order, p0) in [
        ([0, 1, 2], StructuredPrior::Scalar(100.0)),
        ([0, 1, 2], StructuredPrior::Exact),
        ([2, 0, 1], StructuredPrior::Scalar(100.0)),
    ] {
        let st = mixed_structure_in_order(order);
        let r = order.map(|i| r[i]);
        let fast = StructuredKalman::<f64, 3, 3>::new(st, p0, None, &r, KalmanOptions::default()).unwrap();
        assert_eq!(fast.fast.in_order(), order == [0, 1, 2]);
        let general = fast.clone().without_lanes();
        let (mut a, mut b) = (fast, general);
        let (mut ea, mut eb) = ([0.0; 3], [0.0; 3]);
        for (k, (x, z, u)) in samples.iter().enumerate() {
            a.update_into(x, z, u, &mut ea).unwrap();
            b.update_into(x, z, u, &mut eb).unwrap();
            if k > 20 {
                (0..3).for_each(|i| close(ea[i], eb[i], "innovation"));
            }
        }
        assert!(a.fast.live() && !b.fast.live(), "each path is the one tested");
        let (mut ta, mut tb) = ([0.0; 6], [0.0; 6]);
        a.params_into(&mut ta).unwrap();
        b.params_into(&mut tb).unwrap();
        (0..6).for_each(|j| close(ta[j], tb[j], "theta"));
        let (mut ca, mut cb) = ([0.0; 36], [0.0; 36]);
        a.covariance_into(&mut ca).unwrap();
        b.covariance_into(&mut cb).unwrap();
        (0..36).for_each(|j| close(ca[j], cb[j], "covariance"));
        let (mut sa, mut na, mut sb, mut nb) = ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3]);
        a.residuals_into(&mut sa, &mut na).unwrap();
        b.residuals_into(&mut sb, &mut nb).unwrap();
        assert_eq!(na, nb);
        (0..3).for_each(|i| close(sa[i], sb[i], "ssr"));
        close(a.trace().unwrap(), b.trace().unwrap(), "trace");
        // A covariance reset (the lanes written back first), then the lanes again.
        a.reset_covariance(10.0).unwrap();
        b.reset_covariance(10.0).unwrap();
        for (x, z, u) in &samples[..300] {
            a.update_into(x, z, u, &mut ea).unwrap();
            b.update_into(x, z, u, &mut eb).unwrap();
        }
        assert!(a.fast.live());
        a.params_into(&mut ta).unwrap();
        b.params_into(&mut tb).unwrap();
        (0..6).for_each(|j| close(ta[j], tb[j], "theta after a reset"));
        // Leaving the lanes gives the filters the lanes held.
        let f = a.filter(1);
        let a = a.without_lanes();
        assert_eq!(a.filter(1), f);
    }
}

/// The same on the quarter car's physical structure (m known: differences of states and
/// a `der(·)` term in two groups of two), simulated data.
#[test]
fn the_lanes_are_the_general_path_on_the_physical_structure() {
    let (xs, zs) = quarter_samples(3000, 5);
    let ph = *QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap().structure();
    for p0 in [StructuredPrior::Scalar(1000.0), StructuredPrior::Exact] {
        let mut a = StructuredKalman::<f64, 2, 2>::new(ph, p0, None, &[1.0], KalmanOptions::default()).unwrap();
        let mut b = a.clone().without_lanes();
        let (mut ea, mut eb) = ([0.0; 2], [0.0; 2]);
        for (x, z) in xs.iter().zip(&zs) {
            a.update_into(x, z, &[], &mut ea).unwrap();
            b.update_into(x, z, &[], &mut eb).unwrap();
        }
        assert!(a.fast.live() && !b.fast.live());
        let (mut ta, mut tb) = ([0.0; 4], [0.0; 4]);
        a.params_into(&mut ta).unwrap();
        b.params_into(&mut tb).unwrap();
        for j in 0..4 {
            assert!((ta[j] - tb[j]).abs() <= 1e-9 * ta[j].abs().max(1e-3), "{ta:?} vs {tb:?}");
        }
        let (mut ca, mut cb) = ([0.0; 16], [0.0; 16]);
        a.covariance_into(&mut ca).unwrap();
        b.covariance_into(&mut cb).unwrap();
        for j in 0..16 {
            assert!((ca[j] - cb[j]).abs() <= 1e-9 * ca[j].abs().max(cb[j].abs()) + 1e-300, "{ca:?} vs {cb:?}");
        }
    }
}

/// Two equations sharing a parameter, weighted by `r`: every estimate after the start is
/// weighted least squares on all samples so far (normal equations solved directly).
#[test]
fn shared_parameters_are_weighted_least_squares() {
    // ẋ0 = a x0 + b u0, ẋ1 = a x1 + c (one offset): a shared.
    let mut s = Structure::<f64>::new(2, 1, 3).unwrap();
    let t = |coef, param, basis| Term { coef, param: Some(param), basis };
    s.push_equation(0, &[t(1.0, 0, Basis::Var(Var::State(0))), t(1.0, 1, Basis::Var(Var::Input(0)))]).unwrap();
    s.push_equation(1, &[t(1.0, 0, Basis::Var(Var::State(1))), t(1.0, 2, Basis::One)]).unwrap();
    let r = [0.04, 0.25];
    let mut id =
        StructuredKalman::<f64, 3, 1>::new(s, StructuredPrior::Exact, None, &r, KalmanOptions::default()).unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
    let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
    let (mut ata, mut atb) = (nalgebra::Matrix3::<f64>::zeros(), nalgebra::Vector3::<f64>::zeros());
    let mut e = [0.0; 2];
    for k in 0..200 {
        let (x, u) = ([g(), g()], [g()]);
        let z = [-2.0 * x[0] + 0.5 * u[0] + 0.2 * g(), -2.0 * x[1] + 1.5 + 0.5 * g()];
        id.update_into(&x, &z, &u, &mut e).unwrap();
        let rows = [([x[0], u[0], 0.0], z[0], r[0]), ([x[1], 0.0, 1.0], z[1], r[1])];
        for (h, y, ri) in rows {
            let h = nalgebra::Vector3::from(h);
            ata += h * h.transpose() / ri;
            atb += h * y / ri;
        }
        if k >= 3 {
            let want = ata.cholesky().unwrap().solve(&atb);
            let mut got = [0.0; 3];
            id.params_into(&mut got).unwrap();
            for j in 0..3 {
                assert!((got[j] - want[j]).abs() <= 1e-9 * want[j].abs().max(1.0), "k {k}: {got:?} vs {want:?}");
            }
        }
    }
}

#[test]
fn rejected_samples_change_nothing_and_unexcited_terms_are_named() {
    // ẋ0 = a x0 + c sign(x1): x1 never changes sign, so c is an offset confounded with
    // nothing, but a is fine; then x1 ≡ 0: sign = 0, c unidentified.
    let mut s = Structure::<f64>::new(2, 0, 2).unwrap();
    let (st, len) = s.push_combination(&[(Var::State(1), 1.0)]).unwrap();
    let t = |param, basis| Term { coef: 1.0, param: Some(param), basis };
    s.push_equation(0, &[t(0, Basis::Var(Var::State(0))), t(1, Basis::Sign { start: st, len })]).unwrap();
    let mut id = StructuredKalman::<f64, 2, 1>::exact(s, KalmanOptions::default()).unwrap();
    let mut e = [0.0];
    for k in 0..20 {
        id.update_into(&[1.0 + k as f64, 0.0], &[0.5, 0.0], &[], &mut e).unwrap();
    }
    assert!(id.starting() && !id.unidentified(0) && id.unidentified(1));
    let mut p = [0.0; 2];
    assert!(matches!(id.params_into(&mut p), Err(Error::RankDeficient { rank: 1, needed: 2 })));
    id.update_into(&[1.0, 2.0], &[0.5, 0.0], &[], &mut e).unwrap();
    id.params_into(&mut p).unwrap();
    let before = id.clone();
    assert!(id.update_into(&[f64::NAN, 1.0], &[0.0, 0.0], &[], &mut e).is_err());
    assert!(id.update_into(&[1e300, 1e300], &[1e300, 0.0], &[], &mut e).is_err());
    assert_eq!(before.filter(0), id.filter(0));
    assert_eq!((before.equation_ssr(0), before.samples()), (id.equation_ssr(0), id.samples()));
}

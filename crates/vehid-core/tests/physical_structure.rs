//! The vehicles' physical structures: they reproduce the models exactly, and on the thesis'
//! Fig 4-2 data the quarter car's converges in a tenth of the samples the full rows need.

use vehid_core::identify::{Identifier, KalmanIdentifier, KalmanOptions, StructuredKalman};
use vehid_core::metrics::xi;
use vehid_core::model::{HalfCar, PhysicalStructure, QuarterCar};
use vehid_core::sim::{SimConfig, Simulator};

/// Every identified equation of `ps`, at the true parameters, holds exactly on noise-free
/// samples of the model (`ẋ = A x`, no road).
fn reproduces<const N: usize>(ps: &PhysicalStructure<f64>, a: &nalgebra::SMatrix<f64, N, N>, constants: &[f64]) {
    let s = ps.structure();
    let mut p = vec![0.0; s.params()];
    ps.params_of(constants, &mut p).unwrap();
    for k in 0..20 {
        let x = nalgebra::SVector::<f64, N>::from_fn(|i, _| ((i * 7 + k * 13) % 11) as f64 / 5.0 - 1.0);
        let z = a * x;
        for i in 0..s.equations() {
            let mut h = vec![0.0; s.params()];
            let y = s.regression(i, x.as_slice(), z.as_slice(), &[], &mut h);
            let fit: f64 = h.iter().zip(&p).map(|(h, p)| h * p).sum();
            assert!((y - fit).abs() < 1e-9 * (1.0 + y.abs()), "equation {i}: {y} vs {fit}");
        }
        // And the simulation derivative is A x.
        let mut out = [0.0; N];
        s.derivative(&p, x.as_slice(), &[], &mut out);
        for i in 0..N {
            assert!((out[i] - z[i]).abs() < 1e-9 * (1.0 + z[i].abs()), "state {i}: {} vs {}", out[i], z[i]);
        }
    }
}

#[test]
fn quarter_and_half_car_structures_reproduce_their_models() {
    let car = QuarterCar::<f64>::thesis();
    let c = car.constants();
    for known in [
        [None, Some(c[1]), None, None, None],
        [Some(c[0]), None, None, None, None],
        [None, Some(1.0), Some(90.0), None, Some(40.0)],
    ] {
        let ps = QuarterCar::structure(known).unwrap();
        reproduces(&ps, car.model().a(), &c);
    }
    let ps = QuarterCar::structure([None, Some(1.0), None, None, None]).unwrap();
    assert_eq!(ps.param_names(), ["k2/M", "b/M", "M", "k1"]);
    let half = HalfCar::<f64>::thesis();
    let h = half.constants();
    let mut known = [None; 12];
    for i in 8..12 {
        known[i] = Some(h[i]);
    }
    let ps = HalfCar::structure(known).unwrap();
    assert_eq!(ps.structure().params(), 12);
    assert_eq!(ps.structure().partition().groups, 3);
    reproduces(&ps, half.model().a(), &h);
    assert!(HalfCar::<f64>::structure([None; 12]).is_err());
}

/// Physical constants → the thesis' unknown rows → ξ (Eq 3.17).
fn xi_of(ps: &PhysicalStructure<f64>, theta: &[f64], truth: &QuarterCar<f64>) -> f64 {
    let zero = vec![0.0; theta.len() * theta.len()];
    let c: Vec<f64> = (0..5).map(|i| ps.constant(i, theta, &zero).map_or(f64::NAN, |v| v.0)).collect();
    match QuarterCar::new(c[0], c[1], c[2], c[3], c[4]) {
        Ok(est) => xi(truth.theta().transpose().as_slice(), est.theta().transpose().as_slice()).unwrap(),
        Err(_) => f64::INFINITY,
    }
}

/// The first sample from which ξ stays ≤ 0.08 to the end, checked every `every` samples.
fn sustained(xis: &[(usize, f64)]) -> Option<usize> {
    let last_bad = xis.iter().rposition(|&(_, x)| !(x <= 0.08));
    match last_bad {
        None => xis.first().map(|p| p.0),
        Some(i) if i + 1 < xis.len() => Some(xis[i + 1].0),
        Some(_) => None,
    }
}

/// Must-show: the Fig 4-2 scenario (road σ 0.1, σ_v 0.005, dt 0.05, m known),
/// online from an exact start. The physical structure holds ξ ≤ 0.08 from within 4000
/// samples on at least 90 % of 50 seeds; the thesis' full rows (exact start, the true R) on
/// the same data beside it. Seeds 9000-9049; `SEED0=30000` runs 30000-30049 instead (to measure
/// on seeds the structure was not developed on).
#[test]
fn fig_4_2_physical_structure_converges_within_4000_samples() {
    let seed0: u64 = std::env::var("SEED0").ok().and_then(|s| s.parse().ok()).unwrap_or(9000);
    let car = QuarterCar::<f64>::thesis();
    let ps = QuarterCar::structure([None, Some(1.0), None, None, None]).unwrap();
    let (n, every) = (4000, 50);
    let (mut ok_struct, mut ok_rows) = (0, 0);
    for seed in seed0..seed0 + 50 {
        let mut sim =
            Simulator::new(car.model(), SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005), seed).unwrap();
        let mut id = StructuredKalman::<f64, 2, 2>::exact(*ps.structure(), KalmanOptions::default()).unwrap();
        let r = car.model().row_noise_var::<2>(0.1, 0.005).unwrap();
        let mut rows = KalmanIdentifier::<f64, 4, 2>::exact(&[1, 3], &r, KalmanOptions::default()).unwrap();
        let (mut xs, mut xr) = (vec![], vec![]);
        let (mut e, mut th, mut tr) = ([0.0; 2], [0.0; 4], [0.0; 8]);
        for k in 1..=n {
            let s = sim.next_sample();
            id.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
            rows.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
            if k % every == 0 {
                let a = if id.params_into(&mut th).is_ok() { xi_of(&ps, &th, &car) } else { f64::INFINITY };
                xs.push((k, a));
                let b = if rows.params_into(&mut tr).is_ok() {
                    xi(car.theta().transpose().as_slice(), &tr).unwrap()
                } else {
                    f64::INFINITY
                };
                xr.push((k, b));
            }
        }
        ok_struct += usize::from(sustained(&xs).is_some());
        ok_rows += usize::from(sustained(&xr).is_some());
    }
    eprintln!(
        "seeds {seed0}-{}: sustained ξ ≤ 0.08 within {n} samples: physical structure {ok_struct}/50, full rows {ok_rows}/50",
        seed0 + 49
    );
    assert!(ok_struct >= 45, "physical structure: {ok_struct}/50");
}

/// Every constant follows back from the true parameters (`constant`, the walk along the
/// parameters' edges in both directions), and its standard error is the delta method's
/// `√(gᵀ Σ g)` with `g` the constant's gradient, here by central differences of `constant`
/// itself: the quarter car with `m` known and the half car with `m1, m2, l1, l2` known.
#[test]
fn constants_follow_from_the_parameters_with_the_delta_method_standard_error() {
    fn check(ps: &PhysicalStructure<f64>, truth: &[f64]) {
        let np = ps.structure().params();
        let mut theta = vec![0.0; np];
        ps.params_of(truth, &mut theta).unwrap();
        // A covariance with correlations: Σ = L Lᵀ, L lower triangular, entries 1 % of θ.
        let l = |a: usize, b: usize| {
            if b <= a {
                0.01 * theta[a].abs() * (1.0 + 0.3 * (a + b) as f64 % 1.0) / (1.0 + (a - b) as f64)
            } else {
                0.0
            }
        };
        let cov: Vec<f64> = (0..np * np).map(|ab| (0..np).map(|k| l(ab / np, k) * l(ab % np, k)).sum()).collect();
        let zero = vec![0.0; np * np];
        for (c, &t) in truth.iter().enumerate() {
            let (v, sd) = ps.constant(c, &theta, &cov).unwrap_or_else(|e| panic!("constant {c}: {e:?}"));
            assert!((v - t).abs() <= 1e-12 * t.abs(), "constant {c}: {v} against {t}");
            let g: Vec<f64> = (0..np)
                .map(|j| {
                    let h = 1e-6 * theta[j].abs();
                    let at = |d: f64| {
                        let mut p = theta.clone();
                        p[j] += d;
                        ps.constant(c, &p, &zero).unwrap().0
                    };
                    (at(h) - at(-h)) / (2.0 * h)
                })
                .collect();
            let var: f64 = (0..np).map(|a| (0..np).map(|b| g[a] * cov[a * np + b] * g[b]).sum::<f64>()).sum();
            let expect = var.max(0.0).sqrt();
            assert!((sd - expect).abs() <= 1e-6 * expect.max(1e-300), "constant {c}: sd {sd} against {expect}");
            if ps.known(c).is_none() {
                assert!(expect > 0.0, "constant {c}: the test's covariance moves it");
            }
        }
    }
    // The quarter car anchored by each of its constants in turn (M, m, k1, k2, b): the walk
    // then runs along the edges from either end.
    let q = QuarterCar::<f64>::thesis();
    let truth = q.constants();
    for c in 0..5 {
        let mut known = [None; 5];
        known[c] = Some(truth[c]);
        check(&QuarterCar::structure(known).unwrap(), &truth);
    }
    let h = HalfCar::<f64>::thesis();
    let truth = h.constants();
    let mut known = [None; 12];
    for i in 8..12 {
        known[i] = Some(truth[i]);
    }
    check(&HalfCar::structure(known).unwrap(), &truth);
}

/// The realistic sensors' structure: `k2` and `b` with `M` known (or the ratios without it),
/// an offset; `m` and `k1` are not determined, and say what they need.
#[test]
fn realistic_structure_says_what_the_rest_needs() {
    let c = QuarterCar::<f64>::passenger().constants();
    let ps = QuarterCar::realistic_structure([Some(c[0]), None, None, None, None]).unwrap();
    assert_eq!(ps.param_names(), ["k2", "b", "offset"]);
    assert_eq!(ps.needs(0), None);
    for c in [1, 2] {
        assert!(ps.needs(c).unwrap().contains("tyre force"), "{:?}", ps.needs(c));
    }
    // Its equation at the true parameters: a_body = −(k2 d + b v)/M, the offset 0.
    let mut p = [0.0; 3];
    ps.params_of(&c, &mut p).unwrap();
    assert_eq!(p, [c[3], c[4], 0.0]);
    let (x, z) = ([0.01, -0.2, 0.0], [-0.2, 0.0, -(c[3] * 0.01 - c[4] * 0.2) / c[0]]);
    assert!(ps.structure().residual(0, &p, &x, &z, &[]).abs() < 1e-12);
    // Without a known mass only the ratios: every constant needs a mass, or the tyre force.
    let ratios = QuarterCar::<f64>::realistic_structure([None; 5]).unwrap();
    assert_eq!(ratios.param_names(), ["k2/M", "b/M", "offset"]);
    for c in [0, 3, 4] {
        assert!(ratios.needs(c).unwrap().contains("known mass"), "{:?}", ratios.needs(c));
    }
    // The state sensors' structure determines everything once m is known.
    let full = QuarterCar::<f64>::structure([None, Some(c[1]), None, None, None]).unwrap();
    assert!((0..5).all(|c| full.needs(c).is_none()));
}

/// The state-variable filter's fit of the realistic sensors' body equation: on drives over ISO
/// roads with the default (biased, noisy) sensors, `k2` and `b` with `M` known within their
/// intervals and within 1 %; the offset takes the body accelerometer's bias.
#[test]
fn state_filter_fit_of_the_realistic_sensors() {
    use vehid_core::identify::{StateFilterFit, DEFAULT_BANDWIDTH, DEFAULT_BLOCK};
    use vehid_core::sim::{DriveConfig, QuarterDrive, RoadClass};
    let (car, dt) = (QuarterCar::<f64>::passenger(), 0.005);
    let c = car.constants();
    let ps = QuarterCar::realistic_structure([Some(c[0]), None, None, None, None]).unwrap();
    let (mut inside, mut runs) = (0, 0);
    for (seed, road, speed) in
        [(52_101, RoadClass::C, 15.0), (52_102, RoadClass::B, 10.0), (52_103, RoadClass::D, 25.0)]
    {
        let mut fit = StateFilterFit::new(*ps.structure(), dt, DEFAULT_BANDWIDTH, DEFAULT_BLOCK).unwrap();
        let mut drive = QuarterDrive::new(car, DriveConfig::new(dt).road(road).speed(speed), seed).unwrap();
        for _ in 0..(120.0 / dt) as usize {
            fit.update(drive.next_sample().y()).unwrap();
        }
        let st = fit.stats(0.05).unwrap();
        for (j, want) in [(0, c[3]), (1, c[4])] {
            let (lo, hi) = st.conf_int[j];
            runs += 1;
            inside += usize::from(lo <= want && want <= hi);
            assert!(
                (st.params[j] - want).abs() < 0.01 * want,
                "{seed} {}: {} vs {want}",
                ps.param_names()[j],
                st.params[j]
            );
        }
        let bias = drive.biases()[0];
        assert!((st.params[2] - bias).abs() < 0.005, "offset {} for a bias {bias}", st.params[2]);
    }
    // Six intervals at 95 %: at least five cover the truth (P(≤ 4) = 0.3 % if they are right).
    assert!(inside >= 5, "{inside} of {runs} intervals cover the truth");
}

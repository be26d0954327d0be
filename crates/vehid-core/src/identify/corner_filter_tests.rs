//! Tests of the full car's corner fit: the coefficients and the constants from a drive's
//! realistic sensors, the constants exact on exact coefficients (anti-roll bars, a start far
//! off), persistence, bad input.

use super::*;
use crate::health::full_coefficients;
use crate::model::{FullCar, FullCarParams};
use crate::sim::{DriveConfig, FullDrive, FullDriveConfig};

fn with_bars() -> FullCar<f64> {
    let mut p = FullCar::<f64>::passenger().params();
    p.k = [33_000.0, 36_000.0, 39_000.0, 41_000.0];
    p.b = [900.0, 1_100.0, 1_000.0, 1_250.0];
    p.arb_f = 18_000.0;
    p.arb_r = 7_000.0;
    FullCar::new(p).unwrap()
}

/// The 36 coefficients of a car (corner `i`'s nine at `9 i`, offset 0).
fn exact(car: &FullCar<f64>) -> Vec<f64> {
    let th = full_coefficients(car);
    (0..36).map(|q| if q % 9 == 8 { 0.0 } else { th[(q % 9, q / 9)] }).collect()
}

#[test]
fn the_constants_are_exact_on_exact_coefficients() {
    let car = with_bars();
    let p = car.params();
    // The start is far off: inertias 40 % high, no bars.
    let start = FullCar::new(FullCarParams { jx: p.jx * 1.4, jy: p.jy * 1.4, arb_f: 0.0, arb_r: 0.0, ..p }).unwrap();
    let cov: Vec<f64> = (0..36 * 36).map(|q| if q / 36 == q % 36 { 1e-6 } else { 0.0 }).collect();
    let (got, _, se) = start.from_corner_coefficients(&exact(&car), &cov, p.m_body).unwrap();
    let g = got.params();
    let want = [p.jx, p.jy, p.k[0], p.k[1], p.k[2], p.k[3], p.b[0], p.b[1], p.b[2], p.b[3], p.arb_f, p.arb_r];
    let have = [g.jx, g.jy, g.k[0], g.k[1], g.k[2], g.k[3], g.b[0], g.b[1], g.b[2], g.b[3], g.arb_f, g.arb_r];
    for ((name, w), h) in crate::model::CORNER_DETERMINED.iter().zip(want).zip(have) {
        assert!((h - w).abs() <= 1e-8 * w.abs().max(1.0), "{name}: {h} for {w}");
    }
    assert!(se.iter().all(|s| s.is_finite() && *s >= 0.0));
    // What the equations do not hold is the start's.
    assert_eq!((g.kt, g.m, g.l_f, g.track_r), (p.kt, p.m, p.l_f, p.track_r));
    // A body mass 10 % off scales every constant with it.
    let (heavy, _, _) = start.from_corner_coefficients(&exact(&car), &cov, 1.1 * p.m_body).unwrap();
    assert!((heavy.params().k[2] / p.k[2] - 1.1).abs() < 1e-9);
}

#[test]
fn coefficients_and_constants_from_a_drive() {
    // The passenger car with bars on a class C road at 15 m/s, the default realistic sensors
    // (their noise and biases), 120 s at 200 Hz.
    let car = with_bars();
    let dt = 0.005;
    let mut drive = FullDrive::new(car, FullDriveConfig::new(DriveConfig::new(dt).speed(15.0)), 11).unwrap();
    let mut fit = CornerFilterFit::new(dt, CORNER_BANDWIDTH, 2.0).unwrap();
    for _ in 0..24_000 {
        fit.update(drive.next_sample().y()).unwrap();
    }
    let st = fit.stats(0.05).unwrap();
    let want = exact(&car);
    for q in (0..36).filter(|q| q % 9 != 8) {
        // Coefficients below a tenth of the largest in their equation are cross terms of
        // the roll and pitch; their error is judged against the equation's scale.
        let big = want[9 * (q / 9)..9 * (q / 9) + 8].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!((st.params[q] - want[q]).abs() < 0.02 * big, "coefficient {q}: {} for {}", st.params[q], want[q]);
    }
    let (got, _, se) = car.from_corner_coefficients(&st.params, &st.cov, car.params().m_body).unwrap();
    let (g, p) = (got.params(), car.params());
    let pairs = [(g.jx, p.jx), (g.jy, p.jy), (g.k[0], p.k[0]), (g.k[3], p.k[3]), (g.b[1], p.b[1]), (g.b[2], p.b[2])];
    for (h, w) in pairs {
        assert!((h / w - 1.0).abs() < 0.01, "{h} for {w}");
    }
    assert!((g.arb_f / p.arb_f - 1.0).abs() < 0.1, "{} for {}", g.arb_f, p.arb_f);
    assert!(se.iter().all(|s| *s > 0.0));
}

#[test]
fn a_saved_fit_restores_and_bad_input_changes_nothing() {
    let car = FullCar::<f64>::passenger();
    let dt = 0.005;
    let mut drive = FullDrive::new(car, FullDriveConfig::new(DriveConfig::new(dt)), 3).unwrap();
    let mut fit = CornerFilterFit::new(dt, CORNER_BANDWIDTH, 2.0).unwrap();
    for _ in 0..5_000 {
        fit.update(drive.next_sample().y()).unwrap();
    }
    assert!(fit.is_consistent());
    let bytes = postcard::to_allocvec(&fit).unwrap();
    let mut back: CornerFilterFit = postcard::from_bytes(&bytes).unwrap();
    assert!(back.is_consistent());
    assert_eq!(back, fit);
    let before = fit.clone();
    assert!(matches!(fit.update(&[0.0; 11]), Err(Error::Shape { .. })));
    let mut bad = [0.1; 12];
    bad[7] = f64::NAN;
    assert!(matches!(fit.update(&bad), Err(Error::NonFinite { .. })));
    assert_eq!(fit, before);
    for _ in 0..3_000 {
        let s = drive.next_sample();
        fit.update(s.y()).unwrap();
        back.update(s.y()).unwrap();
    }
    assert_eq!(back.stats(0.05).unwrap(), fit.stats(0.05).unwrap());
    let mut broken = back.clone();
    broken.closed.aa[(3, 5)] = f64::INFINITY;
    assert!(!broken.is_consistent());
    let mut broken = back;
    broken.current.n = broken.block + 1;
    assert!(!broken.is_consistent());
    // Too short a record: too few blocks for the covariance.
    let short = CornerFilterFit::new(dt, CORNER_BANDWIDTH, 2.0).unwrap();
    assert!(matches!(short.stats(0.05), Err(Error::InvalidArgument { arg: "samples", .. })));
    assert!(matches!(CornerFilterFit::new(dt, 1000.0, 2.0), Err(Error::InvalidArgument { arg: "bandwidth", .. })));
}

#[test]
fn the_covariance_is_the_cluster_sandwich_of_the_blocks() {
    // The Kronecker sums against each block's score computed directly: the blocks' sums kept
    // as they close, the noise compensation S from the fit's gains and noise estimate,
    // Θ̂ = (A − N S)⁻¹ C, G_b = C_b − (A_b − n_b S) Θ̂, meat = Σ vec G_b vec G_bᵀ.
    let dt = 0.005;
    let mut drive = FullDrive::new(with_bars(), FullDriveConfig::new(DriveConfig::new(dt)), 5).unwrap();
    let mut fit = CornerFilterFit::new(dt, CORNER_BANDWIDTH, 2.0).unwrap();
    let mut blocks: Vec<Sums> = Vec::new();
    for _ in 0..12_345 {
        if fit.current.n >= fit.block {
            blocks.push(fit.current);
        }
        fit.update(drive.next_sample().y()).unwrap();
    }
    blocks.push(fit.current);
    let st = fit.stats(0.05).unwrap();
    let mut total = Sums::default();
    blocks.iter().for_each(|b| total.add(b));
    let [g0, g01, g1] = fit.noise_gains();
    let sd = fit.deflection_noise();
    let mut sn = SMatrix::<f64, 9, 9>::zeros();
    for j in 0..4 {
        let v = sd[j] * sd[j];
        (sn[(2 * j, 2 * j)], sn[(2 * j, 2 * j + 1)]) = (g0 * v, g01 * v);
        (sn[(2 * j + 1, 2 * j)], sn[(2 * j + 1, 2 * j + 1)]) = (g01 * v, g1 * v);
    }
    assert!(sn.iter().any(|v| *v != 0.0));
    let ainv = (total.a - sn * total.n as f64).try_inverse().unwrap();
    let theta = ainv * total.c;
    let mut meat = nalgebra::DMatrix::<f64>::zeros(36, 36);
    for b in &blocks {
        let g = b.c - (b.a - sn * b.n as f64) * theta;
        let v = nalgebra::DVector::from_column_slice(g.as_slice());
        meat += &v * v.transpose();
    }
    let mut bread = nalgebra::DMatrix::<f64>::zeros(36, 36);
    for i in 0..4 {
        bread.view_mut((9 * i, 9 * i), (9, 9)).copy_from(&ainv);
    }
    let (n, g) = (total.n as f64, blocks.len() as f64);
    let cov = &bread * meat * &bread * (g / (g - 1.0) * (n - 1.0) / (n - 9.0));
    for q in 0..36 {
        assert!((st.params[q] - theta.as_slice()[q]).abs() <= 1e-9 * theta.as_slice()[q].abs().max(1.0));
        for r in 0..36 {
            let scale = (cov[(q, q)] * cov[(r, r)]).sqrt();
            assert!((st.cov[q * 36 + r] - cov[(q, r)]).abs() <= 1e-6 * scale, "cov[{q}, {r}]");
        }
    }
    assert_eq!(st.df[0], g - 1.0);
}

#[test]
fn the_noise_compensation_is_the_noise_s_own_second_moments() {
    // White noise alone in the deflection channels (σ 1, 2, 3, 4 mm; no motion, no
    // acceleration): the fourth-difference estimate is each σ within 2 %, and the filtered
    // regressors' second moments A/N are the compensation S (the gains times σ²) within
    // `tol` on the diagonal and `tol` of the diagonal's scale off it — the gains checked
    // against the noise itself, not against their own computation. Both bandwidths the cars
    // use; the narrower filter's output is correlated longer (about 2/λ), so its sample
    // moments scatter more: `tol` 3 % at 30 rad/s, 3 % × √3 at 10 (about three standard
    // errors of 200,000 samples).
    use rand::{rngs::Xoshiro256PlusPlus, SeedableRng};
    use rand_distr::{Distribution, StandardNormal};
    for bandwidth in [CORNER_BANDWIDTH, 10.0] {
        let dt = 0.005;
        let mut fit = CornerFilterFit::new(dt, bandwidth, 2.0).unwrap();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(404);
        let sigma = [1e-3, 2e-3, 3e-3, 4e-3];
        let mut y = [0.0; 12];
        for _ in 0..200_000 {
            for (j, s) in sigma.iter().enumerate() {
                let e: f64 = StandardNormal.sample(&mut rng);
                y[8 + j] = s * e;
            }
            fit.update(&y).unwrap();
        }
        let est = fit.deflection_noise();
        let [g0, g01, g1] = fit.noise_gains();
        let mut all = fit.closed.clone();
        all.close(&fit.current);
        let a = all.total.a / all.total.n as f64;
        let tol = 0.03 * (CORNER_BANDWIDTH / bandwidth).sqrt();
        for j in 0..4 {
            assert!((est[j] / sigma[j] - 1.0).abs() < 0.02, "corner {j}: {} for {}", est[j], sigma[j]);
            let v = sigma[j] * sigma[j];
            let (d0, d1, x) = (a[(2 * j, 2 * j)], a[(2 * j + 1, 2 * j + 1)], a[(2 * j, 2 * j + 1)]);
            assert!((d0 / (g0 * v) - 1.0).abs() < tol, "λ {bandwidth} corner {j}: {d0} for {}", g0 * v);
            assert!((d1 / (g1 * v) - 1.0).abs() < tol, "λ {bandwidth} corner {j}: {d1} for {}", g1 * v);
            assert!((x - g01 * v).abs() < tol * (d0 * d1).sqrt(), "λ {bandwidth} corner {j}: {x} for {}", g01 * v);
        }
    }
}

#[test]
fn noisy_deflections_are_compensated() {
    // A smooth road (ISO class B at 20 m/s) and deflection sensors five times noisier than the
    // default (1.5 mm), 300 s: plain least squares on the filtered signals reads Jx and the
    // dampers low (errors in variables: the noise adds to the regressors' second moments); the
    // compensated fit is within 3 standard errors of the car's coefficients where the plain
    // one is over 8 off on some.
    use crate::model::SensorNoise;
    use crate::sim::RoadClass;
    let car = with_bars();
    let dt = 0.005;
    let noise = SensorNoise { deflection: 1.5e-3, ..SensorNoise::default() };
    let base = DriveConfig::new(dt).speed(20.0).road(RoadClass::B).noise(noise);
    let mut drive = FullDrive::new(car, FullDriveConfig::new(base), 12).unwrap();
    let mut fit = CornerFilterFit::new(dt, CORNER_BANDWIDTH, 2.0).unwrap();
    for _ in 0..60_000 {
        fit.update(drive.next_sample().y()).unwrap();
    }
    let sd = fit.deflection_noise();
    assert!(sd.iter().all(|s| (s / 1.5e-3 - 1.0).abs() < 0.03), "{sd:?}");
    let st = fit.stats(0.05).unwrap();
    let want = exact(&car);
    let mut plain = fit.clone();
    plain.diff4 = [0.0; 4];
    let sp = plain.stats(0.05).unwrap();
    let z = |p: &[f64], q: usize| (p[q] - want[q]) / st.bse[q];
    let worst = |p: &[f64]| (0..36).filter(|q| q % 9 != 8).map(|q| z(p, q).abs()).fold(0.0, f64::max);
    assert!(worst(&st.params) < 3.0, "compensated: {}", worst(&st.params));
    assert!(worst(&sp.params) > 8.0, "plain: {}", worst(&sp.params));
}

#[test]
fn the_constants_standard_errors_are_their_scatter() {
    // Exact coefficients plus Gaussian noise of a known covariance (independent, each
    // coefficient's own size, so that the weights matter): over 400 draws each constant's
    // scatter is its standard error within 15 % (the sample sd of 400 normal draws is within
    // 15 % of the truth with probability > 0.999).
    use rand::{rngs::Xoshiro256PlusPlus, SeedableRng};
    use rand_distr::{Distribution, StandardNormal};
    let car = with_bars();
    let truth = exact(&car);
    let sd: Vec<f64> =
        truth.iter().enumerate().map(|(q, v)| 1e-3 * v.abs().max(1.0) * (1.0 + (q % 5) as f64)).collect();
    let cov: Vec<f64> = (0..36 * 36).map(|q| if q / 36 == q % 36 { sd[q / 36] * sd[q / 36] } else { 0.0 }).collect();
    let (_, _, se) = car.from_corner_coefficients(&truth, &cov, car.params().m_body).unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(81);
    let draws = 400;
    let mut sum = [0.0; 12];
    let mut sq = [0.0; 12];
    for _ in 0..draws {
        let noisy: Vec<f64> = truth
            .iter()
            .zip(&sd)
            .map(|(v, s)| v + s * <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut rng))
            .collect();
        let (got, _, _) = car.from_corner_coefficients(&noisy, &cov, car.params().m_body).unwrap();
        let g = got.params();
        let v = [g.jx, g.jy, g.k[0], g.k[1], g.k[2], g.k[3], g.b[0], g.b[1], g.b[2], g.b[3], g.arb_f, g.arb_r];
        for k in 0..12 {
            sum[k] += v[k];
            sq[k] += v[k] * v[k];
        }
    }
    for k in 0..12 {
        let n = draws as f64;
        let scatter = ((sq[k] - sum[k] * sum[k] / n) / (n - 1.0)).sqrt();
        let name = crate::model::CORNER_DETERMINED[k];
        assert!((scatter / se[k] - 1.0).abs() < 0.15, "{name}: scatter {scatter}, standard error {}", se[k]);
    }
}

#[test]
fn a_car_without_bars_keeps_their_scatter_about_zero() {
    // The passenger car has no bars: on a drive their estimates scatter about 0, and one
    // below 0 is reported as it is (with its standard error) while the car takes 0.
    let car = FullCar::<f64>::passenger();
    let dt = 0.005;
    let mut lows = 0;
    for seed in 0..6 {
        let mut drive = FullDrive::new(car, FullDriveConfig::new(DriveConfig::new(dt).speed(20.0)), 60 + seed).unwrap();
        let mut fit = CornerFilterFit::new(dt, CORNER_BANDWIDTH, 2.0).unwrap();
        for _ in 0..12_000 {
            fit.update(drive.next_sample().y()).unwrap();
        }
        let st = fit.stats(0.05).unwrap();
        let (got, values, se) = car.from_corner_coefficients(&st.params, &st.cov, car.params().m_body).unwrap();
        for (v, s) in values[10..].iter().zip(&se[10..]) {
            assert!(v.abs() < 4.0 * s, "a bar of {v} +- {s} on a car without");
            lows += usize::from(*v < 0.0);
        }
        assert!(got.params().arb_f >= 0.0 && got.params().arb_r >= 0.0);
        assert_eq!(got.params().arb_f, values[10].max(0.0));
    }
    assert!(lows > 0, "no bar estimate below 0 in 12: the test does not reach the clamp");
}

/// The half car's ten coefficients (front equation then rear, offsets 0), written from the
/// body's equations: `α_ij = 1/M + x_i x_j / J`.
fn half_exact(car: &crate::model::HalfCar<f64>) -> Vec<f64> {
    let p = car.params();
    let x = [p.l1, -p.l2];
    let (k, b) = ([p.k12, p.k22], [p.b1, p.b2]);
    let mut out = Vec::new();
    for xi in x {
        for j in 0..2 {
            let alpha = 1.0 / p.m_body + xi * x[j] / p.j;
            out.extend([alpha * k[j], alpha * b[j]]);
        }
        out.push(0.0);
    }
    out
}

#[test]
fn the_half_car_from_its_two_corners() {
    use crate::model::{HalfCar, HALF_CORNER_DETERMINED};
    use crate::sim::{HalfDrive, HalfDriveConfig};
    let car = HalfCar::<f64>::passenger();
    let p = car.params();
    // Exact coefficients, from a start with J 40 % high: exact constants.
    let start = HalfCar::new(crate::model::HalfCarParams { j: 1.4 * p.j, ..p }).unwrap();
    let cov: Vec<f64> = (0..100).map(|q| if q / 10 == q % 10 { 1e-6 } else { 0.0 }).collect();
    let (_, values, _) = start.from_corner_coefficients(&half_exact(&car), &cov, p.m_body).unwrap();
    let want = [p.j, p.k12, p.k22, p.b1, p.b2];
    for ((name, v), w) in HALF_CORNER_DETERMINED.iter().zip(values).zip(want) {
        assert!((v / w - 1.0).abs() < 1e-9, "{name}: {v} for {w}");
    }
    // A drive on class C at 15 m/s with the default realistic sensors, 300 s: the fit's ten
    // coefficients and the constants within 1 %.
    let dt = 0.005;
    let mut drive = HalfDrive::new(car, HalfDriveConfig::new(DriveConfig::new(dt).speed(15.0)), 21).unwrap();
    let mut fit = CornerFilterFit::half(dt, CORNER_BANDWIDTH, 2.0).unwrap();
    assert_eq!((fit.corners(), fit.channels()), (2, 6));
    for _ in 0..60_000 {
        fit.update(drive.next_sample().y()).unwrap();
    }
    let st = fit.stats(0.05).unwrap();
    assert_eq!(st.params.len(), 10);
    let (_, values, se) = car.from_corner_coefficients(&st.params, &st.cov, p.m_body).unwrap();
    for (((name, v), w), s) in HALF_CORNER_DETERMINED.iter().zip(values).zip(want).zip(se) {
        assert!((v / w - 1.0).abs() < 0.01 && s > 0.0, "{name}: {v} +- {s} for {w}");
    }
    assert!(matches!(fit.update(&[0.0; 12]), Err(Error::Shape { expected: 6, .. })));
}

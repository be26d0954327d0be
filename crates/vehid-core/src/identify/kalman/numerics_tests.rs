//! The exact start, the square-root form and tracking, checked against an independent least
//! squares (faer's QR on the stacked problem) and against the single-row reference filter.

use super::lanes::RowGroup;
use super::*;
use crate::identify::{Fixed, Identifier};
use crate::Error;
use nalgebra::{SMatrix, SVector};
use rand::rngs::Xoshiro256PlusPlus;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

type V4 = SVector<f64, 4>;

/// A random regression: `x` with columns scaled by `scales`, `z_i = xᵀθ_i + σ ε` for two rows,
/// `θ_ij` of size `1 / scales_j` (every column contributes alike to `z`).
fn regression(seed: u64, n: usize, scales: [f64; 4], sigma: f64) -> Vec<(V4, V4)> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
    let th1 = V4::from_fn(|j, _| g() / scales[j]);
    let th3 = V4::from_fn(|j, _| g() / scales[j]);
    (0..n)
        .map(|_| {
            let x = V4::from_fn(|j, _| g() * scales[j]);
            let mut z = V4::zeros();
            z[1] = x.dot(&th1) + sigma * g();
            z[3] = x.dot(&th3) + sigma * g();
            (x, z)
        })
        .collect()
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// Least squares by faer's QR on rows `[x_kᵀ / √r] θ = [z_k / √r]`, with the prior
/// `[I / √p0] θ = 0` appended when `p0` is given; also the residual sum of squares of the
/// data rows (unscaled).
fn lstsq(data: &[(V4, V4)], row: usize, p0: Option<f64>) -> (Vec<f64>, f64) {
    use faer::linalg::solvers::SolveLstsq;
    let l = data.len();
    let extra = if p0.is_some() { 4 } else { 0 };
    let a = faer::Mat::<f64>::from_fn(l + extra, 4, |i, j| {
        if i < l {
            data[i].0[j]
        } else if i - l == j {
            1.0 / p0.unwrap_or(1.0).sqrt()
        } else {
            0.0
        }
    });
    let b = faer::Mat::<f64>::from_fn(l + extra, 1, |i, _| if i < l { data[i].1[row] } else { 0.0 });
    let sol = a.qr().solve_lstsq(&b);
    let th: Vec<f64> = (0..4).map(|j| sol[(j, 0)]).collect();
    let ssr = data.iter().map(|(x, z)| (z[row] - (0..4).map(|j| x[j] * th[j]).sum::<f64>()).powi(2)).sum();
    (th, ssr)
}

#[test]
fn exact_start_equals_least_squares_on_every_prefix() {
    // Property test over seeded random regressions, both forms: from the first prefix that
    // identifies the four parameters on, θ̂ and the residual sum of squares equal an
    // independent least squares on that prefix.
    for seed in 0..20u64 {
        let scales = [1.0, 10.0f64.powi((seed % 5) as i32 - 2), 3.0, 0.5];
        let data = regression(seed, 60, scales, 0.3);
        for form in [CovarianceForm::Standard, CovarianceForm::Sqrt] {
            let opts = KalmanOptions { form, ..Default::default() };
            let mut id = KalmanRows::<f64, 4, Fixed<2>>::exact(&[1, 3], &[0.7, 2.0], opts).unwrap();
            let mut worst = 0.0f64;
            let mut first = None;
            for (k, (x, z)) in data.iter().enumerate() {
                let e = id.update(x, z).unwrap();
                if id.starting() {
                    assert!(e.iter().all(|v| v.is_nan()), "no innovation before an estimate exists");
                    assert!(matches!(id.params_into(&mut [0.0; 8]), Err(Error::RankDeficient { .. })));
                    continue;
                }
                first.get_or_insert(k + 1);
                for (i, row) in [1usize, 3].into_iter().enumerate() {
                    let (expect, ssr) = lstsq(&data[..=k], row, None);
                    let got: Vec<f64> = id.theta_row(i).iter().copied().collect();
                    worst = worst.max(rel_diff(&got, &expect));
                    let f = id.filter(i);
                    if k + 1 > 4 {
                        let d = (f.ssr() - ssr).abs() / ssr;
                        assert!(d < 1e-9, "seed {seed} {form:?} k {k}: ssr {} vs {ssr}", f.ssr());
                    }
                    assert_eq!(f.nobs(), (k + 1) as f64);
                }
            }
            assert_eq!(first, Some(4), "four generic samples identify four parameters");
            assert!(worst < 1e-9, "seed {seed} {form:?}: worst relative difference {worst:e}");
        }
    }
}

#[test]
fn exact_start_waits_for_a_direction_the_data_do_not_excite() {
    // x4 = 0 for the first 10 samples: no estimate until a sample moves it.
    let mut data = regression(3, 20, [1.0; 4], 0.1);
    for (x, _) in data.iter_mut().take(10) {
        x[3] = 0.0;
    }
    let mut id = KalmanRows::<f64, 4, Fixed<2>>::exact(&[1, 3], &[1.0], KalmanOptions::default()).unwrap();
    for (k, (x, z)) in data.iter().enumerate() {
        id.update(x, z).unwrap();
        assert_eq!(id.starting(), k < 10, "sample {k}");
        if k == 9 {
            assert!(matches!(id.params_into(&mut [0.0; 8]), Err(Error::RankDeficient { rank: 3, needed: 4 })));
        }
    }
    let (expect, _) = lstsq(&data, 1, None);
    assert!(rel_diff(id.theta_row(0).as_slice(), &expect) < 1e-9);
}

#[test]
fn square_root_form_equals_regularized_least_squares_for_any_prior_and_scaling() {
    // θ̂ = argmin Σ (z − xᵀθ)²/r + |θ|²/p0, for p0 from 1e-3 to 1e12 and columns scaled from
    // 1e-6 to 1e6 (condition of X about 1e12): the square-root form stays within 1e-7.
    let scales = [1e-6, 1e-2, 1e2, 1e6];
    let data = regression(11, 400, scales, 1e-3);
    for p0 in [1e-3, 1.0, 1e6, 1e12] {
        let opts = KalmanOptions { form: CovarianceForm::Sqrt, ..Default::default() };
        let mut id = KalmanRows::<f64, 4, Fixed<2>>::from_slices(&[1, 3], &[p0], &[1.0], opts).unwrap();
        for (x, z) in &data {
            id.update(x, z).unwrap();
        }
        for (i, row) in [1usize, 3].into_iter().enumerate() {
            let (expect, _) = lstsq(&data, row, Some(p0));
            let got = id.theta_row(i);
            // The parameters span twelve orders of magnitude: compare each one's contribution
            // to z (θ_j times its column's scale), relative to the largest.
            let scaled = |t: &[f64]| (0..4).map(|j| t[j] * scales[j]).collect::<Vec<_>>();
            let d = rel_diff(&scaled(got.as_slice()), &scaled(&expect));
            assert!(d < 1e-7, "p0 {p0:e} row {row}: {got:?} vs {expect:?} ({d:e})");
        }
    }
}

#[test]
fn square_root_form_keeps_f32_positive_definite_where_the_standard_form_fails() {
    // f32, p0 = 1e12, columns scaled 1e-3 … 1e3: D stays positive and θ finite for the
    // square-root form; the standard form's P loses definiteness on the same data.
    let data = regression(5, 20_000, [1e-3, 1.0, 1.0, 1e3], 1e-2);
    let to32 = |v: &V4| SVector::<f32, 4>::from_fn(|j, _| v[j] as f32);
    let opts = KalmanOptions { form: CovarianceForm::Sqrt, ..Default::default() };
    let mut sq = KalmanRows::<f32, 4, Fixed<2>>::from_slices(&[1, 3], &[1e12], &[1e-4], opts).unwrap();
    let mut std_form =
        KalmanRows::<f32, 4, Fixed<2>>::from_slices(&[1, 3], &[1e12], &[1e-4], Default::default()).unwrap();
    let mut std_failed = false;
    for (x, z) in &data {
        sq.update(&to32(x), &to32(z)).unwrap();
        std_failed |= std_form.update(&to32(x), &to32(z)).is_err()
            || (0..2).any(|i| {
                let p = std_form.filter(i).p();
                let mut l = p;
                !crate::linalg::cholesky_in_place(l.as_mut_slice(), 4)
            });
    }
    for i in 0..2 {
        let m = sq.filter(i).m;
        assert!((0..4).all(|j| m[(j, j)] > 0.0), "D > 0");
        assert!(sq.theta_row(i).iter().all(|v| v.is_finite()));
    }
    assert!(std_failed, "the standard form should lose definiteness here (else this test shows nothing)");
}

#[test]
fn lanes_equal_the_reference_row_filter_in_every_form_with_tracking() {
    // The vectorized lanes (rows side by side) and the single-row reference compute the same
    // recursion; sums are ordered differently, so equal to rounding.
    let data = regression(8, 3000, [1.0, 2.0, 0.5, 1.0], 0.2);
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        for (lambda, q, directional) in
            [(1.0, 0.0, false), (0.995, 0.0, false), (0.995, 0.0, true), (1.0, 1e-6, false), (0.99, 1e-5, true)]
        {
            let opts = KalmanOptions {
                form,
                forgetting: lambda,
                directional,
                drift: q,
                max_trace: 50.0,
                ..Default::default()
            };
            let mut lanes = KalmanRows::<f64, 4, Fixed<2>>::from_slices(&[1, 3], &[10.0], &[0.3, 0.5], opts).unwrap();
            let mut refs =
                [0.3, 0.5].map(|r| RowIdentifier::<f64, 4>::new(10.0, r).unwrap().configured(form, &opts).unwrap());
            for (x, z) in &data {
                lanes.update(x, z).unwrap();
                refs[0].update(x, z[1]).unwrap();
                refs[1].update(x, z[3]).unwrap();
            }
            for (i, f) in refs.iter().enumerate() {
                let l = lanes.filter(i);
                let d = rel_diff(l.theta().as_slice(), f.theta().as_slice());
                assert!(d < 1e-10, "{form:?} λ {lambda} q {q}: θ differs by {d:e}");
                let d = rel_diff(l.p().as_slice(), f.p().as_slice());
                assert!(d < 1e-8, "{form:?} λ {lambda} q {q}: P differs by {d:e}");
                assert!((l.ssr() - f.ssr()).abs() <= 1e-9 * f.ssr(), "{form:?}: ssr");
            }
        }
    }
}

#[test]
fn forgetting_tracks_a_step_and_does_not_wind_up_without_excitation() {
    // θ steps by 20 % at k = 5000; with λ = 0.995 (memory ≈ 200 samples) the estimate is
    // within 2 % of the new value after a few hundred samples. Then 10⁶ samples of x = 0
    // (parked: no excitation) leave θ unchanged and tr P below the bound.
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(21);
    let th = V4::new(-140.0, -40.0, 50.0, 40.0);
    let opts = KalmanOptions { form: CovarianceForm::Sqrt, forgetting: 0.995, ..Default::default() };
    let mut id = KalmanRows::<f64, 4, Fixed<1>>::exact(&[1], &[1.0], opts).unwrap();
    let mut within = None;
    for k in 0..8000 {
        let truth = if k < 5000 { th } else { th * 1.2 };
        let x = V4::from_fn(|_, _| StandardNormal.sample(&mut rng));
        let noise: f64 = StandardNormal.sample(&mut rng);
        let z = V4::new(0.0, x.dot(&truth) + noise, 0.0, 0.0);
        id.update(&x, &z).unwrap();
        let err = (id.theta_row(0) - truth).abs().max() / truth.abs().max();
        if k >= 5000 && within.is_none() && err < 0.02 {
            within = Some(k - 5000);
        }
    }
    let settled = within.expect("tracks the step");
    eprintln!("exponential forgetting λ = 0.995: within 2 % of a 20 % step after {settled} samples");
    assert!(settled < 600, "within 2 % after {settled} samples");
    // Parked: 10⁶ samples without excitation (x = 0, a noisy z). Exponential forgetting lets
    // tr P grow back to the bound (the trace when filtering started) and no further;
    // directional forgetting keeps P exactly; with drift P grows to the bound. θ never moves.
    let before = id.filter(0);
    let cap = before.cap;
    assert!(cap > 0.0 && cap > before.trace());
    let parked = |opts: KalmanOptions<f64>| {
        let mut p = KalmanRows::<f64, 4, Fixed<1>>::from_filters(&[1], &[before], opts).unwrap();
        for k in 0..1_000_000 {
            let z = V4::new(0.0, 0.3 * ((k % 7) as f64 - 3.0), 0.0, 0.0);
            p.update(&V4::zeros(), &z).unwrap();
        }
        assert_eq!(p.theta_row(0), before.theta(), "no excitation: the estimate does not move");
        p.filter(0)
    };
    let sqrt = KalmanOptions { form: CovarianceForm::Sqrt, forgetting: 0.995, max_trace: cap, ..Default::default() };
    let exp = parked(sqrt).trace();
    assert!(exp < cap / 0.995 * 1.000001 && exp >= cap, "exponential: tr P {} → {exp}, bound {cap}", before.trace());
    let dir = parked(KalmanOptions { directional: true, ..sqrt }).p();
    assert_eq!(dir, before.p(), "directional: nothing is forgotten without excitation");
    let drift = parked(KalmanOptions { drift: 1e-4, ..sqrt }).trace();
    assert!(drift < cap / 0.995 + 4e-4 && drift >= cap, "drift: tr P → {drift}, bound {cap}");
}

#[test]
fn the_outlier_gate_does_not_stop_tracking_a_lasting_change() {
    // The same 20 % step with the gate on (κ = 6, Python's default): the residuals after the
    // step are all beyond the gate; without the Winsorized scale (guards::gated_scale) they
    // stayed gated and the step took 1356 (lanes) / 844 (row) samples, with it 432 / 418.
    // Lanes and the reference row filter alike.
    for form in [CovarianceForm::Standard, CovarianceForm::Sqrt] {
        let opts = KalmanOptions { form, forgetting: 0.995, gate: 6.0, ..Default::default() };
        let mut lanes = KalmanRows::<f64, 4, Fixed<1>>::exact(&[1], &[1.0], opts).unwrap();
        let mut row = RowIdentifier::<f64, 4>::exact(1.0).unwrap().configured(form, &opts).unwrap();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(22);
        let th = V4::new(-140.0, -40.0, 50.0, 40.0);
        let (mut within_lanes, mut within_row) = (None, None);
        for k in 0..8000 {
            let truth = if k < 5000 { th } else { th * 1.2 };
            let x = V4::from_fn(|_, _| StandardNormal.sample(&mut rng));
            let noise: f64 = StandardNormal.sample(&mut rng);
            let y = x.dot(&truth) + 0.3 * noise;
            lanes.update(&x, &V4::new(0.0, y, 0.0, 0.0)).unwrap();
            row.update(&x, y).unwrap();
            let err = |t: &V4| (t - truth).abs().max() / truth.abs().max();
            if k >= 5000 && within_lanes.is_none() && err(&lanes.theta_row(0)) < 0.02 {
                within_lanes = Some(k - 5000);
            }
            if k >= 5000 && within_row.is_none() && err(&row.theta()) < 0.02 {
                within_row = Some(k - 5000);
            }
        }
        let (a, b) = (within_lanes.expect("lanes track"), within_row.expect("row tracks"));
        eprintln!("{form:?}, gate 6: within 2 % of a 20 % step after {a} (lanes) / {b} (row) samples");
        assert!(a < 600 && b < 600, "{form:?}: {a} / {b} samples");
        assert!(lanes.filter(0).gated() > 0, "the step's first residuals were gated");
    }
}

#[test]
fn rejected_samples_change_nothing_in_the_new_forms() {
    let data = regression(2, 50, [1.0; 4], 0.1);
    for form in [CovarianceForm::Standard, CovarianceForm::Sqrt] {
        let opts = KalmanOptions { form, forgetting: 0.99, drift: 1e-6, ..Default::default() };
        for exact in [true, false] {
            let mut id = if exact {
                KalmanRows::<f64, 4, Fixed<2>>::exact(&[1, 3], &[1.0], opts).unwrap()
            } else {
                KalmanRows::<f64, 4, Fixed<2>>::from_slices(&[1, 3], &[100.0], &[1.0], opts).unwrap()
            };
            for (k, (x, z)) in data.iter().enumerate() {
                let before = (0..2).map(|i| id.filter(i)).collect::<Vec<_>>();
                let mut bad = *x;
                bad[k % 4] = if k % 2 == 0 { f64::NAN } else { 1e300 };
                let res = id.update(&bad, z);
                if res.is_err() {
                    let after = (0..2).map(|i| id.filter(i)).collect::<Vec<_>>();
                    assert_eq!(before, after, "{form:?} exact {exact} sample {k}: a rejected sample changed the state");
                }
                id.update(x, z).unwrap();
            }
        }
    }
}

#[test]
fn ud_factors_round_trip() {
    let a = SMatrix::<f64, 4, 4>::new(4.0, 1.0, 0.5, 0.2, 1.0, 3.0, 0.1, 0.3, 0.5, 0.1, 2.0, 0.4, 0.2, 0.3, 0.4, 1.5);
    let ud = super::ud::ud_factor(&a, 4).unwrap();
    let back = super::ud::ud_product(&ud);
    assert!((back - a).abs().max() < 1e-14);
    assert!((super::ud::ud_trace(&ud) - a.trace()).abs() < 1e-14);
    let mut up = ud;
    let v = SVector::<f64, 4>::new(0.3, -1.0, 2.0, 0.5);
    super::ud::ud_rank_one(&mut up, 0.7, v);
    assert!((super::ud::ud_product(&up) - (a + v * v.transpose() * 0.7)).abs().max() < 1e-13);
    let _ = <super::lanes::RowLanes<f64, 4, 2> as RowGroup<f64, 4>>::LANES;
}

/// ξ (Eq 3.17) of the quarter car's rows after `n` road-noise samples, with `z[1]` of one in
/// every 10⁴ samples replaced by `outlier(z)`, for the given options.
fn xi_with_outliers(seed: u64, n: usize, outlier: impl Fn(f64) -> f64, opts: KalmanOptions<f64>) -> (f64, u64) {
    use crate::model::QuarterCar;
    use crate::sim::{SimConfig, Simulator};
    let car = QuarterCar::<f64>::thesis();
    let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(car.model(), cfg, seed).unwrap();
    let r: [f64; 2] = car.model().row_noise_var(0.1, 0.005).unwrap();
    let mut id = KalmanRows::<f64, 4, Fixed<2>>::from_slices(&car.unknown_rows(), &[1000.0], &r, opts).unwrap();
    for k in 0..n {
        let s = sim.next_sample();
        let mut z = s.z;
        if k % 10_000 == 5_000 {
            z[1] = outlier(z[1]);
        }
        id.update(&s.r, &z).unwrap();
    }
    let mut gated = [0u64; 2];
    id.gated_into(&mut gated).unwrap();
    let t = car.theta().transpose();
    (crate::metrics::xi(t.as_slice(), id.theta().transpose().as_slice()).unwrap(), gated[0] + gated[1])
}

#[test]
fn the_gate_keeps_outliers_out_of_the_estimate() {
    // One outlier in 10⁴ samples, of 1e30 and of 1e3 times the signal: with the gate the
    // estimate is within 10 % (in ξ) of the clean run's; without, 1e30 ruins it for good.
    let gate = KalmanOptions { gate: 6.0, ..Default::default() };
    for seed in [31u64, 32] {
        let (clean, g0) = xi_with_outliers(seed, 40_000, |z| z, gate);
        for outlier in [|_z: f64| 1e30, |z: f64| z * 1e3] {
            let (gated, count) = xi_with_outliers(seed, 40_000, outlier, gate);
            assert!((gated - clean).abs() < 0.1 * clean, "seed {seed}: ξ {clean} → {gated}");
            assert!(count >= 4 && count <= g0 + 4, "the four outliers are gated ({count}; clean run {g0})");
        }
        let (ruined, _) = xi_with_outliers(seed, 40_000, |_| 1e30, KalmanOptions::default());
        assert!(ruined > 1e6, "without the gate one outlier ruins the estimate (ξ {ruined})");
    }
}

#[test]
fn huber_weighting_resists_heavy_tailed_noise() {
    // Student-t noise with 2 degrees of freedom (infinite variance): over 8 seeds, the
    // Huber-weighted estimate is on average clearly closer to the truth than plain least
    // squares on the same data, in both forms; lanes and reference agree.
    let th = V4::new(-140.0, -40.0, 50.0, 40.0);
    let run = |seed: u64, opts: KalmanOptions<f64>| {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut id = KalmanRows::<f64, 4, Fixed<1>>::exact(&[1], &[1.0], opts).unwrap();
        let mut reference = RowIdentifier::<f64, 4>::exact(1.0).unwrap().configured(opts.form, &opts).unwrap();
        for _ in 0..5_000 {
            let x = V4::from_fn(|_, _| StandardNormal.sample(&mut rng));
            let g: f64 = StandardNormal.sample(&mut rng);
            let chi: f64 = (0..2).map(|_| StandardNormal.sample(&mut rng)).map(|v: f64| v * v).sum();
            let z = V4::new(0.0, x.dot(&th) + g / (chi / 2.0).sqrt(), 0.0, 0.0);
            id.update(&x, &z).unwrap();
            reference.update(&x, z[1]).unwrap();
        }
        let d = rel_diff(id.theta_row(0).as_slice(), reference.theta().as_slice());
        assert!(d < 1e-9, "lanes and reference agree ({d:e})");
        (id.theta_row(0) - th).norm()
    };
    for form in [CovarianceForm::Standard, CovarianceForm::Sqrt] {
        let (mut plain, mut robust) = (0.0, 0.0);
        for seed in 40..48 {
            plain += run(seed, KalmanOptions { form, ..Default::default() });
            robust += run(seed, KalmanOptions { form, huber: 1.345, ..Default::default() });
        }
        assert!(robust < 0.7 * plain, "{form:?}: Huber {robust} vs least squares {plain}");
    }
}

#[test]
fn the_standard_form_refuses_a_sample_that_would_break_positive_definiteness() {
    // A consistent sample scaled by 1e10 (r unchanged): the standard form's downdate would
    // leave P indefinite; it is refused with advice, the identifier unchanged. The
    // square-root form takes it.
    use crate::model::QuarterCar;
    use crate::sim::{SimConfig, Simulator};
    let car = QuarterCar::<f64>::thesis();
    let mut sim = Simulator::new(car.model(), SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005), 4).unwrap();
    let r: [f64; 2] = car.model().row_noise_var(0.1, 0.005).unwrap();
    let mut std_form = KalmanRows::<f64, 4, Fixed<2>>::from_slices(&[1, 3], &[1000.0], &r, Default::default()).unwrap();
    let sq = KalmanOptions { form: CovarianceForm::Sqrt, ..Default::default() };
    let mut sqrt_form = KalmanRows::<f64, 4, Fixed<2>>::from_slices(&[1, 3], &[1000.0], &r, sq).unwrap();
    for _ in 0..2000 {
        let s = sim.next_sample();
        std_form.update(&s.r, &s.z).unwrap();
        sqrt_form.update(&s.r, &s.z).unwrap();
    }
    let s = sim.next_sample();
    let (x, z) = (s.r * 1e10, s.z * 1e10);
    let before = (std_form.filter(0), std_form.filter(1));
    match std_form.update(&x, &z) {
        Err(Error::Singular { what }) => assert!(what.contains("form='sqrt'"), "{what}"),
        Ok(_) => {
            // Accepted only if the result stayed positive definite.
            for i in 0..2 {
                assert!(super::guards::positive_definite(&std_form.filter(i).p(), 4));
            }
        }
        Err(e) => panic!("{e}"),
    }
    if std_form.filter(0) != before.0 {
        assert!(super::guards::positive_definite(&std_form.filter(0).p(), 4));
    }
    sqrt_form.update(&x, &z).unwrap();
    for i in 0..2 {
        // The factors stay positive (the product P may not factor numerically: its condition
        // is now about 1e20, which is why P is kept factored).
        let m = sqrt_form.filter(i).m;
        assert!((0..4).all(|j| m[(j, j)] > 0.0), "D > 0");
    }
}

#[test]
fn batch_least_squares_names_a_dominating_outlier_and_can_remove_it() {
    use crate::identify::BatchLeastSquares;
    let data = regression(12, 100, [1.0; 4], 0.1);
    let mut ls = BatchLeastSquares::<f64, 4>::new(&[1, 3]).unwrap();
    for (x, z) in &data[..60] {
        ls.push(x, z).unwrap();
    }
    let (mut x, z) = data[60];
    x[0] = 1e20;
    ls.push(&x, &z).unwrap();
    for (x, z) in &data[61..] {
        ls.push(x, z).unwrap();
    }
    assert_eq!(ls.solve(), Err(Error::Dominated { sample: 60 }));
    ls.remove(60).unwrap();
    let mut clean = BatchLeastSquares::<f64, 4>::new(&[1, 3]).unwrap();
    for (i, (x, z)) in data.iter().enumerate() {
        if i != 60 {
            clean.push(x, z).unwrap();
        }
    }
    assert_eq!(ls.solve().unwrap(), clean.solve().unwrap());
    assert!(ls.remove(1000).is_err());
}

/// ξ and the gated count (row 0's) of `id` on the quarter car's run of
/// [`xi_with_outliers`], through the [`Identifier`] interface.
fn xi_of<I: Identifier<f64>>(mut id: I, seed: u64, n: usize, outlier: impl Fn(f64) -> f64) -> (f64, u64) {
    use crate::model::QuarterCar;
    use crate::sim::{SimConfig, Simulator};
    let car = QuarterCar::<f64>::thesis();
    let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(car.model(), cfg, seed).unwrap();
    let mut e = [0.0; 2];
    for k in 0..n {
        let s = sim.next_sample();
        let mut z = s.z;
        if k % 10_000 == 5_000 {
            z[1] = outlier(z[1]);
        }
        id.update_into(s.r.as_slice(), z.as_slice(), &[], &mut e).unwrap();
    }
    let mut gated = [0u64; 2];
    id.gated_into(&mut gated).unwrap();
    assert_eq!(gated[0], gated[1], "a gated sample is left out by every row");
    let mut theta = [0.0; 8];
    id.params_into(&mut theta).unwrap();
    let t = car.theta().transpose();
    (crate::metrics::xi(t.as_slice(), &theta).unwrap(), gated[0])
}

#[test]
fn modes_shared_and_full_gate_outliers_as_rows_does() {
    // The same one-in-10⁴ outliers (1e30, 1e3 times the signal) as
    // `the_gate_keeps_outliers_out_of_the_estimate`, in modes shared and full.
    use crate::model::QuarterCar;
    let car = QuarterCar::<f64>::thesis();
    let rows = car.unknown_rows();
    let r: [f64; 2] = car.model().row_noise_var(0.1, 0.005).unwrap();
    let gate = KalmanOptions { gate: 6.0, ..Default::default() };
    let shared = |opts| KalmanShared::<f64, 4, Fixed<2>>::from_slices(&rows, &[1000.0], &[1.0], opts).unwrap();
    let full = |opts| KalmanFull::<f64, 4, Fixed<2>>::from_slices(&rows, &[1000.0], &r, opts).unwrap();
    for seed in [31u64, 32] {
        let runs = [
            (
                "shared",
                xi_of(shared(gate), seed, 40_000, |z| z),
                xi_of(shared(gate), seed, 40_000, |_| 1e30),
                xi_of(shared(KalmanOptions::default()), seed, 40_000, |_| 1e30),
            ),
            (
                "full",
                xi_of(full(gate), seed, 40_000, |z| z),
                xi_of(full(gate), seed, 40_000, |z| z * 1e3),
                xi_of(full(KalmanOptions::default()), seed, 40_000, |_| 1e30),
            ),
        ];
        for (mode, (clean, g0), (gated, count), (ruined, _)) in runs {
            assert!((gated - clean).abs() < 0.1 * clean, "{mode} seed {seed}: ξ {clean} → {gated}");
            assert!(count >= 4 && count <= g0 + 4, "{mode}: the four outliers are gated ({count}; clean {g0})");
            assert!(ruined > 1e3, "{mode}: without the gate one outlier ruins the estimate (ξ {ruined})");
        }
    }
}

#[test]
fn an_overflow_through_z_names_z_k_in_every_mode() {
    // A derivative of 1.7e308 used to be reported as `r_k` in modes shared and full.
    let x = V4::new(0.01, -0.02, 0.03, 0.01);
    let mut z = V4::zeros();
    z[1] = 1.7e308;
    let opts = KalmanOptions::default();
    let mut shared = KalmanShared::<f64, 4, Fixed<2>>::from_slices(&[1, 3], &[1000.0], &[1.0], opts).unwrap();
    let mut full = KalmanFull::<f64, 4, Fixed<2>>::from_slices(&[1, 3], &[1000.0], &[1.0], opts).unwrap();
    let mut row = RowIdentifier::<f64, 4>::new(1000.0, 1.0).unwrap();
    let (before_s, before_f, before_r) = (shared.clone().theta(), full.clone().theta(), row);
    for res in [shared.update(&x, &z).map(|_| ()), full.update(&x, &z).map(|_| ()), row.update(&x, z[1]).map(|_| ())] {
        assert!(matches!(res, Err(Error::InvalidArgument { arg: "z_k", .. })), "{res:?}");
    }
    assert_eq!((shared.theta(), full.theta(), row), (before_s, before_f, before_r));
    assert_eq!((shared.samples(), full.samples()), (0, 0));
}

/// Covariance resetting: after `reset_covariance(p0)` every mode and form continues exactly as
/// a fresh filter built with the prior mean `θ̂` and `P(0) = p0 I` (the constructors' path,
/// an independent route to the same filter); a refused reset changes nothing.
#[test]
fn reset_covariance_continues_as_a_fresh_filter_from_the_estimate() {
    let data = regression(7, 400, [1.0, 10.0, 0.1, 1.0], 0.05);
    let (before, after) = data.split_at(150);
    let no_gate = |form| KalmanOptions { form, gate: 0.0, ..Default::default() };
    let cases = [
        (Mode::Rows, CovarianceForm::Standard),
        (Mode::Rows, CovarianceForm::Joseph),
        (Mode::Rows, CovarianceForm::Sqrt),
        (Mode::Shared, CovarianceForm::Standard),
        (Mode::Full, CovarianceForm::Standard),
    ];
    for (mode, form) in cases {
        let spec = |p0: f64, theta0: Option<Vec<f64>>| KalmanSpec {
            rows: vec![1, 3],
            p0: Prior::PerRow(vec![p0]),
            theta0,
            r: vec![0.05 * 0.05],
            mode,
            opts: no_gate(form),
        };
        let mut id = boxed_kalman::<f64, 4>(&spec(1e3, None)).unwrap();
        let mut e = [0.0; 2];
        for (x, z) in before {
            id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        }
        let mut theta = vec![0.0; 8];
        id.params_into(&mut theta).unwrap();
        // Refused: nothing changes.
        let copy = format!("{id:?}");
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(id.reset_covariance(bad), Err(Error::InvalidArgument { arg: "p0", .. })), "{mode:?}");
            assert_eq!(format!("{id:?}"), copy, "{mode:?} {form:?}: a refused reset changed the identifier");
        }
        id.reset_covariance(50.0).unwrap();
        let mut p = vec![0.0; 64];
        id.covariance_into(&mut p).unwrap();
        let want: Vec<f64> = (0..64).map(|ij| if ij / 8 == ij % 8 { 50.0 } else { 0.0 }).collect();
        assert!(rel_diff(&p, &want) < 1e-15, "{mode:?} {form:?}: P after the reset {p:?}");
        let mut kept = vec![0.0; 8];
        id.params_into(&mut kept).unwrap();
        assert_eq!(kept, theta, "{mode:?} {form:?}: the reset moved θ̂");
        let mut fresh = boxed_kalman::<f64, 4>(&spec(50.0, Some(theta))).unwrap();
        for (x, z) in after {
            id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
            fresh.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        }
        let (mut a, mut b) = (vec![0.0; 8], vec![0.0; 8]);
        id.params_into(&mut a).unwrap();
        fresh.params_into(&mut b).unwrap();
        assert!(rel_diff(&a, &b) < 1e-12, "{mode:?} {form:?}: {a:?} vs a fresh filter {b:?}");
    }
    // During the exact start there is no estimate to keep: refused, unchanged.
    let mut id = KalmanRows::<f64, 4, Fixed<2>>::exact(&[1, 3], &[1.0], KalmanOptions::default()).unwrap();
    id.update(&data[0].0, &data[0].1).unwrap();
    let copy = (0..2).map(|i| id.filter(i)).collect::<Vec<_>>();
    assert!(matches!(id.reset_covariance(1.0), Err(Error::Unsupported { .. })));
    assert_eq!((0..2).map(|i| id.filter(i)).collect::<Vec<_>>(), copy);
}

/// Three rows of a random regression (`z_0, z_1, z_3`), Gaussian noise of `σ = 0.2`, and
/// every 37th sample's rows displaced by 40 σ (`z_1` up, `z_3` down): outliers for the gate
/// and the Huber weights to act on.
fn regression_with_outliers(seed: u64, n: usize) -> Vec<(V4, V4)> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
    let th = [V4::from_fn(|_, _| g()), V4::from_fn(|_, _| g()), V4::from_fn(|_, _| g())];
    (0..n)
        .map(|k| {
            let x = V4::from_fn(|j, _| g() * [1.0, 2.0, 0.5, 1.0][j]);
            let mut z = V4::zeros();
            for (t, row) in th.iter().zip([0, 1, 3]) {
                z[row] = x.dot(t) + 0.2 * g();
            }
            if k % 37 == 36 {
                z[1] += 8.0;
                z[3] -= 8.0;
            }
            (x, z)
        })
        .collect()
}

/// The options of the sweeps: a form, tracking `(λ, q, directional, max_trace)` and screens
/// `(gate, huber)`.
pub(super) fn sweep_options(
    form: CovarianceForm,
    (forgetting, drift, directional, max_trace): (f64, f64, bool, f64),
    (gate, huber): (f64, f64),
) -> KalmanOptions<f64> {
    KalmanOptions { form, forgetting, directional, drift, max_trace, gate, huber, ..Default::default() }
}

#[test]
fn lanes_equal_the_reference_row_filter_with_every_option() {
    // The lanes (three rows: a group of two and one with a padding lane) against the
    // single-row reference, over every form, the tracking options (exponential and directional
    // forgetting, drift, both, the automatic and a given trace bound), the screens (gate,
    // Huber, both, neither) and both starts (prior and exact), on data with outliers: the
    // estimates, covariances, residual statistics and gated counts agree to rounding, so an
    // option that one of the two applies differently, or in one form only, shows.
    let data = regression_with_outliers(41, 1500);
    let rows = [0usize, 1, 3];
    let r = [0.04, 0.05, 0.03];
    let forms = [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt];
    let tracking = [
        (1.0, 0.0, false, 0.0),
        (0.995, 0.0, false, 0.0),
        (0.99, 0.0, true, 0.0),
        (1.0, 1e-5, false, 40.0),
        (0.995, 1e-6, true, 40.0),
    ];
    let screens = [(0.0, 0.0), (4.0, 0.0), (0.0, 1.345), (4.0, 2.0)];
    let mut gated_somewhere = false;
    for form in forms {
        for (lambda, q, directional, cap) in tracking {
            for (gate, huber) in screens {
                for exact in [false, true] {
                    let opts = sweep_options(form, (lambda, q, directional, cap), (gate, huber));
                    let what = format!(
                        "{form:?} λ {lambda} q {q} dir {directional} cap {cap} gate {gate} huber {huber} exact {exact}"
                    );
                    let mut lanes = if exact {
                        KalmanRows::<f64, 4, Fixed<3>>::exact(&rows, &r, opts)
                    } else {
                        KalmanRows::<f64, 4, Fixed<3>>::from_slices(&rows, &[10.0], &r, opts)
                    }
                    .unwrap();
                    let mut refs = r.map(|ri| {
                        let f = if exact { RowIdentifier::<f64, 4>::exact(ri) } else { RowIdentifier::new(10.0, ri) };
                        f.unwrap().configured(form, &opts).unwrap()
                    });
                    for (k, (x, z)) in data.iter().enumerate() {
                        lanes.update(x, z).unwrap();
                        for (f, &row) in refs.iter_mut().zip(&rows) {
                            f.update(x, z[row]).unwrap();
                        }
                        if k == 2 {
                            // The exact start is still absorbing: both say so alike.
                            for (i, f) in refs.iter().enumerate() {
                                assert_eq!(lanes.filter(i).starting(), f.starting(), "{what}");
                                assert_eq!(lanes.filter(i).start_rank(), f.start_rank(), "{what}");
                            }
                        }
                    }
                    assert_eq!(lanes.samples(), data.len() as u64, "{what}");
                    for (i, f) in refs.iter().enumerate() {
                        let l = lanes.filter(i);
                        let d = rel_diff(l.theta().as_slice(), f.theta().as_slice());
                        assert!(d < 1e-9, "{what}, row {i}: θ differs by {d:e}");
                        let d = rel_diff(l.p().as_slice(), f.p().as_slice());
                        assert!(d < 1e-7, "{what}, row {i}: P differs by {d:e}");
                        assert!((l.trace() - f.trace()).abs() <= 1e-7 * f.trace(), "{what}, row {i}: trace");
                        assert!((l.ssr() - f.ssr()).abs() <= 1e-8 * f.ssr(), "{what}, row {i}: ssr");
                        assert!((l.nobs() - f.nobs()).abs() <= 1e-9 * f.nobs(), "{what}, row {i}: nobs");
                        let (a, b) = (l.innovation_var(), f.innovation_var());
                        assert!((a - b).abs() <= 1e-7 * b.abs(), "{what}, row {i}: innovation variance {a} vs {b}");
                        assert_eq!(l.gated(), f.gated(), "{what}, row {i}: gated");
                        assert_eq!(l.forgetting(), f.forgetting(), "{what}, row {i}");
                        assert_eq!(l.form(), form, "{what}, row {i}");
                        gated_somewhere |= l.gated() > 0;
                        if gate > 0.0 && i > 0 {
                            assert!(l.gated() > 0, "{what}, row {i}: the outliers are gated");
                        }
                    }
                    let sum: f64 = refs.iter().map(|f| f.trace()).sum();
                    assert!((lanes.trace() - sum).abs() <= 1e-7 * sum, "{what}: tr P = Σ tr P_i");
                }
            }
        }
    }
    assert!(gated_somewhere);
}

/// A noise-free row (`r = 0`) whose regressors have zero leading entries: in the square-root
/// form the UD update's `α` stays 0 over those columns (the columns are skipped, then the
/// first informative one starts from `α = 0`).
/// Every form gives the posterior of the prior `θ ~ N(0, p0 I)` conditioned exactly on
/// `Xθ = z`: the minimum-norm solution `θ = Xᵀ(XXᵀ)⁻¹z` and `P = p0 (I − Xᵀ(XXᵀ)⁻¹X)`,
/// computed here, after each of three samples. A retired row then predicts without moving,
/// and a covariance reset makes it update again.
#[test]
fn noise_free_rows_with_leading_zeros_condition_the_prior_exactly() {
    let p0 = 10.0;
    // After the first sample D₀ = 0 and U₀₁ = −1 (P = p0 (I − x xᵀ/2) on the first two
    // states): the second sample's f₀ = x₀ = 0 leaves α = 0 over column 0, and column 1
    // starts from α = 0 with U₀₁ ≠ 0, which reaches column 2 through b₀.
    let xs = [[1.0, 1.0, 0.0, 0.0], [0.0, 1.0, 1.0, 0.0], [0.0, 0.0, 1.0, 2.0]];
    let truth = SVector::<f64, 4>::new(0.7, -1.3, 2.1, 0.4);
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        let opts = KalmanOptions { form, ..Default::default() };
        let mut row = RowIdentifier::<f64, 4>::new(p0, 0.0).unwrap().configured(form, &opts).unwrap();
        for k in 0..xs.len() {
            let x = SVector::<f64, 4>::from(xs[k]);
            row.update(&x, x.dot(&truth)).unwrap();
            let xm = SMatrix::<f64, 4, 4>::from_fn(|i, j| if i <= k { xs[i][j] } else { 0.0 });
            let xk = xm.rows(0, k + 1);
            let gram = (xk * xk.transpose()).try_inverse().unwrap();
            let proj = xk.transpose() * gram * xk;
            let theta = proj * truth;
            let p = (SMatrix::<f64, 4, 4>::identity() - proj) * p0;
            assert!((row.theta() - theta).amax() < 1e-12, "{form:?} sample {k}: {} vs {theta}", row.theta());
            assert!((row.p() - p).amax() < 1e-12 * p0, "{form:?} sample {k}: {} vs {p}", row.p());
        }
        let (theta, p) = (row.theta(), row.p());
        row.retire();
        let x = SVector::<f64, 4>::new(0.2, 0.4, -0.6, 1.0);
        let e = row.update(&x, 5.0).unwrap();
        assert_eq!(e, 5.0 - theta.dot(&x), "{form:?}: a retired row's innovation");
        assert_eq!((row.theta(), row.p()), (theta, p), "{form:?}: a retired row does not move");
        row.reset_covariance(p0).unwrap();
        row.update(&x, 5.0).unwrap();
        assert!((row.theta().dot(&x) - 5.0).abs() < 1e-9, "{form:?}: updates again after the reset");
    }
}

/// The square-root form updates `U` in place, so a sample whose update would overflow `U`
/// must be refused before it starts (`plan_ud`'s bound `|U'_ij| ≤ |U_ij| + |b_i| |p_j|`,
/// `|b_i| ≤ (1 + N max|U|) max|v|`). Two such samples, each with `α` and the step finite:
/// - `P(0) = diag(1e300, 1e-10, 1, 1)`, `r = 1e-300`, `x = (1e-300, 1e10, 0, 0)`:
///   `α₀ = r + p₀₀ x₀² = 2e-300` and `p₁ = −x₁/α₀` overflows;
/// - `P(0) = diag(1e300, 1e-300, 1, 1)`, `r = 1`, `x = (1e-100, 1e300, 0, 0)`: every `p` and
///   `v` finite (`v₀ = 1e200`, `p₁ = −1e200`) but `b₀ p₁` overflows;
/// - `P(0)` with `P₀₀ = 1.5e308`, `P₀₁ = 1e154`, `P₁₁ = 1`, `P₂₂ = 1e-200`, `P₃₃ = 1` (so
///   `U₀₁ = 1e154`), `r = 1`, `x = (0, 1, 1e155, 0)`: `max|v| max|p| = 1e155`, but
///   `b₀ = U₀₁ v₁ = 1e154` and `b₀ p₂` overflows (the bound's `max|U|`).
///
/// Refused with an overflow error, every filter unchanged (the single-row filter, which plans
/// on a copy, likewise), in lanes of one row and of several.
#[test]
fn a_square_root_update_that_would_overflow_u_is_refused_before_it_starts() {
    let diag = |d: [f64; 4]| SMatrix::<f64, 4, 4>::from_diagonal(&SVector::<f64, 4>::from(d));
    let mut coupled = diag([1.5e308, 1.0, 1e-200, 1.0]);
    (coupled[(0, 1)], coupled[(1, 0)]) = (1e154, 1e154);
    let cases = [
        (diag([1e300, 1e-10, 1.0, 1.0]), 1e-300, [1e-300, 1e10, 0.0]),
        (diag([1e300, 1e-300, 1.0, 1.0]), 1.0, [1e-100, 1e300, 0.0]),
        (coupled, 1.0, [0.0, 1.0, 1e155]),
    ];
    for (p0, r, x01) in cases {
        let opts = KalmanOptions { form: CovarianceForm::Sqrt, ..Default::default() };
        let row = RowIdentifier::with_prior(SVector::zeros(), p0, r)
            .unwrap()
            .configured(CovarianceForm::Sqrt, &opts)
            .unwrap();
        let x = SVector::<f64, 4>::new(x01[0], x01[1], x01[2], 0.0);
        let mut single = row;
        assert_eq!(single.update(&x, 0.0), Err(crate::identify::OVERFLOW), "x = {x01:?}");
        assert_eq!(single, row, "x = {x01:?}: the single-row filter changed");
        for k in [1usize, 3] {
            let rows: Vec<usize> = [1usize, 3, 0][..k].to_vec();
            let filters = vec![row; k];
            let mut id = KalmanRows::<f64, 4, crate::identify::Dynamic>::from_filters(&rows, &filters, opts).unwrap();
            let before = id.clone();
            let z = SVector::<f64, 4>::zeros();
            let err = id.update_into(x.as_slice(), z.as_slice(), &[], &mut vec![0.0; k]);
            assert_eq!(err, Err(crate::identify::OVERFLOW), "x = {x01:?}, {k} rows");
            for i in 0..k {
                assert_eq!(id.filter(i), before.filter(i), "x = {x01:?}, {k} rows: row {i} changed");
            }
        }
    }
}

/// The Joseph form of the single-row filter (what every identifier on a `Structure` runs per
/// group) on the same kind of sample: a consistent quarter-car sample scaled by 1e12 after
/// 2,000 samples (`r ≪ √ε s`), whose update leaves `P` indefinite in rounding (here; at
/// 1e10 it does not). Refused naming the square-root form, the filter unchanged; or, if
/// taken, `P` positive definite.
#[test]
fn the_joseph_form_refuses_a_sample_that_would_break_positive_definiteness() {
    use crate::model::QuarterCar;
    use crate::sim::{SimConfig, Simulator};
    let car = QuarterCar::<f64>::thesis();
    let mut sim = Simulator::new(car.model(), SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005), 4).unwrap();
    let r: [f64; 2] = car.model().row_noise_var(0.1, 0.005).unwrap();
    let opts = KalmanOptions { form: CovarianceForm::Joseph, ..Default::default() };
    let mut row =
        RowIdentifier::<f64, 4>::new(1000.0, r[0]).unwrap().configured(CovarianceForm::Joseph, &opts).unwrap();
    for _ in 0..2000 {
        let s = sim.next_sample();
        row.update(&s.r, s.z[1]).unwrap();
    }
    let s = sim.next_sample();
    let before = row;
    let res = row.update(&(s.r * 1e12), s.z[1] * 1e12);
    match res {
        Err(Error::Singular { what }) => {
            assert!(what.contains("form='sqrt'"), "{what}");
            assert_eq!(row, before, "a refused sample changed the filter");
        }
        Ok(_) => assert!(super::guards::positive_definite(&row.p(), 4), "taken, and P is not positive definite"),
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn an_exact_start_whose_covariance_would_underflow_is_refused_not_wrong() {
    // The same regression scaled by s: θ̂ does not depend on s, P = r R⁻¹R⁻ᵀ scales as 1/s².
    // At s = 1e150 P ≈ 1e-300 is still a normal float and the estimate is least squares'; at
    // s = 1e155 it underflows, and the sample that would finish the start is refused with
    // the scale error, the identifier unchanged (before: ξ 6 with no error), in both forms and
    // in the lanes (mode "rows").
    let data = regression(7, 40, [1.0, 2.0, 3.0, 0.5], 0.3);
    for form in [CovarianceForm::Standard, CovarianceForm::Sqrt] {
        let opts = KalmanOptions { form, ..Default::default() };
        let (expect, _) = lstsq(&data, 1, None);
        for (s, ok) in [(1e150, true), (1e155, false)] {
            let mut id = KalmanRows::<f64, 4, Fixed<2>>::exact(&[1, 3], &[0.7, 2.0], opts).unwrap();
            let mut refused = None;
            for (k, (x, z)) in data.iter().enumerate() {
                match id.update(&(x * s), &(z * s)) {
                    Ok(_) => {}
                    Err(e) => {
                        assert_eq!(e, row::exact::SCALE, "{form:?} s {s:e}");
                        assert!(id.starting(), "refused while starting, and still starting");
                        refused.get_or_insert(k);
                    }
                }
            }
            if ok {
                assert!(refused.is_none() && !id.starting());
                let got: Vec<f64> = id.theta_row(0).iter().copied().collect();
                assert!(rel_diff(&got, &expect) < 1e-9, "{form:?}: {got:?} vs {expect:?}");
            } else {
                assert_eq!(refused, Some(3), "{form:?}: the fourth sample would finish the start");
            }
        }
    }
}

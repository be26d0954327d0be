use super::lanes::RowGroup;
use super::*;
use crate::identify::*;
use crate::identify::{BatchLeastSquares, Gain, LsAccumulator, StochasticGradient};
use crate::metrics::xi;
use crate::model::{HalfCar, QuarterCar};
use crate::sim::{SimConfig, Simulator};
use crate::Error;
use nalgebra::{SMatrix, SVector};
use nalgebra::{Vector4, Vector6};

type V4 = SVector<f64, 4>;

fn quarter_samples(seed: u64, n: usize, cfg: SimConfig<f64, 4, 1>) -> Vec<(V4, V4)> {
    let mut sim = Simulator::new(QuarterCar::thesis().model(), cfg, seed).unwrap();
    (0..n).map(|_| sim.next_sample()).map(|s| (s.r, s.z)).collect()
}

fn road(seed: u64, n: usize) -> Vec<(V4, V4)> {
    quarter_samples(seed, n, SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005))
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// θ̂ from faer's QR on the least-squares problem with the prior as extra rows:
/// `[x_kᵀ/√r; I/√p0] θ = [z_k/√r; 0]` (independent of every code path of the filter).
fn ls_with_prior(data: &[(V4, V4)], row: usize, p0: f64, r: f64) -> Vec<f64> {
    use faer::linalg::solvers::SolveLstsq;
    let l = data.len();
    let a = faer::Mat::<f64>::from_fn(l + 4, 4, |i, j| {
        if i < l {
            data[i].0[j] / r.sqrt()
        } else if i - l == j {
            1.0 / p0.sqrt()
        } else {
            0.0
        }
    });
    let b = faer::Mat::<f64>::from_fn(l + 4, 1, |i, _| if i < l { data[i].1[row] / r.sqrt() } else { 0.0 });
    let sol = a.qr().solve_lstsq(&b);
    (0..4).map(|j| sol[(j, 0)]).collect()
}

#[test]
fn recursive_filter_equals_least_squares_with_prior_rows() {
    let data = road(1, 3000);
    let model = QuarterCar::<f64>::thesis().model();
    let r: [f64; 2] = model.row_noise_var(0.1, 0.005).unwrap();
    let mut id = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r).unwrap();
    for (x, z) in &data {
        id.update(x, z).unwrap();
    }
    for (i, row) in [1usize, 3].iter().enumerate() {
        let expect = ls_with_prior(&data, *row, 1000.0, r[i]);
        let got: Vec<f64> = id.theta().row(i).iter().copied().collect();
        let d = rel_diff(&got, &expect);
        assert!(d < 1e-9, "row {row}: relative difference {d:e}");
    }
}

#[test]
fn rows_shared_and_full_agree_where_the_algebra_says_so() {
    let data = road(2, 4000);
    // Equal r/p0 on both rows: shared = rows. Diagonal R, block-diagonal P(0): full = rows.
    let r = [0.3, 0.3];
    let opts = KalmanOptions::default();
    let mut rows = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r).unwrap();
    let mut shared = SharedKalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r).unwrap();
    let mut full =
        FullKalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[1000.0], &[0.3, 0.0, 0.0, 0.3], opts).unwrap();
    for (x, z) in &data {
        let a = rows.update(x, z).unwrap();
        let b = shared.update(x, z).unwrap();
        let c = full.update(x, z).unwrap();
        assert!((a - b).abs().max() <= 1e-10 * a.abs().max().max(1.0));
        assert!((a - c).abs().max() <= 1e-10 * a.abs().max().max(1.0));
    }
    let t = rows.theta();
    let scale = t.abs().max();
    assert!((t - shared.theta()).abs().max() < 1e-10 * scale);
    assert!((t - full.theta()).abs().max() < 1e-10 * scale);
    // Covariances agree too, and the full filter's off-diagonal blocks stay zero.
    for i in 0..2 {
        let f = rows.filter(i);
        let p = f.p();
        assert!((p - shared.p(i)).abs().max() < 1e-10 * p.abs().max());
        assert!((p - full.p_block(i, i)).abs().max() < 1e-10 * p.abs().max());
    }
    assert!(full.p_block(0, 1).abs().max() == 0.0);
    // Different r per row (the thesis' R) in rows mode = full mode with that diagonal R.
    let model = QuarterCar::<f64>::thesis().model();
    let r: [f64; 2] = model.row_noise_var(0.1, 0.005).unwrap();
    let mut rows = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r).unwrap();
    let mut full =
        FullKalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[1000.0], &[r[0], 0.0, 0.0, r[1]], opts).unwrap();
    for (x, z) in &data {
        rows.update(x, z).unwrap();
        full.update(x, z).unwrap();
    }
    for i in 0..2 {
        let a = rows.theta().row(i).clone_owned();
        let b = full.theta().row(i).clone_owned();
        assert!((a - b).abs().max() < 1e-10 * a.abs().max(), "row {i}");
    }
    // Shared refuses unequal ratios.
    assert!(SharedKalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r).is_err());
}

#[test]
fn full_filter_with_correlated_r_equals_generalized_least_squares() {
    // Instrumentation-style correlated errors: R = [[a, c], [c, b]]. Closed form:
    // (R⁻¹ ⊗ Σ x xᵀ + I/p0) θ = Σ (R⁻¹ ⊗ x) z, solved by faer's LU on the 8 × 8 system.
    use faer::linalg::solvers::Solve;
    let data = road(3, 2000);
    let (ra, rb, rc, p0) = (0.5, 0.2, 0.15, 100.0);
    let mut full =
        FullKalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[p0], &[ra, rc, rc, rb], KalmanOptions::default())
            .unwrap();
    for (x, z) in &data {
        full.update(x, z).unwrap();
    }
    let det = ra * rb - rc * rc;
    let ri = [[rb / det, -rc / det], [-rc / det, ra / det]];
    let rows = [1usize, 3];
    let mut a = faer::Mat::<f64>::zeros(8, 8);
    let mut b = faer::Mat::<f64>::zeros(8, 1);
    for (x, z) in &data {
        for i in 0..2 {
            for j in 0..2 {
                for p in 0..4 {
                    for q in 0..4 {
                        a[(i * 4 + p, j * 4 + q)] += ri[i][j] * x[p] * x[q];
                    }
                    b[(i * 4 + p, 0)] += ri[i][j] * x[p] * z[rows[j]];
                }
            }
        }
    }
    for d in 0..8 {
        a[(d, d)] += 1.0 / p0;
    }
    let sol = a.partial_piv_lu().solve(&b);
    let expect: Vec<f64> = (0..8).map(|i| sol[(i, 0)]).collect();
    let mut got = vec![0.0; 8];
    full.theta_into(&mut got).unwrap();
    assert!(rel_diff(&got, &expect) < 1e-9, "{:e}", rel_diff(&got, &expect));
}

#[test]
fn noise_free_initial_condition_excitation_is_exact() {
    // Eq 2.8: n linearly independent noise-free samples determine θ.
    let car = QuarterCar::<f64>::thesis();
    let data = quarter_samples(4, 60, SimConfig::new(0.05).ic_sigma(0.1));
    let mut ls = BatchLeastSquares::<f64, 4>::new(&car.unknown_rows()).unwrap();
    for (x, z) in data.iter().take(4) {
        ls.push(x, z).unwrap();
    }
    let theta = ls.solve().unwrap();
    let truth = car.theta().transpose();
    assert!(rel_diff(&theta, truth.as_slice()) < 1e-9);
    // The memory-bounded accumulator agrees.
    let mut acc = LsAccumulator::<f64, 4, Fixed<2>>::new([1, 3]).unwrap();
    for (x, z) in data.iter().take(4) {
        acc.push(x, z).unwrap();
    }
    assert!((acc.solve().unwrap() - car.theta()).abs().max() < 1e-7 * 140.0);
    // Kalman identifier with r = 0 (no noise): ξ < 1e-8.
    let mut kf = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, [0.0, 0.0]).unwrap();
    for (x, z) in &data {
        kf.update(x, z).unwrap();
    }
    let th = kf.theta();
    let xi_v = xi(car.theta().transpose().as_slice(), th.transpose().as_slice()).unwrap();
    assert!(xi_v < 1e-8, "ξ = {xi_v:e}");
}

#[test]
fn too_few_samples_is_rank_deficient_not_nan() {
    let car = QuarterCar::<f64>::thesis();
    let data = quarter_samples(4, 3, SimConfig::new(0.05).ic_sigma(0.1));
    let mut ls = BatchLeastSquares::<f64, 4>::new(&car.unknown_rows()).unwrap();
    for (x, z) in &data {
        ls.push(x, z).unwrap();
    }
    assert!(matches!(ls.solve(), Err(Error::RankDeficient { rank: 3, needed: 4 })));
    // A direction never excited: the same state repeated.
    let mut ls = BatchLeastSquares::<f64, 4>::new(&[1]).unwrap();
    for _ in 0..10 {
        ls.push(&data[0].0, &data[0].1).unwrap();
    }
    assert!(matches!(ls.solve(), Err(Error::RankDeficient { rank: 1, .. })));
    let mut acc = LsAccumulator::<f64, 4, Fixed<1>>::new([1]).unwrap();
    for _ in 0..10 {
        acc.push(&data[0].0, &data[0].1).unwrap();
    }
    assert!(matches!(acc.solve(), Err(Error::RankDeficient { .. })));
}

#[test]
fn rejected_samples_leave_the_identifier_unchanged() {
    let data = road(5, 50);
    let mut id = KalmanIdentifier::<f64, 4, 2>::from_slices(
        &[1, 3],
        &[1000.0],
        &[81.0, 2.5e-5],
        KalmanOptions { reinit: true, ..Default::default() },
    )
    .unwrap();
    let mut sg = StochasticGradient::<f64, 4, 2>::new([1, 3], Gain::Venter { p: 0.51 }, 0.4).unwrap();
    let mut full =
        FullKalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, nalgebra::Matrix2::new(81.0, 0.0, 0.0, 2.5e-5)).unwrap();
    for (x, z) in &data {
        id.update(x, z).unwrap();
        sg.update(x, z).unwrap();
        full.update(x, z).unwrap();
    }
    let (before, sg_before, full_before) = (id.clone(), sg.clone(), full.clone());
    let (x, z) = data[0];
    let mut bad_x = x;
    bad_x[2] = f64::NAN;
    let mut bad_z = z;
    bad_z[3] = f64::INFINITY;
    let huge = Vector4::repeat(1e300);
    assert!(matches!(id.update(&bad_x, &z), Err(Error::NonFinite { arg: "r_k", index: 2 })));
    assert!(matches!(id.update(&x, &bad_z), Err(Error::NonFinite { arg: "z_k", index: 3 })));
    assert!(id.update(&huge, &huge).is_err());
    assert!(sg.update(&bad_x, &z).is_err() && sg.update(&huge, &huge).is_err());
    assert!(full.update(&x, &bad_z).is_err() && full.update(&huge, &huge).is_err());
    assert_eq!(id.theta(), before.theta());
    assert!((0..2).all(|i| id.filter(i) == before.filter(i)), "θ, P, r and retirement unchanged");
    assert_eq!((id.samples(), id.reinit_count()), (before.samples(), before.reinit_count()));
    assert_eq!(sg.theta(), sg_before.theta());
    assert_eq!(sg.samples(), sg_before.samples());
    assert_eq!(full.theta(), full_before.theta());
    for (i, j) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
        assert_eq!(full.p_block(i, j), full_before.p_block(i, j), "P block ({i}, {j}) unchanged");
    }
    assert_eq!((full.samples(), full.reinit_count()), (full_before.samples(), full_before.reinit_count()));
    // Everything else, in every identifier kind and form: tests/claims.rs.
}

#[test]
fn bad_settings_are_clear_errors() {
    type K = KalmanIdentifier<f64, 4, 2>;
    assert!(matches!(K::new([1, 3], 0.0, [1.0, 1.0]), Err(Error::InvalidArgument { arg: "p0", .. })));
    assert!(matches!(K::new([1, 3], f64::NAN, [1.0, 1.0]), Err(Error::InvalidArgument { arg: "p0", .. })));
    assert!(matches!(K::new([1, 3], 1.0, [-1.0, 1.0]), Err(Error::InvalidArgument { arg: "r", .. })));
    assert!(matches!(K::new([1, 4], 1.0, [1.0, 1.0]), Err(Error::BadRow { row: 4, .. })));
    assert!(matches!(K::new([3, 3], 1.0, [1.0, 1.0]), Err(Error::BadRow { row: 3, .. })));
    assert!(matches!(
        K::from_slices(&[1, 3], &[1.0, 2.0, 3.0], &[1.0], KalmanOptions::default()),
        Err(Error::Shape { arg: "p0", expected: 2, got: 3 })
    ));
    assert!(matches!(
        K::from_slices(&[1], &[1.0], &[1.0], KalmanOptions::default()),
        Err(Error::Shape { arg: "unknown_rows", expected: 2, got: 1 })
    ));
    type G = StochasticGradient<f64, 4, 2>;
    for p in [0.5, 1.01, f64::NAN] {
        assert!(matches!(G::new([1, 3], Gain::Venter { p }, 1.0), Err(Error::InvalidArgument { arg: "p", .. })));
    }
    assert!(matches!(G::new([1, 3], Gain::Venter { p: 1.0 }, 0.0), Err(Error::InvalidArgument { arg: "h", .. })));
    assert!(matches!(
        G::new([1, 3], Gain::Ljung { lambda0: 1.5, lambda_init: 0.95 }, 1.0),
        Err(Error::InvalidArgument { arg: "lambda0", .. })
    ));
    assert!(matches!(
        G::from_slices(&[1, 3], Gain::Lyapunov, &[1.0, 2.0, 3.0], &[0.0], 1),
        Err(Error::Shape { arg: "h", expected: 8, got: 3 })
    ));
    assert!(matches!(
        G::from_slices(&[1, 3], Gain::Lyapunov, &[1.0], &[0.0], 0),
        Err(Error::InvalidArgument { arg: "spacing", .. })
    ));
    let not_spd = SMatrix::<f64, 4, 4>::from_diagonal(&Vector4::new(1.0, 1.0, -1.0, 1.0));
    assert!(matches!(RowIdentifier::with_prior(V4::zeros(), not_spd, 1.0), Err(Error::Singular { .. })));
}

#[test]
fn memory_fits_the_thesis_budget() {
    // Table I: 352 bytes (4-state), 2800 bytes (8-state, decoupled).
    eprintln!(
        "sizes: {} {} {} {} {} {}",
        core::mem::size_of::<KalmanIdentifier<f32, 4, 2>>(),
        core::mem::size_of::<KalmanIdentifier<f32, 8, 4>>(),
        core::mem::size_of::<SharedKalmanIdentifier<f32, 4, 2>>(),
        core::mem::size_of::<SharedKalmanIdentifier<f32, 8, 4>>(),
        core::mem::size_of::<StochasticGradient<f32, 4, 2>>(),
        core::mem::size_of::<KalmanIdentifier<f64, 4, 2>>(),
    );
    let q = core::mem::size_of::<KalmanIdentifier<f32, 4, 2>>();
    let h = core::mem::size_of::<KalmanIdentifier<f32, 8, 4>>();
    assert!(q <= 352, "{q}");
    assert!(h <= 2800, "{h}");
    assert_eq!(q, 336, "update the figure in the module docs");
    assert_eq!(h, 1432, "update the figure in the module docs");
    assert_eq!(core::mem::size_of::<SharedKalmanIdentifier<f32, 4, 2>>(), 184);
    assert_eq!(core::mem::size_of::<SharedKalmanIdentifier<f32, 8, 4>>(), 504);
    assert_eq!(core::mem::size_of::<StochasticGradient<f32, 4, 2>>(), 192);
}

#[test]
fn cost_reports_size_and_arithmetic() {
    let q = KalmanIdentifier::<f32, 4, 2>::new([1, 3], 1000.0, [1.0, 1.0]).unwrap();
    let c = q.cost();
    assert_eq!(c.bytes, core::mem::size_of::<KalmanIdentifier<f32, 4, 2>>());
    // Independent count for N = 4, K = 2, per row: P x 16 mul 12 add; xᵀPx + r, xᵀθ and
    // z − xᵀθ 8 mul 8 add; c = e/s 1 mul; g = Px/s 4 mul; θ += c Px 4 mul 4 add; the upper
    // triangle of P −= Px gᵀ 10 mul 10 add: 43 mul, 34 add, one division, no square root.
    assert_eq!((c.multiplications, c.additions, c.divisions, c.square_roots), (86, 68, 2, 0));
    let v = KalmanIdentifierVec::<f32, 4>::from_slices(&[1, 3], &[1000.0], &[1.0], KalmanOptions::default()).unwrap();
    assert!(v.cost().bytes > core::mem::size_of_val(&v), "heap rows are counted");
    assert_eq!(v.cost().flops(), c.flops());
    let s = SharedKalmanIdentifier::<f32, 4, 2>::new([1, 3], 1000.0, [1.0, 1.0]).unwrap();
    assert!(s.cost().flops() < c.flops(), "shared is the cheapest form");
}

#[test]
fn f32_long_run_keeps_covariance_positive_definite() {
    let car = QuarterCar::<f32>::thesis();
    let cfg = SimConfig::<f32, 4, 1>::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(car.model(), cfg, 6).unwrap();
    let r: [f32; 2] = car.model().row_noise_var(0.1, 0.005).unwrap();
    let mut id = KalmanIdentifier::<f32, 4, 2>::new([1, 3], 1000.0, r).unwrap();
    for _ in 0..1_000_000 {
        let s = sim.next_sample();
        id.update(&s.r, &s.z).unwrap();
    }
    for f in (0..2).map(|i| id.filter(i)) {
        // The lanes store one triangle of P and `p()` mirrors it: its symmetry would be a
        // tautology here (the forms that store whole matrices are checked in tests/claims.rs).
        let p = f.p();
        let mut l = p;
        assert!(crate::linalg::cholesky_in_place(l.as_mut_slice(), 4), "positive definite: {p}");
        assert!(f.theta().iter().all(|v| v.is_finite()));
    }
    let th = id.theta();
    let xi_v = xi(car.theta().transpose().as_slice(), th.transpose().as_slice()).unwrap();
    assert!(xi_v < 0.08, "f32 over 10⁶ samples converges: ξ = {xi_v}");
}

#[test]
fn half_car_prior_regimes() {
    // thesis-notes §8: after 20,000 road-noise samples the smallest eigenvalue of Σ x xᵀ is
    // about 5e-3, so r/p0 decides whether the prior or the data wins in that direction. The
    // LS-with-prior solution shrinks the estimate along an eigenvector v with eigenvalue λ by
    // λ / (λ + r/p0) (from exact data): ≈ 1 when r/p0 ≪ λ (data win), ≈ 0 when r/p0 ≫ λ.
    let half = HalfCar::<f64>::thesis();
    let model = half.model();
    let cfg = SimConfig::<f64, 8, 2>::new(0.05).road_sigma(0.1);
    let mut sim = Simulator::new(model.clone(), cfg, 7).unwrap();
    let data: Vec<_> = (0..20_000).map(|_| sim.next_sample()).collect();
    let mut gram = SMatrix::<f64, 8, 8>::zeros();
    for s in &data {
        gram += s.x * s.x.transpose();
    }
    let eig = gram.symmetric_eigen();
    let (imin, lmin) =
        eig.eigenvalues.iter().enumerate().fold((0, f64::MAX), |b, (i, &l)| if l < b.1 { (i, l) } else { b });
    assert!(lmin > 1e-4 && lmin < 1e-1, "smallest eigenvalue {lmin:e}");
    let v = eig.eigenvectors.column(imin).clone_owned();
    // Body row (index 2 of the unknown rows, A row 5) carries no road input: r = σ_v² only.
    let truth = half.theta().row(2).transpose();
    let along = |ratio: f64| {
        let mut id = KalmanIdentifier::<f64, 8, 4>::new([1, 3, 5, 7], 1.0, [ratio; 4]).unwrap();
        for s in &data {
            id.update(&s.x, &s.xdot).unwrap(); // exact data: only the prior biases
        }
        id.theta().row(2).transpose().dot(&v) / truth.dot(&v)
    };
    let data_wins = along(lmin * 1e-3);
    let prior_wins = along(lmin * 1e3);
    let predicted = |ratio: f64| lmin / (lmin + ratio);
    if truth.dot(&v).abs() > 1e-3 * truth.norm() {
        assert!((data_wins - predicted(lmin * 1e-3)).abs() < 1e-3, "{data_wins}");
        assert!((prior_wins - predicted(lmin * 1e3)).abs() < 1e-3, "{prior_wins}");
    }
    assert!(data_wins > 0.99 && prior_wins < 0.01, "data {data_wins}, prior {prior_wins}");
}

#[test]
fn joseph_form_matches_standard_form() {
    let data = road(8, 2000);
    let mut a = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, [0.5, 0.01]).unwrap();
    let mut b = KalmanIdentifier::<f64, 4, 2>::from_slices(
        &[1, 3],
        &[1000.0],
        &[0.5, 0.01],
        KalmanOptions { form: CovarianceForm::Joseph, ..Default::default() },
    )
    .unwrap();
    for (x, z) in &data {
        a.update(x, z).unwrap();
        b.update(x, z).unwrap();
    }
    assert!((a.theta() - b.theta()).abs().max() < 1e-8 * a.theta().abs().max());
}

#[test]
fn retired_rows_stop_and_reinit_brings_them_back() {
    let data = road(9, 3000);
    let mut id = KalmanIdentifier::<f64, 4, 2>::from_slices(
        &[1, 3],
        &[1000.0],
        &[81.0, 2.5e-5],
        KalmanOptions { retire_below: 1e-2, ..Default::default() },
    )
    .unwrap();
    for (x, z) in &data {
        id.update(x, z).unwrap();
    }
    eprintln!("traces after 3000: {} {}", id.filter(0).p().trace(), id.filter(1).p().trace());
    assert!(id.filter(1).retired(), "the body row (r = 2.5e-5) retires");
    assert!(!id.filter(0).retired(), "the wheel row (r = 81) is still learning");
    let (frozen, wheel_before) = (id.filter(1), id.filter(0));
    for (x, z) in data.iter().take(100) {
        id.update(x, z).unwrap();
    }
    assert_eq!(id.filter(1), frozen, "a retired row's θ, P and r do not move");
    assert_ne!(id.filter(0), wheel_before, "while the active row goes on");
    id.groups.flat_mut()[0].reinitialize();
    assert!(!id.filter(1).retired());
    assert_eq!(id.filter(1).r(), 2.0 * frozen.r());
    assert_eq!(id.filter(1).p()[(0, 0)], 10.0 * frozen.p()[(0, 0)]);
}

#[test]
fn dynamic_storage_equals_fixed_storage() {
    let data = road(10, 500);
    let mut fixed = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, [81.0, 2.5e-5]).unwrap();
    let mut dynamic =
        KalmanIdentifierVec::<f64, 4>::from_slices(&[1, 3], &[1000.0], &[81.0, 2.5e-5], KalmanOptions::default())
            .unwrap();
    let mut e = [0.0; 2];
    for (x, z) in &data {
        let ef = fixed.update(x, z).unwrap();
        dynamic.update_vec(x, z, &mut e).unwrap();
        assert_eq!(ef.as_slice(), &e);
    }
    let mut out = [0.0; 8];
    dynamic.theta_into(&mut out).unwrap();
    assert_eq!(fixed.theta().transpose().as_slice(), &out);
    // Any K works in the dynamic form: one unknown row of a 6-state model equals Fixed<1>.
    let a = SMatrix::<f64, 6, 6>::from_fn(|i, j| {
        if i == j {
            -1.0 - i as f64
        } else if j == i + 1 {
            0.5
        } else {
            0.0
        }
    });
    let model = crate::model::LinearModel::new(a, Vector6::repeat(1.0), &[2]).unwrap();
    let mut sim = Simulator::new(model, SimConfig::new(0.05).road_sigma(0.3), 1).unwrap();
    let mut one =
        KalmanIdentifierVec::<f64, 6>::from_slices(&[2], &[100.0], &[0.09], KalmanOptions::default()).unwrap();
    let mut fixed_one = KalmanIdentifier::<f64, 6, 1>::new([2], 100.0, [0.09]).unwrap();
    let mut e = [0.0];
    for _ in 0..2000 {
        let s = sim.next_sample();
        one.update_vec(&s.r, &s.z, &mut e).unwrap();
        assert_eq!(fixed_one.update(&s.r, &s.z).unwrap()[0], e[0]);
    }
    assert_eq!(one.theta_row(0), fixed_one.theta().row(0).transpose());
}

#[test]
fn several_lane_groups_equal_one_and_reject_as_a_whole() {
    // Six unknown rows of the half car: Fixed<6> keeps them in one group of six lanes, the
    // Dynamic store in groups of DYNAMIC_LANES (planned into its scratch, then applied). Also
    // with the gate and the reinitialization (a gated outlier on row 7, in the last group,
    // reinitializes nothing), in the standard and the square-root form.
    let car = HalfCar::<f64>::thesis();
    let cfg = SimConfig::<f64, 8, 2>::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
    let rows = [0, 1, 3, 5, 6, 7];
    let r = [0.01, 100.0, 100.0, 2.5e-3, 0.02, 2.5e-3];
    let gated = KalmanOptions { gate: 4.0, reinit: true, ..Default::default() };
    for opts in [KalmanOptions::default(), gated, KalmanOptions { form: CovarianceForm::Sqrt, ..gated }] {
        let mut sim = Simulator::new(car.model(), cfg.clone(), 3).unwrap();
        let mut fixed = KalmanRows::<f64, 8, Fixed<6>>::from_slices(&rows, &[1000.0], &r, opts).unwrap();
        let mut dynamic = KalmanIdentifierVec::<f64, 8>::from_slices(&rows, &[1000.0], &r, opts).unwrap();
        let mut pairs = KalmanIdentifierVec2::<f64, 8>::from_slices(&rows, &[1000.0], &r, opts).unwrap();
        assert!(dynamic.groups.len() > 1 && dynamic.scratch.len() == dynamic.groups.len(), "several groups");
        assert_eq!(pairs.groups.len(), 3, "three groups of two lanes");
        let (mut ef, mut e, mut e2) = ([0.0; 6], [0.0; 6], [0.0; 6]);
        let mut last = None;
        for k in 0..3000 {
            let mut s = sim.next_sample();
            if k % 97 == 96 {
                s.z[7] += 1e5; // an outlier the gate leaves out, large enough to reinitialize
            }
            fixed.update_vec(&s.r, &s.z, &mut ef).unwrap();
            dynamic.update_vec(&s.r, &s.z, &mut e).unwrap();
            pairs.update_vec(&s.r, &s.z, &mut e2).unwrap();
            assert_eq!(ef, e, "{opts:?}, sample {k}");
            assert_eq!(e, e2, "{opts:?}, sample {k}");
            assert_eq!(fixed.reinit_count(), dynamic.reinit_count(), "{opts:?}, sample {k}");
            assert_eq!(fixed.reinit_count(), pairs.reinit_count(), "{opts:?}, sample {k}");
            last = Some(s);
        }
        assert!((0..6).all(|i| pairs.filter(i) == fixed.filter(i)), "two-lane groups: the same bits");
        let mut a = [0.0; 48];
        dynamic.theta_into(&mut a).unwrap();
        let mut b = [0.0; 48];
        fixed.theta_into(&mut b).unwrap();
        assert_eq!(a, b);
        if opts.gate > 0.0 {
            assert!(fixed.filter(5).gated() >= 20, "{opts:?}: the outliers are gated ({})", fixed.filter(5).gated());
        }
        // A sample that only the last group rejects (its row's derivative is NaN) changes no group.
        let s = last.unwrap();
        let mut z = s.z;
        z[7] = f64::NAN;
        let before: Vec<_> = (0..6).map(|i| dynamic.filter(i)).collect();
        assert!(matches!(dynamic.update_vec(&s.r, &z, &mut e), Err(Error::NonFinite { arg: "z_k", index: 7 })));
        assert!((0..6).all(|i| dynamic.filter(i) == before[i]));
        assert_eq!(dynamic.samples(), 3000);
    }
}

#[test]
fn batch_least_squares_names_a_full_rank_dominating_sample() {
    // One sample of 1e10 (far beyond the others) keeps the regression full rank
    // but decides a direction alone: named, not solved silently wrong; removed, it solves.
    let car = crate::model::QuarterCar::<f64>::thesis();
    let cfg = crate::sim::SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    let mut sim = crate::sim::Simulator::new(car.model(), cfg, 5).unwrap();
    let mut ls = BatchLeastSquares::<f64, 4>::new(&car.unknown_rows()).unwrap();
    for k in 0..2000 {
        let s = sim.next_sample();
        let x = if k == 7 { Vector4::repeat(1e10) } else { s.r };
        ls.push(&x, &s.z).unwrap();
    }
    assert!(ls.leverage(7) > 0.999, "{}", ls.leverage(7));
    assert!(matches!(ls.solve(), Err(Error::Dominated { sample: 7 })));
    ls.remove(7).unwrap();
    assert!(ls.solve().is_ok() && ls.leverage(1500) < 0.05, "{}", ls.leverage(1500));
}

#[test]
fn batch_least_squares_among_zero_samples_is_not_dominated() {
    // A vehicle parked for 100 samples (state 0), then four excited samples that alone identify
    // the row: a sample among mostly zero ones is not an outlier for being larger (the median
    // norm is 0), so the batch solves, to the exact row; with the larger samples excited too,
    // a 1e10 one is named as before.
    let theta = Vector4::new(-90.0, -40.0, 50.0, 40.0);
    let mut ls = BatchLeastSquares::<f64, 4>::new(&[1]).unwrap();
    let zero = Vector4::zeros();
    for _ in 0..100 {
        ls.push(&zero, &zero).unwrap();
    }
    for x in [
        Vector4::new(1.0, 0.2, 0.0, 0.1),
        Vector4::new(0.0, 1.0, 0.3, 0.0),
        Vector4::new(0.1, 0.0, 1.0, 0.4),
        Vector4::new(0.0, 0.5, 0.0, 1.0),
    ] {
        ls.push(&x, &Vector4::new(0.0, theta.dot(&x), 0.0, 0.0)).unwrap();
    }
    assert_eq!(ls.dominating_sample(), Some(103));
    let got = ls.solve().unwrap();
    for j in 0..4 {
        assert!((got[j] - theta[j]).abs() <= 1e-12 * theta[j].abs(), "{got:?}");
    }
}

/// Every read-out of the `Identifier` interface of `a` and `b`, compared: the same sizes,
/// rows, counts and gated samples exactly; the estimates, covariances, noise, residual
/// statistics and trace to `tol` relative to each quantity's largest entry.
fn assert_same_identifier(a: &dyn DynIdentifier<f64>, b: &dyn DynIdentifier<f64>, tol: f64, what: &str) {
    let d = a.dims();
    assert_eq!(d, b.dims(), "{what}: dims");
    assert_eq!(a.rows(), b.rows(), "{what}: rows");
    assert_eq!(a.samples(), b.samples(), "{what}: samples");
    assert_eq!(a.reinit_count(), b.reinit_count(), "{what}: reinitializations");
    let close = |x: &[f64], y: &[f64], name: &str| {
        let scale = y.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
        let diff = x.iter().zip(y).fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
        assert!(diff <= tol * scale, "{what}: {name} differs by {:e} of its scale", diff / scale);
    };
    let (p, k) = (d.params, d.equations);
    let read = |id: &dyn DynIdentifier<f64>| {
        let mut theta = vec![0.0; p];
        id.params_into(&mut theta).unwrap();
        let mut cov = vec![0.0; p * p];
        id.covariance_into(&mut cov).unwrap();
        let mut noise = vec![0.0; k * k];
        id.noise_into(&mut noise).unwrap();
        let (mut ssr, mut nobs) = (vec![0.0; k], vec![0.0; k]);
        // Modes shared and full keep no residual statistics for the interface.
        let stats = id.residuals_into(&mut ssr, &mut nobs).is_ok();
        let mut gated = vec![0u64; k];
        id.gated_into(&mut gated).unwrap();
        let (mut gp, mut ge) = (vec![0usize; p], vec![0usize; k]);
        id.groups_into(&mut gp, &mut ge).unwrap();
        (theta, cov, noise, stats.then_some((ssr, nobs)), gated, gp, ge, id.trace().unwrap())
    };
    let (ra, rb) = (read(a), read(b));
    close(&ra.0, &rb.0, "θ");
    close(&ra.1, &rb.1, "P");
    close(&ra.2, &rb.2, "R");
    if let (Some(sa), Some(sb)) = (&ra.3, &rb.3) {
        close(&sa.0, &sb.0, "ssr");
        close(&sa.1, &sb.1, "nobs");
    }
    assert_eq!(ra.4, rb.4, "{what}: gated");
    assert_eq!((ra.5, ra.6), (rb.5, rb.6), "{what}: groups");
    close(&[ra.7], &[rb.7], "tr P");
}

/// A random regression on three rows (`z_0, z_1, z_3` of a 4-state `x`), noise σ = 0.2, with
/// an outlier of 45 σ on `z_1` every 53 samples and a jump of `z_0`, `z_3` at sample 600;
/// and a prior mean (12 values) to start from.
fn three_rows_with_outliers(seed: u64, n: usize) -> (Vec<(V4, V4)>, Vec<f64>) {
    use rand::SeedableRng;
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut g = || -> f64 { rand_distr::Distribution::sample(&rand_distr::StandardNormal, &mut rng) };
    let th = [V4::from_fn(|_, _| g()), V4::from_fn(|_, _| g()), V4::from_fn(|_, _| g())];
    let theta_prior: Vec<f64> = (0..12).map(|_| 0.3 * g()).collect();
    let data = (0..n)
        .map(|k| {
            let x = V4::from_fn(|j, _| g() * [1.0, 2.0, 0.5, 1.0][j]);
            let mut z = V4::zeros();
            for (t, row) in th.iter().zip([0, 1, 3]) {
                z[row] = x.dot(t) + 0.2 * g();
            }
            if k % 53 == 52 {
                z[1] += 9.0; // an outlier for the gate; a jump for the reinitialization
            }
            if k == 600 {
                z[0] += 400.0;
                z[3] -= 400.0;
            }
            (x, z)
        })
        .collect();
    (data, theta_prior)
}

#[test]
fn modes_shared_and_full_equal_rows_with_every_option_they_take() {
    // Equal r_i / p0_i on every row (shared = rows) and a diagonal R (full = rows), over
    // one, two and three rows, both forms shared takes (full: the standard), the
    // reinitialization on and off, a prior mean or none, and the gate on one row (with
    // several rows, shared and full leave a sample out on every row when one row gates it,
    // by design). Built from run-time specifications (`boxed_kalman`) and compared through
    // every read-out of the interface, innovation by innovation.
    let (data, theta_prior) = three_rows_with_outliers(77, 1200);
    let (mut reinits, mut joint_gated) = (0, 0);
    for rows in [vec![1usize], vec![1, 3], vec![0, 1, 3]] {
        let k = rows.len();
        let r: Vec<f64> = [0.04, 0.09, 0.02][..k].to_vec();
        let p0: Vec<f64> = r.iter().map(|ri| ri * 250.0).collect();
        for form in [CovarianceForm::Standard, CovarianceForm::Joseph] {
            for reinit in [false, true] {
                for prior_mean in [false, true] {
                    for gate in [0.0, 4.0] {
                        // Several rows under the gate: shared and full leave a sample out on
                        // every row, mode rows per row; so there full is compared with shared.
                        let joint_gate = gate > 0.0 && k > 1;
                        if joint_gate && form != CovarianceForm::Standard {
                            continue;
                        }
                        let opts = KalmanOptions { form, reinit, gate, ..Default::default() };
                        let spec = |mode| KalmanSpec {
                            rows: rows.clone(),
                            p0: Prior::PerRow(p0.clone()),
                            theta0: prior_mean.then(|| theta_prior[..k * 4].to_vec()),
                            r: r.clone(),
                            mode,
                            opts,
                        };
                        let mut reference = boxed_kalman::<f64, 4>(&spec(Mode::Rows)).unwrap();
                        let mut others = vec![boxed_kalman::<f64, 4>(&spec(Mode::Shared)).unwrap()];
                        if joint_gate {
                            reference = others.pop().unwrap();
                            others.push(boxed_kalman::<f64, 4>(&spec(Mode::Full)).unwrap());
                        } else if form == CovarianceForm::Standard {
                            others.push(boxed_kalman::<f64, 4>(&spec(Mode::Full)).unwrap());
                            // And mode rows in the square-root form (its own path of the
                            // gate and the reinitialization).
                            let mut sqrt = spec(Mode::Rows);
                            sqrt.opts.form = CovarianceForm::Sqrt;
                            others.push(boxed_kalman::<f64, 4>(&sqrt).unwrap());
                        }
                        let what =
                            format!("rows {rows:?} {form:?} reinit {reinit} prior mean {prior_mean} gate {gate}");
                        let (mut e0, mut e1) = (vec![0.0; k], vec![0.0; k]);
                        for (n, (x, z)) in data.iter().enumerate() {
                            reference.update_into(x.as_slice(), z.as_slice(), &[], &mut e0).unwrap();
                            for (o, mode) in others.iter_mut().zip(if joint_gate {
                                ["full against shared"; 3]
                            } else {
                                ["shared", "full", "rows sqrt"]
                            }) {
                                o.update_into(x.as_slice(), z.as_slice(), &[], &mut e1).unwrap();
                                for (a, b) in e0.iter().zip(&e1) {
                                    let (r0, r1) = (reference.reinit_count(), o.reinit_count());
                                    assert!(
                                        (a - b).abs() <= 1e-7 * (1.0 + b.abs()),
                                        "{what}, mode {mode}, sample {n}: innovations {e0:?} vs {e1:?} (reinitializations {r0}, {r1})"
                                    );
                                }
                            }
                        }
                        for (o, mode) in others.iter().zip(if joint_gate {
                            ["full against shared"; 3]
                        } else {
                            ["shared", "full", "rows sqrt"]
                        }) {
                            assert_same_identifier(&**o, &*reference, 1e-7, &format!("{what}, mode {mode}"));
                        }
                        reinits += reference.reinit_count();
                        if joint_gate {
                            let mut g = vec![0u64; k];
                            reference.gated_into(&mut g).unwrap();
                            joint_gated += g[0];
                        }
                    }
                }
            }
        }
    }
    assert!(reinits > 0, "the jump at sample 600 reinitializes (else the option is not exercised)");
    assert!(joint_gated > 0, "several rows under the gate: samples gated");
}

#[test]
fn a_sample_dominates_only_beyond_a_million_times_the_median_norm() {
    // "more than 1e6 times the median state norm": median norm exactly 1 (x = e_0, and e_1,
    // e_2 for a full-rank regression), one sample at exactly 1e6 (not named) or just above.
    for (big, named) in [(1e6, false), (1e6 * (1.0 + 1e-12), true)] {
        let mut ls = BatchLeastSquares::<f64, 4>::new(&[1]).unwrap();
        for k in 0..9 {
            ls.push(&V4::from_fn(|j, _| if j == k % 4 { 1.0 } else { 0.0 }), &V4::zeros()).unwrap();
        }
        ls.push(&V4::new(0.0, big, 0.0, 0.0), &V4::zeros()).unwrap();
        assert_eq!(ls.dominating_sample(), named.then_some(9), "a sample of norm {big:e}");
    }
}

#[test]
fn a_structure_of_full_rows_is_mode_rows_with_every_option() {
    // "With one equation per group this is exactly KalmanRows on the structure's regressors"
    // (structured.rs): the full rows 0, 1, 3 as a Structure (fixed and heap storage) against
    // mode rows, over every form, the tracking options, the screens and both starts (a prior
    // mean with the prior), innovation by innovation and through every read-out.
    use crate::identify::{StructuredKalman, StructuredKalmanVec, StructuredPrior};
    use crate::structure::Structure;
    let (data, theta_prior) = three_rows_with_outliers(78, 900);
    let rows = [0usize, 1, 3];
    let r = [0.04, 0.09, 0.02];
    let structure = Structure::<f64>::full_rows(4, &rows).unwrap();
    let tracking =
        [(1.0, 0.0, false, 0.0), (0.99, 0.0, false, 0.0), (0.99, 0.0, true, 0.0), (0.995, 1e-5, false, 60.0)];
    let mut gated = 0;
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        for (lambda, q, directional, cap) in tracking {
            for (gate, huber) in [(0.0, 0.0), (4.0, 0.0), (0.0, 1.345)] {
                for exact in [false, true] {
                    let opts = super::numerics_tests::sweep_options(form, (lambda, q, directional, cap), (gate, huber));
                    let what =
                        format!("{form:?} λ {lambda} q {q} dir {directional} gate {gate} huber {huber} exact {exact}");
                    let spec = KalmanSpec {
                        rows: rows.to_vec(),
                        p0: if exact { Prior::Exact } else { Prior::PerRow(vec![30.0]) },
                        theta0: (!exact).then(|| theta_prior.clone()),
                        r: r.to_vec(),
                        mode: Mode::Rows,
                        opts,
                    };
                    let mut reference = boxed_kalman::<f64, 4>(&spec).unwrap();
                    let p0 = if exact { StructuredPrior::Exact } else { StructuredPrior::Scalar(30.0) };
                    let theta0 = (!exact).then_some(theta_prior.as_slice());
                    let mut others: Vec<Box<dyn DynIdentifier<f64>>> = vec![
                        Box::new(StructuredKalman::<f64, 4, 3>::new(structure, p0, theta0, &r, opts).unwrap()),
                        Box::new(StructuredKalmanVec::<f64, 4>::new(structure, p0, theta0, &r, opts).unwrap()),
                    ];
                    let (mut e0, mut e1) = ([0.0; 3], [0.0; 3]);
                    for (n, (x, z)) in data.iter().enumerate() {
                        reference.update_into(x.as_slice(), z.as_slice(), &[], &mut e0).unwrap();
                        for o in others.iter_mut() {
                            o.update_into(x.as_slice(), z.as_slice(), &[], &mut e1).unwrap();
                            for (a, b) in e0.iter().zip(&e1) {
                                let same = (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-7 * (1.0 + b.abs());
                                assert!(same, "{what}, sample {n}: innovations {e0:?} vs {e1:?}");
                            }
                        }
                    }
                    for o in &others {
                        assert_same_identifier(&**o, &*reference, 1e-7, &what);
                    }
                    let mut g = [0u64; 3];
                    reference.gated_into(&mut g).unwrap();
                    gated += g.iter().sum::<u64>();
                }
            }
        }
    }
    assert!(gated > 0, "the gate acts");
}

#[test]
fn mode_full_takes_noise_free_rows_beside_noisy_ones() {
    // A noise-free row (R_ii = 0) collapses its block of P along what it learned, by design,
    // so it is exempt from the definiteness check of risky samples (as in mode rows): beside
    // a noisy row, mode full takes every sample, and both rows follow mode rows with the same
    // diagonal R, the noise-free one learning its θ exactly.
    let (data, _) = three_rows_with_outliers(79, 300);
    let truth = {
        // The noise-free row: z_0 = xᵀθ exactly.
        let th = V4::new(0.7, -1.2, 0.4, 2.0);
        data.iter().map(|(x, z)| (*x, V4::new(x.dot(&th), z[1], z[2], z[3]))).collect::<Vec<_>>()
    };
    let opts = KalmanOptions::default();
    // The noise-free row first and second (its block of P on and off the diagonal's start).
    for (order, r, at) in [([0, 3], [0.0, 0.04], 0), ([3, 0], [0.04, 0.0], 1)] {
        let mut full = FullKalmanIdentifier::<f64, 4, 2>::from_slices(&order, &[100.0], &r, opts).unwrap();
        let mut rows = KalmanIdentifier::<f64, 4, 2>::new(order, 100.0, r).unwrap();
        for (k, (x, z)) in truth.iter().enumerate() {
            let a = full.update(x, z).unwrap_or_else(|err| panic!("{order:?} sample {k} refused: {err:?}"));
            let b = rows.update(x, z).unwrap();
            assert!((a - b).abs().max() <= 1e-8 * (1.0 + b.abs().max()), "{order:?} sample {k}: {a} vs {b}");
        }
        assert_eq!(full.samples(), 300);
        let th = full.theta_row(at);
        assert!((th - V4::new(0.7, -1.2, 0.4, 2.0)).abs().max() < 1e-9, "{order:?}: {th}");
    }
}

#[test]
fn batch_least_squares_reports_the_storage_its_samples_take() {
    // `storage_bytes`: the stored states (N per sample) and derivatives (one per unknown row),
    // as allocated: at least what the samples hold, within the Vec's doubling above it.
    let mut ls = BatchLeastSquares::<f64, 4>::new(&[1, 3]).unwrap();
    assert_eq!(ls.storage_bytes(), 0);
    for k in 0..1000 {
        let x = V4::from_fn(|j, _| (k * 4 + j) as f64);
        ls.push(&x, &x).unwrap();
    }
    let held = 1000 * (4 + 2) * core::mem::size_of::<f64>();
    assert!(ls.storage_bytes() >= held && ls.storage_bytes() <= 2 * held, "{} for {held}", ls.storage_bytes());
}

#[test]
fn a_run_time_prior_per_row_is_checked_alike_with_and_without_a_prior_mean() {
    // Mode rows built from a specification: `p0` one per row, with no prior mean (the
    // constructor of the rows) or a zero one (a filter per row): the same bad values refused
    // naming `p0`, and the same identifier from good ones.
    for theta0 in [None, Some(vec![0.0; 8])] {
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let spec = KalmanSpec {
                rows: vec![1, 3],
                p0: Prior::PerRow(vec![10.0, bad]),
                theta0: theta0.clone(),
                r: vec![0.1],
                mode: Mode::Rows,
                opts: KalmanOptions::default(),
            };
            let err = boxed_kalman::<f64, 4>(&spec).err();
            assert!(
                matches!(
                    err,
                    Some(Error::InvalidArgument { arg: "p0", .. }) | Some(Error::NonFinite { arg: "p0", .. })
                ),
                "p0 {bad}, prior mean {theta0:?}: {err:?}"
            );
        }
    }
    let data = road(4, 300);
    let spec = |theta0| KalmanSpec {
        rows: vec![1, 3],
        p0: Prior::PerRow(vec![10.0, 1000.0]),
        theta0,
        r: vec![0.1, 0.2],
        mode: Mode::Rows,
        opts: KalmanOptions::default(),
    };
    let mut a = boxed_kalman::<f64, 4>(&spec(None)).unwrap();
    let mut b = boxed_kalman::<f64, 4>(&spec(Some(vec![0.0; 8]))).unwrap();
    let mut direct =
        KalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[10.0, 1000.0], &[0.1, 0.2], KalmanOptions::default())
            .unwrap();
    let (mut ea, mut eb) = ([0.0; 2], [0.0; 2]);
    for (x, z) in &data {
        a.update_into(x.as_slice(), z.as_slice(), &[], &mut ea).unwrap();
        b.update_into(x.as_slice(), z.as_slice(), &[], &mut eb).unwrap();
        let e = direct.update(x, z).unwrap();
        assert_eq!(ea, eb);
        assert_eq!(ea.as_slice(), e.as_slice());
    }
}

/// Mode rows under the outlier gate (Python's default) runs the plain update and sends a
/// sample beyond the gate to the general one (`lanes::PLAIN`, `RowLanes::beyond_gate`): it
/// takes and leaves out exactly the samples the general mode does, bit for bit. The general
/// mode is forced by a Huber constant no residual reaches (`huber = 1e150`: it then weights
/// nothing down, and its gate decisions are the same test on the same values).
#[test]
fn the_gate_in_the_plain_mode_equals_the_general_mode_bit_for_bit() {
    let (data, _) = three_rows_with_outliers(91, 3000);
    for rows in [vec![1usize], vec![1, 3], vec![0, 1, 3]] {
        let k = rows.len();
        let spec = |huber: f64| KalmanSpec {
            rows: rows.clone(),
            p0: Prior::PerRow(vec![10.0; k]),
            theta0: None,
            r: vec![0.04; k],
            mode: Mode::Rows,
            opts: KalmanOptions { gate: 4.0, huber, ..Default::default() },
        };
        let mut plain = boxed_kalman::<f64, 4>(&spec(0.0)).unwrap();
        let mut general = boxed_kalman::<f64, 4>(&spec(1e150)).unwrap();
        let (mut e0, mut e1) = (vec![0.0; k], vec![0.0; k]);
        for (n, (x, z)) in data.iter().enumerate() {
            plain.update_into(x.as_slice(), z.as_slice(), &[], &mut e0).unwrap();
            general.update_into(x.as_slice(), z.as_slice(), &[], &mut e1).unwrap();
            let same = e0.iter().zip(&e1).all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "rows {rows:?}, sample {n}: innovations {e0:?} against {e1:?}");
        }
        assert_same_identifier(plain.as_ref(), general.as_ref(), 0.0, &format!("rows {rows:?}"));
        let mut gated = vec![0u64; k];
        plain.gated_into(&mut gated).unwrap();
        assert!(gated.iter().any(|&g| g >= 40), "rows {rows:?}: the outliers are gated ({gated:?})");
    }
}

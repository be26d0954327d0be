//! Every identifier honours the whole [`Identifier`] contract, read through every method of
//! the trait (and of [`DynIdentifier`], what the Python bindings hold), against references
//! written here: the estimate and its covariance in closed form (least squares by the normal
//! equations; a Kalman filter without forgetting is ridge regression, Eq 4.3–4.7 summed), the
//! residual sums the trait's docs define, what the identifier was built with (rows, noise,
//! groups), and typed errors for every buffer of the wrong length.
//!
//! A mutation-testing aid as much as a test: coverage of the Rust tests showed
//! these read-outs executed by pytest only (through the extension), so a broken accessor
//! passed every Rust test.

use core::ops::ControlFlow;

use nalgebra::{DMatrix, DVector};
use vehid_core::identify::{
    BatchLeastSquares, BiasCompensatedVec, CovarianceForm, DynIdentifier, Dynamic, FullKalmanIdentifierVec, Gain,
    GainKind, Identifier, IvIdentifierVec, KalmanIdentifierVec, KalmanOptions, KalmanRows, LsAccumulator,
    NoiseEstimatingBclsVec, Samples, SharedKalmanIdentifierVec, StochasticGradientVec, StructuredGradient,
    StructuredKalmanVec, StructuredPrior,
};
use vehid_core::structure::Structure;
use vehid_core::Error;

use crate::common::{close, quarter};

const ROWS: [usize; 2] = [1, 3];
const N: usize = 4;

/// The regressors `X` (`L × N`) and the unknown rows' derivatives `Z` (`L × K`).
fn design(x: &[f64], z: &[f64], rows: &[usize]) -> (DMatrix<f64>, DMatrix<f64>) {
    let l = x.len() / N;
    let xm = DMatrix::from_row_slice(l, N, x);
    let zm = DMatrix::from_fn(l, rows.len(), |k, i| z[k * N + rows[i]]);
    (xm, zm)
}

/// Ridge regression of each unknown row: `θ_i = (XᵀX + (r_i/p0) I)⁻¹ Xᵀ z_i` and its
/// posterior covariance `P_i = r_i (XᵀX + (r_i/p0) I)⁻¹` (a Kalman filter from the prior
/// `θ ~ N(0, p0 I)` with noise variance `r_i`, after every sample); `p0 = ∞` is least squares.
/// Also each row's `ssr = Σ (z − xᵀθ_i)² + (r_i/p0)|θ_i|²` (`r_i` times the filter's
/// minimized cost, the sum of its normalized innovations).
fn ridge(x: &[f64], z: &[f64], p0: f64, r: &[f64]) -> (Vec<f64>, Vec<DMatrix<f64>>, Vec<f64>) {
    let (xm, zm) = design(x, z, &ROWS);
    let g = xm.transpose() * &xm;
    let (mut theta, mut cov, mut ssr) = (vec![], vec![], vec![]);
    for (i, &ri) in r.iter().enumerate() {
        let a = &g + DMatrix::identity(N, N) * (ri / p0);
        let inv = a.clone().try_inverse().unwrap();
        let th: DVector<f64> = &inv * (xm.transpose() * zm.column(i));
        let res = zm.column(i) - &xm * &th;
        ssr.push(res.norm_squared() + ri / p0 * th.norm_squared());
        theta.extend(th.iter());
        cov.push(inv * ri);
    }
    (theta, cov, ssr)
}

/// What a read-out should give.
enum Check {
    /// The identifier keeps none: `Unsupported`.
    Unsupported,
    /// Given, finite; its value is checked elsewhere (the identifier's own tests).
    Any,
    /// These values, to this relative tolerance (of the largest entry).
    Value(Vec<f64>, f64),
}

/// What an identifier was built with and what it should give.
struct Expect {
    /// The estimate.
    params: Check,
    /// The covariance `P` (row-major, `params²`).
    cov: Check,
    /// The noise matrix `R` (`equations²`).
    noise: Check,
    /// Each equation's residual sum of squares.
    ssr: Check,
    /// Whether `reset_covariance` is supported after the data.
    reset: bool,
}

/// The block-diagonal matrix of per-row blocks, row-major.
fn block_diag(blocks: &[DMatrix<f64>]) -> Vec<f64> {
    let np = blocks.iter().map(|b| b.nrows()).sum::<usize>();
    let mut out = vec![0.0; np * np];
    let mut at = 0;
    for b in blocks {
        for i in 0..b.nrows() {
            for j in 0..b.ncols() {
                out[(at + i) * np + at + j] = b[(i, j)];
            }
        }
        at += b.nrows();
    }
    out
}

/// A [`Error::Shape`] saying the length it expected and the one it got.
fn is_shape<T: core::fmt::Debug>(name: &str, what: &str, r: Result<T, Error>, want: usize, given: usize) {
    match r {
        Err(Error::Shape { expected, got, .. }) => {
            assert_eq!((expected, got), (want, given), "{name}: {what}'s error: expected length, got length")
        }
        r => panic!("{name}: {what} of a wrong length gave {r:?}"),
    }
}

fn unsupported<T: core::fmt::Debug>(name: &str, what: &str, r: Result<T, Error>) {
    assert!(matches!(r, Err(Error::Unsupported { .. })), "{name}: {what} gave {r:?}, expected Unsupported");
}

/// Runs `id` over the samples and checks every read-out of the trait against `ex`.
fn contract<I: DynIdentifier<f64> + Clone + 'static>(name: &str, mut id: I, x: &[f64], z: &[f64], ex: Expect) {
    let (ne, np) = (ROWS.len(), ROWS.len() * N);
    let d = id.dims();
    assert_eq!((d.states, d.inputs, d.equations, d.params), (N, 0, ne, np), "{name}: dims");
    assert_eq!(id.rows(), &ROWS[..], "{name}: rows");
    assert_eq!(id.samples(), 0, "{name}: samples before any");

    // Buffers one too long or too short: typed errors naming the buffer, never a panic.
    is_shape(name, "params_into", id.params_into(&mut vec![0.0; np + 1]), np, np + 1);
    is_shape(name, "params_into", id.params_into(&mut vec![0.0; np - 1]), np, np - 1);
    is_shape(name, "gated_into", id.gated_into(&mut [0u64; 3]), ne, 3);
    is_shape(name, "groups_into (params)", id.groups_into(&mut vec![0; np + 1], &mut [0; 2]), np, np + 1);
    is_shape(name, "groups_into (equations)", id.groups_into(&mut vec![0; np], &mut [0; 1]), ne, 1);
    let e_short = id.update_into(&x[..N], &z[..N], &[], &mut [0.0; 1]);
    is_shape(name, "update_into's innovations", e_short, ne, 1);
    assert_eq!(id.samples(), 0, "{name}: a refused sample is not counted");

    // The samples, with a sample count and a fit that sees them all.
    let data = Samples::new(N, 0, x, z, &[]).unwrap();
    assert_eq!((data.is_empty(), data.states(), data.inputs()), (false, N, 0));
    assert!(Samples::new(N, 0, &x[..0], &z[..0], &[]).unwrap().is_empty());
    let mut seen = 0;
    id.fit(&data, |k, _, _| {
        assert_eq!(k, seen);
        seen += 1;
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(id.samples(), data.len() as u64, "{name}: samples");

    let mut theta = vec![0.0; np];
    id.params_into(&mut theta).unwrap_or_else(|e| panic!("{name}: {e:?}"));
    assert!(theta.iter().all(|v| v.is_finite()), "{name}: θ {theta:?}");
    if let Check::Value(want, rel) = &ex.params {
        close(name, "θ", &theta, want, *rel);
    }

    let mut cov = vec![0.0; np * np];
    match &ex.cov {
        Check::Unsupported => {
            unsupported(name, "covariance_into", id.covariance_into(&mut cov));
            assert_eq!(id.trace(), None, "{name}: no covariance, no trace");
        }
        check => {
            is_shape(name, "covariance_into", id.covariance_into(&mut vec![0.0; np * np - 1]), np * np, np * np - 1);
            id.covariance_into(&mut cov).unwrap();
            assert!(cov.iter().all(|v| v.is_finite()), "{name}: P {cov:?}");
            if let Check::Value(want, rel) = check {
                close(name, "P", &cov, want, *rel);
            }
            if let Some(t) = id.trace() {
                let diag: f64 = (0..np).map(|j| cov[j * np + j]).sum();
                assert!((t - diag).abs() <= 1e-9 * diag, "{name}: trace {t} against Σ diag P {diag}");
            }
        }
    }

    let mut r = vec![0.0; ne * ne];
    match &ex.noise {
        Check::Unsupported => unsupported(name, "noise_into", id.noise_into(&mut r)),
        check => {
            is_shape(name, "noise_into", id.noise_into(&mut vec![0.0; ne * ne + 1]), ne * ne, ne * ne + 1);
            id.noise_into(&mut r).unwrap();
            assert!(r.iter().all(|v| v.is_finite()), "{name}: R {r:?}");
            if let Check::Value(want, rel) = check {
                close(name, "R", &r, want, *rel);
            }
        }
    }

    let (mut ssr, mut nobs) = (vec![0.0; ne], vec![0.0; ne]);
    match &ex.ssr {
        Check::Unsupported => unsupported(name, "residuals_into", id.residuals_into(&mut ssr, &mut nobs)),
        check => {
            is_shape(name, "residuals_into", id.residuals_into(&mut [0.0; 3], &mut [0.0; 3]), ne, 3);
            is_shape(name, "residuals_into", id.residuals_into(&mut [0.0; 2], &mut [0.0; 1]), ne, 1);
            id.residuals_into(&mut ssr, &mut nobs).unwrap();
            assert!(ssr.iter().all(|v| v.is_finite() && *v > 0.0), "{name}: ssr {ssr:?}");
            if let Check::Value(want, rel) = check {
                for i in 0..ne {
                    let (g, w) = (ssr[i], want[i]);
                    assert!((g - w).abs() <= rel * w, "{name}: ssr[{i}] {g} against {w}");
                }
                assert_eq!(nobs, vec![data.len() as f64; ne], "{name}: nobs");
            }
            // The samples behind the sums: an instrumental identifier starts once it has
            // instruments (after its delay and lags).
            assert!(nobs.iter().all(|&v| v > 0.0 && v <= data.len() as f64), "{name}: nobs {nobs:?}");
        }
    }

    // Rows of a linear model: parameter j in row j / N's group, equation i its own.
    let (mut gp, mut ge) = (vec![9; np], vec![9; ne]);
    id.groups_into(&mut gp, &mut ge).unwrap();
    assert_eq!(gp, (0..np).map(|j| j / N).collect::<Vec<_>>(), "{name}: groups of the parameters");
    assert_eq!(ge, vec![0, 1], "{name}: groups of the equations");
    let mut gated = [7u64; 2];
    id.gated_into(&mut gated).unwrap();
    assert_eq!(gated, [0, 0], "{name}: nothing gated without a gate");
    assert_eq!(id.reinit_count(), 0, "{name}: no reinitialization asked for");

    // The boxed copy: the same estimate, and the concrete type behind it.
    let boxed = id.clone_box();
    let mut again = vec![0.0; np];
    boxed.params_into(&mut again).unwrap();
    assert_eq!(again, theta, "{name}: clone_box");
    assert_eq!(boxed.samples(), id.samples());
    assert!(boxed.as_any().downcast_ref::<I>().is_some(), "{name}: as_any is the concrete identifier");

    // Covariance reset: P = p0 I around the same estimate.
    let mut reset = id.clone();
    if ex.reset {
        reset.reset_covariance(2.5).unwrap();
        reset.covariance_into(&mut cov).unwrap();
        let eye: Vec<f64> = (0..np * np).map(|k| if k % (np + 1) == 0 { 2.5 } else { 0.0 }).collect();
        close(name, "P after reset", &cov, &eye, 1e-15);
        reset.params_into(&mut again).unwrap();
        assert_eq!(again, theta, "{name}: reset keeps θ");
    } else {
        unsupported(name, "reset_covariance", reset.reset_covariance(2.5));
    }

    // A rejected sample in a fit: its index, the reason, and nothing changed.
    let mut bad = x[..8 * N].to_vec();
    bad[3 * N + 1] = f64::NAN;
    let before = id.samples();
    let err = id.fit(&Samples::new(N, 0, &bad, &z[..8 * N], &[]).unwrap(), |_, _, _| ControlFlow::Continue(()));
    let err = err.unwrap_err();
    assert_eq!(err.sample, Some(3), "{name}");
    assert!(matches!(err.error, Error::NonFinite { .. }), "{name}: {err:?}");
    let text = err.to_string();
    assert!(text.starts_with("sample 3 was rejected (") && text.ends_with("the identifier is unchanged"), "{text}");
    assert_eq!(id.samples(), before);
    id.params_into(&mut again).unwrap();
    assert_eq!(again, theta, "{name}: a refused fit changes nothing");
}

/// Derivative noise variance of the quarter car's data (σ_v = 0.1), every row.
const RV: f64 = 0.01;

fn data() -> (Vec<f64>, Vec<f64>) {
    quarter(600, 0.0, 7301)
}

/// Batch least squares: θ the normal equations' solution, `P = (XᵀX)⁻¹` per row with unit
/// noise, the least-squares residual sums.
#[test]
fn batch_least_squares_honours_the_contract() {
    let (x, z) = data();
    let (theta, cov, ssr) = ridge(&x, &z, f64::INFINITY, &[1.0, 1.0]);
    let ex = Expect {
        params: Check::Value(theta, 1e-9),
        cov: Check::Value(block_diag(&cov), 1e-9),
        noise: Check::Value(vec![1.0, 0.0, 0.0, 1.0], 0.0),
        ssr: Check::Value(ssr, 1e-9),
        reset: false,
    };
    contract("batch", BatchLeastSquares::<f64, N>::new(&ROWS).unwrap(), &x, &z, ex);
    // extend: the same samples at once; whole samples only.
    let mut b = BatchLeastSquares::<f64, N>::new(&ROWS).unwrap();
    b.extend(&x, &z).unwrap();
    assert_eq!(b.samples(), x.len() / N);
    close("batch", "θ after extend", &b.solve().unwrap(), &ridge(&x, &z, f64::INFINITY, &[1.0, 1.0]).0, 1e-9);
    for (xs, zs) in [(&x[..5], &z[..5]), (&x[..8], &z[..4]), (&x[..8], &z[..12])] {
        assert!(matches!(b.extend(xs, zs), Err(Error::Shape { .. })), "{} {}", xs.len(), zs.len());
    }
    assert_eq!(b.samples(), x.len() / N, "a refused extend stores nothing");
    b.clear();
    assert_eq!((b.samples(), b.rows()), (0, &ROWS[..]));
}

/// Batch least squares' covariance `(XᵀX)⁻¹` where forming `XᵀX` loses it: `X = H D Vᵀ`
/// with `H` four orthogonal ±1 columns of 16 rows (`HᵀH = 16 I`), `D = diag(1, 1e-3, 1e-6,
/// 1e-9)` and `V` a rotation, so `(XᵀX)⁻¹ = V D⁻² Vᵀ / 16` in closed form. cond(X) = 1e9:
/// the estimate exists (the rank test's floor is `16 ε`), and so must its covariance, though
/// `XᵀX` (cond 1e18) is not positive definite in floating point. The columns are given in
/// reverse too, so that the pivoting reorders them. States all below 1e-160 (the same `X`
/// scaled) make `(XᵀX)⁻¹` overflow: an error naming `r`, not an infinite covariance.
#[test]
fn batch_covariance_is_the_inverse_gram_where_the_gram_cannot_be_formed() {
    let l = 16;
    let h = DMatrix::from_fn(l, N, |i, j| if (i >> j) & 1 == 0 { 1.0 } else { -1.0 });
    let d = DVector::from_vec(vec![1.0, 1e-3, 1e-6, 1e-9]);
    let rot = |a: usize, b: usize, t: f64| {
        let mut g = DMatrix::<f64>::identity(N, N);
        (g[(a, a)], g[(a, b)], g[(b, a)], g[(b, b)]) = (t.cos(), -t.sin(), t.sin(), t.cos());
        g
    };
    let v = rot(0, 1, 0.7) * rot(1, 2, -1.1) * rot(2, 3, 0.4) * rot(0, 3, 2.0);
    let x = &h * DMatrix::from_diagonal(&d) * v.transpose();
    let want = &v * DMatrix::from_diagonal(&d.map(|di| 1.0 / (16.0 * di * di))) * v.transpose();
    let gram = x.transpose() * &x;
    assert!(
        gram.clone().cholesky().is_none_or(|c| (c.inverse() - &want).amax() > 0.1 * want.amax()),
        "the case must defeat the normal equations"
    );
    for reverse in [false, true] {
        let col = |j: usize| if reverse { N - 1 - j } else { j };
        let mut b = BatchLeastSquares::<f64, N>::new(&ROWS).unwrap();
        let xs: Vec<f64> = (0..l).flat_map(|i| (0..N).map(move |j| (i, col(j)))).map(|(i, j)| x[(i, j)]).collect();
        let zs: Vec<f64> = (0..l * N).map(|k| (k as f64 * 0.37).sin()).collect();
        b.extend(&xs, &zs).unwrap();
        b.solve().unwrap();
        let kn = ROWS.len() * N;
        let mut cov = vec![f64::NAN; kn * kn];
        b.covariance_into(&mut cov).unwrap();
        for i in 0..ROWS.len() {
            for a in 0..N {
                for c in 0..N {
                    let got = cov[(i * N + a) * kn + i * N + c];
                    let err = (got - want[(col(a), col(c))]).abs();
                    assert!(
                        err <= 1e-5 * want.amax(),
                        "reverse {reverse}, row {i}, ({a}, {c}): {got} vs {}",
                        want[(col(a), col(c))]
                    );
                }
            }
            for c in 0..kn {
                if c / N != i {
                    assert_eq!(cov[(i * N) * kn + c], 0.0, "cross-row block");
                }
            }
        }
        let mut tiny = BatchLeastSquares::<f64, N>::new(&ROWS).unwrap();
        let small: Vec<f64> = xs.iter().map(|v| v * 1e-160).collect();
        tiny.extend(&small, &zs).unwrap();
        assert!(tiny.solve().is_ok());
        assert!(
            matches!(tiny.covariance_into(&mut cov), Err(Error::InvalidArgument { arg: "r", .. })),
            "{:?}",
            tiny.covariance_into(&mut cov)
        );
    }
}

/// The normal equations accumulated: θ the least-squares solution; no covariance, noise or
/// residuals kept (the Python layer's `LeastSquares` reads them from the batch form). Also
/// its own accessors and its cost per sample (`x xᵀ`: N² mul and add; `x z_i`: K·N), counted
/// here for N = 4 with one and two rows.
#[test]
fn least_squares_accumulator_honours_the_contract() {
    let (x, z) = data();
    let (theta, _, _) = ridge(&x, &z, f64::INFINITY, &[1.0, 1.0]);
    let ex = Expect {
        params: Check::Value(theta.clone(), 1e-8),
        cov: Check::Unsupported,
        noise: Check::Unsupported,
        ssr: Check::Unsupported,
        reset: false,
    };
    contract("accumulator", LsAccumulator::<f64, N, Dynamic>::from_rows(&ROWS).unwrap(), &x, &z, ex);
    let mut acc = LsAccumulator::<f64, N, Dynamic>::from_rows(&ROWS).unwrap();
    assert_eq!(acc.rows(), &ROWS[..]);
    for (xk, zk) in x.chunks(N).zip(z.chunks(N)).take(10) {
        acc.push(&nalgebra::SVector::from_row_slice(xk), &nalgebra::SVector::from_row_slice(zk)).unwrap();
    }
    assert_eq!(acc.samples(), 10);
    is_shape("accumulator", "solve_into", acc.solve_into(&mut [0.0; 7]), 8, 7);
    let two = acc.cost();
    assert_eq!((two.multiplications, two.additions, two.divisions, two.square_roots), (16 + 8, 16 + 8, 0, 0));
    let one = LsAccumulator::<f64, N, Dynamic>::from_rows(&[2]).unwrap().cost();
    assert_eq!((one.multiplications, one.additions), (16 + 4, 16 + 4));
    assert!(two.bytes > core::mem::size_of_val(&acc), "the heap rows are counted");
}

/// Each equation's noise as a diagonal `R`, row-major.
fn diag(r: &[f64]) -> Vec<f64> {
    let k = r.len();
    (0..k * k).map(|j| if j % (k + 1) == 0 { r[j / k] } else { 0.0 }).collect()
}

/// What a Kalman identifier from the prior `p0 I` gives on `(x, z)` with noise variances `r`:
/// ridge regression ([`ridge`]), its covariance, `R = diag(r)`, and the residual sums when the
/// identifier keeps them (`ssr`).
fn ridge_expect(x: &[f64], z: &[f64], p0: f64, r: &[f64], ssr: bool) -> Expect {
    let (theta, cov, sums) = ridge(x, z, p0, r);
    Expect {
        params: Check::Value(theta, 1e-7),
        cov: Check::Value(block_diag(&cov), 1e-7),
        noise: Check::Value(diag(r), 0.0),
        ssr: if ssr { Check::Value(sums, 1e-7) } else { Check::Unsupported },
        reset: true,
    }
}

/// Mode rows from the prior `p0 I`: ridge regression per row, its covariance, and the
/// residual sums `r` times the minimized cost. Also `options()` and `theta_row`.
#[test]
fn kalman_rows_honour_the_contract() {
    let (x, z) = data();
    let (p0, r) = (50.0, [RV, 4.0 * RV]);
    let opts = KalmanOptions { gate: 0.0, ..KalmanOptions::default() };
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        let o = KalmanOptions { form, ..opts };
        let id = KalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[p0], &r, o).unwrap();
        assert_eq!(id.options(), &o);
        contract("rows", id, &x, &z, ridge_expect(&x, &z, p0, &r, true));
    }
}

/// Mode shared (one `P` for the rows, equal variances) and mode full (one `P` over every
/// row) from the prior `p0 I`: ridge regression again.
#[test]
fn kalman_shared_and_full_honour_the_contract() {
    let (x, z) = data();
    let (p0, r) = (50.0, [RV, RV]);
    let ex = || ridge_expect(&x, &z, p0, &r, false);
    let o = KalmanOptions::default();
    contract("shared", SharedKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[p0], &r, o).unwrap(), &x, &z, ex());
    contract("full", FullKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[p0], &r, o).unwrap(), &x, &z, ex());
}

/// A prior mean `θ₀` set before the first sample: ridge regression towards it,
/// `(XᵀX + (r/p0) I)⁻¹ (Xᵀz + (r/p0) θ₀)`, in modes shared and full; shared's own accessors
/// (`rows`, `r(i)`, `theta_row`); three rows' noise matrices (`3 × 3`) in modes rows and
/// shared and batch least squares.
#[test]
fn kalman_prior_means_and_accessors() {
    let (x, z) = data();
    let (p0, r) = (0.5, RV);
    let theta0: Vec<f64> = (0..8).map(|j| 10.0 * j as f64 - 35.0).collect();
    let (xm, zm) = design(&x, &z, &ROWS);
    let a = xm.transpose() * &xm + DMatrix::identity(N, N) * (r / p0);
    let mut want = vec![];
    for i in 0..2 {
        let t0 = DVector::from_column_slice(&theta0[i * N..(i + 1) * N]);
        let th = a.clone().lu().solve(&(xm.transpose() * zm.column(i) + t0 * (r / p0))).unwrap();
        want.extend(th.iter());
    }
    let o = KalmanOptions::default();
    let mut shared = SharedKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[p0], &[r, r], o).unwrap();
    is_shape("shared", "set_theta", shared.set_theta(&theta0[..7]), 8, 7);
    shared.set_theta(&theta0).unwrap();
    let mut full = FullKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[p0], &[r, r], o).unwrap();
    is_shape("full", "set_theta", full.set_theta(&theta0[..7]), 8, 7);
    full.set_theta(&theta0).unwrap();
    let (th_s, th_f) = (crate::common::run(&mut shared, &x, &z), crate::common::run(&mut full, &x, &z));
    close("shared", "θ with a prior mean", &th_s, &want, 1e-7);
    close("full", "θ with a prior mean", &th_f, &want, 1e-7);
    assert_eq!(shared.rows(), &ROWS[..]);
    for i in 0..2 {
        assert_eq!(shared.r(i), r);
        assert_eq!(shared.theta_row(i).as_slice(), &th_s[i * N..(i + 1) * N]);
    }
    let three = [0usize, 1, 3];
    let r3 = [RV, 2.0 * RV, 3.0 * RV];
    let mut rr = [0.0; 9];
    let rows3 = KalmanIdentifierVec::<f64, N>::from_slices(&three, &[p0], &r3, o).unwrap();
    rows3.noise_into(&mut rr).unwrap();
    assert_eq!(rr.to_vec(), diag(&r3));
    is_shape("rows", "noise_into", rows3.noise_into(&mut [0.0; 6]), 9, 6);
    let batch3 = BatchLeastSquares::<f64, N>::new(&three).unwrap();
    batch3.noise_into(&mut rr).unwrap();
    assert_eq!(rr.to_vec(), diag(&[1.0; 3]));
    is_shape("batch", "noise_into", batch3.noise_into(&mut [0.0; 6]), 9, 6);
    let shared3 = SharedKalmanIdentifierVec::<f64, N>::from_slices(&three, &[p0], &[RV; 3], o).unwrap();
    shared3.noise_into(&mut rr).unwrap();
    assert_eq!(rr.to_vec(), diag(&[RV; 3]));
    is_shape("shared", "noise_into", shared3.noise_into(&mut [0.0; 6]), 9, 6);
}

/// Mode shared counts what it gates and reinitializes (mode full too), and says so through
/// its own accessors and the trait's alike: one sample with a derivative 10⁴ σ off, gated (every row leaves
/// it out: one more than on the clean samples); without the gate and with reinitialization
/// on, as often as mode rows on the same samples.
#[test]
fn kalman_shared_counts_gated_and_reinitialized_samples() {
    let (x, clean) = data();
    let mut z = clean.clone();
    z[400 * N + 1] += 1e4 * RV.sqrt();
    let gate = KalmanOptions { gate: 4.0, ..KalmanOptions::default() };
    let gated = |z: &[f64]| {
        let mut s = SharedKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[50.0], &[RV, RV], gate).unwrap();
        crate::common::feed(&mut s, &x, z);
        let mut g = [0u64; 2];
        s.gated_into(&mut g).unwrap();
        assert_eq!(g, [s.gated(); 2]);
        s.gated()
    };
    // The clean samples' own tail beyond 4σ, and the outlier.
    assert_eq!(gated(&z), gated(&clean) + 1);
    let reinit = KalmanOptions { reinit: true, ..KalmanOptions::default() };
    let mut s = SharedKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[50.0], &[RV, RV], reinit).unwrap();
    crate::common::feed(&mut s, &x, &z);
    let mut rows = KalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[50.0], &[RV, RV], reinit).unwrap();
    crate::common::feed(&mut rows, &x, &z);
    // Shared and full run the rows' rule (kalman::tests sweeps them against it).
    let mut full = FullKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[50.0], &[RV, RV], reinit).unwrap();
    crate::common::feed(&mut full, &x, &z);
    assert!(s.reinit_count() >= 2);
    assert_eq!((s.reinit_count(), full.reinit_count()), (rows.reinit_count(), rows.reinit_count()));
    assert_eq!(Identifier::reinit_count(&s), s.reinit_count());
    assert_eq!(Identifier::reinit_count(&full), full.reinit_count());
    assert_eq!(s.gated(), 0);
}

/// Mode rows' reinitialization (Eq 4.36) does not depend on how its rows are packed into
/// lanes: one lane per group (the update's several-group path) reinitializes on the same
/// samples as both rows in one group, with θ̂ equal to rounding, in the standard form (the
/// plain mode of the lanes) and the Joseph form (their general mode).
#[test]
fn mode_rows_reinitializes_alike_whatever_its_lanes() {
    let (x, clean) = data();
    let mut z = clean.clone();
    z[400 * N + 1] += 1e4 * RV.sqrt();
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph] {
        let o = KalmanOptions { reinit: true, form, ..KalmanOptions::default() };
        let mut one = KalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[50.0], &[RV, RV], o).unwrap();
        let mut split = KalmanRows::<f64, N, Dynamic<1>>::from_slices(&ROWS, &[50.0], &[RV, RV], o).unwrap();
        crate::common::feed(&mut one, &x, &z);
        crate::common::feed(&mut split, &x, &z);
        assert!(one.reinit_count() >= 2, "{form:?}: {}", one.reinit_count());
        assert_eq!(split.reinit_count(), one.reinit_count(), "{form:?}");
        let (a, b) = (crate::common::params(&one), crate::common::params(&split));
        close("one lane per group", &format!("θ ({form:?})"), &b, &a, 1e-9);
    }
}

/// Row `i`'s `s = S_ii / r_i = 1 + xᵀP_i x / r_i` before a sample at `x`, from the
/// covariance the identifier reports (two rows).
fn s_row(id: &dyn Identifier<f64>, x: &[f64], i: usize, r: &[f64; 2]) -> f64 {
    let mut cov = vec![0.0; 4 * N * N];
    id.covariance_into(&mut cov).unwrap();
    let p = |a: usize, b: usize| cov[(i * N + a) * 2 * N + i * N + b];
    1.0 + (0..N).map(|a| (0..N).map(|b| x[a] * p(a, b) * x[b]).sum::<f64>()).sum::<f64>() / r[i]
}

/// The joint gate's scale as `KalmanOptions::gate`'s docs define it, from what an identifier
/// of two rows reports: `σ̂_i² = Σ w_i² / (n − N)`, `w_i² = e_i² r_i / S_ii` (`e_i² / s` in
/// mode shared), a gated sample's `w_i²` Winsorized at `κ² σ̂_i²`.
struct GateScale {
    kappa: f64,
    r: [f64; 2],
    ssr: [f64; 2],
    nobs: f64,
}

impl GateScale {
    fn sigma2(&self, i: usize) -> f64 {
        self.ssr[i] / (self.nobs - N as f64)
    }

    /// One sample through `id` and the scale; whether `id` gated it.
    fn step(&mut self, id: &mut dyn Identifier<f64>, x: &[f64], z: &[f64]) -> bool {
        let s = [s_row(id, x, 0, &self.r), s_row(id, x, 1, &self.r)];
        let mut gated = [0u64; 2];
        id.gated_into(&mut gated).unwrap();
        let before = gated[0];
        let mut e = [0.0; 2];
        id.update_into(x, z, &[], &mut e).unwrap();
        id.gated_into(&mut gated).unwrap();
        let out = gated[0] > before;
        for i in 0..2 {
            let w2 = e[i] * e[i] / s[i];
            self.ssr[i] += if out { w2.min(self.kappa * self.kappa * self.sigma2(i)) } else { w2 };
        }
        self.nobs += 1.0;
        out
    }
}

/// The joint gate's scale (modes shared and full) against [`GateScale`], through a gated
/// sample whose regressor is 20 times the data's (`s` about 10, so `e²/s` and `e² s` are far
/// apart): an outlier of 1000 σ on row 0 (Winsorized) and a residual inside the gate on row 1
/// (taken whole). Then probes just outside and just inside `κ σ̂_i` on each row: exactly the
/// first of each pair is gated.
#[test]
fn the_joint_gate_scale_is_the_winsorized_sum_of_normalized_residuals() {
    let (x, z) = data();
    let kappa = 4.0;
    let opts = KalmanOptions { gate: kappa, ..KalmanOptions::default() };
    let r = [RV, 2.0 * RV];
    let shared = SharedKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[50.0, 100.0], &r, opts).unwrap();
    let full = FullKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[50.0, 100.0], &r, opts).unwrap();
    let modes: [(&str, Box<dyn Identifier<f64>>); 2] = [("shared", Box::new(shared)), ("full", Box::new(full))];
    // A sample that fits the estimate exactly but for the residual `e_i` on row `i`.
    let shaped = |id: &dyn Identifier<f64>, xs: &[f64], e: [f64; 2]| {
        let mut theta = vec![0.0; 2 * N];
        id.params_into(&mut theta).unwrap();
        let mut zs = vec![0.0; N];
        for (i, &row) in ROWS.iter().enumerate() {
            zs[row] = (0..N).map(|a| theta[i * N + a] * xs[a]).sum::<f64>() + e[i];
        }
        zs
    };
    for (name, mut id) in modes {
        let mut scale = GateScale { kappa, r, ssr: [0.0; 2], nobs: 0.0 };
        for k in 0..300 {
            scale.step(&mut *id, &x[k * N..(k + 1) * N], &z[k * N..(k + 1) * N]);
        }
        let far: Vec<f64> = x[300 * N..301 * N].iter().map(|v| 20.0 * v).collect();
        let s_far = [s_row(&*id, &far, 0, &r), s_row(&*id, &far, 1, &r)];
        assert!(s_far[1] > 5.0, "{name}: the far sample's s = {s_far:?}");
        let zs = shaped(&*id, &far, [1e3 * (r[0] * s_far[0]).sqrt(), (2.0 * r[1] * s_far[1]).sqrt()]);
        assert!(scale.step(&mut *id, &far, &zs), "{name}: the far outlier is gated");
        for (k, i, factor, want) in
            [(301, 1, 1.03, true), (302, 1, 0.97, false), (303, 0, 1.03, true), (304, 0, 0.97, false)]
        {
            let xs = &x[k * N..(k + 1) * N];
            let mut e = [0.0; 2];
            e[i] = (factor * kappa * kappa * scale.sigma2(i) * s_row(&*id, xs, i, &r)).sqrt();
            let zs = shaped(&*id, xs, e);
            assert_eq!(scale.step(&mut *id, xs, &zs), want, "{name}: row {i} at {factor} κ² σ̂²");
        }
    }
}

/// Mode rows counts a gated sample in its residual statistics Winsorized at the gate
/// (`Identifier::residuals_into`, `KalmanOptions::gate`): `ssr ← λ ssr + κ² σ̂²` with
/// `σ̂² = ssr / (nobs − N)`, `nobs ← λ nobs + 1`, on the row that gated it; the other row
/// takes the sample. Every form, without forgetting and with `λ = 0.99`.
#[test]
fn mode_rows_counts_a_gated_sample_winsorized_at_the_gate() {
    let (x, clean) = data();
    let kappa = 4.0;
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        for lambda in [1.0, 0.99] {
            let opts = KalmanOptions { gate: kappa, form, forgetting: lambda, ..KalmanOptions::default() };
            let mut id = KalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[50.0], &[RV, RV], opts).unwrap();
            crate::common::feed(&mut id, &x[..300 * N], &clean[..300 * N]);
            let what = format!("{form:?}, λ = {lambda}");
            let (mut ssr, mut nobs, mut gated) = ([0.0; 2], [0.0; 2], [0u64; 2]);
            id.residuals_into(&mut ssr, &mut nobs).unwrap();
            id.gated_into(&mut gated).unwrap();
            let mut z = clean[300 * N..301 * N].to_vec();
            z[ROWS[0]] += 1e4 * RV.sqrt();
            id.update_into(&x[300 * N..301 * N], &z, &[], &mut [0.0; 2]).unwrap();
            let (mut ssr1, mut nobs1, mut gated1) = ([0.0; 2], [0.0; 2], [0u64; 2]);
            id.residuals_into(&mut ssr1, &mut nobs1).unwrap();
            id.gated_into(&mut gated1).unwrap();
            assert_eq!((gated1[0], gated1[1]), (gated[0] + 1, gated[1]), "{what}: gated on row 0 only");
            let want = lambda * ssr[0] + kappa * kappa * ssr[0] / (nobs[0] - N as f64);
            assert!((ssr1[0] - want).abs() <= 1e-12 * want, "{what}: ssr {} for {want}", ssr1[0]);
            assert!((nobs1[0] - (lambda * nobs[0] + 1.0)).abs() <= 1e-12 * nobs1[0], "{what}: nobs {}", nobs1[0]);
            assert!((nobs1[1] - (lambda * nobs[1] + 1.0)).abs() <= 1e-12 * nobs1[1], "{what}: row 1 took it");
        }
    }
}

/// A structure of the full rows, from the prior `p0 I`: ridge regression, its covariance and
/// residual sums; `form()` the form it was given.
#[test]
fn structured_kalman_honours_the_contract() {
    let (x, z) = data();
    let (p0, r) = (50.0, [RV, 4.0 * RV]);
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        let o = KalmanOptions { form, gate: 0.0, ..KalmanOptions::default() };
        let st = Structure::full_rows(N, &ROWS).unwrap();
        let id = StructuredKalmanVec::<f64, 8>::new(st, StructuredPrior::Scalar(p0), None, &r, o).unwrap();
        assert_eq!(id.form(), form);
        contract("structured", id, &x, &z, ridge_expect(&x, &z, p0, &r, true));
    }
}

/// The stochastic gradients keep no covariance; `theta_row(i)` is row `i` of the estimate,
/// `rows()` the rows, the gain's kind the one asked for; the cost per step is the count in
/// its docs (per row: N² + 4N multiplications, N² + 2N additions; one power).
#[test]
fn stochastic_gradients_honour_the_contract() {
    let (x, z) = data();
    let ex = || Expect {
        params: Check::Any,
        cov: Check::Unsupported,
        noise: Check::Unsupported,
        ssr: Check::Unsupported,
        reset: false,
    };
    let gain = Gain::of_kind(GainKind::Venter, 0.51, 0.99, 0.95);
    assert_eq!(gain.kind(), GainKind::Venter);
    assert_eq!(Gain::of_kind(GainKind::Ljung, 0.51, 0.99, 0.95), Gain::Ljung { lambda0: 0.99, lambda_init: 0.95 });
    assert_eq!(Gain::<f64>::of_kind(GainKind::Lyapunov, 0.51, 0.99, 0.95).kind(), GainKind::Lyapunov);
    let mut sg = StochasticGradientVec::<f64, N>::from_slices(&ROWS, gain, &[0.4], &[0.0], 1).unwrap();
    contract("gradient", sg.clone(), &x, &z, ex());
    assert_eq!(sg.rows(), &ROWS[..]);
    crate::common::feed(&mut sg, &x[..40 * N], &z[..40 * N]);
    let mut theta = [0.0; 8];
    sg.params_into(&mut theta).unwrap();
    for i in 0..2 {
        assert_eq!(sg.theta_row(i).as_slice(), &theta[i * N..(i + 1) * N]);
    }
    // Venter's gain after 40 steps: 40^(−0.51).
    assert!((sg.gamma() - 40f64.powf(-0.51)).abs() < 1e-12, "{}", sg.gamma());
    let c = sg.cost();
    assert_eq!((c.multiplications, c.additions, c.divisions, c.square_roots), (2 * (16 + 16), 2 * (16 + 8), 1, 0));
    let c1 = StochasticGradientVec::<f64, 3>::from_slices(&[0], gain, &[0.4], &[0.0], 1).unwrap().cost();
    assert_eq!((c1.multiplications, c1.additions), (9 + 12, 9 + 6));
    assert!(c.bytes > core::mem::size_of_val(&sg), "the heap rows are counted");

    let st = || Structure::full_rows(N, &ROWS).unwrap();
    let sgs = StructuredGradient::<f64, 8>::new(st(), Gain::Lyapunov, &[1.0], None, 1).unwrap();
    assert_eq!(sgs.structure(), &st());
    contract("structured gradient", sgs, &x, &z, ex());
}

/// The instrumental-variable family on the full rows: the same contract (their estimates are
/// checked against batch IV in their own tests; 600 samples of this car are far from
/// converged, for least squares too); `delay()` and `lags()` as built, the noise
/// estimator's structure and instrumental identifier the ones it was given.
#[test]
fn instrumental_variables_honour_the_contract() {
    let (x, z) = data();
    let ex = || Expect { params: Check::Any, cov: Check::Any, noise: Check::Any, ssr: Check::Any, reset: false };
    let iv = IvIdentifierVec::<f64, 8, 25>::full_rows(N, &ROWS, 2, StructuredPrior::Exact, &[1.0]).unwrap();
    assert_eq!((iv.delay(), iv.lags()), (2, 0));
    let iv = iv.with_lags(3).unwrap();
    assert_eq!((iv.delay(), iv.lags()), (2, 3));
    contract("iv", iv, &x, &z, ex());

    let ne = NoiseEstimatingBclsVec::<f64, 8>::full_rows(N, &ROWS, 2, 0).unwrap();
    assert_eq!(ne.structure(), &Structure::full_rows(N, &ROWS).unwrap());
    assert_eq!((ne.instrumental().delay(), ne.instrumental().lags()), (2, 0));
    // It estimates the states' noise: on noise-free states and few samples its estimate can
    // exceed what the data show (a typed Singular); noisy states, as it is meant for.
    let (xn, zn) = quarter(4000, 8.0, 7302);
    let ex_ne = Expect { cov: Check::Unsupported, ssr: Check::Unsupported, ..ex() };
    contract("noise estimating", ne, &xn, &zn, ex_ne);

    let bc = BiasCompensatedVec::<f64, 8>::new(Structure::full_rows(N, &ROWS).unwrap(), &[1e-6], &[], &[1.0]).unwrap();
    contract("bias compensated", bc, &x, &z, Expect { cov: Check::Unsupported, ssr: Check::Unsupported, ..ex() });
}

/// Fits of more equations than live on the stack (`FIT_STACK_EQUATIONS`): the innovations on
/// the heap, the estimate the least-squares one.
#[test]
fn fits_of_more_equations_than_the_stack_holds() {
    const M: usize = vehid_core::identify::FIT_STACK_EQUATIONS + 1;
    let rows: Vec<usize> = (0..M).collect();
    let (l, mut s) = (3 * M, 0x9e37_79b9_7f4a_7c15u64);
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let x: Vec<f64> = (0..l * M).map(|_| next()).collect();
    let a: Vec<f64> = (0..M * M).map(|_| next()).collect();
    let z: Vec<f64> = (0..l)
        .flat_map(|k| (0..M).map(|i| (0..M).map(|j| a[i * M + j] * x[k * M + j]).sum::<f64>()).collect::<Vec<_>>())
        .collect();
    let mut acc = LsAccumulator::<f64, M, Dynamic>::from_rows(&rows).unwrap();
    acc.fit(&Samples::new(M, 0, &x, &z, &[]).unwrap(), |_, _, e| {
        assert_eq!(e.len(), M);
        ControlFlow::Continue(())
    })
    .unwrap();
    let mut theta = vec![0.0; M * M];
    acc.params_into(&mut theta).unwrap();
    close("accumulator", "A", &theta, &a, 1e-8);
}

/// Ridge regression towards a prior mean `θ₀` with the prior `P_i(0)` given per row
/// (`blocks[i]`, `N × N`): `θ_i = (XᵀX/r_i + P_i⁻¹)⁻¹ (Xᵀz_i/r_i + P_i⁻¹ θ₀_i)`.
fn ridge_towards(x: &[f64], z: &[f64], blocks: &[DMatrix<f64>], theta0: &[f64], r: &[f64]) -> Vec<f64> {
    let (xm, zm) = design(x, z, &ROWS);
    let mut out = vec![];
    for i in 0..ROWS.len() {
        let pinv = blocks[i].clone().try_inverse().unwrap();
        let t0 = DVector::from_column_slice(&theta0[i * N..(i + 1) * N]);
        let a = xm.transpose() * &xm / r[i] + &pinv;
        let b = xm.transpose() * zm.column(i) / r[i] + pinv * t0;
        out.extend(a.lu().solve(&b).unwrap().iter());
    }
    out
}

/// `boxed_kalman` (what the Python bindings call) builds what each run-time spec asks for:
/// every mode with a prior mean and each kind of prior it takes (one value, one per row, a
/// matrix per row, the whole matrix) gives the ridge estimate towards the prior mean computed
/// here, the exact start least squares; and it refuses, naming the argument and the lengths,
/// a prior mean of the wrong length or with the exact start, the exact start outside mode
/// rows, a prior kind the mode does not take, and row matrices of the wrong length.
#[test]
fn boxed_kalman_builds_every_mode_from_a_run_time_spec() {
    use vehid_core::identify::{boxed_kalman, KalmanSpec, Mode, Prior};
    let (x, z) = data();
    let r = [RV, RV];
    let theta0: Vec<f64> = (0..8).map(|j| 3.0 * j as f64 - 10.0).collect();
    let spd = |i: usize| {
        let m = DMatrix::from_fn(N, N, |a, b| 0.3 * ((a + 2 * b + i) % 3) as f64);
        &m * m.transpose() + DMatrix::identity(N, N) * (0.5 + i as f64)
    };
    let blocks = [spd(0), spd(1)];
    let flat_blocks: Vec<f64> = blocks.iter().flat_map(|b| b.transpose().iter().copied().collect::<Vec<_>>()).collect();
    let whole = block_diag(&blocks);
    let spec = |mode, p0| KalmanSpec {
        rows: ROWS.to_vec(),
        p0,
        theta0: Some(theta0.clone()),
        r: r.to_vec(),
        mode,
        opts: KalmanOptions::default(),
    };
    let scalar = [DMatrix::identity(N, N) * 2.0, DMatrix::identity(N, N) * 2.0];
    let per_row = [DMatrix::identity(N, N) * 2.0, DMatrix::identity(N, N) * 0.7];
    let cases = [
        (Mode::Rows, Prior::PerRow(vec![2.0]), ridge_towards(&x, &z, &scalar, &theta0, &r)),
        (Mode::Rows, Prior::PerRow(vec![2.0, 0.7]), ridge_towards(&x, &z, &per_row, &theta0, &r)),
        (Mode::Rows, Prior::RowMatrices(flat_blocks.clone()), ridge_towards(&x, &z, &blocks, &theta0, &r)),
        (Mode::Rows, Prior::Full(whole.clone()), ridge_towards(&x, &z, &blocks, &theta0, &r)),
        (Mode::Shared, Prior::PerRow(vec![2.0]), ridge_towards(&x, &z, &scalar, &theta0, &r)),
        (Mode::Full, Prior::PerRow(vec![2.0, 0.7]), ridge_towards(&x, &z, &per_row, &theta0, &r)),
        (Mode::Full, Prior::Full(whole.clone()), ridge_towards(&x, &z, &blocks, &theta0, &r)),
    ];
    for (mode, p0, want) in cases {
        let what = format!("{mode:?} {p0:?}");
        let mut id = boxed_kalman::<f64, N>(&spec(mode, p0)).unwrap_or_else(|e| panic!("{what}: {e:?}"));
        let got = crate::common::run(id.as_mut(), &x, &z);
        close(&what, "θ", &got, &want, 1e-7);
    }
    // The exact start in the square-root form (in the standard form its first covariance,
    // from the first four of these strongly correlated samples, costs digits: 2e-6 of the
    // largest entry after 600 samples, 4e-4 after 40).
    let sqrt = KalmanOptions { form: CovarianceForm::Sqrt, ..KalmanOptions::default() };
    let exact = KalmanSpec { theta0: None, opts: sqrt, ..spec(Mode::Rows, Prior::Exact) };
    let got = crate::common::run(boxed_kalman::<f64, N>(&exact).unwrap().as_mut(), &x, &z);
    close("exact", "θ", &got, &ridge(&x, &z, f64::INFINITY, &r).0, 1e-7);
    // Rows beyond two are kept in wider lane groups: the same estimate.
    let three =
        KalmanSpec { rows: vec![0, 1, 3], theta0: None, r: vec![RV], ..spec(Mode::Rows, Prior::PerRow(vec![2.0])) };
    let mut id3 = boxed_kalman::<f64, N>(&three).unwrap();
    let th3 = crate::common::run(id3.as_mut(), &x, &z);
    let mut id2 = boxed_kalman::<f64, N>(&KalmanSpec { rows: vec![1, 3], ..three.clone() }).unwrap();
    let th2 = crate::common::run(id2.as_mut(), &x, &z);
    close("three rows", "θ of rows 1 and 3", &th3[N..], &th2, 1e-12);

    let arg = |s: &KalmanSpec<f64>| match boxed_kalman::<f64, N>(s) {
        Err(Error::InvalidArgument { arg, .. }) => arg.to_string(),
        Err(Error::Shape { arg, expected, got }) => format!("{arg} {expected} {got}"),
        other => panic!("{s:?}: {other:?}"),
    };
    let short = KalmanSpec { theta0: Some(theta0[..7].to_vec()), ..spec(Mode::Rows, Prior::PerRow(vec![2.0])) };
    assert_eq!(arg(&short), "theta0 8 7");
    assert_eq!(arg(&spec(Mode::Rows, Prior::Exact)), "theta0");
    // The exact start outside mode rows: the message names the mode asked for.
    for (mode, name) in [(Mode::Shared, "mode='shared'"), (Mode::Full, "mode='full'")] {
        match boxed_kalman::<f64, N>(&KalmanSpec { theta0: None, ..spec(mode, Prior::Exact) }) {
            Err(Error::InvalidArgument { arg: "p0", expected }) => assert!(expected.contains(name), "{expected}"),
            other => panic!("{name}: {other:?}"),
        }
    }
    // Mode full's noise: one value, one per row or the whole K × K matrix.
    let three_r =
        KalmanSpec { rows: vec![0, 1, 3], theta0: None, r: vec![RV; 4], ..spec(Mode::Full, Prior::PerRow(vec![2.0])) };
    assert_eq!(arg(&three_r), "r 9 4");
    assert_eq!(arg(&spec(Mode::Shared, Prior::Full(whole.clone()))), "p0");
    assert_eq!(arg(&spec(Mode::Full, Prior::RowMatrices(flat_blocks.clone()))), "p0");
    assert_eq!(arg(&spec(Mode::Rows, Prior::RowMatrices(flat_blocks[..31].to_vec()))), "p0 32 31");
}

/// Mode full refuses, naming the option, each option it does not implement (its docs:
/// retirement, the Joseph and square-root forms, Huber weighting, tracking), and takes the
/// same options at their defaults.
#[test]
fn mode_full_names_each_option_it_does_not_take() {
    let d = KalmanOptions::<f64>::default();
    let refused = [
        (KalmanOptions { retire_below: 1e-3, ..d }, "retire_below"),
        (KalmanOptions { form: CovarianceForm::Joseph, ..d }, "form"),
        (KalmanOptions { form: CovarianceForm::Sqrt, ..d }, "form"),
        (KalmanOptions { huber: 2.0, ..d }, "huber"),
    ];
    for (o, name) in refused {
        match FullKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[1.0], &[RV], o) {
            Err(Error::InvalidArgument { arg, .. }) => assert_eq!(arg, name),
            other => panic!("{name}: {other:?}"),
        }
    }
    let tracking =
        FullKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[1.0], &[RV], KalmanOptions { forgetting: 0.99, ..d });
    assert!(matches!(tracking, Err(Error::InvalidArgument { arg: "forgetting", .. })), "{tracking:?}");
    assert!(FullKalmanIdentifierVec::<f64, N>::from_slices(&ROWS, &[1.0], &[RV], d).is_ok());
}

//! Tests of the statistics: closed forms, textbook values, 60-digit references, hand-computed
//! regressions and CUSUMs, error cases.

use super::*;
use crate::Error;
use core::f64::consts::PI;

/// Relative difference, with `|b|` floored at the smallest normal number.
fn rel(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        libm::fabs(a - b) / libm::fabs(b).max(f64::MIN_POSITIVE)
    }
}

fn assert_rel(a: f64, b: f64, tol: f64, what: &str) {
    assert!(rel(a, b) <= tol, "{what}: {a:e} vs {b:e} (relative {:e} > {tol:e})", rel(a, b));
}

// ---------------------------------------------------------------------------------------
// Distributions: closed forms.

#[test]
fn df_one_is_cauchy() {
    for x in [-1e300, -1e12, -50.0, -3.0, -1.0, -0.2, -1e-9, 0.0, 1e-9, 0.2, 1.0, 3.0, 50.0, 1e12, 1e300] {
        // P(T > |x|) = atan(1/|x|)/π; near 0 the central part atan(|x|)/π.
        let ax = libm::fabs(x);
        let exact = if ax < 1.0 {
            if x < 0.0 {
                0.5 - libm::atan(ax) / PI
            } else {
                0.5 + libm::atan(ax) / PI
            }
        } else if x < 0.0 {
            libm::atan(1.0 / ax) / PI
        } else {
            1.0 - libm::atan(1.0 / ax) / PI
        };
        assert_rel(t_cdf(x, 1.0).unwrap(), exact, 4e-15, "Cauchy cdf");
    }
    for p in
        [1e-300, 1e-200, 1e-15, 1e-6, 0.01, 0.1, 0.25, 0.3, 0.45, 0.5 - 1e-12, 0.5 + 1e-12, 0.6, 0.8, 0.99, 1.0 - 1e-12]
    {
        // tan(π(p − ½)): −1/tan(πp) below ½, 1/tan(π(1 − p)) above (1 − p exact there).
        let exact = if (0.25..=0.75).contains(&p) {
            libm::tan(PI * (p - 0.5))
        } else if p < 0.5 {
            -1.0 / libm::tan(PI * p)
        } else {
            1.0 / libm::tan(PI * (1.0 - p))
        };
        assert_rel(t_ppf(p, 1.0).unwrap(), exact, 4e-15, "Cauchy ppf");
    }
}

#[test]
fn df_two_closed_forms() {
    for x in [-1e150, -1e6, -30.0, -2.0, -0.5, -1e-7, 1e-7, 0.5, 2.0, 30.0, 1e6] {
        let r = libm::sqrt(2.0 + x * x);
        // P(T > |x|) = ½(1 − |x|/√(2+x²)) = 1/((√(2+x²) + |x|)√(2+x²)).
        let tail = 1.0 / ((r + libm::fabs(x)) * r);
        let central = libm::fabs(x) / (2.0 * r);
        let exact = if x < 0.0 {
            tail
        } else if central < tail {
            0.5 + central
        } else {
            1.0 - tail
        };
        assert_rel(t_cdf(x, 2.0).unwrap(), exact, 4e-15, "df=2 cdf");
        assert_rel(t_sf(-x, 2.0).unwrap(), exact, 4e-15, "df=2 sf");
    }
    for p in [1e-300, 1e-20, 1e-8, 0.001, 0.025, 0.2, 0.3, 0.5 - 1e-10, 0.5 + 2e-16, 0.7, 0.975, 0.999, 1.0 - 1e-15] {
        let exact = (2.0 * p - 1.0) / libm::sqrt(2.0 * p * (1.0 - p));
        assert_rel(t_ppf(p, 2.0).unwrap(), exact, 4e-15, "df=2 ppf");
    }
}

#[test]
fn df_three_and_four_closed_forms() {
    for x in [-2.0, -1.0, -0.25, 0.25, 1.0, 2.0, 4.0] {
        // ν = 3: F = ½ + (atan(x/√3) + √3 x/(3 + x²))/π; ν = 4: F = ½ + x(x² + 6)/(2(x² + 4)^{3/2}).
        let s3 = libm::sqrt(3.0);
        let f3 = 0.5 + (libm::atan(x / s3) + s3 * x / (3.0 + x * x)) / PI;
        let f4 = 0.5 + x * (x * x + 6.0) / (2.0 * libm::pow(x * x + 4.0, 1.5));
        assert_rel(t_cdf(x, 3.0).unwrap(), f3, 1e-14, "df=3 cdf");
        assert_rel(t_cdf(x, 4.0).unwrap(), f4, 1e-14, "df=4 cdf");
        assert_rel(t_ppf(f3, 3.0).unwrap(), x, 1e-13, "df=3 ppf");
        assert_rel(t_ppf(f4, 4.0).unwrap(), x, 1e-13, "df=4 ppf");
    }
}

#[test]
fn normal_textbook_values() {
    // Φ⁻¹(0.975) = 1.959963984540054…, Φ⁻¹(0.995) = 2.5758293035489004…, Φ⁻¹(0.95) = 1.6448536269514722…
    assert_rel(normal_ppf(0.975).unwrap(), 1.959_963_984_540_054, 1e-15, "z 97.5%");
    assert_rel(normal_ppf(0.995).unwrap(), 2.575_829_303_548_900_4, 1e-15, "z 99.5%");
    assert_rel(normal_ppf(0.95).unwrap(), 1.644_853_626_951_472_2, 1e-15, "z 95%");
    assert_rel(normal_ppf(0.025).unwrap(), -1.959_963_984_540_054, 1e-15, "z 2.5%");
    // Φ(−1) = 0.158655253931457051…, 1 − Φ(3) = 0.00134989803163009452… (mpmath).
    assert_rel(normal_cdf(-1.0).unwrap(), 0.158_655_253_931_457_05, 1e-15, "Φ(−1)");
    assert_eq!(normal_cdf(0.0).unwrap(), 0.5);
    assert_rel(normal_sf(3.0).unwrap(), 0.001_349_898_031_630_094_6, 2e-15, "sf(3)"); // mpmath
                                                                                      // Tails: ppf(cdf(x)) = x.
    for x in [-37.0, -20.0, -8.0, -3.0, -1.0] {
        assert_rel(normal_ppf(normal_cdf(x).unwrap()).unwrap(), x, 2e-15, "normal round trip");
    }
}

// ---------------------------------------------------------------------------------------
// Distributions: 60-digit references for non-integer, large and infinite df.
//
// Generated with mpmath 1.3.0 at 60 digits by the script at the top of `tests_ref.rs`:
// `mp.betainc` for df ≤ 10⁴, the positive hypergeometric series at raised precision above (the
// two agree to the last bit on the CDF table), `mp.ncdf` for df = ∞; quantiles by bisection
// then Newton on those functions. Entries: (x or p, df, value).

include!("tests_ref.rs");

#[test]
fn cdf_matches_sixty_digit_references() {
    for (x, df, want) in CDF_REF {
        let got = t_cdf(x, df).unwrap();
        assert_rel(got, want, 1e-13, "t_cdf vs mpmath");
        assert_rel(t_sf(-x, df).unwrap(), want, 1e-13, "t_sf vs mpmath");
    }
}

#[test]
fn ppf_matches_sixty_digit_references() {
    for (p, df, want) in PPF_REF {
        let got = t_ppf(p, df).unwrap();
        if want.is_infinite() {
            assert_eq!(got, want, "ppf({p}, {df}) beyond f64");
        } else {
            assert_rel(got, want, 1e-13, "t_ppf vs mpmath");
        }
    }
}

/// The accuracy this module claims for a probability `p`: the exponential of a logarithm of
/// size `|ln p|` costs `ε |ln p|`, plus a few rounding errors.
fn tol_p(p: f64) -> f64 {
    1e-14 + 4.0 * f64::EPSILON * libm::fabs(libm::log(p))
}

#[test]
fn symmetry_and_round_trips() {
    for df in [0.05, 0.5, 1.0, 1.5, 3.7, 12.0, 99.5, 1e4, 1e8, 1e15, f64::INFINITY] {
        for x in [-1e5, -60.0, -9.0, -2.5, -1.0, -0.5] {
            let p = t_cdf(x, df).unwrap();
            // F(x) + F(−x) = 1 and the survival function mirrors the CDF.
            assert!(libm::fabs(p + t_cdf(-x, df).unwrap() - 1.0) <= f64::EPSILON);
            assert_eq!(t_sf(-x, df).unwrap(), p);
            if p > 0.0 {
                // x f(x)/F(x) ≈ ν in a heavy tail: an error δ in p moves x by δ/ν.
                let back = t_ppf(p, df).unwrap();
                if back.is_finite() {
                    assert_rel(back, x, tol_p(p) * (1.0 / df).max(1.0), "ppf(cdf(x))");
                }
            }
        }
        for p in [1e-250, 1e-30, 1e-5, 0.01, 0.2, 0.26, 0.4] {
            // ppf(1 − p) = −ppf(p) where 1 − p is exact enough (p ≥ 0.01).
            let lo = t_ppf(p, df).unwrap();
            if p >= 0.01 && lo.is_finite() {
                // (1 − p rounds: the quantile moves by that relative error over ν.)
                assert_rel(t_ppf(1.0 - p, df).unwrap(), -lo, 1e-14 * (1.0 / df).max(1.0), "ppf symmetry");
            }
            if lo.is_finite() {
                assert_rel(t_cdf(lo, df).unwrap(), p, 2.0 * tol_p(p), "cdf(ppf(p))");
            }
        }
    }
}

#[test]
fn huge_df_is_the_normal() {
    for x in [-30.0, -5.0, -1.0, 0.3, 2.0] {
        let z = normal_cdf(x).unwrap();
        assert_eq!(t_cdf(x, 1e31).unwrap(), z); // computed as the normal
                                                // (The two differ by x⁴/(4ν) < 1e-23; the bound is the exp-of-log error ε·|ln P|.)
        assert_rel(t_cdf(x, 1e29).unwrap(), z, 2e-13, "df = 1e29 vs normal");
        // ν = 10¹²: F_ν(x) = Φ(x) − φ(x)(x³ + x)/(4ν) + O(x⁷φ/ν²) (A&S 26.7.5's first term).
        let first_order = z - libm::exp(-0.5 * x * x) / libm::sqrt(2.0 * PI) * (x * x * x + x) / 4e12;
        assert_rel(t_cdf(x, 1e12).unwrap(), first_order, 2e-13, "df = 1e12 vs its expansion");
    }
    assert_rel(t_ppf(0.975, 1e29).unwrap(), 1.959_963_984_540_054, 1e-15, "df = 1e29 quantile");
}

#[test]
fn limits_and_infinities() {
    for df in [0.3, 1.0, 7.0, f64::INFINITY] {
        assert_eq!(t_cdf(f64::NEG_INFINITY, df).unwrap(), 0.0);
        assert_eq!(t_cdf(f64::INFINITY, df).unwrap(), 1.0);
        assert_eq!(t_cdf(0.0, df).unwrap(), 0.5);
        assert_eq!(t_ppf(0.0, df).unwrap(), f64::NEG_INFINITY);
        assert_eq!(t_ppf(1.0, df).unwrap(), f64::INFINITY);
        assert_eq!(t_ppf(0.5, df).unwrap(), 0.0);
    }
    // A quantile beyond f64::MAX: ν = 0.1 and p = 1e-100 (x ≈ −10^{1000}).
    assert_eq!(t_ppf(1e-100, 0.1).unwrap(), f64::NEG_INFINITY);
}

#[test]
fn distribution_errors() {
    for df in [0.0, -1.0, f64::NAN, f64::NEG_INFINITY] {
        assert!(matches!(t_cdf(1.0, df), Err(Error::InvalidArgument { arg: "df", .. })), "{df}");
        assert!(matches!(t_ppf(0.3, df), Err(Error::InvalidArgument { arg: "df", .. })), "{df}");
    }
    assert_eq!(t_cdf(f64::NAN, 3.0), Err(Error::NonFinite { arg: "x", index: 0 }));
    assert_eq!(normal_sf(f64::NAN), Err(Error::NonFinite { arg: "x", index: 0 }));
    assert_eq!(t_ppf(f64::NAN, 3.0), Err(Error::NonFinite { arg: "p", index: 0 }));
    for p in [-1e-300, 1.0 + f64::EPSILON, f64::INFINITY] {
        assert!(matches!(normal_ppf(p), Err(Error::InvalidArgument { arg: "p", .. })), "{p}");
    }
}

// ---------------------------------------------------------------------------------------
// OLS summary.

/// A straight line `y = θ₀ + θ₁ x` through `(0,0), (1,1), (2,3), (3,2)`, fitted by hand:
/// `XᵀX = [[4, 6], [6, 14]]`, `(XᵀX)⁻¹ = [[0.7, −0.3], [−0.3, 0.2]]`, `Xᵀy = (6, 13)`,
/// `θ = (0.3, 0.8)`, residuals `(−0.3, −0.1, 1.1, −0.7)`, `ssr = 1.8`, `df_resid = 2`,
/// `σ² = 0.9`, and the slope's variance `σ²/Σ(x − x̄)² = 0.9/5 = 0.18`.
fn line_fit() -> ([f64; 2], [f64; 4], f64) {
    let (xs, ys) = ([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 3.0, 2.0]);
    let (n, sx, sxx) = (4.0, xs.iter().sum::<f64>(), xs.iter().map(|x| x * x).sum::<f64>());
    let (sy, sxy) = (ys.iter().sum::<f64>(), xs.iter().zip(&ys).map(|(x, y)| x * y).sum::<f64>());
    let det = n * sxx - sx * sx;
    let inv = [sxx / det, -sx / det, -sx / det, n / det];
    let theta = [inv[0] * sy + inv[1] * sxy, inv[2] * sy + inv[3] * sxy];
    let ssr = xs.iter().zip(&ys).map(|(x, y)| (y - theta[0] - theta[1] * x) * (y - theta[0] - theta[1] * x)).sum();
    (theta, inv, ssr)
}

#[test]
fn straight_line_by_hand() {
    let (theta, inv, ssr) = line_fit();
    assert!((theta[0] - 0.3).abs() < 1e-15 && (theta[1] - 0.8).abs() < 1e-15);
    assert!((ssr - 1.8).abs() < 1e-14);
    let (mut bse, mut tv, mut pv, mut ci, mut cov) = ([0.0; 2], [0.0; 2], [0.0; 2], [[0.0; 2]; 2], [0.0; 4]);
    let out =
        SummaryBuffers { bse: &mut bse, tvalues: &mut tv, pvalues: &mut pv, conf_int: &mut ci, cov_params: &mut cov };
    let s = summary_into(&theta, &inv, ssr, 4.0, 0.05, out).unwrap();
    assert_eq!(s.df_resid, 2.0);
    assert_rel(s.sigma2, 0.9, 1e-14, "sigma2");
    assert_rel(bse[1], libm::sqrt(0.18), 1e-14, "slope bse = √(σ²/Σ(x−x̄)²)");
    assert_rel(bse[0], libm::sqrt(0.9 * 0.7), 1e-14, "intercept bse");
    assert_rel(cov[1], -0.27, 1e-14, "cov_params off-diagonal");
    // t.ppf(0.975, 2) = (2p − 1)/√(2p(1 − p)) = 4.302652729696144.
    let q = 0.95 / libm::sqrt(2.0 * 0.975 * 0.025);
    assert_rel(s.t_crit, q, 1e-14, "t_crit");
    assert_rel(ci[1][0], 0.8 - q * libm::sqrt(0.18), 1e-14, "slope lower");
    assert_rel(ci[1][1], 0.8 + q * libm::sqrt(0.18), 1e-14, "slope upper");
    // p-value with ν = 2: 2 P(T > t) = 2/((√(2+t²) + t)√(2+t²)).
    let t1 = 0.8 / libm::sqrt(0.18);
    let r = libm::sqrt(2.0 + t1 * t1);
    assert_rel(tv[1], t1, 1e-14, "slope t");
    assert_rel(pv[1], 2.0 / ((r + t1) * r), 1e-14, "slope p");
    // Eigenvalues of XᵀX are 9 ± √61.
    let cond = libm::sqrt((9.0 + libm::sqrt(61.0)) / (9.0 - libm::sqrt(61.0)));
    assert_rel(s.condition_number, cond, 1e-14, "condition number");
    let mut scratch = [0.0; 4];
    assert_rel(condition_number(&inv, &mut scratch).unwrap(), cond, 1e-14, "condition_number()");
}

#[test]
fn three_points_with_one_residual_degree_of_freedom() {
    // The doc example: (0,0), (1,1), (2,3); with ν = 1 everything is Cauchy.
    let (theta, inv, ssr, nobs) = ([-1.0 / 6.0, 1.5], [5.0 / 6.0, -0.5, -0.5, 0.5], 1.0 / 6.0, 3.0);
    let (mut bse, mut tv, mut pv, mut ci, mut cov) = ([0.0; 2], [0.0; 2], [0.0; 2], [[0.0; 2]; 2], [0.0; 4]);
    let out =
        SummaryBuffers { bse: &mut bse, tvalues: &mut tv, pvalues: &mut pv, conf_int: &mut ci, cov_params: &mut cov };
    let s = summary_into(&theta, &inv, ssr, nobs, 0.1, out).unwrap();
    assert_rel(s.t_crit, 1.0 / libm::tan(PI * 0.05), 1e-14, "t.ppf(0.95, 1) = cot(π/20)");
    // Slope: bse = √(1/12), t = 3√3, p = 2 atan(1/t)/π; intercept: t = −1/√5, p = 2 atan(√5)/π.
    assert_rel(tv[1], 3.0 * libm::sqrt(3.0), 1e-14, "slope t");
    assert_rel(pv[1], 2.0 * libm::atan(1.0 / (3.0 * libm::sqrt(3.0))) / PI, 1e-14, "slope p");
    assert_rel(tv[0], -1.0 / libm::sqrt(5.0), 1e-14, "intercept t");
    assert_rel(pv[0], 2.0 * libm::atan(libm::sqrt(5.0)) / PI, 1e-14, "intercept p");
}

#[cfg(feature = "alloc")]
#[test]
fn summary_struct_equals_the_buffer_form() {
    let (theta, inv, ssr) = line_fit();
    let s = Summary::new(&theta, &inv, ssr, 4.0, 0.01).unwrap();
    let (mut bse, mut tv, mut pv, mut ci, mut cov) = ([0.0; 2], [0.0; 2], [0.0; 2], [[0.0; 2]; 2], [0.0; 4]);
    let out =
        SummaryBuffers { bse: &mut bse, tvalues: &mut tv, pvalues: &mut pv, conf_int: &mut ci, cov_params: &mut cov };
    let r = summary_into(&theta, &inv, ssr, 4.0, 0.01, out).unwrap();
    assert_eq!(
        (s.k(), s.params.as_slice(), s.bse.as_slice(), s.tvalues.as_slice()),
        (2, &theta[..], &bse[..], &tv[..])
    );
    assert_eq!((s.pvalues.as_slice(), s.conf_int.as_slice(), s.cov_params.as_slice()), (&pv[..], &ci[..], &cov[..]));
    assert_eq!((s.sigma2, s.df_resid, s.nobs, s.alpha, s.t_crit), (r.sigma2, r.df_resid, r.nobs, r.alpha, r.t_crit));
    assert_eq!(s.condition_number, r.condition_number);
    // A 99 % interval is wider than a 95 % one.
    let s95 = Summary::new(&theta, &inv, ssr, 4.0, 0.05).unwrap();
    assert!(s.conf_int[1][1] - s.conf_int[1][0] > s95.conf_int[1][1] - s95.conf_int[1][0]);
}

#[cfg(feature = "alloc")]
#[test]
fn fractional_nobs_and_a_perfect_fit() {
    let (theta, inv, _) = line_fit();
    // Effective sample size 2.5 with k = 2: half a residual degree of freedom.
    let s = Summary::new(&theta, &inv, 1.8, 2.5, 0.05).unwrap();
    assert_eq!(s.df_resid, 0.5);
    assert_rel(s.sigma2, 3.6, 1e-15, "sigma2");
    assert!(s.t_crit > 100.0 && s.t_crit.is_finite());
    // ssr = 0: zero standard errors, infinite t, zero p (statsmodels gives the same).
    let s = Summary::new(&theta, &inv, 0.0, 4.0, 0.05).unwrap();
    assert_eq!((s.bse[1], s.tvalues[1], s.pvalues[1]), (0.0, f64::INFINITY, 0.0));
    assert_eq!(s.conf_int[1], [theta[1], theta[1]]);
}

#[test]
fn summary_errors() {
    let (theta, inv, ssr) = line_fit();
    let mut b = ([0.0; 2], [0.0; 2], [0.0; 2], [[0.0; 2]; 2], [0.0; 4]);
    let mut run = |params: &[f64], cov: &[f64], ssr: f64, nobs: f64, alpha: f64| {
        let (bse, tv, pv, ci, cp) = (&mut b.0, &mut b.1, &mut b.2, &mut b.3, &mut b.4);
        let out = SummaryBuffers { bse, tvalues: tv, pvalues: pv, conf_int: ci, cov_params: cp };
        summary_into(params, cov, ssr, nobs, alpha, out)
    };
    assert!(matches!(run(&theta, &inv, ssr, 2.0, 0.05), Err(Error::InvalidArgument { arg: "nobs", .. })));
    assert!(matches!(run(&theta, &inv, ssr, 1.5, 0.05), Err(Error::InvalidArgument { arg: "nobs", .. })));
    assert_eq!(run(&theta, &inv, ssr, f64::NAN, 0.05), Err(Error::NonFinite { arg: "nobs", index: 0 }));
    assert_eq!(run(&[0.3, f64::NAN], &inv, ssr, 4.0, 0.05), Err(Error::NonFinite { arg: "params", index: 1 }));
    assert_eq!(
        run(&theta, &[0.7, -0.3, f64::INFINITY, 0.2], ssr, 4.0, 0.05),
        Err(Error::NonFinite { arg: "cov_unscaled", index: 2 })
    );
    assert!(matches!(run(&theta, &inv, -1.0, 4.0, 0.05), Err(Error::InvalidArgument { arg: "ssr", .. })));
    for alpha in [0.0, 1.0, -0.1, f64::NAN] {
        assert!(matches!(run(&theta, &inv, ssr, 4.0, alpha), Err(Error::InvalidArgument { arg: "alpha", .. })));
    }
    assert!(matches!(
        run(&theta, &[0.7, -0.3, 0.3, 0.2], ssr, 4.0, 0.05),
        Err(Error::InvalidArgument { arg: "cov_unscaled", .. })
    ));
    // Indefinite (eigenvalues 3 and −1) and a non-positive diagonal.
    assert!(matches!(run(&theta, &[1.0, 2.0, 2.0, 1.0], ssr, 4.0, 0.05), Err(Error::Singular { .. })));
    assert!(matches!(run(&theta, &[0.0, 0.0, 0.0, 1.0], ssr, 4.0, 0.05), Err(Error::Singular { .. })));
    assert_eq!(run(&theta, &inv[..3], ssr, 4.0, 0.05), Err(Error::Shape { arg: "cov_unscaled", expected: 4, got: 3 }));
    assert!(matches!(run(&[], &[], ssr, 4.0, 0.05), Err(Error::InvalidArgument { arg: "params", .. })));
    let (mut bse, mut tv, mut pv, mut ci, mut cov) = ([0.0; 3], [0.0; 2], [0.0; 2], [[0.0; 2]; 2], [0.0; 4]);
    let out =
        SummaryBuffers { bse: &mut bse, tvalues: &mut tv, pvalues: &mut pv, conf_int: &mut ci, cov_params: &mut cov };
    assert_eq!(summary_into(&theta, &inv, ssr, 4.0, 0.05, out), Err(Error::Shape { arg: "bse", expected: 2, got: 3 }));
    let mut scratch = [0.0; 3];
    assert!(matches!(condition_number(&inv, &mut scratch), Err(Error::Shape { arg: "scratch", .. })));
    assert!(matches!(condition_number(&inv[..3], &mut scratch), Err(Error::Shape { arg: "cov_unscaled", .. })));
    // The message says what is missing.
    let e = run(&theta, &inv, ssr, 2.0, 0.05).unwrap_err();
    assert!(alloc_free_contains(&e, "no residual"));
}

/// Whether the error's message contains `needle` (without `alloc`: a fixed buffer).
fn alloc_free_contains(e: &Error, needle: &str) -> bool {
    struct Buf([u8; 512], usize);
    impl core::fmt::Write for Buf {
        fn write_str(&mut self, s: &str) -> core::fmt::Result {
            let end = (self.1 + s.len()).min(self.0.len());
            self.0[self.1..end].copy_from_slice(&s.as_bytes()[..end - self.1]);
            self.1 = end;
            Ok(())
        }
    }
    let mut b = Buf([0; 512], 0);
    core::fmt::write(&mut b, format_args!("{e}")).unwrap();
    core::str::from_utf8(&b.0[..b.1]).unwrap().contains(needle)
}

// ---------------------------------------------------------------------------------------
// CUSUM.

#[test]
fn brown_durbin_evans_constants_solve_their_equation() {
    // Q(3a) + exp(−4a²)(1 − Q(a)) = α/2 (Brown, Durbin & Evans 1975, p. 154), Q = normal upper tail.
    let level = |a: f64| 2.0 * (normal_sf(3.0 * a).unwrap() + libm::exp(-4.0 * a * a) * normal_cdf(a).unwrap());
    for (alpha, a) in CUSUM_SCALARS {
        // The constants are given to three decimals.
        assert!(rel(level(a), alpha) < 0.01, "a = {a}: level {} for alpha {alpha}", level(a));
    }
    // statsmodels' 0.950 for α = 10 % solves it for α ≈ 5 % instead.
    assert!((0.045..0.051).contains(&level(0.950)), "{}", level(0.950));
}

#[test]
fn cusum_of_a_hand_made_sequence() {
    // w = (1, −1, 2, 0, 3): mean 1, deviations (0, −2, 1, −1, 2), Σ dev² = 10,
    // σ̂² = 10/(5 − 1) = 2.5; cumulative sums (1, 0, 2, 2, 5); squares (1, 1, 4, 0, 9) → (1, 2, 6, 6, 15).
    let w = [1.0, -1.0, 2.0, 0.0, 3.0];
    let mut out = [0.0; 5];
    let sigma = cusum_into(&w, &mut out).unwrap();
    assert_rel(sigma, libm::sqrt(2.5), 1e-15, "sigma (ddof = 1)");
    for (got, cum) in out.iter().zip([1.0, 0.0, 2.0, 2.0, 5.0]) {
        assert!(libm::fabs(got - cum / libm::sqrt(2.5)) <= 1e-15 * 5.0, "{got}");
    }
    cusum_squares_into(&w, &mut out).unwrap();
    for (got, cum) in out.iter().zip([1.0, 2.0, 6.0, 6.0, 15.0]) {
        assert_rel(*got, cum / 15.0, 1e-15, "cusum of squares");
    }
    assert_eq!(out[4], 1.0);
    // Bounds: a√m + 2aj/√m with a = 0.948, m = 5; from a√m at j = 0 to 3a√m at j = m.
    let a = 0.948;
    assert_rel(cusum_bound(0.05, 5, 0.0).unwrap(), a * libm::sqrt(5.0), 1e-15, "start");
    assert_rel(cusum_bound(0.05, 5, 5.0).unwrap(), 3.0 * a * libm::sqrt(5.0), 1e-15, "end");
    assert_rel(cusum_bound(0.05, 5, 2.0).unwrap(), a * libm::sqrt(5.0) + 4.0 * a / libm::sqrt(5.0), 1e-15, "j = 2");
    assert_rel(cusum_bound(0.10, 5, 0.0).unwrap(), 0.850 * libm::sqrt(5.0), 1e-15, "10 %");
    // Edgerton & Wells at α = 5 % (their column α/2 = 0.025): N = 5/2 − 1 = 1.5.
    let n: f64 = 1.5;
    let c0 = 1.3581015 / libm::sqrt(n) - 0.6701218 / n - 0.8858694 / (n * libm::sqrt(n));
    assert_rel(cusum_squares_critical(0.05, 5).unwrap(), c0, 1e-15, "c0");
    let [lo, hi] = cusum_squares_bounds(0.05, 5, 2.0).unwrap();
    assert_rel(lo, 0.4 - c0, 1e-15, "lower");
    assert_rel(hi, 0.4 + c0, 1e-15, "upper");
    // α = 0.2 and 0.02 exist for the CUSUM of squares only.
    assert!(cusum_squares_critical(0.2, 5).unwrap() < cusum_squares_critical(0.02, 5).unwrap());
}

#[test]
fn cusum_is_scale_invariant_and_safe_from_overflow() {
    let w = [0.3, -1.2, 0.7, 2.2, -0.4, 0.05, 1.1];
    let (mut a, mut b) = ([0.0; 7], [0.0; 7]);
    let sa = cusum_into(&w, &mut a).unwrap();
    for scale in [3.7, 1e-200, 1e250] {
        let ws: [f64; 7] = core::array::from_fn(|i| w[i] * scale);
        let sb = cusum_into(&ws, &mut b).unwrap();
        assert_rel(sb, sa * scale, 1e-14, "sigma scales");
        for (x, y) in a.iter().zip(&b) {
            assert!(libm::fabs(x - y) <= 1e-14 * libm::fabs(*x).max(1.0));
        }
        cusum_squares_into(&w, &mut a).unwrap();
        cusum_squares_into(&ws, &mut b).unwrap();
        for (x, y) in a.iter().zip(&b) {
            assert_rel(*y, *x, 1e-14, "cusum of squares invariant");
        }
        cusum_into(&w, &mut a).unwrap();
    }
}

#[test]
fn cusum_errors() {
    let mut out = [0.0; 4];
    assert_eq!(cusum_into(&[1.0], &mut out[..1]), Err(Error::Shape { arg: "w", expected: 2, got: 1 }));
    assert_eq!(cusum_into(&[1.0, 2.0], &mut out[..3]), Err(Error::Shape { arg: "out", expected: 2, got: 3 }));
    assert!(matches!(cusum_into(&[2.0, 2.0, 2.0], &mut out[..3]), Err(Error::InvalidArgument { arg: "w", .. })));
    assert_eq!(cusum_into(&[1.0, f64::NAN], &mut out[..2]), Err(Error::NonFinite { arg: "w", index: 1 }));
    assert!(matches!(cusum_squares_into(&[0.0, 0.0], &mut out[..2]), Err(Error::InvalidArgument { arg: "w", .. })));
    assert_eq!(cusum_squares_into(&[], &mut out[..0]), Err(Error::Shape { arg: "w", expected: 1, got: 0 }));
    for alpha in [0.2, 0.025, 0.0, f64::NAN] {
        assert!(matches!(cusum_scalar(alpha), Err(Error::InvalidArgument { arg: "alpha", .. })), "{alpha}");
    }
    for alpha in [0.025, 0.5, f64::NAN] {
        assert!(matches!(cusum_squares_critical(alpha, 10), Err(Error::InvalidArgument { arg: "alpha", .. })));
    }
    assert_eq!(cusum_squares_critical(0.05, 2), Err(Error::Shape { arg: "w", expected: 3, got: 2 }));
    assert!(matches!(cusum_bound(0.05, 0, 0.0), Err(Error::InvalidArgument { arg: "m", .. })));
    assert!(matches!(cusum_bound(0.05, 4, f64::NAN), Err(Error::NonFinite { arg: "j", .. })));
    // A computed level is accepted.
    assert_eq!(cusum_scalar(1.0 - 0.95).unwrap(), 0.948);
}

#[cfg(feature = "alloc")]
#[test]
fn cusum_struct_detects_a_break_in_mean_and_in_variance() {
    // A deterministic "noise": a fixed pattern of ±1-ish values.
    let noise = |i: usize| [0.9, -1.1, 0.4, -0.2, 1.3, -0.8, -0.5, 0.6, 1.0, -0.7][i % 10];
    let stable: alloc::vec::Vec<f64> = (0..100).map(noise).collect();
    let c = Cusum::new(&stable, 0.05).unwrap();
    assert_eq!((c.len(), c.first_cusum_crossing(), c.first_cusum_squares_crossing()), (100, None, None));
    // The bounds belong to j = i + 1, ending at 3a√m.
    assert_rel(c.cusum_bound[99], 3.0 * 0.948 * 10.0, 1e-15, "last bound");
    assert_eq!(c.cusum_squares_bounds[99], [1.0 - c.critical, 1.0 + c.critical]);
    // The recursive residuals get a mean after a parameter change at sample 50.
    let shifted: alloc::vec::Vec<f64> = (0..100).map(|i| noise(i) + if i >= 50 { 1.5 } else { 0.0 }).collect();
    let c = Cusum::new(&shifted, 0.05).unwrap();
    assert!(c.first_cusum_crossing().is_some_and(|i| i > 50), "{:?}", c.first_cusum_crossing());
    // The noise variance grows tenfold at sample 50.
    let louder: alloc::vec::Vec<f64> = (0..100).map(|i| noise(i) * if i >= 50 { 10.0 } else { 1.0 }).collect();
    let c = Cusum::new(&louder, 0.05).unwrap();
    // (The quiet first half already lies below the lower bound j/m − c₀.)
    assert!(c.first_cusum_squares_crossing().is_some_and(|i| i < 50), "{:?}", c.first_cusum_squares_crossing());
    // Levels without a CUSUM constant are refused.
    assert!(matches!(Cusum::new(&stable, 0.2), Err(Error::InvalidArgument { arg: "alpha", .. })));
}

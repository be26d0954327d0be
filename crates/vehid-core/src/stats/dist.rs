//! Student's t and the normal distribution: CDF, survival function, quantile (scipy.stats'
//! `t.cdf`, `t.sf`, `t.ppf`, `norm.cdf`, `norm.sf`, `norm.ppf`).
//!
//! Student's t with `ν` degrees of freedom (any real `ν > 0`; `ν = ∞` is the normal) through
//! the regularized incomplete beta function (DLMF 8.17.2, Abramowitz & Stegun 26.7.1):
//! for `t ≥ 0`, with `x = ν/(ν + t²)` and `y = t²/(ν + t²)`,
//! - the tail `P(T > t) = ½ I_x(ν/2, ½)` (continued fraction, used when `y (ν/2 + 5/2) > 3/2`),
//! - the central part `P(0 < T ≤ t) = ½ I_y(½, ν/2)` (positive series, used otherwise),
//!
//! the other one being `½ −` the computed one; each is computed where it is the smaller, so
//! both the CDF and the survival function keep their relative accuracy far into the tails.
//! The normal uses `erfc` / `erf` (`Φ(x) = ½ erfc(−x/√2)`). Quantiles solve the same
//! functions by Newton's method inside a bisection bracket (the tail on a log scale).
//!
//! Accuracy, over `ν` from 1e-2 to 1e31 and probabilities down to 1e-300 (the tests, against
//! scipy and against 50-digit mpmath alone; tables from `benches/stats_reference.py`): a
//! probability `P` (CDF or survival function) to a relative `1e-14 + 4ε|ln P|`, the price of an
//! exponential of a number of size `|ln P|` (at most half of that bound where measured: 1.4e-13
//! at `P = 3e-124`, `ν = 1e13`), and a quantile to a relative 1e-13 (4.3e-14 measured).
//! (A probability below the smallest normal number, 2.2e-308, is subnormal: fewer significant bits.)
//! For `ν > 10³⁰` the normal is used:
//! the two differ there by a relative `≈ x⁴/(4ν) < 10⁻²⁴` wherever the normal tail is
//! representable.

use super::beta::{ibeta_fraction, ibeta_series, power_terms, stirling_delta, LN_SQRT_2PI};
use crate::{Error, Result};

/// Above this many degrees of freedom Student's t is computed as the normal.
const NU_NORMAL: f64 = 1e30;

/// Below this `|t|` the central probability is `f(0)·t` (the next term is `O(t³)`, 1e-200 relative).
const T_SMALL: f64 = 1e-100;

/// Above this `|t|` the tail is its leading power law (the next term is `O(ν²/t²)`).
const T_LARGE: f64 = 1e100;

/// `ln f(0)` of Student's t with `ν = 2a` degrees of freedom:
/// `ln Γ(a + ½) − ln Γ(a) − ½ ln(2π a)`, written through Stirling's remainder so that it
/// stays accurate for large `a`: `a·ln(1 + 1/(2a)) − ½ + δ(a + ½) − δ(a) − ln √(2π)`.
fn ln_density_at_zero(a: f64) -> f64 {
    a * libm::log1p(0.5 / a) - 0.5 + stirling_delta(a + 0.5) - stirling_delta(a) - LN_SQRT_2PI
}

/// `P(T > t)` and `P(0 < T ≤ t)` for `t ≥ 0` (not NaN), and whether the central part was
/// the one computed directly (the other is `½ −` it).
#[derive(Debug, Clone, Copy)]
struct Parts {
    tail: f64,
    central: f64,
    central_direct: bool,
}

fn tail_direct(tail: f64) -> Parts {
    Parts { tail, central: 0.5 - tail, central_direct: false }
}

fn central_direct(central: f64) -> Parts {
    Parts { tail: 0.5 - central, central, central_direct: true }
}

/// Splits the probability mass of `|T| ≥ 0` at `t ≥ 0` (see the module comment).
fn parts(t: f64, nu: f64) -> Parts {
    if t == f64::INFINITY {
        return tail_direct(0.0);
    }
    if nu > NU_NORMAL {
        let z = t * core::f64::consts::FRAC_1_SQRT_2;
        return if t < 1.0 { central_direct(0.5 * libm::erf(z)) } else { tail_direct(0.5 * libm::erfc(z)) };
    }
    let a = 0.5 * nu;
    if t < T_SMALL {
        return central_direct(libm::exp(ln_density_at_zero(a)) * t);
    }
    if t > T_LARGE {
        // P(T > t) = f(0) ν^{(ν−1)/2} t^{−ν} (1 + O(ν²/t²)) = f(0) (√ν/t)^ν / √ν, the power
        // taken directly (an exp of its logarithm would lose ε·|ln P|).
        let root = libm::sqrt(nu);
        return tail_direct(libm::exp(ln_density_at_zero(a)) * libm::pow(root / t, nu) / root);
    }
    let t2 = t * t;
    let s = nu + t2;
    let (x, y) = (nu / s, t2 / s);
    if y * (a + 2.5) > 1.5 {
        // ½ I_x(a, ½) = ½ (x^a y^½ / B) / F.
        tail_direct(0.5 * power_terms(a, 0.5, x, y) / ibeta_fraction(a, 0.5, x, y))
    } else {
        // ½ I_y(½, a) = ½ (y^½ x^a / (½ B)) S.
        central_direct(power_terms(0.5, a, y, x) * ibeta_series(0.5, a, y))
    }
}

/// The density at `t ≥ 0`.
fn density(t: f64, nu: f64) -> f64 {
    if nu > NU_NORMAL {
        return libm::exp(-0.5 * t * t - LN_SQRT_2PI);
    }
    let a = 0.5 * nu;
    // ln(1 + t²/ν), without overflow of t².
    let l = if t > T_LARGE { 2.0 * libm::log(t) - libm::log(nu) } else { libm::log1p(t * t / nu) };
    libm::exp(ln_density_at_zero(a) - (a + 0.5) * l)
}

fn check_df(df: f64) -> Result<()> {
    if df > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidArgument {
            arg: "df",
            expected: "degrees of freedom > 0 (any real number; f64::INFINITY for the normal)",
        })
    }
}

fn check_x(x: f64) -> Result<()> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(Error::NonFinite { arg: "x", index: 0 })
    }
}

/// The CDF `P(T ≤ x)` of Student's t with `df` degrees of freedom (scipy `stats.t.cdf(x, df)`;
/// `½ I_{ν/(ν+x²)}(ν/2, ½)` for `x < 0`, DLMF 8.17.2 / A&S 26.7.1). Dimensionless.
///
/// `df` is any real number > 0; `f64::INFINITY` gives the normal. Relative error below
/// `1e-14 + 4ε|ln P|` (module documentation).
///
/// # Errors
/// [`Error::InvalidArgument`] for `df` ≤ 0 or NaN; [`Error::NonFinite`] for a NaN or infinite `x`.
///
/// # Examples
/// ```
/// use vehid_core::stats::t_cdf;
/// // One degree of freedom is the Cauchy distribution: F(1) = ½ + atan(1)/π = ¾.
/// assert!((t_cdf(1.0, 1.0)? - 0.75).abs() < 1e-15);
/// # Ok::<(), vehid_core::Error>(())
/// ```
pub fn t_cdf(x: f64, df: f64) -> Result<f64> {
    check_df(df)?;
    check_x(x)?;
    let p = parts(libm::fabs(x), df);
    Ok(if x < 0.0 {
        p.tail
    } else if p.central_direct {
        0.5 + p.central
    } else {
        1.0 - p.tail
    })
}

/// The survival function `P(T > x) = 1 − F(x) = F(−x)` of Student's t (scipy
/// `stats.t.sf(x, df)`), accurate where `1 − F(x)` would cancel (a two-sided p-value is
/// `2 t_sf(|t|, df)`).
///
/// # Errors
/// As [`t_cdf`].
pub fn t_sf(x: f64, df: f64) -> Result<f64> {
    t_cdf(-x, df)
}

/// The quantile (inverse CDF) of Student's t: the `x` with `P(T ≤ x) = p` (scipy
/// `stats.t.ppf(p, df)`).
///
/// `p` lies in the open interval `(0, 1)` (the quantiles of 0 and 1 are `∓∞`; scipy returns
/// them, this function reports the argument). A quantile beyond `f64::MAX` (only for `df` well
/// below 1 and `p` near 0 or 1) is returned as `±∞`. For an upper-tail probability `q` too small
/// to survive `1 − q`, use the symmetry `−t_ppf(q, df)`. Relative error below 1e-13.
///
/// Method: Newton's method inside a bracket that bisection keeps, on the central probability
/// `P(0 < T ≤ x) = |p − ½|` for `p ∈ (¼, ¾)` (exact in floating point there) and on
/// `ln P(T > |x|) = ln min(p, 1 − p)` (in `ln x`) beyond.
///
/// # Errors
/// [`Error::InvalidArgument`] for `p` outside `(0, 1)` or `df` ≤ 0; [`Error::NonFinite`] for
/// a NaN `p`.
///
/// # Examples
/// ```
/// use vehid_core::stats::t_ppf;
/// // Two degrees of freedom have a closed form: x = (2p − 1)/√(2p(1 − p)).
/// let p: f64 = 0.975;
/// let exact = (2.0 * p - 1.0) / (2.0 * p * (1.0 - p)).sqrt();
/// assert!((t_ppf(p, 2.0)? / exact - 1.0).abs() < 1e-13);
/// # Ok::<(), vehid_core::Error>(())
/// ```
pub fn t_ppf(p: f64, df: f64) -> Result<f64> {
    if p.is_nan() {
        return Err(Error::NonFinite { arg: "p", index: 0 });
    }
    if !(p > 0.0 && p < 1.0) {
        return Err(Error::InvalidArgument {
            arg: "p",
            expected: "a probability in the open interval (0, 1) (the quantiles of 0 and 1 are infinite)",
        });
    }
    check_df(df)?;
    if p == 0.5 {
        return Ok(0.0);
    }
    let sign = if p < 0.5 { -1.0 } else { 1.0 };
    let q = if p < 0.5 { p } else { 1.0 - p }; // exact for p ≥ ½ (Sterbenz)
    let t = if q > 0.25 { solve_central(libm::fabs(p - 0.5), df) } else { solve_tail(q, df) };
    Ok(sign * t)
}

/// The two-sided Student-t factor `t_{1−α/2}` of a `1 − α` interval (`value ± t · se`) on a
/// quantity estimated from several equations with degrees of freedom `df`: taken at the
/// smallest of them, so that a constant mixing several equations' parameters gets the widest
/// (the least certain equation's) factor. An empty `df`, or `∞` in it, is a known variance:
/// the normal quantile. Dimensionless.
///
/// # Errors
/// [`t_ppf`]'s: `alpha` outside (0, 1) or NaN, a degree of freedom ≤ 0.
///
/// # Examples
/// ```
/// use vehid_core::stats::{t_interval_factor, t_ppf};
/// // Three equations: the factor of the one with 12 degrees of freedom, about 2.179.
/// let t = t_interval_factor(0.05, &[30.0, 12.0, 100.0])?;
/// assert_eq!(t, t_ppf(0.975, 12.0)?);
/// assert!((t - 2.1788).abs() < 1e-4);
/// # Ok::<(), vehid_core::Error>(())
/// ```
pub fn t_interval_factor(alpha: f64, df: &[f64]) -> Result<f64> {
    let df = df.iter().copied().fold(f64::INFINITY, f64::min);
    t_ppf(1.0 - alpha / 2.0, df)
}

/// The standard normal CDF `Φ(x) = ½ erfc(−x/√2)` (scipy `stats.norm.cdf`); `t_cdf(x, ∞)`.
/// Dimensionless; `x` in standard deviations.
///
/// # Errors
/// [`Error::NonFinite`] for a NaN or infinite `x`.
pub fn normal_cdf(x: f64) -> Result<f64> {
    t_cdf(x, f64::INFINITY)
}

/// The standard normal survival function `1 − Φ(x) = ½ erfc(x/√2)` (scipy `stats.norm.sf`).
///
/// # Errors
/// [`Error::NonFinite`] for a NaN or infinite `x`.
pub fn normal_sf(x: f64) -> Result<f64> {
    t_sf(x, f64::INFINITY)
}

/// The standard normal quantile `Φ⁻¹(p)`, `p ∈ (0, 1)` (scipy `stats.norm.ppf`); `t_ppf(p, ∞)`.
///
/// # Errors
/// As [`t_ppf`].
///
/// # Examples
/// ```
/// let z = vehid_core::stats::normal_ppf(0.975)?;
/// assert!((z - 1.959_963_984_540_054).abs() < 1e-15);
/// # Ok::<(), vehid_core::Error>(())
/// ```
pub fn normal_ppf(p: f64) -> Result<f64> {
    t_ppf(p, f64::INFINITY)
}

/// A first guess of the normal upper-tail quantile `z` with `1 − Φ(z) = q`, `q ∈ (0, ½]`
/// (Abramowitz & Stegun 26.2.23, absolute error < 4.5e-4).
fn normal_tail_guess(q: f64) -> f64 {
    let s = libm::sqrt(-2.0 * libm::log(q));
    s - (2.515_517 + s * (0.802_853 + s * 0.010_328)) / (1.0 + s * (1.432_788 + s * (0.189_269 + s * 0.001_308)))
}

/// A first guess of Student's t upper-tail quantile: the Cornish–Fisher expansion around the
/// normal quantile `z` (A&S 26.7.5, two terms) for `ν ≥ 4`, else the larger of it and the
/// power-law tail `P(T > t) ≈ f(0) ν^{(ν−1)/2} t^{−ν}` solved for `t`.
fn t_tail_guess(q: f64, nu: f64) -> f64 {
    let z = normal_tail_guess(q);
    if nu > NU_NORMAL {
        return z;
    }
    let z2 = z * z;
    let cf = z + z * (z2 + 1.0) / (4.0 * nu) + z * (5.0 * z2 * z2 + 16.0 * z2 + 3.0) / (96.0 * nu * nu);
    if nu >= 4.0 {
        return cf;
    }
    let power = libm::exp((ln_density_at_zero(0.5 * nu) + 0.5 * (nu - 1.0) * libm::log(nu) - libm::log(q)) / nu);
    cf.max(power)
}

/// Most Newton steps any quantile takes (they converge in < 10; bisection is the fallback).
const MAX_STEPS: usize = 400;

/// `(lo, hi)` with `0 ≤ lo < hi`, `above(hi)` and not `above(lo)` (or `lo = 0`), found by
/// growing `t0` sixteenfold, `f64::MAX` being the last probe; `None` when not even that is above.
fn bracket(t0: f64, above: impl Fn(f64) -> bool) -> Option<(f64, f64)> {
    let start = if t0 > 0.0 { t0 } else { f64::MIN_POSITIVE }; // (also for a NaN guess)
    let (mut lo, mut probe) = (0.0, start.min(f64::MAX));
    while !above(probe) {
        if probe == f64::MAX {
            return None;
        }
        lo = probe;
        probe = (probe * 16.0).min(f64::MAX);
    }
    Some((lo, probe))
}

/// The `t ≥ 0` with `P(0 < T ≤ t) = c`, `c ∈ (0, ¼)`.
fn solve_central(c: f64, nu: f64) -> f64 {
    let f0 = density(0.0, nu);
    let mut t = if c < 0.01 { c / f0 } else { t_tail_guess(0.5 - c, nu) };
    // Bracket from above: the central probability tends to ½ > c.
    let Some((mut lo, mut hi)) = bracket(t, |x| parts(x, nu).central >= c) else {
        return f64::INFINITY;
    };
    t = t.clamp(lo, hi);
    for _ in 0..MAX_STEPS {
        let g = parts(t, nu).central - c;
        if g == 0.0 {
            return t;
        }
        if g > 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        let mut next = t - g / density(t, nu);
        if !(next > lo && next < hi) {
            next = lo + 0.5 * (hi - lo);
        }
        if libm::fabs(next - t) <= 2.0 * f64::EPSILON * next || next == lo || next == hi {
            return next;
        }
        t = next;
    }
    t
}

/// The `t > 0` with `P(T > t) = q`, `q ∈ (0, ¼]`: Newton on `ln P(T > t)` against `ln t`.
fn solve_tail(q: f64, nu: f64) -> f64 {
    let ln_q = libm::log(q);
    let mut t = t_tail_guess(q, nu);
    if !(t > 0.0) {
        t = 1.0;
    }
    // (A guess that overflows still leaves a finite quantile possible.)
    t = t.min(f64::MAX);
    // Bracket: tail(lo) > q ≥ tail(hi); the tail at 0 is ½ > q.
    let Some((mut lo, mut hi)) = bracket(t, |x| parts(x, nu).tail <= q) else {
        return f64::INFINITY;
    };
    t = t.clamp(lo, hi);
    for _ in 0..MAX_STEPS {
        let tail = parts(t, nu).tail;
        if tail == q {
            return t;
        }
        if tail < q {
            hi = t;
        } else {
            lo = t;
        }
        // d ln P / d ln t = −t f(t) / P.
        let slope = t * density(t, nu) / tail;
        let mut next = if tail > 0.0 && slope > 0.0 && slope.is_finite() {
            t * libm::exp((libm::log(tail) - ln_q) / slope)
        } else {
            f64::NAN
        };
        if !(next > lo && next < hi) {
            // Bisection on the log scale (downwards by 16 while no lower point is known).
            next = if lo == 0.0 {
                hi / 16.0
            } else if hi > 4.0 * lo {
                libm::sqrt(lo) * libm::sqrt(hi)
            } else {
                lo + 0.5 * (hi - lo)
            };
        }
        if libm::fabs(next - t) <= 2.0 * f64::EPSILON * next || next == lo || next == hi {
            return next;
        }
        t = next;
    }
    t
}

//! CUSUM and CUSUM-of-squares tests on recursive residuals (Brown, Durbin & Evans 1975), as
//! statsmodels' `RecursiveLSResults` computes them (`statsmodels/regression/recursive_ls.py`:
//! `cusum`, `cusum_squares`, `_cusum_significance_bounds`, `_cusum_squares_significance_bounds`).
//!
//! The input is the recursive residuals after the diffuse period, `w = (w_{k+1}, …, w_n)`
//! (`m = n − k` values; statsmodels `resid_recursive[d:]` with `d = k`). Both statistics are
//! invariant to the scale of `w`, so standardized innovations (unit variance) and Harvey's
//! recursive residuals (statsmodels multiplies by `√scale`) give the same results. With
//! `j = r − k ∈ 1..=m` the position of `w_r` in the series (index `i = j − 1`):
//!
//! - CUSUM `W_j = Σ_{i ≤ j} w_i / σ̂`, where `σ̂` is the **sample** standard deviation of `w`,
//!   centered and with `ddof = 1`: `σ̂² = Σ (w_i − w̄)² / (m − 1)` (statsmodels
//!   `np.std(resid_recursive[d:], ddof=1)`; Brown et al. use the uncentered `Σ w_i² / m`).
//! - Its bounds `±(a √m + 2 a j / √m)`: the straight lines through `±a√m` at `j = 0` and
//!   `±3a√m` at `j = m` (statsmodels `upper_line(x) = a √(n−d) + 2a (x − d)/√(n−d)` at
//!   `x = d + j`). The constant `a` solves Brown et al.'s (1975, p. 154)
//!   `Q(3a) + exp(−4a²)(1 − Q(a)) = α/2` (`Q` the normal upper tail): 1.143 at α = 1 %,
//!   0.948 at 5 %, 0.850 at 10 %.
//! - CUSUM of squares `s_j = Σ_{i ≤ j} w_i² / Σ_{i ≤ m} w_i²` (statsmodels `cusum_squares`).
//! - Its bounds `j/m ∓ c₀` (statsmodels `line = (x − d)/(n − d)`, `line ∓ crit`), with `c₀`
//!   from the approximation of Edgerton & Wells (1994, Oxford Bull. Econ. Stat. 56(3), 355–365)
//!   that statsmodels uses instead of interpolating Durbin's (1969) table:
//!   `c₀ = s₁/√N + s₂/N + s₃/N^{3/2}`, `N = m/2 − 1`, with the coefficients of
//!   [`CUSUM_SQUARES_SCALARS`] looked up by `α/2` (so α ∈ {0.2, 0.1, 0.05, 0.02, 0.01}).
//!
//! **Deliberate difference:** statsmodels (through at least 0.14) uses `a = 0.950` for
//! α = 10 %, a slip for Brown et al.'s 0.850 (0.950 solves the equation above for α ≈ 5 %,
//! which would make the 10 % band wider than the 5 % one); this module uses 0.850. Its 1 % and
//! 5 % constants and everything else are statsmodels'.

use crate::{Error, Result};

/// The significance levels of the CUSUM test and Brown, Durbin & Evans' (1975) constants `a`
/// for them, as `(alpha, a)`.
pub const CUSUM_SCALARS: [(f64, f64); 3] = [(0.01, 1.143), (0.05, 0.948), (0.10, 0.850)];

/// Edgerton & Wells' (1994) coefficients `(alpha/2, [s₁, s₂, s₃])` of the CUSUM-of-squares
/// critical value `c₀ = s₁/√N + s₂/N + s₃/N^{3/2}` (statsmodels `_cusum_squares_scalars`, whose
/// columns are `alpha/2` = 0.1, 0.05, 0.025, 0.01, 0.005).
pub const CUSUM_SQUARES_SCALARS: [(f64, [f64; 3]); 5] = [
    (0.1, [1.0729830, -0.6698868, -0.5816458]),
    (0.05, [1.2238734, -0.6700069, -0.7351697]),
    (0.025, [1.3581015, -0.6701218, -0.8858694]),
    (0.01, [1.5174271, -0.6702672, -1.0847745]),
    (0.005, [1.6276236, -0.6703724, -1.2365861]),
];

/// Whether two table levels match: equal up to rounding (statsmodels compares with `==`; a
/// computed `1 − 0.95` is accepted here too).
fn same_level(a: f64, b: f64) -> bool {
    libm::fabs(a - b) <= 1e-12
}

/// Brown, Durbin & Evans' constant `a` of the CUSUM bounds at significance level `alpha`
/// (1.143, 0.948, 0.850 for 0.01, 0.05, 0.10).
///
/// # Errors
/// [`Error::InvalidArgument`] for any other `alpha`.
pub fn cusum_scalar(alpha: f64) -> Result<f64> {
    CUSUM_SCALARS.iter().find(|(level, _)| same_level(alpha, *level)).map(|(_, a)| *a).ok_or(Error::InvalidArgument {
        arg: "alpha",
        expected: "0.01, 0.05 or 0.10 (the levels of Brown, Durbin & Evans 1975 for the CUSUM test)",
    })
}

/// The upper CUSUM bound at position `j` (`j = r − k`, from 0 to `m`) of a series of `m`
/// recursive residuals: `a √m + 2 a j / √m` (the lower bound is its negative).
///
/// statsmodels' `_cusum_significance_bounds(alpha, points=d + j)`; the bound that goes with
/// `W_j` (`cusum[j − 1]`) is the one at `j`, and the default points of statsmodels are `j = 0`
/// and `j = m`.
///
/// # Errors
/// [`Error::InvalidArgument`] for an `alpha` without a constant ([`cusum_scalar`]);
/// [`Error::Shape`] for `m = 0` (no residuals); [`Error::NonFinite`] for a `j` that is not finite.
pub fn cusum_bound(alpha: f64, m: usize, j: f64) -> Result<f64> {
    let a = cusum_scalar(alpha)?;
    if m == 0 {
        return Err(Error::Shape { arg: "w", expected: 1, got: 0 });
    }
    if !j.is_finite() {
        return Err(Error::NonFinite { arg: "j", index: 0 });
    }
    let root = libm::sqrt(m as f64);
    Ok(a * root + 2.0 * a * j / root)
}

/// Checks `w` (at least `min` finite values) and returns the power of two that brings its
/// largest magnitude near 1 when squares could overflow or underflow (else 1: then every
/// result is bit for bit the unscaled formula; a power of two scales exactly in any case).
fn check_residuals(w: &[f64], min: usize) -> Result<f64> {
    if w.len() < min {
        return Err(Error::Shape { arg: "w", expected: min, got: w.len() });
    }
    crate::error::check_finite("w", w)?;
    let big = w.iter().fold(0.0f64, |m, v| m.max(libm::fabs(*v)));
    if big == 0.0 || (1e-140..=1e140).contains(&big) {
        return Ok(1.0);
    }
    let (_, e) = libm::frexp(big);
    Ok(libm::ldexp(1.0, -e))
}

/// The CUSUM series `W_j = Σ_{i ≤ j} w_i / σ̂`, `σ̂` the sample standard deviation (`ddof = 1`)
/// of `w`, into `out` (same length as `w`); returns `σ̂` (statsmodels `cusum`; module
/// documentation). `w` holds the `m ≥ 2` recursive residuals after the diffuse period.
///
/// # Errors
/// [`Error::Shape`] for fewer than 2 residuals or an `out` of another length;
/// [`Error::NonFinite`]; [`Error::InvalidArgument`] when all residuals are equal (`σ̂ = 0`).
pub fn cusum_into(w: &[f64], out: &mut [f64]) -> Result<f64> {
    let scale = check_residuals(w, 2)?;
    if out.len() != w.len() {
        return Err(Error::Shape { arg: "out", expected: w.len(), got: out.len() });
    }
    let m = w.len() as f64;
    // Two passes with compensated (Neumaier) sums for the mean and the squared deviations.
    let mean = neumaier(w.iter().map(|v| v * scale)) / m;
    let ss = neumaier(w.iter().map(|v| {
        let d = v * scale - mean;
        d * d
    }));
    let sigma_scaled = libm::sqrt(ss / (m - 1.0));
    if !(sigma_scaled > 0.0) {
        return Err(Error::InvalidArgument {
            arg: "w",
            expected: "recursive residuals that are not all equal (their sample standard deviation scales the CUSUM)",
        });
    }
    let mut cum = 0.0;
    for (o, v) in out.iter_mut().zip(w) {
        cum += v * scale;
        *o = cum / sigma_scaled;
    }
    Ok(sigma_scaled / scale)
}

/// The CUSUM-of-squares series `s_j = Σ_{i ≤ j} w_i² / Σ_{i ≤ m} w_i²` into `out` (same
/// length as `w`; `s_m = 1`) (statsmodels `cusum_squares`).
///
/// # Errors
/// [`Error::Shape`] for an empty `w` or an `out` of another length; [`Error::NonFinite`];
/// [`Error::InvalidArgument`] when all residuals are zero.
pub fn cusum_squares_into(w: &[f64], out: &mut [f64]) -> Result<()> {
    let scale = check_residuals(w, 1)?;
    if out.len() != w.len() {
        return Err(Error::Shape { arg: "out", expected: w.len(), got: out.len() });
    }
    // Sequential cumulative sum, as numpy's cumsum; the last entry is the denominator.
    let mut cum = 0.0;
    for (o, v) in out.iter_mut().zip(w) {
        let s = v * scale;
        cum += s * s;
        *o = cum;
    }
    if !(cum > 0.0) {
        return Err(Error::InvalidArgument {
            arg: "w",
            expected:
                "recursive residuals that are not all zero (their sum of squares normalizes the CUSUM of squares)",
        });
    }
    for o in out.iter_mut() {
        *o /= cum;
    }
    Ok(())
}

/// Edgerton & Wells' (1994) critical value `c₀ = s₁/√N + s₂/N + s₃/N^{3/2}`, `N = m/2 − 1`,
/// of the CUSUM of squares of `m` recursive residuals at significance level `alpha`
/// (statsmodels `_cusum_squares_significance_bounds`'s `crit`).
///
/// # Errors
/// [`Error::InvalidArgument`] unless `alpha/2` is a level of [`CUSUM_SQUARES_SCALARS`]
/// (`alpha` ∈ {0.2, 0.1, 0.05, 0.02, 0.01}); [`Error::Shape`] for `m < 3` (then `N ≤ 0`).
pub fn cusum_squares_critical(alpha: f64, m: usize) -> Result<f64> {
    let s = CUSUM_SQUARES_SCALARS.iter().find(|(half, _)| same_level(alpha / 2.0, *half)).map(|(_, s)| *s).ok_or(
        Error::InvalidArgument {
            arg: "alpha",
            expected: "0.2, 0.1, 0.05, 0.02 or 0.01 (the levels of Edgerton & Wells 1994 for the CUSUM of squares)",
        },
    )?;
    if m < 3 {
        return Err(Error::Shape { arg: "w", expected: 3, got: m });
    }
    let n = 0.5 * m as f64 - 1.0;
    Ok(s[0] / libm::pow(n, 0.5) + s[1] / n + s[2] / libm::pow(n, 1.5))
}

/// The CUSUM-of-squares bounds `[j/m − c₀, j/m + c₀]` at position `j` (from 0 to `m`) of `m`
/// recursive residuals (statsmodels `_cusum_squares_significance_bounds(alpha, points=d + j)`;
/// `s_j` goes with the bounds at `j`).
///
/// # Errors
/// As [`cusum_squares_critical`]; [`Error::NonFinite`] for a `j` that is not finite.
pub fn cusum_squares_bounds(alpha: f64, m: usize, j: f64) -> Result<[f64; 2]> {
    let c0 = cusum_squares_critical(alpha, m)?;
    if !j.is_finite() {
        return Err(Error::NonFinite { arg: "j", index: 0 });
    }
    let line = j / m as f64;
    Ok([line - c0, line + c0])
}

/// Neumaier's compensated sum.
fn neumaier(values: impl Iterator<Item = f64>) -> f64 {
    let (mut sum, mut comp) = (0.0f64, 0.0f64);
    for v in values {
        let t = sum + v;
        comp += if libm::fabs(sum) >= libm::fabs(v) { (sum - t) + v } else { (v - t) + sum };
        sum = t;
    }
    sum + comp
}

/// Both CUSUM tests of one equation's recursive residuals, with their bounds per sample
/// (module documentation). Entry `i` belongs to `w_{k+1+i}` (position `j = i + 1`).
#[cfg(feature = "alloc")]
#[derive(Debug, Clone, PartialEq)]
pub struct Cusum {
    /// The significance level of the bounds.
    pub alpha: f64,
    /// `σ̂`: the sample standard deviation (`ddof = 1`) of the residuals, in their unit.
    pub sigma: f64,
    /// The CUSUM `W_j` (statsmodels `cusum`), dimensionless.
    pub cusum: alloc::vec::Vec<f64>,
    /// The upper CUSUM bound at each `j`, `a √m + 2 a j / √m`; the lower one is its negative.
    pub cusum_bound: alloc::vec::Vec<f64>,
    /// The CUSUM of squares `s_j` (statsmodels `cusum_squares`), from near 0 up to 1.
    pub cusum_squares: alloc::vec::Vec<f64>,
    /// The CUSUM-of-squares bounds `[j/m − c₀, j/m + c₀]` at each `j`.
    pub cusum_squares_bounds: alloc::vec::Vec<[f64; 2]>,
    /// Brown et al.'s constant `a` ([`cusum_scalar`]).
    pub scalar: f64,
    /// Edgerton & Wells' critical value `c₀` ([`cusum_squares_critical`]).
    pub critical: f64,
}

#[cfg(feature = "alloc")]
impl Cusum {
    /// Both tests for the recursive residuals `w` after the diffuse period (`m ≥ 3` values) at
    /// significance level `alpha` ∈ {0.01, 0.05, 0.10} (the levels both tests have).
    ///
    /// # Errors
    /// As [`cusum_into`], [`cusum_squares_into`], [`cusum_scalar`] and
    /// [`cusum_squares_critical`]; [`Error::OutOfMemory`].
    ///
    /// # Examples
    /// ```
    /// use vehid_core::stats::Cusum;
    /// let w = [0.5, -1.0, 0.25, 1.5, -0.75, 0.1, 0.3, -0.2];
    /// let c = Cusum::new(&w, 0.05)?;
    /// assert_eq!(c.first_cusum_crossing(), None); // no evidence of a change
    /// assert_eq!(*c.cusum_squares.last().unwrap(), 1.0);
    /// # Ok::<(), vehid_core::Error>(())
    /// ```
    pub fn new(w: &[f64], alpha: f64) -> Result<Self> {
        let scalar = cusum_scalar(alpha)?;
        let critical = cusum_squares_critical(alpha, w.len())?;
        let m = w.len();
        let mut cusum = super::summary::zeros(m, "the CUSUM")?;
        let mut cusum_squares = super::summary::zeros(m, "the CUSUM of squares")?;
        let sigma = cusum_into(w, &mut cusum)?;
        cusum_squares_into(w, &mut cusum_squares)?;
        let mut bounds = super::summary::zeros(m, "the CUSUM bounds")?;
        let mut cusum_squares_bounds = alloc::vec::Vec::new();
        cusum_squares_bounds
            .try_reserve_exact(m)
            .map_err(|_| Error::OutOfMemory { what: "the CUSUM of squares bounds", bytes: m.saturating_mul(16) })?;
        for (i, b) in bounds.iter_mut().enumerate() {
            let j = (i + 1) as f64;
            *b = cusum_bound(alpha, m, j)?;
            cusum_squares_bounds.push(cusum_squares_bounds_at(j, m, critical));
        }
        Ok(Self { alpha, sigma, cusum, cusum_bound: bounds, cusum_squares, cusum_squares_bounds, scalar, critical })
    }

    /// The number of residuals `m`.
    pub fn len(&self) -> usize {
        self.cusum.len()
    }

    /// `true` when there is no residual (never, for a value built by [`Cusum::new`]).
    pub fn is_empty(&self) -> bool {
        self.cusum.is_empty()
    }

    /// The first index whose CUSUM lies outside its bounds (`|W_j| > bound`): evidence that the
    /// parameters changed (Brown et al. 1975), or `None`.
    pub fn first_cusum_crossing(&self) -> Option<usize> {
        self.cusum.iter().zip(&self.cusum_bound).position(|(w, b)| libm::fabs(*w) > *b)
    }

    /// The first index whose CUSUM of squares lies outside its bounds (evidence of a change in
    /// the parameters or the noise variance), or `None`.
    pub fn first_cusum_squares_crossing(&self) -> Option<usize> {
        self.cusum_squares.iter().zip(&self.cusum_squares_bounds).position(|(s, [lo, hi])| *s < *lo || *s > *hi)
    }
}

#[cfg(feature = "alloc")]
fn cusum_squares_bounds_at(j: f64, m: usize, c0: f64) -> [f64; 2] {
    let line = j / m as f64;
    [line - c0, line + c0]
}

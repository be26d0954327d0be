//! The safeguards shared by the Kalman forms: the outlier screen and its statistics, the
//! checks that a covariance stays positive definite, and the errors of a refused update.

#[cfg(doc)]
use super::KalmanOptions;
use crate::identify::{OVERFLOW, OVERFLOW_Z};
use crate::linalg::cholesky_in_place;
use crate::{Error, Real, Result};
use nalgebra::SMatrix;

/// Samples behind `σ̂` before the outlier screen acts (beyond the `N` the estimate uses).
pub(crate) const SCREEN_WARMUP: f64 = 50.0;

/// The outlier screen ([`KalmanOptions::gate`], [`KalmanOptions::huber`]) of a sample with
/// innovation `e` and innovation variance `s`, given the row's statistics: `None` when gated,
/// else the variance `r` to use (scaled up by the Huber weight). The recursive residual is
/// `w² = e² r / s`; `σ̂² = ssr / (nobs − N)` estimates its variance.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn screen<T: Real>(gate: T, huber: T, nobs: T, ssr: T, r: T, e: T, s: T, params: usize) -> Option<T> {
    if (gate == T::zero() && huber == T::zero()) || nobs < T::of(params as f64 + SCREEN_WARMUP) {
        return Some(r);
    }
    let sigma2 = ssr / (nobs - T::of(params as f64));
    if !(sigma2 > T::zero()) {
        return Some(r); // noise-free so far: no scale to judge by
    }
    let z2 = e * e * r / s / sigma2;
    if gate > T::zero() && !(z2 <= gate * gate) {
        return None;
    }
    if huber > T::zero() && z2 > huber * huber {
        return Some(r * z2.sqrt() / huber);
    }
    Some(r)
}

/// The checks of a covariance reset: `p0` finite and > 0, and not during an exact start
/// (there is no estimate to keep yet).
pub(crate) fn check_reset<T: Real>(p0: T, starting: bool) -> Result<()> {
    if !(p0 > T::zero() && p0.finite()) {
        return Err(Error::InvalidArgument { arg: "p0", expected: "a finite covariance > 0 to restart from" });
    }
    if starting {
        return Err(Error::Unsupported {
            what: "reset_covariance during the exact start (no estimate yet: feed samples until it has one)",
        });
    }
    Ok(())
}

/// The residual statistics `(ssr, nobs)` after a gated sample: its recursive residual enters
/// Winsorized at the gate, `κ² σ̂²` with `σ̂² = ssr / (nobs − N)`, decayed by `λ` like an
/// accepted one. An isolated outlier then moves `σ̂²` by a factor `1 + (κ² − 1)/n` only (n the
/// statistics' memory: every sample so far, or `1/(1 − λ)` with forgetting), while a lasting
/// change of the dynamics, whose every residual lies beyond the gate, raises `σ̂` by that
/// factor per sample until its samples pass: within about `ln(z²/κ²) / ln(1 + (κ² − 1)/n)`
/// samples for residuals `z σ̂` (tens of samples at `κ = 6`, `λ = 0.995`), so a gate does not
/// stop the identifier from tracking a change.
#[inline(always)]
pub(crate) fn gated_scale<T: Real>(gate: T, lambda: T, ssr: T, nobs: T, params: usize) -> (T, T) {
    let sigma2 = ssr / (nobs - T::of(params as f64));
    (ssr * lambda + gate * gate * sigma2, nobs * lambda + T::one())
}

/// The rounding level of `xᵀPx` for a noise-free row (`r = 0`): `ε · 4N · |x|₁ · |P x|₁`
/// (`x_l1`, `px_l1`). At or below it the covariance has collapsed along `x` and the row takes
/// no step (every mode alike).
#[inline(always)]
pub(crate) fn collapse_floor<T: Real, const N: usize>(x_l1: T, px_l1: T) -> T {
    T::default_epsilon() * T::of(4.0 * N as f64) * x_l1 * px_l1
}

/// A sample is risky for the standard form when `r / s` is below this (`√ε`): it carries so
/// much information relative to its noise that the downdate `P − P x xᵀ P / s` cancels to
/// rounding level along `x`. The downdated covariance is then checked (Cholesky) before the
/// update is accepted. (Noise-free rows, `r = 0`, are exempt: their `P` becomes singular by
/// design, and directions already learned take no further step.)
pub(crate) fn risky<T: Real>() -> T {
    T::default_epsilon().sqrt()
}

/// The error of an update the standard or Joseph form cannot make without losing positive
/// definiteness (mode `rows`).
pub(crate) const LOST_DEFINITENESS: Error = Error::Singular {
    what: "the covariance after this sample (the update would lose positive definiteness: the sample is \
           informative far beyond its noise r; use form='sqrt', which cannot, or p0='exact' / a smaller p0)",
};

/// [`LOST_DEFINITENESS`] for modes `shared` and `full`, which have neither the square-root
/// form nor the exact start.
pub(crate) const LOST_DEFINITENESS_JOINT: Error = Error::Singular {
    what: "the covariance after this sample (the update would lose positive definiteness: the sample is \
           informative far beyond its noise r; use a smaller p0, or mode='rows' with form='sqrt', which cannot \
           lose it)",
};

/// `true` when the leading `d × d` block of the symmetric `p` is numerically positive
/// definite (its Cholesky factorization exists).
pub(crate) fn positive_definite<T: Real, const N: usize>(p: &SMatrix<T, N, N>, d: usize) -> bool {
    let mut l = SMatrix::<T, N, N>::zeros();
    let buf = l.as_mut_slice();
    for b in 0..d {
        for a in 0..d {
            buf[b * d + a] = p[(a, b)];
        }
    }
    cholesky_in_place(&mut buf[..d * d], d)
}

/// Which argument an overflowing step is due to: the state (`x θ` not finite) or the
/// derivative (an innovation far beyond the prediction).
#[cold]
pub(crate) fn overflow_culprit<T: Real>(e: T, xth: T) -> crate::Error {
    if !xth.finite() {
        OVERFLOW
    } else if !e.finite() || e.abs() > (xth.abs() + T::one()) * T::of(1e6) {
        OVERFLOW_Z
    } else {
        OVERFLOW
    }
}

//! The checks of a sample shared by the identifiers, and the errors of an update that would
//! overflow.

use super::Dims;
use crate::{Error, Real, Result};
use nalgebra::SVector;

/// Checks a sample: `x` and `z` finite.
#[inline]
pub(crate) fn check_sample<T: Real, const N: usize>(x: &SVector<T, N>, z: &SVector<T, N>) -> Result<()> {
    if let Some(index) = x.iter().position(|v| !v.finite()) {
        return Err(Error::NonFinite { arg: "r_k", index });
    }
    if let Some(index) = z.iter().position(|v| !v.finite()) {
        return Err(Error::NonFinite { arg: "z_k", index });
    }
    Ok(())
}

/// The error for an update whose arithmetic would overflow: the identifier is left unchanged.
pub(crate) const OVERFLOW: Error = Error::InvalidArgument {
    arg: "r_k",
    expected: "sample values small enough that the update stays finite (rescale the units)",
};

/// The error for an update that would overflow through the innovation (a derivative far from
/// the prediction), when the state itself is in range: names `z_k`.
pub(crate) const OVERFLOW_Z: Error = Error::InvalidArgument {
    arg: "z_k",
    expected: "a measured derivative small enough that the update stays finite (rescale the units, or turn the \
               outlier gate on)",
};

/// [`check_lengths`], then every value finite (the errors name `r_k`, `z_k`, `u_k`): the
/// checks every identifier's `update_into` starts with.
///
/// # Errors
/// [`Error::Shape`]; [`Error::NonFinite`].
#[inline(always)]
pub(crate) fn check_slices<T: Real>(dims: Dims, x: &[T], z: &[T], u: &[T], e: &[T]) -> Result<()> {
    check_lengths(dims, x, z, u, e)?;
    for (arg, v) in [("r_k", x), ("z_k", z), ("u_k", u)] {
        crate::error::check_finite(arg, v)?;
    }
    Ok(())
}

/// Checks the lengths of one sample against `dims` (`x`, `z`: `n`; `u`: `m`; `e`: equations).
#[inline(always)]
pub(crate) fn check_lengths<T>(dims: Dims, x: &[T], z: &[T], u: &[T], e: &[T]) -> Result<()> {
    if x.len() != dims.states {
        return Err(Error::Shape { arg: "r_k", expected: dims.states, got: x.len() });
    }
    if z.len() != dims.states {
        return Err(Error::Shape { arg: "z_k", expected: dims.states, got: z.len() });
    }
    if u.len() != dims.inputs {
        return Err(Error::Shape { arg: "u_k", expected: dims.inputs, got: u.len() });
    }
    if e.len() != dims.equations {
        return Err(Error::Shape { arg: "e", expected: dims.equations, got: e.len() });
    }
    Ok(())
}

/// Writes the diagonal `k × k` matrix whose entry `(i, i)` is `diag(i)` into `out` (row-major):
/// an identifier's `noise_into` when its equations' noises are independent.
///
/// # Errors
/// [`Error::Shape`] when `out` does not hold `k²` values.
pub(crate) fn diagonal_into<T: Real>(out: &mut [T], k: usize, diag: impl Fn(usize) -> T) -> Result<()> {
    if out.len() != k * k {
        return Err(Error::Shape { arg: "out", expected: k * k, got: out.len() });
    }
    out.fill(T::zero());
    for i in 0..k {
        out[i * k + i] = diag(i);
    }
    Ok(())
}

//! Conversions between an identifier's fixed-size state and the interface's slices.

use super::{Dims, FitError, Identifier, FIT_STACK_EQUATIONS};
use crate::{Error, Real, Result};
use nalgebra::SMatrix;

/// `θ̂` of a fixed-size identifier as a `K × N` matrix (the estimate of every unknown row).
pub(crate) fn fixed_theta<T: Real, const N: usize, const K: usize>(id: &impl Identifier<T>) -> SMatrix<T, K, N> {
    // Row-major K × N is the column-major storage of its N × K transpose.
    let mut t = SMatrix::<T, N, K>::zeros();
    // The buffer has exactly K·N entries, the identifier's parameter count.
    let _ = id.params_into(t.as_mut_slice());
    t.transpose()
}

/// Runs `f` with an innovation buffer of `len` values: on the stack up to
/// [`FIT_STACK_EQUATIONS`], on the heap beyond (with `alloc`).
pub(crate) fn with_innovations<T: Real, R>(
    len: usize,
    f: impl FnOnce(&mut [T]) -> core::result::Result<R, FitError>,
) -> core::result::Result<R, FitError> {
    if len <= FIT_STACK_EQUATIONS {
        let mut buf = [T::zero(); FIT_STACK_EQUATIONS];
        return f(&mut buf[..len]);
    }
    #[cfg(feature = "alloc")]
    {
        let mut v = alloc::vec::Vec::new();
        v.try_reserve_exact(len).map_err(|_| FitError {
            sample: None,
            error: Error::OutOfMemory { what: "the innovations of one sample", bytes: len * core::mem::size_of::<T>() },
        })?;
        v.resize(len, T::zero());
        f(&mut v)
    }
    #[cfg(not(feature = "alloc"))]
    Err(FitError {
        sample: None,
        error: Error::Capacity { arg: "equations", needed: len, capacity: FIT_STACK_EQUATIONS },
    })
}

/// The dimensions of an identifier on `structure` (states, inputs, identified equations,
/// parameters): what every identifier on a [`Structure`](crate::structure::Structure) reports.
#[inline(always)]
pub(crate) fn structure_dims<T: Real>(structure: &crate::structure::Structure<T>) -> Dims {
    Dims {
        states: structure.states(),
        inputs: structure.inputs(),
        equations: structure.equations(),
        params: structure.params(),
    }
}

/// [`Identifier::groups_into`] of an identifier on a structure with `np` parameters and `ne`
/// identified equations, grouped by `part`.
pub(crate) fn partition_groups_into(
    part: &crate::structure::Partition,
    np: usize,
    ne: usize,
    group_of_param: &mut [usize],
    group_of_eq: &mut [usize],
) -> Result<()> {
    if group_of_param.len() != np {
        return Err(Error::Shape { arg: "group_of_param", expected: np, got: group_of_param.len() });
    }
    if group_of_eq.len() != ne {
        return Err(Error::Shape { arg: "group_of_eq", expected: ne, got: group_of_eq.len() });
    }
    for (j, g) in group_of_param.iter_mut().enumerate() {
        *g = part.group_of_param[j] as usize;
    }
    for (i, g) in group_of_eq.iter_mut().enumerate() {
        *g = part.group_of_eq[i] as usize;
    }
    Ok(())
}

/// [`Identifier::residuals_into`] from per-equation sums `eq_ssr` and counts `eq_nobs` (the
/// first `ssr.len()` of them, which must equal `nobs.len()` and the equations `ne`).
pub(crate) fn copy_residuals<T: Real>(
    ne: usize,
    eq_ssr: &[T],
    eq_nobs: &[T],
    ssr: &mut [T],
    nobs: &mut [T],
) -> Result<()> {
    if ssr.len() != ne || nobs.len() != ne {
        return Err(Error::Shape { arg: "ssr", expected: ne, got: ssr.len().min(nobs.len()) });
    }
    ssr.copy_from_slice(&eq_ssr[..ne]);
    nobs.copy_from_slice(&eq_nobs[..ne]);
    Ok(())
}

/// The diagonal equation-noise matrix `diag(r)` into `out` (`r.len()²`, row-major): the
/// [`Identifier::noise_into`] of identifiers with one variance per equation.
///
/// # Errors
/// [`Error::Shape`] for a wrong length.
pub(crate) fn diagonal_noise_into<T: Real>(r: &[T], out: &mut [T]) -> Result<()> {
    let ne = r.len();
    if out.len() != ne * ne {
        return Err(Error::Shape { arg: "out", expected: ne * ne, got: out.len() });
    }
    out.fill(T::zero());
    for (i, &v) in r.iter().enumerate() {
        out[i * ne + i] = v;
    }
    Ok(())
}

/// An `N`-vector from a slice of length `N` (checked by the caller).
#[inline(always)]
pub(crate) fn vector<T: Real, const N: usize>(v: &[T]) -> nalgebra::SVector<T, N> {
    let mut out = nalgebra::SVector::<T, N>::zeros();
    for (o, &s) in out.iter_mut().zip(v) {
        *o = s;
    }
    out
}

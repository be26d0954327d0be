//! Building a Kalman identifier whose sizes and form are known only at run time (requires
//! `alloc`): the choice of form and lane grouping lives here, so that a binding only
//! converts its arguments.

use super::{KalmanFull, KalmanOptions, KalmanRows, KalmanShared, Mode, RowIdentifier};
use crate::identify::{per_row, DynIdentifier, Dynamic, DYNAMIC_LANES};
use crate::{Error, Real, Result};
use alloc::boxed::Box;
use alloc::vec::Vec;
use nalgebra::{SMatrix, SVector};

/// The prior covariance `P(0)` as given at run time (`k` unknown rows, `n` states).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Prior<T> {
    /// One value for every row, or one per row, times the identity.
    PerRow(Vec<T>),
    /// One `n × n` matrix per row (`k × n × n`, row-major); modes `rows` only.
    RowMatrices(Vec<T>),
    /// The whole `(k·n) × (k·n)` matrix (row-major); mode `full`, or mode `rows` when it is
    /// block diagonal.
    Full(Vec<T>),
    /// No prior: the exact start ([`KalmanRows::exact`]); mode `rows`.
    Exact,
}

/// Everything that defines a Kalman identifier, as run-time data.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct KalmanSpec<T> {
    /// The unknown rows (0-based), in the order of θ and of the innovations.
    pub rows: Vec<usize>,
    /// The prior covariance.
    pub p0: Prior<T>,
    /// The prior mean `θ̂(0)` (`k·n` values, row-major; `None`: zero).
    pub theta0: Option<Vec<T>>,
    /// The regression-error variances: one value, one per row, or (mode `full`) the whole
    /// `k × k` matrix `R`.
    pub r: Vec<T>,
    /// Which form.
    pub mode: Mode,
    /// Covariance form, reinitialization, retirement.
    pub opts: KalmanOptions<T>,
}

/// Builds the identifier `spec` describes for an `N`-state model, boxed. Decoupled rows are
/// kept in groups of two lanes for one or two rows (no padding lanes: measured faster, see
/// [`Dynamic`]) and of [`DYNAMIC_LANES`] otherwise.
///
/// # Errors
/// As the constructors of [`KalmanRows`], [`KalmanShared`] and [`KalmanFull`];
/// [`Error::InvalidArgument`] naming `p0` when its shape does not fit the mode.
pub fn boxed_kalman<T: Real, const N: usize>(spec: &KalmanSpec<T>) -> Result<Box<dyn DynIdentifier<T>>> {
    let k = spec.rows.len();
    if let Some(t) = &spec.theta0 {
        if t.len() != k * N {
            return Err(Error::Shape { arg: "theta0", expected: k * N, got: t.len() });
        }
        crate::error::check_finite("theta0", t)?;
        if spec.p0 == Prior::Exact {
            return Err(Error::InvalidArgument {
                arg: "theta0",
                expected: "no prior mean with p0='exact' (give p0 too: a prior mean needs a prior covariance)",
            });
        }
    }
    if spec.p0 == Prior::Exact && spec.mode != Mode::Rows {
        return Err(Error::InvalidArgument {
            arg: "p0",
            expected: if spec.mode == Mode::Shared {
                "a prior (a number, one per row) for mode='shared': the exact start (p0='exact', the default) \
                 needs mode='rows'"
            } else {
                "a prior (a number, one per row, or a matrix) for mode='full': the exact start (p0='exact', the \
                 default) needs mode='rows'"
            },
        });
    }
    Ok(match spec.mode {
        Mode::Rows if k <= 2 => Box::new(rows::<T, N, 2>(spec)?),
        Mode::Rows => Box::new(rows::<T, N, DYNAMIC_LANES>(spec)?),
        Mode::Shared => {
            let Prior::PerRow(p0) = &spec.p0 else {
                return Err(Error::InvalidArgument {
                    arg: "p0",
                    expected: "a scalar or one value per row for mode='shared'",
                });
            };
            let mut id = KalmanShared::<T, N, Dynamic>::from_slices(&spec.rows, p0, &spec.r, spec.opts)?;
            if let Some(t) = &spec.theta0 {
                id.set_theta(t)?;
            }
            Box::new(id)
        }
        Mode::Full => {
            let (p0, full) = match &spec.p0 {
                Prior::PerRow(p) => (p.as_slice(), None),
                Prior::Full(m) => (&[T::one()][..], Some(m)),
                Prior::RowMatrices(_) | Prior::Exact => {
                    return Err(Error::InvalidArgument {
                        arg: "p0",
                        expected: "a scalar, one value per row, or the full (k·n, k·n) matrix for mode='full'",
                    })
                }
            };
            let mut id = KalmanFull::<T, N, Dynamic>::from_slices(&spec.rows, p0, &spec.r, spec.opts)?;
            if let Some(m) = full {
                id.set_p0(m)?;
            }
            if let Some(t) = &spec.theta0 {
                id.set_theta(t)?;
            }
            Box::new(id)
        }
    })
}

/// The `n × n` blocks on the diagonal of a block-diagonal `(k·n) × (k·n)` matrix, or `None`
/// when an entry off those blocks is not zero.
fn diagonal_blocks<T: Real, const N: usize>(m: &[T], k: usize) -> Option<Vec<T>> {
    let kn = k * N;
    let mut out = Vec::with_capacity(k * N * N);
    for i in 0..kn {
        for j in 0..kn {
            if i / N != j / N && m[i * kn + j] != T::zero() {
                return None;
            }
        }
    }
    for b in 0..k {
        for a in 0..N {
            for c in 0..N {
                out.push(m[(b * N + a) * kn + b * N + c]);
            }
        }
    }
    Some(out)
}

/// The decoupled rows in groups of `L` lanes.
fn rows<T: Real, const N: usize, const L: usize>(spec: &KalmanSpec<T>) -> Result<KalmanRows<T, N, Dynamic<L>>> {
    let k = spec.rows.len();
    let theta0 = |i: usize| match &spec.theta0 {
        Some(t) => SVector::<T, N>::from_fn(|a, _| t[i * N + a]),
        None => SVector::zeros(),
    };
    let with_matrices = |m: &[T]| -> Result<KalmanRows<T, N, Dynamic<L>>> {
        if m.len() != k * N * N {
            return Err(Error::Shape { arg: "p0", expected: k * N * N, got: m.len() });
        }
        let filters = (0..k)
            .map(|i| {
                let p = SMatrix::<T, N, N>::from_fn(|a, b| m[i * N * N + a * N + b]);
                RowIdentifier::with_prior(theta0(i), p, per_row("r", &spec.r, k, i)?)
            })
            .collect::<Result<Vec<_>>>()?;
        KalmanRows::from_filters(&spec.rows, &filters, spec.opts)
    };
    match &spec.p0 {
        Prior::PerRow(p0) if spec.theta0.is_none() => KalmanRows::from_slices(&spec.rows, p0, &spec.r, spec.opts),
        Prior::PerRow(p0) => {
            let filters = (0..k)
                .map(|i| {
                    // Checked as the rows' constructor checks it (the same error either way).
                    let p0 = per_row("p0", p0, k, i)?;
                    crate::error::check_positive("p0", p0)?;
                    let p = SMatrix::<T, N, N>::identity() * p0;
                    RowIdentifier::with_prior(theta0(i), p, per_row("r", &spec.r, k, i)?)
                })
                .collect::<Result<Vec<_>>>()?;
            KalmanRows::from_filters(&spec.rows, &filters, spec.opts)
        }
        Prior::RowMatrices(m) => with_matrices(m),
        Prior::Exact => KalmanRows::exact(&spec.rows, &spec.r, spec.opts),
        Prior::Full(m) => match diagonal_blocks::<T, N>(m, k) {
            Some(blocks) => with_matrices(&blocks),
            None => Err(Error::InvalidArgument {
                arg: "p0",
                expected: "a block-diagonal (k·n, k·n) matrix for mode='rows' (one block per row; a prior that \
                           couples rows needs mode='full')",
            }),
        },
    }
}

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
pub enum Prior<T> {
    /// One value for every row, or one per row, times the identity.
    PerRow(Vec<T>),
    /// One `n × n` matrix per row (`k × n × n`, row-major); modes `rows` only.
    RowMatrices(Vec<T>),
    /// The whole `(k·n) × (k·n)` matrix (row-major); mode `full` only.
    Full(Vec<T>),
}

/// Everything that defines a Kalman identifier, as run-time data.
#[derive(Debug, Clone, PartialEq)]
pub struct KalmanSpec<T> {
    /// The unknown rows (0-based), in the order of θ and of the innovations.
    pub rows: Vec<usize>,
    /// The prior covariance.
    pub p0: Prior<T>,
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
    Ok(match spec.mode {
        Mode::Rows if spec.rows.len() <= 2 => Box::new(rows::<T, N, 2>(spec)?),
        Mode::Rows => Box::new(rows::<T, N, DYNAMIC_LANES>(spec)?),
        Mode::Shared => {
            let Prior::PerRow(p0) = &spec.p0 else {
                return Err(Error::InvalidArgument {
                    arg: "p0",
                    expected: "a scalar or one value per row for mode='shared'",
                });
            };
            Box::new(KalmanShared::<T, N, Dynamic>::from_slices(&spec.rows, p0, &spec.r, spec.opts)?)
        }
        Mode::Full => {
            let (p0, full) = match &spec.p0 {
                Prior::PerRow(p) => (p.as_slice(), None),
                Prior::Full(m) => (&[T::one()][..], Some(m)),
                Prior::RowMatrices(_) => {
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
            Box::new(id)
        }
    })
}

/// The decoupled rows in groups of `L` lanes.
fn rows<T: Real, const N: usize, const L: usize>(spec: &KalmanSpec<T>) -> Result<KalmanRows<T, N, Dynamic<L>>> {
    let k = spec.rows.len();
    match &spec.p0 {
        Prior::PerRow(p0) => KalmanRows::from_slices(&spec.rows, p0, &spec.r, spec.opts),
        Prior::RowMatrices(m) => {
            if m.len() != k * N * N {
                return Err(Error::Shape { arg: "p0", expected: k * N * N, got: m.len() });
            }
            let filters = (0..k)
                .map(|i| {
                    let p = SMatrix::<T, N, N>::from_fn(|a, b| m[i * N * N + a * N + b]);
                    RowIdentifier::with_prior(SVector::zeros(), p, per_row("r", &spec.r, k, i)?)
                })
                .collect::<Result<Vec<_>>>()?;
            KalmanRows::from_filters(&spec.rows, &filters, spec.opts)
        }
        Prior::Full(_) => Err(Error::InvalidArgument {
            arg: "p0",
            expected: "a scalar, one value per row, or one (n, n) matrix per row for mode='rows' \
                       (a full (k·n, k·n) matrix needs mode='full')",
        }),
    }
}

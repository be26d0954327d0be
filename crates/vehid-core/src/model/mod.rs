//! Linear vehicle models `ẋ = A x + B u` (Eq 2.1) and the thesis' two suspensions.
//!
//! - [`LinearModel`]: any system with `N` states and `M` inputs, the set of rows of `A`
//!   that are unknown (to be identified), and the entries of those rows that are known to be
//!   structurally zero.
//! - [`QuarterCar`]: the 4-state quarter car of Eq 3.8–3.13.
//! - [`HalfCar`]: the 8-state half car (heave and pitch) of Eq 6.1–6.8.
//!
//! Both vehicles map physical constants to `A`, `B` and back: the inverse map
//! ([`QuarterCar::from_theta`], [`HalfCar::from_theta`]) recovers the constants from identified
//! rows given the quantities the thesis assumes known, by least squares over the redundant
//! entries.
//!
//! Units: SI throughout (kg, N/m, N·s/m, m, kg·m² for the pitch inertia, rad for pitch).
//!
//! Files: `mod.rs` ([`RowSet`], [`LinearModel`]), `discretize.rs` (the sampled system: exact
//! zero-order hold and the RK4 map), `quarter.rs` ([`QuarterCar`]), `half.rs` ([`HalfCar`]), `full.rs` ([`FullCar`]: four corners,
//! heave, pitch and roll).

mod discretize;
mod full;
mod half;
mod physical;
mod quarter;
mod sensors;

pub use discretize::{auto_substeps, auto_substeps_of, rk4_map, zoh, MAX_SUBSTEPS};
pub use full::{
    FullCar, FullCarParams, CORNERS, CORNER_DETERMINED, FULL_CONSTANTS, FULL_STATES, FULL_STATE_NAMES,
    HALF_CORNER_DETERMINED,
};
pub use half::{HalfCar, HalfCarParams, HalfConstant};
pub use physical::{PhysicalStructure, MAX_CONSTANTS};
pub use quarter::{QuarterCar, QuarterKnown};
pub use sensors::{
    SensorNoise, SensorSet, FULL_REALISTIC_CHANNELS, FULL_STATE_CHANNELS, HALF_REALISTIC_CHANNELS, HALF_STATE_CHANNELS,
    REALISTIC_CHANNELS, STATE_CHANNELS,
};

use crate::error::{check_finite, check_nonneg};
use crate::{Error, Real, Result};
use nalgebra::SMatrix;

/// The set of unknown rows of a model (0-based, ascending), stored without allocation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize), serde(remote = "Self"))]
pub struct RowSet<const N: usize> {
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    idx: [usize; N],
    len: usize,
}

impl<const N: usize> RowSet<N> {
    /// Builds a row set from 0-based row indices (any order; stored ascending).
    ///
    /// # Errors
    /// [`Error::BadRow`] for an index `>= N` or a repeated index; [`Error::InvalidArgument`]
    /// for an empty list.
    pub fn new(rows: &[usize]) -> Result<Self> {
        if rows.is_empty() {
            return Err(Error::InvalidArgument { arg: "unknown_rows", expected: "at least one row of A to identify" });
        }
        let mut mask = [false; N];
        for &r in rows {
            if r >= N || mask[r] {
                return Err(Error::BadRow { arg: "unknown_rows", row: r, n: N });
            }
            mask[r] = true;
        }
        let mut idx = [0usize; N];
        let mut len = 0;
        for (r, &on) in mask.iter().enumerate() {
            if on {
                idx[len] = r;
                len += 1;
            }
        }
        Ok(Self { idx, len })
    }

    /// The rows as a slice, ascending.
    pub fn as_slice(&self) -> &[usize] {
        &self.idx[..self.len]
    }

    /// Number of unknown rows.
    #[allow(clippy::len_without_is_empty)]
    pub fn len(&self) -> usize {
        self.len
    }

    /// `true` when `row` is one of the unknown rows.
    pub fn contains(&self, row: usize) -> bool {
        self.as_slice().contains(&row)
    }

    /// Checks a deserialized set: what [`RowSet::new`] would have built.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let rows = self.idx.get(..self.len).ok_or(Error::Shape { arg: "unknown_rows", expected: N, got: self.len })?;
        if Self::new(rows)? != *self {
            return Err(Error::InvalidArgument {
                arg: "unknown_rows",
                expected: "distinct rows in ascending order, the unused slots 0",
            });
        }
        Ok(())
    }

    /// The rows as a fixed-size array, for the const-generic identifiers.
    ///
    /// # Errors
    /// [`Error::Shape`] when `K` differs from the number of unknown rows.
    pub fn to_array<const K: usize>(&self) -> Result<[usize; K]> {
        if K != self.len {
            return Err(Error::Shape { arg: "unknown_rows", expected: self.len, got: K });
        }
        let mut out = [0usize; K];
        out.copy_from_slice(self.as_slice());
        Ok(out)
    }
}

/// A continuous-time linear model `ẋ = A x + B u` (Eq 2.1) with `N` states and `M` inputs.
///
/// `A` is in 1/s (and 1/s² in acceleration rows), `B` maps the road input (m) to the state
/// derivative. The unknown rows are the rows of `A` an identifier estimates (Eq 2.4:
/// kinematic rows such as `ẋ1 = x2` are known from the structure). Entries of unknown rows
/// marked structurally zero are excluded from the error measure ξ (Eq 6.10).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct LinearModel<T: Real, const N: usize, const M: usize> {
    a: SMatrix<T, N, N>,
    b: SMatrix<T, N, M>,
    rows: RowSet<N>,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array2"))]
    zero: [[bool; N]; N],
}

impl<T: Real, const N: usize, const M: usize> LinearModel<T, N, M> {
    /// Builds a model from `A` (`N × N`), `B` (`N × M`) and the 0-based unknown rows.
    ///
    /// Entries of the unknown rows that are exactly zero in `A` are taken as structurally
    /// zero; override with [`LinearModel::with_structural_zeros`].
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf in `A` or `B`; [`Error::BadRow`] /
    /// [`Error::InvalidArgument`] for bad row lists; [`Error::InvalidArgument`] for `N == 0`.
    pub fn new(a: SMatrix<T, N, N>, b: SMatrix<T, N, M>, unknown_rows: &[usize]) -> Result<Self> {
        if N == 0 || N > 16 {
            return Err(Error::InvalidArgument { arg: "a", expected: "between 1 and 16 states" });
        }
        check_finite("a", a.transpose().as_slice())?;
        check_finite("b", b.transpose().as_slice())?;
        let rows = RowSet::new(unknown_rows)?;
        let mut zero = [[false; N]; N];
        for &r in rows.as_slice() {
            for (c, z) in zero[r].iter_mut().enumerate() {
                *z = a[(r, c)] == T::zero();
            }
        }
        Ok(Self { a, b, rows, zero })
    }

    /// Checks a deserialized model: what [`LinearModel::new`] accepts, structural zeros only
    /// in unknown rows.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        Self::new(self.a, self.b, self.rows.as_slice())?;
        match (0..N).find(|&r| !self.rows.contains(r) && self.zero[r].contains(&true)) {
            Some(row) => Err(Error::BadRow { arg: "structural_zeros", row, n: N }),
            None => Ok(()),
        }
    }

    /// Replaces the structural-zero pattern: `(row, col)` pairs (0-based) of unknown rows
    /// whose true value is known to be zero.
    ///
    /// # Errors
    /// [`Error::BadRow`] when a pair is out of range or not in an unknown row.
    pub fn with_structural_zeros(mut self, entries: &[(usize, usize)]) -> Result<Self> {
        let mut zero = [[false; N]; N];
        for &(r, c) in entries {
            if r >= N || !self.rows.contains(r) {
                return Err(Error::BadRow { arg: "structural_zeros", row: r, n: N });
            }
            if c >= N {
                return Err(Error::BadRow { arg: "structural_zeros", row: c, n: N });
            }
            zero[r][c] = true;
        }
        self.zero = zero;
        Ok(self)
    }

    /// The state matrix `A` (`N × N`).
    pub fn a(&self) -> &SMatrix<T, N, N> {
        &self.a
    }

    /// The input matrix `B` (`N × M`), known a priori.
    pub fn b(&self) -> &SMatrix<T, N, M> {
        &self.b
    }

    /// The unknown rows of `A` (0-based).
    pub fn unknown_rows(&self) -> RowSet<N> {
        self.rows
    }

    /// `true` when entry `(row, col)` of an unknown row is structurally zero.
    pub fn is_structural_zero(&self, row: usize, col: usize) -> bool {
        row < N && col < N && self.zero[row][col]
    }

    /// The true unknown rows of `A` stacked as a `K × N` matrix (the parameters θ of
    /// Eq 2.3 restricted to the unknown rows).
    ///
    /// # Errors
    /// [`Error::Shape`] when `K` is not the number of unknown rows.
    pub fn theta<const K: usize>(&self) -> Result<SMatrix<T, K, N>> {
        let rows = self.rows.to_array::<K>()?;
        Ok(SMatrix::<T, K, N>::from_fn(|i, j| self.a[(rows[i], j)]))
    }

    /// Writes the true unknown rows, row-major (`len(rows) × N`), into `out`.
    ///
    /// # Errors
    /// [`Error::Shape`] when `out` has the wrong length.
    pub fn theta_into(&self, out: &mut [T]) -> Result<()> {
        let k = self.rows.len();
        if out.len() != k * N {
            return Err(Error::Shape { arg: "theta", expected: k * N, got: out.len() });
        }
        for (i, &r) in self.rows.as_slice().iter().enumerate() {
            for j in 0..N {
                out[i * N + j] = self.a[(r, j)];
            }
        }
        Ok(())
    }

    /// `Â`: the model's `A` with its unknown rows replaced by `theta` (row-major,
    /// `len(rows) × N`).
    ///
    /// # Errors
    /// [`Error::Shape`] for a wrong length, [`Error::NonFinite`] for NaN/inf.
    pub fn a_hat(&self, theta: &[T]) -> Result<SMatrix<T, N, N>> {
        let k = self.rows.len();
        if theta.len() != k * N {
            return Err(Error::Shape { arg: "theta", expected: k * N, got: theta.len() });
        }
        check_finite("theta", theta)?;
        let mut a = self.a;
        for (i, &r) in self.rows.as_slice().iter().enumerate() {
            for j in 0..N {
                a[(r, j)] = theta[i * N + j];
            }
        }
        Ok(a)
    }

    /// For a kinematic row `ẋ_row = x_col` (a single 1 in `A`, nothing in `B`), the state it
    /// reads; `None` for any other row. Used by the instrumentation mode of Eq 4.37–4.39.
    pub fn kinematic_source(&self, row: usize) -> Option<usize> {
        if row >= N || self.rows.contains(row) || (0..M).any(|j| self.b[(row, j)] != T::zero()) {
            return None;
        }
        let mut src = None;
        for c in 0..N {
            let v = self.a[(row, c)];
            if v == T::one() && src.is_none() {
                src = Some(c);
            } else if v != T::zero() {
                return None;
            }
        }
        src
    }

    /// Diagonal of `R = R_v + B R_u Bᵀ` on the unknown rows (Eq 4.7): the variance of the
    /// regression error of each unknown row when the road input is treated as measurement
    /// noise. `road_sigma` (m) has one value or one per input; `deriv_noise` (state-derivative
    /// units) one value or one per state. Written into `out` (one value per unknown row).
    ///
    /// # Errors
    /// [`Error::Shape`] for wrong lengths; [`Error::InvalidArgument`] for negative or
    /// non-finite standard deviations.
    pub fn row_noise_var_into(&self, road_sigma: &[T], deriv_noise: &[T], out: &mut [T]) -> Result<()> {
        let su = broadcast::<T, M>("road_sigma", road_sigma)?;
        let sv = broadcast::<T, N>("deriv_noise", deriv_noise)?;
        if out.len() != self.rows.len() {
            return Err(Error::Shape { arg: "r", expected: self.rows.len(), got: out.len() });
        }
        for (o, &r) in out.iter_mut().zip(self.rows.as_slice()) {
            let dv = sv[r] * sv[r];
            if !dv.finite() {
                return Err(TOO_LARGE_DERIV);
            }
            let mut v = dv;
            for j in 0..M {
                let bu = self.b[(r, j)] * su[j];
                v += bu * bu;
            }
            if !v.finite() {
                return Err(TOO_LARGE_ROAD);
            }
            *o = v;
        }
        Ok(())
    }

    /// [`LinearModel::row_noise_var_into`] returning a fixed-size array.
    ///
    /// # Errors
    /// As [`LinearModel::row_noise_var_into`], plus [`Error::Shape`] when `K` is not the
    /// number of unknown rows.
    pub fn row_noise_var<const K: usize>(&self, road_sigma: T, deriv_noise: T) -> Result<[T; K]> {
        let mut out = [T::zero(); K];
        if K != self.rows.len() {
            return Err(Error::Shape { arg: "r", expected: self.rows.len(), got: K });
        }
        self.row_noise_var_into(&[road_sigma], &[deriv_noise], &mut out)?;
        Ok(out)
    }

    /// An upper estimate of the magnitude of the fastest pole, `ρ(A)` (1/s), without
    /// computing eigenvalues; used to choose RK4 sub-steps.
    pub fn fastest_pole(&self) -> f64 {
        crate::linalg::spectral_radius(&self.a)
    }

    /// The poles (eigenvalues of `A`, rad/s), sorted by real part then imaginary part.
    /// Eq 3.14 (quarter car) and Eq 6.8 (half car) list the thesis' values.
    ///
    /// # Errors
    /// [`Error::Singular`] when the Schur iteration does not converge within 1000 sweeps
    /// per eigenvalue (pathological, e.g. near-overflowing entries).
    #[cfg(feature = "alloc")]
    pub fn poles(&self) -> Result<[nalgebra::Complex<T>; N]> {
        let d = nalgebra::DMatrix::<T>::from_fn(N, N, |i, j| self.a[(i, j)]);
        let schur = nalgebra::linalg::Schur::try_new(d, T::default_epsilon(), 1000 * N.max(1))
            .ok_or(Error::Singular { what: "A for the eigenvalue iteration (it did not converge)" })?;
        let ev = schur.complex_eigenvalues();
        let mut out = [nalgebra::Complex::new(T::zero(), T::zero()); N];
        for (o, e) in out.iter_mut().zip(ev.iter()) {
            if !(e.re.finite() && e.im.finite()) {
                return Err(Error::Singular { what: "A for the eigenvalue iteration (non-finite result)" });
            }
            *o = *e;
        }
        out.sort_by(|p, q| (p.re, p.im).partial_cmp(&(q.re, q.im)).unwrap_or(core::cmp::Ordering::Equal));
        Ok(out)
    }
}

/// The error of a road σ so large that `(B σ_u)²` overflows.
const TOO_LARGE_ROAD: Error = Error::InvalidArgument {
    arg: "road_sigma",
    expected: "a road standard deviation small enough that its variance through B is finite (rescale the units)",
};

/// The error of a derivative-noise σ so large that its square overflows.
const TOO_LARGE_DERIV: Error = Error::InvalidArgument {
    arg: "deriv_noise",
    expected: "a derivative-noise standard deviation small enough that its variance is finite (rescale the units)",
};

/// Expands one value to `K` values, or checks there are exactly `K`; each must be a finite
/// non-negative standard deviation.
pub(crate) fn broadcast<T: Real, const K: usize>(arg: &'static str, v: &[T]) -> Result<[T; K]> {
    let mut out = [T::zero(); K];
    match v.len() {
        1 => out.iter_mut().for_each(|o| *o = v[0]),
        n if n == K => out.copy_from_slice(v),
        n => return Err(Error::Shape { arg, expected: K, got: n }),
    }
    for o in out.iter() {
        check_nonneg(arg, *o)?;
    }
    Ok(out)
}

/// The residual of an unknown row of a linear model (Eq 2.8, the row as a regression on the
/// state, the unmeasured road left in it): `z_r − θ_r · x`, `θ_r` the row's identified
/// entries (`x.len()` of them), `z_r` the row's measured derivative.
///
/// # Examples
/// ```
/// assert_eq!(vehid_core::model::row_residual(&[2.0, -1.0], &[3.0, 4.0], 5.0), 3.0);
/// ```
pub fn row_residual<T: Real>(theta_row: &[T], x: &[T], z_row: T) -> T {
    theta_row.iter().zip(x).fold(z_row, |e, (t, xi)| e - *t * *xi)
}

/// The least-squares scale `μ` with `μ v ≈ y`: `μ = v·y / v·v`.
pub(crate) fn scale_ls<T: Real>(v: &[T], y: impl Iterator<Item = T>, what: &'static str) -> Result<T> {
    let mut num = T::zero();
    let mut den = T::zero();
    for (vi, yi) in v.iter().zip(y) {
        num += *vi * yi;
        den += *vi * *vi;
    }
    if !(den > T::zero()) || num == T::zero() {
        return Err(Error::NotIdentifiable { what });
    }
    Ok(num / den)
}

#[cfg(test)]
mod tests;

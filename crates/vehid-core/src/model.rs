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

use crate::error::{check_finite, check_nonneg, check_positive};
use crate::{Error, Real, Result};
use nalgebra::SMatrix;

/// The set of unknown rows of a model (0-based, ascending), stored without allocation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RowSet<const N: usize> {
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
pub struct LinearModel<T: Real, const N: usize, const M: usize> {
    a: SMatrix<T, N, N>,
    b: SMatrix<T, N, M>,
    rows: RowSet<N>,
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
            let mut v = sv[r] * sv[r];
            for j in 0..M {
                let bu = self.b[(r, j)] * su[j];
                v += bu * bu;
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

/// Which mass of the quarter car is known when mapping identified rows back to constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum QuarterKnown<T> {
    /// The wheel (unsprung) mass `m`, kg: the thesis' assumption.
    WheelMass(T),
    /// The body (sprung) mass `M`, kg.
    BodyMass(T),
}

/// The quarter-car suspension of Eq 3.8–3.13, state `x = [x1, ẋ1, x2, ẋ2]` (wheel
/// position m, wheel velocity m/s, body position m, body velocity m/s).
///
/// ```text
/// A = [[0, 1, 0, 0],
///      [-(k1+k2)/m, -b/m, k2/m, b/m],
///      [0, 0, 0, 1],
///      [k2/M, b/M, -k2/M, -b/M]]        B = [0, k1/m, 0, 0]ᵀ
/// ```
/// Unknown rows 1 and 3 (0-based): 8 parameters.
///
/// # Examples
/// ```
/// use vehid_core::model::QuarterCar;
/// let car = QuarterCar::<f64>::thesis();
/// assert_eq!(car.unknown_rows(), [1, 3]);
/// assert!((car.model().a()[(1, 0)] + 140.0).abs() < 1e-12); // -(k1 + k2)/m
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuarterCar<T> {
    m_body: T,
    m_wheel: T,
    k1: T,
    k2: T,
    b: T,
}

impl<T: Real> QuarterCar<T> {
    /// Builds the quarter car from body mass `M` (kg), wheel mass `m` (kg), tyre stiffness
    /// `k1` (N/m), suspension stiffness `k2` (N/m) and damping `b` (N·s/m).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the constant when it is not finite and > 0.
    pub fn new(m_body: T, m_wheel: T, k1: T, k2: T, b: T) -> Result<Self> {
        check_positive("M", m_body)?;
        check_positive("m", m_wheel)?;
        check_positive("k1", k1)?;
        check_positive("k2", k2)?;
        check_positive("b", b)?;
        Ok(Self { m_body, m_wheel, k1, k2, b })
    }

    /// The thesis' values (Ch. III.B): M = 10, m = 1, k1 = 90, k2 = 50, b = 40.
    pub fn thesis() -> Self {
        Self { m_body: T::of(10.0), m_wheel: T::of(1.0), k1: T::of(90.0), k2: T::of(50.0), b: T::of(40.0) }
    }

    /// Body mass `M`, kg.
    pub fn m_body(&self) -> T {
        self.m_body
    }
    /// Wheel mass `m`, kg.
    pub fn m_wheel(&self) -> T {
        self.m_wheel
    }
    /// Tyre stiffness `k1`, N/m.
    pub fn k1(&self) -> T {
        self.k1
    }
    /// Suspension stiffness `k2`, N/m.
    pub fn k2(&self) -> T {
        self.k2
    }
    /// Suspension damping `b`, N·s/m.
    pub fn b(&self) -> T {
        self.b
    }

    /// The constants with their thesis names (`M` body mass, `m` wheel mass).
    pub fn named(&self) -> [(&'static str, T); 5] {
        [("M", self.m_body), ("m", self.m_wheel), ("k1", self.k1), ("k2", self.k2), ("b", self.b)]
    }

    /// The unknown rows of `A` (0-based): the wheel and body acceleration rows.
    pub fn unknown_rows(&self) -> [usize; 2] {
        [1, 3]
    }

    /// The linear model of Eq 3.11.
    pub fn model(&self) -> LinearModel<T, 4, 1> {
        let (mb, m, k1, k2, b) = (self.m_body, self.m_wheel, self.k1, self.k2, self.b);
        let z = T::zero();
        let o = T::one();
        #[rustfmt::skip]
        let a = SMatrix::<T, 4, 4>::new(
            z, o, z, z,
            -(k1 + k2) / m, -b / m, k2 / m, b / m,
            z, z, z, o,
            k2 / mb, b / mb, -k2 / mb, -b / mb,
        );
        let bm = SMatrix::<T, 4, 1>::new(z, k1 / m, z, z);
        // Constants validated at construction, so the model is finite.
        LinearModel { a, b: bm, rows: RowSet { idx: [1, 3, 0, 0], len: 2 }, zero: [[false; 4]; 4] }
    }

    /// The true unknown rows (`2 × 4`), the parameters the identifiers estimate.
    pub fn theta(&self) -> SMatrix<T, 2, 4> {
        let a = self.model().a;
        SMatrix::<T, 2, 4>::from_fn(|i, j| a[(2 * i + 1, j)])
    }

    /// Recovers the physical constants from identified rows (`2 × 4`, rows 1 and 3 of `A`),
    /// given one known mass (the thesis: "one mass must be known").
    ///
    /// With the wheel mass `m` known: `k2 = m θ₁₂`, `b` the mean of `−m θ₁₁` and `m θ₁₃`,
    /// `k1 = −m θ₁₀ − k2`, and `1/M` the least-squares scale between `[k2, b, −k2, −b]` and
    /// the body row. With `M` known the roles are swapped. Exact on exact rows.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] when the known mass is not > 0 or θ is not finite;
    /// [`Error::NotIdentifiable`] when the rows do not give positive constants.
    pub fn from_theta(theta: &SMatrix<T, 2, 4>, known: QuarterKnown<T>) -> Result<Self> {
        check_finite("theta", theta.transpose().as_slice())?;
        let w = theta.row(0);
        let body = theta.row(1);
        let half = T::of(0.5);
        let (m_body, m_wheel, k1, k2, b) = match known {
            QuarterKnown::WheelMass(m) => {
                check_positive("m", m)?;
                let k2 = m * w[2];
                let b = (m * w[3] - m * w[1]) * half;
                let k1 = -m * w[0] - k2;
                let v = [k2, b, -k2, -b];
                let mu = scale_ls(&v, body.iter().copied(), "M (the body row and [k2, b] are orthogonal)")?;
                (T::one() / mu, m, k1, k2, b)
            }
            QuarterKnown::BodyMass(mb) => {
                check_positive("M", mb)?;
                let k2 = (mb * body[0] - mb * body[2]) * half;
                let b = (mb * body[1] - mb * body[3]) * half;
                // wheel row: [θ₁₁, θ₁₂, θ₁₃] = [−b, k2, b] / m; θ₁₀ carries k1.
                let v = [-b, k2, b];
                let mu = scale_ls(&v, [w[1], w[2], w[3]].into_iter(), "m (the wheel row and [b, k2] are orthogonal)")?;
                let m = T::one() / mu;
                (mb, m, -m * w[0] - k2, k2, b)
            }
        };
        Self::new(m_body, m_wheel, k1, k2, b).map_err(|_| Error::NotIdentifiable {
            what: "positive quarter-car constants from these rows (is the estimate converged?)",
        })
    }
}

/// The least-squares scale `μ` with `μ v ≈ y`: `μ = v·y / v·v`.
fn scale_ls<T: Real>(v: &[T], y: impl Iterator<Item = T>, what: &'static str) -> Result<T> {
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

/// The half-car (heave and pitch) suspension of Eq 6.1–6.8, linearized for small pitch.
///
/// State `x = [x1, ẋ1, x2, ẋ2, x3, ẋ3, φ, φ̇]`: front wheel, rear wheel, body heave (m, m/s)
/// and body pitch (rad, rad/s). Inputs `u = [u1, u2]`: the road under the front and the rear
/// wheel (m). `B` has `k11/m1` in row 1 and `k21/m2` in row 3 (0-based). Unknown rows
/// 1, 3, 5, 7: 32 parameters, 4 of them structurally zero (row 1 at x2, ẋ2; row 3 at x1, ẋ1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfCar<T> {
    p: HalfCarParams<T>,
}

/// The physical constants of a [`HalfCar`], in the order of the thesis (Eq 6.1–6.6).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfCarParams<T> {
    /// Front tyre stiffness, N/m.
    pub k11: T,
    /// Rear tyre stiffness, N/m.
    pub k21: T,
    /// Front suspension stiffness, N/m.
    pub k12: T,
    /// Rear suspension stiffness, N/m.
    pub k22: T,
    /// Front damping, N·s/m.
    pub b1: T,
    /// Rear damping, N·s/m.
    pub b2: T,
    /// Front wheel mass, kg.
    pub m1: T,
    /// Rear wheel mass, kg.
    pub m2: T,
    /// Body mass `M`, kg.
    pub m_body: T,
    /// Body pitch inertia `J`, kg·m².
    pub j: T,
    /// Distance from the centre of mass to the front axle, m.
    pub l1: T,
    /// Distance from the centre of mass to the rear axle, m.
    pub l2: T,
}

impl<T: Real> HalfCarParams<T> {
    /// The constants with their thesis names (`M` is the body mass, `J` the pitch inertia),
    /// in the order of Eq 6.1–6.6.
    pub fn named(&self) -> [(&'static str, T); 12] {
        [
            ("k11", self.k11),
            ("k21", self.k21),
            ("k12", self.k12),
            ("k22", self.k22),
            ("b1", self.b1),
            ("b2", self.b2),
            ("m1", self.m1),
            ("m2", self.m2),
            ("M", self.m_body),
            ("J", self.j),
            ("l1", self.l1),
            ("l2", self.l2),
        ]
    }
}

impl<T: Real> HalfCar<T> {
    /// Builds the half car from its constants.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the first constant that is not finite and > 0.
    pub fn new(p: HalfCarParams<T>) -> Result<Self> {
        for (name, v) in p.named() {
            check_positive(name, v)?;
        }
        Ok(Self { p })
    }

    /// The thesis' values (Ch. VI.A): k11 = k21 = 100, k12 = k22 = 40, b1 = b2 = 60,
    /// m1 = m2 = 1, M = 20, J = 60, l1 = 2, l2 = 1.
    pub fn thesis() -> Self {
        let c = T::of;
        Self {
            p: HalfCarParams {
                k11: c(100.0),
                k21: c(100.0),
                k12: c(40.0),
                k22: c(40.0),
                b1: c(60.0),
                b2: c(60.0),
                m1: c(1.0),
                m2: c(1.0),
                m_body: c(20.0),
                j: c(60.0),
                l1: c(2.0),
                l2: c(1.0),
            },
        }
    }

    /// The constants.
    pub fn params(&self) -> HalfCarParams<T> {
        self.p
    }

    /// Wheelbase `L = l1 + l2`, m: the distance the rear wheel trails the front wheel.
    pub fn wheelbase(&self) -> T {
        self.p.l1 + self.p.l2
    }

    /// The unknown rows of `A` (0-based): the four acceleration rows.
    pub fn unknown_rows(&self) -> [usize; 4] {
        [1, 3, 5, 7]
    }

    /// The linear model of Eq 6.1–6.6 (8 states, 2 inputs).
    pub fn model(&self) -> LinearModel<T, 8, 2> {
        let p = self.params();
        let mut a = SMatrix::<T, 8, 8>::zeros();
        for i in [0usize, 2, 4, 6] {
            a[(i, i + 1)] = T::one();
        }
        let rows = Self::rows_from(&p);
        for (i, r) in [1usize, 3, 5, 7].iter().enumerate() {
            for c in 0..8 {
                a[(*r, c)] = rows[i][c];
            }
        }
        let mut b = SMatrix::<T, 8, 2>::zeros();
        b[(1, 0)] = p.k11 / p.m1;
        b[(3, 1)] = p.k21 / p.m2;
        let mut zero = [[false; 8]; 8];
        zero[1][2] = true;
        zero[1][3] = true;
        zero[3][0] = true;
        zero[3][1] = true;
        LinearModel { a, b, rows: RowSet { idx: [1, 3, 5, 7, 0, 0, 0, 0], len: 4 }, zero }
    }

    /// The unknown rows of `A` as functions of the constants (Eq 6.1–6.4 divided by the masses).
    fn rows_from(p: &HalfCarParams<T>) -> [[T; 8]; 4] {
        let z = T::zero();
        let (k12, k22, b1, b2, l1, l2) = (p.k12, p.k22, p.b1, p.b2, p.l1, p.l2);
        let (m1, m2, mb, j) = (p.m1, p.m2, p.m_body, p.j);
        let body = Self::body_pattern(k12, k22, b1, b2, l1, l2);
        let pitch = Self::pitch_pattern(k12, k22, b1, b2, l1, l2);
        [
            [-(k12 + p.k11) / m1, -b1 / m1, z, z, k12 / m1, b1 / m1, k12 * l1 / m1, b1 * l1 / m1],
            [z, z, -(k22 + p.k21) / m2, -b2 / m2, k22 / m2, b2 / m2, -k22 * l2 / m2, -b2 * l2 / m2],
            body.map(|v| v / mb),
            pitch.map(|v| v / j),
        ]
    }

    /// The heave row times `M` (Eq 6.3).
    fn body_pattern(k12: T, k22: T, b1: T, b2: T, l1: T, l2: T) -> [T; 8] {
        [k12, b1, k22, b2, -(k12 + k22), -(b1 + b2), -k12 * l1 + k22 * l2, -b1 * l1 + b2 * l2]
    }

    /// The pitch row times `J` (Eq 6.4).
    fn pitch_pattern(k12: T, k22: T, b1: T, b2: T, l1: T, l2: T) -> [T; 8] {
        [
            k12 * l1,
            b1 * l1,
            -k22 * l2,
            -b2 * l2,
            -k12 * l1 + k22 * l2,
            -b1 * l1 + b2 * l2,
            -(k12 * l1 * l1 + k22 * l2 * l2),
            -(b1 * l1 * l1 + b2 * l2 * l2),
        ]
    }

    /// The true unknown rows (`4 × 8`).
    pub fn theta(&self) -> SMatrix<T, 4, 8> {
        let rows = Self::rows_from(&self.params());
        SMatrix::<T, 4, 8>::from_fn(|i, j| rows[i][j])
    }

    /// Recovers the constants from identified rows (`4 × 8`, rows 1, 3, 5, 7 of `A`) given
    /// the wheel masses `m1`, `m2` (kg) and the known input matrix entries `b21 = k11/m1`,
    /// `b42 = k21/m2` (1/s², the thesis' "B known").
    ///
    /// Per wheel row: the suspension stiffness and damping are the means of their two
    /// appearances, the lever arm the least-squares ratio of the pitch columns to the body
    /// columns. `1/M` and `1/J` are the least-squares scales of the body and pitch rows
    /// against the patterns those constants predict. Exact on exact rows.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for non-positive known values or non-finite θ;
    /// [`Error::NotIdentifiable`] when the rows do not give positive constants.
    pub fn from_theta(theta: &SMatrix<T, 4, 8>, m1: T, m2: T, b21: T, b42: T) -> Result<Self> {
        check_finite("theta", theta.transpose().as_slice())?;
        check_positive("m1", m1)?;
        check_positive("m2", m2)?;
        check_positive("b21", b21)?;
        check_positive("b42", b42)?;
        let half = T::of(0.5);
        let (k11, k21) = (b21 * m1, b42 * m2);
        let f = theta.row(0);
        let r = theta.row(1);
        let k12 = (m1 * f[4] + (-m1 * f[0] - k11)) * half;
        let b1 = (m1 * f[5] - m1 * f[1]) * half;
        let l1 = scale_ls(&[f[4], f[5]], [f[6], f[7]].into_iter(), "l1 (front wheel row is zero)")?;
        let k22 = (m2 * r[4] + (-m2 * r[2] - k21)) * half;
        let b2 = (m2 * r[5] - m2 * r[3]) * half;
        let l2 = -scale_ls(&[r[4], r[5]], [r[6], r[7]].into_iter(), "l2 (rear wheel row is zero)")?;
        let body = Self::body_pattern(k12, k22, b1, b2, l1, l2);
        let inv_m = scale_ls(&body, theta.row(2).iter().copied(), "M (body row)")?;
        let pitch = Self::pitch_pattern(k12, k22, b1, b2, l1, l2);
        let inv_j = scale_ls(&pitch, theta.row(3).iter().copied(), "J (pitch row)")?;
        Self::new(HalfCarParams {
            k11,
            k21,
            k12,
            k22,
            b1,
            b2,
            m1,
            m2,
            m_body: T::one() / inv_m,
            j: T::one() / inv_j,
            l1,
            l2,
        })
        .map_err(|_| Error::NotIdentifiable {
            what: "positive half-car constants from these rows (is the estimate converged?)",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * b.abs().max(1e-300)
    }

    #[cfg(feature = "alloc")]
    fn assert_poles(got: &[nalgebra::Complex<f64>], printed: &[(f64, f64)], digits: i32) {
        // Printed to `digits` significant figures: agree within one unit of the last printed
        // digit (the thesis rounds most values but prints -0.6919 as -0.691).
        for (p, (re, im)) in got.iter().zip(printed) {
            let tol = |v: f64| 10f64.powi(v.abs().log10().floor() as i32 - digits + 1);
            assert!((p.re - re).abs() <= tol(*re), "pole {p} vs printed {re}{im:+}j");
            if *im != 0.0 {
                assert!((p.im - im).abs() <= tol(*im), "pole {p} vs printed {re}{im:+}j");
            } else {
                assert!(p.im.abs() < 1e-9, "pole {p} should be real");
            }
        }
    }

    #[cfg(feature = "alloc")]
    #[test]
    fn quarter_car_poles_match_eq_3_14() {
        let poles = QuarterCar::<f64>::thesis().model().poles().unwrap();
        // Eq 3.14, printed to three significant figures, sorted by real part.
        assert_poles(&poles, &[(-40.6, 0.0), (-1.90, 0.0), (-0.727, -2.30), (-0.727, 2.30)], 3);
    }

    #[cfg(feature = "alloc")]
    #[test]
    fn half_car_poles_match_eq_6_8() {
        let poles = HalfCar::<f64>::thesis().model().poles().unwrap();
        assert_poles(
            &poles,
            &[
                (-65.3, 0.0),
                (-61.5, 0.0),
                (-0.837, 0.0),
                (-0.738, 0.0),
                (-0.691, -2.08),
                (-0.691, 2.08),
                (-0.656, -3.11),
                (-0.656, 3.11),
            ],
            3,
        );
    }

    #[test]
    fn quarter_car_round_trip_both_known_masses() {
        let car = QuarterCar::new(12.5, 1.3, 95.0, 47.0, 38.0).unwrap();
        for known in [QuarterKnown::WheelMass(1.3), QuarterKnown::BodyMass(12.5)] {
            let back = QuarterCar::from_theta(&car.theta(), known).unwrap();
            for (x, y) in [
                (back.m_body, car.m_body),
                (back.m_wheel, car.m_wheel),
                (back.k1, car.k1),
                (back.k2, car.k2),
                (back.b, car.b),
            ] {
                assert!(close(x, y, 1e-12), "{x} vs {y}");
            }
        }
    }

    #[test]
    fn half_car_round_trip() {
        let p = HalfCarParams {
            k11: 110.0,
            k21: 95.0,
            k12: 42.0,
            k22: 37.0,
            b1: 61.0,
            b2: 55.0,
            m1: 1.1,
            m2: 0.9,
            m_body: 21.0,
            j: 58.0,
            l1: 1.8,
            l2: 1.2,
        };
        let car = HalfCar::new(p).unwrap();
        let b = car.model().b().clone_owned();
        let back = HalfCar::from_theta(&car.theta(), p.m1, p.m2, b[(1, 0)], b[(3, 1)]).unwrap();
        let q = back.params();
        for (x, y) in [
            (q.k11, p.k11),
            (q.k21, p.k21),
            (q.k12, p.k12),
            (q.k22, p.k22),
            (q.b1, p.b1),
            (q.b2, p.b2),
            (q.m_body, p.m_body),
            (q.j, p.j),
            (q.l1, p.l1),
            (q.l2, p.l2),
        ] {
            assert!(close(x, y, 1e-10), "{x} vs {y}");
        }
    }

    #[test]
    fn physical_map_refuses_what_it_cannot_know() {
        let th = QuarterCar::<f64>::thesis().theta();
        assert!(matches!(
            QuarterCar::from_theta(&th, QuarterKnown::WheelMass(0.0)),
            Err(Error::InvalidArgument { arg: "m", .. })
        ));
        let zero = SMatrix::<f64, 2, 4>::zeros();
        assert!(matches!(
            QuarterCar::from_theta(&zero, QuarterKnown::WheelMass(1.0)),
            Err(Error::NotIdentifiable { .. })
        ));
        let mut nan = th;
        nan[(0, 1)] = f64::NAN;
        assert!(matches!(
            QuarterCar::from_theta(&nan, QuarterKnown::WheelMass(1.0)),
            Err(Error::NonFinite { arg: "theta", index: 1 })
        ));
    }

    #[test]
    fn constants_are_validated() {
        assert!(matches!(QuarterCar::new(10.0, 0.0, 90.0, 50.0, 40.0), Err(Error::InvalidArgument { arg: "m", .. })));
        assert!(matches!(
            QuarterCar::new(f64::NAN, 1.0, 90.0, 50.0, 40.0),
            Err(Error::InvalidArgument { arg: "M", .. })
        ));
        let mut p = HalfCar::<f64>::thesis().params();
        p.j = -1.0;
        assert!(matches!(HalfCar::new(p), Err(Error::InvalidArgument { arg: "J", .. })));
    }

    #[test]
    fn linear_model_validation_and_structure() {
        let car = QuarterCar::<f64>::thesis().model();
        assert_eq!(car.unknown_rows().as_slice(), &[1, 3]);
        assert_eq!(car.kinematic_source(0), Some(1));
        assert_eq!(car.kinematic_source(2), Some(3));
        assert_eq!(car.kinematic_source(1), None);
        let bad = LinearModel::new(*car.a(), *car.b(), &[1, 4]);
        assert!(matches!(bad, Err(Error::BadRow { row: 4, .. })));
        let dup = LinearModel::new(*car.a(), *car.b(), &[1, 1]);
        assert!(matches!(dup, Err(Error::BadRow { row: 1, .. })));
        let mut a = *car.a();
        a[(2, 3)] = f64::INFINITY;
        assert!(matches!(LinearModel::new(a, *car.b(), &[1]), Err(Error::NonFinite { arg: "a", index: 11 })));
        let half = HalfCar::<f64>::thesis().model();
        let zeros =
            (0..8).flat_map(|r| (0..8).map(move |c| (r, c))).filter(|&(r, c)| half.is_structural_zero(r, c)).count();
        assert_eq!(zeros, 4);
    }

    #[test]
    fn row_noise_var_is_diag_of_rv_plus_b_ru_bt() {
        let car = QuarterCar::<f64>::thesis().model();
        let r: [f64; 2] = car.row_noise_var(0.1, 0.005).unwrap();
        // Row 1: (k1/m)^2 σ_u^2 + σ_v^2 = 8100 * 0.01 + 2.5e-5; row 3 has no input.
        assert!((r[0] - (90.0f64 * 90.0 * 0.01 + 0.005 * 0.005)).abs() < 1e-12);
        assert!((r[1] - 0.005 * 0.005).abs() < 1e-18);
        assert!(car.row_noise_var::<2>(-0.1, 0.0).is_err());
        assert!(car.row_noise_var::<3>(0.1, 0.0).is_err());
    }

    #[test]
    fn f32_models_build() {
        let car = QuarterCar::<f32>::thesis();
        assert!((car.theta()[(0, 0)] + 140.0).abs() < 1e-5);
        let half = HalfCar::<f32>::thesis();
        assert!((half.theta()[(3, 7)] + (60.0 * 4.0 + 60.0) / 60.0).abs() < 1e-5);
    }
}

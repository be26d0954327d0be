//! The quarter car (Eq 3.8–3.13).

use super::physical::{der, st, tk, tt, Builder, PhysicalStructure, TemplateTerm, OFFSET};
use super::{scale_ls, LinearModel, RowSet};
use crate::error::{check_finite, check_positive};
use crate::structure::Basis;
use crate::{Error, Real, Result};
use nalgebra::SMatrix;

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
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
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

    /// A typical passenger-car quarter (one corner of a mid-size sedan): M = 320 kg,
    /// m = 40 kg, k1 = 200 kN/m, k2 = 22 kN/m, b = 1.5 kN·s/m.
    ///
    /// Typical ranges (Gillespie, *Fundamentals of Vehicle Dynamics*, SAE 1992, Ch. 5 "Ride":
    /// body bounce 1–1.5 Hz, wheel hop 10–12 Hz, body damping ratio 0.2–0.4; Wong, *Theory of
    /// Ground Vehicles*, 4th ed. 2008, Ch. 7): sprung quarter mass 250–400 kg, unsprung
    /// 30–50 kg, tyre 150–250 kN/m, spring 15–35 kN/m, damper 1–3 kN·s/m. These values give a
    /// body mode of √(k2/M)/2π = 1.32 Hz, a wheel hop of √((k1+k2)/m)/2π = 11.9 Hz and a body
    /// damping ratio b/(2√(k2 M)) = 0.28.
    pub fn passenger() -> Self {
        Self {
            m_body: T::of(320.0),
            m_wheel: T::of(40.0),
            k1: T::of(200_000.0),
            k2: T::of(22_000.0),
            b: T::of(1_500.0),
        }
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

    /// The constants' names, in the order [`QuarterCar::structure`] and
    /// [`QuarterCar::constants`] use: `M, m, k1, k2, b`.
    pub const CONSTANTS: [&'static str; 5] = ["M", "m", "k1", "k2", "b"];

    /// The constants' values in the order of [`QuarterCar::CONSTANTS`].
    pub fn constants(&self) -> [T; 5] {
        [self.m_body, self.m_wheel, self.k1, self.k2, self.b]
    }

    /// The quarter car's physical structure (see [`PhysicalStructure`]), states
    /// `zw, vw, zb, vb` (wheel and body position and velocity), with the constants given in
    /// `known` (order of [`QuarterCar::CONSTANTS`]) fixed:
    ///
    /// ```text
    /// v̇b = −(k2/M)(zb − zw) − (b/M)(vb − vw)           body (Eq 3.10 / M)
    /// v̇w = −(M/m) der(vb) − (k1/m) zw                  momentum of both masses / m
    /// żw = vw,  żb = vb                                 known
    /// ```
    ///
    /// The wheel equation is the balance of forces on both masses (Eq 3.9 + Eq 3.10: the
    /// suspension force cancels), `m v̇w + M v̇b = k1 (u − zw)`, with the body's acceleration
    /// read from its measured derivative. So the road (which enters only this equation, as
    /// its noise) meets two parameters instead of the thesis' four, while the body equation,
    /// free of the road, fixes `k2/M` and `b/M` from data a thousand times cleaner. With `m`
    /// known the parameters are `k2/M, b/M, M, k1`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a known value not finite and > 0;
    /// [`Error::NotIdentifiable`] when so much is known that nothing is left to identify.
    pub fn structure(known: [Option<T>; 5]) -> Result<PhysicalStructure<T>> {
        // Constants: 0 M, 1 m, 2 k1, 3 k2, 4 b. Edges: 0 k2/M, 1 b/M, 2 M/m, 3 k1/m.
        let edges = [(3, 0, "k2/M"), (4, 0, "b/M"), (0, 1, "M/m"), (2, 1, "k1/m")];
        let one = T::one();
        let body = [tt(-one, 0, st(2)), tt(one, 0, st(0)), tt(-one, 1, st(3)), tt(one, 1, st(1))];
        let wheel = [tt(-one, 2, der(3)), tt(-one, 3, st(0))];
        let (kw, kb) = ([tk(one, st(1))], [tk(one, st(3))]);
        Builder { states: 4, constants: &Self::CONSTANTS, edges: &edges, known: &known, absent: STATE_SENSORS_READ_ALL }
            .build(&[(3, &body), (1, &wheel)], &[(0, &kw), (2, &kb)])
    }

    /// The physical structure that the realistic sensors determine
    /// ([`crate::model::SensorSet::Realistic`]: body and wheel accelerometers and a deflection
    /// sensor), states `d, v, vb` (deflection `zb − zw`, m; its rate, m/s; the body's
    /// velocity, whose derivative is the body accelerometer's `a_body`):
    ///
    /// ```text
    /// v̇b = −(k2/M) d − (b/M) v + offset                body (Eq 3.10 / M)
    /// ḋ = v                                             known
    /// ```
    ///
    /// The body equation is free of the road and of absolute positions, so it holds on any
    /// road; `offset` (m/s²) takes the body accelerometer's bias and the deflection sensor's
    /// zero error (`−(k2/M) d₀`). No sensor measures `v`: [`crate::identify::StateFilterFit`]
    /// fits this equation through a state-variable filter, reading `a_body` as the derivative
    /// of `vb` and never `vb` itself.
    ///
    /// What these sensors determine: `k2/M` and `b/M`; with `M` known, `k2` and `b`
    /// ([`PhysicalStructure::constant`]). The wheel's equation needs the tyre force
    /// `k1 (u − zw)`, which no accelerometer or deflection sensor measures (the wheel's absolute
    /// position and the road's height are both unknown), so `m` and `k1` are not determined
    /// ([`PhysicalStructure::needs`] says so), whatever else is known.
    ///
    /// # Errors
    /// As [`QuarterCar::structure`]; a known `k2` or `b` (with `M` unknown) is used.
    pub fn realistic_structure(known: [Option<T>; 5]) -> Result<PhysicalStructure<T>> {
        let edges = [(3, 0, "k2/M"), (4, 0, "b/M")];
        let one = T::one();
        let body =
            [tt(-one, 0, st(0)), tt(-one, 1, st(1)), TemplateTerm { coef: one, edge: Some(OFFSET), basis: Basis::One }];
        let absent = "the tyre force k1 (u - zw): the wheel's absolute position and the road height, which \
                      accelerometers and a deflection sensor do not measure (record the state sensors, or a \
                      wheel-force sensor)";
        Builder { states: 3, constants: &Self::CONSTANTS, edges: &edges, known: &known, absent }
            .build(&[(2, &body)], &[(0, &[tk(one, st(1))])])
    }
}

/// What a constant in none of the state sensors' equations would need (every constant of the
/// quarter and half car appears in them, so this is never said).
pub(crate) const STATE_SENSORS_READ_ALL: &str = "signals these equations do not read";

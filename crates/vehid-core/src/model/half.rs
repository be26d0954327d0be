//! The half car (Eq 6.1–6.8).

use super::physical::{der, st, tk, tt, Builder, PhysicalStructure, TemplateTerm};
use super::quarter::STATE_SENSORS_READ_ALL;
use super::{scale_ls, LinearModel, RowSet};
use crate::error::{check_finite, check_positive};
use crate::{Error, Real, Result};
use nalgebra::SMatrix;

/// The half-car (heave and pitch) suspension of Eq 6.1–6.8, linearized for small pitch.
///
/// State `x = [x1, ẋ1, x2, ẋ2, x3, ẋ3, φ, φ̇]`: front wheel, rear wheel, body heave (m, m/s)
/// and body pitch (rad, rad/s). Inputs `u = [u1, u2]`: the road under the front and the rear
/// wheel (m). `B` has `k11/m1` in row 1 and `k21/m2` in row 3 (0-based). Unknown rows
/// 1, 3, 5, 7: 32 parameters, 4 of them structurally zero (row 1 at x2, ẋ2; row 3 at x1, ẋ1).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct HalfCar<T> {
    p: HalfCarParams<T>,
}

/// The physical constants of a [`HalfCar`], in the order of the thesis (Eq 6.1–6.6).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
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

    /// A typical passenger car, one side of a mid-size sedan in the pitch plane (the half
    /// of the car over one wheel track; each corner close to [`super::QuarterCar::passenger`]):
    /// M = 640 kg, J = 1040 kg·m², l1 = 1.2 m (CG to front axle), l2 = 1.5 m (to rear),
    /// front/rear spring k12 = 24 kN/m, k22 = 22 kN/m, dampers b1 = 1.6 kN·s/m,
    /// b2 = 1.4 kN·s/m, wheel masses m1 = 40 kg, m2 = 35 kg, tyres k11 = k21 = 200 kN/m.
    ///
    /// Typical values, not one car's data: Gillespie, *Fundamentals of Vehicle Dynamics*
    /// (SAE 1992), Ch. 5 "Ride" (body bounce 1–1.5 Hz with the rear slightly above the front,
    /// damping ratio 0.2–0.4, dynamic index `J/(M l1 l2)` near 1 on most cars), Wong, *Theory
    /// of Ground Vehicles* (4th ed., 2008), Ch. 7. These give a static load of 356 kg over the
    /// front axle and 284 kg over the rear (56 % front), corner bounce frequencies
    /// `√(k2 / M_corner)/2π` of 1.31 Hz front and 1.40 Hz rear, damping ratios 0.27 and 0.28,
    /// wheel hop near 11.9 Hz, and a dynamic index of 0.90.
    pub fn passenger() -> Self {
        let c = T::of;
        Self {
            p: HalfCarParams {
                k11: c(200_000.0),
                k21: c(200_000.0),
                k12: c(24_000.0),
                k22: c(22_000.0),
                b1: c(1_600.0),
                b2: c(1_400.0),
                m1: c(40.0),
                m2: c(35.0),
                m_body: c(640.0),
                j: c(1_040.0),
                l1: c(1.2),
                l2: c(1.5),
            },
        }
    }

    /// Builds the half car from its constants in the order of [`HalfCar::CONSTANTS`]
    /// (`M, J, k11, k21, k12, k22, b1, b2, m1, m2, l1, l2`).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the first constant that is not finite and > 0.
    pub fn from_constants(c: [T; 12]) -> Result<Self> {
        let [m_body, j, k11, k21, k12, k22, b1, b2, m1, m2, l1, l2] = c;
        Self::new(HalfCarParams { k11, k21, k12, k22, b1, b2, m1, m2, m_body, j, l1, l2 })
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

    /// The constants' names, in the order [`HalfCar::structure`] and [`HalfCar::constants`]
    /// use.
    pub const CONSTANTS: [&'static str; 12] =
        ["M", "J", "k11", "k21", "k12", "k22", "b1", "b2", "m1", "m2", "l1", "l2"];

    /// The constants' values in the order of [`HalfCar::CONSTANTS`].
    pub fn constants(&self) -> [T; 12] {
        let p = self.p;
        [p.m_body, p.j, p.k11, p.k21, p.k12, p.k22, p.b1, p.b2, p.m1, p.m2, p.l1, p.l2]
    }

    /// The half car's physical structure (see [`PhysicalStructure`]), states
    /// `z1, v1, z2, v2, zb, vb, ph, om` (front wheel, rear wheel, body heave, pitch), with the
    /// constants given in `known` (order of [`HalfCar::CONSTANTS`]) fixed; the lever arms
    /// `l1`, `l2` must be known. With `d1 = zb + l1 ph − z1`, `d2 = zb − l2 ph − z2` (the
    /// suspension extensions) and `L = l1 + l2`:
    ///
    /// ```text
    /// v̇b = −(k12/M) d1 − (b1/M) ḋ1 − (k22/M) d2 − (b2/M) ḋ2                  heave (Eq 6.3 / M)
    /// ȯm = −l1 (k12/J) d1 − l1 (b1/J) ḋ1 + l2 (k22/J) d2 + l2 (b2/J) ḋ2      pitch (Eq 6.4 / J)
    /// v̇1 = −(l2/L)(M/m1) der(vb) − (1/L)(J/m1) der(om) − (k11/m1) z1         front wheel
    /// v̇2 = −(l1/L)(M/m2) der(vb) + (1/L)(J/m2) der(om) − (k21/m2) z2         rear wheel
    /// ```
    ///
    /// The wheel equations are Eq 6.1–6.2 with each suspension force read from the body's
    /// measured heave and pitch accelerations (solving Eq 6.3–6.4 for the two forces), so the
    /// road, which enters only the wheel equations, meets three parameters per wheel, and
    /// with the wheel masses known the two wheels share `M` and `J`. With `m1, m2, l1, l2`
    /// known: 12 parameters for the 28 non-zero entries of the four rows.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a known value not finite and > 0 or unknown lever arms;
    /// [`Error::NotIdentifiable`] when nothing is left to identify.
    pub fn structure(known: [Option<T>; 12]) -> Result<PhysicalStructure<T>> {
        let (Some(l1), Some(l2)) = (known[10], known[11]) else {
            return Err(Error::InvalidArgument {
                arg: "known",
                expected: "the lever arms l1 and l2 among the known constants (they are coefficients of the half \
                           car's equations)",
            });
        };
        crate::error::check_positive("l1", l1)?;
        crate::error::check_positive("l2", l2)?;
        // Constants: 0 M, 1 J, 2 k11, 3 k21, 4 k12, 5 k22, 6 b1, 7 b2, 8 m1, 9 m2.
        let edges = [
            (4, 0, "k12/M"),
            (6, 0, "b1/M"),
            (5, 0, "k22/M"),
            (7, 0, "b2/M"),
            (4, 1, "k12/J"),
            (6, 1, "b1/J"),
            (5, 1, "k22/J"),
            (7, 1, "b2/J"),
            (0, 8, "M/m1"),
            (1, 8, "J/m1"),
            (2, 8, "k11/m1"),
            (0, 9, "M/m2"),
            (1, 9, "J/m2"),
            (3, 9, "k21/m2"),
        ];
        let one = T::one();
        let l = l1 + l2;
        // c × edge × (extension): d1 = zb + l1 ph − z1 (positions 4, 6, 0; velocities 5, 7, 1),
        // d2 = zb − l2 ph − z2 (positions 4, 6, 2; velocities 5, 7, 3).
        let ext = |c: T, e: u8, front: bool, vel: bool| -> [TemplateTerm<T>; 3] {
            let o = u8::from(vel);
            let (arm, wheel) = if front { (l1, 0) } else { (-l2, 2) };
            [tt(c, e, st(4 + o)), tt(c * arm, e, st(6 + o)), tt(-c, e, st(wheel + o))]
        };
        let cat = |parts: [[TemplateTerm<T>; 3]; 4]| -> [TemplateTerm<T>; 12] {
            let mut out = [parts[0][0]; 12];
            for (i, p) in parts.iter().enumerate() {
                out[3 * i..3 * i + 3].copy_from_slice(p);
            }
            out
        };
        let heave = cat([
            ext(-one, 0, true, false),
            ext(-one, 1, true, true),
            ext(-one, 2, false, false),
            ext(-one, 3, false, true),
        ]);
        let pitch =
            cat([ext(-l1, 4, true, false), ext(-l1, 5, true, true), ext(l2, 6, false, false), ext(l2, 7, false, true)]);
        let front = [tt(-l2 / l, 8, der(5)), tt(-one / l, 9, der(7)), tt(-one, 10, st(0))];
        let rear = [tt(-l1 / l, 11, der(5)), tt(one / l, 12, der(7)), tt(-one, 13, st(2))];
        let k = |i: u8| [tk(one, st(i))];
        let (k0, k2, k4, k6) = (k(1), k(3), k(5), k(7));
        Builder { states: 8, constants: &Self::CONSTANTS, edges: &edges, known: &known, absent: STATE_SENSORS_READ_ALL }
            .build(&[(5, &heave), (7, &pitch), (1, &front), (3, &rear)], &[(0, &k0), (2, &k2), (4, &k4), (6, &k6)])
    }
}

/// A half-car constant that can change during a drive (`sim::HalfDrive`) or that the half
/// car's health monitor names (`health::HalfHealthMonitor`). Names per axle (`_f` front,
/// `_r` rear); the thesis' names in brackets. The lever arms `l1`, `l2` do not change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum HalfConstant {
    /// Body mass `M`, kg. (The health monitor's body-mass events assume the pitch inertia
    /// `J` scales with it: a load spread like the body's own mass.)
    BodyMass,
    /// Body pitch inertia `J`, kg·m².
    PitchInertia,
    /// Front tyre stiffness (`k11`), N/m.
    FrontTyre,
    /// Rear tyre stiffness (`k21`), N/m.
    RearTyre,
    /// Front suspension spring (`k12`), N/m.
    FrontSpring,
    /// Rear suspension spring (`k22`), N/m.
    RearSpring,
    /// Front damper (`b1`), N·s/m.
    FrontDamper,
    /// Rear damper (`b2`), N·s/m.
    RearDamper,
    /// Front wheel mass (`m1`), kg.
    FrontWheelMass,
    /// Rear wheel mass (`m2`), kg.
    RearWheelMass,
}

option_names!(HalfConstant, "constant", {
    BodyMass => "M", PitchInertia => "J", FrontTyre => "k1_f", RearTyre => "k1_r", FrontSpring => "k2_f",
    RearSpring => "k2_r", FrontDamper => "b_f", RearDamper => "b_r", FrontWheelMass => "m_f", RearWheelMass => "m_r"
});

impl HalfConstant {
    /// Position in [`HalfCar::constants`] (`M, J, k11, k21, k12, k22, b1, b2, m1, m2, l1, l2`).
    pub fn index(&self) -> usize {
        match self {
            HalfConstant::BodyMass => 0,
            HalfConstant::PitchInertia => 1,
            HalfConstant::FrontTyre => 2,
            HalfConstant::RearTyre => 3,
            HalfConstant::FrontSpring => 4,
            HalfConstant::RearSpring => 5,
            HalfConstant::FrontDamper => 6,
            HalfConstant::RearDamper => 7,
            HalfConstant::FrontWheelMass => 8,
            HalfConstant::RearWheelMass => 9,
        }
    }
}

//! The full car: four corners, body heave, pitch and roll (the 7-degree-of-freedom ride model).

use super::{LinearModel, RowSet};
use crate::error::{check_nonneg, check_positive};
use crate::{Error, Real, Result};
use nalgebra::SMatrix;

/// The corners' suffixes, in the order every per-corner array uses: front left, front right,
/// rear left, rear right.
pub const CORNERS: [&str; 4] = ["fl", "fr", "rl", "rr"];

/// Number of states of a [`FullCar`].
pub const FULL_STATES: usize = 14;

/// Number of constants of a [`FullCar`] ([`FullCar::CONSTANTS`]).
pub const FULL_CONSTANTS: usize = 25;

/// The state names of a [`FullCar`], in state order (module documentation of [`FullCar`]).
pub const FULL_STATE_NAMES: [&str; FULL_STATES] = [
    "z_fl",
    "v_fl",
    "z_fr",
    "v_fr",
    "z_rl",
    "v_rl",
    "z_rr",
    "v_rr",
    "zb",
    "vb",
    "pitch",
    "pitch_rate",
    "roll",
    "roll_rate",
];

/// The full-car (heave, pitch, roll) ride model, linearized for small angles: a rigid body on
/// four suspension corners, each a spring and a damper to an unsprung mass on a tyre spring.
///
/// **State** `x` (14): each corner's wheel position and velocity, front left, front right,
/// rear left, rear right (`z_fl, v_fl, …, z_rr, v_rr`: m, m/s, indices `2i, 2i+1`), then the
/// body heave `zb, vb` (m, m/s, indices 8, 9), pitch `θ, θ̇` (rad, rad/s, nose up positive,
/// indices 10, 11) and roll `φ, φ̇` (rad, rad/s, left side up positive, indices 12, 13): the
/// order of [`FULL_STATE_NAMES`]. **Inputs** `u` (4): the road height under each wheel (m), in
/// corner order. Positions are deviations from the static equilibrium.
///
/// **Geometry.** The centre of mass is on the car's centreline, `l_f` behind the front axle
/// and `l_r` ahead of the rear one; corner `i` sits at `x_i = +l_f` (front) or `−l_r` (rear)
/// and `y_i = +t/2` (left) or `−t/2` (right), `t` the axle's track width (`track_f`,
/// `track_r`). The suspension extension of corner `i` is
/// `d_i = zb + x_i θ + y_i φ − z_i`.
///
/// **Forces.** The suspension pushes the body with `F_i = −k_i d_i − b_i ḋ_i − F_arb,i`. An
/// anti-roll bar of roll stiffness `K` (N·m/rad, `arb_f`, `arb_r`; 0 for none) is a torsion
/// spring between the axle's two corners: `F_arb,l = K (d_l − d_r) / t²`, `F_arb,r = −F_arb,l`
/// (with the wheels held it adds `K` to the axle's roll stiffness `t² (k_l + k_r) / 4`, and
/// nothing in heave or pitch). The equations of motion (Newton–Euler, small angles):
///
/// ```text
/// M  v̇b = Σ F_i            Jy θ̈ = Σ x_i F_i           Jx φ̈ = Σ y_i F_i
/// m_i v̇_i = −F_i − kt_i (z_i − u_i)                       (each corner)
/// ```
///
/// (e.g. Gillespie, *Fundamentals of Vehicle Dynamics*, SAE 1992, Ch. 5; Jazar, *Vehicle
/// Dynamics*, 2nd ed., Springer 2014, §15.5 "Full car vibrating model"). With equal left and
/// right corners and equal roads under both sides, roll stays zero and the car is the
/// [`super::HalfCar`] with half the body mass and pitch inertia.
///
/// **What data determine.** From the full state (positions, velocities and their derivatives)
/// the seven acceleration rows are identified as for any [`LinearModel`]; the body rows see no
/// road, and [`FullCar::from_theta`] reads every ratio from them (`k_i/M`, `b_i/M`, `Jy/M`,
/// `Jx/M`, the bars over `M`) and the one scale `M` from the wheel rows, given the wheel
/// masses, `B` (the tyres over the wheel masses) and the geometry. With the realistic sensors
/// of a drive (a body accelerometer above each wheel, wheel accelerometers, the four
/// suspension extensions `d_i`) the body equations are fully measured: `M z̈b = Σ F_i`,
/// `Jy θ̈ = Σ x_i F_i`, `Jx φ̈ = Σ y_i F_i` with `F_i = −k_i d_i − b_i ḋ_i − F_arb,i` (the four
/// body accelerometers give `z̈b`, `θ̈`, `φ̈` with one to spare), so they determine the same
/// ratios `k_i/M`, `b_i/M`, `arb/M`, `Jy/M`, `Jx/M` up to the common scale `M`; the tyres
/// `kt_i` and the wheel masses `m_i` are not determined, because the wheel equations hold the
/// tyre force `kt_i (z_i − u_i)`, which needs the wheel's height over the road that no sensor
/// reads (the quarter car's realistic structure says the same of `k1` and `m`). A known body
/// mass (or one known spring) fixes the scale. No estimator for the full car's realistic
/// sensors is built yet.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct FullCar<T> {
    p: FullCarParams<T>,
}

/// The physical constants of a [`FullCar`]; per-corner arrays in the order of [`CORNERS`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct FullCarParams<T> {
    /// Body (sprung) mass `M`, kg.
    pub m_body: T,
    /// Body roll inertia `Jx` about the longitudinal axis through the centre of mass, kg·m².
    pub jx: T,
    /// Body pitch inertia `Jy` about the lateral axis through the centre of mass, kg·m².
    pub jy: T,
    /// Tyre stiffness per corner `kt_*`, N/m.
    pub kt: [T; 4],
    /// Suspension spring per corner `k_*`, N/m (at the wheel).
    pub k: [T; 4],
    /// Suspension damper per corner `b_*`, N·s/m (at the wheel).
    pub b: [T; 4],
    /// Unsprung (wheel) mass per corner `m_*`, kg.
    pub m: [T; 4],
    /// Distance from the centre of mass to the front axle `l_f`, m.
    pub l_f: T,
    /// Distance from the centre of mass to the rear axle `l_r`, m.
    pub l_r: T,
    /// Front track width (between the front wheels' centres) `track_f`, m.
    pub track_f: T,
    /// Rear track width `track_r`, m.
    pub track_r: T,
    /// Front anti-roll bar roll stiffness `arb_f`, N·m/rad (≥ 0; 0: none).
    pub arb_f: T,
    /// Rear anti-roll bar roll stiffness `arb_r`, N·m/rad (≥ 0; 0: none).
    pub arb_r: T,
}

impl<T: Real> FullCarParams<T> {
    /// The constants with their names (those of [`FullCar::CONSTANTS`], in that order).
    pub fn named(&self) -> [(&'static str, T); FULL_CONSTANTS] {
        let v = FullCar::from_params_unchecked(*self).constants();
        let mut out = [("", T::zero()); FULL_CONSTANTS];
        for (o, (n, x)) in out.iter_mut().zip(FullCar::<T>::CONSTANTS.iter().zip(v)) {
            *o = (n, x);
        }
        out
    }
}

impl<T: Real> Default for FullCar<T> {
    /// A symmetric car (left = right, front = rear, centre of mass midway): M = 1200 kg,
    /// Jx = 450 kg·m², Jy = 1800 kg·m², each corner k = 25 kN/m, b = 1.5 kN·s/m, m = 40 kg,
    /// kt = 200 kN/m; l_f = l_r = 1.35 m, tracks 1.5 m, no anti-roll bars. Heave, pitch and
    /// roll decouple (the tests' closed forms).
    fn default() -> Self {
        let c = T::of;
        Self::from_params_unchecked(FullCarParams {
            m_body: c(1200.0),
            jx: c(450.0),
            jy: c(1800.0),
            kt: [c(200_000.0); 4],
            k: [c(25_000.0); 4],
            b: [c(1_500.0); 4],
            m: [c(40.0); 4],
            l_f: c(1.35),
            l_r: c(1.35),
            track_f: c(1.5),
            track_r: c(1.5),
            arb_f: T::zero(),
            arb_r: T::zero(),
        })
    }
}

impl<T: Real> FullCar<T> {
    /// The constants' names, in the order of [`FullCar::constants`] and
    /// [`FullCar::from_constants`]: body, tyres, springs, dampers, wheel masses (each in
    /// corner order), geometry, anti-roll bars.
    pub const CONSTANTS: [&'static str; FULL_CONSTANTS] = [
        "M", "Jx", "Jy", "kt_fl", "kt_fr", "kt_rl", "kt_rr", "k_fl", "k_fr", "k_rl", "k_rr", "b_fl", "b_fr", "b_rl",
        "b_rr", "m_fl", "m_fr", "m_rl", "m_rr", "l_f", "l_r", "track_f", "track_r", "arb_f", "arb_r",
    ];

    fn from_params_unchecked(p: FullCarParams<T>) -> Self {
        Self { p }
    }

    /// Builds the full car from its constants.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the first constant that is not finite and > 0 (the
    /// anti-roll bars: finite and ≥ 0).
    pub fn new(p: FullCarParams<T>) -> Result<Self> {
        let car = Self { p };
        for (name, v) in p.named() {
            if name.starts_with("arb") {
                check_nonneg(name, v)?;
            } else {
                check_positive(name, v)?;
            }
        }
        Ok(car)
    }

    /// Builds the full car from its constants in the order of [`FullCar::CONSTANTS`].
    ///
    /// # Errors
    /// As [`FullCar::new`].
    pub fn from_constants(c: [T; FULL_CONSTANTS]) -> Result<Self> {
        let q = |i: usize| [c[i], c[i + 1], c[i + 2], c[i + 3]];
        Self::new(FullCarParams {
            m_body: c[0],
            jx: c[1],
            jy: c[2],
            kt: q(3),
            k: q(7),
            b: q(11),
            m: q(15),
            l_f: c[19],
            l_r: c[20],
            track_f: c[21],
            track_r: c[22],
            arb_f: c[23],
            arb_r: c[24],
        })
    }

    /// A passenger car after the full-vehicle ride model of Ikenaga, Lewis, Campos and Davis,
    /// "Active suspension control of ground vehicle based on a full-vehicle model", *Proc.
    /// American Control Conference* 2000, pp. 4019–4024 (the parameter set as it is commonly
    /// reproduced in simulation studies): M = 1500 kg, Jx = 460 kg·m², Jy = 2160 kg·m²,
    /// l_f = 1.4 m, l_r = 1.7 m, springs 35 kN/m front and 38 kN/m rear, dampers 1000 N·s/m,
    /// unsprung masses 59 kg, tyres 190 kN/m (its small tyre damping is left out, as in
    /// [`super::HalfCar`]). The track widths, 1.5 m front and rear, are ours (a mid-size
    /// sedan: Gillespie, *Fundamentals of Vehicle Dynamics*, Ch. 5); no anti-roll bars.
    /// Static loads 411 kg per front corner and 339 kg per rear corner; its poles (the model's
    /// eigenvalues): body modes at 1.41, 1.90 and 1.96 Hz with damping ratios 0.10–0.14,
    /// wheel hop at 9.8–9.9 Hz (ratios ≈ 0.14–0.15): lightly damped.
    pub fn passenger() -> Self {
        let c = T::of;
        Self::from_params_unchecked(FullCarParams {
            m_body: c(1500.0),
            jx: c(460.0),
            jy: c(2160.0),
            kt: [c(190_000.0); 4],
            k: [c(35_000.0), c(35_000.0), c(38_000.0), c(38_000.0)],
            b: [c(1_000.0); 4],
            m: [c(59.0); 4],
            l_f: c(1.4),
            l_r: c(1.7),
            track_f: c(1.5),
            track_r: c(1.5),
            arb_f: T::zero(),
            arb_r: T::zero(),
        })
    }

    /// The constants.
    pub fn params(&self) -> FullCarParams<T> {
        self.p
    }

    /// The constants' values in the order of [`FullCar::CONSTANTS`].
    pub fn constants(&self) -> [T; FULL_CONSTANTS] {
        let p = &self.p;
        let mut c = [T::zero(); FULL_CONSTANTS];
        c[0] = p.m_body;
        c[1] = p.jx;
        c[2] = p.jy;
        c[3..7].copy_from_slice(&p.kt);
        c[7..11].copy_from_slice(&p.k);
        c[11..15].copy_from_slice(&p.b);
        c[15..19].copy_from_slice(&p.m);
        c[19..25].copy_from_slice(&[p.l_f, p.l_r, p.track_f, p.track_r, p.arb_f, p.arb_r]);
        c
    }

    /// Wheelbase `L = l_f + l_r`, m: the distance each rear wheel trails its front wheel.
    pub fn wheelbase(&self) -> T {
        self.p.l_f + self.p.l_r
    }

    /// Corner `i`'s position relative to the centre of mass `(x_i, y_i)`, m: forward and
    /// leftward (`i` in the order of [`CORNERS`]; `x = l_f` or `−l_r`, `y = ±track/2`).
    pub fn corner_position(&self, i: usize) -> (T, T) {
        let half = T::of(0.5);
        let front = i < 2;
        let x = if front { self.p.l_f } else { -self.p.l_r };
        let w = if front { self.p.track_f } else { self.p.track_r } * half;
        (x, if i % 2 == 0 { w } else { -w })
    }

    /// The unknown rows of `A` (0-based): the seven acceleration rows.
    pub fn unknown_rows(&self) -> [usize; 7] {
        [1, 3, 5, 7, 9, 11, 13]
    }

    /// The anti-roll bar of corner `i`'s axle as a linear stiffness between the two corners'
    /// extensions, `K / t²` (N/m).
    fn arb_linear(&self, i: usize) -> T {
        let (k, t) = if i < 2 { (self.p.arb_f, self.p.track_f) } else { (self.p.arb_r, self.p.track_r) };
        k / (t * t)
    }

    /// The suspension force on the body at each corner as a row over the state:
    /// `F_i = f_i · x` (N), with the anti-roll bars (type documentation).
    pub fn corner_force_rows(&self) -> [[T; FULL_STATES]; 4] {
        // Extension d_i = g_i · x over positions; ḋ_i the same over velocities.
        let mut g = [[T::zero(); FULL_STATES]; 4];
        for (i, gi) in g.iter_mut().enumerate() {
            let (x, y) = self.corner_position(i);
            gi[2 * i] = -T::one();
            gi[8] = T::one();
            gi[10] = x;
            gi[12] = y;
        }
        let mut f = [[T::zero(); FULL_STATES]; 4];
        for i in 0..4 {
            let partner = i ^ 1;
            let ka = self.arb_linear(i);
            for c in [0usize, 2, 4, 6, 8, 10, 12] {
                let kd = self.p.k[i] * g[i][c] + ka * (g[i][c] - g[partner][c]);
                f[i][c] = -kd;
                f[i][c + 1] = -self.p.b[i] * g[i][c];
            }
        }
        f
    }

    /// The linear model (14 states, 4 inputs): `A` from the equations of motion of the type
    /// documentation, `B` with `kt_i / m_i` in wheel `i`'s acceleration row (`2i + 1`).
    /// Structural zeros: a wheel's row at the other axle's wheels, and at its axle partner
    /// when that axle has no anti-roll bar.
    pub fn model(&self) -> LinearModel<T, FULL_STATES, 4> {
        let p = &self.p;
        let f = self.corner_force_rows();
        let mut a = SMatrix::<T, FULL_STATES, FULL_STATES>::zeros();
        for i in (0..FULL_STATES).step_by(2) {
            a[(i, i + 1)] = T::one();
        }
        for c in 0..FULL_STATES {
            let mut heave = T::zero();
            let mut pitch = T::zero();
            let mut roll = T::zero();
            for (i, fi) in f.iter().enumerate() {
                let (x, y) = self.corner_position(i);
                heave += fi[c];
                pitch += x * fi[c];
                roll += y * fi[c];
                a[(2 * i + 1, c)] = -fi[c] / p.m[i];
            }
            a[(9, c)] = heave / p.m_body;
            a[(11, c)] = pitch / p.jy;
            a[(13, c)] = roll / p.jx;
        }
        let mut b = SMatrix::<T, FULL_STATES, 4>::zeros();
        let mut zero = [[false; FULL_STATES]; FULL_STATES];
        for i in 0..4 {
            a[(2 * i + 1, 2 * i)] -= p.kt[i] / p.m[i];
            b[(2 * i + 1, i)] = p.kt[i] / p.m[i];
            let arb = if i < 2 { p.arb_f } else { p.arb_r };
            for j in 0..4 {
                let other_axle = (j < 2) != (i < 2);
                if other_axle || (j != i && arb == T::zero()) {
                    zero[2 * i + 1][2 * j] = true;
                    zero[2 * i + 1][2 * j + 1] = true;
                }
            }
            // A wheel's damper does not see the partner's position through the bar's velocity.
            zero[2 * i + 1][2 * (i ^ 1) + 1] = true;
        }
        let rows = RowSet { idx: [1, 3, 5, 7, 9, 11, 13, 0, 0, 0, 0, 0, 0, 0], len: 7 };
        LinearModel { a, b, rows, zero }
    }

    /// The mass matrix of the equations of motion, diagonal over the position states
    /// (`m_fl, m_fr, m_rl, m_rr, M, Jy, Jx`), for energy checks: `T = ½ Σ mass_j v_j²`.
    pub fn masses(&self) -> [T; 7] {
        let p = &self.p;
        [p.m[0], p.m[1], p.m[2], p.m[3], p.m_body, p.jy, p.jx]
    }

    /// The true unknown rows (`7 × 14`).
    pub fn theta(&self) -> SMatrix<T, 7, FULL_STATES> {
        let m = self.model();
        let rows = self.unknown_rows();
        SMatrix::<T, 7, FULL_STATES>::from_fn(|i, j| m.a()[(rows[i], j)])
    }

    /// The static equilibrium under gravity `g` (m/s²) on a flat road: the position states
    /// (`z_fl, z_fr, z_rl, z_rr, zb, θ, φ`, m and rad) measured from the unloaded springs'
    /// positions, from `K q = −g (m_fl, m_fr, m_rl, m_rr, M, 0, 0)` with `K` the stiffness
    /// block of `A` times the masses.
    ///
    /// # Errors
    /// [`Error::Singular`] if the stiffness matrix cannot be solved (not for valid constants).
    pub fn static_equilibrium(&self, g: T) -> Result<[T; 7]> {
        let a = self.model();
        let a = a.a();
        let mut k = SMatrix::<T, 7, 7>::zeros();
        for r in 0..7 {
            for c in 0..7 {
                k[(r, c)] = a[(2 * r + 1, 2 * c)];
            }
        }
        // Rows are accelerations: A_pos q = −g per translational row (gravity acceleration).
        let mut rhs = nalgebra::SVector::<T, 7>::zeros();
        for r in 0..5 {
            rhs[r] = g;
        }
        let q = k.lu().solve(&rhs).ok_or(Error::Singular { what: "the full car's stiffness matrix" })?;
        let mut out = [T::zero(); 7];
        out.copy_from_slice(q.as_slice());
        if out.iter().any(|v| !v.finite()) {
            return Err(Error::Singular { what: "the full car's stiffness matrix" });
        }
        Ok(out)
    }
}

#[path = "full_theta.rs"]
mod theta;

#[path = "full_corners.rs"]
mod corners;
pub use corners::{CORNER_DETERMINED, HALF_CORNER_DETERMINED};

#[cfg(test)]
#[path = "full_tests.rs"]
mod tests;

#[cfg(test)]
#[path = "full_identify_tests.rs"]
mod identify_tests;

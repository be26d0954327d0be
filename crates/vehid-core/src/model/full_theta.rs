//! The full car's constants from identified rows of `A` (the inverse of [`FullCar::model`]).

use super::{FullCar, FullCarParams, FULL_STATES};
use crate::error::{check_finite, check_positive};
use crate::model::scale_ls;
use crate::{Error, Real, Result};
use nalgebra::SMatrix;

impl<T: Real> FullCar<T> {
    /// Recovers the constants from identified rows (`7 × 14`, the acceleration rows 1, 3, …, 13
    /// of `A`) given what the rows cannot fix: the wheel masses `m` (kg, corner order), the
    /// input matrix's entries `kt_i / m_i` (`b_in`, 1/s², the thesis' "B known"), and the
    /// geometry `l_f, l_r, track_f, track_r` (m), all > 0.
    ///
    /// The body rows see no road, so on a road treated as noise they are the well-determined
    /// ones; everything but one scale is read from them. With `k_a = arb / t²` (type
    /// documentation of [`FullCar`]), the heave row holds `k_i / M` at `z_i` and `b_i / M` at
    /// `v_i` (the bars cancel), the pitch row `x_i k_i / Jy`, `x_i b_i / Jy`, the roll row
    /// `y_i (k_i + 2 k_a) / Jx` and `y_i b_i / Jx`. So `Jy / M` is the least-squares ratio of
    /// the pitch row's eight corner entries to `x_i` times the heave row's, `Jx / M` that of
    /// the roll row's four velocity entries, and `k_a / M` the mean over the axle's two wheels
    /// of `(roll entry · Jx/M / y_i − k_i/M) / 2`. The scale `M` is then the least-squares
    /// scale of the four wheel rows (with their known `−kt_i/m_i` put back) against the rows
    /// a car of body mass 1 with these ratios has. Exact on exact rows.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a known value not finite and > 0, non-finite θ;
    /// [`Error::NotIdentifiable`] when the rows do not give positive constants (the bars:
    /// a negative estimate is taken as 0).
    pub fn from_theta(theta: &SMatrix<T, 7, FULL_STATES>, m: [T; 4], b_in: [T; 4], geometry: [T; 4]) -> Result<Self> {
        check_finite("theta", theta.transpose().as_slice())?;
        for (name, v) in ["m_fl", "m_fr", "m_rl", "m_rr"].iter().zip(m) {
            check_positive(name, v)?;
        }
        for (name, v) in ["kt_fl/m_fl", "kt_fr/m_fr", "kt_rl/m_rl", "kt_rr/m_rr"].iter().zip(b_in) {
            check_positive(name, v)?;
        }
        for (name, v) in ["l_f", "l_r", "track_f", "track_r"].iter().zip(geometry) {
            check_positive(name, v)?;
        }
        let [l_f, l_r, track_f, track_r] = geometry;
        let half = T::of(0.5);
        let pos = |i: usize| {
            let x = if i < 2 { l_f } else { -l_r };
            let w = if i < 2 { track_f } else { track_r } * half;
            (x, if i % 2 == 0 { w } else { -w })
        };
        let (heave, pitch, roll) = (theta.row(4), theta.row(5), theta.row(6));
        // Per unit body mass: springs, dampers.
        let kappa: [T; 4] = core::array::from_fn(|i| heave[2 * i]);
        let beta: [T; 4] = core::array::from_fn(|i| heave[2 * i + 1]);
        let mut px = [T::zero(); 8];
        let mut py = [T::zero(); 8];
        let mut rv = [T::zero(); 4];
        let mut ry = [T::zero(); 4];
        for i in 0..4 {
            let (x, y) = pos(i);
            px[2 * i] = x * kappa[i];
            px[2 * i + 1] = x * beta[i];
            py[2 * i] = pitch[2 * i];
            py[2 * i + 1] = pitch[2 * i + 1];
            rv[i] = y * beta[i];
            ry[i] = roll[2 * i + 1];
        }
        // pitch entry = (M/Jy) · x_i k_i/M: the scale is M/Jy.
        let m_over_jy = scale_ls(&px, py.into_iter(), "Jy (pitch row)")?;
        let m_over_jx = scale_ls(&rv, ry.into_iter(), "Jx (roll row's damper entries)")?;
        let mut ka = [T::zero(); 2];
        for (axle, ka) in ka.iter_mut().enumerate() {
            let mut sum = T::zero();
            for i in [2 * axle, 2 * axle + 1] {
                let (_, y) = pos(i);
                sum += (roll[2 * i] / m_over_jx / y - kappa[i]) * half;
            }
            *ka = (sum * half).max(T::zero());
        }
        let not_positive = || Error::NotIdentifiable {
            what: "positive full-car constants from these rows (is the estimate converged?)",
        };
        let kt: [T; 4] = core::array::from_fn(|i| b_in[i] * m[i]);
        let mut p = FullCarParams {
            m_body: T::one(),
            jx: T::one() / m_over_jx,
            jy: T::one() / m_over_jy,
            kt,
            k: kappa,
            b: beta,
            m,
            l_f,
            l_r,
            track_f,
            track_r,
            arb_f: ka[0] * track_f * track_f,
            arb_r: ka[1] * track_r * track_r,
        };
        let unit = FullCar::new(p).map_err(|_| not_positive())?;
        // The wheel rows are linear in M once the tyre's known term is put back.
        let a1 = unit.model();
        let mut pattern = [T::zero(); 4 * FULL_STATES];
        let mut target = [T::zero(); 4 * FULL_STATES];
        for i in 0..4 {
            for c in 0..FULL_STATES {
                let tyre = if c == 2 * i { b_in[i] } else { T::zero() };
                pattern[i * FULL_STATES + c] = a1.a()[(2 * i + 1, c)] + tyre;
                target[i * FULL_STATES + c] = theta[(i, c)] + tyre;
            }
        }
        let mass = scale_ls(&pattern, target.into_iter(), "M (wheel rows)")?;
        p.m_body = mass;
        p.jx *= mass;
        p.jy *= mass;
        p.k = p.k.map(|v| v * mass);
        p.b = p.b.map(|v| v * mass);
        p.arb_f *= mass;
        p.arb_r *= mass;
        FullCar::new(p).map_err(|_| not_positive())
    }
}

/// Number of entries of the identified rows of a [`FullCar`] (7 rows × 14 states).
pub const FULL_THETA: usize = 7 * FULL_STATES;

impl<T: Real> FullCar<T> {
    /// [`FullCar::from_theta`] with each constant's standard error by the delta method:
    /// `se_c² = g_cᵀ Σ g_c`, `g_c` the gradient of constant `c` with respect to the 98 row
    /// entries (central differences, a step of `10⁻⁶` of each entry's magnitude, at least
    /// `10⁻⁹`), `cov` the entries' covariance (`98 × 98`, row-major, entries in `theta`'s
    /// row-major order, as an identifier's `covariance_into` gives it). First order in the
    /// entries' errors; the known constants have standard error 0, and so has a bar estimated
    /// at its bound 0.
    ///
    /// # Errors
    /// As [`FullCar::from_theta`]; [`Error::Shape`] for a `cov` of another length,
    /// [`Error::NonFinite`] for NaN/inf in it.
    pub fn from_theta_se(
        theta: &SMatrix<T, 7, FULL_STATES>,
        cov: &[T],
        m: [T; 4],
        b_in: [T; 4],
        geometry: [T; 4],
    ) -> Result<(Self, [T; super::FULL_CONSTANTS])> {
        if cov.len() != FULL_THETA * FULL_THETA {
            return Err(Error::Shape { arg: "cov", expected: FULL_THETA * FULL_THETA, got: cov.len() });
        }
        check_finite("cov", cov)?;
        let car = Self::from_theta(theta, m, b_in, geometry)?;
        let mut grad = [[T::zero(); FULL_THETA]; super::FULL_CONSTANTS];
        for j in 0..FULL_THETA {
            let (r, c) = (j / FULL_STATES, j % FULL_STATES);
            let h = (theta[(r, c)].abs() * T::of(1e-6)).max(T::of(1e-9));
            let mut up = *theta;
            up[(r, c)] += h;
            let mut down = *theta;
            down[(r, c)] -= h;
            let hi = Self::from_theta(&up, m, b_in, geometry)?.constants();
            let lo = Self::from_theta(&down, m, b_in, geometry)?.constants();
            for (g, (a, b)) in grad.iter_mut().zip(hi.iter().zip(lo.iter())) {
                g[j] = (*a - *b) / (h + h);
            }
        }
        let mut se = [T::zero(); super::FULL_CONSTANTS];
        for (s, g) in se.iter_mut().zip(grad.iter()) {
            let mut v = T::zero();
            for a in 0..FULL_THETA {
                if g[a] == T::zero() {
                    continue;
                }
                for b in 0..FULL_THETA {
                    v += g[a] * cov[a * FULL_THETA + b] * g[b];
                }
            }
            *s = v.max(T::zero()).sqrt();
        }
        Ok((car, se))
    }
}

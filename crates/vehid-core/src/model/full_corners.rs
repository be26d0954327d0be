//! The full car's constants from its four body-corner equations, the half car's from its two:
//! the coefficients the realistic sensors determine ([`crate::identify::CornerFilterFit`]).

use super::FullCar;
use crate::error::{check_finite, check_positive};
use crate::model::HalfCar;
use crate::{Error, Result};
use nalgebra::{Cholesky, SMatrix};

/// The constants the body-corner equations determine with the body mass known, in the order
/// [`FullCar::from_corner_coefficients`] returns their standard errors.
pub const CORNER_DETERMINED: [&str; 12] =
    ["Jx", "Jy", "k_fl", "k_fr", "k_rl", "k_rr", "b_fl", "b_fr", "b_rl", "b_rr", "arb_f", "arb_r"];

/// Coefficients fitted: each equation's eight spring and damper coefficients (not its offset).
const FITTED: usize = 32;
/// Unknowns: `k` ×4, `b` ×4, `1/Jx`, `1/Jy`, `arb_f/t_f²`, `arb_r/t_r²`.
const UNKNOWNS: usize = 12;

/// The 32 spring and damper coefficients (equation by equation: `Θ_r,i` at `8 i + r`) of the
/// car `base` with the unknowns `p` (order of [`UNKNOWNS`]) put in: the monitor's
/// [`crate::health::full_coefficients`] on it, unchecked (a Gauss–Newton trial step may leave
/// the constants' ranges).
fn coefficients(base: &super::FullCarParams<f64>, p: &[f64; UNKNOWNS]) -> SMatrix<f64, FITTED, 1> {
    let mut c = *base;
    c.k = [p[0], p[1], p[2], p[3]];
    c.b = [p[4], p[5], p[6], p[7]];
    c.jx = 1.0 / p[8];
    c.jy = 1.0 / p[9];
    c.arb_f = p[10] * c.track_f * c.track_f;
    c.arb_r = p[11] * c.track_r * c.track_r;
    SMatrix::from_column_slice(crate::health::full_coefficients(&FullCar::from_params_unchecked(c)).as_slice())
}

impl FullCar<f64> {
    /// The spring, damper, roll and pitch constants from the coefficients of the four
    /// body-corner equations (`theta`: 36 values, corner `i`'s nine at `9 i`, the order of
    /// [`crate::identify::CornerFilterFit::stats`]) and their covariance `cov` (36 × 36,
    /// row-major), given the body mass `m_body` (kg) — the equations determine every constant
    /// only relative to it — and the geometry of `self` (`l_f`, `l_r` and the tracks); `self`'s
    /// other constants start the fit and are kept where the equations say nothing (the tyres
    /// and the wheel masses: no road term, no wheel equation).
    ///
    /// `Θ` is multilinear in `p = [k_j, b_j, 1/Jx, 1/Jy, arb_f/t_f², arb_r/t_r²]`: with `1/Jx`
    /// and `1/Jy` fixed it is linear in the rest, and the other way round. Gauss–Newton on the
    /// 32 spring and damper coefficients, each weighted by its inverse variance (not the full
    /// covariance: with equal tracks it is nearly singular, module documentation of
    /// [`crate::identify::CornerFilterFit`]), from `self`'s values; the covariance of `p` is the
    /// sandwich `G cov Gᵀ`, `G = (JᵀWJ)⁻¹ JᵀW`, mapped to the constants (`Jx = 1/p₈`, …).
    /// Returns the car, the estimates of [`CORNER_DETERMINED`] and their standard errors (kg·m²,
    /// N/m, N·s/m, N·m/rad). An anti-roll bar's estimate may be below 0 on a car without one
    /// (its scatter about 0): the estimates keep it, the car takes it as 0. Exact on exact
    /// coefficients.
    ///
    /// # Errors
    /// [`Error::Shape`] for `theta` or `cov` of other lengths; [`Error::InvalidArgument`] for
    /// non-finite values or `m_body` not > 0; [`Error::RankDeficient`] when the coefficients do
    /// not determine the constants (a corner without excitation); [`Error::NotIdentifiable`]
    /// when the fit does not converge or gives an inertia, spring or damper ≤ 0, which
    /// coefficients of a rigid body on four suspensions cannot give.
    pub fn from_corner_coefficients(
        &self,
        theta: &[f64],
        cov: &[f64],
        m_body: f64,
    ) -> Result<(Self, [f64; 12], [f64; 12])> {
        let (obs, sigma) = fitted::<36, FITTED>(theta, cov, m_body)?;
        let s = self.params();
        let pos: [(f64, f64); 4] = core::array::from_fn(|i| self.corner_position(i));
        let (tf2, tr2) = (s.track_f * s.track_f, s.track_r * s.track_r);
        let inv_m = 1.0 / m_body;
        let base = super::FullCarParams { m_body, ..s };
        // The start: self's inertias and bars; each spring and damper from its own coefficient.
        let mut p = [0.0; UNKNOWNS];
        p[8] = 1.0 / s.jx;
        p[9] = 1.0 / s.jy;
        p[10] = s.arb_f / tf2;
        p[11] = s.arb_r / tr2;
        for (j, (x, y)) in pos.iter().enumerate() {
            let own = inv_m + x * x * p[9] + y * y * p[8];
            p[j] = (theta[9 * j + 2 * j] / own).max(s.k[j] * 1e-3);
            p[4 + j] = (theta[9 * j + 2 * j + 1] / own).max(s.b[j] * 1e-3);
        }
        let mean_k = s.k.iter().sum::<f64>() / 4.0;
        let scale: [f64; UNKNOWNS] = core::array::from_fn(|k| match k {
            0..=3 => s.k[k],
            4..=7 => s.b[k - 4],
            8 => p[8],
            9 => p[9],
            _ => mean_k,
        });
        let (p, se_p) = fit_coefficients(&obs, &sigma, p, scale, |p: &[f64; UNKNOWNS]| coefficients(&base, p))?;
        let mut c = s;
        c.m_body = m_body;
        c.jx = 1.0 / p[8];
        c.jy = 1.0 / p[9];
        c.k = [p[0], p[1], p[2], p[3]];
        c.b = [p[4], p[5], p[6], p[7]];
        c.arb_f = (p[10] * tf2).max(0.0);
        c.arb_r = (p[11] * tr2).max(0.0);
        let car = FullCar::new(c).map_err(|_| Error::NotIdentifiable {
            what: "the constants: the corner coefficients give an inertia, spring or damper <= 0, which no car has",
        })?;
        let values = [c.jx, c.jy, p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[10] * tf2, p[11] * tr2];
        let se = [
            se_p[8] / (p[8] * p[8]),
            se_p[9] / (p[9] * p[9]),
            se_p[0],
            se_p[1],
            se_p[2],
            se_p[3],
            se_p[4],
            se_p[5],
            se_p[6],
            se_p[7],
            se_p[10] * tf2,
            se_p[11] * tr2,
        ];
        Ok((car, values, se))
    }
}

/// The `N` coefficients of the corner equations (each equation's springs and dampers, then its
/// offset), their `N × N` covariance and the body mass checked; the `F` fitted ones (each
/// equation's all but its offset, equation by equation) and their covariance.
///
/// # Errors
/// [`Error::Shape`] naming `theta` or `cov`; [`Error::InvalidArgument`] for a value not finite,
/// `M` not > 0.
fn fitted<const N: usize, const F: usize>(
    theta: &[f64],
    cov: &[f64],
    m_body: f64,
) -> Result<(SMatrix<f64, F, 1>, SMatrix<f64, F, F>)> {
    if theta.len() != N {
        return Err(Error::Shape { arg: "theta", expected: N, got: theta.len() });
    }
    if cov.len() != N * N {
        return Err(Error::Shape { arg: "cov", expected: N * N, got: cov.len() });
    }
    check_finite("theta", theta)?;
    check_finite("cov", cov)?;
    check_positive("M", m_body)?;
    // N − F equations of `per` coefficients each, the last its offset.
    let per = N / (N - F);
    let at = |q: usize| per * (q / (per - 1)) + q % (per - 1);
    Ok((SMatrix::from_fn(|q, _| theta[at(q)]), SMatrix::from_fn(|q, r| cov[at(q) * N + at(r)])))
}

/// Fits the unknowns `p` of a multilinear map `model(p)` of corner coefficients to the observed
/// ones `obs` (covariance `sigma`): Gauss–Newton from `start`, each coefficient weighted by its
/// inverse variance, every step halved until downhill; the Jacobian by central differences
/// (exact to rounding: the map is linear in each unknown alone), steps `scale · 10⁻³`. Returns
/// `p` and its standard errors from the sandwich `G sigma Gᵀ`, `G = (JᵀWJ)⁻¹ JᵀW`.
///
/// # Errors
/// [`Error::InvalidArgument`] naming `cov` when no coefficient has a positive variance;
/// [`Error::RankDeficient`] when the coefficients do not determine the unknowns;
/// [`Error::NotIdentifiable`] when the fit does not converge in 100 steps.
fn fit_coefficients<const N: usize, const P: usize>(
    obs: &SMatrix<f64, N, 1>,
    sigma: &SMatrix<f64, N, N>,
    start: [f64; P],
    scale: [f64; P],
    model: impl Fn(&[f64; P]) -> SMatrix<f64, N, 1>,
) -> Result<([f64; P], [f64; P])> {
    let weight: [f64; N] = core::array::from_fn(|q| {
        let v = sigma[(q, q)];
        if v > 0.0 {
            1.0 / v
        } else {
            0.0
        }
    });
    if weight.iter().all(|w| *w == 0.0) {
        return Err(Error::InvalidArgument { arg: "cov", expected: "a covariance with positive variances" });
    }
    let cost = |p: &[f64; P]| {
        let r = obs - model(p);
        (0..N).map(|q| weight[q] * r[q] * r[q]).sum::<f64>()
    };
    let jacobian = |p: &[f64; P]| {
        let mut jac = SMatrix::<f64, N, P>::zeros();
        for k in 0..P {
            let h = scale[k] * 1e-3;
            let (mut up, mut down) = (*p, *p);
            up[k] += h;
            down[k] -= h;
            jac.set_column(k, &((model(&up) - model(&down)) / (2.0 * h)));
        }
        jac
    };
    let normal = |jac: &SMatrix<f64, N, P>| {
        let mut wj = *jac;
        for (q, w) in weight.iter().enumerate() {
            wj.row_mut(q).scale_mut(*w);
        }
        (jac.transpose() * wj, wj)
    };
    let deficient = Error::RankDeficient { rank: P - 1, needed: P };
    let mut p = start;
    let mut converged = false;
    let mut now = cost(&p);
    for _ in 0..100 {
        let jac = jacobian(&p);
        let (jtwj, wj) = normal(&jac);
        let chol = Cholesky::new(jtwj).ok_or(deficient.clone())?;
        let step = chol.solve(&(wj.transpose() * (obs - model(&p))));
        let mut t = 1.0;
        let mut next = p;
        let mut next_cost = f64::INFINITY;
        for _ in 0..30 {
            next = core::array::from_fn(|k| p[k] + t * step[k]);
            next_cost = cost(&next);
            if next_cost <= now {
                break;
            }
            t *= 0.5;
        }
        if !(next_cost <= now) {
            converged = true; // no downhill step left: at the minimum to rounding
            break;
        }
        let small = (0..P).all(|k| (t * step[k]).abs() <= 1e-12 * scale[k]);
        p = next;
        now = next_cost;
        if small {
            converged = true;
            break;
        }
    }
    if !converged {
        return Err(Error::NotIdentifiable {
            what: "the constants: the fit of the corner coefficients did not converge",
        });
    }
    let (jtwj, wj) = normal(&jacobian(&p));
    let chol = Cholesky::new(jtwj).ok_or(deficient)?;
    let gain = chol.solve(&wj.transpose()); // G = (JᵀWJ)⁻¹ JᵀW
    let cov_p = gain * sigma * gain.transpose();
    Ok((p, core::array::from_fn(|k| libm::sqrt(cov_p[(k, k)].max(0.0)))))
}

/// The constants the half car's two body-corner equations determine with the body mass known,
/// in the order [`HalfCar::from_corner_coefficients`] returns them.
pub const HALF_CORNER_DETERMINED: [&str; 5] = ["J", "k12", "k22", "b1", "b2"];

impl HalfCar<f64> {
    /// The pitch inertia, springs and dampers from the coefficients of the half car's two
    /// body-corner equations (`theta`: 10 values, front then rear, each `[α_i,f k12, α_i,f b1,
    /// α_i,r k22, α_i,r b2, c_i]` with `α_ij = 1/M + x_i x_j/J`, `x_f = l1`, `x_r = −l2`; the
    /// order of [`crate::identify::CornerFilterFit::stats`] for the half car) and their
    /// covariance `cov` (10 × 10, row-major), given the body mass `m_body` (kg) and `self`'s
    /// `l1`, `l2`; `self`'s other constants start the fit and are kept (the tyres and the wheel
    /// masses are not in these equations). As [`FullCar::from_corner_coefficients`]: a fit of
    /// `[k12, k22, b1, b2, 1/J]` weighted by the coefficients' variances, the sandwich
    /// covariance. Returns the car, the estimates of [`HALF_CORNER_DETERMINED`] (kg·m², N/m,
    /// N·s/m) and their standard errors. Exact on exact coefficients.
    ///
    /// # Errors
    /// As [`FullCar::from_corner_coefficients`].
    pub fn from_corner_coefficients(
        &self,
        theta: &[f64],
        cov: &[f64],
        m_body: f64,
    ) -> Result<(Self, [f64; 5], [f64; 5])> {
        let (obs, sigma) = fitted::<10, 8>(theta, cov, m_body)?;
        let s = self.params();
        let x = [s.l1, -s.l2];
        let inv_m = 1.0 / m_body;
        // p = [k12, k22, b1, b2, 1/J]; Θ_i = [α_if k12, α_if b1, α_ir k22, α_ir b2].
        let model = |p: &[f64; 5]| {
            let alpha = |i: usize, j: usize| inv_m + x[i] * x[j] * p[4];
            SMatrix::<f64, 8, 1>::from_fn(|q, _| {
                let (i, r) = (q / 4, q % 4);
                let j = r / 2;
                alpha(i, j) * if r % 2 == 0 { p[j] } else { p[2 + j] }
            })
        };
        let inv_j = 1.0 / s.j;
        let mut start = [0.0, 0.0, 0.0, 0.0, inv_j];
        for (j, own) in x.iter().map(|xj| inv_m + xj * xj * inv_j).enumerate() {
            start[j] = (theta[5 * j + 2 * j] / own).max([s.k12, s.k22][j] * 1e-3);
            start[2 + j] = (theta[5 * j + 2 * j + 1] / own).max([s.b1, s.b2][j] * 1e-3);
        }
        let scale = [s.k12, s.k22, s.b1, s.b2, start[4]];
        let (p, se_p) = fit_coefficients(&obs, &sigma, start, scale, model)?;
        let mut c = s;
        c.m_body = m_body;
        (c.k12, c.k22, c.b1, c.b2, c.j) = (p[0], p[1], p[2], p[3], 1.0 / p[4]);
        let car = HalfCar::new(c).map_err(|_| Error::NotIdentifiable {
            what: "the constants: the corner coefficients give an inertia, spring or damper <= 0, which no car has",
        })?;
        let values = [c.j, p[0], p[1], p[2], p[3]];
        let se = [se_p[4] / (p[4] * p[4]), se_p[0], se_p[1], se_p[2], se_p[3]];
        Ok((car, values, se))
    }
}

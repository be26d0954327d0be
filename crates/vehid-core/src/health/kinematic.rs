//! The suspension's deflection rate from a deflection sensor and two accelerometers: a
//! three-state steady-state Kalman filter (no allocation, no per-sample matrix algebra).

use crate::error::{check_nonneg, check_positive};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

/// Estimates the deflection `d = zb − zw` (m), its rate `ḋ` (m/s) and the bias `β` (m/s²)
/// of the relative acceleration `a = a_body − a_wheel` from samples of `d` and `a`.
///
/// State `s = [d, ḋ, β]`. Between samples `k − 1` and `k` the true relative acceleration
/// `d̈ = a − β` is taken linear between its two samples, which gives the prediction
///
/// ```text
/// d⁻ = d + dt ḋ + dt² (a_{k−1}/3 + a_k/6) − dt²/2 β
/// ḋ⁻ = ḋ + dt (a_{k−1} + a_k)/2 − dt β
/// β⁻ = β
/// ```
///
/// (`F = [[1, dt, −dt²/2], [0, 1, −dt], [0, 0, 1]]`), then the update with the measured
/// deflection `y_k = d_k + n`: `s = s⁻ + K (y_k − d⁻)`. The gain `K` is the steady state of
/// the Kalman filter with measurement variance `σ_d²` and process noise
/// `Q = σ_a² g gᵀ + diag(0, 0, q_β dt)`, `g = [dt²/2, dt, 0]` (accelerometer noise `σ_a` per
/// sample, a random-walk bias of density `q_β`), found at construction by iterating the
/// Riccati recursion `P⁻ = F P Fᵀ + Q`, `K = P⁻hᵀ/(h P⁻ hᵀ + σ_d²)`, `P = (I − K h) P⁻`
/// (`h = [1, 0, 0]`) to convergence (Anderson & Moore, *Optimal Filtering*, 1979, §4.4).
/// A steady-state gain costs about 20 flops per sample and behaves identically on every
/// vehicle of a fleet.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct DeflectionFilter<T> {
    dt: T,
    gain: [T; 3],
    innov_sd: T,
    s: [T; 3],
    prev_a: T,
    started: bool,
}

impl<T: Real> DeflectionFilter<T> {
    /// A filter for samples every `dt` seconds, relative-acceleration noise `accel_noise`
    /// (m/s² per sample), deflection noise `deflection_noise` (m) and bias random-walk
    /// density `bias_walk` (m/s² per √s).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the argument: `dt` and `deflection_noise` not finite
    /// and > 0, the others not finite and ≥ 0, or a Riccati recursion that does not settle.
    pub fn new(dt: T, accel_noise: T, deflection_noise: T, bias_walk: T) -> Result<Self> {
        check_positive("dt", dt)?;
        check_nonneg("accel_noise", accel_noise)?;
        check_positive("deflection_noise", deflection_noise)?;
        check_nonneg("bias_walk", bias_walk)?;
        let (sd, (f, q)) = (deflection_noise.to_f64(), model(dt, accel_noise, bias_walk));
        let r = sd * sd;
        let (k, innov) = settle::<1>(SMatrix::<f64, 3, 3>::identity() * (1e3 * r), |p| {
            let pm = f * p * f.transpose() + q;
            let innov = pm[(0, 0)] + r;
            let kn = pm.column(0) / innov;
            Some((pm - kn * pm.row(0), kn, innov))
        })?;
        Ok(Self {
            dt,
            gain: [T::of(k[0]), T::of(k[1]), T::of(k[2])],
            innov_sd: T::of(libm::sqrt(innov)),
            s: [T::zero(); 3],
            prev_a: T::zero(),
            started: false,
        })
    }

    /// The steady-state gain `K = [K_d, K_ḋ, K_β]`.
    pub fn gain(&self) -> [T; 3] {
        self.gain
    }

    /// The steady-state standard deviation of the innovation `y_k − d⁻`, m
    /// (`√(h P⁻ hᵀ + σ_d²)`).
    pub fn innovation_sd(&self) -> T {
        self.innov_sd
    }

    /// Forgets the deflection and its rate (after a gap): the next sample restarts the
    /// filter at the measured deflection with rate 0; the bias estimate is kept.
    pub fn reset(&mut self) {
        self.started = false;
    }

    /// The current estimate `[d, ḋ, β]`.
    pub fn state(&self) -> [T; 3] {
        self.s
    }

    /// As [`DeflectionFilter::update`], but returns `None` and changes nothing when the
    /// innovation exceeds `gate` standard deviations ([`DeflectionFilter::innovation_sd`]):
    /// the deflection disagrees with the integrated accelerations (a seam or a glitch).
    #[inline]
    pub fn update_gated(&mut self, d: T, a: T, gate: T) -> Option<(T, T)> {
        if self.started && (d - self.predict(a).0).abs() > gate * self.innov_sd {
            return None;
        }
        Some(self.update(d, a))
    }

    /// One sample: deflection `d` (m) and relative acceleration `a = a_body − a_wheel`
    /// (m/s²); returns `(d̂, ḋ̂)`. The caller passes finite values.
    #[inline]
    pub fn update(&mut self, d: T, a: T) -> (T, T) {
        if !self.started {
            self.s[0] = d;
            self.s[1] = T::zero();
            self.prev_a = a;
            self.started = true;
            return (self.s[0], self.s[1]);
        }
        let (dp, vp) = self.predict(a);
        let b0 = self.s[2];
        let nu = d - dp;
        self.s = [dp + self.gain[0] * nu, vp + self.gain[1] * nu, b0 + self.gain[2] * nu];
        self.prev_a = a;
        (self.s[0], self.s[1])
    }

    /// The prediction `(d⁻, ḋ⁻)` from the estimate and the relative accelerations `prev_a`
    /// and `a` (linear between the samples): `d⁻ = d + h ḋ + h² (a_{k−1}/3 + a_k/6) − h² β/2`,
    /// `ḋ⁻ = ḋ + h (a_{k−1} + a_k)/2 − h β`.
    #[inline(always)]
    fn predict(&self, a: T) -> (T, T) {
        let h = self.dt;
        let [d0, v0, b0] = self.s;
        let half = T::of(0.5);
        let dp = d0 + h * v0 + h * h * (self.prev_a * T::of(1.0 / 3.0) + a * T::of(1.0 / 6.0)) - h * h * half * b0;
        let vp = v0 + h * (self.prev_a + a) * half - h * b0;
        (dp, vp)
    }
}

/// The steady state of a Riccati recursion from `p0`: `step(P)` returns the next `P` (before
/// symmetrization), the gain `K` (`3 × C`) and the deflection's innovation variance, or `None`
/// when the innovation covariance is not positive definite. Iterates (at most 2·10⁶ times)
/// until no gain entry changes by more than `10⁻¹³ (1 + max |K|)`; returns `K` and that
/// variance.
///
/// # Errors
/// [`Error::InvalidArgument`] (`dt`) when the recursion does not settle or its gain is not
/// finite: with positive noise levels that happens only for sample intervals far below any
/// logger's (under about 10⁻⁷ s), so the interval is what the message names.
fn settle<const C: usize>(
    p0: SMatrix<f64, 3, 3>,
    step: impl Fn(&SMatrix<f64, 3, 3>) -> Option<(SMatrix<f64, 3, 3>, SMatrix<f64, 3, C>, f64)>,
) -> Result<(SMatrix<f64, 3, C>, f64)> {
    let (mut p, mut k) = (p0, SMatrix::<f64, 3, C>::zeros());
    for _ in 0..2_000_000 {
        let Some((pn, kn, innov)) = step(&p) else { break };
        let change = (kn - k).abs().max();
        (p, k) = ((pn + pn.transpose()) * 0.5, kn);
        if change <= 1e-13 * (1.0 + k.abs().max()) {
            if k.iter().all(|v| v.is_finite()) {
                return Ok((k, innov));
            }
            break;
        }
    }
    Err(Error::InvalidArgument {
        arg: "dt",
        expected: "a sample interval for which the deflection filter's gain settles with these noise levels (in \
                   seconds: 0.005 for 200 Hz; intervals under about 1e-7 s do not settle)",
    })
}

/// The filter's model for samples every `dt` seconds (f64, for the Riccati recursions): the
/// transition `F` of `[d, ḋ, β]` and the process noise `Q` of the relative acceleration's
/// noise `accel_noise` (through `g = [h²/2, h, 0]`) and the bias walk `bias_walk`, with a tiny
/// floor that keeps the recursion positive definite when every noise is zero.
fn model<T: Real>(dt: T, accel_noise: T, bias_walk: T) -> (SMatrix<f64, 3, 3>, SMatrix<f64, 3, 3>) {
    let (h, sa, qb) = (dt.to_f64(), accel_noise.to_f64(), bias_walk.to_f64());
    #[rustfmt::skip]
    let f = SMatrix::<f64, 3, 3>::new(
        1.0, h, -h * h / 2.0,
        0.0, 1.0, -h,
        0.0, 0.0, 1.0,
    );
    let g = SVector::<f64, 3>::new(h * h / 2.0, h, 0.0);
    let mut q = g * g.transpose() * (sa * sa);
    q[(2, 2)] += qb * qb * h;
    for i in 0..3 {
        q[(i, i)] += 1e-30;
    }
    (f, q)
}

/// The steady-state gain of [`DeflectionFilter`]'s state `[d, ḋ, β]` when the deflection
/// rate is measured too (the thesis' state sensors: `ḋ = vb − vw` from the two measured
/// velocities): measurements `y = [d + n_d, ḋ + n_v]`, `h = [[1, 0, 0], [0, 1, 0]]`, the same
/// prediction and process noise as [`DeflectionFilter`], and the update
/// `s = s⁻ + K (y − h s⁻)` with the `3 × 2` steady-state gain `K` of the Riccati recursion
/// `P⁻ = F P Fᵀ + Q`, `S = h P⁻ hᵀ + diag(σ_d², σ_v²)`, `K = P⁻ hᵀ S⁻¹`, `P = (I − K h) P⁻`.
///
/// Why (module documentation of [`crate::health`], "State sensors"): from the deflection
/// alone, formed from two noisy positions, the filter's `d̂`, `ḋ̂` carry an error that is
/// low-frequency (its autocorrelation 0.7 ten samples apart), and the tracked ratios then
/// scatter 2.7 times (`k2/M`) what `σ² P/(1 + λ)` assumes; with the measured rate the
/// error is small and nearly white and the scatter is what the formula says (1.1 times).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateGain<T> {
    gain: [[T; 2]; 3],
    innov_sd: T,
}

impl<T: Real> RateGain<T> {
    /// The gain for samples every `dt` seconds, relative-acceleration noise `accel_noise`,
    /// deflection noise `deflection_noise`, rate noise `rate_noise` (m/s) and bias random
    /// walk `bias_walk` (as [`DeflectionFilter::new`]).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the argument: `dt`, `deflection_noise` and
    /// `rate_noise` not finite and > 0, the others not finite and ≥ 0, or a recursion that does
    /// not settle.
    pub fn new(dt: T, accel_noise: T, deflection_noise: T, rate_noise: T, bias_walk: T) -> Result<Self> {
        check_positive("dt", dt)?;
        check_nonneg("accel_noise", accel_noise)?;
        check_positive("deflection_noise", deflection_noise)?;
        check_positive("rate_noise", rate_noise)?;
        check_nonneg("bias_walk", bias_walk)?;
        let (sd, sv, (f, q)) = (deflection_noise.to_f64(), rate_noise.to_f64(), model(dt, accel_noise, bias_walk));
        let (k, innov) = settle::<2>(SMatrix::<f64, 3, 3>::identity() * (1e3 * (sd * sd + sv * sv)), |p| {
            let pm = f * p * f.transpose() + q;
            // S = h P⁻ hᵀ + R: the upper-left 2 × 2 block plus the noise; its inverse by hand.
            let (s00, s01, s11) = (pm[(0, 0)] + sd * sd, pm[(0, 1)], pm[(1, 1)] + sv * sv);
            let det = s00 * s11 - s01 * s01;
            if !(det > 0.0) {
                return None;
            }
            let (i00, i01, i11) = (s11 / det, -s01 / det, s00 / det);
            let mut kn = SMatrix::<f64, 3, 2>::zeros();
            for r in 0..3 {
                kn[(r, 0)] = pm[(r, 0)] * i00 + pm[(r, 1)] * i01;
                kn[(r, 1)] = pm[(r, 0)] * i01 + pm[(r, 1)] * i11;
            }
            let mut pn = pm;
            for r in 0..3 {
                for c in 0..3 {
                    pn[(r, c)] = pm[(r, c)] - kn[(r, 0)] * pm[(0, c)] - kn[(r, 1)] * pm[(1, c)];
                }
            }
            Some((pn, kn, s00))
        })?;
        let gain = core::array::from_fn(|r| [T::of(k[(r, 0)]), T::of(k[(r, 1)])]);
        Ok(Self { gain, innov_sd: T::of(libm::sqrt(innov)) })
    }

    /// A zero gain, for a monitor whose sensors do not measure the rate (never used).
    pub(crate) fn unused() -> Self {
        Self { gain: [[T::zero(); 2]; 3], innov_sd: T::zero() }
    }

    /// The steady-state gain `K` (rows `d`, `ḋ`, `β`; columns the deflection's and the
    /// rate's innovation).
    pub fn gain(&self) -> [[T; 2]; 3] {
        self.gain
    }

    /// The steady-state standard deviation of the deflection's innovation, m.
    pub fn innovation_sd(&self) -> T {
        self.innov_sd
    }
}

impl<T: Real> DeflectionFilter<T> {
    /// One sample with the rate measured too ([`RateGain`]): deflection `d` (m), rate `rate`
    /// (m/s), relative acceleration `a` (m/s²); returns `(d̂, ḋ̂)`, or `None` and changes
    /// nothing when the deflection's innovation exceeds `gate` of `gain`'s standard
    /// deviations. The first sample after a (re)start takes `d` and `rate` as they are. The
    /// caller passes finite values.
    #[inline]
    pub fn update_rate_gated(&mut self, d: T, rate: T, a: T, gain: &RateGain<T>, gate: T) -> Option<(T, T)> {
        if !self.started {
            self.s[0] = d;
            self.s[1] = rate;
            self.prev_a = a;
            self.started = true;
            return Some((d, rate));
        }
        let (dp, vp) = self.predict(a);
        let b0 = self.s[2];
        let (nu, nv) = (d - dp, rate - vp);
        if nu.abs() > gate * gain.innov_sd {
            return None;
        }
        let k = &gain.gain;
        self.s = [dp + k[0][0] * nu + k[0][1] * nv, vp + k[1][0] * nu + k[1][1] * nv, b0 + k[2][0] * nu + k[2][1] * nv];
        self.prev_a = a;
        Some((self.s[0], self.s[1]))
    }
}

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
        let (h, sa, sd, qb) = (dt.to_f64(), accel_noise.to_f64(), deflection_noise.to_f64(), bias_walk.to_f64());
        #[rustfmt::skip]
        let f = SMatrix::<f64, 3, 3>::new(
            1.0, h, -h * h / 2.0,
            0.0, 1.0, -h,
            0.0, 0.0, 1.0,
        );
        let g = SVector::<f64, 3>::new(h * h / 2.0, h, 0.0);
        let mut q = g * g.transpose() * (sa * sa);
        q[(2, 2)] += qb * qb * h;
        // A tiny floor keeps the recursion positive definite when every noise is zero.
        for i in 0..3 {
            q[(i, i)] += 1e-30;
        }
        let r = sd * sd;
        let mut p = SMatrix::<f64, 3, 3>::identity() * (1e3 * r);
        let mut k = SVector::<f64, 3>::zeros();
        let mut innov = r;
        let mut settled = false;
        for _ in 0..2_000_000 {
            let pm = f * p * f.transpose() + q;
            innov = pm[(0, 0)] + r;
            let kn = pm.column(0) / innov;
            let mut pn = pm - kn * pm.row(0);
            pn = (pn + pn.transpose()) * 0.5;
            let change = (kn - k).abs().max();
            k = kn;
            p = pn;
            if change <= 1e-13 * (1.0 + k.abs().max()) {
                settled = true;
                break;
            }
        }
        if !settled || k.iter().any(|v| !v.is_finite()) {
            return Err(Error::InvalidArgument {
                arg: "bias_walk",
                expected: "noise levels for which the deflection filter's gain settles (a positive bias_walk)",
            });
        }
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
        if self.started {
            let h = self.dt;
            let [d0, v0, b0] = self.s;
            let dp =
                d0 + h * v0 + h * h * (self.prev_a * T::of(1.0 / 3.0) + a * T::of(1.0 / 6.0)) - h * h * T::of(0.5) * b0;
            if (d - dp).abs() > gate * self.innov_sd {
                return None;
            }
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
        let h = self.dt;
        let [d0, v0, b0] = self.s;
        let third = T::of(1.0 / 3.0);
        let sixth = T::of(1.0 / 6.0);
        let half = T::of(0.5);
        let dp = d0 + h * v0 + h * h * (self.prev_a * third + a * sixth) - h * h * half * b0;
        let vp = v0 + h * (self.prev_a + a) * half - h * b0;
        let nu = d - dp;
        self.s = [dp + self.gain[0] * nu, vp + self.gain[1] * nu, b0 + self.gain[2] * nu];
        self.prev_a = a;
        (self.s[0], self.s[1])
    }
}

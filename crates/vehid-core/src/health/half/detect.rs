//! The decisions of [`HalfHealthMonitor`]: the reference fits to the constants' patterns, the
//! CUSUM tests every decision interval, a change finished into an event.

use super::*;

impl<T: Real> HalfHealthMonitor<T> {
    /// The covariance `scale (Σ ⊗ P) ⊙ (v vᵀ)` of the relative deviations (`v` the
    /// reciprocals of the reference coefficients) of an estimate with covariance factor `p`.
    pub(super) fn relative_cov(
        sigma: &[[T; 2]; 2],
        p: &SMatrix<T, 5, 5>,
        inv: &SVector<T, 8>,
        scale: T,
    ) -> SMatrix<T, 8, 8> {
        SMatrix::from_fn(|i, k| scale * sigma[i / 4][k / 4] * p[(i % 4, k % 4)] * inv[i] * inv[k])
    }

    /// Adopts `theta` (covariance factor `p`, residual covariance `sigma`) as the reference
    /// when `Σ` is positive definite, no coefficient is zero and every named constant's
    /// relative change is known to `min_change / 6`; sets the tracker's wind-up cap so that
    /// forgetting pauses when a spring's or damper's relative change, from its two
    /// coefficients alone, has a standard error above `judge_error` (so that at the cap the
    /// monitor cannot judge, as the quarter car's).
    pub(super) fn try_reference(&mut self, sigma: [[T; 2]; 2], theta: SMatrix<T, 5, 2>, p: &SMatrix<T, 5, 5>) -> bool {
        let det = sigma[0][0] * sigma[1][1] - sigma[0][1] * sigma[1][0];
        if !(sigma[0][0] > T::zero() && det > T::zero()) {
            return false;
        }
        let mut inv = SVector::<T, 8>::zeros();
        for i in 0..8 {
            let v = theta[(i % 4, i / 4)];
            if v == T::zero() || !v.finite() {
                return false;
            }
            inv[i] = T::one() / v;
        }
        let sigma_inv = SMatrix::<T, 2, 2>::new(sigma[1][1], -sigma[0][1], -sigma[1][0], sigma[0][0]) / det;
        let q = p.fixed_view::<4, 4>(0, 0).into_owned();
        let r = theta.fixed_view::<4, 2>(0, 0).into_owned();
        let lim = self.cfg.min_change / T::of(6.0);
        let Some(fits) = fit_kron(&SMatrix::zeros(), &r, &sigma_inv, &q) else { return false };
        if !fits.iter().all(|f| f.var.sqrt() < lim) {
            return false;
        }
        self.sigma = sigma;
        self.theta_ref = theta;
        self.inv_ref = inv;
        self.c_ref = Self::relative_cov(&sigma, p, &inv, T::one());
        self.derive();
        let judge = self.cfg.judge_error;
        let onep = T::one() + self.fast.lambda();
        // Regressor j alone: the pattern (1, 1) over the two equations' coefficients
        // v = (θ_0j, θ_1j), tracked covariance P_jj/(1+λ) D Σ D (D = diag(1/v)), has the
        // variance P_jj / ((1+λ) vᵀΣ⁻¹v); the cap is where that reaches judge_error².
        let inv_det = T::one() / det;
        let mut cap = [T::biggest(); 5];
        for (j, cj) in cap.iter_mut().take(4).enumerate() {
            let (a, b) = (theta[(j, 0)], theta[(j, 1)]);
            let q = (a * a * sigma[1][1] - T::of(2.0) * a * b * sigma[0][1] + b * b * sigma[0][0]) * inv_det;
            *cj = judge * judge * q * onep;
        }
        self.fast.set_cap(cap);
        self.cap = cap;
        self.g = [[T::zero(); 2]; 5];
        self.phase = Phase::Monitoring;
        true
    }

    /// The fits of the named constants to the tracked (`post = false`) or the settling
    /// (`post = true`) estimate's relative deviations.
    pub(super) fn fits(&self, post: bool) -> Option<[Fit<T>; 5]> {
        let (rls, scale) =
            if post { (&self.post, T::one()) } else { (&self.fast, T::one() / (T::one() + self.fast.lambda())) };
        let (th, p, r) = (rls.theta(), rls.p(), &self.theta_ref);
        let dtheta = SMatrix::<T, 4, 2>::from_fn(|j, o| th[(j, o)] - r[(j, o)]);
        let q = SMatrix::<T, 4, 4>::from_fn(|j, k| p[(j, k)] * scale + self.q_ref[(j, k)]);
        fit_kron(&dtheta, &r.fixed_view::<4, 2>(0, 0).into_owned(), &self.sigma_inv, &q)
    }

    /// The CUSUM step on each named constant's relative deviation, for the `n_decide`
    /// samples since the last (the tracked estimate moves on the window's time scale, so
    /// its fits change little within a decision interval).
    pub(super) fn detect(&mut self, kr: u64) {
        let lim = self.cfg.judge_error;
        // Judged only while every spring's and damper's change, from its two coefficients
        // alone, is known to judge_error/√2 (P_jj at most half its cap): the generalized
        // least-squares fits below borrow strength from the other coefficients and stay
        // under judge_error even when the excitation fades and the estimate drifts (the
        // regressors then become mostly the kinematic filters' noise, which biases them).
        let p = self.fast.p();
        let faded = (0..4).any(|j| !(p[(j, j)] <= self.cap[j] * T::of(0.5)));
        let fits = match self.fits(false) {
            Some(f) if !faded && f.iter().all(|f| f.var <= lim * lim) => f,
            _ => {
                self.reason = Some(Reason::LowExcitation);
                return;
            }
        };
        self.reason = None;
        let delta = self.cfg.min_change;
        let half = delta * T::of(0.5);
        let w = T::of(self.n_decide as f64) * (T::one() - self.fast.lambda()) * delta;
        let mut best = (T::zero(), 0usize, 0usize);
        for (u, f) in fits.iter().enumerate() {
            let (g, side) = cusum_step(&mut self.g[u], &mut self.zero_k[u], f.value, w / f.var, half, kr);
            if g > best.0 {
                best = (g, u, side);
            }
        }
        if best.0 > self.cfg.threshold {
            self.onset = self.zero_k[best.1][best.2];
            let mut p0 = *self.fast.p() * T::of(1e3);
            p0[(4, 4)] = p0[(4, 4)].max(T::one());
            self.post = Rls::new(*self.fast.theta(), p0, T::one());
            self.post_n = 0;
            self.phase = Phase::Settling;
        }
    }

    /// Ends the settling: names the constant whose pattern fits best, reports it, moves the
    /// reference (`None` for a settled change below `min_change / 2`: the alarm is dropped).
    pub(super) fn finish(&mut self) -> Option<Event<T, HalfConstant>> {
        let one = T::one();
        let best = self.fits(true).and_then(|fits| {
            (0..5)
                .min_by(|&a, &b| fits[a].ssr.partial_cmp(&fits[b].ssr).unwrap_or(core::cmp::Ordering::Equal))
                .map(|u| (u, fits[u]))
        });
        // A change that arrived with a moved sensor gain is the sensor's: the gain's tracker
        // lags the ratios' by a few seconds, so it is looked at again before reporting; a
        // gain error explains a change up to GAIN_LEVERAGE times its own size.
        if self.sensors.vetoes(best.map_or(T::zero(), |(_, f)| f.value)) {
            self.g = [[T::zero(); 2]; 5];
            self.phase = Phase::Monitoring;
            self.reason = Some(Reason::Sensors);
            return None;
        }
        let Some((u, fit)) = best.filter(|(_, f)| f.value.abs() >= self.cfg.min_change * T::of(0.5)) else {
            self.g = [[T::zero(); 2]; 5];
            self.phase = Phase::Monitoring;
            return None;
        };
        let parameter = HALF_NAMED[u];
        let dx = fit.value;
        let idx = parameter.index();
        let before = self.belief[idx];
        let sd = (self.inflate * fit.var + self.cfg.systematic * self.cfg.systematic).sqrt();
        let (after, low, high) = if parameter == HalfConstant::BodyMass {
            let hi_den = (one + dx - self.z * sd).max(T::of(1e-9));
            (before / (one + dx), before / (one + dx + self.z * sd), before / hi_den)
        } else {
            (before * (one + dx), before * (one + dx - self.z * sd), before * (one + dx + self.z * sd))
        };
        self.belief[idx] = after;
        if parameter == HalfConstant::BodyMass {
            // J scales with M (the load is assumed spread like the body's own mass).
            let j = HalfConstant::PitchInertia.index();
            self.belief[j] /= one + dx;
        }
        let dt = self.cfg.dt.to_f64();
        let ev = Event {
            t: T::of((self.k - 1) as f64 * dt),
            t_change: T::of(self.onset as f64 * dt),
            parameter,
            before,
            after,
            low,
            high,
            change: after / before - one,
            position: None,
        };
        let (th, p) = (*self.post.theta(), *self.post.p());
        self.fast = Rls::new(th, p, self.fast.lambda());
        self.phase = Phase::Monitoring;
        if !self.try_reference(self.sigma, th, &p) {
            self.phase = Phase::Warmup;
            self.sensors.clear_reference();
            self.warm_n = 0;
            self.e2_sum = [[T::zero(); 2]; 2];
            self.e2_n = 0;
            self.e1_sum = [T::zero(); 2];
            self.e_prev = None;
            self.reference = Rls::new(th, p * T::of(1e3), T::one());
        }
        self.events += 1;
        Some(ev)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::health::HealthConfig;
    use crate::model::HalfCar;

    #[test]
    fn a_singular_residual_covariance_is_no_reference() {
        // Σ of two residuals that are one and the same (det Σ = 0 exactly) cannot weigh the
        // two equations against each other: no reference, and nothing changes, however tight
        // the estimate is otherwise.
        let cfg = HealthConfig::new(0.005, HalfCar::<f64>::passenger());
        let mut mon = HalfHealthMonitor::new(cfg).unwrap();
        let before = mon.clone();
        let theta = SMatrix::<f64, 5, 2>::from_fn(|i, j| 10.0 + (i + 3 * j) as f64);
        let p = SMatrix::<f64, 5, 5>::identity() * 1e-14;
        assert!(!mon.try_reference([[1.0, 1.0], [1.0, 1.0]], theta, &p));
        assert_eq!(mon, before);
        // The same estimate with the residuals independent is adopted: the refusal above is Σ's.
        assert!(mon.try_reference([[1.0, 0.0], [0.0, 1.0]], theta, &p));
        assert_ne!(mon, before);
    }
}

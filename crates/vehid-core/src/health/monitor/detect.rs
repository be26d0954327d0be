//! The decisions of [`HealthMonitor`]: each new estimate fed to the reference and the CUSUM
//! tests, the reference taken, a change detected and finished into an event.

use super::*;

impl<T: Real> HealthMonitor<T> {
    /// Uses one regression row `a_body = −(k2/M) d − (b/M) ḋ + c` of sample `kr`.
    pub(super) fn feed(&mut self, kr: u64, d: T, v: T, a: T) -> Option<Event<T>> {
        let phi = SVector::<T, 3>::new(-d, -v, T::one());
        if self.phase != Phase::Warmup && self.sensors.holds() {
            // The sensors disagree: track (so that the faulty samples age out of the
            // tracker) but judge nothing, and drop an alarm being settled.
            self.fast.update(&phi, a);
            self.phase = Phase::Monitoring;
            self.g = [[T::zero(); 2]; 2];
            self.reason = Some(Reason::Sensors);
            return None;
        }
        let q = T::of(OFFSET_WALK);
        self.fast.release(2, q);
        match self.phase {
            Phase::Warmup => {
                let e = self.reference.update(&phi, a);
                self.fast.update(&phi, a);
                self.warm_n += 1;
                if let Some(e) = e {
                    if self.warm_n > self.n_burn {
                        self.e2_sum += e * e;
                        self.e2_n += 1;
                        if let Some(prev) = self.e_prev {
                            self.e1_sum += e * prev;
                        }
                        self.e_prev = Some(e);
                    }
                }
                if self.warm_n >= self.n_warm && self.e2_n > 0 {
                    let sigma2 = self.e2_sum / T::of(self.e2_n as f64);
                    // Lag-1 autocorrelation of the residuals (the rate estimate's error is
                    // coloured): the intervals' variance factor (1 + ρ)/(1 − ρ), ρ in [0, 0.95].
                    let rho = (self.e1_sum / self.e2_sum).max(T::zero()).min(T::of(0.95));
                    self.inflate = (T::one() + rho) / (T::one() - rho);
                    let (th, p) = (*self.reference.theta(), *self.reference.p());
                    self.try_reference(sigma2, [th[0], th[1]], [sigma2 * p[(0, 0)], sigma2 * p[(1, 1)]]);
                }
                None
            }
            Phase::Monitoring => {
                self.fast.update(&phi, a);
                self.detect(kr);
                None
            }
            Phase::Settling => {
                self.fast.update(&phi, a);
                self.post.release(2, q);
                self.post.update(&phi, a);
                self.post_n += 1;
                if self.post_n >= self.n_settle {
                    self.finish()
                } else {
                    None
                }
            }
        }
    }

    /// Adopts `theta` (variances `var`) as the reference when both ratios are positive and
    /// known to `min_change / 6`; sets the tracker's wind-up cap to the largest covariance
    /// the detector judges (`s_j = judge_error`).
    pub(super) fn try_reference(&mut self, sigma2: T, theta: [T; 2], var: [T; 2]) -> bool {
        let lim = self.cfg.min_change / T::of(6.0);
        let ok = (0..2).all(|j| theta[j] > T::zero() && var[j].sqrt() < lim * theta[j]) && sigma2 > T::zero();
        if !ok {
            return false;
        }
        self.sigma2 = sigma2;
        self.theta_ref = theta;
        self.inv_ref = [T::one() / theta[0], T::one() / theta[1]];
        self.var_ref = var;
        let lim = self.cfg.judge_error;
        let onep = T::one() + self.fast.lambda();
        let cap = |j: usize| lim * lim * theta[j] * theta[j] * onep / sigma2;
        self.fast.set_cap([cap(0), cap(1), T::biggest()]);
        self.g = [[T::zero(); 2]; 2];
        self.phase = Phase::Monitoring;
        true
    }

    /// The CUSUM step on the tracked ratios' relative deviations from the reference.
    pub(super) fn detect(&mut self, kr: u64) {
        let th = *self.fast.theta();
        let p = *self.fast.p();
        let onep = T::one() + self.fast.lambda();
        let delta = self.cfg.min_change;
        let half = delta * T::of(0.5);
        let mut r = [T::zero(); 2];
        let mut s2 = [T::zero(); 2];
        let scale = self.sigma2 / onep;
        for j in 0..2 {
            let inv = self.inv_ref[j];
            r[j] = th[j] * inv - T::one();
            s2[j] = (scale * p[(j, j)] + self.var_ref[j]) * inv * inv;
        }
        let lim = self.cfg.judge_error;
        if s2.iter().any(|&s| !(s <= lim * lim)) {
            self.reason = Some(Reason::LowExcitation);
            return;
        }
        self.reason = None;
        let w = (T::one() - self.fast.lambda()) * delta;
        let mut best = (T::zero(), 0usize, 0usize);
        for j in 0..2 {
            let (g, side) = cusum_step(&mut self.g[j], &mut self.zero_k[j], r[j], w / s2[j], half, kr);
            if g > best.0 {
                best = (g, j, side);
            }
        }
        if best.0 > self.cfg.threshold {
            self.onset = self.zero_k[best.1][best.2];
            let mut p0 = *self.fast.p() * T::of(1e3);
            p0[(2, 2)] = p0[(2, 2)].max(T::one());
            self.post = Rls3::new(*self.fast.theta(), p0, T::one());
            self.post_n = 0;
            self.phase = Phase::Settling;
        }
    }

    /// Ends the settling: names the constant, reports it, moves the reference.
    /// (`None`: the settled change is smaller than `min_change / 2`, a transient such as a
    /// jump in the data; the alarm is dropped and the reference kept.)
    pub(super) fn finish(&mut self) -> Option<Event<T>> {
        let th = *self.post.theta();
        let p = *self.post.p();
        let s2 = self.sigma2;
        let (t0, t1) = (self.theta_ref[0], self.theta_ref[1]);
        let x = [th[0] / t0 - T::one(), th[1] / t1 - T::one()];
        // Covariance of the relative deviations: the new estimate's and the reference's.
        let c00 = s2 * p[(0, 0)] / (t0 * t0) + self.var_ref[0] / (t0 * t0);
        let c11 = s2 * p[(1, 1)] / (t1 * t1) + self.var_ref[1] / (t1 * t1);
        let c01 = s2 * p[(0, 1)] / (t0 * t1);
        let det = c00 * c11 - c01 * c01;
        let (i00, i11, i01) = if det > T::zero() {
            (c11 / det, c00 / det, -c01 / det)
        } else {
            (T::one() / c00, T::one() / c11, T::zero())
        };
        let quad = |u: [T; 2], v: [T; 2]| u[0] * (i00 * v[0] + i01 * v[1]) + u[1] * (i01 * v[0] + i11 * v[1]);
        let xx = quad(x, x);
        let mut best: Option<(T, Constant, T, T)> = None;
        for (u, c) in [
            ([T::one(), T::zero()], Constant::Spring),
            ([T::zero(), T::one()], Constant::Damper),
            ([T::one(), T::one()], Constant::BodyMass),
        ] {
            let a = quad(u, x);
            let b = quad(u, u);
            let ssr = xx - a * a / b;
            if best.is_none_or(|(s, ..)| ssr < s) {
                best = Some((ssr, c, a / b, (T::one() / b).sqrt()));
            }
        }
        let (_, parameter, dx, sd) = best.unwrap_or((T::zero(), Constant::Damper, x[1], c11.sqrt()));
        // A change that arrived with a moved sensor gain is the sensor's: the gain's tracker
        // lags the ratios' by a few seconds, so it is looked at again before reporting; a
        // gain error explains a change up to GAIN_LEVERAGE times its own size.
        if self.sensors.vetoes(dx) {
            self.g = [[T::zero(); 2]; 2];
            self.phase = Phase::Monitoring;
            self.reason = Some(Reason::Sensors);
            return None;
        }
        if !(dx.abs() >= self.cfg.min_change * T::of(0.5)) {
            self.g = [[T::zero(); 2]; 2];
            self.phase = Phase::Monitoring;
            return None;
        }
        let idx = match parameter {
            Constant::BodyMass => 0,
            Constant::Spring => 1,
            Constant::Damper => 2,
        };
        let before = self.belief[idx];
        let one = T::one();
        // The interval: the statistical error (inflated for coloured residuals) and the
        // systematic allowance, in quadrature. (The naming above uses the statistical one.)
        let sd = (self.inflate * sd * sd + self.cfg.systematic * self.cfg.systematic).sqrt();
        let (after, low, high) = match parameter {
            Constant::BodyMass => {
                let hi_den = (one + dx - self.z * sd).max(T::of(1e-9));
                (before / (one + dx), before / (one + dx + self.z * sd), before / hi_den)
            }
            _ => (before * (one + dx), before * (one + dx - self.z * sd), before * (one + dx + self.z * sd)),
        };
        self.belief[idx] = after;
        let dt = self.cfg.dt;
        let ev = Event {
            t: T::of((self.k - 1) as f64 * dt.to_f64()),
            t_change: T::of(self.onset as f64 * dt.to_f64()),
            parameter,
            before,
            after,
            low,
            high,
            change: after / before - one,
            position: None,
        };
        // The reference moves to the settled new value; the tracker continues from it.
        self.fast = Rls3::new(th, p, self.fast.lambda());
        self.phase = Phase::Monitoring;
        let var = [s2 * p[(0, 0)], s2 * p[(1, 1)]];
        if !self.try_reference(s2, [th[0], th[1]], var) {
            // Too uncertain to be a reference: learn it again.
            self.phase = Phase::Warmup;
            self.sensors.clear_reference();
            self.warm_n = 0;
            self.e2_sum = T::zero();
            self.e2_n = 0;
            self.e1_sum = T::zero();
            self.e_prev = None;
            self.reference = Rls3::new(th, p * T::of(1e3), T::one());
        }
        self.events += 1;
        Some(ev)
    }
}

//! The decisions of [`FullHealthMonitor`]: the reference, the fits to the constants'
//! patterns, the CUSUM tests every decision interval, a change finished into an event.

use super::*;

impl<T: Real> FullHealthMonitor<T> {
    /// Adopts `theta` (covariance factor `p`, residual covariance `sigma`) as the reference
    /// when `Σ` is positive definite and every named constant's relative change is known to
    /// `min_change / 6`; sets the tracker's wind-up cap so that forgetting pauses when a
    /// spring's or damper's relative change, from its own regressor's four coefficients alone,
    /// has a standard error above `judge_error` (as the half car's monitor).
    pub(super) fn try_reference(
        &mut self,
        sigma: SMatrix<T, 4, 4>,
        theta: SMatrix<T, 9, 4>,
        p: &SMatrix<T, 9, 9>,
    ) -> bool {
        let Some(sigma_inv) = spd_inverse(&sigma) else { return false };
        if !theta.iter().all(|v| v.finite()) {
            return false;
        }
        let (old_sigma, old_theta, old_q) = (self.sigma, self.theta_ref, self.q_ref);
        self.sigma = sigma;
        self.theta_ref = theta;
        self.q_ref = p.fixed_view::<8, 8>(0, 0).into_owned();
        self.derive();
        let lim = self.cfg.min_change / T::of(6.0);
        let ok = fit_kron_patterns(&SMatrix::zeros(), &self.patterns, &self.sigma_inv, &self.q_ref)
            .is_some_and(|fits| fits[..FRONT_BAR].iter().all(|f| f.var > T::zero() && f.var.sqrt() < lim));
        if !ok {
            self.sigma = old_sigma;
            self.theta_ref = old_theta;
            self.q_ref = old_q;
            self.derive();
            return false;
        }
        let judge = self.cfg.judge_error;
        let onep = T::one() + self.fast.lambda();
        // Regressor j alone: the pattern "all four coefficients of regressor j" (v = row j of
        // Θ_ref), tracked covariance P_jj/(1+λ) D Σ D, has the variance P_jj / ((1+λ) vᵀΣ⁻¹v);
        // the cap is where that reaches judge_error².
        let mut cap = [T::biggest(); 9];
        for (j, cj) in cap.iter_mut().take(8).enumerate() {
            let v = theta.fixed_view::<1, 4>(j, 0).into_owned();
            let q = (v * sigma_inv).dot(&v);
            *cj = judge * judge * q * onep;
        }
        self.fast.set_cap(cap);
        self.cap = cap;
        self.g = [[T::zero(); 2]; FULL_NAMED_COUNT];
        self.phase = Phase::Monitoring;
        true
    }

    /// The tracked (`post = false`) or the settling (`post = true`) estimate's deviations from
    /// the reference `X̃` and their covariance factor `Q` (tracked plus reference).
    fn deviations(&self, post: bool) -> (SMatrix<T, 8, 4>, SMatrix<T, 8, 8>) {
        let (rls, scale) =
            if post { (&self.post, T::one()) } else { (&self.fast, T::one() / (T::one() + self.fast.lambda())) };
        let (th, p, r) = (rls.theta(), rls.p(), &self.theta_ref);
        let dtheta = SMatrix::<T, 8, 4>::from_fn(|j, o| th[(j, o)] - r[(j, o)]);
        let q = SMatrix::<T, 8, 8>::from_fn(|j, k| p[(j, k)] * scale + self.q_ref[(j, k)]);
        (dtheta, q)
    }

    /// The fits of the named constants to the tracked (`post = false`) or the settling
    /// (`post = true`) estimate's deviations from the reference.
    pub(crate) fn fits(&self, post: bool) -> Option<Fits<T>> {
        let (dtheta, q) = self.deviations(post);
        fit_kron_patterns(&dtheta, &self.patterns, &self.sigma_inv, &q)
    }

    /// The fits of the constants the monitor judges ([`full_judged`]: not a bar the nominal car
    /// does not have), with their places in [`FULL_NAMED`].
    fn judged<'a>(&self, fits: &'a Fits<T>) -> impl Iterator<Item = (usize, &'a Fit<T>)> + 'a {
        let judged = full_judged(&self.cfg.car);
        fits.iter().enumerate().filter(move |(u, _)| judged[*u])
    }

    /// The point load that fits the settling estimate's deviations best
    /// ([`full_load_pattern`] at every point of the search grid: [`LOAD_REACH`], [`LOAD_STEP`]):
    /// its fit (amplitude `m_e / M`), its position `[x, y]` and its `s`. `None` when `Q` is
    /// not positive definite.
    fn point_load(&self) -> Option<(Fit<T>, [T; 2], T)> {
        let (dtheta, q) = self.deviations(true);
        let qi = spd_inverse(&q)?;
        let zx = (qi * dtheta) * self.sigma_inv;
        let xx = dtheta.dot(&zx);
        let r = self.theta_ref.fixed_view::<8, 4>(0, 0).into_owned();
        let p = self.cfg.car.params();
        let (step, reach) = (LOAD_STEP, LOAD_REACH);
        let nx = libm::round((p.l_f.to_f64() + p.l_r.to_f64() + 2.0 * reach) / step) as i64;
        let half = 0.5 * p.track_f.to_f64().max(p.track_r.to_f64());
        let ny = libm::round(half / step) as i64;
        let mut best: Option<(Fit<T>, [T; 2], T)> = None;
        for ix in 0..=nx {
            let x = T::of(-(p.l_r.to_f64() + reach) + ix as f64 * step);
            for iy in -ny..=ny {
                let y = T::of(iy as f64 * step);
                let (u, s) = full_load_pattern(&self.cfg.car, x, y);
                let u = u.component_mul(&r);
                let uu = u.dot(&((qi * u) * self.sigma_inv));
                if !(uu > T::zero()) {
                    continue;
                }
                let ux = u.dot(&zx);
                let fit = Fit { value: ux / uu, var: T::one() / uu, ssr: xx - ux * ux / uu };
                if best.is_none_or(|b| fit.ssr < b.0.ssr) {
                    best = Some((fit, [x, y], s));
                }
            }
        }
        best
    }

    /// The CUSUM step on each named constant's relative deviation, for the `n_decide`
    /// samples since the last.
    pub(super) fn detect(&mut self, kr: u64) {
        let lim = self.cfg.judge_error;
        // Judged only while every spring's and damper's change, from its own four
        // coefficients alone, is known to judge_error/√2 (the half car's rule).
        let p = self.fast.p();
        let faded = (0..8).any(|j| !(p[(j, j)] <= self.cap[j] * T::of(0.5)));
        let fits = match self.fits(false) {
            Some(f) if !faded && f[..FRONT_BAR].iter().all(|f| f.var <= lim * lim) => f,
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
        // A bar is judged when its own change is known to judge_error too (it is often less
        // well determined than the corners: a soft bar moves the coefficients little).
        for (u, f) in self.judged(&fits).filter(|(u, f)| *u < FRONT_BAR || f.var <= lim * lim) {
            let (g, side) = cusum_step(&mut self.g[u], &mut self.zero_k[u], f.value, w / f.var, half, kr);
            if g > best.0 {
                best = (g, u, side);
            }
        }
        if best.0 > self.cfg.threshold {
            self.onset = self.zero_k[best.1][best.2];
            let mut p0 = *self.fast.p() * T::of(1e3);
            p0[(8, 8)] = p0[(8, 8)].max(T::one());
            self.post = Rls::new(*self.fast.theta(), p0, T::one());
            self.post_n = 0;
            self.phase = Phase::Settling;
        }
    }

    /// A settled change below `min_change / 2`: the alarm is dropped, monitoring goes on.
    fn drop_alarm(&mut self) -> Option<Event<T, FullConstant>> {
        self.g = [[T::zero(); 2]; FULL_NAMED_COUNT];
        self.phase = Phase::Monitoring;
        None
    }

    /// Ends the settling: names the constant whose pattern fits best, or a point load
    /// ([`full_load_pattern`]) when it fits better by [`LOAD_PENALTY`], reports it, moves the
    /// reference (`None` for a settled change below `min_change / 2`: the alarm is dropped).
    pub(super) fn finish(&mut self) -> Option<Event<T, FullConstant>> {
        let one = T::one();
        let best = self.fits(true).and_then(|fits| {
            self.judged(&fits)
                .min_by(|a, b| a.1.ssr.partial_cmp(&b.1.ssr).unwrap_or(core::cmp::Ordering::Equal))
                .map(|(u, f)| (u, *f))
        });
        // A point load, when it fits better than any one constant by more than its position's
        // two degrees of freedom buy (and its mass is finite: m_e s < 1).
        let m_nom = self.cfg.car.params().m_body;
        let mass = |eps: T, s: T| {
            let me = eps * m_nom;
            let den = one - me * s;
            (den > T::of(1e-9)).then(|| me / den)
        };
        let load = self.point_load().filter(|(f, _, s)| {
            mass(f.value, *s).is_some() && best.is_none_or(|(_, b)| f.ssr + T::of(LOAD_PENALTY) < b.ssr)
        });
        // A change that arrived with a moved sensor gain is the sensor's: the gain's tracker
        // lags the ratios' by a few seconds, so it is looked at again before reporting; a
        // gain error explains a change up to GAIN_LEVERAGE times its own size.
        let size = load.map(|(f, ..)| f.value).or(best.map(|(_, f)| f.value)).unwrap_or(T::zero());
        if self.sensors.vetoes(size) {
            self.reason = Some(Reason::Sensors);
            return self.drop_alarm();
        }
        let half = self.cfg.min_change * T::of(0.5);
        let (parameter, before, after, low, high, position) = match (load, best) {
            (Some((fit, at, s)), _) => {
                let idx = FULL_NAMED[BODY_MASS].index();
                let before = self.belief[idx];
                let m = mass(fit.value, s).unwrap_or(T::zero());
                // (A mass removed is at most the body's: m > −1/s ≥ −M; after earlier events
                // the belief may be below M, and a body of no mass is no result.)
                if !(m.abs() >= half * before) || !(before + m > T::zero()) {
                    return self.drop_alarm();
                }
                let sd = (self.inflate * fit.var + self.cfg.systematic * self.cfg.systematic).sqrt();
                let lo = mass(fit.value - self.z * sd, s).unwrap_or(m);
                let hi = mass(fit.value + self.z * sd, s).unwrap_or(T::biggest());
                self.belief[idx] = before + m;
                // About the nominal car's centre of mass, as the drive reports them.
                self.belief[1] += m * at[1] * at[1];
                self.belief[2] += m * at[0] * at[0];
                (FULL_NAMED[BODY_MASS], before, before + m, before + lo, before + hi, Some(at))
            }
            (None, Some((u, fit))) if fit.value.abs() >= half => {
                let parameter = FULL_NAMED[u];
                let dx = fit.value;
                let idx = parameter.index();
                let before = self.belief[idx];
                let sd = (self.inflate * fit.var + self.cfg.systematic * self.cfg.systematic).sqrt();
                let (after, low, high) = if u == BODY_MASS {
                    let hi_den = (one + dx - self.z * sd).max(T::of(1e-9));
                    (before / (one + dx), before / (one + dx + self.z * sd), before / hi_den)
                } else if u >= FRONT_BAR {
                    // The fit is the change of the axle's roll stiffness relative to the nominal
                    // car's, Δarb / K_φ: the bar's own change is that times K_φ, added to the
                    // belief (a lost bar's belief is 0, and its repair must still read as one).
                    // A bar is a torsion spring, ≥ 0: a lost bar (a broken end link) reads
                    // about −100 %, and the estimate and its interval stop at 0.
                    let (_, _, roll) = axle_roll(&self.cfg.car, u - FRONT_BAR);
                    let z = T::zero();
                    let at = |d: T| (before + d * roll).max(z);
                    (at(dx), at(dx - self.z * sd), at(dx + self.z * sd))
                } else {
                    (before * (one + dx), before * (one + dx - self.z * sd), before * (one + dx + self.z * sd))
                };
                self.belief[idx] = after;
                if u == BODY_MASS {
                    // Jx and Jy scale with M (a load spread like the body's own mass).
                    self.belief[1] /= one + dx;
                    self.belief[2] /= one + dx;
                }
                (parameter, before, after, low, high, None)
            }
            _ => return self.drop_alarm(),
        };
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
            position,
        };
        let (th, p) = (*self.post.theta(), *self.post.p());
        self.fast = Rls::new(th, p, self.fast.lambda());
        self.phase = Phase::Monitoring;
        if !self.try_reference(self.sigma, th, &p) {
            self.phase = Phase::Warmup;
            self.sensors.clear_reference();
            self.warm_n = 0;
            self.e2_sum = SMatrix::zeros();
            self.e2_n = 0;
            self.e1_sum = [T::zero(); 4];
            self.e_prev = None;
            self.reference = Rls::new(th, p * T::of(1e3), T::one());
        }
        self.events += 1;
        Some(ev)
    }
}

//! [`KinematicCheck`]: does the deflection sensor still agree with the accelerometers?
//!
//! The deflection `d = zb − zw` and the relative acceleration `a = a_body − a_wheel` are tied
//! by kinematics alone, `d̈ = a`, whatever the springs, dampers and masses are. A sensor that
//! changes its gain, flips its sign, or is swapped with another channel breaks that tie; a
//! changed constant of the car does not. The check therefore watches the gain `g` of
//!
//! ```text
//! F(s) s² d = g · F(s) a,        F(s) = s / (s + ω_h)³ · (ω_l / (s + ω_l))²
//! ```
//!
//! (`F s²` applied to the measured deflection, `F` to the measured relative acceleration;
//! the high-pass `s/(s+ω_h)` removes the accelerometers' bias and a drifting deflection zero,
//! the low-pass `ω_l/(s+ω_l)`² the wheel-hop band, where the sampled double integration
//! is least exact). Both sides are discretized with the same bilinear (Tustin) map, so the
//! discrete filters keep the identity `F s² d = F a` up to the warping of `s²` by the
//! bilinear map, `(tan x / x)² − 1` at `x = π f dt`: 0.15 % at the low-pass corner
//! (3 Hz) at 200 Hz. The gain is estimated by exponentially weighted least squares with the
//! monitor's forgetting; its reference is the warm-up's (a mounting's lever ratio is not
//! 1 and need not be known). A relative change of the gain by more than `tol` makes the
//! monitor's status "cannot judge: sensors disagree" instead of letting the change reach
//! the tracked ratios (a deflection gain error `ε` moves `k2/M` by about `−1.2 ε` to
//! `−1.5 ε` and `b/M` by little, as a spring change would: [`GAIN_LEVERAGE`]).
//!
//! A bias step of the deflection or of an accelerometer does not change `g` (the high-pass
//! removes it after a transient of a few `1/ω_h`); the monitor handles it through its jump
//! gate and the offset `c` of the body equation (module documentation of [`crate::health`]).

use crate::Real;

/// High-pass corner `ω_h / 2π`, Hz. Below it the accelerometers' noise, integrated twice,
/// outgrows the deflection (at 0.3 Hz the tracked gain wandered by ±1.5 % on a class C road
/// with the default sensors; at 0.8 Hz by a few tenths of a percent).
pub const CHECK_HIGH_PASS_HZ: f64 = 0.8;
/// Low-pass corner `ω_l / 2π`, Hz (below the wheel hop, ≈ 10–15 Hz); at most a tenth of the
/// sample rate, where the bilinear map's warping of `s²` stays below 3.3 %.
pub const CHECK_LOW_PASS_HZ: f64 = 5.0;

/// One first-order bilinear section `y_k = p y_{k−1} + b0 x_k + b1 x_{k−1}`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Section<T> {
    y: T,
    x: T,
}

impl<T: Real> Section<T> {
    #[inline(always)]
    fn step(&mut self, x: T, c: &[T; 3]) -> T {
        let y = c[0] * self.y + c[1] * x + c[2] * self.x;
        self.y = y;
        self.x = x;
        y
    }
}

/// The sensors' kinematic consistency check (module documentation): the gain of the
/// filtered deflection's second derivative on the filtered relative acceleration, tracked
/// with forgetting `λ` and compared with the warm-up's reference.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct KinematicCheck<T> {
    // Coefficients [p, b0, b1]: high-pass s/(s+ω_h), unit low-pass 1/(s+ω_h), low-pass ω_l/(s+ω_l).
    hp: [T; 3],
    lp_h: [T; 3],
    lp_l: [T; 3],
    // Exponentially weighted sums Σ y², Σ x y (y: filtered deflection, x: filtered relative
    // acceleration), and the warm-up's plain sums with their count.
    // Deflection: three high-passes and two low-passes; acceleration: one high-pass, two
    // unit low-passes at ω_h, two low-passes at ω_l.
    d: [Section<T>; 5],
    a: [Section<T>; 5],
    lambda: T,
    sdd: T,
    sda: T,
    saa: T,
    rdd: T,
    rda: T,
    raa: T,
    kappa: T,
    rn: u64,
    // Steps since the filters restarted; the statistics wait until their transient is over
    // (`settle` steps). From `settle + 3 / (1 − λ)` on it is `ARMED`: bursts are looked for.
    fresh: u64,
    settle: u64,
    // Samples averaged into one step of the filters, and the running sums of the current group.
    every: u64,
    inv_every: T,
    n_acc: u64,
    acc: [T; 2],
}

/// How many times a deflection sensor's relative gain error the monitor's tracked spring
/// coefficient moves by, at most (with some margin): a gain error `ε` moves `k2/M` by about
/// `−1.2 ε` to `−1.5 ε` and `b/M` by little, since the kinematic filter's rate leans on the
/// accelerometers (measured: `benches/src/bin/check_gain.rs --fault-gain`, the passenger
/// quarter car on class C at 15 m/s). So a settled change of `x` can be a gain error's
/// only when the gain has moved by at least about `|x| / 1.5`; the monitor holds an event
/// back when a gain has moved by `|x| / 3` (`SensorGuard::vetoes`). Without it a gain
/// error of 2 % (below the tolerance) was reported as a spring change of −2.9 % on 16 of 20
/// drives.
pub const GAIN_LEVERAGE: f64 = 3.0;

/// A burst: the check's residual (the filtered acceleration less the filtered deflection's
/// second derivative over the tracked gain) more than this many standard deviations of its
/// exponentially weighted history (a Gaussian residual passes it with probability 2·10⁻⁹ per
/// step). A spring breaking under the body's weight steps both accelerations between two
/// samples (the wheel's by about 20 m/s² in a quarter car of M 420 kg, k2 −22 %); the sampled
/// filters of the two sides of `d̈ = a` do not follow a step alike, and neither does the
/// monitor's deflection-rate filter (`DeflectionFilter`), whose rate and bias then carry the
/// step's error for seconds. So a burst is a jump in the data: the check restarts (its
/// statistics kept, its transient left out), and the monitors restart their rate filters and
/// wait out `reacquire`, as after a deflection jump. Without it, a spring change of a heavy
/// car on a smooth road dipped the tracked gain by 3-7 % for 10-20 s, and the monitor held the
/// change back as "sensors disagree" (`benches/src/bin/check_gain.rs`). A sensor fault that
/// makes a burst (a gain change moves the residual in proportion to the signal) is handled as
/// before it: the sensor-fault suite (`tests/sensor_faults.rs`: bias steps, gains ×0.9 and
/// ×1.1, swapped and stuck channels) gives no event with it either.
pub const JUMP_SIGMAS: f64 = 6.0;

/// `KinematicCheck::fresh` once bursts are looked for.
const ARMED: u64 = u64::MAX;

/// Rate the check's filters run at, Hz, at most (samples are averaged in pairs, fours, …
/// down to it): the band ends at 5 Hz, and at 100 Hz the bilinear warping there is 0.8 %.
/// Running them at 200 Hz cost the half car's monitor 45 ns per sample.
pub const CHECK_RATE_HZ: f64 = 100.0;

impl<T: Real> KinematicCheck<T> {
    /// A check for samples every `dt` seconds with forgetting factor `lambda` in `(0, 1)` per
    /// sample. The filters run on averages of `round(1 / (CHECK_RATE_HZ dt))` samples (at least
    /// one; the same average on both sides keeps their relation), forgetting `lambda` to that
    /// power per step.
    pub fn new(dt: T, lambda: T) -> Self {
        let every = libm::round(1.0 / (CHECK_RATE_HZ * dt.to_f64())).max(1.0) as u64;
        let lambda = T::of(libm::pow(lambda.to_f64(), every as f64));
        let dt = T::of(dt.to_f64() * every as f64);
        let c = 2.0 / dt.to_f64();
        let wh = 2.0 * core::f64::consts::PI * CHECK_HIGH_PASS_HZ;
        let wl = 2.0 * core::f64::consts::PI * CHECK_LOW_PASS_HZ.min(0.1 / dt.to_f64());
        // s → c (1 − z⁻¹)/(1 + z⁻¹): s/(s+ω) = c(1 − z⁻¹) / ((c+ω) − (c−ω) z⁻¹), and so on.
        let hp = [(c - wh) / (c + wh), c / (c + wh), -c / (c + wh)];
        let lp_h = [(c - wh) / (c + wh), 1.0 / (c + wh), 1.0 / (c + wh)];
        let lp_l = [(c - wl) / (c + wl), wl / (c + wl), wl / (c + wl)];
        let of = |v: [f64; 3]| [T::of(v[0]), T::of(v[1]), T::of(v[2])];
        let zero = Section { y: T::zero(), x: T::zero() };
        Self {
            hp: of(hp),
            lp_h: of(lp_h),
            lp_l: of(lp_l),
            d: [zero; 5],
            a: [zero; 5],
            lambda,
            sdd: T::zero(),
            sda: T::zero(),
            saa: T::zero(),
            rdd: T::zero(),
            rda: T::zero(),
            raa: T::zero(),
            // Samples per independent one of the band `f_h`…`f_l` (Nyquist: 2 (f_l − f_h) per s).
            kappa: T::of((1.0 / (2.0 * (wl - wh) / (2.0 * core::f64::consts::PI) * dt.to_f64())).max(1.0)),
            rn: 0,
            fresh: 0,
            // The three high-passes' transient after a restart in mid-motion decays as
            // (ω_h t)² e^(−ω_h t): below 10⁻⁴ of the signal after 15 / ω_h (3 s at 0.8 Hz).
            settle: libm::ceil(15.0 / (wh * dt.to_f64())) as u64,
            every,
            inv_every: T::of(1.0 / every as f64),
            n_acc: 0,
            acc: [T::zero(); 2],
        }
    }

    /// Restarts the filters (after a gap, a stuck channel or a jump): their transient is
    /// left out of the statistics, which are kept.
    pub fn restart(&mut self) {
        let zero = Section { y: T::zero(), x: T::zero() };
        self.d = [zero; 5];
        self.a = [zero; 5];
        self.fresh = 0;
        self.n_acc = 0;
        self.acc = [T::zero(); 2];
    }

    /// One sample: measured deflection `d` (m) and relative acceleration `a` (m/s²);
    /// `warmup`: the sample also forms the reference. Every `every`-th call steps the filters
    /// with the group's averages. Returns whether the step saw a burst ([`JUMP_SIGMAS`]): the
    /// check then restarts ([`Self::restart`]), and the caller should treat the sample as a
    /// jump in the data.
    #[inline]
    pub fn update(&mut self, d: T, a: T, warmup: bool) -> bool {
        self.acc[0] += d;
        self.acc[1] += a;
        self.n_acc += 1;
        if self.n_acc < self.every {
            return false;
        }
        let (d, a) = (self.acc[0] * self.inv_every, self.acc[1] * self.inv_every);
        self.n_acc = 0;
        self.acc = [T::zero(); 2];
        self.step(d, a, warmup)
    }

    /// One step of the filters and the statistics on averaged inputs; whether it saw a burst.
    fn step(&mut self, d: T, a: T, warmup: bool) -> bool {
        if self.fresh == 0 {
            // Start in the steady state of constant inputs `d`, `a` (the high-passes hold
            // them as their last input, every output is 0): no step transient from zero.
            self.d[0].x = d;
            self.a[0].x = a;
        }
        let mut x = d;
        for s in &mut self.d[..3] {
            x = s.step(x, &self.hp);
        }
        x = self.d[3].step(x, &self.lp_l);
        let y = self.d[4].step(x, &self.lp_l);
        let mut x = self.a[0].step(a, &self.hp);
        x = self.a[1].step(x, &self.lp_h);
        x = self.a[2].step(x, &self.lp_h);
        x = self.a[3].step(x, &self.lp_l);
        let x = self.a[4].step(x, &self.lp_l);
        if self.fresh < self.settle {
            self.fresh += 1;
            return false;
        }
        // A burst: the fit's residual over JUMP_SIGMAS standard deviations of its weighted
        // history, once the statistics have run for three of their time constants `1/(1 − λ)`
        // since the last restart (their weighted sums then hold 95 % of their full weight; at
        // `settle / 2` steps, as first written, a fifth, and the bound was 2.8 σ: a false
        // burst in one of six logs of a 70 s drive).
        if self.fresh == ARMED {
            if self.sdd > T::zero() {
                // The residual `x − y Σxy/Σy²` against its weighted mean square
                // `(Σx² − (Σxy)²/Σy²)(1 − λ)`.
                let q = self.sda / self.sdd;
                let res = (self.saa - self.sda * q).max(T::zero()) * (T::one() - self.lambda);
                let r = x - y * q;
                if res > T::zero() && r * r > T::of(JUMP_SIGMAS * JUMP_SIGMAS) * res {
                    self.restart();
                    return true;
                }
            }
        } else {
            self.fresh += 1;
            if (self.fresh - self.settle) as f64 * (1.0 - self.lambda.to_f64()) >= 3.0 {
                self.fresh = ARMED;
            }
        }
        self.sdd = self.lambda * self.sdd + y * y;
        self.sda = self.lambda * self.sda + x * y;
        self.saa = self.lambda * self.saa + x * x;
        if warmup {
            self.rdd += y * y;
            self.rda += x * y;
            self.raa += x * x;
            self.rn += 1;
        }
        false
    }

    /// The tracked gain and the reference gain, `None` before either has data or when the
    /// filtered signals are uncorrelated. The gain `g = Σ y² / Σ x y` of the filtered
    /// deflection `y` on the filtered acceleration `x` is the least-squares fit of `x` on `y`
    /// (`x = y / g`): the deflection side carries far less noise in this band than the twice
    /// integrated accelerations, so it is the regressor, and the fit is not attenuated by the
    /// accelerometers' noise (errors in variables).
    pub fn gains(&self) -> Option<(T, T)> {
        let known = self.sda != T::zero() && self.rda != T::zero();
        (known && self.rdd > T::zero()).then(|| (self.sdd / self.sda, self.rdd / self.rda))
    }

    /// Whether the tracked gain differs from the reference by more than `tol` (relative)
    /// plus three standard errors of the two estimates; `false` while either is unknown, and
    /// while the filtered deflection's power over the window is below a tenth of the
    /// warm-up's (a car standing still: the gain is then the noise's).
    ///
    /// The standard errors are least squares' for the fit of `x` on `y`: relative variance
    /// `κ · res · Σy² / (n (Σxy)²)` with the residual sum `res = Σx² − (Σxy)²/Σy²`, `n` the
    /// effective count (`(1+λ)/(1−λ)` for the exponential weights, the sample count for the
    /// reference) and `κ = 1/(2 (f_l − f_h) dt)` samples per independent one of the band-limited
    /// signals. With clean sensors they are a few tenths of a percent; with noisy ones (the
    /// state sensors at 8 % noise) the check widens instead of flagging the noise.
    pub fn disagrees(&self, tol: T) -> bool {
        match self.deviation() {
            Some((dev, se)) => !(dev <= tol + T::of(3.0) * se),
            None => false,
        }
    }

    /// The relative deviation `|g/g_ref − 1|` and its standard error ([`Self::disagrees`]);
    /// `None` when [`Self::disagrees`] does not judge.
    pub fn deviation(&self) -> Option<(T, T)> {
        let (g, r) = self.gains()?;
        let one = T::one();
        let power = self.sdd * (one - self.lambda);
        let n_ref = T::of(self.rn.max(1) as f64);
        if !(power > T::of(0.1) * self.rdd / n_ref) {
            return None;
        }
        let rel2 = |aa: T, dd: T, da: T, n: T| (aa - da * da / dd).max(T::zero()) * dd / (n * da * da);
        let n_eff = (one + self.lambda) / (one - self.lambda);
        let var = self.kappa * (rel2(self.saa, self.sdd, self.sda, n_eff) + rel2(self.raa, self.rdd, self.rda, n_ref));
        Some(((g / r - one).abs(), var.sqrt()))
    }

    /// Whether the tracked gain has moved from the reference by more than `tol` (relative),
    /// whatever its standard error: before an event is reported, where a change of the car
    /// leaves the gain within a few tenths of a percent and a sensor's gain change is on its
    /// way (the gain's tracker lags the ratios'); `false` while it is not judged.
    pub fn moved(&self, tol: T) -> bool {
        self.deviation().is_some_and(|(dev, _)| !(dev <= tol))
    }

    /// Forgets the reference (a new warm-up forms it again).
    pub fn clear_reference(&mut self) {
        self.rdd = T::zero();
        self.rda = T::zero();
        self.raa = T::zero();
        self.rn = 0;
    }

    /// Whether the saved statistics are finite and non-negative where they must be.
    #[cfg(feature = "serde")]
    pub(crate) fn is_valid(&self) -> bool {
        let fin = |v: T| v.to_f64().is_finite();
        let secs = self.d.iter().chain(self.a.iter()).all(|s| fin(s.x) && fin(s.y));
        secs && self.every >= 1
            && self.n_acc < self.every
            && self.acc.iter().all(|&v| fin(v))
            && [self.sda, self.rda].iter().all(|&v| fin(v))
            && [self.sdd, self.rdd, self.saa, self.raa, self.kappa].iter().all(|&v| fin(v) && v >= T::zero())
            && self.lambda > T::zero()
            && self.lambda < T::one()
    }
}

/// Samples between two looks at the kinematic checks (their gains move over seconds; looking
/// every sample would cost as much as the rest of the update).
pub(crate) const CHECK_EVERY: u64 = 10;

/// The kinematic checks of a monitor's `C` corners and the hold that follows a disagreement:
/// what the quarter car's (`C = 1`) and the half car's (`C = 2`) monitors share. While it
/// holds, the monitor tracks but judges nothing; it holds for one window after the last
/// disagreement.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub(crate) struct SensorGuard<T: Real, const C: usize> {
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    checks: [KinematicCheck<T>; C],
    tol: T,
    n_flush: u64,
    hold: u64,
}

impl<T: Real, const C: usize> SensorGuard<T, C> {
    /// Checks for samples every `dt` seconds, forgetting `lambda` per sample, relative
    /// tolerance `tol` on each gain, a hold of `n_flush` samples.
    pub(crate) fn new(dt: T, lambda: T, tol: T, n_flush: u64) -> Self {
        Self { checks: [KinematicCheck::new(dt, lambda); C], tol, n_flush, hold: 0 }
    }

    /// Sample `k`: each corner's measured deflection and relative acceleration; after the
    /// warm-up, every [`CHECK_EVERY`] samples, a disagreeing corner starts the hold. Returns
    /// whether a corner's check saw a burst ([`KinematicCheck::update`]): the monitor treats
    /// the sample as a jump in the data.
    #[inline]
    pub(crate) fn observe(&mut self, k: u64, corners: [(T, T); C], warmup: bool) -> bool {
        let mut burst = false;
        for (check, (d, a)) in self.checks.iter_mut().zip(corners) {
            burst |= check.update(d, a, warmup);
        }
        if !warmup && k % CHECK_EVERY == 0 && self.checks.iter().any(|c| c.disagrees(self.tol)) {
            self.hold = self.n_flush;
        }
        burst
    }

    /// Whether this sample is held (counted down).
    #[inline]
    pub(crate) fn holds(&mut self) -> bool {
        let on = self.hold > 0;
        self.hold -= u64::from(on);
        on
    }

    /// Before an event of relative size `change` is reported: whether a gain has moved by
    /// more than the tolerance, or by more than `|change| /` [`GAIN_LEVERAGE`] when that is
    /// less ([`KinematicCheck::moved`]: a sensor's gain change on its way, or one that
    /// explains the change); if so, the hold starts.
    pub(crate) fn vetoes(&mut self, change: T) -> bool {
        let tol = self.tol.min(change.abs() / T::of(GAIN_LEVERAGE));
        let moved = self.checks.iter().any(|c| c.moved(tol));
        if moved {
            self.hold = self.n_flush;
        }
        moved
    }

    /// Restarts every corner's filters ([`KinematicCheck::restart`]).
    pub(crate) fn restart(&mut self) {
        self.checks.iter_mut().for_each(|c| c.restart());
    }

    /// Forgets the references (a new warm-up forms them again).
    pub(crate) fn clear_reference(&mut self) {
        self.checks.iter_mut().for_each(|c| c.clear_reference());
    }

    /// Whether a restored guard is valid and has the settings of `fresh` (built from the
    /// same configuration).
    #[cfg(feature = "serde")]
    pub(crate) fn is_valid(&self, fresh: &Self) -> bool {
        self.checks.iter().all(|c| c.is_valid())
            && self.tol == fresh.tol
            && self.n_flush == fresh.n_flush
            && self.hold <= self.n_flush
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A two-tone deflection with its exact second derivative: the gain is 1 within the
    /// bilinear warping, and a deflection read with gain 1.1 shows 1.1 in the tracked gain.
    #[test]
    fn the_gain_of_a_consistent_pair_is_one_and_a_scaled_sensor_shows_its_scale() {
        let dt = 0.005;
        let mut ok = KinematicCheck::new(dt, 1.0 - dt / 6.0);
        let mut scaled = ok;
        let (w1, w2) = (2.0 * core::f64::consts::PI * 1.2, 2.0 * core::f64::consts::PI * 0.7);
        for k in 0..40_000 {
            let t = k as f64 * dt;
            let d = 0.01 * (w1 * t).sin() + 0.004 * (w2 * t + 0.3).sin() + 0.02; // offset: removed
            let a = -0.01 * w1 * w1 * (w1 * t).sin() - 0.004 * w2 * w2 * (w2 * t + 0.3).sin() + 0.3; // bias
            let warm = t < 60.0;
            ok.update(d, a, warm);
            scaled.update(if warm { d } else { 1.1 * d }, a, warm);
        }
        let (g, r) = ok.gains().unwrap();
        assert!((r - 1.0).abs() < 2e-3 && (g - 1.0).abs() < 2e-3, "{g} {r}");
        let (g, r) = scaled.gains().unwrap();
        assert!((g / r - 1.1).abs() < 2e-3, "{g} {r}");
        assert!(scaled.disagrees(0.05) && !ok.disagrees(0.01));
    }
}

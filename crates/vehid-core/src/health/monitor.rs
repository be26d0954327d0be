//! [`HealthMonitor`]: tracking of `k2/M`, `b/M` and change detection (module documentation
//! of [`crate::health`] for the design).

use super::consistency::SensorGuard;
use super::event::{Constant, Estimate, Event, Reason, Status};
use super::kinematic::{DeflectionFilter, RateGain};
use super::rls::Rls3;
use crate::error::{check_nonneg, check_positive};
use crate::model::{QuarterCar, SensorNoise, SensorSet};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

/// Most samples the monitor holds back before using them (the stuck-sensor delay line).
pub const MAX_DELAY: usize = 64;

/// Innovation gate of the kinematic filter, standard deviations: a larger jump of the
/// deflection against the integrated accelerations is [`Reason::Jump`].
pub const JUMP_GATE: f64 = 8.0;

/// Largest relative change of the sensors' kinematic gain ([`KinematicCheck`]) the monitor
/// judges through, as a fraction of `min_change` (a deflection gain error `ε` moves both
/// ratios by about `−ε`; at `0.4 δ` it stays below the CUSUM's allowance `δ/2`).
pub const SENSOR_TOLERANCE: f64 = 0.4;

/// What a restart adds to the unscaled variance of the body equation's offset `c`
/// ([`crate::health::Rls::release`]): as much as the trackers start with.
pub(crate) const OFFSET_RELEASE: f64 = 1e6;

/// Random-walk variance of the body equation's offset `c` per sample, in the trackers'
/// unscaled units ([`crate::health::Rls::release`]): `c` moves with a drifting sensor zero,
/// and a tracker that holds it constant over its window lets the drift into `k2/M`. The
/// offset's own memory is then about `1/√q` samples (200: one second at 200 Hz). The
/// warm-up's reference holds `c` constant (least squares on the warm-up's rows).
pub const OFFSET_WALK: f64 = 2.5e-5;

/// Number of channels [`HealthMonitor::update`] reads with the realistic sensors:
/// `a_body` (m/s²), `a_wheel` (m/s²), `deflection` (m), `model::REALISTIC_CHANNELS`.
pub const CHANNELS: usize = 3;

/// Number of channels [`HealthMonitor::update`] reads with the state sensors: the measured
/// state and derivative of `model::STATE_CHANNELS`.
pub const STATE_CHANNELS: usize = 8;

/// Smallest deflection noise the state sensors' kinematic filter is designed for, m. The
/// state set may be noise-free, but the filter's own model (the acceleration linear between
/// samples) is not exact: with a floor of 1 µm its innovations on noise-free states crossed
/// the jump gate every few samples, and a monitor left at the default noise could not judge
/// 80–100 % of the time (the passenger car at 100 and 200 Hz, the thesis' car at 20 Hz). At
/// 0.1 mm (a third of the realistic deflection sensor's noise) it judged throughout on each.
pub const MIN_DEFLECTION_NOISE: f64 = 1e-4;

/// Settings of a [`HealthMonitor`] (the quarter car, `C = QuarterCar`) or of a
/// [`super::HalfHealthMonitor`] (`C = HalfCar`): the same settings, per axle for the half car.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct HealthConfig<T, C = QuarterCar<T>> {
    /// Sample interval, s (> 0).
    pub dt: T,
    /// The nominal car: its constants are the "before" of the first events (quarter car:
    /// `M`, `k2`, `b`; half car: `M`, `J`, the springs and dampers of both axles).
    pub car: C,
    /// The sensors read by [`HealthMonitor::update`]: [`SensorSet::Realistic`] (default;
    /// `[a_body, a_wheel, deflection]`) or [`SensorSet::State`] (the thesis' measured state
    /// and derivative `[zw, vw, zb, vb, dzw, dvw, dzb, dvb]`, of which the monitor uses the
    /// same three quantities, `a_body = dvb`, `a_wheel = dvw`, `deflection = zb − zw`, and the
    /// deflection rate `vb − vw` in its kinematic filter: module documentation, "State sensors").
    pub sensors: SensorSet,
    /// Noise of `a_body − a_wheel` per sample, m/s² (the kinematic filter's design;
    /// default √(0.02² + 0.1²), the defaults of `model::SensorNoise`).
    pub accel_noise: T,
    /// Deflection sensor noise, m (default 0.3e-3).
    pub deflection_noise: T,
    /// Random-walk density of the relative accelerometer bias, m/s² per √s (default 0.01).
    pub bias_walk: T,
    /// Time constant of the tracker's forgetting, `T_f = dt / (1 − λ)`, s (default 6: with
    /// 2 s and 4 s the tracked `k2/M` strayed past `δ/2` on class B at 8 m/s, with 6 s it did
    /// not in 100 h of varying speed and road, `health_experiment --calibrate --vary`).
    pub window: T,
    /// Seconds of usable data that form the reference (default 20).
    pub warmup: T,
    /// Seconds of usable data after an alarm that measure the new value (default 4).
    pub settle: T,
    /// Seconds the kinematic filter re-converges after missing or stuck data (default 2).
    pub reacquire: T,
    /// Smallest relative change of a ratio worth an event, `δ` (default 0.05).
    pub min_change: T,
    /// Largest relative standard error `s_j` of a tracked ratio at which the monitor
    /// judges (default 0.008, about `δ/6`, so that the allowance `δ/2` is three standard
    /// errors away); above it the status is `CannotJudge(LowExcitation)`.
    pub judge_error: T,
    /// CUSUM threshold `h` (log-likelihood-ratio units; default 8, calibrated by
    /// `benches/src/bin/health_experiment.rs`).
    pub threshold: T,
    /// Confidence level of the intervals (default 0.95).
    pub confidence: T,
    /// Relative systematic error allowed for in an event's interval, added in quadrature to
    /// the statistical one (default 0.005: a relative change measured through the kinematic
    /// filter's rate estimate keeps a bias of a few tenths of a percent that moves with the
    /// constants. Chosen on seeds 7000–7199 for at least 95 % coverage of each change by
    /// `benches/health_coverage.py`; on seeds 9000–9199 the intervals of damper, spring and
    /// mass changes covered the truth 100 %, 98 %, 100 %: conservative for the damper and
    /// the mass).
    pub systematic: T,
    /// Identical consecutive values that make a channel "stuck" (default 20, at most
    /// [`MAX_DELAY`]); also the delay (samples) before a sample is used.
    pub stuck_samples: usize,
}

impl<T: Real, C> HealthConfig<T, C> {
    /// The defaults for samples every `dt` seconds of `car`.
    pub fn new(dt: T, car: C) -> Self {
        Self {
            dt,
            car,
            sensors: SensorSet::Realistic,
            accel_noise: T::of(libm::sqrt(0.02 * 0.02 + 0.1 * 0.1)),
            deflection_noise: T::of(0.3e-3),
            bias_walk: T::of(0.01),
            window: T::of(6.0),
            warmup: T::of(20.0),
            settle: T::of(4.0),
            reacquire: T::of(2.0),
            min_change: T::of(0.05),
            judge_error: T::of(0.008),
            threshold: T::of(8.0),
            confidence: T::of(0.95),
            systematic: T::of(0.005),
            stuck_samples: 20,
        }
    }

    /// The same settings for the sensor set `sensors` with noise `noise` (the noise levels
    /// of a drive, `model::SensorNoise`): the kinematic filter's `accel_noise` and
    /// `deflection_noise` follow from them. Realistic: `√(σ_ab² + σ_aw²)` and `σ_d`. State:
    /// `√2 σ_v` and `√2 σ_w` (differences of two measured channels), the deflection noise at
    /// least [`MIN_DEFLECTION_NOISE`].
    pub fn with_sensors(mut self, sensors: SensorSet, noise: &SensorNoise<T>) -> Self {
        self.sensors = sensors;
        let two = T::of(2.0);
        match sensors {
            SensorSet::Realistic => {
                self.accel_noise = (noise.a_body * noise.a_body + noise.a_wheel * noise.a_wheel).sqrt();
                self.deflection_noise = noise.deflection;
            }
            SensorSet::State => {
                self.accel_noise = (two * noise.deriv * noise.deriv).sqrt();
                self.deflection_noise = (two * noise.state * noise.state).sqrt().max(T::of(MIN_DEFLECTION_NOISE));
            }
        }
        self
    }

    /// Checks the settings ([`HealthMonitor::new`] lists the rules); returns the kinematic
    /// filter they design and the normal quantile `z` of `confidence`.
    pub(crate) fn check(&self) -> Result<(DeflectionFilter<T>, T)> {
        let cfg = self;
        check_positive("dt", cfg.dt)?;
        check_positive("window", cfg.window)?;
        check_positive("warmup", cfg.warmup)?;
        check_positive("settle", cfg.settle)?;
        check_nonneg("reacquire", cfg.reacquire)?;
        check_positive("min_change", cfg.min_change)?;
        check_positive("judge_error", cfg.judge_error)?;
        check_positive("threshold", cfg.threshold)?;
        check_nonneg("systematic", cfg.systematic)?;
        if !(cfg.min_change < T::one()) {
            return Err(Error::InvalidArgument { arg: "min_change", expected: "a relative change in (0, 1)" });
        }
        let conf = cfg.confidence.to_f64();
        if !(conf > 0.0 && conf < 1.0) {
            return Err(Error::InvalidArgument { arg: "confidence", expected: "a level in (0, 1)" });
        }
        if !(2..=MAX_DELAY).contains(&cfg.stuck_samples) {
            return Err(Error::InvalidArgument { arg: "stuck_samples", expected: "between 2 and 64" });
        }
        if cfg.window.to_f64() < 10.0 * cfg.dt.to_f64() {
            return Err(Error::InvalidArgument { arg: "window", expected: "at least 10 sample intervals" });
        }
        let kf = DeflectionFilter::new(cfg.dt, cfg.accel_noise, cfg.deflection_noise, cfg.bias_walk)?;
        let z = T::of(crate::stats::normal_ppf(0.5 + conf / 2.0)?);
        Ok((kf, z))
    }

    /// The sensors' kinematic checks of `K` corners (`consistency.rs`) for a tracker with
    /// forgetting `lambda`: tolerance [`SENSOR_TOLERANCE`]` · min_change`, a hold of one window.
    pub(crate) fn sensor_guard<const K: usize>(&self, lambda: T) -> SensorGuard<T, K> {
        let tol = self.min_change * T::of(SENSOR_TOLERANCE);
        SensorGuard::new(self.dt, lambda, tol, samples_of(self.window, self.dt))
    }

    /// The state sensors' kinematic filter gain with the measured deflection rate
    /// ([`RateGain`]; the rate is formed from measured velocities as the deflection from
    /// measured positions, and the state set has one noise level on every state, so its noise
    /// is `deflection_noise` too); with the realistic sensors a zero gain that is never used.
    pub(crate) fn rate_gain(&self) -> Result<RateGain<T>> {
        match self.sensors {
            SensorSet::Realistic => Ok(RateGain::unused()),
            SensorSet::State => {
                RateGain::new(self.dt, self.accel_noise, self.deflection_noise, self.deflection_noise, self.bias_walk)
            }
        }
    }

    /// Samples in the warm-up, in the one-second burn-in of the noise estimate, in the
    /// settling, in the re-acquisition.
    pub(crate) fn sample_counts(&self) -> [u64; 4] {
        let n_reacq = if self.reacquire > T::zero() { samples_of(self.reacquire, self.dt) } else { 0 };
        [samples_of(self.warmup, self.dt), samples_of(T::of(1.0), self.dt), samples_of(self.settle, self.dt), n_reacq]
    }
}

impl<T: Real> HealthConfig<T> {
    /// Channels per sample of this sensor set ([`CHANNELS`] or [`STATE_CHANNELS`]).
    pub fn channels(&self) -> usize {
        match self.sensors {
            SensorSet::Realistic => CHANNELS,
            SensorSet::State => STATE_CHANNELS,
        }
    }
}

/// Samples of a duration (at least 1).
fn samples_of<T: Real>(seconds: T, dt: T) -> u64 {
    let n = libm::ceil(seconds.to_f64() / dt.to_f64());
    if n >= 1.0 {
        n as u64
    } else {
        1
    }
}

/// Where a monitor (quarter or half car) is in its cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub(super) enum Phase {
    Warmup,
    Monitoring,
    Settling,
}

impl Phase {
    /// The status a monitor in this phase reports: `CannotJudge(reason)` while it cannot.
    pub(super) fn status(self, reason: Option<Reason>) -> Status {
        if let Some(r) = reason {
            return Status::CannotJudge(r);
        }
        match self {
            Phase::Warmup => Status::Warmup,
            Phase::Monitoring => Status::Monitoring,
            Phase::Settling => Status::Settling,
        }
    }
}

/// The suspension health monitor of the quarter car with realistic sensors (module
/// documentation of [`crate::health`]).
///
/// # Examples
/// ```
/// use vehid_core::health::{HealthConfig, HealthMonitor, Status};
/// use vehid_core::model::QuarterCar;
/// let mut mon = HealthMonitor::new(HealthConfig::new(0.005, QuarterCar::<f64>::passenger())).unwrap();
/// assert_eq!(mon.update(&[0.1, -0.3, 0.002]).unwrap(), None);
/// assert_eq!(mon.status(), Status::Warmup);
/// assert!(mon.update(&[0.1, f64::INFINITY, 0.0]).is_err()); // rejected: nothing changed
/// ```
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct HealthMonitor<T: Real> {
    cfg: HealthConfig<T>,
    n_warm: u64,
    n_burn: u64,
    n_settle: u64,
    n_reacq: u64,
    z: T,
    kf: DeflectionFilter<T>,
    // The state sensors' filter gain with the measured rate (derived from the settings by
    // `HealthConfig::rate_gain`, also on load; not saved). Unused with the realistic sensors.
    #[cfg_attr(feature = "serde", serde(skip, default = "RateGain::unused"))]
    rate: RateGain<T>,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array2"))]
    ring: [[T; 3]; MAX_DELAY],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    ring_k: [u64; MAX_DELAY],
    head: usize,
    len: usize,
    prev: [T; 3],
    run: [usize; 3],
    have_prev: bool,
    reacq_left: u64,
    k: u64,
    phase: Phase,
    reason: Option<Reason>,
    reference: Rls3<T>,
    fast: Rls3<T>,
    post: Rls3<T>,
    warm_n: u64,
    post_n: u64,
    e2_sum: T,
    e2_n: u64,
    e1_sum: T,
    e_prev: Option<T>,
    inflate: T,
    sigma2: T,
    theta_ref: [T; 2],
    inv_ref: [T; 2],
    var_ref: [T; 2],
    g: [[T; 2]; 2],
    zero_k: [[u64; 2]; 2],
    onset: u64,
    belief: [T; 3],
    events: u64,
    sensors: SensorGuard<T, 1>,
}

impl<T: Real> HealthMonitor<T> {
    /// A monitor with settings `cfg`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the setting: `dt`, `window`, `warmup`, `settle`,
    /// `min_change` (< 1), `judge_error`, `threshold`, `deflection_noise` not finite and > 0; `reacquire`,
    /// `accel_noise`, `bias_walk` not finite and ≥ 0; `confidence` outside (0, 1);
    /// `stuck_samples` outside `2..=MAX_DELAY`; a `window` shorter than 10 samples.
    pub fn new(cfg: HealthConfig<T>) -> Result<Self> {
        let (kf, z) = cfg.check()?;
        let [n_warm, n_burn, n_settle, n_reacq] = cfg.sample_counts();
        let lambda = T::one() - cfg.dt / cfg.window;
        let p0 = SMatrix::<T, 3, 3>::identity() * T::of(1e6);
        let start = Rls3::new(SVector::zeros(), p0, T::one());
        let rate = cfg.rate_gain()?;
        Ok(Self {
            n_warm,
            n_burn,
            n_settle,
            n_reacq,
            z,
            kf,
            rate,
            ring: [[T::zero(); 3]; MAX_DELAY],
            ring_k: [0; MAX_DELAY],
            head: 0,
            len: 0,
            prev: [T::zero(); 3],
            run: [0; 3],
            have_prev: false,
            reacq_left: 0,
            k: 0,
            phase: Phase::Warmup,
            reason: None,
            reference: start,
            fast: Rls3::new(SVector::zeros(), p0, lambda),
            post: start,
            warm_n: 0,
            post_n: 0,
            e2_sum: T::zero(),
            e2_n: 0,
            e1_sum: T::zero(),
            e_prev: None,
            inflate: T::one(),
            sigma2: T::zero(),
            theta_ref: [T::zero(); 2],
            inv_ref: [T::zero(); 2],
            var_ref: [T::zero(); 2],
            g: [[T::zero(); 2]; 2],
            zero_k: [[0; 2]; 2],
            onset: 0,
            belief: [cfg.car.m_body(), cfg.car.k2(), cfg.car.b()],
            events: 0,
            sensors: cfg.sensor_guard(lambda),
            cfg,
        })
    }

    /// Checks a deserialized monitor (feature `serde`): its settings as [`HealthMonitor::new`]
    /// checks them, the delay line's indices, and finite statistics, so that a corrupt
    /// input is an error, never a panic later.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let fresh = Self::new(self.cfg)?;
        let corrupt = Error::InvalidArgument { arg: "state", expected: "a health monitor's saved state" };
        if self.head >= MAX_DELAY || self.len >= self.cfg.stuck_samples {
            return Err(corrupt);
        }
        // A run counted past the limit (saved before the count saturated) is the same state.
        let limit = self.cfg.stuck_samples;
        self.run.iter_mut().for_each(|r| *r = (*r).min(limit));
        if fresh.n_warm != self.n_warm || fresh.n_burn != self.n_burn || fresh.n_settle != self.n_settle {
            return Err(corrupt);
        }
        let finite = |v: T| v.to_f64().is_finite();
        let stats = [self.sigma2, self.e2_sum, self.e1_sum, self.inflate, self.z];
        if !stats.iter().all(|&v| finite(v)) || !self.belief.iter().all(|&v| finite(v) && v > T::zero()) {
            return Err(corrupt);
        }
        if !self.sensors.is_valid(&fresh.sensors) {
            return Err(corrupt);
        }
        self.rate = fresh.rate;
        Ok(())
    }

    /// The settings.
    pub fn config(&self) -> &HealthConfig<T> {
        &self.cfg
    }

    /// What the monitor is doing now.
    pub fn status(&self) -> Status {
        self.phase.status(self.reason)
    }

    /// Samples seen (accepted calls of [`HealthMonitor::update`]).
    pub fn samples(&self) -> u64 {
        self.k
    }

    /// Events reported so far.
    pub fn events(&self) -> u64 {
        self.events
    }

    /// The current belief `[M (kg), k2 (N/m), b (N·s/m)]`: the nominal car's, moved by
    /// every event.
    pub fn constants(&self) -> [T; 3] {
        self.belief
    }

    /// The reference `[k2/M, b/M]` the tracked ratios are compared with (`None` during
    /// the warm-up).
    pub fn reference(&self) -> Option<[T; 2]> {
        (self.phase != Phase::Warmup).then_some(self.theta_ref)
    }

    /// The CUSUM statistics `[[k2/M up, down], [b/M up, down]]` (threshold
    /// [`HealthConfig::threshold`]).
    pub fn cusum(&self) -> [[T; 2]; 2] {
        self.g
    }

    /// The noise variance of the body equation, (m/s²)²: the warm-up's residual variance
    /// once the reference is formed, its running value before.
    pub(crate) fn noise_var(&self) -> T {
        if self.phase != Phase::Warmup {
            self.sigma2
        } else if self.e2_n > 0 {
            self.e2_sum / T::of(self.e2_n as f64)
        } else {
            T::biggest().sqrt()
        }
    }

    /// The tracked `[k2/M, b/M, c]` with `confidence` intervals from `f σ² P / (1 + λ)` (the
    /// variance of an exponentially weighted least-squares estimate with stationary
    /// regressors; `f = (1 + ρ)/(1 − ρ)` for the lag-1 autocorrelation `ρ` of the warm-up's
    /// residuals, 1 before the reference is formed).
    pub fn estimate(&self) -> Estimate<T> {
        let s2 = self.inflate * self.noise_var() / (T::one() + self.fast.lambda());
        let th = self.fast.theta();
        let mut out = Estimate { value: [th[0], th[1], th[2]], low: [T::zero(); 3], high: [T::zero(); 3] };
        for j in 0..3 {
            let half = self.z * (s2 * self.fast.p()[(j, j)]).max(T::zero()).sqrt();
            out.low[j] = th[j] - half;
            out.high[j] = th[j] + half;
        }
        out
    }

    /// One sample: `y = [a_body (m/s²), a_wheel (m/s²), deflection (m)]` with the realistic
    /// sensors, `y = [zw, vw, zb, vb, dzw, dvw, dzb, dvb]` (m, m/s, m/s²) with the state
    /// sensors ([`HealthConfig::sensors`]); returns the event it completes, if any. A NaN
    /// channel marks a missing sample (a gap: status `CannotJudge(Missing)`). No allocation.
    ///
    /// # Errors
    /// [`Error::Shape`] for a length other than [`HealthConfig::channels`],
    /// [`Error::NonFinite`] for ±∞; the monitor is then unchanged.
    pub fn update(&mut self, y: &[T]) -> Result<Option<Event<T>>> {
        let missing = screen(y, self.cfg.channels())?;
        // The state sensors also measure the deflection rate `vb − vw`. (Two calls of the
        // inlined step, so that the realistic path is compiled without the rate's branch.)
        match self.cfg.sensors {
            SensorSet::Realistic => self.step(missing, [y[0], y[1], y[2]], None),
            SensorSet::State => self.step(missing, [y[7], y[5], y[2] - y[0]], Some(y[3] - y[1])),
        }
    }

    /// [`HealthMonitor::update`] after the screening: `y = [a_body, a_wheel, deflection]`,
    /// `rate` the measured deflection rate (state sensors), `missing` a NaN channel.
    #[inline(always)]
    fn step(&mut self, missing: bool, y: [T; CHANNELS], rate: Option<T>) -> Result<Option<Event<T>>> {
        let k = self.k;
        self.k += 1;
        if missing {
            self.have_prev = false;
            self.run = [0; 3];
            self.interrupt(Reason::Missing);
            return Ok(None);
        }
        let stuck = stuck_step(&mut self.prev, &mut self.run, self.have_prev, &y, self.cfg.stuck_samples);
        self.have_prev = true;
        if stuck {
            self.interrupt(Reason::Stuck);
            return Ok(None);
        }
        // No gate while the filter re-converges after a restart (its rate starts at 0).
        let gate = if self.reacq_left > 0 { T::biggest() } else { T::of(JUMP_GATE) };
        let filtered = match rate {
            None => self.kf.update_gated(y[2], y[0] - y[1], gate),
            Some(r) => self.kf.update_rate_gated(y[2], r, y[0] - y[1], &self.rate, gate),
        };
        let Some((d, v)) = filtered else {
            self.interrupt(Reason::Jump);
            return Ok(None);
        };
        self.sensors.observe(k, [(y[2], y[0] - y[1])], self.phase == Phase::Warmup);
        if self.reacq_left > 0 {
            self.reacq_left -= 1;
            self.reason = Some(Reason::Reacquiring);
            return Ok(None);
        }
        if matches!(self.reason, Some(Reason::Missing | Reason::Stuck | Reason::Jump | Reason::Reacquiring)) {
            self.reason = None;
        }
        // The delay line: a sample is used once `stuck_samples` newer ones arrived intact.
        let at = (self.head + self.len) % MAX_DELAY;
        self.ring[at] = [d, v, y[0]];
        self.ring_k[at] = k;
        self.len += 1;
        if self.len < self.cfg.stuck_samples {
            return Ok(None);
        }
        let [d, v, a] = self.ring[self.head];
        let kr = self.ring_k[self.head];
        self.head = (self.head + 1) % MAX_DELAY;
        self.len -= 1;
        Ok(self.feed(kr, d, v, a))
    }

    /// Drops the held-back samples and restarts the kinematic filter.
    /// The offset `c` of every tracker is released (`Rls::release`): a sensor whose zero
    /// jumped, or came back from a gap with another zero, moves `c` and nothing else.
    fn interrupt(&mut self, reason: Reason) {
        self.len = 0;
        self.kf.reset();
        self.sensors.restart();
        let q = T::of(OFFSET_RELEASE);
        self.reference.release(2, q);
        self.fast.release(2, q);
        self.post.release(2, q);
        self.reacq_left = self.n_reacq;
        self.reason = Some(reason);
    }

    /// Uses one regression row `a_body = −(k2/M) d − (b/M) ḋ + c` of sample `kr`.
    fn feed(&mut self, kr: u64, d: T, v: T, a: T) -> Option<Event<T>> {
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
    fn try_reference(&mut self, sigma2: T, theta: [T; 2], var: [T; 2]) -> bool {
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
    fn detect(&mut self, kr: u64) {
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
    fn finish(&mut self) -> Option<Event<T>> {
        // A change that arrived with a moved sensor gain is the sensor's: the gain's tracker
        // lags the ratios' by a few seconds, so it is looked at again before reporting.
        if self.sensors.vetoes() {
            self.g = [[T::zero(); 2]; 2];
            self.phase = Phase::Monitoring;
            self.reason = Some(Reason::Sensors);
            return None;
        }
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

/// One step of a pair of one-sided CUSUMs `[up, down]` on the relative deviation `r` (module
/// documentation of [`crate::health`], step 6): `g ← max(0, g + w (±r − δ/2))` with weight
/// `w = (1 − λ) δ / s²` and `half = δ/2`; records in `zero_k` the sample `kr` at which a side
/// was last zero. Returns the larger statistic and its side (0 up, 1 down; the first on a tie).
#[inline]
pub(crate) fn cusum_step<T: Real>(g: &mut [T; 2], zero_k: &mut [u64; 2], r: T, w: T, half: T, kr: u64) -> (T, usize) {
    let mut best = (T::zero(), 0usize);
    for (side, sign) in [T::one(), -T::one()].into_iter().enumerate() {
        let inc = w * (sign * r - half);
        let v = (g[side] + inc).max(T::zero());
        g[side] = v;
        if v == T::zero() {
            zero_k[side] = kr;
        }
        if v > best.0 {
            best = (v, side);
        }
    }
    best
}

/// Checks one sample's channels: the length `n`, ±∞ (an error, naming the index); returns
/// whether a channel is NaN (a missing sample).
pub(crate) fn screen<T: Real>(y: &[T], n: usize) -> Result<bool> {
    if y.len() != n {
        return Err(Error::Shape { arg: "y", expected: n, got: y.len() });
    }
    let mut missing = false;
    for (index, v) in y.iter().enumerate() {
        let f = v.to_f64();
        if f.is_nan() {
            missing = true;
        } else if !f.is_finite() {
            return Err(Error::NonFinite { arg: "y", index });
        }
    }
    Ok(missing)
}

/// Counts each channel's run of identical values (`run[i]`: repeats of `prev[i]`); `true`
/// when a channel has repeated its value `limit` times in a row (stuck).
pub(crate) fn stuck_step<T: Real, const C: usize>(
    prev: &mut [T; C],
    run: &mut [usize; C],
    have_prev: bool,
    y: &[T; C],
    limit: usize,
) -> bool {
    let mut stuck = false;
    for i in 0..C {
        if have_prev && y[i] == prev[i] {
            // Saturated at the limit: a channel stuck for hours keeps a small, savable count.
            run[i] = (run[i] + 1).min(limit);
        } else {
            run[i] = 0;
        }
        prev[i] = y[i];
        stuck |= run[i] + 1 >= limit;
    }
    stuck
}

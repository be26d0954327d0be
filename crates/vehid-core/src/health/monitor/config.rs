//! [`HealthConfig`]: the monitors' configuration (sampling, car, sensors, tuning) and what is
//! derived from it.

use super::*;

/// Settings of a [`HealthMonitor`] (the quarter car, `C = QuarterCar`) or of a
/// [`crate::health::HalfHealthMonitor`] (`C = HalfCar`): the same settings, per axle for the half car.
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

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

mod config;
mod detect;

pub use config::HealthConfig;

/// Most samples the monitor holds back before using them (the stuck-sensor delay line).
pub const MAX_DELAY: usize = 64;

/// Innovation gate of the kinematic filter, standard deviations: a larger jump of the
/// deflection against the integrated accelerations is [`Reason::Jump`].
pub const JUMP_GATE: f64 = 8.0;

/// Largest relative change of the sensors' kinematic gain ([`super::KinematicCheck`]) the monitor
/// judges through, as a fraction of `min_change`. A deflection gain error `ε` moves `k2/M` by
/// about `−1.2 ε` to `−1.5 ε` ([`super::GAIN_LEVERAGE`]), so a gain error just under this
/// tolerance can move it past the CUSUM's allowance `δ/2`: an event is also held back when a
/// gain has moved by a third of the event's size.
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
        if self.sensors.observe(k, [(y[2], y[0] - y[1])], self.phase == Phase::Warmup) {
            // A burst of the kinematic check (a step of the accelerations): a jump.
            self.interrupt(Reason::Jump);
            return Ok(None);
        }
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

//! [`HalfHealthMonitor`]: the quarter car's monitor for the half car (module documentation
//! of [`crate::health`], section "The half car", for the derivation).

use super::consistency::SensorGuard;
use super::event::{Event, Reason, Status};
use super::kinematic::{DeflectionFilter, RateGain};
use super::monitor::{
    cusum_step, screen, stuck_step, HealthConfig, Phase, JUMP_GATE, MAX_DELAY, OFFSET_RELEASE, OFFSET_WALK,
};
use super::pattern::{fit_kron, Fit};
use super::rls::Rls;
use crate::model::{HalfCar, HalfConstant, SensorSet};
use crate::{Real, Result};
use nalgebra::{SMatrix, SVector};

mod detect;

/// Channels [`HalfHealthMonitor::update`] reads with the realistic sensors:
/// `[a_body_f, a_body_r, a_wheel_f, a_wheel_r, deflection_f, deflection_r]`
/// (`model::HALF_REALISTIC_CHANNELS`).
pub const HALF_CHANNELS: usize = 6;

/// Channels [`HalfHealthMonitor::update`] reads with the state sensors (the measured state
/// and derivative, `model::HALF_STATE_CHANNELS`).
pub const HALF_STATE_CHANNELS: usize = 16;

/// The constants the half car's monitor names, in the order of its patterns and of
/// [`HalfHealthMonitor::cusum`].
pub const HALF_NAMED: [HalfConstant; 5] = [
    HalfConstant::FrontSpring,
    HalfConstant::FrontDamper,
    HalfConstant::RearSpring,
    HalfConstant::RearDamper,
    HalfConstant::BodyMass,
];

impl<T: Real> HealthConfig<T, HalfCar<T>> {
    /// Channels per sample of this sensor set ([`HALF_CHANNELS`] or [`HALF_STATE_CHANNELS`]).
    pub fn channels(&self) -> usize {
        match self.sensors {
            SensorSet::Realistic => HALF_CHANNELS,
            SensorSet::State => HALF_STATE_CHANNELS,
        }
    }
}

/// The half car's decision interval, seconds: the pattern fits and the CUSUM steps run on
/// every sample whose index is a multiple of `round(DECISION_INTERVAL / dt)` (at least 1;
/// 10 at 200 Hz), each step weighted by that many samples (module documentation of
/// [`crate::health`], "The half car").
pub const DECISION_INTERVAL: f64 = 0.05;

/// The tracked coefficients of the two body-corner equations with their intervals: row `o`
/// (0 front, 1 rear) is `[α_o,f k2_f, α_o,f b_f, α_o,r k2_r, α_o,r b_r, c_o]` (1/s², 1/s,
/// 1/s², 1/s, m/s²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfEstimate<T> {
    /// The estimates.
    pub value: [[T; 5]; 2],
    /// Lower ends of the `confidence` intervals.
    pub low: [[T; 5]; 2],
    /// Upper ends.
    pub high: [[T; 5]; 2],
}

/// The suspension health monitor of the half car with realistic sensors (module
/// documentation of [`crate::health`], "The half car"). The settings are the quarter car's
/// [`HealthConfig`], with the half car as the nominal car; each axle's kinematic filter uses
/// the same noise settings.
///
/// # Examples
/// ```
/// use vehid_core::health::{HalfHealthMonitor, HealthConfig, Status};
/// use vehid_core::model::HalfCar;
/// let mut mon = HalfHealthMonitor::new(HealthConfig::new(0.005, HalfCar::<f64>::passenger())).unwrap();
/// assert_eq!(mon.update(&[0.1, 0.2, -0.3, 0.1, 0.002, -0.001]).unwrap(), None);
/// assert_eq!(mon.status(), Status::Warmup);
/// assert!(mon.update(&[0.1, 0.2, f64::INFINITY, 0.1, 0.0, 0.0]).is_err()); // nothing changed
/// ```
///
/// With the feature `serde` it is saved and restored (checked on load, as the quarter car's
/// monitor: a corrupt input is an error, never a later panic).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct HalfHealthMonitor<T: Real> {
    cfg: HealthConfig<T, HalfCar<T>>,
    n_warm: u64,
    n_burn: u64,
    n_settle: u64,
    n_reacq: u64,
    // Samples per decision (`DECISION_INTERVAL / dt`, derived from the settings; not saved).
    #[cfg_attr(feature = "serde", serde(skip))]
    n_decide: u64,
    z: T,
    kf: [DeflectionFilter<T>; 2],
    // The state sensors' filter gain with the measured rates (both axles; derived from the
    // settings, also on load; not saved). Unused with the realistic sensors.
    #[cfg_attr(feature = "serde", serde(skip, default = "RateGain::unused"))]
    rate: RateGain<T>,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array2"))]
    ring: [[T; 6]; MAX_DELAY],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    ring_k: [u64; MAX_DELAY],
    head: usize,
    len: usize,
    prev: [T; 6],
    run: [usize; 6],
    have_prev: bool,
    reacq_left: u64,
    k: u64,
    phase: Phase,
    reason: Option<Reason>,
    reference: Rls<T, 5, 2>,
    fast: Rls<T, 5, 2>,
    post: Rls<T, 5, 2>,
    warm_n: u64,
    post_n: u64,
    e2_sum: [[T; 2]; 2],
    e2_n: u64,
    e1_sum: [T; 2],
    e_prev: Option<SVector<T, 2>>,
    inflate: T,
    sigma: [[T; 2]; 2],
    inv_ref: SVector<T, 8>,
    c_ref: SMatrix<T, 8, 8>,
    theta_ref: SMatrix<T, 5, 2>,
    // Derived from `c_ref`, `theta_ref` and `sigma` (by `derive`, also on load; not saved):
    // the reference's covariance factor `P_ref` (rows and columns 0–3) and `Σ⁻¹`.
    #[cfg_attr(feature = "serde", serde(skip, default = "SMatrix::zeros"))]
    q_ref: SMatrix<T, 4, 4>,
    #[cfg_attr(feature = "serde", serde(skip, default = "SMatrix::zeros"))]
    sigma_inv: SMatrix<T, 2, 2>,
    cap: [T; 5],
    g: [[T; 2]; 5],
    zero_k: [[u64; 2]; 5],
    onset: u64,
    sensors: SensorGuard<T, 2>,
    belief: [T; 12],
    events: u64,
}

impl<T: Real> HalfHealthMonitor<T> {
    /// A monitor with settings `cfg`.
    ///
    /// # Errors
    /// As [`super::HealthMonitor::new`]: [`Error::InvalidArgument`](crate::Error::InvalidArgument)
    /// naming the setting.
    pub fn new(cfg: HealthConfig<T, HalfCar<T>>) -> Result<Self> {
        let (kf, z) = cfg.check()?;
        let [n_warm, n_burn, n_settle, n_reacq] = cfg.sample_counts();
        let lambda = T::one() - cfg.dt / cfg.window;
        let p0 = SMatrix::<T, 5, 5>::identity() * T::of(1e6);
        let start = Rls::new(SMatrix::zeros(), p0, T::one());
        let rate = cfg.rate_gain()?;
        Ok(Self {
            n_warm,
            n_burn,
            n_settle,
            n_reacq,
            n_decide: (libm::round(DECISION_INTERVAL / cfg.dt.to_f64()) as u64).max(1),
            z,
            kf: [kf, kf],
            rate,
            ring: [[T::zero(); 6]; MAX_DELAY],
            ring_k: [0; MAX_DELAY],
            head: 0,
            len: 0,
            prev: [T::zero(); 6],
            run: [0; 6],
            have_prev: false,
            reacq_left: 0,
            k: 0,
            phase: Phase::Warmup,
            reason: None,
            reference: start,
            fast: Rls::new(SMatrix::zeros(), p0, lambda),
            post: start,
            warm_n: 0,
            post_n: 0,
            e2_sum: [[T::zero(); 2]; 2],
            e2_n: 0,
            e1_sum: [T::zero(); 2],
            e_prev: None,
            inflate: T::one(),
            sigma: [[T::zero(); 2]; 2],
            inv_ref: SVector::zeros(),
            c_ref: SMatrix::zeros(),
            theta_ref: SMatrix::zeros(),
            q_ref: SMatrix::zeros(),
            sigma_inv: SMatrix::zeros(),
            cap: [T::biggest(); 5],
            g: [[T::zero(); 2]; 5],
            zero_k: [[0; 2]; 5],
            onset: 0,
            sensors: cfg.sensor_guard(lambda),
            belief: cfg.car.constants(),
            events: 0,
            cfg,
        })
    }

    /// Checks a deserialized monitor (feature `serde`): its settings as
    /// [`HalfHealthMonitor::new`] checks them, the delay line's indices, finite statistics
    /// and positive constants.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let fresh = Self::new(self.cfg)?;
        let corrupt =
            crate::Error::InvalidArgument { arg: "state", expected: "a half-car health monitor's saved state" };
        if self.head >= MAX_DELAY || self.len >= self.cfg.stuck_samples {
            return Err(corrupt);
        }
        // A run counted past the limit (saved before the count saturated) is the same state.
        let limit = self.cfg.stuck_samples;
        self.run.iter_mut().for_each(|r| *r = (*r).min(limit));
        if fresh.n_warm != self.n_warm || fresh.n_burn != self.n_burn || fresh.n_settle != self.n_settle {
            return Err(corrupt);
        }
        let finite = |v: &T| v.to_f64().is_finite();
        let stats = [self.e2_sum[0][0], self.e2_sum[1][1], self.e1_sum[0], self.e1_sum[1], self.inflate, self.z];
        if !stats.iter().all(finite)
            || !self.sigma.iter().flatten().all(finite)
            || !self.belief.iter().all(|v| finite(v) && *v > T::zero())
        {
            return Err(corrupt);
        }
        if !self.sensors.is_valid(&fresh.sensors) {
            return Err(corrupt);
        }
        self.n_decide = fresh.n_decide;
        self.rate = fresh.rate;
        self.derive();
        Ok(())
    }

    /// Sets the fits' factors derived from the reference: `Σ⁻¹` and `P_ref`'s block of the
    /// eight coefficients, recovered from `c_ref = D (Σ ⊗ P_ref) D` (its first equation's
    /// block, `Σ_00 P_ref,jk / (θ_ref,j θ_ref,k)`) so that a restored monitor, which saves
    /// `c_ref` only, derives the same bits. (Zeros while there is no reference.)
    fn derive(&mut self) {
        let s = self.sigma;
        let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
        if !(s[0][0] > T::zero() && det > T::zero()) {
            self.sigma_inv = SMatrix::zeros();
            self.q_ref = SMatrix::zeros();
            return;
        }
        self.sigma_inv = SMatrix::<T, 2, 2>::new(s[1][1], -s[0][1], -s[1][0], s[0][0]) / det;
        let (th, c, s00) = (&self.theta_ref, &self.c_ref, s[0][0]);
        self.q_ref = SMatrix::from_fn(|j, k| c[(j, k)] * th[(j, 0)] * th[(k, 0)] / s00);
    }

    /// Samples per decision, and a setter for the tests (1: decide on every sample).
    #[cfg(test)]
    pub(crate) fn decision_samples(&mut self, n: Option<u64>) -> u64 {
        if let Some(n) = n {
            self.n_decide = n;
        }
        self.n_decide
    }

    /// The settings.
    pub fn config(&self) -> &HealthConfig<T, HalfCar<T>> {
        &self.cfg
    }

    /// What the monitor is doing now.
    pub fn status(&self) -> Status {
        self.phase.status(self.reason)
    }

    /// Samples seen (accepted calls of [`HalfHealthMonitor::update`]).
    pub fn samples(&self) -> u64 {
        self.k
    }

    /// Events reported so far.
    pub fn events(&self) -> u64 {
        self.events
    }

    /// The current belief of the car's constants in the order of [`HalfCar::CONSTANTS`]:
    /// the nominal car's, moved by every event (a body-mass event moves `M` and `J`).
    pub fn constants(&self) -> [T; 12] {
        self.belief
    }

    /// The reference coefficients (rows as in [`HalfEstimate`]; `None` during the warm-up).
    pub fn reference(&self) -> Option<[[T; 5]; 2]> {
        (self.phase != Phase::Warmup).then(|| rows(&self.theta_ref))
    }

    /// The CUSUM statistics `[up, down]` of each constant of [`HALF_NAMED`] (threshold
    /// [`HealthConfig::threshold`]), as of the last decision (every [`DECISION_INTERVAL`]; so
    /// is the status's low excitation).
    pub fn cusum(&self) -> [[T; 2]; 5] {
        self.g
    }

    /// The residual covariance `Σ` of the two body-corner equations, (m/s²)²: the
    /// warm-up's once the reference is formed, its running value before.
    pub fn noise_cov(&self) -> [[T; 2]; 2] {
        if self.phase != Phase::Warmup {
            self.sigma
        } else if self.e2_n > 0 {
            let n = T::of(self.e2_n as f64);
            self.e2_sum.map(|r| r.map(|v| v / n))
        } else {
            [[T::biggest().sqrt(), T::zero()], [T::zero(), T::biggest().sqrt()]]
        }
    }

    /// The tracked coefficients with `confidence` intervals from `f Σ_oo P / (1 + λ)`
    /// (as [`super::HealthMonitor::estimate`], per equation).
    pub fn estimate(&self) -> HalfEstimate<T> {
        let s = self.noise_cov();
        let value = rows(self.fast.theta());
        let mut out = HalfEstimate { value, low: value, high: value };
        for o in 0..2 {
            let s2 = self.inflate * s[o][o] / (T::one() + self.fast.lambda());
            for j in 0..5 {
                let half = self.z * (s2 * self.fast.p()[(j, j)]).max(T::zero()).sqrt();
                out.low[o][j] = value[o][j] - half;
                out.high[o][j] = value[o][j] + half;
            }
        }
        out
    }

    /// One sample: `y = [a_body_f, a_body_r, a_wheel_f, a_wheel_r, deflection_f,
    /// deflection_r]` (m/s², m) with the realistic sensors, the 16 channels of
    /// `model::HALF_STATE_CHANNELS` with the state sensors (the monitor forms the same six
    /// quantities from them: `dvb ± l dom`, `dv1`, `dv2`, `zb + l1 ph − z1`, `zb − l2 ph − z2`,
    /// and the deflection rates `vb + l1 om − v1`, `vb − l2 om − v2` for the kinematic filters);
    /// returns the event it completes, if any. A NaN channel marks a missing sample. No
    /// allocation.
    ///
    /// # Errors
    /// [`Error::Shape`](crate::Error::Shape) for a length other than the sensor set's channels,
    /// [`Error::NonFinite`](crate::Error::NonFinite) for ±∞; the monitor is then unchanged.
    pub fn update(&mut self, y: &[T]) -> Result<Option<Event<T, HalfConstant>>> {
        let missing = screen(y, self.cfg.channels())?;
        let p = self.cfg.car.params();
        let (l1, l2) = (p.l1, p.l2);
        // The state sensors also measure the deflection rates `vb + l1 om − v1`,
        // `vb − l2 om − v2`. (Two calls of the inlined step, so that the realistic path is
        // compiled without the rates' branch.)
        match self.cfg.sensors {
            SensorSet::Realistic => self.step(missing, [y[0], y[1], y[2], y[3], y[4], y[5]], None),
            SensorSet::State => self.step(
                missing,
                [y[13] + l1 * y[15], y[13] - l2 * y[15], y[9], y[11], y[4] + l1 * y[6] - y[0], y[4] - l2 * y[6] - y[2]],
                Some([y[5] + l1 * y[7] - y[1], y[5] - l2 * y[7] - y[3]]),
            ),
        }
    }

    /// [`HalfHealthMonitor::update`] after the screening: the six quantities `y`, `rates` the
    /// measured deflection rates (state sensors), `missing` a NaN channel.
    #[inline(always)]
    fn step(&mut self, missing: bool, y: [T; 6], rates: Option<[T; 2]>) -> Result<Option<Event<T, HalfConstant>>> {
        let k = self.k;
        self.k += 1;
        if missing {
            self.have_prev = false;
            self.run = [0; 6];
            self.interrupt(Reason::Missing);
            return Ok(None);
        }
        let stuck = stuck_step(&mut self.prev, &mut self.run, self.have_prev, &y, self.cfg.stuck_samples);
        self.have_prev = true;
        if stuck {
            self.interrupt(Reason::Stuck);
            return Ok(None);
        }
        let gate = if self.reacq_left > 0 { T::biggest() } else { T::of(JUMP_GATE) };
        let (front, rear) = match rates {
            None => {
                (self.kf[0].update_gated(y[4], y[0] - y[2], gate), self.kf[1].update_gated(y[5], y[1] - y[3], gate))
            }
            Some([rf, rr]) => (
                self.kf[0].update_rate_gated(y[4], rf, y[0] - y[2], &self.rate, gate),
                self.kf[1].update_rate_gated(y[5], rr, y[1] - y[3], &self.rate, gate),
            ),
        };
        let (Some((df, vf)), Some((dr, vr))) = (front, rear) else {
            self.interrupt(Reason::Jump);
            return Ok(None);
        };
        if self.sensors.observe(k, [(y[4], y[0] - y[2]), (y[5], y[1] - y[3])], self.phase == Phase::Warmup) {
            // A burst of a kinematic check (a step of the accelerations): a jump.
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
        let at = (self.head + self.len) % MAX_DELAY;
        self.ring[at] = [df, vf, dr, vr, y[0], y[1]];
        self.ring_k[at] = k;
        self.len += 1;
        if self.len < self.cfg.stuck_samples {
            return Ok(None);
        }
        let row = self.ring[self.head];
        let kr = self.ring_k[self.head];
        self.head = (self.head + 1) % MAX_DELAY;
        self.len -= 1;
        Ok(self.feed(kr, row))
    }

    /// Drops the held-back samples and restarts both kinematic filters.
    /// The offsets `c` of every tracker are released, as the quarter car's monitor does.
    fn interrupt(&mut self, reason: Reason) {
        self.len = 0;
        self.kf[0].reset();
        self.kf[1].reset();
        self.sensors.restart();
        let q = T::of(OFFSET_RELEASE);
        self.reference.release(4, q);
        self.fast.release(4, q);
        self.post.release(4, q);
        self.reacq_left = self.n_reacq;
        self.reason = Some(reason);
    }

    /// Uses one regression row `[a_bf, a_br] = −Θᵀ [d_f, ḋ_f, d_r, ḋ_r] + c` of sample `kr`.
    fn feed(&mut self, kr: u64, row: [T; 6]) -> Option<Event<T, HalfConstant>> {
        let [df, vf, dr, vr, af, ar] = row;
        let phi = SVector::<T, 5>::new(-df, -vf, -dr, -vr, T::one());
        let y = SVector::<T, 2>::new(af, ar);
        self.fast.release(4, T::of(OFFSET_WALK));
        if self.phase != Phase::Warmup && self.sensors.holds() {
            // The sensors disagree (as in the quarter car's monitor): track, judge nothing.
            self.fast.update_all(&phi, &y);
            self.phase = Phase::Monitoring;
            self.g = [[T::zero(); 2]; 5];
            self.reason = Some(Reason::Sensors);
            return None;
        }
        match self.phase {
            Phase::Warmup => {
                let e = self.reference.update_all(&phi, &y);
                self.fast.update_all(&phi, &y);
                self.warm_n += 1;
                if let (Some(e), true) = (e, self.warm_n > self.n_burn) {
                    for a in 0..2 {
                        for b in 0..2 {
                            self.e2_sum[a][b] += e[a] * e[b];
                        }
                    }
                    self.e2_n += 1;
                    if let Some(prev) = self.e_prev {
                        for o in 0..2 {
                            self.e1_sum[o] += e[o] * prev[o];
                        }
                    }
                    self.e_prev = Some(e);
                }
                if self.warm_n >= self.n_warm && self.e2_n > 0 {
                    let n = T::of(self.e2_n as f64);
                    let sigma = self.e2_sum.map(|r| r.map(|v| v / n));
                    let mut rho = T::zero();
                    for o in 0..2 {
                        rho = rho.max(self.e1_sum[o] / self.e2_sum[o][o]);
                    }
                    let rho = rho.max(T::zero()).min(T::of(0.95));
                    self.inflate = (T::one() + rho) / (T::one() - rho);
                    let (th, p) = (*self.reference.theta(), *self.reference.p());
                    self.try_reference(sigma, th, &p);
                }
                None
            }
            Phase::Monitoring => {
                self.fast.update_all(&phi, &y);
                if kr % self.n_decide == 0 {
                    self.detect(kr);
                }
                None
            }
            Phase::Settling => {
                self.fast.update_all(&phi, &y);
                self.post.release(4, T::of(OFFSET_WALK));
                self.post.update_all(&phi, &y);
                self.post_n += 1;
                if self.post_n >= self.n_settle {
                    self.finish()
                } else {
                    None
                }
            }
        }
    }
}

/// `Θ` (`5 × 2`, a column per equation) as rows per equation.
fn rows<T: Real>(theta: &SMatrix<T, 5, 2>) -> [[T; 5]; 2] {
    [0, 1].map(|o| [0, 1, 2, 3, 4].map(|j| theta[(j, o)]))
}

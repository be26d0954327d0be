//! [`FullHealthMonitor`]: the half car's monitor for the full car (module documentation of
//! [`crate::health`], section "The full car", for the derivation).

use super::consistency::SensorGuard;
use super::event::{Event, Reason, Status};
use super::half::DECISION_INTERVAL;
use super::kinematic::{DeflectionFilter, RateGain};
use super::monitor::{
    cusum_step, screen, stuck_step, HealthConfig, Phase, JUMP_GATE, MAX_DELAY, OFFSET_RELEASE, OFFSET_WALK,
};
use super::pattern::{fit_kron_patterns, spd_inverse, Fit, Pattern};
use super::rls::Rls;
use crate::model::{FullCar, SensorSet, FULL_CONSTANTS};
use crate::sim::FullConstant;
use crate::{Real, Result};
use nalgebra::{SMatrix, SVector};

mod detect;

/// Channels [`FullHealthMonitor::update`] reads with the realistic sensors
/// (`model::FULL_REALISTIC_CHANNELS`): `[a_body_fl, a_body_fr, a_body_rl, a_body_rr,
/// a_wheel_fl, …, a_wheel_rr, deflection_fl, …, deflection_rr]`.
pub const FULL_CHANNELS: usize = 12;

/// Channels [`FullHealthMonitor::update`] reads with the state sensors (the measured state and
/// derivative, `model::FULL_STATE_CHANNELS`).
pub const FULL_STATE_CHANNELS: usize = 28;

/// Number of constants the full car's monitor names ([`FULL_NAMED`]).
pub const FULL_NAMED_COUNT: usize = 11;

/// The constants the full car's monitor names, in the order of its patterns and of
/// [`FullHealthMonitor::cusum`]: the four springs `k_fl … k_rr`, the four dampers
/// `b_fl … b_rr` (corner order fl, fr, rl, rr), the body mass `M` (a load: `Jx`, `Jy` scale with
/// it), the front and rear anti-roll bars `arb_f`, `arb_r` (N m/rad). A bar is judged by the
/// change it makes to its axle's roll stiffness ([`full_bar_share`]: the CUSUM's `min_change`
/// and `judge_error` apply to `Δarb / K_φ`); its event reports the bar's own change. A bar the
/// nominal car does not have (`0`) is not judged: its pattern is zero
/// ([`full_relative_patterns`]) and its CUSUM stays 0.
pub const FULL_NAMED: [FullConstant; FULL_NAMED_COUNT] = [
    FullConstant::at(7),
    FullConstant::at(8),
    FullConstant::at(9),
    FullConstant::at(10),
    FullConstant::at(11),
    FullConstant::at(12),
    FullConstant::at(13),
    FullConstant::at(14),
    FullConstant::at(0),
    FullConstant::at(23),
    FullConstant::at(24),
];

/// The least accelerometer noise the full car's monitor assumes, m/s² (added to the residual
/// covariance `Σ` in quadrature): the four corner equations hold only three rigid-body
/// accelerations, so on noise-free accelerations (state sensors without derivative noise) one
/// combination's residual is exactly zero and `Σ` singular. 10⁻³ m/s² is 0.1 mg, a twentieth
/// of the realistic body accelerometer's default noise.
pub const MIN_ACCEL_NOISE: f64 = 1e-3;

/// Index of the body mass in [`FULL_NAMED`].
const BODY_MASS: usize = 8;

/// Index of the front anti-roll bar in [`FULL_NAMED`] (the rear one follows).
pub(crate) const FRONT_BAR: usize = 9;

impl<T: Real> HealthConfig<T, FullCar<T>> {
    /// Channels per sample of this sensor set ([`FULL_CHANNELS`] or [`FULL_STATE_CHANNELS`]).
    pub fn channels(&self) -> usize {
        match self.sensors {
            SensorSet::Realistic => FULL_CHANNELS,
            SensorSet::State => FULL_STATE_CHANNELS,
        }
    }
}

/// The body's acceleration coefficients `α_ij = 1/M + x_i x_j / Jy + y_i y_j / Jx` (corner
/// order; module documentation, "The full car").
pub fn full_alpha<T: Real>(car: &FullCar<T>) -> SMatrix<T, 4, 4> {
    let p = car.params();
    SMatrix::from_fn(|i, j| {
        let (xi, yi) = car.corner_position(i);
        let (xj, yj) = car.corner_position(j);
        T::one() / p.m_body + xi * xj / p.jy + yi * yj / p.jx
    })
}

/// The suspension's stiffness matrix over the four extensions: the springs on the diagonal,
/// each anti-roll bar `K/t²` between its axle's two corners (`[[1, −1], [−1, 1]] K/t²`).
pub fn full_stiffness<T: Real>(car: &FullCar<T>) -> SMatrix<T, 4, 4> {
    let p = car.params();
    let mut k = SMatrix::<T, 4, 4>::from_diagonal(&SVector::from(p.k));
    for (a, bar, t) in [(0, p.arb_f, p.track_f), (2, p.arb_r, p.track_r)] {
        let s = bar / (t * t);
        k[(a, a)] += s;
        k[(a + 1, a + 1)] += s;
        k[(a, a + 1)] -= s;
        k[(a + 1, a)] -= s;
    }
    k
}

/// The coefficients of the four body-corner equations `a_i = Σ_j (Θ_2j,i (−d_j) + Θ_2j+1,i
/// (−ḋ_j)) + c_i` of `car` (`8 × 4`, a column per equation `i`; row `2j` the extension of corner
/// `j`, row `2j + 1` its rate): `Θ_2j,i = (α K)_ij`, `Θ_2j+1,i = α_ij b_j`.
pub fn full_coefficients<T: Real>(car: &FullCar<T>) -> SMatrix<T, 8, 4> {
    let (alpha, stiff, b) = (full_alpha(car), full_stiffness(car), car.params().b);
    let ak = alpha * stiff;
    SMatrix::from_fn(|r, i| {
        let j = r / 2;
        if r % 2 == 0 {
            ak[(i, j)]
        } else {
            alpha[(i, j)] * b[j]
        }
    })
}

/// The relative patterns `u_c = (∂Θ/∂ ln c) / Θ` of the constants of [`FULL_NAMED`] at `car`
/// (entries where `Θ` is zero to rounding are 0): spring `k_j`, `α_ij k_j / (αK)_ij` in row `2j`
/// (1 without anti-roll bars); damper `b_j`, 1 in row `2j + 1`; the body mass, all ones — the
/// sign of `∂ ln Θ / ∂ ln M = −1` is folded into its report (`M (1 + ε)` moves every coefficient
/// by `1/(1 + ε) − 1`); the front bar (`s = arb_f / t_f²`, [`full_stiffness`]),
/// `(α_i,fl − α_i,fr) s / Θ` in row 0 (corner fl's extension) and its negative over `Θ` in row 2
/// (fr's), the rear bar the same on rows 4 and 6, each divided by the bar's share of its axle's
/// roll stiffness ([`full_bar_share`]: the fitted amplitude is the change of the roll
/// stiffness, `Δarb / K_φ`) — zero for a bar of `0` (not judged).
pub fn full_relative_patterns<T: Real>(car: &FullCar<T>) -> [SMatrix<T, 8, 4>; FULL_NAMED_COUNT] {
    let (alpha, theta, p) = (full_alpha(car), full_coefficients(car), car.params());
    let big = theta.iter().fold(T::zero(), |m, v| m.max(v.abs()));
    let tiny = big * T::of(1e-9);
    let rel = |d: T, th: T| if th.abs() > tiny { d / th } else { T::zero() };
    // s / share = (arb / t²) (K_φ / arb) = K_φ / t² (0 without the bar).
    let bars: [T; 2] = core::array::from_fn(|a| {
        let (bar, t, roll) = axle_roll(car, a);
        if bar > T::zero() {
            roll / (t * t)
        } else {
            T::zero()
        }
    });
    core::array::from_fn(|c| {
        SMatrix::from_fn(|r, i| match c {
            0..=3 if r == 2 * c => rel(alpha[(i, c)] * p.k[c], theta[(r, i)]),
            4..=7 if r == 2 * (c - 4) + 1 => T::one(),
            BODY_MASS => T::one(),
            FRONT_BAR.. if r % 2 == 0 && r / 4 == c - FRONT_BAR => {
                // Corners a (left) and a + 1 (right) of the bar's axle; row 2j is corner j's.
                let a = 2 * (c - FRONT_BAR);
                let d = (alpha[(i, a)] - alpha[(i, a + 1)]) * bars[c - FRONT_BAR];
                rel(if r / 2 == a { d } else { -d }, theta[(r, i)])
            }
            _ => T::zero(),
        })
    })
}

/// The share of axle `a`'s (0 front, 1 rear) roll stiffness that its anti-roll bar holds,
/// `arb / K_φ` with `K_φ = (k_l + k_r) t² / 4 + arb` (N m/rad: the two springs at `±t/2`
/// and the bar); 0 without a bar. The monitor judges a bar's change by `Δarb / K_φ`, the
/// change of the axle's roll stiffness: what the ride and the handling feel (a 10 % change of
/// a bar holding a quarter of the roll stiffness moves it by 2.5 %).
pub fn full_bar_share<T: Real>(car: &FullCar<T>, a: usize) -> T {
    let (bar, _, roll) = axle_roll(car, a);
    if bar > T::zero() {
        bar / roll
    } else {
        T::zero()
    }
}

/// Axle `a`'s (0 front, 1 rear) anti-roll bar, track width and roll stiffness
/// `K_φ = (k_l + k_r) t²/4 + arb` (N m/rad, m, N m/rad).
pub(crate) fn axle_roll<T: Real>(car: &FullCar<T>, a: usize) -> (T, T, T) {
    let p = car.params();
    let (bar, t, k) =
        if a == 0 { (p.arb_f, p.track_f, p.k[0] + p.k[1]) } else { (p.arb_r, p.track_r, p.k[2] + p.k[3]) };
    (bar, t, k * t * t / T::of(4.0) + bar)
}

/// Which constants of [`FULL_NAMED`] the monitor judges for `car`: every one but an
/// anti-roll bar the car does not have.
pub(crate) fn full_judged<T: Real>(car: &FullCar<T>) -> [bool; FULL_NAMED_COUNT] {
    core::array::from_fn(|c| c < FRONT_BAR || axle_roll(car, c - FRONT_BAR).0 > T::zero())
}

/// The relative pattern of a point mass `m` set down on the body at `(x, y)` (m from the
/// centre of mass, `x` forward, `y` to the left), and `s = 1/M + x²/Jy + y²/Jx`. The mass
/// matrix `diag(M, Jy, Jx)` gains `m v vᵀ` (`v = [1, x, y]`), so by Sherman–Morrison the body's
/// acceleration coefficients become `α − m_e w wᵀ` with `w_i = 1/M + x_i x/Jy + y_i y/Jx` (corner
/// `i`'s acceleration per unit force at the load) and `m_e = m / (1 + m s)`: `ΔΘ_2j,i =
/// −m_e w_i (K w)_j`, `ΔΘ_2j+1,i = −m_e w_i w_j b_j` ([`full_coefficients`]). Returned per unit
/// `m_e / M` and relative to `Θ` (entries where `Θ` is zero to rounding are 0); a fitted
/// amplitude `ε` is the mass `m = ε M / (1 − ε M s)`.
pub fn full_load_pattern<T: Real>(car: &FullCar<T>, x: T, y: T) -> (SMatrix<T, 8, 4>, T) {
    let p = car.params();
    let theta = full_coefficients(car);
    let stiff = full_stiffness(car);
    let w = SVector::<T, 4>::from_fn(|i, _| {
        let (xi, yi) = car.corner_position(i);
        T::one() / p.m_body + xi * x / p.jy + yi * y / p.jx
    });
    let kw = stiff * w;
    let big = theta.iter().fold(T::zero(), |m, v| m.max(v.abs()));
    let tiny = big * T::of(1e-9);
    let u = SMatrix::from_fn(|r, i| {
        let j = r / 2;
        let d = if r % 2 == 0 { kw[j] } else { w[j] * p.b[j] };
        let th = theta[(r, i)];
        if th.abs() > tiny {
            -p.m_body * w[i] * d / th
        } else {
            T::zero()
        }
    });
    (u, T::one() / p.m_body + x * x / p.jy + y * y / p.jx)
}

/// How far beyond the axles a point load is looked for, m ([`FullHealthMonitor`]'s load
/// search: from `l_r + LOAD_REACH` behind the centre of mass to `l_f + LOAD_REACH` ahead of
/// it, across the wider track, on a grid of [`LOAD_STEP`]).
pub const LOAD_REACH: f64 = 1.0;

/// Spacing of the load search's grid, m.
pub const LOAD_STEP: f64 = 0.1;

/// What a point load's fit must gain over the best single constant's (or the load spread like
/// the body's) weighted residual to be reported as one: the 95 % point of χ² with the 2
/// degrees of freedom its position adds (5.99).
pub const LOAD_PENALTY: f64 = 5.99;

/// The tracked coefficients of the four body-corner equations with their intervals: row `i`
/// (corner `i`'s equation) is `[Θ_0,i, …, Θ_7,i, c_i]` ([`full_coefficients`]: the extension and
/// rate coefficients of corners fl, fr, rl, rr, 1/s² and 1/s, then the offset, m/s²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FullEstimate<T> {
    /// The estimates.
    pub value: [[T; 9]; 4],
    /// Lower ends of the `confidence` intervals.
    pub low: [[T; 9]; 4],
    /// Upper ends.
    pub high: [[T; 9]; 4],
}

/// The suspension health monitor of the full car with realistic sensors (module
/// documentation of [`crate::health`], "The full car"). The settings are the quarter car's
/// [`HealthConfig`], with the full car as the nominal car; each corner's kinematic filter uses
/// the same noise settings. Events name the corner (`"b_fl"`, `"k_rr"`) or the body mass
/// (`"M"`).
///
/// # Examples
/// ```
/// use vehid_core::health::{FullHealthMonitor, HealthConfig, Status};
/// use vehid_core::model::FullCar;
/// let mut mon = FullHealthMonitor::new(HealthConfig::new(0.005, FullCar::<f64>::passenger())).unwrap();
/// let y = [0.1, 0.2, 0.1, 0.0, -0.3, 0.1, 0.2, -0.1, 0.002, -0.001, 0.0, 0.001];
/// assert_eq!(mon.update(&y).unwrap(), None);
/// assert_eq!(mon.status(), Status::Warmup);
/// let mut bad = y;
/// bad[5] = f64::INFINITY;
/// assert!(mon.update(&bad).is_err()); // nothing changed
/// assert_eq!(mon.samples(), 1);
/// ```
///
/// With the feature `serde` it is saved and restored (checked on load, as the half car's
/// monitor: a corrupt input is an error, never a later panic).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct FullHealthMonitor<T: Real> {
    cfg: HealthConfig<T, FullCar<T>>,
    n_warm: u64,
    n_burn: u64,
    n_settle: u64,
    n_reacq: u64,
    // Samples per decision (`DECISION_INTERVAL / dt`, derived from the settings; not saved).
    #[cfg_attr(feature = "serde", serde(skip))]
    n_decide: u64,
    z: T,
    kf: [DeflectionFilter<T>; 4],
    // The state sensors' filter gain with the measured rates (every corner; derived from the
    // settings, also on load; not saved). Unused with the realistic sensors.
    #[cfg_attr(feature = "serde", serde(skip, default = "RateGain::unused"))]
    rate: RateGain<T>,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array2"))]
    ring: [[T; 12]; MAX_DELAY],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    ring_k: [u64; MAX_DELAY],
    head: usize,
    len: usize,
    prev: [T; 12],
    run: [usize; 12],
    have_prev: bool,
    reacq_left: u64,
    k: u64,
    phase: Phase,
    reason: Option<Reason>,
    reference: Rls<T, 9, 4>,
    fast: Rls<T, 9, 4>,
    post: Rls<T, 9, 4>,
    warm_n: u64,
    post_n: u64,
    e2_sum: SMatrix<T, 4, 4>,
    e2_n: u64,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    e1_sum: [T; 4],
    e_prev: Option<SVector<T, 4>>,
    inflate: T,
    sigma: SMatrix<T, 4, 4>,
    theta_ref: SMatrix<T, 9, 4>,
    // The reference's covariance factor (rows and columns 0–7 of its `P`).
    q_ref: SMatrix<T, 8, 8>,
    // Derived from the nominal car, `theta_ref` and `sigma` (by `derive`, also on load; not
    // saved): the patterns `Ũ = Θ_ref ⊙ u` and `Σ⁻¹`.
    #[cfg_attr(feature = "serde", serde(skip, default = "zero_patterns"))]
    patterns: [Pattern<T, 8, 4>; FULL_NAMED_COUNT],
    #[cfg_attr(feature = "serde", serde(skip, default = "SMatrix::zeros"))]
    sigma_inv: SMatrix<T, 4, 4>,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    cap: [T; 9],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array2"))]
    g: [[T; 2]; FULL_NAMED_COUNT],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array2"))]
    zero_k: [[u64; 2]; FULL_NAMED_COUNT],
    onset: u64,
    sensors: SensorGuard<T, 4>,
    belief: [T; FULL_CONSTANTS],
    events: u64,
}

#[cfg(feature = "serde")]
fn zero_patterns<T: Real>() -> [Pattern<T, 8, 4>; FULL_NAMED_COUNT] {
    [Pattern { u: SMatrix::zeros(), row: None, zero: true }; FULL_NAMED_COUNT]
}

impl<T: Real> FullHealthMonitor<T> {
    /// A monitor with settings `cfg`.
    ///
    /// # Errors
    /// As [`super::HealthMonitor::new`]: [`crate::Error::InvalidArgument`] naming the setting.
    pub fn new(cfg: HealthConfig<T, FullCar<T>>) -> Result<Self> {
        let (kf, z) = cfg.check()?;
        let rate = cfg.rate_gain()?;
        let [n_warm, n_burn, n_settle, n_reacq] = cfg.sample_counts();
        let lambda = T::one() - cfg.dt / cfg.window;
        let p0 = SMatrix::<T, 9, 9>::identity() * T::of(1e6);
        let start = Rls::new(SMatrix::zeros(), p0, T::one());
        let rel = full_relative_patterns(&cfg.car);
        Ok(Self {
            n_warm,
            n_burn,
            n_settle,
            n_reacq,
            n_decide: (libm::round(DECISION_INTERVAL / cfg.dt.to_f64()) as u64).max(1),
            z,
            kf: [kf; 4],
            rate,
            ring: [[T::zero(); 12]; MAX_DELAY],
            ring_k: [0; MAX_DELAY],
            head: 0,
            len: 0,
            prev: [T::zero(); 12],
            run: [0; 12],
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
            e2_sum: SMatrix::zeros(),
            e2_n: 0,
            e1_sum: [T::zero(); 4],
            e_prev: None,
            inflate: T::one(),
            sigma: SMatrix::zeros(),
            theta_ref: SMatrix::zeros(),
            q_ref: SMatrix::zeros(),
            patterns: rel.map(Pattern::new),
            sigma_inv: SMatrix::zeros(),
            cap: [T::biggest(); 9],
            g: [[T::zero(); 2]; FULL_NAMED_COUNT],
            zero_k: [[0; 2]; FULL_NAMED_COUNT],
            onset: 0,
            sensors: cfg.sensor_guard(lambda),
            belief: cfg.car.constants(),
            events: 0,
            cfg,
        })
    }

    /// Checks a deserialized monitor (feature `serde`): its settings as
    /// [`FullHealthMonitor::new`] checks them, the delay line's indices, finite statistics
    /// and positive constants.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let fresh = Self::new(self.cfg)?;
        let corrupt =
            crate::Error::InvalidArgument { arg: "state", expected: "a full-car health monitor's saved state" };
        if self.head >= MAX_DELAY || self.len >= self.cfg.stuck_samples {
            return Err(corrupt);
        }
        let limit = self.cfg.stuck_samples;
        self.run.iter_mut().for_each(|r| *r = (*r).min(limit));
        if fresh.n_warm != self.n_warm || fresh.n_burn != self.n_burn || fresh.n_settle != self.n_settle {
            return Err(corrupt);
        }
        let finite = |v: &T| v.to_f64().is_finite();
        let stats = [self.e1_sum[0], self.e1_sum[1], self.e1_sum[2], self.e1_sum[3], self.inflate, self.z];
        if !stats.iter().all(finite)
            || !self.e2_sum.iter().all(finite)
            || !self.sigma.iter().all(finite)
            || !self.theta_ref.iter().all(finite)
            || !self.q_ref.iter().all(finite)
            || !self
                .belief
                .iter()
                .enumerate()
                .all(|(i, v)| finite(v) && (*v > T::zero() || (i >= 23 && *v == T::zero())))
        {
            return Err(corrupt);
        }
        if !self.sensors.is_valid(&fresh.sensors) {
            return Err(corrupt);
        }
        self.n_decide = fresh.n_decide;
        self.rate = fresh.rate;
        self.patterns = fresh.patterns;
        self.derive();
        Ok(())
    }

    /// Sets what is derived from the reference: `Σ⁻¹` and the patterns `Ũ_c = Θ_ref ⊙ u_c` of
    /// the nominal car's relative patterns `u_c` ([`full_relative_patterns`]); a bar's is
    /// `Θ_nom ⊙ u_c`, the nominal car's own derivative: `Θ` is linear in a bar, so that
    /// derivative holds at any value of it, a lost bar's included (the reference's `Θ` would
    /// scale it by what the bar's loss took from its rows). (Zeros while `Σ` is not positive
    /// definite.)
    fn derive(&mut self) {
        let rel = full_relative_patterns(&self.cfg.car);
        let th = self.theta_ref.fixed_view::<8, 4>(0, 0).into_owned();
        let nominal = full_coefficients(&self.cfg.car);
        self.patterns =
            core::array::from_fn(|c| Pattern::new(rel[c].component_mul(if c >= FRONT_BAR { &nominal } else { &th })));
        self.sigma_inv = spd_inverse(&self.sigma).unwrap_or_else(SMatrix::zeros);
    }

    /// The settings.
    pub fn config(&self) -> &HealthConfig<T, FullCar<T>> {
        &self.cfg
    }

    /// What the monitor is doing now.
    pub fn status(&self) -> Status {
        self.phase.status(self.reason)
    }

    /// Samples seen (accepted calls of [`FullHealthMonitor::update`]).
    pub fn samples(&self) -> u64 {
        self.k
    }

    /// Events reported so far.
    pub fn events(&self) -> u64 {
        self.events
    }

    /// The current belief of the car's constants in the order of [`FullCar::CONSTANTS`]: the
    /// nominal car's, moved by every event (a body-mass event moves `M`, `Jx` and `Jy`).
    pub fn constants(&self) -> [T; FULL_CONSTANTS] {
        self.belief
    }

    /// The reference coefficients (rows as in [`FullEstimate`]; `None` during the warm-up).
    pub fn reference(&self) -> Option<[[T; 9]; 4]> {
        (self.phase != Phase::Warmup).then(|| rows(&self.theta_ref))
    }

    /// The CUSUM statistics `[up, down]` of each constant of [`FULL_NAMED`] (threshold
    /// [`HealthConfig::threshold`]), as of the last decision (every [`DECISION_INTERVAL`]).
    pub fn cusum(&self) -> [[T; 2]; FULL_NAMED_COUNT] {
        self.g
    }

    /// The residual covariance `Σ` of the four body-corner equations, (m/s²)²: the warm-up's
    /// once the reference is formed, its running value before.
    pub fn noise_cov(&self) -> [[T; 4]; 4] {
        let m = if self.phase != Phase::Warmup {
            self.sigma
        } else if self.e2_n > 0 {
            self.e2_sum / T::of(self.e2_n as f64)
        } else {
            SMatrix::identity() * T::biggest().sqrt()
        };
        core::array::from_fn(|a| core::array::from_fn(|b| m[(a, b)]))
    }

    /// The tracked coefficients with `confidence` intervals from `f Σ_ii P / (1 + λ)`
    /// (as [`super::HealthMonitor::estimate`], per equation).
    pub fn estimate(&self) -> FullEstimate<T> {
        let s = self.noise_cov();
        let value = rows(self.fast.theta());
        let mut out = FullEstimate { value, low: value, high: value };
        for (o, so) in s.iter().enumerate() {
            let s2 = self.inflate * so[o] / (T::one() + self.fast.lambda());
            for j in 0..9 {
                let half = self.z * (s2 * self.fast.p()[(j, j)]).max(T::zero()).sqrt();
                out.low[o][j] = value[o][j] - half;
                out.high[o][j] = value[o][j] + half;
            }
        }
        out
    }

    /// One sample `y`: the 12 channels of [`FULL_CHANNELS`] (m/s², m) with the realistic
    /// sensors, the 28 of `model::FULL_STATE_CHANNELS` with the state sensors (the monitor
    /// forms the same twelve quantities from them, corner `i` at `(x_i, y_i)`: `dvb + x_i
    /// dpitch_rate + y_i droll_rate`, `dv_i`, `zb + x_i pitch + y_i roll − z_i`, and the
    /// deflection rates `vb + x_i pitch_rate + y_i roll_rate − v_i` for the kinematic filters);
    /// returns the event it completes, if any. A NaN channel marks a missing sample. No
    /// allocation.
    ///
    /// # Errors
    /// [`crate::Error::Shape`] for a length other than the sensor set's channels,
    /// [`crate::Error::NonFinite`] for ±∞; the monitor is then unchanged.
    pub fn update(&mut self, y: &[T]) -> Result<Option<Event<T, FullConstant>>> {
        let missing = screen(y, self.cfg.channels())?;
        match self.cfg.sensors {
            SensorSet::Realistic => {
                let mut v = [T::zero(); 12];
                v.copy_from_slice(y);
                Ok(self.step(missing, v, None))
            }
            SensorSet::State => {
                let (mut v, mut rates) = ([T::zero(); 12], [T::zero(); 4]);
                let d = FULL_STATE_CHANNELS / 2;
                for (i, r) in rates.iter_mut().enumerate() {
                    let (xi, yi) = self.cfg.car.corner_position(i);
                    v[i] = y[d + 9] + xi * y[d + 11] + yi * y[d + 13];
                    v[4 + i] = y[d + 2 * i + 1];
                    v[8 + i] = y[8] + xi * y[10] + yi * y[12] - y[2 * i];
                    *r = y[9] + xi * y[11] + yi * y[13] - y[2 * i + 1];
                }
                Ok(self.step(missing, v, Some(rates)))
            }
        }
    }

    /// [`FullHealthMonitor::update`] after the screening: the twelve quantities `y`, `rates`
    /// the measured deflection rates (state sensors), `missing` a NaN channel.
    #[inline(always)]
    fn step(&mut self, missing: bool, y: [T; 12], rates: Option<[T; 4]>) -> Option<Event<T, FullConstant>> {
        let k = self.k;
        self.k += 1;
        if missing {
            self.have_prev = false;
            self.run = [0; 12];
            self.interrupt(Reason::Missing);
            return None;
        }
        let stuck = stuck_step(&mut self.prev, &mut self.run, self.have_prev, &y, self.cfg.stuck_samples);
        self.have_prev = true;
        if stuck {
            self.interrupt(Reason::Stuck);
            return None;
        }
        let gate = if self.reacq_left > 0 { T::biggest() } else { T::of(JUMP_GATE) };
        // A jump on any corner restarts every corner's filter (`interrupt`).
        let rel: [T; 4] = core::array::from_fn(|i| y[i] - y[4 + i]);
        let mut kf = self.kf;
        let mut dv = [(T::zero(), T::zero()); 4];
        for i in 0..4 {
            let step = match rates {
                None => kf[i].update_gated(y[8 + i], rel[i], gate),
                Some(r) => kf[i].update_rate_gated(y[8 + i], r[i], rel[i], &self.rate, gate),
            };
            match step {
                Some(s) => dv[i] = s,
                None => {
                    self.interrupt(Reason::Jump);
                    return None;
                }
            }
        }
        self.kf = kf;
        if self.sensors.observe(k, core::array::from_fn(|i| (y[8 + i], rel[i])), self.phase == Phase::Warmup) {
            // A burst of a kinematic check (a step of the accelerations): a jump.
            self.interrupt(Reason::Jump);
            return None;
        }
        if self.reacq_left > 0 {
            self.reacq_left -= 1;
            self.reason = Some(Reason::Reacquiring);
            return None;
        }
        if matches!(self.reason, Some(Reason::Missing | Reason::Stuck | Reason::Jump | Reason::Reacquiring)) {
            self.reason = None;
        }
        let at = (self.head + self.len) % MAX_DELAY;
        let mut row = [T::zero(); 12];
        for i in 0..4 {
            row[2 * i] = dv[i].0;
            row[2 * i + 1] = dv[i].1;
            row[8 + i] = y[i];
        }
        self.ring[at] = row;
        self.ring_k[at] = k;
        self.len += 1;
        if self.len < self.cfg.stuck_samples {
            return None;
        }
        let row = self.ring[self.head];
        let kr = self.ring_k[self.head];
        self.head = (self.head + 1) % MAX_DELAY;
        self.len -= 1;
        self.feed(kr, row)
    }

    /// Drops the held-back samples and restarts the kinematic filters; the offsets `c` of
    /// every tracker are released, as the half car's monitor does.
    fn interrupt(&mut self, reason: Reason) {
        self.len = 0;
        self.kf.iter_mut().for_each(|f| f.reset());
        self.sensors.restart();
        let q = T::of(OFFSET_RELEASE);
        self.reference.release(8, q);
        self.fast.release(8, q);
        self.post.release(8, q);
        self.reacq_left = self.n_reacq;
        self.reason = Some(reason);
    }

    /// Uses one regression row `a_i = Σ_j (Θ_2j,i (−d_j) + Θ_2j+1,i (−ḋ_j)) + c_i` of sample `kr`.
    fn feed(&mut self, kr: u64, row: [T; 12]) -> Option<Event<T, FullConstant>> {
        let phi = SVector::<T, 9>::from_fn(|r, _| if r < 8 { -row[r] } else { T::one() });
        let y = SVector::<T, 4>::new(row[8], row[9], row[10], row[11]);
        self.fast.release(8, T::of(OFFSET_WALK));
        if self.phase != Phase::Warmup && self.sensors.holds() {
            // The sensors disagree (as in the quarter car's monitor): track, judge nothing.
            self.fast.update_all(&phi, &y);
            self.phase = Phase::Monitoring;
            self.g = [[T::zero(); 2]; FULL_NAMED_COUNT];
            self.reason = Some(Reason::Sensors);
            return None;
        }
        match self.phase {
            Phase::Warmup => {
                let e = self.reference.update_all(&phi, &y);
                self.fast.update_all(&phi, &y);
                self.warm_n += 1;
                if let (Some(e), true) = (e, self.warm_n > self.n_burn) {
                    self.e2_sum += e * e.transpose();
                    self.e2_n += 1;
                    if let Some(prev) = self.e_prev {
                        for o in 0..4 {
                            self.e1_sum[o] += e[o] * prev[o];
                        }
                    }
                    self.e_prev = Some(e);
                }
                if self.warm_n >= self.n_warm && self.e2_n > 0 {
                    // The four equations hold three rigid-body accelerations: with noise-free
                    // accelerations one combination's residual is zero and Σ singular; the
                    // floor keeps the weights finite.
                    let floor = T::of(MIN_ACCEL_NOISE * MIN_ACCEL_NOISE);
                    let sigma = self.e2_sum / T::of(self.e2_n as f64) + SMatrix::<T, 4, 4>::identity() * floor;
                    let mut rho = T::zero();
                    for o in 0..4 {
                        rho = rho.max(self.e1_sum[o] / self.e2_sum[(o, o)]);
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
                self.post.release(8, T::of(OFFSET_WALK));
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

/// `Θ` (`9 × 4`, a column per equation) as rows per equation.
fn rows<T: Real>(theta: &SMatrix<T, 9, 4>) -> [[T; 9]; 4] {
    core::array::from_fn(|o| core::array::from_fn(|j| theta[(j, o)]))
}

/// The fits' type, for `detect.rs`.
type Fits<T> = [Fit<T>; FULL_NAMED_COUNT];

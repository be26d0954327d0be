//! Realistic drives of the full car: the half car's drive (`half_drive.rs`) with a left and a
//! right track, changes per corner, and the sensors at the four corners.
//!
//! **Car.** The [`FullCar`] (state `[z_fl, v_fl, z_fr, v_fr, z_rl, v_rl, z_rr, v_rr, zb, vb, θ,
//! θ̇, φ, φ̇]`, deviations from the static equilibrium of the initial constants), inputs the
//! road under each wheel in the order `fl, fr, rl, rr`.
//!
//! **Road.** The front wheels roll on two parallel ISO 8608 tracks `track_f` apart with the
//! isotropic-road coherence of `two_track.rs` ([`TwoTrackRoad`]); each rear wheel follows its
//! front wheel's track (same path) `L = l_f + l_r` metres later, read from a ring of past
//! heights by linear interpolation exactly as the half car's rear wheel is
//! (`half_drive.rs`: points at least `L/256` apart, the road rolled out over the first `L`
//! metres before the first sample). Each wheel's road is linear in time over a sample
//! interval and the state is advanced exactly for it: `x(k+1) = Φ x(k) + Γ [u, u̇, 1]ᵀ` from
//! the exponential of the augmented matrix (state `[x, u (4), u̇ (4), 1]`, 23 × 23), rebuilt
//! at a change.
//!
//! **Gravity.** With `gravity` on (the default) the static preloads stay those of the
//! initial car: with `q0` its static equilibrium under gravity ([`FullCar::static_equilibrium`],
//! positions from the unloaded springs) the accelerations gain the constant `f = A q0 + g_v`
//! (`g_v = −g` in the four wheel rows and the heave row), zero before any change; a heavier
//! body sinks, a softer spring lets its corner down (and the body rolls and pitches toward it).
//!
//! **Changes.** [`FullChange`]: at time `t` a constant named as in [`FullCar::CONSTANTS`]
//! (`"M"`, `"Jx"`, `"Jy"`, `"kt_fl"`, …, `"k_rr"`, `"b_fl"`, …, `"m_rr"`, `"arb_f"`, `"arb_r"`;
//! not the geometry) becomes `value`, by a step or a linear ramp, with the timing rules of the
//! quarter car's [`super::Change`]. A load spread like the body's own mass is `M`, `Jx`, `Jy`
//! changed at the same `t`.
//!
//! **Loads.** [`FullLoad`]: a point mass `m` set down on the body at `(x, y)` (m from the
//! initial centre of mass, `x` forward, `y` to the left: the frame of
//! [`FullCar::corner_position`]) at time `t`, at once or over a ramp. A point of the body at
//! `(x, y)` moves by `v · q`, `v = [1, x, y]`, `q = [z_b, θ, φ]`, so the load adds `m v vᵀ` to the
//! body's mass matrix `M_b = diag(M, Jy, Jx)` and `−m g v` to its generalized forces (with
//! `gravity`). The body's three acceleration rows of `A` (and of the gravity term) become
//! `(M_b + m v vᵀ)⁻¹ M_b` times the unloaded ones, plus `−(M_b + m v vᵀ)⁻¹ m g v`: exact, in the
//! coordinates of the unloaded car (its centre of mass moves by `m (x, y) / (M + m)`; the
//! corners' sensors stay where they are). The sample's constants show `M + m`,
//! `Jx + m y²`, `Jy + m x²` (about the initial centre of mass).
//!
//! **Sensors.** [`SensorSet::State`]: the measured state and derivative (28 channels,
//! [`FULL_STATE_CHANNELS`], white noise [`SensorNoise::state`], [`SensorNoise::deriv`]).
//! [`SensorSet::Realistic`]: [`FULL_REALISTIC_CHANNELS`]: a body accelerometer above each
//! wheel (`z̈b + x_i θ̈ + y_i φ̈`), a wheel accelerometer per corner and each corner's
//! suspension extension, with the quarter car's noise defaults
//! ([`SensorNoise`](crate::model::SensorNoise): body accelerometers `a_body` white and
//! `a_body_bias` constant, wheel accelerometers `a_wheel`, `a_wheel_bias`, deflection sensors
//! `deflection`; the eight biases drawn once per seed).

use super::drive::{DriveConfig, GRAVITY, MAX_CHANGES};
use super::half_drive::RoadHistory;
use super::streams;
use super::two_track::TwoTrackRoad;
use crate::error::{check_finite, check_nonneg, check_positive};
use crate::linalg::expm_with_integral;
use crate::model::{
    FullCar, SensorNoise, SensorSet, FULL_CONSTANTS, FULL_REALISTIC_CHANNELS, FULL_STATES, FULL_STATE_CHANNELS,
};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};
use rand::rngs::Xoshiro256PlusPlus;
use rand_distr::{Distribution, StandardNormal};

/// Most sensor channels of a full-car sample (the state set's 28).
pub const FULL_MAX_CHANNELS: usize = 28;

/// Size of the augmented state `[x, u, u̇, 1]`.
const AUG: usize = FULL_STATES + 9;

/// A full-car constant a [`FullChange`] can name: its index in [`FullCar::CONSTANTS`] (the
/// body's `M`, `Jx`, `Jy`, every corner constant and the anti-roll bars; not the geometry).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FullConstant(u8);

impl FullConstant {
    /// The constant at position `i` of [`FullCar::CONSTANTS`] (`i < 25`; the callers are
    /// this crate's tables, e.g. `health::FULL_NAMED`).
    pub(crate) const fn at(i: u8) -> Self {
        assert!((i as usize) < FULL_CONSTANTS);
        Self(i)
    }

    /// The constant's position in [`FullCar::constants`].
    pub fn index(&self) -> usize {
        self.0 as usize
    }

    /// Its name (as in [`FullCar::CONSTANTS`]).
    pub fn as_str(&self) -> &'static str {
        FullCar::<f64>::CONSTANTS[self.index()]
    }

    /// Whether constant `i` of [`FullCar::CONSTANTS`] can change during a drive.
    fn changeable(i: usize) -> bool {
        !(19..23).contains(&i)
    }
}

impl core::fmt::Display for FullConstant {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Saved by name (`"b_fl"`), read back through [`core::str::FromStr`] (an unknown name is an
/// error, never a later panic).
#[cfg(feature = "serde")]
impl serde::Serialize for FullConstant {
    fn serialize<S: serde::Serializer>(&self, s: S) -> core::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for FullConstant {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> core::result::Result<Self, D::Error> {
        struct Name;
        impl serde::de::Visitor<'_> for Name {
            type Value = FullConstant;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str("a full-car constant's name")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> core::result::Result<FullConstant, E> {
                v.parse().map_err(|_| E::custom("an unknown full-car constant"))
            }
        }
        d.deserialize_str(Name)
    }
}

impl core::str::FromStr for FullConstant {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match FullCar::<f64>::CONSTANTS.iter().position(|n| *n == s) {
            Some(i) if Self::changeable(i) => Ok(Self(i as u8)),
            _ => Err(Error::UnknownOption {
                arg: "constant",
                expected:
                    "one of \"M\", \"Jx\", \"Jy\", \"kt_fl\" … \"kt_rr\", \"k_fl\" … \"k_rr\", \"b_fl\" … \"b_rr\", \
                           \"m_fl\" … \"m_rr\", \"arb_f\", \"arb_r\" (corners fl, fr, rl, rr; the geometry does not \
                           change)",
            }),
        }
    }
}

/// A change of one full-car constant during a drive: a step at `t` or a linear ramp over
/// `ramp` seconds starting at `t` (module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FullChange<T> {
    /// Start time, s (≥ 0).
    pub t: T,
    /// The constant changed.
    pub constant: FullConstant,
    /// Its value at the end of the change, in the constant's unit (> 0; ≥ 0 for a bar).
    pub value: T,
    /// Ramp duration, s (0 for a step).
    pub ramp: T,
}

impl<T: Real> FullChange<T> {
    /// A step of the constant named `name` to `value` at `t` s.
    ///
    /// # Errors
    /// [`Error::UnknownOption`] for a name not in [`FullCar::CONSTANTS`] or a geometry
    /// constant; [`Error::InvalidArgument`] for a `t` not finite and ≥ 0 or a `value` not
    /// finite and > 0 (≥ 0 for an anti-roll bar).
    pub fn step(t: T, name: &str, value: T) -> Result<Self> {
        Self::ramp(t, name, value, T::zero())
    }

    /// A linear ramp of the constant named `name` from its value at `t` to `value` at
    /// `t + ramp` seconds.
    ///
    /// # Errors
    /// As [`FullChange::step`], and [`Error::InvalidArgument`] for a `ramp` not finite and ≥ 0.
    pub fn ramp(t: T, name: &str, value: T, ramp: T) -> Result<Self> {
        let constant: FullConstant = name.parse()?;
        let c = Self { t, constant, value, ramp };
        c.validate()?;
        Ok(c)
    }

    fn validate(&self) -> Result<()> {
        check_nonneg("changes.t", self.t)?;
        if self.constant.as_str().starts_with("arb") {
            check_nonneg("changes.value", self.value)?;
        } else {
            check_positive("changes.value", self.value)?;
        }
        check_nonneg("changes.ramp", self.ramp)
    }
}

/// Most loads of a [`FullDriveConfig`].
pub const MAX_LOADS: usize = 4;

/// A point mass set down on the body during a drive (module documentation, "Loads"): `mass`
/// kg at `(x, y)` m from the initial centre of mass (`x` forward, `y` to the left), from `t` s,
/// its mass growing linearly over `ramp` s (0: at once).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FullLoad<T> {
    /// Start time, s (≥ 0).
    pub t: T,
    /// Mass, kg (> 0).
    pub mass: T,
    /// Position forward of the initial centre of mass, m.
    pub x: T,
    /// Position to the left of the initial centre of mass, m.
    pub y: T,
    /// Ramp duration, s (0 for a load set down at once).
    pub ramp: T,
}

impl<T: Real> FullLoad<T> {
    /// `mass` kg set down at `(x, y)` at `t` s.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a `t` not finite and ≥ 0 or a `mass` not finite and > 0;
    /// [`Error::NonFinite`] for an `x` or `y` not finite.
    pub fn at(t: T, mass: T, x: T, y: T) -> Result<Self> {
        Self::ramp(t, mass, x, y, T::zero())
    }

    /// As [`FullLoad::at`], the mass growing linearly from 0 at `t` to `mass` at `t + ramp`.
    ///
    /// # Errors
    /// As [`FullLoad::at`], and [`Error::InvalidArgument`] for a `ramp` not finite and ≥ 0.
    pub fn ramp(t: T, mass: T, x: T, y: T, ramp: T) -> Result<Self> {
        let l = Self { t, mass, x, y, ramp };
        l.validate()?;
        Ok(l)
    }

    fn validate(&self) -> Result<()> {
        check_nonneg("load.t", self.t)?;
        check_positive("load.mass", self.mass)?;
        check_finite("load.x", &[self.x])?;
        check_finite("load.y", &[self.y])?;
        check_nonneg("load.ramp", self.ramp)
    }

    /// The mass in place at time `t`, kg.
    fn mass_at(&self, t: f64) -> f64 {
        let (t0, ramp, m) = (self.t.to_f64(), self.ramp.to_f64(), self.mass.to_f64());
        if t < t0 {
            0.0
        } else if ramp > 0.0 && t < t0 + ramp {
            m * ((t - t0) / ramp)
        } else {
            m
        }
    }
}

/// Settings of a full-car drive: the quarter car's [`DriveConfig`] (interval, road, speed,
/// sensors, noise, gravity; it must hold no quarter-car change), the full car's changes and
/// its loads.
#[derive(Debug, Clone, PartialEq)]
pub struct FullDriveConfig<T> {
    /// Everything but the changes.
    pub base: DriveConfig<T>,
    changes: [Option<FullChange<T>>; MAX_CHANGES],
    loads: [Option<FullLoad<T>>; MAX_LOADS],
}

impl<T: Real> FullDriveConfig<T> {
    /// The settings of `base`, no change.
    pub fn new(base: DriveConfig<T>) -> Self {
        Self { base, changes: [None; MAX_CHANGES], loads: [None; MAX_LOADS] }
    }

    /// Adds a load.
    ///
    /// # Errors
    /// [`Error::Capacity`] beyond [`MAX_LOADS`]; the checks of [`FullLoad::at`].
    pub fn with_load(mut self, load: FullLoad<T>) -> Result<Self> {
        load.validate()?;
        match self.loads.iter_mut().find(|c| c.is_none()) {
            Some(slot) => *slot = Some(load),
            None => return Err(Error::Capacity { arg: "loads", needed: MAX_LOADS + 1, capacity: MAX_LOADS }),
        }
        Ok(self)
    }

    /// The loads configured.
    pub fn loads(&self) -> impl Iterator<Item = &FullLoad<T>> {
        self.loads.iter().flatten()
    }

    /// Adds a parameter change.
    ///
    /// # Errors
    /// [`Error::Capacity`] beyond [`MAX_CHANGES`]; the checks of [`FullChange::step`].
    pub fn with_change(mut self, change: FullChange<T>) -> Result<Self> {
        change.validate()?;
        match self.changes.iter_mut().find(|c| c.is_none()) {
            Some(slot) => *slot = Some(change),
            None => return Err(Error::Capacity { arg: "changes", needed: MAX_CHANGES + 1, capacity: MAX_CHANGES }),
        }
        Ok(self)
    }

    /// The changes configured.
    pub fn changes(&self) -> impl Iterator<Item = &FullChange<T>> {
        self.changes.iter().flatten()
    }

    fn validate(&self) -> Result<()> {
        let b = &self.base;
        check_positive("dt", b.dt)?;
        check_positive("cutoff", b.cutoff)?;
        check_nonneg("speed", b.speed)?;
        b.noise.validate()?;
        if b.changes().next().is_some() {
            return Err(Error::InvalidArgument {
                arg: "base",
                expected: "a drive configuration without quarter-car changes (add FullChange values instead)",
            });
        }
        for c in self.changes() {
            c.validate()?;
        }
        for l in self.loads() {
            l.validate()?;
        }
        Ok(())
    }
}

/// One sample of a full-car drive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FullDriveSample<T: Real> {
    /// Sample index `k`.
    pub k: u64,
    /// Time `k·dt`, s.
    pub t: T,
    /// Distance the rear axle travelled before this sample, m (the front axle is `L` ahead).
    pub s: T,
    /// Speed over the interval after this sample, m/s.
    pub speed: T,
    /// True state (module documentation), m, m/s, rad, rad/s.
    pub x: SVector<T, FULL_STATES>,
    /// True derivative.
    pub xdot: SVector<T, FULL_STATES>,
    /// Road height under each wheel `[fl, fr, rl, rr]`, m.
    pub u: [T; 4],
    /// The constants in effect, in the order of [`FullCar::CONSTANTS`].
    pub constants: [T; FULL_CONSTANTS],
    y: [T; FULL_MAX_CHANNELS],
    len: usize,
}

impl<T: Real> FullDriveSample<T> {
    /// The sensor channels (names: [`FullDrive::channels`]).
    pub fn y(&self) -> &[T] {
        &self.y[..self.len]
    }
}

/// A streaming full-car drive: one [`FullDriveSample`] per call, no allocation (module
/// documentation).
///
/// # Examples
/// ```
/// use vehid_core::model::FullCar;
/// use vehid_core::sim::{DriveConfig, FullChange, FullDrive, FullDriveConfig};
/// let cfg = FullDriveConfig::new(DriveConfig::new(0.005))
///     .with_change(FullChange::step(60.0, "b_fl", 900.0).unwrap())
///     .unwrap();
/// let mut drive = FullDrive::new(FullCar::<f64>::passenger(), cfg, 1).unwrap();
/// assert_eq!(drive.channels()[0], "a_body_fl");
/// assert_eq!(drive.next_sample().y().len(), 12);
/// ```
#[derive(Debug, Clone)]
pub struct FullDrive<T: Real> {
    cfg: FullDriveConfig<T>,
    dt: f64,
    c: [f64; FULL_CONSTANTS],
    start: [f64; MAX_CHANGES],
    /// Each load's mass in place, kg.
    load: [f64; MAX_LOADS],
    /// Static equilibrium of the initial car (positions; velocities zero).
    q0: SVector<f64, FULL_STATES>,
    a: SMatrix<f64, FULL_STATES, FULL_STATES>,
    b: SMatrix<f64, FULL_STATES, 4>,
    f: SVector<f64, FULL_STATES>,
    phi: SMatrix<f64, FULL_STATES, FULL_STATES>,
    gamma: SMatrix<f64, FULL_STATES, 9>,
    x: SVector<f64, FULL_STATES>,
    u: [f64; 4],
    bias: [f64; 8],
    road: TwoTrackRoad,
    hist: [RoadHistory; 2],
    wheelbase: f64,
    s: f64,
    k: u64,
    rng_w: Xoshiro256PlusPlus,
    rng_v: Xoshiro256PlusPlus,
}

impl<T: Real> FullDrive<T> {
    /// A drive of `car` (its initial constants) with settings `cfg`; `seed` fixes the road,
    /// the biases and the noise. The car starts at rest in its static equilibrium on the
    /// road under its four wheels.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the setting: `dt`, `cutoff` not finite and > 0,
    /// `speed` or a noise level not finite and ≥ 0, a change's time, value or ramp, a `base`
    /// holding quarter-car changes, a `track` too wide for the road's coherence model.
    pub fn new(car: FullCar<T>, cfg: FullDriveConfig<T>, seed: u64) -> Result<Self> {
        cfg.validate()?;
        let b = &cfg.base;
        let dt = b.dt.to_f64();
        let c = car.constants().map(|v| v.to_f64());
        let car64 = FullCar::<f64>::from_constants(c)?;
        let [mut rng_bias, rng_road, rng_w, rng_v] = streams(seed);
        let mut road = TwoTrackRoad::new(b.road, b.cutoff.to_f64(), c[21], rng_road)?;
        let mut bias = [0.0; 8];
        if b.sensors == SensorSet::Realistic {
            let n = &b.noise;
            for (i, bi) in bias.iter_mut().enumerate() {
                let sd = if i < 4 { n.a_body_bias } else { n.a_wheel_bias };
                let e: f64 = StandardNormal.sample(&mut rng_bias);
                *bi = e * sd.to_f64();
            }
        }
        let q = car64.static_equilibrium(GRAVITY)?;
        let mut q0 = SVector::<f64, FULL_STATES>::zeros();
        for (j, v) in q.iter().enumerate() {
            q0[2 * j] = *v;
        }
        // Roll the tracks out over the first wheelbase: the rear wheels start at 0, the front at L.
        let wheelbase = car64.wheelbase();
        let spacing = wheelbase / 256.0;
        let mut hist = [RoadHistory::new(spacing), RoadHistory::new(spacing)];
        let v = b.speed.to_f64();
        let step0 = if v > 0.0 { (v * dt).min(spacing) } else { spacing };
        let n0 = libm::ceil(wheelbase / step0).max(1.0) as usize;
        let push = |hist: &mut [RoadHistory; 2], s: f64, h: [f64; 2]| {
            for (r, z) in hist.iter_mut().zip(h) {
                r.push(s, z);
            }
        };
        push(&mut hist, 0.0, road.heights());
        for r in hist.iter_mut() {
            r.spacing = 0.0;
        }
        for i in 1..=n0 {
            road.advance(wheelbase / n0 as f64);
            push(&mut hist, wheelbase * i as f64 / n0 as f64, road.heights());
        }
        for r in hist.iter_mut() {
            r.spacing = spacing;
        }
        let [fl, fr] = road.heights();
        let u = [fl, fr, hist[0].height(0.0), hist[1].height(0.0)];
        let mut d = Self {
            cfg,
            dt,
            c,
            start: [f64::NAN; MAX_CHANGES],
            load: [0.0; MAX_LOADS],
            q0,
            a: SMatrix::zeros(),
            b: SMatrix::zeros(),
            f: SVector::zeros(),
            phi: SMatrix::zeros(),
            gamma: SMatrix::zeros(),
            x: SVector::zeros(),
            u,
            bias,
            road,
            hist,
            wheelbase,
            s: wheelbase,
            k: 0,
            rng_w,
            rng_v,
        };
        d.rebuild()?;
        d.x = d.rest_on(u)?;
        Ok(d)
    }

    /// The static state on road heights `u`: `A x + B u = 0` with zero velocities.
    fn rest_on(&self, u: [f64; 4]) -> Result<SVector<f64, FULL_STATES>> {
        let mut k = SMatrix::<f64, 7, 7>::zeros();
        let mut rhs = SVector::<f64, 7>::zeros();
        for r in 0..7 {
            for c in 0..7 {
                k[(r, c)] = self.a[(2 * r + 1, 2 * c)];
            }
            rhs[r] = -(0..4).map(|j| self.b[(2 * r + 1, j)] * u[j]).sum::<f64>();
        }
        let q = k.lu().solve(&rhs).ok_or(Error::Singular { what: "the full car's stiffness matrix" })?;
        let mut x = SVector::zeros();
        for (j, v) in q.iter().enumerate() {
            x[2 * j] = *v;
        }
        Ok(x)
    }

    /// The sensor channel names of every sample.
    pub fn channels(&self) -> &'static [&'static str] {
        self.cfg.base.sensors.full_channels()
    }

    /// The configuration.
    pub fn config(&self) -> &FullDriveConfig<T> {
        &self.cfg
    }

    /// The accelerometer biases drawn for this seed, m/s²: body `fl, fr, rl, rr`, then
    /// wheel `fl, fr, rl, rr` (zero for the state set).
    pub fn biases(&self) -> [T; 8] {
        self.bias.map(T::of)
    }

    /// The constants in effect, in the order of [`FullCar::CONSTANTS`] (with the loads in
    /// place: module documentation, "Loads").
    pub fn constants(&self) -> [T; FULL_CONSTANTS] {
        self.loaded_constants().map(T::of)
    }

    /// The car's constants with the loads in place: `M + Σ m`, `Jx + Σ m y²`, `Jy + Σ m x²`.
    fn loaded_constants(&self) -> [f64; FULL_CONSTANTS] {
        let mut c = self.c;
        for (l, &m) in self.cfg.loads.iter().zip(&self.load) {
            if let Some(l) = l {
                let (x, y) = (l.x.to_f64(), l.y.to_f64());
                c[0] += m;
                c[1] += m * y * y;
                c[2] += m * x * x;
            }
        }
        c
    }

    /// The road's two tracks (for their coherence model).
    pub fn road(&self) -> &TwoTrackRoad {
        &self.road
    }

    /// Drives on onto a road of class `road` (from the current heights).
    pub fn set_road(&mut self, road: super::RoadClass) {
        self.cfg.base.road = road;
        self.road.set_class(road);
    }

    /// Index of the next sample.
    pub fn k(&self) -> u64 {
        self.k
    }

    /// Rebuilds `A`, `B`, the gravity terms and the exact transition `Φ, Γ`.
    fn rebuild(&mut self) -> Result<()> {
        let car = FullCar::from_constants(self.c)?;
        let model = car.model();
        let (mut a, mut bm) = (*model.a(), *model.b());
        let mut f = SVector::<f64, FULL_STATES>::zeros();
        if self.cfg.base.gravity {
            f = a * self.q0;
            for r in [1usize, 3, 5, 7, 9] {
                f[r] -= GRAVITY;
            }
        }
        if self.load.iter().any(|&m| m > 0.0) {
            // The body's rows: (M_b + Σ m v vᵀ)⁻¹ M_b times the unloaded ones, and the loads'
            // weight (module documentation, "Loads").
            let p = car.params();
            let mb = SMatrix::<f64, 3, 3>::from_diagonal(&SVector::from([p.m_body, p.jy, p.jx]));
            let (mut ml, mut w) = (mb, SVector::<f64, 3>::zeros());
            for (l, &m) in self.cfg.loads.iter().zip(&self.load) {
                if let Some(l) = l {
                    let v = SVector::<f64, 3>::from([1.0, l.x.to_f64(), l.y.to_f64()]);
                    ml += v * v.transpose() * m;
                    w -= v * (m * GRAVITY);
                }
            }
            let inv = ml.try_inverse().ok_or(Error::Singular { what: "the loaded body's mass matrix" })?;
            let t = inv * mb;
            const BODY: [usize; 3] = [9, 11, 13];
            let rows = |m: &SMatrix<f64, FULL_STATES, FULL_STATES>| {
                SMatrix::<f64, 3, FULL_STATES>::from_fn(|i, j| m[(BODY[i], j)])
            };
            let ab = t * rows(&a);
            let bb = t * SMatrix::<f64, 3, 4>::from_fn(|i, j| bm[(BODY[i], j)]);
            let fb = t * SVector::<f64, 3>::from_fn(|i, _| f[BODY[i]])
                + if self.cfg.base.gravity { inv * w } else { SVector::zeros() };
            for (i, &r) in BODY.iter().enumerate() {
                for j in 0..FULL_STATES {
                    a[(r, j)] = ab[(i, j)];
                }
                for j in 0..4 {
                    bm[(r, j)] = bb[(i, j)];
                }
                f[r] = fb[i];
            }
        }
        // Augmented state [x, u (4), u̇ (4), 1]: each wheel's road linear over the interval.
        let mut aug = SMatrix::<f64, AUG, AUG>::zeros();
        aug.fixed_view_mut::<FULL_STATES, FULL_STATES>(0, 0).copy_from(&a);
        aug.fixed_view_mut::<FULL_STATES, 4>(0, FULL_STATES).copy_from(&bm);
        aug.fixed_view_mut::<FULL_STATES, 1>(0, AUG - 1).copy_from(&f);
        for j in 0..4 {
            aug[(FULL_STATES + j, FULL_STATES + 4 + j)] = 1.0;
        }
        let (e, _) = expm_with_integral(&aug, self.dt);
        let phi: SMatrix<f64, FULL_STATES, FULL_STATES> = e.fixed_view::<FULL_STATES, FULL_STATES>(0, 0).into_owned();
        let gamma: SMatrix<f64, FULL_STATES, 9> = e.fixed_view::<FULL_STATES, 9>(0, FULL_STATES).into_owned();
        if phi.iter().chain(gamma.iter()).any(|v| !v.is_finite()) {
            return Err(Error::InvalidArgument {
                arg: "dt",
                expected: "a sample interval short enough for the car that e^{A dt} stays finite",
            });
        }
        (self.a, self.b, self.f, self.phi, self.gamma) = (a, bm, f, phi, gamma);
        Ok(())
    }

    /// Applies the changes and loads due at time `t`; `true` when a constant or a load moved.
    fn apply_changes(&mut self, t: f64) -> bool {
        let mut moved = false;
        for (l, m) in self.cfg.loads.iter().zip(self.load.iter_mut()) {
            if let Some(l) = l {
                let now = l.mass_at(t);
                if now != *m {
                    *m = now;
                    moved = true;
                }
            }
        }
        for (i, ch) in self.cfg.changes.iter().enumerate() {
            let Some(ch) = ch else { continue };
            let t0 = ch.t.to_f64();
            if t < t0 {
                continue;
            }
            let j = ch.constant.index();
            if self.start[i].is_nan() {
                self.start[i] = self.c[j];
            }
            let target = ch.value.to_f64();
            let ramp = ch.ramp.to_f64();
            let v = if ramp > 0.0 && t < t0 + ramp {
                self.start[i] + (target - self.start[i]) * ((t - t0) / ramp)
            } else {
                target
            };
            if v != self.c[j] {
                self.c[j] = v;
                moved = true;
            }
        }
        moved
    }

    /// Produces sample `k` at the configured speed and advances to `k + 1`.
    pub fn next_sample(&mut self) -> FullDriveSample<T> {
        let v = self.cfg.base.speed.to_f64();
        self.step(v)
    }

    /// Produces sample `k`, then drives on at `speed` m/s for one interval.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a speed not finite and ≥ 0 (the drive is unchanged).
    pub fn next_sample_at(&mut self, speed: T) -> Result<FullDriveSample<T>> {
        check_nonneg("speed", speed)?;
        Ok(self.step(speed.to_f64()))
    }

    /// The realistic channels of a state and derivative (before noise and bias).
    fn realistic(&self, x: &SVector<f64, FULL_STATES>, xdot: &SVector<f64, FULL_STATES>) -> [f64; 12] {
        let half = 0.5;
        let (lf, lr, tf, tr) = (self.c[19], self.c[20], self.c[21], self.c[22]);
        let mut out = [0.0; 12];
        for i in 0..4 {
            let px = if i < 2 { lf } else { -lr };
            let w = if i < 2 { tf } else { tr } * half;
            let py = if i % 2 == 0 { w } else { -w };
            out[i] = xdot[9] + px * xdot[11] + py * xdot[13];
            out[4 + i] = xdot[2 * i + 1];
            out[8 + i] = x[8] + px * x[10] + py * x[12] - x[2 * i];
        }
        out
    }

    #[inline]
    fn step(&mut self, v: f64) -> FullDriveSample<T> {
        let t = self.k as f64 * self.dt;
        if self.apply_changes(t) {
            // Constants validated, dt > 0: keep the old transition if the new one failed.
            let _ = self.rebuild();
        }
        let u = self.u;
        let x = self.x;
        let xdot = self.a * x + self.b * SVector::<f64, 4>::from(u) + self.f;
        let mut y = [T::zero(); FULL_MAX_CHANNELS];
        let len = match self.cfg.base.sensors {
            SensorSet::Realistic => {
                let n: &SensorNoise<T> = &self.cfg.base.noise;
                let (sb, sw, sd) = (n.a_body.to_f64(), n.a_wheel.to_f64(), n.deflection.to_f64());
                let clean = self.realistic(&x, &xdot);
                for (i, yi) in y.iter_mut().take(12).enumerate() {
                    let (sdev, bias) = match i {
                        0..=3 => (sb, self.bias[i]),
                        4..=7 => (sw, self.bias[i]),
                        _ => (sd, 0.0),
                    };
                    *yi = T::of(clean[i] + bias + sdev * gauss(&mut self.rng_w));
                }
                FULL_REALISTIC_CHANNELS.len()
            }
            SensorSet::State => {
                let (sw, sv) = (self.cfg.base.noise.state.to_f64(), self.cfg.base.noise.deriv.to_f64());
                for i in 0..FULL_STATES {
                    y[i] = T::of(x[i] + sw * gauss(&mut self.rng_w));
                }
                for i in 0..FULL_STATES {
                    y[FULL_STATES + i] = T::of(xdot[i] + sv * gauss(&mut self.rng_v));
                }
                FULL_STATE_CHANNELS.len()
            }
        };
        let out = FullDriveSample {
            k: self.k,
            t: T::of(t),
            s: T::of(self.s - self.wheelbase),
            speed: T::of(v),
            x: x.map(T::of),
            xdot: xdot.map(T::of),
            u: u.map(T::of),
            constants: self.loaded_constants().map(T::of),
            y,
            len,
        };
        let ds = v * self.dt;
        self.road.advance(ds);
        self.s += ds;
        let [nfl, nfr] = self.road.heights();
        self.hist[0].push(self.s, nfl);
        self.hist[1].push(self.s, nfr);
        let rear = self.s - self.wheelbase;
        let next = [nfl, nfr, self.hist[0].height(rear), self.hist[1].height(rear)];
        let mut input = SVector::<f64, 9>::zeros();
        for j in 0..4 {
            input[j] = u[j];
            input[4 + j] = (next[j] - u[j]) / self.dt;
        }
        input[8] = 1.0;
        self.x = self.phi * x + self.gamma * input;
        self.u = next;
        self.k += 1;
        out
    }
}

#[inline]
fn gauss(rng: &mut Xoshiro256PlusPlus) -> f64 {
    StandardNormal.sample(rng)
}

#[cfg(test)]
#[path = "full_drive_tests.rs"]
mod tests;

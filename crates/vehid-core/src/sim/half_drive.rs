//! Realistic drives of the half car: the quarter car's drive (`drive.rs`) with two
//! axles on one ISO 8608 road, parameter changes per axle, and the sensors over both axles.
//!
//! **Car.** The [`HalfCar`] of Eq 6.1–6.6, state `[x1, ẋ1, x2, ẋ2, x3, ẋ3, φ, φ̇]` (front
//! wheel, rear wheel, body heave (m, m/s), pitch (rad, rad/s), deviations from the static
//! equilibrium of the initial constants), inputs the road under the front and the rear wheel.
//! The suspension extensions are `d_f = x3 + l1 φ − x1`, `d_r = x3 − l2 φ − x2` (Eq 6.1–6.4).
//!
//! **Road by distance, the rear a wheelbase later.** The front wheel rolls on the ISO 8608
//! profile of `iso8608.rs` (the exact AR(1) in distance per sample, `drive.rs`); the rear
//! wheel meets the same profile `L = l1 + l2` metres later (a delay of `L / v` seconds at
//! speed `v`). The front heights are kept with their distances in a fixed ring of
//! [`ROAD_HISTORY`] points (no allocation); the rear height is the linear interpolation of
//! that ring at the rear wheel's distance `s − L`, so within a sample interval. A point is
//! stored only once the car has moved at least `L / 256` since the last one, so the ring
//! always spans more than `L` (4 `L` at least), also when crawling. Before the first sample
//! the road is rolled out over the first `L` metres (steps of `min(v dt, L/256)`), so both
//! wheels start on the profile. As in the quarter car's drive, each wheel's road is linear
//! in time over a sample interval (first-order hold) and the state is advanced exactly for
//! it: `x(k+1) = Φ x(k) + Γ [u_f, u_r, u̇_f, u̇_r, 1]ᵀ` from the exponential of the
//! augmented matrix (state `[x, u_f, u_r, u̇_f, u̇_r, 1]`, 13 × 13). (The rear road is the
//! front's piecewise-linear profile sampled at the rear's positions and held linear per
//! interval: at 15 m/s and 200 Hz the vertices are 7.5 cm apart.)
//!
//! **Gravity.** With `gravity` on (the default) the static forces stay those of the initial
//! car, as in the quarter car's drive: with the static suspension loads `F_f = M0 g l2/L`,
//! `F_r = M0 g l1/L`, the initial spring compressions `s_f = F_f/k12_0`, `s_r = F_r/k22_0`
//! and tyre compressions `t_f = (F_f + m1_0 g)/k11_0`, `t_r = (F_r + m2_0 g)/k21_0`, the
//! accelerations gain the constant terms
//!
//! ```text
//! heave  (k12 s_f + k22 s_r)/M − g          pitch  (l1 k12 s_f − l2 k22 s_r)/J
//! front  (k11 t_f − k12 s_f)/m1 − g         rear   (k21 t_r − k22 s_r)/m2 − g
//! ```
//!
//! all zero before any change; more load makes the body sink (and pitch, if the loads'
//! shares move).
//!
//! **Changes.** [`HalfChange`]: at time `t` a named constant ([`HalfConstant`]: `"M"`, `"J"`,
//! `"k1_f"`, `"k1_r"`, `"k2_f"`, `"k2_r"`, `"b_f"`, `"b_r"`, `"m_f"`, `"m_r"`) becomes
//! `value`, by a step or a linear ramp, with the timing rules of the quarter car's
//! [`super::Change`]. (A load that scales `M` and `J` together is two changes at the same `t`.)
//!
//! **Sensors.** [`SensorSet::State`]: the thesis' measured state and derivative (16
//! channels, [`HALF_STATE_CHANNELS`]). [`SensorSet::Realistic`]: [`HALF_REALISTIC_CHANNELS`]
//! `["a_body_f", "a_body_r", "a_wheel_f", "a_wheel_r", "deflection_f", "deflection_r"]`: body
//! accelerometers above the front and the rear axle (`ẍ3 + l1 φ̈`, `ẍ3 − l2 φ̈`, small pitch),
//! wheel accelerometers, and the two suspension extensions; the quarter car's noise and bias
//! defaults ([`SensorNoise`](crate::model::SensorNoise): the body accelerometers' white noise and bias are `a_body`,
//! `a_body_bias`, the wheels' `a_wheel`, `a_wheel_bias`; four biases drawn once per seed).

use super::drive::{DriveConfig, GRAVITY, MAX_CHANGES};
use super::iso8608::IsoRoad;
use super::streams;
use crate::error::{check_nonneg, check_positive};
use crate::linalg::expm_with_integral;
use crate::model::{HalfCar, HalfConstant, SensorSet, HALF_REALISTIC_CHANNELS, HALF_STATE_CHANNELS};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};
use rand::rngs::Xoshiro256PlusPlus;
use rand_distr::{Distribution, StandardNormal};

/// Points of front-road history a [`HalfDrive`] keeps for its rear wheel.
pub const ROAD_HISTORY: usize = 1024;

/// Most sensor channels of a half-car sample (the state set's 16).
pub const HALF_MAX_CHANNELS: usize = 16;

/// A change of one half-car constant during a drive: a step at `t` or a linear ramp over
/// `ramp` seconds starting at `t` (module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfChange<T> {
    /// Start time, s (≥ 0).
    pub t: T,
    /// The constant changed.
    pub constant: HalfConstant,
    /// Its value at the end of the change, in the constant's unit (> 0).
    pub value: T,
    /// Ramp duration, s (0 for a step).
    pub ramp: T,
}

impl<T: Real> HalfChange<T> {
    /// A step of the constant named `name` ([`HalfConstant`]'s names) to `value` at `t` s.
    ///
    /// # Errors
    /// [`Error::UnknownOption`] for another name; [`Error::InvalidArgument`] for a `t` not
    /// finite and ≥ 0 or a `value` not finite and > 0.
    pub fn step(t: T, name: &str, value: T) -> Result<Self> {
        Self::ramp(t, name, value, T::zero())
    }

    /// A linear ramp of the constant named `name` from its value at `t` to `value` at
    /// `t + ramp` seconds.
    ///
    /// # Errors
    /// As [`HalfChange::step`], and [`Error::InvalidArgument`] for a `ramp` not finite and ≥ 0.
    pub fn ramp(t: T, name: &str, value: T, ramp: T) -> Result<Self> {
        let constant: HalfConstant = name.parse()?;
        let c = Self { t, constant, value, ramp };
        c.validate()?;
        Ok(c)
    }

    fn validate(&self) -> Result<()> {
        check_nonneg("changes.t", self.t)?;
        check_positive("changes.value", self.value)?;
        check_nonneg("changes.ramp", self.ramp)
    }
}

/// Settings of a half-car drive: the quarter car's [`DriveConfig`] (interval, road, speed,
/// sensors, noise, gravity; it must hold no quarter-car change) and the half car's changes.
#[derive(Debug, Clone, PartialEq)]
pub struct HalfDriveConfig<T> {
    /// Everything but the changes.
    pub base: DriveConfig<T>,
    changes: [Option<HalfChange<T>>; MAX_CHANGES],
}

impl<T: Real> HalfDriveConfig<T> {
    /// The settings of `base` (its defaults: ISO 8608 class C at 15 m/s, realistic sensors),
    /// no change.
    pub fn new(base: DriveConfig<T>) -> Self {
        Self { base, changes: [None; MAX_CHANGES] }
    }

    /// Adds a parameter change.
    ///
    /// # Errors
    /// [`Error::Capacity`] beyond [`MAX_CHANGES`]; the checks of [`HalfChange::step`].
    pub fn with_change(mut self, change: HalfChange<T>) -> Result<Self> {
        change.validate()?;
        match self.changes.iter_mut().find(|c| c.is_none()) {
            Some(slot) => *slot = Some(change),
            None => return Err(Error::Capacity { arg: "changes", needed: MAX_CHANGES + 1, capacity: MAX_CHANGES }),
        }
        Ok(self)
    }

    /// The changes configured.
    pub fn changes(&self) -> impl Iterator<Item = &HalfChange<T>> {
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
                expected: "a drive configuration without quarter-car changes (add HalfChange values instead)",
            });
        }
        for c in self.changes() {
            c.validate()?;
        }
        Ok(())
    }
}

/// One sample of a half-car drive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfDriveSample<T: Real> {
    /// Sample index `k`.
    pub k: u64,
    /// Time `k·dt`, s.
    pub t: T,
    /// Distance the car travelled before this sample, m.
    pub s: T,
    /// Speed over the interval after this sample, m/s.
    pub speed: T,
    /// True state `[x1, ẋ1, x2, ẋ2, x3, ẋ3, φ, φ̇]` (m, m/s, rad, rad/s).
    pub x: SVector<T, 8>,
    /// True derivative.
    pub xdot: SVector<T, 8>,
    /// Road height under the front and the rear wheel, m.
    pub u: [T; 2],
    /// The constants in effect, in the order of [`HalfCar::CONSTANTS`].
    pub constants: [T; 12],
    y: [T; HALF_MAX_CHANNELS],
    len: usize,
}

impl<T: Real> HalfDriveSample<T> {
    /// The sensor channels (names: [`HalfDrive::channels`]).
    pub fn y(&self) -> &[T] {
        &self.y[..self.len]
    }
}

/// The front road's recent heights by distance (a fixed ring; module documentation).
#[derive(Debug, Clone)]
pub(super) struct RoadHistory {
    s: [f64; ROAD_HISTORY],
    z: [f64; ROAD_HISTORY],
    head: usize,
    len: usize,
    pub(super) spacing: f64,
}

impl RoadHistory {
    pub(super) fn new(spacing: f64) -> Self {
        Self { s: [0.0; ROAD_HISTORY], z: [0.0; ROAD_HISTORY], head: 0, len: 0, spacing }
    }

    /// Index of the `i`-th oldest point.
    fn at(&self, i: usize) -> usize {
        (self.head + i) % ROAD_HISTORY
    }

    /// Stores the front height `z` at distance `s` if the car moved at least the spacing
    /// since the last point (always the first).
    pub(super) fn push(&mut self, s: f64, z: f64) {
        if self.len > 0 && s - self.s[self.at(self.len - 1)] < self.spacing {
            return;
        }
        if self.len == ROAD_HISTORY {
            self.head = (self.head + 1) % ROAD_HISTORY;
            self.len -= 1;
        }
        let i = self.at(self.len);
        self.s[i] = s;
        self.z[i] = z;
        self.len += 1;
    }

    /// The height at distance `q` by linear interpolation between the stored points; drops
    /// the points no later query needs (queries come in increasing `q`).
    pub(super) fn height(&mut self, q: f64) -> f64 {
        while self.len >= 2 && self.s[self.at(1)] <= q {
            self.head = (self.head + 1) % ROAD_HISTORY;
            self.len -= 1;
        }
        let i0 = self.at(0);
        if self.len < 2 || q <= self.s[i0] {
            return self.z[i0];
        }
        let i1 = self.at(1);
        let w = (q - self.s[i0]) / (self.s[i1] - self.s[i0]);
        self.z[i0] + w * (self.z[i1] - self.z[i0])
    }
}

/// A streaming half-car drive: one [`HalfDriveSample`] per call, no allocation (module
/// documentation).
///
/// # Examples
/// ```
/// use vehid_core::model::HalfCar;
/// use vehid_core::sim::{DriveConfig, HalfChange, HalfDrive, HalfDriveConfig};
/// let cfg = HalfDriveConfig::new(DriveConfig::new(0.005))
///     .with_change(HalfChange::step(60.0, "b_f", 1440.0).unwrap())
///     .unwrap();
/// let mut drive = HalfDrive::new(HalfCar::<f64>::passenger(), cfg, 1).unwrap();
/// assert_eq!(drive.channels()[0], "a_body_f");
/// assert_eq!(drive.next_sample().y().len(), 6);
/// ```
#[derive(Debug, Clone)]
pub struct HalfDrive<T: Real> {
    cfg: HalfDriveConfig<T>,
    dt: f64,
    c: [f64; 12],
    start: [f64; MAX_CHANGES],
    statics: [f64; 4],
    a: SMatrix<f64, 8, 8>,
    b: SMatrix<f64, 8, 2>,
    f: SVector<f64, 8>,
    phi: SMatrix<f64, 8, 8>,
    gamma: SMatrix<f64, 8, 5>,
    x: SVector<f64, 8>,
    u: [f64; 2],
    bias: [f64; 4],
    road: IsoRoad,
    hist: RoadHistory,
    wheelbase: f64,
    s: f64,
    k: u64,
    rng_w: Xoshiro256PlusPlus,
    rng_v: Xoshiro256PlusPlus,
}

impl<T: Real> HalfDrive<T> {
    /// A drive of `car` (its initial constants) with settings `cfg`; `seed` fixes the road,
    /// the biases and the noise. The car starts at rest in its static equilibrium on the
    /// road under both wheels.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the setting: `dt`, `cutoff` not finite and > 0,
    /// `speed` or a noise level not finite and ≥ 0, a change's time, value or ramp, a `base`
    /// holding quarter-car changes.
    pub fn new(car: HalfCar<T>, cfg: HalfDriveConfig<T>, seed: u64) -> Result<Self> {
        cfg.validate()?;
        let b = &cfg.base;
        let dt = b.dt.to_f64();
        let c = car.constants().map(|v| v.to_f64());
        let [mut rng_bias, rng_road, rng_w, rng_v] = streams(seed);
        let mut road = IsoRoad::new(b.road, b.cutoff.to_f64(), rng_road)?;
        let mut bias = [0.0; 4];
        if b.sensors == SensorSet::Realistic {
            let n = &b.noise;
            let sd = [n.a_body_bias, n.a_body_bias, n.a_wheel_bias, n.a_wheel_bias];
            for (bi, s) in bias.iter_mut().zip(sd) {
                let e: f64 = StandardNormal.sample(&mut rng_bias);
                *bi = e * s.to_f64();
            }
        }
        let [mb, _, k11, k21, k12, k22, _, _, m1, m2, l1, l2] = c;
        let wheelbase = l1 + l2;
        let (ff, fr) = (mb * GRAVITY * l2 / wheelbase, mb * GRAVITY * l1 / wheelbase);
        let statics = [ff / k12, fr / k22, (ff + m1 * GRAVITY) / k11, (fr + m2 * GRAVITY) / k21];
        // Roll the road out over the first wheelbase: the rear wheel starts at 0, the front at L.
        let mut hist = RoadHistory::new(wheelbase / 256.0);
        let v = b.speed.to_f64();
        let step0 = if v > 0.0 { (v * dt).min(wheelbase / 256.0) } else { wheelbase / 256.0 };
        let n0 = libm::ceil(wheelbase / step0).max(1.0) as usize;
        hist.push(0.0, road.height());
        for i in 1..=n0 {
            road.advance(wheelbase / n0 as f64);
            hist.spacing = 0.0;
            hist.push(wheelbase * i as f64 / n0 as f64, road.height());
        }
        hist.spacing = wheelbase / 256.0;
        let uf = road.height();
        let ur = hist.height(0.0);
        let x = SVector::from([uf, 0.0, ur, 0.0, (l2 * uf + l1 * ur) / wheelbase, 0.0, (uf - ur) / wheelbase, 0.0]);
        let mut d = Self {
            cfg,
            dt,
            c,
            start: [f64::NAN; MAX_CHANGES],
            statics,
            a: SMatrix::zeros(),
            b: SMatrix::zeros(),
            f: SVector::zeros(),
            phi: SMatrix::zeros(),
            gamma: SMatrix::zeros(),
            x,
            u: [uf, ur],
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
        Ok(d)
    }

    /// The sensor channel names of every sample.
    pub fn channels(&self) -> &'static [&'static str] {
        self.cfg.base.sensors.half_channels()
    }

    /// The configuration.
    pub fn config(&self) -> &HalfDriveConfig<T> {
        &self.cfg
    }

    /// The accelerometer biases `[body front, body rear, wheel front, wheel rear]` drawn for
    /// this seed, m/s² (zero for the state set).
    pub fn biases(&self) -> [T; 4] {
        self.bias.map(T::of)
    }

    /// The constants in effect, in the order of [`HalfCar::CONSTANTS`].
    pub fn constants(&self) -> [T; 12] {
        self.c.map(T::of)
    }

    /// Drives on onto a road of class `road` (from the current height).
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
        let car = HalfCar::from_constants(self.c)?;
        let model = car.model();
        let (a, bm) = (*model.a(), *model.b());
        let [mb, j, k11, k21, k12, k22, _, _, m1, m2, l1, l2] = self.c;
        let mut f = SVector::<f64, 8>::zeros();
        if self.cfg.base.gravity {
            let [sf, sr, tf, tr] = self.statics;
            f[1] = (k11 * tf - k12 * sf) / m1 - GRAVITY;
            f[3] = (k21 * tr - k22 * sr) / m2 - GRAVITY;
            f[5] = (k12 * sf + k22 * sr) / mb - GRAVITY;
            f[7] = (l1 * k12 * sf - l2 * k22 * sr) / j;
        }
        // Augmented state [x, u_f, u_r, u̇_f, u̇_r, 1]: each wheel's road linear over the interval.
        let mut aug = SMatrix::<f64, 13, 13>::zeros();
        aug.fixed_view_mut::<8, 8>(0, 0).copy_from(&a);
        aug.fixed_view_mut::<8, 2>(0, 8).copy_from(&bm);
        aug.fixed_view_mut::<8, 1>(0, 12).copy_from(&f);
        aug[(8, 10)] = 1.0;
        aug[(9, 11)] = 1.0;
        let (e, _) = expm_with_integral(&aug, self.dt);
        let phi: SMatrix<f64, 8, 8> = e.fixed_view::<8, 8>(0, 0).into_owned();
        let gamma: SMatrix<f64, 8, 5> = e.fixed_view::<8, 5>(0, 8).into_owned();
        if phi.iter().chain(gamma.iter()).any(|v| !v.is_finite()) {
            return Err(Error::InvalidArgument {
                arg: "dt",
                expected: "a sample interval short enough for the car that e^{A dt} stays finite",
            });
        }
        (self.a, self.b, self.f, self.phi, self.gamma) = (a, bm, f, phi, gamma);
        Ok(())
    }

    /// Applies the changes due at time `t`; `true` when a constant moved.
    fn apply_changes(&mut self, t: f64) -> bool {
        let mut moved = false;
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
    pub fn next_sample(&mut self) -> HalfDriveSample<T> {
        let v = self.cfg.base.speed.to_f64();
        self.step(v)
    }

    /// Produces sample `k`, then drives on at `speed` m/s for one interval.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a speed not finite and ≥ 0 (the drive is unchanged).
    pub fn next_sample_at(&mut self, speed: T) -> Result<HalfDriveSample<T>> {
        check_nonneg("speed", speed)?;
        Ok(self.step(speed.to_f64()))
    }

    #[inline]
    fn step(&mut self, v: f64) -> HalfDriveSample<T> {
        let t = self.k as f64 * self.dt;
        if self.apply_changes(t) {
            // Constants validated > 0, dt > 0: keep the old transition if the new one failed.
            let _ = self.rebuild();
        }
        let [uf, ur] = self.u;
        let x = self.x;
        let xdot = self.a * x + self.b * SVector::<f64, 2>::new(uf, ur) + self.f;
        let (l1, l2) = (self.c[10], self.c[11]);
        let mut y = [T::zero(); HALF_MAX_CHANNELS];
        let len = match self.cfg.base.sensors {
            SensorSet::Realistic => {
                let n = &self.cfg.base.noise;
                let (sb, sw, sd) = (n.a_body.to_f64(), n.a_wheel.to_f64(), n.deflection.to_f64());
                let clean = [
                    xdot[5] + l1 * xdot[7] + self.bias[0],
                    xdot[5] - l2 * xdot[7] + self.bias[1],
                    xdot[1] + self.bias[2],
                    xdot[3] + self.bias[3],
                    x[4] + l1 * x[6] - x[0],
                    x[4] - l2 * x[6] - x[2],
                ];
                let sd = [sb, sb, sw, sw, sd, sd];
                for i in 0..6 {
                    y[i] = T::of(clean[i] + sd[i] * gauss(&mut self.rng_w));
                }
                HALF_REALISTIC_CHANNELS.len()
            }
            SensorSet::State => {
                let (sw, sv) = (self.cfg.base.noise.state.to_f64(), self.cfg.base.noise.deriv.to_f64());
                for i in 0..8 {
                    y[i] = T::of(x[i] + sw * gauss(&mut self.rng_w));
                }
                for i in 0..8 {
                    y[8 + i] = T::of(xdot[i] + sv * gauss(&mut self.rng_v));
                }
                HALF_STATE_CHANNELS.len()
            }
        };
        let out = HalfDriveSample {
            k: self.k,
            t: T::of(t),
            s: T::of(self.s - self.wheelbase),
            speed: T::of(v),
            x: x.map(T::of),
            xdot: xdot.map(T::of),
            u: [T::of(uf), T::of(ur)],
            constants: self.c.map(T::of),
            y,
            len,
        };
        let ds = v * self.dt;
        self.road.advance(ds);
        self.s += ds;
        let nf = self.road.height();
        self.hist.push(self.s, nf);
        let nr = self.hist.height(self.s - self.wheelbase);
        let input = SVector::<f64, 5>::new(uf, ur, (nf - uf) / self.dt, (nr - ur) / self.dt, 1.0);
        self.x = self.phi * x + self.gamma * input;
        self.u = [nf, nr];
        self.k += 1;
        out
    }
}

#[inline]
fn gauss(rng: &mut Xoshiro256PlusPlus) -> f64 {
    StandardNormal.sample(rng)
}

#[cfg(test)]
#[path = "half_drive_tests.rs"]
mod tests;

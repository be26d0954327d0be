//! Seeded simulation of `ẋ = A x + B u` with every noise source of the thesis (Ch. III.C).
//!
//! Per sample `k` (time `t_k = k·dt`):
//! - the road input `u(k) ~ N(0, σ_u²)` per input, held over `[t_k, t_{k+1})` (Eq 4.25),
//!   plus any pulse active at `k`;
//! - the true state `x(k)` and derivative `ẋ(k) = A x(k) + B u(k)`;
//! - the measurements `r(k) = x(k) + w(k)`, `w ~ N(0, diag σ_w²)` and
//!   `z(k) = ẋ(k) + v(k)`, `v ~ N(0, diag σ_v²)`; in instrumentation mode (Eq 4.37–4.39) a
//!   kinematic row `ẋ_i = x_j` is read from the sensor of `x_j`, so `z_i = r_j`;
//! - then `x(k+1) = Φ x(k) + Γ u(k)` by RK4 ([`Method::Rk4`], sub-stepped) or the exact
//!   zero-order hold ([`Method::Exact`]).
//!
//! The initial state is `x(0) ~ N(0, σ_ic² I)`. Each noise source has its own random
//! stream derived from the seed, so changing one σ leaves the others' realizations alone
//! (a noise-free and a noisy run with the same seed see the same road). The generator is
//! Xoshiro256++ and the normal variates are drawn in `f64`, so a seed gives the same run on
//! every platform, in `f32` and `f64` alike (up to the `f32` rounding).
//!
//! Files: `config.rs` (settings, pulses, the integration method), `time.rs` ([`Simulator`],
//! samples at a fixed interval), `road.rs` ([`RoadSimulator`]: two axles on one road, samples
//! by distance at a speed profile), `run.rs` ([`Run`], a whole simulation in memory),
//! `drive.rs` ([`QuarterDrive`]: realistic drives — an ISO 8608 road by distance,
//! parameter changes at given times, accelerometers and a deflection sensor; `iso8608.rs`:
//! the road by distance); `half_drive.rs` ([`HalfDrive`]: the same for the half car, the rear
//! wheel a wheelbase behind the front on one road); `full_drive.rs` ([`FullDrive`]: the full
//! car on a left and a right track, `two_track.rs`: [`TwoTrackRoad`], the tracks' coherence).

mod config;
mod drive;
mod full_drive;
mod half_drive;
mod iso8608;
mod road;
#[cfg(feature = "alloc")]
mod run;
mod time;
mod two_track;

pub use config::{per_component, Method, Pulse, SimConfig, SimSettings, MAX_PULSES, MAX_SIGMA};
pub use drive::{
    Change, DriveConfig, DriveSample, QuarterConstant, QuarterDrive, SensorNoise, SensorSet, GRAVITY, MAX_CHANGES,
    MAX_CHANNELS, REALISTIC_CHANNELS, STATE_CHANNELS,
};
pub use full_drive::{
    FullChange, FullConstant, FullDrive, FullDriveConfig, FullDriveSample, FullLoad, FULL_MAX_CHANNELS, MAX_LOADS,
};
pub use half_drive::{HalfChange, HalfDrive, HalfDriveConfig, HalfDriveSample, HALF_MAX_CHANNELS, ROAD_HISTORY};
pub use iso8608::{IsoRoad, RoadClass, DEFAULT_CUTOFF, N0};
pub use road::{RoadConfig, RoadMode, RoadSample, RoadSimulator, SpeedProfile};
#[cfg(feature = "alloc")]
pub use run::Run;
pub use time::{Sample, Simulator};
pub use two_track::{TwoTrackRoad, HALF_COHERENCE};

use crate::Real;
use nalgebra::SVector;
use rand::rngs::Xoshiro256PlusPlus;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// Seeds of the independent streams: initial condition, road, state noise, derivative noise.
pub(crate) fn streams(seed: u64) -> [Xoshiro256PlusPlus; 4] {
    let mut master = Xoshiro256PlusPlus::seed_from_u64(seed);
    [
        Xoshiro256PlusPlus::from_rng(&mut master),
        Xoshiro256PlusPlus::from_rng(&mut master),
        Xoshiro256PlusPlus::from_rng(&mut master),
        Xoshiro256PlusPlus::from_rng(&mut master),
    ]
}

/// The sensors of Ch. III.C: `r = x + w`, `z = ẋ + v` (one draw per component, `w` first),
/// and in instrumentation mode (Eq 4.37–4.39) a kinematic row read from its state's sensor.
/// (`#[inline]`: the per-sample path, so that it can be inlined into its caller whichever
/// codegen unit holds that caller's instantiation.)
#[inline]
pub(crate) fn measure<T: Real, const N: usize, const M: usize>(
    cfg: &SimConfig<T, N, M>,
    kinematic: &[Option<usize>; N],
    rng_w: &mut Xoshiro256PlusPlus,
    rng_v: &mut Xoshiro256PlusPlus,
    x: &SVector<T, N>,
    xdot: &SVector<T, N>,
) -> (SVector<T, N>, SVector<T, N>) {
    let mut r = *x;
    for i in 0..N {
        r[i] += normal::<T>(rng_w) * cfg.state_noise[i];
    }
    let mut z = *xdot;
    for i in 0..N {
        z[i] += normal::<T>(rng_v) * cfg.deriv_noise[i];
    }
    if cfg.instrumentation {
        for i in 0..N {
            if let Some(j) = kinematic[i] {
                z[i] = r[j];
            }
        }
    }
    (r, z)
}

#[inline]
pub(crate) fn normal<T: Real>(rng: &mut Xoshiro256PlusPlus) -> T {
    let v: f64 = StandardNormal.sample(rng);
    T::of(v)
}

#[cfg(test)]
mod tests;

//! # vehid-core
//!
//! Online identification of a land vehicle's suspension dynamics, after J. H. Kessler,
//! *Adaptive Modeling of the Dynamics of Autonomous Land Vehicles* (NPS, 1986).
//!
//! From measured samples of the state `r(k) = x(k) + w(k)` and of its derivative
//! `z(k) = ẋ(k) + v(k)` the identifiers estimate the unknown rows of the continuous-time
//! matrix `A` of `ẋ = A x + B u` (Eq 2.2–2.4), where `B` is known and the road input `u`
//! is never measured.
//!
//! Modules, one per concept:
//! - [`model`]: linear models, the quarter car (Eq 3.11) and the half car (Eq 6.1–6.6);
//! - [`sim`]: a seeded simulator with every noise source of the thesis (Ch. III.C), and a
//!   road simulator for two axles on one road driven at a speed profile (Ch. VI.D);
//! - [`sampler`]: distance-triggered sampling that pairs rear- and front-axle samples (Eq 6.12–6.14);
//! - [`analysis`]: discretization, stationary covariances, Eq 4.27 output standard deviations;
//! - [`metrics`]: the parameter error measure ξ (Eq 3.17) and sensor SNR (Eq 4.31);
//! - [`simd`]: the run-time choice of vector instructions (results never depend on it);
//! - [`identify`]: batch least squares, the Kalman-filter identifier, stochastic gradient,
//!   and the two-axle identifier (thesis' Eq 6.14 and road cancellation);
//! - [`health`]: the suspension health monitor: `k2/M`, `b/M` tracked from
//!   accelerometers and a deflection sensor, changes detected and named;
//! - [`stats`]: the estimates' uncertainty as statsmodels names it (`bse`, `conf_int`,
//!   `sigma2`, `cov_params`), Student's t, and the CUSUM tests of the recursive residuals.
//!
//! Everything is generic over the scalar ([`Real`]: `f32` or `f64`) and over the dimensions
//! (const generics). The per-sample paths allocate nothing.
//!
//! ## Features
//! - `std` (default): implements `std::error::Error`; enables `alloc` and faer-based QR.
//! - `alloc`: whole-run simulation, stored-sample least squares, dynamic row counts.
//! - neither: `#![no_std]`, for microcontrollers; models, streaming simulator and the
//!   recursive identifiers are all available.
//! - `serde` (any of the above): `Serialize`/`Deserialize` for every identifier, in both
//!   stores ([`identify::Fixed`] without allocation, [`identify::Dynamic`]), its options and
//!   the models it holds. A deserialized identifier continues bit for bit where the
//!   serialized one was; input whose parts do not fit together (buffer lengths, rows, the
//!   two-axle ring) is a deserialization error, never a later panic. Deserialize through the
//!   trait (`postcard::from_bytes`, `serde_json::from_str`, `<T as Deserialize>::deserialize`).
#![cfg_attr(not(feature = "std"), no_std)]
#![deny(missing_docs)]

#[cfg(feature = "alloc")]
extern crate alloc;

/// Gives a unit enum of choices its option names: `NAMES`, `as_str`, `Display`, and
/// `FromStr` whose error names the argument and lists the choices.
macro_rules! option_names {
    ($ty:ident, $arg:literal, { $v0:ident => $n0:literal $(, $v:ident => $n:literal)* $(,)? }) => {
        impl $ty {
            /// Every accepted name, in declaration order.
            pub const NAMES: &'static [&'static str] = &[$n0 $(, $n)*];

            /// The name of this choice (what `FromStr` accepts).
            pub fn as_str(&self) -> &'static str {
                match self {
                    Self::$v0 => $n0,
                    $(Self::$v => $n,)*
                }
            }
        }

        impl core::str::FromStr for $ty {
            type Err = crate::Error;

            fn from_str(s: &str) -> crate::Result<Self> {
                match s {
                    $n0 => Ok(Self::$v0),
                    $($n => Ok(Self::$v),)*
                    _ => Err(crate::Error::UnknownOption {
                        arg: $arg,
                        expected: concat!("\"", $n0, "\"" $(, ", \"", $n, "\"")*),
                    }),
                }
            }
        }

        impl core::fmt::Display for $ty {
            fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str(self.as_str())
            }
        }
    };
}

pub mod analysis;
mod array;
mod error;
pub mod health;
pub mod identify;
pub(crate) mod linalg;
pub mod metrics;
pub mod model;
#[cfg(feature = "serde")]
mod persist;
pub mod sampler;
mod scalar;
pub mod sim;
pub mod simd;
pub mod stats;
pub mod structure;

pub use error::{Error, Result};
pub use nalgebra;
pub use scalar::Real;

/// The README's Rust examples, compiled and run as doctests so they cannot rot.
#[cfg(all(doctest, feature = "std"))]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;

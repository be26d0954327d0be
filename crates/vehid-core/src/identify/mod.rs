//! Identifiers of the unknown rows of `A` (Ch. II–V of the thesis).
//!
//! | identifier | equations | file |
//! |---|---|---|
//! | [`BatchLeastSquares`] (std), [`LsAccumulator`] | Eq 2.14, 3.4 | `least_squares.rs` |
//! | [`KalmanIdentifier`] (decoupled rows), [`SharedKalmanIdentifier`], [`FullKalmanIdentifier`] | Eq 4.3–4.7, 4.35–4.36, 6.16–6.18 | `kalman/` |
//! | [`StochasticGradient`] | Eq 2.56, 5.2–5.18 | `gradient.rs` |
//! | [`Structured`] (any [`crate::structure::Structure`]: grey-box models linear in their parameters) | Eq 2.2–2.4, 6.16–6.18 | `structured.rs`, `structured_fast.rs` |
//! | [`InstrumentalVariables`] (noisy measured states: instruments = regressors `delay` samples earlier) | Söderström & Stoica §8 | `instrumental.rs` (`instrumental/`: the ring of past samples, the prior's blocks, the shared-parameter regressor), `iv_filter.rs` |
//! | [`BiasCompensated`] (noisy measured states, known noise covariance: `(XᵀX − N Σ_w)⁻¹ Xᵀz`) | Söderström 2007 §4.3 | `bias_compensated.rs` |
//! | [`NoiseEstimatingBcls`] (noisy measured states, `Σ_w` estimated from the least-squares residual at an instrumental estimate, then compensated) | Zheng 1998, 2002; Söderström 2018 Ch. 7 | `noise_estimating.rs` |
//! | [`JointEkf`] (noisy measured states: states, parameters and road estimated together by an extended Kalman filter; the thesis' Ch. VII proposal) | Ljung 1979 | `joint_ekf.rs` (`joint_ekf/noise.rs`: [`EkfNoise`]) |
//! | [`TwoAxleIdentifier`] (two axles on one road: plain, Eq 6.14, road cancellation) | Eq 6.9, 6.12–6.14 | `two_axle.rs` |
//! | [`TwoAxleStructured`] (road cancellation on a physical [`crate::structure::Structure`]: the half car's 12 parameters) | Eq 6.1–6.9 | `two_axle_structured.rs` (`two_axle_structured/config.rs`: [`TwoAxleStructuredConfig`]) |
//! | [`Differenced`] (any identifier on a road that is not white: the samples quasi-differenced by the road's ISO 8608 shaping filter in distance; with [`InstrumentalVariables`] inside, consistent) | Anderson & Hsiao 1981; Cochrane & Orcutt 1949 | `road.rs` (`road/boxed.rs`: [`BoxedIdentifier`]) |
//! | [`StateFilterFit`] (the body equation from a body accelerometer and a deflection sensor: a state-variable filter on both sides, cluster-robust intervals for its coloured residuals) | Young 1981; Garnier et al. 2003; Cameron & Miller 2015 | `state_filter.rs` |
//!
//! All of them but [`JointEkf`] (which estimates the state too) regress the measured
//! derivative of each unknown row on the measured state: `z_i(k) = r(k)ᵀ θ_i + ε_i(k)`
//! (Eq 2.2–2.4 with `H = I ⊗ xᵀ`), and all of them implement
//! one interface, [`Identifier`] (`interface.rs`; an identifier's implementation of it, and
//! its persistence, in `<its file>/identifier.rs`): samples in through
//! [`Identifier::update_into`], which allocates nothing and is transactional (a rejected
//! sample — NaN, inf, a numerically singular step — returns an error and leaves the
//! identifier exactly as it was), estimates out through caller buffers, and a transactional
//! batch [`Identifier::fit`]. [`DynIdentifier`] (alloc) is its boxed form. What the
//! identifiers share: [`Samples`] (`samples.rs`), the sample checks and overflow errors
//! (`checks.rs`), conversions between their fixed-size state and the interface's slices
//! (`buffers.rs`), [`Cost`] (`cost.rs`).
//!
//! # Storage
//! Each identifier is generic over a [`Store`] (`store.rs`): [`Fixed<K>`] keeps the `K`
//! unknown rows in arrays (no allocation at all; the form for embedded use and the aliases
//! [`KalmanIdentifier`], [`StochasticGradient`], ...), [`Dynamic`] keeps them in `Vec`s sized
//! at construction (requires `alloc`; the form the Python bindings use, so that one
//! monomorphization per state count serves any number of unknown rows). The numerics are
//! the same code for both.
//!
//! # Speed
//! The decoupled rows of [`KalmanRows`] are stored side by side in lanes (`kalman/lanes.rs`),
//! so one update treats all rows at once with vector instructions; on x86-64 with `std` the
//! rows and shared updates also have an AVX2 copy chosen at run time ([`crate::simd`]). Every
//! path computes the same bits. Measured figures and how to reproduce them: `benches/README.md`.

mod bias_compensated;
mod buffers;
mod checks;
#[cfg(feature = "alloc")]
mod corner_filter;
mod cost;
mod deriv_noise;
#[cfg(feature = "alloc")]
mod estimate_stats;
mod gradient;
mod instrumental;
mod interface;
mod iv_filter;
mod iv_model;
pub(crate) mod iv_predictor;
mod joint_ekf;
mod kalman;
mod least_squares;
mod noise_estimating;
pub(crate) mod persist;
mod road;
mod samples;
mod screen;
#[cfg(feature = "alloc")]
mod state_filter;
mod store;
mod structured;
mod structured_fast;
mod structured_gradient;
mod two_axle;
mod two_axle_structured;

#[cfg(feature = "alloc")]
pub use bias_compensated::BiasCompensatedVec;
pub use bias_compensated::{BcGroup, BiasCompensated, BiasCompensatedLs};
#[cfg(feature = "alloc")]
pub use corner_filter::{CornerFilterFit, CORNER_BANDWIDTH, CORNER_COEFFICIENTS, CORNER_REGRESSORS};
pub use cost::Cost;
#[cfg(feature = "alloc")]
pub use estimate_stats::{estimate_stats, posterior_stats, EstimateStats};
#[cfg(feature = "alloc")]
pub use gradient::StochasticGradientVec;
pub use gradient::{Gain, GainKind, GradientCore, StochasticGradient};
#[cfg(feature = "alloc")]
pub use instrumental::IvIdentifierVec;
pub use instrumental::{InstrumentalVariables, IvIdentifier, RING_VALUES};
pub use interface::{Dims, FitError, Identifier, FIT_STACK_EQUATIONS};
#[cfg(feature = "alloc")]
pub use interface::{DynIdentifier, FitOptions};
pub use iv_filter::IvFilter;
#[cfg(feature = "alloc")]
pub use iv_model::ModelIvIdentifierVec;
pub use iv_model::{ModelInstruments, ModelIvIdentifier};
pub use joint_ekf::{joint_ekf_substeps, EkfNoise, JointEkf, MAX_EKF_SUBSTEPS};
#[cfg(feature = "alloc")]
pub use kalman::{
    boxed_kalman, FullKalmanIdentifierVec, KalmanIdentifierVec, KalmanIdentifierVec2, KalmanSpec, Prior,
    SharedKalmanIdentifierVec,
};
pub use kalman::{
    CovarianceForm, FullKalmanIdentifier, KalmanFull, KalmanIdentifier, KalmanOptions, KalmanRows, KalmanShared, Mode,
    RowIdentifier, SharedKalmanIdentifier,
};
#[cfg(feature = "std")]
pub use least_squares::BatchLeastSquares;
pub use least_squares::LsAccumulator;
#[cfg(feature = "alloc")]
pub use noise_estimating::NoiseEstimatingBclsVec;
pub use noise_estimating::{NoiseEstimatingBcls, NoiseEstimatingBclsLs};
pub(crate) use persist::persist_by_serde;
pub use persist::Persist;
#[cfg(feature = "alloc")]
pub use road::BoxedIdentifier;
pub use road::{
    Contact, Differenced, RoadModel, RoadState, Travel, DEFAULT_MIN_SPACING, LIFT_OFF_LOAD, MAX_ROAD_WEIGHT,
};
pub use samples::{SampleIter, Samples};
pub use screen::{Refresh, ScreenState, Screened, START_SAMPLES, START_VALUES};
#[cfg(feature = "alloc")]
pub use state_filter::{StateFilterFit, DEFAULT_BANDWIDTH, DEFAULT_BLOCK};
pub use store::{Dynamic, Fixed, Flat, NoScratch, Store, DYNAMIC_LANES};
#[cfg(feature = "alloc")]
pub use structured::StructuredKalmanVec;
pub use structured::{Structured, StructuredKalman, StructuredPrior};
pub use structured_gradient::StructuredGradient;
#[cfg(feature = "alloc")]
pub use two_axle::TwoAxleIdentifierVec;
pub use two_axle::{Past, TwoAxle, TwoAxleConfig, TwoAxleIdentifier, WheelMethod, MAX_TRACKS};
#[cfg(feature = "alloc")]
pub use two_axle_structured::TwoAxleStructuredVec;
pub use two_axle_structured::{FrontRegression, TwoAxleStructured, TwoAxleStructuredConfig, TwoAxleStructuredKalman};

pub(crate) use buffers::{fixed_theta, vector};
pub(crate) use checks::{check_lengths, check_sample, OVERFLOW, OVERFLOW_Z};
pub(crate) use store::{per_row, rows_buffer, rows_into};

//! ISO 8608 road profiles by distance (module documentation of `drive.rs` for the shaping
//! filter and its exact discretization).

use crate::error::check_positive;
use crate::Result;
use rand::rngs::Xoshiro256PlusPlus;
use rand_distr::{Distribution, StandardNormal};

/// The ISO 8608 reference spatial frequency `n0`, cycles/m.
pub const N0: f64 = 0.1;

/// Default shaping-filter cutoff `n_c`, cycles/m (wavelengths above 100 m are flat).
pub const DEFAULT_CUTOFF: f64 = 0.01;

/// An ISO 8608 road class (or a flat road).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RoadClass {
    /// No road excitation.
    Flat,
    /// Class A, `G_d(n0)` = 16e-6 m³ (very good).
    A,
    /// Class B, 64e-6 m³ (good).
    B,
    /// Class C, 256e-6 m³ (average).
    #[default]
    C,
    /// Class D, 1024e-6 m³ (poor).
    D,
    /// Class E, 4096e-6 m³ (very poor).
    E,
}

option_names!(RoadClass, "road", {
    Flat => "flat", A => "iso8608-A", B => "iso8608-B", C => "iso8608-C", D => "iso8608-D", E => "iso8608-E"
});

impl RoadClass {
    /// The class' displacement PSD at `n0 = 0.1` cycles/m, `G_d(n0)` in m³ (ISO 8608: the
    /// geometric mean of the class; 0 for a flat road).
    pub fn gd0(&self) -> f64 {
        match self {
            RoadClass::Flat => 0.0,
            RoadClass::A => 16e-6,
            RoadClass::B => 64e-6,
            RoadClass::C => 256e-6,
            RoadClass::D => 1024e-6,
            RoadClass::E => 4096e-6,
        }
    }
}

/// An ISO 8608 road profile by distance (module documentation: the first-order shaping
/// filter, exactly discretized per sample as an AR(1) in distance).
#[derive(Debug, Clone)]
pub struct IsoRoad {
    sigma: f64,
    cutoff: f64,
    z: f64,
    rng: Xoshiro256PlusPlus,
}

impl IsoRoad {
    /// A road of `class` with shaping cutoff `cutoff` (cycles/m, > 0), its height drawn
    /// from the stationary distribution `N(0, π n0² G_d(n0) / (2 n_c))`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`](crate::Error::InvalidArgument) for a cutoff not finite and > 0.
    pub fn new(class: RoadClass, cutoff: f64, mut rng: Xoshiro256PlusPlus) -> Result<Self> {
        check_positive("cutoff", cutoff)?;
        let sigma = libm::sqrt(core::f64::consts::PI * N0 * N0 * class.gd0() / (2.0 * cutoff));
        let e: f64 = StandardNormal.sample(&mut rng);
        Ok(Self { sigma, cutoff, z: sigma * e, rng })
    }

    /// The current road height, m.
    pub fn height(&self) -> f64 {
        self.z
    }

    /// The stationary standard deviation of the height, `σ_r`, m.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// Continues on a road of another class from the current height (the height's
    /// spread relaxes to the new class over a few `1/(2π n_c)` metres, 16 m by default).
    pub fn set_class(&mut self, class: RoadClass) {
        self.sigma = libm::sqrt(core::f64::consts::PI * N0 * N0 * class.gd0() / (2.0 * self.cutoff));
    }

    /// Moves `ds ≥ 0` metres along the road: `z ← φ z + σ_r √(1 − φ²) ε`,
    /// `φ = exp(−2π n_c ds)` (nothing moves for `ds = 0`).
    pub fn advance(&mut self, ds: f64) {
        if ds > 0.0 {
            let phi = libm::exp(-2.0 * core::f64::consts::PI * self.cutoff * ds);
            let e: f64 = StandardNormal.sample(&mut self.rng);
            self.z = phi * self.z + self.sigma * libm::sqrt(1.0 - phi * phi) * e;
        }
    }
}

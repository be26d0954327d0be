//! The configuration of [`TwoAxleStructured`]: the wheelbase in samples and the front
//! regression.

use super::*;

/// Settings of a [`TwoAxleStructured`] identifier: prior and noise levels (each equation's
/// variance is derived from them and the model's `B`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TwoAxleStructuredConfig<T> {
    /// `None`: the exact start (no prior; least squares on all samples once identified);
    /// `Some(p0)`: `P(0) = p0 I` on every parameter.
    pub p0: Option<T>,
    /// Road standard deviation σ_u, m.
    pub road_sigma: T,
    /// Derivative measurement noise σ_v (every component), state units per second.
    pub deriv_noise: T,
    /// Also use the direct front wheel equation, weighted by its variance `σ_v² + b21² σ_u²`.
    pub direct_front: bool,
    /// Remove the attenuation bias of the derivative noise in `der(·)` regressors (see
    /// [`TwoAxleStructured`]'s "Derivative noise"); `false`: plain least squares.
    pub compensate: bool,
}

impl<T: Real> TwoAxleStructuredConfig<T> {
    /// The exact start, the direct front equation on, the derivative noise compensated.
    pub fn new(road_sigma: T, deriv_noise: T) -> Self {
        Self { p0: None, road_sigma, deriv_noise, direct_front: true, compensate: true }
    }

    pub(super) fn validate(&self) -> Result<()> {
        if let Some(p0) = self.p0 {
            check_positive("p0", p0)?;
        }
        check_nonneg("road_sigma", self.road_sigma)?;
        check_nonneg("deriv_noise", self.deriv_noise)
    }
}

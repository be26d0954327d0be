//! The noise model of [`JointEkf`]: its variances and their checks.

use super::*;

/// The noise model of [`JointEkf`] (see the module docs for where each enters). Variances,
/// not standard deviations.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct EkfNoise<T: Real, const N: usize> {
    /// `Σ_w` (diagonal): variance of the measured state's noise, per state, state units²
    /// (m², (m/s)²). Must be > 0 (give a small value for an exact sensor).
    pub state_var: SVector<T, N>,
    /// `Σ_v` (diagonal): variance of the measured derivative's noise, per state, (state
    /// units / s)². Must be > 0.
    pub deriv_var: SVector<T, N>,
    /// `g`: the road's input column of `ẋ` (the `B` of `ẋ = A x + B u`), state units / s per
    /// road unit (quarter car: `[0, k1/m, 0, 0]`).
    pub road_gain: SVector<T, N>,
    /// `σ_u²`: variance of the road input of one sample, road units² (m²); ≥ 0.
    pub road_var: T,
    /// `q`: variance of the parameters' random walk per sample, parameter units²; 0 for
    /// constant parameters, > 0 to track slow changes.
    pub param_walk_var: T,
}

impl<T: Real, const N: usize> EkfNoise<T, N> {
    /// The same standard deviations on every component: `σ_w` on the measured state, `σ_v`
    /// on the measured derivative, `σ_u` on the road (entering through `road_gain`), no
    /// parameter walk.
    pub fn from_sigmas(sigma_w: T, sigma_v: T, road_gain: SVector<T, N>, sigma_u: T) -> Self {
        Self {
            state_var: SVector::repeat(sigma_w * sigma_w),
            deriv_var: SVector::repeat(sigma_v * sigma_v),
            road_gain,
            road_var: sigma_u * sigma_u,
            param_walk_var: T::zero(),
        }
    }

    /// Sets the parameters' random-walk variance per sample `q`.
    pub fn with_param_walk(mut self, q: T) -> Self {
        self.param_walk_var = q;
        self
    }

    pub(super) fn check(&self) -> Result<()> {
        for &v in self.state_var.iter() {
            check_positive("state_var", v)?;
        }
        for &v in self.deriv_var.iter() {
            check_positive("deriv_var", v)?;
        }
        check_finite("road_gain", self.road_gain.as_slice())?;
        check_nonneg("road_var", self.road_var)?;
        check_nonneg("param_walk_var", self.param_walk_var)
    }
}

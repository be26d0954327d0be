//! Options of the Kalman identifiers.

use crate::error::check_nonneg;
use crate::{Real, Result};

#[cfg(doc)]
use super::{KalmanFull, KalmanRows, KalmanShared, RowIdentifier};

/// How the covariance is propagated after a measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CovarianceForm {
    /// `P ← P − P x xᵀ P / (xᵀ P x + r)` (Eq 4.6), kept exactly symmetric: [`KalmanRows`]
    /// and [`KalmanShared`] update only the upper triangle (`P_ab −= (Px)_a (Px)_b / s`,
    /// `a ≤ b`) and mirror it; [`RowIdentifier`] evaluates `P − u uᵀ` with `u = P x / √s`.
    #[default]
    Standard,
    /// Joseph's form `P ← (I − g xᵀ) P (I − g xᵀ)ᵀ + r g gᵀ`, positive semi-definite by
    /// construction (slower; for `f32` over very long runs).
    Joseph,
}

option_names!(CovarianceForm, "form", { Standard => "standard", Joseph => "joseph" });

/// Which of the three Kalman forms to run (they are equal where their assumptions hold).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// Decoupled rows (Eq 6.16–6.18): [`KalmanRows`], each row with its own `p0` and `r`.
    #[default]
    Rows,
    /// One covariance shared by every row (`P_i = r_i Q`): [`KalmanShared`]; needs the same
    /// `r_i / p0_i` on every row.
    Shared,
    /// The stacked filter with a general `R` (Eq 4.3–4.7): [`KalmanFull`].
    Full,
}

option_names!(Mode, "mode", { Rows => "rows", Shared => "shared", Full => "full" });

/// Options common to the Kalman identifiers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KalmanOptions<T> {
    /// Covariance update form.
    pub form: CovarianceForm,
    /// Apply the reinitialization rule of Eq 4.36.
    pub reinit: bool,
    /// `rows` form only: a row stops updating once `tr P_i` falls below this value
    /// (0 = never). A reinitialization brings retired rows back.
    pub retire_below: T,
}

impl<T: Real> Default for KalmanOptions<T> {
    fn default() -> Self {
        Self { form: CovarianceForm::Standard, reinit: false, retire_below: T::zero() }
    }
}

impl<T: Real> KalmanOptions<T> {
    pub(crate) fn validate(&self) -> Result<()> {
        check_nonneg("retire_below", self.retire_below)
    }
}

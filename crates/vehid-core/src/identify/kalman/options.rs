//! Options of the Kalman identifiers.

use crate::error::check_nonneg;
use crate::{Error, Real, Result};

#[cfg(doc)]
use super::{KalmanFull, KalmanRows, KalmanShared, RowIdentifier};

/// How the covariance is propagated after a measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum CovarianceForm {
    /// `P ← P − P x xᵀ P / (xᵀ P x + r)` (Eq 4.6), kept exactly symmetric: [`KalmanRows`]
    /// and [`KalmanShared`] update only the upper triangle (`P_ab −= (Px)_a (Px)_b / s`,
    /// `a ≤ b`) and mirror it; [`RowIdentifier`] evaluates `P − u uᵀ` with `u = P x / √s`.
    #[default]
    Standard,
    /// Joseph's form `P ← (I − g xᵀ) P (I − g xᵀ)ᵀ + r g gᵀ`, symmetric positive
    /// semi-definite by construction when evaluated exactly (slower; it does not protect
    /// against rounding in `f32` over long runs: use `Sqrt`).
    Joseph,
    /// Bierman's square-root form: `P = U D Uᵀ` (`U` unit upper triangular, `D` diagonal) is
    /// updated through its factors and never formed, so `D > 0` (P positive definite) in any
    /// precision, for any `p0` and any scaling of the regressors. Chosen over a QR array form
    /// because it needs no square root and `O(N²)` work per scalar measurement, like the
    /// standard form (Bierman, *Factorization Methods for Discrete Sequential Estimation*,
    /// 1977). The recommended form for `f32` and for long online runs.
    Sqrt,
}

option_names!(CovarianceForm, "form", { Standard => "standard", Joseph => "joseph", Sqrt => "sqrt" });

/// Which of the three Kalman forms to run (they are equal where their assumptions hold).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
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
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct KalmanOptions<T> {
    /// Covariance update form.
    pub form: CovarianceForm,
    /// Apply the reinitialization rule of Eq 4.36. A sample the outlier gate
    /// ([`KalmanOptions::gate`]) leaves out, on any row, reinitializes nothing: an outlier is
    /// not a change of the dynamics (every mode alike).
    pub reinit: bool,
    /// `rows` form only: a row stops updating once `tr P_i` falls below this value
    /// (0 = never). A reinitialization brings retired rows back.
    pub retire_below: T,
    /// Forgetting factor `λ ∈ (0, 1]` (1: none): old samples weigh `λ^age`, so the estimate
    /// tracks parameters that change, with a memory of about `1 / (1 − λ)` samples.
    /// Exponential (`P ← P / λ` after each update) unless [`KalmanOptions::directional`].
    pub forgetting: T,
    /// Forget only in the direction each sample informs (Kulhavý & Kárný 1984, see
    /// [`super::RowIdentifier`]): directions without excitation keep their information, so a
    /// vehicle at rest forgets nothing (the memory per direction is then about
    /// `N / (1 − λ)` samples for `N` equally excited parameters, `N` times the exponential
    /// one). Off: exponential forgetting, bounded by [`KalmanOptions::max_trace`].
    pub directional: bool,
    /// Random-walk drift `q ≥ 0`: after each update `P ← P + q I`, the variance (in squared
    /// parameter units) by which each parameter may drift per sample.
    pub drift: T,
    /// Outlier gate `κ` (0: off): a sample whose recursive residual `w = e √(r/s)` exceeds
    /// `κ σ̂` (`σ̂²` the residual variance estimated from the samples accepted so far) leaves
    /// the row unchanged and is counted ([`super::RowIdentifier::gated`]). Active once the
    /// row has `N + 50` samples behind its estimate of `σ̂`. In [`KalmanShared`] and
    /// [`KalmanFull`] the test is the same per row (`w_i = e_i √(r_i / s_i)`, with `s_i` the
    /// row's innovation variance), and a sample beyond the gate on any row is left out by every
    /// row (they share one covariance / are filtered jointly). On by default in Python
    /// (`gate=6`, every mode); off here, which keeps exact equivalence with least squares.
    pub gate: T,
    /// Huber weighting constant `c` (0: off; 1.345 is the usual choice; [`KalmanRows`] only): a sample with
    /// `|w| > c σ̂` is weighted down, its variance `r` scaled by `|w| / (c σ̂)`, so that its
    /// influence grows linearly instead of quadratically (Huber's M-estimator, applied
    /// recursively).
    pub huber: T,
    /// Wind-up bound: forgetting and drift act only while `tr P` is below this value
    /// (0: the trace when filtering starts, i.e. `tr P(0)` or the trace at the end of an exact
    /// start). Without excitation (`P x = 0`) the estimate cannot move, and this keeps the
    /// covariance from growing without bound meanwhile.
    pub max_trace: T,
}

impl<T: Real> Default for KalmanOptions<T> {
    fn default() -> Self {
        Self {
            form: CovarianceForm::Standard,
            reinit: false,
            retire_below: T::zero(),
            forgetting: T::one(),
            directional: false,
            drift: T::zero(),
            gate: T::zero(),
            huber: T::zero(),
            max_trace: T::zero(),
        }
    }
}

impl<T: Real> KalmanOptions<T> {
    pub(crate) fn validate(&self) -> Result<()> {
        check_nonneg("retire_below", self.retire_below)?;
        if !(self.forgetting.finite() && self.forgetting > T::zero() && self.forgetting <= T::one()) {
            return Err(Error::InvalidArgument {
                arg: "forgetting",
                expected: "a forgetting factor λ in (0, 1] (1: no forgetting; 0.999: memory of about 1000 samples)",
            });
        }
        check_nonneg("drift", self.drift)?;
        check_nonneg("gate", self.gate)?;
        check_nonneg("huber", self.huber)?;
        check_nonneg("max_trace", self.max_trace)
    }

    /// `true` when forgetting or drift is on.
    pub fn tracking(&self) -> bool {
        self.forgetting < T::one() || self.drift > T::zero()
    }
}

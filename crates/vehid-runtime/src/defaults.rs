//! What a run-time caller gets when it does not say, in one place (the Python classes' and the
//! command line's defaults). The core's own defaults are for Rust users, who state what they
//! want (e.g. `KalmanOptions::default()` has no outlier gate).

use crate::build::PREDICTOR;

/// The outlier gate of every identifier: of the Kalman identifiers (every mode), a sample whose
/// recursive residual exceeds 6 estimated standard deviations is left out (for Gaussian noise:
/// one sample in 5·10⁸); of the others, the screen (`vehid_core::identify::Screened`) at the
/// same κ: a prediction error beyond 6 standard deviations, or a value beyond 36 times its root
/// mean square (at most one good sample in 1300 whatever the distribution, by Chebyshev; none
/// for a Gaussian signal); the Kalman identifiers run behind that value test and its held start
/// too. `gate=0` is the identifier alone.
pub const GATE: f64 = 6.0;

/// Standard deviation of the white road noise of the thesis' simulation study (Ch. III.C,
/// Eq 4.25), in the model's input units.
pub const ROAD_SIGMA: f64 = 0.1;

/// Standard deviation of the noise on each measured derivative in the thesis' simulation study
/// (Ch. III.C), in the state's units per second.
pub const DERIV_NOISE: f64 = 0.005;

/// The regression-error variances `r` of a Kalman identifier whose caller gave neither `r` nor
/// the noise levels to compute it from (Eq 4.7): with the exact start (`exact`: no prior), 1
/// per row, which leaves the estimate as it is (least squares: the exact start's estimate does
/// not depend on `r`) and makes `P = (XᵀX)⁻¹`; with a prior none (`None`: the estimate weighs
/// the prior against the data by `r`, which only the caller knows).
pub fn kalman_r(exact: bool) -> Option<Vec<f64>> {
    exact.then(|| vec![1.0])
}

/// The equation-error variance `r` of each equation of the instrumental-variable and
/// bias-compensated identifiers when the caller gives none: 1 (every equation weighed alike).
pub const NOISY_R: f64 = 1.0;

/// The refined instruments' past samples (`lags`) of the instrumental-variable identifiers
/// for samples of `width` values: 6 (what the quarter car's full rows need at 8 % state
/// noise), fewer when the samples are wide, so that the predictor fits in [`PREDICTOR`].
pub fn iv_lags(width: usize) -> usize {
    ((PREDICTOR - 1) / width.max(1)).clamp(1, 6)
}

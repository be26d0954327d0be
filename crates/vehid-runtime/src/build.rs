//! Identifiers built at run-time sizes: each function picks the core type for a linear model's
//! `n` states through the size table, or for a structure's largest parameter group through its
//! bucket, and returns it boxed.

use crate::sizes::dispatch_n;
use vehid_core::identify::{
    boxed_kalman, BatchLeastSquares, BiasCompensatedVec, BoxedIdentifier, DynIdentifier, EkfNoise, Gain,
    IvIdentifierVec, JointEkf, KalmanOptions, KalmanSpec, NoiseEstimatingBclsVec, Refresh, Screened,
    StochasticGradientVec, StructuredGradient, StructuredKalmanVec, StructuredPrior, TwoAxleStructuredConfig,
    TwoAxleStructuredVec,
};
use vehid_core::model::LinearModel;
use vehid_core::structure::Structure;
use vehid_core::{Error, Result};

/// A boxed identifier.
pub type Boxed = Box<dyn DynIdentifier<f64>>;

fn kalman_n<const N: usize>(spec: &KalmanSpec<f64>) -> Result<Boxed> {
    boxed_kalman::<f64, N>(spec)
}

/// The Kalman identifier `spec` describes (`vehid_core::identify::boxed_kalman`) for an
/// `n`-state model.
///
/// # Errors
/// The core's; sizes outside the table.
pub fn kalman(n: usize, spec: &KalmanSpec<f64>) -> Result<Boxed> {
    dispatch_n!(n, kalman_n(spec))
}

fn gradient_n<const N: usize>(rows: &[usize], gain: Gain<f64>, h: &[f64], snv: &[f64], spacing: u32) -> Result<Boxed> {
    Ok(Box::new(StochasticGradientVec::<f64, N>::from_slices(rows, gain, h, snv, spacing)?))
}

/// The stochastic-gradient identifier (`StochasticGradientVec::from_slices`: Eq 2.56,
/// 5.2–5.18) of the unknown `rows` of an `n`-state model.
///
/// # Errors
/// The core's; sizes outside the table.
pub fn gradient(n: usize, rows: &[usize], gain: Gain<f64>, h: &[f64], snv: &[f64], spacing: u32) -> Result<Boxed> {
    dispatch_n!(n, gradient_n(rows, gain, h, snv, spacing))
}

fn batch_n<const N: usize>(rows: &[usize]) -> Result<Boxed> {
    Ok(Box::new(BatchLeastSquares::<f64, N>::new(rows)?))
}

/// Batch least squares over stored samples (Eq 2.14) of the unknown `rows` of an `n`-state
/// model.
///
/// # Errors
/// The core's; sizes outside the table.
pub fn batch(n: usize, rows: &[usize]) -> Result<Boxed> {
    dispatch_n!(n, batch_n(rows))
}

/// Least squares on all samples without storing them (`BatchLeastSquares(model,
/// keep_samples=False)`): the exact-start rows filter of the unknown `rows` of an `n`-state
/// model, which holds `P = (XᵀX)⁻¹` from the first samples that identify it (r = 1: the stored
/// form's unit-noise convention), without a gate, so that its estimate is the normal
/// equations' (Eq 2.14) solved recursively (Eq 2.2–2.4).
///
/// # Errors
/// The core's; sizes outside the table.
pub fn batch_recursive(n: usize, rows: &[usize]) -> Result<Boxed> {
    let spec = KalmanSpec {
        rows: rows.to_vec(),
        p0: vehid_core::identify::Prior::Exact,
        theta0: None,
        r: vec![1.0],
        mode: vehid_core::identify::Mode::Rows,
        opts: KalmanOptions::default(),
    };
    kalman(n, &spec)
}

fn stored<const N: usize>(id: &dyn DynIdentifier<f64>) -> Option<&BatchLeastSquares<f64, N>> {
    unscreened(id).as_any().downcast_ref::<BatchLeastSquares<f64, N>>()
}

/// An identifier behind the outlier screen (`vehid_core::identify::Screened`), as built here.
pub type ScreenedCore = Screened<f64, BoxedIdentifier<f64>>;

/// `inner` behind the outlier screen at `gate` κ (`Screened`: residual and magnitude tests,
/// the first samples held and judged together), its residuals those of `s` (the identifier's
/// structure, or the full rows of a linear model's unknown rows), the estimate re-read after
/// every sample (`Refresh::Every`: a recursive identifier), as the samples grow by a quarter
/// (`Refresh::Geometric`: identifiers that solve on read) or never (`Refresh::Never`: the
/// Kalman identifiers, whose own gate tests the residual); `gate = 0`: `inner` as it is.
///
/// # Errors
/// The core's (a `gate` not finite and ≥ 0).
pub fn screened(inner: Boxed, s: &Structure<f64>, gate: f64, refresh: Refresh) -> Result<Boxed> {
    if gate == 0.0 {
        return Ok(inner);
    }
    Ok(Box::new(ScreenedCore::new(BoxedIdentifier(inner), *s, gate, refresh)?))
}

/// `inner` behind the outlier screen's magnitude test and held start only (`gate = 0`: `inner`
/// as it is), for an identifier whose equations no structure holds (a linear model's rows beyond
/// a structure's capacity: the full car's seven rows of 14 states).
///
/// # Errors
/// The core's (a `gate` not finite and ≥ 0; more than 16 equations).
pub fn screened_magnitudes(inner: Boxed, gate: f64) -> Result<Boxed> {
    if gate == 0.0 {
        return Ok(inner);
    }
    Ok(Box::new(ScreenedCore::magnitudes_only(BoxedIdentifier(inner), gate)?))
}

/// The identifier behind the screen when `id` is screened ([`screened`]), else `id`.
pub fn unscreened(id: &dyn DynIdentifier<f64>) -> &dyn DynIdentifier<f64> {
    match id.as_any().downcast_ref::<ScreenedCore>() {
        Some(s) => s.inner().0.as_ref(),
        None => id,
    }
}

/// The screen's gate κ of `id` (0 when it is not screened).
pub fn screen_gate(id: &dyn DynIdentifier<f64>) -> f64 {
    id.as_any().downcast_ref::<ScreenedCore>().map_or(0.0, |s| s.gate())
}

fn batch_bytes_n<const N: usize>(id: &dyn DynIdentifier<f64>) -> Result<usize> {
    Ok(stored::<N>(id).map_or(0, |b| b.storage_bytes()))
}

/// Bytes the stored samples of a batch least squares take (0 for another identifier).
///
/// # Errors
/// Sizes outside the table.
pub fn batch_storage_bytes(id: &dyn DynIdentifier<f64>) -> Result<usize> {
    dispatch_n!(id.dims().states, batch_bytes_n(id))
}

fn batch_remove_n<const N: usize>(id: &mut Boxed, index: usize) -> Result<()> {
    let Some(batch) = stored::<N>(id.as_ref()) else {
        return Err(Error::InvalidArgument { arg: "self", expected: "a BatchLeastSquares" });
    };
    // On a copy, which replaces the original only when it succeeded (behind its screen, if any:
    // the screen keeps its scales and counts).
    let mut copy = batch.clone();
    copy.remove(index)?;
    *id = match id.as_any().downcast_ref::<ScreenedCore>() {
        Some(s) => {
            let mut s = s.clone();
            *s.inner_mut() = BoxedIdentifier(Box::new(copy));
            Box::new(s)
        }
        None => Box::new(copy),
    };
    Ok(())
}

/// Removes the stored sample `index` of a batch least squares (`BatchLeastSquares::remove`);
/// all or nothing.
///
/// # Errors
/// [`Error::InvalidArgument`] for another identifier; the core's.
pub fn batch_remove(id: &mut Boxed, index: usize) -> Result<()> {
    dispatch_n!(id.dims().states, batch_remove_n(id, index))
}

// ---- Identifiers on a Structure: the filters are sized by a bucket of the structure's
// largest parameter group (2, 4, 8, 16 or 32), one compiled type per bucket.

/// The bucket of `largest` parameters: 2, 4, 8, 16 or 32.
fn bucket_of(largest: usize) -> usize {
    match largest {
        0..=2 => 2,
        3..=4 => 4,
        5..=8 => 8,
        9..=16 => 16,
        _ => 32,
    }
}

/// Calls `$f::<P>$args` for the bucket `$p` (2, 4, 8, 16, else 32).
macro_rules! dispatch_p {
    ($p:expr, $f:ident $args:tt) => {
        match $p {
            2 => $f::<2> $args,
            4 => $f::<4> $args,
            8 => $f::<8> $args,
            16 => $f::<16> $args,
            _ => $f::<32> $args,
        }
    };
}

/// Capacity of the refined instruments' predictor (`IVIdentifier(lags=...)`): `lags × (2n + m)
/// + 1 ≤ PREDICTOR` (the predictor keeps a matrix of this size squared).
pub const PREDICTOR: usize = 64;

fn structured_p<const P: usize>(
    s: Structure<f64>,
    p0: StructuredPrior<'_, f64>,
    theta0: Option<&[f64]>,
    r: &[f64],
    opts: KalmanOptions<f64>,
) -> Result<Boxed> {
    Ok(Box::new(StructuredKalmanVec::<f64, P>::new(s, p0, theta0, r, opts)?))
}

/// The recursive least-squares (Kalman) identifier of a structure (`StructuredKalmanVec`:
/// Eq 2.2–2.4, 6.16–6.18), its filters sized for its largest parameter group.
///
/// # Errors
/// The core's.
pub fn structured_kalman(
    s: Structure<f64>,
    p0: StructuredPrior<'_, f64>,
    theta0: Option<&[f64]>,
    r: &[f64],
    opts: KalmanOptions<f64>,
) -> Result<Boxed> {
    dispatch_p!(bucket_of(s.partition().largest()), structured_p(s, p0, theta0, r, opts))
}

fn structured_gradient_p<const P: usize>(s: Structure<f64>, gain: Gain<f64>, h: &[f64], spacing: u32) -> Result<Boxed> {
    Ok(Box::new(StructuredGradient::<f64, P>::new(s, gain, h, None, spacing)?))
}

/// The stochastic-gradient identifier of a structure (`StructuredGradient`; weights `h`: one,
/// or one per parameter), sized for all its parameters.
///
/// # Errors
/// The core's.
pub fn structured_gradient(s: Structure<f64>, gain: Gain<f64>, h: &[f64], spacing: u32) -> Result<Boxed> {
    dispatch_p!(bucket_of(s.params()).max(4), structured_gradient_p(s, gain, h, spacing))
}

/// The auxiliary model of `IVIdentifier(instruments="model")`: sample interval `dt` (s), RK4
/// steps per sample, samples between refreshes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelInstrumentSettings {
    /// Sample interval, s.
    pub dt: f64,
    /// RK4 steps per sample.
    pub substeps: u32,
    /// Samples between refreshes of the auxiliary model.
    pub refresh: usize,
}

fn iv_pq<const P: usize, const Q: usize>(
    s: Structure<f64>,
    delay: usize,
    lags: usize,
    p0: StructuredPrior<'_, f64>,
    theta0: Option<&[f64]>,
    r: &[f64],
) -> Result<Boxed> {
    Ok(Box::new(IvIdentifierVec::<f64, P, Q>::new(s, delay, p0, theta0, r)?.with_lags(lags)?))
}

fn iv_p<const P: usize>(
    s: Structure<f64>,
    delay: usize,
    lags: usize,
    p0: StructuredPrior<'_, f64>,
    theta0: Option<&[f64]>,
    r: &[f64],
    model: Option<ModelInstrumentSettings>,
) -> Result<Boxed> {
    if let Some(a) = model {
        let iv = IvIdentifierVec::<f64, P, 0>::new(s, delay, p0, theta0, r)?;
        return Ok(Box::new(iv.with_model_instruments(a.dt, a.substeps, a.refresh, None)?));
    }
    if lags == 0 {
        iv_pq::<P, 0>(s, delay, lags, p0, theta0, r)
    } else {
        iv_pq::<P, PREDICTOR>(s, delay, lags, p0, theta0, r)
    }
}

/// Recursive instrumental variables on a structure (`IvIdentifierVec`: Söderström & Stoica
/// §8): instruments the regressors `delay` samples back, refined by a predictor over `lags`
/// past samples, or an auxiliary model's noise-free states (`model`).
///
/// # Errors
/// The core's.
#[allow(clippy::too_many_arguments)]
pub fn iv(
    s: Structure<f64>,
    delay: usize,
    lags: usize,
    p0: StructuredPrior<'_, f64>,
    theta0: Option<&[f64]>,
    r: &[f64],
    model: Option<ModelInstrumentSettings>,
) -> Result<Boxed> {
    dispatch_p!(bucket_of(s.partition().largest()), iv_p(s, delay, lags, p0, theta0, r, model))
}

fn bias_compensated_p<const P: usize>(s: Structure<f64>, sw: &[f64], sv: &[f64], r: &[f64]) -> Result<Boxed> {
    Ok(Box::new(BiasCompensatedVec::<f64, P>::new(s, sw, sv, r)?))
}

/// Bias-compensated least squares on a structure with known state-noise covariance `sw` and
/// derivative-noise covariance `sv` (`BiasCompensatedVec`: Söderström 2007 §4.3).
///
/// # Errors
/// The core's.
pub fn bias_compensated(s: Structure<f64>, sw: &[f64], sv: &[f64], r: &[f64]) -> Result<Boxed> {
    dispatch_p!(bucket_of(s.partition().largest()), bias_compensated_p(s, sw, sv, r))
}

fn noise_estimating_pq<const P: usize, const Q: usize>(
    s: Structure<f64>,
    delay: usize,
    lags: usize,
    sv: &[f64],
    r: &[f64],
) -> Result<Boxed> {
    let iv = IvIdentifierVec::<f64, P, Q>::new(s, delay, StructuredPrior::Exact, None, r)?.with_lags(lags)?;
    Ok(Box::new(NoiseEstimatingBclsVec::<f64, P, Q>::new(iv, sv)?))
}

fn noise_estimating_p<const P: usize>(
    s: Structure<f64>,
    delay: usize,
    lags: usize,
    sv: &[f64],
    r: &[f64],
) -> Result<Boxed> {
    if lags == 0 {
        noise_estimating_pq::<P, 0>(s, delay, lags, sv, r)
    } else {
        noise_estimating_pq::<P, PREDICTOR>(s, delay, lags, sv, r)
    }
}

/// Bias-compensated least squares with the state-noise covariance estimated from the data
/// (`NoiseEstimatingBclsVec`: Zheng 1998, 2002), its instrumental start with `delay` and `lags`.
///
/// # Errors
/// The core's.
pub fn noise_estimating(s: Structure<f64>, delay: usize, lags: usize, sv: &[f64], r: &[f64]) -> Result<Boxed> {
    dispatch_p!(bucket_of(s.partition().largest()), noise_estimating_p(s, delay, lags, sv, r))
}

/// The group sizes `P` of the road cancellation on a structure that are built (the largest
/// group with the two wheel equations' merged: 4 for the half car's physical structure with
/// m1, m2, l1, l2 known, 16 for its full rows).
pub const TWO_AXLE_SIZES: [usize; 3] = [4, 8, 16];

fn two_axle_structured_p<const P: usize>(
    s: Structure<f64>,
    car: &LinearModel<f64, 8, 2>,
    d: usize,
    cfg: TwoAxleStructuredConfig<f64>,
) -> Result<Boxed> {
    Ok(Box::new(TwoAxleStructuredVec::<f64, P>::new(s, car, d, cfg)?))
}

/// Road cancellation on a structure of the half car `car` (`TwoAxleStructuredVec`: Eq 6.1–6.9),
/// the rear axle `d` samples behind the front, built for the smallest of [`TWO_AXLE_SIZES`]
/// that holds its largest group once the core has merged the two wheel equations' groups (the
/// core says which with a capacity error).
///
/// # Errors
/// The core's; [`Error::Capacity`] (`arg` "P") naming the size needed when even the largest is
/// too small.
pub fn two_axle_structured(
    s: Structure<f64>,
    car: &LinearModel<f64, 8, 2>,
    d: usize,
    cfg: TwoAxleStructuredConfig<f64>,
) -> Result<Boxed> {
    let mut built = Err(Error::Capacity { arg: "P", needed: 0, capacity: 0 });
    for p in TWO_AXLE_SIZES {
        built = match p {
            4 => two_axle_structured_p::<4>(s, car, d, cfg),
            8 => two_axle_structured_p::<8>(s, car, d, cfg),
            _ => two_axle_structured_p::<16>(s, car, d, cfg),
        };
        if !matches!(built, Err(Error::Capacity { arg: "P", .. })) {
            break;
        }
    }
    built
}

/// The states of the joint extended Kalman filters that are built (the quarter car's).
pub const EKF_STATES: usize = 4;

/// The sizes `D` (= 4 + params + 1) of the joint extended Kalman filters that are built: the
/// quarter car's structures with 3 and 4 parameters and its full rows (8).
pub const EKF_SIZES: [usize; 3] = [8, 9, 13];

#[allow(clippy::too_many_arguments)]
fn joint_ekf_d<const D: usize>(
    s: Structure<f64>,
    theta0: &[f64],
    p0: &[f64],
    x0_var: f64,
    noise: EkfNoise<f64, EKF_STATES>,
    dt: f64,
    substeps: u32,
) -> Result<Boxed> {
    Ok(Box::new(JointEkf::<f64, EKF_STATES, D>::new(s, theta0, p0, x0_var, noise, dt, substeps)?))
}

/// The joint extended Kalman filter of states, parameters and road (`JointEkf`: Ljung 1979) on
/// a complete structure of [`EKF_STATES`] states whose `D` is one of [`EKF_SIZES`].
///
/// # Errors
/// [`Error::Capacity`] (`arg` "D") for another size; the core's.
pub fn joint_ekf(
    s: Structure<f64>,
    theta0: &[f64],
    p0: &[f64],
    x0_var: f64,
    noise: EkfNoise<f64, EKF_STATES>,
    dt: f64,
    substeps: u32,
) -> Result<Boxed> {
    match s.states() + s.params() + 1 {
        _ if s.states() != EKF_STATES => Err(Error::Shape { arg: "states", expected: EKF_STATES, got: s.states() }),
        8 => joint_ekf_d::<8>(s, theta0, p0, x0_var, noise, dt, substeps),
        9 => joint_ekf_d::<9>(s, theta0, p0, x0_var, noise, dt, substeps),
        13 => joint_ekf_d::<13>(s, theta0, p0, x0_var, noise, dt, substeps),
        d => Err(Error::Capacity { arg: "D", needed: d, capacity: 13 }),
    }
}

// ---- Reading a built identifier of a kind whose sizes are listed above, for the settings
// only that kind has (the binding's getters): each enumerates the built sizes here, so that
// no other crate lists them.

/// A road-cancelling identifier on a structure, as built by [`two_axle_structured`].
pub type TwoAxleStructuredCore<const P: usize> = TwoAxleStructuredVec<f64, P>;

/// A joint extended Kalman filter, as built by [`joint_ekf`].
pub type JointEkfCore<const D: usize> = JointEkf<f64, EKF_STATES, D>;

/// `Some($body)` with `$id` bound to the [`two_axle_structured`] core behind the
/// `&dyn DynIdentifier` `$inner` (any of [`TWO_AXLE_SIZES`]); `None` for another identifier.
#[macro_export]
macro_rules! with_two_axle_structured {
    ($inner:expr, |$id:ident| $body:expr) => {{
        let boxed: &$crate::build::Boxed = &$inner;
        let any = $crate::build::unscreened(boxed.as_ref()).as_any();
        if let Some($id) = any.downcast_ref::<$crate::build::TwoAxleStructuredCore<4>>() {
            Some($body)
        } else if let Some($id) = any.downcast_ref::<$crate::build::TwoAxleStructuredCore<8>>() {
            Some($body)
        } else if let Some($id) = any.downcast_ref::<$crate::build::TwoAxleStructuredCore<16>>() {
            Some($body)
        } else {
            None
        }
    }};
}

/// `Some($body)` with `$id` bound to the [`joint_ekf`] core behind the `&dyn DynIdentifier`
/// `$inner` (any of [`EKF_SIZES`]); `None` for another identifier.
#[macro_export]
macro_rules! with_joint_ekf {
    ($inner:expr, |$id:ident| $body:expr) => {{
        let any = $inner.as_any();
        if let Some($id) = any.downcast_ref::<$crate::build::JointEkfCore<8>>() {
            Some($body)
        } else if let Some($id) = any.downcast_ref::<$crate::build::JointEkfCore<9>>() {
            Some($body)
        } else if let Some($id) = any.downcast_ref::<$crate::build::JointEkfCore<13>>() {
            Some($body)
        } else {
            None
        }
    }};
}

/// The instruments `(delay, lags)` of a [`noise_estimating`] core, after writing its estimated
/// state-noise variances into `var` when given; `None` for another identifier (e.g. the plain
/// [`bias_compensated`] one).
pub fn noise_estimating_instruments(
    inner: &dyn DynIdentifier<f64>,
    var: Option<&mut [f64]>,
) -> Option<Result<(usize, usize)>> {
    fn read<const P: usize, const Q: usize>(
        id: &NoiseEstimatingBclsVec<f64, P, Q>,
        var: Option<&mut [f64]>,
    ) -> Result<(usize, usize)> {
        if let Some(v) = var {
            id.state_noise_var_into(v)?;
        }
        Ok((id.instrumental().delay(), id.instrumental().lags()))
    }
    let any = unscreened(inner).as_any();
    macro_rules! try_p {
        ($($p:literal),*) => {$(
            if let Some(id) = any.downcast_ref::<NoiseEstimatingBclsVec<f64, $p, 0>>() {
                return Some(read(id, var));
            }
            if let Some(id) = any.downcast_ref::<NoiseEstimatingBclsVec<f64, $p, PREDICTOR>>() {
                return Some(read(id, var));
            }
        )*};
    }
    try_p!(2, 4, 8, 16, 32);
    None
}

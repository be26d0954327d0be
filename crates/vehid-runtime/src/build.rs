//! Identifiers of linear models built at run-time sizes: each function picks the core type for
//! the model's `n` states through the size table and returns it boxed.

use crate::sizes::dispatch_n;
use vehid_core::identify::{boxed_kalman, BatchLeastSquares, DynIdentifier, Gain, KalmanSpec, StochasticGradientVec};
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

fn stored<const N: usize>(id: &dyn DynIdentifier<f64>) -> Option<&BatchLeastSquares<f64, N>> {
    id.as_any().downcast_ref::<BatchLeastSquares<f64, N>>()
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
    // On a copy, which replaces the original only when it succeeded.
    let mut copy = batch.clone();
    copy.remove(index)?;
    *id = Box::new(copy);
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

//! [`Monitor`]: what the quarter, half and full car's monitors share, and [`fit_rows`], a
//! block of samples through any of them, all or nothing.

use super::event::{Constant, Event};
use super::{FullHealthMonitor, HalfHealthMonitor, HealthMonitor};
#[cfg(feature = "alloc")]
use crate::identify::FitError;
use crate::model::HalfConstant;
use crate::sim::FullConstant;
#[cfg(feature = "alloc")]
use crate::Error;
use crate::{Real, Result};

/// A health monitor: one sample of its channels in, at most one event out (each monitor's
/// `update`: transactional, a rejected sample changes nothing).
pub trait Monitor<T: Real>: Clone {
    /// What an event names (a quarter car's, half car's or full car's constant).
    type Constant: Copy;
    /// One sample `y` (the monitor's channels, in their units).
    ///
    /// # Errors
    /// The monitor's: a sample of the wrong length or with an infinite value.
    fn update(&mut self, y: &[T]) -> Result<Option<Event<T, Self::Constant>>>;
}

impl<T: Real> Monitor<T> for HealthMonitor<T> {
    type Constant = Constant;
    #[inline]
    fn update(&mut self, y: &[T]) -> Result<Option<Event<T>>> {
        HealthMonitor::update(self, y)
    }
}

impl<T: Real> Monitor<T> for HalfHealthMonitor<T> {
    type Constant = HalfConstant;
    #[inline]
    fn update(&mut self, y: &[T]) -> Result<Option<Event<T, HalfConstant>>> {
        HalfHealthMonitor::update(self, y)
    }
}

impl<T: Real> Monitor<T> for FullHealthMonitor<T> {
    type Constant = FullConstant;
    #[inline]
    fn update(&mut self, y: &[T]) -> Result<Option<Event<T, FullConstant>>> {
        FullHealthMonitor::update(self, y)
    }
}

/// Runs `mon` over the samples of `data` (rows of `channels` values, row-major), appending
/// each event to `events`; all or nothing: when a sample is rejected, or `interrupt` (asked
/// every `check_every` samples, 0: never) returns `true` ([`Error::Interrupted`]), the monitor
/// is restored as it was before the call (a copy taken first) and `events` as well, and the
/// error names the sample's index in `data`.
///
/// # Errors
/// [`Error::Shape`] (no sample index) when `data` is not whole rows of `channels` values;
/// the rejected sample's error or the interrupt, with its index.
///
/// # Examples
/// ```
/// use vehid_core::health::{fit_rows, HealthConfig, HealthMonitor};
/// use vehid_core::model::QuarterCar;
/// let mut mon = HealthMonitor::new(HealthConfig::new(0.005, QuarterCar::<f64>::passenger()))?;
/// let mut events = Vec::new();
/// let data = [0.1, -0.3, 0.002, 0.2, f64::INFINITY, 0.001];
/// let err = fit_rows(&mut mon, &data, 3, &mut events, 0, &mut || false).unwrap_err();
/// assert_eq!(err.sample, Some(1)); // the second sample; the first is undone too
/// assert_eq!(mon.samples(), 0);
/// # Ok::<(), vehid_core::Error>(())
/// ```
#[cfg(feature = "alloc")]
pub fn fit_rows<T: Real, M: Monitor<T>>(
    mon: &mut M,
    data: &[T],
    channels: usize,
    events: &mut alloc::vec::Vec<Event<T, M::Constant>>,
    check_every: usize,
    interrupt: &mut dyn FnMut() -> bool,
) -> core::result::Result<(), FitError> {
    if channels == 0 || data.len() % channels != 0 {
        let expected = channels.max(1) * (data.len() / channels.max(1) + 1);
        return Err(FitError { sample: None, error: Error::Shape { arg: "y", expected, got: data.len() } });
    }
    let (start, had) = (mon.clone(), events.len());
    let mut to_check = check_every;
    for (k, row) in data.chunks_exact(channels).enumerate() {
        if check_every > 0 {
            to_check -= 1;
            if to_check == 0 {
                to_check = check_every;
                if interrupt() {
                    *mon = start;
                    events.truncate(had);
                    return Err(FitError { sample: Some(k), error: Error::Interrupted });
                }
            }
        }
        match mon.update(row) {
            Ok(Some(e)) => events.push(e),
            Ok(None) => {}
            Err(error) => {
                *mon = start;
                events.truncate(had);
                return Err(FitError { sample: Some(k), error });
            }
        }
    }
    Ok(())
}

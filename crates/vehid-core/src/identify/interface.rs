//! The identifier interface: one trait that every identifier implements.
//!
//! An identifier consumes samples — the measured state `x = r(k)` (`n` values), the measured
//! derivative `z(k)` (`n` values) and, for models with measured inputs, `u(k)` (`m` values) —
//! and estimates a parameter vector from the equations it identifies (for a
//! [`crate::model::LinearModel`], the unknown rows of `A`, Eq 2.2–2.4: one equation per unknown
//! row, `z_i(k) = x(k)ᵀ θ_i + ε_i(k)`, and the parameters are the rows stacked row-major).
//!
//! [`Identifier::update_into`] is the one per-sample entry point. It allocates nothing and is
//! transactional: a rejected sample returns an error and leaves the identifier exactly as it
//! was. [`Identifier::fit`] runs a batch of samples with the same guarantee for the whole
//! batch (all or nothing), calling back after every accepted sample so that a caller can
//! record history or stop. Everything else (estimates, covariance, counters) is read through
//! the trait too, so a consumer (the Python bindings, the thesis reproduction, a health
//! monitor) writes no adapter per identifier.
//!
//! The trait works on slices so that it is object-safe: with `alloc`, [`DynIdentifier`] is
//! the boxed form used where the identifier is chosen at run time.

use super::buffers::with_innovations;
use super::Samples;
use crate::{Error, Real, Result};
use core::ops::ControlFlow;

/// The sizes of an identification problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dims {
    /// States `n`: the length of `x` and of `z` in a sample.
    pub states: usize,
    /// Measured inputs `m`: the length of `u` in a sample (0 in the thesis' setting, where
    /// the road input is never measured).
    pub inputs: usize,
    /// Identified equations: one innovation per equation and sample.
    pub equations: usize,
    /// Estimated parameters.
    pub params: usize,
}

/// Why [`Identifier::fit`] stopped. The identifier is as it was before the call.
#[derive(Debug, Clone, PartialEq)]
pub struct FitError {
    /// Index of the sample that was rejected (or at which the fit was stopped); `None` when
    /// the batch as a whole was refused before any sample (wrong shape, no memory).
    pub sample: Option<usize>,
    /// The reason.
    pub error: Error,
}

impl core::fmt::Display for FitError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.sample {
            Some(i) => write!(f, "sample {i} was rejected ({}); the identifier is unchanged", self.error),
            None => write!(f, "{}; the identifier is unchanged", self.error),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for FitError {}

/// Innovations of up to this many equations live on the stack during [`Identifier::fit`]
/// (more need `alloc`).
pub const FIT_STACK_EQUATIONS: usize = 32;

/// What an identifier is: samples in, parameters (and their uncertainty) out.
///
/// Implemented by every identifier of [`crate::identify`]. The per-sample entry point
/// [`Identifier::update_into`] allocates nothing and is transactional. Estimates come out
/// through caller buffers, so the trait is usable without `alloc`.
///
/// # Examples
/// Generic code over any identifier:
/// ```
/// use vehid_core::identify::{Identifier, KalmanIdentifier, Samples, StochasticGradient, Gain};
/// use vehid_core::model::QuarterCar;
/// use vehid_core::sim::{SimConfig, Simulator};
///
/// fn estimate<I: Identifier<f64> + Clone>(id: &mut I, x: &[f64], z: &[f64]) -> [f64; 8] {
///     let data = Samples::new(4, 0, x, z, &[]).unwrap();
///     id.fit(&data, |_, _, _| core::ops::ControlFlow::Continue(())).unwrap();
///     let mut theta = [0.0; 8];
///     id.params_into(&mut theta).unwrap();
///     theta
/// }
///
/// let car = QuarterCar::<f64>::thesis();
/// let mut sim = Simulator::new(car.model(), SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005), 1)?;
/// let (mut x, mut z) = (vec![], vec![]);
/// for _ in 0..2000 {
///     let s = sim.next_sample();
///     x.extend_from_slice(s.r.as_slice());
///     z.extend_from_slice(s.z.as_slice());
/// }
/// let r = car.model().row_noise_var::<2>(0.1, 0.005)?;
/// let mut kf = KalmanIdentifier::<f64, 4, 2>::new(car.unknown_rows(), 1000.0, r)?;
/// let mut sg = StochasticGradient::<f64, 4, 2>::new(car.unknown_rows(), Gain::Venter { p: 0.51 }, 0.4)?;
/// let (a, b) = (estimate(&mut kf, &x, &z), estimate(&mut sg, &x, &z));
/// assert!(a.iter().chain(&b).all(|v| v.is_finite()));
/// # Ok::<(), vehid_core::Error>(())
/// ```
pub trait Identifier<T: Real> {
    /// The problem's sizes.
    fn dims(&self) -> Dims;

    /// The state whose derivative each equation identifies, in the order of the innovations
    /// (for a linear model: its unknown rows of `A`, 0-based).
    fn rows(&self) -> &[usize];

    /// One sample: measured state `x` (`n`), measured derivative `z` (`n`), measured inputs
    /// `u` (`m`; empty when the model has none). Writes one innovation per equation into
    /// `e` (the prediction error before the update). No allocation.
    ///
    /// # Errors
    /// [`Error::Shape`] for wrong lengths, [`Error::NonFinite`] for NaN/inf,
    /// [`Error::Singular`] or an overflow error when the step cannot be taken. The identifier
    /// is unchanged after any error.
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()>;

    /// The current parameter estimate (for a linear model: `θ̂`, the unknown rows of `A`
    /// row-major) into `out` (`dims().params` values).
    ///
    /// # Errors
    /// [`Error::Shape`] for a wrong length; an estimator that cannot give an estimate yet
    /// (batch least squares before the data span every direction) says why.
    fn params_into(&self, out: &mut [T]) -> Result<()>;

    /// Samples accepted so far.
    fn samples(&self) -> u64;

    /// The parameter covariance `P` (`params × params`, row-major) into `out`: the
    /// posterior covariance of the estimate under the identifier's noise model.
    ///
    /// # Errors
    /// [`Error::Unsupported`] for an identifier without one (the stochastic gradient);
    /// [`Error::Shape`] for a wrong length.
    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        let _ = out;
        Err(Error::Unsupported { what: "a parameter covariance (this identifier keeps none)" })
    }

    /// The equations' noise covariance `R` in use (`equations × equations`, row-major).
    ///
    /// # Errors
    /// [`Error::Unsupported`] for an identifier without one; [`Error::Shape`] for a wrong length.
    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        let _ = out;
        Err(Error::Unsupported { what: "a noise covariance R (this identifier uses none)" })
    }

    /// Each identified equation's residual statistics (statsmodels' `ssr` and `nobs`): into
    /// `ssr` the sum of its squared recursive residuals `Σ e_k² r/s_k` in the equation's own
    /// units (after an exact start: the least-squares residual sum of squares on every sample
    /// so far; decayed like the estimate under forgetting), into `nobs` the samples behind it
    /// (an effective count `Σ λ^j` under forgetting). One value per equation each. A sample
    /// the outlier gate left out counts with its residual Winsorized at the gate, `κ² σ̂²`
    /// (the scale the gate judges by; `KalmanOptions::gate`), so that `ssr / (nobs − N)` errs
    /// on the large side when outliers were gated.
    ///
    /// # Errors
    /// [`Error::Unsupported`] for an identifier that keeps none; [`Error::Shape`].
    fn residuals_into(&self, ssr: &mut [T], nobs: &mut [T]) -> Result<()> {
        let _ = (ssr, nobs);
        Err(Error::Unsupported {
            what: "residual statistics (this identifier keeps none: use KalmanIdentifier in mode rows or \
                   BatchLeastSquares)",
        })
    }

    /// Which parameters and equations form independent groups (no equation couples two
    /// groups; each group has its own block of `P` and one noise scale): `group_of_param`
    /// (`params` values) and `group_of_eq` (`equations` values). The default: equation `i` with
    /// the `i`-th block of `params / equations` parameters (the rows of a linear model).
    ///
    /// # Errors
    /// [`Error::Shape`] for wrong lengths.
    fn groups_into(&self, group_of_param: &mut [usize], group_of_eq: &mut [usize]) -> Result<()> {
        let d = self.dims();
        if group_of_param.len() != d.params {
            return Err(Error::Shape { arg: "group_of_param", expected: d.params, got: group_of_param.len() });
        }
        if group_of_eq.len() != d.equations {
            return Err(Error::Shape { arg: "group_of_eq", expected: d.equations, got: group_of_eq.len() });
        }
        let per = d.params / d.equations.max(1);
        for (j, g) in group_of_param.iter_mut().enumerate() {
            *g = j / per.max(1);
        }
        for (i, g) in group_of_eq.iter_mut().enumerate() {
            *g = i;
        }
        Ok(())
    }

    /// `tr P`, when the identifier keeps a covariance (Eq 4.36 compares it with the innovations).
    fn trace(&self) -> Option<T> {
        None
    }

    /// Reinitializations (Eq 4.36) so far.
    fn reinit_count(&self) -> u32 {
        0
    }

    /// Covariance resetting (Goodwin & Sin, *Adaptive Filtering, Prediction and Control*,
    /// 1984, §3.3): `P ← p0 I` around the current estimate, which becomes the prior mean
    /// (a filter that had seen nothing but a sample `θ̂` with variance `p0`). The way back for
    /// an identifier whose covariance has lost positive definiteness (every sample refused),
    /// and a way to let it move again after a sudden change. `θ̂`, the noise variances, the
    /// residual statistics and the counts are kept; rows retired by `retire_below` update
    /// again. `p0` in the parameters' units² (`(1/s)²` for entries of `A`).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `p0` not finite and > 0; [`Error::Unsupported`] for an
    /// identifier without a covariance, or one still in its exact start (no estimate to keep
    /// yet). The identifier is unchanged after an error.
    fn reset_covariance(&mut self, p0: T) -> Result<()> {
        let _ = p0;
        Err(Error::Unsupported { what: "reset_covariance (this identifier keeps no covariance to reset)" })
    }

    /// Keeps the identifier's time when a wrapper leaves the current sample out (the outlier
    /// screen, [`super::Screened`]): the next sample is the one after it. Only identifiers that
    /// pair samples by their place in time act on it: the two-axle identifiers advance their
    /// road-point index, so that the rear axle stays paired with the front axle's sample one
    /// wheelbase earlier (the skipped point pairs with nothing). The default: nothing. No
    /// allocation; it changes no estimate.
    fn skip_sample(&mut self) {}

    /// Samples each equation gated as outliers (see `KalmanOptions::gate`), one count per
    /// equation into `out`; zeros for an identifier without a gate.
    ///
    /// # Errors
    /// [`Error::Shape`] for a wrong length.
    fn gated_into(&self, out: &mut [u64]) -> Result<()> {
        let k = self.dims().equations;
        if out.len() != k {
            return Err(Error::Shape { arg: "out", expected: k, got: out.len() });
        }
        out.fill(0);
        Ok(())
    }

    /// Runs every sample of `data` in order; after each accepted sample `k` calls
    /// `each(k, self, innovations)`, which may stop the fit by returning
    /// [`ControlFlow::Break`] with the reason.
    ///
    /// All or nothing: when a sample is rejected or `each` stops the fit, the identifier is
    /// restored to its state before the call and the sample's index is reported. The
    /// default implementation keeps a copy of the identifier (one clone per call; nothing
    /// per sample); identifiers with a cheaper way to roll back (batch least squares)
    /// override it.
    ///
    /// # Errors
    /// [`FitError`] with the rejected sample and the reason.
    fn fit<F>(&mut self, data: &Samples<'_, T>, mut each: F) -> core::result::Result<(), FitError>
    where
        Self: Sized + Clone,
        F: FnMut(usize, &Self, &[T]) -> ControlFlow<Error>,
    {
        let dims = self.dims();
        data.check(dims).map_err(|error| FitError { sample: None, error })?;
        with_innovations(dims.equations, |e| {
            let before = self.clone();
            for (k, (x, z, u)) in data.iter().enumerate() {
                let step = match self.update_into(x, z, u, e) {
                    Ok(()) => each(k, self, e),
                    Err(err) => ControlFlow::Break(err),
                };
                if let ControlFlow::Break(error) = step {
                    *self = before;
                    return Err(FitError { sample: Some(k), error });
                }
            }
            Ok(())
        })
    }
}

/// Options of [`DynIdentifier::fit_dyn`].
#[cfg(feature = "alloc")]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FitOptions {
    /// Append the parameters to the history every this many samples (0: never).
    pub record_every: usize,
    /// Call the interrupt check every this many samples (0: never).
    pub check_every: usize,
}

/// The boxed, run-time-chosen form of [`Identifier`] (requires `alloc`): what the Python
/// bindings hold. Implemented for every identifier that is `Clone + Send + Sync`.
#[cfg(feature = "alloc")]
pub trait DynIdentifier<T: Real>: Identifier<T> + super::Persist + Send + Sync + core::fmt::Debug {
    /// [`Identifier::fit`] with the parameters appended to `history` every
    /// `opts.record_every` samples (the space is reserved up front, fallibly) and
    /// `interrupt()` asked every `opts.check_every` samples whether to stop (it returns
    /// `true` to stop; the fit then fails with [`Error::Interrupted`] and changes nothing).
    /// A record where the estimate does not exist yet (`params_into` fails with
    /// [`Error::RankDeficient`] or [`Error::Singular`]) is NaN.
    ///
    /// # Errors
    /// As [`Identifier::fit`]; [`Error::OutOfMemory`] when the history cannot be reserved.
    fn fit_dyn(
        &mut self,
        data: &Samples<'_, T>,
        opts: FitOptions,
        history: &mut alloc::vec::Vec<T>,
        interrupt: &mut dyn FnMut() -> bool,
    ) -> core::result::Result<(), FitError>;

    /// A boxed copy.
    fn clone_box(&self) -> alloc::boxed::Box<dyn DynIdentifier<T>>;

    /// The concrete identifier, for the few settings only one kind has.
    fn as_any(&self) -> &dyn core::any::Any;
}

#[cfg(feature = "alloc")]
impl<T, I> DynIdentifier<T> for I
where
    T: Real,
    I: Identifier<T> + super::Persist + Clone + Send + Sync + core::fmt::Debug + 'static,
{
    fn fit_dyn(
        &mut self,
        data: &Samples<'_, T>,
        opts: FitOptions,
        history: &mut alloc::vec::Vec<T>,
        interrupt: &mut dyn FnMut() -> bool,
    ) -> core::result::Result<(), FitError> {
        let params = self.dims().params;
        let every = opts.record_every;
        let records = data.len().checked_div(every).unwrap_or(0);
        let start = history.len();
        let need = records.checked_mul(params).ok_or(FitError {
            sample: None,
            error: Error::OutOfMemory { what: "the history (record_every)", bytes: usize::MAX },
        })?;
        history.try_reserve_exact(need).map_err(|_| FitError {
            sample: None,
            error: Error::OutOfMemory {
                what: "the history (raise record_every)",
                bytes: need.saturating_mul(core::mem::size_of::<T>()),
            },
        })?;
        // Countdowns, not `k % every`: a division per sample would cost more than the
        // bookkeeping it guards.
        let check = opts.check_every;
        let (mut to_record, mut to_check) = (every, check);
        let res = self.fit(data, |_, id, _| {
            if every > 0 {
                to_record -= 1;
                if to_record == 0 {
                    to_record = every;
                    let at = history.len();
                    history.resize(at + params, T::zero());
                    match id.params_into(&mut history[at..]) {
                        Ok(()) => {}
                        // Not identified yet (too few samples), or an estimate solved on read
                        // whose matrix is not yet invertible (a bias-compensated one early on):
                        // recorded as NaN, as the estimate does not exist.
                        Err(Error::RankDeficient { .. } | Error::Singular { .. }) => {
                            history[at..].fill(T::of(f64::NAN))
                        }
                        Err(e) => return ControlFlow::Break(e),
                    }
                }
            }
            if check > 0 {
                to_check -= 1;
                if to_check == 0 {
                    to_check = check;
                    if interrupt() {
                        return ControlFlow::Break(Error::Interrupted);
                    }
                }
            }
            ControlFlow::Continue(())
        });
        if res.is_err() {
            history.truncate(start);
        }
        res
    }

    fn clone_box(&self) -> alloc::boxed::Box<dyn DynIdentifier<T>> {
        alloc::boxed::Box::new(self.clone())
    }

    fn as_any(&self) -> &dyn core::any::Any {
        self
    }
}

/// Inside an `impl Identifier<T> for W`, the methods that read or reset the estimate, forwarded
/// to the identifier `W` holds in its field `$inner`: `params_into`, `covariance_into`,
/// `noise_into`, `residuals_into`, `groups_into`, `trace`, `reinit_count` and
/// `reset_covariance`. For the wrappers that change what a sample does (the outlier screen, the
/// road differencing, the boxed form) and not what the estimate is; each writes `dims`, `rows`,
/// `update_into`, `samples` and whatever else it changes itself.
macro_rules! forward_estimate {
    ($inner:tt) => {
        fn params_into(&self, out: &mut [T]) -> $crate::Result<()> {
            self.$inner.params_into(out)
        }

        fn covariance_into(&self, out: &mut [T]) -> $crate::Result<()> {
            self.$inner.covariance_into(out)
        }

        fn noise_into(&self, out: &mut [T]) -> $crate::Result<()> {
            self.$inner.noise_into(out)
        }

        fn residuals_into(&self, ssr: &mut [T], nobs: &mut [T]) -> $crate::Result<()> {
            self.$inner.residuals_into(ssr, nobs)
        }

        fn groups_into(&self, group_of_param: &mut [usize], group_of_eq: &mut [usize]) -> $crate::Result<()> {
            self.$inner.groups_into(group_of_param, group_of_eq)
        }

        fn trace(&self) -> Option<T> {
            self.$inner.trace()
        }

        fn reinit_count(&self) -> u32 {
            self.$inner.reinit_count()
        }

        fn reset_covariance(&mut self, p0: T) -> $crate::Result<()> {
            self.$inner.reset_covariance(p0)
        }
    };
}
pub(crate) use forward_estimate;

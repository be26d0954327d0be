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

/// A batch of samples, each stored row-major: sample `k` is `x[k n .. (k+1) n]`,
/// `z[k n .. (k+1) n]` and `u[k m .. (k+1) m]`.
#[derive(Debug, Clone, Copy)]
pub struct Samples<'a, T> {
    x: &'a [T],
    z: &'a [T],
    u: &'a [T],
    states: usize,
    inputs: usize,
    len: usize,
}

impl<'a, T> Samples<'a, T> {
    /// Checks the layout: `x` and `z` hold the same whole number of samples of `states`
    /// values, `u` holds `inputs` values per sample (nothing when `inputs` is 0).
    ///
    /// # Errors
    /// [`Error::Shape`] naming `r` (the measured states), `z` or `u`; [`Error::InvalidArgument`]
    /// for `states == 0`.
    pub fn new(states: usize, inputs: usize, x: &'a [T], z: &'a [T], u: &'a [T]) -> Result<Self> {
        if states == 0 {
            return Err(Error::InvalidArgument { arg: "states", expected: "at least one state" });
        }
        if x.len() % states != 0 {
            return Err(Error::Shape { arg: "r", expected: (x.len() / states + 1) * states, got: x.len() });
        }
        let len = x.len() / states;
        if z.len() != x.len() {
            return Err(Error::Shape { arg: "z", expected: x.len(), got: z.len() });
        }
        let need_u = len.checked_mul(inputs).ok_or(Error::Shape { arg: "u", expected: usize::MAX, got: u.len() })?;
        if u.len() != need_u {
            return Err(Error::Shape { arg: "u", expected: need_u, got: u.len() });
        }
        Ok(Self { x, z, u, states, inputs, len })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.len
    }

    /// `true` when there is no sample.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// States per sample.
    pub fn states(&self) -> usize {
        self.states
    }

    /// Inputs per sample.
    pub fn inputs(&self) -> usize {
        self.inputs
    }

    /// The samples in order, as `(x, z, u)` slices.
    pub fn iter(&self) -> SampleIter<'a, T> {
        SampleIter { x: self.x, z: self.z, u: self.u, n: self.states, m: self.inputs }
    }

    /// The samples from index `start` on.
    pub fn skip_to(&self, start: usize) -> Samples<'a, T> {
        let start = start.min(self.len);
        let (n, m) = (self.states, self.inputs);
        Samples {
            x: &self.x[start * n..],
            z: &self.z[start * n..],
            u: &self.u[start * m..],
            states: n,
            inputs: m,
            len: self.len - start,
        }
    }

    /// Checks that these samples fit an identifier of the given dimensions.
    ///
    /// # Errors
    /// [`Error::Shape`] naming `r` (states per sample) or `u` (inputs per sample).
    pub fn check(&self, dims: Dims) -> Result<()> {
        if self.states != dims.states {
            return Err(Error::Shape { arg: "r", expected: dims.states, got: self.states });
        }
        if self.inputs != dims.inputs {
            return Err(Error::Shape { arg: "u", expected: dims.inputs, got: self.inputs });
        }
        Ok(())
    }
}

/// Iterator over the samples of [`Samples`]: `(x, z, u)` per sample.
#[derive(Debug, Clone)]
pub struct SampleIter<'a, T> {
    x: &'a [T],
    z: &'a [T],
    u: &'a [T],
    n: usize,
    m: usize,
}

impl<'a, T> Iterator for SampleIter<'a, T> {
    type Item = (&'a [T], &'a [T], &'a [T]);

    #[inline(always)]
    fn next(&mut self) -> Option<Self::Item> {
        if self.x.len() < self.n || self.z.len() < self.n || self.u.len() < self.m {
            return None;
        }
        let (x, xr) = self.x.split_at(self.n);
        let (z, zr) = self.z.split_at(self.n);
        let (u, ur) = self.u.split_at(self.m);
        (self.x, self.z, self.u) = (xr, zr, ur);
        Some((x, z, u))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = self.x.len() / self.n.max(1);
        (left, Some(left))
    }
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

/// Runs `f` with an innovation buffer of `len` values: on the stack up to
/// [`FIT_STACK_EQUATIONS`], on the heap beyond (with `alloc`).
pub(crate) fn with_innovations<T: Real, R>(
    len: usize,
    f: impl FnOnce(&mut [T]) -> core::result::Result<R, FitError>,
) -> core::result::Result<R, FitError> {
    if len <= FIT_STACK_EQUATIONS {
        let mut buf = [T::zero(); FIT_STACK_EQUATIONS];
        return f(&mut buf[..len]);
    }
    #[cfg(feature = "alloc")]
    {
        let mut v = alloc::vec::Vec::new();
        v.try_reserve_exact(len).map_err(|_| FitError {
            sample: None,
            error: Error::OutOfMemory { what: "the innovations of one sample", bytes: len * core::mem::size_of::<T>() },
        })?;
        v.resize(len, T::zero());
        f(&mut v)
    }
    #[cfg(not(feature = "alloc"))]
    Err(FitError {
        sample: None,
        error: Error::Capacity { arg: "equations", needed: len, capacity: FIT_STACK_EQUATIONS },
    })
}

/// The dimensions of an identifier on `structure` (states, inputs, identified equations,
/// parameters): what every identifier on a [`Structure`](crate::structure::Structure) reports.
#[inline(always)]
pub(crate) fn structure_dims<T: Real>(structure: &crate::structure::Structure<T>) -> Dims {
    Dims {
        states: structure.states(),
        inputs: structure.inputs(),
        equations: structure.equations(),
        params: structure.params(),
    }
}

/// [`Identifier::groups_into`] of an identifier on a structure with `np` parameters and `ne`
/// identified equations, grouped by `part`.
pub(crate) fn partition_groups_into(
    part: &crate::structure::Partition,
    np: usize,
    ne: usize,
    group_of_param: &mut [usize],
    group_of_eq: &mut [usize],
) -> Result<()> {
    if group_of_param.len() != np {
        return Err(Error::Shape { arg: "group_of_param", expected: np, got: group_of_param.len() });
    }
    if group_of_eq.len() != ne {
        return Err(Error::Shape { arg: "group_of_eq", expected: ne, got: group_of_eq.len() });
    }
    for (j, g) in group_of_param.iter_mut().enumerate() {
        *g = part.group_of_param[j] as usize;
    }
    for (i, g) in group_of_eq.iter_mut().enumerate() {
        *g = part.group_of_eq[i] as usize;
    }
    Ok(())
}

/// [`Identifier::residuals_into`] from per-equation sums `eq_ssr` and counts `eq_nobs` (the
/// first `ssr.len()` of them, which must equal `nobs.len()` and the equations `ne`).
pub(crate) fn copy_residuals<T: Real>(
    ne: usize,
    eq_ssr: &[T],
    eq_nobs: &[T],
    ssr: &mut [T],
    nobs: &mut [T],
) -> Result<()> {
    if ssr.len() != ne || nobs.len() != ne {
        return Err(Error::Shape { arg: "ssr", expected: ne, got: ssr.len().min(nobs.len()) });
    }
    ssr.copy_from_slice(&eq_ssr[..ne]);
    nobs.copy_from_slice(&eq_nobs[..ne]);
    Ok(())
}

/// [`check_lengths`], then every value finite (the errors name `r_k`, `z_k`, `u_k`): the
/// checks every identifier's `update_into` starts with.
///
/// # Errors
/// [`Error::Shape`]; [`Error::NonFinite`].
#[inline(always)]
pub(crate) fn check_slices<T: Real>(dims: Dims, x: &[T], z: &[T], u: &[T], e: &[T]) -> Result<()> {
    check_lengths(dims, x, z, u, e)?;
    for (arg, v) in [("r_k", x), ("z_k", z), ("u_k", u)] {
        crate::error::check_finite(arg, v)?;
    }
    Ok(())
}

/// The diagonal equation-noise matrix `diag(r)` into `out` (`r.len()²`, row-major): the
/// [`Identifier::noise_into`] of identifiers with one variance per equation.
///
/// # Errors
/// [`Error::Shape`] for a wrong length.
pub(crate) fn diagonal_noise_into<T: Real>(r: &[T], out: &mut [T]) -> Result<()> {
    let ne = r.len();
    if out.len() != ne * ne {
        return Err(Error::Shape { arg: "out", expected: ne * ne, got: out.len() });
    }
    out.fill(T::zero());
    for (i, &v) in r.iter().enumerate() {
        out[i * ne + i] = v;
    }
    Ok(())
}

/// Checks the lengths of one sample against `dims` (`x`, `z`: `n`; `u`: `m`; `e`: equations).
#[inline(always)]
pub(crate) fn check_lengths<T>(dims: Dims, x: &[T], z: &[T], u: &[T], e: &[T]) -> Result<()> {
    if x.len() != dims.states {
        return Err(Error::Shape { arg: "r_k", expected: dims.states, got: x.len() });
    }
    if z.len() != dims.states {
        return Err(Error::Shape { arg: "z_k", expected: dims.states, got: z.len() });
    }
    if u.len() != dims.inputs {
        return Err(Error::Shape { arg: "u_k", expected: dims.inputs, got: u.len() });
    }
    if e.len() != dims.equations {
        return Err(Error::Shape { arg: "e", expected: dims.equations, got: e.len() });
    }
    Ok(())
}

/// An `N`-vector from a slice of length `N` (checked by the caller).
#[inline(always)]
pub(crate) fn vector<T: Real, const N: usize>(v: &[T]) -> nalgebra::SVector<T, N> {
    let mut out = nalgebra::SVector::<T, N>::zeros();
    for (o, &s) in out.iter_mut().zip(v) {
        *o = s;
    }
    out
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

//! Recursive instrumental variables (IV) on a [`Structure`]: consistent estimates when the
//! measured state is noisy.
//!
//! # Why least squares fails, and what an instrument is
//! Every equation of a structure is a scalar regression `y_i = h_i(r, z, u)ᵀ p + ε_i`
//! ([`Structure::regression`]). With noise `w` on the measured state `r = x + w`, the
//! regressor `h` carries the noise and so does the error (`ε ∋ −pᵀ ∂h/∂x · w`): `E[h ε] ≠ 0`,
//! and least squares (the thesis' Kalman identifier, Eq 4.3–4.7) converges to the wrong
//! parameters (the attenuation bias of Eq 2.20; Ch. IV.D, VII of the thesis). An *instrument*
//! `ζ` is a vector correlated with `h` (so `E[ζ hᵀ]` is invertible) and uncorrelated with `ε`;
//! then `θ̂ = (Σ ζ hᵀ)⁻¹ Σ ζ y` is consistent (Söderström & Stoica, *System Identification*,
//! 1989, §8.1; Ljung, *System Identification*, 2nd ed., 1999, §7.6).
//!
//! # The instruments here: the regressors `delay` samples earlier
//! `ζ_i(k) = h_i(r(k−d), z(k−d), u(k−d))`, equation `i`'s regressor computed by the same
//! structure from the sample `d = delay` steps back (kept in a fixed ring: no allocation).
//! They are valid when
//! - the sensor noise is white from sample to sample (independent `w(k)`, `v(k)`), so the
//!   noise in `ζ(k)` (at `k − d`) is independent of the noise in `ε(k)` (at `k`);
//! - the equation error's other part — the unmeasured road input `B u(k)` — is independent
//!   of the past: with the road held over each interval (Eq 4.25), `x(k−d)` depends on
//!   `u(k−d−1), u(k−d−2), …` only;
//! - the true state is autocorrelated over `d` samples (the suspension's modes are much slower
//!   than the sample interval: `E[ζ hᵀ]` is then well conditioned).
//!
//! They are **not** valid when the sensor noise is coloured (filtered, drifting, quantized
//! with memory): `w(k)` and `w(k−d)` are then correlated and the estimate is biased again.
//! The delay must exceed the noise's correlation time (for a first-order low-pass noise of
//! time constant `τ`, the bias falls like `exp(−d·dt/τ)`) while staying well within the
//! state's own correlation time (the slowest pole); a derivative computed from the measured
//! state by differencing is coloured by construction. They are also invalid when the road
//! input is coloured and enters the equation, and they lose accuracy (not consistency) as
//! `E[ζ hᵀ]` approaches singularity; a step whose correlation `r + hᵀPζ` vanishes is refused
//! ([`Error::Singular`], the identifier unchanged).
//!
//! # The filter
//! One [`IvFilter`] per independent parameter group ([`Structure::partition`]), exactly as
//! [`super::Structured`] runs one least-squares filter per group: the groups are independent
//! problems (no equation links them), so the estimate is the same as one filter over all
//! parameters, at `Σ_g d_g²` instead of `(Σ_g d_g)²` per sample (for the thesis' full rows:
//! one `n`-parameter filter per row, the decoupled form of Eq 6.16–6.18). Equations that share
//! parameters are updated in turn in their group's filter, weighted by `√(r_g / r_i)` like
//! [`super::Structured`]. The start is exact (batch IV on the first samples, then the
//! recursion: every estimate is batch IV on all samples so far) or from a prior `P(0) = p0`.
//!
//! When every group has the same regressor and so the same instrument (the thesis' full rows:
//! `h = x(k)`, `ζ = x(k − d)` in every row; or any structure whose equations repeat the same
//! parameter terms, one group each) and all groups start alike (the same prior block and
//! weight `r`, or the exact start), their `P = r (Σ ζ hᵀ + r P₀⁻¹)⁻¹` and `M = Σ ζ ζᵀ` are
//! the same matrices forever: the identifier then runs one `P` update per sample and a `θ̂`
//! update per group (`instrumental/shared.rs`), with the same arithmetic, so the same bits,
//! as the per-group loop. It is detected at construction and on load; nothing to choose.
//!
//! # Refined instruments ([`InstrumentalVariables::with_lags`])
//! The delayed regressors are weak instruments for the fast wheel mode (time constant
//! 0.025 s, half a sample interval: the wheel velocity one sample back says little about the
//! wheel velocity now), so their estimate, though consistent, scatters widely on the thesis'
//! full rows. The optimal instruments are the regressors' noise-free part, and with a white
//! equation error no prefilter is needed (Söderström & Stoica §8.2: the optimal prefilter is
//! the inverse noise model). `with_lags(L)` estimates that noise-free part from the past with
//! an auxiliary model — a recursive linear predictor of the current sample from the `L`
//! samples before `k − d + 1` (`iv_predictor.rs`) — and evaluates the regressors there. The
//! past state *and its measured derivative* carry the road input that moved the state since,
//! so the prediction recovers the fast mode too. For regressors linear in the sample the
//! result is two-stage least squares on those `L` lags.
//!
//! # Instruments from the auxiliary model ([`InstrumentalVariables::with_model_instruments`])
//! SRIVC/RIVC proper (Young & Garnier: the auxiliary model is the estimated continuous-time
//! system simulated from the measured input, iterated) for structures with a measured input:
//! the structure with the estimate `p̂_a`, integrated by RK4 over each sample interval with
//! the measured input held, gives the noise-free state `x̂(k)` and the instruments
//! `ζ_i(k) = h_i(x̂(k), f(x̂(k), u(k)), u(k))`; every `refresh` samples the current estimate
//! becomes `p̂_a` when its linear part is stable, else the previous model stays
//! (`iv_model.rs`, [`super::ModelInstruments`]). No prefilter: the derivatives are measured
//! and the equation error white. On the thesis' cars the road input is never measured, so
//! that model cannot be simulated there; the predictor above is its data-driven stand-in.

mod shared;

use super::checks::check_lengths;
use super::iv_filter::IvFilter;
use super::iv_predictor::{Predictor, SAMPLE_VALUES};
use super::{Dims, Flat, Identifier, StructuredPrior, OVERFLOW};
use crate::structure::{Partition, Structure, MAX_EQUATIONS, MAX_PARAMS};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};
use shared::{shared_regressor, SharedRegressor};

mod identifier;
mod prior;
use prior::prior_blocks;

mod ring;

pub(crate) use ring::Ring;
pub use ring::RING_VALUES;

/// Recursive instrumental variables on a [`Structure`] over group storage `F` (module docs):
/// [`IvIdentifier`] (arrays, no allocation at all) or [`IvIdentifierVec`] (heap, sized at
/// construction). `Q` is the capacity of the refined instruments' predictor
/// ([`InstrumentalVariables::with_lags`]; 0: the delayed regressors only).
///
/// With the feature `serde` the whole state is serialized (the filters, the ring of past
/// samples, the predictor, the residual sums) and a deserialized identifier is checked
/// against its structure and settings, so a corrupt input is a serde error; a restored one
/// continues bit for bit.
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct InstrumentalVariables<T: Real, const P: usize, F: Flat<IvFilter<T, P>>, const Q: usize = 0> {
    structure: Structure<T>,
    part: Partition,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    filters: F,
    /// The filters before the current update (of the groups it touched): scratch, not state
    /// (serialized empty where the store allows, refilled on load).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::scratch"))]
    backup: F,
    ring: Ring<T>,
    delay: u16,
    /// Past samples the predictor reads (0: instruments are the delayed regressors).
    lags: u16,
    pred: Predictor<T, Q>,
    rows: [usize; MAX_EQUATIONS],
    r: [T; MAX_EQUATIONS],
    scale: [T; MAX_EQUATIONS],
    /// Per equation: Σ of squared a-posteriori residuals (own units) and samples behind it.
    eq_ssr: [T; MAX_EQUATIONS],
    eq_nobs: [T; MAX_EQUATIONS],
    samples: u64,
    /// Every group shares one gain (`shared.rs`): derived from the structure and the filters
    /// at construction and on load, not stored.
    #[cfg_attr(feature = "serde", serde(skip))]
    shared: Option<SharedRegressor>,
}

/// [`InstrumentalVariables`] with its `G` groups' filters in an array and a predictor of
/// capacity `Q` (0: none): no allocation.
pub type IvIdentifier<T, const P: usize, const G: usize, const Q: usize = 0> =
    InstrumentalVariables<T, P, [IvFilter<T, P>; G], Q>;

/// [`InstrumentalVariables`] with its groups' filters in a `Vec` sized at construction
/// (requires `alloc`): one monomorphization per `(P, Q)` serves any number of groups.
#[cfg(feature = "alloc")]
pub type IvIdentifierVec<T, const P: usize, const Q: usize = 0> =
    InstrumentalVariables<T, P, alloc::vec::Vec<IvFilter<T, P>>, Q>;

/// Each equation's variance (`r`: one value or one per equation) and its row weight
/// `√(r_g / r_i)` within its group `g`, and each group's `r_g` (its first equation's).
pub(crate) fn equation_weights<T: Real>(
    part: &Partition,
    ne: usize,
    r: &[T],
) -> Result<([T; MAX_EQUATIONS], [T; MAX_EQUATIONS], [T; MAX_EQUATIONS])> {
    let mut r_all = [T::one(); MAX_EQUATIONS];
    match r.len() {
        1 => r_all[..ne].fill(r[0]),
        k if k == ne => r_all[..ne].copy_from_slice(r),
        k => return Err(Error::Shape { arg: "r", expected: ne, got: k }),
    }
    crate::error::check_finite("r", &r_all[..ne])?;
    if r_all[..ne].iter().any(|&v| !(v > T::zero())) {
        return Err(Error::InvalidArgument { arg: "r", expected: "variances > 0 (one per identified equation)" });
    }
    let (mut r_group, mut seen, mut scale) =
        ([T::zero(); MAX_EQUATIONS], [false; MAX_EQUATIONS], [T::one(); MAX_EQUATIONS]);
    for i in 0..ne {
        let g = part.group_of_eq[i] as usize;
        if !seen[g] {
            seen[g] = true;
            r_group[g] = r_all[i];
        }
        scale[i] = (r_group[g] / r_all[i]).sqrt();
    }
    Ok((r_all, scale, r_group))
}

/// Equation `i`'s regression `(y, h)` at `(x, z, u)` in its group's local parameter order,
/// scaled by `w`.
#[inline(always)]
pub(crate) fn local_regression<T: Real, const P: usize>(
    s: &Structure<T>,
    part: &Partition,
    i: usize,
    w: T,
    x: &[T],
    z: &[T],
    u: &[T],
) -> (T, SVector<T, P>) {
    let mut h = SVector::<T, P>::zeros();
    let mut y = z.get(s.equation_state(i)).copied().unwrap_or_else(T::zero);
    for t in s.terms(i) {
        let phi = t.coef * s.basis(t.basis, x, z, u);
        match t.param {
            Some(p) => h[part.local[p as usize] as usize] += phi,
            None => y -= phi,
        }
    }
    (y * w, h * w)
}

impl<T: Real, const P: usize, F: Flat<IvFilter<T, P>>, const Q: usize> InstrumentalVariables<T, P, F, Q> {
    /// Checks a deserialized identifier (feature `serde`; its structure, filters and
    /// predictor checked themselves) against its structure and settings, and refills the
    /// scratch copy of the filters. Each failure is [`Error::InvalidArgument`] (`arg` "state")
    /// naming what is wrong: the groups (the structure's partition, at most `P` parameters
    /// each, one filter each), the equation rows, the variances `r` (finite, > 0) and the row
    /// weights `√(r_g / r_i)` derived from them, each filter's size and weight `r_g`, the
    /// delay (≥ 1), `lags` within `Q`, the ring (`delay + lags − 1` slots of `2n + m` values,
    /// filled by the samples counted, values finite and below the update's limit), the
    /// predictor's size, and the residual sums (finite, ≥ 0).
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let corrupt = |expected| Err(Error::InvalidArgument { arg: "state", expected });
        let s = &self.structure;
        let (n, m, ne) = (s.states(), s.inputs(), s.equations());
        let part = s.partition();
        let ng = part.groups as usize;
        if part != self.part || part.largest() > P {
            return corrupt("an IV identifier's parameter groups: its structure's, of at most P parameters each");
        }
        if self.backup.flat().is_empty() {
            self.backup = self.filters.clone();
        }
        if self.filters.flat().len() != ng || self.backup.flat().len() != ng {
            return corrupt("an IV identifier with one filter per parameter group");
        }
        if s.equation_states().enumerate().any(|(i, st)| self.rows[i] != st) || self.rows[ne..].iter().any(|&r| r != 0)
        {
            return corrupt("an IV identifier's equation rows: its structure's equation states");
        }
        let Ok((_, scale, r_group)) = equation_weights(&part, ne, &self.r[..ne]) else {
            return corrupt("an IV identifier's equation variances r finite and > 0");
        };
        if scale[..ne] != self.scale[..ne] {
            return corrupt("an IV identifier's row weights √(r_g / r_i) from its variances r");
        }
        let filter_fits = |(g, f): (usize, &IvFilter<T, P>)| f.dim() == part.size[g] as usize && f.r() == r_group[g];
        if !self.filters.flat().iter().enumerate().all(filter_fits) {
            return corrupt("an IV identifier's filters of their groups' sizes and weights r_g");
        }
        let (d, lags, width) = (self.delay as usize, self.lags as usize, 2 * n + m);
        if d == 0 {
            return corrupt("an IV identifier's delay of at least 1 sample");
        }
        if lags > 0 && lags * width + 1 > Q {
            return corrupt("an IV identifier's lags × (2n + m) + 1 within its predictor's capacity Q");
        }
        let ring = &self.ring;
        let slots = if lags == 0 { d } else { d + lags - 1 };
        if ring.width as usize != width
            || ring.slots as usize != slots
            || slots * width > RING_VALUES
            || ring.head >= ring.slots
            || ring.filled > ring.slots
        {
            return corrupt("an IV identifier's ring of delay + lags − 1 past samples of 2n + m values");
        }
        let fill = self.samples.min(u64::from(ring.slots));
        if u64::from(ring.filled) != fill || (!ring.full() && ring.head != ring.filled) {
            return corrupt("an IV identifier's ring filled by the samples it counts");
        }
        let limit = T::biggest().sqrt() / T::of(256.0);
        let (used, rest) = ring.buf.split_at(slots * width);
        if !used.iter().all(|v| v.abs() < limit) || rest.iter().any(|&v| v != T::zero()) {
            return corrupt("an IV identifier's past samples below √(largest float)/256, nothing stored beyond them");
        }
        let (pd, po) = self.pred.size();
        let pred_fits =
            if lags == 0 { pd == 0 && (po == 0 || po == width) } else { pd == lags * width + 1 && po == width };
        if !pred_fits {
            return corrupt("an IV identifier's predictor of lags × (2n + m) + 1 regressors and 2n + m outputs");
        }
        let sums = self.eq_ssr[..ne].iter().chain(&self.eq_nobs[..ne]);
        if !sums.into_iter().all(|&v| v.finite() && v >= T::zero()) {
            return corrupt("an IV identifier's residual sums and counts finite and ≥ 0");
        }
        self.shared = shared_regressor(&self.structure, &self.part, self.filters.flat());
        Ok(())
    }

    /// An IV identifier of `structure`'s parameters with instruments delayed by `delay ≥ 1`
    /// samples, prior `p0` ([`StructuredPrior::Exact`]: batch IV on the first samples, then
    /// recursive; otherwise `P(0)` as given, with prior mean `theta0`, `None`: 0), and equation
    /// variances `r` (one, or one per identified equation; > 0; in the units of the equation's
    /// measured derivative, squared; they weigh equations that share parameters and, with a
    /// prior, `r/p0` weighs the prior against the data, as for [`super::Structured`]).
    ///
    /// # Errors
    /// [`Error::NotIdentifiable`] for an unused or confounded parameter; [`Error::Capacity`]
    /// when a group has more than `P` parameters, `F` cannot hold the groups, or
    /// `delay × (2n + m)` exceeds [`RING_VALUES`]; [`Error::InvalidArgument`] for `delay = 0`;
    /// [`Error::Shape`] / [`Error::InvalidArgument`] naming `p0`, `theta0` or `r`.
    pub fn new(
        structure: Structure<T>,
        delay: usize,
        p0: StructuredPrior<'_, T>,
        theta0: Option<&[T]>,
        r: &[T],
    ) -> Result<Self> {
        structure.check_identifiable()?;
        let part = structure.partition();
        let (np, ne, ng) = (structure.params(), structure.equations(), part.groups as usize);
        if part.largest() > P {
            return Err(Error::Capacity { arg: "P", needed: part.largest(), capacity: P });
        }
        let ring = Ring::new(structure.states(), structure.inputs(), delay, delay)?;
        let (r_all, scale, r_group) = equation_weights(&part, ne, r)?;
        if let Some(t) = theta0 {
            if t.len() != np {
                return Err(Error::Shape { arg: "theta0", expected: np, got: t.len() });
            }
            crate::error::check_finite("theta0", t)?;
            if p0 == StructuredPrior::Exact {
                return Err(Error::InvalidArgument {
                    arg: "theta0",
                    expected: "no prior mean with p0='exact' (give p0 too: a prior mean needs a prior covariance)",
                });
            }
        }
        let blocks = prior_blocks::<T, P>(&structure, &part, p0)?;
        let zero = IvFilter::<T, P>::exact(1, T::one())?;
        let mut filters = F::filled("groups", ng, zero)?;
        for (g, slot) in filters.flat_mut().iter_mut().enumerate() {
            let d = part.size[g] as usize;
            *slot = match blocks {
                None => IvFilter::exact(d, r_group[g])?,
                Some(ref pm) => {
                    let mut theta = SVector::<T, P>::zeros();
                    for j in (0..np).filter(|&j| part.group_of_param[j] as usize == g) {
                        theta[part.local[j] as usize] = theta0.map_or(T::zero(), |t| t[j]);
                    }
                    IvFilter::with_prior(d, theta, pm.block(g), r_group[g])?
                }
            };
        }
        let mut rows = [0usize; MAX_EQUATIONS];
        for (i, s) in structure.equation_states().enumerate() {
            rows[i] = s;
        }
        Ok(Self {
            shared: shared_regressor(&structure, &part, filters.flat()),
            structure,
            part,
            backup: filters.clone(),
            filters,
            ring,
            delay: delay as u16,
            lags: 0,
            pred: Predictor::new(0, 0),
            rows,
            r: r_all,
            scale,
            eq_ssr: [T::zero(); MAX_EQUATIONS],
            eq_nobs: [T::zero(); MAX_EQUATIONS],
            samples: 0,
        })
    }

    /// The exact start with unit weights: the common case.
    ///
    /// # Errors
    /// As [`InstrumentalVariables::new`].
    pub fn exact(structure: Structure<T>, delay: usize) -> Result<Self> {
        Self::new(structure, delay, StructuredPrior::Exact, None, &[T::one()])
    }

    /// The thesis' full unknown rows of an `n`-state linear model
    /// ([`Structure::full_rows`]): parameters the rows of `A`, row-major, as every
    /// identifier's `θ`.
    ///
    /// # Errors
    /// As [`Structure::full_rows`] and [`InstrumentalVariables::new`].
    pub fn full_rows(n: usize, rows: &[usize], delay: usize, p0: StructuredPrior<'_, T>, r: &[T]) -> Result<Self> {
        Self::new(Structure::full_rows(n, rows)?, delay, p0, None, r)
    }

    /// Refined instruments (see `iv_predictor.rs`): the regressors of the current sample as
    /// predicted from the `lags ≥ 1` samples `k − d, …, k − d − lags + 1` by a recursive
    /// least-squares predictor (the auxiliary model; exact start), `ζ_i = h_i(ŝ(k))`. With
    /// regressors linear in the sample this is two-stage least squares on the instruments
    /// `[s(k−d); …; 1]`. `lags = 0` restores the delayed regressors. Call before the first
    /// sample.
    ///
    /// # Errors
    /// [`Error::Capacity`] naming `lags` when `lags × (2n + m) + 1 > Q`, or `delay` when the
    /// ring cannot hold `delay + lags − 1` samples; [`Error::InvalidArgument`] after samples.
    pub fn with_lags(mut self, lags: usize) -> Result<Self> {
        if self.samples > 0 {
            return Err(Error::InvalidArgument { arg: "lags", expected: "set before the first sample" });
        }
        let (n, m) = (self.structure.states(), self.structure.inputs());
        let d = self.delay as usize;
        let slots = if lags == 0 { d } else { d + lags - 1 };
        let dim = lags.saturating_mul(2 * n + m).saturating_add(1);
        if lags > 0 && dim > Q {
            return Err(Error::Capacity { arg: "lags", needed: dim, capacity: Q });
        }
        self.ring = Ring::new(n, m, d, slots)?;
        self.lags = lags as u16;
        self.pred = Predictor::new(if lags == 0 { 0 } else { dim }, 2 * n + m);
        Ok(self)
    }

    /// Past samples the refined instruments' predictor reads (0: delayed regressors).
    pub fn lags(&self) -> usize {
        self.lags as usize
    }

    /// The structure identified.
    pub fn structure(&self) -> &Structure<T> {
        &self.structure
    }

    /// The instruments' delay `d`, samples.
    pub fn delay(&self) -> usize {
        self.delay as usize
    }

    /// The filter of group `g`.
    pub fn filter(&self, g: usize) -> &IvFilter<T, P> {
        &self.filters.flat()[g]
    }

    /// `true` while some group has no estimate yet (the ring is filling, the predictor or the
    /// exact start is absorbing samples).
    pub fn starting(&self) -> bool {
        self.filters.flat().iter().any(|f| f.starting())
    }

    /// Innovations against the current estimate (prior, or 0 while starting), when there is
    /// no instrument for this sample yet.
    fn innovations(&self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        for i in 0..self.structure.equations() {
            let g = self.part.group_of_eq[i] as usize;
            let (y, h) = local_regression::<T, P>(&self.structure, &self.part, i, self.scale[i], x, z, u);
            let f = &self.filters.flat()[g];
            let pred = if f.starting() { T::zero() } else { h.dot(f.theta()) };
            e[i] = (y - pred) / self.scale[i];
            if !e[i].finite() {
                return Err(OVERFLOW);
            }
        }
        Ok(())
    }

    /// One sample with refined instruments (after the ring has filled): the instruments'
    /// sample is the current one as predicted from the `lags` samples before `k − d + 1`
    /// (none while the predictor starts: innovations only). The predictor's step is planned
    /// first and applied last, so that a rejected sample changes nothing.
    fn update_refined(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        let (n, m) = (self.structure.states(), self.structure.inputs());
        let (d, lags, width) = (self.delay as usize, self.lags as usize, 2 * n + m);
        let mut q = [T::zero(); Q];
        let mut at = [T::zero(); SAMPLE_VALUES];
        for j in 0..lags {
            q[j * width..(j + 1) * width].copy_from_slice(self.ring.ago(d + j));
        }
        q[lags * width] = T::one();
        let have = !self.pred.starting();
        if have {
            self.pred.predict(&q, &mut at[..width]);
        }
        let mut now = [T::zero(); SAMPLE_VALUES];
        now[..n].copy_from_slice(x);
        now[n..2 * n].copy_from_slice(z);
        now[2 * n..width].copy_from_slice(u);
        let step = self.pred.plan(&q, &now[..width])?;
        match self.shared_ready() {
            Some(kind) if have => {
                let (h, zeta) = self.shared_regressors(kind, x, z, u, split(&at[..width], n), e)?;
                self.update_shared(&h, &zeta, e)?;
            }
            _ if have => self.update_groups(x, z, u, split(&at[..width], n), e)?,
            _ => self.innovations(x, z, u, e)?,
        }
        self.pred.apply(&step, &q, &now[..width]);
        Ok(())
    }

    /// One sample through each group's own filter (equations in turn, weighted); the
    /// instruments' sample is `(ax, az, au)`. Transactional: on an error the groups touched
    /// are restored from their backup and the residual sums from their copy.
    fn update_groups(
        &mut self,
        x: &[T],
        z: &[T],
        u: &[T],
        (ax, az, au): (&[T], &[T], &[T]),
        e: &mut [T],
    ) -> Result<()> {
        let (ssr0, nobs0) = (self.eq_ssr, self.eq_nobs);
        let mut touched = 0u32;
        let mut failed = None;
        let (s, part) = (&self.structure, &self.part);
        for i in 0..s.equations() {
            let g = part.group_of_eq[i] as usize;
            if touched & (1 << g) == 0 {
                touched |= 1 << g;
                self.backup.flat_mut()[g] = self.filters.flat()[g];
            }
            let w = self.scale[i];
            let (y, h) = local_regression::<T, P>(s, part, i, w, x, z, u);
            let (_, zeta) = local_regression::<T, P>(s, part, i, w, ax, az, au);
            if !(y.finite() && h.iter().chain(zeta.iter()).all(|v| v.finite())) {
                failed = Some(OVERFLOW);
                break;
            }
            match self.filters.flat_mut()[g].update(&h, &zeta, y) {
                Ok((inn, post)) => {
                    e[i] = inn / w;
                    if let Some(res) = post {
                        let res = res / w;
                        self.eq_ssr[i] += res * res;
                        self.eq_nobs[i] += T::one();
                    }
                }
                Err(err) => {
                    failed = Some(err);
                    break;
                }
            }
        }
        if let Some(err) = failed {
            self.restore(touched);
            (self.eq_ssr, self.eq_nobs) = (ssr0, nobs0);
            return Err(err);
        }
        // After the per-group step (the exact start of a shared identifier) the shared step
        // stays only while the groups still share their gain.
        let f = self.filters.flat();
        if self.shared.is_some() && !f.iter().all(|g| g.shares_gain_with(&f[0])) {
            self.shared = None;
        }
        Ok(())
    }

    /// The sample's lengths and values, as every update checks them before changing anything.
    fn check_sample(&self, x: &[T], z: &[T], u: &[T], e: &[T]) -> Result<()> {
        check_lengths(self.dims(), x, z, u, e)?;
        // Every value is kept for later samples' instruments, whose products must stay finite:
        // a value that would overflow when squared is refused now (accepted, it would make
        // every later sample overflow while it stays in the ring).
        let limit = T::biggest().sqrt() / T::of(256.0);
        for (arg, v) in [("r_k", x), ("z_k", z), ("u_k", u)] {
            // One pass (a NaN fails `<` too); the error names a non-finite value first.
            if v.iter().any(|a| !(a.abs() < limit)) {
                crate::error::check_finite(arg, v)?;
                return Err(Error::InvalidArgument {
                    arg,
                    expected: "values below √(largest float)/256 (about 5e151 in f64, 7e16 in f32), whose squares \
                               stay finite (rescale the units)",
                });
            }
        }
        Ok(())
    }

    /// One sample whose instruments' sample `(ax, az, au)` the caller gives (the auxiliary
    /// model's, `iv_model.rs`) instead of the ring's: the same checks, the same shared or
    /// per-group step, and the sample stored in the ring as usual. Transactional.
    pub(crate) fn update_with(&mut self, x: &[T], z: &[T], u: &[T], at: (&[T], &[T], &[T]), e: &mut [T]) -> Result<()> {
        self.check_sample(x, z, u, e)?;
        if let Some(kind) = self.shared_ready() {
            let (h, zeta) = self.shared_regressors(kind, x, z, u, at, e)?;
            self.update_shared(&h, &zeta, e)?;
        } else {
            self.update_groups(x, z, u, at, e)?;
        }
        self.ring.push(x, z, u);
        self.samples += 1;
        Ok(())
    }

    fn restore(&mut self, touched: u32) {
        for g in 0..self.part.groups as usize {
            if touched & (1 << g) != 0 {
                self.filters.flat_mut()[g] = self.backup.flat()[g];
            }
        }
    }
}

/// A sample `(x, z, u)` of `n` states from its `2n + m` values.
#[inline(always)]
fn split<T>(sample: &[T], n: usize) -> (&[T], &[T], &[T]) {
    let (x, rest) = sample.split_at(n);
    let (z, u) = rest.split_at(n);
    (x, z, u)
}

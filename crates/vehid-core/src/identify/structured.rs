//! Recursive least squares on a [`Structure`]: any model linear in its parameters.
//!
//! Each identified equation `i` of the structure is, at each sample, one scalar regression
//! `y_i = h_i(x, ż, u)ᵀ p + ε_i` ([`Structure::regression`]; Eq 2.2–2.4 generalized). The
//! parameters split into independent groups ([`Structure::partition`]: two parameters share
//! a group when some equation holds both); each group is one [`RowIdentifier`] (Eq 6.16–6.18
//! with every form, the exact start, tracking and the outlier screen), updated once per
//! equation of the group, in order. Equations that share parameters are weighted by their
//! variances `r_i` (row `i` scaled by `√(r_g / r_i)`, `r_g` the group's first equation's):
//! `r` only matters between equations of one group. With one equation per group — the
//! full-row case, and the quarter car's physical structure — this is exactly
//! [`super::KalmanRows`] on the structure's regressors.
//!
//! The filters have `P` parameters each (a const generic: the largest group's size; smaller
//! groups use the leading entries, [`RowIdentifier::restricted`]) and live in a [`Flat`]
//! storage: `[RowIdentifier<T, P>; G]` for exactly `G` groups ([`StructuredKalman`], no
//! allocation at all) or a `Vec` ([`StructuredKalmanVec`]). An update allocates nothing; it
//! is transactional (the groups it touched are restored on any error).
//!
//! The fast path (`structured_fast.rs`): with one equation per group (up to four groups) and
//! every filter in the plain step (the standard form after its start, no tracking, no outlier
//! screen, `r > 0`), the filters are kept side by side in lanes with a regressor each, as
//! [`super::KalmanRows`] keeps its rows, and the regression is read from a table compiled at
//! construction. A sample is planned for every lane before any is applied, so a refused one
//! changes nothing; one the lanes cannot take at once (non-finite, or a risky downdate to
//! check) goes through the general path. The full-row structure steps bit for bit as
//! `KalmanRows`; other structures as the general path, to rounding.

use super::checks::{check_lengths, check_slices};
use super::kalman::RowIdentifier;
use super::structured_fast::Fast;
use super::{CovarianceForm, Dims, Flat, Identifier, KalmanOptions, OVERFLOW};
use crate::error::check_finite;
use crate::structure::{Partition, Structure, MAX_EQUATIONS, MAX_PARAMS};
use crate::{Error, Real, Result};
use nalgebra::SVector;

mod identifier;

/// The prior of a [`Structured`] identifier.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StructuredPrior<'a, T> {
    /// No prior: every group absorbs samples exactly until its parameters are identified,
    /// then each estimate is (weighted) least squares on all samples so far.
    Exact,
    /// `P(0) = p0 I`.
    Scalar(T),
    /// `p0_i I` on the parameters of equation `i` (a parameter in several equations takes the
    /// value of the first).
    PerEquation(&'a [T]),
    /// The whole `params × params` prior covariance (row-major). Entries coupling
    /// independent groups must be 0.
    Matrix(&'a [T]),
}

/// Recursive least squares on a [`Structure`], over filter storage `F` (see the module docs).
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct Structured<T: Real, const P: usize, F: Flat<RowIdentifier<T, P>>> {
    structure: Structure<T>,
    part: Partition,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    filters: F,
    /// The filters before the current update (of the groups it touched): scratch, not state
    /// (serialized empty where the store allows, refilled on load).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::scratch"))]
    backup: F,
    /// The fast path (`structured_fast`): with one equation per group, the filters side by
    /// side in lanes and the regression compiled. While it is live, its lanes are the filters'
    /// state (the filters above are brought up to date when it leaves). Not serialized (the
    /// serialized filters are brought up to date first); rebuilt on load.
    #[cfg_attr(feature = "serde", serde(skip, default = "Fast::none"))]
    fast: Fast<T, P>,
    rows: [usize; MAX_EQUATIONS],
    /// Each equation's variance `r_i` and row scale `√(r_g / r_i)`.
    r: [T; MAX_EQUATIONS],
    scale: [T; MAX_EQUATIONS],
    /// Per equation: Σ w² of its recursive residuals (unscaled, decayed like its group's) and
    /// the samples behind it, and the samples its group gated.
    eq_ssr: [T; MAX_EQUATIONS],
    eq_nobs: [T; MAX_EQUATIONS],
    eq_gated: [u64; MAX_EQUATIONS],
    samples: u64,
}

/// A [`Structured`] identifier with its `G` groups' filters in an array: no allocation.
pub type StructuredKalman<T, const P: usize, const G: usize> = Structured<T, P, [RowIdentifier<T, P>; G]>;

/// A [`Structured`] identifier with its groups' filters in a `Vec` sized at construction
/// (requires `alloc`): one monomorphization per `P` serves any number of groups.
#[cfg(feature = "alloc")]
pub type StructuredKalmanVec<T, const P: usize> = Structured<T, P, alloc::vec::Vec<RowIdentifier<T, P>>>;

impl<T: Real, const P: usize, F: Flat<RowIdentifier<T, P>>> Structured<T, P, F> {
    /// Checks a deserialized identifier (feature `serde`; its structure checked itself): the
    /// partition, one filter (and one backup) per group, the equations' states, so that a
    /// corrupt input is an error, never a panic later.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let corrupt = Error::InvalidArgument { arg: "state", expected: "a structured identifier's saved state" };
        if self.backup.flat().is_empty() {
            self.backup = self.filters.clone();
        }
        let part = self.structure.partition();
        let ng = part.groups as usize;
        if part != self.part || part.largest() > P || self.filters.flat().len() != ng || self.backup.flat().len() != ng
        {
            return Err(corrupt);
        }
        let ne = self.structure.equations();
        if self.structure.equation_states().enumerate().any(|(i, s)| self.rows[i] != s)
            || self.rows[ne..].iter().any(|&r| r != 0)
        {
            return Err(corrupt);
        }
        self.fast = Fast::new(&self.structure, &self.part);
        Ok(())
    }

    /// An identifier of `structure`'s parameters with prior `p0`, prior mean `theta0`
    /// (`None`: 0; not with the exact start), equation variances `r` (one value for all, or one
    /// per identified equation; with the exact start any positive values, which only weigh
    /// equations that share parameters) and the options `opts` (form, tracking, outlier
    /// screen; not `reinit` or `retire_below`).
    ///
    /// # Errors
    /// [`Error::NotIdentifiable`] for a structure with an unused or confounded parameter;
    /// [`Error::Capacity`] when a group has more than `P` parameters or `F` cannot hold the
    /// groups; [`Error::Shape`] / [`Error::InvalidArgument`] naming `p0`, `theta0` or `r`.
    pub fn new(
        structure: Structure<T>,
        p0: StructuredPrior<'_, T>,
        theta0: Option<&[T]>,
        r: &[T],
        opts: KalmanOptions<T>,
    ) -> Result<Self> {
        structure.check_identifiable()?;
        opts.validate()?;
        if opts.reinit || opts.retire_below != T::zero() {
            return Err(Error::Unsupported {
                what: "reinitialization or retirement on a structure (use forgetting or drift to track changes)",
            });
        }
        let part = structure.partition();
        let (np, ne, ng) = (structure.params(), structure.equations(), part.groups as usize);
        if part.largest() > P {
            return Err(Error::Capacity { arg: "P", needed: part.largest(), capacity: P });
        }
        let r_all = match r.len() {
            1 => [r[0]; MAX_EQUATIONS],
            k if k == ne => {
                let mut a = [T::zero(); MAX_EQUATIONS];
                a[..ne].copy_from_slice(r);
                a
            }
            k => return Err(Error::Shape { arg: "r", expected: ne, got: k }),
        };
        check_finite("r", &r_all[..ne])?;
        if r_all[..ne].iter().any(|&v| v < T::zero()) {
            return Err(Error::InvalidArgument { arg: "r", expected: "variances ≥ 0" });
        }
        if let Some(t) = theta0 {
            if t.len() != np {
                return Err(Error::Shape { arg: "theta0", expected: np, got: t.len() });
            }
            check_finite("theta0", t)?;
            if p0 == StructuredPrior::Exact {
                return Err(Error::InvalidArgument {
                    arg: "theta0",
                    expected: "no prior mean with p0='exact' (give p0 too: a prior mean needs a prior covariance)",
                });
            }
        }
        // Each group's variance (its first equation's) and each equation's row scale.
        let mut r_group = [T::zero(); MAX_EQUATIONS];
        let mut seen = [false; MAX_EQUATIONS];
        let mut scale = [T::one(); MAX_EQUATIONS];
        for i in 0..ne {
            let g = part.group_of_eq[i] as usize;
            if !seen[g] {
                seen[g] = true;
                r_group[g] = r_all[i];
            }
            let (rg, ri) = (r_group[g], r_all[i]);
            if (rg == T::zero()) != (ri == T::zero()) {
                return Err(Error::InvalidArgument {
                    arg: "r",
                    expected: "equations that share parameters all noise-free (r = 0) or all noisy (r > 0)",
                });
            }
            if ri > T::zero() {
                scale[i] = (rg / ri).sqrt();
            }
        }
        // Each parameter's prior variance.
        let mut p_diag = [T::zero(); MAX_PARAMS];
        match p0 {
            StructuredPrior::Exact => {}
            StructuredPrior::Scalar(v) => p_diag[..np].fill(v),
            StructuredPrior::PerEquation(v) => {
                if v.len() != ne {
                    return Err(Error::Shape { arg: "p0", expected: ne, got: v.len() });
                }
                for i in (0..ne).rev() {
                    for t in structure.terms(i) {
                        if let Some(j) = t.param {
                            p_diag[j as usize] = v[i];
                        }
                    }
                }
            }
            StructuredPrior::Matrix(m) => {
                if m.len() != np * np {
                    return Err(Error::Shape { arg: "p0", expected: np * np, got: m.len() });
                }
                crate::error::check_finite("p0", m)?;
                for a in 0..np {
                    for b in 0..np {
                        if part.group_of_param[a] != part.group_of_param[b] && m[a * np + b] != T::zero() {
                            return Err(Error::InvalidArgument {
                                arg: "p0",
                                expected: "no prior covariance between parameters of independent groups (no equation \
                                           links them)",
                            });
                        }
                    }
                }
            }
        }
        let zero = RowIdentifier::<T, P>::new(T::one(), T::one())?;
        let mut filters = F::filled("groups", ng, zero)?;
        for (g, slot) in filters.flat_mut().iter_mut().enumerate() {
            let d = part.size[g] as usize;
            let rg = r_group[g];
            let members = |j: usize| part.group_of_param[j] as usize == g;
            let f = if p0 == StructuredPrior::Exact {
                if rg == T::zero() {
                    return Err(Error::InvalidArgument {
                        arg: "r",
                        expected: "r > 0 with p0='exact' (it only weighs equations; any positive value)",
                    });
                }
                RowIdentifier::exact(rg)?.restricted(d)?
            } else {
                let mut theta = SVector::<T, P>::zeros();
                let mut pm = nalgebra::SMatrix::<T, P, P>::identity();
                for a in (0..np).filter(|&a| members(a)) {
                    let la = part.local[a] as usize;
                    theta[la] = theta0.map_or(T::zero(), |t| t[a]);
                    match p0 {
                        StructuredPrior::Matrix(m) => {
                            for b in (0..np).filter(|&b| members(b)) {
                                pm[(la, part.local[b] as usize)] = m[a * np + b];
                            }
                        }
                        _ => {
                            crate::error::check_positive("p0", p_diag[a])?;
                            pm[(la, la)] = p_diag[a];
                        }
                    }
                }
                RowIdentifier::with_prior(theta, pm, rg)?.restricted(d)?
            };
            *slot = f.configured(opts.form, &opts)?;
        }
        let mut rows = [0usize; MAX_EQUATIONS];
        for (i, s) in structure.equation_states().enumerate() {
            rows[i] = s;
        }
        Ok(Self {
            fast: Fast::new(&structure, &part),
            structure,
            part,
            backup: filters.clone(),
            filters,
            rows,
            r: r_all,
            scale,
            eq_ssr: [T::zero(); MAX_EQUATIONS],
            eq_nobs: [T::zero(); MAX_EQUATIONS],
            eq_gated: [0; MAX_EQUATIONS],
            samples: 0,
        })
    }

    /// The exact start with unit weights (`r = 1` for every equation): the common case.
    ///
    /// # Errors
    /// As [`Structured::new`].
    pub fn exact(structure: Structure<T>, opts: KalmanOptions<T>) -> Result<Self> {
        Self::new(structure, StructuredPrior::Exact, None, &[T::one()], opts)
    }

    /// The structure identified.
    pub fn structure(&self) -> &Structure<T> {
        &self.structure
    }

    /// Its parameter groups.
    pub fn partition(&self) -> &Partition {
        &self.part
    }

    /// The filter of group `g` (a copy: with one equation per group the filters may be kept
    /// side by side in lanes).
    ///
    /// # Panics
    /// When `g` is not below the number of groups.
    pub fn filter(&self, g: usize) -> RowIdentifier<T, P> {
        self.fast.filter(g, &self.filters.flat()[g])
    }

    /// Every filter up to date and the lanes no longer live (before anything else touches the
    /// filters).
    #[cold]
    #[inline(never)]
    fn leave_lanes(&mut self) {
        let ne = self.structure.equations();
        let stats = (&mut self.eq_ssr[..ne], &mut self.eq_nobs[..ne]);
        self.fast.leave(self.filters.flat_mut(), stats);
    }

    /// The identifier with its filters up to date (for serialization).
    #[cfg(feature = "serde")]
    pub(crate) fn settled(&self) -> Option<Self> {
        self.fast.live().then(|| {
            let mut c = self.clone();
            c.leave_lanes();
            c
        })
    }

    /// Forces the general path from now on (tests: the fast path against it).
    #[cfg(test)]
    pub(crate) fn without_lanes(mut self) -> Self {
        self.leave_lanes();
        self.fast = Fast::none();
        self
    }

    /// The covariance form.
    pub fn form(&self) -> CovarianceForm {
        self.filters.flat().first().map_or(CovarianceForm::Standard, |f| f.form())
    }

    /// `true` while some group is still in its exact start.
    pub fn starting(&self) -> bool {
        self.filters.flat().iter().any(|f| f.starting())
    }

    /// Whether parameter `j` is not identified yet by the data (during an exact start: its
    /// regressor so far is a combination of the others').
    pub fn unidentified(&self, j: usize) -> bool {
        j < self.structure.params()
            && self.filters.flat()[self.part.group_of_param[j] as usize].unidentified(self.part.local[j] as usize)
    }

    /// Equation `i`'s recursive-residual statistics: `(Σ w², samples)` (the residual sum of
    /// squares of least squares on all samples after an exact start, in the equation's own
    /// units; decayed by λ with forgetting).
    pub fn equation_ssr(&self, i: usize) -> (T, T) {
        self.fast.equation(i, (self.eq_ssr[i], self.eq_nobs[i]))
    }

    /// Equation `i`'s variance `r_i`.
    pub fn equation_r(&self, i: usize) -> T {
        self.r[i]
    }

    /// The regression of equation `i` for group filtering: `(y, h)` with `h` in the group's
    /// local parameter order, scaled by the equation's weight. `None` on overflow.
    #[inline(always)]
    fn local_regression(&self, i: usize, x: &[T], z: &[T], u: &[T]) -> (T, SVector<T, P>) {
        Self::regression_of((&self.structure, &self.part, &self.rows, &self.scale), i, x, z, u)
    }

    /// [`Self::local_regression`] from the parts it reads (structure, partition, each
    /// equation's state and row scale).
    #[inline(always)]
    fn regression_of(
        (s, part, rows, scale): (&Structure<T>, &Partition, &[usize; MAX_EQUATIONS], &[T; MAX_EQUATIONS]),
        i: usize,
        x: &[T],
        z: &[T],
        u: &[T],
    ) -> (T, SVector<T, P>) {
        let (y, h) = group_regression::<T, P>(s, part, rows[i], i, x, z, u);
        let w = scale[i];
        (y * w, h * w)
    }

    fn restore(&mut self, touched: u32) {
        restore_groups(self.filters.flat_mut(), self.backup.flat(), touched);
    }
}

impl<T: Real, const P: usize, F: Flat<RowIdentifier<T, P>>> Structured<T, P, F> {
    /// The general update: each equation through its group's [`RowIdentifier::update`] (every
    /// form, the exact start, tracking, the outlier screen), the groups it touched restored
    /// on any error. (Not inlined: the fast path's caller keeps a small frame.)
    #[inline(never)]
    fn update_general(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        let ne = self.structure.equations();
        let (ssr0, nobs0, gated0) = (self.eq_ssr, self.eq_nobs, self.eq_gated);
        let mut touched = 0u32;
        for i in 0..ne {
            let g = self.part.group_of_eq[i] as usize;
            if touched & (1 << g) == 0 {
                touched |= 1 << g;
                self.backup.flat_mut()[g] = self.filters.flat()[g];
            }
            let (y, h) = self.local_regression(i, x, z, u);
            let step = if y.finite() && h.iter().all(|v| v.finite()) {
                let f = &mut self.filters.flat_mut()[g];
                let (ssr, gated, start, lambda) = (f.ssr(), f.gated(), f.starting(), f.forgetting());
                f.update(&h, y).map(|inn| {
                    let decay = if start { T::one() } else { lambda };
                    // The filter's statistics moved by this equation's share, in its own
                    // units; a gated sample's enters Winsorized at the gate, as in the filter
                    // (and in mode rows).
                    if f.gated() != gated {
                        self.eq_gated[i] += 1;
                    }
                    let w = self.scale[i];
                    self.eq_ssr[i] = self.eq_ssr[i] * decay + (f.ssr() - ssr * decay) / (w * w);
                    self.eq_nobs[i] = self.eq_nobs[i] * decay + T::one();
                    inn / self.scale[i]
                })
            } else {
                Err(OVERFLOW)
            };
            match step {
                Ok(v) => e[i] = v,
                Err(err) => {
                    self.restore(touched);
                    (self.eq_ssr, self.eq_nobs, self.eq_gated) = (ssr0, nobs0, gated0);
                    return Err(match err {
                        Error::NonFinite { .. } => OVERFLOW,
                        other => other,
                    });
                }
            }
        }
        self.samples += 1;
        Ok(())
    }
}

/// `true` when every value is finite (`0 · v` is NaN exactly for NaN and ±inf): one pass of
/// arithmetic, no branch per value; the index of a bad value is found by `check_slices`.
#[inline(always)]
fn all_finite<T: Real>(v: &[T]) -> bool {
    v.iter().fold(T::zero(), |a, &b| a + b * T::zero()) == T::zero()
}

/// Equation `i`'s regression `(y, h)` (its state's derivative `z[state]` less its known terms,
/// and the regressor in its group's local parameter order, unweighted; Eq 2.2–2.4 on a
/// structure): what [`Structured`] and [`super::TwoAxleStructured`] feed their group filters.
#[inline(always)]
pub(crate) fn group_regression<T: Real, const P: usize>(
    s: &Structure<T>,
    part: &Partition,
    state: usize,
    i: usize,
    x: &[T],
    z: &[T],
    u: &[T],
) -> (T, SVector<T, P>) {
    let mut h = SVector::<T, P>::zeros();
    let mut y = z[state];
    for t in s.terms(i) {
        let phi = t.coef * s.basis(t.basis, x, z, u);
        match t.param {
            Some(p) => h[part.local[p as usize] as usize] += phi,
            None => y -= phi,
        }
    }
    (y, h)
}

/// The groups' filters before an update put back (`touched`: bit `g` for group `g`): the
/// rollback of an update that failed after some groups had stepped.
pub(crate) fn restore_groups<T: Real, const P: usize>(
    filters: &mut [RowIdentifier<T, P>],
    backup: &[RowIdentifier<T, P>],
    touched: u32,
) {
    for (g, (f, b)) in filters.iter_mut().zip(backup).enumerate() {
        if touched & (1 << g) != 0 {
            *f = *b;
        }
    }
}

/// The block-diagonal covariance of a structure's parameters (`np × np`, row-major) from its
/// groups' filters: `P` of the group on its block, 0 between groups, and during a group's
/// exact start `∞` on its diagonal (nothing identified yet).
///
/// # Errors
/// [`Error::Shape`] for a wrong length.
pub(crate) fn group_covariance_into<T: Real, const P: usize>(
    part: &Partition,
    np: usize,
    filters: &[RowIdentifier<T, P>],
    out: &mut [T],
) -> Result<()> {
    if out.len() != np * np {
        return Err(Error::Shape { arg: "out", expected: np * np, got: out.len() });
    }
    for a in 0..np {
        for b in 0..np {
            let (ga, gb) = (part.group_of_param[a], part.group_of_param[b]);
            let f = &filters[ga as usize];
            out[a * np + b] = if ga != gb {
                T::zero()
            } else if f.starting() {
                if a == b {
                    T::of(f64::INFINITY)
                } else {
                    T::zero()
                }
            } else {
                f.p()[(part.local[a] as usize, part.local[b] as usize)]
            };
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;

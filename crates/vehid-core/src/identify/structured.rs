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
mod tests {
    use super::*;
    use crate::identify::KalmanIdentifier;
    use crate::model::QuarterCar;
    use crate::sim::{SimConfig, Simulator};
    use crate::structure::{Basis, Term, Var};
    use rand::rngs::Xoshiro256PlusPlus;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    fn quarter_samples(n: usize, seed: u64) -> (Vec<[f64; 4]>, Vec<[f64; 4]>) {
        let car = QuarterCar::<f64>::thesis();
        let mut sim =
            Simulator::new(car.model(), SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005), seed).unwrap();
        (0..n)
            .map(|_| {
                let s = sim.next_sample();
                let (x, z) = (s.r, s.z);
                ([x[0], x[1], x[2], x[3]], [z[0], z[1], z[2], z[3]])
            })
            .unzip()
    }

    #[test]
    fn full_rows_are_the_kalman_rows() {
        let (xs, zs) = quarter_samples(3000, 7);
        let s = Structure::<f64>::full_rows(4, &[1, 3]).unwrap();
        let opts = KalmanOptions::default();
        for p0 in [StructuredPrior::Exact, StructuredPrior::Scalar(1000.0)] {
            let r = [81.000025, 2.5e-5];
            let mut a = StructuredKalman::<f64, 4, 2>::new(s, p0, None, &r, opts).unwrap();
            let mut b = match p0 {
                StructuredPrior::Exact => KalmanIdentifier::<f64, 4, 2>::exact(&[1, 3], &r, opts).unwrap(),
                _ => KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r).unwrap(),
            };
            let (mut ea, mut eb) = ([0.0; 2], [0.0; 2]);
            for (x, z) in xs.iter().zip(&zs) {
                a.update_into(x, z, &[], &mut ea).unwrap();
                b.update_into(x, z, &[], &mut eb).unwrap();
                // The innovations (NaN during the exact start, in both).
                assert_eq!(ea.map(f64::to_bits), eb.map(f64::to_bits));
            }
            // Bit for bit: the plain step has the rows identifier's arithmetic.
            let (mut ta, mut tb) = ([0.0; 8], [0.0; 8]);
            a.params_into(&mut ta).unwrap();
            b.params_into(&mut tb).unwrap();
            assert_eq!(ta, tb);
            let (mut ca, mut cb) = ([0.0; 64], [0.0; 64]);
            a.covariance_into(&mut ca).unwrap();
            b.covariance_into(&mut cb).unwrap();
            assert_eq!(ca, cb);
            let (mut sa, mut na, mut sb, mut nb) = ([0.0; 2], [0.0; 2], [0.0; 2], [0.0; 2]);
            a.residuals_into(&mut sa, &mut na).unwrap();
            b.residuals_into(&mut sb, &mut nb).unwrap();
            assert_eq!((sa, na), (sb, nb));
        }
    }

    /// The plain step plans every group before it applies any: a sample the second group
    /// refuses (its own regressor overflows `s`) leaves the first group unchanged too.
    #[test]
    fn plain_step_plans_every_group_before_applying() {
        // ẋ0 = a x0, ẋ1 = b x1: two groups, one equation each.
        let mut s = Structure::<f64>::new(2, 0, 2).unwrap();
        let t = |param, i| Term { coef: 1.0, param: Some(param), basis: Basis::Var(Var::State(i)) };
        s.push_equation(0, &[t(0, 0)]).unwrap();
        s.push_equation(1, &[t(1, 1)]).unwrap();
        let mut id = StructuredKalman::<f64, 1, 2>::new(
            s,
            StructuredPrior::Scalar(10.0),
            None,
            &[1.0],
            KalmanOptions::default(),
        )
        .unwrap();
        let mut e = [0.0; 2];
        for k in 0..50 {
            let x = [1.0 + (k % 7) as f64, 2.0 - (k % 5) as f64];
            id.update_into(&x, &[-2.0 * x[0], 0.5 * x[1]], &[], &mut e).unwrap();
        }
        assert!(id.filter(0).plain() && id.filter(1).plain(), "the fast path is the one tested");
        let before = id.clone();
        assert!(id.update_into(&[1.0, 1e200], &[-2.0, 0.0], &[], &mut e).is_err());
        assert_eq!((before.filter(0), before.filter(1)), (id.filter(0), id.filter(1)));
        assert_eq!((before.equation_ssr(0), before.equation_ssr(1)), (id.equation_ssr(0), id.equation_ssr(1)));
        assert_eq!(before.samples(), id.samples());
    }

    /// A structure with every kind of term, three groups of 3, 2 and 1 parameters (so two
    /// groups of lanes, one lane padding): ẋ0 = a x0 + b u0 + c − 0.5 x1,
    /// ẋ1 = d (x2 − x1) + f sign(x3), ẋ2 = g der(0); its equations pushed in the order
    /// `order` (the parameters' numbering kept: with another order than `[0, 1, 2]` the
    /// groups, numbered by parameter, come in another order than the equations, and the fast
    /// path's lanes are out of the equations' order).
    fn mixed_structure_in_order(order: [usize; 3]) -> Structure<f64> {
        let mut s = Structure::<f64>::new(4, 1, 6).unwrap();
        let (st, len) = s.push_combination(&[(Var::State(3), 1.0)]).unwrap();
        let t = |coef, param, basis| Term { coef, param, basis };
        let v = |i| Basis::Var(Var::State(i));
        for eq in order {
            match eq {
                0 => s.push_equation(
                    0,
                    &[
                        t(1.0, Some(0), v(0)),
                        t(1.0, Some(1), Basis::Var(Var::Input(0))),
                        t(1.0, Some(2), Basis::One),
                        t(0.5, None, v(1)),
                    ],
                ),
                1 => s.push_equation(
                    1,
                    &[t(1.0, Some(3), v(2)), t(-1.0, Some(3), v(1)), t(2.0, Some(4), Basis::Sign { start: st, len })],
                ),
                _ => s.push_equation(2, &[t(1.0, Some(5), Basis::Var(Var::Deriv(0)))]),
            }
            .unwrap();
        }
        s
    }

    /// The fast path (the groups in lanes, the compiled regression) gives what the general
    /// path (each group's `RowIdentifier::update` on the interpreted regression) gives, to
    /// rounding, over many samples: innovations, estimate, covariance, statistics; with a
    /// prior and after an exact start, on the mixed structure (the physical one below), its
    /// equations in the groups' order and out of it.
    #[test]
    fn the_lanes_are_the_general_path() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
        let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
        let samples: Vec<([f64; 4], [f64; 4], [f64; 1])> = (0..3000)
            .map(|_| {
                let (x, u) = ([g(), g(), g(), g()], [g()]);
                let z0 = -2.0 * x[0] + 0.7 * u[0] + 0.3 - 0.5 * x[1] + 0.1 * g();
                let z = [z0, 1.5 * (x[2] - x[1]) - 0.4 * x[3].signum() + 0.2 * g(), 0.8 * z0 + 0.05 * g(), g()];
                (x, z, u)
            })
            .collect();
        let close = |a: f64, b: f64, what: &str| {
            assert!((a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-3), "{what}: {a} vs {b}");
        };
        let r = [0.01, 0.04, 0.0025];
        // The equations in the groups' order, and out of it (equation i in group (i + 2) % 3).
        for (order, p0) in [
            ([0, 1, 2], StructuredPrior::Scalar(100.0)),
            ([0, 1, 2], StructuredPrior::Exact),
            ([2, 0, 1], StructuredPrior::Scalar(100.0)),
        ] {
            let st = mixed_structure_in_order(order);
            let r = order.map(|i| r[i]);
            let fast = StructuredKalman::<f64, 3, 3>::new(st, p0, None, &r, KalmanOptions::default()).unwrap();
            assert_eq!(fast.fast.in_order(), order == [0, 1, 2]);
            let general = fast.clone().without_lanes();
            let (mut a, mut b) = (fast, general);
            let (mut ea, mut eb) = ([0.0; 3], [0.0; 3]);
            for (k, (x, z, u)) in samples.iter().enumerate() {
                a.update_into(x, z, u, &mut ea).unwrap();
                b.update_into(x, z, u, &mut eb).unwrap();
                if k > 20 {
                    (0..3).for_each(|i| close(ea[i], eb[i], "innovation"));
                }
            }
            assert!(a.fast.live() && !b.fast.live(), "each path is the one tested");
            let (mut ta, mut tb) = ([0.0; 6], [0.0; 6]);
            a.params_into(&mut ta).unwrap();
            b.params_into(&mut tb).unwrap();
            (0..6).for_each(|j| close(ta[j], tb[j], "theta"));
            let (mut ca, mut cb) = ([0.0; 36], [0.0; 36]);
            a.covariance_into(&mut ca).unwrap();
            b.covariance_into(&mut cb).unwrap();
            (0..36).for_each(|j| close(ca[j], cb[j], "covariance"));
            let (mut sa, mut na, mut sb, mut nb) = ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3]);
            a.residuals_into(&mut sa, &mut na).unwrap();
            b.residuals_into(&mut sb, &mut nb).unwrap();
            assert_eq!(na, nb);
            (0..3).for_each(|i| close(sa[i], sb[i], "ssr"));
            close(a.trace().unwrap(), b.trace().unwrap(), "trace");
            // A covariance reset (the lanes written back first), then the lanes again.
            a.reset_covariance(10.0).unwrap();
            b.reset_covariance(10.0).unwrap();
            for (x, z, u) in &samples[..300] {
                a.update_into(x, z, u, &mut ea).unwrap();
                b.update_into(x, z, u, &mut eb).unwrap();
            }
            assert!(a.fast.live());
            a.params_into(&mut ta).unwrap();
            b.params_into(&mut tb).unwrap();
            (0..6).for_each(|j| close(ta[j], tb[j], "theta after a reset"));
            // Leaving the lanes gives the filters the lanes held.
            let f = a.filter(1);
            let a = a.without_lanes();
            assert_eq!(a.filter(1), f);
        }
    }

    /// The same on the quarter car's physical structure (m known: differences of states and
    /// a `der(·)` term in two groups of two), simulated data.
    #[test]
    fn the_lanes_are_the_general_path_on_the_physical_structure() {
        let (xs, zs) = quarter_samples(3000, 5);
        let ph = *QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap().structure();
        for p0 in [StructuredPrior::Scalar(1000.0), StructuredPrior::Exact] {
            let mut a = StructuredKalman::<f64, 2, 2>::new(ph, p0, None, &[1.0], KalmanOptions::default()).unwrap();
            let mut b = a.clone().without_lanes();
            let (mut ea, mut eb) = ([0.0; 2], [0.0; 2]);
            for (x, z) in xs.iter().zip(&zs) {
                a.update_into(x, z, &[], &mut ea).unwrap();
                b.update_into(x, z, &[], &mut eb).unwrap();
            }
            assert!(a.fast.live() && !b.fast.live());
            let (mut ta, mut tb) = ([0.0; 4], [0.0; 4]);
            a.params_into(&mut ta).unwrap();
            b.params_into(&mut tb).unwrap();
            for j in 0..4 {
                assert!((ta[j] - tb[j]).abs() <= 1e-9 * ta[j].abs().max(1e-3), "{ta:?} vs {tb:?}");
            }
            let (mut ca, mut cb) = ([0.0; 16], [0.0; 16]);
            a.covariance_into(&mut ca).unwrap();
            b.covariance_into(&mut cb).unwrap();
            for j in 0..16 {
                assert!((ca[j] - cb[j]).abs() <= 1e-9 * ca[j].abs().max(cb[j].abs()) + 1e-300, "{ca:?} vs {cb:?}");
            }
        }
    }

    /// Two equations sharing a parameter, weighted by `r`: every estimate after the start is
    /// weighted least squares on all samples so far (normal equations solved directly).
    #[test]
    fn shared_parameters_are_weighted_least_squares() {
        // ẋ0 = a x0 + b u0, ẋ1 = a x1 + c (one offset): a shared.
        let mut s = Structure::<f64>::new(2, 1, 3).unwrap();
        let t = |coef, param, basis| Term { coef, param: Some(param), basis };
        s.push_equation(0, &[t(1.0, 0, Basis::Var(Var::State(0))), t(1.0, 1, Basis::Var(Var::Input(0)))]).unwrap();
        s.push_equation(1, &[t(1.0, 0, Basis::Var(Var::State(1))), t(1.0, 2, Basis::One)]).unwrap();
        let r = [0.04, 0.25];
        let mut id =
            StructuredKalman::<f64, 3, 1>::new(s, StructuredPrior::Exact, None, &r, KalmanOptions::default()).unwrap();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
        let (mut ata, mut atb) = (nalgebra::Matrix3::<f64>::zeros(), nalgebra::Vector3::<f64>::zeros());
        let mut e = [0.0; 2];
        for k in 0..200 {
            let (x, u) = ([g(), g()], [g()]);
            let z = [-2.0 * x[0] + 0.5 * u[0] + 0.2 * g(), -2.0 * x[1] + 1.5 + 0.5 * g()];
            id.update_into(&x, &z, &u, &mut e).unwrap();
            let rows = [([x[0], u[0], 0.0], z[0], r[0]), ([x[1], 0.0, 1.0], z[1], r[1])];
            for (h, y, ri) in rows {
                let h = nalgebra::Vector3::from(h);
                ata += h * h.transpose() / ri;
                atb += h * y / ri;
            }
            if k >= 3 {
                let want = ata.cholesky().unwrap().solve(&atb);
                let mut got = [0.0; 3];
                id.params_into(&mut got).unwrap();
                for j in 0..3 {
                    assert!((got[j] - want[j]).abs() <= 1e-9 * want[j].abs().max(1.0), "k {k}: {got:?} vs {want:?}");
                }
            }
        }
    }

    #[test]
    fn rejected_samples_change_nothing_and_unexcited_terms_are_named() {
        // ẋ0 = a x0 + c sign(x1): x1 never changes sign, so c is an offset confounded with
        // nothing, but a is fine; then x1 ≡ 0: sign = 0, c unidentified.
        let mut s = Structure::<f64>::new(2, 0, 2).unwrap();
        let (st, len) = s.push_combination(&[(Var::State(1), 1.0)]).unwrap();
        let t = |param, basis| Term { coef: 1.0, param: Some(param), basis };
        s.push_equation(0, &[t(0, Basis::Var(Var::State(0))), t(1, Basis::Sign { start: st, len })]).unwrap();
        let mut id = StructuredKalman::<f64, 2, 1>::exact(s, KalmanOptions::default()).unwrap();
        let mut e = [0.0];
        for k in 0..20 {
            id.update_into(&[1.0 + k as f64, 0.0], &[0.5, 0.0], &[], &mut e).unwrap();
        }
        assert!(id.starting() && !id.unidentified(0) && id.unidentified(1));
        let mut p = [0.0; 2];
        assert!(matches!(id.params_into(&mut p), Err(Error::RankDeficient { rank: 1, needed: 2 })));
        id.update_into(&[1.0, 2.0], &[0.5, 0.0], &[], &mut e).unwrap();
        id.params_into(&mut p).unwrap();
        let before = id.clone();
        assert!(id.update_into(&[f64::NAN, 1.0], &[0.0, 0.0], &[], &mut e).is_err());
        assert!(id.update_into(&[1e300, 1e300], &[1e300, 0.0], &[], &mut e).is_err());
        assert_eq!(before.filter(0), id.filter(0));
        assert_eq!((before.equation_ssr(0), before.samples()), (id.equation_ssr(0), id.samples()));
    }
}

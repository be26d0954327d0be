//! Bias-compensated least squares (BCLS) with a known sensor-noise covariance.
//!
//! With noise on the measured state (`r = x + w`, `w ~ (0, Σ_w)`, white), least squares on
//! `y_i = h_iᵀ p + ε_i` converges to `(E[h hᵀ])⁻¹ E[h y]`, in which the noise adds
//! `E[h̃ h̃ᵀ] = S Σ Sᵀ` (`h̃ = S η` the noise part of the regressor) and `E[h̃ ỹ] = S Σ g` (the
//! part shared with the output): the attenuation bias of the thesis' Eq 2.20. Subtracting both
//! (Söderström, "Errors-in-variables methods in system identification", *Automatica* 43,
//! 2007, §4.3; Stoica & Söderström, *Int. J. Control* 35, 1982; the thesis' own `[I + R Σ_N]`
//! of Eq 5.2–5.6 is the same correction in its stochastic-gradient form):
//!
//! ```text
//! θ̂_BCLS = (Σ_k h hᵀ − N S Σ Sᵀ)⁻¹ (Σ_k h y − N S Σ g)
//! ```
//!
//! — for the thesis' full rows `h = r`, `S = I`, `g = 0`: `θ̂ = (XᵀX − N Σ_w)⁻¹ Xᵀz` row by row.
//! The identifier accumulates `Σ h hᵀ` and `Σ h y` per parameter group (allocation-free, no
//! stored samples, `O(d²)` per equation and sample) and solves when the estimate is read
//! (`O(d³)`, Cholesky). It is consistent when `Σ` is right; a `Σ` too large makes the
//! corrected matrix indefinite ([`Error::Singular`]), too small leaves part of the bias.
//!
//! # What it supports
//! The noise vector is `η = [w; v]`: state noise `w` (covariance `Σ_w`, n × n) and derivative
//! noise `v` (`Σ_v`, default 0), independent of each other and white from sample to sample.
//! Every term's basis function must be *linear* in the noisy variables: a state, `der(·)` of a
//! state, a measured input (taken as exact), an offset; `sign`, `pos`, `neg` only of
//! noise-free variables (a nonlinear function of a noisy state has a bias that depends on
//! the unknown true state: refused with [`Error::Unsupported`]; use instrumental variables).
//! Known (parameter-free) terms may read noisy variables: their noise enters `g`. This covers
//! the full rows of any linear model (with `Σ_w`) and the vehicles' physical structures (the
//! quarter car's wheel equation reads `der(vb)`: give `Σ_v` too).
//!
//! `Σ_w` estimated from the data (it needs more equations than parameters: Söderström 2007
//! §4.3) is [`super::NoiseEstimatingBcls`], which takes them from an instrumental-variable
//! estimate run alongside. Not implemented: a covariance of the estimate (the
//! errors-in-variables sandwich needs fourth moments of the regressors): use
//! [`super::InstrumentalVariables`] for standard errors.

use super::checks::check_slices;
use super::instrumental::{equation_weights, local_regression};
use super::{Dims, Flat, Identifier, OVERFLOW};
use crate::linalg::{cholesky_in_place, cholesky_solve};
use crate::structure::{Basis, Partition, Structure, Var, MAX_EQUATIONS, MAX_STATES};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

/// The noise variables: `n` states then `n` derivatives.
pub(crate) const ETA: usize = 2 * MAX_STATES;

/// One parameter group's sums and noise correction. Serialized as is (feature `serde`); its
/// owner checks it on load ([`BiasCompensated`]'s `restored`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct BcGroup<T: Real, const P: usize> {
    /// `Σ h hᵀ`, `Σ h y` (rows weighted by `√(r_g/r_i)`).
    pub(crate) a: SMatrix<T, P, P>,
    pub(crate) b: SVector<T, P>,
    /// Per sample: `Σ_i w_i² S_i Σ S_iᵀ` and `Σ_i w_i² S_i Σ g_i`.
    pub(crate) c: SMatrix<T, P, P>,
    pub(crate) d: SVector<T, P>,
    pub(crate) dim: u8,
    pub(crate) count: u64,
}

/// Bias-compensated least squares on a [`Structure`] over group storage `F` (module docs):
/// [`BiasCompensatedLs`] (arrays, no allocation) or [`BiasCompensatedVec`] (heap).
///
/// With the feature `serde` the sums and the noise correction are serialized and a
/// deserialized identifier is checked against its structure, so a corrupt input is a serde
/// error; a restored one continues bit for bit.
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct BiasCompensated<T: Real, const P: usize, F: Flat<BcGroup<T, P>>> {
    structure: Structure<T>,
    part: Partition,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    groups: F,
    /// The groups before the current update (of those it touched): scratch, not state
    /// (serialized empty where the store allows, refilled on load).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::scratch"))]
    backup: F,
    rows: [usize; MAX_EQUATIONS],
    r: [T; MAX_EQUATIONS],
    scale: [T; MAX_EQUATIONS],
    samples: u64,
}

/// [`BiasCompensated`] with its `G` groups in an array: no allocation.
pub type BiasCompensatedLs<T, const P: usize, const G: usize> = BiasCompensated<T, P, [BcGroup<T, P>; G]>;

/// [`BiasCompensated`] with its groups in a `Vec` sized at construction (requires `alloc`).
#[cfg(feature = "alloc")]
pub type BiasCompensatedVec<T, const P: usize> = BiasCompensated<T, P, alloc::vec::Vec<BcGroup<T, P>>>;

/// A noise covariance given as one variance (every component), one per component, or the
/// full `n × n` matrix (row-major), into `out` at offset `at`.
fn noise_block<T: Real>(arg: &'static str, v: &[T], n: usize, at: usize, out: &mut [[T; ETA]; ETA]) -> Result<()> {
    crate::error::check_finite(arg, v)?;
    match v.len() {
        0 => {}
        1 => (0..n).for_each(|j| out[at + j][at + j] = v[0]),
        k if k == n => (0..n).for_each(|j| out[at + j][at + j] = v[j]),
        k if k == n * n => {
            for a in 0..n {
                for b in 0..n {
                    out[at + a][at + b] = v[a * n + b];
                }
            }
        }
        k => return Err(Error::Shape { arg, expected: n, got: k }),
    }
    for a in 0..n {
        if out[at + a][at + a] < T::zero() {
            return Err(Error::InvalidArgument { arg, expected: "variances >= 0" });
        }
        for b in 0..n {
            let (x, y) = (out[at + a][at + b], out[at + b][at + a]);
            let bound = (out[at + a][at + a] * out[at + b][at + b]).sqrt();
            if (x - y).abs() > T::default_epsilon() * T::of(16.0) * (x.abs() + y.abs())
                || x.abs() > bound * T::of(1.0 + 1e-12)
            {
                return Err(Error::InvalidArgument {
                    arg,
                    expected: "a covariance matrix: symmetric, |Σ_ab| ≤ √(Σ_aa Σ_bb)",
                });
            }
        }
    }
    Ok(())
}

/// The regressor's and the output's sensitivity to the noise `η = [w; v]` in equation `i`
/// (weighted by `w`), in its group's local parameter order: `S` (local parameter × `η`) and
/// `g` (`η`), so that the regressor's noise is `S η` and the output's is `gᵀ η` (module docs).
/// `noisy(k)` says whether `η_k` carries noise, for the check that no `sign`/`pos`/`neg` term
/// reads a noisy variable.
///
/// # Errors
/// [`Error::Unsupported`] for a `sign`/`pos`/`neg` term of a noisy variable.
#[allow(clippy::type_complexity)]
pub(crate) fn noise_sensitivity<T: Real>(
    structure: &Structure<T>,
    part: &Partition,
    i: usize,
    w: T,
    noisy_var: impl Fn(usize) -> bool,
) -> Result<([[T; ETA]; MAX_PARAMS_LOCAL], [T; ETA])> {
    let n = structure.states();
    let noisy = |v: Var| match v {
        Var::State(j) => Some(j as usize),
        Var::Deriv(j) => Some(n + j as usize),
        Var::Input(_) => None,
    };
    let mut s = [[T::zero(); ETA]; MAX_PARAMS_LOCAL];
    let mut gy = [T::zero(); ETA];
    gy[n + structure.equation_state(i)] = w;
    for t in structure.terms(i) {
        let mut sens = [T::zero(); ETA];
        match t.basis {
            Basis::One => {}
            Basis::Var(v) => {
                if let Some(k) = noisy(v) {
                    sens[k] = T::one();
                }
            }
            Basis::Sign { start, len } | Basis::Pos { start, len } | Basis::Neg { start, len } => {
                let reads_noise =
                    structure.combination(start, len).iter().any(|&(v, _)| noisy(v).is_some_and(&noisy_var));
                if reads_noise {
                    return Err(Error::Unsupported {
                        what: "bias compensation of a sign/pos/neg term of a noisy state or derivative (its bias \
                               depends on the unknown true state): use instrumental variables",
                    });
                }
            }
        }
        match t.param {
            Some(p) => {
                let l = part.local[p as usize] as usize;
                for k in 0..2 * n {
                    s[l][k] += w * t.coef * sens[k];
                }
            }
            None => {
                for k in 0..2 * n {
                    gy[k] -= w * t.coef * sens[k];
                }
            }
        }
    }
    Ok((s, gy))
}

impl<T: Real, const P: usize, F: Flat<BcGroup<T, P>>> BiasCompensated<T, P, F> {
    /// Checks a deserialized identifier (feature `serde`; its structure checked itself)
    /// against its structure, and refills the scratch copy of the groups. Each failure is
    /// [`Error::InvalidArgument`] (`arg` "state") naming what is wrong: the groups (the
    /// structure's partition, at most `P` parameters each, one entry each), the equation rows,
    /// the variances `r` (finite, > 0) and the row weights `√(r_g / r_i)` derived from them,
    /// each group's size and sample count (every sample adds to every group), and its sums
    /// and correction (finite, `Σ h hᵀ` with a diagonal ≥ 0, zero beyond its parameters).
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let corrupt = |expected| Err(Error::InvalidArgument { arg: "state", expected });
        let s = &self.structure;
        let ne = s.equations();
        let part = s.partition();
        let ng = part.groups as usize;
        if part != self.part || part.largest() > P {
            return corrupt("a BCLS identifier's parameter groups: its structure's, of at most P parameters each");
        }
        if self.backup.flat().is_empty() {
            self.backup = self.groups.clone();
        }
        if self.groups.flat().len() != ng || self.backup.flat().len() != ng {
            return corrupt("a BCLS identifier with one set of sums per parameter group");
        }
        if s.equation_states().enumerate().any(|(i, st)| self.rows[i] != st) || self.rows[ne..].iter().any(|&r| r != 0)
        {
            return corrupt("a BCLS identifier's equation rows: its structure's equation states");
        }
        let Ok((_, scale, _)) = equation_weights(&part, ne, &self.r[..ne]) else {
            return corrupt("a BCLS identifier's equation variances r finite and > 0");
        };
        if scale[..ne] != self.scale[..ne] {
            return corrupt("a BCLS identifier's row weights √(r_g / r_i) from its variances r");
        }
        for (g, grp) in self.groups.flat().iter().enumerate() {
            let d = grp.dim as usize;
            if d != part.size[g] as usize || grp.count != self.samples {
                return corrupt("a BCLS identifier's groups of their sizes, each counting every sample");
            }
            let values = grp.a.iter().chain(grp.b.iter()).chain(grp.c.iter()).chain(grp.d.iter());
            if !values.into_iter().all(|v| v.finite()) || (0..d).any(|i| grp.a[(i, i)] < T::zero()) {
                return corrupt("a BCLS identifier's sums and correction finite, Σ h hᵀ with a diagonal ≥ 0");
            }
            let outside = (0..P).any(|i| {
                (i >= d && (grp.b[i] != T::zero() || grp.d[i] != T::zero()))
                    || (0..P).any(|j| (i >= d || j >= d) && (grp.a[(i, j)] != T::zero() || grp.c[(i, j)] != T::zero()))
            });
            if outside {
                return corrupt("a BCLS identifier's sums and correction zero beyond each group's parameters");
            }
        }
        Ok(())
    }

    /// A BCLS identifier of `structure`'s parameters for state-noise covariance
    /// `state_noise_var` (`Σ_w`, state units²: one variance, one per state, or `n × n`
    /// row-major), derivative-noise covariance `deriv_noise_var` (`Σ_v`, (state units/s)²;
    /// empty: 0) and equation variances `r` (one or one per equation; they only weigh
    /// equations that share parameters).
    ///
    /// # Errors
    /// [`Error::NotIdentifiable`] for an unused or confounded parameter; [`Error::Capacity`]
    /// for a group over `P` parameters or groups `F` cannot hold; [`Error::Unsupported`] for a
    /// `sign`/`pos`/`neg` term of a noisy variable; [`Error::Shape`] / [`Error::InvalidArgument`]
    /// naming `state_noise_var`, `deriv_noise_var` or `r`.
    pub fn new(structure: Structure<T>, state_noise_var: &[T], deriv_noise_var: &[T], r: &[T]) -> Result<Self> {
        structure.check_identifiable()?;
        let part = structure.partition();
        let (n, ne, ng) = (structure.states(), structure.equations(), part.groups as usize);
        if part.largest() > P {
            return Err(Error::Capacity { arg: "P", needed: part.largest(), capacity: P });
        }
        if state_noise_var.is_empty() {
            return Err(Error::Shape { arg: "state_noise_var", expected: n, got: 0 });
        }
        let mut sigma = [[T::zero(); ETA]; ETA];
        noise_block("state_noise_var", state_noise_var, n, 0, &mut sigma)?;
        noise_block("deriv_noise_var", deriv_noise_var, n, n, &mut sigma)?;
        let (r_all, scale, _) = equation_weights(&part, ne, r)?;
        let zero = BcGroup {
            a: SMatrix::zeros(),
            b: SVector::zeros(),
            c: SMatrix::zeros(),
            d: SVector::zeros(),
            dim: 0,
            count: 0,
        };
        let mut groups = F::filled("groups", ng, zero)?;
        for (g, grp) in groups.flat_mut().iter_mut().enumerate() {
            grp.dim = part.size[g];
        }
        for i in 0..ne {
            let noisy_given = |k: usize| sigma[k][k] > T::zero();
            let (s, gy) = noise_sensitivity(&structure, &part, i, scale[i], noisy_given)?;
            let grp = &mut groups.flat_mut()[part.group_of_eq[i] as usize];
            let d = grp.dim as usize;
            for a in 0..d {
                // (S Σ)_a·
                let mut sa = [T::zero(); ETA];
                for k in 0..2 * n {
                    sa[k] = (0..2 * n).fold(T::zero(), |acc, l| acc + s[a][l] * sigma[l][k]);
                }
                for b in 0..d {
                    grp.c[(a, b)] += (0..2 * n).fold(T::zero(), |acc, k| acc + sa[k] * s[b][k]);
                }
                grp.d[a] += (0..2 * n).fold(T::zero(), |acc, k| acc + sa[k] * gy[k]);
            }
        }
        for grp in groups.flat() {
            if !(grp.c.iter().chain(grp.d.iter()).all(|v| v.finite())) {
                return Err(Error::InvalidArgument {
                    arg: "state_noise_var",
                    expected: "variances small enough that the noise correction stays finite (rescale the units)",
                });
            }
        }
        let mut rows = [0usize; MAX_EQUATIONS];
        for (i, st) in structure.equation_states().enumerate() {
            rows[i] = st;
        }
        Ok(Self { structure, part, backup: groups.clone(), groups, rows, r: r_all, scale, samples: 0 })
    }

    /// The thesis' full unknown rows of an `n`-state linear model with state-noise
    /// covariance `state_noise_var` (one, `n`, or `n × n` values): `θ̂ = (XᵀX − N Σ_w)⁻¹ Xᵀz`
    /// per row.
    ///
    /// # Errors
    /// As [`Structure::full_rows`] and [`BiasCompensated::new`].
    pub fn full_rows(n: usize, rows: &[usize], state_noise_var: &[T]) -> Result<Self> {
        Self::new(Structure::full_rows(n, rows)?, state_noise_var, &[], &[T::one()])
    }

    /// The structure identified.
    pub fn structure(&self) -> &Structure<T> {
        &self.structure
    }

    /// Group `g`'s per-sample noise correction `(Σ_i w_i² S_i Σ S_iᵀ, Σ_i w_i² S_i Σ g_i)`.
    pub fn correction(&self, g: usize) -> (&SMatrix<T, P, P>, &SVector<T, P>) {
        let grp = &self.groups.flat()[g];
        (&grp.c, &grp.d)
    }

    /// Group `g`'s estimate (its `dim` leading entries) with its own noise correction.
    fn solve(&self, g: usize) -> Result<SVector<T, P>> {
        let grp = &self.groups.flat()[g];
        self.solve_with(g, &grp.c, &grp.d)
    }

    /// Group `g`'s estimate `(Σ h hᵀ − N c)⁻¹ (Σ h y − N d)` with the per-sample noise
    /// correction `(c, d)` given (its leading `dim` entries are read).
    ///
    /// # Errors
    /// [`Error::RankDeficient`] while the data do not span the group's parameters;
    /// [`Error::Singular`] when the corrected matrix is not positive definite.
    pub(crate) fn solve_with(&self, g: usize, c: &SMatrix<T, P, P>, dv: &SVector<T, P>) -> Result<SVector<T, P>> {
        let grp = &self.groups.flat()[g];
        let d = grp.dim as usize;
        let nn = T::of(grp.count as f64);
        let mut m = SMatrix::<T, P, P>::identity();
        let mut a = SMatrix::<T, P, P>::identity();
        let mut v = SVector::<T, P>::zeros();
        for i in 0..d {
            for j in 0..d {
                a[(i, j)] = grp.a[(i, j)];
                m[(i, j)] = grp.a[(i, j)] - nn * c[(i, j)];
            }
            v[i] = grp.b[i] - nn * dv[i];
        }
        // Equilibrate by diag(Σ h hᵀ)^{-1/2} before judging definiteness.
        let mut w = SVector::<T, P>::repeat(T::one());
        for i in 0..d {
            let x = a[(i, i)];
            if !(x > T::zero()) {
                return Err(Error::RankDeficient { rank: 0, needed: d });
            }
            w[i] = T::one() / x.sqrt();
        }
        // Cholesky factors of the equilibrated leading blocks (row-major d × d).
        let factor = |x: &SMatrix<T, P, P>| {
            let mut f = [T::zero(); MAX_PARAMS_LOCAL * MAX_PARAMS_LOCAL];
            for i in 0..d {
                for j in 0..d {
                    f[i * d + j] = x[(i, j)] * w[i] * w[j];
                }
            }
            let ok = cholesky_in_place(&mut f[..d * d], d);
            (f, ok)
        };
        let tol = T::default_epsilon().sqrt() * T::of(d as f64);
        let (fa, ok) = factor(&a);
        if !ok || (0..d).any(|i| !(fa[i * d + i] * fa[i * d + i] > tol)) {
            return Err(Error::RankDeficient { rank: 0, needed: d });
        }
        let (fm, ok) = factor(&m);
        if !ok {
            return Err(Error::Singular {
                what: "the bias-compensated normal matrix Σ h hᵀ − N S Σ Sᵀ (the noise covariance given exceeds what \
                       the data show in some direction: state_noise_var too large, or too few samples)",
            });
        }
        let mut z = [T::zero(); MAX_PARAMS_LOCAL];
        for i in 0..d {
            z[i] = v[i] * w[i];
        }
        cholesky_solve(&fm[..d * d], d, &mut z[..d]);
        Ok(SVector::from_fn(|i, _| if i < d { z[i] * w[i] } else { T::zero() }))
    }

    /// Group `g`'s sums and correction.
    pub(crate) fn group(&self, g: usize) -> &BcGroup<T, P> {
        &self.groups.flat()[g]
    }

    /// The parameter groups (the structure's partition).
    pub(crate) fn partition(&self) -> &Partition {
        &self.part
    }

    /// Each equation's row weight `√(r_g / r_i)`.
    pub(crate) fn scale(&self, i: usize) -> T {
        self.scale[i]
    }

    /// Undoes the last accepted [`Identifier::update_into`] bit for bit (every group is touched
    /// by every sample, as every group has an equation, so the scratch copy holds them all as
    /// they were). Only right after an accepted update: the caller's transaction failed later.
    pub(crate) fn revert_last(&mut self) {
        // At most MAX_EQUATIONS (16) groups.
        let all = (1u32 << self.part.groups) - 1;
        self.restore(all);
        self.samples -= 1;
    }

    fn restore(&mut self, touched: u32) {
        for g in 0..self.part.groups as usize {
            if touched & (1 << g) != 0 {
                self.groups.flat_mut()[g] = self.backup.flat()[g];
            }
        }
    }
}

/// Local parameters a group can have (the structure's capacity).
pub(crate) const MAX_PARAMS_LOCAL: usize = crate::structure::MAX_PARAMS;

super::persist_by_serde!([T: Real, const P: usize, F: Flat<BcGroup<T, P>>] BiasCompensated<T, P, F>);

impl<T: Real, const P: usize, F: Flat<BcGroup<T, P>>> Identifier<T> for BiasCompensated<T, P, F> {
    fn dims(&self) -> Dims {
        super::buffers::structure_dims(&self.structure)
    }

    fn rows(&self) -> &[usize] {
        &self.rows[..self.structure.equations()]
    }

    /// Adds one sample to the sums. The innovations are NaN: the estimate is solved only
    /// when read ([`Identifier::params_into`]), as for batch least squares.
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        check_slices(self.dims(), x, z, u, e)?;
        let ne = self.structure.equations();
        let mut touched = 0u32;
        for i in 0..ne {
            let g = self.part.group_of_eq[i] as usize;
            if touched & (1 << g) == 0 {
                touched |= 1 << g;
                self.backup.flat_mut()[g] = self.groups.flat()[g];
                self.groups.flat_mut()[g].count += 1;
            }
            let (y, h) = local_regression::<T, P>(&self.structure, &self.part, i, self.scale[i], x, z, u);
            let grp = &mut self.groups.flat_mut()[g];
            grp.a.ger(T::one(), &h, &h, T::one());
            grp.b.axpy(y, &h, T::one());
            if !(grp.a.iter().chain(grp.b.iter()).all(|v| v.finite())) {
                self.restore(touched);
                return Err(OVERFLOW);
            }
            e[i] = T::of(f64::NAN);
        }
        self.samples += 1;
        Ok(())
    }

    /// Solves every group: `(Σ h hᵀ − N C)⁻¹ (Σ h y − N d)`.
    ///
    /// # Errors
    /// [`Error::RankDeficient`] while the data do not span a group's parameters;
    /// [`Error::Singular`] when the corrected matrix is not positive definite.
    fn params_into(&self, out: &mut [T]) -> Result<()> {
        let np = self.structure.params();
        if out.len() != np {
            return Err(Error::Shape { arg: "out", expected: np, got: out.len() });
        }
        for g in 0..self.part.groups as usize {
            let th = self.solve(g).map_err(|e| match e {
                Error::RankDeficient { .. } => Error::RankDeficient { rank: 0, needed: np },
                other => other,
            })?;
            for j in (0..np).filter(|&j| self.part.group_of_param[j] as usize == g) {
                out[j] = th[self.part.local[j] as usize];
            }
        }
        Ok(())
    }

    fn samples(&self) -> u64 {
        self.samples
    }

    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        super::buffers::diagonal_noise_into(&self.r[..self.structure.equations()], out)
    }

    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        let _ = out;
        Err(Error::Unsupported {
            what: "a parameter covariance for bias-compensated least squares (its errors-in-variables sandwich needs \
                   fourth moments of the data): use IVIdentifier for standard errors",
        })
    }

    fn groups_into(&self, group_of_param: &mut [usize], group_of_eq: &mut [usize]) -> Result<()> {
        let (np, ne) = (self.structure.params(), self.structure.equations());
        super::buffers::partition_groups_into(&self.part, np, ne, group_of_param, group_of_eq)
    }
}

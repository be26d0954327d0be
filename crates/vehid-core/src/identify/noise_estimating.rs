//! Bias-compensated least squares with the state-noise variances estimated from the data.
//!
//! [`super::BiasCompensated`] removes the attenuation bias of least squares when it is told
//! the state-noise covariance `Σ_w`. Here `Σ_w` (diagonal: one variance `σ_j²` per state,
//! state units²) is estimated from the same samples, recursively, by the bias-eliminating
//! idea of Zheng (W. X. Zheng, "A bias correction method for identification of linear
//! dynamic errors-in-variables models", *IEEE Trans. Automatic Control* 47, 2002;
//! "Transfer function estimation from noisy input and output data", *Int. J. Adaptive Control
//! and Signal Processing* 12, 1998) with the extra equations supplied by an instrumental-
//! variable estimate (Söderström, *Errors-in-Variables Methods in System Identification*,
//! Springer 2018, Ch. 7 "bias-eliminating methods" and Ch. 6 "instrumental variable
//! methods"; its §7.2 gives the estimating equation used below).
//!
//! # The equations
//! For one parameter group with sums `A = Σ_k h hᵀ`, `b = Σ_k h y` over `N` samples, the
//! least-squares normal equations are biased by the regressor noise: for white noise
//! `η = [w; v]` (states, derivatives; independent of the true signals and of each other),
//!
//! ```text
//! (A/N − C(Σ)) θ = b/N − d(Σ) + o(1),   C(Σ) = Σ_i S_i Σ S_iᵀ,   d(Σ) = Σ_i S_i Σ g_i
//! ```
//!
//! (`S_i`, `g_i` the regressor's and the output's noise sensitivities of equation `i`, rows
//! weighted by `√(r_g/r_i)`; [`super::BiasCompensated`]'s module docs). With `Σ_w`
//! diagonal and `Σ_v` known, `C` and `d` are linear in the unknown variances:
//! `C = C_v + Σ_j σ_j² C_j`, `d = d_v + Σ_j σ_j² d_j` with `C_j = Σ_i s_ij s_ijᵀ`,
//! `d_j = Σ_i s_ij g_ij` (`s_ij` the column of `S_i` of state `j`). Given a consistent
//! estimate `θ̃` (here: recursive instrumental variables, [`super::InstrumentalVariables`],
//! run alongside on the same samples), the residual of the uncompensated normal equations
//!
//! ```text
//! ρ = (A θ̃ − b)/N − (C_v θ̃ − d_v)  ≈  Σ_j σ_j² φ_j,     φ_j = C_j θ̃ − d_j
//! ```
//!
//! is linear in the variances. Stacking every group's `ρ` and `φ_j` gives an overdetermined
//! linear problem for `σ² = (σ_0², …)` — for the thesis' full rows (`S_i = I`, `g_i = 0`)
//! `ρ_ij = σ_j² θ̃_ij`, two equations (rows 1 and 3) per state — solved by weighted least
//! squares under `σ_j² ≥ 0` (non-negative least squares by cyclic coordinate descent on the
//! `n × n` normal equations, which for full rows is exact in one sweep):
//!
//! ```text
//! σ̂² = argmin_{σ² ≥ 0} Σ_{g,l} ω_gl (ρ_gl − Σ_j σ_j² φ_j,gl)²,   ω_gl = N / (s_g² A_ll)
//! ```
//!
//! The weight `ω_gl` is the inverse of `ρ_gl`'s sampling variance `s_g² A_ll / N²` (white
//! equation error of variance `s_g²`, the instrumental estimate's per-sample residual
//! variance): without it the wheel row (equation noise variance ≈ 81 from the road) would
//! dominate the body row (≈ 10⁻²). For full rows and equal weights this is the pooled
//! `σ̂_j² = Σ_i θ̃_ij ρ_ij / Σ_i θ̃_ij²` (weighted by `θ̃_ij²`); on the development seeds
//! (quarter car, full rows, 8 %) equal weights gave σ̂ errors 3–10 times larger and a worst ξ
//! of 8.2 against 1.18. Then the compensated estimate
//! is [`super::BiasCompensated`]'s with `Σ̂`:
//!
//! ```text
//! θ̂ = (A − N C(Σ̂))⁻¹ (b − N d(Σ̂))
//! ```
//!
//! Not iterated, because iterating changes nothing: `θ̂` solves
//! `(A/N − C(Σ̂)) θ̂ = b/N − d(Σ̂)`, so at `θ̃ = θ̂` the residual is `ρ(θ̂) = Σ_j σ̂_j² φ_j(θ̂)`
//! exactly and the fit returns `Σ̂` again (on the development seeds one and two further
//! passes gave the same ξ to every printed digit). Every pair `(θ̂(Σ), Σ)` is such a fixed
//! point: the least-squares equations alone (one per parameter) cannot fix the parameters
//! and the variances together, and it is the instrumental equations that anchor `θ̃`
//! (the extra equations every bias-eliminating scheme needs: Söderström 2018 Ch. 7).
//!
//! # Conditions (when `σ̂_j²` means something)
//! - The state noise is white (independent from sample to sample), zero-mean, independent
//!   of the true state and of the derivative noise; `Σ_w` is diagonal (independent sensors).
//!   Coloured noise biases `θ̃` (the instruments fail, [`super::InstrumentalVariables`]) and
//!   with it `σ̂²`.
//! - Only the states that some parameterized term reads (as a state, linearly) are
//!   estimated; the others are reported as NaN ([`NoiseEstimatingBcls::state_noise_var_into`])
//!   and their noise does not bias the regression. `sign`/`pos`/`neg` terms of states are
//!   refused ([`Error::Unsupported`]), as every state is taken as noisy.
//! - `σ_j²` is determined by the parameters that multiply state `j`: with every `θ_ij ≈ 0`
//!   its column `φ_j` vanishes and `σ̂_j²` is noise, while `C_j` still applies it in full.
//!   States that always enter together (the quarter car's physical structure reads the
//!   velocities only as `vb − vw`) are determined only as that combination (what the
//!   compensation needs); the split between them is arbitrary.
//! - The derivative noise `Σ_v` is given (it enters the regressors of structures with
//!   `der(·)` terms; for full rows it never biases the estimate and may be left empty).
//!
//! - `θ̃` must be good: with the instruments the regressors one sample back, the quarter car's
//!   wheel row is too scattered (the fast wheel mode: [`super::InstrumentalVariables`]) and
//!   the wheel velocity's `σ̂²` is often clamped at 0; the refined instruments
//!   ([`InstrumentalVariables::with_lags`]) put every state's `σ̂` within a few percent.
//!
//! # Cost
//! Per sample: [`super::BiasCompensated`]'s `O(d²)` sums and [`super::InstrumentalVariables`]'s
//! recursive step, no allocation; the estimate is solved when read (`O(d³)` per group and
//! `O(n² + Σ terms · n)` for the variances).

use super::bias_compensated::{noise_sensitivity, BcGroup, MAX_PARAMS_LOCAL};
use super::checks::check_lengths;
use super::{BiasCompensated, Dims, Flat, Identifier, InstrumentalVariables, IvFilter, StructuredPrior};
use crate::structure::{Structure, MAX_EQUATIONS, MAX_PARAMS, MAX_STATES};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

/// Coordinate-descent sweeps of the variances' non-negative least squares at most.
const MAX_SWEEPS: usize = 500;

/// Bias-compensated least squares with the state-noise variances estimated from the data
/// (module docs), on a [`Structure`]: the sums of [`BiasCompensated`] (storage `F`) and an
/// [`InstrumentalVariables`] identifier (storage `FI`, refined instruments of capacity `Q`)
/// fed the same samples. Aliases: [`NoiseEstimatingBclsLs`] (arrays, no allocation),
/// [`NoiseEstimatingBclsVec`] (heap).
///
/// # Examples
/// The quarter car's full rows 1 and 3 with 8 % state noise:
/// ```
/// use vehid_core::identify::{Identifier, NoiseEstimatingBclsLs};
/// use vehid_core::model::QuarterCar;
/// use vehid_core::sim::{SimConfig, Simulator};
///
/// let car = QuarterCar::<f64>::thesis();
/// let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.1).state_noise(0.008);
/// let mut sim = Simulator::new(car.model(), cfg, 7)?;
/// // Refined instruments (delay 1, 6 lags of the 8 values of a sample, and a constant: Q = 49).
/// let mut id = NoiseEstimatingBclsLs::<f64, 4, 2, 49>::full_rows(4, &[1, 3], 1, 6)?;
/// let mut e = [0.0; 2];
/// for _ in 0..20_000 {
///     let s = sim.next_sample();
///     id.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e)?;
/// }
/// let mut var = [0.0; 4];
/// id.state_noise_var_into(&mut var)?;
/// assert!(var.iter().all(|v| (v.sqrt() / 0.008 - 1.0).abs() < 0.1), "{var:?}");
/// let mut theta = [0.0; 8];
/// id.params_into(&mut theta)?;
/// # Ok::<(), vehid_core::Error>(())
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct NoiseEstimatingBcls<
    T: Real,
    const P: usize,
    F: Flat<BcGroup<T, P>>,
    FI: Flat<IvFilter<T, P>>,
    const Q: usize = 0,
> {
    /// The least-squares sums `A`, `b` and the known part of the correction (`Σ_v`).
    bc: BiasCompensated<T, P, F>,
    /// The consistent estimate `θ̃`.
    iv: InstrumentalVariables<T, P, FI, Q>,
    /// Bit `j`: state `j`'s variance is estimated (some parameterized term reads it).
    estimated: u32,
}

/// [`NoiseEstimatingBcls`] with its `G` groups in arrays (no allocation at all) and a refined
/// instruments' predictor of capacity `Q` (0: delayed regressors only).
pub type NoiseEstimatingBclsLs<T, const P: usize, const G: usize, const Q: usize = 0> =
    NoiseEstimatingBcls<T, P, [BcGroup<T, P>; G], [IvFilter<T, P>; G], Q>;

/// [`NoiseEstimatingBcls`] with its groups in `Vec`s sized at construction (requires `alloc`).
#[cfg(feature = "alloc")]
pub type NoiseEstimatingBclsVec<T, const P: usize, const Q: usize = 0> =
    NoiseEstimatingBcls<T, P, alloc::vec::Vec<BcGroup<T, P>>, alloc::vec::Vec<IvFilter<T, P>>, Q>;

/// The states read linearly by some parameterized term of `s` (bit `j`: state `j`).
///
/// # Errors
/// [`Error::Unsupported`] for a `sign`/`pos`/`neg` term of a state.
fn read_states<T: Real>(s: &Structure<T>) -> Result<u32> {
    let (n, part) = (s.states(), s.partition());
    let mut mask = 0u32;
    for i in 0..s.equations() {
        let (sm, _) = noise_sensitivity(s, &part, i, T::one(), |k| k < n)?;
        for row in sm.iter().take(part.size[part.group_of_eq[i] as usize] as usize) {
            for (j, v) in row.iter().take(n).enumerate() {
                if *v != T::zero() {
                    mask |= 1 << j;
                }
            }
        }
    }
    Ok(mask)
}

impl<T: Real, const P: usize, F: Flat<BcGroup<T, P>>, FI: Flat<IvFilter<T, P>>, const Q: usize>
    NoiseEstimatingBcls<T, P, F, FI, Q>
{
    /// Checks a deserialized identifier (feature `serde`; its two parts checked themselves):
    /// both on the same structure, having seen the same samples, and the estimated states
    /// those the structure reads. Each failure is [`Error::InvalidArgument`] (`arg` "state").
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let corrupt = |expected| Err(Error::InvalidArgument { arg: "state", expected });
        if self.bc.structure() != self.iv.structure() || self.bc.samples() != self.iv.samples() {
            return corrupt(
                "a noise-estimating BCLS identifier whose sums and instruments share structure and samples",
            );
        }
        if read_states(self.bc.structure()).ok() != Some(self.estimated) {
            return corrupt("a noise-estimating BCLS identifier estimating the states its structure reads");
        }
        Ok(())
    }

    /// The identifier on `iv`'s structure, with `iv` (any instruments, prior and equation
    /// variances `r`, which also weigh the least-squares rows; it must have seen no sample)
    /// giving the consistent estimate `θ̃`, and the derivative-noise covariance
    /// `deriv_noise_var` (`Σ_v`, (state units/s)²: one variance, one per state, or `n × n`
    /// row-major; empty: 0) known. Every state's noise variance that a parameterized term
    /// reads is estimated.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming `iv` when it has seen samples; [`Error::Unsupported`]
    /// for a `sign`/`pos`/`neg` term of a state or noisy derivative; as [`BiasCompensated::new`]
    /// for `deriv_noise_var` and the groups' capacity `F`.
    pub fn new(iv: InstrumentalVariables<T, P, FI, Q>, deriv_noise_var: &[T]) -> Result<Self> {
        if iv.samples() > 0 {
            return Err(Error::InvalidArgument {
                arg: "iv",
                expected: "an instrumental-variable identifier that has seen no sample (both parts must see the \
                           same ones)",
            });
        }
        let s = *iv.structure();
        let ne = s.equations();
        let mut rm = [T::zero(); MAX_EQUATIONS * MAX_EQUATIONS];
        iv.noise_into(&mut rm[..ne * ne])?;
        let r: [T; MAX_EQUATIONS] = core::array::from_fn(|i| if i < ne { rm[i * ne + i] } else { T::one() });
        let estimated = read_states(&s)?;
        let bc = BiasCompensated::new(s, &[T::zero()], deriv_noise_var, &r[..ne])?;
        Ok(Self { bc, iv, estimated })
    }

    /// The thesis' full unknown rows of an `n`-state linear model (parameters the rows of
    /// `A`, row-major), with instruments the regressors `delay ≥ 1` samples back (`lags = 0`)
    /// or refined through `lags` past samples ([`InstrumentalVariables::with_lags`], which
    /// needs `Q ≥ lags · 2n + 1`), exact start, unit weights, no derivative noise correction
    /// (none is needed: full rows read no derivative).
    ///
    /// # Errors
    /// As [`Structure::full_rows`], [`InstrumentalVariables::new`],
    /// [`InstrumentalVariables::with_lags`] and [`NoiseEstimatingBcls::new`].
    pub fn full_rows(n: usize, rows: &[usize], delay: usize, lags: usize) -> Result<Self> {
        let iv = InstrumentalVariables::full_rows(n, rows, delay, StructuredPrior::Exact, &[T::one()])?;
        Self::new(iv.with_lags(lags)?, &[])
    }

    /// The structure identified.
    pub fn structure(&self) -> &Structure<T> {
        self.bc.structure()
    }

    /// The instrumental-variable identifier that gives `θ̃` (its estimate, covariance and
    /// residuals are those of instrumental variables alone).
    pub fn instrumental(&self) -> &InstrumentalVariables<T, P, FI, Q> {
        &self.iv
    }

    /// `true` when state `j`'s noise variance is estimated (some parameterized term reads
    /// the state); `false` for `j ≥ n`.
    pub fn estimates_state(&self, j: usize) -> bool {
        j < self.bc.structure().states() && self.estimated & (1 << j) != 0
    }

    /// The estimated state-noise variances `σ̂_j²` (state units², `n` values, ≥ 0; NaN for the
    /// states no parameterized term reads) into `out` (module docs: the weighted
    /// non-negative least-squares fit of `ρ = Σ_j σ_j² φ_j`).
    ///
    /// # Errors
    /// [`Error::Shape`] for a wrong length; [`Error::RankDeficient`] while the instrumental
    /// estimate is starting.
    pub fn state_noise_var_into(&self, out: &mut [T]) -> Result<()> {
        let n = self.bc.structure().states();
        if out.len() != n {
            return Err(Error::Shape { arg: "out", expected: n, got: out.len() });
        }
        let var = self.variances()?;
        for (j, o) in out.iter_mut().enumerate() {
            *o = if self.estimates_state(j) { var[j] } else { T::of(f64::NAN) };
        }
        Ok(())
    }

    /// Group `g`'s local parameters from the full vector `th`.
    fn local(&self, g: usize, th: &[T]) -> SVector<T, P> {
        let part = self.bc.partition();
        let mut v = SVector::<T, P>::zeros();
        for (j, &t) in th.iter().enumerate() {
            if part.group_of_param[j] as usize == g {
                v[part.local[j] as usize] = t;
            }
        }
        v
    }

    /// `σ̂²` (module docs), fitted at the instrumental estimate `θ̃`.
    fn variances(&self) -> Result<[T; MAX_STATES]> {
        let s = self.bc.structure();
        let (n, ne, np) = (s.states(), s.equations(), s.params());
        let part = *self.bc.partition();
        let mut th = [T::zero(); MAX_PARAMS];
        self.iv.params_into(&mut th[..np])?;
        let (mut ssr, mut nobs) = ([T::zero(); MAX_EQUATIONS], [T::zero(); MAX_EQUATIONS]);
        self.iv.residuals_into(&mut ssr[..ne], &mut nobs[..ne])?;
        // The normal equations of the weighted fit, n × n.
        let mut gm = [[T::zero(); MAX_STATES]; MAX_STATES];
        let mut cv = [T::zero(); MAX_STATES];
        for g in 0..part.groups as usize {
            let grp = self.bc.group(g);
            let d = grp.dim as usize;
            let nn = T::of(grp.count as f64);
            let tg = self.local(g, &th[..np]);
            let rho = (grp.a * tg - grp.b) / nn - (grp.c * tg - grp.d);
            let mut phi = [SVector::<T, P>::zeros(); MAX_STATES];
            // The group's equation-error variance per sample (rows weighted as in the sums).
            let mut s2 = T::zero();
            for i in (0..ne).filter(|&i| part.group_of_eq[i] as usize == g) {
                let w = self.bc.scale(i);
                if nobs[i] > T::zero() {
                    s2 += w * w * ssr[i] / nobs[i];
                }
                let (sm, gy) = noise_sensitivity(s, &part, i, w, |_| false)?;
                for j in (0..n).filter(|&j| self.estimated & (1 << j) != 0) {
                    let proj = (0..d).fold(T::zero(), |acc, l| acc + sm[l][j] * tg[l]) - gy[j];
                    for l in 0..d {
                        phi[j][l] += sm[l][j] * proj;
                    }
                }
            }
            for l in 0..d {
                // ρ_gl's sampling variance is s² A_ll / N²: weight by its inverse (× 1/N).
                let v = s2 * grp.a[(l, l)] / nn;
                let om = if v > T::zero() && v.finite() { T::one() / v } else { T::one() };
                for j in 0..n {
                    cv[j] += om * phi[j][l] * rho[l];
                    for k in 0..n {
                        gm[j][k] += om * phi[j][l] * phi[k][l];
                    }
                }
            }
        }
        Ok(nnls(&gm, &cv, n, self.estimated).0)
    }

    /// Group `g`'s per-sample correction with the estimated variances `var` added to the
    /// known `Σ_v` part: `(C_v + Σ_j σ̂_j² C_j, d_v + Σ_j σ̂_j² d_j)`.
    fn correction(&self, g: usize, var: &[T; MAX_STATES]) -> Result<(SMatrix<T, P, P>, SVector<T, P>)> {
        let s = self.bc.structure();
        let (n, ne) = (s.states(), s.equations());
        let part = *self.bc.partition();
        let grp = self.bc.group(g);
        let d = grp.dim as usize;
        let (mut c, mut dv) = (grp.c, grp.d);
        for i in (0..ne).filter(|&i| part.group_of_eq[i] as usize == g) {
            let (sm, gy) = noise_sensitivity(s, &part, i, self.bc.scale(i), |_| false)?;
            for j in (0..n).filter(|&j| self.estimated & (1 << j) != 0) {
                for a in 0..d {
                    let sa = var[j] * sm[a][j];
                    for b in 0..d {
                        c[(a, b)] += sa * sm[b][j];
                    }
                    dv[a] += sa * gy[j];
                }
            }
        }
        Ok((c, dv))
    }
}

/// `argmin_{x ≥ 0} ½ xᵀ G x − cᵀ x` over the coordinates in `mask` (the others 0) by cyclic
/// coordinate descent (Gauss–Seidel projected on `x ≥ 0`; exact in one sweep for a diagonal
/// `G`), until no coordinate moves by more than `8 ε` of the largest, or [`MAX_SWEEPS`].
/// A coordinate with `G_jj ≤ 0` (its column vanishes: nothing determines it) stays 0.
/// Returns `x` and the sweeps made.
fn nnls<T: Real>(
    g: &[[T; MAX_STATES]; MAX_STATES],
    c: &[T; MAX_STATES],
    n: usize,
    mask: u32,
) -> ([T; MAX_STATES], usize) {
    let mut x = [T::zero(); MAX_STATES];
    let tol = T::default_epsilon() * T::of(8.0);
    for sweep in 1..=MAX_SWEEPS {
        let (mut moved, mut size) = (T::zero(), T::zero());
        for j in (0..n).filter(|&j| mask & (1 << j) != 0) {
            if !(g[j][j] > T::zero()) {
                continue;
            }
            let r = c[j] - (0..n).fold(T::zero(), |acc, k| acc + g[j][k] * x[k]);
            let new = (x[j] + r / g[j][j]).max(T::zero());
            moved = moved.max((new - x[j]).abs());
            size = size.max(new.abs());
            x[j] = new;
        }
        if !(moved > tol * size) {
            return (x, sweep);
        }
    }
    (x, MAX_SWEEPS)
}

super::persist_by_serde!([T: Real, const P: usize, F: Flat<BcGroup<T, P>>, FI: Flat<IvFilter<T, P>>, const Q: usize] NoiseEstimatingBcls<T, P, F, FI, Q>);

impl<T: Real, const P: usize, F: Flat<BcGroup<T, P>>, FI: Flat<IvFilter<T, P>>, const Q: usize> Identifier<T>
    for NoiseEstimatingBcls<T, P, F, FI, Q>
{
    fn dims(&self) -> Dims {
        self.bc.dims()
    }

    fn rows(&self) -> &[usize] {
        self.bc.rows()
    }

    /// Adds the sample to the least-squares sums and steps the instrumental filter; the
    /// innovations are the instrumental filter's (against `θ̃`). Transactional: a sample
    /// either part refuses leaves both as they were.
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        check_lengths(self.dims(), x, z, u, e)?;
        self.bc.update_into(x, z, u, e)?;
        if let Err(err) = self.iv.update_into(x, z, u, e) {
            self.bc.revert_last();
            return Err(err);
        }
        Ok(())
    }

    /// `θ̂ = (A − N C(Σ̂))⁻¹ (b − N d(Σ̂))` per group, with `Σ̂` fitted at the instrumental
    /// estimate (module docs).
    ///
    /// # Errors
    /// [`Error::Shape`]; [`Error::RankDeficient`] while the instrumental estimate is starting
    /// or the data do not span a group; [`Error::Singular`] when the compensated matrix is not
    /// positive definite.
    fn params_into(&self, out: &mut [T]) -> Result<()> {
        let np = self.bc.structure().params();
        if out.len() != np {
            return Err(Error::Shape { arg: "out", expected: np, got: out.len() });
        }
        let var = self.variances()?;
        let part = *self.bc.partition();
        for g in 0..part.groups as usize {
            let (c, dv) = self.correction(g, &var)?;
            let th = self.bc.solve_with(g, &c, &dv).map_err(|e| match e {
                Error::RankDeficient { .. } => Error::RankDeficient { rank: 0, needed: np },
                other => other,
            })?;
            for j in (0..np).filter(|&j| part.group_of_param[j] as usize == g) {
                out[j] = th[part.local[j] as usize];
            }
        }
        Ok(())
    }

    fn samples(&self) -> u64 {
        self.bc.samples()
    }

    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        self.bc.noise_into(out)
    }

    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        let _ = out;
        Err(Error::Unsupported {
            what: "a parameter covariance for bias-compensated least squares with estimated noise (its sandwich \
                   needs fourth moments of the data and the variance estimate's own scatter): use IVIdentifier \
                   for standard errors",
        })
    }

    fn groups_into(&self, group_of_param: &mut [usize], group_of_eq: &mut [usize]) -> Result<()> {
        self.bc.groups_into(group_of_param, group_of_eq)
    }
}

const _: () = assert!(MAX_STATES <= 32 && MAX_PARAMS_LOCAL == MAX_PARAMS);

#[cfg(test)]
mod tests {
    use super::*;

    fn padded(rows: &[&[f64]]) -> [[f64; MAX_STATES]; MAX_STATES] {
        let mut g = [[0.0; MAX_STATES]; MAX_STATES];
        for (i, r) in rows.iter().enumerate() {
            g[i][..r.len()].copy_from_slice(r);
        }
        g
    }

    fn vector(v: &[f64]) -> [f64; MAX_STATES] {
        let mut out = [0.0; MAX_STATES];
        out[..v.len()].copy_from_slice(v);
        out
    }

    /// The stopping rule and the answer (`nnls`' docs): for a diagonal `G` the first sweep
    /// is exact (`x_j = max(0, c_j / G_jj)`) and the second sees nothing move, so it stops
    /// after two; for a coupled `G` it stops at the Karush–Kuhn–Tucker point (`x ≥ 0`, the
    /// gradient `G x − c` zero where `x > 0`, ≥ 0 where `x = 0`) well before [`MAX_SWEEPS`],
    /// coordinates outside `mask` and those with `G_jj = 0` staying 0.
    #[test]
    fn nnls_stops_when_nothing_moves_at_the_constrained_minimum() {
        let g = padded(&[&[4.0], &[0.0, 1.0], &[0.0, 0.0, 2.0]]);
        let (x, sweeps) = nnls(&g, &vector(&[2.0, -1.0, 3.0]), 3, 0b111);
        assert_eq!((&x[..3], sweeps), (&[0.5, 0.0, 1.5][..], 2));
        // Coupled (positive definite), with one coordinate held at 0 by the bound, one
        // outside the mask, one with a vanishing column.
        let g = padded(&[
            &[4.0, 1.5, -1.0, 0.5, 0.0],
            &[1.5, 3.0, 0.8, 0.0, 0.0],
            &[-1.0, 0.8, 2.5, 0.3, 0.0],
            &[0.5, 0.0, 0.3, 1.0, 0.0],
            &[0.0, 0.0, 0.0, 0.0, 0.0],
        ]);
        let c = vector(&[3.0, -2.0, 2.0, 1.0, 5.0]);
        for mask in [0b11111u32, 0b10111] {
            let (x, sweeps) = nnls(&g, &c, 5, mask);
            assert!(sweeps > 2 && sweeps < MAX_SWEEPS, "mask {mask:b}: {sweeps} sweeps");
            assert_eq!(x[4], 0.0, "the vanishing column");
            if mask & 0b1000 == 0 {
                assert_eq!(x[3], 0.0, "outside the mask");
            } else {
                assert!(x[3] > 0.0, "x[3] is free: {x:?}");
            }
            for j in (0..5).filter(|&j| mask & (1 << j) != 0 && g[j][j] > 0.0) {
                let grad = (0..5).map(|k| g[j][k] * x[k]).sum::<f64>() - c[j];
                assert!(x[j] >= 0.0, "mask {mask:b}: x[{j}] = {}", x[j]);
                if x[j] > 0.0 {
                    assert!(grad.abs() < 1e-12, "mask {mask:b}: free x[{j}], gradient {grad}");
                } else {
                    assert!(grad > -1e-12, "mask {mask:b}: bound x[{j}], gradient {grad}");
                }
            }
            assert!(x[1] == 0.0 && x[0] > 0.0 && x[2] > 0.0, "mask {mask:b}: the bound must be active: {x:?}");
        }
    }
}

//! The body equation from the sensors a car has: a body accelerometer and a deflection
//! sensor, through a state-variable filter, with intervals that hold for its coloured
//! residuals.
//!
//! The body equation of the quarter car (Eq 3.10 / M, [`crate::model::QuarterCar::realistic_structure`])
//!
//! ```text
//! a_body = −(k2/M) d − (b/M) ḋ + offset
//! ```
//!
//! needs the deflection rate `ḋ`, which no sensor measures. Differentiating the deflection
//! amplifies its noise, and estimating `ḋ` with a kinematic filter from the accelerometers
//! ([`crate::health::DeflectionFilter`]) leaves a rate error correlated with `ḋ` (from the
//! accelerations' interpolation between samples) that biases `b/M` by about a percent — far
//! outside the intervals of a long drive. The state-variable filter (Young 1981; the
//! `SVF` of Garnier, Mensler & Richard's CONTSID, *Control Eng. Practice* 11, 2003) applies
//! one stable low-pass `F(s) = λ² / (s + λ)²` to both sides of the equation, which is linear
//! with constant coefficients, so it still holds for the filtered signals:
//!
//! ```text
//! F[a_body] = −(k2/M) F[d] − (b/M) (sF)[d] + offset        (F(0) = 1)
//! ```
//!
//! where `(sF)[d] = F[ḋ]`, the smoothed deflection rate, comes from the deflection samples
//! alone. `F` is discretized by the bilinear (Tustin) transform, the same for every signal.
//! The derivative inside it is a five-point central difference,
//! `ḋ_k ≈ (d_{k−2} − 8 d_{k−1} + 8 d_{k+1} − d_{k+2}) / (12 Δt)` (relative error
//! `(ωΔt)⁴/30`), with `a_body` and `d` delayed by the same two samples: the bilinear
//! differentiator `sF` itself is off by `(ωΔt)²/12`, which at the wheel-hop frequency (~10 Hz,
//! passed a little by `F`) biased `b/M` by 0.04–0.07 % — several standard errors on a 300 s
//! drive. The deflection noise enters `F[ḋ]` with a power that grows as `λ³`, so `λ` is kept
//! low (default 10 rad/s; `benches/real_roads.py --sensors realistic` for the figures).
//!
//! The filtered equation's residual is coloured (the filter's impulse response lasts about
//! `5/λ`), so the least-squares standard errors would be several times too small. The
//! covariance is instead cluster-robust over consecutive blocks of samples (Cameron & Miller,
//! *J. Human Resources* 50, 2015; statsmodels `cov_type="cluster"`), blocks much longer than
//! the residual's correlation (default 2 s):
//!
//! ```text
//! θ̂ = A⁻¹ c,   A = Σ h hᵀ,  c = Σ h y,   g_b = c_b − A_b θ̂  (block b's score)
//! cov = A⁻¹ (Σ_b g_b g_bᵀ) A⁻¹ · G/(G − 1) · (N − 1)/(N − k)
//! ```
//!
//! (`G` blocks, `N` samples, `k` parameters: statsmodels' small-sample correction) and the
//! intervals use Student's t with `G − 1` degrees of freedom.
//!
//! The parameters are those of the structure given (the ratios `k2/M, b/M`, or `k2, b` with
//! `M` known, and the offset), so [`crate::model::PhysicalStructure::constant`] maps them to
//! the constants.

use super::EstimateStats;
use crate::structure::{Structure, MAX_PARAMS};
use crate::{Error, Result};
use alloc::vec::Vec;
use nalgebra::{DMatrix, DVector};

/// Default bandwidth `λ` of the state-variable filter, rad/s.
pub const DEFAULT_BANDWIDTH: f64 = 10.0;
/// Default length of the blocks of the cluster-robust covariance, s.
pub const DEFAULT_BLOCK: f64 = 2.0;
/// Most parameters of the body equation (`k2/M`, `b/M`, offset).
const NP: usize = 3;

/// Samples of `[a_body, deflection]` kept for the five-point derivative.
pub(super) const HISTORY: usize = 5;

/// A second-order IIR filter in transposed direct form II (`y = b0 u + s0`,
/// `s0 ← b1 u − a1 y + s1`, `s1 ← b2 u − a2 y`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub(super) struct Biquad {
    pub(super) b: [f64; 3],
    pub(super) a: [f64; 2],
    pub(super) s: [f64; 2],
}

impl Biquad {
    /// The bilinear transform (`s = K (1 − z⁻¹)/(1 + z⁻¹)`, `K = 2/dt`) of `λ² / (s + λ)²`:
    /// with `α = K + λ`, `β = λ − K`, `(s + λ)² = (α + β z⁻¹)² / (1 + z⁻¹)²`.
    pub(super) fn bilinear(dt: f64, lambda: f64) -> Self {
        let k = 2.0 / dt;
        let (al, be) = (k + lambda, lambda - k);
        let g = lambda * lambda / (al * al);
        Self { b: [g, 2.0 * g, g], a: [2.0 * be / al, be * be / (al * al)], s: [0.0; 2] }
    }

    #[inline]
    pub(super) fn step(&mut self, u: f64) -> f64 {
        let y = self.b[0] * u + self.s[0];
        self.s = [self.b[1] * u - self.a[0] * y + self.s[1], self.b[2] * u - self.a[1] * y];
        y
    }

    /// The state of a filter whose input has been `u` for ever (no start transient from an
    /// offset).
    pub(super) fn prime(&mut self, u: f64) {
        let dc = (self.b[0] + self.b[1] + self.b[2]) / (1.0 + self.a[0] + self.a[1]);
        let y = dc * u;
        let s1 = self.b[2] * u - self.a[1] * y;
        self.s = [self.b[1] * u - self.a[0] * y + s1, s1];
    }
}

/// The settings of a state-variable-filter fit checked: the block length and the samples left
/// out while the filters settle (`⌈10/(λ dt)⌉`), both in samples.
///
/// # Errors
/// [`Error::InvalidArgument`] naming `dt`, `bandwidth` (finite, > 0, below the Nyquist
/// frequency `π/dt` by a factor of 10 so that the bilinear transform is accurate) or `block`
/// (finite, at least `20/λ` and one sample).
pub(super) fn filter_settings(dt: f64, bandwidth: f64, block: f64) -> Result<(u64, u64)> {
    crate::error::check_positive("dt", dt)?;
    if !(bandwidth.is_finite() && bandwidth > 0.0 && bandwidth * dt <= core::f64::consts::PI / 10.0) {
        return Err(Error::InvalidArgument {
            arg: "bandwidth",
            expected: "a filter bandwidth in rad/s, > 0 and at most a tenth of the Nyquist frequency pi/dt",
        });
    }
    if !(block.is_finite() && block >= 20.0 / bandwidth && block >= dt) {
        return Err(Error::InvalidArgument {
            arg: "block",
            expected: "a block length in seconds of at least 20/bandwidth (the residuals' correlation)",
        });
    }
    Ok((libm::round(block / dt).max(1.0) as u64, libm::ceil(10.0 / (bandwidth * dt)) as u64))
}

/// The five-point central derivative at the centre of `v` (samples `dt` s apart):
/// `(v₀ − 8 v₁ + 8 v₃ − v₄) / (12 dt)`.
#[inline]
pub(super) fn five_point(v: [f64; HISTORY], dt: f64) -> f64 {
    (v[0] - 8.0 * v[1] + 8.0 * v[3] - v[4]) / (12.0 * dt)
}

/// Sums of one block of samples: `A = Σ h hᵀ`, `c = Σ h y`, `Σ y²`, the count.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Moments {
    a: [[f64; NP]; NP],
    c: [f64; NP],
    yy: f64,
    n: u64,
}

impl Moments {
    fn add(&mut self, o: &Moments) {
        for i in 0..NP {
            for j in 0..NP {
                self.a[i][j] += o.a[i][j];
            }
            self.c[i] += o.c[i];
        }
        self.yy += o.yy;
        self.n += o.n;
    }
}

/// The sums over closed blocks that the cluster-robust covariance needs, kept without storing
/// the blocks: with a block's score `g_b = c_b − A_b θ`,
/// `Σ_b g_b g_bᵀ = Σ c_b c_bᵀ − Σ (c_b θᵀ A_bᵀ + A_b θ c_bᵀ) + Σ A_b θ θᵀ A_bᵀ`, so the sums
/// `Σ c_b c_bᵀ`, `Σ c_b ⊗ A_b` and `Σ A_b ⊗ A_b` (fixed size) give it for any θ later.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Clusters {
    total: Moments,
    cc: [[f64; NP]; NP],
    ca: [[[f64; NP]; NP]; NP],
    aa: [[[[f64; NP]; NP]; NP]; NP],
    blocks: u64,
}

impl Clusters {
    /// Takes in one block's sums.
    fn close(&mut self, b: &Moments) {
        if b.n == 0 {
            return;
        }
        self.total.add(b);
        for i in 0..NP {
            for j in 0..NP {
                self.cc[i][j] += b.c[i] * b.c[j];
                for l in 0..NP {
                    self.ca[i][j][l] += b.c[i] * b.a[j][l];
                    for m in 0..NP {
                        self.aa[i][j][l][m] += b.a[i][j] * b.a[l][m];
                    }
                }
            }
        }
        self.blocks += 1;
    }

    /// `Σ_b g_b g_bᵀ` at `θ` (`np` parameters).
    fn meat(&self, theta: &DVector<f64>, np: usize) -> DMatrix<f64> {
        DMatrix::from_fn(np, np, |i, j| {
            let mut v = self.cc[i][j];
            for l in 0..np {
                v -= (self.ca[i][j][l] + self.ca[j][i][l]) * theta[l];
                for m in 0..np {
                    v += self.aa[i][l][j][m] * theta[l] * theta[m];
                }
            }
            v
        })
    }
}

/// The body equation of the realistic sensors identified through a state-variable filter,
/// with cluster-robust intervals (module documentation). Samples are the realistic channels
/// `[a_body, a_wheel, deflection]` (m/s², m/s², m; the wheel's is not read).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct StateFilterFit {
    structure: Structure<f64>,
    dt: f64,
    bandwidth: f64,
    block: u64,
    skip: u64,
    filters: [Biquad; 3],
    /// The last [`HISTORY`] samples `[a_body, deflection]`, oldest first.
    history: [[f64; 2]; HISTORY],
    since_start: u64,
    current: Moments,
    closed: Clusters,
}

impl StateFilterFit {
    /// A fit of `structure`'s one identified equation, which reads the states `d, v` and the
    /// derivative of state 2 (as [`crate::model::QuarterCar::realistic_structure`]), from
    /// samples every `dt` s, filter bandwidth `bandwidth` (rad/s, [`DEFAULT_BANDWIDTH`]) and
    /// blocks of `block` s ([`DEFAULT_BLOCK`]).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming `dt`, `bandwidth` (finite, > 0, below the Nyquist
    /// frequency `π/dt` by a factor of 10 so that the bilinear transform is accurate) or
    /// `block` (finite, at least `20/λ` and one sample); [`Error::Unsupported`] for a
    /// structure with more than one identified equation, other than 3 states or more than 3
    /// parameters.
    pub fn new(structure: Structure<f64>, dt: f64, bandwidth: f64, block: f64) -> Result<Self> {
        let (block, skip) = filter_settings(dt, bandwidth, block)?;
        if structure.equations() != 1 || structure.states() != 3 || structure.params() > NP || structure.inputs() != 0 {
            return Err(Error::Unsupported {
                what: "a state-variable-filter fit other than of the realistic sensors' body equation \
                       (QuarterCar::realistic_structure)",
            });
        }
        let f = Biquad::bilinear(dt, bandwidth);
        Ok(Self {
            structure,
            dt,
            bandwidth,
            block,
            skip,
            filters: [f; 3],
            history: [[0.0; 2]; HISTORY],
            since_start: 0,
            current: Moments::default(),
            closed: Clusters::default(),
        })
    }

    /// Whether a restored value keeps every invariant [`StateFilterFit::update`] and
    /// [`StateFilterFit::stats`] rely on: its settings valid and its filters the ones they
    /// give, every sum finite, each block within the block length, the normal matrices
    /// symmetric with a non-negative diagonal.
    pub fn is_consistent(&self) -> bool {
        let Ok(fresh) = Self::new(self.structure, self.dt, self.bandwidth, self.block as f64 * self.dt) else {
            return false;
        };
        let coefficients = |f: &Biquad| (f.b, f.a);
        let filters_ok = self.filters.iter().zip(&fresh.filters).all(|(f, g)| coefficients(f) == coefficients(g))
            && self.filters.iter().all(|f| f.s.iter().all(|v| v.is_finite()))
            && self.history.iter().flatten().all(|v| v.is_finite());
        let sums_ok = |m: &Moments| {
            m.yy.is_finite()
                && m.yy >= 0.0
                && m.c.iter().all(|v| v.is_finite())
                && (0..NP).all(|i| m.a[i][i] >= 0.0 && (0..NP).all(|j| m.a[i][j].is_finite() && m.a[i][j] == m.a[j][i]))
        };
        fresh.block == self.block
            && fresh.skip == self.skip
            && filters_ok
            && sums_ok(&self.current)
            && self.current.n <= self.block
            && sums_ok(&self.closed.total)
            && self.closed.total.n >= self.closed.blocks
            && (self.closed.blocks > 0 || self.closed.total == Moments::default())
            && self.closed.cc.iter().flatten().chain(self.closed.ca.iter().flatten().flatten()).all(|v| v.is_finite())
            && self.closed.aa.iter().flatten().flatten().flatten().all(|v| v.is_finite())
            && (0..NP).all(|i| self.closed.cc[i][i] >= 0.0)
    }

    /// The structure fitted.
    pub fn structure(&self) -> &Structure<f64> {
        &self.structure
    }

    /// Sample interval, s.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Filter bandwidth `λ`, rad/s.
    pub fn bandwidth(&self) -> f64 {
        self.bandwidth
    }

    /// Block length, samples.
    pub fn block(&self) -> u64 {
        self.block
    }

    /// Samples left out after each start while the filters settle: `⌈10/(λ dt)⌉`, and the
    /// four of the first five-point derivative.
    pub fn settling(&self) -> u64 {
        self.skip + HISTORY as u64 - 1
    }

    /// Samples used.
    pub fn samples(&self) -> u64 {
        self.closed.total.n + self.current.n
    }

    /// One sample of the realistic channels `[a_body, a_wheel, deflection]`.
    ///
    /// # Errors
    /// [`Error::Shape`] for other than 3 values; [`Error::NonFinite`] (`"y"`) — nothing changes
    /// (a gap: call [`StateFilterFit::restart`]). No allocation.
    pub fn update(&mut self, y: &[f64]) -> Result<()> {
        if y.len() != 3 {
            return Err(Error::Shape { arg: "y", expected: 3, got: y.len() });
        }
        crate::error::check_finite("y", y)?;
        if self.current.n >= self.block {
            self.closed.close(&core::mem::take(&mut self.current));
        }
        self.history.rotate_left(1);
        self.history[HISTORY - 1] = [y[0], y[2]];
        self.since_start += 1;
        if self.since_start < HISTORY as u64 {
            return Ok(());
        }
        // The centre sample (two back) and the deflection's rate there.
        let [ab, d] = self.history[2];
        let rate = five_point(self.history.map(|s| s[1]), self.dt);
        if self.since_start == HISTORY as u64 {
            self.filters[0].prime(ab);
            self.filters[1].prime(d);
            self.filters[2].prime(rate);
        }
        let fa = self.filters[0].step(ab);
        let fd = self.filters[1].step(d);
        let fv = self.filters[2].step(rate);
        if self.since_start <= self.settling() {
            return Ok(());
        }
        let (x, z) = ([fd, fv, 0.0], [fv, 0.0, fa]);
        let np = self.structure.params();
        let mut h = [0.0; MAX_PARAMS];
        let yv = self.structure.regression(0, &x, &z, &[], &mut h[..np]);
        let m = &mut self.current;
        for i in 0..np {
            for j in 0..np {
                m.a[i][j] += h[i] * h[j];
            }
            m.c[i] += h[i] * yv;
        }
        m.yy += yv * yv;
        m.n += 1;
        Ok(())
    }

    /// Rows of the realistic channels (`N × 3`, row-major), as [`StateFilterFit::update`] on
    /// each; every value is checked first, so a bad one changes nothing.
    ///
    /// # Errors
    /// As [`StateFilterFit::update`]; [`Error::NonFinite`] gives the flat index.
    pub fn fit(&mut self, y: &[f64]) -> Result<()> {
        if y.len() % 3 != 0 {
            return Err(Error::Shape { arg: "y", expected: 3, got: y.len() % 3 });
        }
        crate::error::check_finite("y", y)?;
        y.chunks_exact(3).try_for_each(|row| self.update(row))
    }

    /// A gap in the record: the filters start again at the next sample (the first
    /// [`StateFilterFit::settling`] samples after it are left out, and the last two before it
    /// were never used: the derivative needs two samples on each side), and the current
    /// block ends.
    pub fn restart(&mut self) {
        self.since_start = 0;
        self.closed.close(&core::mem::take(&mut self.current));
    }

    /// The estimate, its cluster-robust covariance and `1 − alpha` intervals (module
    /// documentation); `df` is `G − 1`, `sigma2` the filtered equation's residual variance.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `alpha` outside (0, 1); [`Error::InvalidArgument`]
    /// naming `samples` for fewer than `k + 1` blocks (too short a record: the covariance needs
    /// blocks); [`Error::RankDeficient`] when the filtered deflection and its rate do not
    /// determine the parameters (no excitation: a smooth road, a car at rest).
    pub fn stats(&self, alpha: f64) -> Result<EstimateStats> {
        if !(alpha > 0.0 && alpha < 1.0) {
            return Err(Error::InvalidArgument { arg: "alpha", expected: "a level in (0, 1), e.g. 0.05" });
        }
        let np = self.structure.params();
        // The open block counts as one more cluster.
        let mut all = self.closed;
        all.close(&self.current);
        let g = all.blocks as usize;
        if g < np + 1 {
            return Err(Error::InvalidArgument {
                arg: "samples",
                expected: "more data: at least one block (block seconds) per parameter and one more",
            });
        }
        let total = all.total;
        let a = DMatrix::from_fn(np, np, |i, j| total.a[i][j]);
        let scale = (0..np).map(|i| a[(i, i)]).fold(0.0, f64::max);
        let chol = nalgebra::linalg::Cholesky::new(a.clone());
        let rank =
            chol.as_ref().map_or(0, |c| (0..np).filter(|&i| c.l()[(i, i)] * c.l()[(i, i)] > 1e-12 * scale).count());
        let chol = chol.filter(|_| rank == np).ok_or(Error::RankDeficient { rank, needed: np })?;
        let ainv = chol.inverse();
        let c = DVector::from_fn(np, |i, _| total.c[i]);
        let theta = &ainv * &c;
        let meat = all.meat(&theta, np);
        let (n, gf, k) = (total.n as f64, g as f64, np as f64);
        let cov = &ainv * meat * &ainv * (gf / (gf - 1.0) * (n - 1.0) / (n - k));
        let ssr = (total.yy - 2.0 * theta.dot(&c) + (theta.transpose() * &a * &theta)[(0, 0)]).max(0.0);
        let df = gf - 1.0;
        let q = crate::stats::t_ppf(1.0 - alpha / 2.0, df)?;
        let bse: Vec<f64> = (0..np).map(|i| libm::sqrt(cov[(i, i)].max(0.0))).collect();
        Ok(EstimateStats {
            params: theta.iter().copied().collect(),
            cov: (0..np * np).map(|i| cov[(i / np, i % np)]).collect(),
            conf_int: (0..np).map(|i| (theta[i] - q * bse[i], theta[i] + q * bse[i])).collect(),
            bse,
            df: alloc::vec![df; np],
            sigma2: alloc::vec![ssr / (n - k)],
            nobs: alloc::vec![n],
            alpha,
        })
    }
}

#[cfg(all(test, feature = "serde"))]
mod tests {
    use super::*;
    use crate::model::QuarterCar;

    /// A fit saved after many blocks is consistent, restores equal and continues bit for bit;
    /// one corrupted sum is refused by `is_consistent`.
    #[test]
    fn a_saved_fit_restores_and_corruption_is_seen() {
        let ps = QuarterCar::<f64>::realistic_structure([Some(320.0), None, None, None, None]).unwrap();
        let dt = 0.005;
        let mut fit = StateFilterFit::new(*ps.structure(), dt, 10.0, 2.0).unwrap();
        let sample = |k: usize| {
            let t = k as f64 * dt;
            [-(t * 7.0).sin(), 0.3 * (t * 60.0).sin(), 0.01 * (t * 7.0).sin() + 0.001 * (t * 3.1).cos()]
        };
        for k in 0..5000 {
            fit.update(&sample(k)).unwrap();
        }
        assert!(fit.is_consistent());
        let bytes = postcard::to_allocvec(&fit).unwrap();
        let mut back: StateFilterFit = postcard::from_bytes(&bytes).unwrap();
        assert!(back.is_consistent());
        assert_eq!(back, fit);
        for k in 5000..6000 {
            fit.update(&sample(k)).unwrap();
            back.update(&sample(k)).unwrap();
        }
        assert_eq!(back.stats(0.05).unwrap(), fit.stats(0.05).unwrap());
        let mut bad = back.clone();
        bad.closed.cc[0][0] = f64::NAN;
        assert!(!bad.is_consistent());
        let mut bad = back;
        bad.current.n = bad.block + 1;
        assert!(!bad.is_consistent());
    }
}

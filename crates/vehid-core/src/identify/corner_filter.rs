//! The full car's four body-corner equations (the half car's two) from the sensors a car has (a
//! body accelerometer above each wheel and each corner's deflection sensor), through the
//! state-variable filter of [`StateFilterFit`](super::StateFilterFit), with cluster-robust
//! intervals.
//!
//! The half car is the same with two corners (front, rear) and `α_ij = 1/M + x_i x_j / J`
//! (`x_f = l1`, `x_r = −l2`): five regressors, ten coefficients.
//!
//! Each corner's vertical body acceleration obeys (`crate::health`'s module documentation:
//! the body's heave, pitch and roll under the four suspension forces `T_j = (K d)_j + b_j ḋ_j`)
//!
//! ```text
//! a_i = Σ_j Θ_2j,i (−d_j) + Θ_2j+1,i (−ḋ_j) + c_i,     Θ_2j,i = (α K)_ij,  Θ_2j+1,i = α_ij b_j
//! α_ij = 1/M + x_i x_j / Jy + y_i y_j / Jx
//! ```
//!
//! with no road term, so it holds on any road. As for the quarter car, no sensor measures the
//! rates `ḋ_j`: the same low-pass `F(s) = λ²/(s + λ)²` on both sides replaces them by `(sF)[d_j]`,
//! computed from the deflection samples (five-point derivative, bilinear transform):
//!
//! ```text
//! F[a_i] = Σ_j Θ_2j,i (−F[d_j]) + Θ_2j+1,i (−(sF)[d_j]) + c_i
//! ```
//!
//! The four equations share their nine regressors `h = [−F d_fl, −(sF) d_fl, …, −(sF) d_rr, 1]`,
//! so one normal matrix `A = Σ h hᵀ` serves them all: `Θ̂ = A⁻¹ C`, `C = Σ h F[a]ᵀ` (`9 × 4`),
//! which is least squares equation by equation. The covariance of all 36 coefficients is
//! cluster-robust over blocks of samples (Cameron & Miller 2015), across the equations too: a
//! block's score is `G_b = C_b − A_b Θ̂` and
//!
//! ```text
//! cov(vec Θ̂) = (I ⊗ A⁻¹) (Σ_b vec G_b vec G_bᵀ) (I ⊗ A⁻¹) · G/(G − 1) · (N − 1)/(N − k)
//! ```
//!
//! (`G` blocks, `N` samples, `k = 9` per equation: statsmodels' correction for one equation),
//! Student's t on `G − 1` degrees of freedom. The sums `Σ vec C_b vec C_bᵀ`, `Σ vec C_b vec A_bᵀ`
//! and `Σ vec A_b vec A_bᵀ` give the middle term at any `Θ̂` later without keeping the blocks.
//!
//! **The deflection sensors' noise.** The regressors are filtered *measured* deflections: their
//! white noise `n_j` (variance `σ_j²`) adds `N S` to `E[A]`, with `S` block-diagonal, corner `j`'s
//! block `σ_j² [[Σ f₀², Σ f₀f₁], [Σ f₀f₁, Σ f₁²]]` (`f₀` the impulse response of `F`, `f₁` of `F`
//! after the five-point derivative, computed once: [`CornerFilterFit::noise_gains`]), while the
//! accelerations' noise is independent of it. Least squares is then biased toward zero by
//! `(A/N)⁻¹ S` — errors in variables; little on a rough road, but on a smooth one (ISO class B)
//! the bias of Jx and the dampers reached 0.6–1.2 standard errors and the 95 % intervals
//! covered 73–87 % (vehid's default 0.3 mm deflection noise; 0.3 standard errors with the noise
//! off). The fit compensates it (bias-compensated least squares; Söderström, *Errors-in-variables
//! methods in system identification*, Automatica 43, 2007): `Θ̂ = (A − N Ŝ)⁻¹ C`, each block's
//! score `G_b = C_b − (A_b − N_b Ŝ) Θ̂`, with `σ̂_j²` from the deflection's fourth differences,
//! `σ̂_j² = Σ (Δ⁴ d_j)² / (70 N₄)` (a difference-based variance estimate: Hall, Kay &
//! Titterington, *Biometrika* 77, 1990; `Δ⁴` cancels a bias and any cubic trend, and the motion's
//! share is `(ω Δt)⁸` of its power at frequency `ω`: 10⁻⁴ at the wheel hop's 10 Hz and 200 Hz
//! sampling), [`CornerFilterFit::deflection_noise`].
//!
//! With equal track widths the four corner accelerations hold only three rigid-body motions
//! (`a_fl − a_fr − a_rl + a_rr = 0`), so the estimates of the four equations are nearly
//! dependent and the 36 × 36 covariance is close to singular in that direction: it is kept
//! as computed (each coefficient's interval is right), and
//! [`crate::model::FullCar::from_corner_coefficients`] reads the constants without inverting it.

use super::state_filter::{filter_settings, five_point, Biquad, HISTORY};
use super::EstimateStats;
use crate::{Error, Result};
use alloc::vec::Vec;
use nalgebra::{Cholesky, DMatrix, SMatrix};

/// Default bandwidth `λ` of the full car's filter, rad/s: three times the quarter car's
/// ([`super::DEFAULT_BANDWIDTH`]). At low frequency the body moves as one and the four
/// deflections are nearly collinear, so their sensor noise biases the dampers and the roll
/// inertia there; a wider filter takes in the wheel-hop band, where the corners move apart.
/// Measured on 40 drives (vehid's default sensor noise, ISO class C, 15 m/s, 300 s, seeds
/// 76000–76039): the dampers' mean error +0.29/−0.13 % (front/rear, 1.4–2.3 standard errors) at
/// 10 rad/s, +1.4/−0.7 % at 5, within ±0.03 % (≤ 0.5 standard errors) at 30 and 50. 30 keeps
/// the filter valid down to 100 Hz sampling (`λ dt ≤ π/10`). The half car's two corners move
/// apart at every frequency (heave and pitch: two motions, two corners), and it keeps the
/// quarter car's 10 rad/s: on the same 40 drives its dampers' mean error was −0.01 % there
/// (≤ 0.6 standard errors for every constant) and −0.035 % at 30 (1.0–1.2).
pub const CORNER_BANDWIDTH: f64 = 30.0;
/// Regressors of each of the full car's corner equations: each corner's filtered extension
/// and rate, and 1 (the half car's: 5).
pub const CORNER_REGRESSORS: usize = 9;
/// Most corner equations (the full car's fl, fr, rl, rr); the sums are kept at this size.
const EQS: usize = 4;
/// The full car's coefficients in all: 9 per equation (the half car's: 10).
pub const CORNER_COEFFICIENTS: usize = CORNER_REGRESSORS * EQS;
/// Entries of the normal matrix.
const AA: usize = CORNER_REGRESSORS * CORNER_REGRESSORS;

/// Sums of one block of samples: `A = Σ h hᵀ`, `C = Σ h yᵀ`, `Σ y yᵀ`, the count.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Sums {
    a: SMatrix<f64, CORNER_REGRESSORS, CORNER_REGRESSORS>,
    c: SMatrix<f64, CORNER_REGRESSORS, EQS>,
    yy: SMatrix<f64, EQS, EQS>,
    n: u64,
}

impl Sums {
    fn add(&mut self, o: &Sums) {
        self.a += o.a;
        self.c += o.c;
        self.yy += o.yy;
        self.n += o.n;
    }

    fn finite(&self) -> bool {
        self.a.iter().chain(self.c.iter()).chain(self.yy.iter()).all(|v| v.is_finite())
            && (0..CORNER_REGRESSORS).all(|i| self.a[(i, i)] >= 0.0)
            && (0..EQS).all(|i| self.yy[(i, i)] >= 0.0)
            && self.a == self.a.transpose()
    }
}

/// The closed blocks' sums of the cluster-robust covariance (module documentation).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Clusters {
    total: Sums,
    cc: SMatrix<f64, CORNER_COEFFICIENTS, CORNER_COEFFICIENTS>,
    ca: SMatrix<f64, CORNER_COEFFICIENTS, AA>,
    aa: SMatrix<f64, AA, AA>,
    // `Σ n_b vec C_b`, `Σ n_b vec A_b`, `Σ n_b²`: the noise compensation's share of the scores.
    nc: SMatrix<f64, CORNER_COEFFICIENTS, 1>,
    na: SMatrix<f64, AA, 1>,
    nn: f64,
    blocks: u64,
}

impl Default for Clusters {
    fn default() -> Self {
        Self {
            total: Sums::default(),
            cc: SMatrix::zeros(),
            ca: SMatrix::zeros(),
            aa: SMatrix::zeros(),
            nc: SMatrix::zeros(),
            na: SMatrix::zeros(),
            nn: 0.0,
            blocks: 0,
        }
    }
}

impl Clusters {
    /// Takes in one block's sums (column-major `vec`: `vec C[l + 9 i] = C[l, i]`).
    fn close(&mut self, b: &Sums) {
        if b.n == 0 {
            return;
        }
        self.total.add(b);
        let (c, a) = (b.c.as_slice(), b.a.as_slice());
        for (q, cq) in c.iter().enumerate() {
            for (r, cr) in c.iter().enumerate() {
                self.cc[(q, r)] += cq * cr;
            }
            for (r, ar) in a.iter().enumerate() {
                self.ca[(q, r)] += cq * ar;
            }
        }
        for (q, aq) in a.iter().enumerate() {
            for (r, ar) in a.iter().enumerate() {
                self.aa[(q, r)] += aq * ar;
            }
        }
        let nb = b.n as f64;
        self.nc += SMatrix::<f64, CORNER_COEFFICIENTS, 1>::from_column_slice(c) * nb;
        self.na += SMatrix::<f64, AA, 1>::from_column_slice(a) * nb;
        self.nn += nb * nb;
        self.blocks += 1;
    }

    /// `Σ_b vec G_b vec G_bᵀ` at `theta` (`k × c`: the first `k` regressors, `c` equations),
    /// `G_b = C_b − (A_b − n_b S) θ` (`S` the noise compensation, `k × k`), over the entries in
    /// use (`k c` of them, equation by equation).
    fn meat(&self, theta: &DMatrix<f64>, s: &DMatrix<f64>) -> DMatrix<f64> {
        const S: usize = CORNER_REGRESSORS; // the stride of the kept sums' vec
        let (k, c) = theta.shape();
        let qs: Vec<usize> = (0..c).flat_map(|i| (0..k).map(move |l| l + S * i)).collect();
        let rs: Vec<usize> = (0..k).flat_map(|m| (0..k).map(move |l| l + S * m)).collect();
        let cc = DMatrix::from_fn(qs.len(), qs.len(), |a, b| self.cc[(qs[a], qs[b])]);
        let ca = DMatrix::from_fn(qs.len(), rs.len(), |a, b| self.ca[(qs[a], rs[b])]);
        let aa = DMatrix::from_fn(rs.len(), rs.len(), |a, b| self.aa[(rs[a], rs[b])]);
        // vec(A_b θ)[l + k i] = Σ_m A_b[l, m] θ[m, i] = Σ_m vec A_b[l + k m] θ[m, i]: a linear map
        // L of vec A_b, so vec G_b = vec C_b − L vec A_b.
        let mut lmap = DMatrix::<f64>::zeros(k * c, k * k);
        for i in 0..c {
            for l in 0..k {
                for m in 0..k {
                    lmap[(l + k * i, l + k * m)] = theta[(m, i)];
                }
            }
        }
        let cross = ca * lmap.transpose();
        let plain = &cc - &cross - cross.transpose() + &lmap * aa * lmap.transpose();
        // vec G_b = (vec C_b − L vec A_b) + n_b v, v = vec(S θ): Σ adds u vᵀ + v uᵀ + Σ n_b² v vᵀ
        // with u = Σ n_b (vec C_b − L vec A_b).
        let st = s * theta;
        let v = DMatrix::from_fn(k * c, 1, |q, _| st[(q % k, q / k)]);
        let nc = DMatrix::from_fn(qs.len(), 1, |a, _| self.nc[qs[a]]);
        let na = DMatrix::from_fn(rs.len(), 1, |a, _| self.na[rs[a]]);
        let u = nc - &lmap * na;
        let uv = &u * v.transpose();
        plain + &uv + uv.transpose() + &v * v.transpose() * self.nn
    }
}

/// The full car's four body-corner equations (or the half car's two) identified through a
/// state-variable filter, with cluster-robust intervals (module documentation). Samples are the
/// car's realistic channels `[a_body_fl, …, a_body_rr, a_wheel_fl, …, a_wheel_rr,
/// deflection_fl, …, deflection_rr]` (the half car's `[a_body_f, a_body_r, a_wheel_f,
/// a_wheel_r, deflection_f, deflection_r]`; m/s², m/s², m; deflection `z_body − z_wheel` at the
/// corner, positive in extension; the wheels' are not read).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CornerFilterFit {
    /// 4 (the full car) or 2 (the half car).
    corners: usize,
    dt: f64,
    bandwidth: f64,
    block: u64,
    skip: u64,
    /// The body accelerations', the deflections' and the rates' filters, corner by corner.
    filters: [[Biquad; EQS]; 3],
    /// The last [`HISTORY`] samples `[a_body ×4, deflection ×4]`, oldest first.
    history: [[f64; 2 * EQS]; HISTORY],
    since_start: u64,
    /// `Σ (Δ⁴ d_j)²` of each corner's deflection, and the fourth differences counted.
    diff4: [f64; EQS],
    diff4_n: u64,
    current: Sums,
    closed: Clusters,
}

impl CornerFilterFit {
    /// A fit from samples every `dt` s, filter bandwidth `bandwidth` (rad/s,
    /// [`CORNER_BANDWIDTH`]) and blocks of `block` s ([`super::DEFAULT_BLOCK`]).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming `dt`, `bandwidth` or `block` as
    /// [`StateFilterFit::new`](super::StateFilterFit::new).
    pub fn new(dt: f64, bandwidth: f64, block: f64) -> Result<Self> {
        Self::with_corners(EQS, dt, bandwidth, block)
    }

    /// The half car's two body-corner equations (front, rear), otherwise as
    /// [`CornerFilterFit::new`].
    ///
    /// # Errors
    /// As [`CornerFilterFit::new`].
    pub fn half(dt: f64, bandwidth: f64, block: f64) -> Result<Self> {
        Self::with_corners(2, dt, bandwidth, block)
    }

    fn with_corners(corners: usize, dt: f64, bandwidth: f64, block: f64) -> Result<Self> {
        let (block, skip) = filter_settings(dt, bandwidth, block)?;
        let f = Biquad::bilinear(dt, bandwidth);
        Ok(Self {
            corners,
            dt,
            bandwidth,
            block,
            skip,
            filters: [[f; EQS]; 3],
            history: [[0.0; 2 * EQS]; HISTORY],
            since_start: 0,
            diff4: [0.0; EQS],
            diff4_n: 0,
            current: Sums::default(),
            closed: Clusters::default(),
        })
    }

    /// Whether a restored value keeps every invariant [`CornerFilterFit::update`] and
    /// [`CornerFilterFit::stats`] rely on: settings valid and its filters the ones they give,
    /// every sum finite, the normal matrices symmetric with a non-negative diagonal, each block
    /// within the block length.
    pub fn is_consistent(&self) -> bool {
        if !matches!(self.corners, 2 | EQS) {
            return false;
        }
        let Ok(fresh) = Self::with_corners(self.corners, self.dt, self.bandwidth, self.block as f64 * self.dt) else {
            return false;
        };
        let coefficients = |f: &Biquad| (f.b, f.a);
        let filters_ok = self
            .filters
            .iter()
            .flatten()
            .zip(fresh.filters.iter().flatten())
            .all(|(f, g)| coefficients(f) == coefficients(g) && f.s.iter().all(|v| v.is_finite()))
            && self.history.iter().flatten().all(|v| v.is_finite());
        let c = &self.closed;
        fresh.block == self.block
            && fresh.skip == self.skip
            && filters_ok
            && self.current.finite()
            && self.current.n <= self.block
            && c.total.finite()
            && c.total.n >= c.blocks
            && (c.blocks > 0 || c.total == Sums::default())
            && c.cc.iter().chain(c.ca.iter()).chain(c.aa.iter()).all(|v| v.is_finite())
            && (0..CORNER_COEFFICIENTS).all(|i| c.cc[(i, i)] >= 0.0)
            && c.nc.iter().chain(c.na.iter()).all(|v| v.is_finite())
            && c.nn.is_finite()
            && c.nn >= 0.0
            && self.diff4.iter().all(|v| v.is_finite() && *v >= 0.0)
    }

    /// The filtered deflection noise's second moments per unit of its variance,
    /// `[Σ f₀², Σ f₀ f₁, Σ f₁²]` (module documentation, "The deflection sensors' noise"): an
    /// impulse of white noise through the two regressors' paths, `F` on the centre sample and
    /// `F` after the five-point derivative, summed until the filter has forgotten it (twenty
    /// settling times).
    pub fn noise_gains(&self) -> [f64; 3] {
        let mut f0 = Biquad::bilinear(self.dt, self.bandwidth);
        let mut f1 = f0;
        // The impulse at the newest of the five samples: the centre sample sees it two steps
        // later, the derivative at each of the five positions (oldest first: v0 − 8 v1 + 8 v3 − v4).
        let w = [-1.0, 8.0, 0.0, -8.0, 1.0].map(|x| x / (12.0 * self.dt));
        let mut g = [0.0; 3];
        for step in 0..20 * self.skip + 10 {
            let k = step as usize;
            let y0 = f0.step(if k == 2 { 1.0 } else { 0.0 });
            let y1 = f1.step(if k < 5 { w[k] } else { 0.0 });
            g[0] += y0 * y0;
            g[1] += y0 * y1;
            g[2] += y1 * y1;
        }
        g
    }

    /// The deflection noise's share `S` of the normal matrix per sample (`k × k`, `k` the
    /// regressors; module documentation, "The deflection sensors' noise"): corner `j`'s
    /// extension and rate block `σ̂_j² [[Σ f₀², Σ f₀f₁], [Σ f₀f₁, Σ f₁²]]`
    /// ([`CornerFilterFit::noise_gains`], [`CornerFilterFit::deflection_noise`]), 0 elsewhere.
    fn noise_share(&self) -> DMatrix<f64> {
        let [g0, g01, g1] = self.noise_gains();
        let sd = self.deflection_noise();
        let mut s = DMatrix::<f64>::zeros(self.regressors(), self.regressors());
        for j in 0..self.corners {
            let v = sd[j] * sd[j];
            let block = SMatrix::<f64, 2, 2>::new(g0, g01, g01, g1) * v;
            s.view_mut((2 * j, 2 * j), (2, 2)).copy_from(&block);
        }
        s
    }

    /// Each corner's deflection noise estimated from the samples, m: the standard deviation
    /// `σ̂_j = √(Σ (Δ⁴ d_j)² / (70 N₄))` (module documentation, "The deflection sensors'
    /// noise"); 0 before five samples (`[fl, fr, rl, rr]`, the half car's `[f, r]` first).
    pub fn deflection_noise(&self) -> [f64; EQS] {
        let n = (70 * self.diff4_n.max(1)) as f64;
        self.diff4.map(|s| libm::sqrt(s / n))
    }

    /// Corner equations: 4 (the full car) or 2 (the half car).
    pub fn corners(&self) -> usize {
        self.corners
    }

    /// Regressors per equation: `2 corners + 1`.
    pub fn regressors(&self) -> usize {
        2 * self.corners + 1
    }

    /// Channels per sample: `3 corners`.
    pub fn channels(&self) -> usize {
        3 * self.corners
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

    /// Samples left out after each start while the filters settle (as
    /// [`StateFilterFit::settling`](super::StateFilterFit::settling)).
    pub fn settling(&self) -> u64 {
        self.skip + HISTORY as u64 - 1
    }

    /// Samples used.
    pub fn samples(&self) -> u64 {
        self.closed.total.n + self.current.n
    }

    /// One sample of the realistic channels (12 for the full car, 6 for the half car).
    ///
    /// # Errors
    /// [`Error::Shape`] for another number of values; [`Error::NonFinite`] (`"y"`) — nothing changes
    /// (a gap: call [`CornerFilterFit::restart`]). No allocation.
    pub fn update(&mut self, y: &[f64]) -> Result<()> {
        let c = self.corners;
        if y.len() != 3 * c {
            return Err(Error::Shape { arg: "y", expected: 3 * c, got: y.len() });
        }
        crate::error::check_finite("y", y)?;
        if self.current.n >= self.block {
            self.closed.close(&core::mem::take(&mut self.current));
        }
        self.history.rotate_left(1);
        let last = &mut self.history[HISTORY - 1];
        last[..c].copy_from_slice(&y[..c]);
        last[EQS..EQS + c].copy_from_slice(&y[2 * c..]);
        self.since_start += 1;
        if self.since_start < HISTORY as u64 {
            return Ok(());
        }
        // The centre sample (two back), each deflection's rate there, and its fourth
        // difference (its noise, for the compensation).
        let centre = self.history[2];
        let prime = self.since_start == HISTORY as u64;
        let mut h = SMatrix::<f64, CORNER_REGRESSORS, 1>::zeros();
        let mut fa = SMatrix::<f64, EQS, 1>::zeros();
        self.diff4_n += 1;
        for j in 0..c {
            let d = self.history.map(|s| s[EQS + j]);
            let d4 = d[0] - 4.0 * d[1] + 6.0 * d[2] - 4.0 * d[3] + d[4];
            self.diff4[j] += d4 * d4;
            let rate = five_point(d, self.dt);
            let [fa_f, fd_f, fv_f] = &mut self.filters;
            if prime {
                fa_f[j].prime(centre[j]);
                fd_f[j].prime(centre[EQS + j]);
                fv_f[j].prime(rate);
            }
            fa[j] = fa_f[j].step(centre[j]);
            h[2 * j] = -fd_f[j].step(centre[EQS + j]);
            h[2 * j + 1] = -fv_f[j].step(rate);
        }
        h[2 * c] = 1.0;
        if self.since_start <= self.settling() {
            return Ok(());
        }
        // Rank-one updates in place (each entry gains one product: the same sums as forming
        // h hᵀ first, without the temporary; h_i h_j = h_j h_i keeps A symmetric).
        let m = &mut self.current;
        m.a.ger(1.0, &h, &h, 1.0);
        m.c.ger(1.0, &h, &fa, 1.0);
        m.yy.ger(1.0, &fa, &fa, 1.0);
        m.n += 1;
        Ok(())
    }

    /// Rows of the realistic channels (`N × 12`, or `N × 6` for the half car, row-major), as
    /// [`CornerFilterFit::update`] on each; every value is checked first, so a bad one changes
    /// nothing.
    ///
    /// # Errors
    /// As [`CornerFilterFit::update`]; [`Error::NonFinite`] gives the flat index.
    pub fn fit(&mut self, y: &[f64]) -> Result<()> {
        let width = self.channels();
        if y.len() % width != 0 {
            return Err(Error::Shape { arg: "y", expected: width, got: y.len() % width });
        }
        crate::error::check_finite("y", y)?;
        y.chunks_exact(width).try_for_each(|row| self.update(row))
    }

    /// A gap in the record: the filters start again at the next sample, and the current block
    /// ends (as [`StateFilterFit::restart`](super::StateFilterFit::restart)).
    pub fn restart(&mut self) {
        self.since_start = 0;
        self.closed.close(&core::mem::take(&mut self.current));
    }

    /// The 36 coefficients, equation by equation (corner `i`'s nine at `9 i ..`: the extension
    /// and the rate of fl, fr, rl, rr, then the offset `c_i` in m/s²; units 1/s² and 1/s; the
    /// half car's 10, five per equation: f, r, offset), their
    /// cluster-robust covariance and `1 − alpha` intervals; `df` is `G − 1`, `sigma2` each
    /// filtered equation's residual variance.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `alpha` outside (0, 1), or naming `samples` for fewer
    /// than ten blocks (the covariance needs blocks); [`Error::RankDeficient`] when the filtered
    /// deflections and their rates do not determine the coefficients (no excitation, a corner's
    /// sensor stuck, two corners moving alike, or a deflection's filtered motion no larger than
    /// its sensor's noise: the compensated normal matrix is then not positive definite).
    pub fn stats(&self, alpha: f64) -> Result<EstimateStats> {
        let (k, eqs) = (self.regressors(), self.corners);
        let np = k * eqs;
        if !(alpha > 0.0 && alpha < 1.0) {
            return Err(Error::InvalidArgument { arg: "alpha", expected: "a level in (0, 1), e.g. 0.05" });
        }
        let mut all = self.closed.clone();
        all.close(&self.current);
        let g = all.blocks as usize;
        if g < k + 1 {
            return Err(Error::InvalidArgument {
                arg: "samples",
                expected: "more data: at least one block (block seconds) per regressor and one more",
            });
        }
        let total = all.total;
        let a = DMatrix::from_fn(k, k, |i, j| total.a[(i, j)]);
        let cs = DMatrix::from_fn(k, eqs, |i, j| total.c[(i, j)]);
        let s = self.noise_share();
        let compensated = &a - &s * total.n as f64;
        let scale = (0..k).map(|i| a[(i, i)]).fold(0.0, f64::max);
        let chol = Cholesky::new(compensated);
        let rank =
            chol.as_ref().map_or(0, |c| (0..k).filter(|&i| c.l()[(i, i)] * c.l()[(i, i)] > 1e-12 * scale).count());
        let chol = chol.filter(|_| rank == k).ok_or(Error::RankDeficient { rank, needed: k })?;
        let ainv = chol.inverse();
        let theta = &ainv * &cs;
        let meat = all.meat(&theta, &s);
        let mut bread = DMatrix::<f64>::zeros(np, np);
        for i in 0..eqs {
            bread.view_mut((k * i, k * i), (k, k)).copy_from(&ainv);
        }
        let (n, gf, kf) = (total.n as f64, g as f64, k as f64);
        let cov = &bread * meat * &bread * (gf / (gf - 1.0) * (n - 1.0) / (n - kf));
        // Symmetric to rounding (the Kronecker sums cancel): made exactly so.
        let cov = (&cov + cov.transpose()) * 0.5;
        let df = gf - 1.0;
        let q = crate::stats::t_ppf(1.0 - alpha / 2.0, df)?;
        let params: Vec<f64> = theta.as_slice().to_vec();
        let bse: Vec<f64> = (0..np).map(|i| libm::sqrt(cov[(i, i)].max(0.0))).collect();
        let sigma2 = (0..eqs)
            .map(|i| {
                let (t, c) = (theta.column(i), cs.column(i));
                (total.yy[(i, i)] - 2.0 * t.dot(&c) + (t.transpose() * &a * t)[(0, 0)]).max(0.0) / (n - kf)
            })
            .collect();
        Ok(EstimateStats {
            conf_int: params.iter().zip(&bse).map(|(p, s)| (p - q * s, p + q * s)).collect(),
            params,
            cov: cov.as_slice().to_vec(),
            bse,
            df: alloc::vec![df; np],
            sigma2,
            nobs: alloc::vec![n; eqs],
            alpha,
        })
    }
}

#[cfg(all(test, feature = "serde"))]
#[path = "corner_filter_tests.rs"]
mod tests;

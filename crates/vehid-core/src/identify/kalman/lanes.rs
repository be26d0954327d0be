//! The decoupled rows of [`super::KalmanRows`] side by side ("lanes"), for speed.
//!
//! Every unknown row runs the same recursion on the same regressor `x` (Eq 6.16–6.18), so
//! `L` rows are stored interleaved: entry `(a, b)` of all `L` covariances is one `[T; L]`,
//! and every step of the update is the same operation on all lanes at once. The compiler
//! turns a `[T; L]` into one SIMD register (two `f64` rows in SSE2, four in AVX2), with no
//! shuffles and no horizontal sums: `P x`, `xᵀ P x`, the division and the rank-one update
//! are done for all rows together. Only the upper triangle `a ≤ b` of each `P` is stored
//! and updated (the lower triangle is its mirror), which makes `P` exactly symmetric by
//! construction and saves `N(N−1)/2` products per row in the downdate.
//!
//! Sums are evaluated in a fixed pairwise order written out here, so the rounding is the
//! same whatever instructions the compiler picks (SSE2, AVX2); no fused multiply-add is
//! used. The AVX2 path of [`super::KalmanRows`] is therefore bit-identical to the portable
//! one (tested).

use super::{CovarianceForm, RowIdentifier};
use crate::identify::OVERFLOW;
use crate::linalg::symmetrize;
use crate::{Error, Real};
use nalgebra::{SMatrix, SVector};

/// `a[0] + a[1] + … + a[M−1]` for each lane, summed pairwise in a fixed order.
#[inline(always)]
pub(crate) fn lane_sum<T: Real, const L: usize, const M: usize>(mut a: [[T; L]; M]) -> [T; L] {
    let mut len = M;
    while len > 1 {
        let half = len / 2;
        for i in 0..half {
            for k in 0..L {
                a[i][k] += a[i + len - half][k];
            }
        }
        len -= half;
    }
    if M == 0 {
        [T::zero(); L]
    } else {
        a[0]
    }
}

/// `Σ_b v[b] x_b` for each lane (`v[b]` a lane vector), summed pairwise in a fixed order.
#[inline(always)]
pub(crate) fn lane_dot<T: Real, const L: usize, const N: usize>(v: &[[T; L]; N], x: &SVector<T, N>) -> [T; L] {
    let mut t = [[T::zero(); L]; N];
    for b in 0..N {
        for k in 0..L {
            t[b][k] = v[b][k] * x[b];
        }
    }
    lane_sum(t)
}

/// `a[0] + … + a[M−1]`, summed pairwise in a fixed order.
#[inline(always)]
pub(crate) fn tree_sum<T: Real, const M: usize>(a: [T; M]) -> T {
    let mut l = [[T::zero(); 1]; M];
    for (d, s) in l.iter_mut().zip(a) {
        d[0] = s;
    }
    lane_sum(l)[0]
}

/// `±0` when every entry of `x` and `z` is finite, NaN otherwise (`0 · v` is NaN exactly
/// for NaN and ±inf). One vector pass; the exact index is found only on the error path.
#[inline(always)]
pub(crate) fn finite_probe<T: Real, const N: usize>(x: &SVector<T, N>, z: &SVector<T, N>) -> T {
    let mut d = [T::zero(); N];
    for a in 0..N {
        d[a] = x[a] * T::zero() + z[a] * T::zero();
    }
    tree_sum(d)
}

/// `true` for a finite value (`v − v = 0`; NaN for NaN and ±inf), without a branch.
#[inline(always)]
#[allow(clippy::eq_op)]
pub(crate) fn is_fin<T: Real>(v: T) -> bool {
    v - v == T::zero()
}

/// One sample's planned step for a group of lanes: computed by [`RowGroup::plan`], applied
/// by [`RowGroup::apply`] (nothing changes in between, so a rejected sample changes nothing).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaneScratch<T: Real, const N: usize, const L: usize> {
    /// `P x` per lane (standard form); the gain numerator `b` (square-root form).
    px: [[T; L]; N],
    /// `e / s` (0 for a lane that takes no step).
    c: [T; L],
    /// `1 / s` (0 for a lane that takes no step).
    w: [T; L],
    /// `s = xᵀ P x + r`.
    s: [T; L],
    /// `xᵀ θ`.
    xth: [T; L],
    /// `Σ_a (P x)_a c`: finite exactly when the θ step is.
    step: [T; L],
    /// 1 when the lane takes a step, 0 when not (a number, so that the lanes stay in
    /// vector registers).
    go: [T; L],
    /// The innovation `e` per lane.
    e: [T; L],
    /// Tracking: the directional-forgetting coefficient `c` (the update adds `c (Px)(Px)ᵀ`;
    /// 0 when off), the exponential forgetting factor applied after the update (`1/λ`, or 1
    /// when off) and the drift added to the diagonal (0 when off).
    fc: [T; L],
    scale: [T; L],
    add: [T; L],
    /// The outlier screen: 1 for a lane whose sample is gated, and the variance each lane
    /// uses (`r`, scaled up by the Huber weight).
    gated: [T; L],
    reff: [T; L],
    /// Square-root form: the updated `U D Uᵀ` factors (upper triangle; `D` on the diagonal).
    ud: [[[T; L]; N]; N],
}

/// `L` decoupled row filters stored side by side. Lanes `used..L` are padding (a
/// [`crate::identify::Dynamic`] store rounds the number of rows up to a multiple of `L`);
/// padding never steps and never fails.
///
/// What `p` holds depends on the form and the phase: the upper triangle of each lane's `P`
/// (standard and Joseph forms), `U` above the diagonal and `D` on it (square-root form), or,
/// during an exact start, the upper-triangular factor `R` of the regressors (the same in
/// every lane) with `theta` holding `Qᵀz`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowLanes<T: Real, const N: usize, const L: usize> {
    /// `theta[a][k]`: coefficient `a` of lane `k`.
    theta: [[T; L]; N],
    /// `p[a][b][k]` for `a ≤ b`: the upper triangle of lane `k`'s matrix (see above).
    p: [[[T; L]; N]; N],
    r: [T; L],
    /// Index into `z` of each lane's row (0 for padding).
    zrow: [usize; L],
    /// 1 when the lane steps (used and not retired), else 0.
    active: [T; L],
    /// Statistics per lane: Σ of squared recursive residuals, effective samples, last `s`.
    ssr: [T; L],
    nobs: [T; L],
    s: [T; L],
    /// Tracking: the trace bound per lane, the forgetting factor and the drift.
    cap: [T; L],
    lambda: T,
    drift: T,
    directional: bool,
    /// Outlier gate κ, Huber constant (0: off), and the samples each lane gated.
    gate: T,
    huber: T,
    gated: [u64; L],
    used: usize,
    form: CovarianceForm,
    /// Absorbing an exact start (every lane at once: they share the regressors).
    start: bool,
    any_r_zero: bool,
}

/// A group of row filters handled together (implemented by [`RowLanes`] for every lane
/// count). An implementation detail of the stores, public only because
/// [`crate::identify::Store`] names it.
pub trait RowGroup<T: Real, const N: usize>: Copy + core::fmt::Debug + PartialEq {
    /// Lanes per group.
    const LANES: usize;
    /// The planned step of one sample.
    type Scratch: Copy + core::fmt::Debug;
    /// A group whose lanes are all padding.
    fn padding() -> Self;
    /// An empty scratch.
    fn scratch() -> Self::Scratch;
    /// Puts `filter`, the row filter of row `zrow`, into lane `k` (and marks it used). The
    /// group takes the filter's form, phase and tracking settings.
    fn set_lane(&mut self, k: usize, zrow: usize, filter: &RowIdentifier<T, N>);
    /// The filter in lane `k`.
    fn lane(&self, k: usize) -> RowIdentifier<T, N>;
    /// `θ̂` of lane `k`.
    fn theta_lane(&self, k: usize) -> SVector<T, N>;
    /// `tr P` of lane `k`.
    fn trace_lane(&self, k: usize) -> T;
    /// Lane `k` stops stepping.
    fn retire_lane(&mut self, k: usize);
    /// Eq 4.36 on every used lane: `P_aa ← 10 P_aa`, `r ← 2 r`; used lanes step again.
    fn reinitialize(&mut self);
    /// `true` while the lanes absorb an exact start.
    fn starting(&self) -> bool;
    /// Exact start: one sample absorbed by every used lane (innovations NaN into `e`).
    ///
    /// # Errors
    /// Overflow; the group is unchanged then.
    fn absorb(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> crate::Result<()>;
    /// Plans one sample: innovations of the used lanes into `e`; returns `false` when the
    /// sample must be rejected (see [`RowGroup::check`]). Changes nothing.
    fn plan(&self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T], sc: &mut Self::Scratch) -> bool;
    /// The error of a rejected plan, if a lane of this group caused it (first lane first).
    ///
    /// # Errors
    /// Overflow for a non-finite `s` or θ step, [`Error::Singular`] for `s ≤ 0`.
    fn check(&self, sc: &Self::Scratch) -> crate::Result<()>;
    /// Applies a planned step.
    fn apply(&mut self, x: &SVector<T, N>, sc: &Self::Scratch);
}

impl<T: Real, const N: usize, const L: usize> RowLanes<T, N, L> {
    /// Lanes with `r = 0` whose `s = xᵀPx` is at rounding level take no step: noise-free
    /// data and a covariance collapsed along `x`, nothing is left to learn in that direction.
    /// Returns the new step flags. (The arguments are copies: a reference into the plan
    /// would keep the whole plan in memory on the fast path too.)
    #[inline(never)]
    fn collapsed_lanes(&self, x: &SVector<T, N>, px: [[T; L]; N], s: [T; L], mut go: [T; L]) -> [T; L] {
        let mut ax = [T::zero(); N];
        for a in 0..N {
            ax[a] = x[a].abs();
        }
        let ax = tree_sum(ax);
        for k in 0..L {
            let mut ap = [T::zero(); N];
            for a in 0..N {
                ap[a] = px[a][k].abs();
            }
            let floor = T::default_epsilon() * T::of(4.0 * N as f64) * ax * tree_sum(ap);
            if self.r[k] == T::zero() && s[k] <= floor {
                go[k] = T::zero();
            }
        }
        go
    }

    /// Joseph's form, lane by lane: `P ← (I − g xᵀ) P (I − g xᵀ)ᵀ + r g gᵀ`, `g = P x / s`.
    #[inline(never)]
    fn joseph(&mut self, x: &SVector<T, N>, sc: LaneScratch<T, N, L>) {
        for k in 0..self.used {
            if sc.go[k] == T::zero() {
                continue;
            }
            let p = self.p_lane(k);
            let g = SVector::<T, N>::from_fn(|a, _| sc.px[a][k] * sc.w[k]);
            let a = SMatrix::<T, N, N>::identity() - g * x.transpose();
            let px = SVector::<T, N>::from_fn(|a, _| sc.px[a][k]);
            let mut p = a * p * a.transpose() + g * g.transpose() * sc.reff[k] + px * px.transpose() * sc.fc[k];
            symmetrize(&mut p);
            for i in 0..N {
                for j in i..N {
                    self.p[i][j][k] = p[(i, j)] * sc.scale[k];
                }
                self.p[i][i][k] += sc.add[k];
            }
        }
    }

    /// Lane `k`'s stored matrix, mirrored (`P`, or the packed `U D` factors).
    fn p_lane(&self, k: usize) -> SMatrix<T, N, N> {
        let mut p = SMatrix::<T, N, N>::zeros();
        for a in 0..N {
            for b in a..N {
                p[(a, b)] = self.p[a][b][k];
                if self.form != CovarianceForm::Sqrt && !self.start {
                    p[(b, a)] = self.p[a][b][k];
                }
            }
        }
        p
    }

    /// Tracking of one sample, per lane, from the trace before it (`trace`) and the
    /// innovation variance `s`, while the trace is below the lane's bound (see
    /// [`RowIdentifier`]): `(c, scale, add)` with `c = ((1 − λ)/λ) r / (s (s − r))` the
    /// directional-forgetting coefficient, `scale = 1/λ` the exponential one (one of the two
    /// per the options; else 0 and 1), `add = q` the drift.
    #[inline(always)]
    fn tracking(&self, trace: [T; L], s: [T; L], r: [T; L], go: [T; L]) -> ([T; L], [T; L], [T; L]) {
        let k_lambda = (T::one() - self.lambda) / self.lambda;
        let inv = T::one() / self.lambda;
        let mut fc = [T::zero(); L];
        let mut scale = [T::one(); L];
        let mut add = [T::zero(); L];
        for k in 0..L {
            let on = (go[k] != T::zero()) & (trace[k] < self.cap[k]);
            let xpx = s[k] - r[k];
            let dir = on & self.directional & (xpx > T::zero());
            fc[k] = if dir { k_lambda * r[k] / (s[k] * xpx) } else { T::zero() };
            scale[k] = if on & !self.directional { inv } else { T::one() };
            add[k] = if on { self.drift } else { T::zero() };
        }
        (fc, scale, add)
    }

    /// The outlier screen of every lane ([`super::row::screen`]): the gated flags (1/0) and
    /// the variance each lane uses.
    #[inline(never)]
    fn screen_lanes(&self, e: [T; L], s: [T; L]) -> ([T; L], [T; L]) {
        let mut gated = [T::zero(); L];
        let mut reff = self.r;
        for k in 0..L {
            match super::row::screen::<T, N>(self.gate, self.huber, self.nobs[k], self.ssr[k], self.r[k], e[k], s[k]) {
                Some(r) => reff[k] = r,
                None => gated[k] = T::one(),
            }
        }
        (gated, reff)
    }

    /// For the lanes whose sample is risky for the standard form (`r / s` below `√ε`), the
    /// downdated covariance must stay positive definite (checked by Cholesky); `false` when
    /// one would not (the sample is then refused: see [`super::row::LOST_DEFINITENESS`]).
    #[cold]
    #[inline(never)]
    fn downdates_stay_definite(&self, sc: &LaneScratch<T, N, L>) -> bool {
        if self.form != CovarianceForm::Standard {
            return true;
        }
        (0..self.used).all(|k| {
            if sc.go[k] == T::zero() || !(sc.reff[k] < super::row::risky::<T>() * sc.s[k]) {
                return true;
            }
            // Exactly the arithmetic of `apply`: the upper triangle, then mirrored.
            let mut p = SMatrix::<T, N, N>::zeros();
            let coef = sc.w[k] - sc.fc[k];
            for a in 0..N {
                for b in a..N {
                    let v = self.p[a][b][k] - sc.px[a][k] * (sc.px[b][k] * coef);
                    p[(a, b)] = v;
                    p[(b, a)] = v;
                }
            }
            super::row::positive_definite(&p)
        })
    }

    /// `tr(U D Uᵀ)` of every lane (square-root form): `Σ_j D_j (1 + Σ_{a<j} U_aj²)`.
    fn ud_traces(&self) -> [T; L] {
        let mut tr = [[T::zero(); L]; N];
        for j in 0..N {
            for k in 0..L {
                let mut col = T::one();
                for a in 0..j {
                    col += self.p[a][j][k] * self.p[a][j][k];
                }
                tr[j][k] = self.p[j][j][k] * col;
            }
        }
        lane_sum(tr)
    }

    /// Agee–Turner rank-one updates of every lane's factors, `U D Uᵀ + c_k a_k a_kᵀ`
    /// (`c_k ≥ 0`; a lane with `c_k = 0` is unchanged).
    fn ud_rank_one_lanes(&mut self, mut c: [T; L], mut a: [[T; L]; N]) {
        for j in (0..N).rev() {
            let mut bj = [T::zero(); L];
            for k in 0..L {
                let d = self.p[j][j][k];
                let dn = d + c[k] * a[j][k] * a[j][k];
                let live = dn > T::zero() && c[k] > T::zero();
                bj[k] = if live { c[k] * a[j][k] / dn } else { T::zero() };
                c[k] = if live { c[k] * d / dn } else { c[k] };
                self.p[j][j][k] = if live { dn } else { d };
            }
            for i in 0..j {
                for k in 0..L {
                    a[i][k] -= a[j][k] * self.p[i][j][k];
                    self.p[i][j][k] += bj[k] * a[i][k];
                }
            }
        }
    }

    /// The square-root form's plan (Bierman's update in every lane at once; see
    /// [`RowIdentifier`]): the new factors into `sc.ud`, the gain numerator into `sc.px`.
    #[inline(never)]
    fn plan_ud(&self, x: &SVector<T, N>, ek: [T; L], sc: &mut LaneScratch<T, N, L>) -> bool {
        // f = Uᵀ x, v = D f.
        let mut f = [[T::zero(); L]; N];
        let mut v = [[T::zero(); L]; N];
        for j in 0..N {
            let mut col = [[T::zero(); L]; N];
            for i in 0..j {
                col[i] = self.p[i][j];
            }
            col[j] = [T::one(); L];
            f[j] = lane_dot(&col, x);
            for k in 0..L {
                v[j][k] = self.p[j][j][k] * f[j][k];
            }
        }
        (sc.gated, sc.reff) = ([T::zero(); L], self.r);
        if self.gate > T::zero() || self.huber > T::zero() {
            let mut fv = [[T::zero(); L]; N];
            for j in 0..N {
                for k in 0..L {
                    fv[j][k] = f[j][k] * v[j][k];
                }
            }
            let xpx = lane_sum(fv);
            let mut s0 = self.r;
            for k in 0..L {
                s0[k] += xpx[k];
            }
            (sc.gated, sc.reff) = self.screen_lanes(ek, s0);
        }
        let mut alpha = sc.reff;
        let mut b = [[T::zero(); L]; N];
        sc.ud = self.p;
        let mut ok = true;
        for j in 0..N {
            let prev = alpha;
            let mut pj = [T::zero(); L];
            for k in 0..L {
                alpha[k] = prev[k] + f[j][k] * v[j][k];
                let live = alpha[k] > T::zero();
                ok &= alpha[k] >= T::zero() && alpha[k] <= T::biggest() && (live | (f[j][k] == T::zero()));
                let ratio = if live { prev[k] / alpha[k] } else { T::one() };
                sc.ud[j][j][k] = self.p[j][j][k] * ratio;
                pj[k] = if live && prev[k] > T::zero() { -f[j][k] / prev[k] } else { T::zero() };
            }
            for i in 0..j {
                for k in 0..L {
                    let u = self.p[i][j][k];
                    sc.ud[i][j][k] = u + b[i][k] * pj[k];
                    b[i][k] += u * v[j][k];
                }
            }
            b[j] = v[j];
        }
        // s = α_N; lanes with s = 0 (r = 0, nothing new along x) take no step, nor gated ones.
        sc.go = self.active;
        for k in 0..L {
            let live = alpha[k] > T::zero() && sc.gated[k] == T::zero();
            sc.go[k] = if live { sc.go[k] } else { T::zero() };
            sc.s[k] = if live { alpha[k] } else { T::one() };
            let go = sc.go[k] != T::zero();
            sc.w[k] = if go { T::one() / sc.s[k] } else { T::zero() };
            sc.c[k] = if go { ek[k] * sc.w[k] } else { T::zero() };
            if !go {
                // A lane that takes no step keeps its factors.
                for a in 0..N {
                    for bb in a..N {
                        sc.ud[a][bb][k] = self.p[a][bb][k];
                    }
                }
            }
        }
        sc.px = b;
        let mut st = [[T::zero(); L]; N];
        for a in 0..N {
            for k in 0..L {
                st[a][k] = b[a][k] * sc.c[k];
            }
        }
        sc.step = lane_sum(st);
        (sc.fc, sc.scale, sc.add) = if self.lambda < T::one() || self.drift > T::zero() {
            self.tracking(self.ud_traces(), sc.s, sc.reff, sc.go)
        } else {
            ([T::zero(); L], [T::one(); L], [T::zero(); L])
        };
        for k in 0..L {
            ok &= is_fin(sc.step[k]);
            for a in 0..N {
                for bb in a..N {
                    ok &= is_fin(sc.ud[a][bb][k]);
                }
            }
        }
        ok
    }

    /// Applies the square-root plan: `θ += b c`, the new factors, then forgetting (`D ← D/λ`)
    /// and drift (Agee–Turner rank-one updates `+ q e_i e_iᵀ`) where the plan turned them on.
    #[inline(never)]
    fn apply_ud(&mut self, sc: &LaneScratch<T, N, L>) {
        for a in 0..N {
            for k in 0..L {
                self.theta[a][k] += sc.px[a][k] * sc.c[k];
            }
        }
        self.p = sc.ud;
        if self.lambda < T::one() && !self.directional {
            for j in 0..N {
                for k in 0..L {
                    self.p[j][j][k] *= sc.scale[k];
                }
            }
        }
        if sc.fc.iter().any(|c| *c > T::zero()) {
            // Bierman's b is P x: directional forgetting adds c (P x)(P x)ᵀ.
            self.ud_rank_one_lanes(sc.fc, sc.px);
        }
        if sc.add.iter().any(|q| *q > T::zero()) {
            for i in 0..N {
                let mut unit = [[T::zero(); L]; N];
                unit[i] = [T::one(); L];
                self.ud_rank_one_lanes(sc.add, unit);
            }
        }
    }

    /// The statistics of an applied step.
    #[inline(always)]
    fn record(&mut self, sc: &LaneScratch<T, N, L>) {
        let keep = self.lambda;
        if self.gate > T::zero() {
            for k in 0..self.used {
                self.gated[k] += u64::from(sc.gated[k] != T::zero());
            }
        }
        for k in 0..L {
            let go = sc.go[k] != T::zero();
            let w2 = sc.e[k] * sc.c[k] * self.r[k];
            self.ssr[k] = if go { self.ssr[k] * keep + w2 } else { self.ssr[k] };
            self.nobs[k] = if go { self.nobs[k] * keep + T::one() } else { self.nobs[k] };
            self.s[k] = if go { sc.s[k] } else { self.s[k] };
        }
    }
}

impl<T: Real, const N: usize, const L: usize> RowGroup<T, N> for RowLanes<T, N, L> {
    const LANES: usize = L;
    type Scratch = LaneScratch<T, N, L>;

    fn padding() -> Self {
        let mut p = [[[T::zero(); L]; N]; N];
        for (a, row) in p.iter_mut().enumerate() {
            row[a] = [T::one(); L];
        }
        Self {
            theta: [[T::zero(); L]; N],
            p,
            r: [T::one(); L],
            zrow: [0; L],
            active: [T::zero(); L],
            ssr: [T::zero(); L],
            nobs: [T::zero(); L],
            s: [T::zero(); L],
            cap: [T::zero(); L],
            lambda: T::one(),
            drift: T::zero(),
            directional: false,
            gate: T::zero(),
            huber: T::zero(),
            gated: [0; L],
            used: 0,
            form: CovarianceForm::Standard,
            start: false,
            any_r_zero: false,
        }
    }

    fn scratch() -> Self::Scratch {
        LaneScratch {
            px: [[T::zero(); L]; N],
            c: [T::zero(); L],
            w: [T::zero(); L],
            s: [T::zero(); L],
            xth: [T::zero(); L],
            step: [T::zero(); L],
            go: [T::zero(); L],
            e: [T::zero(); L],
            fc: [T::zero(); L],
            scale: [T::one(); L],
            add: [T::zero(); L],
            gated: [T::zero(); L],
            reff: [T::zero(); L],
            ud: [[[T::zero(); L]; N]; N],
        }
    }

    fn set_lane(&mut self, k: usize, zrow: usize, f: &RowIdentifier<T, N>) {
        for a in 0..N {
            self.theta[a][k] = f.theta[a];
            for b in a..N {
                self.p[a][b][k] = f.m[(a, b)];
            }
        }
        self.r[k] = f.r;
        self.zrow[k] = zrow;
        self.active[k] = if f.retired { T::zero() } else { T::one() };
        (self.ssr[k], self.nobs[k], self.s[k], self.cap[k], self.gated[k]) = (f.ssr, f.nobs, f.s, f.cap, f.gated);
        (self.lambda, self.drift, self.directional) = (f.lambda, f.drift, f.directional);
        (self.form, self.start, self.gate, self.huber) = (f.form, f.start, f.gate, f.huber);
        self.used = self.used.max(k + 1);
        self.any_r_zero = (0..self.used).any(|i| self.r[i] == T::zero());
    }

    fn lane(&self, k: usize) -> RowIdentifier<T, N> {
        let mut theta = SVector::<T, N>::zeros();
        for a in 0..N {
            theta[a] = self.theta[a][k];
        }
        RowIdentifier {
            theta,
            m: self.p_lane(k),
            r: self.r[k],
            form: self.form,
            start: self.start,
            retired: self.active[k] == T::zero(),
            lambda: self.lambda,
            directional: self.directional,
            drift: self.drift,
            cap: self.cap[k],
            gate: self.gate,
            huber: self.huber,
            gated: self.gated[k],
            ssr: self.ssr[k],
            nobs: self.nobs[k],
            s: self.s[k],
        }
    }

    fn theta_lane(&self, k: usize) -> SVector<T, N> {
        if self.start {
            return SVector::repeat(T::of(f64::NAN));
        }
        SVector::from_fn(|a, _| self.theta[a][k])
    }

    fn trace_lane(&self, k: usize) -> T {
        if self.start || self.form == CovarianceForm::Sqrt {
            return self.lane(k).trace();
        }
        let mut d = [T::zero(); N];
        for (a, v) in d.iter_mut().enumerate() {
            *v = self.p[a][a][k];
        }
        tree_sum(d)
    }

    fn retire_lane(&mut self, k: usize) {
        self.active[k] = T::zero();
    }

    fn reinitialize(&mut self) {
        if self.start {
            return;
        }
        for k in 0..self.used {
            if self.form == CovarianceForm::Sqrt {
                let mut f = self.lane(k);
                f.reinitialize();
                let zrow = self.zrow[k];
                self.set_lane(k, zrow, &f);
                continue;
            }
            for a in 0..N {
                self.p[a][a][k] *= T::of(10.0);
            }
            self.r[k] *= T::of(2.0);
            self.active[k] = T::one();
        }
    }

    fn starting(&self) -> bool {
        self.start
    }

    #[cold]
    fn absorb(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> crate::Result<()> {
        let mut next = *self;
        for k in 0..self.used {
            let mut f = self.lane(k);
            let zk = z.as_slice().get(self.zrow[k]).copied().unwrap_or_else(T::zero);
            e[k] = f.update(x, zk)?;
            next.set_lane(k, self.zrow[k], &f);
        }
        *self = next;
        Ok(())
    }

    #[inline(always)]
    fn plan(&self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T], sc: &mut Self::Scratch) -> bool {
        sc.xth = lane_dot(&self.theta, x);
        let mut ek = [T::zero(); L];
        for k in 0..L {
            // `zrow` is always in range; `get` keeps the lanes free of a panic branch, which
            // would stop the compiler from keeping them in one vector register.
            let zk = z.as_slice().get(self.zrow[k]).copied().unwrap_or_else(T::zero);
            ek[k] = zk - sc.xth[k];
        }
        sc.e = ek;
        let used = e.len().min(L);
        e[..used].copy_from_slice(&ek[..used]);
        if self.form == CovarianceForm::Sqrt {
            return self.plan_ud(x, ek, sc);
        }
        // P x from the upper triangle, lane by lane, each sum pairwise.
        for a in 0..N {
            let mut col = [[T::zero(); L]; N];
            for b in 0..N {
                col[b] = if a <= b { self.p[a][b] } else { self.p[b][a] };
            }
            sc.px[a] = lane_dot(&col, x);
        }
        // xᵀ P x (stored at once: the compiler then keeps the lanes together).
        sc.s = lane_dot(&sc.px, x);
        for k in 0..L {
            sc.s[k] += self.r[k];
        }
        sc.go = self.active;
        if self.any_r_zero {
            sc.go = self.collapsed_lanes(x, sc.px, sc.s, sc.go);
        }
        (sc.gated, sc.reff) = ([T::zero(); L], self.r);
        if self.gate > T::zero() || self.huber > T::zero() {
            (sc.gated, sc.reff) = self.screen_lanes(ek, sc.s);
            for k in 0..L {
                sc.go[k] = if sc.gated[k] != T::zero() { T::zero() } else { sc.go[k] };
                sc.s[k] += sc.reff[k] - self.r[k];
            }
        }
        let mut ok = true;
        for k in 0..L {
            let s = sc.s[k];
            let inv = T::one() / s;
            let go = sc.go[k] != T::zero();
            // A lane that steps needs 0 < s < inf.
            ok &= !go | ((s > T::zero()) & (s <= T::biggest()));
            sc.w[k] = if go { inv } else { T::zero() };
            sc.c[k] = if go { ek[k] * inv } else { T::zero() };
        }
        let mut st = [[T::zero(); L]; N];
        for a in 0..N {
            for k in 0..L {
                st[a][k] = sc.px[a][k] * sc.c[k];
            }
        }
        sc.step = lane_sum(st);
        let mut risky = false;
        for k in 0..L {
            ok &= is_fin(sc.step[k]);
            risky |= (sc.go[k] != T::zero()) & (sc.reff[k] < super::row::risky::<T>() * sc.s[k]);
        }
        if self.lambda < T::one() || self.drift > T::zero() {
            let mut d = [[T::zero(); L]; N];
            for a in 0..N {
                d[a] = self.p[a][a];
            }
            (sc.fc, sc.scale, sc.add) = self.tracking(lane_sum(d), sc.s, sc.reff, sc.go);
        } else {
            (sc.fc, sc.scale, sc.add) = ([T::zero(); L], [T::one(); L], [T::zero(); L]);
        }
        if risky {
            ok &= self.downdates_stay_definite(sc);
        }
        ok
    }

    #[cold]
    fn check(&self, sc: &Self::Scratch) -> crate::Result<()> {
        let sqrt = self.form == CovarianceForm::Sqrt;
        for k in 0..self.used {
            if sc.go[k] == T::zero() && !sqrt {
                continue;
            }
            if !sc.s[k].finite() || !sc.step[k].finite() {
                return Err(OVERFLOW);
            }
            if sqrt && (0..N).any(|a| (a..N).any(|b| !sc.ud[a][b][k].finite())) {
                return Err(OVERFLOW);
            }
            if !(sc.s[k] > T::zero()) {
                return Err(Error::Singular {
                    what: "the innovation variance xᵀPx + r (P lost positive definiteness: use form='sqrt', f64, or \
                           reinitialization)",
                });
            }
        }
        if sqrt {
            return Err(Error::Singular {
                what: "the innovation variance xᵀPx + r (the square-root factors are not positive)",
            });
        }
        if self.form == CovarianceForm::Standard && !self.downdates_stay_definite(sc) {
            return Err(super::row::LOST_DEFINITENESS);
        }
        Ok(())
    }

    #[inline(always)]
    fn apply(&mut self, x: &SVector<T, N>, sc: &Self::Scratch) {
        self.record(sc);
        match self.form {
            CovarianceForm::Standard => {
                for a in 0..N {
                    for k in 0..L {
                        self.theta[a][k] += sc.px[a][k] * sc.c[k];
                    }
                }
                // P_ab ← P_ab − (P x)_a (P x)_b (1/s − c) on the upper triangle (c: directional
                // forgetting, 0 when off).
                let mut g = [[T::zero(); L]; N];
                for b in 0..N {
                    for k in 0..L {
                        g[b][k] = sc.px[b][k] * (sc.w[k] - sc.fc[k]);
                    }
                }
                for a in 0..N {
                    for b in a..N {
                        for k in 0..L {
                            self.p[a][b][k] -= sc.px[a][k] * g[b][k];
                        }
                    }
                }
                if self.lambda < T::one() || self.drift > T::zero() {
                    self.track(sc);
                }
            }
            CovarianceForm::Joseph => {
                for a in 0..N {
                    for k in 0..L {
                        self.theta[a][k] += sc.px[a][k] * sc.c[k];
                    }
                }
                self.joseph(x, *sc);
            }
            CovarianceForm::Sqrt => self.apply_ud(sc),
        }
    }
}

impl<T: Real, const N: usize, const L: usize> RowLanes<T, N, L> {
    /// Exponential forgetting and drift of the standard form after the downdate:
    /// `P ← P · scale + add I`.
    #[inline(never)]
    fn track(&mut self, sc: &LaneScratch<T, N, L>) {
        for a in 0..N {
            for b in a..N {
                for k in 0..L {
                    self.p[a][b][k] *= sc.scale[k];
                }
            }
            for k in 0..L {
                self.p[a][a][k] += sc.add[k];
            }
        }
    }
}

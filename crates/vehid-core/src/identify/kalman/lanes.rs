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
    /// `P x` per lane.
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
}

/// `L` decoupled row filters stored side by side. Lanes `used..L` are padding (a
/// [`crate::identify::Dynamic`] store rounds the number of rows up to a multiple of `L`); padding never
/// steps and never fails.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowLanes<T: Real, const N: usize, const L: usize> {
    /// `theta[a][k]`: coefficient `a` of lane `k`.
    theta: [[T; L]; N],
    /// `p[a][b][k]` for `a ≤ b`: the upper triangle of lane `k`'s covariance.
    p: [[[T; L]; N]; N],
    r: [T; L],
    /// Index into `z` of each lane's row (0 for padding).
    zrow: [usize; L],
    /// 1 when the lane steps (used and not retired), else 0.
    active: [T; L],
    used: usize,
    any_r_zero: bool,
}

/// A group of row filters handled together (implemented by [`RowLanes`] for every lane
/// count). An implementation detail of the stores, public only because [`crate::identify::Store`] names it.
pub trait RowGroup<T: Real, const N: usize>: Copy + core::fmt::Debug + PartialEq {
    /// Lanes per group.
    const LANES: usize;
    /// The planned step of one sample.
    type Scratch: Copy + core::fmt::Debug;
    /// A group whose lanes are all padding.
    fn padding() -> Self;
    /// An empty scratch.
    fn scratch() -> Self::Scratch;
    /// Puts `filter`, the row filter of row `zrow`, into lane `k` (and marks it used).
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
    /// Plans one sample: innovations of the used lanes into `e`; returns `false` when the
    /// sample must be rejected (see [`RowGroup::check`]). Changes nothing.
    fn plan(&self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T], sc: &mut Self::Scratch) -> bool;
    /// The error of a rejected plan, if a lane of this group caused it (first lane first).
    ///
    /// # Errors
    /// Overflow for a non-finite `s` or θ step, [`Error::Singular`] for `s ≤ 0`.
    fn check(&self, sc: &Self::Scratch) -> crate::Result<()>;
    /// Applies a planned step.
    fn apply(&mut self, x: &SVector<T, N>, sc: &Self::Scratch, form: CovarianceForm);
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
            let f = self.lane(k);
            let g = SVector::<T, N>::from_fn(|a, _| sc.px[a][k] * sc.w[k]);
            let a = SMatrix::<T, N, N>::identity() - g * x.transpose();
            let mut p = a * f.p() * a.transpose() + g * g.transpose() * self.r[k];
            symmetrize(&mut p);
            for i in 0..N {
                for j in i..N {
                    self.p[i][j][k] = p[(i, j)];
                }
            }
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
            used: 0,
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
        }
    }

    fn set_lane(&mut self, k: usize, zrow: usize, f: &RowIdentifier<T, N>) {
        for a in 0..N {
            self.theta[a][k] = f.theta()[a];
            for b in a..N {
                self.p[a][b][k] = f.p()[(a, b)];
            }
        }
        self.r[k] = f.r();
        self.zrow[k] = zrow;
        self.active[k] = if f.retired() { T::zero() } else { T::one() };
        self.used = self.used.max(k + 1);
        self.any_r_zero = (0..self.used).any(|i| self.r[i] == T::zero());
    }

    fn lane(&self, k: usize) -> RowIdentifier<T, N> {
        let mut p = SMatrix::<T, N, N>::zeros();
        for a in 0..N {
            for b in a..N {
                p[(a, b)] = self.p[a][b][k];
                p[(b, a)] = self.p[a][b][k];
            }
        }
        RowIdentifier::from_parts(self.theta_lane(k), p, self.r[k], self.active[k] == T::zero())
    }

    fn theta_lane(&self, k: usize) -> SVector<T, N> {
        SVector::from_fn(|a, _| self.theta[a][k])
    }

    fn trace_lane(&self, k: usize) -> T {
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
        for k in 0..self.used {
            for a in 0..N {
                self.p[a][a][k] *= T::of(10.0);
            }
            self.r[k] *= T::of(2.0);
            self.active[k] = T::one();
        }
    }

    #[inline(always)]
    fn plan(&self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T], sc: &mut Self::Scratch) -> bool {
        // P x from the upper triangle, lane by lane, each sum pairwise.
        for a in 0..N {
            let mut col = [[T::zero(); L]; N];
            for b in 0..N {
                col[b] = if a <= b { self.p[a][b] } else { self.p[b][a] };
            }
            sc.px[a] = lane_dot(&col, x);
        }
        // xᵀ P x and xᵀ θ (each stored at once: the compiler then keeps the lanes together).
        sc.s = lane_dot(&sc.px, x);
        sc.xth = lane_dot(&self.theta, x);
        let mut ek = [T::zero(); L];
        for k in 0..L {
            // `zrow` is always in range; `get` keeps the lanes free of a panic branch, which
            // would stop the compiler from keeping them in one vector register.
            let zk = z.as_slice().get(self.zrow[k]).copied().unwrap_or_else(T::zero);
            ek[k] = zk - sc.xth[k];
            sc.s[k] += self.r[k];
        }
        sc.go = self.active;
        if self.any_r_zero {
            sc.go = self.collapsed_lanes(x, sc.px, sc.s, sc.go);
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
        for k in 0..L {
            ok &= is_fin(sc.step[k]);
        }
        let used = e.len().min(L);
        e[..used].copy_from_slice(&ek[..used]);
        ok
    }

    #[cold]
    fn check(&self, sc: &Self::Scratch) -> crate::Result<()> {
        for k in 0..self.used {
            if sc.go[k] == T::zero() {
                continue;
            }
            if !sc.s[k].finite() {
                return Err(OVERFLOW);
            }
            if !(sc.s[k] > T::zero()) {
                return Err(Error::Singular {
                    what: "the innovation variance xᵀPx + r (P lost positive definiteness: use the \
                           Joseph form, f64, or reinitialization)",
                });
            }
            if !sc.step[k].finite() {
                return Err(OVERFLOW);
            }
        }
        Ok(())
    }

    #[inline(always)]
    fn apply(&mut self, x: &SVector<T, N>, sc: &Self::Scratch, form: CovarianceForm) {
        for a in 0..N {
            for k in 0..L {
                self.theta[a][k] += sc.px[a][k] * sc.c[k];
            }
        }
        match form {
            CovarianceForm::Standard => {
                // P_ab ← P_ab − (P x)_a (P x)_b / s on the upper triangle.
                let mut g = [[T::zero(); L]; N];
                for b in 0..N {
                    for k in 0..L {
                        g[b][k] = sc.px[b][k] * sc.w[k];
                    }
                }
                for a in 0..N {
                    for b in a..N {
                        for k in 0..L {
                            self.p[a][b][k] -= sc.px[a][k] * g[b][k];
                        }
                    }
                }
            }
            CovarianceForm::Joseph => self.joseph(x, *sc),
        }
    }
}

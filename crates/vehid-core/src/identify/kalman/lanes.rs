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
use crate::identify::{OVERFLOW, OVERFLOW_Z};
use crate::linalg::symmetrize;
use crate::{Error, Real};
use nalgebra::{SMatrix, SVector};

/// `for $j in 0..$n $body`, written out for the first 16 indices (a loop beyond). The compiler
/// fully unrolls a loop only below a size threshold that it applies before vectorizing,
/// counting each lane as an operation: the square-root form's column sweeps for `N = 8` and
/// four lanes exceed it and were left as loops over memory, scalar. Written out (a macro: a
/// closure called sixteen times would not be inlined), every index is a constant and the
/// lanes stay in vector registers.
macro_rules! unrolled {
    ($n:expr, |$j:ident| $body:block) => {{
        unrolled!(@each $n, $j, $body, 0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15);
        for $j in 16..$n {
            $body
        }
    }};
    (@each $n:expr, $j:ident, $body:block, $($i:literal)*) => {
        $(
            // A `const` test: the copies past `$n` are not even compiled.
            if const { $i < $n } {
                let $j: usize = $i;
                $body
            }
        )*
    };
}

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

/// Writes the lanes `v` into `out` (its first `L` entries, or all of them when it is shorter),
/// lane by lane: a copy of a run-time length would call `memcpy` and keep `v` in memory.
#[inline(always)]
fn put_lanes<T: Real, const L: usize>(out: &mut [T], v: [T; L]) {
    if let Some(head) = out.get_mut(..L) {
        head.copy_from_slice(&v);
    } else {
        for k in 0..L {
            if let Some(o) = out.get_mut(k) {
                *o = v[k];
            }
        }
    }
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

/// Which argument an overflowing step is due to: the state (`x θ` not finite) or the
/// derivative (an innovation far beyond the prediction).
#[cold]
pub(crate) fn overflow_culprit<T: Real>(e: T, xth: T) -> crate::Error {
    if !xth.finite() {
        OVERFLOW
    } else if !e.finite() || e.abs() > (xth.abs() + T::one()) * T::of(1e6) {
        OVERFLOW_Z
    } else {
        OVERFLOW
    }
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
    /// The statistics after the step (`ssr`, `nobs`, last `s`; unchanged in a lane that takes
    /// no step), computed by the plan so that applying it is a plain copy.
    ssr: [T; L],
    nobs: [T; L],
    s_last: [T; L],
}

/// The planned step of the square-root form: the common part (innovations, gain numerator
/// `P x`, statistics, tracking) and, per column `j`, `v_j = D_j f_j`, Bierman's
/// `p_j = −f_j / α_{j−1}` and `D_j`'s factor `α_{j−1} / α_j` (`apply_sqrt` replays the column
/// sweep with them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SqrtScratch<T: Real, const N: usize, const L: usize> {
    base: LaneScratch<T, N, L>,
    v: [[T; L]; N],
    p: [[T; L]; N],
    ratio: [[T; L]; N],
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
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct RowLanes<T: Real, const N: usize, const L: usize> {
    /// `theta[a][k]`: coefficient `a` of lane `k`.
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array2"))]
    theta: [[T; L]; N],
    /// `p[a][b][k]` for `a ≤ b`: the upper triangle of lane `k`'s matrix (see above).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array3"))]
    p: [[[T; L]; N]; N],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    r: [T; L],
    /// Index into `z` of each lane's row (0 for padding).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    zrow: [usize; L],
    /// 1 when the lane steps (used and not retired), else 0.
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    active: [T; L],
    /// Statistics per lane: Σ of squared recursive residuals, effective samples, last `s`.
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    ssr: [T; L],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    nobs: [T; L],
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    s: [T; L],
    /// Tracking: the trace bound per lane, the forgetting factor and the drift.
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    cap: [T; L],
    lambda: T,
    drift: T,
    directional: bool,
    /// Outlier gate κ, Huber constant (0: off), and the samples each lane gated.
    gate: T,
    huber: T,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    gated: [u64; L],
    #[cfg_attr(feature = "serde", serde(deserialize_with = "crate::persist::at_most::<_, L>"))]
    used: usize,
    form: CovarianceForm,
    /// Absorbing an exact start (every lane at once: they share the regressors).
    start: bool,
    any_r_zero: bool,
    /// Which update applies ([`RowGroup::mode`]): [`PLAIN`], [`FORGET`] or [`GENERAL`].
    /// Derived from the fields above by [`RowGroup::refresh`], not stored (0, read as the
    /// general path, until refreshed).
    #[cfg_attr(feature = "serde", serde(skip))]
    mode: u8,
    /// Exponential forgetting's factor per lane while its trace is below the bound: `1/λ`
    /// in the active lanes, 1 in the others. Derived like `mode`.
    #[cfg_attr(feature = "serde", serde(skip, default = "ones"))]
    forget: [T; L],
}

/// `[1; L]` (the default of a derived lane vector).
#[cfg(feature = "serde")]
fn ones<T: Real, const L: usize>() -> [T; L] {
    [T::one(); L]
}

/// [`RowGroup::mode`]: the standard form after the start, no tracking, no outlier screen, no
/// lane with `r = 0`.
pub const PLAIN: u8 = 1;
/// [`RowGroup::mode`]: as [`PLAIN`] with exponential forgetting (no drift, not directional).
pub const FORGET: u8 = 2;
/// [`RowGroup::mode`]: anything else (the other forms, the exact start, the outlier screen,
/// lanes with `r = 0`, drift and directional forgetting). Each special mode is one more
/// compiled copy of the update per identifier type, so only the common cases have one.
pub const GENERAL: u8 = 0;

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
    /// Covariance resetting on every used lane ([`RowIdentifier::reset_covariance`]; `p0`
    /// checked by the caller): `P ← p0 I`, `θ̂` kept; used lanes step again.
    fn reset_covariance(&mut self, p0: T);
    /// `true` while the lanes absorb an exact start.
    fn starting(&self) -> bool;
    /// Exact start: one sample absorbed by every used lane (innovations NaN into `e`).
    ///
    /// # Errors
    /// Overflow; the group is unchanged then.
    fn absorb(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> crate::Result<()>;
    /// The update that applies: [`PLAIN`], [`FORGET`] or [`GENERAL`]. [`RowGroup::plan`] and
    /// [`RowGroup::apply`] may be called with `MODE` equal to it (or [`GENERAL`], always
    /// valid): the two special ones leave out the tests for the options they exclude.
    fn mode(&self) -> u8;
    /// Derives what is not stored (after deserialization).
    fn refresh(&mut self);
    /// Plans one sample: innovations of the used lanes into `e`; returns `false` when the
    /// sample cannot be applied at once: it is refused, or a lane's downdate is risky (see
    /// [`RowGroup::check`]). Changes nothing. `MODE`: see [`RowGroup::mode`].
    fn plan<const MODE: u8>(&self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T], sc: &mut Self::Scratch) -> bool;
    /// Of a plan that [`RowGroup::plan`] did not accept at once: `true` when it may be applied
    /// all the same (every lane's θ step finite, `0 < s < ∞` in the lanes that step, and the
    /// risky downdates stay positive definite).
    fn accepts(&self, x: &SVector<T, N>, sc: &Self::Scratch) -> bool;
    /// The error of a plan that [`RowGroup::accepts`] refuses, if a lane of this group caused
    /// it (first lane first).
    ///
    /// # Errors
    /// Overflow for a non-finite `s` or θ step, [`Error::Singular`] for `s ≤ 0` or a risky
    /// downdate that would lose positive definiteness.
    fn check(&self, x: &SVector<T, N>, sc: &Self::Scratch) -> crate::Result<()>;
    /// Applies a planned step (`MODE` as in the plan).
    fn apply<const MODE: u8>(&mut self, x: &SVector<T, N>, sc: &Self::Scratch);
    /// The planned step of one sample in the square-root form.
    type SqrtScratch: Copy + core::fmt::Debug;
    /// An empty square-root scratch.
    fn sqrt_scratch() -> Self::SqrtScratch;
    /// [`RowGroup::plan`] for the square-root form (Bierman's update).
    fn plan_sqrt(&self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T], sc: &mut Self::SqrtScratch) -> bool;
    /// [`RowGroup::check`] for the square-root form.
    ///
    /// # Errors
    /// Overflow, or [`Error::Singular`] when the factors are not positive.
    fn check_sqrt(&self, sc: &Self::SqrtScratch) -> crate::Result<()>;
    /// Applies a step planned by [`RowGroup::plan_sqrt`].
    fn apply_sqrt(&mut self, sc: &Self::SqrtScratch);
    /// `true` when the used lanes hold exactly `rows` (their indices into `z`), in order.
    fn lanes_are(&self, rows: &[usize]) -> bool;
    /// `true` when a plan leaves its sample out of a lane as an outlier (the gate).
    fn gates(sc: &Self::Scratch) -> bool;
    /// [`RowGroup::gates`] for a plan of the square-root form.
    fn gates_sqrt(sc: &Self::SqrtScratch) -> bool;
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
            let floor = super::row::collapse_floor::<T, N>(ax, tree_sum(ap));
            if self.r[k] == T::zero() && s[k] <= floor {
                go[k] = T::zero();
            }
        }
        go
    }

    /// [`Self::collapsed_lanes`] for the square-root form, from `f = Uᵀx` and `v = D f`:
    /// `xᵀPx = Σ f_j v_j`, `P x = U v`. (`s` without `r`: only the lanes with `r = 0` are
    /// judged.)
    #[inline(never)]
    fn collapsed_lanes_ud(&self, x: &SVector<T, N>, f: &[[T; L]; N], v: &[[T; L]; N], go: [T; L]) -> [T; L] {
        let mut fv = [[T::zero(); L]; N];
        let mut px = *v;
        for j in 0..N {
            for k in 0..L {
                fv[j][k] = f[j][k] * v[j][k];
            }
            for i in 0..j {
                for k in 0..L {
                    px[i][k] += self.p[i][j][k] * v[j][k];
                }
            }
        }
        self.collapsed_lanes(x, px, lane_sum(fv), go)
    }

    /// Joseph's form, lane by lane: `P ← (I − g xᵀ) P (I − g xᵀ)ᵀ + r g gᵀ`, `g = P x / s`.
    #[inline(never)]
    fn joseph(&mut self, x: &SVector<T, N>, sc: LaneScratch<T, N, L>) {
        for k in 0..self.used {
            if sc.go[k] == T::zero() {
                continue;
            }
            let p = self.joseph_lane(x, &sc, k);
            for i in 0..N {
                for j in i..N {
                    self.p[i][j][k] = p[(i, j)];
                }
            }
        }
    }

    /// Lane `k`'s covariance after Joseph's update (with the tracking the plan turned on:
    /// directional forgetting `c (P x)(P x)ᵀ`, then `· scale` and `+ add` on the diagonal),
    /// mirrored.
    fn joseph_lane(&self, x: &SVector<T, N>, sc: &LaneScratch<T, N, L>, k: usize) -> SMatrix<T, N, N> {
        let p = self.p_lane(k);
        let g = SVector::<T, N>::from_fn(|a, _| sc.px[a][k] * sc.w[k]);
        let a = SMatrix::<T, N, N>::identity() - g * x.transpose();
        let px = SVector::<T, N>::from_fn(|a, _| sc.px[a][k]);
        let mut p = a * p * a.transpose() + g * g.transpose() * sc.reff[k] + px * px.transpose() * sc.fc[k];
        symmetrize(&mut p);
        for i in 0..N {
            for j in i..N {
                let v = p[(i, j)] * sc.scale[k] + if i == j { sc.add[k] } else { T::zero() };
                p[(i, j)] = v;
                p[(j, i)] = v;
            }
        }
        p
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
        // Whole-lane arithmetic and selects of computed values (`on` is 1 or 0, so that
        // `on · q` is q or 0 exactly); the kind of forgetting is one test for all lanes.
        let mut on = [T::zero(); L];
        for k in 0..L {
            on[k] = if (go[k] != T::zero()) & (trace[k] < self.cap[k]) { T::one() } else { T::zero() };
        }
        let mut fc = [T::zero(); L];
        let mut scale = [T::one(); L];
        let mut add = [T::zero(); L];
        let drift = self.drift;
        for k in 0..L {
            add[k] = on[k] * drift;
        }
        if self.directional {
            let k_lambda = (T::one() - self.lambda) / self.lambda;
            for k in 0..L {
                let xpx = s[k] - r[k];
                let dir = (on[k] != T::zero()) & (xpx > T::zero());
                fc[k] = if dir { k_lambda * r[k] / (s[k] * xpx) } else { T::zero() };
            }
        } else {
            let inv = T::one() / self.lambda;
            for k in 0..L {
                scale[k] = if on[k] != T::zero() { inv } else { T::one() };
            }
        }
        (fc, scale, add)
    }

    /// [`Self::tracking`] for exponential forgetting alone (no drift, not directional): the
    /// factor `1/λ` in the lanes that step (in this mode, the active ones) with their trace
    /// below the bound, else 1.
    #[inline(always)]
    fn forgetting(&self, trace: [T; L]) -> [T; L] {
        let mut scale = [T::one(); L];
        for k in 0..L {
            scale[k] = if trace[k] < self.cap[k] { self.forget[k] } else { T::one() };
        }
        scale
    }

    /// `tr P` of every lane (the standard form: the sum of the stored diagonal, pairwise).
    #[inline(always)]
    fn diag_traces(&self) -> [T; L] {
        let mut d = [[T::zero(); L]; N];
        for a in 0..N {
            d[a] = self.p[a][a];
        }
        lane_sum(d)
    }

    /// The outlier screen of every lane ([`super::row::screen`]): the gated flags (1/0) and
    /// the variance each lane uses.
    #[inline(never)]
    fn screen_lanes(&self, e: [T; L], s: [T; L]) -> ([T; L], [T; L]) {
        let mut gated = [T::zero(); L];
        let mut reff = self.r;
        for k in 0..L {
            match super::row::screen(self.gate, self.huber, self.nobs[k], self.ssr[k], self.r[k], e[k], s[k], N) {
                Some(r) => reff[k] = r,
                None => gated[k] = T::one(),
            }
        }
        (gated, reff)
    }

    /// For the lanes whose sample is risky for the standard or Joseph form (`r / s` below
    /// `√ε`), the covariance after the update must stay positive definite (checked by
    /// Cholesky, on exactly the arithmetic the update will do); `false` when one would not
    /// (the sample is then refused: see [`super::row::LOST_DEFINITENESS`]).
    #[cold]
    #[inline(never)]
    fn downdates_stay_definite(&self, x: &SVector<T, N>, sc: LaneScratch<T, N, L>) -> bool {
        if self.form == CovarianceForm::Sqrt {
            return true;
        }
        (0..self.used).all(|k| {
            if sc.go[k] == T::zero() || sc.reff[k] == T::zero() || !(sc.reff[k] < super::row::risky::<T>() * sc.s[k]) {
                return true;
            }
            if self.form == CovarianceForm::Joseph {
                return super::row::positive_definite(&self.joseph_lane(x, &sc, k), N);
            }
            // Exactly the arithmetic of `apply`: the upper triangle, then mirrored.
            let mut p = SMatrix::<T, N, N>::zeros();
            let tracking = self.lambda < T::one() || self.drift > T::zero();
            for a in 0..N {
                for b in a..N {
                    let v = if tracking {
                        let g = sc.px[b][k] * ((sc.w[k] - sc.fc[k]) * sc.scale[k]);
                        self.p[a][b][k] * sc.scale[k] - sc.px[a][k] * g + if a == b { sc.add[k] } else { T::zero() }
                    } else {
                        self.p[a][b][k] - sc.px[a][k] * (sc.px[b][k] * sc.w[k])
                    };
                    p[(a, b)] = v;
                    p[(b, a)] = v;
                }
            }
            super::row::positive_definite(&p, N)
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
    /// [`RowIdentifier`]): Bierman's per-column quantities for `apply_ud`, the gain numerator (`P x`)
    /// into `sc.px`; checks that the update cannot overflow. Everything is computed into
    /// locals and the plan written once at the end (so that it can stay in registers).
    #[inline(always)]
    fn plan_ud(&self, x: &SVector<T, N>, xth: [T; L], ek: [T; L], ss: &mut SqrtScratch<T, N, L>) -> bool {
        // f = Uᵀ x, v = D f (each f_j the pairwise sum over all N terms, the zero ones too).
        let mut f = [[T::zero(); L]; N];
        let mut v = [[T::zero(); L]; N];
        unrolled!(N, |j| {
            let mut col = [[T::zero(); L]; N];
            for i in 0..j {
                col[i] = self.p[i][j];
            }
            col[j] = [T::one(); L];
            f[j] = lane_dot(&col, x);
            for k in 0..L {
                v[j][k] = self.p[j][j][k] * f[j][k];
            }
        });
        let (mut gated, mut reff) = ([T::zero(); L], self.r);
        // Lanes that step: active, not collapsed along x (noise-free lanes, as in the
        // covariance forms) and not gated (the others keep their factors: ratio 1, p 0).
        let mut act = self.active;
        if self.any_r_zero {
            act = self.collapsed_lanes_ud(x, &f, &v, act);
        }
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
            (gated, reff) = self.screen_lanes(ek, s0);
            for k in 0..L {
                // `gated` is 1 or 0: exactly the active flag or 0.
                act[k] *= T::one() - gated[k];
            }
        }
        // The sweep over the columns, in passes of one simple loop each (the ones the compiler
        // would leave rolled for N = 8 written out by `unrolled!`), with the arithmetic of the
        // column-by-column form: α_j = α_{j−1} + f_j v_j (non-decreasing: f_j v_j = D_j f_j²
        // ≥ 0), one division per column (1/α_j serves D_j's factor and the next column's p),
        // selects on whole lanes.
        let mut alphas = [[T::zero(); L]; N];
        let mut alpha = reff;
        for j in 0..N {
            for k in 0..L {
                alpha[k] += f[j][k] * v[j][k];
            }
            alphas[j] = alpha;
        }
        let mut inv0 = [T::zero(); L];
        for k in 0..L {
            inv0[k] = if reff[k] > T::zero() { T::one() / reff[k] } else { T::zero() };
        }
        let mut inv = [[T::zero(); L]; N];
        for j in 0..N {
            for k in 0..L {
                let q = T::one() / alphas[j][k];
                inv[j][k] = if alphas[j][k] > T::zero() { q } else { T::zero() };
            }
        }
        let mut ratio = [[T::one(); L]; N];
        let mut pj = [[T::zero(); L]; N];
        unrolled!(N, |j| {
            let (prev, inv_prev) = if j == 0 { (reff, inv0) } else { (alphas[j - 1], inv[j - 1]) };
            for k in 0..L {
                let live = alphas[j][k] > T::zero();
                let step = act[k] != T::zero();
                ratio[j][k] = if step & live { prev[k] * inv[j][k] } else { T::one() };
                pj[j][k] = if step { -f[j][k] * inv_prev[k] } else { T::zero() };
            }
        });
        // The maxima of |p| and |v| (for the overflow bound below) as compare and select:
        // `max` would also order NaNs, which costs three instructions per lane here and
        // cannot matter (a NaN in p or v makes α_N NaN or infinite: the plan is refused).
        let mut pmax = [T::zero(); L];
        let mut vmax = [T::zero(); L];
        for j in 0..N {
            for k in 0..L {
                let (ap, av) = (pj[j][k].abs(), v[j][k].abs());
                pmax[k] = if ap > pmax[k] { ap } else { pmax[k] };
                vmax[k] = if av > vmax[k] { av } else { vmax[k] };
            }
        }
        // The gain numerator b = P x: b_i = v_i + Σ_{j>i} U_ij v_j, summed in increasing j.
        let mut b = v;
        for i in 0..N {
            for j in (i + 1)..N {
                for k in 0..L {
                    b[i][k] += self.p[i][j][k] * v[j][k];
                }
            }
        }
        // α_N finite and ≥ 0 (it is when the factors are: D ≥ 0).
        let mut ok = true;
        for k in 0..L {
            ok &= (alpha[k] >= T::zero()) & (alpha[k] <= T::biggest());
        }
        // |U'_ij| ≤ |U_ij| + |b_i| |p_j| with |b_i| ≤ (1 + N max|U|) max|v|: bounded, so that
        // `apply_sqrt`, which updates U in place, cannot overflow.
        let mut umax = [T::zero(); L];
        for j in 0..N {
            for i in 0..j {
                for k in 0..L {
                    let au = self.p[i][j][k].abs();
                    umax[k] = if au > umax[k] { au } else { umax[k] };
                }
            }
        }
        let mut bounded = [true; L];
        for k in 0..L {
            let bbound = (T::one() + T::of(N as f64) * umax[k]) * vmax[k];
            bounded[k] = is_fin(umax[k] + bbound * pmax[k]);
        }
        // s = α_N; lanes with s = 0 (r = 0, nothing new along x) take no step, nor gated ones.
        let (mut go, mut s, mut w, mut c) = ([T::zero(); L], [T::one(); L], [T::zero(); L], [T::zero(); L]);
        for k in 0..L {
            let live = (alpha[k] > T::zero()) & (act[k] != T::zero());
            go[k] = if live { T::one() } else { T::zero() };
            s[k] = if live { alpha[k] } else { T::one() };
            w[k] = if live { T::one() / s[k] } else { T::zero() };
            c[k] = if live { ek[k] * w[k] } else { T::zero() };
        }
        let mut st = [[T::zero(); L]; N];
        for a in 0..N {
            for k in 0..L {
                st[a][k] = b[a][k] * c[k];
            }
        }
        let mut step = lane_sum(st);
        let (ssr, nobs, s_last) = self.statistics(go, ek, c, s);
        let (fc, scale, add) = if self.tracks() {
            self.tracking(self.ud_traces(), s, reff, go)
        } else {
            ([T::zero(); L], [T::one(); L], [T::zero(); L])
        };
        for k in 0..L {
            // A factor update that could overflow shows as a non-finite step (see `check`).
            step[k] = if bounded[k] { step[k] } else { T::of(f64::INFINITY) };
            ok &= is_fin(step[k]);
        }
        ss.base = LaneScratch { px: b, c, w, s, xth, step, go, e: ek, fc, scale, add, gated, reff, ssr, nobs, s_last };
        (ss.v, ss.p, ss.ratio) = (v, pj, ratio);
        ok
    }

    /// Applies the square-root plan: `θ += b c`, the new factors, then forgetting (`D ← D/λ`)
    /// and drift (Agee–Turner rank-one updates `+ q e_i e_iᵀ`) where the plan turned them on.
    #[inline(always)]
    fn apply_ud(&mut self, ss: &SqrtScratch<T, N, L>) {
        let sc = &ss.base;
        for a in 0..N {
            for k in 0..L {
                self.theta[a][k] += sc.px[a][k] * sc.c[k];
            }
        }
        // Bierman's column sweep, replayed in place with the plan's v, p and ratios: the same
        // arithmetic as the plan's gain, so the same numbers. Row by row (each entry needs
        // only its row's running sum b_i, so the order of the rows does not matter).
        for j in 0..N {
            for k in 0..L {
                self.p[j][j][k] *= ss.ratio[j][k];
            }
        }
        unrolled!(N, |i| {
            let mut b = ss.v[i];
            for j in (i + 1)..N {
                for k in 0..L {
                    let u = self.p[i][j][k];
                    self.p[i][j][k] = u + b[k] * ss.p[j][k];
                    b[k] += u * ss.v[j][k];
                }
            }
        });
        if !self.tracks() {
            return;
        }
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

    /// The statistics after a step with innovations `e`, `c = e / s` and variances `s` in the
    /// lanes where `go` is set (the others keep theirs): `(ssr, nobs, s)`. Computed while
    /// planning, from values in registers: selecting between two stored values here would
    /// make the compiler select between their addresses and keep the plan in memory.
    #[inline(always)]
    fn statistics(&self, go: [T; L], e: [T; L], c: [T; L], s: [T; L]) -> ([T; L], [T; L], [T; L]) {
        // Written as arithmetic and selects of computed values only (a select of a stored
        // value becomes a branch or a select of addresses): with `go` 1 or 0, `kk` is λ or 1
        // (exactly) and `w2`, `sg` are 0 in a lane that takes no step, so that lane keeps its
        // values exactly (they are ≥ +0).
        let keep = self.lambda;
        let (mut ssr, mut nobs, mut s_last) = ([T::zero(); L], [T::zero(); L], [T::zero(); L]);
        for k in 0..L {
            let step = go[k] != T::zero();
            let kk = go[k] * keep + (T::one() - go[k]);
            let w2 = if step { e[k] * c[k] * self.r[k] } else { T::zero() };
            let sg = if step { s[k] } else { T::zero() };
            ssr[k] = self.ssr[k] * kk + w2;
            nobs[k] = self.nobs[k] * kk + go[k];
            s_last[k] = self.s[k] * (T::one() - go[k]) + sg;
        }
        (ssr, nobs, s_last)
    }

    /// The statistics of an applied step (planned by [`Self::statistics`]).
    #[inline(always)]
    fn record<const MODE: u8>(&mut self, sc: &LaneScratch<T, N, L>) {
        (self.ssr, self.nobs, self.s) = (sc.ssr, sc.nobs, sc.s_last);
        if const { MODE == GENERAL } && self.gate > T::zero() {
            // Over every lane (padding is never gated): a run-time bound would index the plan
            // dynamically and keep it in memory. A gated sample enters the scale Winsorized at
            // the gate (row::gated_scale): a lasting change opens the gate within tens of
            // samples.
            for k in 0..L {
                let gated = sc.gated[k] != T::zero();
                self.gated[k] += u64::from(gated);
                if gated {
                    (self.ssr[k], self.nobs[k]) =
                        super::row::gated_scale(self.gate, self.lambda, self.ssr[k], self.nobs[k], N);
                }
            }
        }
    }

    /// The innovations `z_row − xᵀθ` of every lane, from `xth = xᵀθ`: the measured values
    /// gathered first, then one whole-lane subtraction (so that `xᵀθ` stays vectorized).
    #[inline(always)]
    fn innovations(&self, z: &SVector<T, N>, xth: [T; L]) -> [T; L] {
        let mut zk = [T::zero(); L];
        for k in 0..L {
            // `zrow` is always in range; `get` keeps the lanes free of a panic branch, which
            // would stop the compiler from keeping them in one vector register.
            zk[k] = z.as_slice().get(self.zrow[k]).copied().unwrap_or_else(T::zero);
        }
        let mut ek = [T::zero(); L];
        for k in 0..L {
            ek[k] = zk[k] - xth[k];
        }
        ek
    }

    /// `true` when forgetting or drift is on.
    #[inline(always)]
    fn tracks(&self) -> bool {
        self.lambda < T::one() || self.drift > T::zero()
    }
}

impl<T: Real, const N: usize, const L: usize> RowGroup<T, N> for RowLanes<T, N, L> {
    const LANES: usize = L;
    type Scratch = LaneScratch<T, N, L>;
    type SqrtScratch = SqrtScratch<T, N, L>;

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
            mode: PLAIN,
            forget: [T::one(); L],
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
            ssr: [T::zero(); L],
            nobs: [T::zero(); L],
            s_last: [T::zero(); L],
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
        self.refresh();
    }

    #[inline(always)]
    fn mode(&self) -> u8 {
        self.mode
    }

    fn refresh(&mut self) {
        let standard = self.form == CovarianceForm::Standard
            && !self.start
            && !self.any_r_zero
            && self.gate == T::zero()
            && self.huber == T::zero();
        let exponential = !self.directional && self.drift == T::zero();
        self.mode = match (standard, self.tracks(), exponential) {
            (true, false, _) => PLAIN,
            (true, true, true) => FORGET,
            _ => GENERAL,
        };
        let inv = T::one() / self.lambda;
        for k in 0..L {
            self.forget[k] = if self.active[k] != T::zero() { inv } else { T::one() };
        }
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
            dim: N as u8,
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
        self.refresh();
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
        self.refresh();
    }

    fn reset_covariance(&mut self, p0: T) {
        for k in 0..self.used {
            let mut f = self.lane(k);
            if f.reset_covariance(p0).is_ok() {
                let zrow = self.zrow[k];
                self.set_lane(k, zrow, &f);
            }
        }
        self.refresh();
    }

    fn starting(&self) -> bool {
        self.start
    }

    fn lanes_are(&self, rows: &[usize]) -> bool {
        self.used == rows.len() && self.zrow.get(..self.used) == Some(rows)
    }

    fn gates(sc: &Self::Scratch) -> bool {
        // Padding is never gated.
        sc.gated.iter().any(|g| *g != T::zero())
    }

    fn gates_sqrt(sc: &Self::SqrtScratch) -> bool {
        Self::gates(&sc.base)
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
    fn plan<const MODE: u8>(&self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T], sc: &mut Self::Scratch) -> bool {
        // Everything is computed into locals and the plan written once at the end: the
        // compiler then keeps it in registers (no initialization, no stores it cannot drop).
        let xth = lane_dot(&self.theta, x);
        let ek = self.innovations(z, xth);
        put_lanes(e, ek);
        // P x from the upper triangle, lane by lane, each sum pairwise.
        let mut px = [[T::zero(); L]; N];
        for a in 0..N {
            let mut col = [[T::zero(); L]; N];
            for b in 0..N {
                col[b] = if a <= b { self.p[a][b] } else { self.p[b][a] };
            }
            px[a] = lane_dot(&col, x);
        }
        // Exponential forgetting needs tr P before the update: summed while the diagonal is
        // loaded anyway.
        let trace = if const { MODE == FORGET } { self.diag_traces() } else { [T::zero(); L] };
        let mut s = lane_dot(&px, x);
        for k in 0..L {
            s[k] += self.r[k];
        }
        let mut go = self.active;
        if const { MODE == GENERAL } && self.any_r_zero {
            go = self.collapsed_lanes(x, px, s, go);
        }
        let (mut gated, mut reff) = ([T::zero(); L], self.r);
        if const { MODE == GENERAL } && (self.gate > T::zero() || self.huber > T::zero()) {
            (gated, reff) = self.screen_lanes(ek, s);
            for k in 0..L {
                go[k] = if gated[k] != T::zero() { T::zero() } else { go[k] };
                s[k] += reff[k] - self.r[k];
            }
        }
        // Per lane, as whole-lane arithmetic and selects (so that it stays vectorized). A lane
        // that steps needs 0 < s < inf; r/s below √ε makes its downdate risky. Either marks
        // the lane's step check with a NaN, so that one test of the steps refuses the plan:
        // `check` then names the cause, or finds only risky downdates that stay definite.
        let rk = super::row::risky::<T>();
        let mut w = [T::zero(); L];
        let mut c = [T::zero(); L];
        let mut flag = [T::zero(); L];
        for k in 0..L {
            let inv = T::one() / s[k];
            let step = go[k] != T::zero();
            let fine = (s[k] > T::zero()) & (s[k] <= T::biggest());
            let risky = (reff[k] > T::zero()) & (reff[k] < rk * s[k]);
            flag[k] = if step & (risky | !fine) { T::of(f64::NAN) } else { T::zero() };
            w[k] = if step { inv } else { T::zero() };
            c[k] = if step { ek[k] * inv } else { T::zero() };
        }
        let mut st = [[T::zero(); L]; N];
        for a in 0..N {
            for k in 0..L {
                st[a][k] = px[a][k] * c[k];
            }
        }
        let step = lane_sum(st);
        let mut ok = true;
        for k in 0..L {
            ok &= is_fin(step[k] + flag[k]);
        }
        let (fc, scale, add) = match MODE {
            PLAIN => ([T::zero(); L], [T::one(); L], [T::zero(); L]),
            FORGET => ([T::zero(); L], self.forgetting(trace), [T::zero(); L]),
            _ if self.tracks() => self.tracking(self.diag_traces(), s, reff, go),
            _ => ([T::zero(); L], [T::one(); L], [T::zero(); L]),
        };
        let (ssr, nobs, s_last) = self.statistics(go, ek, c, s);
        *sc = LaneScratch { px, c, w, s, xth, step, go, e: ek, fc, scale, add, gated, reff, ssr, nobs, s_last };
        ok
    }

    #[cold]
    fn accepts(&self, x: &SVector<T, N>, sc: &Self::Scratch) -> bool {
        let rk = super::row::risky::<T>();
        let mut risky = false;
        for k in 0..L {
            let go = sc.go[k] != T::zero();
            if !sc.step[k].finite() || (go && !(sc.s[k] > T::zero() && sc.s[k] <= T::biggest())) {
                return false;
            }
            risky |= go && sc.reff[k] > T::zero() && sc.reff[k] < rk * sc.s[k];
        }
        !risky || self.downdates_stay_definite(x, *sc)
    }

    #[cold]
    fn check(&self, x: &SVector<T, N>, sc: &Self::Scratch) -> crate::Result<()> {
        for k in 0..self.used {
            if sc.go[k] == T::zero() {
                continue;
            }
            // s overflows through the state; a finite s with an infinite step, through the
            // innovation.
            if !sc.s[k].finite() {
                return Err(OVERFLOW);
            }
            if !sc.step[k].finite() {
                return Err(overflow_culprit(sc.e[k], sc.xth[k]));
            }
            if !(sc.s[k] > T::zero()) {
                return Err(Error::Singular {
                    what: "the innovation variance xᵀPx + r (P lost positive definiteness: reset_covariance(p0) restarts the identifier from its \
                           estimate; form='sqrt' cannot lose it)",
                });
            }
        }
        if !self.downdates_stay_definite(x, *sc) {
            return Err(super::row::LOST_DEFINITENESS);
        }
        Ok(())
    }

    fn sqrt_scratch() -> Self::SqrtScratch {
        SqrtScratch { base: Self::scratch(), v: [[T::zero(); L]; N], p: [[T::zero(); L]; N], ratio: [[T::one(); L]; N] }
    }

    #[cold]
    fn check_sqrt(&self, ss: &Self::SqrtScratch) -> crate::Result<()> {
        let sc = &ss.base;
        for k in 0..self.used {
            if !sc.s[k].finite() {
                return Err(OVERFLOW);
            }
            if !sc.step[k].finite() {
                return Err(overflow_culprit(sc.e[k], sc.xth[k]));
            }
        }
        Err(Error::Singular { what: "the innovation variance xᵀPx + r (the square-root factors are not positive)" })
    }

    #[inline(always)]
    fn plan_sqrt(&self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T], ss: &mut Self::SqrtScratch) -> bool {
        let xth = lane_dot(&self.theta, x);
        let ek = self.innovations(z, xth);
        put_lanes(e, ek);
        self.plan_ud(x, xth, ek, ss)
    }

    #[inline(always)]
    fn apply_sqrt(&mut self, ss: &Self::SqrtScratch) {
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        self.record::<GENERAL>(&ss.base);
        self.apply_ud(ss);
    }

    #[inline(always)]
    fn apply<const MODE: u8>(&mut self, x: &SVector<T, N>, sc: &Self::Scratch) {
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        self.record::<MODE>(sc);
        if const { MODE == PLAIN } {
            self.step_theta(sc);
            self.downdate(sc);
            return;
        }
        if const { MODE == FORGET } {
            self.step_theta(sc);
            self.downdate_forget(sc);
            return;
        }
        match self.form {
            CovarianceForm::Standard => {
                self.step_theta(sc);
                if self.tracks() {
                    self.downdate_tracking(sc);
                } else {
                    self.downdate(sc);
                }
            }
            CovarianceForm::Joseph => {
                self.step_theta(sc);
                self.joseph(x, *sc);
            }
            // Planned and applied by `plan_sqrt` / `apply_sqrt`.
            CovarianceForm::Sqrt => {}
        }
    }
}

impl<T: Real, const N: usize, const L: usize> RowLanes<T, N, L> {
    /// `θ += c P x`.
    #[inline(always)]
    fn step_theta(&mut self, sc: &LaneScratch<T, N, L>) {
        for a in 0..N {
            for k in 0..L {
                self.theta[a][k] += sc.px[a][k] * sc.c[k];
            }
        }
    }

    /// The standard form's downdate: `P_ab ← P_ab − (P x)_a (P x)_b / s` on the upper triangle.
    #[inline(always)]
    fn downdate(&mut self, sc: &LaneScratch<T, N, L>) {
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

    /// [`Self::downdate_tracking`] for exponential forgetting alone: `P_ab ← P_ab·scale −
    /// (P x)_a (P x)_b (1/s)·scale` (the same numbers: `c = 0` and no drift to add).
    #[inline(always)]
    fn downdate_forget(&mut self, sc: &LaneScratch<T, N, L>) {
        let mut g = [[T::zero(); L]; N];
        for b in 0..N {
            for k in 0..L {
                g[b][k] = sc.px[b][k] * (sc.w[k] * sc.scale[k]);
            }
        }
        for a in 0..N {
            for b in a..N {
                for k in 0..L {
                    self.p[a][b][k] = self.p[a][b][k] * sc.scale[k] - sc.px[a][k] * g[b][k];
                }
            }
        }
    }

    /// The standard form's downdate with tracking, in one pass over the upper triangle:
    /// `P_ab ← P_ab·scale − (P x)_a (P x)_b (1/s − c)·scale`, then `+ add` on the diagonal
    /// (exponential forgetting `scale = 1/λ`, directional forgetting `c`, drift `add`).
    #[inline(always)]
    fn downdate_tracking(&mut self, sc: &LaneScratch<T, N, L>) {
        let mut g = [[T::zero(); L]; N];
        for b in 0..N {
            for k in 0..L {
                g[b][k] = sc.px[b][k] * ((sc.w[k] - sc.fc[k]) * sc.scale[k]);
            }
        }
        for a in 0..N {
            for b in a..N {
                for k in 0..L {
                    self.p[a][b][k] = self.p[a][b][k] * sc.scale[k] - sc.px[a][k] * g[b][k];
                }
            }
            for k in 0..L {
                self.p[a][a][k] += sc.add[k];
            }
        }
    }
}

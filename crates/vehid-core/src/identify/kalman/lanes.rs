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

use super::sums::{lane_sum, tree_sum};
use super::{CovarianceForm, RowIdentifier};
use crate::Real;
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

mod group;
mod sqrt;
mod standard;

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

/// [`RowGroup::mode`]: the standard form after the start, no tracking, no Huber weighting,
/// no lane with `r = 0`; the outlier gate tested in the plan (a sample beyond it goes to the
/// general mode).
pub const PLAIN: u8 = 1;
/// [`RowGroup::mode`]: as [`PLAIN`] with exponential forgetting (no drift, not directional).
pub const FORGET: u8 = 2;
/// [`RowGroup::mode`]: anything else (the other forms, the exact start, Huber weighting,
/// forgetting under the outlier gate, lanes with `r = 0`, drift and directional forgetting). Each special mode is one more
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
            let floor = super::guards::collapse_floor::<T, N>(ax, tree_sum(ap));
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

    /// The outlier screen of every lane ([`super::guards::screen`]): the gated flags (1/0) and
    /// the variance each lane uses.
    #[inline(never)]
    fn screen_lanes(&self, e: [T; L], s: [T; L]) -> ([T; L], [T; L]) {
        let mut gated = [T::zero(); L];
        let mut reff = self.r;
        for k in 0..L {
            match super::guards::screen(self.gate, self.huber, self.nobs[k], self.ssr[k], self.r[k], e[k], s[k], N) {
                Some(r) => reff[k] = r,
                None => gated[k] = T::one(),
            }
        }
        (gated, reff)
    }

    /// The lanes whose sample the outlier gate leaves out: [`super::guards::screen`]'s test
    /// without the Huber weighting (the plain mode has none), as whole-lane arithmetic. The
    /// same operations on the same values as the screen, so that a sample the plain mode takes
    /// is one the general mode would take.
    #[inline(always)]
    fn beyond_gate(&self, e: [T; L], s: [T; L]) -> [bool; L] {
        let warm = T::of(N as f64 + super::guards::SCREEN_WARMUP);
        let gate2 = self.gate * self.gate;
        let mut out = [false; L];
        for k in 0..L {
            let sigma2 = self.ssr[k] / (self.nobs[k] - T::of(N as f64));
            let z2 = e[k] * e[k] * self.r[k] / s[k] / sigma2;
            out[k] = (self.nobs[k] >= warm) & (sigma2 > T::zero()) & !(z2 <= gate2);
        }
        out
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
            // the gate (guards::gated_scale): a lasting change opens the gate within tens of
            // samples.
            for k in 0..L {
                let gated = sc.gated[k] != T::zero();
                self.gated[k] += u64::from(gated);
                if gated {
                    (self.ssr[k], self.nobs[k]) =
                        super::guards::gated_scale(self.gate, self.lambda, self.ssr[k], self.nobs[k], N);
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

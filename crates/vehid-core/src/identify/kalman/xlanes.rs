//! Row filters side by side ("lanes", as in [`super::KalmanRows`]) that each have their own
//! regressor: the plain step of the independent groups of a structure
//! ([`crate::identify::Structured`] with one equation per group).
//!
//! Lane `k` is one [`RowIdentifier`] in its plain step (the standard form after the start, no
//! tracking, no outlier screen, `r > 0`: [`RowIdentifier::plain`]) for the scalar regression
//! `y_k = x_kᵀθ_k + ε_k`, `ε_k ~ (0, r_k)` (Eq 6.16–6.18): `e = y − xᵀθ`, `s = xᵀPx + r`,
//! `θ ← θ + P x e/s`, `P ← P − P x xᵀP / s`. Entry `(a, b)` of all `L` covariances is one
//! `[T; L]`, and entry `a` of all regressors too, so every step is one operation on all lanes
//! at once, with the arithmetic of the rows identifier's lanes (the upper triangle of `P`,
//! every sum pairwise in the same fixed order, no fused multiply-add): a lane steps bit for
//! bit as a row of [`super::KalmanRows`] on the same regressor, and as
//! [`RowIdentifier::update`] to rounding (which sums in another order).
//!
//! A group with fewer parameters than `N` uses the leading entries: its regressor and its `θ`
//! and `P` are 0 beyond them ([`RowIdentifier::restricted`]), so `P x` is 0 there and those
//! entries never move. A lane that holds no filter (padding) has `x = 0`, `y = 0`, `P = 0`,
//! `r = 1`: `e = 0`, `s = 1`, no step and no failure.

use super::sums::{is_fin, lane_sum};
use super::RowIdentifier;
use crate::Real;

/// `L` plain row filters with a regressor each (see the module docs). Besides each filter's
/// statistics (`Σ w²`, samples, last `s`) a lane carries its equation's (`eq_ssr`, `eq_nobs`:
/// what [`crate::identify::Structured`] reports per equation).
///
/// Aligned to 16 bytes, so that a lane vector of two `f64` never straddles a cache line
/// (with the default alignment of 8 the split depended on where the identifier was placed,
/// and the update ran either about 35 or 50 ns, run to run).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(align(16))]
pub(crate) struct XLanes<T: Real, const N: usize, const L: usize> {
    /// `theta[a][k]`: coefficient `a` of lane `k`.
    theta: [[T; L]; N],
    /// `p[a][b][k]` for `a ≤ b`: the upper triangle of lane `k`'s `P` (the rest unused).
    p: [[[T; L]; N]; N],
    r: [T; L],
    ssr: [T; L],
    nobs: [T; L],
    s: [T; L],
    eq_ssr: [T; L],
    eq_nobs: [T; L],
}

/// One sample's planned step of [`XLanes`] (computed by [`XLanes::plan`], applied by
/// [`XLanes::apply`]; nothing changes in between).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct XPlan<T: Real, const N: usize, const L: usize> {
    /// `P x` per lane.
    px: [[T; L]; N],
    /// `c = e / s` and `w = 1 / s`.
    c: [T; L],
    w: [T; L],
    /// The innovations `e = y − xᵀθ`.
    pub(crate) e: [T; L],
    /// The statistics after the step: the filter's `Σ w²`, samples and `s`, the equation's
    /// `Σ w²` and samples.
    ssr: [T; L],
    nobs: [T; L],
    s: [T; L],
    eq_ssr: [T; L],
    eq_nobs: [T; L],
}

impl<T: Real, const N: usize, const L: usize> XPlan<T, N, L> {
    /// An empty plan (to be written by [`XLanes::plan`]).
    #[inline(always)]
    pub(crate) fn empty() -> Self {
        let z = [T::zero(); L];
        Self { px: [z; N], c: z, w: z, e: z, ssr: z, nobs: z, s: z, eq_ssr: z, eq_nobs: z }
    }
}

/// `Σ_b v[b] x[b]` lane by lane (each lane its own `x`), summed pairwise in the fixed order of
/// [`lane_sum`] (that of [`super::sums::lane_dot`]).
#[inline(always)]
fn lane_dot_x<T: Real, const L: usize, const N: usize>(v: &[[T; L]; N], x: &[[T; L]; N]) -> [T; L] {
    let mut t = [[T::zero(); L]; N];
    for b in 0..N {
        for k in 0..L {
            t[b][k] = v[b][k] * x[b][k];
        }
    }
    lane_sum(t)
}

impl<T: Real, const N: usize, const L: usize> XLanes<T, N, L> {
    /// Every lane padding.
    pub(crate) fn padding() -> Self {
        let z = [T::zero(); L];
        Self { theta: [z; N], p: [[z; N]; N], r: [T::one(); L], ssr: z, nobs: z, s: z, eq_ssr: z, eq_nobs: z }
    }

    /// Puts `f` (which must be [`RowIdentifier::plain`]) into lane `k`, with its equation's
    /// statistics `(Σ w², samples)`.
    pub(crate) fn set_lane(&mut self, k: usize, f: &RowIdentifier<T, N>, eq: (T, T)) {
        for a in 0..N {
            self.theta[a][k] = f.theta[a];
            for b in a..N {
                self.p[a][b][k] = f.m[(a, b)];
            }
        }
        (self.r[k], self.ssr[k], self.nobs[k], self.s[k]) = (f.r, f.ssr, f.nobs, f.s);
        (self.eq_ssr[k], self.eq_nobs[k]) = eq;
    }

    /// Lane `k` written back into `f` (the filter it was set from: the settings are kept, the
    /// estimate, covariance (mirrored) and statistics replaced), and its equation's
    /// statistics.
    pub(crate) fn lane_into(&self, k: usize, f: &mut RowIdentifier<T, N>) -> (T, T) {
        for a in 0..N {
            f.theta[a] = self.theta[a][k];
            for b in a..N {
                f.m[(a, b)] = self.p[a][b][k];
                f.m[(b, a)] = self.p[a][b][k];
            }
        }
        (f.ssr, f.nobs, f.s) = (self.ssr[k], self.nobs[k], self.s[k]);
        (self.eq_ssr[k], self.eq_nobs[k])
    }

    /// Lane `k`'s equation statistics `(Σ w², samples)`.
    pub(crate) fn equation(&self, k: usize) -> (T, T) {
        (self.eq_ssr[k], self.eq_nobs[k])
    }

    /// Plans one sample (regressors `x[a][k]`, left-hand sides `y[k]`; lanes that hold no
    /// filter must have both 0) into `pl`. `false` when some lane must take the general
    /// update: `s` not in `(0, max]`, a step that is not finite (non-finite input included),
    /// or `r/s` below `√ε` (a risky downdate to check). Changes nothing else. (Everything is
    /// computed into locals and `pl` written once at the end, so that it can stay in
    /// registers.)
    #[inline(always)]
    pub(crate) fn plan(&self, x: &[[T; L]; N], y: [T; L], pl: &mut XPlan<T, N, L>) -> bool {
        let xth = lane_dot_x(&self.theta, x);
        let mut e = [T::zero(); L];
        for k in 0..L {
            e[k] = y[k] - xth[k];
        }
        let mut px = [[T::zero(); L]; N];
        for a in 0..N {
            let mut col = [[T::zero(); L]; N];
            for b in 0..N {
                col[b] = if a <= b { self.p[a][b] } else { self.p[b][a] };
            }
            px[a] = lane_dot_x(&col, x);
        }
        let mut s = lane_dot_x(&px, x);
        for k in 0..L {
            s[k] += self.r[k];
        }
        let rk = super::guards::risky::<T>();
        let (mut w, mut c, mut flag) = ([T::zero(); L], [T::zero(); L], [T::zero(); L]);
        for k in 0..L {
            let inv = T::one() / s[k];
            let fine = (s[k] > T::zero()) & (s[k] <= T::biggest());
            let risky = self.r[k] < rk * s[k];
            flag[k] = if risky | !fine { T::of(f64::NAN) } else { T::zero() };
            w[k] = inv;
            c[k] = e[k] * inv;
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
        // The statistics as the row filter keeps them (λ = 1), and the equation's as
        // `Structured` accumulates them (the change of the filter's Σ w², weight 1).
        let (mut ssr, mut nobs, mut eq_ssr, mut eq_nobs) =
            ([T::zero(); L], [T::zero(); L], [T::zero(); L], [T::zero(); L]);
        for k in 0..L {
            ssr[k] = self.ssr[k] + e[k] * c[k] * self.r[k];
            nobs[k] = self.nobs[k] + T::one();
            eq_ssr[k] = self.eq_ssr[k] + (ssr[k] - self.ssr[k]);
            eq_nobs[k] = self.eq_nobs[k] + T::one();
        }
        *pl = XPlan { px, c, w, e, ssr, nobs, s, eq_ssr, eq_nobs };
        ok
    }

    /// Applies a step planned by [`XLanes::plan`] (which returned `true`): `θ += c P x`,
    /// `P_ab −= (P x)_a (P x)_b / s` on the upper triangle, the statistics.
    #[inline(always)]
    pub(crate) fn apply(&mut self, pl: &XPlan<T, N, L>) {
        for a in 0..N {
            for k in 0..L {
                self.theta[a][k] += pl.px[a][k] * pl.c[k];
            }
        }
        let mut g = [[T::zero(); L]; N];
        for b in 0..N {
            for k in 0..L {
                g[b][k] = pl.px[b][k] * pl.w[k];
            }
        }
        for a in 0..N {
            for b in a..N {
                for k in 0..L {
                    self.p[a][b][k] -= pl.px[a][k] * g[b][k];
                }
            }
        }
        (self.ssr, self.nobs, self.s) = (pl.ssr, pl.nobs, pl.s);
        (self.eq_ssr, self.eq_nobs) = (pl.eq_ssr, pl.eq_nobs);
    }
}

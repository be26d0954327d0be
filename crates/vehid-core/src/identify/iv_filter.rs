//! One recursive instrumental-variable filter for one group of parameters: the engine of
//! [`super::InstrumentalVariables`].
//!
//! For scalar equations `y = hᵀθ + ε` whose regressor `h` is correlated with `ε` (noise on the
//! measured state enters both), an instrument `ζ` correlated with `h` but not with `ε` gives
//! the consistent estimate `θ̂ = (Σ ζ hᵀ)⁻¹ Σ ζ y` (Söderström & Stoica, *System
//! Identification*, 1989, §8.1, Eq 8.12). Its recursive form (§8.3, Eq 8.29; Ljung, *System
//! Identification*, 2nd ed., 1999, §11.2, Eq 11.44) is Sherman–Morrison applied to the
//! non-symmetric `Σ ζ hᵀ`:
//!
//! ```text
//! s = r + hᵀ P ζ                       (a scalar; not positive in general)
//! θ ← θ + P ζ (y − hᵀθ) / s
//! P ← P − P ζ hᵀ P / s                  P = r (Σ ζ hᵀ)⁻¹ after an exact start
//! ```
//!
//! Unlike recursive least squares (`ζ = h`, `s ≥ r > 0`), `s` can vanish: the step then
//! divides by (nearly) zero, and the filter refuses the sample with [`Error::Singular`]. `P`
//! is not a covariance: the estimate's covariance is the sandwich
//! `σ² (Σ ζ hᵀ)⁻¹ (Σ ζ ζᵀ) (Σ h ζᵀ)⁻¹` (Söderström & Stoica Eq 8.26, white `ε`), for which the
//! filter also accumulates `M = Σ ζ ζᵀ`.
//!
//! The exact start accumulates `Σ ζ hᵀ` and `Σ ζ y` until the former is well conditioned
//! (after equilibration by `diag(M)^{-1/2}`, every LU pivot above `√ε · d` of the largest),
//! then sets `P = r (Σ ζ hᵀ)⁻¹`, `θ̂ = (Σ ζ hᵀ)⁻¹ Σ ζ y`: from then on every estimate is the
//! batch IV estimate on all samples so far (up to rounding), with no prior at all.

use crate::identify::OVERFLOW;
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

/// The error of a step whose instrument correlation `s = r + hᵀPζ` (nearly) vanishes.
pub(crate) const SINGULAR: Error = Error::Singular {
    what: "the instrument correlation s = r + hᵀPζ of the instruments ζ = h(k − delay) (the regressors \
           `delay` samples earlier) with this sample's regressors h (this sample would divide by ~0; the \
           identifier is unchanged: excite the system, or choose a delay over which the states stay correlated)",
};

/// One group's recursive IV filter (module docs).
///
/// With the feature `serde` it is serialized field by field; a deserialized filter is checked
/// (its size, weight, finiteness and unused entries), so a corrupt one is a serde error.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct IvFilter<T: Real, const P: usize> {
    /// `θ̂`; during the exact start `Σ ζ y`.
    theta: SVector<T, P>,
    /// `P = r (Σ ζ hᵀ + r P₀⁻¹)⁻¹`; during the exact start `Σ ζ hᵀ`.
    p: SMatrix<T, P, P>,
    /// `Σ ζ ζᵀ`.
    m: SMatrix<T, P, P>,
    r: T,
    start: bool,
    /// Parameters in use (the leading `dim ≤ P`; the rest stays 0).
    dim: u8,
    /// Samples absorbed.
    count: u64,
}

impl<T: Real, const P: usize> IvFilter<T, P> {
    /// Checks a deserialized filter (feature `serde`): `1 ≤ dim ≤ P`; the weight `r` finite
    /// and `> 0` during the exact start (which divides by nothing but later multiplies
    /// `(Σ ζ hᵀ)⁻¹` by it), `≥ 0` after; `θ̂`, `P` and `M` finite and 0 outside the leading
    /// `dim` entries (which the update never touches); `M`'s diagonal (sums of squares) ≥ 0.
    /// Each failure names what is wrong (`Error::InvalidArgument` with `arg` "state").
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let corrupt = |expected| Err(Error::InvalidArgument { arg: "state", expected });
        let d = self.dim as usize;
        if d == 0 || d > P {
            return corrupt("an IV filter of 1 to P parameters (dim)");
        }
        let r_ok = if self.start { self.r > T::zero() } else { self.r >= T::zero() };
        if !(self.r.finite() && r_ok) {
            return corrupt("an IV filter weight r finite and > 0 (≥ 0 after the exact start)");
        }
        let values = self.theta.iter().chain(self.p.iter()).chain(self.m.iter());
        if !values.into_iter().all(|v| v.finite()) {
            return corrupt("an IV filter's θ, P and M finite");
        }
        let outside = (0..P).any(|a| {
            (a >= d && self.theta[a] != T::zero())
                || (0..P).any(|b| (a >= d || b >= d) && (self.p[(a, b)] != T::zero() || self.m[(a, b)] != T::zero()))
        });
        if outside {
            return corrupt("an IV filter's θ, P and M zero beyond its dim parameters");
        }
        if (0..d).any(|a| self.m[(a, a)] < T::zero()) {
            return corrupt("an IV filter's instrument moment M = Σ ζ ζᵀ with a diagonal ≥ 0");
        }
        Ok(())
    }

    /// A filter of `dim` parameters with the exact start (weight `r > 0`).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `dim` outside `1..=P` or `r` not finite and > 0.
    pub fn exact(dim: usize, r: T) -> Result<Self> {
        check_dim::<P>(dim)?;
        crate::error::check_positive("r", r)?;
        Ok(Self {
            theta: SVector::zeros(),
            p: SMatrix::zeros(),
            m: SMatrix::zeros(),
            r,
            start: true,
            dim: dim as u8,
            count: 0,
        })
    }

    /// A filter of `dim` parameters with prior mean `theta0` and `P(0) = p0` (only the leading
    /// `dim × dim` block is used) and equation variance `r ≥ 0`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `dim` outside `1..=P`, `r` negative or not finite;
    /// [`Error::NonFinite`] naming `p0` or `theta0`.
    pub fn with_prior(dim: usize, theta0: SVector<T, P>, p0: SMatrix<T, P, P>, r: T) -> Result<Self> {
        check_dim::<P>(dim)?;
        crate::error::check_nonneg("r", r)?;
        crate::error::check_finite("p0", p0.as_slice())?;
        crate::error::check_finite("theta0", theta0.as_slice())?;
        let mut f = Self { theta: theta0, p: p0, m: SMatrix::zeros(), r, start: false, dim: dim as u8, count: 0 };
        f.clear_unused();
        Ok(f)
    }

    fn clear_unused(&mut self) {
        let d = self.dim as usize;
        for a in 0..P {
            for b in 0..P {
                if a >= d || b >= d {
                    self.p[(a, b)] = T::zero();
                    self.m[(a, b)] = T::zero();
                }
            }
            if a >= d {
                self.theta[a] = T::zero();
            }
        }
    }

    /// One equation's sample: regressor `h`, instrument `zeta`, output `y`. Returns the
    /// innovation `y − hᵀθ̂` (before the update) and, once filtering, the a-posteriori residual
    /// `y − hᵀθ̂⁺ = e r / s`. Transactional: on an error nothing changed.
    ///
    /// # Errors
    /// [`Error::Singular`] when `|s| ≤ √ε (r + Σ|h_a (Pζ)_a|)`; the overflow error when the
    /// step would not be finite.
    #[inline]
    pub fn update(&mut self, h: &SVector<T, P>, zeta: &SVector<T, P>, y: T) -> Result<(T, Option<T>)> {
        if self.start {
            return self.absorb(h, zeta, y).map(|e| (e, None));
        }
        let g = self.gain(h, zeta)?;
        let e = y - dot(h, &self.theta);
        let theta = step(&self.theta, &g.k, e);
        let mut check = [T::zero(); P];
        for v in [&g.p, &g.m] {
            zero_sum(v, &mut check);
        }
        zero_sum(&theta, &mut check);
        if !check.iter().all(|&v| v == T::zero()) {
            return Err(OVERFLOW);
        }
        (self.theta, self.p, self.m) = (theta, g.p, g.m);
        self.count += 1;
        Ok((e, Some(e * (self.r / g.s))))
    }

    /// The gain side of a step (the same for every filter with this `P`, `M` and `r`):
    /// `s = r + hᵀPζ` (refused when it nearly vanishes), `K = Pζ/s`, `P − K (Pᵀh)ᵀ` and
    /// `M + ζζᵀ`, written out over the column arrays (`P` is a compile-time size: unrolled
    /// and vectorized, and the same operations in [`IvFilter::update`] and
    /// [`IvFilter::update_shared`], so both give the same bits).
    #[inline(always)]
    fn gain(&self, h: &SVector<T, P>, zeta: &SVector<T, P>) -> Result<Gain<T, P>> {
        let (pc, hv, zv) = (&self.p.data.0, &h.data.0[0], &zeta.data.0[0]);
        // Every sum pairwise (even and odd terms apart, `sum2`): half the dependent additions
        // on the step's critical path (P → Pζ → s → K → P).
        let mut pz = [T::zero(); P];
        let mut hp = [T::zero(); P];
        for a in 0..P {
            pz[a] = sum2::<T, P>(|b| pc[b][a] * zv[b]);
        }
        for (b, hb) in hp.iter_mut().enumerate() {
            *hb = sum2::<T, P>(|a| hv[a] * pc[b][a]);
        }
        let s = self.r + sum2::<T, P>(|a| hv[a] * pz[a]);
        let scale = self.r + sum2::<T, P>(|a| (hv[a] * pz[a]).abs());
        if !(s.abs() > T::default_epsilon().sqrt() * scale) {
            return Err(if s.finite() && scale.finite() { SINGULAR } else { OVERFLOW });
        }
        let mut k = SVector::<T, P>::zeros();
        for a in 0..P {
            k[a] = pz[a] / s;
        }
        let (mut p, mut m) = (self.p, self.m);
        let (pn, mn, kv) = (&mut p.data.0, &mut m.data.0, &k.data.0[0]);
        for b in 0..P {
            for a in 0..P {
                pn[b][a] -= kv[a] * hp[b];
            }
        }
        // `M_·b += ζ ζ_b`, column by column: the same products, but seen as `ζ_a ζ_b` and
        // `ζ_b ζ_a` the compiler computes each pair once and rebuilds the columns from
        // scalar and half-register pieces (some 40 more instructions per sample, and `M`
        // stored in pieces). Reading `ζ_b` from an opaque copy keeps whole columns.
        let zc = core::hint::black_box(*zv);
        for b in 0..P {
            for a in 0..P {
                mn[b][a] += zv[a] * zc[b];
            }
        }
        Ok(Gain { k, s, p, m })
    }

    /// `true` when `other` has the same `P`, `M`, weight `r`, size, start state and sample
    /// count (everything but `θ̂`): two such filters fed the same `h` and `ζ` stay so, and
    /// [`IvFilter::update_shared`] may update them together.
    pub(crate) fn shares_gain_with(&self, other: &Self) -> bool {
        self.p == other.p
            && self.m == other.m
            && self.r == other.r
            && self.start == other.start
            && self.dim == other.dim
            && self.count == other.count
    }

    /// One sample for filters that share their gain ([`IvFilter::shares_gain_with`], none
    /// starting) and see the same regressor `h` and instrument `ζ`, one output each: `ye[g]`
    /// is filter `g`'s `y` on entry and its innovation `y − hᵀθ̂_g` on return. `P ζ`, `s`,
    /// the gain and the `P` and `M` updates are computed once; each filter adds its own
    /// `θ̂_g ← θ̂_g + P ζ e_g / s`. The arithmetic is [`IvFilter::update`]'s, operation for
    /// operation, so every filter ends bit for bit as there. Returns `s` (each a-posteriori
    /// residual is `e_g r / s`). Transactional: on an error no filter changed (`ye` is then
    /// meaningless).
    ///
    /// # Errors
    /// As [`IvFilter::update`].
    #[inline]
    pub(crate) fn update_shared(
        filters: &mut [Self],
        h: &SVector<T, P>,
        zeta: &SVector<T, P>,
        ye: &mut [T],
    ) -> Result<T> {
        // Four or more f64 parameters fill 256-bit registers: the AVX2 copy when the CPU has
        // it (no FMA, the same operations: the same bits, see `simd.rs`).
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        if const { P >= 4 && core::mem::size_of::<T>() == 8 } && crate::simd::avx2() {
            // SAFETY: the CPU supports AVX2 (checked at run time by `simd::avx2`).
            return unsafe { Self::shared_avx2(filters, h, zeta, ye) };
        }
        Self::shared(filters, h, zeta, ye)
    }

    /// [`IvFilter::shared`] compiled for AVX2 (same arithmetic, wider registers).
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    fn shared_avx2(filters: &mut [Self], h: &SVector<T, P>, zeta: &SVector<T, P>, ye: &mut [T]) -> Result<T> {
        Self::shared(filters, h, zeta, ye)
    }

    /// The body of [`IvFilter::update_shared`] (no dispatch: for callers already compiled
    /// for the wider registers).
    #[inline(always)]
    pub(crate) fn shared(filters: &mut [Self], h: &SVector<T, P>, zeta: &SVector<T, P>, ye: &mut [T]) -> Result<T> {
        let Some(f0) = filters.first() else { return Ok(T::one()) };
        debug_assert!(!f0.start && filters.iter().all(|f| f.shares_gain_with(f0)));
        let g = f0.gain(h, zeta)?;
        let mut check = [T::zero(); P];
        for v in [&g.p, &g.m] {
            zero_sum(v, &mut check);
        }
        for (f, v) in filters.iter().zip(ye.iter_mut()) {
            let e = *v - dot(h, &f.theta);
            zero_sum(&step(&f.theta, &g.k, e), &mut check);
            *v = e;
        }
        if !check.iter().all(|&v| v == T::zero()) {
            return Err(OVERFLOW);
        }
        for (f, &e) in filters.iter_mut().zip(ye.iter()) {
            f.theta = step(&f.theta, &g.k, e);
            (f.p, f.m) = (g.p, g.m);
            f.count += 1;
        }
        let s = g.s;
        Ok(s)
    }

    /// The exact start: accumulate, and end the start when `Σ ζ hᵀ` is well conditioned.
    fn absorb(&mut self, h: &SVector<T, P>, zeta: &SVector<T, P>, y: T) -> Result<T> {
        let mut c = self.p;
        c.ger(T::one(), zeta, h, T::one());
        let b = self.theta + zeta * y;
        let mut m = self.m;
        m.ger(T::one(), zeta, zeta, T::one());
        if !(c.iter().all(|v| v.finite()) && b.iter().all(|v| v.finite()) && m.iter().all(|v| v.finite())) {
            return Err(OVERFLOW);
        }
        (self.p, self.theta, self.m) = (c, b, m);
        self.count += 1;
        if self.count >= u64::from(self.dim) {
            self.try_start();
        }
        Ok(y)
    }

    /// Ends the exact start when the accumulated correlation is well conditioned.
    fn try_start(&mut self) {
        let d = self.dim as usize;
        // Equilibrate by diag(M)^{-1/2} (the instruments' scales; the regressors' are the same
        // signals delayed), so the pivot test does not depend on the units.
        let mut w = SVector::<T, P>::repeat(T::one());
        for a in 0..d {
            let v = self.m[(a, a)];
            if !(v > T::zero()) {
                return;
            }
            w[a] = T::one() / v.sqrt();
        }
        let mut c = self.p;
        for a in 0..d {
            for b in 0..d {
                c[(a, b)] *= w[a] * w[b];
            }
        }
        let Some(inv) = invert(&c, d) else { return };
        // (D C D)⁻¹ = D⁻¹ C⁻¹ D⁻¹, so C⁻¹ = D (D C D)⁻¹ D.
        let mut cinv = SMatrix::<T, P, P>::zeros();
        for a in 0..d {
            for b in 0..d {
                cinv[(a, b)] = inv[(a, b)] * w[a] * w[b];
            }
        }
        let theta = cinv * self.theta;
        let p = cinv * self.r;
        if theta.iter().all(|v| v.finite()) && p.iter().all(|v| v.finite()) {
            (self.theta, self.p, self.start) = (theta, p, false);
        }
    }

    /// `true` while the exact start is absorbing samples (no estimate yet).
    pub fn starting(&self) -> bool {
        self.start
    }

    /// The estimate `θ̂` (the leading `dim` entries are the group's parameters). Meaningless
    /// while [`IvFilter::starting`].
    pub fn theta(&self) -> &SVector<T, P> {
        &self.theta
    }

    /// `P = r (Σ ζ hᵀ)⁻¹` (not symmetric, not a covariance). Meaningless while starting.
    pub fn p(&self) -> &SMatrix<T, P, P> {
        &self.p
    }

    /// `M = Σ ζ ζᵀ` of the samples absorbed.
    pub fn instrument_moment(&self) -> &SMatrix<T, P, P> {
        &self.m
    }

    /// The covariance of `θ̂` per unit `σ²/r` (so that `σ²/r` times it is the sandwich
    /// `σ² (Σζhᵀ)⁻¹ (Σζζᵀ) (Σhζᵀ)⁻¹`): `P M Pᵀ / r`; the leading `dim × dim` block.
    pub fn covariance(&self) -> SMatrix<T, P, P> {
        (self.p * self.m * self.p.transpose()) / self.r
    }

    /// The equation weight `r`.
    pub fn r(&self) -> T {
        self.r
    }

    /// Parameters in use.
    pub fn dim(&self) -> usize {
        self.dim as usize
    }

    /// Samples absorbed.
    pub fn count(&self) -> u64 {
        self.count
    }
}

/// The inverse of the leading `d × d` block of `c` (Gauss–Jordan with partial pivoting; the
/// rest 0), or `None` when a pivot falls below `√ε · d` times the largest entry: the block is
/// then numerically singular (its entries are equilibrated to unit diagonal scale).
pub(crate) fn invert<T: Real, const P: usize>(c: &SMatrix<T, P, P>, d: usize) -> Option<SMatrix<T, P, P>> {
    let mut a = *c;
    let mut inv = SMatrix::<T, P, P>::zeros();
    for i in 0..d {
        inv[(i, i)] = T::one();
    }
    let big = (0..d).flat_map(|i| (0..d).map(move |j| (i, j))).fold(T::zero(), |m, ij| m.max(c[ij].abs()));
    let tol = T::default_epsilon().sqrt() * T::of(d as f64) * big;
    for col in 0..d {
        let (piv, val) =
            (col..d).map(|r| (r, a[(r, col)].abs())).fold((col, -T::one()), |b, x| if x.1 > b.1 { x } else { b });
        if !(val > tol) {
            return None;
        }
        a.swap_rows(col, piv);
        inv.swap_rows(col, piv);
        let p = a[(col, col)];
        for j in 0..d {
            a[(col, j)] /= p;
            inv[(col, j)] /= p;
        }
        for r in (0..d).filter(|&r| r != col) {
            let f = a[(r, col)];
            if f != T::zero() {
                for j in 0..d {
                    let (x, y) = (a[(col, j)], inv[(col, j)]);
                    a[(r, j)] -= f * x;
                    inv[(r, j)] -= f * y;
                }
            }
        }
    }
    Some(inv)
}

/// The gain side of one step ([`IvFilter::gain`]).
#[derive(Clone, Copy)]
struct Gain<T: Real, const P: usize> {
    k: SVector<T, P>,
    s: T,
    p: SMatrix<T, P, P>,
    m: SMatrix<T, P, P>,
}

/// Adds `0 · v` of every entry `v` of `a`, row by row, to `acc`: each sum stays 0 while the
/// entries are finite and becomes NaN once one is not (`0 · ∞` and `0 · NaN` are NaN), so one
/// test of `acc` at the end checks several matrices (vector operations, no early exit; a sum
/// of zeros cannot overflow).
#[inline(always)]
fn zero_sum<T: Real, const R: usize, const C: usize>(a: &SMatrix<T, R, C>, acc: &mut [T; R]) {
    for c in &a.data.0 {
        for (s, &v) in acc.iter_mut().zip(c) {
            *s += v * T::zero();
        }
    }
}

/// `Σ_{a < P} f(a)` as (even terms) + (odd terms), each in order: the fixed summation order
/// of every sum in the step.
#[inline(always)]
fn sum2<T: Real, const P: usize>(f: impl Fn(usize) -> T) -> T {
    let mut even = f(0);
    let mut odd = if P > 1 { f(1) } else { T::zero() };
    for a in 2..P {
        if a % 2 == 0 {
            even += f(a);
        } else {
            odd += f(a);
        }
    }
    even + odd
}

/// `hᵀθ` ([`sum2`]).
#[inline(always)]
fn dot<T: Real, const P: usize>(h: &SVector<T, P>, theta: &SVector<T, P>) -> T {
    let (h, theta) = (&h.data.0[0], &theta.data.0[0]);
    sum2::<T, P>(|a| h[a] * theta[a])
}

/// `θ + K e`.
#[inline(always)]
fn step<T: Real, const P: usize>(theta: &SVector<T, P>, k: &SVector<T, P>, e: T) -> SVector<T, P> {
    let mut out = *theta;
    for (o, &kv) in out.data.0[0].iter_mut().zip(&k.data.0[0]) {
        *o += kv * e;
    }
    out
}

fn check_dim<const P: usize>(dim: usize) -> Result<()> {
    if dim == 0 || dim > P {
        return Err(Error::Capacity { arg: "P", needed: dim, capacity: P });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// After the exact start every estimate is batch IV on all samples so far.
    #[test]
    fn exact_start_then_recursion_is_batch_iv() {
        let mut f = IvFilter::<f64, 3>::exact(2, 0.7).unwrap();
        let (mut c, mut b) = (nalgebra::Matrix2::<f64>::zeros(), nalgebra::Vector2::<f64>::zeros());
        let mut state = 0.3f64;
        let mut prev = [1.0, 0.5];
        for k in 0..60 {
            state = (state * 3.7 + 0.11).fract();
            let h = [state - 0.5, (k as f64 * 0.37).sin()];
            let y = 2.0 * h[0] - 1.0 * h[1] + 0.1 * (state - 0.5);
            let zeta = prev;
            f.update(&SVector::from([h[0], h[1], 0.0]), &SVector::from([zeta[0], zeta[1], 0.0]), y).unwrap();
            assert_eq!(f.count(), k as u64 + 1, "every sample absorbed is counted");
            c += nalgebra::Vector2::from(zeta) * nalgebra::Vector2::from(h).transpose();
            b += nalgebra::Vector2::from(zeta) * y;
            prev = h;
            if !f.starting() {
                let want = c.lu().solve(&b).unwrap();
                for a in 0..2 {
                    assert!((f.theta()[a] - want[a]).abs() < 1e-9 * want[a].abs().max(1.0), "k {k}");
                }
                assert_eq!(f.theta()[2], 0.0);
            }
        }
        assert!(!f.starting());
    }

    #[test]
    fn a_vanishing_correlation_is_refused_and_changes_nothing() {
        let p0 = SMatrix::<f64, 1, 1>::from_element(2.0);
        let mut f = IvFilter::<f64, 1>::with_prior(1, SVector::zeros(), p0, 1.0).unwrap();
        let before = f;
        // s = r + h p ζ = 1 + 1·2·(−0.5) = 0.
        let err = f.update(&SVector::from([1.0]), &SVector::from([-0.5]), 3.0).unwrap_err();
        assert_eq!(err, SINGULAR);
        assert_eq!(f, before);
        assert!(f.update(&SVector::from([1.0]), &SVector::from([f64::MAX]), f64::MAX).is_err());
        assert_eq!(f, before);
    }
}

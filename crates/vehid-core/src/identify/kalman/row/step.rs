//! The measurement update of [`RowIdentifier`] after its start: the standard and Joseph
//! forms on `P`, Bierman's on `U D Uᵀ`, the tracking (forgetting, drift), the outlier screen
//! and the residual statistics.

use super::super::guards::{collapse_floor, gated_scale, positive_definite, risky, screen, LOST_DEFINITENESS};
use super::super::ud::ud_rank_one;
use super::super::CovarianceForm;
#[cfg(doc)]
use super::super::KalmanOptions;
use super::RowIdentifier;
use crate::identify::OVERFLOW;
use crate::linalg::{mat_vec, symmetrize};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

impl<T: Real, const N: usize> RowIdentifier<T, N> {
    /// The directional forgetting term of an update with innovation variance `s`: the
    /// covariance after the update is inflated along `x` only,
    /// `P⁺ + ((1 − λ)/λ) P⁺x xᵀP⁺ / xᵀP⁺x` (Kulhavý & Kárný 1984), which with
    /// `P⁺x = P x r/s` is `c (P x)(P x)ᵀ`, `c = ((1 − λ)/λ) r / (s (s − r))`. A sample that
    /// carries no information (`x = 0`, `s = r`) forgets nothing: no wind-up without
    /// excitation. 0 when forgetting is off.
    pub(super) fn forget_coefficient(&self, s: T, r: T, track: bool) -> T {
        let xpx = s - r;
        if !track || !self.directional || self.lambda >= T::one() || !(xpx > T::zero()) {
            return T::zero();
        }
        (T::one() - self.lambda) / self.lambda * r / (s * xpx)
    }

    /// Exponential forgetting `P ← P / λ` (`D ← D / λ` in the square-root form).
    pub(super) fn forget_exponentially(&mut self) {
        let inv = T::one() / self.lambda;
        match self.form {
            CovarianceForm::Sqrt => {
                for j in 0..N {
                    self.m[(j, j)] *= inv;
                }
            }
            _ => self.m *= inv,
        }
    }

    /// Random-walk drift `P ← P + q I`.
    pub(super) fn add_drift(&mut self) {
        match self.form {
            CovarianceForm::Sqrt => {
                for i in 0..self.dim() {
                    let mut a = SVector::<T, N>::zeros();
                    a[i] = T::one();
                    ud_rank_one(&mut self.m, self.drift, a);
                }
            }
            _ => {
                for j in 0..self.dim() {
                    self.m[(j, j)] += self.drift;
                }
            }
        }
    }

    /// The covariance form's measurement update (standard or Joseph).
    pub(super) fn step_p(&mut self, x: &SVector<T, N>, e: T, track: bool) -> Result<()> {
        let mut px = SVector::zeros();
        mat_vec(&self.m, x, &mut px);
        let s = x.dot(&px) + self.r;
        if !s.finite() {
            return Err(OVERFLOW);
        }
        if self.r == T::zero() {
            // Noise-free data and a covariance collapsed along x (xᵀPx at rounding level):
            // nothing is left to learn in that direction.
            let floor = collapse_floor::<T, N>(x.abs().sum(), px.abs().sum());
            if s <= floor {
                return Ok(());
            }
        }
        if !(s > T::zero()) {
            return Err(Error::Singular {
                what: "the innovation variance xᵀPx + r (P lost positive definiteness: reset_covariance(p0) restarts the identifier from its \
                       estimate; form='sqrt' cannot lose it)",
            });
        }
        let Some(r_eff) = self.screen(e, s) else {
            self.record_gated();
            return Ok(());
        };
        let s = s - self.r + r_eff;
        let inv_s = T::one() / s;
        let g = px * inv_s;
        self.theta += g * e;
        let fc = self.forget_coefficient(s, r_eff, track);
        match self.form {
            CovarianceForm::Joseph => {
                let a = SMatrix::<T, N, N>::identity() - g * x.transpose();
                let mut next = a * self.m * a.transpose() + g * g.transpose() * r_eff + px * px.transpose() * fc;
                symmetrize(&mut next);
                if r_eff > T::zero() && r_eff < risky::<T>() * s && !positive_definite(&next, self.dim()) {
                    return Err(LOST_DEFINITENESS);
                }
                self.m = next;
            }
            _ => {
                // P − (P x)(P x)ᵀ (1/s − c), the forgetting folded into the downdate. Entry
                // (a, b) and (b, a) subtract the same product: P stays exactly symmetric.
                let gk = px * (inv_s - fc);
                let mut next = self.m;
                for b in 0..N {
                    for a in 0..N {
                        next[(a, b)] -= px[a] * gk[b];
                    }
                }
                symmetrize(&mut next);
                if r_eff > T::zero() && r_eff < risky::<T>() * s && !positive_definite(&next, self.dim()) {
                    return Err(LOST_DEFINITENESS);
                }
                self.m = next;
            }
        }
        self.record(e, s);
        Ok(())
    }

    /// Bierman's square-root (`U D Uᵀ`) measurement update: `f = Uᵀx`, `v = D f`,
    /// `α_j = r + Σ_{i≤j} f_i v_i`; `D_j ← D_j α_{j−1} / α_j`; the gain accumulates in `b`
    /// while `U` is updated column by column (Bierman, *Factorization Methods for Discrete
    /// Sequential Estimation*, 1977, §V.3). `s = α_N`.
    pub(super) fn step_ud(&mut self, x: &SVector<T, N>, e: T, track: bool) -> Result<()> {
        let m = &mut self.m;
        // f = Uᵀ x (U unit upper triangular: U_aa = 1).
        let mut f = SVector::<T, N>::zeros();
        for j in 0..N {
            let mut v = x[j];
            for i in 0..j {
                v += m[(i, j)] * x[i];
            }
            f[j] = v;
        }
        let mut v = SVector::<T, N>::zeros();
        for j in 0..N {
            v[j] = m[(j, j)] * f[j];
        }
        // The innovation variance first (s = r + Σ f_j v_j), for the outlier screen.
        let s = (0..N).fold(self.r, |a, j| a + f[j] * v[j]);
        if self.r == T::zero() {
            // Noise-free data and xᵀPx at rounding level against |x|₁ |P x|₁ (`P x = U v`): as
            // in the covariance forms, nothing is learned along x. (Taking such a sample would
            // collapse P along a direction x reaches only at rounding level, with the
            // estimate there made of rounding errors, for good.)
            let mut px = v;
            for i in 0..N {
                for j in (i + 1)..N {
                    px[i] += m[(i, j)] * v[j];
                }
            }
            if s <= collapse_floor::<T, N>(x.abs().sum(), px.abs().sum()) {
                return Ok(());
            }
        }
        let r_eff = if s > T::zero() && s.finite() {
            let (gate, huber, nobs, ssr, r) = (self.gate, self.huber, self.nobs, self.ssr, self.r);
            match screen(gate, huber, nobs, ssr, r, e, s, self.dim as usize) {
                Some(r_eff) => r_eff,
                None => {
                    self.record_gated();
                    return Ok(());
                }
            }
        } else {
            self.r
        };
        let m = &mut self.m;
        let mut alpha = r_eff;
        let mut b = SVector::<T, N>::zeros();
        for j in 0..N {
            let prev = alpha;
            alpha = prev + f[j] * v[j];
            if !alpha.finite() {
                return Err(OVERFLOW);
            }
            if !(alpha > T::zero()) {
                if alpha < T::zero() || f[j] != T::zero() {
                    return Err(Error::Singular {
                        what: "the innovation variance xᵀPx + r (the square-root factors are not positive)",
                    });
                }
                // r = 0 and no information along x yet (f_j = v_j = 0): column j is unchanged.
                continue;
            }
            m[(j, j)] *= prev / alpha;
            if prev > T::zero() {
                let p = -f[j] / prev;
                for i in 0..j {
                    let u = m[(i, j)];
                    m[(i, j)] = u + b[i] * p;
                    b[i] += u * v[j];
                }
            } else {
                // α_{j−1} = 0: every earlier b_i is 0, U's column keeps its values.
                for i in 0..j {
                    b[i] += m[(i, j)] * v[j];
                }
            }
            b[j] = v[j];
        }
        if !(alpha > T::zero()) {
            // r = 0 and x orthogonal to everything learned: nothing to learn (noise-free).
            return Ok(());
        }
        let s = alpha;
        let c = e / s;
        for a in 0..N {
            self.theta[a] += b[a] * c;
        }
        // Bierman's b is P x: directional forgetting is the rank-one update c (P x)(P x)ᵀ.
        let fc = self.forget_coefficient(s, r_eff, track);
        if fc > T::zero() {
            ud_rank_one(&mut self.m, fc, b);
        }
        self.record(e, s);
        Ok(())
    }

    /// The outlier screen of a sample with innovation `e` and variance `s`: `None` when the
    /// gate rejects it, else the variance to use (`r`, or `r` scaled up by the Huber weight).
    pub(super) fn screen(&self, e: T, s: T) -> Option<T> {
        screen(self.gate, self.huber, self.nobs, self.ssr, self.r, e, s, self.dim())
    }

    /// Counts a gated sample and lets it inform the scale: its recursive residual enters
    /// `σ̂²` Winsorized at the gate, `κ² σ̂²` (see [`gated_scale`]).
    pub(super) fn record_gated(&mut self) {
        (self.ssr, self.nobs) = gated_scale(self.gate, self.lambda, self.ssr, self.nobs, self.dim());
        self.gated += 1;
    }

    /// Accumulates the statistics of an accepted update with innovation `e`, variance `s`.
    pub(super) fn record(&mut self, e: T, s: T) {
        let decay = self.lambda;
        self.ssr = self.ssr * decay + e * e * self.r / s;
        self.nobs = self.nobs * decay + T::one();
        self.s = s;
    }
}

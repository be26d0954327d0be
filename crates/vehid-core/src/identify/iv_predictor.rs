//! The auxiliary model of the refined instrumental variables: a recursive linear predictor of
//! the current sample from past ones (the first stage of two-stage least squares).
//!
//! The best instrument for a regressor `h(k)` is its noise-free part `E[h(k) | past]`
//! (Söderström & Stoica, *System Identification*, 1989, §8.2: the optimal instruments are the
//! noise-free regressors; Young's refined IV, *Recursive Estimation and Time-Series
//! Analysis*, 2nd ed., 2011, Ch. 7, and the SRIVC of Young & Garnier obtain them from an
//! auxiliary model of the system driven by the measured input). The road input here is never
//! measured, so the auxiliary model cannot be simulated from it; instead the sample
//! `s(k) = [r(k); z(k); u(k)]` is predicted from the `lags` samples before `k − d + 1`:
//!
//! ```text
//! q(k) = [s(k−d); s(k−d−1); …; s(k−d−lags+1); 1]        ŝ(k) = Π̂ᵀ q(k)
//! ```
//!
//! with `Π̂` the recursive least-squares fit of `s` on `q` over the samples so far (one
//! covariance `(Σ q qᵀ)⁻¹` shared by every output, exact start). For a suspension the past
//! state and its measured derivative carry the road input that moved the state since (through
//! `B u`), so `ŝ` recovers almost all of the true state's variation, where the delayed state
//! alone misses the fast wheel mode. The instruments are then `ζ_i(k) = h_i(ŝ(k))`: for
//! regressors linear in the sample this makes the IV estimate two-stage least squares
//! (instruments `q`, weighting `(Σ q qᵀ)⁻¹`), asymptotically the most efficient IV estimate
//! on those instruments. They are valid for the same reasons as the delayed regressors
//! (`Π̂` at `k` uses samples before `k` only), and invalid under the same coloured noise.

use crate::identify::iv_filter::invert;
use crate::identify::OVERFLOW;
use crate::structure::{MAX_INPUTS, MAX_STATES};
use crate::{Real, Result};
use nalgebra::SMatrix;

/// Most values of one sample `[r; z; u]`.
pub const SAMPLE_VALUES: usize = 2 * MAX_STATES + MAX_INPUTS;

/// One planned step of a [`Predictor`]: `P q`, the prediction errors and `1 + qᵀ P q`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Step<T, const Q: usize> {
    pq: [T; Q],
    innov: [T; SAMPLE_VALUES],
    den: T,
    /// Bound on how much any entry can grow in this step.
    grow: T,
}

/// `Σ a_i b_i`.
#[inline(always)]
fn dot<T: Real>(a: &[T], b: &[T]) -> T {
    a.iter().zip(b).fold(T::zero(), |acc, (&x, &y)| acc + x * y)
}

/// `y += α x`.
#[inline(always)]
fn axpy<T: Real>(alpha: T, x: &[T], y: &mut [T]) {
    for (yi, &xi) in y.iter_mut().zip(x) {
        *yi += alpha * xi;
    }
}

/// The recursive predictor of the current sample (module docs); `Q` bounds the regressors
/// `lags × (2n + m) + 1`.
///
/// With the feature `serde` it is serialized field by field; a deserialized predictor is
/// checked (its size, finiteness, unused entries and entry bound), so a corrupt one is a
/// serde error.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct Predictor<T: Real, const Q: usize> {
    /// `(Σ q qᵀ)⁻¹`; during the exact start `Σ q qᵀ`.
    p: SMatrix<T, Q, Q>,
    /// `Π̂` (regressor × output); during the exact start `Σ q sᵀ`.
    pi: SMatrix<T, Q, SAMPLE_VALUES>,
    /// Regressors `L` and outputs in use.
    dim: u16,
    outputs: u8,
    start: bool,
    count: u64,
    /// An upper bound of the largest entry of `P` and `Π̂` (for the overflow check).
    big: T,
}

impl<T: Real, const Q: usize> Predictor<T, Q> {
    /// Checks a deserialized predictor (feature `serde`): `dim ≤ Q` regressors and at most
    /// [`SAMPLE_VALUES`] outputs; `P` and `Π̂` finite and 0 outside the leading `dim × dim`
    /// and `dim × outputs` blocks (which every step reads and writes, and no other);
    /// `big` finite and at least half the largest entry (the overflow check of
    /// [`Predictor::plan`] relies on it: a much smaller bound would let a step overflow in
    /// [`Predictor::apply`], which cannot fail; `plan` keeps a factor 4 of headroom, and a
    /// saved `big` is an upper bound up to rounding, so half is safe and never refuses a
    /// genuine state). Each failure names what is wrong.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let corrupt = |expected| Err(crate::Error::InvalidArgument { arg: "state", expected });
        let (d, no) = (self.dim as usize, self.outputs as usize);
        if d > Q || no > SAMPLE_VALUES {
            return corrupt("a predictor of at most Q regressors and SAMPLE_VALUES outputs");
        }
        if !self.p.iter().chain(self.pi.iter()).all(|v| v.finite()) {
            return corrupt("a predictor's P and Π̂ finite");
        }
        let outside_p = (0..Q).any(|a| (0..Q).any(|b| (a >= d || b >= d) && self.p[(a, b)] != T::zero()));
        let outside_pi =
            (0..Q).any(|a| (0..SAMPLE_VALUES).any(|j| (a >= d || j >= no) && self.pi[(a, j)] != T::zero()));
        if outside_p || outside_pi {
            return corrupt("a predictor's P and Π̂ zero beyond its regressors and outputs");
        }
        let largest = self.p.iter().chain(self.pi.iter()).fold(T::zero(), |m, v| m.max(v.abs()));
        if !(self.big.finite() && self.big >= largest * T::of(0.5)) {
            return corrupt("a predictor's entry bound `big` finite and at least half its largest entry");
        }
        Ok(())
    }

    /// A predictor of `outputs` values from `dim ≤ Q` regressors (exact start).
    pub(crate) fn new(dim: usize, outputs: usize) -> Self {
        Self {
            p: SMatrix::zeros(),
            pi: SMatrix::zeros(),
            dim: dim as u16,
            outputs: outputs as u8,
            start: true,
            count: 0,
            big: T::zero(),
        }
    }

    /// Regressors and outputs in use, `(dim, outputs)` (checked when a saved identifier is
    /// loaded).
    #[cfg(feature = "serde")]
    pub(crate) fn size(&self) -> (usize, usize) {
        (self.dim as usize, self.outputs as usize)
    }

    /// `true` until `Σ q qᵀ` is well conditioned (no prediction yet).
    pub fn starting(&self) -> bool {
        self.start
    }

    /// `ŝ = Π̂ᵀ q` into `out` (`outputs` values).
    #[inline]
    pub(crate) fn predict(&self, q: &[T], out: &mut [T]) {
        let d = self.dim as usize;
        for (j, o) in out.iter_mut().enumerate().take(self.outputs as usize) {
            *o = dot(&self.pi.as_slice()[j * Q..j * Q + d], &q[..d]);
        }
    }

    /// Plans adding the sample `(q, s)` and checks that every entry stays finite (bounds from
    /// the largest entry so far), so that [`Predictor::apply`] cannot fail: the identifier's
    /// update stays transactional without a copy of the predictor.
    ///
    /// # Errors
    /// The overflow error naming `r_k`.
    #[inline]
    pub(crate) fn plan(&self, q: &[T], s: &[T]) -> Result<Step<T, Q>> {
        let (d, no) = (self.dim as usize, self.outputs as usize);
        let amax = |v: &[T]| v.iter().fold(T::zero(), |m, x| m.max(x.abs()));
        let mut step = Step { pq: [T::zero(); Q], innov: [T::zero(); SAMPLE_VALUES], den: T::one(), grow: T::zero() };
        let grow = if self.start {
            let (mq, ms) = (amax(&q[..d]), amax(&s[..no]));
            mq * mq.max(ms)
        } else {
            // P q by columns (P is symmetric and stored column-major).
            let p = self.p.as_slice();
            for b in 0..d {
                axpy(q[b], &p[b * Q..b * Q + d], &mut step.pq[..d]);
            }
            step.den = T::one() + dot(&q[..d], &step.pq[..d]);
            for j in 0..no {
                step.innov[j] = s[j] - dot(&self.pi.as_slice()[j * Q..j * Q + d], &q[..d]);
            }
            let mpq = amax(&step.pq[..d]);
            (mpq / step.den.abs()) * mpq.max(amax(&step.innov[..no]))
        };
        step.grow = grow;
        let quarter = T::biggest() / T::of(4.0);
        if grow.finite() && step.den.finite() && grow < quarter && self.big + grow < quarter {
            Ok(step)
        } else {
            Err(OVERFLOW)
        }
    }

    /// Adds the sample `(q, s)` as planned: recursive least squares with unit weight,
    /// `g = P q / (1 + qᵀ P q)`, `Π̂ += g (s − Π̂ᵀ q)ᵀ`, `P −= g (P q)ᵀ` (or, during the exact
    /// start, the sums `Σ q qᵀ`, `Σ q sᵀ`). Every operation is a column sweep.
    #[inline]
    pub(crate) fn apply(&mut self, step: &Step<T, Q>, q: &[T], s: &[T]) {
        let (d, no) = (self.dim as usize, self.outputs as usize);
        self.count += 1;
        // An upper bound of the largest entry (exact again at the start's end).
        self.big += step.grow;
        if self.start {
            let p = self.p.as_mut_slice();
            for b in 0..d {
                axpy(q[b], &q[..d], &mut p[b * Q..b * Q + d]);
            }
            let pi = self.pi.as_mut_slice();
            for j in 0..no {
                axpy(s[j], &q[..d], &mut pi[j * Q..j * Q + d]);
            }
            if self.count >= d as u64 {
                self.try_start();
            }
            return;
        }
        let p = self.p.as_mut_slice();
        for b in 0..d {
            axpy(-step.pq[b] / step.den, &step.pq[..d], &mut p[b * Q..b * Q + d]);
        }
        let pi = self.pi.as_mut_slice();
        for j in 0..no {
            axpy(step.innov[j] / step.den, &step.pq[..d], &mut pi[j * Q..j * Q + d]);
        }
    }

    /// Ends the exact start once every regressor has been seen `dim` times: `P = (Σ q qᵀ + δ
    /// D²)⁻¹` with `D² = diag(Σ q qᵀ)` and `δ = 16 √ε d`, a ridge far below the data's scale.
    /// Lagged samples of a nearly noise-free system are nearly collinear (the state one step
    /// on is a linear function of the state and input before), and the predictor needs to be
    /// good, not exact: without the ridge it could wait forever. Any predictor built from past
    /// samples gives valid instruments.
    fn try_start(&mut self) {
        let d = self.dim as usize;
        let mut w = [T::one(); Q];
        for a in 0..d {
            let v = self.p[(a, a)];
            if v > T::zero() {
                w[a] = T::one() / v.sqrt();
            }
        }
        let mut c = self.p;
        for a in 0..d {
            for b in 0..d {
                c[(a, b)] *= w[a] * w[b];
            }
            c[(a, a)] += T::of(16.0) * T::default_epsilon().sqrt() * T::of(d as f64);
        }
        let Some(inv) = invert(&c, d) else { return };
        let mut p = SMatrix::<T, Q, Q>::zeros();
        for a in 0..d {
            for b in 0..d {
                p[(a, b)] = inv[(a, b)] * w[a] * w[b];
            }
        }
        let mut pi = SMatrix::<T, Q, SAMPLE_VALUES>::zeros();
        for a in 0..d {
            for j in 0..self.outputs as usize {
                pi[(a, j)] = (0..d).fold(T::zero(), |acc, b| acc + p[(a, b)] * self.pi[(b, j)]);
            }
        }
        let big = p.iter().chain(pi.iter()).fold(T::zero(), |m, v| m.max(v.abs()));
        if big.finite() {
            (self.p, self.pi, self.start, self.big) = (p, pi, false, big);
        }
    }
}

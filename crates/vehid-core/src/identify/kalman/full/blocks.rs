//! The arithmetic of [`KalmanFull`]'s covariance kept as `K × K` blocks of `N × N`: the
//! downdate block by block, the check that the stacked covariance stays positive definite,
//! the outlier screen of a stacked innovation and the error of an overflowing step.

use super::*;

/// Block `(i, j)` of the covariance after the update, `P_ij − Σ_l W_il C_jlᵀ`.
#[inline(always)]
/// `P ← P − W Cᵀ` in place on `K × K` blocks: each upper block from [`downdated_block`] (which
/// reads only that block of `P`), the diagonal blocks symmetrized, the lower ones mirrored.
pub(super) fn downdate_blocks<T: Real, const N: usize>(
    p: &mut [SMatrix<T, N, N>],
    w: &[SVector<T, N>],
    c: &[SVector<T, N>],
    k: usize,
) {
    for i in 0..k {
        for j in i..k {
            p[i * k + j] = downdated_block(p, w, c, k, i, j);
            if i == j {
                symmetrize(&mut p[i * k + i]);
            } else {
                p[j * k + i] = p[i * k + j].transpose();
            }
        }
    }
}

fn downdated_block<T: Real, const N: usize>(
    p: &[SMatrix<T, N, N>],
    w: &[SVector<T, N>],
    c: &[SVector<T, N>],
    k: usize,
    i: usize,
    j: usize,
) -> SMatrix<T, N, N> {
    let mut d = SMatrix::<T, N, N>::zeros();
    for l in 0..k {
        d += w[i * k + l] * c[j * k + l].transpose();
    }
    p[i * k + j] - d
}

/// `true` when the symmetric `(K·N) × (K·N)` matrix held as `K × K` blocks of `N × N`
/// (row-major) is numerically positive definite: its Cholesky factorization exists. Factors
/// in place (the lower triangle is overwritten).
pub(super) fn blocks_positive_definite<T: Real, const N: usize>(b: &mut [SMatrix<T, N, N>], k: usize) -> bool {
    let n = k * N;
    let at = |i: usize, j: usize| (i / N * k + j / N, i % N, j % N);
    let get = |b: &[SMatrix<T, N, N>], i: usize, j: usize| {
        let (blk, a, c) = at(i, j);
        b[blk][(a, c)]
    };
    for j in 0..n {
        let mut d = get(b, j, j);
        for q in 0..j {
            let v = get(b, j, q);
            d -= v * v;
        }
        if !(d > T::zero()) || !d.finite() {
            return false;
        }
        let d = d.sqrt();
        let (blk, a, c) = at(j, j);
        b[blk][(a, c)] = d;
        for i in (j + 1)..n {
            let mut v = get(b, i, j);
            for q in 0..j {
                v -= get(b, i, q) * get(b, j, q);
            }
            let (blk, a, c) = at(i, j);
            b[blk][(a, c)] = v / d;
        }
    }
    true
}

/// The overflow error of an update that overflowed through its step: names `z_k` when the
/// largest innovation is far beyond its prediction, `r_k` otherwise.
#[cold]
pub(super) fn culprit<T: Real, const N: usize>(theta: &[SVector<T, N>], x: &SVector<T, N>, e: &[T]) -> Error {
    let i = (0..e.len()).fold(0, |b, i| if !(e[i].abs() <= e[b].abs()) { i } else { b });
    match (e.get(i), theta.get(i)) {
        (Some(&ei), Some(th)) => overflow_culprit(ei, th.dot(x)),
        _ => OVERFLOW,
    }
}

/// The outlier gate of mode `full` ([`KalmanOptions::gate`] `κ`), from `S = H P Hᵀ + R` (`s`,
/// before it is factored) and `R`: once `N + 50` samples are behind the scale, the sample is
/// left out when any row's recursive residual `w_i = e_i √(R_ii / S_ii)` exceeds `κ σ̂_i`
/// (`σ̂_i² = Σ w_i² / (n − N)`), as in mode `rows`; the rows are filtered jointly, so every row
/// leaves it out. A gated sample informs the scale: each row's `w_i²` enters Winsorized at
/// `κ² σ̂_i²` (see [`super::super::guards::gated_scale`]). `true` when gated (the caller counts it).
pub(super) fn gate_out<T: Real, const N: usize>(
    gate: T,
    nobs: &mut T,
    ssr: &mut [T],
    e: &[T],
    s: &[T],
    r: &[T],
) -> bool {
    let k = e.len();
    let params = T::of(N as f64);
    if *nobs < params + T::of(SCREEN_WARMUP) {
        return false;
    }
    let n = *nobs - params;
    // S_ii = 0 (a noise-free row with nothing new along x) carries no residual.
    let w2 = |i: usize| {
        let sii = s[i * k + i];
        if sii > T::zero() {
            e[i] * e[i] * r[i * k + i] / sii
        } else {
            T::zero()
        }
    };
    let out = (0..k).any(|i| {
        let sigma2 = ssr[i] / n;
        sigma2 > T::zero() && !(w2(i) <= gate * gate * sigma2)
    });
    if out {
        for i in 0..k {
            let cap = gate * gate * ssr[i] / n;
            let v = w2(i);
            ssr[i] += if v <= cap { v } else { cap };
        }
        *nobs += T::one();
    }
    out
}

//! Sums in a fixed pairwise order, lane by lane, and branch-free finiteness probes: the
//! arithmetic that makes every path of the Kalman forms (portable, AVX2) round alike.

use crate::Real;
use nalgebra::SVector;

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

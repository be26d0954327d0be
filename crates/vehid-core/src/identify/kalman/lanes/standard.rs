//! The covariance update of the lanes in the standard form (the downdate `P − P x xᵀ P / s`,
//! with forgetting or tracking folded in) and in Joseph's form, and the check that a risky
//! downdate stays positive definite.

use super::super::CovarianceForm;
use super::{LaneScratch, RowLanes};
use crate::linalg::symmetrize;
use crate::Real;
use nalgebra::{SMatrix, SVector};

impl<T: Real, const N: usize, const L: usize> RowLanes<T, N, L> {
    /// Joseph's form, lane by lane: `P ← (I − g xᵀ) P (I − g xᵀ)ᵀ + r g gᵀ`, `g = P x / s`.
    #[inline(never)]
    pub(super) fn joseph(&mut self, x: &SVector<T, N>, sc: LaneScratch<T, N, L>) {
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
    pub(super) fn joseph_lane(&self, x: &SVector<T, N>, sc: &LaneScratch<T, N, L>, k: usize) -> SMatrix<T, N, N> {
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

    /// For the lanes whose sample is risky for the standard or Joseph form (`r / s` below
    /// `√ε`), the covariance after the update must stay positive definite (checked by
    /// Cholesky, on exactly the arithmetic the update will do); `false` when one would not
    /// (the sample is then refused: see [`super::super::guards::LOST_DEFINITENESS`]).
    #[cold]
    #[inline(never)]
    pub(super) fn downdates_stay_definite(&self, x: &SVector<T, N>, sc: LaneScratch<T, N, L>) -> bool {
        if self.form == CovarianceForm::Sqrt {
            return true;
        }
        (0..self.used).all(|k| {
            if sc.go[k] == T::zero()
                || sc.reff[k] == T::zero()
                || !(sc.reff[k] < super::super::guards::risky::<T>() * sc.s[k])
            {
                return true;
            }
            if self.form == CovarianceForm::Joseph {
                return super::super::guards::positive_definite(&self.joseph_lane(x, &sc, k), N);
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
            super::super::guards::positive_definite(&p, N)
        })
    }

    /// `θ += c P x`.
    #[inline(always)]
    pub(super) fn step_theta(&mut self, sc: &LaneScratch<T, N, L>) {
        for a in 0..N {
            for k in 0..L {
                self.theta[a][k] += sc.px[a][k] * sc.c[k];
            }
        }
    }

    /// The standard form's downdate: `P_ab ← P_ab − (P x)_a (P x)_b / s` on the upper triangle.
    #[inline(always)]
    pub(super) fn downdate(&mut self, sc: &LaneScratch<T, N, L>) {
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
    pub(super) fn downdate_forget(&mut self, sc: &LaneScratch<T, N, L>) {
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
    pub(super) fn downdate_tracking(&mut self, sc: &LaneScratch<T, N, L>) {
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

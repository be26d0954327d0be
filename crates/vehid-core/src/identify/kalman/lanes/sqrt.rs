//! The square-root form of the lanes: Bierman's `U D Uᵀ` update of every lane at once (the
//! plan of a sample and its application), the rank-one updates of tracking, the traces.

use super::super::sums::{is_fin, lane_dot, lane_sum};
use super::{LaneScratch, RowLanes, SqrtScratch};
use crate::Real;
use nalgebra::SVector;

impl<T: Real, const N: usize, const L: usize> RowLanes<T, N, L> {
    /// `tr(U D Uᵀ)` of every lane (square-root form): `Σ_j D_j (1 + Σ_{a<j} U_aj²)`.
    pub(super) fn ud_traces(&self) -> [T; L] {
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
    pub(super) fn ud_rank_one_lanes(&mut self, mut c: [T; L], mut a: [[T; L]; N]) {
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
    pub(super) fn plan_ud(&self, x: &SVector<T, N>, xth: [T; L], ek: [T; L], ss: &mut SqrtScratch<T, N, L>) -> bool {
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
    pub(super) fn apply_ud(&mut self, ss: &SqrtScratch<T, N, L>) {
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
}

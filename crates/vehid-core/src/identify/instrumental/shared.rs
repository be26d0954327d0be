//! The shared-gain step of [`InstrumentalVariables`]: one `P` update for every group.
//!
//! On the thesis' full rows (and any structure whose identified equations all have the same
//! parameter terms, each in a group of its own) every group's regressor is the same vector
//! `h(k)` of the sample and, since the instruments are those regressors evaluated elsewhere
//! (`delay` samples back, or on the predicted sample), its instrument is the same `ζ(k)` too.
//! The IV recursion's gain side (Söderström & Stoica, *System Identification*, 1989, Eq 8.29)
//!
//! ```text
//! s = r + hᵀ P ζ,   K = P ζ / s,   P ← P − K (Pᵀ h)ᵀ,   M ← M + ζ ζᵀ
//! ```
//!
//! then reads nothing that differs between groups: started alike (the same prior block and
//! weight `r`, or the same exact start), every group's `P = r (Σ ζ hᵀ + r P₀⁻¹)⁻¹` and
//! `M = Σ ζ ζᵀ` are the same matrices forever. Only `θ̂_g ← θ̂_g + K (y_g − hᵀθ̂_g)` differs. So
//! one `n × n` non-symmetric `P` update per sample plus one `θ̂` update per group is exact:
//! [`IvFilter::update_shared`] does the arithmetic of [`IvFilter::update`] operation for
//! operation, so the estimates, `P`, `M` and the residual sums are bit for bit those of the
//! per-group loop (`tests/noisy_states.rs` compares the two over many samples).
//!
//! Every filter still holds its own copy of `P` and `M` (written each sample), so that
//! [`InstrumentalVariables::filter`], the covariance and the serialized form are those of the
//! per-group identifier; whether the step is shared is not stored but derived from the
//! structure and the filters (at construction and on load). The exact start runs per group
//! (its first samples only); should the groups ever leave it apart, the identifier falls back
//! to the per-group step for good.

use super::{local_regression, InstrumentalVariables};
use crate::identify::{Flat, IvFilter};
use crate::structure::{Basis, Partition, Structure, Var};
use crate::{Real, Result};
use nalgebra::SVector;

/// How the regressor common to every equation is evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SharedRegressor {
    /// `h = x` (the full rows: parameter `j` of each group multiplies state `j`), and
    /// `y_i = z_i` (no known terms).
    States,
    /// Equation 0's parameter terms, which every equation repeats; `y_i` through its known
    /// terms.
    Terms,
}

/// The shared form of `s`'s groups when it applies (module docs): every identified equation
/// in a group of its own (group `i` for equation `i`), the same parameter terms in every
/// equation (coefficient, basis and local index, in order), and every filter with the same
/// gain ([`IvFilter::shares_gain_with`]: the same prior block and weight, or the exact start).
pub(crate) fn shared_regressor<T: Real, const P: usize>(
    s: &Structure<T>,
    part: &Partition,
    filters: &[IvFilter<T, P>],
) -> Option<SharedRegressor> {
    let ne = s.equations();
    if ne == 0 || part.groups as usize != ne || filters.len() != ne {
        return None;
    }
    if (0..ne).any(|i| part.group_of_eq[i] as usize != i) || !filters.iter().all(|f| f.shares_gain_with(&filters[0])) {
        return None;
    }
    let params =
        |i: usize| s.terms(i).iter().filter_map(|t| t.param.map(|p| (t.coef, t.basis, part.local[p as usize])));
    if !(1..ne).all(|i| params(i).eq(params(0))) {
        return None;
    }
    // `h = x` when equation 0's terms are `1 · x_j` for its group's parameter `j`, each once.
    // Once is implied by the count: every parameter of group 0 appears in equation 0 (the
    // group's only equation; a parameter in no equation is a group of its own, refused above
    // as groups ≠ equations), so `dim` parameter terms cannot read one parameter twice.
    let dim = part.size[0] as usize;
    let identity = params(0).count() == dim
        && params(0).all(|(coef, basis, local)| coef == T::one() && basis == Basis::Var(Var::State(local)));
    let known = (0..ne).any(|i| s.terms(i).iter().any(|t| t.param.is_none()));
    Some(if identity && !known { SharedRegressor::States } else { SharedRegressor::Terms })
}

/// Equation `i`'s output `y_i = z_i − Σ known terms`, as [`local_regression`] computes it.
#[inline(always)]
fn output<T: Real>(s: &Structure<T>, i: usize, x: &[T], z: &[T], u: &[T]) -> T {
    let mut y = z.get(s.equation_state(i)).copied().unwrap_or_else(T::zero);
    for t in s.terms(i).iter().filter(|t| t.param.is_none()) {
        y -= t.coef * s.basis(t.basis, x, z, u);
    }
    y
}

impl<T: Real, const P: usize, F: Flat<IvFilter<T, P>>, const Q: usize> InstrumentalVariables<T, P, F, Q> {
    /// The shared step's regressor kind, once every group has started.
    #[inline(always)]
    pub(super) fn shared_ready(&self) -> Option<SharedRegressor> {
        self.shared.filter(|_| !self.filters.flat()[0].starting())
    }

    /// The whole sample on the full rows' path (`h = x`, `ζ = x(k − d)`, `y_i = z_{row_i}`:
    /// [`SharedRegressor::States`], delayed instruments, every group started, the ring full),
    /// with the general path's checks written for it: `None` when the sample has the wrong
    /// lengths or a value those checks refuse (the general path then reports it), else the
    /// step's result. Transactional as the general path.
    #[inline(always)]
    pub(super) fn update_states(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Option<Result<()>> {
        // Four or more f64 parameters fill 256-bit registers: the whole sample in the AVX2
        // copy when the CPU has it (no FMA, the same operations: the same bits, `simd.rs`), so
        // that no value crosses from narrow stores to wide loads on the way.
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        if const { P >= 4 && core::mem::size_of::<T>() == 8 } && crate::simd::avx2() {
            // SAFETY: the CPU supports AVX2 (checked at run time by `simd::avx2`).
            return unsafe { self.states_avx2(x, z, u, e) };
        }
        self.states(x, z, u, e)
    }

    /// [`Self::states`] compiled for AVX2 (same arithmetic, wider registers).
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    fn states_avx2(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Option<Result<()>> {
        self.states(x, z, u, e)
    }

    /// The body of [`Self::update_states`].
    #[inline(always)]
    fn states(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Option<Result<()>> {
        let s = &self.structure;
        let (n, m, ne) = (s.states(), s.inputs(), s.equations());
        if x.len() != n || z.len() != n || u.len() != m || e.len() != ne {
            return None;
        }
        // As update_into's check (a NaN fails `<` too), without early exits.
        let limit = T::biggest().sqrt() / T::of(256.0);
        let bad = |v: &[T]| v.iter().fold(false, |b, a| b | !(a.abs() < limit));
        let dim = self.filters.flat()[0].dim();
        let past = self.ring.ago(self.delay as usize);
        // As local_regression: 0 + 1·x_j (so that −0 becomes +0 there as here).
        let (mut h, mut zeta) = (SVector::<T, P>::zeros(), SVector::<T, P>::zeros());
        // Every state a regressor and no input (the full rows in a store of their size): the
        // same work on compile-time lengths.
        let exact = n == P && m == 0;
        if exact {
            let (x, z, past) = (&x[..P], &z[..P], &past[..P]);
            if bad(x) | bad(z) {
                return None;
            }
            for j in 0..P {
                h[j] += x[j];
                zeta[j] += past[j];
            }
        } else {
            if bad(x) | bad(z) | bad(u) {
                return None;
            }
            for j in 0..dim {
                h[j] += x[j];
                zeta[j] += past[j];
            }
        }
        for (y, &row) in e.iter_mut().zip(&self.rows) {
            *y = z.get(row).copied().unwrap_or_else(T::zero);
        }
        let filters = self.filters.flat_mut();
        let r = filters[0].r();
        let sv = match IvFilter::shared(filters, &h, &zeta, e) {
            Ok(sv) => sv,
            Err(err) => return Some(Err(err)),
        };
        let w = r / sv;
        for ((&inn, ssr), nobs) in e.iter().zip(&mut self.eq_ssr).zip(&mut self.eq_nobs) {
            let res = inn * w;
            *ssr += res * res;
            *nobs += T::one();
        }
        if exact {
            self.ring.push_states::<P>(x, z);
        } else {
            self.ring.push(x, z, u);
        }
        self.samples += 1;
        Some(Ok(()))
    }

    /// The common regressor `h` at `(x, z, u)` and instrument `ζ` at the instruments' sample
    /// `(ax, az, au)`, and each equation's output `y_i` into `e` (as the per-group loop
    /// computes them: its row weights are all 1 here). Checked as that loop checks equation
    /// 0's: the overflow error when `y_0`, `h` or `ζ` is not finite (the other outputs are
    /// checked by the step, through the estimates they move).
    #[inline(always)]
    pub(super) fn shared_regressors(
        &self,
        kind: SharedRegressor,
        x: &[T],
        z: &[T],
        u: &[T],
        (ax, az, au): (&[T], &[T], &[T]),
        e: &mut [T],
    ) -> Result<(SVector<T, P>, SVector<T, P>)> {
        let s = &self.structure;
        let (h, zeta) = match kind {
            SharedRegressor::States => {
                // As local_regression: 0 + 1·x_j (so that −0 becomes +0 there as here).
                let (mut h, mut zeta) = (SVector::<T, P>::zeros(), SVector::<T, P>::zeros());
                let dim = self.filters.flat()[0].dim();
                for ((hj, zj), (&xj, &aj)) in h.iter_mut().zip(zeta.iter_mut()).zip(x.iter().zip(ax)).take(dim) {
                    *hj += xj;
                    *zj += aj;
                }
                for (y, &row) in e.iter_mut().zip(&self.rows) {
                    *y = z.get(row).copied().unwrap_or_else(T::zero);
                }
                (h, zeta)
            }
            SharedRegressor::Terms => {
                let one = T::one();
                let (y0, h) = local_regression::<T, P>(s, &self.part, 0, one, x, z, u);
                let (_, zeta) = local_regression::<T, P>(s, &self.part, 0, one, ax, az, au);
                e[0] = y0;
                for (i, y) in e.iter_mut().enumerate().skip(1) {
                    *y = output(s, i, x, z, u);
                }
                (h, zeta)
            }
        };
        if !(e[0].finite() && h.iter().chain(zeta.iter()).all(|v| v.finite())) {
            return Err(crate::identify::OVERFLOW);
        }
        Ok((h, zeta))
    }

    /// The shared step on `h`, `ζ` and the outputs in `e` (replaced by the innovations), and
    /// the residual sums. On an error nothing changed.
    #[inline(always)]
    pub(super) fn update_shared(&mut self, h: &SVector<T, P>, zeta: &SVector<T, P>, e: &mut [T]) -> Result<()> {
        let filters = self.filters.flat_mut();
        let r = filters[0].r();
        let sv = IvFilter::update_shared(filters, h, zeta, e)?;
        let w = r / sv;
        for ((&inn, ssr), nobs) in e.iter().zip(&mut self.eq_ssr).zip(&mut self.eq_nobs) {
            let res = inn * w;
            *ssr += res * res;
            *nobs += T::one();
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::SharedRegressor;
    use crate::identify::{Identifier, IvFilter, IvIdentifier, StructuredPrior};
    use crate::model::QuarterCar;
    use crate::sim::{SimConfig, Simulator};
    use crate::structure::{Basis, Structure, Term, Var};
    use crate::{Error, Real};
    use alloc::format;
    use alloc::vec::Vec;

    /// `n` samples `(r, z)` of the thesis' quarter car, state noise 8 % of σ_u.
    fn quarter(n: usize, seed: u64) -> Vec<([f64; 4], [f64; 4])> {
        let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.1).state_noise(0.008);
        let mut sim = Simulator::new(QuarterCar::<f64>::thesis().model(), cfg, seed).unwrap();
        (0..n)
            .map(|_| {
                let s = sim.next_sample();
                let (mut r, mut z) = ([0.0; 4], [0.0; 4]);
                r.copy_from_slice(s.r.as_slice());
                z.copy_from_slice(s.z.as_slice());
                (r, z)
            })
            .collect()
    }

    /// The same identifier forced onto the per-group step.
    fn per_group<T: Real, const P: usize, const G: usize, const Q: usize>(
        id: &IvIdentifier<T, P, G, Q>,
    ) -> IvIdentifier<T, P, G, Q> {
        let mut g = id.clone();
        g.shared = None;
        g
    }

    /// Bit for bit the same state (Debug prints every float's shortest round-trip form, −0
    /// included): the filters, the ring, the predictor, the residual sums and the count (not
    /// the step kind, nor the per-group step's scratch copy of the filters).
    fn same_state<T: Real, const P: usize, const G: usize, const Q: usize>(
        a: &IvIdentifier<T, P, G, Q>,
        b: &IvIdentifier<T, P, G, Q>,
    ) -> bool {
        let state = |x: &IvIdentifier<T, P, G, Q>| {
            format!("{:?} {:?} {:?} {:?} {:?} {}", x.filters, x.ring, x.pred, x.eq_ssr, x.eq_nobs, x.samples)
        };
        state(a) == state(b)
    }

    /// Runs `id` and its per-group twin over `data`, checking every innovation to the bit
    /// and the whole state every 37 samples and at the end.
    fn compare<T: Real, const P: usize, const G: usize, const Q: usize>(
        id: IvIdentifier<T, P, G, Q>,
        kind: SharedRegressor,
        data: &[(Vec<T>, Vec<T>, Vec<T>)],
    ) {
        assert_eq!(id.shared, Some(kind));
        let mut fast = id;
        let mut slow = per_group(&fast);
        let ne = fast.dims().equations;
        let (mut ea, mut eb) = ([T::zero(); 16], [T::zero(); 16]);
        for (k, (x, z, u)) in data.iter().enumerate() {
            let ra = fast.update_into(x, z, u, &mut ea[..ne]);
            let rb = slow.update_into(x, z, u, &mut eb[..ne]);
            assert_eq!(ra, rb, "sample {k}");
            assert_eq!(format!("{:?}", &ea[..ne]), format!("{:?}", &eb[..ne]), "sample {k}");
            if k % 37 == 0 {
                assert!(same_state(&fast, &slow), "sample {k}");
            }
        }
        assert!(!fast.starting() && fast.shared == Some(kind), "the shared step never ran");
        assert!(same_state(&fast, &slow));
        assert_eq!(slow.shared, None);
    }

    fn quarter_f64(n: usize, seed: u64) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        quarter(n, seed).into_iter().map(|(r, z)| (r.to_vec(), z.to_vec(), Vec::new())).collect()
    }

    /// The shared step is the per-group loop, bit for bit: the thesis' full rows with a
    /// prior, the exact start, per-equation priors alike, refined instruments, a longer
    /// delay, in f64 and f32.
    #[test]
    fn shared_step_is_the_per_group_loop_bit_for_bit() {
        let data = quarter_f64(3000, 11);
        let rows = [1, 3];
        let full = |delay, p0| IvIdentifier::<f64, 4, 2>::full_rows(4, &rows, delay, p0, &[0.7]).unwrap();
        compare(full(1, StructuredPrior::Scalar(1000.0)), SharedRegressor::States, &data);
        compare(full(1, StructuredPrior::Exact), SharedRegressor::States, &data);
        compare(full(3, StructuredPrior::PerEquation(&[50.0, 50.0])), SharedRegressor::States, &data);
        let theta0 = [0.1, -0.2, 0.3, 0.0, 1.0, 2.0, -3.0, 0.5];
        let with_mean = IvIdentifier::<f64, 4, 2>::new(
            Structure::full_rows(4, &rows).unwrap(),
            1,
            StructuredPrior::Scalar(10.0),
            Some(&theta0),
            &[2.0, 2.0],
        )
        .unwrap();
        compare(with_mean, SharedRegressor::States, &data);
        let refined = IvIdentifier::<f64, 4, 2, 17>::full_rows(4, &rows, 1, StructuredPrior::Exact, &[1.0])
            .unwrap()
            .with_lags(2)
            .unwrap();
        compare(refined, SharedRegressor::States, &data);
        let data32: Vec<(Vec<f32>, Vec<f32>, Vec<f32>)> = data
            .iter()
            .map(|(r, z, _)| (r.iter().map(|&v| v as f32).collect(), z.iter().map(|&v| v as f32).collect(), Vec::new()))
            .collect();
        let f32_rows =
            IvIdentifier::<f32, 4, 2>::full_rows(4, &rows, 1, StructuredPrior::Scalar(1000.0), &[1.0]).unwrap();
        compare(f32_rows, SharedRegressor::States, &data32);
    }

    /// Equations with the same parameter terms (an input, an offset, a `sign`), with known
    /// terms of their own and without, share the step through equation 0's terms, bit for bit.
    /// Without known terms, parameter terms as many as the group's parameters that are not
    /// each `1 · x_j` must not take `h = x`: an input among them, or `2 · x₁` beside `1 · 1`
    /// (each half of `coef = 1 and basis = x_j` true for one term).
    #[test]
    fn equations_with_equal_terms_share_the_step() {
        for variant in 0..3 {
            equal_terms_share_the_step(variant);
        }
    }

    fn equal_terms_share_the_step(variant: usize) {
        let per = if variant < 2 { 4 } else { 3 }; // parameters per equation
        let mut s = Structure::<f64>::new(3, 1, 3 * per).unwrap();
        let (start, len) = s.push_combination(&[(Var::State(1), 1.0), (Var::State(2), -0.5)]).unwrap();
        for (i, state) in [0usize, 2, 1].into_iter().enumerate() {
            let p = |j: usize| Some((per * i + j) as u8);
            let general = [
                Term { coef: 1.0, param: p(0), basis: Basis::Var(Var::State(0)) },
                Term { coef: -2.0, param: p(1), basis: Basis::Var(Var::Input(0)) },
                Term { coef: 1.0, param: p(2), basis: Basis::One },
                Term { coef: 1.0, param: p(3), basis: Basis::Sign { start, len } },
                Term { coef: 0.5, param: None, basis: Basis::Var(Var::State(state as u8)) },
            ];
            let scaled = [
                Term { coef: 1.0, param: p(0), basis: Basis::Var(Var::State(0)) },
                Term { coef: 2.0, param: p(1), basis: Basis::Var(Var::State(1)) },
                Term { coef: 1.0, param: p(2), basis: Basis::One },
            ];
            let terms = match variant {
                0 => &general[..],
                1 => &general[..4],
                _ => &scaled[..],
            };
            s.push_equation(state, terms).unwrap();
        }
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut g = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut x = [0.0f64; 3];
        let data: Vec<_> = (0..2000)
            .map(|_| {
                let u = g();
                x = [0.9 * x[0] + 0.3 * x[1] + g(), 0.8 * x[1] - 0.2 * x[2] + u, 0.7 * x[2] + 0.1 * x[0] + g()];
                let z = [x[0] - 0.3 * u + 0.1 * g(), 0.4 * x[0] + 0.2 + 0.1 * g(), -x[0] + u + 0.1 * g()];
                (x.map(|v| v + 0.05 * g()).to_vec(), z.to_vec(), [u].to_vec())
            })
            .collect();
        for p0 in [StructuredPrior::Scalar(100.0), StructuredPrior::Exact] {
            let id = IvIdentifier::<f64, 4, 3>::new(s, 2, p0, None, &[0.5]).unwrap();
            compare(id, SharedRegressor::Terms, &data);
        }
    }

    /// Only structures whose groups share their gain take the shared step.
    #[test]
    fn the_step_is_shared_only_when_the_gains_are() {
        let full = Structure::<f64>::full_rows(4, &[1, 3]).unwrap();
        let id = |p0, r: &[f64]| IvIdentifier::<f64, 4, 2>::new(full, 1, p0, None, r).unwrap().shared;
        assert_eq!(id(StructuredPrior::Scalar(1.0), &[1.0, 1.0]), Some(SharedRegressor::States));
        assert_eq!(id(StructuredPrior::Exact, &[1.0, 2.0]), None, "different weights r");
        assert_eq!(id(StructuredPrior::PerEquation(&[1.0, 2.0]), &[1.0]), None, "different priors");
        let physical = *QuarterCar::<f64>::structure([None, Some(1.0), None, None, None]).unwrap().structure();
        assert_eq!(IvIdentifier::<f64, 2, 2>::exact(physical, 1).unwrap().shared, None, "different regressors");
    }

    /// Rejected samples on the shared step (a vanishing correlation; one group's estimate
    /// overflowing after the other's succeeded) change nothing, as on the per-group loop,
    /// with the same error; a restored identifier takes the shared step again.
    #[test]
    fn rejected_samples_on_the_shared_step_change_nothing() {
        let full = Structure::<f64>::full_rows(2, &[0, 1]).unwrap();
        let theta0 = [0.0, 0.0, 1e157, 1e157];
        let mut id =
            IvIdentifier::<f64, 2, 2>::new(full, 1, StructuredPrior::Scalar(1.0), Some(&theta0), &[1.0]).unwrap();
        let mut e = [0.0; 2];
        id.update_into(&[1.0, 0.0], &[0.0, 0.0], &[], &mut e).unwrap();
        let mut slow = per_group(&id);
        for (x, want) in [([-1.0, 0.0], "singular"), ([1e151, 1e151], "overflow")] {
            let (a, b) = (id.clone(), slow.clone());
            let ea = id.update_into(&x, &[0.5, 0.5], &[], &mut e).unwrap_err();
            let eb = slow.update_into(&x, &[0.5, 0.5], &[], &mut e).unwrap_err();
            assert_eq!(ea, eb);
            assert_eq!(matches!(ea, Error::Singular { .. }), want == "singular", "{ea:?}");
            assert!(same_state(&id, &a) && same_state(&slow, &b) && same_state(&id, &slow), "{want}");
        }
        id.update_into(&[1e-10, 0.0], &[0.0, 0.0], &[], &mut e).unwrap();
        assert_eq!(id.filter(0).count(), 1);
        assert_eq!(id.shared, Some(SharedRegressor::States));
        let bytes = postcard::to_allocvec(&id).unwrap();
        let back: IvIdentifier<f64, 2, 2> = postcard::from_bytes(&bytes).unwrap();
        assert_eq!(back.shared, Some(SharedRegressor::States));
        assert!(same_state(&back, &id));
    }

    /// Groups that stop sharing their gain during the exact start fall back to the per-group
    /// step for good.
    #[test]
    fn groups_apart_fall_back_to_the_per_group_step() {
        let data = quarter(50, 3);
        let mut id = IvIdentifier::<f64, 4, 2>::full_rows(4, &[1, 3], 1, StructuredPrior::Exact, &[1.0]).unwrap();
        let mut e = [0.0; 2];
        for (x, z) in &data[..3] {
            id.update_into(x, z, &[], &mut e).unwrap();
        }
        assert_eq!(id.shared, Some(SharedRegressor::States));
        id.filters[1] = IvFilter::exact(4, 1.0).unwrap();
        id.update_into(&data[3].0, &data[3].1, &[], &mut e).unwrap();
        assert_eq!(id.shared, None);
    }
}

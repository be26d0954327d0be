//! Claims that had no test failing when they broke, each against an independent
//! reference:
//!
//! - the stochastic gradient (Eq 2.56, 5.2–5.18: Venter, Lyapunov and Ljung gains, the `Σ_w`
//!   bias removal, the spacing) step by step against a plain reimplementation of the
//!   equations written here;
//! - transactional updates: every identifier refuses a NaN, an inf, and a finite sample whose
//!   update overflows only after a multiplication, and its whole state (every field, through
//!   its `Debug` form: shortest round-trip floats, so equal text is equal values) is as before;
//!   it then continues exactly as a twin that never saw the bad samples.
//!
//! `docs/claims.md` lists the deliberate breaks these tests were seen to catch.

use nalgebra::SVector;
use vehid_core::identify::{
    BatchLeastSquares, BiasCompensatedVec, CovarianceForm, FullKalmanIdentifier, FullKalmanIdentifierVec, Gain,
    Identifier, IvIdentifierVec, KalmanFull, KalmanIdentifier, KalmanIdentifierVec, KalmanOptions,
    SharedKalmanIdentifier, SharedKalmanIdentifierVec, StochasticGradient, StochasticGradientVec, Store,
    StructuredGradient, StructuredKalmanVec, StructuredPrior,
};
use vehid_core::model::{HalfCar, QuarterCar};
use vehid_core::sim::{SimConfig, Simulator};
use vehid_core::structure::Structure;

type V4 = SVector<f64, 4>;
type V8 = SVector<f64, 8>;

/// Half-car samples (8 states: six unknown rows make two lane groups of the heap store).
fn half_samples(seed: u64, n: usize) -> Vec<(V8, V8)> {
    let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(HalfCar::<f64>::thesis().model(), cfg, seed).unwrap();
    (0..n).map(|_| sim.next_sample()).map(|s| (s.r, s.z)).collect()
}

/// Six unknown rows of the half car in the heap store: two lane groups (on x86-64), so the
/// plan of several groups before any applies is exercised.
fn half_six_rows(form: CovarianceForm) -> KalmanIdentifierVec<f64, 8> {
    let o = KalmanOptions { form, ..Default::default() };
    KalmanIdentifierVec::<f64, 8>::from_slices(&[0, 1, 2, 3, 5, 7], &[1000.0], &[1.0, 81.0, 1.0, 2.5e-5, 1.0, 1.0], o)
        .unwrap()
}

/// Quarter-car samples `(r, z)` with road, derivative and state noise.
fn samples(seed: u64, n: usize, state_noise: f64) -> Vec<(V4, V4)> {
    let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005).state_noise(state_noise);
    let mut sim = Simulator::new(QuarterCar::<f64>::thesis().model(), cfg, seed).unwrap();
    (0..n).map(|_| sim.next_sample()).map(|s| (s.r, s.z)).collect()
}

// ---------------------------------------------------------------------------------------
// Stochastic gradient against the equations
// ---------------------------------------------------------------------------------------

#[derive(Clone, Copy, Debug)]
enum RefGain {
    Venter(f64),
    Lyapunov,
    Ljung { lambda0: f64, lambda_init: f64 },
}

/// The thesis' stochastic gradient written from the equations, one row at a time:
/// `e_i = z_row − xᵀθ_i`; on every `spacing`-th sample `k ← k + 1`, the gain
/// (Eq 5.8 `γ = k^(−p)`; Eq 5.9 `γ = 1 / Σ_ij h_ij x_j²`; Eq 5.15–5.18 `λ ← λ₀λ + 1 − λ₀`,
/// `γ ← γ / (γ + λ)`, `γ(0) = 1`, `λ(0) = λ_init`), and Eq 2.56 with `H = I ⊗ xᵀ`:
/// `θ_ij ← θ_ij + γ h_ij (Σ_w,j θ_ij + x_j e_i)` (`Σ_w` diagonal).
struct RefSg {
    rows: Vec<usize>,
    theta: Vec<[f64; 4]>,
    h: Vec<[f64; 4]>,
    sw: [f64; 4],
    gain: RefGain,
    spacing: u64,
    seen: u64,
    k: u64,
    gamma: f64,
    lambda: f64,
}

impl RefSg {
    fn new(rows: &[usize], gain: RefGain, h: Vec<[f64; 4]>, sw: [f64; 4], spacing: u64) -> Self {
        let lambda = match gain {
            RefGain::Ljung { lambda_init, .. } => lambda_init,
            _ => 1.0,
        };
        let theta = vec![[0.0; 4]; rows.len()];
        Self { rows: rows.to_vec(), theta, h, sw, gain, spacing, seen: 0, k: 0, gamma: 1.0, lambda }
    }

    fn step(&mut self, x: &V4, z: &V4) -> Vec<f64> {
        let e: Vec<f64> = self
            .rows
            .iter()
            .zip(&self.theta)
            .map(|(&row, th)| z[row] - (0..4).map(|j| th[j] * x[j]).sum::<f64>())
            .collect();
        let active = self.seen % self.spacing == 0;
        self.seen += 1;
        if !active {
            return e;
        }
        let gamma = match self.gain {
            RefGain::Venter(p) => (self.k as f64 + 1.0).powf(-p),
            RefGain::Lyapunov => {
                let den: f64 = self.h.iter().map(|h| (0..4).map(|j| h[j] * x[j] * x[j]).sum::<f64>()).sum();
                if den <= 0.0 {
                    return e;
                }
                1.0 / den
            }
            RefGain::Ljung { lambda0, .. } => {
                self.lambda = lambda0 * self.lambda + (1.0 - lambda0);
                self.gamma / (self.gamma + self.lambda)
            }
        };
        self.k += 1;
        self.gamma = gamma;
        for (i, th) in self.theta.iter_mut().enumerate() {
            let old = *th;
            for j in 0..4 {
                th[j] = old[j] + gamma * self.h[i][j] * (self.sw[j] * old[j] + x[j] * e[i]);
            }
        }
        e
    }
}

/// Runs the identifier and the reference side by side; θ̂ (and the innovations) must agree
/// at every step to `tol` relative to the largest |θ| so far, and every sample is counted.
fn compare_sg(name: &str, id: &mut dyn Identifier<f64>, reference: &mut RefSg, data: &[(V4, V4)], tol: f64) {
    let k = reference.rows.len();
    let mut e = vec![0.0; k];
    let mut th = vec![0.0; 4 * k];
    let mut scale = 1e-300f64;
    let mut moved = 0.0f64;
    for (step, (x, z)) in data.iter().enumerate() {
        id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        let e_ref = reference.step(x, z);
        // Every sample is counted, the ones the spacing skips included.
        assert_eq!(id.samples(), step as u64 + 1, "{name}: step {step}: samples()");
        id.params_into(&mut th).unwrap();
        let th_ref: Vec<f64> = reference.theta.iter().flatten().copied().collect();
        scale = th_ref.iter().fold(scale, |m, v| m.max(v.abs()));
        moved = moved.max(scale);
        let d = th.iter().zip(&th_ref).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(d <= tol * scale, "{name}: step {step}: θ̂ {th:?} against the equations {th_ref:?} (|Δ| {d:e})");
        for (a, b) in e.iter().zip(&e_ref) {
            let bound = tol * (scale * x.abs().sum() + b.abs());
            assert!((a - b).abs() <= bound, "{name}: step {step}: innovation {a} against {b}");
        }
    }
    assert!(moved > 1e-3, "{name}: the estimate never moved: nothing was compared");
}

#[test]
fn stochastic_gradient_follows_the_equations_step_by_step() {
    let data = samples(7, 400, 0.01);
    let rows = [1usize, 3];
    // Per-parameter weights, the wheel row one tenth of the body row (Eq 5.10), not all equal.
    let h_body = [0.4, 0.3, 0.2, 0.1];
    let h = vec![h_body.map(|v| v * 0.1), h_body];
    let h_flat: Vec<f64> = h.iter().flatten().copied().collect();
    let sw = [1e-2, 4e-2, 1e-2, 3e-2];
    let gains = [
        (RefGain::Venter(0.51), Gain::Venter { p: 0.51 }),
        (RefGain::Venter(0.95), Gain::Venter { p: 0.95 }),
        (RefGain::Lyapunov, Gain::Lyapunov),
        (RefGain::Ljung { lambda0: 0.99, lambda_init: 0.95 }, Gain::Ljung { lambda0: 0.99, lambda_init: 0.95 }),
    ];
    for (rg, g) in gains {
        for noise in [[0.0; 4], sw] {
            for spacing in [1u32, 3] {
                let name = format!("{rg:?}, Σ_w {noise:?}, spacing {spacing}");
                let mut reference = RefSg::new(&rows, rg, h.clone(), noise, spacing.into());
                let mut id = StochasticGradientVec::<f64, 4>::from_slices(&rows, g, &h_flat, &noise, spacing).unwrap();
                compare_sg(&name, &mut id, &mut reference, &data, 1e-12);
                // The fixed store: the same code, the same numbers.
                let mut reference = RefSg::new(&rows, rg, h.clone(), noise, spacing.into());
                let mut id = StochasticGradient::<f64, 4, 2>::from_slices(&rows, g, &h_flat, &noise, spacing).unwrap();
                compare_sg(&format!("{name} (fixed)"), &mut id, &mut reference, &data, 1e-12);
                if noise == [0.0; 4] {
                    // On the full rows as a Structure (its module docs: this identifier without
                    // the state-noise correction), the weights one per parameter.
                    let mut reference = RefSg::new(&rows, rg, h.clone(), noise, spacing.into());
                    let st = Structure::full_rows(4, &rows).unwrap();
                    let mut id = StructuredGradient::<f64, 8>::new(st, g, &h_flat, None, spacing).unwrap();
                    compare_sg(&format!("{name} (structure)"), &mut id, &mut reference, &data, 1e-12);
                    let steps = (data.len() as u64).div_ceil(u64::from(spacing));
                    assert_eq!(id.steps(), steps, "{name}: a step every {spacing} samples");
                    assert_eq!(id.gain(), g);
                }
            }
        }
    }
}

#[test]
fn bias_removal_term_matters_in_the_comparison() {
    // The Σ_w term must move θ̂ by far more than the comparison's tolerance, or a flipped sign
    // would pass unseen.
    let data = samples(7, 400, 0.01);
    let sw = [1e-2, 4e-2, 1e-2, 3e-2];
    let mut with = RefSg::new(&[1, 3], RefGain::Venter(0.51), vec![[0.04; 4], [0.4; 4]], sw, 1);
    let mut flipped = RefSg::new(&[1, 3], RefGain::Venter(0.51), vec![[0.04; 4], [0.4; 4]], sw.map(|v| -v), 1);
    for (x, z) in &data {
        with.step(x, z);
        flipped.step(x, z);
    }
    let a: Vec<f64> = with.theta.iter().flatten().copied().collect();
    let b: Vec<f64> = flipped.theta.iter().flatten().copied().collect();
    let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let d = a.iter().zip(&b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(d > 1e-6 * scale, "the bias-removal term is invisible: {d:e} of {scale:e}");
}

// ---------------------------------------------------------------------------------------
// Transactional updates
// ---------------------------------------------------------------------------------------

/// The whole state of a persistable identifier: its serialized bytes (every field but the
/// scratch space of the plan, which holds nothing between updates; floats bit for bit).
fn ser<I: serde::Serialize>(id: &I) -> Vec<u8> {
    postcard::to_allocvec(id).unwrap()
}

/// The whole state of an identifier without serialization or scratch space: every field
/// through the derived `Debug` (floats in shortest round-trip form, so equal text is equal
/// values).
fn dbg<I: core::fmt::Debug>(id: &I) -> Vec<u8> {
    format!("{id:?}").into_bytes()
}

/// Everything the [`Identifier`] interface reads (estimate, covariance, noise, residual
/// statistics, trace, counters), or its error.
fn getters<I: Identifier<f64>>(id: &I) -> String {
    let d = id.dims();
    let mut th = vec![0.0; d.params];
    let mut cov = vec![0.0; d.params * d.params];
    let mut noise = vec![0.0; d.equations * d.equations];
    let (mut ssr, mut nobs) = (vec![0.0; d.equations], vec![0.0; d.equations]);
    let r = (id.params_into(&mut th), id.covariance_into(&mut cov), id.noise_into(&mut noise));
    let res = id.residuals_into(&mut ssr, &mut nobs);
    format!(
        "{r:?} {th:?} {cov:?} {noise:?} {res:?} {ssr:?} {nobs:?} {:?} {} {}",
        id.trace(),
        id.reinit_count(),
        id.samples()
    )
}

/// The state of the identifiers on a structure, which keep a backup of the groups an update
/// touches (scratch space: it holds nothing between updates): every group's filter, every
/// equation's statistics, and the interface's getters.
fn structured(id: &StructuredKalmanVec<f64, 8>) -> Vec<u8> {
    let groups: Vec<_> = (0..id.partition().groups as usize).map(|g| format!("{:?}", id.filter(g))).collect();
    let eqs: Vec<_> = (0..id.structure().equations()).map(|i| (id.equation_ssr(i), id.equation_r(i))).collect();
    format!("{groups:?} {eqs:?} {}", getters(id)).into_bytes()
}

/// The full form's state without its scratch (`P x`, the gain columns and the factor of
/// `S`, which it also serializes): θ̂, every block of `P`, and the interface's getters.
fn full<S: Store<f64, 4>>(id: &KalmanFull<f64, 4, S>) -> Vec<u8> {
    let k = id.dims().equations;
    let blocks: Vec<_> = (0..k * k).map(|ij| id.p_block(ij / k, ij % k).as_slice().to_vec()).collect();
    format!("{blocks:?} {}", getters(id)).into_bytes()
}

fn iv(id: &IvIdentifierVec<f64, 8>) -> Vec<u8> {
    let groups: Vec<_> =
        (0..id.structure().partition().groups as usize).map(|g| format!("{:?}", id.filter(g))).collect();
    format!("{groups:?} {} {}", id.starting(), getters(id)).into_bytes()
}

fn bc(id: &BiasCompensatedVec<f64, 8>) -> Vec<u8> {
    let groups: Vec<_> =
        (0..id.structure().partition().groups as usize).map(|g| format!("{:?}", id.correction(g))).collect();
    format!("{groups:?} {}", getters(id)).into_bytes()
}

/// Runs `warm` samples, offers every bad sample (each must be refused and change nothing),
/// then runs `after` samples on it and on a twin cloned before the bad samples: the two must
/// stay identical.
fn refuses_and_continues<const S: usize, I>(
    name: &str,
    state: fn(&I) -> Vec<u8>,
    mut id: I,
    warm: &[(SVector<f64, S>, SVector<f64, S>)],
    bad: &[(SVector<f64, S>, SVector<f64, S>)],
    after: &[(SVector<f64, S>, SVector<f64, S>)],
) where
    I: Identifier<f64> + Clone,
{
    let d = id.dims();
    let mut e = vec![0.0; d.equations];
    for (x, z) in warm {
        id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
    }
    let mut twin = id.clone();
    let before = state(&id);
    for (i, (x, z)) in bad.iter().enumerate() {
        let r = id.update_into(x.as_slice(), z.as_slice(), &[], &mut e);
        assert!(r.is_err(), "{name}: bad sample {i} ({x:?}, {z:?}) was accepted");
        assert!(state(&id) == before, "{name}: bad sample {i} ({r:?}) changed the state");
    }
    let mut e2 = e.clone();
    for (x, z) in after {
        id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        twin.update_into(x.as_slice(), z.as_slice(), &[], &mut e2).unwrap();
        assert_eq!(
            e.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            e2.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
    }
    assert!(state(&id) == state(&twin), "{name}: the run after the bad samples differs from the twin's");
    let (mut a, mut b) = (vec![0.0; d.params], vec![0.0; d.params]);
    if id.params_into(&mut a).is_ok() {
        twin.params_into(&mut b).unwrap();
        assert!(a.iter().all(|v| v.is_finite()), "{name}: θ̂ not finite: {a:?}");
    }
}

/// NaN and inf in the state and in the derivative, at the first and at a middle index.
fn non_finite<const S: usize>(x: SVector<f64, S>, z: SVector<f64, S>) -> Vec<(SVector<f64, S>, SVector<f64, S>)> {
    let mut out = Vec::new();
    for (i, v) in [(0, f64::NAN), (2, f64::INFINITY), (3, f64::NEG_INFINITY), (1, f64::NAN)] {
        let mut bx = x;
        bx[i] = v;
        out.push((bx, z));
        let mut bz = z;
        bz[i] = v;
        out.push((x, bz));
    }
    out
}

fn opts(form: CovarianceForm) -> KalmanOptions<f64> {
    KalmanOptions { form, ..Default::default() }
}

#[test]
fn every_identifier_refuses_non_finite_samples_and_changes_nothing() {
    let data = samples(11, 300, 0.0);
    let (warm, after) = (&data[..150], &data[150..]);
    let bad = non_finite(data[150].0, data[150].1);
    let rows = [1usize, 3];
    let r = [81.0, 2.5e-5];
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        let o = opts(form);
        let name = format!("rows {form:?}");
        refuses_and_continues(
            &name,
            ser,
            KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap(),
            warm,
            &bad,
            after,
        );
        refuses_and_continues(
            &name,
            ser,
            KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &r, o).unwrap(),
            warm,
            &bad,
            after,
        );
        let exact = KalmanIdentifierVec::<f64, 4>::exact(&rows, &r, o).unwrap();
        refuses_and_continues(&format!("{name} exact start"), ser, exact.clone(), &[], &bad, after);
        refuses_and_continues(&format!("{name} exact start, started"), ser, exact, warm, &bad, after);
        let t = KalmanOptions { forgetting: 0.99, drift: 1e-6, gate: 4.0, ..o };
        let t = KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, t).unwrap();
        refuses_and_continues(&format!("{name} tracking"), ser, t, warm, &bad, after);
        if form != CovarianceForm::Sqrt {
            let re = KalmanOptions { reinit: true, ..o };
            let re = KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1.0], &r, re).unwrap();
            refuses_and_continues(&format!("{name} reinit"), ser, re, warm, &bad, after);
        }
        let four = KalmanIdentifierVec::<f64, 4>::from_slices(&[0, 1, 2, 3], &[1000.0], &[1.0, 81.0, 1.0, 2.5e-5], o);
        refuses_and_continues(&format!("{name} four rows"), ser, four.unwrap(), warm, &bad, after);
        let h = half_samples(3, 300);
        let hbad = non_finite(h[150].0, h[150].1);
        refuses_and_continues(
            &format!("{name} half car, two groups"),
            ser,
            half_six_rows(form),
            &h[..150],
            &hbad,
            &h[150..],
        );
        if form != CovarianceForm::Sqrt {
            let name = format!("shared {form:?}");
            let s = SharedKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &[0.3], o).unwrap();
            refuses_and_continues(&name, ser, s, warm, &bad, after);
            let s = SharedKalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &[0.3], o).unwrap();
            refuses_and_continues(&name, ser, s, warm, &bad, after);
        }
        if form == CovarianceForm::Standard {
            let f = FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap();
            refuses_and_continues("full", full, f, warm, &bad, after);
            let f = FullKalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &r, o).unwrap();
            refuses_and_continues("full", full, f, warm, &bad, after);
        }
        let st = Structure::full_rows(4, &rows).unwrap();
        let sk = StructuredKalmanVec::<f64, 8>::new(st, StructuredPrior::Scalar(1000.0), None, &r, o).unwrap();
        refuses_and_continues(&format!("structured {form:?}"), structured, sk, warm, &bad, after);
    }
    for g in [Gain::Venter { p: 0.51 }, Gain::Lyapunov, Gain::Ljung { lambda0: 0.99, lambda_init: 0.95 }] {
        let sg = StochasticGradientVec::<f64, 4>::from_slices(&rows, g, &[0.04, 0.4], &[1e-4], 1).unwrap();
        refuses_and_continues(&format!("SG {g:?}"), ser, sg, warm, &bad, after);
        let sg = StochasticGradient::<f64, 4, 2>::from_slices(&rows, g, &[0.04, 0.4], &[0.0], 2).unwrap();
        refuses_and_continues(&format!("SG {g:?} fixed"), ser, sg, warm, &bad, after);
        let st = Structure::full_rows(4, &rows).unwrap();
        let sg = StructuredGradient::<f64, 8>::new(st, g, &[0.04], None, 1).unwrap();
        refuses_and_continues(&format!("structured SG {g:?}"), dbg, sg, warm, &bad, after);
    }
    refuses_and_continues("batch LS", ser, BatchLeastSquares::<f64, 4>::new(&rows).unwrap(), warm, &bad, after);
    let iv = IvIdentifierVec::<f64, 8>::full_rows(4, &rows, 1, StructuredPrior::Exact, &[1.0]).unwrap();
    refuses_and_continues("IV", self::iv, iv, warm, &bad, after);
    let st = Structure::full_rows(4, &rows).unwrap();
    let bc = BiasCompensatedVec::<f64, 8>::new(st, &[1e-6], &[], &[1.0]).unwrap();
    refuses_and_continues("bias compensated", self::bc, bc, warm, &bad, after);
}

/// A finite sample whose update overflows only after a multiplication: the innovation is
/// finite (one derivative near the largest float) and so is `s = xᵀPx + r`, but the step
/// `P x e / s` is not. Applied, it would change θ̂ (to inf) and `P` (finitely): the refusal must come
/// before anything is written.
#[test]
fn kalman_refuses_a_step_that_overflows_after_multiplication_and_changes_nothing() {
    let data = samples(13, 300, 0.0);
    let (warm, after) = (&data[..150], &data[150..]);
    let rows = [1usize, 3];
    let r = [81.0, 2.5e-5];
    // The body row's derivative near the largest float (the others as measured, so that the
    // sum of |e| stays finite too), and a measured state scaled until the gain `P x / s` of a
    // row exceeds 2 (so `g e` overflows): the first power of ten that does, on an independent
    // reading of a rows filter's `P`; s and e finite.
    let mut huge = data[150].1;
    huge[3] = f64::MAX * 0.5;
    let mut probe =
        KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &r, opts(CovarianceForm::Standard)).unwrap();
    for (x, z) in warm {
        probe.update(x, z).unwrap();
    }
    let overflows = |x: &V4| {
        (0..2).any(|i| {
            let px = probe.filter(i).p() * x;
            let s = x.dot(&px) + r[i];
            let e = huge[rows[i]] - probe.theta_row(i).dot(x);
            s.is_finite() && e.is_finite() && px.iter().any(|v| !(v / s * e).is_finite())
        })
    };
    let x = (-12..=2).map(|k| data[150].0 * 10f64.powi(k)).find(overflows).expect("a state whose step overflows");
    let bad = [(x, huge)];
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        let o = opts(form);
        let name = format!("rows {form:?}");
        refuses_and_continues(
            &name,
            ser,
            KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap(),
            warm,
            &bad,
            after,
        );
        refuses_and_continues(
            &name,
            ser,
            KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &r, o).unwrap(),
            warm,
            &bad,
            after,
        );
        let four = KalmanIdentifierVec::<f64, 4>::from_slices(&[0, 1, 2, 3], &[1000.0], &[1.0, 81.0, 1.0, 2.5e-5], o);
        refuses_and_continues(&format!("{name} four rows"), ser, four.unwrap(), warm, &bad, after);
        let h = half_samples(3, 300);
        let mut hz = h[150].1;
        hz[3] = f64::MAX * 0.5;
        let hbad = [(h[150].0, hz)];
        refuses_and_continues(
            &format!("{name} half car, two groups"),
            ser,
            half_six_rows(form),
            &h[..150],
            &hbad,
            &h[150..],
        );
        let t = KalmanOptions { forgetting: 0.99, drift: 1e-6, ..o };
        let t = KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, t).unwrap();
        refuses_and_continues(&format!("{name} tracking"), ser, t, warm, &bad, after);
        let st = Structure::full_rows(4, &rows).unwrap();
        let sk = StructuredKalmanVec::<f64, 8>::new(st, StructuredPrior::Scalar(1000.0), None, &r, o).unwrap();
        refuses_and_continues(&format!("structured {form:?}"), structured, sk, warm, &bad, after);
        if form != CovarianceForm::Sqrt {
            let s = SharedKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &[0.3], o).unwrap();
            refuses_and_continues(&format!("shared {form:?}"), ser, s, warm, &bad, after);
        }
        if form == CovarianceForm::Standard {
            let f = FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap();
            refuses_and_continues("full", full, f, warm, &bad, after);
        }
    }
    // The stochastic gradient (Venter and Ljung: the normalized gain bounds the step):
    // γ h x e overflows with a large state component.
    let mut bx = x;
    bx[0] = 1e3;
    let huge = V4::repeat(f64::MAX * 0.5);
    for g in [Gain::Venter { p: 0.51 }, Gain::Ljung { lambda0: 0.99, lambda_init: 0.95 }] {
        let sg = StochasticGradientVec::<f64, 4>::from_slices(&rows, g, &[0.4], &[1e-4], 1).unwrap();
        refuses_and_continues(&format!("SG {g:?}"), ser, sg, warm, &[(bx, huge)], after);
    }
}

// ---------------------------------------------------------------------------------------
// Exact symmetry of the covariances stored as whole matrices
// ---------------------------------------------------------------------------------------

/// The forms that store a whole matrix and update both triangles keep it exactly symmetric:
/// the shared `Q` (entry `(a, b)` and `(b, a)` from the same product), the full form's `P`
/// (diagonal blocks symmetrized, the lower blocks the transposes of the upper ones) and the
/// standalone row filter. (The decoupled rows in lanes store one triangle: their `P` is
/// symmetric by construction, and checking the matrix mirrored from it would prove nothing.)
#[test]
fn whole_matrix_covariances_stay_exactly_symmetric() {
    use vehid_core::identify::RowIdentifier;
    let data = samples(17, 2000, 0.0);
    let rows = [1usize, 3];
    let shared_of =
        |form| SharedKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &[0.3], opts(form)).unwrap();
    let mut shared = [shared_of(CovarianceForm::Standard), shared_of(CovarianceForm::Joseph)];
    // R with a covariance between the rows: P's off-diagonal blocks are not zero.
    let r_full = [81.0, 0.01, 0.01, 2.5e-5];
    let mut full =
        FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r_full, opts(CovarianceForm::Standard))
            .unwrap();
    let row_of = |form| RowIdentifier::<f64, 4>::new(1000.0, 2.5e-5).unwrap().configured(form, &opts(form)).unwrap();
    let mut row = [row_of(CovarianceForm::Standard), row_of(CovarianceForm::Joseph)];
    let mut e = [0.0; 2];
    let mut asymmetric = vec![];
    for (k, (x, z)) in data.iter().enumerate() {
        for (i, s) in shared.iter_mut().enumerate() {
            s.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
            if s.q() != &s.q().transpose() {
                asymmetric.push(("shared Q", i, k));
            }
        }
        full.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        for i in 0..2 {
            for j in 0..2 {
                if full.p_block(i, j) != &full.p_block(j, i).transpose() {
                    asymmetric.push(("full P", i * 2 + j, k));
                }
            }
        }
        for (i, f) in row.iter_mut().enumerate() {
            f.update(x, z[3]).unwrap();
            if f.p() != f.p().transpose() {
                asymmetric.push(("row filter P", i, k));
            }
        }
    }
    assert!(
        asymmetric.is_empty(),
        "not exactly symmetric (what, which, sample): {:?}",
        &asymmetric[..asymmetric.len().min(8)]
    );
    // Not a vacuous check: the updates filled every matrix.
    assert!(shared.iter().all(|s| s.q().iter().all(|v| *v != 0.0)));
    assert!(full.p_block(0, 0).iter().all(|v| *v != 0.0) && full.p_block(0, 1).iter().all(|v| *v != 0.0));
    assert!(row.iter().all(|f| f.p().iter().all(|v| *v != 0.0)));
}

// ---------------------------------------------------------------------------------------
// What every identifier reports about itself (gaps found by `make mutants`)
// ---------------------------------------------------------------------------------------

/// Every identifier names the state rows it identifies (`rows()`), counts the samples it
/// took, and reports its independent parameter groups (`groups_into`, which `estimate_stats` relies on): for
/// the quarter car's full rows 1 and 3, rows `[1, 3]`, parameters 0–3 in one group and 4–7 in
/// the other, equation `i` in group `i`. Written from the thesis' row layout (θ row-major,
/// Eq 2.1–2.4), not read from any identifier.
#[test]
fn every_identifier_reports_its_rows_and_parameter_groups() {
    let rows = [1usize, 3];
    let r = [81.0, 2.5e-5];
    let o = KalmanOptions::default();
    let full = || Structure::full_rows(4, &rows).unwrap();
    let mut ids: Vec<(&str, Box<dyn Identifier<f64>>)> = vec![
        ("rows", Box::new(KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &r, o).unwrap())),
        ("rows vec", Box::new(KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap())),
        ("rows exact", Box::new(KalmanIdentifierVec::<f64, 4>::exact(&rows, &r, o).unwrap())),
        ("shared", Box::new(SharedKalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &[0.3], o).unwrap())),
        ("full", Box::new(FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap())),
        (
            "SG",
            Box::new(StochasticGradient::<f64, 4, 2>::from_slices(&rows, Gain::Lyapunov, &[1.0], &[0.0], 1).unwrap()),
        ),
        (
            "SG vec",
            Box::new(StochasticGradientVec::<f64, 4>::from_slices(&rows, Gain::Lyapunov, &[1.0], &[0.0], 1).unwrap()),
        ),
        ("batch LS", Box::new(BatchLeastSquares::<f64, 4>::new(&rows).unwrap())),
        (
            "structured",
            Box::new(StructuredKalmanVec::<f64, 8>::new(full(), StructuredPrior::Scalar(1000.0), None, &r, o).unwrap()),
        ),
        (
            "structured SG",
            Box::new(StructuredGradient::<f64, 8>::new(full(), Gain::Lyapunov, &[1.0], None, 1).unwrap()),
        ),
        ("IV", Box::new(IvIdentifierVec::<f64, 8>::full_rows(4, &rows, 1, StructuredPrior::Exact, &[1.0]).unwrap())),
        ("bias compensated", Box::new(BiasCompensatedVec::<f64, 8>::new(full(), &[1e-6], &[], &[1.0]).unwrap())),
    ];
    // The batch's own accessor (beside the interface's, checked below).
    assert_eq!(BatchLeastSquares::<f64, 4>::new(&rows).unwrap().rows(), &rows, "batch LS: BatchLeastSquares::rows");
    let data = samples(12, 40, 0.0);
    for (name, id) in &mut ids {
        assert_eq!(id.rows(), &rows, "{name}: rows()");
        let mut e = [0.0; 2];
        for (x, z) in &data {
            id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        }
        assert_eq!(id.samples(), 40, "{name}: samples()");
        // The covariance (every identifier but the stochastic gradients and bias compensation,
        // which say why, keeps one) and, where reported, its trace.
        let mut p = vec![0.0; 64];
        match id.covariance_into(&mut p) {
            Ok(()) => {
                let diag: f64 = (0..8).map(|a| p[a * 8 + a]).sum();
                assert!(diag > 0.0, "{name}: covariance {p:?}");
                if let Some(t) = id.trace() {
                    assert!((t - diag).abs() <= 1e-12 * diag, "{name}: trace {t} against the covariance's {diag}");
                }
                if name.starts_with("rows") {
                    assert!(id.trace().is_some(), "{name}: no trace");
                }
                // A buffer of the wrong size is refused, saying which size it needs.
                match id.covariance_into(&mut [0.0; 3]) {
                    Err(vehid_core::Error::Shape { arg: "out", expected: 64, got: 3 }) => {}
                    other => panic!("{name}: covariance_into on 3 values: {other:?}"),
                }
            }
            Err(e) => assert!(name.contains("SG") || *name == "bias compensated", "{name}: covariance_into: {e}"),
        }
        let d = id.dims();
        assert_eq!((d.states, d.equations, d.params), (4, 2, 8), "{name}: dims()");
        let (mut gp, mut ge) = ([usize::MAX; 8], [usize::MAX; 2]);
        match id.groups_into(&mut gp, &mut ge) {
            Ok(()) => {
                assert_eq!(gp, [0, 0, 0, 0, 1, 1, 1, 1], "{name}: groups of the parameters");
                assert_eq!(ge, [0, 1], "{name}: groups of the equations");
            }
            Err(e) => panic!("{name}: groups_into: {e}"),
        }
    }
}

/// `fit` over a batch with measured inputs (the `Samples` iterator steps `x`, `z` and `u`
/// together) gives exactly the estimate of the same samples fed one by one with
/// `update_into`: a structure with an input, `v̇ = a·τ − b·v`.
#[test]
fn fit_with_measured_inputs_equals_the_samples_one_by_one() {
    use vehid_core::identify::Samples;
    use vehid_core::structure::StructureBuilder;
    let st =
        || StructureBuilder::new(&["q", "v"], &["tau"]).equation("v", "a*tau - b*v").known("q", "v").build::<f64>();
    let make = || {
        StructuredKalmanVec::<f64, 8>::new(
            st().unwrap().0,
            StructuredPrior::Exact,
            None,
            &[1.0],
            KalmanOptions::default(),
        )
    };
    let (mut one, mut batch) = (make().unwrap(), make().unwrap());
    let (mut x, mut z, mut u) = (Vec::new(), Vec::new(), Vec::new());
    let (mut q, mut v) = (0.0f64, 0.0f64);
    for k in 0..200 {
        let tau = (0.37 * k as f64).sin() + 0.5 * (0.11 * k as f64).cos();
        let dv = 2.0 * tau - 0.8 * v + 0.01 * (1.3 * k as f64).sin();
        x.extend_from_slice(&[q, v]);
        z.extend_from_slice(&[v, dv]);
        u.push(tau);
        q += 0.05 * v;
        v += 0.05 * dv;
    }
    let mut e = [0.0; 1];
    for k in 0..200 {
        one.update_into(&x[2 * k..2 * k + 2], &z[2 * k..2 * k + 2], &u[k..k + 1], &mut e).unwrap();
    }
    let samples = Samples::new(2, 1, &x, &z, &u).unwrap();
    batch.fit(&samples, |_, _, _| core::ops::ControlFlow::Continue(())).unwrap();
    assert_eq!(batch.samples(), 200, "fit stopped early");
    let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
    one.params_into(&mut a).unwrap();
    batch.params_into(&mut b).unwrap();
    assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "fit {b:?} against update_into {a:?}");
}

/// `estimate_stats` is ordinary least squares' statistics (statsmodels' `OLS(...).fit()`):
/// after an exact start with `r = 1`, on 12 samples of a 4-parameter row, `df = n − k = 8`,
/// `sigma2 = ssr / df`, `bse = √diag(sigma2 (XᵀX)⁻¹)` and the 95 % interval `θ̂ ± t bse`,
/// computed here from the normal equations, with Student's t quantile t₀.₉₇₅(8) =
/// 2.306004135033371 from the published tables (R's `qt(0.975, 8)`).
#[test]
fn estimate_stats_is_ordinary_least_squares() {
    use nalgebra::{SMatrix, SVector};
    use vehid_core::identify::estimate_stats;
    let rows = [1usize, 3];
    let theta = [[-90.0, -40.0, 50.0, 40.0], [5.0, 4.0, -5.0, -4.0]];
    let n = 12;
    // Variances other than 1 (and unequal): ordinary least squares' statistics do not depend
    // on the r the filter assumes, so every r must cancel.
    let mut id = KalmanIdentifierVec::<f64, 4>::exact(&rows, &[3.0, 0.25], KalmanOptions::default()).unwrap();
    let mut xs = Vec::new();
    let mut ys = [Vec::new(), Vec::new()];
    let mut e = [0.0; 2];
    for k in 0..n {
        let f = k as f64;
        // The first three samples lie on one line (rank 1): the exact start absorbs them with
        // residuals, and ends only at the sixth.
        let f = if k < 3 { 0.0 } else { f };
        let x = V4::new((0.7 * f).sin(), (1.3 * f + 0.2).cos(), (0.4 * f + 1.0).sin() * 2.0, 0.1 * f - 0.5)
            * if k < 3 { 1.0 + k as f64 } else { 1.0 };
        let mut z = V4::zeros();
        for (i, &row) in rows.iter().enumerate() {
            let noise = 0.3 * (2.1 * k as f64 + i as f64).sin();
            z[row] = (0..4).map(|j| theta[i][j] * x[j]).sum::<f64>() + noise;
            ys[i].push(z[row]);
        }
        xs.push(x);
        id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
    }
    let st = estimate_stats(&id, 0.05).unwrap();
    let t975_8 = 2.306004135033371;
    let close =
        |a: f64, b: f64, what: &str| assert!((a - b).abs() <= 1e-8 * b.abs().max(1e-12), "{what}: {a} against {b}");
    let xtx: SMatrix<f64, 4, 4> = xs.iter().map(|x| x * x.transpose()).sum();
    let inv = xtx.try_inverse().unwrap();
    for i in 0..2 {
        let xty: SVector<f64, 4> = xs.iter().zip(&ys[i]).map(|(x, y)| x * *y).sum();
        let beta = inv * xty;
        let ssr: f64 = xs.iter().zip(&ys[i]).map(|(x, y)| (y - x.dot(&beta)).powi(2)).sum();
        let s2 = ssr / (n - 4) as f64;
        close(st.sigma2[i], s2, "sigma2");
        assert_eq!(st.nobs[i], n as f64);
        for j in 0..4 {
            let p = 4 * i + j;
            assert_eq!(st.df[p], (n - 4) as f64, "df");
            close(st.params[p], beta[j], "params");
            let bse = (s2 * inv[(j, j)]).sqrt();
            close(st.bse[p], bse, "bse");
            close(st.conf_int[p].0, beta[j] - t975_8 * bse, "conf_int low");
            close(st.conf_int[p].1, beta[j] + t975_8 * bse, "conf_int high");
        }
    }
}

/// Feeds the same quarter-car samples to two identifiers of its rows 1 and 3 and asserts the
/// same estimate, bit for bit.
fn same_estimates_after(a: &mut dyn Identifier<f64>, b: &mut dyn Identifier<f64>, data: Vec<(V4, V4)>) {
    let mut e = [0.0; 2];
    for (x, z) in data {
        a.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        b.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
    }
    let (mut ta, mut tb) = ([0.0; 8], [0.0; 8]);
    a.params_into(&mut ta).unwrap();
    b.params_into(&mut tb).unwrap();
    assert_eq!(ta.map(f64::to_bits), tb.map(f64::to_bits));
}

/// A symmetric positive-definite `(k·n) × (k·n)` matrix with every entry distinct and
/// coupling every pair of rows: `G Gᵀ + kn·I` of a fixed, irregular `G`.
fn coupled_spd(kn: usize) -> Vec<f64> {
    let g = |i: usize, j: usize| ((i * 7 + j * 3) % 11) as f64 / 11.0 - 0.4 + 0.01 * (i as f64) * (j as f64 + 1.0);
    let mut m = vec![0.0; kn * kn];
    for i in 0..kn {
        for j in 0..kn {
            m[i * kn + j] = (0..kn).map(|l| g(i, l) * g(j, l)).sum::<f64>() + if i == j { kn as f64 } else { 0.0 };
        }
    }
    m
}

/// Mode full's prior covariance as a whole matrix (`set_p0`): the covariance it reports
/// before any sample is that matrix, entry for entry (the `(k·n) × (k·n)` layout of θ, rows
/// of A row-major), its trace is the matrix's, and the identifier then runs as one built
/// with the same diagonal prior when the matrix is diagonal.
#[test]
fn mode_full_takes_a_whole_prior_matrix_as_given() {
    let rows = [1usize, 3];
    let r = [81.0, 2.5e-5];
    let o = KalmanOptions::default();
    let p0 = coupled_spd(8);
    let mut id = FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1.0], &r, o).unwrap();
    id.set_p0(&p0).unwrap();
    let mut got = vec![0.0; 64];
    id.covariance_into(&mut got).unwrap();
    assert_eq!(got, p0, "the covariance right after set_p0");
    let trace: f64 = (0..8).map(|i| p0[i * 8 + i]).sum();
    assert!((id.trace() - trace).abs() <= 1e-12 * trace, "trace {} against {trace}", id.trace());
    // Diagonal: the same bits as the scalar prior.
    let mut diag = vec![0.0; 64];
    for i in 0..8 {
        diag[i * 8 + i] = 1000.0;
    }
    let mut a = FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1.0], &r, o).unwrap();
    a.set_p0(&diag).unwrap();
    let mut b = FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap();
    same_estimates_after(&mut a, &mut b, samples(21, 400, 0.0));
    assert!((a.trace() - b.trace()).abs() == 0.0 && a.trace() > 0.0);
    // Wrong sizes and a non-symmetric matrix are refused, naming p0.
    assert!(matches!(id.set_p0(&p0[..63]), Err(vehid_core::Error::Shape { arg: "p0", expected: 64, got: 63 })));
    let mut skew = p0.clone();
    skew[1] += 1e-3;
    assert!(id.set_p0(&skew).is_err());
}

/// Mode full's noise: the whole `k × k` matrix `R` (any order of the diagonal entries) is
/// taken when symmetric, refused when not.
#[test]
fn mode_full_takes_a_symmetric_noise_matrix() {
    let rows = [1usize, 3];
    let o = KalmanOptions::default();
    for r in [[81.0, 1e-3, 1e-3, 2.5e-5], [2.5e-5, 1e-6, 1e-6, 81.0]] {
        let id = FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap();
        let mut got = [0.0; 4];
        id.noise_into(&mut got).unwrap();
        assert_eq!(got, r);
    }
    assert!(FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &[81.0, 1e-3, 1.1e-3, 2.5e-5], o).is_err());
    // Three rows, a negative correlation (positive semi-definite: |r_02| ≤ √(r_00 r_22)).
    let r3 = [100.0, 0.0, -5.0, 0.0, 2.0, 0.0, -5.0, 0.0, 1.0];
    let id = FullKalmanIdentifierVec::<f64, 4>::from_slices(&[0, 1, 3], &[1000.0], &r3, o).unwrap();
    let mut got = [0.0; 9];
    id.noise_into(&mut got).unwrap();
    assert_eq!(got, r3);
}

/// Mode rows takes a whole prior matrix when it is block diagonal (`Prior::Full`, what Python's
/// `p0=<matrix>` passes): the same identifier as its blocks given row by row
/// (`Prior::RowMatrices`), bit for bit.
#[test]
fn mode_rows_takes_a_block_diagonal_prior_matrix() {
    use vehid_core::identify::{boxed_kalman, KalmanSpec, Mode, Prior};
    let rows = vec![1usize, 3];
    let whole = coupled_spd(8);
    let mut block_diag = vec![0.0; 64];
    let mut blocks = Vec::new();
    for b in 0..2 {
        for a in 0..4 {
            for c in 0..4 {
                block_diag[(b * 4 + a) * 8 + b * 4 + c] = whole[(b * 4 + a) * 8 + b * 4 + c];
                blocks.push(whole[(b * 4 + a) * 8 + b * 4 + c]);
            }
        }
    }
    let spec = |p0| KalmanSpec {
        rows: rows.clone(),
        p0,
        theta0: None,
        r: vec![81.0, 2.5e-5],
        mode: Mode::Rows,
        opts: KalmanOptions::default(),
    };
    let mut a = boxed_kalman::<f64, 4>(&spec(Prior::Full(block_diag))).unwrap();
    let mut b = boxed_kalman::<f64, 4>(&spec(Prior::RowMatrices(blocks))).unwrap();
    let (mut pa, mut pb) = (vec![0.0; 64], vec![0.0; 64]);
    a.covariance_into(&mut pa).unwrap();
    b.covariance_into(&mut pb).unwrap();
    assert_eq!(pa, pb);
    same_estimates_after(a.as_mut(), b.as_mut(), samples(22, 300, 0.0));
}

/// Mode full's outlier gate: a derivative of 1e30 in one of 10⁴ samples is left out (counted
/// as gated) and the estimate is as if it had never come; without the gate it ruins it.
#[test]
fn mode_full_gates_an_outlier() {
    let rows = [1usize, 3];
    let r = [81.0, 2.5e-5];
    let data = samples(23, 3000, 0.0);
    let run = |gate: f64, outlier: bool| {
        let o = KalmanOptions { gate, ..KalmanOptions::default() };
        let mut id = FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap();
        let mut e = [0.0; 2];
        for (k, (x, z)) in data.iter().enumerate() {
            let mut z = *z;
            if outlier && k == 2000 {
                z[1] = 1e30;
            }
            let _ = id.update_into(x.as_slice(), z.as_slice(), &[], &mut e);
        }
        let mut t = [0.0; 8];
        id.params_into(&mut t).unwrap();
        (t, id.gated())
    };
    let (clean, none) = run(6.0, false);
    let (gated, one) = run(6.0, true);
    assert_eq!((none, one), (0, 1), "samples gated without and with the outlier");
    let truth = QuarterCar::<f64>::thesis();
    let th = |t: &[f64; 8]| vehid_core::metrics::xi(truth.theta().transpose().as_slice(), t).unwrap();
    assert!(th(&clean).is_finite() && th(&clean) < 2.0, "the clean run: ξ {}", th(&clean));
    assert!((th(&gated) - th(&clean)).abs() <= 0.1 * th(&clean), "gated ξ {} against clean {}", th(&gated), th(&clean));
    let (open, _) = run(0.0, true);
    assert!(!(th(&open) < 10.0 * th(&clean)), "without the gate the outlier should show: ξ {}", th(&open));
}

/// On a Structure whose equations share a parameter, each with its own variance `r_i`, the
/// identifier reports that `R` (`noise_into`), and its residual sums are in each equation's
/// own units: weighted by `r_g / r_i` (`r_g` the group's first) they add up to the weighted
/// least-squares residual sum of squares at the final estimate, which after an exact start is
/// the batch solution of the normal equations (computed here directly).
#[test]
fn structured_residuals_are_in_each_equations_units() {
    use nalgebra::{Matrix3, Vector3};
    use vehid_core::structure::StructureBuilder;
    let (st, _) = StructureBuilder::new(&["x0", "x1"], &[])
        .equation("x0", "a*x0 + b*x1")
        .equation("x1", "a*x1 - x0 + c")
        .build::<f64>()
        .unwrap();
    let r = [0.5, 2.0];
    let mut id =
        StructuredKalmanVec::<f64, 4>::new(st, StructuredPrior::Exact, None, &r, KalmanOptions::default()).unwrap();
    let mut noise = [0.0; 4];
    id.noise_into(&mut noise).unwrap();
    assert_eq!(noise, [r[0], 0.0, 0.0, r[1]]);
    let (mut c, mut b) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
    let mut rows = Vec::new();
    let mut e = [0.0; 2];
    for k in 0..200 {
        let f = k as f64;
        let x = [(0.3 * f).sin() + 0.2, (0.71 * f + 1.0).cos()];
        let z = [-1.5 * x[0] + 0.7 * x[1] + 0.05 * (1.7 * f).sin(), -1.5 * x[1] - x[0] + 0.4 + 0.05 * (2.3 * f).cos()];
        id.update_into(&x, &z, &[], &mut e).unwrap();
        // (h, y, weight 1/r_i): ẋ0 = a x0 + b x1; ẋ1 + x0 = a x1 + c.
        for (h, y, w) in
            [(Vector3::new(x[0], x[1], 0.0), z[0], 1.0 / r[0]), (Vector3::new(x[1], 0.0, 1.0), z[1] + x[0], 1.0 / r[1])]
        {
            c += h * h.transpose() * w;
            b += h * (y * w);
            rows.push((h, y, r[0] * w));
        }
    }
    let theta = c.lu().solve(&b).unwrap();
    let want: f64 = rows.iter().map(|(h, y, w)| w * (y - h.dot(&theta)).powi(2)).sum();
    let (mut ssr, mut nobs) = ([0.0; 2], [0.0; 2]);
    id.residuals_into(&mut ssr, &mut nobs).unwrap();
    let got = ssr[0] + r[0] / r[1] * ssr[1];
    assert!((got - want).abs() <= 1e-8 * want, "weighted residual sums {got} against {want}");
    let mut p = [0.0; 3];
    id.params_into(&mut p).unwrap();
    assert!((0..3).all(|j| (p[j] - theta[j]).abs() <= 1e-9 * theta[j].abs().max(1.0)), "{p:?} against {theta:?}");
}

/// Exponential forgetting alone (the rows form's fast path) keeps the covariance's trace
/// under its bound (`max_trace`) while the vehicle is parked: 10⁵ samples of x = 0 scale P by
/// 1/λ each until the bound, and no further; θ̂ does not move.
#[test]
fn forgetting_alone_stops_at_the_trace_bound_when_parked() {
    let rows = [1usize, 3];
    let cap = 50_000.0;
    let o = KalmanOptions { forgetting: 0.99, max_trace: cap, ..KalmanOptions::default() };
    for mut id in [
        Box::new(KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &[81.0, 2.5e-5], o).unwrap())
            as Box<dyn Identifier<f64>>,
        Box::new(KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &[81.0, 2.5e-5], o).unwrap()),
    ] {
        let mut e = [0.0; 2];
        for (x, z) in samples(24, 500, 0.0) {
            id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        }
        let mut before = [0.0; 8];
        id.params_into(&mut before).unwrap();
        let zero = [0.0; 4];
        for _ in 0..100_000 {
            id.update_into(&zero, &[0.0, 0.01, 0.0, -0.01], &[], &mut e).unwrap();
        }
        let mut after = [0.0; 8];
        id.params_into(&mut after).unwrap();
        assert_eq!(before, after, "θ̂ moved while parked");
        let mut p = [0.0; 64];
        id.covariance_into(&mut p).unwrap();
        // Each row's P grows by 1/λ per sample while its trace is under the bound: it stops
        // within one factor 1/λ of it.
        for row in 0..2 {
            let tr: f64 = (0..4).map(|a| p[(row * 4 + a) * 8 + row * 4 + a]).sum();
            assert!(tr >= cap && tr <= cap / 0.99 * (1.0 + 1e-12), "row {row}: trace {tr} against the bound {cap}");
        }
    }
}

/// A derivative so large that the step overflows (the innovation far beyond any prediction)
/// is refused naming `z_k` (a state that large would name `r_k`), in every form.
#[test]
fn an_overflowing_derivative_is_named_z_k() {
    let rows = [1usize, 3];
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        // The gain P x / s is about 1.7 on the first entry (P = 1000 I, |x|² = 0.1, r = 81):
        // the step from z = 1.7e308 is beyond the largest float.
        let mut id = KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[1000.0], &[81.0, 2.5e-5], opts(form)).unwrap();
        let mut e = [0.0; 2];
        let err = id.update_into(&[0.3, 0.1, 0.0, 0.0], &[0.0, 1.7e308, 0.0, 0.0], &[], &mut e).unwrap_err();
        assert!(matches!(err, vehid_core::Error::InvalidArgument { arg: "z_k", .. }), "{form:?}: {err:?}");
    }
}

/// A row filter restricted to its first `d` parameters takes 1 ≤ d ≤ N, refusing the rest.
#[test]
fn a_row_filter_restricts_to_between_one_and_n_parameters() {
    use vehid_core::identify::RowIdentifier;
    for d in [0, 5] {
        assert!(RowIdentifier::<f64, 4>::new(1.0, 1.0).unwrap().restricted(d).is_err(), "d = {d}");
    }
    for d in 1..=4 {
        assert!(RowIdentifier::<f64, 4>::new(1.0, 1.0).unwrap().restricted(d).is_ok(), "d = {d}");
    }
}

/// Mode full's reinitialization (Eq 4.35–4.36): after a sample whose innovations satisfy
/// `10 Σ|e_i| > tr P`, the diagonal of `P` is multiplied by 10 (so the trace it then reports
/// is ten times the one the test saw) and the count grows by one; otherwise nothing. Checked
/// at every sample, from the innovations the identifier returns and the trace it reports.
#[test]
fn mode_full_reinitializes_exactly_when_eq_4_35_says() {
    let rows = [1usize, 3];
    let o = KalmanOptions { reinit: true, ..KalmanOptions::default() };
    let mut id = FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1.0], &[81.0, 2.5e-5], o).unwrap();
    let mut e = [0.0; 2];
    let (mut seen, mut count) = (0, 0);
    for (k, (x, z)) in samples(25, 2000, 0.0).into_iter().enumerate() {
        id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        let abs_e = e[0].abs() + e[1].abs();
        let now = id.reinit_count();
        let trace = id.trace();
        if now > count {
            assert_eq!(now, count + 1);
            assert!(
                10.0 * abs_e > trace / 10.0,
                "sample {k}: reinitialized with 10 Σ|e| = {} ≤ tr P = {}",
                10.0 * abs_e,
                trace / 10.0
            );
            seen += 1;
        } else {
            assert!(
                !(10.0 * abs_e > trace),
                "sample {k}: not reinitialized with 10 Σ|e| = {} > tr P = {trace}",
                10.0 * abs_e
            );
        }
        count = now;
    }
    assert!(seen > 0, "the data never called for a reinitialization");
}

/// With exponential forgetting, the identifier on the full-row Structure reports the same
/// discounted residual sums and observation counts as the rows form (each row its own group):
/// `ssr ← λ ssr + w²`, `n ← λ n + 1`, per equation.
#[test]
fn structured_residual_sums_forget_as_the_rows_do() {
    let rows = [1usize, 3];
    let r = [81.0, 2.5e-5];
    let o = KalmanOptions { forgetting: 0.98, ..KalmanOptions::default() };
    let mut a = KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap();
    let st = Structure::full_rows(4, &rows).unwrap();
    let mut b = StructuredKalmanVec::<f64, 8>::new(st, StructuredPrior::Scalar(1000.0), None, &r, o).unwrap();
    let mut e = [0.0; 2];
    for (x, z) in samples(26, 1500, 0.0) {
        a.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        b.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
    }
    let (mut sa, mut na, mut sb, mut nb) = ([0.0; 2], [0.0; 2], [0.0; 2], [0.0; 2]);
    a.residuals_into(&mut sa, &mut na).unwrap();
    b.residuals_into(&mut sb, &mut nb).unwrap();
    for i in 0..2 {
        assert!((sa[i] - sb[i]).abs() <= 1e-6 * sa[i], "row {i}: ssr {} (rows) against {} (structure)", sa[i], sb[i]);
        assert!((na[i] - nb[i]).abs() <= 1e-9 * na[i], "row {i}: n {} against {}", na[i], nb[i]);
        // The discounted count of 1500 samples: (1 − λ^1500) / (1 − λ), about 50.
        let n = (1.0 - 0.98f64.powi(1500)) / 0.02;
        assert!((na[i] - n).abs() <= 1e-9 * n, "row {i}: n {} against {n}", na[i]);
    }
}

/// Noise-free rows (`r = 0`) learn the parameters exactly from `N` independent samples,
/// whatever the scale of the prior `p0 I`: the step `θ += P x e / xᵀPx` does not depend on
/// P's scale. The reference is the θ the samples were made from (N independent noise-free
/// equations determine it). A row skips a sample only when `xᵀPx` is at rounding level
/// against `|x|₁ |Px|₁` (a covariance collapsed along `x`), so a small `p0` is not taken for a
/// collapsed one.
#[test]
fn noise_free_rows_learn_exactly_whatever_the_prior_scale() {
    use vehid_core::identify::RowIdentifier;
    let th = [V4::new(-3.0, 0.5, 2.0, 7.0), V4::new(0.25, -40.0, 1.5, -0.75)];
    let xs = [
        V4::new(1.0, 0.2, -0.3, 0.5),
        V4::new(-0.4, 1.1, 0.7, 0.1),
        V4::new(0.3, -0.6, 0.9, -1.2),
        V4::new(0.8, 0.5, 0.2, 0.6),
        V4::new(-1.3, 0.4, -0.8, 0.9),
        V4::new(0.05, 0.3, 1.7, -0.2),
    ];
    let close = |a: &V4, b: &V4| (a - b).norm() <= 1e-9 * b.norm();
    // z on rows 1 and 3, noise-free.
    let z_of = |x: &V4| {
        let mut z = V4::zeros();
        z[1] = x.dot(&th[0]);
        z[3] = x.dot(&th[1]);
        z
    };
    let both_rows = |got: &[f64; 8], what: &str| {
        for i in 0..2 {
            let g = V4::from_column_slice(&got[4 * i..4 * i + 4]);
            assert!(close(&g, &th[i]), "{what}, row {i}: {g} against {}", th[i]);
        }
    };
    for p0 in [1e-9, 1.0, 1e9] {
        for (i, t) in th.iter().enumerate() {
            let mut f = RowIdentifier::<f64, 4>::new(p0, 0.0).unwrap();
            for x in &xs {
                f.update(x, x.dot(t)).unwrap();
            }
            assert!(close(&f.theta(), t), "p0 = {p0}, row filter {i}: {} against {t}", f.theta());
        }
        for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
            let mut id = KalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[p0], &[0.0, 0.0], opts(form)).unwrap();
            let mut e = [0.0; 2];
            for x in &xs {
                id.update_into(x.as_slice(), z_of(x).as_slice(), &[], &mut e).unwrap();
            }
            let mut got = [0.0; 8];
            id.params_into(&mut got).unwrap();
            both_rows(&got, &format!("p0 = {p0}, {form:?}"));
        }
        // Mode full with R = 0 (its collapsed-row floor is mode rows'), and beyond the four
        // samples that identify the rows.
        let mut id =
            FullKalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[p0], &[0.0], opts(CovarianceForm::Standard))
                .unwrap();
        for x in &xs {
            id.update(x, &z_of(x)).unwrap();
        }
        let mut got = [0.0; 8];
        id.theta_into(&mut got).unwrap();
        both_rows(&got, &format!("p0 = {p0}, mode full"));
        // The full rows as a Structure with r = 0 (not its lanes' plain step, which has no
        // collapsed-row floor: the general path).
        let st = Structure::full_rows(4, &[1, 3]).unwrap();
        let opts = opts(CovarianceForm::Standard);
        let mut sk = StructuredKalmanVec::<f64, 8>::new(st, StructuredPrior::Scalar(p0), None, &[0.0], opts).unwrap();
        let mut e = [0.0; 2];
        for x in xs.iter().chain(&regressors(5, 300)) {
            sk.update_into(x.as_slice(), z_of(x).as_slice(), &[], &mut e).unwrap();
        }
        let mut got = [0.0; 8];
        sk.params_into(&mut got).unwrap();
        both_rows(&got, &format!("p0 = {p0}, structure"));
    }
}

/// A noise-free row skips a sample whose `xᵀPx` is at rounding level against `|x|₁ |Px|₁`
/// (the collapsed-row floor), also when `P` is not collapsed along `x` but `x` reaches the
/// unlearned direction only at rounding level: after `e₁, e₂, e₃` (which leave `P = e₄e₄ᵀ`
/// exactly), `x = (1, 1, 1, 10⁻¹⁶)` carries nothing about `θ₄` that survives the rounding of
/// `z`. Taking it would collapse `P` along `e₄` with `θ₄` still at its prior 0, for good;
/// skipped, `e₄` teaches `θ₄` exactly. Every form of mode rows and mode full, whose floor is
/// read per row (the noise-free row second).
#[test]
fn a_sample_reaching_the_unlearned_direction_at_rounding_level_teaches_noise_free_rows_nothing() {
    let th = [V4::new(-3.0, 0.5, 2.0, 7.0), V4::new(0.25, 6.0, 2.5, -0.75)];
    let z_of = |x: &V4| {
        let mut z = V4::zeros();
        z[1] = x.dot(&th[0]);
        z[3] = x.dot(&th[1]);
        z
    };
    let xs = [V4::x(), V4::y(), V4::z(), V4::new(1.0, 1.0, 1.0, 1e-16), V4::w()];
    let mut ids: Vec<(String, Box<dyn Identifier<f64>>, usize)> = vec![];
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        let id = KalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[1.0], &[0.0, 0.0], opts(form)).unwrap();
        ids.push((format!("rows {form:?}"), Box::new(id), 0));
    }
    // Mode full noise-free, and with a noisy first row (whose estimate is not exact: only the
    // noise-free second row is checked).
    let full = |r0: f64| {
        FullKalmanIdentifier::<f64, 4, 2>::from_slices(
            &[1, 3],
            &[1.0],
            &[r0, 0.0, 0.0, 0.0],
            opts(CovarianceForm::Standard),
        )
        .unwrap()
    };
    ids.push(("full, R = 0".into(), Box::new(full(0.0)), 0));
    ids.push(("full, R = diag(0.01, 0)".into(), Box::new(full(0.01)), 1));
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        let mut f = vehid_core::identify::RowIdentifier::<f64, 4>::new(1.0, 0.0)
            .unwrap()
            .configured(form, &KalmanOptions::default())
            .unwrap();
        for x in &xs {
            f.update(x, x.dot(&th[1])).unwrap();
        }
        assert!((f.theta() - th[1]).norm() <= 1e-12 * th[1].norm(), "row filter {form:?}: {}", f.theta());
    }
    for (name, mut id, first) in ids {
        let mut e = [0.0; 2];
        for x in &xs {
            id.update_into(x.as_slice(), z_of(x).as_slice(), &[], &mut e).unwrap();
        }
        let mut got = [0.0; 8];
        id.params_into(&mut got).unwrap();
        for i in first..2 {
            let g = V4::from_column_slice(&got[4 * i..4 * i + 4]);
            assert!((g - th[i]).norm() <= 1e-12 * th[i].norm(), "{name}, row {i}: {g} against {}", th[i]);
        }
    }
}

/// A deterministic stream of regressors with entries in [−1, 1).
fn regressors(seed: u64, n: usize) -> Vec<V4> {
    let mut s = seed;
    let mut next = move || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (0..n).map(|_| V4::new(next(), next(), next(), next())).collect()
}

/// The `8 × 8` covariance an identifier of two rows reports, and whether it has a Cholesky
/// factor (nalgebra's, not the identifier's).
fn covariance8(id: &dyn Identifier<f64>) -> (Vec<f64>, bool) {
    let mut p = vec![0.0; 64];
    id.covariance_into(&mut p).unwrap();
    let spd = nalgebra::SMatrix::<f64, 8, 8>::from_row_slice(&p).cholesky().is_some();
    (p, spd)
}

/// A sample informative far beyond its noise (`r / s` below `√ε`: "risky") whose downdate
/// stays well inside positive definiteness (`r / s` = 1e-11, far above ε) is taken (modes
/// full and rows, the latter with exponential forgetting too), and the step from the prior
/// `θ = 0`, `P = p0 I` is the closed form `θ_i = p0 x z_i / (p0 |x|² + r)`,
/// `P = (p0 I − p0² x xᵀ / (p0 |x|² + r)) / λ` in each row's block (λ = 1 without
/// forgetting), zero across rows.
#[test]
fn risky_samples_that_stay_definite_are_taken_as_the_closed_form_says() {
    let rows = [1usize, 3];
    let (p0, r) = (1e5, 1e-6);
    let th = [V4::new(-3.0, 0.5, 2.0, 7.0), V4::new(0.25, -40.0, 1.5, -0.75)];
    for (n, x) in regressors(31, 40).into_iter().enumerate() {
        let mut z = V4::zeros();
        z[1] = x.dot(&th[0]) + 0.01;
        z[3] = x.dot(&th[1]) - 0.02;
        let s = p0 * x.norm_squared() + r;
        assert!(r < f64::EPSILON.sqrt() * s, "the sample must be risky");
        let full = |forgetting| {
            let o = KalmanOptions { forgetting, ..KalmanOptions::default() };
            Box::new(FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[p0], &[r, r], o).unwrap())
                as Box<dyn Identifier<f64>>
        };
        let row_form = |form, forgetting| {
            // A trace bound above p0's: forgetting acts from the first sample.
            let o = KalmanOptions { form, forgetting, max_trace: 1e12, ..KalmanOptions::default() };
            Box::new(KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[p0], &[r, r], o).unwrap())
                as Box<dyn Identifier<f64>>
        };
        let cases: Vec<(&str, f64, Box<dyn Identifier<f64>>)> = vec![
            ("full", 1.0, full(1.0)),
            ("rows standard", 1.0, row_form(CovarianceForm::Standard, 1.0)),
            ("rows Joseph", 1.0, row_form(CovarianceForm::Joseph, 1.0)),
            ("rows standard, forgetting", 0.98, row_form(CovarianceForm::Standard, 0.98)),
            ("rows Joseph, forgetting", 0.98, row_form(CovarianceForm::Joseph, 0.98)),
        ];
        for (name, forgetting, mut id) in cases {
            let mut e = [0.0; 2];
            id.update_into(x.as_slice(), z.as_slice(), &[], &mut e)
                .unwrap_or_else(|err| panic!("sample {n}, {name}: refused: {err:?}"));
            let mut t = [0.0; 8];
            id.params_into(&mut t).unwrap();
            for i in 0..2 {
                let want = x * (p0 * z[rows[i]] / s);
                let got = V4::from_column_slice(&t[4 * i..4 * i + 4]);
                assert!(
                    (got - want).norm() <= 1e-9 * want.norm(),
                    "sample {n}, {name}, row {i}: θ {got} against {want}"
                );
            }
            let (p, spd) = covariance8(id.as_ref());
            assert!(spd, "sample {n}, {name}: the covariance is not positive definite");
            for a in 0..8 {
                for b in 0..8 {
                    let want = if a / 4 != b / 4 {
                        0.0
                    } else {
                        (f64::from(u8::from(a == b)) * p0 - p0 * p0 * x[a % 4] * x[b % 4] / s) / forgetting
                    };
                    assert!(
                        (p[a * 8 + b] - want).abs() <= 1e-9 * p0,
                        "sample {n}, {name}: P[{a}, {b}] {} against {want}",
                        p[a * 8 + b]
                    );
                }
            }
        }
    }
}

/// A risky sample whose downdate is positive definite in exact arithmetic but not in
/// floating point (`r / s` ≈ 1e-17 on row 1, below ε: the new smallest eigenvalue `p0 r / s` is under
/// the rounding of `P`'s entries) is checked before it is taken (modes full and rows): it is
/// either taken, and the covariance then has a Cholesky factor, or refused as singular with
/// the state unchanged. Some of the 200 samples are refused: the case arises.
#[test]
fn risky_samples_whose_downdate_would_be_indefinite_are_refused() {
    let rows = [1usize, 3];
    // Row 0 is not risky (r / s ≈ 1e-5); row 1 is, and alone decides the check.
    let (p0, r) = (1e5, [1.0, 1e-12]);
    let mut prior = vec![0.0; 64];
    for a in 0..8 {
        prior[a * 8 + a] = p0;
    }
    for mode in ["full", "rows standard", "rows Joseph", "rows standard, forgetting"] {
        let mut refused = 0;
        for (n, x) in regressors(32, 200).into_iter().enumerate() {
            let mut id: Box<dyn Identifier<f64>> = match mode {
                "full" => Box::new(
                    FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[p0], &r, KalmanOptions::default()).unwrap(),
                ),
                "rows standard, forgetting" => Box::new(
                    KalmanIdentifier::<f64, 4, 2>::from_slices(
                        &rows,
                        &[p0],
                        &r,
                        KalmanOptions { forgetting: 0.98, max_trace: 1e12, ..KalmanOptions::default() },
                    )
                    .unwrap(),
                ),
                "rows standard" => Box::new(
                    KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[p0], &r, opts(CovarianceForm::Standard))
                        .unwrap(),
                ),
                _ => Box::new(
                    KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[p0], &r, opts(CovarianceForm::Joseph)).unwrap(),
                ),
            };
            let z = V4::new(0.0, x.sum(), 0.0, 2.0 * x[0]);
            let mut e = [0.0; 2];
            match id.update_into(x.as_slice(), z.as_slice(), &[], &mut e) {
                Ok(()) => {
                    let (_, spd) = covariance8(id.as_ref());
                    assert!(spd, "{mode}, sample {n}: taken, and the covariance has no Cholesky factor");
                }
                Err(err) => {
                    assert!(matches!(err, vehid_core::Error::Singular { .. }), "{mode}, sample {n}: {err:?}");
                    let (p, _) = covariance8(id.as_ref());
                    let mut t = [1.0; 8];
                    id.params_into(&mut t).unwrap();
                    assert!(
                        p == prior && t == [0.0; 8] && id.samples() == 0,
                        "{mode}, sample {n}: refused but changed"
                    );
                    refused += 1;
                }
            }
        }
        assert!(refused > 0, "{mode}: no sample of 200 was refused");
        eprintln!("{mode}: {refused} of 200 refused");
    }
}

/// The shared form's arithmetic per update, counted here from its algorithm (each distinct
/// product once: `Q`'s downdate gives entries (a, b) and (b, a) the same number). For N
/// states and K rows: `Q x` N² mul, N(N−1) add; `s = 1 + xᵀQx` N mul, N add; `1/s` one
/// division; `g = Qx/s` N mul; per row `e_i = z_i − θ_iᵀx` and `θ_i += g e_i` 2N mul, 2N add;
/// the upper triangle of `Q −= (Qx) gᵀ` N(N+1)/2 mul and add. No square root.
#[test]
fn shared_form_cost_is_its_operation_count() {
    fn count(n: usize, k: usize) -> (usize, usize, usize, usize) {
        let tri = n * (n + 1) / 2;
        let mul = n * n + n + n + k * 2 * n + tri;
        let add = n * (n - 1) + n + k * 2 * n + tri;
        (mul, add, 1, 0)
    }
    let c = SharedKalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, [1.0, 1.0]).unwrap().cost();
    assert_eq!((c.multiplications, c.additions, c.divisions, c.square_roots), count(4, 2));
    assert_eq!(count(4, 2), (50, 42, 1, 0));
    let h =
        SharedKalmanIdentifierVec::<f64, 8>::from_slices(&[1, 3, 5, 7], &[1000.0], &[1.0], KalmanOptions::default())
            .unwrap()
            .cost();
    assert_eq!((h.multiplications, h.additions, h.divisions, h.square_roots), count(8, 4));
}

/// `Samples::skip_to(start)` is the samples from `start` on: the same `(x, z, u)` slices as
/// the iterator after `start` steps, for 0, 1 and 2 inputs per sample; past the end, none.
#[test]
fn samples_skip_to_is_the_iterator_after_start_steps() {
    use vehid_core::identify::Samples;
    let (n, len) = (3usize, 5usize);
    let x: Vec<f64> = (0..n * len).map(|i| i as f64).collect();
    let z: Vec<f64> = (0..n * len).map(|i| 100.0 + i as f64).collect();
    for m in [0usize, 1, 2] {
        let u: Vec<f64> = (0..m * len).map(|i| -(i as f64)).collect();
        let all = Samples::new(n, m, &x, &z, &u).unwrap();
        for start in 0..=len + 1 {
            let rest = all.skip_to(start);
            assert_eq!(rest.len(), len.saturating_sub(start), "m = {m}, start = {start}");
            let got: Vec<_> = rest.iter().collect();
            let want: Vec<_> = all.iter().skip(start).collect();
            assert_eq!(got, want, "m = {m}, start = {start}");
        }
    }
}

/// `fit_dyn`'s history: `record_every = k` appends the parameters after every k-th sample
/// (the estimate the identifier reports after that sample, stepped here one sample at a time),
/// `0` never; `check_every = k` asks the interrupt after every k-th sample, `0` never.
#[test]
fn fit_dyn_records_and_checks_every_k_samples_and_never_for_0() {
    use vehid_core::identify::{DynIdentifier, FitOptions, Samples};
    let data = samples(33, 10, 0.0);
    let x: Vec<f64> = data.iter().flat_map(|(x, _)| x.iter().copied()).collect();
    let z: Vec<f64> = data.iter().flat_map(|(_, z)| z.iter().copied()).collect();
    let s = Samples::new(4, 0, &x, &z, &[]).unwrap();
    let fresh = || {
        KalmanIdentifierVec::<f64, 4>::from_slices(&[1, 3], &[1000.0], &[81.0, 2.5e-5], opts(CovarianceForm::Standard))
            .unwrap()
    };
    // The reference: the estimate after each sample, one update at a time.
    let mut by_hand = fresh();
    let mut after = Vec::new();
    let mut e = [0.0; 2];
    for (x, z) in &data {
        by_hand.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        let mut t = [0.0; 8];
        by_hand.params_into(&mut t).unwrap();
        after.push(t);
    }
    for (every, check) in [(0usize, 0usize), (3, 4), (1, 0), (0, 1)] {
        let mut id = fresh();
        let mut history = Vec::new();
        let mut asked = 0;
        id.fit_dyn(&s, FitOptions { record_every: every, check_every: check }, &mut history, &mut || {
            asked += 1;
            false
        })
        .unwrap();
        let want: Vec<f64> =
            if every == 0 { vec![] } else { after.iter().skip(every - 1).step_by(every).flatten().copied().collect() };
        assert_eq!(history, want, "record_every {every}");
        assert_eq!(asked, data.len().checked_div(check).unwrap_or(0), "check_every {check}");
    }
}

/// Mode full takes a positive semi-definite noise matrix `R` at any scale and refuses one with
/// a negative eigenvalue at any scale: for s from 1e-6 to 1e6, `R = s v vᵀ` (rank one, its
/// eigenvalues 0 and s|v|²: perfectly correlated rows, as noise-free data give) is taken, and
/// `s [[1, 1.001], [1.001, 1]]` (eigenvalues 2.001 s and −0.001 s) refused as singular.
#[test]
fn mode_full_checks_the_noise_matrix_whatever_its_scale() {
    let rows = [1usize, 3];
    let o = KalmanOptions::default();
    for s in [1e-6, 1e-3, 1.0, 81.0, 1e3, 1e6] {
        for v in [[1.0, 1.0], [1.0, 2.0], [3.0, -1.0], [0.7, 0.3]] {
            let r = [s * v[0] * v[0], s * v[0] * v[1], s * v[1] * v[0], s * v[1] * v[1]];
            assert!(
                FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).is_ok(),
                "s = {s}, v = {v:?}: a rank-one R refused"
            );
        }
        let r = [s, 1.001 * s, 1.001 * s, s];
        assert!(
            matches!(
                FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o),
                Err(vehid_core::Error::Singular { .. })
            ),
            "s = {s}: an indefinite R taken"
        );
    }
}

/// Mode full's `cost().bytes` counts, in the heap store, at least the heap of the three
/// buffers an update works in: `P` (K² blocks of N × N), `C = P x` and the gains `W` (K² vectors
/// of N each), on top of the identifier itself, and at most the heap of all its buffers (`P`
/// and its candidate, `C`, `W`, `R`, `S`, `θ`, the residual sums and the rows: `vec![x; n]`
/// allocates exactly n); in the fixed store, where they live inside it, its size.
#[test]
fn mode_full_cost_counts_its_heap_buffers() {
    let (k, n) = (2usize, 4usize);
    let v =
        FullKalmanIdentifierVec::<f64, 4>::from_slices(&[1, 3], &[1000.0], &[81.0, 2.5e-5], KalmanOptions::default())
            .unwrap();
    // Every heap buffer (`vec![x; n]` allocates exactly n): the rows (usize), θ (K·N), P and
    // its candidate copy (K² blocks of N²), R and S's factor (K²), C and W (K² vectors of N),
    // the gate's sums (K).
    let heap = 8 * k + 8 * (k * n + 2 * k * k * n * n + 2 * k * k + 2 * k * k * n + k);
    assert_eq!(v.cost().bytes, core::mem::size_of_val(&v) + heap);
    let f =
        FullKalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[1000.0], &[81.0, 2.5e-5], KalmanOptions::default())
            .unwrap();
    assert_eq!(f.cost().bytes, core::mem::size_of_val(&f));
}

/// Mode full refuses a sample whose step `W e` overflows because the gain is huge and the
/// innovation large while `C = P x` is tiny (noise-free rows, `x` at 1e-150, `z` at 1e300: the
/// gain is about 1/|x| ≈ 1e150 and the step 1e450), and changes nothing.
#[test]
fn mode_full_refuses_a_huge_gain_times_a_large_innovation() {
    let rows = [1usize, 3];
    let mut id =
        FullKalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &[0.0, 0.0], KalmanOptions::default())
            .unwrap();
    let before = full(&id);
    let x: [f64; 4] = [1e-150, 1e-150, 0.0, 0.0];
    let z = [0.0, 1e300, 0.0, 1e300];
    // The premise: the step's size, from the quantities the identifier starts from.
    let (s, c) = (1000.0 * (x[0] * x[0] + x[1] * x[1]), 1000.0 * x[0]);
    assert!(s > 0.0 && c > 0.0 && (c / s * z[1]).is_infinite());
    let mut e = [0.0; 2];
    assert!(id.update_into(&x, &z, &[], &mut e).is_err(), "an overflowing step was taken");
    assert_eq!(full(&id), before, "the refused sample changed the state");
}

/// Mode rows' outlier gate in every covariance form: a derivative of 1e30 in one of 3000
/// samples is left out (counted as gated on its row) and the estimate stays that of the clean
/// run; the square-root form, the same filter in other arithmetic, agrees with the standard
/// form to 1e-6 of the largest parameter with the gate on.
#[test]
fn mode_rows_gates_an_outlier_in_every_form() {
    let rows = [1usize, 3];
    let r = [81.0, 2.5e-5];
    let data = samples(23, 3000, 0.0);
    let run = |form, outlier: bool| {
        let o = KalmanOptions { form, gate: 6.0, ..KalmanOptions::default() };
        let mut id = KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1000.0], &r, o).unwrap();
        let mut e = [0.0; 2];
        for (k, (x, z)) in data.iter().enumerate() {
            let mut z = *z;
            if outlier && k == 2000 {
                z[1] = 1e30;
            }
            id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        }
        let mut t = [0.0; 8];
        id.params_into(&mut t).unwrap();
        let mut g = [0u64; 2];
        id.gated_into(&mut g).unwrap();
        (t, g)
    };
    let truth = QuarterCar::<f64>::thesis();
    let xi = |t: &[f64; 8]| vehid_core::metrics::xi(truth.theta().transpose().as_slice(), t).unwrap();
    let (standard, _) = run(CovarianceForm::Standard, true);
    for form in [CovarianceForm::Standard, CovarianceForm::Joseph, CovarianceForm::Sqrt] {
        let (clean, _) = run(form, false);
        let (gated, g) = run(form, true);
        assert_eq!(g[0], 1, "{form:?}: samples gated on the wheel row");
        assert!(xi(&clean).is_finite() && xi(&clean) < 2.0, "{form:?}: the clean run: ξ {}", xi(&clean));
        assert!(
            (xi(&gated) - xi(&clean)).abs() <= 0.1 * xi(&clean),
            "{form:?}: ξ {} against clean {}",
            xi(&gated),
            xi(&clean)
        );
        let scale = standard.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let d = gated.iter().zip(&standard).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(d <= 1e-6 * scale, "{form:?}: {gated:?} against the standard form's {standard:?}");
    }
}

/// Mode rows' reinitialization (Eq 4.35–4.36) in the square-root form is the standard form's:
/// the same reinitializations, and estimates within 1e-6 of the largest parameter.
#[test]
fn mode_rows_reinitializes_alike_in_the_square_root_form() {
    let rows = [1usize, 3];
    let run = |form| {
        let o = KalmanOptions { form, reinit: true, ..KalmanOptions::default() };
        let mut id = KalmanIdentifierVec::<f64, 4>::from_slices(&rows, &[1.0], &[81.0, 2.5e-5], o).unwrap();
        let mut e = [0.0; 2];
        for (x, z) in samples(25, 2000, 0.0) {
            id.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        }
        let mut t = [0.0; 8];
        id.params_into(&mut t).unwrap();
        (t, id.reinit_count())
    };
    let (a, na) = run(CovarianceForm::Standard);
    let (b, nb) = run(CovarianceForm::Sqrt);
    assert!(na > 0, "the data never called for a reinitialization");
    assert_eq!(na, nb);
    let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let d = a.iter().zip(&b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(d <= 1e-6 * scale, "{b:?} against the standard form's {a:?}");
}

/// `Cost::flops()` is every floating-point operation once: the four counts' sum, each of them
/// visible in it (powers of ten, so a count left out, subtracted or counted twice shows as a
/// wrong digit), and `bytes` not among them. Also on the identifiers' own costs, among them
/// mode full's, the one form with square roots.
#[test]
fn cost_flops_is_the_sum_of_the_four_operation_counts() {
    use vehid_core::identify::Cost;
    let c = Cost { multiplications: 1, additions: 10, divisions: 100, square_roots: 1000, bytes: 10_000 };
    assert_eq!(c.flops(), 1111);
    let full =
        FullKalmanIdentifierVec::<f64, 4>::from_slices(&[1, 3], &[1000.0], &[81.0, 2.5e-5], KalmanOptions::default())
            .unwrap()
            .cost();
    let rows = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, [1.0, 1.0]).unwrap().cost();
    let shared = SharedKalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, [1.0, 1.0]).unwrap().cost();
    assert!(full.square_roots > 0, "mode full takes square roots (its Cholesky of S)");
    for c in [full, rows, shared] {
        assert_eq!(c.flops(), c.multiplications + c.additions + c.divisions + c.square_roots, "{c:?}");
    }
}

/// Mode full's `cost()` is the operation count its docs define, counted here by walking the
/// update's loops one by one (each formula as written: a sum of n terms n − 1 additions, a
/// subtraction an addition), for K = 1, 2, 3 rows of N = 4 and K = 4 of N = 8. The Cholesky
/// factorization of the K × K `S`: per column j, `S_jj − Σ_{p<j} L_jp²` and a square root,
/// then each `L_ij = (S_ij − Σ_{p<j} L_ip L_jp) / L_jj` below it; each of the K·N solves with
/// the factor: per row i of the forward and of the back substitution, i (or K − 1 − i)
/// products, as many subtractions, one division.
#[test]
fn mode_full_cost_is_its_operation_count() {
    fn count(k: usize, n: usize) -> (usize, usize, usize, usize) {
        let (mut mul, mut add, mut div, mut sqrt) = (0, 0, 0, 0);
        // e_i = z_i − θ_iᵀx
        for _ in 0..k {
            mul += n;
            add += n;
        }
        // C_ij = P_ij x, every block
        for _ in 0..k * k {
            mul += n * n;
            add += n * (n - 1);
        }
        // S_ij = xᵀ C_ij + R_ij on and below the diagonal
        for i in 0..k {
            for _ in 0..=i {
                mul += n;
                add += n;
            }
        }
        // Cholesky of S
        for j in 0..k {
            mul += j;
            add += j;
            sqrt += 1;
            for _ in j + 1..k {
                mul += j;
                add += j;
                div += 1;
            }
        }
        // W = C S⁻¹: one solve per row i of W's blocks and state a
        for _ in 0..k * n {
            for i in 0..k {
                mul += i;
                add += i;
                div += 1;
            }
            for i in 0..k {
                mul += k - 1 - i;
                add += k - 1 - i;
                div += 1;
            }
        }
        // θ_i += Σ_l W_il e_l
        for _ in 0..k * k {
            mul += n;
            add += n;
        }
        // P_ij −= Σ_l W_il C_jlᵀ on and above the diagonal; the diagonal blocks symmetrized
        for i in 0..k {
            for j in i..k {
                mul += k * n * n;
                add += k * n * n;
                if i == j {
                    mul += n * (n - 1) / 2;
                    add += n * (n - 1) / 2;
                }
            }
        }
        (mul, add, div, sqrt)
    }
    let of = |c: vehid_core::identify::Cost| (c.multiplications, c.additions, c.divisions, c.square_roots);
    let opts = KalmanOptions::default();
    let one = FullKalmanIdentifierVec::<f64, 4>::from_slices(&[1], &[1000.0], &[1.0], opts).unwrap();
    assert_eq!(of(one.cost()), count(1, 4));
    let two = FullKalmanIdentifier::<f64, 4, 2>::from_slices(&[1, 3], &[1000.0], &[81.0, 2.5e-5], opts).unwrap();
    assert_eq!(of(two.cost()), count(2, 4));
    // K = 2, N = 4: the solves are 16 multiplications and 32 divisions of the 33.
    assert_eq!(count(2, 4).2, 33);
    let three = FullKalmanIdentifierVec::<f64, 4>::from_slices(&[0, 1, 3], &[1000.0], &[1.0], opts).unwrap();
    assert_eq!(of(three.cost()), count(3, 4));
    let four = FullKalmanIdentifierVec::<f64, 8>::from_slices(&[1, 3, 5, 7], &[1000.0], &[1.0], opts).unwrap();
    assert_eq!(of(four.cost()), count(4, 8));
}

/// Mode full's accessors read back what it was given, entry for entry, before any sample:
/// `r(i, j)` the whole `K × K` noise matrix (three rows, every off-diagonal entry distinct),
/// `p_block(i, j)` block `(i, j)` of the whole prior matrix (`(K·N) × (K·N)`, row-major),
/// `theta_row(i)` row `i` of the prior mean, `rows()` the rows, `trace()` the prior's trace.
#[test]
fn mode_full_accessors_read_back_the_matrices_given() {
    const N: usize = 4;
    let rows = [0usize, 1, 3];
    let k = rows.len();
    let r = [4.0, 0.5, -0.3, 0.5, 3.0, 0.2, -0.3, 0.2, 2.0];
    let mut id = FullKalmanIdentifierVec::<f64, N>::from_slices(&rows, &[1.0], &r, KalmanOptions::default()).unwrap();
    let kn = k * N;
    let p0 = coupled_spd(kn);
    id.set_p0(&p0).unwrap();
    let theta0: Vec<f64> = (0..kn).map(|i| 0.5 + i as f64).collect();
    id.set_theta(&theta0).unwrap();
    assert_eq!(id.rows(), &rows);
    for i in 0..k {
        for j in 0..k {
            assert_eq!(id.r(i, j), r[i * k + j], "r({i}, {j})");
            let b = id.p_block(i, j);
            for a in 0..N {
                for c in 0..N {
                    assert_eq!(b[(a, c)], p0[(i * N + a) * kn + j * N + c], "p_block({i}, {j})[({a}, {c})]");
                }
            }
        }
        assert_eq!(id.theta_row(i).as_slice(), &theta0[i * N..(i + 1) * N], "theta_row({i})");
    }
    let trace: f64 = (0..kn).map(|i| p0[i * kn + i]).sum();
    assert!((id.trace() - trace).abs() <= 1e-12 * trace, "trace {} against {trace}", id.trace());
}

/// Modes full and shared cannot track (their docs: forgetting and drift need mode rows): each
/// refuses forgetting alone, drift alone and both, naming `forgetting`, and takes neither;
/// `KalmanOptions::tracking()` is true exactly when forgetting (λ < 1) or drift (q > 0) is on.
#[test]
fn modes_full_and_shared_refuse_forgetting_and_drift_alike() {
    for (forgetting, drift) in [(1.0, 0.0), (0.98, 0.0), (1.0, 1e-6), (0.98, 1e-6)] {
        let o = KalmanOptions { forgetting, drift, ..KalmanOptions::default() };
        let on = forgetting < 1.0 || drift > 0.0;
        assert_eq!(o.tracking(), on, "tracking() with λ = {forgetting}, q = {drift}");
        let full = FullKalmanIdentifierVec::<f64, 4>::from_slices(&[1, 3], &[1000.0], &[1.0], o);
        let shared = SharedKalmanIdentifierVec::<f64, 4>::from_slices(&[1, 3], &[1000.0], &[1.0], o);
        for (mode, refused) in [("full", full.err()), ("shared", shared.err())] {
            match refused {
                Some(vehid_core::Error::InvalidArgument { arg: "forgetting", .. }) => {
                    assert!(on, "mode {mode} refused λ = {forgetting}, q = {drift}")
                }
                None => assert!(!on, "mode {mode} took λ = {forgetting}, q = {drift}"),
                Some(e) => panic!("mode {mode}, λ = {forgetting}, q = {drift}: {e:?}"),
            }
        }
    }
}

/// The normalized (Lyapunov) gain `1 / Σ h x²` (Eq 5.9) has no direction to move in when the
/// regressor is zero: such a sample is taken and counted, the estimate and the gain's step
/// count stay, and the identifier then continues exactly as a twin that never saw it. With
/// and without the bias removal term `Σ_w`.
#[test]
fn lyapunov_gain_takes_a_zero_regressor_without_a_step() {
    let rows = [1usize, 3];
    let data = samples(8, 200, 0.01);
    let params = |id: &StochasticGradientVec<f64, 4>| {
        let mut t = [0.0; 8];
        id.params_into(&mut t).unwrap();
        t.map(f64::to_bits)
    };
    for noise in [[0.0; 4], [1e-2, 4e-2, 1e-2, 3e-2]] {
        let make = || StochasticGradientVec::<f64, 4>::from_slices(&rows, Gain::Lyapunov, &[0.5], &noise, 1).unwrap();
        let (mut a, mut b) = (make(), make());
        let mut e = [0.0; 2];
        for (j, (x, z)) in data.iter().enumerate() {
            if j == 100 {
                let (samples, steps, before) = (a.samples(), a.steps(), params(&a));
                a.update_into(&[0.0; 4], z.as_slice(), &[], &mut e).unwrap();
                assert_eq!((a.samples(), a.steps()), (samples + 1, steps), "Σ_w {noise:?}: counted, no step");
                assert_eq!(params(&a), before, "Σ_w {noise:?}: the estimate moved");
            }
            a.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
            b.update_into(x.as_slice(), z.as_slice(), &[], &mut e).unwrap();
        }
        assert_eq!(params(&a), params(&b), "Σ_w {noise:?}: not the twin's estimate");
        assert!(a.steps() == b.steps() && a.steps() == 200);
    }
}

/// Mode full's `*_into` read-outs refuse an `out` of the wrong length with a Shape error that
/// names `out` and the length they need: `θ` K·N values, the covariance (K·N)², the noise
/// matrix K² (three rows, where K² and 2K differ).
#[test]
fn mode_full_read_outs_name_the_length_they_need() {
    let (k, n) = (3usize, 4usize);
    let id = FullKalmanIdentifierVec::<f64, 4>::from_slices(&[0, 1, 3], &[1000.0], &[1.0], KalmanOptions::default())
        .unwrap();
    let shape = |r: Result<(), vehid_core::Error>| match r {
        Err(vehid_core::Error::Shape { arg: "out", expected, got }) => (expected, got),
        other => panic!("{other:?}"),
    };
    for (what, len) in [("params", k * n), ("covariance", k * n * k * n), ("noise", k * k)] {
        for wrong in [len - 1, len + 1] {
            let mut out = vec![0.0; wrong];
            let r = match what {
                "params" => id.params_into(&mut out),
                "covariance" => id.covariance_into(&mut out),
                _ => id.noise_into(&mut out),
            };
            assert_eq!(shape(r), (len, wrong), "{what}_into with {wrong} values");
        }
        let mut out = vec![0.0; len];
        let r = match what {
            "params" => id.params_into(&mut out),
            "covariance" => id.covariance_into(&mut out),
            _ => id.noise_into(&mut out),
        };
        assert!(r.is_ok(), "{what}_into with {len} values: {r:?}");
    }
}

/// With drift alone (λ = 1, q = 1) a risky sample is checked on the covariance the update
/// makes, `P − P x xᵀ P / s + q I`, in mode rows' standard form: the samples of
/// `risky_samples_whose_downdate_would_be_indefinite_are_refused` that the plain downdate
/// cannot take (some are refused without drift, shown here too) are all taken with the drift,
/// each leaving a covariance with a Cholesky factor.
#[test]
fn risky_samples_are_checked_with_the_drift_they_get() {
    let rows = [1usize, 3];
    let (p0, r) = (1e5, [1.0, 1e-12]);
    let mut refused_without = 0;
    for (n, x) in regressors(32, 200).into_iter().enumerate() {
        let z = V4::new(0.0, x.sum(), 0.0, 2.0 * x[0]);
        let mut e = [0.0; 2];
        let drift = KalmanOptions { drift: 1.0, max_trace: 1e12, ..opts(CovarianceForm::Standard) };
        let mut id = KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[p0], &r, drift).unwrap();
        let taken = id.update_into(x.as_slice(), z.as_slice(), &[], &mut e);
        assert!(taken.is_ok(), "sample {n}: refused with drift: {taken:?}");
        assert!(covariance8(&id).1, "sample {n}: taken, and the covariance has no Cholesky factor");
        let mut plain =
            KalmanIdentifier::<f64, 4, 2>::from_slices(&rows, &[p0], &r, opts(CovarianceForm::Standard)).unwrap();
        refused_without += usize::from(plain.update_into(x.as_slice(), z.as_slice(), &[], &mut e).is_err());
    }
    assert!(refused_without > 0, "without drift no sample of 200 was refused: the case never arose");
}

/// Bias-compensated least squares (`identify/bias_compensated.rs`) on `der(q) = a q + m der(v)`:
/// the regressor `[q, der(v)]` carries the state noise of `q` and the derivative noise of `v`,
/// so the normal equations are corrected by `N diag(σ_w,q², σ_v,v²)` (the output's noise, on
/// `der(q)`, is independent of both): `θ = (HᵀH − N diag(σ_w,q², σ_v,v²))⁻¹ Hᵀy`, computed
/// here from the samples. Every variance distinct, so that a term read with another
/// variable's noise shows.
#[test]
fn bias_compensation_reads_each_variables_own_noise() {
    use vehid_core::structure::StructureBuilder;
    let (st, names) = StructureBuilder::new(&["q", "v"], &[]).equation("q", "a*q + m*der(v)").build::<f64>().unwrap();
    assert_eq!(names.params, ["a", "m"]);
    let data = samples(21, 500, 0.0);
    // Variances a fraction of each signal's mean square (distinct fractions).
    let ms = |f: &dyn Fn(&(V4, V4)) -> f64| data.iter().map(|d| f(d) * f(d)).sum::<f64>() / data.len() as f64;
    let sw = [0.1 * ms(&|d| d.0[0]), 0.3 * ms(&|d| d.0[1])];
    let sv = [0.05 * ms(&|d| d.1[0]), 0.2 * ms(&|d| d.1[1])];
    let mut id = BiasCompensatedVec::<f64, 8>::new(st, &sw, &sv, &[1.0]).unwrap();
    let (mut hh, mut hy) = (nalgebra::Matrix2::<f64>::zeros(), nalgebra::Vector2::<f64>::zeros());
    let mut e = [0.0];
    for (x, z) in &data {
        let (xs, zs) = ([x[0], x[1]], [z[0], z[1]]);
        id.update_into(&xs, &zs, &[], &mut e).unwrap();
        let h = nalgebra::Vector2::new(x[0], z[1]);
        hh += h * h.transpose();
        hy += h * z[0];
    }
    let n = data.len() as f64;
    let corrected = hh - nalgebra::Matrix2::from_diagonal(&nalgebra::Vector2::new(n * sw[0], n * sv[1]));
    let expect = corrected.lu().solve(&hy).unwrap();
    let mut theta = [0.0; 2];
    id.params_into(&mut theta).unwrap();
    let scale = expect.abs().max();
    assert!(
        (theta[0] - expect[0]).abs().max((theta[1] - expect[1]).abs()) <= 1e-9 * scale,
        "{theta:?} against (HᵀH − N Σ)⁻¹ Hᵀy = {expect:?}"
    );
    // The correction matters here (else the comparison would show nothing).
    let plain = hh.lu().solve(&hy).unwrap();
    assert!((plain - expect).abs().max() > 1e-3 * scale, "{plain:?} vs {expect:?}");
}

/// Bias compensation of a known term (`identify/bias_compensated.rs`: the output's
/// correction `g`): on `der(q) = a q + m der(p) + 2 der(p)` (three states, the known term on
/// the last one's derivative), the known term moves to the output, `y = der(q) − 2 der(p)`,
/// whose noise `−2 v_p` is correlated with the regressor `der(p)`'s own
/// (`E[h (−2 v_p)] = (0, −2 σ_v,p²)`), so that `θ = (HᵀH − N Σ)⁻¹ (Hᵀy + 2 N σ_v,p² e₂)`,
/// computed here from the samples (θ's `m` is the true coefficient less the known 2).
#[test]
fn bias_compensation_corrects_a_known_terms_noise() {
    use vehid_core::structure::StructureBuilder;
    let (st, names) =
        StructureBuilder::new(&["q", "v", "p"], &[]).equation("q", "a*q + m*der(p) + 2*der(p)").build::<f64>().unwrap();
    assert_eq!(names.params, ["a", "m"]);
    let data = samples(22, 500, 0.0);
    let ms = |f: &dyn Fn(&(V4, V4)) -> f64| data.iter().map(|d| f(d) * f(d)).sum::<f64>() / data.len() as f64;
    let sw = [0.1 * ms(&|d| d.0[0]), 0.3 * ms(&|d| d.0[1]), 0.15 * ms(&|d| d.0[2])];
    let sv = [0.05 * ms(&|d| d.1[0]), 0.2 * ms(&|d| d.1[1]), 0.25 * ms(&|d| d.1[2])];
    let mut id = BiasCompensatedVec::<f64, 8>::new(st, &sw, &sv, &[1.0]).unwrap();
    let (mut hh, mut hy) = (nalgebra::Matrix2::<f64>::zeros(), nalgebra::Vector2::<f64>::zeros());
    let mut e = [0.0];
    for (x, z) in &data {
        id.update_into(&[x[0], x[1], x[2]], &[z[0], z[1], z[2]], &[], &mut e).unwrap();
        let h = nalgebra::Vector2::new(x[0], z[2]);
        hh += h * h.transpose();
        hy += h * (z[0] - 2.0 * z[2]);
    }
    let n = data.len() as f64;
    let corrected = hh - nalgebra::Matrix2::from_diagonal(&nalgebra::Vector2::new(n * sw[0], n * sv[2]));
    let expect = corrected.lu().solve(&(hy + nalgebra::Vector2::new(0.0, 2.0 * n * sv[2]))).unwrap();
    let mut theta = [0.0; 2];
    id.params_into(&mut theta).unwrap();
    let scale = expect.abs().max();
    assert!(
        (theta[0] - expect[0]).abs().max((theta[1] - expect[1]).abs()) <= 1e-9 * scale,
        "{theta:?} against (HᵀH − N Σ)⁻¹ (Hᵀy + 2Nσ² e₂) = {expect:?}"
    );
    // The output's correction matters here.
    let without = corrected.lu().solve(&hy).unwrap();
    assert!((without - expect).abs().max() > 1e-3 * scale, "{without:?} vs {expect:?}");
}

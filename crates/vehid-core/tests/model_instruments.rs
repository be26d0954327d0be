//! Instruments from the auxiliary model (SRIVC/RIVC, `identify/iv_model.rs`) on a
//! mass-spring-damper with a measured force: `q̇ = v`, `v̇ = a F − k q − b v` (a = 1, k = 40,
//! b = 2.5: 1.0 Hz, damping ratio 0.2), dt = 0.01 s, the force an AR(1) sequence
//! `F(k) = 0.9 F(k−1) + e(k)` held over each interval. The data are simulated by the exact
//! zero-order-hold map `exp([A B; 0 0] dt)` (a Taylor series here, not the identifier's RK4),
//! with white noise of `pct` % of each state's standard deviation on the measured `q`, `v`
//! and on the measured acceleration.
//!
//! The must-show figures are `#[ignore]`d release tests (measured values in their doc
//! comments; `cargo test -p vehid-core --release --test integration model_instruments:: --
//! --ignored --nocapture`); the normal suite holds fast versions and the exact checks.

use crate::common::{log_slope, median};
use vehid_core::identify::{
    Identifier, IvIdentifier, IvIdentifierVec, ModelIvIdentifier, ModelIvIdentifierVec, StructuredPrior,
};
use vehid_core::structure::{Structure, StructureBuilder};
use vehid_core::Error;

const DT: f64 = 0.01;
const TRUTH: [f64; 3] = [1.0, 8883.0, 18.8];
/// The force's AR(1) coefficient.
const AR: f64 = 0.5;
/// Noise on the measurements, % of each signal's standard deviation.
const PCT: f64 = 30.0;

fn msd() -> Structure<f64> {
    let (s, names) = StructureBuilder::new(&["q", "v"], &["F"])
        .equation("v", "a*F - k*q - b*v")
        .known("q", "v")
        .build::<f64>()
        .unwrap();
    assert_eq!(names.params, ["a", "k", "b"]);
    s
}

/// Seeded normals (splitmix64, Box–Muller).
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// `exp(M)` of a 3×3 matrix: Taylor to 30 terms of `M / 2⁸`, squared 8 times (exact to
/// rounding for ‖M‖ ≤ 30).
fn expm3(m: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mul = |a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]| {
        let mut c = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] = (0..3).map(|l| a[i][l] * b[l][j]).sum::<f64>();
            }
        }
        c
    };
    let scaled = m.map(|row| row.map(|v| v / 256.0));
    let mut out = [[0.0; 3]; 3];
    let mut term = [[0.0; 3]; 3];
    for i in 0..3 {
        out[i][i] = 1.0;
        term[i][i] = 1.0;
    }
    for k in 1..30 {
        term = mul(&term, &scaled).map(|row| row.map(|v| v / k as f64));
        for i in 0..3 {
            for j in 0..3 {
                out[i][j] += term[i][j];
            }
        }
    }
    for _ in 0..8 {
        out = mul(&out, &out);
    }
    out
}

/// The exact ZOH map of `q̇ = v, v̇ = a F − k q − b v`: `x⁺ = Φ x + Γ F`.
fn zoh(p: [f64; 3], dt: f64) -> ([[f64; 2]; 2], [f64; 2]) {
    let [a, k, b] = p;
    let m = [[0.0, dt, 0.0], [-k * dt, -b * dt, a * dt], [0.0, 0.0, 0.0]];
    let e = expm3(m);
    ([[e[0][0], e[0][1]], [e[1][0], e[1][1]]], [e[0][2], e[1][2]])
}

/// A noise-free sample: state, derivative, force.
type Clean = ([f64; 2], [f64; 2], f64);

/// One run: measured states, measured derivatives, inputs (row per sample).
struct Data {
    r: Vec<[f64; 2]>,
    z: Vec<[f64; 2]>,
    u: Vec<[f64; 1]>,
}

/// `n` samples of the rig with parameters `p`, noise `pct` % of each state's std (and the
/// acceleration's) on the measurements.
fn rig(p: [f64; 3], n: usize, pct: f64, seed: u64) -> Data {
    let mut rng = Rng(seed.wrapping_mul(0x2545_f491_4f6c_dd1d) ^ 0x1234_5678);
    let (phi, gam) = zoh(p, DT);
    let (mut x, mut f) = ([0.0f64; 2], 0.0f64);
    let mut clean = Vec::with_capacity(n);
    for _ in 0..n {
        f = AR * f + rng.normal();
        let xd = [x[1], p[0] * f - p[1] * x[0] - p[2] * x[1]];
        clean.push((x, xd, f));
        x = [phi[0][0] * x[0] + phi[0][1] * x[1] + gam[0] * f, phi[1][0] * x[0] + phi[1][1] * x[1] + gam[1] * f];
    }
    let std = |g: &dyn Fn(&Clean) -> f64| {
        let m = clean.iter().map(g).sum::<f64>() / n as f64;
        (clean.iter().map(|c| (g(c) - m).powi(2)).sum::<f64>() / n as f64).sqrt()
    };
    let s = [std(&|c| c.0[0]), std(&|c| c.0[1]), std(&|c| c.1[1])];
    let w = pct / 100.0;
    let mut d = Data { r: Vec::with_capacity(n), z: Vec::with_capacity(n), u: Vec::with_capacity(n) };
    for (x, xd, f) in clean {
        d.r.push([x[0] + w * s[0] * rng.normal(), x[1] + w * s[1] * rng.normal()]);
        d.z.push([xd[0], xd[1] + w * s[2] * rng.normal()]);
        d.u.push([f]);
    }
    d
}

/// The relative error, root mean square over the parameters: `√(mean_j (θ̂_j/θ_j − 1)²)`.
fn rel_err(th: &[f64]) -> f64 {
    (th.iter().zip(&TRUTH).map(|(a, b)| (a / b - 1.0).powi(2)).sum::<f64>() / 3.0).sqrt()
}

fn srivc(refresh: usize) -> ModelIvIdentifier<f64, 3, 1> {
    IvIdentifier::<f64, 3, 1>::exact(msd(), 1).unwrap().with_model_instruments(DT, 4, refresh, None).unwrap()
}

fn delayed() -> IvIdentifier<f64, 3, 1> {
    IvIdentifier::<f64, 3, 1>::exact(msd(), 1).unwrap()
}

/// Runs `id` over `d`, returning the estimate after each sample count in `marks`.
fn run_marks<I: Identifier<f64>>(id: &mut I, d: &Data, marks: &[usize]) -> Vec<[f64; 3]> {
    let mut e = [0.0];
    let mut out = vec![];
    let mut m = 0;
    for k in 0..d.r.len() {
        id.update_into(&d.r[k], &d.z[k], &d.u[k], &mut e).unwrap();
        while m < marks.len() && k + 1 == marks[m] {
            let mut th = [0.0; 3];
            id.params_into(&mut th).unwrap();
            out.push(th);
            m += 1;
        }
    }
    out
}

/// (c) With a fixed auxiliary model (`theta_aux` given, `refresh = 0`) and the exact start,
/// every estimate is the batch IV estimate `(Σ ζ hᵀ)⁻¹ Σ ζ y` whose instruments
/// `ζ = [F, −q̂, −v̂]` come from the auxiliary model simulated here by the exact ZOH map
/// (the identifier uses RK4: the two agree to `O((|λ| dt)⁵)`), from `x̂(1) = Φ r(0) + Γ F(0)`.
#[test]
fn fixed_model_instruments_are_batch_iv_with_the_simulated_instruments() {
    let d = rig(TRUTH, 3000, 10.0, 7);
    let aux = [1.1, 8000.0, 22.0];
    for substeps in [4u32, 16] {
        let mut id = IvIdentifier::<f64, 3, 1>::exact(msd(), 1)
            .unwrap()
            .with_model_instruments(DT, substeps, 0, Some(&aux))
            .unwrap();
        let (phi, gam) = zoh(aux, DT);
        let mut xh = [0.0; 2];
        let (mut c, mut b) = (nalgebra::Matrix3::<f64>::zeros(), nalgebra::Vector3::<f64>::zeros());
        let mut e = [0.0];
        let mut worst = 0.0f64;
        for k in 0..d.r.len() {
            id.update_into(&d.r[k], &d.z[k], &d.u[k], &mut e).unwrap();
            let f = d.u[k][0];
            if k >= 1 {
                let h = nalgebra::Vector3::new(f, -d.r[k][0], -d.r[k][1]);
                let zeta = nalgebra::Vector3::new(f, -xh[0], -xh[1]);
                c += zeta * h.transpose();
                b += zeta * d.z[k][1];
            }
            let from = if k == 0 { d.r[0] } else { xh };
            xh = [
                phi[0][0] * from[0] + phi[0][1] * from[1] + gam[0] * f,
                phi[1][0] * from[0] + phi[1][1] * from[1] + gam[1] * f,
            ];
            if k >= 10 && !id.inner().starting() {
                let want = c.lu().solve(&b).unwrap();
                let mut th = [0.0; 3];
                id.params_into(&mut th).unwrap();
                for j in 0..3 {
                    worst = worst.max((th[j] - want[j]).abs() / want[j].abs());
                }
            }
        }
        let tol = if substeps == 4 { 2e-5 } else { 1e-7 };
        assert!(worst < tol, "substeps {substeps}: worst relative difference {worst:e}");
        assert_eq!((id.adopted(), id.refused(), id.restarts()), (0, 0, 0));
        assert_eq!(id.theta_aux().unwrap(), &aux);
    }
}

/// (a), fast: the error falls like 1/√N (10 seeds, 10⁴ to 10⁵ samples).
#[test]
fn model_instruments_error_falls_like_one_over_root_n() {
    let marks = [10_000usize, 30_000, 100_000];
    let mut errs = vec![vec![]; marks.len()];
    for seed in 0..10 {
        let d = rig(TRUTH, marks[marks.len() - 1], PCT, seed);
        for (j, th) in run_marks(&mut srivc(100), &d, &marks).iter().enumerate() {
            errs[j].push(rel_err(th));
        }
    }
    let med: Vec<f64> = errs.iter().map(|v| median(v)).collect();
    let slope = log_slope(&marks, &med);
    eprintln!("median relative error {med:?}, slope {slope:.3}");
    assert!((-0.65..=-0.35).contains(&slope), "slope {slope}");
}

/// (b), fast: on the same data the auxiliary model's instruments beat the delayed regressors
/// (10 seeds, 3·10⁴ samples).
#[test]
fn model_instruments_beat_the_delayed_regressors() {
    let (mut a, mut b) = (vec![], vec![]);
    for seed in 100..110 {
        let d = rig(TRUTH, 30_000, PCT, seed);
        a.push(rel_err(&run_marks(&mut srivc(100), &d, &[30_000])[0]));
        b.push(rel_err(&run_marks(&mut delayed(), &d, &[30_000])[0]));
    }
    let (ma, mb) = (median(&a), median(&b));
    eprintln!("median relative error: model {ma:.4e}, delayed {mb:.4e}, ratio {:.3}", ma / mb);
    assert!(ma < 0.9 * mb, "model {ma} delayed {mb}");
}

/// The must-show figures (release; 50 seeds from `VEHID_SEED_BASE`, default 1000): (a) the
/// consistency slope of the median relative error over 10^3.5 … 10^5.5 samples, and (b) the
/// median error against the delayed regressors' on the same data, at 30 % noise. Measured on
/// seeds 13000–13049 (not used while building it): median relative error 0.0234, 0.0111,
/// 0.0064, 0.0041, 0.0022 (slope −0.50) against the delayed regressors' 0.0264, 0.0125,
/// 0.0088, 0.0057, 0.0030 (slope −0.45): ratios 0.89, 0.89, 0.73, 0.72, 0.72; better on 34/50
/// seeds at 316,228 samples. Seeds 7000, 9000, 11000: slopes −0.49, −0.52, −0.46.
#[test]
#[ignore]
fn must_show_srivc_figures() {
    const SEEDS: u64 = 50;
    let base: u64 = std::env::var("VEHID_SEED_BASE").ok().and_then(|v| v.parse().ok()).unwrap_or(1000);
    let marks = [3_162usize, 10_000, 31_623, 100_000, 316_228];
    let mut errs = vec![vec![]; marks.len()];
    let mut errd = vec![vec![]; marks.len()];
    let mut wins = 0;
    let mut last = vec![];
    for seed in base..base + SEEDS {
        let d = rig(TRUTH, marks[marks.len() - 1], PCT, seed);
        let a = run_marks(&mut srivc(100), &d, &marks);
        let b = run_marks(&mut delayed(), &d, &marks);
        for j in 0..marks.len() {
            errs[j].push(rel_err(&a[j]));
            errd[j].push(rel_err(&b[j]));
        }
        wins += usize::from(rel_err(&a[marks.len() - 1]) < rel_err(&b[marks.len() - 1]));
        last.push(a[marks.len() - 1]);
    }
    let ms: Vec<f64> = errs.iter().map(|v| median(v)).collect();
    let md: Vec<f64> = errd.iter().map(|v| median(v)).collect();
    let (ss, sd) = (log_slope(&marks, &ms), log_slope(&marks, &md));
    let ratios: Vec<f64> = ms.iter().zip(&md).map(|(a, b)| a / b).collect();
    eprintln!("seeds {base}..{}: N {marks:?}", base + SEEDS);
    eprintln!("model   median rel. error {ms:.5?}, slope {ss:.3}");
    eprintln!("delayed median rel. error {md:.5?}, slope {sd:.3}");
    eprintln!("ratio model/delayed {ratios:.3?}; model better on {wins}/{SEEDS} seeds at N = {}", marks[4]);
    // Bias check: each parameter's mean relative error at the largest N, against its standard
    // error over the seeds (a bias would show as |mean| ≫ its standard error).
    for j in 0..3 {
        let v: Vec<f64> = last.iter().map(|t| t[j] / TRUTH[j] - 1.0).collect();
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt();
        eprintln!("param {j}: mean rel. error {m:+.5}, std {sd:.5}, t {:.2}", m / (sd / (v.len() as f64).sqrt()));
    }
    assert!((-0.6..=-0.4).contains(&ss), "slope {ss}");
    assert!(ratios[2..].iter().all(|&r| r < 0.9), "{ratios:?}");
}

/// (d) Construction errors name the argument and the fix; stability is judged on the linear
/// part (an offset does not make a stable rig unstable).
#[test]
fn construction_errors_name_the_argument() {
    let arg = |r: Result<ModelIvIdentifier<f64, 3, 1>, Error>| match r {
        Err(Error::InvalidArgument { arg, .. }) => arg,
        other => panic!("{other:?}"),
    };
    let no_input = Structure::<f64>::full_rows(2, &[1]).unwrap();
    let err = IvIdentifier::<f64, 3, 1>::exact(no_input, 1).unwrap().with_model_instruments(DT, 1, 10, None);
    let Err(Error::InvalidArgument { arg: "instruments", expected }) = err else { panic!("{err:?}") };
    assert!(expected.contains("measured input") && expected.contains("delayed regressors"), "{expected}");
    let (incomplete, _) =
        StructureBuilder::new(&["q", "v"], &["F"]).equation("v", "a*F - k*q - b*v").build::<f64>().unwrap();
    assert_eq!(arg(IvIdentifier::exact(incomplete, 1).unwrap().with_model_instruments(DT, 1, 10, None)), "structure");
    assert_eq!(arg(IvIdentifier::exact(msd(), 1).unwrap().with_model_instruments(0.0, 1, 10, None)), "dt");
    assert_eq!(arg(IvIdentifier::exact(msd(), 1).unwrap().with_model_instruments(DT, 0, 10, None)), "substeps");
    assert_eq!(arg(IvIdentifier::exact(msd(), 1).unwrap().with_model_instruments(DT, 1, 0, None)), "refresh");
    // Negative damping: an unstable auxiliary model is refused.
    let unstable = [1.0, 40.0, -0.5];
    assert_eq!(
        arg(IvIdentifier::exact(msd(), 1).unwrap().with_model_instruments(DT, 1, 10, Some(&unstable))),
        "theta_aux"
    );
    let err = IvIdentifier::<f64, 3, 1>::exact(msd(), 1).unwrap().with_model_instruments(DT, 1, 0, Some(&[1.0]));
    assert!(matches!(err, Err(Error::Shape { arg: "theta_aux", .. })), "{err:?}");
    // Stability is the linear part's: a constant force `c` moves the state without changing
    // Φ, so the rig with an offset of 10⁴ (a step of c·dt² ≈ 1 in q per sample from rest) is as
    // stable as without one, and negative damping as unstable.
    let (offset, _) = StructureBuilder::new(&["q", "v"], &["F"])
        .equation("v", "a*F - k*q - b*v + c")
        .known("q", "v")
        .build::<f64>()
        .unwrap();
    let with = |theta: [f64; 4]| {
        IvIdentifier::<f64, 4, 1>::exact(offset, 1).unwrap().with_model_instruments(DT, 4, 10, Some(&theta))
    };
    assert!(with([1.0, 8883.0, 18.8, 1e4]).is_ok(), "a stable rig with an offset refused");
    assert!(matches!(with([1.0, 8883.0, -18.8, 1e4]), Err(Error::InvalidArgument { arg: "theta_aux", .. })));
}

/// (d) An estimate with unstable poles (data of a rig with negative damping) is never adopted
/// as the auxiliary model: the previous one stays, the refusals are counted, nothing blows up.
#[test]
fn unstable_estimates_keep_the_previous_auxiliary_model() {
    let bad = [1.0, 40.0, -0.3];
    let d = rig(bad, 2000, 1.0, 3);
    let start = [1.0, 40.0, 2.5];
    let mut id =
        IvIdentifier::<f64, 3, 1>::exact(msd(), 1).unwrap().with_model_instruments(DT, 1, 50, Some(&start)).unwrap();
    let th = &run_marks(&mut id, &d, &[2000])[0];
    assert!(th[2] < 0.0, "the estimate found the negative damping: {th:?}");
    assert!(id.refused() >= 30 && id.adopted() == 0, "refused {} adopted {}", id.refused(), id.adopted());
    assert_eq!(id.theta_aux().unwrap(), &start);
    assert!(id.state_aux().unwrap().iter().all(|v| v.is_finite()));
    // Without an initial model: the delayed regressors stay the instruments.
    let mut id = srivc(50);
    run_marks(&mut id, &d, &[2000]);
    assert!(id.theta_aux().is_none() && id.state_aux().is_none() && id.refused() > 0);
}

/// (d) Rejected samples change nothing, the auxiliary state included: a NaN, a wrong length,
/// and a vanishing instrument correlation `s = r + hᵀPζ` (Error::Singular).
#[test]
fn rejected_samples_change_nothing() {
    let d = rig(TRUTH, 600, 10.0, 5);
    let mut id = IvIdentifier::<f64, 3, 1>::new(msd(), 1, StructuredPrior::Scalar(10.0), None, &[1.0])
        .unwrap()
        .with_model_instruments(DT, 1, 100, Some(&[1.0, 40.0, 2.5]))
        .unwrap();
    run_marks(&mut id, &d, &[600]);
    assert!(id.state_aux().is_some());
    let state = |id: &ModelIvIdentifier<f64, 3, 1>| format!("{id:?}");
    let before = state(&id);
    let mut e = [0.0];
    assert!(id.update_into(&[f64::NAN, 0.0], &[0.0, 0.0], &[0.1], &mut e).is_err());
    assert!(id.update_into(&[0.0, 0.0], &[0.0, 0.0], &[0.1, 0.2], &mut e).is_err());
    assert!(id.update_into(&[0.0, 0.0, 0.0], &[0.0, 0.0], &[0.1], &mut e).is_err());
    assert_eq!(state(&id), before);
    // s = r + hᵀ P ζ with h = [0, 0, −v] (F = 0, q = 0): v = r / (P ζ)₂ makes it vanish.
    let xh = id.state_aux().unwrap().to_vec();
    let zeta = nalgebra::Vector3::new(0.0, -xh[0], -xh[1]);
    let pz = id.inner().filter(0).p() * zeta;
    let v = 1.0 / pz[2];
    let err = id.update_into(&[0.0, v], &[0.0, 0.0], &[0.0], &mut e).unwrap_err();
    assert!(matches!(err, Error::Singular { .. }), "{err:?}");
    assert_eq!(state(&id), before);
}

/// Serialized and restored, it continues bit for bit; a corrupt auxiliary state is refused.
#[test]
fn it_round_trips_and_continues_bit_for_bit() {
    let d = rig(TRUTH, 1500, 10.0, 9);
    let mut a = IvIdentifierVec::<f64, 3>::exact(msd(), 1).unwrap().with_model_instruments(DT, 2, 100, None).unwrap();
    let mut e = [0.0];
    for k in 0..700 {
        a.update_into(&d.r[k], &d.z[k], &d.u[k], &mut e).unwrap();
    }
    assert!(a.adopted() > 0);
    let bytes = postcard::to_allocvec(&a).unwrap();
    let mut b: ModelIvIdentifierVec<f64, 3> = postcard::from_bytes(&bytes).unwrap();
    for k in 700..1500 {
        a.update_into(&d.r[k], &d.z[k], &d.u[k], &mut e).unwrap();
        b.update_into(&d.r[k], &d.z[k], &d.u[k], &mut e).unwrap();
    }
    // Everything but the per-group step's scratch copy of the filters (serialized empty).
    let state = |id: &ModelIvIdentifierVec<f64, 3>| {
        let mut th = [0.0; 3];
        id.params_into(&mut th).unwrap();
        let f = id.inner().filter(0);
        format!(
            "{th:?} {:?} {:?} {:?} {:?} {:?}",
            f.p(),
            f.instrument_moment(),
            id.theta_aux(),
            id.state_aux(),
            (id.adopted(), id.refused(), id.restarts(), id.samples())
        )
    };
    assert_eq!(state(&a), state(&b));
    // The last value of the encoding is `restarts`; before it the auxiliary model's fields.
    // A NaN in the serialized dt (f64 little-endian inside postcard) must be refused:
    // flip every 8-byte window holding dt's bits and check the corrupt copy fails to load.
    let dt_bits = DT.to_le_bytes();
    let at = bytes.windows(8).rposition(|w| w == dt_bits).expect("dt in the encoding");
    let mut bad = bytes.clone();
    bad[at..at + 8].copy_from_slice(&(-1.0f64).to_le_bytes());
    assert!(postcard::from_bytes::<ModelIvIdentifierVec<f64, 3>>(&bad).is_err());
}

/// f32 works (generic over the scalar).
#[test]
fn model_instruments_in_f32() {
    let (s, _) = StructureBuilder::new(&["q", "v"], &["F"])
        .equation("v", "a*F - k*q - b*v")
        .known("q", "v")
        .build::<f32>()
        .unwrap();
    let d = rig(TRUTH, 20_000, 5.0, 21);
    let mut id = IvIdentifier::<f32, 3, 1>::exact(s, 1).unwrap().with_model_instruments(0.01, 1, 100, None).unwrap();
    let mut e = [0.0f32];
    for k in 0..d.r.len() {
        let c = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<_>>();
        id.update_into(&c(&d.r[k]), &c(&d.z[k]), &c(&d.u[k]), &mut e).unwrap();
    }
    let mut th = [0.0f32; 3];
    id.params_into(&mut th).unwrap();
    let th64 = th.map(f64::from);
    assert!(rel_err(&th64) < 0.05, "{th:?}");
    assert!(id.adopted() > 0);
}

/// (d) The auxiliary model's stability test (run on `theta_aux` at construction and on every
/// candidate later) judges the dynamics whatever the number of measured inputs: the rig's
/// spring and damper driven by one, two and three forces, each with its own gain, take a
/// damped `theta_aux` (b = 2.5) and refuse one with negative damping (b = −0.5), naming
/// `theta_aux`.
#[test]
fn the_stability_test_holds_for_any_number_of_inputs() {
    fn check<const P: usize>(inputs: &[&str]) {
        let drive: Vec<String> = inputs.iter().enumerate().map(|(i, f)| format!("g{i}*{f}")).collect();
        let (s, names) = StructureBuilder::new(&["q", "v"], inputs)
            .equation("v", &format!("{} - k*q - b*v", drive.join(" + ")))
            .known("q", "v")
            .build::<f64>()
            .unwrap();
        assert_eq!(names.params.len(), P);
        let theta = |b: f64| -> Vec<f64> {
            names
                .params
                .iter()
                .map(|p| {
                    if p == "k" {
                        40.0
                    } else if p == "b" {
                        b
                    } else {
                        1.0
                    }
                })
                .collect()
        };
        let make =
            |t: &[f64]| IvIdentifier::<f64, P, 1>::exact(s, 1).unwrap().with_model_instruments(DT, 1, 10, Some(t));
        let n = inputs.len();
        assert!(make(&theta(2.5)).is_ok(), "{n} inputs: a damped model refused");
        let err = make(&theta(-0.5));
        assert!(matches!(err, Err(Error::InvalidArgument { arg: "theta_aux", .. })), "{n} inputs: {:?}", err.err());
    }
    check::<3>(&["F"]);
    check::<4>(&["F", "G"]);
    check::<5>(&["F", "G", "H"]);
}

#[test]
fn the_stability_test_holds_for_any_number_of_states() {
    // The model-instrument stability test on two, three and four states (a spring-damper
    // driven through one or two first-order lags): a damped theta_aux taken, negative
    // damping refused naming it. Its simulation must size the state and output buffers
    // from the structure, not for two states.
    fn check(states: &[&str], known: &[(&str, &str)], drive: &str) {
        let mut b =
            StructureBuilder::new(states, &["F"]).equation("v", &format!("{drive} - k*q - b*v")).known("q", "v");
        for (state, rhs) in known {
            b = b.known(state, rhs);
        }
        let (s, names) = b.build::<f64>().unwrap();
        assert_eq!(names.params, ["k", "b"]);
        let make =
            |t: &[f64]| IvIdentifier::<f64, 2, 1>::exact(s, 1).unwrap().with_model_instruments(DT, 1, 10, Some(t));
        let n = states.len();
        assert!(make(&[40.0, 2.5]).is_ok(), "{n} states: a damped model refused");
        let err = make(&[40.0, -0.5]);
        assert!(matches!(err, Err(Error::InvalidArgument { arg: "theta_aux", .. })), "{n} states: {:?}", err.err());
    }
    check(&["q", "v"], &[], "F");
    check(&["q", "v", "w"], &[("w", "F - 3*w")], "w");
    check(&["q", "v", "w", "y"], &[("w", "F - 3*w"), ("y", "w - 5*y")], "y");
}

/// A read-out of an identifier into a buffer.
type ReadOut = dyn Fn(&dyn Identifier<f64>, &mut [f64]) -> vehid_core::Result<()>;

/// The read-outs are those of the instrumental-variable identifier inside (`inner()`),
/// entry for entry: dims (2 states, 1 input, 1 equation, 3 parameters), rows (the equation of
/// `v`), θ̂, samples, `P`, `R`, the residual sums and the groups; `settings()` what it was
/// built with; one refresh per `refresh` samples once the estimate exists (adopted or refused).
#[test]
fn the_read_outs_are_the_inner_identifiers() {
    let d = rig(TRUTH, 1500, 10.0, 11);
    let refresh = 100;
    let mut id = IvIdentifier::<f64, 3, 1>::exact(msd(), 1)
        .unwrap()
        .with_model_instruments(DT, 3, refresh, Some(&[1.1, 8000.0, 22.0]))
        .unwrap();
    assert_eq!(id.settings(), (DT, 3, refresh));
    let mut e = [0.0];
    let mut started = None;
    for k in 0..d.r.len() {
        id.update_into(&d.r[k], &d.z[k], &d.u[k], &mut e).unwrap();
        if started.is_none() && !id.inner().starting() {
            started = Some(k);
        }
    }
    let dims = id.dims();
    assert_eq!((dims.states, dims.inputs, dims.equations, dims.params), (2, 1, 1, 3));
    assert_eq!(id.rows(), &[1]);
    assert_eq!(id.rows(), id.inner().rows());
    assert_eq!(id.samples(), d.r.len() as u64);
    let inner = id.inner();
    let pair = |f: &ReadOut, len: usize| {
        let (mut a, mut b) = (vec![0.0; len], vec![f64::NAN; len]);
        f(&id, &mut a).unwrap();
        f(inner, &mut b).unwrap();
        assert!(a.iter().all(|v| v.is_finite()));
        assert_eq!(a, b);
    };
    pair(&|i, o| i.params_into(o), 3);
    pair(&|i, o| i.covariance_into(o), 9);
    pair(&|i, o| i.noise_into(o), 1);
    pair(&|i, o| i.residuals_into(&mut o[..1], &mut [0.0]), 1);
    let (mut gp, mut ge) = ([9; 3], [9; 1]);
    id.groups_into(&mut gp, &mut ge).unwrap();
    let (mut gp2, mut ge2) = ([7; 3], [7; 1]);
    inner.groups_into(&mut gp2, &mut ge2).unwrap();
    assert_eq!((gp, ge), (gp2, ge2));
    // The samples after the first estimate, counted from the one that made it.
    let after = d.r.len() - started.unwrap();
    assert_eq!(id.adopted() + id.refused(), (after / refresh) as u64);
}

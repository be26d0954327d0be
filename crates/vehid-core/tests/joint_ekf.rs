//! The joint state and parameter EKF on the quarter car with white noise
//! on the measured state (road σ_u 0.1, derivative noise σ_v 0.1, dt 0.05 s), against the
//! thesis' Kalman rows identifier.
//!
//! The must-show figures are `#[ignore]`d release tests (their measured values in their doc
//! comments; run them with
//! `cargo test -p vehid-core --release --test joint_ekf -- --ignored --nocapture`); the normal
//! suite holds a fast convergence check and the exact checks.

use nalgebra::{SMatrix, SVector};
use vehid_core::identify::{posterior_stats, EkfNoise, Identifier, JointEkf, KalmanIdentifier};
use vehid_core::model::{auto_substeps, rk4_map, zoh, QuarterCar};
use vehid_core::structure::{Basis, Structure, Term, Var};
use vehid_core::Error;

/// Counts this thread's allocations (the "no allocation per sample" invariant, checked here
/// rather than in `no_alloc.rs`, whose identifiers list other work is editing).
struct Counting;

thread_local! {
    static ALLOCATIONS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

// SAFETY: forwards to the system allocator; only counts.
unsafe impl std::alloc::GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { std::alloc::System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

mod common;
use common::{median, quarter_sampled as quarter, run, time_updates, xi_rows, DERIV, DT, ROAD};

/// The quarter car's physical structure with `m` known: `k2/M, b/M, M, k1`.
fn physical() -> Structure<f64> {
    *QuarterCar::structure([None, Some(1.0), None, None, None]).unwrap().structure()
}

/// The thesis' full rows 1 and 3 with the kinematic rows `ż = v` as known equations.
fn full_rows() -> Structure<f64> {
    let mut s = Structure::<f64>::full_rows(4, &[1, 3]).unwrap();
    for (row, from) in [(0, 1u8), (2, 3)] {
        s.push_equation(row, &[Term { coef: 1.0, param: None, basis: Basis::Var(Var::State(from)) }]).unwrap();
    }
    s
}

fn noise(pct: f64) -> EkfNoise<f64, 4> {
    let car = QuarterCar::<f64>::thesis();
    let g = SVector::<f64, 4>::from_column_slice(car.model().b().as_slice());
    EkfNoise::from_sigmas(pct / 100.0 * ROAD, DERIV, g, ROAD)
}

/// The rows 1 and 3 of `A` implied by parameters `p` of `s` (its derivative on unit vectors).
fn implied_rows(s: &Structure<f64>, p: &[f64]) -> [f64; 8] {
    let mut rows = [0.0; 8];
    for j in 0..4 {
        let mut e = [0.0; 4];
        e[j] = 1.0;
        let mut col = [0.0; 4];
        s.derivative(p, &e, &[], &mut col);
        rows[j] = col[1];
        rows[4 + j] = col[3];
    }
    rows
}

/// The prior: each parameter at half or 1.5 times its true value (alternately), with a
/// standard deviation of 100 % of the guess.
fn guess(truth: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let g: Vec<f64> = truth.iter().enumerate().map(|(j, t)| t * if j % 2 == 0 { 0.5 } else { 1.5 }).collect();
    let v = g.iter().map(|g| g * g).collect();
    (g, v)
}

/// True physical parameters `k2/M, b/M, M, k1`.
const PHYS_TRUTH: [f64; 4] = [5.0, 4.0, 10.0, 90.0];

fn ekf_physical(pct: f64, substeps: u32) -> JointEkf<f64, 4, 9> {
    let (g, v) = guess(&PHYS_TRUTH);
    JointEkf::new(physical(), &g, &v, 1.0, noise(pct), DT, substeps).unwrap()
}

fn ekf_rows(pct: f64, substeps: u32) -> JointEkf<f64, 4, 13> {
    let (g, v) = guess(QuarterCar::<f64>::thesis().theta().transpose().as_slice());
    JointEkf::new(full_rows(), &g, &v, 1.0, noise(pct), DT, substeps).unwrap()
}

fn xi_ekf_physical(x: &[f64], z: &[f64], pct: f64, substeps: u32) -> f64 {
    xi_rows(&implied_rows(&physical(), &run(&mut ekf_physical(pct, substeps), x, z)))
}

fn xi_ekf_rows(x: &[f64], z: &[f64], pct: f64, substeps: u32) -> f64 {
    xi_rows(&implied_rows(&full_rows(), &run(&mut ekf_rows(pct, substeps), x, z)))
}

/// ξ of the thesis' identifier (Eq 4.3–4.7: p0 = 1000, R from the noise levels).
fn rows_kalman(x: &[f64], z: &[f64]) -> f64 {
    let r = QuarterCar::<f64>::thesis().model().row_noise_var::<2>(ROAD, DERIV).unwrap();
    let mut id = KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r).unwrap();
    xi_rows(&run(&mut id, x, z))
}

/// Convergence at 8 % state noise on seeds 1–3 (used while developing), 40,000 samples:
/// measured ξ of the implied rows 1.0e-5, 1.4e-5, 2.4e-5 (physical structure) and 0.0020,
/// 0.0015, 0.0002 (full rows), where the thesis' Kalman rows identifier on the same samples
/// has 4.6, 5.0, 5.0. Asserted with a margin of about 10×: ξ ≤ 3e-4 (physical), ≤ 0.02
/// (rows), and the Kalman identifier above 4 (the data are the biased case).
#[test]
fn converges_at_8_percent_state_noise() {
    for seed in 1..=3u64 {
        let (x, z, sub) = quarter(40_000, 8.0, seed);
        let (p, r, k) = (xi_ekf_physical(&x, &z, 8.0, sub), xi_ekf_rows(&x, &z, 8.0, sub), rows_kalman(&x, &z));
        eprintln!("seed {seed}: ξ physical {p:.2e}, rows {r:.2e}, Kalman rows {k:.2}");
        assert!(p <= 3e-4, "seed {seed}: physical ξ {p}");
        assert!(r <= 0.02, "seed {seed}: rows ξ {r}");
        assert!(k > 4.0, "seed {seed}: Kalman ξ {k}");
    }
}

/// f32 runs the same code: the physical structure at 8 %, 20,000 samples.
#[test]
fn converges_in_f32() {
    let (x, z, sub) = quarter(20_000, 8.0, 4);
    let ps = QuarterCar::<f32>::structure([None, Some(1.0), None, None, None]).unwrap();
    let (g, v) = guess(&PHYS_TRUTH);
    let (g, v): (Vec<f32>, Vec<f32>) = (g.iter().map(|&a| a as f32).collect(), v.iter().map(|&a| a as f32).collect());
    let n = noise(8.0);
    let n32 = EkfNoise::<f32, 4>::from_sigmas(0.008, DERIV as f32, n.road_gain.map(|a| a as f32), ROAD as f32);
    let mut id = JointEkf::<f32, 4, 9>::new(*ps.structure(), &g, &v, 1.0, n32, DT as f32, sub).unwrap();
    let mut e = [0.0f32; 2];
    for (xk, zk) in x.chunks(4).zip(z.chunks(4)) {
        let (xf, zf): (Vec<f32>, Vec<f32>) =
            (xk.iter().map(|&a| a as f32).collect(), zk.iter().map(|&a| a as f32).collect());
        id.update_into(&xf, &zf, &[], &mut e).unwrap();
    }
    let mut th = [0.0f32; 4];
    id.params_into(&mut th).unwrap();
    let th: Vec<f64> = th.iter().map(|&a| a as f64).collect();
    let xi = xi_rows(&implied_rows(&physical(), &th));
    assert!(xi < 1e-3, "{th:?}: ξ {xi}");
}

fn bits<T: core::fmt::Debug>(v: &T) -> String {
    // Debug prints every float exactly (shortest round trip, -0 apart from 0).
    format!("{v:?}")
}

/// A rejected sample (NaN, inf, a value that overflows the prediction, wrong lengths)
/// returns a typed error and leaves the filter as it was, to the bit: it then continues
/// exactly as a twin that never saw the sample.
#[test]
fn rejected_samples_change_nothing() {
    let (x, z, sub) = quarter(600, 8.0, 5);
    let mut id = ekf_physical(8.0, sub);
    let mut twin = id;
    let mut e = [0.0; 2];
    for (k, (xk, zk)) in x.chunks(4).zip(z.chunks(4)).enumerate() {
        if k % 97 == 50 {
            let before = bits(&id);
            let nan_r = id.update_into(&[0.0, f64::NAN, 0.0, 0.0], zk, &[], &mut e);
            assert_eq!(nan_r, Err(Error::NonFinite { arg: "r_k", index: 1 }));
            let inf_z = id.update_into(xk, &[0.0, 0.0, 0.0, f64::INFINITY], &[], &mut e);
            assert_eq!(inf_z, Err(Error::NonFinite { arg: "z_k", index: 3 }));
            assert!(id.update_into(&[1e300, 0.0, 0.0, 0.0], zk, &[], &mut e).is_err());
            assert!(matches!(id.update_into(&xk[..3], zk, &[], &mut e), Err(Error::Shape { arg: "r_k", .. })));
            assert!(matches!(id.update_into(xk, zk, &[1.0], &mut e), Err(Error::Shape { arg: "u_k", .. })));
            assert!(matches!(id.update_into(xk, zk, &[], &mut [0.0; 3]), Err(Error::Shape { arg: "e", .. })));
            assert_eq!(bits(&id), before, "sample {k}");
        }
        id.update_into(xk, zk, &[], &mut e).unwrap();
        twin.update_into(xk, zk, &[], &mut e).unwrap();
    }
    assert_eq!(bits(&id), bits(&twin));
    assert_eq!(id.samples(), 600);
}

/// No allocation per sample (after the data are made), both structures.
#[test]
fn updates_do_not_allocate() {
    let (x, z, sub) = quarter(300, 8.0, 7);
    let (mut a, mut b) = (ekf_physical(8.0, sub), ekf_rows(8.0, sub));
    let mut e = [0.0; 2];
    let before = ALLOCATIONS.with(|c| c.get());
    for (xk, zk) in x.chunks(4).zip(z.chunks(4)) {
        a.update_into(xk, zk, &[], &mut e).unwrap();
        b.update_into(xk, zk, &[], &mut e).unwrap();
    }
    assert_eq!(ALLOCATIONS.with(|c| c.get()) - before, 0);
}

/// Arguments out of range are typed errors naming the argument.
#[test]
fn bad_arguments_are_typed_errors() {
    let (g, v) = guess(&PHYS_TRUTH);
    let ok = noise(8.0);
    let make = |s: Structure<f64>, g: &[f64], v: &[f64], x0: f64, n: EkfNoise<f64, 4>, dt: f64, sub: u32| {
        JointEkf::<f64, 4, 9>::new(s, g, v, x0, n, dt, sub).map(|_| ())
    };
    assert!(make(physical(), &g, &v, 1.0, ok, DT, 5).is_ok());
    let arg = |r: Result<(), Error>| match r {
        Err(Error::InvalidArgument { arg, .. } | Error::Shape { arg, .. } | Error::NonFinite { arg, .. }) => arg,
        other => panic!("{other:?}"),
    };
    let neg = |f: fn(&mut EkfNoise<f64, 4>)| {
        let mut n = ok;
        f(&mut n);
        n
    };
    assert_eq!(arg(make(physical(), &g, &v, 1.0, neg(|n| n.state_var[2] = -1e-4), DT, 5)), "state_var");
    assert_eq!(arg(make(physical(), &g, &v, 1.0, neg(|n| n.state_var[0] = 0.0), DT, 5)), "state_var");
    assert_eq!(arg(make(physical(), &g, &v, 1.0, neg(|n| n.deriv_var[1] = -0.01), DT, 5)), "deriv_var");
    assert_eq!(arg(make(physical(), &g, &v, 1.0, neg(|n| n.road_var = -0.01), DT, 5)), "road_var");
    assert_eq!(arg(make(physical(), &g, &v, 1.0, neg(|n| n.param_walk_var = -1.0), DT, 5)), "param_walk_var");
    assert_eq!(arg(make(physical(), &g, &v, 1.0, neg(|n| n.road_gain[1] = f64::NAN), DT, 5)), "road_gain");
    let mut v_neg = v.clone();
    v_neg[2] = -1.0;
    assert_eq!(arg(make(physical(), &g, &v_neg, 1.0, ok, DT, 5)), "p0_var");
    assert_eq!(arg(make(physical(), &g[..3], &v, 1.0, ok, DT, 5)), "p0");
    assert_eq!(arg(make(physical(), &g, &v[..3], 1.0, ok, DT, 5)), "p0_var");
    assert_eq!(arg(make(physical(), &[f64::NAN, 1.0, 1.0, 1.0], &v, 1.0, ok, DT, 5)), "p0");
    assert_eq!(arg(make(physical(), &g, &v, -1.0, ok, DT, 5)), "x0_var");
    assert_eq!(arg(make(physical(), &g, &v, 1.0, ok, 0.0, 5)), "dt");
    assert_eq!(arg(make(physical(), &g, &v, 1.0, ok, DT, 0)), "substeps");
    // The augmented dimension must be states + params + 1 (here 13, not 9).
    assert_eq!(
        make(full_rows(), &[0.0; 8], &[1.0; 8], 1.0, ok, DT, 5),
        Err(Error::Shape { arg: "D", expected: 13, got: 9 })
    );
    // Every state needs an equation (the full rows without ż = v).
    let bare = Structure::<f64>::full_rows(4, &[1, 3]).unwrap();
    let r = JointEkf::<f64, 4, 13>::new(bare, &[0.0; 8], &[1.0; 8], 1.0, ok, DT, 5);
    assert!(matches!(r, Err(Error::InvalidArgument { arg: "structure", .. })), "{r:?}");
    let three = Structure::<f64>::full_rows(3, &[1]).unwrap();
    let r = JointEkf::<f64, 4, 8>::new(three, &[0.0; 3], &[1.0; 3], 1.0, ok, DT, 5);
    assert!(matches!(r, Err(Error::Shape { arg: "structure", expected: 4, got: 3 })), "{r:?}");
}

/// The rest of the interface: dims, rows, the parameters' covariance (symmetric, the prior
/// at the start), the equations' noise, one group, trace, covariance reset.
#[test]
fn identifier_interface() {
    let (x, z, sub) = quarter(200, 8.0, 6);
    let mut id = ekf_rows(8.0, sub);
    let d = id.dims();
    assert_eq!((d.states, d.inputs, d.equations, d.params), (4, 0, 2, 8));
    assert_eq!(id.rows(), &[1, 3]);
    let (_, v) = guess(QuarterCar::<f64>::thesis().theta().transpose().as_slice());
    assert_eq!(id.trace(), Some(v.iter().sum()));
    run(&mut id, &x, &z);
    let mut c = [0.0; 64];
    id.covariance_into(&mut c).unwrap();
    for a in 0..8 {
        assert!(c[a * 8 + a] > 0.0);
        for b in 0..8 {
            assert_eq!(c[a * 8 + b].to_bits(), c[b * 8 + a].to_bits());
        }
    }
    assert!(id.trace().unwrap() < v.iter().sum::<f64>() / 10.0);
    let mut r = [0.0; 4];
    id.noise_into(&mut r).unwrap();
    // Wheel row: σ_v² + (k1/m)² σ_u² = 0.01 + 81; body row: σ_v².
    assert!((r[0] - 81.01).abs() < 1e-9 && (r[3] - 0.01).abs() < 1e-12 && r[1] == 0.0, "{r:?}");
    let (mut gp, mut ge) = ([9; 8], [9; 2]);
    id.groups_into(&mut gp, &mut ge).unwrap();
    assert_eq!((gp, ge), ([0; 8], [0; 2]));
    assert!(matches!(id.covariance_into(&mut [0.0; 63]), Err(Error::Shape { .. })));
    assert!(matches!(id.params_into(&mut [0.0; 7]), Err(Error::Shape { .. })));
    assert!(matches!(id.reset_covariance(-1.0), Err(Error::InvalidArgument { arg: "p0", .. })));
    id.reset_covariance(2.0).unwrap();
    assert_eq!(id.trace(), Some(16.0));
    let p = id.state_covariance();
    assert!((0..4).all(|i| p[(i, i)] > 0.0));
}

/// RK4 with the simulator's sub-steps against the exact zero-order hold, thesis quarter car
/// at dt = 0.05 s: the discretization error the filter's model carries against a continuous
/// plant (against the simulator, which integrates with the same RK4, it carries none).
/// Measured: 5 sub-steps, relative error 1.0e-4 in Φ and 1.3e-4 in Γ.
#[test]
fn rk4_discretization_error() {
    let m = QuarterCar::<f64>::thesis().model();
    let sub = auto_substeps(&m, DT);
    let (pr, gr) = rk4_map(&m, DT, sub).unwrap();
    let (pe, ge) = zoh(&m, DT).unwrap();
    let (ep, eg) = ((pr - pe).norm() / pe.norm(), (gr - ge).norm() / ge.norm());
    eprintln!("substeps {sub}: relative error Φ {ep:.2e}, Γ {eg:.2e}");
    assert_eq!(sub, 5);
    assert!(ep < 3e-4 && eg < 3e-4, "{ep} {eg}");
}

/// Must-show: seeds 3000–3011 (none used while developing), 40,000
/// samples each, release; the prior of [`guess`]; ξ of the rows 1 and 3 implied by the
/// estimate; Kalman = the thesis' rows identifier (p0 1000, R from the noise levels) on the
/// same samples. Measured (median / worst over the 12 seeds):
///
/// | σ_w (% of σ_u) | EKF, physical structure | EKF, full rows | Kalman rows |
/// |---|---|---|---|
/// | 0.5 | 2.0e-7 / 1.3e-6 | 3.8e-4 / 1.4e-3 | 0.19 / 0.39 |
/// | 8 | 3.3e-6 / 1.4e-5 | 9.2e-4 / 6.8e-3 | 4.78 / 5.16 |
/// | 32 | 5.6e-5 / 2.8e-4 | 0.017 / 15.4 | 5.83 / 5.89 |
///
/// The one failure, full rows at 32 % on seed 3010: the first samples carried the wheel row
/// far off (ξ 55 at sample 4,000, θ₁₀ ≈ −540 for −140) and the filter, overconfident along
/// the badly excited direction of the two positions, is walking back slowly (ξ 15 at 40,000,
/// still falling). The other 11 seeds there: ξ ≤ 0.077. The physical structure's `g`
/// carries `k1/m` (module docs): compare the full rows with the Kalman identifier.
///
/// Run: `cargo test -p vehid-core --release --test joint_ekf -- --ignored --nocapture must_show`
#[test]
#[ignore]
fn must_show_xi_over_seeds() {
    for pct in [0.5, 8.0, 32.0] {
        let (mut phys, mut rows, mut kal) = (vec![], vec![], vec![]);
        for seed in 3000..3012u64 {
            let (x, z, sub) = quarter(40_000, pct, seed);
            let (p, r, k) = (xi_ekf_physical(&x, &z, pct, sub), xi_ekf_rows(&x, &z, pct, sub), rows_kalman(&x, &z));
            eprintln!("σ_w {pct} %, seed {seed}: EKF physical {p:.3e}, EKF rows {r:.3e}, Kalman rows {k:.4}");
            phys.push(p);
            rows.push(r);
            kal.push(k);
        }
        for (name, v) in [("EKF physical", &mut phys), ("EKF rows", &mut rows), ("Kalman rows", &mut kal)] {
            let worst = v.iter().fold(0.0f64, |a, &b| a.max(if b.is_nan() { f64::INFINITY } else { b }));
            eprintln!("σ_w {pct} %: {name}: median {:.3e}, worst {worst:.3e}", median(v));
        }
        assert!(median(&rows) <= median(&kal) && median(&phys) <= median(&kal), "σ_w {pct} %");
    }
}

/// Wall-clock ns per update (release; indicative only).
/// Run: `cargo test -p vehid-core --release --test joint_ekf -- --ignored --nocapture timing`
#[test]
#[ignore]
fn timing() {
    let (x, z, sub) = quarter(4096, 8.0, 1);
    let reps = 20;
    let time = |name: &str, id: &mut dyn Identifier<f64>| time_updates(name, id, &x, &z, reps);
    time("joint EKF, physical (D = 9, 5 RK4 sub-steps)", &mut ekf_physical(8.0, sub));
    time("joint EKF, full rows (D = 13, 5 RK4 sub-steps)", &mut ekf_rows(8.0, sub));
    time("joint EKF, physical, 1 sub-step", &mut ekf_physical(8.0, 1));
    let r = QuarterCar::<f64>::thesis().model().row_noise_var::<2>(ROAD, DERIV).unwrap();
    time("Kalman rows", &mut KalmanIdentifier::<f64, 4, 2>::new([1, 3], 1000.0, r).unwrap());
}

#[test]
fn accessors_read_back_the_construction() {
    // Before any sample: the structure, noise model, interval and sub-steps given, the state
    // at zero with covariance x0_var I, the parameters at the prior mean.
    let (g, v) = guess(&PHYS_TRUTH);
    let dt = 0.0125;
    let ekf = JointEkf::<f64, 4, 9>::new(physical(), &g, &v, 2.5, noise(8.0), dt, 7).unwrap();
    assert_eq!(ekf.structure(), &physical());
    assert_eq!(ekf.noise(), &noise(8.0));
    assert_eq!(ekf.dt(), dt);
    assert_eq!(ekf.substeps(), 7);
    assert_eq!(ekf.state(), SVector::<f64, 4>::zeros());
    assert_eq!(ekf.state_covariance(), nalgebra::SMatrix::<f64, 4, 4>::identity() * 2.5);
    let mut p = [0.0; 4];
    ekf.params_into(&mut p).unwrap();
    assert_eq!(p.as_slice(), g.as_slice());
    assert_eq!(ekf.samples(), 0);
}

// ---------------------------------------------------------------------------------------
// A nonlinear structure with measured inputs, against an EKF written out here.
//
// Four states, three measured inputs, ten parameters (D = 15). Every kind of basis the
// filter differentiates: an offset (`One`, with and without a parameter), states, inputs
// (`Var::Input`, with and without a parameter), `sign` of a combination of a state and an
// input and of an input alone (0 on some samples: `sign(0) = 0`), `pos` and `neg` of
// combinations with coefficients other than ±1, and a `neg` that reads `der(1)` (twice, in
// one combination) in an equation given *before* the equation of state 1:
//
//   ẋ0 = p8 x1 + p9 sign(u2)
//   ẋ1 = p0 x0 + p1 x1 + p2 + p3 sign(2 x0 − 3 u0) + p4 pos(x1 − 0.5 x0 + u1) + 0.7 u1 + 0.2
//   ẋ2 = p5 neg(1.5 der(1) + 0.5 der(1) − 0.5 x2 + 2 u1) − 2 p6 x2 + p7 u0
//   ẋ3 = x0 − 0.5 x3                                           (known)
//
// plus the road `g u` (`g = NL_GAIN`), `der(1)` being the whole `ẋ1` (road included, as the
// measured `z_1` is).
// ---------------------------------------------------------------------------------------

const NL_D: usize = 15;
const NL_GAIN: [f64; 4] = [0.0, 1.5, 0.8, 0.0];

/// The nonlinear structure above, its equations pushed in the order x2, x1, x0, x3.
fn nonlinear() -> Structure<f64> {
    let mut s = Structure::<f64>::new(4, 3, 10).unwrap();
    let (a, al) = s.push_combination(&[(Var::State(0), 2.0), (Var::Input(0), -3.0)]).unwrap();
    let (b, bl) = s.push_combination(&[(Var::State(1), 1.0), (Var::State(0), -0.5), (Var::Input(1), 1.0)]).unwrap();
    let (c, cl) = s
        .push_combination(&[(Var::Deriv(1), 1.5), (Var::Deriv(1), 0.5), (Var::State(2), -0.5), (Var::Input(1), 2.0)])
        .unwrap();
    let (d, dl) = s.push_combination(&[(Var::Input(2), 1.0)]).unwrap();
    let t = |coef: f64, param: Option<u8>, basis: Basis| Term { coef, param, basis };
    let x = |i: u8| Basis::Var(Var::State(i));
    let u = |i: u8| Basis::Var(Var::Input(i));
    s.push_equation(
        2,
        &[t(1.0, Some(5), Basis::Neg { start: c, len: cl }), t(-2.0, Some(6), x(2)), t(1.0, Some(7), u(0))],
    )
    .unwrap();
    s.push_equation(
        1,
        &[
            t(1.0, Some(0), x(0)),
            t(1.0, Some(1), x(1)),
            t(1.0, Some(2), Basis::One),
            t(1.0, Some(3), Basis::Sign { start: a, len: al }),
            t(1.0, Some(4), Basis::Pos { start: b, len: bl }),
            t(0.7, None, u(1)),
            t(0.2, None, Basis::One),
        ],
    )
    .unwrap();
    s.push_equation(0, &[t(1.0, Some(8), x(1)), t(1.0, Some(9), Basis::Sign { start: d, len: dl })]).unwrap();
    s.push_equation(3, &[t(1.0, None, x(0)), t(-0.5, None, x(3))]).unwrap();
    s
}

fn sign(e: f64) -> f64 {
    if e > 0.0 {
        1.0
    } else if e < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// `ẋ` of [`nonlinear`] written out by hand, at the augmented state `s = [x; p; road]`.
fn nl_f(s: &SVector<f64, NL_D>, u: &[f64; 3]) -> SVector<f64, 4> {
    let (x, p, road) = (&s.as_slice()[..4], &s.as_slice()[4..14], s[14]);
    let ca = 2.0 * x[0] - 3.0 * u[0];
    let cb = x[1] - 0.5 * x[0] + u[1];
    let xd1 = p[0] * x[0] + p[1] * x[1] + p[2] + p[3] * sign(ca) + p[4] * cb.max(0.0) + 0.7 * u[1] + 0.2;
    let xd1 = xd1 + NL_GAIN[1] * road;
    let cc = 2.0 * xd1 - 0.5 * x[2] + 2.0 * u[1];
    let xd2 = p[5] * cc.min(0.0) - 2.0 * p[6] * x[2] + p[7] * u[0] + NL_GAIN[2] * road;
    let xd0 = p[8] * x[1] + p[9] * sign(u[2]) + NL_GAIN[0] * road;
    let xd3 = x[0] - 0.5 * x[3] + NL_GAIN[3] * road;
    SVector::from([xd0, xd1, xd2, xd3])
}

/// The next state: `substeps` classical RK4 steps of `nl_f`, parameters and road held.
fn nl_rk4(s: &SVector<f64, NL_D>, u: &[f64; 3], dt: f64, substeps: u32) -> SVector<f64, 4> {
    let h = dt / f64::from(substeps);
    let mut y = *s;
    let at = |y: &SVector<f64, NL_D>, x: SVector<f64, 4>| {
        let mut v = *y;
        v.fixed_rows_mut::<4>(0).copy_from(&x);
        v
    };
    for _ in 0..substeps {
        let x = y.fixed_rows::<4>(0).into_owned();
        let k1 = nl_f(&y, u);
        let k2 = nl_f(&at(&y, x + k1 * (h / 2.0)), u);
        let k3 = nl_f(&at(&y, x + k2 * (h / 2.0)), u);
        let k4 = nl_f(&at(&y, x + k3 * h), u);
        y = at(&y, x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0));
    }
    y.fixed_rows::<4>(0).into_owned()
}

/// Central differences `∂g/∂s` (`4 × D`) of a map of the augmented state.
fn central_jacobian(
    s: &SVector<f64, NL_D>,
    g: impl Fn(&SVector<f64, NL_D>) -> SVector<f64, 4>,
) -> SMatrix<f64, 4, NL_D> {
    let mut j = SMatrix::<f64, 4, NL_D>::zeros();
    for k in 0..NL_D {
        let h = 1e-5 * s[k].abs().max(1.0);
        let (mut a, mut b) = (*s, *s);
        a[k] += h;
        b[k] -= h;
        j.set_column(k, &((g(&a) - g(&b)) / (2.0 * h)));
    }
    j
}

/// One batch measurement update `y = H s + noise(diag R)` with innovation `innov`: the
/// textbook Kalman gain and the Joseph form.
fn kalman_update(
    s: &mut SVector<f64, NL_D>,
    p: &mut SMatrix<f64, NL_D, NL_D>,
    h: &SMatrix<f64, 4, NL_D>,
    r: &SVector<f64, 4>,
    innov: &SVector<f64, 4>,
) {
    let rm = SMatrix::<f64, 4, 4>::from_diagonal(r);
    let sm = h * *p * h.transpose() + rm;
    let k = *p * h.transpose() * sm.try_inverse().unwrap();
    *s += k * innov;
    let a = SMatrix::<f64, NL_D, NL_D>::identity() - k * h;
    *p = a * *p * a.transpose() + k * rm * k.transpose();
}

/// The joint EKF of the module docs, written out with dense matrices and finite-difference
/// Jacobians of the hand-written model: update with `r` (`H = [I 0 0]`), update with `z`
/// (`H = ∂f/∂s` at the `r`-updated estimate), predict (`F = [J; 0 I 0; 0 0 0]` with `J`
/// the central differences of the RK4 map, `q = NL_Q` on the parameters, the road restarted at
/// `(0, σ_u²)`). Returns the identified equations' innovations `z_i − f_i` at the
/// `r`-updated estimate, in the order of `rows`.
fn reference_step(
    s: &mut SVector<f64, NL_D>,
    p: &mut SMatrix<f64, NL_D, NL_D>,
    dt: f64,
    substeps: u32,
    rows: &[usize],
    (r, z, u): (&[f64; 4], &[f64; 4], &[f64; 3]),
) -> Vec<f64> {
    let mut hr = SMatrix::<f64, 4, NL_D>::zeros();
    for i in 0..4 {
        hr[(i, i)] = 1.0;
    }
    let innov_r = SVector::from(*r) - s.fixed_rows::<4>(0);
    kalman_update(s, p, &hr, &SVector::from(NL_STATE_VAR), &innov_r);
    let f = nl_f(s, u);
    let innov_z = SVector::from(*z) - f;
    let e = rows.iter().map(|&i| innov_z[i]).collect();
    let hz = central_jacobian(s, |v| nl_f(v, u));
    kalman_update(s, p, &hz, &SVector::from(NL_DERIV_VAR), &innov_z);
    let jx = central_jacobian(s, |v| nl_rk4(v, u, dt, substeps));
    let mut fm = SMatrix::<f64, NL_D, NL_D>::zeros();
    fm.fixed_rows_mut::<4>(0).copy_from(&jx);
    for k in 4..NL_D - 1 {
        fm[(k, k)] = 1.0;
    }
    let xn = nl_rk4(s, u, dt, substeps);
    *p = fm * *p * fm.transpose();
    for k in 4..NL_D - 1 {
        p[(k, k)] += NL_Q;
    }
    p[(NL_D - 1, NL_D - 1)] = NL_ROAD_VAR;
    s.fixed_rows_mut::<4>(0).copy_from(&xn);
    s[NL_D - 1] = 0.0;
    e
}

/// The noise model of the nonlinear tests (`Σ_w`, `Σ_v`, `σ_u²`, `q`; `g` is `NL_GAIN`):
/// unequal variances, the road on states 1 and 2, a parameter walk.
const NL_STATE_VAR: [f64; 4] = [1e-4, 4e-4, 2e-4, 1e-4];
const NL_DERIV_VAR: [f64; 4] = [0.04, 0.01, 0.02, 0.03];
const NL_ROAD_VAR: f64 = 0.09;
const NL_Q: f64 = 1e-3;

fn nl_noise() -> EkfNoise<f64, 4> {
    EkfNoise {
        state_var: SVector::from(NL_STATE_VAR),
        deriv_var: SVector::from(NL_DERIV_VAR),
        road_gain: SVector::from(NL_GAIN),
        road_var: NL_ROAD_VAR,
        param_walk_var: 0.0,
    }
    .with_param_walk(NL_Q)
}

const NL_P0: [f64; 10] = [-4.0, -1.0, 0.3, 0.5, -2.0, 1.2, 1.5, 0.8, 1.0, 0.25];
const NL_X0_VAR: f64 = 0.5;

/// Samples `(r_k, z_k, u_k)`: the inputs give `sign(u2)` its three cases (0 on the first
/// and last sample), `2 x0 − 3 u0` both signs, `pos`/`neg` active and inactive.
const NL_SAMPLES: [([f64; 4], [f64; 4], [f64; 3]); 4] = [
    ([0.05, -0.1, 0.08, 0.02], [0.3, -1.0, 0.5, 0.1], [0.4, 0.5, 0.0]),
    ([0.04, 0.12, -0.05, 0.03], [-0.2, 0.8, -0.6, 0.05], [-0.4, -0.5, 0.7]),
    ([-0.03, 0.2, 0.1, 0.01], [0.5, -0.4, 1.1, -0.02], [0.4, -0.5, -0.7]),
    ([0.02, -0.15, 0.0, -0.01], [-0.1, 0.6, -0.3, 0.0], [-0.4, 0.5, 0.0]),
];

fn nl_ekf(dt: f64, substeps: u32) -> JointEkf<f64, 4, NL_D> {
    JointEkf::new(nonlinear(), &NL_P0, &[1.0; 10], NL_X0_VAR, nl_noise(), dt, substeps).unwrap()
}

fn close(what: &str, got: f64, want: f64, tol: f64) {
    assert!((got - want).abs() <= tol * (1.0 + want.abs()), "{what}: {got} against the reference {want}");
}

/// The nonlinear structure's filter, sample by sample, against [`reference_step`] (a dense
/// EKF written in this file, its Jacobians central differences of the hand-written `ẋ` and
/// of its RK4 map): the innovations `e`, the predicted state `x̂` and its covariance, the
/// parameters and their covariance after each of four samples (2 RK4 sub-steps each).
/// Before the filter: the hand-written `ẋ` is the structure's own `Structure::derivative`
/// (plus `g u`) at the samples' points, so the reference models what the structure says.
#[test]
fn nonlinear_bases_and_inputs_match_a_finite_difference_ekf() {
    let (dt, sub) = (0.05, 2);
    let st = nonlinear();
    let mut ekf = nl_ekf(dt, sub);
    assert_eq!(ekf.rows(), &[2, 1, 0]);
    let mut s = SVector::<f64, NL_D>::zeros();
    let mut p = SMatrix::<f64, NL_D, NL_D>::zeros();
    for k in 0..4 {
        p[(k, k)] = NL_X0_VAR;
    }
    for j in 0..10 {
        s[4 + j] = NL_P0[j];
        p[(4 + j, 4 + j)] = 1.0;
    }
    p[(NL_D - 1, NL_D - 1)] = NL_ROAD_VAR;
    let mut e = [0.0; 3];
    for (k, (r, z, u)) in NL_SAMPLES.iter().enumerate() {
        // The hand-written model is the structure's (road 0), at the prior and at the sample.
        let mut at_r = s;
        at_r.fixed_rows_mut::<4>(0).copy_from_slice(r);
        for probe in [s, at_r] {
            let mut xd = [0.0; 4];
            st.derivative(&probe.as_slice()[4..14], &probe.as_slice()[..4], u, &mut xd);
            let want = nl_f(&probe, u);
            for i in 0..4 {
                close(&format!("sample {k}: ẋ{i}"), xd[i], want[i], 1e-14);
            }
        }
        let want_e = reference_step(&mut s, &mut p, dt, sub, &[2, 1, 0], (r, z, u));
        ekf.update_into(r, z, u, &mut e).unwrap();
        for i in 0..3 {
            close(&format!("sample {k}: innovation {i}"), e[i], want_e[i], 1e-8);
        }
        let (x, px) = (ekf.state(), ekf.state_covariance());
        let mut th = [0.0; 10];
        ekf.params_into(&mut th).unwrap();
        let mut pp = [0.0; 100];
        ekf.covariance_into(&mut pp).unwrap();
        let scale = p.abs().max();
        for a in 0..4 {
            close(&format!("sample {k}: x̂{a}"), x[a], s[a], 1e-8);
            for b in 0..4 {
                close(&format!("sample {k}: P_x[{a},{b}]"), px[(a, b)] / scale, p[(a, b)] / scale, 1e-8);
            }
        }
        for a in 0..10 {
            close(&format!("sample {k}: p̂{a}"), th[a], s[4 + a], 1e-8);
            for b in 0..10 {
                close(&format!("sample {k}: P_p[{a},{b}]"), pp[a * 10 + b] / scale, p[(4 + a, 4 + b)] / scale, 1e-8);
            }
        }
    }
    assert_eq!(ekf.samples(), 4);
}

/// At the kink of `pos`/`neg` (the combination exactly 0) the filter takes the flat side:
/// no tangent, as for `sign` (whose derivative is 0 wherever it exists). Structure: `ẋ0 =
/// u0` (known, `u0 = 0`, no road: `x0` stays exactly 0), `ẋ1 = p0 pos(x0) + p1 neg(2 x0) + p2
/// x1`. After one sample with `r0 = z0 = 0`, `x0` is then informed by `r0` alone: `x̂0 = 0`
/// exactly, uncorrelated with `x1`, and its variance is the scalar Kalman update's closed
/// form `v w / (v + w)` (`v` the prior variance, `w` the sensor's), carried unchanged
/// through the prediction (`ẋ0` reads nothing).
#[test]
fn pos_and_neg_at_their_kink_carry_no_tangent() {
    let mut st = Structure::<f64>::new(2, 1, 3).unwrap();
    let (a, al) = st.push_combination(&[(Var::State(0), 1.0)]).unwrap();
    let (b, bl) = st.push_combination(&[(Var::State(0), 2.0)]).unwrap();
    let t = |coef: f64, param: Option<u8>, basis: Basis| Term { coef, param, basis };
    st.push_equation(
        1,
        &[
            t(1.0, Some(0), Basis::Pos { start: a, len: al }),
            t(1.0, Some(1), Basis::Neg { start: b, len: bl }),
            t(1.0, Some(2), Basis::Var(Var::State(1))),
        ],
    )
    .unwrap();
    st.push_equation(0, &[t(1.0, None, Basis::Var(Var::Input(0)))]).unwrap();
    let (v, w) = (0.5, 0.01);
    let noise = EkfNoise {
        state_var: SVector::from([w, w]),
        deriv_var: SVector::from([0.01, 0.01]),
        road_gain: SVector::from([0.0, 1.0]),
        road_var: 0.04,
        param_walk_var: 0.0,
    };
    let mut ekf = JointEkf::<f64, 2, 6>::new(st, &[3.0, -2.0, -1.0], &[1.0; 3], v, noise, 0.05, 2).unwrap();
    let mut e = [0.0];
    ekf.update_into(&[0.0, 0.3], &[0.0, 0.5], &[0.0], &mut e).unwrap();
    let (x, p) = (ekf.state(), ekf.state_covariance());
    assert_eq!(x[0], 0.0);
    assert_eq!(p[(0, 1)], 0.0);
    assert!((p[(0, 0)] - v * w / (v + w)).abs() <= 1e-15, "{}", p[(0, 0)]);
    // The sample did inform x1 and the parameters (the check above is not vacuous).
    assert!(x[1] != 0.0 && p[(1, 1)] < v);
}

/// The noise model's accessor and the identifier's reports on the nonlinear structure
/// (three identified equations, rows 2, 1, 0): `with_param_walk` sets `q` and nothing else;
/// `noise_into` is the closed form `Σ_v,ii δ_ij + g_i g_j σ_u²` over the rows in order, written
/// out here; a wrong buffer is a shape error stating the size expected (9 = 3²); so are
/// `groups_into`'s.
#[test]
fn noise_report_and_shapes_of_a_three_equation_filter() {
    let base = EkfNoise::from_sigmas(0.01, 0.1, SVector::from(NL_GAIN), 0.3);
    let walked = base.with_param_walk(0.25);
    assert_eq!(walked.param_walk_var, 0.25);
    assert_eq!(EkfNoise { param_walk_var: 0.0, ..walked }, base);
    let ekf = nl_ekf(0.05, 2);
    let (dv, su2) = (NL_DERIV_VAR, NL_ROAD_VAR);
    let rows = [2usize, 1, 0];
    assert_eq!(ekf.rows(), &rows);
    let mut r = [f64::NAN; 9];
    ekf.noise_into(&mut r).unwrap();
    for (a, &ra) in rows.iter().enumerate() {
        for (b, &rb) in rows.iter().enumerate() {
            let want = if a == b { dv[ra] } else { 0.0 } + NL_GAIN[ra] * NL_GAIN[rb] * su2;
            assert!((r[a * 3 + b] - want).abs() <= 1e-15, "R[{a},{b}] = {} against {want}", r[a * 3 + b]);
        }
    }
    // The road couples rows 2 and 1: 0.8 × 1.5 × 0.09.
    assert!((r[1] - 0.108).abs() < 1e-15 && (r[3] - 0.108).abs() < 1e-15);
    assert_eq!(ekf.noise_into(&mut [0.0; 6]), Err(Error::Shape { arg: "out", expected: 9, got: 6 }));
    let (mut gp, mut ge) = ([0usize; 10], [0usize; 3]);
    assert_eq!(
        ekf.groups_into(&mut gp[..9], &mut ge),
        Err(Error::Shape { arg: "group_of_param", expected: 10, got: 9 })
    );
    assert_eq!(ekf.groups_into(&mut gp, &mut ge[..2]), Err(Error::Shape { arg: "group_of_eq", expected: 3, got: 2 }));
}

/// `posterior_stats` of the nonlinear structure's filter after four samples, against the
/// formulas written out from the identifier's own reports read directly: `params` =
/// `params_into`, `cov` = `covariance_into` (P as it is, not rescaled), `bse = √diag P`,
/// the interval `θ̂ ± z bse` with the normal quantile `z_{0.975} = 1.959963984540054`
/// (`z_{0.95} = 1.6448536269514722` at α = 0.1), `df = ∞`, `sigma2` = the diagonal of
/// `noise_into`, `nobs` = the samples taken, per equation.
#[test]
fn posterior_stats_read_the_filter_as_it_is() {
    let mut ekf = nl_ekf(0.05, 2);
    let mut e = [0.0; 3];
    for (r, z, u) in &NL_SAMPLES {
        ekf.update_into(r, z, u, &mut e).unwrap();
    }
    let mut th = [0.0; 10];
    ekf.params_into(&mut th).unwrap();
    let mut p = [0.0; 100];
    ekf.covariance_into(&mut p).unwrap();
    let mut r = [0.0; 9];
    ekf.noise_into(&mut r).unwrap();
    for (alpha, z) in [(0.05, 1.959963984540054), (0.1, 1.6448536269514722)] {
        let st = posterior_stats(&ekf, alpha).unwrap();
        assert_eq!(st.alpha, alpha);
        assert_eq!(st.params, th.to_vec());
        assert_eq!(st.cov, p.to_vec());
        assert_eq!(st.df, vec![f64::INFINITY; 10]);
        assert_eq!(st.nobs, vec![4.0; 3]);
        assert_eq!(st.sigma2, vec![r[0], r[4], r[8]]);
        assert_eq!(st.bse.len(), 10);
        assert_eq!(st.conf_int.len(), 10);
        for j in 0..10 {
            let bse = p[j * 10 + j].sqrt();
            assert!((st.bse[j] - bse).abs() <= 1e-15 * bse, "bse {j}: {} against {bse}", st.bse[j]);
            let (lo, hi) = st.conf_int[j];
            let tol = 1e-12 * (th[j].abs() + bse);
            let want = (th[j] - z * bse, th[j] + z * bse);
            assert!(
                (lo - want.0).abs() <= tol && (hi - want.1).abs() <= tol,
                "interval {j}: {:?} against {want:?}",
                (lo, hi)
            );
        }
    }
    // The check distinguishes: the diagonals differ from the off-diagonal entries.
    assert!(p[1] != p[11] && r[1] != r[4] && r[3] != r[4]);
}

/// The default sub-steps are the simulator's for the structure's A: on the thesis' full rows
/// at the car's own rows, `auto_substeps` of the car (the thesis' quarter car at 0.05 s and a
/// smaller step, so that the count is not 1 by default); a stiffer A needs more; the shapes are
/// checked.
#[test]
fn default_substeps_are_the_simulators_for_the_linearized_structure() {
    use vehid_core::identify::joint_ekf_substeps;
    for (car, dt) in [(QuarterCar::<f64>::thesis(), 0.05), (QuarterCar::<f64>::passenger(), 0.01)] {
        let model = car.model();
        let a = model.a();
        let rows: Vec<f64> = [1, 3].iter().flat_map(|&r| (0..4).map(move |j| a[(r, j)])).collect();
        let want = auto_substeps(&model, dt) as u32;
        assert_eq!(joint_ekf_substeps::<f64, 4>(&full_rows(), &rows, dt).unwrap(), want, "{dt}");
        // A much stiffer wheel row (its first entry 400 times larger) needs more, as many as
        // the simulator takes for that A.
        let mut stiff = rows.clone();
        stiff[0] *= 400.0;
        let mut a2 = *a;
        a2[(1, 0)] *= 400.0;
        let want2 = auto_substeps(&vehid_core::model::LinearModel::new(a2, *model.b(), &[1, 3]).unwrap(), dt) as u32;
        assert!(want2 > want, "{want2} {want}");
        assert_eq!(joint_ekf_substeps::<f64, 4>(&full_rows(), &stiff, dt).unwrap(), want2);
    }
    let err = joint_ekf_substeps::<f64, 4>(&full_rows(), &[0.0; 3], 0.05).unwrap_err();
    assert!(matches!(err, Error::Shape { arg: "params", expected: 8, got: 3 }), "{err:?}");
    assert!(matches!(joint_ekf_substeps::<f64, 3>(&full_rows(), &[0.0; 8], 0.05), Err(Error::Shape { .. })));
}

//! The joint state and parameter EKF (issue 15, item 3) on the quarter car with white noise
//! on the measured state (road σ_u 0.1, derivative noise σ_v 0.1, dt 0.05 s), against the
//! thesis' Kalman rows identifier.
//!
//! The must-show figures are `#[ignore]`d release tests (their measured values in their doc
//! comments; run them with
//! `cargo test -p vehid-core --release --test joint_ekf -- --ignored --nocapture`); the normal
//! suite holds a fast convergence check and the exact checks.

use nalgebra::SVector;
use vehid_core::identify::{EkfNoise, Identifier, JointEkf, KalmanIdentifier};
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

/// Must-show (issue 15, item 3): seeds 3000–3011 (none used while developing), 40,000
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

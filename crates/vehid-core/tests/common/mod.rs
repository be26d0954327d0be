//! The quarter car with noisy state sensors, as the noisy-state tests use it
//! (`noisy_states.rs`, `noise_estimating.rs`, `joint_ekf.rs`): rows 1 and 3 of the thesis'
//! car, a white road σ_u 0.1, dt 0.05 s, derivative noise σ_v 0.1, white state noise σ_w a
//! percentage of σ_u on every state. Each test crate uses part of it.
#![allow(dead_code)]

use vehid_core::identify::Identifier;
use vehid_core::metrics::xi;
use vehid_core::model::{PhysicalStructure, QuarterCar};
use vehid_core::sim::{SimConfig, Simulator};

pub const ROAD: f64 = 0.1;
pub const DERIV: f64 = 0.1;
pub const DT: f64 = 0.05;
/// The refined instruments' predictor capacity (6 lags of the quarter car's 8 values, and
/// the constant).
pub const Q: usize = 49;
/// Lags of the refined instruments (the Python default for the quarter car).
pub const LAGS: usize = 6;

/// `n` samples of the quarter car with state noise `pct` % of σ_u: `(r, z)` row-major, and
/// the simulator's RK4 sub-steps.
pub fn quarter_sampled(n: usize, pct: f64, seed: u64) -> (Vec<f64>, Vec<f64>, u32) {
    let car = QuarterCar::<f64>::thesis();
    let cfg = SimConfig::new(DT).road_sigma(ROAD).deriv_noise(DERIV).state_noise(pct / 100.0 * ROAD);
    let mut sim = Simulator::new(car.model(), cfg, seed).unwrap();
    let (mut x, mut z) = (Vec::with_capacity(4 * n), Vec::with_capacity(4 * n));
    for _ in 0..n {
        let s = sim.next_sample();
        x.extend_from_slice(s.r.as_slice());
        z.extend_from_slice(s.z.as_slice());
    }
    (x, z, sim.substeps() as u32)
}

/// [`quarter_sampled`] without the sub-steps.
pub fn quarter(n: usize, pct: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let (x, z, _) = quarter_sampled(n, pct, seed);
    (x, z)
}

/// The quarter car's physical structure with `m` known: `k2/M, b/M, M, k1`.
pub fn physical() -> PhysicalStructure<f64> {
    QuarterCar::structure([None, Some(1.0), None, None, None]).unwrap()
}

/// Physical parameters → constants → the thesis' unknown rows → ξ (Eq 3.17).
pub fn xi_physical(theta: &[f64]) -> f64 {
    let ps = physical();
    let truth = QuarterCar::<f64>::thesis();
    let zero = vec![0.0; theta.len() * theta.len()];
    let c: Vec<f64> = (0..5).map(|i| ps.constant(i, theta, &zero).map_or(f64::NAN, |v| v.0)).collect();
    match QuarterCar::new(c[0], c[1], c[2], c[3], c[4]) {
        Ok(est) => xi(truth.theta().transpose().as_slice(), est.theta().transpose().as_slice()).unwrap(),
        Err(_) => f64::INFINITY,
    }
}

/// ξ (Eq 3.17) of estimated rows 1 and 3 (row-major).
pub fn xi_rows(theta: &[f64]) -> f64 {
    let truth = QuarterCar::<f64>::thesis();
    xi(truth.theta().transpose().as_slice(), theta).unwrap_or(f64::INFINITY)
}

/// Feeds every sample.
pub fn feed<I: Identifier<f64> + ?Sized>(id: &mut I, x: &[f64], z: &[f64]) {
    let mut e = vec![0.0; id.dims().equations];
    for (xk, zk) in x.chunks(4).zip(z.chunks(4)) {
        id.update_into(xk, zk, &[], &mut e).unwrap();
    }
}

/// The estimate (NaN when there is none).
pub fn params<I: Identifier<f64> + ?Sized>(id: &I) -> Vec<f64> {
    let mut th = vec![0.0; id.dims().params];
    match id.params_into(&mut th) {
        Ok(()) => th,
        Err(_) => vec![f64::NAN; th.len()],
    }
}

/// Runs every sample; the final estimate (NaN when there is none).
pub fn run<I: Identifier<f64> + ?Sized>(id: &mut I, x: &[f64], z: &[f64]) -> Vec<f64> {
    feed(id, x, z);
    params(id)
}

/// Prints the time per update of `id` over `reps` passes of the samples (the ignored timing
/// tests: a rough figure; criterion has the real ones).
pub fn time_updates(name: &str, id: &mut dyn Identifier<f64>, x: &[f64], z: &[f64], reps: usize) {
    let mut e = vec![0.0; id.dims().equations];
    let t = std::time::Instant::now();
    for _ in 0..reps {
        for (xk, zk) in x.chunks(4).zip(z.chunks(4)) {
            let _ = std::hint::black_box(id.update_into(xk, zk, &[], &mut e));
        }
    }
    let n = reps * x.len() / 4;
    eprintln!("{name}: {:.0} ns/update", t.elapsed().as_nanos() as f64 / n as f64);
}

/// `got` equals `want` within `rel` of `want`'s largest magnitude, entry by entry (the
/// message names `name`, `what` and the entry).
pub fn close(name: &str, what: &str, got: &[f64], want: &[f64], rel: f64) {
    assert_eq!(got.len(), want.len(), "{name}: {what} length");
    let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(f64::MIN_POSITIVE);
    for (j, (g, w)) in got.iter().zip(want).enumerate() {
        assert!((g - w).abs() <= rel * scale, "{name}: {what}[{j}] = {g}, expected {w} (relative {rel})");
    }
}

/// The median of `v` (sorted copy; the mean of the middle two for an even length).
pub fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// Least-squares slope of `ln y` on `ln n` (the consistency figures' 1/√N test).
pub fn log_slope(n: &[usize], y: &[f64]) -> f64 {
    let xs: Vec<f64> = n.iter().map(|&v| (v as f64).ln()).collect();
    let ys: Vec<f64> = y.iter().map(|v| v.ln()).collect();
    let k = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / k, ys.iter().sum::<f64>() / k);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

//! Wall-clock time of the per-sample update of the identifiers Python's `fit()` runs, on the
//! same seeded data as `benches/python/fit_vs_rust.py`, for the ratio Python ÷ Rust.
//!
//! Run: `cargo run -q --release -p vehid-benches --bin time_updates -- MODEL N REPEATS`
//! (`MODEL`: `quarter` or `half`). Prints one line per path: `name ns_per_sample` (best of
//! `REPEATS` passes over `N` samples):
//! - `fixed`: the allocation-free `KalmanIdentifier<f64, N, K>::update` a Rust user calls;
//! - `heap`: the heap form Python holds (`boxed_kalman`: `KalmanRows<f64, N, Dynamic<L>>`),
//!   whole batch through `DynIdentifier::fit_dyn` on the row-major arrays, exactly the call
//!   Python's `fit` makes with the GIL released.
//!
//! `time_updates monitor-quarter|monitor-half FILE REPEATS`: the health monitor's update
//! (`HealthMonitor` / `HalfHealthMonitor` of the passenger car, dt 5 ms, realistic sensors with
//! their default noise: what `vehid.HealthMonitor(car)` builds) over the samples in `FILE`
//! (little-endian f64, 3 or 6 channels per sample, written by `fit_vs_rust.py` from the same
//! drive its Python `fit()` reads), one fresh monitor per pass: prints `monitor ns_per_sample`.
//!
//! The data: `Simulator` with dt 0.05 s, road σ 0.1, initial σ 0.1, derivative noise 0.005,
//! seed 1 (exactly what the Python script simulates), the identifier with p0 = 1000 and R
//! from the same noise levels (Eq 4.7).

use std::hint::black_box;
use std::process::ExitCode;
use std::time::Instant;
use vehid_core::health::{HalfHealthMonitor, HealthConfig, HealthMonitor};
use vehid_core::identify::{
    boxed_kalman, FitOptions, KalmanIdentifier, KalmanOptions, KalmanSpec, Mode, Prior, Samples,
};
use vehid_core::model::{HalfCar, LinearModel, QuarterCar};
use vehid_core::sim::{SensorNoise, SensorSet, SimConfig, Simulator};

fn data<const N: usize, const M: usize>(
    model: LinearModel<f64, N, M>,
    n: usize,
) -> vehid_core::Result<(Vec<f64>, Vec<f64>)> {
    let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(model, cfg, 1)?;
    let (mut x, mut z) = (Vec::with_capacity(n * N), Vec::with_capacity(n * N));
    sim.run_with(n, |s| {
        x.extend_from_slice(s.r.as_slice());
        z.extend_from_slice(s.z.as_slice());
    });
    Ok((x, z))
}

/// Best time per sample (ns) of `repeats` passes of `pass`.
fn best(repeats: usize, n: usize, mut pass: impl FnMut()) -> f64 {
    (0..repeats.max(1))
        .map(|_| {
            let t0 = Instant::now();
            pass();
            t0.elapsed().as_secs_f64() * 1e9 / n as f64
        })
        .fold(f64::INFINITY, f64::min)
}

fn run<const N: usize, const M: usize, const K: usize>(
    model: LinearModel<f64, N, M>,
    rows: [usize; K],
    n: usize,
    repeats: usize,
) -> vehid_core::Result<()> {
    let (x, z) = data(model.clone(), n)?;
    let r: [f64; K] = model.row_noise_var(0.1, 0.005)?;
    let fixed = best(repeats, n, || {
        let mut id = KalmanIdentifier::<f64, N, K>::new(rows, 1000.0, r).expect("valid settings");
        for (xs, zs) in x.chunks_exact(N).zip(z.chunks_exact(N)) {
            let xv = vehid_core::nalgebra::SVector::<f64, N>::from_column_slice(xs);
            let zv = vehid_core::nalgebra::SVector::<f64, N>::from_column_slice(zs);
            let _ = black_box(id.update(black_box(&xv), black_box(&zv)));
        }
        black_box(id.theta());
    });
    let spec = KalmanSpec {
        rows: rows.to_vec(),
        p0: Prior::PerRow(vec![1000.0]),
        theta0: None,
        r: r.to_vec(),
        mode: Mode::Rows,
        opts: KalmanOptions::default(),
    };
    let samples = Samples::new(N, 0, &x, &z, &[])?;
    let heap = best(repeats, n, || {
        let mut id = boxed_kalman::<f64, N>(&spec).expect("valid settings");
        let mut hist = Vec::new();
        let opts = FitOptions { record_every: 0, check_every: 1 << 16 };
        let _ = black_box(id.fit_dyn(black_box(&samples), opts, &mut hist, &mut || false));
        black_box(id.samples());
    });
    println!("fixed {fixed:.2}");
    println!("heap {heap:.2}");
    Ok(())
}

/// The samples of a file of little-endian f64 values.
fn read_f64(path: &str) -> Result<Vec<f64>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{path}: {e}"))?;
    if bytes.len() % 8 != 0 {
        return Err(format!("{path}: not a whole number of f64 values"));
    }
    Ok(bytes.chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes"))).collect())
}

/// `HealthMonitor::update` (quarter, 3 channels) or `HalfHealthMonitor::update` (half, 6) per
/// sample of `y`, a fresh monitor per pass.
fn monitor(half: bool, y: &[f64], repeats: usize) -> vehid_core::Result<()> {
    let noise = SensorNoise::<f64>::default();
    let ns = if half {
        let cfg = HealthConfig::new(0.005, HalfCar::<f64>::passenger()).with_sensors(SensorSet::Realistic, &noise);
        HalfHealthMonitor::new(cfg)?;
        best(repeats, y.len() / 6, || {
            let mut mon = HalfHealthMonitor::new(cfg).expect("valid settings");
            for row in y.chunks_exact(6) {
                let _ = black_box(mon.update(black_box(row)));
            }
            black_box(mon.samples());
        })
    } else {
        let cfg = HealthConfig::new(0.005, QuarterCar::<f64>::passenger()).with_sensors(SensorSet::Realistic, &noise);
        HealthMonitor::new(cfg)?;
        best(repeats, y.len() / 3, || {
            let mut mon = HealthMonitor::new(cfg).expect("valid settings");
            for row in y.chunks_exact(3) {
                let _ = black_box(mon.update(black_box(row)));
            }
            black_box(mon.samples());
        })
    };
    println!("monitor {ns:.2}");
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let parsed = match args.as_slice() {
        [m, n, r] => n.parse::<usize>().ok().zip(r.parse::<usize>().ok()).map(|(n, r)| (m.as_str(), n, r)),
        _ => None,
    };
    if let [m @ ("monitor-quarter" | "monitor-half"), file, r] = args.iter().map(String::as_str).collect::<Vec<_>>()[..]
    {
        let (Ok(y), Ok(repeats)) = (read_f64(file), r.parse::<usize>()) else {
            eprintln!("usage: time_updates monitor-quarter|monitor-half FILE REPEATS (FILE: little-endian f64)");
            return ExitCode::from(2);
        };
        return match monitor(m == "monitor-half", &y, repeats) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("time_updates: {e}");
                ExitCode::FAILURE
            }
        };
    }
    let Some((model, n, repeats)) = parsed else {
        eprintln!("usage: time_updates quarter|half N REPEATS, or monitor-quarter|monitor-half FILE REPEATS");
        return ExitCode::from(2);
    };
    let res = match model {
        "quarter" => {
            let car = QuarterCar::<f64>::thesis();
            run(car.model(), car.unknown_rows(), n, repeats)
        }
        "half" => {
            let car = HalfCar::<f64>::thesis();
            run(car.model(), car.unknown_rows(), n, repeats)
        }
        other => {
            eprintln!("time_updates: unknown model {other:?} (quarter or half)");
            return ExitCode::from(2);
        }
    };
    match res {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("time_updates: {e}");
            ExitCode::FAILURE
        }
    }
}

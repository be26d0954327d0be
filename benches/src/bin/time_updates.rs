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
//! The data: `Simulator` with dt 0.05 s, road σ 0.1, initial σ 0.1, derivative noise 0.005,
//! seed 1 (exactly what the Python script simulates), the identifier with p0 = 1000 and R
//! from the same noise levels (Eq 4.7).

use std::hint::black_box;
use std::process::ExitCode;
use std::time::Instant;
use vehid_core::identify::{
    boxed_kalman, FitOptions, KalmanIdentifier, KalmanOptions, KalmanSpec, Mode, Prior, Samples,
};
use vehid_core::model::{HalfCar, LinearModel, QuarterCar};
use vehid_core::sim::{SimConfig, Simulator};

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

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let parsed = match args.as_slice() {
        [m, n, r] => n.parse::<usize>().ok().zip(r.parse::<usize>().ok()).map(|(n, r)| (m.as_str(), n, r)),
        _ => None,
    };
    let Some((model, n, repeats)) = parsed else {
        eprintln!("usage: time_updates quarter|half N REPEATS");
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

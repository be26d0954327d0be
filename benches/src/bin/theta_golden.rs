//! The Rust side of the Python bit-for-bit check (`tests/test_golden_theta.py`).
//!
//! Simulates the thesis quarter car (dt 0.05 s, road σ_u 0.1 m, derivative noise 0.005,
//! RK4 with automatic sub-steps) for `N` samples from `SEED`, runs the Kalman identifier
//! (Eq 4.3–4.7; p0 = 1000, r = `row_noise_var(0.1, 0.005)`) over them and prints θ̂
//! row-major as 8 hexadecimal `f64::to_bits` patterns, one per line.
//!
//! Run: `cargo run -q --release -p vehid-benches --bin theta_golden -- SEED N`

use std::process::ExitCode;
use vehid_core::identify::KalmanIdentifier;
use vehid_core::model::QuarterCar;
use vehid_core::sim::{Method, SimConfig, Simulator};

fn parse<T: std::str::FromStr>(arg: Option<String>, what: &str) -> Result<T, String> {
    let text = arg.ok_or_else(|| format!("missing {what}"))?;
    text.parse().map_err(|_| format!("{what} must be a non-negative integer, got {text:?}"))
}

fn theta_bits(seed: u64, n: usize) -> vehid_core::Result<Vec<u64>> {
    let car = QuarterCar::<f64>::thesis();
    let model = car.model();
    let mut cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    cfg.method = Method::Rk4;
    cfg.substeps = None;
    let r = model.row_noise_var::<2>(0.1, 0.005)?;
    let mut sim = Simulator::new(model, cfg, seed)?;
    let mut id = KalmanIdentifier::<f64, 4, 2>::new(car.unknown_rows(), 1000.0, r)?;
    for _ in 0..n {
        let s = sim.next_sample();
        id.update(&s.r, &s.z)?;
    }
    let theta = id.theta();
    Ok((0..2).flat_map(|i| (0..4).map(move |j| (i, j))).map(|(i, j)| theta[(i, j)].to_bits()).collect())
}

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let parsed = parse::<u64>(args.next(), "SEED").and_then(|seed| Ok((seed, parse::<usize>(args.next(), "N")?)));
    let (seed, n) = match parsed {
        Ok(v) => v,
        Err(e) => {
            eprintln!("theta_golden: {e}\nusage: theta_golden SEED N");
            return ExitCode::from(2);
        }
    };
    match theta_bits(seed, n) {
        Ok(bits) => {
            for b in bits {
                println!("{b:016x}");
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("theta_golden: {e}");
            ExitCode::FAILURE
        }
    }
}

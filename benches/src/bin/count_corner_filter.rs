//! A fixed number of the full car's realistic-sensor fit updates (`CornerFilterFit`, the Python
//! `RealisticIdentifier(FullCar)`) on a seeded drive, for instruction counting under callgrind
//! (`benches/callgrind_check.py`, `make bench-check`); a binary of its own so that its code does
//! not change how the other counting binaries are compiled.
//!
//! Run: `cargo run -q --release -p vehid-benches --bin count_corner_filter -- full_corner_filter_realistic N`.
//! The passenger full car on ISO 8608 class C at 15 m/s, its twelve realistic channels at
//! 200 Hz (vehid's default sensor noise); the fit is past 2,000 samples before the counted
//! updates, which take the next [`LEN`] samples (cycled beyond). The data are generated
//! whatever `N` is, so the instructions of `N` updates are the count with `N` minus the count
//! with `N = 0`.

use std::hint::black_box;
use std::process::ExitCode;
use vehid_core::identify::{CornerFilterFit, DEFAULT_BANDWIDTH, DEFAULT_BLOCK};
use vehid_core::model::FullCar;
use vehid_core::sim::{DriveConfig, FullDrive, FullDriveConfig};

/// Samples of the drive counted through (100 s at 200 Hz).
const LEN: usize = 20_000;

fn run(n: usize) -> vehid_core::Result<String> {
    let dt = 0.005;
    let mut drive =
        FullDrive::new(FullCar::<f64>::passenger(), FullDriveConfig::new(DriveConfig::new(dt).speed(15.0)), 42)?;
    let data: Vec<[f64; 12]> = (0..LEN + 2000)
        .map(|_| {
            let mut y = [0.0; 12];
            y.copy_from_slice(drive.next_sample().y());
            y
        })
        .collect();
    let mut fit = CornerFilterFit::new(dt, DEFAULT_BANDWIDTH, DEFAULT_BLOCK)?;
    for y in &data[..2000] {
        fit.update(y)?;
    }
    let mut bad = 0;
    for y in data[2000..].iter().cycle().take(n) {
        bad += usize::from(black_box(fit.update(black_box(y))).is_err());
    }
    Ok(format!("{bad} refused, {} samples", fit.samples()))
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n = match (args.first().map(String::as_str), args.get(1).map(|s| s.parse::<usize>())) {
        (Some("full_corner_filter_realistic"), Some(Ok(n))) if args.len() == 2 => n,
        _ => {
            eprintln!("usage: count_corner_filter full_corner_filter_realistic N");
            return ExitCode::from(2);
        }
    };
    match run(n) {
        Ok(state) => {
            println!("{state}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("count_corner_filter: {e}");
            ExitCode::FAILURE
        }
    }
}

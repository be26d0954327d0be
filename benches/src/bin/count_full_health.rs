//! A fixed number of the full car's health-monitor updates on a seeded drive, for instruction
//! counting under callgrind (as `count_health`, in a binary of its own so that its code does not
//! change how `count_health`'s benches are compiled; `full_health` in `callgrind_check.py`'s gate).
//!
//! Run: `valgrind --tool=callgrind target/release/count_full_health full_health N` for `N = 0` and `N`
//! updates; the difference over `N` is the instructions per update. The passenger full car on
//! ISO 8608 class C at 15 m/s, realistic sensors at 200 Hz (as the criterion bench
//! `health/full_monitor_update_f64`), the monitor past its warm-up (30 s) before the counted
//! updates, which cycle through the next 100 s of the same drive.
//!
//! `count_full_health full_drive N` counts the drive itself instead: `N` samples of the same
//! drive (both ISO 8608 tracks in distance, the fourteen states' step, the twelve realistic
//! sensors and their noise; as the criterion bench `simulate_f64/full/drive`), after the same
//! 30 s.

use std::hint::black_box;
use std::process::ExitCode;
use vehid_core::health::{FullHealthMonitor, HealthConfig};
use vehid_core::model::FullCar;
use vehid_core::sim::{DriveConfig, FullDrive, FullDriveConfig};

/// Samples of the drive counted through (100 s at 200 Hz).
const LEN: usize = 20_000;

fn run(n: usize) -> vehid_core::Result<String> {
    let car = FullCar::<f64>::passenger();
    let mut drive = FullDrive::new(car, FullDriveConfig::new(DriveConfig::new(0.005)), 42)?;
    let mut mon = FullHealthMonitor::new(HealthConfig::new(0.005, car))?;
    for _ in 0..6000 {
        mon.update(drive.next_sample().y())?;
    }
    let data: Vec<[f64; 12]> = (0..LEN)
        .map(|_| {
            let mut y = [0.0; 12];
            y.copy_from_slice(drive.next_sample().y());
            y
        })
        .collect();
    let mut events = 0;
    for y in data.iter().cycle().take(n) {
        events += usize::from(black_box(mon.update(black_box(y)))?.is_some());
    }
    Ok(format!("{events} events, status {:?}", mon.status()))
}

/// `n` samples of the drive, after its first 30 s.
fn drive(n: usize) -> vehid_core::Result<String> {
    let car = FullCar::<f64>::passenger();
    let mut drive = FullDrive::new(car, FullDriveConfig::new(DriveConfig::new(0.005)), 42)?;
    for _ in 0..6000 {
        black_box(drive.next_sample());
    }
    let mut sum = 0.0;
    for _ in 0..n {
        sum += black_box(drive.next_sample()).y()[0];
    }
    Ok(format!("sum of the first channel {sum:.6e}"))
}

fn main() -> ExitCode {
    // `full_health N` or `full_drive N`, as callgrind_check.py calls every counting binary
    // (`BENCH N`).
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(bench), Some(Ok(n))) = (args.first().map(String::as_str), args.get(1).map(|s| s.parse::<usize>())) else {
        eprintln!("usage: count_full_health full_health|full_drive N");
        return ExitCode::from(2);
    };
    let counted = match bench {
        "full_health" => run(n),
        "full_drive" => drive(n),
        _ => {
            eprintln!("usage: count_full_health full_health|full_drive N");
            return ExitCode::from(2);
        }
    };
    match counted {
        Ok(state) => {
            println!("{state}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("count_full_health: {e}");
            ExitCode::FAILURE
        }
    }
}

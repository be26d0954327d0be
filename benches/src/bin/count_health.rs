//! A fixed number of health-monitor updates on a seeded drive, for instruction counting under
//! callgrind (`benches/callgrind_check.py`, `make bench-check`). A binary of its own, apart
//! from `count_updates`: adding this code to that binary moved other benches' counts by up to
//! 13 % through the compiler's partitioning and inlining, with no change in the library.
//!
//! Run: `cargo run -q --release -p vehid-benches --bin count_health -- quarter_health N`
//! (or `half_health N`: the passenger half car, `HalfHealthMonitor`, as the criterion bench
//! `health/half_monitor_update_f64`). A
//! passenger car on ISO 8608 class C at 15 m/s, realistic sensors at 200 Hz (as the criterion
//! bench `health/monitor_update_f64`); the monitor is past its warm-up (30 s of the drive)
//! before the counted updates, which take the next [`LEN`] samples of the same drive (cycled
//! beyond). The data are generated whatever `N` is, so the instructions of `N` updates are
//! the count with `N` minus the count with `N = 0`.

use std::hint::black_box;
use std::process::ExitCode;
use vehid_core::health::{HalfHealthMonitor, HealthConfig, HealthMonitor};
use vehid_core::model::{HalfCar, QuarterCar};
use vehid_core::sim::{DriveConfig, HalfDrive, HalfDriveConfig, QuarterDrive};

/// Samples of the drive counted through (100 s at 200 Hz).
const LEN: usize = 20_000;

fn run(n: usize) -> vehid_core::Result<String> {
    let car = QuarterCar::<f64>::passenger();
    let mut drive = QuarterDrive::new(car, DriveConfig::new(0.005), 42)?;
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car))?;
    for _ in 0..6000 {
        mon.update(drive.next_sample().y())?;
    }
    let data: Vec<[f64; 3]> = (0..LEN)
        .map(|_| {
            let s = drive.next_sample();
            [s.y()[0], s.y()[1], s.y()[2]]
        })
        .collect();
    let mut events = 0;
    for y in data.iter().cycle().take(n) {
        events += usize::from(black_box(mon.update(black_box(y)))?.is_some());
    }
    Ok(format!("{events} events, status {:?}, {:?}", mon.status(), mon.estimate().value))
}

fn run_half(n: usize) -> vehid_core::Result<String> {
    let car = HalfCar::<f64>::passenger();
    let mut drive = HalfDrive::new(car, HalfDriveConfig::new(DriveConfig::new(0.005)), 42)?;
    let mut mon = HalfHealthMonitor::new(HealthConfig::new(0.005, car))?;
    for _ in 0..6000 {
        mon.update(drive.next_sample().y())?;
    }
    let data: Vec<[f64; 6]> = (0..LEN)
        .map(|_| {
            let mut y = [0.0; 6];
            y.copy_from_slice(drive.next_sample().y());
            y
        })
        .collect();
    let mut events = 0;
    for y in data.iter().cycle().take(n) {
        events += usize::from(black_box(mon.update(black_box(y)))?.is_some());
    }
    Ok(format!("{events} events, status {:?}, {:?}", mon.status(), mon.estimate().value))
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (half, n) = match (args.first().map(String::as_str), args.get(1).map(|s| s.parse::<usize>())) {
        (Some("quarter_health"), Some(Ok(n))) if args.len() == 2 => (false, n),
        (Some("half_health"), Some(Ok(n))) if args.len() == 2 => (true, n),
        _ => {
            eprintln!("usage: count_health quarter_health|half_health N");
            return ExitCode::from(2);
        }
    };
    match if half { run_half(n) } else { run(n) } {
        Ok(state) => {
            println!("{state}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("count_health: {e}");
            ExitCode::FAILURE
        }
    }
}

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
//!
//! `quarter_health_state N`, `half_health_state N`: the same with the thesis' state sensors at
//! 8 % noise (`health_experiment --state-noise 0.08`'s levels; the kinematic filters with the
//! measured deflection rates, as the criterion benches `health/monitor_update_state_f64` and
//! `health/half_monitor_update_state_f64`).

use std::hint::black_box;
use std::process::ExitCode;
use vehid_core::health::{HalfHealthMonitor, HealthConfig, HealthMonitor};
use vehid_core::model::{HalfCar, QuarterCar};
use vehid_core::sim::{DriveConfig, HalfDrive, HalfDriveConfig, QuarterDrive, SensorNoise, SensorSet};

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

/// The state sensors at 8 % noise of the quarter car (`half`: of the half car), the levels
/// `health_experiment --state-noise 0.08` measures.
fn noise_8(half: bool) -> SensorNoise<f64> {
    let (state, deriv) = if half { (1.782e-3, 7.175e-2) } else { (1.859e-3, 9.971e-2) };
    SensorNoise { state, deriv, ..SensorNoise::default() }
}

fn run_state(n: usize) -> vehid_core::Result<String> {
    let car = QuarterCar::<f64>::passenger();
    let noise = noise_8(false);
    let mut drive = QuarterDrive::new(car, DriveConfig::new(0.005).sensors(SensorSet::State).noise(noise), 42)?;
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car).with_sensors(SensorSet::State, &noise))?;
    for _ in 0..6000 {
        mon.update(drive.next_sample().y())?;
    }
    let data: Vec<[f64; 8]> = (0..LEN)
        .map(|_| {
            let mut y = [0.0; 8];
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

fn run_half_state(n: usize) -> vehid_core::Result<String> {
    let car = HalfCar::<f64>::passenger();
    let noise = noise_8(true);
    let base = DriveConfig::new(0.005).sensors(SensorSet::State).noise(noise);
    let mut drive = HalfDrive::new(car, HalfDriveConfig::new(base), 42)?;
    let mut mon = HalfHealthMonitor::new(HealthConfig::new(0.005, car).with_sensors(SensorSet::State, &noise))?;
    for _ in 0..6000 {
        mon.update(drive.next_sample().y())?;
    }
    let data: Vec<[f64; 16]> = (0..LEN)
        .map(|_| {
            let mut y = [0.0; 16];
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
    let (which, n) = match (args.first().map(String::as_str), args.get(1).map(|s| s.parse::<usize>())) {
        (Some(w @ ("quarter_health" | "half_health" | "quarter_health_state" | "half_health_state")), Some(Ok(n)))
            if args.len() == 2 =>
        {
            (w, n)
        }
        _ => {
            eprintln!("usage: count_health quarter_health|half_health|quarter_health_state|half_health_state N");
            return ExitCode::from(2);
        }
    };
    let state = match which {
        "quarter_health" => run(n),
        "half_health" => run_half(n),
        "quarter_health_state" => run_state(n),
        _ => run_half_state(n),
    };
    match state {
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

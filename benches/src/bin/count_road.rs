//! A fixed number of coloured-road identifier updates on a seeded drive, for instruction
//! counting under callgrind (`benches/callgrind_check.py`, `make bench-check`); a binary of its
//! own so that its code does not change how `count_updates` is compiled.
//!
//! Run: `cargo run -q --release -p vehid-benches --bin count_road -- quarter_iv_physical_road N`.
//! The passenger quarter car on ISO 8608 class C at 15 m/s, true states at 200 Hz; the
//! identifier (`Differenced` around `IvIdentifier<f64, 2, 2>`, delay 1, exact start, on the
//! physical structure with m known) is past its start (2,000 samples) before the counted
//! updates, which take the next [`LEN`] samples (cycled beyond). `quarter_iv_physical_drive N`:
//! the same IV identifier without the road model on the same samples, so that the wrapper's
//! own cost is the difference. The data are generated whatever `N` is, so the instructions of
//! `N` updates are the count with `N` minus the count with `N = 0`.
//! `quarter_state_filter_realistic N`: the realistic sensors' body-equation fit
//! (`StateFilterFit`, M known) on the same drive's realistic channels, past 2,000 samples.

use std::hint::black_box;
use std::process::ExitCode;
use vehid_core::identify::{Differenced, Identifier, IvIdentifier, RoadModel, StructuredPrior, Travel};
use vehid_core::model::QuarterCar;
use vehid_core::sim::{DriveConfig, QuarterDrive, SensorSet};

/// Samples of the drive counted through (100 s at 200 Hz).
const LEN: usize = 20_000;

fn run(n: usize, road: bool) -> vehid_core::Result<String> {
    let car = QuarterCar::<f64>::passenger();
    let dt = 0.005;
    let mut drive = QuarterDrive::new(car, DriveConfig::new(dt).sensors(SensorSet::State), 42)?;
    let data: Vec<[f64; 8]> = (0..LEN + 2000)
        .map(|_| {
            let mut y = [0.0; 8];
            y.copy_from_slice(drive.next_sample().y());
            y
        })
        .collect();
    let s = *QuarterCar::<f64>::structure([None, Some(40.0), None, None, None])?.structure();
    let iv = IvIdentifier::<f64, 2, 2>::new(s, 1, StructuredPrior::Exact, None, &[1.0])?;
    let mut id: Box<dyn Identifier<f64>> = if road {
        // Every sample differenced (min_spacing 0): the wrapper's cost per inner update, its
        // worst case (the default 0.25 m skips three samples in four here, at a few instructions).
        Box::new(
            Differenced::new(iv, &s, RoadModel::Shaped { cutoff: 0.01 }, Travel::PerSample(15.0 * dt))?
                .with_min_spacing(0.0)?,
        )
    } else {
        Box::new(iv)
    };
    let mut e = [0.0; 2];
    for y in &data[..2000] {
        id.update_into(&y[..4], &y[4..], &[], &mut e)?;
    }
    let mut bad = 0;
    for y in data[2000..].iter().cycle().take(n) {
        bad += usize::from(black_box(id.update_into(black_box(&y[..4]), black_box(&y[4..]), &[], &mut e)).is_err());
    }
    let mut p = [0.0; 4];
    id.params_into(&mut p)?;
    Ok(format!("{bad} refused, params {p:?}"))
}

fn run_state_filter(n: usize) -> vehid_core::Result<String> {
    use vehid_core::identify::{StateFilterFit, DEFAULT_BANDWIDTH, DEFAULT_BLOCK};
    let car = QuarterCar::<f64>::passenger();
    let dt = 0.005;
    let mut drive = QuarterDrive::new(car, DriveConfig::new(dt), 42)?;
    let data: Vec<[f64; 3]> = (0..LEN + 2000)
        .map(|_| {
            let mut y = [0.0; 3];
            y.copy_from_slice(drive.next_sample().y());
            y
        })
        .collect();
    let ps = QuarterCar::<f64>::realistic_structure([Some(car.constants()[0]), None, None, None, None])?;
    let mut fit = StateFilterFit::new(*ps.structure(), dt, DEFAULT_BANDWIDTH, DEFAULT_BLOCK)?;
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
    let (which, n) = match (args.first().map(String::as_str), args.get(1).map(|s| s.parse::<usize>())) {
        (
            Some(w @ ("quarter_iv_physical_road" | "quarter_iv_physical_drive" | "quarter_state_filter_realistic")),
            Some(Ok(n)),
        ) if args.len() == 2 => (w, n),
        _ => {
            eprintln!(
                "usage: count_road quarter_iv_physical_road|quarter_iv_physical_drive|quarter_state_filter_realistic N"
            );
            return ExitCode::from(2);
        }
    };
    let result = if which == "quarter_state_filter_realistic" {
        run_state_filter(n)
    } else {
        run(n, which == "quarter_iv_physical_road")
    };
    match result {
        Ok(state) => {
            println!("{state}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("count_road: {e}");
            ExitCode::FAILURE
        }
    }
}

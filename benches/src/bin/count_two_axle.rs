//! A fixed number of the full car's two-axle identifier updates on a seeded drive, for
//! instruction counting under callgrind (`full_two_axle` in `callgrind_check.py`'s gate; a
//! binary of its own so that its code does not change how the other counting binaries'
//! benches are compiled).
//!
//! Run: `valgrind --tool=callgrind target/release/count_two_axle full_two_axle N` for `N = 0`
//! and `N` updates; the difference over `N` is the instructions per update. Road cancellation
//! on two tracks (as the criterion bench `update_f64/full/two_axle_rows`): the passenger full
//! car on ISO 8608 class C at 20 m/s, 200 Hz, true states, the rear wheels 31 samples behind,
//! after 6000 updates; the counted updates cycle through the next 100 s of the same drive.

use std::hint::black_box;
use std::process::ExitCode;
use vehid_core::identify::{TwoAxleConfig, TwoAxleIdentifier, WheelMethod};
use vehid_core::model::FullCar;
use vehid_core::sim::{DriveConfig, FullDrive, FullDriveConfig, RoadClass};

/// Samples of the drive counted through (100 s at 200 Hz).
const LEN: usize = 20_000;

/// `n` updates of the full car's two-axle identifier, after 6000.
fn two_axle(n: usize) -> vehid_core::Result<String> {
    let car = FullCar::<f64>::passenger();
    let cfg = FullDriveConfig::new(DriveConfig::new(0.005).road(RoadClass::C).speed(20.0));
    let mut drive = FullDrive::new(car, cfg, 42)?;
    let cfg = TwoAxleConfig::new(WheelMethod::Cancel, 1000.0, 0.1, 0.005);
    let mut id = TwoAxleIdentifier::<f64, 14, 28, 3, 32, 4>::new(&car.model(), 31, cfg)?;
    let mut e = [0.0; 7];
    for _ in 0..6000 {
        let s = drive.next_sample();
        id.update_at(&s.x, &s.xdot, None, &mut e)?;
    }
    let data: Vec<_> = (0..LEN).map(|_| drive.next_sample()).map(|s| (s.x, s.xdot)).collect();
    let mut paired = 0;
    for (x, z) in data.iter().cycle().take(n) {
        paired += usize::from(black_box(id.update_at(black_box(x), black_box(z), None, &mut e))?);
    }
    Ok(format!("{paired} paired, theta[0] {:.6e}", id.theta_row(1)[0]))
}

fn main() -> ExitCode {
    // `full_two_axle N`, as callgrind_check.py calls every counting binary (`BENCH N`).
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some("full_two_axle"), Some(Ok(n))) =
        (args.first().map(String::as_str), args.get(1).map(|s| s.parse::<usize>()))
    else {
        eprintln!("usage: count_two_axle full_two_axle N");
        return ExitCode::from(2);
    };
    match two_axle(n) {
        Ok(state) => {
            println!("{state}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("count_two_axle: {e}");
            ExitCode::FAILURE
        }
    }
}

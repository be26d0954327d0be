//! The drive and the health monitor allocate nothing per sample: a whole scenario (warm-up,
//! a damper ramp rebuilt every sample, an alarm, settling, the event, a gap of NaN rows, a
//! stuck channel, reacquiring) runs under a counting allocator with zero allocations; the
//! same for the half car's drive (its road history ring) and monitor, and the full car's drive
//! (two tracks, two rings) and monitor.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use vehid_core::health::{FullHealthMonitor, HalfHealthMonitor, HealthConfig, HealthMonitor};
use vehid_core::model::{FullCar, HalfCar, QuarterCar};
use vehid_core::sim::{
    Change, DriveConfig, FullChange, FullDrive, FullDriveConfig, HalfChange, HalfDrive, HalfDriveConfig, QuarterDrive,
    SensorNoise, SensorSet,
};

struct Counting;

thread_local! {
    static ALLOCS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocs() -> usize {
    ALLOCS.with(|c| c.get())
}

#[test]
fn a_whole_monitoring_scenario_allocates_nothing() {
    let car = QuarterCar::<f64>::passenger();
    let cfg = DriveConfig::new(0.005).with_change(Change::ramp(30.0, "b", 1200.0, 5.0).unwrap()).unwrap();
    let mut drive = QuarterDrive::new(car, cfg, 4242).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    let before = allocs();
    let mut events = 0;
    for k in 0..(80.0 / 0.005) as usize {
        let s = drive.next_sample();
        let mut y = [s.y()[0], s.y()[1], s.y()[2]];
        if (12_000..12_400).contains(&k) {
            y = [f64::NAN; 3];
        } else if (13_000..13_100).contains(&k) {
            y[2] = 0.01;
        }
        if mon.update(&y).unwrap().is_some() {
            events += 1;
        }
    }
    assert_eq!(allocs() - before, 0);
    assert!(events >= 1, "the damper ramp (-20 %) was not reported");
}

#[test]
fn a_whole_state_sensor_scenario_allocates_nothing() {
    // The state sensors at 8 % noise (the measured-rate filter), with a gap and a jump.
    let car = QuarterCar::<f64>::passenger();
    let noise = SensorNoise { state: 1.859e-3, deriv: 9.971e-2, ..SensorNoise::default() };
    let cfg = DriveConfig::new(0.005)
        .sensors(SensorSet::State)
        .noise(noise)
        .with_change(Change::ramp(30.0, "b", 1200.0, 5.0).unwrap())
        .unwrap();
    let mut drive = QuarterDrive::new(car, cfg, 4243).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car).with_sensors(SensorSet::State, &noise)).unwrap();
    let before = allocs();
    let mut events = 0;
    for k in 0..(80.0 / 0.005) as usize {
        let s = drive.next_sample();
        let mut y = [0.0; 8];
        y.copy_from_slice(s.y());
        if (12_000..12_400).contains(&k) {
            y = [f64::NAN; 8];
        } else if (13_000..13_100).contains(&k) {
            y[2] += 0.5;
        }
        if mon.update(&y).unwrap().is_some() {
            events += 1;
        }
    }
    assert_eq!(allocs() - before, 0);
    assert!(events >= 1, "the damper ramp (-20 %) was not reported");
}

#[test]
fn a_whole_half_car_scenario_allocates_nothing() {
    let car = HalfCar::<f64>::passenger();
    let cfg = HalfDriveConfig::new(DriveConfig::new(0.005))
        .with_change(HalfChange::ramp(30.0, "b_r", 1120.0, 5.0).unwrap())
        .unwrap();
    let mut drive = HalfDrive::new(car, cfg, 4242).unwrap();
    let mut mon = HalfHealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    let before = allocs();
    let mut events = 0;
    for k in 0..(80.0 / 0.005) as usize {
        let s = drive.next_sample();
        let mut y = [0.0; 6];
        y.copy_from_slice(s.y());
        if (12_000..12_400).contains(&k) {
            y = [f64::NAN; 6];
        } else if (13_000..13_100).contains(&k) {
            y[4] = 0.01;
        }
        if mon.update(&y).unwrap().is_some() {
            events += 1;
        }
    }
    assert_eq!(allocs() - before, 0);
    assert!(events >= 1, "the rear damper ramp (-20 %) was not reported");
}

#[test]
fn a_whole_half_car_state_sensor_scenario_allocates_nothing() {
    // The state sensors at 8 % noise (the measured-rate filters), with a gap and a jump.
    let car = HalfCar::<f64>::passenger();
    let noise = SensorNoise { state: 1.782e-3, deriv: 7.175e-2, ..SensorNoise::default() };
    let base = DriveConfig::new(0.005).sensors(SensorSet::State).noise(noise);
    let cfg = HalfDriveConfig::new(base).with_change(HalfChange::ramp(30.0, "b_r", 1120.0, 5.0).unwrap()).unwrap();
    let mut drive = HalfDrive::new(car, cfg, 4244).unwrap();
    let mut mon = HalfHealthMonitor::new(HealthConfig::new(0.005, car).with_sensors(SensorSet::State, &noise)).unwrap();
    let before = allocs();
    let mut events = 0;
    for k in 0..(80.0 / 0.005) as usize {
        let s = drive.next_sample();
        let mut y = [0.0; 16];
        y.copy_from_slice(s.y());
        if (12_000..12_400).contains(&k) {
            y = [f64::NAN; 16];
        } else if (13_000..13_100).contains(&k) {
            y[4] += 0.5;
        }
        if mon.update(&y).unwrap().is_some() {
            events += 1;
        }
    }
    assert_eq!(allocs() - before, 0);
    assert!(events >= 1, "the rear damper ramp (-20 %) was not reported");
}

#[test]
fn a_full_car_drive_allocates_nothing() {
    // Both sensor sets, a damper ramp rebuilt every sample, a load step, changing speed (also
    // standing) and a road class change.
    let car = FullCar::<f64>::passenger();
    for sensors in [SensorSet::Realistic, SensorSet::State] {
        let cfg = FullDriveConfig::new(DriveConfig::new(0.005).sensors(sensors))
            .with_change(FullChange::ramp(5.0, "b_rl", 900.0, 5.0).unwrap())
            .unwrap()
            .with_change(FullChange::step(12.0, "M", 1600.0).unwrap())
            .unwrap();
        let mut drive = FullDrive::new(car, cfg, 4245).unwrap();
        let before = allocs();
        let mut acc = 0.0;
        for k in 0..4000usize {
            let v = if (1500..1600).contains(&k) { 0.0 } else { 5.0 + (k % 700) as f64 / 30.0 };
            if k == 2000 {
                drive.set_road(vehid_core::sim::RoadClass::D);
            }
            let s = drive.next_sample_at(v).unwrap();
            acc += s.y()[0];
        }
        assert!(acc.is_finite());
        assert_eq!(allocs() - before, 0, "{sensors:?}");
    }
}

#[test]
fn a_whole_full_car_scenario_allocates_nothing() {
    // Warm-up, a damper ramp, the alarm, settling, the event (its fits and the reference
    // moved), a gap of NaN rows, a jump, reacquiring.
    let car = FullCar::<f64>::passenger();
    let cfg = FullDriveConfig::new(DriveConfig::new(0.005))
        .with_change(FullChange::ramp(30.0, "b_rl", 800.0, 5.0).unwrap())
        .unwrap();
    let mut drive = FullDrive::new(car, cfg, 4245).unwrap();
    let mut mon = FullHealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    let before = allocs();
    let mut events = 0;
    for k in 0..(80.0 / 0.005) as usize {
        let s = drive.next_sample();
        let mut y = [0.0; 12];
        y.copy_from_slice(s.y());
        if (12_000..12_400).contains(&k) {
            y = [f64::NAN; 12];
        } else if (13_000..13_100).contains(&k) {
            y[9] = 0.01;
        }
        if mon.update(&y).unwrap().is_some() {
            events += 1;
        }
    }
    assert_eq!(allocs() - before, 0);
    assert!(events >= 1, "the rear left damper ramp (-20 %) was not reported");
}

//! The drive and the health monitor allocate nothing per sample: a whole scenario (warm-up,
//! a damper ramp rebuilt every sample, an alarm, settling, the event, a gap of NaN rows, a
//! stuck channel, reacquiring) runs under a counting allocator with zero allocations.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use vehid_core::health::{HealthConfig, HealthMonitor};
use vehid_core::model::QuarterCar;
use vehid_core::sim::{Change, DriveConfig, QuarterDrive};

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

//! ns per sample of `HealthMonitor::update` (issue 17's fleet target: ≤ 100 ns per sample
//! per vehicle, so one core follows 50,000 vehicles at 200 Hz), f64 and f32; and of the half
//! car's `HalfHealthMonitor::update` (f64; `health/half_monitor_update_f64`, passenger half
//! car, realistic sensors over both axles, same road and rate).
//!
//! Run: `cargo bench -p vehid-benches --bench health`. The input is a seeded realistic drive
//! (passenger quarter car, ISO 8608 class C at 15 m/s, 200 Hz) cycled through by a monitor
//! already past its warm-up, so the timed path is the monitoring one.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use vehid_core::health::{HalfHealthMonitor, HealthConfig, HealthMonitor, Status};
use vehid_core::model::{HalfCar, QuarterCar};
use vehid_core::sim::{DriveConfig, HalfDrive, HalfDriveConfig, QuarterDrive};
use vehid_core::Real;

/// 600 s of drive: the cycle's seam (a jump in the data, which the monitor reports as a
/// change) comes once per 120,000 updates.
const LEN: usize = 120_000;

fn bench<T: Real>(c: &mut Criterion, name: &str) {
    let car = QuarterCar::<T>::passenger();
    let mut drive = QuarterDrive::new(car, DriveConfig::new(T::of(0.005)), 42).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(T::of(0.005), car)).unwrap();
    for _ in 0..6000 {
        mon.update(drive.next_sample().y()).unwrap();
    }
    assert_eq!(mon.status(), Status::Monitoring);
    let data: Vec<[T; 3]> = (0..LEN)
        .map(|_| {
            let s = drive.next_sample();
            [s.y()[0], s.y()[1], s.y()[2]]
        })
        .collect();
    let mut g = c.benchmark_group("health");
    g.throughput(Throughput::Elements(1));
    let mut i = 0;
    g.bench_function(name, |b| {
        b.iter(|| {
            i = (i + 1) % LEN;
            black_box(mon.update(black_box(&data[i])).unwrap())
        })
    });
    g.finish();
}

fn bench_half(c: &mut Criterion) {
    let car = HalfCar::<f64>::passenger();
    let mut drive = HalfDrive::new(car, HalfDriveConfig::new(DriveConfig::new(0.005)), 42).unwrap();
    let mut mon = HalfHealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    for _ in 0..6000 {
        mon.update(drive.next_sample().y()).unwrap();
    }
    assert_eq!(mon.status(), Status::Monitoring);
    let data: Vec<[f64; 6]> = (0..LEN)
        .map(|_| {
            let mut y = [0.0; 6];
            y.copy_from_slice(drive.next_sample().y());
            y
        })
        .collect();
    let mut g = c.benchmark_group("health");
    g.throughput(Throughput::Elements(1));
    let mut i = 0;
    g.bench_function("half_monitor_update_f64", |b| {
        b.iter(|| {
            i = (i + 1) % LEN;
            black_box(mon.update(black_box(&data[i])).unwrap())
        })
    });
    g.finish();
}

fn monitor(c: &mut Criterion) {
    bench::<f64>(c, "monitor_update_f64");
    bench::<f32>(c, "monitor_update_f32");
    bench_half(c);
}

criterion_group!(benches, monitor);
criterion_main!(benches);

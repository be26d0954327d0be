//! ns per sample of `HealthMonitor::update` (the fleet target: ≤ 100 ns per sample
//! per vehicle, so one core follows 50,000 vehicles at 200 Hz), f64 and f32; and of the half
//! car's `HalfHealthMonitor::update` (f64; `health/half_monitor_update_f64`, passenger half
//! car, realistic sensors over both axles, same road and rate).
//!
//! With the thesis' state sensors at 8 % noise (`health_experiment --state-noise 0.08`'s levels;
//! the kinematic filters with the measured deflection rates): `health/monitor_update_state_f64`
//! and `health/half_monitor_update_state_f64`.
//!
//! The full car's `FullHealthMonitor::update` (f64 and f32; `health/full_monitor_update_f64`,
//! passenger full car, realistic sensors at the four corners, same road and rate; the issue's
//! target ≤ 250 ns per sample).
//!
//! Run: `cargo bench -p vehid-benches --bench health`. The input is a seeded realistic drive
//! (passenger quarter car, ISO 8608 class C at 15 m/s, 200 Hz) cycled through by a monitor
//! already past its warm-up, so the timed path is the monitoring one.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use vehid_core::health::{FullHealthMonitor, HalfHealthMonitor, HealthConfig, HealthMonitor, Status};
use vehid_core::model::{FullCar, HalfCar, QuarterCar};
use vehid_core::sim::{
    DriveConfig, FullDrive, FullDriveConfig, HalfDrive, HalfDriveConfig, QuarterDrive, SensorNoise, SensorSet,
};
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

/// The state sensors at 8 % noise (quarter car, or `half`), as `count_health` sets them.
fn noise_8(half: bool) -> SensorNoise<f64> {
    let (state, deriv) = if half { (1.782e-3, 7.175e-2) } else { (1.859e-3, 9.971e-2) };
    SensorNoise { state, deriv, ..SensorNoise::default() }
}

fn bench_state(c: &mut Criterion) {
    let car = QuarterCar::<f64>::passenger();
    let noise = noise_8(false);
    let mut drive = QuarterDrive::new(car, DriveConfig::new(0.005).sensors(SensorSet::State).noise(noise), 42).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car).with_sensors(SensorSet::State, &noise)).unwrap();
    for _ in 0..6000 {
        mon.update(drive.next_sample().y()).unwrap();
    }
    assert_eq!(mon.status(), Status::Monitoring);
    let data: Vec<[f64; 8]> = (0..LEN)
        .map(|_| {
            let mut y = [0.0; 8];
            y.copy_from_slice(drive.next_sample().y());
            y
        })
        .collect();
    let mut g = c.benchmark_group("health");
    g.throughput(Throughput::Elements(1));
    let mut i = 0;
    g.bench_function("monitor_update_state_f64", |b| {
        b.iter(|| {
            i = (i + 1) % LEN;
            black_box(mon.update(black_box(&data[i])).unwrap())
        })
    });
    g.finish();
}

fn bench_half_state(c: &mut Criterion) {
    let car = HalfCar::<f64>::passenger();
    let noise = noise_8(true);
    let base = DriveConfig::new(0.005).sensors(SensorSet::State).noise(noise);
    let mut drive = HalfDrive::new(car, HalfDriveConfig::new(base), 42).unwrap();
    let mut mon = HalfHealthMonitor::new(HealthConfig::new(0.005, car).with_sensors(SensorSet::State, &noise)).unwrap();
    for _ in 0..6000 {
        mon.update(drive.next_sample().y()).unwrap();
    }
    assert_eq!(mon.status(), Status::Monitoring);
    let data: Vec<[f64; 16]> = (0..LEN)
        .map(|_| {
            let mut y = [0.0; 16];
            y.copy_from_slice(drive.next_sample().y());
            y
        })
        .collect();
    let mut g = c.benchmark_group("health");
    g.throughput(Throughput::Elements(1));
    let mut i = 0;
    g.bench_function("half_monitor_update_state_f64", |b| {
        b.iter(|| {
            i = (i + 1) % LEN;
            black_box(mon.update(black_box(&data[i])).unwrap())
        })
    });
    g.finish();
}

fn bench_full<T: Real>(c: &mut Criterion, name: &str) {
    let car = FullCar::<T>::passenger();
    let mut drive = FullDrive::new(car, FullDriveConfig::new(DriveConfig::new(T::of(0.005))), 42).unwrap();
    let mut mon = FullHealthMonitor::new(HealthConfig::new(T::of(0.005), car)).unwrap();
    for _ in 0..6000 {
        mon.update(drive.next_sample().y()).unwrap();
    }
    assert_eq!(mon.status(), Status::Monitoring);
    let data: Vec<[T; 12]> = (0..LEN)
        .map(|_| {
            let mut y = [T::zero(); 12];
            y.copy_from_slice(drive.next_sample().y());
            y
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

fn monitor(c: &mut Criterion) {
    bench::<f64>(c, "monitor_update_f64");
    bench::<f32>(c, "monitor_update_f32");
    bench_half(c);
    bench_state(c);
    bench_half_state(c);
    bench_full::<f64>(c, "full_monitor_update_f64");
    bench_full::<f32>(c, "full_monitor_update_f32");
}

criterion_group!(benches, monitor);
criterion_main!(benches);

//! Tests of the half car's drive: the rear wheel meets the front wheel's road a wheelbase
//! later, the static sag and pitch a load causes, the sensors' geometry, bad settings.

use super::*;
use crate::model::{HalfCar, SensorNoise};
use crate::sim::{Change, DriveConfig, RoadClass};

fn quiet() -> SensorNoise<f64> {
    SensorNoise {
        a_body: 0.0,
        a_body_bias: 0.0,
        a_wheel: 0.0,
        a_wheel_bias: 0.0,
        deflection: 0.0,
        ..SensorNoise::default()
    }
}

#[test]
fn rear_wheel_meets_the_front_road_a_wheelbase_later() {
    // L = 2.7 m at 15 m/s and 200 Hz: exactly 36 samples behind.
    let car = HalfCar::<f64>::passenger();
    let mut drive = HalfDrive::new(car, HalfDriveConfig::new(DriveConfig::new(0.005)), 7).unwrap();
    let u: Vec<[f64; 2]> = (0..2000).map(|_| drive.next_sample().u).collect();
    let sd = (u.iter().map(|v| v[0] * v[0]).sum::<f64>() / u.len() as f64).sqrt();
    assert!(sd > 1e-3, "the road moves: {sd}");
    for k in 36..u.len() {
        assert!((u[k][1] - u[k - 36][0]).abs() < 1e-9 * sd, "k {k}: {} vs {}", u[k][1], u[k - 36][0]);
    }
    // Half a sample later (L = 2.7 m, 0.15 m per sample at 30 m/s: 18 samples; at 20 m/s
    // 27 samples): the interpolation is exact on the vertices whatever the speed.
    let mut drive = HalfDrive::new(car, HalfDriveConfig::new(DriveConfig::new(0.005).speed(20.0)), 7).unwrap();
    let u: Vec<[f64; 2]> = (0..500).map(|_| drive.next_sample().u).collect();
    for k in 27..u.len() {
        assert!((u[k][1] - u[k - 27][0]).abs() < 1e-9 * sd);
    }
}

#[test]
fn rear_wheel_follows_when_crawling_and_standing() {
    // 0.05 m/s: 10800 samples per wheelbase, far more than the ring holds; points every
    // L/256 keep the profile, and the rear meets the stored heights.
    let car = HalfCar::<f64>::passenger();
    let mut drive = HalfDrive::new(car, HalfDriveConfig::new(DriveConfig::new(0.005).speed(0.05)), 3).unwrap();
    let mut last = drive.next_sample();
    for _ in 0..30_000 {
        let s = drive.next_sample();
        assert!(s.u[1].is_finite() && s.x.iter().all(|v| v.is_finite()));
        last = s;
    }
    // Standing: nothing moves but the car settling.
    let held = drive.next_sample_at(0.0).unwrap();
    let again = drive.next_sample_at(0.0).unwrap();
    assert_eq!(held.u, again.u);
    assert!(last.s < held.s + 1e-12);
    assert!(drive.next_sample_at(-1.0).is_err());
}

#[test]
fn a_load_makes_the_body_sink_and_pitch_as_statics_say() {
    // Flat road, no noise: the car rests at 0 until M grows by 64 kg (10 %) at 1 s; the
    // new static position: each corner's extra load ΔM g l_other/L compresses its spring
    // and its tyre.
    let car = HalfCar::<f64>::passenger();
    let base = DriveConfig::new(0.005).road(RoadClass::Flat).noise(quiet());
    let cfg = HalfDriveConfig::new(base).with_change(HalfChange::step(1.0, "M", 704.0).unwrap()).unwrap();
    let mut drive = HalfDrive::new(car, cfg, 1).unwrap();
    let first = drive.next_sample();
    assert!(first.x.iter().all(|v| v.abs() < 1e-12), "{}", first.x);
    let mut s = first;
    for _ in 0..(30.0 / 0.005) as usize {
        s = drive.next_sample();
    }
    let p = car.params();
    let l = p.l1 + p.l2;
    let (df, dr) = (64.0 * GRAVITY * p.l2 / l, 64.0 * GRAVITY * p.l1 / l);
    let front = -(df / p.k12 + df / p.k11);
    let rear = -(dr / p.k22 + dr / p.k21);
    let (zb, ph) = (s.x[4], s.x[6]);
    assert!((zb + p.l1 * ph - front).abs() < 1e-6, "front corner {} vs {front}", zb + p.l1 * ph);
    assert!((zb - p.l2 * ph - rear).abs() < 1e-6, "rear corner {} vs {rear}", zb - p.l2 * ph);
    // The deflection sensors read the springs' extra compression; the accelerometers 0.
    let y = s.y();
    assert!((y[4] + df / p.k12).abs() < 1e-6 && (y[5] + dr / p.k22).abs() < 1e-6, "{y:?}");
    assert!(y[..4].iter().all(|a| a.abs() < 1e-6), "{y:?}");
    assert_eq!(s.constants[0], 704.0);
}

#[test]
fn sensors_read_the_corners_of_the_state() {
    let car = HalfCar::<f64>::passenger();
    let base = DriveConfig::new(0.005).noise(quiet());
    let mut drive = HalfDrive::new(car, HalfDriveConfig::new(base.clone()), 5).unwrap();
    let mut state = HalfDrive::new(car, HalfDriveConfig::new(base.sensors(SensorSet::State)), 5).unwrap();
    assert_eq!(drive.channels(), &HALF_REALISTIC_CHANNELS);
    assert_eq!(state.channels().len(), 16);
    let (l1, l2) = (1.2, 1.5);
    for _ in 0..1000 {
        let s = drive.next_sample();
        let z = state.next_sample();
        let (x, xd, y, r) = (s.x, s.xdot, s.y(), z.y());
        assert_eq!(r[..8], x.as_slice()[..]);
        assert_eq!(r[8..], xd.as_slice()[..]);
        assert!((y[0] - (xd[5] + l1 * xd[7])).abs() < 1e-12);
        assert!((y[1] - (xd[5] - l2 * xd[7])).abs() < 1e-12);
        assert_eq!([y[2], y[3]], [xd[1], xd[3]]);
        assert!((y[4] - (x[4] + l1 * x[6] - x[0])).abs() < 1e-15);
        assert!((y[5] - (x[4] - l2 * x[6] - x[2])).abs() < 1e-15);
    }
    // The default noise draws four biases.
    let noisy = HalfDrive::<f64>::new(car, HalfDriveConfig::new(DriveConfig::new(0.005)), 5).unwrap();
    assert!(noisy.biases().iter().all(|b| *b != 0.0));
}

#[test]
fn transition_matches_a_fine_integration() {
    // One interval of the exact transition against 1000 explicit Euler sub-steps of the same
    // linear-in-time road (the state's error is O(dt/1000)).
    let car = HalfCar::<f64>::passenger();
    let mut drive = HalfDrive::new(car, HalfDriveConfig::new(DriveConfig::new(0.005).road(RoadClass::D)), 9).unwrap();
    for _ in 0..400 {
        drive.next_sample();
    }
    let a = drive.next_sample();
    let b = drive.next_sample();
    let m = car.model();
    let n = 20_000;
    let h = 0.005 / n as f64;
    let mut x = a.x;
    for i in 0..n {
        let w = i as f64 / n as f64;
        let u = nalgebra::SVector::<f64, 2>::new(a.u[0] + w * (b.u[0] - a.u[0]), a.u[1] + w * (b.u[1] - a.u[1]));
        x += (m.a() * x + m.b() * u) * h;
    }
    let err = (x - b.x).amax() / b.x.amax();
    assert!(err < 1e-3, "relative error {err}");
}

#[test]
fn bad_settings_are_errors() {
    let car = HalfCar::<f64>::passenger();
    assert!(matches!(HalfChange::<f64>::step(1.0, "k12", 1.0), Err(Error::UnknownOption { .. })));
    assert!(HalfChange::<f64>::step(-1.0, "b_f", 1.0).is_err());
    assert!(HalfChange::<f64>::step(1.0, "b_f", f64::NAN).is_err());
    assert!(HalfChange::<f64>::ramp(1.0, "b_f", 1.0, -2.0).is_err());
    let quarter = DriveConfig::new(0.005).with_change(Change::step(1.0, "b", 1.0).unwrap()).unwrap();
    assert!(matches!(
        HalfDrive::new(car, HalfDriveConfig::new(quarter), 1),
        Err(Error::InvalidArgument { arg: "base", .. })
    ));
    assert!(HalfDrive::new(car, HalfDriveConfig::new(DriveConfig::new(0.0)), 1).is_err());
    assert!(HalfDrive::new(car, HalfDriveConfig::new(DriveConfig::new(0.005).speed(f64::INFINITY)), 1).is_err());
    let mut cfg = HalfDriveConfig::new(DriveConfig::new(0.005));
    for i in 0..MAX_CHANGES {
        cfg = cfg.with_change(HalfChange::step(i as f64, "J", 1000.0).unwrap()).unwrap();
    }
    assert!(matches!(cfg.with_change(HalfChange::step(9.0, "J", 1000.0).unwrap()), Err(Error::Capacity { .. })));
}

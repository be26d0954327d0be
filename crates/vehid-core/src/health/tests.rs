//! Tests of the health monitor: the kinematic filter against a closed form, the RLS against
//! the normal equations, detection and naming of each change on simulated drives, the
//! cannot-judge states, transactional errors.

use super::*;
use crate::model::QuarterCar;
use crate::sim::{Change, DriveConfig, QuarterDrive, RoadClass};
use crate::Error;
use nalgebra::{SMatrix, SVector};

#[test]
fn deflection_filter_recovers_rate_and_bias_of_a_sine() {
    // d = A sin ωt, so ḋ = Aω cos ωt and the relative acceleration is −Aω² sin ωt + β.
    let (dt, amp, w, beta) = (0.005, 0.01, 2.0 * core::f64::consts::PI * 1.5, 0.25);
    let mut f = DeflectionFilter::new(dt, 0.1, 0.3e-3, 0.01).unwrap();
    let mut worst: f64 = 0.0;
    for k in 0..40_000 {
        let t = k as f64 * dt;
        let (_, v) = f.update(amp * (w * t).sin(), -amp * w * w * (w * t).sin() + beta);
        if t > 150.0 {
            worst = worst.max((v - amp * w * (w * t).cos()).abs());
        }
    }
    // Noise-free: the only errors are the linear interpolation of the acceleration
    // (O(dt²ω³A) ≈ 1e-5 m/s) and the bias' slow convergence. Rate amplitude 0.094 m/s.
    assert!(worst < 1e-3, "worst rate error {worst}");
    assert!((f.state()[2] - beta).abs() < 0.01, "bias {}", f.state()[2]);
}

#[test]
fn rls_without_forgetting_is_batch_least_squares() {
    let mut rls = Rls3::new(SVector::zeros(), SMatrix::identity() * 1e8, 1.0);
    let mut xtx = SMatrix::<f64, 3, 3>::zeros();
    let mut xty = SVector::<f64, 3>::zeros();
    for k in 0..500 {
        let t = k as f64;
        let phi = SVector::<f64, 3>::new((0.37 * t).sin(), (1.3 * t).cos() * 2.0, 1.0);
        let y = 3.0 * phi[0] - 0.5 * phi[1] + 0.2 + 0.01 * (7.1 * t).sin();
        rls.update(&phi, y).unwrap();
        xtx += phi * phi.transpose();
        xty += phi * y;
    }
    let batch = xtx.try_inverse().unwrap() * xty;
    assert!((rls.theta() - batch).norm() < 1e-6, "{} vs {}", rls.theta(), batch);
}

/// A passenger-car drive on class C at 15 m/s, 200 Hz, realistic sensors, with `change`;
/// returns the events of a monitor over `seconds`.
fn drive_events(seed: u64, change: Option<(&str, f64)>, seconds: f64) -> (Vec<Event<f64>>, HealthMonitor<f64>) {
    let car = QuarterCar::<f64>::passenger();
    let mut cfg = DriveConfig::new(0.005);
    if let Some((name, v)) = change {
        cfg = cfg.with_change(Change::step(40.0, name, v).unwrap()).unwrap();
    }
    let mut drive = QuarterDrive::new(car, cfg, seed).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    let mut events = Vec::new();
    for _ in 0..(seconds / 0.005) as usize {
        let s = drive.next_sample();
        if let Some(e) = mon.update(s.y()).unwrap() {
            events.push(e);
        }
    }
    (events, mon)
}

#[test]
fn each_change_is_detected_named_and_measured() {
    // Truth: damper 1500 → 1350 (−10 %), spring 22000 → 19800 (−10 %), body 320 → 384
    // (+20 %), each at 40 s. The monitor must name it, report it within 3 points, and
    // report it within 20 s.
    for (seed, name, value, want, before) in [
        (9101, "b", 1350.0, Constant::Damper, 1500.0),
        (9102, "k2", 19_800.0, Constant::Spring, 22_000.0),
        (9103, "M", 384.0, Constant::BodyMass, 320.0),
    ] {
        let (events, mon) = drive_events(seed, Some((name, value)), 70.0);
        assert_eq!(events.len(), 1, "{name}: {events:?}");
        let e = events[0];
        assert_eq!(e.parameter, want, "{name}: {e:?}");
        assert_eq!(e.before, before);
        let truth = value / before - 1.0;
        assert!((e.change - truth).abs() < 0.03, "{name}: reported {} vs {truth}", e.change);
        assert!(e.t > 40.0 && e.t < 60.0, "{name}: at {}", e.t);
        assert!(e.t_change > 38.0 && e.t_change <= e.t, "{name}: onset {}", e.t_change);
        assert!(e.low < e.after && e.after < e.high);
        assert_eq!(mon.status(), Status::Monitoring);
        assert_eq!(
            mon.constants()[match want {
                Constant::BodyMass => 0,
                Constant::Spring => 1,
                Constant::Damper => 2,
            }],
            e.after
        );
    }
}

#[test]
fn no_change_no_event_and_the_reference_matches_the_car() {
    let (events, mon) = drive_events(9200, None, 300.0);
    assert!(events.is_empty(), "{events:?}");
    let car = QuarterCar::<f64>::passenger();
    let r = mon.reference().unwrap();
    // The reference is the body equation's ratios (a few percent of bias at most from
    // the filtered regressors).
    assert!((r[0] / (car.k2() / car.m_body()) - 1.0).abs() < 0.05, "k2/M {}", r[0]);
    assert!((r[1] / (car.b() / car.m_body()) - 1.0).abs() < 0.05, "b/M {}", r[1]);
    let est = mon.estimate();
    assert!(est.low[1] < est.value[1] && est.value[1] < est.high[1]);
}

#[test]
fn missing_and_stuck_data_cannot_be_judged_and_raise_nothing() {
    let car = QuarterCar::<f64>::passenger();
    let cfg = DriveConfig::new(0.005).with_change(Change::step(30.0, "b", 1000.0).unwrap()).unwrap();
    let mut drive = QuarterDrive::new(car, cfg, 9300).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    for _ in 0..(25.0 / 0.005) as usize {
        assert!(mon.update(drive.next_sample().y()).unwrap().is_none());
    }
    assert_eq!(mon.status(), Status::Monitoring);
    // A gap (NaN rows) across the change, then a deflection sensor stuck at a constant:
    // no event while it lasts.
    for _ in 0..1000 {
        drive.next_sample();
        assert!(mon.update(&[f64::NAN, f64::NAN, f64::NAN]).unwrap().is_none());
        assert_eq!(mon.status(), Status::CannotJudge(Reason::Missing));
    }
    let mut stuck_seen = false;
    for _ in 0..(20.0 / 0.005) as usize {
        let s = drive.next_sample();
        let y = [s.y()[0], s.y()[1], 0.0123];
        assert!(mon.update(&y).unwrap().is_none());
        stuck_seen |= mon.status() == Status::CannotJudge(Reason::Stuck);
    }
    assert!(stuck_seen);
    // The sensor recovers: reacquire, then the change (damper −33 %) is reported.
    let mut events = Vec::new();
    let mut reacq = false;
    for _ in 0..(30.0 / 0.005) as usize {
        let s = drive.next_sample();
        reacq |= mon.status() == Status::CannotJudge(Reason::Reacquiring);
        if let Some(e) = mon.update(s.y()).unwrap() {
            events.push(e);
        }
    }
    assert!(reacq);
    assert_eq!(events.len(), 1, "{events:?}");
    assert_eq!(events[0].parameter, Constant::Damper);
}

#[test]
fn a_smooth_road_cannot_be_judged() {
    let car = QuarterCar::<f64>::passenger();
    let mut drive = QuarterDrive::new(car, DriveConfig::new(0.005), 9400).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    for _ in 0..(25.0 / 0.005) as usize {
        mon.update(drive.next_sample().y()).unwrap();
    }
    assert_eq!(mon.status(), Status::Monitoring);
    // Onto a flat road (only sensor noise left), with the damper broken: no event.
    let cfg =
        DriveConfig::new(0.005).road(RoadClass::Flat).with_change(Change::step(0.0, "b", 700.0).unwrap()).unwrap();
    let mut flat = QuarterDrive::new(car, cfg, 9401).unwrap();
    for _ in 0..(60.0 / 0.005) as usize {
        assert!(mon.update(flat.next_sample().y()).unwrap().is_none());
    }
    assert_eq!(mon.status(), Status::CannotJudge(Reason::LowExcitation));
}

#[test]
fn bad_input_is_an_error_and_changes_nothing() {
    let car = QuarterCar::<f64>::passenger();
    let mut drive = QuarterDrive::new(car, DriveConfig::new(0.005), 9500).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    for _ in 0..5000 {
        mon.update(drive.next_sample().y()).unwrap();
    }
    let before = mon.clone();
    assert!(matches!(mon.update(&[0.0, f64::INFINITY, 0.0]), Err(Error::NonFinite { arg: "y", index: 1 })));
    assert!(matches!(mon.update(&[0.0, 0.0]), Err(Error::Shape { arg: "y", expected: 3, got: 2 })));
    assert_eq!(mon, before);
    let mut cfg = HealthConfig::new(0.005, car);
    cfg.min_change = 1.5;
    assert!(matches!(HealthMonitor::new(cfg), Err(Error::InvalidArgument { arg: "min_change", .. })));
    let mut cfg = HealthConfig::new(0.005, car);
    cfg.stuck_samples = 100;
    assert!(matches!(HealthMonitor::new(cfg), Err(Error::InvalidArgument { arg: "stuck_samples", .. })));
    let mut cfg = HealthConfig::new(0.005, car);
    cfg.threshold = f64::NAN;
    assert!(matches!(HealthMonitor::new(cfg), Err(Error::InvalidArgument { arg: "threshold", .. })));
    assert!(matches!(
        HealthMonitor::new(HealthConfig::new(-0.005, car)),
        Err(Error::InvalidArgument { arg: "dt", .. })
    ));
}

#[test]
fn f32_monitor_detects_the_damper() {
    let car = QuarterCar::<f32>::passenger();
    let cfg = DriveConfig::new(0.005f32).with_change(Change::step(40.0, "b", 1350.0).unwrap()).unwrap();
    let mut drive = QuarterDrive::new(car, cfg, 9600).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005f32, car)).unwrap();
    let mut events = Vec::new();
    for _ in 0..(70.0 / 0.005) as usize {
        if let Some(e) = mon.update(drive.next_sample().y()).unwrap() {
            events.push(e);
        }
    }
    assert_eq!(events.len(), 1, "{events:?}");
    assert_eq!(events[0].parameter, Constant::Damper);
    assert!((events[0].change + 0.1).abs() < 0.03, "{}", events[0].change);
}

#[test]
fn a_jump_in_the_data_is_no_event() {
    // After 30 s of drive, replay the next 41 s in a loop (as a log with seams would).
    // Without the jump gate each seam's transient in the kinematic filter was reported as
    // a 3 % spring change (sample 9040); with it, each seam is `CannotJudge(Jump)`.
    let car = QuarterCar::<f64>::passenger();
    let mut drive = QuarterDrive::new(car, DriveConfig::new(0.005), 42).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    for _ in 0..6000 {
        mon.update(drive.next_sample().y()).unwrap();
    }
    let data: Vec<[f64; 3]> = (0..8192)
        .map(|_| {
            let s = drive.next_sample();
            [s.y()[0], s.y()[1], s.y()[2]]
        })
        .collect();
    let mut jumps = 0;
    for k in 0..100_000 {
        let ev = mon.update(&data[k % data.len()]).unwrap();
        assert!(ev.is_none(), "event at sample {k}: {ev:?}");
        jumps += usize::from(mon.status() == Status::CannotJudge(Reason::Jump));
    }
    assert_eq!(mon.events(), 0);
    // Every seam (12 of them) was seen as a jump.
    assert_eq!(jumps, 100_000 / 8192);
}

#[test]
fn the_state_sensors_feed_the_same_three_quantities() {
    // The thesis' state set with 1 % noise on every channel level: a_body = dvb,
    // a_wheel = dvw, deflection = zb − zw. A damper −10 % is found and named as with the
    // realistic sensors; an 8-channel sample is required and a 3-channel one refused.
    use crate::sim::{SensorNoise, SensorSet};
    let car = QuarterCar::<f64>::passenger();
    let noise = SensorNoise { state: 1e-4, deriv: 0.02, ..SensorNoise::default() };
    let cfg = DriveConfig::new(0.005)
        .sensors(SensorSet::State)
        .noise(noise)
        .with_change(Change::step(40.0, "b", 1350.0).unwrap())
        .unwrap();
    let mut drive = QuarterDrive::new(car, cfg, 9201).unwrap();
    let hc = HealthConfig::new(0.005, car).with_sensors(SensorSet::State, &noise);
    assert_eq!(hc.channels(), STATE_CHANNELS);
    assert!((hc.deflection_noise - 2f64.sqrt() * 1e-4).abs() < 1e-12);
    let mut mon = HealthMonitor::new(hc).unwrap();
    assert!(matches!(mon.update(&[0.0; 3]), Err(Error::Shape { expected: 8, got: 3, .. })));
    assert_eq!(mon.samples(), 0);
    let mut events = Vec::new();
    for _ in 0..(70.0 / 0.005) as usize {
        if let Some(e) = mon.update(drive.next_sample().y()).unwrap() {
            events.push(e);
        }
    }
    assert_eq!(events.len(), 1, "{events:?}");
    assert_eq!(events[0].parameter, Constant::Damper, "{:?}", events[0]);
    assert!((events[0].change + 0.10).abs() < 0.03, "{:?}", events[0]);
    assert!(events[0].t > 40.0 && events[0].t < 60.0, "{:?}", events[0]);
}

#[cfg(feature = "serde")]
#[test]
fn a_saved_monitor_continues_bit_for_bit_and_a_corrupt_one_is_refused() {
    // Saved mid-drive (after the warm-up, before the damper change at 40 s), restored, and
    // both fed the rest of the drive: the same events and the same state, bit for bit.
    let car = QuarterCar::<f64>::passenger();
    let cfg = DriveConfig::new(0.005).with_change(Change::step(40.0, "b", 1350.0).unwrap()).unwrap();
    let mut drive = QuarterDrive::new(car, cfg, 9301).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    saved_continues(&mut mon, &mut drive, 40.0);
    // A corrupt delay-line index or settings are a serde error, not a panic later (JSON, to
    // edit one field).
    let text = serde_json::to_string(&mon).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["head"] = serde_json::json!(99);
    assert!(serde_json::from_value::<HealthMonitor<f64>>(v).is_err());
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["cfg"]["dt"] = serde_json::json!(-1.0);
    assert!(serde_json::from_value::<HealthMonitor<f64>>(v).is_err());
}

/// The state sensors at 8 % noise as `health_experiment --state-noise 0.08` sets them on
/// the passenger car (class C, 15 m/s): `σ_w` = 8 % of std(zb) on every state, `σ_v` = 8 %
/// of std(dvb) on every derivative (the deflection `zb − zw` then carries 27 % noise).
fn state_noise_8() -> crate::sim::SensorNoise<f64> {
    crate::sim::SensorNoise { state: 1.859e-3, deriv: 9.971e-2, ..crate::sim::SensorNoise::default() }
}

/// The relative spread (standard deviation over mean) of the tracked `k2/M` and `b/M`,
/// sampled every second from 30 s to `seconds` of a no-change drive with the state sensors
/// at 8 % noise, and their mean relative error against the car's.
fn tracked_spread(mon: &mut HealthMonitor<f64>, seed: u64, seconds: f64) -> [(f64, f64); 2] {
    use crate::sim::SensorSet;
    let car = QuarterCar::<f64>::passenger();
    let cfg = DriveConfig::new(0.005).sensors(SensorSet::State).noise(state_noise_8());
    let mut drive = QuarterDrive::new(car, cfg, seed).unwrap();
    let mut th: Vec<[f64; 2]> = Vec::new();
    for k in 0..(seconds / 0.005) as usize {
        assert_eq!(mon.update(drive.next_sample().y()).unwrap(), None);
        if k >= 6000 && k % 200 == 0 {
            let v = mon.estimate().value;
            th.push([v[0], v[1]]);
        }
    }
    let truth = [car.k2() / car.m_body(), car.b() / car.m_body()];
    core::array::from_fn(|j| {
        let n = th.len() as f64;
        let m = th.iter().map(|t| t[j]).sum::<f64>() / n;
        let sd = (th.iter().map(|t| (t[j] - m).powi(2)).sum::<f64>() / n).sqrt();
        (sd / m, m / truth[j] - 1.0)
    })
}

#[test]
fn with_8_percent_state_noise_the_measured_rate_keeps_the_tracked_ratios_tight() {
    // Module documentation, "State sensors": the deflection from two noisy positions alone
    // leaves a low-frequency error in d̂, ḋ̂ that spreads the tracked k2/M 2.7 times as far
    // as σ² P/(1 + λ) says (1.0 % against 0.37 %); with the measured rate vb − vw in the
    // filter the spread is 0.35 %. Seeded, 600 s: the monitor's spread is under 0.6 % and
    // its mean within 1 % of the truth; the same tracker fed by the deflection-only filter
    // (what the monitor did before) spreads past 0.8 %.
    use crate::sim::SensorSet;
    let car = QuarterCar::<f64>::passenger();
    let hc = HealthConfig::new(0.005, car).with_sensors(SensorSet::State, &state_noise_8());
    let mut mon = HealthMonitor::new(hc).unwrap();
    let [(sk, bk), (sb, bb)] = tracked_spread(&mut mon, 9601, 600.0);
    assert!(sk < 0.006 && sb < 0.004, "spread k2/M {sk}, b/M {sb}");
    assert!(bk.abs() < 0.01 && bb.abs() < 0.01, "bias k2/M {bk}, b/M {bb}");
    assert_eq!(mon.status(), Status::Monitoring);
    // The deflection-only filter, through the same tracker.
    let cfg = DriveConfig::new(0.005).sensors(SensorSet::State).noise(state_noise_8());
    let mut drive = QuarterDrive::new(car, cfg, 9601).unwrap();
    let mut kf = DeflectionFilter::new(0.005, hc.accel_noise, hc.deflection_noise, hc.bias_walk).unwrap();
    let p0 = SMatrix::<f64, 3, 3>::identity() * 1e6;
    let mut rls = Rls3::new(SVector::zeros(), p0, 1.0 - 0.005 / hc.window);
    let mut th = Vec::new();
    for k in 0..(600.0 / 0.005) as usize {
        let s = drive.next_sample();
        let y = s.y();
        let (d, v) = kf.update(y[2] - y[0], y[7] - y[5]);
        rls.update(&SVector::<f64, 3>::new(-d, -v, 1.0), y[7]).unwrap();
        if k >= 6000 && k % 200 == 0 {
            th.push(rls.theta()[0]);
        }
    }
    let n = th.len() as f64;
    let m = th.iter().sum::<f64>() / n;
    let sd = (th.iter().map(|t| (t - m).powi(2)).sum::<f64>() / n).sqrt();
    assert!(sd / m > 0.008, "deflection-only spread {}", sd / m);
}

#[test]
fn the_rate_filter_recovers_a_sine_and_refuses_a_jump_unchanged() {
    // d = A sin ωt measured with its rate: noise-free, the estimate follows the rate to the
    // acceleration's interpolation error; a deflection jump past the gate changes nothing.
    let (dt, amp, w) = (0.005, 0.01, 2.0 * core::f64::consts::PI * 1.5);
    let g = RateGain::new(dt, 0.14, 2.6e-3, 2.6e-3, 0.01).unwrap();
    assert!(g.gain().iter().flatten().all(|v: &f64| v.is_finite()) && g.innovation_sd() > 2.6e-3);
    let mut f = DeflectionFilter::new(dt, 0.14, 2.6e-3, 0.01).unwrap();
    let mut worst: f64 = 0.0;
    for k in 0..20_000 {
        let t = k as f64 * dt;
        let (d, v, a) = (amp * (w * t).sin(), amp * w * (w * t).cos(), -amp * w * w * (w * t).sin());
        let (_, ve) = f.update_rate_gated(d, v, a, &g, 8.0).unwrap();
        if t > 50.0 {
            worst = worst.max((ve - v).abs());
        }
    }
    assert!(worst < 1e-4, "worst rate error {worst}");
    let before = f;
    assert_eq!(f.update_rate_gated(1.0, 0.0, 0.0, &g, 8.0), None);
    assert_eq!(f, before);
    assert!(matches!(
        RateGain::new(dt, 0.14, 2.6e-3, 0.0, 0.01),
        Err(Error::InvalidArgument { arg: "rate_noise", .. })
    ));
}

#[test]
fn a_state_sensor_monitor_refuses_bad_input_unchanged() {
    use crate::sim::SensorSet;
    let car = QuarterCar::<f64>::passenger();
    let cfg = DriveConfig::new(0.005).sensors(SensorSet::State).noise(state_noise_8());
    let mut drive = QuarterDrive::new(car, cfg, 9602).unwrap();
    let hc = HealthConfig::new(0.005, car).with_sensors(SensorSet::State, &state_noise_8());
    let mut mon = HealthMonitor::new(hc).unwrap();
    for _ in 0..5000 {
        mon.update(drive.next_sample().y()).unwrap();
    }
    let before = mon.clone();
    let mut y = [0.0; 8];
    y.copy_from_slice(drive.next_sample().y());
    y[3] = f64::INFINITY; // vb: the rate's channel
    assert!(matches!(mon.update(&y), Err(Error::NonFinite { arg: "y", index: 3 })));
    assert_eq!(mon, before);
}

#[cfg(feature = "serde")]
#[test]
fn a_saved_state_sensor_monitor_continues_bit_for_bit() {
    // The measured-rate gain is not saved: a restored monitor derives it from its settings
    // and continues exactly as the original (the damper change at 40 s found by both).
    use crate::sim::SensorSet;
    let car = QuarterCar::<f64>::passenger();
    let cfg = DriveConfig::new(0.005)
        .sensors(SensorSet::State)
        .noise(state_noise_8())
        .with_change(Change::step(40.0, "b", 1350.0).unwrap())
        .unwrap();
    let mut drive = QuarterDrive::new(car, cfg, 9603).unwrap();
    let hc = HealthConfig::new(0.005, car).with_sensors(SensorSet::State, &state_noise_8());
    let mut mon = HealthMonitor::new(hc).unwrap();
    saved_continues(&mut mon, &mut drive, 30.0);
}

/// Runs `mon` on 30 s of `drive` without an event, saves and restores it (postcard; equal to
/// the original), feeds both the next `after` seconds: the same single event and the same
/// state at the end, bit for bit.
#[cfg(feature = "serde")]
fn saved_continues(mon: &mut HealthMonitor<f64>, drive: &mut QuarterDrive<f64>, after: f64) {
    for _ in 0..(30.0 / 0.005) as usize {
        assert_eq!(mon.update(drive.next_sample().y()).unwrap(), None);
    }
    let bytes = postcard::to_allocvec(&*mon).unwrap();
    let mut back: HealthMonitor<f64> = postcard::from_bytes(&bytes).unwrap();
    assert_eq!(back, *mon);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for _ in 0..(after / 0.005) as usize {
        let s = drive.next_sample();
        a.extend(mon.update(s.y()).unwrap());
        b.extend(back.update(s.y()).unwrap());
    }
    assert_eq!(a.len(), 1, "{a:?}");
    assert_eq!(a, b);
    assert_eq!(back, *mon);
}

#[test]
fn f32_state_sensor_monitor_detects_the_damper_at_8_percent() {
    // The measured-rate filter in f32 (its gain solved in f64, then rounded).
    use crate::sim::{SensorNoise, SensorSet};
    let car = QuarterCar::<f32>::passenger();
    let noise = SensorNoise::<f32> { state: 1.859e-3, deriv: 9.971e-2, ..SensorNoise::default() };
    let cfg = DriveConfig::new(0.005f32)
        .sensors(SensorSet::State)
        .noise(noise)
        .with_change(Change::step(40.0, "b", 1350.0).unwrap())
        .unwrap();
    let mut drive = QuarterDrive::new(car, cfg, 9604).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005f32, car).with_sensors(SensorSet::State, &noise)).unwrap();
    let mut events = Vec::new();
    for _ in 0..(70.0 / 0.005) as usize {
        if let Some(e) = mon.update(drive.next_sample().y()).unwrap() {
            events.push(e);
        }
    }
    assert_eq!(events.len(), 1, "{events:?}");
    assert_eq!(events[0].parameter, Constant::Damper);
    assert!((events[0].change + 0.1).abs() < 0.03 && events[0].t > 40.0, "{:?}", events[0]);
}

/// A monitor saved while a channel has been stuck for longer than the delay line (here 300
/// samples) restores and continues as the original.
#[cfg(feature = "serde")]
#[test]
fn a_monitor_saved_during_a_long_stuck_channel_restores() {
    let car = QuarterCar::<f64>::passenger();
    let mut drive = QuarterDrive::new(car, DriveConfig::new(0.005), 9701).unwrap();
    let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    for _ in 0..(25.0 / 0.005) as usize {
        mon.update(drive.next_sample().y()).unwrap();
    }
    let stuck = drive.next_sample().y()[2];
    for _ in 0..300 {
        let mut y = drive.next_sample().y().to_vec();
        y[2] = stuck;
        mon.update(&y).unwrap();
    }
    assert_eq!(mon.status(), Status::CannotJudge(Reason::Stuck));
    let bytes = postcard::to_allocvec(&mon).unwrap();
    let mut back: HealthMonitor<f64> = postcard::from_bytes(&bytes).unwrap();
    assert_eq!(back, mon);
    for _ in 0..2000 {
        let s = drive.next_sample();
        assert_eq!(mon.update(s.y()).unwrap(), back.update(s.y()).unwrap());
    }
    assert_eq!(back, mon);
}

/// A sample interval too small for the kinematic filter's gain to settle is refused naming
/// `dt` (the user's option), not `bias_walk` (a constant the user never set, as in
/// `vehid monitor --dt 1e-9`); 10⁻⁷ s still works.
#[test]
fn a_sample_interval_the_filter_cannot_settle_at_is_named_as_dt() {
    let car = QuarterCar::<f64>::passenger();
    for dt in [1e-9, 1e-12, 1e-300] {
        match HealthMonitor::new(HealthConfig::new(dt, car)) {
            Err(Error::InvalidArgument { arg, expected }) => {
                assert_eq!(arg, "dt", "dt {dt}: {expected}");
                assert!(expected.contains("sample interval"), "{expected}");
            }
            other => panic!("dt {dt}: {other:?}"),
        }
    }
    assert!(HealthMonitor::new(HealthConfig::new(1e-7, car)).is_ok());
}

#[test]
fn the_tracked_intervals_are_z_standard_errors_either_side() {
    // The same drive through monitors that differ only in the confidence level: the tracked
    // values agree to the bit and every interval is centred on its value, with half-widths in
    // the ratio of the normal quantiles (1.959964 for 95 %, 1 for 68.2689 %: published values).
    let car = QuarterCar::<f64>::passenger();
    let mut drive = QuarterDrive::new(car, DriveConfig::new(0.005), 9311).unwrap();
    let mut wide = HealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
    let mut cfg = HealthConfig::new(0.005, car);
    cfg.confidence = 0.682_689_492_137_086;
    let mut narrow = HealthMonitor::new(cfg).unwrap();
    let mut checked = 0;
    for k in 0..24_000 {
        let s = drive.next_sample();
        wide.update(s.y()).unwrap();
        narrow.update(s.y()).unwrap();
        if k % 4_000 != 3_999 {
            continue;
        }
        let (w, n) = (wide.estimate(), narrow.estimate());
        for j in 0..3 {
            assert_eq!(w.value[j].to_bits(), n.value[j].to_bits(), "sample {k}, value {j}");
            for e in [w, n] {
                let (lo, hi) = (e.value[j] - e.low[j], e.high[j] - e.value[j]);
                assert!(lo > 0.0 && (lo - hi).abs() <= 1e-12 * lo.max(e.value[j].abs()), "sample {k}, {j}: {e:?}");
            }
            let ratio = (w.high[j] - w.low[j]) / (n.high[j] - n.low[j]);
            assert!((ratio - 1.959_964).abs() < 1e-5, "sample {k}, {j}: ratio {ratio}");
        }
        checked += 1;
    }
    assert_eq!(checked, 6);
}

#[test]
fn the_tracked_intervals_match_the_spread_over_seeds() {
    // The interval's half-width divided by z is the tracked value's standard error: over 24
    // drives (each its own road and noise, no change) the mean standard error at 90 s is
    // between half and three times the values' spread over the drives. Measured: 1.45 times
    // for k2/M and 2.03 times for b/M, so the tracked intervals are conservative (the
    // autocorrelation inflation `f` and the stationary-regressor approximation of `P/(1 + λ)`
    // overstate the spread); the events' intervals are calibrated by coverage instead
    // (`HealthConfig::systematic`, benches/health_coverage.py). A sample standard deviation of
    // 24 is itself within ±30 % at 95 %.
    let car = QuarterCar::<f64>::passenger();
    let (mut values, mut errors) = (vec![vec![]; 3], vec![vec![]; 3]);
    for seed in 0..24 {
        let mut drive = QuarterDrive::new(car, DriveConfig::new(0.005), 9400 + seed).unwrap();
        let mut mon = HealthMonitor::new(HealthConfig::new(0.005, car)).unwrap();
        for _ in 0..18_000 {
            mon.update(drive.next_sample().y()).unwrap();
        }
        let e = mon.estimate();
        for j in 0..2 {
            values[j].push(e.value[j]);
            errors[j].push((e.high[j] - e.low[j]) / 2.0 / 1.959_964);
        }
    }
    for j in 0..2 {
        let n = values[j].len() as f64;
        let mean = values[j].iter().sum::<f64>() / n;
        let sd = (values[j].iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let se = errors[j].iter().sum::<f64>() / n;
        assert!(se > sd / 2.0 && se < sd * 3.0, "ratio {j}: standard error {se}, spread over seeds {sd}");
    }
}

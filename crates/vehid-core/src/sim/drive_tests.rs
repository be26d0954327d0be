//! Tests of the realistic drives: the road's spectrum against ISO 8608 (a Welch estimate
//! computed here), the timing of changes, the static sag a load causes, sensor statistics,
//! and the errors for bad settings.

use super::*;
use crate::model::QuarterCar;
use crate::sim::streams;
use crate::sim::{IsoRoad, RoadClass, DEFAULT_CUTOFF, N0};
use rand::SeedableRng;

/// Welch's one-sided PSD (Hann window, non-overlapping segments of `len` samples at
/// spacing `ds` m) at the DFT bins whose frequency lies in `[lo, hi]` cycles/m: returns
/// the mean estimate over those bins and the mean of the ISO line `G0 (n0/n)²` at the same
/// bins.
fn welch_band(x: &[f64], ds: f64, len: usize, lo: f64, hi: f64, g0: f64) -> (f64, f64) {
    let w: Vec<f64> =
        (0..len).map(|i| 0.5 - 0.5 * (2.0 * core::f64::consts::PI * i as f64 / len as f64).cos()).collect();
    let u: f64 = w.iter().map(|v| v * v).sum();
    let df = 1.0 / (len as f64 * ds);
    let bins: Vec<usize> = (1..len / 2).filter(|&j| (lo..=hi).contains(&(j as f64 * df))).collect();
    assert!(!bins.is_empty());
    let segs = x.len() / len;
    let mut est = 0.0;
    let mut iso = 0.0;
    for &j in &bins {
        let (c, s): (Vec<f64>, Vec<f64>) = (0..len)
            .map(|i| {
                let a = 2.0 * core::f64::consts::PI * (j * i % len) as f64 / len as f64;
                (a.cos() * w[i], a.sin() * w[i])
            })
            .unzip();
        let mut p = 0.0;
        for k in 0..segs {
            let seg = &x[k * len..(k + 1) * len];
            let re: f64 = seg.iter().zip(&c).map(|(v, c)| v * c).sum();
            let im: f64 = seg.iter().zip(&s).map(|(v, s)| v * s).sum();
            p += 2.0 * ds * (re * re + im * im) / u;
        }
        est += p / segs as f64;
        let n = j as f64 * df;
        iso += g0 * (N0 / n) * (N0 / n);
    }
    (est / bins.len() as f64, iso / bins.len() as f64)
}

#[test]
fn iso_road_spectrum_has_the_class_level_and_slope() {
    // Class C sampled every 0.075 m (15 m/s at 200 Hz), 300 segments of 4096 samples.
    // Per bin the Welch estimate of 300 independent segments has a relative standard error
    // of 1/√300 = 5.8 %; averaged over the bins of a ±10 % band (6 bins at 0.1, 61 at 1.0
    // cycles/m; neighbouring Hann bins are correlated, so at least 3 and 30 independent) the
    // error is ≤ 3.3 % and ≤ 1.1 %. Tolerances: 15 % and 6 % (≥ 4.5 standard errors; the
    // cutoff n_c = 0.01 lowers G at 0.1 by 1 %, aliasing raises it at 1.0 by about 1.5 %).
    let (ds, len, segs) = (0.075, 4096, 300);
    let [_, rng, ..] = streams(2024);
    let mut road = IsoRoad::new(RoadClass::C, DEFAULT_CUTOFF, rng).unwrap();
    let x: Vec<f64> = (0..len * segs)
        .map(|_| {
            let z = road.height();
            road.advance(ds);
            z
        })
        .collect();
    let g0 = RoadClass::C.gd0();
    let (lo_est, lo_iso) = welch_band(&x, ds, len, 0.09, 0.11, g0);
    let (hi_est, hi_iso) = welch_band(&x, ds, len, 0.9, 1.1, g0);
    assert!((lo_est / lo_iso - 1.0).abs() < 0.15, "G_d near 0.1: {lo_est:e} vs ISO {lo_iso:e}");
    assert!((hi_est / hi_iso - 1.0).abs() < 0.06, "G_d near 1.0: {hi_est:e} vs ISO {hi_iso:e}");
    // Slope between the bands' centres (a decade apart): ISO −2; the levels' tolerances
    // give at most log10(1.15·1.06)/1 ≈ 0.09.
    let slope = (hi_est / lo_est).log10() / (hi_iso / lo_iso).log10() * -2.0;
    assert!((slope + 2.0).abs() < 0.1, "slope {slope}");
    // Class E is 256 times class A.
    assert_eq!(RoadClass::E.gd0() / RoadClass::A.gd0(), 256.0);
}

#[test]
fn road_does_not_move_when_the_car_stands() {
    let rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(3);
    let mut road = IsoRoad::new(RoadClass::D, DEFAULT_CUTOFF, rng).unwrap();
    let z = road.height();
    road.advance(0.0);
    assert_eq!(road.height(), z);
    road.advance(0.1);
    assert_ne!(road.height(), z);
}

fn quiet() -> SensorNoise<f64> {
    SensorNoise {
        a_body: 0.0,
        a_body_bias: 0.0,
        a_wheel: 0.0,
        a_wheel_bias: 0.0,
        deflection: 0.0,
        state: 0.0,
        deriv: 0.0,
    }
}

#[test]
fn a_step_takes_effect_at_the_first_sample_at_or_after_its_time() {
    let dt = 0.005;
    let t_change = 1.0;
    let car = QuarterCar::<f64>::passenger();
    let cfg = DriveConfig::new(dt)
        .sensors(SensorSet::State)
        .noise(quiet())
        .with_change(Change::step(t_change, "b", 1200.0).unwrap())
        .unwrap();
    let mut drive = QuarterDrive::new(car, cfg, 5).unwrap();
    let first = (0u64..).find(|&k| k as f64 * dt >= t_change).unwrap();
    let after = QuarterCar::new(320.0, 40.0, 200_000.0, 22_000.0, 1200.0).unwrap().model();
    let before = car.model();
    for _ in 0..first + 5 {
        let s = drive.next_sample();
        let m = if s.k < first { &before } else { &after };
        assert_eq!(s.constants[4], if s.k < first { 1500.0 } else { 1200.0 }, "k = {}", s.k);
        // The derivative is the model's in effect (a damper change moves no static force).
        let want = m.a() * s.x + m.b() * SVector::<f64, 1>::new(s.u);
        assert!((want - s.xdot).norm() < 1e-9 * (1.0 + want.norm()), "k = {}", s.k);
        // State set without noise: r = x, z = ẋ.
        assert_eq!(&s.y()[..4], s.x.as_slice());
        assert_eq!(&s.y()[4..], s.xdot.as_slice());
    }
}

#[test]
fn a_ramp_is_linear_from_the_value_at_its_start() {
    let dt = 0.01;
    let cfg = DriveConfig::new(dt).with_change(Change::ramp(1.0, "k2", 20_000.0, 2.0).unwrap()).unwrap();
    let mut drive = QuarterDrive::<f64>::new(QuarterCar::passenger(), cfg, 1).unwrap();
    for _ in 0..400 {
        let s = drive.next_sample();
        let want = if s.t < 1.0 {
            22_000.0
        } else if s.t < 3.0 {
            22_000.0 - 2_000.0 * (s.t - 1.0) / 2.0
        } else {
            20_000.0
        };
        assert!((s.constants[3] - want).abs() < 1e-6, "t = {}: {} vs {want}", s.t, s.constants[3]);
    }
}

#[test]
fn a_load_lowers_the_body_by_its_static_sag() {
    // Flat road, no noise: 64 kg more on the body compresses the spring by ΔM g / k2.
    let cfg = DriveConfig::new(0.005)
        .road(RoadClass::Flat)
        .noise(quiet())
        .with_change(Change::step(0.5, "M", 384.0).unwrap())
        .unwrap();
    let mut drive = QuarterDrive::<f64>::new(QuarterCar::passenger(), cfg, 1).unwrap();
    let mut last = drive.next_sample();
    for _ in 0..6000 {
        last = drive.next_sample();
    }
    let sag = 64.0 * GRAVITY / 22_000.0;
    assert!((last.y()[2] + sag).abs() < 1e-6 * sag.max(1.0), "{} vs {}", last.y()[2], -sag);
    // The accelerometers read the motion only (static 1 g calibrated out): at rest, zero.
    assert!(last.y()[0].abs() < 1e-6 && last.y()[1].abs() < 1e-6);
}

#[test]
fn realistic_sensors_have_the_stated_noise_and_a_constant_bias() {
    let noise = SensorNoise::default();
    let cfg = DriveConfig::new(0.005).noise(noise);
    let mut drive = QuarterDrive::<f64>::new(QuarterCar::passenger(), cfg, 17).unwrap();
    let bias = drive.biases();
    assert!(bias[0] != 0.0 && bias[1] != 0.0);
    let n = 100_000;
    let mut sum = [0.0; 3];
    let mut sq = [0.0; 3];
    for _ in 0..n {
        let s = drive.next_sample();
        let e = [s.y()[0] - s.xdot[3], s.y()[1] - s.xdot[1], s.y()[2] - (s.x[2] - s.x[0])];
        for i in 0..3 {
            sum[i] += e[i];
            sq[i] += e[i] * e[i];
        }
    }
    let sig = [noise.a_body, noise.a_wheel, noise.deflection];
    let off = [bias[0], bias[1], 0.0];
    for i in 0..3 {
        let mean = sum[i] / n as f64;
        let var = sq[i] / n as f64 - mean * mean;
        // Mean: standard error σ/√n (5 of them allowed); variance: relative error √(2/n) = 0.45 %.
        assert!((mean - off[i]).abs() < 5.0 * sig[i] / (n as f64).sqrt(), "channel {i}: mean {mean} vs {}", off[i]);
        assert!((var / (sig[i] * sig[i]) - 1.0).abs() < 0.025, "channel {i}: var {var}");
    }
    // Across seeds the biases have the stated spread (400 seeds: relative error of the
    // standard deviation 1/√800 = 3.5 %; 15 % allowed).
    let (mut sb, mut sw) = (0.0, 0.0);
    for seed in 0..400 {
        let b = QuarterDrive::<f64>::new(QuarterCar::passenger(), DriveConfig::new(0.005), seed).unwrap().biases();
        sb += b[0] * b[0];
        sw += b[1] * b[1];
    }
    assert!(((sb / 400.0).sqrt() / 0.1 - 1.0).abs() < 0.15);
    assert!(((sw / 400.0).sqrt() / 0.3 - 1.0).abs() < 0.15);
}

#[test]
fn same_seed_same_drive_and_speed_profiles() {
    let cfg = DriveConfig::new(0.005);
    let mut a = QuarterDrive::<f64>::new(QuarterCar::passenger(), cfg.clone(), 9).unwrap();
    let mut b = QuarterDrive::<f64>::new(QuarterCar::passenger(), cfg, 9).unwrap();
    for k in 0..500 {
        let v = 10.0 + 0.01 * k as f64;
        let (sa, sb) = (a.next_sample_at(v).unwrap(), b.next_sample_at(v).unwrap());
        assert_eq!(sa, sb);
    }
    // f32 sees the same run (rounded).
    let mut c = QuarterDrive::<f32>::new(QuarterCar::passenger(), DriveConfig::new(0.005), 9).unwrap();
    let mut d = QuarterDrive::<f64>::new(QuarterCar::passenger(), DriveConfig::new(0.005), 9).unwrap();
    for _ in 0..100 {
        let (sc, sd) = (c.next_sample(), d.next_sample());
        assert!((sc.y()[2] as f64 - sd.y()[2]).abs() < 1e-6);
    }
}

#[test]
fn bad_settings_are_typed_errors() {
    let car = QuarterCar::<f64>::passenger();
    let mut drive = QuarterDrive::new(car, DriveConfig::new(0.005), 1).unwrap();
    let k = drive.k();
    assert!(matches!(drive.next_sample_at(-1.0), Err(Error::InvalidArgument { arg: "speed", .. })));
    assert!(matches!(drive.next_sample_at(f64::NAN), Err(Error::InvalidArgument { arg: "speed", .. })));
    assert_eq!(drive.k(), k);
    assert!(matches!(Change::step(1.0, "spring", 1.0), Err(Error::UnknownOption { arg: "constant", .. })));
    assert!(matches!(Change::step(1.0, "b", f64::NAN), Err(Error::InvalidArgument { arg: "changes.value", .. })));
    assert!(matches!(Change::step(-1.0, "b", 1.0), Err(Error::InvalidArgument { arg: "changes.t", .. })));
    assert!(matches!(Change::ramp(1.0, "b", 1.0, -2.0), Err(Error::InvalidArgument { arg: "changes.ramp", .. })));
    let bad = DriveConfig::new(0.005).speed(-3.0);
    assert!(matches!(QuarterDrive::new(car, bad, 1), Err(Error::InvalidArgument { arg: "speed", .. })));
    let bad = DriveConfig::new(f64::NAN);
    assert!(matches!(QuarterDrive::new(car, bad, 1), Err(Error::InvalidArgument { arg: "dt", .. })));
    let mut bad = DriveConfig::new(0.005);
    bad.noise.a_body = -1.0;
    assert!(matches!(QuarterDrive::new(car, bad, 1), Err(Error::InvalidArgument { arg: "noise.a_body", .. })));
    assert!(matches!("iso8608-F".parse::<RoadClass>(), Err(Error::UnknownOption { arg: "road", .. })));
    assert_eq!("iso8608-C".parse::<RoadClass>().unwrap(), RoadClass::C);
    let mut cfg = DriveConfig::new(0.005);
    for _ in 0..MAX_CHANGES {
        cfg = cfg.with_change(Change::step(1.0, "b", 1.0).unwrap()).unwrap();
    }
    assert!(matches!(cfg.with_change(Change::step(1.0, "b", 1.0).unwrap()), Err(Error::Capacity { .. })));
}

#[test]
fn a_new_road_class_changes_the_height_spread_by_the_root_of_the_level_ratio() {
    // 100 km at 0.5 m per step, correlation length 1/(2π n_c) = 16 m: about 6000
    // independent heights, so the standard deviation is known to ~1 %; 8 % allowed.
    let rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(77);
    let mut road = IsoRoad::new(RoadClass::C, DEFAULT_CUTOFF, rng).unwrap();
    let spread = |road: &mut IsoRoad| {
        for _ in 0..1000 {
            road.advance(0.5);
        }
        let n = 200_000;
        let mut sq = 0.0;
        for _ in 0..n {
            road.advance(0.5);
            sq += road.height() * road.height();
        }
        (sq / n as f64).sqrt()
    };
    let c = spread(&mut road);
    // σ_r² = π n0² G_d(n0) / (2 n_c) for class C: 4.0e-4 m², σ_r = 2.0 cm.
    let want = (core::f64::consts::PI * N0 * N0 * RoadClass::C.gd0() / (2.0 * DEFAULT_CUTOFF)).sqrt();
    assert!((c / want - 1.0).abs() < 0.08, "{c} vs {want}");
    road.set_class(RoadClass::E);
    let e = spread(&mut road);
    assert!((e / c / 4.0 - 1.0).abs() < 0.08, "E/C spread {}", e / c);
}

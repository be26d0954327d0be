//! Tests of the full car's drive and its two tracks: each track's ISO 8608 level and slope,
//! the left/right coherence against the model (several seeds), the rear wheels a wheelbase
//! behind, the static sag a load causes, the sensors' geometry, bad settings.

use super::*;
use crate::model::{FullCar, SensorNoise};
use crate::sim::{DriveConfig, RoadClass, DEFAULT_CUTOFF, HALF_COHERENCE, N0};
use core::f64::consts::PI;
use rand::SeedableRng;

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

/// Welch estimates at the DFT bins `bins` of segments of `seg` points (Hann window, no
/// overlap), averaged over the segments and over each bin's two neighbours: one-sided PSDs of
/// both tracks and their cross-spectrum `(G_l, G_r, G_lr)` per bin (m³ at spacing `ds`).
fn welch(l: &[f64], r: &[f64], ds: f64, seg: usize, bins: &[usize]) -> Vec<(f64, f64, (f64, f64))> {
    let w: Vec<f64> = (0..seg).map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / seg as f64).cos()).collect();
    let w2: f64 = w.iter().map(|v| v * v).sum();
    let mut out = vec![(0.0, 0.0, (0.0, 0.0)); bins.len()];
    let nseg = l.len() / seg;
    for s in 0..nseg {
        let (ls, rs) = (&l[s * seg..(s + 1) * seg], &r[s * seg..(s + 1) * seg]);
        let (ml, mr) = (ls.iter().sum::<f64>() / seg as f64, rs.iter().sum::<f64>() / seg as f64);
        for (o, &b0) in out.iter_mut().zip(bins) {
            for b in b0 - 1..=b0 + 1 {
                let (mut xl, mut xr) = ((0.0, 0.0), (0.0, 0.0));
                for i in 0..seg {
                    let ang = -2.0 * PI * (b * i) as f64 / seg as f64;
                    let (c, sn) = (ang.cos(), ang.sin());
                    let (vl, vr) = ((ls[i] - ml) * w[i], (rs[i] - mr) * w[i]);
                    xl = (xl.0 + vl * c, xl.1 + vl * sn);
                    xr = (xr.0 + vr * c, xr.1 + vr * sn);
                }
                let k = 2.0 * ds / w2 / (3.0 * nseg as f64);
                o.0 += k * (xl.0 * xl.0 + xl.1 * xl.1);
                o.1 += k * (xr.0 * xr.0 + xr.1 * xr.1);
                // X_l conj(X_r)
                o.2 .0 += k * (xl.0 * xr.0 + xl.1 * xr.1);
                o.2 .1 += k * (xl.1 * xr.0 - xl.0 * xr.1);
            }
        }
    }
    out
}

#[test]
fn two_tracks_have_the_iso_spectrum_and_the_model_coherence() {
    // Class C, 1.5 m between the wheel paths, 5 cm spacing, 2^19 points (26 km) per seed,
    // segments of 4096 points (0.0049 cycles/m bins). Each track's PSD must be the ISO 8608
    // line G_d(n0) n0²/(n² + n_c²) and the normalized cross-spectrum the model's
    // γ(n) = 1/(1 + (n/n_a)²) with n_a = 1.2572/(2π·1.5), real.
    let (ds, seg, track) = (0.05, 4096usize, 1.5);
    let n_of = |b: usize| b as f64 / (seg as f64 * ds);
    let bins = [6usize, 16, 27, 51, 102, 205];
    let seeds = [11u64, 12, 13, 14];
    let mut ratio = vec![0.0; bins.len()];
    let mut coh = vec![0.0; bins.len()];
    let mut quad = vec![0.0; bins.len()];
    let mut model = vec![0.0; bins.len()];
    for seed in seeds {
        let rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut road = TwoTrackRoad::new(RoadClass::C, DEFAULT_CUTOFF, track, rng).unwrap();
        let n = 1 << 19;
        let (mut l, mut r) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for _ in 0..n {
            let [a, b] = road.heights();
            l.push(a);
            r.push(b);
            road.advance(ds);
        }
        for (i, (gl, gr, (cre, cim))) in welch(&l, &r, ds, seg, &bins).into_iter().enumerate() {
            let nn = n_of(bins[i]);
            let iso = RoadClass::C.gd0() * N0 * N0 / (nn * nn + DEFAULT_CUTOFF * DEFAULT_CUTOFF);
            ratio[i] += 0.5 * (gl + gr) / iso / seeds.len() as f64;
            coh[i] += cre / (gl * gr).sqrt() / seeds.len() as f64;
            quad[i] += cim / (gl * gr).sqrt() / seeds.len() as f64;
            model[i] = road.coherence(nn);
        }
    }
    for i in 0..bins.len() {
        let nn = n_of(bins[i]);
        assert!((ratio[i] - 1.0).abs() < 0.08, "n = {nn:.3}: PSD / ISO = {:.3}", ratio[i]);
        assert!((coh[i] - model[i]).abs() < 0.05, "n = {nn:.3}: coherence {:.3} vs model {:.3}", coh[i], model[i]);
        assert!(quad[i].abs() < 0.05, "n = {nn:.3}: the tracks are in phase, quadrature {:.3}", quad[i]);
    }
    // The coherence spans the model's range: near 1 at long waves, near 0 at short ones.
    assert!(model[0] > 0.9 && model[bins.len() - 1] < 0.05);
    let n_a = HALF_COHERENCE / (2.0 * PI * track);
    assert!(
        (TwoTrackRoad::new(RoadClass::C, DEFAULT_CUTOFF, track, Xoshiro256PlusPlus::seed_from_u64(1))
            .unwrap()
            .coherence(n_a)
            - 0.5)
            .abs()
            < 1e-12
    );
}

#[test]
fn rear_wheels_meet_their_front_tracks_a_wheelbase_later() {
    // L = 3.1 m at 15.5 m/s and 200 Hz: exactly 40 samples behind, each on its own side.
    let car = FullCar::<f64>::passenger();
    let cfg = FullDriveConfig::new(DriveConfig::new(0.005).speed(15.5));
    let mut drive = FullDrive::new(car, cfg, 7).unwrap();
    let u: Vec<[f64; 4]> = (0..3000).map(|_| drive.next_sample().u).collect();
    let sd = (u.iter().map(|v| v[0] * v[0]).sum::<f64>() / u.len() as f64).sqrt();
    assert!(sd > 1e-3, "the road moves: {sd}");
    let diff = (u.iter().map(|v| (v[0] - v[1]).powi(2)).sum::<f64>() / u.len() as f64).sqrt();
    assert!(diff > 0.05 * sd, "left and right differ: {diff} vs {sd}");
    for k in 40..u.len() {
        assert!((u[k][2] - u[k - 40][0]).abs() < 1e-9 * sd, "k {k}: rear left {} vs {}", u[k][2], u[k - 40][0]);
        assert!((u[k][3] - u[k - 40][1]).abs() < 1e-9 * sd, "k {k}: rear right");
    }
}

#[test]
fn a_load_makes_each_corner_sag_as_statics_say() {
    // Symmetric-sided car on a flat road, body mass +240 kg (centre of mass unmoved) at 1 s:
    // each front spring takes ΔM g l_r/(2L) more, each rear ΔM g l_f/(2L); the deflection
    // sensors read the extension, so each drops by that load over its spring.
    let car = FullCar::<f64>::passenger();
    let p = car.params();
    let dm = 240.0;
    let base = DriveConfig::new(0.005).road(RoadClass::Flat).noise(quiet());
    let cfg = FullDriveConfig::new(base).with_change(FullChange::step(1.0, "M", p.m_body + dm).unwrap()).unwrap();
    let mut drive = FullDrive::new(car, cfg, 3).unwrap();
    let first = drive.next_sample();
    let mut last = first;
    for _ in 0..8000 {
        last = drive.next_sample();
    }
    let l = p.l_f + p.l_r;
    for i in 0..4 {
        let load = dm * GRAVITY * if i < 2 { p.l_r } else { p.l_f } / (2.0 * l);
        let drop = first.y()[8 + i] - last.y()[8 + i];
        assert!((drop - load / p.k[i]).abs() < 1e-3 * load / p.k[i], "corner {i}: {drop} vs {}", load / p.k[i]);
        assert!(first.y()[8 + i].abs() < 1e-12, "at rest before the change");
    }
    assert!(last.x[12].abs() < 1e-12, "no roll");
    assert!(last.xdot.iter().all(|v| v.abs() < 1e-6), "settled: {:?}", last.xdot);
}

#[test]
fn a_point_load_makes_each_corner_sag_as_statics_say() {
    // The symmetric car (equal corners, no anti-roll bars) on a flat road, 150 kg set down at
    // (x, y) = (−1.0, 0.4) m at 1 s. With S = Σ c_i c_iᵀ (c_i = [1, x_i, y_i], here
    // diag(4, 4 l², 4 w²)) the body takes q = −m g (k_eff S)⁻¹ v and corner i's spring the force
    // m g c_iᵀ S⁻¹ v = m g (1/4 + x_i x / (4 l²) + y_i y / (4 w²)); its extension drops by that
    // over k. The mass matrix does not enter: this checks the load's weight and where it acts.
    let car = FullCar::<f64>::default();
    let p = car.params();
    let (m, x, y) = (150.0, -1.0, 0.4);
    let base = DriveConfig::new(0.005).road(RoadClass::Flat).noise(quiet());
    let cfg = FullDriveConfig::new(base).with_load(FullLoad::at(1.0, m, x, y).unwrap()).unwrap();
    let mut drive = FullDrive::new(car, cfg, 3).unwrap();
    let first = drive.next_sample();
    assert_eq!(first.constants[0], p.m_body, "no load before 1 s");
    let mut last = first;
    for _ in 0..8000 {
        last = drive.next_sample();
    }
    let (l, w) = (p.l_f, p.track_f / 2.0);
    for i in 0..4 {
        let (xi, yi) = car.corner_position(i);
        let force = m * GRAVITY * (0.25 + xi * x / (4.0 * l * l) + yi * y / (4.0 * w * w));
        let drop = first.y()[8 + i] - last.y()[8 + i];
        assert!(
            (drop - force / p.k[i]).abs() < 1e-3 * force.abs() / p.k[i],
            "corner {i}: {drop} vs {}",
            force / p.k[i]
        );
    }
    assert!(last.xdot.iter().all(|v| v.abs() < 1e-6), "settled: {:?}", last.xdot);
    let c = last.constants;
    assert_eq!([c[0], c[1], c[2]], [p.m_body + m, p.jx + m * y * y, p.jy + m * x * x]);
    // A ramp: half the mass halfway, and the settings are checked.
    let base = DriveConfig::new(0.005).road(RoadClass::Flat).noise(quiet());
    let cfg = FullDriveConfig::new(base).with_load(FullLoad::ramp(0.0, 100.0, 0.0, 0.0, 1.0).unwrap()).unwrap();
    let mut drive = FullDrive::new(car, cfg, 3).unwrap();
    let mid = (0..=100).map(|_| drive.next_sample()).last().unwrap();
    assert!((mid.constants[0] - (p.m_body + 50.0)).abs() < 1e-9, "{}", mid.constants[0]);
    assert!(matches!(FullLoad::at(0.0, 0.0, 0.0, 0.0), Err(Error::InvalidArgument { arg: "load.mass", .. })));
    assert!(matches!(FullLoad::at(0.0, 1.0, f64::NAN, 0.0), Err(Error::NonFinite { arg: "load.x", .. })));
    assert!(matches!(FullLoad::at(-1.0, 1.0, 0.0, 0.0), Err(Error::InvalidArgument { arg: "load.t", .. })));
    let mut cfg = FullDriveConfig::new(DriveConfig::new(0.005));
    for _ in 0..MAX_LOADS {
        cfg = cfg.with_load(FullLoad::at(0.0, 1.0, 0.0, 0.0).unwrap()).unwrap();
    }
    assert!(matches!(
        cfg.with_load(FullLoad::at(0.0, 1.0, 0.0, 0.0).unwrap()),
        Err(Error::Capacity { arg: "loads", .. })
    ));
}

#[test]
fn realistic_channels_are_the_corners_geometry() {
    let car = FullCar::<f64>::passenger();
    let base = DriveConfig::new(0.005).noise(quiet());
    let mut drive = FullDrive::new(car, FullDriveConfig::new(base), 5).unwrap();
    assert_eq!(drive.channels().len(), 12);
    for _ in 0..500 {
        let s = drive.next_sample();
        let y = s.y();
        for i in 0..4 {
            let (x, yy) = car.corner_position(i);
            let acc = s.xdot[9] + x * s.xdot[11] + yy * s.xdot[13];
            let ext = s.x[8] + x * s.x[10] + yy * s.x[12] - s.x[2 * i];
            assert!((y[i] - acc).abs() < 1e-12 * acc.abs().max(1.0));
            assert!((y[4 + i] - s.xdot[2 * i + 1]).abs() < 1e-12 * s.xdot[2 * i + 1].abs().max(1.0));
            assert!((y[8 + i] - ext).abs() < 1e-15);
        }
        // The derivative is the model's: A x + B u on a car whose constants have not changed.
        let m = car.model();
        let want = m.a() * s.x + m.b() * nalgebra::SVector::<f64, 4>::from(s.u);
        for (a, b) in want.iter().zip(s.xdot.iter()) {
            assert!((a - b).abs() < 1e-9 * a.abs().max(1.0));
        }
    }
    // The state set: the true state and derivative, in channel order.
    let base = DriveConfig::new(0.005).sensors(SensorSet::State);
    let mut drive = FullDrive::new(car, FullDriveConfig::new(base), 5).unwrap();
    let s = drive.next_sample();
    assert_eq!(s.y().len(), 28);
    for i in 0..14 {
        assert_eq!(s.y()[i], s.x[i]);
        assert_eq!(s.y()[14 + i], s.xdot[i]);
    }
}

#[test]
fn full_drive_is_seeded() {
    let car = FullCar::<f64>::passenger();
    let run = |seed: u64| {
        let mut d = FullDrive::new(car, FullDriveConfig::new(DriveConfig::new(0.005)), seed).unwrap();
        (0..300).map(|_| d.next_sample().y()[0]).collect::<Vec<f64>>()
    };
    assert_eq!(run(4), run(4));
    assert_ne!(run(4), run(5));
    // f32 follows f64 (same streams, rounding only).
    let mut d32 =
        FullDrive::new(FullCar::<f32>::passenger(), FullDriveConfig::new(DriveConfig::new(0.005)), 4).unwrap();
    let a = run(4);
    for v in a.iter().take(300) {
        let y = d32.next_sample().y()[0] as f64;
        assert!((y - v).abs() < 1e-3 * v.abs().max(0.1), "{y} vs {v}");
    }
}

#[test]
fn full_drive_refuses_bad_settings() {
    let car = FullCar::<f64>::passenger();
    assert!(matches!(FullChange::<f64>::step(1.0, "l_f", 1.0), Err(Error::UnknownOption { arg: "constant", .. })));
    assert!(matches!(FullChange::<f64>::step(1.0, "b_xx", 1.0), Err(Error::UnknownOption { .. })));
    assert!(matches!(FullChange::step(1.0, "b_fl", -1.0), Err(Error::InvalidArgument { arg: "changes.value", .. })));
    assert!(FullChange::step(1.0, "arb_r", 0.0).is_ok());
    assert_eq!(FullChange::step(1.0, "k_rr", 3e4).unwrap().constant.as_str(), "k_rr");
    let bad_dt = FullDriveConfig::new(DriveConfig::new(0.0));
    assert!(matches!(FullDrive::new(car, bad_dt, 1), Err(Error::InvalidArgument { arg: "dt", .. })));
    let mut p = car.params();
    p.track_f = 20.0;
    let wide = FullCar::new(p).unwrap();
    assert!(matches!(
        FullDrive::new(wide, FullDriveConfig::new(DriveConfig::new(0.005)), 1),
        Err(Error::InvalidArgument { arg: "track", .. })
    ));
    let mut d = FullDrive::new(car, FullDriveConfig::new(DriveConfig::new(0.005)), 1).unwrap();
    assert!(d.next_sample_at(f64::NAN).is_err());
    let mut full = FullDriveConfig::new(DriveConfig::new(0.005));
    for i in 0..MAX_CHANGES {
        full = full.with_change(FullChange::step(i as f64, "M", 1500.0).unwrap()).unwrap();
    }
    assert!(matches!(full.with_change(FullChange::step(9.0, "M", 1.0).unwrap()), Err(Error::Capacity { .. })));
}

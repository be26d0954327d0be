//! Tests of the simulators.

use super::*;
use crate::model::{HalfCar, QuarterCar};
use crate::Error;
use nalgebra::SVector;

fn quarter_sim(seed: u64, cfg: SimConfig<f64, 4, 1>) -> Simulator<f64, 4, 1> {
    Simulator::new(QuarterCar::thesis().model(), cfg, seed).unwrap()
}

#[test]
fn same_seed_same_run_bit_for_bit() {
    let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.2).state_noise(0.01).deriv_noise(0.005);
    let mut a = quarter_sim(7, cfg.clone());
    let mut b = quarter_sim(7, cfg.clone());
    let mut c = quarter_sim(8, cfg);
    let mut differs = false;
    for _ in 0..1000 {
        let (sa, sb, sc) = (a.next_sample(), b.next_sample(), c.next_sample());
        assert_eq!(sa, sb);
        differs |= sa.z != sc.z;
    }
    assert!(differs);
}

#[test]
fn noise_streams_are_independent_of_other_sigmas() {
    // The road realization does not change when measurement noise is switched on.
    let quiet = SimConfig::new(0.05).road_sigma(0.1);
    let noisy = quiet.clone().state_noise(0.01).deriv_noise(0.005);
    let (mut a, mut b) = (quarter_sim(3, quiet), quarter_sim(3, noisy));
    for _ in 0..100 {
        let (sa, sb) = (a.next_sample(), b.next_sample());
        assert_eq!(sa.x, sb.x);
        assert_eq!(sa.u, sb.u);
        assert!(sa.r != sb.r);
    }
}

#[test]
fn measurements_equal_truth_plus_noise_with_requested_std() {
    let cfg = SimConfig::new(0.05).road_sigma(0.1).state_noise(0.02).deriv_noise(0.005);
    let mut sim = quarter_sim(11, cfg);
    let n = 20_000;
    let (mut sw, mut sv, mut xd) = (0.0, 0.0, 0.0);
    for _ in 0..n {
        let s = sim.next_sample();
        let xdot = QuarterCar::<f64>::thesis().model().a() * s.x + QuarterCar::<f64>::thesis().model().b() * s.u;
        xd += (xdot - s.xdot).norm();
        sw += (s.r - s.x).norm_squared();
        sv += (s.z - s.xdot).norm_squared();
    }
    assert!(xd < 1e-9);
    // Sample variance of 4n normal draws: relative standard error sqrt(2/(4n)) ≈ 0.5 %.
    let vw = sw / (4 * n) as f64;
    let vv = sv / (4 * n) as f64;
    assert!((vw / 0.02f64.powi(2) - 1.0).abs() < 0.03, "{vw}");
    assert!((vv / 0.005f64.powi(2) - 1.0).abs() < 0.03, "{vv}");
}

#[test]
fn long_run_std_matches_discrete_lyapunov() {
    // The sampled state is a stationary AR(1) process with covariance P solving
    // P = Φ P Φᵀ + Γ σ² Γᵀ. The sample variance over n correlated samples has a standard
    // error of about σ² sqrt(2 τ / n) with τ the correlation time in samples
    // (1.4 s / 0.05 s = 28): sqrt(56/200000) ≈ 1.7 %; allow 4 standard errors (7 %) on
    // the variance, i.e. 3.5 % on the standard deviation.
    let cfg = SimConfig::new(0.05).road_sigma(0.1).method_exact();
    let mut sim = quarter_sim(5, cfg);
    let (phi, gamma) = (*sim.transition().0, *sim.transition().1);
    let p = crate::analysis::discrete_stationary_cov(&phi, &gamma, &[0.1]).unwrap();
    for _ in 0..2000 {
        sim.next_sample(); // burn-in from x(0) = 0
    }
    let n = 200_000;
    let mut acc = SVector::<f64, 4>::zeros();
    sim.run_with(n, |s| acc += s.x.component_mul(&s.x));
    for i in 0..4 {
        let sd = (acc[i] / n as f64).sqrt();
        let expect = p[(i, i)].sqrt();
        assert!((sd / expect - 1.0).abs() < 0.035, "state {i}: {sd} vs {expect}");
    }
    // ẋ1 at the sample instants: the thesis notes quote ≈ 2.09 σ_u (not Eq 4.28's 1.84).
    assert!((p[(1, 1)].sqrt() / 0.1 - 2.09).abs() < 0.01);
}

#[test]
fn rk4_with_many_substeps_matches_exact() {
    let mk = |m: Method, s: Option<usize>| {
        let mut cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.3);
        cfg.method = m;
        cfg.substeps = s;
        Simulator::new(HalfCar::<f64>::thesis().model(), cfg, 9).unwrap()
    };
    let (mut a, mut b) = (mk(Method::Exact, None), mk(Method::Rk4, Some(400)));
    for _ in 0..2000 {
        let (sa, sb) = (a.next_sample(), b.next_sample());
        assert!((sa.x - sb.x).abs().max() < 1e-8);
    }
}

#[test]
fn half_car_auto_substeps_is_stable_but_one_step_is_refused() {
    let model = HalfCar::<f64>::thesis().model();
    let cfg = SimConfig::new(0.05).road_sigma(0.1);
    let mut sim = Simulator::new(model.clone(), cfg.clone(), 1).unwrap();
    assert!(sim.substeps() >= 2);
    let mut big = 0.0f64;
    sim.run_with(5000, |s| big = big.max(s.x.abs().max()));
    assert!(big < 1.0);
    let mut one = cfg;
    one.substeps = Some(1);
    assert!(matches!(Simulator::new(model, one, 1), Err(Error::InvalidArgument { arg: "substeps", .. })));
}

#[test]
fn instrumentation_reads_kinematic_rows_from_velocity_sensor() {
    let mut cfg = SimConfig::new(0.05).road_sigma(0.1).state_noise(0.01).deriv_noise(0.005);
    cfg.instrumentation = true;
    let mut sim = quarter_sim(2, cfg);
    for _ in 0..10 {
        let s = sim.next_sample();
        assert_eq!(s.z[0], s.r[1]);
        assert_eq!(s.z[2], s.r[3]);
        assert!(s.z[1] != s.xdot[1]);
    }
}

#[test]
fn pulses_and_bad_configs() {
    let cfg = SimConfig::new(0.05).with_pulse(Pulse { start: 8, width: 2, amplitude: 0.5 }).unwrap();
    let mut sim = quarter_sim(1, cfg);
    let us: Vec<f64> = (0..12).map(|_| sim.next_sample().u[0]).collect();
    assert_eq!(&us[7..11], &[0.0, 0.5, 0.5, 0.0]);
    let model = QuarterCar::<f64>::thesis().model();
    let bad = |cfg: SimConfig<f64, 4, 1>| Simulator::new(model.clone(), cfg, 0).err().unwrap();
    assert!(matches!(bad(SimConfig::new(0.0)), Error::InvalidArgument { arg: "dt", .. }));
    assert!(matches!(bad(SimConfig::new(f64::NAN)), Error::InvalidArgument { arg: "dt", .. }));
    assert!(matches!(bad(SimConfig::new(0.05).road_sigma(-1.0)), Error::InvalidArgument { arg: "road_sigma", .. }));
    assert!(matches!(
        bad(SimConfig::new(0.05).ic_sigma(f64::INFINITY)),
        Error::InvalidArgument { arg: "ic_sigma", .. }
    ));
    assert!(matches!(bad(SimConfig::new(0.05).deriv_noise(-0.1)), Error::InvalidArgument { arg: "deriv_noise", .. }));
    let mut zero_sub = SimConfig::new(0.05);
    zero_sub.substeps = Some(0);
    assert!(matches!(bad(zero_sub), Error::InvalidArgument { arg: "substeps", .. }));
    assert!(SimConfig::<f64, 4, 1>::new(0.05).with_pulse(Pulse { start: 0, width: 0, amplitude: 1.0 }).is_err());
    let mut full = SimConfig::<f64, 4, 1>::new(0.05);
    for _ in 0..MAX_PULSES {
        full = full.with_pulse(Pulse { start: 0, width: 1, amplitude: 1.0 }).unwrap();
    }
    assert!(matches!(full.with_pulse(Pulse { start: 0, width: 1, amplitude: 1.0 }), Err(Error::Capacity { .. })));
}

#[test]
fn f32_simulation_tracks_f64() {
    let cfg64 = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    let cfg32 = SimConfig::<f32, 4, 1>::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    let mut a = quarter_sim(4, cfg64);
    let mut b = Simulator::new(QuarterCar::<f32>::thesis().model(), cfg32, 4).unwrap();
    for _ in 0..500 {
        let (sa, sb) = (a.next_sample(), b.next_sample());
        for i in 0..4 {
            assert!((sa.x[i] - sb.x[i] as f64).abs() < 1e-4);
        }
    }
}

fn half_road(mode: RoadMode, spacing: f64, seed: u64) -> RoadSimulator<f64, 8, 16> {
    let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    RoadSimulator::new(HalfCar::thesis().model(), cfg, RoadConfig::new(spacing, 3.0).mode(mode), seed).unwrap()
}

#[test]
fn road_independent_at_constant_speed_is_the_time_simulator() {
    // 6 m/s over 0.3 m road points is the thesis' 0.05 s held input, and the streams are
    // the Simulator's: the same run.
    let mut road = half_road(RoadMode::Independent, 0.3, 4);
    let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    let mut time = Simulator::new(HalfCar::<f64>::thesis().model(), cfg, 4).unwrap();
    for k in 0..3000 {
        let (a, b) = (road.next_sample(6.0).unwrap(), time.next_sample());
        assert_eq!(a.u, b.u);
        assert!((a.x - b.x).abs().max() < 1e-9 * (1.0 + b.x.abs().max()), "k={k}");
        assert!((a.t - b.t).abs() < 1e-9 && (a.s - 0.3 * k as f64).abs() < 1e-9);
    }
}

#[test]
fn road_white_rear_meets_front_road_d_samples_later_at_any_speed() {
    let mut sim = half_road(RoadMode::White, 0.3, 2);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
    let mut us = Vec::new();
    let mut t_prev = 0.0;
    for k in 0..500 {
        let v = 0.5 + 20.0 * rand::RngExt::random::<f64>(&mut rng);
        let s = sim.next_sample(v).unwrap();
        assert!((s.s - 0.3 * k as f64).abs() < 1e-9);
        if k > 0 {
            assert!(s.t > t_prev);
        }
        t_prev = s.t;
        us.push(s.u);
        if k >= 10 {
            assert_eq!(s.u[1], us[k - 10][0]);
        }
        if k % 50 == 0 {
            sim.wait(0.7).unwrap(); // a stop: time passes, no sample, no motion
        }
    }
    assert!(us.iter().all(|u| u[0] != 0.0));
}

#[test]
fn road_non_integer_wheelbase_and_time_driving() {
    // Δ = 0.4 m, L = 3 m: d = 7, the rear axle is 0.2 m into a cell when the front is on a
    // boundary, so at sample k it is on the front's cell k − 8.
    let mut sim = half_road(RoadMode::White, 0.4, 5);
    let mut fronts = Vec::new();
    for k in 0..100 {
        let s = sim.next_sample(5.0).unwrap();
        fronts.push(s.u[0]);
        if k >= 8 {
            assert_eq!(s.u[1], fronts[k - 8]);
        }
    }
    // Driving by time: 2 s at 3 m/s is 6 m; a stop moves nothing.
    let s0 = sim.distance();
    sim.advance(3.0, 2.0).unwrap();
    assert!((sim.distance() - s0 - 6.0).abs() < 1e-9);
    let (x, k) = (*sim.state(), sim.k());
    sim.advance(0.0, 1.0).unwrap();
    assert_eq!(sim.k(), k);
    assert!(*sim.state() != x);
    let before = sim.clone();
    assert!(matches!(sim.next_sample(0.0), Err(Error::InvalidArgument { arg: "speed", .. })));
    assert!(matches!(sim.advance(-1.0, 1.0), Err(Error::InvalidArgument { arg: "speed", .. })));
    assert!(matches!(sim.advance(1.0, f64::NAN), Err(Error::InvalidArgument { arg: "duration", .. })));
    assert_eq!((before.state(), before.k(), before.distance()), (sim.state(), sim.k(), sim.distance()));
}

#[test]
fn road_bad_configs() {
    let model = HalfCar::<f64>::thesis().model();
    let cfg = SimConfig::new(0.05).road_sigma(0.1);
    let mk = |spacing: f64, wheelbase: f64| {
        RoadSimulator::<f64, 8, 16>::new(model.clone(), cfg.clone(), RoadConfig::new(spacing, wheelbase), 1).err()
    };
    assert!(matches!(mk(0.1, 3.0), Some(Error::Capacity { needed: 32, capacity: 16, .. })));
    assert!(matches!(mk(0.0, 3.0), Some(Error::InvalidArgument { arg: "spacing", .. })));
    assert!(matches!(mk(0.3, f64::NAN), Some(Error::InvalidArgument { arg: "wheelbase", .. })));
    assert!(mk(0.3, 3.0).is_none());
}

/// `k()` is the index of the next sample: 0 before the first, one more after each (written
/// because `Simulator::k` returning a constant survived mutation; the tests compared it only with
/// itself).
#[test]
fn the_sample_index_counts_the_samples_drawn() {
    let mut sim = quarter_sim(3, SimConfig::new(0.05).road_sigma(0.1));
    for i in 0..7u64 {
        assert_eq!(sim.k(), i);
        let _ = sim.next_sample();
    }
    let _ = sim.run(5);
    assert_eq!(sim.k(), 12);
}

#[test]
fn a_profile_run_checks_the_entries_it_uses_and_refuses_without_simulating() {
    // Entries 0..7 hold 5 moving samples and 2 stops; a NaN and a negative speed lie beyond.
    let speeds = [6.0, 0.0, 5.0, 6.0, 0.0, 4.0, 6.0, 6.0, f64::NAN, -1.0];
    let mut sim = half_road(RoadMode::White, 0.3, 7);
    let mut profile = SpeedProfile::PerSample { speeds: &speeds, next: 0, stop: 0.5 };
    let mut count = 0;
    sim.run_profile(5, &mut profile, |_| count += 1).unwrap();
    assert_eq!((count, sim.k()), (5, 5));
    let SpeedProfile::PerSample { next, .. } = profile else { unreachable!() };
    assert_eq!(next, 7);
    // The next run would use the NaN: refused, naming its index in the whole profile, with
    // nothing simulated and the cursor where it was.
    let err = sim.run_profile(2, &mut profile, |_| count += 1).unwrap_err();
    assert!(matches!(err, Error::NonFinite { arg: "speed", index: 8 }), "{err:?}");
    assert_eq!((count, sim.k()), (5, 5));
    assert!(matches!(profile, SpeedProfile::PerSample { next: 7, .. }));
    // One more sample is there (entry 7); after it, a negative entry, then the end.
    sim.run_profile(1, &mut profile, |_| count += 1).unwrap();
    let tail = [6.0, 0.0, -1.0];
    let mut other = SpeedProfile::PerSample { speeds: &tail, next: 0, stop: 0.5 };
    assert!(matches!(sim.run_profile(2, &mut other, |_| ()), Err(Error::InvalidArgument { arg: "speed", .. })));
    let short = [6.0, 0.0, 6.0];
    let mut other = SpeedProfile::PerSample { speeds: &short, next: 0, stop: 0.5 };
    assert!(matches!(sim.run_profile(3, &mut other, |_| ()), Err(Error::InvalidArgument { arg: "n", .. })));
    assert_eq!(sim.k(), 6);
    sim.run_profile(2, &mut other, |_| ()).unwrap(); // two moving entries: two samples
    assert_eq!(sim.k(), 8);
}

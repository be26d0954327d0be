//! Two axles on one road (Ch. VI.D, issue 6): the asynchronous sampler's properties, the
//! thesis' Fig 6-7/6-8/6-9 protocol, road cancellation, and varying speed.
//!
//! Statistical claims run over 8 seeds and report medians with `eprintln!` (run with
//! `cargo test -p vehid-core --test two_axle -- --nocapture` to see them; `--release` for
//! the `#[ignore]`d heavier variants: `-- --ignored --nocapture`).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use vehid_core::identify::{TwoAxleConfig, TwoAxleIdentifier, WheelMethod};
use vehid_core::metrics::xi;
use vehid_core::model::HalfCar;
use vehid_core::sampler::AxleSampler;
use vehid_core::sim::{RoadConfig, RoadMode, RoadSimulator, SimConfig};
use vehid_core::Error;

// ---- allocation counter (per thread, so parallel tests do not interfere) -----------------

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

// ---- helpers --------------------------------------------------------------------------

const WHEELBASE: f64 = 3.0;
const SPACING: f64 = 0.3;
const D: usize = 10;
type Id = TwoAxleIdentifier<f64, 8, 16, 2, 16>;

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// ξ of each unknown row (front wheel, rear wheel, heave, pitch) and the largest relative
/// error of a non-zero wheel-row parameter.
fn row_errors(id: &Id) -> ([f64; 4], f64) {
    let truth = HalfCar::<f64>::thesis().theta();
    let est = id.theta::<4>().unwrap();
    let mut out = [0.0; 4];
    let mut worst: f64 = 0.0;
    for i in 0..4 {
        let t: Vec<f64> = truth.row(i).iter().copied().collect();
        let h: Vec<f64> = est.row(i).iter().copied().collect();
        out[i] = xi(&t, &h).unwrap();
        if i < 2 {
            for (a, b) in t.iter().zip(&h) {
                if *a != 0.0 {
                    worst = worst.max(((b - a) / a).abs());
                }
            }
        }
    }
    (out, worst)
}

fn identifier(method: WheelMethod) -> Id {
    let car = HalfCar::<f64>::thesis();
    Id::new(&car.model(), D, TwoAxleConfig::new(method, 1000.0, 0.1, 0.005)).unwrap()
}

fn road_sim(mode: RoadMode, seed: u64) -> RoadSimulator<f64, 8, 16> {
    let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    let road = RoadConfig::new(SPACING, WHEELBASE).mode(mode);
    RoadSimulator::new(HalfCar::thesis().model(), cfg, road, seed).unwrap()
}

/// Runs the thesis protocol for one seed: `n` samples at 6 m/s (0.05 s per 0.3 m), the same
/// samples fed to one identifier per method. Returns (row ξ, worst wheel parameter error).
fn protocol(mode: RoadMode, seed: u64, n: usize, methods: &[WheelMethod]) -> Vec<([f64; 4], f64)> {
    let mut sim = road_sim(mode, seed);
    let mut ids: Vec<Id> = methods.iter().map(|&m| identifier(m)).collect();
    for _ in 0..n {
        let s = sim.next_sample(6.0).unwrap();
        for id in ids.iter_mut() {
            id.update(&s.r, &s.z).unwrap();
        }
    }
    ids.iter().map(row_errors).collect()
}

/// Runs `f(seed)` for seeds 1..=n on two threads.
fn over_seeds<R: Send>(n: u64, f: impl Fn(u64) -> R + Sync) -> Vec<R> {
    std::thread::scope(|scope| {
        let f = &f;
        let handles: Vec<_> = (1..=n).map(|seed| scope.spawn(move || (seed, f(seed)))).collect();
        let mut out: Vec<(u64, R)> = handles.into_iter().map(|h| h.join().unwrap()).collect();
        out.sort_by_key(|(s, _)| *s);
        out.into_iter().map(|(_, r)| r).collect()
    })
}

// ---- the sampler ----------------------------------------------------------------------

/// One random speed profile through one sampler; checks every pair against the positions
/// recorded here (not the sampler's own error figure). Returns (samples, pairs, worst error).
fn sampler_case(rng: &mut Xoshiro256PlusPlus, positions: &mut Vec<f64>) -> (usize, usize, f64) {
    let d = rng.random_range(1..=32usize);
    let wheelbase = rng.random_range(0.5..6.0);
    let spacing = wheelbase / d as f64;
    let tol = spacing * rng.random_range(0.001..0.2);
    let mut s = AxleSampler::<f64, 32>::new(wheelbase, spacing, tol).unwrap();
    assert_eq!(s.delay(), d);
    positions.clear();
    let (mut pairs, mut worst) = (0usize, 0.0f64);
    let mut speed: f64 = 0.0;
    let before = allocs();
    for _ in 0..20_000 {
        // A new speed now and then: ramps by redrawing, stops, fast and slow.
        if rng.random::<f64>() < 0.01 {
            speed = match rng.random_range(0..4) {
                0 => 0.0,
                1 => rng.random_range(0.0..1.0),
                _ => rng.random_range(0.0..40.0),
            };
        }
        let dt = rng.random_range(1e-4..5e-3);
        let event = rng.random::<f64>();
        let result = if event < 0.002 {
            // Odometry jumps ahead by up to 3 spacings.
            let to = s.position() + rng.random_range(0.0..3.0) * spacing;
            s.feed_distance(to)
        } else if event < 0.004 {
            // Odometry runs backwards: an error, nothing changes.
            let (pos, n) = (s.position(), s.samples());
            let r = s.feed_distance(pos - rng.random_range(1e-9..1.0));
            assert!(matches!(r, Err(Error::InvalidArgument { arg: "s", .. })));
            assert_eq!((s.position(), s.samples()), (pos, n));
            continue;
        } else {
            s.advance(speed, dt)
        };
        if let Some(t) = result.unwrap() {
            assert_eq!(t.sample as usize, positions.len());
            if positions.len() < positions.capacity() {
                positions.push(t.position);
            }
            if let Some(p) = t.pair {
                let err = ((t.position - wheelbase) - positions[p.sample as usize]).abs();
                assert!(err <= tol * (1.0 + 1e-12), "pair error {err} > tolerance {tol}");
                assert_eq!(p.grid + d as u64, t.grid);
                worst = worst.max(err / tol);
                pairs += 1;
            }
        }
    }
    assert_eq!(allocs(), before, "the sampler allocated");
    (positions.len(), pairs, worst)
}

#[test]
fn sampler_random_profiles_never_pair_beyond_tolerance_never_allocate() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(2024);
    let mut positions = Vec::with_capacity(1_000_000);
    let (mut samples, mut pairs, mut worst) = (0, 0, 0.0f64);
    for _ in 0..60 {
        let (n, p, w) = sampler_case(&mut rng, &mut positions);
        samples += n;
        pairs += p;
        worst = worst.max(w);
    }
    eprintln!("sampler property: 60 random profiles, {samples} samples, {pairs} pairs, worst pair error {worst:.3} × tolerance");
    assert!(pairs > samples / 4, "too few pairs: {pairs} of {samples}");
}

#[test]
fn sampler_pairs_everything_when_fed_finely_and_schedules_exactly() {
    // Travel per reading ≤ tolerance / 2: every sample after the first d is paired.
    let mut s = AxleSampler::<f64, 16>::new(WHEELBASE, SPACING, 0.01).unwrap();
    let (mut n, mut paired) = (0u64, 0u64);
    let mut v: f64 = 0.0;
    for step in 0..200_000u64 {
        v = (v + if step % 7000 < 3500 { 0.002 } else { -0.003 }).clamp(0.0, 5.0); // ramps and stops
        if let Some(t) = s.advance(v, 0.001).unwrap() {
            n += 1;
            if t.grid >= D as u64 {
                assert!(t.pair.is_some(), "sample {} unpaired", t.sample);
                paired += 1;
            }
        }
    }
    assert!(n > 1000 && paired == n - D as u64, "{n} samples, {paired} pairs");
    // Scheduling by time_to_next lands exactly on the grid.
    let mut s = AxleSampler::<f64, 16>::new(WHEELBASE, SPACING, 1e-9).unwrap();
    s.feed_distance(0.0).unwrap();
    for k in 1..100 {
        let v = 1.0 + (k % 13) as f64;
        let t = s.time_to_next(v).unwrap();
        let trig = s.advance(v, t).unwrap().expect("a sample on the grid point");
        assert_eq!(trig.grid, k);
        assert_eq!(trig.pair.is_some(), k >= D as u64);
    }
    assert_eq!(s.time_to_next(0.0), None); // stopped: never (no division by zero)
}

#[test]
fn sampler_errors_and_reset() {
    assert!(matches!(AxleSampler::<f64, 8>::new(3.0, 0.3, 0.01), Err(Error::Capacity { needed: 10, capacity: 8, .. })));
    assert!(matches!(AxleSampler::<f64, 16>::new(3.0, 0.7, 0.01), Err(Error::InvalidArgument { arg: "spacing", .. })));
    assert!(matches!(
        AxleSampler::<f64, 16>::new(3.0, 0.3, -1.0),
        Err(Error::InvalidArgument { arg: "tolerance", .. })
    ));
    assert!(matches!(AxleSampler::<f64, 16>::new(0.0, 0.3, 0.0), Err(Error::InvalidArgument { arg: "wheelbase", .. })));
    assert!(matches!(AxleSampler::<f64, 16>::new(3.0, 7.0, 10.0), Err(Error::InvalidArgument { arg: "spacing", .. })));
    let mut s = AxleSampler::<f32, 16>::new(3.0, 0.3, 0.01).unwrap();
    assert!(s.feed_distance(0.0).unwrap().is_some());
    for _ in 0..100 {
        assert!(s.advance(0.0, 1.0).unwrap().is_none()); // stopped: no samples
    }
    assert!(matches!(s.advance(-1.0, 1.0), Err(Error::InvalidArgument { arg: "speed", .. })));
    assert!(matches!(s.feed_distance(f32::NAN), Err(Error::NonFinite { arg: "s", .. })));
    for k in 1..=12u64 {
        let t = s.feed_distance(0.3 * k as f32 + 0.001).unwrap().unwrap();
        assert_eq!(t.grid, k);
    }
    s.reset(1.0).unwrap();
    let t = s.feed_distance(1.0).unwrap().unwrap();
    assert_eq!((t.grid, t.sample, t.pair), (0, 13, None));
}

// ---- the thesis protocol and road cancellation ------------------------------------------

const SEEDS: u64 = 8;

#[test]
fn road_cancellation_over_8_seeds() {
    // The acceptance claim alone (debug-friendly): one road, plain rows vs road cancellation.
    let n = 20_000;
    let white = over_seeds(SEEDS, |seed| protocol(RoadMode::White, seed, n, &[WheelMethod::None, WheelMethod::Cancel]));
    let mut none: Vec<f64> = white.iter().map(|r| r[0].0[0] + r[0].0[1]).collect();
    let mut cancel: Vec<f64> = white.iter().map(|r| r[1].0[0] + r[1].0[1]).collect();
    let mut ratio: Vec<f64> = none.iter().zip(&cancel).map(|(a, b)| a / b).collect();
    let worst = white.iter().map(|r| r[1].1).fold(0.0, f64::max);
    eprintln!(
        "road cancellation, {SEEDS} seeds × {n} samples: wheel-row ξ median {:.3e} (none {:.3e}), median ratio {:.0}×, worst wheel parameter {:.1} %",
        median(&mut cancel),
        median(&mut none),
        median(&mut ratio),
        100.0 * worst
    );
    for (s, r) in white.iter().enumerate() {
        let (x, w) = r[1];
        assert!(x[0] + x[1] <= 0.05, "seed {}: cancel wheel ξ {}", s + 1, x[0] + x[1]);
        assert!(w < 0.10, "seed {}: a wheel parameter off by {:.1} %", s + 1, 100.0 * w);
    }
    assert!(median(&mut ratio) >= 10.0);
}

#[test]
#[ignore = "heavy in debug (8 seeds × 20,000 samples × 4 identifiers): run with --release -- --ignored --nocapture"]
fn fig_6_7_to_6_9_and_road_cancellation_over_8_seeds() {
    // Thesis protocol: half car, σ_u = 0.1 (road only), σ_v = 0.005, P0 = 1000, 20,000 samples,
    // 6 m/s with a sample every 0.3 m (the thesis' 0.05 s), d = 10.
    let n = 20_000;
    let methods = [WheelMethod::None, WheelMethod::Thesis, WheelMethod::Cancel];
    let white = over_seeds(SEEDS, |seed| protocol(RoadMode::White, seed, n, &methods));
    let indep = over_seeds(SEEDS, |seed| protocol(RoadMode::Independent, seed, n, &[WheelMethod::None]));
    let med = |f: &dyn Fn(u64) -> f64| {
        let mut v: Vec<f64> = (0..SEEDS).map(f).collect();
        median(&mut v)
    };
    let rows = ["front", "rear", "heave", "pitch"];
    let report = |name: &str, get: &dyn Fn(u64) -> ([f64; 4], f64)| {
        let m: Vec<f64> = (0..4).map(|i| med(&|s| get(s).0[i])).collect();
        let w = med(&|s| get(s).1);
        eprintln!(
            "{name:<32} median ξ per row: {}  wheel-row ξ {:.3e}  worst wheel param err {:.1} %",
            rows.iter().zip(&m).map(|(r, v)| format!("{r} {v:.3e}")).collect::<Vec<_>>().join(", "),
            m[0] + m[1],
            100.0 * w
        );
        m
    };
    eprintln!("two axles, {SEEDS} seeds, {n} samples (medians):");
    let fig67 = report("Fig 6-7 independent roads, none", &|s| indep[s as usize][0]);
    let fig68 = report("Fig 6-8 one road, none", &|s| white[s as usize][0]);
    let fig69 = report("Fig 6-9 one road, thesis Eq 6.14", &|s| white[s as usize][1]);
    let cancel = report("one road, road cancellation", &|s| white[s as usize][2]);
    let ratio = med(&|s| {
        let (a, b) = (white[s as usize][0].0, white[s as usize][2].0);
        (a[0] + a[1]) / (b[0] + b[1])
    });
    eprintln!("wheel-row ξ, none / cancel: median ratio {ratio:.0}×");
    eprintln!(
        "rear-row ξ: independent {:.3e}, one road {:.3e} (× {:.2}), Eq 6.14 {:.3e} (× {:.2} of one road)",
        fig67[1],
        fig68[1],
        fig68[1] / fig67[1],
        fig69[1],
        fig69[1] / fig68[1]
    );
    // Acceptance (issue 6): wheel rows within 10 % (share of ξ ≤ 0.05) on every seed, and
    // at least 10× smaller wheel-row error than the plain rows.
    for s in 0..SEEDS as usize {
        let (x, worst) = white[s][2];
        assert!(x[0] + x[1] <= 0.05, "seed {}: cancel wheel ξ {}", s + 1, x[0] + x[1]);
        assert!(worst < 0.10, "seed {}: a wheel parameter off by {:.1} %", s + 1, 100.0 * worst);
    }
    assert!(cancel[0] + cancel[1] <= 0.05);
    assert!(ratio >= 10.0, "none / cancel = {ratio}");
}

#[test]
#[ignore = "heavy (8 seeds × 200,000 samples): run with --release -- --ignored --nocapture"]
fn fig_6_8_long_runs_separate_bias_from_slow_convergence() {
    // At 20,000 samples the plain rows have not converged even on independent roads, so the
    // comparison above cannot tell bias from slow convergence; 200,000 samples can.
    let n = 200_000;
    let methods = [WheelMethod::None, WheelMethod::Thesis, WheelMethod::Cancel];
    let white = over_seeds(SEEDS, |seed| protocol(RoadMode::White, seed, n, &methods));
    let indep = over_seeds(SEEDS, |seed| protocol(RoadMode::Independent, seed, n, &[WheelMethod::None]));
    let med = |f: &dyn Fn(usize) -> f64| {
        let mut v: Vec<f64> = (0..SEEDS as usize).map(f).collect();
        median(&mut v)
    };
    for (name, get) in [
        ("independent roads, none", &(|s: usize| indep[s][0]) as &dyn Fn(usize) -> ([f64; 4], f64)),
        ("one road, none", &|s: usize| white[s][0]),
        ("one road, thesis Eq 6.14", &|s: usize| white[s][1]),
        ("one road, cancel", &|s: usize| white[s][2]),
    ] {
        eprintln!(
            "{n} samples, {name:<26} median ξ front {:.3e} rear {:.3e} heave {:.3e} pitch {:.3e}; worst wheel param {:.1} %",
            med(&|s| get(s).0[0]),
            med(&|s| get(s).0[1]),
            med(&|s| get(s).0[2]),
            med(&|s| get(s).0[3]),
            100.0 * med(&|s| get(s).1)
        );
    }
}

// ---- varying speed, sampler-driven ------------------------------------------------------

/// Drives the half car along one road at a varying speed (ramps between 2 and 12 m/s and
/// full stops), reads its odometry every `dt_odo` s, samples when the sampler says so and feeds
/// the identifier on the sampler's grid and pairs. Returns (row ξ, worst wheel error,
/// worst pair error / tolerance, samples, pairs).
fn varying_speed(seed: u64, n: usize, method: WheelMethod) -> ([f64; 4], f64, f64, u64, u64) {
    let tol = 0.03;
    let dt_odo = 0.002;
    let mut sim = road_sim(RoadMode::White, seed);
    let mut sampler = AxleSampler::<f64, 16>::new(WHEELBASE, SPACING, tol).unwrap();
    let mut id = identifier(method);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(1000 + seed);
    let mut positions = Vec::with_capacity(n);
    let (mut v, mut target, mut stop) = (6.0f64, 6.0f64, 0.0f64);
    let mut e = [0.0; 4];
    let mut worst_pair: f64 = 0.0;
    let mut pairs = 0;
    while positions.len() < n {
        if stop > 0.0 {
            stop -= dt_odo;
            sim.advance(0.0, dt_odo).unwrap();
            assert!(sampler.feed_distance(sim.distance()).unwrap().is_none());
            continue;
        }
        if rng.random::<f64>() < 0.0005 {
            target = rng.random_range(2.0..12.0);
        }
        if rng.random::<f64>() < 0.00005 {
            stop = rng.random_range(0.5..3.0);
            v = 0.0;
        }
        v += (target - v).clamp(-3.0 * dt_odo, 3.0 * dt_odo); // ±3 m/s² ramps
                                                              // The vehicle moves; its odometry (the simulator's distance) goes to the sampler.
        sim.advance(v, dt_odo).unwrap();
        let trig = sampler.feed_distance(sim.distance()).unwrap();
        if let Some(t) = trig {
            let s = sim.sample_now();
            positions.push(t.position);
            if let Some(p) = t.pair {
                let err = (t.position - WHEELBASE - positions[p.sample as usize]).abs();
                assert!(err <= tol);
                worst_pair = worst_pair.max(err / tol);
                pairs += 1;
            }
            id.update_trigger(&s.r, &s.z, &t, &mut e).unwrap();
        }
    }
    let (x, w) = row_errors(&id);
    (x, w, worst_pair, positions.len() as u64, pairs)
}

fn varying_speed_claim(seeds: u64, n: usize) {
    let runs = over_seeds(seeds, |seed| {
        (varying_speed(seed, n, WheelMethod::Cancel), varying_speed(seed, n, WheelMethod::None))
    });
    let mut wheel: Vec<f64> = runs.iter().map(|r| r.0 .0[0] + r.0 .0[1]).collect();
    let mut none: Vec<f64> = runs.iter().map(|r| r.1 .0[0] + r.1 .0[1]).collect();
    let worst_pair = runs.iter().map(|r| r.0 .2).fold(0.0, f64::max);
    let paired: u64 = runs.iter().map(|r| r.0 .4).sum();
    let total: u64 = runs.iter().map(|r| r.0 .3).sum();
    let worst_param = runs.iter().map(|r| r.0 .1).fold(0.0, f64::max);
    eprintln!(
        "varying speed (2–12 m/s ramps, stops; odometry every 2 ms; tolerance 3 cm), {seeds} seeds × {n} samples: \
         cancel wheel ξ median {:.3e}, none {:.3e}; worst wheel param err {:.2} %; pairs {paired}/{total}, worst pair error {:.2} × tolerance",
        median(&mut wheel),
        median(&mut none),
        100.0 * worst_param,
        worst_pair
    );
    assert!(worst_pair <= 1.0);
    for r in &runs {
        assert!(r.0 .0[0] + r.0 .0[1] <= 0.05 && r.0 .1 < 0.10);
    }
}

#[test]
fn varying_speed_sampler_driven_cancellation_holds() {
    // Debug-friendly size: 2 seeds × 8,000 samples; the 8-seed, 20,000-sample version is
    // ignored below (run it with --release).
    varying_speed_claim(2, 8_000);
}

#[test]
#[ignore = "heavy (8 seeds × 20,000 sampler-driven samples): run with --release -- --ignored"]
fn varying_speed_sampler_driven_cancellation_holds_8_seeds() {
    varying_speed_claim(8, 20_000);
}

// ---- identifier edge cases ----------------------------------------------------------------

#[test]
fn two_axle_rejects_bad_input_and_stays_unchanged() {
    let car = HalfCar::<f64>::thesis();
    let cfg = TwoAxleConfig::new(WheelMethod::Cancel, 1000.0, 0.1, 0.005);
    assert!(matches!(
        TwoAxleIdentifier::<f64, 8, 16, 2, 8>::new(&car.model(), 10, cfg),
        Err(Error::Capacity { needed: 10, capacity: 8, .. })
    ));
    assert!(matches!(TwoAxleIdentifier::<f64, 8, 15, 2, 16>::new(&car.model(), 10, cfg), Err(Error::Shape { .. })));
    let mut bad = cfg;
    bad.p0_wheel = -1.0;
    assert!(matches!(Id::new(&car.model(), 10, bad), Err(Error::InvalidArgument { arg: "p0", .. })));
    let mut id = identifier(WheelMethod::Cancel);
    let mut sim = road_sim(RoadMode::White, 9);
    for _ in 0..50 {
        let s = sim.next_sample(6.0).unwrap();
        id.update(&s.r, &s.z).unwrap();
    }
    let before = id.theta::<4>().unwrap();
    let s = sim.next_sample(6.0).unwrap();
    let mut r = s.r;
    r[3] = f64::NAN;
    assert!(matches!(id.update(&r, &s.z), Err(Error::NonFinite { arg: "r_k", .. })));
    let mut e = [0.0; 4];
    assert!(matches!(id.update_at(&s.r, &s.z, Some(3), &mut e), Err(Error::InvalidArgument { arg: "grid", .. })));
    assert_eq!(id.theta::<4>().unwrap(), before);
    assert_eq!(id.samples(), 50);
    assert_eq!(id.paired(), 40);
    assert!(id.update(&s.r, &s.z).unwrap());
    let (vf, vr, vc) = id.wheel_variances();
    assert!((vf - (0.005f64.powi(2) + 1e4 * 0.01)).abs() < 1e-9 && (vr - vf).abs() < 1e-12);
    assert!((vc - 2.0 * 0.005f64.powi(2)).abs() < 1e-15);
    let a = id.a_hat();
    assert_eq!(a[(0, 1)], 1.0);
    assert_eq!(a.row(1), id.theta::<4>().unwrap().row(0));
}

//! Two axles on one road (Ch. VI.D): the asynchronous sampler's properties, the
//! thesis' Fig 6-7/6-8/6-9 protocol, road cancellation, Eq 6.14 written again from the
//! equations, and varying speed.
//!
//! Statistical claims run over 8 seeds and report medians with `eprintln!` (run with
//! `cargo test -p vehid-core --test two_axle -- --nocapture` to see them; `--release` for
//! the `#[ignore]`d heavier variants: `-- --ignored --nocapture`). Their bounds come with the
//! distribution over many seeds that justifies them, measured by the ignored
//! `two_axle_figures_over_seeds` (`SEED0=2000 SEEDS=200 cargo test --release -p vehid-core
//! --test two_axle two_axle_figures_over_seeds -- --ignored --nocapture`; `N=20000 P0=1000`
//! for the thesis protocol) and `sampler_pair_share_over_seeds`.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use nalgebra::SVector;
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use vehid_core::identify::{
    Identifier, TwoAxleConfig, TwoAxleIdentifier, TwoAxleIdentifierVec, TwoAxleStructuredConfig,
    TwoAxleStructuredKalman, WheelMethod,
};
use vehid_core::metrics::xi;
use vehid_core::model::{HalfCar, LinearModel};
use vehid_core::sampler::{AxleSampler, Pair, Trigger};
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

/// One random speed profile through one sampler; checks every pairing decision against the
/// positions and grid points recorded here (not the sampler's own error figure), by the rule
/// the sampler documents: a sample at `s` on grid point `g ≥ d` is paired exactly when a
/// sample was taken on grid point `g − d`, at `s'` with `|(s − L) − s'| ≤ tolerance`.
/// Returns (samples, pairs, pairs the rule expects, decisions within rounding of the
/// tolerance (not compared), worst pair error / tolerance).
fn sampler_case(rng: &mut Xoshiro256PlusPlus, taken: &mut Vec<(u64, f64)>) -> (usize, usize, usize, usize, f64) {
    let d = rng.random_range(1..=32usize);
    let wheelbase = rng.random_range(0.5..6.0);
    let spacing = wheelbase / d as f64;
    let tol = spacing * rng.random_range(0.001..0.2);
    let mut s = AxleSampler::<f64, 32>::new(wheelbase, spacing, tol).unwrap();
    assert_eq!(s.delay(), d);
    taken.clear();
    let (mut pairs, mut expected, mut borderline, mut worst) = (0usize, 0usize, 0usize, 0.0f64);
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
            assert_eq!(t.sample as usize, taken.len());
            assert!(taken.len() < taken.capacity(), "the record would allocate");
            // The rule, from what was recorded: the sample on grid point g − d, if any.
            let partner = t
                .grid
                .checked_sub(d as u64)
                .and_then(|want| taken.binary_search_by_key(&want, |&(g, _)| g).ok().map(|i| (i, taken[i].1)));
            let err = partner.map(|(_, at)| ((t.position - wheelbase) - at).abs());
            match err {
                // Within rounding of the tolerance either decision is right.
                Some(e) if (e - tol).abs() <= 1e-12 * wheelbase.max(t.position) => borderline += 1,
                _ => {
                    let due = err.is_some_and(|e| e <= tol);
                    assert_eq!(
                        t.pair.is_some(),
                        due,
                        "sample {} on grid point {}: paired {:?}, the rule says {due} \
                        (partner {partner:?}, error {err:?}, tolerance {tol})",
                        t.sample,
                        t.grid,
                        t.pair
                    );
                    expected += usize::from(due);
                }
            }
            taken.push((t.grid, t.position));
            if let Some(p) = t.pair {
                let at = taken[p.sample as usize].1;
                let err = ((t.position - wheelbase) - at).abs();
                assert!(err <= tol * (1.0 + 1e-12), "pair error {err} > tolerance {tol}");
                assert_eq!(p.grid + d as u64, t.grid);
                assert_eq!(Some(p.sample as usize), partner.map(|(i, _)| i));
                worst = worst.max(err / tol);
                pairs += 1;
            }
        }
    }
    assert_eq!(allocs(), before, "the sampler allocated");
    (taken.len(), pairs, expected, borderline, worst)
}

/// The 60 random profiles of `sampler_random_profiles_…` from one seed of their generator:
/// (samples, pairs, pairs the rule expects, decisions not compared, worst error / tolerance).
fn sampler_profiles(seed: u64) -> (usize, usize, usize, usize, f64) {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut taken = Vec::with_capacity(20_001);
    let mut total = (0, 0, 0, 0, 0.0f64);
    for _ in 0..60 {
        let (n, p, e, b, w) = sampler_case(&mut rng, &mut taken);
        total = (total.0 + n, total.1 + p, total.2 + e, total.3 + b, total.4.max(w));
    }
    total
}

#[test]
fn sampler_random_profiles_never_pair_beyond_tolerance_never_allocate() {
    // Both sides of the pairing rule, decision by decision: never a pair beyond the
    // tolerance, and never a pair missed that the rule makes (a sample on grid point g − d
    // within tolerance). This replaces a count (`pairs > samples / 4`: 47,176 pairs against
    // the bound 45,676 on this seed), which was arbitrary and thin: over the generator's
    // seeds 1–100 the pairs are 19.7–39.2 % of the samples (median 26.0 %; 35 seeds at or
    // below a quarter: `sampler_pair_share_over_seeds`), so the count said nothing a correct
    // sampler guarantees. Measured on this seed: 47,176 pairs, all 47,176 the rule makes, no
    // decision within rounding of the tolerance.
    let (samples, pairs, expected, borderline, worst) = sampler_profiles(2024);
    eprintln!(
        "sampler property: 60 random profiles, {samples} samples, {pairs} pairs (the rule: {expected}, \
         {borderline} within rounding of the tolerance), worst pair error {worst:.3} × tolerance"
    );
    assert!(
        pairs >= expected && pairs <= expected + borderline,
        "{pairs} pairs, the rule: {expected} (+ {borderline})"
    );
    assert!(pairs > 0 && pairs < samples, "{pairs} pairs of {samples} samples: both cases must occur");
}

#[test]
#[ignore = "a measurement: run with --release -- --ignored --nocapture"]
fn sampler_pair_share_over_seeds() {
    // The share of samples paired in the 60 random profiles, over the generator's seeds
    // 1–100 (the property test above uses 2024).
    let mut shares: Vec<f64> = (1..=100)
        .map(|seed| {
            let (n, p, e, b, _) = sampler_profiles(seed);
            assert!(p >= e && p <= e + b);
            p as f64 / n as f64
        })
        .collect();
    let mid = median(&mut shares); // sorts them
    let quarter = shares.iter().filter(|&&v| v <= 0.25).count();
    eprintln!(
        "pairs / samples over 100 seeds: min {:.3}, median {mid:.3}, max {:.3}; {quarter} seeds at or below 1/4",
        shares[0], shares[99]
    );
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
    let mut worst: Vec<f64> = white.iter().map(|r| r[1].1).collect();
    eprintln!(
        "road cancellation, {SEEDS} seeds × {n} samples: wheel-row ξ median {:.3e} (none {:.3e}), median ratio {:.0}×, \
         worst wheel parameter median {:.1} %, largest {:.1} %",
        median(&mut cancel),
        median(&mut none),
        median(&mut ratio),
        100.0 * median(&mut worst),
        100.0 * worst.iter().fold(0.0f64, |a, &b| a.max(b))
    );
    check_cancellation_acceptance(&white.iter().map(|r| r[1]).collect::<Vec<_>>(), &ratio);
}

/// The acceptance for road cancellation (thesis protocol, 20,000 samples), over the
/// seeds' results (row ξ, worst wheel parameter): in medians over the
/// seeds, the wheel rows' share of ξ ≤ 0.05, every wheel parameter within 10 %, and ≥ 10×
/// smaller wheel-row ξ than the plain rows (`ratio`: plain / cancelled per seed); and per seed
/// that no run is far off.
///
/// Measured over seeds 1–400 (`two_axle_figures_over_seeds` with N=20000 P0=1000): the worst
/// of the 14 non-zero wheel parameters has median 4.9 %, 90th percentile 8.4 %, maximum
/// 17.7 %, and 17 of the 400 seeds (4 %) have one beyond 10 %; the wheel-row ξ median 4.9e-3,
/// maximum 0.066 (one seed above 0.05). So "within 10 % on every seed", which this test used
/// to assert, held on seeds 1–8 (largest 8.5 %) by the draw: 14 of the 50 disjoint groups of
/// eight seeds in 1–400 have a seed beyond 10 %. The medians are what holds: over those 50
/// groups the median worst parameter is 2.5–6.8 % (bound 10 %), the median wheel-row ξ at
/// most 0.011 (bound 0.05). Per seed the bounds are about twice the largest of the 400:
/// wheel-row ξ ≤ 0.15, worst parameter ≤ 30 %. Checked on 400 seeds never looked at
/// before (5001–5400): per seed at most 0.040 and 16.9 % (17 seeds beyond 10 % again); the
/// medians of their 50 groups of eight 2.4–7.7 % and at most 0.0097.
fn check_cancellation_acceptance(runs: &[([f64; 4], f64)], ratio: &[f64]) {
    for (s, (x, w)) in runs.iter().enumerate() {
        assert!(x[0] + x[1] <= 0.15, "seed {}: cancel wheel ξ {}", s + 1, x[0] + x[1]);
        assert!(*w <= 0.30, "seed {}: a wheel parameter off by {:.1} %", s + 1, 100.0 * w);
    }
    let mut xi: Vec<f64> = runs.iter().map(|(x, _)| x[0] + x[1]).collect();
    let mut worst: Vec<f64> = runs.iter().map(|r| r.1).collect();
    assert!(median(&mut xi) <= 0.05, "median wheel-row ξ {}", median(&mut xi));
    assert!(median(&mut worst) < 0.10, "median worst wheel parameter {:.1} %", 100.0 * median(&mut worst));
    assert!(
        median(&mut ratio.to_vec()) >= 10.0,
        "plain / cancelled wheel-row ξ: median {}",
        median(&mut ratio.to_vec())
    );
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
    // Acceptance, as `road_cancellation_over_8_seeds` checks it.
    let ratios: Vec<f64> = white
        .iter()
        .map(|r| {
            let (a, b) = (r[0].0, r[2].0);
            (a[0] + a[1]) / (b[0] + b[1])
        })
        .collect();
    check_cancellation_acceptance(&white.iter().map(|r| r[2]).collect::<Vec<_>>(), &ratios);
    assert!(cancel[0] + cancel[1] <= 0.05);
    assert!(ratio >= 10.0, "none / cancel = {ratio}");
}

/// ξ of the rear wheel row after `n` samples of one seed, for each method, with `P(0) = p0 I`
/// on every row.
fn rear_row_xi(mode: RoadMode, seed: u64, n: usize, p0: f64, methods: &[WheelMethod]) -> Vec<f64> {
    let car = HalfCar::<f64>::thesis();
    let mut sim = road_sim(mode, seed);
    let mut ids: Vec<Id> =
        methods.iter().map(|&m| Id::new(&car.model(), D, TwoAxleConfig::new(m, p0, 0.1, 0.005)).unwrap()).collect();
    for _ in 0..n {
        let s = sim.next_sample(6.0).unwrap();
        for id in ids.iter_mut() {
            id.update(&s.r, &s.z).unwrap();
        }
    }
    ids.iter().map(|id| row_errors(id).0[1]).collect()
}

#[test]
fn fig_6_8_rear_row_bias_appears_on_one_road_and_cancellation_removes_it() {
    // Fig 6-8, two-sided and cheap. On one road the rear input u2(k) = u1(k − d) is a past
    // front input, which the state remembers: the plain rear row is biased. With the thesis'
    // P(0) = 1000 that bias hides behind slow convergence for > 10^5 samples (r/p0 = 0.08
    // for a wheel row against λ_min(Σ x xᵀ) ≈ 5e-3 after 20,000 samples: the prior holds the
    // weakly excited direction near 0; the ignored 200,000-sample run below shows it there).
    // With P(0) = 10^6 I (r/p0 = 8e-5) every row is least squares on its samples within a few
    // thousand, so 10,000 samples tell bias from scatter: the same plain rows on two
    // independent roads (Fig 6-7: the only change is that the roads are not shared) are the
    // unbiased reference, road cancellation the cure.
    //
    // Bounds (per seed), chosen on seeds 1–8, whose extremes are: one road ≥ 1.49e4, ratio
    // to independent roads ≥ 155, cancelled ≤ 7.8e-3. A factor 4 or 5 from each; then 200
    // more seeds (1001–1200) gave 1.43e4, 64 and 0.026, the last too near 4 × 7.8e-3, so the
    // cancellation bound went to 0.1. Checked on 200 seeds never looked at before (2001–2200,
    // release build): one-road rear ξ min 1.47e4 (bound 3,000: margin × 4.9), ratio min 98
    // (bound 30: × 3.3), cancelled max 0.036 (bound 0.1: × 2.8); medians 1.7e4, 1,244, 3.9e-3.
    let (n, p0) = (10_000, 1e6);
    let runs = over_seeds(SEEDS, |seed| {
        let one = rear_row_xi(RoadMode::White, seed, n, p0, &[WheelMethod::None, WheelMethod::Cancel]);
        let indep = rear_row_xi(RoadMode::Independent, seed, n, p0, &[WheelMethod::None]);
        (one[0], indep[0], one[1])
    });
    for (s, &(plain, indep, cancel)) in runs.iter().enumerate() {
        eprintln!(
            "seed {}: rear-row ξ, one road {plain:.3e}, independent roads {indep:.3e}, cancelled {cancel:.2e}",
            s + 1
        );
        assert!(
            plain >= 3000.0 && plain >= 30.0 * indep,
            "seed {}: no rear-row bias on one road: ξ {plain:e} \
            against {indep:e} on independent roads",
            s + 1
        );
        assert!(cancel <= 0.1, "seed {}: road cancellation leaves rear-row ξ {cancel:e}", s + 1);
    }
}

/// Reads a number from the environment variable `name`, else `default`.
fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

#[test]
#[ignore = "a measurement over many seeds: run with --release -- --ignored --nocapture (SEED0, SEEDS, N, P0)"]
fn two_axle_figures_over_seeds() {
    // The distributions behind the bounds of `fig_6_8_rear_row_bias_…` (defaults: its
    // n = 10,000 and P(0) = 10^6) and of `road_cancellation_over_8_seeds` (N=20000 P0=1000):
    // seeds SEED0+1 ..= SEED0+SEEDS, eight at a time on two threads.
    let (n, p0): (usize, f64) = (env_or("N", 10_000), env_or("P0", 1e6));
    let (seed0, seeds): (u64, u64) = (env_or("SEED0", 0), env_or("SEEDS", 8));
    let car = HalfCar::<f64>::thesis();
    let mut rows = Vec::new();
    for chunk in 0..seeds.div_ceil(8) {
        rows.extend(over_seeds(8.min(seeds - 8 * chunk), |s| {
            let seed = seed0 + 8 * chunk + s;
            let run = |mode, methods: &[WheelMethod]| {
                let mut sim = road_sim(mode, seed);
                let mut ids: Vec<Id> = methods
                    .iter()
                    .map(|&m| Id::new(&car.model(), D, TwoAxleConfig::new(m, p0, 0.1, 0.005)).unwrap())
                    .collect();
                for _ in 0..n {
                    let s = sim.next_sample(6.0).unwrap();
                    for id in ids.iter_mut() {
                        id.update(&s.r, &s.z).unwrap();
                    }
                }
                ids.iter().map(row_errors).collect::<Vec<_>>()
            };
            let one = run(RoadMode::White, &[WheelMethod::None, WheelMethod::Cancel]);
            let indep = run(RoadMode::Independent, &[WheelMethod::None]);
            let (plain, cancel, indep) = (one[0].0[1], one[1].0[1], indep[0].0[1]);
            [plain, indep, plain / indep, cancel, one[1].0[0] + one[1].0[1], one[1].1]
        }));
    }
    eprintln!("{n} samples, P(0) = {p0}, seeds {}..={}:", seed0 + 1, seed0 + seeds);
    let names = [
        "rear ξ, one road, plain rows",
        "rear ξ, independent roads, plain rows",
        "ratio one road / independent",
        "rear ξ, one road, cancelled",
        "wheel-row ξ, cancelled",
        "worst wheel parameter, cancelled",
    ];
    for (k, name) in names.iter().enumerate() {
        let mut v: Vec<f64> = rows.iter().map(|r| r[k]).collect();
        v.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let q = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
        eprintln!(
            "  {name:<38} min {:.3e}  p10 {:.3e}  median {:.3e}  p90 {:.3e}  max {:.3e}",
            v[0],
            q(0.1),
            q(0.5),
            q(0.9),
            v[v.len() - 1]
        );
    }
    if env_or("PER_SEED", 0) == 1 {
        for (i, r) in rows.iter().enumerate() {
            eprintln!("  seed {}: {}", seed0 + 1 + i as u64, r.map(|v| format!("{v:.4e}")).join(" "));
        }
    }
    let over = rows.iter().filter(|r| r[5] >= 0.10).count();
    eprintln!("  seeds with a cancelled wheel parameter off by 10 % or more: {over} of {seeds}");
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
    // The thesis' protocol shows the bias too, given the samples (measured, seeds 1–8: rear
    // ξ medians 0.60 on independent roads, 192 on one road, 2.4e-4 cancelled). The cheap
    // check of the same claim, run by `make test`, is `fig_6_8_rear_row_bias_appears_…`.
    let (indep_rear, plain_rear, cancel_rear) =
        (med(&|s| indep[s][0].0[1]), med(&|s| white[s][0].0[1]), med(&|s| white[s][2].0[1]));
    assert!(plain_rear >= 30.0 * indep_rear, "one road {plain_rear:e}, independent roads {indep_rear:e}");
    assert!(cancel_rear <= 0.01, "cancelled rear ξ {cancel_rear:e}");
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

// ---- Eq 6.14, written again from the equations ---------------------------------------------

/// One row of Eq 4.3–4.7 as the thesis writes it, in plain Rust (no code of the crate):
/// `e = z − xᵀθ`, `s = xᵀPx + r`, `θ ← θ + P x e / s`, `P ← P − (P x)(P x)ᵀ / s`.
struct PlainRow {
    theta: [f64; 8],
    p: [[f64; 8]; 8],
    r: f64,
}

impl PlainRow {
    fn new(p0: f64, r: f64) -> Self {
        let mut p = [[0.0; 8]; 8];
        for (i, row) in p.iter_mut().enumerate() {
            row[i] = p0;
        }
        Self { theta: [0.0; 8], p, r }
    }

    /// `xᵀθ` (the prediction before this sample).
    fn predict(&self, x: &[f64; 8]) -> f64 {
        (0..8).map(|j| x[j] * self.theta[j]).sum()
    }

    /// One measurement update with the innovation `e` already formed.
    fn step(&mut self, x: &[f64; 8], e: f64) {
        let px: Vec<f64> = (0..8).map(|a| (0..8).map(|b| self.p[a][b] * x[b]).sum()).collect();
        let s: f64 = (0..8).map(|a| x[a] * px[a]).sum::<f64>() + self.r;
        for a in 0..8 {
            self.theta[a] += px[a] * e / s;
            for b in 0..8 {
                self.p[a][b] -= px[a] * px[b] / s;
            }
        }
    }
}

#[test]
fn thesis_wheel_method_is_eq_6_14_step_by_step() {
    // Eq 6.12–6.14 (the "thesis" wheel method), from the thesis' equations only: the front
    // row's innovation e1(k) = z2 − xᵀθ̂_2 estimates the road, and the rear row's is
    // e2(k) = z4 − xᵀθ̂_4 − ρ·e1(k − d), ρ = b42 / b21 (rear over front tyre entry of B:
    // k21/m2 over k11/m1, Eq 6.2 and 6.4, from the car's constants, not from the model the
    // identifier builds). Both rows are the plain Kalman rows of Eq 4.3–4.7 with
    // r = σ_v² + b² σ_u² and P(0) = 1000 I; the rear row takes no step before its first pair.
    // Compared at every sample: both innovations the identifier returns and both rows of θ̂.
    let car = HalfCar::<f64>::thesis();
    let c = car.params();
    let (b21, b42) = (c.k11 / c.m1, c.k21 / c.m2);
    let rho = b42 / b21;
    let (su, sv, p0) = (0.1f64, 0.005f64, 1000.0);
    let d = (WHEELBASE / SPACING).round() as usize;
    assert_eq!(d, D);
    let mut front = PlainRow::new(p0, sv * sv + b21 * b21 * su * su);
    let mut rear = PlainRow::new(p0, sv * sv + b42 * b42 * su * su);
    let mut e1_past = Vec::new();
    let mut id = identifier(WheelMethod::Thesis);
    let mut sim = road_sim(RoadMode::White, 31);
    let mut e = [0.0; 4];
    // Rounding: the reference sums in another order, so the two differ by rounding only
    // (measured on this seed: 1.1e-14 of the innovations' scale, 1.6e-15 of the rows'). The
    // bound 1e-9 is far above that and far below a change of the equation: a flipped sign
    // changes e2 by 2ρ·e1(k − d), the size of the innovations themselves, at the first pair.
    let (mut worst_e, mut worst_theta) = (0.0f64, 0.0f64);
    for k in 0..3000 {
        let s = sim.next_sample(6.0).unwrap();
        let x: [f64; 8] = core::array::from_fn(|j| s.r[j]);
        let e1 = s.z[1] - front.predict(&x);
        front.step(&x, e1);
        let e2 = if k >= d {
            let e2 = s.z[3] - rear.predict(&x) - rho * e1_past[k - d];
            rear.step(&x, e2);
            e2
        } else {
            0.0
        };
        e1_past.push(e1);
        let paired = id.update_next(&s.r, &s.z, &mut e).unwrap();
        assert_eq!(paired, k >= d, "sample {k}");
        let scale = s.z[1].abs().max(s.z[3].abs()).max(1.0);
        let de = (e[0] - e1).abs().max((e[1] - e2).abs()) / scale;
        assert!(de <= 1e-9, "sample {k}: innovations (e1, e2) = ({}, {}), Eq 6.13/6.14 give ({e1}, {e2})", e[0], e[1]);
        let theta = id.theta::<4>().unwrap();
        for (row, plain) in [(0, &front.theta), (1, &rear.theta)] {
            let norm = plain.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1.0);
            let dt = (0..8).map(|j| (theta[(row, j)] - plain[j]).abs()).fold(0.0, f64::max) / norm;
            assert!(dt <= 1e-9, "sample {k}: row {row} of θ̂ differs from Eq 6.14's by {dt:e} (relative)");
            worst_theta = worst_theta.max(dt);
        }
        worst_e = worst_e.max(de);
    }
    eprintln!("Eq 6.14 step by step, 3000 samples: largest relative difference: innovations {worst_e:.1e}, rows {worst_theta:.1e}");
    // The ρ and the sample count it reports are those of the equations.
    assert!((id.ratio() - rho).abs() <= 1e-12 * rho.abs(), "ratio {} against ρ = {rho}", id.ratio());
    assert_eq!(Identifier::samples(&id), 3000);
}

#[test]
fn cancellation_reports_the_front_rows_innovation() {
    // With road cancellation the front row's innovation is still `z_2 − xᵀθ̂_2` (θ̂ before the
    // sample), though the joint filter, not a front row, holds θ̂_2: every sample of 3000,
    // after the pairs have moved the front row off its prior.
    let mut id = identifier(WheelMethod::Cancel);
    let mut sim = road_sim(RoadMode::White, 32);
    let mut e = [0.0; 4];
    let mut moved = 0;
    for k in 0..3000 {
        let s = sim.next_sample(6.0).unwrap();
        let front = id.theta::<4>().unwrap().row(0).clone_owned();
        let prediction: f64 = (0..8).map(|j| front[j] * s.r[j]).sum();
        id.update_next(&s.r, &s.z, &mut e).unwrap();
        let expect = s.z[1] - prediction;
        assert!((e[0] - expect).abs() <= 1e-9 * (1.0 + s.z[1].abs()), "sample {k}: {} against {expect}", e[0]);
        moved += usize::from(prediction.abs() > 1e-6 * s.z[1].abs());
    }
    assert!(moved > 1000, "the front row stayed at its prior ({moved} samples)");
}

// ---- accessors, against what the test gave and the identifiers' other outputs -----------

/// `n` made-up samples `(x, z)`, every component uniform in ±1 (fixed seed): they move every
/// estimate, which is all the accessor checks below need (no car's dynamics).
fn made_up(seed: u64, n: usize) -> Vec<(SVector<f64, 8>, SVector<f64, 8>)> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let x = SVector::<f64, 8>::from_fn(|_, _| rng.random_range(-1.0..1.0));
            let z = SVector::<f64, 8>::from_fn(|_, _| rng.random_range(-1.0..1.0));
            (x, z)
        })
        .collect()
}

/// The plain accessors of the rows identifier against what the test gave it: `config()` the
/// settings passed in (every field off `TwoAxleConfig::new`'s), `delay()` the `d` passed in,
/// `wheel_rows()` the rows holding the non-zero entry of the model's front and rear column of
/// `B` (found here), `ratio()` ρ = b42 / b21 = (k21/m2) / (k11/m1) from the car's constants
/// (the passenger car: 8/7), `Identifier::rows` the car's unknown rows, and both `samples()`
/// the number of samples fed (23, of which all but the first `d` paired).
#[test]
fn two_axle_accessors_read_back_what_the_test_gave() {
    let car = HalfCar::<f64>::passenger();
    let model = car.model();
    let cfg = TwoAxleConfig {
        method: WheelMethod::Thesis,
        p0_wheel: 250.0,
        p0_body: 7.0,
        road_sigma: 0.02,
        deriv_noise: 0.003,
        direct_front: false,
        exact: false,
        gate: 0.0,
    };
    let d = 7;
    let mut id = Id::new(&model, d, cfg).unwrap();
    assert_eq!(*id.config(), cfg);
    assert_eq!(id.delay(), d);
    let entered = |col: usize| -> Vec<usize> { (0..8).filter(|&i| model.b()[(i, col)] != 0.0).collect() };
    let (front, rear) = (entered(0), entered(1));
    assert_eq!((front.len(), rear.len()), (1, 1), "B: one row per road input");
    assert_eq!(id.wheel_rows(), (front[0], rear[0]));
    let c = car.params();
    let rho = (c.k21 / c.m2) / (c.k11 / c.m1);
    assert!((rho - 8.0 / 7.0).abs() < 1e-12, "ρ = {rho}: the passenger car's 40 kg / 35 kg");
    assert!((id.ratio() - rho).abs() <= 1e-12 * rho, "ratio {} against ρ = {rho}", id.ratio());
    assert_eq!(Identifier::rows(&id), &car.unknown_rows()[..]);
    assert_eq!((id.samples(), Identifier::samples(&id)), (0, 0));
    let n = 23;
    for (x, z) in made_up(41, n) {
        id.update(&x, &z).unwrap();
    }
    assert_eq!((id.samples(), Identifier::samples(&id), id.paired()), (n as u64, n as u64, (n - d) as u64));
}

/// `theta_row` against the rows identifier's other outputs, for each wheel method after 60
/// made-up samples (every unknown row moved off its zero prior: checked): row `i` of
/// `theta_into`'s, `params_into`'s and `theta::<4>()`'s `K × N` estimate (`K = 4` unknown
/// rows, `N = 8`) is `theta_row(rows()[i])`; with `Cancel`, `joint()` holds
/// `[a_rear; a_front]`, so its first `N` parameters are `theta_row(rear)` and its last `N`
/// `theta_row(front)`. A known row reads that row of the model's `A` (the half car's
/// kinematic rows 0, 2, 4, 6); a row index past `A`'s last panics, as indexing would (it
/// used to read the last row). Wrong lengths are shape errors that name the length
/// needed: `K·N = 32` for `theta_into`, `K = 4` for `theta`, 4 innovations for `e`.
#[test]
fn two_axle_theta_row_is_the_row_of_theta_into_and_params_into() {
    let car = HalfCar::<f64>::thesis();
    let model = car.model();
    let rows = car.unknown_rows();
    let (x1, z1) = made_up(43, 1)[0];
    for method in [WheelMethod::None, WheelMethod::Thesis, WheelMethod::Cancel] {
        let mut id = identifier(method);
        for (x, z) in made_up(42, 60) {
            id.update(&x, &z).unwrap();
        }
        let (mut theta, mut params) = ([f64::NAN; 32], [f64::NAN; 32]);
        id.theta_into(&mut theta).unwrap();
        id.params_into(&mut params).unwrap();
        let matrix = id.theta::<4>().unwrap();
        for (i, &row) in rows.iter().enumerate() {
            let t = id.theta_row(row);
            assert!(t.iter().any(|&v| v != 0.0), "{method:?}: row {row} still at its prior");
            assert_eq!(&theta[8 * i..8 * (i + 1)], t.as_slice(), "{method:?}: theta_into, row {row}");
            assert_eq!(&params[8 * i..8 * (i + 1)], t.as_slice(), "{method:?}: params_into, row {row}");
            assert_eq!(matrix.row(i).transpose(), t, "{method:?}: theta::<4>(), row {row}");
        }
        if method == WheelMethod::Cancel {
            let (front, rear) = id.wheel_rows();
            let joint = id.joint().theta();
            assert_eq!(joint.fixed_rows::<8>(0).into_owned(), id.theta_row(rear));
            assert_eq!(joint.fixed_rows::<8>(8).into_owned(), id.theta_row(front));
        }
        for row in [0, 2, 4, 6] {
            assert_eq!(id.theta_row(row), model.a().row(row).transpose(), "{method:?}: known row {row}");
        }
        let past = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| id.theta_row(8)));
        assert!(past.is_err(), "row 8 of an 8-state model: {past:?}");
        assert!(matches!(id.theta_into(&mut [0.0; 31]), Err(Error::Shape { arg: "out", expected: 32, got: 31 })));
        assert!(matches!(id.theta::<3>(), Err(Error::Shape { arg: "K", expected: 4, got: 3 })));
        let e = &mut [0.0; 3];
        assert!(matches!(id.update_at(&x1, &z1, None, e), Err(Error::Shape { arg: "e", expected: 4, got: 3 })));
    }
}

/// The rows identifier's refusals, each the error its docs list: a `B` whose front column
/// enters two rows (argument `b`), `d = 0` (`d`); a saved identifier read back with `P ≠ 2N`
/// (the joint filter cut to 15 parameters for `N = 8`: the message names the 16 needed) or
/// with `d = 0`. And a model whose only unknown rows are the two wheel rows (no body rows)
/// builds and runs: its rows are those two, and `theta_row` of every other row is the
/// model's.
#[test]
fn two_axle_refuses_what_its_docs_list() {
    use serde_json::json;
    let car = HalfCar::<f64>::thesis();
    let model = car.model();
    let cfg = TwoAxleConfig::new(WheelMethod::Cancel, 1000.0, 0.1, 0.005);
    let mut b = *model.b();
    b[(5, 0)] = 1.0; // the front road input also enters the heave row
    let two_rows = LinearModel::new(*model.a(), b, &car.unknown_rows()).unwrap();
    assert!(matches!(Id::new(&two_rows, D, cfg), Err(Error::InvalidArgument { arg: "b", .. })));
    assert!(matches!(Id::new(&model, 0, cfg), Err(Error::InvalidArgument { arg: "d", .. })));

    let good = serde_json::to_value(TwoAxleIdentifierVec::<f64, 8, 16>::new(&model, D, cfg).unwrap()).unwrap();
    assert!(serde_json::from_value::<TwoAxleIdentifierVec<f64, 8, 16>>(good.clone()).is_ok());
    let mut v = good.clone();
    for track in 0..2 {
        v["joint"][track]["theta"] = json!(vec![0.0; 15]);
        v["joint"][track]["m"] = json!((0..225).map(|k| if k % 16 == 0 { 1000.0 } else { 0.0 }).collect::<Vec<f64>>());
        v["joint"][track]["dim"] = json!(15);
    }
    let err = serde_json::from_value::<TwoAxleIdentifierVec<f64, 8, 15>>(v).unwrap_err().to_string();
    assert!(err.contains("has 15 elements but 16 are needed"), "{err}");
    let mut v = good;
    v["d"] = json!(0);
    let err = serde_json::from_value::<TwoAxleIdentifierVec<f64, 8, 16>>(v).unwrap_err().to_string();
    assert!(err.contains("at least 1 road point"), "{err}");

    let wheels = LinearModel::new(*model.a(), *model.b(), &[1, 3]).unwrap();
    let mut id = TwoAxleIdentifierVec::<f64, 8, 16>::new(&wheels, D, cfg).unwrap();
    assert_eq!(Identifier::rows(&id), &[1, 3][..]);
    let mut e = [0.0; 2];
    for (x, z) in made_up(44, 30) {
        id.update_next(&x, &z, &mut e).unwrap();
    }
    assert_eq!(id.paired(), 30 - D as u64);
    for row in [0, 2, 4, 5, 6, 7] {
        assert_eq!(id.theta_row(row), model.a().row(row).transpose(), "row {row}");
    }
}

// ---- the structured two-axle identifier ------------------------------------------------------

type Physical = TwoAxleStructuredKalman<f64, 4, 3, 16>;

/// `car`'s physical structure with `m1`, `m2`, `l1`, `l2` known (12 parameters).
fn physical(car: &HalfCar<f64>) -> vehid_core::structure::Structure<f64> {
    let c = car.constants();
    let mut known = [None; 12];
    for (k, v) in known.iter_mut().zip(&c).skip(8) {
        *k = Some(*v);
    }
    *HalfCar::structure(known).unwrap().structure()
}

/// The structured identifier's accessors against what the test gave it and the closed forms
/// its docs state, on the passenger car (ρ = b42 / b21 = 8/7; on the thesis' car ρ = 1, and
/// ρ, ρ² and 1 look alike) with σ_v² and b21² σ_u² of one size (0.01 and 0.04, so neither
/// hides the other): `config()` the settings passed in, `delay()` the `d` passed in,
/// `ratio()` ρ from the car's constants, `rows()` the structure's equation states (rows 5, 7,
/// 1, 3 of `A`), `equation_r(i)` each equation's variance (heave, pitch: no road, σ_v²; front
/// wheel: the direct equation's σ_v² + b21² σ_u²; rear wheel: the cancelled one's
/// σ_v² (1 + ρ²)), `noise_into` the diagonal `R` of those, and `wheel_variances()` (front,
/// rear, cancelled) = (σ_v² + b21² σ_u², σ_v² + b42² σ_u², σ_v² (1 + ρ²)), all written out
/// here from k11/m1 and k21/m2.
#[test]
fn two_axle_structured_accessors_are_the_configuration_and_the_equations_variances() {
    let car = HalfCar::<f64>::passenger();
    let c = car.params();
    let (b21, b42) = (c.k11 / c.m1, c.k21 / c.m2);
    let rho = b42 / b21;
    let (su, sv) = (4e-5, 0.1);
    let cfg = TwoAxleStructuredConfig {
        p0: Some(50.0),
        road_sigma: su,
        deriv_noise: sv,
        direct_front: false,
        compensate: false,
    };
    let d = 9;
    let id = Physical::new(physical(&car), &car.model(), d, cfg).unwrap();
    assert_eq!(*id.config(), cfg);
    assert_eq!(id.delay(), d);
    assert!((id.ratio() - rho).abs() <= 1e-12 * rho, "ratio {} against ρ = {rho}", id.ratio());
    assert_eq!(Identifier::rows(&id), &[5, 7, 1, 3][..]);
    let sv2 = sv * sv;
    let variance = |row: usize| match row {
        1 => sv2 + b21 * b21 * su * su,
        3 => sv2 * (1.0 + rho * rho),
        _ => sv2,
    };
    let close = |got: f64, want: f64| (got - want).abs() <= 1e-12 * want.abs();
    let mut noise = [f64::NAN; 16];
    id.noise_into(&mut noise).unwrap();
    for (i, row) in [5, 7, 1, 3].into_iter().enumerate() {
        assert!(close(id.equation_r(i), variance(row)), "equation {i} (row {row}): {}", id.equation_r(i));
        for j in 0..4 {
            let want = if i == j { variance(row) } else { 0.0 };
            assert!(close(noise[4 * i + j], want), "R[{i}][{j}] = {} against {want}", noise[4 * i + j]);
        }
    }
    let (front, rear, cancelled) = id.wheel_variances();
    let want = (sv2 + b21 * b21 * su * su, sv2 + b42 * b42 * su * su, sv2 * (1.0 + rho * rho));
    assert!(
        close(front, want.0) && close(rear, want.1) && close(cancelled, want.2),
        "wheel variances {:?} against {want:?}",
        (front, rear, cancelled)
    );
}

/// The structured identifier fed through hand-made sampler triggers (the thesis' car,
/// `d = 10`, made-up samples on grid points 0–59 with 25–27 skipped, as after an odometry
/// jump), each step checked against what the test knows: `update_trigger` says paired exactly
/// when the trigger carries a pair (the test gives one when grid point g − d was fed and g is
/// not 3 mod 7, as a sampler refuses a pair beyond its tolerance), the rear wheel's
/// innovation is 0 on an unpaired sample (its docs), and `samples()` / `paired()` count what
/// was fed and paired. Then, with plain least squares (`compensate = false`: the estimate is
/// the filters'), the accessors agree with the `Identifier` outputs: `partition()` is the
/// grouping `groups_into` reports, with the 3 groups the docs give (the two wheel equations in
/// one, the heave and the pitch equation each in its own); parameter `j` of `params_into` is
/// entry `local[j]` of `filter(group_of_param[j])`'s estimate; `trace()` the filters' traces
/// summed.
#[test]
fn two_axle_structured_triggers_filters_and_partition_agree_with_its_outputs() {
    let car = HalfCar::<f64>::thesis();
    let cfg = TwoAxleStructuredConfig { compensate: false, ..TwoAxleStructuredConfig::new(0.1, 0.005) };
    let mut id = Physical::new(physical(&car), &car.model(), D, cfg).unwrap();
    let (front, rear) = id.wheel_equations();
    let (mut fed, mut paired) = (Vec::new(), 0u64);
    let mut e = [0.0; 4];
    for (g, (x, z)) in made_up(45, 60).iter().enumerate() {
        let grid = g as u64;
        if (25..=27).contains(&grid) {
            continue;
        }
        let earlier = grid.checked_sub(D as u64).and_then(|p| fed.iter().position(|&f| f == p).map(|i| (i, p)));
        let pair = earlier.filter(|_| grid % 7 != 3).map(|(i, p)| Pair { sample: i as u64, grid: p, error: 0.0 });
        let trigger = Trigger { sample: fed.len() as u64, grid, position: SPACING * grid as f64, pair };
        let got = id.update_trigger(x.as_slice(), z.as_slice(), &[], &trigger, &mut e).unwrap();
        assert_eq!(got, pair.is_some(), "grid point {grid}");
        if pair.is_none() {
            assert_eq!(e[rear], 0.0, "grid point {grid}: the rear wheel took no step");
        }
        fed.push(grid);
        paired += u64::from(pair.is_some());
    }
    assert!(paired >= 20 && paired + 20 <= fed.len() as u64, "{paired} of {} paired: both kinds", fed.len());
    assert_eq!((id.samples(), id.paired()), (fed.len() as u64, paired));

    assert!(!id.starting());
    let part = *id.partition();
    let (mut group_of_param, mut group_of_eq) = ([0usize; 12], [0usize; 4]);
    id.groups_into(&mut group_of_param, &mut group_of_eq).unwrap();
    assert_eq!(part.groups, 3);
    assert_eq!(part.group_of_param[..12].iter().map(|&g| g as usize).collect::<Vec<_>>(), group_of_param);
    assert_eq!(part.group_of_eq[..4].iter().map(|&g| g as usize).collect::<Vec<_>>(), group_of_eq);
    assert_eq!(group_of_eq[front], group_of_eq[rear]);
    let (heave, pitch, wheels) = (group_of_eq[0], group_of_eq[1], group_of_eq[front]);
    assert!(heave != pitch && heave != wheels && pitch != wheels, "groups of the equations: {group_of_eq:?}");
    let mut p = [f64::NAN; 12];
    id.params_into(&mut p).unwrap();
    for (j, &v) in p.iter().enumerate() {
        let f = id.filter(part.group_of_param[j] as usize);
        assert!(v.is_finite() && v != 0.0, "parameter {j}: {v}");
        assert_eq!(f.theta()[part.local[j] as usize], v, "parameter {j}");
    }
    let traces: f64 = (0..3).map(|g| id.filter(g).trace()).sum();
    let trace = id.trace().unwrap();
    assert!(traces > 0.0 && (trace - traces).abs() <= 1e-12 * traces, "trace {trace} against {traces}");
}

// ---- the outlier screen and the axle pairing ----------------------------------------------

/// ξ over the four unknown rows, the samples paired, and the samples screened, after `n`
/// samples of the thesis protocol (cancellation) behind the screen at `gate`, sample `bad`
/// (if any) with value `j` of `r | z` replaced by 1e30 (a sensor glitch at that road point).
fn screened_run(seed: u64, n: usize, gate: f64, bad: Option<(usize, usize)>) -> (f64, u64, u64) {
    use vehid_core::identify::{Refresh, Screened};
    use vehid_core::structure::Structure;
    let inner = identifier(WheelMethod::Cancel);
    let s = Structure::full_rows(8, inner.rows()).unwrap();
    let mut id = Screened::new(inner, s, gate, Refresh::Every).unwrap();
    let mut sim = road_sim(RoadMode::White, seed);
    let mut e = [0.0; 4];
    let mut refused = 0;
    for k in 0..n {
        let smp = sim.next_sample(6.0).unwrap();
        let (mut r, mut z) = (smp.r, smp.z);
        if let Some((j, _)) = bad.filter(|&(_, at)| at == k) {
            if j < 8 {
                r[j] = 1e30;
            } else {
                z[j - 8] = 1e30;
            }
        }
        if let Err(err) = id.update_into(r.as_slice(), z.as_slice(), &[], &mut e) {
            // The very first sample, before anything can judge it, may be refused (changing
            // nothing): the caller goes on without it.
            assert!(k == 0 && bad.is_some_and(|(_, at)| at == 0), "sample {k} refused: {err}");
            refused += 1;
        }
    }
    let truth = HalfCar::<f64>::thesis().theta();
    let est = id.inner().theta::<4>().unwrap();
    let t: Vec<f64> = truth.iter().copied().collect();
    let h: Vec<f64> = est.iter().copied().collect();
    // A refused sample counts as left out, as a screened one.
    (xi(&t, &h).unwrap(), id.inner().paired(), id.screened() + refused)
}

/// A 1e30 sample (a body state, a wheel state, an identified derivative, a derivative no row
/// identifies) at road point 10⁴ or at the first point is screened (or, as the very first
/// sample, refused and left out by the caller), and the road points after
/// it stay paired with the front axle's one wheelbase earlier: exactly two pairs are lost (the
/// outlier's own, and the rear sample that would have met it), ξ moves by under 10 %. Before
/// the screen, such a sample was refused, and a caller going on shifted every later pairing
/// by one point (ξ 0.0069 → 339 in the reproducer).
#[test]
fn a_screened_sample_keeps_the_rear_axle_paired_with_the_front() {
    const N: usize = 11_000;
    for seed in [17, 4242] {
        let (clean, paired, false_alarms) = screened_run(seed, N, 6.0, None);
        for j in [0, 5, 9, 8] {
            for at in [10_000, 0] {
                let (x, p, screened) = screened_run(seed, N, 6.0, Some((j, at)));
                assert!(
                    (x - clean).abs() < 0.1 * clean && screened > false_alarms,
                    "seed {seed}, value {j} at {at}: ξ {clean:.4} -> {x:.4e}, {screened} screened"
                );
                // The first point pairs with nothing anyway: one pair lost (its rear partner's).
                let lost = if at == 0 { 1 } else { 2 };
                assert_eq!(p, paired - lost, "seed {seed}, value {j} at {at}: the pairing moved");
            }
        }
    }
}

/// A screened sample's point passes (`skip_sample`): a sample that is simply not given (the
/// pairing then shifts, as the refused sample did) would pair every later rear sample
/// with the wrong front one and ruin the wheel rows; the screen must not do that.
#[test]
fn skipping_a_point_is_not_dropping_it() {
    let mut a = identifier(WheelMethod::Cancel);
    let mut b = identifier(WheelMethod::Cancel);
    let mut sim = road_sim(RoadMode::White, 3);
    let mut e = [0.0; 4];
    for k in 0..6000 {
        let s = sim.next_sample(6.0).unwrap();
        if k == 3000 {
            a.skip_sample(); // the point passes
            continue; // b: dropped, the later points shift by one
        }
        a.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
        b.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e).unwrap();
    }
    let (ra, _) = row_errors(&a);
    let (rb, _) = row_errors(&b);
    assert!(ra[1] < 0.1 && rb[1] > 10.0 * ra[1], "rear row ξ: skipped {:.4}, dropped {:.4}", ra[1], rb[1]);
}

// ---- the full car: two tracks ---------------------------------------------------------

/// The passenger full car (wheelbase 3.1 m) on ISO 8608 class C at 20 m/s, sampled every
/// 5 ms (0.1 m: the rear wheels `d = 31` samples behind their front wheels), true states and
/// derivatives: `n` samples into a rows identifier of each method. Returns, per method, the
/// largest relative error over the non-zero entries of the seven unknown rows, and of the
/// wheel rows alone.
fn full_car_errors(seed: u64, n: usize, methods: &[WheelMethod]) -> Vec<(f64, f64)> {
    use vehid_core::model::FullCar;
    use vehid_core::sim::{DriveConfig, FullDrive, FullDriveConfig, RoadClass};
    type Full = TwoAxleIdentifierVec<f64, 14, 28, 4>;
    let car = FullCar::<f64>::passenger();
    let (speed, dt) = (20.0, 0.005);
    let d = (car.wheelbase() / (speed * dt)).round() as usize;
    assert_eq!(d, 31);
    let cfg = FullDriveConfig::new(DriveConfig::new(dt).road(RoadClass::C).speed(speed));
    let mut drive = FullDrive::new(car, cfg, seed).unwrap();
    let mut ids: Vec<Full> = methods
        .iter()
        .map(|&m| Full::new(&car.model(), d, TwoAxleConfig::new(m, 1000.0, 0.1, 0.005)).unwrap())
        .collect();
    let mut e = [0.0; 7];
    for _ in 0..n {
        let s = drive.next_sample();
        for id in ids.iter_mut() {
            id.update_at(&s.x, &s.xdot, None, &mut e).unwrap();
        }
    }
    let truth = car.model();
    ids.iter()
        .map(|id| {
            assert_eq!((id.tracks(), id.track_rows(0), id.track_rows(1)), (2, (1, 5), (3, 7)));
            let (mut all, mut wheels) = (0.0f64, 0.0f64);
            for &row in id.rows() {
                let est = id.theta_row(row);
                for j in 0..14 {
                    let a = truth.a()[(row, j)];
                    if a != 0.0 {
                        let err = (est[j] / a - 1.0).abs();
                        all = all.max(err);
                        if row < 8 {
                            wheels = wheels.max(err);
                        }
                    }
                }
            }
            (all, wheels)
        })
        .collect()
}

/// Road cancellation generalized to two tracks: each rear wheel rolls on its front wheel's
/// track (left and right coherent, `sim/two_track.rs`) a wheelbase later, and each track's
/// pair of wheel rows is identified on the regression in which its road cancels. On four
/// seeds every non-zero entry of the seven unknown rows is within 5 % after 20,000 samples
/// (100 s, 2 km); the plain rows on the same samples are far off on the wheel rows (the
/// unmeasured coloured road is correlated with the state). Fresh seeds, more samples:
/// `benches/real_roads.py --full`.
#[test]
fn full_car_road_cancellation_on_two_tracks() {
    let runs = over_seeds(4, |seed| full_car_errors(7_000 + seed, 20_000, &[WheelMethod::Cancel, WheelMethod::None]));
    for (seed, r) in runs.iter().enumerate() {
        eprintln!(
            "full car seed {}: cancel worst entry {:.4}, plain rows' wheel rows {:.3}",
            7_001 + seed,
            r[0].0,
            r[1].1
        );
        assert!(r[0].0 < 0.05, "seed {}: an entry {:.1} % off with road cancellation", 7_001 + seed, 100.0 * r[0].0);
        assert!(r[1].1 > 0.5, "seed {}: the plain rows' wheel rows only {:.1} % off", 7_001 + seed, 100.0 * r[1].1);
    }
}

/// The full car's identifier refuses a model whose inputs are not the front wheels' then the
/// rear wheels' (here: each wheel's road moved to another wheel's column order that puts two
/// inputs on one row), and a rejected sample changes nothing.
#[test]
fn full_car_two_axle_refuses_bad_models_and_samples() {
    use vehid_core::model::FullCar;
    type Full = TwoAxleIdentifierVec<f64, 14, 28, 4>;
    let car = FullCar::<f64>::passenger();
    let m = car.model();
    let mut b = *m.b();
    b[(3, 0)] = b[(1, 0)]; // the first input on two rows
    let bad = LinearModel::new(*m.a(), b, m.unknown_rows().as_slice()).unwrap();
    let cfg = TwoAxleConfig::new(WheelMethod::Cancel, 1000.0, 0.1, 0.005);
    assert!(matches!(Full::new(&bad, 31, cfg), Err(Error::InvalidArgument { arg: "b", .. })));
    let mut id = Full::new(&m, 31, cfg).unwrap();
    let x = SVector::<f64, 14>::from_fn(|i, _| 0.01 * i as f64);
    let mut e = [0.0; 7];
    for _ in 0..40 {
        id.update_at(&x, &(m.a() * x), None, &mut e).unwrap();
    }
    let before = id.clone();
    let mut z = m.a() * x;
    z[5] = f64::NAN;
    assert!(id.update_at(&x, &z, None, &mut e).is_err());
    assert_eq!(format!("{before:?}"), format!("{id:?}"));
}

/// One seed of the full car's statistics (`estimate_stats` through the `Identifier` read-outs): each
/// track's two wheel rows one group whose covariance is the joint filter's `P` (rear row's
/// parameters first, cross-covariance included), its residual sums on the rear row; the body
/// rows one group each. With white derivative noise of the declared σ_v on every row the
/// estimated noise scale `σ̂²/r` is 1 within 5 % on every row. Returns how many of the 66
/// nonzero entries' 95 % intervals hold the truth, and the sum of their squared standardized
/// errors (the exact start: see the comment).
fn full_car_stats_run(seed: u64) -> (usize, usize, f64) {
    use rand_distr::{Distribution, StandardNormal};
    use vehid_core::identify::estimate_stats;
    use vehid_core::model::FullCar;
    use vehid_core::sim::{DriveConfig, FullDrive, FullDriveConfig, RoadClass};
    type Full = TwoAxleIdentifierVec<f64, 14, 28, 4>;
    let car = FullCar::<f64>::passenger();
    let sv = 0.05;
    let cfg = FullDriveConfig::new(DriveConfig::new(0.005).road(RoadClass::C).speed(20.0));
    let mut drive = FullDrive::new(car, cfg, seed).unwrap();
    // The exact start: with a prior its misfit (θ²/p0 summed, about 60 with the thesis'
    // P(0) = 1000 against entries up to 5000 s⁻²) would enter the recursive residual sums.
    let mut cfg = TwoAxleConfig::new(WheelMethod::Cancel, 1000.0, 0.1, sv);
    cfg.direct_front = false;
    cfg.exact = true;
    let mut id = Full::new(&car.model(), 31, cfg).unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut e = [0.0; 7];
    for _ in 0..20_000 {
        let s = drive.next_sample();
        let z = s.xdot
            + SVector::<f64, 14>::from_fn(|_, _| {
                let w: f64 = StandardNormal.sample(&mut rng);
                sv * w
            });
        id.update_at(&s.x, &z, None, &mut e).unwrap();
    }
    let (mut gp, mut ge) = (vec![0; 98], vec![0; 7]);
    id.groups_into(&mut gp, &mut ge).unwrap();
    assert_eq!(ge, [0, 1, 0, 1, 2, 3, 4], "rows 1, 3, 5, 7, 9, 11, 13: the left track 1/5, the right 3/7");
    let mut cov = vec![0.0; 98 * 98];
    id.covariance_into(&mut cov).unwrap();
    let p = id.joint().p(); // the left track: [a_5; a_1]
    let (rear, front) = (2, 0); // positions of rows 5 and 1 among the unknown rows
    for (a, b) in [(0, 0), (3, 17), (20, 2), (27, 27)] {
        let (ia, ib) = (
            if a < 14 { rear * 14 + a } else { front * 14 + a - 14 },
            if b < 14 { rear * 14 + b } else { front * 14 + b - 14 },
        );
        assert_eq!(cov[ia * 98 + ib], p[(a, b)], "P[{a}, {b}]");
    }
    // Row 1's first parameter against row 3's (positions 0 and 1): the tracks are independent.
    assert_eq!(cov[14], 0.0, "the two tracks are independent");
    let (mut ssr, mut nobs) = ([0.0; 7], [0.0; 7]);
    id.residuals_into(&mut ssr, &mut nobs).unwrap();
    assert_eq!((ssr[0], nobs[0]), (0.0, 0.0), "the front row adds nothing: its track's sums are on the rear row");
    assert_eq!((ssr[2], nobs[2]), (id.joint().ssr(), id.joint().nobs()));
    let st = estimate_stats(&id, 0.05).unwrap();
    let mut r = [0.0; 49];
    id.noise_into(&mut r).unwrap();
    for (i, &s2) in st.sigma2.iter().enumerate() {
        let ratio = s2 / r[i * 7 + i];
        assert!((ratio - 1.0).abs() < 0.05, "row {}: sigma2/r {ratio:.3}", id.rows()[i]);
    }
    let truth = car.model();
    let (mut inside, mut n, mut z2) = (0, 0, 0.0);
    for (i, &row) in id.rows().iter().enumerate() {
        for j in 0..14 {
            let a = truth.a()[(row, j)];
            if a != 0.0 {
                let (lo, hi) = st.conf_int[i * 14 + j];
                inside += usize::from(lo <= a && a <= hi);
                n += 1;
                let zs = (st.params[i * 14 + j] - a) / st.bse[i * 14 + j];
                z2 += zs * zs;
            }
        }
    }
    (inside, n, z2)
}

#[test]
fn full_car_two_axle_statistics_are_the_filters_and_cover() {
    // Over 8 seeds: about 95 % of the intervals hold the truth, the standardized errors' mean
    // square is about 1.
    let runs = over_seeds(8, |k| full_car_stats_run(400 + k));
    let (inside, n, z2) = runs.iter().fold((0, 0, 0.0), |a, r| (a.0 + r.0, a.1 + r.1, a.2 + r.2));
    let (cover, z2) = (inside as f64 / n as f64, z2 / n as f64);
    eprintln!("95 % intervals holding the truth: {inside}/{n}; mean squared standardized error {z2:.3}");
    // Measured: 519/528 (98.3 %), 0.855 (seeds 401-408); per seed 0.50-1.08.
    assert!(n == 8 * 66 && (0.9..=1.0).contains(&cover), "{inside}/{n} intervals hold the truth");
    assert!((0.6..1.4).contains(&z2), "mean squared standardized error {z2:.3}");
}

/// The exact start (`TwoAxleConfig::exact`): no estimate until every filter in use has its
/// parameters determined (`RankDeficient`), then least squares; on true states of the full car
/// on class C the cancelled regressions fit to rounding (every entry within 10⁻⁶, where
/// `p0 = 1000` leaves the prior's 0.1–0.3 %). The thesis' method refuses it.
#[test]
fn full_car_exact_start_is_least_squares() {
    use vehid_core::model::FullCar;
    use vehid_core::sim::{DriveConfig, FullDrive, FullDriveConfig, RoadClass};
    type Full = TwoAxleIdentifierVec<f64, 14, 28, 4>;
    let car = FullCar::<f64>::passenger();
    let model = car.model();
    let mut cfg = TwoAxleConfig::new(WheelMethod::Cancel, 1000.0, 0.1, 0.005);
    cfg.exact = true;
    cfg.direct_front = false;
    let mut id = Full::new(&model, 31, cfg).unwrap();
    let drive_cfg = FullDriveConfig::new(DriveConfig::new(0.005).road(RoadClass::C).speed(20.0));
    let mut drive = FullDrive::new(car, drive_cfg, 515).unwrap();
    let mut e = [0.0; 7];
    let mut out = [0.0; 98];
    for k in 0..20_000 {
        let s = drive.next_sample();
        id.update_at(&s.x, &s.xdot, None, &mut e).unwrap();
        if k == 40 {
            // 10 pairs so far: the joint filters (28 parameters) are still in their start.
            assert!(matches!(id.theta_into(&mut out), Err(Error::RankDeficient { needed: 28, .. })));
        }
    }
    id.theta_into(&mut out).unwrap();
    let mut worst = 0.0f64;
    for (i, &row) in id.rows().iter().enumerate() {
        for j in 0..14 {
            let a = model.a()[(row, j)];
            if a != 0.0 {
                worst = worst.max((out[i * 14 + j] / a - 1.0).abs());
            }
        }
    }
    assert!(worst < 1e-6, "worst entry {worst:e}");
    let mut thesis = TwoAxleConfig::new(WheelMethod::Thesis, 1000.0, 0.1, 0.005);
    thesis.exact = true;
    assert!(matches!(Full::new(&model, 31, thesis), Err(Error::InvalidArgument { arg: "exact", .. })));
}

/// One 1e30 derivative (rear left wheel) after 10⁴ good samples of the full car: with each
/// filter's own gate (`TwoAxleConfig::gate`, κ = 6) behind the screen's magnitude test
/// (`Screened::magnitudes_only`: the full car's rows exceed what the screen's structure holds)
/// ξ moves by under 10 %; without them the estimate is ruined. Also a 1e30 state, on a state
/// with a coefficient (the heave rate) and one without in the rows that see it (the front left
/// wheel's position in the left rear wheel's row: left out by the magnitude test, which every
/// sample passes through), and an outlier within the magnitude bound (the heave row's
/// residual gate).
#[test]
fn full_car_gate_survives_one_outlier() {
    use vehid_core::identify::Screened;
    use vehid_core::model::FullCar;
    use vehid_core::sim::{DriveConfig, FullDrive, FullDriveConfig, RoadClass};
    type Full = TwoAxleIdentifierVec<f64, 14, 28, 4>;
    let car = FullCar::<f64>::passenger();
    let model = car.model();
    let truth: Vec<f64> = car.theta().transpose().iter().copied().collect();
    let drive_cfg = FullDriveConfig::new(DriveConfig::new(0.005).road(RoadClass::C).speed(20.0));
    let mut drive = FullDrive::new(car, drive_cfg, 606).unwrap();
    let data: Vec<_> = (0..12_000).map(|_| drive.next_sample()).map(|s| (s.x, s.xdot)).collect();
    // (state?, index, value): the value replaces the sample's, or (NaN) 0.5 is added to it.
    let run = |gate: f64, bad: Option<(bool, usize, f64)>| -> (f64, f64) {
        let mut cfg = TwoAxleConfig::new(WheelMethod::Cancel, 1000.0, 0.1, 0.005);
        cfg.direct_front = false;
        cfg.gate = gate;
        let mut id = Screened::magnitudes_only(Full::new(&model, 31, cfg).unwrap(), gate).unwrap();
        let mut e = [0.0; 7];
        for (k, (x, z)) in data.iter().enumerate() {
            let (mut x, mut z) = (*x, *z);
            if k == 10_000 {
                match bad {
                    Some((true, i, v)) => x[i] = v,
                    Some((false, i, v)) if v.is_nan() => z[i] += 0.5,
                    Some((false, i, v)) => z[i] = v,
                    None => {}
                }
            }
            let step = id.update_into(x.as_slice(), z.as_slice(), &[], &mut e);
            // With the gate every sample is taken (the outlier left out); without it a state
            // outlier may be refused (then nothing changes) or ruin the estimate.
            if gate > 0.0 {
                step.unwrap();
            }
        }
        if gate > 0.0 {
            let by_magnitude = bad.is_some_and(|b| !b.2.is_nan());
            assert_eq!(id.screened(), u64::from(by_magnitude), "{bad:?}: the magnitude test's count");
            assert_eq!(id.inner().samples(), 12_000 - u64::from(by_magnitude), "{bad:?}: the samples passed on");
            let mut gated = [0u64; 7];
            id.gated_into(&mut gated).unwrap();
            if by_magnitude {
                assert!(gated.iter().all(|&g| g >= 1), "{bad:?}: every row counts the sample left out: {gated:?}");
            } else if bad.is_some() {
                assert_eq!(gated[4], 1, "the heave row's gate: {gated:?}");
            }
        }
        let mut th = [0.0; 98];
        id.inner().theta_into(&mut th).unwrap();
        // Every row, and the heave row (the fifth unknown row, row 9) alone.
        (xi(&truth, &th).unwrap(), xi(&truth[56..70], &th[56..70]).unwrap())
    };
    let clean = run(6.0, None);
    // 1e30 in a derivative and in two states (magnitude test); 0.5 m/s² added to the heave
    // acceleration, within its magnitude bound (the heave row's own residual gate).
    // ξ of every row, and of the heave row for the outlier in its derivative.
    for bad in [(false, 5, 1e30), (true, 9, 1e30), (true, 0, 1e30), (false, 9, f64::NAN)] {
        let pick = |r: (f64, f64)| if bad.2.is_nan() { r.1 } else { r.0 };
        let (clean, gated) = (pick(clean), pick(run(6.0, Some(bad))));
        assert!((gated / clean - 1.0).abs() < 0.1, "{bad:?}: xi {clean:.3e} -> {gated:.3e} with the gate");
        if !bad.0 {
            let ungated = pick(run(0.0, Some(bad)));
            assert!(ungated > 10.0 * clean, "{bad:?} without the gate: xi {clean:.3e} -> {ungated:.3e}");
        }
    }
}

//! The thesis' qualitative findings about the identifiers (Ch. IV–V), each tested as a
//! statistical claim over 8 seeds (medians and counts, never one lucky seed).
//!
//! Every test prints what it measured (`cargo test -p vehid-thesis --test thesis_claims --
//! --nocapture`); the figures are quoted in the project notes.

use vehid_core::identify::{Gain, Identifier, KalmanIdentifier, KalmanOptions, StochasticGradient};
use vehid_core::metrics::xi;
use vehid_core::model::QuarterCar;
use vehid_core::sim::{SimConfig, Simulator};

const SEEDS: [u64; 8] = [11, 22, 33, 44, 55, 66, 77, 88];

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The noise settings of a thesis figure caption: σ_ic, σ_u, σ_w, σ_v.
#[derive(Clone, Copy)]
struct Noise {
    ic: f64,
    road: f64,
    state: f64,
    deriv: f64,
}

fn config(n: Noise) -> SimConfig<f64, 4, 1> {
    SimConfig::new(0.05).ic_sigma(n.ic).road_sigma(n.road).state_noise(n.state).deriv_noise(n.deriv)
}

/// Something that identifies the quarter car's rows 1 and 3 sample by sample.
/// ξ (total, wheel row, body row) recorded every `every` samples.
struct Trace {
    total: Vec<f64>,
    body: Vec<f64>,
    every: usize,
}

impl Trace {
    fn at(&self, k: usize) -> f64 {
        self.total[k / self.every - 1]
    }
    fn body_at(&self, k: usize) -> f64 {
        self.body[k / self.every - 1]
    }
    /// First recorded iteration after which ξ stays below `level`, if any.
    fn settles_below(&self, level: f64) -> Option<usize> {
        let last_above = self.total.iter().rposition(|&v| v >= level);
        match last_above {
            None => Some(self.every),
            Some(i) if i + 1 < self.total.len() => Some((i + 2) * self.every),
            Some(_) => None,
        }
    }
}

fn run(seed: u64, noise: Noise, n: usize, every: usize, id: &mut dyn Identifier<f64>) -> Trace {
    let car = QuarterCar::<f64>::thesis();
    let truth = car.theta();
    let mut sim = Simulator::new(car.model(), config(noise), seed).unwrap();
    let mut tr = Trace { total: vec![], body: vec![], every };
    for k in 1..=n {
        let s = sim.next_sample();
        id.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut [0.0; 2]).unwrap();
        if k % every == 0 {
            // θ̂ row-major: row 1 of A (wheel), then row 3 (body).
            let mut th = [0.0; 8];
            id.params_into(&mut th).unwrap();
            let t = truth.transpose();
            tr.total.push(xi(t.as_slice(), &th).unwrap());
            let body_true: Vec<f64> = truth.row(1).iter().copied().collect();
            tr.body.push(xi(&body_true, &th[4..]).unwrap());
        }
    }
    tr
}

fn kalman(p0: f64, r: [f64; 2], reinit: bool) -> KalmanIdentifier<f64, 4, 2> {
    KalmanIdentifier::from_slices(&[1, 3], &[p0], &r, KalmanOptions { reinit, ..Default::default() }).unwrap()
}

fn correct_r(noise: Noise) -> [f64; 2] {
    QuarterCar::<f64>::thesis().model().row_noise_var(noise.road, noise.deriv).unwrap()
}

const FIG_4_2: Noise = Noise { ic: 0.0, road: 0.1, state: 0.0, deriv: 0.005 };

/// Iterations of the Fig 4-2 runs (long enough for every seed to settle; see below).
const FIG_4_2_RUN: usize = 200_000;

#[test]
fn fig_4_2_body_row_fast_wheel_row_slow() {
    // Road noise only: it enters the wheel row, so that row is learned against noise
    // 90·σ_u while the body row sees only σ_v. Claim: the body row converges within 1,000
    // iterations; ξ needs tens of thousands of iterations to fall below 0.08 (the thesis:
    // more than 40,000), and it does fall below it. Two-sided: a seed that never
    // settles fails the test (with 60,000 iterations four of the eight did not, and the old
    // median test passed on ∞).
    // Measured (seeds 11..88): settled after 23,500 to 86,000 iterations, median 72,750.
    let mut body_1000 = vec![];
    let mut xi_1000 = vec![];
    let mut settle = vec![];
    for seed in SEEDS {
        let mut id = kalman(1000.0, correct_r(FIG_4_2), false);
        let tr = run(seed, FIG_4_2, FIG_4_2_RUN, 500, &mut id);
        body_1000.push(tr.body_at(1000));
        xi_1000.push(tr.at(1000));
        settle.push(tr.settles_below(0.08).map(|k| k as f64).unwrap_or(f64::INFINITY));
    }
    let (b, x, s) = (median(body_1000.clone()), median(xi_1000), median(settle.clone()));
    eprintln!("Fig 4-2: median body-row ξ at 1,000 = {b:.2e}; median ξ at 1,000 = {x:.3}; median iterations until ξ stays < 0.08 = {s}; per seed {settle:?}");
    assert!(body_1000.iter().all(|&v| v < 1e-3), "body row converged by 1,000 on every seed: {body_1000:?}");
    assert!(x > 0.08, "ξ not yet acceptable at 1,000");
    // Slow: no seed before 10,000 (measured 23,500 at the earliest), half of them after the
    // thesis' 40,000 (median measured 72,750).
    assert!(settle.iter().all(|&k| k >= 10_000.0), "ξ < 0.08 needs tens of thousands of iterations: {settle:?}");
    assert!(s >= 40_000.0, "median iterations until ξ stays < 0.08: {s} (the thesis: > 40,000)");
    // ... but it converges: every seed holds ξ < 0.08 by 120,000 (measured 86,000 at the latest).
    assert!(settle.iter().all(|&k| k <= 120_000.0), "every seed settles below 0.08: {settle:?}");
}

#[test]
fn fig_4_5_4_6_state_noise_leaves_a_bias_floor() {
    // σ_w = 2 % of σ_u: the regressors are noisy, so the estimate is biased (Eq 2.20). The
    // thesis calls it divergent; we measure whether ξ keeps growing or settles on a floor.
    let noisy = Noise { state: 0.002, ..FIG_4_2 };
    let mut ratio = vec![];
    let mut growth = vec![];
    let mut floor = vec![];
    for seed in SEEDS {
        let mut clean = kalman(1000.0, correct_r(FIG_4_2), false);
        let mut dirty = kalman(1000.0, correct_r(noisy), false);
        let a = run(seed, FIG_4_2, 40_000, 1000, &mut clean);
        let b = run(seed, noisy, 40_000, 1000, &mut dirty);
        ratio.push(b.at(40_000) / a.at(40_000));
        growth.push(b.at(40_000) / b.at(20_000));
        floor.push(b.at(40_000));
    }
    let (r, g, f) = (median(ratio.clone()), median(growth.clone()), median(floor));
    eprintln!("Fig 4-6: median ξ(40k) noisy/clean = {r:.1}; median ξ(40k)/ξ(20k) with noise = {g:.3}; median noisy ξ(40k) = {f:.3}");
    assert!(ratio.iter().all(|&v| v > 2.0), "noisy ξ above noise-free on every seed: {ratio:?}");
    assert!(r > 4.0, "and far above it in the median: {ratio:?}");
    assert!(f > 0.08, "the bias keeps ξ above the acceptance level");
    // A floor, not divergence: ξ changes by less than a factor 2 from 20k to 40k.
    assert!(g > 0.5 && g < 2.0, "bias floor (not divergence): {growth:?}");
}

#[test]
fn fig_4_1_reinit_rescues_a_p0_chosen_far_too_small() {
    // Fig 4-1's slow curves: P(0) too small, the prior dominates (the estimate depends on
    // r/p0 only). Eq 4.36 fires while tr P is small and the errors large, and inflates P.
    let noise = Noise { ic: 0.1, road: 0.1, state: 0.0, deriv: 0.005 };
    let (mut with, mut without, mut fired) = (vec![], vec![], vec![]);
    for seed in SEEDS {
        let mut plain = kalman(10.0, correct_r(noise), false);
        let mut re = kalman(10.0, correct_r(noise), true);
        let a = run(seed, noise, 40_000, 1000, &mut plain);
        let b = run(seed, noise, 40_000, 1000, &mut re);
        without.push(a.at(40_000));
        with.push(b.at(40_000));
        fired.push(re.reinit_count() as f64);
    }
    eprintln!(
        "Fig 4-1 (p0 = 10): median ξ(40k) without reinit = {:.3}, with = {:.3}; reinits per run {:?}",
        median(without.clone()),
        median(with.clone()),
        fired
    );
    assert!(fired.iter().all(|&f| f >= 1.0), "the rule fires on every seed");
    let better = with.iter().zip(&without).filter(|(w, wo)| w < wo).count();
    assert!(better >= 7, "reinit improves ξ on at least 7 of 8 seeds: {with:?} vs {without:?}");
    assert!(median(with) < median(without) / 1.5, "by a clear margin in the median");
}

#[test]
fn fig_4_8_r_chosen_too_small() {
    // Fig 4-8: σ_v = 0.8 but the identifier assumes a smaller R. In exact arithmetic the
    // estimate depends on r/p0 only, so a too-small r is a too-large p0. Report what the rule
    // does; claim only what the algebra guarantees: it fires, and R grows by 2 per firing.
    let noise = Noise { ic: 0.05, road: 0.1, state: 0.001, deriv: 0.8 };
    let good = correct_r(noise);
    let small = [good[0] / 100.0, good[1] / 100.0];
    let (mut correct, mut plain, mut re, mut fired) = (vec![], vec![], vec![], vec![]);
    for seed in SEEDS {
        let mut c = kalman(1000.0, good, false);
        let mut p = kalman(1000.0, small, false);
        let mut r = kalman(1000.0, small, true);
        correct.push(run(seed, noise, 20_000, 1000, &mut c).at(20_000));
        plain.push(run(seed, noise, 20_000, 1000, &mut p).at(20_000));
        re.push(run(seed, noise, 20_000, 1000, &mut r).at(20_000));
        fired.push(r.reinit_count() as f64);
        let r_now = r.filter(0).r();
        assert!((r_now / small[0] - 2f64.powi(r.reinit_count() as i32)).abs() < 1e-9);
    }
    eprintln!(
        "Fig 4-8 (R/100): median ξ(20k) correct R = {:.3}, small R = {:.3}, small R + reinit = {:.3}; median reinits {}",
        median(correct),
        median(plain),
        median(re),
        median(fired.clone())
    );
    assert!(fired.iter().all(|&f| f >= 1.0));
}

#[test]
fn fig_5_1_venter_gradient_is_far_slower_than_kalman() {
    let noise = Noise { ic: 0.08, road: 0.1, state: 0.0, deriv: 0.0 };
    let (mut kf, mut sg) = (vec![], vec![]);
    for seed in SEEDS {
        let mut k = kalman(1000.0, correct_r(Noise { deriv: 0.005, ..noise }), false);
        // Eq 5.10: wheel-row weights one tenth of the body-row weights.
        let h = [0.4, 0.4, 0.4, 0.4, 4.0, 4.0, 4.0, 4.0];
        let mut g =
            StochasticGradient::<f64, 4, 2>::from_slices(&[1, 3], Gain::Venter { p: 0.51 }, &h, &[0.0], 1).unwrap();
        kf.push(run(seed, noise, 40_000, 1000, &mut k).at(40_000));
        sg.push(run(seed, noise, 40_000, 1000, &mut g).at(40_000));
    }
    eprintln!("Fig 5-1: median ξ(40k) Kalman = {:.2e}, Venter p=0.51 = {:.3}", median(kf.clone()), median(sg.clone()));
    assert!(kf.iter().zip(&sg).all(|(k, s)| s > &(10.0 * k)), "gradient ≫ Kalman on every seed");
}

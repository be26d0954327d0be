//! The quarter-car health monitor against its documented design (`health/mod.rs`): the
//! detector step by step (reference, standard errors, CUSUM, threshold), its calibration over
//! seeds (false alarms, detection delay, the intervals' coverage), the kinematic filter
//! against an independent Riccati solution and a closed form, and the tracker's wind-up cap.
//!
//! Seeds: developed on seeds 31_001–33_229 and 100–109; the tests run on the seeds they name
//! (from 52_000), run once when the tests were final. No bound was tuned to a seed: each
//! comes from the documentation and a binomial or interpolation argument stated beside it.

use nalgebra::{SMatrix, SVector};
use vehid_core::health::{
    Constant, DeflectionFilter, HealthConfig, HealthMonitor, RateGain, Reason, Rls, Rls3, Status, JUMP_GATE,
    OFFSET_WALK,
};
use vehid_core::model::QuarterCar;
use vehid_core::sim::{Change, DriveConfig, QuarterDrive};

const DT: f64 = 0.005;

fn car() -> QuarterCar<f64> {
    QuarterCar::<f64>::passenger()
}

/// A passenger-car drive (class C, 15 m/s, 200 Hz, realistic sensors) with `change` at
/// `at` seconds (`None`: no change).
fn drive(seed: u64, change: Option<(&str, f64)>, at: f64) -> QuarterDrive<f64> {
    let mut cfg = DriveConfig::new(DT);
    if let Some((name, v)) = change {
        cfg = cfg.with_change(Change::step(at, name, v).unwrap()).unwrap();
    }
    QuarterDrive::new(car(), cfg, seed).unwrap()
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) + 1e-300
}

// ---------------------------------------------------------------------------------------
// The detector, step by step
// ---------------------------------------------------------------------------------------

/// The monitor's documented pipeline (module documentation of `health`, steps 2–6) written
/// again from the equations, on the public kinematic filter and tracker: the delay line of
/// `stuck_samples`, the reference of the first `warmup` seconds (least squares without
/// forgetting), the noise variance of the a-priori residuals after the first second, the
/// wind-up cap, the relative deviations `r_j = θ_j/θ_ref,j − 1` with standard errors
/// `s_j² = (σ² P_jj/(1+λ) + σ² P_ref,jj)/θ_ref,j²`, and Page's CUSUM
/// `g ← max(0, g + (1 − λ)(δ/s_j²)(±r_j − δ/2))`, alarm when `g > h`.
struct Detector {
    cfg: HealthConfig<f64>,
    kf: DeflectionFilter<f64>,
    ring: Vec<[f64; 3]>,
    reference: Rls3<f64>,
    fast: Rls3<f64>,
    rows: Vec<[f64; 4]>,
    warm_n: usize,
    e2: (f64, usize),
    theta_ref: Option<[f64; 2]>,
    var_ref: [f64; 2],
    sigma2: f64,
    g: [[f64; 2]; 2],
    judged: bool,
    alarm: bool,
}

impl Detector {
    fn new(cfg: HealthConfig<f64>) -> Self {
        let p0 = SMatrix::<f64, 3, 3>::identity() * 1e6;
        let lambda = 1.0 - cfg.dt / cfg.window;
        Self {
            kf: DeflectionFilter::new(cfg.dt, cfg.accel_noise, cfg.deflection_noise, cfg.bias_walk).unwrap(),
            ring: Vec::new(),
            reference: Rls3::new(SVector::zeros(), p0, 1.0),
            fast: Rls3::new(SVector::zeros(), p0, lambda),
            rows: Vec::new(),
            warm_n: 0,
            e2: (0.0, 0),
            theta_ref: None,
            var_ref: [0.0; 2],
            sigma2: 0.0,
            g: [[0.0; 2]; 2],
            judged: true,
            alarm: false,
            cfg,
        }
    }

    fn update(&mut self, y: &[f64]) {
        let (d, v) = self.kf.update_gated(y[2], y[0] - y[1], JUMP_GATE).expect("no jump in a simulated drive");
        self.ring.push([d, v, y[0]]);
        if self.ring.len() < self.cfg.stuck_samples {
            return;
        }
        let [d, v, a] = self.ring.remove(0);
        let phi = SVector::<f64, 3>::new(-d, -v, 1.0);
        let lambda = self.fast.lambda();
        let n_warm = (self.cfg.warmup / self.cfg.dt).ceil() as usize;
        let n_burn = (1.0 / self.cfg.dt).ceil() as usize;
        // The tracker's offset `c` is a random walk (`OFFSET_WALK`), the reference's is not.
        self.fast.release(2, OFFSET_WALK);
        let Some(t_ref) = self.theta_ref else {
            let e = self.reference.update(&phi, a).unwrap();
            self.fast.update(&phi, a).unwrap();
            self.rows.push([-d, -v, 1.0, a]);
            self.warm_n += 1;
            if self.warm_n > n_burn {
                self.e2 = (self.e2.0 + e * e, self.e2.1 + 1);
            }
            if self.warm_n >= n_warm {
                let s2 = self.e2.0 / self.e2.1 as f64;
                let (th, p) = (self.reference.theta(), self.reference.p());
                let var = [s2 * p[(0, 0)], s2 * p[(1, 1)]];
                let lim = self.cfg.min_change / 6.0;
                assert!((0..2).all(|j| th[j] > 0.0 && var[j].sqrt() < lim * th[j]), "the reference is usable");
                self.sigma2 = s2;
                self.theta_ref = Some([th[0], th[1]]);
                self.var_ref = var;
                let je = self.cfg.judge_error;
                let cap = |j: usize| je * je * th[j] * th[j] * (1.0 + lambda) / s2;
                self.fast.set_cap([cap(0), cap(1), f64::MAX]);
            }
            return;
        };
        self.fast.update(&phi, a).unwrap();
        let (th, p) = (self.fast.theta(), self.fast.p());
        let delta = self.cfg.min_change;
        let mut r = [0.0; 2];
        let mut s2 = [0.0; 2];
        for j in 0..2 {
            r[j] = th[j] / t_ref[j] - 1.0;
            s2[j] = (self.sigma2 * p[(j, j)] / (1.0 + lambda) + self.var_ref[j]) / (t_ref[j] * t_ref[j]);
        }
        self.judged = s2.iter().all(|&s| s <= self.cfg.judge_error * self.cfg.judge_error);
        if !self.judged {
            return;
        }
        for j in 0..2 {
            let w = (1.0 - lambda) * delta / s2[j];
            for (side, sign) in [1.0, -1.0].into_iter().enumerate() {
                self.g[j][side] = (self.g[j][side] + w * (sign * r[j] - delta / 2.0)).max(0.0);
                self.alarm |= self.g[j][side] > self.cfg.threshold;
            }
        }
    }
}

/// Batch least squares of the warm-up's rows with the recursion's prior `P(0) = 10⁶ I`,
/// `θ(0) = 0`: `θ = (Xᵀ X + 10⁻⁶ I)⁻¹ Xᵀ y` (the reference is exactly this).
fn batch_reference(rows: &[[f64; 4]]) -> [f64; 2] {
    let mut a = SMatrix::<f64, 3, 3>::identity() * 1e-6;
    let mut b = SVector::<f64, 3>::zeros();
    for r in rows {
        let x = SVector::<f64, 3>::new(r[0], r[1], r[2]);
        a += x * x.transpose();
        b += x * r[3];
    }
    let th = a.cholesky().unwrap().solve(&b);
    [th[0], th[1]]
}

#[test]
fn the_monitor_is_its_documented_detector_step_by_step() {
    // A damper −10 % at 30 s: the monitor's reference, CUSUM statistics and status against the
    // equations at every sample, up to and including the alarm.
    let cfg = HealthConfig::new(DT, car());
    let mut mon = HealthMonitor::new(cfg).unwrap();
    let mut det = Detector::new(cfg);
    let mut d = drive(52_001, Some(("b", 1350.0)), 30.0);
    let mut checked_ref = false;
    let mut max_g = 0.0f64;
    for k in 0..(45.0 / DT) as usize {
        let s = d.next_sample();
        assert_eq!(mon.update(s.y()).unwrap(), None, "sample {k}");
        det.update(s.y());
        let Some(t_ref) = det.theta_ref else {
            assert_eq!(mon.status(), Status::Warmup, "sample {k}");
            continue;
        };
        if !checked_ref {
            // The reference: least squares on the warm-up's rows.
            let batch = batch_reference(&det.rows);
            let got = mon.reference().expect("a reference after the warm-up");
            for j in 0..2 {
                assert!(close(got[j], t_ref[j], 1e-12), "reference {j}: {} vs the equations' {}", got[j], t_ref[j]);
                assert!(close(got[j], batch[j], 1e-9), "reference {j}: {} vs batch least squares {}", got[j], batch[j]);
            }
            checked_ref = true;
        }
        if det.alarm {
            assert_eq!(
                mon.status(),
                Status::Settling,
                "sample {k}: a CUSUM {:?} past the threshold {}, but no alarm",
                det.g,
                cfg.threshold
            );
            assert!(k as f64 * DT > 30.0, "an alarm before the change at {} s", k as f64 * DT);
            assert!(max_g > 0.0);
            return;
        }
        let want = if det.judged { Status::Monitoring } else { Status::CannotJudge(Reason::LowExcitation) };
        assert_eq!(mon.status(), want, "sample {k}");
        let g = mon.cusum();
        for j in 0..2 {
            for side in 0..2 {
                let (got, exp) = (g[j][side], det.g[j][side]);
                assert!(close(got, exp, 1e-9), "sample {k}: CUSUM [{j}][{side}] is {got}, the equations give {exp}");
                max_g = max_g.max(exp);
            }
        }
    }
    panic!("no alarm within 15 s of the damper change (largest CUSUM {max_g})");
}

// ---------------------------------------------------------------------------------------
// Calibration over seeds
// ---------------------------------------------------------------------------------------

/// `P(X ≥ k)` for `X ~ Binomial(n, p)`.
fn binomial_sf(k: usize, n: usize, p: f64) -> f64 {
    let mut c = 1.0f64; // C(n, i)
    let mut sf = 0.0;
    for i in 0..=n {
        if i > 0 {
            c *= (n + 1 - i) as f64 / i as f64;
        }
        if i >= k {
            sf += c * p.powi(i as i32) * (1.0 - p).powi((n - i) as i32);
        }
    }
    sf
}

/// What one drive shows: the sample at which the first alarm was raised (status `Settling`),
/// the first event, the largest CUSUM statistic before the alarm.
struct Run {
    alarm_t: Option<f64>,
    event: Option<vehid_core::health::Event<f64>>,
    max_g: f64,
}

fn run(mon: &mut HealthMonitor<f64>, d: &mut QuarterDrive<f64>, seconds: f64) -> Run {
    let mut out = Run { alarm_t: None, event: None, max_g: 0.0 };
    for k in 0..(seconds / DT) as usize {
        let ev = mon.update(d.next_sample().y()).unwrap();
        if out.event.is_none() {
            out.event = ev;
        }
        if out.alarm_t.is_none() {
            if mon.status() == Status::Settling {
                out.alarm_t = Some(k as f64 * DT);
            } else {
                out.max_g = mon.cusum().iter().flatten().fold(out.max_g, |m, &g| m.max(g));
            }
        }
    }
    out
}

#[test]
fn no_false_alarm_over_seeds() {
    // Documented (docs/capabilities/health.md): no false alarm in 200 h without change, the
    // CUSUMs left at zero; the requirement is at most 1 per 10 h. 16 drives of 50 s
    // (30 s judged each, 8 min in all): at 1 per 10 h the chance of 2 or more alarms is
    // below 10⁻³, so 2 alarms reject the claimed calibration.
    let (drives, seconds) = (16, 50.0);
    let rate_per_drive = (seconds - 20.0) / 36_000.0;
    let allowed = (0..drives).find(|&k| binomial_sf(k + 1, drives, rate_per_drive) < 1e-3).unwrap();
    let mut alarms = 0;
    let mut worst = 0.0f64;
    for seed in 52_100..52_100 + drives as u64 {
        let mut mon = HealthMonitor::new(HealthConfig::new(DT, car())).unwrap();
        let r = run(&mut mon, &mut drive(seed, None, 0.0), seconds);
        alarms += usize::from(r.alarm_t.is_some());
        worst = worst.max(r.max_g);
        assert!(mon.reference().is_some(), "seed {seed}: no reference");
    }
    assert!(alarms <= allowed, "{alarms} false alarms in {drives} drives of {seconds} s (allowed {allowed})");
    // The statistics stay far from the threshold (8): below a quarter of it.
    assert!(worst < 2.0, "largest CUSUM statistic without change: {worst}");
}

/// The documented changes (docs/capabilities/health.md, "Measured performance": 100 seeds,
/// change at 60 s): name, true new value, nominal value, the constant to name, the median and
/// the 95th percentile of the delay of the report after the change (s).
const CHANGES: [(&str, f64, f64, Constant, f64, f64); 3] = [
    ("b", 1350.0, 1500.0, Constant::Damper, 5.96, 6.47),
    ("k2", 19_800.0, 22_000.0, Constant::Spring, 4.34, 4.52),
    ("M", 384.0, 320.0, Constant::BodyMass, 4.25, 4.38),
];

/// Drives per change in the calibration tests.
const SEEDS: u64 = 30;

/// The first event of each drive with each of [`CHANGES`] at 60 s (70 s long; seeds from
/// 52_200, a block of 1000 per change), computed once for the tests that read them.
fn change_events() -> &'static [Vec<vehid_core::health::Event<f64>>; 3] {
    static RUNS: std::sync::OnceLock<[Vec<vehid_core::health::Event<f64>>; 3]> = std::sync::OnceLock::new();
    RUNS.get_or_init(|| {
        core::array::from_fn(|c| {
            let (name, value, ..) = CHANGES[c];
            (0..SEEDS)
                .map(|i| {
                    let seed = 52_200 + 1000 * c as u64 + i;
                    let mut mon = HealthMonitor::new(HealthConfig::new(DT, car())).unwrap();
                    let r = run(&mut mon, &mut drive(seed, Some((name, value)), 60.0), 70.0);
                    r.event
                        .unwrap_or_else(|| panic!("seed {seed}: {name} → {value} not reported (alarm {:?})", r.alarm_t))
                })
                .collect()
        })
    })
}

#[test]
fn detection_delay_over_seeds() {
    // Every change found, named, and reported after the change; the delays against the
    // documented distribution: with `n` drives, the number reported later than the documented
    // median is Binomial(n, 1/2) and later than the 95th percentile Binomial(n, 0.05); each
    // count must stay within its upper 10⁻⁴ tail.
    let n = SEEDS as usize;
    let k50 = (0..n).find(|&k| binomial_sf(k + 1, n, 0.5) < 1e-4).unwrap();
    let k95 = (0..n).find(|&k| binomial_sf(k + 1, n, 0.05) < 1e-4).unwrap();
    for (c, events) in change_events().iter().enumerate() {
        let (name, _, _, want, median, p95) = CHANGES[c];
        let mut delays = Vec::new();
        for e in events {
            assert_eq!(e.parameter, want, "{name}: {e:?}");
            assert!(e.t > 60.0, "{name}: reported at {} s, before the change", e.t);
            delays.push(e.t - 60.0);
        }
        delays.sort_by(f64::total_cmp);
        let late50 = delays.iter().filter(|&&d| d > median).count();
        let late95 = delays.iter().filter(|&&d| d > p95).count();
        assert!(
            late50 <= k50 && late95 <= k95,
            "{name}: report delays {delays:.2?}: {late50} past the median {median} s (allowed {k50}), {late95} past \
             the 95th percentile {p95} s (allowed {k95})"
        );
    }
}

#[test]
fn event_intervals_cover_the_truth_over_seeds() {
    // Documented: an event's 95 % interval holds the true new value (200/200 damper, 196/200
    // spring, 200/200 mass on seeds 9000–9199). Over the 3 × 30 events, the number of misses is
    // Binomial(90, 0.05) at the nominal coverage: it must stay within its upper 10⁻⁴ tail.
    let n = 3 * SEEDS as usize;
    let allowed = (0..n).find(|&k| binomial_sf(k + 1, n, 0.05) < 1e-4).unwrap();
    let mut missed = Vec::new();
    for (c, events) in change_events().iter().enumerate() {
        let (name, truth, before, ..) = CHANGES[c];
        for e in events {
            assert_eq!(e.before, before);
            if !(e.low <= truth && truth <= e.high) {
                missed.push((name, e.low, e.after, e.high));
            }
        }
    }
    assert!(
        missed.len() <= allowed,
        "{} of {n} intervals miss the truth (allowed {allowed}): {missed:?}",
        missed.len()
    );
}

#[test]
fn the_interval_allows_for_the_systematic_error() {
    // `HealthConfig::systematic` is added in quadrature to the statistical error: an event's
    // interval is at least `± z · systematic` relative wide (here 3 %: far wider than the
    // statistical part, measured 0.2–0.45 % of the value on these drives), and no wider than
    // the systematic part with a statistical part of 1 %.
    let mut cfg = HealthConfig::new(DT, car());
    cfg.systematic = 0.03;
    let mut mon = HealthMonitor::new(cfg).unwrap();
    let r = run(&mut mon, &mut drive(52_400, Some(("b", 1350.0)), 30.0), 45.0);
    let e = r.event.expect("the damper change is reported");
    assert_eq!(e.parameter, Constant::Damper);
    let z = 1.959_963_984_540_054;
    let (lo, hi) = ((e.after - e.low) / e.before / z, (e.high - e.after) / e.before / z);
    assert!(close(lo, hi, 1e-9), "a spring or damper interval is symmetric: {lo} {hi}");
    assert!(
        lo >= 0.03 && lo < (0.03f64.powi(2) + 0.01f64.powi(2)).sqrt(),
        "relative standard error {lo} (at least the systematic 0.03)"
    );
}

// ---------------------------------------------------------------------------------------
// The kinematic filter
// ---------------------------------------------------------------------------------------

/// The filter's transition and process noise from its documentation (`kinematic.rs`):
/// `F = [[1, h, −h²/2], [0, 1, −h], [0, 0, 1]]`, `Q = σ_a² g gᵀ + diag(0, 0, q_β² h)`,
/// `g = [h²/2, h, 0]`.
fn model(h: f64, sa: f64, qb: f64) -> (SMatrix<f64, 3, 3>, SMatrix<f64, 3, 3>) {
    let f = SMatrix::<f64, 3, 3>::new(1.0, h, -h * h / 2.0, 0.0, 1.0, -h, 0.0, 0.0, 1.0);
    let g = SVector::<f64, 3>::new(h * h / 2.0, h, 0.0);
    let mut q = g * g.transpose() * (sa * sa);
    q[(2, 2)] += qb * qb * h;
    (f, q)
}

/// The steady-state a-priori covariance `X` of the filter `x⁺ = F x + w` (`Q`), `y = C x + n`
/// (`R`), by the structure-preserving doubling algorithm (Chu, Fan & Lin, "A structure-
/// preserving doubling algorithm for discrete-time algebraic Riccati equations", *Linear
/// Algebra Appl.* 396, 2005) on the DARE `X = F X Fᵀ − F X Cᵀ (C X Cᵀ + R)⁻¹ C X Fᵀ + Q`:
/// `A₀ = Fᵀ`, `G₀ = Cᵀ R⁻¹ C`, `H₀ = Q`, `W = I + G H`, `A ← A W⁻¹ A`,
/// `G ← G + A W⁻¹ G Aᵀ`, `H ← H + Aᵀ H W⁻¹ A`; `H → X` quadratically. (The code iterates the
/// Riccati recursion instead.) Returns `X` and the gain `K = X Cᵀ (C X Cᵀ + R)⁻¹`.
fn doubling<const M: usize>(
    f: SMatrix<f64, 3, 3>,
    q: SMatrix<f64, 3, 3>,
    c: SMatrix<f64, M, 3>,
    r: SMatrix<f64, M, M>,
) -> (SMatrix<f64, 3, 3>, SMatrix<f64, 3, M>) {
    let (mut a, mut g, mut h) = (f.transpose(), c.transpose() * r.try_inverse().unwrap() * c, q);
    for _ in 0..100 {
        let w = (SMatrix::<f64, 3, 3>::identity() + g * h).try_inverse().unwrap();
        let a1 = a * w * a;
        let g1 = g + a * w * g * a.transpose();
        let h1 = h + a.transpose() * h * w * a;
        let done = (h1 - h).abs().max() <= 1e-15 * h1.abs().max();
        (a, g, h) = (a1, (g1 + g1.transpose()) * 0.5, (h1 + h1.transpose()) * 0.5);
        if done {
            break;
        }
    }
    let k = h * c.transpose() * (c * h * c.transpose() + r).try_inverse().unwrap();
    (h, k)
}

#[test]
fn the_filter_gains_are_the_riccati_solution() {
    // The deflection-only filter and the measured-rate filter, at the monitor's defaults and
    // the state sensors' 8 % noise, across sample intervals.
    for (dt, sa, sd, sv, qb) in [
        (0.005, (0.02f64.powi(2) + 0.1f64.powi(2)).sqrt(), 0.3e-3, 0.0, 0.01),
        (0.005, 0.14, 2.6e-3, 2.6e-3, 0.01),
        (0.001, 0.05, 1e-4, 0.0, 0.05),
        (0.02, 0.3, 1e-3, 5e-3, 0.002),
    ] {
        let (f, q) = model(dt, sa, qb);
        let c1 = SMatrix::<f64, 1, 3>::new(1.0, 0.0, 0.0);
        let (x, k) = doubling(f, q, c1, SMatrix::<f64, 1, 1>::new(sd * sd));
        let kf = DeflectionFilter::new(dt, sa, sd, qb).unwrap();
        for i in 0..3 {
            assert!(close(kf.gain()[i], k[i], 1e-7), "dt {dt}: K[{i}] {} vs doubling {}", kf.gain()[i], k[i]);
        }
        let innov = (x[(0, 0)] + sd * sd).sqrt();
        assert!(close(kf.innovation_sd(), innov, 1e-7), "innovation sd {} vs {innov}", kf.innovation_sd());
        if sv > 0.0 {
            let c2 = SMatrix::<f64, 2, 3>::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0);
            let (x2, k2) = doubling(f, q, c2, SMatrix::<f64, 2, 2>::new(sd * sd, 0.0, 0.0, sv * sv));
            let g = RateGain::new(dt, sa, sd, sv, qb).unwrap();
            for i in 0..3 {
                for j in 0..2 {
                    let (got, want) = (g.gain()[i][j], k2[(i, j)]);
                    assert!(close(got, want, 1e-7), "dt {dt}: rate gain K[{i}][{j}] {got} vs doubling {want}");
                }
            }
            assert!(close(g.innovation_sd(), (x2[(0, 0)] + sd * sd).sqrt(), 1e-7));
        }
    }
}

/// A small seeded generator: splitmix64 uniforms, Box–Muller normals.
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

#[test]
fn the_filter_follows_its_equations_step_by_step() {
    // Random deflections and accelerations: each update is the documented prediction
    // `d⁻ = d + h ḋ + h² (a_{k−1}/3 + a_k/6) − h² β/2`, `ḋ⁻ = ḋ + h (a_{k−1} + a_k)/2 − h β`,
    // then `s = s⁻ + K (y − d⁻)` with the doubling algorithm's gain.
    let (h, sa, sd, qb) = (0.005, 0.1, 0.3e-3, 0.01);
    let (f, q) = model(h, sa, qb);
    let (_, k) = doubling(f, q, SMatrix::<f64, 1, 3>::new(1.0, 0.0, 0.0), SMatrix::<f64, 1, 1>::new(sd * sd));
    let mut kf = DeflectionFilter::new(h, sa, sd, qb).unwrap();
    let mut rng = Rng(52_500);
    let (y0, a0) = (0.01 * rng.normal(), rng.normal());
    assert_eq!(kf.update(y0, a0), (y0, 0.0));
    let (mut s, mut prev_a) = ([y0, 0.0, 0.0], a0);
    for step in 0..500 {
        let (y, a) = (0.01 * rng.normal(), rng.normal());
        let dp = s[0] + h * s[1] + h * h * (prev_a / 3.0 + a / 6.0) - h * h / 2.0 * s[2];
        let vp = s[1] + h * (prev_a + a) / 2.0 - h * s[2];
        let nu = y - dp;
        s = [dp + k[0] * nu, vp + k[1] * nu, s[2] + k[2] * nu];
        prev_a = a;
        let (d, v) = kf.update(y, a);
        let st = kf.state();
        for (i, got) in [d, v, st[2]].into_iter().enumerate() {
            assert!((got - s[i]).abs() <= 1e-7 * s[i].abs() + 1e-12, "step {step}: state {i} {got} vs {}", s[i]);
        }
    }
}

#[test]
fn the_filter_rate_converges_to_the_derivative_of_a_sine() {
    // Noise-free d = A sin ωt with exact relative accelerations: the only error is the linear
    // interpolation of the acceleration between samples. Per step the prediction misses the
    // truth by `w_k = [d_k − d_{k−1} − h ḋ_{k−1} − h²(a_{k−1}/3 + a_k/6), ḋ_k − ḋ_{k−1} −
    // h(a_{k−1} + a_k)/2, 0]` (computed here from the closed form), and the estimate's error
    // obeys `e_k = (I − K c)(F e_{k−1} − w_k)`. So after the start-up transient `M^k e_0`
    // (`M = (I − K c) F`) the rate error is at most `Σ_j |[M^j (I − K c)]_{1,·}| · max |w|`.
    let (h, sa, sd, qb) = (0.005, 0.1, 0.3e-3, 0.01);
    let (amp, w) = (0.01, 2.0 * std::f64::consts::PI * 1.5);
    let (f, _) = model(h, sa, qb);
    let mut kf = DeflectionFilter::new(h, sa, sd, qb).unwrap();
    let kg = kf.gain();
    let k = SVector::<f64, 3>::new(kg[0], kg[1], kg[2]);
    let c = SMatrix::<f64, 1, 3>::new(1.0, 0.0, 0.0);
    let ikc = SMatrix::<f64, 3, 3>::identity() - k * c;
    let m = ikc * f;
    let d = |t: f64| amp * (w * t).sin();
    let v = |t: f64| amp * w * (w * t).cos();
    let a = |t: f64| -amp * w * w * (w * t).sin();
    let n = 40_000;
    // The largest interpolation miss over the run, per component.
    let mut wmax = [0.0f64; 2];
    for i in 1..n {
        let (t0, t1) = ((i - 1) as f64 * h, i as f64 * h);
        let wd = d(t1) - d(t0) - h * v(t0) - h * h * (a(t0) / 3.0 + a(t1) / 6.0);
        let wv = v(t1) - v(t0) - h * (a(t0) + a(t1)) / 2.0;
        wmax = [wmax[0].max(wd.abs()), wmax[1].max(wv.abs())];
    }
    // Σ_j |row 1 of M^j (I − K c)|, and the start-up transient M^j e_0 (the first sample sets the
    // rate to 0: e_0 = [0, −Aω, 0]): checked from the sample after which it stays below 10⁻¹².
    let (mut mj, mut gain_sum) = (SMatrix::<f64, 3, 3>::identity(), [0.0f64; 2]);
    let mut e = SVector::<f64, 3>::new(0.0, -amp * w, 0.0);
    let mut transient = Vec::with_capacity(n);
    for _ in 0..n {
        let g = mj * ikc;
        gain_sum = [gain_sum[0] + g[(1, 0)].abs(), gain_sum[1] + g[(1, 1)].abs()];
        transient.push(e[1].abs());
        mj = m * mj;
        e = m * e;
    }
    let from = (0..n).rev().find(|&j| transient[j] >= 1e-12).map_or(0, |j| j + 1);
    assert!(from < n / 2, "the filter forgets its start (from sample {from})");
    let bound = gain_sum[0] * wmax[0] + gain_sum[1] * wmax[1] + 1e-12;
    let mut worst = 0.0f64;
    for i in 0..n {
        let t = i as f64 * h;
        let (_, ve) = kf.update(d(t), a(t));
        if i >= from {
            worst = worst.max((ve - v(t)).abs());
        }
    }
    assert!(worst <= bound, "rate error {worst:.3e} beyond the interpolation bound {bound:.3e} (from sample {from})");
    // The bound means something: under 10⁻³ of the rate's amplitude.
    assert!(bound < 1e-3 * amp * w, "bound {bound:.3e}");
}

// ---------------------------------------------------------------------------------------
// The tracker's wind-up cap
// ---------------------------------------------------------------------------------------

#[test]
fn forgetting_pauses_when_any_one_diagonal_exceeds_its_cap() {
    // One step by the documented update: `λ' = 1` while any diagonal entry of P exceeds its
    // cap. Here only P₀₀ does; the step then divides by 1, not by λ.
    let lambda = 0.9;
    let p0 = SMatrix::<f64, 3, 3>::from_diagonal(&SVector::<f64, 3>::new(2.0, 0.5, 0.5));
    let phi = SVector::<f64, 3>::new(0.3, -1.0, 1.0);
    let expect = |lam: f64| {
        let pphi = p0 * phi;
        let k = pphi / (lam + phi.dot(&pphi));
        (p0 - k * pphi.transpose()) / lam
    };
    for (cap, lam) in [([1.0, 1.0, 1.0], 1.0), ([1.0, 0.1, 0.1], 1.0), ([3.0, 1.0, 1.0], lambda)] {
        let mut rls = Rls3::new(SVector::zeros(), p0, lambda);
        rls.set_cap(cap);
        rls.update(&phi, 1.0).unwrap();
        let want = expect(lam);
        assert!((rls.p() - want).abs().max() < 1e-12, "cap {cap:?}: P {} vs {want}", rls.p());
    }
    // Over a run that never excites the first regressor, P₀₀ stops growing at its cap (one
    // step past it at most) while the other diagonals stay far below theirs.
    let cap = [50.0, 1e6, 1e6];
    let mut rls = Rls::<f64, 3, 1>::new(SMatrix::zeros(), SMatrix::identity(), 0.99);
    rls.set_cap(cap);
    for k in 0..5_000 {
        let t = k as f64 * 0.1;
        rls.update(&SVector::<f64, 3>::new(0.0, t.sin(), 1.0), 0.0).unwrap();
        let p = rls.p();
        assert!(p[(0, 0)] <= cap[0] / 0.99, "sample {k}: P₀₀ {} past its cap {}", p[(0, 0)], cap[0]);
        assert!(p[(1, 1)] < 2.0 && p[(2, 2)] < 2.0, "sample {k}: {p}");
    }
    assert!(rls.p()[(0, 0)] > cap[0], "the cap was reached");
}

/// A spring breaking under a heavy car's weight on a smooth road (the heavy quarter car of
/// `benches/src/bin/check_gain.rs`: M 420 kg, m 40 kg, k2 30 kN/m, b 2.1 kN s/m; k2 × 0.78 at
/// 60 s; ISO 8608 class B at 8 m/s; realistic sensors at 200 Hz). The spring's share of the
/// body's weight goes to the tyre between two samples: both accelerations step (the wheel's
/// by about 20 m/s²), which the kinematic check's two sampled sides and the deflection-rate
/// filter do not follow alike. The check calls that a burst (`health::JUMP_SIGMAS`), and the
/// monitor treats it as a jump in the data: restarts its rate filter and waits out
/// `reacquire`. Over 8 drives the median delay is at most 12 s, every drive names the spring
/// within 30 s, and at least 6 of the 8 intervals hold the new spring (95 % intervals: 5 or
/// fewer with probability 0.6 %). Before, the check's gain dipped by 3–7 % for 10–20 s and
/// held the change back as "sensors disagree" (`check_gain` seeds 62_400–62_407, the change at
/// 120 s: 11–35 s, median 19 s; with the jump 7–19 s, median 8 s); a first version that only
/// left the burst out of the check's statistics reported after 4 s with the new value 2–6 %
/// off and outside its interval on 5 of 8 drives (the rate filter's transient). Developed on
/// seeds 500–502, 600–607 and 62_400–62_407 (at 120 s) and first run here on 62_400–62_407;
/// it runs on fresh seeds 63_100–63_107. Without the burst (its test `if false`) it fails:
/// "delays [13.6, 12.2, 22.6, 14.2, 11.2, 14.2, 24.5, 11.0] (median 13.9 s)" (on 62_400–62_407:
/// median 21.2 s, one drive without an event).
#[test]
fn a_spring_breaking_under_a_heavy_car_on_a_smooth_road_is_reported_within_12_s() {
    use vehid_core::sim::{RoadClass, SensorSet};
    let heavy = QuarterCar::new(420.0, 40.0, 200_000.0, 30_000.0, 2_100.0).unwrap();
    let (at, after) = (60.0, 0.78 * heavy.k2());
    let (mut delays, mut held) = (Vec::new(), 0);
    for seed in 63_100..63_108 {
        let cfg = DriveConfig::new(DT)
            .sensors(SensorSet::Realistic)
            .road(RoadClass::B)
            .speed(8.0)
            .with_change(Change::step(at, "k2", after).unwrap())
            .unwrap();
        let mut sim = QuarterDrive::new(heavy, cfg, seed).unwrap();
        let mut mon = HealthMonitor::new(HealthConfig::new(DT, heavy)).unwrap();
        let mut first = None;
        for _ in 0..((at + 30.0) / DT) as usize {
            let s = sim.next_sample();
            if let Some(ev) = mon.update(s.y()).unwrap() {
                first.get_or_insert(ev);
            }
        }
        let Some(ev) = first else {
            delays.push(f64::INFINITY);
            continue;
        };
        assert!(ev.t > at, "seed {seed}: an event before the change at {:.1} s", ev.t);
        assert_eq!(ev.parameter, Constant::Spring, "seed {seed}");
        delays.push(ev.t - at);
        held += usize::from(ev.low <= after && after <= ev.high);
    }
    let mut sorted = delays.clone();
    sorted.sort_by(f64::total_cmp);
    let median = 0.5 * (sorted[3] + sorted[4]);
    assert!(median <= 12.0 && sorted[7].is_finite(), "delays {delays:.1?} (median {median:.1} s)");
    assert!(held >= 6, "{held} of 8 intervals hold the new spring; delays {delays:.1?}");
}

//! Soak of the recommended online form in `f32`: `SOAK_UPDATES` updates (default
//! 10⁸, ≈ 58 days at 20 Hz) of `KalmanIdentifier<f32, N, K>` with
//! `KalmanOptions { form: CovarianceForm::Sqrt, .. }` per run, each against the same run in
//! `f64`.
//!
//! Run: `make soak`, or `SOAK_UPDATES=2e6 cargo run -q --release -p vehid-benches --bin soak`.
//! Environment: `SOAK_UPDATES` updates per run (default `1e8`), `SOAK_CHECK` updates between
//! checks (default `1e6`), `SOAK_THREADS` runs in parallel (default 1: clean ns/update figures;
//! the 12 runs are 4 data streams of 3 scales each, so at most 4 threads help), `SOAK_ONLY` a
//! substring of the run names to keep (e.g. `half/still`).
//!
//! The runs (12): quarter car (`KalmanIdentifier<_, 4, 2>`) and half car (`<_, 8, 4>`),
//! thesis values, P(0) = 1000 I, R from Eq 4.7 (road σ 0.1, derivative noise 0.005), no gate
//! (the Rust default), × two data streams × three scales:
//! - `excited`: the seeded simulator (dt 0.05 s, road σ 0.1 on every input, derivative noise
//!   0.005, seed 1);
//! - `still`: the same simulator for the first 10⁴ samples, then road 0: the state decays to 0
//!   (through the subnormal range) and only the derivative noise is left, so `x = 0` with a
//!   noisy `z` for almost the whole run (no excitation: nothing to learn, nothing to forget);
//! - states scaled ×1, ×10, ×0.1: `r` and `z` multiplied by the scale, `R` by its square, `P(0)`
//!   and θ unchanged (the same least-squares problem in other units).
//!
//! The data are simulated once in `f64`; the `f32` identifier gets them rounded to `f32`, the
//! `f64` reference (same form and settings) as they are.
//!
//! Every `SOAK_CHECK` updates (and at the end), for every row of both identifiers:
//! - P positive definite. The `U D Uᵀ` factors are private, so `P = U D Uᵀ` is formed
//!   (`RowIdentifier::p`), widened to `f64` and factored again as `U D Uᵀ`: every `D_j` must
//!   be finite and > 0 (reported: the smallest `D_j`, and `λ_min(P) / λ_max(P)` by a symmetric
//!   eigendecomposition in `f64`);
//! - θ̂ finite, `tr P` finite and > 0, and no update rejected (without a gate the data never
//!   justify a rejection).
//!
//! At the end: ξ (Eq 3.17) of the `f32` run within a factor 10 of the `f64` run's. One progress
//! line per run and check, then a table; exit status 1 when any run fails (2: bad settings).

use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};
use vehid_core::identify::{CovarianceForm, KalmanIdentifier, KalmanOptions};
use vehid_core::metrics::xi;
use vehid_core::model::{HalfCar, LinearModel, QuarterCar};
use vehid_core::nalgebra::{DMatrix, SMatrix, SVector};
use vehid_core::sim::{SimConfig, Simulator};
use vehid_core::Real;

/// Seed of the simulator (every run).
const SEED: u64 = 1;
/// Excited samples at the start of a `still` run.
const START: u64 = 10_000;
/// Samples simulated at a time (then fed to every identifier of the stream).
const CHUNK: u64 = 10_000;
/// P(0) = P0 I.
const P0: f64 = 1000.0;
/// The state scales.
const SCALES: [f64; 3] = [1.0, 10.0, 0.1];
/// ξ of f32 and f64 must agree within this factor.
const XI_FACTOR: f64 = 10.0;

/// The data streams: model and excitation.
const STREAMS: [(&str, bool); 4] = [("quarter", true), ("quarter", false), ("half", true), ("half", false)];

struct Settings {
    updates: u64,
    check: u64,
    only: String,
}

/// The lowest figures seen at the checks of one identifier, and what went wrong.
struct Watch {
    /// Smallest `D_j` of the re-factored `P` over rows and checks.
    min_d: f64,
    /// Smallest `λ_min(P) / λ_max(P)` over rows and checks.
    min_ratio: f64,
    rejected: u64,
    time: Duration,
    failures: Vec<String>,
}

impl Watch {
    fn new() -> Self {
        Self { min_d: f64::INFINITY, min_ratio: f64::INFINITY, rejected: 0, time: Duration::ZERO, failures: Vec::new() }
    }

    fn fail(&mut self, what: String) {
        // The first few say what happened; the rest would repeat it at every check.
        if self.failures.len() < 3 {
            self.failures.push(what);
        }
    }
}

/// One finished run, for the table.
struct Outcome {
    name: String,
    updates: u64,
    ns32: f64,
    ns64: f64,
    min_d: f64,
    min_ratio: f64,
    xi32: f64,
    xi64: f64,
    failures: Vec<String>,
}

/// `D` of `P = U D Uᵀ` (`U` unit upper triangular), or `None` when a pivot is not > 0 (P not
/// positive definite) or not finite. The factorization Bierman's form keeps.
fn ud_diagonal<const N: usize>(p: &SMatrix<f64, N, N>) -> Option<SVector<f64, N>> {
    let mut u = SMatrix::<f64, N, N>::identity();
    let mut d = SVector::<f64, N>::zeros();
    for j in (0..N).rev() {
        let mut dj = p[(j, j)];
        for k in j + 1..N {
            dj -= u[(j, k)] * u[(j, k)] * d[k];
        }
        if !(dj > 0.0) || !dj.is_finite() {
            return None;
        }
        d[j] = dj;
        for i in 0..j {
            let mut v = p[(i, j)];
            for k in j + 1..N {
                v -= u[(i, k)] * u[(j, k)] * d[k];
            }
            u[(i, j)] = v / dj;
        }
    }
    Some(d)
}

/// The f64 figures of one row's covariance: (min D, λ_min/λ_max), or a failure message.
fn covariance_figures<const N: usize>(p: &SMatrix<f64, N, N>) -> Result<(f64, f64), String> {
    if p.iter().any(|v| !v.is_finite()) {
        return Err("P holds a non-finite entry".into());
    }
    let d = ud_diagonal(p).ok_or_else(|| "P is not positive definite (a U D Uᵀ pivot ≤ 0)".to_string())?;
    let eig = DMatrix::from_fn(N, N, |i, j| p[(i, j)]).symmetric_eigenvalues();
    let (lo, hi) = (eig.min(), eig.max());
    Ok((d.min(), if hi > 0.0 { lo / hi } else { f64::NAN }))
}

/// One precision's identifier of a run with its watch.
struct Tracked<T: Real, const N: usize, const K: usize> {
    id: KalmanIdentifier<T, N, K>,
    watch: Watch,
    buf: Vec<(SVector<T, N>, SVector<T, N>)>,
}

impl<T: Real, const N: usize, const K: usize> Tracked<T, N, K> {
    fn new(rows: [usize; K], r: &[f64; K], scale: f64) -> vehid_core::Result<Self> {
        let r: Vec<T> = r.iter().map(|v| T::of(v * scale * scale)).collect();
        let opts = KalmanOptions { form: CovarianceForm::Sqrt, ..KalmanOptions::default() };
        let id = KalmanIdentifier::<T, N, K>::from_slices(&rows, &[T::of(P0)], &r, opts)?;
        Ok(Self { id, watch: Watch::new(), buf: Vec::with_capacity(CHUNK as usize) })
    }

    /// Updates with every sample of `data` scaled by `scale` (the conversion is not timed).
    fn feed(&mut self, data: &[(SVector<f64, N>, SVector<f64, N>)], scale: f64) {
        self.buf.clear();
        self.buf.extend(data.iter().map(|(x, z)| (x.map(|v| T::of(v * scale)), z.map(|v| T::of(v * scale)))));
        let mut rejected = 0u64;
        let mut first: Option<vehid_core::Error> = None;
        let t0 = Instant::now();
        for (x, z) in &self.buf {
            if let Err(e) = self.id.update(x, z) {
                rejected += 1;
                first.get_or_insert(e);
            }
        }
        self.watch.time += t0.elapsed();
        if let Some(e) = first {
            let at = self.id.samples() + self.watch.rejected;
            self.watch.fail(format!("{rejected} updates rejected near update {at}, first: {e}"));
        }
        self.watch.rejected += rejected;
    }

    /// θ̂ row-major, in f64 (NaN when it cannot be read).
    fn theta(&self) -> Vec<f64> {
        let mut out = vec![T::zero(); K * N];
        match self.id.theta_into(&mut out) {
            Ok(()) => out.iter().map(|v| v.to_f64()).collect(),
            Err(_) => vec![f64::NAN; K * N],
        }
    }

    /// The checks at `done` updates; returns (min D, min λ ratio) of this check.
    fn check(&mut self, done: u64) -> (f64, f64) {
        let (mut min_d, mut min_ratio) = (f64::INFINITY, f64::INFINITY);
        for i in 0..K {
            let f = self.id.filter(i);
            if f.theta().iter().any(|v| !v.finite()) {
                self.watch.fail(format!("θ̂ of row {i} not finite at update {done}"));
            }
            let tr = f.trace().to_f64();
            if !(tr > 0.0) || !tr.is_finite() {
                self.watch.fail(format!("tr P of row {i} is {tr:e} at update {done}"));
            }
            let p = f.p().map(|v| v.to_f64());
            match covariance_figures(&p) {
                Ok((d, ratio)) => {
                    min_d = min_d.min(d);
                    min_ratio = min_ratio.min(ratio);
                }
                Err(what) => {
                    self.watch.fail(format!("row {i} at update {done}: {what}"));
                    min_d = f64::NAN;
                }
            }
        }
        self.watch.min_d = if min_d.is_nan() { f64::NAN } else { self.watch.min_d.min(min_d) };
        self.watch.min_ratio = self.watch.min_ratio.min(min_ratio);
        (min_d, min_ratio)
    }
}

/// A run: one scale of one stream, in both precisions.
struct Run<const N: usize, const K: usize> {
    name: String,
    scale: f64,
    f32: Tracked<f32, N, K>,
    f64: Tracked<f64, N, K>,
}

fn xi_of(truth: &[f64], theta: &[f64]) -> f64 {
    xi(truth, theta).unwrap_or(f64::NAN)
}

/// Runs one data stream through the identifiers of its three scales.
fn stream<const N: usize, const M: usize, const K: usize>(
    name: &str,
    model: LinearModel<f64, N, M>,
    rows: [usize; K],
    excited: bool,
    s: &Settings,
) -> vehid_core::Result<Vec<Outcome>> {
    let r: [f64; K] = model.row_noise_var(0.1, 0.005)?;
    let mut truth = vec![0.0; K * N];
    model.theta_into(&mut truth)?;
    let mut runs = Vec::new();
    for scale in SCALES {
        let run_name = format!("{name}/{}/x{scale}", if excited { "excited" } else { "still" });
        if !run_name.contains(&s.only) {
            continue;
        }
        runs.push(Run::<N, K> {
            name: run_name,
            scale,
            f32: Tracked::new(rows, &r, scale)?,
            f64: Tracked::new(rows, &r, scale)?,
        });
    }
    if runs.is_empty() {
        return Ok(Vec::new());
    }
    let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
    let mut sim = Simulator::new(model, cfg, SEED)?;
    let zero = SVector::<f64, M>::zeros();
    let mut data = Vec::with_capacity(CHUNK as usize);
    let (mut done, mut next_check) = (0u64, s.check.min(s.updates));
    let checks = s.updates.div_ceil(s.check);
    let t0 = Instant::now();
    while done < s.updates {
        let len = (next_check - done).min(CHUNK);
        data.clear();
        for _ in 0..len {
            let smp = if excited || sim.k() < START { sim.next_sample() } else { sim.next_sample_with(&zero)? };
            data.push((smp.r, smp.z));
        }
        for run in &mut runs {
            run.f32.feed(&data, run.scale);
            run.f64.feed(&data, run.scale);
        }
        done += len;
        if done == next_check {
            for run in &mut runs {
                let (d32, q32) = run.f32.check(done);
                let (d64, q64) = run.f64.check(done);
                let (x32, x64) = (xi_of(&truth, &run.f32.theta()), xi_of(&truth, &run.f64.theta()));
                println!(
                    "soak {:<22} check {:>3}/{checks} {done:>11} updates  f32: min D {d32:9.3e} λmin/λmax {q32:9.3e} \
                     ξ {x32:9.3e}  f64: min D {d64:9.3e} λmin/λmax {q64:9.3e} ξ {x64:9.3e}  rejected {}/{}  [{:.0} s]",
                    run.name,
                    done.div_ceil(s.check),
                    run.f32.watch.rejected,
                    run.f64.watch.rejected,
                    t0.elapsed().as_secs_f64(),
                );
            }
            next_check = (next_check + s.check).min(s.updates);
        }
    }
    Ok(runs
        .into_iter()
        .map(|run| {
            let (xi32, xi64) = (xi_of(&truth, &run.f32.theta()), xi_of(&truth, &run.f64.theta()));
            let mut failures = run.f32.watch.failures.clone();
            failures.extend(run.f64.watch.failures.iter().map(|f| format!("f64 reference: {f}")));
            let within = xi32.is_finite() && xi64.is_finite() && xi32 <= XI_FACTOR * xi64 && xi64 <= XI_FACTOR * xi32;
            if !within {
                failures.push(format!("ξ f32 {xi32:.3e} is not within a factor {XI_FACTOR} of ξ f64 {xi64:.3e}"));
            }
            let ns = |w: &Watch| w.time.as_secs_f64() * 1e9 / s.updates as f64;
            Outcome {
                name: run.name,
                updates: s.updates,
                ns32: ns(&run.f32.watch),
                ns64: ns(&run.f64.watch),
                min_d: run.f32.watch.min_d,
                min_ratio: run.f32.watch.min_ratio,
                xi32,
                xi64,
                failures,
            }
        })
        .collect())
}

fn run_stream(i: usize, s: &Settings) -> vehid_core::Result<Vec<Outcome>> {
    let (model, excited) = STREAMS[i];
    match model {
        "quarter" => {
            let q = QuarterCar::<f64>::thesis();
            stream("quarter", q.model(), q.unknown_rows(), excited, s)
        }
        _ => {
            let h = HalfCar::<f64>::thesis();
            stream("half", h.model(), h.unknown_rows(), excited, s)
        }
    }
}

/// A count from the environment: `1e8`, `100000000` or `100_000_000`.
fn count(var: &str, default: u64) -> Result<u64, String> {
    let Ok(text) = std::env::var(var) else { return Ok(default) };
    let v: f64 = text.replace('_', "").trim().parse().map_err(|_| format!("{var}={text:?} is not a number"))?;
    if !(v >= 1.0) || v.fract() != 0.0 || v > 1e15 {
        return Err(format!("{var}={text:?}: expected a whole number of updates >= 1"));
    }
    Ok(v as u64)
}

fn settings() -> Result<(Settings, usize), String> {
    let updates = count("SOAK_UPDATES", 100_000_000)?;
    let check = count("SOAK_CHECK", 1_000_000)?;
    let threads = count("SOAK_THREADS", 1)? as usize;
    let only = std::env::var("SOAK_ONLY").unwrap_or_default();
    Ok((Settings { updates, check, only }, threads.min(STREAMS.len())))
}

fn main() -> ExitCode {
    let (s, threads) = match settings() {
        Ok(v) => v,
        Err(e) => {
            eprintln!("soak: {e}");
            return ExitCode::from(2);
        }
    };
    println!(
        "soak: {} updates per run, checks every {}, {threads} thread(s); f32 and f64 KalmanIdentifier, form sqrt, \
         p0 {P0}, no gate; seed {SEED}",
        s.updates, s.check
    );
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<(usize, vehid_core::Result<Vec<Outcome>>)>> = Mutex::new(Vec::new());
    let t0 = Instant::now();
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= STREAMS.len() {
                    break;
                }
                let out = run_stream(i, &s);
                results.lock().unwrap_or_else(|e| e.into_inner()).push((i, out));
            });
        }
    });
    let mut results = results.into_inner().unwrap_or_else(|e| e.into_inner());
    results.sort_by_key(|(i, _)| *i);
    let mut failed = false;
    let mut outcomes = Vec::new();
    for (i, res) in results {
        match res {
            Ok(o) => outcomes.extend(o),
            Err(e) => {
                eprintln!("soak: stream {}/{} could not run: {e}", STREAMS[i].0, STREAMS[i].1);
                failed = true;
            }
        }
    }
    println!();
    println!("soak summary ({:.0} s): min D and λmin/λmax are the f32 run's, the lowest over rows and checks", {
        t0.elapsed().as_secs_f64()
    });
    println!(
        "| run | updates | ns/update f32 | ns/update f64 | min D (f32) | min λmin/λmax (f32) | ξ f32 | ξ f64 | ξ32/ξ64 \
         | verdict |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    for o in &outcomes {
        let verdict = if o.failures.is_empty() { "ok" } else { "FAIL" };
        println!(
            "| {} | {:.0e} | {:.1} | {:.1} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.2} | {verdict} |",
            o.name,
            o.updates as f64,
            o.ns32,
            o.ns64,
            o.min_d,
            o.min_ratio,
            o.xi32,
            o.xi64,
            o.xi32 / o.xi64
        );
    }
    for o in &outcomes {
        for f in &o.failures {
            println!("FAIL {}: {f}", o.name);
            failed = true;
        }
    }
    if outcomes.is_empty() {
        eprintln!("soak: no run matches SOAK_ONLY={:?}", s.only);
        return ExitCode::from(2);
    }
    if failed {
        ExitCode::FAILURE
    } else {
        println!("soak: every run passed");
        ExitCode::SUCCESS
    }
}

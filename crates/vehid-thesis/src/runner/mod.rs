//! The runner: every curve of the selected figures over `S` seeds, in parallel (scoped
//! threads over a shared job counter), ξ_k (Eq 3.17 / 6.10) recorded on a fixed grid, then
//! the median and the 10–90 % band over seeds and each claim evaluated against the
//! measurements. The first seed of every identifier curve also records the car's physical
//! constants with their 95 % intervals on a decimated grid (`constants`).

mod constants;
mod ident;
mod job;

pub use constants::CONSTANT_POINTS;
pub(crate) use constants::{structure_constants, Estimate};

pub(crate) use job::Trace;

use crate::beyond;
use crate::figures::{select, Experiment, ModelKind};
use crate::report::{FigureResult, Report};
use crate::seeds::{beyond_class_seed, beyond_seed, job_seed};
use crate::stats::summarize;
use crate::tables::tables;
use crate::verdict::evaluate;
use job::simulate;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// Options of a reproduction run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Quick mode: 5 seeds and at most [`QUICK_ITERATIONS`] iterations per curve.
    pub quick: bool,
    /// Seeds per curve (default 5 quick, 16 full).
    pub seeds: Option<usize>,
    /// Cap on the iterations of every curve (on top of quick mode's cap).
    pub max_iterations: Option<usize>,
    /// Base seed; every realization derives from it.
    pub base_seed: u64,
    /// Worker threads (default: the available parallelism).
    pub threads: Option<usize>,
    /// Figure ids to run (empty = all).
    pub only: Vec<String>,
    /// Also compute the tables (Eq 4.28, 4.32, 4.34, Table I).
    pub tables: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            quick: false,
            seeds: None,
            max_iterations: None,
            base_seed: 1986,
            threads: None,
            only: vec![],
            tables: true,
        }
    }
}

/// Iteration cap of quick mode.
pub const QUICK_ITERATIONS: usize = 10_000;

/// A progress report: jobs (one curve × seed) done out of total.
#[derive(Debug, Clone, Copy)]
pub struct Progress<'a> {
    /// Jobs finished.
    pub done: usize,
    /// Jobs in total.
    pub total: usize,
    /// The figure of the job just finished.
    pub figure: &'a str,
}

/// The recording grid: every iteration up to 50, then every `every`.
fn grid(n: usize) -> Vec<u64> {
    let every = (n / 200).max(1);
    let mut k: Vec<u64> = (1..=n.min(50) as u64).collect();
    let mut j = every;
    while j <= n {
        if j > 50 {
            k.push(j as u64);
        }
        j += every;
    }
    if k.last().copied() != Some(n as u64) && n > 0 {
        k.push(n as u64);
    }
    k
}

/// from the worker threads.
///
/// # Errors
/// An unknown figure id in `only`; a simulation or identifier error (a bug in the table).
pub fn run(opts: &RunOptions, progress: &(dyn Fn(Progress<'_>) + Sync)) -> crate::Result<Report> {
    let start = std::time::Instant::now();
    // Figures beyond the thesis (B-1, B-2, B-3) are selected by id like the thesis' figures; an
    // empty selection runs everything.
    let (beyond_ids, thesis_ids): (Vec<String>, Vec<String>) =
        opts.only.iter().cloned().partition(|id| beyond::is_beyond(id));
    let exps = if !opts.only.is_empty() && thesis_ids.is_empty() { vec![] } else { select(&thesis_ids)? };
    let wants = |id: &str| opts.only.is_empty() || beyond_ids.iter().any(|b| b.trim() == id);
    let (run_sweep, run_half, run_roads) = (wants(beyond::SWEEP_ID), wants(beyond::HALF_ID), wants(beyond::ROADS_ID));
    let run_full = wants(beyond::FULL_ID);
    let full_seconds = match opts.max_iterations {
        // A cap on the iterations caps the drives' samples too (but keeps the change inside them).
        Some(m) => (m.max(1) as f64 * beyond::full::FULL_DT)
            .clamp(beyond::full::FULL_CHANGE_AT + 1.0, beyond::full::FULL_SECONDS),
        None => beyond::full::FULL_SECONDS,
    };
    let seeds = opts.seeds.unwrap_or(if opts.quick { 5 } else { 16 }).max(1);
    // The figures beyond the thesis keep at least MIN_SEEDS seeds unless `seeds` is given.
    let beyond_seeds = opts.seeds.unwrap_or(seeds.max(beyond::MIN_SEEDS)).max(1);
    let threads =
        opts.threads.unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(2)).clamp(1, 64);
    let cap = |mut n: usize| {
        if let Some(m) = opts.max_iterations {
            n = n.min(m.max(1));
        }
        n
    };
    let iters_of = |e: &Experiment| cap(if opts.quick { e.iterations.min(QUICK_ITERATIONS) } else { e.iterations });
    let beyond_samples = cap(if opts.quick { beyond::QUICK_SWEEP_SAMPLES } else { beyond::SWEEP_SAMPLES });
    let roads_samples = cap(if opts.quick { beyond::QUICK_ROADS_SAMPLES } else { beyond::ROADS_SAMPLES });
    // Jobs: a curve × seed of a thesis figure, a level × seed of B-1 / B-2 or a class × seed of
    // B-3; longest first for a balanced finish (a B job runs every method on its samples: 7, 6
    // or 2 identifiers).
    let grids: Vec<Vec<u64>> = exps.iter().map(|e| grid(iters_of(e))).collect();
    let mut jobs: Vec<Job> = vec![];
    for (fi, e) in exps.iter().enumerate() {
        if e.needs.is_some() {
            continue;
        }
        for ci in 0..e.curves.len() {
            for s in 0..seeds {
                jobs.push(Job::Curve(fi, ci, s));
            }
        }
    }
    for s in 0..beyond_seeds {
        if run_sweep {
            jobs.extend((0..beyond::SWEEP_LEVELS.len()).map(|li| Job::Sweep(li, s)));
        }
        if run_half {
            jobs.extend((0..beyond::HALF_LEVELS.len()).map(|li| Job::Half(li, s)));
        }
        if run_roads {
            jobs.extend((0..beyond::ROAD_CLASSES.len()).map(|ci| Job::Roads(ci, s)));
        }
    }
    let full_seeds = opts.seeds.unwrap_or(beyond::full::FULL_SEEDS).max(1);
    if run_full {
        for s in 0..full_seeds {
            jobs.extend((0..beyond::FULL_SCENARIOS.len()).map(|ci| Job::Full(ci, s)));
        }
    }
    let cost = |j: &Job| match *j {
        Job::Curve(fi, _, _) => {
            let e = exps[fi];
            iters_of(e) * if e.model == ModelKind::Quarter { 1 } else { 4 }
        }
        Job::Sweep(..) => beyond_samples * 20,
        Job::Half(..) => beyond_samples * 30,
        Job::Roads(..) => roads_samples * 2,
        Job::Full(..) => (full_seconds / beyond::full::FULL_DT) as usize,
    };
    jobs.sort_by_key(|j| core::cmp::Reverse(cost(j)));
    let results: Mutex<Vec<Slot>> = Mutex::new((0..jobs.len()).map(|_| None).collect());
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..threads.min(jobs.len().max(1)) {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(&job) = jobs.get(i) else { break };
                let t0 = std::time::Instant::now();
                let (out, figure) = match job {
                    Job::Curve(fi, ci, s) => {
                        let e = exps[fi];
                        let seed = job_seed(opts.base_seed, e, ci, s);
                        (simulate(e, &e.curves[ci], &grids[fi], seed, s == 0).map(Out::Trace), e.id)
                    }
                    Job::Sweep(li, s) => {
                        let seed = beyond_seed(opts.base_seed, beyond::SWEEP_ID, s);
                        let out = beyond::sweep_job(beyond::SWEEP_LEVELS[li], beyond_samples, seed);
                        (out.map(Out::Sweep), beyond::SWEEP_ID)
                    }
                    Job::Half(li, s) => {
                        let seed = beyond_seed(opts.base_seed, beyond::HALF_ID, s);
                        let out = beyond::half_job(beyond::HALF_LEVELS[li], beyond_samples, seed);
                        (out.map(Out::Half), beyond::HALF_ID)
                    }
                    Job::Roads(ci, s) => {
                        let seed = beyond_class_seed(opts.base_seed, beyond::ROADS_ID, ci, s);
                        let out = beyond::roads_job(beyond::ROAD_CLASSES[ci], roads_samples, seed);
                        (out.map(Out::Roads), beyond::ROADS_ID)
                    }
                    Job::Full(ci, s) => {
                        let seed = beyond_class_seed(opts.base_seed, beyond::FULL_ID, ci, s);
                        (beyond::full_job(ci, full_seconds, seed).map(Out::Full), beyond::FULL_ID)
                    }
                };
                results.lock().unwrap_or_else(|p| p.into_inner())[i] = Some((out, t0.elapsed().as_secs_f64()));
                let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                progress(Progress { done: d, total: jobs.len(), figure });
            });
        }
    });
    // After the workers: Table I times updates, which must not share the cores.
    let table_out = if opts.tables { Some(tables(opts.base_seed, seeds, opts.quick)) } else { None };
    let mut results = results.into_inner().unwrap_or_else(|p| p.into_inner());
    let figure = |e: &Experiment, iterations: usize| FigureResult {
        id: e.id,
        title: e.title,
        model: e.model,
        thesis_iterations: e.iterations,
        iterations,
        seeds,
        assumptions: e.assumptions,
        skipped: None,
        k: vec![],
        curves: vec![],
        verdicts: vec![],
    };
    let mut figures = vec![];
    for (fi, e) in exps.iter().enumerate() {
        let n = iters_of(e);
        if let Some(why) = e.needs {
            figures.push(FigureResult { skipped: Some(why.to_string()), ..figure(e, 0) });
            continue;
        }
        let mut curves = vec![];
        for (ci, curve) in e.curves.iter().enumerate() {
            let mut traces = vec![];
            for (ji, j) in jobs.iter().enumerate() {
                if *j == Job::Curve(fi, ci, j.seed()) {
                    if let (Out::Trace(t), _) = take(&mut results, ji)? {
                        traces.push(t);
                    }
                }
            }
            curves.push(summarize(curve, ci, &traces, &grids[fi]));
        }
        let verdicts = e.claims.iter().map(|c| evaluate(c, &curves, n, opts.quick)).collect();
        figures.push(FigureResult { k: grids[fi].clone(), curves, verdicts, ..figure(e, n) });
    }
    // Figures beyond the thesis: outputs indexed [level][seed].
    let (mut sweep_out, mut half_out) = (
        vec![vec![vec![]; beyond_seeds]; beyond::SWEEP_LEVELS.len()],
        vec![vec![vec![]; beyond_seeds]; beyond::HALF_LEVELS.len()],
    );
    let mut roads_out = vec![vec![vec![]; beyond_seeds]; beyond::ROAD_CLASSES.len()];
    let mut full_out = vec![vec![]; beyond::FULL_SCENARIOS.len()];
    let (mut sweep_cpu, mut half_cpu, mut roads_cpu, mut full_cpu) = (0.0, 0.0, 0.0, 0.0);
    for (ji, j) in jobs.iter().enumerate() {
        match *j {
            Job::Sweep(li, s) => {
                if let (Out::Sweep(v), t) = take(&mut results, ji)? {
                    sweep_out[li][s] = v;
                    sweep_cpu += t;
                }
            }
            Job::Half(li, s) => {
                if let (Out::Half(v), t) = take(&mut results, ji)? {
                    half_out[li][s] = v;
                    half_cpu += t;
                }
            }
            Job::Roads(ci, s) => {
                if let (Out::Roads(v), t) = take(&mut results, ji)? {
                    roads_out[ci][s] = v;
                    roads_cpu += t;
                }
            }
            Job::Full(ci, s) => {
                if let (Out::Full(v), t) = take(&mut results, ji)? {
                    full_out[ci].push((s, v));
                    full_cpu += t;
                }
            }
            Job::Curve(..) => {}
        }
    }
    let sweep = run_sweep.then(|| {
        beyond::sweep_result(&beyond::SWEEP_LEVELS, &sweep_out, beyond_samples, beyond::SWEEP_SAMPLES, sweep_cpu)
    });
    let half_one_road =
        run_half.then(|| beyond::half_result(&beyond::HALF_LEVELS, &half_out, beyond_samples, half_cpu));
    let real_roads =
        run_roads.then(|| beyond::roads_result(&roads_out, roads_samples, beyond::ROADS_SAMPLES, roads_cpu));
    let full_car = run_full.then(|| {
        let by_seed: Vec<Vec<beyond::FullOutcome>> = full_out
            .into_iter()
            .map(|mut v| {
                v.sort_by_key(|(s, _)| *s);
                v.into_iter().map(|(_, o)| o).collect()
            })
            .collect();
        beyond::full_result(&by_seed, full_seconds, full_cpu)
    });
    let mut tables = match table_out {
        Some(t) => t?,
        None => vec![],
    };
    tables.extend(beyond::tables(sweep.as_ref(), half_one_road.as_ref(), real_roads.as_ref(), full_car.as_ref()));
    Ok(Report {
        quick: opts.quick,
        base_seed: opts.base_seed,
        threads,
        seconds: start.elapsed().as_secs_f64(),
        figures,
        tables,
        sweep,
        half_one_road,
        real_roads,
        full_car,
    })
}

/// One job of the pool.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Job {
    /// A thesis figure's (figure, curve, seed index).
    Curve(usize, usize, usize),
    /// Fig B-1's (level, seed index).
    Sweep(usize, usize),
    /// Fig B-2's (level, seed index).
    Half(usize, usize),
    /// Fig B-3's (road class, seed index).
    Roads(usize, usize),
    /// Fig B-4's (scenario, seed index).
    Full(usize, usize),
}

impl Job {
    fn seed(&self) -> usize {
        match *self {
            Job::Curve(_, _, s) | Job::Sweep(_, s) | Job::Half(_, s) | Job::Roads(_, s) | Job::Full(_, s) => s,
        }
    }
}

/// A job's output and its wall time, s (`None` until it ran).
type Slot = Option<(crate::Result<Out>, f64)>;

/// What a job produced.
enum Out {
    Trace(Trace),
    Sweep(Vec<beyond::QuarterXi>),
    Half(Vec<beyond::HalfXi>),
    Roads(Vec<beyond::RoadConstants>),
    Full(beyond::FullOutcome),
}

/// Job `ji`'s output and its wall time, taken out of the results (each is read once).
fn take(results: &mut [Slot], ji: usize) -> crate::Result<(Out, f64)> {
    let (out, t) = results[ji].take().expect("every job ran");
    Ok((out?, t))
}

//! The runner: every curve of the selected figures over `S` seeds, in parallel (scoped
//! threads over a shared job counter), ξ_k (Eq 3.17 / 6.10) recorded on a fixed grid, then
//! the median and the 10–90 % band over seeds and each claim evaluated against the
//! measurements. The first seed of every identifier curve also records the car's physical
//! constants with their 95 % intervals on a decimated grid (`constants`).

mod constants;
mod ident;
mod job;

pub use constants::CONSTANT_POINTS;

pub(crate) use job::Trace;

use crate::figures::{select, Experiment, ModelKind};
use crate::report::{FigureResult, Report};
use crate::seeds::job_seed;
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
    let exps = select(&opts.only)?;
    let seeds = opts.seeds.unwrap_or(if opts.quick { 5 } else { 16 }).max(1);
    let threads =
        opts.threads.unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(2)).clamp(1, 64);
    let iters_of = |e: &Experiment| {
        let mut n = e.iterations;
        if opts.quick {
            n = n.min(QUICK_ITERATIONS);
        }
        if let Some(m) = opts.max_iterations {
            n = n.min(m.max(1));
        }
        n
    };
    // Jobs: (figure, curve, seed), longest first for a balanced finish.
    let grids: Vec<Vec<u64>> = exps.iter().map(|e| grid(iters_of(e))).collect();
    let mut jobs: Vec<(usize, usize, usize)> = vec![];
    for (fi, e) in exps.iter().enumerate() {
        if e.needs.is_some() {
            continue;
        }
        for ci in 0..e.curves.len() {
            for s in 0..seeds {
                jobs.push((fi, ci, s));
            }
        }
    }
    let cost = |j: &(usize, usize, usize)| {
        let e = exps[j.0];
        iters_of(e) * if e.model == ModelKind::Quarter { 1 } else { 4 }
    };
    jobs.sort_by_key(|j| core::cmp::Reverse(cost(j)));
    let results: Mutex<Vec<Option<crate::Result<Trace>>>> = Mutex::new((0..jobs.len()).map(|_| None).collect());
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..threads.min(jobs.len().max(1)) {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(&(fi, ci, s)) = jobs.get(i) else { break };
                let e = exps[fi];
                let tr = simulate(e, &e.curves[ci], &grids[fi], job_seed(opts.base_seed, e, ci, s), s == 0);
                results.lock().unwrap_or_else(|p| p.into_inner())[i] = Some(tr);
                let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                progress(Progress { done: d, total: jobs.len(), figure: e.id });
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
                if j.0 == fi && j.1 == ci {
                    traces.push(results[ji].take().expect("every job ran")?);
                }
            }
            curves.push(summarize(curve, ci, &traces, &grids[fi]));
        }
        let verdicts = e.claims.iter().map(|c| evaluate(c, &curves, n, opts.quick)).collect();
        figures.push(FigureResult { k: grids[fi].clone(), curves, verdicts, ..figure(e, n) });
    }
    let tables = match table_out {
        Some(t) => t?,
        None => vec![],
    };
    Ok(Report {
        quick: opts.quick,
        base_seed: opts.base_seed,
        threads,
        seconds: start.elapsed().as_secs_f64(),
        figures,
        tables,
    })
}

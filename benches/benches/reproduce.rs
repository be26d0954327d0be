//! End-to-end time of the thesis reproduction in quick mode: what `vehid reproduce --quick`
//! (and `make demo`) spends in Rust.
//!
//! One iteration is `vehid_thesis::run` with the options the CLI passes for `--quick`
//! (`RunOptions { quick: true, ..Default::default() }`: every figure, 5 seeds, at most
//! 10,000 iterations per curve, base seed 1986, the tables of Eq 4.28, 4.32, 4.34 and Table I,
//! threads = the available parallelism) followed by `Report::to_json` (serde_json; the Python
//! binding converts the same report to Python objects instead, which is not timed here). The
//! Python side (rendering index.md / index.html, plots) is not timed, and nothing is written:
//! no report files (criterion keeps only its own estimates under `target/criterion/reproduce/`).
//!
//! Run: `cargo bench -p vehid-benches --bench reproduce` (about 10 s after the build: 10
//! samples of one run each, flat sampling).
//!
//! `cargo test --benches` runs the bench once, unoptimised, as a smoke test; a full quick run
//! takes about a minute in the debug build, so in that mode (no `--bench` argument, which is
//! how criterion itself tells the two apart) every figure and table still runs, but with one
//! seed and at most 300 iterations per curve.

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use std::hint::black_box;
use std::time::Duration;
use vehid_thesis::{run, Progress, RunOptions};

/// `cargo bench` passes `--bench`; `cargo test --benches` does not.
fn benchmarking() -> bool {
    std::env::args().any(|a| a == "--bench")
}

fn reproduce_quick(c: &mut Criterion) {
    // Exactly what `vehid reproduce --quick` asks of the runner.
    let mut opts = RunOptions { quick: true, ..RunOptions::default() };
    if !benchmarking() {
        opts.seeds = Some(1);
        opts.max_iterations = Some(300);
    }
    let quiet = |_: Progress<'_>| {};
    let mut g = c.benchmark_group("reproduce");
    // One run takes about half a second: the same number of iterations in every sample
    // (linear sampling would need 55 runs for 10 samples).
    g.sampling_mode(SamplingMode::Flat);
    g.bench_function("quick", |b| {
        b.iter(|| {
            let report = run(black_box(&opts), &quiet).expect("the quick reproduction runs");
            black_box(report.to_json())
        })
    });
    g.finish();
}

fn config() -> Criterion {
    Criterion::default().warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(8)).sample_size(10)
}

criterion_group! { name = benches; config = config(); targets = reproduce_quick }
criterion_main!(benches);

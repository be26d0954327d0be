//! Fig B-1, B-2, B-3 and B-4 (beyond the thesis) alone: runs them through the reproduction
//! runner, prints each claim with its verdict and writes the report (`beyond.json`, the same
//! fields the Python report reads) into a directory. The figures and their tables are drawn in
//! one place, the Python report: `vehid reproduce --only B-1,B-2,B-3,B-4` with the same seeds
//! gives the same numbers.
//!
//! `cargo run --release -p vehid-thesis --example beyond -- [--quick] [--seeds N] [--seed S]
//! [--only B-1,B-3] [OUT]` (OUT defaults to `report-beyond/`).

use std::io::Write;
use vehid_thesis::{run, Progress, RunOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut opts = RunOptions {
        only: ["B-1", "B-2", "B-3", "B-4"].iter().map(|s| s.to_string()).collect(),
        tables: false,
        ..RunOptions::default()
    };
    let mut out = std::path::PathBuf::from("report-beyond");
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--quick" => opts.quick = true,
            "--seeds" => opts.seeds = Some(args.next().ok_or("--seeds N")?.parse()?),
            "--seed" => opts.base_seed = args.next().ok_or("--seed S")?.parse()?,
            "--threads" => opts.threads = Some(args.next().ok_or("--threads N")?.parse()?),
            "--only" => opts.only = args.next().ok_or("--only IDS")?.split(',').map(|s| s.trim().to_string()).collect(),
            other => out = other.into(),
        }
    }
    let t0 = std::time::Instant::now();
    let report = run(&opts, &|p: Progress<'_>| {
        eprint!("\rbeyond: {}/{} runs (Fig {})   ", p.done, p.total, p.figure);
        let _ = std::io::stderr().flush();
    })?;
    eprintln!();
    // The beyond figures' tables are their claims as rows, the numbers in the table's method.
    for t in &report.tables {
        println!("{}\n  {}", t.title, t.method);
        for r in &t.rows {
            println!("  [{}] {}: {}", if r.agrees { "agrees" } else { "differs" }, r.label, r.vehid);
        }
    }
    std::fs::create_dir_all(&out)?;
    std::fs::write(out.join("beyond.json"), report.to_json())?;
    println!(
        "{} (base seed {}, {} threads, {:.1} s)",
        out.join("beyond.json").display(),
        report.base_seed,
        report.threads,
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

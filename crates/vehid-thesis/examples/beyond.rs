//! Fig B-1, B-2 and B-3 (beyond the thesis) alone: runs them through the reproduction runner
//! and writes their tables and claims (`beyond.md`) and the report (`beyond.json`) into a
//! directory. The figures are drawn by the Python report (`vehid reproduce --only B-1,B-3`).
//!
//! `cargo run --release -p vehid-thesis --example beyond -- [--quick] [--seeds N] [--seed S]
//! [--only B-1,B-3] [OUT]` (OUT defaults to `report-beyond/`).

use std::io::Write;
use vehid_thesis::{beyond, run, Progress, RunOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut opts =
        RunOptions { only: vec!["B-1".into(), "B-2".into(), "B-3".into()], tables: false, ..RunOptions::default() };
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
    std::fs::create_dir_all(&out)?;
    let cmd = format!(
        "cargo run --release -p vehid-thesis --example beyond --{}{} (base seed {}, {} threads, {:.1} s)",
        if opts.quick { " --quick" } else { "" },
        opts.seeds.map(|s| format!(" --seeds {s}")).unwrap_or_default(),
        report.base_seed,
        report.threads,
        t0.elapsed().as_secs_f64()
    );
    std::fs::write(out.join("beyond.md"), beyond::markdown(&report, &cmd))?;
    std::fs::write(out.join("beyond.json"), report.to_json())?;
    println!("{}", out.join("beyond.md").display());
    Ok(())
}

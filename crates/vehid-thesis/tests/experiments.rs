//! The reproduction runner (`vehid reproduce`): one figure per chapter end to end, with
//! small iteration counts, and the check that the report's numbers are computed from the
//! seed, not copied (change the base seed, the numbers change).

use vehid_thesis::{run, select, Report, RunOptions, EXPERIMENTS};

fn quick(seed: u64, only: &[&str], max_iterations: usize) -> Report {
    let opts = RunOptions {
        quick: true,
        seeds: Some(3),
        max_iterations: Some(max_iterations),
        base_seed: seed,
        threads: Some(2),
        only: only.iter().map(|s| s.to_string()).collect(),
        tables: false,
    };
    run(&opts, &|_| {}).unwrap()
}

#[test]
fn the_table_covers_every_figure_of_chapters_3_to_6() {
    assert!(EXPERIMENTS.iter().all(|e| e.needs.is_none()), "every figure runs");
    let ids: Vec<&str> = EXPERIMENTS.iter().map(|e| e.id).collect();
    let mut want = vec![];
    for (ch, lo, hi) in [(3, 2, 7), (4, 1, 9), (5, 1, 4), (6, 2, 9)] {
        for i in lo..=hi {
            want.push(format!("{ch}-{i}"));
        }
    }
    assert_eq!(ids, want);
    for e in EXPERIMENTS {
        // Every caption's four σ are non-negative and every curve-carrying figure has claims
        // (4-7 is analytic).
        for c in e.curves {
            assert!(c.ic >= 0.0 && c.road >= 0.0 && c.state >= 0.0 && c.deriv >= 0.0, "{}", e.id);
        }
        if e.needs.is_none() && !e.curves.is_empty() {
            assert!(!e.claims.is_empty(), "Fig {} has no claim", e.id);
        }
    }
    assert!(select(&["9-9".to_string()]).is_err());
}

#[test]
fn one_figure_per_chapter_runs_and_the_numbers_follow_the_seed() {
    let figs = ["3-5", "4-2", "5-1", "6-3"];
    let a = quick(1, &figs, 600);
    let b = quick(2, &figs, 600);
    let a2 = quick(1, &figs, 600);
    assert_eq!(a.figures.len(), 4);
    for ((fa, fb), fa2) in a.figures.iter().zip(&b.figures).zip(&a2.figures) {
        assert!(fa.skipped.is_none(), "{}", fa.experiment.id);
        assert_eq!(fa.iterations, 600.min(fa.experiment.iterations));
        assert!(!fa.verdicts.is_empty());
        for (ca, (cb, ca2)) in fa.curves.iter().zip(fb.curves.iter().zip(&fa2.curves)) {
            assert_eq!(ca.median.len(), fa.k.len());
            assert!(ca.p10.iter().zip(&ca.median).zip(&ca.p90).all(|((l, m), h)| l.is_nan() || (l <= m && m <= h)));
            // Reproducible from the base seed …
            assert_eq!(ca.final_xi, ca2.final_xi, "Fig {}", fa.experiment.id);
            // … and computed from it: another seed, other numbers.
            assert_ne!(ca.final_xi, cb.final_xi, "Fig {}", fa.experiment.id);
        }
        // The verdict text carries the measured numbers, which move with the seed.
        let ma: Vec<&str> = fa.verdicts.iter().map(|v| v.measured.as_str()).collect();
        let mb: Vec<&str> = fb.verdicts.iter().map(|v| v.measured.as_str()).collect();
        eprintln!("Fig {}: {:?} | {:?}", fa.experiment.id, ma, mb);
    }
    let json = a.to_json();
    assert!(json.starts_with('{') && json.contains("\"3-5\"") && json.contains("\"verdicts\""));
}

#[test]
fn one_road_figures_run_with_the_two_axle_identifier() {
    let r = quick(1, &["6-8", "6-9"], 300);
    for f in &r.figures {
        assert!(f.skipped.is_none(), "Fig {}", f.experiment.id);
        assert!(f.curves.iter().all(|c| c.final_xi.iter().all(|v| v.is_finite())), "Fig {}", f.experiment.id);
    }
}

/// The whole quick reproduction with the verdicts printed (`cargo test --release -p
/// vehid-thesis --test experiments -- --ignored --nocapture`).
#[test]
#[ignore]
fn print_quick_reproduction() {
    let quick = std::env::var("VEHID_FULL").is_err();
    let opts = RunOptions { quick, ..RunOptions::default() };
    let r = run(&opts, &|_| {}).unwrap();
    for f in &r.figures {
        for v in &f.verdicts {
            let mark = if v.agrees { "agrees" } else { "DIFFERS" };
            eprintln!("Fig {} [{mark}] {} -> {} {}", f.experiment.id, v.claim, v.measured, v.note);
        }
        if let Some(s) = &f.skipped {
            eprintln!("Fig {} skipped: {s}", f.experiment.id);
        }
    }
    for t in &r.tables {
        eprintln!("{}", t.title);
        for row in &t.rows {
            eprintln!("  {}: thesis {} vehid {} {} {}", row.label, row.thesis, row.vehid, row.agrees, row.note);
        }
    }
    eprintln!("wall time {:.1} s on {} threads", r.seconds, r.threads);
}

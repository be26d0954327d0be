//! The figures beyond the thesis as markdown tables, for readers of the Rust runner's output
//! (the `beyond` example). They are drawn in one place, the Python report (`vehid reproduce
//! --only B-1,B-3` draws Fig B-1 and B-3 from the same runs: the same seeds give the same
//! numbers).

use super::{tables::NOT_THESIS, HALF_ID, ROADS_ID, SWEEP_ID};
use crate::report::{fmt_num, HalfResult, Report, RoadsResult, SweepResult, Verdict};
use crate::stats::median;
use std::fmt::Write;

fn md_cell(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

fn verdicts_md(md: &mut String, vs: &[Verdict]) {
    md.push_str("| claim (vehid's, not the thesis') | measured | verdict | note |\n|---|---|---|---|\n");
    for v in vs {
        let _ = writeln!(
            md,
            "| {} | {} | *{}* | {} |",
            md_cell(&v.claim),
            md_cell(&v.measured),
            if v.agrees { "agrees" } else { "differs" },
            md_cell(&v.note)
        );
    }
    md.push('\n');
}

fn worst(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::NEG_INFINITY, |a, b| if b.is_nan() { f64::INFINITY } else { a.max(b) })
}

fn sweep_md(md: &mut String, r: &SweepResult) {
    let _ = writeln!(md, "## Fig {SWEEP_ID}: {}\n\n**{}.**\n\n{}\n", r.title, r.origin, r.setup);
    let _ = write!(md, "Median ξ [25–75 %] (worst seed) after {} samples, {} seeds:\n\n| method |", r.samples, r.seeds);
    for l in &r.levels {
        let _ = write!(md, " σ_w = {l} % |");
    }
    md.push_str("\n|---|");
    md.push_str(&"---|".repeat(r.levels.len()));
    md.push('\n');
    for c in &r.curves {
        let _ = write!(md, "| {} |", md_cell(c.label));
        for i in 0..r.levels.len() {
            let _ = write!(
                md,
                " {} [{}, {}] ({}) |",
                fmt_num(c.median[i]),
                fmt_num(c.q25[i]),
                fmt_num(c.q75[i]),
                fmt_num(c.max[i])
            );
        }
        md.push('\n');
    }
    md.push('\n');
    for c in &r.curves {
        let refused: u64 = c.refused.iter().sum();
        let errors: usize = c.errors.iter().map(Vec::len).sum();
        let _ = write!(md, "- {}: {}", c.label, md_cell(c.setup));
        if refused > 0 || errors > 0 {
            let _ = write!(md, " — refused {refused} samples; no estimate on {errors} runs");
            if let Some((_, e)) = c.errors.iter().flatten().next() {
                let _ = write!(md, " ({})", md_cell(e));
            }
        }
        md.push('\n');
    }
    md.push('\n');
    verdicts_md(md, &r.verdicts);
}

fn half_md(md: &mut String, r: &HalfResult) {
    let _ = writeln!(md, "## Fig {HALF_ID}: {}\n\n**{}.**\n\n{}\n", r.title, r.origin, r.setup);
    let _ = writeln!(md, "Median (worst) over {} seeds after {} samples:\n", r.seeds, r.samples);
    md.push_str(
        "| method | σ_w | ξ wheel rows 1, 3 | ξ body rows 5, 7 | worst entry (relative error) | no estimate |\n",
    );
    md.push_str("|---|---|---|---|---|---|\n");
    for row in &r.rows {
        for c in &row.cells {
            let none = if c.errors.is_empty() {
                "—".to_string()
            } else {
                format!("{}/{}: {}", c.errors.len(), r.seeds, c.errors[0].1)
            };
            let _ = writeln!(
                md,
                "| {} | {} % | {} ({}) | {} ({}) | {} ({}) | {} |",
                md_cell(row.label),
                c.level,
                fmt_num(median(&c.wheel)),
                fmt_num(worst(&c.wheel)),
                fmt_num(median(&c.body)),
                fmt_num(worst(&c.body)),
                fmt_num(median(&c.worst_entry)),
                fmt_num(worst(&c.worst_entry)),
                md_cell(&none)
            );
        }
    }
    md.push('\n');
    for row in &r.rows {
        let _ = writeln!(md, "- {}: {}", row.label, md_cell(row.setup));
    }
    for (m, why) in &r.not_run {
        let _ = writeln!(md, "- not run, {m}: {}", md_cell(why));
    }
    md.push('\n');
    verdicts_md(md, &r.verdicts);
}

fn roads_md(md: &mut String, r: &RoadsResult) {
    let _ = writeln!(md, "## Fig {ROADS_ID}: {}\n\n**{}.**\n\n{}\n", r.title, r.origin, r.setup);
    let _ = write!(
        md,
        "Median (worst seed) relative error, %, and the seeds whose 95 % interval holds the truth, after {} samples, \
         {} seeds per class:\n\n| identifier | class |",
        r.samples, r.seeds
    );
    for (k, t) in r.constants.iter().zip(&r.truth) {
        let _ = write!(md, " {k} (true {}) |", fmt_num(*t));
    }
    md.push_str(" no estimate |\n|---|---|");
    md.push_str(&"---|".repeat(r.constants.len() + 1));
    md.push('\n');
    for row in &r.rows {
        for c in &row.cells {
            let _ = write!(md, "| {} | {} |", md_cell(row.label), c.class);
            for i in 0..r.constants.len() {
                let _ = write!(
                    md,
                    " {} ({}); {}/{} |",
                    fmt_num(100.0 * c.median[i]),
                    fmt_num(100.0 * c.max[i]),
                    c.covered[i],
                    r.seeds
                );
            }
            let none = if c.errors.is_empty() {
                "—".to_string()
            } else {
                format!("{}/{}: {}", c.errors.len(), r.seeds, c.errors[0].1)
            };
            let _ = writeln!(md, " {} |", md_cell(&none));
        }
    }
    md.push('\n');
    for row in &r.rows {
        let _ = writeln!(md, "- {}: {}", row.label, md_cell(row.setup));
    }
    md.push('\n');
    verdicts_md(md, &r.verdicts);
}

/// Fig B-1, B-2 and B-3 of `report` as markdown tables and their claims; `command` is how
/// the report was made.
pub fn markdown(report: &Report, command: &str) -> String {
    let mut md = String::from("# vehid: identifiers for noisy states and real roads (beyond the thesis)\n\n");
    let _ = writeln!(
        md,
        "Generated by `{command}`. Not figures of Kessler (1986): vehid's comparison of its identifiers for noisy \
         states and on real roads. Every number is computed by the run; the claims' `thesis` column in the \
         reproduction report reads \"{NOT_THESIS}\". The figures are drawn by the Python report: \
         `vehid reproduce --only B-1,B-2,B-3` with the same seeds.\n"
    );
    if let Some(r) = &report.sweep {
        sweep_md(&mut md, r);
    }
    if let Some(r) = &report.half_one_road {
        half_md(&mut md, r);
    }
    if let Some(r) = &report.real_roads {
        roads_md(&mut md, r);
    }
    if let Some(r) = &report.full_car {
        super::full::full_md(&mut md, r, verdicts_md);
    }
    md
}

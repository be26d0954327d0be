//! Fig B-1 to B-4 as report tables: the claims as rows (with the verdict), the numbers in the
//! table's text. The Python report (`vehid reproduce`) draws the figures and their tables from
//! the report's fields ([`crate::Report::sweep`] and the others) and shows these tables for the
//! claims and their verdicts; the `beyond` example prints them.

use super::{HALF_ID, ROADS_ID, SWEEP_ID};
use crate::report::{fmt_num, FullResult, HalfResult, RoadsResult, SweepResult, Table, TableRow, Verdict};
use crate::stats::median;

/// The `thesis` column of a row that is vehid's claim, not the thesis'.
pub const NOT_THESIS: &str = "— (vehid's claim, beyond the thesis)";

fn row(v: &Verdict) -> TableRow {
    TableRow {
        label: v.claim.clone(),
        thesis: NOT_THESIS.to_string(),
        vehid: v.measured.clone(),
        agrees: v.agrees,
        note: v.note.clone(),
    }
}

/// `median [lo, hi]` with the numbers of the report.
fn band(m: f64, lo: f64, hi: f64) -> String {
    format!("{} [{}, {}]", fmt_num(m), fmt_num(lo), fmt_num(hi))
}

/// Fig B-1's numbers, one sentence per method.
pub fn sweep_numbers(r: &SweepResult) -> String {
    let levels = r.levels.iter().map(|l| format!("{l}")).collect::<Vec<_>>().join(", ");
    let per = r
        .curves
        .iter()
        .map(|c| {
            let cells = (0..r.levels.len()).map(|i| band(c.median[i], c.q25[i], c.q75[i])).collect::<Vec<_>>();
            format!("{}: {}", c.label, cells.join("; "))
        })
        .collect::<Vec<_>>()
        .join(". ");
    format!("Median ξ [25–75 %] after {} samples over {} seeds at σ_w = {levels} % of σ_u: {per}", r.samples, r.seeds)
}

/// Fig B-2's numbers, one sentence per method and level: median (worst) of each pair's ξ and
/// of the worst entry.
pub fn half_numbers(r: &HalfResult) -> String {
    let worst =
        |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, |a, b| if b.is_nan() { f64::INFINITY } else { a.max(b) });
    let mut parts = vec![];
    for row in &r.rows {
        for c in &row.cells {
            let mut s = format!(
                "{} at σ_w = {} %: wheel rows {} ({}), body rows {} ({}), worst entry {} ({})",
                row.label,
                c.level,
                fmt_num(median(&c.wheel)),
                fmt_num(worst(&c.wheel)),
                fmt_num(median(&c.body)),
                fmt_num(worst(&c.body)),
                fmt_num(median(&c.worst_entry)),
                fmt_num(worst(&c.worst_entry)),
            );
            if !c.errors.is_empty() {
                s += &format!(", no estimate on {} of {} seeds ({})", c.errors.len(), r.seeds, c.errors[0].1);
            }
            parts.push(s);
        }
    }
    format!(
        "Median (worst) over {} seeds after {} samples: {}. Not run: {}",
        r.seeds,
        r.samples,
        parts.join("; "),
        r.not_run.iter().map(|(m, why)| format!("{m}: {why}")).collect::<Vec<_>>().join("; ")
    )
}

/// Fig B-3's numbers, one sentence per identifier: per class the median (worst) relative error
/// of each constant, in %, and the seeds whose 95 % interval holds it.
pub fn roads_numbers(r: &RoadsResult) -> String {
    let per = r
        .rows
        .iter()
        .map(|row| {
            let cells = row
                .cells
                .iter()
                .map(|c| {
                    let k = (0..r.constants.len())
                        .map(|i| {
                            format!(
                                "{} {} ({}; {}/{}; median estimate {} {})",
                                r.constants[i],
                                fmt_num(100.0 * c.median[i]),
                                fmt_num(100.0 * c.max[i]),
                                c.covered[i],
                                r.seeds,
                                fmt_num(median(&c.value[i])),
                                r.units[i]
                            )
                        })
                        .collect::<Vec<_>>()
                        .join(", ");
                    let none = if c.errors.is_empty() {
                        String::new()
                    } else {
                        format!(", no estimate on {} seeds ({})", c.errors.len(), c.errors[0].1)
                    };
                    format!("class {}: {k}{none}", c.class)
                })
                .collect::<Vec<_>>();
            format!("{}: {}", row.label, cells.join("; "))
        })
        .collect::<Vec<_>>()
        .join(". ");
    format!(
        "Median (worst seed) relative error in %, the seeds whose 95 % interval holds the truth and the median \
         estimate, after {} samples over {} seeds per class (true values: {}): {per}",
        r.samples,
        r.seeds,
        r.constants
            .iter()
            .zip(&r.truth)
            .zip(&r.units)
            .map(|((k, t), u)| format!("{k} {} {u}", fmt_num(*t)))
            .collect::<Vec<_>>()
            .join(", ")
    )
}

/// The tables of the figures that ran.
pub fn tables(
    sweep: Option<&SweepResult>,
    half: Option<&HalfResult>,
    roads: Option<&RoadsResult>,
    full: Option<&FullResult>,
) -> Vec<Table> {
    let mut out = vec![];
    if let Some(r) = sweep {
        out.push(Table {
            title: format!("Fig {SWEEP_ID}, beyond the thesis (not from Kessler 1986): {}", r.title),
            method: format!("{}. {} {}", r.origin, r.setup, sweep_numbers(r)),
            rows: r.verdicts.iter().map(row).collect(),
        });
    }
    if let Some(r) = half {
        out.push(Table {
            title: format!("Fig {HALF_ID}, beyond the thesis (not from Kessler 1986): {}", r.title),
            method: format!("{}. {} {}", r.origin, r.setup, half_numbers(r)),
            rows: r.verdicts.iter().map(row).collect(),
        });
    }
    if let Some(r) = roads {
        out.push(Table {
            title: format!("Fig {ROADS_ID}, beyond the thesis (not from Kessler 1986): {}", r.title),
            method: format!("{}. {} {}", r.origin, r.setup, roads_numbers(r)),
            rows: r.verdicts.iter().map(row).collect(),
        });
    }
    if let Some(r) = full {
        out.push(Table {
            title: format!("Fig {}, beyond the thesis (not from Kessler 1986): {}", super::FULL_ID, r.title),
            method: format!("{}. {} {}", r.origin, r.setup, super::full_numbers(r)),
            rows: r.verdicts.iter().map(row).collect(),
        });
    }
    out
}

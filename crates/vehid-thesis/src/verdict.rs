//! Claims evaluated against the measurements: one [`Verdict`] per [`ThesisClaim`], and per
//! claim of the figures beyond the thesis ([`SweepClaim`], [`HalfClaim`]).

use crate::beyond::{
    HalfCheck, HalfClaim, HalfMethod, Part, QuarterMethod, RoadsCheck, RoadsClaim, RoadsIdent, SweepCheck, SweepClaim,
};
use crate::figures::{Claim, ThesisClaim};
use crate::report::{fmt_num, CurveResult, HalfCell, HalfResult, RoadsCell, RoadsResult, SweepResult, Verdict};
use crate::stats::median;
use vehid_core::sim::RoadClass;

fn iters_text(v: f64, n: usize) -> String {
    if v.is_infinite() {
        format!("not within the {n} iterations run")
    } else {
        format!("{} iterations", fmt_num(v))
    }
}

pub(crate) fn evaluate(claim: &ThesisClaim, curves: &[CurveResult], n: usize, quick: bool) -> Verdict {
    let end = |i: usize| median(&curves[i].final_xi);
    let (measured, agrees, mut note): (String, bool, String) = match claim.check {
        Claim::SettlesAfter { curve, level, iters } => {
            let m = median(&curves[curve].settle);
            let truncated = m.is_infinite() && (n as f64) < iters;
            let note = if truncated {
                format!(
                    "lower bound only: the run ({n} iterations) is shorter than the claim{}",
                    if quick { " (quick mode)" } else { "" }
                )
            } else if m < iters {
                format!("vehid settles below {level} sooner than the thesis reports; the thesis' curve is one realization (its plateaus are seed-dependent) — see the 10–90 % band")
            } else {
                String::new()
            };
            (format!("median iterations until ξ stays < {level}: {}", iters_text(m, n)), m >= iters, note)
        }
        Claim::SettlesWithin { curve, level, iters } => {
            let m = median(&curves[curve].settle);
            let ok = m <= iters;
            let note = if ok { String::new() } else { format!("vehid settles below {level} later than {iters}") };
            (format!("median iterations until ξ stays < {level}: {}", iters_text(m, n)), ok, note)
        }
        Claim::ReachesWithin { curve, level, iters } => {
            let m = median(&curves[curve].reach);
            let ok = m <= iters;
            let note = if ok {
                String::new()
            } else {
                format!("vehid's median first crossing of {level} comes later than the thesis' {iters}")
            };
            (format!("median first iteration with ξ < {level}: {}", iters_text(m, n)), ok, note)
        }
        Claim::EndsAbove { curve, level } => {
            let m = end(curve);
            let ok = m > level;
            let note = if ok { String::new() } else { format!("vehid reaches ξ ≤ {level} within the run") };
            (format!("median ξ at {n}: {}", fmt_num(m)), ok, note)
        }
        Claim::Increasing { curves: order } => {
            let vals: Vec<f64> = order.iter().map(|&i| end(i)).collect();
            let ok = vals.windows(2).all(|w| w[0] <= w[1]);
            let txt = vals.iter().map(|v| fmt_num(*v)).collect::<Vec<_>>().join(" ≤ ");
            let note = if ok {
                String::new()
            } else {
                "the median ordering at the end of the run is not monotone".to_string()
            };
            (format!("median ξ at {n}, in the claimed order: {txt}"), ok, note)
        }
        Claim::MinimumNear { curve, lo, hi } => {
            let m = median(&curves[curve].argmin);
            let v = median(&curves[curve].min_xi);
            let ok = m >= lo && m <= hi;
            let note = if ok { String::new() } else { format!("the minimum is outside [{lo}, {hi}]") };
            (format!("median minimum ξ = {} at iteration {}", fmt_num(v), fmt_num(m)), ok, note)
        }
        Claim::Ratio { a, b, lo, hi } => {
            let r: Vec<f64> = curves[a].final_xi.iter().zip(&curves[b].final_xi).map(|(x, y)| x / y).collect();
            let m = median(&r);
            let ok = m >= lo && m <= hi;
            let note =
                if ok { String::new() } else { format!("the ratio is outside [{}, {}]", fmt_num(lo), fmt_num(hi)) };
            (format!("median ξ ratio (curve {} / curve {}) at {n}: {}", a + 1, b + 1, fmt_num(m)), ok, note)
        }
        Claim::Difference { a, b, lo, hi } => {
            let d: Vec<f64> = curves[a].final_xi.iter().zip(&curves[b].final_xi).map(|(x, y)| x - y).collect();
            let m = median(&d);
            let ok = m >= lo && m <= hi;
            let note = if ok {
                String::new()
            } else {
                format!(
                    "the difference is outside [{}, {}]{}",
                    fmt_num(lo),
                    fmt_num(hi),
                    if n < 40_000 { " (run shorter than the thesis' 40,000)" } else { "" }
                )
            };
            (format!("median ξ difference (curve {} − curve {}) at {n}: {}", a + 1, b + 1, fmt_num(m)), ok, note)
        }
        Claim::BestBetween { lo, hi } => {
            let (best, bi) =
                (0..curves.len())
                    .map(|i| (end(i), i))
                    .fold((f64::INFINITY, 0), |acc, x| if x.0 < acc.0 { x } else { acc });
            let ok = best > lo && best < hi;
            let note =
                if ok { String::new() } else { format!("best curve outside ({}, {})", fmt_num(lo), fmt_num(hi)) };
            (format!("best median ξ at {n}: {} ({})", fmt_num(best), curves[bi].label), ok, note)
        }
        Claim::LowestMinimum { a } => {
            let mins: Vec<f64> = curves.iter().map(|c| median(&c.min_xi)).collect();
            let ok = mins.iter().enumerate().all(|(i, &v)| i == a || mins[a] < v);
            let txt = mins.iter().map(|v| fmt_num(*v)).collect::<Vec<_>>().join(", ");
            let note = if ok { String::new() } else { "another curve reaches a lower minimum".to_string() };
            (format!("median minimum ξ per curve: {txt}"), ok, note)
        }
    };
    if !agrees && !claim.why.is_empty() {
        note = claim.why.to_string();
    }
    Verdict { claim: claim.text.to_string(), measured, agrees, note }
}

/// The index of σ_w `level` among `levels` (`None`: not run).
fn level_index(levels: &[f64], level: f64) -> Option<usize> {
    levels.iter().position(|&l| l == level)
}

fn in_range(v: f64, lo: f64, hi: f64) -> bool {
    v >= lo && v <= hi
}

fn range_text(lo: f64, hi: f64) -> String {
    format!("[{}, {}]", fmt_num(lo), fmt_num(hi))
}

/// A claim about a level the run did not include: it cannot agree.
fn missing_level(text: &str, level: f64) -> Verdict {
    Verdict {
        claim: text.to_string(),
        measured: format!("σ_w = {level} % was not run"),
        agrees: false,
        note: "the claim's level is not among the run's levels".to_string(),
    }
}

/// Fig B-1's claim evaluated against its runs (medians over seeds after the run).
pub(crate) fn evaluate_sweep(claim: &SweepClaim, r: &SweepResult) -> Verdict {
    let n = r.samples;
    let curve = |m: QuarterMethod| {
        let i = QuarterMethod::ALL.iter().position(|&x| x == m).unwrap_or(0);
        &r.curves[i]
    };
    let (measured, agrees) = match claim.check {
        SweepCheck::Median { methods, level, lo, hi } => {
            let Some(li) = level_index(&r.levels, level) else { return missing_level(claim.text, level) };
            let vals: Vec<(f64, &str)> = methods.iter().map(|&m| (curve(m).median[li], m.label())).collect();
            let ok = vals.iter().all(|&(v, _)| in_range(v, lo, hi));
            let txt = vals.iter().map(|(v, l)| format!("{l} {}", fmt_num(*v))).collect::<Vec<_>>().join("; ");
            (format!("median ξ at {n} samples, σ_w = {level} %: {txt} (claimed range {})", range_text(lo, hi)), ok)
        }
        SweepCheck::Ratio { a, b, level, lo, hi } => {
            let Some(li) = level_index(&r.levels, level) else { return missing_level(claim.text, level) };
            let ratios: Vec<f64> = curve(a).xi[li].iter().zip(&curve(b).xi[li]).map(|(x, y)| x / y).collect();
            let m = median(&ratios);
            (
                format!(
                    "median over seeds of ξ({}) / ξ({}) at {n} samples, σ_w = {level} %: {} (claimed range {})",
                    a.label(),
                    b.label(),
                    fmt_num(m),
                    range_text(lo, hi)
                ),
                in_range(m, lo, hi),
            )
        }
        SweepCheck::Increasing { method, from, to } => {
            let c = curve(method);
            let sel: Vec<(f64, f64)> = r
                .levels
                .iter()
                .zip(&c.median)
                .filter(|(l, _)| **l >= from && **l <= to)
                .map(|(l, v)| (*l, *v))
                .collect();
            let ok = sel.len() >= 2 && sel.windows(2).all(|w| w[0].1 < w[1].1);
            let txt = sel.iter().map(|(l, v)| format!("{l} %: {}", fmt_num(*v))).collect::<Vec<_>>().join(", ");
            (format!("median ξ of {} at {n} samples: {txt}", method.label()), ok)
        }
    };
    let note = if agrees { String::new() } else { "outside the claimed range".to_string() };
    Verdict { claim: claim.text.to_string(), measured, agrees, note }
}

/// Per seed, `part` of one method's cell (the larger pair for [`Part::WorstPair`]).
fn half_part(cell: &HalfCell, part: Part) -> Vec<f64> {
    match part {
        Part::Wheel => cell.wheel.clone(),
        Part::Body => cell.body.clone(),
        Part::WorstPair => cell.wheel.iter().zip(&cell.body).map(|(a, b)| a.max(*b)).collect(),
    }
}

fn part_text(part: Part) -> &'static str {
    match part {
        Part::Wheel => "ξ of the wheel rows",
        Part::Body => "ξ of the body rows",
        Part::WorstPair => "ξ of the larger pair",
    }
}

/// Fig B-2's claim evaluated against its runs.
pub(crate) fn evaluate_half(claim: &HalfClaim, r: &HalfResult) -> Verdict {
    let n = r.samples;
    let row = |m: HalfMethod| {
        let i = HalfMethod::ALL.iter().position(|&x| x == m).unwrap_or(0);
        &r.rows[i]
    };
    let (measured, agrees) = match claim.check {
        HalfCheck::Median { method, part, level, lo, hi } => {
            let Some(li) = level_index(&r.levels, level) else { return missing_level(claim.text, level) };
            let m = median(&half_part(&row(method).cells[li], part));
            (
                format!(
                    "median {} for {} at {n} samples, σ_w = {level} %: {} (claimed range {})",
                    part_text(part),
                    method.label(),
                    fmt_num(m),
                    range_text(lo, hi)
                ),
                in_range(m, lo, hi),
            )
        }
        HalfCheck::Ratio { a, b, part, level, lo, hi } => {
            let Some(li) = level_index(&r.levels, level) else { return missing_level(claim.text, level) };
            let (x, y) = (half_part(&row(a).cells[li], part), half_part(&row(b).cells[li], part));
            let m = median(&x.iter().zip(&y).map(|(x, y)| x / y).collect::<Vec<_>>());
            (
                format!(
                    "median over seeds of the ratio of {} ({} / {}) at σ_w = {level} %: {} (claimed range {})",
                    part_text(part),
                    a.label(),
                    b.label(),
                    fmt_num(m),
                    range_text(lo, hi)
                ),
                in_range(m, lo, hi),
            )
        }
        HalfCheck::Best { level, lo, hi } => {
            let Some(li) = level_index(&r.levels, level) else { return missing_level(claim.text, level) };
            let (best, label) = r
                .rows
                .iter()
                .map(|row| (median(&half_part(&row.cells[li], Part::WorstPair)), row.label))
                .fold((f64::INFINITY, ""), |acc, x| if x.0 < acc.0 { x } else { acc });
            (
                format!(
                    "best median of the larger pair's ξ at σ_w = {level} %: {} ({label}; claimed range {})",
                    fmt_num(best),
                    range_text(lo, hi)
                ),
                in_range(best, lo, hi),
            )
        }
    };
    let note = if agrees { String::new() } else { "outside the claimed range".to_string() };
    Verdict { claim: claim.text.to_string(), measured, agrees, note }
}

/// The cells of `ident` on `classes` (`None` when a class was not run).
fn roads_cells<'a>(r: &'a RoadsResult, ident: RoadsIdent, classes: &[RoadClass]) -> Option<Vec<&'a RoadsCell>> {
    let mi = RoadsIdent::ALL.iter().position(|&x| x == ident)?;
    let row = r.rows.get(mi)?;
    classes
        .iter()
        .map(|&c| {
            let letter = crate::beyond::class_letter(c);
            row.cells.iter().find(|cell| cell.class == letter)
        })
        .collect()
}

fn classes_text(classes: &[RoadClass]) -> String {
    classes.iter().map(|&c| crate::beyond::class_letter(c)).collect::<Vec<_>>().join(", ")
}

/// Fig B-3's claim evaluated against its runs.
pub(crate) fn evaluate_roads(claim: &RoadsClaim, r: &RoadsResult) -> Verdict {
    let (n, seeds) = (r.samples, r.seeds);
    let classes = match claim.check {
        RoadsCheck::AllWithin { classes, .. }
        | RoadsCheck::Median { classes, .. }
        | RoadsCheck::Coverage { classes, .. }
        | RoadsCheck::Ratio { classes, .. } => classes,
    };
    let missing = || Verdict {
        claim: claim.text.to_string(),
        measured: format!("the classes {} were not all run", classes_text(classes)),
        agrees: false,
        note: "the claim's classes are not among the run's".to_string(),
    };
    let (measured, agrees) = match claim.check {
        RoadsCheck::AllWithin { ident, classes, tol, lo, hi } => {
            let Some(cells) = roads_cells(r, ident, classes) else { return missing() };
            let counts: Vec<(usize, &str)> = cells
                .iter()
                .map(|c| ((0..seeds).filter(|&s| c.rel_err.iter().all(|e| e[s] <= tol)).count(), c.class))
                .collect();
            let frac = |k: usize| if seeds == 0 { f64::NAN } else { k as f64 / seeds as f64 };
            let ok = counts.iter().all(|&(k, _)| in_range(frac(k), lo, hi));
            let txt = counts.iter().map(|(k, c)| format!("{c} {k}/{seeds}")).collect::<Vec<_>>().join(", ");
            (
                format!(
                    "seeds with every constant within {} % ({}, {n} samples): {txt} (claimed fraction {})",
                    fmt_num(tol * 100.0),
                    ident.label(),
                    range_text(lo, hi)
                ),
                ok,
            )
        }
        RoadsCheck::Median { ident, constants, classes, lo, hi } => {
            let Some(cells) = roads_cells(r, ident, classes) else { return missing() };
            let idx: Vec<(usize, &str)> =
                constants.iter().filter_map(|&k| r.constants.iter().position(|&x| x == k).map(|i| (i, k))).collect();
            if idx.len() != constants.len() {
                return missing();
            }
            let vals: Vec<(f64, &str, &str)> =
                cells.iter().flat_map(|c| idx.iter().map(move |&(i, k)| (c.median[i], c.class, k))).collect();
            let ok = vals.iter().all(|&(v, _, _)| in_range(v, lo, hi));
            let (min, max) = extremes(&vals);
            (
                format!(
                    "median relative error of {} ({}, {n} samples) over classes {}: smallest {}, largest {} (claimed \
                     range {})",
                    constants.join(", "),
                    ident.label(),
                    classes_text(classes),
                    min,
                    max,
                    range_text(lo, hi)
                ),
                ok,
            )
        }
        RoadsCheck::Coverage { ident, classes, lo, hi } => {
            let Some(cells) = roads_cells(r, ident, classes) else { return missing() };
            let held: usize = cells.iter().flat_map(|c| c.covered.iter()).sum();
            let total = cells.len() * r.constants.len() * seeds;
            let frac = if total == 0 { f64::NAN } else { held as f64 / total as f64 };
            let per = cells
                .iter()
                .map(|c| format!("{} {}/{}", c.class, c.covered.iter().sum::<usize>(), r.constants.len() * seeds))
                .collect::<Vec<_>>()
                .join(", ");
            (
                format!(
                    "95 % intervals holding the true constant ({}, {n} samples): {held} of {total} = {} % ({per}; \
                     claimed fraction {})",
                    ident.label(),
                    fmt_num(100.0 * frac),
                    range_text(lo, hi)
                ),
                in_range(frac, lo, hi),
            )
        }
        RoadsCheck::Ratio { a, b, classes, lo, hi } => {
            let (Some(ca), Some(cb)) = (roads_cells(r, a, classes), roads_cells(r, b, classes)) else {
                return missing();
            };
            let mut vals = vec![];
            for (x, y) in ca.iter().zip(&cb) {
                for (i, k) in r.constants.iter().enumerate() {
                    let ratios: Vec<f64> = x.rel_err[i].iter().zip(&y.rel_err[i]).map(|(p, q)| p / q).collect();
                    vals.push((median(&ratios), x.class, *k));
                }
            }
            let ok = vals.iter().all(|&(v, _, _)| in_range(v, lo, hi));
            let (min, max) = extremes(&vals);
            (
                format!(
                    "median over seeds of the relative error's ratio {} / {} per class and constant ({n} samples): \
                     smallest {min}, largest {max} (claimed range {})",
                    a.label(),
                    b.label(),
                    range_text(lo, hi)
                ),
                ok,
            )
        }
    };
    let note = if agrees { String::new() } else { "outside the claimed range".to_string() };
    Verdict { claim: claim.text.to_string(), measured, agrees, note }
}

/// The smallest and the largest of `(value, class, constant)`, as text (NaN counts as largest).
fn extremes(vals: &[(f64, &str, &str)]) -> (String, String) {
    let key = |v: f64| if v.is_nan() { f64::INFINITY } else { v };
    let text = |x: Option<&(f64, &str, &str)>| {
        x.map_or("n/a".to_string(), |&(v, c, k)| format!("{} (class {c}, {k})", fmt_num(v)))
    };
    let min = vals.iter().min_by(|a, b| key(a.0).total_cmp(&key(b.0)));
    let max = vals.iter().max_by(|a, b| key(a.0).total_cmp(&key(b.0)));
    (text(min), text(max))
}

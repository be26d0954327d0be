//! Claims evaluated against the measurements: one [`Verdict`] per [`ThesisClaim`], and per
//! claim of the figures beyond the thesis ([`SweepClaim`], [`HalfClaim`]).

use crate::beyond::{HalfCheck, HalfClaim, HalfMethod, Part, QuarterMethod, SweepCheck, SweepClaim};
use crate::figures::{Claim, ThesisClaim};
use crate::report::{fmt_num, CurveResult, HalfCell, HalfResult, SweepResult, Verdict};
use crate::stats::median;

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

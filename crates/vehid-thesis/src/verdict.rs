//! Claims evaluated against the measurements: one [`Verdict`] per [`ThesisClaim`].

use crate::figures::{Claim, ThesisClaim};
use crate::report::{fmt_num, CurveResult, Verdict};
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

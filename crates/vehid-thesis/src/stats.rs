//! Statistics over seeds: quantiles, and per seed the settle, reach and minimum metrics.

use crate::figures::{curve_name, Curve};
use crate::report::CurveResult;
use crate::runner::Trace;

/// Quantile `q ∈ [0, 1]` of the finite-or-infinite (non-NaN) values, linear interpolation.
pub fn quantile(values: &[f64], q: f64) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let pos = q * (v.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    if lo == hi || v[hi] == v[lo] {
        return v[lo];
    }
    if v[hi].is_infinite() {
        return if pos - lo as f64 >= 0.5 { v[hi] } else { v[lo] };
    }
    v[lo] + (pos - lo as f64) * (v[hi] - v[lo])
}

/// Median (see [`quantile`]).
pub fn median(values: &[f64]) -> f64 {
    quantile(values, 0.5)
}

/// The acceptance level of ξ (Eq 3.17): the thesis calls an identification with ξ ≤ 0.08
/// acceptable. The per-seed metrics below are measured against it.
pub const ACCEPTABLE_XI: f64 = 0.08;

/// The iteration after which ξ stays below `level`: the grid point after the last one with
/// ξ ≥ `level` (or NaN), the first grid point if there is none, ∞ if ξ ends above.
/// `xi[i]` is ξ at iteration `k[i]`.
pub fn settle(xi: &[f64], k: &[u64], level: f64) -> f64 {
    match xi.iter().rposition(|&v| v.is_nan() || v >= level) {
        None => k.first().map(|&v| v as f64).unwrap_or(f64::INFINITY),
        Some(i) if i + 1 < k.len() => k[i + 1] as f64,
        Some(_) => f64::INFINITY,
    }
}

/// The first iteration with ξ < `level`, ∞ if never.
pub fn reach(xi: &[f64], k: &[u64], level: f64) -> f64 {
    xi.iter().position(|&v| v < level).map(|i| k[i] as f64).unwrap_or(f64::INFINITY)
}

/// The minimum ξ and the iteration where it is first reached (∞ and NaN if ξ is never a
/// number).
pub fn minimum(xi: &[f64], k: &[u64]) -> (f64, f64) {
    let (mut best, mut at) = (f64::INFINITY, f64::NAN);
    for (i, &v) in xi.iter().enumerate() {
        if v < best {
            best = v;
            at = k[i] as f64;
        }
    }
    (best, at)
}

/// Curve `index` of a figure over its seeds: median and 10–90 % band at every grid point `k`,
/// the per-seed metrics, and the constants the first seed recorded.
pub(crate) fn summarize(curve: &Curve, index: usize, traces: &[Trace], k: &[u64]) -> CurveResult {
    let n = k.len();
    let col = |i: usize| traces.iter().map(|t| t.xi[i]).collect::<Vec<f64>>();
    let median_v = (0..n).map(|i| quantile(&col(i), 0.5)).collect();
    let p10 = (0..n).map(|i| quantile(&col(i), 0.1)).collect();
    let p90 = (0..n).map(|i| quantile(&col(i), 0.9)).collect();
    let mut r = CurveResult {
        label: curve_name(curve, index),
        ident: curve.ident,
        ic: curve.ic,
        road: curve.road,
        state: curve.state,
        deriv: curve.deriv,
        pulse_width: curve.pulse_width,
        median: median_v,
        p10,
        p90,
        final_xi: vec![],
        settle: vec![],
        reach: vec![],
        min_xi: vec![],
        argmin: vec![],
        reinits: vec![],
        constants: traces.iter().find_map(|t| t.constants.clone()),
    };
    for t in traces {
        r.final_xi.push(t.xi.last().copied().unwrap_or(f64::NAN));
        r.settle.push(settle(&t.xi, k, ACCEPTABLE_XI));
        r.reach.push(reach(&t.xi, k, ACCEPTABLE_XI));
        let (best, at) = minimum(&t.xi, k);
        r.min_xi.push(best);
        r.argmin.push(at);
        r.reinits.push(t.reinits as f64);
    }
    r
}

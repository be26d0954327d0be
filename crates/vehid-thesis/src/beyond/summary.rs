//! Fig B-1 and B-2 from their jobs' outputs: quantiles over seeds, failures kept visible,
//! the claims evaluated.

use super::{
    HalfMethod, HalfXi, QuarterMethod, QuarterXi, DERIV_SIGMA, EKF_MIN_STATE_SIGMA, HALF_CLAIMS, HALF_DERIV_SIGMA,
    HALF_EKF_NOT_RUN, HALF_ID, ROAD_SIGMA, SWEEP_CLAIMS, SWEEP_ID,
};
use crate::report::{HalfCell, HalfResult, HalfRow, SweepCurve, SweepResult};
use crate::stats::quantile;
use crate::verdict::{evaluate_half, evaluate_sweep};

/// The line that marks both figures as vehid's own.
pub const ORIGIN: &str = "beyond the thesis: not a figure of Kessler (1986); vehid's comparison of the identifiers \
                          for noisy states (issue 15)";

/// Fig B-1 from `out[level][seed]` (one entry per method, [`QuarterMethod::ALL`] order).
pub(crate) fn sweep_result(
    levels: &[f64],
    out: &[Vec<Vec<QuarterXi>>],
    samples: usize,
    full_samples: usize,
    cpu_seconds: f64,
) -> SweepResult {
    let seeds = out.first().map_or(0, Vec::len);
    let curves: Vec<SweepCurve> = QuarterMethod::ALL
        .iter()
        .enumerate()
        .map(|(mi, m)| {
            let xi: Vec<Vec<f64>> = out.iter().map(|lv| lv.iter().map(|s| s[mi].xi).collect()).collect();
            let q = |p: f64| xi.iter().map(|v| quantile(v, p)).collect::<Vec<f64>>();
            SweepCurve {
                label: m.label(),
                setup: m.setup(),
                median: q(0.5),
                q25: q(0.25),
                q75: q(0.75),
                min: q(0.0),
                max: q(1.0),
                refused: out.iter().map(|lv| lv.iter().map(|s| s[mi].refused as u64).sum()).collect(),
                errors: out
                    .iter()
                    .map(|lv| {
                        lv.iter().enumerate().filter_map(|(si, s)| s[mi].error.clone().map(|e| (si, e))).collect()
                    })
                    .collect(),
                xi,
            }
        })
        .collect();
    let setup = format!(
        "The thesis' quarter car (QuarterCar::thesis()), white road σ_u = {ROAD_SIGMA} m held over each sample, \
         derivative noise σ_v = {DERIV_SIGMA} on every derivative, dt = 0.05 s, no initial disturbance, white state \
         noise σ_w (the level, % of σ_u, in m and m/s) on every state; {samples} samples per run (full mode: \
         {full_samples}), {seeds} seeds; within a seed every method sees the same samples and the levels share the \
         noise realizations. ξ (Eq 3.17) of rows 1 and 3 of A, for a structure those its parameters imply. At σ_w = 0 \
         the joint EKF is told σ_w = {EKF_MIN_STATE_SIGMA} (it needs Σ_w > 0). Median (line) and 25–75 % band \
         (shaded) over seeds; min and max in the data."
    );
    let mut r = SweepResult {
        id: SWEEP_ID,
        title: "ξ after the run against the state noise σ_w, every method for noisy states and the thesis' identifier \
                (quarter car)",
        origin: ORIGIN,
        samples,
        full_samples,
        seeds,
        levels: levels.to_vec(),
        setup,
        curves,
        verdicts: vec![],
        cpu_seconds,
    };
    r.verdicts = sweep_verdicts(&r);
    r
}

/// Fig B-2 from `out[level][seed]` (one entry per method, [`HalfMethod::ALL`] order).
pub(crate) fn half_result(levels: &[f64], out: &[Vec<Vec<HalfXi>>], samples: usize, cpu_seconds: f64) -> HalfResult {
    let seeds = out.first().map_or(0, Vec::len);
    let rows = HalfMethod::ALL
        .iter()
        .enumerate()
        .map(|(mi, m)| HalfRow {
            label: m.label(),
            setup: m.setup(),
            cells: levels
                .iter()
                .zip(out)
                .map(|(&level, lv)| HalfCell {
                    level,
                    wheel: lv.iter().map(|s| s[mi].wheel).collect(),
                    body: lv.iter().map(|s| s[mi].body).collect(),
                    worst_entry: lv.iter().map(|s| s[mi].worst_entry).collect(),
                    refused: lv.iter().map(|s| s[mi].refused as u64).sum(),
                    errors: lv.iter().enumerate().filter_map(|(si, s)| s[mi].error.clone().map(|e| (si, e))).collect(),
                })
                .collect(),
        })
        .collect();
    let setup = format!(
        "The thesis' half car (HalfCar::thesis()) on one white road (σ_u = {ROAD_SIGMA} m), sampled by distance every \
         0.3 m at 6 m/s (sim::RoadSimulator; the rear wheel meets the front wheel's road 10 samples later), \
         derivative noise σ_v = {HALF_DERIV_SIGMA} (Fig 6-8's), white state noise σ_w (% of σ_u, in the states' units) \
         on all 8 states, no initial disturbance; {samples} samples per run, {seeds} seeds, every method on the same \
         samples. ξ (Eq 3.17) of the wheel rows 1 and 3 and of the body rows 5 and 7 of A, and the largest relative \
         error over the 28 non-zero entries; σ_w = 0 is the noise-free reference."
    );
    let mut r = HalfResult {
        id: HALF_ID,
        title: "The half car on one road with noisy states: ξ per pair of rows for each method that applies",
        origin: ORIGIN,
        samples,
        seeds,
        levels: levels.to_vec(),
        setup,
        rows,
        not_run: vec![("joint EKF".to_string(), HALF_EKF_NOT_RUN.to_string())],
        verdicts: vec![],
        cpu_seconds,
    };
    r.verdicts = half_verdicts(&r);
    r
}

/// Fig B-1's claims ([`SWEEP_CLAIMS`]) evaluated against `r`'s curves (the runner stores them
/// in [`SweepResult::verdicts`]; public so that a changed result can be re-judged).
pub fn sweep_verdicts(r: &SweepResult) -> Vec<crate::report::Verdict> {
    SWEEP_CLAIMS.iter().map(|c| evaluate_sweep(c, r)).collect()
}

/// Fig B-2's claims ([`HALF_CLAIMS`]) evaluated against `r`'s rows.
pub fn half_verdicts(r: &HalfResult) -> Vec<crate::report::Verdict> {
    HALF_CLAIMS.iter().map(|c| evaluate_half(c, r)).collect()
}

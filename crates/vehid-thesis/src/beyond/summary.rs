//! Fig B-1, B-2 and B-3 from their jobs' outputs: quantiles over seeds, failures kept visible,
//! the claims evaluated.

use super::roads::{physical, CONSTANT_INDEX};
use super::{
    HalfMethod, HalfXi, QuarterMethod, QuarterXi, RoadConstants, RoadsIdent, DERIV_SIGMA, EKF_MIN_STATE_SIGMA,
    HALF_CLAIMS, HALF_DERIV_SIGMA, HALF_EKF_NOT_RUN, HALF_ID, ROADS_CLAIMS, ROADS_CONSTANTS, ROADS_DT, ROADS_ID,
    ROADS_SPEED, ROAD_CLASSES, ROAD_SIGMA, SWEEP_CLAIMS, SWEEP_ID,
};
use crate::report::{
    HalfCell, HalfResult, HalfRow, KnownConstant, RoadsCell, RoadsResult, RoadsRow, SweepCurve, SweepResult,
};
use crate::stats::quantile;
use crate::verdict::{evaluate_half, evaluate_roads, evaluate_sweep};
use vehid_core::model::QuarterCar;
use vehid_core::sim::{RoadClass, DEFAULT_CUTOFF};

/// The line that marks both figures as vehid's own.
pub const ORIGIN: &str = "beyond the thesis: not a figure of Kessler (1986); vehid's comparison of the identifiers \
                          for noisy states";

/// Fig B-3's origin line.
pub const ROADS_ORIGIN: &str = "beyond the thesis: not a figure of Kessler (1986); vehid's comparison of the thesis' \
                                identifier and its real-road identifier on ISO 8608 roads";

/// The class' letter, `"A"` … `"E"`.
pub(crate) fn class_letter(c: RoadClass) -> &'static str {
    match c {
        RoadClass::Flat => "flat",
        RoadClass::A => "A",
        RoadClass::B => "B",
        RoadClass::C => "C",
        RoadClass::D => "D",
        RoadClass::E => "E",
    }
}

/// One identifier's cell of Fig B-3 from its results on one class' seeds.
fn roads_cell(class: RoadClass, runs: &[&RoadConstants], truth: &[f64; 4]) -> RoadsCell {
    let per = |f: &dyn Fn(&RoadConstants, usize) -> f64| -> Vec<Vec<f64>> {
        (0..4).map(|j| runs.iter().map(|r| f(r, j)).collect()).collect()
    };
    let value = per(&|r, j| r.constants[j][0]);
    let rel_err = per(&|r, j| {
        let v = r.constants[j][0];
        if v.is_finite() {
            (v / truth[j] - 1.0).abs()
        } else {
            f64::INFINITY
        }
    });
    let q = |p: f64| rel_err.iter().map(|v| quantile(v, p)).collect::<Vec<f64>>();
    RoadsCell {
        class: class_letter(class),
        covered: (0..4)
            .map(|j| runs.iter().filter(|r| r.constants[j][1] <= truth[j] && truth[j] <= r.constants[j][2]).count())
            .collect(),
        value,
        lo: per(&|r, j| r.constants[j][1]),
        hi: per(&|r, j| r.constants[j][2]),
        median: q(0.5),
        min: q(0.0),
        max: q(1.0),
        rel_err,
        refused: runs.iter().map(|r| r.refused as u64).sum(),
        errors: runs.iter().enumerate().filter_map(|(si, r)| r.error.clone().map(|e| (si, e))).collect(),
    }
}

/// Fig B-3 from `out[class][seed]` (one entry per identifier, [`RoadsIdent::ALL`] order).
pub(crate) fn roads_result(
    out: &[Vec<Vec<RoadConstants>>],
    samples: usize,
    full_samples: usize,
    cpu_seconds: f64,
) -> RoadsResult {
    let seeds = out.first().map_or(0, Vec::len);
    let car = QuarterCar::<f64>::passenger();
    let c = car.constants();
    let truth = CONSTANT_INDEX.map(|i| c[i]);
    let rows = RoadsIdent::ALL
        .iter()
        .enumerate()
        .map(|(mi, m)| RoadsRow {
            label: m.label(),
            setup: m.setup(),
            cells: ROAD_CLASSES
                .iter()
                .zip(out)
                .map(|(&class, runs)| {
                    roads_cell(class, &runs.iter().filter_map(|s| s.get(mi)).collect::<Vec<_>>(), &truth)
                })
                .collect(),
        })
        .collect();
    let names = physical().map(|p| p.param_names().join(", ")).unwrap_or_default();
    let setup = format!(
        "The passenger quarter car (QuarterCar::passenger(): M = {} kg, m = {} kg, k1 = {} N/m, k2 = {} N/m, \
         b = {} N·s/m) driving at {ROADS_SPEED} m/s over ISO 8608 roads of classes A–E (sim::QuarterDrive: the \
         standard shaping filter, cutoff {DEFAULT_CUTOFF} cycles/m, the road linear between samples), from rest on \
         the road; its true states and derivatives (SensorSet::State, no noise) every dt = {ROADS_DT} s; \
         {samples} samples ({} s, {} m) per run (full mode: {full_samples}), {seeds} seeds per class, each class \
         its own seeds; both identifiers on the same samples, on the physical structure with the wheel mass known \
         (parameters {names}). The constants and their 95 % intervals: PhysicalStructure::constant on the \
         parameters and their covariance (estimate_stats; value ± t₀.₉₇₅(df) se). The simulated car is linear and \
         starts at rest on the road, so a class only scales every signal by √G_d(n0), to which both identifiers \
         are blind: the classes differ by their seeds, not by their roughness. Relative error |estimate / truth − \
         1|: median (marker) and range over seeds (bar).",
        c[0],
        c[1],
        c[2],
        c[3],
        c[4],
        crate::fmt_num(samples as f64 * ROADS_DT),
        crate::fmt_num(samples as f64 * ROADS_DT * ROADS_SPEED),
    );
    let mut r = RoadsResult {
        id: ROADS_ID,
        title: "Real roads: the relative error of the constants M, k1, k2, b for the thesis' identifier and the \
                real-road one, ISO 8608 classes A–E (passenger quarter car)",
        origin: ROADS_ORIGIN,
        samples,
        full_samples,
        seeds,
        speed: ROADS_SPEED,
        dt: ROADS_DT,
        classes: ROAD_CLASSES.iter().map(|&c| class_letter(c)).collect(),
        constants: ROADS_CONSTANTS.to_vec(),
        units: vec!["kg", "N/m", "N/m", "N·s/m"],
        truth: truth.to_vec(),
        known: KnownConstant { name: "m", unit: "kg", value: c[1] },
        setup,
        rows,
        verdicts: vec![],
        cpu_seconds,
    };
    r.verdicts = roads_verdicts(&r);
    r
}

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

/// Fig B-3's claims ([`ROADS_CLAIMS`]) evaluated against `r`'s rows.
pub fn roads_verdicts(r: &RoadsResult) -> Vec<crate::report::Verdict> {
    ROADS_CLAIMS.iter().map(|c| evaluate_roads(c, r)).collect()
}

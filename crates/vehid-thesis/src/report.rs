//! What a reproduction produced: per figure the curves (median and band over seeds, per-seed
//! metrics, the physical constants identified along the first seed) and the verdicts, and
//! the tables. Plain data: every type derives
//! [`serde::Serialize`], and [`Report::to_json`] writes it with serde_json (the criterion
//! bench times it); the Python binding turns the same serialization into Python objects.
//!
//! # Non-finite numbers
//!
//! ξ is NaN where there is no estimate yet (batch least squares before the data have full
//! rank) and ∞ where an identifier overflowed; per seed, `settle` and `reach` are ∞ when ξ
//! never got (to stay) below 0.08, `argmin` is NaN when ξ never was a number. JSON has neither
//! NaN nor ∞, so the JSON has **every non-finite number as `null`** (serde_json's documented
//! rule for non-finite floats, held by `tests/experiments.rs`,
//! `the_json_has_the_report_fields_and_writes_every_non_finite_number_as_null`): a JSON
//! reader sees "no finite value". In `settle` and `reach` `null` means never (∞); in the ξ
//! series (`median`, `p10`, `p90`, `final_xi`, `min_xi`) it means no estimate or overflow;
//! in `argmin`, no minimum; in a curve's identified constants (`constants`: `value`, `lo`,
//! `hi`) it means no estimate (or no positive constants from it) and, for `lo` and `hi`, no
//! interval (an identifier without a covariance); `constants` itself is `null` for batch
//! least squares. The scalar floats (σ, `seconds`, `truth`) are always finite. The serialization
//! itself keeps NaN and ±∞, so the Rust values and the Python binding's objects have them as
//! they are.
//!
//! The figures beyond the thesis ([`SweepResult`], [`HalfResult`], [`RoadsResult`]) follow the
//! same rule (their per-seed ξ and relative errors are ∞ where an identifier gave no estimate,
//! B-3's estimates and interval ends NaN); they are written only when they ran.
//!
//! `ident` and `model` are serialized as their Rust `Debug` text (e.g.
//! `Kalman { p0_wheel: 1000.0, p0_body: 1000.0, r_scale: 1.0, reinit: false }`), which is what
//! the report prints.

use crate::figures::{Ident, ModelKind};
use serde::Serialize;

/// Median and 10–90 % band of one curve, plus per-seed summary metrics.
#[derive(Debug, Clone, Serialize)]
pub struct CurveResult {
    /// The legend name: the curve's label, or `curve i` (1-based) when it has none.
    pub label: String,
    /// The identifier and its settings.
    #[serde(serialize_with = "ser::debug_text")]
    pub ident: Ident,
    /// Initial-condition σ_ic.
    pub ic: f64,
    /// Road σ_u.
    pub road: f64,
    /// State measurement σ_w.
    pub state: f64,
    /// State derivative measurement σ_v.
    pub deriv: f64,
    /// Pulse width in sample intervals (0 = no pulse).
    pub pulse_width: u64,
    /// Median ξ over seeds at each recorded iteration.
    pub median: Vec<f64>,
    /// 10 % quantile.
    pub p10: Vec<f64>,
    /// 90 % quantile.
    pub p90: Vec<f64>,
    /// Per seed: ξ at the last recorded iteration.
    pub final_xi: Vec<f64>,
    /// Per seed: iteration after which ξ stays below 0.08 (∞ if never).
    pub settle: Vec<f64>,
    /// Per seed: first iteration with ξ < 0.08 (∞ if never).
    pub reach: Vec<f64>,
    /// Per seed: minimum ξ over the run.
    pub min_xi: Vec<f64>,
    /// Per seed: iteration of the minimum.
    pub argmin: Vec<f64>,
    /// Per seed: Eq 4.36 reinitializations (Kalman), else 0.
    pub reinits: Vec<f64>,
    /// The car's physical constants identified along the curve's first realization (seed
    /// index 0), with their 95 % intervals; `None` for batch least squares (Ch. III).
    pub constants: Option<IdentifiedConstants>,
}

/// A constant of the car that the identification takes as known (it fixes the scale: the
/// equations of motion determine only ratios of the constants).
#[derive(Debug, Clone, Serialize)]
pub struct KnownConstant {
    /// The model's name of it (`QuarterCar::CONSTANTS` / `HalfCar::CONSTANTS`), e.g. `m`.
    pub name: &'static str,
    /// Its unit, e.g. `kg`.
    pub unit: &'static str,
    /// Its value (the thesis' car), in `unit`.
    pub value: f64,
}

/// One identified physical constant along the iterations of [`IdentifiedConstants::k`].
#[derive(Debug, Clone, Serialize)]
pub struct ConstantSeries {
    /// The model's name of it, e.g. `M`, `k1`, `k2`, `b` (quarter car, Eq 3.8–3.13).
    pub name: &'static str,
    /// Its unit: `kg` (masses), `kg·m²` (J), `N/m` (stiffnesses), `N·s/m` (dampings), `m`
    /// (lever arms).
    pub unit: &'static str,
    /// The true value (the thesis' car), in `unit`.
    pub truth: f64,
    /// The estimate at each `k` (NaN: no estimate yet, the rows give no positive constants,
    /// or the identifier diverged).
    pub value: Vec<f64>,
    /// Lower end of the 95 % interval at each `k` (NaN: the identifier keeps no covariance,
    /// or the covariance is not defined yet).
    pub lo: Vec<f64>,
    /// Upper end of the 95 % interval at each `k` (NaN as for `lo`).
    pub hi: Vec<f64>,
}

/// The physical constants identified along one realization of a curve (the runner's
/// `constants` module documents the maps from the estimate and the intervals).
#[derive(Debug, Clone, Serialize)]
pub struct IdentifiedConstants {
    /// The simulator seed of the realization (seed index 0 of the curve, [`crate::job_seed`]).
    pub seed: u64,
    /// How the constants and their intervals follow from the estimate, one line.
    pub method: String,
    /// The iterations recorded: a decimated subset of the figure's `k` (about
    /// [`crate::CONSTANT_POINTS`] points, evenly spaced on a log and on a linear axis, the last
    /// iteration always included).
    pub k: Vec<u64>,
    /// The constants held known.
    pub known: Vec<KnownConstant>,
    /// The identified constants, in the model's order of constants.
    pub constants: Vec<ConstantSeries>,
}

/// A claim's verdict.
#[derive(Debug, Clone, Serialize)]
pub struct Verdict {
    /// The thesis' claim.
    pub claim: String,
    /// What vehid measured, one line.
    pub measured: String,
    /// Whether the measurement agrees.
    pub agrees: bool,
    /// Why it differs (or a caveat), empty when there is nothing to add.
    pub note: String,
}

/// The result of one figure.
#[derive(Debug, Clone, Serialize)]
pub struct FigureResult {
    /// Figure number, e.g. `"4-2"` ([`crate::select`] finds its [`crate::Experiment`]).
    pub id: &'static str,
    /// Caption, shortened.
    pub title: &'static str,
    /// Model.
    #[serde(serialize_with = "ser::debug_text")]
    pub model: ModelKind,
    /// Iterations of the full run (as in the thesis, or assumed).
    pub thesis_iterations: usize,
    /// Iterations actually run.
    pub iterations: usize,
    /// Seeds run.
    pub seeds: usize,
    /// Values chosen because the thesis does not print them.
    pub assumptions: &'static str,
    /// Why it was skipped, if it was.
    pub skipped: Option<String>,
    /// Recorded iterations.
    pub k: Vec<u64>,
    /// Curves.
    pub curves: Vec<CurveResult>,
    /// Claims evaluated.
    pub verdicts: Vec<Verdict>,
}

/// One row of a table (thesis value vs vehid's).
#[derive(Debug, Clone, Serialize)]
pub struct TableRow {
    /// What the row is.
    pub label: String,
    /// The thesis' value, as printed.
    pub thesis: String,
    /// vehid's value.
    pub vehid: String,
    /// Agreement.
    pub agrees: bool,
    /// Explanation.
    pub note: String,
}

/// A table of the report.
#[derive(Debug, Clone, Serialize)]
pub struct Table {
    /// Heading, e.g. "Eq 4.28".
    pub title: String,
    /// How it was measured.
    pub method: String,
    /// Rows.
    pub rows: Vec<TableRow>,
}

/// One method of Fig B-1 (beyond the thesis): ξ after the run at each σ_w, over seeds.
#[derive(Debug, Clone, Serialize)]
pub struct SweepCurve {
    /// The legend text.
    pub label: &'static str,
    /// How the method is set up and what it is told.
    pub setup: &'static str,
    /// Median ξ over seeds at each level of [`SweepResult::levels`] (an estimate that could
    /// not be read counts as ∞).
    pub median: Vec<f64>,
    /// 25 % quantile at each level.
    pub q25: Vec<f64>,
    /// 75 % quantile at each level.
    pub q75: Vec<f64>,
    /// Smallest ξ over seeds at each level.
    pub min: Vec<f64>,
    /// Largest ξ over seeds at each level (the worst seed).
    pub max: Vec<f64>,
    /// ξ per level, per seed (seed index order).
    pub xi: Vec<Vec<f64>>,
    /// Samples the identifier refused, per level, summed over seeds.
    pub refused: Vec<u64>,
    /// Per level, the seeds with no estimate at the end and the identifier's error (empty
    /// when every seed has one).
    pub errors: Vec<Vec<(usize, String)>>,
}

/// Fig B-1 (beyond the thesis): ξ after the run against the state noise σ_w, per method.
#[derive(Debug, Clone, Serialize)]
pub struct SweepResult {
    /// `"B-1"`.
    pub id: &'static str,
    /// Caption.
    pub title: &'static str,
    /// Where the figure comes from: not from the thesis.
    pub origin: &'static str,
    /// Samples per run.
    pub samples: usize,
    /// Samples per run of the full mode.
    pub full_samples: usize,
    /// Seeds per method and level.
    pub seeds: usize,
    /// The state-noise levels σ_w, % of σ_u.
    pub levels: Vec<f64>,
    /// The simulation and the seeds, one paragraph.
    pub setup: String,
    /// One curve per method.
    pub curves: Vec<SweepCurve>,
    /// The figure's claims evaluated.
    pub verdicts: Vec<Verdict>,
    /// Wall time of its jobs summed over the worker threads, s.
    pub cpu_seconds: f64,
}

/// One method at one σ_w in Fig B-2: per seed ξ of the wheel rows, of the body rows, and the
/// worst entry.
#[derive(Debug, Clone, Serialize)]
pub struct HalfCell {
    /// σ_w, % of σ_u.
    pub level: f64,
    /// Per seed: ξ of the wheel rows 1 and 3 (∞: no estimate).
    pub wheel: Vec<f64>,
    /// Per seed: ξ of the body rows 5 and 7.
    pub body: Vec<f64>,
    /// Per seed: the largest relative error over the 28 non-zero entries.
    pub worst_entry: Vec<f64>,
    /// Samples refused, summed over seeds.
    pub refused: u64,
    /// The seeds with no estimate and the identifier's error.
    pub errors: Vec<(usize, String)>,
}

/// One method of Fig B-2.
#[derive(Debug, Clone, Serialize)]
pub struct HalfRow {
    /// The row label.
    pub label: &'static str,
    /// How the method is set up and what it is told.
    pub setup: &'static str,
    /// One cell per level of [`HalfResult::levels`].
    pub cells: Vec<HalfCell>,
}

/// Fig B-2 (beyond the thesis, a table): the half car on one road with noisy states.
#[derive(Debug, Clone, Serialize)]
pub struct HalfResult {
    /// `"B-2"`.
    pub id: &'static str,
    /// Caption.
    pub title: &'static str,
    /// Where it comes from: not from the thesis.
    pub origin: &'static str,
    /// Samples per run.
    pub samples: usize,
    /// Seeds per method and level.
    pub seeds: usize,
    /// σ_w levels, % of σ_u (the noise-free reference and the level of the claims).
    pub levels: Vec<f64>,
    /// The simulation and the seeds, one paragraph.
    pub setup: String,
    /// One row per method run.
    pub rows: Vec<HalfRow>,
    /// Methods not run, and why.
    pub not_run: Vec<(String, String)>,
    /// Its claims evaluated.
    pub verdicts: Vec<Verdict>,
    /// Wall time of its jobs summed over the worker threads, s.
    pub cpu_seconds: f64,
}

/// One scenario of Fig B-4 (beyond the thesis): per seed what the full car's monitor named
/// first after the change, when, and how large.
#[derive(Debug, Clone, Serialize)]
pub struct FullRow {
    /// The row label (the change).
    pub label: &'static str,
    /// The constant the monitor should name (`FullCar::CONSTANTS`; empty: no change).
    pub expect: &'static str,
    /// The true relative change of `expect`, %.
    pub truth: f64,
    /// Per seed, the constant named by the first event after the change (empty: none).
    pub named: Vec<String>,
    /// Per seed, that event's delay after the change, s (∞: none).
    pub delay: Vec<f64>,
    /// Per seed, its reported relative change, % (NaN: none).
    pub change: Vec<f64>,
    /// Events before the change over the seeds (the drive without a change: every event).
    pub early: u64,
}

/// Fig B-4 (beyond the thesis, a table): the full car's health monitor, one change at a time.
#[derive(Debug, Clone, Serialize)]
pub struct FullResult {
    /// `"B-4"`.
    pub id: &'static str,
    /// Caption.
    pub title: &'static str,
    /// Where it comes from: not from the thesis.
    pub origin: &'static str,
    /// Length of each drive, s.
    pub seconds: f64,
    /// When the constants change, s.
    pub change_at: f64,
    /// Seeds per row.
    pub seeds: usize,
    /// The simulation, the monitor and the seeds, one paragraph.
    pub setup: String,
    /// One row per scenario (the last: no change).
    pub rows: Vec<FullRow>,
    /// Its claims evaluated.
    pub verdicts: Vec<Verdict>,
    /// Wall time of its jobs summed over the worker threads, s.
    pub cpu_seconds: f64,
}

/// One identifier of Fig B-3 on one road class: per constant and seed the estimate, its 95 %
/// interval and its relative error, and their summaries over seeds.
#[derive(Debug, Clone, Serialize)]
pub struct RoadsCell {
    /// The ISO 8608 class, `"A"` … `"E"`.
    pub class: &'static str,
    /// Per constant ([`RoadsResult::constants`] order), per seed: the estimate (NaN: none).
    pub value: Vec<Vec<f64>>,
    /// Per constant, per seed: the lower end of the 95 % interval (NaN: none).
    pub lo: Vec<Vec<f64>>,
    /// Per constant, per seed: the upper end of the 95 % interval (NaN: none).
    pub hi: Vec<Vec<f64>>,
    /// Per constant, per seed: the relative error `|estimate / truth − 1|` (∞: no estimate).
    pub rel_err: Vec<Vec<f64>>,
    /// Per constant: the median relative error over seeds.
    pub median: Vec<f64>,
    /// Per constant: the smallest relative error over seeds.
    pub min: Vec<f64>,
    /// Per constant: the largest relative error over seeds (the worst seed).
    pub max: Vec<f64>,
    /// Per constant: the seeds whose 95 % interval holds the true value.
    pub covered: Vec<usize>,
    /// Samples refused, summed over seeds.
    pub refused: u64,
    /// The seeds with no estimate and the identifier's error.
    pub errors: Vec<(usize, String)>,
}

/// One identifier of Fig B-3.
#[derive(Debug, Clone, Serialize)]
pub struct RoadsRow {
    /// The legend text.
    pub label: &'static str,
    /// How it is set up and what it is told.
    pub setup: &'static str,
    /// One cell per class of [`RoadsResult::classes`].
    pub cells: Vec<RoadsCell>,
}

/// Fig B-3 (beyond the thesis), "real roads": the thesis' identifier against the real-road one
/// on ISO 8608 roads of classes A–E.
#[derive(Debug, Clone, Serialize)]
pub struct RoadsResult {
    /// `"B-3"`.
    pub id: &'static str,
    /// Caption.
    pub title: &'static str,
    /// Where it comes from: not from the thesis.
    pub origin: &'static str,
    /// Samples per run.
    pub samples: usize,
    /// Samples per run of the full mode.
    pub full_samples: usize,
    /// Seeds per class.
    pub seeds: usize,
    /// Speed, m/s.
    pub speed: f64,
    /// Sample interval, s.
    pub dt: f64,
    /// The ISO 8608 classes, `"A"` … `"E"`.
    pub classes: Vec<&'static str>,
    /// The constants' names (`M`, `k1`, `k2`, `b`).
    pub constants: Vec<&'static str>,
    /// Their units.
    pub units: Vec<&'static str>,
    /// Their true values (the passenger car's).
    pub truth: Vec<f64>,
    /// The constant held known: the wheel mass.
    pub known: KnownConstant,
    /// The simulation and the seeds, one paragraph.
    pub setup: String,
    /// One row per identifier.
    pub rows: Vec<RoadsRow>,
    /// Its claims evaluated.
    pub verdicts: Vec<Verdict>,
    /// Wall time of its jobs summed over the worker threads, s.
    pub cpu_seconds: f64,
}

/// Everything a reproduction produced.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// Quick mode.
    pub quick: bool,
    /// Base seed.
    pub base_seed: u64,
    /// Threads used.
    pub threads: usize,
    /// Wall time of the run, s.
    pub seconds: f64,
    /// Figures.
    pub figures: Vec<FigureResult>,
    /// Tables (with, when Fig B-1 / B-2 / B-3 ran, their claims and numbers as tables too: the form
    /// a renderer that knows only figures of ξ against iterations can show).
    pub tables: Vec<Table>,
    /// Fig B-1 (beyond the thesis), when selected (absent from the JSON otherwise; the Python
    /// binding converts it the same way, and `vehid reproduce` draws it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sweep: Option<SweepResult>,
    /// Fig B-2 (beyond the thesis), when selected (absent from the JSON otherwise; as
    /// [`Report::sweep`] for the binding; `vehid reproduce` shows it as a table).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub half_one_road: Option<HalfResult>,
    /// Fig B-3 (beyond the thesis), when selected (absent from the JSON otherwise; as
    /// [`Report::sweep`] for the binding; `vehid reproduce` draws it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub real_roads: Option<RoadsResult>,
    /// Fig B-4 (beyond the thesis): the full car's health monitor, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub full_car: Option<FullResult>,
}

impl Report {
    /// The report as JSON, field names as in the Rust types; every non-finite number is
    /// `null` (see the [module documentation](self)).
    pub fn to_json(&self) -> String {
        // Infallible: no maps (so no non-string keys) and no serializer that can fail.
        serde_json::to_string(self).expect("a Report always serializes to JSON")
    }
}

/// Formats a number for the report (integers without decimals, ∞ as "never").
pub fn fmt_num(v: f64) -> String {
    if v.is_nan() {
        "n/a".to_string()
    } else if v.is_infinite() {
        "∞".to_string()
    } else if v != 0.0 && (v.abs() >= 1e5 || v.abs() < 1e-3) {
        format!("{v:.2e}")
    } else if v.fract() == 0.0 {
        format!("{v:.0}")
    } else if v.abs() >= 10.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.3}")
    }
}

/// The `serialize_with` helpers of the report's fields.
mod ser {
    use serde::Serializer;

    /// A value as its `Debug` text.
    pub(super) fn debug_text<T: core::fmt::Debug, S: Serializer>(v: &T, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(&format_args!("{v:?}"))
    }
}

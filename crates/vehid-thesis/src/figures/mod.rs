//! The thesis' figures as data: one [`Experiment`] per figure of Chapters III–VI.
//!
//! [`EXPERIMENTS`] holds one [`Experiment`] per figure (3-2 … 3-7, 4-1 … 4-9, 5-1 … 5-4,
//! 6-2 … 6-9): the model, one [`Curve`] per curve of the figure with the caption's four noise
//! σ (initial conditions, road, state measurement, state derivative measurement), the
//! identifier and its settings, the thesis' iteration count, and the thesis' claims as
//! checkable [`Claim`]s. Where a caption is garbled or a value is not printed, the table says
//! so in [`Experiment::assumptions`].

mod catalog;
mod claim;
mod curve;

pub use catalog::EXPERIMENTS;
pub use claim::{Claim, ThesisClaim};
pub use curve::{curve_name, Curve, GainKind, Ident};

/// The vehicle model of an experiment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelKind {
    /// The 4-state quarter car (Eq 3.8–3.13), unknown rows 1 and 3 (0-based).
    Quarter,
    /// The 8-state half car (Eq 6.1–6.8) driven through the front wheel only (Ch. VI.C).
    HalfFront,
    /// The half car with two independent road inputs (Fig 6-7).
    HalfIndependent,
    /// The half car driven along a road sampled by distance: the rear wheel meets the front
    /// wheel's road one wheelbase later (Fig 6-8, 6-9; a curve labelled "independent…" gets
    /// independent roads instead).
    HalfOneRoad,
}

/// One figure of the thesis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Experiment {
    /// Figure number, e.g. `"4-2"`.
    pub id: &'static str,
    /// Caption, shortened.
    pub title: &'static str,
    /// Model.
    pub model: ModelKind,
    /// Curves.
    pub curves: &'static [Curve],
    /// Iterations of the full run (as in the thesis, or assumed).
    pub iterations: usize,
    /// Curves are different noise ensembles of the same settings (Fig 3-2); otherwise all
    /// curves of a seed share the noise realizations (only the σ scale them), as the thesis
    /// did in Fig 3-6 ("the same noise sample was used for all four curves").
    pub distinct_ensembles: bool,
    /// Claims checked against the measurements.
    pub claims: &'static [ThesisClaim],
    /// Values chosen here because the thesis does not print them (or the OCR is garbled).
    pub assumptions: &'static str,
    /// `Some(reason)` when vehid cannot run the figure yet.
    pub needs: Option<&'static str>,
}

/// The pulse amplitude (m) of Fig 3-4, 4-4 and 6-5: not printed in the thesis (assumption).
/// The pulse switches on just after the measurement of the ninth cycle, so a one-cycle pulse
/// is never seen at a sample instant (the thesis' condition for no input–output correlation).
pub const PULSE_AMPLITUDE: f64 = 1.0;
/// The sample at which pulses start: the ninth measurement cycle (Ch. VI.C.4).
pub const PULSE_START: u64 = 8;
/// The sample interval, s.
pub const DT: f64 = 0.05;

/// The experiments selected by `only` (all when empty).
///
/// # Errors
/// [`crate::Error::InvalidArgument`] naming `only` for an unknown figure id.
pub fn select(only: &[String]) -> crate::Result<Vec<&'static Experiment>> {
    if only.is_empty() {
        return Ok(EXPERIMENTS.iter().collect());
    }
    let mut out = vec![];
    for id in only {
        match EXPERIMENTS.iter().find(|e| e.id == id.trim()) {
            Some(e) => out.push(e),
            None => {
                return Err(crate::Error::InvalidArgument {
                    arg: "only",
                    expected: "figure ids of Ch. III–VI such as 4-2 (3-2 … 3-7, 4-1 … 4-9, 5-1 … 5-4, 6-2 … 6-9), or B-1, B-2 (beyond the thesis: the runner selects those)",
                })
            }
        }
    }
    Ok(out)
}

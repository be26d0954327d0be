//! The thesis' claims about a figure, in a form the measurements can check.

/// A claim of the thesis about a figure, in a form the measurements can check. Curves are
/// indices into [`Experiment::curves`](super::Experiment::curves); "at the end" means the last recorded iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Claim {
    /// ξ needs at least `iters` iterations to stay below `level` (median over seeds).
    SettlesAfter {
        /// Curve.
        curve: usize,
        /// Acceptance level.
        level: f64,
        /// Iterations claimed.
        iters: f64,
    },
    /// ξ stays below `level` from at most `iters` iterations on (median over seeds; a claim
    /// of vehid's extensions, the counterpart of [`Claim::SettlesAfter`]).
    SettlesWithin {
        /// Curve.
        curve: usize,
        /// Acceptance level.
        level: f64,
        /// Iterations claimed.
        iters: f64,
    },
    /// ξ reaches `level` within `iters` iterations (median first crossing).
    ReachesWithin {
        /// Curve.
        curve: usize,
        /// Level.
        level: f64,
        /// Iterations claimed.
        iters: f64,
    },
    /// The median ξ at the end is above `level` (no acceptable identification in the run).
    EndsAbove {
        /// Curve.
        curve: usize,
        /// Level.
        level: f64,
    },
    /// The median ξ at the end increases along the listed curves.
    Increasing {
        /// Curves in the claimed order (best first).
        curves: &'static [usize],
    },
    /// The median iteration of minimum ξ lies in `[lo, hi]`.
    MinimumNear {
        /// Curve.
        curve: usize,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// The median over seeds of ξ_a / ξ_b at the end lies in `[lo, hi]`.
    Ratio {
        /// Numerator curve.
        a: usize,
        /// Denominator curve.
        b: usize,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// The median over seeds of ξ_a − ξ_b at the end lies in `[lo, hi]`.
    Difference {
        /// Curve.
        a: usize,
        /// Curve subtracted.
        b: usize,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// The best curve's median ξ at the end lies in `[lo, hi]`.
    BestBetween {
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// The median minimum over the run of curve `a` is below that of every other curve.
    LowestMinimum {
        /// Curve.
        a: usize,
    },
}

/// A thesis claim with its one-line statement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThesisClaim {
    /// The thesis' claim, one line.
    pub text: &'static str,
    /// Its checkable form.
    pub check: Claim,
    /// The likely reason when vehid's measurement differs (shown only then; empty if none known).
    pub why: &'static str,
}

//! The claims of Fig B-1 and B-2 (vehid's, not the thesis'), in a form the runs check
//! (`verdict.rs` evaluates them). Every bound is two-sided where a value outside it on
//! either side would mean something is wrong.

use super::{HalfMethod, QuarterMethod};

/// A checkable statement about Fig B-1 (medians over seeds of ξ after the run).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SweepCheck {
    /// The median ξ of every listed method at σ_w = `level` % lies in `[lo, hi]`.
    Median {
        /// Methods.
        methods: &'static [QuarterMethod],
        /// σ_w, % of σ_u (one of [`super::SWEEP_LEVELS`]).
        level: f64,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// The median over seeds of ξ_a / ξ_b (same seed, same samples) at `level` lies in
    /// `[lo, hi]`.
    Ratio {
        /// Numerator method.
        a: QuarterMethod,
        /// Denominator method.
        b: QuarterMethod,
        /// σ_w, % of σ_u.
        level: f64,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// The median ξ of `method` increases (strictly) from level to level over
    /// `from ..= to` (% of σ_u).
    Increasing {
        /// Method.
        method: QuarterMethod,
        /// First level.
        from: f64,
        /// Last level.
        to: f64,
    },
}

/// A claim of Fig B-1 with its one-line statement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepClaim {
    /// The claim, one line.
    pub text: &'static str,
    /// Its checkable form.
    pub check: SweepCheck,
}

/// Which part of the half car's estimate a claim is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// ξ of the wheel rows 1 and 3.
    Wheel,
    /// ξ of the body rows 5 and 7.
    Body,
    /// The larger of the two.
    WorstPair,
}

/// A checkable statement about Fig B-2 (medians over seeds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HalfCheck {
    /// The median of `part` for `method` at `level` lies in `[lo, hi]`.
    Median {
        /// Method.
        method: HalfMethod,
        /// The part of the estimate.
        part: Part,
        /// σ_w, % of σ_u (one of [`super::HALF_LEVELS`]).
        level: f64,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// The median over seeds of `part`'s ξ_a / ξ_b at `level` lies in `[lo, hi]`.
    Ratio {
        /// Numerator method.
        a: HalfMethod,
        /// Denominator method.
        b: HalfMethod,
        /// The part of the estimate.
        part: Part,
        /// σ_w, % of σ_u.
        level: f64,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// The best method's median worst-pair ξ at `level` lies in `[lo, hi]`.
    Best {
        /// σ_w, % of σ_u.
        level: f64,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
}

/// A claim of Fig B-2 with its one-line statement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfClaim {
    /// The claim, one line.
    pub text: &'static str,
    /// Its checkable form.
    pub check: HalfCheck,
}

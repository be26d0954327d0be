//! The claims of Fig B-1, B-2 and B-3 (vehid's, not the thesis'), in a form the runs check
//! (`verdict.rs` evaluates them). Every bound is two-sided where a value outside it on
//! either side would mean something is wrong.

use super::{HalfMethod, QuarterMethod, RoadsIdent};
use vehid_core::sim::RoadClass;

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

/// A checkable statement about Fig B-3 (relative errors `|estimate / truth − 1|` of the
/// constants M, k1, k2, b over seeds, per road class).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RoadsCheck {
    /// On every listed class, the fraction of seeds on which every constant of `ident` is
    /// within `tol` lies in `[lo, hi]` (no estimate: not within).
    AllWithin {
        /// Identifier.
        ident: RoadsIdent,
        /// Road classes.
        classes: &'static [RoadClass],
        /// Relative error bound.
        tol: f64,
        /// Lower bound of the fraction.
        lo: f64,
        /// Upper bound of the fraction.
        hi: f64,
    },
    /// On every listed class, the median over seeds of each listed constant's relative error
    /// of `ident` lies in `[lo, hi]`.
    Median {
        /// Identifier.
        ident: RoadsIdent,
        /// Constants, by name (`M`, `k1`, `k2`, `b`).
        constants: &'static [&'static str],
        /// Road classes.
        classes: &'static [RoadClass],
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// The fraction of `ident`'s 95 % intervals that hold the true constant, pooled over the
    /// listed classes, the four constants and the seeds, lies in `[lo, hi]` (no interval: not
    /// held).
    Coverage {
        /// Identifier.
        ident: RoadsIdent,
        /// Road classes.
        classes: &'static [RoadClass],
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// On every listed class and for every constant, the median over seeds of the ratio of
    /// relative errors `a / b` (same seed, same samples) lies in `[lo, hi]`.
    Ratio {
        /// Numerator identifier.
        a: RoadsIdent,
        /// Denominator identifier.
        b: RoadsIdent,
        /// Road classes.
        classes: &'static [RoadClass],
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
}

/// A claim of Fig B-3 with its one-line statement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoadsClaim {
    /// The claim, one line.
    pub text: &'static str,
    /// Its checkable form.
    pub check: RoadsCheck,
}

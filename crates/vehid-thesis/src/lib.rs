//! # vehid-thesis
//!
//! The simulation study of J. H. Kessler, *Adaptive Modeling of the Dynamics of Autonomous
//! Land Vehicles* (NPS, 1986), as data, and a runner that reproduces it (`vehid reproduce`).
//! An application of [`vehid_core`], kept out of it: it needs `std` (threads, clocks).
//!
//! Modules, one per concept:
//! - [`beyond`]: figures beyond the thesis (not in Kessler 1986), run by the same runner and
//!   selected by id: Fig B-1, ξ after the run against the state noise σ_w for every identifier
//!   for noisy states and the thesis' own (quarter car), and Fig B-2, the half car on one road
//!   with noisy states, and Fig B-3, "real roads": the thesis' identifier against the real-road
//!   one on ISO 8608 roads of classes A–E (the passenger car's constants M, k1, k2, b and their
//!   95 % intervals); their claims checked like the thesis', mirrored as report tables;
//! - [`figures`]: [`EXPERIMENTS`], one [`Experiment`] per figure of Chapters III–VI (3-2 …
//!   3-7, 4-1 … 4-9, 5-1 … 5-4, 6-2 … 6-9) with its curves, identifiers and the thesis'
//!   claims as checkable [`Claim`]s;
//! - [`seeds`]: the seed of every realization, derived from one base seed ([`job_seed`]);
//! - [`runner`]: [`run`] walks the table, every curve over `S` seeds, in parallel (scoped
//!   threads over a shared job counter), ξ_k (Eq 3.17 / 6.10) recorded on a fixed grid, and
//!   along the first seed of every identifier curve the car's physical constants (M, k1, k2,
//!   b of the quarter car; the half car's) with their 95 % intervals on a decimated grid;
//! - [`stats`]: the median and 10–90 % band over seeds, and per seed the settle, reach and
//!   minimum metrics;
//! - `verdict`: each claim evaluated against the measurements;
//! - [`tables`](mod@tables): Eq 4.28, Eq 4.32, Eq 4.34 and Table I, computed the same way;
//! - [`report`]: the [`Report`] and its JSON ([`Report::to_json`]).
//!
//! Every number is computed at run time from the base seed.
//!
//! # Examples
//!
//! ```
//! use vehid_thesis::{run, RunOptions};
//!
//! let opts = RunOptions {
//!     only: vec!["3-5".into()],
//!     seeds: Some(2),
//!     max_iterations: Some(100),
//!     tables: false,
//!     ..RunOptions::default()
//! };
//! let report = run(&opts, &|_| {})?;
//! assert_eq!(report.figures[0].curves.len(), 4);
//! # Ok::<(), vehid_thesis::Error>(())
//! ```
#![deny(missing_docs)]

pub mod beyond;
pub mod figures;
pub mod report;
pub mod runner;
pub mod seeds;
pub mod stats;
pub mod tables;
mod verdict;

pub use figures::{
    curve_name, select, Claim, Curve, Experiment, GainKind, Ident, ModelKind, ThesisClaim, DT, EXPERIMENTS,
    PULSE_AMPLITUDE, PULSE_START,
};
pub use report::{
    fmt_num, ConstantSeries, CurveResult, FigureResult, FullResult, FullRow, HalfCell, HalfResult, HalfRow,
    IdentifiedConstants, KnownConstant, Report, RoadsCell, RoadsResult, RoadsRow, SweepCurve, SweepResult, Table,
    TableRow, Verdict,
};
pub use runner::{run, Progress, RunOptions, CONSTANT_POINTS, QUICK_ITERATIONS};
pub use seeds::job_seed;
pub use stats::{median, quantile};
pub use tables::{tables, EQ_4_28, EQ_4_32, EQ_4_34};
/// The error type: vehid-core's (an unknown figure id is [`Error::InvalidArgument`]).
pub use vehid_core::{Error, Result};

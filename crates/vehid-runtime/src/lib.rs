//! vehid at run-time sizes: the layer between a binding and the core.
//!
//! The core (`vehid-core`) is generic over the scalar and over its sizes; a caller that learns
//! the sizes at run time (the Python bindings, a configuration file) needs them turned into
//! types once, and its objects saved and restored without recovering their types. This crate
//! does both, so that the binding only converts, validates its arguments and maps errors:
//! - [`sizes`]: the size table of linear models (`N` states in 1..=16, `M` inputs in 1..=4);
//!   the sizes built on a structure are listed in [`build`] (with the accessors that read
//!   them back): no other crate lists either;
//! - [`model`]: linear models as plain data and their one-off algebra;
//! - [`sim`]: simulators of any size behind one interface;
//! - [`build`]: every identifier, of a linear model or on a structure;
//! - [`defaults`]: what a run-time caller gets when it does not say;
//! - [`saved`] and [`seal`]: saved identifiers (the core's `Persist` state in a checked
//!   envelope) and the CRC-32 seal of every saved state.

pub mod build;
pub mod defaults;
pub mod model;
pub mod saved;
pub mod seal;
pub mod sim;
pub mod sizes;

pub use model::ModelData;

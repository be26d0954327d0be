//! Criterion benches for vehid.

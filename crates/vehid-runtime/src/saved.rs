//! Saved identifiers: what a pickle of an identifier holds, and the checks that decide whether
//! it may be restored into a given object.
//!
//! An identifier is saved as its class, what it was built on (its model or structure, as text),
//! its settings (the rest of what rebuilds an equivalent fresh object, as text), its model's
//! data and its core's own state
//! ([`vehid_core::identify::Persist::save_state`]), sealed with a CRC-32 ([`crate::seal`]).
//! Restoring builds a fresh object from the class and settings, then [`load`]s the state into
//! it: the saved class, basis, settings and model must be the fresh object's (so the core's type is
//! the one that saved the state), and the core loads its own state all or nothing.

use crate::model::ModelData;
use crate::seal;
use serde::{Deserialize, Serialize};
use vehid_core::identify::DynIdentifier;

/// Version of the saved layout. Raise it when the envelope or any core type's serialized
/// form changes in a way older readers (or this reader, for older states) cannot follow.
/// 3: the core's type named by the binding, a CRC-32. 4: the core's type implied by the
/// class and its settings (`Persist`), the envelope below. 5: the outlier screen of the
/// identifiers without one of their own (its state saved with the core's, its gate among the
/// settings). 6: the two-axle identifier's wheel filters per track (the full car's two); the
/// other identifiers' states are those of 5.
pub const FORMAT: u32 = 6;

/// The oldest format this reader restores: format 5 states of every identifier whose state did
/// not change since ([`load`] names the format when one did and does not load).
pub const OLDEST: u32 = 5;

/// What a saved identifier holds.
#[derive(Debug, Serialize, Deserialize)]
struct Envelope {
    class: String,
    basis: String,
    settings: String,
    model: ModelData,
    state: Vec<u8>,
}

/// What an object is, for saving and restoring: its class, what it was built on (its model
/// or structure, as text) and its other settings (as text), and its model's data.
#[derive(Debug, Clone, Copy)]
pub struct Identity<'a> {
    /// The class name.
    pub class: &'a str,
    /// What the object was built on.
    pub basis: &'a str,
    /// Its other settings.
    pub settings: &'a str,
    /// Its model.
    pub model: &'a ModelData,
}

/// Why a state was not restored (the text is the message for the user).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Refused(pub String);

impl core::fmt::Display for Refused {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(&self.0)
    }
}

fn corrupt(what: &str) -> Refused {
    Refused(format!("cannot restore the identifier: {what} (the pickle is corrupt, or was not made by vehid)"))
}

/// The sealed state of `id`, the object `who`.
///
/// # Errors
/// The core's, e.g. an identifier type that does not implement `Persist`.
pub fn save(id: &dyn DynIdentifier<f64>, who: Identity<'_>) -> vehid_core::Result<Vec<u8>> {
    let envelope = Envelope {
        class: who.class.into(),
        basis: who.basis.into(),
        settings: who.settings.into(),
        model: who.model.clone(),
        state: id.save_state()?,
    };
    seal::seal(&envelope).map_err(|_| vehid_core::Error::OutOfMemory { what: "the saved state", bytes: usize::MAX })
}

/// Checks the format a state was saved in (`version`: the vehid that saved it, for the message).
///
/// # Errors
/// [`Refused`] naming the formats read for any outside [`OLDEST`]..=[`FORMAT`].
pub fn check_format(format: u32, version: &str) -> Result<(), Refused> {
    if (OLDEST..=FORMAT).contains(&format) {
        return Ok(());
    }
    Err(Refused(format!(
        "cannot restore the identifier: it was pickled by {version} in state format {format}, and this vehid ({}) \
         reads formats {OLDEST} to {FORMAT} only; refit it, or load it with the version that saved it",
        env!("CARGO_PKG_VERSION")
    )))
}

/// Restores the sealed `bytes` into `id`, a fresh object `who`; all or nothing. `saved_in`:
/// the format and the vehid version the state was saved in (checked by [`check_format`]).
///
/// # Errors
/// [`Refused`] when the bytes fail their checksum or do not decode, were saved from an object
/// of another class, settings, basis or model, or the core refuses the state (naming the
/// format when it is older than [`FORMAT`]: the core's state changed since).
pub fn load(
    id: &mut dyn DynIdentifier<f64>,
    bytes: &[u8],
    who: Identity<'_>,
    saved_in: (u32, &str),
) -> Result<(), Refused> {
    let saved: Envelope =
        seal::open(bytes).map_err(|e| corrupt(&format!("its payload does not decode or fails its checksum ({e})")))?;
    if saved.class != who.class || saved.settings != who.settings {
        return Err(Refused(format!(
            "cannot restore a {} from the state of another kind of identifier (a {} with {}; this one has {})",
            who.class, saved.class, saved.settings, who.settings
        )));
    }
    if saved.model != *who.model || saved.basis != who.basis {
        return Err(Refused(format!(
            "cannot restore the identifier: the state is of an identifier of another model than this object's \
             ({}, not {})",
            saved.basis, who.basis
        )));
    }
    id.load_state(&saved.state).map_err(|e| match saved_in {
        (format, version) if format < FORMAT => Refused(format!(
            "cannot restore the {}: it was pickled by {version} in state format {format}, and its state changed in \
             format {FORMAT} (this vehid, {}); refit it, or load it with the version that saved it",
            who.class,
            env!("CARGO_PKG_VERSION")
        )),
        _ => corrupt(&format!("its core does not load ({e})")),
    })
}

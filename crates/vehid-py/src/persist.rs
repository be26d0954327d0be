//! Pickling and copying of identifiers.
//!
//! An identifier pickles as `copyreg.__newobj_ex__(cls, args, kwargs)` plus a state, which
//! works with every pickle protocol (0–5). Each class says what builds a fresh object of its
//! class and settings in its own `__getnewargs_ex__` (the model or Structure, and the settings
//! that decide the core's type); `__setstate__` then loads the saved core state into that
//! fresh object. The state is `(FORMAT, "vehid <version>", payload)`, the payload
//! `vehid_runtime::saved`'s sealed envelope: the class, the settings (the text of the fresh
//! object's arguments), the model and the core's own state (`Persist`). Restoring checks the
//! format, then that the envelope is of this object's class, settings and model, then the
//! core loads its state all or nothing.

use crate::guard::{borrow, borrow_mut};
use crate::identify::PyIdentifier;
use crate::model::{Kind, PyLinearModel};
use crate::VehidError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};
use vehid_runtime::saved::{self, Refused};

/// The arguments of `__newobj_ex__`: positional, keyword.
pub type NewArgs<'py> = (Bound<'py, PyTuple>, Bound<'py, PyDict>);

/// `(args, kwargs)` that build a fresh identifier like `base` (on its Structure, or on its
/// linear model) with the keyword arguments `kwargs` (what a class's `__getnewargs_ex__` returns).
pub fn new_args<'py>(py: Python<'py>, base: &PyIdentifier, kwargs: Bound<'py, PyDict>) -> PyResult<NewArgs<'py>> {
    let model = match &base.structure {
        Some(st) => st.bind(py).clone().into_any(),
        None => Bound::new(py, PyLinearModel::new_core(base.model.clone(), Kind::Generic))?.into_any(),
    };
    Ok((PyTuple::new(py, [model])?, kwargs))
}

/// The object's class name, its fresh-object arguments, and their text: the positional ones
/// (the model or Structure) and the keyword ones (the settings).
fn identity<'py>(obj: &Bound<'py, PyIdentifier>) -> PyResult<(String, NewArgs<'py>, [String; 2])> {
    let args: NewArgs<'py> = obj.call_method0("__getnewargs_ex__")?.extract()?;
    let text = [args.0.repr()?.to_string(), args.1.repr()?.to_string()];
    Ok((obj.get_type().name()?.to_string(), args, text))
}

fn who<'a>(class: &'a str, text: &'a [String; 2], model: &'a vehid_runtime::ModelData) -> saved::Identity<'a> {
    saved::Identity { class, basis: &text[0], settings: &text[1], model }
}

fn refused(r: Refused) -> PyErr {
    VehidError::new_err(r.0)
}

/// `__reduce__`: `(copyreg.__newobj_ex__, (cls, args, kwargs), state)`.
pub fn reduce<'py>(obj: &Bound<'py, PyIdentifier>) -> PyResult<Bound<'py, PyTuple>> {
    let py = obj.py();
    let (class, (args, kwargs), text) = identity(obj)?;
    let this = borrow(obj)?;
    let payload = saved::save(this.inner.as_ref(), who(&class, &text, &this.model))
        .map_err(|e| VehidError::new_err(format!("cannot pickle the {class}: {e}")))?;
    let state = (saved::FORMAT, concat!("vehid ", env!("CARGO_PKG_VERSION")), PyBytes::new(py, &payload));
    let newobj = py.import("copyreg")?.getattr("__newobj_ex__")?;
    (newobj, (obj.get_type(), args, kwargs), state).into_pyobject(py)
}

/// `__copy__` / `__deepcopy__`: a fresh object of the same class with a copy of the core (the
/// models are immutable and shared).
pub fn copy<'py>(obj: &Bound<'py, PyIdentifier>) -> PyResult<Bound<'py, PyAny>> {
    let (_, (args, kwargs), _) = identity(obj)?;
    let new = obj.get_type().call(args, Some(&kwargs))?;
    let new = new.cast::<PyIdentifier>()?;
    let core = borrow(obj)?.inner.clone_box();
    borrow_mut(new)?.inner = core;
    Ok(new.clone().into_any())
}

/// `__setstate__`: the format first, then the envelope and the core (`saved::load`).
pub fn set_state(obj: &Bound<'_, PyIdentifier>, state: &Bound<'_, PyAny>) -> PyResult<()> {
    let not_a_state = || {
        refused(Refused(
            "cannot restore the identifier: its state is not a (format, version, bytes) tuple (the pickle is corrupt, \
             or was not made by vehid)"
                .into(),
        ))
    };
    let t = state.cast::<PyTuple>().map_err(|_| not_a_state())?;
    let head = (t.len() >= 3)
        .then(|| t.get_item(0)?.extract::<u32>().and_then(|f| Ok((f, t.get_item(1)?.extract::<String>()?))));
    let (format, version) = head.and_then(Result::ok).ok_or_else(not_a_state)?;
    saved::check_format(format, &version).map_err(refused)?;
    let payload: Vec<u8> = match t.len() {
        3 => t.get_item(2)?.extract().map_err(|_| not_a_state())?,
        _ => return Err(not_a_state()),
    };
    let (class, _, text) = identity(obj)?;
    let mut this = borrow_mut(obj)?;
    let model = this.model.clone();
    saved::load(this.inner.as_mut(), &payload, who(&class, &text, &model), (format, &version)).map_err(refused)
}

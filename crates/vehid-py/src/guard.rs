//! Threads and interrupts: what the bindings do when one object is used from two
//! threads, and when Ctrl-C arrives during a long call.
//!
//! Threads: a method that releases the GIL (`fit`, `theta` of a large batch, `Simulator.run`)
//! keeps its object borrowed meanwhile, so another thread can call into the same object.
//! pyo3's own borrow check would refuse that with `RuntimeError: Already borrowed`; every
//! method of the identifiers and of `Simulator` borrows through [`borrow`] / [`borrow_mut`]
//! instead, which refuse it with a `VehidError` that says what to do. Nothing is changed by
//! the refused call, and the call in progress is not disturbed.
//!
//! Interrupts: a long call releases the GIL and asks [`Interrupts::check`] between pieces of
//! work. At most every [`CHECK_INTERVAL`] that takes the GIL back for a moment and lets Python
//! run its signal handlers (`py.check_signals()`); a pending exception (`KeyboardInterrupt`
//! from Ctrl-C) stops the call, which undoes its work and raises it. Python runs signal
//! handlers in the main thread only: a call made from another thread is not interrupted.

use crate::VehidError;
use pyo3::prelude::*;
use pyo3::pyclass::boolean_struct::False;
use pyo3::PyClass;
use std::time::{Duration, Instant};

/// How long a GIL-released call runs at most between two looks at pending signals.
pub const CHECK_INTERVAL: Duration = Duration::from_millis(20);

/// The `VehidError` of a call into an object another thread is using.
fn in_use(obj: &Bound<'_, PyAny>) -> PyErr {
    let name = obj.get_type().name().map_or_else(|_| "object".to_string(), |n| n.to_string());
    let copy = if name == "Simulator" {
        "create one Simulator per thread"
    } else {
        "give each thread its own copy (copy.deepcopy(obj))"
    };
    VehidError::new_err(format!(
        "this {name} is in use by another thread (a call on it, such as fit() or run(), is still running with the \
         GIL released): {copy}, or serialize the calls with a threading.Lock; nothing was changed"
    ))
}

/// Borrows `slf` for reading, or refuses with a `VehidError` when another thread holds it.
pub(crate) fn borrow<'py, T: PyClass>(slf: &Bound<'py, T>) -> PyResult<PyRef<'py, T>> {
    slf.try_borrow().map_err(|_| in_use(slf.as_any()))
}

/// Borrows `slf` for a change, or refuses with a `VehidError` when another thread uses it.
pub(crate) fn borrow_mut<'py, T: PyClass<Frozen = False>>(slf: &Bound<'py, T>) -> PyResult<PyRefMut<'py, T>> {
    slf.try_borrow_mut().map_err(|_| in_use(slf.as_any()))
}

/// The interrupt check of one GIL-released call (see the module documentation).
pub(crate) struct Interrupts {
    last: Instant,
    pending: Option<PyErr>,
}

impl Interrupts {
    pub(crate) fn new() -> Self {
        Self { last: Instant::now(), pending: None }
    }

    /// `true` when the call must stop: a signal handler raised (the exception is kept for
    /// [`Interrupts::raise`]). Cheap between looks (one clock read); call it often.
    pub(crate) fn check(&mut self) -> bool {
        if self.pending.is_some() {
            return true;
        }
        if self.last.elapsed() < CHECK_INTERVAL {
            return false;
        }
        if let Err(e) = Python::attach(|py| py.check_signals()) {
            self.pending = Some(e);
            return true;
        }
        self.last = Instant::now();
        false
    }

    /// The exception a signal handler raised, if the call was stopped by one.
    pub(crate) fn raise(self) -> Option<PyErr> {
        self.pending
    }
}

/// Samples between two [`Interrupts::check`] calls for an identifier with `params`
/// parameters: an update costs up to about `params²` operations (mode "full"), so that a
/// check comes every ~10⁵ operations (a clock read per some 10 µs of work at the least), and
/// at least every sample for the largest models.
pub(crate) fn check_every(params: usize) -> usize {
    ((1usize << 17) / params.saturating_mul(params).max(1)).clamp(1, 1 << 16)
}

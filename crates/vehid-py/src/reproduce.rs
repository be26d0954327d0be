//! `vehid reproduce`: the thesis' simulation study (the `vehid-thesis` runner), run with the
//! GIL released; the report comes back as Python objects for `vehid.reproduce` to render.
//!
//! The report's own serde serialization (the one `Report::to_json` writes) is turned into
//! Python objects by `pythonize`: structs are dicts with the same keys as the JSON, vectors
//! lists, tuples tuples, `None` fields left out where the JSON leaves them out, and floats stay
//! floats, so NaN and ±∞ arrive as `nan` / `float('inf')` (the JSON writes them as `null`).

use crate::core_err;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::io::Write;
use std::sync::Mutex;
use std::time::{Duration, Instant};
use vehid_thesis::{run, Progress, RunOptions};

/// Runs the reproduction and returns the report as nested dicts and lists (NaN and ±inf
/// as floats).
///
/// quick: 5 seeds and at most 10,000 iterations per curve; only: figure ids (e.g.
/// ["4-2", "4-5"]), all when None; seed: the base seed; seeds / max_iterations / threads
/// override the defaults; tables: also compute Eq 4.28, 4.32, 4.34 and Table I; progress:
/// print a progress line to stderr while running.
#[pyfunction]
#[pyo3(signature = (quick=false, only=None, seed=1986, seeds=None, max_iterations=None, threads=None, tables=true, progress=false))]
#[allow(clippy::too_many_arguments)]
pub fn reproduce_report<'py>(
    py: Python<'py>,
    quick: bool,
    only: Option<Vec<String>>,
    seed: u64,
    seeds: Option<usize>,
    max_iterations: Option<usize>,
    threads: Option<usize>,
    tables: bool,
    progress: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let opts =
        RunOptions { quick, seeds, max_iterations, base_seed: seed, threads, only: only.unwrap_or_default(), tables };
    let last = Mutex::new(Instant::now() - Duration::from_secs(1));
    let report = py.detach(|| {
        let cb = |p: Progress<'_>| {
            if !progress {
                return;
            }
            let mut t = last.lock().unwrap_or_else(|e| e.into_inner());
            if p.done == p.total || t.elapsed() >= Duration::from_millis(200) {
                *t = Instant::now();
                let width = 30;
                let filled = width * p.done / p.total.max(1);
                let mut err = std::io::stderr().lock();
                let _ = write!(
                    err,
                    "\rreproduce [{}{}] {}/{} runs (Fig {})   ",
                    "#".repeat(filled),
                    "-".repeat(width - filled),
                    p.done,
                    p.total,
                    p.figure
                );
                if p.done == p.total {
                    let _ = writeln!(err);
                }
                let _ = err.flush();
            }
        };
        run(&opts, &cb)
    });
    let report = report.map_err(core_err)?;
    pythonize::pythonize(py, &report).map_err(|e| PyValueError::new_err(format!("the report as Python objects: {e}")))
}

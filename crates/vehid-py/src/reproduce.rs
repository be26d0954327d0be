//! `vehid reproduce`: the thesis' simulation study (the `vehid-thesis` runner), run with the
//! GIL released; the report comes back as Python objects for `vehid.reproduce` to render.
//!
//! The conversion is written out here, field by field, with the keys of the report's serde
//! serialization (`vehid_thesis::report`): the serde→Python bridge `pythonize` would derive it,
//! but its newest release (0.29) requires pyo3 0.29 and this crate uses pyo3 0.30. Floats stay
//! floats, so NaN and ±∞ arrive as `nan` / `float('inf')` (the JSON writes them as `null`).

use crate::core_err;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::io::Write;
use std::sync::Mutex;
use std::time::{Duration, Instant};
use vehid_thesis::{
    run, CurveResult, FigureResult, HalfCell, HalfResult, HalfRow, IdentifiedConstants, Progress, Report, RoadsCell,
    RoadsResult, RoadsRow, RunOptions, SweepCurve, SweepResult, Table, TableRow, Verdict,
};

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
) -> PyResult<Bound<'py, PyDict>> {
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
    report_dict(py, &report.map_err(core_err)?)
}

/// The report as nested dicts and lists, with the keys of its JSON (`Report::to_json`): as
/// there, `sweep` (Fig B-1), `half_one_road` (Fig B-2) and `real_roads` (Fig B-3) only when
/// they ran.
fn report_dict<'py>(py: Python<'py>, r: &Report) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("quick", r.quick)?;
    d.set_item("base_seed", r.base_seed)?;
    d.set_item("threads", r.threads)?;
    d.set_item("seconds", r.seconds)?;
    d.set_item("figures", list(py, &r.figures, figure_dict)?)?;
    d.set_item("tables", list(py, &r.tables, table_dict)?)?;
    if let Some(s) = &r.sweep {
        d.set_item("sweep", sweep_dict(py, s)?)?;
    }
    if let Some(h) = &r.half_one_road {
        d.set_item("half_one_road", half_dict(py, h)?)?;
    }
    if let Some(h) = &r.real_roads {
        d.set_item("real_roads", roads_dict(py, h)?)?;
    }
    Ok(d)
}

fn list<'py, T>(
    py: Python<'py>,
    items: &[T],
    f: impl Fn(Python<'py>, &T) -> PyResult<Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyList>> {
    let l = PyList::empty(py);
    for item in items {
        l.append(f(py, item)?)?;
    }
    Ok(l)
}

fn figure_dict<'py>(py: Python<'py>, f: &FigureResult) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("id", f.id)?;
    d.set_item("title", f.title)?;
    d.set_item("model", format!("{:?}", f.model))?;
    d.set_item("thesis_iterations", f.thesis_iterations)?;
    d.set_item("iterations", f.iterations)?;
    d.set_item("seeds", f.seeds)?;
    d.set_item("assumptions", f.assumptions)?;
    d.set_item("skipped", f.skipped.as_deref())?;
    d.set_item("k", f.k.as_slice())?;
    d.set_item("curves", list(py, &f.curves, curve_dict)?)?;
    d.set_item("verdicts", list(py, &f.verdicts, verdict_dict)?)?;
    Ok(d)
}

fn curve_dict<'py>(py: Python<'py>, c: &CurveResult) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("label", c.label.as_str())?;
    d.set_item("ident", format!("{:?}", c.ident))?;
    d.set_item("ic", c.ic)?;
    d.set_item("road", c.road)?;
    d.set_item("state", c.state)?;
    d.set_item("deriv", c.deriv)?;
    d.set_item("pulse_width", c.pulse_width)?;
    for (key, values) in [
        ("median", &c.median),
        ("p10", &c.p10),
        ("p90", &c.p90),
        ("final_xi", &c.final_xi),
        ("settle", &c.settle),
        ("reach", &c.reach),
        ("min_xi", &c.min_xi),
        ("argmin", &c.argmin),
        ("reinits", &c.reinits),
    ] {
        d.set_item(key, values.as_slice())?;
    }
    match &c.constants {
        Some(k) => d.set_item("constants", constants_dict(py, k)?)?,
        None => d.set_item("constants", py.None())?,
    }
    Ok(d)
}

fn constants_dict<'py>(py: Python<'py>, c: &IdentifiedConstants) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("seed", c.seed)?;
    d.set_item("method", c.method.as_str())?;
    d.set_item("k", c.k.as_slice())?;
    let known = PyList::empty(py);
    for k in &c.known {
        let e = PyDict::new(py);
        e.set_item("name", k.name)?;
        e.set_item("unit", k.unit)?;
        e.set_item("value", k.value)?;
        known.append(e)?;
    }
    d.set_item("known", known)?;
    let series = PyList::empty(py);
    for s in &c.constants {
        let e = PyDict::new(py);
        e.set_item("name", s.name)?;
        e.set_item("unit", s.unit)?;
        e.set_item("truth", s.truth)?;
        e.set_item("value", s.value.as_slice())?;
        e.set_item("lo", s.lo.as_slice())?;
        e.set_item("hi", s.hi.as_slice())?;
        series.append(e)?;
    }
    d.set_item("constants", series)?;
    Ok(d)
}

fn verdict_dict<'py>(py: Python<'py>, v: &Verdict) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("claim", v.claim.as_str())?;
    d.set_item("measured", v.measured.as_str())?;
    d.set_item("agrees", v.agrees)?;
    d.set_item("note", v.note.as_str())?;
    Ok(d)
}

fn table_dict<'py>(py: Python<'py>, t: &Table) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("title", t.title.as_str())?;
    d.set_item("method", t.method.as_str())?;
    d.set_item("rows", list(py, &t.rows, row_dict)?)?;
    Ok(d)
}

fn row_dict<'py>(py: Python<'py>, r: &TableRow) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("label", r.label.as_str())?;
    d.set_item("thesis", r.thesis.as_str())?;
    d.set_item("vehid", r.vehid.as_str())?;
    d.set_item("agrees", r.agrees)?;
    d.set_item("note", r.note.as_str())?;
    Ok(d)
}

/// Fig B-1 (beyond the thesis), with the keys of `SweepResult`'s JSON.
fn sweep_dict<'py>(py: Python<'py>, r: &SweepResult) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("id", r.id)?;
    d.set_item("title", r.title)?;
    d.set_item("origin", r.origin)?;
    d.set_item("samples", r.samples)?;
    d.set_item("full_samples", r.full_samples)?;
    d.set_item("seeds", r.seeds)?;
    d.set_item("levels", r.levels.as_slice())?;
    d.set_item("setup", r.setup.as_str())?;
    d.set_item("curves", list(py, &r.curves, sweep_curve_dict)?)?;
    d.set_item("verdicts", list(py, &r.verdicts, verdict_dict)?)?;
    d.set_item("cpu_seconds", r.cpu_seconds)?;
    Ok(d)
}

fn sweep_curve_dict<'py>(py: Python<'py>, c: &SweepCurve) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("label", c.label)?;
    d.set_item("setup", c.setup)?;
    for (key, values) in [("median", &c.median), ("q25", &c.q25), ("q75", &c.q75), ("min", &c.min), ("max", &c.max)] {
        d.set_item(key, values.as_slice())?;
    }
    let xi = PyList::empty(py);
    for per_seed in &c.xi {
        xi.append(per_seed.as_slice())?;
    }
    d.set_item("xi", xi)?;
    d.set_item("refused", c.refused.as_slice())?;
    let errors = PyList::empty(py);
    for level in &c.errors {
        errors.append(errors_list(py, level)?)?;
    }
    d.set_item("errors", errors)?;
    Ok(d)
}

/// `(seed index, message)` pairs as a list of 2-tuples (JSON: 2-element arrays).
fn errors_list<'py>(py: Python<'py>, errors: &[(usize, String)]) -> PyResult<Bound<'py, PyList>> {
    let l = PyList::empty(py);
    for (seed, message) in errors {
        l.append((*seed, message.as_str()))?;
    }
    Ok(l)
}

/// Fig B-2 (beyond the thesis), with the keys of `HalfResult`'s JSON.
fn half_dict<'py>(py: Python<'py>, r: &HalfResult) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("id", r.id)?;
    d.set_item("title", r.title)?;
    d.set_item("origin", r.origin)?;
    d.set_item("samples", r.samples)?;
    d.set_item("seeds", r.seeds)?;
    d.set_item("levels", r.levels.as_slice())?;
    d.set_item("setup", r.setup.as_str())?;
    d.set_item("rows", list(py, &r.rows, half_row_dict)?)?;
    let not_run = PyList::empty(py);
    for (method, why) in &r.not_run {
        not_run.append((method.as_str(), why.as_str()))?;
    }
    d.set_item("not_run", not_run)?;
    d.set_item("verdicts", list(py, &r.verdicts, verdict_dict)?)?;
    d.set_item("cpu_seconds", r.cpu_seconds)?;
    Ok(d)
}

fn half_row_dict<'py>(py: Python<'py>, r: &HalfRow) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("label", r.label)?;
    d.set_item("setup", r.setup)?;
    d.set_item("cells", list(py, &r.cells, half_cell_dict)?)?;
    Ok(d)
}

fn half_cell_dict<'py>(py: Python<'py>, c: &HalfCell) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("level", c.level)?;
    for (key, values) in [("wheel", &c.wheel), ("body", &c.body), ("worst_entry", &c.worst_entry)] {
        d.set_item(key, values.as_slice())?;
    }
    d.set_item("refused", c.refused)?;
    d.set_item("errors", errors_list(py, &c.errors)?)?;
    Ok(d)
}

/// Fig B-3 (beyond the thesis), with the keys of `RoadsResult`'s JSON.
fn roads_dict<'py>(py: Python<'py>, r: &RoadsResult) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("id", r.id)?;
    d.set_item("title", r.title)?;
    d.set_item("origin", r.origin)?;
    d.set_item("samples", r.samples)?;
    d.set_item("full_samples", r.full_samples)?;
    d.set_item("seeds", r.seeds)?;
    d.set_item("speed", r.speed)?;
    d.set_item("dt", r.dt)?;
    d.set_item("classes", r.classes.as_slice())?;
    d.set_item("constants", r.constants.as_slice())?;
    d.set_item("units", r.units.as_slice())?;
    d.set_item("truth", r.truth.as_slice())?;
    let known = PyDict::new(py);
    known.set_item("name", r.known.name)?;
    known.set_item("unit", r.known.unit)?;
    known.set_item("value", r.known.value)?;
    d.set_item("known", known)?;
    d.set_item("setup", r.setup.as_str())?;
    d.set_item("rows", list(py, &r.rows, roads_row_dict)?)?;
    d.set_item("verdicts", list(py, &r.verdicts, verdict_dict)?)?;
    d.set_item("cpu_seconds", r.cpu_seconds)?;
    Ok(d)
}

fn roads_row_dict<'py>(py: Python<'py>, r: &RoadsRow) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("label", r.label)?;
    d.set_item("setup", r.setup)?;
    d.set_item("cells", list(py, &r.cells, roads_cell_dict)?)?;
    Ok(d)
}

fn roads_cell_dict<'py>(py: Python<'py>, c: &RoadsCell) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("class", c.class)?;
    for (key, values) in [("value", &c.value), ("lo", &c.lo), ("hi", &c.hi), ("rel_err", &c.rel_err)] {
        let l = PyList::empty(py);
        for per_seed in values {
            l.append(per_seed.as_slice())?;
        }
        d.set_item(key, l)?;
    }
    for (key, values) in [("median", &c.median), ("min", &c.min), ("max", &c.max)] {
        d.set_item(key, values.as_slice())?;
    }
    d.set_item("covered", c.covered.as_slice())?;
    d.set_item("refused", c.refused)?;
    d.set_item("errors", errors_list(py, &c.errors)?)?;
    Ok(d)
}

//! What a reproduction produced: per figure the curves (median and band over seeds, per-seed
//! metrics) and the verdicts, and the tables.

use crate::figures::{curve_name, Curve, Experiment};

/// Median and 10–90 % band of one curve, plus per-seed summary metrics.
#[derive(Debug, Clone)]
pub struct CurveResult {
    /// The curve's definition.
    pub curve: Curve,
    /// Median ξ over seeds at each recorded iteration.
    pub median: Vec<f64>,
    /// 10 % quantile.
    pub p10: Vec<f64>,
    /// 90 % quantile.
    pub p90: Vec<f64>,
    /// Per seed: ξ at the last recorded iteration.
    pub final_xi: Vec<f64>,
    /// Per seed: iteration after which ξ stays below 0.08 (∞ if never).
    pub settle: Vec<f64>,
    /// Per seed: first iteration with ξ < 0.08 (∞ if never).
    pub reach: Vec<f64>,
    /// Per seed: minimum ξ over the run.
    pub min_xi: Vec<f64>,
    /// Per seed: iteration of the minimum.
    pub argmin: Vec<f64>,
    /// Per seed: Eq 4.36 reinitializations (Kalman), else 0.
    pub reinits: Vec<f64>,
}

/// A claim's verdict.
#[derive(Debug, Clone)]
pub struct Verdict {
    /// The thesis' claim.
    pub claim: String,
    /// What vehid measured, one line.
    pub measured: String,
    /// Whether the measurement agrees.
    pub agrees: bool,
    /// Why it differs (or a caveat), empty when there is nothing to add.
    pub note: String,
}

/// The result of one figure.
#[derive(Debug, Clone)]
pub struct FigureResult {
    /// The definition.
    pub experiment: &'static Experiment,
    /// Recorded iterations.
    pub k: Vec<u64>,
    /// Iterations actually run.
    pub iterations: usize,
    /// Seeds run.
    pub seeds: usize,
    /// Curves.
    pub curves: Vec<CurveResult>,
    /// Claims evaluated.
    pub verdicts: Vec<Verdict>,
    /// Why it was skipped, if it was.
    pub skipped: Option<String>,
}

/// One row of a table (thesis value vs vehid's).
#[derive(Debug, Clone)]
pub struct TableRow {
    /// What the row is.
    pub label: String,
    /// The thesis' value, as printed.
    pub thesis: String,
    /// vehid's value.
    pub vehid: String,
    /// Agreement.
    pub agrees: bool,
    /// Explanation.
    pub note: String,
}

/// A table of the report.
#[derive(Debug, Clone)]
pub struct Table {
    /// Heading, e.g. "Eq 4.28".
    pub title: String,
    /// How it was measured.
    pub method: String,
    /// Rows.
    pub rows: Vec<TableRow>,
}

/// Everything a reproduction produced.
#[derive(Debug, Clone)]
pub struct Report {
    /// Quick mode.
    pub quick: bool,
    /// Base seed.
    pub base_seed: u64,
    /// Threads used.
    pub threads: usize,
    /// Wall time of the run, s.
    pub seconds: f64,
    /// Figures.
    pub figures: Vec<FigureResult>,
    /// Tables.
    pub tables: Vec<Table>,
}
/// Formats a number for the report (integers without decimals, ∞ as "never").
pub fn fmt_num(v: f64) -> String {
    if v.is_nan() {
        "n/a".to_string()
    } else if v.is_infinite() {
        "∞".to_string()
    } else if v != 0.0 && (v.abs() >= 1e5 || v.abs() < 1e-3) {
        format!("{v:.2e}")
    } else if v.fract() == 0.0 {
        format!("{v:.0}")
    } else if v.abs() >= 10.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.3}")
    }
}

fn jstr(s: &str, out: &mut String) {
    out.push('"');
    for ch in s.chars() {
        match ch {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
}

fn jnum(v: f64, out: &mut String) {
    if v.is_finite() {
        out.push_str(&format!("{v}"));
    } else if v.is_nan() {
        out.push_str("null");
    } else if v > 0.0 {
        out.push_str("\"inf\"");
    } else {
        out.push_str("\"-inf\"");
    }
}

fn jarr(v: &[f64], out: &mut String) {
    out.push('[');
    for (i, x) in v.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        jnum(*x, out);
    }
    out.push(']');
}

fn jkv(key: &str, out: &mut String) {
    jstr(key, out);
    out.push(':');
}

impl Report {
    /// The report as JSON (non-finite numbers: `null` for NaN, `"inf"` for ∞).
    pub fn to_json(&self) -> String {
        let mut o = String::new();
        o.push('{');
        jkv("quick", &mut o);
        o.push_str(if self.quick { "true" } else { "false" });
        o.push(',');
        jkv("base_seed", &mut o);
        o.push_str(&self.base_seed.to_string());
        o.push(',');
        jkv("threads", &mut o);
        o.push_str(&self.threads.to_string());
        o.push(',');
        jkv("seconds", &mut o);
        jnum(self.seconds, &mut o);
        o.push(',');
        jkv("figures", &mut o);
        o.push('[');
        for (fi, f) in self.figures.iter().enumerate() {
            if fi > 0 {
                o.push(',');
            }
            let e = f.experiment;
            o.push('{');
            jkv("id", &mut o);
            jstr(e.id, &mut o);
            o.push(',');
            jkv("title", &mut o);
            jstr(e.title, &mut o);
            o.push(',');
            jkv("model", &mut o);
            jstr(&format!("{:?}", e.model), &mut o);
            o.push(',');
            jkv("thesis_iterations", &mut o);
            o.push_str(&e.iterations.to_string());
            o.push(',');
            jkv("iterations", &mut o);
            o.push_str(&f.iterations.to_string());
            o.push(',');
            jkv("seeds", &mut o);
            o.push_str(&f.seeds.to_string());
            o.push(',');
            jkv("assumptions", &mut o);
            jstr(e.assumptions, &mut o);
            o.push(',');
            jkv("skipped", &mut o);
            match &f.skipped {
                Some(s) => jstr(s, &mut o),
                None => o.push_str("null"),
            }
            o.push(',');
            jkv("k", &mut o);
            jarr(&f.k.iter().map(|&v| v as f64).collect::<Vec<_>>(), &mut o);
            o.push(',');
            jkv("curves", &mut o);
            o.push('[');
            for (ci, c) in f.curves.iter().enumerate() {
                if ci > 0 {
                    o.push(',');
                }
                let d = &c.curve;
                o.push('{');
                jkv("label", &mut o);
                jstr(&curve_name(d, ci), &mut o);
                o.push(',');
                jkv("ident", &mut o);
                jstr(&format!("{:?}", d.ident), &mut o);
                o.push(',');
                for (key, v) in [("ic", d.ic), ("road", d.road), ("state", d.state), ("deriv", d.deriv)] {
                    jkv(key, &mut o);
                    jnum(v, &mut o);
                    o.push(',');
                }
                jkv("pulse_width", &mut o);
                o.push_str(&d.pulse_width.to_string());
                o.push(',');
                for (key, v) in [
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
                    jkv(key, &mut o);
                    jarr(v, &mut o);
                    o.push(',');
                }
                o.pop();
                o.push('}');
            }
            o.push_str("],");
            jkv("verdicts", &mut o);
            o.push('[');
            for (vi, v) in f.verdicts.iter().enumerate() {
                if vi > 0 {
                    o.push(',');
                }
                o.push('{');
                jkv("claim", &mut o);
                jstr(&v.claim, &mut o);
                o.push(',');
                jkv("measured", &mut o);
                jstr(&v.measured, &mut o);
                o.push(',');
                jkv("agrees", &mut o);
                o.push_str(if v.agrees { "true" } else { "false" });
                o.push(',');
                jkv("note", &mut o);
                jstr(&v.note, &mut o);
                o.push('}');
            }
            o.push_str("]}");
        }
        o.push_str("],");
        jkv("tables", &mut o);
        o.push('[');
        for (ti, t) in self.tables.iter().enumerate() {
            if ti > 0 {
                o.push(',');
            }
            o.push('{');
            jkv("title", &mut o);
            jstr(&t.title, &mut o);
            o.push(',');
            jkv("method", &mut o);
            jstr(&t.method, &mut o);
            o.push(',');
            jkv("rows", &mut o);
            o.push('[');
            for (ri, r) in t.rows.iter().enumerate() {
                if ri > 0 {
                    o.push(',');
                }
                o.push('{');
                for (key, v) in [("label", &r.label), ("thesis", &r.thesis), ("vehid", &r.vehid), ("note", &r.note)] {
                    jkv(key, &mut o);
                    jstr(v, &mut o);
                    o.push(',');
                }
                jkv("agrees", &mut o);
                o.push_str(if r.agrees { "true" } else { "false" });
                o.push('}');
            }
            o.push_str("]}");
        }
        o.push_str("]}");
        o
    }
}

//! Fig B-1 and B-3 drawn (SVG, no dependencies) and the three figures as markdown: the
//! rendering of the figures beyond the thesis for readers of the Rust runner's output (the
//! `beyond` example).

use super::{tables::NOT_THESIS, HALF_ID, ROADS_ID, SWEEP_ID};
use crate::report::{fmt_num, HalfResult, Report, RoadsResult, SweepResult, Verdict};
use crate::stats::{median, ACCEPTABLE_XI};
use std::fmt::Write;

const COLORS: [&str; 7] = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2"];

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// Fig B-1 as an SVG: median ξ (log axis) against σ_w (one tick per level, evenly spaced:
/// the levels include 0), the 25–75 % band shaded, ξ = 0.08 dashed.
pub fn sweep_svg(r: &SweepResult) -> String {
    let (w, h) = (900.0, 560.0);
    let (x0, x1, y0, y1) = (80.0, 560.0, 60.0, 480.0);
    let finite = |v: f64| v.is_finite() && v > 0.0;
    let all: Vec<f64> = r
        .curves
        .iter()
        .flat_map(|c| c.q25.iter().chain(&c.q75).chain(&c.median))
        .copied()
        .filter(|&v| finite(v))
        .collect();
    let lo = all.iter().copied().fold(ACCEPTABLE_XI, f64::min).log10().floor();
    let hi = all.iter().copied().fold(ACCEPTABLE_XI, f64::max).log10().ceil();
    let nl = r.levels.len().max(2);
    let px = |i: usize| x0 + (x1 - x0) * i as f64 / (nl - 1) as f64;
    let py = |v: f64| y1 - (y1 - y0) * (v.log10() - lo) / (hi - lo).max(1.0);
    let mut s = String::new();
    let _ = write!(
        s,
        "<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{h}' font-family='sans-serif' font-size='12'>\
         <rect width='100%' height='100%' fill='white'/>"
    );
    let _ = write!(
        s,
        "<text x='{x0}' y='22' font-size='14'>Fig {} (beyond the thesis — not a figure of Kessler 1986)</text>\
         <text x='{x0}' y='40' font-size='11' fill='#444'>ξ after {} samples against σ_w, quarter car; median and 25–75 % \
         band over {} seeds</text>",
        esc(r.id),
        r.samples,
        r.seeds
    );
    // Axes, grid and ticks.
    let mut e = lo as i32;
    while e <= hi as i32 {
        let y = py(10f64.powi(e));
        let _ = write!(
            s,
            "<line x1='{x0}' y1='{y}' x2='{x1}' y2='{y}' stroke='#ddd'/><text x='{}' y='{}' text-anchor='end'>1e{e}</text>",
            x0 - 6.0,
            y + 4.0
        );
        e += 1;
    }
    for (i, l) in r.levels.iter().enumerate() {
        let x = px(i);
        let _ = write!(
            s,
            "<line x1='{x}' y1='{y0}' x2='{x}' y2='{y1}' stroke='#eee'/><text x='{x}' y='{}' text-anchor='middle'>{l}</text>",
            y1 + 18.0
        );
    }
    let _ = write!(
        s,
        "<rect x='{x0}' y='{y0}' width='{}' height='{}' fill='none' stroke='black'/>\
         <text x='{}' y='{}' text-anchor='middle'>state noise σ_w, % of σ_u (one tick per level run)</text>\
         <text transform='translate(24 {}) rotate(-90)' text-anchor='middle'>ξ after the run (Eq 3.17, log axis)</text>",
        x1 - x0,
        y1 - y0,
        (x0 + x1) / 2.0,
        y1 + 40.0,
        (y0 + y1) / 2.0
    );
    let ya = py(ACCEPTABLE_XI);
    let _ = write!(
        s,
        "<line x1='{x0}' y1='{ya}' x2='{x1}' y2='{ya}' stroke='black' stroke-dasharray='6 4'/>\
         <text x='{}' y='{}' font-size='10'>ξ = 0.08 (acceptable)</text>",
        x1 - 110.0,
        ya - 4.0
    );
    for (ci, c) in r.curves.iter().enumerate() {
        let col = COLORS[ci % COLORS.len()];
        // Band: q75 left to right, q25 back (where both are finite).
        let idx: Vec<usize> = (0..r.levels.len()).filter(|&i| finite(c.q25[i]) && finite(c.q75[i])).collect();
        if idx.len() >= 2 {
            let mut pts: Vec<String> = idx.iter().map(|&i| format!("{:.1},{:.1}", px(i), py(c.q75[i]))).collect();
            pts.extend(idx.iter().rev().map(|&i| format!("{:.1},{:.1}", px(i), py(c.q25[i]))));
            let _ = write!(s, "<polygon points='{}' fill='{col}' fill-opacity='0.15' stroke='none'/>", pts.join(" "));
        }
        let med: Vec<String> = (0..r.levels.len())
            .filter(|&i| finite(c.median[i]))
            .map(|i| format!("{:.1},{:.1}", px(i), py(c.median[i])))
            .collect();
        let _ = write!(s, "<polyline points='{}' fill='none' stroke='{col}' stroke-width='2'/>", med.join(" "));
        for i in (0..r.levels.len()).filter(|&i| finite(c.median[i])) {
            let _ = write!(s, "<circle cx='{:.1}' cy='{:.1}' r='3' fill='{col}'/>", px(i), py(c.median[i]));
        }
        let ly = y0 + 10.0 + 22.0 * ci as f64;
        let _ = write!(
            s,
            "<line x1='{}' y1='{ly}' x2='{}' y2='{ly}' stroke='{col}' stroke-width='3'/><text x='{}' y='{}'>{}</text>",
            x1 + 15.0,
            x1 + 40.0,
            x1 + 46.0,
            ly + 4.0,
            esc(c.label)
        );
    }
    s.push_str("</svg>\n");
    s
}

/// Fig B-3 as an SVG: one panel per constant, the relative error (log axis) per road class,
/// per identifier the median (marker) and the range over seeds (bar); under the real-road
/// identifier's markers, the seeds whose 95 % interval holds the truth.
pub fn roads_svg(r: &RoadsResult) -> String {
    let (w, h) = (1000.0, 470.0);
    let (top, bottom, left, gap) = (70.0, 390.0, 70.0, 20.0);
    let pw = (w - left - 20.0 - gap * 3.0) / 4.0;
    let ok = |v: f64| v.is_finite() && v > 0.0;
    let all: Vec<f64> = r
        .rows
        .iter()
        .flat_map(|row| row.cells.iter().flat_map(|c| c.min.iter().chain(&c.max)))
        .copied()
        .filter(|&v| ok(v))
        .collect();
    let lo = all.iter().copied().fold(0.01, f64::min).log10().floor();
    // A decade above the largest error: the thesis' identifier's errors near 1 stay off the frame.
    let hi = (3.0 * all.iter().copied().fold(1.0, f64::max)).log10().ceil();
    let py = |v: f64| bottom - (bottom - top) * (v.max(10f64.powf(lo)).log10() - lo) / (hi - lo).max(1.0);
    let nc = r.classes.len().max(1);
    let mut s = String::new();
    let _ = write!(
        s,
        "<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{h}' font-family='sans-serif' font-size='12'>\
         <rect width='100%' height='100%' fill='white'/>\
         <text x='{left}' y='22' font-size='14'>Fig {} (beyond the thesis — not a figure of Kessler 1986): real roads</text>\
         <text x='{left}' y='40' font-size='11' fill='#444'>relative error |estimate / truth − 1| after {} samples ({} m/s, \
         dt {} s), median and range over {} seeds per ISO 8608 class; passenger quarter car, m known</text>",
        esc(r.id),
        r.samples,
        r.speed,
        r.dt,
        r.seeds
    );
    for (ki, name) in r.constants.iter().enumerate() {
        let x0 = left + ki as f64 * (pw + gap);
        let x1 = x0 + pw;
        let px = |ci: usize| x0 + pw * (ci as f64 + 0.5) / nc as f64;
        let mut e = lo as i32;
        while e <= hi as i32 {
            let y = py(10f64.powi(e));
            let _ = write!(s, "<line x1='{x0}' y1='{y}' x2='{x1}' y2='{y}' stroke='#ddd'/>");
            if ki == 0 {
                let _ = write!(s, "<text x='{}' y='{}' text-anchor='end'>1e{e}</text>", x0 - 6.0, y + 4.0);
            }
            e += 1;
        }
        let y5 = py(0.05);
        let _ = write!(
            s,
            "<line x1='{x0}' y1='{y5}' x2='{x1}' y2='{y5}' stroke='black' stroke-dasharray='5 4'/>\
             <rect x='{x0}' y='{top}' width='{pw}' height='{}' fill='none' stroke='black'/>\
             <text x='{}' y='{}' text-anchor='middle' font-size='13'>{} (true {})</text>",
            bottom - top,
            (x0 + x1) / 2.0,
            top - 8.0,
            esc(name),
            fmt_num(r.truth[ki])
        );
        for (ci, c) in r.classes.iter().enumerate() {
            let _ = write!(s, "<text x='{}' y='{}' text-anchor='middle'>{c}</text>", px(ci), bottom + 16.0);
        }
        for (mi, row) in r.rows.iter().enumerate() {
            let col = COLORS[mi % COLORS.len()];
            let dx = if mi == 0 { -7.0 } else { 7.0 };
            for (ci, cell) in row.cells.iter().enumerate() {
                let x = px(ci) + dx;
                if ok(cell.min[ki]) || ok(cell.max[ki]) {
                    let (a, b) = (py(cell.min[ki]), py(if ok(cell.max[ki]) { cell.max[ki] } else { 10f64.powf(hi) }));
                    let _ =
                        write!(s, "<line x1='{x}' y1='{a:.1}' x2='{x}' y2='{b:.1}' stroke='{col}' stroke-width='2'/>");
                }
                if ok(cell.median[ki]) {
                    let _ = write!(s, "<circle cx='{x:.1}' cy='{:.1}' r='4' fill='{col}'/>", py(cell.median[ki]));
                }
                if mi == r.rows.len() - 1 {
                    let _ = write!(
                        s,
                        "<text x='{x:.1}' y='{}' text-anchor='middle' font-size='9' fill='{col}'>{}/{}</text>",
                        bottom - 4.0,
                        cell.covered[ki],
                        r.seeds
                    );
                }
            }
        }
    }
    let _ = write!(
        s,
        "<text x='{}' y='{}' text-anchor='middle'>ISO 8608 road class</text>\
         <text transform='translate(18 {}) rotate(-90)' text-anchor='middle'>relative error (log axis)</text>",
        (left + w - 20.0) / 2.0,
        bottom + 34.0,
        (top + bottom) / 2.0
    );
    for (mi, row) in r.rows.iter().enumerate() {
        let col = COLORS[mi % COLORS.len()];
        let x = left + 380.0 * mi as f64;
        let _ = write!(
            s,
            "<circle cx='{x}' cy='{}' r='4' fill='{col}'/><text x='{}' y='{}'>{}</text>",
            h - 22.0,
            x + 8.0,
            h - 18.0,
            esc(row.label)
        );
    }
    let _ = write!(
        s,
        "<text x='{left}' y='{}' font-size='10' fill='#444'>dashed: 5 %; small numbers: seeds whose 95 % interval holds \
         the truth (real-road identifier)</text>",
        h - 4.0
    );
    s.push_str("</svg>\n");
    s
}

fn md_cell(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

fn verdicts_md(md: &mut String, vs: &[Verdict]) {
    md.push_str("| claim (vehid's, not the thesis') | measured | verdict | note |\n|---|---|---|---|\n");
    for v in vs {
        let _ = writeln!(
            md,
            "| {} | {} | *{}* | {} |",
            md_cell(&v.claim),
            md_cell(&v.measured),
            if v.agrees { "agrees" } else { "differs" },
            md_cell(&v.note)
        );
    }
    md.push('\n');
}

fn worst(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::NEG_INFINITY, |a, b| if b.is_nan() { f64::INFINITY } else { a.max(b) })
}

fn sweep_md(md: &mut String, r: &SweepResult) {
    let _ = writeln!(md, "## Fig {SWEEP_ID}: {}\n\n**{}.**\n\n{}\n", r.title, r.origin, r.setup);
    let _ = writeln!(md, "![Fig {SWEEP_ID}](fig-{SWEEP_ID}.svg)\n");
    let _ = write!(md, "Median ξ [25–75 %] (worst seed) after {} samples, {} seeds:\n\n| method |", r.samples, r.seeds);
    for l in &r.levels {
        let _ = write!(md, " σ_w = {l} % |");
    }
    md.push_str("\n|---|");
    md.push_str(&"---|".repeat(r.levels.len()));
    md.push('\n');
    for c in &r.curves {
        let _ = write!(md, "| {} |", md_cell(c.label));
        for i in 0..r.levels.len() {
            let _ = write!(
                md,
                " {} [{}, {}] ({}) |",
                fmt_num(c.median[i]),
                fmt_num(c.q25[i]),
                fmt_num(c.q75[i]),
                fmt_num(c.max[i])
            );
        }
        md.push('\n');
    }
    md.push('\n');
    for c in &r.curves {
        let refused: u64 = c.refused.iter().sum();
        let errors: usize = c.errors.iter().map(Vec::len).sum();
        let _ = write!(md, "- {}: {}", c.label, md_cell(c.setup));
        if refused > 0 || errors > 0 {
            let _ = write!(md, " — refused {refused} samples; no estimate on {errors} runs");
            if let Some((_, e)) = c.errors.iter().flatten().next() {
                let _ = write!(md, " ({})", md_cell(e));
            }
        }
        md.push('\n');
    }
    md.push('\n');
    verdicts_md(md, &r.verdicts);
}

fn half_md(md: &mut String, r: &HalfResult) {
    let _ = writeln!(md, "## Fig {HALF_ID}: {}\n\n**{}.**\n\n{}\n", r.title, r.origin, r.setup);
    let _ = writeln!(md, "Median (worst) over {} seeds after {} samples:\n", r.seeds, r.samples);
    md.push_str(
        "| method | σ_w | ξ wheel rows 1, 3 | ξ body rows 5, 7 | worst entry (relative error) | no estimate |\n",
    );
    md.push_str("|---|---|---|---|---|---|\n");
    for row in &r.rows {
        for c in &row.cells {
            let none = if c.errors.is_empty() {
                "—".to_string()
            } else {
                format!("{}/{}: {}", c.errors.len(), r.seeds, c.errors[0].1)
            };
            let _ = writeln!(
                md,
                "| {} | {} % | {} ({}) | {} ({}) | {} ({}) | {} |",
                md_cell(row.label),
                c.level,
                fmt_num(median(&c.wheel)),
                fmt_num(worst(&c.wheel)),
                fmt_num(median(&c.body)),
                fmt_num(worst(&c.body)),
                fmt_num(median(&c.worst_entry)),
                fmt_num(worst(&c.worst_entry)),
                md_cell(&none)
            );
        }
    }
    md.push('\n');
    for row in &r.rows {
        let _ = writeln!(md, "- {}: {}", row.label, md_cell(row.setup));
    }
    for (m, why) in &r.not_run {
        let _ = writeln!(md, "- not run, {m}: {}", md_cell(why));
    }
    md.push('\n');
    verdicts_md(md, &r.verdicts);
}

fn roads_md(md: &mut String, r: &RoadsResult) {
    let _ = writeln!(md, "## Fig {ROADS_ID}: {}\n\n**{}.**\n\n{}\n", r.title, r.origin, r.setup);
    let _ = writeln!(md, "![Fig {ROADS_ID}](fig-{ROADS_ID}.svg)\n");
    let _ = write!(
        md,
        "Median (worst seed) relative error, %, and the seeds whose 95 % interval holds the truth, after {} samples, \
         {} seeds per class:\n\n| identifier | class |",
        r.samples, r.seeds
    );
    for (k, t) in r.constants.iter().zip(&r.truth) {
        let _ = write!(md, " {k} (true {}) |", fmt_num(*t));
    }
    md.push_str(" no estimate |\n|---|---|");
    md.push_str(&"---|".repeat(r.constants.len() + 1));
    md.push('\n');
    for row in &r.rows {
        for c in &row.cells {
            let _ = write!(md, "| {} | {} |", md_cell(row.label), c.class);
            for i in 0..r.constants.len() {
                let _ = write!(
                    md,
                    " {} ({}); {}/{} |",
                    fmt_num(100.0 * c.median[i]),
                    fmt_num(100.0 * c.max[i]),
                    c.covered[i],
                    r.seeds
                );
            }
            let none = if c.errors.is_empty() {
                "—".to_string()
            } else {
                format!("{}/{}: {}", c.errors.len(), r.seeds, c.errors[0].1)
            };
            let _ = writeln!(md, " {} |", md_cell(&none));
        }
    }
    md.push('\n');
    for row in &r.rows {
        let _ = writeln!(md, "- {}: {}", row.label, md_cell(row.setup));
    }
    md.push('\n');
    verdicts_md(md, &r.verdicts);
}

/// Fig B-1, B-2 and B-3 of `report` as markdown (the images are `fig-B-1.svg` and
/// `fig-B-3.svg` beside it); `command` is how the report was made.
pub fn markdown(report: &Report, command: &str) -> String {
    let mut md = String::from("# vehid: identifiers for noisy states and real roads (beyond the thesis)\n\n");
    let _ = writeln!(
        md,
        "Generated by `{command}`. Not figures of Kessler (1986): vehid's comparison of its identifiers for noisy \
         states and on real roads. Every number is computed by the run; the claims' `thesis` column in the \
         reproduction report reads \"{NOT_THESIS}\".\n"
    );
    if let Some(r) = &report.sweep {
        sweep_md(&mut md, r);
    }
    if let Some(r) = &report.half_one_road {
        half_md(&mut md, r);
    }
    if let Some(r) = &report.real_roads {
        roads_md(&mut md, r);
    }
    md
}

"""``vehid fleet report``: one static, self-contained HTML page of a fleet store.

The vehicles with events come first (the latest event first), then the others; per vehicle
its events (which constant, when, from what to what, the change and its interval), a small
inline SVG of its tracked ratios against the hours of its logs (its days end to end; each ratio
as its change in % from its first judged value; red lines at the events), the share of its
driving the monitor could not judge, and its problems. No script, no external file: it
opens from a disk or a mail attachment.
"""

from __future__ import annotations

import html
import json
import math
import os
from typing import Any, Dict, List, Tuple

from ..monitor import PARAMETERS
from .store import STATE, StoreError, open_store

_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd")
_STYLE = """
body{font:14px/1.4 system-ui,sans-serif;margin:2em;color:#222}
table{border-collapse:collapse}td,th{border-bottom:1px solid #ddd;padding:4px 8px;vertical-align:top;text-align:left}
th{background:#f4f4f4}.ev{color:#b00}.muted{color:#888}.num{text-align:right}
.legend span{display:inline-block;margin-right:1em}
"""


def _clock(t: float) -> str:
    t = max(0.0, t)
    h, rest = divmod(int(t), 3600)
    return f"{h:02d}:{rest // 60:02d}:{rest % 60:02d}"


def _svg(points: List[Tuple[float, List[Any]]], names: List[str], marks: List[float], breaks: List[float],
         width: int = 260, height: int = 64) -> str:
    """A small line plot against the hours of logs: each series as its change (%) from its
    first finite value; red lines at ``marks`` (events), grey ones at ``breaks`` (a new day)."""
    if not points:
        return '<span class="muted">no trend</span>'
    xs = [p[0] for p in points]
    x0, x1 = min(xs + marks), max(xs + marks)
    series: List[List[Tuple[float, float]]] = []
    for j in range(len(names)):
        first = next((p[1][j] for p in points if p[1][j] is not None), None)
        if first is None or first == 0:
            series.append([])
            continue
        series.append([(x, 100.0 * (v[j] / first - 1.0)) for x, v in points if v[j] is not None])
    ys = [y for s in series for _, y in s] or [0.0]
    lo, hi = min(ys + [-5.0]), max(ys + [5.0])
    sx = (width - 4) / (x1 - x0) if x1 > x0 else 0.0
    sy = (height - 4) / (hi - lo)

    def px(x: float) -> float:
        return round(float(2 + (x - x0) * sx), 1)

    def py(y: float) -> float:
        return round(float(height - 2 - (y - lo) * sy), 1)

    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
             f'viewBox="0 0 {width} {height}" role="img" aria-label="tracked ratios, % change">',
             f'<rect width="{width}" height="{height}" fill="#fafafa"/>',
             f'<line x1="0" x2="{width}" y1="{py(0.0)}" y2="{py(0.0)}" stroke="#bbb" stroke-dasharray="2,2"/>']
    for b in breaks:
        parts.append(f'<line x1="{px(b)}" x2="{px(b)}" y1="0" y2="{height}" stroke="#ccc" stroke-width="1"/>')
    for m in marks:
        parts.append(f'<line x1="{px(m)}" x2="{px(m)}" y1="0" y2="{height}" stroke="#d00" stroke-width="1"/>')
    for j, s in enumerate(series):
        if s:
            pts = " ".join(f"{px(x)},{py(y)}" for x, y in s)
            parts.append(f'<polyline fill="none" stroke="{_COLORS[j % len(_COLORS)]}" stroke-width="1" '
                         f'points="{pts}"><title>{html.escape(names[j])}</title></polyline>')
    parts.append(f'<text x="{width - 2}" y="10" font-size="9" text-anchor="end" fill="#666">'
                 f'{hi:+.0f} %</text><text x="{width - 2}" y="{height - 3}" font-size="9" text-anchor="end" '
                 f'fill="#666">{lo:+.0f} %</text></svg>')
    return "".join(parts)


def _vehicles(store: Any) -> Dict[str, Dict[str, Any]]:
    out: Dict[str, Dict[str, Any]] = {}
    for (vid, day), row in sorted(store.rows.items()):
        s = json.loads(row.summary)
        v = out.setdefault(vid, {"days": [], "events": [], "seconds": 0.0, "cannot": 0.0, "problems": [],
                                 "points": [], "names": [], "marks": [], "status": "", "x": 0.0, "breaks": []})
        v["days"].append(day)
        if s.get("problem") is not None:
            v["problems"].append((day, s["problem"]))
            continue
        # x: hours of the vehicle's logs, the days put end to end (a day from its first sample to its last)
        x0, t0 = v["x"], s["t0"]
        if v["points"]:
            v["breaks"].append(x0)
        v["seconds"] += s["seconds"]
        v["cannot"] += s["status"]["cannot judge"]
        v["status"] = s["end_status"]
        v["names"] = s["trend"]["names"]
        for t, vals in zip(s["trend"]["t"], s["trend"]["values"]):
            v["points"].append((x0 + (t - t0) / 3600.0, vals))
        for ev in s["events"]:
            v["events"].append((day, ev))
            v["marks"].append(x0 + (ev["t"] - t0) / 3600.0)
        v["x"] = x0 + (s["t1"] - t0) / 3600.0
    for vid, day, reason in store.run_problems:
        if vid in out:
            out[vid]["problems"].append((day, reason))
    return out


def render(store_path: str) -> str:
    """The report of the store at ``store_path`` as an HTML page (a string)."""
    if not os.path.exists(os.path.join(store_path, STATE)):
        raise StoreError(f"{store_path}: not a fleet store (no {STATE}): run vehid fleet run DIR --store "
                         f"{store_path} first")
    store = open_store(store_path, states=False)  # the summaries are what the page shows
    vehicles = _vehicles(store)
    with_events = sorted((v for v in vehicles if vehicles[v]["events"]),
                         key=lambda v: (vehicles[v]["events"][-1][0], v), reverse=True)
    ordered = with_events + sorted(v for v in vehicles if not vehicles[v]["events"])
    hours = sum(v["seconds"] for v in vehicles.values()) / 3600.0
    n_events = sum(len(v["events"]) for v in vehicles.values())
    esc = html.escape
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8"><title>vehid fleet report</title>',
           f"<style>{_STYLE}</style></head><body>", "<h1>Fleet suspension health</h1>",
           f'<p id="summary">{len(vehicles)} vehicles, {len(store.rows)} vehicle-days, {hours:.1f} vehicle-hours; '
           f"{n_events} events on {len(with_events)} vehicles; {len(store.problems_table())} problems. "
           f"Store: <code>{esc(store_path)}</code>.</p>",
           "<p>Trend: each tracked ratio (quarter car: k2/M, b/M; half and full car: each corner's spring and damper "
           "coefficient) as its change in % from its first judged value, against the hours of the vehicle's logs "
           "(its days end to end, grey lines between them); red lines: events. <em>Cannot judge</em>: the share "
           "of the driving time the monitor could not judge (too little excitation, missing or stuck data).</p>",
           '<table id="vehicles"><thead><tr><th>vehicle</th><th>days</th><th class="num">hours</th>'
           '<th>events</th><th>trend</th><th class="num">cannot judge</th><th>now</th></tr></thead><tbody>']
    for vid in ordered:
        v = vehicles[vid]
        evs = []
        for day, ev in v["events"]:
            name, unit = PARAMETERS.get(ev["parameter"], (ev["parameter"], ""))
            evs.append(f'<div class="ev">{esc(day)} {_clock(ev["t"])}: <b>{esc(ev["parameter"])}</b> '
                       f'({esc(name)}) {ev["before"]:.5g} → {ev["after"]:.5g} {esc(unit)} '
                       f'({100 * ev["change"]:+.1f} %; 95 % {ev["low"]:.5g}..{ev["high"]:.5g})</div>')
        for day, reason in v["problems"]:
            evs.append(f'<div class="muted">problem {esc(day)}: {esc(reason)}</div>')
        share = v["cannot"] / v["seconds"] if v["seconds"] > 0 else math.nan
        days = f'{esc(v["days"][0])} … {esc(v["days"][-1])} ({len(v["days"])})'
        out.append(f'<tr data-vehicle="{esc(vid)}" data-events="{len(v["events"])}"><td>{esc(vid)}</td>'
                   f'<td>{days}</td><td class="num">{v["seconds"] / 3600:.2f}</td>'
                   f'<td>{"".join(evs) or "<span class=muted>none</span>"}</td>'
                   f'<td>{_svg(v["points"], v["names"], v["marks"], v["breaks"])}</td>'
                   f'<td class="num">{"–" if math.isnan(share) else f"{100 * share:.1f} %"}</td>'
                   f'<td>{esc(v["status"])}</td></tr>')
    out.append("</tbody></table>")
    probs = store.problems_table().to_pylist()
    out.append(f"<h2>Problems ({len(probs)})</h2>")
    if probs:
        out.append('<table id="problems"><thead><tr><th>vehicle</th><th>day</th><th>reason</th></tr></thead><tbody>')
        out += [f"<tr><td>{esc(p['vehicle'])}</td><td>{esc(p['day'])}</td><td>{esc(p['reason'])}</td></tr>"
                for p in probs]
        out.append("</tbody></table>")
    else:
        out.append("<p>None.</p>")
    out.append("</body></html>")
    return "\n".join(out)


def report(store_path: str, output: str) -> int:
    """Writes the report of the store at ``store_path`` to the file ``output``; returns the
    number of vehicles listed."""
    page = render(store_path)
    with open(output, "w", encoding="utf-8") as f:
        f.write(page)
    return page.count("<tr data-vehicle=")

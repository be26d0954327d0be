"""`vehid fleet report` rendered by a real browser: headless Chromium driven by Playwright.

What `test_fleet.py` checks with Python's HTML parser (every element closed, the rows in
order, every event's text) says that the page is well formed; this test says that a browser
shows it: the browser's own parser builds the same table (one row per vehicle, in order, none
moved out by error recovery), the page asks for nothing beyond itself (no request, no console
message), every vehicle's row and every event's text is laid out with a size, each trend plot
is drawn at its size with every line inside its frame, and one red line per event.

Chromium comes from the system (Debian's `chromium`, which `make test` installs when it runs as
root: `make browser`); Playwright (PyPI) drives it through its own executable, so nothing is
downloaded by Playwright itself. Without either the test is skipped, saying which is missing.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any, Dict, List

import pytest
from fleet_helpers import make_fleet, store_tables

import vehid.fleet as fleet
from vehid.cli import main

sync_api = pytest.importorskip("playwright.sync_api", reason="Playwright is not installed (make venv installs it)")


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("no Chromium on PATH: `make browser` installs Debian's (as root), or put one on PATH")


# Measured in the browser: the vehicle rows as laid out, each row's trend plot (its drawn size,
# its viewBox, the bounding box of every line and polyline in the plot's own units) and the
# count of red lines (events).
_MEASURE = """() => {
  const rows = [...document.querySelectorAll('#vehicles > tbody > tr')];
  return rows.map(tr => {
    const r = tr.getBoundingClientRect();
    const svg = tr.querySelector('svg');
    const out = {vehicle: tr.dataset.vehicle, events: Number(tr.dataset.events), w: r.width, h: r.height,
                 text: tr.innerText, svg: null};
    if (svg) {
      const b = svg.getBoundingClientRect();
      const vb = svg.viewBox.baseVal;
      const shapes = [...svg.querySelectorAll('line, polyline')].map(e => {
        const bb = e.getBBox();
        return {tag: e.tagName, stroke: e.getAttribute('stroke'), x: bb.x, y: bb.y, w: bb.width, h: bb.height};
      });
      out.svg = {w: b.width, h: b.height, vb: [vb.x, vb.y, vb.width, vb.height], shapes};
    }
    return out;
  });
}"""


def test_report_renders_in_a_headless_browser(tmp_path: Path) -> None:
    src = make_fleet(tmp_path / "fleet")
    store = tmp_path / "store"
    fleet.run(str(src), str(store), workers=1)
    page_path = tmp_path / "report.html"
    assert main(["fleet", "report", str(store), "-o", str(page_path)]) == 0
    events = store_tables(store)["events"].to_pylist()
    vehicles = sorted({r["vehicle"] for r in store_tables(store)["state"].to_pylist()})
    url = page_path.resolve().as_uri()

    requests: List[str] = []
    messages: List[str] = []
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=_chromium(), args=["--no-sandbox"] if os.geteuid() == 0 else [])
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.on("request", lambda r: requests.append(r.url))
            page.on("console", lambda m: messages.append(f"{m.type}: {m.text}"))
            page.on("pageerror", lambda e: messages.append(f"error: {e}"))
            page.goto(url, wait_until="load")
            rows: List[Dict[str, Any]] = page.evaluate(_MEASURE)
            page.screenshot(path=str(tmp_path / "report.png"), full_page=True)
        finally:
            browser.close()

    assert requests == [url], requests  # the page itself, nothing else
    assert messages == []
    # The browser's table: every vehicle once, those with events first, as the store says.
    assert sorted(r["vehicle"] for r in rows) == vehicles
    flags = [r["events"] > 0 for r in rows]
    assert flags == sorted(flags, reverse=True) and any(flags) and not all(flags)
    for r in rows:
        mine = [e for e in events if e["vehicle"] == r["vehicle"]]
        assert r["events"] == len(mine)
        assert r["w"] > 0 and r["h"] > 0, r["vehicle"]
        for e in mine:
            assert f"{e['before']:.5g} → {e['after']:.5g}" in r["text"], (r["vehicle"], e)
        # The trend plot: drawn at its size, every line inside its frame, one red line per event.
        svg = r["svg"]
        assert svg is not None, r["vehicle"]
        x0, y0, vw, vh = svg["vb"]
        assert (svg["w"], svg["h"]) == (vw, vh) and vw > 0 and vh > 0
        tol = 1e-3
        for s in svg["shapes"]:
            assert x0 - tol <= s["x"] and s["x"] + s["w"] <= x0 + vw + tol, (r["vehicle"], s)
            assert y0 - tol <= s["y"] and s["y"] + s["h"] <= y0 + vh + tol, (r["vehicle"], s)
        assert sum(s["stroke"] == "#d00" for s in svg["shapes"]) == len(mine), r["vehicle"]
        # A drawn trend for every vehicle that was judged at all (a polyline with extent).
        assert any(s["tag"] == "polyline" and s["w"] > 0 for s in svg["shapes"]), r["vehicle"]
    assert (tmp_path / "report.png").stat().st_size > 0

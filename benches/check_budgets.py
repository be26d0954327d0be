"""Every performance budget of ``benches/budgets.toml`` against the measured figure and the C loop.

Reads

* criterion's estimates, ``<dir>/<group>/<bench>/new/estimates.json`` (the slope estimate when
  criterion has one, else the mean: the figure ``cargo bench`` prints), from the last
  ``cargo bench -p vehid-benches --bench identify`` (``target/criterion``; the file's age is
  printed) or, with ``--criterion DIR`` given several times, the best of several such runs
  (``make bench-budgets`` keeps a copy of each of its ``BUDGET_RUNS`` runs: on a shared
  machine a slow spell of another tenant can inflate one run by a third, never deflate it);
* the Python overhead figures of ``benches/python/overhead.py --json`` (default
  ``target/bench/python_overhead.json``; measured now, with fewer samples, if that file is
  missing);
* the plain C RLS loop (``benches/peers/rls.c``, ``cc -O3 -march=native``) timed now on seeded
  vehid data (rows and shared, quarter and half car), or taken from ``--c-json`` (the
  ``c_reference_ns`` of ``make bench-peers``'s ``target/peers/peers.json``);

and prints each budget with the measured figure, the verdict and the ratio of the figure to
the C loop's ns per sample (for the throughput budgets: the figure's ns per sample over the
C loop's). It exits 0 whatever the verdicts — the numbers are reported, not asserted — unless
``--strict``, with which a miss (or a missing figure) exits 1.

Run: ``make bench-budgets`` (refreshes the criterion benches the budgets use and the Python
figures, then runs this) or ``.venv/bin/python benches/check_budgets.py [--strict]``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import subprocess
import sys
from pathlib import Path
from typing import Dict, List, Optional

import tomllib

ROOT = Path(__file__).resolve().parent.parent
BENCHES = ROOT / "benches"
CRITERION = ROOT / "target" / "criterion"
PY_JSON = ROOT / "target" / "bench" / "python_overhead.json"


def best_criterion_ns(key: str, roots: List[Path]) -> Optional[dict]:
    """The smallest figure of ``key`` over several criterion output directories."""
    figs = [f for f in (criterion_ns(key, r) for r in roots) if f is not None]
    if not figs:
        return None
    best = min(figs, key=lambda f: f["ns"])
    if len(figs) > 1:
        spread = max(f["ns"] for f in figs) / best["ns"]
        best = dict(best, **{"from": f"criterion, best of {len(figs)} runs (max/min {spread:.2f})"})
    return best


def criterion_ns(key: str, root: Path = CRITERION) -> Optional[dict]:
    """ns per iteration of criterion bench ``group/bench`` and the age of its estimate."""
    path = root.joinpath(*key.split("/"), "new", "estimates.json")
    if not path.exists():
        return None
    est = json.loads(path.read_text())
    stat = est.get("slope") or est["mean"]
    age = dt.datetime.now() - dt.datetime.fromtimestamp(path.stat().st_mtime)
    return {"ns": float(stat["point_estimate"]), "from": f"criterion, {age.total_seconds() / 60:.0f} min old"}


def python_figures(path: Path, measure: bool) -> Optional[dict]:
    if measure or not path.exists():
        print(f"measuring the Python figures (benches/python/overhead.py --json {path.relative_to(ROOT)}) ...")
        subprocess.run([sys.executable, str(BENCHES / "python" / "overhead.py"), "--n", "300000", "--calls", "50000",
                        "--repeats", "5", "--json", str(path)], check=True, stdout=subprocess.DEVNULL)
    return json.loads(path.read_text()) if path.exists() else None


def c_reference(c_json: Optional[Path]) -> Dict[str, float]:
    if c_json is not None:
        return {k: float(v) for k, v in json.loads(c_json.read_text())["c_reference_ns"].items()}
    sys.path.insert(0, str(BENCHES / "peers"))
    import crls  # noqa: E402  (needs numpy and vehid: run with .venv/bin/python)

    return crls.reference_ns()


def evaluate(budget: dict, figure_ns: Optional[float], c_ns: Dict[str, float]) -> dict:
    """One budget's row: measured value in its unit, verdict, ratio to the C loop."""
    row = {"name": budget["name"], "unit": budget["unit"], "c_ref": budget["c_ref"]}
    limit = budget.get("max", budget.get("min"))
    row["budget"] = ("≤ " if "max" in budget else "≥ ") + _fmt(limit, budget["unit"])
    if figure_ns is None:
        row.update(measured="—", verdict="NO FIGURE", ratio=None, ok=False)
        return row
    if budget["unit"] == "samples/s":
        value = 1e9 / figure_ns
        ok = value >= budget["min"]
    else:
        value = figure_ns
        ok = value <= budget["max"]
    c = c_ns.get(budget["c_ref"])
    row.update(measured=_fmt(value, budget["unit"]), ns=figure_ns, verdict="ok" if ok else "MISS",
               ratio=None if c is None else figure_ns / c, c_ns=c, ok=ok)
    return row


def _fmt(value: float, unit: str) -> str:
    if unit == "samples/s":
        return f"{value / 1e6:.1f} M/s"
    return f"{value:.1f} ns" if value < 10_000 else f"{value / 1000:.1f} µs"


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budgets", type=Path, default=BENCHES / "budgets.toml")
    ap.add_argument("--criterion", type=Path, action="append", default=None,
                    help="criterion's output directory (repeat: the best figure over the runs)")
    ap.add_argument("--python-json", type=Path, default=PY_JSON)
    ap.add_argument("--measure-python", action="store_true", help="re-measure the Python figures")
    ap.add_argument("--c-json", type=Path, default=None, help="take the C figures from a bench-peers JSON")
    ap.add_argument("--strict", action="store_true", help="exit 1 on a missed budget or a missing figure")
    args = ap.parse_args(argv)

    budgets = tomllib.loads(args.budgets.read_text())["budget"]
    roots = args.criterion or [CRITERION]
    py = python_figures(args.python_json, args.measure_python)
    c_ns = c_reference(args.c_json)
    print("C loop (rls.c, ns/sample): " + ", ".join(f"{k} {v:.2f}" for k, v in c_ns.items())
          + (f"  (from {args.c_json})" if args.c_json else "  (timed now, 200000 samples, best of 7)"))

    rows = []
    for b in budgets:
        if b["source"] == "criterion":
            fig = best_criterion_ns(b["key"], roots)
            ns, src = (fig["ns"], fig["from"]) if fig else (None, "no criterion estimate: run cargo bench")
        else:
            ns = None if py is None or b["key"] not in py else float(py[b["key"]]) * float(b.get("scale", 1.0))
            src = "overhead.py" if ns is not None else "no Python figure"
        row = evaluate(b, ns, c_ns)
        row["from"] = src
        rows.append(row)

    print(f"\n{'budget':<36} {'limit':>11} {'measured':>11} {'verdict':>8} {'÷ C loop':>9}  C ref (ns)      source")
    for r in rows:
        ratio = "—" if r["ratio"] is None else f"{r['ratio']:.2f}"
        c = "—" if r.get("c_ns") is None else f"{r['c_ref']} {r['c_ns']:.1f}"
        print(f"{r['name']:<36} {r['budget']:>11} {r['measured']:>11} {r['verdict']:>8} {ratio:>9}  "
              f"{c:<15} {r['from']}")
    missed = [r["name"] for r in rows if not r["ok"]]
    print(f"\n{len(rows) - len(missed)} of {len(rows)} budgets met"
          + (f"; missed: {', '.join(missed)}" if missed else ""))
    return 1 if (args.strict and missed) else 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The budget report (benches/check_budgets.py): the budgets file and the per-budget verdicts.

Not a timed test: the figures are fed in; `make bench-budgets` measures them.
"""

from __future__ import annotations

import json

import pytest
import tomllib
from bench_scripts import ROOT, load  # tests/ is on sys.path under pytest

cb = load("check_budgets")
BUDGETS = {b["name"]: b for b in tomllib.loads((ROOT / "benches" / "budgets.toml").read_text())["budget"]}
C_NS = {"quarter_rows": 25.0, "half_rows": 100.0, "quarter_shared": 10.0, "half_shared": 40.0}


def test_budgets_file_has_the_issue_limits():
    limits = {name: b.get("max", b.get("min")) for name, b in BUDGETS.items()}
    assert limits["rows update, quarter car (f64)"] == 20.0
    assert limits["rows update, half car (f64)"] == 60.0
    assert limits["shared update, quarter car (f64)"] == 12.0
    assert limits["shared update, half car (f64)"] == 35.0
    assert limits["Python fit(), quarter car"] == 20e6
    assert limits["one Python update(), quarter car"] == 1000.0
    assert limits["simulator, quarter car, exact"] == 10e6
    assert all(b["c_ref"] in C_NS for b in BUDGETS.values())


def test_time_budget_and_c_ratio():
    b = BUDGETS["rows update, quarter car (f64)"]
    row = cb.evaluate(b, 18.0, C_NS)
    assert row["ok"] and row["verdict"] == "ok"
    assert row["ratio"] == pytest.approx(18.0 / 25.0)
    assert not cb.evaluate(b, 21.0, C_NS)["ok"]


def test_throughput_budget_is_a_minimum():
    b = BUDGETS["Python fit(), quarter car"]
    assert cb.evaluate(b, 49.0, C_NS)["ok"]  # 20.4 M samples/s
    row = cb.evaluate(b, 51.0, C_NS)  # 19.6 M samples/s
    assert not row["ok"] and row["verdict"] == "MISS"
    assert row["ratio"] == pytest.approx(51.0 / 25.0)


def test_missing_figure_is_a_miss():
    row = cb.evaluate(BUDGETS["simulator, quarter car, exact"], None, C_NS)
    assert not row["ok"] and row["verdict"] == "NO FIGURE"


def test_reads_criterion_estimates(tmp_path):
    d = tmp_path / "update_f64" / "quarter_kalman_rows" / "new"
    d.mkdir(parents=True)
    (d / "estimates.json").write_text(json.dumps({"mean": {"point_estimate": 20.5}, "slope": {"point_estimate": 19.5}}))
    assert cb.criterion_ns("update_f64/quarter_kalman_rows", tmp_path)["ns"] == 19.5
    (d / "estimates.json").write_text(json.dumps({"mean": {"point_estimate": 20.5}, "slope": None}))
    assert cb.criterion_ns("update_f64/quarter_kalman_rows", tmp_path)["ns"] == 20.5
    assert cb.criterion_ns("update_f64/nothing", tmp_path) is None


def test_best_of_several_criterion_runs(tmp_path):
    for run, ns in (("1", 26.0), ("2", 21.0), ("3", 23.0)):
        d = tmp_path / run / "update_f64" / "quarter_kalman_rows" / "new"
        d.mkdir(parents=True)
        (d / "estimates.json").write_text(json.dumps({"mean": {"point_estimate": ns}, "slope": None}))
    roots = [tmp_path / r for r in ("1", "2", "3", "missing")]
    best = cb.best_criterion_ns("update_f64/quarter_kalman_rows", roots)
    assert best["ns"] == 21.0 and "best of 3 runs" in best["from"] and "1.24" in best["from"]
    assert cb.best_criterion_ns("update_f64/quarter_kalman_rows", roots[1:2])["ns"] == 21.0
    assert cb.best_criterion_ns("update_f64/nothing", roots) is None

"""The regression gate's comparison (benches/callgrind_check.py), against doctored baselines.

Unit tests of the pure comparison, plus one real callgrind count of one bench (skipped without
valgrind or cargo) showing that the gate fails against a baseline 10 % below what it measures —
what a build slowed by 10 % would look like — and passes against the count itself. The counts
are of the binary in the profile `make test` builds (unoptimized benches: the numbers are not
release's); `make bench-check` compares release's with the checked-in baseline. Speed is not
asserted here.
"""

from __future__ import annotations

import json
import shutil

import pytest
from bench_scripts import ROOT, load  # tests/ is on sys.path under pytest

cc = load("callgrind_check")
MEASURED = {"quarter_rows": 473.3, "half_rows": 2191.1, "quarter_sim_exact": 681.8}


def scaled(factor: float) -> dict:
    return {k: v * factor for k, v in MEASURED.items()}


def test_identical_baseline_passes():
    rows = cc.compare(MEASURED, dict(MEASURED))
    assert cc.passed(rows)
    assert {r.status for r in rows} == {"ok"}


def test_baseline_ten_percent_lower_fails():
    # A build that executes 10 % more instructions than the baseline.
    rows = cc.compare(MEASURED, scaled(1 / 1.10))
    assert not cc.passed(rows)
    assert {r.status for r in rows} == {"REGRESSION"}


def test_one_regression_is_enough():
    base = dict(MEASURED)
    base["half_rows"] = MEASURED["half_rows"] / 1.06
    rows = cc.compare(MEASURED, base)
    assert not cc.passed(rows)
    assert [r.bench for r in rows if r.failed] == ["half_rows"]


def test_growth_within_tolerance_passes():
    assert cc.passed(cc.compare(MEASURED, scaled(1 / 1.049)))
    assert not cc.passed(cc.compare(MEASURED, scaled(1 / 1.051)))


def test_tolerance_is_a_parameter():
    assert cc.passed(cc.compare(MEASURED, scaled(1 / 1.10), tolerance=0.15))


def test_faster_passes_with_a_hint():
    rows = cc.compare(MEASURED, scaled(1.2))
    assert cc.passed(rows)
    assert {r.status for r in rows} == {"faster"}
    assert "--update" in cc.format_table(rows)


def test_missing_baseline_fails_and_unmeasured_entry_passes():
    base = dict(MEASURED)
    del base["quarter_rows"]
    base["half_shared"] = 785.4
    rows = {r.bench: r for r in cc.compare(MEASURED, base)}
    assert rows["quarter_rows"].status == "NO BASELINE"
    assert rows["half_shared"].status == "not measured"
    assert not cc.passed(list(rows.values()))
    assert cc.passed(cc.compare({"half_rows": 2191.1}, dict(MEASURED)))


def test_checked_in_baseline_covers_every_key_bench():
    base = json.loads((ROOT / "benches" / "callgrind_baseline.json").read_text())
    assert set(base["counts"]) == set(cc.BENCHES)
    assert base["tolerance"] == 0.05
    assert all(v > 0 for v in base["counts"].values())


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
@pytest.mark.skipif(shutil.which("cargo") is None, reason="cargo is not installed")
def test_real_count_against_doctored_baseline(tmp_path, capsys):
    base = json.loads((ROOT / "benches" / "callgrind_baseline.json").read_text())
    exe = cc.build_bins(["count_updates"], timeout=3600)["count_updates"]
    n = 2_000
    count = cc.per_update(exe, "quarter_rows", n)
    # The counts measure the work: the half car's update (four rows of eight parameters) costs
    # several times the quarter car's (two rows of four): 4.6x in release, 4.7x here.
    assert cc.per_update(exe, "half_rows", n) > 3 * count > 0
    slowed = dict(base, n_updates=n, counts={"quarter_rows": count * 0.90})
    same = dict(base, n_updates=n, counts={"quarter_rows": count})
    (tmp_path / "slowed.json").write_text(json.dumps(slowed))
    (tmp_path / "same.json").write_text(json.dumps(same))
    argv = ["--bench", "quarter_rows", "--no-build", "--binary", str(exe)]
    assert cc.main(argv + ["--baseline", str(tmp_path / "slowed.json")]) == 1
    assert "REGRESSION" in capsys.readouterr().out
    assert cc.main(argv + ["--baseline", str(tmp_path / "same.json")]) == 0
    assert "bench-check: ok" in capsys.readouterr().out

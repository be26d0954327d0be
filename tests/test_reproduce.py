"""`vehid reproduce`: one figure per chapter end to end through the CLI (tiny iteration
counts), and the report's numbers are computed from the seed, not copied."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

import vehid
from vehid.cli import main

ONE_PER_CHAPTER = "3-5,4-2,5-1,6-3"


def _reproduce(tmp_path: Path, seed: int, capsys: pytest.CaptureFixture[str]) -> Path:
    out = tmp_path / f"report-{seed}"
    argv = ["reproduce", "--quick", "--only", ONE_PER_CHAPTER, "--out", str(out), "--seed", str(seed),
            "--seeds", "3", "--max-iterations", "400", "--no-tables", "--quiet"]
    assert main(argv) == 0
    printed = capsys.readouterr().out.strip()
    assert Path(printed) == out / "index.md"
    return out


def test_reproduce_writes_a_report_with_verdicts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = _reproduce(tmp_path, 1, capsys)
    md = (out / "index.md").read_text(encoding="utf-8")
    for fig in ONE_PER_CHAPTER.split(","):
        assert f"### Fig {fig}:" in md
    marks = re.findall(r"\*(agrees|differs)\*", md)
    assert len(marks) >= 4
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "<html>" in html and ("agrees" in html or "differs" in html)
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        assert "matplotlib is not installed" in md
    else:
        assert (out / "fig-4-2.png").stat().st_size > 1000
        assert "fig-4-2.png" in html


def test_reproduce_numbers_follow_the_seed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = json.loads((_reproduce(tmp_path, 1, capsys) / "report.json").read_text(encoding="utf-8"))
    b = json.loads((_reproduce(tmp_path, 2, capsys) / "report.json").read_text(encoding="utf-8"))
    measured_a = [v["measured"] for f in a["figures"] for v in f["verdicts"]]
    measured_b = [v["measured"] for f in b["figures"] for v in f["verdicts"]]
    assert measured_a != measured_b
    finals_a = [c["final_xi"] for f in a["figures"] for c in f["curves"]]
    finals_b = [c["final_xi"] for f in b["figures"] for c in f["curves"]]
    assert all(x != y for x, y in zip(finals_a, finals_b))


def test_reproduce_run_api_and_errors() -> None:
    data = vehid.reproduce.run(quick=True, only=["4-7", "6-9"], seeds=1, max_iterations=50, tables=False)
    ids = [f["id"] for f in data["figures"]]
    assert ids == ["4-7", "6-9"]
    assert data["figures"][0]["curves"] == []  # analytic figure
    assert len(data["figures"][1]["curves"]) == 3 and data["figures"][1]["skipped"] is None
    with pytest.raises(ValueError, match="only"):
        vehid.reproduce.run(quick=True, only=["9-9"], tables=False)


def test_reproduce_cli_rejects_bad_arguments(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["reproduce", "--only", "9-9", "--out", "/nonexistent/never", "--quiet"]) == 2
    assert "only" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["reproduce", "--seeds", "0"])

"""The `vehid` command line."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import vehid
from vehid import cli, clitools


def test_simulate_writes_the_documented_columns(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    argv = ["simulate", "--model", "half", "--n", "300", "--state-noise", "0.01", "--seed", "3", "-o", str(out)]
    assert cli.main(argv) == 0
    header = out.read_text().splitlines()[0].split(",")
    n, m = 8, 2
    assert header == (
        ["t"]
        + [f"x{i}" for i in range(1, n + 1)]
        + [f"dx{i}" for i in range(1, n + 1)]
        + [f"true_x{i}" for i in range(1, n + 1)]
        + [f"true_dx{i}" for i in range(1, n + 1)]
        + [f"u{j}" for j in range(1, m + 1)]
    )
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    run = vehid.Simulator(vehid.HalfCar(), road_sigma=0.1, state_noise=0.01, deriv_noise=0.005, seed=3).run(300)
    # Text round trip is exact (shortest repr of each float64).
    expected = np.column_stack([run.t, run.r, run.z, run.x, run.xdot, run.u])
    assert np.array_equal(data, expected)


def test_simulate_to_stdout_in_chunks(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(clitools, "CHUNK", 7)
    monkeypatch.setattr(clitools, "PROGRESS_ABOVE", 10)
    assert cli.main(["simulate", "--model", "quarter", "--n", "20", "-o", "-"]) == 0
    captured = capsys.readouterr()
    lines = captured.out.splitlines()
    assert len(lines) == 21 and lines[0].startswith("t,x1,x2,x3,x4,dx1")
    # Chunked output is the same stream as one run.
    data = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    run = vehid.Simulator(vehid.QuarterCar(), seed=1).run(20)
    assert np.array_equal(data[:, 1:5], run.r)
    assert "simulated 20/20 samples" in captured.err


def test_simulate_reports_bad_values(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["simulate", "--model", "quarter", "--road-sigma", "-1", "-o", "-"]) == 2
    assert "road_sigma" in capsys.readouterr().err


def test_demo_prints_the_three_standard_deviations(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["demo", "--n", "4000"]) == 0
    out = capsys.readouterr().out
    assert "Eq 4.27" in out
    rows = [line for line in out.splitlines() if line.startswith(("x1", "x2", "x3", "x4"))]
    # The states are named as the CSV columns of `vehid simulate` are (x2 is the wheel velocity).
    assert [r[:26].rstrip() for r in rows] == [
        "x1 (wheel_pos, m)", "x2 (wheel_vel, m/s)", "x3 (body_pos, m)", "x4 (body_vel, m/s)"]
    analytic = [float(r.split()[-2]) for r in rows]
    np.testing.assert_allclose(analytic, vehid.QuarterCar().sampled_std(0.1, 0.05, method="exact"), rtol=1e-4)


def test_python_dash_m_entry_point() -> None:
    done = subprocess.run([sys.executable, "-m", "vehid", "--version"], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == f"vehid {vehid.__version__}"

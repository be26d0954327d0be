"""The full car on the command line: `vehid simulate --model full` (a drive on two ISO 8608
tracks, its changes and point loads) and `vehid identify --model full` (road cancellation on
both tracks, the physical constants with their intervals); a drive's true constants read by
`vehid identify` (the truth, and the wheel masses)."""

import json
from pathlib import Path

import numpy as np
import pytest

import vehid
from vehid import cli

PASSENGER = vehid.FullCar.passenger().params


def test_simulate_then_identify_the_full_car(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # 100 s of state sensors at 20 m/s (0.1 m per sample: 31 samples between the axles), then
    # road cancellation on both tracks from the exact start: every spring, damper, M, Jx and Jy
    # within 1 % and inside its 95 % interval; the four wheel masses default to the passenger
    # car's 59 kg, and --m-fl overrides one.
    csv = tmp_path / "full.csv"
    assert cli.main(["simulate", "--model", "full", "--road", "iso8608-C", "--sensors", "state", "--speed", "20",
                     "--n", "20000", "--seed", "5", "-o", str(csv)]) == 0
    header = csv.read_text().splitlines()[0].split(",")
    assert header[1:3] == ["z_fl", "v_fl"] and header[-25:] == [f"true_{c}" for c in vehid.FullCar.CONSTANTS]
    capsys.readouterr()
    assert cli.main(["identify", str(csv), "--model", "full", "--method", "two-axle", "--spacing", "0.1",
                     "--json"]) == 0
    captured = capsys.readouterr()
    report = json.loads(captured.out)
    assert report["options"]["p0"] == "exact" and report["known"] == {f"m_{c}": 59.0 for c in ("fl", "fr", "rl", "rr")}
    # The drive's true constants are the truth (xi) and give the wheel masses, with a note.
    assert report["truth"]["source"] == "the file's true_* constants" and report["xi"] < 1e-3, report["xi"]
    assert "m_fl = 59 kg from the file's true_* constants" in captured.err and "ignoring" not in captured.err
    intervals = report["physical_intervals"]
    for name in ["M", "Jx", "Jy"] + [f"{k}_{c}" for k in ("k", "b") for c in ("fl", "fr", "rl", "rr")]:
        value, low, high = intervals[name]
        truth = PASSENGER[name]
        assert abs(value / truth - 1) < 0.01 and low < truth < high, (name, value, low, high)
    assert cli.main(["identify", str(csv), "--model", "full", "--method", "two-axle", "--spacing", "0.1",
                     "--m-fl", "60"]) == 0
    out = capsys.readouterr().out
    assert "known: m_fl = 60 kg, m_fr = 59 kg" in out and "delta method" in out
    assert "b_fl = " in out and "N s/m" in out
    # The spacing must put the rear axle over an earlier sample point.
    assert cli.main(["identify", str(csv), "--model", "full", "--method", "two-axle", "--spacing", "0.075"]) == 2
    assert "does not divide the wheelbase" in capsys.readouterr().err


def test_a_drive_with_a_boot_load_and_its_monitor(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # --change T:load=KG,load_x=X,load_y=Y sets a point load down; vehid monitor names it with
    # its place. --car thesis has no full car.
    csv = tmp_path / "boot.csv"
    assert cli.main(["simulate", "--model", "full", "--road", "iso8608-C", "--n", "18000", "--seed", "6",
                     "--change", "40:load=100,load_x=-2.5", "-o", str(csv)]) == 0
    header = csv.read_text().splitlines()[0].split(",")
    m_col = np.loadtxt(csv, delimiter=",", skiprows=1, usecols=[header.index("true_M")])
    assert m_col[0] == 1500.0 and m_col[-1] == 1600.0
    capsys.readouterr()
    assert cli.main(["monitor", str(csv), "--model", "full", "--json"]) == 0
    events = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(events) == 1 and events[0]["parameter"] == "M", events
    assert abs(events[0]["after"] - 1600.0) < 45.0 and abs(events[0]["load_x"] + 2.5) < 0.5, events
    assert cli.main(["simulate", "--model", "full", "--road", "iso8608-C", "--car", "thesis", "--n", "10",
                     "-o", str(tmp_path / "x.csv")]) == 2
    assert "no full car" in capsys.readouterr().err


def test_a_quarter_car_drive_gives_its_wheel_mass(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A quarter-car drive (state sensors, class C, 100 s at 15 m/s): its true_m = 40 kg is the
    # known wheel mass, where the thesis car's 1 kg made every constant 1/40 of the truth; a
    # drive with a --change has no single truth (no xi), said in a note.
    csv = tmp_path / "q.csv"
    assert cli.main(["simulate", "--model", "quarter", "--road", "iso8608-C", "--sensors", "state", "--n", "20000",
                     "--seed", "8", "-o", str(csv)]) == 0
    capsys.readouterr()
    assert cli.main(["identify", str(csv), "--model", "quarter", "--road", "iso8608", "--speed", "15",
                     "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["known"] == {"m": 40.0} and report["truth"]["constants"]["M"] == 320.0
    for name in ("M", "k1", "k2", "b"):
        value, low, high = report["physical_intervals"][name]
        truth = report["truth"]["constants"][name]
        assert abs(value / truth - 1) < 0.15 and low < truth < high, (name, value, low, high)
    changed = tmp_path / "changed.csv"
    assert cli.main(["simulate", "--model", "quarter", "--road", "iso8608-C", "--sensors", "state", "--n", "4000",
                     "--change", "10:b=1350", "--seed", "8", "-o", str(changed)]) == 0
    capsys.readouterr()
    assert cli.main(["identify", str(changed), "--model", "quarter", "--json"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["xi"] is None and "true constants change during the run" in captured.err

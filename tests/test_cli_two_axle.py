"""`vehid simulate --speed` and `vehid identify --method two-axle` end to end."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

import vehid


def vehid_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "vehid", *args], capture_output=True, text=True, check=False)


def test_simulate_by_distance_then_identify_with_road_cancellation(tmp_path: Path) -> None:
    csv = tmp_path / "half.csv"
    done = vehid_cli("simulate", "--model", "half", "--n", "20000", "--speed", "6", "--spacing", "0.3",
                     "--seed", "3", "-o", str(csv))
    assert done.returncode == 0, done.stderr
    header = csv.read_text().splitlines()[0].split(",")
    assert header[-1] == "s"
    s = np.loadtxt(csv, delimiter=",", skiprows=1, usecols=[len(header) - 1])
    assert np.allclose(np.diff(s), 0.3)  # one sample every 0.3 m
    results = {}
    for method in ["none", "cancel"]:
        out = vehid_cli("identify", str(csv), "--model", "half", "--method", "two-axle", "--wheel-method", method,
                        "--json")
        assert out.returncode == 0, out.stderr
        results[method] = json.loads(out.stdout)
    theta = np.array(results["cancel"]["theta"])
    # The same estimate as the Python API on the same samples.
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    n = 8
    two = vehid.TwoAxleIdentifier(vehid.HalfCar(), spacing=0.3, method="cancel", p0=1000.0, road_sigma=0.1,
                                  deriv_noise=0.005)
    two.fit(data[:, 1 : 1 + n], data[:, 1 + n : 1 + 2 * n])
    assert np.array_equal(theta, two.theta)
    assert results["cancel"]["xi"] < 0.05 < results["none"]["xi"]


def test_two_axle_needs_the_half_car(tmp_path: Path) -> None:
    csv = tmp_path / "q.csv"
    assert vehid_cli("simulate", "--model", "quarter", "--n", "100", "-o", str(csv)).returncode == 0
    out = vehid_cli("identify", str(csv), "--model", "quarter", "--method", "two-axle")
    assert out.returncode == 2 and "--model half" in out.stderr

"""Python and Rust give the same θ̂, bit for bit, for the same seed.

The Rust side is ``benches/src/bin/theta_golden.rs`` (vehid-core used directly, fixed-size
``KalmanIdentifier<f64, 4, 2>``); the Python side goes through ``Simulator.run`` and
``KalmanIdentifier.fit`` (heap rows, GIL released). Both must print the same 8 ``f64`` bit
patterns. The extension must be built from the same core sources (``make develop``; ``make
test`` does that first). Skipped when ``cargo`` is not on PATH.
"""

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import vehid

ROOT = Path(__file__).resolve().parents[1]
SEED, N = 7, 5000


def python_bits(seed: int, n: int) -> list[str]:
    car = vehid.QuarterCar()
    run = vehid.Simulator(car, dt=0.05, road_sigma=0.1, deriv_noise=0.005, seed=seed).run(n)
    kf = vehid.KalmanIdentifier(car, p0=1000.0, road_sigma=0.1, deriv_noise=0.005)
    kf.fit(run.r, run.z)
    return [f"{b:016x}" for b in np.ascontiguousarray(kf.theta, dtype=np.float64).view(np.uint64).ravel()]


@pytest.mark.skipif(shutil.which("cargo") is None, reason="cargo is not on PATH")
def test_theta_matches_rust_bit_for_bit() -> None:
    # Built with vehid-py in the selection, as benches/callgrind_check.py builds its binaries:
    # the dependencies then resolve to the extension's features and its build serves (a `cargo
    # run -p vehid-benches` alone would compile vehid-core and its dependencies again), in the
    # extension's profile (`make test`: ci, whose vehid-runtime, through which Python's fit runs,
    # is compiled at opt-level 1: the bits must not depend on it; this binary does not use it).
    profile = os.environ.get("VEHID_CARGO_PROFILE", "release")
    built = subprocess.run(
        ["cargo", "build", "-q", "--profile", profile, "-p", "vehid-benches", "-p", "vehid-py", "--bin", "theta_golden",
         "--message-format=json-render-diagnostics"],
        cwd=ROOT, capture_output=True, text=True, timeout=3600,
    )
    assert built.returncode == 0, built.stderr
    exe = [m["executable"] for m in map(json.loads, built.stdout.splitlines())
           if m.get("reason") == "compiler-artifact" and m["target"]["name"] == "theta_golden" and m.get("executable")]
    assert len(exe) == 1, built.stdout
    done = subprocess.run([exe[0], str(SEED), str(N)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    rust = done.stdout.split()
    assert len(rust) == 8, done.stdout
    py = python_bits(SEED, N)
    assert py == rust, "\n".join(f"python {p}  rust {r}" for p, r in zip(py, rust))


def test_theta_is_a_real_estimate() -> None:
    # Guards the golden test against agreeing on garbage: after 5000 samples the body row is
    # identified closely (the wheel row carries the road input as noise, so it converges slowly).
    bits = python_bits(SEED, N)
    theta = np.array([int(b, 16) for b in bits], dtype=np.uint64).view(np.float64).reshape(2, 4)
    assert np.all(np.isfinite(theta))
    assert vehid.xi(vehid.QuarterCar().theta[1], theta[1]) < 1e-3

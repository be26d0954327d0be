"""Python and Rust give the same θ̂, bit for bit, for the same seed.

The Rust side is ``benches/src/bin/theta_golden.rs`` (vehid-core used directly, fixed-size
``KalmanIdentifier<f64, 4, 2>``); the Python side goes through ``Simulator.run`` and
``KalmanIdentifier.fit`` (heap rows, GIL released). Both must print the same 8 ``f64`` bit
patterns. The extension must be built from the same core sources (``make develop``; ``make
test`` does that first). Skipped when ``cargo`` is not on PATH.
"""

import shutil
import subprocess

import numpy as np
import pytest
from bench_scripts import load  # tests/ is on sys.path under pytest

import vehid

SEED, N = 7, 5000


def python_bits(seed: int, n: int) -> list[str]:
    car = vehid.QuarterCar()
    run = vehid.Simulator(car, dt=0.05, road_sigma=0.1, deriv_noise=0.005, seed=seed).run(n)
    kf = vehid.KalmanIdentifier(car, p0=1000.0, road_sigma=0.1, deriv_noise=0.005)
    kf.fit(run.r, run.z)
    return [f"{b:016x}" for b in np.ascontiguousarray(kf.theta, dtype=np.float64).view(np.uint64).ravel()]


@pytest.mark.skipif(shutil.which("cargo") is None, reason="cargo is not on PATH")
def test_theta_matches_rust_bit_for_bit() -> None:
    # Built as benches/callgrind_check.py builds its binaries, in the extension's profile and with
    # its dependencies' features, so that `make test`'s one build serves (its `ci` profile
    # compiles this binary at opt-level 0 and the extension's vehid-runtime, through which
    # Python's fit runs, at 1: the bits must not depend on the optimization level).
    exe = load("callgrind_check").build_bins(["theta_golden"], timeout=3600)["theta_golden"]
    done = subprocess.run([exe, str(SEED), str(N)], capture_output=True, text=True, timeout=600)
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

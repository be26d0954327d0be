"""Python ``fit()`` against the Rust update, per sample, measured in one run.

For the quarter car and the half car (thesis values, decoupled Kalman rows, p0 = 1000, R
from road σ 0.1 and derivative noise 0.005) on the same seeded data (dt 0.05 s, road σ 0.1,
initial σ 0.1, seed 1), prints ns per sample of

* ``rust fixed``: ``KalmanIdentifier<f64, N, K>::update``, the allocation-free form a Rust
  user calls (``benches/src/bin/time_updates.rs``);
* ``rust heap fit``: the heap form Python holds, through ``DynIdentifier::fit_dyn``;
* ``python fit``: ``vehid.KalmanIdentifier(..., gate=0.0).fit(run.r, run.z)``: the same
  identifier as the Rust side, whose ``KalmanOptions::default()`` has no outlier gate (Python's
  default gate of 6 would run the general update against the Rust plain one);

and the ratio python / rust fixed (the budget: ≤ 1.25×); then ``python gate 6``, the same
``fit`` with Python's default outlier gate (κ = 6), and its ratio to the ungated ``fit`` (issue
33: the screen must cost little; the same budget, measured on the same data in the same
rounds). Then the health monitor of the
passenger quarter and half car (``vehid.HealthMonitor(car)``: dt 5 ms, realistic sensors) on one
seeded drive (ISO 8608 class C at 15 m/s, seed 42, ``--monitor-seconds`` long): ``rust``, its
``update`` per sample (the same samples, written to a file for ``time_updates``), against
``python fit``, ``HealthMonitor.fit(y)``, and the same budget. Best of ``--repeats`` passes each;
the Rust and Python passes are interleaved so that a slow spell of the machine hits both.

Run: ``make bench-fit`` (builds the release binary first) or
``.venv/bin/python benches/python/fit_vs_rust.py [--n 1000000] [--repeats 7]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Dict, List

import numpy as np

import vehid

ROOT = Path(__file__).resolve().parents[2]
BUDGET = 1.25


def rust(model: str, n: object, repeats: int, binary: Path) -> Dict[str, float]:
    out = subprocess.run([str(binary), model, str(n), str(repeats)], capture_output=True, text=True, check=True)
    return {line.split()[0]: float(line.split()[1]) for line in out.stdout.splitlines() if line.strip()}


def python_fit(car: vehid.LinearModel, n: int, repeats: int, gate: float = 0.0) -> float:
    run = vehid.Simulator(car, dt=0.05, road_sigma=0.1, ic_sigma=0.1, deriv_noise=0.005, seed=1).run(n)
    r, z = np.ascontiguousarray(run.r), np.ascontiguousarray(run.z)
    best = float("inf")
    for _ in range(repeats):
        kf = vehid.KalmanIdentifier(car, p0=1000.0, road_sigma=0.1, deriv_noise=0.005, gate=gate)
        t0 = time.perf_counter()
        kf.fit(r, z)
        best = min(best, (time.perf_counter() - t0) * 1e9 / n)
    return best


def monitor_drive(car: vehid.LinearModel, seconds: float) -> np.ndarray:
    sim = vehid.Simulator(car, dt=0.005, road="iso8608-C", speed=15.0, sensors="realistic", seed=42)
    return np.ascontiguousarray(sim.run(int(round(seconds / 0.005))).y)


def python_monitor(car: vehid.LinearModel, y: np.ndarray, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        mon = vehid.HealthMonitor(car)
        t0 = time.perf_counter()
        mon.fit(y)
        best = min(best, (time.perf_counter() - t0) * 1e9 / len(y))
    return best


def main(argv: List[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000, help="samples (default 1000000)")
    parser.add_argument("--repeats", type=int, default=7, help="passes per measurement; best kept (default 7)")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved Rust/Python rounds (default 3)")
    parser.add_argument("--monitor-seconds", type=float, default=600.0,
                        help="seconds of drive for the health monitor (default 600)")
    parser.add_argument("--binary", type=Path, default=ROOT / "target" / "release" / "time_updates")
    args = parser.parse_args(argv)
    if not args.binary.exists():
        print(f"fit_vs_rust: {args.binary} is missing: run `cargo build --release -p vehid-benches "
              "--bin time_updates` (make bench-fit does)", file=sys.stderr)
        return 2
    worst = 0.0
    print(f"ns per sample, best of {args.repeats} passes x {args.rounds} interleaved rounds, {args.n} samples")
    print(f"{'model':8} {'rust fixed':>11} {'rust heap fit':>14} {'python fit':>11} {'python/fixed':>13} "
          f"{'python gate 6':>14} {'gate 6/none':>12}")
    for name, car in (("quarter", vehid.QuarterCar()), ("half", vehid.HalfCar())):
        fixed = heap = py = gated = float("inf")
        for _ in range(args.rounds):
            r = rust(name, args.n, args.repeats, args.binary)
            fixed, heap = min(fixed, r["fixed"]), min(heap, r["heap"])
            py = min(py, python_fit(car, args.n, args.repeats))
            gated = min(gated, python_fit(car, args.n, args.repeats, gate=6.0))
        ratio, gate_ratio = py / fixed, gated / py
        worst = max(worst, ratio, gate_ratio)
        print(f"{name:8} {fixed:11.1f} {heap:14.1f} {py:11.1f} {ratio:12.2f}x {gated:14.1f} {gate_ratio:11.2f}x")
    print(f"health monitor, {args.monitor_seconds:g} s of drive at 200 Hz")
    print(f"{'car':8} {'rust update':>11} {'python fit':>11} {'python/rust':>12}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, car in (("quarter", vehid.QuarterCar.passenger()), ("half", vehid.HalfCar.passenger())):
            y = monitor_drive(car, args.monitor_seconds)
            path = Path(tmp) / f"{name}.f64"
            y.astype("<f8").tofile(path)
            rust_ns = py = float("inf")
            for _ in range(args.rounds):
                rust_ns = min(rust_ns, rust(f"monitor-{name}", str(path), args.repeats, args.binary)["monitor"])
                py = min(py, python_monitor(car, y, args.repeats))
            ratio = py / rust_ns
            worst = max(worst, ratio)
            print(f"{name:8} {rust_ns:11.1f} {py:11.1f} {ratio:11.2f}x")
    verdict = "ok" if worst <= BUDGET else "OVER BUDGET"
    print(f"budget: python fit within {BUDGET}x of the Rust update, and the gate within {BUDGET}x of none: "
          f"{verdict} (worst {worst:.2f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

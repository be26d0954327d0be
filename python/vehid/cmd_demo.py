"""``vehid demo``: a quarter-car run compared with the analytic standard deviations of its
states (the sampled system's stationary covariance, and Eq 4.27).

>>> build = argparse.ArgumentParser().add_subparsers()
>>> add_parser(build)
>>> build.choices["demo"].parse_args([]).n
40000
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np

from ._vehid import QuarterCar, Simulator
from .clitools import count, quantity, run_chunks


def cmd_demo(args: argparse.Namespace) -> int:
    """Runs ``vehid demo`` with parsed arguments."""
    n, road_sigma, dt, seed = args.n, 0.1, 0.05, 1
    car = QuarterCar()
    sim = Simulator(car, dt=dt, road_sigma=road_sigma, seed=seed, method="exact")
    x = np.concatenate([r.x for r in run_chunks(sim, n, progress=sys.stderr)])
    simulated = x.std(axis=0)
    sampled = car.sampled_std(road_sigma, dt, method="exact")
    continuous = car.output_std(road_sigma, hold=dt)
    names = [quantity("quarter", f"x{i}") for i in range(1, car.n_states + 1)]
    print(f"{car!r}: {n} samples, dt = {dt} s, road sigma_u = {road_sigma} m, seed {seed}, exact ZOH")
    print()
    print(f"{'state':26s} {'simulated':>10s} {'analytic':>10s} {'Eq 4.27':>10s}")
    print(f"{'':26s} {'std':>10s} {'(sampled)':>10s} {'(contin.)':>10s}")
    for name, s, a, c in zip(names, simulated, sampled, continuous):
        print(f"{name:26s} {s:10.5f} {a:10.5f} {c:10.5f}")
    print()
    print("The states are the columns x1..x4 of `vehid simulate` (see `vehid identify --help`).")
    print("simulated: std of the true state over the run; analytic (sampled): the stationary")
    print("covariance P = Phi P Phi' + Gamma s_u^2 Gamma' of the discretized system at the sample instants.")
    print("Eq 4.27 averages over every instant of each held 0.05 s road step, while the samples fall exactly")
    print("where the held input steps: the same for the slow states, larger for the fast wheel velocity.")
    return 0


def add_parser(sub: Any) -> None:
    """Adds ``vehid demo`` and its option to the subparsers ``sub``."""
    demo = sub.add_parser("demo", help="quarter-car run vs the analytic standard deviations")
    demo.add_argument("--n", type=count(2), default=40_000, help="number of samples, at least 2 (default 40000)")
    demo.set_defaults(func=cmd_demo)

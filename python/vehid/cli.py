"""The ``vehid`` command line (also ``python -m vehid``).

Subcommands:

* ``simulate``: simulate the quarter or half car and write a CSV run;
* ``demo``: a quarter-car run compared with the analytic standard deviations.
"""

from __future__ import annotations

import argparse
import sys
from typing import IO, Callable, Iterator, List, Optional, Sequence

import numpy as np

from . import HalfCar, LinearModel, QuarterCar, Run, Simulator, VehidError, __version__

#: Samples simulated per call to ``Simulator.run`` when a run is split into chunks.
CHUNK = 100_000
#: Runs longer than this report their progress on stderr.
PROGRESS_ABOVE = 200_000

MODELS: dict[str, Callable[[], LinearModel]] = {"quarter": QuarterCar, "half": HalfCar}


def run_chunks(
    sim: Simulator, n: int, progress: Optional[IO[str]] = None, chunk: int = CHUNK
) -> Iterator[Run]:
    """Simulates ``n`` samples in chunks of at most ``chunk``, yielding each ``Run``.

    When ``progress`` is given and ``n`` exceeds :data:`PROGRESS_ABOVE`, a line per chunk
    reports how far the simulation is.
    """
    done = 0
    while done < n:
        step = min(chunk, n - done)
        yield sim.run(step)
        done += step
        if progress is not None and n > PROGRESS_ABOVE:
            print(f"vehid: simulated {done}/{n} samples ({100 * done // n}%)", file=progress, flush=True)


def csv_header(n_states: int, n_inputs: int) -> List[str]:
    """Column names: ``t, x1..xn, dx1..dxn, true_x1.., true_dx1.., u1..``."""
    cols = ["t"]
    cols += [f"x{i}" for i in range(1, n_states + 1)]
    cols += [f"dx{i}" for i in range(1, n_states + 1)]
    cols += [f"true_x{i}" for i in range(1, n_states + 1)]
    cols += [f"true_dx{i}" for i in range(1, n_states + 1)]
    cols += [f"u{j}" for j in range(1, n_inputs + 1)]
    return cols


def write_csv_rows(out: IO[str], run: Run) -> None:
    """Appends the samples of ``run`` in the column order of :func:`csv_header`."""
    data = np.column_stack([run.t, run.r, run.z, run.x, run.xdot, run.u])
    # repr() of a Python float is the shortest text that reads back to the same float64.
    out.writelines(",".join(map(repr, row)) + "\n" for row in data.tolist())


def cmd_simulate(args: argparse.Namespace) -> int:
    model = MODELS[args.model]()
    sim = Simulator(
        model,
        dt=args.dt,
        road_sigma=args.road_sigma,
        ic_sigma=args.ic_sigma,
        state_noise=args.state_noise,
        deriv_noise=args.deriv_noise,
        seed=args.seed,
        method=args.method,
    )
    to_stdout = args.output == "-"
    out: IO[str] = sys.stdout if to_stdout else open(args.output, "w", encoding="ascii", newline="\n")
    try:
        out.write(",".join(csv_header(model.n_states, model.n_inputs)) + "\n")
        for run in run_chunks(sim, args.n, progress=sys.stderr):
            write_csv_rows(out, run)
        out.flush()
    finally:
        if not to_stdout:
            out.close()
    if not to_stdout:
        print(f"vehid: wrote {args.n} samples of the {args.model} car to {args.output}", file=sys.stderr)
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    n, road_sigma, dt, seed = args.n, 0.1, 0.05, 1
    car = QuarterCar()
    sim = Simulator(car, dt=dt, road_sigma=road_sigma, seed=seed, method="exact")
    x = np.concatenate([r.x for r in run_chunks(sim, n, progress=sys.stderr)])
    simulated = x.std(axis=0)
    sampled = car.sampled_std(road_sigma, dt, method="exact")
    continuous = car.output_std(road_sigma, hold=dt)
    names = ["x1  wheel position (m)", "dx1 wheel velocity (m/s)", "x2  body position (m)", "dx2 body velocity (m/s)"]
    print(f"{car!r}: {n} samples, dt = {dt} s, road sigma_u = {road_sigma} m, seed {seed}, exact ZOH")
    print()
    print(f"{'state':26s} {'simulated':>10s} {'analytic':>10s} {'Eq 4.27':>10s}")
    print(f"{'':26s} {'std':>10s} {'(sampled)':>10s} {'(contin.)':>10s}")
    for name, s, a, c in zip(names, simulated, sampled, continuous):
        print(f"{name:26s} {s:10.5f} {a:10.5f} {c:10.5f}")
    print()
    print("simulated: std of the true state over the run; analytic (sampled): the stationary")
    print("covariance P = Phi P Phi' + Gamma s_u^2 Gamma' of the discretized system at the sample instants.")
    print("Eq 4.27 averages over every instant of each held 0.05 s road step, while the samples fall exactly")
    print("where the held input steps: the same for the slow states, larger for the fast wheel velocity.")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="vehid", description="Online identification of vehicle suspension dynamics (Kessler 1986)."
    )
    parser.add_argument("--version", action="version", version=f"vehid {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    sim = sub.add_parser("simulate", help="simulate a vehicle and write a CSV run")
    sim.add_argument("--model", choices=sorted(MODELS), required=True, help="quarter (4 states) or half (8 states)")
    sim.add_argument("--n", type=int, default=40_000, help="number of samples (default 40000)")
    sim.add_argument("--dt", type=float, default=0.05, help="sample interval, s (default 0.05)")
    sim.add_argument("--road-sigma", type=float, default=0.1, help="road input std sigma_u, m (default 0.1)")
    sim.add_argument("--ic-sigma", type=float, default=0.0, help="initial-state std (default 0)")
    sim.add_argument("--state-noise", type=float, default=0.0, help="state measurement noise std sigma_w (default 0)")
    sim.add_argument("--deriv-noise", type=float, default=0.005, help="derivative noise std sigma_v (default 0.005)")
    sim.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    sim.add_argument("--method", choices=["rk4", "exact"], default="rk4", help="integrator (default rk4)")
    sim.add_argument("-o", "--output", required=True, metavar="FILE", help="CSV file to write, '-' for stdout")
    sim.set_defaults(func=cmd_simulate)

    demo = sub.add_parser("demo", help="quarter-car run vs the analytic standard deviations")
    demo.add_argument("--n", type=int, default=40_000, help="number of samples (default 40000)")
    demo.set_defaults(func=cmd_demo)
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "n", 0) < 0:
        parser.error("--n must be >= 0")
    try:
        func: Callable[[argparse.Namespace], int] = args.func
        return func(args)
    except VehidError as e:
        print(f"vehid: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # `vehid simulate -o - | head`: the reader left; not an error of ours.
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    raise SystemExit(main())

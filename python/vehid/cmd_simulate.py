"""``vehid simulate``: simulate the quarter or the half car (or a model file's Structure over
measured inputs) and write a CSV run; a drive on an ISO 8608 road (``--road iso8608-C``,
``--sensors``, ``--change``) is :func:`vehid.monitor.cmd_simulate_drive`.

>>> csv_header(1, 1)
['t', 'x1', 'dx1', 'true_x1', 'true_dx1', 'u1']
"""

from __future__ import annotations

import argparse
import sys
from typing import IO, Any, Dict, List

import numpy as np

from . import clitools, model_file
from ._vehid import DEFAULT_DERIV_NOISE, DEFAULT_ROAD_SIGMA, Run, Simulator
from .clitools import MODELS, CliError, count, model_arg, run_chunks, stdout, write_output
from .io import open_table
from .monitor import cmd_simulate_drive


def csv_header(n_states: int, n_inputs: int, distance: bool = False) -> List[str]:
    """Column names: ``t, x1..xn, dx1..dxn, true_x1.., true_dx1.., u1..`` and, for a run
    sampled by distance (``--speed``), ``s`` (m travelled) last.

    >>> csv_header(2, 1)
    ['t', 'x1', 'x2', 'dx1', 'dx2', 'true_x1', 'true_x2', 'true_dx1', 'true_dx2', 'u1']
    >>> csv_header(1, 1, distance=True)[-2:]
    ['u1', 's']
    """
    cols = ["t"]
    cols += [f"x{i}" for i in range(1, n_states + 1)]
    cols += [f"dx{i}" for i in range(1, n_states + 1)]
    cols += [f"true_x{i}" for i in range(1, n_states + 1)]
    cols += [f"true_dx{i}" for i in range(1, n_states + 1)]
    cols += [f"u{j}" for j in range(1, n_inputs + 1)]
    if distance:
        cols.append("s")
    return cols


def write_csv_rows(out: IO[str], run: Run, distance: bool = False) -> None:
    """Appends the samples of ``run`` in the column order of :func:`csv_header`."""
    cols = [run.t, run.r, run.z, run.x, run.xdot, run.u]
    if distance:
        if run.s is None:
            raise CliError("this run was not sampled by distance (no `s`): pass --speed")
        cols.append(run.s)
    data = np.column_stack(cols)
    # repr() of a Python float is the shortest text that reads back to the same float64.
    out.writelines(",".join(map(repr, row)) + "\n" for row in data.tolist())


def cmd_simulate_file(args: argparse.Namespace) -> int:
    """``simulate --model model.toml --input u.csv --params ...``: free-run simulation of a
    Structure over measured inputs."""
    if args.input is None:
        raise CliError(f"--model {args.model}: give --input FILE with the measured inputs to simulate over")
    try:
        x0 = None if args.x0 is None else [float(v) for v in args.x0.split(",")]
    except ValueError:
        raise CliError(f"--x0 {args.x0}: expected numbers, comma-separated") from None
    if args.output == "-":
        stdout()  # before the work
    try:
        mf = model_file.load(args.model)
        params = model_file.parse_params(mf, args.params)
        with open_table(args.input) as table:
            dt = 0.05 if args.dt is None else args.dt
            header, rows = model_file.simulate(mf, table, params, dt, x0, clitools.CHUNK)
    except model_file.ModelFileError as e:
        raise CliError(str(e)) from None

    def write(out: IO[str]) -> None:
        out.write(",".join(header) + "\n")
        np.savetxt(out, rows, delimiter=",", fmt="%.17g")

    write_output(args.output, write)
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    """Runs ``vehid simulate`` with parsed arguments."""
    if args.road not in ("white", "independent") or args.sensors is not None or args.change:
        return cmd_simulate_drive(args)
    if args.car is not None:
        raise CliError("--car applies to a drive (--road iso8608-A..E, --sensors, --change)")
    if args.model not in MODELS:
        return cmd_simulate_file(args)
    if args.input is not None or args.params is not None or args.x0 is not None:
        raise CliError("--input, --params and --x0 apply to a model file (--model NAME.toml)")
    model = MODELS[args.model]()
    distance = args.speed is not None
    road_kw: Dict[str, Any] = {}
    if distance:
        road_kw = {"speed": args.speed, "spacing": args.spacing, "road": args.road}
    sim = Simulator(
        model,
        dt=0.05 if args.dt is None else args.dt,
        road_sigma=args.road_sigma,
        ic_sigma=args.ic_sigma,
        state_noise=args.state_noise,
        deriv_noise=args.deriv_noise,
        seed=args.seed,
        method=args.method,
        **road_kw,
    )

    def write(out: IO[str]) -> None:
        out.write(",".join(csv_header(model.n_states, model.n_inputs, distance)) + "\n")
        for run in run_chunks(sim, args.n, progress=sys.stderr):
            write_csv_rows(out, run, distance)

    write_output(args.output, write, remove_partial=True)
    if args.output != "-":
        print(f"vehid: wrote {args.n} samples of the {args.model} car to {args.output}", file=sys.stderr)
    return 0


def add_parser(sub: Any) -> None:
    """Adds ``vehid simulate`` and its options to the subparsers ``sub``."""
    sim = sub.add_parser("simulate", help="simulate a vehicle and write a CSV run")
    sim.add_argument("--model", type=model_arg, required=True, metavar="MODEL",
                     help="quarter (4 states), half (8 states), or a model file NAME.toml (with --input, --params)")
    sim.add_argument("--input", default=None, metavar="FILE",
                     help="model file: CSV of the measured inputs to simulate over (columns per [columns])")
    sim.add_argument("--params", default=None, metavar="VALUES",
                     help="model file: the parameters, NAME=VALUE pairs, comma-separated")
    sim.add_argument("--x0", default=None, metavar="VALUES", help="model file: initial state, comma-separated (0)")
    sim.add_argument("--n", type=count(0), default=40_000, help="number of samples (default 40000)")
    sim.add_argument("--dt", type=float, default=None, help="sample interval, s (default 0.05; a drive 0.005)")
    sim.add_argument("--road-sigma", type=float, default=DEFAULT_ROAD_SIGMA,
                     help=f"road input std sigma_u, m (default {DEFAULT_ROAD_SIGMA:g})")
    sim.add_argument("--ic-sigma", type=float, default=0.0, help="initial-state std (default 0)")
    sim.add_argument("--state-noise", type=float, default=0.0, help="state measurement noise std sigma_w (default 0)")
    sim.add_argument("--deriv-noise", type=float, default=DEFAULT_DERIV_NOISE,
                     help=f"derivative noise std sigma_v (default {DEFAULT_DERIV_NOISE:g})")
    sim.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    sim.add_argument("--method", choices=["rk4", "exact"], default="rk4", help="integrator (default rk4)")
    sim.add_argument("--speed", type=float, default=None,
                     help="half car on one road: drive at this speed, m/s, sampling every --spacing metres "
                          "(adds the distance column s)")
    sim.add_argument("--spacing", type=float, default=0.3, help="with --speed: metres between samples (default 0.3)")
    sim.add_argument("--road", choices=["white", "independent", "flat", "iso8608-A", "iso8608-B", "iso8608-C",
                                        "iso8608-D", "iso8608-E"], default="white",
                     help="with --speed: one road under both axles (white) or independent inputs (Fig 6-7); "
                          "iso8608-A..E (or flat): a drive of the quarter car (or, with --model half, the half "
                          "car, its rear wheel a wheelbase behind) on an ISO 8608 road, writing its sensors "
                          "(columns t, the channels, s, true_M, true_m, true_k1, true_k2, true_b; the half car's "
                          "true_M, true_J, true_k11, ..., true_l2) for vehid monitor")
    sim.add_argument("--sensors", choices=["realistic", "state"], default=None,
                     help="a drive's sensors: realistic (a_body, a_wheel in m/s^2, deflection in m; default) or "
                          "state (the thesis' zw, vw, zb, vb and their derivatives)")
    sim.add_argument("--change", action="append", default=None, metavar="T:NAME=VALUE[:RAMP]",
                     help="a drive's parameter change: at T seconds NAME (M, m, k1, k2, b; the half car's k2_f, "
                          "k2_r, b_f, b_r, M, J, ...) becomes VALUE, in a "
                          "step or a RAMP of that many seconds, e.g. 60:b=1350 (repeatable)")
    sim.add_argument("--car", default=None, metavar="CONSTANTS",
                     help="a drive's car: passenger (M=320 kg, m=40 kg, k1=200 kN/m, k2=22 kN/m, b=1500 N s/m; "
                          "default) or thesis, and/or NAME=VALUE overrides, e.g. passenger,b=1400")
    sim.add_argument("-o", "--output", required=True, metavar="FILE",
                     help="CSV file to write, '-' for stdout "
                          "(columns t, x1..xn, dx1..dxn, true_x1.., true_dx1.., u1..)")
    sim.set_defaults(func=cmd_simulate)

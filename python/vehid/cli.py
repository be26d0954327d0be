"""The ``vehid`` command line (also ``python -m vehid``).

Subcommands:

* ``simulate``: simulate the quarter or half car and write a CSV run;
* ``identify``: read such a CSV run (a file or ``-`` for stdin), identify the unknown rows of
  A, and print them, the physical constants and, when the file carries the true values, ξ;
* ``demo``: a quarter-car run compared with the analytic standard deviations;
* ``reproduce``: the thesis' figures and tables, regenerated, into a report (``vehid.reproduce``).

User errors (a missing file, bad columns or cells, too few samples, a value vehid rejects)
print one line on stderr and exit with status 2.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import re
import sys
import warnings
from dataclasses import dataclass
from typing import IO, Any, Callable, Dict, Iterator, List, Optional, Sequence, Union

import numpy as np
from numpy.typing import NDArray

from . import (
    BatchLeastSquares,
    TwoAxleIdentifier,
    HalfCar,
    KalmanIdentifier,
    LinearModel,
    QuarterCar,
    Run,
    Simulator,
    StochasticGradient,
    VehidError,
    __version__,
    xi,
)

#: Samples simulated per call to ``Simulator.run`` when a run is split into chunks.
CHUNK = 100_000
#: Runs longer than this report their progress on stderr.
PROGRESS_ABOVE = 200_000

MODELS: dict[str, Callable[[], LinearModel]] = {"quarter": QuarterCar, "half": HalfCar}
#: What ``vehid identify`` calls each model in its messages.
MODEL_NAMES = {"quarter": "quarter car", "half": "half car"}


class CliError(Exception):
    """A user error the command line reports in one line (exit status 2)."""


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


def csv_header(n_states: int, n_inputs: int, distance: bool = False) -> List[str]:
    """Column names: ``t, x1..xn, dx1..dxn, true_x1.., true_dx1.., u1..`` and, for a run
    sampled by distance (``--speed``), ``s`` (m travelled) last."""
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


def cmd_simulate(args: argparse.Namespace) -> int:
    model = MODELS[args.model]()
    distance = args.speed is not None
    road_kw: Dict[str, Any] = {}
    if distance:
        road_kw = {"speed": args.speed, "spacing": args.spacing, "road": args.road}
    sim = Simulator(
        model,
        dt=args.dt,
        road_sigma=args.road_sigma,
        ic_sigma=args.ic_sigma,
        state_noise=args.state_noise,
        deriv_noise=args.deriv_noise,
        seed=args.seed,
        method=args.method,
        **road_kw,
    )
    to_stdout = args.output == "-"
    out: IO[str] = sys.stdout if to_stdout else open(args.output, "w", encoding="ascii", newline="\n")
    try:
        out.write(",".join(csv_header(model.n_states, model.n_inputs, distance)) + "\n")
        for run in run_chunks(sim, args.n, progress=sys.stderr):
            write_csv_rows(out, run, distance)
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


# --- identify -------------------------------------------------------------------------


@dataclass
class CsvLayout:
    """Where the columns ``identify`` needs are in a CSV run."""

    names: List[str]
    x: List[int]
    dx: List[int]
    has_truth: bool


_COLUMN = re.compile(r"^(t|s|x|dx|true_x|true_dx|u)(\d*)$")


def csv_layout(header: str, model: LinearModel, name: str, source: str) -> CsvLayout:
    """Checks the header of a CSV run against ``model`` (called ``name`` on the command line)."""
    n, m = model.n_states, model.n_inputs
    names = [c.strip() for c in header.strip().split(",")]
    expected = f"t, x1..x{n}, dx1..dx{n} (as `vehid simulate` writes)"
    if names == [""]:
        raise CliError(f"{source}: empty header line; expected the columns {expected}")
    seen: Dict[str, int] = {}
    parsed: List[tuple[str, int]] = []
    for i, col in enumerate(names):
        match = _COLUMN.match(col)
        ok = match is not None and (match.group(1) in ("t", "s")) == (match.group(2) == "")
        if match is None or not ok or match.group(2).startswith("0"):
            raise CliError(f"{source}: unknown column {col!r} (column {i + 1}); expected {expected}")
        if col in seen:
            raise CliError(f"{source}: column {col!r} appears twice (columns {seen[col] + 1} and {i + 1})")
        seen[col] = i
        parsed.append((match.group(1), int(match.group(2) or 0)))
    states = max((idx for kind, idx in parsed if kind == "x"), default=0)
    if states not in (0, n):
        other = {4: "quarter", 8: "half"}.get(states)
        hint = f": use --model {other}" if other else ""
        raise CliError(f"{source} has {states} states (x1..x{states}) but the {MODEL_NAMES[name]} has {n}{hint}")
    need = ["t"] + [f"x{i}" for i in range(1, n + 1)] + [f"dx{i}" for i in range(1, n + 1)]
    missing = [c for c in need if c not in seen]
    if missing:
        raise CliError(f"{source}: missing column(s) {', '.join(missing)}; expected {expected}")
    for col, (kind, idx) in zip(names, parsed):
        if kind not in ("t", "s") and idx > (m if kind == "u" else n):
            raise CliError(f"{source}: column {col!r} does not fit the {MODEL_NAMES[name]} ({n} states, {m} inputs)")
    return CsvLayout(
        names=names,
        x=[seen[f"x{i}"] for i in range(1, n + 1)],
        dx=[seen[f"dx{i}"] for i in range(1, n + 1)],
        has_truth=all(f"true_x{i}" in seen for i in range(1, n + 1)),
    )


def _cell_error(lines: List[str], first_line: int, layout: CsvLayout, source: str, fallback: str) -> CliError:
    """Finds the first bad line of a chunk that numpy refused, for a message with its place."""
    width = len(layout.names)
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        cells = line.rstrip("\r\n").split(",")
        where = f"{source}, line {first_line + i}"
        if len(cells) != width:
            return CliError(f"{where}: {len(cells)} cells, but the header has {width} columns")
        for name, cell in zip(layout.names, cells):
            try:
                float(cell)
            except ValueError:
                return CliError(f"{where}, column {name!r}: {cell.strip()!r} is not a number")
    return CliError(f"{source}: {fallback}")


def read_chunks(
    stream: IO[str], layout: CsvLayout, source: str, chunk: int, first_line: int = 2
) -> Iterator[tuple[NDArray[np.float64], NDArray[np.float64], int]]:
    """Parses the data lines of a CSV run ``chunk`` lines at a time; yields ``(r, z, chars)``:
    measured states and derivatives (samples, n) and the characters read for them."""
    line_no = first_line
    while True:
        lines = list(itertools.islice(stream, chunk))
        if not lines:
            return
        chars = sum(map(len, lines))
        if any(line.strip() for line in lines):
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("error")
                    data = np.loadtxt(lines, delimiter=",", ndmin=2, comments=None, dtype=np.float64)
            except (ValueError, Warning) as e:
                raise _cell_error(lines, line_no, layout, source, str(e)) from None
            if data.shape[1] != len(layout.names):
                raise _cell_error(lines, line_no, layout, source, "wrong number of cells")
            r = np.ascontiguousarray(data[:, layout.x])
            z = np.ascontiguousarray(data[:, layout.dx])
            bad = ~(np.isfinite(r).all(axis=1) & np.isfinite(z).all(axis=1))
            if bad.any():
                row = int(np.argmax(bad))
                data_lines = [i for i, line in enumerate(lines) if line.strip()]
                col = next(c for c in layout.x + layout.dx if not np.isfinite(data[row, c]))
                cell = lines[data_lines[row]].split(",")[col].strip()
                raise CliError(
                    f"{source}, line {line_no + data_lines[row]}, column {layout.names[col]!r}: "
                    f"{cell!r} is not a finite number (drop or repair that sample)"
                )
            yield r, z, chars
        line_no += len(lines)


def parse_floats(text: str) -> Union[float, List[float]]:
    """``"1000"`` -> 1000.0; ``"1000,8"`` -> [1000.0, 8.0] (one value per unknown row)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or comma-separated numbers, got {text!r}") from None
    return values[0] if len(values) == 1 else values


def positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a positive mass in kg, got {text!r}")
    return v


Identifier = Union[KalmanIdentifier, StochasticGradient, BatchLeastSquares, TwoAxleIdentifier]


def make_identifier(args: argparse.Namespace, model: LinearModel) -> Identifier:
    if args.method == "kalman":
        return KalmanIdentifier(
            model,
            p0=args.p0,
            road_sigma=args.road_sigma,
            deriv_noise=args.deriv_noise,
            mode=args.mode,
            reinit=args.reinit,
        )
    if args.method == "sg":
        return StochasticGradient(model, gain=args.gain, h=args.h)
    if args.method == "two-axle":
        if args.model != "half":
            raise CliError("--method two-axle needs --model half (two axles on one road)")
        p0 = args.p0 if isinstance(args.p0, float) else args.p0[0] if len(args.p0) == 1 else None
        if p0 is None:
            raise CliError("--method two-axle takes one --p0 value (the body rows' prior is the thesis' 8)")
        return TwoAxleIdentifier(
            model,
            spacing=args.spacing,
            method=args.wheel_method,
            p0=p0,
            road_sigma=args.road_sigma,
            deriv_noise=args.deriv_noise,
        )
    return BatchLeastSquares(model)


def method_options(args: argparse.Namespace) -> Dict[str, Any]:
    """The settings that shaped the estimate, for the report."""
    if args.method == "kalman":
        return {"p0": args.p0, "road_sigma": args.road_sigma, "deriv_noise": args.deriv_noise,
                "mode": args.mode, "reinit": args.reinit}
    if args.method == "sg":
        return {"gain": args.gain, "h": 1.0 if args.h is None else args.h}
    if args.method == "two-axle":
        return {"p0": args.p0, "road_sigma": args.road_sigma, "deriv_noise": args.deriv_noise,
                "spacing": args.spacing, "wheel_method": args.wheel_method}
    return {}


def known_masses(args: argparse.Namespace) -> Dict[str, float]:
    return {"m": args.m} if args.model == "quarter" else {"m1": args.m1, "m2": args.m2}


@dataclass
class Progress:
    """Progress lines on stderr for long inputs (more than :data:`PROGRESS_ABOVE` samples,
    known from the file size or seen so far on a stream)."""

    out: IO[str]
    source: str
    size: Optional[int]
    chars: int = 0
    samples: int = 0

    def step(self, samples: int, chars: int) -> None:
        self.samples += samples
        self.chars += chars
        if self.size and self.chars:
            estimate = self.samples * self.size / self.chars
            if estimate > PROGRESS_ABOVE:
                pct = min(100, 100 * self.chars // self.size)
                print(f"vehid: identified {self.samples} samples ({pct}% of {self.source})", file=self.out, flush=True)
        elif self.samples > PROGRESS_ABOVE:
            print(f"vehid: identified {self.samples} samples", file=self.out, flush=True)


#: Units of the physical constants, by name without the axle digit.
UNITS = {"M": "kg", "m": "kg", "k": "N/m", "b": "N s/m", "J": "kg m^2", "l": "m"}


def _finite_or_none(v: float) -> Optional[float]:
    return v if math.isfinite(v) else None


def _json_array(a: NDArray[np.float64]) -> Any:
    return [[_finite_or_none(float(v)) for v in row] for row in a]


def cmd_identify(args: argparse.Namespace) -> int:
    model = MODELS[args.model]()
    n = model.n_states
    source = "<stdin>" if args.file == "-" else args.file
    ident = make_identifier(args, model)  # option errors before any reading
    try:
        stream: IO[str] = (
            sys.stdin if args.file == "-" else open(args.file, encoding="utf-8")
        )
    except FileNotFoundError:
        raise CliError(f"{args.file}: no such file") from None
    except IsADirectoryError:
        raise CliError(f"{args.file}: is a directory, not a CSV file") from None
    except OSError as e:
        raise CliError(f"{args.file}: cannot open ({e.strerror})") from None
    size = None
    if args.file != "-":
        try:
            size = os.fstat(stream.fileno()).st_size
        except OSError:
            size = None
    progress = Progress(sys.stderr, source, size)
    batches: List[tuple[NDArray[np.float64], NDArray[np.float64]]] = []
    try:
        header = stream.readline()
        if not header:
            raise CliError(f"{source}: empty file; expected a CSV run with a header line (vehid simulate -o FILE)")
        layout = csv_layout(header, model, args.model, source)
        progress.chars = len(header)
        for r, z, chars in read_chunks(stream, layout, source, CHUNK):
            if isinstance(ident, BatchLeastSquares):
                batches.append((r, z))  # solved once, at the end
            else:
                ident.fit(r, z)
            progress.step(len(r), chars)
    except UnicodeDecodeError:
        raise CliError(f"{source}: not a text (UTF-8) CSV file") from None
    finally:
        if stream is not sys.stdin:
            stream.close()
    samples = progress.samples
    if samples < n:
        raise CliError(
            f"{source} has {samples} sample{'s' if samples != 1 else ''}; the {MODEL_NAMES[args.model]} "
            f"needs at least {n} (one per state), and many more for a useful estimate"
        )
    if isinstance(ident, BatchLeastSquares):
        ident.fit(np.concatenate([b[0] for b in batches]), np.concatenate([b[1] for b in batches]))
    theta = ident.theta
    known = known_masses(args)
    physical: Optional[Dict[str, float]] = None
    physical_error: Optional[str] = None
    try:
        physical = model.physical(theta, **known)
    except VehidError as e:
        physical_error = str(e)
    true_theta = model.theta if layout.has_truth else None
    xi_value = xi(true_theta, theta) if true_theta is not None else None
    rows = list(model.unknown_rows)
    if args.json:
        report = {
            "source": source,
            "model": args.model,
            "method": args.method,
            "options": method_options(args),
            "samples": samples,
            "unknown_rows": rows,
            "theta": _json_array(theta),
            "known": known,
            "physical": physical,
            "physical_error": physical_error,
            "true_theta": None if true_theta is None else _json_array(true_theta),
            "xi": None if xi_value is None else _finite_or_none(xi_value),
        }
        print(json.dumps(report, allow_nan=False))
        return 0
    opts = ", ".join(f"{k} {v}" for k, v in method_options(args).items())
    print(f"{source}: {samples} samples, {MODEL_NAMES[args.model]} ({n} states), method {args.method}"
          + (f" ({opts})" if opts else ""))
    print()
    width = max(12, max(len(f"{v:.6g}") for v in theta.ravel()) + 2)
    print("identified rows of A (0-based)" + (", and the true rows" if true_theta is not None else "") + ":")
    for i, row in enumerate(rows):
        print(f"  row {row}  " + "".join(f"{v:{width}.6g}" for v in theta[i]))
        if true_theta is not None:
            print(f"  true   " + "".join(f"{v:{width}.6g}" for v in true_theta[i]))
    print()
    given = ", ".join(f"{k} = {v:g} kg" for k, v in known.items())
    if physical is not None:
        print(f"physical constants (known: {given}):")
        for k, v in physical.items():
            print(f"  {k:3s} = {v:<12.6g} {UNITS.get(k.rstrip('0123456789'), '')}".rstrip())
    else:
        print(f"physical constants (known: {given}): not available: {physical_error}")
    if xi_value is not None:
        print()
        print(f"xi (Eq 3.17, vs the thesis {MODEL_NAMES[args.model]}) = {xi_value:.6g}")
    return 0


def cmd_reproduce(args: argparse.Namespace) -> int:
    from .reproduce import command

    return command(args)


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
    sim.add_argument("--speed", type=float, default=None,
                     help="half car on one road: drive at this speed, m/s, sampling every --spacing metres "
                          "(adds the distance column s)")
    sim.add_argument("--spacing", type=float, default=0.3, help="with --speed: metres between samples (default 0.3)")
    sim.add_argument("--road", choices=["white", "independent"], default="white",
                     help="with --speed: one road under both axles (white) or independent inputs (Fig 6-7)")
    sim.add_argument("-o", "--output", required=True, metavar="FILE", help="CSV file to write, '-' for stdout")
    sim.set_defaults(func=cmd_simulate)

    ident = sub.add_parser(
        "identify",
        help="identify the unknown rows of A from a CSV run",
        description="Reads a CSV run written by `vehid simulate` (columns t, x1..xn, dx1..dxn; "
        "optional true_x.., true_dx.., u..), identifies the unknown rows of A and prints them, the "
        "physical constants and, when the file carries the true values, xi (Eq 3.17) against the "
        "thesis model.",
    )
    ident.add_argument("file", metavar="FILE", help="CSV run, '-' for stdin")
    ident.add_argument("--model", choices=sorted(MODELS), required=True, help="quarter (4 states) or half (8 states)")
    ident.add_argument("--method", choices=["kalman", "ls", "sg", "two-axle"], default="kalman",
                       help="kalman (Eq 4.3-4.7, default), ls (batch least squares, Eq 2.14), sg (stochastic "
                            "gradient), two-axle (half car on one road, samples every --spacing metres)")
    ident.add_argument("--spacing", type=float, default=0.3,
                       help="two-axle: metres between samples, as simulated (default 0.3)")
    ident.add_argument("--wheel-method", choices=["none", "thesis", "cancel"], default="cancel",
                       help="two-axle: wheel rows by plain rows, Eq 6.14, or road cancellation (default)")
    ident.add_argument("--p0", type=parse_floats, default=1000.0, metavar="P0",
                       help="kalman: prior covariance P(0), one value or one per unknown row, comma-separated (default 1000)")
    ident.add_argument("--road-sigma", type=float, default=0.1,
                       help="kalman: road input std sigma_u, m, for R (Eq 4.7) (default 0.1)")
    ident.add_argument("--deriv-noise", type=float, default=0.005,
                       help="kalman: derivative noise std sigma_v, for R (default 0.005)")
    ident.add_argument("--mode", choices=["rows", "shared", "full"], default="rows",
                       help="kalman: decoupled rows (default), one shared covariance (needs the same R and P0 on "
                       "every row, e.g. --road-sigma 0), or the full stacked filter")
    ident.add_argument("--reinit", action="store_true", help="kalman: reinitialize by Eq 4.36")
    ident.add_argument("--gain", choices=["venter", "lyapunov", "ljung"], default="venter",
                       help="sg: gain sequence (default venter)")
    ident.add_argument("--h", type=parse_floats, default=None, metavar="H",
                       help="sg: weights, one value, one per unknown row or one per parameter, comma-separated (default 1)")
    ident.add_argument("--m", type=positive_float, default=1.0, help="quarter: known wheel mass m, kg (default 1)")
    ident.add_argument("--m1", type=positive_float, default=1.0, help="half: known front wheel mass m1, kg (default 1)")
    ident.add_argument("--m2", type=positive_float, default=1.0, help="half: known rear wheel mass m2, kg (default 1)")
    ident.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    ident.set_defaults(func=cmd_identify)

    demo = sub.add_parser("demo", help="quarter-car run vs the analytic standard deviations")
    demo.add_argument("--n", type=int, default=40_000, help="number of samples (default 40000)")
    demo.set_defaults(func=cmd_demo)

    rep = sub.add_parser(
        "reproduce",
        help="reproduce the thesis' figures and tables into a report",
        description="Runs the thesis' simulation study (every figure of Ch. III-VI, Monte Carlo over seeds), "
        "writes one PNG per figure (with the plot extra: pip install vehid[plot]) and report/index.md + index.html "
        "comparing each thesis claim with vehid's measurement, and prints the report's path.",
    )
    from .reproduce import add_arguments as _reproduce_arguments

    _reproduce_arguments(rep)
    rep.set_defaults(func=cmd_reproduce)
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "n", 0) < 0:
        parser.error("--n must be >= 0")
    try:
        func: Callable[[argparse.Namespace], int] = args.func
        return func(args)
    except (VehidError, CliError) as e:
        print(f"vehid: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # `vehid simulate -o - | head`: the reader left; not an error of ours.
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The ``vehid`` command line (also ``python -m vehid``): its argument parser and :func:`main`.

Each subcommand lives in its own module, which adds its options to the parser
(``add_parser``) and runs it:

* ``simulate`` (:mod:`vehid.cmd_simulate`): simulate the quarter or half car and write a CSV
  run; a drive of a car's sensors on an ISO 8608 road (:func:`vehid.monitor.cmd_simulate_drive`);
* ``identify`` (:mod:`vehid.cmd_identify`): read a run (CSV in any common dialect, or Parquet;
  a file or ``-`` for stdin), identify the unknown rows of A, and print them, the physical
  constants and, when the truth is known (``--truth`` or the file's ``true_*`` columns), ξ;
* ``monitor`` (:mod:`vehid.monitor`): the suspension health monitor over a log of a car's
  sensors, one line per change found;
* ``inspect`` (:mod:`vehid.inspect_log`): what a log holds and which channels it can feed;
* ``demo`` (:mod:`vehid.cmd_demo`): a quarter-car run compared with the analytic standard
  deviations;
* ``reproduce`` (:mod:`vehid.cmd_reproduce`, :mod:`vehid.reproduce`): the thesis' figures and
  tables, regenerated, into a report;
* ``fleet`` (:mod:`vehid.fleet.cli`): the health monitor over a fleet's logs.

What the commands share (:class:`~vehid.clitools.CliError`, writing ``-o`` outputs, the
argparse types) is :mod:`vehid.clitools`. Every failure prints one line on stderr and exits
with status 2 (an interrupt: 130); a closed stdout (``vehid simulate -o - | head``) ends the
command quietly.

The names this module held before the commands had modules of their own are still
importable from it (``from vehid.cli import csv_header``); to change :data:`CHUNK` or
:data:`PROGRESS_ABOVE`, set them on :mod:`vehid.clitools`, where the commands read them.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Callable, NoReturn, Optional, Sequence

from . import cmd_demo as demo_command
from . import cmd_identify as identify_command
from . import cmd_reproduce as reproduce_command
from . import cmd_simulate as simulate_command
from . import inspect_log, monitor
from ._vehid import VehidError, __version__
from .clitools import (
    CHUNK,
    MODEL_NAMES,
    MODELS,
    PROGRESS_ABOVE,
    CliError,
    count,
    delimiter,
    model_arg,
    model_columns,
    parse_floats,
    positive_float,
    quantity,
    run_chunks,
    stdout,
    write_output,
)
from .cmd_demo import cmd_demo
from .cmd_identify import (
    DIAG_ALPHA,
    DIAG_LAGS,
    DIAG_SAMPLES,
    GAP_FACTOR,
    GAP_WARNINGS,
    LIFT_WARN,
    PRIOR_WEIGHT,
    ROADS,
    THESIS_P0,
    UNITS,
    WHITE_ROAD_METHODS,
    Identifier,
    Intervals,
    Layout,
    Progress,
    TimeCheck,
    Truth,
    TruthFit,
    check_road_args,
    cmd_identify,
    cmd_identify_file,
    coloured,
    column_label,
    columns_help,
    feed,
    feed_batch_least_squares,
    kalman_p0,
    known_masses,
    make_identifier,
    method_options,
    modes,
    parse_p0,
    parse_truth,
    physical_identifier,
    prior_note,
    residual_checks,
    residual_warning,
    resolve_layout,
    road_options,
    road_spacing,
    state_space,
)
from .cmd_reproduce import cmd_reproduce
from .cmd_simulate import cmd_simulate, cmd_simulate_file, csv_header, write_csv_rows
from .fleet import cli as fleet_cli
from .io import TableError

#: What vehid.cli held before each command had its own module: still importable from here.
__all__ = [
    "CHUNK", "CliError", "DIAG_ALPHA", "DIAG_LAGS", "DIAG_SAMPLES", "GAP_FACTOR", "GAP_WARNINGS", "Identifier",
    "Intervals", "LIFT_WARN", "Layout", "MODELS", "MODEL_NAMES", "PRIOR_WEIGHT", "PROGRESS_ABOVE", "Parser",
    "Progress", "ROADS", "THESIS_P0", "TimeCheck", "Truth", "TruthFit", "UNITS", "WHITE_ROAD_METHODS", "build_parser",
    "check_road_args", "cmd_demo", "cmd_identify", "cmd_identify_file", "cmd_reproduce", "cmd_simulate",
    "cmd_simulate_file", "coloured", "column_label", "columns_help", "count", "csv_header", "delimiter", "feed",
    "feed_batch_least_squares", "kalman_p0", "known_masses", "main", "make_identifier", "method_options", "model_arg",
    "model_columns", "modes", "parse_floats", "parse_p0", "parse_truth", "physical_identifier", "positive_float",
    "prior_note", "quantity", "residual_checks", "residual_warning", "resolve_layout", "road_options", "road_spacing",
    "run_chunks", "state_space", "stdout", "write_csv_rows", "write_output",
]


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``vehid: error: ... (see vehid identify --help)``."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"vehid: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The ``vehid`` argument parser: one subcommand each for ``simulate``, ``identify``,
    ``monitor``, ``inspect``, ``demo``, ``reproduce`` and ``fleet``, with their defaults.

    >>> args = build_parser().parse_args(["identify", "run.csv", "--model", "quarter", "--p0", "1000,8"])
    >>> args.command, args.file, args.method, args.mode, args.p0, args.m
    ('identify', 'run.csv', 'kalman', 'rows', [1000.0, 8.0], None)
    >>> args = build_parser().parse_args(["simulate", "--model", "half", "--speed", "6", "-o", "-"])
    >>> args.n, args.spacing, args.road, args.seed
    (40000, 0.3, 'white', 1)
    """
    parser = Parser(prog="vehid", description="Online identification of vehicle suspension dynamics (Kessler 1986).")
    parser.add_argument("--version", action="version", version=f"vehid {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    simulate_command.add_parser(sub)
    identify_command.add_parser(sub)

    mon = sub.add_parser("monitor", help="watch a log of a car's sensors for suspension changes (damper, spring, "
                         "body mass)", description=monitor.DESCRIPTION)
    monitor.add_arguments(mon, delimiter)
    mon.set_defaults(func=monitor.cmd_monitor)

    insp = sub.add_parser("inspect", help="what a log holds (CSV, Parquet, ROS 2 bag, MCAP) and which channels it "
                          "can feed", description=inspect_log.DESCRIPTION)
    inspect_log.add_arguments(insp, delimiter)
    insp.set_defaults(func=inspect_log.cmd_inspect)

    demo_command.add_parser(sub)
    reproduce_command.add_parser(sub)
    fleet_cli.add_parser(sub)
    return parser


# --- main -------------------------------------------------------------------------------


def _silence_stdout() -> None:
    """Points stdout at /dev/null, so that the interpreter's last flush of a closed pipe or
    a full disk cannot print a second message."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):  # no real file behind stdout (e.g. under pytest)
        pass


def _flush_stdout() -> None:
    if sys.stdout is not None:  # None: started with stdout closed
        sys.stdout.flush()


def _fail(message: str, status: int = 2) -> int:
    try:
        _flush_stdout()
    except (OSError, ValueError):
        _silence_stdout()
    print(" ".join(message.split("\n")), file=sys.stderr)
    return status


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Runs ``vehid`` with the arguments ``argv`` (default: the command line's) and returns
    the exit status: 0, 2 for any error (one line on stderr), 130 for an interrupt.

    >>> main(["simulate", "--model", "quarter", "--n", "2", "-o", "-"])  # doctest: +ELLIPSIS
    t,x1,x2,x3,x4,dx1,dx2,dx3,dx4,true_x1,...,u1
    0...
    0.05...
    0
    >>> main(["identify", "no-such-file.csv", "--model", "quarter"])  # the error goes to stderr
    2
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        func: Callable[[argparse.Namespace], int] = args.func
        status = func(args)
        _flush_stdout()
        return status
    except (VehidError, CliError, TableError) as e:
        return _fail(f"vehid: error: {e}")
    except BrokenPipeError:
        # `vehid simulate -o - | head`: the reader left; not an error of ours.
        _silence_stdout()
        return 0
    except OSError as e:  # writing the report to stdout or stderr failed (e.g. a full disk)
        what = "standard output" if e.filename is None else e.filename
        return _fail(f"vehid: error: {what}: cannot write ({e.strerror or e})")
    except KeyboardInterrupt:
        return _fail("vehid: interrupted", 130)
    except MemoryError:
        return _fail("vehid: error: out of memory")
    except Exception as e:  # a bug: still one line, never a traceback
        return _fail(f"vehid: internal error: {type(e).__name__}: {e} (a bug in vehid: please report it)")
    except BaseException as e:
        if type(e).__name__ != "PanicException":  # SystemExit, GeneratorExit: not ours to stop
            raise
        return _fail(f"vehid: internal error: a panic in vehid's Rust core: {e} (a bug in vehid: please report it)")


if __name__ == "__main__":
    raise SystemExit(main())

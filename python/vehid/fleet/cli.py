"""``vehid fleet simulate | run | report``: the fleet commands (:mod:`vehid.fleet`)."""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import IO, Any, Callable, Optional

from ..clitools import CliError

DESCRIPTION = ("The suspension health monitor over a fleet's logs (DIR/vehicle=<id>/day=<YYYY-MM-DD>/*.parquet "
               "and DIR/fleet.toml), day after day, into a store (Parquet: state, events, problems); locally or on "
               "a Dask cluster; and its report.")


class ProgressBar:
    """Progress over vehicle-days on ``out``: a bar redrawn in place on a terminal, else a line
    every ``every`` seconds; always a last line."""

    def __init__(self, what: str, out: Optional[IO[str]] = None, every: float = 5.0) -> None:
        self.what, self.every = what, every
        self.out = sys.stderr if out is None else out
        self.t0 = time.monotonic()
        self.last = -1e9
        self.tty = bool(getattr(self.out, "isatty", lambda: False)())

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        final = done >= total
        if not final and now - self.last < (0.2 if self.tty else self.every):
            return
        self.last = now
        pct = 100 * done // max(1, total)
        bar = "#" * (pct // 5) + "-" * (20 - pct // 5)
        text = f"vehid: {self.what} [{bar}] {done}/{total} ({pct} %), {now - self.t0:.0f} s"
        if self.tty:
            self.out.write("\r" + text + ("\n" if final else ""))
        else:
            self.out.write(text + "\n")
        self.out.flush()


def _client(address: str) -> Any:
    import importlib

    try:
        client_class = importlib.import_module("distributed").Client
    except ImportError:
        raise CliError("--scheduler needs dask.distributed: pip install 'vehid[fleet]'") from None
    try:
        return client_class(address, timeout=10)
    except (OSError, TimeoutError, ValueError) as e:
        raise CliError(f"--scheduler {address}: cannot connect ({str(e).splitlines()[0] if str(e) else e!r}); give "
                     "the scheduler's address, e.g. tcp://10.0.0.5:8786") from None


def cmd_simulate(args: argparse.Namespace) -> int:
    """``vehid fleet simulate DIR --vehicles N --days D --hours H --faults FRACTION --seed S``."""
    from .simulate import simulate

    try:
        truth = simulate(args.dir, args.vehicles, args.days, args.hours, args.faults, args.seed,
                         progress=ProgressBar("fleet simulate: vehicles"))
    except ValueError as e:
        raise CliError(str(e)) from None
    print(f"vehid: wrote {args.vehicles} vehicles × {args.days} days × {args.hours:g} h and {truth.num_rows} "
          f"injected faults to {args.dir} (fleet.toml, truth.parquet)", file=sys.stderr)
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    """``vehid fleet run DIR --store STORE [--workers N | --scheduler ADDRESS] [--from DAY]``."""
    from .engine import run

    client = _client(args.scheduler) if args.scheduler else None
    try:
        res = run(args.dir, args.store, client=client, workers=args.workers, since=getattr(args, "from"),
                  batch=args.batch, progress=ProgressBar("fleet run: vehicle-days"))
    except ValueError as e:
        raise CliError(str(e)) from None
    finally:
        if client is not None:
            client.close()
    ev = res.events
    vehicles = len(set(ev.column("vehicle").to_pylist()))
    hours = res.log_seconds / 3600
    rate = f", {hours / res.elapsed:.1f} vehicle-hours/s" if res.elapsed > 0 and hours > 0 else ""
    print(f"vehid: fleet run: {res.processed} vehicle-days ({hours:.2f} vehicle-hours) in {res.elapsed:.1f} s{rate}; "
          f"the store holds {ev.num_rows} events on {vehicles} vehicles and {res.problems.num_rows} problems "
          f"({os.path.join(args.store, 'events.parquet')})", file=sys.stderr)
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    """``vehid fleet report STORE -o report.html``."""
    from .report import report

    try:
        n = report(args.store, args.output)
    except ValueError as e:
        raise CliError(str(e)) from None
    except OSError as e:
        raise CliError(f"-o {args.output}: cannot write ({e.strerror or e})") from None
    print(f"vehid: wrote the report of {n} vehicles to {args.output}", file=sys.stderr)
    return 0


def _count(least: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {least}, got {text!r}") from None
        if value < least:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {least}, got {value}")
        return value

    return parse


def _fraction(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a fraction 0..1, got {text!r}") from None
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a fraction 0..1 (e.g. 0.2), got {value}")
    return value


def _hours(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected hours > 0, got {text!r}") from None
    if not (value > 0 and value < 24):
        raise argparse.ArgumentTypeError(f"expected hours of driving a day, 0 < H < 24, got {value}")
    return value


def add_parser(sub: Any) -> None:
    """Adds ``vehid fleet`` and its three commands to the subparsers ``sub``."""
    fleet = sub.add_parser("fleet", help="the health monitor over a fleet's logs, day after day (locally or Dask)",
                           description=DESCRIPTION)
    cmds = fleet.add_subparsers(dest="fleet_command", required=True, metavar="COMMAND")
    sim = cmds.add_parser("simulate", help="write a simulated fleet with injected faults (and truth.parquet)")
    sim.add_argument("dir", metavar="DIR", help="a new or empty directory")
    sim.add_argument("--vehicles", type=_count(1), default=10, help="vehicles (default 10)")
    sim.add_argument("--days", type=_count(1), default=3, help="days per vehicle (default 3)")
    sim.add_argument("--hours", type=_hours, default=0.1, help="hours of driving per day (default 0.1)")
    sim.add_argument("--faults", type=_fraction, default=0.2,
                     help="fraction of the vehicles with one injected fault (default 0.2)")
    sim.add_argument("--seed", type=_count(0), default=1, help="seed (default 1)")
    sim.set_defaults(func=cmd_simulate)
    r = cmds.add_parser("run", help="monitor every vehicle's new days into the store (resumes after its last "
                        "stored day)")
    r.add_argument("dir", metavar="DIR", help="the fleet: DIR/fleet.toml, DIR/vehicle=<id>/day=<YYYY-MM-DD>/*.parquet")
    r.add_argument("--store", required=True, metavar="STORE", help="the store's directory (created if missing)")
    how = r.add_mutually_exclusive_group()
    how.add_argument("--workers", type=_count(1), default=None, help="local threads (default: the CPUs)")
    how.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="a Dask scheduler (e.g. tcp://10.0.0.5:8786): run on its cluster (needs vehid[fleet])")
    r.add_argument("--from", default=None, metavar="DAY",
                   help="recompute every vehicle's days from DAY (YYYY-MM-DD) on, replacing them")
    r.add_argument("--batch", type=_count(1), default=None, help="vehicles per task (default: 1 locally; on Dask "
                   "about 4 tasks per worker, at most 64)")
    r.set_defaults(func=cmd_run)
    rep = cmds.add_parser("report", help="write the store's report: one static HTML page")
    rep.add_argument("store", metavar="STORE", help="the store's directory")
    rep.add_argument("-o", "--output", required=True, metavar="HTML", help="the page to write, e.g. report.html")
    rep.set_defaults(func=cmd_report)

"""``vehid monitor``: the suspension health monitor (:class:`vehid.HealthMonitor`) over a
log of a car's sensors, printing one line per change it finds.

A file or a ROS 2 bag is read through :mod:`vehid.fieldlog` (CSV in any common dialect,
Parquet, ``.mcap``, ``.db3``, a bag folder; ``--columns`` pairs or a ``channels.toml``):
its channels (``a_body, a_wheel, deflection`` for the realistic sensors; the thesis' ``zw,
vw, zb, vb, dzw, dvw, dzb, dvb`` for the state sensors) converted to SI from their declared
units, put on one grid (the log's rate when one clock already runs at it, else 5 ms, or
``--dt``; resampled by :mod:`vehid.align`), the deflection's delay against the
accelerometers estimated and removed, and checked against the named car before the
monitor sees a sample. Standard input (``-``) is read in chunks as a CSV at one fixed rate
(``--dt``, or the nominal interval of the first chunk). A missing value (``nan``, an empty
cell) and a gap in the time column (over 1.5 sample intervals) are missing samples: the
monitor reports "cannot judge" for a while, never a change, and the summary counts them.

Nothing numerical about the suspension happens here: the monitor runs in the Rust core;
this module reads, checks, prints and plots.
"""

from __future__ import annotations

import argparse
import bisect
import datetime
import json
import math
import re
import sys
from dataclasses import dataclass, field
from typing import IO, Any, Callable, Dict, List, Literal, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import NDArray

from . import fieldlog
from ._vehid import Event, FullCar, HalfCar, HealthMonitor, QuarterCar, Simulator, VehidError
from .align import nominal_interval
from .channels import FULL_SENSOR_COLUMNS, HALF_SENSOR_COLUMNS, SENSOR_COLUMNS, event_corner
from .clitools import CliError, run_chunks, stdout, write_output
from .io import Column, Table, TableError, column_factor, match_columns, open_table, parse_column_map
from .reproduce import load_pyplot

#: Samples read per chunk.
CHUNK = 100_000
#: Runs longer than this report their progress on stderr.
PROGRESS_ABOVE = 200_000
#: Seconds between two records of the tracked ratios and the status (plot and summary).
RECORD = 0.5
#: Longest gap fed to the monitor as missing samples, s (:data:`vehid.fieldlog.GAP_CAP`, as
#: ``vehid.fleet``'s): a longer gap (a parked car, a log of several drives) is fed as this many
#: seconds of missing samples, by which time the monitor has long restarted its filters (it
#: keeps its reference and its CUSUMs); the times after it stay on the log's clock. Memory and
#: time are then bounded by the samples logged, not by the gaps' length.
GAP_CAP = fieldlog.GAP_CAP

#: What a load's corner (:func:`vehid.channels.event_corner`) is called in a report line.
CORNER_WORDS = {"f": "the front axle", "r": "the rear axle", "fl": "the front left corner",
                "fr": "the front right corner", "rl": "the rear left corner", "rr": "the rear right corner", "": "?"}
#: What each named constant is, and its unit, for the printed lines.

PARAMETERS = {"b": ("damper", "N s/m"), "k2": ("spring", "N/m"), "M": ("body mass", "kg"),
              "b_f": ("front damper", "N s/m"), "b_r": ("rear damper", "N s/m"),
              "k2_f": ("front spring", "N/m"), "k2_r": ("rear spring", "N/m"),
              **{f"b_{c}": (f"{w} damper", "N s/m") for c, w in
                 (("fl", "front left"), ("fr", "front right"), ("rl", "rear left"), ("rr", "rear right"))},
              **{f"k_{c}": (f"{w} spring", "N/m") for c, w in
                 (("fl", "front left"), ("fr", "front right"), ("rl", "rear left"), ("rr", "rear right"))},
              "arb_f": ("front anti-roll bar", "N m/rad"), "arb_r": ("rear anti-roll bar", "N m/rad")}

CARS: Dict[str, Callable[[], Union[QuarterCar, HalfCar, FullCar]]] = {
    "quarter": QuarterCar, "passenger": QuarterCar.passenger, "half": HalfCar.passenger, "full": FullCar.passenger}


def parse_change(text: str) -> Tuple[float, Dict[str, float], float]:
    """``--change T:NAME=VALUE[,NAME=VALUE][:RAMP]`` of ``vehid simulate``.

    >>> parse_change("60:b=1350"), parse_change("30:k2=19800,b=1400:5")
    ((60.0, {'b': 1350.0}, 0.0), (30.0, {'k2': 19800.0, 'b': 1400.0}, 5.0))
    """
    parts = text.split(":")
    usage = f"--change {text}: expected T:NAME=VALUE[,NAME=VALUE][:RAMP], e.g. 60:b=1350 or 60:b=1350:10"
    if len(parts) not in (2, 3):
        raise CliError(usage)
    try:
        t = float(parts[0])
        ramp = float(parts[2]) if len(parts) == 3 else 0.0
        values: Dict[str, float] = {}
        for item in parts[1].split(","):
            name, sep, value = item.partition("=")
            if not sep:
                raise ValueError
            values[name.strip()] = float(value)
    except ValueError:
        raise CliError(usage) from None
    return t, values, ramp


def drive_car(text: Optional[str], half: bool = False, full: bool = False) -> Union[QuarterCar, HalfCar, FullCar]:
    """``--car`` of a drive: ``passenger`` (default) or ``thesis``, then ``NAME=VALUE``
    overrides (the half car's by their thesis names: ``k12``, ``b1``, ...; the full car, whose
    only documented car is the passenger one, by its own: ``b_fl``, ``M``, ...).

    >>> drive_car("thesis,b=30").params["b"], drive_car(None).params["M"]
    (30.0, 320.0)
    >>> drive_car("b1=1500", half=True).params["b1"], drive_car("thesis", half=True).params["M"]
    (1500.0, 20.0)
    """
    tokens = [t.strip() for t in (text or "").split(",") if t.strip()]
    base = "passenger"
    if tokens and tokens[0] in ("passenger", "thesis"):
        base = tokens.pop(0)
    overrides = ",".join(tokens) or None
    if full:
        if base == "thesis":
            raise CliError("--car thesis: the thesis has no full car; the full car's drive is the passenger car's "
                           "(--car passenger, the default) with your NAME=VALUE overrides")
        return with_constants(FullCar.passenger(), overrides)
    car = with_constants(HalfCar.passenger() if base == "passenger" else HalfCar(), overrides) if half \
        else nominal_car("quarter" if base == "thesis" else "passenger", overrides)
    return car


#: The columns of a drive's true constants (``Run.constants``), per car.
TRUE_COLUMNS = {
    "quarter": ("M", "m", "k1", "k2", "b"),
    "half": ("M", "J", "k11", "k21", "k12", "k22", "b1", "b2", "m1", "m2", "l1", "l2"),
    "full": tuple(FullCar.CONSTANTS),
}


def cmd_simulate_drive(args: argparse.Namespace) -> int:
    """``vehid simulate --road iso8608-C [--model half] [--sensors] [--change ...] [--car ...]``:
    a drive of the quarter or the half car, its sensor channels, distance and true constants as
    CSV."""
    if args.model not in ("quarter", "half", "full"):
        raise CliError(f"--model {args.model}: a drive (--road iso8608-A..E, --sensors, --change) simulates the "
                         "quarter car (--model quarter), the half car (--model half) or the full car (--model full), "
                         "with --car passenger (default), thesis or your constants")
    half, full = args.model == "half", args.model == "full"
    if args.road in ("white", "independent"):
        raise CliError("--sensors and --change apply to a drive on an ISO 8608 road: give --road iso8608-A..E")
    for given, name in ((args.input or args.params or args.x0, "--input/--params/--x0"),
                        (args.method != "rk4", "--method"), (args.ic_sigma != 0.0, "--ic-sigma")):
        if given:
            raise CliError(f"{name} does not apply to a drive (the road's roughness is its class)")
    to_stdout = args.output == "-"
    if to_stdout:
        stdout()  # closed: said before the work
    car = drive_car(args.car, half=half, full=full)
    sensors: Literal["realistic", "state"] = args.sensors or "realistic"
    kw: Dict[str, Any] = {}
    if sensors == "state":
        kw = {"state_noise": args.state_noise, "deriv_noise": args.deriv_noise}
    sim = Simulator(car, dt=0.005 if args.dt is None else args.dt, road=args.road,
                    speed=15.0 if args.speed is None else args.speed,
                    changes=[parse_change(c) for c in args.change or []], sensors=sensors, seed=args.seed, **kw)

    header = ["t", *(sim.channels or ()), "s", *(f"true_{c}" for c in TRUE_COLUMNS[args.model])]

    def write(out: IO[str]) -> None:
        out.write(",".join(header) + "\n")
        for run in run_chunks(sim, args.n, progress=sys.stderr):
            assert run.s is not None and run.constants is not None  # a drive has both
            data = np.column_stack([run.t, run.y, run.s, run.constants])
            out.writelines(",".join(map(repr, row)) + "\n" for row in data.tolist())

    write_output(args.output, write)
    if to_stdout:
        return 0
    print(f"vehid: wrote {args.n} samples of a drive on {args.road} ({sensors} sensors) to {args.output}",
          file=sys.stderr)
    return 0


def nominal_car(model: str, constants: Optional[str]) -> Union[QuarterCar, HalfCar, FullCar]:
    """The nominal car of ``--model`` with ``--car`` overrides (``"M=320,b=1500"``; the half
    car's constants by their thesis names, ``"b1=1500,k22=21000"``).

    >>> nominal_car("passenger", "b=1400").params["b"], nominal_car("half", "b1=1500").params["b1"]
    (1400.0, 1500.0)
    """
    if model not in CARS:
        if model.endswith(".toml"):
            raise CliError(f"--model {model}: the health monitor covers the quarter car (--model quarter or "
                             "passenger), the half car (--model half) and the full car (--model full), with --car "
                             "for your car's constants")
        raise CliError(f"--model {model}: choose quarter (the thesis' car), passenger (a typical passenger car), "
                         "half (a typical passenger half car) or full (a passenger full car)")
    return with_constants(CARS[model](), constants)


def with_constants(car: Union[QuarterCar, HalfCar, FullCar],
                   constants: Optional[str]) -> Union[QuarterCar, HalfCar, FullCar]:
    """``car`` with ``--car`` overrides ``"NAME=VALUE,..."`` (its own constants' names)."""
    params = dict(car.params)
    for item in (constants or "").split(","):
        if not item.strip():
            continue
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in params:
            raise CliError(f"--car {constants}: expected NAME=VALUE pairs with NAME in {', '.join(params)} "
                             f"(e.g. --car M=320,b=1500), got {item.strip()!r}")
        try:
            params[name] = float(value)
        except ValueError:
            raise CliError(f"--car {constants}: {name}={value.strip()!r} is not a number") from None
    if isinstance(car, FullCar):
        return FullCar(**params)
    if isinstance(car, HalfCar):
        return HalfCar(**params)
    return QuarterCar(**params)


@dataclass
class Record:
    """The tracked ratios and the status every :data:`RECORD` seconds."""

    t: List[float] = field(default_factory=list)
    k2m: List[Tuple[float, float, float]] = field(default_factory=list)
    bm: List[Tuple[float, float, float]] = field(default_factory=list)
    status: List[str] = field(default_factory=list)
    #: Half and full car: each record's change of every corner's spring and damper from the
    #: monitor's first reference (:func:`corner_changes`).
    corners: List[NDArray[np.float64]] = field(default_factory=list)


class Feeder:
    """Feeds samples and missing samples to the monitor in blocks of :data:`RECORD`
    seconds, prints each event as it comes and records what the plot and the summary show."""

    def __init__(self, mon: HealthMonitor, t0: float, out: IO[str], as_json: bool) -> None:
        self.mon, self.t0, self.out, self.as_json = mon, t0, out, as_json
        self.block = max(1, int(round(RECORD / mon.dt)))
        self.record = Record()
        self.events: List[Event] = []
        self.missing = 0
        #: The monitor's first reference (the car as the warm-up found it; half car).
        self.ref0: Optional[Dict[str, Any]] = None
        #: Long gaps: (the monitor's time at which the samples resume, s; the seconds of the gap
        #: not fed, over :data:`GAP_CAP`).
        self.skipped: List[Tuple[float, float]] = []
        #: The monitor's times where the samples resume after a long gap, and the seconds not
        #: fed up to each (for :meth:`clock`, in order).
        self._at: List[float] = []
        self._not_fed: List[float] = []

    def clock(self, t: float) -> float:
        """The log's time of the monitor's time ``t`` (s): ``t0 + t``, plus the seconds of the
        long gaps not fed before it."""
        i = bisect.bisect_right(self._at, t + 1e-9)
        return self.t0 + t + (self._not_fed[i - 1] if i else 0.0)

    def skip(self, seconds: float, at: Optional[float] = None) -> None:
        """A gap's ``seconds`` not fed (beyond :data:`GAP_CAP`), the samples resuming at the
        monitor's time ``at`` (default: now): the times after it move on."""
        at = self.mon.samples * self.mon.dt if at is None else at
        self.skipped.append((at, seconds))
        self._at.append(at)
        self._not_fed.append((self._not_fed[-1] if self._not_fed else 0.0) + seconds)

    def feed(self, y: NDArray[np.float64]) -> None:
        self.missing += int(np.isnan(y).any(axis=1).sum())  # a sample with a missing channel is missing
        for i in range(0, len(y), self.block):
            self._step(y[i : i + self.block])

    def gap(self, samples: int) -> None:
        """``samples`` missing samples (a gap in the time column)."""
        self.missing += samples
        width = len(self.mon.channels)
        while samples > 0:
            k = min(samples, self.block)
            self._step(np.full((k, width), math.nan))
            samples -= k

    def _step(self, y: NDArray[np.float64]) -> None:
        for ev in self.mon.fit(y):
            self.events.append(ev)
            self.print_event(ev)
        est = self.mon.estimate
        self.record.t.append(self.clock(self.mon.samples * self.mon.dt))
        none = (math.nan, math.nan, math.nan)
        self.record.k2m.append(est.get("k2/M", none))  # the quarter car's ratios (the plot)
        self.record.bm.append(est.get("b/M", none))
        self.record.status.append(self.mon.status)
        if "front" in est or "fl" in est:
            if self.ref0 is None:
                self.ref0 = self.mon.reference
            self.record.corners.append(corner_changes(est, self.ref0))


    def print_event(self, ev: Event) -> None:
        if self.as_json:
            d: Dict[str, Any] = ev.to_dict()
            d["t"] = round(self.clock(ev.t), 9)
            d["t_change"] = round(self.clock(ev.t_change), 9)
            d["name"] = PARAMETERS[ev.parameter][0]
            d["unit"] = PARAMETERS[ev.parameter][1]
            print(json.dumps(d), file=self.out, flush=True)
            return
        name, unit = PARAMETERS[ev.parameter]
        at = "" if ev.position is None else (
            f"; a load at x {ev.position[0]:+.1f} m, y {ev.position[1]:+.1f} m from the centre of mass, toward "
            f"{CORNER_WORDS[event_corner(ev.parameter, ev.position) or '']}")
        print(f"{self.clock(ev.t):.3f} s  {ev.parameter} ({name}): {ev.before:.6g} -> {ev.after:.6g} {unit} "
              f"({100 * ev.change:+.1f} %; 95 % interval {ev.low:.6g} .. {ev.high:.6g}; "
              f"onset {self.clock(ev.t_change):.2f} s{at})", file=self.out, flush=True)


#: The half car's suspension constants in the order of its coefficients
#: ``[α k2_f, α b_f, α k2_r, α b_r]`` (the monitor's estimate), as the plot names them.
HALF_PLOTTED = (("k2_f", "front spring"), ("b_f", "front damper"), ("k2_r", "rear spring"), ("b_r", "rear damper"))

#: The full car's corners in the order of its body-corner equations and coefficients
#: (``HealthMonitor.estimate``: corner ``i``'s equation holds ``α_ii k_i`` at ``2i`` and
#: ``α_ii b_i`` at ``2i + 1``), with the plot's words.
FULL_CORNERS = (("fl", "front left"), ("fr", "front right"), ("rl", "rear left"), ("rr", "rear right"))


def corner_changes(est: Dict[str, Any], ref: Optional[Dict[str, Any]]) -> NDArray[np.float64]:
    """The half or full car's tracked change of each corner's spring and damper from the
    monitor's reference: an array ``[constant, (value, low, high)]`` of relative changes (0.1 is
    +10 %), the constants in the order of the coefficients (half car: ``k2_f, b_f, k2_r, b_r``;
    full car: ``k_fl, b_fl, k_fr, b_fr, k_rl, b_rl, k_rr, b_rr``). Corner ``i``'s constants are
    read from its own body-corner equation, coefficients ``2i`` and ``2i + 1``: there each is
    ``α_ii`` times the constant (half car: ``1/M + a²/J`` at the front, ``b²`` at the rear; full
    car: ``1/M + x_i²/Jy + y_i²/Jx``), which the ratio to the reference cancels,
    ``α θ̂ / (α θ_ref) − 1``. (In another corner's equation the factor ``α_ij`` can be near zero
    for a car whose inertias are near ``M`` times the products of the distances, so that
    coefficient's relative change is mostly noise; the monitor weighs all of them by their
    covariance.) NaN during the warm-up (no reference yet)."""
    corners = ["front", "rear"] if "front" in est else [c for c, _ in FULL_CORNERS]
    out = np.full((2 * len(corners), 3), math.nan)
    if ref is None:
        return out
    for i, corner in enumerate(corners):
        for j in (2 * i, 2 * i + 1):
            r = ref[corner][j]
            if r != 0:
                out[j] = np.asarray(est[corner][j], dtype=np.float64) / r - 1.0
    return out


def _time_steps(t: NDArray[np.float64], prev: Optional[float], dt: float, table: Table,
                lines: NDArray[np.int64], prev_line: int) -> Tuple[NDArray[np.int64], Dict[int, Tuple[float, str]]]:
    """Missing samples before each sample: ``round(Δt/dt) − 1``, at most :data:`GAP_CAP`
    seconds of them, and for each longer gap (by the sample's index) its length (s) and its
    line; refuses a time that does not increase, or an interval under half of ``dt``."""
    tt = t if prev is None else np.concatenate([[prev], t])
    ll = lines if prev is None else np.concatenate([[prev_line], lines])
    d = np.diff(tt)
    if len(d) and not (d >= 0.5 * dt).all():
        i = int(np.argmin(d >= 0.5 * dt))
        where = table.where(int(ll[i + 1]))
        if d[i] <= 0:
            raise CliError(f"{where}: time {float(tt[i + 1])!r} s does not increase after {float(tt[i])!r} s: "
                             "the time column must increase strictly (sort the log, drop duplicated samples)")
        raise CliError(f"{where}: the sample interval {float(d[i]):.6g} s is under half the sample interval "
                         f"{dt:.6g} s: the monitor needs a fixed rate (resample the log, or give --dt)")
    cap = int(round(GAP_CAP / dt))
    grid = np.rint(np.minimum(d / dt, 2.0**52))  # grid intervals from each sample to the next
    steps = (np.minimum(grid, cap + 1) - 1).astype(np.int64)
    first = 0 if prev is not None else 1  # steps[i] is before sample i + first
    long = {i + first: (float(d[i]), table.where(int(ll[i + 1]))) for i in np.flatnonzero(grid > cap + 1).tolist()}
    return (steps if prev is not None else np.concatenate([[0], steps]).astype(np.int64)), long


#: The monitor's default tracking window, s (``--window``).
DEFAULT_WINDOW = 6.0


def _health_monitor(car: Union[QuarterCar, HalfCar, FullCar], dt: float, sensors: Literal["realistic", "state"],
                    settings: Dict[str, Any], args: argparse.Namespace, source: str) -> HealthMonitor:
    """The monitor at the sample interval ``dt``; an error the core finds in a setting the
    user never gave is said as what it is: a sample interval (``--dt`` or the time column's)
    that does not fit it."""
    given = (f"--dt {args.dt:g}" if args.dt is not None
             else f"the sample interval {dt:.6g} s (the grid of {source}: its nominal rate, or 5 ms)")
    try:
        return HealthMonitor(car, dt=dt, sensors=sensors, **settings)
    except VehidError as e:
        m = re.match(r"invalid `(\w+)`: (.*)", str(e))
        name = m.group(1) if m else ""
        if name == "window":
            least = f"{10 * dt:.6g}"
            if args.window is None:
                raise CliError(f"{given}: the tracking window (--window, default {DEFAULT_WINDOW:g} s) must span at "
                                 f"least 10 sample intervals: give a shorter --dt, or --window {least} or more") \
                    from None
            raise CliError(f"--window {args.window:g}: expected at least 10 sample intervals ({given}): give "
                             f"--window {least} or more, or a shorter --dt") from None
        if name == "dt" and "settles" in str(e):
            raise CliError(f"{given}: too short a sample interval for the monitor's filters (the deflection "
                             "filter's gain does not settle): give the log's sample interval in seconds, e.g. "
                             "--dt 0.005 for 200 Hz") from None
        if name == "dt":
            raise CliError(f"{given}: the sample interval must be a finite number of seconds > 0") from None
        raise


def cmd_monitor(args: argparse.Namespace) -> int:
    if args.dt is not None and not (math.isfinite(args.dt) and args.dt > 0):
        raise CliError(f"--dt {args.dt:g}: the sample interval must be a finite number of seconds > 0")
    car = nominal_car(args.model or "quarter", args.car)
    sensors: Literal["realistic", "state"] = args.sensors
    settings = {k: getattr(args, k) for k in ("window", "warmup", "min_change", "threshold", "confidence")
                if getattr(args, k) is not None}
    if getattr(args, "noise", None):
        settings["sensor_noise"] = parse_noise(args.noise, sensors)
    # matplotlib before the log: a missing plot extra is said at once, not after the whole run.
    plt = _pyplot() if args.plot else None
    half = isinstance(car, HalfCar)
    if isinstance(car, FullCar):
        channels = FULL_SENSOR_COLUMNS[sensors]
    else:
        channels = (HALF_SENSOR_COLUMNS if half else SENSOR_COLUMNS)[sensors]
    events, track = getattr(args, "events", None), getattr(args, "track", None)
    if events and not events.lower().endswith((".parquet", ".mcap")):  # said before the run, not after
        raise CliError(f"--events {events}: give a .parquet or .mcap file")
    if track and not track.lower().endswith(".parquet"):
        raise CliError(f"--track {track}: give a .parquet file (or --events FILE.mcap for both)")
    if args.file != "-":
        return _monitor_file(args, car, sensors, settings, channels, plt)
    try:
        mapping = parse_column_map(args.columns or [])
    except TableError as e:
        raise CliError(str(e)) from None
    columns = (Column("t", "time", "s"),) + channels
    with open_table(args.file, delimiter=args.delimiter) as table:
        match = match_columns(table.names, columns, mapping, where=table.source)
        absent = [c for c in channels if c.name not in match.index]
        if absent:
            shown = ", ".join(repr(h) for h in table.names[:12]) + (", ..." if len(table.names) > 12 else "")
            raise CliError(
                f"{table.source} has no column {', '.join(c.describe() for c in absent)} for "
                f"--sensors {sensors} (its columns: {shown}); map yours with --columns "
                f"{absent[0].name}=NAME")
        has_t = "t" in match.index
        if not has_t and args.dt is None:
            raise CliError(f"{table.source} has no time column t: give the sample interval with --dt SECONDS")
        cols = ([match.index["t"]] if has_t else []) + [match.index[c.name] for c in channels]
        labels = (["t"] if has_t else []) + [c.describe() for c in channels]
        mon: Optional[HealthMonitor] = None
        feeder: Optional[Feeder] = None
        prev: Optional[float] = None
        prev_line = 0
        samples = 0
        units = [Column("t", "time", "s")] * has_t + list(channels)
        try:  # declared units ([mm], [g], [ms]) to SI
            factors = np.asarray([column_factor(c.unit, table.names[i], f"{table.source}, column {table.names[i]!r}")
                                  for c, i in zip(units, cols)])
        except TableError as e:
            raise CliError(str(e)) from None
        for chunk in table.chunks(cols, labels, CHUNK, missing=True):
            data = table.to_si(chunk.data, factors, chunk.lines, labels)
            if has_t and np.isnan(data[:, 0]).any():
                row = int(np.argmax(np.isnan(data[:, 0])))
                raise CliError(f"{table.where(int(chunk.lines[row]))}: the time is missing (nan): every sample "
                                 "needs its time (drop the sample: the gap is then seen in the time column)")
            y = np.ascontiguousarray(data[:, 1:] if has_t else data)
            if mon is None:
                dt = args.dt
                if dt is None:
                    dt = nominal_interval(data[:, 0])
                    if not math.isfinite(dt):
                        raise CliError(f"{table.source}: one sample cannot give the sample interval: give --dt")
                mon = _health_monitor(car, dt, sensors, settings, args, table.source)
                feeder = Feeder(mon, float(data[0, 0]) if has_t else 0.0, sys.stdout, args.json)
            assert feeder is not None
            if has_t:
                steps, long = _time_steps(data[:, 0], prev, mon.dt, table, chunk.lines, prev_line)
                prev, prev_line = float(data[-1, 0]), int(chunk.lines[-1])
                start = 0
                for g in np.flatnonzero(steps).tolist():
                    feeder.feed(y[start:g])
                    feeder.gap(int(steps[g]))
                    if g in long:
                        seconds, where = long[g]
                        feeder.skip(seconds - (int(steps[g]) + 1) * mon.dt)
                        print(f"vehid: note: {where}: {fieldlog.long_gap_words(seconds)}", file=sys.stderr, flush=True)
                    start = g
                feeder.feed(y[start:])
            else:
                feeder.feed(y)
            samples += len(y)
            if table.size and samples > PROGRESS_ABOVE:
                pct = min(100, 100 * table.consumed // table.size)
                print(f"vehid: monitored {samples} samples ({pct}% of {table.source})", file=sys.stderr, flush=True)
            elif samples > PROGRESS_ABOVE:
                print(f"vehid: monitored {samples} samples", file=sys.stderr, flush=True)
        if mon is None or feeder is None:
            raise CliError(f"{table.source} has no samples")
        summary(feeder, table.source, samples, sys.stderr)
        if plt is not None:
            plot(feeder, car, args.plot, plt)
        if events or track:  # times on the log's clock: its time column's (or 0 at the first sample)
            _export(args, feeder, 0.0)
    return 0


def _monitor_file(args: argparse.Namespace, car: Union[QuarterCar, HalfCar, FullCar],
                  sensors: Literal["realistic", "state"], settings: Dict[str, Any], channels: Sequence[Column],
                  plt: Any) -> int:
    """``vehid monitor`` on a file or a bag (:mod:`vehid.fieldlog`): the channels read in SI,
    put on one grid (resampled where their rates differ, the deflection's delay removed),
    checked against the named car, then fed to the monitor."""
    names = [c.name for c in channels]
    cmap: Optional[fieldlog.ChannelMap] = None
    pairs: List[str] = []
    try:
        for text in args.columns or []:
            if fieldlog.is_channel_map(text):
                if cmap is not None:
                    raise TableError(f"--columns {text}: one channel map at a time ({cmap.path} is given too)")
                cmap = fieldlog.load_channel_map(text, names)
            else:
                pairs.append(text)
        mapping = parse_column_map(pairs)
        log = fieldlog.read_log(args.file, channels, cmap, mapping, args.delimiter, args.dt)
        dt = fieldlog.grid_interval(log, args.dt)
    except TableError as e:
        raise CliError(str(e)) from None
    mon = _health_monitor(car, dt, sensors, settings, args, log.source)
    try:
        al = fieldlog.align(log, dt, cmap.channels if cmap else None)
        if sensors == "realistic" and isinstance(car, QuarterCar):
            p = car.params
            fieldlog.car_check(al, p["k2"] / p["M"], p["b"] / p["M"], _car_words(args))
    except TableError as e:
        raise CliError(str(e)) from None
    noise = dict(settings.get("sensor_noise") or {})
    origin: Dict[str, str] = {k: "declared" for k in noise}
    if sensors == "realistic":
        found = fieldlog.accelerometer_noise(al, log)
        for name, value in found.items():  # the accelerometers' noise: the data's where over the default's
            if name in noise or not math.isfinite(value):
                continue
            if value > NOISE_USED_ABOVE * DEFAULT_NOISE[name]:
                noise[name], origin[name] = value, "from the data"
            else:
                origin[name] = f"the default; the data: {value:.3g} m/s^2"
    if sensors == "realistic" and "deflection" not in noise:  # the one noise that blinds the monitor
        est = fieldlog.deflection_noise(log, dt)
        origin["deflection"] = f"the default; the data: {1e3 * est:.3g} mm" if math.isfinite(est) else "the default"
        if math.isfinite(est) and est > NOISE_USED_ABOVE * fieldlog.DEFAULT_DEFLECTION_NOISE:
            noise["deflection"], origin["deflection"] = est, "from the data"
            al.notes.append(f"the deflection's noise, estimated from the data: {1e3 * est:.3g} mm per sample (the "
                            f"default {1e3 * fieldlog.DEFAULT_DEFLECTION_NOISE:g} mm would blind the monitor): used "
                            "(--noise deflection=M to declare it)")
    if noise != (settings.get("sensor_noise") or {}):
        settings = dict(settings, sensor_noise=noise)
        mon = _health_monitor(car, dt, sensors, settings, args, log.source)
    for note in al.notes:
        print(f"vehid: note: {note}", file=sys.stderr, flush=True)
    t0 = 0.0 if log.absolute else al.t0
    if log.absolute:
        start = datetime.datetime.fromtimestamp(log.origin + al.t0, datetime.timezone.utc).isoformat(
            timespec="milliseconds")
        print(f"vehid: note: times are seconds from the log's start, {start}", file=sys.stderr, flush=True)
    feeder = Feeder(mon, t0, sys.stdout, args.json)
    for at, cut in al.skips:  # the long gaps shortened on the grid
        feeder.skip(cut, at - al.t0)
    feeder.feed(np.ascontiguousarray(al.y))
    summary(feeder, log.source, len(al.y), sys.stderr, noise_words(noise, origin) if sensors == "realistic" else "")
    if plt is not None:
        plot(feeder, car, args.plot, plt)
    if getattr(args, "events", None) or getattr(args, "track", None):
        _export(args, feeder, (log.origin + al.t0) if log.absolute else 0.0)
    return 0


def _export(args: argparse.Namespace, feeder: Feeder, origin: float) -> None:
    """``--events`` and ``--track``: the events and the tracked ratios, times on the log's
    clock (since 1970 for a bag or timestamps: the raw topics' clock)."""
    from . import export

    rec = feeder.record
    k2m, bm = np.asarray(rec.k2m, dtype=np.float64).reshape(-1, 3), np.asarray(rec.bm, dtype=np.float64).reshape(-1, 3)
    track: Dict[str, List[Any]] = {"t": [origin + t for t in rec.t], "status": list(rec.status)}
    for name, v in (("k2_over_M", k2m), ("b_over_M", bm)):
        track[name], track[f"{name}_low"], track[f"{name}_high"] = v[:, 0].tolist(), v[:, 1].tolist(), v[:, 2].tolist()
    rows = export.event_rows(feeder.events, lambda t: origin + feeder.clock(t), PARAMETERS)
    try:
        if args.events:
            export.write_events(args.events, rows, track)
        if args.track:
            export.write_track(args.track, track)
    except TableError as e:
        raise CliError(str(e)) from None


def _car_words(args: argparse.Namespace) -> str:
    """How the user named the nominal car, for messages."""
    given = f"--model {args.model}" if args.model else "--model quarter (the default: the thesis' 10 kg car)"
    return given + (f" --car {args.car}" if args.car else "")


#: ``--noise`` names: the sensor noise standard deviations the monitor assumes.
NOISE_NAMES = ("a_body", "a_wheel", "deflection", "a_body_bias", "a_wheel_bias")
#: The same for the state sensors: every state's and every derivative's white noise, in the
#: channels' own units.
STATE_NOISE_NAMES = ("state", "deriv")


def parse_noise(text: str, sensors: str = "realistic") -> Dict[str, float]:
    """``--noise a_body=0.06,deflection=0.0009`` (m/s^2, m: the sensors' white noise per
    sample at the log's rate; with ``--sensors state``, ``state=1e-4,deriv=0.02``) to the
    monitor's ``sensor_noise``.

    >>> parse_noise("a_body=0.06, deflection=9e-4"), parse_noise("state=1e-4", "state")
    ({'a_body': 0.06, 'deflection': 0.0009}, {'state': 0.0001})
    """
    names = STATE_NOISE_NAMES if sensors == "state" else NOISE_NAMES
    units = "each channel's own units" if sensors == "state" else "m/s^2, m"
    out: Dict[str, float] = {}
    for item in text.split(","):
        if not item.strip():
            continue
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in names:
            raise CliError(f"--noise {text}: expected NAME=VALUE with NAME in {', '.join(names)} "
                             f"({units}; --sensors {sensors}), got {item.strip()!r}")
        try:
            v = float(value)
        except ValueError:
            raise CliError(f"--noise {text}: {name}={value.strip()!r} is not a number") from None
        if not (math.isfinite(v) and v > 0):
            raise CliError(f"--noise {text}: {name} must be a finite number > 0")
        out[name] = v
    return out


#: The monitor's default sensor noise per sample, and the factor over it from which an
#: estimate is used (kept in :mod:`vehid.fieldlog`, which ``vehid inspect`` shares).
DEFAULT_NOISE = fieldlog.DEFAULT_NOISE
NOISE_USED_ABOVE = fieldlog.NOISE_USED_ABOVE


def noise_words(noise: Dict[str, float], origin: Dict[str, str]) -> str:
    """The sensor noise the monitor assumed, for the summary: each sensor's standard deviation
    per sample and where it came from (declared, from the data, the default).

    >>> noise_words({"a_body": 0.0213, "deflection": 9e-4}, {"a_body": "from the data", "deflection": "declared"})
    ... # doctest: +NORMALIZE_WHITESPACE
    'noise per sample: a_body 0.0213 m/s^2 (from the data), a_wheel 0.1 m/s^2 (the default),
     deflection 0.9 mm (declared)'
    """
    parts = []
    for name in ("a_body", "a_wheel", "deflection"):
        value = noise.get(name, DEFAULT_NOISE[name])
        shown = f"{1e3 * value:.3g} mm" if name == "deflection" else f"{value:.3g} m/s^2"
        parts.append(f"{name} {shown} ({origin.get(name, 'the default')})")
    return "noise per sample: " + ", ".join(parts)


def summary(feeder: Feeder, source: str, samples: int, out: IO[str], noise: str = "") -> None:
    """One line on stderr: what was monitored, the events, how much of the time the monitor
    could not judge, and (``noise``) the sensor noise it assumed."""
    st = feeder.record.status
    judged = sum(s in ("monitoring", "settling") for s in st)
    warmup = sum(s == "warmup" for s in st)
    cannot = [s for s in st if s.startswith("cannot judge")]
    reasons: Dict[str, int] = {}
    for s in cannot:
        reasons[s.split(": ", 1)[1]] = reasons.get(s.split(": ", 1)[1], 0) + 1
    why = ", ".join(f"{k} {100 * v / len(st):.0f} %" for k, v in sorted(reasons.items(), key=lambda kv: -kv[1]))
    mon = feeder.mon
    n = len(feeder.events)
    long = ""
    if feeder.skipped:
        k, total = len(feeder.skipped), sum(sec for _, sec in feeder.skipped)
        long = (f", {k} gap{'s' if k != 1 else ''} over {GAP_CAP:g} s fed as {GAP_CAP:g} s of missing samples "
                f"({total:.6g} s not fed)")
    print(f"vehid: {source}: {samples} samples ({mon.samples * mon.dt:.1f} s, {feeder.missing} missing{long}), "
          f"{n} event{'s' if n != 1 else ''}; warm-up {100 * warmup / max(1, len(st)):.0f} %, judged "
          f"{100 * judged / max(1, len(st)):.0f} % of the time"
          + (f", cannot judge {100 * len(cannot) / len(st):.0f} % ({why})" if cannot else "")
          + f"; now {mon.status}" + (f"; {noise}" if noise else ""), file=out, flush=True)


def _pyplot() -> Any:
    """matplotlib's pyplot on the Agg backend (as ``vehid reproduce`` loads it), or the error
    naming the plot extra."""
    plt = load_pyplot()
    if plt is None:
        raise CliError("--plot needs matplotlib: pip install 'vehid[plot]'")
    return plt


def plot(feeder: Feeder, car: Union[QuarterCar, HalfCar, FullCar], path: str, plt: Any) -> None:
    """The tracked ratios with their 95 % bands, the times the monitor could not judge
    (grey) and the events (vertical lines), into ``path`` (PNG, drawn with ``plt``, pyplot)."""
    if isinstance(car, HalfCar):
        _plot_corners(plt, feeder, path, HALF_PLOTTED, 1)
        return
    if isinstance(car, FullCar):
        plotted = [(f"{k}_{c}", f"{words} {what}") for c, words in FULL_CORNERS for k, what in
                   (("k", "spring"), ("b", "damper"))]
        _plot_corners(plt, feeder, path, plotted, 2)
        return
    rec = feeder.record
    t = np.asarray(rec.t)
    judged = _judged(rec)
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(9, 6))
    p = car.params
    for ax, values, name, unit, nominal in (
        (axes[0], rec.k2m, r"$k_2/M$", r"s$^{-2}$", p["k2"] / p["M"]),
        (axes[1], rec.bm, r"$b/M$", r"s$^{-1}$", p["b"] / p["M"]),
    ):
        v = np.asarray(values)
        shown = np.where(judged, v[:, 0], np.nan)
        ax.fill_between(t, np.where(judged, v[:, 1], np.nan), np.where(judged, v[:, 2], np.nan), alpha=0.3,
                        label="95 % band")
        ax.plot(t, shown, lw=1, label="tracked")
        ax.axhline(nominal, color="k", ls=":", lw=1, label="nominal car")
        _mark(ax, feeder, t, judged)
        ax.set_ylabel(f"{name} ({unit})")
    axes[0].legend(loc="lower left", fontsize=8)
    axes[1].set_xlabel("time (s)")
    axes[0].set_title("Tracked ratios (grey: cannot judge; red: events)")
    _save(plt, fig, path)


def _save(plt: Any, fig: Any, path: str) -> None:
    """Lays ``fig`` out and writes it to ``path``; a one-line error if it cannot be written."""
    fig.tight_layout()
    try:
        fig.savefig(path, dpi=100)
    except OSError as e:
        raise CliError(f"--plot {path}: cannot write ({e.strerror or e})") from None
    finally:
        plt.close(fig)


def _judged(rec: Record) -> NDArray[np.bool_]:
    """Per record: could the monitor judge (monitoring or settling)?"""
    return np.array([s in ("monitoring", "settling") for s in rec.status])


def _mark(ax: Any, feeder: Feeder, t: NDArray[np.float64], judged: NDArray[np.bool_]) -> None:
    """Grey where the monitor could not judge; a red line and label at each event."""
    for i in np.flatnonzero(~judged):
        ax.axvspan(t[i] - RECORD, t[i], color="0.85", lw=0)
    for ev in feeder.events:
        ax.axvline(feeder.t0 + ev.t, color="r", lw=1)
        ax.annotate(f"{ev.parameter} {100 * ev.change:+.1f} %", (feeder.t0 + ev.t, 1.0),
                    xycoords=("data", "axes fraction"), va="top", ha="left", color="r", fontsize=8)


def _plot_corners(plt: Any, feeder: Feeder, path: str, plotted: Sequence[Tuple[str, str]], columns: int) -> None:
    """The half or full car: one panel per suspension constant (``plotted``: its name and
    words, in the order of :func:`corner_changes`; the half car's in one column, the full car's
    in two: spring and damper), its change in % from the monitor's first reference (the car as
    the warm-up found it) as its own body-corner equation tracks it, with the 95 % band, the
    times it could not judge and the events."""
    rec = feeder.record
    t = np.asarray(rec.t)
    judged = _judged(rec)
    h = 100.0 * np.asarray(rec.corners).reshape(len(t), len(plotted), 3)
    rows = len(plotted) // columns
    fig, grid = plt.subplots(rows, columns, sharex=True, figsize=(9 * columns, 2.5 * rows), squeeze=False)
    axes = list(grid.flat)
    for j, (ax, (name, words)) in enumerate(zip(axes, plotted)):
        v = np.where(judged[:, None], h[:, j, :], np.nan)
        ax.fill_between(t, v[:, 1], v[:, 2], alpha=0.3, label="95 % band")
        ax.plot(t, v[:, 0], lw=1, label="tracked")
        ax.axhline(0.0, color="k", ls=":", lw=1, label="as after the warm-up")
        _mark(ax, feeder, t, judged)
        ax.set_ylabel(f"{words}\n({name}) change (%)")
    axes[0].legend(loc="lower left", fontsize=8)
    for ax in axes[-columns:]:
        ax.set_xlabel("time (s)")
    fig.suptitle("Tracked change since the warm-up, 95 % bands (grey: cannot judge; red: events)")
    _save(plt, fig, path)


#: ``vehid monitor --help``.
DESCRIPTION = (
    "Runs the suspension health monitor over a log and prints one line per change it finds: which constant "
    "(b damper, k2 spring, M body mass), when, from what to what, with a 95 % interval. Only k2/M and b/M are "
    "observable without a road measurement: equal relative changes of both are the body mass. With --model half "
    "(columns a_body_f, a_body_r, a_wheel_f, a_wheel_r, deflection_f, deflection_r) it names b_f, b_r, k2_f, k2_r "
    "or M (with J scaled alike); with --model full (columns a_body_fl .. a_body_rr, a_wheel_fl .. a_wheel_rr, "
    "deflection_fl .. deflection_rr) b_fl .. b_rr, k_fl .. k_rr or M (with Jx, Jy scaled alike). Missing values "
    "(nan, empty cells) and gaps in the time column make the monitor 'cannot judge' for a while, never report "
    "(a gap over 60 s, a parked car, is fed as 60 s of missing samples; times stay on the log's clock). "
    "Units are converted to SI ([mm] headers, a channels.toml, Parquet metadata), channels at several rates "
    "resampled, the deflection's delay estimated and removed, and the log checked against the named car first "
    "(see vehid inspect). A summary goes to stderr."
)


def add_arguments(p: argparse.ArgumentParser, delimiter: Callable[[str], str]) -> None:
    """The options of ``vehid monitor`` (``delimiter``: the parser of ``--delimiter``)."""
    p.add_argument("file", metavar="FILE",
                   help="CSV or Parquet log, a ROS 2 bag (.mcap, .db3, a bag folder; with --columns channels.toml) "
                        "or '-' for stdin (CSV)")
    p.add_argument("--model", default=None, metavar="MODEL",
                   help="the nominal car: quarter (the thesis' values, default), passenger (M=320 kg, m=40 kg, "
                        "k1=200 kN/m, k2=22 kN/m, b=1500 N s/m) or half (a passenger half car: M=640 kg, "
                        "J=1040 kg m^2, l1=1.2 m, l2=1.5 m, k12/k22=24/22 kN/m, b1/b2=1600/1400 N s/m; columns "
                        "a_body_f, a_body_r, a_wheel_f, a_wheel_r, deflection_f, deflection_r) or full (the "
                        "passenger full car of vehid.FullCar.passenger(); columns a_body_fl .. a_body_rr, "
                        "a_wheel_fl .. a_wheel_rr, deflection_fl .. deflection_rr); --car overrides its constants")
    p.add_argument("--car", default=None, metavar="CONSTANTS",
                   help="your car's nominal constants, e.g. M=320,k2=22000,b=1500 (kg, N/m, N s/m): the 'before' "
                        "of the first events")
    p.add_argument("--sensors", choices=["realistic", "state"], default="realistic",
                   help="realistic (default): columns a_body, a_wheel (m/s^2), deflection (m); state: the thesis' "
                        "zw, vw, zb, vb, dzw, dvw, dzb, dvb")
    p.add_argument("--dt", type=float, default=None,
                   help="the monitor's sample interval, s (default: the log's nominal rate when one clock runs at it, "
                        "else 0.005; channels are resampled to it); without a time column, the log's interval")
    p.add_argument("--columns", action="append", metavar="MAP",
                   help="NAME=COLUMN,...: which file column holds each channel (e.g. a_body=acc_z_body); or a "
                        "channels.toml mapping each channel to a topic (bags, MCAP) or a column, with field, unit "
                        "(m, mm, m/s, mm/s, m/s^2, g), sign, scale, gravity and delay (see docs: field logs)")
    p.add_argument("--noise", default=None, metavar="STDS",
                   help="the sensors' white noise per sample, e.g. a_body=0.06,a_wheel=0.3,deflection=0.0009 "
                        "(m/s^2, m; undeclared: the accelerometers' estimated from the log, the deflection's the "
                        "default 0.0003 unless the log shows over 1.25 times that; the summary says which; standard "
                        "input: the defaults 0.02, 0.1, 0.0003); with --sensors state: state=SW,deriv=SV, every "
                        "state's and derivative's (default 0)")
    p.add_argument("--delimiter", type=delimiter, default=None, metavar="D", help="CSV separator (default: sniffed)")
    p.add_argument("--window", type=float, default=None, help="tracking window T_f, s (default 6)")
    p.add_argument("--warmup", type=float, default=None, help="seconds of data forming the reference (default 20)")
    p.add_argument("--min-change", type=float, default=None,
                   help="smallest relative change worth an event (default 0.05)")
    p.add_argument("--threshold", type=float, default=None, help="CUSUM threshold h (default 8, calibrated)")
    p.add_argument("--confidence", type=float, default=None, help="level of the intervals (default 0.95)")
    p.add_argument("--json", action="store_true", help="one JSON object per event instead of text")
    p.add_argument("--events", default=None, metavar="FILE",
                   help="also write the events to FILE.parquet, or to FILE.mcap with the tracked k2/M, b/M and the "
                        "status (topics /vehid/...; on the bag's clock: Foxglove or PlotJuggler overlay them; "
                        "needs vehid[parquet] or vehid[ros])")
    p.add_argument("--track", default=None, metavar="FILE",
                   help="also write the tracked k2/M and b/M with their 95 %% bands and the status every 0.5 s to "
                        "FILE.parquet")
    p.add_argument("--plot", default=None, metavar="PNG",
                   help="write the tracked ratios with their bands and the events (the half and full car: each "
                        "corner's spring's and damper's change since the warm-up) (needs vehid[plot])")


__all__: Sequence[str] = [
    "DESCRIPTION", "HALF_SENSOR_COLUMNS", "SENSOR_COLUMNS", "add_arguments", "cmd_monitor", "cmd_simulate_drive",
    "drive_car", "nominal_car",
    "parse_change",
]

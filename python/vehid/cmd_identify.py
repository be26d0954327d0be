"""``vehid identify``: read a run (CSV in any common dialect, or Parquet; a file or ``-`` for
stdin), identify the unknown rows of A, and print them, the physical constants and, when the
truth is known (``--truth`` or the file's ``true_*`` columns), ξ (Eq 3.17).

Reading goes through :mod:`vehid.io`, in chunks, so memory stays bounded whatever the
input's length; the identifiers are the core's (``--method kalman``, ``ls``, ``sg``,
``two-axle``, and instrumental variables for ``--road iso8608``). ``--sensors realistic``
is :mod:`vehid.identify_realistic`, a model file (``--model NAME.toml``)
:func:`vehid.model_file.identify`.

>>> kalman_p0(argparse.Namespace(p0="exact", mode="rows"))
'exact'
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import re
import sys
from dataclasses import dataclass, field
from typing import IO, Any, Callable, Dict, List, Literal, Optional, Tuple, Union, cast

import numpy as np
from numpy.typing import NDArray

from . import clitools, model_file
from ._vehid import (
    DEFAULT_DERIV_NOISE,
    DEFAULT_ROAD_SIGMA,
    BatchLeastSquares,
    IVIdentifier,
    KalmanIdentifier,
    LinearModel,
    QuarterCar,
    StochasticGradient,
    Structure,
    TwoAxleIdentifier,
    VehidError,
    ljung_box,
    xi,
)
from .clitools import (
    MODEL_NAMES,
    MODELS,
    CliError,
    delimiter,
    model_arg,
    model_columns,
    parse_floats,
    positive_float,
)
from .identify_realistic import RealisticError, cmd_identify_realistic
from .io import (
    STATES,
    TIME_NAMES,
    Column,
    Table,
    TableError,
    column_factor,
    match_columns,
    normalize,
    open_table,
    parse_column_map,
)

#: A time step longer than this many median sample intervals is reported as a gap.
GAP_FACTOR = 10.0
#: Gap warnings printed one by one; the rest are counted.
GAP_WARNINGS = 5


@dataclass
class Layout:
    """What ``identify`` reads: header positions ``columns`` (in this order in each chunk),
    their message ``labels``, and where in a chunk each quantity is."""

    columns: List[int] = field(default_factory=list)
    labels: List[str] = field(default_factory=list)
    used: Dict[str, str] = field(default_factory=dict)
    t: Optional[int] = None
    x: List[int] = field(default_factory=list)
    dx: List[int] = field(default_factory=list)
    true_x: List[int] = field(default_factory=list)
    true_dx: List[int] = field(default_factory=list)
    u: List[int] = field(default_factory=list)
    s: Optional[int] = None
    #: A drive's true constants (``vehid simulate --road ...``: ``true_M``, ...), every one of
    #: the model's: ``(name, place in a chunk)``.
    constants: List[Tuple[str, int]] = field(default_factory=list)
    #: Per read column, the factor to ``col``'s SI unit from the unit its header declares
    #: (``SuspTravel [mm]``: 0.001).
    scales: List[float] = field(default_factory=list)

    def add(self, col: Column, position: int, header: str) -> int:
        """Reads header column ``position`` as ``col``; its place in a chunk."""
        self.columns.append(position)
        self.labels.append(column_label(col, header))
        self.used[col.name] = header
        self.scales.append(column_factor(col.unit, header, f"column {header.strip()!r} ({col.describe()})"))
        return len(self.columns) - 1


def column_label(col: Column, header: str) -> str:
    """How messages name a file column read as ``col``: ``'x3' (body_pos, m)``,
    ``'body_pos' (x3, m)`` or ``'wheel_z' (x1, wheel_pos, m)``."""
    key = normalize(header)
    if key == col.name:
        parts = [col.alias, col.unit]
    elif key == col.alias or (col.name == "t" and key in TIME_NAMES):
        parts = [col.name, col.unit]
    else:
        parts = [col.name, col.alias, col.unit]
    return f"{header!r} ({', '.join(p for p in parts if p)})"


_NUMBERED = re.compile(r"(x|dx|true_x|true_dx|u)(\d+)")


def _misfits(table: Table, unknown: List[int], name: str, model: LinearModel) -> None:
    """Header names that are run columns of another model: a wrong ``--model``."""
    n, m = model.n_states, model.n_inputs
    numbered = [(_NUMBERED.fullmatch(normalize(table.names[i])), table.names[i]) for i in unknown]
    states = max((int(mt.group(2)) for mt, _ in numbered if mt and mt.group(1) in ("x", "dx")), default=0)
    for mt, header in numbered:
        if mt is None:
            continue
        if mt.group(2).startswith("0"):
            raise CliError(f"{table.source}: column {header!r}: states and inputs are numbered from 1 "
                           f"(x1..x{n}, dx1..dx{n}, u1..u{m})")
        if mt.group(1) in ("x", "dx") and states > n:
            other = {4: "quarter", 8: "half", 14: "full"}.get(states)
            hint = f": use --model {other}" if other else ""
            raise CliError(f"{table.source} has {states} states (x1..x{states}) "
                           f"but the {MODEL_NAMES[name]} has {n}{hint}")
        raise CliError(f"{table.source}: column {header!r} does not fit the {MODEL_NAMES[name]} "
                       f"({n} states, {m} input{'s' if m > 1 else ''})")
    for header in (table.names[i] for i in unknown):
        for other, states_of in STATES.items():
            if other != name and normalize(header) in {a for a, _ in states_of} - {a for a, _ in STATES[name]}:
                raise CliError(f"{table.source}: column {header!r} is a state of the {MODEL_NAMES[other]}: "
                               f"use --model {other}")


def resolve_layout(
    table: Table, name: str, model: LinearModel, mapping: Dict[str, str], no_time: bool, file_truth: bool,
    notes: IO[str], distance: bool = False,
) -> Layout:
    """Matches the header of ``table`` to the columns of a run of ``name``: which to read
    (``distance``: also the distance column ``s``, where there is one)."""
    n, m = model.n_states, model.n_inputs
    cols = model_columns(name)
    match = match_columns(table.names, list(cols.values()), mapping, table.source)
    index = match.index
    _misfits(table, match.unknown, name, model)
    need = [f"x{i}" for i in range(1, n + 1)] + [f"dx{i}" for i in range(1, n + 1)]
    missing = [c for c in need if c not in index]
    if missing:
        if len(table.names) == 1 and table.kind == "csv":
            header = table.names[0]
            shown = header if len(header) <= 40 else header[:37] + "..."
            marks = [c for c in set(header) if not c.isalnum() and c not in "_.-+ \"'[]()"]
            hint = ""
            if marks:
                mark = max(sorted(marks), key=header.count)
                hint = f"; it seems separated by {mark!r} (--delimiter '{mark}')"
            raise CliError(f"{table.source}, line {table.header_line}: the header is one column "
                           f"{shown!r}{hint or ': pass the delimiter with --delimiter'}")
        found_x = max((int(c[1:]) for c in index if re.fullmatch(r"x\d+", c)), default=0)
        other = {4: "quarter", 8: "half", 14: "full"}.get(found_x)
        if other and found_x < n and all(f"x{i}" in index for i in range(1, found_x + 1)):
            raise CliError(f"{table.source} has {found_x} states (x1..x{found_x}) but the {MODEL_NAMES[name]} "
                           f"has {n}: use --model {other}")
        shown = ", ".join(cols[c].describe() for c in missing[:4]) + (", ..." if len(missing) > 4 else "")
        unused = [repr(table.names[i]) for i in match.unknown]
        extra = f"; columns not used: {', '.join(unused[:6])}{', ...' if len(unused) > 6 else ''}" if unused else ""
        raise CliError(f"{table.source}: missing column(s) {shown}{extra}; name them as vehid identify --help lists, "
                       f"or map them, e.g. --columns {missing[0]}=NAME")
    layout = Layout()
    if no_time:
        if "t" in mapping:
            raise CliError("--no-time and --columns t=... contradict each other: drop one")
    elif "t" in index:
        layout.t = layout.add(cols["t"], index["t"], table.names[index["t"]])
    else:
        raise CliError(f"{table.source}: no time column ({', '.join(TIME_NAMES)}): map one with --columns t=NAME, "
                       "or pass --no-time to identify without one")
    layout.x = [layout.add(cols[c], index[c], table.names[index[c]]) for c in need[:n]]
    layout.dx = [layout.add(cols[c], index[c], table.names[index[c]]) for c in need[n:]]
    if file_truth:
        truth = [f"true_x{i}" for i in range(1, n + 1)] + [f"true_dx{r + 1}" for r in model.unknown_rows]
        truth += [f"u{j}" for j in range(1, m + 1)]
        present = [c for c in truth if c in index]
        if len(present) == len(truth):
            layout.true_x = [layout.add(cols[c], index[c], table.names[index[c]]) for c in truth[:n]]
            k = len(model.unknown_rows)
            layout.true_dx = [layout.add(cols[c], index[c], table.names[index[c]]) for c in truth[n:n + k]]
            layout.u = [layout.add(cols[c], index[c], table.names[index[c]]) for c in truth[n + k:]]
        elif present:
            absent = ", ".join(c for c in truth if c not in index)
            print(f"vehid: note: {table.source}: the true_* columns are incomplete (no {absent}): no xi; "
                  "pass --truth for one", file=notes)
    if distance and "s" in index:
        layout.s = layout.add(cols["s"], index["s"], table.names[index["s"]])
    # A drive's true constants, as vehid simulate names them (every one of the model's).
    exact = {h.strip().strip('"'): i for i, h in enumerate(table.names)}
    places = [(c, exact.get(f"true_{c}")) for c in MODELS[name]().params]  # type: ignore[attr-defined]
    unknown = match.unknown
    if file_truth and all(i is not None for _, i in places):
        at = [(c, cast(int, i)) for c, i in places]
        layout.constants = [(c, layout.add(Column(f"true_{c}", None, unit_of(c)), i, table.names[i])) for c, i in at]
        taken = {i for _, i in places}
        unknown = [i for i in unknown if i not in taken]
    unused = [repr(table.names[i]) for i in unknown]
    if unused:
        print(f"vehid: note: {table.source}: ignoring column(s) {', '.join(unused[:8])}"
              f"{', ...' if len(unused) > 8 else ''} (names vehid does not know; map them with --columns)", file=notes)
    return layout


# --- identify: time, truth, progress ------------------------------------------------------


class Intervals:
    """The sample intervals, for their median: all of them up to :attr:`CAP`, then every
    second, fourth, ... one (memory stays bounded on endless input).

    >>> iv = Intervals(cap=4)
    >>> iv.add(np.array([0.1, 0.1, 0.2, 0.1, 0.1, 0.3]))
    >>> iv.stride, iv.median()
    (2, 0.1)
    """

    CAP = 1 << 20

    def __init__(self, cap: Optional[int] = None) -> None:
        self.cap = self.CAP if cap is None else cap
        self.kept: NDArray[np.float64] = np.zeros(0)
        self.stride = 1
        self.count = 0

    def add(self, d: NDArray[np.float64]) -> None:
        start = (-self.count) % self.stride
        self.kept = np.concatenate([self.kept, d[start :: self.stride]])
        self.count += len(d)
        while len(self.kept) > self.cap:
            self.kept = self.kept[::2].copy()
            self.stride *= 2

    def median(self) -> float:
        return float(np.median(self.kept)) if len(self.kept) else math.nan


class TimeCheck:
    """The time column: finite (the reader checks), strictly increasing across chunks; the
    median sample interval; steps longer than :data:`GAP_FACTOR` medians are warned about."""

    def __init__(self, table: Table, name: str, label: str, warn: IO[str]) -> None:
        self.table, self.name, self.label, self.warn = table, name, label, warn
        self.first: Optional[float] = None
        self.last: Optional[float] = None
        self.last_line = 0
        self.intervals = Intervals()
        self.gaps = 0

    def add(self, t: NDArray[np.float64], lines: NDArray[np.int64]) -> None:
        if self.last is None:
            self.first = float(t[0])
            tt, ll = t, lines
        else:
            tt = np.concatenate([[self.last], t])
            ll = np.concatenate([[self.last_line], lines])
        d = np.diff(tt)
        if len(d) and not (d > 0).all():
            i = int(np.argmin(d > 0))
            now, before = float(tt[i + 1]), float(tt[i])
            where = self.table.where(int(ll[i + 1]))
            prev = f"{self.table.unit} {int(ll[i])}"
            if now == before:
                raise CliError(f"{where}: time {now!r} s repeats {prev}: the time column {self.label} must increase "
                               "strictly (drop the duplicated sample)")
            raise CliError(f"{where}: time {now!r} s is before {before!r} s on {prev}: the time column {self.label} "
                           "must increase strictly (sort the file by time)")
        if len(d):
            self.intervals.add(d)
            limit = GAP_FACTOR * self.intervals.median()
            for j in np.flatnonzero(d > limit).tolist():
                self.gaps += 1
                if self.gaps <= GAP_WARNINGS:
                    print(f"vehid: warning: {self.table.where(int(ll[j + 1]))}: time jumps by {float(d[j]):.6g} s "
                          f"({float(d[j]) / self.intervals.median():.3g}x the median sample interval "
                          f"{self.intervals.median():.6g} s)", file=self.warn)
        self.last, self.last_line = float(t[-1]), int(lines[-1])

    def finish(self) -> None:
        if self.gaps > GAP_WARNINGS:
            print(f"vehid: warning: {self.table.source}: {self.gaps} time gaps longer than {GAP_FACTOR:g}x the median "
                  f"sample interval in all (the first {GAP_WARNINGS} shown)", file=self.warn)

    def report(self) -> Dict[str, Any]:
        return {"column": self.name, "start": self.first, "end": self.last,
                "median_interval": _finite_or_none(self.intervals.median()), "gaps": self.gaps}


@dataclass
class RowFit:
    """One unknown row of :class:`TruthFit`: its state's index, the entries of A and the
    inputs its parameters stand for (``a<j>``, ``b<j>``), the fit with those inputs and,
    while they have been zero in every sample, the fit without them."""

    row: int
    entries: List[int]
    inputs: List[int]
    full: BatchLeastSquares
    free: Optional[BatchLeastSquares]

    def chosen(self) -> Tuple[BatchLeastSquares, int]:
        """The fit that gives the row, and its number of parameters."""
        if self.free is None:
            return self.full, len(self.entries) + len(self.inputs)
        return self.free, len(self.entries)


class TruthFit:
    """The true unknown rows of A from a run's noise-free columns, which obey
    ``true_dx = A true_x + B u`` exactly, fitted by the core's least squares.

    Each unknown row is one equation of a :class:`vehid.Structure` (a parameter per entry of
    the row that the model does not hold at zero, and one per input that enters the row, its
    value free) identified by :class:`vehid.BatchLeastSquares` (recursive, nothing stored):
    chunk by chunk, in bounded memory. Where the row's inputs have been zero in every sample
    (a run without road input), the row is fitted without them: they then say nothing of B
    and change nothing in A. :meth:`solve` returns ``None`` and why, when the columns do not
    determine the rows (the core's rank check) or do not follow a linear model exactly (the
    residual variance of the fit, ``stats().sigma2``, against the columns' own size).

    >>> from vehid import Simulator
    >>> car = QuarterCar()
    >>> run = Simulator(car, seed=1).run(200)
    >>> fit = TruthFit(car)
    >>> fit.add(run.x, run.u, run.xdot[:, list(car.unknown_rows)])
    >>> rows, why = fit.solve()
    >>> bool(np.allclose(rows, car.theta, rtol=1e-12, atol=0)), why
    (True, '')
    """

    #: The largest residual, relative to the size of the true derivative, of an exact truth.
    TOLERANCE = 1e-8

    def __init__(self, model: LinearModel) -> None:
        n, m = model.n_states, model.n_inputs
        self.shape = (len(model.unknown_rows), n)
        self.samples = 0
        #: Why the core refused a chunk, if it did (then there is no truth).
        self.refused: Optional[str] = None
        #: Per unknown row, the sum of squares of its true derivative.
        self.sum_squares = np.zeros(len(model.unknown_rows))
        states = [f"x{j + 1}" for j in range(n)]
        inputs = [f"u{j + 1}" for j in range(m)]
        self.rows: List[RowFit] = []
        for i, row in enumerate(model.unknown_rows):
            entries = [j for j in range(n) if not model.structural_zeros[i, j]]
            driving = [j for j in range(m) if model.b[row, j] != 0.0]
            terms = [f"a{j + 1} * {states[j]}" for j in entries]
            forced = [f"b{j + 1} * {inputs[j]}" for j in driving]
            full = BatchLeastSquares(Structure(states, inputs, {states[row]: " + ".join(terms + forced)}))
            free = BatchLeastSquares(Structure(states, inputs, {states[row]: " + ".join(terms)})) if driving else None
            self.rows.append(RowFit(row, entries, driving, full, free))

    def add(self, x: NDArray[np.float64], u: NDArray[np.float64], dx: NDArray[np.float64],
            placed: Callable[[str], str] = str) -> None:
        """The true states ``x``, inputs ``u`` and unknown rows' true derivatives ``dx`` of a
        chunk of samples; ``placed`` words a refusal with its place in the file
        (:meth:`vehid.io.Table.rejected`)."""
        if self.refused is not None:
            return
        x, u = np.ascontiguousarray(x), np.ascontiguousarray(u)
        for i, fit in enumerate(self.rows):
            z = np.zeros_like(x)  # the derivatives of the other states are not read
            z[:, fit.row] = dx[:, i]
            if fit.free is not None and np.any(u[:, fit.inputs] != 0.0):
                fit.free = None
            try:
                fit.full.fit(x, z, u=u)
                if fit.free is not None:
                    fit.free.fit(x, z, u=u)
            except VehidError as e:  # e.g. samples too large for the exact start: no truth, no failure
                self.refused = placed(str(e))
                return
        self.sum_squares += np.einsum("ij,ij->j", dx, dx)
        self.samples += len(x)

    def solve(self) -> Tuple[Optional[NDArray[np.float64]], str]:
        """The true rows (k, n), or ``None`` and why not."""
        if self.refused is not None:
            return None, f"the core's least squares refused them ({self.refused})"
        if any(self.samples < fit.chosen()[1] for fit in self.rows):
            return None, "too few samples to fit the true rows"
        theta = np.zeros(self.shape)
        relative = 0.0
        for i, fit in enumerate(self.rows):
            ident, size = fit.chosen()
            structure = ident.structure
            assert structure is not None  # built on one
            try:
                values = ident.params
                stats = ident.stats() if self.samples > size else None  # none: no residual to measure
            except VehidError:  # the core's rank check: the samples do not determine the row
                return None, "the true states do not excite every direction"
            params = dict(zip(structure.parameters, values.tolist()))
            theta[i, fit.entries] = [params[f"a{j + 1}"] for j in fit.entries]
            squares = 0.0 if stats is None else float(stats.sigma2[0]) * (self.samples - size)
            scale = float(self.sum_squares[i])
            relative = max(relative, math.sqrt(squares / (scale if scale > 0 else 1.0)))
        if relative > self.TOLERANCE:
            return None, f"they do not follow dx = A x + B u exactly (relative residual {relative:.2g})"
        return theta, ""


@dataclass
class Truth:
    """The true rows, where they come from, and the true constants (if known)."""

    theta: NDArray[np.float64]
    source: str
    constants: Optional[Dict[str, float]]


def parse_truth(text: Optional[str], name: str) -> Optional[Truth]:
    """``--truth thesis`` or ``--truth M=10,m=1,...`` (every constant of the model).

    >>> truth = parse_truth("M=10, m=1, k1=90, k2=50, b=40", "quarter")
    >>> truth.source, truth.constants["b"]
    ('--truth M=10,m=1,k1=90,k2=50,b=40', 40.0)
    >>> bool((truth.theta == parse_truth("thesis", "quarter").theta).all())
    True
    >>> parse_truth("M=10,m=1", "quarter")
    Traceback (most recent call last):
    ...
    vehid.clitools.CliError: --truth: missing k1, k2, b: give every constant of the quarter car ...
    """
    if text is None:
        return None
    default = MODELS[name]()
    expected = dict(default.params)  # type: ignore[attr-defined]
    if text.strip() == "thesis":
        return Truth(default.theta, "--truth thesis", expected)
    values: Dict[str, float] = {}
    for item in text.split(","):
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise CliError(f"--truth: {item.strip()!r} is not NAME=VALUE (e.g. --truth {_truth_example(expected)})")
        if key not in expected:
            raise CliError(f"--truth: {key!r} is not a constant of the {MODEL_NAMES[name]} ({', '.join(expected)})")
        try:
            v = float(value)
        except ValueError:
            raise CliError(f"--truth: {key}={value.strip()!r} is not a number") from None
        if not math.isfinite(v):
            raise CliError(f"--truth: {key}={value.strip()} is not a finite number")
        values[key] = v
    missing = [k for k in expected if k not in values]
    if missing:
        raise CliError(f"--truth: missing {', '.join(missing)}: give every constant of the {MODEL_NAMES[name]} "
                       f"(e.g. --truth {_truth_example(expected)}), or --truth thesis")
    try:
        model = MODELS[name](**values)
    except VehidError as e:
        raise CliError(f"--truth: {e}") from None
    return Truth(model.theta, "--truth " + ",".join(f"{k}={v:g}" for k, v in values.items()), values)


def _truth_example(expected: Dict[str, float]) -> str:
    return ",".join(f"{k}={v:g}" for k, v in expected.items())


@dataclass
class Progress:
    """Progress lines on stderr for long inputs (more than
    :data:`vehid.clitools.PROGRESS_ABOVE` samples, known from the file size or seen so far on a
    stream)."""

    out: IO[str]
    source: str
    size: Optional[int]
    chars: int = 0
    samples: int = 0

    def step(self, samples: int, consumed: int) -> None:
        """``samples`` more samples; ``consumed``: how much of the input is read in all."""
        self.samples += samples
        self.chars = consumed
        if self.size and self.chars:
            estimate = self.samples * self.size / self.chars
            if estimate > clitools.PROGRESS_ABOVE:
                pct = min(100, 100 * self.chars // self.size)
                print(f"vehid: identified {self.samples} samples ({pct}% of {self.source})", file=self.out, flush=True)
        elif self.samples > clitools.PROGRESS_ABOVE:
            print(f"vehid: identified {self.samples} samples", file=self.out, flush=True)


# --- identify: the identifiers ----------------------------------------------------------


def parse_p0(text: str) -> Union[str, float, List[float]]:
    """``--p0``: ``"exact"`` (the exact start: least squares on the first samples, no prior)
    or the prior covariance as :func:`parse_floats` reads it.

    >>> parse_p0(" Exact "), parse_p0("1000"), parse_p0("1000,8")
    ('exact', 1000.0, [1000.0, 8.0])
    """
    if text.strip().lower() == "exact":
        return "exact"
    return parse_floats(text)


#: The prior used where the exact start does not apply (modes shared and full, two axles):
#: the thesis' P(0) = 1000 I.
THESIS_P0 = 1000.0


def kalman_p0(args: argparse.Namespace) -> Union[str, float, List[float]]:
    """The ``p0`` the Kalman identifier gets: the exact start unless the user chose a prior,
    or the mode has no exact start (then the thesis' prior, and the report says so).

    >>> kalman_p0(argparse.Namespace(p0="exact", mode="rows"))
    'exact'
    >>> kalman_p0(argparse.Namespace(p0="exact", mode="shared")), kalman_p0(argparse.Namespace(p0=8.0, mode="full"))
    (1000.0, 8.0)
    """
    if args.p0 == "exact" and args.mode != "rows":
        return THESIS_P0
    return cast(Union[str, float, List[float]], args.p0)

Identifier = Union[KalmanIdentifier, StochasticGradient, BatchLeastSquares, TwoAxleIdentifier, IVIdentifier]

#: ``--road`` choices of ``vehid identify``.
ROADS = ("white", "iso8608", "random-walk")


def coloured(args: argparse.Namespace) -> bool:
    """``--road`` names a road that is not white (the equations are differenced, method iv)."""
    return getattr(args, "road", "white") != "white"


def road_options(args: argparse.Namespace, spacing: Union[float, str]) -> Dict[str, Any]:
    """The keywords of ``IVIdentifier`` for ``--road``, with ``spacing`` (m per sample or
    "odometer")."""
    kw: Dict[str, Any] = {"road": args.road, "spacing": spacing}
    if args.min_spacing is not None:
        kw["min_spacing"] = args.min_spacing
    if args.lift_off is not None:
        kw["lift_off"] = (args.lift_off, 1.0 if args.m is None else args.m)
    if args.road == "iso8608" and args.road_cutoff is not None:
        kw["road_cutoff"] = args.road_cutoff
    if args.delay is not None:
        kw["delay"] = args.delay
    return kw


def check_road_args(args: argparse.Namespace) -> None:
    """Refuses ``--road`` settings that do not fit together, before any reading."""
    if not coloured(args):
        if any(v is not None for v in (args.road_cutoff, args.speed, args.delay, args.min_spacing, args.lift_off)):
            raise CliError("--road-cutoff, --speed, --delay, --min-spacing and --lift-off describe a road that is not "
                           "white: add --road iso8608 (or random-walk)")
        return
    if args.method != "kalman":
        raise CliError(f"--road {args.road} identifies by instrumental variables on the differenced equations; "
                       f"--method {args.method} (least squares or a gradient on them) would be biased by the road: "
                       "drop --method")
    if args.road == "random-walk" and args.road_cutoff is not None:
        raise CliError("--road-cutoff is for --road iso8608 (a random walk has no cutoff)")
    if args.delay is not None and args.delay < 1:
        raise CliError(f"--delay must be >= 1 sample, got {args.delay}")
    if args.lift_off is not None and args.model != "quarter":
        raise CliError("--lift-off checks the quarter car's tyre contact (--model quarter)")
    args.method = "iv"


def two_axle_p0(args: argparse.Namespace) -> Union[Literal["exact"], float, None]:
    """``--p0`` of ``--method two-axle``: the full car's rows start exactly by default (least
    squares, no prior: its constants' intervals need it), the half car's from the thesis' prior
    (Ch. VI's figures); ``None`` for more than one value.

    >>> two_axle_p0(argparse.Namespace(p0="exact", model="full", wheel_method="cancel"))
    'exact'
    >>> two_axle_p0(argparse.Namespace(p0="exact", model="half", wheel_method="cancel"))
    1000.0
    """
    if args.p0 == "exact":
        return "exact" if args.model == "full" and args.wheel_method != "thesis" else THESIS_P0
    given = args.p0
    return given if isinstance(given, float) else given[0] if len(given) == 1 else None


def make_identifier(args: argparse.Namespace, model: LinearModel, spacing: Union[float, str] = 1.0) -> Identifier:
    if args.method == "iv":
        return IVIdentifier(model, **road_options(args, spacing))
    if args.method == "kalman":
        return KalmanIdentifier(
            model,
            p0=kalman_p0(args),
            road_sigma=args.road_sigma,
            deriv_noise=args.deriv_noise,
            mode=args.mode,
            reinit=args.reinit,
        )
    if args.method == "sg":
        return StochasticGradient(model, gain=args.gain, h=args.h)
    if args.method == "two-axle":
        if args.model not in ("half", "full"):
            raise CliError("--method two-axle needs --model half or full (two axles on one road)")
        p0 = two_axle_p0(args)
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
    # Memory-bounded: the same least-squares estimate, computed recursively, nothing stored.
    return BatchLeastSquares(model, keep_samples=False)


def feed_batch_least_squares(ls: BatchLeastSquares, r: NDArray[np.float64], z: NDArray[np.float64]) -> None:
    """The one place where ``vehid identify --method ls`` hands its samples over, chunk by
    chunk.

    The identifier is the memory-bounded ``BatchLeastSquares(model, keep_samples=False)``:
    it keeps no samples, only its recursive solution (``storage_bytes`` stays 0), so a file
    of any length is identified in bounded memory, like the recursive methods.
    """
    ls.fit(r, z)  # all or nothing per chunk


def feed(
    ident: Identifier, r: NDArray[np.float64], z: NDArray[np.float64], odometer: Optional[NDArray[np.float64]] = None
) -> None:
    """One chunk into the identifier; every recursive ``fit`` continues where it stopped
    (``odometer``: the distance column, m, for a coloured-road identifier that reads it)."""
    if isinstance(ident, BatchLeastSquares):
        feed_batch_least_squares(ident, r, z)
    elif odometer is not None:
        ident.fit(r, z, u=np.ascontiguousarray(odometer[:, None]))
    else:
        ident.fit(r, z)


#: The share of samples counted off the ground above which ``--lift-off`` flags the constants.
LIFT_WARN = 0.005

#: The methods whose residuals ``vehid identify`` checks for whiteness (least squares: the
#: thesis' white-road assumption).
WHITE_ROAD_METHODS = ("kalman", "ls")

#: Samples (the most recent) whose residuals the whiteness check of ``vehid identify`` reads.
DIAG_SAMPLES = 20_000
#: Lags of that Ljung-Box test.
DIAG_LAGS = 10
#: Its level: a white-noise equation is warned about in 1 % of runs.
DIAG_ALPHA = 0.01


def residual_checks(
    ident: Identifier, model_name: str, rows: List[int], x: NDArray[np.float64], dx: NDArray[np.float64]
) -> List[Dict[str, Any]]:
    """The Ljung-Box whiteness test of each identified equation's residuals at the final
    estimate, on the samples ``x``, ``dx`` (the most recent :data:`DIAG_SAMPLES`): one dict per
    equation with its ``state`` name, ``lb_stat``, ``lb_pvalue`` and ``white`` (p >=
    :data:`DIAG_ALPHA`); an equation without residual variance (noise-free) is left out."""
    out: List[Dict[str, Any]] = []
    if len(x) <= 2 * DIAG_LAGS:
        return out
    res = ident.residuals(x, dx)
    names = STATES.get(model_name)
    for i, row in enumerate(rows):
        try:
            stat, p = ljung_box(res[:, i], lags=DIAG_LAGS)
        except VehidError:
            continue
        state = names[row][0] if names else f"x{row + 1}"
        out.append({"row": row, "state": state, "lb_stat": stat, "lb_pvalue": p, "white": bool(p >= DIAG_ALPHA)})
    return out


def residual_warning(check: Dict[str, Any]) -> str:
    """The one-line warning for an equation whose residuals are not white."""
    wheel = "wheel" in check["state"]
    cause = ("the road input is not white noise (a real road's height is a random walk in distance), so least "
             "squares on this equation is biased, and so are the constants it gives: identify with --road iso8608 "
             "(and --speed or a distance column s)") if wheel else (
             "an input or disturbance the model does not hold enters it (or the sensors' noise is not white): its "
             "estimate and intervals assume white noise")
    return (f"the residuals of d({check['state']})/dt are not white (Ljung-Box Q = {check['lb_stat']:.4g} over "
            f"{DIAG_LAGS} lags, p = {check['lb_pvalue']:.2g}): {cause}")


def road_spacing(
    args: argparse.Namespace, source: str, layout: Layout, first: NDArray[np.float64]
) -> Union[float, str]:
    """The distance per sample for ``--road``: ``--speed`` times the first chunk's median
    sample interval, or "odometer" when the file's distance column ``s`` is read."""
    if args.speed is None:
        if layout.s is None:
            raise CliError(f"--road {args.road} needs the distance travelled: {source} has no distance column s "
                           "(m; map yours with --columns s=NAME), so give the constant speed with --speed M/S")
        return "odometer"
    if layout.t is None or len(first) < 2:
        raise CliError(f"--road {args.road} --speed needs the time column (the distance per sample is speed x the "
                       "sample interval): drop --no-time, or give a distance column s instead")
    dt = float(np.median(np.diff(first[:, layout.t])))
    if not (math.isfinite(dt) and dt > 0):
        raise CliError(f"{source}: the time column's median interval is {dt}: no distance per sample from --speed")
    return float(args.speed * dt)


def method_options(args: argparse.Namespace, ident: Optional[Identifier] = None) -> Dict[str, Any]:
    """The settings that shaped the estimate, for the report (``--road``: as the identifier
    ``ident`` took them, its defaults included)."""
    if args.method == "kalman":
        return {"p0": kalman_p0(args), "road_sigma": args.road_sigma, "deriv_noise": args.deriv_noise,
                "mode": args.mode, "reinit": args.reinit}
    if args.method == "sg":
        return {"gain": args.gain, "h": 1.0 if args.h is None else args.h}
    if args.method == "two-axle":
        return {"p0": two_axle_p0(args), "road_sigma": args.road_sigma,
                "deriv_noise": args.deriv_noise, "spacing": args.spacing, "wheel_method": args.wheel_method}
    if args.method == "iv" and isinstance(ident, IVIdentifier):
        opts: Dict[str, Any] = {"road": ident.road, "delay": ident.delay, "min_spacing": ident.min_spacing}
        if ident.road_cutoff is not None:
            opts["road_cutoff"] = ident.road_cutoff
        opts["distance"] = f"--speed {args.speed} m/s" if args.speed is not None else "the file's column s"
        if ident.lift_off is not None:
            opts["lift_off"] = list(ident.lift_off)
        return opts
    return {}


def physical_identifier(
    args: argparse.Namespace, model: LinearModel, known: Dict[str, float], spacing: Union[float, str] = 1.0
) -> Optional[Union[KalmanIdentifier, IVIdentifier]]:
    """The quarter car's physical structure with the known wheel mass, identified by least
    squares on the same samples (exact start, no gate): its constants come with 95 %
    intervals (``car.physical(stats)``). ``None`` for the other methods and for the half car
    (its physical structure also needs the lever arms, and on one road it is biased: see the
    README's "Models linear in their parameters")."""
    if args.model != "quarter" or args.method not in ("kalman", "ls", "iv"):
        return None
    if args.method == "iv":
        return IVIdentifier(model.structure(known=known), **road_options(args, spacing))
    return KalmanIdentifier(model.structure(known=known), gate=0.0)


#: Posterior / prior variance above which a direction is reported as still leaning on the
#: prior: the data have not reduced its variance tenfold.
PRIOR_WEIGHT = 0.1


def prior_note(args: argparse.Namespace, ident: Identifier, rows: List[int]) -> Optional[str]:
    """When the user chose a prior (``--p0``) and it still carries weight in some entries of
    the rows (posterior variance above :data:`PRIOR_WEIGHT` × the prior's): which entries."""
    if args.method != "kalman" or args.mode != "rows" or kalman_p0(args) == "exact":
        return None
    p0 = np.broadcast_to(np.asarray(kalman_p0(args), dtype=float), (len(rows),))
    cov = np.asarray(cast(KalmanIdentifier, ident).covariance)
    ratio = np.diagonal(cov, axis1=1, axis2=2) / p0[:, None]
    heavy = [f"a[{rows[i]},{j}] ({ratio[i, j]:.2g})" for i, j in zip(*np.nonzero(ratio > PRIOR_WEIGHT))]
    if not heavy:
        return None
    return (f"the prior (--p0) still carries weight in {', '.join(heavy)} (posterior / prior variance): those "
            "entries lean on P(0), not only on the data; the exact start (--p0 exact, the default) has no prior")


def known_masses(args: argparse.Namespace, truth: Optional[Truth] = None,
                 notes: Optional[List[str]] = None) -> Dict[str, float]:
    """The known wheel masses (``--m``; the half car's ``--m1``, ``--m2``; the full car's
    ``--m-fl`` .. ``--m-rr``, each ``--m`` when not given), kg: as given, else from ``--truth``
    when it names them (with a note in ``notes``: a passenger car's 40 kg wheel taken as 1 kg
    made every constant 1/40 of the truth), else the car ``--model`` names: the thesis car's
    1 kg (the report says "known: m = 1 kg"), the full passenger car's 59 kg."""
    names = {"quarter": ("m",), "full": ("m_fl", "m_fr", "m_rl", "m_rr")}.get(args.model, ("m1", "m2"))
    out: Dict[str, float] = {}
    for name in names:
        given = getattr(args, name, None)
        if given is None and args.model == "full":
            given = getattr(args, "m", None)
        if given is None and truth is not None and truth.constants and name in truth.constants:
            given = float(truth.constants[name])
            if notes is not None and given != 1.0:
                notes.append(f"--{name.replace('_', '-')} not given: {name} = {given:g} kg from {truth.source}")
        elif given is None and args.model == "full":
            given = float(MODELS["full"]().params[name])  # type: ignore[attr-defined]
        elif given is None:
            given = 1.0  # the car --model names: the thesis' (the report says "known: m = 1 kg")
        setattr(args, name, given)
        out[name] = given
    return out


def modes(a: NDArray[np.float64]) -> List[Dict[str, float]]:
    """The modes of ``x' = A x``: per oscillating pair (eigenvalue with Im > 0) and per real
    eigenvalue, the natural frequency (Hz, ``|lambda| / 2 pi``) and the damping ratio
    (``-Re lambda / |lambda|``), by frequency. The eigenvalues are the core's
    (:meth:`vehid.LinearModel.poles` of a model with this ``A``).

    >>> [(round(m["frequency_hz"], 3), round(m["damping_ratio"], 3)) for m in modes(np.array([[0, 1], [-4.0, -0.4]]))]
    [(0.318, 0.1)]
    """
    a = np.asarray(a, dtype=np.float64)
    out = []
    for lam in LinearModel(a, np.zeros((len(a), 1)), list(range(len(a)))).poles().tolist():
        if lam.imag < -1e-12 * max(1.0, abs(lam)):
            continue
        mag = float(abs(lam))
        out.append({"frequency_hz": mag / (2 * math.pi), "damping_ratio": -float(lam.real) / mag if mag else 1.0,
                    "real": float(lam.real), "imag": float(lam.imag)})
    return sorted(out, key=lambda m: m["frequency_hz"])


def state_space(model: LinearModel, theta: NDArray[np.float64], physical: Optional[Dict[str, float]]) -> Dict[str, Any]:
    """``--json``'s identified model: ``A`` (the identified rows in the model's structure),
    ``B`` (from the identified physical constants where known, else the model's), and the
    ``modes`` of ``A`` (:func:`modes`); ``None`` entries where ``A`` is not finite."""
    try:
        a = np.asarray(model.a_hat(theta), dtype=np.float64)
    except VehidError:
        return {"A": None, "B": None, "modes": None}
    b = np.asarray(model.b, dtype=np.float64)
    if physical and isinstance(model, QuarterCar):
        try:
            b = np.asarray(QuarterCar(**physical).b, dtype=np.float64)
        except (VehidError, TypeError):
            pass
    if not np.isfinite(a).all():
        return {"A": None, "B": _json_array(b), "modes": None}
    return {"A": _json_array(a), "B": _json_array(b), "modes": modes(a)}


#: Units of the physical constants, by name without the axle digit or corner.
UNITS = {"M": "kg", "m": "kg", "k": "N/m", "b": "N s/m", "J": "kg m^2", "l": "m", "kt": "N/m", "Jx": "kg m^2",
         "Jy": "kg m^2", "track": "m", "arb": "N m/rad"}


def unit_of(name: str) -> str:
    """The unit of a physical constant of the built-in cars.

    >>> unit_of("k12"), unit_of("b_fl"), unit_of("Jy"), unit_of("arb_r"), unit_of("l_f")
    ('N/m', 'N s/m', 'kg m^2', 'N m/rad', 'm')
    """
    base = name.rstrip("0123456789")
    for suffix in ("_fl", "_fr", "_rl", "_rr", "_f", "_r"):
        if base.endswith(suffix):
            base = base[: -len(suffix)]
            break
    return UNITS.get(base, "")


def _seconds(v: Optional[float]) -> str:
    """A time for people: 6 significant digits, but whole seconds and microseconds of a
    timestamp since the epoch.

    >>> _seconds(149.95000000000002), _seconds(1.7e9 + 0.05), _seconds(2.5e-7)
    ('149.95', '1700000000.05', '2.5e-07')
    """
    if v is None:
        return "?"
    if abs(v) >= 1e6:
        return f"{v:.6f}".rstrip("0").rstrip(".")
    return f"{v:.6g}"


def _finite_or_none(v: float) -> Optional[float]:
    return v if math.isfinite(v) else None


def _json_array(a: NDArray[np.float64]) -> Any:
    return [[_finite_or_none(float(v)) for v in row] for row in a]


# --- identify ---------------------------------------------------------------------------


def cmd_identify_file(args: argparse.Namespace) -> int:
    """``identify --model model.toml``: a Structure from a model file."""
    checks: List[TimeCheck] = []
    try:
        mf = model_file.load(args.model)
        with open_table(args.file, delimiter=args.delimiter) as table:

            def time_check(name: str, label: str) -> TimeCheck:
                checks.append(TimeCheck(table, name, label, sys.stderr))
                return checks[-1]

            report = model_file.identify(mf, table, args.method, clitools.CHUNK,
                                         time=None if args.no_time else time_check)
    except model_file.ModelFileError as e:
        raise CliError(str(e)) from None
    for check in checks:
        check.finish()
    if args.json:
        print(json.dumps({"source": args.file, "model": args.model, "method": args.method, **report}))
        return 0
    print(f"{args.file}: {report['samples']} samples, model {args.model}, method {args.method}")
    print()
    level = int(round(100 * (1 - report["alpha"])))
    print(f"  {'parameter':12s} {'estimate':>14s} {'std err':>12s}   {level} % interval")
    for name, v, se, (lo, hi) in zip(report["names"], report["params"], report["bse"], report["conf_int"]):
        print(f"  {name:12s} {v:14.6g} {se:12.4g}   [{lo:.6g}, {hi:.6g}]")
    print()
    print("residual variance per equation: " + ", ".join(f"d{k}/dt {v:.4g}" for k, v in report["sigma2"].items()))
    return 0
def cmd_identify(args: argparse.Namespace) -> int:
    """Runs ``vehid identify`` with parsed arguments."""
    if args.sensors == "realistic":
        try:
            return cmd_identify_realistic(args)
        except RealisticError as e:
            raise CliError(str(e)) from None
    if args.model not in MODELS:
        return cmd_identify_file(args)
    model = MODELS[args.model]()
    n = model.n_states
    try:
        mapping = parse_column_map(args.columns or [])
    except TableError as e:
        raise CliError(str(e)) from None
    truth = parse_truth(args.truth, args.model)
    check_road_args(args)
    mass_notes: List[str] = []
    ident: Optional[Identifier] = make_identifier(args, model)  # option errors before any reading
    structured = None
    known: Dict[str, float] = {}
    with open_table(args.file, delimiter=args.delimiter) as table:
        source = table.source
        layout = resolve_layout(table, args.model, model, mapping, args.no_time, truth is None, sys.stderr,
                                distance=coloured(args) and args.speed is None)
        # A drive's true constants are read from its first row: the wheel masses known from them
        # too (as from --truth), so the physical identifier waits for that row.
        file_constants: Optional[Dict[str, float]] = None
        constants_vary = False
        if not layout.constants:
            known = known_masses(args, truth, mass_notes)
        if coloured(args):  # built at the first chunk, when the distance per sample is known
            ident = None
        elif not layout.constants:
            structured = physical_identifier(args, model, known)
        time = None
        if layout.t is not None:
            time = TimeCheck(table, layout.used["t"], layout.labels[layout.t], sys.stderr)
        fit = TruthFit(model) if layout.true_x else None
        progress = Progress(sys.stderr, source, table.size)
        recent: Tuple[NDArray[np.float64], NDArray[np.float64]] = (np.empty((0, n)), np.empty((0, n)))
        scales = np.asarray(layout.scales) if any(f != 1.0 for f in layout.scales) else None
        for chunk in table.chunks(layout.columns, layout.labels, clitools.CHUNK):
            data = chunk.data if scales is None else table.to_si(chunk.data, scales, chunk.lines, layout.labels)
            if time is not None and layout.t is not None:
                time.add(data[:, layout.t], chunk.lines)
            x, dx = np.ascontiguousarray(data[:, layout.x]), np.ascontiguousarray(data[:, layout.dx])
            odometer = None if layout.s is None else data[:, layout.s]
            if layout.constants:
                values = data[:, [i for _, i in layout.constants]]
                if file_constants is None and len(values):
                    file_constants = {c: float(v) for (c, _), v in zip(layout.constants, values[0])}
                    known = known_masses(args, Truth(model.theta, "the file's true_* constants", file_constants),
                                         mass_notes)
                    if not coloured(args):
                        structured = physical_identifier(args, model, known)
                if file_constants is not None and not (values == np.asarray(list(file_constants.values()))).all():
                    constants_vary = True
            if ident is None:
                spacing = road_spacing(args, source, layout, data)
                ident = make_identifier(args, model, spacing)
                structured = physical_identifier(args, model, known, spacing)
            try:
                feed(ident, x, dx, odometer)
                if structured is not None:
                    feed(structured, x, dx, odometer)
            except VehidError as e:  # a refused sample: named by its line, not its index in the chunk
                raise CliError(table.rejected(str(e), chunk.lines)) from None
            if args.method in WHITE_ROAD_METHODS:  # the residuals' whiteness is checked on the last samples
                recent = (np.concatenate([recent[0], x])[-DIAG_SAMPLES:],
                          np.concatenate([recent[1], dx])[-DIAG_SAMPLES:])
            if fit is not None:
                fit.add(data[:, layout.true_x], data[:, layout.u], data[:, layout.true_dx],
                        functools.partial(table.rejected, lines=chunk.lines))
            progress.step(len(data), table.consumed)
    if time is not None:
        time.finish()
    samples = progress.samples
    if samples < n:
        raise CliError(
            f"{source} has {samples} sample{'s' if samples != 1 else ''}; the {MODEL_NAMES[args.model]} "
            f"needs at least {n} (one per state), and many more for a useful estimate"
        )
    assert ident is not None  # built at the first chunk at the latest, and there was one
    theta = ident.theta
    rows = list(model.unknown_rows)
    # 95 % intervals of the rows' entries, where the identifier keeps the statistics.
    conf_int: Optional[NDArray[np.float64]] = None
    if args.method in ("kalman", "ls", "iv"):
        try:
            stats = cast(Union[KalmanIdentifier, BatchLeastSquares, IVIdentifier], ident).stats()
            conf_int = np.asarray(stats.conf_int).reshape(len(rows), n, 2)
        except VehidError:
            conf_int = None
    intervals: Optional[Dict[str, Tuple[float, float, float]]] = None
    if structured is not None or (args.method == "two-axle" and args.model == "full"):
        # The quarter car's physical structure, or the full car's rows (each track's joint
        # filter's covariance): the constants by the delta method.
        try:
            intervals = model.physical((structured or ident).stats(), **known)
        except VehidError:
            intervals = None
        for mass_note in mass_notes:  # the constants scale with the wheel mass: said with them
            print(f"vehid: note: {mass_note}", file=sys.stderr)
    note = prior_note(args, ident, rows)
    if note is not None:
        print(f"vehid: note: {note}", file=sys.stderr)
    lifted = None
    if args.method == "iv" and args.lift_off is not None:
        lifted = cast(IVIdentifier, structured if structured is not None else ident).lifted
        if lifted > LIFT_WARN * samples:
            print(f"vehid: warning: {source}: the tyre was off the ground, or about to leave it, in {lifted} of "
                  f"{samples} samples ({100 * lifted / samples:.2g} %; tyre force from the accelerations below a fifth "
                  "of the static load): the linear model does not hold there, and the constants are biased (on an "
                  "ISO class E road at 25 m/s, 8-20 %): do not trust them", file=sys.stderr)
    # The white-noise assumption of least squares, checked on the residuals.
    checks = residual_checks(ident, args.model, rows, *recent) if args.method in WHITE_ROAD_METHODS else []
    for check in checks:
        if not check["white"]:
            print(f"vehid: warning: {residual_warning(check)}", file=sys.stderr)
    physical: Optional[Dict[str, float]] = None
    physical_error: Optional[str] = None
    try:
        physical = model.physical(theta, **known)
    except VehidError as e:
        physical_error = str(e)
    if fit is not None:
        true_theta, why = fit.solve()
        if true_theta is None:
            print(f"vehid: note: {source}: no xi from the true_* columns: {why}; pass --truth for one", file=sys.stderr)
        else:  # entries the model holds at zero by its structure (left out of xi) are exactly 0
            try:
                constants: Optional[Dict[str, float]] = model.physical(true_theta, **known)
            except VehidError:
                constants = None
            truth = Truth(true_theta, "the file's true_* columns", constants)
    if file_constants is not None:
        if constants_vary:
            print(f"vehid: note: {source}: the true constants change during the run (a drive's --change): no xi, "
                  "and the wheel masses are the first sample's", file=sys.stderr)
        else:
            try:
                truth = Truth(MODELS[args.model](**file_constants).theta, "the file's true_* constants", file_constants)
            except VehidError as e:
                print(f"vehid: note: {source}: the true_* constants do not make a car ({e}): no xi", file=sys.stderr)
        if structured is None and not (args.method == "two-axle" and args.model == "full"):
            for mass_note in mass_notes:  # said with the constants below otherwise
                print(f"vehid: note: {mass_note}", file=sys.stderr)
    xi_value = xi(truth.theta, theta) if truth is not None else None
    if args.json:
        report = {
            "source": source,
            "model": args.model,
            "method": args.method,
            "options": method_options(args, ident),
            "samples": samples,
            "columns": layout.used,
            "time": None if time is None else time.report(),
            "unknown_rows": rows,
            "theta": _json_array(theta),
            "conf_int": None if conf_int is None else [_json_array(block) for block in conf_int],
            "known": known,
            "physical": physical,
            "physical_intervals": None if intervals is None else {k: list(v) for k, v in intervals.items()},
            "prior_note": note,
            "residual_checks": checks,
            "lifted": lifted,
            "physical_error": physical_error,
            "truth": None if truth is None else {"source": truth.source, "constants": truth.constants},
            "true_theta": None if truth is None else _json_array(truth.theta),
            "xi": None if xi_value is None else _finite_or_none(xi_value),
        }
        report.update(state_space(model, theta, physical))
        print(json.dumps(report, allow_nan=False))
        return 0
    opts = ", ".join(f"{k} {v}" for k, v in method_options(args, ident).items())
    print(f"{source}: {samples} samples, {MODEL_NAMES[args.model]} ({n} states), method {args.method}"
          + (f" ({opts})" if opts else ""))
    if time is None:
        print("time: not read (--no-time)")
    else:
        gaps = f", {time.gaps} gap(s) longer than {GAP_FACTOR:g}x the median (see the warnings)" if time.gaps else ""
        print(f"time: {time.label} from {_seconds(time.first)} to {_seconds(time.last)} s, median sample interval "
              f"{time.intervals.median():.6g} s{gaps}")
    print()
    shown = theta.ravel().tolist() + ([] if truth is None else truth.theta.ravel().tolist())
    width = max(12, max(len(f"{v:.6g}") for v in shown) + 2)
    print("identified rows of A (0-based)" + (", and the true rows" if truth is not None else "") + ":")
    for i, row in enumerate(rows):
        print(f"  row {row}  " + "".join(f"{v:{width}.6g}" for v in theta[i]))
        if conf_int is not None:
            half = (conf_int[i, :, 1] - conf_int[i, :, 0]) / 2
            print("  ± 95 % " + "".join(f"{v:{width}.2g}" for v in half))
        if truth is not None:
            print("  true   " + "".join(f"{v:{width}.6g}" for v in truth.theta[i]))
    print()
    given = ", ".join(f"{k} = {v:g} kg" for k, v in known.items())
    true_constants = truth.constants if truth is not None and truth.constants else {}
    if physical is not None:
        print(f"physical constants (known: {given}):")
        for k, v in physical.items():
            unit = unit_of(k)
            true_v = f"true {true_constants[k]:.6g}" if k in true_constants else ""
            print(f"  {k:3s} = {v:<12.6g} {unit:6s} {true_v}".rstrip())
    else:
        print(f"physical constants (known: {given}): not available: {physical_error}")
    if intervals is not None:
        print()
        how = ("instrumental variables on the differenced equations" if args.method == "iv"
               else "the rows' covariance, delta method" if args.method == "two-axle"
               else "least squares on the same samples")
        print(f"physical constants in the car's physical structure ({how}, known: {given}), 95 % intervals:")
        for k, (v, lo, hi) in intervals.items():
            if k in known or lo == hi:  # given, or fixed by the model (a tyre from B, the geometry)
                continue
            unit = unit_of(k)
            true_v = f"true {true_constants[k]:.6g}" if k in true_constants else ""
            band = f"[{lo:.6g}, {hi:.6g}]"
            print(f"  {k:3s} = {v:<12.6g} {band:24s} {unit:6s} {true_v}".rstrip())
    if truth is not None and xi_value is not None:
        print()
        print(f"xi (Eq 3.17, vs the true rows from {truth.source}) = {xi_value:.6g}")
    return 0


def columns_help() -> str:
    """The column table of ``vehid identify --help``, from :data:`vehid.io.STATES`."""
    out = [
        "columns (matched by name; case and spaces do not matter, a unit in brackets such as 'wheel_pos [mm]'",
        "or 't [ms]' is converted to SI; other columns are ignored; --columns NAME=COLUMN maps any other name):",
        f"  t        time, s (also {', '.join(TIME_NAMES[1:])}): finite and strictly increasing. Irregular",
        "           sampling is fine: nothing in the identifiers' update depends on the sample interval;",
        f"           the median interval is reported, steps over {GAP_FACTOR:g}x it are warned about.",
        "           No time column: pass --no-time.",
    ]
    for name, states in STATES.items():
        cols = model_columns(name)
        out.append(f"  {MODEL_NAMES[name]} (--model {name}): state x, measured derivative dx")
        for i in range(1, len(states) + 1):
            x, dx = cols[f"x{i}"], cols[f"dx{i}"]
            out.append(f"    {x.name:4s} {x.alias or '':16s} {x.unit:6s}  {dx.name:4s} {dx.alias or '':18s} {dx.unit}")
    out += [
        "  true_x1.., true_dx1.. (or true_ + a name above), u1.. (road input, m): the noise-free values",
        "           vehid simulate writes; with them identify fits the true rows and reports xi.",
        "  Also read: CSV separated by , ; tab | or spaces (sniffed), quoted cells, # comment lines, a",
        "  UTF-8 byte-order mark, pandas' index column, CRLF; Parquet with pip install 'vehid[parquet]'.",
    ]
    return "\n".join(out)


def add_parser(sub: Any) -> None:
    """Adds ``vehid identify`` and its options to the subparsers ``sub``."""
    ident = sub.add_parser(
        "identify",
        help="identify the unknown rows of A from a measured run (CSV or Parquet)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Reads a run (CSV or Parquet, a file or - for stdin) of measured states x and their measured "
        "derivatives dx,\nidentifies the unknown rows of A and prints them, the physical constants and, when "
        "the truth is\nknown (--truth, or the true_* columns vehid simulate writes), xi (Eq 3.17).",
        epilog=columns_help(),
    )
    ident.add_argument("file", metavar="FILE", help="CSV or Parquet run, '-' for stdin (CSV)")
    ident.add_argument("--model", required=True, metavar="MODEL", type=model_arg,
                       help="quarter (4 states), half (8 states), full (14 states: FullCar.passenger's B), or a "
                            "model file (.toml: any vehid.Structure, see python/vehid/model_file.py)")
    ident.add_argument("--columns", action="append", metavar="MAP",
                       help="map file columns to the model's names: NAME=COLUMN pairs, comma-separated "
                            "(e.g. x1=wheel_z,dx1=wheel_zdot,t=Zeit), or a file with one NAME = COLUMN per line; "
                            "may be repeated")
    ident.add_argument("--no-time", action="store_true",
                       help="the file has no time column: identify without the time checks")
    ident.add_argument("--delimiter", type=delimiter, default=None, metavar="D",
                       help="CSV delimiter: , ; tab | space (default: sniffed from the header)")
    ident.add_argument("--truth", default=None, metavar="CONSTANTS",
                       help="the true constants, for xi: every one of the model, e.g. M=10,m=1,k1=90,k2=50,b=40, "
                            "or 'thesis' (default: the file's true_* columns if any, else no xi)")
    ident.add_argument("--method", choices=["kalman", "ls", "sg", "two-axle"], default="kalman",
                       help="kalman (Eq 4.3-4.7, default), ls (least squares on every sample, Eq 2.14, computed "
                            "recursively in bounded memory), sg (stochastic gradient), two-axle (half or full car on "
                            "one road, samples every --spacing metres)")
    ident.add_argument("--spacing", type=float, default=0.3,
                       help="two-axle: metres between samples, as simulated (default 0.3)")
    ident.add_argument("--wheel-method", choices=["none", "thesis", "cancel"], default="cancel",
                       help="two-axle: wheel rows by plain rows, Eq 6.14, or road cancellation (default)")
    ident.add_argument("--p0", type=parse_p0, default="exact", metavar="P0",
                       help="kalman: 'exact' (default: the exact start, least squares on the first samples, no "
                            "prior; modes shared/full and two-axle use the thesis' 1000) or a prior covariance "
                            "P(0), one value or one per unknown row, comma-separated")
    ident.add_argument("--road-sigma", type=float, default=DEFAULT_ROAD_SIGMA,
                       help=f"kalman: road input std sigma_u, m, for R (Eq 4.7) (default {DEFAULT_ROAD_SIGMA:g})")
    ident.add_argument("--deriv-noise", type=float, default=DEFAULT_DERIV_NOISE,
                       help=f"kalman: derivative noise std sigma_v, for R (default {DEFAULT_DERIV_NOISE:g})")
    ident.add_argument("--mode", choices=["rows", "shared", "full"], default="rows",
                       help="kalman: decoupled rows (default), one shared covariance (needs the same R and P0 on "
                       "every row, e.g. --road-sigma 0), or the full stacked filter")
    ident.add_argument("--reinit", action="store_true", help="kalman: reinitialize by Eq 4.36")
    ident.add_argument("--gain", choices=["venter", "lyapunov", "ljung"], default="venter",
                       help="sg: gain sequence (default venter)")
    ident.add_argument("--h", type=parse_floats, default=None, metavar="H",
                       help="sg: weights, one value, one per unknown row or one per parameter, comma-separated "
                            "(default 1)")
    ident.add_argument("--road", choices=ROADS, default="white",
                       help="what the unmeasured road input is: white (the thesis' road noise, default: least "
                            "squares is right), or iso8608 / random-walk (a real road, whose height is a random "
                            "walk in distance: least squares is biased there; the equations are differenced by the "
                            "road's shaping filter and identified by instrumental variables, method iv). Needs the "
                            "distance travelled: --speed, or a distance column s (m, e.g. an odometer)")
    ident.add_argument("--road-cutoff", type=float, default=None, metavar="NC",
                       help="--road iso8608: the shaping filter's cutoff, cycles/m (default 0.01, vehid's drives)")
    ident.add_argument("--speed", type=positive_float, default=None,
                       help="--road iso8608/random-walk: the constant speed, m/s (the distance per sample is speed "
                            "x the median sample interval); without it the file's distance column s is read")
    ident.add_argument("--min-spacing", type=float, default=None, metavar="M",
                       help="--road iso8608/random-walk: the least distance between two differenced samples, m "
                            "(default 0.25: a road as a tyre feels it is smooth over shorter stretches; 0: every "
                            "sample, for simulated roads whose increments are independent from sample to sample)")
    ident.add_argument("--lift-off", type=positive_float, default=None, metavar="M",
                       help="--road, quarter car: count the samples where the tyre is off the ground (its force from "
                            "the accelerations near zero), given the body mass M in kg (a nominal value serves) and "
                            "--m, and flag the constants when there are any (the linear model does not hold there)")
    ident.add_argument("--delay", type=int, default=None,
                       help="--road iso8608/random-walk: the instruments' delay in samples (default 1; use 2 when the "
                            "measured states carry white noise, whose difference is correlated over two samples)")
    ident.add_argument("--sensors", choices=["state", "realistic"], default="state",
                       help="state (default): the measured state and its derivative (the thesis' sensors, columns "
                            "zw, vw, zb, vb and their derivatives); realistic: a body and a wheel accelerometer and a "
                            "deflection sensor (columns a_body, a_wheel, deflection; quarter car), which determine "
                            "k2/M and b/M (k2 and b with --M) on any road, never m or k1 (printed as not "
                            "identifiable, with what they need); the half car's a_body_f .. deflection_r (with --M: J, "
                            "k12, k22, b1, b2), the full car's a_body_fl .. deflection_rr (with --M: Jx, Jy, every k "
                            "and b, the anti-roll bars)")
    ident.add_argument("--M", type=positive_float, default=None,
                       help="--sensors realistic: the known body mass M, kg (then k2 and b, else only k2/M and b/M)")
    ident.add_argument("--bandwidth", type=positive_float, default=None,
                       help="--sensors realistic: the state-variable filter's bandwidth, rad/s (default 10; the full "
                            "car's 30)")
    ident.add_argument("--geometry", default=None, metavar="NAME=VALUE,...",
                       help="--model full|half --sensors realistic: the corners' positions, m: the full car's l_f, "
                            "l_r, track_f, track_r (default: the passenger full car's 1.4, 1.7, 1.5, 1.5), the half "
                            "car's l1, l2 (the passenger half car's 1.2, 1.5)")
    ident.add_argument("--block", type=positive_float, default=2.0,
                       help="--sensors realistic: the blocks of the cluster-robust intervals, s (default 2)")
    ident.add_argument("--dt", type=positive_float, default=None,
                       help="--sensors realistic: the sample interval, s, when the log has no time column")
    ident.add_argument("--m", type=positive_float, default=None,
                       help="quarter: known wheel mass m, kg (default: m of --truth, else the thesis car's 1 kg)")
    ident.add_argument("--m1", type=positive_float, default=None,
                       help="half: known front wheel mass m1, kg (default: as --m)")
    ident.add_argument("--m2", type=positive_float, default=None,
                       help="half: known rear wheel mass m2, kg (default: as --m)")
    for corner, where in (("fl", "front left"), ("fr", "front right"), ("rl", "rear left"), ("rr", "rear right")):
        ident.add_argument(f"--m-{corner}", dest=f"m_{corner}", type=positive_float, default=None,
                           help=f"full: known {where} wheel mass m_{corner}, kg (default: --m, else --truth's, "
                                "else the passenger full car's 59 kg)")
    ident.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    ident.set_defaults(func=cmd_identify)

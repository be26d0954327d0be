"""Reading measured runs: CSV in the dialects people's tools write, and Parquet, in chunks.

``vehid identify`` reads its input through this module; it is public so that the same rules
serve scripts. Three pieces:

* **Names.** :data:`STATES` is the one table of what each state of the built-in models is
  (physical name and unit); :func:`run_columns` derives from it every column a run can hold:
  ``t``, ``x1..xn``, ``dx1..dxn``, ``true_x1..``, ``true_dx1..``, ``u1..`` (the names of
  ``vehid simulate``) with their physical aliases (``wheel_pos``, ``d_wheel_pos``, ...).
* **Matching.** :func:`match_columns` finds those columns in a header, by name (case, spaces
  and a trailing unit such as ``[m]`` do not matter) or through an explicit mapping
  (:func:`parse_column_map`, the ``--columns`` option).
* **Reading.** :func:`open_table` opens a CSV file (delimiter ``,`` ``;`` tab ``|`` or
  whitespace, sniffed or given; a UTF-8 byte-order mark; quoted cells; ``#`` comment lines;
  an Excel ``sep=`` line; pandas' unnamed index column; CRLF; decimal commas with ``;`` or
  tab) or a Parquet file (with the optional ``vehid[parquet]`` extra, i.e. pyarrow), ``-``
  for standard input. :meth:`Table.chunks` yields the wanted columns as float64 blocks of at
  most ``rows`` samples with the absolute line number of every sample, so memory stays
  bounded whatever the input (even ``/dev/zero`` or an endless pipe), and every error
  names its line. Errors are :class:`TableError` with a one-line message.

>>> cols = {c.name: c for c in run_columns("quarter", 4, 1)}
>>> cols["x2"].describe(), cols["dx2"].describe()
('x2 (wheel_vel, m/s)', 'dx2 (d_wheel_vel, m/s^2)')
>>> header = ["Time [s]", "wheel_pos", "x2", "body_pos", "Body Vel (m/s)"]
>>> m = match_columns(header, run_columns("quarter", 4, 1), {"x2": "x2"})
>>> sorted(m.index.items())
[('t', 0), ('x1', 1), ('x2', 2), ('x3', 3), ('x4', 4)]

Reading a semicolon-separated table with a comment line and decimal commas:

>>> import io as _io
>>> data = b"# logged 2024-05-01\\nt;x1;dx1\\n0,0;1,5;-2\\n0,1;1,25;-2,5\\n"
>>> with open_table("-", stdin=_io.BytesIO(data)) as table:
...     print(table.names, repr(table.delimiter))
...     for chunk in table.chunks([0, 2], ["t", "dx1"], rows=100):
...         print(chunk.data.tolist(), chunk.lines.tolist())
['t', 'x1', 'dx1'] ';'
[[0.0, -2.0], [0.1, -2.5]] [3, 4]
"""

from __future__ import annotations

import csv
import datetime
import importlib
import io as _stdio
import math
import os
import re
import stat
import sys
import warnings
from dataclasses import dataclass, field
from itertools import repeat
from types import TracebackType
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Type

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "SI_UNIT",
    "STANDARD_GRAVITY",
    "STATES",
    "TIME_UNITS",
    "UNITS",
    "TIME_NAMES",
    "WHITESPACE",
    "Chunk",
    "Column",
    "Match",
    "Table",
    "TableError",
    "match_columns",
    "column_factor",
    "header_unit",
    "normalize",
    "open_table",
    "parse_timestamp",
    "quantity_of",
    "si_factor",
    "parse_column_map",
    "run_columns",
]

#: What each state of the built-in models is: ``(physical name, unit)`` for ``x1..xn`` in
#: order. The one place these names are chosen: the command line's help, its messages,
#: ``vehid demo`` and the README take them from here. The measured derivative ``dxi`` is
#: called ``d_`` + the state's name; the true values ``true_`` + either name.
STATES: Dict[str, Tuple[Tuple[str, str], ...]] = {
    "quarter": (
        ("wheel_pos", "m"),
        ("wheel_vel", "m/s"),
        ("body_pos", "m"),
        ("body_vel", "m/s"),
    ),
    "half": (
        ("front_wheel_pos", "m"),
        ("front_wheel_vel", "m/s"),
        ("rear_wheel_pos", "m"),
        ("rear_wheel_vel", "m/s"),
        ("body_pos", "m"),
        ("body_vel", "m/s"),
        ("pitch", "rad"),
        ("pitch_rate", "rad/s"),
    ),
    "full": (
        ("front_left_wheel_pos", "m"),
        ("front_left_wheel_vel", "m/s"),
        ("front_right_wheel_pos", "m"),
        ("front_right_wheel_vel", "m/s"),
        ("rear_left_wheel_pos", "m"),
        ("rear_left_wheel_vel", "m/s"),
        ("rear_right_wheel_pos", "m"),
        ("rear_right_wheel_vel", "m/s"),
        ("body_pos", "m"),
        ("body_vel", "m/s"),
        ("pitch", "rad"),
        ("pitch_rate", "rad/s"),
        ("roll", "rad"),
        ("roll_rate", "rad/s"),
    ),
}

#: The state channels of a drive with state sensors (``vehid simulate --road iso8608-C --sensors
#: state``), in the order of :data:`STATES`: read as ``x1..`` (and ``d`` + name as ``dx1..``).
DRIVE_STATES: Dict[str, Tuple[str, ...]] = {
    "quarter": ("zw", "vw", "zb", "vb"),
    "half": ("z1", "v1", "z2", "v2", "zb", "vb", "ph", "om"),
    "full": ("z_fl", "v_fl", "z_fr", "v_fr", "z_rl", "v_rl", "z_rr", "v_rr", "zb", "vb", "pitch", "pitch_rate", "roll",
             "roll_rate"),
}

#: Header names taken as the time column ``t`` (after :func:`normalize`), in seconds.
TIME_NAMES = ("t", "time", "time_s", "t_s", "seconds")

#: The ``delimiter`` meaning "runs of spaces or tabs".
WHITESPACE = "whitespace"

#: Candidate delimiters, in the order a tie is broken.
DELIMITERS = (",", ";", "\t", "|")

#: Bytes read from the input at a time.
BLOCK = 1 << 20
#: A line longer than this (bytes) is refused: not a table (e.g. ``/dev/zero``).
MAX_LINE = 1 << 20
#: A header line longer than this (bytes) is refused (the :mod:`csv` module's field limit).
MAX_HEADER = 131_072


class TableError(ValueError):
    """A table vehid cannot read, with a one-line message that names the place."""


def _per_second(unit: str) -> str:
    """The unit of a derivative: ``m`` -> ``m/s``, ``m/s`` -> ``m/s^2``."""
    if not unit:
        return ""
    return unit[:-2] + "/s^2" if unit.endswith("/s") else unit + "/s"


@dataclass(frozen=True)
class Column:
    """One quantity a run can hold: its name (as ``vehid simulate`` writes it), its
    physical alias (``None`` where there is none) and its unit."""

    name: str
    alias: Optional[str]
    unit: str
    #: Further header names taken as this column (a drive's channel names: ``zw``, ``dzw``).
    more: Tuple[str, ...] = ()

    def describe(self) -> str:
        """``"x1 (wheel_pos, m)"``: the name, the alias and the unit, as messages show it."""
        inner = ", ".join(p for p in (self.alias, self.unit) if p)
        return f"{self.name} ({inner})" if inner else self.name

    def names(self) -> Tuple[str, ...]:
        """Every header name (normalized) taken as this column."""
        if self.name == "t":
            return TIME_NAMES
        return ((self.name,) if self.alias is None else (self.name, self.alias)) + self.more


def run_columns(model: str, n_states: int, n_inputs: int) -> List[Column]:
    """The columns of a run of ``model`` (a key of :data:`STATES`, or any other name for a
    model without physical names): ``t``, ``x``, ``dx``, ``true_x``, ``true_dx``, ``u``, ``s``.

    >>> [c.describe() for c in run_columns("half", 8, 2)][6:9]
    ['x6 (body_vel, m/s)', 'x7 (pitch, rad)', 'x8 (pitch_rate, rad/s)']
    """
    table = STATES.get(model, tuple((None, "") for _ in range(n_states)))
    if len(table) != n_states:
        raise ValueError(f"the {model} model has {len(table)} named states, not {n_states}")
    states = [(f"x{i}", alias, unit) for i, (alias, unit) in enumerate(table, start=1)]
    derivs = [(f"d{name}", None if a is None else f"d_{a}", _per_second(u)) for name, a, u in states]
    drive = DRIVE_STATES.get(model, ())
    more = [(d,) for d in drive] + [(f"d{d}",) for d in drive] if drive else [()] * (2 * n_states)
    cols = [Column("t", "time", "s")]
    cols += [Column(name, a, u, m) for (name, a, u), m in zip(states + derivs, more)]
    cols += [Column(f"true_{name}", None if a is None else f"true_{a}", u) for name, a, u in states + derivs]
    cols += [Column(f"u{j}", None, "m") for j in range(1, n_inputs + 1)]
    cols.append(Column("s", "distance", "m"))
    return cols


_UNIT_SUFFIX = re.compile(r"\s*(\[[^\]]*\]|\([^)]*\))\s*$")


def normalize(name: str) -> str:
    """The form in which header names are compared: no surrounding quotes or spaces, no
    trailing unit in brackets, lower case, runs of spaces or dashes as one underscore.

    >>> normalize(' "Wheel Pos [m]" '), normalize("pitch-rate (rad/s)"), normalize("X1")
    ('wheel_pos', 'pitch_rate', 'x1')
    """
    s = name.strip().strip('"').strip()
    s = _UNIT_SUFFIX.sub("", s).strip()
    return re.sub(r"[\s\-]+", "_", s).lower()


# --- units ----------------------------------------------------------------------------

#: Standard gravity, m/s^2 (the ``g`` of accelerations declared in g).
STANDARD_GRAVITY = 9.80665

#: The units vehid converts, by the form they are written in (lower case, no spaces):
#: ``(quantity, factor to SI)``. Quantities: ``length`` (SI m), ``velocity`` (m/s),
#: ``acceleration`` (m/s^2), ``angle`` (rad), ``angular rate`` (rad/s).
UNITS: Dict[str, Tuple[str, float]] = {
    "m": ("length", 1.0), "mm": ("length", 1e-3), "cm": ("length", 1e-2),
    "m/s": ("velocity", 1.0), "mm/s": ("velocity", 1e-3),
    "m/s^2": ("acceleration", 1.0), "m/s2": ("acceleration", 1.0), "m/s\u00b2": ("acceleration", 1.0),
    "m/s/s": ("acceleration", 1.0), "mm/s^2": ("acceleration", 1e-3), "g": ("acceleration", STANDARD_GRAVITY),
    "rad": ("angle", 1.0), "deg": ("angle", math.pi / 180), "rad/s": ("angular rate", 1.0),
    "deg/s": ("angular rate", math.pi / 180),
}
#: The units of a time column: seconds per unit.
TIME_UNITS: Dict[str, float] = {"s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "\u00b5s": 1e-6, "\u03bcs": 1e-6,
                                "ns": 1e-9}
#: The SI unit of each quantity.
SI_UNIT = {"length": "m", "velocity": "m/s", "acceleration": "m/s^2", "time": "s", "angle": "rad",
           "angular rate": "rad/s"}


def header_unit(name: str) -> Optional[str]:
    """The unit a header name declares in a trailing ``[...]`` or ``(...)``, else ``None``.

    >>> header_unit("SuspTravel [mm]"), header_unit("Time (ms)"), header_unit("a_body")
    ('mm', 'ms', None)
    """
    m = _UNIT_SUFFIX.search(name.strip().strip('"'))
    return m.group(1)[1:-1].strip() if m else None


def quantity_of(unit: str) -> str:
    """The quantity of an SI unit as :class:`Column` writes it: ``"m/s^2"`` -> ``"acceleration"``;
    ``""`` for a unit vehid does not convert (rad, ...)."""
    return next((q for q, u in SI_UNIT.items() if u == unit), "")


def si_factor(unit: str, quantity: str, where: str) -> float:
    """The factor that turns values in ``unit`` into SI for ``quantity`` (``length``,
    ``velocity``, ``acceleration`` or ``time``). Raises :class:`TableError` naming ``where``
    (the column or topic) for a unit vehid does not know or one of another quantity.

    >>> si_factor("mm", "length", "x"), si_factor("g", "acceleration", "x"), si_factor("ms", "time", "t")
    (0.001, 9.80665, 0.001)
    """
    key = re.sub(r"\s+", "", unit).replace("**", "^").lower()
    if quantity == "time":
        if key in TIME_UNITS:
            return TIME_UNITS[key]
        raise TableError(f"{where}: unit {unit!r} is not a time unit vehid reads (s, ms, us, ns; or timestamps): "
                         "declare the right one")
    found = UNITS.get(key)
    if found is None:
        known = ", ".join(k for k, (q, _) in UNITS.items() if q == quantity) or "SI"
        raise TableError(f"{where}: unit {unit!r} is unknown; for this channel vehid reads {known}: declare one "
                         "of those (a [unit] header, unit = ... in the channel map)")
    if found[0] != quantity:
        raise TableError(f"{where}: unit {unit!r} is a {found[0]}, but this channel is a {quantity} "
                         f"({SI_UNIT.get(quantity, '?')}): is the column mapped to the right channel?")
    return found[1]


def column_factor(unit: str, header: str, where: str) -> float:
    """The factor that turns header column ``header`` (which may declare its unit, ``[mm]``)
    into ``unit``, the SI unit of the quantity it is read as (``m``, ``m/s``, ``s``, ...): 1
    when it declares none. Raises :class:`TableError` naming ``where`` for a unit vehid does
    not know or one of another quantity.

    >>> column_factor("m", "SuspTravel [mm]", "x"), column_factor("s", "Time (ms)", "t"), column_factor("m", "z", "x")
    (0.001, 0.001, 1.0)
    """
    declared = header_unit(header)
    if not declared:
        return 1.0
    quantity = quantity_of(unit)
    if not quantity:
        return 1.0  # a unit vehid does not convert: read as written
    return si_factor(declared, quantity, where)


def parse_timestamp(text: str) -> Optional[float]:
    """An ISO 8601 timestamp (``2026-11-27 10:15:00.000``, ``2026-11-27T10:15:00Z``,
    ``...+01:00``) as seconds since 1970-01-01 UTC; a timestamp without a zone is taken as
    UTC. ``None`` when ``text`` is not one.

    >>> parse_timestamp("1970-01-01 00:00:01.500"), parse_timestamp("12.5")
    (1.5, None)
    """
    if len(text) < 10 or text[4:5] != "-":
        return None
    try:
        stamp = datetime.datetime.fromisoformat(text.strip())
    except ValueError:
        return None
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=datetime.timezone.utc)
    return (stamp - _EPOCH).total_seconds()


_EPOCH = datetime.datetime(1970, 1, 1, tzinfo=datetime.timezone.utc)


# --- column mapping -------------------------------------------------------------------


def _pairs(text: str, where: str) -> List[Tuple[str, str]]:
    """``"x1=a, dx1 = b"`` -> [("x1", "a"), ("dx1", "b")]; a value may be quoted."""
    out = []
    for item in next(csv.reader([text], skipinitialspace=True)):
        if not item.strip():
            continue
        sep = "=" if "=" in item else ":" if ":" in item else None
        key, value = item.split(sep, 1) if sep else (item, "")
        key, value = key.strip(), value.strip().strip('"').strip("'")
        if not key or not value:
            raise TableError(f"{where}: {item.strip()!r} is not NAME=COLUMN (e.g. x1=wheel_z)")
        out.append((key, value))
    return out


def parse_column_map(texts: Sequence[str]) -> Dict[str, str]:
    """``--columns`` values to one mapping ``{model name: file column}``.

    Each text is either pairs ``NAME=COLUMN`` separated by commas, or the path of a small
    mapping file with one pair per line (``NAME = COLUMN`` or ``NAME = "COLUMN"``, so a TOML
    file works; ``#`` comments and ``[section]`` lines are skipped).

    >>> parse_column_map(["x1=wheel_z,dx1=wheel_zdot", "t = Zeit"])
    {'x1': 'wheel_z', 'dx1': 'wheel_zdot', 't': 'Zeit'}
    """
    mapping: Dict[str, str] = {}
    for text in texts:
        if "=" in text:
            pairs = _pairs(text, "--columns")
        else:
            pairs = _mapping_file(text)
        for key, value in pairs:
            if key in mapping:
                raise TableError(f"--columns: {key!r} is given twice ({mapping[key]!r} and {value!r})")
            mapping[key] = value
    return mapping


def _mapping_file(path: str) -> List[Tuple[str, str]]:
    where = f"--columns {path}"
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_LINE + 1)
    except FileNotFoundError:
        raise TableError(f"{where}: no such file (give NAME=COLUMN pairs or a mapping file)") from None
    except IsADirectoryError:
        raise TableError(f"{where}: is a directory, not a mapping file") from None
    except OSError as e:
        raise TableError(f"{where}: cannot read ({e.strerror})") from None
    if len(raw) > MAX_LINE:
        raise TableError(f"{where}: larger than {MAX_LINE >> 20} MiB: not a mapping file")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise TableError(f"{where}: not a text (UTF-8) file") from None
    pairs: List[Tuple[str, str]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith(("#", "[")):
            continue
        if " #" in line and not line.rstrip().endswith('"'):
            line = line.split(" #", 1)[0]
        pairs += _pairs(line, f"{where}, line {number}")
    return pairs


@dataclass
class Match:
    """Where the columns of a run are in a header: ``index[name]`` is the position of the
    column :class:`Column` ``name``; ``unknown`` the positions of header columns matched to
    nothing (besides an unnamed index column, which is always skipped)."""

    index: Dict[str, int]
    unknown: List[int] = field(default_factory=list)


def _is_index_column(name: str) -> bool:
    """pandas' index: an empty name (``to_csv()``), ``Unnamed: 0`` (after a round trip),
    ``__index_level_0__`` (``to_parquet()``)."""
    index = re.fullmatch(r"unnamed:_?\d+|__index_level_\d+__", normalize(name))
    return name.strip().strip('"') == "" or index is not None


def match_columns(
    header: Sequence[str], columns: Sequence[Column], mapping: Mapping[str, str], where: str = "the file"
) -> Match:
    """Finds ``columns`` in ``header``: through ``mapping`` (model name or alias -> header
    name) first, else by name or alias. Raises :class:`TableError` for a mapping that names
    no known column or no header column, and for a column found twice."""
    norm = [normalize(h) for h in header]
    by_name: Dict[str, Column] = {}
    for col in columns:
        for name in col.names():
            by_name.setdefault(name, col)
    index: Dict[str, int] = {}
    for key, value in mapping.items():
        target = by_name.get(normalize(key))
        if target is None:
            known = ", ".join(c.describe() for c in columns if re.fullmatch(r"t|d?x\d+", c.name))
            raise TableError(f"--columns {key}={value}: {key!r} is not a column name vehid knows here; "
                             f"known: {known}, true_*, u1..")
        if target.name in index:
            raise TableError(f"--columns: {target.describe()} is mapped twice")
        exact = [i for i, h in enumerate(header) if h.strip().strip('"') == value]
        found = exact or [i for i, v in enumerate(norm) if v == normalize(value)]
        if not found:
            shown = ", ".join(repr(h) for h in header[:12]) + (", ..." if len(header) > 12 else "")
            raise TableError(f"--columns {key}={value}: {where} has no column {value!r} (its columns: {shown})")
        if len(found) > 1:
            raise TableError(f"--columns {key}={value}: {where} has {len(found)} columns named {value!r} "
                             f"(columns {', '.join(str(i + 1) for i in found)})")
        index[target.name] = found[0]
    for col in columns:  # a mapped column may serve again under its own name (one sensor, two quantities)
        if col.name in index:
            continue
        names = col.names()
        found = [i for i, v in enumerate(norm) if v in names]
        if len(found) > 1:
            first, second = found[0], found[1]
            if norm[first] == norm[second]:
                raise TableError(f"{where}: column {header[second].strip()!r} appears twice "
                                 f"(columns {first + 1} and {second + 1})")
            raise TableError(f"{where}: columns {header[first].strip()!r} ({first + 1}) and "
                             f"{header[second].strip()!r} ({second + 1}) both give {col.describe()}: "
                             f"choose one with --columns {col.name}=NAME")
        if found:
            index[col.name] = found[0]
    used = set(index.values())
    unknown = [i for i in range(len(header)) if i not in used and not _is_index_column(header[i])]
    return Match(index=index, unknown=unknown)


# --- reading --------------------------------------------------------------------------


#: How the core words the refusal of one sample of those handed over (its index among them).
_REJECTED = re.compile(r"sample (\d+) was rejected \((.*)\); the (identifier|monitor) is unchanged", re.S)


@dataclass
class Chunk:
    """Consecutive samples: ``data`` (samples, columns) float64, all finite, and ``lines``
    the absolute line number (CSV) or 1-based row number (Parquet) of each sample."""

    data: NDArray[np.float64]
    lines: NDArray[np.int64]


class Table:
    """An open table: ``names`` (the header), :meth:`chunks`, and for progress reports
    ``consumed`` out of ``size`` (bytes for CSV, rows for Parquet; ``size`` is ``None`` when
    unknown, as on a pipe). Use as a context manager, or call :meth:`close`."""

    source: str
    names: List[str]
    kind: str = "csv"
    delimiter: Optional[str] = None
    size: Optional[int] = None
    _consumed: int = 0
    #: The word for a sample's place in messages: "line" (CSV) or "row" (Parquet).
    unit: str = "line"
    #: The line of the header (after comment lines); 0 for Parquet.
    header_line: int = 0

    @property
    def consumed(self) -> int:
        """How much of the input has been read: bytes (CSV) or rows (Parquet)."""
        return self._consumed

    def where(self, line: int) -> str:
        """``"run.csv, line 12"``."""
        return f"{self.source}, {self.unit} {line}"

    def to_si(self, data: NDArray[np.float64], factors: Any, lines: NDArray[np.int64],
              labels: Sequence[str]) -> NDArray[np.float64]:
        """``data * factors``: a chunk's columns (``labels``) times their factors to SI; a
        finite cell that the factor takes beyond a float's range is refused naming its place.

        >>> t = Table(); t.source = "run.csv"
        >>> t.to_si(np.array([[1.0, 2.0], [1e308, 3.0]]), np.array([9.80665, 1.0]), np.array([7, 8]),
        ...         ["'a [g]'", "'b'"])
        Traceback (most recent call last):
        vehid.io.TableError: run.csv, line 8, column 'a [g]': 1e+308 times 9.80665 (its unit to SI) is beyond ...
        """
        with np.errstate(over="ignore", invalid="ignore"):
            out = np.asarray(data * factors, dtype=np.float64)
        bad = np.isinf(out) & np.isfinite(data)
        if bad.any():
            r = int(np.argmax(bad.any(axis=1)))
            c = int(np.argmax(bad[r]))
            f = float(np.broadcast_to(np.asarray(factors, dtype=np.float64), data.shape)[r, c])
            raise TableError(f"{self.where(int(lines[r]))}, column {labels[c]}: {float(data[r, c])!r} times {f:g} (its "
                             "unit to SI) is beyond a float's range: drop or repair that sample")
        return out

    def rejected(self, message: str, lines: NDArray[np.int64]) -> str:
        """The core's refusal of one sample of a chunk whose samples are on ``lines`` (as
        :class:`Chunk` gives them), with the sample's place in the file instead of its index
        in the chunk; any other ``message`` as it is.

        >>> t = Table(); t.source = "run.csv"
        >>> t.rejected("sample 2 was rejected (too large); the identifier is unchanged (none of the 4 "
        ...            "samples were applied)", np.array([5, 6, 9, 10]))
        'run.csv, line 9: the identifier rejected this sample (too large)'
        """
        m = _REJECTED.match(message)
        if m is None or int(m.group(1)) >= len(lines):
            return message
        return f"{self.where(int(lines[int(m.group(1))]))}: the {m.group(3)} rejected this sample ({m.group(2)})"

    def chunks(
        self, columns: Sequence[int], labels: Sequence[str], rows: int, missing: bool = False,
        stamps: Sequence[int] = (),
    ) -> Iterator[Chunk]:
        """Yields the header columns ``columns`` (positions in :attr:`names`) in blocks of at
        most ``rows`` samples. ``labels`` name them in messages (``"column 'x3' (body_pos, m)"``).
        A cell that is not a finite number raises :class:`TableError` naming its line; with
        ``missing=True`` NaN (``nan`` in a CSV, null in Parquet) and an empty CSV cell (how data
        loggers write a gap) are kept as missing values (NaN) and only ±inf and text raise.
        ``stamps``: positions in ``columns`` whose CSV cells may be ISO 8601 timestamps
        (``2026-11-27 10:15:00.000``; without a zone, UTC), read as seconds since 1970 (a
        Parquet timestamp column is always read so)."""
        raise NotImplementedError

    def declared_unit(self, column: int) -> Optional[str]:
        """The unit the file declares for header column ``column``: a trailing ``[mm]`` or
        ``(mm)`` in its name, or (Parquet) the field metadata ``unit`` / ``units``; ``None``
        when it declares none."""
        return header_unit(self.names[column])

    def is_timestamp(self, column: int) -> bool:
        """Whether header column ``column`` holds timestamps (a Parquet timestamp type)."""
        return False

    def close(self) -> None:
        """Releases the input (standard input stays open)."""

    def __enter__(self) -> Table:
        return self

    def __exit__(
        self, exc_type: Optional[Type[BaseException]], exc: Optional[BaseException], tb: Optional[TracebackType]
    ) -> None:
        self.close()


def _open_error(path: str, e: OSError) -> TableError:
    if isinstance(e, FileNotFoundError):
        return TableError(f"{path}: no such file")
    if isinstance(e, IsADirectoryError):
        return TableError(f"{path}: is a directory, not a CSV or Parquet file")
    return TableError(f"{path}: cannot open ({e.strerror or e})")


def open_table(path: str, delimiter: Optional[str] = None, stdin: Any = None) -> Table:
    """Opens ``path`` (``"-"``: standard input, or ``stdin`` when given) as a :class:`Table`:
    Parquet when the file starts with Parquet's magic bytes, CSV otherwise. ``delimiter``:
    ``None`` to sniff, one character, or :data:`WHITESPACE`."""
    if path == "-":
        stream = stdin if stdin is not None else sys.stdin
        if stream is None:  # started with stdin closed (<&-)
            raise TableError("-: standard input is closed: give a file name, or pipe the data in")
        raw: Any = getattr(stream, "buffer", stream)
        if isinstance(raw, _stdio.TextIOBase):  # a text stream without bytes below (io.StringIO)
            raw = _TextAsBytes(raw)
        return _CsvTable(raw, "<stdin>", None, delimiter, close=False)
    try:
        f = open(path, "rb")
    except OSError as e:
        raise _open_error(path, e) from None
    try:
        st = os.fstat(f.fileno())
        size = st.st_size if _is_regular(st.st_mode) else None
        magic = f.peek(4)[:4] if size else b""
    except OSError as e:
        f.close()
        raise TableError(f"{path}: cannot read ({e.strerror or e})") from None
    if magic == b"PAR1":
        f.close()
        return _ParquetTable(path)
    return _CsvTable(f, path, size, delimiter, close=True)


def _is_regular(mode: int) -> bool:
    return stat.S_ISREG(mode)


class _TextAsBytes:
    """A text stream (``io.StringIO`` standing in for stdin) read as UTF-8 bytes."""

    def __init__(self, text: Any) -> None:
        self.text = text

    def read1(self, n: int) -> bytes:
        text: str = self.text.read(n)
        return text.encode("utf-8")


def _show(delimiter: Optional[str]) -> str:
    return {"\t": "tab", WHITESPACE: "spaces", None: "spaces"}.get(delimiter, repr(delimiter))


def _option(delimiter: str) -> str:
    return {"\t": "--delimiter tab", WHITESPACE: "--delimiter space"}.get(delimiter, f"--delimiter '{delimiter}'")


def _split(line: str, delimiter: Optional[str]) -> List[str]:
    """The cells of one line (quotes removed)."""
    if delimiter is None or delimiter == WHITESPACE:
        return [c.strip('"') for c in line.split()]
    try:
        return next(csv.reader([line], delimiter=delimiter, skipinitialspace=True), [])
    except csv.Error:  # a cell over the csv module's field limit: no column name or number anyway
        return [c.strip().strip('"') for c in line.split(delimiter)]


def _sniff(header: str, sample: Optional[str]) -> str:
    """The delimiter that splits ``header`` into the most cells (and ``sample``, the first
    data line, into as many); whitespace when none of :data:`DELIMITERS` splits it."""
    best, best_n = None, 1
    for d in DELIMITERS:
        n = len(_split(header, d))
        if n > best_n and (sample is None or len(_split(sample, d)) == n):
            best, best_n = d, n
    if best is None:
        for d in DELIMITERS:  # the data disagree with every candidate: go by the header
            n = len(_split(header, d))
            if n > best_n:
                best, best_n = d, n
    if best is None and len(header.split()) > 1:
        return WHITESPACE
    return best or ","


def _suggest(line: str, width: int, current: Optional[str]) -> str:
    """A hint naming the delimiter that splits ``line`` into ``width`` cells, if any."""
    for d in DELIMITERS + (WHITESPACE,):
        if d != current and len(_split(line, d)) == width and width > 1:
            return f"; it seems separated by {_show(d)} ({_option(d)})"
    return ""


_DECIMAL_COMMA = re.compile(r"^\s*[+-]?\d+,\d+([eE][+-]?\d+)?\s*$")
_BLANK_OR_COMMENT = re.compile(r"^\s*(#|$)")


class _Lines:
    """Numbered text lines of a byte stream, read and decoded a block at a time: a line
    longer than :data:`MAX_LINE`, a NUL byte or a byte that is not UTF-8 is an error naming
    its line, so memory stays bounded whatever the input."""

    def __init__(self, raw: Any, source: str) -> None:
        self.raw = raw
        self.source = source
        self.buf: List[str] = []
        self.tail = b""  # the start of a line whose end is not read yet
        self.eof = False
        self.first = True
        self.next_line = 1  # the number of buf[0]
        self.consumed = 0  # characters handed out (bytes, for ASCII), with the line breaks

    def _read(self) -> bytes:
        try:
            read1 = getattr(self.raw, "read1", None)
            block: bytes = read1(BLOCK) if read1 is not None else self.raw.read(BLOCK)
        except OSError as e:
            raise TableError(f"{self.source}: cannot read ({e.strerror or e})") from None
        return block

    def _decode(self, data: bytes) -> str:
        try:
            return data.decode("utf-8")
        except UnicodeDecodeError as e:
            line = self.next_line + len(self.buf) + data.count(b"\n", 0, e.start)
            raise TableError(f"{self.source}, line {line}: not a text (UTF-8) file (byte 0x{data[e.start]:02x}); "
                             "save it as 'CSV UTF-8' or convert it (iconv -f LATIN1 -t UTF-8)") from None

    def fill(self) -> bool:
        """Reads one block into the buffer; False at the end of the input."""
        if self.eof:
            return False
        block = self._read()
        if self.first:
            while block and len(block) < 4:  # a byte-order mark may come in pieces from a pipe
                more = self._read()
                if not more:
                    break
                block += more
            self.first = False
            block = self._check_start(block)
        if not block:
            if self.tail:
                self.buf.append(self._decode(self.tail))
                self.tail = b""
            self.eof = True
            return False
        nul = block.find(b"\0")
        if nul >= 0:
            line = self.next_line + len(self.buf) + (self.tail + block[:nul]).count(b"\n")
            raise TableError(f"{self.source}, line {line}: a NUL byte: not a text file (a CSV or Parquet file)")
        data = self.tail + block
        cut = data.rfind(b"\n")
        if cut >= 0:
            self.buf.extend(self._decode(data[:cut]).split("\n"))
            data = data[cut + 1 :]
        self.tail = data
        if len(self.tail) > MAX_LINE:
            line = self.next_line + len(self.buf)
            raise TableError(f"{self.source}, line {line}: longer than {MAX_LINE >> 20} MiB without a line break: "
                             "not a CSV table")
        return True

    def _check_start(self, block: bytes) -> bytes:
        if block.startswith(b"\xef\xbb\xbf"):  # UTF-8 byte-order mark, as Excel writes it
            self.consumed += 3
            return block[3:]
        if block.startswith((b"\xff\xfe", b"\xfe\xff")):
            raise TableError(f"{self.source}: not a text (UTF-8) file: UTF-16 (as Excel's 'Unicode Text' writes); "
                             "save it as 'CSV UTF-8' or convert it (iconv -f UTF-16 -t UTF-8)")
        if block.startswith(b"PAR1"):
            raise TableError(f"{self.source}: a Parquet file cannot be read from a pipe (its index is at the end): "
                             "pass its file name")
        if block.startswith(b"\x1f\x8b"):
            raise TableError(f"{self.source}: gzip-compressed; decompress it first "
                             "(gunzip -c FILE | vehid identify - ...)")
        return block

    def take(self, k: int) -> Tuple[int, List[str]]:
        """Up to ``k`` lines (without their line break) and the number of the first."""
        while len(self.buf) < k and self.fill():
            pass
        lines = self.buf[:k]
        del self.buf[:k]
        first = self.next_line
        self.next_line += len(lines)
        self.consumed += sum(map(len, lines)) + len(lines)
        return first, lines

    def peek(self, i: int) -> Optional[str]:
        """Line ``i`` ahead (0: the next one) without taking it, if it is in the first block."""
        while len(self.buf) <= i and not self.eof and len(self.buf) < 10_000:
            if not self.fill():
                break
        return self.buf[i] if i < len(self.buf) else None


class _CsvTable(Table):
    def __init__(self, raw: Any, source: str, size: Optional[int], delimiter: Optional[str], close: bool) -> None:
        self.source, self.size = source, size
        self._raw, self._close = raw, close
        self._lines = _Lines(raw, source)
        self.decimal_comma = False
        try:
            self._read_header(delimiter)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        if self._close:
            self._raw.close()

    @property
    def consumed(self) -> int:
        return self._lines.consumed

    def _read_header(self, delimiter: Optional[str]) -> None:
        lines = self._lines
        given = delimiter
        anything = False
        while True:
            number, got = lines.take(1)
            if not got:
                what = "only comment or blank lines" if anything else "empty file"
                raise TableError(f"{self.source}: {what}; expected a table with a header line "
                                 "(t, x1..xn, dx1..dxn, as vehid simulate -o FILE writes)")
            anything = True
            text = got[0]
            if _BLANK_OR_COMMENT.match(text):
                continue
            sep = re.fullmatch(r"\s*sep=(.)\s*", text)
            if sep:  # Excel's "sep=;" line (--delimiter, if given, wins)
                given = sep.group(1) if given is None else given
                continue
            break
        self.header_line = number
        size = len(text.encode("utf-8"))
        if size > MAX_HEADER:
            raise TableError(f"{self.where(number)}: the header line is {size:,} bytes, over the limit of "
                             f"{MAX_HEADER:,}: write the file with only the columns needed (or shorter names)")
        sample = None
        for i in range(100):
            ahead = lines.peek(i)
            if ahead is None:
                break
            if not _BLANK_OR_COMMENT.match(ahead):
                sample = ahead
                break
        if given is None:
            self.delimiter = _sniff(text, sample)
        else:
            self.delimiter = given
            cells = _split(text, given)
            if len(cells) == 1:
                hint = _suggest(text, max(len(_split(text, d)) for d in DELIMITERS + (WHITESPACE,)), given)
                if hint:
                    raise TableError(f"{self.where(number)}: the header has no {_show(given)}{hint}")
        self.names = [c.strip() for c in _split(text, self.delimiter)]
        if any(self.names) and all(_is_number(c) for c in self.names if c):
            raise TableError(f"{self.where(number)}: the first line holds numbers, not column names: "
                             "add a header line (t, x1..xn, dx1..dxn; see vehid identify --help)")
        self.width = len(self.names)
        if sample is not None and self.delimiter != ",":
            cells = _split(sample, self.delimiter)
            self.decimal_comma = any(_DECIMAL_COMMA.match(c) for c in cells) and not any("." in c for c in cells)

    def _width_error(self, line: str, number: int, cells: int) -> TableError:
        hint = _suggest(line, self.width, self.delimiter)
        return TableError(f"{self.where(number)}: {cells} cell{'s' if cells != 1 else ''}, but the header "
                          f"has {self.width} columns (separated by {_show(self.delimiter)}){hint}")

    def chunks(
        self, columns: Sequence[int], labels: Sequence[str], rows: int, missing: bool = False,
        stamps: Sequence[int] = (),
    ) -> Iterator[Chunk]:
        cols = list(columns)
        delim = None if self.delimiter == WHITESPACE else self.delimiter
        while True:
            first, lines = self._lines.take(rows)
            if not lines:
                return
            if any(map(_BLANK_OR_COMMENT.match, lines)):
                keep = [i for i, s in enumerate(lines) if not _BLANK_OR_COMMENT.match(s)]
                if not keep:
                    continue
                lines = [lines[i] for i in keep]
                numbers = np.asarray(keep, dtype=np.int64) + first
            else:
                numbers = np.arange(first, first + len(lines), dtype=np.int64)
            if self.decimal_comma:
                lines = [s.replace(",", ".") for s in lines]
            self._check_widths(lines, numbers)
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("error")
                    data = np.loadtxt(lines, delimiter=delim, usecols=cols, quotechar='"', comments=None,
                                      ndmin=2, dtype=np.float64)
            except (ValueError, Warning) as e:
                if not (missing or stamps):
                    raise self._cell_error(lines, numbers, cols, labels, str(e)) from None
                data = self._slow_cells(lines, numbers, cols, labels, missing, stamps, str(e))
            finite = np.isfinite(data) | np.isnan(data) if missing else np.isfinite(data)
            if not finite.all():
                row = int(np.argmin(finite.all(axis=1)))
                col = int(np.argmin(finite[row]))
                cell = _split(lines[row], self.delimiter)[cols[col]].strip()
                raise TableError(f"{self.where(int(numbers[row]))}, column {labels[col]}: {_show_cell(cell)} is not a "
                                 "finite number (drop or repair that sample)")
            yield Chunk(data=data, lines=numbers)

    def _slow_cells(
        self, lines: List[str], numbers: NDArray[np.int64], cols: List[int], labels: Sequence[str], missing: bool,
        stamps: Sequence[int], fallback: str
    ) -> NDArray[np.float64]:
        """The cells cell by cell, where the fast reader failed: empty cells as NaN (with
        ``missing``), timestamps in the columns ``stamps`` as seconds since 1970."""
        out = np.empty((len(lines), len(cols)), dtype=np.float64)
        stamp_set = set(stamps)
        for r, (line, number) in enumerate(zip(lines, numbers)):
            cells = _split(line, self.delimiter)
            if len(cells) != self.width:
                raise self._width_error(line, int(number), len(cells))
            for j, col in enumerate(cols):
                cell = cells[col].strip().strip('"').strip()
                if not cell and missing:
                    out[r, j] = math.nan
                    continue
                try:
                    out[r, j] = float(cell)
                    continue
                except ValueError:
                    pass
                seconds = parse_timestamp(cell) if j in stamp_set else None
                if seconds is None:
                    raise self._cell_error([line], numbers[r : r + 1], cols, labels, fallback)
                out[r, j] = seconds
        return out

    def _check_widths(self, lines: List[str], numbers: NDArray[np.int64]) -> None:
        """Every line has as many cells as the header (numpy, given ``usecols``, would not
        notice a line with more, nor one with fewer beyond the last column read)."""
        d = self.delimiter
        assert d is not None
        if d == WHITESPACE:
            widths = list(map(len, map(str.split, lines)))
        elif any(map(str.__contains__, lines, repeat('"'))):
            widths = [s.count(d) + 1 if '"' not in s else len(_split(s, d)) for s in lines]
        else:  # the common case, in C: count the delimiters
            counts = list(map(str.count, lines, repeat(d)))
            if counts.count(self.width - 1) == len(counts):
                return
            widths = [c + 1 for c in counts]
        if widths.count(self.width) != len(widths):
            row = next(i for i, w in enumerate(widths) if w != self.width)
            raise self._width_error(lines[row], int(numbers[row]), widths[row])

    def _cell_error(
        self, lines: List[str], numbers: NDArray[np.int64], cols: List[int], labels: Sequence[str], fallback: str
    ) -> TableError:
        for line, number in zip(lines, numbers):
            cells = _split(line, self.delimiter)
            if len(cells) != self.width:
                return self._width_error(line, int(number), len(cells))
            for col, label in zip(cols, labels):
                cell = cells[col].strip()
                if not cell:
                    return TableError(f"{self.where(int(number))}, column {label}: empty cell "
                                      "(a missing value: drop or repair that sample)")
                if not _is_number(cell):
                    return TableError(f"{self.where(int(number))}, column {label}: {_show_cell(cell)} is not a number")
        return TableError(f"{self.source}: {fallback}")


def _show_cell(cell: str) -> str:
    """A cell as messages quote it: its first characters only, when it is long.

    >>> _show_cell("1.5x"), _show_cell("8" * 1000)
    ("'1.5x'", "'888888888888888888888888888888'... (1,000 characters)")
    """
    return repr(cell) if len(cell) <= 40 else f"{cell[:30]!r}... ({len(cell):,} characters)"


def _is_number(text: str) -> bool:
    try:
        float(text.strip().strip('"'))
    except ValueError:
        return False
    return True


# --- Parquet --------------------------------------------------------------------------


def _pyarrow(source: str) -> Tuple[Any, Any, Any]:
    """``pyarrow``, ``pyarrow.parquet`` and ``pyarrow.compute``, or a one-line error naming the extra."""
    try:
        pa = importlib.import_module("pyarrow")
        pq = importlib.import_module("pyarrow.parquet")
        pc = importlib.import_module("pyarrow.compute")
    except ImportError:
        raise TableError(f"{source}: a Parquet file; reading it needs pyarrow: pip install 'vehid[parquet]'") from None
    return pa, pq, pc


class _ParquetTable(Table):
    kind = "parquet"
    unit = "row"

    def __init__(self, path: str) -> None:
        self.source = path
        self._pa, pq, self._pc = _pyarrow(path)
        try:
            self._file = pq.ParquetFile(path)
        except Exception as e:  # pyarrow raises its own ArrowInvalid / OSError family
            raise TableError(f"{path}: not a readable Parquet file ({str(e).splitlines()[0]})") from None
        self.names = list(self._file.schema_arrow.names)
        self.size = int(self._file.metadata.num_rows)

    def close(self) -> None:
        self._file.close()

    def _floats(self, array: Any, label: str) -> Tuple[NDArray[np.float64], NDArray[np.bool_]]:
        pa = self._pa
        kind = array.type
        nulls = np.asarray(array.is_null().to_numpy(zero_copy_only=False), dtype=np.bool_)
        if pa.types.is_timestamp(kind) or pa.types.is_duration(kind):  # seconds (since the epoch)
            scale = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}[kind.unit]
            ticks = np.asarray(array.cast(pa.int64()).fill_null(0).to_numpy(zero_copy_only=False), dtype=np.int64)
            seconds = ticks.astype(np.float64) * scale
            seconds[nulls] = np.nan
            return seconds, nulls
        if not (pa.types.is_integer(kind) or pa.types.is_floating(kind) or pa.types.is_decimal(kind)
                or pa.types.is_boolean(kind)):
            raise TableError(f"{self.source}: column {label} holds {kind} values, not numbers")
        values = self._pc.cast(array, pa.float64(), safe=False).fill_null(float("nan"))
        return np.asarray(values.to_numpy(zero_copy_only=False), dtype=np.float64), nulls

    def declared_unit(self, column: int) -> Optional[str]:
        meta = self._file.schema_arrow.field(column).metadata or {}
        for key in (b"unit", b"units", b"Unit"):
            if key in meta:
                return bytes(meta[key]).decode("utf-8", "replace").strip()
        return header_unit(self.names[column])

    def is_timestamp(self, column: int) -> bool:
        return bool(self._pa.types.is_timestamp(self._file.schema_arrow.field(column).type))

    def chunks(
        self, columns: Sequence[int], labels: Sequence[str], rows: int, missing: bool = False,
        stamps: Sequence[int] = (),
    ) -> Iterator[Chunk]:
        names = [self.names[c] for c in columns]
        first = 1
        try:
            batches = self._file.iter_batches(batch_size=rows, columns=names)
            for batch in batches:
                k = batch.num_rows
                if k == 0:
                    continue
                blocks = [self._floats(batch.column(i), label) for i, label in enumerate(labels)]
                data = np.column_stack([b[0] for b in blocks])
                numbers = np.arange(first, first + k, dtype=np.int64)
                finite = np.isfinite(data) | np.isnan(data) if missing else np.isfinite(data)
                if not finite.all():
                    row = int(np.argmin(finite.all(axis=1)))
                    col = int(np.argmin(finite[row]))
                    what = ("empty (null)" if blocks[col][1][row]
                            else f"{float(data[row, col])!r} is not a finite number")
                    raise TableError(f"{self.where(first + row)}, column {labels[col]}: {what} "
                                     "(drop or repair that sample)")
                self._consumed += k
                first += k
                yield Chunk(data=data, lines=numbers)
        except TableError:
            raise
        except Exception as e:
            raise TableError(f"{self.source}: cannot read ({str(e).splitlines()[0]})") from None

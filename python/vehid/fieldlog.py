"""Field logs: a car's sensor channels from data-logger tables and ROS 2 bags, in SI units on
one clock, for ``vehid monitor`` and ``vehid inspect``.

* :func:`load_channel_map` reads a ``channels.toml`` (which topic or column feeds each vehid
  channel, its field, unit, sign, scale, gravity and delay).
* :func:`read_log` reads the channels of a CSV or Parquet table (units from ``[mm]``
  headers, the map or Parquet field metadata; time in s, ms, us, ns or timestamps; empty
  cells missing) or of a ROS 2 bag (``.mcap``, ``.db3``, a bag folder; through ``rosbags``)
  as :class:`Series`: times (s) and values (SI) per channel.
* :func:`align` puts them on one grid (:mod:`vehid.align`: the nominal rate, the
  resampler, the deflection's delay estimated and removed) and checks that they are
  plausible (units, the deflection's sign, gravity, the named car) before any result.

Every error is a :class:`vehid.io.TableError` (a ``ValueError``) with one line naming the
column, topic or key and the fix.
"""

from __future__ import annotations

import math
import os
import re
import sys
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np
from numpy.typing import NDArray

from . import align as _align
from .channels import ANGLE_UNITS, ChannelMap, ChannelSpec, Log, Series, unit_of
from .io import STANDARD_GRAVITY, Column, TableError, match_columns, normalize, open_table, si_factor

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python < 3.11
    import tomli as tomllib

__all__ = ["Aligned", "ChannelMap", "ChannelSpec", "Log", "Series", "accelerometer_noise", "accelerometer_noises",
           "align", "car_check", "deflection_noise", "deflection_noises", "long_gap_words", "shorten_gaps",
           "grid_interval", "is_bag", "is_channel_map", "load_channel_map", "read_log", "unit_of", "BAG_SUFFIXES"]

#: File suffixes read as ROS bags (a folder is read as a rosbag2 bag too).
BAG_SUFFIXES = (".mcap", ".db3", ".bag")
#: The monitor's calibrated rate: the grid's interval when the channels' rates differ, s.
DEFAULT_DT = 0.005
#: Samples read per chunk of a table.
CHUNK = 200_000
#: A deflection delay under this (s) is reported, not removed.
DELAY_TOLERANCE = 0.25e-3
#: Keys a channel's section may hold.
SPEC_KEYS = ("topic", "column", "field", "joint", "unit", "gravity", "sign", "scale", "delay")


def is_bag(path: str) -> bool:
    """Whether ``path`` is read as a ROS bag: a ``.mcap``, ``.db3`` or ``.bag`` file, or a folder."""
    return os.path.isdir(path) or path.lower().endswith(BAG_SUFFIXES)


#: A line that opens a channel map's section (``[a_body]``, ``[deflection_f]``, ``[time]``, a state
#: channel), even when broken (``[a_body`` without its bracket).
_SECTION = (rb"^\s*\[\s*(a_body|a_wheel|deflection|time|t|zw|vw|zb|vb|dzw|dvw|dzb|dvb|z[12]|v[12]|ph|om|dz[12]|"
            rb"dv[12]|dph|dom)(_[fr])?\s*(\]|$)")


def is_channel_map(path: str) -> bool:
    """Whether a ``--columns`` value is a ``channels.toml`` (a TOML file with sections of
    keys, ``[a_body] column = ...``) rather than ``NAME=COLUMN`` pairs or a flat mapping file.
    A ``.toml`` file with channel sections that is not valid TOML raises :class:`TableError`."""
    if "=" in path or not path.lower().endswith(".toml") or not os.path.isfile(path):
        return False
    try:
        with open(path, "rb") as f:
            raw = f.read(1 << 20)
        data = tomllib.loads(raw.decode("utf-8-sig"))
    except OSError:
        return False
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        if re.search(_SECTION, raw, flags=re.M):  # meant as a channel map
            raise TableError(f"--columns {path}: not valid TOML ({e}): fix the channel map") from None
        return False
    return any(isinstance(v, dict) for v in data.values())


def load_channel_map(path: str, channels: Sequence[str]) -> ChannelMap:
    """Reads ``path`` (TOML) for the vehid channels ``channels``: one section per channel
    (``[a_body]``: ``topic`` or ``column``, ``field``, ``joint``, ``unit``, ``gravity``,
    ``sign``, ``scale``, ``delay``), an optional ``[time]`` section (``column``, ``unit``) and
    an optional top-level ``stamp = "header" | "log"``."""
    where = f"--columns {path}"
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except OSError as e:
        raise TableError(f"{where}: cannot read ({e.strerror or e})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise TableError(f"{where}: not a TOML file ({e})") from None
    specs: Dict[str, ChannelSpec] = {}
    out = ChannelMap(path, specs)
    for key, value in data.items():
        if key == "stamp":
            if value not in ("header", "log"):
                raise TableError(f"{where}: stamp = {value!r}: expected \"header\" (header.stamp) or \"log\" "
                                 "(the time the message was logged)")
            out.stamp = str(value)
            continue
        if not isinstance(value, dict):
            raise TableError(f"{where}: {key} = {value!r}: expected sections [CHANNEL] (channels: "
                             f"{', '.join(channels)}, time) or stamp = \"header\"|\"log\"")
        if key in ("time", "t"):
            bad = [k for k in value if k not in ("column", "unit")]
            if bad:
                raise TableError(f"{where}: [{key}] {bad[0]}: the time section takes column and unit")
            out.time_column = _text(value, "column", where, key)
            out.time_unit = _text(value, "unit", where, key)
            continue
        if key not in channels:
            raise TableError(f"{where}: [{key}] is not a channel here; the channels are {', '.join(channels)} "
                             "(and [time])")
        specs[key] = _spec(key, value, where)
    return out


def _text(section: Mapping[str, Any], key: str, where: str, name: str) -> Optional[str]:
    value = section.get(key)
    if value is not None and not isinstance(value, str):
        raise TableError(f"{where}: [{name}] {key} = {value!r}: expected a string")
    return value


def _number(section: Mapping[str, Any], key: str, where: str, name: str) -> Optional[float]:
    value = section.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise TableError(f"{where}: [{name}] {key} = {value!r}: expected a finite number")
    return float(value)


def _spec(name: str, section: Mapping[str, Any], where: str) -> ChannelSpec:
    bad = [k for k in section if k not in SPEC_KEYS]
    if bad:
        raise TableError(f"{where}: [{name}] {bad[0]}: unknown key; a channel takes {', '.join(SPEC_KEYS)}")
    spec = ChannelSpec(name, topic=_text(section, "topic", where, name), column=_text(section, "column", where, name),
                       field=_text(section, "field", where, name), joint=_text(section, "joint", where, name),
                       unit=_text(section, "unit", where, name), gravity=_text(section, "gravity", where, name))
    if (spec.topic is None) == (spec.column is None):
        raise TableError(f"{where}: [{name}] needs one of topic = \"/...\" (bags, MCAP) or column = \"...\" "
                         "(CSV, Parquet)")
    if spec.gravity not in (None, "included", "removed"):
        raise TableError(f"{where}: [{name}] gravity = {spec.gravity!r}: expected \"included\" (specific force, "
                         "as an IMU reports) or \"removed\"")
    sign = _number(section, "sign", where, name)
    if sign is not None:
        if sign not in (1.0, -1.0):
            raise TableError(f"{where}: [{name}] sign = {sign:g}: expected 1 or -1")
        spec.sign, spec.sign_given = sign, True
    scale = _number(section, "scale", where, name)
    if scale is not None:
        if scale == 0:
            raise TableError(f"{where}: [{name}] scale = 0: expected a non-zero factor")
        spec.scale, spec.scale_given = scale, True
    spec.delay = _number(section, "delay", where, name)
    return spec


def read_log(path: str, channels: Sequence[Column], cmap: Optional[ChannelMap] = None,
             pairs: Optional[Mapping[str, str]] = None, delimiter: Optional[str] = None,
             dt: Optional[float] = None) -> Log:
    """The channels ``channels`` of the log ``path`` (a table, or a bag when :func:`is_bag`),
    through the channel map ``cmap`` or ``NAME=COLUMN`` ``pairs`` (tables), in SI."""
    if is_bag(path):
        if cmap is None:
            raise TableError(f"{path}: a ROS bag: map its topics to the channels with --columns channels.toml "
                             f"({', '.join(c.name for c in channels)}; vehid inspect {path} lists its topics)")
        from .bags import read_bag

        return read_bag(path, channels, cmap)
    return _read_table(path, channels, cmap, pairs or {}, delimiter, dt)


# --- tables ---------------------------------------------------------------------------

#: Further names of a time column (after :func:`vehid.io.normalize`).
MORE_TIME_NAMES = ("timestamp", "time_stamp", "datetime", "zeit")


def _read_table(path: str, channels: Sequence[Column], cmap: Optional[ChannelMap], pairs: Mapping[str, str],
                delimiter: Optional[str], dt: Optional[float]) -> Log:
    mapping = dict(pairs)
    specs = cmap.channels if cmap else {}
    for name, spec in specs.items():
        if spec.column is None:
            raise TableError(f"--columns {cmap.path if cmap else ''}: [{name}] topic = {spec.topic!r}: {path} is a "
                             "table: give column = \"...\"")
        mapping[name] = spec.column
    if cmap and cmap.time_column:
        mapping["t"] = cmap.time_column
    with open_table(path, delimiter=delimiter) as table:
        cols = (Column("t", "time", "s"),) + tuple(channels)
        match = match_columns(table.names, cols, mapping, where=table.source)
        if "t" not in match.index:
            more = [i for i, h in enumerate(table.names) if normalize(h) in MORE_TIME_NAMES]
            if len(more) == 1:
                match.index["t"] = more[0]
        absent = [c for c in channels if c.name not in match.index]
        if absent:
            shown = ", ".join(repr(h) for h in table.names[:12]) + (", ..." if len(table.names) > 12 else "")
            raise TableError(f"{table.source} has no column {', '.join(c.describe() for c in absent)} (its columns: "
                             f"{shown}); map yours with --columns {absent[0].name}=NAME or a channels.toml")
        has_t = "t" in match.index
        if not has_t and dt is None:
            raise TableError(f"{table.source} has no time column t: give the sample interval with --dt SECONDS")
        order = ([match.index["t"]] if has_t else []) + [match.index[c.name] for c in channels]
        labels = (["t"] if has_t else []) + [c.describe() for c in channels]
        factors: List[Tuple[float, str, str]] = []
        for c in channels:
            i = match.index[c.name]
            factors.append(unit_of(specs.get(c.name), table.declared_unit(i), c, f"{table.source}, column "
                                 f"{table.names[i]!r}"))
        time_factor, absolute = 1.0, False
        if has_t:
            i = match.index["t"]
            absolute = table.is_timestamp(i)
            declared = (cmap.time_unit if cmap and cmap.time_unit else None) or table.declared_unit(i)
            if declared and not absolute:
                time_factor = si_factor(declared, "time", f"{table.source}, time column {table.names[i]!r}")
        blocks, lines = [], []
        for chunk in table.chunks(order, labels, CHUNK, missing=True, stamps=[0] if has_t else []):
            blocks.append(chunk.data)
            lines.append(chunk.lines)
        if not blocks:
            raise TableError(f"{table.source} has no samples")
        data = np.concatenate(blocks)
        rows = np.concatenate(lines)
        if has_t:
            t = data[:, 0] * time_factor
            if np.isnan(t).any():
                row = int(np.argmax(np.isnan(t)))
                raise TableError(f"{table.where(int(rows[row]))}: the time is missing: every sample needs its time "
                                 "(drop the sample: the gap is then seen in the time column)")
            absolute = absolute or bool(t[0] > 1e8)  # seconds since 1970 (timestamps)
            values = data[:, 1:]
        else:
            assert dt is not None
            t = np.arange(len(data), dtype=np.float64) * dt
            values = data
        _increasing(t, rows, table.where)
        origin = 0.0
        if absolute:  # seconds from the first sample: the float's resolution stays at nanoseconds
            origin = float(t[0])
            t = np.asarray(t - origin, dtype=np.float64)
        series = []
        for j, c in enumerate(channels):
            factor, unit, unit_from = factors[j]
            cspec = specs.get(c.name)
            sign = cspec.sign * cspec.scale if cspec else 1.0
            i = match.index[c.name]
            v = table.to_si(values[:, j : j + 1], factor * sign, rows, [labels[j + has_t]])[:, 0]
            series.append(Series(c.name, f"column {table.names[i]!r}", t, v, unit, unit_from, lines=rows))
        return Log(table.source, table.kind, series, absolute, origin=origin)


def _increasing(t: NDArray[np.float64], rows: NDArray[np.int64], where: Any) -> None:
    d = np.diff(t)
    if len(d) and not (d > 0).all():
        i = int(np.argmin(d > 0))
        raise TableError(f"{where(int(rows[i + 1]))}: time {float(t[i + 1])!r} s does not increase after "
                         f"{float(t[i])!r} s: the time column must increase strictly (sort the log, drop duplicated "
                         "samples)")


# --- one grid ---------------------------------------------------------------------------


@dataclass
class Aligned:
    """The channels on one grid: ``y[k]`` at ``t0 + k dt`` (s), NaN missing; ``delays``: the
    deflection's delay per axle removed (s; NaN: could not be estimated), ``notes``: what
    was done, one line each, for the user."""

    t0: float
    dt: float
    y: NDArray[np.float64]
    names: List[str]
    rates: Dict[str, float]
    delays: Dict[str, float] = field(default_factory=dict)
    notes: List[str] = field(default_factory=list)
    missing: int = 0
    #: The delay the data say, per deflection (s), whether removed or not.
    estimated: Dict[str, float] = field(default_factory=dict)
    #: Long gaps shortened to :data:`GAP_CAP` (:func:`shorten_gaps`): (the grid's time where the
    #: samples resume, s; the seconds taken out there).
    skips: List[Tuple[float, float]] = field(default_factory=list)


#: Longest gap of the log (no channel has a sample) put on the grid as missing samples, s (as
#: ``vehid.fleet``'s ``GAP_CAP``); a longer gap (a parked car, a log of several drives) is
#: shortened to this: the monitor has long restarted its filters by then (it keeps its
#: reference and its CUSUMs), and the grid, so memory and time, stays bounded by the samples
#: logged, not by the gaps' length.
GAP_CAP = 60.0


def _line(log: Log, number: int) -> str:
    """A sample's place in a table: ``"drive.csv, line 12"`` (a CSV's line) or ``"drive.parquet,
    row 11"`` (a Parquet file's 1-based row), as :meth:`vehid.io.Table.where` words it."""
    return f"{log.source}, {'row' if log.kind == 'parquet' else 'line'} {number}"


def long_gap_words(seconds: float) -> str:
    """What a gap over :data:`GAP_CAP` becomes, for the note that names its place.

    >>> long_gap_words(5011200.0)  # doctest: +NORMALIZE_WHITESPACE
    "a gap of 5.0112e+06 s (58 days) in the time column: fed to the monitor as 60 s of missing
     samples (it restarts its filters after them and keeps its reference; the times after the gap
     stay on the log's clock)"
    """
    span = (f" ({seconds / 86400:.3g} days)" if seconds >= 86400 else
            f" ({seconds / 3600:.3g} h)" if seconds >= 3600 else f" ({seconds / 60:.3g} min)")
    return (f"a gap of {seconds:.6g} s{span} in the time column: fed to the monitor as {GAP_CAP:g} s of missing "
            "samples (it restarts its filters after them and keeps its reference; the times after the gap stay on "
            "the log's clock)")


def shorten_gaps(log: Log, step: float) -> List[Tuple[float, float, str]]:
    """Shortens each gap of ``log`` that every channel shares, over :data:`GAP_CAP` s, to
    ``round(GAP_CAP / step) + 1`` grid intervals (the stretch ``vehid monitor`` feeds a long gap
    of a streamed table as): the times after it move back by the rest (in place; channels that
    share one clock keep sharing it). Returns, per gap: the time where the samples resume (on
    the shortened clock), the seconds taken out, and where it is (the line, for tables)."""
    merged = np.unique(np.concatenate([s.t for s in log.series]))
    cap = int(round(GAP_CAP / step))
    d = np.diff(merged)
    long = np.flatnonzero(np.rint(np.minimum(d / step, 2.0**52)) > cap + 1)
    if not len(long):
        return []
    ends = merged[long + 1]
    cut = d[long] - (cap + 1) * step
    before = np.concatenate([[0.0], np.cumsum(cut)])
    out = []
    s0 = log.series[0]
    for b, c, done in zip(ends.tolist(), cut.tolist(), before[:-1].tolist()):
        i = int(np.searchsorted(s0.t, b))
        where = (_line(log, int(s0.lines[i])) if s0.lines is not None and i < len(s0.lines) and s0.t[i] == b
                 else f"{log.source}, at {b:.6g} s")
        out.append((b - done - c, c, where))
    shifted: Dict[int, NDArray[np.float64]] = {}
    for s in log.series:
        if id(s.t) not in shifted:
            shifted[id(s.t)] = np.asarray(s.t - before[np.searchsorted(ends, s.t, side="right")], dtype=np.float64)
        s.t = shifted[id(s.t)]
    return out


def grid_interval(log: Log, dt: Optional[float]) -> float:
    """The grid's interval: ``dt`` when given; else the channels' common nominal interval
    when they share one and it is not shorter than :data:`DEFAULT_DT`... (documented in
    ``docs/capabilities/field-logs.md``): the monitor's calibrated 5 ms when any channel is
    at least that fast, else the fastest channel's interval."""
    if dt is not None:
        return dt
    rates = [_align.nominal_interval(s.t) for s in log.series]
    fastest = min(r for r in rates if math.isfinite(r)) if any(math.isfinite(r) for r in rates) else math.nan
    if not math.isfinite(fastest):
        raise TableError(f"{log.source}: one sample cannot give the sample interval: give --dt")
    return DEFAULT_DT if fastest <= DEFAULT_DT * 1.0001 else fastest


def _gravity(s: Series, spec: Optional[ChannelSpec], notes: List[str]) -> None:
    """Removes gravity from an acceleration where it is included (declared, an IMU, or a
    mean within 20 % of +g); refuses a mean near -g (the axis points down)."""
    declared = (spec.gravity if spec else None) or s.gravity
    if declared == "removed":
        return
    finite = s.v[np.isfinite(s.v)]
    mean = float(np.mean(finite)) if len(finite) else 0.0
    if declared == "included" or abs(mean - STANDARD_GRAVITY) < 0.2 * STANDARD_GRAVITY:
        s.v = s.v - STANDARD_GRAVITY
        s.gravity_removed = True
        if declared != "included":
            notes.append(f"{s.channel} ({s.source}): mean {mean:.3g} m/s^2: gravity included, removed (declare "
                         "gravity = \"included\" or \"removed\" in the channel map)")
        return
    if abs(mean + STANDARD_GRAVITY) < 0.2 * STANDARD_GRAVITY:
        raise TableError(f"{s.channel} ({s.source}) reads {mean:.3g} m/s^2 on average: -g, so its axis points "
                         "down; vehid's points up: declare sign = -1 for it in the channel map")


def align(log: Log, dt: Optional[float], specs: Optional[Mapping[str, ChannelSpec]] = None,
          estimate: bool = True) -> Aligned:
    """Puts ``log``'s channels on one grid of interval :func:`grid_interval` (s), after
    removing gravity from the accelerations, and removes the deflection's delay against the
    accelerometers (declared ``delay`` in the map, else estimated when ``estimate``)."""
    specs = specs or {}
    notes = list(log.notes)
    for s in log.series:
        if s.channel.startswith(("a_body", "a_wheel")):
            _gravity(s, specs.get(s.channel), notes)
    step = grid_interval(log, dt)
    rates = {s.channel: _align.nominal_interval(s.t) for s in log.series}
    skips = shorten_gaps(log, step)
    for _, cut, where in skips:
        notes.append(f"{where}: {long_gap_words(cut + (round(GAP_CAP / step) + 1) * step)}")
    t0 = max(float(s.t[0]) for s in log.series)
    t1 = min(float(s.t[-1]) for s in log.series)
    if t1 <= t0:
        spans = ", ".join(f"{s.channel} {s.t[0]:.6g}..{s.t[-1]:.6g} s" for s in log.series)
        raise TableError(f"{log.source}: the channels do not overlap in time ({spans})")
    n = int(math.floor((t1 - t0) / step + 1e-6)) + 1
    inputs = max(len(s.t) for s in log.series)
    if n > 20 * inputs + 1000:
        if skips:  # so many long gaps that even shortened they outweigh the samples
            raise TableError(f"{log.source}: {len(skips):,} gaps over {GAP_CAP:g} s (the first at {skips[0][2]}), "
                             f"each put on the grid as {GAP_CAP:g} s of missing samples, give {n:,} samples on the "
                             f"grid from {inputs:,} in the log: split the log at its gaps")
        s = max(log.series, key=lambda x: float(np.max(np.diff(x.t))) if len(x.t) > 1 else 0.0)
        i = int(np.argmax(np.diff(s.t)))
        jump = float(s.t[i + 1] - s.t[i])
        if jump > 1000 * step:  # a clock that jumps, not a rate
            where = _line(log, int(s.lines[i + 1])) if s.lines is not None else f"{s.source}"
            raise TableError(f"{where}: the time jumps {jump:.6g} s forward ({s.channel}): a clock jump or a log "
                             "of several drives: split the log there")
        raise TableError(f"--dt {step:g}: {n:,} samples on the grid from {inputs:,} in the log: give the log's "
                         "sample interval (or none: the grid then follows the log)")
    shared = all(s.t is log.series[0].t for s in log.series)
    same = shared and abs(rates[log.series[0].channel] - step) < 1e-9 * step + 1e-12
    y = np.empty((n, len(log.series)))
    if same:  # one clock at the grid's rate: the samples as logged, gaps as missing rows
        y = _placed(log, step, t0, n)
    else:
        for j, s in enumerate(log.series):
            y[:, j] = _align.resample(s.t, s.v, rates[s.channel], t0, step, n)
        if not shared or any(abs(r - step) > 1e-9 for r in rates.values()):
            notes.append("resampled to " + f"{1 / step:g} Hz (" + ", ".join(f"{c} {1 / r:g} Hz" for c, r in
                                                                         rates.items()) + ")")
    out = Aligned(t0, step, y, [s.channel for s in log.series], rates, notes=notes,
                  skips=[(at, cut) for at, cut, _ in skips])
    for axle in ("", "_f", "_r"):
        names = [f"a_body{axle}", f"a_wheel{axle}", f"deflection{axle}"]
        if all(c in out.names for c in names):
            _deflection(out, log, names, specs, estimate)
    if estimate:  # each body accelerometer's delay, from the body equation
        axles = [a for a in ("", "_f", "_r") if all(f"{c}{a}" in out.names for c in ("a_body", "deflection"))]
        for axle in axles:
            _body(out, log, specs, axle, [b for b in axles if b != axle])
        for axle in axles:
            if f"a_wheel{axle}" in out.names:
                _refine(out, log, specs, axle, [b for b in axles if b != axle])
    if not same or any(abs(v) >= DELAY_TOLERANCE for v in out.delays.values() if math.isfinite(v)):
        # the grid's ends where a channel (resampled, or shifted) does not reach: not a gap
        good = np.flatnonzero(np.isfinite(out.y).all(axis=1))
        if len(good):
            first, last = int(good[0]), int(good[-1])
            out.y = out.y[first : last + 1]
            out.t0 += first * step
    out.missing = int(np.isnan(out.y).any(axis=1).sum())
    return out


def _placed(log: Log, step: float, t0: float, n: int) -> NDArray[np.float64]:
    """The samples of a one-clock table at their grid index ``round((t - t0) / dt)``; an
    interval under half the grid's is refused naming its line."""
    s0 = log.series[0]
    k = np.rint((s0.t - t0) / step).astype(np.int64)
    dk = np.diff(k)
    if len(dk) and not (dk >= 1).all():
        i = int(np.argmin(dk >= 1))
        where = _line(log, int(s0.lines[i + 1])) if s0.lines is not None else log.source
        raise TableError(f"{where}: the sample interval {float(s0.t[i + 1] - s0.t[i]):.6g} s is under half the "
                         f"sample interval {step:.6g} s: the monitor needs a fixed rate (resample the log, or give "
                         "--dt)")
    keep = (k >= 0) & (k < n)
    y = np.full((n, len(log.series)), math.nan)
    for j, s in enumerate(log.series):
        y[k[keep], j] = s.v[keep]
    return y


def _deflection(out: Aligned, log: Log, names: List[str], specs: Mapping[str, ChannelSpec],
                estimate: bool) -> None:
    """The deflection of one axle: its scale, sign and delay checked against the
    accelerometers; the delay removed (re-read at the shifted times)."""
    ib, iw, idf = (out.names.index(c) for c in names)
    defl = names[2]
    std = float(np.nanstd(out.y[:, idf])) if np.isfinite(out.y[:, idf]).any() else 0.0
    if std > 0.25:
        raise TableError(f"{defl} ({_source(log, defl)}): standard deviation {std:.3g} m, implausible for a "
                         "suspension's travel: is it in mm? declare its unit (a [mm] header, or unit = \"mm\")")
    spec = specs.get(defl)
    est = _align.estimate_delay(out.y[:, ib], out.y[:, iw], out.y[:, idf], out.dt)
    if est.why:
        out.delays[defl] = math.nan
        out.notes.append(f"{defl}: its delay against the accelerometers cannot be estimated ({est.why}): "
                         "not removed")
        return
    if abs(est.corr) < 0.3:
        out.delays[defl] = math.nan
        out.notes.append(f"{defl}: its second derivative does not follow a_body - a_wheel (correlation "
                         f"{est.corr:.2f}): its delay cannot be estimated, not removed; check the channel map")
        return
    slope = abs(est.slope)
    if not 0.5 < slope < 2.0:
        joint = "JointState" in _source(log, defl) and not any(s.unit.startswith(tuple(ANGLE_UNITS))
                                                                for s in log.series if s.channel == defl)
        revolute = ("; or a revolute joint's angle read as m? declare unit = \"rad\" and scale = the travel per "
                    "rad" if joint else "")
        raise TableError(f"{defl} ({_source(log, defl)}): its second derivative is {slope:.3g} times "
                         f"{names[0]} - {names[1]}, not about 1: the units disagree ({_unit_guess(slope)}{revolute})")
    if est.corr < 0:
        if spec is not None and spec.sign_given:
            raise TableError(f"{defl} ({_source(log, defl)}): sign = {spec.sign:g} in the channel map, but its "
                             "second derivative follows a_wheel - a_body: vehid's deflection is body minus wheel "
                             "(extension positive): use the other sign")
        out.y[:, idf] = -out.y[:, idf]
        for s in log.series:
            if s.channel == defl:
                s.v = -s.v
        out.notes.append(f"{defl}: compression-positive (its second derivative follows a_wheel - a_body): read "
                         "with the opposite sign (vehid's is body minus wheel, extension positive; declare sign = "
                         "-1 to say so)")
    delay = est.delay
    out.estimated[defl] = est.delay
    if spec is not None and spec.delay is not None:
        delay = spec.delay
        if abs(delay - est.delay) > 1e-3:
            raise TableError(f"{defl}: delay = {delay:g} s in the channel map, but the data "
                             f"show {1e3 * est.delay:.2f} ms (d'' against a_body - a_wheel, correlation "
                             f"{abs(est.corr):.2f}): correct the delay, or leave it out to have it estimated")
        out.notes.append(f"{defl}: the declared delay {1e3 * delay:.2f} ms removed (estimated: "
                         f"{1e3 * est.delay:.2f} ms)")
    elif not estimate:
        out.delays[defl] = est.delay
        out.notes.append(f"{defl}: {1e3 * est.delay:.2f} ms late against the accelerometers (estimated, not "
                         "removed)")
        return
    out.delays[defl] = delay
    if abs(delay) < DELAY_TOLERANCE:
        return
    s = next(x for x in log.series if x.channel == defl)
    out.y[:, idf] = _align.resample(s.t, s.v, out.rates[defl], out.t0, out.dt, len(out.y), shift=delay)
    if spec is None or spec.delay is None:
        out.notes.append(f"{defl}: {1e3 * abs(delay):.2f} ms {'late' if delay > 0 else 'early'} against the "
                         f"accelerometers (estimated from d'' = a_body - a_wheel, correlation {abs(est.corr):.2f}): "
                         "removed")


def _body(out: Aligned, log: Log, specs: Mapping[str, ChannelSpec], axle: str = "", others: Sequence[str] = ()) -> None:
    """The body accelerometer's delay (``a_body`` + ``axle``) against the (aligned)
    deflection, from the body equation (:func:`vehid.align.estimate_body_delay`; the half car:
    the other axles ``others``' deflections are regressors too): removed when over
    :data:`DELAY_TOLERANCE` and the fit is close (correlation over 0.9); a declared ``delay``
    is taken as given."""
    body, defl = f"a_body{axle}", f"deflection{axle}"
    spec = specs.get(body)
    ib, idf = out.names.index(body), out.names.index(defl)
    if spec is not None and spec.delay is not None:
        delay = spec.delay
    else:
        more = [out.y[:, out.names.index(f"deflection{b}")] for b in others]
        est = _align.estimate_body_delay(out.y[:, ib], out.y[:, idf], out.dt, others=more)
        out.estimated[body] = est.delay
        if est.why or not est.corr > 0.9:
            return
        delay = est.delay
        if abs(delay) < DELAY_TOLERANCE:
            out.delays[body] = delay
            return
        out.notes.append(f"{body}: {1e3 * abs(delay):.2f} ms {'late' if delay > 0 else 'early'} against the "
                         f"deflection (estimated from the body equation, correlation {est.corr:.3f}): removed")
    out.delays[body] = delay
    if abs(delay) < DELAY_TOLERANCE:
        return
    s = next(x for x in log.series if x.channel == body)
    out.y[:, ib] = _align.resample(s.t, s.v, out.rates[body], out.t0, out.dt, len(out.y), shift=delay)


def _refine(out: Aligned, log: Log, specs: Mapping[str, ChannelSpec], axle: str = "", others: Sequence[str] = (),
            rounds: int = 4) -> None:
    """Both delays of an axle again, in turn, while they move by over 20 us: a late body
    accelerometer biases the deflection's first estimate (``a_body`` is in ``d''``'s side of
    the equation: 3.25 ms found of 4 with the body 20 ms late), and the body's is measured
    against that deflection. Each channel is re-read from its own samples at its total delay;
    the notes give the final figures. Not where a delay is declared or was not removed."""
    body, wheel, defl = (f"{c}{axle}" for c in ("a_body", "a_wheel", "deflection"))
    if any(specs.get(c) is not None and specs[c].delay is not None for c in (body, defl)):
        return
    td, tb = out.delays.get(defl, math.nan), out.delays.get(body, math.nan)
    if not (math.isfinite(td) and math.isfinite(tb)) or abs(tb) < DELAY_TOLERANCE:
        return
    ib, iw, idf = (out.names.index(c) for c in (body, wheel, defl))
    series = {s.channel: s for s in log.series}
    for _ in range(rounds):
        r = _align.estimate_delay(out.y[:, ib], out.y[:, iw], out.y[:, idf], out.dt).delay
        if not math.isfinite(r) or abs(r) < 2e-5:
            break
        td += r
        s = series[defl]
        out.y[:, idf] = _align.resample(s.t, s.v, out.rates[defl], out.t0, out.dt, len(out.y), shift=td)
        more = [out.y[:, out.names.index(f"deflection{b}")] for b in others]
        rb = _align.estimate_body_delay(out.y[:, ib], out.y[:, idf], out.dt, others=more).delay
        if math.isfinite(rb):
            tb += rb
            s = series[body]
            out.y[:, ib] = _align.resample(s.t, s.v, out.rates[body], out.t0, out.dt, len(out.y), shift=tb)
    out.delays[defl], out.delays[body] = td, tb
    for i, note in enumerate(out.notes):
        if note.startswith(f"{defl}: ") and "against the accelerometers" in note and "removed" in note:
            out.notes[i] = (f"{defl}: {1e3 * abs(td):.2f} ms {'late' if td > 0 else 'early'} against the "
                            "accelerometers (estimated from d'' = a_body - a_wheel, with the body accelerometer's "
                            "delay): removed")
        if note.startswith(f"{body}: ") and "removed" in note:
            out.notes[i] = (f"{body}: {1e3 * abs(tb):.2f} ms {'late' if tb > 0 else 'early'} against the wheel "
                            f"accelerometer ({1e3 * abs(tb - td):.2f} ms {'late' if tb > td else 'early'} against the "
                            "deflection; estimated from the body equation): removed")


def _source(log: Log, channel: str) -> str:
    return next((s.source for s in log.series if s.channel == channel), channel)


def _unit_guess(slope: float) -> str:
    """The likely cause of a deflection-to-acceleration scale ``slope`` far from 1."""
    guesses = [(1000.0, "the deflection in mm read as m? declare unit = \"mm\""),
               (100.0, "the deflection in cm read as m? declare unit = \"cm\""),
               (STANDARD_GRAVITY, "the accelerations in g read as m/s^2? declare unit = \"g\""),
               (1 / STANDARD_GRAVITY, "the accelerations in m/s^2 declared as g?"),
               (1e-3, "the deflection in m declared as mm?")]
    best = min(guesses, key=lambda g: abs(math.log(slope / g[0])))
    if abs(math.log(slope / best[0])) < math.log(2.0):
        return best[1]
    return "check each channel's unit and scale"


def car_check(out: Aligned, k2m: float, bm: float, car: str) -> None:
    """Refuses, in one line naming the likely cause, a quarter-car log whose body equation is
    far from the named car's: ``k2/M`` (1/s^2) negative, or over 3 times off ``k2m`` (the
    nominal car's ``car``, e.g. ``"--model quarter"``). ``bm`` (1/s) is shown alongside."""
    if not all(c in out.names for c in ("a_body", "deflection")):
        return
    got_k, got_b = _align.body_ratios(out.y[:, out.names.index("a_body")], out.y[:, out.names.index("deflection")],
                                      out.dt)
    if not math.isfinite(got_k):
        return
    if got_k <= 0:
        raise TableError(f"the log's body equation has k2/M = {got_k:.3g} 1/s^2 (negative): a_body or the deflection "
                         "has the wrong sign (vehid: up positive, deflection body minus wheel): declare sign = -1 "
                         "for one of them")
    ratio = got_k / k2m
    if ratio > 3.0 or ratio < 1 / 3.0:
        factor = f"{ratio:.3g} times" if ratio > 1 else f"1/{1 / ratio:.3g} of"
        kept = out.estimated.get("deflection", 0.0) - out.delays.get("deflection", 0.0)
        cause = (f"the deflection's {1e3 * kept:.3g} ms delay, which the data show but the channel map's delay "
                 "keeps? or a different car? " if math.isfinite(kept) and abs(kept) > 2e-3 else "a different car? ")
        raise TableError(f"the log's k2/M ~ {got_k:.3g} 1/s^2 (b/M ~ {got_b:.3g} 1/s) is {factor} that of {car} "
                         f"(k2/M = {k2m:.3g}, b/M = {bm:.3g}): {cause}name yours with --model passenger "
                         "or --car M=...,k2=...,b=...")


#: The health monitor's default sensor noise per sample (``SensorNoise::default``): m/s^2,
#: m/s^2, m.
DEFAULT_NOISE = {"a_body": 0.02, "a_wheel": 0.1, "deflection": 0.3e-3}
#: The health monitor's default deflection noise, m per sample.
DEFAULT_DEFLECTION_NOISE = DEFAULT_NOISE["deflection"]
#: An undeclared sensor's noise estimated from the log is given to the monitor when over this
#: many times the default: a sensor noisier than assumed misleads the monitor, a quieter one
#: costs a little sensitivity (and a log at the defaults is monitored as before).
NOISE_USED_ABOVE = 1.25


def deflection_noise(log: Log, dt: float) -> float:
    """The deflection sensor's white noise (m per sample at the grid's interval ``dt``, s)
    estimated from the data (:func:`vehid.align.white_noise` on each deflection channel's own
    samples; where the grid is slower, scaled by the anti-aliasing filter's share of the
    band, ``sqrt(0.9 h / dt)``); the largest over the axles; NaN when too short."""
    out = math.nan
    for sigma in deflection_noises(log, dt).values():
        if math.isfinite(sigma) and not sigma <= out:
            out = sigma
    return out


def deflection_noises(log: Log, dt: float) -> Dict[str, float]:
    """Each deflection channel's white noise, as :func:`deflection_noise` finds it:
    ``{"deflection": m}`` (the half car: ``deflection_f``, ``deflection_r``); NaN when too short."""
    out: Dict[str, float] = {}
    for s in log.series:
        if not s.channel.startswith("deflection"):
            continue
        h = _align.nominal_interval(s.t)
        sigma = _align.white_noise(s.t, s.v, h)
        if h < dt:
            sigma *= math.sqrt(0.9 * h / dt)
        out[s.channel] = sigma
    return out


def accelerometer_noise(al: Aligned, log: Log) -> Dict[str, float]:
    """The body and wheel accelerometers' white noise (m/s^2 per sample at the grid's
    interval) estimated from the aligned channels ``al`` (:func:`vehid.align.sensor_noise`, per
    axle, the largest over the axles; NaN when it cannot be estimated). Each axle's deflection
    noise enters as :func:`vehid.align.kinematic_deflection_noise` finds it on the grid when
    the deflection is sampled at least as fast as the grid; a slower deflection (a 100 Hz
    JointState on a 200 Hz grid) leaves its noise on the grid unknown to the few per cent the
    body's estimate needs (there the deflection's share of the body equation's residual is
    several times the body's noise): the body's is then NaN and the wheel's an upper bound
    (``sqrt(s_body^2 + s_wheel^2)``, a few per cent over for the default sensors). For channels
    resampled to the grid the figures are per grid sample as the monitor takes them: the same
    spectral level (a 400 Hz accelerometer's noise averaged to 200 Hz is ``1/sqrt(2)`` of its
    own). Not for an axle
    whose deflection's delay could not be estimated (its deflection does not follow ``a_body -
    a_wheel``: the relations do not hold)."""
    out = {"a_body": math.nan, "a_wheel": math.nan}
    for name, v in accelerometer_noises(al).items():
        k = name[:-2] if name.endswith(("_f", "_r")) else name  # a_body_f -> a_body
        if math.isfinite(v) and not v <= out[k]:
            out[k] = v
    return out


def accelerometer_noises(al: Aligned) -> Dict[str, float]:
    """Each accelerometer's white noise, as :func:`accelerometer_noise` finds it, by channel:
    ``{"a_body": ..., "a_wheel": ...}`` (the half car: ``a_body_f``, ``a_wheel_f``, ``a_body_r``,
    ``a_wheel_r``); NaN where it cannot be estimated; no entry for an axle whose deflection does
    not follow ``a_body - a_wheel``."""
    out: Dict[str, float] = {}
    # an axle whose deflection does not follow a_body - a_wheel (its delay could not be estimated) has
    # no relation to take the signal out with
    axles = [a for a in ("", "_f", "_r") if all(f"{c}{a}" in al.names for c in ("a_body", "a_wheel", "deflection"))
             and math.isfinite(al.delays.get(f"deflection{a}", 0.0))]
    col = {name: al.y[:, al.names.index(name)] for name in al.names}
    sd: Dict[str, float] = {}
    for a in axles:
        name = f"deflection{a}"
        if al.rates.get(name, math.inf) <= al.dt * 1.0001:
            sd[a] = _align.kinematic_deflection_noise(col[f"a_body{a}"], col[f"a_wheel{a}"], col[name], al.dt)
        else:  # slower than the grid: not known well enough on it (its spectrum floor holds road there)
            sd[a] = math.nan
    for a in axles:
        rest = [b for b in axles if b != a]
        est = _align.sensor_noise(col[f"a_body{a}"], col[f"a_wheel{a}"], col[f"deflection{a}"], al.dt,
                                  [sd[a], *(sd[b] for b in rest)], [col[f"deflection{b}"] for b in rest])
        out[f"a_body{a}"], out[f"a_wheel{a}"] = est.a_body, est.a_wheel
    return out

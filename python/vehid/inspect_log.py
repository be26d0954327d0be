"""``vehid inspect LOG``: what a CSV, Parquet, ROS 2 bag (``.db3``, a bag folder) or MCAP file
holds, before anything is computed from it: its columns or topics, message types, rates and
their jitter, units (declared or guessed), time span, gaps, the offset of each topic's header
stamps from its log time, and which vehid channels each can feed; with the channels found
(by name, or through ``--columns``), the deflection's delay and sign against the
accelerometers. It ends with a channel map to start from (bags) or the map it used.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import IO, Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
from numpy.typing import NDArray

from . import align as _align
from . import fieldlog
from .bags import MESSAGE_FIELDS, first_line, open_bag, stamp_ns
from .channels import HALF_SENSOR_COLUMNS, SENSOR_COLUMNS
from .io import STANDARD_GRAVITY, UNITS, TableError, normalize, open_table, parse_column_map, si_factor

__all__ = ["DESCRIPTION", "add_arguments", "cmd_inspect", "guess_channel"]

#: Messages deserialized per topic for stamps and fields.
SAMPLE_MESSAGES = 4000
#: Rows read from a table for its figures (the whole file is not needed to describe it).
SAMPLE_ROWS = 400_000

DESCRIPTION = (
    "Describes a log before it is used: columns or topics, message types, rates and jitter, units (declared or "
    "guessed), time span, gaps, clock offsets, and which vehid channels (a_body, a_wheel, deflection) each can feed; "
    "with those channels found (by name or --columns), the deflection's and the body accelerometer's delays and "
    "the deflection's sign. Where they are not found, it prints a channels.toml to start from."
)

#: Name fragments that suggest a vehid channel (after :func:`vehid.io.normalize`).
HINTS = (("deflection", ("defl", "susp", "travel", "stroke", "ride_height", "joint")),
         ("a_wheel", ("wheel", "hub", "knuckle", "unsprung", "axle")),
         ("a_body", ("body", "chassis", "sprung", "imu", "acc")))


def guess_channel(name: str, quantity: str) -> Optional[str]:
    """The vehid channel a column or topic ``name`` of ``quantity`` (``length`` or
    ``acceleration``) suggests, if any.

    >>> guess_channel("SuspTravel [mm]", "length"), guess_channel("/wheel/imu", "acceleration")
    ('deflection', 'a_wheel')
    """
    key = normalize(name).replace("/", "_").lower()
    for channel, words in HINTS:
        wanted = "length" if channel == "deflection" else "acceleration"
        if wanted == quantity and any(w in key for w in words):
            return channel
    return None


def _rate(t: NDArray[np.float64]) -> str:
    """``"400 Hz (jitter 0.01 ms), 3 gaps"`` for times ``t`` (s)."""
    if len(t) < 2:
        return "one sample"
    h = _align.nominal_interval(t)
    d = np.diff(t)
    steady = d[d <= _align.gap_limit(t)]  # none when the times are not finite
    jitter = float(np.std(steady - h)) if len(steady) else 0.0
    jitter = 0.0 if jitter < 1e-9 else jitter  # a float's noise, not the clock's
    gaps = int((d > _align.gap_limit(t)).sum())
    return (f"{1 / h:.6g} Hz (interval {1e3 * h:.6g} ms, jitter {1e6 * jitter:.3g} us), "
            f"{gaps} gap{'s' * (gaps != 1)}")


def _span(t: NDArray[np.float64]) -> str:
    return f"{t[-1] - t[0]:.6g} s" if len(t) else "empty"


def _guess_unit(v: NDArray[np.float64], quantity: str) -> str:
    """A guess at the unit of values ``v`` with no declared unit, from their size."""
    v = v[np.isfinite(v)]
    if len(v) < 10:
        return "?"
    mean, std = float(np.mean(v)), float(np.std(v))
    if quantity == "length":
        return "mm?" if std > 0.25 else "m"
    if abs(mean - 1.0) < 0.2 and std < 5:
        return "g? (mean 1: gravity included)"
    if abs(mean - STANDARD_GRAVITY) < 2:
        return "m/s^2 (gravity included)"
    return "m/s^2"


def cmd_inspect(args: argparse.Namespace) -> int:
    out = sys.stdout
    if fieldlog.is_bag(args.file):
        _inspect_bag(args, out)
    else:
        _inspect_table(args, out)
    return 0


def _channels(half: bool = False) -> Sequence[Any]:
    return (HALF_SENSOR_COLUMNS if half else SENSOR_COLUMNS)["realistic"]


def _cmap(args: argparse.Namespace) -> Tuple[Optional[fieldlog.ChannelMap], Dict[str, str]]:
    cmap, pairs = None, []
    for text in args.columns or []:
        if fieldlog.is_channel_map(text):
            cmap = fieldlog.load_channel_map(text, [c.name for c in (*_channels(), *_channels(True))])
        else:
            pairs.append(text)
    return cmap, parse_column_map(pairs)


def _sample(table: Any, cols: List[int], time_i: Optional[int]) -> NDArray[np.float64]:
    """The columns ``cols`` of ``table`` (its first :data:`SAMPLE_ROWS` rows), float64, empty
    cells NaN, the time column ``time_i`` read as timestamps where it holds them."""
    stamps = [cols.index(time_i)] if time_i in cols else []
    data: List[NDArray[np.float64]] = []
    read = 0
    for chunk in table.chunks(cols, [repr(table.names[i]) for i in cols], 100_000, missing=True, stamps=stamps):
        data.append(chunk.data)
        read += len(chunk.data)
        if read >= SAMPLE_ROWS:
            break
    return np.concatenate(data) if data else np.zeros((0, len(cols)))


def _inspect_table(args: argparse.Namespace, out: IO[str]) -> None:
    cmap, pairs = _cmap(args)
    with open_table(args.file, delimiter=args.delimiter) as table:
        names = table.names
        kind = "Parquet" if table.kind == "parquet" else f"CSV (delimiter {table.delimiter!r})"
        print(f"{table.source}: {kind}, {len(names)} columns", file=out)
        time_i = next((i for i, h in enumerate(names) if normalize(h) in ("t", "time", "time_s", "t_s", "seconds")
                       + fieldlog.MORE_TIME_NAMES), None)
        if cmap and cmap.time_column in names:
            time_i = names.index(cmap.time_column)
        text: Dict[int, str] = {}
        try:
            y = _sample(table, list(range(len(names))), time_i)
        except TableError:  # a column of text (event markers, comments): read the others one by one
            blocks = []
            for i in range(len(names)):
                try:
                    with open_table(args.file, delimiter=args.delimiter) as again:
                        blocks.append(_sample(again, [i], time_i))
                except TableError as e:
                    text[i] = str(e).split(": ")[-1]
                    blocks.append(np.full((0, 1), math.nan))
            rows = max(len(b) for b in blocks)
            y = np.column_stack([b[:, 0] if len(b) == rows else np.full(rows, math.nan) for b in blocks])
        read = len(y)
        if read == 0:
            print("  no samples", file=out)
            return
        proposals: Dict[str, Tuple[Tuple[str, str], ...]] = {}
        if time_i is not None:
            proposals["time"] = (("column", names[time_i]),)
        partial = "" if read < SAMPLE_ROWS else f" (the first {read:,} rows)"
        if time_i is not None:
            declared = (cmap.time_unit if cmap and cmap.time_unit else None) or table.declared_unit(time_i)
            t = y[:, time_i]
            if table.is_timestamp(time_i) or t[0] > 1e8:
                unit, factor = "timestamps", 1.0
            elif declared:
                factor = si_factor(declared, "time", f"time column {names[time_i]!r}")
                unit = f"{declared} (declared)"
            else:
                h = _align.nominal_interval(t)
                factor, unit = (1e-3, "ms? (no unit declared; intervals of whole numbers)") if h >= 0.5 else \
                    (1.0, "s (no unit declared)")
            ts = t * factor
            print(f"  time: column {names[time_i]!r}, {unit}; {len(ts):,} samples{partial} over {_span(ts)}; "
                  f"{_rate(ts)}", file=out)
        else:
            print("  time: no time column (give --dt to vehid monitor)", file=out)
        for i, name in enumerate(names):
            if i == time_i:
                continue
            if i in text:
                print(f"  column {name!r}: not numbers ({text[i]}); not read", file=out)
                continue
            v = y[:, i]
            declared = table.declared_unit(i)
            shown: Optional[str] = f"{declared} (declared)" if declared else None
            q = ""
            if declared:
                q = UNITS.get(declared.lower().replace(" ", ""), ("", 1.0))[0]
            guess_q = q or ("length" if guess_channel(name, "length") == "deflection" else "acceleration")
            feeds = guess_channel(name, guess_q)
            if shown is None:
                shown = _guess_unit(v, guess_q) + " (guessed)"
            if feeds and feeds not in proposals:
                guessed = shown.split(" ")[0].rstrip("?")
                proposals[feeds] = (("column", name),) + ((("unit", guessed),) if "guessed" in shown and
                                                          guessed in UNITS and guessed not in ("m", "m/s^2") else ())
            missing = int(np.isnan(v).sum())
            print(f"  column {name!r}: {shown}; mean {np.nanmean(v):.4g}, std {np.nanstd(v):.4g}; "
                  f"{missing} missing" + (f"; can feed {feeds}" if feeds else ""), file=out)
    if not _channels_found(args, cmap, pairs, out) and cmap is None:
        _propose(proposals, out)


def _channels_found(args: argparse.Namespace, cmap: Optional[fieldlog.ChannelMap], pairs: Dict[str, str],
                    out: IO[str]) -> bool:
    """With the quarter car's three channels found (or the half car's six): the grid, the
    deflections' delays and signs, the sensors' noise (True)."""
    half = cmap is not None and any(c.endswith(("_f", "_r")) for c in cmap.channels)
    try:
        try:
            log = fieldlog.read_log(args.file, _channels(half), cmap, pairs, args.delimiter, None)
        except TableError:
            if half or cmap is not None:
                raise
            try:  # a half car's log (a_body_f, ..., deflection_r)?
                log = fieldlog.read_log(args.file, _channels(True), cmap, pairs, args.delimiter, None)
            except TableError:
                log = fieldlog.read_log(args.file, _channels(), cmap, pairs, args.delimiter, None)  # its message
        al = fieldlog.align(log, None, cmap.channels if cmap else None, estimate=True)
    except TableError as e:
        print(f"  vehid channels: not all found or not usable ({e})", file=out)
        return False
    srcs = ", ".join(f"{s.channel} <- {s.source} [{s.unit}: {s.unit_from}]" for s in log.series)
    print(f"  vehid channels: {srcs}", file=out)
    for note in al.notes:
        print(f"  note: {note}", file=out)
    for name, delay in al.delays.items():
        if math.isfinite(delay):
            how = ("the deflection (from the body equation)" if name.startswith("a_body") else
                   "the accelerometers (from d'' = a_body - a_wheel)")
            print(f"  clock: {name} is {1e3 * abs(delay):.2f} ms {'late' if delay >= 0 else 'early'} against {how}",
                  file=out)
    print(f"  on the monitor's grid: {len(al.y):,} samples at {1 / al.dt:g} Hz, {al.missing} missing", file=out)
    print(f"  {noise_line({**fieldlog.accelerometer_noises(al), **fieldlog.deflection_noises(log, al.dt)})}", file=out)
    return True


def noise_line(found: Dict[str, float]) -> str:
    """The sensors' white noise per grid sample estimated from the data (``{channel: SI}``,
    NaN: not estimated), each beside the monitor's default, as ``vehid monitor`` would take it.

    >>> noise_line({"a_body": 0.0613, "a_wheel": 0.0964, "deflection": float("nan")})
    ... # doctest: +NORMALIZE_WHITESPACE
    'sensor noise per sample, estimated from the data (vehid monitor uses an estimate over 1.25 times its default
     unless --noise declares it): a_body 0.0613 m/s^2 (default 0.02: used), a_wheel 0.0964 m/s^2 (default 0.1),
     deflection not estimated (default 0.3 mm)'
    """
    parts = []
    kinds = ("a_body", "a_wheel", "deflection")
    base = {name: name[:-2] if name.endswith(("_f", "_r")) else name for name in found}  # a_body_f -> a_body
    for name in sorted(found, key=lambda c: (c[len(base[c]):], kinds.index(base[c]))):
        value, default = found[name], fieldlog.DEFAULT_NOISE[base[name]]
        mm = base[name] == "deflection"
        shown = f"{1e3 * value:.3g} mm" if mm else f"{value:.3g} m/s^2"
        shown_default = f"{1e3 * default:g} mm" if mm else f"{default:g}"
        used = ": used" if value > fieldlog.NOISE_USED_ABOVE * default else ""
        parts.append(f"{name} {shown} (default {shown_default}{used})" if math.isfinite(value)
                     else f"{name} not estimated (default {shown_default})")
    return (f"sensor noise per sample, estimated from the data (vehid monitor uses an estimate over "
            f"{fieldlog.NOISE_USED_ABOVE:g} times its default unless --noise declares it): " + ", ".join(parts))


def _inspect_bag(args: argparse.Namespace, out: IO[str]) -> None:
    cmap, _ = _cmap(args)
    reader = open_bag(args.file)
    proposals: Dict[str, Tuple[str, str, Optional[str]]] = {}
    try:
        with reader:
            conns = sorted(reader.connections, key=lambda c: c.topic)
            total = sum(c.msgcount for c in conns)
            print(f"{args.file}: ROS bag, {len(conns)} topics, {total:,} messages", file=out)
            for conn in conns:
                proposals.update(_topic(reader, conn, out))
    except TableError:
        raise
    except Exception as e:
        raise TableError(f"{args.file}: cannot read the bag ({first_line(e)}): is it truncated?") from None
    if cmap is not None:
        _channels_found(args, cmap, {}, out)
        return
    _propose({k: (("topic", v[0]), ("field", v[1])) + ((("joint", v[2]),) if v[2] else ())
              for k, v in proposals.items()}, out)


def _propose(proposals: Dict[str, Tuple[Tuple[str, str], ...]], out: IO[str]) -> None:
    """Prints a channel map from ``{channel: ((key, value), ...)}`` guesses."""
    if not proposals:
        return
    print("a channels.toml to start from (check each guess; then vehid monitor LOG --columns channels.toml):",
          file=out)
    for channel in ("time", "a_body", "a_wheel", "deflection"):
        if channel in proposals:
            print(f"[{channel}]", file=out)
            for key, value in proposals[channel]:
                print(f"{key} = \"{value}\"", file=out)


def _numeric_fields(msg: Any, prefix: str = "", depth: int = 0) -> List[str]:
    """The paths of a message's numeric fields (arrays as ``name[i]``, at most 3 shown)."""
    out: List[str] = []
    if depth > 4:
        return out
    for name in getattr(msg, "__dataclass_fields__", {}):
        value = getattr(msg, name)
        path = f"{prefix}{name}"
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            out.append(path)
        elif isinstance(value, np.ndarray) and value.dtype.kind in "fiu":
            out += [f"{path}[{i}]" for i in range(min(3, len(value)))]
        elif hasattr(value, "__dataclass_fields__") and name != "header":
            out += _numeric_fields(value, path + ".", depth + 1)
    return out


def _topic(reader: Any, conn: Any, out: IO[str]) -> Dict[str, Tuple[str, str, Optional[str]]]:
    """One topic's line; the channel it may feed, as ``{channel: (topic, field, joint)}``."""
    logged: List[int] = []
    stamps: List[int] = []
    first: Any = None
    for k, (_, t, raw) in enumerate(reader.messages(connections=[conn])):
        logged.append(int(t))
        if k < SAMPLE_MESSAGES:
            msg = reader.deserialize(raw, conn.msgtype)
            first = first if first is not None else msg
            s = stamp_ns(msg)
            if s:
                stamps.append(s)
    t_log = np.asarray((np.asarray(logged, dtype=np.int64) - (logged[0] if logged else 0)) * 1e-9, dtype=np.float64)
    typ = conn.msgtype
    line = f"  {conn.topic}: {typ}, {len(logged):,} messages over {_span(t_log)}"
    if stamps:
        st = np.asarray(stamps, dtype=np.int64)
        t_st = np.asarray((st - st[0]) * 1e-9, dtype=np.float64)
        offset = float(np.median(np.asarray(logged[: len(st)], dtype=np.int64) - st)) * 1e-6
        line += f"; header.stamp {_rate(np.sort(t_st))}; logged {offset:.3g} ms after its stamp"
        back = np.diff(st) < 0
        if back.any():
            line += f"; {int(back.sum())} messages logged out of stamp order"
    else:
        line += f"; no header.stamp: log time {_rate(t_log)}"
    feeds: Dict[str, Tuple[str, str, Optional[str]]] = {}
    default = MESSAGE_FIELDS.get(typ)
    if typ == "sensor_msgs/msg/Imu":
        imu = guess_channel(conn.topic, "acceleration") or "a_body"
        feeds[imu] = (conn.topic, "linear_acceleration.z", None)
        line += "; linear_acceleration (m/s^2, gravity included: REP 145) -> a_body or a_wheel"
    elif typ == "sensor_msgs/msg/JointState" and first is not None:
        names = list(first.name)
        line += (f"; joints {', '.join(names[:8])}: position -> deflection (m for a prismatic joint; a revolute "
                 "joint's angle: unit = \"rad\" and scale = its travel in m per rad)")
        if names:
            feeds["deflection"] = (conn.topic, "position", names[0])
    elif default is not None:
        ch: Optional[str] = guess_channel(conn.topic, "length") or guess_channel(conn.topic, "acceleration")
        line += f"; {default[0]}" + (f" -> {ch}?" if ch else " (a scalar: any channel, with its unit)")
        if ch:
            feeds[ch] = (conn.topic, default[0], None)
    elif first is not None:
        fields = _numeric_fields(first)
        line += f"; numeric fields: {', '.join(fields[:8]) or 'none'} (field = \"...\" in the channel map)"
    print(line, file=out)
    return feeds


def add_arguments(p: argparse.ArgumentParser, delimiter: Callable[[str], str]) -> None:
    """The options of ``vehid inspect``."""
    p.add_argument("file", metavar="LOG", help="CSV or Parquet file, ROS 2 bag (.mcap, .db3, a bag folder)")
    p.add_argument("--columns", action="append", metavar="MAP",
                   help="a channels.toml (or NAME=COLUMN pairs): with it, the channels are read as vehid monitor "
                        "reads them, and their delay and sign are shown")
    p.add_argument("--delimiter", type=delimiter, default=None, metavar="D", help="CSV separator (default: sniffed)")


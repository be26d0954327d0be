"""The pure fold at the core of a fleet run: one vehicle-day at a time,
``(state | None, day's table) -> (state, events, summary)``.

Deterministic: the same state and table give the same bytes, whichever process or thread runs
it. The state is the HealthMonitor's own versioned serialized form (the tuple it pickles
through, ``(format, "vehid <version>", payload)``), packed into bytes by :func:`pack_state`;
restoring it goes through the monitor's checked ``__setstate__``, never through ``pickle``,
so a store cannot run code.

How a day is fed to the monitor:

* the day's rows in time order (column ``t``, seconds from the day's start; a missing cell,
  null or NaN, is a missing sample, as in ``vehid monitor``);
* a step of ``t`` over 1.5 sample intervals is a gap: ``round(step/dt) - 1`` missing samples,
  at most :data:`GAP_CAP` seconds of them (beyond that the monitor has long restarted its
  filters; a parked car's hours are not fed);
* a day after another day starts with one missing sample (the days are not contiguous: the
  monitor restarts its filters and keeps its reference and CUSUMs, so a change overnight is
  still found).
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple

import numpy as np
from numpy.typing import NDArray

from .._vehid import HealthMonitor, VehidError
from ..channels import FULL_SENSOR_COLUMNS, HALF_SENSOR_COLUMNS, SENSOR_COLUMNS, event_corner
from ..io import Column, TableError, match_columns
from ._deps import module
from .config import VehicleConfig

#: Longest gap fed as missing samples, s.
GAP_CAP = 60.0
#: Seconds of samples per call into the monitor; the status is sampled after each (the shares).
BLOCK = 5.0
#: Seconds between two points of the daily trend of the tracked ratios.
TREND = 60.0
_MAGIC = b"VHFS"


#: The schema metadata key under which :func:`vehid.fleet.layout.read_day` records the day's
#: files and their rows (JSON ``[[name, rows], ...]``), so that a message names a row in its file.
FILES_KEY = b"vehid.files"


def row_place(table: Any, i: int) -> str:
    """Row ``i`` (0-based) of a day's ``table`` as messages name it: ``"b.parquet, row 12"``
    (1-based, in its own file) when the table records its files (``FILES_KEY``), else
    ``"row 13"`` (1-based, in the table)."""
    meta = (table.schema.metadata or {}).get(FILES_KEY)
    if meta:
        start = 0
        for name, rows in json.loads(meta):
            if i < start + rows:
                return f"{name}, row {i - start + 1}"
            start += rows
    return f"row {i + 1}"


class DayError(ValueError):
    """A vehicle-day the fold cannot use (missing column, time not increasing, ...): the
    message is the reason recorded in the store."""


def pack_state(mon: HealthMonitor) -> bytes:
    """The monitor's serialized form as bytes: ``VHFS``, its format (u32), its version
    string (u16 length + UTF-8) and its payload."""
    fmt, version, payload = mon.__reduce__()[2]
    v = str(version).encode()
    return _MAGIC + struct.pack("<IH", int(fmt), len(v)) + v + bytes(payload)


def unpack_state(data: bytes, config: VehicleConfig) -> HealthMonitor:
    """The monitor saved by :func:`pack_state` (built as ``config`` says, then its state
    replaced by the saved one); :class:`DayError` if the bytes are not such a state or the
    monitor refuses them."""
    if not data.startswith(_MAGIC) or len(data) < 10:
        raise DayError("the stored state is not a vehid monitor state (corrupt store?)")
    fmt, n = struct.unpack_from("<IH", data, 4)
    version = data[10 : 10 + n].decode(errors="replace")
    mon = config.monitor_new()
    try:
        mon.__setstate__((fmt, version, data[10 + n :]))
    except VehidError as e:
        raise DayError(f"the stored state cannot be restored: {e}") from None
    return mon


def state_version(data: bytes) -> str:
    """The ``vehid <version>`` that wrote a packed state."""
    _, n = struct.unpack_from("<IH", data, 4)
    return data[10 : 10 + n].decode(errors="replace")


@dataclass
class DayResult:
    """What the fold returns for one vehicle-day."""

    #: The monitor's state after the day (:func:`pack_state`).
    state: bytes
    #: One dict per event: t (s from the day's start), parameter, before, after, low, high, corner,
    #: t_change (s from the day's start, the estimated onset), change (relative).
    events: List[Dict[str, Any]] = field(default_factory=list)
    #: JSON-able: samples, seconds, missing, status shares (s), trend, ... (see :func:`fold`).
    summary: Dict[str, Any] = field(default_factory=dict)


def channels(config: VehicleConfig) -> Tuple[Column, ...]:
    """The sensor channels a vehicle's logs must hold."""
    table = FULL_SENSOR_COLUMNS if config.full else HALF_SENSOR_COLUMNS if config.half else SENSOR_COLUMNS
    return table[config.sensors]


def day_arrays(table: Any, config: VehicleConfig, where: str = "the day") -> Tuple[NDArray[np.float64],
                                                                                  NDArray[np.float64]]:
    """``(t, y)`` of a day's pyarrow table: times (s) and the channels (float64, C order, NaN
    where a cell is missing); :class:`DayError` for a missing column or one that is not numbers."""
    pa = module("pyarrow")
    pc = module("pyarrow.compute")
    chans = channels(config)
    try:
        match = match_columns(table.column_names, (Column("t", "time", "s"),) + chans, dict(config.columns),
                              where=where)
    except TableError as e:
        raise DayError(str(e)) from None
    absent = [c.name for c in (Column("t", "time", "s"),) + chans if c.name not in match.index]
    if absent:
        raise DayError(f"missing column(s) {', '.join(absent)} (columns: {', '.join(table.column_names[:12])}); "
                       "name them so, or map them with columns = {...} in fleet.toml")

    def into(out: NDArray[np.float64], name: str) -> None:
        """The column ``name`` into ``out`` (a view), chunk by chunk: no joined copy."""
        col = table.column(match.index[name])
        if not (pa.types.is_integer(col.type) or pa.types.is_floating(col.type)):
            raise DayError(f"column {table.column_names[match.index[name]]!r} holds {col.type}, not numbers")
        if col.null_count:
            col = pc.cast(col, pa.float64()).fill_null(math.nan)
        at = 0
        for chunk in col.chunks:
            k = len(chunk)
            out[at : at + k] = chunk.to_numpy(zero_copy_only=False)
            at += k

    n = table.num_rows
    t = np.empty(n)
    into(t, "t")
    y = np.empty((n, len(chans)))
    for j, c in enumerate(chans):
        into(y[:, j], c.name)
    return t, y


def fold(state: Optional[bytes], table: Any, config: VehicleConfig) -> DayResult:
    """One vehicle-day: restores the monitor from ``state`` (None: a new vehicle), feeds it
    the day's ``table`` (pyarrow: ``t`` in s from the day's start and the channels, as
    ``vehid monitor`` reads them) and returns the new state, the day's events and its summary.

    The summary holds ``t0``, ``t1`` (s, the first and last time), ``samples`` (rows),
    ``seconds`` (rows × dt), ``missing`` (missing samples fed for gaps), ``status`` (seconds
    of driving in ``warmup``, ``judged`` and ``cannot judge``: the status after each block of
    :data:`BLOCK` s, counted for the block), ``reasons`` (seconds per reason of "cannot judge"),
    ``end_status``, ``trend`` (every :data:`TREND` s of driving: ``t`` and the tracked ratios by
    name, null where the monitor could not judge) and ``config`` (the settings' fingerprint).

    Raises :class:`DayError` (nothing changes) for a day it cannot use."""
    t, y = day_arrays(table, config)
    if len(t) == 0:
        raise DayError("no samples")
    if np.isnan(t).any():
        i = int(np.argmax(np.isnan(t)))
        raise DayError(f"{row_place(table, i)}: the time t is missing")
    mon = config.monitor_new() if state is None else unpack_state(state, config)
    dt = mon.dt
    d = np.diff(t)
    bad = ~(d >= 0.5 * dt)
    if bad.any():
        i = int(np.argmax(bad))
        if d[i] <= 0:
            raise DayError(f"{row_place(table, i + 1)}: time {t[i + 1]!r} s does not increase after {t[i]!r} s "
                           "(rows out of order or repeated: sort the day's files, drop duplicated samples)")
        raise DayError(f"{row_place(table, i + 1)}: the sample interval {d[i]:.6g} s is under half of dt = {dt:g} s "
                       "(fleet.toml's dt, or resample the log)")
    cap = int(round(GAP_CAP / dt))
    # Segments of rows between gaps; before each, its missing samples (one before the first
    # row after an earlier day).
    breaks = np.flatnonzero(d >= 1.5 * dt) + 1
    starts = np.concatenate([[0], breaks]).astype(np.int64)
    ends = np.concatenate([breaks, [len(t)]]).astype(np.int64)
    before = np.minimum(np.rint(d[breaks - 1] / dt).astype(np.int64) - 1, cap) if len(breaks) else np.zeros(0, int)
    missing = np.concatenate([[0 if state is None else 1], before]).astype(np.int64)
    # Where each segment's first row falls among the samples fed today.
    fed_start = starts + np.cumsum(missing)

    s0 = mon.samples
    width = y.shape[1]
    block = max(1, int(round(BLOCK / dt)))
    trend_rows = max(1, int(round(TREND / dt)))
    names = (tuple(f"{q}_{c}" for c in ("fl", "fr", "rl", "rr") for q in ("k", "b")) if config.full
             else ("k2_f", "b_f", "k2_r", "b_r") if config.half else ("k2/M", "b/M"))
    shares: Dict[str, float] = {"warmup": 0.0, "judged": 0.0, "cannot judge": 0.0}
    reasons: Dict[str, float] = {}
    trend_t: List[float] = []
    trend_v: List[List[Optional[float]]] = []
    events: List[Dict[str, Any]] = []

    def day_time(tm: float) -> float:
        """The day's time of the monitor's time ``tm`` (a missing sample's: its row's less
        whole intervals)."""
        k = int(round(tm / dt)) - s0
        j = max(0, int(np.searchsorted(fed_start, k, side="right")) - 1)
        row = starts[j] + (k - fed_start[j])
        if row < starts[j]:
            return float(t[starts[j]] - (starts[j] - row) * dt)
        if row >= ends[j]:
            return float(t[ends[j] - 1] + (row - ends[j] + 1) * dt)
        return float(t[row])

    def feed(rows: NDArray[np.float64], where: float) -> None:
        try:
            evs = mon.fit(rows)
        except VehidError as e:
            raise DayError(f"near t = {where:.3f} s: the monitor refused the samples ({e})") from None
        for ev in evs:
            p = ev.parameter
            events.append({"t": day_time(ev.t), "parameter": p, "before": ev.before, "after": ev.after,
                           "low": ev.low, "high": ev.high, "corner": event_corner(p, ev.position),
                           "t_change": day_time(ev.t_change), "change": ev.change})

    for a, b, gap in zip(starts.tolist(), ends.tolist(), missing.tolist()):
        if gap:
            feed(np.full((gap, width), math.nan), float(t[a]))
        for i in range(a, b, block):
            j = min(i + block, b)
            feed(y[i:j], float(t[i]))
            status = mon.status
            seconds = (j - i) * dt
            judged = status in ("monitoring", "settling")
            if judged:
                shares["judged"] += seconds
            elif status == "warmup":
                shares["warmup"] += seconds
            else:
                shares["cannot judge"] += seconds
                why = status.split(": ", 1)[-1]
                reasons[why] = reasons.get(why, 0.0) + seconds
            if j // trend_rows > i // trend_rows or i == 0:
                trend_t.append(round(float(t[j - 1]), 3))
                trend_v.append(_tracked(mon.estimate, config.model) if judged else [None] * len(names))
    summary: Dict[str, Any] = {
        "t0": float(t[0]), "t1": float(t[-1]), "samples": int(len(t)), "seconds": round(len(t) * dt, 9),
        "missing": int(missing.sum()), "status": {k: round(v, 6) for k, v in shares.items()},
        "reasons": {k: round(v, 6) for k, v in sorted(reasons.items())}, "end_status": mon.status,
        "trend": {"names": list(names), "t": trend_t, "values": trend_v}, "config": config.fingerprint(),
    }
    return DayResult(state=pack_state(mon), events=events, summary=summary)


def _tracked(est: Dict[str, Any], model: str) -> List[Optional[float]]:
    """The tracked ratios now: the quarter car's k2/M (1/s²) and b/M (1/s); the half car's
    corner coefficients of its own constants (α k2_f, α b_f from the front equation, α k2_r,
    α b_r from the rear); the full car's each corner's spring's and damper's in its own
    equation ((α K)_ii, α_ii b_i; corners fl, fr, rl, rr)."""
    if model == "full":
        vals = [est[c][j][0] for i, c in enumerate(("fl", "fr", "rl", "rr")) for j in (2 * i, 2 * i + 1)]
    elif model == "half":
        vals = [est["front"][0][0], est["front"][1][0], est["rear"][2][0], est["rear"][3][0]]
    else:
        vals = [est["k2/M"][0], est["b/M"][0]]
    return [float(f"{float(v):.6g}") if math.isfinite(float(v)) else None for v in vals]


def summary_json(summary: Dict[str, Any]) -> str:
    """The summary as the store holds it (compact, keys sorted: the same bytes every time)."""
    return json.dumps(summary, sort_keys=True, separators=(",", ":"), allow_nan=False)

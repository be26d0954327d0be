"""The health monitor's results where users look: events and tracked ratios as Parquet (pyarrow)
or as MCAP (through ``rosbags``' writer, ROS 2 message types, so that Foxglove or PlotJuggler
overlay them on the raw topics: same clock as the bag's when the log carries absolute times).

MCAP topics: ``/vehid/events`` (``std_msgs/String``, one JSON object per event, at the event's
time), ``/vehid/k2_over_M`` and ``/vehid/b_over_M`` (``std_msgs/Float64``, 1/s^2 and 1/s, every
record of the monitor, with ``_low`` and ``_high`` topics for the 95 % band) and
``/vehid/status`` (``std_msgs/String``).
"""

from __future__ import annotations

import importlib
import json
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Callable, Dict, List, Sequence

from .io import TableError

__all__ = ["event_rows", "write_events", "write_track"]


def event_rows(events: Sequence[Any], clock: Callable[[float], float], names: Dict[str, Any]) -> List[Dict[str, Any]]:
    """The events as rows: ``t`` and ``t_change`` (s, on the log's clock: ``clock`` of the
    monitor's time), the constant, its name and unit, before, after, the interval and the change."""
    rows = []
    for ev in events:
        name, unit = names.get(ev.parameter, (ev.parameter, ""))
        rows.append({"t": clock(ev.t), "t_change": clock(ev.t_change), "parameter": ev.parameter, "name": name,
                     "unit": unit, "before": ev.before, "after": ev.after, "low": ev.low, "high": ev.high,
                     "change": ev.change})
    return rows


def _parquet(path: str, columns: Dict[str, List[Any]]) -> None:
    try:
        pa = importlib.import_module("pyarrow")
        pq = importlib.import_module("pyarrow.parquet")
    except ImportError:
        raise TableError(f"{path}: writing Parquet needs pyarrow: pip install 'vehid[parquet]'") from None
    try:
        pq.write_table(pa.table(columns), path)
    except OSError as e:
        raise TableError(f"{path}: cannot write ({e})") from None


def write_events(path: str, rows: List[Dict[str, Any]], track: Dict[str, List[Any]]) -> None:
    """``--events PATH``: ``.parquet`` (the events) or ``.mcap`` (the events and the track)."""
    if path.lower().endswith(".mcap"):
        _mcap(path, rows, track)
        return
    if not path.lower().endswith(".parquet"):
        raise TableError(f"--events {path}: give a .parquet or .mcap file")
    keys = ["t", "t_change", "parameter", "name", "unit", "before", "after", "low", "high", "change"]
    _parquet(path, {k: [r[k] for r in rows] for k in keys})


def write_track(path: str, track: Dict[str, List[Any]]) -> None:
    """``--track PATH.parquet``: the tracked ratios every record (t, k2/M, b/M with their 95 %
    band, the status)."""
    if not path.lower().endswith(".parquet"):
        raise TableError(f"--track {path}: give a .parquet file (or --events FILE.mcap for both)")
    _parquet(path, track)


def _mcap(path: str, rows: List[Dict[str, Any]], track: Dict[str, List[Any]]) -> None:
    try:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise TableError(f"--events {path}: writing MCAP needs rosbags: pip install 'vehid[ros]'") from None
    ts = get_typestore(Stores.ROS2_HUMBLE)
    string, double = ts.types["std_msgs/msg/String"], ts.types["std_msgs/msg/Float64"]
    tmp = tempfile.mkdtemp(prefix="vehid-mcap-", dir=os.path.dirname(os.path.abspath(path)) or None)
    try:
        bag = Path(tmp) / "bag"
        with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as w:
            events = w.add_connection("/vehid/events", "std_msgs/msg/String", typestore=ts)
            status = w.add_connection("/vehid/status", "std_msgs/msg/String", typestore=ts)
            series = {name: w.add_connection(f"/vehid/{name}", "std_msgs/msg/Float64", typestore=ts)
                      for name in ("k2_over_M", "k2_over_M_low", "k2_over_M_high", "b_over_M", "b_over_M_low",
                                   "b_over_M_high")}
            for row in rows:
                w.write(events, _ns(row["t"]), ts.serialize_cdr(string(data=json.dumps(row)), "std_msgs/msg/String"))
            for k, t in enumerate(track["t"]):
                w.write(status, _ns(t), ts.serialize_cdr(string(data=str(track["status"][k])), "std_msgs/msg/String"))
                for name, conn in series.items():
                    value = float(track[name][k])
                    if math.isfinite(value):
                        w.write(conn, _ns(t), ts.serialize_cdr(double(data=value), "std_msgs/msg/Float64"))
        written = next(bag.glob("*.mcap"))
        shutil.move(str(written), path)
    except OSError as e:
        raise TableError(f"--events {path}: cannot write ({e})") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _ns(t: float) -> int:
    """Seconds (since 1970, or on the log's clock) as the integer nanoseconds MCAP stores."""
    return max(0, int(round(t * 1e9)))

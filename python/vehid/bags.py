"""ROS 2 bags and MCAP for :mod:`vehid.fieldlog`, through ``rosbags`` (pure Python, no ROS
install; ``pip install 'vehid[ros]'``): ``.mcap`` and ``.db3`` files and rosbag2 folders,
split bags included (a folder of several storage files, read in order; one of its files alone
is refused, naming the folder), and ROS 1 ``.bag`` files (rosbags' ROS 1 reader). A
channel is one numeric field of one topic's messages, at its ``header.stamp`` (or the time it
was logged); REP 145: an IMU's linear acceleration is specific force (gravity included), and
covariance[0] = -1 marks it absent (read as missing).
"""

from __future__ import annotations

import math
import os
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .channels import MAX_JUMP, ChannelMap, ChannelSpec, Log, Series, unit_of
from .io import Column, TableError

__all__ = ["MESSAGE_FIELDS", "first_line", "open_bag", "read_bag", "stamp_ns"]

#: What each ROS message type gives by default: ``(field, unit, gravity)``.
MESSAGE_FIELDS: Dict[str, Tuple[str, str, Optional[str]]] = {
    "sensor_msgs/msg/Imu": ("linear_acceleration.z", "m/s^2", "included"),
    "sensor_msgs/msg/JointState": ("position", "m", None),
    "std_msgs/msg/Float64": ("data", "", None),
    "std_msgs/msg/Float32": ("data", "", None),
    "geometry_msgs/msg/AccelStamped": ("accel.linear.z", "m/s^2", None),
    "geometry_msgs/msg/Vector3Stamped": ("vector.z", "", None),
    "sensor_msgs/msg/Range": ("range", "m", None),
}


def _rosbags() -> Tuple[Any, Any, Any]:
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise TableError("reading ROS bags and MCAP needs rosbags: pip install 'vehid[ros]'") from None
    return AnyReader, Stores, get_typestore


def open_bag(path: str) -> Any:
    """A ``rosbags`` ``AnyReader`` on ``path`` (not yet opened), or a one-line error."""
    from pathlib import Path

    AnyReader, Stores, get_typestore = _rosbags()
    if not os.path.exists(path):
        raise TableError(f"{path}: no such file or folder")
    _whole_bag(path)
    try:
        return AnyReader([Path(path)], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
    except Exception as e:  # rosbags' own error family
        raise TableError(f"{path}: not a readable ROS bag ({first_line(e)})") from None


def _whole_bag(path: str) -> None:
    """Refuses one storage file of a split rosbag2 bag (its folder's ``metadata.yaml`` lists
    more than one): read alone, it would be part of the drive, silently."""
    folder, name = os.path.split(os.path.abspath(path))
    meta = os.path.join(folder, "metadata.yaml")
    if os.path.isdir(path) or not os.path.isfile(meta):
        return
    try:
        with open(meta, encoding="utf-8") as f:
            text = f.read(1 << 20)
    except (OSError, UnicodeDecodeError):
        return
    block = text.split("relative_file_paths:", 1)[1] if "relative_file_paths:" in text else ""
    files = []
    for line in block.splitlines()[1:]:
        item = line.strip()
        if not item.startswith("- "):
            break
        files.append(item[2:].strip().strip("'\""))
    if len(files) > 1 and name in files:
        raise TableError(f"{path}: part {files.index(name) + 1} of {len(files)} of a split bag (its metadata.yaml "
                         f"lists {', '.join(files)}): give the bag's folder, {folder}, to read all of it")


def first_line(e: BaseException) -> str:
    text = str(e).strip().splitlines()
    return text[0] if text else type(e).__name__


def _field(msg: Any, path: str) -> Any:
    """``msg.a.b[2]``-style field ``path`` of a message."""
    value = msg
    for part in path.split("."):
        name, _, index = part.partition("[")
        value = getattr(value, name)
        if index:
            value = value[int(index.rstrip("]"))]
    return value


def stamp_ns(msg: Any) -> Optional[int]:
    header = getattr(msg, "header", None)
    stamp = getattr(header, "stamp", None)
    if stamp is None:
        return None
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def read_bag(path: str, channels: Sequence[Column], cmap: ChannelMap) -> Log:
    """The channels ``channels`` of the bag ``path`` through the channel map ``cmap``, in SI
    (:class:`vehid.fieldlog.Log`; times in s from the first channel's first stamp)."""
    reader = open_bag(path)
    series: List[Series] = []
    notes: List[str] = []
    origin: List[int] = []
    try:
        with reader:
            by_topic = {c.topic: c for c in reader.connections}
            for c in channels:
                spec = cmap.channels.get(c.name)
                if spec is None:
                    raise TableError(f"--columns {cmap.path}: no [{c.name}] section: {path} needs one for each of "
                                     f"{', '.join(x.name for x in channels)} (vehid inspect {path} lists the topics)")
                if spec.topic not in by_topic:
                    shown = ", ".join(sorted(t for t in by_topic if t is not None)[:12])
                    raise TableError(f"{path}: no topic {spec.topic!r} for [{c.name}] (its topics: {shown})")
                series.append(_bag_series(reader, by_topic[spec.topic], spec, c, cmap.stamp, path, notes, origin))
    except TableError:
        raise
    except Exception as e:  # a truncated or corrupt bag: rosbags' and the storage's errors
        raise TableError(f"{path}: cannot read the bag ({first_line(e)}): is it truncated? "
                         "(ros2 bag reindex can repair a bag whose recording was cut)") from None
    return Log(path, "bag", series, True, notes, origin=origin[0] * 1e-9)


def _bag_series(reader: Any, conn: Any, spec: ChannelSpec, column: Column, stamp: str, path: str,
                notes: List[str], origin: List[int]) -> Series:
    """One channel of a bag; times in s from ``origin[0]`` (ns since 1970: the first
    channel's first stamp, set by the first call)."""
    msgtype = conn.msgtype
    where = f"{path}, topic {spec.topic}"
    default = MESSAGE_FIELDS.get(msgtype)
    fieldpath = spec.field or (default[0] if default else None)
    if fieldpath is None:
        known = ", ".join(k.replace("/msg/", "/") for k in MESSAGE_FIELDS)
        raise TableError(f"{where}: a {msgtype} message: vehid reads {known} by default; give field = \"...\" "
                         f"(the value's path in the message) in [{spec.channel}]")
    if msgtype == "sensor_msgs/msg/JointState" and spec.field is None and spec.joint is None:
        fieldpath = "position[0]"
    ts: List[int] = []
    vs: List[float] = []
    no_header = False
    index: Optional[int] = None
    for _, logged, raw in reader.messages(connections=[conn]):
        msg = reader.deserialize(raw, msgtype)
        if spec.joint is not None:
            if index is None:
                names = list(getattr(msg, "name", []))
                if spec.joint not in names:
                    raise TableError(f"{where}: no joint {spec.joint!r} in its JointState (its joints: "
                                     f"{', '.join(names[:12])})")
                index = names.index(spec.joint)
            fp = f"{spec.field or 'position'}[{index}]"
        else:
            fp = fieldpath
        try:
            value = float(_field(msg, fp))
        except (AttributeError, IndexError, ValueError, TypeError):
            raise TableError(f"{where}: a {msgtype} message has no number at field {fp!r} for [{spec.channel}]: "
                             "give the right field = \"...\" (vehid inspect lists the fields)") from None
        if msgtype == "sensor_msgs/msg/Imu" and fp.startswith("linear_acceleration"):
            cov = getattr(msg, "linear_acceleration_covariance", None)
            if cov is not None and len(cov) and float(cov[0]) == -1.0:  # REP 145: the field is absent
                value = math.nan
        t = stamp_ns(msg) if stamp == "header" else None
        if t is None or t == 0:
            no_header = no_header or stamp == "header"
            t = int(logged)
        ts.append(t)
        vs.append(value)
    if not ts:
        raise TableError(f"{where}: no messages for [{spec.channel}]")
    if no_header:
        notes.append(f"topic {spec.topic}: no header.stamp in its messages: the log time is used")
    t_ns = np.asarray(ts, dtype=np.int64)
    order = np.argsort(t_ns, kind="stable")
    back = np.flatnonzero(np.diff(t_ns) < 0)
    if len(back):
        i = int(back[0])
        jump = (t_ns[i] - t_ns[i + 1]) * 1e-9
        if jump > 1.0:
            raise TableError(f"{where}: the clock jumps back {jump:.3g} s at message {i + 2} (header.stamp): "
                             "split the bag there, or read the log time with stamp = \"log\" in the channel map")
        t_ns = t_ns[order]  # messages that arrived out of order
    v = np.asarray(vs, dtype=np.float64)[order] if len(back) else np.asarray(vs, dtype=np.float64)
    d = np.diff(t_ns)
    if len(d) and int(d.max()) > MAX_JUMP * 1e9:
        i = int(np.argmax(d))
        raise TableError(f"{where}: the clock jumps {d[i] * 1e-9:.6g} s forward at message {i + 2}: "
                         "split the bag there (or read the log time with stamp = \"log\")")
    if len(d) and (d == 0).any():
        keep = np.concatenate([[True], d > 0])
        t_ns, v = t_ns[keep], v[keep]
    unit_spec = spec.unit or (default[1] if default and default[1] else None)
    factor, unit, unit_from = unit_of(spec if spec.unit else None, unit_spec, column, where)
    if not spec.unit and unit_spec:
        unit_from = f"{msgtype.split('/')[-1]} message (REP 103: SI)"
    with np.errstate(over="ignore", invalid="ignore"):
        si = v * factor * spec.sign * spec.scale
    over = np.flatnonzero(np.isinf(si) & np.isfinite(v))
    if len(over):
        raise TableError(f"{where}: message {int(over[0]) + 1} (in stamp order): {float(v[over[0]])!r} times "
                         f"{factor * spec.scale:g} (its unit and scale to SI) is beyond a float's range")
    v = si
    if not origin:
        origin.append(int(t_ns[0]))
    seconds = (t_ns - origin[0]).astype(np.float64) * 1e-9
    gravity = default[2] if default is not None and column.unit == "m/s^2" else None
    return Series(column.name, f"topic {spec.topic} ({msgtype.split('/')[-1]}.{fp if spec.joint else fieldpath})",
                  seconds, v, unit, unit_from, gravity=gravity)

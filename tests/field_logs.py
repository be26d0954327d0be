"""One drive written the ways field logs arrive (the tests' and the bench's helper): vehid's CSV,
ROS 2 bags (MCAP and sqlite3) with IMUs at 400 Hz and a JointState at 100 Hz, a data logger's
CSV (ms, g, mm at 500 Hz, the deflection late) and Parquet with timestamps."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np
from numpy.typing import NDArray
from scipy import signal

import vehid

#: The drive's rate, s (the IMUs' rate).
DT = 0.0025
#: Seconds since 1970 at the drive's start (the bags' and the Parquet file's clock).
EPOCH = 1_795_000_000.0
G = 9.80665


def drive(seconds: float, changes: Sequence[Tuple[float, Dict[str, float]]] = (), seed: int = 1,
          road: str = "iso8608-C", noise: Optional[Dict[str, float]] = None) -> vehid.Run:
    """A passenger car's drive at 400 Hz with the realistic sensors."""
    sim = vehid.Simulator(vehid.QuarterCar.passenger(), dt=DT, road=road, speed=15.0, changes=list(changes),
                          sensors="realistic", seed=seed, sensor_noise=noise)
    return sim.run(int(round(seconds / DT)))


def delayed(x: NDArray[np.float64], seconds: float, dt: float) -> NDArray[np.float64]:
    """``x`` (at interval ``dt``) as a sensor ``seconds`` late reads it: ``x(t - seconds)``,
    by band-limited (FFT) interpolation, so the shift is exact for any fraction of a sample."""
    n = len(x)
    f = np.fft.rfftfreq(2 * n, dt)
    spec = np.fft.rfft(np.concatenate([x, x[::-1]]))  # mirrored: no wrap-around jump
    return np.asarray(np.fft.irfft(spec * np.exp(-2j * np.pi * f * seconds), 2 * n)[:n], dtype=np.float64)


def vehid_csv(path: Path, run: vehid.Run) -> Path:
    """vehid's own CSV at 200 Hz (scipy's polyphase resampler from the 400 Hz drive)."""
    y = signal.resample_poly(run.y, 1, 2, axis=0)
    t = np.arange(len(y)) * 2 * DT
    np.savetxt(path, np.column_stack([t, y]), delimiter=",", header="t,a_body,a_wheel,deflection", comments="",
               fmt="%.9g")
    return path


def logger_csv(path: Path, run: vehid.Run, late: float = 0.004, compression: bool = False,
               body_late: float = 0.0) -> Path:
    """A data logger's CSV at 500 Hz: ``Time [ms]``, accelerations in g with gravity, the
    deflection in mm ``late`` s late (and compression-positive when asked), the body
    accelerometer ``body_late`` s late."""
    y = signal.resample_poly(run.y, 5, 4, axis=0)
    dt = 0.002
    d = delayed(y[:, 2], late, dt) * (-1.0 if compression else 1.0)
    body = delayed(y[:, 0], body_late, dt) if body_late else y[:, 0]
    t_ms = np.arange(len(y)) * 2.0
    data = np.column_stack([t_ms, body / G + 1.0, y[:, 1] / G + 1.0, d * 1e3])
    np.savetxt(path, data, delimiter=",", header="Time [ms],AccZ_body [g],AccZ_wheel [g],SuspTravel [mm]",
               comments="", fmt=["%.0f", "%.7f", "%.7f", "%.5f"])
    return path


LOGGER_MAP = """\
[time]
column = "Time [ms]"

[a_body]
column = "AccZ_body [g]"

[a_wheel]
column = "AccZ_wheel [g]"

[deflection]
column = "SuspTravel [mm]"
"""


def bag(path: Path, run: vehid.Run, storage: str = "mcap", joint_every: int = 4,
        imu_type: str = "sensor_msgs/msg/Imu", samples: Optional[slice] = None, antialias: bool = False,
        joint_scale: float = 1.0) -> Path:
    """A ROS 2 bag (``storage`` "mcap" or "sqlite3"; "ros1": a ROS 1 ``.bag`` file at
    ``path``, rosbags' ROS 1 writer): ``/body/imu`` and ``/wheel/imu`` (Imu at 400 Hz, z up,
    gravity included, header stamps; logged 1-4 ms later), ``/suspension/joint_states``
    (JointState at 400/``joint_every`` Hz, joint ``susp_fl``: the deflection, m); of the drive's
    ``samples`` (default all). The JointState samples the 400 Hz deflection as a publisher
    does, without a filter; ``antialias``: low-passed first (scipy's ``firwin``, 201 taps, cut-off
    0.4 of the JointState's rate, applied forward and back: zero phase); ``joint_scale``: the
    joint is revolute, its position the angle ``deflection / joint_scale`` (rad; the travel is
    ``joint_scale`` m per rad)."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ros1 = storage == "ros1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    T = ts.types
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    rng = np.random.default_rng(5)
    zero9 = np.zeros(9)
    serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    extra: Dict[str, Any] = {"seq": 0} if ros1 else {}

    def header(t: float) -> Any:
        ns = int(round(t * 1e9))
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9,
                                                                                nanosec=ns % 10**9),
                                        frame_id="imu", **extra)

    def imu(t: float, a: float) -> Any:
        v3 = T["geometry_msgs/msg/Vector3"]
        if imu_type != "sensor_msgs/msg/Imu":
            return T[imu_type](header=header(t), vector=v3(x=0.0, y=0.0, z=a + G))
        return T["sensor_msgs/msg/Imu"](
            header=header(t), orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=zero9, angular_velocity=v3(x=0.0, y=0.0, z=0.0),
            angular_velocity_covariance=zero9, linear_acceleration=v3(x=0.0, y=0.0, z=a + G),
            linear_acceleration_covariance=zero9)

    deflection = np.asarray(run.y[:, 2], dtype=np.float64)
    if antialias and joint_every > 1:
        deflection = signal.filtfilt(signal.firwin(201, 0.4 / (joint_every * DT), fs=1 / DT), [1.0], deflection)
    writer = Writer1(path) if ros1 else Writer(path, version=9, storage_plugin=plugin)
    with writer as w:
        body = w.add_connection("/body/imu", imu_type, typestore=ts)
        wheel = w.add_connection("/wheel/imu", imu_type, typestore=ts)
        joints = w.add_connection("/suspension/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
        for k in range(len(run))[samples or slice(None)]:
            t = EPOCH + k * DT
            lag = int(rng.integers(1_000_000, 4_000_000))
            logged = int(round(t * 1e9)) + lag
            w.write(body, logged, serialize(imu(t, float(run.y[k, 0])), imu_type))
            w.write(wheel, logged, serialize(imu(t, float(run.y[k, 1])), imu_type))
            if k % joint_every == 0:
                msg = T["sensor_msgs/msg/JointState"](header=header(t), name=["susp_fl"],
                                                      position=np.array([deflection[k] / joint_scale]),
                                                      velocity=np.zeros(0),
                                                      effort=np.zeros(0))
                w.write(joints, logged, serialize(msg, "sensor_msgs/msg/JointState"))
    return path


def split_bag(path: Path, run: vehid.Run, parts: int = 2) -> Path:
    """A rosbag2 MCAP bag split into ``parts`` storage files, as ``ros2 bag record
    --max-bag-duration`` leaves it: the folder ``path`` with ``path_0.mcap``, ``path_1.mcap``,
    ... and one ``metadata.yaml`` listing them in order (each part written by rosbags' writer,
    the metadata merged here)."""
    import shutil

    import yaml

    path.mkdir()
    edges = np.linspace(0, len(run), parts + 1).astype(int)
    metas = []
    for i in range(parts):
        part = bag(path.parent / f"{path.name}.part{i}", run, samples=slice(int(edges[i]), int(edges[i + 1])))
        shutil.move(str(next(part.glob("*.mcap"))), str(path / f"{path.name}_{i}.mcap"))
        metas.append(yaml.safe_load((part / "metadata.yaml").read_text())["rosbag2_bagfile_information"])
        shutil.rmtree(part)
    info = metas[0]
    info["relative_file_paths"] = [f"{path.name}_{i}.mcap" for i in range(parts)]
    info["files"] = [dict(m["files"][0], path=f"{path.name}_{i}.mcap") for i, m in enumerate(metas)]
    start = info["starting_time"]["nanoseconds_since_epoch"]
    end = max(m["starting_time"]["nanoseconds_since_epoch"] + m["duration"]["nanoseconds"] for m in metas)
    info["duration"]["nanoseconds"] = end - start
    info["message_count"] = sum(m["message_count"] for m in metas)
    for j, topic in enumerate(info["topics_with_message_count"]):
        topic["message_count"] = sum(m["topics_with_message_count"][j]["message_count"] for m in metas)
    (path / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False))
    return path


BAG_MAP = """\
[a_body]
topic = "/body/imu"
field = "linear_acceleration.z"
gravity = "included"

[a_wheel]
topic = "/wheel/imu"

[deflection]
topic = "/suspension/joint_states"
joint = "susp_fl"
unit = "m"
"""


def parquet(path: Path, run: vehid.Run) -> Path:
    """Parquet at 400 Hz: a ``timestamp`` column (ns, UTC) and the channels, the deflection in
    mm declared in its field metadata."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    stamps = (np.int64(int(EPOCH)) * 10**9 + np.arange(len(run)) * int(DT * 1e9)).astype("datetime64[ns]")
    schema = pa.schema([pa.field("timestamp", pa.timestamp("ns", tz="UTC")),
                        pa.field("a_body", pa.float64(), metadata={"unit": "m/s^2"}),
                        pa.field("a_wheel", pa.float64(), metadata={"unit": "m/s^2"}),
                        pa.field("deflection", pa.float64(), metadata={"unit": "mm"})])
    table = pa.table([pa.array(stamps, pa.timestamp("ns", tz="UTC")), run.y[:, 0], run.y[:, 1], run.y[:, 2] * 1e3],
                     schema=schema)
    pq.write_table(table, path)
    return path

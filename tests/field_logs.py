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
        imu_type: str = "sensor_msgs/msg/Imu") -> Path:
    """A ROS 2 bag: ``/body/imu`` and ``/wheel/imu`` (Imu at 400 Hz, z up, gravity included,
    header stamps; logged 1-4 ms later), ``/suspension/joint_states`` (JointState at
    400/``joint_every`` Hz, joint ``susp_fl``: the deflection, m)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    rng = np.random.default_rng(5)
    zero9 = np.zeros(9)

    def header(t: float) -> Any:
        ns = int(round(t * 1e9))
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9,
                                                                                nanosec=ns % 10**9),
                                        frame_id="imu")

    def imu(t: float, a: float) -> Any:
        v3 = T["geometry_msgs/msg/Vector3"]
        if imu_type != "sensor_msgs/msg/Imu":
            return T[imu_type](header=header(t), vector=v3(x=0.0, y=0.0, z=a + G))
        return T["sensor_msgs/msg/Imu"](
            header=header(t), orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=zero9, angular_velocity=v3(x=0.0, y=0.0, z=0.0),
            angular_velocity_covariance=zero9, linear_acceleration=v3(x=0.0, y=0.0, z=a + G),
            linear_acceleration_covariance=zero9)

    with Writer(path, version=9, storage_plugin=plugin) as w:
        body = w.add_connection("/body/imu", imu_type, typestore=ts)
        wheel = w.add_connection("/wheel/imu", imu_type, typestore=ts)
        joints = w.add_connection("/suspension/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
        for k in range(len(run)):
            t = EPOCH + k * DT
            lag = int(rng.integers(1_000_000, 4_000_000))
            logged = int(round(t * 1e9)) + lag
            w.write(body, logged, ts.serialize_cdr(imu(t, float(run.y[k, 0])), imu_type))
            w.write(wheel, logged, ts.serialize_cdr(imu(t, float(run.y[k, 1])), imu_type))
            if k % joint_every == 0:
                msg = T["sensor_msgs/msg/JointState"](header=header(t), name=["susp_fl"],
                                                      position=np.array([run.y[k, 2]]), velocity=np.zeros(0),
                                                      effort=np.zeros(0))
                w.write(joints, logged, ts.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
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

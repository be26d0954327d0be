"""A car's sensor channels as vehid reads them from a field log, and what each sensor set
holds: the types :mod:`vehid.fieldlog` (tables) and :mod:`vehid.bags` (ROS 2 bags, MCAP) both
build, and the channel lists ``vehid monitor``, ``vehid inspect`` and ``vehid identify
--sensors realistic`` read.

>>> [c.name for c in SENSOR_COLUMNS["realistic"]]
['a_body', 'a_wheel', 'deflection']
>>> unit_of(None, "mm", Column("deflection", "susp_defl", "m"), "column 'deflection'")
(0.001, 'mm', 'declared')
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np
from numpy.typing import NDArray

from .io import Column, TableError, quantity_of, si_factor

#: A clock that jumps back, or forward by more than this (s), is refused.
MAX_JUMP = 3600.0

#: The channels of each sensor set, with an alias and the unit.
SENSOR_COLUMNS: Dict[str, Tuple[Column, ...]] = {
    "realistic": (
        Column("a_body", "body_acc", "m/s^2"),
        Column("a_wheel", "wheel_acc", "m/s^2"),
        Column("deflection", "susp_defl", "m"),
    ),
    "state": tuple(
        Column(name, None, unit)
        for name, unit in zip(
            ("zw", "vw", "zb", "vb", "dzw", "dvw", "dzb", "dvb"),
            ("m", "m/s", "m", "m/s", "m/s", "m/s^2", "m/s", "m/s^2"),
        )
    ),
}

#: The half car's channels (``--model half``).
HALF_SENSOR_COLUMNS: Dict[str, Tuple[Column, ...]] = {
    "realistic": (
        Column("a_body_f", None, "m/s^2"),
        Column("a_body_r", None, "m/s^2"),
        Column("a_wheel_f", None, "m/s^2"),
        Column("a_wheel_r", None, "m/s^2"),
        Column("deflection_f", None, "m"),
        Column("deflection_r", None, "m"),
    ),
    "state": tuple(
        Column(name, None, unit)
        for name, unit in zip(
            ("z1", "v1", "z2", "v2", "zb", "vb", "ph", "om", "dz1", "dv1", "dz2", "dv2", "dzb", "dvb", "dph", "dom"),
            ("m", "m/s", "m", "m/s", "m", "m/s", "rad", "rad/s", "m/s", "m/s^2", "m/s", "m/s^2", "m/s", "m/s^2",
             "rad/s", "rad/s^2"),
        )
    ),
}

_FULL_STATES = (("z_fl", "m"), ("v_fl", "m/s"), ("z_fr", "m"), ("v_fr", "m/s"), ("z_rl", "m"), ("v_rl", "m/s"),
                ("z_rr", "m"), ("v_rr", "m/s"), ("zb", "m"), ("vb", "m/s"), ("pitch", "rad"), ("pitch_rate", "rad/s"),
                ("roll", "rad"), ("roll_rate", "rad/s"))

#: The full car's channels (``--model full``): a body accelerometer above each wheel, the wheel
#: accelerometers, the suspension extensions, corners fl, fr, rl, rr; or the 28 state channels.
FULL_SENSOR_COLUMNS: Dict[str, Tuple[Column, ...]] = {
    "realistic": tuple(
        [Column(f"a_body_{c}", None, "m/s^2") for c in ("fl", "fr", "rl", "rr")]
        + [Column(f"a_wheel_{c}", None, "m/s^2") for c in ("fl", "fr", "rl", "rr")]
        + [Column(f"deflection_{c}", None, "m") for c in ("fl", "fr", "rl", "rr")]
    ),
    "state": tuple([Column(name, None, unit) for name, unit in _FULL_STATES]
                   + [Column(f"d{name}", None, unit[:-2] + "/s^2" if unit.endswith("/s") else unit + "/s")
                      for name, unit in _FULL_STATES]),
}


#: How far from the centre line (m) a load counts as on one side (:func:`event_corner`).
SIDE = 0.2


def event_corner(parameter: str, position: Optional[Tuple[float, float]] = None) -> Optional[str]:
    """The corner (``"fl"`` .. ``"rr"``) or axle (``"f"``, ``"r"``) an event names: its
    constant's suffix, or for a point load (``position``, m forward and to the left of the centre
    of mass) the corner it was set down toward (the axle when within :data:`SIDE` of the centre
    line); ``None`` otherwise.

    >>> event_corner("b_fl"), event_corner("k2_r"), event_corner("M"), event_corner("M", (-2.5, 0.05))
    ('fl', 'r', None, 'r')
    >>> event_corner("M", (0.4, -0.5))
    'fr'
    """
    if position is not None:
        axle = "f" if position[0] >= 0 else "r"
        side = "" if abs(position[1]) < SIDE else ("l" if position[1] > 0 else "r")
        return axle + side
    return parameter.split("_", 1)[1] if "_" in parameter else None


@dataclass
class ChannelSpec:
    """Where one vehid channel comes from (a section of ``channels.toml``)."""

    channel: str
    topic: Optional[str] = None
    column: Optional[str] = None
    field: Optional[str] = None
    #: JointState: the joint's name (else ``position[0]`` or ``field = "position[i]"``).
    joint: Optional[str] = None
    unit: Optional[str] = None
    #: Accelerations: ``"included"`` (specific force, REP 145) or ``"removed"``; ``None``: as
    #: the message type says (Imu: included), else detected from the mean.
    gravity: Optional[str] = None
    sign: float = 1.0
    sign_given: bool = False
    scale: float = 1.0
    scale_given: bool = False
    #: A known delay of this channel against the others, s (then none is estimated).
    delay: Optional[float] = None


@dataclass
class ChannelMap:
    """A ``channels.toml``: the channels, the time column (tables) and which stamp (bags)."""

    path: str
    channels: Dict[str, ChannelSpec]
    time_column: Optional[str] = None
    time_unit: Optional[str] = None
    #: Bags: ``"header"`` (``header.stamp``, default) or ``"log"`` (the time the message was logged).
    stamp: str = "header"


@dataclass
class Series:
    """One channel as read: times ``t`` (s; since 1970 where the log has absolute times) and
    values ``v`` (SI; NaN missing), with where they came from and in which unit."""

    channel: str
    source: str
    t: NDArray[np.float64]
    v: NDArray[np.float64]
    unit: str
    unit_from: str
    #: Table rows (line numbers) of the samples, for messages; ``None`` for bags.
    lines: Optional[NDArray[np.int64]] = None
    #: Whether gravity was removed from this channel (accelerations).
    gravity_removed: bool = False
    #: What the message type says of gravity (an IMU: ``"included"``, REP 145), if anything.
    gravity: Optional[str] = None


@dataclass
class Log:
    """A log's channels: ``series`` in the order asked for; ``absolute``: the times are
    seconds from ``origin`` (s since 1970; timestamps, bags), else as the log writes them."""

    source: str
    kind: str
    series: List[Series]
    absolute: bool
    notes: List[str] = field(default_factory=list)
    origin: float = 0.0


def unit_of(spec: Optional[ChannelSpec], declared: Optional[str], column: Column, where: str) -> Tuple[float, str, str]:
    """``(factor to SI, unit, where the unit came from)`` of a channel: the map's unit, else the
    one declared (``declared``), else SI."""
    quantity = quantity_of(column.unit)
    if spec is not None and spec.unit:
        unit, source = spec.unit, "channel map"
    elif declared:
        unit, source = declared, "declared"
    else:
        return 1.0, column.unit, "none declared: SI taken"
    if not quantity:
        if unit.strip() != column.unit:
            raise TableError(f"{where}: unit {unit!r}: vehid reads this channel only in {column.unit}")
        return 1.0, unit, source
    angle = ANGLE_UNITS.get(unit.strip().lower())
    if angle is not None and quantity == "length":  # a revolute joint's angle for a travel
        if spec is None or not spec.scale_given:
            raise TableError(f"{where}: unit {unit!r} is an angle (a revolute joint?), but {column.name} is the "
                             "suspension's travel (m): give scale = R in its channel map section, the wheel's travel "
                             "per radian of the joint in m (the arm's length times its motion ratio: read as R x the "
                             "angle, linear), or log the travel itself (a prismatic joint, m)")
        return angle, f"{unit} x {spec.scale:g} m/rad", source
    return si_factor(unit, quantity, where), unit, source


#: The angles a deflection may be given in (with ``scale``, m of travel per rad): rad per unit.
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180}

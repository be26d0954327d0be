"""A simulated fleet in the fleet layout, with injected faults and ``truth.parquet`` listing
them: for tests, demos and benchmarks.

Every vehicle draws from its own random stream (``seed`` and its index), so vehicle ``i`` is the
same in a fleet of 10 and of 10,000. The mix: four in five vehicles are quarter cars of three
classes (compact, sedan, SUV), one in five a passenger half car; each vehicle's constants are
its class's within ±3 %. Each day it drives ``hours`` on an ISO 8608 road of class B, C or D
at 8–25 m/s, leaving between 07:00 and 09:00; a drive of 20 minutes or more is two trips with
a 10–40 minute stop between them; each trip is written as files of at most 30 minutes, named
by their start time (``t`` as float64, the channels as float32, plain encoding, LZ4). A
faulty vehicle (``faults`` of the fleet, rounded) has one change on one
of its days, at least 60 s into that day's driving and 60 s before its end: a damper
−15 to −40 %, a spring −10 to −25 % or (quarter cars) a body mass +15 to +35 %; it stays after.
"""

from __future__ import annotations

import datetime
import math
import os
import threading
from typing import Any, Callable, Dict, List, Literal, Optional, Tuple

import numpy as np

from .._vehid import HalfCar, QuarterCar, Simulator
from ._deps import module

#: The quarter-car classes: (M kg, k2 N/m, b N s/m); the wheel and tyre as the passenger car.
CLASSES: Dict[str, Tuple[float, float, float]] = {
    "compact": (260.0, 19000.0, 1250.0), "sedan": (320.0, 22000.0, 1500.0), "suv": (420.0, 30000.0, 2100.0)}
#: A half car's monitor names -> its HalfCar constants.
HALF_NAMES = {"b_f": "b1", "b_r": "b2", "k2_f": "k12", "k2_r": "k22", "M": "M"}
#: Longest file, s.
FILE_SECONDS = 1800.0
ROADS: Tuple[Literal["iso8608-B", "iso8608-C", "iso8608-D"], ...] = ("iso8608-B", "iso8608-C", "iso8608-D")


def _vehicle_plan(seed: int, i: int, faulty: bool, days: int, hours: float) -> Dict[str, Any]:
    rng = np.random.default_rng([seed, i])
    half = bool(rng.random() < 0.2)
    if half:
        base = dict(HalfCar.passenger().params)
        names: Tuple[str, ...] = ("M", "k12", "k22", "b1", "b2")
        cls = "half"
    else:
        cls = ("compact", "sedan", "suv")[int(rng.integers(0, 3))]
        m, k2, b = CLASSES[cls]
        base = {"M": m, "k2": k2, "b": b}
        names = ("M", "k2", "b")
    constants = {n: float(f"{base[n] * (1 + rng.uniform(-0.03, 0.03)):.5g}") for n in names}
    fault = None
    if faulty:
        param = str(rng.choice(["b_f", "b_r", "k2_f", "k2_r"] if half else ["b", "k2", "M"]))
        kind = param.split("_")[0]
        factor = {"b": rng.uniform(0.6, 0.85), "k2": rng.uniform(0.75, 0.9), "M": rng.uniform(1.15, 1.35)}[kind]
        day = int(rng.integers(0, days))
        at = float(rng.uniform(60.0, hours * 3600.0 - 60.0))
        fault = (day, at, param, float(factor))
    return {"half": half, "class": cls, "constants": constants, "fault": fault,
            "seeds": [int(s) for s in rng.integers(1, 2**62, size=days)], "rng": rng}


def _car(plan: Dict[str, Any], constants: Dict[str, float]) -> Any:
    if plan["half"]:
        p = dict(HalfCar.passenger().params)
        p.update(constants)
        return HalfCar(**p)
    p = dict(QuarterCar.passenger().params)
    p.update(constants)
    return QuarterCar(**p)


def _fleet_toml(plans: List[Tuple[str, Dict[str, Any]]], dt: float) -> str:
    out = ["# A simulated fleet (vehid fleet simulate): each vehicle's class and nominal constants.",
           "[defaults]", 'model = "passenger"', 'sensors = "realistic"', f"dt = {dt!r}", ""]
    for cls, (m, k2, b) in CLASSES.items():
        out += [f"[classes.{cls}]", 'model = "passenger"', f"constants = {{ M = {m!r}, k2 = {k2!r}, b = {b!r} }}", ""]
    out += ["[classes.half]", 'model = "half"', ""]
    for vid, plan in plans:
        cs = ", ".join(f"{k} = {v!r}" for k, v in plan["constants"].items())
        out += [f"[vehicles.{vid}]", f'class = "{plan["class"]}"', f"constants = {{ {cs} }}", ""]
    return "\n".join(out)


def simulate(directory: str, vehicles: int, days: int, hours: float, faults: float, seed: int = 1, *,
             start: str = "2026-01-05", dt: float = 0.005, first: int = 0, total: Optional[int] = None,
             workers: int = 1, progress: Optional[Callable[[int, int], None]] = None) -> Any:
    """Writes a simulated fleet into ``directory``: ``vehicles`` vehicles × ``days`` days ×
    ``hours`` hours of driving a day (sampled every ``dt`` s), ``faults`` (0..1) of the
    vehicles with one injected fault, from ``seed``; the first day is ``start``
    (YYYY-MM-DD). Writes ``fleet.toml``, the logs and ``truth.parquet`` (vehicle, day, t (s
    from the day's start), parameter, before, after), and returns the truth table.

    ``first`` and ``total`` write vehicles ``first .. first + vehicles - 1`` of a fleet of
    ``total`` (default: ``first + vehicles``): a large fleet in parts, the same vehicles as in
    one go. ``workers`` threads simulate vehicles side by side (the result does not depend
    on it). ``progress(done, total)`` is called after each vehicle. ``ValueError`` names a
    bad argument."""
    pa = module("pyarrow")
    pq = module("pyarrow.parquet")

    if not isinstance(vehicles, int) or vehicles < 1:
        raise ValueError(f"--vehicles {vehicles}: expected a number of vehicles >= 1")
    if not isinstance(days, int) or days < 1:
        raise ValueError(f"--days {days}: expected a number of days >= 1")
    if not (math.isfinite(hours) and hours > 0):
        raise ValueError(f"--hours {hours}: expected the hours of driving per day, > 0 (e.g. 1 or 0.05)")
    if not (0.0 <= faults <= 1.0):
        raise ValueError(f"--faults {faults}: expected the fraction of vehicles with a fault, 0..1 (e.g. 0.2)")
    if faults > 0 and hours * 3600 < 180:
        raise ValueError(f"--hours {hours}: a fault needs at least 3 minutes of driving a day (--hours 0.05), "
                         "or give --faults 0")
    if not (math.isfinite(dt) and 0 < dt <= 0.1):
        raise ValueError(f"dt={dt}: expected a sample interval in seconds, 0 < dt <= 0.1")
    try:
        day0 = datetime.date.fromisoformat(start)
    except ValueError:
        raise ValueError(f"start={start!r}: expected a day YYYY-MM-DD") from None
    if os.path.exists(directory) and not os.path.isdir(directory):
        raise ValueError(f"{directory}: is a file; give a directory for the fleet")
    if os.path.isdir(directory) and os.listdir(directory):
        raise ValueError(f"{directory}: not empty; give a new or empty directory (a simulation never overwrites)")
    total = first + vehicles if total is None else total
    if first < 0 or total < first + vehicles:
        raise ValueError(f"first={first}, total={total}: expected 0 <= first and first + vehicles <= total")
    os.makedirs(directory, exist_ok=True)
    n_faulty = int(round(faults * total))
    faulty = set(np.random.default_rng([seed, 2**31]).permutation(total)[:n_faulty].tolist())
    width = max(5, len(str(total - 1)))
    plans = [(f"v{i:0{width}d}", _vehicle_plan(seed, i, i in faulty, days, hours))
             for i in range(first, first + vehicles)]
    with open(os.path.join(directory, "fleet.toml"), "w", encoding="utf-8") as f:
        f.write(_fleet_toml(plans, dt))
    rows: List[List[Tuple[Any, ...]]] = [[] for _ in plans]
    done = [0]
    lock = threading.Lock()

    def one(k: int) -> None:
        rows[k] = _drive(directory, plans[k][0], plans[k][1], days, hours, dt, day0)
        with lock:
            done[0] += 1
            if progress is not None:
                progress(done[0], len(plans))

    if workers > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(one, range(len(plans))))
    else:
        for k in range(len(plans)):
            one(k)
    truth: Dict[str, List[Any]] = {k: [] for k in ("vehicle", "day", "t", "parameter", "before", "after")}
    for vrows in rows:
        for r in vrows:
            for col, v in zip(truth, r):
                truth[col].append(v)
    types = {"vehicle": pa.string(), "day": pa.string(), "t": pa.float64(), "parameter": pa.string(),
             "before": pa.float64(), "after": pa.float64()}
    table = pa.table({k: pa.array(v, types[k]) for k, v in truth.items()})
    pq.write_table(table, os.path.join(directory, "truth.parquet"))
    return table


def _drive(directory: str, vid: str, plan: Dict[str, Any], days: int, hours: float, dt: float,
           day0: datetime.date) -> List[Tuple[Any, ...]]:
    """Simulates and writes one vehicle's days; its truth rows."""
    pa = module("pyarrow")
    pq = module("pyarrow.parquet")
    truth: List[Tuple[Any, ...]] = []
    n = int(round(hours * 3600.0 / dt))
    rng = plan["rng"]
    constants = dict(plan["constants"])
    for d in range(days):
        day = (day0 + datetime.timedelta(days=d)).isoformat()
        road = ROADS[int(rng.choice(3, p=[0.3, 0.5, 0.2]))]
        speed = float(rng.uniform(8.0, 25.0))
        depart = float(np.round(rng.uniform(7 * 3600, 9 * 3600) / dt) * dt)
        trips = [n] if n * dt < 1200 else [n // 2, n - n // 2]
        pause = float(np.round(rng.uniform(600, 2400) / dt) * dt)
        changes: List[Tuple[float, Dict[str, float]]] = []
        changed: Optional[Tuple[str, float]] = None
        fault = plan["fault"]
        if fault is not None and fault[0] == d:
            _, at, param, factor = fault
            at = float(np.round(at / dt) * dt)
            name = HALF_NAMES[param] if plan["half"] else param
            before = constants[name]
            after = float(f"{before * factor:.5g}")
            changes = [(at, {param: after})]
            changed = (name, after)
            t_day = depart + at + (pause if len(trips) == 2 and at >= trips[0] * dt else 0.0)
            truth.append((vid, day, t_day, param, before, after))
        sim = Simulator(_car(plan, constants), dt=dt, road=road, speed=speed, changes=changes,
                        sensors="realistic", seed=plan["seeds"][d])
        vdir = os.path.join(directory, f"vehicle={vid}", f"day={day}")
        os.makedirs(vdir, exist_ok=True)
        t0 = depart
        for j, count in enumerate(trips):
            if j == 1:
                t0 += pause
            per_file = int(round(FILE_SECONDS / dt))
            for s in range(0, count, per_file):
                m = min(per_file, count - s)
                r = sim.run(m)
                t = t0 + (np.arange(m) + s) * dt
                cols: Dict[str, Any] = {"t": pa.array(t, pa.float64())}
                for c, name in enumerate(r.channels):
                    cols[name] = pa.array(r.y[:, c].astype(np.float32))
                start_t = float(t[0])
                hh, rest = divmod(int(start_t), 3600)
                fname = f"{hh:02d}-{rest // 60:02d}-{rest % 60:02d}.parquet"
                # Sensor noise gains nothing from dictionary encoding and reads twice as fast without.
                pq.write_table(pa.table(cols), os.path.join(vdir, fname), use_dictionary=False, compression="lz4")
            t0 += count * dt
        if changed is not None:  # the fault stays
            constants[changed[0]] = changed[1]
    return truth

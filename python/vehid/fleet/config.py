"""The fleet file ``fleet.toml``: each vehicle's car model, nominal constants, sensors, sample
interval, monitor settings and column names.

Schema (every table optional but ``[defaults]`` or ``[vehicles.<id>]`` for each vehicle)::

    [defaults]                      # every vehicle, unless its class or its own entry says otherwise
    model = "passenger"             # quarter (the thesis' car) | passenger | half | full (passenger half, full car)
    sensors = "realistic"           # realistic (a_body, a_wheel, deflection) | state
    dt = 0.005                      # sample interval, s (200 Hz)
    constants = { b = 1500.0 }      # the nominal car's constants (the model's names and SI units)
    monitor = { warmup = 20.0 }     # HealthMonitor settings (window, warmup, min_change, threshold, ...)
    columns = { a_body = "AccZ" }   # channel = the Parquet column holding it (default: vehid's names)

    [classes.van]                   # a class of vehicles: the same keys
    constants = { M = 600.0, k2 = 40000.0 }

    [vehicles.v0001]                # one vehicle: the same keys, and its class
    class = "van"
    constants = { b = 2800.0 }

A vehicle's settings are its defaults, overridden by its class, overridden by its own entry
(``constants``, ``monitor`` and ``columns`` key by key). A vehicle of the dataset with no
entry takes ``[defaults]``; without ``[defaults]`` it is reported as a problem, not guessed.
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
from dataclasses import dataclass
from typing import Any, Dict, Mapping, Optional, Tuple, Union

from .._vehid import FullCar, HalfCar, HealthMonitor, QuarterCar

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python < 3.11 only
    import tomli as tomllib

#: The car models a vehicle may have.
MODELS = ("quarter", "passenger", "half", "full")
#: The HealthMonitor settings ``monitor = {...}`` may give (seconds, fractions, counts).
MONITOR_SETTINGS = ("window", "warmup", "settle", "reacquire", "min_change", "judge_error", "threshold",
                    "confidence", "systematic", "stuck_samples")
_KEYS = ("model", "sensors", "dt", "constants", "monitor", "columns", "class")


class ConfigError(ValueError):
    """``fleet.toml`` is not valid: the message names the table, the key and the fix."""


@dataclass(frozen=True)
class VehicleConfig:
    """One vehicle's resolved settings (plain values: it pickles, for the Dask engine)."""

    #: ``quarter``, ``passenger``, ``half`` or ``full``.
    model: str = "passenger"
    #: ``realistic`` or ``state``.
    sensors: str = "realistic"
    #: Sample interval, s.
    dt: float = 0.005
    #: The nominal car's constants that differ from the model's (name, value in SI units).
    constants: Tuple[Tuple[str, float], ...] = ()
    #: HealthMonitor settings (name, value).
    monitor: Tuple[Tuple[str, float], ...] = ()
    #: Channel -> Parquet column name.
    columns: Tuple[Tuple[str, str], ...] = ()

    @property
    def half(self) -> bool:
        """True for the half car (six channels), False for the quarter car (three)."""
        return self.model == "half"

    @property
    def full(self) -> bool:
        """True for the full car (twelve channels, or 28 state channels)."""
        return self.model == "full"

    def car(self) -> Union[QuarterCar, HalfCar, FullCar]:
        """The nominal car: the model with ``constants`` applied."""
        if self.model == "full":
            params = dict(FullCar.passenger().params)
            params.update(self.constants)
            return FullCar(**params)
        if self.model == "half":
            params = dict(HalfCar.passenger().params)
            params.update(self.constants)
            return HalfCar(**params)
        params = dict((QuarterCar.passenger() if self.model == "passenger" else QuarterCar()).params)
        params.update(self.constants)
        return QuarterCar(**params)

    def monitor_new(self) -> HealthMonitor:
        """A fresh HealthMonitor of this vehicle (no data seen yet)."""
        settings: Dict[str, Any] = {k: (int(v) if k == "stuck_samples" else v) for k, v in self.monitor}
        return HealthMonitor(self.car(), dt=self.dt, sensors=self.sensors,  # type: ignore[arg-type]
                             **settings)

    def fingerprint(self) -> str:
        """A short stable hash of these settings: the store notes it with every day, so that a
        changed ``fleet.toml`` is noticed rather than silently mixed into a vehicle's chain."""
        text = json.dumps([self.model, self.sensors, self.dt, self.constants, self.monitor, self.columns])
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class FleetConfig:
    """``fleet.toml`` read: its defaults (None: no ``[defaults]``), classes and vehicles."""

    defaults: Optional[Dict[str, Any]]
    classes: Dict[str, Dict[str, Any]]
    vehicles: Dict[str, Dict[str, Any]]
    source: str = "fleet.toml"

    def vehicle(self, vid: str) -> VehicleConfig:
        """The resolved settings of vehicle ``vid``; :class:`ConfigError` if it has none or
        they are invalid."""
        entry = self.vehicles.get(vid)
        if entry is None and self.defaults is None:
            raise ConfigError(f"{self.source}: vehicle {vid!r} has no [vehicles.{vid}] entry and there is no "
                              "[defaults] table: add either")
        where = f"[vehicles.{vid}]" if entry is not None else "[defaults]"
        layers = [self.defaults or {}]
        cls = (entry or {}).get("class")
        if cls is not None:
            if cls not in self.classes:
                raise ConfigError(f"{self.source}: {where} class = {cls!r}: no [classes.{cls}] table "
                                  f"(classes: {', '.join(sorted(self.classes)) or 'none'})")
            layers.append(self.classes[cls])
        layers.append(entry or {})
        merged: Dict[str, Any] = {"constants": {}, "monitor": {}, "columns": {}}
        for layer in layers:
            for key, value in layer.items():
                if key in ("constants", "monitor", "columns"):
                    merged[key].update(value)
                elif key != "class":
                    merged[key] = value
        return _resolve(merged, f"{self.source}: {where}")


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"{what} = {value!r}: expected a finite number")
    return float(value)


def _resolve(d: Dict[str, Any], where: str) -> VehicleConfig:
    model = d.get("model", "passenger")
    if model not in MODELS:
        raise ConfigError(f"{where} model = {model!r}: choose {', '.join(MODELS)}")
    sensors = d.get("sensors", "realistic")
    if sensors not in ("realistic", "state"):
        raise ConfigError(f"{where} sensors = {sensors!r}: choose realistic or state")
    dt = _number(d.get("dt", 0.005), f"{where} dt")
    if dt <= 0:
        raise ConfigError(f"{where} dt = {dt!r}: the sample interval must be > 0 s (e.g. 0.005 for 200 Hz)")
    nominal: Union[QuarterCar, HalfCar, FullCar] = (
        FullCar.passenger() if model == "full" else HalfCar.passenger() if model == "half" else QuarterCar.passenger())
    known = nominal.params
    constants = []
    for name, value in sorted(d["constants"].items()):
        if name not in known:
            raise ConfigError(f"{where} constants: {name!r} is not a constant of the {model} car "
                              f"({', '.join(known)})")
        constants.append((name, _number(value, f"{where} constants.{name}")))
    monitor = []
    for name, value in sorted(d["monitor"].items()):
        if name not in MONITOR_SETTINGS:
            raise ConfigError(f"{where} monitor: {name!r} is not a monitor setting ({', '.join(MONITOR_SETTINGS)})")
        monitor.append((name, _number(value, f"{where} monitor.{name}")))
    columns = []
    for name, value in sorted(d["columns"].items()):
        if not isinstance(value, str):
            raise ConfigError(f"{where} columns.{name} = {value!r}: expected the column's name (a string)")
        columns.append((str(name), value))
    cfg = VehicleConfig(model=model, sensors=sensors, dt=dt, constants=tuple(constants), monitor=tuple(monitor),
                        columns=tuple(columns))
    try:
        cfg.monitor_new()
    except ValueError as e:
        raise ConfigError(f"{where}: {e}") from None
    return cfg


def _table(doc: Mapping[str, Any], key: str, source: str) -> Dict[str, Any]:
    value = doc.get(key, {})
    if not isinstance(value, dict):
        raise ConfigError(f"{source}: {key} must be a table ([{key}])")
    return dict(value)


def _check_entry(entry: Any, where: str) -> Dict[str, Any]:
    if not isinstance(entry, dict):
        raise ConfigError(f"{where} must be a table")
    for key, value in entry.items():
        if key not in _KEYS:
            raise ConfigError(f"{where}: unknown key {key!r} (keys: {', '.join(_KEYS)})")
        if key in ("constants", "monitor", "columns") and not isinstance(value, dict):
            raise ConfigError(f"{where} {key} must be a table, e.g. {key} = {{ name = value }}")
    return dict(entry)


def parse_config(text: str, source: str = "fleet.toml") -> FleetConfig:
    """Parses the text of a fleet file; :class:`ConfigError` names what is wrong."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{source}: not valid TOML ({e})") from None
    unknown = set(doc) - {"defaults", "classes", "vehicles"}
    if unknown:
        raise ConfigError(f"{source}: unknown table(s) {', '.join(sorted(unknown))} "
                          "(expected [defaults], [classes.NAME], [vehicles.ID])")
    defaults = _check_entry(doc["defaults"], f"{source}: [defaults]") if "defaults" in doc else None
    if defaults is not None and "class" in defaults:
        raise ConfigError(f"{source}: [defaults] cannot name a class")
    classes = {k: _check_entry(v, f"{source}: [classes.{k}]") for k, v in _table(doc, "classes", source).items()}
    for k, v in classes.items():
        if "class" in v:
            raise ConfigError(f"{source}: [classes.{k}] cannot name a class (one level only)")
    vehicles = {str(k): _check_entry(v, f"{source}: [vehicles.{k}]")
                for k, v in _table(doc, "vehicles", source).items()}
    cfg = FleetConfig(defaults=defaults, classes=classes, vehicles=vehicles, source=source)
    if defaults is not None:
        cfg.vehicle("\0defaults")  # checks the defaults themselves
    return cfg


def load_config(path: str) -> FleetConfig:
    """Reads ``path`` (a ``fleet.toml``); :class:`ConfigError` if it is missing or invalid."""
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file: a fleet needs its fleet.toml (see docs/capabilities/fleet.md; "
                          "vehid fleet simulate writes one)") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"{path}: cannot read ({e})") from None
    return parse_config(text, path)

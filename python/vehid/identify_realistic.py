"""``vehid identify LOG --model quarter|full --sensors realistic``: the constants a car's own
sensors determine.

A body accelerometer, a wheel accelerometer and a suspension deflection sensor (the channels
``a_body``, ``a_wheel``, ``deflection`` of ``vehid simulate --sensors realistic`` and ``vehid
monitor``) determine the body equation ``dvb/dt = -(k2/M) d - (b/M) v + offset``: the ratios
k2/M and b/M, and with the body mass known (``--M``) k2 and b. The tyre force ``k1 (u - zw)``
is measured by none of them (the wheel's absolute position and the road height are unknown),
so m and k1 are printed as not identifiable, with what would determine them. The fit is the
core's state-variable filter (``vehid.RealisticIdentifier``); this module reads the log,
restarts the filter at gaps and prints.

The full car (``--model full``): a body accelerometer above each wheel, the wheel
accelerometers and each corner's deflection (``a_body_fl`` .. ``deflection_rr``) determine its
four body-corner equations, and with ``--M`` the roll and pitch inertias, every corner's spring
and damper and the anti-roll bars, given the corners' positions (``--geometry``: the passenger
full car's by default); the tyres and the wheel masses are printed as not identifiable.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any, Dict, List, Optional, Tuple

import numpy as np
from numpy.typing import NDArray

from . import FullCar, HalfCar, QuarterCar, RealisticIdentifier, VehidError, fieldlog
from .align import nominal_interval
from .channels import FULL_SENSOR_COLUMNS, HALF_SENSOR_COLUMNS, SENSOR_COLUMNS
from .io import Column, Table, TableError, column_factor, match_columns, open_table, parse_column_map

CHUNK = 65_536
# A step between samples this many times the sample interval is a gap: the filter restarts.
GAP_FACTOR = 1.5
UNITS = {"k2": "N/m", "b": "N s/m", "k2/M": "1/s^2", "b/M": "1/s", "offset": "m/s^2", "M": "kg", "m": "kg",
         "k1": "N/m", "Jx": "kg m^2", "Jy": "kg m^2", "arb_f": "N m/rad", "arb_r": "N m/rad", "J": "kg m^2",
         "k12": "N/m", "k22": "N/m", "b1": "N s/m", "b2": "N s/m",
         **{f"{q}_{c}": u for c in ("fl", "fr", "rl", "rr") for q, u in (("k", "N/m"), ("b", "N s/m"))}}
#: The corners' positions ``--geometry`` may give (the full car's, the half car's).
GEOMETRY = {"full": ("l_f", "l_r", "track_f", "track_r"), "half": ("l1", "l2")}
#: What the full car's realistic sensors cannot determine, and what would.
FULL_NEEDS = {**{f"kt_{c}": f"the tyre force kt_{c} (u - zw): the road height under the wheel"
                 for c in ("fl", "fr", "rl", "rr")},
              **{f"m_{c}": f"the wheel's equation m_{c} dvw/dt = T - kt (zw - u): the tyre force"
                 for c in ("fl", "fr", "rl", "rr")}}
#: The half car's: the tyres k11, k21 and the wheel masses m1, m2.
HALF_NEEDS = {"k11": "the front tyre force k11 (u - zw): the road height under the wheel",
              "k21": "the rear tyre force k21 (u - zw): the road height under the wheel",
              "m1": "the front wheel's equation: the tyre force", "m2": "the rear wheel's equation: the tyre force"}


def _unit(name: str) -> str:
    """A parameter's unit: the named ones, the full car's corner coefficients (``a_fl:d_fr``
    1/s^2, ``a_fl:rate_fr`` 1/s, ``a_fl:offset`` m/s^2)."""
    if ":" in name:
        tail = name.split(":", 1)[1]
        return "1/s^2" if tail.startswith("d_") else "1/s" if tail.startswith("rate_") else "m/s^2"
    return UNITS.get(name, "")


def _corner_car(model: str, text: Optional[str]) -> Any:
    """The passenger full or half car with ``--geometry`` applied."""
    cls: Any = FullCar if model == "full" else HalfCar
    params = dict(cls.passenger().params)
    for key, value in (_pairs(text, "--geometry") if text else {}).items():
        if key not in GEOMETRY[model]:
            raise RealisticError(f"--geometry: {key!r} is not one of {', '.join(GEOMETRY[model])}")
        params[key] = value
    try:
        return cls(**params)
    except VehidError as e:
        raise RealisticError(f"--geometry: {e}") from None


class RealisticError(Exception):
    """A user error, reported in one line (exit status 2)."""


def _gaps(t: NDArray[np.float64], prev: Optional[float], dt: float, table: Table, lines: NDArray[np.int64],
          prev_line: int) -> NDArray[np.bool_]:
    """Whether each sample follows a gap (a step longer than GAP_FACTOR sample intervals); a
    missing time, or one that does not increase, is refused naming its line (``lines``: the
    samples' places in ``table``; ``prev_line``: the previous chunk's last sample's)."""
    full = t if prev is None else np.concatenate([[prev], t])
    ll = lines if prev is None else np.concatenate([[prev_line], lines])
    missing = ~np.isfinite(full)
    if missing.any():
        j = int(np.argmax(missing))
        raise RealisticError(f"{table.where(int(ll[j]))}: the time is missing: every sample needs its time (drop "
                             "the sample: the gap is then seen in the time column)")
    step = np.diff(full)
    if (step <= 0).any():
        i = int(np.argmax(step <= 0))
        raise RealisticError(f"{table.where(int(ll[i + 1]))}: time {float(full[i + 1])!r} s does not increase after "
                             f"{float(full[i])!r} s: the time column must increase strictly (sort the log, drop "
                             "duplicated samples)")
    gap = step > GAP_FACTOR * dt
    return gap if prev is not None else np.concatenate([[False], gap])


class _Fit:
    """The model's side of the fit: the quarter car's structure or the full car, its channels,
    the identifier, the constants from its stats and what stays undetermined."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.model = args.model
        self.corners = args.model in ("full", "half")  # the corner equations
        self.known: Dict[str, float] = {} if args.M is None else {"M": args.M}
        self.args = args
        if self.corners:
            half = args.model == "half"
            self.car: Any = _corner_car(args.model, args.geometry)
            self.source: Any = self.car
            self.channels = (HALF_SENSOR_COLUMNS if half else FULL_SENSOR_COLUMNS)["realistic"]
            self.needs = dict(HALF_NEEDS if half else FULL_NEEDS)
            if not self.known:
                relative = ("M", "J", "k12", "k22", "b1", "b2") if half else ("M", "Jx", "Jy", "arb_f", "arb_r")
                self.needs.update({k: "a known body mass (--M): these sensors give each only relative to it"
                                   for k in relative})
        else:
            if args.geometry is not None:
                raise RealisticError("--geometry is the full or the half car's (--model full|half)")
            self.car = QuarterCar.passenger()
            try:
                self.source = self.car.structure(known=self.known, sensors="realistic")
            except VehidError as e:
                raise RealisticError(str(e)) from None
            self.channels = SENSOR_COLUMNS["realistic"]
            self.needs = self.source.not_identifiable

    def identifier(self, dt: float, where: str) -> RealisticIdentifier:
        try:
            return RealisticIdentifier(self.source, dt, bandwidth=self.args.bandwidth, block=self.args.block)
        except VehidError as e:
            raise RealisticError(f"{where}: {e}") from None

    def constants(self, st: Any, where: str) -> Dict[str, Tuple[float, float, float]]:
        if not self.known:
            return {}
        try:
            out: Dict[str, Tuple[float, float, float]] = (
                self.car.physical(st, **self.known) if self.corners else self.car.physical(st))
            return out
        except VehidError as e:
            raise RealisticError(f"{where}: {e}") from None


def cmd_identify_realistic(args: argparse.Namespace) -> int:
    if args.model not in ("quarter", "half", "full"):
        raise RealisticError(
            "--sensors realistic: the quarter, half or full car (--model quarter|half|full); a model file's "
            "structure needs its state sensors")
    fit = _Fit(args)
    truth = _truth(args.truth, args.model)
    channels = fit.channels
    if args.file != "-" and (fieldlog.is_bag(args.file) or any(fieldlog.is_channel_map(c) for c in args.columns or [])):
        return _identify_field_log(args, fit, truth)
    try:
        mapping = parse_column_map(args.columns or [])
    except TableError as e:
        raise RealisticError(str(e)) from None
    ident: Optional[RealisticIdentifier] = None
    samples = gaps = missing = 0
    with open_table(args.file, delimiter=args.delimiter) as table:
        match = match_columns(table.names, (Column("t", "time", "s"),) + channels, mapping, where=table.source)
        absent = [c for c in channels if c.name not in match.index]
        if absent:
            raise RealisticError(
                f"{table.source} has no column {', '.join(c.describe() for c in absent)} for --sensors realistic "
                f"(its columns: {', '.join(repr(h) for h in table.names[:12])}); map yours with --columns "
                f"{absent[0].name}=NAME")
        has_t = "t" in match.index and not args.no_time
        if not has_t and args.dt is None:
            raise RealisticError(f"{table.source} has no time column t: give the sample interval with --dt SECONDS")
        # A drive's true constants (vehid simulate's true_M, ...: every one of the car's), read
        # as the truth when --truth is not given and they stay constant.
        names = list(fit.car.params)
        exact = {h: i for i, h in enumerate(table.names)}
        true_at = [exact.get(f"true_{c}") for c in names]
        read_truth = truth is None and all(i is not None for i in true_at)
        extra = [i for i in true_at if i is not None] if read_truth else []
        width = len(channels)
        cols = ([match.index["t"]] if has_t else []) + [match.index[c.name] for c in channels] + extra
        labels = (["t"] if has_t else []) + [c.describe() for c in channels] + [f"true_{c}" for c in names] * read_truth
        units = [Column("t", "time", "s")] * has_t + list(channels) + [Column("true", None, "")] * len(extra)
        try:  # declared units ([mm], [g], [ms]) to SI
            factors = np.asarray([column_factor(c.unit, table.names[i], f"column {table.names[i]!r}")
                                  for c, i in zip(units, cols)])
        except TableError as e:
            raise RealisticError(str(e)) from None
        prev: Optional[float] = None
        prev_line = 0
        file_truth: Optional[Dict[str, float]] = None
        varies = False
        for chunk in table.chunks(cols, labels, CHUNK, missing=True):
            data = table.to_si(chunk.data, factors, chunk.lines, labels)
            first = int(has_t)
            y = np.ascontiguousarray(data[:, first:first + width])
            if read_truth:
                true_rows = data[:, first + width:]
                if file_truth is None:
                    file_truth = dict(zip(names, true_rows[0].tolist()))
                varies = varies or bool((true_rows != true_rows[0]).any())
            if ident is None:
                dt = args.dt
                if dt is None:
                    if len(data) < 2:
                        raise RealisticError(f"{table.source}: one sample cannot give the sample interval: give --dt")
                    dt = nominal_interval(data[:, 0])  # the nominal rate, not a float's noise
                ident = fit.identifier(dt, table.source)
            restart = np.zeros(len(y), dtype=bool)
            if has_t:
                restart = _gaps(data[:, 0], prev, ident.dt, table, chunk.lines, prev_line)
                prev, prev_line = float(data[-1, 0]), int(chunk.lines[-1])
            # A missing value: the sample is left out and the filter restarts.
            bad = np.asarray(~np.isfinite(y).all(axis=1), dtype=bool)
            missing += int(bad.sum())
            gaps += int(restart.sum())
            start = 0
            for i in np.flatnonzero(restart | bad).tolist() + [len(y)]:
                if start < i:
                    ident.fit(y[start:i])
                if i < len(y):
                    ident.restart()
                    start = i + 1 if bool(bad[i]) else i
            samples += len(y)
        source = table.source
    if file_truth is not None and varies:
        print(f"vehid: note: {source}: the drive's true constants change during it (a --change): no single truth "
              "to compare with", file=sys.stderr)
    elif file_truth is not None:
        truth = file_truth
    if ident is None:
        raise RealisticError(f"{source} has no samples")
    try:
        st = ident.stats()
    except VehidError as e:
        raise RealisticError(f"{source}: {e}") from None
    constants = fit.constants(st, source)
    report = _report(args, fit, source, samples, gaps, missing, ident, st, constants, truth)
    if args.json:
        print(json.dumps(report, allow_nan=False))
    else:
        _print(report)
    return 0


def _identify_field_log(args: argparse.Namespace, fit: _Fit, truth: Optional[Dict[str, float]]) -> int:
    """A bag, or a table through a ``channels.toml``: the channels read, converted, aligned
    and checked as ``vehid monitor`` reads them (:mod:`vehid.fieldlog`), then fitted; the
    filter restarts after every missing sample."""
    channels = fit.channels
    cmap: Optional[fieldlog.ChannelMap] = None
    pairs: List[str] = []
    try:
        for text in args.columns or []:
            if fieldlog.is_channel_map(text):
                cmap = fieldlog.load_channel_map(text, [c.name for c in channels])
            else:
                pairs.append(text)
        log = fieldlog.read_log(args.file, channels, cmap, parse_column_map(pairs), args.delimiter, args.dt)
        al = fieldlog.align(log, args.dt, cmap.channels if cmap else None)
    except TableError as e:
        raise RealisticError(str(e)) from None
    for note in al.notes:
        print(f"vehid: note: {note}", file=sys.stderr)
    ident = fit.identifier(al.dt, log.source)
    bad = ~np.isfinite(al.y).all(axis=1)
    starts = np.flatnonzero(np.diff(np.concatenate([[True], bad]).astype(np.int8)) == -1)
    stops = np.flatnonzero(np.diff(np.concatenate([bad, [True]]).astype(np.int8)) == 1) + 1
    for k, (a, b) in enumerate(zip(starts.tolist(), stops.tolist())):
        if k:
            ident.restart()
        ident.fit(np.ascontiguousarray(al.y[a:b]))
    try:
        st = ident.stats()
    except VehidError as e:
        raise RealisticError(f"{log.source}: {e}") from None
    constants = fit.constants(st, log.source)
    report = _report(args, fit, log.source, len(al.y), max(0, len(starts) - 1), int(bad.sum()), ident, st, constants,
                     truth)
    if args.json:
        print(json.dumps(report, allow_nan=False))
    else:
        _print(report)
    return 0


def _truth(text: Optional[str], model: str = "quarter") -> Optional[Dict[str, float]]:
    if text is None:
        return None
    if text.strip() == "passenger":
        cls: Any = {"full": FullCar, "half": HalfCar}.get(model, QuarterCar)
        return dict(cls.passenger().params)
    if text.strip() == "thesis" and model == "quarter":
        return dict(QuarterCar().params)
    return _pairs(text, "--truth")


def _pairs(text: str, option: str) -> Dict[str, float]:
    """``NAME=VALUE,...`` with finite values."""
    out: Dict[str, float] = {}
    for item in text.split(","):
        key, sep, value = item.partition("=")
        try:
            out[key.strip()] = float(value)
        except ValueError:
            raise RealisticError(f"{option}: {item.strip()!r} is not NAME=VALUE") from None
        if not sep or not math.isfinite(out[key.strip()]):
            raise RealisticError(f"{option}: {item.strip()!r} is not NAME=VALUE with a finite value")
    return out


def _report(args: argparse.Namespace, fit: _Fit, source: str, samples: int, gaps: int, missing: int,
            ident: RealisticIdentifier, st: Any, constants: Dict[str, Tuple[float, float, float]],
            truth: Optional[Dict[str, float]]) -> Dict[str, Any]:
    params: List[Dict[str, Any]] = []
    for name, v, (lo, hi) in zip(st.names, st.params.tolist(), st.conf_int.tolist()):
        true = None
        if truth is not None and ":" in name:
            true = None
        elif truth is not None and "/" in name:
            a, b = name.split("/")
            true = truth[a] / truth[b] if a in truth and b in truth else None
        elif truth is not None and name in truth:
            true = truth[name]
        params.append({"name": name, "value": v, "low": lo, "high": hi, "true": true})
    consts = {k: {"value": v, "low": lo, "high": hi, "true": None if truth is None else truth.get(k)}
              for k, (v, lo, hi) in constants.items()}
    return {
        "source": source,
        "model": fit.model,
        "sensors": "realistic",
        "samples": samples,
        "used": ident.samples,
        "restarts": gaps,
        "missing": missing,
        "dt": ident.dt,
        "bandwidth": ident.bandwidth,
        "block": ident.block,
        "blocks": float(st.df[0]) + 1,
        "alpha": st.alpha,
        "known": {"M": args.M} if args.M is not None else {},
        "params": params,
        "constants": consts,
        "not_identifiable": {k: v for k, v in fit.needs.items() if k not in constants},
    }


def _print(r: Dict[str, Any]) -> None:
    full = r["model"] in ("full", "half")
    corners = "f, r" if r["model"] == "half" else "fl, fr, rl, rr"
    what = (f"{r['model']} car, realistic sensors (a_body, a_wheel, deflection at {corners})" if full
            else "quarter car, realistic sensors (a_body, a_wheel, deflection)")
    print(f"{r['source']}: {r['samples']} samples ({r['used']} used; {r['restarts']} restart(s) at gaps, "
          f"{r['missing']} with a missing value), {what}, sample interval {r['dt']:.6g} s")
    print(f"method: state-variable filter (bandwidth {r['bandwidth']:g} rad/s) on the "
          f"{'body-corner equations' if full else 'body equation'}, intervals "
          f"cluster-robust over {r['blocks']:.0f} blocks of {r['block']:g} s")
    print()
    level = f"{100 * (1 - r['alpha']):g} %"
    if full:
        print(f"body-corner equations a_i = sum_j (alpha K)_ij (-d_j) + alpha_ij b_j (-v_j) + offset_i, {level} "
              "intervals (a_i:d_j is (alpha K)_ij, a_i:rate_j alpha_ij b_j):")
    else:
        print(f"body equation dvb/dt = -(k2/M) d - (b/M) v + offset, {level} intervals:")
    width = 13 if full else 6
    for p in r["params"]:
        band = f"[{p['low']:.6g}, {p['high']:.6g}]"
        true = f"true {p['true']:.6g}" if p["true"] is not None else ""
        print(f"  {p['name']:{width}s} = {p['value']:<12.6g} {band:26s} {_unit(p['name']):7s} {true}".rstrip())
    print()
    name_width = 5 if full else 3
    given = ", ".join(f"{k} = {v:g} kg" for k, v in r["known"].items()) or "none"
    print(f"physical constants (known: {given}), {level} intervals:")
    for k, c in r["constants"].items():
        if k in r["known"]:
            continue
        band = f"[{c['low']:.6g}, {c['high']:.6g}]"
        true = f"true {c['true']:.6g}" if c["true"] is not None else ""
        print(f"  {k:{name_width}s} = {c['value']:<12.6g} {band:26s} {_unit(k):7s} {true}".rstrip())
    for k, why in r["not_identifiable"].items():
        print(f"  {k:{name_width}s}   not identifiable from these signals: needs {why}")

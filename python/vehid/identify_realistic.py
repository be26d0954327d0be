"""``vehid identify LOG --model quarter --sensors realistic``: the constants a car's own sensors
determine.

A body accelerometer, a wheel accelerometer and a suspension deflection sensor (the channels
``a_body``, ``a_wheel``, ``deflection`` of ``vehid simulate --sensors realistic`` and ``vehid
monitor``) determine the body equation ``dvb/dt = -(k2/M) d - (b/M) v + offset``: the ratios
k2/M and b/M, and with the body mass known (``--M``) k2 and b. The tyre force ``k1 (u - zw)``
is measured by none of them (the wheel's absolute position and the road height are unknown),
so m and k1 are printed as not identifiable, with what would determine them. The fit is the
core's state-variable filter (``vehid.RealisticIdentifier``); this module reads the log,
restarts the filter at gaps and prints.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any, Dict, List, Optional, Tuple

import numpy as np
from numpy.typing import NDArray

from . import QuarterCar, RealisticIdentifier, VehidError, fieldlog
from .align import nominal_interval
from .channels import SENSOR_COLUMNS
from .io import Column, Table, TableError, column_factor, match_columns, open_table, parse_column_map

CHUNK = 65_536
# A step between samples this many times the sample interval is a gap: the filter restarts.
GAP_FACTOR = 1.5
UNITS = {"k2": "N/m", "b": "N s/m", "k2/M": "1/s^2", "b/M": "1/s", "offset": "m/s^2", "M": "kg", "m": "kg",
         "k1": "N/m"}


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


def cmd_identify_realistic(args: argparse.Namespace) -> int:
    if args.model != "quarter":
        raise RealisticError(
            "--sensors realistic: the quarter car only (--model quarter); for the half car identify each axle's "
            "body equation from its own channels (a_body_f, a_wheel_f, deflection_f as a quarter car), or record "
            "the state sensors")
    known: Dict[str, float] = {} if args.M is None else {"M": args.M}
    truth = _truth(args.truth)
    try:
        structure = QuarterCar.passenger().structure(known=known, sensors="realistic")
    except VehidError as e:
        raise RealisticError(str(e)) from None
    channels = SENSOR_COLUMNS["realistic"]
    if args.file != "-" and (fieldlog.is_bag(args.file) or any(fieldlog.is_channel_map(c) for c in args.columns or [])):
        return _identify_field_log(args, structure, known, truth)
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
        cols = ([match.index["t"]] if has_t else []) + [match.index[c.name] for c in channels]
        labels = (["t"] if has_t else []) + [c.describe() for c in channels]
        units = [Column("t", "time", "s")] * has_t + list(channels)
        try:  # declared units ([mm], [g], [ms]) to SI
            factors = np.asarray([column_factor(c.unit, table.names[i], f"column {table.names[i]!r}")
                                  for c, i in zip(units, cols)])
        except TableError as e:
            raise RealisticError(str(e)) from None
        prev: Optional[float] = None
        prev_line = 0
        for chunk in table.chunks(cols, labels, CHUNK, missing=True):
            data = table.to_si(chunk.data, factors, chunk.lines, labels)
            y = np.ascontiguousarray(data[:, 1:] if has_t else data)
            if ident is None:
                dt = args.dt
                if dt is None:
                    if len(data) < 2:
                        raise RealisticError(f"{table.source}: one sample cannot give the sample interval: give --dt")
                    dt = nominal_interval(data[:, 0])  # the nominal rate, not a float's noise
                try:
                    ident = RealisticIdentifier(structure, dt, bandwidth=args.bandwidth, block=args.block)
                except VehidError as e:
                    raise RealisticError(f"{table.source}: {e}") from None
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
    if ident is None:
        raise RealisticError(f"{source} has no samples")
    try:
        st = ident.stats()
    except VehidError as e:
        raise RealisticError(f"{source}: {e}") from None
    car = QuarterCar.passenger()
    constants = car.physical(st) if known else {}
    needs = structure.not_identifiable
    report = _report(args, source, samples, gaps, missing, ident, st, constants, needs, truth)
    if args.json:
        print(json.dumps(report, allow_nan=False))
    else:
        _print(report)
    return 0


def _identify_field_log(args: argparse.Namespace, structure: Any, known: Dict[str, float],
                        truth: Optional[Dict[str, float]]) -> int:
    """A bag, or a table through a ``channels.toml``: the channels read, converted, aligned
    and checked as ``vehid monitor`` reads them (:mod:`vehid.fieldlog`), then fitted; the
    filter restarts after every missing sample."""
    channels = SENSOR_COLUMNS["realistic"]
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
    try:
        ident = RealisticIdentifier(structure, al.dt, bandwidth=args.bandwidth, block=args.block)
    except VehidError as e:
        raise RealisticError(f"{log.source}: {e}") from None
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
    constants = QuarterCar.passenger().physical(st) if known else {}
    report = _report(args, log.source, len(al.y), max(0, len(starts) - 1), int(bad.sum()), ident, st, constants,
                     structure.not_identifiable, truth)
    if args.json:
        print(json.dumps(report, allow_nan=False))
    else:
        _print(report)
    return 0


def _truth(text: Optional[str]) -> Optional[Dict[str, float]]:
    if text is None:
        return None
    if text.strip() == "passenger":
        return dict(QuarterCar.passenger().params)
    if text.strip() == "thesis":
        return dict(QuarterCar().params)
    out: Dict[str, float] = {}
    for item in text.split(","):
        key, sep, value = item.partition("=")
        try:
            out[key.strip()] = float(value)
        except ValueError:
            raise RealisticError(f"--truth: {item.strip()!r} is not NAME=VALUE") from None
        if not sep or not math.isfinite(out[key.strip()]):
            raise RealisticError(f"--truth: {item.strip()!r} is not NAME=VALUE with a finite value")
    return out


def _report(args: argparse.Namespace, source: str, samples: int, gaps: int, missing: int,
            ident: RealisticIdentifier, st: Any, constants: Dict[str, Tuple[float, float, float]],
            needs: Dict[str, str], truth: Optional[Dict[str, float]]) -> Dict[str, Any]:
    params: List[Dict[str, Any]] = []
    for name, v, (lo, hi) in zip(st.names, st.params.tolist(), st.conf_int.tolist()):
        true = None
        if truth is not None and "/" in name:
            a, b = name.split("/")
            true = truth[a] / truth[b] if a in truth and b in truth else None
        elif truth is not None and name in truth:
            true = truth[name]
        params.append({"name": name, "value": v, "low": lo, "high": hi, "true": true})
    consts = {k: {"value": v, "low": lo, "high": hi, "true": None if truth is None else truth.get(k)}
              for k, (v, lo, hi) in constants.items()}
    return {
        "source": source,
        "model": "quarter",
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
        "not_identifiable": {k: v for k, v in needs.items() if k not in constants},
    }


def _print(r: Dict[str, Any]) -> None:
    print(f"{r['source']}: {r['samples']} samples ({r['used']} used; {r['restarts']} restart(s) at gaps, "
          f"{r['missing']} with a missing value), quarter car, realistic sensors (a_body, a_wheel, deflection), "
          f"sample interval {r['dt']:.6g} s")
    print(f"method: state-variable filter (bandwidth {r['bandwidth']:g} rad/s) on the body equation, intervals "
          f"cluster-robust over {r['blocks']:.0f} blocks of {r['block']:g} s")
    print()
    level = f"{100 * (1 - r['alpha']):g} %"
    print(f"body equation dvb/dt = -(k2/M) d - (b/M) v + offset, {level} intervals:")
    for p in r["params"]:
        band = f"[{p['low']:.6g}, {p['high']:.6g}]"
        true = f"true {p['true']:.6g}" if p["true"] is not None else ""
        print(f"  {p['name']:6s} = {p['value']:<12.6g} {band:26s} {UNITS.get(p['name'], ''):7s} {true}".rstrip())
    print()
    given = ", ".join(f"{k} = {v:g} kg" for k, v in r["known"].items()) or "none"
    print(f"physical constants (known: {given}), {level} intervals:")
    for k, c in r["constants"].items():
        if k in r["known"]:
            continue
        band = f"[{c['low']:.6g}, {c['high']:.6g}]"
        true = f"true {c['true']:.6g}" if c["true"] is not None else ""
        print(f"  {k:3s} = {c['value']:<12.6g} {band:26s} {UNITS.get(k, ''):7s} {true}".rstrip())
    for k, why in r["not_identifiable"].items():
        print(f"  {k:3s}   not identifiable from these signals: needs {why}")

"""The fleet log layout: a Parquet dataset partitioned by vehicle and day,

    DIR/fleet.toml
    DIR/vehicle=<id>/day=<YYYY-MM-DD>/<any name>.parquet      (one or more files per vehicle-day)

each file holding a time column ``t`` (seconds from the day's start) and the sensor channels
as ``vehid monitor`` reads them (``a_body, a_wheel, deflection``: m/s², m/s², m; the half car's
``..._f, ..._r``; names matched as ``vehid monitor`` matches them, or mapped in fleet.toml).
A day's files are read in the order of their names and joined (name them by start time).
Any Parquet file will do; sensor channels read about twice as fast written without dictionary
encoding (pyarrow: ``use_dictionary=False``), with LZ4 or Snappy compression.
"""

from __future__ import annotations

import datetime
import json
import os
from dataclasses import dataclass, field
from typing import Any, Dict, List, Tuple

from ._deps import module
from .fold import FILES_KEY, DayError

CONFIG = "fleet.toml"


@dataclass
class Dataset:
    """What a fleet directory holds: per vehicle its days (sorted) and each day's files;
    entries that do not fit the layout, with the reason."""

    root: str
    #: vehicle -> [(day, [file paths])], days sorted.
    vehicles: Dict[str, List[Tuple[str, List[str]]]] = field(default_factory=dict)
    #: (vehicle, day or "", reason) for a directory that does not fit the layout.
    problems: List[Tuple[str, str, str]] = field(default_factory=list)


def _is_day(text: str) -> bool:
    try:
        return datetime.date.fromisoformat(text).isoformat() == text
    except ValueError:
        return False


def scan(root: str) -> Dataset:
    """Lists ``root``'s vehicles, days and files (no file is opened). ``ValueError`` if
    ``root`` is not a directory."""
    if not os.path.isdir(root):
        raise ValueError(f"{root}: not a directory (a fleet: DIR/vehicle=<id>/day=<YYYY-MM-DD>/*.parquet and "
                         "DIR/fleet.toml)")
    ds = Dataset(root=root)
    for name in sorted(os.listdir(root)):
        path = os.path.join(root, name)
        if not name.startswith("vehicle=") or not os.path.isdir(path):
            continue
        vid = name[len("vehicle="):]
        if not vid:
            ds.problems.append(("", "", f"{name}: an empty vehicle id"))
            continue
        days: List[Tuple[str, List[str]]] = []
        for dname in sorted(os.listdir(path)):
            dpath = os.path.join(path, dname)
            if not os.path.isdir(dpath):
                continue
            day = dname[len("day="):] if dname.startswith("day=") else ""
            if not _is_day(day):
                ds.problems.append((vid, dname, f"{name}/{dname}: not a day=YYYY-MM-DD directory (skipped)"))
                continue
            files = sorted(os.path.join(dpath, f) for f in os.listdir(dpath)
                           if f.endswith(".parquet") and not f.startswith("."))
            days.append((day, files))
        ds.vehicles[vid] = days
    return ds


def read_day(files: List[str]) -> Any:
    """The day's files joined into one pyarrow table (in the files' name order; read on the
    calling thread: the engines run many days side by side);
    :class:`DayError` naming the file for one that cannot be read or does not fit the others."""
    pa = module("pyarrow")
    pq = module("pyarrow.parquet")

    if not files:
        raise DayError("no .parquet file in the day's directory")
    tables = []
    for path in files:
        try:
            tables.append(pq.read_table(path, use_threads=False))
        except Exception as e:  # pyarrow's ArrowInvalid / OSError family
            raise DayError(f"{os.path.basename(path)}: not a readable Parquet file "
                           f"({str(e).splitlines()[0] if str(e) else type(e).__name__})") from None
    files_meta = json.dumps([[os.path.basename(p), tb.num_rows] for p, tb in zip(files, tables)]).encode()

    def recorded(tb: Any) -> Any:  # the files and their rows, for messages (fold.row_place)
        return tb.replace_schema_metadata({**(tb.schema.metadata or {}), FILES_KEY: files_meta})

    if len(tables) == 1:
        return recorded(tables[0])
    names = tables[0].column_names
    for path, tb in zip(files[1:], tables[1:]):
        if set(tb.column_names) != set(names):
            raise DayError(f"{os.path.basename(path)}: its columns ({', '.join(tb.column_names[:12])}) differ from "
                           f"{os.path.basename(files[0])}'s ({', '.join(names[:12])})")
    try:
        return recorded(pa.concat_tables([tb.select(names) for tb in tables], promote_options="permissive"))
    except Exception as e:
        raise DayError(f"the day's files do not join ({str(e).splitlines()[0]})") from None

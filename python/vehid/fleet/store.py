"""The fleet store: three Parquet tables in one directory.

* ``state.parquet`` — one row per vehicle-day: ``vehicle``, ``day`` (YYYY-MM-DD),
  ``vehid_version``, ``state`` (the monitor after that day, :func:`vehid.fleet.fold.pack_state`;
  null when no day of that vehicle could be used yet) and ``summary`` (JSON: the fold's summary,
  the day's ``events`` and, for a day that could not be used, its ``problem``). Its metadata
  also holds the problems of the last run that belong to no stored day (a day out of order, a
  vehicle without settings, a directory that does not fit the layout).
  **It is the store**: the only table a run commits, by writing a new file and renaming it
  over the old one (``os.replace``, atomic on POSIX and Windows), so a crash at any moment
  leaves the last committed store.
* ``events.parquet`` — ``vehicle, day, t, parameter, before, after, low, high, corner``
  (then ``t_change`` and ``change``), sorted; and ``problems.parquet`` — ``vehicle, day,
  reason``. Both are written from ``state.parquet`` after it, and carry in their metadata the
  digest of the state they were made from: :func:`open_store` rebuilds them when they are
  stale (a crash between the two writes), so they never disagree with it.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from typing import Any, Dict, Iterable, List, Optional, Tuple

from ._deps import module

STATE, EVENTS, PROBLEMS = "state.parquet", "events.parquet", "problems.parquet"
_DIGEST = b"vehid.fleet.state_digest"
_RUN_PROBLEMS = b"vehid.fleet.run_problems"
_FORMAT = b"vehid.fleet.format"


class StoreError(ValueError):
    """The store cannot be read or written: the message names the file and the fix."""


@dataclass
class Row:
    """One stored vehicle-day."""

    vehid_version: str
    state: Optional[bytes]
    summary: str


@dataclass
class Store:
    """A store in memory: rows by ``(vehicle, day)`` and the last run's other problems."""

    path: str
    rows: Dict[Tuple[str, str], Row] = field(default_factory=dict)
    run_problems: List[Tuple[str, str, str]] = field(default_factory=list)

    def days(self, vehicle: str) -> List[str]:
        """The vehicle's stored days, sorted."""
        return sorted(d for v, d in self.rows if v == vehicle)

    def by_vehicle(self) -> Dict[str, List[str]]:
        """Every stored vehicle's days, sorted."""
        out: Dict[str, List[str]] = {}
        for v, d in sorted(self.rows):
            out.setdefault(v, []).append(d)
        return out

    # --- tables ---------------------------------------------------------------------------

    def state_table(self) -> Any:
        """``state.parquet`` as a pyarrow table (sorted by vehicle, day)."""
        pa = module("pyarrow")

        keys = sorted(self.rows)
        return pa.table({
            "vehicle": pa.array([k[0] for k in keys], pa.string()),
            "day": pa.array([k[1] for k in keys], pa.string()),
            "vehid_version": pa.array([self.rows[k].vehid_version for k in keys], pa.string()),
            "state": pa.array([self.rows[k].state for k in keys], pa.binary()),
            "summary": pa.array([self.rows[k].summary for k in keys], pa.string()),
        })

    def events_table(self) -> Any:
        """``events.parquet`` as a pyarrow table: every stored event, sorted by vehicle, day, t."""
        pa = module("pyarrow")

        cols: Dict[str, List[Any]] = {k: [] for k in EVENT_COLUMNS}
        for (v, d) in sorted(self.rows):
            for ev in json.loads(self.rows[(v, d)].summary).get("events", []):
                cols["vehicle"].append(v)
                cols["day"].append(d)
                for k in EVENT_COLUMNS[2:]:
                    cols[k].append(ev[k])
        return pa.table({k: pa.array(cols[k], t) for k, t in _event_types().items()})

    def problems_table(self) -> Any:
        """``problems.parquet`` as a pyarrow table: the stored days that could not be used,
        then the last run's other problems."""
        pa = module("pyarrow")

        rows = [(v, d, p) for (v, d), r in sorted(self.rows.items())
                if (p := json.loads(r.summary).get("problem")) is not None]
        rows += sorted(self.run_problems)
        return pa.table({"vehicle": pa.array([r[0] for r in rows], pa.string()),
                         "day": pa.array([r[1] for r in rows], pa.string()),
                         "reason": pa.array([r[2] for r in rows], pa.string())})

    def digest(self) -> str:
        """SHA-256 of the stored rows and run problems: what the derived tables were made from."""
        h = hashlib.sha256()
        for (v, d), r in sorted(self.rows.items()):
            for part in (v, d, r.vehid_version, r.summary):
                h.update(part.encode() + b"\0")
            h.update(b"\1" + r.state if r.state is not None else b"\0")
        h.update(json.dumps(sorted(self.run_problems)).encode())
        return h.hexdigest()

    # --- writing --------------------------------------------------------------------------

    def commit(self) -> None:
        """Writes ``state.parquet`` (the commit), then ``events.parquet`` and ``problems.parquet``."""
        try:
            os.makedirs(self.path, exist_ok=True)
        except OSError as e:
            raise StoreError(f"--store {self.path}: cannot create the directory ({e.strerror or e})") from None
        digest = self.digest().encode()
        meta = {_FORMAT: b"1", _DIGEST: digest, _RUN_PROBLEMS: json.dumps(sorted(self.run_problems)).encode()}
        write_atomic(self.state_table(), os.path.join(self.path, STATE), meta)
        self._write_derived(digest)

    def _write_derived(self, digest: bytes) -> None:
        write_atomic(self.events_table(), os.path.join(self.path, EVENTS), {_DIGEST: digest})
        write_atomic(self.problems_table(), os.path.join(self.path, PROBLEMS), {_DIGEST: digest})


#: The events table's columns, in order.
EVENT_COLUMNS = ("vehicle", "day", "t", "parameter", "before", "after", "low", "high", "corner", "t_change", "change")


def _event_types() -> Dict[str, Any]:
    pa = module("pyarrow")

    f, s = pa.float64(), pa.string()
    return {"vehicle": s, "day": s, "t": f, "parameter": s, "before": f, "after": f, "low": f, "high": f,
            "corner": s, "t_change": f, "change": f}


def write_atomic(table: Any, path: str, metadata: Dict[bytes, bytes]) -> None:
    """Writes ``table`` to ``path`` atomically: a temporary file in the same directory,
    flushed to disk, then renamed over ``path``. On any failure ``path`` is as it was and the
    temporary file is removed."""
    pq = module("pyarrow.parquet")

    tmp = f"{path}.tmp-{os.getpid()}"
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), **metadata})
    try:
        pq.write_table(table, tmp, compression="zstd")
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.remove(tmp)
        except OSError:
            pass
        if isinstance(e, OSError):
            raise StoreError(f"{path}: cannot write ({e.strerror or e})") from None
        raise


def open_store(path: str) -> Store:
    """Reads the store at ``path`` (an empty store if it has no ``state.parquet`` yet), and
    rewrites its events and problems tables if they are not those of its state (a crash
    between the writes). :class:`StoreError` for a directory that is not a store or a
    damaged state table."""
    pq = module("pyarrow.parquet")

    if os.path.exists(path) and not os.path.isdir(path):
        raise StoreError(f"--store {path}: is a file; give a directory (created if missing)")
    store = Store(path=path)
    state_path = os.path.join(path, STATE)
    if not os.path.exists(state_path):
        if os.path.isdir(path) and any(not n.startswith(".") for n in os.listdir(path)):
            others = sorted(os.listdir(path))[:5]
            if not set(others) <= {EVENTS, PROBLEMS} and not all(".tmp-" in n for n in others):
                raise StoreError(f"--store {path}: a directory that is not a fleet store (it holds "
                                 f"{', '.join(others)}, no {STATE}): give an empty or new directory")
        return store
    try:
        table = pq.read_table(state_path)
    except Exception as e:
        raise StoreError(f"{state_path}: not readable ({str(e).splitlines()[0]}): the store is damaged; restore "
                         "it from a backup, or remove the store to recompute it from the logs") from None
    need = {"vehicle", "day", "vehid_version", "state", "summary"}
    if not need <= set(table.column_names):
        raise StoreError(f"{state_path}: not a fleet state table (columns {', '.join(table.column_names)})")
    meta = table.schema.metadata or {}
    d = table.to_pydict()
    for v, day, ver, st, su in zip(d["vehicle"], d["day"], d["vehid_version"], d["state"], d["summary"]):
        store.rows[(v, day)] = Row(ver, st, su)
    store.run_problems = [(str(p[0]), str(p[1]), str(p[2])) for p in json.loads(meta.get(_RUN_PROBLEMS, b"[]"))]
    digest = store.digest().encode()
    if any(_digest_of(os.path.join(path, name)) != digest for name in (EVENTS, PROBLEMS)):
        store._write_derived(digest)
    return store


def _digest_of(path: str) -> Optional[bytes]:
    pq = module("pyarrow.parquet")

    try:
        meta = pq.read_schema(path).metadata or {}
    except Exception:
        return None
    return meta.get(_DIGEST)


def read_table(path: str, name: str) -> Any:
    """One table of the store at ``path`` (``events``, ``state`` or ``problems``), consistent
    with its state (:func:`open_store` first)."""
    store = open_store(path)
    tables = {"events": store.events_table, "state": store.state_table, "problems": store.problems_table}
    if name not in tables:
        raise ValueError(f"name={name!r}: choose events, state or problems")
    return tables[name]()


def merge(store: Store, rows: Iterable[Tuple[str, str, Row]]) -> None:
    """Puts ``rows`` (vehicle, day, row) into ``store``, replacing those days."""
    for v, d, r in rows:
        store.rows[(v, d)] = r

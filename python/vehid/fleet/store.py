"""The fleet store: three Parquet tables in one directory.

* ``state.parquet`` — one row per vehicle-day: ``vehicle``, ``day`` (YYYY-MM-DD),
  ``vehid_version``, ``state`` (the monitor after that day, :func:`vehid.fleet.fold.pack_state`;
  null when no day of that vehicle could be used yet) and ``summary`` (JSON: the fold's summary,
  the day's ``events`` and, for a day that could not be used, its ``problem``). It is a
  directory, a Parquet dataset that ``pyarrow.parquet.read_table`` (and pandas, Dask, DuckDB)
  read as one table: one file per day, ``<YYYY-MM-DD>.parquet``, sorted by vehicle, so that a
  run rewrites the days it touched and no others.

  Its manifest ``state.parquet/_commit.json`` (Parquet readers skip names that start with
  ``_`` or ``.``) **is the store**: it lists the files that make the state with the digest of
  each, and the problems of the last run that belong to no stored day (a day out of order, a
  vehicle without settings, a directory that does not fit the layout). A commit writes its
  files first under names nothing reads (``.<day>.parquet.tmp-<n>``), then a new manifest,
  flushed and renamed over the old one (``os.replace``, atomic on POSIX and Windows), then
  renames the files into place. A process killed before the manifest's rename leaves the last
  committed store; one killed after it has its renames redone when the store is next opened.
  A reader that finds a day file other than the one the manifest it read lists (a commit came
  between) starts again from the new manifest.
* A commit in the middle of a run (every 60 s of a long one) writes only the rows that changed
  since the previous commit, as a part ``_part-<n>.parquet`` the manifest lists; the run's
  last commit folds the parts into the day files. So a commit costs what it adds, not the
  store's history, and what Parquet readers see is the state at the end of the last run.
* ``events.parquet`` — ``vehicle, day, t, parameter, before, after, low, high, corner``
  (then ``t_change`` and ``change``), sorted; and ``problems.parquet`` — ``vehicle, day,
  reason``. Both are written from the state at a run's last commit and carry in their metadata
  the digest of the state they were made from: :func:`open_store` rebuilds them when they are
  stale (a crash between the writes, a run killed after a commit in its middle), so they never
  disagree with it.

A store written before the day files (``state.parquet`` as one file, format 1) is read as it
is, and the first commit rewrites it as day files (the file is kept as ``.state.parquet.v1``
until the new directory is in place).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
from collections.abc import MutableMapping
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Iterable, Iterator, List, Optional, Set, Tuple

from ._deps import module

STATE, EVENTS, PROBLEMS = "state.parquet", "events.parquet", "problems.parquet"
#: The lock file a run holds (``vehid.fleet.engine``): the pid of the process running.
LOCK = ".lock"
#: The manifest inside ``state.parquet``.
MANIFEST = "_commit.json"
#: The store's format (the manifest's ``format``): 2 is the directory of day files.
FORMAT = 2
_LEGACY, _SWAP = ".state.parquet.v1", ".state.parquet.new"
_DIGEST = b"vehid.fleet.state_digest"
_RUN_PROBLEMS = b"vehid.fleet.run_problems"
_FILE_DIGEST = b"vehid.fleet.file_digest"
_STATE_COLUMNS = ("vehicle", "day", "vehid_version", "state", "summary")


class StoreError(ValueError):
    """The store cannot be read or written: the message names the file and the fix."""


@dataclass
class Row:
    """One stored vehicle-day."""

    vehid_version: str
    state: Optional[bytes]
    summary: str
    _info: Optional[Dict[str, Any]] = field(default=None, repr=False, compare=False)

    def info(self) -> Dict[str, Any]:
        """The summary, parsed (once)."""
        if self._info is None:
            self._info = json.loads(self.summary)
        return self._info


class Rows(MutableMapping):  # type: ignore[type-arg]
    """The stored rows by ``(vehicle, day)``, indexed by vehicle, remembering which keys and
    days changed since the last commit (what the next one writes).

    A row may be known by its key alone (``load_later``): its day file is read, whole, when
    one of its rows is first asked for, so that a run holds the index of the store and the
    days it reads or writes, not the history. The index is one set of days per vehicle: a key
    of a day not read yet is one whose row is not in memory."""

    def __init__(self, fetch: Optional[Callable[[str], Iterable[Tuple[str, Row]]]] = None) -> None:
        self._rows: Dict[Tuple[str, str], Row] = {}
        #: The days whose file holds rows not read yet: every key of such a day that is in the
        #: index and not in ``_rows`` (a key set since is in ``_rows``, one deleted is not in
        #: the index).
        self._later: Set[str] = set()
        self._fetch = fetch
        self._by_vehicle: Dict[str, Set[str]] = {}
        self._count = 0
        #: Keys set or deleted since the last commit (the next part's rows).
        self.changed_keys: Set[Tuple[str, str]] = set()
        #: Days with a key set or deleted since the last commit that wrote the day files.
        self.changed_days: Set[str] = set()
        #: Days with a key set or deleted since the events and problems tables were written.
        self.derived_days: Set[str] = set()

    def _index(self, key: Tuple[str, str]) -> None:
        days = self._by_vehicle.setdefault(key[0], set())
        if key[1] not in days:
            days.add(key[1])
            self._count += 1

    def load(self, key: Tuple[str, str], row: Row) -> None:
        """Puts a committed row in, not counted as a change."""
        self._index(key)
        self._rows[key] = row

    def load_later(self, key: Tuple[str, str]) -> None:
        """Puts a committed row in by its key: its day file is read when it is asked for."""
        self._index(key)
        self._later.add(key[1])

    def read_all(self) -> None:
        """Reads every row still known by its key alone."""
        for day in sorted(self._later):
            self._read(day)

    def _read(self, day: str) -> None:
        assert self._fetch is not None, "a row known by its key alone needs a reader"
        rows = self._fetch(day)
        self._later.discard(day)
        for v, row in rows:
            if (v, day) in self and (v, day) not in self._rows:
                self._rows[(v, day)] = row

    def __contains__(self, key: object) -> bool:
        return isinstance(key, tuple) and len(key) == 2 and key[1] in self._by_vehicle.get(key[0], ())

    def __getitem__(self, key: Tuple[str, str]) -> Row:
        row = self._rows.get(key)
        if row is None:
            if key[1] not in self._later or key not in self:
                raise KeyError(key)
            self._read(key[1])
            row = self._rows[key]
        return row

    def __setitem__(self, key: Tuple[str, str], row: Row) -> None:
        self.load(key, row)
        self.changed_keys.add(key)
        self.changed_days.add(key[1])
        self.derived_days.add(key[1])

    def __delitem__(self, key: Tuple[str, str]) -> None:
        if key not in self:
            raise KeyError(key)
        self.unload(key)
        self.changed_keys.add(key)

    def unload(self, key: Tuple[str, str]) -> None:
        """Takes a row out as a committed part does (its day counts as changed, the key not:
        the part already holds the deletion)."""
        if key in self:
            self._rows.pop(key, None)
            days = self._by_vehicle[key[0]]
            days.discard(key[1])
            if not days:
                del self._by_vehicle[key[0]]
            self._count -= 1
        self.changed_days.add(key[1])
        self.derived_days.add(key[1])

    def __iter__(self) -> Iterator[Tuple[str, str]]:
        return ((v, d) for v, ds in list(self._by_vehicle.items()) for d in list(ds))

    def __len__(self) -> int:
        return self._count

    def held(self) -> int:
        """How many rows are in memory (read from their day files, or set)."""
        return len(self._rows)

    def days_of(self, vehicle: str) -> List[str]:
        """The vehicle's days, sorted."""
        return sorted(self._by_vehicle.get(vehicle, ()))

    def vehicles_on(self, day: str) -> List[str]:
        """The vehicles with a row on ``day``, sorted (a pass over the vehicles)."""
        return sorted(v for v, ds in self._by_vehicle.items() if day in ds)


@dataclass
class Store:
    """A store in memory: rows by ``(vehicle, day)``, the last run's other problems, and the
    manifest it was read from (what the next commit starts from)."""

    path: str
    rows: Rows = field(default_factory=Rows)
    run_problems: List[Tuple[str, str, str]] = field(default_factory=list)
    #: The committed day files: day -> digest of its rows.
    day_files: Dict[str, str] = field(default_factory=dict)
    #: The committed parts (not yet folded into the day files): file, digest, deleted keys.
    parts: List[Dict[str, Any]] = field(default_factory=list)
    #: The last commit's number.
    seq: int = 0
    #: Read from a single-file ``state.parquet`` (the first commit rewrites it as day files).
    legacy: bool = False
    #: The digest of the state ``events.parquet`` and ``problems.parquet`` were made from, when
    #: they are this store's (the rows of ``rows.derived_days`` changed since), and the run
    #: problems they hold: what lets a commit update them instead of making them anew.
    derived_digest: Optional[str] = None
    derived_run_problems: List[Tuple[str, str, str]] = field(default_factory=list)
    #: The derived tables as the last commit wrote them.
    written: Optional[Tuple[Any, Any]] = None
    #: Read without the monitor states (``open_store(states=False)``): not to be committed.
    without_states: bool = False

    def days(self, vehicle: str) -> List[str]:
        """The vehicle's stored days, sorted."""
        return self.rows.days_of(vehicle)

    # --- tables ---------------------------------------------------------------------------

    def state_table(self) -> Any:
        """``state.parquet`` as a pyarrow table (sorted by vehicle, day)."""
        return _state_table(self.rows, sorted(self.rows))

    def events_table(self) -> Any:
        """``events.parquet`` as a pyarrow table: every stored event, sorted by vehicle, day, t."""
        return self._events_of(sorted(self.rows))

    def problems_table(self) -> Any:
        """``problems.parquet`` as a pyarrow table: the stored days that could not be used,
        then the last run's other problems."""
        return self._problems_of(sorted(self.rows), sorted(self.run_problems))

    def _events_of(self, keys: Iterable[Tuple[str, str]]) -> Any:
        pa = module("pyarrow")

        cols: Dict[str, List[Any]] = {k: [] for k in EVENT_COLUMNS}
        for (v, d) in keys:
            for ev in self.rows[(v, d)].info().get("events", []):
                cols["vehicle"].append(v)
                cols["day"].append(d)
                for k in EVENT_COLUMNS[2:]:
                    cols[k].append(ev[k])
        return pa.table({k: pa.array(cols[k], t) for k, t in _event_types().items()})

    def _problems_of(self, keys: Iterable[Tuple[str, str]], others: List[Tuple[str, str, str]]) -> Any:
        pa = module("pyarrow")

        rows = [(v, d, p) for (v, d) in keys if (p := self.rows[(v, d)].info().get("problem")) is not None]
        rows += others
        return pa.table({"vehicle": pa.array([r[0] for r in rows], pa.string()),
                         "day": pa.array([r[1] for r in rows], pa.string()),
                         "reason": pa.array([r[2] for r in rows], pa.string())})

    def derived_tables(self) -> Tuple[Any, Any]:
        """The events and problems tables: as the last commit wrote them, else made now."""
        return self.written if self.written is not None else (self.events_table(), self.problems_table())

    def digest(self) -> str:
        """SHA-256 of the committed state (the day files' and parts' digests and the run's
        problems): what the derived tables were made from."""
        return _state_digest(self.day_files, self.parts, self.run_problems)

    # --- writing --------------------------------------------------------------------------

    def commit(self, final: bool = True) -> None:
        """Commits the rows changed since the last commit. ``final`` (a run's last commit):
        the day files they fall on are rewritten (with the parts before them), then
        ``events.parquet`` and ``problems.parquet``; otherwise they go into one new part."""
        if self.without_states:
            raise StoreError(f"{self.path}: opened without its states (open_store(states=False)), so it cannot be "
                             "committed: open it with its states")
        try:
            os.makedirs(self.path, exist_ok=True)
        except OSError as e:
            raise StoreError(f"--store {self.path}: cannot create the directory ({e.strerror or e})") from None
        sp = os.path.join(self.path, STATE)
        if self.legacy or os.path.isfile(sp):
            self._convert(sp)
        else:
            os.makedirs(sp, exist_ok=True)
            self._sweep(sp)
            if final:
                self._commit_days(sp)
            else:
                self._commit_part(sp)
        if final:
            self._write_derived(self.digest().encode())

    def _manifest(self, pending: List[List[str]], remove: List[str]) -> Dict[str, Any]:
        return {"format": FORMAT, "seq": self.seq, "days": dict(sorted(self.day_files.items())),
                "parts": self.parts, "run_problems": sorted(list(p) for p in self.run_problems),
                "pending": pending, "remove": remove}

    def _write_rows(self, path: str, keys: List[Tuple[str, str]]) -> str:
        """Writes the rows ``keys`` as a state file at ``path`` (flushed, not renamed) and
        returns their digest, which the file's metadata holds too."""
        digest = _rows_digest(self.rows, keys)
        _write_file(path, _parquet(_state_table(self.rows, keys), {_FILE_DIGEST: digest.encode()}))
        return digest

    def _publish(self, sp: str, day_files: Dict[str, str], parts: List[Dict[str, Any]],
                 pending: List[List[str]], remove: List[str]) -> None:
        """Commits: the next manifest, with these day files and parts (and the renames and
        removals that put its files in place), written over the last one; the store in memory
        is as it was if that fails."""
        old = self.day_files, self.parts, self.seq
        self.day_files, self.parts, self.seq = day_files, parts, self.seq + 1
        try:
            _write_json(os.path.join(sp, MANIFEST), self._manifest(pending, remove))
        except BaseException:
            self.day_files, self.parts, self.seq = old
            raise

    def _commit_part(self, sp: str) -> None:
        if not self.rows.changed_keys:
            return
        keys = sorted(k for k in self.rows.changed_keys if k in self.rows)
        deleted = sorted(list(k) for k in self.rows.changed_keys if k not in self.rows)
        name = f"_part-{self.seq + 1:06d}.parquet"  # no manifest lists it until it is published
        try:
            digest = self._write_rows(os.path.join(sp, name), keys) if keys else _rows_digest(self.rows, [])
            self._publish(sp, self.day_files, self.parts + [{"file": name if keys else None, "digest": digest,
                                                              "deleted": deleted}], [], [])
        except BaseException:
            _remove(os.path.join(sp, name))
            raise
        self.rows.changed_keys.clear()

    def _commit_days(self, sp: str) -> None:
        days = dict(self.day_files)
        pending: List[List[str]] = []
        remove = [p["file"] for p in self.parts if p["file"] is not None]
        try:
            for day in sorted(self.rows.changed_days):
                vehicles = self.rows.vehicles_on(day)
                if vehicles:
                    pending.append([f".{day}.parquet.tmp-{self.seq + 1}", f"{day}.parquet"])
                    days[day] = self._write_rows(os.path.join(sp, pending[-1][0]), [(v, day) for v in vehicles])
                elif day in days:
                    del days[day]
                    remove.append(f"{day}.parquet")
            self._publish(sp, days, [], pending, remove)
        except BaseException:
            for tmp, _ in pending:
                _remove(os.path.join(sp, tmp))
            raise
        _apply(sp, pending, remove)
        self.rows.changed_keys.clear()
        self.rows.changed_days.clear()

    def _convert(self, sp: str) -> None:
        """Rewrites a single-file ``state.parquet`` as the directory of day files: the whole
        directory is made beside it, then swapped in (the file kept as ``.state.parquet.v1``
        until the directory is in place; :func:`open_store` finishes a swap a crash cut)."""
        new, old = os.path.join(self.path, _SWAP), os.path.join(self.path, _LEGACY)
        shutil.rmtree(new, ignore_errors=True)
        os.makedirs(new)
        days = {day: self._write_rows(os.path.join(new, f"{day}.parquet"),
                                      [(v, day) for v in self.rows.vehicles_on(day)])
                for day in sorted({d for _, d in self.rows})}
        self._publish(new, days, [], [], [])
        if os.path.isfile(sp):
            os.replace(sp, old)
        os.rename(new, sp)
        _fsync_dir(self.path)
        _remove(old)
        self.legacy = False
        self.rows.changed_keys.clear()
        self.rows.changed_days.clear()

    def _sweep(self, sp: str) -> None:
        """Removes what a process killed while writing left: temporary files (in the store
        and in ``state.parquet``), and parts no manifest lists."""
        listed = {p["file"] for p in self.parts}
        for directory in (self.path, sp):
            for name in os.listdir(directory):
                if (name.startswith(".") and ".tmp-" in name) or (name.startswith("_part-") and name not in listed):
                    _remove(os.path.join(directory, name))

    def _write_derived(self, digest: bytes) -> None:
        tables = self._derived_update() if self.derived_digest is not None else None
        if tables is None:
            self.rows.read_all()
            tables = self.events_table(), self.problems_table()
        write_atomic(tables[0], os.path.join(self.path, EVENTS), {_DIGEST: digest})
        write_atomic(tables[1], os.path.join(self.path, PROBLEMS), {_DIGEST: digest})
        self.derived_digest, self.derived_run_problems = digest.decode(), sorted(self.run_problems)
        self.rows.derived_days.clear()
        self.written = tables

    def _derived_update(self) -> Optional[Tuple[Any, Any]]:
        """The events and problems tables from those on disk (when they are those of
        ``derived_digest``): their rows of the days changed since replaced by those days' rows
        now, the run problems by this run's. The same tables as made anew, row for row."""
        pa, pc, pq = module("pyarrow"), module("pyarrow.compute"), module("pyarrow.parquet")

        try:
            old = [pq.read_table(os.path.join(self.path, name)) for name in (EVENTS, PROBLEMS)]
        except Exception:
            return None
        if any((t.schema.metadata or {}).get(_DIGEST) != (self.derived_digest or "").encode() for t in old):
            return None
        days = sorted(self.rows.derived_days)
        keys = [(v, d) for d in days for v in self.rows.vehicles_on(d)]
        changed = pa.array(days, pa.string())
        by_key = [("vehicle", "ascending"), ("day", "ascending")]  # a stable sort: t's order stays

        def update(kept: Any, new: Any) -> Any:
            kept = kept.replace_schema_metadata(None)
            kept = kept.filter(pc.invert(pc.is_in(kept.column("day"), value_set=changed)))
            return pa.concat_tables([kept, new]).sort_by(by_key).combine_chunks()

        events = update(old[0], self._events_of(keys))
        stored = old[1].slice(0, old[1].num_rows - len(self.derived_run_problems))
        problems = pa.concat_tables([update(stored, self._problems_of(keys, [])),
                                     self._problems_of([], sorted(self.run_problems))]).combine_chunks()
        return events, problems


#: The events table's columns, in order.
EVENT_COLUMNS = ("vehicle", "day", "t", "parameter", "before", "after", "low", "high", "corner", "t_change", "change")


def _event_types() -> Dict[str, Any]:
    pa = module("pyarrow")

    f, s = pa.float64(), pa.string()
    return {"vehicle": s, "day": s, "t": f, "parameter": s, "before": f, "after": f, "low": f, "high": f,
            "corner": s, "t_change": f, "change": f}


def _state_table(rows: Any, keys: List[Tuple[str, str]]) -> Any:
    pa = module("pyarrow")

    got = [rows[k] for k in keys]
    return pa.table({
        "vehicle": pa.array([k[0] for k in keys], pa.string()),
        "day": pa.array([k[1] for k in keys], pa.string()),
        "vehid_version": pa.array([r.vehid_version for r in got], pa.string()),
        "state": pa.array([r.state for r in got], pa.binary()),
        "summary": pa.array([r.summary for r in got], pa.string()),
    })


def _rows_digest(rows: Any, keys: List[Tuple[str, str]]) -> str:
    """SHA-256 of the rows ``keys`` (in that order)."""
    h = hashlib.sha256()
    for v, d in keys:
        r = rows[(v, d)]
        for part in (v, d, r.vehid_version, r.summary):
            h.update(part.encode() + b"\0")
        h.update(b"\1" + r.state if r.state is not None else b"\0")
    return h.hexdigest()


def _state_digest(days: Dict[str, str], parts: List[Dict[str, Any]], run_problems: Iterable[Any]) -> str:
    text = json.dumps({"days": sorted(days.items()), "parts": [[p["digest"], p["deleted"]] for p in parts],
                       "run_problems": sorted(list(p) for p in run_problems)})
    return hashlib.sha256(text.encode()).hexdigest()


def _remove(path: str) -> None:
    try:
        os.remove(path)
    except FileNotFoundError:
        pass


def _fsync_dir(path: str) -> None:
    """Flushes a directory's entries (a rename's durability) where the system allows it."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _write_file(path: str, write: Callable[[str], None], final: Optional[str] = None) -> None:
    """Writes a file with ``write(path)`` and flushes it to disk; with ``final``, renames it
    there (atomic: ``final`` is as it was until then). On any failure no file of this write
    is left."""
    try:
        write(path)
        with open(path, "rb+") as f:
            os.fsync(f.fileno())
        if final is not None:
            os.replace(path, final)
            _fsync_dir(os.path.dirname(final))
    except BaseException as e:
        _remove(path)
        if isinstance(e, OSError):
            raise StoreError(f"{final or path}: cannot write ({e.strerror or e})") from None
        raise


def _parquet(table: Any, metadata: Dict[bytes, bytes]) -> Callable[[str], None]:
    """Writes ``table`` with ``metadata`` added to its own, as a Parquet file."""
    pq = module("pyarrow.parquet")

    table = table.replace_schema_metadata({**(table.schema.metadata or {}), **metadata})
    return lambda path: pq.write_table(table, path, compression="zstd")


def _temporary(path: str) -> str:
    """The temporary name of an atomic write of ``path`` (readers skip names starting with
    ``.``; the pid keeps two processes' apart)."""
    directory, name = os.path.split(path)
    return os.path.join(directory, f".{name}.tmp-{os.getpid()}")


def write_atomic(table: Any, path: str, metadata: Dict[bytes, bytes]) -> None:
    """Writes ``table`` to ``path`` atomically: a temporary file in the same directory,
    flushed to disk, then renamed over ``path``. On any failure ``path`` is as it was and the
    temporary file is removed."""
    _write_file(_temporary(path), _parquet(table, metadata), final=path)


def _write_json(path: str, obj: Any) -> None:
    """Writes ``obj`` as JSON to ``path`` atomically (as :func:`write_atomic`)."""

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(obj, f, indent=1)

    _write_file(_temporary(path), write, final=path)


def _apply(sp: str, pending: List[List[str]], remove: List[str]) -> None:
    """Puts a committed manifest's files in place: renames its new files (those not yet
    renamed; another process opening the store may do the same at the same time) and removes
    the files it no longer lists."""
    for tmp, final in pending:
        try:
            os.replace(os.path.join(sp, tmp), os.path.join(sp, final))
        except FileNotFoundError:
            pass
    for name in remove:
        _remove(os.path.join(sp, name))
    _fsync_dir(sp)


def _finish_swap(path: str) -> None:
    """Completes (or undoes) a conversion of a single-file state a crash cut short."""
    sp, new, old = (os.path.join(path, n) for n in (STATE, _SWAP, _LEGACY))
    if os.path.exists(old):
        if not os.path.exists(sp):
            if os.path.isfile(os.path.join(new, MANIFEST)):
                os.rename(new, sp)
            else:
                os.replace(old, sp)
        if os.path.isdir(sp):
            _remove(old)
    if os.path.isdir(new) and os.path.exists(sp):
        shutil.rmtree(new, ignore_errors=True)


def _damaged(where: str, why: str) -> StoreError:
    return StoreError(f"{where}: {why}: the store is damaged; restore it from a backup, or remove the store to "
                      "recompute it from the logs")


def _read(path: str, digest: Optional[str], columns: Optional[List[str]] = None) -> Any:
    """A state file (``columns`` of it), checked against the digest its manifest gives."""
    pq = module("pyarrow.parquet")

    try:
        schema = pq.read_schema(path)
        if not set(_STATE_COLUMNS) <= set(schema.names):
            raise StoreError(f"{path}: not a fleet state table (columns {', '.join(schema.names)})")
        if digest is not None and (schema.metadata or {}).get(_FILE_DIGEST) != digest.encode():
            raise _Moved(path)
        return pq.read_table(path, columns=columns)
    except (StoreError, _Moved):
        raise
    except Exception as e:
        raise _damaged(path, f"not readable ({str(e).splitlines()[0]})") from None


class _Moved(Exception):
    """A file is not the one the manifest read names (a commit moved on meanwhile)."""


def _load_table(store: Store, table: Any, changed: bool) -> None:
    """Puts a file's rows into ``store``; ``changed``: their days count as changed (a part's
    rows, which the next commit of the day files takes in)."""
    d = table.to_pydict()
    states = d["state"] if "state" in d else [None] * table.num_rows
    for v, day, ver, st, su in zip(d["vehicle"], d["day"], d["vehid_version"], states, d["summary"]):
        store.rows.load((v, day), Row(ver, st, su))
        if changed:
            store.rows.changed_days.add(day)


def _rows_of(table: Any, day: str) -> List[Tuple[str, Row]]:
    d = table.to_pydict()
    return [(v, Row(ver, st, su)) for v, ver, st, su in zip(d["vehicle"], d["vehid_version"], d["state"], d["summary"])]


def _fetcher(sp: str, opened: Dict[str, str]) -> Callable[[str], List[Tuple[str, Row]]]:
    """Reads a day file's rows, checked against the digest ``opened`` (the manifest) gives."""

    def fetch(day: str) -> List[Tuple[str, Row]]:
        file = os.path.join(sp, f"{day}.parquet")
        try:
            return _rows_of(_read(file, opened[day]), day)
        except _Moved:
            raise _damaged(file, f"changed since the store was opened (its digest is not the one {MANIFEST} "
                                 "gave): was another process writing it?") from None

    return fetch


def _load_dir(path: str, lazy: bool, states: bool) -> Store:
    sp = os.path.join(path, STATE)
    manifest = os.path.join(sp, MANIFEST)
    columns = None if states else [c for c in _STATE_COLUMNS if c != "state"]
    for attempt in range(5):
        store = Store(path=path, without_states=not states)
        opened: Dict[str, str] = {}  # the day files as the manifest read lists them
        if lazy:
            store.rows = Rows(_fetcher(sp, opened))
        if not os.path.exists(manifest):
            if any(n.endswith(".parquet") and not n.startswith((".", "_")) for n in os.listdir(sp)):
                raise _damaged(sp, f"no {MANIFEST} beside its files")
            return store
        try:
            with open(manifest, encoding="utf-8") as f:
                man = json.load(f)
            if man.get("format") != FORMAT:
                raise StoreError(f"{manifest}: store format {man.get('format')!r}; this vehid ({_version()}) "
                                 f"reads format {FORMAT}: use the vehid that wrote it, or remove the store to "
                                 "recompute it from the logs")
            _apply(sp, man["pending"], man["remove"])
            store.seq, store.day_files, store.parts = int(man["seq"]), dict(man["days"]), list(man["parts"])
            store.run_problems = [(str(p[0]), str(p[1]), str(p[2])) for p in man["run_problems"]]
            opened.update(store.day_files)
            for day, digest in store.day_files.items():
                file = os.path.join(sp, f"{day}.parquet")
                if lazy:  # the keys now (each vehicle's name held once), the rows when asked for
                    for v in _read(file, digest, ["vehicle"]).column("vehicle").to_pylist():
                        store.rows.load_later((sys.intern(v), day))
                else:
                    _load_table(store, _read(file, digest, columns), changed=False)
            for part in store.parts:  # rows committed in the middle of a run: the next commit folds them
                if part["file"] is not None:
                    _load_table(store, _read(os.path.join(sp, part["file"]), part["digest"], columns), changed=True)
                for v, day in part["deleted"]:
                    store.rows.unload((v, day))
            return store
        except _Moved as e:
            if attempt == 4:
                raise _damaged(str(e), f"not the file {MANIFEST} lists (its digest differs)") from None
        except StoreError:
            raise
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise _damaged(manifest, f"not a manifest ({type(e).__name__}: {e})") from None
    raise AssertionError("unreachable")


def _version() -> str:
    from .. import __version__

    return __version__


def _load_file(path: str) -> Store:
    """A single-file ``state.parquet`` (before the day files): every row counts as changed,
    so that the first commit writes the day files."""
    sp = os.path.join(path, STATE)
    store = Store(path=path, legacy=True)
    table = _read(sp, None)
    _load_table(store, table, changed=False)
    meta = table.schema.metadata or {}
    store.run_problems = [(str(p[0]), str(p[1]), str(p[2])) for p in json.loads(meta.get(_RUN_PROBLEMS, b"[]"))]
    return store


def open_store(path: str, lazy: bool = False, states: bool = True) -> Store:
    """Reads the store at ``path`` (an empty store if it has no ``state.parquet`` yet),
    finishing a commit a crash cut after its manifest, and rewrites its events and problems
    tables if they are not those of its state (unless a run in another process holds the
    store: it updates them at its last commit). ``lazy``: the day files' rows are read when
    first asked for (their keys now), so that a run holds what it reads and writes, not the
    whole history (a run holds the store's lock: nothing else writes it meanwhile).
    ``states=False``: every row without its monitor state (``state`` None), for what reads the
    summaries alone (the report); such a store cannot be committed.
    :class:`StoreError` for a directory that is not a store or a damaged state."""
    if os.path.exists(path) and not os.path.isdir(path):
        raise StoreError(f"--store {path}: is a file; give a directory (created if missing)")
    if os.path.isdir(path):
        _finish_swap(path)
    sp = os.path.join(path, STATE)
    if os.path.isfile(sp):
        store = _load_file(path)
    elif os.path.isdir(sp):
        store = _load_dir(path, lazy, states)
    else:
        if os.path.isdir(path) and any(not n.startswith(".") for n in os.listdir(path)):
            others = sorted(os.listdir(path))[:5]
            if not set(others) <= {EVENTS, PROBLEMS} and not all(".tmp-" in n for n in others):
                raise StoreError(f"--store {path}: a directory that is not a fleet store (it holds "
                                 f"{', '.join(others)}, no {STATE}): give an empty or new directory")
        return Store(path=path)
    if not store.legacy:
        digest = store.digest()
        if all(_digest_of(os.path.join(path, name)) == digest.encode() for name in (EVENTS, PROBLEMS)):
            store.derived_digest, store.derived_run_problems = digest, sorted(store.run_problems)
        elif not _run_elsewhere(path):
            store._write_derived(digest.encode())
        # else a run in another process is between its commits: it updates the tables at its
        # last commit from the files as they are (the tables of this store are its rows').
    return store


def _run_elsewhere(path: str) -> bool:
    """Whether another live process holds the store's lock (a run between its commits)."""
    try:
        with open(os.path.join(path, LOCK)) as f:
            pid = int(f.read().strip() or 0)
    except (OSError, ValueError):
        return False
    if pid <= 0 or pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # alive, another user's
        return True
    return True


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

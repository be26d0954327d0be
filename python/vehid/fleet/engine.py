"""Running the fold over a fleet: which vehicle-days to process (resume), the engines (a
thread pool, or Dask), and the commits to the store.

Each vehicle's new days are one chain, processed in order inside one task; tasks hold a batch
of vehicles so that a scheduler sees few, long tasks. A task is a pure function of its input
(settings, the last stored state, the day files), so its result is the same bytes whichever
engine, worker or retry runs it, and a task lost with its worker is simply run again.
"""

from __future__ import annotations

import datetime
import functools
import json
import math
import os
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Optional, Tuple

from .. import __version__
from ._deps import module
from .config import ConfigError, VehicleConfig, load_config
from .fold import DayError, fold, summary_json
from .layout import CONFIG, read_day, scan
from .store import LOCK, Row, Store, StoreError, open_store

#: Seconds between two commits of a long run (a crash loses at most this much work).
COMMIT_EVERY = 60.0

#: One vehicle's chain: id, settings, the last stored state (None: none), its new days and files.
Task = Tuple[str, VehicleConfig, Optional[bytes], List[Tuple[str, List[str]]]]
#: What a task returns per vehicle: id, [(day, row)], seconds of logs read.
Done = Tuple[str, List[Tuple[str, Row]], float]
#: ``progress(done, total)``: vehicle-days processed so far and in all.
Progress = Callable[[int, int], None]


@dataclass
class FleetResult:
    """What :func:`run` did and the store after it."""

    #: The store's directory.
    store: str
    #: ``events.parquet``: vehicle, day, t (s from the day's start), parameter, before, after, low, high,
    #: corner, t_change (s), change (relative).
    events: Any
    #: ``problems.parquet``: vehicle, day, reason.
    problems: Any
    #: Vehicle-days processed by this run.
    processed: int
    #: Seconds of logs read by this run (vehicle-hours × 3600).
    log_seconds: float
    #: Wall time of the run, s.
    elapsed: float

    @functools.cached_property
    def states(self) -> Any:
        """``state.parquet``: vehicle, day, vehid_version, state, summary (sorted by vehicle,
        day), read from the store when first asked for (it holds every stored day, which the
        run itself does not read)."""
        return open_store(self.store).state_table()


def run_chain(task: Task) -> Done:
    """Folds one vehicle's new days in order. A day that cannot be used is stored with its
    reason as the problem and the state as it was (no state lost); the chain continues."""
    vid, config, state, days = task
    rows: List[Tuple[str, Row]] = []
    seconds = 0.0
    for day, files in days:
        try:
            res = fold(state, read_day(files), config)
        except DayError as e:
            summary = {"problem": str(e), "events": [], "config": config.fingerprint()}
            rows.append((day, Row(__version__, state, summary_json(summary))))
            continue
        except Exception as e:  # a bug must cost one vehicle-day, not the fleet's run
            summary = {"problem": f"internal error: {type(e).__name__}: {e} (a bug in vehid: please report it)",
                       "events": [], "config": config.fingerprint()}
            rows.append((day, Row(__version__, state, summary_json(summary))))
            continue
        state = res.state
        seconds += res.summary["seconds"]
        rows.append((day, Row(__version__, state, summary_json({**res.summary, "events": res.events}))))
    return vid, rows, seconds


def run_batch(tasks: List[Task]) -> List[Done]:
    """The chains of a batch of vehicles, one after the other (what an engine's task runs)."""
    return [run_chain(t) for t in tasks]


def _check_day(text: str, what: str) -> str:
    try:
        if datetime.date.fromisoformat(text).isoformat() == text:
            return text
    except ValueError:
        pass
    raise ValueError(f"{what}={text!r}: expected a day YYYY-MM-DD, e.g. 2026-01-31")


def plan(fleet: str, store: Store, since: Optional[str] = None) -> Tuple[List[Task], List[Tuple[str, str, str]]]:
    """The chains to run and the run's problems: per vehicle of the dataset, its days after
    its last stored day (all of them from ``since`` on, when given: those stored are replaced)."""
    config = load_config(os.path.join(fleet, CONFIG))
    ds = scan(fleet)
    problems = list(ds.problems)
    tasks: List[Task] = []
    for vid, days in ds.vehicles.items():
        try:
            vc = config.vehicle(vid)
        except ConfigError as e:
            problems.append((vid, "", str(e)))
            continue
        stored = store.days(vid)
        if since is not None:
            stored = [d for d in stored if d < since]
        last = stored[-1] if stored else None
        if last is not None:
            row = store.rows[(vid, last)]
            fp = json.loads(row.summary).get("config")
            if fp is not None and fp != vc.fingerprint():
                problems.append((vid, last, f"fleet.toml changed for this vehicle after {last}: its new days wait; "
                                            f"rerun with --from {stored[0]} (since={stored[0]!r}) to apply it"))
                continue
        have = set(stored)
        late = [d for d, _ in days if last is not None and d <= last and d not in have]
        for d in late:
            problems.append((vid, d, f"day out of order: it arrived after {last} was processed, so it is not in "
                                     f"this vehicle's chain; rerun with --from {d} (since={d!r}) to include it"))
        new = [(d, f) for d, f in days if last is None or d > last]
        if new:
            tasks.append((vid, vc, store.rows[(vid, last)].state if last is not None else None, new))
    return tasks, problems


class _Lock:
    """``STORE/.lock``: one run at a time per store (a lock left by a dead process is taken over)."""

    def __init__(self, path: str) -> None:
        self.path = os.path.join(path, LOCK)

    def __enter__(self) -> _Lock:
        for _ in range(2):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            except FileExistsError:
                try:
                    with open(self.path) as f:
                        pid = int(f.read().strip() or 0)
                    os.kill(pid, 0)
                except (ValueError, ProcessLookupError, FileNotFoundError):
                    try:
                        os.remove(self.path)  # stale: its process is gone
                    except FileNotFoundError:
                        pass
                    continue
                except PermissionError:
                    pass
                raise StoreError(f"{self.path}: another vehid fleet run (pid {pid}) is using this store; wait for it, "
                                 "or remove the file if that process is not vehid") from None
            with os.fdopen(fd, "w") as f:
                f.write(str(os.getpid()))
            return self
        raise StoreError(f"{self.path}: cannot take the store's lock")

    def __exit__(self, *exc: Any) -> None:
        try:
            os.remove(self.path)
        except FileNotFoundError:
            pass


def _batches(tasks: List[Task], size: int) -> List[List[Task]]:
    return [tasks[i : i + size] for i in range(0, len(tasks), size)]


def run(fleet: str, store: str, client: Any = None, workers: Optional[int] = None, *, since: Optional[str] = None,
        batch: Optional[int] = None, progress: Optional[Progress] = None,
        commit_every: float = COMMIT_EVERY) -> FleetResult:
    """Runs the health monitor over the fleet at ``fleet`` (``DIR/fleet.toml`` and
    ``DIR/vehicle=<id>/day=<YYYY-MM-DD>/*.parquet``) into the store at ``store`` (a directory,
    created if missing), and returns what it did with the store's tables.

    Each vehicle resumes after its last stored day; ``since`` (``"YYYY-MM-DD"``) recomputes
    every vehicle's days from that day on, replacing them (the same logs give the same rows).
    ``client``: a ``dask.distributed.Client`` (the work runs on its cluster; the fleet and the
    store must be paths its workers can read); else a local pool of ``workers`` threads
    (default: the number of CPUs). ``batch``: vehicles per task (default: one locally; on
    Dask about four tasks per worker, at most 64 vehicles). ``progress(done, total)`` is called
    with the vehicle-days processed. The store is committed every ``commit_every`` seconds of
    wall time and at the end.

    Raises ``ValueError`` (:class:`~vehid.fleet.config.ConfigError`,
    :class:`~vehid.fleet.store.StoreError`) for a bad argument, fleet file or store; bad data
    is recorded in the store's problems table and never raises."""
    t_start = time.perf_counter()
    if client is not None and workers is not None:
        raise ValueError("workers= is for the local engine; with client= the cluster's workers run the tasks")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise ValueError(f"workers={workers!r}: expected a number of threads >= 1")
    if batch is not None and (not isinstance(batch, int) or batch < 1):
        raise ValueError(f"batch={batch!r}: expected a number of vehicles per task >= 1")
    if since is not None:
        since = _check_day(since, "since")
    module("pyarrow.parquet")  # a missing extra before anything is created
    scan(fleet)  # the fleet's errors before the store is created
    load_config(os.path.join(fleet, CONFIG))
    if os.path.exists(store) and not os.path.isdir(store):
        raise StoreError(f"--store {store}: is a file; give a directory (created if missing)")
    try:
        os.makedirs(store, exist_ok=True)
    except OSError as e:
        raise StoreError(f"--store {store}: cannot create the directory ({e.strerror or e})") from None
    with _Lock(store):  # (what a process killed while writing left behind goes at the commit)
        st = open_store(store, lazy=True)
        tasks, problems = plan(fleet, st, since)
        if since is not None:  # the days recomputed are replaced; a vehicle left out keeps its rows
            chained = {t[0] for t in tasks}
            for key in [k for k in st.rows if k[0] in chained and k[1] >= since]:
                del st.rows[key]
        st.run_problems = problems
        total = sum(len(t[3]) for t in tasks)
        n_workers = workers or (len(_dask_workers(client)) if client is not None else os.cpu_count() or 1)
        # Locally a task is one vehicle (threads cost nothing to start); on Dask about four
        # tasks per worker, so that the scheduler sees few, long tasks.
        size = batch or (max(1, min(64, math.ceil(len(tasks) / (4 * max(1, n_workers))))) if client is not None
                         else 1)
        done_days = 0
        seconds = 0.0
        last_commit = time.monotonic()
        if progress is not None:
            progress(0, total)

        def take(results: List[Done]) -> None:
            nonlocal done_days, seconds, last_commit
            for vid, rows, secs in results:
                for day, row in rows:
                    st.rows[(vid, day)] = row
                done_days += len(rows)
                seconds += secs
            if progress is not None:
                progress(done_days, total)
            if time.monotonic() - last_commit > commit_every:
                st.commit(final=False)
                last_commit = time.monotonic()

        batches = _batches(tasks, size)
        if client is not None:
            _run_dask(client, batches, take)
        else:
            _run_local(n_workers, batches, take)
        st.commit()
    events, problems = st.derived_tables()
    return FleetResult(store=store, events=events, problems=problems, processed=done_days, log_seconds=seconds,
                       elapsed=time.perf_counter() - t_start)


def _run_local(workers: int, batches: List[List[Task]], take: Callable[[List[Done]], None]) -> None:
    if workers == 1:
        for b in batches:
            take(run_batch(b))
        return
    with ThreadPoolExecutor(max_workers=workers) as pool:
        pending = {pool.submit(run_batch, b) for b in batches}
        try:
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in sorted(finished, key=id):
                    take(f.result())
        except BaseException:
            for f in pending:
                f.cancel()
            raise


def _dask_workers(client: Any) -> Dict[str, Any]:
    try:
        workers: Dict[str, Any] = client.scheduler_info()["workers"]
    except Exception as e:
        raise ValueError(f"client={client!r}: not a connected dask.distributed Client ({e})") from None
    return workers


def _run_dask(client: Any, batches: List[List[Task]], take: Callable[[List[Done]], None]) -> None:
    as_completed = module("distributed").as_completed

    _dask_workers(client)
    futures = [client.submit(run_batch, b, pure=False, key=f"vehid-fleet-{i}-{os.getpid()}-{time.time_ns()}")
               for i, b in enumerate(batches)]
    try:
        for f in as_completed(futures):
            take(f.result())
    except BaseException:
        client.cancel(futures)
        raise

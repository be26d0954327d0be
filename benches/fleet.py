"""Fleet figures: end-to-end throughput and a fleet detection run.

``throughput``: a simulated fleet (``--vehicles`` × 1 day × ``--hours``) written as Parquet,
then, ``--repeats`` times in turn on the same data: the monitor's raw speed (each
vehicle-day's samples already in memory, ``HealthMonitor.fit`` in one call; one thread, and
``--workers`` threads), the local engine end to end (read Parquet → monitor → write the store)
with ``--workers`` threads, and the Dask engine on a ``LocalCluster`` of ``--workers`` worker
processes (its start not counted). Figures in vehicle-hours of 200 Hz logs per second; the
medians over the repeats, and end to end against raw × cores. Then, on paper, the cluster for
``--paper-vehicles`` vehicles driving ``--paper-hours`` a day for a year.

``detect``: ``--vehicles`` vehicles × ``--days`` × ``--hours`` (``--faults`` of them with one
injected fault, fresh seeds from ``--seed``), simulated in parts of ``--part`` vehicles,
each part run through ``vehid.fleet.run`` into one store and then deleted (the logs of 1,000
vehicle-hours would take ~20 GB). Scores the store's events against ``truth.parquet``: a
fault is found when an event names its constant within ``--window`` s after it (recall); an
event is right when it is such a first match (precision); false alarms per 10 h are the
events on fault-free driving (vehicles without a fault, the time before a fault, and the days
after it: the car does not change again).

``store``: what a commit costs as the store's history grows, without logs or the monitor: a
store of ``--vehicles`` vehicles × ``--days`` days of rows the size of real ones (a 2.7 kB
state, a 2.7 kB summary; random, seeded), committed, then ``--more`` further days, each
committed as a daily run would (the store opened as a run opens it, reading the rows it
asks for; ``--parts`` commits: those a long run makes every 60 s, in its middle, then its last
one): the seconds to open it and read each vehicle's last state, of the commits, the bytes
they wrote, and the stored rows read;
then the seconds to open the store reading every row (as the report does).

    .venv/bin/python benches/fleet.py throughput --vehicles 16 --hours 1 --workers 2 --seed 1
    .venv/bin/python benches/fleet.py detect --vehicles 1000 --hours 1 --faults 0.5 --seed 7100000
    .venv/bin/python benches/fleet.py store --vehicles 1000 --days 90 --more 3 --parts 10 --seed 1
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Dict, List, Tuple

import numpy as np
import pyarrow.parquet as pq

import vehid
import vehid.fleet as fleet
from vehid.fleet.cli import ProgressBar
from vehid.fleet.fold import day_arrays
from vehid.fleet.layout import read_day, scan
from vehid.fleet.simulate import simulate


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _load(src: str) -> List[Tuple[fleet.VehicleConfig, np.ndarray]]:
    cfg = fleet.load_config(os.path.join(src, "fleet.toml"))
    out = []
    for vid, days in scan(src).vehicles.items():
        vc = cfg.vehicle(vid)
        for _, files in days:
            out.append((vc, day_arrays(read_day(files), vc)[1]))
    return out


def _raw(data: List[Tuple[fleet.VehicleConfig, np.ndarray]], workers: int, cpu: List[float]) -> float:
    """Seconds to monitor every vehicle-day in memory, on ``workers`` threads (the CPU
    seconds this process spent appended to ``cpu``)."""
    mons = [vc.monitor_new() for vc, _ in data]
    c0 = time.process_time()
    t0 = time.perf_counter()
    if workers == 1:
        for m, (_, y) in zip(mons, data):
            m.fit(y)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(lambda k: mons[k].fit(data[k][1]), range(len(data))))
    el = time.perf_counter() - t0
    cpu.append(time.process_time() - c0)
    return el


def throughput(args: argparse.Namespace) -> None:
    import dask
    from distributed import Client, LocalCluster

    work = tempfile.mkdtemp(prefix="vehid-fleet-bench-")
    try:
        src = os.path.join(work, "fleet")
        t0 = time.perf_counter()
        simulate(src, args.vehicles, 1, args.hours, 0.3, args.seed, workers=args.workers,
                 progress=ProgressBar("simulate: vehicles"))
        size = sum(os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(src) for f in fs)
        _say(f"simulated {args.vehicles} vehicle-days × {args.hours:g} h in {time.perf_counter() - t0:.1f} s "
             f"({size / 1e6:.0f} MB of Parquet)")
        data = _load(src)
        hours = sum(len(y) for _, y in data) * 0.005 / 3600
        figures: Dict[str, List[float]] = {"raw 1 thread": [], f"raw {args.workers} threads": [],
                                           f"local {args.workers} threads": [], f"dask {args.workers} processes": []}
        # Dask's worker profiler samples every task's stack every 10 ms for the dashboard
        # (`--dask-profile off`: `distributed.worker.profile.enabled: false`, as a cluster's Dask
        # config may set it).
        with dask.config.set({"distributed.worker.profile.enabled": args.dask_profile == "on"}), \
                LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                             dashboard_address=":0") as cluster, Client(cluster) as client:
            client.run(lambda: None)  # the workers' first task (their imports) not counted
            cpu: Dict[str, List[float]] = {k: [] for k in figures}
            for r in range(args.repeats):
                figures["raw 1 thread"].append(hours / _raw(data, 1, cpu["raw 1 thread"]))
                figures[f"raw {args.workers} threads"].append(
                    hours / _raw(data, args.workers, cpu[f"raw {args.workers} threads"]))
                for name, kw in ((f"local {args.workers} threads", {"workers": args.workers}),
                                 (f"dask {args.workers} processes", {"client": client})):
                    store = os.path.join(work, "store")
                    shutil.rmtree(store, ignore_errors=True)
                    w0 = client.run(time.process_time)
                    c0 = time.process_time()
                    t1 = time.perf_counter()
                    res = fleet.run(src, store, **kw)
                    figures[name].append(res.log_seconds / 3600 / (time.perf_counter() - t1))
                    c1 = time.process_time() - c0
                    if "client" in kw:  # the workers' CPU seconds too
                        w1 = client.run(time.process_time)
                        c1 += sum(w1[w] - w0[w] for w in w1 if w in w0)
                    cpu[name].append(c1)
                _say(f"repeat {r + 1}/{args.repeats}: " + ", ".join(f"{k} {v[-1]:.1f}" for k, v in figures.items())
                     + " vehicle-hours/s; load average " + " ".join(f"{x:.1f}" for x in os.getloadavg()))
        med = {k: statistics.median(v) for k, v in figures.items()}
        raw1 = med["raw 1 thread"]
        state = pq.read_table(os.path.join(work, "store", "state.parquet"))
        per_day = sum(len(s or b"") + len(j) for s, j in zip(state.column("state").to_pylist(),
                                                            state.column("summary").to_pylist())) / state.num_rows
        print(f"\nThroughput, {hours:.1f} vehicle-hours of 200 Hz logs ({args.vehicles} vehicles, a fifth half cars), "
              f"{os.cpu_count()} CPUs, medians of {args.repeats} (vehid {vehid.__version__}, seed {args.seed}; "
              f"Dask's worker profiler {args.dask_profile}):")
        for k, v in med.items():
            print(f"  {k:<22} {v:8.1f} vehicle-hours/s  ({v * 3600:8.0f} vehicles at 200 Hz in real time"
                  f"{', ' + format(1e9 / (v * 3600 * 200), '.0f') + ' ns/sample' if k.startswith('raw 1') else ''})")
        print("  CPU seconds per vehicle-hour (all threads and processes; what load on a shared machine does not "
              "change):")
        cpu_med = {k: statistics.median(v) / hours for k, v in cpu.items()}
        for k, v in cpu_med.items():
            print(f"  {k:<22} {1000 * v:8.1f} ms  (end to end / raw: {cpu_med['raw 1 thread'] / v:.2f})")
        cores = args.workers
        for k in (f"local {args.workers} threads", f"dask {args.workers} processes"):
            print(f"  {k}: {100 * med[k] / (raw1 * cores):.0f} % of raw × {cores} cores, "
                  f"{100 * med[k] / med[f'raw {args.workers} threads']:.0f} % of raw on {args.workers} threads")
        per_core = max(med[f"local {args.workers} threads"], med[f"dask {args.workers} processes"]) / cores
        vh_year = args.paper_vehicles * args.paper_hours * 365
        core_hours = vh_year / per_core / 3600
        print(f"\nOn paper: {args.paper_vehicles:,} vehicles × {args.paper_hours:g} h a day × 365 days = "
              f"{vh_year / 1e6:.0f} M vehicle-hours a year; end to end at {per_core:.1f} vehicle-hours/s per core: "
              f"{core_hours:,.0f} core-hours a year, {core_hours / 365:,.0f} a day: each night's logs in 1 hour on "
              f"{core_hours / 365:,.0f} cores, or all day long on {core_hours / 365 / 24:.1f} cores. Logs: "
              f"{size / (hours * 3600) * args.paper_vehicles * args.paper_hours * 3600 * 365 / 1e15:.1f} PB a year "
              f"as written here; the store: {per_day / 1e3:.1f} kB per vehicle-day, "
              f"{per_day * args.paper_vehicles * 365 / 1e9:.0f} GB a year (every day's state kept).")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _score(truth: List[Dict[str, Any]], events: List[Dict[str, Any]], states: Any, window: float,
           hours: float) -> Dict[str, Any]:
    faults = {(f["vehicle"], f["day"]): f for f in truth}
    matched = set()
    found, named, delays, errors = 0, 0, [], []
    delays_by: Dict[str, List[float]] = {}
    for f in truth:
        evs = [e for e in events if (e["vehicle"], e["day"]) == (f["vehicle"], f["day"])
               and f["t"] <= e["t"] <= f["t"] + window]
        if evs:
            found += 1
        right = [e for e in evs if e["parameter"] == f["parameter"]]
        if right:
            e = right[0]
            matched.add((e["vehicle"], e["day"], e["t"], e["parameter"]))
            named += 1
            delays.append(e["t"] - f["t"])
            delays_by.setdefault(f["parameter"], []).append(e["t"] - f["t"])
            errors.append(100 * (e["after"] / f["after"] - 1))
    false, after_fault = 0, 0
    false_by: Dict[str, int] = {}
    after_by: Dict[str, int] = {}
    for e in events:
        if (e["vehicle"], e["day"], e["t"], e["parameter"]) in matched:
            continue
        f = faults.get((e["vehicle"], e["day"]))
        if f is None or e["t"] < f["t"]:
            false += 1
            false_by[e["parameter"]] = false_by.get(e["parameter"], 0) + 1
        else:
            after_fault += 1
            key = f"{f['parameter']}: {e['parameter']}"
            after_by[key] = after_by.get(key, 0) + 1
    driving = states.column("summary").to_pylist()
    summ = [json.loads(s) for s in driving]
    total_s = sum(s.get("seconds", 0.0) for s in summ)
    cannot = sum(s["status"]["cannot judge"] for s in summ if "status" in s)
    clean_s = total_s - sum(
        next(s for (v, d), s in zip(zip(states.column("vehicle").to_pylist(), states.column("day").to_pylist()), summ)
             if (v, d) == k).get("t1", 0.0) - f["t"] for k, f in faults.items())
    return {"faults": len(truth), "found": found, "named right": named, "events": len(events),
            "recall": named / max(1, len(truth)), "precision": len(matched) / max(1, len(events)),
            "false alarms": false, "fault-free hours": clean_s / 3600,
            "false alarms per 10 h": 10 * false / max(1e-9, clean_s / 3600),
            "other events after a fault": after_fault, "false by": false_by, "after by": after_by,
            "delay median s": statistics.median(delays) if delays else float("nan"),
            "delay p95 s": float(np.percentile(delays, 95)) if delays else float("nan"),
            "delays by": {k: (statistics.median(v), float(np.percentile(v, 95))) for k, v in delays_by.items()},
            "after within 3 points": sum(abs(x) <= 3 for x in errors),
            "cannot judge %": 100 * cannot / max(1e-9, total_s), "hours": total_s / 3600}


def detect(args: argparse.Namespace) -> None:
    work = tempfile.mkdtemp(prefix="vehid-fleet-detect-")
    t0 = time.perf_counter()
    try:
        store = os.path.join(work, "store")
        truth: List[Dict[str, Any]] = []
        for first in range(0, args.vehicles, args.part):
            n = min(args.part, args.vehicles - first)
            part = os.path.join(work, f"part{first}")
            truth += simulate(part, n, args.days, args.hours, args.faults, args.seed, first=first,
                              total=args.vehicles, workers=args.workers).to_pylist()
            fleet.run(part, store, workers=args.workers)
            shutil.rmtree(part)
            done = first + n
            el = time.perf_counter() - t0
            _say(f"detect: {done}/{args.vehicles} vehicles simulated and monitored, {el:.0f} s "
                 f"(about {el / done * (args.vehicles - done):.0f} s left)")
        st = fleet.open_store(store)
        s = _score(truth, st.events_table().to_pylist(), st.state_table(), args.window, args.hours)
        by_kind: Dict[str, List[int]] = {}
        for f in truth:
            k = f["parameter"]
            by_kind.setdefault(k, [0, 0])[0] += 1
        ev = st.events_table().to_pylist()
        for f in truth:
            if any((e["vehicle"], e["day"], e["parameter"]) == (f["vehicle"], f["day"], f["parameter"])
                   and f["t"] <= e["t"] <= f["t"] + args.window for e in ev):
                by_kind[f["parameter"]][1] += 1
        print(f"\nFleet detection, {args.vehicles} vehicles × {args.days} days × {args.hours:g} h "
              f"(seed {args.seed}, {args.faults:g} with "
              f"a fault; vehid {vehid.__version__}), {time.perf_counter() - t0:.0f} s:")
        print(f"  faults {s['faults']}: found {s['found']}, named right {s['named right']} "
              f"(recall {100 * s['recall']:.1f} %), {s['after within 3 points']} within 3 points of the new value; "
              f"delay median {s['delay median s']:.2f} s, p95 {s['delay p95 s']:.2f} s")
        print("  per constant (faults, named right): " + ", ".join(f"{k} {v[0]}/{v[1]}" for k, v in
                                                                   sorted(by_kind.items())))
        print("  delay by constant, median / p95 s: " + ", ".join(f"{k} {m:.1f} / {q:.1f}" for k, (m, q) in
                                                                 sorted(s["delays by"].items())))
        print(f"  events {s['events']}: precision {100 * s['precision']:.1f} %; {s['other events after a fault']} "
              f"further events after a fault")
        print("  further events after a fault (fault: event): "
              + ", ".join(f"{k} {v}" for k, v in sorted(s["after by"].items())))
        print("  false alarms by constant: " + ", ".join(f"{k} {v}" for k, v in sorted(s["false by"].items())))
        print(f"  false alarms {s['false alarms']} in {s['fault-free hours']:.0f} fault-free hours: "
              f"{s['false alarms per 10 h']:.2f} per 10 h; cannot judge {s['cannot judge %']:.2f} % of "
              f"{s['hours']:.0f} h")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _files(root: str) -> Dict[str, Tuple[int, int, int]]:
    out = {}
    for d, _, names in os.walk(root):
        for n in names:
            st = os.stat(os.path.join(d, n))
            out[os.path.join(d, n)] = (st.st_ino, st.st_mtime_ns, st.st_size)
    return out


def store_cost(args: argparse.Namespace) -> None:
    import datetime

    from vehid.fleet.store import Row, open_store

    rng = np.random.default_rng(args.seed)
    vehicles = [f"v{i:06d}" for i in range(args.vehicles)]
    day0 = datetime.date(2026, 1, 5)

    def rows_of(k: int) -> List[Tuple[str, str, Any]]:
        day = (day0 + datetime.timedelta(days=k)).isoformat()
        out = []
        for v in vehicles:
            summary = json.dumps({"trend": rng.standard_normal(120).round(6).tolist(), "events": []})
            out.append((v, day, Row(vehid.__version__, rng.bytes(2700), summary)))
        return out

    work = tempfile.mkdtemp(prefix="vehid-store-")
    try:
        path = os.path.join(work, "store")
        st = open_store(path)
        for k in range(args.days):
            for v, d, r in rows_of(k):
                st.rows[(v, d)] = r
            if (k + 1) % 10 == 0 or k + 1 == args.days:
                _say(f"store: {k + 1}/{args.days} days of history built")
        t = time.perf_counter()
        st.commit()
        _say(f"store: history committed ({len(st.rows)} rows) in {time.perf_counter() - t:.2f} s")
        print(f"store: {args.vehicles} vehicles x {args.days} days of history; then one day at a time")
        print(f"  history rows  open + last states, s  {args.parts - 1} commits in the run's middle, s  "
              "its last commit, s  written MB  rows read")
        for k in range(args.days, args.days + args.more):
            rows = rows_of(k)
            before = _files(path)
            t = time.perf_counter()
            st = open_store(path, lazy=True)  # as a run opens it, then reads each vehicle's last state
            for v in vehicles:
                st.rows[(v, st.days(v)[-1])]
            opening = time.perf_counter() - t
            read = st.rows.held()
            middle = 0.0
            for j in range(args.parts):
                for v, d, r in rows[j * len(rows) // args.parts:(j + 1) * len(rows) // args.parts]:
                    st.rows[(v, d)] = r
                t = time.perf_counter()
                st.commit(final=j + 1 == args.parts)
                dt = time.perf_counter() - t
                middle += dt if j + 1 < args.parts else 0.0
            after = _files(path)
            written = sum(s[2] for f, s in after.items() if before.get(f) != s)
            print(f"  {len(st.rows):12d}  {opening:13.3f}  {middle:34.3f}  {dt:17.3f}  {written / 1e6:10.1f}  "
                  f"{read:9d}", flush=True)
        import tracemalloc

        tracemalloc.start()
        lazy = open_store(path, lazy=True)
        index = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        print(f"  open_store(lazy=True): the index of {len(lazy.rows)} rows holds {index / 1e6:.1f} MB "
              f"({index / len(lazy.rows):.0f} bytes per row; tracemalloc's peak)")
        del lazy
        t = time.perf_counter()
        opened = open_store(path)
        print(f"  open_store (every row): {len(opened.rows)} rows in {time.perf_counter() - t:.2f} s; store on disk "
              f"{sum(s[2] for s in _files(path).values()) / 1e6:.1f} MB")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="what", required=True)
    tp = sub.add_parser("throughput", help="end-to-end throughput beside the raw monitor")
    tp.add_argument("--vehicles", type=int, default=16)
    tp.add_argument("--hours", type=float, default=1.0)
    tp.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    tp.add_argument("--repeats", type=int, default=3)
    tp.add_argument("--seed", type=int, default=1)
    tp.add_argument("--paper-vehicles", type=int, default=100_000)
    tp.add_argument("--paper-hours", type=float, default=2.0, help="hours of driving per vehicle and day")
    tp.add_argument("--dask-profile", choices=("on", "off"), default="on",
                    help="Dask's worker profiler (distributed.worker.profile.enabled: on is Dask's default)")
    tp.set_defaults(func=throughput)
    dp = sub.add_parser("detect", help="recall, precision and false alarms on a simulated fleet")
    dp.add_argument("--vehicles", type=int, default=1000)
    dp.add_argument("--hours", type=float, default=1.0, help="hours of driving a day")
    dp.add_argument("--days", type=int, default=1, help="days per vehicle (a fault on one of them)")
    dp.add_argument("--faults", type=float, default=0.5)
    dp.add_argument("--seed", type=int, default=7100000)
    dp.add_argument("--part", type=int, default=50, help="vehicles simulated per part (disk use)")
    dp.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    dp.add_argument("--window", type=float, default=60.0, help="s after a fault in which its event counts")
    dp.set_defaults(func=detect)
    sp = sub.add_parser("store", help="what a commit costs as the store's history grows")
    sp.add_argument("--vehicles", type=int, default=1000)
    sp.add_argument("--days", type=int, default=90, help="days of history before the timed commits")
    sp.add_argument("--more", type=int, default=3, help="days committed one at a time, timed")
    sp.add_argument("--parts", type=int, default=10, help="commits per day (the last one folds the others in)")
    sp.add_argument("--seed", type=int, default=1)
    sp.set_defaults(func=store_cost, workers=1, hours=1.0)
    args = p.parse_args()
    if min(args.vehicles, args.workers) < 1 or args.hours <= 0:
        p.error("--vehicles, --workers >= 1 and --hours > 0")
    if args.what == "store" and min(args.days, args.more, args.parts) < 1:
        p.error("--days, --more and --parts >= 1")
    args.func(args)


if __name__ == "__main__":
    main()

"""vehid.fleet: the fold, resume, idempotent reruns, atomic commits, bad data, the report and
the command line, on a small simulated fleet (the Dask engine: test_fleet_dask.py)."""

from __future__ import annotations

import html.parser
import json
import math
import os
import shutil
from pathlib import Path
from typing import Any, Dict, List, Tuple

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from fleet_helpers import assert_same_store, days_of, make_fleet, store_tables, subset

import vehid
import vehid.fleet as fleet
from vehid.cli import main
from vehid.fleet import engine
from vehid.fleet import store as store_mod
from vehid.fleet.fold import GAP_CAP, DayError, fold, pack_state, unpack_state
from vehid.fleet.layout import scan


@pytest.fixture(scope="module")
def src(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_fleet(tmp_path_factory.mktemp("fleet") / "fleet")


@pytest.fixture(scope="module")
def clean(src: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The store of one run over the whole fleet, one thread."""
    store = tmp_path_factory.mktemp("clean") / "store"
    fleet.run(str(src), str(store), workers=1)
    return store


# --- engines and resume -------------------------------------------------------------------


def test_local_threads_give_the_same_store_bit_for_bit(src: Path, clean: Path, tmp_path: Path) -> None:
    for workers, batch in ((2, None), (2, 1), (3, 2)):
        out = tmp_path / f"w{workers}b{batch}"
        fleet.run(str(src), str(out), workers=workers, batch=batch)
        assert_same_store(clean, out)
    assert store_tables(clean)["state"].num_rows == len(list(src.glob("vehicle=*/day=*")))


def test_resume_days_one_by_one_equals_one_run(src: Path, clean: Path, tmp_path: Path) -> None:
    days = days_of(src)
    store = tmp_path / "store"
    for k in range(1, len(days) + 1):
        part = subset(src, tmp_path / "growing", days[:k])  # the lake receives one more day
        res = fleet.run(str(part), str(store), workers=2)
        assert res.processed == len(list(src.glob("vehicle=*"))), k  # only the new day, each vehicle
    assert_same_store(clean, store)


def test_rerun_is_idempotent(src: Path, clean: Path, tmp_path: Path) -> None:
    store = tmp_path / "store"
    shutil.copytree(clean, store)
    res = fleet.run(str(src), str(store), workers=2)
    assert res.processed == 0
    assert_same_store(clean, store)
    days = days_of(src)
    for since in (days[1], days[0]):
        res = fleet.run(str(src), str(store), workers=2, since=since)
        assert res.processed == sum(d >= since for d in days) * len(list(src.glob("vehicle=*")))
        assert_same_store(clean, store)


def test_events_match_the_single_vehicle_monitor_on_the_joined_days(src: Path, clean: Path) -> None:
    """Each vehicle's stored events are those of one HealthMonitor fed its days joined (one
    missing sample between two days), in the same order, with the same values."""
    cfg = fleet.load_config(str(src / "fleet.toml"))
    events = store_tables(clean)["events"].to_pylist()
    seen = 0
    for vid, days in scan(str(src)).vehicles.items():
        vc = cfg.vehicle(vid)
        mon = vc.monitor_new()
        expected: List[Tuple[str, float, str, float, float, float, float]] = []
        for k, (day, files) in enumerate(days):
            tb = pa.concat_tables([pq.read_table(f) for f in files])
            t = tb.column("t").to_numpy()
            assert np.all(np.diff(t) < 1.5 * vc.dt)  # one trip a day: no gap to feed
            y = np.column_stack([tb.column(c).to_numpy().astype(np.float64) for c in mon.channels])
            start = mon.samples
            if k:
                mon.fit(np.full((1, y.shape[1]), math.nan))
            for ev in mon.fit(y):
                t_day = t[0] + (ev.t / vc.dt - start - (1 if k else 0)) * vc.dt
                expected.append((day, t_day, ev.parameter, ev.before, ev.after, ev.low, ev.high))
        got = [(e["day"], e["t"], e["parameter"], e["before"], e["after"], e["low"], e["high"])
               for e in events if e["vehicle"] == vid]
        assert [g[:1] + g[2:] for g in got] == [x[:1] + x[2:] for x in expected], vid
        assert np.allclose([g[1] for g in got], [x[1] for x in expected], rtol=0, atol=1e-6)
        last = store_tables(clean)["state"].filter(pa.compute.equal(pa.compute.field("vehicle"), vid))
        assert last.column("state")[-1].as_py() == pack_state(mon)
        seen += len(expected)
    assert seen > 0  # the fleet has faults, and they are found


def test_the_injected_faults_are_found(src: Path, clean: Path) -> None:
    truth = pq.read_table(src / "truth.parquet").to_pylist()
    events = store_tables(clean)["events"].to_pylist()
    assert truth
    for f in truth:
        hits = [e for e in events if e["vehicle"] == f["vehicle"] and e["day"] == f["day"]
                and e["parameter"] == f["parameter"] and f["t"] <= e["t"] <= f["t"] + 30.0]
        assert hits, f
        assert abs(hits[0]["after"] / f["after"] - 1) < 0.05, (hits[0], f)


# --- the fold -------------------------------------------------------------------------------


def _day(t: np.ndarray, y: np.ndarray) -> Any:
    return pa.table({"t": t, "a_body": y[:, 0], "a_wheel": y[:, 1], "deflection": y[:, 2]})


def test_fold_feeds_gaps_as_missing_samples_up_to_the_cap() -> None:
    car = vehid.QuarterCar.passenger()
    vc = fleet.VehicleConfig()
    y = vehid.Simulator(car, dt=0.005, road="iso8608-C", speed=15.0, changes=[(40.0, {"b": 1000.0})],
                        sensors="realistic", seed=5).run(12_000).y
    t = 100.0 + np.arange(12_000) * 0.005
    t[6000:] += 10.0            # a 10 s stop: 2000 missing samples
    t[9000:] += 3600.0          # an hour parked: GAP_CAP seconds of them
    res = fold(None, _day(t, y), vc)
    mon = vc.monitor_new()
    stream = [y[:6000], np.full((2000, 3), math.nan), y[6000:9000],
              np.full((int(round(GAP_CAP / 0.005)), 3), math.nan), y[9000:]]
    evs = mon.fit(np.ascontiguousarray(np.concatenate(stream)))
    assert [e.after for e in evs] == [e["after"] for e in res.events] and evs
    assert res.state == pack_state(mon)
    assert res.summary["missing"] == 2000 + int(round(GAP_CAP / 0.005))
    k = int(round(evs[0].t / 0.005))
    assert res.events[0]["t"] == pytest.approx(t[k - 2000 - int(round(GAP_CAP / 0.005))], abs=1e-9)
    again = fold(None, _day(t, y), vc)
    assert again.state == res.state and again.events == res.events and again.summary == res.summary


def test_fold_state_round_trips_and_refuses_garbage() -> None:
    vc = fleet.VehicleConfig()
    mon = vc.monitor_new()
    mon.fit(vehid.Simulator(vehid.QuarterCar.passenger(), dt=0.005, road="iso8608-C", speed=15.0,
                            sensors="realistic", seed=2).run(1000).y)
    data = pack_state(mon)
    assert pack_state(unpack_state(data, vc)) == data
    with pytest.raises(DayError, match="not a vehid monitor state"):
        unpack_state(b"garbage", vc)
    with pytest.raises(DayError, match="cannot be restored"):
        unpack_state(data[:-7], vc)


@pytest.mark.parametrize("change, reason", [
    (lambda t, y: (t[::-1].copy(), y), "does not increase"),
    (lambda t, y: (t * 0.1, y), "under half of dt"),
    (lambda t, y: (t[:0], y[:0]), "no samples"),
])
def test_fold_refuses_a_bad_day_with_the_reason(change: Any, reason: str) -> None:
    y = np.random.default_rng(1).normal(size=(500, 3))
    t, y = change(np.arange(500) * 0.005, y)
    with pytest.raises(DayError, match=reason):
        fold(None, _day(t, y), fleet.VehicleConfig())


# --- the store: atomic commits ----------------------------------------------------------------


def test_a_crash_while_writing_the_state_leaves_the_last_good_store(src: Path, clean: Path, tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    days = days_of(src)
    store = tmp_path / "store"
    fleet.run(str(subset(src, tmp_path / "d1", days[:1])), str(store), workers=1)
    before = store_tables(store)
    real = pq.write_table

    def crash(table: Any, where: Any, **kw: Any) -> None:
        real(table.slice(0, table.num_rows // 2), where, **kw)  # half a file on disk, then the process dies
        raise KeyboardInterrupt

    monkeypatch.setattr(pq, "write_table", crash)
    with pytest.raises(KeyboardInterrupt):
        fleet.run(str(src), str(store), workers=1)
    monkeypatch.undo()
    assert sorted(os.listdir(store)) == ["events.parquet", "problems.parquet", "state.parquet"]  # no temp left
    after = store_tables(store)
    for name in before:
        assert after[name].equals(before[name]), name
    fleet.run(str(src), str(store), workers=1)
    assert_same_store(clean, store)


def test_a_crash_between_the_state_and_the_events_is_repaired_on_open(src: Path, clean: Path, tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    store = tmp_path / "store"
    fleet.run(str(subset(src, tmp_path / "d1", days_of(src)[:1])), str(store), workers=1)
    stale = store_tables(store)["events"]

    def crash(self: Any, digest: bytes) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(store_mod.Store, "_write_derived", crash)
    with pytest.raises(KeyboardInterrupt):
        fleet.run(str(src), str(store), workers=1)
    monkeypatch.undo()
    assert store_tables(store)["events"].equals(stale)  # the file is stale: the state moved on
    assert fleet.read_table(str(store), "events").equals(store_tables(clean)["events"])
    assert_same_store(clean, store)  # open_store rewrote the derived tables


def test_a_run_killed_between_commits_resumes_to_the_same_store(src: Path, clean: Path, tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    store = tmp_path / "store"
    real = engine.run_batch
    calls = []

    def dies_on_the_third(batch: Any) -> Any:
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(batch)

    monkeypatch.setattr(engine, "run_batch", dies_on_the_third)
    with pytest.raises(KeyboardInterrupt):
        fleet.run(str(src), str(store), workers=1, batch=1, commit_every=0.0)
    monkeypatch.undo()
    partial = fleet.read_table(str(store), "state")
    assert len(set(partial.column("vehicle").to_pylist())) == 2  # two vehicles committed
    # ... as parts, which Parquet readers do not see until a run's last commit folds them in
    assert store_tables(store)["state"].num_rows == 0
    parts = sorted((store / "state.parquet").glob("_part-*.parquet"))
    assert len(parts) == 2  # one commit after each vehicle: each part holds that vehicle's days alone
    assert [len(set(pq.read_table(p).column("vehicle").to_pylist())) for p in parts] == [1, 1]
    res = fleet.run(str(src), str(store), workers=1)
    assert res.processed == (len(list(src.glob("vehicle=*"))) - 2) * len(days_of(src))
    assert_same_store(clean, store)


# --- the state's files: a commit writes what it changed -----------------------------------


def _stamps(store: Path) -> Dict[str, Tuple[int, int]]:
    return {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in (store / "state.parquet").iterdir()}


def test_a_run_rewrites_the_days_it_touched_and_no_others(src: Path, clean: Path, tmp_path: Path) -> None:
    days = days_of(src)
    lake, store = tmp_path / "lake", tmp_path / "store"
    fleet.run(str(subset(src, lake, days[:-1])), str(store), workers=1)
    before = _stamps(store)
    assert sorted(before) == [f"{d}.parquet" for d in days[:-1]] + ["_commit.json"]
    fleet.run(str(subset(src, lake, days)), str(store), workers=1)  # the last day arrives
    after = _stamps(store)
    assert all(after[f"{d}.parquet"] == before[f"{d}.parquet"] for d in days[:-1])  # not rewritten
    assert f"{days[-1]}.parquet" in after
    assert_same_store(clean, store)
    # --from a day rewrites that day's file and the later ones, no earlier one
    before = _stamps(store)
    fleet.run(str(src), str(store), workers=1, since=days[1])
    after = _stamps(store)
    assert after[f"{days[0]}.parquet"] == before[f"{days[0]}.parquet"]
    assert all(after[f"{d}.parquet"] != before[f"{d}.parquet"] for d in days[1:])
    assert_same_store(clean, store)


def test_a_run_reads_the_days_it_needs_not_the_history(src: Path, clean: Path, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    days = days_of(src)
    lake, store = tmp_path / "lake", tmp_path / "store"
    fleet.run(str(subset(src, lake, days[:-1])), str(store), workers=1)
    real, read = store_mod._rows_of, []

    def rows_of(table: Any, day: str) -> Any:
        read.append(day)
        return real(table, day)

    monkeypatch.setattr(store_mod, "_rows_of", rows_of)
    res = fleet.run(str(subset(src, lake, days)), str(store), workers=1)
    assert read == [days[-2]]  # the last stored day's states, to go on from; no older day
    monkeypatch.undo()
    assert res.events.equals(fleet.read_table(str(clean), "events"))
    assert res.states.equals(fleet.read_table(str(clean), "state"))
    assert_same_store(clean, store)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_commits_keep_the_store_equal_to_a_model_and_its_tables_to_those_made_anew(tmp_path: Path,
                                                                                          seed: int) -> None:
    """Random rounds of changes (rows set on old and new days, rows deleted, run problems),
    committed in a run's middle or at its end, each round on the store opened lazily as a run
    opens it: the store reads back as a plain dict of the same rows, and its events and
    problems tables (updated by each commit) equal those made anew from every row."""
    rng = np.random.default_rng(seed)
    path = str(tmp_path / "store")
    days = [f"2026-01-{d:02d}" for d in range(3, 12)]
    vehicles = [f"v{k}" for k in range(6)]
    model: Dict[Tuple[str, str], store_mod.Row] = {}

    def row() -> store_mod.Row:
        events = [{"t": float(t), "parameter": str(rng.choice(["b", "k2", "M"])), "before": 1.0, "after": 1.2,
                   "low": 1.1, "high": 1.3, "corner": None, "t_change": float(t) - 2.0, "change": 0.2}
                  for t in sorted(rng.uniform(0, 100, rng.integers(0, 3)))]
        summary = {"events": events, "n": int(rng.integers(1 << 30))}
        if rng.random() < 0.2:
            summary["problem"] = f"problem {rng.integers(100)}"
        return store_mod.Row("0.x", rng.bytes(int(rng.integers(0, 40))) if rng.random() < 0.9 else None,
                             json.dumps(summary))

    for rnd in range(12):
        st = store_mod.open_store(path, lazy=True)
        for _ in range(int(rng.integers(1, 3))):  # commits of this "run"
            for _ in range(int(rng.integers(1, 12))):
                key = (str(rng.choice(vehicles)), str(rng.choice(days)))
                if key in model and rng.random() < 0.25:
                    del st.rows[key]
                    del model[key]
                else:
                    st.rows[key] = model[key] = row()
            st.run_problems = [(str(rng.choice(vehicles)), str(rng.choice(days + [""])), f"run {rnd}")
                               for _ in range(int(rng.integers(0, 3)))]
            st.commit(final=rng.random() < 0.5)
        if rng.random() < 0.8:  # a run ends with its last commit; else it was killed after a middle one
            st.commit()
        for key in ((v, d) for v in vehicles for d in days):  # the run's own view: no row it deleted
            assert (st.rows.get(key) is None) == (key not in model) == (key not in st.rows), (rnd, key)
        full = store_mod.open_store(path)  # (rewrites the derived tables if the run was killed)
        assert {k: (r.vehid_version, r.state, r.summary) for k, r in full.rows.items()} == \
            {k: (r.vehid_version, r.state, r.summary) for k, r in model.items()}, rnd
        for name, made in (("events", full.events_table()), ("problems", full.problems_table())):
            assert pq.read_table(tmp_path / "store" / f"{name}.parquet").equals(made), (rnd, name)
        assert full.run_problems == sorted(st.run_problems)


def test_the_state_reads_as_one_table_one_file_per_day(clean: Path) -> None:
    files = sorted(p.name for p in (clean / "state.parquet").glob("*.parquet"))
    state = fleet.read_table(str(clean), "state")
    assert files == [f"{d}.parquet" for d in sorted(set(state.column("day").to_pylist()))]
    for name in files:
        t = pq.read_table(clean / "state.parquet" / name)
        assert set(t.column("day").to_pylist()) == {name[: -len(".parquet")]}
        assert t.column("vehicle").to_pylist() == sorted(t.column("vehicle").to_pylist())
    whole = pq.read_table(clean / "state.parquet")  # a Parquet reader sees the directory as one table
    assert whole.sort_by([("vehicle", "ascending"), ("day", "ascending")]).equals(state)


def test_a_crash_after_the_manifest_is_redone_on_open(src: Path, clean: Path, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    store = tmp_path / "store"
    fleet.run(str(subset(src, tmp_path / "d1", days_of(src)[:1])), str(store), workers=1)

    real = store_mod._apply

    def crash(sp: str, pending: Any, remove: Any) -> None:
        if any(os.path.exists(os.path.join(sp, tmp)) for tmp, _ in pending):
            raise KeyboardInterrupt  # the manifest is written, no file is in place yet
        real(sp, pending, remove)  # (opening the store: the last commit's files are in place)

    monkeypatch.setattr(store_mod, "_apply", crash)
    with pytest.raises(KeyboardInterrupt):
        fleet.run(str(src), str(store), workers=1)
    monkeypatch.undo()
    assert any(".tmp-" in n for n in os.listdir(store / "state.parquet"))  # committed, not yet renamed
    assert fleet.read_table(str(store), "state").equals(fleet.read_table(str(clean), "state"))
    assert_same_store(clean, store)  # opening the store put the files in place


def test_a_damaged_state_is_refused_with_the_file_and_the_fix(clean: Path, tmp_path: Path) -> None:
    days = sorted(p.name for p in (clean / "state.parquet").glob("*.parquet"))
    store = tmp_path / "store"
    shutil.copytree(clean, store)
    shutil.copy(store / "state.parquet" / days[1], store / "state.parquet" / days[0])  # another day's file
    with pytest.raises(fleet.StoreError, match=f"{days[0]}: not the file _commit.json lists.*remove the store"):
        fleet.open_store(str(store))
    (store / "state.parquet" / days[0]).write_bytes(b"not parquet")
    with pytest.raises(fleet.StoreError, match=f"{days[0]}: not readable"):
        fleet.open_store(str(store))
    shutil.rmtree(store)
    shutil.copytree(clean, store)
    man = json.loads((store / "state.parquet" / "_commit.json").read_text())
    (store / "state.parquet" / "_commit.json").write_text(json.dumps({**man, "format": 3}))
    with pytest.raises(fleet.StoreError, match="store format 3; this vehid .* reads format 2"):
        fleet.open_store(str(store))
    (store / "state.parquet" / "_commit.json").unlink()
    with pytest.raises(fleet.StoreError, match="no _commit.json beside its files"):
        fleet.open_store(str(store))


def test_a_reader_meeting_a_commit_reads_the_new_store_whole(clean: Path, tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """A commit between a reader's reading the manifest and its reading a day file (the file
    no longer the one that manifest lists): the reader starts again from the new manifest and
    returns the new store, not a mix."""
    old, new = tmp_path / "old", tmp_path / "new"
    shutil.copytree(clean, old)
    shutil.copytree(clean, new)
    st = store_mod.open_store(str(new))
    first = sorted(st.rows)[0]
    st.rows[first] = store_mod.Row("changed", st.rows[first].state, st.rows[first].summary)
    st.commit()
    real, calls = store_mod._read, []

    def read(path: str, digest: Any, columns: Any = None) -> Any:
        calls.append(path)
        if len(calls) == 1:  # another process commits now
            shutil.rmtree(old / "state.parquet")
            shutil.copytree(new / "state.parquet", old / "state.parquet")
        return real(path, digest, columns)

    monkeypatch.setattr(store_mod, "_read", read)
    got = store_mod.open_store(str(old))
    monkeypatch.undo()
    assert len(calls) > len(got.day_files)  # it started again
    assert got.state_table().equals(fleet.read_table(str(new), "state"))
    assert got.rows[first].vehid_version == "changed"


def test_the_report_reads_no_monitor_state(clean: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The report reads the summaries alone (the states are half the store): the same rows
    otherwise, and a store read so refuses a commit."""
    full, bare = store_mod.open_store(str(clean)), store_mod.open_store(str(clean), states=False)
    assert sorted(full.rows) == sorted(bare.rows)
    assert all(bare.rows[k].state is None and bare.rows[k].summary == full.rows[k].summary for k in full.rows)
    with pytest.raises(fleet.StoreError, match="opened without its states"):
        bare.commit()
    real, asked = store_mod._read, []

    def read(path: str, digest: Any, columns: Any = None) -> Any:
        asked.append(columns)
        return real(path, digest, columns)

    monkeypatch.setattr(store_mod, "_read", read)
    from vehid.fleet.report import render

    page = render(str(clean))
    assert asked and all(c is not None and "state" not in c for c in asked), asked
    monkeypatch.undo()
    assert page == render(str(clean))


def test_a_reader_during_a_run_leaves_the_tables_to_the_run(clean: Path, tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """Between a run's commits the events and problems files are stale (made before its
    parts). A reader then (the report, read_table) reads the tables from the rows and leaves
    the files to the run, which updates them at its last commit from the files as they were
    (not made anew from every row); with no run, the reader rewrites them."""
    store = tmp_path / "store"
    shutil.copytree(clean, store)
    run = store_mod.open_store(str(store), lazy=True)
    key = sorted(run.rows)[-1]
    run.rows[key] = store_mod.Row("changed", run.rows[key].state, run.rows[key].summary.replace("{", '{"x": 1, ', 1))
    run.commit(final=False)
    files = {n: (store / n).read_bytes() for n in ("events.parquet", "problems.parquet")}
    (store / ".lock").write_text(str(os.getppid()))  # a live process other than this one
    assert fleet.read_table(str(store), "events").equals(fleet.read_table(str(clean), "events"))
    assert {n: (store / n).read_bytes() for n in files} == files  # left to the run
    anew = []
    monkeypatch.setattr(store_mod.Store, "events_table", lambda self: anew.append(1) or store_mod.Store._events_of(
        self, sorted(self.rows)))
    run.commit()  # the run's last commit: an update of the files
    monkeypatch.undo()
    assert anew == []
    full = store_mod.open_store(str(store))
    assert pq.read_table(store / "events.parquet").equals(full.events_table())
    (store / ".lock").unlink()
    run = store_mod.open_store(str(store), lazy=True)
    run.rows[key] = store_mod.Row("again", run.rows[key].state, run.rows[key].summary)
    run.commit(final=False)
    store_mod.open_store(str(store))  # no run holds the store: the reader rewrites the files
    assert pq.read_schema(store / "events.parquet").metadata[b"vehid.fleet.state_digest"] == \
        store_mod.open_store(str(store)).digest().encode()


def _single_file_store(clean: Path, store: Path) -> None:
    """``clean`` as the single-file store the previous version wrote (format 1)."""
    store.mkdir()
    for name in ("events.parquet", "problems.parquet"):
        shutil.copy(clean / name, store / name)
    state = fleet.read_table(str(clean), "state")
    meta = {b"vehid.fleet.format": b"1", b"vehid.fleet.state_digest": b"0" * 64, b"vehid.fleet.run_problems": b"[]"}
    pq.write_table(state.replace_schema_metadata(meta), store / "state.parquet", compression="zstd")


def test_a_single_file_store_is_read_and_rewritten_as_day_files(src: Path, clean: Path, tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    store = tmp_path / "store"
    _single_file_store(clean, store)
    assert fleet.read_table(str(store), "state").equals(fleet.read_table(str(clean), "state"))
    assert (store / "state.parquet").is_file()  # reading changes nothing
    real = os.rename

    def dies(a: Any, b: Any) -> None:  # the old file is set aside, the new directory not yet in
        raise KeyboardInterrupt

    monkeypatch.setattr(store_mod.os, "rename", dies)
    with pytest.raises(KeyboardInterrupt):
        fleet.run(str(src), str(store), workers=1)
    monkeypatch.setattr(store_mod.os, "rename", real)
    assert not (store / "state.parquet").exists() and (store / ".state.parquet.v1").is_file()
    assert fleet.read_table(str(store), "state").equals(fleet.read_table(str(clean), "state"))  # swap finished
    assert (store / "state.parquet").is_dir() and not (store / ".state.parquet.v1").exists()
    shutil.rmtree(store)
    _single_file_store(clean, store)
    res = fleet.run(str(src), str(store), workers=1)  # nothing new: the commit converts the store
    assert res.processed == 0
    assert sorted(os.listdir(store)) == ["events.parquet", "problems.parquet", "state.parquet"]
    assert_same_store(clean, store)


# --- bad data ---------------------------------------------------------------------------------


def test_bad_data_is_recorded_per_vehicle_day_and_spares_the_others(src: Path, clean: Path, tmp_path: Path) -> None:
    days = days_of(src)
    bad = subset(src, tmp_path / "bad")
    vids = sorted(p.name[len("vehicle="):] for p in bad.glob("vehicle=*"))
    corrupt, missing, unordered = vids[0], vids[1], vids[2]
    for f in (bad / f"vehicle={corrupt}" / f"day={days[1]}").glob("*.parquet"):
        f.write_bytes(b"PAR1 this is not a parquet file")
    for f in (bad / f"vehicle={missing}" / f"day={days[0]}").glob("*.parquet"):
        pq.write_table(pq.read_table(f).drop_columns(["deflection"]), f)
    for f in (bad / f"vehicle={unordered}" / f"day={days[2]}").glob("*.parquet"):
        tb = pq.read_table(f)
        pq.write_table(tb.take(pa.array(np.r_[1, 0, 2:tb.num_rows])), f)
    store = tmp_path / "store"
    res = fleet.run(str(bad), str(store), workers=2)
    probs = {(p["vehicle"], p["day"]): p["reason"] for p in res.problems.to_pylist()}
    assert "not a readable Parquet file" in probs[(corrupt, days[1])]
    assert "missing column(s) deflection" in probs[(missing, days[0])]
    assert "does not increase" in probs[(unordered, days[2])]
    assert len(probs) == 3
    good = store_tables(clean)["state"].to_pylist()
    got = store_tables(store)["state"].to_pylist()
    by = {(r["vehicle"], r["day"]): r for r in got}
    for r in good:
        if r["vehicle"] not in (corrupt, missing, unordered):
            assert by[(r["vehicle"], r["day"])] == r  # the others: as in a clean run
    # no state lost: a bad day keeps the state before it, and the chain goes on from it
    assert by[(corrupt, days[1])]["state"] == by[(corrupt, days[0])]["state"] is not None
    assert by[(missing, days[0])]["state"] is None and by[(missing, days[1])]["state"] is not None
    assert by[(corrupt, days[0])] == next(r for r in good if (r["vehicle"], r["day"]) == (corrupt, days[0]))
    # a day that arrives after a later one was processed is out of order: recorded, not folded in
    late = subset(src, tmp_path / "late", days[1:])
    store2 = tmp_path / "store2"
    fleet.run(str(late), str(store2), workers=1)
    subset(src, late, days[:1])
    res = fleet.run(str(late), str(store2), workers=1)
    reasons = [p for p in res.problems.to_pylist() if p["day"] == days[0]]
    assert len(reasons) == len(vids) and all("day out of order" in p["reason"] for p in reasons)
    assert res.processed == 0
    res = fleet.run(str(late), str(store2), workers=1, since=days[0])  # as the reason says
    assert res.problems.num_rows == 0
    assert_same_store(clean, store2)


# --- fleet.toml -------------------------------------------------------------------------------


@pytest.mark.parametrize("text, message", [
    ("[defaults]\nmodel = 'truck'", "model = 'truck': choose quarter, passenger, half"),
    ("[defaults]\nconstants = { k3 = 1.0 }", "'k3' is not a constant of the passenger car"),
    ("[vehicles.a]\nclass = 'van'", "class = 'van': no [classes.van] table"),
    ("[defaults]\ndt = -1", "dt = -1.0: the sample interval must be > 0"),
    ("[defaults]\nmonitor = { windw = 3 }", "'windw' is not a monitor setting"),
    ("[defaults]\nspeed = 3", "unknown key 'speed'"),
    ("[default]\n", "unknown table(s) default"),
    ("[defaults\n", "not valid TOML"),
])
def test_fleet_toml_errors_name_the_key(text: str, message: str) -> None:
    with pytest.raises(fleet.ConfigError) as e:
        fleet.parse_config(text).vehicle("a")
    assert message in str(e.value)


def test_fleet_toml_layers_defaults_class_vehicle() -> None:
    cfg = fleet.parse_config("[defaults]\nmodel='passenger'\nconstants={M=300.0}\n[classes.van]\nconstants={b=2000.0}"
                             "\n[vehicles.a]\nclass='van'\nconstants={k2=30000.0}\ndt=0.01\n")
    a = cfg.vehicle("a")
    assert a.car().params["M"] == 300.0 and a.car().params["b"] == 2000.0 and a.car().params["k2"] == 30000.0
    assert a.dt == 0.01 and cfg.vehicle("other").dt == 0.005
    with pytest.raises(fleet.ConfigError, match="no .vehicles.x. entry and there is no .defaults."):
        fleet.parse_config("[vehicles.a]\n").vehicle("x")


def test_a_full_car_vehicle_reports_the_corner_and_its_trend(tmp_path: Path) -> None:
    """A full car in a fleet (``model = "full"``): its twelve channels from the logs, a damper
    fault named with its corner, a boot load named toward the corner it was set down at, and the
    trend tracks each corner's own spring and damper coefficients."""
    root = tmp_path / "fleet"
    (root).mkdir()
    (root / "fleet.toml").write_text('[defaults]\nmodel = "full"\n')
    full = vehid.FullCar.passenger()
    for day, changes in (("2026-03-02", [(40.0, {"b_fl": 700.0})]),
                         ("2026-03-03", [(40.0, {"load": 100.0, "load_x": -2.5, "load_y": -0.4})])):
        run = vehid.Simulator(full, dt=0.005, road="iso8608-C", speed=15.0, changes=changes,  # type: ignore[arg-type]
                              sensors="realistic", seed=31 + len(day)).run(18000)
        d = root / "vehicle=car" / f"day={day}"
        d.mkdir(parents=True)
        cols = {"t": run.t + 8 * 3600.0, **{c: run.y[:, i] for i, c in enumerate(run.channels)}}
        pq.write_table(pa.table(cols), d / "08-00-00.parquet")
        full = vehid.FullCar(**{**full.params, "b_fl": 700.0})  # the fault stays
    res = fleet.run(str(root), str(tmp_path / "store"), workers=1)
    assert res.problems.num_rows == 0, res.problems.to_pylist()
    events = res.events.to_pylist()
    assert [(e["day"], e["parameter"], e["corner"]) for e in events] == [
        ("2026-03-02", "b_fl", "fl"), ("2026-03-03", "M", "rr")], events
    assert abs(events[0]["after"] / 700.0 - 1) < 0.05 and abs(events[1]["after"] / 1600.0 - 1) < 0.05, events
    first = json.loads(res.states.to_pylist()[0]["summary"])["trend"]
    assert first["names"] == ["k_fl", "b_fl", "k_fr", "b_fr", "k_rl", "b_rl", "k_rr", "b_rr"]
    k_fl, b_fl, k_fr, b_fr = first["values"][-1][:4]  # day one's end, the faulty damper on
    # Each corner's own coefficients in its own equation, (alpha K)_ii and alpha_ii b_i: the two
    # front corners have the same alpha_ii (equal track), so the springs' match and the dampers'
    # stand as 700 to 1000.
    assert abs(k_fl / k_fr - 1) < 0.05 and abs(b_fl / b_fr / 0.7 - 1) < 0.05, first["values"]


# --- the report -------------------------------------------------------------------------------


class _Page(html.parser.HTMLParser):
    """Checks that every element is closed in order, and collects the vehicle rows."""

    VOID = {"meta", "br", "img", "input", "link", "hr"}

    def __init__(self) -> None:
        super().__init__()
        self.stack: List[str] = []
        self.rows: List[Dict[str, str]] = []
        self.svgs = 0
        self.text: List[str] = []
        self.scripts = 0

    def handle_starttag(self, tag: str, attrs: List[Tuple[str, Any]]) -> None:
        if tag == "tr" and dict(attrs).get("data-vehicle"):
            self.rows.append({k: v or "" for k, v in attrs})
        self.svgs += tag == "svg"
        self.scripts += tag in ("script", "link", "img", "iframe")
        if tag not in self.VOID:
            self.stack.append(tag)

    def handle_startendtag(self, tag: str, attrs: List[Tuple[str, Any]]) -> None:
        pass

    def handle_endtag(self, tag: str) -> None:
        assert self.stack and self.stack[-1] == tag, (tag, self.stack[-5:])
        self.stack.pop()

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def test_report_lists_vehicles_with_events_first(clean: Path, tmp_path: Path) -> None:
    out = tmp_path / "report.html"
    assert main(["fleet", "report", str(clean), "-o", str(out)]) == 0
    page = _Page()
    page.feed(out.read_text(encoding="utf-8"))
    page.close()
    assert page.stack == []
    assert page.scripts == 0  # self-contained: nothing to fetch
    events = store_tables(clean)["events"].to_pylist()
    states = store_tables(clean)["state"].to_pylist()
    vehicles = sorted({r["vehicle"] for r in states})
    assert sorted(r["data-vehicle"] for r in page.rows) == vehicles
    flags = [int(r["data-events"]) > 0 for r in page.rows]
    assert flags == sorted(flags, reverse=True) and any(flags) and not all(flags)
    for r in page.rows:
        assert int(r["data-events"]) == sum(e["vehicle"] == r["data-vehicle"] for e in events)
    assert page.svgs == len(vehicles)
    text = "".join(page.text)
    for e in events:
        assert f"{e['before']:.5g} → {e['after']:.5g}" in text
    assert text.count("cannot judge") >= 1 and "%" in text


# --- the command line -------------------------------------------------------------------------


def test_cli_simulate_run_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d, s = tmp_path / "f", tmp_path / "s"
    assert main(["fleet", "simulate", str(d), "--vehicles", "2", "--days", "1", "--hours", "0.05", "--faults", "0.5",
                 "--seed", "4"]) == 0
    assert pq.read_table(d / "truth.parquet").column_names == ["vehicle", "day", "t", "parameter", "before", "after"]
    assert main(["fleet", "run", str(d), "--store", str(s), "--workers", "2"]) == 0
    err = capsys.readouterr().err
    assert "2/2 (100 %)" in err and "2 vehicle-days" in err
    assert pq.read_table(s / "events.parquet").column_names[:8] == [
        "vehicle", "day", "t", "parameter", "before", "after", "low", "high"]
    assert pq.read_table(s / "state.parquet").column_names == ["vehicle", "day", "vehid_version", "state", "summary"]
    summary = json.loads(pq.read_table(s / "state.parquet").column("summary")[0].as_py())
    assert summary["samples"] == int(round(0.05 * 3600 / 0.005))


@pytest.mark.parametrize("argv, message", [
    (["fleet", "run", "{tmp}/none", "--store", "{tmp}/s"], "none: not a directory (a fleet:"),
    (["fleet", "run", "{tmp}/empty", "--store", "{tmp}/s"], "fleet.toml: no such file"),
    (["fleet", "run", "{tmp}", "--store", "{tmp}/file"], "is a file; give a directory"),
    (["fleet", "run", "{tmp}", "--store", "{tmp}/s", "--from", "2026-02-30"], "since='2026-02-30': expected a day"),
    (["fleet", "report", "{tmp}/s", "-o", "{tmp}/r.html"], "not a fleet store (no state.parquet)"),
    (["fleet", "simulate", "{tmp}", "--vehicles", "1"], "not empty; give a new or empty directory"),
    (["fleet", "simulate", "{tmp}/n", "--hours", "0.01", "--faults", "0.5"], "a fault needs at least 3 minutes"),
])
def test_cli_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: List[str],
                                 message: str) -> None:
    (tmp_path / "fleet.toml").write_text("[defaults]\n")
    (tmp_path / "file").write_text("x")
    (tmp_path / "empty").mkdir()
    assert main([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


def test_a_process_killed_mid_write_leaves_a_store_that_reads(src: Path, clean: Path, tmp_path: Path) -> None:
    """A real process death (SIGKILL, no cleanup runs) while it writes state.parquet: the
    store reads as it was, and the rerun removes the half-written file and completes it."""
    import signal
    import subprocess
    import sys

    store = tmp_path / "store"
    fleet.run(str(subset(src, tmp_path / "d1", days_of(src)[:1])), str(store), workers=1)
    before = store_tables(store)
    script = (
        "import os, signal, sys, pyarrow.parquet as pq, vehid.fleet as fleet\n"
        "real = pq.write_table\n"
        "def dies(table, where, **kw):\n"
        "    real(table.slice(0, table.num_rows // 2), where, **kw)\n"
        "    os.kill(os.getpid(), signal.SIGKILL)\n"
        "pq.write_table = dies\n"
        "fleet.run(sys.argv[1], sys.argv[2], workers=1)\n"
    )
    proc = subprocess.run([sys.executable, "-c", script, str(src), str(store)], capture_output=True,
                          env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}, timeout=120)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    left = [p.name for p in store.rglob("*")]
    assert any(".tmp-" in n for n in left)  # the half-written file is still there
    (store / ".events.parquet.tmp-99999").write_bytes(b"half")  # as a kill while writing the events leaves
    after = store_tables(store)
    for name in before:
        assert after[name].equals(before[name]), name
    fleet.run(str(src), str(store), workers=1)
    assert not any(".tmp-" in p.name or p.name == ".lock" for p in store.rglob("*"))
    assert_same_store(clean, store)


def test_simulate_in_parts_writes_the_same_vehicles(tmp_path: Path) -> None:
    from vehid.fleet.simulate import simulate

    whole = simulate(str(tmp_path / "whole"), 4, 1, 0.05, 0.5, 21)
    parts = [simulate(str(tmp_path / f"p{k}"), 2, 1, 0.05, 0.5, 21, first=2 * k, total=4, workers=2)
             for k in range(2)]
    assert whole.to_pylist() == parts[0].to_pylist() + parts[1].to_pylist() and whole.num_rows == 2
    for f in sorted((tmp_path / "whole").glob("vehicle=*/day=*/*.parquet")):
        rel = f.relative_to(tmp_path / "whole")
        other = next(p / rel for p in (tmp_path / "p0", tmp_path / "p1") if (p / rel).exists())
        assert pq.read_table(f).equals(pq.read_table(other))


def test_a_missing_extra_is_one_line_naming_it(src: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                               hide_package: Any) -> None:
    hide_package("pyarrow")
    assert main(["fleet", "run", str(src), "--store", str(tmp_path / "s")]) == 2
    assert "needs pyarrow: pip install 'vehid[fleet]'" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()
    hide_package("distributed")
    assert main(["fleet", "run", str(src), "--store", str(tmp_path / "s"), "--scheduler", "tcp://127.0.0.1:1"]) == 2
    assert "--scheduler needs dask.distributed: pip install 'vehid[fleet]'" in capsys.readouterr().err


def test_a_changed_fleet_toml_is_noticed_not_mixed_in(src: Path, tmp_path: Path) -> None:
    days = days_of(src)
    lake = subset(src, tmp_path / "lake", days[:1])
    store = tmp_path / "store"
    fleet.run(str(lake), str(store), workers=1)
    subset(src, lake, days)  # the next days arrive (with the same fleet.toml), then it is edited
    toml = (lake / "fleet.toml").read_text()
    vid = sorted(p.name[len("vehicle="):] for p in lake.glob("vehicle=*"))[0]
    head, entry = toml.split(f"[vehicles.{vid}]\n", 1)
    (lake / "fleet.toml").write_text(head + f"[vehicles.{vid}]\nmonitor = {{ warmup = 25.0 }}\n" + entry)
    res = fleet.run(str(lake), str(store), workers=1)
    probs = res.problems.to_pylist()
    assert [(p["vehicle"], p["day"]) for p in probs] == [(vid, days[0])]
    assert "fleet.toml changed for this vehicle" in probs[0]["reason"] and f"--from {days[0]}" in probs[0]["reason"]
    assert store_mod.open_store(str(store)).days(vid) == days[:1]  # its new days wait
    res = fleet.run(str(lake), str(store), workers=1, since=days[0])
    assert res.problems.num_rows == 0 and store_mod.open_store(str(store)).days(vid) == days

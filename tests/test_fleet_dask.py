"""vehid.fleet on a real Dask cluster: a LocalCluster of two worker processes (its own
scheduler), the same store bit for bit as the local engine, and a worker killed mid-run."""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any, Iterator, List

import pytest
from fleet_helpers import assert_same_store, make_fleet

import vehid.fleet as fleet

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def client() -> Iterator[Any]:
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cl:
        with distributed.Client(cl) as c:
            yield c


@pytest.fixture(scope="module")
def src(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_fleet(tmp_path_factory.mktemp("fleet") / "fleet", vehicles=6)


@pytest.fixture(scope="module")
def local(src: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    store = tmp_path_factory.mktemp("local") / "store"
    fleet.run(str(src), str(store), workers=1)
    return store


def test_dask_two_processes_give_the_local_store_bit_for_bit(client: Any, src: Path, local: Path,
                                                             tmp_path: Path) -> None:
    pids = client.run(os.getpid)
    assert len(set(pids.values()) | {os.getpid()}) == 3  # two worker processes besides this one
    for batch in (None, 1):
        store = tmp_path / f"b{batch}"
        res = fleet.run(str(src), str(store), client=client, batch=batch)
        assert res.processed == len(list(src.glob("vehicle=*/day=*")))
        assert_same_store(local, store)
    with pytest.raises(ValueError, match="workers= is for the local engine"):
        fleet.run(str(src), str(tmp_path / "x"), client=client, workers=2)


def test_a_worker_killed_mid_run_changes_nothing(client: Any, src: Path, local: Path, tmp_path: Path) -> None:
    killed: List[int] = []

    def kill_one(done: int, total: int) -> None:
        if done > 0 and not killed:
            busy = [w for w, keys in client.processing().items() if keys]
            if busy:  # a worker with a task in hand: killed, its task must be run again elsewhere
                pid = client.run(os.getpid, workers=[busy[0]])[busy[0]]
                os.kill(pid, signal.SIGKILL)  # a worker process this test's cluster started
                killed.append(pid)

    store = tmp_path / "store"
    res = fleet.run(str(src), str(store), client=client, batch=1, progress=kill_one)
    assert killed and res.processed == len(list(src.glob("vehicle=*/day=*")))
    assert_same_store(local, store)
    client.wait_for_workers(2, timeout=60)  # the nanny restarted it


def test_cli_run_on_a_scheduler(client: Any, src: Path, local: Path, tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    from vehid.cli import main

    store = tmp_path / "store"
    assert main(["fleet", "run", str(src), "--store", str(store), "--scheduler", client.scheduler.address]) == 0
    assert "vehicle-days" in capsys.readouterr().err
    assert_same_store(local, store)

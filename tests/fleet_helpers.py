"""Shared helpers of the fleet tests: a small simulated fleet, partial copies of it, and the
store's tables read back."""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any, Dict, Iterable, Optional

import pyarrow.parquet as pq

from vehid.fleet.simulate import simulate
from vehid.fleet.store import open_store

#: The test fleet: small enough for the whole fleet suite to stay quick on one core.
VEHICLES, DAYS, HOURS, FAULTS, SEED = 5, 3, 0.05, 0.6, 11


def make_fleet(path: Path, vehicles: int = VEHICLES, days: int = DAYS, seed: int = SEED) -> Path:
    """A simulated fleet at ``path`` (3-minute days, a fault on most vehicles)."""
    simulate(str(path), vehicles, days, HOURS, FAULTS, seed)
    return path


def subset(src: Path, dst: Path, days: Optional[Iterable[str]] = None,
           vehicles: Optional[Iterable[str]] = None) -> Path:
    """A copy of the fleet ``src`` at ``dst`` holding only ``days`` (and ``vehicles``), its
    files copied (so that a test may damage them)."""
    keep_days = None if days is None else set(days)
    keep_veh = None if vehicles is None else set(vehicles)
    dst.mkdir(parents=True, exist_ok=True)
    shutil.copy(src / "fleet.toml", dst / "fleet.toml")
    for vdir in sorted(src.glob("vehicle=*")):
        if keep_veh is not None and vdir.name[len("vehicle="):] not in keep_veh:
            continue
        for ddir in sorted(vdir.glob("day=*")):
            if keep_days is not None and ddir.name[len("day="):] not in keep_days:
                continue
            target = dst / vdir.name / ddir.name
            if not target.exists():
                shutil.copytree(ddir, target)
    return dst


def days_of(fleet: Path) -> list[str]:
    """The fleet's days, sorted."""
    return sorted({d.name[len("day="):] for d in fleet.glob("vehicle=*/day=*")})


def store_tables(store: Path) -> Dict[str, Any]:
    """The store's three tables as written (read straight from the files)."""
    return {name: pq.read_table(os.path.join(store, f"{name}.parquet")) for name in ("state", "events", "problems")}


def state_files(store: Path) -> Dict[str, bytes]:
    """The state's files (``state.parquet/*``) by name, but the manifest (which numbers the
    commits), with their bytes."""
    return {p.name: p.read_bytes() for p in sorted((store / "state.parquet").iterdir()) if p.name != "_commit.json"}


def assert_same_store(a: Path, b: Path) -> None:
    """The two stores hold the same tables, value for value, and the same state files, bit
    for bit (so the same day files and no part or temporary file left)."""
    ta, tb = store_tables(a), store_tables(b)
    for name in ta:
        assert ta[name].equals(tb[name]), name
    for x in (a, b):  # the derived tables a commit updated are those made anew from every row
        full = open_store(str(x))
        assert full.events_table().equals(pq.read_table(x / "events.parquet")), x
        assert full.problems_table().equals(pq.read_table(x / "problems.parquet")), x
    fa, fb = state_files(a), state_files(b)
    assert sorted(fa) == sorted(fb)
    assert all(n.endswith(".parquet") and n[0].isdigit() for n in fa), sorted(fa)
    for name in fa:
        assert fa[name] == fb[name], name

"""Fleet scale: every vehicle's suspension health from its logs, day after day, on a laptop or
a Dask cluster.

>>> import vehid.fleet                                            # doctest: +SKIP
>>> res = vehid.fleet.run("fleet/", store="store/")               # doctest: +SKIP
>>> res.events                                                    # doctest: +SKIP

* :mod:`vehid.fleet.layout` — the dataset: ``DIR/vehicle=<id>/day=<YYYY-MM-DD>/*.parquet``;
* :mod:`vehid.fleet.config` — ``DIR/fleet.toml``: each vehicle's car, constants, sensors, dt;
* :mod:`vehid.fleet.fold` — the pure fold ``(state | None, day) -> (state, events, summary)``;
* :mod:`vehid.fleet.engine` — :func:`run`: resume, the local and Dask engines, commits;
* :mod:`vehid.fleet.store` — ``state.parquet``, ``events.parquet``, ``problems.parquet``;
* :mod:`vehid.fleet.simulate` — a simulated fleet with injected faults and its truth;
* :mod:`vehid.fleet.report` — the static HTML report.

Needs pyarrow (``pip install 'vehid[fleet]'``, which also brings Dask).
"""

from __future__ import annotations

from .config import ConfigError, FleetConfig, VehicleConfig, load_config, parse_config
from .engine import FleetResult, run
from .fold import DayError, DayResult, fold
from .store import StoreError, open_store, read_table

__all__ = ["ConfigError", "DayError", "DayResult", "FleetConfig", "FleetResult", "StoreError", "VehicleConfig",
           "fold", "load_config", "open_store", "parse_config", "read_table", "run"]

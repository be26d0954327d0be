"""The optional packages the fleet needs, imported on first use: pyarrow (always) and
dask.distributed (the Dask engine); a missing one is a one-line error naming the extra."""

from __future__ import annotations

import importlib
from typing import Any


def module(name: str) -> Any:
    """``importlib.import_module(name)``, or ``ValueError`` naming ``pip install 'vehid[fleet]'``."""
    try:
        return importlib.import_module(name)
    except ImportError:
        top = name.split(".")[0]
        raise ValueError(f"vehid.fleet needs {'dask.distributed' if top == 'distributed' else top}: "
                         "pip install 'vehid[fleet]'") from None

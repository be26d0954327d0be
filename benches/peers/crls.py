"""The plain C RLS loop (``rls.c``), compiled with ``cc -O3 -march=native`` and called via ctypes.

Shared by ``run_peers.py`` and ``../check_budgets.py`` (needs only numpy). The library is built
into ``target/peers/`` (rebuilt when ``rls.c`` is newer); ``CC`` overrides the compiler.
"""

from __future__ import annotations

import ctypes
import os
import subprocess
import time
from pathlib import Path
from typing import List, Sequence, Tuple

import numpy as np

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "rls.c"
BUILD = HERE.parent.parent / "target" / "peers"
CFLAGS = ["-O3", "-march=native", "-shared", "-fPIC", "-std=c11"]

_lib = None


def compile_command() -> List[str]:
    return [os.environ.get("CC", "cc"), *CFLAGS, str(SOURCE), "-o", str(BUILD / "librls.so")]


def load() -> ctypes.CDLL:
    """Compiles (if needed) and loads the library."""
    global _lib
    if _lib is not None:
        return _lib
    BUILD.mkdir(parents=True, exist_ok=True)
    so = BUILD / "librls.so"
    if not so.exists() or so.stat().st_mtime < SOURCE.stat().st_mtime:
        subprocess.run(compile_command(), check=True)
    lib = ctypes.CDLL(str(so))
    dp = ctypes.POINTER(ctypes.c_double)
    ip = ctypes.POINTER(ctypes.c_int)
    lib.rls_rows.argtypes = [dp, dp, ctypes.c_size_t, ctypes.c_int, ip, ctypes.c_int, dp, ctypes.c_double, dp]
    lib.rls_rows.restype = ctypes.c_int
    lib.rls_shared.argtypes = [dp, dp, ctypes.c_size_t, ctypes.c_int, ip, ctypes.c_int, ctypes.c_double, dp]
    lib.rls_shared.restype = ctypes.c_int
    _lib = lib
    return lib


def _ptr(a: np.ndarray, ctype: type) -> ctypes._Pointer:
    return a.ctypes.data_as(ctypes.POINTER(ctype))


def _prep(x: np.ndarray, z: np.ndarray, rows: Sequence[int]) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    x = np.ascontiguousarray(x, dtype=np.float64)
    z = np.ascontiguousarray(z, dtype=np.float64)
    if x.shape != z.shape or x.ndim != 2:
        raise ValueError("x and z must both be (n, N)")
    return x, z, np.ascontiguousarray(rows, dtype=np.intc)


def rows(x: np.ndarray, z: np.ndarray, unknown: Sequence[int], r: Sequence[float], p0: float) -> np.ndarray:
    """θ̂ (K × N) of the decoupled-rows RLS with P(0) = p0 I and measurement variances r."""
    lib = load()
    x, z, idx = _prep(x, z, unknown)
    rr = np.ascontiguousarray(r, dtype=np.float64)
    out = np.zeros((len(idx), x.shape[1]))
    rc = lib.rls_rows(_ptr(x, ctypes.c_double), _ptr(z, ctypes.c_double), x.shape[0], x.shape[1],
                      _ptr(idx, ctypes.c_int), len(idx), _ptr(rr, ctypes.c_double), float(p0),
                      _ptr(out, ctypes.c_double))
    if rc != 0:
        raise ValueError("rls_rows: unsupported dimensions")
    return out


def shared(x: np.ndarray, z: np.ndarray, unknown: Sequence[int], q0: float) -> np.ndarray:
    """θ̂ (K × N) of the shared-covariance RLS with Q(0) = q0 I (P_i = r_i Q)."""
    lib = load()
    x, z, idx = _prep(x, z, unknown)
    out = np.zeros((len(idx), x.shape[1]))
    rc = lib.rls_shared(_ptr(x, ctypes.c_double), _ptr(z, ctypes.c_double), x.shape[0], x.shape[1],
                        _ptr(idx, ctypes.c_int), len(idx), float(q0), _ptr(out, ctypes.c_double))
    if rc != 0:
        raise ValueError("rls_shared: unsupported dimensions")
    return out


def ns_per_sample(func, n: int, repeats: int = 7) -> float:
    """Best-of-`repeats` wall time of `func()` (one call over `n` samples), in ns per sample."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - t0)
    return best / n * 1e9


def reference_ns(n: int = 200_000, seed: int = 1, repeats: int = 7) -> dict:
    """ns per sample of the C loop on seeded vehid data: rows and shared, quarter and half car."""
    import vehid

    out = {}
    for name, car in (("quarter", vehid.QuarterCar()), ("half", vehid.HalfCar())):
        run = vehid.Simulator(car, dt=0.05, road_sigma=0.1, ic_sigma=0.1, deriv_noise=0.005, seed=seed).run(n)
        x, z = np.ascontiguousarray(run.r), np.ascontiguousarray(run.z)
        unknown = list(car.unknown_rows)
        r = car.row_noise_var(0.1, 0.005)
        out[f"{name}_rows"] = ns_per_sample(lambda x=x, z=z, unknown=unknown, r=r: rows(x, z, unknown, r, 1000.0),
                                            n, repeats)
        out[f"{name}_shared"] = ns_per_sample(lambda x=x, z=z, unknown=unknown: shared(x, z, unknown, 1000.0),
                                              n, repeats)
    return out

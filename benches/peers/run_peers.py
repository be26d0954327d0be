"""vehid against what users would otherwise use: the same quarter- and half-car data through every peer.

Run: ``make bench-peers`` (creates ``.venv-peers`` with filterpy, padasip, statsmodels, numpy and
a vehid wheel; the peers are never vehid dependencies), or, in such a venv,
``python benches/peers/run_peers.py [--n 20000] [--half-n 10000] [--json target/peers/peers.json]``.

Data: a seeded ``vehid.Simulator`` run of the thesis quarter car (dt 0.05, road_sigma 0.1,
ic_sigma 0.1, deriv_noise 0.005, seed 1). Problem: for each unknown row i of A (rows 1 and 3),
``z_i(k) = x(k)ᵀ θ_i + v`` with ``r_i = row_noise_var(0.1, 0.005)[i]``, ``P_i(0) = p0 I``
(p0 = 1000), ``θ_i(0) = 0`` — exactly vehid's ``KalmanIdentifier(mode="rows")``. Each peer is
set up to solve that same problem:

* **filterpy** ``KalmanFilter(dim_x=4, dim_z=1)`` per row as a parameter identifier: state θ_i,
  F = I, Q = 0, H = x(k)ᵀ (passed to ``update``), R = r_i, P = p0 I. ``predict()`` is skipped:
  with F = I and Q = 0 it is the identity (skipping it favours filterpy). filterpy's update
  uses Joseph's form.
* **padasip** ``FilterRLS(n=4, mu=1, eps=r_i/p0, w="zeros")`` per row, driven by its own
  ``run()`` loop. padasip's RLS is unweighted with ``R(0) = I/eps``; the unweighted problem
  with prior ``(p0/r_i) I`` has the same minimiser as the weighted one with ``p0 I`` and
  ``r_i``, so eps = r_i/p0 makes θ identical (its R is P/r_i). mu = 1: no forgetting.
* **statsmodels** ``RecursiveLS`` per row. Its default prior is (exact) diffuse and it fixes the
  observation variance to 1 (the scale is concentrated out), so it is given
  ``initialization="known"``, ``initial_state=0``, ``initial_state_cov=(p0/r_i) I`` — the same
  minimiser again. Timed: model construction + ``filter()`` (no smoother).
* **numpy RLS loop**: the textbook recursion written with numpy per sample and row.
* **numpy lstsq**: batch least squares with the prior as extra rows,
  ``[X/√r_i; I/√p0] θ = [z_i/√r_i; 0]``.
* **vehid** ``update()`` per sample from Python, and ``fit()`` on the whole array.
* **C**: ``rls.c``, the same recursion as a plain C loop (``cc -O3 -march=native``) via ctypes.

First the agreement table: every peer's θ̂ against vehid's ``fit()``, as
``max_i ‖θ_peer,i − θ_vehid,i‖ / ‖θ_vehid,i‖`` (must be ≤ 1e-8). Only if all agree are the
times measured and printed (best of several repeats, ns per sample = one update of both
rows), with the ratio to vehid ``fit()`` and to the C loop, all in this one run.

Then the same two tables for the **half car** (``vehid.HalfCar()``, the thesis' values of
Eq 6.1–6.8: 8 states, 2 road inputs, unknown rows 1, 3, 5, 7 as given by ``unknown_rows``,
``r_i = row_noise_var(0.1, 0.005)[i]``), simulated with the same settings and seed and solved
the same way by every peer above (``dim_x = n = 8``; each per-row peer runs 4 rows of 8
parameters; ns per sample = one update of all 4 rows). The half-car peers are slow (filterpy,
padasip and the numpy loop take 30–100 µs per sample, statsmodels 13–18 µs), so this table
uses fewer samples: ``--half-n`` (default 10000, about 10 s; 0 skips it), printed in its
header. Its agreement check also comes first and its times are printed only if every peer
agrees.

Exit status 1 on a disagreement (quarter or half car). ``--json`` also writes the figures:
the quarter car under the top-level keys ``n``, ``seed``, ``peers``, ``vehid_theta``, the half
car under ``half_car`` (same keys plus ``rows`` and ``r``), and the C reference on both cars
and the shared form (``c_reference_ns``, used by ``benches/check_budgets.py``).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import platform
import sys
import time
from pathlib import Path
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import crls  # noqa: E402

import vehid  # noqa: E402

TOL = 1e-8
P0 = 1000.0


CARS = {"quarter": vehid.QuarterCar, "half": vehid.HalfCar}


class Problem:
    def __init__(self, n: int, seed: int, car: str = "quarter") -> None:
        self.name = car
        self.car = CARS[car]()
        run = vehid.Simulator(self.car, dt=0.05, road_sigma=0.1, ic_sigma=0.1, deriv_noise=0.005, seed=seed).run(n)
        self.x = np.ascontiguousarray(run.r)
        self.z = np.ascontiguousarray(run.z)
        self.rows = list(self.car.unknown_rows)
        self.r = np.asarray(self.car.row_noise_var(0.1, 0.005), dtype=float)
        self.n = n
        self.p0 = P0


# ---- the peers: each returns θ̂ (K × N) --------------------------------------------------

def vehid_fit(pb: Problem) -> np.ndarray:
    kf = vehid.KalmanIdentifier(pb.car, p0=pb.p0, r=pb.r)
    kf.fit(pb.x, pb.z)
    return kf.theta


def vehid_update(pb: Problem) -> np.ndarray:
    kf = vehid.KalmanIdentifier(pb.car, p0=pb.p0, r=pb.r)
    update = kf.update
    for xk, zk in zip(pb.x, pb.z):
        update(xk, zk)
    return kf.theta


def c_loop(pb: Problem) -> np.ndarray:
    return crls.rows(pb.x, pb.z, pb.rows, pb.r, pb.p0)


def numpy_rls(pb: Problem) -> np.ndarray:
    k, n_states = len(pb.rows), pb.x.shape[1]
    theta = np.zeros((k, n_states))
    p = np.stack([np.eye(n_states) * pb.p0 for _ in range(k)])
    for xk, zk in zip(pb.x, pb.z):
        for i, row in enumerate(pb.rows):
            px = p[i] @ xk
            s = xk @ px + pb.r[i]
            theta[i] += px * ((zk[row] - xk @ theta[i]) / s)
            p[i] -= np.outer(px, px) / s
    return theta


def numpy_lstsq(pb: Problem) -> np.ndarray:
    n_states = pb.x.shape[1]
    out = []
    for i, row in enumerate(pb.rows):
        w = 1.0 / np.sqrt(pb.r[i])
        a = np.vstack([pb.x * w, np.eye(n_states) / np.sqrt(pb.p0)])
        b = np.concatenate([pb.z[:, row] * w, np.zeros(n_states)])
        out.append(np.linalg.lstsq(a, b, rcond=None)[0])
    return np.array(out)


def filterpy_kf(pb: Problem) -> np.ndarray:
    from filterpy.kalman import KalmanFilter

    n_states = pb.x.shape[1]
    out = []
    for i, row in enumerate(pb.rows):
        kf = KalmanFilter(dim_x=n_states, dim_z=1)
        kf.x = np.zeros((n_states, 1))
        kf.F = np.eye(n_states)
        kf.Q = np.zeros((n_states, n_states))
        kf.P = np.eye(n_states) * pb.p0
        kf.R = np.array([[pb.r[i]]])
        update = kf.update
        hs = pb.x[:, None, :]  # (n, 1, N): H = x(k)ᵀ
        for h, zk in zip(hs, pb.z[:, row]):
            update(zk, H=h)
        out.append(kf.x[:, 0].copy())
    return np.array(out)


def padasip_rls(pb: Problem) -> np.ndarray:
    import padasip as pa

    out = []
    for i, row in enumerate(pb.rows):
        f = pa.filters.FilterRLS(n=pb.x.shape[1], mu=1.0, eps=pb.r[i] / pb.p0, w="zeros")
        f.run(pb.z[:, row], pb.x)
        out.append(np.array(f.w, dtype=float))
    return np.array(out)


def statsmodels_rls(pb: Problem) -> np.ndarray:
    from statsmodels.regression.recursive_ls import RecursiveLS

    n_states = pb.x.shape[1]
    out = []
    for i, row in enumerate(pb.rows):
        mod = RecursiveLS(pb.z[:, row], pb.x, initialization="known", initial_state=np.zeros(n_states),
                          initial_state_cov=np.eye(n_states) * (pb.p0 / pb.r[i]))
        res = mod.filter()
        out.append(np.array(res.filtered_state[:, -1]))
    return np.array(out)


PEERS: List[Tuple[str, str, Callable[[Problem], np.ndarray], int]] = [
    # (name, what is timed, function, timing repeats)
    ("vehid fit()", "vehid.KalmanIdentifier.fit on (n, N) arrays", vehid_fit, 15),
    ("vehid update()", "one Python call per sample", vehid_update, 5),
    ("C loop (-O3 -march=native)", "rls.c via one ctypes call", c_loop, 15),
    ("numpy lstsq (batch)", "prior as extra rows, per row", numpy_lstsq, 7),
    ("numpy RLS loop", "per sample and row", numpy_rls, 2),
    ("filterpy KalmanFilter", "update(z, H=x') per sample and row", filterpy_kf, 2),
    ("padasip FilterRLS", "FilterRLS.run per row", padasip_rls, 2),
    ("statsmodels RecursiveLS", "construct + filter per row", statsmodels_rls, 3),
]


def version_of(name: str) -> str:
    mod = {"vehid": "vehid", "C": None, "numpy": "numpy", "filterpy": "filterpy", "padasip": "padasip",
           "statsmodels": "statsmodels"}.get(name.split()[0])
    if mod is None:
        return subprocess_cc_version()
    try:
        return importlib.metadata.version(mod)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def subprocess_cc_version() -> str:
    import subprocess

    try:
        out = subprocess.run([crls.compile_command()[0], "--version"], capture_output=True, text=True, check=True)
        return out.stdout.splitlines()[0]
    except (OSError, subprocess.CalledProcessError):
        return "?"


def rel_err(theta: np.ndarray, ref: np.ndarray) -> float:
    return float(max(np.linalg.norm(theta[i] - ref[i]) / np.linalg.norm(ref[i]) for i in range(ref.shape[0])))


def best_ns(func: Callable[[], object], n: int, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - t0)
    return best / n * 1e9


def peer_table(pb: Problem) -> Tuple[Optional[Dict[str, dict]], np.ndarray]:
    """Agreement, then (only if every peer agrees) times; prints both tables. None on a disagreement."""
    ref = vehid_fit(pb)
    results: Dict[str, dict] = {}
    print(f"\n1. agreement with vehid fit() (max over rows of |θ_peer − θ_vehid| / |θ_vehid|; tolerance {TOL:g})")
    print(f"   {'peer':<28} {'version':<14} {'rel. error':>11}  verdict")
    all_ok = True
    for name, what, func, _ in PEERS:
        ver = version_of(name)
        try:
            theta = func(pb)
        except ImportError as e:
            print(f"   {name:<28} {ver:<14} {'—':>11}  SKIPPED ({e})")
            results[name] = {"status": "missing", "error": str(e)}
            continue
        err = rel_err(theta, ref)
        ok = err <= TOL
        all_ok &= ok
        results[name] = {"status": "ok" if ok else "disagrees", "rel_err": err, "version": ver, "what": what}
        print(f"   {name:<28} {ver[:14]:<14} {err:11.2e}  {'agrees' if ok else 'DISAGREES'}")
    print("   vehid θ̂ =", np.array2string(ref, precision=6, max_line_width=120).replace("\n", "\n            "))
    if not all_ok:
        print(f"\nnot every peer agrees with vehid on the {pb.name} car: no times printed", file=sys.stderr)
        return None, ref

    rows = "both rows" if len(pb.rows) == 2 else f"all {len(pb.rows)} rows"
    print(f"\n2. time per sample (one update of {rows}), best of repeats, all measured in this run")
    for name, _what, func, repeats in PEERS:
        if results[name]["status"] != "ok":
            continue
        results[name]["ns_per_sample"] = best_ns(lambda func=func: func(pb), pb.n, repeats)
        results[name]["repeats"] = repeats
    v = results["vehid fit()"]["ns_per_sample"]
    c = results["C loop (-O3 -march=native)"]["ns_per_sample"]
    print(f"   {'peer':<28} {'ns/sample':>12} {'÷ vehid fit':>12} {'÷ C loop':>10}  timed")
    for name, what, _, repeats in sorted(PEERS, key=lambda p: results[p[0]].get("ns_per_sample", float("inf"))):
        res = results[name]
        if "ns_per_sample" not in res:
            print(f"   {name:<28} {'—':>12} {'—':>12} {'—':>10}  {res['status']}")
            continue
        ns = res["ns_per_sample"]
        print(f"   {name:<28} {ns:12.1f} {ns / v:12.2f} {ns / c:10.2f}  {what} (best of {repeats})")
    return results, ref


def header(pb: Problem, seed: int) -> str:
    inputs = f", {pb.car.n_inputs} inputs" if pb.car.n_inputs > 1 else ""
    return (f"peers: {pb.name} car ({pb.x.shape[1]} states{inputs}), {pb.n} samples (seed {seed}), rows {pb.rows}, "
            f"p0 = {pb.p0:g}, r = [{', '.join(f'{v:.6g}' for v in pb.r)}]; Python {platform.python_version()}, "
            f"numpy {np.__version__}, {platform.machine()}")


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=20_000, help="quarter-car samples (default 20000)")
    ap.add_argument("--half-n", type=int, default=10_000,
                    help="half-car samples (default 10000; its peers are slow); 0 skips the half car")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", type=Path, default=None, help="also write the figures here")
    args = ap.parse_args(argv)

    pb = Problem(args.n, args.seed)
    print(header(pb, args.seed))
    results, ref = peer_table(pb)
    if results is None:
        return 1

    half: Optional[dict] = None
    if args.half_n > 0:
        hp = Problem(args.half_n, args.seed, "half")
        print("\n" + header(hp, args.seed))
        half_results, half_ref = peer_table(hp)
        if half_results is None:
            return 1
        half = {"n": args.half_n, "seed": args.seed, "rows": hp.rows, "r": hp.r.tolist(), "peers": half_results,
                "vehid_theta": half_ref.tolist()}

    if args.json is not None:
        ref_c = crls.reference_ns()
        print("\nC reference for the budgets (200000 samples, ns/sample): "
              + ", ".join(f"{k} {v:.2f}" for k, v in ref_c.items()))
        args.json.parent.mkdir(parents=True, exist_ok=True)
        out = {"n": args.n, "seed": args.seed, "peers": results, "c_reference_ns": ref_c, "vehid_theta": ref.tolist()}
        if half is not None:
            out["half_car"] = half
        args.json.write_text(json.dumps(out, indent=2))
        print(f"figures written to {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Python-level overhead of the identifiers (not a test: it prints numbers and budgets).

Measures with ``time.perf_counter`` over repeats, on the thesis quarter car:

* one ``KalmanIdentifier.update()`` call, in µs (budget: ≤ 1 µs);
* ``KalmanIdentifier.fit()`` on 10⁶ samples, in ns per sample, against the Rust per-sample
  cost (budget: within 1.5×). The Rust figure is ``--rust-ns`` (for example the
  ``update_f64/quarter/kalman_rows`` time of ``cargo bench -p vehid-benches --bench identify``),
  or an assumed 50 ns when not given, and the output says which.

Run: ``make bench-python`` or ``.venv/bin/python benches/python/overhead.py [--rust-ns 40]``;
``--json PATH`` also writes the figures (``make bench-budgets`` reads them).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Callable, List

import numpy as np

import vehid

UPDATE_BUDGET_US = 1.0
FIT_BUDGET_RATIO = 1.5
DEFAULT_RUST_NS = 50.0


def identifier(car: vehid.QuarterCar) -> vehid.KalmanIdentifier:
    return vehid.KalmanIdentifier(car, p0=1000.0, road_sigma=0.1, deriv_noise=0.005)


def timed(repeats: int, setup: Callable[[], Callable[[], None]]) -> List[float]:
    """Seconds of each of `repeats` runs of the function `setup()` returns (setup untimed)."""
    out = []
    for _ in range(repeats):
        func = setup()
        t0 = time.perf_counter()
        func()
        out.append(time.perf_counter() - t0)
    return out


def ok(good: bool) -> str:
    return "OK" if good else "OVER BUDGET"


def main(argv: List[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rust-ns", type=float, default=None,
                        help=f"Rust ns per sample to compare fit() with (default: an assumed {DEFAULT_RUST_NS:g})")
    parser.add_argument("--n", type=int, default=1_000_000, help="samples for fit() (default 1000000)")
    parser.add_argument("--calls", type=int, default=100_000, help="update() calls per repeat (default 100000)")
    parser.add_argument("--repeats", type=int, default=7, help="repeats; the best is reported (default 7)")
    parser.add_argument("--json", type=Path, default=None,
                        help="also write the figures here (read by benches/check_budgets.py)")
    args = parser.parse_args(argv)

    car = vehid.QuarterCar()
    run = vehid.Simulator(car, dt=0.05, road_sigma=0.1, ic_sigma=0.1, deriv_noise=0.005, seed=1).run(args.n)
    r, z = np.ascontiguousarray(run.r), np.ascontiguousarray(run.z)

    # --- update(): one call, from Python, on float64 (n,) arrays ------------------------
    calls = min(args.calls, args.n)
    pairs = [(r[i].copy(), z[i].copy()) for i in range(calls)]

    def updates() -> Callable[[], None]:
        kf = identifier(car)
        update = kf.update

        def go() -> None:
            for x, zk in pairs:
                update(x, zk)

        return go

    def empty_loop() -> Callable[[], None]:
        def go() -> None:
            for _x, _zk in pairs:
                pass

        return go

    def conversions() -> Callable[[], None]:
        # For scale: vehid.xi converts its two (n,) arrays like update() does, does a trivial
        # computation and returns a float (no output array).
        def go() -> None:
            for x, zk in pairs:
                vehid.xi(x, zk)

        return go

    upd = [t / calls * 1e6 for t in timed(args.repeats, updates)]
    loop = [t / calls * 1e6 for t in timed(args.repeats, empty_loop)]
    conv = [t / calls * 1e6 for t in timed(args.repeats, conversions)]

    # --- fit(): n samples in one call (GIL released) -----------------------------------
    def fit() -> Callable[[], None]:
        kf = identifier(car)

        def go() -> None:
            kf.fit(r, z)

        return go

    fit_ns = [t / args.n * 1e9 for t in timed(args.repeats, fit)]

    def fit_inputs() -> Callable[[], None]:
        # For scale: the same two (n, 4) arrays converted (copied out of numpy) and scanned once.
        def go() -> None:
            vehid.xi(r, z)

        return go

    copy_ns = [t / args.n * 1e9 for t in timed(args.repeats, fit_inputs)]

    rust_ns = DEFAULT_RUST_NS if args.rust_ns is None else args.rust_ns
    rust_src = ("given with --rust-ns" if args.rust_ns is not None
                else "ASSUMED default, not measured: pass --rust-ns from `cargo bench -p vehid-benches "
                "--bench identify -- update_f64/quarter/kalman_rows`")
    ratio = min(fit_ns) / rust_ns

    print(f"vehid {vehid.__version__} Python overhead: quarter car, KalmanIdentifier(mode='rows', p0=1000, "
          f"road_sigma=0.1, deriv_noise=0.005); Python {sys.version.split()[0]}, numpy {np.__version__}")
    print(f"update(): {min(upd):7.3f} us per call  (best of {args.repeats} x {calls} calls; median "
          f"{statistics.median(upd):.3f}; the bare loop costs {min(loop):.3f})   budget <= {UPDATE_BUDGET_US:g} us: "
          f"{ok(min(upd) <= UPDATE_BUDGET_US)}")
    print(f"          for scale: vehid.xi(r_k, z_k) (two (n,) conversions, no output array) "
          f"{min(conv):.3f} us")
    print(f"fit():    {min(fit_ns):7.2f} ns per sample on {args.n} samples  (best of {args.repeats}; median "
          f"{statistics.median(fit_ns):.2f})")
    print(f"          for scale: vehid.xi(r, z) on the same arrays (the two input copies and one pass) "
          f"{min(copy_ns):.2f} ns per sample")
    print(f"Rust:     {rust_ns:7.2f} ns per sample  ({rust_src})")
    print(f"fit()/Rust = {ratio:.2f}   budget <= {FIT_BUDGET_RATIO:g}: {ok(ratio <= FIT_BUDGET_RATIO)}")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({
            "vehid": vehid.__version__, "n": args.n, "calls": calls, "repeats": args.repeats,
            "update_us_best": min(upd), "update_us_median": statistics.median(upd),
            "fit_ns_best": min(fit_ns), "fit_ns_median": statistics.median(fit_ns),
        }, indent=2) + "\n")
        print(f"figures written to {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Identification on ISO 8608 roads (the real-roads must-show): the passenger quarter car,
its true states and derivatives, 300 s at 200 Hz per run.

``--generator vehid`` (default) drives the car with vehid's own simulator (the ISO 8608 shaping
filter, the road model the identifier assumes); ``--generator independent`` with
``benches/independent_road.py`` (a random-phase harmonic road over ISO 8608's band, integrated by
scipy): no code or road model in common with vehid.

For each setting (road class B..E at 10, 20, 30 m/s, and a speed varying over 8..30 m/s with the
odometer given), over ``--seeds`` seeds from ``--seed0``:

- the thesis' identifier (the exact-start Kalman identifier, i.e. least squares, on the physical
  structure with the wheel mass known) and vehid's coloured-road identifier
  (``IVIdentifier(structure, road="iso8608", spacing=...)``), each giving M, k1, k2, b;
- how many of the first ``--first`` seeds have every constant within 5 % (target: >= 9 of 10);
- how often each constant's nominal 95 % interval holds the truth over all seeds (90-98 %).

Prints one progress line per setting and a table at the end; ``--json PATH`` writes the figures.
Reproducible from the seeds: ``.venv/bin/python benches/real_roads.py --seed0 50000 --seeds 100``.
``--half`` / ``--full``: the half car / the full car on one road by road cancellation (e.g.
``benches/real_roads.py --full --seed0 61000 --seeds 10 --classes B,C,D --speeds 10,20 --samples 20000``);
``--full --sensors realistic``: the full car from its realistic sensors (``RealisticIdentifier(full)``;
``--half --sensors realistic`` the half car's).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import vehid

sys.path.insert(0, str(Path(__file__).resolve().parent))
import independent_road  # noqa: E402  (benches/ is not a package)

DT = 0.005
N = 60_000  # 300 s at 200 Hz
CONSTANTS = ("M", "k1", "k2", "b")


def speed_profile(seed: int) -> np.ndarray:
    """A smooth speed between 8 and 30 m/s: a sine of period 60 s with a random phase."""
    t = np.arange(N) * DT
    phase = np.random.default_rng(seed).uniform(0, 2 * np.pi)
    return 19.0 + 11.0 * np.sin(2 * np.pi * t / 60.0 + phase)


def noisy(a: np.ndarray, frac: float, rng: np.random.Generator) -> np.ndarray:
    """``a`` with white noise of ``frac`` times each column's standard deviation."""
    return a + frac * a.std(axis=0) * rng.standard_normal(a.shape) if frac > 0 else a


def one_run(
    car: vehid.QuarterCar, cls: str, speed: float | None, seed: int, lags: int | None, noise: float = 0.0,
    generator: str = "vehid", min_spacing: float | None = None,
) -> dict[str, dict[str, tuple]]:
    truth = car.params
    s = car.structure(known={"m": truth["m"]})
    sp = speed_profile(seed) if speed is None else speed
    if generator == "vehid":
        run = vehid.Simulator(car, dt=DT, road=f"iso8608-{cls}", speed=sp, sensors="state", seed=seed).run(N)
        x0, xd0, dist = run.x, run.xdot, run.s
    else:
        x0, xd0, dist = independent_road.simulate(truth, cls, sp, DT, N, seed)
    rng = np.random.default_rng(seed + 7_777_777)
    x, xd = noisy(x0, noise, rng), noisy(xd0, noise, rng)
    delay = 2 if noise > 0 else 1  # white noise, differenced, is correlated over two samples
    out = {}
    thesis = vehid.KalmanIdentifier(s)
    thesis.fit(x, xd)
    out["thesis"] = car.physical(thesis.stats(), m=truth["m"])
    spaced = {} if min_spacing is None else {"min_spacing": min_spacing}
    if speed is None:
        road = vehid.IVIdentifier(s, delay, lags=lags, road="iso8608", spacing="odometer", **spaced)
        road.fit(x, xd, u=dist[:, None])
    else:
        road = vehid.IVIdentifier(s, delay, lags=lags, road="iso8608", spacing=speed * DT, **spaced)
        road.fit(x, xd)
    out["road"] = car.physical(road.stats(), m=truth["m"])
    return out


def half_car(seed0: int, seeds: int, classes: str, speeds: str) -> int:
    """The passenger half car on ISO roads (the rear wheel on the front wheel's road a wheelbase
    later), true states: ``TwoAxleIdentifier`` on its physical structure (m1, m2, l1, l2 known),
    road cancellation; how many of the 28 nonzero entries of the unknown rows are within 5 %."""
    half = vehid.HalfCar.passenger()
    p = half.params
    s = half.structure(known={k: p[k] for k in ("m1", "m2", "l1", "l2")})
    rows = list(half.unknown_rows)
    nz = half.a[rows] != 0
    for cls in classes.split(","):
        for v in (float(x) for x in speeds.split(",") if x != "varying"):
            good, worst = 0, []
            for seed in range(seed0, seed0 + seeds):
                run = vehid.Simulator(half, dt=DT, road=f"iso8608-{cls}", speed=v, sensors="state", seed=seed).run(N)
                two = vehid.TwoAxleIdentifier(s, car=half, spacing=v * DT, compensate=False)
                two.fit(run.x, run.xdot)
                err = np.abs(two.a_hat[rows][nz] / half.a[rows][nz] - 1)
                good += bool(np.all(err < 0.05))
                worst.append(float(err.max()))
            print(f"half car, {cls} {v:.0f} m/s: all {int(nz.sum())} entries within 5 % on {good}/{seeds} seeds;"
                  f" worst entry's error: median {100 * np.median(worst):.2g} %, largest {100 * max(worst):.2g} %",
                  flush=True)
    return 0


def full_car(seed0: int, seeds: int, classes: str, speeds: str, n: int, generator: str = "vehid") -> int:
    """The passenger full car on ISO roads (two coherent tracks, each rear wheel on its front
    wheel's track a wheelbase later), true states, ``n`` samples at 200 Hz:
    ``TwoAxleIdentifier(FullCar)``, road cancellation per track (the direct front equation off:
    the road is not white); how many seeds have every nonzero entry of the seven unknown rows
    within 5 % (66 for the passenger car, without anti-roll bars), the worst entry, the worst
    identified constant through ``physical()`` (wheel masses known), and the plain rows' worst
    wheel entry on the same samples."""
    car = vehid.FullCar.passenger()
    masses = {k: v for k, v in car.params.items() if k.startswith("m_")}
    named = [k for k in car.params if k in ("M", "Jx", "Jy") or k[:2] in ("k_", "b_")]
    rows = list(car.unknown_rows)
    nz = car.a[rows] != 0
    wheel = [r for r in rows if r < 8]
    wnz = car.a[wheel] != 0
    t0 = time.time()
    for cls in classes.split(","):
        for v in (float(x) for x in speeds.split(",") if x != "varying"):
            good, worst, consts, plain = 0, [], [], []
            for i, seed in enumerate(range(seed0, seed0 + seeds)):
                if generator == "vehid":
                    run = vehid.Simulator(car, dt=DT, road=f"iso8608-{cls}", speed=v, sensors="state", seed=seed).run(n)
                    x, xdot = run.x, run.xdot
                else:
                    x, xdot, _ = independent_road.simulate_full(car.params, cls, v, DT, n, seed)
                two = vehid.TwoAxleIdentifier(car, spacing=v * DT, direct_front=False)
                two.fit(x, xdot)
                err = np.abs(two.a_hat[rows][nz] / car.a[rows][nz] - 1)
                good += bool(np.all(err < 0.05))
                worst.append(float(err.max()))
                est = car.physical(two.theta, **masses)
                consts.append(max(abs(est[k] / car.params[k] - 1) for k in named))
                rows_only = vehid.TwoAxleIdentifier(car, spacing=v * DT, method="none")
                rows_only.fit(x, xdot)
                plain.append(float(np.abs(rows_only.a_hat[wheel][wnz] / car.a[wheel][wnz] - 1).max()))
                print(f"[{i + 1}/{seeds} {time.time() - t0:.0f} s] full car {cls} {v:.0f} m/s seed {seed}: worst entry"
                      f" {100 * worst[-1]:.2f} %, worst constant {100 * consts[-1]:.2f} %, plain rows"
                      f" {100 * plain[-1]:.0f} %", flush=True)
            print(f"full car ({generator}), {cls} {v:.0f} m/s, {n} samples: all {int(nz.sum())} entries within 5 %"
                  f" on {good}/{seeds} seeds; worst entry median {100 * np.median(worst):.2g} %, largest"
                  f" {100 * max(worst):.2g} %;"
                  f" worst of M, Jx, Jy, k, b: median {100 * np.median(consts):.2g} %, largest"
                  f" {100 * max(consts):.2g} %; plain rows' worst wheel entry: median {100 * np.median(plain):.0f} %",
                  flush=True)
    return 0


def lift_off(seed0: int, seeds: int) -> int:
    """Class E at 25 m/s with a tyre that only pushes (``independent_road.simulate_lift_off``):
    the share of samples off the ground, how many of them the lift-off check counts (the nominal
    M 10 % off), whether the run is flagged (``vehid identify``'s rule: more than 0.5 % counted),
    and how far the constants are off."""
    car = vehid.QuarterCar.passenger()
    truth = car.params
    s = car.structure(known={"m": truth["m"]})
    shares, found, errs, flagged, missed = [], [], [], 0, []
    for i, seed in enumerate(range(seed0, seed0 + seeds)):
        x, xd, lifted = independent_road.simulate_lift_off(truth, "E", 25.0, DT, N, seed)
        iv = vehid.IVIdentifier(s, road="iso8608", spacing=25.0 * DT, lift_off=(1.1 * truth["M"], truth["m"]))
        iv.fit(x, xd)
        phys = car.physical(iv.stats(), m=truth["m"])
        shares.append(lifted.mean())
        found.append(iv.lifted / max(1, int(lifted.sum())))
        # The check reads each sample alone: fed only the flight samples, it counts those it sees.
        flight = vehid.IVIdentifier(s, road="iso8608", spacing=25.0 * DT, min_spacing=0.0,
                                    lift_off=(1.1 * truth["M"], truth["m"]))
        flight.fit(x[lifted], xd[lifted])
        missed.append(int(lifted.sum()) - flight.lifted)
        errs.append(max(abs(phys[k][0] / truth[k] - 1) for k in CONSTANTS))
        flagged += iv.lifted > 0.005 * len(x)
        print(f"[{i + 1}/{seeds}] seed {seed}: off the ground {100 * lifted.mean():.1f} %, counted"
              f" {iv.lifted} for {int(lifted.sum())}, worst constant {100 * errs[-1]:.1f} % off", flush=True)
    print(f"off the ground: median {100 * np.median(shares):.1f} % of samples; flight samples missed: at most "
          f"{max(missed)} per run; counted / lifted: median {np.median(found):.2f}, least {min(found):.3f}; "
          f"flagged {flagged}/{seeds}; worst constant's error: median "
          f"{100 * np.median(errs):.1f} %, within 5 % on {sum(e < 0.05 for e in errs)}/{seeds}")
    return 0


def realistic(seed0: int, seeds: int, first: int, classes: str, speeds: str, generator: str) -> int:
    """The realistic sensors (body and wheel accelerometers, deflection; vehid's default noise and
    biases): ``RealisticIdentifier`` on ``QuarterCar.structure(known={"M": ...}, sensors="realistic")``
    gives k2 and b (m and k1 are not determined); within 5 % on the first ``first`` seeds, and the
    95 % intervals' coverage over all seeds. ``--generator independent``: the channels from
    ``independent_road.simulate`` (scipy; its true accelerations and deflection, with the same
    sensor noise and biases as vehid's defaults added here)."""
    car = vehid.QuarterCar.passenger()
    truth = car.params
    s = car.structure(known={"M": truth["M"]}, sensors="realistic")
    settings = [(c, None if v == "varying" else float(v)) for c in classes.split(",") for v in speeds.split(",")]
    t0 = time.time()
    rows = []
    for i, (cls, speed) in enumerate(settings):
        cover, within, worst = {"k2": 0, "b": 0}, 0, []
        for j, seed in enumerate(range(seed0, seed0 + seeds)):
            sp = speed_profile(seed) if speed is None else speed
            if generator == "vehid":
                y = vehid.Simulator(car, dt=DT, road=f"iso8608-{cls}", speed=sp, sensors="realistic",
                                    seed=seed).run(N).y
            else:
                x, xd, _ = independent_road.simulate(truth, cls, sp, DT, N, seed)
                rng = np.random.default_rng(seed + 9_999)
                # vehid's default realistic noise: white 0.02 / 0.1 m/s^2, biases of std 0.1 / 0.3 m/s^2,
                # deflection 0.3 mm.
                a_b = xd[:, 3] + 0.02 * rng.standard_normal(N) + 0.1 * rng.standard_normal()
                a_w = xd[:, 1] + 0.1 * rng.standard_normal(N) + 0.3 * rng.standard_normal()
                d = x[:, 2] - x[:, 0] + 0.3e-3 * rng.standard_normal(N)
                y = np.column_stack([a_b, a_w, d])
            phys = car.physical(vehid.RealisticIdentifier(s, DT).fit(y).stats())
            err = max(abs(phys[k][0] / truth[k] - 1) for k in cover)
            worst.append(err)
            within += j < first and err < 0.05
            for k in cover:
                cover[k] += phys[k][1] <= truth[k] <= phys[k][2]
        label = f"{cls} {'8-30' if speed is None else f'{speed:.0f}'} m/s"
        rows.append((label, within, cover, float(np.median(worst)), float(max(worst))))
        print(f"[{i + 1}/{len(settings)} {time.time() - t0:.0f} s] realistic sensors, {label}: k2 and b within 5 % on"
              f" {within}/{min(first, seeds)}; 95 % coverage k2 {100 * cover['k2'] / seeds:.0f} %, b"
              f" {100 * cover['b'] / seeds:.0f} %; worst error median {100 * rows[-1][3]:.2f} %,"
              f" largest {100 * rows[-1][4]:.2f} %", flush=True)
    return 0


#: The full car of the realistic-sensor runs: the passenger car with anti-roll bars (N m/rad),
#: so that the bars are identified too.
FULL_BARS = {"arb_f": 15_000.0, "arb_r": 8_000.0}


def realistic_full(seed0: int, seeds: int, first: int, classes: str, speeds: str, generator: str, n: int,
                   half: bool = False) -> int:
    """The full car's realistic sensors (a body accelerometer above each wheel, the wheel
    accelerometers, each corner's deflection; vehid's default noise and biases), the passenger
    car with anti-roll bars (:data:`FULL_BARS`), ``n`` samples at 200 Hz:
    ``RealisticIdentifier(full)`` and ``full.physical(stats, M=...)`` give Jx, Jy, each spring
    and damper and both bars (the tyres and wheel masses are not determined); every constant
    within 5 % on the first ``first`` seeds, and each 95 % interval's coverage over all seeds.
    ``--generator independent``: the states from ``independent_road.simulate_full`` (Lagrange's
    equations, scipy), the channels formed by ``independent_road.full_realistic``.
    ``half``: the passenger half car instead (J, k12, k22, b1, b2; vehid's drives only)."""
    if half and generator != "vehid":
        raise SystemExit("--half --sensors realistic: vehid's drives only (--generator vehid)")
    car: Any = vehid.HalfCar.passenger() if half else vehid.FullCar(**{**vehid.FullCar.passenger().params,
                                                                       **FULL_BARS})
    truth = car.params
    names = (["J", "k12", "k22", "b1", "b2"] if half else
             ["Jx", "Jy", *[f"{q}_{c}" for q in ("k", "b") for c in ("fl", "fr", "rl", "rr")], "arb_f", "arb_r"])
    settings = [(c, float(v)) for c in classes.split(",") for v in speeds.split(",")]
    t0 = time.time()
    for i, (cls, speed) in enumerate(settings):
        cover = {k: 0 for k in names}
        within, worst = 0, []
        for j, seed in enumerate(range(seed0, seed0 + seeds)):
            if generator == "vehid":
                y = vehid.Simulator(car, dt=DT, road=f"iso8608-{cls}", speed=speed, sensors="realistic",
                                    seed=seed).run(n).y
            else:
                x, xd, _ = independent_road.simulate_full(truth, cls, speed, DT, n, seed)
                y = independent_road.full_realistic(truth, x, xd, np.random.default_rng(seed + 9_999))
            phys = car.physical(vehid.RealisticIdentifier(car, DT).fit(y).stats(), M=truth["M"])
            err = {k: abs(phys[k][0] / truth[k] - 1) for k in names}
            worst.append(max(err.values()))
            within += j < first and worst[-1] < 0.05
            for k in names:
                cover[k] += phys[k][1] <= truth[k] <= phys[k][2]
            print(f"[{i + 1}/{len(settings)}, seed {j + 1}/{seeds}, {time.time() - t0:.0f} s] worst constant"
                  f" {max(err, key=err.__getitem__)} {100 * worst[-1]:.2f} %", flush=True)
        cov = ", ".join(f"{k} {100 * cover[k] / seeds:.0f}" for k in names)
        print(f"{'half' if half else 'full'} car, realistic sensors ({generator}), {cls} {speed:.0f} m/s, {n} samples:"
              f" every constant within"
              f" 5 % on {within}/{min(first, seeds)}; worst error median {100 * np.median(worst):.2f} %, largest"
              f" {100 * max(worst):.2f} %; 95 % coverage (%): {cov}", flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed0", type=int, default=50_000)
    ap.add_argument("--seeds", type=int, default=100, help="seeds per setting (coverage)")
    ap.add_argument("--first", type=int, default=10, help="seeds counted for 'within 5 %%'")
    ap.add_argument("--classes", default="B,C,D,E")
    ap.add_argument("--speeds", default="10,20,30,varying")
    ap.add_argument("--lags", type=int, default=None, help="IVIdentifier lags (default: its own)")
    ap.add_argument("--noise", type=float, default=0.0,
                    help="white state and derivative noise, fraction of each signal's std")
    ap.add_argument("--generator", choices=["vehid", "independent"], default="vehid")
    ap.add_argument("--min-spacing", type=float, default=None,
                    help="IVIdentifier min_spacing, m (default: its own, 0.25)")
    ap.add_argument("--half", action="store_true", help="the half car by road cancellation instead")
    ap.add_argument("--full", action="store_true",
                    help="the full car by road cancellation on two tracks instead (speeds must divide its 3.1 m"
                         " wheelbase into whole 5 ms samples: 10, 20, 31 m/s)")
    ap.add_argument("--samples", type=int, default=N, help="samples per run (--full)")
    ap.add_argument("--lift-off", action="store_true",
                    help="class E at 25 m/s with a tyre that lifts off instead: counted and flagged?")
    ap.add_argument("--sensors", choices=["state", "realistic"], default="state",
                    help="realistic: accelerometers and deflection, RealisticIdentifier (k2, b with M known)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    if a.sensors == "realistic" and (a.full or a.half):
        return realistic_full(a.seed0, a.seeds, a.first, a.classes, a.speeds, a.generator, a.samples, a.half)
    if a.sensors == "realistic":
        return realistic(a.seed0, a.seeds, a.first, a.classes, a.speeds, a.generator)
    if a.half:
        return half_car(a.seed0, min(a.seeds, a.first), a.classes, a.speeds)
    if a.full:
        return full_car(a.seed0, min(a.seeds, a.first), a.classes, a.speeds, a.samples, a.generator)
    if a.lift_off:
        return lift_off(a.seed0, a.seeds)
    car = vehid.QuarterCar.passenger()
    truth = car.params
    settings = [(c, None if v == "varying" else float(v)) for c in a.classes.split(",") for v in a.speeds.split(",")]
    results = []
    t0 = time.time()
    for i, (cls, speed) in enumerate(settings):
        within = {"thesis": 0, "road": 0}
        cover = {k: 0 for k in CONSTANTS}
        worst = []
        for j, seed in enumerate(range(a.seed0, a.seed0 + a.seeds)):
            res = one_run(car, cls, speed, seed, a.lags, a.noise, a.generator, a.min_spacing)
            for name, phys in res.items():
                err = max(abs(phys[k][0] / truth[k] - 1) for k in CONSTANTS)
                if j < a.first:
                    within[name] += err < 0.05
                if name == "road":
                    worst.append(err)
            for k in CONSTANTS:
                _, lo, hi = res["road"][k]
                cover[k] += lo <= truth[k] <= hi
        label = f"{cls} {'8-30' if speed is None else f'{speed:.0f}'} m/s"
        row = {
            "setting": label,
            "within_5pct_road": within["road"],
            "within_5pct_thesis": within["thesis"],
            "first": min(a.first, a.seeds),
            "coverage": {k: cover[k] / a.seeds for k in CONSTANTS},
            "median_worst_error": float(np.median(worst)),
            "seeds": a.seeds,
        }
        results.append(row)
        cov = " ".join(f"{k} {100 * row['coverage'][k]:.0f}%" for k in CONSTANTS)
        print(
            f"[{i + 1}/{len(settings)} {time.time() - t0:.0f} s] {label}: within 5 %: road"
            f" {within['road']}/{row['first']}, thesis {within['thesis']}/{row['first']}; 95 % coverage {cov};"
            f" median worst error"
            f" {100 * row['median_worst_error']:.2f} %",
            flush=True,
        )
    print("\nsetting        | within 5 % (coloured road / thesis) | 95 % coverage M, k1, k2, b")
    for r in results:
        cov = ", ".join(f"{100 * r['coverage'][k]:.0f}" for k in CONSTANTS)
        within = f"{r['within_5pct_road']}/{r['first']} / {r['within_5pct_thesis']}/{r['first']}"
        print(f"{r['setting']:<14} | {within:<35} | {cov}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"seed0": a.seed0, "seeds": a.seeds, "noise": a.noise, "generator": a.generator,
                       "results": results}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())

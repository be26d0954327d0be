"""The full car identified from its full state, on fresh seeds.

The thesis' protocol on the passenger full car (``vehid.FullCar.passenger()``, with anti-roll
bars added so that they are identified too): a white road held per sample (σ_u = 1 cm, Eq 4.25)
under each wheel, the full state measured without noise and its derivative with the
Simulator's default σ_v = 0.005 (the thesis' derivative noise), at 200 Hz; the seven
acceleration rows by batch least squares, the constants back through ``FullCar.physical``
(wheel masses known; the tyres from B; the geometry the car's). Prints, per seed, the worst
relative error of the 21 identified constants (the bars against the springs' roll stiffness
k t²/4) and the worst relative error of the nonzero entries of each kind of row (the body
rows, which see no road, and the wheel rows, which carry the road as noise), then how many
seeds have every constant within 5 %.

Run (after building the extension; about a second per seed)::

    python benches/full_car_identify.py                      # seeds 9000-9009, 120 000 samples
    python benches/full_car_identify.py --seeds 9100 9120 --samples 60000
"""

from __future__ import annotations

import argparse

import numpy as np

import vehid

CORNERS = ("fl", "fr", "rl", "rr")


def one_seed(car: vehid.FullCar, seed: int, n: int) -> tuple[float, str, float, float]:
    run = vehid.Simulator(car, dt=0.005, road_sigma=0.01, seed=seed).run(n)
    ls = vehid.BatchLeastSquares(car)
    ls.fit(run.r, run.z)
    theta = ls.theta
    est = car.physical(theta, **{f"m_{c}": car.params[f"m_{c}"] for c in CORNERS})
    worst, name = 0.0, ""
    roll_scale = car.params["k_fl"] * car.params["track_f"] ** 2 / 4
    for k, v in car.params.items():
        scale = roll_scale if k.startswith("arb") else v
        rel = abs(est[k] - v) / scale
        if rel > worst:
            worst, name = rel, k
    truth = car.theta
    nz = truth != 0
    rel_rows = np.where(nz, np.abs(theta - truth) / np.where(nz, np.abs(truth), 1.0), 0.0)
    return worst, name, float(rel_rows[4:].max()), float(rel_rows[:4].max())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", nargs=2, type=int, default=[9000, 9010], metavar=("FIRST", "END"))
    ap.add_argument("--samples", type=int, default=120_000)
    args = ap.parse_args()
    car = vehid.FullCar(**{**vehid.FullCar.passenger().params, "arb_f": 15000.0, "arb_r": 6000.0})
    ok = 0
    seeds = range(*args.seeds)
    for seed in seeds:
        worst, name, body, wheel = one_seed(car, seed, args.samples)
        ok += worst < 0.05
        print(
            f"seed {seed}: worst constant {name} {100 * worst:.2f} %; worst nonzero entry: "
            f"body rows {100 * body:.3g} %, wheel rows {100 * wheel:.3g} %",
            flush=True,
        )
    print(f"{ok}/{len(seeds)} seeds with every constant within 5 % after {args.samples} samples")


if __name__ == "__main__":
    main()

"""States that could be saved but not restored: a BatchLeastSquares on a structure, and a health
monitor saved while a channel had been stuck longer than its delay line."""

from __future__ import annotations

import copy
import pickle

import vehid


def test_batch_least_squares_on_a_structure_pickles_and_continues() -> None:
    s = vehid.QuarterCar().structure(known={"m": 1.0})
    run = vehid.Simulator(vehid.QuarterCar(), seed=74_001).run(3000)
    a = vehid.BatchLeastSquares(s)
    a.fit(run.r[:1500], run.z[:1500])
    b, c = pickle.loads(pickle.dumps(a)), copy.deepcopy(a)
    for ident in (a, b, c):
        ident.fit(run.r[1500:], run.z[1500:])
    assert a.params.tolist() == b.params.tolist() == c.params.tolist()


def test_a_monitor_stuck_for_longer_than_its_delay_line_pickles() -> None:
    car = vehid.QuarterCar.passenger()
    y = vehid.Simulator(car, dt=0.005, road="iso8608-C", speed=15.0, sensors="realistic", seed=74_002).run(8000).y
    mon = vehid.HealthMonitor(car, dt=0.005)
    mon.fit(y[:6000])
    stuck = y[6000:6300].copy()
    stuck[:, 2] = stuck[0, 2]  # the deflection sensor stuck for 300 samples (the line holds 64)
    mon.fit(stuck)
    back = pickle.loads(pickle.dumps(mon))
    assert [e.t for e in mon.fit(y[6300:])] == [e.t for e in back.fit(y[6300:])]
    assert pickle.dumps(mon) == pickle.dumps(back)

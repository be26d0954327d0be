"""The full car's health monitor from Python (`vehid.HealthMonitor(FullCar)`, Rust
`vehid_core::health::FullHealthMonitor`): the api.md example, naming by corner, a load,
pickling, bad input, `vehid monitor --model full`, a point load, drives from an independent
simulator."""

import importlib.util
import io
import json
import pickle
from pathlib import Path

import numpy as np
import pytest
from bench_scripts import load  # tests/ is on sys.path under pytest

import vehid
from vehid import cli, monitor

DT = 0.005
FULL = vehid.FullCar.passenger()
# The full car written without vehid (Lagrange's equations, scipy's lsim): benches/independent_road.py.
INDEPENDENT = load("independent_road")


def drive(seconds: float, changes: object = None, seed: int = 1) -> vehid.Run:
    sim = vehid.Simulator(FULL, dt=DT, road="iso8608-C", speed=15.0, changes=changes,  # type: ignore[arg-type]
                          sensors="realistic", seed=seed)
    return sim.run(int(round(seconds / DT)))


def test_the_api_example_names_the_front_left_damper() -> None:
    # api.md, Wave 3: the damper of the front left corner from 1000 to 1350 N s/m at 60 s.
    full = vehid.FullCar.passenger()
    sim = vehid.Simulator(full, dt=0.005, road="iso8608-C", speed=15.0,
                          changes=[(60.0, {"b_fl": 1350.0})], sensors="realistic", seed=1)
    mon = vehid.HealthMonitor(full, dt=0.005, sensors="realistic")
    events = mon.fit(sim.run(20_000).y)
    assert len(events) == 1, events
    ev = events[0]
    assert ev.parameter == "b_fl"
    assert 60.0 < ev.t < 75.0 and abs(ev.change - 0.35) < 0.05, ev
    assert ev.low < 1350.0 < ev.high
    assert mon.constants["b_fl"] == ev.after and mon.constants["M"] == 1500.0


def test_a_rear_right_spring_pickles_and_continues_bit_for_bit() -> None:
    run = drive(100.0, changes=[(40.0, {"k_rr": 34_200.0})], seed=52)
    mon = vehid.HealthMonitor(FULL, dt=DT)
    assert mon.channels == run.channels and len(mon.channels) == 12
    assert mon.fit(run.y[:6000]) == [] and mon.status == "monitoring"
    ref = mon.reference
    assert ref is not None and sorted(ref) == ["fl", "fr", "rl", "rr"] and len(ref["fl"]) == 9
    assert len(mon.estimate["rr"]) == 9
    twin = pickle.loads(pickle.dumps(mon))
    events = mon.fit(run.y[6000:])
    assert [e.parameter for e in events] == ["k_rr"] and abs(events[0].change + 0.10) < 0.03
    assert twin.fit(run.y[6000:]) == events
    assert pickle.loads(pickle.dumps(events[0])) == events[0]


def test_a_load_and_bad_input() -> None:
    run = drive(100.0, changes=[(40.0, {"M": 1800.0, "Jx": 552.0, "Jy": 2592.0})], seed=53)
    mon = vehid.HealthMonitor(FULL, dt=DT)
    events = mon.fit(run.y)
    assert [e.parameter for e in events] == ["M"] and abs(events[0].change - 0.20) < 0.03
    assert abs(mon.constants["Jy"] / 2160.0 - mon.constants["M"] / 1500.0) < 1e-12
    with pytest.raises(vehid.VehidError, match=r"shape \(12,\)"):
        mon.update(np.zeros(6))
    before = pickle.dumps(mon)
    with pytest.raises(vehid.VehidError, match="infinite"):
        mon.fit(np.full((3, 12), np.inf))
    assert pickle.dumps(mon) == before
    state = vehid.HealthMonitor(FULL, dt=DT, sensors="state")
    with pytest.raises(vehid.VehidError, match=r"shape \(28,\)"):
        state.update(np.zeros(12))


def test_a_boot_load_is_named_with_its_mass_and_place(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # 100 kg set down 0.8 m behind the rear axle, 0.4 m right of centre, at 40 s (the drive's
    # point load): one event 'M', 1500 -> ~1600 kg with its interval holding 1600, the place
    # within 0.5 m; the monitor's constants gain the load (Jx, Jy about the nominal centre of
    # mass); the event pickles with its position and prints it on the command line.
    run = drive(90.0, changes=[(40.0, {"load": 100.0, "load_x": -2.5, "load_y": -0.4})], seed=55)
    mon = vehid.HealthMonitor(FULL, dt=DT)
    events = mon.fit(run.y)
    assert [e.parameter for e in events] == ["M"], events
    ev = events[0]
    assert abs(ev.after - 1600.0) < 45.0 and ev.low < 1600.0 < ev.high, ev
    assert ev.position is not None and np.hypot(ev.position[0] + 2.5, ev.position[1] + 0.4) < 0.5, ev
    m, (x, y) = ev.after - 1500.0, ev.position
    assert mon.constants["Jy"] == pytest.approx(2160.0 + m * x * x) and mon.constants["Jx"] == pytest.approx(
        460.0 + m * y * y)
    assert pickle.loads(pickle.dumps(ev)) == ev and "position=" in repr(ev)
    d = ev.to_dict()
    assert (d["load_x"], d["load_y"]) == ev.position
    with pytest.raises(vehid.VehidError, match="position"):
        vehid.Event(1.0, 0.5, "b_fl", 1000.0, 900.0, 880.0, 920.0, -0.1, (0.0, 0.0))
    log = tmp_path / "boot.csv"
    np.savetxt(log, np.column_stack([run.t, run.y]), delimiter=",", header="t," + ",".join(run.channels),
               comments="")
    assert cli.main(["monitor", str(log), "--model", "full"]) == 0
    out = capsys.readouterr().out
    assert "M (body mass)" in out and "a load at x -2." in out and "toward the rear right corner" in out, out


def realistic(x: np.ndarray, xdot: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The passenger full car's realistic channels from its states, with vehid's default
    sensor noise (benches/independent_road.full_realistic: the geometry written there)."""
    return INDEPENDENT.full_realistic(FULL.params, x, xdot, rng)


@pytest.mark.parametrize("case", ["none", "b_rl", "boot"])
def test_the_monitor_on_an_independent_simulator(case: str) -> None:
    # Drives from benches/independent_road.py (Lagrange's equations and two random-phase
    # harmonic tracks written without vehid, scipy's lsim; a change from sample 12,000 = 60 s
    # on, integrated on from the state there), the sensors formed here: no event without a
    # change; the rear left damper -10 % named within 3 points; 100 kg in the boot (0.8 m
    # behind the rear axle, 0.3 m left) named M, 1500 -> 1600 kg within 3 points of M, placed
    # within 0.5 m.
    n, k = 18_000, 12_000
    change = {"none": None, "b_rl": (k, {"b_rl": 900.0}, None), "boot": (k, {}, (100.0, -2.5, 0.3))}[case]
    x, xdot, _ = INDEPENDENT.simulate_full(FULL.params, "C", 15.0, DT, n, seed=71, change=change)
    y = realistic(x, xdot, np.random.default_rng(72))
    events = vehid.HealthMonitor(FULL, dt=DT).fit(y)
    if case == "none":
        assert events == []
        return
    assert len(events) == 1, events
    ev = events[0]
    assert 60.0 < ev.t < 70.0, ev
    if case == "b_rl":
        assert ev.parameter == "b_rl" and abs(ev.change + 0.10) < 0.03, ev
    else:
        assert ev.parameter == "M" and abs(ev.change - 100.0 / 1500.0) < 0.03, ev
        assert ev.position is not None and np.hypot(ev.position[0] + 2.5, ev.position[1] - 0.3) < 0.5, ev


def test_vehid_monitor_model_full(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = drive(100.0, changes=[(40.0, {"b_rl": 900.0})], seed=54)
    log = tmp_path / "full.csv"
    header = "t," + ",".join(run.channels)
    np.savetxt(log, np.column_stack([run.t, run.y]), delimiter=",", header=header, comments="")
    assert cli.main(["monitor", str(log), "--model", "full", "--json"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1, out
    ev = json.loads(out[0])
    assert ev["parameter"] == "b_rl" and ev["name"] == "rear left damper" and ev["before"] == 1000.0
    assert abs(ev["change"] + 0.10) < 0.03
    if importlib.util.find_spec("matplotlib") is not None:
        png = tmp_path / "full.png"
        assert cli.main(["monitor", str(log), "--model", "full", "--plot", str(png)]) == 0
        assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # What the plot draws: each corner's spring and damper, their change since the warm-up
    # from the corner's own equation; at the end of the drive the rear left damper's is the
    # -10 % change and the seven others 0, each within its band.
    mon = vehid.HealthMonitor(FULL, dt=DT, sensors="realistic")
    feeder = monitor.Feeder(mon, 0.0, io.StringIO(), False)
    feeder.feed(run.y)
    last = feeder.record.corners[-1]
    assert last.shape == (8, 3) and np.isnan(feeder.record.corners[0]).all()
    truth = np.zeros(8)
    truth[5] = 900.0 / 1000.0 - 1.0  # k_fl, b_fl, k_fr, b_fr, k_rl, b_rl, ...
    assert np.abs(last[:, 0] - truth).max() < 0.03, last
    assert ((last[:, 1] < last[:, 0]) & (last[:, 0] < last[:, 2])).all(), last
    assert cli.main(["monitor", str(log), "--model", "full", "--sensors", "state"]) == 2
    assert "z_fl" in capsys.readouterr().err  # a log of the realistic sensors has no state channels


def test_state_sensors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # The 28 state channels with 0.1 mm and 0.02 m/s^2 of white noise, from Python and from the
    # command line (vehid simulate --sensors state, vehid monitor --sensors state --noise
    # state=...,deriv=...): the rear left damper -10 % at 40 s named within 3 points; noise-free
    # too (the accelerometer floor).
    sim = vehid.Simulator(FULL, dt=DT, road="iso8608-C", speed=15.0, changes=[(40.0, {"b_rl": 900.0})],
                          sensors="state", state_noise=1e-4, deriv_noise=0.02, seed=57)
    run = sim.run(14_000)
    mon = vehid.HealthMonitor(FULL, dt=DT, sensors="state", sensor_noise={"state": 1e-4, "deriv": 0.02})
    events = mon.fit(run.y)
    assert [e.parameter for e in events] == ["b_rl"] and abs(events[0].change + 0.10) < 0.03, events
    log = tmp_path / "state.csv"
    for noise in (["--state-noise", "1e-4", "--deriv-noise", "0.02"], []):
        assert cli.main(["simulate", "--model", "full", "--road", "iso8608-C", "--sensors", "state", *noise,
                         "--change", "40:b_rl=900", "--n", "14000", "--seed", "57", "-o", str(log)]) == 0
        capsys.readouterr()
        declared = ["--noise", "state=1e-4,deriv=0.02"] if noise else []
        assert cli.main(["monitor", str(log), "--model", "full", "--sensors", "state", *declared, "--json"]) == 0
        out = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
        assert [e["parameter"] for e in out] == ["b_rl"] and abs(out[0]["change"] + 0.10) < 0.03, (noise, out)
    assert cli.main(["monitor", str(log), "--model", "full", "--sensors", "state", "--noise", "a_body=0.1"]) == 2
    assert "NAME in state, deriv" in capsys.readouterr().err


def test_anti_roll_bars_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A car with bars (15 and 8 kN m/rad) loses its front bar's end link at 40 s: one event
    # 'arb_f' of about -100 %, its interval stopping at 0 (a bar is a torsion spring), and
    # `vehid monitor --car arb_f=...,arb_r=...` names it in words.
    barred = vehid.FullCar(**{**FULL.params, "arb_f": 15_000.0, "arb_r": 8_000.0})
    sim = vehid.Simulator(barred, dt=DT, road="iso8608-C", speed=15.0, changes=[(40.0, {"arb_f": 0.0})],
                          sensors="realistic", seed=61)
    run = sim.run(int(round(80.0 / DT)))
    mon = vehid.HealthMonitor(barred, dt=DT)
    events = mon.fit(run.y)
    assert [e.parameter for e in events] == ["arb_f"], events
    ev = events[0]
    assert ev.before == 15_000.0 and ev.change < -0.9 and ev.low == 0.0 < ev.high and 40.0 < ev.t < 50.0, ev
    assert mon.constants["arb_f"] == ev.after and mon.constants["arb_r"] == 8_000.0
    log = tmp_path / "bars.csv"
    np.savetxt(log, np.column_stack([run.t, run.y]), delimiter=",", header="t," + ",".join(run.channels),
               comments="")
    assert cli.main(["monitor", str(log), "--model", "full", "--car", "arb_f=15000,arb_r=8000"]) == 0
    out = capsys.readouterr().out
    assert "arb_f (front anti-roll bar): 15000 -> " in out and "N m/rad" in out, out

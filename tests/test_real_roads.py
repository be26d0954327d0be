"""Identification on a real road (ISO 8608: the height a random walk in distance), not the
thesis' white road noise: ``IVIdentifier(..., road="iso8608", spacing=...)`` and
``vehid identify --road iso8608``.

References: the car's true constants on drives of vehid's ISO 8608 road (seeds not used while
the method was developed), a second implementation in numpy (differences, instruments one
sample back, solved by ``numpy.linalg.solve``), and the interval coverage over seeds.
"""

from __future__ import annotations

import copy
import json
import pickle
from pathlib import Path

import numpy as np
import pytest

import vehid
from vehid import cli

DT = 0.005
CAR = vehid.QuarterCar.passenger()
TRUTH = CAR.params
CONSTANTS = ("M", "k1", "k2", "b")


def drive(seed: int, n: int = 20_000, road: str = "iso8608-C", speed: object = 15.0) -> vehid.Run:
    return vehid.Simulator(CAR, dt=DT, road=road, speed=speed, sensors="state", seed=seed).run(n)


def structure() -> vehid.Structure:
    return CAR.structure(known={"m": TRUTH["m"]})


def test_the_thesis_identifier_is_far_off_and_the_coloured_road_one_within_five_percent() -> None:
    # The documented claim: 300 s at 200 Hz, every constant within 5 % on >= 9 of 10 seeds.
    good = 0
    for seed in range(8101, 8111):
        run = drive(seed, n=60_000)
        road = vehid.IVIdentifier(structure(), road="iso8608", spacing=15.0 * DT)
        road.fit(run.x, run.xdot)
        got = CAR.physical(road.stats(), m=TRUTH["m"])
        good += all(abs(got[k][0] / TRUTH[k] - 1) < 0.05 for k in CONSTANTS)
        if seed == 8101:
            thesis = vehid.KalmanIdentifier(structure())
            thesis.fit(run.x, run.xdot)
            bad = CAR.physical(thesis.stats(), m=TRUTH["m"])
            assert bad["M"][0] < 0.3 * TRUTH["M"], bad  # the thesis identifier's known bias (52 kg for 320)
    assert good >= 9, good


def test_the_estimate_is_instrumental_variables_on_the_quasi_differences_computed_by_numpy() -> None:
    run = drive(8111, n=8000)
    s = structure()
    iv = vehid.IVIdentifier(s, delay=1, road="iso8608", spacing=15.0 * DT, min_spacing=0.0)
    iv.fit(run.x, run.xdot)
    assert iv.lags == 0  # the default on a coloured road
    rho = np.exp(-2 * np.pi * 0.01 * 15.0 * DT)
    x = run.x[1:] - rho * run.x[:-1]
    z = run.xdot[1:] - rho * run.xdot[:-1]
    m = TRUTH["m"]
    # body: dvb = (k2/M)(zw - zb) + (b/M)(vw - vb);  wheel: dvw = -(M/m) dvb - (k1/m) zw
    body = np.column_stack([x[:, 0] - x[:, 2], x[:, 1] - x[:, 3]])
    wheel = np.column_stack([-z[:, 3] / m, -x[:, 0] / m])
    want = []
    for h, y in ((body, z[:, 3]), (wheel, z[:, 1])):
        want.extend(np.linalg.solve(h[:-1].T @ h[1:], h[:-1].T @ y[1:]))  # instruments: one sample back
    np.testing.assert_allclose(iv.params, want, rtol=1e-7)


def test_odometer_at_constant_speed_equals_the_spacing_and_varying_speed_is_identified() -> None:
    run = drive(8121, n=10_000)
    a = vehid.IVIdentifier(structure(), road="iso8608", spacing=15.0 * DT)
    a.fit(run.x, run.xdot)
    b = vehid.IVIdentifier(structure(), road="iso8608", spacing="odometer")
    b.fit(run.x, run.xdot, u=run.s[:, None])
    np.testing.assert_allclose(a.params, b.params, rtol=1e-9)
    speed = 19.0 + 11.0 * np.sin(2 * np.pi * np.arange(40_000) * DT / 60.0)  # 8..30 m/s
    run = drive(8122, n=40_000, speed=speed)
    c = vehid.IVIdentifier(structure(), road="iso8608", spacing="odometer")
    c.fit(run.x, run.xdot, u=run.s[:, None])
    got = CAR.physical(c.stats(), m=TRUTH["m"])
    for k in CONSTANTS:
        assert abs(got[k][0] / TRUTH[k] - 1) < 0.05, (k, got[k])


def test_on_an_independent_smooth_road_spaced_samples_are_needed_and_enough() -> None:
    # A road generated and integrated without vehid (benches/independent_road.py: random-phase
    # harmonics over ISO 8608's band, scipy's lsim): its increments are correlated below ~0.18 m.
    from bench_scripts import load  # tests/ is on sys.path under pytest

    pytest.importorskip("scipy")
    sim = load("independent_road")
    for seed, speed in ((8601, 10.0), (8602, 15.0), (8603, 25.0)):
        x, xd, _ = sim.simulate(TRUTH, "C", speed, DT, 40_000, seed)
        spaced = vehid.IVIdentifier(structure(), road="iso8608", spacing=speed * DT)  # 0.25 m apart
        spaced.fit(x, xd)
        got = CAR.physical(spaced.stats(), m=TRUTH["m"])
        for k in CONSTANTS:
            assert abs(got[k][0] / TRUTH[k] - 1) < 0.05, (seed, k, got[k])
        every = vehid.IVIdentifier(structure(), road="iso8608", spacing=speed * DT, min_spacing=0.0)
        every.fit(x, xd)
        if speed <= 15.0:  # 5 cm and 7.5 cm per sample: instruments correlated with the road's increments
            assert abs(CAR.physical(every.stats(), m=TRUTH["m"])["M"][0] / TRUTH["M"] - 1) > 0.2


def test_the_intervals_cover_the_truth_over_seeds() -> None:
    # 40 seeds: a nominal 95 % interval misses in more than 6 of 40 with probability < 1 %.
    miss = {k: 0 for k in CONSTANTS}
    for seed in range(8200, 8240):
        run = drive(seed, n=12_000)
        iv = vehid.IVIdentifier(structure(), road="iso8608", spacing=15.0 * DT)
        iv.fit(run.x, run.xdot)
        for k, (_, lo, hi) in CAR.physical(iv.stats(), m=TRUTH["m"]).items():
            if k in miss:
                miss[k] += not lo <= TRUTH[k] <= hi
    assert all(v <= 6 for v in miss.values()), miss


def test_a_coloured_road_identifier_pickles_and_copies_and_continues_bit_for_bit() -> None:
    run = drive(8131, n=6000)
    iv = vehid.IVIdentifier(structure(), road="iso8608", road_cutoff=0.02, spacing="odometer")
    iv.fit(run.x[:3000], run.xdot[:3000], u=run.s[:3000, None])
    copies = [pickle.loads(pickle.dumps(iv, protocol=p)) for p in (2, 5)] + [copy.copy(iv), copy.deepcopy(iv)]
    for c in copies:
        assert (c.road, c.road_cutoff, c.spacing, c.min_spacing) == ("iso8608", 0.02, "odometer", 0.25)
    for ident in [iv, *copies]:
        ident.fit(run.x[3000:], run.xdot[3000:], u=run.s[3000:, None])
    for c in copies:
        assert np.array_equal(c.params, iv.params)
        assert c.samples == iv.samples == 6000
    # A state saved with another road model is refused, naming why.
    white = vehid.IVIdentifier(structure(), lags=0)  # the same instruments: only the road differs
    reduce = iv.__reduce__()
    with pytest.raises(vehid.VehidError, match="road"):
        white.__setstate__(reduce[2])
    with pytest.raises(vehid.VehidError, match="road"):
        vehid.IVIdentifier(structure(), road="iso8608", spacing=0.5).__setstate__(reduce[2])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"road": "iso8608"}, "needs `spacing`"),
        ({"road": "bumpy", "spacing": 0.1}, "unknown `road`"),
        ({"spacing": 0.1}, "coloured road"),
        ({"road": "random-walk", "road_cutoff": 0.01, "spacing": 0.1}, "road_cutoff"),
        ({"road": "iso8608", "road_cutoff": -1.0, "spacing": 0.1}, "road_cutoff"),
        ({"road": "iso8608", "spacing": 0.0}, "spacing"),
        ({"road": "iso8608", "spacing": float("nan")}, "spacing"),
        ({"road": "iso8608", "spacing": "gps"}, "spacing"),
        ({"road": "iso8608", "spacing": 0.1, "min_spacing": -0.5}, "min_spacing"),
        ({"min_spacing": 0.3}, "coloured road"),
    ],
)
def test_bad_road_arguments_are_refused_naming_the_fix(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        vehid.IVIdentifier(structure(), **kwargs)


def test_models_that_do_not_difference_are_refused() -> None:
    rig = vehid.Structure(states=["q", "v"], equations={"v": "a*v + c*sign(v)"}, known={"q": "v"})
    with pytest.raises(ValueError, match="sign"):
        vehid.IVIdentifier(rig, road="random-walk", spacing=1.0)
    offset = vehid.Structure(states=["q", "v"], equations={"v": "a*v + d"}, known={"q": "v"})
    with pytest.raises(ValueError, match="offset"):
        vehid.IVIdentifier(offset, road="random-walk", spacing=1.0)


def test_an_odometer_that_goes_back_is_refused_and_changes_nothing() -> None:
    run = drive(8141, n=500)
    iv = vehid.IVIdentifier(structure(), road="iso8608", spacing="odometer")
    iv.fit(run.x[:300], run.xdot[:300], u=run.s[:300, None])
    before = pickle.dumps(iv)
    s = run.s[300:].copy()
    s[100] = s[99] - 1.0
    with pytest.raises(vehid.VehidError, match="odometer"):
        iv.fit(run.x[300:], run.xdot[300:], u=s[:, None])
    assert pickle.dumps(iv) == before


def test_vehid_identify_road_iso8608_on_a_drive_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "drive.csv"
    argv = ["simulate", "--model", "quarter", "--road", "iso8608-C", "--sensors", "state", "--n", "40000"]
    assert cli.main([*argv, "--seed", "8151", "-o", str(log)]) == 0
    capsys.readouterr()
    out = {}
    for road in (["--road", "white"], ["--road", "iso8608"], ["--road", "iso8608", "--speed", "15"]):
        assert cli.main(["identify", str(log), "--model", "quarter", "--m", "40", *road, "--json"]) == 0
        out[" ".join(road)] = json.loads(capsys.readouterr().out)
    assert out["--road white"]["physical_intervals"]["M"][0] < 100  # the thesis' identifier, biased
    for key in ("--road iso8608", "--road iso8608 --speed 15"):
        assert out[key]["method"] == "iv"
        for k in CONSTANTS:
            v, lo, hi = out[key]["physical_intervals"][k]
            assert abs(v / TRUTH[k] - 1) < 0.05, (key, k, v)
    a, b = (out[k]["physical_intervals"]["M"][0] for k in ("--road iso8608", "--road iso8608 --speed 15"))
    assert abs(a / b - 1) < 1e-9  # the odometer column and --speed agree at constant speed


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--road", "iso8608", "--method", "ls"], "drop --method"),
        (["--speed", "15"], "add --road"),
        (["--road", "random-walk", "--road-cutoff", "0.01"], "road-cutoff"),
    ],
)
def test_vehid_identify_refuses_road_options_that_do_not_fit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list, match: str
) -> None:
    log = tmp_path / "d.csv"
    assert cli.main(["simulate", "--model", "quarter", "--n", "200", "-o", str(log)]) == 0
    assert cli.main(["identify", str(log), "--model", "quarter", *extra]) == 2
    assert match in capsys.readouterr().err


def test_vehid_identify_road_needs_a_distance(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "d.csv"
    assert cli.main(["simulate", "--model", "quarter", "--n", "200", "-o", str(log)]) == 0  # no column s
    assert cli.main(["identify", str(log), "--model", "quarter", "--road", "iso8608"]) == 2
    assert "--speed" in capsys.readouterr().err


# --- the model check: whiteness of the residuals ------------------------------------------


def test_ljung_box_is_the_textbook_statistic_with_scipy_p_values() -> None:
    chi2 = pytest.importorskip("scipy.stats").chi2
    rng = np.random.default_rng(8301)
    for n, lags in ((50, 1), (400, 10), (3000, 25)):
        x = rng.standard_normal(n).cumsum() if lags == 10 else rng.standard_normal(n)
        d = x - x.mean()
        rho = np.array([d[j:] @ d[:-j] for j in range(1, lags + 1)]) / (d @ d)
        q = n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, lags + 1)))
        stat, p = vehid.ljung_box(x, lags=lags)
        assert stat == pytest.approx(q, rel=1e-12)
        assert p == pytest.approx(chi2.sf(q, lags), rel=1e-10, abs=1e-300)
    for bad, match in (([1.0] * 30, "variance"), ([1.0, np.nan] * 20, "NaN"), (np.zeros((5, 5)), "one series")):
        with pytest.raises(ValueError, match=match):
            vehid.ljung_box(bad, lags=3)
    with pytest.raises(ValueError, match="lags"):
        vehid.ljung_box(rng.standard_normal(10), lags=10)


def test_residuals_are_the_equations_minus_the_estimate() -> None:
    car = vehid.QuarterCar()
    run = vehid.Simulator(car, road_sigma=0.1, deriv_noise=0.005, seed=8311).run(3000)
    kf = vehid.KalmanIdentifier(car)
    kf.fit(run.r, run.z)
    want = np.column_stack([run.z[:, row] - run.r @ kf.theta[i] for i, row in enumerate(car.unknown_rows)])
    np.testing.assert_allclose(kf.residuals(run.r, run.z), want, rtol=1e-12, atol=1e-12)
    s = car.structure(known={"m": 1.0})
    ks = vehid.KalmanIdentifier(s)
    ks.fit(run.r, run.z)
    p = ks.params
    by_structure = np.array([s.derivative(p, x, None) for x in run.r[:50]])
    # The structure's wheel equation reads der(body_vel): its residual uses the measured one.
    got = ks.residuals(run.r[:50], run.z[:50])
    np.testing.assert_allclose(got[:, 0], run.z[:50, 3] - by_structure[:, 3], rtol=1e-10, atol=1e-12)


def test_the_check_warns_on_iso_roads_and_rarely_on_the_thesis_white_road() -> None:
    # White road (the thesis' simulation): each decision is p >= 0.01 with p recomputed by scipy
    # from the residuals (Q over 10 lags). The body equation's residual (derivative noise) is
    # independent of the states: its p-values are uniform (Kolmogorov-Smirnov). The wheel
    # equation's states are driven by its own past residuals (the road), which makes the test
    # conservative there (Box & Pierce 1970: mean Q about 8, not 10): at most 4 warnings in 60.
    # ISO roads: every run warned.
    stats = pytest.importorskip("scipy.stats")
    car = vehid.QuarterCar()
    false, pvalues = 0, []
    for seed in range(8400, 8460):
        run = vehid.Simulator(car, road_sigma=0.1, deriv_noise=0.005, seed=seed).run(8000)
        kf = vehid.KalmanIdentifier(car)
        kf.fit(run.r, run.z)
        checks = cli.residual_checks(kf, "quarter", list(car.unknown_rows), run.r, run.z)
        assert len(checks) == 2
        res = kf.residuals(run.r, run.z)
        for i, c in enumerate(checks):
            d = res[:, i] - res[:, i].mean()
            n = len(d)
            rho = np.array([d[j:] @ d[:-j] for j in range(1, 11)]) / (d @ d)
            q = n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, 11)))
            assert c["white"] == (stats.chi2.sf(q, 10) >= 0.01), (seed, c)
        wheel = [c for c in checks if c["state"] == "wheel_vel"][0]
        false += not wheel["white"]
        pvalues.append([c for c in checks if c["state"] == "body_vel"][0]["lb_pvalue"])
    assert false <= 4, false
    assert stats.kstest(pvalues, "uniform").pvalue > 1e-3, sorted(pvalues)
    for seed in range(8500, 8520):
        run = drive(seed, n=8000, road="iso8608-B", speed=10.0 + seed % 20)
        kf = vehid.KalmanIdentifier(CAR)
        kf.fit(run.x, run.xdot)
        checks = cli.residual_checks(kf, "quarter", list(CAR.unknown_rows), run.x, run.xdot)
        wheel = [c for c in checks if c["state"] == "wheel_vel"]
        assert wheel and not wheel[0]["white"], (seed, checks)


def test_vehid_identify_warns_when_the_road_is_not_white(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "drive.csv"
    argv = ["simulate", "--model", "quarter", "--road", "iso8608-C", "--sensors", "state", "--n", "20000"]
    assert cli.main([*argv, "--seed", "8161", "-o", str(log)]) == 0
    capsys.readouterr()
    assert cli.main(["identify", str(log), "--model", "quarter", "--m", "40"]) == 0
    err = capsys.readouterr().err
    assert "warning: the residuals of d(wheel_vel)/dt are not white" in err and "--road iso8608" in err
    assert cli.main(["identify", str(log), "--model", "quarter", "--m", "40", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert [c["white"] for c in report["residual_checks"] if c["state"] == "wheel_vel"] == [False]


def test_the_half_car_on_an_iso_road_by_road_cancellation() -> None:
    # The rear wheel meets the front wheel's road a wheelbase later whatever its spectrum, so
    # cancelling it identifies all 28 entries on an ISO road too (true states, fresh seeds).
    half = vehid.HalfCar.passenger()
    p = half.params
    s = half.structure(known={k: p[k] for k in ("m1", "m2", "l1", "l2")})
    rows = list(half.unknown_rows)
    nz = half.a[rows] != 0
    assert nz.sum() == 28
    for seed, speed in ((8701, 10.0), (8702, 20.0)):
        run = vehid.Simulator(half, dt=DT, road="iso8608-D", speed=speed, sensors="state", seed=seed).run(20_000)
        two = vehid.TwoAxleIdentifier(s, car=half, spacing=speed * DT, compensate=False)
        two.fit(run.x, run.xdot)
        err = np.abs(two.a_hat[rows][nz] / half.a[rows][nz] - 1)
        assert err.max() < 0.05, (seed, err.max())
        rows_only = vehid.KalmanIdentifier(half)  # the thesis' rows, white-road assumption
        rows_only.fit(run.x, run.xdot)
        wheel = np.abs(rows_only.a_hat[rows][nz] / half.a[rows][nz] - 1)
        assert wheel.max() > 0.2, wheel.max()


def test_lift_off_is_found_and_flagged() -> None:
    # Class E at 25 m/s with a tyre that only pushes (benches/independent_road.py, RK4 of its
    # own): off the ground a large share of the time, where the linear model does not hold, and
    # the constants come out biased. The check counts every lifted sample (the nominal body mass
    # 10 % off serves) and changes nothing else; the command line flags the constants.
    from bench_scripts import load  # tests/ is on sys.path under pytest

    sim = load("independent_road")
    # seed 8821: not one LIFT_OFF_LOAD was chosen or checked on
    x, xd, lifted = sim.simulate_lift_off(TRUTH, "E", 25.0, DT, 30_000, 8821)
    assert 0.02 < lifted.mean() < 0.5, lifted.mean()
    plain = vehid.IVIdentifier(structure(), road="iso8608", spacing=25.0 * DT)
    plain.fit(x, xd)
    off = CAR.physical(plain.stats(), m=TRUTH["m"])
    assert max(abs(off[k][0] / TRUTH[k] - 1) for k in CONSTANTS) > 0.08, off
    for nominal in (TRUTH["M"], 1.1 * TRUTH["M"], 0.9 * TRUTH["M"]):
        checked = vehid.IVIdentifier(structure(), road="iso8608", spacing=25.0 * DT, lift_off=(nominal, TRUTH["m"]))
        checked.fit(x, xd)
        assert lifted.sum() - 0.001 * len(x) <= checked.lifted <= 1.5 * lifted.sum(), (checked.lifted, lifted.sum())
        np.testing.assert_array_equal(checked.params, plain.params)
    # On a drive whose tyre stays on the ground nothing is counted.
    run = drive(8802, n=20_000, road="iso8608-B", speed=15.0)
    calm = vehid.IVIdentifier(structure(), road="iso8608", spacing=15.0 * DT, lift_off=(TRUTH["M"], TRUTH["m"]))
    calm.fit(run.x, run.xdot)
    assert calm.lifted == 0
    with pytest.raises(ValueError, match="lift_off"):
        vehid.IVIdentifier(structure(), road="iso8608", spacing=0.1, lift_off=(-1.0, 40.0))
    with pytest.raises(ValueError, match="coloured road"):
        vehid.IVIdentifier(structure(), lift_off=(320.0, 40.0))
    half = vehid.HalfCar.passenger()
    with pytest.raises(ValueError, match="quarter car"):
        vehid.IVIdentifier(half, road="iso8608", spacing=0.1, lift_off=(640.0, 40.0))

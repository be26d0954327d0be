"""Identification from the sensors a car has (accelerometers and a deflection sensor): the
body equation through the core's state-variable filter (vehid.RealisticIdentifier), checked
against scipy's filters and statsmodels' cluster-robust OLS on the same samples, on drives
over ISO roads, and through ``vehid identify --sensors realistic``; the constants these sensors
cannot determine are named, never printed as numbers."""

from __future__ import annotations

import copy
import json
import pickle
from pathlib import Path
from typing import Any, List

import numpy as np
import pytest

import vehid
from vehid import cli

DT = 0.005
CAR = vehid.QuarterCar.passenger()
TRUE = CAR.params


def drive(seconds: float, seed: int, road: str = "iso8608-C", speed: float = 15.0) -> vehid.Run:
    sim = vehid.Simulator(CAR, dt=DT, road=road, speed=speed, sensors="realistic", seed=seed)
    return sim.run(int(round(seconds / DT)))


def filtered_regression(y: np.ndarray, bandwidth: float, m_body: float, settling: int) -> tuple[np.ndarray, np.ndarray]:
    """The filtered body equation by scipy: F(s) = λ²/(s+λ)², bilinear, started in its steady
    state, on a_body, the deflection and its five-point central derivative (each at the centre
    sample); regressors [-F d/M, -F ḋ/M, 1], target F a_body, after the filters' settling."""
    from scipy import signal

    lam = bandwidth
    d = y[:, 2]
    rate = (d[:-4] - 8 * d[1:-3] + 8 * d[3:-1] - d[4:]) / (12 * DT)
    b, a, _ = signal.cont2discrete(([lam**2], [1.0, 2 * lam, lam**2]), DT, method="bilinear")
    b = np.ravel(b)
    skip = settling - 4  # the first four samples only fill the derivative's window
    fa, fd, fv = (signal.lfilter(b, a, x, zi=signal.lfilter_zi(b, a) * x[0])[0][skip:]
                  for x in (y[2:-2, 0], d[2:-2], rate))
    return np.column_stack([-fd / m_body, -fv / m_body, np.ones(len(fd))]), fa


def test_the_fit_is_ols_with_cluster_robust_errors_on_scipys_filtered_signals() -> None:
    sm = pytest.importorskip("statsmodels.api")
    run = drive(60.0, seed=71_001)
    s = CAR.structure(known={"M": TRUE["M"]}, sensors="realistic")
    ident = vehid.RealisticIdentifier(s, DT).fit(run.y)
    st = ident.stats()
    x, y = filtered_regression(run.y, ident.bandwidth, TRUE["M"], ident.settling)
    assert ident.samples == len(y)
    groups = np.arange(len(y)) // int(round(ident.block / DT))
    ref = sm.OLS(y, x).fit(cov_type="cluster", cov_kwds={"groups": groups})
    np.testing.assert_allclose(st.params, ref.params, rtol=1e-7)
    np.testing.assert_allclose(st.bse, ref.bse, rtol=1e-6)
    assert st.df[0] == groups[-1]  # G - 1 degrees of freedom
    assert st.names == ("k2", "b", "offset")


@pytest.mark.parametrize("road,speed,seed", [("iso8608-B", 10.0, 71_101), ("iso8608-C", 20.0, 71_102),
                                             ("iso8608-D", 30.0, 71_103)])
def test_k2_and_b_from_the_realistic_sensors_on_iso_roads(road: str, speed: float, seed: int) -> None:
    run = drive(120.0, seed, road, speed)
    s = CAR.structure(known={"M": TRUE["M"]}, sensors="realistic")
    st = vehid.RealisticIdentifier(s, DT).fit(run.y).stats()
    phys = CAR.physical(st)
    assert set(phys) == {"M", "k2", "b"}  # m and k1: not determined, left out
    for k in ("k2", "b"):
        v, lo, hi = phys[k]
        assert abs(v / TRUE[k] - 1) < 0.01, (k, v)
        assert lo < v < hi


def test_the_sensors_that_do_not_determine_a_constant_say_what_it_needs() -> None:
    with_mass = CAR.structure(known={"M": 320.0}, sensors="realistic")
    assert set(with_mass.not_identifiable) == {"m", "k1"}
    assert all("tyre force" in v for v in with_mass.not_identifiable.values())
    ratios = CAR.structure(sensors="realistic")
    assert ratios.parameters == ("k2/M", "b/M", "offset")
    assert all("known mass" in ratios.not_identifiable[k] for k in ("M", "k2", "b"))
    assert CAR.structure(known={"m": 40.0}).not_identifiable == {}
    assert ratios.states == ("d", "v", "vb")
    assert "sensors='realistic'" in repr(ratios)
    assert pickle.loads(pickle.dumps(ratios)) == ratios
    with pytest.raises(vehid.VehidError, match="sensors"):
        CAR.structure(sensors="camera")  # type: ignore[arg-type]
    with pytest.raises(vehid.VehidError, match="half car"):
        vehid.HalfCar.passenger().structure(known={"m1": 40.0, "m2": 40.0}, sensors="realistic")


def test_bad_input_is_refused_and_changes_nothing() -> None:
    run = drive(20.0, seed=71_201)
    s = CAR.structure(known={"M": 320.0}, sensors="realistic")
    ident = vehid.RealisticIdentifier(s, DT).fit(run.y[:2000])
    before = pickle.dumps(ident)
    y = run.y[2000:3000].copy()
    y[500, 2] = np.nan
    with pytest.raises(ValueError, match="row 500, column 2"):
        ident.fit(y)
    with pytest.raises(ValueError, match=r"shape \(samples, 3\)"):
        ident.fit(run.y[:, :2])
    with pytest.raises(ValueError, match=r"y_k"):
        ident.update([0.1, 0.2])
    with pytest.raises(ValueError, match="y_k"):
        ident.update([0.1, np.inf, 0.0])
    assert pickle.dumps(ident) == before
    with pytest.raises(ValueError, match="realistic"):
        vehid.RealisticIdentifier(CAR.structure(known={"m": 40.0}), DT)
    with pytest.raises(ValueError, match="bandwidth"):
        vehid.RealisticIdentifier(s, DT, bandwidth=500.0)
    with pytest.raises(ValueError, match="block"):
        vehid.RealisticIdentifier(s, DT, block=0.5)
    with pytest.raises(ValueError, match="samples"):
        vehid.RealisticIdentifier(s, DT).fit(run.y[:600]).stats()  # too short for a covariance


def test_a_restored_identifier_continues_bit_for_bit_and_corrupt_state_is_refused() -> None:
    run = drive(30.0, seed=71_301)
    s = CAR.structure(sensors="realistic")
    a = vehid.RealisticIdentifier(s, DT).fit(run.y[:3000])
    b = pickle.loads(pickle.dumps(a))
    c = copy.deepcopy(a)
    for ident in (a, b, c):
        ident.fit(run.y[3000:])
    assert a.stats().params.tolist() == b.stats().params.tolist() == c.stats().params.tolist()
    fn, args, (fmt, version, payload) = a.__reduce__()
    fresh = fn(*args)
    # Trailing bytes, a cut payload and any single changed byte are refused (the state carries a
    # CRC-32).
    flipped = [payload[:i] + bytes([payload[i] ^ 0x01]) + payload[i + 1:] for i in range(0, len(payload), 7)]
    for bad in (payload + b"\x00", payload[:-9], *flipped):
        with pytest.raises(ValueError, match="cannot restore"):
            fresh.__setstate__((fmt, version, bad))
    with pytest.raises(ValueError, match="format"):
        fresh.__setstate__((fmt + 1, version, payload))


def test_a_gap_restarts_the_filter() -> None:
    run = drive(60.0, seed=71_401)
    s = CAR.structure(known={"M": 320.0}, sensors="realistic")
    whole = vehid.RealisticIdentifier(s, DT).fit(run.y)
    gap = vehid.RealisticIdentifier(s, DT).fit(run.y[:5000])
    gap.restart()
    gap.fit(run.y[6000:])
    # Both halves after their settling: 1000 samples fewer and one more settling left out.
    assert gap.samples == whole.samples - 1000 - gap.settling
    assert abs(gap.stats().params[0] / TRUE["k2"] - 1) < 0.01


def run_identify(tmp_path: Path, capsys: pytest.CaptureFixture[str], run: vehid.Run, extra: List[str],
                 keep: Any = None) -> dict[str, Any]:
    data = np.column_stack([run.t, run.y])
    if keep is not None:
        data = data[keep]
    log = tmp_path / "log.csv"
    np.savetxt(log, data, delimiter=",", header="t,a_body,a_wheel,deflection", comments="", fmt="%.9g")
    capsys.readouterr()
    assert cli.main(["identify", str(log), "--model", "quarter", "--sensors", "realistic", *extra]) == 0
    out = capsys.readouterr().out
    return json.loads(out) if "--json" in extra else {"text": out}


def test_vehid_identify_realistic_prints_k2_b_and_what_m_and_k1_need(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = drive(90.0, seed=71_501)
    r = run_identify(tmp_path, capsys, run, ["--M", "320", "--json"])
    for k in ("k2", "b"):
        c = r["constants"][k]
        assert abs(c["value"] / TRUE[k] - 1) < 0.01 and c["low"] < c["value"] < c["high"]
    assert set(r["not_identifiable"]) == {"m", "k1"}
    text = run_identify(tmp_path, capsys, run, ["--truth", "passenger"])["text"]
    assert "k2/M" in text and "true 68.75" in text
    for k in ("M", "k2", "b", "m", "k1"):
        assert f"{k:3s}   not identifiable from these signals: needs" in text, text
    # A gap of 1 s and a missing value: the filter restarts at each, the result holds.
    keep = np.ones(len(run.t), dtype=bool)
    keep[4000:4200] = False
    r = run_identify(tmp_path, capsys, run, ["--M", "320", "--json"], keep=keep)
    assert r["restarts"] == 1 and r["samples"] == len(run.t) - 200
    assert abs(r["constants"]["k2"]["value"] / TRUE["k2"] - 1) < 0.01


def test_vehid_identify_realistic_refuses_what_it_cannot_do(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "log.csv"
    np.savetxt(log, np.zeros((10, 3)), delimiter=",", header="t,a_body,deflection", comments="")
    assert cli.main(["identify", str(log), "--model", "quarter", "--sensors", "realistic"]) == 2
    assert "no column a_wheel" in capsys.readouterr().err
    assert cli.main(["identify", str(log), "--model", "half", "--sensors", "realistic"]) == 2
    assert "no column a_body_f" in capsys.readouterr().err
    assert cli.main(["identify", str(log), "--model", "car.toml", "--sensors", "realistic"]) == 2
    assert "the quarter, half or full car (--model quarter|half|full)" in capsys.readouterr().err

"""The full car from the sensors a car has (a body accelerometer above each wheel, the wheel
accelerometers, each corner's deflection): ``RealisticIdentifier(full)`` checked against scipy's
filters and statsmodels' cluster-robust OLS on the same samples, its cross-equation covariance
against numpy, the constants through ``full.physical(stats, M=...)`` on drives from vehid and from
an independent simulator, pickling and bad input."""

from __future__ import annotations

import copy
import json
import pickle
from pathlib import Path

import numpy as np
import pytest
from bench_scripts import load  # tests/ is on sys.path under pytest
from readme_blocks import README, python_blocks

import vehid
from vehid import cli

DT = 0.005
BARS = {"arb_f": 15_000.0, "arb_r": 8_000.0}
CAR = vehid.FullCar(**{**vehid.FullCar.passenger().params, **BARS})
TRUE = CAR.params
NAMES = ["Jx", "Jy", *[f"{q}_{c}" for q in ("k", "b") for c in ("fl", "fr", "rl", "rr")], "arb_f", "arb_r"]
# The full car written without vehid (Lagrange's equations, scipy's lsim): benches/independent_road.py.
INDEPENDENT = load("independent_road")


def drive(seconds: float, seed: int, road: str = "iso8608-C", speed: float = 15.0) -> vehid.Run:
    sim = vehid.Simulator(CAR, dt=DT, road=road, speed=speed, sensors="realistic", seed=seed)
    return sim.run(int(round(seconds / DT)))


def filtered(y: np.ndarray, bandwidth: float, settling: int) -> tuple[np.ndarray, np.ndarray]:
    """The filtered corner equations by scipy: F(s) = λ²/(s+λ)², bilinear, started in its
    steady state, on each body acceleration, each deflection and its five-point central
    derivative (at the centre sample); regressors [-F d_fl, -F ḋ_fl, ..., -F ḋ_rr, 1] and the
    four targets F a_i, after the filters' settling."""
    from scipy import signal

    lam = bandwidth
    b, a, _ = signal.cont2discrete(([lam**2], [1.0, 2 * lam, lam**2]), DT, method="bilinear")
    b = np.ravel(b)
    skip = settling - 4

    def f(x: np.ndarray) -> np.ndarray:
        return signal.lfilter(b, a, x, zi=signal.lfilter_zi(b, a) * x[0])[0][skip:]

    cols = []
    for j in range(4):
        d = y[:, 8 + j]
        rate = (d[:-4] - 8 * d[1:-3] + 8 * d[3:-1] - d[4:]) / (12 * DT)
        cols += [-f(d[2:-2]), -f(rate)]
    h = np.column_stack(cols + [np.ones(len(cols[0]))])
    return h, np.column_stack([f(y[2:-2, i]) for i in range(4)])


def noise_gains(bandwidth: float) -> np.ndarray:
    """The filtered deflection noise's second moments per unit variance, by scipy: white noise
    reaches the deflection regressor through F on the centre sample (two samples back) and the
    rate regressor through F after the five-point derivative (`filtered`'s rate, written as a
    causal filter: taps -1, 8, 0, -8, 1 over 12 dt, newest first); [Σ f0², Σ f0 f1, Σ f1²]."""
    from scipy import signal

    b, a, _ = signal.cont2discrete(([bandwidth**2], [1.0, 2 * bandwidth, bandwidth**2]), DT, method="bilinear")
    n = 20_000
    centre, taps = np.zeros(n), np.zeros(n)
    centre[2] = 1.0
    taps[:5] = np.array([-1.0, 8.0, 0.0, -8.0, 1.0]) / (12 * DT)
    f0, f1 = signal.lfilter(np.ravel(b), a, centre), signal.lfilter(np.ravel(b), a, taps)
    return np.array([f0 @ f0, f0 @ f1, f1 @ f1])


def compensated_fit(h: np.ndarray, ys: np.ndarray, deflections: np.ndarray, bandwidth: float,
                    groups: np.ndarray, compensate: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The corner equations' bias-compensated least squares and its cluster sandwich, from the
    documented equations (identify/corner_filter.rs, "The deflection sensors' noise"): each
    deflection's noise variance from its fourth differences, Σ(Δ⁴d)²/(70 N₄); S block-diagonal
    with σ² times `noise_gains`; Θ = (HᵀH − N S)⁻¹ HᵀY, scores C_b − (A_b − n_b S) Θ. With
    `compensate=False`, S = 0: plain least squares and its cluster-robust covariance."""
    corners = deflections.shape[1]
    k = 2 * corners + 1
    s = np.zeros((k, k))
    if compensate:
        g0, g01, g1 = noise_gains(bandwidth)
        for j in range(corners):
            v = np.mean(np.diff(deflections[:, j], 4) ** 2) / 70
            s[2 * j:2 * j + 2, 2 * j:2 * j + 2] = v * np.array([[g0, g01], [g01, g1]])
    n = len(h)
    ainv = np.linalg.inv(h.T @ h - n * s)
    theta = ainv @ h.T @ ys
    g = groups[-1] + 1
    scores = []
    for blk in range(g):
        hb, yb = h[groups == blk], ys[groups == blk]
        scores.append((hb.T @ yb - (hb.T @ hb - len(hb) * s) @ theta).T.ravel())
    sc = np.stack(scores)
    bread = np.kron(np.eye(ys.shape[1]), ainv)
    cov = bread @ sc.T @ sc @ bread * g / (g - 1) * (n - 1) / (n - k)
    return theta, cov


def test_the_fit_is_compensated_least_squares_with_cluster_robust_errors_on_scipys_filtered_signals() -> None:
    # The sandwich written here in numpy is statsmodels' cluster-robust OLS when nothing is
    # compensated (each equation's estimates and standard errors); with the deflection noise
    # compensated (its variance from numpy's fourth differences, its gains from scipy's impulse
    # responses) it is vehid's fit, all 36 coefficients and their covariance.
    sm = pytest.importorskip("statsmodels.api")
    run = drive(60.0, seed=74_001)
    ident = vehid.RealisticIdentifier(CAR, DT).fit(run.y)
    st = ident.stats()
    h, ys = filtered(run.y, ident.bandwidth, ident.settling)
    assert ident.samples == len(h)
    assert st.names[:3] == ("a_fl:d_fl", "a_fl:rate_fl", "a_fl:d_fr") and st.names[8] == "a_fl:offset"
    groups = np.arange(len(h)) // int(round(ident.block / DT))
    plain, plain_cov = compensated_fit(h, ys, run.y[:, 8:], ident.bandwidth, groups, compensate=False)
    for i in range(4):
        ref = sm.OLS(ys[:, i], h).fit(cov_type="cluster", cov_kwds={"groups": groups})
        np.testing.assert_allclose(plain[:, i], ref.params, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(np.sqrt(np.diag(plain_cov))[9 * i:9 * i + 9], ref.bse, rtol=1e-6)
    theta, cov = compensated_fit(h, ys, run.y[:, 8:], ident.bandwidth, groups)
    np.testing.assert_allclose(st.params, theta.T.ravel(), rtol=1e-7, atol=1e-9)
    # Compared in units of the standard errors (the Kronecker sums cancel to ~1e-6 of them).
    se = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(st.cov / np.outer(se, se), cov / np.outer(se, se), rtol=0, atol=1e-5)
    assert st.df[0] == groups[-1]
    # The compensation matters at this size: the damper coefficients move by over a tenth of a
    # standard error.
    assert np.max(np.abs(theta - plain).T.ravel() / se) > 0.1


def test_the_constants_from_a_drive_are_the_cars() -> None:
    # vehid's drive, class C at 15 m/s, 120 s: the coefficients hold each corner's spring and
    # damper, the inertias and the bars; with the body mass, each within a few tenths of a
    # percent (the bars: a few percent), inside its interval's reach.
    st = vehid.RealisticIdentifier(CAR, DT).fit(drive(120.0, seed=74_002).y).stats()
    phys = CAR.physical(st, M=TRUE["M"])
    assert set(phys) == {"M", *NAMES}  # kt and m: not determined by these sensors
    assert phys["M"] == (TRUE["M"],) * 3
    for name in NAMES:
        v, lo, hi = phys[name]
        tol = 0.1 if name.startswith("arb") else 0.01
        assert abs(v / TRUE[name] - 1) < tol, (name, v, TRUE[name])
        half = (hi - lo) / 2
        assert 0 < half and abs(v - TRUE[name]) < 2.5 * half, (name, phys[name], TRUE[name])


@pytest.mark.parametrize("seed", [74_101, 74_102])
def test_the_constants_on_an_independent_simulator(seed: int) -> None:
    # The states from benches/independent_road.py (Lagrange's equations with the bars, two
    # random-phase harmonic tracks, scipy's lsim), the sensors formed there with vehid's
    # default noise: every constant within 2 % (bars 10 %).
    x, xdot, _ = INDEPENDENT.simulate_full(TRUE, "C", 20.0, DT, 24_000, seed=seed)
    y = INDEPENDENT.full_realistic(TRUE, x, xdot, np.random.default_rng(seed + 1))
    phys = CAR.physical(vehid.RealisticIdentifier(CAR, DT).fit(y).stats(), M=TRUE["M"])
    for name in NAMES:
        tol = 0.1 if name.startswith("arb") else 0.02
        assert abs(phys[name][0] / TRUE[name] - 1) < tol, (name, phys[name], TRUE[name])


def test_pickles_continues_and_refuses_bad_input() -> None:
    y = drive(30.0, seed=74_003).y
    ident = vehid.RealisticIdentifier(CAR, DT).fit(y[:3000])
    assert "FullCar" in repr(ident) and ident.car is not None and ident.car.params == TRUE
    with pytest.raises(vehid.VehidError, match="no Structure"):
        _ = ident.structure
    back = pickle.loads(pickle.dumps(ident))
    twin = copy.deepcopy(ident)
    for obj in (ident, back, twin):
        obj.fit(y[3000:])
    assert np.array_equal(back.stats().params, ident.stats().params)
    assert np.array_equal(twin.stats().cov, ident.stats().cov)
    # Format 3 added the deflection noise's sums to the corner fits: a format-2 state of one is
    # refused, naming the formats read (the quarter car's format-2 states still load).
    fn, args, (fmt, version, payload) = ident.__reduce__()
    assert fmt == 3
    with pytest.raises(ValueError, match="format 2, and this vehid .* reads this fit in formats 3 to 3 only"):
        fn(*args).__setstate__((2, "vehid 0.1.0", payload))
    quarter = vehid.RealisticIdentifier(vehid.QuarterCar.passenger().structure(sensors="realistic"), DT)
    qfn, qargs, (_, qversion, qpayload) = quarter.__reduce__()
    qfn(*qargs).__setstate__((2, qversion, qpayload))
    before = pickle.dumps(ident)
    with pytest.raises(ValueError, match=r"shape \(samples, 12\)"):
        ident.fit(y[:, :3])
    with pytest.raises(ValueError, match=r"shape \(12,\)"):
        ident.update(np.zeros(3))
    bad = y[:10].copy()
    bad[4, 9] = np.nan
    with pytest.raises(ValueError, match="row 4, column 9"):
        ident.fit(bad)
    assert pickle.dumps(ident) == before
    st = ident.stats()
    with pytest.raises(ValueError, match="M="):
        CAR.physical(st)
    with pytest.raises(TypeError, match="m_fl"):
        CAR.physical(st, M=1500.0, m_fl=59.0)
    with pytest.raises(ValueError, match="samples"):
        vehid.RealisticIdentifier(CAR, DT).fit(y[:500]).stats()
    # The quarter car's structure is refused a full car's channels, and the other way round.
    s = vehid.QuarterCar.passenger().structure(known={"M": 320.0}, sensors="realistic")
    with pytest.raises(ValueError, match=r"shape \(samples, 3\)"):
        vehid.RealisticIdentifier(s, DT).fit(y)


def test_the_worked_example_runs() -> None:
    # docs/capabilities/real-roads.md, "The full car's realistic sensors": its Python block.
    page = (README.parent / "docs" / "capabilities" / "real-roads.md").read_text()
    blocks = [code for _, code in python_blocks(page) if "RealisticIdentifier(full" in code]
    assert len(blocks) == 1
    exec(compile(blocks[0], "real-roads.md", "exec"), {})


def test_vehid_identify_model_full_sensors_realistic(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A passenger full car's drive from `vehid simulate` (no bars), identified from its twelve
    # realistic channels: with --M every k and b within 1 % (--truth passenger gives the true
    # column; without it the drive's true_* columns would), the bars about 0, the tyres and
    # wheel masses not identifiable; without --M the constants are named as needing it.
    log = tmp_path / "full.csv"
    assert cli.main(["simulate", "--model", "full", "--road", "iso8608-C", "--speed", "20", "--sensors", "realistic",
                     "--n", "40000", "--seed", "4", "-o", str(log)]) == 0
    capsys.readouterr()
    assert cli.main(["identify", str(log), "--model", "full", "--sensors", "realistic", "--M", "1500",
                     "--truth", "passenger", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["model"] == "full" and r["bandwidth"] == 30.0 and len(r["params"]) == 36
    truth = vehid.FullCar.passenger().params
    for name in NAMES[:10]:
        c = r["constants"][name]
        assert abs(c["value"] / truth[name] - 1) < 0.01 and c["true"] == truth[name], (name, c)
    for bar in ("arb_f", "arb_r"):
        c = r["constants"][bar]
        assert abs(c["value"]) < c["high"] - c["low"], (bar, c)  # within about two standard errors of 0
    assert set(r["not_identifiable"]) == {f"{q}_{c}" for q in ("kt", "m") for c in ("fl", "fr", "rl", "rr")}
    assert cli.main(["identify", str(log), "--model", "full", "--sensors", "realistic"]) == 0
    out = capsys.readouterr().out
    assert "a_fl:rate_fl" in out and "Jx      not identifiable from these signals: needs a known body mass" in out
    assert cli.main(["identify", str(log), "--model", "full", "--sensors", "realistic", "--M", "1500",
                     "--geometry", "l_f=1.4,wheelbase=3"]) == 2
    assert "'wheelbase' is not one of l_f, l_r, track_f, track_r" in capsys.readouterr().err


# --- the half car: the same fit with its two corners -------------------------------------------

HALF = vehid.HalfCar.passenger()
HALF_NAMES = ["J", "k12", "k22", "b1", "b2"]


def test_the_half_car_from_its_realistic_sensors() -> None:
    # Its two body-corner equations from the six channels: the compensated least squares and
    # cluster sandwich of `compensated_fit` on scipy's filtered signals (statsmodels' cluster-
    # robust OLS per equation without the compensation); J and each spring and damper within
    # 1 % with M known.
    sm = pytest.importorskip("statsmodels.api")
    run = vehid.Simulator(HALF, dt=DT, road="iso8608-C", speed=15.0, sensors="realistic", seed=74_201).run(60_000)
    ident = vehid.RealisticIdentifier(HALF, DT).fit(run.y)
    st = ident.stats()
    assert st.names == ("a_f:d_f", "a_f:rate_f", "a_f:d_r", "a_f:rate_r", "a_f:offset",
                        "a_r:d_f", "a_r:rate_f", "a_r:d_r", "a_r:rate_r", "a_r:offset")
    from scipy import signal
    lam = ident.bandwidth
    b, a, _ = signal.cont2discrete(([lam**2], [1.0, 2 * lam, lam**2]), DT, method="bilinear")
    b = np.ravel(b)
    skip = ident.settling - 4

    def f(x: np.ndarray) -> np.ndarray:
        return signal.lfilter(b, a, x, zi=signal.lfilter_zi(b, a) * x[0])[0][skip:]

    cols = []
    for j in range(2):
        d = run.y[:, 4 + j]
        rate = (d[:-4] - 8 * d[1:-3] + 8 * d[3:-1] - d[4:]) / (12 * DT)
        cols += [-f(d[2:-2]), -f(rate)]
    h = np.column_stack(cols + [np.ones(len(cols[0]))])
    groups = np.arange(len(h)) // int(round(ident.block / DT))
    ys = np.column_stack([f(run.y[2:-2, i]) for i in range(2)])
    plain, plain_cov = compensated_fit(h, ys, run.y[:, 4:], lam, groups, compensate=False)
    theta, cov = compensated_fit(h, ys, run.y[:, 4:], lam, groups)
    for i in range(2):
        ref = sm.OLS(ys[:, i], h).fit(cov_type="cluster", cov_kwds={"groups": groups})
        np.testing.assert_allclose(plain[:, i], ref.params, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(np.sqrt(np.diag(plain_cov))[5 * i:5 * i + 5], ref.bse, rtol=1e-6)
        np.testing.assert_allclose(st.params[5 * i:5 * i + 5], theta[:, i], rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(st.bse[5 * i:5 * i + 5], np.sqrt(np.diag(cov))[5 * i:5 * i + 5], rtol=1e-6)
    phys = HALF.physical(st, M=HALF.params["M"])
    assert set(phys) == {"M", *HALF_NAMES}
    for name in HALF_NAMES:
        v, lo, hi = phys[name]
        assert abs(v / HALF.params[name] - 1) < 0.01 and lo < v < hi, (name, phys[name], HALF.params[name])
    back = pickle.loads(pickle.dumps(ident))
    assert "HalfCar" in repr(back) and np.array_equal(back.stats().cov, st.cov)
    with pytest.raises(ValueError, match=r"shape \(samples, 6\)"):
        ident.fit(np.zeros((10, 12)))
    # The structure route says where the half car's realistic fit is (not a quarter car per axle).
    with pytest.raises(vehid.VehidError, match=r"RealisticIdentifier\(half, dt\)"):
        HALF.structure(known={"M": 640.0}, sensors="realistic")
    with pytest.raises(vehid.VehidError, match=r"RealisticIdentifier\(full, dt\)"):
        CAR.structure()


@pytest.mark.parametrize("seed", [74_301, 74_302])
def test_the_half_car_on_an_independent_simulator(seed: int) -> None:
    # Newton's equations of the half car written without vehid (benches/independent_road.py,
    # scipy's lsim, its own ISO road), the sensors with vehid's default noise: J and each
    # spring and damper within 1 % with M known.
    y = INDEPENDENT.simulate_half_realistic(HALF.params, "C", 20.0, DT, 60_000, seed)
    phys = HALF.physical(vehid.RealisticIdentifier(HALF, DT).fit(y).stats(), M=HALF.params["M"])
    for name in HALF_NAMES:
        assert abs(phys[name][0] / HALF.params[name] - 1) < 0.01, (name, phys[name], HALF.params[name])


def test_vehid_identify_model_half_sensors_realistic(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "half.csv"
    assert cli.main(["simulate", "--model", "half", "--road", "iso8608-C", "--speed", "20", "--sensors", "realistic",
                     "--n", "40000", "--seed", "6", "-o", str(log)]) == 0
    capsys.readouterr()
    assert cli.main(["identify", str(log), "--model", "half", "--sensors", "realistic", "--M", "640", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["model"] == "half" and len(r["params"]) == 10
    for name in HALF_NAMES:  # the truth from the drive's true_* columns (no --truth given)
        c = r["constants"][name]
        assert abs(c["value"] / HALF.params[name] - 1) < 0.01 and c["true"] == HALF.params[name], (name, c)
    assert set(r["not_identifiable"]) == {"k11", "k21", "m1", "m2"}
    # --truth passenger is the passenger half car's (it was the full car's).
    assert cli.main(["identify", str(log), "--model", "half", "--sensors", "realistic", "--M", "640", "--truth",
                     "passenger", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["constants"]["k12"]["true"] == HALF.params["k12"]
    assert cli.main(["identify", str(log), "--model", "half", "--sensors", "realistic", "--M", "640",
                     "--geometry", "l_f=1.2"]) == 2
    assert "'l_f' is not one of l1, l2" in capsys.readouterr().err

"""The full car from Python: constants, the model against an independent numpy construction and
scipy's eigenvalues, pickling, drives (shapes, the rear delay, changes per corner, the sensors'
geometry, the left/right coherence by scipy's cross-spectra), the constants recovered from
identified rows, and the rows identified on one road by road cancellation on the two tracks (on
vehid's drives and on an independent simulator's), with their statistics."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import scipy.linalg
import scipy.signal
from bench_scripts import load  # tests/ is on sys.path under pytest
from scipy.special import k1

import vehid

DT = 0.005
CORNERS = ("fl", "fr", "rl", "rr")


# The full car's model written without vehid (Lagrange's equations, benches/independent_road.py).
INDEPENDENT = load("independent_road")


def test_constants_defaults_and_errors() -> None:
    car = vehid.FullCar.passenger()
    assert car.n_states == 14 and car.n_inputs == 4 and car.unknown_rows == (1, 3, 5, 7, 9, 11, 13)
    p = car.params
    assert list(p) == vehid.FullCar.CONSTANTS and len(p) == 25
    assert p["M"] == 1500.0 and p["Jx"] == 460.0 and p["Jy"] == 2160.0 and p["k_rr"] == 38000.0
    assert car.wheelbase == pytest.approx(3.1)
    sym = vehid.FullCar()
    assert all(sym.params[f"k_{c}"] == sym.params["k_fl"] for c in CORNERS)
    own = vehid.FullCar(**{**p, "b_fl": 1200.0, "arb_f": 8000.0})
    assert own.params["b_fl"] == 1200.0 and own.params["arb_f"] == 8000.0 and own != car
    with pytest.raises(TypeError, match="unexpected keyword argument 'b_xx'"):
        vehid.FullCar(b_xx=1.0)
    with pytest.raises(vehid.VehidError, match="M"):
        vehid.FullCar(M=0.0)
    with pytest.raises(vehid.VehidError, match="arb_r"):
        vehid.FullCar(arb_r=-1.0)
    with pytest.raises(vehid.VehidError, match="k_fl"):
        vehid.FullCar(k_fl="stiff")  # type: ignore[arg-type]
    assert "FullCar(M=1500.0" in repr(car)


def test_model_is_lagranges_and_poles_are_scipys() -> None:
    p = {**vehid.FullCar.passenger().params, "arb_f": 15000.0, "arb_r": 6000.0, "k_fr": 33000.0, "b_rl": 1150.0}
    car = vehid.FullCar(**p)
    np.testing.assert_allclose(car.a, INDEPENDENT.full_matrices(p)[0], rtol=1e-12, atol=1e-9)
    b = car.b
    for i, c in enumerate(CORNERS):
        assert b[2 * i + 1, i] == pytest.approx(p[f"kt_{c}"] / p[f"m_{c}"])
    assert np.count_nonzero(b) == 4
    ev = scipy.linalg.eigvals(car.a)
    got = np.sort_complex(car.poles())
    np.testing.assert_allclose(got, np.sort_complex(ev), rtol=1e-9)
    assert np.all(got.real < 0)


def test_equal_sides_are_the_half_car() -> None:
    half = vehid.HalfCar.passenger()
    h = half.params
    full = vehid.FullCar(
        M=2 * h["M"], Jy=2 * h["J"], Jx=480.0, l_f=h["l1"], l_r=h["l2"], track_f=1.45, track_r=1.55,
        arb_f=9000.0, arb_r=4000.0,
        **{f"kt_{c}": h["k11"] if c[0] == "f" else h["k21"] for c in CORNERS},
        **{f"k_{c}": h["k12"] if c[0] == "f" else h["k22"] for c in CORNERS},
        **{f"b_{c}": h["b1"] if c[0] == "f" else h["b2"] for c in CORNERS},
        **{f"m_{c}": h["m1"] if c[0] == "f" else h["m2"] for c in CORNERS},
    )
    e = np.zeros((14, 8))
    for fi, hi in [(0, 0), (1, 1), (2, 0), (3, 1), (4, 2), (5, 3), (6, 2), (7, 3), (8, 4), (9, 5), (10, 6), (11, 7)]:
        e[fi, hi] = 1.0
    eu = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 1.0]])
    np.testing.assert_allclose(full.a @ e, e @ half.a, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(full.b @ eu, e @ half.b, rtol=1e-12, atol=1e-9)


def test_pickles_and_compares() -> None:
    car = vehid.FullCar(**{**vehid.FullCar.passenger().params, "arb_f": 5000.0})
    back = pickle.loads(pickle.dumps(car))
    assert back == car and hash(back) == hash(car) and back.params == car.params


def drive(seconds: float, **kw: object) -> vehid.Run:
    kw.setdefault("seed", 1)
    sim = vehid.Simulator(vehid.FullCar.passenger(), dt=DT, road="iso8608-C", **kw)  # type: ignore[arg-type]
    return sim.run(int(round(seconds / DT)))


def test_the_api_drive_and_its_change() -> None:
    sim = vehid.Simulator(
        vehid.FullCar.passenger(), dt=0.005, road="iso8608-C", speed=15.0,
        changes=[(60.0, {"b_fl": 1350.0})], sensors="realistic", seed=1,
    )
    run = sim.run(14_000)
    n = len(run)
    assert run.channels == tuple(
        [f"a_body_{c}" for c in CORNERS] + [f"a_wheel_{c}" for c in CORNERS] + [f"deflection_{c}" for c in CORNERS]
    )
    assert run.y.shape == (n, 12) and run.x.shape == (n, 14) and run.u.shape == (n, 4)
    assert run.constants is not None and run.constants.shape == (n, 25)
    b_fl = run.constants[:, vehid.FullCar.CONSTANTS.index("b_fl")]
    assert np.all(b_fl[run.t < 60.0] == 1000.0) and np.all(b_fl[run.t >= 60.0] == 1350.0)
    # The deflection sensors read each corner's extension with 0.3 mm of noise.
    x = run.x
    for i, (cx, cy) in enumerate(INDEPENDENT.corner_positions(vehid.FullCar.passenger().params)):
        err = run.y[:, 8 + i] - (x[:, 8] + cx * x[:, 10] + cy * x[:, 12] - x[:, 2 * i])
        assert 0.27e-3 < np.std(err) < 0.33e-3
    # The body and wheels move, the sides differently.
    assert np.std(x[:, 12]) > 1e-4 and np.std(run.u[:, 0] - run.u[:, 1]) > 1e-3


def test_a_point_load_moves_the_body_as_lagranges_equations_say() -> None:
    # 120 kg set down 2.2 m behind and 0.4 m left of the centre of mass at 2 s (a boot load):
    # after it every sample's derivative is A'x + B'u + f' with A', B' from Lagrange's equations
    # with the point mass in the mass matrix (written without vehid) and f' = -M'^-1 m g w, the
    # load's weight (the unloaded car's is balanced at the initial equilibrium); before it the
    # unloaded car's. The constants show M + m, Jx + m y^2, Jy + m x^2.
    car = vehid.FullCar.passenger()
    p = car.params
    m, x, y = 120.0, -2.2, 0.4
    run = drive(4.0, speed=15.0, sensors="state", changes=[(2.0, {"load": m, "load_x": x, "load_y": y})])
    before, after = run.t < 2.0 - 1e-9, run.t >= 2.0 - 1e-9
    a0, b0 = INDEPENDENT.full_matrices(p)
    a1, b1 = INDEPENDENT.full_matrices(p, load=(m, x, y))
    w = np.zeros(7)
    w[4:] = [1.0, x, y]
    mass = np.diag([p[f"m_{c}"] for c in CORNERS] + [p["M"], p["Jy"], p["Jx"]]) + m * np.outer(w, w)
    f = np.zeros(14)
    f[1::2] = -np.linalg.solve(mass, m * 9.80665 * w)
    scale = np.abs(run.xdot).max(axis=0)
    for sel, a, b, c in ((before, a0, b0, np.zeros(14)), (after, a1, b1, f)):
        resid = run.xdot[sel] - run.x[sel] @ a.T - run.u[sel] @ b.T - c
        assert np.all(np.abs(resid) <= 1e-9 * scale + 1e-12), np.abs(resid).max(axis=0)
    assert run.constants is not None
    names = vehid.FullCar.CONSTANTS
    c_after = run.constants[after][0]
    assert c_after[names.index("M")] == p["M"] + m
    assert c_after[names.index("Jx")] == pytest.approx(p["Jx"] + m * y * y, rel=1e-15)
    assert c_after[names.index("Jy")] == pytest.approx(p["Jy"] + m * x * x, rel=1e-15)
    with pytest.raises(vehid.VehidError, match="give its mass"):
        drive(0.1, changes=[(1.0, {"load_x": -2.0})])
    with pytest.raises(vehid.VehidError, match="load.mass"):
        drive(0.1, changes=[(1.0, {"load": -5.0})])
    with pytest.raises(vehid.VehidError, match="FullCar"):
        vehid.Simulator(vehid.HalfCar.passenger(), dt=DT, road="iso8608-C", changes=[(1.0, {"load": 50.0})])


def test_rear_wheels_follow_their_front_tracks() -> None:
    # Wheelbase 3.1 m at 15.5 m/s and 200 Hz: 40 samples.
    run = drive(20.0, speed=15.5, seed=3)
    np.testing.assert_allclose(run.u[40:, 2], run.u[:-40, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.u[40:, 3], run.u[:-40, 1], rtol=0, atol=1e-12)
    state = drive(1.0, sensors="state")
    assert len(state.channels) == 28 and state.r.shape == (200, 14)


def test_left_right_coherence_is_the_isotropic_roads() -> None:
    # scipy's Welch cross-spectrum of the two front tracks, 3 seeds of 16 min at 15 m/s:
    # Re(G_lr)/sqrt(G_l G_r) against the model 1/(1 + (n/n_a)^2), n_a = 1.2572/(2π · 1.5 m),
    # itself within 0.041 of the isotropic road's 2πnB K1(2πnB).
    v, track = 15.0, 1.5
    n_a = 1.257151390677 / (2 * np.pi * track)
    nn = np.linspace(1e-3, 10.0, 20_000) * (1 / (2 * np.pi * track))
    iso = 2 * np.pi * nn * track * k1(2 * np.pi * nn * track)
    assert np.max(np.abs(iso - 1 / (1 + (nn / n_a) ** 2))) < 0.041
    est = []
    for seed in (5, 6, 7):
        run = drive(983.0, speed=v, seed=seed)
        f, gl = scipy.signal.welch(run.u[:, 0], fs=1 / DT, nperseg=4096)
        _, gr = scipy.signal.welch(run.u[:, 1], fs=1 / DT, nperseg=4096)
        _, glr = scipy.signal.csd(run.u[:, 0], run.u[:, 1], fs=1 / DT, nperseg=4096)
        est.append(glr.real / np.sqrt(gl * gr))
    coh = np.mean(est, axis=0)
    n = f / v  # cycles per metre
    for target in (0.03, 0.08, 0.13, 0.25, 0.5):
        j = np.argmin(np.abs(n - target))
        sl = slice(j - 2, j + 3)
        model = 1 / (1 + (n[sl] / n_a) ** 2)
        assert abs(np.mean(coh[sl]) - np.mean(model)) < 0.06, (target, np.mean(coh[sl]), np.mean(model))


def test_constants_back_from_identified_rows() -> None:
    # White road held per sample, the full state measured: batch least squares on the seven rows
    # (checked against numpy's lstsq), then physical() with the wheel masses known.
    car = vehid.FullCar.passenger()
    run = vehid.Simulator(car, dt=DT, road_sigma=0.01, seed=12).run(120_000)
    ls = vehid.BatchLeastSquares(car)
    ls.fit(run.r, run.z)
    theta = ls.theta
    rows = list(car.unknown_rows)
    by_numpy = np.linalg.lstsq(run.r, run.z[:, rows], rcond=None)[0].T
    np.testing.assert_allclose(theta, by_numpy, rtol=1e-6, atol=1e-6)
    masses = {f"m_{c}": car.params[f"m_{c}"] for c in CORNERS}
    exact = car.physical(car.theta, **masses)
    for k, v in car.params.items():
        assert exact[k] == pytest.approx(v, rel=1e-9, abs=1e-6), k
    est = car.physical(theta, **masses)
    for k, v in car.params.items():
        if not k.startswith("arb"):
            assert est[k] == pytest.approx(v, rel=0.05), (k, est[k], v)
    # With the identifier's Stats: intervals by the delta method on the rows' covariance.
    ivals = car.physical(ls.stats(alpha=0.01), **masses)
    for k, v in car.params.items():
        value, low, high = ivals[k]
        assert value == pytest.approx(est[k], rel=1e-9, abs=1e-9), k
        if k in ("M", "Jx", "Jy") or k[:2] in ("k_", "b_"):
            assert low < v < high, (k, low, v, high)
            assert 0.002 < (high - low) / v < 0.2, (k, low, high)
        elif not k.startswith("arb"):
            assert low == value == high and value == pytest.approx(v, rel=1e-12), k  # known: masses, tyres, geometry
    with pytest.raises(vehid.VehidError, match="m_fl="):
        car.physical(theta)
    with pytest.raises(vehid.VehidError, match="no physical structure yet"):
        car.structure(known=masses)


def cancelled_lstsq(run: vehid.Run, front: int, rear: int, rho: float, d: int) -> tuple[np.ndarray, np.ndarray]:
    """One track's road cancellation by numpy: z_rear(k) - rho z_front(k-d) regressed on
    [x(k), -rho x(k-d)] by least squares; the rear and the front row."""
    x, z = run.x, run.xdot
    h = np.hstack([x[d:], -rho * x[:-d]])
    y = z[d:, rear] - rho * z[:-d, front]
    sol = np.linalg.lstsq(h, y, rcond=None)[0]
    n = x.shape[1]
    return sol[:n], sol[n:]


def test_two_tracks_road_cancellation_on_an_iso_road() -> None:
    # ISO 8608 class C at 20 m/s, sampled every 5 ms (0.1 m: the rear wheels 31 samples behind),
    # the true state: each track's wheel rows by road cancellation, every non-zero entry of the
    # seven unknown rows within 5 % (and the same as numpy's least squares on the cancelled
    # equations), the constants back through physical(); the plain rows are far off.
    car = vehid.FullCar.passenger()
    v = 20.0
    run = vehid.Simulator(car, dt=DT, road="iso8608-C", speed=v, sensors="state", seed=31).run(20_000)
    two = vehid.TwoAxleIdentifier(car, spacing=v * DT, direct_front=False, p0="exact")  # least squares
    with pytest.raises(vehid.VehidError, match="lacks excitation"):
        two.theta  # noqa: B018  (no estimate before the first samples determine it)
    two.fit(run.x, run.xdot)
    assert (two.delay, two.paired) == (31, 20_000 - 31)
    rows = list(car.unknown_rows)
    nz = car.a[rows] != 0
    err = np.abs(two.a_hat[rows][nz] / car.a[rows][nz] - 1)
    assert err.max() < 0.05, err.max()
    b = car.b
    for j, (front, rear) in enumerate([(1, 5), (3, 7)]):  # left track, right track
        rho = b[rear, 2 + j] / b[front, j]
        a_rear, a_front = cancelled_lstsq(run, front, rear, rho, 31)
        np.testing.assert_allclose(two.a_hat[rear], a_rear, rtol=1e-8, atol=1e-8 * np.abs(a_rear).max())
        np.testing.assert_allclose(two.a_hat[front], a_front, rtol=1e-8, atol=1e-8 * np.abs(a_front).max())
    masses = {f"m_{c}": car.params[f"m_{c}"] for c in CORNERS}
    est = car.physical(two.theta, **masses)
    for k, val in car.params.items():
        if not k.startswith("arb"):
            assert est[k] == pytest.approx(val, rel=0.02), (k, est[k], val)
    plain = vehid.TwoAxleIdentifier(car, spacing=v * DT, method="none")
    plain.fit(run.x, run.xdot)
    wheel = [r for r in rows if r < 8]
    wnz = car.a[wheel] != 0
    assert np.abs(plain.a_hat[wheel][wnz] / car.a[wheel][wnz] - 1).max() > 0.5
    # Pickled, it continues bit for bit.
    twin = pickle.loads(pickle.dumps(two))
    more = vehid.Simulator(car, dt=DT, road="iso8608-C", speed=v, sensors="state", seed=32).run(500)
    two.fit(more.x, more.xdot)
    twin.fit(more.x, more.xdot)
    np.testing.assert_array_equal(two.theta, twin.theta)
    with pytest.raises(vehid.VehidError, match="does not divide the wheelbase"):
        vehid.TwoAxleIdentifier(car, spacing=15 * DT)
    with pytest.raises(vehid.VehidError, match="methods \"none\" and \"cancel\""):
        vehid.TwoAxleIdentifier(car, spacing=v * DT, method="thesis", p0="exact")


def test_two_tracks_statistics_give_the_constants_intervals() -> None:
    # White derivative noise of the declared size on the true derivatives, the exact start (a
    # prior's misfit would enter the residual sums): stats() by the joint filters, the
    # constants' intervals through physical() by the delta method; at alpha = 0.003 (about 3
    # standard errors) each holds the truth. Coverage over seeds: tests/two_axle.rs in Rust.
    car = vehid.FullCar.passenger()
    v, sv = 20.0, 0.05
    run = vehid.Simulator(car, dt=DT, road="iso8608-C", speed=v, sensors="state", seed=77).run(20_000)
    z = run.xdot + sv * np.random.default_rng(77).standard_normal(run.xdot.shape)
    two = vehid.TwoAxleIdentifier(car, spacing=v * DT, p0="exact", deriv_noise=sv, direct_front=False)
    two.fit(run.x, z)
    st = two.stats(alpha=0.003)
    assert st.names[0] == "a[1,0]" and len(st.params) == 7 * 14
    masses = {f"m_{c}": car.params[f"m_{c}"] for c in CORNERS}
    ivals = car.physical(st, **masses)
    for k, val in car.params.items():
        value, low, high = ivals[k]
        if k in ("M", "Jx", "Jy") or k[:2] in ("k_", "b_"):
            assert low < val < high, (k, low, val, high)
            assert (high - low) / val < 0.1, (k, low, high)


def test_two_tracks_on_data_from_an_independent_simulator() -> None:
    # benches/independent_road.py: the full car's A and B from Lagrange's equations written
    # there (checked against vehid's), two independent harmonic class C tracks (not vehid's
    # shaping filter nor its coherence model), scipy's lsim: every nonzero entry within 5 %.
    ir = INDEPENDENT
    car = vehid.FullCar.passenger()
    a, b = ir.full_matrices(car.params)
    np.testing.assert_allclose(a, car.a, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(b, car.b, rtol=1e-12, atol=1e-9)
    x, xdot, u = ir.simulate_full(car.params, "C", 20.0, DT, 20_000, 5)
    np.testing.assert_allclose(u[31:, 2:], u[:-31, :2], rtol=0, atol=1e-12)  # rear = front, 3.1 m later
    two = vehid.TwoAxleIdentifier(car, spacing=20.0 * DT, direct_front=False, p0="exact")
    two.fit(x, xdot)
    rows = list(car.unknown_rows)
    nz = car.a[rows] != 0
    assert np.abs(two.a_hat[rows][nz] / car.a[rows][nz] - 1).max() < 0.05


def test_two_tracks_gate_each_filter() -> None:
    # The full car's rows exceed what the outer screen holds: each filter gates its own samples
    # (gate=6, the default): one 1e30 derivative or state after 10^4 good samples moves the
    # estimate by under 10 %; with gate=0 the derivative ruins it.
    car = vehid.FullCar.passenger()
    run = vehid.Simulator(car, dt=DT, road="iso8608-C", speed=20.0, sensors="state", seed=41).run(12_000)
    truth = car.theta

    def xi_with(gate: float, col: int, in_state: bool) -> tuple[float, int]:
        x, z = run.x.copy(), run.xdot.copy()
        if col >= 0:
            (x if in_state else z)[10_000, col] = 1e30
        two = vehid.TwoAxleIdentifier(car, spacing=20.0 * DT, direct_front=False, gate=gate)
        two.fit(x, z)
        return vehid.xi(truth, two.theta), int(two.gated.min())

    clean, none_left_out = xi_with(6.0, -1, False)
    assert none_left_out == 0
    for col, in_state in [(5, False), (9, True), (0, True)]:
        value, left_out = xi_with(6.0, col, in_state)
        assert abs(value / clean - 1) < 0.1 and left_out == 1, (col, in_state, value, left_out)
    assert xi_with(0.0, 5, False)[0] > 10 * clean


def test_residuals_and_regressors_of_rows_no_structure_holds() -> None:
    # The full car's seven rows of 14 exceed a Structure: residuals and regressors come from the
    # rows themselves, z_r - theta_r . x (numpy's here), and the regression reproduces them.
    car = vehid.FullCar.passenger()
    run = vehid.Simulator(car, dt=DT, road_sigma=0.01, seed=13).run(3000)
    ident = vehid.KalmanIdentifier(car)
    ident.fit(run.r, run.z)
    rows = list(car.unknown_rows)
    want = run.z[:, rows] - run.r @ ident.theta.T
    np.testing.assert_allclose(ident.residuals(run.r, run.z), want, rtol=1e-12, atol=1e-12)
    h, y = ident.regressors(run.r, run.z, equation=2)
    assert h.shape == (3000, 98) and np.array_equal(h[:, 28:42], run.r) and not h[:, :28].any()
    np.testing.assert_allclose(y - h @ ident.theta.ravel(), want[:, 2], rtol=1e-12, atol=1e-10)


def test_batch_least_squares_on_the_full_car_is_screened() -> None:
    # The full car's seven rows of 14 exceed what the outlier screen's structure holds: batch
    # least squares gets the screen's magnitude test and held start alone. One 1e30 derivative
    # after 10^4 good samples: the estimate within 10 % in xi (gate=0: ruined).
    car = vehid.FullCar.passenger()
    run = vehid.Simulator(car, dt=DT, road_sigma=0.01, seed=12).run(12_000)

    def xi_with(gate: float, bad: bool) -> tuple[float, int]:
        z = run.z.copy()
        if bad:
            z[10_000, 5] = 1e30
        ls = vehid.BatchLeastSquares(car, gate=gate)
        ls.fit(run.r, z)
        return vehid.xi(car.theta, ls.theta), int(ls.gated.min())

    clean, _ = xi_with(6.0, False)
    screened, left_out = xi_with(6.0, True)
    assert abs(screened / clean - 1) < 0.1 and left_out == 1, (clean, screened, left_out)
    assert xi_with(0.0, True)[0] > 10 * clean

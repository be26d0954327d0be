"""The identifiers from Python: the same numbers as the core's own tests, through the binding.

Expected values come from an independent computation (numpy least squares with the prior as
extra rows, the thesis' printed structure), never from the code under test."""

import threading

import numpy as np
import pytest

import vehid

CAR = vehid.QuarterCar()
HALF = vehid.HalfCar()


def road_run(n: int = 3000, seed: int = 1, **kw: float) -> vehid.Run:
    opts = dict(dt=0.05, road_sigma=0.1, ic_sigma=0.1, deriv_noise=0.005, seed=seed)
    opts.update(kw)
    return vehid.Simulator(CAR, **opts).run(n)  # type: ignore[arg-type]


def ls_with_prior(r: np.ndarray, z: np.ndarray, p0: float, rv: float) -> np.ndarray:
    n = r.shape[1]
    a = np.vstack([r / np.sqrt(rv), np.eye(n) / np.sqrt(p0)])
    b = np.concatenate([z / np.sqrt(rv), np.zeros(n)])
    return np.linalg.lstsq(a, b, rcond=None)[0]


def test_kalman_equals_least_squares_with_prior() -> None:
    run = road_run()
    rv = CAR.row_noise_var(road_sigma=0.1, deriv_noise=0.005)
    kf = vehid.KalmanIdentifier(CAR, p0=1000.0, r=rv)
    kf.fit(run.r, run.z)
    for i, row in enumerate(CAR.unknown_rows):
        expect = ls_with_prior(run.r, run.z[:, row], 1000.0, rv[i])
        assert np.max(np.abs(kf.theta[i] - expect)) <= 1e-9 * np.max(np.abs(expect))


def test_r_from_noise_levels_equals_explicit_r() -> None:
    run = road_run(500)
    a = vehid.KalmanIdentifier(CAR, p0=1000.0, road_sigma=0.1, deriv_noise=0.005)
    b = vehid.KalmanIdentifier(CAR, p0=1000.0, r=CAR.row_noise_var(0.1, 0.005))
    a.fit(run.r, run.z)
    b.fit(run.r, run.z)
    assert np.array_equal(a.theta, b.theta)
    assert np.allclose(a.r, [90.0**2 * 0.01 + 0.005**2, 0.005**2])


def test_modes_agree_and_update_equals_fit() -> None:
    run = road_run(2000)
    thetas = {}
    for mode in ["rows", "shared", "full"]:
        kf = vehid.KalmanIdentifier(CAR, p0=1000.0, r=[0.3, 0.3], mode=mode)
        hist = kf.fit(run.r, run.z, record_every=500)
        assert hist.shape == (4, 2, 4)
        assert np.array_equal(hist[-1], kf.theta)
        thetas[mode] = kf.theta
    scale = np.max(np.abs(thetas["rows"]))
    assert np.max(np.abs(thetas["rows"] - thetas["shared"])) < 1e-10 * scale
    assert np.max(np.abs(thetas["rows"] - thetas["full"])) < 1e-10 * scale
    one = vehid.KalmanIdentifier(CAR, p0=1000.0, r=[0.3, 0.3])
    for rk, zk in zip(run.r, run.z):
        e = one.update(rk, zk)
    assert e.shape == (2,)
    assert np.array_equal(one.theta, thetas["rows"])
    assert one.samples == 2000


def test_covariance_shapes_and_a_hat() -> None:
    run = road_run(200)
    kf = vehid.KalmanIdentifier(CAR, p0=[1000.0, 10.0], r=[81.0, 1e-4])
    kf.fit(run.r, run.z)
    p = kf.covariance
    assert p.shape == (2, 4, 4)
    assert np.array_equal(p, np.transpose(p, (0, 2, 1)))
    assert np.all(np.linalg.eigvalsh(p) > 0)
    a_hat = kf.a_hat
    assert np.array_equal(a_hat[[0, 2]], CAR.a[[0, 2]])
    assert np.array_equal(a_hat[[1, 3]], kf.theta)
    full = vehid.KalmanIdentifier(CAR, p0=np.eye(8) * 100.0, r=[[0.5, 0.1], [0.1, 0.2]], mode="full")
    full.fit(run.r, run.z)
    assert full.covariance.shape == (8, 8) and full.r.shape == (2, 2)


def test_half_car_block_prior_per_row_matrices() -> None:
    # The thesis' 8-state P(0): 1000 on the wheel rows, 8 on the body rows.
    run = vehid.Simulator(HALF, road_sigma=0.1, deriv_noise=0.005, seed=2).run(2000)
    a = vehid.KalmanIdentifier(HALF, p0=[1000.0, 1000.0, 8.0, 8.0], road_sigma=0.1, deriv_noise=0.005)
    b = vehid.KalmanIdentifier(
        HALF, p0=np.stack([np.eye(8) * v for v in [1000.0, 1000.0, 8.0, 8.0]]), road_sigma=0.1, deriv_noise=0.005
    )
    a.fit(run.r, run.z)
    b.fit(run.r, run.z)
    assert np.allclose(a.theta, b.theta, rtol=0, atol=1e-9 * np.max(np.abs(a.theta)))


def test_reinit_is_counted_and_doubles_r() -> None:
    run = road_run(5000)
    kf = vehid.KalmanIdentifier(CAR, p0=10.0, road_sigma=0.1, deriv_noise=0.005, reinit=True)
    kf.fit(run.r, run.z)
    assert kf.reinit_count >= 1
    assert np.allclose(kf.r, CAR.row_noise_var(0.1, 0.005) * 2.0**kf.reinit_count)


def test_batch_least_squares_is_exact_on_noise_free_initial_conditions() -> None:
    run = vehid.Simulator(CAR, road_sigma=0.0, ic_sigma=0.1, deriv_noise=0.0, seed=4).run(4)
    ls = vehid.BatchLeastSquares(CAR)
    hist = ls.fit(run.r, run.z, record_every=1)
    theta = ls.theta
    assert np.array_equal(hist[-1], theta)  # the history: θ̂ on every prefix
    assert np.isnan(hist[:3]).all()  # fewer than 4 samples: no estimate yet
    assert np.max(np.abs(theta - CAR.theta) / np.abs(CAR.theta)) < 1e-9
    assert ls.samples == 4 and ls.storage_bytes >= 4 * 6 * 8
    short = vehid.BatchLeastSquares(CAR)
    short.fit(run.r[:3], run.z[:3])
    assert short.samples == 3  # stored; one more independent sample makes it solvable
    with pytest.raises(vehid.VehidError, match="lacks excitation"):
        _ = short.theta
    short.update(run.r[3], run.z[3])
    assert np.allclose(short.theta, theta, rtol=1e-9)


def test_gradient_gains_run_and_venter_is_slower_than_kalman() -> None:
    run = road_run(20_000, ic_sigma=0.08, deriv_noise=0.0)
    kf = vehid.KalmanIdentifier(CAR, p0=1000.0, road_sigma=0.1, deriv_noise=0.005)
    kf.fit(run.r, run.z)
    h = [0.4] * 4 + [4.0] * 4  # Eq 5.10: wheel-row weights a tenth of the body-row ones
    sg = vehid.StochasticGradient(CAR, gain="venter", h=h, p=0.51)
    sg.fit(run.r, run.z)
    assert vehid.xi(CAR.theta, sg.theta) > 10 * vehid.xi(CAR.theta, kf.theta)
    for gain in ["lyapunov", "ljung"]:
        g = vehid.StochasticGradient(CAR, gain=gain, h=[0.04, 0.4], spacing=2, state_noise_var=1e-6)
        g.fit(run.r[:1000], run.z[:1000])
        assert np.all(np.isfinite(g.theta)) and g.samples == 1000


def test_bad_arguments_name_the_argument() -> None:
    def bad(func, *words):  # type: ignore[no-untyped-def]
        with pytest.raises(vehid.VehidError) as info:
            func()
        for w in words:
            assert w in str(info.value), (w, str(info.value))

    bad(lambda: vehid.KalmanIdentifier(CAR, p0=0.0, r=[1.0, 1.0]), "p0")
    bad(lambda: vehid.KalmanIdentifier(CAR, p0=1.0, r=[-1.0, 1.0]), "r")
    bad(lambda: vehid.KalmanIdentifier(CAR, p0=1.0, r=[1.0, 1.0, 1.0]), "r")
    bad(lambda: vehid.KalmanIdentifier(CAR, p0=[1.0, 2.0, 3.0], r=[1.0, 1.0]), "p0")
    bad(lambda: vehid.KalmanIdentifier(CAR, p0=1.0), "r=")
    bad(lambda: vehid.KalmanIdentifier(CAR, r=[1.0, 1.0], road_sigma=0.1), "not both")
    bad(lambda: vehid.KalmanIdentifier(CAR, r=[1.0, 1.0], mode="fast"), "mode", "rows")
    bad(lambda: vehid.KalmanIdentifier(CAR, r=[1.0, 2.0], mode="shared"), "shared")
    bad(lambda: vehid.StochasticGradient(CAR, p=0.5), "p")
    bad(lambda: vehid.StochasticGradient(CAR, p=1.5), "p")
    bad(lambda: vehid.StochasticGradient(CAR, gain="newton"), "gain", "venter")
    bad(lambda: vehid.StochasticGradient(CAR, h=-1.0), "h")
    bad(lambda: vehid.StochasticGradient(CAR, spacing=0), "spacing")
    # gate=0: the identifier alone, whose refusals are checked here (with the default gate the
    # 1e300 sample below is screened: accepted, counted in `gated`, changing nothing else).
    kf = vehid.KalmanIdentifier(CAR, p0=1000.0, r=[81.0, 2.5e-5], reinit=True, gate=0)
    run = road_run(50)
    kf.fit(run.r, run.z)
    before = (kf.theta.copy(), kf.covariance.copy(), kf.samples, kf.reinit_count)
    bad(lambda: kf.update([0.0, np.nan, 0.0, 0.0], run.z[0]), "r_k", "index 1")
    bad(lambda: kf.update(run.r[0], [0.0, 0.0, 0.0, np.inf]), "z_k")
    bad(lambda: kf.update(run.r[0], run.z[0][:3]), "z_k", "(4,)")
    bad(lambda: kf.update([1e300] * 4, [1e300] * 4), "finite")
    bad(lambda: kf.fit(run.r, run.z[:-1]), "`z`")
    bad(lambda: kf.fit(run.r[:, :3], run.z[:, :3]), "`r`")
    r_nan = run.r.copy()
    r_nan[7, 2] = np.nan
    bad(lambda: kf.fit(r_nan, run.z), "r[7, 2]")
    bad(lambda: kf.fit(run.r, run.z, record_every=-1), "record_every")
    after = (kf.theta, kf.covariance, kf.samples, kf.reinit_count)
    assert np.array_equal(before[0], after[0]) and np.array_equal(before[1], after[1])
    assert before[2:] == after[2:]


def test_int_and_non_contiguous_input_are_accepted() -> None:
    run = road_run(300)
    a = vehid.KalmanIdentifier(CAR, p0=1000, r=[81, 1])
    b = vehid.KalmanIdentifier(CAR, p0=1000.0, r=[81.0, 1.0])
    big_r = np.zeros((300, 8))
    big_r[:, ::2] = run.r
    big_z = np.asfortranarray(run.z)
    a.fit(big_r[:, ::2], big_z)
    b.fit(run.r, run.z)
    assert np.array_equal(a.theta, b.theta)


def test_fit_from_threads_gives_identical_results() -> None:
    run = road_run(200_000)
    ids = [vehid.KalmanIdentifier(CAR, p0=1000.0, road_sigma=0.1, deriv_noise=0.005) for _ in range(2)]
    threads = [threading.Thread(target=i.fit, args=(run.r, run.z)) for i in ids]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert np.array_equal(ids[0].theta, ids[1].theta)
    assert ids[0].samples == 200_000


def test_fit_releases_the_gil(assert_releases_gil) -> None:  # type: ignore[no-untyped-def]
    run = road_run(25_000)
    kf = vehid.KalmanIdentifier(CAR, p0=1000.0, road_sigma=0.1, deriv_noise=0.005)
    assert_releases_gil(lambda: kf.fit(run.r, run.z), 40)
    assert kf.samples == 40 * 25_000

"""Two axles on one road: road simulator, AxleSampler, TwoAxleIdentifier."""

import numpy as np
import pytest

import vehid


def wheel_xi(half: vehid.HalfCar, theta: np.ndarray) -> float:
    return vehid.xi(half.theta[:2], theta[:2])


def test_road_simulator_rear_meets_front_road_and_reports_distance():
    half = vehid.HalfCar()
    sim = vehid.Simulator(half, speed=6.0, spacing=0.3, road="white", seed=3)
    run = sim.run(200)
    assert sim.road == "white" and sim.spacing == 0.3
    assert run.s is not None
    np.testing.assert_allclose(run.s, 0.3 * np.arange(200), atol=1e-9)
    np.testing.assert_allclose(run.t, 0.05 * np.arange(200), atol=1e-9)
    d = 10  # (l1 + l2) / spacing
    np.testing.assert_array_equal(run.u[d:, 1], run.u[:-d, 0])
    # A time simulation has no distance.
    assert vehid.Simulator(half).run(5).s is None


def test_per_sample_speeds_make_irregular_times_and_zeros_are_stops():
    half = vehid.HalfCar()
    speed = np.array([6.0, 3.0, 0.0, 12.0, 6.0, 6.0])
    sim = vehid.Simulator(half, speed=speed, spacing=0.3, dt=0.5)
    run = sim.run(5)  # five positive entries: five samples
    np.testing.assert_allclose(run.s, 0.3 * np.arange(5), atol=1e-12)
    # Sample k is followed by the interval at the next positive speed; the 0 entry is a 0.5 s
    # stop on the road point reached, before its sample.
    np.testing.assert_allclose(np.diff(run.t), [0.05, 0.1 + 0.5, 0.025, 0.05], atol=1e-12)
    with pytest.raises(vehid.VehidError, match="speed"):
        sim.run(2)  # only one positive entry left
    with pytest.raises(ValueError, match="speed"):
        vehid.Simulator(half, speed=[1.0, -1.0])
    with pytest.raises(ValueError, match="road"):
        vehid.Simulator(half, speed=6.0, road="bumpy")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="8-state"):
        vehid.Simulator(vehid.QuarterCar(), speed=6.0)


def test_independent_roads_match_the_time_simulator():
    half = vehid.HalfCar()
    a = vehid.Simulator(half, speed=6.0, spacing=0.3, road="independent", seed=5).run(500)
    b = vehid.Simulator(half, dt=0.05, seed=5).run(500)
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_allclose(a.x, b.x, atol=1e-9)


def test_road_cancellation_beats_plain_rows():
    half = vehid.HalfCar()
    run = vehid.Simulator(half, speed=6.0, spacing=0.3, road_sigma=0.1, deriv_noise=0.005, seed=1).run(20_000)
    errs = {}
    for method in ("none", "thesis", "cancel"):
        two = vehid.TwoAxleIdentifier(half, spacing=0.3, method=method, p0=1000.0, road_sigma=0.1, deriv_noise=0.005)
        two.fit(run.r, run.z)
        assert two.theta.shape == (4, 8) and two.a_hat.shape == (8, 8)
        assert two.samples == 20_000 and two.delay == 10
        errs[method] = wheel_xi(half, two.theta)
    assert errs["cancel"] <= 0.05
    assert errs["none"] >= 10 * errs["cancel"]


def test_two_axle_update_matches_fit_and_rejects_bad_samples():
    half = vehid.HalfCar()
    run = vehid.Simulator(half, speed=6.0, spacing=0.3, seed=2).run(300)
    a = vehid.TwoAxleIdentifier(half)
    b = vehid.TwoAxleIdentifier(half)
    a.fit(run.r, run.z)
    for r, z in zip(run.r, run.z):
        e = b.update(r, z)
        assert e.shape == (4,)
    np.testing.assert_array_equal(a.theta, b.theta)
    assert b.paired == 290
    before = b.theta.copy()
    bad = run.r[0].copy()
    bad[2] = np.nan
    with pytest.raises(vehid.VehidError, match="r_k"):
        b.update(bad, run.z[0])
    r = run.r.copy()
    r[5, 0] = np.inf
    with pytest.raises(vehid.VehidError, match=r"`r\[5, 0\]` is not finite.*unchanged"):
        b.fit(r, run.z)
    np.testing.assert_array_equal(b.theta, before)
    with pytest.raises(ValueError, match="method"):
        vehid.TwoAxleIdentifier(half, method="magic")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="spacing"):
        vehid.TwoAxleIdentifier(half, spacing=0.7)
    with pytest.raises(ValueError, match="wheelbase"):
        vehid.TwoAxleIdentifier(vehid.LinearModel(half.a, half.b, unknown_rows=[1, 3, 5, 7]))


def test_axle_sampler_pairs_within_tolerance_at_varying_speed():
    s = vehid.AxleSampler(wheelbase=3.0, spacing=0.3)
    assert s.delay == 10 and s.tolerance == pytest.approx(0.003)
    rng = np.random.default_rng(0)
    v, positions, pairs = 0.0, [], 0
    for _ in range(100_000):
        v = float(np.clip(v + rng.normal(0, 0.05), 0.0, 2.5))  # slow random ramps and stops
        t = s.advance(v, 0.001)
        if t is not None:
            sample, grid, pos, pair = t
            assert sample == len(positions)
            positions.append(pos)
            if pair is not None:
                assert abs(pos - 3.0 - positions[pair[0]]) <= s.tolerance
                assert pair[1] == grid - 10
                pairs += 1
    assert pairs > 0.9 * len(positions) - 10
    assert s.time_to_next(0.0) is None
    assert s.advance(0.0, 10.0) is None  # stopped: no sample
    with pytest.raises(vehid.VehidError, match="backwards"):
        s.feed(s.position - 1.0)
    s.reset(0.0)
    assert s.feed(0.0) == (len(positions), 0, 0.0, None)
    with pytest.raises(vehid.VehidError, match="capacity"):
        vehid.AxleSampler(wheelbase=3.0, spacing=0.0003)


def kalman_row(theta: np.ndarray, p: np.ndarray, x: np.ndarray, e: float, r: float) -> None:
    """One recursive least-squares step (Eq 4.3–4.6, standard form), in place."""
    px = p @ x
    s = x @ px + r
    theta += px * (e / s)
    p -= np.outer(px, px) / s


def thesis_wheel_rows(half: vehid.HalfCar, r: np.ndarray, z: np.ndarray, d: int, p0: float,
                      road_sigma: float, deriv_noise: float, sign: float = -1.0) -> tuple:
    """Eq 6.12–6.14 in numpy: the front wheel row's innovation ``e1(k) = z2(k) − x(k)ᵀθ̂_2``
    estimates ``b21 u1(k)``; the rear row's innovation is
    ``e2(k) = z4(k) − x(k)ᵀθ̂_4 − (b42/b21) e1(k − d)``, from its first pair on; each row a
    Kalman row with ``P(0) = p0 I`` and the variance of Eq 4.7, ``σ_v² + b² σ_u²``.
    (``sign=+1`` is the deliberately wrong Eq 6.14, to show the test can tell.)"""
    b = np.asarray(half.b)
    b21, b42 = b[1, 0], b[3, 1]
    rho = b42 / b21
    rf = deriv_noise**2 + b21**2 * road_sigma**2
    rr = deriv_noise**2 + b42**2 * road_sigma**2
    n = r.shape[1]
    tf, pf = np.zeros(n), p0 * np.eye(n)
    tr, pr = np.zeros(n), p0 * np.eye(n)
    e1 = np.zeros(len(r))
    for k in range(len(r)):
        x = r[k]
        e1[k] = z[k, 1] - tf @ x
        kalman_row(tf, pf, x, e1[k], rf)
        if k >= d:
            kalman_row(tr, pr, x, z[k, 3] - tr @ x + sign * rho * e1[k - d], rr)
    return tf, tr, (rf, rr)


def test_thesis_wheel_method_is_eq_6_14() -> None:
    half = vehid.HalfCar()
    run = vehid.Simulator(half, speed=6.0, spacing=0.3, road_sigma=0.1, deriv_noise=0.005, seed=4).run(3000)
    two = vehid.TwoAxleIdentifier(half, spacing=0.3, method="thesis", p0=1000.0, road_sigma=0.1, deriv_noise=0.005)
    for k in range(0, 3000, 500):  # along the run, not only at its end
        two.fit(run.r[k:k + 500], run.z[k:k + 500])
        front, rear, (rf, rr) = thesis_wheel_rows(half, run.r[:k + 500], run.z[:k + 500], two.delay, 1000.0, 0.1, 0.005)
        np.testing.assert_allclose(two.theta[0], front, rtol=1e-8, atol=1e-8 * np.max(np.abs(front)))
        np.testing.assert_allclose(two.theta[1], rear, rtol=1e-8, atol=1e-8 * np.max(np.abs(rear)))
    assert two.wheel_variances[:2] == pytest.approx((rf, rr), rel=1e-12)
    # The reference can tell the sign of Eq 6.14's correction: the rows differ far beyond the
    # tolerance above.
    _, wrong, _ = thesis_wheel_rows(half, run.r, run.z, two.delay, 1000.0, 0.1, 0.005, sign=+1.0)
    assert np.max(np.abs(wrong - rear)) > 1e-3 * np.max(np.abs(rear))

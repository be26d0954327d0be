"""Simulator: shapes, reproducibility, streaming, noise, and long-run statistics."""


import numpy as np
import pytest

import vehid

FIELDS = ("t", "x", "xdot", "u", "r", "z")


def test_run_shapes_and_time() -> None:
    for model in (vehid.QuarterCar(), vehid.HalfCar()):
        n, m = model.n_states, model.n_inputs
        run = vehid.Simulator(model, dt=0.05, seed=3).run(250)
        assert len(run) == 250 and (run.n_states, run.n_inputs) == (n, m)
        assert run.t.shape == (250,)
        for name in ("x", "xdot", "r", "z"):
            arr = getattr(run, name)
            assert arr.shape == (250, n) and arr.dtype == np.float64, name
        assert run.u.shape == (250, m)
        np.testing.assert_allclose(run.t, 0.05 * np.arange(250), rtol=1e-15)


def test_same_seed_bit_identical_different_seed_differs() -> None:
    kw = dict(road_sigma=0.1, ic_sigma=0.2, state_noise=0.01, deriv_noise=0.005)
    car = vehid.QuarterCar()
    a = vehid.Simulator(car, seed=7, **kw).run(2000)
    b = vehid.Simulator(car, seed=7, **kw).run(2000)
    c = vehid.Simulator(car, seed=8, **kw).run(2000)
    for name in FIELDS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    for name in ("x", "u", "r", "z"):
        assert not np.array_equal(getattr(a, name), getattr(c, name)), name


def test_run_continues_the_stream() -> None:
    car = vehid.HalfCar()
    whole = vehid.Simulator(car, seed=5).run(300)
    sim = vehid.Simulator(car, seed=5)
    parts = [sim.run(100), sim.run(0), sim.run(200)]
    assert sim.samples == 300
    for name in FIELDS:
        joined = np.concatenate([getattr(p, name) for p in parts])
        assert np.array_equal(joined, getattr(whole, name)), name
    empty = parts[1]
    assert empty.x.shape == (0, 8) and empty.u.shape == (0, 2)


def test_measurements_are_truth_without_noise_and_derivative_is_ax_plus_bu() -> None:
    car = vehid.QuarterCar()
    run = vehid.Simulator(car, road_sigma=0.1, ic_sigma=0.1, state_noise=0.0, deriv_noise=0.0).run(500)
    assert np.array_equal(run.r, run.x)
    assert np.array_equal(run.z, run.xdot)
    np.testing.assert_allclose(run.xdot, run.x @ car.a.T + run.u @ car.b.T, rtol=1e-12, atol=1e-12)


def test_per_component_noise_levels() -> None:
    # state noise only on the body position: the other measured states are exact.
    run = vehid.Simulator(vehid.QuarterCar(), state_noise=[0, 0, 0.01, 0], deriv_noise=0.0, seed=2).run(20_000)
    w = run.r - run.x
    assert np.array_equal(w[:, [0, 1, 3]], np.zeros((20_000, 3)))
    # Sample std of 20,000 normal draws: relative standard error 1/sqrt(2 n) = 0.5 %; 4 SE.
    assert w[:, 2].std() == pytest.approx(0.01, rel=0.02)
    half = vehid.Simulator(vehid.HalfCar(), road_sigma=[0.1, 0.0], seed=2).run(100)
    assert np.array_equal(half.u[:, 1], np.zeros(100)) and half.u[:, 0].any()


def test_pulses_and_instrumentation() -> None:
    car = vehid.QuarterCar()
    run = vehid.Simulator(car, road_sigma=0.0, pulses=[(8, 2, 0.5)]).run(12)
    assert run.u[:, 0].tolist() == [0.0] * 8 + [0.5, 0.5] + [0.0] * 2
    run = vehid.Simulator(car, state_noise=0.01, instrumentation=True).run(50)
    # Kinematic rows x1' = x2 and x3' = x4 read the velocity sensors (Eq 4.37-4.39).
    assert np.array_equal(run.z[:, 0], run.r[:, 1])
    assert np.array_equal(run.z[:, 2], run.r[:, 3])


def test_simulator_attributes() -> None:
    car = vehid.HalfCar()
    sim = vehid.Simulator(car, dt=0.05, seed=11)
    assert sim.dt == 0.05 and sim.seed == 11 and sim.method == "rk4"
    # The half car's fastest pole (about 65/s) is beyond RK4's stability at dt = 0.05 s.
    assert sim.substeps >= 2
    assert sim.model is car
    assert vehid.Simulator(car, substeps=10).substeps == 10
    assert vehid.Simulator(car, method="exact").substeps == 0
    assert "seed=11" in repr(sim)


def stationary_check(model: vehid.LinearModel, method: str, seed: int) -> None:
    """Long-run std of the simulated true state vs the analytic std at the sample instants.

    Tolerance: the samples are correlated, so the standard error of the sample variance is
    estimated from the data by batch means: 40 batches of 5,000 samples (5,000 samples are
    250 s, far longer than the slowest time constant, about 1.5 s, so batch variances are
    nearly independent). The std of the batch variances / sqrt(40) is the standard error of
    the overall variance; we allow 4 of those (a false alarm about once in 15,000 runs,
    and the seed is fixed anyway), converted to the std (relative error halves).
    """
    road_sigma, dt, batches, size = 0.1, 0.05, 40, 5_000
    sim = vehid.Simulator(model, dt=dt, road_sigma=road_sigma, seed=seed, method=method)
    sim.run(2_000)  # burn-in from x(0) = 0 (40 slowest time constants)
    x = sim.run(batches * size).x
    var_batches = np.square(x).reshape(batches, size, -1).mean(axis=1)  # zero-mean process
    var = var_batches.mean(axis=0)
    se_var = var_batches.std(axis=0, ddof=1) / np.sqrt(batches)
    expected = model.sampled_std(road_sigma, dt, method=method)
    rel_err = np.abs(np.sqrt(var) / expected - 1.0)
    rel_tol = 0.5 * 4.0 * se_var / var
    assert np.all(rel_tol < 0.05), rel_tol  # the check is meaningful: errors of a few % at most
    assert np.all(rel_err < rel_tol), (rel_err, rel_tol)


def test_long_run_std_matches_sampled_analytic_quarter_exact() -> None:
    stationary_check(vehid.QuarterCar(), "exact", seed=5)


def test_long_run_std_matches_sampled_analytic_half_rk4() -> None:
    stationary_check(vehid.HalfCar(), "rk4", seed=6)


def test_run_releases_the_gil(assert_releases_gil) -> None:  # type: ignore[no-untyped-def]
    sim = vehid.Simulator(vehid.HalfCar(), seed=1)
    assert_releases_gil(lambda: sim.run(25_000), 40)
    assert sim.samples == 40 * 25_000

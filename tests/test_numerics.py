"""Recursive estimates a statistician can trust: the exact start, the square-root form, priors
and tracking, each against an independent numpy least squares."""

from __future__ import annotations

import numpy as np
import pytest

import vehid

CAR = vehid.QuarterCar()


def regression(seed: int, n: int, scales: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random regressors with scaled columns, z rows 1 and 3 = x θ_row + noise (θ_j ~ 1/scale_j)."""
    rng = np.random.default_rng(seed)
    theta = rng.standard_normal((2, 4)) / scales
    x = rng.standard_normal((n, 4)) * scales
    z = np.zeros((n, 4))
    z[:, [1, 3]] = x @ theta.T + sigma * rng.standard_normal((n, 2))
    return x, z, theta


def test_exact_start_is_least_squares_on_every_prefix() -> None:
    # The default (no p0): from the first prefix that identifies the parameters on, the
    # recorded history equals numpy's least squares on each prefix.
    for seed in range(5):
        x, z, _ = regression(100 + seed, 40, np.array([1.0, 10.0, 0.1, 3.0]), 0.2)
        for form in ["standard", "sqrt"]:
            kf = vehid.KalmanIdentifier(CAR, form=form, gate=0)  # no gate: exact least squares
            hist = kf.fit(x, z, record_every=1)
            assert np.isnan(hist[:3]).all()  # three samples cannot identify four parameters
            for k in range(4, 41):
                expect = np.linalg.lstsq(x[:k], z[:k][:, [1, 3]], rcond=None)[0].T
                np.testing.assert_allclose(hist[k - 1], expect, rtol=1e-9, atol=1e-12 * np.abs(expect).max())


def test_square_root_form_is_the_prior_regularized_least_squares() -> None:
    # argmin Σ (z − xᵀθ)²/r + |θ − θ0|²/p0, by an augmented numpy lstsq, for p0 1e-3 … 1e12
    # and columns scaled 1e-6 … 1e6 (compared per contribution θ_j · scale_j).
    scales = np.array([1e-6, 1e-2, 1e2, 1e6])
    x, z, _ = regression(7, 300, scales, 1e-3)
    theta0 = np.array([[0.5, -1.0, 2.0, 0.1], [1.0, 0.0, -0.5, 0.2]]) / scales
    r = 0.5
    for p0 in [1e-3, 1.0, 1e6, 1e12]:
        kf = vehid.KalmanIdentifier(CAR, p0=p0, r=r, theta0=theta0, form="sqrt", gate=0)
        kf.fit(x, z)
        for i, row in enumerate([1, 3]):
            a = np.vstack([x / np.sqrt(r), np.eye(4) / np.sqrt(p0)])
            b = np.concatenate([z[:, row] / np.sqrt(r), theta0[i] / np.sqrt(p0)])
            expect = np.linalg.lstsq(a, b, rcond=None)[0]
            got = kf.theta[i]
            err = np.max(np.abs((got - expect) * scales)) / np.max(np.abs(expect * scales))
            assert err < 1e-7, (p0, row, err)


def test_a_block_diagonal_full_prior_is_accepted_by_the_rows_mode() -> None:
    x, z, _ = regression(3, 200, np.ones(4), 0.1)
    blocks = np.array([np.diag([1.0, 2.0, 3.0, 4.0]), np.eye(4) * 5.0])
    full = np.zeros((8, 8))
    full[:4, :4], full[4:, 4:] = blocks
    a = vehid.KalmanIdentifier(CAR, p0=blocks, r=1.0)
    b = vehid.KalmanIdentifier(CAR, p0=full, r=1.0)
    a.fit(x, z)
    b.fit(x, z)
    np.testing.assert_array_equal(a.theta, b.theta)
    full[0, 5] = full[5, 0] = 0.1
    with pytest.raises(vehid.VehidError, match="block-diagonal.*mode='full'"):
        vehid.KalmanIdentifier(CAR, p0=full, r=1.0)


def test_forgetting_tracks_a_20_percent_step() -> None:
    rng = np.random.default_rng(4)
    n, step = 8000, 4000
    x = rng.standard_normal((n, 4))
    truth = np.tile(CAR.theta, (n, 1, 1))
    truth[step:] *= 1.2
    z = np.zeros((n, 4))
    z[:, [1, 3]] = np.einsum("kij,kj->ki", truth, x) + 0.3 * rng.standard_normal((n, 2))
    kf = vehid.KalmanIdentifier(CAR, forgetting=0.995, form="sqrt")
    hist = kf.fit(x, z, record_every=1)
    err = np.max(np.abs(hist - truth) / np.abs(truth).max(axis=(1, 2))[:, None, None], axis=(1, 2))
    within = int(np.argmax(err[step:] < 0.02))
    assert 0 < within < 600, within


def test_settings_that_cannot_work_are_refused() -> None:
    with pytest.raises(vehid.VehidError, match="theta0"):
        vehid.KalmanIdentifier(CAR, theta0=np.zeros((2, 4)))  # a prior mean needs a p0
    with pytest.raises(vehid.VehidError, match="mode='rows'"):
        vehid.KalmanIdentifier(CAR, p0=10.0, r=1.0, mode="full", form="sqrt")
    with pytest.raises(vehid.VehidError, match="mode='rows'"):
        vehid.KalmanIdentifier(CAR, r=1.0, mode="shared")  # exact start is rows only
    with pytest.raises(vehid.VehidError, match="forgetting"):
        vehid.KalmanIdentifier(CAR, forgetting=1.5)
    with pytest.raises(vehid.VehidError, match="form"):
        vehid.KalmanIdentifier(CAR, form="cholesky")
    with pytest.raises(vehid.VehidError, match="not both"):
        vehid.KalmanIdentifier(CAR, form="sqrt", joseph=True)
    with pytest.raises(vehid.VehidError, match="p0"):
        vehid.KalmanIdentifier(CAR, p0="diffuse")


def test_the_gate_is_on_by_default_and_keeps_an_outlier_out() -> None:
    # The README's run with one corrupted derivative (1e30) in the middle: the default
    # identifier leaves it out and says so; with gate=0 it is ruined.
    run = vehid.Simulator(CAR, road_sigma=0.1, deriv_noise=0.005, seed=1).run(40_001)
    z = run.z.copy()
    z[20_000, 1] = 1e30
    kf = vehid.KalmanIdentifier(CAR, p0=1000.0, road_sigma=0.1, deriv_noise=0.005)
    kf.fit(run.r, z)
    clean = vehid.KalmanIdentifier(CAR, p0=1000.0, road_sigma=0.1, deriv_noise=0.005)
    clean.fit(run.r, run.z)
    # Left out by both rows: the screen's magnitude test (36 times the derivative's RMS) takes it
    # before the row's own gate, and a screened sample is left out by every row.
    assert list(kf.gated) == [1, 1]
    xi_clean = vehid.xi(CAR.theta, clean.theta)
    assert abs(vehid.xi(CAR.theta, kf.theta) - xi_clean) < 0.1 * xi_clean
    off = vehid.KalmanIdentifier(CAR, p0=1000.0, road_sigma=0.1, deriv_noise=0.005, gate=0)
    off.fit(run.r, z)
    assert vehid.xi(CAR.theta, off.theta) > 1e6

"""Residual diagnostics named as statsmodels names them — vehid.ccf, vehid.recursive_residuals,
vehid.cusum, Identifier.regressors, vehid.diagnostics — each checked against statsmodels on the
same numbers, and on drives: the thesis' identifier on a white road passes, on an ISO road its
wheel equation fails."""

from __future__ import annotations

import numpy as np
import pytest
from statsmodels.regression.recursive_ls import RecursiveLS
from statsmodels.tsa.stattools import ccf as sm_ccf

import vehid

CAR = vehid.QuarterCar.passenger()


def test_ccf_is_statsmodels_ccf() -> None:
    rng = np.random.default_rng(73_001)
    x = rng.standard_normal(500).cumsum()
    y = np.convolve(rng.standard_normal(500), [1.0, 0.6, 0.3], mode="same") + 0.2 * x
    np.testing.assert_allclose(vehid.ccf(x, y, nlags=12), sm_ccf(x, y, adjusted=True, fft=False, nlags=12),
                               rtol=1e-10, atol=1e-13)
    assert len(vehid.ccf(x, y)) == 500
    with pytest.raises(ValueError, match="y"):
        vehid.ccf(x, y[:-1], nlags=3)
    with pytest.raises(ValueError, match="variance"):
        vehid.ccf(np.ones(10), y[:10], nlags=3)


def test_recursive_residuals_and_cusum_are_statsmodels_recursive_ls() -> None:
    rng = np.random.default_rng(73_002)
    n, p = 400, 3
    h = np.column_stack([rng.standard_normal(n), rng.uniform(-1, 1, n), np.ones(n)])
    y = h @ [1.5, -2.0, 0.3] + 0.1 * rng.standard_normal(n)
    y[300:] += 0.15  # a change in the offset at sample 300
    res = RecursiveLS(y, h).fit()
    w = vehid.recursive_residuals(h, y)
    np.testing.assert_allclose(w, res.resid_recursive[p:], rtol=1e-8, atol=1e-12)
    c = vehid.cusum(w, alpha=0.05)
    np.testing.assert_allclose(c["cusum"], res.cusum, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(c["cusum_squares"], res.cusum_squares, rtol=1e-8, atol=1e-12)
    lower, upper = res._cusum_significance_bounds(alpha=0.05, ddof=0, points=np.arange(p + 1, n + 1))
    np.testing.assert_allclose(c["cusum_bound"], upper, rtol=1e-12)
    # The change is found, after it happened.
    assert c["first_cusum_crossing"] is not None and c["first_cusum_crossing"] + p > 300
    with pytest.raises(ValueError, match="shape"):
        vehid.recursive_residuals(h[:, :2].T, y)
    with pytest.raises(ValueError, match="excitation"):
        vehid.recursive_residuals(np.ones((10, 2)), np.arange(10.0))


def test_regressors_reproduce_the_residuals() -> None:
    run = vehid.Simulator(CAR, dt=0.005, road="iso8608-C", speed=15.0, sensors="state", seed=73_003).run(4000)
    ident = vehid.KalmanIdentifier(CAR.structure(known={"m": 40.0}))
    ident.fit(run.x, run.xdot)
    res = ident.residuals(run.x, run.xdot)
    for i in range(res.shape[1]):
        h, y = ident.regressors(run.x, run.xdot, equation=i)
        np.testing.assert_allclose(y - h @ ident.params, res[:, i], rtol=1e-9, atol=1e-9 * np.abs(y).max())
    with pytest.raises(ValueError, match="equation"):
        ident.regressors(run.x, run.xdot, equation=2)
    rows = vehid.KalmanIdentifier(CAR)  # a linear model's rows: the states are the regressors
    h, y = rows.regressors(run.x, run.xdot, equation=0)
    np.testing.assert_array_equal(h[:, :4], run.x)


@pytest.mark.parametrize("seed", [73_101, 73_102, 73_103])
def test_diagnostics_pass_the_thesis_setting_and_flag_a_real_road(seed: int) -> None:
    thesis = vehid.QuarterCar()
    run = vehid.Simulator(thesis, seed=seed).run(20_000)  # the thesis' white road, dt 0.05
    ident = vehid.KalmanIdentifier(thesis.structure(known={"m": 1.0}))
    ident.fit(run.r, run.z)
    for d in vehid.diagnostics(ident, run.r, run.z, lags=10, alpha=0.01):
        # alpha 0.01 each: three tests on two equations and three seeds fail together with
        # probability < 0.2, a fixed seed set keeps it from flaking.
        assert d["white"], d["ljung_box"]
        assert all(np.all(np.abs(c) < 5 * d["ccf_bound"]) for c in d["ccf"].values())
    car = CAR
    run = vehid.Simulator(car, dt=0.005, road="iso8608-C", speed=15.0, sensors="state", seed=seed).run(20_000)
    ident = vehid.KalmanIdentifier(car.structure(known={"m": 40.0}))
    ident.fit(run.x, run.xdot)
    body, wheel = vehid.diagnostics(ident, run.x, run.xdot, lags=10)
    assert not wheel["white"] and wheel["ljung_box"]["pvalue"] < 1e-10
    assert wheel["cusum"]["first_cusum_crossing"] is not None  # the road's drift in the recursive residuals
    assert body["white"] is not None and body["cusum"] is not None  # begins at rest: started where determined
    assert set(wheel["ccf"]) == {"M", "k1"} and set(body["ccf"]) == {"k2/M", "b/M"}

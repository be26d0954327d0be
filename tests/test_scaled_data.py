"""Data scaled far from the units an identifier works in: a right answer or a refusal naming the
fix, never a confident wrong one (the exact start's covariance `r R⁻¹R⁻ᵀ` scales as 1/x²)."""

from __future__ import annotations

import numpy as np
import pytest

import vehid

CAR = vehid.QuarterCar()
RUN = vehid.Simulator(CAR, seed=5).run(3000)


def xi(ident: vehid.KalmanIdentifier) -> float:
    return float(np.linalg.norm(ident.theta - CAR.theta) / np.linalg.norm(CAR.theta))


@pytest.mark.parametrize("form", ["standard", "sqrt"])
def test_the_exact_start_on_scaled_data_is_right_or_refused(form: str) -> None:
    reference = vehid.KalmanIdentifier(CAR, form=form)
    reference.fit(RUN.r, RUN.z)
    for scale in (1e-100, 1e100, 1e150):
        ident = vehid.KalmanIdentifier(CAR, form=form)
        ident.fit(RUN.r * scale, RUN.z * scale)
        assert xi(ident) == pytest.approx(xi(reference), rel=1e-6), scale
    for scale in (1e155, 1e300):
        ident = vehid.KalmanIdentifier(CAR, form=form)
        with pytest.raises(ValueError, match="rescale the units"):
            ident.fit(RUN.r * scale, RUN.z * scale)
        assert ident.samples == 0

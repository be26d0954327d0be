"""Claims that had no test failing when they broke, each against an independent
reference (``docs/claims.md`` lists the deliberate breaks these tests were seen to catch):

- the stochastic gradient (Eq 2.56, 5.2–5.18) step by step against numpy written from the
  equations: Venter, Lyapunov and Ljung gains, the Σ_w bias removal, the spacing;
- transactional updates for every identifier kind and mode: a refused NaN / inf sample, and a
  finite sample whose step overflows only after a multiplication, leave the whole state (the
  pickled bytes: every field of the core identifier) as it was, and the identifier then
  continues bit for bit as a twin that never saw them.
"""

from __future__ import annotations

import pickle
from typing import Any, Callable, List, Tuple

import numpy as np
import pytest

import vehid

CAR = vehid.QuarterCar()
ROWS = [1, 3]


def quarter_run(n: int, seed: int, state_noise: float = 0.0) -> vehid.Run:
    sim = vehid.Simulator(
        CAR, road_sigma=0.1, ic_sigma=0.1, deriv_noise=0.005, state_noise=state_noise, seed=seed
    )
    return sim.run(n)


# ---------------------------------------------------------------------------------------------
# Stochastic gradient against the equations
# ---------------------------------------------------------------------------------------------


class ReferenceSG:
    """The thesis' stochastic gradient from the equations, with ``H = I ⊗ xᵀ``:
    ``e_i = z_row − xᵀθ_i``; on every ``spacing``-th sample ``k ← k + 1``, the gain (Eq 5.8
    ``γ = k^(−p)``; Eq 5.9 ``γ = 1 / Σ_ij h_ij x_j²``; Eq 5.15–5.18 ``λ ← λ₀λ + 1 − λ₀``,
    ``γ ← γ / (γ + λ)`` from ``γ(0) = 1``, ``λ(0) = λ_init``) and Eq 2.56
    ``θ_i ← θ_i + γ h_i ∘ (Σ_w θ_i + x e_i)`` (``Σ_w = diag(state_noise_var)``)."""

    def __init__(self, gain: str, h: np.ndarray, p: float, sw: np.ndarray, spacing: int,
                 lambda0: float, lambda_init: float) -> None:
        self.gain, self.h, self.p, self.sw, self.spacing = gain, h, p, sw, spacing
        self.lambda0 = lambda0
        self.theta = np.zeros_like(h)
        self.seen = 0
        self.k = 0
        self.gamma = 1.0
        self.lam = lambda_init if gain == "ljung" else 1.0

    def step(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        e = z[ROWS] - self.theta @ x
        active = self.seen % self.spacing == 0
        self.seen += 1
        if not active:
            return e
        if self.gain == "venter":
            gamma = (self.k + 1.0) ** (-self.p)
        elif self.gain == "lyapunov":
            den = float(np.sum(self.h * x**2))
            if den <= 0:
                return e
            gamma = 1.0 / den
        else:
            self.lam = self.lambda0 * self.lam + (1.0 - self.lambda0)
            gamma = self.gamma / (self.gamma + self.lam)
        self.k += 1
        self.gamma = gamma
        self.theta = self.theta + gamma * self.h * (self.sw * self.theta + np.outer(e, x))
        return e


SG_CASES = [
    pytest.param(gain, p, sw, spacing, id=f"{gain}-p{p}-sw{int(sw)}-l{spacing}")
    for gain, p in [("venter", 0.51), ("venter", 0.95), ("lyapunov", 0.51), ("ljung", 0.51)]
    for sw in (False, True)
    for spacing in (1, 3)
]


@pytest.mark.parametrize("gain, p, with_sw, spacing", SG_CASES)
def test_stochastic_gradient_follows_the_equations_step_by_step(
    gain: str, p: float, with_sw: bool, spacing: int
) -> None:
    run = quarter_run(400, seed=7, state_noise=0.01)
    # Per-parameter weights, the wheel row one tenth of the body row (Eq 5.10), not all equal.
    body = np.array([0.4, 0.3, 0.2, 0.1])
    h = np.vstack([0.1 * body, body])
    sw = np.array([1e-2, 4e-2, 1e-2, 3e-2]) if with_sw else np.zeros(4)
    sg = vehid.StochasticGradient(
        CAR, gain=gain, h=h.ravel(), p=p, spacing=spacing, state_noise_var=sw, lambda0=0.99, lambda_init=0.95
    )
    ref = ReferenceSG(gain, h, p, sw, spacing, lambda0=0.99, lambda_init=0.95)
    scale = 1e-300
    for k, (x, z) in enumerate(zip(run.r, run.z)):
        e = sg.update(x, z)
        e_ref = ref.step(x, z)
        scale = max(scale, float(np.max(np.abs(ref.theta))))
        d = float(np.max(np.abs(sg.theta - ref.theta)))
        assert d <= 1e-12 * scale, f"step {k}: θ̂ {sg.theta} against the equations {ref.theta}"
        np.testing.assert_allclose(e, e_ref, rtol=0, atol=1e-12 * (scale * np.sum(np.abs(x)) + np.max(np.abs(e_ref))))
    assert scale > 1e-3, "the estimate never moved: nothing was compared"
    assert sg.samples == 400


def test_the_bias_removal_term_is_visible_to_the_comparison() -> None:
    """A flipped Σ_w sign must move θ̂ far beyond the 1e-12 tolerance above."""
    run = quarter_run(400, seed=7, state_noise=0.01)
    h = np.vstack([np.full(4, 0.04), np.full(4, 0.4)])
    sw = np.array([1e-2, 4e-2, 1e-2, 3e-2])
    a = ReferenceSG("venter", h, 0.51, sw, 1, 0.99, 0.95)
    b = ReferenceSG("venter", h, 0.51, -sw, 1, 0.99, 0.95)
    for x, z in zip(run.r, run.z):
        a.step(x, z)
        b.step(x, z)
    assert np.max(np.abs(a.theta - b.theta)) > 1e-6 * np.max(np.abs(a.theta))


# ---------------------------------------------------------------------------------------------
# Transactional updates
# ---------------------------------------------------------------------------------------------

RV = CAR.row_noise_var(0.1, 0.005)

IDENTIFIERS: List[Tuple[str, Callable[[], Any]]] = [
    ("rows-standard", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV)),
    ("rows-joseph", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV, form="joseph")),
    ("rows-sqrt", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV, form="sqrt")),
    ("rows-exact", lambda: vehid.KalmanIdentifier(CAR)),
    ("rows-sqrt-exact", lambda: vehid.KalmanIdentifier(CAR, form="sqrt")),
    ("rows-reinit", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV, reinit=True)),
    ("rows-forgetting", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV, forgetting=0.99, drift=1e-6)),
    ("rows-directional", lambda: vehid.KalmanIdentifier(CAR, form="sqrt", forgetting=0.98, directional=True)),
    ("rows-gate-huber", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV, gate=4.0, huber=2.0)),
    ("shared-standard", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=0.3, mode="shared")),
    ("shared-joseph", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=0.3, mode="shared", form="joseph")),
    ("shared-reinit", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=0.3, mode="shared", reinit=True)),
    ("full-standard", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=[[81.0, 0.01], [0.01, 2.5e-5]], mode="full")),
    ("sg-venter", lambda: vehid.StochasticGradient(CAR, h=[0.04, 0.4], state_noise_var=1e-4)),
    ("sg-lyapunov", lambda: vehid.StochasticGradient(CAR, gain="lyapunov", spacing=3)),
    ("sg-ljung", lambda: vehid.StochasticGradient(CAR, gain="ljung", h=0.1, state_noise_var=1e-4)),
    ("batch", lambda: vehid.BatchLeastSquares(CAR)),
    ("structured", lambda: vehid.KalmanIdentifier(CAR.structure(known={"m": 1.0}), p0=1000.0)),
    ("structured-exact", lambda: vehid.KalmanIdentifier(CAR.structure(known={"m": 1.0}))),
    ("structured-sg", lambda: vehid.StochasticGradient(CAR.structure(known={"m": 1.0}), h=0.01)),
    ("iv", lambda: vehid.IVIdentifier(CAR, delay=1, lags=0)),
    ("bias-compensated", lambda: vehid.BiasCompensated(CAR, state_noise_var=1e-6)),
]


GETTERS = ["theta", "params", "samples", "covariance", "r", "trace", "reinit_count", "gated", "a_hat"]


def state(ident: Any, pickled: bool = True) -> Any:
    """Every field of the core identifier: the postcard bytes behind the pickle; for a
    class that does not pickle, and with ``pickled=False``, every getter's bytes (or its
    error) and the statistics."""
    if pickled:
        try:
            return pickle.dumps(ident)
        except vehid.VehidError:
            pass
    out: List[Any] = []
    for name in GETTERS:
        try:
            out.append(np.asarray(getattr(ident, name)).tobytes())
        except AttributeError:
            out.append(None)
        except vehid.VehidError as e:
            out.append(str(e))
    try:
        st = ident.stats()
        out += [np.asarray(getattr(st, k)).tobytes() for k in ("params", "bse", "cov", "sigma2", "nobs", "df")]
    except (vehid.VehidError, AttributeError) as e:
        out.append(str(e))
    return out


def bad_samples(x: np.ndarray, z: np.ndarray) -> List[Tuple[np.ndarray, np.ndarray]]:
    out = []
    for i, v in [(0, np.nan), (2, np.inf), (3, -np.inf), (1, np.nan)]:
        bx = x.copy()
        bx[i] = v
        out.append((bx, z))
        bz = z.copy()
        bz[i] = v
        out.append((x, bz))
    return out


def refuses_and_continues(make: Callable[[], Any], bad: List[Tuple[np.ndarray, np.ndarray]], run: vehid.Run,
                          warm: int = 150, pickled: bool = True) -> None:
    ident = make()
    ident.fit(run.r[:warm], run.z[:warm])
    twin = make()  # the same samples, never the bad ones (not every class copies)
    twin.fit(run.r[:warm], run.z[:warm])
    before = state(ident, pickled)
    assert state(twin, pickled) == before
    for i, (x, z) in enumerate(bad):
        with pytest.raises((vehid.VehidError, ValueError)):
            ident.update(x, z)
        assert state(ident, pickled) == before, f"bad sample {i} changed the state"
    for x, z in zip(run.r[warm:], run.z[warm:]):  # update by update, as the bad ones came
        a = ident.update(x, z)
        b = twin.update(x, z)
        assert a.tobytes() == b.tobytes()
    assert state(ident) == state(twin)
    assert ident.samples == twin.samples == len(run.r)


@pytest.mark.parametrize("name, make", IDENTIFIERS, ids=[n for n, _ in IDENTIFIERS])
def test_every_identifier_refuses_non_finite_samples_and_changes_nothing(name: str, make: Callable[[], Any]) -> None:
    run = quarter_run(300, seed=11)
    refuses_and_continues(make, bad_samples(run.r[150], run.z[150]), run)


# The outlier gate off (the default gate would leave the sample out instead, and count it).
KALMAN: List[Tuple[str, Callable[[], Any]]] = [
    ("rows-standard", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV, gate=0)),
    ("rows-joseph", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV, form="joseph", gate=0)),
    ("rows-sqrt", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV, form="sqrt", gate=0)),
    ("rows-reinit", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV, reinit=True, gate=0)),
    ("rows-forgetting", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV, forgetting=0.99, drift=1e-6, gate=0)),
    ("shared-standard", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=0.3, mode="shared", gate=0)),
    ("shared-joseph", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=0.3, mode="shared", form="joseph", gate=0)),
    ("full-standard", lambda: vehid.KalmanIdentifier(CAR, p0=1000.0, r=[[81.0, 0.01], [0.01, 2.5e-5]], mode="full",
                                                     gate=0)),
    ("structured", lambda: vehid.KalmanIdentifier(CAR.structure(known={"m": 1.0}), p0=1000.0, gate=0)),
]


@pytest.mark.parametrize("name, make", KALMAN, ids=[n for n, _ in KALMAN])
def test_kalman_refuses_a_step_that_overflows_after_multiplication(name: str, make: Callable[[], Any]) -> None:
    """``x`` and ``z`` finite, and so are the innovation and ``s = xᵀPx + r``; the step
    ``P x e / s`` is not (one derivative near the largest float). Applied, it would change θ̂
    and P."""
    run = quarter_run(300, seed=13)
    z = run.z[150].copy()
    z[3] = np.finfo(float).max * 0.5  # the body row's derivative; the sum of |e| stays finite
    # The state: a measured one scaled by the first power of ten that makes a row's gain
    # ``P x / s`` exceed 2, on an independent reading of a rows filter's P (s and e finite).
    kf = vehid.KalmanIdentifier(CAR, p0=1000.0, r=RV)
    kf.fit(run.r[:150], run.z[:150])
    cov = kf.covariance

    def overflows(x: np.ndarray) -> bool:
        for i, row in enumerate(ROWS):
            p = cov[i]  # (rows, n, n): one P per row
            s = x @ p @ x + RV[i]
            e = z[row] - kf.theta[i] @ x
            with np.errstate(over="ignore"):
                if np.isfinite(s) and np.isfinite(e) and not np.all(np.isfinite(p @ x / s * e)):
                    return True
        return False

    x = next(run.r[150] * 10.0**k for k in range(-12, 3) if overflows(run.r[150] * 10.0**k))
    # The full form pickles its scratch space (P x, the gain, the factor of S), which a refused
    # sample overwrites: compare what it holds between samples, through every getter.
    refuses_and_continues(make, [(x, z)], run, pickled=not name.startswith("full"))


def test_stochastic_gradient_refuses_a_step_that_overflows_after_multiplication() -> None:
    run = quarter_run(300, seed=13)
    x = run.r[150].copy()
    x[0] = 1e3
    z = np.full(4, np.finfo(float).max * 0.5)
    for gain in ("venter", "ljung"):
        refuses_and_continues(
            # gate=0: the gradient's own refusal (the default screen would screen this sample)
            lambda g=gain: vehid.StochasticGradient(CAR, gain=g, h=0.4, state_noise_var=1e-4, gate=0), [(x, z)], run
        )

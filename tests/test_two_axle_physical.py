"""vehid.TwoAxleIdentifier on a Structure: road cancellation on the half car's physical
structure (the core's TwoAxleStructured), against the figures of
crates/vehid-core/tests/half_one_road.rs on the same samples.

The setting is the Rust test's (and the README's "Two axles on one road"): the thesis' half
car, a sample every 0.3 m at 6 m/s (d = 3 m / 0.3 m = 10), white road sigma 0.1 m,
derivative noise 0.005; m1, m2, l1, l2 known (12 parameters for the 28 non-zero entries of
rows 1, 3, 5, 7 of A).
"""

import copy
import pickle
from typing import Any, Dict, List

import numpy as np
import pytest

import vehid

HALF = vehid.HalfCar()
KNOWN: Dict[str, float] = {"m1": 1.0, "m2": 1.0, "l1": 2.0, "l2": 1.0}
PHYS = HALF.structure(known=KNOWN)


def road_run(n: int, seed: int) -> vehid.Run:
    sim = vehid.Simulator(HALF, road_sigma=0.1, deriv_noise=0.005, seed=seed, speed=6.0, spacing=0.3)
    return sim.run(n)


def physical(**kw: Any) -> vehid.TwoAxleIdentifier:
    args: Dict[str, Any] = {"car": HALF, "spacing": 0.3, "road_sigma": 0.1, "deriv_noise": 0.005, **kw}
    return vehid.TwoAxleIdentifier(PHYS, **args)


def worst_entry(a_hat: np.ndarray) -> float:
    """The largest relative error over the 28 non-zero entries of rows 1, 3, 5, 7 of A."""
    rows = list(HALF.unknown_rows)
    truth, est = HALF.a[rows], a_hat[rows]
    nz = truth != 0
    assert nz.sum() == 28
    return float(np.max(np.abs((est[nz] - truth[nz]) / truth[nz])))


def same(a: Any, b: Any) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return bool(a.shape == b.shape and a.tobytes() == b.tobytes())


@pytest.fixture(scope="module")
def run1() -> vehid.Run:
    return road_run(20_000, seed=1)


def test_every_entry_within_5_percent_where_the_rows_identifier_is_not(run1: vehid.Run) -> None:
    # `cargo test -p vehid-core --test integration half_one_road::every_entry -- --nocapture` prints, for
    # seed 1 (20,000 samples), the worst of the 28 entries: 1.56 % (physical structure) and
    # 5.41 % (rows identifier, Cancel). The binding gives those figures (to the digits
    # printed).
    two = physical()
    two.fit(run1.r, run1.z)
    rows = vehid.TwoAxleIdentifier(HALF, spacing=0.3, method="cancel", p0=1000.0, road_sigma=0.1, deriv_noise=0.005)
    rows.fit(run1.r, run1.z)
    w_phys, w_rows = worst_entry(two.a_hat), worst_entry(rows.a_hat)
    assert abs(w_phys - 0.0156) <= 0.00005 and w_phys < 0.05, w_phys
    assert abs(w_rows - 0.0541) <= 0.00005 and w_rows > 0.05, w_rows
    # params: the structure's 12; theta: the four rows they give, in the structure's order.
    assert two.params.shape == (12,) and two.structure == PHYS
    assert two.unknown_rows == [5, 7, 1, 3]
    assert two.theta.shape == (4, 8)
    np.testing.assert_array_equal(two.a_hat[two.unknown_rows], two.theta)
    np.testing.assert_allclose(two.theta, np.column_stack([PHYS.derivative(two.params, e) for e in np.eye(8)])[
        two.unknown_rows], rtol=1e-12, atol=1e-9)
    known = [r for r in range(8) if r not in two.unknown_rows]
    np.testing.assert_array_equal(two.a_hat[known], HALF.a[known])
    assert two.method == "cancel" and two.delay == 10 and two.paired == 20_000 - 10
    assert two.model is HALF and two.compensate and two.samples == 20_000
    front, rear, cancelled = two.wheel_variances
    np.testing.assert_allclose((front, rear, cancelled), rows.wheel_variances, rtol=1e-12)


def test_least_squares_without_compensation_is_the_attenuated_estimate(run1: vehid.Run) -> None:
    # The der(.) noise in the wheel equations' regressors pulls M, J, k11, k21 about 12 % low
    # (the core's module docs); compensate=False is plain least squares.
    plain = physical(compensate=False)
    plain.fit(run1.r, run1.z)
    comp = physical()
    comp.fit(run1.r, run1.z)
    names = list(PHYS.parameters)
    for name, truth in [("M", HALF.params["M"]), ("J", HALF.params["J"]), ("k11", HALF.params["k11"])]:
        j = names.index(name)
        assert plain.params[j] < 0.95 * truth < comp.params[j], (name, plain.params[j], comp.params[j])
    assert not plain.compensate
    # No residual statistics are kept (and the compensated estimate has no plain covariance).
    for two in (plain, comp):
        with pytest.raises(ValueError, match="not available"):
            two.stats()


def test_exact_start_then_estimates_and_a_prior() -> None:
    run = road_run(400, seed=2)
    two = physical()
    with pytest.raises(ValueError):
        _ = two.theta  # no estimate during the exact start
    hist = two.fit(run.r, run.z, record_every=1)
    assert hist.shape == (400, 12) and np.isnan(hist[0]).all() and np.isfinite(hist[-1]).all()
    np.testing.assert_array_equal(hist[-1], two.params)
    prior = physical(p0=1e6)
    prior.update(run.r[0], run.z[0])
    assert np.isfinite(prior.theta).all()


def test_pickled_and_copied_twins_continue_bit_for_bit() -> None:
    run = road_run(1200, seed=3)

    def rest(ident: vehid.TwoAxleIdentifier) -> List[Any]:
        """The continuation: fit with a history, then single updates; every figure's bits."""
        out = [ident.fit(run.r[600:1190], run.z[600:1190], record_every=30).tobytes()]
        out += [ident.update(run.r[k], run.z[k]).tobytes() for k in range(1190, 1200)]
        return out + [ident.params.tobytes(), ident.theta.tobytes(), ident.paired, ident.samples]

    for kw in ({}, {"p0": 1000.0, "direct_front": False}, {"compensate": False}):
        two = physical(**kw)
        two.fit(run.r[:600], run.z[:600])
        twins = [pickle.loads(pickle.dumps(two, protocol=p)) for p in (0, 2, 5)] + [copy.copy(two), copy.deepcopy(two)]
        mine = rest(two)
        for twin in twins:
            assert type(twin) is vehid.TwoAxleIdentifier and twin.structure == PHYS and twin.model == HALF
            assert (twin.spacing, twin.wheelbase, twin.compensate) == (two.spacing, two.wheelbase, two.compensate)
            assert twin.samples == 600
            assert rest(twin) == mine


def test_a_pickle_of_the_rows_identifier_is_refused_and_back() -> None:
    rows_state = vehid.TwoAxleIdentifier(HALF).__reduce__()[2]
    phys_state = physical().__reduce__()[2]
    with pytest.raises(vehid.VehidError):
        physical().__setstate__(rows_state)
    with pytest.raises(vehid.VehidError):
        vehid.TwoAxleIdentifier(HALF).__setstate__(phys_state)


def test_bad_input_raises_value_error_naming_the_argument() -> None:
    with pytest.raises(ValueError, match="`car` is needed"):
        vehid.TwoAxleIdentifier(PHYS)
    with pytest.raises(ValueError, match="`car` is for a Structure"):
        vehid.TwoAxleIdentifier(HALF, car=HALF)
    with pytest.raises(ValueError, match="car"):
        vehid.TwoAxleIdentifier(PHYS, car=vehid.QuarterCar())
    with pytest.raises(ValueError, match="method"):
        physical(method="thesis")
    with pytest.raises(ValueError, match="p0_body"):
        physical(p0_body=8.0)
    with pytest.raises(ValueError, match="p0"):
        physical(p0=-1.0)
    with pytest.raises(ValueError, match="p0"):
        physical(p0="diffuse")
    with pytest.raises(ValueError, match="p0"):
        vehid.TwoAxleIdentifier(HALF, p0="exact", method="thesis")
    with pytest.raises(ValueError, match="compensate"):
        vehid.TwoAxleIdentifier(HALF, compensate=False)
    with pytest.raises(ValueError, match="spacing"):
        physical(spacing=0.7)
    with pytest.raises(ValueError, match="deriv_noise"):
        physical(deriv_noise=-0.005)
    with pytest.raises(ValueError, match="road_sigma"):
        physical(road_sigma=np.nan)
    # A structure without the wheel rows' equations.
    body = vehid.Structure(states=[f"x{i}" for i in range(1, 9)], equations={"x6": "a*x5 + b*x6"})
    with pytest.raises(ValueError, match="wheel"):
        vehid.TwoAxleIdentifier(body, car=HALF)


def test_a_rejected_update_changes_nothing() -> None:
    run = road_run(300, seed=4)
    two = physical(gate=0)  # the identifier's own refusals (the default screen screens 1e300)
    two.fit(run.r[:200], run.z[:200])
    before = pickle.dumps(two)
    x, z = run.r[200], run.z[200]
    for r_k, z_k in [
        (np.where(np.arange(8) == 0, np.nan, x), z),
        (x, np.where(np.arange(8) == 7, np.inf, z)),
        (np.where(np.arange(8) == 4, 1e300, x), z),
        (x, np.where(np.arange(8) == 5, 1e300, z)),
        (x[:7], z),
    ]:
        with pytest.raises(ValueError):
            two.update(r_k, z_k)
        assert pickle.dumps(two) == before
    bad = run.r[200:210].copy()
    bad[9, 3] = np.nan
    with pytest.raises(ValueError, match=r"r\[9, 3\]"):
        two.fit(bad, run.z[200:210])
    assert pickle.dumps(two) == before and two.samples == 200

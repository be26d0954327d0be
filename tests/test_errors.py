"""Error paths: every bad input is a VehidError (a ValueError) naming the argument, or a
TypeError for a wrong keyword; never a pyo3 PanicException (which derives from
BaseException, so it would escape every `except Exception` and fail these tests)."""

import math
from typing import Any, Callable

import numpy as np
import pytest

import vehid

CAR = vehid.QuarterCar()
HALF = vehid.HalfCar()


def raises_vehid(func: Callable[[], Any], *words: str) -> str:
    with pytest.raises(vehid.VehidError) as info:
        func()
    assert isinstance(info.value, ValueError)
    message = str(info.value)
    for word in words:
        assert word in message, (word, message)
    return message


def test_vehid_error_is_value_error() -> None:
    assert issubclass(vehid.VehidError, ValueError)
    with pytest.raises(ValueError):
        vehid.QuarterCar(m=0.0)


@pytest.mark.parametrize("name", ["M", "m", "k1", "k2", "b"])
def test_quarter_constants_must_be_positive(name: str) -> None:
    for bad in (0.0, -1.0, math.nan, math.inf):
        raises_vehid(lambda bad=bad: vehid.QuarterCar(**{name: bad}), f"`{name}`")


def test_half_constants_must_be_positive() -> None:
    raises_vehid(lambda: vehid.HalfCar(J=-60.0), "`J`")
    raises_vehid(lambda: vehid.HalfCar(m2=0.0), "`m2`")


def test_negative_sigmas() -> None:
    raises_vehid(lambda: vehid.Simulator(CAR, road_sigma=-0.1), "`road_sigma`")
    raises_vehid(lambda: vehid.Simulator(CAR, ic_sigma=-1.0), "`ic_sigma`")
    raises_vehid(lambda: vehid.Simulator(CAR, state_noise=[0, 0, -0.01, 0]), "`state_noise`")
    raises_vehid(lambda: vehid.Simulator(CAR, deriv_noise=-0.005), "`deriv_noise`")
    raises_vehid(lambda: CAR.output_std(road_sigma=-1.0), "`road_sigma`")
    raises_vehid(lambda: CAR.row_noise_var(0.1, -0.005), "`deriv_noise`")
    raises_vehid(lambda: CAR.sampled_std(road_sigma=-1.0), "`road_sigma`")


def test_non_positive_dt_and_hold() -> None:
    for dt in (0.0, -0.05, math.nan, math.inf):
        raises_vehid(lambda dt=dt: vehid.Simulator(CAR, dt=dt), "`dt`")
        raises_vehid(lambda dt=dt: CAR.sampled_std(dt=dt), "`dt`")
    raises_vehid(lambda: CAR.output_std(hold=0.0), "`hold`")


def test_nan_and_inf_inputs() -> None:
    a = CAR.a.copy()
    a[2, 3] = np.nan
    raises_vehid(lambda: vehid.LinearModel(a, CAR.b, [1, 3]), "`a`", "index 11")
    b = CAR.b.copy()
    b[1, 0] = np.inf
    raises_vehid(lambda: vehid.LinearModel(CAR.a, b, [1, 3]), "`b`")
    theta = CAR.theta.copy()
    theta[0, 1] = np.nan
    raises_vehid(lambda: CAR.physical(theta, m=1.0), "`theta_hat`")
    raises_vehid(lambda: CAR.a_hat(theta), "`theta_hat`")
    raises_vehid(lambda: vehid.Simulator(CAR, road_sigma=math.nan), "`road_sigma`")
    raises_vehid(lambda: vehid.Simulator(CAR, pulses=[(0, 1, math.nan)]), "`pulses`")
    raises_vehid(lambda: CAR.physical(CAR.theta, m=math.nan), "`m`")
    raises_vehid(lambda: vehid.xi([1.0, math.nan], [1.0, 1.0]), "`theta`")
    raises_vehid(lambda: vehid.snr_db(1.0, math.nan), "`noise_std`")


def test_wrong_shapes() -> None:
    raises_vehid(lambda: vehid.LinearModel(np.zeros((3, 4)), np.zeros((3, 1)), [0]), "`a`", "(3, 4)")
    raises_vehid(lambda: vehid.LinearModel(np.zeros((2, 2, 2)), np.zeros((2, 1)), [0]), "`a`")
    raises_vehid(lambda: vehid.LinearModel(np.zeros(4), np.zeros((4, 1)), [0]), "`a`")
    raises_vehid(lambda: vehid.LinearModel(-np.eye(3), np.zeros((2, 1)), [0]), "`b`")
    raises_vehid(lambda: vehid.LinearModel(-np.eye(3), np.zeros((3, 5)), [0]), "`b`")
    raises_vehid(lambda: vehid.LinearModel(-np.eye(3), np.zeros((3, 0)), [0]), "`b`")
    raises_vehid(lambda: CAR.physical(np.zeros((2, 3)), m=1.0), "`theta_hat`", "(2, 3)")
    raises_vehid(lambda: CAR.a_hat(CAR.theta.ravel()), "`theta_hat`")
    raises_vehid(lambda: HALF.physical(CAR.theta, m1=1.0, m2=1.0), "`theta_hat`")
    raises_vehid(lambda: vehid.xi(CAR.theta, CAR.theta[:, :3]), "`theta_hat`")
    raises_vehid(lambda: vehid.snr_db([1.0, 2.0], [1.0, 2.0, 3.0]), "`noise_std`")
    raises_vehid(lambda: vehid.Simulator(HALF, road_sigma=[0.1, 0.1, 0.1]), "`road_sigma`")
    raises_vehid(lambda: vehid.Simulator(CAR, deriv_noise=[0.005] * 3), "`deriv_noise`")
    raises_vehid(lambda: vehid.Simulator(CAR, state_noise=[]), "`state_noise`")
    raises_vehid(lambda: vehid.Simulator(CAR, road_sigma=[[0.1]]), "`road_sigma`")
    raises_vehid(lambda: HALF.output_std(road_sigma=[1.0, 1.0, 1.0]), "`road_sigma`")
    raises_vehid(lambda: vehid.LinearModel("abc", [1.0], [0]), "`a`")


def test_state_and_input_counts() -> None:
    raises_vehid(lambda: vehid.LinearModel(-np.eye(17), np.ones((17, 1)), [0]), "`a`", "16")
    raises_vehid(lambda: vehid.LinearModel(np.zeros((0, 0)), np.zeros((0, 1)), [0]), "`a`")
    raises_vehid(lambda: vehid.LinearModel(-np.eye(2), np.ones((2, 5)), [0]), "`b`", "4")


def test_bad_unknown_rows() -> None:
    a, b = CAR.a, CAR.b
    raises_vehid(lambda: vehid.LinearModel(a, b, [1, 4]), "`unknown_rows`", "row 4")
    raises_vehid(lambda: vehid.LinearModel(a, b, [1, 1]), "`unknown_rows`", "row 1")
    raises_vehid(lambda: vehid.LinearModel(a, b, [-1]), "`unknown_rows`")
    raises_vehid(lambda: vehid.LinearModel(a, b, []), "`unknown_rows`")
    raises_vehid(lambda: vehid.LinearModel(a, b, [1], structural_zeros=[(0, 1)]), "`structural_zeros`")
    raises_vehid(lambda: vehid.LinearModel(a, b, [1], structural_zeros=[(1, 9)]), "`structural_zeros`")


def test_unknown_method_string_lists_valid_ones() -> None:
    for call in (
        lambda: vehid.Simulator(CAR, method="euler"),
        lambda: CAR.sampled_std(method="RK4"),
        lambda: CAR.sampled_cov(method=""),
    ):
        raises_vehid(call, "`method`", '"rk4"', '"exact"')


def test_bad_integers() -> None:
    sim = vehid.Simulator(CAR)
    raises_vehid(lambda: sim.run(-1), "`n`")
    raises_vehid(lambda: vehid.Simulator(CAR, seed=-1), "`seed`")
    raises_vehid(lambda: vehid.Simulator(CAR, seed=2**64), "`seed`")
    raises_vehid(lambda: vehid.Simulator(CAR, substeps=0), "`substeps`")
    raises_vehid(lambda: vehid.Simulator(CAR, substeps=-3), "`substeps`")
    raises_vehid(lambda: vehid.Simulator(HALF, substeps=1), "`substeps`")  # RK4 would diverge
    raises_vehid(lambda: vehid.Simulator(CAR, pulses=[(0, 0, 1.0)]), "`pulses`")
    raises_vehid(lambda: vehid.Simulator(CAR, pulses=[(-1, 1, 1.0)]), "`pulses`")
    raises_vehid(lambda: vehid.Simulator(CAR, pulses=[(0, 1, 1.0)] * 9), "`pulses`")
    assert sim.samples == 0  # a rejected run() leaves the stream where it was


def test_physical_needs_the_right_known_values() -> None:
    raises_vehid(lambda: CAR.physical(CAR.theta), "m=", "M=")
    raises_vehid(lambda: CAR.physical(CAR.theta, m=1.0, M=10.0), "exactly one")
    raises_vehid(lambda: CAR.physical(CAR.theta, m=-1.0), "`m`")
    raises_vehid(lambda: HALF.physical(HALF.theta, m1=1.0), "m2=")
    raises_vehid(lambda: CAR.physical(np.zeros((2, 4)), m=1.0), "cannot recover")
    generic = vehid.LinearModel(CAR.a, CAR.b, [1, 3])
    raises_vehid(lambda: generic.physical(CAR.theta, m=1.0), "generic LinearModel")
    with pytest.raises(TypeError, match="mass"):
        CAR.physical(CAR.theta, mass=1.0)


def test_unknown_keywords_are_type_errors() -> None:
    with pytest.raises(TypeError):
        vehid.Simulator(HALF, velocity=6.0)  # type: ignore[call-arg]
    with pytest.raises(TypeError):
        vehid.QuarterCar(J=1.0)  # type: ignore[call-arg]
    with pytest.raises(TypeError):
        vehid.Simulator("not a model")  # type: ignore[arg-type]


def test_unstable_model_has_no_stationary_quantities() -> None:
    a = CAR.a.copy()
    a[3, 3] = 100.0
    unstable = vehid.LinearModel(a, CAR.b, [1, 3])
    raises_vehid(lambda: unstable.output_std(1.0), "pole")
    raises_vehid(lambda: unstable.sampled_std(0.1, method="exact"), "pole")


def test_a_rejected_call_changes_nothing() -> None:
    sim = vehid.Simulator(CAR, seed=4)
    first = sim.run(10)
    raises_vehid(lambda: sim.run(-5), "`n`")
    again = vehid.Simulator(CAR, seed=4)
    again.run(10)
    assert np.array_equal(sim.run(10).x, again.run(10).x)
    assert first.x.shape == (10, 4)


WEIRD = [None, "x", b"x", [], [[]], [1.0, "a"], {}, np.array([]), np.zeros((0, 4)), np.zeros((2, 4, 1)),
         1e308, -1e308, 1e-308, np.inf, np.nan, 2**70, -(2**70), True, object(), np.array(["a"]),
         np.ones((16, 16)) * 1e300, np.ones((4, 4), dtype=np.int8)]


def never_panics(func: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
    try:
        func(*args, **kwargs)
    except Exception:
        pass  # VehidError, TypeError, MemoryError...: all fine. A PanicException is not.


def test_no_input_panics() -> None:
    for w in WEIRD:
        never_panics(vehid.LinearModel, w, CAR.b, [1])
        never_panics(vehid.LinearModel, CAR.a, w, [1])
        never_panics(vehid.LinearModel, CAR.a, CAR.b, w)
        never_panics(vehid.LinearModel, w, w, [0])
        never_panics(vehid.LinearModel, CAR.a, CAR.b, [1], structural_zeros=w)
        never_panics(vehid.QuarterCar, M=w)
        never_panics(vehid.HalfCar, l1=w)
        never_panics(CAR.output_std, w)
        never_panics(CAR.output_std, 1.0, w)
        never_panics(CAR.row_noise_var, w, w)
        never_panics(CAR.sampled_std, w)
        never_panics(CAR.sampled_std, 0.1, w)
        never_panics(CAR.sampled_std, 0.1, 0.05, "rk4", w)
        never_panics(CAR.physical, w, m=1.0)
        never_panics(CAR.physical, CAR.theta, m=w)
        never_panics(HALF.physical, w, m1=w, m2=1.0)
        never_panics(CAR.a_hat, w)
        never_panics(vehid.xi, w, w)
        never_panics(vehid.xi, CAR.theta, w)
        never_panics(vehid.snr_db, w, 1.0)
        never_panics(vehid.snr_db, w, w)
        for key in ("dt", "road_sigma", "ic_sigma", "state_noise", "deriv_noise", "seed", "substeps",
                    "method", "pulses", "instrumentation"):
            never_panics(lambda key=key, w=w: vehid.Simulator(CAR, **{key: w}).run(2))
        never_panics(vehid.Simulator(CAR).run, w)
    # Extreme but finite models: huge or tiny entries must give errors or numbers, not panics.
    for scale in (1e-300, 1e150, 1e300):
        model = vehid.LinearModel(-np.eye(3) * scale, np.ones((3, 2)) * scale, [0, 2])
        for call in (model.poles, model.output_std, model.sampled_std,
                     lambda model=model: model.sampled_std(method="exact"),
                     lambda model=model: model.row_noise_var(1e300),
                     lambda model=model: vehid.Simulator(model).run(3),
                     lambda model=model: vehid.Simulator(model, method="exact").run(3)):
            never_panics(call)

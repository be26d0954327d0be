"""Models: structure, poles, Eq 4.27 output standard deviations, SNR, physical round trips.

Expected numbers are either the thesis' printed values (compared within the precision they
are printed to) or computed here independently from the model's own matrices.
"""

from decimal import Decimal

import numpy as np
import pytest

import vehid

# Eq 3.14 and Eq 6.8 as printed in the thesis (strings: the number of printed digits sets the
# tolerance, one unit of the last printed digit).
QUARTER_POLES = [("-0.727", "2.30"), ("-0.727", "-2.30"), ("-1.90", "0"), ("-40.6", "0")]
HALF_POLES = [
    ("-0.656", "3.11"),
    ("-0.656", "-3.11"),
    ("-0.691", "2.08"),
    ("-0.691", "-2.08"),
    ("-0.738", "0"),
    ("-0.837", "0"),
    ("-61.5", "0"),
    ("-65.3", "0"),
]
# Eq 4.28: sigma_i / sigma_u for the quarter car, road noise held for 0.05 s.
QUARTER_OUTPUT_STD = [0.386, 1.84, 0.402, 1.03]
# Eq 4.31-4.32: sensor SNR in dB at sigma_u = 25 sigma_w.
QUARTER_SNR_DB = [19.7, 33.3, 20.0, 28.2]


def last_digit(printed: str) -> float:
    """One unit of the last printed digit of a decimal string ("-0.727" -> 0.001)."""
    exponent = Decimal(printed).as_tuple().exponent
    assert isinstance(exponent, int)
    return float(10.0**exponent)


def assert_poles_match(poles: np.ndarray, printed: list) -> None:
    assert poles.dtype == np.complex128
    assert len(poles) == len(printed)
    remaining = list(poles)
    for re_s, im_s in printed:
        re, im = float(re_s), float(im_s)
        # Match each printed pole to the nearest computed one.
        best = min(remaining, key=lambda p: abs(p - complex(re, im)))
        remaining.remove(best)
        assert abs(best.real - re) <= last_digit(re_s), (best, re_s, im_s)
        if im == 0.0:
            assert abs(best.imag) < 1e-9, best
        else:
            assert abs(best.imag - im) <= last_digit(im_s), (best, re_s, im_s)


def test_quarter_car_poles_eq_3_14() -> None:
    assert_poles_match(vehid.QuarterCar().poles(), QUARTER_POLES)


def test_half_car_poles_eq_6_8() -> None:
    assert_poles_match(vehid.HalfCar().poles(), HALF_POLES)


def test_quarter_car_structure() -> None:
    car = vehid.QuarterCar()
    assert isinstance(car, vehid.LinearModel)
    assert (car.n_states, car.n_inputs, car.unknown_rows) == (4, 1, (1, 3))
    assert car.a.shape == (4, 4) and car.b.shape == (4, 1)
    assert car.a.dtype == np.float64
    # Eq 3.11 from the constants given to the constructor.
    M, m, k1, k2, b = 10.0, 1.0, 90.0, 50.0, 40.0
    expected_a = np.array(
        [[0, 1, 0, 0], [-(k1 + k2) / m, -b / m, k2 / m, b / m], [0, 0, 0, 1], [k2 / M, b / M, -k2 / M, -b / M]]
    )
    np.testing.assert_allclose(car.a, expected_a, rtol=1e-15)
    np.testing.assert_allclose(car.b[:, 0], [0, k1 / m, 0, 0], rtol=1e-15)
    np.testing.assert_array_equal(car.theta, car.a[[1, 3], :])
    assert car.structural_zeros.shape == (2, 4) and not car.structural_zeros.any()
    assert car.params == {"M": M, "m": m, "k1": k1, "k2": k2, "b": b}
    assert repr(car) == "QuarterCar(M=10.0, m=1.0, k1=90.0, k2=50.0, b=40.0)"


def test_half_car_structure() -> None:
    half = vehid.HalfCar()
    assert (half.n_states, half.n_inputs, half.unknown_rows) == (8, 2, (1, 3, 5, 7))
    assert half.theta.shape == (4, 8)
    np.testing.assert_array_equal(half.theta, half.a[[1, 3, 5, 7], :])
    # Eq 6.10: four structurally zero parameters (front row at x2, x2'; rear row at x1, x1').
    zeros = np.argwhere(half.structural_zeros).tolist()
    assert zeros == [[0, 2], [0, 3], [1, 0], [1, 1]]
    assert half.wheelbase == 3.0
    np.testing.assert_allclose(half.b[[1, 3], [0, 1]], [100.0, 100.0])
    assert "J=60.0" in repr(half)


def test_output_std_eq_4_28() -> None:
    sd = vehid.QuarterCar().output_std(road_sigma=1.0, hold=0.05)
    assert sd.shape == (4,)
    np.testing.assert_allclose(sd, QUARTER_OUTPUT_STD, rtol=0.005)
    # Linear in sigma_u; per-input sigma equals the scalar for one input.
    np.testing.assert_allclose(vehid.QuarterCar().output_std(0.1), 0.1 * sd, rtol=1e-12)
    np.testing.assert_allclose(vehid.QuarterCar().output_std([0.1]), 0.1 * sd, rtol=1e-12)


def test_snr_at_sigma_u_25_sigma_w_eq_4_32() -> None:
    sigma_w = 0.004
    sd = vehid.QuarterCar().output_std(road_sigma=25 * sigma_w)
    snr = vehid.snr_db(sd, sigma_w)
    assert isinstance(snr, np.ndarray) and snr.shape == (4,)
    np.testing.assert_allclose(snr, QUARTER_SNR_DB, atol=0.1)


def test_snr_db_scalar_and_arrays() -> None:
    assert isinstance(vehid.snr_db(10.0, 1.0), float)
    assert vehid.snr_db(10.0, 1.0) == pytest.approx(20.0)
    np.testing.assert_allclose(vehid.snr_db([1.0, 10.0], [1.0, 1.0]), [0.0, 20.0], atol=1e-12)
    np.testing.assert_allclose(vehid.snr_db(1.0, np.array([[1.0, 0.1]])), [[0.0, 20.0]], atol=1e-12)


def test_row_noise_var_is_diag_of_rv_plus_b_ru_bt() -> None:
    for model, sigma_u in [(vehid.QuarterCar(), [0.1]), (vehid.HalfCar(), [0.1, 0.2])]:
        sigma_v = 0.005
        b = model.b
        full = sigma_v**2 * np.eye(model.n_states) + b @ np.diag(np.square(sigma_u)) @ b.T
        expected = np.diag(full)[list(model.unknown_rows)]
        got = model.row_noise_var(road_sigma=sigma_u, deriv_noise=sigma_v)
        assert got.shape == (len(model.unknown_rows),)
        np.testing.assert_allclose(got, expected, rtol=1e-14)


def test_quarter_physical_round_trip() -> None:
    consts = {"M": 12.5, "m": 1.3, "k1": 95.0, "k2": 47.0, "b": 38.0}
    car = vehid.QuarterCar(**consts)
    for known in ({"m": consts["m"]}, {"M": consts["M"]}):
        back = car.physical(car.theta, **known)
        assert set(back) == set(consts)
        for key, value in consts.items():
            assert back[key] == pytest.approx(value, rel=1e-10), (known, key)


def test_half_physical_round_trip() -> None:
    consts = dict(k11=110.0, k21=95.0, k12=42.0, k22=37.0, b1=61.0, b2=55.0, m1=1.1, m2=0.9, M=21.0, J=58.0,
                  l1=1.8, l2=1.2)
    half = vehid.HalfCar(**consts)
    back = half.physical(half.theta, m1=consts["m1"], m2=consts["m2"])
    assert set(back) == set(consts)
    for key, value in consts.items():
        assert back[key] == pytest.approx(value, rel=1e-10), key
    assert half.params == pytest.approx(consts, rel=1e-15)


def test_physical_accepts_lists_and_perturbed_rows() -> None:
    car = vehid.QuarterCar()
    back = car.physical(car.theta.tolist(), m=1.0)
    assert back["k1"] == pytest.approx(90.0, rel=1e-12)
    # A slightly wrong estimate still maps to constants near the truth.
    near = car.physical(car.theta * 1.01, m=1.0)
    assert near["k2"] == pytest.approx(50.0, rel=0.02)


def test_a_hat_replaces_unknown_rows() -> None:
    car = vehid.QuarterCar()
    np.testing.assert_array_equal(car.a_hat(car.theta), car.a)
    theta_hat = car.theta + 1.0
    a_hat = car.a_hat(theta_hat)
    np.testing.assert_array_equal(a_hat[[1, 3]], theta_hat)
    np.testing.assert_array_equal(a_hat[[0, 2]], car.a[[0, 2]])


def test_generic_linear_model_matches_quarter_car() -> None:
    car = vehid.QuarterCar()
    # Int-convertible, non-contiguous and 1-D inputs are accepted.
    a_fortran = np.asfortranarray(car.a)
    own = vehid.LinearModel(a_fortran, car.b[:, 0], unknown_rows=[3, 1])
    assert repr(own) == "LinearModel(n_states=4, n_inputs=1, unknown_rows=(1, 3))"
    assert own.unknown_rows == (1, 3)
    np.testing.assert_array_equal(own.a, car.a)
    np.testing.assert_array_equal(own.poles(), car.poles())
    np.testing.assert_array_equal(own.output_std(), car.output_std())
    strided = np.zeros((8, 8))
    strided[::2, ::2] = car.a
    also = vehid.LinearModel(strided[::2, ::2], car.b, [1, 3])
    np.testing.assert_array_equal(also.a, car.a)
    ints = vehid.LinearModel([[0, 1], [-4, -2]], [[0], [4]], [1])
    assert ints.a.dtype == np.float64
    assert ints.theta.tolist() == [[-4.0, -2.0]]


def test_structural_zeros_default_and_override() -> None:
    a = [[0.0, 1.0], [-4.0, 0.0]]
    model = vehid.LinearModel(a, [0.0, 1.0], [1])
    assert model.structural_zeros.tolist() == [[False, True]]
    model = vehid.LinearModel(a, [0.0, 1.0], [1], structural_zeros=[])
    assert model.structural_zeros.tolist() == [[False, False]]


def test_all_sizes_dispatch() -> None:
    for n in range(1, 17):
        for m in range(1, 5):
            a = -np.eye(n) * (1.0 + np.arange(n))
            b = np.ones((n, m))
            model = vehid.LinearModel(a, b, [n - 1])
            assert (model.n_states, model.n_inputs) == (n, m)
            np.testing.assert_allclose(sorted(model.poles().real), sorted(np.diag(a)), rtol=1e-12)
            assert model.output_std(0.1).shape == (n,)
            run = vehid.Simulator(model, seed=n * 10 + m).run(3)
            assert run.x.shape == (3, n) and run.u.shape == (3, m)


def test_sampled_std_rk4_converges_to_exact() -> None:
    car = vehid.HalfCar()
    exact = car.sampled_std(0.1, 0.05, method="exact")
    fine = car.sampled_std(0.1, 0.05, method="rk4", substeps=400)
    np.testing.assert_allclose(fine, exact, rtol=1e-8)
    cov = car.sampled_cov(0.1, 0.05, method="exact")
    assert cov.shape == (8, 8)
    np.testing.assert_allclose(cov, cov.T, atol=1e-15)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), exact, rtol=1e-15)


def test_xi_eq_3_17() -> None:
    half = vehid.HalfCar()
    theta = half.theta
    theta_hat = theta * 1.1 + half.structural_zeros * 5.0
    # Only the non-zero true entries count: each contributes (0.1)^2.
    expected = 0.01 * np.count_nonzero(theta)
    assert vehid.xi(theta, theta_hat) == pytest.approx(expected, rel=1e-12)
    assert vehid.xi(theta, theta) == 0.0
    assert vehid.xi(theta, np.full_like(theta, np.nan)) == float("inf")


def test_version_and_exports() -> None:
    assert isinstance(vehid.__version__, str) and vehid.__version__.count(".") == 2
    for name in vehid.__all__:
        assert hasattr(vehid, name), name
    assert issubclass(vehid.VehidError, ValueError)


def test_reprs_use_python_quoting_and_tuples() -> None:
    """Every repr quotes strings as Python does (single quotes) and shows row indices as a
    tuple, as ``LinearModel``'s and ``car.unknown_rows`` do."""
    car = vehid.QuarterCar()
    s = car.structure(known={"m": 1.0})
    t = vehid.Structure(["q", "v"], ["f"], {"v": "-k*q + g*f"}, known={"q": "v"})
    objs = [
        vehid.KalmanIdentifier(car), vehid.StochasticGradient(car), vehid.BatchLeastSquares(car),
        vehid.IVIdentifier(s), vehid.BiasCompensated(s, state_noise_var=1e-4), vehid.TwoAxleIdentifier(vehid.HalfCar()),
        vehid.Simulator(car), t, s, car,
    ]
    for obj in objs:
        assert '"' not in repr(obj), repr(obj)
    kf = "KalmanIdentifier(mode='rows', unknown_rows=(1, 3), samples=0, reinit_count=0)"
    assert repr(vehid.KalmanIdentifier(car)) == kf
    sg = repr(vehid.StochasticGradient(car, gain="ljung"))
    assert sg.startswith("StochasticGradient(gain='ljung', unknown_rows=(1, 3)"), sg
    assert repr(t) == "Structure(states=['q', 'v'], inputs=['f'], equations={'v': '-k*q + g*f'}, parameters=['k', 'g'])"
    assert tuple(car.unknown_rows) == (1, 3) and str(car.unknown_rows) in repr(vehid.BatchLeastSquares(car))

"""Type stub of the compiled extension ``vehid._vehid`` (hand-written; kept honest by
``python -m mypy.stubtest vehid._vehid``)."""

from typing import Any, Dict, Literal, Optional, Sequence, Tuple, Union, final, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray
from typing_extensions import Self, disjoint_base

__version__: str
#: What the classes use when a caller does not give ``road_sigma`` (m), ``deriv_noise`` and
#: ``gate`` (κ, standard deviations): the thesis' noise levels (Ch. III.C) and the outlier gate.
DEFAULT_ROAD_SIGMA: float
DEFAULT_DERIV_NOISE: float
DEFAULT_GATE: float
__all__ = [
    "VehidError",
    "__version__",
    "DEFAULT_ROAD_SIGMA",
    "DEFAULT_DERIV_NOISE",
    "DEFAULT_GATE",
    "LinearModel",
    "QuarterCar",
    "HalfCar",
    "FullCar",
    "Simulator",
    "Run",
    "Identifier",
    "KalmanIdentifier",
    "StochasticGradient",
    "BatchLeastSquares",
    "TwoAxleIdentifier",
    "IVIdentifier",
    "BiasCompensated",
    "JointEKF",
    "AxleSampler",
    "Structure",
    "Stats",
    "HealthMonitor",
    "Event",
    "RealisticIdentifier",
    "_physical_structure",
    "_full_car_from_constants",
    "validate",
    "xi",
    "ljung_box",
    "ccf",
    "recursive_residuals",
    "cusum",
    "snr_db",
    "reproduce_report",
]

_Floats = Union[float, ArrayLike]
_Method = Literal["rk4", "exact"]

class VehidError(ValueError):
    """A value passed to vehid is invalid, or a computation cannot be done on it."""

@disjoint_base
class LinearModel:
    """A continuous-time linear model ``ẋ = A x + B u`` (Eq 2.1), 1..16 states, 1..4 inputs."""

    def __new__(
        cls,
        a: ArrayLike,
        b: ArrayLike,
        unknown_rows: Sequence[int],
        structural_zeros: Optional[Sequence[Tuple[int, int]]] = None,
    ) -> LinearModel: ...
    @property
    def n_states(self) -> int: ...
    @property
    def n_inputs(self) -> int: ...
    @property
    def a(self) -> NDArray[np.float64]: ...
    @property
    def b(self) -> NDArray[np.float64]: ...
    @property
    def unknown_rows(self) -> Tuple[int, ...]: ...
    @property
    def theta(self) -> NDArray[np.float64]: ...
    @property
    def structural_zeros(self) -> NDArray[np.bool_]: ...
    def poles(self) -> NDArray[np.complex128]: ...
    def output_std(self, road_sigma: _Floats = 1.0, hold: float = 0.05) -> NDArray[np.float64]: ...
    def row_noise_var(
        self, road_sigma: _Floats = 0.1, deriv_noise: _Floats = 0.005
    ) -> NDArray[np.float64]: ...
    def sampled_cov(
        self,
        road_sigma: _Floats = 0.1,
        dt: float = 0.05,
        method: _Method = "rk4",
        substeps: Optional[int] = None,
    ) -> NDArray[np.float64]: ...
    def sampled_std(
        self,
        road_sigma: _Floats = 0.1,
        dt: float = 0.05,
        method: _Method = "rk4",
        substeps: Optional[int] = None,
    ) -> NDArray[np.float64]: ...
    def a_hat(self, theta_hat: ArrayLike) -> NDArray[np.float64]: ...
    def __reduce__(self) -> Tuple[Any, ...]: ...
    def __eq__(self, value: object, /) -> bool: ...
    def __ne__(self, value: object, /) -> bool: ...
    def __hash__(self) -> int: ...
    @overload
    def physical(self, theta_hat: Stats, **known: float) -> dict[str, Tuple[float, float, float]]: ...
    @overload
    def physical(self, theta_hat: ArrayLike, **known: float) -> dict[str, float]: ...
    def structure(
        self, known: Optional[Dict[str, float]] = None, sensors: Literal["state", "realistic"] = "state"
    ) -> Structure: ...

@final
class QuarterCar(LinearModel):
    """The quarter car of Eq 3.8–3.13 (defaults: the thesis' values)."""

    def __new__(
        cls, M: float = 10.0, m: float = 1.0, k1: float = 90.0, k2: float = 50.0, b: float = 40.0
    ) -> QuarterCar: ...
    @classmethod
    def passenger(cls) -> Self: ...
    @property
    def params(self) -> dict[str, float]: ...

@final
class HalfCar(LinearModel):
    """The half car of Eq 6.1–6.8 (defaults: the thesis' values)."""

    def __new__(
        cls,
        k11: float = 100.0,
        k21: float = 100.0,
        k12: float = 40.0,
        k22: float = 40.0,
        b1: float = 60.0,
        b2: float = 60.0,
        m1: float = 1.0,
        m2: float = 1.0,
        M: float = 20.0,
        J: float = 60.0,
        l1: float = 2.0,
        l2: float = 1.0,
    ) -> HalfCar: ...
    @classmethod
    def passenger(cls) -> Self: ...
    @property
    def params(self) -> dict[str, float]: ...
    @property
    def wheelbase(self) -> float: ...

@final
class FullCar(LinearModel):
    """The full car: heave, pitch and roll of the body on four corners (14 states)."""

    CONSTANTS: list[str]
    def __new__(cls, **constants: float) -> FullCar: ...
    @classmethod
    def passenger(cls) -> Self: ...
    @property
    def params(self) -> dict[str, float]: ...
    @property
    def wheelbase(self) -> float: ...

@final
class Run:
    """One stretch of a simulation; arrays have the sample index first."""

    @property
    def t(self) -> NDArray[np.float64]: ...
    @property
    def x(self) -> NDArray[np.float64]: ...
    @property
    def xdot(self) -> NDArray[np.float64]: ...
    @property
    def u(self) -> NDArray[np.float64]: ...
    @property
    def r(self) -> NDArray[np.float64]: ...
    @property
    def z(self) -> NDArray[np.float64]: ...
    @property
    def n_states(self) -> int: ...
    @property
    def n_inputs(self) -> int: ...
    @property
    def s(self) -> Optional[NDArray[np.float64]]: ...
    @property
    def y(self) -> NDArray[np.float64]: ...
    @property
    def channels(self) -> Tuple[str, ...]: ...
    @property
    def constants(self) -> Optional[NDArray[np.float64]]: ...
    def __len__(self) -> int: ...

_Road = Literal[
    "white", "independent", "flat", "iso8608-A", "iso8608-B", "iso8608-C", "iso8608-D", "iso8608-E"
]
_Sensors = Literal["realistic", "state"]
_Change = Union[Tuple[float, Dict[str, float]], Tuple[float, Dict[str, float], float]]

@final
class Simulator:
    """A seeded simulator of ``ẋ = A x + B u`` with the thesis' noise sources."""

    def __new__(
        cls,
        model: LinearModel,
        dt: float = 0.05,
        road_sigma: _Floats = 0.1,
        ic_sigma: float = 0.0,
        state_noise: _Floats = 0.0,
        deriv_noise: _Floats = 0.005,
        seed: int = 1,
        substeps: Optional[int] = None,
        method: _Method = "rk4",
        pulses: Optional[Sequence[Tuple[int, int, float]]] = None,
        instrumentation: bool = False,
        speed: Optional[_Floats] = None,
        spacing: Optional[float] = None,
        road: Optional[_Road] = None,
        changes: Optional[Sequence[_Change]] = None,
        sensors: Optional[_Sensors] = None,
        sensor_noise: Optional[Dict[str, float]] = None,
    ) -> Simulator: ...
    def run(self, n: int) -> Run: ...
    @property
    def substeps(self) -> int: ...
    @property
    def dt(self) -> float: ...
    @property
    def spacing(self) -> Optional[float]: ...
    @property
    def road(self) -> Optional[_Road]: ...
    @property
    def channels(self) -> Optional[Tuple[str, ...]]: ...
    @property
    def sensors(self) -> Optional[_Sensors]: ...
    @property
    def seed(self) -> int: ...
    @property
    def method(self) -> _Method: ...
    @property
    def model(self) -> LinearModel: ...
    @property
    def samples(self) -> int: ...
    @property
    def n_states(self) -> int: ...
    @property
    def n_inputs(self) -> int: ...

_Mode = Literal["rows", "shared", "full"]
_Form = Literal["standard", "joseph", "sqrt"]
_Gain = Literal["venter", "lyapunov", "ljung"]

@disjoint_base
class Identifier:
    """The base class of every identifier: samples in, estimates out (not constructed directly)."""

    def update(self, r_k: ArrayLike, z_k: ArrayLike, u_k: Optional[ArrayLike] = None) -> NDArray[np.float64]: ...
    def fit(
        self, r: ArrayLike, z: ArrayLike, u: Optional[ArrayLike] = None, record_every: int = 0
    ) -> NDArray[np.float64]: ...
    @property
    def theta(self) -> NDArray[np.float64]: ...
    @property
    def params(self) -> NDArray[np.float64]: ...
    @property
    def a_hat(self) -> NDArray[np.float64]: ...
    @property
    def samples(self) -> int: ...
    @property
    def unknown_rows(self) -> list[int]: ...
    @property
    def gated(self) -> NDArray[np.uint64]: ...
    @property
    def structure(self) -> Optional[Structure]: ...
    def residuals(self, r: ArrayLike, z: ArrayLike, u: Optional[ArrayLike] = None) -> NDArray[np.float64]: ...
    def regressors(
        self, r: ArrayLike, z: ArrayLike, u: Optional[ArrayLike] = None, equation: int = 0
    ) -> Tuple[NDArray[np.float64], NDArray[np.float64]]: ...
    def stats(self, alpha: float = 0.05) -> Stats: ...
    def __getnewargs_ex__(self) -> Tuple[Tuple[Any, ...], Dict[str, Any]]: ...
    def __reduce__(self) -> Tuple[Any, ...]: ...
    def __setstate__(self, state: Tuple[int, str, bytes]) -> None: ...
    def __copy__(self) -> Self: ...
    def __deepcopy__(self, memo: Any) -> Self: ...

@final
class KalmanIdentifier(Identifier):
    """The Kalman-filter identifier (Eq 4.3–4.7): recursive weighted least squares."""

    def __new__(
        cls,
        model: Union[LinearModel, Structure],
        p0: Optional[Union[str, _Floats]] = None,
        r: Optional[_Floats] = None,
        *,
        theta0: Optional[ArrayLike] = None,
        road_sigma: Optional[_Floats] = None,
        deriv_noise: Optional[_Floats] = None,
        reinit: bool = False,
        mode: str = "rows",
        form: Optional[str] = None,
        joseph: bool = False,
        retire_below: float = 0.0,
        forgetting: float = 1.0,
        drift: float = 0.0,
        directional: bool = False,
        max_trace: Optional[float] = None,
        gate: Optional[float] = None,
        huber: float = 0.0,
    ) -> KalmanIdentifier: ...
    @property
    def form(self) -> _Form: ...
    @property
    def covariance(self) -> NDArray[np.float64]: ...
    @property
    def r(self) -> NDArray[np.float64]: ...
    @property
    def trace(self) -> float: ...
    @property
    def reinit_count(self) -> int: ...
    def reset_covariance(self, p0: float) -> None: ...
    @property
    def mode(self) -> _Mode: ...

@final
class StochasticGradient(Identifier):
    """The stochastic-gradient identifier (Eq 2.56, 5.2–5.18)."""

    def __new__(
        cls,
        model: Union[LinearModel, Structure],
        gain: str = "venter",
        h: Optional[_Floats] = None,
        p: float = 0.51,
        *,
        spacing: int = 1,
        state_noise_var: Optional[_Floats] = None,
        lambda0: float = 0.99,
        lambda_init: float = 0.95,
        gate: Optional[float] = None,
    ) -> StochasticGradient: ...
    @property
    def gain(self) -> _Gain: ...

@final
class BatchLeastSquares(Identifier):
    """Batch least squares (Eq 2.14) by column-pivoted QR over stored samples, or
    memory-bounded (``keep_samples=False``: recursive, nothing stored)."""

    def __new__(
        cls, model: Union[LinearModel, Structure], keep_samples: bool = True, *, gate: Optional[float] = None
    ) -> BatchLeastSquares: ...
    @property
    def keep_samples(self) -> bool: ...
    @property
    def storage_bytes(self) -> int: ...
    def clear(self) -> None: ...
    def remove(self, index: int) -> None: ...

@final
class IVIdentifier(Identifier):
    """Recursive instrumental variables: consistent with white noise on the measured state."""

    def __new__(
        cls,
        model: Union[LinearModel, Structure],
        delay: int = 1,
        lags: Optional[int] = None,
        p0: Optional[Union[str, _Floats]] = None,
        r: Optional[_Floats] = None,
        *,
        theta0: Optional[ArrayLike] = None,
        instruments: Literal["delayed", "model"] = "delayed",
        dt: Optional[float] = None,
        refresh: int = 100,
        substeps: int = 1,
        road: Literal["white", "random-walk", "iso8608"] = "white",
        road_cutoff: Optional[float] = None,
        spacing: Optional[Union[float, Literal["odometer"]]] = None,
        min_spacing: Optional[float] = None,
        lift_off: Optional[Tuple[float, float]] = None,
        gate: Optional[float] = None,
    ) -> IVIdentifier: ...
    @property
    def road(self) -> Literal["white", "random-walk", "iso8608"]: ...
    @property
    def road_cutoff(self) -> Optional[float]: ...
    @property
    def spacing(self) -> Optional[Union[float, Literal["odometer"]]]: ...
    @property
    def min_spacing(self) -> Optional[float]: ...
    @property
    def lift_off(self) -> Optional[Tuple[float, float]]: ...
    @property
    def lifted(self) -> int: ...
    @property
    def delay(self) -> int: ...
    @property
    def lags(self) -> int: ...
    @property
    def instruments(self) -> str: ...
    @property
    def dt(self) -> Optional[float]: ...
    @property
    def refresh(self) -> int: ...
    @property
    def substeps(self) -> int: ...

@final
class BiasCompensated(Identifier):
    """Bias-compensated least squares (XᵀX − N Σ_w)⁻¹ Xᵀz, Σ_w given or estimated from the data."""

    def __new__(
        cls,
        model: Union[LinearModel, Structure],
        state_noise_var: Union[_Floats, Literal["estimate"]],
        deriv_noise_var: Optional[_Floats] = None,
        r: Optional[_Floats] = None,
        *,
        delay: Optional[int] = None,
        lags: Optional[int] = None,
        gate: Optional[float] = None,
    ) -> BiasCompensated: ...
    @property
    def estimates_noise(self) -> bool: ...
    @property
    def instruments(self) -> Optional[Tuple[int, int]]: ...
    def state_noise_var_estimate(self) -> NDArray[np.float64]: ...

@final
class JointEKF(Identifier):
    """Joint state, parameter and road estimation: an extended Kalman filter (the thesis' Ch. VII)."""

    def __new__(
        cls,
        model: Union[LinearModel, Structure],
        theta0: ArrayLike,
        p0: Optional[_Floats] = None,
        *,
        state_noise: _Floats,
        deriv_noise: Optional[_Floats] = None,
        road_sigma: float = 0.1,
        road_gain: Optional[ArrayLike] = None,
        dt: float = 0.05,
        substeps: Optional[int] = None,
        x0_var: float = 1.0,
        drift: float = 0.0,
    ) -> JointEKF: ...
    @property
    def state(self) -> NDArray[np.float64]: ...
    @property
    def state_covariance(self) -> NDArray[np.float64]: ...
    @property
    def dt(self) -> float: ...
    @property
    def substeps(self) -> int: ...
    @property
    def road_gain(self) -> NDArray[np.float64]: ...

def ljung_box(x: ArrayLike, lags: int = 10) -> Tuple[float, float]: ...
def ccf(x: ArrayLike, y: ArrayLike, nlags: Optional[int] = None) -> NDArray[np.float64]: ...
def recursive_residuals(h: ArrayLike, y: ArrayLike) -> NDArray[np.float64]: ...
def cusum(w: ArrayLike, alpha: float = 0.05) -> dict[str, Any]: ...
def xi(theta: ArrayLike, theta_hat: ArrayLike) -> float: ...
@overload
def snr_db(signal_std: float, noise_std: float) -> float: ...
@overload
def snr_db(signal_std: ArrayLike, noise_std: ArrayLike) -> Union[float, NDArray[np.float64]]: ...

_WheelMethod = Literal["none", "thesis", "cancel"]
_Trigger = Tuple[int, int, float, Optional[Tuple[int, int, float]]]

@final
class TwoAxleIdentifier(Identifier):
    """Half or full car on one road (Ch. VI.D): plain rows, Eq 6.14, road cancellation (half car: also a Structure)."""

    def __new__(
        cls,
        model: Union[LinearModel, Structure],
        spacing: float = 0.3,
        method: str = "cancel",
        p0: Optional[Union[float, Literal["exact"]]] = None,
        road_sigma: float = 0.1,
        deriv_noise: float = 0.005,
        *,
        p0_body: Optional[float] = None,
        wheelbase: Optional[float] = None,
        direct_front: bool = True,
        car: Optional[LinearModel] = None,
        compensate: bool = True,
        gate: Optional[float] = None,
    ) -> TwoAxleIdentifier: ...
    @property
    def method(self) -> _WheelMethod: ...
    @property
    def delay(self) -> int: ...
    @property
    def spacing(self) -> float: ...
    @property
    def wheelbase(self) -> float: ...
    @property
    def wheel_variances(self) -> Tuple[float, float, float]: ...
    @property
    def paired(self) -> int: ...
    @property
    def model(self) -> LinearModel: ...
    @property
    def compensate(self) -> bool: ...

@final
class AxleSampler:
    """Distance-triggered sampling that pairs rear- and front-axle samples."""

    def __new__(
        cls, wheelbase: float = 3.0, spacing: float = 0.3, tolerance: Optional[float] = None
    ) -> AxleSampler: ...
    def feed(self, s: float) -> Optional[_Trigger]: ...
    def advance(self, speed: float, dt: float) -> Optional[_Trigger]: ...
    def time_to_next(self, speed: float) -> Optional[float]: ...
    @property
    def distance_to_next(self) -> float: ...
    def reset(self, s: float) -> None: ...
    @property
    def delay(self) -> int: ...
    @property
    def spacing(self) -> float: ...
    @property
    def wheelbase(self) -> float: ...
    @property
    def tolerance(self) -> float: ...
    @property
    def position(self) -> float: ...
    @property
    def samples(self) -> int: ...

def reproduce_report(
    quick: bool = False,
    only: Optional[Sequence[str]] = None,
    seed: int = 1986,
    seeds: Optional[int] = None,
    max_iterations: Optional[int] = None,
    threads: Optional[int] = None,
    tables: bool = True,
    progress: bool = False,
) -> Dict[str, Any]: ...

@final
class Structure:
    """A model linear in its parameters: states, measured inputs, equations as text."""

    def __new__(
        cls,
        states: Sequence[str],
        inputs: Optional[Sequence[str]] = None,
        equations: Optional[Dict[str, str]] = None,
        known: Optional[Dict[str, str]] = None,
        parameters: Optional[Sequence[str]] = None,
    ) -> Structure: ...
    @property
    def not_identifiable(self) -> dict[str, str]: ...
    @property
    def parameters(self) -> Tuple[str, ...]: ...
    @property
    def states(self) -> Tuple[str, ...]: ...
    @property
    def inputs(self) -> Tuple[str, ...]: ...
    @property
    def identified(self) -> Tuple[str, ...]: ...
    @property
    def n_params(self) -> int: ...
    @property
    def n_states(self) -> int: ...
    @property
    def n_inputs(self) -> int: ...
    @property
    def groups(self) -> Tuple[Tuple[str, ...], ...]: ...
    def derivative(self, params: ArrayLike, x: ArrayLike, u: Optional[ArrayLike] = None) -> list[float]: ...
    def simulate(
        self,
        params: ArrayLike,
        x0: ArrayLike,
        u: Optional[ArrayLike] = None,
        *,
        dt: float,
        samples: Optional[int] = None,
        substeps: int = 10,
    ) -> NDArray[np.float64]: ...
    def __eq__(self, value: object, /) -> bool: ...
    def __reduce__(self) -> Tuple[Any, ...]: ...

@final
class Stats:
    """An estimate and its uncertainty, as statsmodels names them."""

    @property
    def names(self) -> Tuple[str, ...]: ...
    @property
    def params(self) -> NDArray[np.float64]: ...
    @property
    def bse(self) -> NDArray[np.float64]: ...
    @property
    def conf_int(self) -> NDArray[np.float64]: ...
    @property
    def cov(self) -> NDArray[np.float64]: ...
    @property
    def sigma2(self) -> NDArray[np.float64]: ...
    @property
    def nobs(self) -> NDArray[np.float64]: ...
    @property
    def df(self) -> NDArray[np.float64]: ...
    @property
    def alpha(self) -> float: ...
    @property
    def structure(self) -> Optional[Structure]: ...

@final
class RealisticIdentifier:
    """The body equation from a body accelerometer and a deflection sensor (a state-variable filter);
    given a FullCar, its four body-corner equations from the twelve realistic channels."""

    def __new__(cls, structure: Union[Structure, FullCar], dt: float, bandwidth: Optional[float] = None,
                block: float = ...) -> Self: ...
    def update(self, y_k: ArrayLike) -> None: ...
    def fit(self, y: ArrayLike) -> Self: ...
    def restart(self) -> None: ...
    def stats(self, alpha: float = 0.05) -> Stats: ...
    @property
    def structure(self) -> Structure: ...
    @property
    def car(self) -> Optional[FullCar]: ...
    @property
    def samples(self) -> int: ...
    @property
    def dt(self) -> float: ...
    @property
    def bandwidth(self) -> float: ...
    @property
    def block(self) -> float: ...
    @property
    def settling(self) -> int: ...
    def __reduce__(self) -> Tuple[Any, ...]: ...
    def __setstate__(self, state: Tuple[int, str, bytes]) -> None: ...
    def __copy__(self) -> Self: ...
    def __deepcopy__(self, memo: Any) -> Self: ...

def _physical_structure(car: str, known: Any, sensors: str = "state") -> Structure: ...
def _full_car_from_constants(constants: Sequence[float]) -> FullCar: ...
def validate(
    structure: Structure,
    params: ArrayLike,
    x: ArrayLike,
    u: Optional[ArrayLike] = None,
    *,
    dt: float,
    substeps: int = 10,
) -> Dict[str, NDArray[np.float64]]: ...

_Parameter = Literal[
    "M", "k2", "b",  # quarter car
    "k2_f", "b_f", "k2_r", "b_r",  # half car
    "k_fl", "k_fr", "k_rl", "k_rr", "b_fl", "b_fr", "b_rl", "b_rr", "arb_f", "arb_r",  # full car
]

@final
class Event:
    """A detected change of one physical constant (reported by ``HealthMonitor``)."""

    def __new__(
        cls, t: float, t_change: float, parameter: _Parameter, before: float, after: float, low: float,
        high: float, change: float, position: Optional[Tuple[float, float]] = None,
    ) -> Event: ...
    def __reduce__(self) -> Tuple[Any, ...]: ...
    @property
    def t(self) -> float: ...
    @property
    def t_change(self) -> float: ...
    @property
    def parameter(self) -> _Parameter: ...
    @property
    def before(self) -> float: ...
    @property
    def after(self) -> float: ...
    @property
    def low(self) -> float: ...
    @property
    def high(self) -> float: ...
    @property
    def change(self) -> float: ...
    @property
    def position(self) -> Optional[Tuple[float, float]]: ...
    def to_dict(self) -> Dict[str, Union[float, str]]: ...
    def __eq__(self, value: object, /) -> bool: ...

@final
class HealthMonitor:
    """The suspension health monitor of a quarter, half or full car: which constant changed, when, to what."""

    def __new__(
        cls,
        car: Union[QuarterCar, HalfCar, FullCar],
        dt: float = 0.005,
        sensors: _Sensors = "realistic",
        sensor_noise: Optional[Dict[str, float]] = None,
        *,
        window: Optional[float] = None,
        warmup: Optional[float] = None,
        settle: Optional[float] = None,
        reacquire: Optional[float] = None,
        min_change: Optional[float] = None,
        judge_error: Optional[float] = None,
        threshold: Optional[float] = None,
        confidence: Optional[float] = None,
        systematic: Optional[float] = None,
        stuck_samples: Optional[int] = None,
    ) -> HealthMonitor: ...
    def update(self, y_k: ArrayLike) -> list[Event]: ...
    def fit(self, y: ArrayLike) -> list[Event]: ...
    @property
    def status(self) -> str: ...
    @property
    def samples(self) -> int: ...
    @property
    def events(self) -> int: ...
    @property
    def constants(self) -> dict[str, float]: ...
    @property
    def estimate(self) -> dict[str, Any]: ...
    @property
    def reference(self) -> Optional[dict[str, Any]]: ...
    @property
    def dt(self) -> float: ...
    @property
    def sensors(self) -> _Sensors: ...
    @property
    def channels(self) -> Tuple[str, ...]: ...
    def __reduce__(self) -> Tuple[Any, ...]: ...
    def __setstate__(self, state: Any) -> None: ...
    def __copy__(self) -> HealthMonitor: ...
    def __deepcopy__(self, memo: Any) -> HealthMonitor: ...

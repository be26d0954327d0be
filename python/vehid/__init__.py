"""vehid: online identification of land-vehicle suspension dynamics.

After J. H. Kessler, *Adaptive Modeling of the Dynamics of Autonomous Land Vehicles*
(NPS, 1986). The numerics live in the Rust crate ``vehid-core``; this package is its
Python face.

>>> import vehid
>>> car = vehid.QuarterCar()
>>> car.n_states, car.n_inputs, car.unknown_rows
(4, 1, (1, 3))
>>> run = vehid.Simulator(car, seed=1).run(1000)
>>> run.x.shape
(1000, 4)
"""

from . import reproduce
from ._vehid import (
    AxleSampler,
    BatchLeastSquares,
    BiasCompensated,
    Event,
    FullCar,
    HalfCar,
    HealthMonitor,
    Identifier,
    IVIdentifier,
    JointEKF,
    KalmanIdentifier,
    LinearModel,
    QuarterCar,
    RealisticIdentifier,
    Run,
    Simulator,
    Stats,
    StochasticGradient,
    Structure,
    TwoAxleIdentifier,
    VehidError,
    __version__,
    ccf,
    cusum,
    ljung_box,
    recursive_residuals,
    snr_db,
    validate,
    xi,
)
from .diagnostics import diagnostics

__all__ = [
    "AxleSampler",
    "BatchLeastSquares",
    "BiasCompensated",
    "Event",
    "FullCar",
    "HalfCar",
    "HealthMonitor",
    "IVIdentifier",
    "Identifier",
    "JointEKF",
    "KalmanIdentifier",
    "LinearModel",
    "QuarterCar",
    "RealisticIdentifier",
    "Run",
    "Simulator",
    "Stats",
    "StochasticGradient",
    "Structure",
    "TwoAxleIdentifier",
    "VehidError",
    "__version__",
    "ccf",
    "cusum",
    "diagnostics",
    "ljung_box",
    "recursive_residuals",
    "reproduce",
    "snr_db",
    "validate",
    "xi",
]

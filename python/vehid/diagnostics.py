"""Residual diagnostics of an identified model, named as statsmodels names them.

``diagnostics(ident, r, z, u)`` checks each identified equation at the identifier's estimate:

- ``ljung_box``: the whiteness of its residuals (``vehid.ljung_box``; statsmodels
  ``acorr_ljungbox``);
- ``ccf``: the cross-correlation of its residuals with each regressor at lags ``0..lags``
  (``vehid.ccf``; statsmodels ``ccf``), against the band ``±2/√n`` of independent series
  (least squares makes lag 0 zero by construction: the later lags are the test);
- ``cusum``: the CUSUM and CUSUM-of-squares tests of its recursive residuals
  (``vehid.recursive_residuals``, ``vehid.cusum``; statsmodels ``RecursiveLSResults``): a
  parameter that changed during the record, or an input the model leaves out.

Every number comes from the compiled core; this module only selects and names.

>>> import vehid
>>> car = vehid.QuarterCar.passenger()
>>> run = vehid.Simulator(car, dt=0.005, road="iso8608-C", speed=15.0, sensors="state", seed=3).run(20_000)
>>> ident = vehid.KalmanIdentifier(car.structure(known={"m": 40.0}))
>>> _ = ident.fit(run.x, run.xdot)
>>> wheel = diagnostics(ident, run.x, run.xdot)[1]      # the wheel equation: biased by the road
>>> wheel["ljung_box"]["pvalue"] < 1e-6, wheel["cusum"]["first_cusum_crossing"] is not None
(True, True)
"""

from __future__ import annotations

import math
from typing import Any, Dict, List, Optional

import numpy as np
from numpy.typing import ArrayLike

from ._vehid import Identifier, VehidError, ccf, cusum, ljung_box, recursive_residuals


def diagnostics(ident: Identifier, r: ArrayLike, z: ArrayLike, u: Optional[ArrayLike] = None, lags: int = 10,
                alpha: float = 0.05) -> List[Dict[str, Any]]:
    """One dict per identified equation (in the order of ``ident.unknown_rows`` or its
    structure's equations): ``equation`` (index), ``ljung_box`` (``stat``, ``pvalue``, ``lags``),
    ``ccf`` ({parameter: cross-correlations at lags 0..lags}), ``ccf_bound`` (``2/√n``),
    ``cusum`` (the dict of ``vehid.cusum``, or None when the recursive residuals do not exist:
    the first samples do not determine the equation) and ``white`` (Ljung-Box p >= alpha).
    A test that cannot be computed (a residual without variance) is None."""
    res = np.asarray(ident.residuals(r, z, u))
    structure = ident.structure
    names = list(structure.parameters) if structure is not None else None
    out: List[Dict[str, Any]] = []
    n = res.shape[0]
    for i in range(res.shape[1]):
        h, y = ident.regressors(r, z, u, equation=i)
        used = [j for j in range(h.shape[1]) if np.any(h[:, j] != 0)]  # this equation's parameters
        e = res[:, i]
        try:
            stat, p = ljung_box(e, lags=lags)
            lb: Optional[Dict[str, float]] = {"stat": stat, "pvalue": p, "lags": lags}
        except VehidError:
            lb = None
        cross: Dict[str, Any] = {}
        for j in used:
            name = names[j] if names is not None else f"theta[{j}]"
            try:
                cross[name] = ccf(e, h[:, j], nlags=lags + 1)
            except VehidError:
                cross[name] = None
        try:
            cs: Optional[Dict[str, Any]] = cusum(recursive_residuals(h[:, used], y), alpha=alpha)
        except VehidError:
            cs = None
        out.append({
            "equation": i,
            "ljung_box": lb,
            "white": None if lb is None else bool(lb["pvalue"] >= alpha),
            "ccf": cross,
            "ccf_bound": 2.0 / math.sqrt(n),
            "cusum": cs,
        })
    return out


__all__ = ["diagnostics"]

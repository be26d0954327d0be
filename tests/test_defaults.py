"""The defaults a caller gets without saying are defined once (``vehid_runtime::defaults``,
exported as ``vehid._vehid.DEFAULT_*``): every signature that shows one shows that value, the
command line passes it, and an identifier built without the argument is the one built with it."""

from __future__ import annotations

import inspect
from typing import Any, Dict, List, Tuple

import numpy as np
import pytest

import vehid
from vehid import _vehid
from vehid.cli import build_parser

DEFAULTS = {
    "road_sigma": _vehid.DEFAULT_ROAD_SIGMA,
    "deriv_noise": _vehid.DEFAULT_DERIV_NOISE,
    "gate": _vehid.DEFAULT_GATE,
}


def test_the_defaults_are_the_thesis_noise_levels_and_the_gate() -> None:
    # The thesis' simulation study (Ch. III.C): road σ_u = 0.1 m, derivative noise 0.005; the gate κ = 6.
    assert DEFAULTS == {"road_sigma": 0.1, "deriv_noise": 0.005, "gate": 6.0}


def _signatures() -> List[Tuple[str, inspect.Signature]]:
    out = []
    for name, obj in vars(_vehid).items():
        for qual, f in [(name, obj)] + [(f"{name}.{m}", getattr(obj, m)) for m in dir(obj) if inspect.isclass(obj)
                                          and not m.startswith("__") and callable(getattr(obj, m, None))]:
            try:
                out.append((qual, inspect.signature(f)))
            except (TypeError, ValueError):
                continue
    return out


def test_every_documented_default_is_the_one_used() -> None:
    seen: Dict[str, int] = {k: 0 for k in DEFAULTS}
    for qual, sig in _signatures():
        for p in sig.parameters.values():
            if p.name in DEFAULTS and p.default not in (inspect.Parameter.empty, None):
                # road_sigma=1.0 of output_std is the unit-intensity convention of Eq 4.27, not the default noise.
                if qual.endswith("output_std"):
                    continue
                assert p.default == DEFAULTS[p.name], f"{qual}({p.name}={p.default!r})"
                seen[p.name] += 1
    # The check reads real signatures: TwoAxleIdentifier, JointEKF, Simulator and the model methods show them.
    assert seen["road_sigma"] >= 4 and seen["deriv_noise"] >= 2, seen


@pytest.mark.parametrize("command", ["simulate", "identify"])
def test_the_command_line_passes_the_same_defaults(command: str) -> None:
    sub = build_parser()._subparsers._group_actions[0].choices[command]  # type: ignore[union-attr]
    options: Dict[str, Any] = {a.dest: a.default for a in sub._actions}
    for name in ("road_sigma", "deriv_noise"):
        assert options[name] == DEFAULTS[name], (command, name)
        help_text = next(a.help for a in sub._actions if a.dest == name)
        assert f"(default {DEFAULTS[name]:g})" in str(help_text)


def test_an_identifier_without_the_arguments_is_the_one_with_the_defaults() -> None:
    car = vehid.HalfCar()
    run = vehid.Simulator(car, speed=6.0, spacing=0.3, seed=5).run(4000)
    ids = [
        vehid.TwoAxleIdentifier(car, p0=1000.0),
        vehid.TwoAxleIdentifier(car, p0=1000.0, road_sigma=DEFAULTS["road_sigma"],
                                deriv_noise=DEFAULTS["deriv_noise"], gate=DEFAULTS["gate"]),
        vehid.TwoAxleIdentifier(car, p0=1000.0, road_sigma=2 * DEFAULTS["road_sigma"]),
    ]
    for ident in ids:
        ident.fit(run.r, run.z)
    assert np.array_equal(ids[0].theta, ids[1].theta)
    # A different road_sigma is a different identifier (the comparison above can fail).
    assert not np.array_equal(ids[0].theta, ids[2].theta)


def test_the_kalman_identifiers_r_default_is_one_from_the_exact_start_and_none_with_a_prior() -> None:
    car = vehid.QuarterCar()
    run = vehid.Simulator(car, seed=3).run(2000)
    exact, unit = vehid.KalmanIdentifier(car), vehid.KalmanIdentifier(car, r=1.0)
    exact.fit(run.x, run.xdot)
    unit.fit(run.x, run.xdot)
    assert np.array_equal(exact.theta, unit.theta) and np.array_equal(exact.covariance, unit.covariance)
    # With a prior the estimate weighs it against the data by r: no default, an error naming the ways to give it.
    with pytest.raises(ValueError, match="`r=`.*`road_sigma=`"):
        vehid.KalmanIdentifier(car, p0=100.0)

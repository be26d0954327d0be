"""A seeded fuzzer of vehid's whole public Python API: models and their methods,
``Simulator``, every identifier (``KalmanIdentifier`` with all its options,
``StochasticGradient``, ``BatchLeastSquares``, ``TwoAxleIdentifier``, and, in
``tests/fuzz_surfaces.py``, ``IVIdentifier``, ``BiasCompensated``, ``JointEKF``, structures
from a grammar-aware generator of equation texts, the ``HealthMonitor`` and the command
line), ``AxleSampler``, ``xi`` and ``snr_db``, called with random shapes, dtypes, NaN/inf,
huge and subnormal values, ``None``, strings, bytes, non-contiguous, Fortran-ordered and
read-only arrays.

Two properties are checked on every call:

- only ``VehidError`` / ``ValueError`` / ``TypeError`` / ``OverflowError`` / ``MemoryError``
  may be raised, never pyo3's ``PanicException`` (a ``BaseException``) or anything else;
- a rejected ``update`` / ``fit`` / ``remove`` / ``clear`` leaves the identifier bit for bit
  as it was (:func:`observable`: θ̂ or the error reading it, the sample count, P, R, tr P, the
  gated and reinitialization counts, the stored bytes, the paired samples), and a rejected
  ``Simulator.run`` leaves the simulator where it was (its next samples are the same).

It is a module, not a test file (pytest does not collect it): ``tests/test_fuzz_identify.py``
runs a few thousand calls in ``make test``; ``make fuzz`` runs it as a script::

    python tests/fuzz_harness.py [--calls 100000] [--seed 1] [--episode K]

(``FUZZ_CALLS`` and ``FUZZ_SEED`` set the defaults). Each episode (one object built, then
exercised) draws from its own generator, seeded by ``(seed, episode)``, so that a failure
reproduces alone with ``--seed S --episode K``. Exit status 1 on a failure.
"""

from __future__ import annotations

import argparse
import copy
import os
import pickle
import sys
import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np
from fuzz_common import ALLOWED, OBSERVED, Failure, attempt, describe, describe_kw, describe_one, observable, summary  # noqa: F401
from fuzz_surfaces import SurfaceEpisodes

import vehid

CAR = vehid.QuarterCar()
HALF = vehid.HalfCar()
ONE = vehid.LinearModel([[-1.0]], [[1.0]], [0])
THREE = vehid.LinearModel(
    [[0.0, 1.0, 0.0], [-2.0, -3.0, 1.0], [1.0, 0.0, -4.0]], [[0.0], [1.0], [0.5]], [1, 2]
)
SIXTEEN = vehid.LinearModel(-np.eye(16) + np.diag(np.ones(15), 1), np.ones((16, 2)), [0, 5, 15])
MODELS = [CAR, HALF, ONE, THREE, SIXTEEN]

SCALARS: List[Any] = [
    None, 0, 1, -1, 3, 2**31, 2**63, 2**70, -(2**70), 0.0, -0.0, 1.0, -1.0, 0.5, 1e-320, 5e-324, 1e308,
    -1e308, np.inf, -np.inf, np.nan, 1j, True, False, "", "rows", "full", "shared", "venter", "sqrt",
    "joseph", "exact", "ljung", "lyapunov", "nonsense", "\x00", b"rows", [], [[]], {}, (), object(), slice(1),
    np.float32(2.0), np.int8(-3), np.uint64(2**64 - 1), np.complex64(1 + 2j), [1.0, "a"], [[1.0, 2.0], [3.0]],
    np.float64(np.nan), np.float64(1e-310),
]
DTYPES = [np.float64, np.float32, np.float16, np.int64, np.int8, np.uint8, np.complex128, np.bool_,
          object, str]
SPECIAL = [np.nan, np.inf, -np.inf, 1e308, -1e308, 1e200, 1e-320, 5e-324, -0.0, 0.0]
#: Sample counts for ``Simulator.run``: small, wrong, or too large to allocate (never a
#: large count that would really be simulated).
RUN_LENGTHS: List[Any] = [0, 1, 2, 7, 50, 300, -1, 2**70, 10**13, 2**62, 1.5, "10", None, np.int64(5),
                          np.uint8(3), True]


class Garbage:
    """Random argument values: sometimes right, mostly wrong in one of many ways."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng

    def pick(self, items: List[Any]) -> Any:
        return items[int(self.rng.integers(len(items)))]

    def chance(self, p: float) -> bool:
        return bool(self.rng.random() < p)

    def shape(self, n: int, k: int) -> Tuple[int, ...]:
        choices: List[Tuple[int, ...]] = [
            (), (n,), (k,), (0,), (n + 1,), (int(self.rng.integers(0, 40)), n), (0, n), (3, n + 1),
            (2, n, 1), (k, n), (k, n, n), (k * n, k * n), (n, 0), (1, 1, 1, 1), (k, k), (n, n),
        ]
        return self.pick(choices)

    def array(self, shape: Tuple[int, ...]) -> Any:
        with np.errstate(all="ignore"):
            data = np.asarray(self.rng.normal(size=shape) * 10.0 ** float(self.rng.integers(-3, 4)))
            if self.chance(0.1):
                data = data * self.pick([1e300, 1e-300, 1e-310, 1e150])
        if self.chance(0.25) and data.size:
            flat = data.reshape(-1)
            for _ in range(int(self.rng.integers(1, 3))):
                flat[int(self.rng.integers(flat.size))] = self.pick(SPECIAL)
        return self.styled(data)

    def styled(self, data: Any) -> Any:
        """``data`` in another dtype, layout or container now and then."""
        dtype = self.pick(DTYPES) if self.chance(0.3) else np.float64
        try:
            with np.errstate(all="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out: Any = np.asarray(data).astype(dtype)
        except (ValueError, OverflowError):  # e.g. NaN to int
            out = data
        style = self.rng.random()
        if style < 0.1 and out.ndim >= 1:
            out = np.repeat(out, 2, axis=-1)[..., ::2]  # non-contiguous view
        elif style < 0.2:
            out = np.asfortranarray(out)
        elif style < 0.3:
            out = out.tolist()
        elif style < 0.33 and out.ndim >= 1:
            out = out.copy()
            out.flags.writeable = False
        elif style < 0.36 and out.ndim >= 1:
            out = np.broadcast_to(out, out.shape)  # read-only, zero-stride-capable view
        return out

    def value(self, n: int, k: int, good: Any = None) -> Any:
        """A value for an argument whose right value is ``good`` (None: no natural one)."""
        roll = self.rng.random()
        if good is not None and roll < 0.35:
            return good
        if roll < 0.55:
            return self.pick(SCALARS)
        return self.array(self.shape(n, k))

    def kwargs(self, n: int, k: int, options: List[Tuple[str, Any]], p: float = 0.4) -> Dict[str, Any]:
        return {key: self.value(n, k, good) for key, good in options if self.chance(p)}


# --- one episode per kind of object ----------------------------------------------------------------


@dataclass
class Stats:
    calls: int = 0
    accepted: int = 0
    raised: Dict[str, int] = field(default_factory=dict)
    slowest: List[Tuple[float, str]] = field(default_factory=list)


class Episode(SurfaceEpisodes):
    """One object built and exercised; every call goes through :meth:`call`."""

    def __init__(self, rng: np.random.Generator, stats: Stats, runs: Dict[int, vehid.Run]) -> None:
        self.g = Garbage(rng)
        self.stats = stats
        self.runs = runs

    def call(self, what: str, func: Callable[..., Any], *args: Any, **kwargs: Any) -> Tuple[bool, Any]:
        t0 = time.perf_counter()
        ok, out = attempt(func, *args, **kwargs)
        dt = time.perf_counter() - t0
        s = self.stats
        s.calls += 1
        if ok:
            s.accepted += 1
        else:
            name = type(out).__name__
            s.raised[name] = s.raised.get(name, 0) + 1
        if dt > 0.05:
            s.slowest.append((dt, f"{what}({describe(args)}{'; ' if kwargs else ''}{describe_kw(kwargs)})"))
            s.slowest.sort(reverse=True)
            del s.slowest[5:]
        return ok, out

    def good_run(self, model: vehid.LinearModel) -> vehid.Run:
        return self.runs[id(model)]

    # --- identifiers ---

    def make_identifier(self, model: vehid.LinearModel) -> Tuple[bool, Any]:
        g = self.g
        n, k = model.n_states, len(model.unknown_rows)
        kind = g.pick(["kalman", "kalman", "kalman", "gradient", "batch"])
        good_r = model.row_noise_var(0.1, 0.005)
        if kind == "kalman":
            kw: Dict[str, Any] = {}
            if g.chance(0.5):
                kw["r"] = g.value(n, k, good_r)
            elif g.chance(0.7):
                kw["road_sigma"] = g.value(n, k, 0.1)
                kw["deriv_noise"] = g.value(n, k, 0.005)
            kw.update(g.kwargs(n, k, [
                ("reinit", False), ("mode", g.pick(["rows", "shared", "full"])), ("form", g.pick(["standard", "joseph",
                                                                                                   "sqrt"])),
                ("joseph", True), ("retire_below", 0.0), ("forgetting", g.pick([1.0, 0.99, 0.5])),
                ("drift", g.pick([0.0, 1e-6])), ("directional", True), ("max_trace", g.pick([None, 1e4])),
                ("gate", g.pick([None, 0.0, 3.0, 6.0])), ("huber", g.pick([0.0, 1.345])),
                ("theta0", model.theta),
            ], p=0.25))
            p0 = g.value(n, k, g.pick([1000.0, "exact", 1e15, [10.0] * k]))
            return self.call("KalmanIdentifier", vehid.KalmanIdentifier, model, p0, **kw)
        if kind == "gradient":
            kw = g.kwargs(n, k, [("spacing", 1), ("state_noise_var", 0.0), ("lambda0", 0.99), ("lambda_init", 0.95)])
            gain = g.value(n, k, g.pick(["venter", "lyapunov", "ljung"]))
            return self.call("StochasticGradient", vehid.StochasticGradient, model, gain, g.value(n, k, 0.1),
                             g.value(n, k, 0.51), **kw)
        target = g.value(n, k, model) if g.chance(0.2) else model
        return self.call("BatchLeastSquares", vehid.BatchLeastSquares, target)

    def samples(self, model: vehid.LinearModel) -> Tuple[Any, Any]:
        """Rows of a good run, perhaps spoiled: finite but enormous from some row on (passes the
        up-front checks, may be rejected part way through), or garbage."""
        g = self.g
        n, k = model.n_states, len(model.unknown_rows)
        run = self.good_run(model)
        lo = int(g.rng.integers(len(run)))
        hi = lo + int(g.rng.integers(0, 40))
        r, z = run.r[lo:hi].copy(), run.z[lo:hi].copy()
        if len(r) and g.chance(0.3):
            row = int(g.rng.integers(len(r)))
            target = r if g.chance(0.5) else z
            target[row:] *= g.pick([1e10, 1e150, 1e200, 1e300, 1.7e308, 1e-300])
        if len(r) and g.chance(0.1):
            r[int(g.rng.integers(len(r))), int(g.rng.integers(n))] = g.pick(SPECIAL)
        return g.value(n, k, r), g.value(n, k, z)

    def exercise_identifier(self, ident: Any, model: vehid.LinearModel, steps: int) -> None:
        g = self.g
        n, k = model.n_states, len(model.unknown_rows)
        name = type(ident).__name__
        run = self.good_run(model)
        for _ in range(steps):
            action = g.pick(["update", "update", "update", "fit", "fit", "prop", "prop", "copy", "remove", "clear",
                             "reset_covariance"])
            if action == "prop":
                prop = g.pick(["theta", "params", "a_hat", "covariance", "r", "trace", "reinit_count", "samples",
                               "unknown_rows", "gated", "mode", "form", "gain", "storage_bytes", "method", "delay",
                               "spacing", "wheelbase", "wheel_variances", "paired", "model"])
                if hasattr(type(ident), prop):
                    self.call(f"{name}.{prop}", getattr, ident, prop)
                continue
            if action == "copy":
                self.check_copy(ident)
                continue
            if action in ("remove", "clear", "reset_covariance") and not hasattr(ident, action):
                continue
            before = observable(ident)
            if action == "update":
                i = int(g.rng.integers(len(run)))
                r, z = run.r[i].copy(), run.z[i].copy()
                if g.chance(0.2):
                    (r if g.chance(0.5) else z)[int(g.rng.integers(n))] = g.pick(SPECIAL + [1e30, 1e10])
                args: Tuple[Any, ...] = (g.value(n, k, r), g.value(n, k, z))
                extra = {"u_k": g.value(n, k)} if g.chance(0.05) else {}
                ok, _ = self.call(f"{name}.update", ident.update, *args, **extra)
            elif action == "fit":
                args = self.samples(model)
                extra = {}
                if g.chance(0.4):
                    extra["record_every"] = g.value(n, k, int(g.rng.integers(0, 5)))
                if g.chance(0.05):
                    extra["u"] = g.value(n, k)
                ok, _ = self.call(f"{name}.fit", ident.fit, *args, **extra)
            elif action == "remove":
                args = (g.value(n, k, int(g.rng.integers(-2, 50))),)
                extra = {}
                ok, _ = self.call(f"{name}.remove", ident.remove, *args)
            elif action == "reset_covariance":
                args = (g.value(n, k, float(10.0 ** g.rng.uniform(-3, 6))),)
                extra = {}
                ok, _ = self.call(f"{name}.reset_covariance", ident.reset_covariance, *args)
            else:
                args, extra = (), {}
                ok, _ = self.call(f"{name}.clear", ident.clear)
            if not ok:
                after = observable(ident)
                if after != before:
                    raise Failure(f"a rejected {name}.{action}({describe(args)}; {describe_kw(extra)}) changed the "
                                  f"identifier: {summary(before)} -> {summary(after)}")
        self.call(f"{name}.__repr__", repr, ident)

    def check_copy(self, ident: Any) -> None:
        """A copy or a pickle round trip has the same observable state."""
        how = self.g.pick(["copy", "deepcopy", "pickle"])
        func: Callable[[Any], Any] = {"copy": copy.copy, "deepcopy": copy.deepcopy,
                                      "pickle": lambda x: pickle.loads(pickle.dumps(x, protocol=5))}[how]
        ok, twin = self.call(f"{type(ident).__name__} {how}", func, ident)
        if ok and observable(twin) != observable(ident):
            raise Failure(f"a {how} of {type(ident).__name__} differs: {summary(observable(ident))} -> "
                          f"{summary(observable(twin))}")

    def identifier_episode(self) -> None:
        model = self.g.pick(MODELS)
        ok, ident = self.make_identifier(model)
        if ok:
            self.exercise_identifier(ident, model, int(self.g.rng.integers(1, 25)))

    def two_axle_episode(self) -> None:
        g = self.g
        kw = g.kwargs(8, 4, [("spacing", 0.3), ("method", g.pick(["none", "thesis", "cancel"])), ("p0", 1000.0),
                             ("road_sigma", 0.1), ("deriv_noise", 0.005), ("p0_body", 8.0), ("wheelbase", 3.0),
                             ("direct_front", True)])
        model = HALF if g.chance(0.8) else g.pick([CAR, THREE, None, "half"])
        ok, ident = self.call("TwoAxleIdentifier", vehid.TwoAxleIdentifier, model, **kw)
        if ok:
            self.exercise_identifier(ident, HALF, int(g.rng.integers(1, 15)))

    def sampler_episode(self) -> None:
        g = self.g
        args = [g.value(1, 1, v) for v in (3.0, 0.3, 0.01)][: int(g.rng.integers(0, 4))]
        ok, sampler = self.call("AxleSampler", vehid.AxleSampler, *args)
        if not ok:
            return
        for _ in range(int(g.rng.integers(1, 10))):
            method, arity = g.pick([("feed", 1), ("advance", 2), ("time_to_next", 1), ("reset", 1)])
            self.call(f"AxleSampler.{method}", getattr(sampler, method),
                      *[g.value(1, 1, float(g.rng.normal() * 10)) for _ in range(arity)])
            prop = g.pick(["distance_to_next", "delay", "spacing", "wheelbase", "tolerance", "position", "samples"])
            self.call(f"AxleSampler.{prop}", getattr, sampler, prop)

    # --- models ---

    def model_episode(self) -> None:
        g = self.g
        kind = g.pick(["quarter", "half", "linear", "existing", "existing"])
        if kind == "quarter":
            kw = g.kwargs(1, 1, [(name, v) for name, v in CAR.params.items()])
            ok, model = self.call("QuarterCar", vehid.QuarterCar, **kw)
        elif kind == "half":
            kw = g.kwargs(1, 1, [(name, v) for name, v in HALF.params.items()], p=0.2)
            ok, model = self.call("HalfCar", vehid.HalfCar, **kw)
        elif kind == "linear":
            base = g.pick(MODELS)
            n, k = base.n_states, len(base.unknown_rows)
            a = g.value(n, k, base.a + (g.rng.normal(size=(n, n)) if g.chance(0.2) else 0.0))
            b = g.value(n, k, base.b)
            rows = g.value(n, k, list(base.unknown_rows)) if g.chance(0.5) else g.pick(
                [[0], [n - 1], [n], [-1], [0, 0], list(range(n)), [], [1.5], ["1"]])
            extra = {"structural_zeros": g.pick([[(0, 0)], [(n, 0)], [], None, [(0,)], "x"])} if g.chance(0.2) else {}
            ok, model = self.call("LinearModel", vehid.LinearModel, a, b, rows, **extra)
        else:
            ok, model = True, g.pick(MODELS)
        if not ok:
            return
        if not (np.all(np.isfinite(model.a)) and np.all(np.isfinite(model.b))):
            raise Failure(f"{type(model).__name__} accepted with a non-finite A or B: {model!r}")
        n, k = model.n_states, len(model.unknown_rows)
        for _ in range(int(g.rng.integers(1, 6))):
            method = g.pick(["poles", "output_std", "row_noise_var", "sampled_cov", "sampled_std", "a_hat", "physical",
                             "theta", "a", "b", "structural_zeros", "unknown_rows", "params", "pickle", "eq"])
            if method == "poles":
                self.call("poles", model.poles)
            elif method == "output_std":
                kw = g.kwargs(n, k, [("road_sigma", 1.0), ("hold", g.pick([0.05, 1.0, 1e-300, 1e300, 1e160]))])
                hold = number(kw.get("hold"))
                if n == 16 and hold is not None and 1.0 < abs(hold) < 1e30:
                    kw["hold"] = 1.0  # long but legal computations (seconds each): not what this searches for
                self.call("output_std", model.output_std, **kw)
            elif method == "row_noise_var":
                kw = g.kwargs(n, k, [("road_sigma", g.pick([0.1, 1e155])), ("deriv_noise", 0.005)])
                self.call("row_noise_var", model.row_noise_var, **kw)
            elif method in ("sampled_cov", "sampled_std"):
                kw = g.kwargs(n, k, [("road_sigma", 0.1), ("dt", g.pick([0.05, 1e-9, 10.0])),
                                     ("method", g.pick(["rk4", "exact"])), ("substeps", g.pick([None, 1, 7, 0]))])
                sub = number(kw.get("substeps"))
                if sub is not None and 1000 < sub < 2**40:
                    kw["substeps"] = 1000  # a legal but long discretization: not what this searches for
                self.call(method, getattr(model, method), **kw)
            elif method == "a_hat":
                self.call("a_hat", model.a_hat, g.value(n, k, model.theta))
            elif method == "physical":
                known = g.pick([{"m": 1.0}, {"M": 10.0}, {"m1": 1.0, "m2": 1.0}, {}, {"m": "x"}, {"zz": 1.0},
                                {"m": g.pick(SPECIAL)}])
                self.call("physical", model.physical, g.value(n, k, model.theta), **known)
            elif method == "pickle":
                ok, twin = self.call("model pickle", lambda m: pickle.loads(pickle.dumps(m)), model)
                if ok and twin != model:
                    raise Failure(f"a pickled {type(model).__name__} differs from the original")
            elif method == "eq":
                self.call("model ==", lambda a, b: (a == b, a != b, hash(a)), model, g.value(n, k, g.pick(MODELS)))
            elif hasattr(type(model), method):
                self.call(f"model.{method}", getattr, model, method)
        self.call("model repr", repr, model)

    # --- the simulator ---

    def simulator_episode(self) -> None:
        g = self.g
        model = g.pick(MODELS) if g.chance(0.9) else g.pick([None, "quarter", 3])
        n = model.n_states if isinstance(model, vehid.LinearModel) else 4
        kw = g.kwargs(n, 2, [
            ("dt", g.pick([0.05, 0.005, 1e-6, 2.0])), ("road_sigma", g.pick([0.1, 1e308, 0.0])), ("ic_sigma", 0.1),
            ("state_noise", 0.001), ("deriv_noise", 0.005), ("seed", g.pick([1, 2**64 - 1, 0])),
            ("substeps", g.pick([None, 1, 4])), ("method", g.pick(["rk4", "exact"])),
            ("pulses", [(3, 2, 0.5)]), ("instrumentation", True),
        ], p=0.2)
        if model is HALF and g.chance(0.4):
            kw.update(g.kwargs(8, 2, [("speed", g.pick([6.0, 5e-5, [6.0, 0.0, 6.0] * 20])),
                                      ("spacing", g.pick([0.3, 0.15, 6e-9])),
                                      ("road", g.pick(["white", "independent"]))], p=0.6))
        sub = number(kw.get("substeps"))
        if sub is not None and 100 < sub < 2**40:
            kw["substeps"] = 100  # legal but slow: not what this searches for
        ok, sim = self.call("Simulator", vehid.Simulator, model, **kw)
        if not ok:
            return
        for _ in range(int(g.rng.integers(1, 5))):
            if g.chance(0.7):
                n_run = g.pick(RUN_LENGTHS)
                before = sim.samples
                twin = copy_simulator(model, kw) if g.chance(0.2) else None
                ok, run = self.call("Simulator.run", sim.run, n_run)
                if ok:
                    check_run(run, n_run, sim)
                elif sim.samples != before:
                    raise Failure(f"a rejected Simulator.run({n_run!r}) moved the simulator from sample {before} to "
                                  f"{sim.samples} ({describe_kw(kw)})")
                elif twin is not None:
                    self.same_continuation(sim, twin, before)
            else:
                prop = g.pick(["substeps", "dt", "spacing", "road", "seed", "method", "model", "samples", "n_states",
                               "n_inputs"])
                self.call(f"Simulator.{prop}", getattr, sim, prop)
        self.call("Simulator repr", repr, sim)

    def same_continuation(self, sim: vehid.Simulator, twin: Any, at: int) -> None:
        """After a rejected run, ``sim`` continues exactly as a fresh twin advanced to ``at``."""
        if at and not attempt(twin.run, at)[0]:
            return
        ok_a, a = attempt(sim.run, 3)
        ok_b, b = attempt(twin.run, 3)
        same = ok_a and ok_b and np.array_equal(a.r, b.r, equal_nan=True) and np.array_equal(a.z, b.z, equal_nan=True)
        if ok_a and ok_b and not same:
            raise Failure("after a rejected run the simulator does not continue as before")

    # --- functions ---

    def function_episode(self) -> None:
        g = self.g
        if g.chance(0.5):
            t = g.value(2, 4, CAR.theta)
            self.call("xi", vehid.xi, t, g.value(2, 4, CAR.theta if g.chance(0.5) else t))
        else:
            self.call("snr_db", vehid.snr_db, g.value(3, 3, 1.0), g.value(3, 3, 0.1))


def number(v: Any) -> Optional[float]:
    """``v`` as a float when it is a real number (not a bool, array or string), else None."""
    if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_)):
        return float(v)
    return None


def copy_simulator(model: Any, kw: Dict[str, Any]) -> Optional[vehid.Simulator]:
    ok, twin = attempt(vehid.Simulator, model, **kw)
    return twin if ok else None


def check_run(run: vehid.Run, n: Any, sim: vehid.Simulator) -> None:
    """An accepted run has the samples asked for, with finite data and matching shapes."""
    want = int(n)
    if len(run) != want or run.r.shape != (want, sim.n_states) or run.u.shape != (want, sim.n_inputs):
        raise Failure(f"Simulator.run({n!r}) returned {len(run)} samples, r {run.r.shape}, u {run.u.shape}")
    for name in ("t", "x", "xdot", "u", "r", "z"):
        if not np.all(np.isfinite(getattr(run, name))):
            raise Failure(f"Simulator.run({n!r}) returned non-finite `{name}` (no error)")



KINDS: List[Tuple[str, Callable[[Episode], None]]] = [
    ("identifier", Episode.identifier_episode),
    ("identifier", Episode.identifier_episode),
    ("identifier", Episode.identifier_episode),
    ("two_axle", Episode.two_axle_episode),
    ("sampler", Episode.sampler_episode),
    ("model", Episode.model_episode),
    ("simulator", Episode.simulator_episode),
    ("function", Episode.function_episode),
    ("structure", Episode.structure_episode),
    ("structure", Episode.structure_episode),
    ("noisy", lambda ep: ep.noisy_episode(MODELS)),
    ("noisy", lambda ep: ep.noisy_episode(MODELS)),
    ("monitor", Episode.monitor_episode),
    ("monitor", Episode.monitor_episode),
    ("cli", Episode.cli_episode),
]


def good_runs(seed: int) -> Dict[int, vehid.Run]:
    return {id(m): vehid.Simulator(m, road_sigma=0.1, ic_sigma=0.1, deriv_noise=0.005, seed=seed).run(300)
            for m in MODELS}


def episode(seed: int, k: int, stats: Stats, runs: Dict[int, vehid.Run], kinds: Optional[List[str]] = None) -> None:
    """Episode ``k`` of ``seed`` (its own generator: reproducible alone)."""
    rng = np.random.default_rng([seed, k])
    choices = [kd for kd in KINDS if kinds is None or kd[0] in kinds]
    ep = Episode(rng, stats, runs)
    _, run_episode = choices[int(rng.integers(len(choices)))]
    with np.errstate(all="ignore"):
        run_episode(ep)


def fuzz(calls: int, seed: int, kinds: Optional[List[str]] = None,
         progress: Optional[Callable[[Stats, int, float], None]] = None, every: int = 0) -> Stats:
    """Runs episodes until ``calls`` calls were made; raises :class:`Failure` on the first
    violation, with the seed and episode that reproduce it."""
    stats = Stats()
    runs = good_runs(seed)
    t0 = time.perf_counter()
    k, shown = 0, 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # as under pytest: a warning is a refused call
        while stats.calls < calls:
            try:
                episode(seed, k, stats, runs, kinds)
            except Failure as e:
                raise Failure(f"{e} [reproduce: python tests/fuzz_harness.py --seed {seed} --episode {k}]") from None
            k += 1
            if progress is not None and every and stats.calls - shown >= every:
                shown = stats.calls
                progress(stats, k, time.perf_counter() - t0)
    return stats


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calls", type=float, default=float(os.environ.get("FUZZ_CALLS", 100_000)))
    parser.add_argument("--seed", type=int, default=int(os.environ.get("FUZZ_SEED", 1)))
    parser.add_argument("--episode", type=int, default=None, help="run only this episode (to reproduce a failure)")
    args = parser.parse_args(argv)
    calls = int(args.calls)
    print(f"fuzz: seed {args.seed}, {calls} calls (FUZZ_CALLS / --calls; FUZZ_SEED / --seed)", flush=True)
    if args.episode is not None:
        stats = Stats()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            episode(args.seed, args.episode, stats, good_runs(args.seed))
        print(f"fuzz: episode {args.episode}: {stats.calls} calls, no failure")
        return 0

    def progress(s: Stats, k: int, seconds: float) -> None:
        print(f"fuzz: {s.calls:>9,} calls, {k:>7,} episodes, {seconds:7.1f} s ({s.calls / seconds:,.0f} calls/s), "
              f"{s.accepted:,} accepted, {s.calls - s.accepted:,} rejected", flush=True)

    t0 = time.perf_counter()
    try:
        stats = fuzz(calls, args.seed, progress=progress, every=max(1000, calls // 20))
    except Failure as e:
        print(f"fuzz: FAILED: {e}", file=sys.stderr)
        return 1
    seconds = time.perf_counter() - t0
    print(f"fuzz: done: {stats.calls:,} calls in {seconds:.1f} s, seed {args.seed}: 0 panics, 0 foreign exceptions, "
          f"every rejected call left its object unchanged")
    print("fuzz: rejected by " + ", ".join(f"{name} {n:,}" for name, n in sorted(stats.raised.items())))
    for dt, what in stats.slowest:
        print(f"fuzz: slow call: {dt:.2f} s {what}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The fuzz harness's newer surfaces: equation texts drawn from the structure
grammar and then broken, the structures' identifiers, the noise-robust identifiers
(``IVIdentifier``, ``BiasCompensated``, ``JointEKF``), the health monitor (with its saved
state corrupted byte by byte) and the command line in-process.

:class:`SurfaceEpisodes` is mixed into the harness's ``Episode`` (``tests/fuzz_harness.py``):
its methods use the episode's ``g`` (random values), ``call`` (one counted call, which raises
:class:`~fuzz_common.Failure` on a panic or a foreign exception) and ``exercise_identifier``.
Besides the harness's two properties (only the allowed exceptions; a rejected call changes
nothing) it checks:

- a structure built from a well-formed equation text evaluates as the text says: its
  ``derivative`` against Python's own evaluation of the same text (the grammar is a subset of
  Python's expressions), to 10⁻⁸ of the terms' magnitude;
- a structure, a monitor and every identifier survive copy and pickle unchanged; a saved
  monitor or identifier with one byte changed is refused (``VehidError``) and leaves the
  object it was loaded into unchanged;
- the command line never reports an internal error, prints no Python warning and never
  raises: exit 0, or 2 with its last line on stderr ``vehid: error: ...``;
- no call takes longer than :data:`HANG_SECONDS` (a hang is a failure).
"""

from __future__ import annotations

import contextlib
import copy
import io
import math
import os
import pickle
import sys
import tempfile
import time
from typing import Any, Dict, List, Tuple

import numpy as np
from fuzz_common import Failure, describe, observable, summary

import vehid
from vehid import cli

#: A call slower than this is a hang (the slowest legal calls here take well under a second).
HANG_SECONDS = 30.0

#: Names the generator draws from: states, inputs, parameters (some of them look like the
#: grammar's functions or Python's keywords, to test the tokenizer).
STATE_NAMES = ["x", "v", "q", "zb", "zw", "theta_1", "s"]
INPUT_NAMES = ["u", "tau", "f"]
PARAM_NAMES = ["a", "b", "k", "c2", "br", "m_inv", "g", "p"]
HOSTILE_NAMES = ["sign", "pos", "", "1x", "x y", "é", "a-b", "_", "x" * 300, "\x00", "if", "lambda", "nan", "inf"]


def sign(v: float) -> float:
    return float(np.sign(v))


def pos(v: float) -> float:
    return max(v, 0.0)


def neg(v: float) -> float:
    return min(v, 0.0)


class Grammar:
    """Random equation texts: each a sum of parameter-weighted terms (what a structure must
    be, linear in its parameters), with the grammar's numbers, parentheses, unary minus,
    division by numbers and ``sign`` / ``pos`` / ``neg`` of linear combinations."""

    def __init__(self, rng: np.random.Generator, states: List[str], inputs: List[str], params: List[str]) -> None:
        self.rng, self.states, self.inputs, self.params = rng, states, inputs, params

    def pick(self, items: List[str]) -> str:
        return items[int(self.rng.integers(len(items)))]

    def number(self) -> str:
        v = float(self.rng.choice([1.0, 2.0, 0.5, 3.25, 10.0, 1e-3, 7.0]))
        return self.pick([f"{v}", f"{v:g}", f"{v:e}", f"{int(v)}" if v >= 1 else f"{v}"])

    def signal(self) -> str:
        return self.pick(self.states + self.inputs)

    def linear(self, depth: int) -> str:
        """A linear combination of signals (the argument of ``sign`` and the like)."""
        parts = [self.signal()]
        for _ in range(int(self.rng.integers(0, 3))):
            parts.append(f"{self.pick(['+', '-'])} {self.number()}*{self.signal()}" if self.rng.random() < 0.5
                         else f"{self.pick(['+', '-'])} {self.signal()}")
        text = " ".join(parts)
        return f"({text})" if depth > 0 and self.rng.random() < 0.3 else text

    def factor(self, depth: int) -> str:
        """A factor without parameters, one variable per term once expanded (what a structure
        takes): a signal, a function of a combination, a number times a factor, a parenthesized
        sum or difference of factors, a negated factor, a factor over a number."""
        roll = self.rng.random()
        if roll < 0.45:
            return self.signal()
        if roll < 0.6:
            return f"{self.pick(['sign', 'pos', 'neg'])}({self.linear(depth)})"
        if roll < 0.75 and depth < 3:
            return f"{self.number()}*{self.factor(depth + 1)}"
        if roll < 0.85 and depth < 3:
            return f"({self.factor(depth + 1)} {self.pick(['+', '-'])} {self.factor(depth + 1)})"
        if roll < 0.92:
            return f"-{self.factor(depth + 1)}" if depth < 3 else self.signal()
        return f"{self.factor(depth + 1)}/{self.number()}" if depth < 3 else self.signal()

    def equation(self) -> Tuple[str, List[str]]:
        """An equation text and its terms (each a valid Python expression of the same names),
        whose sum it is."""
        terms: List[str] = []
        pieces: List[str] = []
        for i in range(int(self.rng.integers(1, 5))):
            p, f = self.pick(self.params), self.factor(0)
            term = self.pick([f"{p}*{f}", f"{f}*{p}", f"{p}*({f})", f"{self.number()}*{p}*{f}"])
            sgn = "-" if self.rng.random() < 0.4 else "+"
            pieces.append((f"{sgn} " if i else ("-" if sgn == "-" else "")) + term)
            terms.append(f"{sgn}({term})")
        return " ".join(pieces), terms


def hostile(rng: np.random.Generator, text: str) -> str:
    """``text`` broken in one of the ways a user's file (or an attacker) breaks it."""
    k = int(rng.integers(12))
    n = int(rng.choice([2, 50, 65, 500, 10_000, 20_000]))
    if k == 0:
        return "(" * n + text + ")" * n
    if k == 1:
        return "-" * n + text
    if k == 2:
        return "sign(" * n + "x" + ")" * n
    if k == 3:
        return "*".join(["(1+1)"] * int(rng.integers(2, 60))) + "*a*x"
    if k == 4:
        return "*".join(["(a+b+x)"] * int(rng.integers(2, 30)))
    if k == 5:
        return " + ".join(f"p{i}*x" for i in range(n))
    if k == 6 and text:
        i = int(rng.integers(len(text)))
        return text[:i] + str(rng.choice(list("()*/+-^.,;:=!\\'\"#$%&@[]{}|~`0e\x00\u2212"))) + text[i:]
    if k == 7 and text:
        i = int(rng.integers(len(text)))
        return text[:i] + text[i + 1:]
    if k == 8:
        return text + " * " + str(rng.choice(["1e999", "nan", "inf", "1e-400", "0", "0.0/0", "1e308*1e308"]))
    if k == 9:
        return text.replace("*", str(rng.choice(["**", "^", "", " ", "//"])), 1)
    if k == 10:
        return str(rng.choice(["", " ", "()", "a*", "*a", "a*x)", "(a*x", "a x", "sign()", "pos(a*x)", "a*sign(a)",
                               "exp(x)", "a*b*x", "a/x", "a*x/0", "1", "x", "\ufeffa*x", "a*x\n+b*v"]))
    return text * int(rng.integers(2, 5))


class SurfaceEpisodes:
    """The newer surfaces' episodes (mixed into the harness's ``Episode``)."""

    g: Any
    runs: Dict[Any, Any]

    # Provided by the harness's Episode.
    def call(self, what: str, func: Any, *args: Any, **kwargs: Any) -> Tuple[bool, Any]:  # pragma: no cover
        raise NotImplementedError

    def exercise_identifier(self, ident: Any, model: Any, steps: int) -> None:  # pragma: no cover
        raise NotImplementedError

    def timed(self, what: str, func: Any, *args: Any, **kwargs: Any) -> Tuple[bool, Any]:
        """:meth:`call`, failing on a hang."""
        t0 = time.perf_counter()
        out = self.call(what, func, *args, **kwargs)
        if time.perf_counter() - t0 > HANG_SECONDS:
            raise Failure(f"{what}({describe(args)}) took {time.perf_counter() - t0:.0f} s: a hang")
        return out

    # --- structures from the grammar ---

    def structure_episode(self) -> None:
        g = self.g
        rng = g.rng
        n_states = int(rng.integers(1, 4))
        states = list(rng.choice(STATE_NAMES, size=n_states, replace=False))
        inputs = list(rng.choice(INPUT_NAMES, size=int(rng.integers(0, 3)), replace=False))
        params = list(rng.choice(PARAM_NAMES, size=int(rng.integers(1, 5)), replace=False))
        grammar = Grammar(rng, states, inputs, params)
        equations: Dict[str, str] = {}
        terms: Dict[str, List[str]] = {}
        well_formed = True
        for s in states:
            if rng.random() < 0.15:
                continue  # a state without an equation (refused, or known below)
            text, ts = grammar.equation()
            if rng.random() < 0.15:
                text, well_formed = hostile(rng, text), False
            equations[s] = text
            terms[s] = ts
        kw: Dict[str, Any] = {}
        if rng.random() < 0.2:
            kw["known"] = {s: grammar.linear(0) for s in states if s not in equations}
        if rng.random() < 0.1:
            kw["parameters"] = g.pick([params, params[::-1], params + ["zz"], [], ["a", "a"], None, "ab", [1]])
            well_formed = well_formed and kw["parameters"] in (params, params[::-1])
        if rng.random() < 0.05:
            states, well_formed = states + [g.pick(HOSTILE_NAMES)], False
        if rng.random() < 0.05:
            inputs, well_formed = inputs + [g.pick(HOSTILE_NAMES + states[:1])], False
        if rng.random() < 0.03:
            equations, well_formed = g.pick([{}, None, {"nope": "a*x"}, {states[0]: 3}, [("x", "a*x")]]), False
        ok, s = self.timed("Structure", vehid.Structure, states, inputs, equations, **kw)
        if not ok:
            return
        if well_formed and "known" not in kw and set(equations) == set(states):
            self.check_evaluation(s, states, inputs, terms)
        ok, twin = self.call("Structure pickle", lambda x: pickle.loads(pickle.dumps(x)), s)
        if ok and twin != s:
            raise Failure(f"a pickled Structure differs from the original: {equations!r}")
        for _ in range(int(rng.integers(1, 4))):
            what = g.pick(["derivative", "simulate", "props", "identifier", "identifier"])
            n_p, n_x, n_u = s.n_params, s.n_states, s.n_inputs
            if what == "derivative":
                self.call("Structure.derivative", s.derivative, g.value(n_x, n_p, np.ones(n_p)),
                          g.value(n_x, n_p, np.ones(n_x)), g.value(n_u, n_p, np.ones(n_u) if n_u else None))
            elif what == "simulate":
                samples = g.pick([3, 20, 0, -1, 2**40, None, 1.5])
                self.timed("Structure.simulate", s.simulate, g.value(n_x, n_p, np.full(n_p, 0.1)),
                           g.value(n_x, n_p, np.zeros(n_x)),
                           g.value(n_u, n_p, np.zeros((20, n_u))) if n_u else None,
                           dt=g.value(1, 1, 0.01), samples=samples, substeps=g.pick([1, 10, 0, -3, 10_000]))
            elif what == "props":
                for prop in ("parameters", "states", "inputs", "identified", "groups", "not_identifiable",
                             "n_params"):
                    self.call(f"Structure.{prop}", getattr, s, prop)
                self.call("Structure repr", repr, s)
            else:
                self.structure_identifier(s)

    def check_evaluation(self, s: Any, states: List[str], inputs: List[str], terms: Dict[str, List[str]]) -> None:
        """The structure's derivative equals the text evaluated by Python."""
        rng = self.g.rng
        names = list(s.parameters)
        p = rng.normal(size=len(names))
        x = rng.normal(size=len(states))
        u = rng.normal(size=len(inputs))
        env: Dict[str, Any] = {"sign": sign, "pos": pos, "neg": neg, "__builtins__": {}}
        env.update(zip(names, p))
        env.update(zip(states, x))
        env.update(zip(inputs, u))
        ok, got = self.call("Structure.derivative", s.derivative, p, x, u if len(inputs) else None)
        if not ok:
            return  # e.g. a parameter only in a function's argument (not linear): refused
        for i, st in enumerate(s.states):
            if st not in terms:
                continue
            values = [float(eval(t, env)) for t in terms[st]]  # noqa: S307 - our own grammar's text
            want, scale = math.fsum(values), math.fsum(abs(v) for v in values)
            if not abs(got[i] - want) <= 1e-8 * scale + 1e-300:
                raise Failure(f"Structure({states}, {inputs}): d{st}/dt is {got[i]!r}, the text "
                              f"{' '.join(terms[st])} gives {want!r}")

    def structure_identifier(self, s: Any) -> None:
        g = self.g
        n_x, n_u = s.n_states, s.n_inputs
        kind = g.pick(["kalman", "kalman", "batch", "iv", "bias", "gradient"])
        if kind == "kalman":
            ok, ident = self.call("KalmanIdentifier(structure)", vehid.KalmanIdentifier, s,
                                  g.value(n_x, 1, g.pick([1000.0, "exact"])),
                                  **g.kwargs(n_x, 1, [("r", 1.0), ("gate", 6.0), ("mode", "rows")], p=0.3))
        elif kind == "batch":
            ok, ident = self.call("BatchLeastSquares(structure)", vehid.BatchLeastSquares, s)
        elif kind == "iv":
            ok, ident = self.call("IVIdentifier(structure)", vehid.IVIdentifier, s,
                                  **g.kwargs(n_x, 1, [("delay", 1), ("p0", 1000.0)], p=0.3))
        elif kind == "bias":
            ok, ident = self.call("BiasCompensated(structure)", vehid.BiasCompensated, s,
                                  g.value(n_x, 1, g.pick([0.01, "estimate"])))
        else:
            ok, ident = self.call("StochasticGradient(structure)", vehid.StochasticGradient, s,
                                  g.value(n_x, 1, "venter"), 0.1, 0.51)
        if not ok:
            return
        name = type(ident).__name__
        for _ in range(int(g.rng.integers(1, 8))):
            m = int(g.rng.integers(0, 60))
            x = g.rng.normal(size=(m, n_x))
            z = g.rng.normal(size=(m, n_x))
            u = g.rng.normal(size=(m, n_u)) if n_u else None
            if m and g.chance(0.3):
                (x if g.chance(0.5) else z)[int(g.rng.integers(m)), int(g.rng.integers(n_x))] = g.pick(
                    [np.nan, np.inf, 1e30, 1e300])
            before = observable(ident)
            if g.chance(0.5) and m:
                args: Tuple[Any, ...] = (g.value(n_x, 1, x[0]), g.value(n_x, 1, z[0]))
                ok, _ = self.call(f"{name}.update", ident.update, *args,
                                  **({"u_k": g.value(n_u, 1, u[0])} if u is not None else {}))
            else:
                args = (g.value(n_x, 1, x), g.value(n_x, 1, z))
                ok, _ = self.timed(f"{name}.fit", ident.fit, *args, **({"u": g.value(n_u, 1, u)} if u is not None
                                                                         else {}))
            if not ok and observable(ident) != before:
                raise Failure(f"a rejected {name} call ({describe(args)}) on a structure changed it: "
                              f"{summary(before)} -> {summary(observable(ident))}")
        self.check_saved(ident)
        for prop in ("theta", "params", "samples", "gated"):
            if hasattr(type(ident), prop):
                self.call(f"{name}.{prop}", getattr, ident, prop)
        if hasattr(ident, "stats"):
            self.call(f"{name}.stats", ident.stats)

    # --- the noise-robust identifiers on the harness's models ---

    def noisy_episode(self, models: List[Any]) -> None:
        g = self.g
        model = g.pick(models)
        n, k = model.n_states, len(model.unknown_rows)
        kind = g.pick(["iv", "iv", "bias", "bias", "ekf"])
        if kind == "iv":
            kw = g.kwargs(n, k, [("delay", g.pick([1, 2, 0, -1])), ("lags", g.pick([None, 1, 3, 50])),
                                 ("p0", g.pick([1000.0, "exact", None])), ("r", 1.0),
                                 ("instruments", g.pick(["delayed", "model"])), ("dt", 0.05),
                                 ("refresh", g.pick([100, 1, 0])), ("substeps", g.pick([1, 4, 0])),
                                 ("road", g.pick(["white", "random-walk", "iso8608"])),
                                 ("spacing", g.pick([None, 0.5, "odometer"])),
                                 ("lift_off", g.pick([None, (0.5, 0.1)]))], p=0.25)
            ok, ident = self.call("IVIdentifier", vehid.IVIdentifier, model, **kw)
        elif kind == "bias":
            noise = g.value(n, k, g.pick([0.01, "estimate", [1e-4] * n]))
            kw = g.kwargs(n, k, [("deriv_noise_var", 2.5e-5), ("r", 1.0), ("delay", 1), ("lags", 2)], p=0.25)
            ok, ident = self.call("BiasCompensated", vehid.BiasCompensated, model, noise, **kw)
        else:
            kw = g.kwargs(n, k, [("deriv_noise", 0.005), ("road_sigma", 0.1), ("dt", 0.05), ("substeps", 2),
                                 ("x0_var", 1.0), ("drift", 0.0)], p=0.25)
            kw["state_noise"] = g.value(n, k, 0.001)
            ok, ident = self.call("JointEKF", vehid.JointEKF, model, g.value(n, k, model.theta),
                                  g.value(n, k, g.pick([None, 10.0])), **kw)
        if ok:
            self.exercise_identifier(ident, model, int(g.rng.integers(1, 20)))
            self.check_saved(ident)

    def check_saved(self, obj: Any) -> None:
        """A saved object with one byte changed (or one appended) is refused and leaves the
        object it was loaded into unchanged."""
        g = self.g
        ok, red = self.call(f"{type(obj).__name__}.__reduce__", obj.__reduce__)
        if not ok or len(red) < 3 or not isinstance(red[2], tuple) or len(red[2]) < 3:
            return
        fmt, version, payload = red[2][:3]
        if not isinstance(payload, bytes) or not payload:
            return
        i = int(g.rng.integers(len(payload) + 1))
        bad = payload + b"\x00" if i == len(payload) else (
            payload[:i] + bytes([payload[i] ^ (1 << int(g.rng.integers(8)))]) + payload[i + 1:])
        target = copy.copy(obj)
        before = target.__reduce__()
        ok, _ = self.call(f"{type(obj).__name__}.__setstate__", target.__setstate__, (fmt, version, bad,
                                                                                      *red[2][3:]))
        if ok:
            raise Failure(f"a saved {type(obj).__name__} with byte {i} of {len(payload)} changed was accepted")
        if target.__reduce__() != before:
            raise Failure(f"a refused load changed the {type(obj).__name__} it was loaded into")

    # --- the health monitor ---

    def monitor_run(self, car: Any, sensors: str) -> Any:
        key = ("monitor", repr(car), sensors)
        if key not in self.runs:
            params = car.params
            change = ({"b": 0.7 * params["b"]} if "b" in params else {"b_fl": 0.7 * params["b_fl"]}
                      if "b_fl" in params else {"b_f": 0.7 * params["b1"]})
            sim = vehid.Simulator(car, dt=0.005, road="iso8608-C", speed=15.0, sensors=sensors, seed=5,
                                  changes=[(24.0, change)])
            self.runs[key] = sim.run(6000).y
        return self.runs[key]

    def monitor_episode(self) -> None:
        g = self.g
        car = g.pick([vehid.QuarterCar.passenger(), vehid.HalfCar.passenger(), vehid.QuarterCar(),
                      vehid.FullCar.passenger()])
        sensors = g.pick(["realistic", "realistic", "state"]) if not isinstance(car, vehid.FullCar) else "realistic"
        good = self.monitor_run(car, sensors)
        args: List[Any] = [car if g.chance(0.9) else g.value(4, 1, car)]
        kw: Dict[str, Any] = {"dt": g.value(1, 1, 0.005) if g.chance(0.1) else 0.005,
                              "sensors": g.value(1, 1, sensors) if g.chance(0.1) else sensors}
        kw.update(g.kwargs(1, 1, [("window", 6.0), ("warmup", g.pick([20.0, 1.0])), ("settle", 4.0),
                                  ("reacquire", 1.0), ("min_change", 0.05), ("judge_error", 0.008),
                                  ("threshold", 8.0), ("confidence", 0.95), ("systematic", 0.01),
                                  ("stuck_samples", 20),
                                  ("sensor_noise", g.pick([{"deflection": 1e-3}, {"a_body": 0.05, "x": 1.0},
                                                           {"a_wheel": -1.0}, {}]))], p=0.1))
        ok, mon = self.call("HealthMonitor", vehid.HealthMonitor, *args, **kw)
        if not ok:
            return
        width = good.shape[1]
        for _ in range(int(g.rng.integers(1, 12))):
            action = g.pick(["fit", "fit", "update", "update", "props", "copy", "saved"])
            if action == "props":
                for prop in ("status", "samples", "events", "constants", "estimate", "reference", "dt", "sensors",
                             "channels"):
                    self.call(f"HealthMonitor.{prop}", getattr, mon, prop)
                self.call("HealthMonitor repr", repr, mon)
                continue
            if action == "copy":
                how = g.pick(["copy", "deepcopy", "pickle"])
                fn = {"copy": copy.copy, "deepcopy": copy.deepcopy, "pickle": lambda m: pickle.loads(pickle.dumps(m))}
                ok, twin = self.call(f"HealthMonitor {how}", fn[how], mon)
                if ok and monitor_view(twin) != monitor_view(mon):
                    raise Failure(f"a {how} of a HealthMonitor differs")
                continue
            if action == "saved":
                self.check_saved(mon)
                continue
            before = monitor_view(mon)
            lo = int(g.rng.integers(len(good)))
            y = good[lo:lo + int(g.rng.choice([1, 10, 500, 3000]))].copy()
            if len(y) and g.chance(0.4):
                i, j = int(g.rng.integers(len(y))), int(g.rng.integers(width))
                spoil = g.pick(["nan", "inf", "huge", "stuck", "step", "swap"])
                if spoil == "nan":
                    y[i:, j] = np.nan
                elif spoil == "inf":
                    y[i, j] = g.pick([np.inf, -np.inf])
                elif spoil == "huge":
                    y[i, j] = g.pick([1e30, -1e300, 1.7e308])
                elif spoil == "stuck":
                    y[i:, j] = y[i, j]
                elif spoil == "step":
                    y[i:, j] += g.pick([0.05, -1.0, 100.0])
                else:
                    y[i:, [0, j]] = y[i:, [j, 0]]
            if action == "update":
                arg = g.value(width, 1, y[0] if len(y) else np.zeros(width))
                ok, out = self.call("HealthMonitor.update", mon.update, arg)
            else:
                arg = g.value(width, 1, y)
                ok, out = self.timed("HealthMonitor.fit", mon.fit, arg)
            if not ok and monitor_view(mon) != before:
                raise Failure(f"a rejected HealthMonitor.{action}({describe((arg,))}) changed the monitor")
            if ok:
                for ev in out:
                    if not all(math.isfinite(v) for v in (ev.t, ev.before, ev.after, ev.low, ev.high)):
                        raise Failure(f"a HealthMonitor event with a non-finite field: {ev!r}")

    # --- the command line, in-process ---

    def cli_episode(self) -> None:
        g = self.g
        with tempfile.TemporaryDirectory() as tmp:
            cmd = g.pick(["identify", "identify", "monitor", "monitor", "monitor", "inspect", "simulate", "bogus"])
            argv, stdin_text = self.cli_argv(tmp, cmd)
            out, err = io.StringIO(), io.StringIO()
            stdin = io.TextIOWrapper(io.BytesIO(stdin_text), encoding="utf-8")
            old_stdin = sys.stdin
            try:
                sys.stdin = stdin
                with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                    ok, status = self.timed("vehid " + " ".join(a[:30] for a in argv), cli.main, argv)
            except SystemExit as e:  # argparse's own exit on a bad option (status 2)
                status, ok = e.code, True
            finally:
                sys.stdin = old_stdin
            text = err.getvalue()
            if not ok:
                raise Failure(f"vehid {argv} raised instead of exiting: {status!r}")
            if "internal error" in text or "Traceback" in text or "Warning:" in text:
                raise Failure(f"vehid {argv}: {text.strip()[:300]}")
            if status not in (0, 2, None):
                raise Failure(f"vehid {argv} exited {status!r}: {text.strip()[:200]}")
            last = text.strip().splitlines()[-1] if text.strip() else ""
            if status == 2 and not last.startswith("vehid: error: ") and "usage:" not in text:
                raise Failure(f"vehid {argv} failed without an error line on stderr: {text.strip()[:300]!r}")

    def table_text(self, cmd: str, model: str) -> bytes:
        """A table for ``cmd``: mostly the columns it reads (a monitor log, a run of the model's
        states and derivatives), with bad cells, units, delimiters, now and then garbage."""
        g = self.g
        rng = g.rng
        roll = rng.random()
        if roll < 0.04:
            return bytes(rng.integers(0, 256, size=int(rng.integers(1, 400)), dtype=np.uint8))
        if roll < 0.06:
            return g.pick([b"", b"\n", b"\xef\xbb\xbf", "a,b\n1,2\n".encode("utf-16")])
        if cmd == "monitor":
            cols = g.pick([["t", "a_body", "a_wheel", "deflection"], ["time [ms]", "a_body [g]", "a_wheel [g]",
                                                                       "SuspTravel [mm]"],
                           ["t", "a_body_f", "a_body_r", "a_wheel_f", "a_wheel_r", "deflection_f", "deflection_r"]])
            rows = int(rng.choice([0, 1, 3, 400, 5000]))
        elif "toml" in model:
            cols, rows = ["t", "q", "v", "dq", "dv", "tau"], int(rng.choice([0, 2, 40, 300]))
        else:
            n = 8 if model == "half" else 4
            cols = (["t"] + [f"x{i + 1}" for i in range(n)] + [f"dx{i + 1}" for i in range(n)]
                    + ["u1"] + (["u2"] if n == 8 else []))
            rows = int(rng.choice([0, 2, 40, 300]))
        if g.chance(0.05):
            cols = g.pick([["x1", "x1", ""], ["t"], cols[:-1], cols + ["extra"]])
        data = rng.normal(size=(rows, len(cols))) * 0.05
        if rows and cols[0] in ("t", "time [ms]"):
            step = 5.0 if cols[0] == "time [ms]" else 0.005
            data[:, 0] = np.arange(rows) * step
            if g.chance(0.1):
                data[int(rng.integers(rows)):, 0] += g.pick([-step * 3, 86400.0 * 58, 1e-9, np.nan])
        sep = "," if g.chance(0.8) else g.pick([";", "\t"])
        lines = [sep.join(cols)]
        for r in data:
            cells = [repr(float(v)) for v in r]
            if g.chance(0.01):
                cells[int(rng.integers(len(cells)))] = g.pick(["", "nan", "inf", "-1e400", "x", "1,5", "2026-11-27"])
            lines.append((sep if g.chance(0.995) else ",").join(cells))
        if g.chance(0.1):
            lines.append(g.pick(["", "1,2", ",,,,", "\x00"]))
        return ("\n".join(lines) + "\n").encode()

    def model_text(self) -> str:
        g = self.g
        rng = g.rng
        grammar = Grammar(rng, ["q", "v"], ["tau"], ["k", "b", "g"])
        eq, _ = grammar.equation()
        if g.chance(0.3):
            eq = hostile(rng, eq)
        eq = eq.replace("\\", "\\\\").replace('"', '\\"')
        text = (f'states = ["q", "v"]\ninputs = ["tau"]\n[equations]\nv = "{eq}"\n[known]\nq = "v"\n'
                '[columns]\nq = "q"\nv = "v"\ntau = "tau"\n')
        if g.chance(0.2):
            i = int(rng.integers(len(text)))
            text = text[:i] + g.pick(["[", "]", '"', "=", "\n", "\x00", "\ufeff", "states = 3\n"]) + text[i:]
        return text

    def cli_argv(self, tmp: str, cmd: str) -> Tuple[List[str], bytes]:
        """A command line for ``cmd`` (valid most of the time, each option now and then wrong)
        and what its standard input holds."""
        g = self.g
        model_file = os.path.join(tmp, "model.toml")
        with open(model_file, "w", encoding="utf-8", errors="surrogatepass") as f:
            f.write(self.model_text())
        if cmd == "monitor":
            model = g.pick(["quarter", "passenger", "half", "passenger", "full", ""]) if g.chance(0.9) else "x"
        else:
            model = g.pick(["quarter", "half", model_file]) if g.chance(0.9) else g.pick(["nope", "", "full"])
        data = os.path.join(tmp, "data.csv")
        table = self.table_text(cmd, model)
        with open(data, "wb") as f:
            f.write(table)
        src = data if g.chance(0.8) else g.pick(["-", os.path.join(tmp, "missing.csv"), tmp])
        argv: List[str] = [cmd]
        if cmd in ("identify", "monitor", "inspect"):
            argv.append(src)
        if cmd in ("identify", "monitor", "simulate"):
            argv += ["--model", model]
        wrong = g.chance(0.3)
        options = {
            "identify": [["--m", g.pick(["1", "40", "-1", "nan", "1e309"]) if wrong else "1"],
                         ["--p0", g.pick(["exact", "1e3", "x"]) if wrong else "1e3"],
                         ["--dt", g.pick(["0.005", "0", "-1", "1e-300"]) if wrong else "0.005"],
                         ["--params", "k=1,b=2"]],
            "monitor": [["--dt", g.pick(["1e-9", "0", "inf"]) if wrong else "0.005"],
                        ["--sensors", g.pick(["state", "x"]) if wrong else "realistic"], ["--json"]],
            "simulate": [["--n", g.pick(["0", "-1", "1e20", "x"]) if wrong else "50"],
                         ["--road", g.pick(["iso8608-C", "white"])],
                         ["--seed", g.pick(["-1", "2**64"]) if wrong else "3"],
                         ["--sensors", g.pick(["realistic", "state"])],
                         ["--params", g.pick(["k=1,b=2,g=1", "k=", "=1", "k=nan"])]],
            "inspect": [],
            "bogus": [],
        }[cmd]
        for opt in options:
            if g.chance(0.3):
                argv += opt
        if cmd == "simulate":
            if "--n" not in argv:
                argv += ["--n", "50"]
            argv += ["-o", g.pick([os.path.join(tmp, "o.csv"), os.path.join(tmp, "o.csv"), "/proc/x", tmp])]
        return argv, table if src == "-" else b""


def monitor_view(mon: Any) -> Tuple[str, ...]:
    """A health monitor's observable state: its status, counts, estimates and reference."""
    return tuple(repr(getattr(mon, p)) for p in ("status", "samples", "events", "estimate", "reference",
                                                  "constants"))

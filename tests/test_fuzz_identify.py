"""Randomized garbage against the whole public API, through ``tests/fuzz_harness.py`` (the
harness ``make fuzz`` runs for 10⁶ calls): constructors, update, fit, copies and pickles,
models' methods, ``Simulator``, ``TwoAxleIdentifier``, ``AxleSampler``, ``xi``, ``snr_db``, and
(``tests/fuzz_surfaces.py``) structures from the equation grammar, the noise-robust
identifiers, the health monitor with corrupted saved states, and the command line.

Each call must either succeed or raise VehidError / ValueError / TypeError / OverflowError /
MemoryError; anything else fails, above all pyo3's ``PanicException`` (a ``BaseException``,
so it would slip past ``except Exception``). A rejected ``update()`` / ``fit()`` must leave
the identifier bit for bit as it was (θ̂, samples, P, R, the counters: ``observable``); the
one documented exception is ``BatchLeastSquares.fit`` on valid samples it cannot solve for
yet, which stores them and says so. Seeded: a failure names the seed and episode that
reproduce it (``python tests/fuzz_harness.py --seed S --episode K``).
"""

from __future__ import annotations

import copy
import sys
import time
from typing import Any, Dict, List, Tuple

import numpy as np
import pytest
from fuzz_common import Failure
from fuzz_harness import CAR, Episode, Garbage, Stats, fuzz, observable  # tests/ is on sys.path under pytest
from fuzz_surfaces import Grammar, SurfaceEpisodes, hostile

import vehid

#: Calls per seed in ``make test`` (4 seeds: 10^4 calls in all, a few seconds).
CALLS_PER_SEED = 2_500


def sample_run(model: vehid.LinearModel, n: int, seed: int) -> vehid.Run:
    return vehid.Simulator(model, road_sigma=0.1, ic_sigma=0.1, deriv_noise=0.005, seed=seed).run(n)


@pytest.mark.parametrize("seed", range(4))
def test_public_api_survives_garbage(seed: int) -> None:
    t0 = time.perf_counter()
    stats = fuzz(CALLS_PER_SEED, seed)
    assert stats.calls >= CALLS_PER_SEED
    assert stats.accepted > 0.1 * stats.calls and stats.calls - stats.accepted > 0.1 * stats.calls, stats
    assert time.perf_counter() - t0 < 20, "2,500 calls should take a few seconds"


@pytest.mark.parametrize("kind", ["identifier", "two_axle", "sampler", "model", "simulator", "function",
                                  "structure", "noisy", "monitor", "cli"])
def test_every_kind_of_object_is_fuzzed(kind: str) -> None:
    stats = fuzz(150, 1000, kinds=[kind])
    assert stats.calls >= 150
    assert stats.accepted > 0, f"no {kind} call was accepted: the episode exercises nothing but its refusals"


# --- the newer surfaces' own checks can fail (tests/fuzz_surfaces.py) ---------------------------


class _Episode(SurfaceEpisodes):
    """An episode of the surfaces alone, with the harness's ``call``."""

    def __init__(self, seed: int) -> None:
        self.g = Garbage(np.random.default_rng(seed))
        self.runs: Dict[Any, Any] = {}
        self.stats = Stats()

    def call(self, what: str, func: Any, *args: Any, **kwargs: Any) -> Tuple[bool, Any]:
        return Episode.call(self, what, func, *args, **kwargs)  # type: ignore[arg-type]


class _OffBySign:
    """A structure whose derivative drops a unary minus (what `parse.rs` would do with the
    sign of a factor ignored): the evaluator check must see it."""

    def __init__(self, real: Any) -> None:
        self.real = real
        self.parameters, self.states = real.parameters, real.states

    def derivative(self, p: Any, x: Any, u: Any = None) -> List[float]:
        return [-v for v in self.real.derivative(p, x, u)]


def test_the_grammar_check_catches_a_structure_that_evaluates_otherwise() -> None:
    ep = _Episode(3)
    s = vehid.Structure(["x", "v"], ["u"], {"x": "a*v", "v": "-k*x - b*sign(v - 2*u) + g*u"})
    terms = {"x": ["+(a*v)"], "v": ["-(k*x)", "-(b*sign(v - 2*u))", "+(g*u)"]}
    ep.check_evaluation(s, ["x", "v"], ["u"], terms)  # the real one agrees with Python
    with pytest.raises(Failure, match="the text"):
        ep.check_evaluation(_OffBySign(s), ["x", "v"], ["u"], terms)


def test_the_grammar_generates_texts_that_build_and_texts_that_break() -> None:
    rng = np.random.default_rng(5)
    grammar = Grammar(rng, ["x", "v"], ["u"], ["a", "b", "k"])
    built = 0
    for _ in range(200):
        text, terms = grammar.equation()
        try:
            vehid.Structure(["x", "v"], ["u"], {"x": "a*v", "v": text})
            built += 1
        except vehid.VehidError:
            pass
        assert len(terms) >= 1
    assert built > 100, built
    broken = [hostile(rng, "a*x") for _ in range(200)]
    assert len({len(t) for t in broken}) > 20  # deep nesting, long minus chains, blown-up products...


def test_the_monitor_check_sees_a_refused_call_that_changed_the_monitor(monkeypatch: pytest.MonkeyPatch) -> None:
    # A saved monitor with a changed byte that loads must fail the episode.
    ep = _Episode(4)
    mon = vehid.HealthMonitor(vehid.QuarterCar.passenger(), dt=0.005)

    class Accepting:
        def __reduce__(self) -> Any:
            return mon.__reduce__()

        def __setstate__(self, state: Any) -> None:  # accepts anything: the defect the check is for
            pass

    monkeypatch.setattr(copy, "copy", lambda obj: Accepting())
    with pytest.raises(Failure, match="was accepted"):
        ep.check_saved(mon)


def test_the_cli_check_sees_an_internal_error(monkeypatch: pytest.MonkeyPatch) -> None:
    import fuzz_surfaces

    def broken_main(argv: Any) -> int:
        print("vehid: internal error: ZeroDivisionError: division by zero (a bug in vehid: please report it)",
              file=sys.stderr)
        return 2

    monkeypatch.setattr(fuzz_surfaces.cli, "main", broken_main)
    with pytest.raises(Failure, match="internal error"):
        _Episode(1).cli_episode()


@pytest.mark.parametrize("mode", ["rows", "shared", "full"])
def test_rejected_fit_part_way_leaves_kalman_unchanged(mode: str) -> None:
    run = sample_run(CAR, 100, 3)
    kf = vehid.KalmanIdentifier(CAR, p0=1000.0, r=[0.3, 0.3], mode=mode, gate=0)
    kf.fit(run.r[:50], run.z[:50])
    before = observable(kf)
    r = run.r[50:].copy()
    r[20:] *= 1e200  # finite, so only the update itself can reject it (the outlier gate is off: it would
    # leave the sample out instead)
    with pytest.raises(vehid.VehidError, match="sample 20 was rejected .* the identifier is unchanged"):
        kf.fit(r, run.z[50:], record_every=5)
    assert observable(kf) == before
    if mode == "rows":  # with the gate on (the default) the same samples are left out and counted
        gated = vehid.KalmanIdentifier(CAR, p0=1000.0, r=[0.3, 0.3])
        gated.fit(run.r[:50], run.z[:50])
        gated.fit(r, run.z[50:])
        assert gated.samples == 100 and np.all(gated.gated >= 30)
    # ... and it still works afterwards, exactly as if the bad call never happened.
    fresh = vehid.KalmanIdentifier(CAR, p0=1000.0, r=[0.3, 0.3], mode=mode, gate=0)
    fresh.fit(run.r[:50], run.z[:50])
    kf.fit(run.r[50:], run.z[50:])
    fresh.fit(run.r[50:], run.z[50:])
    assert np.array_equal(kf.theta, fresh.theta) and kf.samples == fresh.samples == 100


def test_batch_least_squares_keeps_unsolvable_samples_and_says_why() -> None:
    run = sample_run(CAR, 100, 3)
    ls = vehid.BatchLeastSquares(CAR)
    ls.fit(run.r[:2], run.z[:2])  # two samples cannot determine four unknowns per row
    assert ls.samples == 2  # kept: more samples complete the batch
    with pytest.raises(vehid.VehidError, match="lacks excitation"):
        _ = ls.theta
    ls.fit(run.r[2:], run.z[2:])
    before = observable(ls)
    assert ls.samples == 100
    bad = np.zeros((5, 4))
    bad[3, 1] = np.nan
    with pytest.raises(vehid.VehidError, match="not finite"):
        ls.fit(np.zeros((5, 4)), bad)  # rejected up front: nothing is stored
    assert observable(ls) == before

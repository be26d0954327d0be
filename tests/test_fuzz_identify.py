"""Randomized garbage against the whole public API, through ``tests/fuzz_harness.py`` (the
harness ``make fuzz`` runs for 10⁵ calls): constructors, update, fit, copies and pickles,
models' methods, ``Simulator``, ``TwoAxleIdentifier``, ``AxleSampler``, ``xi``, ``snr_db``.

Each call must either succeed or raise VehidError / ValueError / TypeError / OverflowError /
MemoryError; anything else fails, above all pyo3's ``PanicException`` (a ``BaseException``,
so it would slip past ``except Exception``). A rejected ``update()`` / ``fit()`` must leave
the identifier bit for bit as it was (θ̂, samples, P, R, the counters: ``observable``); the
one documented exception is ``BatchLeastSquares.fit`` on valid samples it cannot solve for
yet, which stores them and says so. Seeded: a failure names the seed and episode that
reproduce it (``python tests/fuzz_harness.py --seed S --episode K``).
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from fuzz_harness import CAR, fuzz, observable  # tests/ is on sys.path under pytest

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


@pytest.mark.parametrize("kind", ["identifier", "two_axle", "sampler", "model", "simulator", "function"])
def test_every_kind_of_object_is_fuzzed(kind: str) -> None:
    stats = fuzz(150, 1000, kinds=[kind])
    assert stats.calls >= 150


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

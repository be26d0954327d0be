"""Several rates, several clocks: the numerics that put a field log's channels on one grid.

Three pieces, each documented in ``docs/capabilities/field-logs.md``:

* :func:`nominal_interval`: a channel's sample interval as its nominal rate, not a float's
  noise: the mean of the intervals that are not gaps (so that jitter and time stamps
  quantized to 1 ms at 400 Hz, 2, 3, 2, 3 ms, average to 2.5 ms), rounded to whole
  microseconds (0.0049999999999954525 s -> 0.005 s).
* :func:`resample`: a channel at the times ``t0 + k dt (+ shift)``: split at gaps (an interval
  over 1.5 median intervals, or over the median plus 8 times the intervals' robust spread
  where stamps jitter; or a missing value); where the channel is faster than the
  grid, a linear-phase FIR low-pass (Kaiser-windowed sinc, 60 dB, pass band to 0.4 of the
  grid's rate, stop band from its Nyquist frequency) applied centred (zero phase); then
  cubic Hermite pieces with fourth-order slopes through the samples at their own times
  (jitter included), evaluated on the grid. Grid points outside every segment are NaN.
* :func:`estimate_delay`: how late the deflection is against the accelerometers, from the
  physics that ties them, ``d'' = a_body - a_wheel`` (``d = z_body - z_wheel``): both sides
  band-limited to 1-25 Hz and the deflection differentiated twice in the frequency domain,
  cross-correlated through the FFT, the correlation interpolated 16-fold in the frequency
  domain and its peak refined by a parabola. Its sign says the deflection's sign
  convention; its slope (about 1) checks the units.

numpy only (scipy is the tests' independent reference, not a dependency).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, List, Optional, Sequence, Tuple

import numpy as np
from numpy.typing import NDArray

__all__ = ["Delay", "SensorNoise", "body_ratios", "estimate_body_delay", "estimate_delay", "gap_limit",
           "kinematic_deflection_noise", "nominal_interval", "sensor_noise",
           "resample", "segments", "white_noise"]

#: An interval over this many nominal intervals is a gap.
GAP = 1.5
#: The band (Hz) in which the deflection and the accelerations are compared.
BAND = (1.0, 25.0)
#: Frequency-domain interpolation of the cross-correlation (its resolution is dt / UPSAMPLE).
UPSAMPLE = 16
#: At most this much data (s) enters the delay estimate (the longest stretch without gaps).
DELAY_SPAN = 120.0
#: The estimate needs at least this much data without gaps, s.
DELAY_MIN_SPAN = 10.0


def _jitter(d: NDArray[np.float64], med: float) -> float:
    """A robust spread of the intervals ``d`` around their median ``med`` (1.4826 MAD)."""
    return float(1.4826 * np.median(np.abs(d - med)))


def gap_limit(t: NDArray[np.float64]) -> float:
    """The interval (s) over which ``t`` has a gap: :data:`GAP` median intervals, or the
    median plus 8 times the intervals' robust spread where the times jitter (message
    stamps taken on arrival)."""
    d = np.diff(np.asarray(t, dtype=np.float64))
    d = d[d > 0]
    if len(d) == 0:
        return math.inf
    med = float(np.median(d))
    return max(GAP * med, med + 8.0 * _jitter(d, med))


def nominal_interval(t: NDArray[np.float64]) -> float:
    """The nominal sample interval (s) of increasing times ``t`` (s): the mean of the
    intervals within :func:`gap_limit` of the median either way (not gaps, not bunched
    samples), so that jitter and time stamps
    quantized to whole ms (2, 3, 2, 3 ms at 400 Hz) average out, rounded to a whole
    microsecond (to 10 ns under 100 us) so that a float's noise is not taken for the rate.
    NaN for fewer than two samples.

    >>> nominal_interval(np.arange(1000) * 0.005 + 1e5)
    0.005
    >>> nominal_interval(np.floor(np.arange(1001) * 2.5) * 1e-3)   # 400 Hz stamped in whole ms
    0.0025
    """
    d = np.diff(np.asarray(t, dtype=np.float64))
    d = d[d > 0]
    if len(d) == 0:
        return math.nan
    med, limit = float(np.median(d)), gap_limit(t)
    near = d[(d <= limit) & (d >= 2 * med - limit)]  # symmetric about the median: jitter averages out
    h = float(np.mean(near)) if len(near) else med
    grid = 1e-6 if h >= 1e-4 else 1e-8
    return max(grid, round(h / grid) * grid)


def segments(t: NDArray[np.float64], v: NDArray[np.float64], h: float) -> List[Tuple[int, int]]:
    """``[start, stop)`` index ranges of ``t`` without a gap (an interval over
    :func:`gap_limit`, at least :data:`GAP` nominal intervals ``h``) and without a missing
    (NaN) value."""
    ok = np.isfinite(v)
    breaks = np.flatnonzero(np.diff(t) > max(GAP * h, gap_limit(t))) + 1
    out: List[Tuple[int, int]] = []
    for a, b in zip(np.concatenate([[0], breaks]), np.concatenate([breaks, [len(t)]])):
        a, b = int(a), int(b)
        if b <= a:
            continue
        good = ok[a:b]
        if good.all():
            out.append((a, b))
            continue
        edges = np.flatnonzero(np.diff(np.concatenate([[False], good, [False]]).astype(np.int8)))
        out += [(a + int(s), a + int(e)) for s, e in zip(edges[::2], edges[1::2])]
    return out


#: Stop-band attenuation of the anti-aliasing filter, dB.
ATTENUATION = 60.0


def antialias_taps(h_in: float, dt_out: float) -> Optional[NDArray[np.float64]]:
    """The low-pass FIR taps for going from interval ``h_in`` to ``dt_out`` (s), or ``None``
    when the channel is not faster than the grid (no filter then): a Kaiser-windowed sinc
    (Kaiser's formulas for :data:`ATTENUATION` dB; the taps of ``scipy.signal.firwin`` with
    ``scipy.signal.kaiserord``), cut-off at 0.45 of the grid's rate, an odd number of taps
    (a whole-sample centre: zero phase when applied centred), unit gain at 0 Hz."""
    if h_in >= 0.99 * dt_out:
        return None
    fs_in, fs_out = 1.0 / h_in, 1.0 / dt_out
    width = 0.1 * fs_out / (0.5 * fs_in)          # 0.4 fs_out .. 0.5 fs_out, as a fraction of Nyquist
    a = ATTENUATION
    beta = 0.1102 * (a - 8.7) if a > 50 else 0.5842 * (a - 21) ** 0.4 + 0.07886 * (a - 21)
    numtaps = int(math.ceil((a - 7.95) / 2.285 / (math.pi * width) + 1)) | 1
    cutoff = 0.45 * fs_out / (0.5 * fs_in)        # as a fraction of Nyquist
    m = np.arange(numtaps) - (numtaps - 1) / 2
    taps = cutoff * np.sinc(cutoff * m) * np.kaiser(numtaps, beta)
    return np.asarray(taps / taps.sum(), dtype=np.float64)


def _lowpass(v: NDArray[np.float64], taps: NDArray[np.float64]) -> NDArray[np.float64]:
    half = len(taps) // 2
    if len(v) <= half:
        return v
    padded = np.pad(v, half, mode="reflect")
    return np.asarray(np.convolve(padded, taps, mode="valid"), dtype=np.float64)


def hermite(ts: NDArray[np.float64], vs: NDArray[np.float64], tk: NDArray[np.float64]) -> NDArray[np.float64]:
    """Values ``vs`` at increasing times ``ts`` interpolated at ``tk`` (within ``ts``' span)
    by cubic Hermite pieces whose slopes are fourth-order finite differences (the three-point
    derivative for unequal intervals, Richardson-combined with the five-point span): exact for
    cubics; a sine at 0.12 cycles per sample within 0.15 % (scipy's cubic spline: 0.09 %)."""
    n = len(ts)
    h = np.diff(ts)
    s = np.diff(vs) / h
    m = np.empty(n)
    m[0], m[-1] = s[0], s[-1]
    m[1:-1] = (s[:-1] * h[1:] + s[1:] * h[:-1]) / (h[:-1] + h[1:])
    if n >= 5:
        wide = (vs[4:] - vs[:-4]) / (ts[4:] - ts[:-4])
        m[2:-2] = (4.0 * m[2:-2] - wide) / 3.0
    i = np.clip(np.searchsorted(ts, tk, side="right") - 1, 0, n - 2)
    u = (tk - ts[i]) / h[i]
    h00 = (1 + 2 * u) * (1 - u) ** 2
    h10 = u * (1 - u) ** 2
    h01 = u * u * (3 - 2 * u)
    h11 = u * u * (u - 1)
    return np.asarray(h00 * vs[i] + h10 * h[i] * m[i] + h01 * vs[i + 1] + h11 * h[i] * m[i + 1], dtype=np.float64)


def resample(t: NDArray[np.float64], v: NDArray[np.float64], h: float, t0: float, dt: float, n: int,
             shift: float = 0.0) -> NDArray[np.float64]:
    """The channel ``(t, v)`` (s, any unit; NaN missing) of nominal interval ``h`` at the
    ``n`` times ``t0 + k dt + shift`` (s): anti-aliased where it is faster than ``dt``
    (:func:`antialias_taps`), interpolated by :func:`hermite` at its own sample times; NaN
    where no segment (see :func:`segments`) covers a time. A positive ``shift`` reads the
    channel later: it removes a delay of ``shift``."""
    out = np.full(n, math.nan)
    taps = antialias_taps(h, dt)
    grid_first = t0 + shift
    for a, b in segments(t, v, h):
        ts, vs = t[a:b], v[a:b]
        if taps is not None:
            vs = _lowpass(vs, taps)
        lo = max(0, math.ceil((ts[0] - grid_first) / dt - 1e-6))
        hi = min(n - 1, math.floor((ts[-1] - grid_first) / dt + 1e-6))
        if hi < lo:
            continue
        tk = np.clip(grid_first + np.arange(lo, hi + 1) * dt, ts[0], ts[-1])
        out[lo : hi + 1] = hermite(ts, vs, tk) if len(ts) >= 2 else vs[0]
    return out


@dataclass
class Delay:
    """What the deflection and the accelerometers say about each other."""

    #: How late the deflection is against the accelerations, s (NaN: cannot be estimated).
    delay: float
    #: The normalized cross-correlation at the peak (negative: the other sign convention).
    corr: float
    #: The regression slope of the deflection's second derivative on ``a_body - a_wheel`` at
    #: the peak (about 1 when both are in SI units; 1000 for a deflection in mm).
    slope: float
    #: Seconds of data the estimate used.
    span: float
    #: Why it could not be estimated ("" when it could).
    why: str = ""


def _longest_finite(y: NDArray[np.float64]) -> Tuple[int, int]:
    good = np.isfinite(y).all(axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[False], good, [False]]).astype(np.int8)))
    if len(edges) == 0:
        return 0, 0
    starts, stops = edges[::2], edges[1::2]
    i = int(np.argmax(stops - starts))
    return int(starts[i]), int(stops[i])


def _spectra(x: NDArray[np.float64], dt: float) -> Tuple[NDArray[np.complex128], NDArray[np.float64], int]:
    """The spectrum of ``x`` (mean removed, 5 % cosine tapers at both ends, zero-padded to a
    power of two at least twice its length), its frequencies (Hz) weighted by the band
    :data:`BAND` (raised-cosine edges: 0.5 Hz below, 5 Hz above), and the padded length."""
    n = len(x)
    size = 1 << int(math.ceil(math.log2(2 * n)))
    edge = max(1, n // 20)
    taper = np.ones(n)
    ramp = 0.5 - 0.5 * np.cos(np.pi * (np.arange(edge) + 0.5) / edge)
    taper[:edge], taper[n - edge :] = ramp, ramp[::-1]
    spec = np.fft.rfft((x - np.mean(x)) * taper, size)
    f = np.fft.rfftfreq(size, dt)
    lo, hi = BAND[0], min(BAND[1], 0.4 / dt)
    w = np.clip((f - (lo - 0.5)) / 0.5, 0, 1) * np.clip((hi + 5.0 - f) / 5.0, 0, 1)
    w = 0.5 - 0.5 * np.cos(np.pi * w)
    return np.asarray(spec * w, dtype=np.complex128), np.asarray(f, dtype=np.float64), size


def estimate_delay(a_body: NDArray[np.float64], a_wheel: NDArray[np.float64], deflection: NDArray[np.float64],
                   dt: float, max_lag: float = 0.1) -> Delay:
    """The deflection's delay against the accelerometers (s, positive: the deflection is
    late), from ``d'' = a_body - a_wheel`` on the longest stretch without gaps (at most
    :data:`DELAY_SPAN` s), the three on one grid of interval ``dt`` (s). Lags up to
    ``max_lag`` (s) either way are searched.

    >>> dt = 0.005; t = np.arange(40_000) * dt; rng = np.random.default_rng(1)
    >>> d = np.convolve(rng.standard_normal(len(t)), np.hanning(9), "same") * 1e-3
    >>> acc = np.gradient(np.gradient(d, dt), dt)            # a_body - a_wheel, a_wheel = 0
    >>> late = np.interp(t - 0.0031, t, d)                    # the deflection 3.1 ms late
    >>> round(estimate_delay(acc, 0 * acc, late, dt).delay * 1e3, 1)
    3.1
    """
    y = np.column_stack([a_body, a_wheel, deflection])
    a, b = _longest_finite(y)
    b = min(b, a + int(DELAY_SPAN / dt))
    span = (b - a) * dt
    if span < DELAY_MIN_SPAN:
        return Delay(math.nan, math.nan, math.nan, span,
                     f"{span:.1f} s without gaps, under the {DELAY_MIN_SPAN:g} s the estimate needs")
    acc, f, size = _spectra(y[a:b, 0] - y[a:b, 1], dt)
    d, _, _ = _spectra(y[a:b, 2], dt)
    d2 = -((2 * np.pi * f) ** 2) * d                          # the second derivative, in the band
    sxx = float(np.fft.irfft(np.abs(acc) ** 2, size)[0])      # sum of squares (lag 0 of the autocorrelation)
    syy = float(np.fft.irfft(np.abs(d2) ** 2, size)[0])
    if not (sxx > 0 and syy > 0):
        return Delay(math.nan, math.nan, math.nan, span, "a channel is constant")
    up = np.fft.irfft(np.conj(acc) * d2, size * UPSAMPLE) * UPSAMPLE   # lag k: k dt / UPSAMPLE (circular)
    reach = int(max_lag / dt * UPSAMPLE)
    lags = np.concatenate([np.arange(-reach, 0), np.arange(0, reach + 1)])
    c = up[lags] / math.sqrt(sxx * syy)
    i = int(np.argmax(np.abs(c)))
    frac = 0.0
    if 0 < i < len(c) - 1:
        y0, y1, y2 = abs(c[i - 1]), abs(c[i]), abs(c[i + 1])
        den = y0 - 2 * y1 + y2
        frac = 0.5 * (y0 - y2) / den if den != 0 else 0.0
    lag = (lags[i] + frac) * dt / UPSAMPLE
    peak = float(c[i])
    slope = peak * math.sqrt(syy / sxx)
    return Delay(float(lag), peak, slope, span)


def body_ratios(a_body: NDArray[np.float64], deflection: NDArray[np.float64], dt: float) -> Tuple[float, float]:
    """``(k2/M, b/M)`` (1/s^2, 1/s) of the body equation ``a_body = -(k2/M) d - (b/M) d'`` by
    least squares on the band-passed signals (the longest stretch without gaps, at most
    :data:`DELAY_SPAN` s; ``d'`` from the spectrum): a rough figure to check that a log and
    the named car belong together, not an estimate to report. NaN when there is too little
    data."""
    y = np.column_stack([a_body, deflection])
    a, b = _longest_finite(y)
    b = min(b, a + int(DELAY_SPAN / dt))
    if (b - a) * dt < DELAY_MIN_SPAN:
        return math.nan, math.nan
    n = b - a
    acc, f, size = _spectra(y[a:b, 0], dt)
    d, _, _ = _spectra(y[a:b, 1], dt)
    cols = [np.fft.irfft(x, size)[:n] for x in (acc, -d, -2j * np.pi * f * d)]
    theta, *_ = np.linalg.lstsq(np.column_stack(cols[1:]), cols[0], rcond=None)
    return float(theta[0]), float(theta[1])


#: The band (fractions of a channel's Nyquist frequency) where a deflection's spectrum is its
#: sensor's white noise: above the wheel hop the travel itself has fallen far below it.
NOISE_BAND = (0.6, 0.95)


def white_noise(t: NDArray[np.float64], v: NDArray[np.float64], h: float) -> float:
    """The standard deviation of the white noise on a channel (its unit, per sample at its own
    interval ``h``, s), from the level of its spectrum in :data:`NOISE_BAND` of its Nyquist
    frequency on the longest stretch without gaps (at most :data:`DELAY_SPAN` s): the median
    periodogram level there, divided by ln 2 (the median of an exponential variable), is
    ``2 sigma^2 h``. Meant for the deflection, whose travel is far below its sensor's noise
    there; an upper bound for a channel with content in that band. NaN under 1000 samples.

    >>> rng = np.random.default_rng(3); t = np.arange(20_000) * 0.005
    >>> round(white_noise(t, 0.01 * np.sin(2 * np.pi * 1.3 * t) + 3e-4 * rng.standard_normal(len(t)), 0.005), 5)
    0.0003
    """
    best = max(segments(t, v, h), key=lambda ab: ab[1] - ab[0], default=(0, 0))
    a, b = best[0], min(best[1], best[0] + int(DELAY_SPAN / h))
    if b - a < 1000:
        return math.nan
    x = v[a:b] - np.mean(v[a:b])
    n = len(x)
    power = np.abs(np.fft.rfft(x)) ** 2 * 2 * h / n
    f = np.fft.rfftfreq(n, h)
    nyquist = 0.5 / h
    band = (f > NOISE_BAND[0] * nyquist) & (f < NOISE_BAND[1] * nyquist)
    return math.sqrt(float(np.median(power[band])) / math.log(2.0) / (2 * h))


def estimate_body_delay(a_body: NDArray[np.float64], deflection: NDArray[np.float64], dt: float,
                        max_lag: float = 0.05, rounds: int = 10,
                        others: Sequence[NDArray[np.float64]] = ()) -> Delay:
    """The body accelerometer's delay against the deflection (s, positive: late), from the
    body equation ``a_body = -(k2/M) d - (b/M) d'`` on the longest stretch without gaps: the
    ratios fitted by least squares, ``a_body`` cross-correlated with their prediction from
    ``d`` (band-limited, 16-fold interpolated, parabola), ``a_body`` advanced by the lag found
    and the two steps repeated until the lag changes by under 10 us (a fit at the wrong lag
    absorbs part of it into ``b/M``). ``slope`` is the fitted k2/M (1/s^2). The three on one
    grid of interval ``dt`` (s). ``others``: the other axles' deflections (the half car: a
    body corner's acceleration is linear in both axles' deflections and rates, through ``1/M``
    and ``l^2/J``), regressors too."""
    y = np.column_stack([a_body, deflection, *others])
    a, b = _longest_finite(y)
    b = min(b, a + int(DELAY_SPAN / dt))
    span = (b - a) * dt
    if span < DELAY_MIN_SPAN:
        return Delay(math.nan, math.nan, math.nan, span,
                     f"{span:.1f} s without gaps, under the {DELAY_MIN_SPAN:g} s the estimate needs")
    n = b - a
    acc, f, size = _spectra(y[a:b, 0], dt)
    ds = [_spectra(y[a:b, j], dt)[0] for j in range(1, y.shape[1])]
    w = 2j * np.pi * f
    tau, peak = 0.0, math.nan
    theta: NDArray[np.float64] = np.zeros(2 * len(ds))
    reach = int(max_lag / dt * UPSAMPLE)
    lags = np.concatenate([np.arange(-reach, 0), np.arange(0, reach + 1)])
    for _ in range(rounds):
        advanced = acc * np.exp(w * tau)
        cols = [np.fft.irfft(x, size)[:n] for x in [advanced] + [c for d in ds for c in (-d, -w * d)]]
        fit, *_ = np.linalg.lstsq(np.column_stack(cols[1:]), cols[0], rcond=None)
        theta = np.asarray(fit, dtype=np.float64)
        pred = -sum((theta[2 * i] + theta[2 * i + 1] * w) * d for i, d in enumerate(ds))
        sxx = float(np.fft.irfft(np.abs(pred) ** 2, size)[0])
        syy = float(np.fft.irfft(np.abs(advanced) ** 2, size)[0])
        if not (sxx > 0 and syy > 0):
            return Delay(math.nan, math.nan, math.nan, span, "a channel is constant")
        c = np.fft.irfft(np.conj(pred) * advanced, size * UPSAMPLE)[lags] * UPSAMPLE / math.sqrt(sxx * syy)
        i = int(np.argmax(c))
        frac = 0.0
        if 0 < i < len(c) - 1:
            den = c[i - 1] - 2 * c[i] + c[i + 1]
            frac = 0.5 * (c[i - 1] - c[i + 1]) / den if den != 0 else 0.0
        step = (lags[i] + frac) * dt / UPSAMPLE
        tau += step
        peak = float(c[i])
        if abs(step) < 1e-5:
            break
    return Delay(float(tau), peak, float(theta[0]), span)


#: Accelerometer noise: the band (Hz) of the kinematic residual's fit (the deflection's noise,
#: twice differentiated, dominates above a few Hz; the relation is checked to 10 Hz).
KINEMATIC_BAND = (0.2, 1.0)
#: Accelerometer noise: the band (Hz) in which the sampled kinematic relation's two small
#: corrections are fitted.
KINEMATIC_FIT = (0.2, 20.0)
#: Accelerometer noise: the band (Hz) of the body equation's residual (its own noise is
#: comparable to the deflection noise's share only at low frequency).
BODY_BAND = (0.2, 2.0)
#: The deflection's noise: the band (fractions of the grid's Nyquist frequency) of the
#: kinematic residual where it dominates (within the resampler's pass band, 0.8).
DEFLECTION_BAND = (0.3, 0.7)
#: The body equation is fitted in windows this long (s), overlapping by half, and the body
#: accelerometer's noise is the mean of theirs, leaving out those over 5 times their median: a
#: change of the car (the monitor's events) spoils a window or two, not the estimate.
NOISE_WINDOW = 20.0
#: At most this much data (s) enters the noise estimate.
NOISE_SPAN = 600.0


@dataclass
class SensorNoise:
    """The accelerometers' white noise estimated from the data (:func:`sensor_noise`):
    standard deviations per sample at the grid's interval (m/s^2); NaN where it cannot be
    estimated (``why`` says why); ``span``: the seconds of data used."""

    a_body: float
    a_wheel: float
    span: float
    why: str = ""


def _numerov(x: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.asarray((x[2:] + 10.0 * x[1:-1] + x[:-2]) / 12.0, dtype=np.float64)


def _hann_spectra(cols: List[NDArray[np.float64]], dt: float,
                  band: Tuple[float, float]) -> Tuple[List[NDArray[np.complex128]], NDArray[np.float64], float]:
    """Hann-windowed spectra of ``cols`` (means removed) in ``band`` (Hz, at least 5 bins
    above 0), their angular frequencies, and the factor that makes ``|X|^2`` a one-sided
    periodogram over ``2 dt`` (a white noise of variance ``s^2`` has expectation ``s^2``)."""
    n = len(cols[0])
    w = np.hanning(n)
    f = np.fft.rfftfreq(n, dt)
    keep = (f >= max(band[0], 5.0 / (n * dt))) & (f <= band[1])
    out = [np.fft.rfft((c - np.mean(c)) * w)[keep] for c in cols]
    return out, np.asarray(2 * np.pi * f[keep], dtype=np.float64), 1.0 / float(np.sum(w * w))


def sensor_noise(a_body: NDArray[np.float64], a_wheel: NDArray[np.float64], deflection: NDArray[np.float64],
                 dt: float, sigma_d: Sequence[float], others: Sequence[NDArray[np.float64]] = ()) -> SensorNoise:
    """The body and wheel accelerometers' white noise (standard deviations per sample at the
    grid's interval ``dt``, s; m/s^2) from two relations the signals obey whatever the road,
    on the longest stretch without gaps (at most :data:`NOISE_SPAN` s), the channels on one
    grid with their delays removed; ``sigma_d``: the deflections' noise (m; ``deflection``'s,
    then ``others``', e.g. from :func:`kinematic_deflection_noise`; NaN: unknown, and then the
    body's noise is not estimated and the wheel's is an upper bound, ``sqrt(s_body^2 +
    s_wheel^2)``).

    1. The body equation: ``a_body`` is linear in the deflections and their rates (the quarter
       car: ``-(k2/M) d - (b/M) d'``; the half car: both axles', through ``1/M`` and
       ``l^2/J``; ``others`` are the other axles' deflections). Fitted by least squares in
       :data:`BODY_BAND` (rates by central differences), its residual is the sensors' noise,
       of spectrum ``s_body^2 + sum_i s_d,i^2 |t_i1 + i t_i2 sin(w dt) / dt|^2`` (per sample);
       ``s_body^2`` is the level that makes the periodogram's values, each exponential about
       that spectrum, most likely (the Whittle likelihood; P. Whittle, "The analysis of
       multiple stationary time series", J. R. Stat. Soc. B 15, 1953; D. B. Percival and A. T.
       Walden, *Spectral Analysis for Physical Applications*, 1993, sec. 6.6).
    2. The kinematics, ``d'' = a_body - a_wheel`` (``d = z_body - z_wheel``; any suspension).
       Sampled, ``(d[k+1] - 2 d[k] + d[k-1]) / dt^2 = x[k] + a (x[k+1] - 2 x[k] + x[k-1]) + c
       a_wheel[k]`` with ``x = a_body - a_wheel``: ``a`` is the interpolation between samples
       (1/12 for smooth signals, Numerov's; 1/6 for a road input linear between samples) and
       ``c`` the ``dt^2/12`` term of the wheel's own stiffness (``-(k1/m) dt^2 / 12``), both fitted
       by least squares in :data:`KINEMATIC_FIT`. Its residual's spectrum in
       :data:`KINEMATIC_BAND` (below 1 Hz the twice-differentiated deflection noise is small)
       is ``s_body^2 h^2 + s_wheel^2 (h - c)^2 + s_d^2 F^2``, ``h = 1 - a (2 - 2 cos w dt)``,
       ``F = (2 - 2 cos w dt) / dt^2``: ``s_wheel^2`` by the same likelihood.

    Assumptions: white noise, independent between sensors; the relations exact up to it (a
    linear spring and damper for the body equation: a nonlinear damper leaves part of the
    signal in the residual and over-estimates ``s_body``); the channels aligned (a residual
    delay ``tau`` leaves ``w tau`` of the signal); the body's and the wheel's noise at the
    grid's rate (a channel slower than the grid has none above its own Nyquist frequency, but
    the bands here are far below). NaN (and ``why``) under :data:`DELAY_MIN_SPAN` s of data.
    Within 20 % of the simulated sensors' noise, 0.3-3 times the defaults, on 300 s drives of the
    quarter and the half car (tests/test_field_logs.py).

    >>> dt = 0.005; n = 40_000; rng = np.random.default_rng(2)
    >>> d = np.convolve(rng.standard_normal(n), np.hanning(41), "same") * 2e-4   # the travel
    >>> acc = np.gradient(np.gradient(d, dt), dt)                                # its d''
    >>> ab = -70 * d - 5 * np.gradient(d, dt)                                    # the body equation
    >>> s = sensor_noise(ab + 0.02 * rng.standard_normal(n), ab - acc + 0.1 * rng.standard_normal(n),
    ...                  d + 3e-4 * rng.standard_normal(n), dt, [3e-4])
    >>> round(s.a_body / 0.02, 1), round(s.a_wheel / 0.1, 1)
    (1.0, 1.0)
    """
    y = np.column_stack([a_body, a_wheel, deflection, *others])
    a, b = _longest_finite(y)
    b = min(b, a + int(NOISE_SPAN / dt))
    span = (b - a) * dt
    nan = math.nan
    if span < DELAY_MIN_SPAN:
        return SensorNoise(nan, nan, span, f"{span:.1f} s without gaps, under the {DELAY_MIN_SPAN:g} s the "
                           "estimate needs")
    y = y[a:b]
    sd2 = [float(v) ** 2 for v in sigma_d]
    # (2) the body equation's residual, window by window: the body accelerometer's noise
    body = all(math.isfinite(v) for v in sd2)
    sb2 = 0.0
    if body:
        step = int(round(NOISE_WINDOW / dt))
        starts = range(0, len(y) - step + 1, step // 2) if len(y) >= 2 * step else range(1)
        levels = [_body_level(y[k : k + step] if len(y) >= 2 * step else y, dt, sd2) for k in starts]
        levels = [v for v in levels if math.isfinite(v)]
        if not levels:
            return SensorNoise(nan, nan, span, "too short for the noise's spectrum")
        typical = float(np.median(levels))
        sb2 = float(np.mean([v for v in levels if v <= 5.0 * typical]))  # a window a change spoils left out
    # (1) the kinematic residual: the wheel accelerometer's
    spec, w, scale, taps = _kinematic(y[:, 0], y[:, 1], y[:, 2], dt, KINEMATIC_BAND)
    p = np.abs(spec[0] - np.column_stack(spec[1:]) @ taps) ** 2 * scale
    hx = 1.0 - taps[0] * (2.0 - 2.0 * np.cos(w * dt))      # the accelerations' weighting [-a, 1 + 2 a, -a]
    fw = (2.0 - 2.0 * np.cos(w * dt)) / dt**2              # the deflection's second difference
    sw2 = _level(p, (sd2[0] if math.isfinite(sd2[0]) else 0.0) * fw**2 + sb2 * hx**2, (hx - taps[1]) ** 2)
    if not body:
        return SensorNoise(nan, math.sqrt(sw2) if sw2 > 0 else nan, span,
                           "the deflection's noise unknown: the body's not estimated, the wheel's an upper bound")
    return SensorNoise(math.sqrt(sb2) if sb2 > 0 else nan, math.sqrt(sw2) if sw2 > 0 else nan, span,
                       "" if sb2 > 0 and sw2 > 0 else "the residuals leave no accelerometer noise")


def _body_level(y: NDArray[np.float64], dt: float, sd2: Sequence[float]) -> float:
    """The body accelerometer's noise variance from the body equation's residual on ``y``
    (columns ``a_body, a_wheel, deflection, other deflections``; :func:`sensor_noise`, step 1)."""
    defl = [y[:, j] for j in range(2, y.shape[1])]
    cols = [y[1:-1, 0]] + [c for v in defl for c in (v[1:-1], (v[2:] - v[:-2]) / (2 * dt))]
    spec, w, scale = _hann_spectra(cols, dt, BODY_BAND)
    if len(w) < 4 * len(defl):
        return math.nan
    reg = np.column_stack(spec[1:])
    theta = np.linalg.lstsq(np.vstack([reg.real, reg.imag]), -np.concatenate([spec[0].real, spec[0].imag]),
                            rcond=None)[0]
    # the fit takes len(theta) of the 2 len(w) real degrees of freedom: the residual's expectation
    p = np.abs(spec[0] + reg @ theta) ** 2 * scale * (2 * len(w)) / (2 * len(w) - len(theta))
    known = sum(s2 * (theta[2 * i] ** 2 + (theta[2 * i + 1] * np.sin(w * dt) / dt) ** 2) for i, s2 in enumerate(sd2))
    return _level(p, known)


def _kinematic(a_body: NDArray[np.float64], a_wheel: NDArray[np.float64], d: NDArray[np.float64], dt: float,
               band: Tuple[float, float]) -> Tuple[List[NDArray[np.complex128]], NDArray[np.float64], float,
                                                   NDArray[np.float64]]:
    """The sampled kinematic relation's spectra in ``band`` (Hz; :func:`_hann_spectra`):
    ``[target, regressors]`` with ``target = (d[k+1] - 2 d[k] + d[k-1]) / dt^2 - x[k]``,
    ``x = a_body - a_wheel``, the regressors ``x[k+1] - 2 x[k] + x[k-1]`` and ``a_wheel[k]``,
    and their two coefficients fitted by least squares in :data:`KINEMATIC_FIT` (within the
    grid's 0.4 of its rate)."""
    x = a_body - a_wheel
    target = (d[2:] - 2.0 * d[1:-1] + d[:-2]) / dt**2 - x[1:-1]
    regs = [x[2:] - 2.0 * x[1:-1] + x[:-2], a_wheel[1:-1]]
    spec, _, _ = _hann_spectra([target, *regs], dt, (KINEMATIC_FIT[0], min(KINEMATIC_FIT[1], 0.2 / dt)))
    reg = np.column_stack(spec[1:])
    taps = np.linalg.lstsq(np.vstack([reg.real, reg.imag]), np.concatenate([spec[0].real, spec[0].imag]),
                           rcond=None)[0]
    out, w, scale = _hann_spectra([target, *regs], dt, band)
    return out, w, scale, np.asarray(taps, dtype=np.float64)


def kinematic_deflection_noise(a_body: NDArray[np.float64], a_wheel: NDArray[np.float64],
                               deflection: NDArray[np.float64], dt: float) -> float:
    """The deflection sensor's white noise (m per sample at the grid's interval ``dt``, s)
    from the residual of the sampled kinematic relation (:func:`sensor_noise`, step 1) in
    :data:`DEFLECTION_BAND` of the grid's Nyquist frequency, where the deflection's noise,
    differentiated twice, is thousands of times the accelerometers' and the relation's own
    error: unlike the deflection's spectrum floor (:func:`white_noise`), the road's travel
    there does not count. On the longest stretch without gaps (at most :data:`NOISE_SPAN` s);
    NaN under :data:`DELAY_MIN_SPAN` s. For channels at least as fast as the grid (a slower
    one has no noise above its own Nyquist frequency on the grid)."""
    y = np.column_stack([a_body, a_wheel, deflection])
    a, b = _longest_finite(y)
    b = min(b, a + int(NOISE_SPAN / dt))
    if (b - a) * dt < DELAY_MIN_SPAN:
        return math.nan
    y = y[a:b]
    nyquist = 0.5 / dt
    spec, w, scale, taps = _kinematic(y[:, 0], y[:, 1], y[:, 2], dt,
                                      (DEFLECTION_BAND[0] * nyquist, DEFLECTION_BAND[1] * nyquist))
    p = np.abs(spec[0] - np.column_stack(spec[1:]) @ taps) ** 2 * scale
    fw = (2.0 - 2.0 * np.cos(w * dt)) / dt**2
    return math.sqrt(_level(p, 0.0, fw**2))


def _level(p: NDArray[np.float64], known: Any, g: Any = 1.0) -> float:
    """The constant ``c >= 0`` with ``E[p] = c g + known`` (periodogram levels ``p``, each
    exponential about its mean): the Whittle likelihood's root, by bisection."""
    def score(c: float) -> float:
        m = c * g + known
        return float(np.sum(g * (p - m) / (m * m)))

    if not np.any(known):
        return float(np.mean(p / g))                        # the likelihood's root in closed form
    lo, hi = 0.0, max(float(np.mean(p)), 1e-300)
    if score(lo) <= 0:
        return 0.0
    while score(hi) > 0:
        hi *= 2.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if score(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)

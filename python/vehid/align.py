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
from typing import List, Optional, Tuple

import numpy as np
from numpy.typing import NDArray

__all__ = ["Delay", "body_ratios", "estimate_body_delay", "estimate_delay", "gap_limit", "nominal_interval",
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
                        max_lag: float = 0.05, rounds: int = 10) -> Delay:
    """The body accelerometer's delay against the deflection (s, positive: late), from the
    body equation ``a_body = -(k2/M) d - (b/M) d'`` on the longest stretch without gaps: the
    ratios fitted by least squares, ``a_body`` cross-correlated with their prediction from
    ``d`` (band-limited, 16-fold interpolated, parabola), ``a_body`` advanced by the lag found
    and the two steps repeated until the lag changes by under 10 us (a fit at the wrong lag
    absorbs part of it into ``b/M``). ``slope`` is the fitted k2/M (1/s^2). The three on one
    grid of interval ``dt`` (s)."""
    y = np.column_stack([a_body, deflection])
    a, b = _longest_finite(y)
    b = min(b, a + int(DELAY_SPAN / dt))
    span = (b - a) * dt
    if span < DELAY_MIN_SPAN:
        return Delay(math.nan, math.nan, math.nan, span,
                     f"{span:.1f} s without gaps, under the {DELAY_MIN_SPAN:g} s the estimate needs")
    n = b - a
    acc, f, size = _spectra(y[a:b, 0], dt)
    d, _, _ = _spectra(y[a:b, 1], dt)
    w = 2j * np.pi * f
    tau, peak = 0.0, math.nan
    theta: NDArray[np.float64] = np.zeros(2)
    reach = int(max_lag / dt * UPSAMPLE)
    lags = np.concatenate([np.arange(-reach, 0), np.arange(0, reach + 1)])
    for _ in range(rounds):
        advanced = acc * np.exp(w * tau)
        cols = [np.fft.irfft(x, size)[:n] for x in (advanced, -d, -w * d)]
        fit, *_ = np.linalg.lstsq(np.column_stack(cols[1:]), cols[0], rcond=None)
        theta = np.asarray(fit, dtype=np.float64)
        pred = -(theta[0] + theta[1] * w) * d
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

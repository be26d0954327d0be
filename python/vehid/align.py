"""Several rates, several clocks: the numerics that put a field log's channels on one grid.

Three pieces, each documented in ``docs/capabilities/field-logs.md``:

* :func:`nominal_interval`: a channel's sample interval as its nominal rate, not a float's
  noise: the mean of the intervals that are not gaps (so that jitter and time stamps
  quantized to 1 ms at 400 Hz, 2, 3, 2, 3 ms, average to 2.5 ms), rounded to whole
  microseconds (0.0049999999999954525 s -> 0.005 s).
* :func:`resample`: a channel at the times ``t0 + k dt (+ shift)``: split at gaps (an interval
  over 1.5 median intervals, or over the median plus 8 times the intervals' robust spread
  where stamps jitter; or a missing value); where the channel is faster than the
  grid, a linear-phase FIR low-pass (Kaiser window, 60 dB, pass band to 0.4 of the grid's
  rate, stop band from its Nyquist frequency) applied forwards and centred (zero phase); then
  a cubic spline through the samples at their own times (jitter included) evaluated on the
  grid. Grid points outside every segment are NaN: missing.
* :func:`estimate_delay`: how late the deflection is against the accelerometers, from the
  physics that ties them, ``d'' = a_body - a_wheel`` (``d = z_body - z_wheel``): both sides
  band-passed (1-25 Hz, zero phase), cross-correlated through the FFT, the correlation
  interpolated 16-fold in the frequency domain and its peak refined by a parabola. Its
  sign says the deflection's sign convention; its slope (about 1) checks the units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np
from numpy.typing import NDArray

__all__ = ["Delay", "body_ratios", "estimate_delay", "gap_limit", "nominal_interval", "resample", "segments"]

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
    intervals that are not gaps (:func:`gap_limit`), so that jitter and time stamps
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
    near = d[d <= gap_limit(t)]
    h = float(np.mean(near)) if len(near) else float(np.median(d))
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


def antialias_taps(h_in: float, dt_out: float) -> Optional[NDArray[np.float64]]:
    """The low-pass FIR taps for going from interval ``h_in`` to ``dt_out`` (s), or ``None``
    when the channel is not faster than the grid (no filter then)."""
    if h_in >= 0.99 * dt_out:
        return None
    from scipy import signal

    fs_in, fs_out = 1.0 / h_in, 1.0 / dt_out
    width = 0.1 * fs_out / (0.5 * fs_in)          # 0.4 fs_out .. 0.5 fs_out, as a fraction of Nyquist
    numtaps, beta = signal.kaiserord(60.0, width)
    numtaps |= 1                                  # odd: a whole-sample centre, zero phase
    taps = signal.firwin(numtaps, 0.45 * fs_out, window=("kaiser", beta), fs=fs_in)
    return np.asarray(taps, dtype=np.float64)


def _lowpass(v: NDArray[np.float64], taps: NDArray[np.float64]) -> NDArray[np.float64]:
    half = len(taps) // 2
    if len(v) <= half:
        return v
    padded = np.pad(v, half, mode="reflect")
    return np.asarray(np.convolve(padded, taps, mode="valid"), dtype=np.float64)


def resample(t: NDArray[np.float64], v: NDArray[np.float64], h: float, t0: float, dt: float, n: int,
             shift: float = 0.0) -> NDArray[np.float64]:
    """The channel ``(t, v)`` (s, any unit; NaN missing) of nominal interval ``h`` at the
    ``n`` times ``t0 + k dt + shift`` (s): anti-aliased where it is faster than ``dt``, by a
    cubic spline through its samples; NaN where no segment (see :func:`segments`) covers a
    time. A positive ``shift`` reads the channel later: it removes a delay of ``shift``."""
    from scipy.interpolate import CubicSpline

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
        if len(ts) >= 4:
            out[lo : hi + 1] = CubicSpline(ts, vs, bc_type="not-a-knot")(tk)
        elif len(ts) >= 2:
            out[lo : hi + 1] = np.interp(tk, ts, vs)
        else:
            out[lo : hi + 1] = vs[0]
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


def _bandpassed(x: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
    from scipy import signal

    hi = min(BAND[1], 0.4 / dt)
    sos = signal.butter(4, [BAND[0], hi], btype="bandpass", fs=1.0 / dt, output="sos")
    return np.asarray(signal.sosfiltfilt(sos, x), dtype=np.float64)


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
    acc = _bandpassed(y[a:b, 0] - y[a:b, 1], dt)
    d2 = _bandpassed(np.gradient(np.gradient(y[a:b, 2], dt), dt), dt)
    n = len(acc)
    sxx, syy = float(acc @ acc), float(d2 @ d2)
    if sxx <= 0 or syy <= 0:
        return Delay(math.nan, math.nan, math.nan, span, "a channel is constant")
    size = 1 << int(math.ceil(math.log2(2 * n)))
    cross = np.conj(np.fft.rfft(acc, size)) * np.fft.rfft(d2, size)
    up = np.fft.irfft(cross, size * UPSAMPLE) * UPSAMPLE       # lag k: k dt / UPSAMPLE (circular)
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
    :data:`DELAY_SPAN` s): a rough figure to check that a log and the named car belong
    together, not an estimate to report. NaN when there is too little data."""
    y = np.column_stack([a_body, deflection])
    a, b = _longest_finite(y)
    b = min(b, a + int(DELAY_SPAN / dt))
    if (b - a) * dt < DELAY_MIN_SPAN:
        return math.nan, math.nan
    acc = _bandpassed(y[a:b, 0], dt)
    d = _bandpassed(y[a:b, 1], dt)
    dd = _bandpassed(np.gradient(y[a:b, 1], dt), dt)
    theta, *_ = np.linalg.lstsq(np.column_stack([-d, -dd]), acc, rcond=None)
    return float(theta[0]), float(theta[1])

"""What the fuzzers share (``tests/fuzz_harness.py`` and its newer surfaces,
``tests/fuzz_surfaces.py``): the exceptions a call may raise, :class:`Failure`,
:func:`attempt`, the short descriptions of arguments, and an identifier's observable state.
A module of its own so that both import the same :class:`Failure` when the harness runs as a
script."""

from __future__ import annotations

from typing import Any, Callable, Dict, List, Tuple

import numpy as np

import vehid

#: What a call may raise. numpy's ComplexWarning appears when warnings are errors (as under
#: pytest, and in this script): a complex scalar passed as a float option goes through its
#: ``__float__``, which warns; under the error filter the call is refused before anything
#: happens.
ALLOWED: Tuple[type, ...] = (vehid.VehidError, ValueError, TypeError, OverflowError, MemoryError,
                             np.exceptions.ComplexWarning)


class Failure(AssertionError):
    """A property violated: a panic, a foreign exception, or a rejected call that changed
    state."""


def attempt(func: Callable[..., Any], *args: Any, **kwargs: Any) -> Tuple[bool, Any]:
    """``(True, result)`` or ``(False, exception)``; raises :class:`Failure` on a panic or an
    exception outside :data:`ALLOWED`."""
    try:
        return True, func(*args, **kwargs)
    except BaseException as e:  # noqa: B036 - PanicException derives from BaseException
        if isinstance(e, (KeyboardInterrupt, SystemExit)):
            raise
        if type(e).__name__ == "PanicException" or not isinstance(e, ALLOWED):
            raise Failure(f"{type(e).__name__} from {getattr(func, '__qualname__', func)!r} "
                          f"({describe(args)}; {describe_kw(kwargs)}): {e}") from e
        return False, e


def describe_one(a: Any) -> str:
    if isinstance(a, np.ndarray):
        if a.dtype.kind in "fc" and a.size:
            with np.errstate(all="ignore"):
                return f"{a.dtype}{a.shape} max|.|={np.max(np.abs(a)):.3g}"
        return f"{a.dtype}{a.shape}"
    return repr(a)[:60]


def describe(args: Tuple[Any, ...]) -> str:
    """Short text for arguments (arrays by dtype and shape, with their largest magnitude)."""
    return ", ".join(describe_one(a) for a in args)


def describe_kw(kw: Dict[str, Any]) -> str:
    return ", ".join(f"{k}={describe_one(v)}" for k, v in kw.items())


#: The observable state (``storage_bytes`` is not part of it: it is the capacity of a batch's
#: storage, which a rejected ``fit`` may have grown, and a copy trims).
OBSERVED = ("theta", "samples", "covariance", "r", "trace", "gated", "reinit_count", "paired")


def observable(ident: Any) -> Tuple[Any, ...]:
    """Everything a rejected call must leave bit for bit: θ̂ (or the error reading it), the
    sample count, and P, R, tr P, the gated and reinitialization counts and the paired samples
    where the identifier has them. Arrays by dtype, shape and bytes (NaN compares equal to
    itself, -0.0 differs from 0.0)."""
    out: List[Any] = []
    for name in OBSERVED:
        if not hasattr(type(ident), name):
            continue
        try:
            v = getattr(ident, name)
        except ValueError as e:
            out.append((name, type(e).__name__, str(e)))
            continue
        if isinstance(v, np.ndarray):
            out.append((name, v.dtype.str, v.shape, v.tobytes()))
        elif isinstance(v, float):
            out.append((name, np.float64(v).tobytes()))
        else:
            out.append((name, repr(v)))
    return tuple(out)


def summary(obs: Tuple[Any, ...]) -> str:
    return "; ".join(f"{o[0]}={o[-1][:40]!r}" if isinstance(o[-1], (bytes, str)) else repr(o)[:60] for o in obs)

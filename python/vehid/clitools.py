"""What every command of the ``vehid`` command line shares: the user error :class:`CliError`
(one line on stderr, exit status 2), writing ``-o`` outputs (:func:`write_output`,
:func:`stdout`), simulating in chunks (:func:`run_chunks`), the built-in models, and the
argparse types of the options (:func:`count`, :func:`positive_float`, :func:`parse_floats`,
:func:`delimiter`, :func:`model_arg`).

:data:`CHUNK` and :data:`PROGRESS_ABOVE` are read when a command runs, from this module: set
them here (``vehid.clitools.CHUNK = ...``) to change them.

The states are named once, in :data:`vehid.io.STATES`; messages show them as
:func:`quantity` does:

>>> quantity("quarter", "x2"), quantity("half", "dx8")
('x2 (wheel_vel, m/s)', 'dx8 (d_pitch_rate, rad/s^2)')
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from typing import IO, Callable, Dict, Iterator, List, Optional, Union

from ._vehid import FullCar, HalfCar, LinearModel, QuarterCar, Run, Simulator
from .io import WHITESPACE, Column, run_columns

#: Samples simulated, or read, per chunk.
CHUNK = 100_000
#: Runs longer than this report their progress on stderr.
PROGRESS_ABOVE = 200_000


def full_car(**constants: float) -> FullCar:
    """The full car ``--model full`` names: the documented passenger car
    (:meth:`vehid.FullCar.passenger`), or the car of ``constants`` (every one)."""
    return FullCar(**constants) if constants else FullCar.passenger()


MODELS: dict[str, Callable[..., LinearModel]] = {"quarter": QuarterCar, "half": HalfCar, "full": full_car}
#: What ``vehid identify`` calls each model in its messages.
MODEL_NAMES = {"quarter": "quarter car", "half": "half car", "full": "full car"}


class CliError(Exception):
    """A user error the command line reports in one line (exit status 2)."""


def model_columns(name: str) -> Dict[str, Column]:
    """The columns of a run of the built-in model ``name``, by their api.md name."""
    model = MODELS[name]()
    return {c.name: c for c in run_columns(name, model.n_states, model.n_inputs)}


def quantity(model: str, column: str) -> str:
    """``"x1 (wheel_pos, m)"``: a column of ``model``'s runs as every message shows it."""
    return model_columns(model)[column].describe()


def run_chunks(
    sim: Simulator, n: int, progress: Optional[IO[str]] = None, chunk: Optional[int] = None
) -> Iterator[Run]:
    """Simulates ``n`` samples in chunks of at most ``chunk`` (default :data:`CHUNK`),
    yielding each ``Run``.

    When ``progress`` is given and ``n`` exceeds :data:`PROGRESS_ABOVE`, a line per chunk
    reports how far the simulation is.
    """
    step_max = CHUNK if chunk is None else chunk
    done = 0
    while done < n:
        step = min(step_max, n - done)
        yield sim.run(step)
        done += step
        if progress is not None and n > PROGRESS_ABOVE:
            print(f"vehid: simulated {done}/{n} samples ({100 * done // n}%)", file=progress, flush=True)


def _open_output(path: str) -> IO[str]:
    try:
        return open(path, "w", encoding="ascii", newline="\n")
    except IsADirectoryError:
        raise CliError(f"-o {path}: is a directory; give a file name (or - for stdout)") from None
    except FileNotFoundError:
        raise CliError(f"-o {path}: no such directory: {os.path.dirname(path) or '.'}") from None
    except OSError as e:
        raise CliError(f"-o {path}: cannot create ({e.strerror or e})") from None


def stdout() -> IO[str]:
    """Standard output for ``-o -``; an error when the command started with it closed (``>&-``)."""
    if sys.stdout is None:
        raise CliError("-o -: standard output is closed")
    return sys.stdout


def write_output(path: str, write: Callable[[IO[str]], None], remove_partial: bool = False) -> None:
    """``write(out)`` to ``-o path``: standard output for ``-`` (a closed pipe or a full disk:
    main() reports it, as for every command), else a new file, closed; a write error there is
    one CliError line (the partial file removed when ``remove_partial``)."""
    if path == "-":
        out = stdout()
        write(out)
        out.flush()
        return
    out = _open_output(path)
    try:
        write(out)
        out.close()
    except OSError as e:
        _close_quietly(out)
        removed = ""
        if remove_partial and os.path.isfile(path):
            try:
                os.remove(path)
                removed = "; removed the partial file"
            except OSError:
                pass
        raise CliError(f"-o {path}: cannot write ({e.strerror or e}){removed}") from None
    except BaseException:
        _close_quietly(out)
        raise


def _close_quietly(f: IO[str]) -> None:
    try:
        f.close()
    except OSError:  # the flush of what is left fails the same way
        pass


def parse_floats(text: str) -> Union[float, List[float]]:
    """``"1000"`` -> 1000.0; ``"1000,8"`` -> [1000.0, 8.0] (one value per unknown row).

    >>> parse_floats("1000"), parse_floats("1000, 8")
    (1000.0, [1000.0, 8.0])
    >>> parse_floats("1e3,x")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: expected a number or comma-separated numbers, got '1e3,x'
    """
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or comma-separated numbers, got {text!r}") from None
    return values[0] if len(values) == 1 else values


def positive_float(text: str) -> float:
    """An argparse type: a finite number > 0 (masses, ``--dt``, ``--speed``, ``--bandwidth``, ...;
    argparse names the option in its message).

    >>> positive_float("1.5")
    1.5
    >>> positive_float("0")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: expected a finite number > 0, got '0'
    """
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return v


def count(minimum: int) -> Callable[[str], int]:
    """An argparse type: a whole number ``>= minimum``.

    >>> at_least_2 = count(2)
    >>> at_least_2("40000")
    40000
    >>> at_least_2("1")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: expected a whole number >= 2, got 1
    """

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if v < minimum:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {minimum}, got {v}")
        return v

    return parse


_DELIMITER_NAMES = {"comma": ",", "semicolon": ";", "tab": "\t", "\\t": "\t", "pipe": "|",
                    "space": WHITESPACE, "spaces": WHITESPACE, "whitespace": WHITESPACE, " ": WHITESPACE}


def delimiter(text: str) -> str:
    """An argparse type: ``,`` ``;`` ``tab`` ``|`` ``space`` (runs of spaces or tabs), or
    another single punctuation character.

    >>> delimiter("Tab"), delimiter(";"), delimiter("space") == WHITESPACE
    ('\\t', ';', True)
    >>> delimiter("x")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: expected one of , ; tab | space (or another punctuation character), got 'x'
    """
    d = _DELIMITER_NAMES.get(text.lower(), text)
    if d == WHITESPACE or (len(d) == 1 and (d in ",;\t|" or (not d.isalnum() and d not in ".+-\"'#_ \r\n"))):
        return d
    raise argparse.ArgumentTypeError("expected one of , ; tab | space (or another punctuation character), "
                                     f"got {text!r}")


def model_arg(text: str) -> str:
    """``--model`` of simulate and identify: a built-in model or a model file.

    >>> model_arg("half"), model_arg("rig.toml")
    ('half', 'rig.toml')
    >>> model_arg("car")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: invalid choice: 'car' (choose from full, half, quarter, or a model file NAME.toml)
    """
    if text in MODELS or text.endswith(".toml"):
        return text
    raise argparse.ArgumentTypeError(
        f"invalid choice: {text!r} (choose from {', '.join(sorted(MODELS))}, or a model file NAME.toml)"
    )

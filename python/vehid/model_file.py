"""Model files: a :class:`vehid.Structure` and its data columns in TOML.

``vehid identify data.csv --model rig.toml`` reads::

    states = ["q", "v"]
    inputs = ["tau"]

    [equations]            # identified: d(state)/dt = ...
    v = "a*tau - b*v - c*sign(v) - d"

    [known]                # optional, parameter-free (for simulation)
    q = "v"

    [columns]              # optional: file column for a name (default: the name itself)
    q = "pos_m"
    v = "vel_mps"
    dv = "acc_mps2"        # the measured derivative of state v (default column: d<state>)
    tau = "force_N"
    t = "time_s"           # optional time column (checked for monotonic time)

Which derivative columns are read: those of the identified states and of every state used
as ``der(state)``; the others are not needed.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Tuple

from ._vehid import Structure, VehidError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python < 3.11
    import tomli as tomllib

_SECTIONS = {"states", "inputs", "equations", "known", "columns", "parameters"}
_DER = re.compile(r"\bder\s*\(\s*([A-Za-z_][A-Za-z0-9_]*)\s*\)")


class ModelFileError(ValueError):
    """A model file that cannot be used: the message names the file, the entry and the fix."""


@dataclass
class ModelFile:
    """A loaded model file: the structure, and for every name the file column it reads."""

    path: str
    structure: Structure
    #: State name -> column of its measured value.
    x: Dict[str, str] = field(default_factory=dict)
    #: State name -> column of its measured derivative (only the derivatives the model reads).
    dx: Dict[str, str] = field(default_factory=dict)
    #: Input name -> column.
    u: Dict[str, str] = field(default_factory=dict)
    #: The time column, if any.
    t: Optional[str] = None


def _names(doc: Dict[str, Any], key: str, path: str, required: bool) -> List[str]:
    v = doc.get(key, [] if not required else None)
    if v is None:
        raise ModelFileError(f"{path}: `{key}` is missing: add e.g. {key} = [\"x\", \"v\"]")
    if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
        raise ModelFileError(f"{path}: `{key}` must be a list of names, e.g. {key} = [\"x\", \"v\"]")
    return v


def _table(doc: Dict[str, Any], key: str, path: str) -> Dict[str, str]:
    v = doc.get(key, {})
    if not isinstance(v, dict) or not all(isinstance(t, str) for t in v.values()):
        raise ModelFileError(f"{path}: [{key}] must map names to strings, e.g. v = \"-a*v + b*u\"")
    return v


def load(path: str) -> ModelFile:
    """Reads and checks ``path``; every problem is a :class:`ModelFileError` (one line)."""
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except FileNotFoundError:
        raise ModelFileError(f"{path}: no such model file") from None
    except IsADirectoryError:
        raise ModelFileError(f"{path}: is a directory, not a model file") from None
    except OSError as e:
        raise ModelFileError(f"{path}: cannot read ({e.strerror or e})") from None
    except UnicodeDecodeError as e:
        utf16 = e.object[:2] in (b"\xff\xfe", b"\xfe\xff")
        fix = "it is UTF-16: convert it (iconv -f UTF-16 -t UTF-8)" if utf16 else "save it as UTF-8 text"
        raise ModelFileError(f"{path} is not a UTF-8 TOML model file (byte 0x{e.object[e.start]:02x} at offset "
                             f"{e.start}): {fix}") from None
    except tomllib.TOMLDecodeError as e:
        raise ModelFileError(f"{path}: not valid TOML: {e}") from None
    unknown = sorted(set(doc) - _SECTIONS)
    if unknown:
        raise ModelFileError(
            f"{path}: unknown entr{'y' if len(unknown) == 1 else 'ies'} {', '.join(unknown)} "
            f"(a model file has {', '.join(sorted(_SECTIONS))})"
        )
    states = _names(doc, "states", path, True)
    inputs = _names(doc, "inputs", path, False)
    equations = _table(doc, "equations", path)
    known = _table(doc, "known", path)
    columns = _table(doc, "columns", path)
    params = _names(doc, "parameters", path, False) if "parameters" in doc else None
    try:
        s = Structure(states, inputs, equations, known, params)
    except VehidError as e:
        raise ModelFileError(f"{path}: {e}") from None
    der = {m.group(1) for text in equations.values() for m in _DER.finditer(text)}
    read_dx = [st for st in states if st in equations or st in der]
    allowed = set(states) | set(inputs) | {f"d{st}" for st in states} | {"t"}
    bad = sorted(set(columns) - allowed)
    if bad:
        raise ModelFileError(
            f"{path}: [columns] has {', '.join(bad)}, which is not a state, d<state>, input or t "
            f"(states: {', '.join(states)}; inputs: {', '.join(inputs) or 'none'})"
        )
    return ModelFile(
        path=path,
        structure=s,
        x={st: columns.get(st, st) for st in states},
        dx={st: columns.get(f"d{st}", f"d{st}") for st in read_dx},
        u={i: columns.get(i, i) for i in inputs},
        t=columns.get("t"),
    )


def identify(
    model: ModelFile, table: Any, method: str, chunk: int, alpha: float = 0.05,
    time: Optional[Callable[[str, str], Any]] = None,
) -> Dict[str, Any]:
    """Identifies ``model``'s parameters from an open table (:func:`vehid.io.open_table`),
    chunk by chunk (memory bounded). Returns the report: samples, names, params, bse,
    conf_int, sigma2.

    ``time``: given the time column's name and label, the check of its values (an object
    whose ``add(t, lines)`` raises on a bad time); the time column is ``[columns]``' ``t``,
    else a column named ``t``. ``None``: the time column is not read (a ``t`` in
    ``[columns]`` must still be in the file)."""
    import numpy as np

    from ._vehid import BatchLeastSquares, Identifier, KalmanIdentifier

    s = model.structure
    wanted: Dict[str, str] = {}
    for kind, mapping in (("state", model.x), ("derivative of", model.dx), ("input", model.u)):
        for name, col in mapping.items():
            wanted[col] = f"{kind} {name}"
    t_col = model.t
    if t_col is None and time is not None and "t" in table.names and "t" not in wanted:
        t_col = "t"
    if t_col is not None:
        wanted[t_col] = "time"
    missing = [c for c in wanted if c not in table.names]
    if missing:
        raise ModelFileError(
            f"{table.source}: no column {', '.join(repr(c) for c in missing)} "
            f"(needed for {', '.join(wanted[c] for c in missing)}); the file has {', '.join(table.names)}: "
            f"map them in {model.path}'s [columns]"
        )
    states, inputs = list(s.states), list(s.inputs)
    cols = [table.names.index(model.x[st]) for st in states]
    dcols = {st: table.names.index(c) for st, c in model.dx.items()}
    ucols = [table.names.index(model.u[i]) for i in inputs]
    tcols = [] if t_col is None or time is None else [table.names.index(t_col)]
    order = cols + list(dcols.values()) + ucols + tcols
    what = {table.names.index(c): w for c, w in wanted.items()}
    labels = [f"{table.names[i]!r} ({what[i]})" for i in order]
    check = None if not tcols or time is None or t_col is None else time(t_col, labels[-1])
    ident: Identifier
    if method == "kalman":
        ident = KalmanIdentifier(s)
    elif method == "ls":
        ident = BatchLeastSquares(s)
    else:
        raise ModelFileError(f"--method {method} does not run on a model file: use kalman or ls")
    n, nd = len(states), len(dcols)
    pos = {st: n + k for k, st in enumerate(dcols)}
    samples = 0
    for ch in table.chunks(order, labels, chunk):
        data = ch.data
        x = np.ascontiguousarray(data[:, :n])
        z = np.zeros_like(x)
        for j, st in enumerate(states):
            if st in pos:
                z[:, j] = data[:, pos[st]]
        if check is not None:
            check.add(np.ascontiguousarray(data[:, -1]), ch.lines)
        u = np.ascontiguousarray(data[:, n + nd : n + nd + len(inputs)]) if inputs else None
        try:
            ident.fit(x, z, u=u)
        except VehidError as e:  # a refused sample: named by its line, not its index in the chunk
            raise ModelFileError(table.rejected(str(e), ch.lines)) from None
        samples += len(data)
    stats = ident.stats(alpha=alpha)
    return {
        "samples": samples,
        "names": list(stats.names),
        "params": stats.params.tolist(),
        "bse": stats.bse.tolist(),
        "conf_int": stats.conf_int.tolist(),
        "sigma2": dict(zip(s.identified, stats.sigma2.tolist())),
        "alpha": alpha,
    }


def parse_params(model: ModelFile, text: Optional[str]) -> List[float]:
    """``--params a=2,b=0.8,...``: a value for every parameter of the structure."""
    names = list(model.structure.parameters)
    if not text:
        raise ModelFileError(f"give --params with a value for each of {', '.join(names)} (e.g. {names[0]}=1.0)")
    given: Dict[str, float] = {}
    for item in text.split(","):
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in names:
            raise ModelFileError(f"--params: {item.strip()!r} is not NAME=VALUE for a parameter ({', '.join(names)})")
        try:
            given[name] = float(value)
        except ValueError:
            raise ModelFileError(f"--params: {name}={value.strip()!r} is not a number") from None
    missing = [n for n in names if n not in given]
    if missing:
        raise ModelFileError(f"--params: no value for {', '.join(missing)}")
    return [given[n] for n in names]


def simulate(
    model: ModelFile, table: Any, params: List[float], dt: float, x0: Optional[List[float]], chunk: int
) -> Tuple[List[str], Any]:
    """Free-run simulation of ``model`` with ``params`` over the inputs read from ``table``
    (columns per ``[columns]``), ``dt`` seconds apart. Returns the CSV header and the rows
    (t, states, inputs) as an array."""
    import numpy as np

    s = model.structure
    inputs = list(s.inputs)
    if not inputs:
        raise ModelFileError(f"{model.path} has no inputs: nothing to read from an input file")
    missing = [model.u[i] for i in inputs if model.u[i] not in table.names]
    if missing:
        raise ModelFileError(
            f"{table.source}: no column {', '.join(repr(c) for c in missing)} for the inputs; the file has "
            f"{', '.join(table.names)}: map them in {model.path}'s [columns]"
        )
    cols = [table.names.index(model.u[i]) for i in inputs]
    u = np.concatenate(
        [c.data for c in table.chunks(cols, [f"{model.u[i]!r} (input {i})" for i in inputs], chunk)]
        or [np.zeros((0, len(inputs)))]
    )
    if len(u) == 0:
        raise ModelFileError(f"{table.source}: no samples")
    start = x0 if x0 is not None else [0.0] * s.n_states
    if len(start) != s.n_states:
        raise ModelFileError(f"--x0: {len(start)} values for {s.n_states} states ({', '.join(s.states)})")
    x = s.simulate(params, start, u, dt=dt)
    t = np.arange(len(u)) * dt
    header = ["t", *s.states, *inputs]
    return header, np.column_stack([t, x, u])

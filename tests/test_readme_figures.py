"""The figures README.md states beside its runnable Python examples are the figures the
examples print (so that the README's printed figures are not only run but compared).

The blocks are taken from README.md itself (never copied here) and run in order, as
``test_docstrings.py::test_readme_python_blocks`` runs them, with ``print`` recorded by the
README line that calls it. Two kinds of statement are checked:

* a ``print(...)`` line whose comment states figures, e.g. ``# wheel rows: ~7, ~10,
  ~0.006`` or ``# about 5.8, 0.0001, 0.01``: the numbers it prints (over every call, in
  order: a loop prints one per pass) must be the comment's numbers, as many, each within
  half a unit of the last digit the README shows (the README's figure is the printed one
  rounded to the digits it gives: ``~7`` allows 6.5 .. 7.5, ``~0.006`` 0.0055 .. 0.0065,
  ``5.8`` 5.75 .. 5.85, ``~10`` 9.5 .. 10.5). No looser tolerance is needed: every run is
  seeded and gives the same bits on every platform (ARCHITECTURE.md, Invariants), so the
  only difference allowed is the README's rounding;
* a bare expression whose comment is a Python literal, e.g. ``rig.parameters  # ('a', 'b',
  'c', 'd')``: the expression must equal it.

The expected numbers are read from the README's comments, so the test fails when either the
README or the code changes alone.
"""

from __future__ import annotations

import ast
import builtins
import io
import re
import sys
import tokenize
from decimal import Decimal
from typing import Any, Dict, List, Tuple

import numpy as np
import pytest
from readme_blocks import README, python_blocks  # tests/ is on sys.path under pytest

import vehid  # noqa: F401  (the README's blocks import it; imported here so a broken build fails first)

# A figure list at the end of a comment: after a colon or "about", numbers separated by
# commas, each optionally marked approximate with "~".
FIGURES = re.compile(r"(?:about|:)\s*(~?\s*\d[\d.]*(?:e-?\d+)?(?:\s*,\s*~?\s*\d[\d.]*(?:e-?\d+)?)*)\s*$")


def comment(line: str) -> str:
    """The comment of a code line (after the first ``#`` outside a string), or ""."""
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(line + "\n").readline))
    except (tokenize.TokenError, SyntaxError):  # a line that does not tokenize alone: no comment read
        return ""
    return next((t.string[1:].strip() for t in tokens if t.type == tokenize.COMMENT), "")


def numbers(value: Any) -> List[float]:
    """The numbers in what was printed: scalars, and the entries of lists, tuples, arrays."""
    if isinstance(value, (bool, str, bytes)):
        return []
    if isinstance(value, (int, float, np.integer, np.floating)):
        return [float(value)]
    if isinstance(value, (list, tuple, np.ndarray)):
        return [v for item in value for v in numbers(item)]
    return []


def half_unit(figure: str) -> float:
    """Half a unit of the last digit of ``figure`` as written ("10" -> 0.5, "0.006" -> 0.0005)."""
    exponent = Decimal(figure).as_tuple().exponent
    assert isinstance(exponent, int)
    return 0.5 * 10.0**exponent


Run = Tuple[str, Dict[int, List[Any]], List[Tuple[int, str, Any, Any]]]


def stated_values(code: str) -> List[Tuple[int, ast.expr, Any]]:
    """The bare expressions (not calls) of a block whose comment is a Python literal: (line
    in the block, expression, the literal)."""
    lines = code.splitlines()
    out = []
    for node in ast.parse(code).body:
        if isinstance(node, ast.Expr) and not isinstance(node.value, ast.Call):
            try:
                out.append((node.lineno, node.value, ast.literal_eval(comment(lines[node.lineno - 1]))))
            except (ValueError, SyntaxError):
                pass
    return out


def run_readme() -> Run:
    """Runs every ```python block in order (one namespace); returns the README's text, the
    arguments of every print() by the README line that called it, and each bare expression
    with a stated value: (README line, its source, its value after its block ran, the
    comment's literal)."""
    text = README.read_text(encoding="utf-8")
    printed: Dict[int, List[Any]] = {}
    values: List[Tuple[int, str, Any, Any]] = []
    filename = str(README)

    def recording_print(*args: Any, **kwargs: Any) -> None:
        frame = sys._getframe(1)
        if frame.f_code.co_filename == filename:
            printed.setdefault(frame.f_lineno, []).extend(args)

    namespace: Dict[str, Any] = {"__builtins__": {**vars(builtins), "print": recording_print}}
    for line, code in python_blocks(text):
        # Padded with newlines so that line numbers (and tracebacks) are the README's.
        exec(compile("\n" * line + code, filename, "exec"), namespace)
        # Evaluated once the block has run, before a later block can rebind its names.
        for at, expr, literal in stated_values(code):
            value = eval(compile(ast.Expression(expr), filename, "eval"), namespace)
            values.append((line + at, ast.unparse(expr), value, literal))
    return text, printed, values


@pytest.fixture(scope="module")
def readme_run() -> Run:
    if not README.exists():
        pytest.skip("no README.md")
    return run_readme()


def stated_figures(text: str) -> List[Tuple[int, str, List[str]]]:
    """Every print() line of a python block whose comment states figures: (README line,
    the line, the figures as written)."""
    out = []
    for start, code in python_blocks(text):
        for i, line in enumerate(code.splitlines(), start=start + 1):
            if "print(" not in line.split("#")[0]:
                continue
            m = FIGURES.search(comment(line))
            if m:
                out.append((i, line.strip(), [f.strip().lstrip("~").strip() for f in m.group(1).split(",")]))
    return out


def test_the_readme_states_the_figures_this_test_checks() -> None:
    # The comments this test reads must exist (else it would pass by checking nothing): the
    # two-axle example's wheel rows and physical structure, the noisy-sensor example's three
    # identifiers and its joint EKF.
    stated = stated_figures(README.read_text(encoding="utf-8"))
    assert any("wheel rows" in ln for _, ln, _ in stated), stated
    assert any("worst(half_phys.a_hat)" in ln for _, ln, _ in stated), stated
    assert any("print(xis)" in ln for _, ln, _ in stated), stated
    assert any("rows(ekf.params)" in ln for _, ln, _ in stated), stated
    assert all(len(figs) >= 1 for _, _, figs in stated)


def test_printed_figures_are_the_readmes(readme_run: Run) -> None:
    text, printed, _ = readme_run
    stated = stated_figures(text)
    assert stated, "no print() with stated figures found in README.md"
    wrong = []
    for line_no, line, figures in stated:
        got = [v for arg in printed.get(line_no, []) for v in numbers(arg)]
        if len(got) != len(figures):
            wrong.append(f"README.md:{line_no}: {line!r} printed {len(got)} numbers {got}, the comment states "
                         f"{len(figures)}: {figures}")
            continue
        for value, figure in zip(got, figures):
            if not abs(value - float(figure)) <= half_unit(figure):
                wrong.append(f"README.md:{line_no}: printed {value:.6g}, the comment says ~{figure} "
                             f"(allowed ± {half_unit(figure):g})")
    assert not wrong, "\n".join(wrong)


def test_stated_values_of_bare_expressions(readme_run: Run) -> None:
    # `rig.parameters  # ('a', 'b', 'c', 'd')`: a bare expression whose comment is a Python
    # literal states its value.
    _, _, values = readme_run
    assert values, "no bare expression with a stated value found in README.md (rig.parameters)"
    wrong = [f"README.md:{line}: {src} is {value!r}, the comment says {literal!r}"
             for line, src, value, literal in values if value != literal]
    assert not wrong, "\n".join(wrong)

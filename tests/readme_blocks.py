"""The README's runnable examples, for the tests that run them (``test_docstrings``,
``test_readme_figures``, ``test_health``, ``test_install_check``): one reading of the fences."""

from __future__ import annotations

import re
from pathlib import Path
from typing import List, Tuple

README = Path(__file__).resolve().parent.parent / "README.md"


def python_blocks(text: str) -> List[Tuple[int, str]]:
    """Each ```python block: (the README line before its first line, its code)."""
    blocks = re.finditer(r"```python\n(.*?)```", text, flags=re.S)
    return [(text.count("\n", 0, m.start(1)), m.group(1)) for m in blocks]


def padded_source(text: str) -> str:
    """Every ```python block as one module, padded with newlines so that its line numbers (in
    tracebacks, in mypy's messages) are the README's."""
    source = ""
    for line, code in python_blocks(text):
        source += "\n" * (line - source.count("\n")) + code
    return source


def console_steps(text: str) -> List[Tuple[List[str], List[str]]]:
    """The ```console blocks as (argv after ``$ vehid``, the lines printed after it)."""
    steps: List[Tuple[List[str], List[str]]] = []
    for block in re.finditer(r"```console\n(.*?)```", text, flags=re.S):
        for line in block.group(1).strip("\n").splitlines():
            if line.startswith("$ vehid "):
                steps.append((line[len("$ vehid "):].split(), []))
            elif steps:
                steps[-1][1].append(line)
    return steps

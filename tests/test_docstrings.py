"""Examples in docstrings (and in README.md's ```python blocks, once it exists) run as tests."""

import doctest
import re
from pathlib import Path

import pytest

import vehid
import vehid.cli

README = Path(__file__).resolve().parent.parent / "README.md"


@pytest.mark.parametrize("module", [vehid, vehid.cli])
def test_docstring_examples(module: object) -> None:
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)  # type: ignore[arg-type]
    assert result.failed == 0
    if module is vehid:
        assert result.attempted > 0


@pytest.mark.skipif(not README.exists(), reason="no README.md yet")
def test_readme_python_blocks() -> None:
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.S)
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, str(README), "exec"), namespace)

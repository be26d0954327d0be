"""Examples in docstrings and in README.md's ```python blocks run as tests."""

import doctest
import sys
from pathlib import Path
from typing import Any, Dict

import pytest
from readme_blocks import README, padded_source, python_blocks  # tests/ is on sys.path under pytest

import vehid
import vehid.align
import vehid.channels
import vehid.cli
import vehid.clitools
import vehid.cmd_demo
import vehid.cmd_identify
import vehid.cmd_reproduce
import vehid.cmd_simulate
import vehid.fieldlog
import vehid.inspect_log
import vehid.io
import vehid.monitor

#: The modules whose examples run: the package, the command line (its parser and main, what
#: the commands share, one module per command), the reader, a field log's channels, its reading
#: (fieldlog), vehid inspect, the monitor.
MODULES = [vehid, vehid.cli, vehid.clitools, vehid.cmd_simulate, vehid.cmd_identify, vehid.cmd_demo,
           vehid.cmd_reproduce, vehid.io, vehid.channels, vehid.monitor, vehid.align, vehid.fieldlog,
           vehid.inspect_log]


@pytest.mark.parametrize("module", MODULES, ids=lambda m: m.__name__)
def test_docstring_examples(module: Any) -> None:
    # Every module documents itself by examples, the command line too (its argument parser,
    # the argparse types, the --truth and --p0 readers, main's exit status): none may be
    # without, and every one must print what its docstring shows.
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0
    assert result.attempted > 0


# The README's Python quickstart uses the identifier classes, which the extension does not
# expose yet: the test switches itself on as soon as they are bound.
@pytest.mark.skipif(not README.exists(), reason="no README.md")
@pytest.mark.skipif(not hasattr(vehid, "KalmanIdentifier"), reason="identifier bindings not in vehid yet")
def test_readme_python_blocks() -> None:
    text = README.read_text(encoding="utf-8")
    namespace: Dict[str, Any] = {}
    for line, code in python_blocks(text):
        # Pad with newlines so that tracebacks point at the README's own line numbers.
        exec(compile("\n" * line + code, str(README), "exec"), namespace)


@pytest.mark.skipif(not README.exists(), reason="no README.md")
def test_readme_python_blocks_pass_mypy_strict(tmp_path: Path) -> None:
    """Every ```python block of the README, as one module, type-checks under ``mypy --strict``
    against the package's stubs (``_vehid.pyi``): what a user's typed script meets."""
    mypy = pytest.importorskip("mypy.api")
    module = tmp_path / "readme_module.py"
    module.write_text(padded_source(README.read_text(encoding="utf-8")), encoding="utf-8")
    package = Path(vehid.__file__).resolve().parent.parent
    out, err, status = mypy.run(
        ["--strict", "--no-incremental", "--cache-dir", str(tmp_path / "cache"), "--python-executable", sys.executable,
         str(module)]
    )
    assert status == 0, f"README.md, mypy --strict (package at {package}):\n{out}{err}"

"""Hostile input to the command line: each case found by a randomized run is one line on
stderr with exit status 2 naming the argument or file and the fix, or the right quiet
behaviour, never an internal error or a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import List

import pytest

from vehid import cli

PYTHONPATH = str(Path(cli.__file__).resolve().parents[1])


def vehid_sh(command: str, timeout: float = 120) -> "subprocess.CompletedProcess[str]":
    """Runs ``command`` in ``sh -c``, with ``vehid`` standing for this interpreter's ``-m vehid``."""
    env = {**os.environ, "PYTHONPATH": PYTHONPATH}
    script = command.replace("vehid ", f"'{sys.executable}' -m vehid ")
    return subprocess.run(["sh", "-c", script], capture_output=True, text=True, timeout=timeout, env=env)


def error_line(capsys: pytest.CaptureFixture[str], argv: List[str]) -> str:
    """The one line of a failing command: exit 2 (returned, or argparse's SystemExit)."""
    capsys.readouterr()
    try:
        status = cli.main(argv)
    except SystemExit as e:
        status = e.code  # type: ignore[assignment]
    captured = capsys.readouterr()
    assert status == 2, captured
    assert captured.out == "" and captured.err.count("\n") == 1, captured
    assert "internal error" not in captured.err
    return captured.err.rstrip("\n")


# --- reproduce --seed ---------------------------------------------------------------------


@pytest.mark.parametrize("seed", ["-1", "18446744073709551616"])
def test_reproduce_seed_out_of_range(seed: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert error_line(capsys, ["reproduce", "--seed", seed, "--out", str(tmp_path / "r")]) == (
        f"vehid: error: argument --seed: expected a whole number from 0 to 18446744073709551615 (2**64 - 1), "
        f"got {seed} (see vehid reproduce --help)")

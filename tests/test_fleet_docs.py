"""docs/capabilities/fleet.md's worked example runs, in order, and prints what the page says:
each injected fault found, a second run with nothing to do, the fold day by day."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

PAGE = Path(__file__).resolve().parent.parent / "docs" / "capabilities" / "fleet.md"


def test_fleet_page_example_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    text = PAGE.read_text(encoding="utf-8")
    blocks = [m.group(1) for m in re.finditer(r"```python[^\n]*\n(.*?)```", text, flags=re.S)]
    assert len(blocks) == 3
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    namespace: dict[str, object] = {}
    with contextlib.redirect_stdout(out):
        for code in blocks:
            exec(compile(code, str(PAGE), "exec"), namespace)
    lines = out.getvalue().splitlines()
    injected = [ln.split()[1:5] for ln in lines if ln.startswith("injected:")]
    found = [ln.split()[1:5] for ln in lines if ln.startswith("found:")]
    assert injected and all(any(f[:2] == i[:2] and f[3] == i[3] for f in found) for i in injected)
    assert "0 vehicle-days; True" in lines
    assert sum(" events; " in ln for ln in lines) == 2

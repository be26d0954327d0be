"""Shared test helpers."""

import importlib
import signal
import threading
import time
from typing import Any, Callable

import pytest

# A shell starts a background job (`make test &`, `nohup ... &`) with SIGINT ignored, Python
# then installs no KeyboardInterrupt handler, and the children it starts inherit the ignored
# signal: every Ctrl-C test (test_reliability.py, test_cli_failures.py) would fail for the way
# the suite was launched. Restored here, in the controller and in every xdist worker, so that
# they test the code and not the launching shell.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def _assert_releases_gil(call: Callable[[], None], calls: int) -> None:
    """Runs ``call`` ``calls`` times in a worker thread while this thread counts ticks.

    Held inside ``call``, the GIL would let the counting loop tick only between the worker's
    calls (about ``calls`` ticks); released, the loop spins all along (thousands of ticks per
    0.1 s). So the assertion fails when the GIL is held.
    """

    def work() -> None:
        for _ in range(calls):
            call()

    thread = threading.Thread(target=work)
    t0 = time.perf_counter()
    thread.start()
    ticks = 0
    while thread.is_alive():
        ticks += 1
        time.sleep(0)  # yields the GIL to the worker between ticks
    elapsed = time.perf_counter() - t0
    thread.join()
    assert elapsed > 0.01, "run too short to tell; raise the sample count"
    assert ticks > 5 * calls, (ticks, elapsed)


@pytest.fixture
def assert_releases_gil() -> Callable[[Callable[[], None], int], None]:
    """``assert_releases_gil(call, calls)``: fails if ``call`` holds the GIL while it runs."""
    return _assert_releases_gil


@pytest.fixture
def hide_package(monkeypatch: pytest.MonkeyPatch) -> Callable[[str], None]:
    """``hide_package(name)``: ``importlib.import_module``, as vehid imports its optional
    extras, raises ImportError for ``name`` and its submodules (the test venv has them all)."""
    real = importlib.import_module

    def hide(package: str) -> None:
        def fake(name: str, *args: Any) -> Any:
            if name.split(".")[0] == package:
                raise ImportError(f"No module named {name!r}")
            return real(name, *args)

        monkeypatch.setattr(importlib, "import_module", fake)

    return hide

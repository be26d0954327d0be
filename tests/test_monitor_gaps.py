"""``vehid monitor`` on a log with a long gap in its time column (a parked car, a log of several
drives): the gap is fed as at most 60 s of missing samples (``vehid.fieldlog.GAP_CAP``), the
times after it stay on the log's clock, and memory and time are bounded by the samples logged,
not by the gap's length (fed whole, one 58-day gap in a 20,000-row log took 83 s and 4.7 GB)."""

from __future__ import annotations

import io
import json
import time
import tracemalloc
from pathlib import Path
from typing import Dict, List, Tuple

import numpy as np
import pytest

import vehid
from vehid import cli, fieldlog
from vehid import monitor as monitor_cmd

DT = 0.005
DAY = 86400.0


def drive(seconds: float, changes: List[Tuple[float, Dict[str, float]]], seed: int) -> vehid.Run:
    sim = vehid.Simulator(vehid.QuarterCar.passenger(), dt=DT, road="iso8608-C", speed=15.0, changes=changes,
                          sensors="realistic", seed=seed)
    return sim.run(int(round(seconds / DT)))


def write(path: Path, t: np.ndarray, y: np.ndarray) -> str:
    np.savetxt(path, np.column_stack([t, y]), delimiter=",", header="t,a_body,a_wheel,deflection", comments="",
               fmt="%.10f")
    return str(path)


def run_monitor(path: str, stdin: bool, capsys: pytest.CaptureFixture[str],
                monkeypatch: pytest.MonkeyPatch) -> Tuple[List[Dict[str, float]], str]:
    """``vehid monitor --json`` on ``path`` (as a file, or piped to standard input): its
    events and its stderr (exit 0 asserted)."""
    capsys.readouterr()
    if stdin:
        monkeypatch.setattr("sys.stdin", io.StringIO(Path(path).read_text()))
    assert cli.main(["monitor", "-" if stdin else path, "--model", "passenger", "--json"]) == 0
    out, err = capsys.readouterr()
    return [json.loads(line) for line in out.strip().splitlines()], err


@pytest.mark.parametrize("stdin", [False, True])
def test_a_58_day_gap_is_fed_as_60_s_in_bounded_time_and_memory(stdin: bool, tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str],
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    # The case: 20,000 rows at 200 Hz, one 58-day jump of the time column after row
    # 10,000 (piped: between two chunks of 10,000). The monitor finishes in seconds, well under
    # 100 MB of Python and numpy memory, says where the gap is and what it did, and counts 60 s
    # of missing samples.
    monkeypatch.setattr(monitor_cmd, "CHUNK", 10_000)
    run = drive(100.0, [], seed=3)
    t = run.t.copy()
    t[10_000:] += 58 * DAY
    path = write(tmp_path / "parked.csv", t, run.y)
    tracemalloc.start()
    start = time.perf_counter()
    try:
        events, err = run_monitor(path, stdin, capsys, monkeypatch)
        seconds = time.perf_counter() - start
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert seconds < 15.0, seconds
    assert peak < 100e6, peak
    assert events == []
    where = "<stdin>" if stdin else path
    assert (f"vehid: note: {where}, line 10002: a gap of 5.0112e+06 s (58 days) in the time column: fed to the "
            "monitor as 60 s of missing samples") in err, err
    assert "12000 missing, 1 gap over 60 s fed as 60 s of missing samples (5.01114e+06 s not fed)" in err, err


@pytest.mark.parametrize("stdin", [False, True])
def test_events_after_a_long_gap_are_on_the_logs_clock(stdin: bool, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str],
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    # The same drive logged twice: with a gap of one day after 100 s, and with a gap of exactly
    # 60 s there (the longest fed whole). The damper, changed -10 % during the gap (the drive
    # resumes with it), is found in both (the monitor kept its reference across the gap), at the
    # same sample: the day's log gives each time one day less 60 s later, to the microsecond.
    run = drive(200.0, [(100.0, {"b": 1350.0})], seed=4)
    times = {}
    for name, gap in (("day", DAY), ("minute", fieldlog.GAP_CAP)):
        t = run.t.copy()
        t[20_000:] += gap
        times[name] = run_monitor(write(tmp_path / f"{name}.csv", t, run.y), stdin, capsys, monkeypatch)
    (day, day_err), (minute, minute_err) = times["day"], times["minute"]
    assert [e["parameter"] for e in minute] == ["b"], minute_err
    assert "gap over 60 s" not in minute_err and "1 gap over 60 s" in day_err
    assert [e["parameter"] for e in day] == ["b"], day_err
    for key in ("t", "t_change"):
        assert day[0][key] - minute[0][key] == pytest.approx(DAY - fieldlog.GAP_CAP, abs=1e-6), (day, minute)
    assert day[0]["after"] == minute[0]["after"]


def test_a_log_of_many_long_gaps_is_refused_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # 1,000 samples, a 2-minute pause after every 100: shortened, the 9 gaps would still put
    # over 20 times the samples logged on the grid.
    run = drive(5.0, [], seed=5)
    t = run.t + 120.0 * (np.arange(len(run.t)) // 100)
    path = write(tmp_path / "pauses.csv", t, run.y)
    capsys.readouterr()
    assert cli.main(["monitor", path, "--model", "passenger"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err, err
    assert (f"vehid: error: {path}: 9 gaps over 60 s (the first at {path}, line 102), each put on the grid as 60 s "
            "of missing samples, give 109,000 samples on the grid from 1,000 in the log: split the log at its gaps"
            ) in err, err

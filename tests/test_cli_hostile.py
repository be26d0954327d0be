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


def vehid_sh(command: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
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


# --- closed pipes, closed stdin and stdout --------------------------------------------------

MODEL = """states = ["q", "v"]
inputs = ["u"]
[equations]
v = "a*u - b*v"
[known]
q = "v"
"""


@pytest.fixture()
def model_run(tmp_path: Path) -> Path:
    """A model file m.toml and 200,000 inputs u.csv (more than a pipe holds) in ``tmp_path``."""
    (tmp_path / "m.toml").write_text(MODEL)
    rows = "\n".join(f"{0.01 * i!r},{(i % 7) * 0.1!r}" for i in range(200_000))
    (tmp_path / "u.csv").write_text("t,u\n" + rows + "\n")
    return tmp_path


@pytest.mark.parametrize("command", [
    "vehid simulate --model quarter --n 200000 -o -",
    "vehid simulate --model quarter --road iso8608-C --n 200000 -o -",
    "vehid simulate --model half --road iso8608-C --n 200000 -o -",
    "vehid simulate --model {d}/m.toml --input {d}/u.csv --params a=1,b=2 -o -",
])
def test_closed_pipe_ends_quietly(command: str, model_run: Path) -> None:
    piped = vehid_sh(f"( {command.format(d=model_run)}; echo \"status $?\" >&2 ) | head -1")
    assert piped.stdout.count("\n") == 1 and piped.stdout.startswith("t,")
    assert piped.stderr == "status 0\n"


@pytest.mark.parametrize("command, message", [
    ("vehid simulate --model {d}/m.toml --input {d}/u.csv --params a=1,b=2 -o - >&-",
     "vehid: error: -o -: standard output is closed"),
    ("vehid simulate --model quarter --road iso8608-C --n 10 -o - >&-",
     "vehid: error: -o -: standard output is closed"),
    ("vehid simulate --model {d}/m.toml --input - --params a=1,b=2 -o {d}/out.csv <&-",
     "vehid: error: -: standard input is closed: give a file name, or pipe the data in"),
    ("vehid identify - --model quarter <&-",
     "vehid: error: -: standard input is closed: give a file name, or pipe the data in"),
    ("vehid monitor - <&-",
     "vehid: error: -: standard input is closed: give a file name, or pipe the data in"),
])
def test_closed_stdin_or_stdout(command: str, message: str, model_run: Path) -> None:
    done = vehid_sh(command.format(d=model_run))
    assert (done.returncode, done.stderr) == (2, message + "\n")


# --- model files that are not UTF-8 text ------------------------------------------------------


@pytest.mark.parametrize("content, byte, offset, fix", [
    (b"\xff\xfe" + MODEL.encode("utf-16-le"), 0xFF, 0,  # UTF-16 with its byte-order mark (Notepad's "Unicode")
     "it is UTF-16: convert it (iconv -f UTF-16 -t UTF-8)"),
    (bytes(range(256)), 0x80, 128, "save it as UTF-8 text"),  # binary
])
def test_model_file_not_utf8(content: bytes, byte: int, offset: int, fix: str, model_run: Path,
                             capsys: pytest.CaptureFixture[str]) -> None:
    bad = model_run / "bad.toml"
    bad.write_bytes(content)
    data = model_run / "d.csv"
    data.write_text("t,q,v,dv,u\n0,0,0,0,0\n")
    expected = (f"vehid: error: {bad} is not a UTF-8 TOML model file (byte 0x{byte:02x} at offset {offset}): {fix}")
    assert error_line(capsys, ["identify", str(data), "--model", str(bad)]) == expected
    assert error_line(capsys, ["simulate", "--model", str(bad), "--input", str(model_run / "u.csv"),
                               "--params", "a=1,b=2", "-o", "-"]) == expected


# --- over-long CSV headers and cells -----------------------------------------------------------


def test_csv_header_over_the_limit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    names = ["t", "x1", "x2", "x3", "x4", "dx1", "dx2", "dx3", "dx4"] + [f"extra_column_{i}" for i in range(9000)]
    header = ",".join(names)
    assert len(header) > 131_072
    path = tmp_path / "wide.csv"
    path.write_text(header + "\n" + ",".join(["0"] * len(names)) + "\n")
    expected = (f"vehid: error: {path}, line 1: the header line is {len(header):,} bytes, over the limit of "
                "131,072: write the file with only the columns needed (or shorter names)")
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == expected
    assert error_line(capsys, ["monitor", str(path)]) == expected
    assert error_line(capsys, ["identify", str(path), "--model", "quarter", "--delimiter", ";"]) == expected


def test_csv_cell_over_the_field_limit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "long-cell.csv"
    path.write_text("t,x1,x2,x3,x4,dx1,dx2,dx3,dx4\n0,1,2,3,4,5,6,7,8\n0.1,1,2,3,4,5,6,7," + "8" * 140_000 + "\n")
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == (
        f"vehid: error: {path}, line 3, column 'dx4' (d_body_vel, m/s^2): '{'8' * 30}'... (140,000 characters) "
        "is not a finite number (drop or repair that sample)")


# --- a model file's time column ------------------------------------------------------------------


def _model_data(path: Path, times: List[str]) -> None:
    """Samples of ``dv = a*u - b*v`` (a = 2, b = 0.5) at ``times``."""
    rows = []
    for i, t in enumerate(times):
        v, u = 0.1 * (i % 5), 0.3 * (i % 3)
        rows.append(f"{t},{0.01 * i!r},{v!r},{2 * u - 0.5 * v!r},{u!r}")
    path.write_text("t,q,v,dv,u\n" + "\n".join(rows) + "\n")


@pytest.mark.parametrize("mapped", [False, True])
def test_model_file_time_is_checked(mapped: bool, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    model = tmp_path / "m.toml"
    model.write_text(MODEL + ('[columns]\nt = "t"\n' if mapped else ""))
    data = tmp_path / "d.csv"
    times = [f"{0.1 * i!r}" for i in range(20)]
    _model_data(data, times)
    assert cli.main(["identify", str(data), "--model", str(model)]) == 0  # increasing: fine
    capsys.readouterr()
    _model_data(data, times[:10] + [times[3]] + times[11:])
    assert error_line(capsys, ["identify", str(data), "--model", str(model)]) == (
        f"vehid: error: {data}, line 12: time {float(times[3])!r} s is before {float(times[9])!r} s on line 11: "
        "the time column 't' (time) must increase strictly (sort the file by time)")
    _model_data(data, times[:10] + ["nan"] + times[11:])
    assert error_line(capsys, ["identify", str(data), "--model", str(model)]) == (
        f"vehid: error: {data}, line 12, column 't' (time): 'nan' is not a finite number (drop or repair that sample)")
    assert cli.main(["identify", str(data), "--model", str(model), "--no-time"]) == 0  # not read


# --- reproduce --out, checked before the work ------------------------------------------------


def test_reproduce_out_not_writable_fails_before_the_work(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    import vehid.reproduce

    def work(args: object) -> int:
        raise AssertionError("the reproduction ran before --out was checked")

    monkeypatch.setattr(vehid.reproduce, "command", work)
    line = error_line(capsys, ["reproduce", "--quick", "--out", "/proc/x"])
    assert line.startswith("vehid: error: --out /proc/x: cannot write into /proc (")
    assert line.endswith("): choose a writable directory")
    assert not Path("/proc/x").exists()


def test_reproduce_out_check_leaves_no_trace(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import vehid.reproduce

    seen: List[List[str]] = []
    monkeypatch.setattr(vehid.reproduce, "command", lambda args: seen.append(os.listdir(tmp_path)) or 0)
    assert cli.main(["reproduce", "--quick", "--out", str(tmp_path / "a" / "b")]) == 0
    assert seen == [[]] and os.listdir(tmp_path) == []  # nothing created before the work, no probe left
    (tmp_path / "r").mkdir()
    assert cli.main(["reproduce", "--quick", "--out", str(tmp_path / "r")]) == 0
    assert os.listdir(tmp_path / "r") == []


# --- monitor --dt: the message names --dt ---------------------------------------------------------


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("drive") / "drive.csv"
    assert cli.main(["simulate", "--model", "quarter", "--road", "iso8608-C", "--n", "400", "-o", str(path)]) == 0
    return path


@pytest.mark.parametrize("dt, message", [
    ("1e-9", "--dt 1e-09: too short a sample interval for the monitor's filters (the deflection filter's gain does "
             "not settle): give the log's sample interval in seconds, e.g. --dt 0.005 for 200 Hz"),
    ("100", "--dt 100: the tracking window (--window, default 6 s) must span at least 10 sample intervals: give a "
            "shorter --dt, or --window 1000 or more"),
    ("0", "--dt 0: the sample interval must be a finite number of seconds > 0"),
    ("-1", "--dt -1: the sample interval must be a finite number of seconds > 0"),
    ("nan", "--dt nan: the sample interval must be a finite number of seconds > 0"),
])
def test_monitor_dt_is_named(dt: str, message: str, drive: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert error_line(capsys, ["monitor", str(drive), "--dt", dt]) == f"vehid: error: {message}"


def test_monitor_window_given_keeps_its_name(drive: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert error_line(capsys, ["monitor", str(drive), "--dt", "1", "--window", "5"]) == (
        "vehid: error: --window 5: expected at least 10 sample intervals (--dt 1): give --window 10 or more, "
        "or a shorter --dt")


@pytest.mark.parametrize("option", ["--dt", "--speed", "--bandwidth", "--block", "--m"])
def test_a_positive_number_option_names_itself_not_a_mass(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                                           option: str) -> None:
    # Found by the fuzz harness's command-line episodes: `--dt -1` said "expected a positive
    # mass in kg" (the options share one argparse type).
    log = tmp_path / "run.csv"
    log.write_text("t,x1,x2,x3,x4,dx1,dx2,dx3,dx4,u1\n")
    line = error_line(capsys, ["identify", str(log), "--model", "quarter", option, "-1"])
    assert f"argument {option}: expected a finite number > 0, got '-1'" in line
    assert "mass" not in line


def test_inspect_of_a_time_column_with_an_infinite_value_prints_no_numpy_warning(tmp_path: Path) -> None:
    # Found by the fuzz harness (warnings as errors): the jitter of an empty selection warned.
    log = tmp_path / "log.csv"
    log.write_text("time [ms],SuspTravel [mm],a_body [g]\n0.0,0.1,0.2\ninf,0.3,0.4\n10,0.5,0.2\n")
    r = vehid_sh(f"vehid inspect {log}")
    assert r.returncode == 0 and "Warning" not in r.stderr, r.stderr

"""Every failure of the command line is one line on stderr and exit status 2, never a
traceback; a closed stdout ends quietly; an interrupt exits with 130. Each case asserts the
exact line."""

from __future__ import annotations

import errno
import gzip
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable, List

import numpy as np
import pytest

import vehid
import vehid.io as vio
from vehid import cli, clitools, cmd_demo, cmd_identify

VEHID = [sys.executable, "-m", "vehid"]
HAS_DEV_FULL = Path("/dev/full").exists()


@pytest.fixture(scope="module")
def run_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("fail") / "run.csv"
    assert cli.main(["simulate", "--model", "quarter", "--n", "300", "--seed", "2", "-o", str(path)]) == 0
    return path


def error_line(capsys: pytest.CaptureFixture[str], argv: List[str]) -> str:
    """The one line of a failing command: exit 2 (returned, or argparse's SystemExit)."""
    capsys.readouterr()
    try:
        status = cli.main(argv)
    except SystemExit as e:
        status = e.code  # type: ignore[assignment]
    assert status == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1, captured
    return captured.err.rstrip("\n")


# --- simulate, demo, reproduce -----------------------------------------------------------


def test_simulate_output_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    q = ["simulate", "--model", "quarter", "--n", "50"]
    assert error_line(capsys, [*q, "-o", "/nonexistent/x.csv"]) == (
        "vehid: error: -o /nonexistent/x.csv: no such directory: /nonexistent")
    assert error_line(capsys, [*q, "-o", str(tmp_path)]) == (
        f"vehid: error: -o {tmp_path}: is a directory; give a file name (or - for stdout)")
    assert error_line(capsys, [*q, "--n", "-1", "-o", "-"]) == (
        "vehid: error: argument --n: expected a whole number >= 0, got -1 (see vehid simulate --help)")
    assert error_line(capsys, [*q, "--dt", "0", "-o", "-"]).startswith("vehid: error: ")


@pytest.mark.skipif(not HAS_DEV_FULL, reason="needs /dev/full")
def test_simulate_to_a_full_device(capsys: pytest.CaptureFixture[str]) -> None:
    assert error_line(capsys, ["simulate", "--model", "quarter", "--n", "50", "-o", "/dev/full"]) == (
        "vehid: error: -o /dev/full: cannot write (No space left on device)")


def test_a_partial_file_is_removed(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    class Full:
        """A file that takes the header, then finds the disk full."""

        def __init__(self, path: str) -> None:
            self.f = open(path, "w")

        def write(self, text: str) -> int:
            return self.f.write(text)

        def writelines(self, lines: Any) -> None:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def close(self) -> None:
            self.f.close()

    monkeypatch.setattr(clitools, "_open_output", Full)
    out = tmp_path / "run.csv"
    assert error_line(capsys, ["simulate", "--model", "quarter", "--n", "50", "-o", str(out)]) == (
        f"vehid: error: -o {out}: cannot write (No space left on device); removed the partial file")
    assert not out.exists()


@pytest.mark.parametrize("n, message", [
    ("0", "expected a whole number >= 2, got 0"),
    ("-3", "expected a whole number >= 2, got -3"),
    ("1", "expected a whole number >= 2, got 1"),
    ("many", "expected a whole number, got 'many'"),
])
def test_demo_needs_samples(capsys: pytest.CaptureFixture[str], n: str, message: str) -> None:
    assert error_line(capsys, ["demo", "--n", n]) == f"vehid: error: argument --n: {message} (see vehid demo --help)"


def test_reproduce_output_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                 monkeypatch: pytest.MonkeyPatch) -> None:
    if HAS_DEV_FULL:
        assert error_line(capsys, ["reproduce", "--quick", "--out", "/dev/full/x"]) == (
            "vehid: error: --out /dev/full/x: /dev/full is not a directory")
    blocker = tmp_path / "notes.txt"
    blocker.write_text("")
    out = blocker / "report"
    assert error_line(capsys, ["reproduce", "--quick", "--out", str(out)]) == (
        f"vehid: error: --out {out}: {blocker} is not a directory")

    def full(args: Any) -> int:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "r" / "index.html"))

    monkeypatch.setattr(vehid.reproduce, "command", full)
    assert error_line(capsys, ["reproduce", "--quick", "--out", str(tmp_path / "r")]) == (
        f"vehid: error: --out {tmp_path / 'r'}: cannot write the report (No space left on device: "
        f"{tmp_path / 'r' / 'index.html'})")


def test_a_bug_is_still_one_line(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(args: Any) -> int:
        raise TypeError("boom")

    monkeypatch.setattr(cmd_demo, "cmd_demo", broken)
    assert error_line(capsys, ["demo"]) == "vehid: internal error: TypeError: boom (a bug in vehid: please report it)"


# --- identify: unreadable and malformed input ----------------------------------------------


def test_unreadable_inputs(run_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                           monkeypatch: pytest.MonkeyPatch) -> None:
    q = ["--model", "quarter"]
    assert error_line(capsys, ["identify", str(tmp_path / "none.csv"), *q]) == (
        f"vehid: error: {tmp_path / 'none.csv'}: no such file")
    assert error_line(capsys, ["identify", str(tmp_path), *q]) == (
        f"vehid: error: {tmp_path}: is a directory, not a CSV or Parquet file")
    if Path("/proc/self/mem").exists():  # opens, but every read fails (EIO)
        assert error_line(capsys, ["identify", "/proc/self/mem", *q]) == (
            "vehid: error: /proc/self/mem: cannot read (Input/output error)")

    def denied(path: str, mode: str = "r") -> Any:
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), path)

    monkeypatch.setattr(vio, "open", denied, raising=False)  # root reads anything: pretend
    assert error_line(capsys, ["identify", str(run_csv), *q]) == (
        f"vehid: error: {run_csv}: cannot open (Permission denied)")


def _write(tmp_path: Path, name: str, data: bytes) -> str:
    path = tmp_path / name
    path.write_bytes(data)
    return str(path)


HEADER = b"t,x1,x2,x3,x4,dx1,dx2,dx3,dx4\n"
ROW = b"0.1,1,2,3,4,5,6,7,8\n"
EXPECTED = "(t, x1..xn, dx1..dxn, as vehid simulate -o FILE writes)"

MALFORMED: List[Any] = [
    ("empty.csv", b"", "{p}: empty file; expected a table with a header line " + EXPECTED),
    ("comments.csv", b"# nothing yet\n\n#\n", "{p}: only comment or blank lines; expected a table with a header line "
     + EXPECTED),
    ("header.csv", HEADER, "{p} has 0 samples; the quarter car needs at least 4 (one per state), and many more for "
     "a useful estimate"),
    ("one.csv", HEADER + ROW, "{p} has 1 sample; the quarter car needs at least 4 (one per state), and many more "
     "for a useful estimate"),
    ("three.csv", HEADER + ROW + ROW.replace(b"0.1", b"0.2") + ROW.replace(b"0.1", b"0.3"),
     "{p} has 3 samples; the quarter car needs at least 4 (one per state), and many more for a useful estimate"),
    ("numbers.csv", ROW * 3, "{p}, line 1: the first line holds numbers, not column names: add a header line "
     "(t, x1..xn, dx1..dxn; see vehid identify --help)"),
    ("nul.csv", HEADER + ROW + b"0.2,1,2\x00,3\n", "{p}, line 3: a NUL byte: not a text file (a CSV or Parquet file)"),
    ("utf16.csv", "t,x1\n".encode("utf-16"), "{p}: not a text (UTF-8) file: UTF-16 (as Excel's 'Unicode Text' "
     "writes); save it as 'CSV UTF-8' or convert it (iconv -f UTF-16 -t UTF-8)"),
    ("latin1.csv", "t,x1 [°]\n".encode("latin-1"), "{p}, line 1: not a text (UTF-8) file (byte 0xb0); save it as "
     "'CSV UTF-8' or convert it (iconv -f LATIN1 -t UTF-8)"),
    ("latin1_data.csv", HEADER + ROW * 3 + "0.5,1,2,3,4,5,6,7,8 # é\n".encode("latin-1"),
     "{p}, line 5: not a text (UTF-8) file (byte 0xe9); save it as 'CSV UTF-8' or convert it "
     "(iconv -f LATIN1 -t UTF-8)"),
    ("long.csv", HEADER + b"1" * (3 << 20), "{p}, line 2: longer than 1 MiB without a line break: not a CSV table"),
    ("gz.csv.gz", gzip.compress(HEADER + ROW), "{p}: gzip-compressed; decompress it first "
     "(gunzip -c FILE | vehid identify - ...)"),
    ("colon.csv", HEADER.replace(b",", b":") + ROW.replace(b",", b":"),
     "{p}, line 1: the header is one column 't:x1:x2:x3:x4:dx1:dx2:dx3:dx4'; it seems separated by ':' "
     "(--delimiter ':')"),
    ("mixed.csv", HEADER + ROW + ROW.replace(b",", b";"), "{p}, line 3: 1 cell, but the header has 9 columns "
     "(separated by ','); it seems separated by ';' (--delimiter ';')"),
    ("ragged.csv", HEADER + ROW + b"0.2,1,2,3,4,5,6,7,8,9\n", "{p}, line 3: 10 cells, but the header has 9 columns "
     "(separated by ',')"),
    ("states.csv", b"t,x0,x1,x2,x3,dx0,dx1,dx2,dx3\n" + ROW, "{p}: column 'x0': states and inputs are numbered from "
     "1 (x1..x4, dx1..dx4, u1..u1)"),
    ("empty_cell.csv", HEADER + ROW + b"0.2,1,,3,4,5,6,7,8\n", "{p}, line 3, column 'x2' (wheel_vel, m/s): empty "
     "cell (a missing value: drop or repair that sample)"),
    ("inf.csv", HEADER + ROW + b"0.2,1,2,3,4,5,6,7,1e999\n", "{p}, line 3, column 'dx4' (d_body_vel, m/s^2): "
     "'1e999' is not a finite number (drop or repair that sample)"),
    ("date.csv", HEADER + ROW + b"2024-05-01 12:00,1,2,3,4,5,6,7,8\n", "{p}, line 3, column 't' (time, s): "
     "'2024-05-01 12:00' is not a number"),
]


@pytest.mark.parametrize("name, data, message", MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed_files(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, data: bytes,
                         message: str) -> None:
    path = _write(tmp_path, name, data)
    assert error_line(capsys, ["identify", path, "--model", "quarter"]) == "vehid: error: " + message.format(p=path)


def test_delimiter_errors(run_csv: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert error_line(capsys, ["identify", str(run_csv), "--model", "quarter", "--delimiter", ";"]) == (
        f"vehid: error: {run_csv}, line 1: the header has no ';'; it seems separated by ',' (--delimiter ',')")
    for bad in ("ab", "", "1", ".", "-"):
        assert error_line(capsys, ["identify", str(run_csv), "--model", "quarter", "--delimiter", bad]) == (
            "vehid: error: argument --delimiter: expected one of , ; tab | space (or another punctuation "
            f"character), got {bad!r} (see vehid identify --help)")


def test_option_errors_are_one_line(run_csv: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert error_line(capsys, ["identify", str(run_csv)]) == (
        "vehid: error: the following arguments are required: --model (see vehid identify --help)")
    line = error_line(capsys, ["identify", str(run_csv), "--model", "bus"])
    assert line == (
        "vehid: error: argument --model: invalid choice: 'bus' (choose from full, half, quarter, or a model file "
        "NAME.toml) (see vehid identify --help)")
    assert error_line(capsys, []) == "vehid: error: the following arguments are required: COMMAND (see vehid --help)"


# --- processes: pipes, full disks, interrupts --------------------------------------------------


def test_closed_stdout_is_quiet() -> None:
    sim = subprocess.Popen([*VEHID, "simulate", "--model", "quarter", "--n", "200000", "-o", "-"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert sim.stdout is not None and sim.stderr is not None
    first = sim.stdout.readline()
    sim.stdout.close()  # what `| head -1` does
    err = sim.stderr.read()
    sim.stderr.close()
    assert sim.wait(timeout=120) == 0
    assert first.startswith(b"t,x1,x2,x3,x4,dx1") and err == b""


@pytest.mark.skipif(not HAS_DEV_FULL, reason="needs /dev/full")
def test_stdout_on_a_full_device(run_csv: Path) -> None:
    with open("/dev/full", "w") as full:
        sim = subprocess.run([*VEHID, "simulate", "--model", "quarter", "--n", "100", "-o", "-"], stdout=full,
                             stderr=subprocess.PIPE, text=True, timeout=120)
        ident = subprocess.run([*VEHID, "identify", str(run_csv), "--model", "quarter", "--json"], stdout=full,
                               stderr=subprocess.PIPE, text=True, timeout=120)
    for done in (sim, ident):
        assert (done.returncode, done.stderr) == (
            2, "vehid: error: standard output: cannot write (No space left on device)\n")


def test_closed_stdout_at_start() -> None:
    done = subprocess.run(" ".join([*VEHID, "simulate", "--model", "quarter", "--n", "10", "-o", "-"]) + " >&-",
                          shell=True, capture_output=True, text=True, timeout=120)
    assert (done.returncode, done.stderr) == (2, "vehid: error: -o -: standard output is closed\n")


def test_interrupt_exits_130() -> None:
    child = subprocess.Popen([*VEHID, "identify", "-", "--model", "quarter"], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert child.stdin is not None
    child.stdin.write(HEADER + ROW)
    child.stdin.flush()
    time.sleep(1.5)  # reading, waiting for more
    child.send_signal(signal.SIGINT)
    out, err = child.communicate(timeout=60)
    assert (child.returncode, out, err) == (130, b"", b"vehid: interrupted\n")


def test_argument_errors_in_a_process_are_one_line() -> None:
    done = subprocess.run([*VEHID, "demo", "--n", "0"], capture_output=True, text=True, timeout=120)
    assert (done.returncode, done.stdout, done.stderr) == (
        2, "", "vehid: error: argument --n: expected a whole number >= 2, got 0 (see vehid demo --help)\n")


# --- --method ls is fed chunk by chunk -------------------------------------------------------


def test_batch_least_squares_is_fed_in_chunks(run_csv: Path, capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    sizes: List[int] = []
    real: Callable[..., None] = cmd_identify.feed_batch_least_squares

    def spy(ls: vehid.BatchLeastSquares, r: Any, z: Any) -> None:
        sizes.append(len(r))
        real(ls, r, z)

    monkeypatch.setattr(clitools, "CHUNK", 64)
    monkeypatch.setattr(cmd_identify, "feed_batch_least_squares", spy)
    assert cli.main(["identify", str(run_csv), "--model", "quarter", "--method", "ls", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert sizes == [64] * 4 + [44]  # never the whole file at once
    run = vehid.Simulator(vehid.QuarterCar(), seed=2).run(300)
    ref = vehid.BatchLeastSquares(vehid.QuarterCar(), keep_samples=False)  # the CLI's memory-bounded form
    ref.fit(run.r, run.z)
    assert np.array_equal(np.array(report["theta"]), ref.theta)
    stored = vehid.BatchLeastSquares(vehid.QuarterCar())  # the same least squares, to rounding
    stored.fit(run.r, run.z)
    np.testing.assert_allclose(ref.theta, stored.theta, rtol=1e-8, atol=1e-10)

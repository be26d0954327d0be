"""`vehid.io`: the dialects of CSV that real tools write, Parquet, streaming with bounded
memory, and absolute line numbers in every message.

Every dialect must give exactly the θ of the plain `vehid simulate` CSV (the same float64
text, read through another dialect, is the same number)."""

from __future__ import annotations

import doctest
import importlib
import io
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable, Dict, List

import numpy as np
import pytest

import vehid.io as vio
from vehid import cli, clitools

N = 2000


@pytest.fixture(scope="module")
def plain(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("io") / "plain.csv"
    assert cli.main(["simulate", "--model", "quarter", "--n", str(N), "--seed", "4", "-o", str(path)]) == 0
    return path


def identify_json(capsys: pytest.CaptureFixture[str], *argv: str) -> Any:
    capsys.readouterr()
    assert cli.main(["identify", *argv, "--json"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "", captured.err
    return json.loads(captured.out)


def error_line(capsys: pytest.CaptureFixture[str], argv: List[str]) -> str:
    """The one line a failing command prints (exit status 2, nothing on stdout)."""
    capsys.readouterr()
    assert cli.main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1, captured
    return captured.err.rstrip("\n")


def test_module_docstrings() -> None:
    result = doctest.testmod(vio, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0 and result.attempted >= 8


# --- dialects ------------------------------------------------------------------------


def _rows(text: str) -> List[List[str]]:
    return [line.split(",") for line in text.splitlines()]


def _join(rows: List[List[str]], sep: str, end: str = "\n") -> str:
    return "".join(sep.join(r) + end for r in rows)


DIALECTS: Dict[str, Callable[[str], bytes]] = {
    "semicolon": lambda t: _join(_rows(t), ";").encode(),
    "tab": lambda t: _join(_rows(t), "\t").encode(),
    "spaces": lambda t: _join([[c.rjust(24) for c in r] for r in _rows(t)], " ").encode(),
    "pipe": lambda t: _join(_rows(t), "|").encode(),
    "utf8 BOM (Excel)": lambda t: b"\xef\xbb\xbf" + t.encode(),
    "quoted header": lambda t: _join([[f'"{c}"' for c in _rows(t)[0]]] + _rows(t)[1:], ",").encode(),
    "every cell quoted": lambda t: _join([[f'"{c}"' for c in r] for r in _rows(t)], ",").encode(),
    "comment lines": lambda t: ("# logged by rig 7\n#\n" + t.replace("\n", "\n# a comment line\n", 3)).encode(),
    "blank lines": lambda t: ("\n" + t.replace("\n", "\n\n", 5) + "\n\n").encode(),
    "pandas to_csv (unnamed index)": lambda t: "".join(
        ("," if i == 0 else f"{i - 1},") + line + "\n" for i, line in enumerate(t.splitlines())).encode(),
    "pandas round trip (Unnamed: 0)": lambda t: "".join(
        ("Unnamed: 0," if i == 0 else f"{i - 1},") + line + "\n" for i, line in enumerate(t.splitlines())).encode(),
    "CRLF": lambda t: t.replace("\n", "\r\n").encode(),
    "Excel in Europe (BOM, sep=;, decimal comma, CRLF)": lambda t: b"\xef\xbb\xbf" + (
        "sep=;\r\n" + _join([[c.replace(".", ",") for c in r] for r in _rows(t)], ";", "\r\n")).encode(),
    "no final line break": lambda t: t.rstrip("\n").encode(),
}


@pytest.mark.parametrize("dialect", list(DIALECTS))
def test_every_dialect_gives_the_same_theta(
    plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, dialect: str
) -> None:
    reference = identify_json(capsys, str(plain), "--model", "quarter")
    path = tmp_path / "run.csv"
    data = DIALECTS[dialect](plain.read_text())
    path.write_bytes(data)
    report = identify_json(capsys, str(path), "--model", "quarter")
    assert report["theta"] == reference["theta"] and report["samples"] == N
    assert report["xi"] == reference["xi"]
    # The same bytes on stdin (read as bytes, below the text layer, as from a pipe).
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))
    assert identify_json(capsys, "-", "--model", "quarter")["theta"] == reference["theta"]


def test_delimiter_option_overrides_the_sniffer(plain: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "semi.csv"
    path.write_bytes(DIALECTS["semicolon"](plain.read_text()))
    reference = identify_json(capsys, str(plain), "--model", "quarter")
    for d in (";", "semicolon"):
        assert identify_json(capsys, str(path), "--model", "quarter", "--delimiter", d)["theta"] == reference["theta"]
    spaces = tmp_path / "spaces.txt"
    spaces.write_bytes(DIALECTS["spaces"](plain.read_text()))
    assert identify_json(capsys, str(spaces), "--model", "quarter",
                         "--delimiter", "space")["theta"] == reference["theta"]


def test_an_excel_sep_line_with_a_delimiter_option(plain: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "sep.csv"
    path.write_bytes(b"sep=;\n" + DIALECTS["semicolon"](plain.read_text()))
    reference = identify_json(capsys, str(plain), "--model", "quarter")
    assert identify_json(capsys, str(path), "--model", "quarter", "--delimiter", ";")["theta"] == reference["theta"]


def test_comment_lines_count_in_line_numbers(plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    header, *data = plain.read_text().splitlines(keepends=True)
    bad = data[9].split(",")
    bad[2] = "oops"
    text = "# rig 7\n# 2024-05-01\n\n" + header + "".join(data[:4]) + "# pause\n" + "".join(data[4:9]) + ",".join(bad)
    path = tmp_path / "commented.csv"
    path.write_text(text)
    # Lines: 3 before the header (line 4), 4 samples, a comment, 5 samples: the bad one is line 15.
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == (
        f"vehid: error: {path}, line 15, column 'x2' (wheel_vel, m/s): 'oops' is not a number")


# --- line numbers are absolute ---------------------------------------------------------


def _synthetic(path: Path, samples: int, comment_lines: int = 0) -> None:
    """A quarter-car shaped table (t, x1..x4, dx1..dx4) of random numbers, fast to write."""
    rng = np.random.default_rng(1)
    data = np.column_stack([np.arange(samples) * 0.01, rng.normal(size=(samples, 8))])
    with open(path, "w") as f:
        f.writelines(f"# comment {i}\n" for i in range(comment_lines))
        f.write("t,x1,x2,x3,x4,dx1,dx2,dx3,dx4\n")
        np.savetxt(f, data, delimiter=",", fmt="%.6f")


def test_a_bad_cell_deep_in_a_long_file_names_its_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "long.csv"
    _synthetic(path, 150_010, comment_lines=2)  # header on line 3, samples from line 4
    lines = path.read_text().splitlines(keepends=True)
    cells = lines[150_001].split(",")  # line 150,002 (sample 149,999), beyond the first chunk
    cells[3] = "n/a"
    lines[150_001] = ",".join(cells)
    path.write_text("".join(lines))
    assert error_line(capsys, ["identify", str(path), "--model", "quarter", "--method", "sg"]) == (
        f"vehid: error: {path}, line 150002, column 'x3' (body_pos, m): 'n/a' is not a number")


@pytest.mark.parametrize("chunk", [7, 100, 100_000])
def test_line_numbers_do_not_depend_on_the_chunk(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, chunk: int
) -> None:
    monkeypatch.setattr(clitools, "CHUNK", chunk)
    path = tmp_path / "t.csv"
    _synthetic(path, 500, comment_lines=1)
    lines = path.read_text().splitlines(keepends=True)
    empty = lines[301].split(",")
    empty[6] = ""
    nan = lines[402].split(",")
    nan[5] = "NaN"
    lines[301], lines[402] = ",".join(empty), ",".join(nan)
    path.write_text("".join(lines))
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == (
        f"vehid: error: {path}, line 302, column 'dx2' (d_wheel_vel, m/s^2): empty cell "
        "(a missing value: drop or repair that sample)")
    lines[301] = lines[300]
    path.write_text("".join(lines))
    assert error_line(capsys, ["identify", str(path), "--model", "quarter", "--no-time"]) == (
        f"vehid: error: {path}, line 403, column 'dx1' (d_wheel_pos, m/s): 'NaN' is not a finite number "
        "(drop or repair that sample)")


# --- streaming: bounded memory -------------------------------------------------------------


class Endless(io.RawIOBase):
    """An endless stream of valid quarter-car lines, counting the bytes handed out."""

    def __init__(self) -> None:
        self.given = 0
        self.k = 0
        self.header = b"t,x1,x2,x3,x4,dx1,dx2,dx3,dx4\n"

    def readable(self) -> bool:
        return True

    def read1(self, n: int = -1) -> bytes:
        out = self.header
        self.header = b""
        while len(out) < min(n, 1 << 16):
            self.k += 1
            out += f"{self.k * 0.01!r},0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8\n".encode()
        self.given += len(out)
        return out


def test_reading_stays_bounded_on_endless_input() -> None:
    source = Endless()
    with vio.open_table("-", stdin=source) as table:
        chunks = table.chunks(list(range(9)), [f"c{i}" for i in range(9)], rows=1000)
        first = next(chunks)
        assert first.data.shape == (1000, 9) and first.lines[0] == 2 and first.lines[-1] == 1001
        after_first = source.given
        for _ in range(200):
            chunk = next(chunks)
        assert chunk.lines[-1] == 201_001  # absolute line numbers all along
    # What was read ahead of the chunks handed out: at most one block (vio.BLOCK) per chunk.
    line = len(b"0.01,0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8\n") + 10
    assert after_first < 1000 * line + vio.BLOCK
    assert source.given < 201 * 1000 * line + vio.BLOCK


def test_dev_zero_fails_at_once(tmp_path: Path) -> None:
    for argv, stdin in ((["/dev/zero"], None), (["-"], "/dev/zero")):
        with open(stdin or os.devnull, "rb") as f:
            done = subprocess.run([sys.executable, "-m", "vehid", "identify", *argv, "--model", "quarter"],
                                  stdin=f, capture_output=True, text=True, timeout=60)
        name = "<stdin>" if argv == ["-"] else "/dev/zero"
        assert (done.returncode, done.stdout, done.stderr) == (
            2, "", f"vehid: error: {name}, line 1: a NUL byte: not a text file (a CSV or Parquet file)\n")


def _rss_kib(pid: int) -> int:
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs /proc")
def test_identify_on_an_endless_pipe_keeps_its_memory() -> None:
    code = ("import sys, vehid.cli, vehid.clitools as c; c.CHUNK = 2000; c.PROGRESS_ABOVE = 0; "
            "sys.exit(vehid.cli.main(['identify', '-', '--model', 'quarter']))")
    child = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stderr=subprocess.PIPE,
                             stdout=subprocess.DEVNULL)
    assert child.stdin is not None and child.stderr is not None
    stop = threading.Event()

    def write() -> None:
        assert child.stdin is not None
        rng = np.random.default_rng(0)
        block = [",".join(f"{v:.5f}" for v in row) for row in rng.normal(size=(2000, 8))]
        k = 0
        try:
            child.stdin.write(b"t,x1,x2,x3,x4,dx1,dx2,dx3,dx4\n")
            while not stop.is_set():
                lines = "".join(f"{(k + i) * 0.01:.2f},{block[i]}\n" for i in range(2000))
                child.stdin.write(lines.encode())
                k += 2000
        except (BrokenPipeError, ValueError):
            pass

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    rss: Dict[int, int] = {}
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and 400_000 not in rss:
            line = child.stderr.readline().decode()
            assert line.startswith("vehid: identified "), line
            samples = int(line.split()[2])
            if samples in (40_000, 400_000):
                rss[samples] = _rss_kib(child.pid)
    finally:
        stop.set()
        child.kill()
        child.wait(timeout=30)
        writer.join(timeout=30)
        try:
            child.stdin.close()
        except BrokenPipeError:
            pass
        child.stderr.close()
    assert 400_000 in rss, "the child did not get that far in time"
    # 360,000 more samples (about 20 MB of text) read: the process did not grow with them.
    assert rss[400_000] - rss[40_000] < 10_000, rss  # --method ls (stores every sample) grows by ~20 MB


# --- Parquet -------------------------------------------------------------------------------


def _has_pyarrow() -> bool:
    try:
        importlib.import_module("pyarrow.parquet")
    except ImportError:
        return False
    return True


needs_pyarrow = pytest.mark.skipif(not _has_pyarrow(), reason="pyarrow not installed (pip install 'vehid[parquet]')")


def _write_parquet(path: Path, columns: Dict[str, Any]) -> None:
    pa = importlib.import_module("pyarrow")
    pq = importlib.import_module("pyarrow.parquet")
    pq.write_table(pa.table(columns), str(path), row_group_size=700)


def _columns_of(csv: Path) -> Dict[str, Any]:
    header = csv.read_text().splitlines()[0].split(",")
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    return {name: data[:, i] for i, name in enumerate(header)}


@needs_pyarrow
def test_parquet_gives_the_csv_theta(
    plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(clitools, "CHUNK", 500)  # several batches across row groups
    path = tmp_path / "run.parquet"
    cols = _columns_of(plain)
    _write_parquet(path, {"__index_level_0__": np.arange(N), **cols})  # pandas' index is skipped
    reference = identify_json(capsys, str(plain), "--model", "quarter")
    report = identify_json(capsys, str(path), "--model", "quarter")
    assert report["theta"] == reference["theta"] and report["samples"] == N
    assert report["xi"] == reference["xi"]


@needs_pyarrow
def test_parquet_time_as_timestamps(plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pa = importlib.import_module("pyarrow")
    cols = _columns_of(plain)
    stamps = pa.array((cols.pop("t") * 1e9).astype("int64") + 1_700_000_000 * 10**9, type=pa.timestamp("ns"))
    path = tmp_path / "stamped.parquet"
    _write_parquet(path, {"time": stamps, **cols})
    report = identify_json(capsys, str(path), "--model", "quarter")
    assert report["time"]["median_interval"] == pytest.approx(0.05)
    assert report["columns"]["t"] == "time"


@needs_pyarrow
def test_parquet_errors_name_the_row(plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pa = importlib.import_module("pyarrow")
    cols = _columns_of(plain)
    x3 = cols["x3"].tolist()
    x3[1500] = None
    path = tmp_path / "null.parquet"
    _write_parquet(path, {**cols, "x3": pa.array(x3, type=pa.float64())})
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == (
        f"vehid: error: {path}, row 1501, column 'x3' (body_pos, m): empty (null) (drop or repair that sample)")
    path = tmp_path / "text.parquet"
    _write_parquet(path, {**cols, "dx1": pa.array([str(v) for v in cols["dx1"]])})
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == (
        f"vehid: error: {path}: column 'dx1' (d_wheel_pos, m/s) holds string values, not numbers")
    t = cols["t"].copy()
    t[900] = t[899]
    path = tmp_path / "time.parquet"
    _write_parquet(path, {**cols, "t": t})
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == (
        f"vehid: error: {path}, row 901: time {float(t[900])!r} s repeats row 900: the time column 't' (time, s) "
        "must increase strictly (drop the duplicated sample)")
    broken = tmp_path / "broken.parquet"
    broken.write_bytes(b"PAR1" + b"\x00" * 100)
    line = error_line(capsys, ["identify", str(broken), "--model", "quarter"])
    assert line.startswith(f"vehid: error: {broken}: not a readable Parquet file (")


def test_parquet_without_pyarrow_names_the_extra(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], hide_package: Callable[[str], None]
) -> None:
    hide_package("pyarrow")
    path = tmp_path / "run.parquet"
    path.write_bytes(b"PAR1" + b"\x00" * 100 + b"PAR1")
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == (
        f"vehid: error: {path}: a Parquet file; reading it needs pyarrow: pip install 'vehid[parquet]'")


def test_parquet_on_stdin_is_refused(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(b"PAR1\x00\x00\x00PAR1")))
    assert error_line(capsys, ["identify", "-", "--model", "quarter"]) == (
        "vehid: error: <stdin>: a Parquet file cannot be read from a pipe (its index is at the end): "
        "pass its file name")


def test_extra_is_declared() -> None:
    text = (Path(__file__).resolve().parents[1] / "pyproject.toml").read_text()
    assert 'parquet = ["pyarrow"]' in text

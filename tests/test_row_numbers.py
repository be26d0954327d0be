"""Every message about one sample of a file names its place in the file, never its index in
the chunk the command read it in: for a CSV the line number (1-based,
counting the header and comment lines: the line an editor shows), for Parquet the 1-based
data row (a fleet day's row in its own file, though the day's files are read joined). Each
case puts the bad cell beyond the first chunk (the chunk made small) or the first file."""

from __future__ import annotations

import re
from pathlib import Path
from typing import List

import numpy as np
import pytest

import vehid
from vehid import cli, clitools, fieldlog
from vehid import monitor as monitor_cmd

#: The sample (0-based, among the data rows) that holds the bad cell: in the third chunk of 1,000.
BAD = 2_345


def one_line_error(capsys: pytest.CaptureFixture[str], argv: List[str]) -> str:
    capsys.readouterr()
    assert cli.main(argv) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith("vehid: error: ") and "Traceback" not in err, err
    return err.strip()


@pytest.fixture(scope="module")
def quarter_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("rows") / "q.csv"
    assert cli.main(["simulate", "--model", "quarter", "--n", "3000", "-o", str(path)]) == 0
    return path


def with_cell(src: Path, dst: Path, column: str, value: str, comments: int = 0) -> Path:
    """``src`` with data row ``BAD``'s ``column`` set to ``value`` and ``comments`` comment
    lines before the header (so that lines and rows differ by more than the header)."""
    lines = src.read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[1 + BAD].split(",")
    cells[header.index(column)] = value
    lines[1 + BAD] = ",".join(cells)
    dst.write_text("".join(f"# comment {i}\n" for i in range(comments)) + "\n".join(lines) + "\n")
    return dst


@pytest.mark.parametrize("method", ["kalman", "ls"])
def test_identify_names_the_line_of_a_sample_the_identifier_rejects(
        method: str, quarter_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    # A finite value too large for the update (1e200): the core rejects the sample by its index
    # in the chunk handed over; the message gives the file's line (3 comment lines + the
    # header + BAD data rows before it).
    monkeypatch.setattr(clitools, "CHUNK", 1000)
    path = with_cell(quarter_csv, tmp_path / "big.csv", "x1", "1e200", comments=3)
    msg = one_line_error(capsys, ["identify", str(path), "--model", "quarter", "--method", method])
    line = 3 + 1 + BAD + 1
    assert f"{path}, line {line}: the identifier rejected this sample (" in msg, msg
    assert "1e200" in path.read_text().splitlines()[line - 1]
    assert "sample 345" not in msg and "unchanged" not in msg, msg


def test_identify_names_the_parquet_row_of_a_rejected_sample(quarter_csv: Path, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str],
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    monkeypatch.setattr(clitools, "CHUNK", 1000)
    header = quarter_csv.read_text().splitlines()[0].split(",")
    data = np.loadtxt(quarter_csv, delimiter=",", skiprows=1)
    data[BAD, header.index("x1")] = 1e200
    path = tmp_path / "big.parquet"
    pq.write_table(pa.table({h: data[:, i] for i, h in enumerate(header)}), path, row_group_size=700)
    msg = one_line_error(capsys, ["identify", str(path), "--model", "quarter"])
    assert f"{path}, row {BAD + 1}: the identifier rejected this sample (" in msg, msg


def test_a_huge_true_value_is_screened_from_the_truth_fit(quarter_csv: Path, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str],
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    # The default gate (the outlier screen) leaves this sample out of the true_* columns' own
    # fit, which without the screen would refuse it: xi is given.
    monkeypatch.setattr(clitools, "CHUNK", 1000)
    path = with_cell(quarter_csv, tmp_path / "truth.csv", "true_x1", "1e200")
    capsys.readouterr()
    assert cli.main(["identify", str(path), "--model", "quarter"]) == 0
    captured = capsys.readouterr()
    assert "no xi from the true_* columns" not in captured.err, captured.err
    assert "xi" in captured.out, captured.out


def test_a_model_files_identification_screens_a_huge_sample(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    # Before the outlier screens this sample was refused, naming its line; the default gate
    # now leaves it out and the noise-free data give the parameters exactly.
    monkeypatch.setattr(clitools, "CHUNK", 1000)
    model = tmp_path / "decay.toml"
    model.write_text('states = ["x"]\ninputs = ["u"]\n[equations]\nx = "a*x + b*u"\n')
    rng = np.random.default_rng(1)
    n = 3000
    x, u = rng.standard_normal(n), rng.standard_normal(n)
    rows = ["t,x,dx,u"] + [f"{0.01 * k:.2f},{x[k]:.17g},{u[k] - x[k]:.17g},{u[k]:.17g}" for k in range(n)]
    rows[1 + BAD] = f"{0.01 * BAD:.2f},1e200,0.0,0.0"
    path = tmp_path / "decay.csv"
    path.write_text("\n".join(rows) + "\n")
    capsys.readouterr()
    assert cli.main(["identify", str(path), "--model", str(model)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^  a +-1 ", out, re.M) and re.search(r"^  b +1 ", out, re.M), out


@pytest.mark.parametrize("cell, said", [("abc", "'abc' is not a number"), ("inf", "'inf' is not a finite number")])
@pytest.mark.parametrize("stdin", [False, True])
def test_the_monitor_names_the_line_of_a_bad_cell(cell: str, said: str, stdin: bool, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str],
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    # The file is read in chunks of 1,000 (fieldlog.CHUNK), a piped table too (monitor.CHUNK).
    monkeypatch.setattr(fieldlog, "CHUNK", 1000)
    monkeypatch.setattr(monitor_cmd, "CHUNK", 1000)
    sim = vehid.Simulator(vehid.QuarterCar.passenger(), dt=0.005, road="iso8608-C", sensors="realistic", seed=2)
    run = sim.run(3000)
    src = tmp_path / "drive.csv"
    np.savetxt(src, np.column_stack([run.t, run.y]), delimiter=",", header="t,a_body,a_wheel,deflection",
               comments="", fmt="%.9g")
    path = with_cell(src, tmp_path / "bad.csv", "a_wheel", cell, comments=2)
    if stdin:
        import io
        monkeypatch.setattr("sys.stdin", io.StringIO(path.read_text()))
    msg = one_line_error(capsys, ["monitor", "-" if stdin else str(path), "--model", "passenger"])
    assert f"{'<stdin>' if stdin else path}, line {2 + 1 + BAD + 1}, column " in msg and said in msg, msg


def test_the_monitor_names_a_parquet_row_not_a_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A Parquet file has rows, not lines: a long gap (and a time that goes back) is placed by
    # its 1-based row.
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    sim = vehid.Simulator(vehid.QuarterCar.passenger(), dt=0.005, road="iso8608-C", sensors="realistic", seed=2)
    run = sim.run(4000)
    t = run.t.copy()
    t[BAD:] += 86400.0
    path = tmp_path / "gap.parquet"
    columns = {"t": t, **{name: run.y[:, j] for j, name in enumerate(("a_body", "a_wheel", "deflection"))}}
    pq.write_table(pa.table(columns), path)
    capsys.readouterr()
    assert cli.main(["monitor", str(path), "--model", "passenger"]) == 0
    err = capsys.readouterr().err
    assert f"vehid: note: {path}, row {BAD + 1}: a gap of 86400 s (1 days)" in err, err
    columns["t"] = np.where(np.arange(len(t)) >= BAD, run.t - 1.0, run.t)
    pq.write_table(pa.table(columns), path)
    msg = one_line_error(capsys, ["monitor", str(path), "--model", "passenger"])
    assert f"{path}, row {BAD + 1}: time" in msg and "does not increase" in msg, msg


def test_a_fleet_days_bad_row_is_named_in_its_own_file(tmp_path: Path) -> None:
    # A vehicle-day of two Parquet files is joined into one table; a time that goes back in the
    # second file is named by that file and its own row, not the joined table's.
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    from vehid import fleet
    from vehid.fleet.fold import DayError, fold
    from vehid.fleet.layout import read_day

    rng = np.random.default_rng(3)
    t = np.arange(3000) * 0.005
    t[BAD] = t[BAD - 2]  # back, at row BAD + 1 of the day: row BAD + 1 - 1000 of the second file
    y = rng.normal(size=(3000, 3)) * [0.5, 2.0, 0.003]
    files = []
    for k, (a, b) in enumerate(((0, 1000), (1000, 3000))):
        files.append(str(tmp_path / f"part{k}.parquet"))
        pq.write_table(pa.table({"t": t[a:b], "a_body": y[a:b, 0], "a_wheel": y[a:b, 1], "deflection": y[a:b, 2]}),
                       files[-1])
    with pytest.raises(DayError, match=rf"^part1\.parquet, row {BAD + 1 - 1000}: time .* does not increase"):
        fold(None, read_day(files), fleet.VehicleConfig())


@pytest.mark.parametrize("stdin", [False, True])
def test_a_cell_that_overflows_in_si_is_named_by_its_line(stdin: bool, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str],
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    # 1e308 in a column declared in g is finite in the file and infinite in m/s^2: it was handed
    # on and refused by the monitor as "`y[0, 0]` is infinite" (its index in a 0.5 s block, with
    # numpy's overflow warning on stderr). Now refused naming its line and column.
    monkeypatch.setattr(fieldlog, "CHUNK", 1000)
    monkeypatch.setattr(monitor_cmd, "CHUNK", 1000)
    sim = vehid.Simulator(vehid.QuarterCar.passenger(), dt=0.005, road="iso8608-C", sensors="realistic", seed=2)
    run = sim.run(3000)
    y = run.y.copy()
    y[:, 0] /= 9.80665
    y[BAD, 0] = 1e308
    path = tmp_path / "g.csv"
    np.savetxt(path, np.column_stack([run.t, y]), delimiter=",", header="t,a_body [g],a_wheel,deflection",
               comments="", fmt="%.9g")
    if stdin:
        import io
        monkeypatch.setattr("sys.stdin", io.StringIO(path.read_text()))
    msg = one_line_error(capsys, ["monitor", "-" if stdin else str(path), "--model", "passenger"])
    assert (f"{'<stdin>' if stdin else path}, line {BAD + 2}, column a_body (body_acc, m/s^2): 1e+308 times 9.80665 "
            "(its unit to SI) is beyond a float's range: drop or repair that sample") in msg, msg


def test_identify_names_the_line_of_a_cell_that_overflows_in_si(quarter_csv: Path, tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str],
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(clitools, "CHUNK", 1000)
    lines = quarter_csv.read_text().splitlines()
    lines[0] = lines[0].replace("dx2,", "dx2 [g],", 1)
    src = tmp_path / "g.csv"
    src.write_text("\n".join(lines) + "\n")
    path = with_cell(src, tmp_path / "big.csv", "dx2 [g]", "1e308")
    msg = one_line_error(capsys, ["identify", str(path), "--model", "quarter"])
    assert f"{path}, line {BAD + 2}, column " in msg and "1e+308 times 9.80665 (its unit to SI)" in msg, msg


@pytest.mark.parametrize("cell, said", [("", "the time is missing"), ("back", "does not increase after")])
def test_identify_realistic_names_the_line_of_a_bad_time(cell: str, said: str, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str],
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    # vehid identify --sensors realistic said "the time column must increase from sample to
    # sample" with no place; now the line of a missing time or of one that goes back.
    from vehid import identify_realistic

    monkeypatch.setattr(identify_realistic, "CHUNK", 1000)
    sim = vehid.Simulator(vehid.QuarterCar.passenger(), dt=0.005, road="iso8608-C", sensors="realistic", seed=2)
    run = sim.run(3000)
    src = tmp_path / "drive.csv"
    np.savetxt(src, np.column_stack([run.t, run.y]), delimiter=",", header="t,a_body,a_wheel,deflection",
               comments="", fmt="%.9g")
    value = "" if cell == "" else f"{float(run.t[BAD - 3]):.9g}"
    path = with_cell(src, tmp_path / "bad.csv", "t", value)
    msg = one_line_error(capsys, ["identify", str(path), "--model", "quarter", "--sensors", "realistic"])
    assert f"{path}, line {BAD + 2}: " in msg and said in msg, msg

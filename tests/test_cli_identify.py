"""`vehid identify`: CSV in, identified rows, physical constants and ξ out.

Expected numbers come from the Python API run on the same simulation (the CSV text round
trip is exact), so the command line must give exactly what the library gives.
"""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path
from typing import Any, List

import numpy as np
import pytest

import vehid
from vehid import cli, clitools


def simulate(path: Path, model: str = "quarter", n: int = 3000, seed: int = 2) -> Path:
    assert cli.main(["simulate", "--model", model, "--n", str(n), "--seed", str(seed), "-o", str(path)]) == 0
    return path


def run_of(model: vehid.LinearModel, n: int, seed: int) -> vehid.Run:
    return vehid.Simulator(model, road_sigma=0.1, deriv_noise=0.005, seed=seed).run(n)


def physical_or_none(model: vehid.LinearModel, theta: Any, **known: float) -> Any:
    try:
        return model.physical(theta, **known)
    except vehid.VehidError:
        return None


def identify_json(capsys: pytest.CaptureFixture[str], *argv: str) -> Any:
    capsys.readouterr()
    assert cli.main(["identify", *argv, "--json"]) == 0
    out = capsys.readouterr().out
    assert len(out.strip().splitlines()) == 1  # one JSON object
    return json.loads(out)


def fails(capsys: pytest.CaptureFixture[str], argv: List[str], *words: str) -> str:
    capsys.readouterr()
    assert cli.main(argv) == 2
    captured = capsys.readouterr()
    err = captured.err
    assert captured.out == ""
    assert err.startswith("vehid: error: ") and err.count("\n") == 1, err
    for word in words:
        assert word in err, (word, err)
    return err


@pytest.fixture(scope="module")
def quarter_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate(tmp_path_factory.mktemp("runs") / "quarter.csv", "quarter", 3000, seed=2)


def test_text_report(quarter_csv: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["identify", str(quarter_csv), "--model", "quarter"]) == 0
    out = capsys.readouterr().out
    assert "3000 samples, quarter car (4 states), method kalman" in out
    assert "  row 1 " in out and "  row 3 " in out and "  true " in out
    assert "physical constants (known: m = 1 kg)" in out
    car = vehid.QuarterCar()
    kf = vehid.KalmanIdentifier(car, road_sigma=0.1, deriv_noise=0.005)  # the exact start, as the CLI's default
    run = run_of(car, 3000, 2)
    kf.fit(run.r, run.z)
    assert "time: 't' (time, s) from 0 to 149.95 s, median sample interval 0.05 s\n" in out
    assert "(p0 exact," in out and "  ± 95 % " in out
    assert "physical constants in the car's physical structure (least squares on the same samples, known: m = 1 kg), " \
        "95 % intervals:" in out
    # The true rows are fitted to the file's noise-free columns, not assumed to be the thesis car.
    xi_line = "xi (Eq 3.17, vs the true rows from the file's true_* columns) = "
    assert f"{xi_line}{vehid.xi(car.theta, kf.theta):.6g}" in out


@pytest.mark.parametrize("chunk", [7, 1000, 100_000])
def test_kalman_equals_the_library_in_any_chunking(
    quarter_csv: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, chunk: int
) -> None:
    monkeypatch.setattr(clitools, "CHUNK", chunk)
    car = vehid.QuarterCar()
    report = identify_json(capsys, str(quarter_csv), "--model", "quarter", "--p0", "500", "--road-sigma", "0.2")
    run = run_of(car, 3000, 2)
    kf = vehid.KalmanIdentifier(car, p0=500.0, road_sigma=0.2, deriv_noise=0.005)
    kf.fit(run.r, run.z)
    assert np.array_equal(np.array(report["theta"]), kf.theta)
    assert report["samples"] == 3000 and report["unknown_rows"] == [1, 3]
    # The true rows are fitted to the file's true_* columns: the thesis car to round-off.
    assert report["xi"] == pytest.approx(vehid.xi(car.theta, kf.theta), rel=1e-9)
    np.testing.assert_allclose(report["true_theta"], car.theta, rtol=1e-9)
    assert report["truth"]["source"] == "the file's true_* columns"
    assert report["time"] == {"column": "t", "start": 0.0, "end": pytest.approx(149.95),
                              "median_interval": pytest.approx(0.05), "gaps": 0}
    assert report["options"] == {"p0": 500.0, "road_sigma": 0.2, "deriv_noise": 0.005, "mode": "rows", "reinit": False}
    assert report["physical"] == physical_or_none(car, kf.theta, m=1.0)


def test_honest_defaults_exact_start_and_intervals(quarter_csv: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The default is the exact start (no prior); the rows come with the 95 % intervals of
    ``stats()``, and the quarter car's constants with the intervals of its physical structure
    identified on the same samples; a prior the user chose is reported where it still
    carries weight."""
    car = vehid.QuarterCar()
    run = run_of(car, 3000, 2)
    report = identify_json(capsys, str(quarter_csv), "--model", "quarter")
    assert report["options"]["p0"] == "exact" and report["prior_note"] is None
    kf = vehid.KalmanIdentifier(car, road_sigma=0.1, deriv_noise=0.005)
    kf.fit(run.r, run.z)
    assert np.array_equal(np.array(report["theta"]), kf.theta)
    np.testing.assert_array_equal(np.array(report["conf_int"]), kf.stats().conf_int.reshape(2, 4, 2))
    ps = vehid.KalmanIdentifier(car.structure(known={"m": 1.0}), gate=0.0)
    ps.fit(run.r, run.z)
    expected = car.physical(ps.stats(), m=1.0)
    assert report["physical_intervals"] == {k: list(v) for k, v in expected.items()}
    ls = identify_json(capsys, str(quarter_csv), "--model", "quarter", "--method", "ls")
    ref = vehid.BatchLeastSquares(car, keep_samples=False)  # the CLI's memory-bounded form
    ref.fit(run.r, run.z)
    np.testing.assert_array_equal(np.array(ls["conf_int"]), ref.stats().conf_int.reshape(2, 4, 2))
    # A prior chosen by the user: 3000 samples leave some entries' variance near P(0).
    prior = identify_json(capsys, str(quarter_csv), "--model", "quarter", "--p0", "1000")
    assert prior["options"]["p0"] == 1000.0
    kp = vehid.KalmanIdentifier(car, p0=1000.0, road_sigma=0.1, deriv_noise=0.005)
    kp.fit(run.r, run.z)
    ratio = np.diagonal(kp.covariance, axis1=1, axis2=2) / 1000.0
    assert ratio.max() > 0.1 and prior["prior_note"] is not None
    for i, j in zip(*np.nonzero(ratio > 0.1)):
        assert f"a[{[1, 3][i]},{j}]" in prior["prior_note"]
    sg = identify_json(capsys, str(quarter_csv), "--model", "quarter", "--method", "sg")
    assert sg["conf_int"] is None and sg["physical_intervals"] is None


def test_every_method_and_mode(quarter_csv: Path, capsys: pytest.CaptureFixture[str]) -> None:
    car = vehid.QuarterCar()
    run = run_of(car, 3000, 2)
    ls = identify_json(capsys, str(quarter_csv), "--model", "quarter", "--method", "ls")
    ref_ls = vehid.BatchLeastSquares(car, keep_samples=False)
    ref_ls.fit(run.r, run.z)
    assert np.array_equal(np.array(ls["theta"]), ref_ls.theta)
    sg = identify_json(capsys, str(quarter_csv), "--model", "quarter", "--method", "sg", "--gain", "ljung",
                       "--h", "0.1,1")
    ref = vehid.StochasticGradient(car, gain="ljung", h=[0.1, 1.0])
    ref.fit(run.r, run.z)
    assert np.array_equal(np.array(sg["theta"]), ref.theta) and sg["options"] == {"gain": "ljung", "h": [0.1, 1.0]}
    for extra in (["--mode", "full"], ["--mode", "shared", "--road-sigma", "0"], ["--reinit"], ["--p0", "1000,8"]):
        report = identify_json(capsys, str(quarter_csv), "--model", "quarter", *extra)
        assert np.isfinite(report["xi"]), extra
    shared = identify_json(capsys, str(quarter_csv), "--model", "quarter", "--mode", "shared", "--road-sigma", "0")
    ref2 = vehid.KalmanIdentifier(car, p0=1000.0, road_sigma=0.0, deriv_noise=0.005, mode="shared")
    ref2.fit(run.r, run.z)
    assert np.array_equal(np.array(shared["theta"]), ref2.theta)


def test_half_car_and_known_masses(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = simulate(tmp_path / "half.csv", "half", 2000, seed=5)
    half = vehid.HalfCar()
    report = identify_json(capsys, str(path), "--model", "half", "--method", "ls", "--m1", "1.5", "--m2", "0.5")
    run = run_of(half, 2000, 5)
    ref_half = vehid.BatchLeastSquares(half, keep_samples=False)
    ref_half.fit(run.r, run.z)
    theta = ref_half.theta
    assert np.array_equal(np.array(report["theta"]), theta)
    assert report["known"] == {"m1": 1.5, "m2": 0.5} and report["unknown_rows"] == [1, 3, 5, 7]
    assert report["xi"] == pytest.approx(vehid.xi(half.theta, theta), rel=1e-9)
    assert report["physical"] == physical_or_none(half, theta, m1=1.5, m2=0.5)


def test_unconverged_constants_are_reported_not_fatal(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = simulate(tmp_path / "short.csv", "quarter", 200, seed=1)
    car = vehid.QuarterCar()
    run = run_of(car, 200, 1)
    kf = vehid.KalmanIdentifier(car, road_sigma=0.1, deriv_noise=0.005)
    kf.fit(run.r, run.z)
    with pytest.raises(vehid.VehidError):
        car.physical(kf.theta, m=1.0)  # this short run gives rows with no positive constants
    assert cli.main(["identify", str(path), "--model", "quarter"]) == 0
    out = capsys.readouterr().out
    assert "not available: cannot recover" in out and "xi (Eq 3.17" in out
    report = identify_json(capsys, str(path), "--model", "quarter")
    assert report["physical"] is None and "cannot recover" in report["physical_error"]


def test_stdin_and_no_truth_columns(
    quarter_csv: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    lines = quarter_csv.read_text().splitlines()
    # Keep only t, x1..x4, dx1..dx4: no true values, so no ξ.
    short = "\n".join(",".join(line.split(",")[:9]) for line in lines) + "\n"
    monkeypatch.setattr(sys, "stdin", io.StringIO(short))
    report = identify_json(capsys, "-", "--model", "quarter")
    assert report["source"] == "<stdin>" and report["xi"] is None and report["true_theta"] is None
    monkeypatch.setattr(sys, "stdin", io.StringIO(short))
    assert cli.main(["identify", "-", "--model", "quarter"]) == 0
    out = capsys.readouterr().out
    assert "xi" not in out and "true" not in out and "row 3" in out


def test_columns_in_any_order_and_crlf(quarter_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rows = [line.split(",") for line in quarter_csv.read_text().splitlines()]
    order = list(reversed(range(len(rows[0]))))
    path = tmp_path / "reordered.csv"
    path.write_bytes("".join(",".join(r[i] for i in order) + "\r\n" for r in rows).encode())
    a = identify_json(capsys, str(quarter_csv), "--model", "quarter")
    b = identify_json(capsys, str(path), "--model", "quarter")
    assert a["theta"] == b["theta"] and a["xi"] == b["xi"]


def test_progress_on_long_inputs(
    quarter_csv: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(clitools, "CHUNK", 1000)
    monkeypatch.setattr(clitools, "PROGRESS_ABOVE", 2000)
    assert cli.main(["identify", str(quarter_csv), "--model", "quarter"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[-1] == f"vehid: identified 3000 samples (100% of {quarter_csv})", err
    assert len(err) == 3
    monkeypatch.setattr(sys, "stdin", io.StringIO(quarter_csv.read_text()))
    assert cli.main(["identify", "-", "--model", "quarter"]) == 0
    assert capsys.readouterr().err.splitlines() == ["vehid: identified 3000 samples"]
    monkeypatch.setattr(clitools, "PROGRESS_ABOVE", 5000)
    assert cli.main(["identify", str(quarter_csv), "--model", "quarter"]) == 0
    assert capsys.readouterr().err == ""


def test_user_errors(quarter_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    q = ["--model", "quarter"]
    fails(capsys, ["identify", str(tmp_path / "nope.csv"), *q], "nope.csv: no such file")
    fails(capsys, ["identify", str(tmp_path), *q], "is a directory")
    header, *data = quarter_csv.read_text().splitlines(keepends=True)

    def write(name: str, text: str) -> str:
        path = tmp_path / name
        path.write_text(text)
        return str(path)

    fails(capsys, ["identify", write("empty.csv", ""), *q], "empty file")
    fails(capsys, ["identify", write("blank.csv", "\n1,2\n"), *q], "blank.csv, line 2: the first line holds numbers")
    fails(capsys, ["identify", write("header.csv", header), *q], "has 0 samples", "at least 4")
    fails(capsys, ["identify", write("three.csv", header + "".join(data[:3])), *q], "has 3 samples")
    fails(capsys, ["identify", write("bad.csv", header.replace("dx4", "speed") + data[0]), *q],
          "missing column(s) dx4 (d_body_vel, m/s^2); columns not used: 'speed'")
    cols = header.strip().split(",")
    no_dx4 = ",".join(c for c in cols if c != "dx4") + "\n"
    fails(capsys, ["identify", write("nodx4.csv", no_dx4), *q], "missing column(s) dx4")
    fails(capsys, ["identify", write("dup.csv", header.strip() + ",x2\n"), *q], "'x2' appears twice")
    fails(capsys, ["identify", write("u.csv", header.strip() + ",u2\n"), *q], "'u2' does not fit")
    fails(capsys, ["identify", write("x0.csv", "t,x0\n"), *q], "column 'x0': states and inputs are numbered from 1")
    bad_cell = data[10].split(",")
    bad_cell[3] = "abc"
    text = header + "".join(data[:10]) + ",".join(bad_cell) + "".join(data[11:20])
    fails(capsys, ["identify", write("cell.csv", text), *q],
          "line 12, column 'x3' (body_pos, m): 'abc' is not a number")
    text = header + "".join(data[:5]) + data[5].rsplit(",", 1)[0] + "\n"
    fails(capsys, ["identify", write("short_row.csv", text), *q],
          "line 7: 17 cells, but the header has 18 columns (separated by ',')")
    nan_cell = data[4].split(",")
    nan_cell[6] = "nan"
    text = header + "".join(data[:4]) + ",".join(nan_cell) + "".join(data[5:20])
    fails(capsys, ["identify", write("nan.csv", text), *q],
          "line 6, column 'dx2' (d_wheel_vel, m/s^2): 'nan' is not a finite number")
    # The time must be finite too.
    nan_t = data[4].split(",")
    nan_t[0] = "nan"
    text = header + "".join(data[:4]) + ",".join(nan_t) + "".join(data[5:])
    fails(capsys, ["identify", write("nan_t.csv", text), *q], "line 6, column 't' (time, s): 'nan' is not a finite")
    # A NaN in a column identify does not read (u1: the truth comes from --truth) is no obstacle.
    nan_u = data[4].rstrip("\n").split(",")
    nan_u[-1] = "nan"
    text = header + "".join(data[:4]) + ",".join(nan_u) + "\n" + "".join(data[5:])
    report = identify_json(capsys, write("nan_u.csv", text), *q, "--truth", "thesis")
    assert report["samples"] == 3000 and report["truth"]["source"] == "--truth thesis"
    (tmp_path / "binary.csv").write_bytes(b"\xff\xfe\x00garbage")
    fails(capsys, ["identify", str(tmp_path / "binary.csv"), *q], "not a text")


def test_wrong_model_for_the_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = simulate(tmp_path / "half.csv", "half", 50)
    fails(capsys, ["identify", str(path), "--model", "quarter"], "has 8 states", "use --model half")


def test_values_vehid_rejects(quarter_csv: Path, capsys: pytest.CaptureFixture[str]) -> None:
    q = [str(quarter_csv), "--model", "quarter"]
    fails(capsys, ["identify", *q, "--p0", "-1"], "`p0`")
    fails(capsys, ["identify", *q, "--road-sigma", "-0.1"], "`road_sigma`")
    fails(capsys, ["identify", *q, "--p0", "1,2,3"], "`p0`")
    fails(capsys, ["identify", *q, "--mode", "shared"], "mode='shared'")
    fails(capsys, ["identify", *q, "--method", "sg", "--h", "nan"], "`h`")
    # Batch least squares on too little excitation: vehid's own error, exit 2.
    rows = quarter_csv.read_text().splitlines(keepends=True)
    path = quarter_csv.parent / "still.csv"
    path.write_text(rows[0] + rows[1] * 6)  # one state six times: rank 1 (and a repeated time)
    fails(capsys, ["identify", str(path), "--model", "quarter", "--method", "ls"],
          "still.csv, line 3: time 0.0 s repeats")
    fails(capsys, ["identify", str(path), "--model", "quarter", "--method", "ls", "--no-time"], "lacks excitation")


def test_option_errors_exit_2(quarter_csv: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for bad in (["--m", "-1"], ["--m1", "nan"], ["--p0", "x"], ["--method", "rls"]):
        with pytest.raises(SystemExit) as info:
            cli.main(["identify", str(quarter_csv), "--model", "quarter", *bad])
        assert info.value.code == 2
        assert "Traceback" not in capsys.readouterr().err


def test_pipe_between_processes_without_tracebacks(tmp_path: Path) -> None:
    vehid_cmd = [sys.executable, "-m", "vehid"]
    sim = subprocess.Popen([*vehid_cmd, "simulate", "--model", "quarter", "--n", "2000", "-o", "-"],
                           stdout=subprocess.PIPE)
    done = subprocess.run([*vehid_cmd, "identify", "-", "--model", "quarter"], stdin=sim.stdout,
                          capture_output=True, text=True, timeout=120)
    assert sim.stdout is not None
    sim.stdout.close()
    assert sim.wait(timeout=120) == 0
    assert done.returncode == 0, done.stderr
    assert "2000 samples" in done.stdout and "xi (Eq 3.17" in done.stdout
    missing = subprocess.run([*vehid_cmd, "identify", str(tmp_path / "none.csv"), "--model", "half"],
                             capture_output=True, text=True, timeout=120)
    assert missing.returncode == 2 and missing.stdout == ""
    assert missing.stderr == f"vehid: error: {tmp_path / 'none.csv'}: no such file\n"

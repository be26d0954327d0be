"""`vehid identify` on users' files: physical column names and `--columns`, the time column,
and where the truth behind ξ comes from (`--truth`, the file's true_* columns, or nowhere)."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, List

import numpy as np
import pytest

import vehid
from vehid import cli, clitools, cmd_identify
from vehid.io import STATES

ROOT = Path(__file__).resolve().parents[1]
N = 2000


@pytest.fixture(scope="module")
def plain(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("input") / "plain.csv"
    assert cli.main(["simulate", "--model", "quarter", "--n", str(N), "--seed", "6", "-o", str(path)]) == 0
    return path


@pytest.fixture(scope="module")
def half(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("input") / "half.csv"
    assert cli.main(["simulate", "--model", "half", "--n", str(N), "--seed", "6", "-o", str(path)]) == 0
    return path


def identify_json(capsys: pytest.CaptureFixture[str], *argv: str, err: str = "") -> Any:
    capsys.readouterr()
    assert cli.main(["identify", *argv, "--json"]) == 0
    captured = capsys.readouterr()
    assert captured.err == err
    return json.loads(captured.out)


def error_line(capsys: pytest.CaptureFixture[str], argv: List[str]) -> str:
    capsys.readouterr()
    assert cli.main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1, captured
    return captured.err.rstrip("\n")


def renamed(src: Path, dst: Path, names: List[str], keep: int = 9) -> Path:
    """The first ``keep`` columns of ``src`` under new header ``names``."""
    lines = src.read_text().splitlines()
    dst.write_text("\n".join([",".join(names)] + [",".join(line.split(",")[:keep]) for line in lines[1:]]) + "\n")
    return dst


# --- names -----------------------------------------------------------------------------

QUARTER_PHYSICAL = ["time", "wheel_pos", "wheel_vel", "body_pos", "body_vel",
                    "d_wheel_pos", "d_wheel_vel", "d_body_pos", "d_body_vel"]


@pytest.mark.parametrize("names", [
    QUARTER_PHYSICAL,
    ["t", "wheel_pos", "wheel_vel", "body_pos", "body_vel", "dx1", "dx2", "dx3", "dx4"],  # api names for dx
    ["Time [s]", "Wheel Pos [m]", "WHEEL_VEL (m/s)", "body-pos", " body_vel ", "d_wheel_pos [m/s]",
     "d_wheel_vel [m/s^2]", "D_Body_Pos", "d_body_vel"],  # case, spaces, dashes, units
    ["seconds", "x1", "x2", "x3", "x4", "d_wheel_pos", "d_wheel_vel", "d_body_pos", "d_body_vel"],
])
def test_physical_names_are_aliases(
    plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], names: List[str]
) -> None:
    reference = identify_json(capsys, str(plain), "--model", "quarter", "--truth", "thesis")
    path = renamed(plain, tmp_path / "named.csv", names)
    report = identify_json(capsys, str(path), "--model", "quarter", "--truth", "thesis")
    assert report["theta"] == reference["theta"] and report["xi"] == reference["xi"]
    assert report["columns"]["x1"] == names[1].strip() and report["columns"]["t"] == names[0].strip()


def test_half_car_physical_names(half: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    names = ["t"] + [a for a, _ in STATES["half"]] + [f"d_{a}" for a, _ in STATES["half"]]
    path = renamed(half, tmp_path / "half_named.csv", names, keep=17)
    reference = identify_json(capsys, str(half), "--model", "half", "--method", "ls", "--truth", "thesis")
    report = identify_json(capsys, str(path), "--model", "half", "--method", "ls", "--truth", "thesis")
    assert report["theta"] == reference["theta"]
    assert names[1:9] == ["front_wheel_pos", "front_wheel_vel", "rear_wheel_pos", "rear_wheel_vel",
                          "body_pos", "body_vel", "pitch", "pitch_rate"]


def test_columns_option_and_mapping_file(plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    own = ["Zeit", "wheel_z", "wheel_zdot", "body_z", "body_zdot", "wz_rate", "wz_acc", "bz_rate", "bz_acc"]
    path = renamed(plain, tmp_path / "own.csv", own)
    reference = identify_json(capsys, str(plain), "--model", "quarter", "--truth", "thesis")
    pairs = "t=Zeit,x1=wheel_z,x2=wheel_zdot,x3=body_z,x4=body_zdot"
    report = identify_json(capsys, str(path), "--model", "quarter", "--truth", "thesis", "--columns", pairs,
                           "--columns", "d_wheel_pos=wz_rate, dx2=wz_acc, d_body_pos=bz_rate, dx4=bz_acc")
    assert report["theta"] == reference["theta"]
    assert report["columns"] == dict(zip(["t", "x1", "x2", "x3", "x4", "dx1", "dx2", "dx3", "dx4"], own))
    mapping = tmp_path / "columns.toml"
    mapping.write_text("# rig 7\n[columns]\nt = \"Zeit\"\nwheel_pos = \"wheel_z\"\nx2 = wheel_zdot  # comment\n"
                       "x3: body_z\nx4 = body_zdot\ndx1 = wz_rate\ndx2 = wz_acc\ndx3 = bz_rate\ndx4 = bz_acc\n")
    report = identify_json(capsys, str(path), "--model", "quarter", "--truth", "thesis", "--columns", str(mapping))
    assert report["theta"] == reference["theta"]


def test_one_sensor_for_two_quantities(plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lines = plain.read_text().splitlines()
    # No dx1 column: the measured wheel velocity x2 stands for it (dx1 = d/dt wheel_pos).
    path = tmp_path / "shared.csv"
    path.write_text("\n".join(",".join(c for i, c in enumerate(line.split(",")[:9]) if i != 5) for line in lines)
                    + "\n")
    report = identify_json(capsys, str(path), "--model", "quarter", "--columns", "dx1=x2")
    assert report["columns"]["dx1"] == "x2" and report["columns"]["x2"] == "x2" and report["samples"] == N


def test_column_errors(plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    q = [str(plain), "--model", "quarter"]
    assert error_line(capsys, ["identify", *q, "--columns", "x1=nope"]) == (
        f"vehid: error: --columns x1=nope: {plain} has no column 'nope' (its columns: 't', 'x1', 'x2', 'x3', 'x4', "
        "'dx1', 'dx2', 'dx3', 'dx4', 'true_x1', 'true_x2', 'true_x3', ...)")
    assert error_line(capsys, ["identify", *q, "--columns", "wheel=x1"]) == (
        "vehid: error: --columns wheel=x1: 'wheel' is not a column name vehid knows here; known: t (time, s), "
        "x1 (wheel_pos, m), x2 (wheel_vel, m/s), x3 (body_pos, m), x4 (body_vel, m/s), dx1 (d_wheel_pos, m/s), "
        "dx2 (d_wheel_vel, m/s^2), dx3 (d_body_pos, m/s), dx4 (d_body_vel, m/s^2), true_*, u1..")
    assert error_line(capsys, ["identify", *q, "--columns", "x1=x1,wheel_pos=x2"]) == (
        "vehid: error: --columns: x1 (wheel_pos, m) is mapped twice")
    assert error_line(capsys, ["identify", *q, "--columns", "x1=x1", "--columns", "x1=x2"]) == (
        "vehid: error: --columns: 'x1' is given twice ('x1' and 'x2')")
    assert error_line(capsys, ["identify", *q, "--columns", "x1=,x2=x2"]) == (
        "vehid: error: --columns: 'x1=' is not NAME=COLUMN (e.g. x1=wheel_z)")
    assert error_line(capsys, ["identify", *q, "--columns", str(tmp_path / "map.toml")]) == (
        f"vehid: error: --columns {tmp_path / 'map.toml'}: no such file (give NAME=COLUMN pairs or a mapping file)")
    bad_map = tmp_path / "bad.toml"
    bad_map.write_text("x1 = wheel_z\njunk\n")
    assert error_line(capsys, ["identify", *q, "--columns", str(bad_map)]) == (
        f"vehid: error: --columns {bad_map}, line 2: 'junk' is not NAME=COLUMN (e.g. x1=wheel_z)")
    both = renamed(plain, tmp_path / "both.csv", ["t", "x1", "x2", "x3", "x4", "dx1", "dx2", "dx3", "wheel_pos"])
    assert error_line(capsys, ["identify", str(both), "--model", "quarter"]) == (
        f"vehid: error: {both}: columns 'x1' (2) and 'wheel_pos' (9) both give x1 (wheel_pos, m): "
        "choose one with --columns x1=NAME")
    assert error_line(capsys, ["identify", str(both), "--model", "quarter", "--columns", "x1=x1"]) == (
        f"vehid: error: {both}: missing column(s) dx4 (d_body_vel, m/s^2); columns not used: 'wheel_pos'; "
        "name them as vehid identify --help lists, or map them, e.g. --columns dx4=NAME")
    half_names = renamed(plain, tmp_path / "halfnames.csv", ["t", "front_wheel_pos", "x2", "x3", "x4", "dx1", "dx2",
                                                              "dx3", "dx4"])
    assert error_line(capsys, ["identify", str(half_names), "--model", "quarter"]) == (
        f"vehid: error: {half_names}: column 'front_wheel_pos' is a state of the half car: use --model half")


def test_unknown_columns_are_ignored_with_a_note(plain: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    lines = plain.read_text().splitlines()
    path = tmp_path / "extra.csv"
    path.write_text("\n".join([lines[0] + ",speed,gear"] + [line + f",12.5,{'third' if i % 2 else 'fourth'}"
                                                            for i, line in enumerate(lines[1:])]) + "\n")
    note = (f"vehid: note: {path}: ignoring column(s) 'speed', 'gear' "
            "(names vehid does not know; map them with --columns)\n")
    report = identify_json(capsys, str(path), "--model", "quarter", err=note)
    assert report["samples"] == N  # a text column nobody reads is no obstacle


def test_help_lists_every_column_with_its_unit(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        cli.main(["identify", "--help"])
    text = capsys.readouterr().out
    for model, states in STATES.items():
        for i, (alias, unit) in enumerate(states, start=1):
            dunit = unit[:-2] + "/s^2" if unit.endswith("/s") else unit + "/s"
            assert re.search(rf"x{i}\s+{alias}\s+{re.escape(unit)}\s+dx{i}\s+d_{alias}\s+{re.escape(dunit)}\n", text), \
                (model, alias)
    assert "nothing in the identifiers' update depends on the sample interval" in " ".join(text.split())
    assert "--no-time" in text and "--truth" in text and "--columns" in text


def test_readme_uses_the_same_names() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    section = readme[readme.index("## Command line"):readme.index("## What is in the box")]
    for states in STATES.values():
        for i, (alias, unit) in enumerate(states, start=1):
            assert re.search(rf"\| `x{i}` \| `{alias}` \| {re.escape(unit)} \|", section), alias
    for flag in ("--columns", "--truth", "--no-time", "--delimiter", "vehid[parquet]"):
        assert flag in section, flag


# --- time ------------------------------------------------------------------------------


def test_time_must_increase(plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                            monkeypatch: pytest.MonkeyPatch) -> None:
    header, *data = plain.read_text().splitlines(keepends=True)
    swapped = data[:]
    swapped[700], swapped[701] = swapped[701], swapped[700]
    path = tmp_path / "swapped.csv"
    path.write_text(header + "".join(swapped))
    t700 = float(data[700].split(",")[0])
    t701 = float(data[701].split(",")[0])
    expected = (f"vehid: error: {path}, line 703: time {t700!r} s is before {t701!r} s on line 702: the time column "
                "'t' (time, s) must increase strictly (sort the file by time)")
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == expected
    monkeypatch.setattr(clitools, "CHUNK", 701)  # the two lines in different chunks
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == expected
    dup = data[:]
    dup[1200] = dup[1199]
    path = tmp_path / "dup.csv"
    path.write_text(header + "".join(dup))
    t = float(data[1199].split(",")[0])
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == (
        f"vehid: error: {path}, line 1202: time {t!r} s repeats line 1201: the time column 't' (time, s) must "
        "increase strictly (drop the duplicated sample)")
    # Renamed time columns are checked the same way.
    named = renamed(path, tmp_path / "named.csv", ["Zeit"] + header.split(",")[1:9])
    assert error_line(capsys, ["identify", str(named), "--model", "quarter", "--columns", "t=Zeit"]) == (
        f"vehid: error: {named}, line 1202: time {t!r} s repeats line 1201: the time column 'Zeit' (t, time, s) "
        "must increase strictly (drop the duplicated sample)")


def test_no_time_column_needs_no_time(plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lines = plain.read_text().splitlines()
    path = tmp_path / "untimed.csv"
    path.write_text("\n".join(",".join(line.split(",")[1:9]) for line in lines) + "\n")
    assert error_line(capsys, ["identify", str(path), "--model", "quarter"]) == (
        f"vehid: error: {path}: no time column (t, time, time_s, t_s, seconds): map one with --columns t=NAME, "
        "or pass --no-time to identify without one")
    reference = identify_json(capsys, str(plain), "--model", "quarter")
    report = identify_json(capsys, str(path), "--model", "quarter", "--no-time")
    assert report["theta"] == reference["theta"] and report["time"] is None and report["xi"] is None
    capsys.readouterr()
    assert cli.main(["identify", str(path), "--model", "quarter", "--no-time"]) == 0
    assert "\ntime: not read (--no-time)\n" in capsys.readouterr().out
    assert error_line(capsys, ["identify", str(plain), "--model", "quarter", "--no-time", "--columns", "t=t"]) == (
        "vehid: error: --no-time and --columns t=... contradict each other: drop one")


def test_irregular_sampling_is_fine_and_gaps_are_reported(
    plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    header, *data = plain.read_text().splitlines(keepends=True)
    rng = np.random.default_rng(3)
    keep = sorted(rng.choice(len(data), size=1500, replace=False).tolist())  # irregular: 1 to several dt
    path = tmp_path / "irregular.csv"
    path.write_text(header + "".join(data[i] for i in keep))
    report = identify_json(capsys, str(path), "--model", "quarter")
    assert report["samples"] == 1500 and report["time"]["gaps"] == 0
    car = vehid.QuarterCar()
    sub = vehid.Simulator(car, seed=6).run(N)
    kf = vehid.KalmanIdentifier(car, road_sigma=0.1, deriv_noise=0.005)  # the CLI's default: the exact start
    kf.fit(sub.r[keep], sub.z[keep])
    assert np.array_equal(np.array(report["theta"]), kf.theta)  # the update never sees the interval
    # Gaps: samples 500..559 and six more stretches missing.
    drop = set(range(500, 560)) | {i for k in range(6) for i in range(1000 + 100 * k, 1015 + 100 * k)}
    path = tmp_path / "gappy.csv"
    path.write_text(header + "".join(line for i, line in enumerate(data) if i not in drop))
    capsys.readouterr()
    assert cli.main(["identify", str(path), "--model", "quarter"]) == 0
    captured = capsys.readouterr()
    # Line numbers: header line 1, sample i on line i + 2 before the first gap, i + 2 - 60 after it, ...
    assert captured.err.splitlines() == [
        f"vehid: warning: {path}, line 502: time jumps by 3.05 s (61x the median sample interval 0.05 s)",
        f"vehid: warning: {path}, line 942: time jumps by 0.8 s (16x the median sample interval 0.05 s)",
        f"vehid: warning: {path}, line 1027: time jumps by 0.8 s (16x the median sample interval 0.05 s)",
        f"vehid: warning: {path}, line 1112: time jumps by 0.8 s (16x the median sample interval 0.05 s)",
        f"vehid: warning: {path}, line 1197: time jumps by 0.8 s (16x the median sample interval 0.05 s)",
        f"vehid: warning: {path}: 7 time gaps longer than 10x the median sample interval in all (the first 5 shown)",
    ]
    assert ("time: 't' (time, s) from 0 to 99.95 s, median sample interval 0.05 s, 7 gap(s) longer than 10x the "
            "median (see the warnings)\n") in captured.out


# --- truth -----------------------------------------------------------------------------

OTHER = {"M": 12.0, "m": 1.5, "k1": 80.0, "k2": 45.0, "b": 35.0}


@pytest.fixture(scope="module")
def other_car(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run of a quarter car that is not the thesis' one, with its true_* columns."""
    run = vehid.Simulator(vehid.QuarterCar(**OTHER), seed=8).run(N)
    path = tmp_path_factory.mktemp("truth") / "other.csv"
    with open(path, "w") as f:
        f.write(",".join(cli.csv_header(4, 1)) + "\n")
        cli.write_csv_rows(f, run)
    return path


def test_truth_from_the_file_is_the_file_s_car(other_car: Path, capsys: pytest.CaptureFixture[str]) -> None:
    report = identify_json(capsys, str(other_car), "--model", "quarter", "--m", "1.5")
    other = vehid.QuarterCar(**OTHER)
    theta = np.array(report["theta"])
    np.testing.assert_allclose(report["true_theta"], other.theta, rtol=1e-9)
    assert report["xi"] == pytest.approx(vehid.xi(other.theta, theta), rel=1e-9)
    assert report["xi"] != pytest.approx(vehid.xi(vehid.QuarterCar().theta, theta), rel=1e-3)  # not the thesis car
    assert report["truth"]["source"] == "the file's true_* columns"
    for k in ("M", "k1", "k2", "b"):
        assert report["truth"]["constants"][k] == pytest.approx(OTHER[k], rel=1e-9)


def test_truth_option(other_car: Path, capsys: pytest.CaptureFixture[str]) -> None:
    given = ",".join(f"{k}={v:g}" for k, v in OTHER.items())
    # The wheel mass comes from --truth when --m is not given, and the note says so.
    report = identify_json(capsys, str(other_car), "--model", "quarter", "--truth", given,
                           err=f"vehid: note: --m not given: m = 1.5 kg from --truth {given}\n")
    theta = np.array(report["theta"])
    assert report["xi"] == vehid.xi(vehid.QuarterCar(**OTHER).theta, theta)
    assert report["truth"] == {"source": f"--truth {given}", "constants": OTHER}
    thesis = identify_json(capsys, str(other_car), "--model", "quarter", "--truth", "thesis")
    assert thesis["xi"] == vehid.xi(vehid.QuarterCar().theta, theta)  # --truth wins over the columns
    capsys.readouterr()
    assert cli.main(["identify", str(other_car), "--model", "quarter", "--truth", given]) == 0
    out = capsys.readouterr().out
    assert f"xi (Eq 3.17, vs the true rows from --truth {given}) = {report['xi']:.6g}\n" in out
    # The true constants beside the estimated ones (least squares has converged here).
    assert cli.main(["identify", str(other_car), "--model", "quarter", "--truth", given, "--method", "ls",
                     "--m", "1.5"]) == 0
    out = capsys.readouterr().out
    for k, unit in (("M", "kg"), ("k1", "N/m"), ("k2", "N/m"), ("b", "N s/m")):
        assert re.search(rf"\n  {k:3s} = \S+ +{unit} +true {OTHER[k]:g}\n", out), (k, out)


def test_no_truth_no_xi(plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = renamed(plain, tmp_path / "measured.csv", plain.read_text().split("\n")[0].split(",")[:9])
    report = identify_json(capsys, str(path), "--model", "quarter")
    assert report["xi"] is None and report["truth"] is None and report["true_theta"] is None
    capsys.readouterr()
    assert cli.main(["identify", str(path), "--model", "quarter"]) == 0
    out = capsys.readouterr().out.split("\n", 1)[1]  # after the line naming the file
    assert "xi" not in out and "true" not in out


def test_incomplete_or_inexact_truth_columns_give_no_xi(
    plain: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = renamed(plain, tmp_path / "partial.csv", plain.read_text().split("\n")[0].split(",")[:13], keep=13)
    report = identify_json(capsys, str(path), "--model", "quarter", err=(
        f"vehid: note: {path}: the true_* columns are incomplete (no true_dx2, true_dx4, u1): no xi; "
        "pass --truth for one\n"))
    assert report["xi"] is None
    lines = plain.read_text().splitlines()
    noisy = tmp_path / "noisy.csv"
    rng = np.random.default_rng(0)
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[14] = repr(float(cells[14]) + rng.normal(scale=1e-3))  # true_dx2 with noise: not a truth
        out.append(",".join(cells))
    noisy.write_text("\n".join(out) + "\n")
    capsys.readouterr()
    assert cli.main(["identify", str(noisy), "--model", "quarter", "--json"]) == 0
    captured = capsys.readouterr()
    assert re.fullmatch(rf"vehid: note: {re.escape(str(noisy))}: no xi from the true_\* columns: they do not follow "
                        r"dx = A x \+ B u exactly \(relative residual \S+\); pass --truth for one\n", captured.err)
    assert json.loads(captured.out)["xi"] is None


@pytest.mark.parametrize("model", [vehid.QuarterCar(), vehid.HalfCar(), vehid.HalfCar.passenger()])
def test_true_rows_are_the_core_s_least_squares(model: vehid.LinearModel) -> None:
    """The true rows behind ξ come from the core's least squares (one Structure per row, fed in
    chunks): the model's rows to rounding, structural zeros exactly 0; and with no road input
    (u = 0: the inputs say nothing of B) from the states alone."""
    rows = list(model.unknown_rows)
    for sim in (vehid.Simulator(model, seed=4, deriv_noise=0.01), vehid.Simulator(model, road_sigma=0.0, ic_sigma=0.1)):
        run = sim.run(5000)
        fit = cmd_identify.TruthFit(model)
        for a in range(0, 5000, 1300):
            fit.add(run.x[a:a + 1300], run.u[a:a + 1300], run.xdot[a:a + 1300, rows])
        theta, why = fit.solve()
        assert why == "" and theta is not None
        np.testing.assert_allclose(theta, model.theta, rtol=1e-10, atol=1e-10 * np.abs(model.theta).max())
        assert (theta[model.structural_zeros] == 0.0).all()


def test_true_rows_that_do_not_determine_a() -> None:
    """What the core's rank check, the sample count and the residual say, in the words of the
    note: too few samples, states that do not excite every direction (a state a multiple of
    another; the input a combination of the states, which would pass A + B c for A), truth
    columns that are not exact."""
    car = vehid.QuarterCar()
    run = vehid.Simulator(car, seed=3).run(3000)
    x, u, dx = run.x, run.u, run.xdot[:, list(car.unknown_rows)]

    def solve(x: Any, u: Any, dx: Any) -> str:
        fit = cmd_identify.TruthFit(car)
        fit.add(x, u, dx)
        theta, why = fit.solve()
        assert (theta is None) == (why != "")
        return why

    assert solve(x[:4], u[:4], dx[:4]) == "too few samples to fit the true rows"
    assert solve(x * 0.0, u * 0.0, dx * 0.0) == "the true states do not excite every direction"
    tied = x.copy()
    tied[:, 2] = 2.0 * x[:, 0]
    assert solve(tied, u, dx) == "the true states do not excite every direction"
    combination = x[:, [0]] - 0.5 * x[:, [3]]
    forced = dx.copy()
    forced[:, 0] = x @ car.theta[0] + car.b[1, 0] * combination[:, 0]
    assert solve(x, combination, forced) == "the true states do not excite every direction"
    noisy = dx + np.random.default_rng(0).normal(scale=1e-6, size=dx.shape)
    why = solve(x, u, noisy)
    assert re.fullmatch(r"they do not follow dx = A x \+ B u exactly \(relative residual 1\.\de-06\)", why), why
    assert solve(x, u, dx + np.random.default_rng(0).normal(scale=1e-10, size=dx.shape)) == ""


@pytest.mark.parametrize("truth, message", [
    ("M=10", "--truth: missing m, k1, k2, b: give every constant of the quarter car "
             "(e.g. --truth M=10,m=1,k1=90,k2=50,b=40), or --truth thesis"),
    ("M=10,m=1,k1=90,k2=50,b=40,J=3", "--truth: 'J' is not a constant of the quarter car (M, m, k1, k2, b)"),
    ("M=ten", "--truth: M='ten' is not a number"),
    ("M=inf,m=1,k1=90,k2=50,b=40", "--truth: M=inf is not a finite number"),
    ("M", "--truth: 'M' is not NAME=VALUE (e.g. --truth M=10,m=1,k1=90,k2=50,b=40)"),
    ("M=-10,m=1,k1=90,k2=50,b=40", "--truth: invalid `M`: expected a finite value > 0"),
])
def test_truth_errors(plain: Path, capsys: pytest.CaptureFixture[str], truth: str, message: str) -> None:
    assert error_line(capsys, ["identify", str(plain), "--model", "quarter", "--truth", truth]) == (
        f"vehid: error: {message}")

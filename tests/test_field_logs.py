"""Field logs (``vehid monitor`` on ROS 2 bags, MCAP, data-logger CSV and Parquet): units,
clocks, rates, the deflection's delay and sign, and the checks before any result.

The drive is written by ``tests/field_logs.py`` with facts known independently of the code
under test: scipy's polyphase resampler for the 200 and 500 Hz tables, an FFT phase shift
for the deflection's delay, rosbags' own writer for the bags, pyarrow's for Parquet."""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path
from typing import Dict, List, Tuple

import field_logs as F  # tests/ is on sys.path under pytest
import numpy as np
import pytest
from scipy import signal

import vehid
from vehid import align, cli, fieldlog
from vehid import monitor as monitor_cmd
from vehid.io import TableError

pytest.importorskip("rosbags")


def events(capsys: pytest.CaptureFixture[str], argv: List[str]) -> Tuple[List[Dict[str, float]], str]:
    """``vehid monitor ... --json``: its events and its stderr (exit 0 asserted)."""
    capsys.readouterr()
    assert cli.main(["monitor", *argv, "--json"]) == 0
    out, err = capsys.readouterr()
    return [json.loads(line) for line in out.strip().splitlines()], err


def error(capsys: pytest.CaptureFixture[str], argv: List[str]) -> str:
    """The one line of a refused ``vehid`` command (exit 2, no traceback)."""
    capsys.readouterr()
    try:
        status = cli.main(argv)
    except SystemExit as e:
        status = e.code  # type: ignore[assignment]
    out, err = capsys.readouterr()
    assert status == 2, err
    assert out == "" and err.count("\n") == 1 and err.startswith("vehid: error: "), err
    assert "Traceback" not in err and "internal error" not in err
    return err.strip()


@pytest.fixture(scope="module")
def damper() -> vehid.Run:
    """70 s at 400 Hz, the damper 1500 -> 1350 N s/m at 40 s."""
    return F.drive(70.0, changes=[(40.0, {"b": 1350.0})], seed=2)


@pytest.fixture(scope="module")
def five(tmp_path_factory: pytest.TempPathFactory, damper: vehid.Run) -> Dict[str, List[str]]:
    """The drive written five ways, each with the arguments that read it."""
    d = tmp_path_factory.mktemp("five")
    (d / "bag.toml").write_text(F.BAG_MAP)
    (d / "logger.toml").write_text(F.LOGGER_MAP)
    mcap = F.bag(d / "drive_mcap", damper)
    db3 = F.bag(d / "drive_db3", damper, storage="sqlite3")
    return {
        "vehid csv": [str(F.vehid_csv(d / "drive.csv", damper))],
        "mcap": [str(next(mcap.glob("*.mcap"))), "--columns", str(d / "bag.toml")],
        "bag folder": [str(mcap), "--columns", str(d / "bag.toml")],
        "db3": [str(next(db3.glob("*.db3"))), "--columns", str(d / "bag.toml")],
        "logger csv": [str(F.logger_csv(d / "logger.csv", damper)), "--columns", str(d / "logger.toml")],
        "parquet": [str(F.parquet(d / "drive.parquet", damper))],
    }


# --- one drive, five ways ------------------------------------------------------------------


def test_one_drive_written_five_ways_gives_the_same_event(five: Dict[str, List[str]],
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    # The same damper event from every form, within two samples (10 ms) of each other, and each
    # one's "after" within every other's 95 % interval. The logger's deflection is 4 ms late:
    # the note says it was found and removed.
    found: Dict[str, Dict[str, float]] = {}
    for name, argv in five.items():
        evs, err = events(capsys, [*argv, "--model", "passenger"])
        assert [e["parameter"] for e in evs] == ["b"], (name, evs, err)
        found[name] = evs[0]
        if name == "logger csv":
            assert "ms late against the accelerometers" in err and "removed" in err, err
            ms = float(err.split("deflection: ")[1].split(" ms late")[0])
            assert abs(ms - 4.0) < 1.0, err
        assert " 0 missing" in err, (name, err)
    times = [e["t"] for e in found.values()]
    assert max(times) - min(times) <= 0.0101, found
    assert 40.0 < min(times) < 50.0
    for a in found.values():
        for b in found.values():
            assert b["low"] <= a["after"] <= b["high"], found


def test_the_bag_is_read_on_its_header_stamps_not_the_log_time(five: Dict[str, List[str]], tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    # The bag's messages were logged 1-4 ms after their header stamps, at random. On the header
    # stamps (the default) the deflection's delay is under the tolerance and the event is found
    # (the test above); read on the log time (stamp = "log") the channels jitter by 3 ms, which
    # the twice-differentiated deflection does not survive: the note says its delay cannot be
    # estimated, instead of a silent result.
    argv = five["mcap"]
    evs, err = events(capsys, [*argv, "--model", "passenger"])
    assert "ms late" not in err and [e["parameter"] for e in evs] == ["b"], err
    log_map = tmp_path / "log.toml"
    log_map.write_text('stamp = "log"\n' + F.BAG_MAP)
    _, err = events(capsys, [argv[0], "--columns", str(log_map), "--model", "passenger"])
    assert "does not follow a_body - a_wheel" in err and "cannot be estimated" in err, err


# --- units, clocks, rates ------------------------------------------------------------------


def test_nominal_interval_is_the_rate_not_a_floats_noise() -> None:
    t = np.arange(20_000) * 0.005  # as a CSV writes them: 0.0049999999999954525 s apart, here and there
    t = np.asarray([float(f"{x:.9g}") for x in t + 1000.0])
    assert np.median(np.diff(t)) != 0.005
    assert align.nominal_interval(t) == 0.005
    quantized = np.floor(np.arange(1002) * 2.5) * 1e-3  # 400 Hz stamped in whole ms: 2, 3, 2, 3, ... ms
    assert np.median(np.diff(quantized)) != 0.0025 and align.nominal_interval(quantized) == 0.0025
    jittered = np.arange(4000) * 0.0025 + np.random.default_rng(1).uniform(0, 2e-4, 4000)
    assert align.nominal_interval(jittered) == 0.0025


def test_the_monitor_event_lands_where_the_library_puts_it(damper: vehid.Run, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    # The times written as a CSV writes them (0.0049999999999954525 s apart here and there):
    # vehid monitor's event at the sample HealthMonitor.fit finds it at with dt = 5 ms.
    path = F.vehid_csv(tmp_path / "d.csv", damper)
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    expected = vehid.HealthMonitor(vehid.QuarterCar.passenger(), dt=0.005).fit(data[:, 1:])
    evs, _ = events(capsys, [str(path), "--model", "passenger"])
    assert [round(e["t"], 6) for e in evs] == [round(e.t, 6) for e in expected]


def test_units_from_brackets_are_converted(damper: vehid.Run, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    # vehid's names with units in brackets: time in ms, the deflection in mm, accelerations in g:
    # the same event as the SI file.
    si = F.vehid_csv(tmp_path / "si.csv", damper)
    data = np.loadtxt(si, delimiter=",", skiprows=1)
    scaled = np.column_stack([data[:, 0] * 1e3, data[:, 1] / 9.80665, data[:, 2] / 9.80665, data[:, 3] * 1e3])
    mm = tmp_path / "mm.csv"
    np.savetxt(mm, scaled, delimiter=",", header="Time [ms],a_body [g],a_wheel [g],deflection [mm]", comments="",
               fmt="%.10g")
    ref, _ = events(capsys, [str(si), "--model", "passenger"])
    got, err = events(capsys, [str(mm), "--model", "passenger"])
    assert [e["parameter"] for e in got] == ["b"] and abs(got[0]["t"] - ref[0]["t"]) < 1e-6, err
    assert abs(got[0]["after"] - ref[0]["after"]) < 1e-3 * ref[0]["after"]


def test_an_unknown_unit_is_refused_naming_the_column(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "u.csv"
    path.write_text("t,a_body,a_wheel,deflection [furlong]\n0,0,0,0\n0.005,0,0,0\n")
    msg = error(capsys, ["monitor", str(path), "--model", "passenger"])
    assert "column 'deflection [furlong]'" in msg and "'furlong' is unknown" in msg and "mm" in msg, msg
    path.write_text("t [h],a_body,a_wheel,deflection\n0,0,0,0\n0.005,0,0,0\n")
    msg = error(capsys, ["monitor", str(path), "--model", "passenger"])
    assert "time column 't [h]'" in msg and "ms" in msg, msg


def test_empty_cells_are_missing_and_counted(damper: vehid.Run, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    # A logger writes a gap as empty cells: 8 samples with an empty deflection, read as missing
    # and counted in the summary (not "0 missing"); the event still found.
    path = F.vehid_csv(tmp_path / "e.csv", damper)
    lines = path.read_text().splitlines()
    for k in range(3001, 3009):
        cells = lines[k].split(",")
        cells[3] = ""
        lines[k] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    evs, err = events(capsys, [str(path), "--model", "passenger"])
    assert [e["parameter"] for e in evs] == ["b"] and " 8 missing" in err, err


def test_csv_timestamps_are_read(damper: vehid.Run, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    si = F.vehid_csv(tmp_path / "si.csv", damper)
    data = np.loadtxt(si, delimiter=",", skiprows=1)
    start = np.datetime64("2026-11-27T10:15:00.000")
    stamps = [str(start + np.timedelta64(int(round(t * 1e3)), "ms")).replace("T", " ") for t in data[:, 0]]
    path = tmp_path / "stamps.csv"
    path.write_text("timestamp,a_body,a_wheel,deflection\n" + "".join(
        f"{s},{a!r},{b!r},{c!r}\n" for s, (a, b, c) in zip(stamps, data[:, 1:].tolist())))
    ref, _ = events(capsys, [str(si), "--model", "passenger"])
    got, err = events(capsys, [str(path), "--model", "passenger"])
    assert "2026-11-27T10:15:00.000" in err, err
    assert [e["parameter"] for e in got] == ["b"] and abs(got[0]["t"] - ref[0]["t"]) < 1e-6


def test_resampler_agrees_with_scipys_polyphase_resampler() -> None:
    # 400 Hz -> 200 Hz on a signal with content up to 60 Hz and above the new Nyquist (120 Hz):
    # vehid's resampler (FIR + spline at the sample times) against scipy.signal.resample_poly on
    # the pass band's content; the 120 Hz tone is removed by both (aliased to 80 Hz otherwise).
    dt = 0.0025
    t = np.arange(16_000) * dt
    low = np.sin(2 * np.pi * 3.1 * t) + 0.5 * np.sin(2 * np.pi * 11.7 * t + 1) + 0.2 * np.sin(2 * np.pi * 60 * t)
    x = low + 0.3 * np.sin(2 * np.pi * 120 * t)
    ours = align.resample(t, x, dt, 0.0, 0.005, 8000)
    ref = signal.resample_poly(x, 1, 2)
    inner = slice(200, -200)
    assert np.max(np.abs(ours[inner] - ref[inner])) < 0.01
    assert np.max(np.abs(ours[inner] - low[::2][inner])) < 0.01


@pytest.mark.parametrize("h_in, dt_out", [(0.0025, 0.005), (0.002, 0.005), (0.001, 0.005), (0.0025, 0.01)])
def test_antialias_taps_are_scipys_firwin(h_in: float, dt_out: float) -> None:
    # The numpy design against scipy.signal.kaiserord + firwin with the same specification.
    ours = align.antialias_taps(h_in, dt_out)
    assert ours is not None
    fs_in, fs_out = 1 / h_in, 1 / dt_out
    numtaps, beta = signal.kaiserord(60.0, 0.1 * fs_out / (0.5 * fs_in))
    ref = signal.firwin(numtaps | 1, 0.45 * fs_out, window=("kaiser", beta), fs=fs_in)
    assert len(ours) == len(ref) and np.max(np.abs(ours - ref)) < 1e-12
    w, resp = signal.freqz(ours, worN=4096, fs=fs_in)
    assert np.max(np.abs(resp[w >= 0.5 * fs_out])) < 10 ** (-55 / 20)  # the grid's Nyquist and above
    assert np.max(np.abs(np.abs(resp[w <= 0.4 * fs_out]) - 1)) < 0.01  # the pass band


def test_hermite_interpolation_against_scipys_cubic_spline() -> None:
    from scipy.interpolate import CubicSpline

    rng = np.random.default_rng(2)
    ts = np.arange(0, 10, 0.01) + rng.uniform(0, 2e-4, 1000)  # 100 Hz with jitter, as a JointState
    vs = np.sin(2 * np.pi * 12 * ts) + 0.3 * np.sin(2 * np.pi * 3 * ts)
    tk = np.arange(0.1, 9.9, 0.005) + 0.0013
    truth = np.sin(2 * np.pi * 12 * tk) + 0.3 * np.sin(2 * np.pi * 3 * tk)
    ours = np.max(np.abs(align.hermite(ts, vs, tk) - truth))
    spline = np.max(np.abs(CubicSpline(ts, vs)(tk) - truth))
    assert ours < 0.003 and ours < 3 * spline, (ours, spline)


def test_resampler_marks_gaps_missing() -> None:
    t = np.concatenate([np.arange(0, 10, 0.0025), np.arange(12, 20, 0.0025)])
    y = align.resample(t, np.sin(t), 0.0025, 0.0, 0.005, 4000)
    tk = np.arange(4000) * 0.005
    gap = (tk > t[3999] + 1e-9) & (tk < 12.0 - 1e-9)
    assert np.isnan(y[gap]).all() and np.isfinite(y[~gap]).all()


@pytest.mark.parametrize("late_ms", [0.0, 2.0, 7.3, 20.0])
def test_the_deflections_delay_is_estimated_within_a_millisecond(late_ms: float) -> None:
    # A drive at 400 Hz, the deflection delayed by an exact FFT phase shift, all three resampled
    # to 200 Hz: the estimate within 1 ms of the injected delay (benches/field_log_offsets.py
    # measures it over seeds).
    run = F.drive(40.0, seed=11)
    y = run.y.copy()
    y[:, 2] = F.delayed(y[:, 2], late_ms * 1e-3, F.DT)
    grid = [align.resample(run.t, y[:, j], F.DT, 0.0, 0.005, 7990) for j in range(3)]
    est = align.estimate_delay(grid[0], grid[1], grid[2], 0.005)
    assert abs(est.delay * 1e3 - late_ms) < 1.0, est
    assert est.corr > 0.9 and 0.7 < est.slope < 1.3


def test_a_late_deflection_is_found_and_removed(damper: vehid.Run, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    # One sample (5 ms) late in vehid's own CSV: the note names the delay, and the damper's event
    # comes as in the file without the delay (without the removal it came 20-70 s late, or never).
    path = F.vehid_csv(tmp_path / "ok.csv", damper)
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    ref, _ = events(capsys, [str(path), "--model", "passenger"])
    data[1:, 3] = data[:-1, 3]
    late = tmp_path / "late.csv"
    np.savetxt(late, data[1:], delimiter=",", header="t,a_body,a_wheel,deflection", comments="", fmt="%.9g")
    got, err = events(capsys, [str(late), "--model", "passenger"])
    assert "ms late" in err and "removed" in err, err
    assert abs(float(err.split("deflection: ")[1].split(" ms late")[0]) - 5.0) < 1.0, err
    assert [e["parameter"] for e in got] == ["b"] and abs(got[0]["t"] - ref[0]["t"]) < 0.5, (got, ref)


def test_compression_positive_travel_is_detected(damper: vehid.Run, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    d = tmp_path
    (d / "logger.toml").write_text(F.LOGGER_MAP)
    path = F.logger_csv(d / "c.csv", damper, compression=True)
    evs, err = events(capsys, [str(path), "--columns", str(d / "logger.toml"), "--model", "passenger"])
    assert "compression-positive" in err and [e["parameter"] for e in evs] == ["b"], err
    # Declared with the wrong sign: refused, naming the convention.
    (d / "wrong.toml").write_text(F.LOGGER_MAP + "sign = 1\n")
    msg = error(capsys, ["monitor", str(path), "--columns", str(d / "wrong.toml"), "--model", "passenger"])
    assert "extension positive" in msg and "sign" in msg, msg


# --- plausibility before results -------------------------------------------------------------


def test_a_deflection_in_mm_read_as_metres_is_refused(damper: vehid.Run, tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    data = np.loadtxt(F.vehid_csv(tmp_path / "si.csv", damper), delimiter=",", skiprows=1)
    data[:, 3] *= 1e3
    path = tmp_path / "mm.csv"
    np.savetxt(path, data, delimiter=",", header="t,a_body,a_wheel,deflection", comments="", fmt="%.9g")
    msg = error(capsys, ["monitor", str(path), "--model", "passenger"])
    assert "deflection" in msg and "mm" in msg, msg


def test_accelerations_in_g_read_as_si_are_refused(damper: vehid.Run, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    data = np.loadtxt(F.vehid_csv(tmp_path / "si.csv", damper), delimiter=",", skiprows=1)
    data[:, 1:3] /= 9.80665
    path = tmp_path / "g.csv"
    np.savetxt(path, data, delimiter=",", header="t,a_body,a_wheel,deflection", comments="", fmt="%.9g")
    msg = error(capsys, ["monitor", str(path), "--model", "passenger"])
    assert "in g" in msg and "unit = \"g\"" in msg, msg


def test_a_log_of_another_car_is_refused_naming_the_car(damper: vehid.Run, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    # The passenger car's log without --model (the thesis' 10 kg car): k2/M is 14 times off.
    path = F.vehid_csv(tmp_path / "p.csv", damper)
    msg = error(capsys, ["monitor", str(path)])
    assert "--model quarter (the default" in msg and "--model passenger" in msg, msg
    ratio = float(msg.split(" is ")[1].split(" times")[0])
    assert 10 < ratio < 18, msg


# --- bags: the channel map and bad bags --------------------------------------------------------


def test_a_bag_without_a_channel_map_names_the_fix(five: Dict[str, List[str]],
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    msg = error(capsys, ["monitor", five["mcap"][0], "--model", "passenger"])
    assert "--columns channels.toml" in msg and "vehid inspect" in msg, msg


@pytest.mark.parametrize("edit, expected", [
    (("/body/imu", "/body/imu_missing"), "no topic '/body/imu_missing' for [a_body]"),
    (('field = "linear_acceleration.z"', 'field = "linear_acceleration.w"'), "no number at field"),
    (('joint = "susp_fl"', 'joint = "susp_rr"'), "no joint 'susp_rr'"),
    (('unit = "m"', 'unit = "furlong"'), "'furlong' is unknown"),
    (('gravity = "included"', 'gravity = "yes"'), "gravity = 'yes'"),
    (('unit = "m"', 'unit = "m"\nspeed = 3'), "[deflection] speed: unknown key"),
    (("[a_wheel]", "[a_wheel"), "not valid TOML"),
    (("[a_wheel]", "[a_whee]"), "[a_whee] is not a channel here"),
])
def test_a_bad_channel_map_is_one_line(five: Dict[str, List[str]], tmp_path: Path, edit: Tuple[str, str],
                                       expected: str, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(F.BAG_MAP.replace(*edit))
    msg = error(capsys, ["monitor", five["mcap"][0], "--columns", str(bad), "--model", "passenger"])
    assert expected in msg, msg


def test_a_truncated_bag_is_one_line(five: Dict[str, List[str]], tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    src = Path(five["mcap"][0])
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(src.read_bytes()[: src.stat().st_size // 2])
    msg = error(capsys, ["monitor", str(cut), "--columns", five["mcap"][2], "--model", "passenger"])
    assert str(cut) in msg and ("truncated" in msg or "not a readable" in msg), msg


def test_a_wrong_message_type_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = F.drive(12.0, seed=3)
    path = F.bag(tmp_path / "vec", run, imu_type="geometry_msgs/msg/Vector3Stamped")
    (tmp_path / "m.toml").write_text(F.BAG_MAP)
    msg = error(capsys, ["monitor", str(path), "--columns", str(tmp_path / "m.toml"), "--model", "passenger"])
    assert "topic /body/imu" in msg and "Vector3Stamped" in msg and "field" in msg, msg


@pytest.mark.parametrize("jump, said", [(-30.0, "clock jumps back"), (7200.0, "clock jumps 7200.01 s forward")])
def test_a_clock_jump_is_one_line(jump: float, said: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A bag's header stamps back 30 s, or forward 2 h (over an hour), half-way through a topic.
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    path = tmp_path / "jump"
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/defl", "std_msgs/msg/Float64", typestore=ts)
        h = w.add_connection("/h", "sensor_msgs/msg/JointState", typestore=ts)
        for k in range(100):
            stamp = k * 0.01 + (0.0 if k < 50 else jump)
            ns = int(round((F.EPOCH + stamp) * 1e9))
            msg = T["sensor_msgs/msg/JointState"](
                header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9,
                                                                                        nanosec=ns % 10**9),
                                                frame_id=""), name=["j"], position=np.array([0.0]),
                velocity=np.zeros(0), effort=np.zeros(0))
            w.write(h, int(F.EPOCH * 1e9) + k * 10**7, ts.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
            w.write(c, int(F.EPOCH * 1e9) + k * 10**7, ts.serialize_cdr(T["std_msgs/msg/Float64"](data=0.0),
                                                                            "std_msgs/msg/Float64"))
    (tmp_path / "m.toml").write_text('[a_body]\ntopic = "/defl"\nunit = "m/s^2"\n[a_wheel]\ntopic = "/defl"\n'
                                     'unit = "m/s^2"\n[deflection]\ntopic = "/h"\n')
    msg = error(capsys, ["monitor", str(path), "--columns", str(tmp_path / "m.toml"), "--model", "passenger"])
    assert "topic /h" in msg and said in msg and "stamp = \"log\"" in msg, msg


def test_a_bag_value_that_overflows_in_si_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # 1e308 g is finite in the message and infinite in m/s^2: refused naming the topic and the
    # message, not handed on to fail as an infinite sample at an index of the grid.
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "big"
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/acc", "std_msgs/msg/Float64", typestore=ts)
        for k in range(100):
            value = 1e308 if k == 60 else 0.001 * k
            w.write(c, int(F.EPOCH * 1e9) + k * 10**7, ts.serialize_cdr(ts.types["std_msgs/msg/Float64"](data=value),
                                                                        "std_msgs/msg/Float64"))
    (tmp_path / "m.toml").write_text('[a_body]\ntopic = "/acc"\nunit = "g"\n[a_wheel]\ntopic = "/acc"\n'
                                     'unit = "m/s^2"\n[deflection]\ntopic = "/acc"\nunit = "m"\n')
    msg = error(capsys, ["monitor", str(path), "--columns", str(tmp_path / "m.toml"), "--model", "passenger"])
    assert "topic /acc" in msg and "message 61 (in stamp order): 1e+308 times 9.80665" in msg, msg
    assert "beyond a float's range" in msg, msg


def test_a_revolute_joint_is_read_with_its_travel_per_radian(five: Dict[str, List[str]], damper: vehid.Run,
                                                              tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    # The suspension's JointState from a revolute joint: its position is the arm's angle, the
    # travel / 0.35 m per rad. Declared (unit = "rad", scale = 0.35) it gives the prismatic bag's
    # event (the same sample, the same new value); in degrees too. Declared without its scale,
    # refused in one line naming the fix; undeclared (the angle read as m: 2.9 times the travel),
    # the kinematic check refuses it naming the revolute joint (with R = 0.8 m it cannot tell).
    R = 0.35
    path = F.bag(tmp_path / "revolute", damper, joint_scale=R)
    ref, _ = events(capsys, [*five["mcap"], "--model", "passenger"])
    for unit in ("rad", "deg"):  # scale: m of travel per rad either way
        cmap = tmp_path / f"{unit}.toml"
        cmap.write_text(F.BAG_MAP.replace('unit = "m"', f'unit = "{unit}"\nscale = {R!r}'))
        if unit == "deg":  # the bag's angle in degrees
            path = F.bag(tmp_path / "revolute_deg", damper, joint_scale=R * math.pi / 180)
        got, err = events(capsys, [str(path), "--columns", str(cmap), "--model", "passenger"])
        assert [e["parameter"] for e in got] == [e["parameter"] for e in ref] == ["b"], err
        assert got[0]["t"] == pytest.approx(ref[0]["t"], abs=1e-9), (got, ref)
        assert got[0]["after"] == pytest.approx(ref[0]["after"], rel=1e-6), (got, ref)
    cmap = tmp_path / "noscale.toml"
    cmap.write_text(F.BAG_MAP.replace('unit = "m"', 'unit = "rad"'))
    msg = error(capsys, ["monitor", str(path), "--columns", str(cmap), "--model", "passenger"])
    assert "topic /suspension/joint_states" in msg and "is an angle (a revolute joint?)" in msg, msg
    assert "give scale = R in its channel map section, the wheel's travel per radian of the joint in m" in msg, msg
    cmap.write_text(F.BAG_MAP.replace('unit = "m"\n', ""))
    msg = error(capsys, ["monitor", str(tmp_path / "revolute"), "--columns", str(cmap), "--model", "passenger"])
    assert "not about 1: the units disagree" in msg and "a revolute joint's angle read as m? declare unit = " \
           "\"rad\" and scale = the travel per rad" in msg, msg
    # The limit the docs state: with R = 0.8 m (the angle 1.25 times the travel) the check
    # cannot tell, and the undeclared angle is read as a travel.
    events(capsys, [str(F.bag(tmp_path / "revolute_08", damper, joint_scale=0.8)), "--columns", str(cmap),
                    "--model", "passenger"])


def test_a_channel_map_is_checked_on_its_own() -> None:
    with pytest.raises(TableError, match=r"\[a_body\] needs one of topic"):
        fieldlog._spec("a_body", {"field": "x"}, "m")
    with pytest.raises(TableError, match=r"sign = 2: expected 1 or -1"):
        fieldlog._spec("a_body", {"column": "x", "sign": 2}, "m")
    assert math.isclose(fieldlog._spec("a_body", {"column": "x", "scale": 0.5}, "m").scale, 0.5)


def test_removing_the_test_bags(tmp_path: Path) -> None:
    # rosbags refuses to overwrite: a fresh folder per bag (guards the helper itself).
    run = F.drive(2.0, seed=1)
    F.bag(tmp_path / "b", run)
    from rosbags.rosbag2 import WriterError

    with pytest.raises(WriterError):
        F.bag(tmp_path / "b", run)
    shutil.rmtree(tmp_path / "b")


# --- vehid inspect ---------------------------------------------------------------------------


def test_inspect_a_bag_lists_topics_rates_and_a_channel_map(five: Dict[str, List[str]], tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    # The map it proposes is one vehid monitor reads: the same event as the hand-written map's.
    capsys.readouterr()
    assert cli.main(["inspect", five["bag folder"][0]]) == 0
    out = capsys.readouterr().out
    assert "/body/imu: sensor_msgs/msg/Imu, 28,000 messages" in out and "400 Hz" in out, out
    assert "/suspension/joint_states: sensor_msgs/msg/JointState, 7,000 messages" in out and "100 Hz" in out
    assert "logged 2.5 ms after its stamp" in out  # the writer's lags are uniform in 1..4 ms
    assert "a revolute joint's angle: unit = \"rad\" and scale = its travel in m per rad" in out, out
    proposed = out[out.index("[a_body]"):]
    (tmp_path / "proposed.toml").write_text(proposed)
    evs, _ = events(capsys, [five["bag folder"][0], "--columns", str(tmp_path / "proposed.toml"),
                             "--model", "passenger"])
    assert [e["parameter"] for e in evs] == ["b"]


def test_inspect_a_logger_csv_reads_its_units_and_clock(five: Dict[str, List[str]],
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    path, _, cmap = five["logger csv"]
    capsys.readouterr()
    assert cli.main(["inspect", path]) == 0
    out = capsys.readouterr().out
    assert "column 'Time [ms]', ms (declared)" in out and "500 Hz" in out, out
    assert "'SuspTravel [mm]': mm (declared)" in out and "can feed deflection" in out
    assert "[deflection]\ncolumn = \"SuspTravel [mm]\"" in out
    assert cli.main(["inspect", path, "--columns", cmap]) == 0
    out = capsys.readouterr().out
    ms = float(out.split("clock: deflection is ")[1].split(" ms late")[0])
    assert abs(ms - 4.0) < 1.0, out


def test_inspect_guesses_units_not_declared(damper: vehid.Run, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    data = np.loadtxt(F.vehid_csv(tmp_path / "si.csv", damper), delimiter=",", skiprows=1)
    path = tmp_path / "raw.csv"
    np.savetxt(path, np.column_stack([data[:, 0] * 1e3, data[:, 1] / 9.80665 + 1, data[:, 2], data[:, 3] * 1e3]),
               delimiter=",", header="time,body_acc,wheel_acc,susp_travel", comments="", fmt="%.9g")
    capsys.readouterr()
    assert cli.main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "ms? (no unit declared" in out and "'body_acc': g? (mean 1" in out, out
    assert "'susp_travel': mm? (guessed)" in out, out


def test_inspect_refuses_a_truncated_bag_in_one_line(five: Dict[str, List[str]], tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    src = Path(five["mcap"][0])
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(src.read_bytes()[: src.stat().st_size // 3])
    assert str(cut) in error(capsys, ["inspect", str(cut)])


# --- vehid identify: the wheel mass from the car the user named ---------------------------------


def test_identify_takes_the_wheel_mass_from_truth(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # The thesis car scaled by 40 (m = 40 kg): with --truth naming m and no --m, the constants
    # are the truth's (before: every one 1/40 of it, with tight intervals), and a note says why.
    big = {"M": 400.0, "m": 40.0, "k1": 3600.0, "k2": 2000.0, "b": 1600.0}
    run = vehid.Simulator(vehid.QuarterCar(**big), seed=8).run(6000)
    path = tmp_path / "big.csv"
    with open(path, "w") as f:
        f.write(",".join(cli.csv_header(4, 1)[:9]) + "\n")  # t, x, dx: no true_* columns
        np.savetxt(f, np.column_stack([run.t, run.r, run.z]), delimiter=",", fmt="%.10g")  # measured
    truth = ",".join(f"{k}={v:g}" for k, v in big.items())
    capsys.readouterr()
    assert cli.main(["identify", str(path), "--model", "quarter", "--truth", truth, "--method", "ls", "--json"]) == 0
    out, err = capsys.readouterr()
    assert "m = 40 kg from --truth" in err, err
    physical = json.loads(out)["physical_intervals"]
    for k in ("M", "k2", "b"):
        assert abs(physical[k][0] / big[k] - 1) < 0.1, (k, physical)


def test_identify_reads_units_in_brackets(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # The same run with the positions in mm, the wheel velocity in mm/s and the time in ms: the
    # same identified rows as in SI (before: constants 1000 times off with tight intervals).
    run = vehid.Simulator(vehid.QuarterCar(), seed=3).run(3000)
    si, mm = tmp_path / "si.csv", tmp_path / "mm.csv"
    data = np.column_stack([run.t, run.r, run.z])
    header = cli.csv_header(4, 1)[:9]
    np.savetxt(si, data, delimiter=",", header=",".join(header), comments="", fmt="%.12g")
    scale = np.array([1e3, 1e3, 1e3, 1e3, 1, 1e3, 1, 1, 1])
    units = ["t [ms]", "x1 [mm]", "x2 [mm/s]", "x3 [mm]", "x4 [m/s]", "dx1 [mm/s]", "dx2", "dx3", "dx4"]
    np.savetxt(mm, data * scale, delimiter=",", header=",".join(units), comments="", fmt="%.12g")

    def theta(path: Path) -> np.ndarray:
        capsys.readouterr()
        assert cli.main(["identify", str(path), "--model", "quarter", "--json"]) == 0
        return np.asarray(json.loads(capsys.readouterr().out)["theta"])

    np.testing.assert_allclose(theta(mm), theta(si), rtol=1e-6, atol=1e-9)
    bad = tmp_path / "bad.csv"
    bad.write_text(si.read_text().replace("x1,", "x1 [inch],", 1))
    msg = error(capsys, ["identify", str(bad), "--model", "quarter"])
    assert "column 'x1 [inch]'" in msg and "'inch' is unknown" in msg, msg


def test_the_docs_worked_example_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    # docs/capabilities/field-logs.md's Python block, run in an empty directory: it prints what
    # the page says it prints.
    import re

    page = Path(__file__).resolve().parent.parent / "docs" / "capabilities" / "field-logs.md"
    blocks = re.findall(r"```python\n(.*?)```", page.read_text(encoding="utf-8"), flags=re.S)
    assert len(blocks) == 1
    monkeypatch.chdir(tmp_path)
    capsys.readouterr()
    exec(compile(blocks[0], str(page), "exec"), {})
    out, err = capsys.readouterr()
    assert " b (damper): 1500 -> " in out, out
    assert 40.0 < float(out.split()[0]) < 50.0
    assert "gravity included, removed" in err and "resampled to 200 Hz" in err, err
    ms = float(err.split("deflection: ")[1].split(" ms late")[0])
    assert abs(ms - 5.0) < 0.25 and "removed" in err, err


def test_a_declared_delay_the_data_contradict_is_named(damper: vehid.Run, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    # The deflection 20 ms late but declared on time (delay = 0): refused, naming the delay the
    # data show (fed as declared, the monitor could not judge 99 % of the time).
    (tmp_path / "zero.toml").write_text(F.LOGGER_MAP + "delay = 0.0\n")
    path = F.logger_csv(tmp_path / "late.csv", damper, late=0.020)
    msg = error(capsys, ["monitor", str(path), "--columns", str(tmp_path / "zero.toml"), "--model", "passenger"])
    assert "delay = 0 s in the channel map, but the data show 19.9" in msg or "data show 20.0" in msg, msg


@pytest.mark.parametrize("factor", [0.3, 3.0])
def test_undeclared_sensor_noise(factor: float, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Sensors 0.3 and 3 times as noisy as the defaults, not declared: the damper's event as with
    # the noise declared (--noise), within 0.5 s. At 3 times, the deflection's noise is estimated
    # from the data (within 15 % of the truth) and said in a note; without that the monitor
    # could not judge 100 % of the time.
    noise = {k: v * factor for k, v in {"a_body": 0.02, "a_wheel": 0.1, "deflection": 3e-4}.items()}
    run = vehid.Simulator(vehid.QuarterCar.passenger(), dt=0.005, road="iso8608-C", speed=15.0,
                          changes=[(40.0, {"b": 1350.0})], sensors="realistic", seed=5, sensor_noise=noise).run(14_000)
    path = tmp_path / "noisy.csv"
    np.savetxt(path, np.column_stack([run.t, run.y]), delimiter=",", header="t,a_body,a_wheel,deflection",
               comments="", fmt="%.9g")
    declared, _ = events(capsys, [str(path), "--model", "passenger", "--noise",
                                  ",".join(f"{k}={v:g}" for k, v in noise.items())])
    got, err = events(capsys, [str(path), "--model", "passenger"])
    assert [e["parameter"] for e in got] == ["b"] == [e["parameter"] for e in declared], (got, declared, err)
    assert abs(got[0]["t"] - declared[0]["t"]) < 0.5, (got, declared)
    if factor > 1:
        est = float(err.split("estimated from the data: ")[1].split(" mm")[0]) * 1e-3
        assert abs(est / noise["deflection"] - 1) < 0.15, err
    else:
        assert "noise, estimated" not in err, err


# --- results back where users look ---------------------------------------------------------------


def test_events_and_track_as_parquet_and_mcap(five: Dict[str, List[str]], tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    # On the bag's clock (since 1970), read back with pyarrow and with rosbags' reader.
    import pyarrow.parquet as pq
    from rosbags.highlevel import AnyReader

    ev_pq, ev_mcap, track = tmp_path / "ev.parquet", tmp_path / "ev.mcap", tmp_path / "track.parquet"
    evs, _ = events(capsys, [*five["mcap"], "--model", "passenger", "--events", str(ev_pq), "--track", str(track)])
    table = pq.read_table(ev_pq).to_pylist()
    assert [r["parameter"] for r in table] == ["b"] and abs(table[0]["t"] - (F.EPOCH + evs[0]["t"])) < 1e-3
    assert table[0]["low"] <= table[0]["after"] <= table[0]["high"] and table[0]["unit"] == "N s/m"
    tr = pq.read_table(track)
    assert tr.num_rows == 140 and abs(tr.column("t")[0].as_py() - (F.EPOCH + 0.5)) < 0.01
    assert abs(np.nanmedian(tr.column("k2_over_M").to_numpy()) / (22000 / 320) - 1) < 0.1
    events(capsys, [*five["mcap"], "--model", "passenger", "--events", str(ev_mcap)])
    with AnyReader([ev_mcap]) as reader:
        topics = {c.topic: c for c in reader.connections}
        assert {"/vehid/events", "/vehid/k2_over_M", "/vehid/status"} <= set(topics)
        (conn, stamp, raw), = list(reader.messages(connections=[topics["/vehid/events"]]))
        row = json.loads(reader.deserialize(raw, conn.msgtype).data)
    assert row["parameter"] == "b" and abs(stamp * 1e-9 - table[0]["t"]) < 1e-6
    msg = error(capsys, ["monitor", five["mcap"][0], "--columns", five["mcap"][2], "--model", "passenger",
                         "--events", str(tmp_path / "ev.txt")])
    assert ".parquet or .mcap" in msg


def test_identify_json_gives_a_b_and_the_modes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # The modes of the identified A (least squares on a long thesis run) against the true
    # car's poles (vehid's LinearModel.poles, an independent eigen-solver in Rust).
    run = vehid.Simulator(vehid.QuarterCar(), seed=4).run(20_000)
    path = tmp_path / "q.csv"
    np.savetxt(path, np.column_stack([run.t, run.r, run.z]), delimiter=",",
               header=",".join(cli.csv_header(4, 1)[:9]), comments="", fmt="%.12g")
    capsys.readouterr()
    assert cli.main(["identify", str(path), "--model", "quarter", "--method", "ls", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    a = np.asarray(report["A"])
    assert a.shape == (4, 4) and np.asarray(report["B"]).shape == (4, 1)
    np.testing.assert_allclose(a[[1, 3]], np.asarray(report["theta"]).reshape(2, 4))
    poles = vehid.QuarterCar().poles()
    truth = sorted({(round(abs(p) / (2 * math.pi), 9), round(-p.real / abs(p), 9)) for p in poles})
    got = [(m["frequency_hz"], m["damping_ratio"]) for m in report["modes"]]
    assert len(got) == len(truth)
    for (f, z), (tf, tz) in zip(got, truth):
        assert abs(f / tf - 1) < 0.1 and abs(z - tz) < 0.1, (got, truth)


def test_identify_realistic_reads_bags_and_logger_files(five: Dict[str, List[str]],
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    # The body equation from the MCAP bag, the logger's CSV (ms, g, mm, 500 Hz, the deflection
    # 4 ms late) and vehid's CSV: k2 within each other's 95 % intervals, and near the truth.
    found = {}
    for name in ("vehid csv", "mcap", "logger csv"):
        capsys.readouterr()
        assert cli.main(["identify", *five[name], "--model", "quarter", "--sensors", "realistic", "--M", "320",
                         "--json"]) == 0
        report = json.loads(capsys.readouterr().out)
        found[name] = report["constants"]["k2"]
    for a in found.values():
        assert abs(a["value"] / 22000 - 1) < 0.01
        for b in found.values():
            assert b["low"] <= a["value"] <= b["high"], found


def test_standard_input_reads_units_too(damper: vehid.Run, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    import io as _io

    si = F.vehid_csv(tmp_path / "si.csv", damper)
    data = np.loadtxt(si, delimiter=",", skiprows=1)
    text = "t [ms],a_body,a_wheel,deflection [mm]\n" + "".join(
        f"{t * 1e3:.6f},{a!r},{b!r},{c * 1e3!r}\n" for t, a, b, c in data.tolist())
    ref, _ = events(capsys, [str(si), "--model", "passenger"])
    monkeypatch.setattr("sys.stdin", _io.StringIO(text))
    got, err = events(capsys, ["-", "--model", "passenger"])
    assert [e["parameter"] for e in got] == ["b"] and abs(got[0]["t"] - ref[0]["t"]) < 1e-6, err


def test_a_clock_jump_in_a_table_is_a_long_gap_or_one_line(damper: vehid.Run, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    # Forward, the table's one clock cannot tell a jump from a pause: a long gap (fed as 60 s of
    # missing samples, said in a note naming its line; tests/test_monitor_gaps.py); backward,
    # refused in one line naming it.
    data = np.loadtxt(F.vehid_csv(tmp_path / "si.csv", damper), delimiter=",", skiprows=1)
    data[7000:, 0] += 86_400.0  # a day forward half-way
    path = tmp_path / "jump.csv"
    np.savetxt(path, data, delimiter=",", header="t,a_body,a_wheel,deflection", comments="", fmt="%.10g")
    _, err = events(capsys, [str(path), "--model", "passenger"])
    assert "line 7002: a gap of 86400 s (1 days) in the time column: fed to the monitor as 60 s" in err, err
    data[7000:, 0] -= 2 * 86_400.0  # and back
    np.savetxt(path, data, delimiter=",", header="t,a_body,a_wheel,deflection", comments="", fmt="%.10g")
    msg = error(capsys, ["monitor", str(path), "--model", "passenger"])
    assert "line 7002" in msg and "does not increase" in msg, msg


@pytest.mark.parametrize("body_ms", [6.0, -3.0, 20.0])
def test_a_late_body_accelerometer_is_found_and_removed(body_ms: float, damper: vehid.Run, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    # Three clocks: the deflection 4 ms late and the body accelerometer 6 or 20 ms late (or 3 ms
    # early) against the wheel's: both estimated and removed; the damper's event as in vehid's
    # CSV of the same drive.
    (tmp_path / "logger.toml").write_text(F.LOGGER_MAP)
    ref, _ = events(capsys, [str(F.vehid_csv(tmp_path / "ref.csv", damper)), "--model", "passenger"])
    path = F.logger_csv(tmp_path / "three.csv", damper, body_late=body_ms * 1e-3)
    got, err = events(capsys, [str(path), "--columns", str(tmp_path / "logger.toml"), "--model", "passenger"])
    word = "late" if body_ms > 0 else "early"
    est = float(err.split("a_body: ")[1].split(f" ms {word}")[0]) * (1 if body_ms > 0 else -1)
    assert abs(est - body_ms) < 1.0, err
    # Within 0.25 ms (the first estimate of the deflection's, before both were refined in turn,
    # was 0.75 ms short with the body 20 ms late).
    assert abs(float(err.split("deflection: ")[1].split(" ms late")[0]) - 4.0) < 0.25, err
    assert [e["parameter"] for e in got] == ["b"] and abs(got[0]["t"] - ref[0]["t"]) < 0.1, (got, ref)


def test_the_half_cars_front_deflection_late(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # The half car, its front deflection 5 ms late: found per axle (d_f'' = a_body_f - a_wheel_f)
    # and removed; the front damper's event as in the log without the delay (within 1 s).
    sim = vehid.Simulator(vehid.HalfCar.passenger(), dt=0.005, road="iso8608-C", speed=15.0,
                          changes=[(40.0, {"b_f": 1440.0})], sensors="realistic", seed=3)
    run = sim.run(16_000)
    header = "t," + ",".join(run.channels or ())
    ok, late = tmp_path / "ok.csv", tmp_path / "late.csv"
    np.savetxt(ok, np.column_stack([run.t, run.y]), delimiter=",", header=header, comments="")
    y = run.y.copy()
    j = (run.channels or ()).index("deflection_f")
    y[:, j] = F.delayed(y[:, j], 0.005, 0.005)
    np.savetxt(late, np.column_stack([run.t, y]), delimiter=",", header=header, comments="")
    ref, _ = events(capsys, [str(ok), "--model", "half"])
    got, err = events(capsys, [str(late), "--model", "half"])
    assert abs(float(err.split("deflection_f: ")[1].split(" ms late")[0]) - 5.0) < 1.0, err
    assert "deflection_r:" not in err
    assert [e["parameter"] for e in got] == [e["parameter"] for e in ref] == ["b_f"], (got, ref)
    assert abs(got[0]["t"] - ref[0]["t"]) < 1.0


def test_inspect_reads_around_a_text_column(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "events.csv"
    path.write_text("t [ms],a_body,Event,deflection [mm]\n0,0.1,start,1\n5,0.2,,2\n10,0.3,bump,3\n")
    capsys.readouterr()
    assert cli.main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "column 'Event': not numbers ('start' is not a number); not read" in out, out
    assert "'deflection [mm]': mm (declared); mean 2," in out and "200 Hz" in out, out


# --- the accelerometers' noise from the data -------------------------------------------------------

#: The simulated sensors' default white noise (``SensorNoise::default``), m/s^2, m/s^2, m.
NOISE_DEFAULTS = {"a_body": 0.02, "a_wheel": 0.1, "deflection": 3e-4}


def noisy_drive(path: Path, half: bool, factor: float, seed: int, seconds: float = 300.0,
                changes: List[Tuple[float, Dict[str, float]]] = ()) -> Dict[str, float]:  # type: ignore[assignment]
    """A passenger car's drive at 200 Hz, every sensor's noise ``factor`` times the defaults,
    written as vehid's CSV to ``path``; returns the noise (the truth)."""
    noise = {k: v * factor for k, v in NOISE_DEFAULTS.items()}
    car = vehid.HalfCar.passenger() if half else vehid.QuarterCar.passenger()
    sim = vehid.Simulator(car, dt=0.005, road="iso8608-C", speed=15.0, changes=list(changes), sensors="realistic",
                          seed=seed, sensor_noise=noise)
    run = sim.run(int(round(seconds / 0.005)))
    np.savetxt(path, np.column_stack([run.t, run.y]), delimiter=",", header="t," + ",".join(sim.channels or ()),
               comments="", fmt="%.9g")
    return noise


def summary_noise(err: str) -> Dict[str, Tuple[float, str]]:
    """The summary's ``noise per sample: NAME VALUE UNIT (ORIGIN), ...`` (SI, origin)."""
    line = next(x for x in err.splitlines() if "noise per sample: " in x)
    out = {}
    for name, value, unit, origin in re.findall(r"(a_body|a_wheel|deflection) ([0-9.e+-]+) (m/s\^2|mm) \(([^)]*)\)",
                                                line.split("noise per sample: ")[1]):
        out[name] = (float(value) * (1e-3 if unit == "mm" else 1.0), origin)
    return out


@pytest.mark.parametrize("half,factor,seed", [(False, 0.3, 7301), (False, 1.0, 7302), (False, 3.0, 7303),
                                              (True, 0.3, 7304), (True, 1.0, 7305), (True, 3.0, 7306)])
def test_the_accelerometers_noise_is_estimated_from_the_data(half: bool, factor: float, seed: int, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str],
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    # 300 s of the passenger car (quarter and half), every sensor 0.3-3 times as noisy as the
    # defaults, undeclared: the summary gives the body's and the wheel's noise from the data within
    # 20 % of the simulation's (seeds not used to build the estimator); the monitor is given them
    # when over 1.25 times the defaults (else it keeps the defaults: a log at them is monitored
    # as before).
    path = tmp_path / "drive.csv"
    truth = noisy_drive(path, half, factor, seed)
    given: List[Dict[str, float]] = []
    real = monitor_cmd.HealthMonitor

    def recording(*args: object, **kw: object) -> vehid.HealthMonitor:
        given.append(dict(kw.get("sensor_noise") or {}))  # type: ignore[call-overload]
        return real(*args, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(monitor_cmd, "HealthMonitor", recording)
    _, err = events(capsys, [str(path), "--model", "half" if half else "passenger"])
    got = summary_noise(err)
    for name in ("a_body", "a_wheel"):
        value, origin = got[name]
        if factor > 1.25:
            assert origin == "from the data", err
            assert abs(given[-1][name] / value - 1) < 5e-3, (given, got)  # the monitor runs with it
        else:
            assert value == NOISE_DEFAULTS[name] and name not in given[-1], (given, err)
            value = float(re.fullmatch(r"the default; the data: ([0-9.e+-]+) m/s\^2", origin).group(1))  # type: ignore[union-attr]
        assert abs(value / truth[name] - 1) < 0.2, (name, value, truth[name], err)
    assert got["deflection"][1] == "from the data" if factor > 1.25 else got["deflection"][1].startswith("the default")


@pytest.mark.parametrize("half,factor,seed", [(False, 0.3, 7321), (False, 3.0, 7322), (True, 3.0, 7323)])
def test_inspect_shows_the_sensor_noise_estimated_from_the_data(half: bool, factor: float, seed: int, tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    # vehid inspect gives each sensor's noise from the data (the half car's per axle) beside the
    # monitor's default, marked "used" where the monitor takes it (over 1.25 times the default):
    # the figures the monitor's summary gives (the half car's: the larger axle's), the
    # accelerometers' within 20 % of the simulation's (the deflection's too at 3 times the
    # defaults; at 0.3 times its spectrum's floor is the road's, not the sensor's).
    path = tmp_path / "drive.csv"
    truth = noisy_drive(path, half, factor, seed, seconds=150.0)
    capsys.readouterr()
    assert cli.main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if "sensor noise per sample, estimated from the data" in x)
    got = {name: (value, unit, default, used) for name, value, unit, default, used in
           re.findall(r"((?:a_body|a_wheel|deflection)(?:_[fr])?) ([0-9.e+-]+) (m/s\^2|mm) "
                      r"\(default ([0-9.e+-]+)(?: mm)?(: used)?\)", line)}
    axles = ("_f", "_r") if half else ("",)
    assert set(got) == {f"{c}{a}" for c in NOISE_DEFAULTS for a in axles}, line
    _, err = events(capsys, [str(path), "--model", "half" if half else "passenger"])
    summary = summary_noise(err)
    for name in NOISE_DEFAULTS:
        si = 1e-3 if name == "deflection" else 1.0
        for a in axles:
            value, unit, default, used = got[name + a]
            assert float(default) * si == NOISE_DEFAULTS[name], line
            assert bool(used) == (factor > 1.25), line
            if name != "deflection" or factor > 1.25:
                assert abs(float(value) * si / truth[name] - 1) < 0.2, (name + a, line)
        monitor_value, origin = summary[name]
        shown = f"{monitor_value / si:.3g}" if origin == "from the data" else origin.split("the data: ")[1].split()[0]
        assert float(shown) == max(float(got[name + a][0]) for a in axles), (name, line, err)  # the monitor's figure


def test_the_accelerometers_noise_against_scipys_welch_where_it_is_the_only_signal() -> None:
    # Independent check of the estimator's scale (the periodogram's normalization, the Whittle
    # level): with the car at rest (zero deflection), the body equation's residual is the body
    # accelerometer's noise alone and the kinematic one the wheel's: scipy's Welch spectrum of
    # each raw channel gives its variance per sample.
    rng = np.random.default_rng(11)
    n, dt = 60_000, 0.005
    d = 3e-4 * rng.standard_normal(n)
    ab, aw = 0.05 * rng.standard_normal(n), 0.2 * rng.standard_normal(n)
    s = align.sensor_noise(ab, aw, d, dt, [3e-4])
    for est, x in ((s.a_body, ab), (s.a_wheel, aw)):
        f, pxx = signal.welch(x, fs=1 / dt, nperseg=4096)
        welch = math.sqrt(float(np.mean(pxx[(f > 0.2) & (f < 2.0)])) / (2 * dt))
        assert abs(est / welch - 1) < 0.1, (est, welch)


def test_declared_noise_wins_and_is_said(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "drive.csv"
    noisy_drive(path, False, 2.0, 7311, seconds=80.0)
    _, err = events(capsys, [str(path), "--model", "passenger", "--noise", "a_body=0.05"])
    got = summary_noise(err)
    assert got["a_body"] == (0.05, "declared"), err
    assert got["a_wheel"][1] == "from the data", err


def test_a_change_of_the_car_does_not_spoil_the_body_noise(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # The damper -10 % at 100 s and the spring -10 % at 200 s: the body equation changes twice;
    # fitted window by window, the body's noise stays within 20 % of the truth.
    path = tmp_path / "drive.csv"
    truth = noisy_drive(path, False, 2.0, 7312, changes=[(100.0, {"b": 1350.0}), (200.0, {"k2": 19800.0})])
    _, err = events(capsys, [str(path), "--model", "passenger"])
    got = summary_noise(err)
    assert abs(got["a_body"][0] / truth["a_body"] - 1) < 0.2, err


@pytest.mark.parametrize("late_ms", [{"a_body_r": 20.0}, {"a_body_f": 12.0, "a_body_r": 5.0, "deflection_r": 4.0},
                                     {"a_body_f": 20.0, "deflection_f": 3.0}])
def test_the_half_cars_body_accelerometers_late(late_ms: Dict[str, float], tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    # The half car, each axle's body accelerometer 0-20 ms late against its wheel's (and a
    # deflection late too): each found from its corner's body equation (both axles' deflections
    # and rates) within 1 ms and removed; the front damper's event as in the log without delays.
    sim = vehid.Simulator(vehid.HalfCar.passenger(), dt=0.005, road="iso8608-C", speed=15.0,
                          changes=[(40.0, {"b_f": 1440.0})], sensors="realistic", seed=11)
    run = sim.run(16_000)
    names = list(run.channels or ())
    header = "t," + ",".join(names)
    ok, late = tmp_path / "ok.csv", tmp_path / "late.csv"
    np.savetxt(ok, np.column_stack([run.t, run.y]), delimiter=",", header=header, comments="")
    y = run.y.copy()
    for name, ms in late_ms.items():
        y[:, names.index(name)] = F.delayed(y[:, names.index(name)], ms * 1e-3, 0.005)
    np.savetxt(late, np.column_stack([run.t, y]), delimiter=",", header=header, comments="")
    ref, _ = events(capsys, [str(ok), "--model", "half"])
    got, err = events(capsys, [str(late), "--model", "half"])
    for axle in ("_f", "_r"):
        truth = late_ms.get(f"a_body{axle}", 0.0)
        found = re.search(rf"a_body{axle}: ([0-9.]+) ms late against the wheel accelerometer", err)
        if truth < 0.25:
            assert found is None or float(found.group(1)) < 1.0, err
        else:
            assert found is not None and abs(float(found.group(1)) - truth) < 1.0, err
    assert [e["parameter"] for e in got] == [e["parameter"] for e in ref] == ["b_f"], (got, ref, err)
    assert abs(got[0]["t"] - ref[0]["t"]) < 1.0, (got, ref)


def test_a_half_car_body_corner_follows_both_axles() -> None:
    # A half car's body corner accelerates with both axles' deflections and rates (through 1/M
    # and l^2/J): with the other axle's deflection as a regressor the body equation fits closer
    # (1 - correlation at least a third smaller) and the body accelerometer's delay (12 ms, by an
    # FFT phase shift) is found within 0.25 ms (the delay tolerance).
    sim = vehid.Simulator(vehid.HalfCar.passenger(), dt=0.005, road="iso8608-C", speed=15.0, sensors="realistic",
                          seed=13)
    run = sim.run(16_000)
    names = list(run.channels or ())
    y = run.y
    for axle, other in (("_f", "_r"), ("_r", "_f")):
        body = F.delayed(y[:, names.index(f"a_body{axle}")], 0.012, 0.005)
        alone = align.estimate_body_delay(body, y[:, names.index(f"deflection{axle}")], 0.005)
        both = align.estimate_body_delay(body, y[:, names.index(f"deflection{axle}")], 0.005,
                                         others=[y[:, names.index(f"deflection{other}")]])
        assert 1 - both.corr < (2 / 3) * (1 - alone.corr), (axle, alone, both)
        assert abs(both.delay - 0.012) < 2.5e-4, (axle, both)


def test_events_and_track_from_standard_input(damper: vehid.Run, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    # `--events` and `--track` on a log read from standard input: the same rows as from the file
    # (times on the log's clock, its time column's), read back with pyarrow; and the MCAP form.
    import io as _io

    import pyarrow.parquet as pq

    path = F.vehid_csv(tmp_path / "drive.csv", damper)
    out = {kind: (tmp_path / f"{kind}_events.parquet", tmp_path / f"{kind}_track.parquet")
           for kind in ("file", "stdin")}
    events(capsys, [str(path), "--model", "passenger", "--events", str(out["file"][0]), "--track", str(out["file"][1])])
    monkeypatch.setattr("sys.stdin", _io.StringIO(path.read_text()))
    got, _ = events(capsys, ["-", "--model", "passenger", "--events", str(out["stdin"][0]), "--track",
                             str(out["stdin"][1])])
    rows = {kind: pq.read_table(ev).to_pylist() for kind, (ev, _) in out.items()}
    assert [r["parameter"] for r in rows["stdin"]] == ["b"] and rows["stdin"] == rows["file"], rows
    assert abs(rows["stdin"][0]["t"] - got[0]["t"]) < 1e-9
    tracks = {kind: pq.read_table(tr).to_pydict() for kind, (_, tr) in out.items()}
    assert tracks["stdin"]["t"] == tracks["file"]["t"] and len(tracks["stdin"]["t"]) == 140
    np.testing.assert_allclose(tracks["stdin"]["k2_over_M"], tracks["file"]["k2_over_M"], equal_nan=True)
    mcap = tmp_path / "ev.mcap"
    monkeypatch.setattr("sys.stdin", _io.StringIO(path.read_text()))
    events(capsys, ["-", "--model", "passenger", "--events", str(mcap)])
    assert mcap.stat().st_size > 0


def test_a_ros1_bag_and_a_split_bag_read_as_the_mcap(five: Dict[str, List[str]], damper: vehid.Run, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    # The same drive as a ROS 1 .bag (rosbags' ROS 1 writer) and as a rosbag2 folder split into
    # two MCAP files: the same event as the single MCAP file's, to the digit; one file of the
    # split bag alone is refused in one line naming the folder to give.
    bag_map = five["mcap"][2]
    ros1 = F.bag(tmp_path / "drive.bag", damper, storage="ros1")
    split = F.split_bag(tmp_path / "split", damper)
    assert sorted(p.name for p in split.glob("*.mcap")) == ["split_0.mcap", "split_1.mcap"]
    ref, err = events(capsys, [*five["mcap"], "--model", "passenger"])
    for path in (ros1, split):
        got, _ = events(capsys, [str(path), "--columns", bag_map, "--model", "passenger"])
        assert [(e["parameter"], e["t"], e["after"]) for e in got] == [(e["parameter"], e["t"], e["after"])
                                                                      for e in ref], (path, got, ref)
    msg = error(capsys, ["monitor", str(split / "split_1.mcap"), "--columns", bag_map, "--model", "passenger"])
    assert "part 2 of 2 of a split bag" in msg and f"give the bag's folder, {split}," in msg, msg
    # The bag's JointState (100 Hz) is slower than the 200 Hz grid: the body's noise is not
    # estimated; the wheel's, an upper bound sqrt(s_body^2 + s_wheel^2), is per grid sample (the
    # 400 Hz IMU's 0.1 m/s^2 averaged to 200 Hz: 0.1 / sqrt(2)).
    got_noise = summary_noise(err)
    assert got_noise["a_body"] == (0.02, "the default"), err
    wheel = float(got_noise["a_wheel"][1].split("the data: ")[1].split(" m/s^2")[0])
    assert abs(wheel / (math.hypot(0.02, 0.1) / math.sqrt(2)) - 1) < 0.1, err


def test_the_bags_differ_from_the_tables_by_their_deflections_sampling(tmp_path: Path,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    # Why the bags' event lands 10-75 ms from the tables' (docs: "One drive, five ways"): not
    # the bag, its stamps or its 1-4 ms logging lag, but the JointState sampling the deflection at
    # 100 Hz without a filter (its noise above 50 Hz folds into the band). Seed 5, where the
    # bag lands 45 ms early: with the JointState at 400 Hz the bag's event is the Parquet
    # table's (the same sample, the new value within 0.01 N s/m); at 100 Hz low-passed before it
    # is sampled, within two samples (10 ms).
    run = F.drive(70.0, changes=[(40.0, {"b": 1350.0})], seed=5)
    (tmp_path / "bag.toml").write_text(F.BAG_MAP)
    argv = ["--columns", str(tmp_path / "bag.toml"), "--model", "passenger"]
    table, _ = events(capsys, [str(F.parquet(tmp_path / "drive.parquet", run)), "--model", "passenger"])
    as_sampled, _ = events(capsys, [str(F.bag(tmp_path / "b100", run)), *argv])
    fast, _ = events(capsys, [str(F.bag(tmp_path / "b400", run, joint_every=1)), *argv])
    filtered, _ = events(capsys, [str(F.bag(tmp_path / "b100aa", run, antialias=True)), *argv])
    assert [(e["parameter"], e["t"]) for e in fast] == [(e["parameter"], e["t"]) for e in table], (fast, table)
    assert abs(fast[0]["after"] - table[0]["after"]) < 0.01, (fast, table)
    assert [e["parameter"] for e in filtered] == ["b"] and abs(filtered[0]["t"] - table[0]["t"]) < 0.0101, filtered
    assert abs(as_sampled[0]["t"] - table[0]["t"]) > 0.025, (as_sampled, table)

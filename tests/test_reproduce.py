"""`vehid reproduce`: one figure per chapter end to end through the CLI (tiny iteration
counts), and the report's numbers are computed from the seed, not copied."""

from __future__ import annotations

import json
import math
import re
from html import escape as html_escape
from pathlib import Path
from typing import Any, Callable, Dict, List

import pytest

import vehid
from vehid.cli import main

ONE_PER_CHAPTER = "3-5,4-2,5-1,6-3"


def _reproduce(tmp_path: Path, seed: int, capsys: pytest.CaptureFixture[str]) -> Path:
    out = tmp_path / f"report-{seed}"
    argv = ["reproduce", "--quick", "--only", ONE_PER_CHAPTER, "--out", str(out), "--seed", str(seed),
            "--seeds", "3", "--max-iterations", "400", "--no-tables", "--quiet"]
    assert main(argv) == 0
    printed = capsys.readouterr().out.strip()
    assert Path(printed) == out / "index.md"
    return out


def test_reproduce_writes_a_report_with_verdicts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = _reproduce(tmp_path, 1, capsys)
    md = (out / "index.md").read_text(encoding="utf-8")
    for fig in ONE_PER_CHAPTER.split(","):
        assert f"### Fig {fig}:" in md
    marks = re.findall(r"\*(agrees|differs|inconclusive)\*", md)
    assert len(marks) >= 4
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "<html>" in html and ("agrees" in html or "differs" in html or "inconclusive" in html)
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        assert "matplotlib is not installed" in md
    else:
        assert (out / "fig-4-2.png").stat().st_size > 1000
        assert "fig-4-2.png" in html


def test_reproduce_without_matplotlib_writes_the_report_without_images(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], hide_package: Callable[[str], None]
) -> None:
    """Without the plot extra the report is still written, says why it has no images and how
    to get them, and links none (the missing package is simulated where `vehid.reproduce`
    imports it: the test venv has matplotlib)."""
    hide_package("matplotlib")
    out = _reproduce(tmp_path, 1, capsys)
    md = (out / "index.md").read_text(encoding="utf-8")
    assert "matplotlib is not installed (`pip install vehid[plot]`)" in md
    for fig in ONE_PER_CHAPTER.split(","):
        assert f"### Fig {fig}:" in md
    assert not list(out.glob("*.png"))
    assert ".png" not in md and ".png" not in (out / "index.html").read_text(encoding="utf-8")


def test_reproduce_numbers_follow_the_seed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = json.loads((_reproduce(tmp_path, 1, capsys) / "report.json").read_text(encoding="utf-8"))
    b = json.loads((_reproduce(tmp_path, 2, capsys) / "report.json").read_text(encoding="utf-8"))
    measured_a = [v["measured"] for f in a["figures"] for v in f["verdicts"]]
    measured_b = [v["measured"] for f in b["figures"] for v in f["verdicts"]]
    assert measured_a != measured_b
    finals_a = [c["final_xi"] for f in a["figures"] for c in f["curves"]]
    finals_b = [c["final_xi"] for f in b["figures"] for c in f["curves"]]
    assert all(x != y for x, y in zip(finals_a, finals_b))


def test_reproduce_run_api_and_errors() -> None:
    data = vehid.reproduce.run(quick=True, only=["4-7", "6-9"], seeds=1, max_iterations=50, tables=False)
    ids = [f["id"] for f in data["figures"]]
    assert ids == ["4-7", "6-9"]
    assert data["figures"][0]["curves"] == []  # analytic figure
    assert len(data["figures"][1]["curves"]) == 3 and data["figures"][1]["skipped"] is None
    with pytest.raises(ValueError, match="only"):
        vehid.reproduce.run(quick=True, only=["9-9"], tables=False)


# The report's keys: the binding's conversion (crates/vehid-py/src/reproduce.rs) writes the
# field names of vehid_thesis::report, whose JSON the Rust test
# crates/vehid-thesis/tests/experiments.rs checks against the same lists.
REPORT_KEYS = {"quick", "base_seed", "threads", "seconds", "figures", "tables"}
FIGURE_KEYS = {"id", "title", "model", "thesis_iterations", "iterations", "seeds", "assumptions", "skipped", "k",
               "curves", "verdicts"}
SERIES = ("median", "p10", "p90", "final_xi", "settle", "reach", "min_xi", "argmin", "reinits")
CURVE_KEYS = {"label", "ident", "ic", "road", "state", "deriv", "pulse_width", "constants", *SERIES}
VERDICT_KEYS = {"claim", "measured", "agrees", "note"}
TABLE_KEYS = {"title", "method", "rows"}
ROW_KEYS = {"label", "thesis", "vehid", "agrees", "note"}


def test_reproduce_run_gives_real_floats_nan_and_inf() -> None:
    # Batch LS (Fig 3-5) has no estimate before the data have full rank (nan), and with state
    # noise ξ never settles below 0.08 on some curves (inf): real floats, no strings to parse.
    data = vehid.reproduce.run(quick=True, only=["3-5"], seed=1, seeds=3, max_iterations=200, threads=2, tables=False)
    assert set(data) == REPORT_KEYS
    fig = data["figures"][0]
    assert set(fig) == FIGURE_KEYS
    assert (fig["id"], fig["model"], fig["thesis_iterations"], fig["skipped"]) == ("3-5", "Quarter", 500, None)
    assert all(isinstance(k, int) for k in fig["k"])
    for c in fig["curves"]:
        assert set(c) == CURVE_KEYS
        assert c["ident"] == "BatchLs"
        assert all(isinstance(v, float) for key in SERIES for v in c[key])
    for v in fig["verdicts"]:
        assert set(v) == VERDICT_KEYS
    assert any(math.isnan(v) for c in fig["curves"] for v in c["median"])
    assert any(v == math.inf for c in fig["curves"] for v in c["settle"])


def test_reproduce_tables_have_their_keys() -> None:
    data = vehid.reproduce.run(quick=True, only=["4-7"], seeds=1, max_iterations=10)
    assert [t["title"].split(":")[0] for t in data["tables"]] == ["Eq 4.28", "Eq 4.32", "Eq 4.34", "Table I"]
    for t in data["tables"]:
        assert set(t) == TABLE_KEYS
        assert all(set(r) == ROW_KEYS and isinstance(r["agrees"], bool) for r in t["rows"])


def test_reproduce_cli_rejects_bad_arguments(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["reproduce", "--only", "9-9", "--out", "/nonexistent/never", "--quiet"]) == 2
    assert "only" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["reproduce", "--seeds", "0"])


def test_reproduce_defines_xi_once_in_words_and_formula(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = _reproduce(tmp_path, 1, capsys)
    md = (out / "index.md").read_text(encoding="utf-8")
    html = (out / "index.html").read_text(encoding="utf-8")
    # Near the top: before the summary, once.
    assert md.count("## ξ, the error measure") == 1 and md.index("## ξ, the error measure") < md.index("## Summary")
    assert "sum of the squared relative errors" in md and "ξ_k = Σ_i ((θ_i − θ̂_i(k)) / θ_i)²" in md
    assert "ξ < 0.08 is the thesis' \"acceptable\"" in md
    assert html.count("<h2>ξ, the error measure</h2>") == 1
    assert html.index("<h2>ξ, the error measure</h2>") < html.index("<h2>Summary</h2>")
    assert "sum of the squared relative errors" in html and "θ̂<sub>i</sub>(k)" in html


COUNTS = re.compile(r"^reproduce: (\d+) agree, (\d+) differ, (\d+) inconclusive, in (\d+\.\d) s$")


def test_reproduce_a_lower_bound_is_inconclusive_not_agrees(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    # Fig 4-2 claims ξ < 0.08 takes more than 40,000 iterations; 400 iterations can only bound
    # that from below: the runner says "lower bound only" (and agrees = true), the report
    # says inconclusive, everywhere it counts or marks verdicts.
    out = tmp_path / "lb"
    assert main(["reproduce", "--quick", "--only", "4-2", "--out", str(out), "--seeds", "2",
                 "--max-iterations", "400", "--no-tables"]) == 0
    captured = capsys.readouterr()
    data = json.loads((out / "report.json").read_text(encoding="utf-8"))
    verdicts = data["figures"][0]["verdicts"]
    lower = [v for v in verdicts if "lower bound only" in v["note"]]
    assert len(lower) == 1 and lower[0]["agrees"] is True
    decided = [v for v in verdicts if v not in lower]
    n_agree = sum(v["agrees"] for v in decided)
    last = captured.err.strip().splitlines()[-1].split("\r")[-1].strip()
    m = COUNTS.match(last)
    assert m, last
    assert (int(m[1]), int(m[2]), int(m[3])) == (n_agree, len(decided) - n_agree, 1)

    md = (out / "index.md").read_text(encoding="utf-8")
    assert f"{n_agree} claims and table rows *agree*, {len(decided) - n_agree} *differ*, 1 *inconclusive*" in md
    confirms = md.split("### Claims vehid confirms")[1].split("### Claims vehid does not confirm")[0]
    undecided = md.split("### Claims this run cannot decide (*inconclusive*)")[1].split("## Figures")[0]
    assert lower[0]["claim"] not in confirms and lower[0]["claim"] in undecided
    row = next(line for line in md.splitlines() if line.startswith(f"| {lower[0]['claim']} |"))
    assert "| *inconclusive* |" in row
    assert sorted(re.findall(r"\| \*(agrees|differs|inconclusive)\* \|", md)) == sorted(
        ["inconclusive"] + ["agrees" if v["agrees"] else "differs" for v in decided])

    html = (out / "index.html").read_text(encoding="utf-8")
    assert "1 inconclusive" in html and "<h3>Claims this run cannot decide (inconclusive)</h3>" in html
    assert html.count('<em class="inconclusive">inconclusive</em>') == 1
    html_undecided = html.split("cannot decide (inconclusive)</h3>")[1].split("</ul>")[0]
    assert html_escape(lower[0]["claim"]) in html_undecided


def test_reproduce_header_gives_the_end_to_end_time(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    # The time the user waits includes drawing the figures: make each take 0.25 s more and
    # the header's end-to-end time (not the runner's) must show it.
    import time

    import vehid.reproduce as rep

    draw = rep._plot_figure

    def slow(*args: object) -> None:
        time.sleep(0.25)
        draw(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(rep, "_plot_figure", slow)
    monkeypatch.setattr(rep, "load_pyplot", lambda: pytest.importorskip("matplotlib.pyplot"))
    out = tmp_path / "t"
    assert main(["reproduce", "--quick", "--only", ONE_PER_CHAPTER, "--out", str(out), "--seeds", "2",
                 "--max-iterations", "100", "--no-tables"]) == 0
    err = capsys.readouterr().err.strip().splitlines()[-1].split("\r")[-1].strip()
    md = (out / "index.md").read_text(encoding="utf-8")
    html = (out / "index.html").read_text(encoding="utf-8")
    m = re.search(r"in (\d+\.\d) s end to end \(from the command's start to writing this report; "
                  r"the runner (\d+\.\d) s of it", md)
    assert m, md.splitlines()[2]
    total, runner = float(m[1]), float(m[2])
    data = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert runner == round(data["seconds"], 1)
    assert total >= runner + 4 * 0.25 - 0.05
    line = COUNTS.match(err)
    assert line, err
    assert float(line[4]) >= total - 0.05  # the final line: the whole command, the report written
    assert f"in {m[1]} s end to end" in html


def _drawn(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, data: Dict[str, Any]) -> Dict[str, Any]:
    """Renders the report and keeps every matplotlib figure open: {figure id: Axes}."""
    plt = pytest.importorskip("matplotlib.pyplot")
    kept: List[Any] = []
    monkeypatch.setattr(plt, "close", kept.append)
    vehid.reproduce.write_report(data, tmp_path / "figs")
    axes = {}
    for f in kept:
        if "identified constants" in f.get_suptitle():
            continue  # the constants beside the figure (tested on their own)
        ax = f.axes[0]
        axes[ax.get_title().split(":")[0].removeprefix("Fig ")] = ax
    return axes


def _outside_math(text: str) -> str:
    return re.sub(r"\$[^$]*\$", "", text)


def test_reproduce_figures_label_in_mathtext_with_units(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    data = vehid.reproduce.run(quick=True, only=["4-4", "4-6", "4-7", "6-9"], seed=1, seeds=2,
                               max_iterations=2000, tables=False)
    axes = _drawn(tmp_path, monkeypatch, data)
    assert set(axes) == {"4-4", "4-6", "4-7", "6-9"}
    for fid, ax in axes.items():
        texts = [ax.get_title(), ax.get_xlabel(), ax.get_ylabel()]
        texts += [t.get_text() for t in ax.get_legend().get_texts()]
        texts += [t.get_text() for t in ax.figure.texts]
        for t in texts:
            # σ, ξ and subscripts only inside mathtext: no raw underscores, no bare σ_w.
            assert "_" not in _outside_math(t) and "σ" not in _outside_math(t), (fid, t)
        if fid != "4-7":
            legend = [t.get_text() for t in ax.get_legend().get_texts()]
            assert all(r"$\sigma_u$ = " in t and " m, " in t for t in legend[:-1]), legend
            assert legend[-1] == r"$\xi$ = 0.08 (acceptable)"
            assert ax.get_ylabel().startswith(r"$\xi_k = \sum_i")
            assert "iteration $k$ (one sample = 0.05 s" in ax.get_xlabel()
            caption = ax.figure.texts[0].get_text()
            assert "road input, m" in caption and "m/s²" in caption
            assert ("rad/s" in caption) == (fid == "6-9")
    assert r"$\sigma_{w}$ = 2 % of $\sigma_{u}$" in axes["4-6"].get_title()


def test_reproduce_pulse_legends_give_the_width(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    data = vehid.reproduce.run(quick=True, only=["4-4"], seed=1, seeds=2, max_iterations=300, tables=False)
    legend = [t.get_text() for t in _drawn(tmp_path, monkeypatch, data)["4-4"].get_legend().get_texts()]
    assert [t.split(":")[0] for t in legend[:4]] == [
        f"pulse {w}, pulse width {w} × 0.05 s = {0.05 * w:.2f} s" for w in (1, 2, 3, 4)]
    md = (tmp_path / "figs" / "index.md").read_text(encoding="utf-8")
    assert "| pulse 3 (pulse width 3 × 0.05 s = 0.15 s) |" in md
    assert "| curve | σ_ic (m, m/s) | σ_u (m) | σ_w (m, m/s) | σ_v (m/s, m/s²) |" in md


def test_reproduce_log_iterations_where_the_action_is_early(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Fig 4-4: the pulses act at the ninth sample and ξ is flat after about 100: on a linear
    # axis of 2000 iterations that is the first 5 %.
    data = vehid.reproduce.run(quick=True, only=["4-4"], seed=1, seeds=2, max_iterations=2000, tables=False)
    fig = data["figures"][0]
    assert vehid.reproduce._action_is_early(fig)
    # A curve that changes evenly over the run keeps a linear axis.
    even = [10 ** (-k / 500) for k in range(1, 1001)]
    slow = dict(fig, id="9-9", k=list(range(1, 1001)),
                curves=[dict(fig["curves"][0], label="slow", pulse_width=0, median=even,
                             p10=[v / 2 for v in even], p90=[v * 2 for v in even])])
    assert not vehid.reproduce._action_is_early(slow)
    # Nor does a figure whose one moving curve moves late, beside curves that hardly move
    # early (Fig 5-2: the Lyapunov gain diverges after 100 iterations, the Venter gains sit).
    late = [10.0 if k < 500 else 10.0 ** (1 + (k - 500) / 250) for k in range(1, 1001)]
    early_flat = [8.0 if k < 50 else 6.0 for k in range(1, 1001)]
    mixed = dict(slow, id="9-8", curves=[dict(slow["curves"][0], median=late),
                                         dict(slow["curves"][0], median=early_flat)])
    assert not vehid.reproduce._action_is_early(mixed)
    axes = _drawn(tmp_path, monkeypatch, dict(data, figures=[fig, slow]))
    assert axes["4-4"].get_xscale() == "log" and "log axis" in axes["4-4"].get_xlabel()
    assert axes["9-9"].get_xscale() == "linear" and "linear axis" in axes["9-9"].get_xlabel()


def test_reproduce_analytic_figures_say_so_and_draw_no_band(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    data = vehid.reproduce.run(quick=True, only=["4-7", "4-2"], seed=1, seeds=1, max_iterations=100, tables=False)
    axes = _drawn(tmp_path, monkeypatch, data)
    title = axes["4-7"].get_title()
    assert "analytic" in title.split("\n")[1] and "not simulated" in title
    assert "seeds" not in title.replace("no seeds", "")
    assert "band over" not in title and not axes["4-7"].collections
    assert "Eq 4.25" in axes["4-7"].get_legend().get_texts()[0].get_text()
    # One seed: no band either, and the title says so.
    assert "one seed (no band)" in axes["4-2"].get_title() and not axes["4-2"].collections


def test_reproduce_draws_each_figure_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Drawing is most of the time a user waits for the report; tight_layout draws every
    # figure once more to measure its text: the figures use fixed margins instead.
    figure = pytest.importorskip("matplotlib.figure")
    draws: List[int] = []
    draw = figure.Figure.draw

    def counted(self: Any, renderer: Any) -> None:
        draws.append(1)
        draw(self, renderer)

    monkeypatch.setattr(figure.Figure, "draw", counted)
    data = vehid.reproduce.run(quick=True, only=["4-4", "4-7"], seed=1, seeds=2, max_iterations=100, tables=False)
    vehid.reproduce.write_report(data, tmp_path / "once")
    # Fig 4-4, its identified constants, Fig 4-7.
    assert (tmp_path / "once" / "fig-4-4-constants.png").exists() and len(draws) == 3


# ---- The report for an engineer: the identified physical constants ----

QUARTER_CONSTANTS = [("M", "kg", 10.0), ("k1", "N/m", 90.0), ("k2", "N/m", 50.0), ("b", "N·s/m", 40.0)]


def _constants_run() -> Dict[str, Any]:
    return vehid.reproduce.run(quick=True, only=["3-5", "4-2", "4-3", "5-1", "6-3"], seed=7, seeds=2,
                               max_iterations=400, tables=False)


def test_reproduce_json_carries_the_identified_constants(tmp_path: Path) -> None:
    data = _constants_run()
    figs = {f["id"]: f for f in data["figures"]}
    # Batch least squares (Ch. III) records none; every identifier of Ch. IV–VI does.
    assert all(c["constants"] is None for c in figs["3-5"]["curves"])
    for fid in ("4-2", "4-3", "5-1", "6-3"):
        fig = figs[fid]
        for c in fig["curves"]:
            ic = c["constants"]
            assert set(ic) == {"seed", "method", "k", "known", "constants"}
            # A decimated subset of the figure's iterations, ending at the last one.
            assert set(ic["k"]) <= set(fig["k"]) and ic["k"][-1] == fig["k"][-1]
            assert ic["k"] == sorted(ic["k"]) and len(ic["k"]) <= vehid_thesis_points() + 1
            for s in ic["constants"]:
                assert set(s) == {"name", "unit", "truth", "value", "lo", "hi"}
                assert len(s["value"]) == len(s["lo"]) == len(s["hi"]) == len(ic["k"])
    quarter = figs["4-2"]["curves"] + figs["4-3"]["curves"]
    for c in quarter:
        ic = c["constants"]
        assert [(s["name"], s["unit"], s["truth"]) for s in ic["constants"]] == QUARTER_CONSTANTS
        assert ic["known"] == [{"name": "m", "unit": "kg", "value": 1.0}]
    # The Kalman filter (Fig 4-3) and the physical structure (Fig 4-2's second curve) have a
    # covariance: a finite 95 % interval around the final estimate.
    for c in figs["4-3"]["curves"] + figs["4-2"]["curves"][1:]:
        for s in c["constants"]["constants"]:
            assert s["lo"][-1] < s["value"][-1] < s["hi"][-1], (c["label"], s)
    # Fig 4-2's Kalman filter on road noise alone has not converged after 400 iterations: its
    # rows give no positive constants (QuarterCar.physical refuses them too), so no value.
    assert all(math.isnan(v) for s in figs["4-2"]["curves"][0]["constants"]["constants"] for v in s["value"][-5:])
    # The stochastic gradient keeps no covariance: estimates, no interval.
    for c in figs["5-1"]["curves"]:
        assert all(math.isnan(v) for s in c["constants"]["constants"] for v in s["lo"] + s["hi"])
        assert "no interval" in c["constants"]["method"]
    half = figs["6-3"]["curves"][0]["constants"]
    assert {s["name"] for s in half["constants"]} == {"M", "J", "k12", "k22", "b1", "b2", "l1", "l2"}
    assert {k["name"] for k in half["known"]} == {"k11", "k21", "m1", "m2"}


def vehid_thesis_points() -> int:
    """vehid_thesis::CONSTANT_POINTS (the decimation of the constants' grid)."""
    return 40


def _library_run(curve: Dict[str, Any], n: int) -> vehid.Simulator:
    sim = vehid.Simulator(vehid.QuarterCar(), dt=0.05, road_sigma=curve["road"], ic_sigma=curve["ic"],
                          state_noise=curve["state"], deriv_noise=curve["deriv"], seed=curve["constants"]["seed"])
    return sim.run(n)


def test_reproduce_final_constants_are_the_librarys(tmp_path: Path) -> None:
    # Fig 4-3's Kalman filter (σ_u = 0.025) and Fig 4-2's physical structure, run again through
    # the Python API on the same seeds and data.
    data = vehid.reproduce.run(quick=True, only=["4-3", "4-2"], seed=3, seeds=2, max_iterations=600, tables=False)
    fig43, fig42 = data["figures"]
    car = vehid.QuarterCar()
    kalman, physical = fig43["curves"][3], fig42["curves"][1]
    # The Kalman filter on the free rows (P(0) = 1000, R from σ_u and σ_v, no outlier gate, as
    # the runner): the constants from its rows with the wheel mass known.
    run = _library_run(kalman, fig43["k"][-1])
    kf = vehid.KalmanIdentifier(car, p0=1000.0, road_sigma=kalman["road"], deriv_noise=kalman["deriv"], gate=0.0)
    kf.fit(run.r, run.z)
    lib = car.physical(kf.theta, m=1.0)
    for s in kalman["constants"]["constants"]:
        assert s["value"][-1] == pytest.approx(lib[s["name"]], rel=1e-9), s["name"]
    # The physical structure (m known, exact start): values and 95 % intervals by the library.
    run = _library_run(physical, fig42["k"][-1])
    ph = vehid.KalmanIdentifier(car.structure(known={"m": 1.0}), p0="exact", gate=0.0)
    ph.fit(run.r, run.z)
    lib3 = car.physical(ph.stats(alpha=0.05))
    for s in physical["constants"]["constants"]:
        got = (s["value"][-1], s["lo"][-1], s["hi"][-1])
        assert got == pytest.approx(lib3[s["name"]], rel=1e-7), s["name"]
    # The report's table gives exactly these final numbers, with the truth.
    out = tmp_path / "rep"
    vehid.reproduce.write_report(data, out)
    md = (out / "index.md").read_text(encoding="utf-8")
    html = (out / "index.html").read_text(encoding="utf-8")
    fmt = vehid.reproduce._fmt

    def cell(v: float, lo: float, hi: float) -> str:
        return f"{fmt(v)} [{fmt(lo)}, {fmt(hi)}]"

    for (name, unit, truth), sk in zip(QUARTER_CONSTANTS, kalman["constants"]["constants"]):
        row = f"| {name} ({unit}) | {fmt(truth)} | "
        lines = [ln for ln in md.splitlines() if ln.startswith(row)]
        # Fig 4-3 (its 4th curve last), then Fig 4-2 (its Kalman filter not converged: n/a).
        assert len(lines) == 2 and lines[0].count(" | ") == 5, lines
        assert lines[0].endswith(f" | {cell(lib[name], sk['lo'][-1], sk['hi'][-1])} |"), lines
        assert lines[1] == f"{row}n/a | {cell(*lib3[name])} |", lines
        assert html_escape(cell(*lib3[name])) in html
    assert "| m (kg) | 1 | known | known |" in md
    assert "| m (kg) | 1 | known | known | known | known |" in md


def test_reproduce_report_shows_the_constants_beside_xi(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    plt = pytest.importorskip("matplotlib.pyplot")
    data = _constants_run()
    plt.close("all")  # figures other tests kept open (pyplot warns beyond 20)
    close = plt.close
    kept: List[Any] = []
    monkeypatch.setattr(plt, "close", kept.append)
    out = tmp_path / "figs"
    vehid.reproduce.write_report(data, out)
    md = (out / "index.md").read_text(encoding="utf-8")
    html = (out / "index.html").read_text(encoding="utf-8")
    for fid in ("4-2", "4-3", "5-1", "6-3"):
        name = f"fig-{fid}-constants.png"
        assert (out / name).stat().st_size > 1000
        assert f"![Fig {fid}, identified constants]({name})" in md
        assert f"<div class='pair'><img src='fig-{fid}.png'" in html and name in html
    assert not (out / "fig-3-5-constants.png").exists()
    const = {f.get_suptitle().split(":")[0]: f for f in kept if "identified constants" in f.get_suptitle()}
    assert set(const) == {"Fig 4-2", "Fig 4-3", "Fig 5-1", "Fig 6-3"}
    f = const["Fig 4-2"]
    labels = [ax.get_ylabel() for ax in f.axes if ax.get_visible()]
    assert labels == ["$M$ (kg)", "$k_{1}$ (N/m)", "$k_{2}$ (N/m)", r"$b$ (N$\cdot$s/m)"]
    for ax, (_, _, truth) in zip(f.axes, QUARTER_CONSTANTS):
        # The true value dashed, one estimate line and one interval band per curve.
        dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
        assert len(dashed) == 1 and list(dashed[0].get_ydata()) == [truth, truth]
        assert len(ax.get_lines()) == 1 + 2 and len(ax.collections) == 2
    legend = [t.get_text() for t in f.legends[0].get_texts()]
    assert legend[-2:] == ["true value", "95 % interval"]
    assert "$m$ = 1 kg" in f.get_suptitle()
    half = [ax.get_ylabel() for ax in const["Fig 6-3"].axes if ax.get_visible()]
    assert half[:2] == ["$M$ (kg)", r"$J$ (kg$\cdot$m$^2$)"]
    for f in kept:
        close(f)


# ---- Beyond the thesis: Fig B-1 drawn, Fig B-2 as a table ----

SWEEP_KEYS = {"id", "title", "origin", "samples", "full_samples", "seeds", "levels", "setup", "curves", "verdicts",
              "cpu_seconds"}
SWEEP_CURVE_KEYS = {"label", "setup", "median", "q25", "q75", "min", "max", "xi", "refused", "errors"}
HALF_KEYS = {"id", "title", "origin", "samples", "seeds", "levels", "setup", "rows", "not_run", "verdicts",
             "cpu_seconds"}
HALF_ROW_KEYS = {"label", "setup", "cells"}
HALF_CELL_KEYS = {"level", "wheel", "body", "worst_entry", "refused", "errors"}


def test_reproduce_beyond_draws_b1_and_tabulates_b2(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    plt = pytest.importorskip("matplotlib.pyplot")
    plt.close("all")  # figures other tests kept open (pyplot warns beyond 20)
    close = plt.close
    kept: List[Any] = []
    monkeypatch.setattr(plt, "close", kept.append)
    out = tmp_path / "beyond"
    assert main(["reproduce", "--quick", "--only", "B-1,B-2", "--out", str(out), "--no-tables", "--quiet"]) == 0
    assert Path(capsys.readouterr().out.strip()) == out / "index.md"
    data = json.loads((out / "report.json").read_text(encoding="utf-8"))
    # The binding's keys: those of the runner's JSON (vehid_thesis::report::{SweepResult, HalfResult}).
    sweep, half = data["sweep"], data["half_one_road"]
    assert set(sweep) == SWEEP_KEYS and all(set(c) == SWEEP_CURVE_KEYS for c in sweep["curves"])
    assert set(half) == HALF_KEYS and all(set(r) == HALF_ROW_KEYS for r in half["rows"])
    assert all(set(c) == HALF_CELL_KEYS for r in half["rows"] for c in r["cells"])
    assert (sweep["id"], sweep["samples"], half["id"]) == ("B-1", 10_000, "B-2")
    assert [len(c["xi"][0]) for c in sweep["curves"]] == [sweep["seeds"]] * len(sweep["curves"])
    # The figure exists and plots the runner's medians and bands, one line per method.
    assert (out / "fig-B-1.png").stat().st_size > 10_000
    figs = [f for f in kept if f.axes and f.axes[0].get_title().startswith("Fig B-1:")]
    assert len(figs) == 1
    ax = figs[0].axes[0]
    lines = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
    assert len(lines) == len(sweep["curves"]) == 7 and len(ax.collections) == 7
    for ln, c in zip(lines, sweep["curves"]):
        assert list(ln.get_xdata()) == sweep["levels"]
        want = [v if math.isfinite(v) and v > 0 else math.nan for v in c["median"]]
        assert ln.get_ydata() == pytest.approx(want, rel=0, abs=0, nan_ok=True)
        assert ln.get_label() == vehid.reproduce.BEYOND_NAMES[c["label"]]
    for band, c in zip(ax.collections, sweep["curves"]):
        ys = [y for path in band.get_paths() for _, y in path.vertices]
        q25 = [v for v in c["q25"] if math.isfinite(v) and v > 0]
        q75 = [v for v in c["q75"] if math.isfinite(v) and v > 0]
        assert min(ys) == pytest.approx(min(q25)) and max(ys) == pytest.approx(max(q75))
    assert ax.get_yscale() == "log" and ax.get_xscale() == "symlog"
    assert r"$\sigma_w$, % of $\sigma_u$" in ax.get_xlabel() and r"$\xi$ after 10000 samples" in ax.get_ylabel()
    assert "beyond the thesis" in ax.get_title() and "25–75 % band" in ax.get_title()
    assert "_" not in _outside_math(ax.get_title()) and "σ" not in _outside_math(ax.get_title())
    # The report's text: the figure, B-2's numbers and its reading; the claims stay in Tables.
    md = (out / "index.md").read_text(encoding="utf-8")
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "### Fig B-1:" in md and "![Fig B-1](fig-B-1.png)" in md and "<img src='fig-B-1.png'" in html
    assert "### Fig B-2:" in md and "| method | σ_w | ξ wheel rows 1, 3 |" in md
    plain = next(r for r in half["rows"] if r["label"].startswith("thesis' Kalman rows"))
    cell = plain["cells"][half["levels"].index(8.0)]
    pair = [max(a, b) for a, b in zip(cell["wheel"], cell["body"])]
    assert f"| {plain['label']} | 8 % | {vehid.reproduce._fmt(vehid.reproduce._median(cell['wheel']))} (" in md
    assert f"| {vehid.reproduce._fmt(vehid.reproduce._median(pair))} (" in md
    assert "At σ_w = 8 % no method identifies the half car on one road" in md
    assert "At σ_w = 8 % no method identifies the half car on one road" in html
    assert "### Fig B-1, beyond the thesis" in md and "### Fig B-2, beyond the thesis" in md
    assert md.count("*agrees*") + md.count("*differs*") == len(sweep["verdicts"]) + len(half["verdicts"])
    for f in kept:
        close(f)


# ---- Beyond the thesis: Fig B-3, real roads ----

ROADS_KEYS = {"id", "title", "origin", "samples", "full_samples", "seeds", "speed", "dt", "classes", "constants",
              "units", "truth", "known", "setup", "rows", "verdicts", "cpu_seconds"}
ROADS_CELL_KEYS = {"class", "value", "lo", "hi", "rel_err", "median", "min", "max", "covered", "refused", "errors"}


def test_reproduce_draws_b3_real_roads(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    plt = pytest.importorskip("matplotlib.pyplot")
    plt.close("all")
    close = plt.close
    kept: List[Any] = []
    monkeypatch.setattr(plt, "close", kept.append)
    out = tmp_path / "roads"
    argv = ["reproduce", "--quick", "--only", "B-3", "--seeds", "3", "--max-iterations", "12000", "--out", str(out),
            "--no-tables", "--quiet"]
    assert main(argv) == 0
    assert Path(capsys.readouterr().out.strip()) == out / "index.md"
    data = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert "sweep" not in data and "half_one_road" not in data
    roads = data["real_roads"]
    # The binding's keys: those of the runner's JSON (vehid_thesis::report::RoadsResult).
    assert set(roads) == ROADS_KEYS and all(set(c) == ROADS_CELL_KEYS for r in roads["rows"] for c in r["cells"])
    assert (roads["id"], roads["samples"], roads["seeds"]) == ("B-3", 12_000, 3)
    assert roads["classes"] == ["A", "B", "C", "D", "E"] and roads["constants"] == ["M", "k1", "k2", "b"]
    assert roads["truth"] == [320.0, 200_000.0, 22_000.0, 1_500.0] and roads["known"]["value"] == 40.0
    assert [r["label"] for r in roads["rows"]] == list(vehid.reproduce.ROADS_NAMES)
    for r in roads["rows"]:
        for c in r["cells"]:
            for k, t in enumerate(roads["truth"]):
                assert c["rel_err"][k] == pytest.approx([abs(v / t - 1) for v in c["value"][k]], rel=1e-12)
                assert c["covered"][k] == sum(lo <= t <= hi for lo, hi in zip(c["lo"][k], c["hi"][k]))
    # The thesis' identifier is far off (M about a sixth of its value), the real-road one close.
    thesis, real = roads["rows"]
    assert all(c["median"][0] > 0.5 for c in thesis["cells"]) and all(c["median"][0] < 0.2 for c in real["cells"])
    # The figure: one panel per constant (medians and ranges per identifier, log axis), one of coverage.
    assert (out / "fig-B-3.png").stat().st_size > 10_000
    figs = [f for f in kept if f._suptitle is not None and f._suptitle.get_text().startswith("Fig B-3:")]
    assert len(figs) == 1
    axes = figs[0].axes
    assert len(axes) == 5
    for k, ax in enumerate(axes[:4]):
        assert ax.get_yscale() == "log" and ax.get_title().startswith(vehid.reproduce._symbol(roads["constants"][k]))
        marks = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
        assert len(marks) == 2
        for ln, r in zip(marks, roads["rows"]):
            assert list(ln.get_ydata()) == pytest.approx([c["median"][k] for c in r["cells"]])
    cov = axes[4]
    heights = [p.get_height() for p in cov.patches]
    want = [vehid.reproduce._coverage(roads, c) for r in roads["rows"] for c in r["cells"]]
    assert heights == pytest.approx(want)
    assert "beyond the thesis" in figs[0]._suptitle.get_text()
    # The report's text: the figure, the numbers, the reading, the claims as a table.
    md = (out / "index.md").read_text(encoding="utf-8")
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "### Fig B-3:" in md and "![Fig B-3](fig-B-3.png)" in md and "<img src='fig-B-3.png'" in html
    assert "vehid's comparison of its identifiers on real roads" in md and "“Fig B-3”" in html
    name, m = vehid.reproduce._roads_name(real["label"]), vehid.reproduce._fmt(100 * real["cells"][0]["median"][0])
    assert f"| {name} | A | {m} (" in md
    assert "largest median error" in md and "### Fig B-3, beyond the thesis" in md
    assert md.count("*agrees*") + md.count("*differs*") == len(roads["verdicts"]) == 6
    for f in kept:
        close(f)


FULL_KEYS = {"id", "title", "origin", "seconds", "change_at", "seeds", "setup", "rows", "verdicts", "cpu_seconds"}
FULL_ROW_KEYS = {"label", "expect", "truth", "named", "delay", "change", "early"}


def test_reproduce_tabulates_b4_the_full_car_monitor(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "full"
    argv = ["reproduce", "--quick", "--only", "B-4", "--seeds", "4", "--out", str(out), "--no-tables", "--quiet"]
    assert main(argv) == 0
    assert Path(capsys.readouterr().out.strip()) == out / "index.md"
    data = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert not {"sweep", "half_one_road", "real_roads"} & set(data)
    full = data["full_car"]
    # The binding's keys: those of the runner's JSON (vehid_thesis::report::FullResult).
    assert set(full) == FULL_KEYS and all(set(r) == FULL_ROW_KEYS for r in full["rows"])
    assert (full["id"], full["seeds"], full["seconds"], full["change_at"]) == ("B-4", 4, 90.0, 60.0)
    labels = [r["label"] for r in full["rows"]]
    assert labels[:4] == [f"damper {c} −10 %" for c in ("fl", "fr", "rl", "rr")] and labels[-1] == "no change"
    assert labels[-2] == "load 100 kg in the boot" and abs(full["rows"][-2]["truth"] - 100 / 15) < 1e-12
    for r in full["rows"][:-1]:
        # Each change is named (its corner too) within the 30 s after it, at about its true size
        # (a bar's within 8 points: its share of the roll stiffness divides the error).
        tol = 8 if r["label"].startswith("anti-roll bar") else 3
        assert r["named"] == [r["expect"]] * 4 and all(0 < d < 30 for d in r["delay"]), r
        assert all(abs(c - r["truth"]) < tol for c in r["change"]) and r["early"] == 0
    assert [r["expect"] for r in full["rows"] if r["label"].startswith("anti-roll bar")] == ["arb_f", "arb_r"]
    assert full["rows"][-1]["early"] == 0 and full["rows"][-1]["named"] == [""] * 4
    assert all(v["agrees"] for v in full["verdicts"]) and len(full["verdicts"]) == 10
    # The report: the table with the numbers computed from the rows, the claims in Tables.
    md = (out / "index.md").read_text(encoding="utf-8")
    html = (out / "index.html").read_text(encoding="utf-8")
    head, rows, _ = vehid.reproduce._full_table(full)
    assert "### Fig B-4:" in md and "| " + " | ".join(head) + " |" in md
    assert rows[0][:2] == ["damper fl −10 %", "4/4"] and "| " + " | ".join(rows[0]) + " |" in md
    assert "its health monitor on the full car" in md and "“Fig B-4”" in html and "<h3>Fig B-4:" in html
    assert "### Fig B-4, beyond the thesis" in md
    assert md.count("*agrees*") + md.count("*differs*") == len(full["verdicts"])

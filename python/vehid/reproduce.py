"""``vehid reproduce``: the thesis' simulation study, regenerated, with a report.

The experiments (one per figure of Ch. III–VI, with the captions' noise levels) and the
runner live in Rust (the ``vehid-thesis`` crate); this module renders what the runner
measured: one PNG per figure (ξ_k on a log scale against iterations, themselves on a log
axis where the action is early; median and 10–90 % band over seeds; analytic figures drawn
from their formula; needs the optional ``vehid[plot]`` extra, i.e. matplotlib); beside each
figure where an identifier runs (Ch. IV–VI), a second PNG of the car's physical constants
the runner identified along the first seed (M, k1, k2, b of the quarter car; the half car's),
with their 95 % intervals and the true values; and
``index.md`` / ``index.html`` with, per figure, the thesis' claim and vehid's measured
counterpart marked *agrees*, *differs* or *inconclusive* (the run was shorter than the claim
and bounds the measured number from below only), and the tables for Eq 4.28, Eq 4.32, Eq 4.34 and
Table I. When they ran, the figures beyond the thesis (not Kessler's) follow: Fig B-1, ξ after
the run on a log scale against the state noise σ_w, one line per method for noisy states
(median and 25–75 % band over seeds, ``fig-B-1.png``), Fig B-2, the half car on one road,
as a table, and Fig B-3, "real roads": the relative error of the passenger car's constants M,
k1, k2, b (log axis) on ISO 8608 roads of classes A–E for the thesis' identifier and the
real-road one, with the coverage of their 95 % intervals (``fig-B-3.png``), and Fig B-4, the
full car's health monitor, as a table (per change at one corner: named right, delay, reported
size; false alarms); their claims are rows of the tables. Every number in the report is computed by the run.

>>> data = run(quick=True, only=["3-5"], seeds=2, max_iterations=100, tables=False)
>>> data["figures"][0]["id"], len(data["figures"][0]["curves"])
('3-5', 4)
"""

from __future__ import annotations

import argparse
import html
import importlib
import json
import math
import re
import sys
import textwrap
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

from ._vehid import reproduce_report

__all__ = ["run", "write_report", "add_arguments", "command"]

Json = Dict[str, Any]


def run(
    quick: bool = False,
    only: Optional[Sequence[str]] = None,
    seed: int = 1986,
    seeds: Optional[int] = None,
    max_iterations: Optional[int] = None,
    threads: Optional[int] = None,
    tables: bool = True,
    progress: bool = False,
) -> Json:
    """Runs the reproduction (GIL released) and returns the runner's report as a dict.

    ``quick``: 5 seeds and at most 10,000 iterations per curve (full: 16 seeds, the thesis'
    iterations). ``only``: figure ids such as ``["4-2", "4-5"]``. ``progress``: a progress
    line on stderr. Non-finite numbers come back as ``float('inf')`` / ``nan``.
    """
    return reproduce_report(
        quick=quick,
        only=list(only) if only else None,
        seed=seed,
        seeds=seeds,
        max_iterations=max_iterations,
        threads=threads,
        tables=tables,
        progress=progress,
    )


def _fmt(v: float) -> str:
    if math.isnan(v):
        return "n/a"
    if math.isinf(v):
        return "∞"
    if v != 0 and (abs(v) >= 1e5 or abs(v) < 1e-3):
        return f"{v:.2e}"
    if abs(v) >= 10:
        return f"{v:.1f}"
    return f"{v:.3g}"


def _median(xs: List[float]) -> float:
    v = sorted(x for x in xs if not math.isnan(x))
    if not v:
        return math.nan
    n = len(v)
    return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])


#: The sample interval of every experiment, s (one iteration = one sample; vehid-thesis' DT).
DT = 0.05


def _tex(text: str) -> str:
    """A runner label as matplotlib mathtext: ``σ_u`` → ``$\\sigma_u$``, ``σ_ic`` → ``$\\sigma_{ic}$``,
    ``ξ`` → ``$\\xi$``; no raw underscore is left (one outside a symbol becomes a space)."""
    text = text.replace("$", r"\$")
    text = re.sub(r"σ_(\w+)", lambda m: rf"$\sigma_{{{m[1]}}}$", text)
    text = text.replace("ξ", r"$\xi$")
    return re.sub(r"(?<!\\sigma)_(?![{])", " ", text)


def _units(model: str) -> Tuple[str, str]:
    """The units of (σ_ic and σ_w, σ_v) for a model: per state, and per state derivative."""
    if model.startswith("Half"):
        return "m, m/s, rad, rad/s", "m/s, m/s², rad/s, rad/s²"
    return "m, m/s", "m/s, m/s²"


def _pulse(c: Json) -> str:
    """The pulse's width, e.g. ``pulse width 2 × 0.05 s = 0.10 s``; empty without a pulse."""
    w = c["pulse_width"]
    return f"pulse width {w} × {DT:g} s = {w * DT:.2f} s" if w else ""


def _sigmas(c: Json) -> str:
    """The curve's noise levels in mathtext; σ_u with its unit (m), the per-state ones in the caption."""
    s = (
        rf"$\sigma_{{ic}}$ = {c['ic']:g}, $\sigma_u$ = {c['road']:g} m, "
        rf"$\sigma_w$ = {c['state']:g}, $\sigma_v$ = {c['deriv']:g}"
    )
    return s


def _legend_label(c: Json) -> str:
    """The curve's legend entry: its name, its pulse's width if it has one, its noise levels."""
    pulse = f", {_pulse(c)}" if c["pulse_width"] else ""
    return f"{_tex(c['label'])}{pulse}: {_sigmas(c)}"


#: Fraction of the iterations that counts as "early", and the share of a median curve's
#: range (in decades of ξ) that must happen in it for the iterations to go on a log axis.
EARLY, EARLY_SHARE = 0.1, 0.5


def _action_is_early(fig: Json) -> bool:
    """Whether the median curves cover at least half of their range of log ξ (summed over
    the curves, so a curve that hardly moves weighs little) within the first 10 % of the
    iterations (the identifiers' transients): then a linear axis would squeeze the action
    into a sliver at the left and the iterations go on a log axis."""
    k = fig["k"]
    if not k or k[0] < 1:
        return False
    cut = EARLY * k[-1]
    early_range = total_range = 0.0
    for c in fig["curves"]:
        pts = [(kk, math.log10(v)) for kk, v in zip(k, c["median"]) if math.isfinite(v) and v > 0]
        early = [y for kk, y in pts if kk <= cut]
        if len(pts) < 2 or not early:
            continue
        total_range += max(y for _, y in pts) - min(y for _, y in pts)
        early_range += max(early) - min(early)
    return total_range > 0 and early_range >= EARLY_SHARE * total_range


def _is_analytic(fig: Json) -> bool:
    """A figure drawn from a formula (no simulation, no seeds): the runner gives it no curves."""
    return fig["skipped"] is None and not fig["curves"]


def load_pyplot() -> Any:
    """matplotlib's pyplot on the Agg backend (no display needed), or ``None`` without matplotlib."""
    try:
        mpl = importlib.import_module("matplotlib")
        mpl.use("Agg")
        return importlib.import_module("matplotlib.pyplot")
    except ImportError:
        return None


def _plot_figure(plt: Any, fig: Json, path: Path) -> None:
    f, ax = plt.subplots(figsize=(7.5, 4.9))
    fid = fig["id"]
    if _is_analytic(fig):
        # Eq 4.25: triangular autocorrelation of the held road noise, T = 0.05 s.
        t = DT
        taus = [t * (i / 50.0 - 2.0) for i in range(201)]
        ax.plot(taus, [max(0.0, 1.0 - abs(tau) / t) for tau in taus], color="C0",
                label=rf"$R_u(\tau) / \sigma_u^2 = \max(0, 1 - |\tau| / T)$, $T$ = {t:g} s (Eq 4.25)")
        ax.set_xlabel(r"lag $\tau$ (s)")
        ax.set_ylabel(r"$R_u(\tau) / \sigma_u^2$ (dimensionless)")
        ax.legend(fontsize=8, loc="upper right")
        ax.grid(True, alpha=0.25)
        sub = "analytic: drawn from the formula (Eq 4.25), not simulated: no seeds, no band"
    else:
        k = fig["k"]
        for i, c in enumerate(fig["curves"]):
            med = [v if math.isfinite(v) and v > 0 else math.nan for v in c["median"]]
            color = f"C{i}"
            ax.plot(k, med, color=color, lw=1.4, label=_legend_label(c))
            if fig["seeds"] > 1:
                lo = [v if math.isfinite(v) and v > 0 else math.nan for v in c["p10"]]
                hi = [v if math.isfinite(v) and v > 0 else math.nan for v in c["p90"]]
                ax.fill_between(k, lo, hi, color=color, alpha=0.18, lw=0)
        ax.axhline(0.08, color="k", ls="--", lw=0.8, label=r"$\xi$ = 0.08 (acceptable)")
        ax.set_yscale("log")
        early = _action_is_early(fig)
        if early:
            ax.set_xscale("log")
        ax.set_xlabel(rf"iteration $k$ (one sample = {DT:g} s; {'log' if early else 'linear'} axis)")
        ax.set_ylabel(r"$\xi_k = \sum_i\,((\theta_i - \hat{\theta}_i(k)) / \theta_i)^2$")
        ax.legend(fontsize=6.5, loc="best")
        ax.grid(True, which="both", alpha=0.25)
        state, deriv = _units(fig["model"])
        f.text(0.01, 0.005,
               rf"$\sigma_{{ic}}$ initial state, $\sigma_w$ state measurement noise: per state, in {state}; "
               rf"$\sigma_u$ road input, m; $\sigma_v$ derivative measurement noise, in {deriv}",
               fontsize=6.5, color="0.3", ha="left", va="bottom")
        sub = (f"vehid, median and 10–90 % band over {fig['seeds']} seeds" if fig["seeds"] > 1
               else "vehid, one seed (no band)")
    ax.set_title(f"Fig {fid}: {_tex(fig['title'])}\n{sub}", fontsize=9)
    # Fixed margins: tight_layout would draw every figure twice (it measures the text by
    # drawing), and drawing is most of the time the user waits for the report.
    f.subplots_adjust(left=0.11, right=0.98, top=0.89, bottom=0.15)
    f.savefig(path, dpi=110)
    plt.close(f)


def _constants(fig: Json) -> List[Tuple[int, Json]]:
    """The curves (index, curve) for which the runner recorded the car's constants."""
    return [(i, c) for i, c in enumerate(fig["curves"]) if c.get("constants")]


def _symbol(name: str) -> str:
    """A constant's name as mathtext: ``k1`` → ``$k_{1}$``, ``M`` → ``$M$``."""
    m = re.fullmatch(r"([A-Za-z]+?)(\d*)", name)
    if m is None or not m[2]:
        return f"${name}$"
    return f"${m[1]}_{{{m[2]}}}$"


def _unit_tex(unit: str) -> str:
    """A unit as mathtext where it needs it: ``N·s/m`` → ``N$\\cdot$s/m``, ``kg·m²`` → ``kg$\\cdot$m$^2$``."""
    return unit.replace("·", r"$\cdot$").replace("²", "$^2$")


def _finite_or_nan(xs: List[float]) -> List[float]:
    return [v if math.isfinite(v) else math.nan for v in xs]


def _plot_constants(plt: Any, fig: Json, path: Path) -> None:
    """The identified constants against iteration (one panel each): per curve the estimate
    along its first seed and the runner's 95 % interval (band), the true value dashed."""
    curves = _constants(fig)
    names = [s["name"] for s in curves[0][1]["constants"]["constants"]]
    cols = 2 if len(names) <= 4 else 4
    rows = max(1, math.ceil(len(names) / cols))
    # Shared iteration axes, tick labels on the bottom row only, no minor ticks: the ticks are
    # most of the drawing time, and drawing is most of the time a user waits for the report.
    f, axes = plt.subplots(rows, cols, figsize=(7.5, 4.9), squeeze=False, sharex=True)
    null = importlib.import_module("matplotlib.ticker").NullLocator
    early = _action_is_early(fig)
    last = fig["k"][-1] if fig["k"] else 1
    for p, name in enumerate(names):
        ax = axes[p // cols][p % cols]
        truth = math.nan
        seen: List[float] = []
        for i, c in curves:
            ic = c["constants"]
            s = next(x for x in ic["constants"] if x["name"] == name)
            truth = s["truth"]
            k = ic["k"]
            val, lo, hi = _finite_or_nan(s["value"]), _finite_or_nan(s["lo"]), _finite_or_nan(s["hi"])
            ax.plot(k, val, color=f"C{i}", lw=1.2)
            ax.fill_between(k, lo, hi, color=f"C{i}", alpha=0.2, lw=0)
            # The axis shows the late part of the run (where the estimate settles) and the truth.
            seen += [v for kk, v in zip(k, val + lo + hi) if kk >= EARLY * last and math.isfinite(v)]
        ax.axhline(truth, color="k", ls="--", lw=0.9)
        if math.isfinite(truth) and truth > 0:
            ys = [truth] + [v for v in seen if -2 * truth <= v <= 4 * truth]
            pad = 0.08 * max(max(ys) - min(ys), 0.02 * truth)
            ax.set_ylim(min(ys) - pad, max(ys) + pad)
        if not seen:
            ax.text(0.5, 0.5, "no positive constants from the estimate yet", transform=ax.transAxes,
                    ha="center", va="center", fontsize=6.5, color="0.4")
        ax.set_ylabel(f"{_symbol(name)} ({_unit_tex(s['unit'])})", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.25)
        if p // cols == rows - 1:
            ax.set_xlabel(rf"iteration $k$ ({'log' if early else 'linear'} axis)", fontsize=7)
    for p in range(len(names), rows * cols):
        axes[p // cols][p % cols].set_visible(False)
    # Once for the shared axis (a scale set later would reset the locators).
    if early:
        axes[0][0].set_xscale("log")
    axes[0][0].set_xlim(max(1, fig["k"][0]) if fig["k"] else 1, last)
    for ax in axes.flat:
        ax.xaxis.set_minor_locator(null())
        ax.yaxis.set_minor_locator(null())
    line2d = importlib.import_module("matplotlib.lines").Line2D
    patch = importlib.import_module("matplotlib.patches").Patch
    handles = [line2d([], [], color=f"C{i}", lw=1.2) for i, _ in curves]
    labels = [_tex(c["label"]) for _, c in curves]
    handles += [line2d([], [], color="k", ls="--", lw=0.9),
                patch(color="0.5", alpha=0.3, lw=0)]
    labels += ["true value", "95 % interval"]
    f.legend(handles, labels, loc="lower center", ncol=min(len(labels), 4), fontsize=6.5, frameon=False)
    known = ", ".join(f"{_symbol(k['name'])} = {k['value']:g} {_unit_tex(k['unit'])}"
                      for k in curves[0][1]["constants"]["known"])
    f.suptitle(f"Fig {fig['id']}: identified constants, first seed of each curve\nknown: {known}", fontsize=9)
    f.subplots_adjust(left=0.08 if cols > 2 else 0.1, right=0.98, top=0.87, bottom=0.2, hspace=0.3,
                      wspace=0.7 if cols > 2 else 0.35)
    f.savefig(path, dpi=110)
    plt.close(f)


def _interval(v: float, lo: float, hi: float) -> str:
    """``value [lo, hi]``; the value alone without an interval."""
    if math.isfinite(lo) and math.isfinite(hi):
        return f"{_fmt(v)} [{_fmt(lo)}, {_fmt(hi)}]"
    return _fmt(v)


def _constants_table(fig: Json) -> Tuple[List[str], List[List[str]], str]:
    """The final identified constants: header, rows (constant, truth, one cell per curve),
    and a caption (iteration, seeds, how the intervals were computed)."""
    curves = _constants(fig)
    first = curves[0][1]["constants"]
    head = ["constant", "true"] + [c["label"] for _, c in curves]
    rows: List[List[str]] = []
    for s0 in first["constants"]:
        row = [f"{s0['name']} ({s0['unit']})", _fmt(s0["truth"])]
        for _, c in curves:
            s = next(x for x in c["constants"]["constants"] if x["name"] == s0["name"])
            row.append(_interval(s["value"][-1], s["lo"][-1], s["hi"][-1]) if s["value"] else "n/a")
        rows.append(row)
    for k in first["known"]:
        rows.append([f"{k['name']} ({k['unit']})", _fmt(k["value"])] + ["known"] * len(curves))
    distinct = {c["constants"]["seed"] for _, c in curves}
    seeds = (f"simulator seed {distinct.pop()}, the same noise for every curve" if len(distinct) == 1
             else "simulator seeds " + ", ".join(f"{c['label']}: {c['constants']['seed']}" for _, c in curves))
    methods = "; ".join(dict.fromkeys(c["constants"]["method"] for _, c in curves))
    last = first["k"][-1] if first["k"] else 0
    caption = (f"Identified constants after {last} iterations, first seed of each curve ({seeds}), "
               f"with their 95 % intervals [low, high] where the identifier has a covariance: {methods}.")
    return head, rows, caption


# ---- Beyond the thesis: Fig B-1 (ξ against σ_w), Fig B-2 (the half car on one road) and
# Fig B-3 (real roads) ----

#: The legend's name of each Fig B-1 method, as docs/capabilities/noisy-states.md names them
#: (the Python class, the model it runs on), keyed by the runner's label
#: (vehid_thesis::beyond::QuarterMethod::label); an unknown label is shown as it is.
BEYOND_NAMES = {
    "thesis' Kalman identifier, full rows": "KalmanIdentifier, full rows (the thesis')",
    "IV (refined), full rows": "IVIdentifier, full rows (refined, lags=6)",
    "IV (refined), physical structure": "IVIdentifier, physical structure (m known)",
    "bias-compensated LS, full rows": "BiasCompensated, full rows",
    "bias-compensated LS, physical structure": "BiasCompensated, physical structure",
    "joint EKF, full rows": "JointEKF, full rows",
    "joint EKF, physical structure": "JointEKF, physical structure",
}


def _beyond_name(label: str) -> str:
    return BEYOND_NAMES.get(label, label)


def _positive_or_nan(xs: List[float]) -> List[float]:
    """Values a log axis can show; NaN (a gap) for the rest (∞: no estimate on most seeds)."""
    return [v if math.isfinite(v) and v > 0 else math.nan for v in xs]


def _sweep_subtitle(sweep: Json) -> str:
    band = (f"median and 25–75 % band over {sweep['seeds']} seeds" if sweep["seeds"] > 1
            else "one seed (no band)")
    return f"beyond the thesis (not a figure of Kessler 1986); vehid, {band}, {sweep['samples']} samples per run"


def _plot_sweep(plt: Any, sweep: Json, path: Path) -> None:
    """Fig B-1: per method the median ξ after the run (log axis) against σ_w (% of σ_u; a
    symlog axis, linear below 0.5 %, since the levels start at 0) and the runner's 25–75 %
    band; ξ = 0.08 dashed."""
    f, ax = plt.subplots(figsize=(7.5, 5.8))
    levels = sweep["levels"]
    for i, c in enumerate(sweep["curves"]):
        color = f"C{i}"
        ax.plot(levels, _positive_or_nan(c["median"]), color=color, lw=1.4, marker="o", ms=3,
                label=_beyond_name(c["label"]))
        if sweep["seeds"] > 1:
            ax.fill_between(levels, _positive_or_nan(c["q25"]), _positive_or_nan(c["q75"]),
                            color=color, alpha=0.15, lw=0)
    ax.axhline(0.08, color="k", ls="--", lw=0.8, label=r"$\xi$ = 0.08 (acceptable)")
    ax.set_yscale("log")
    # Base 2 and a linear part [0, 0.5] one factor of 2 wide: the levels 0, 0.5, 2, ..., 32
    # sit at nearly even steps, each at its true value.
    ax.set_xscale("symlog", base=2, linthresh=0.5, linscale=0.5)
    ax.set_xticks(levels)
    ax.set_xlim(-0.1 * max(levels[1], 0.5), 1.25 * max(levels))  # symlog's margins would reach far left of 0
    ax.set_xticklabels([f"{v:g}" for v in levels])
    ax.xaxis.set_minor_locator(importlib.import_module("matplotlib.ticker").NullLocator())
    ax.set_xlabel(r"state noise $\sigma_w$, % of $\sigma_u$ (symlog axis: linear below 0.5 %)")
    ax.set_ylabel(rf"$\xi$ after {sweep['samples']} samples (Eq 3.17)")
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=6.5, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, frameon=False)
    title = textwrap.wrap(f"Fig {sweep['id']}: {sweep['title']}", 95)
    ax.set_title("\n".join(_tex(t) for t in title) + "\n" + _sweep_subtitle(sweep), fontsize=9)
    f.text(0.01, 0.005,
           r"$\sigma_w$ state measurement noise, per state in m and m/s, given as % of $\sigma_u$ (road input, m); "
           r"$\xi$ of rows 1 and 3 of $A$; every method on the same samples",
           fontsize=6.5, color="0.3", ha="left", va="bottom")
    f.subplots_adjust(left=0.11, right=0.98, top=0.85, bottom=0.26)
    f.savefig(path, dpi=110)
    plt.close(f)


def _worst(xs: List[float]) -> float:
    """The worst seed (NaN counts as ∞, as the runner's tables count it)."""
    return max((math.inf if math.isnan(v) else v for v in xs), default=math.nan)


def _worst_pair(cell: Json) -> List[float]:
    """Per seed, ξ of the larger pair of rows (wheel or body), as the runner's B-2 claims."""
    return [max(a, b) for a, b in zip(cell["wheel"], cell["body"])]


def _sweep_table(sweep: Json) -> Tuple[List[str], List[List[str]], str]:
    """Fig B-1's numbers: one row per method, one cell per σ_w: median [25 %, 75 %] (worst)."""
    head = ["method", "runner's label"] + [f"σ_w = {v:g} %" for v in sweep["levels"]]
    rows = []
    for c in sweep["curves"]:
        cells = [f"{_fmt(m)} [{_fmt(lo)}, {_fmt(hi)}] ({_fmt(w)})"
                 for m, lo, hi, w in zip(c["median"], c["q25"], c["q75"], c["max"])]
        rows.append([_beyond_name(c["label"]), c["label"]] + cells)
    caption = (f"Median ξ [25 %, 75 %] (worst seed) after {sweep['samples']} samples, {sweep['seeds']} seeds "
               "(∞: no estimate). ")
    runs = len(sweep["levels"]) * sweep["seeds"]
    errors = [f"{_beyond_name(c['label'])}: no estimate on {sum(len(e) for e in c['errors'])} of {runs} runs "
              f"({next(m for e in c['errors'] for _, m in e)})"
              for c in sweep["curves"] if any(c["errors"])]
    if errors:
        caption += "; ".join(errors) + ". "
    caption += sweep["setup"]
    return head, rows, caption


def _half_table(half: Json) -> Tuple[List[str], List[List[str]], str]:
    """Fig B-2's numbers: one row per method and σ_w: median (worst) ξ of the wheel rows, the
    body rows, the larger pair, and the worst entry's relative error; seeds with no estimate."""
    head = ["method", "σ_w", "ξ wheel rows 1, 3", "ξ body rows 5, 7", "ξ larger pair",
            "worst entry (relative error)", "no estimate"]
    rows = []
    for r in half["rows"]:
        for c in r["cells"]:
            pair = _worst_pair(c)
            none = f"{len(c['errors'])}/{half['seeds']}: {c['errors'][0][1]}" if c["errors"] else "—"
            rows.append([r["label"], f"{c['level']:g} %"]
                        + [f"{_fmt(_median(x))} ({_fmt(_worst(x))})"
                           for x in (c["wheel"], c["body"], pair, c["worst_entry"])]
                        + [none])
    caption = (f"Median (worst seed) over {half['seeds']} seeds after {half['samples']} samples "
               f"(∞: no estimate). {half['setup']}")
    return head, rows, caption


def _half_conclusion(half: Json) -> str:
    """The table's reading at the largest σ_w run: the best median ξ of the larger pair of
    rows, and whether any method is acceptable there (ξ ≤ 0.08)."""
    level = max(half["levels"])
    li = half["levels"].index(level)
    best, label = min(((_median(_worst_pair(r["cells"][li])), r["label"]) for r in half["rows"]),
                      key=lambda x: math.inf if math.isnan(x[0]) else x[0])
    if not best <= 0.08:
        return (f"At σ_w = {level:g} % no method identifies the half car on one road: the best median ξ of the "
                f"larger pair of rows is {_fmt(best)} ({label}), above the acceptable 0.08.")
    return (f"At σ_w = {level:g} %, {label} identifies the half car on one road: median ξ of the larger pair "
            f"of rows {_fmt(best)} (acceptable: ≤ 0.08).")


#: The legend's name of each Fig B-3 identifier (the Python class and how it is built), keyed by
#: the runner's label (vehid_thesis::beyond::RoadsIdent::label).
ROADS_NAMES = {
    "thesis' identifier (least squares, white road)":
        "thesis' identifier: KalmanIdentifier on the physical structure (least squares, white road)",
    "real-road identifier (IV, ISO 8608 road differenced)":
        "real-road identifier: IVIdentifier(road=\"iso8608\") on the physical structure",
}


def _roads_name(label: str) -> str:
    return ROADS_NAMES.get(label, label)


def _coverage(roads: Json, cell: Json) -> float:
    """The fraction of a cell's 95 % intervals (every constant, every seed) that hold the truth."""
    total = len(roads["constants"]) * roads["seeds"]
    return sum(cell["covered"]) / total if total else math.nan


def _ratio_median(roads: Json, row: Json, k: int) -> float:
    """The median over classes of the median estimate over seeds of constant ``k``, over its true value."""
    meds = [_median(c["value"][k]) / roads["truth"][k] for c in row["cells"]]
    return _median([v for v in meds if math.isfinite(v)])


def _plot_roads(plt: Any, roads: Json, path: Path) -> None:
    """Fig B-3: one panel per constant, the relative error (log axis, shared) per road class, per
    identifier the median over seeds (marker) and the range (bar), 5 % dashed, the thesis'
    identifier's estimate as a fraction of the truth written beside its markers; and a panel of
    the fraction of the 95 % intervals that hold the true constant, per class and identifier."""
    f = plt.figure(figsize=(10, 7.2))
    grid = f.add_gridspec(2, 3, width_ratios=[1, 1, 0.9], wspace=0.32, hspace=0.36)
    classes = roads["classes"]
    xs = list(range(len(classes)))
    rows = roads["rows"]
    width = 0.3 / max(1, len(rows) - 1) if len(rows) > 1 else 0.0
    ends = [v for r in rows for c in r["cells"] for v in c["min"] + c["max"] if math.isfinite(v) and v > 0]
    ylim = (10 ** math.floor(math.log10(min(ends + [0.01]))), 10 ** math.ceil(math.log10(max(ends + [1.0])) + 0.3))
    for k, (name, unit, truth) in enumerate(zip(roads["constants"], roads["units"], roads["truth"])):
        ax = f.add_subplot(grid[k // 2, k % 2])
        for i, r in enumerate(rows):
            dx = (i - (len(rows) - 1) / 2) * width
            med = [c["median"][k] for c in r["cells"]]
            lo = [c["min"][k] for c in r["cells"]]
            hi = [c["max"][k] for c in r["cells"]]
            # A log axis shows positive finite values only (∞: no estimate on a seed).
            pts = [(x + dx, m, m - a, b - m) for x, m, a, b in zip(xs, med, lo, hi)
                   if all(math.isfinite(v) and v > 0 for v in (m, a, b))]
            ax.errorbar([p[0] for p in pts], [p[1] for p in pts], yerr=[[p[2] for p in pts], [p[3] for p in pts]],
                        fmt="o", ms=4, color=f"C{i}", capsize=2, lw=1.2,
                        label=_roads_name(r["label"]) if k == 0 else None)
        ratio = _ratio_median(roads, rows[0], k)
        if math.isfinite(ratio):
            ax.text(0.5, 0.97, f"thesis' estimate ≈ {ratio:.2g} × true", transform=ax.transAxes, ha="center",
                    va="top", fontsize=7, color="C0")
        ax.axhline(0.05, color="k", ls="--", lw=0.8, label="5 %" if k == 0 else None)
        ax.set_yscale("log")
        ax.set_ylim(*ylim)
        ax.set_xticks(xs)
        ax.set_xticklabels(classes)
        ax.set_xlim(-0.5, len(classes) - 0.5)
        ax.set_title(f"{_symbol(name)} (true {truth:g} {_unit_tex(unit)})", fontsize=9)
        if k % 2 == 0:
            ax.set_ylabel(r"relative error $|\hat{c}/c - 1|$")
        if k // 2 == 1:
            ax.set_xlabel("ISO 8608 road class")
        ax.grid(True, which="both", alpha=0.25)
    ax = f.add_subplot(grid[:, 2])
    bw = 0.8 / max(1, len(rows))
    total = len(roads["constants"]) * roads["seeds"]
    for i, r in enumerate(rows):
        dx = (i - (len(rows) - 1) / 2) * bw
        for x, c in zip(xs, r["cells"]):
            ax.bar(x + dx, _coverage(roads, c), width=bw, color=f"C{i}", alpha=0.8)
            ax.text(x + dx, _coverage(roads, c) + 0.01, f"{sum(c['covered'])}", ha="center", va="bottom",
                    fontsize=6, color=f"C{i}")
    ax.axhline(0.95, color="k", ls=":", lw=0.8)
    ax.set_ylim(0, 1.08)
    ax.set_xticks(xs)
    ax.set_xticklabels(classes)
    ax.set_xlabel("ISO 8608 road class")
    ax.set_ylabel(f"fraction of 95 % intervals holding the true constant (of {total})")
    ax.set_title(f"coverage (M, k1, k2, b × {roads['seeds']} seeds;\ndotted: the nominal 95 %)", fontsize=9)
    ax.grid(True, axis="y", alpha=0.25)
    handles, labels = f.axes[0].get_legend_handles_labels()
    f.legend(handles, labels, fontsize=7, loc="lower center", ncol=3, frameon=False)
    band = (f"median (marker) and range (bar) over {roads['seeds']} seeds per class" if roads["seeds"] > 1
            else "one seed per class (no range)")
    drive = f"{_fmt(roads['samples'] * roads['dt'])} s at {_fmt(roads['speed'])} m/s, dt = {roads['dt']:g} s"
    sub = (f"beyond the thesis (not a figure of Kessler 1986); vehid, {band}, {roads['samples']} samples ({drive}) "
           f"per run; passenger quarter car, true states, m = {_fmt(roads['known']['value'])} kg known")
    title = textwrap.wrap(f"Fig {roads['id']}: {roads['title']}", 120) + textwrap.wrap(sub, 140)
    f.suptitle("\n".join(_tex(t) for t in title), fontsize=8.5)
    f.subplots_adjust(left=0.08, right=0.98, top=0.84, bottom=0.13)
    f.savefig(path, dpi=110)
    plt.close(f)


def _roads_table(roads: Json) -> Tuple[List[str], List[List[str]], str]:
    """Fig B-3's numbers: one row per identifier and class: per constant the median (worst)
    relative error in %, the intervals holding the truth, and seeds with no estimate."""
    truths = zip(roads["constants"], roads["truth"], roads["units"])
    head = (["identifier", "class"] + [f"{k}: error % (true {t:g} {u})" for k, t, u in truths]
            + ["95 % intervals holding the truth", "no estimate"])
    rows = []
    for r in roads["rows"]:
        for c in r["cells"]:
            none = f"{len(c['errors'])}/{roads['seeds']}: {c['errors'][0][1]}" if c["errors"] else "—"
            rows.append([_roads_name(r["label"]), c["class"]]
                        + [f"{_fmt(100 * m)} ({_fmt(100 * w)})" for m, w in zip(c["median"], c["max"])]
                        + [" ".join(f"{k} {n}/{roads['seeds']}" for k, n in zip(roads["constants"], c["covered"])),
                           none])
    caption = (f"Relative error |estimate / truth − 1| in %, median (worst seed) over {roads['seeds']} seeds per "
               f"class after {roads['samples']} samples (∞: no estimate). {roads['setup']}")
    return head, rows, caption


def _roads_conclusion(roads: Json) -> str:
    """The figure's reading: each identifier's largest median error over the classes and
    constants, and the real-road identifier's pooled coverage."""
    parts = []
    for r in roads["rows"]:
        worst = max(((m, c["class"], k) for c in r["cells"] for m, k in zip(c["median"], roads["constants"])),
                    key=lambda x: math.inf if math.isnan(x[0]) else x[0])
        held = sum(sum(c["covered"]) for c in r["cells"])
        total = len(r["cells"]) * len(roads["constants"]) * roads["seeds"]
        parts.append(f"{_roads_name(r['label'])}: largest median error {_fmt(100 * worst[0])} % "
                     f"({worst[2]}, class {worst[1]}), 95 % intervals holding the truth {held} of {total}")
    return "; ".join(parts) + "."


def _not_run(half: Json) -> List[str]:
    return [f"Not run, {m}: {why}." for m, why in half["not_run"]]


#: The report's keys of the figures beyond the thesis, in the report's order.
BEYOND_KEYS = ("sweep", "half_one_road", "real_roads", "full_car")


def _full_table(full: Json) -> Tuple[List[str], List[List[str]], str]:
    """Fig B-4's numbers: one row per change (the last: none): the seeds on which the change is
    named right, the median and largest delay, the median reported change, the events before it."""
    head = ["change", "named right", "median delay (s)", "largest delay (s)", "median reported (%)", "truth (%)",
            "events before the change"]
    rows = []
    for r in full["rows"]:
        if not r["expect"]:
            rows.append([r["label"], "—", "—", "—", "—", _fmt(r["truth"]), str(r["early"])])
            continue
        named = sum(n == r["expect"] for n in r["named"])
        detected = [c for c in r["change"] if math.isfinite(c)]
        rows.append([r["label"], f"{named}/{len(r['named'])}", _fmt(_median(r["delay"])), _fmt(max(r["delay"])),
                     _fmt(_median(detected)) if detected else "—", _fmt(r["truth"]), str(r["early"])])
    caption = (f"{full['seeds']} seeds per row, {full['seconds']:g} s drives, the change at {full['change_at']:g} s "
               f"(a miss counts as ∞). {full['setup']}")
    return head, rows, caption


def _beyond_intro(data: Json, quote: str) -> str:
    """The section's first paragraph: what the figures compare and which tables hold their claims."""
    figs = [data[k] for k in BEYOND_KEYS if k in data]
    close = "”" if quote == "“" else quote
    names = " and ".join(f"{quote}Fig {f['id']}{close}" for f in figs)
    what = []
    if "sweep" in data or "half_one_road" in data:
        what.append("for noisy states")
    if "real_roads" in data:
        what.append("on real roads")
    compared = f"vehid's comparison of its identifiers {' and '.join(what)}" if what else ""
    if "full_car" in data:
        compared += ("; and " if compared else "") + "its health monitor on the full car"
    return (f"Not figures of Kessler (1986): {compared}. Their "
            f"claims and verdicts are in the table{'s' if len(figs) > 1 else ''} {names} below.")


def _beyond_md(data: Json, images: Dict[str, str]) -> List[str]:
    """The section of the figures beyond the thesis (their claims and verdicts: in Tables)."""
    sweep, half, roads = data.get("sweep"), data.get("half_one_road"), data.get("real_roads")
    full = data.get("full_car")
    if sweep is None and half is None and roads is None and full is None:
        return []
    md = ["## Beyond the thesis", "", _beyond_intro(data, "\""), ""]
    for fig, table in ((sweep, _sweep_table), (half, _half_table), (roads, _roads_table), (full, _full_table)):
        if fig is None:
            continue
        md += [f"### Fig {fig['id']}: {fig['title']}", "", f"**{fig['origin']}.**", ""]
        if fig["id"] in images:
            md += [f"![Fig {fig['id']}]({images[fig['id']]})", ""]
        head, rows, caption = table(fig)
        md += [_md_cell(caption), "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        md += ["| " + " | ".join(_md_cell(x) for x in r) + " |" for r in rows]
        md.append("")
        if fig is half:
            md += [f"**{_half_conclusion(half)}**", ""] + [f"- {_md_cell(s)}" for s in _not_run(half)] + [""]
        elif fig is roads and roads is not None:
            md += [f"**{_md_cell(_roads_conclusion(roads))}**", ""]
            md += [f"- {_roads_name(r['label'])}: {_md_cell(r['setup'])}" for r in roads["rows"]] + [""]
        elif fig is full:
            pass
        else:
            md += [f"- {_beyond_name(c['label'])}: {_md_cell(c['setup'])}" for c in fig["curves"]] + [""]
    return md


def _beyond_html(data: Json, images: Dict[str, str]) -> List[str]:
    """:func:`_beyond_md` as HTML."""
    e = html.escape
    sweep, half, roads = data.get("sweep"), data.get("half_one_road"), data.get("real_roads")
    full = data.get("full_car")
    if sweep is None and half is None and roads is None and full is None:
        return []
    h = ["<h2>Beyond the thesis</h2>", f"<p>{e(_beyond_intro(data, '“'))}</p>"]
    for fig, table in ((sweep, _sweep_table), (half, _half_table), (roads, _roads_table), (full, _full_table)):
        if fig is None:
            continue
        h.append(f"<h3>Fig {e(fig['id'])}: {e(fig['title'])}</h3><p><strong>{e(fig['origin'])}.</strong></p>")
        if fig["id"] in images:
            h.append(f"<img src='{e(images[fig['id']])}' alt='Fig {e(fig['id'])}'>")
        head, rows, caption = table(fig)
        h.append(f"<p><small>{e(caption)}</small></p><table><tr>" + "".join(f"<th>{e(x)}</th>" for x in head)
                 + "</tr>")
        h += ["<tr>" + "".join(f"<td>{e(x)}</td>" for x in r) + "</tr>" for r in rows]
        h.append("</table>")
        if fig is half:
            h.append(f"<p><strong>{e(_half_conclusion(half))}</strong></p><ul>"
                     + "".join(f"<li>{e(s)}</li>" for s in _not_run(half)) + "</ul>")
        elif fig is roads and roads is not None:
            h.append(f"<p><strong>{e(_roads_conclusion(roads))}</strong></p><ul>"
                     + "".join(f"<li>{e(_roads_name(r['label']))}: {e(r['setup'])}</li>" for r in roads["rows"])
                     + "</ul>")
        elif fig is full:
            pass
        else:
            h.append("<ul>" + "".join(f"<li>{e(_beyond_name(c['label']))}: {e(c['setup'])}</li>"
                                      for c in fig["curves"]) + "</ul>")
    return h


#: The three verdicts, in the order the report lists them.
VERDICTS = ("agrees", "differs", "inconclusive")

#: What the runner writes into a verdict's note when the run was shorter than the claim and
#: only bounds the measured number from below (crates/vehid-thesis/src/verdict.rs, the
#: SettlesAfter claims); the runner's ``agrees`` is then true, but nothing was decided.
LOWER_BOUND = "lower bound only"


def _verdict(v: Json) -> str:
    """``agrees``, ``differs``, or ``inconclusive`` where the run only bounds the claim from below."""
    if LOWER_BOUND in v["note"]:
        return "inconclusive"
    return "agrees" if v["agrees"] else "differs"


def _mark(verdict: str) -> str:
    return f"*{verdict}*"


Rows = Dict[str, List[Tuple[str, Json]]]

INCONCLUSIVE = (
    "the run was shorter than the claim and bounds the measured number from below only; "
    "the full mode runs the thesis' iterations"
)


def _claim_rows(data: Json) -> Rows:
    """Every figure claim and table row, as ``(where, verdict)``, by verdict (keys VERDICTS)."""
    rows: Rows = {k: [] for k in VERDICTS}
    for fig in data["figures"]:
        for v in fig["verdicts"]:
            rows[_verdict(v)].append((f"Fig {fig['id']}", v))
    for t in data["tables"]:
        for r in t["rows"]:
            item = {
                "claim": f"{r['label']}: {r['thesis']}",
                "measured": r["vehid"],
                "agrees": r["agrees"],
                "note": r["note"],
            }
            rows[_verdict(item)].append((t["title"].split(":")[0], item))
    return rows


def _counts(rows: Rows) -> str:
    """``N agree, M differ, K inconclusive`` (the final stderr line's words)."""
    return f"{len(rows['agrees'])} agree, {len(rows['differs'])} differ, {len(rows['inconclusive'])} inconclusive"


#: ξ in words and formula, once per report (Eq 3.17; thesis notes §5).
XI_WORDS = (
    "ξ_k, the error measure of every figure (Eq 3.17), is the sum of the squared relative errors "
    "of the identified entries after k iterations (one iteration = one sample, 0.05 s): over the "
    "entries θ_i of the unknown rows of A that are not zero in the true car, θ̂_i(k) the estimate "
    "after k samples,"
)
XI_FORMULA = "ξ_k = Σ_i ((θ_i − θ̂_i(k)) / θ_i)²"
XI_ACCEPT = (
    "ξ = 0 is a perfect identification; the root-mean-square relative error of the entries is "
    "√(ξ / number of entries). ξ < 0.08 is the thesis' \"acceptable\" (the dashed line in the figures): "
    "for the quarter car's 8 entries it is necessary for every entry to be within 10 % (8 × 0.1² = 0.08); "
    "the half car has 28 entries."
)


def _md_cell(s: str) -> str:
    return s.replace("|", "\\|").replace("\n", " ")


def write_report(data: Json, out: Path, command: str = "vehid reproduce", started: Optional[float] = None) -> Path:
    """Writes the PNGs, ``index.md`` and ``index.html`` into ``out``; returns index.md's path.

    ``started``: the :func:`time.perf_counter` value at the start of the whole command; the
    header then gives the end-to-end time (from it to writing the report) beside the
    runner's own.
    """
    out.mkdir(parents=True, exist_ok=True)
    plt = load_pyplot()
    images: Dict[str, str] = {}
    if plt is not None:
        for fig in data["figures"]:
            if fig["skipped"] is None and (fig["curves"] or fig["id"] == "4-7"):
                name = f"fig-{fig['id']}.png"
                _plot_figure(plt, fig, out / name)
                images[fig["id"]] = name
                if _constants(fig):
                    cname = f"fig-{fig['id']}-constants.png"
                    _plot_constants(plt, fig, out / cname)
                    images[f"{fig['id']}-constants"] = cname
        sweep = data.get("sweep")
        if sweep is not None:
            name = f"fig-{sweep['id']}.png"
            _plot_sweep(plt, sweep, out / name)
            images[sweep["id"]] = name
        roads = data.get("real_roads")
        if roads is not None:
            name = f"fig-{roads['id']}.png"
            _plot_roads(plt, roads, out / name)
            images[roads["id"]] = name
    rows = _claim_rows(data)
    ok, bad, open_ = rows["agrees"], rows["differs"], rows["inconclusive"]
    skipped = [f for f in data["figures"] if f["skipped"]]
    mode = "quick" if data["quick"] else "full"
    beyond = [data[k] for k in BEYOND_KEYS if k in data]
    seeds = max((f["seeds"] for f in data["figures"] + beyond), default=0)
    head = (
        f"Generated by `{command}` ({mode} mode: {seeds} seeds per curve, base seed {data['base_seed']}, "
        f"{data['threads']} threads, runner wall time {data['seconds']:.1f} s)."
    )
    if started is not None:
        total = time.perf_counter() - started
        head = (
            f"Generated by `{command}` in {total:.1f} s end to end (from the command's start to writing this "
            f"report; the runner {data['seconds']:.1f} s of it, the figures and pages the rest); {mode} mode: "
            f"{seeds} seeds per curve, base seed {data['base_seed']}, {data['threads']} threads."
        )
    plots = (
        "Figures: ξ_k (log axis) against iterations, median over seeds (line) and 10–90 % band (shaded); "
        "the iterations on a log axis where the action is early (each figure's axis says which), "
        "Fig 4-7 drawn from its formula. Beside each identifier's figure (Ch. IV–VI), the car's physical "
        "constants it identified along the first seed of each curve, with their 95 % interval (band, where the "
        "identifier has a covariance) and the true value (dashed)."
        + (" Fig B-1 (beyond the thesis): ξ after the run (log axis) against the state noise σ_w, median over "
           "seeds (line) and 25–75 % band (shaded) per method." if "sweep" in data else "")
        + (" Fig B-3 (beyond the thesis): the relative error of each constant (log axis) per ISO 8608 road class, "
           "median (marker) and range (bar) over seeds per identifier, and the coverage of the 95 % intervals."
           if "real_roads" in data else "")
        if plt is not None
        else "matplotlib is not installed (`pip install vehid[plot]`): the report has no images; "
        "every number below is still computed."
    )

    md: List[str] = ["# vehid reproduces Kessler (1986), Ch. III–VI", "", head, plots, ""]
    md += ["## ξ, the error measure", "", XI_WORDS, "", f"    {XI_FORMULA}", "", XI_ACCEPT, ""]
    md += [
        "## Summary",
        "",
        f"{len(ok)} claims and table rows *agree*, {len(bad)} *differ*, {len(open_)} *inconclusive* "
        f"({INCONCLUSIVE}), {len(skipped)} figures skipped.",
        "",
        "### Claims vehid confirms",
        "",
    ]
    md += [
        f"- {w}: {_md_cell(v['claim'])} — {_md_cell(v['measured'])}"
        + (f" ({_md_cell(v['note'])})" if v["note"] else "")
        for w, v in ok
    ] or ["- none"]
    md += ["", "### Claims vehid does not confirm", ""]
    md += [
        f"- {w}: {_md_cell(v['claim'])} — {_md_cell(v['measured'])}. {_md_cell(v['note'])}"
        for w, v in bad
    ] or ["- none"]
    md += ["", "### Claims this run cannot decide (*inconclusive*)", ""]
    md += [
        f"- {w}: {_md_cell(v['claim'])} — {_md_cell(v['measured'])}. {_md_cell(v['note'])}"
        for w, v in open_
    ] or ["- none"]
    if skipped:
        md += ["", "### Not run", ""]
        md += [f"- Fig {f['id']} ({f['title']}): {f['skipped']}" for f in skipped]
    md += ["", "## Figures", ""]
    for fig in data["figures"]:
        md += [f"### Fig {fig['id']}: {fig['title']}", ""]
        if fig["skipped"]:
            md += [f"Skipped: {fig['skipped']}.", ""]
            continue
        if fig["id"] in images:
            md += [f"![Fig {fig['id']}]({images[fig['id']]})", ""]
        if f"{fig['id']}-constants" in images:
            md += [f"![Fig {fig['id']}, identified constants]({images[fig['id'] + '-constants']})", ""]
        if fig["curves"]:
            iters = fig["iterations"]
            note = "" if iters == fig["thesis_iterations"] else f" (the table's full run: {fig['thesis_iterations']})"
            md += [f"{iters} iterations{note}, {fig['seeds']} seeds.", ""]
            state, deriv = _units(fig["model"])
            md += [
                f"| curve | σ_ic ({state}) | σ_u (m) | σ_w ({state}) | σ_v ({deriv}) | identifier "
                "| median ξ at end [10–90 %] |",
                "|---|---|---|---|---|---|---|",
            ]
            for c in fig["curves"]:
                fin = c["final_xi"]
                lo, hi = c["p10"][-1], c["p90"][-1]
                label = c["label"] + (f" ({_pulse(c)})" if c["pulse_width"] else "")
                md.append(
                    f"| {_md_cell(label)} | {c['ic']:g} | {c['road']:g} | {c['state']:g} | {c['deriv']:g} | "
                    f"`{_md_cell(c['ident'])}` | {_fmt(_median(fin))} [{_fmt(lo)}, {_fmt(hi)}] |"
                )
            md.append("")
        if _constants(fig):
            head_c, rows_c, caption = _constants_table(fig)
            md += [_md_cell(caption), "", "| " + " | ".join(_md_cell(x) for x in head_c) + " |",
                   "|" + "---|" * len(head_c)]
            md += ["| " + " | ".join(_md_cell(x) for x in r) + " |" for r in rows_c]
            md.append("")
        if fig["verdicts"]:
            md += ["| thesis | vehid | verdict | explanation |", "|---|---|---|---|"]
            for v in fig["verdicts"]:
                md.append(
                    f"| {_md_cell(v['claim'])} | {_md_cell(v['measured'])} | {_mark(_verdict(v))} | "
                    f"{_md_cell(v['note'])} |"
                )
            md.append("")
        md += [f"Assumptions: {fig['assumptions']}", ""]
    md += _beyond_md(data, images)
    md += ["## Tables", ""]
    for t in data["tables"]:
        md += [
            f"### {t['title']}",
            "",
            t["method"] + ".",
            "",
            "| | thesis | vehid | verdict | explanation |",
            "|---|---|---|---|---|",
        ]
        for r in t["rows"]:
            md.append(
                f"| {_md_cell(r['label'])} | {_md_cell(r['thesis'])} | {_md_cell(r['vehid'])} | "
                f"{_mark(_verdict(r))} | {_md_cell(r['note'])} |"
            )
        md.append("")
    index_md = out / "index.md"
    index_md.write_text("\n".join(md), encoding="utf-8")
    (out / "index.html").write_text(_html(data, images, head, plots, rows, skipped), encoding="utf-8")
    (out / "report.json").write_text(json.dumps(data, default=str), encoding="utf-8")
    return index_md


def _html(
    data: Json,
    images: Dict[str, str],
    head: str,
    plots: str,
    rows: Rows,
    skipped: List[Json],
) -> str:
    e = html.escape

    ok, bad, open_ = rows["agrees"], rows["differs"], rows["inconclusive"]

    def mark(verdict: str) -> str:
        return f'<em class="{verdict}">{verdict}</em>'

    h: List[str] = [
        "<!doctype html><html><head><meta charset='utf-8'><title>vehid reproduces Kessler (1986)</title>",
        "<style>body{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}"
        "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:3px 6px;font-size:90%}"
        ".formula{font-family:serif;font-size:120%;margin-left:2em}.agrees{color:#176117}.differs{color:#a01b1b}.inconclusive{color:#8a5a00}img{max-width:100%}"
        ".pair{display:flex;gap:4px}.pair img{width:50%}</style></head><body>",
        "<h1>vehid reproduces Kessler (1986), Ch. III–VI</h1>",
        f"<p>{e(head)}<br>{e(plots)}</p>",
        "<h2>ξ, the error measure</h2>",
        f"<p>{e(XI_WORDS)}</p>",
        "<p class='formula'>ξ<sub>k</sub> = Σ<sub>i</sub> ((θ<sub>i</sub> − θ̂<sub>i</sub>(k)) / θ<sub>i</sub>)²</p>",
        f"<p>{e(XI_ACCEPT)}</p>",
        f"<h2>Summary</h2><p>{len(ok)} claims and table rows agree, {len(bad)} differ, "
        f"{len(open_)} inconclusive ({e(INCONCLUSIVE)}), {len(skipped)} figures skipped.</p>",
        "<h3>Claims vehid confirms</h3><ul>",
    ]
    h += [
        f"<li>{e(w)}: {e(v['claim'])} — {e(v['measured'])}" + (f" ({e(v['note'])})" if v["note"] else "") + "</li>"
        for w, v in ok
    ]
    h += ["</ul><h3>Claims vehid does not confirm</h3><ul>"]
    h += [f"<li>{e(w)}: {e(v['claim'])} — {e(v['measured'])}. {e(v['note'])}</li>" for w, v in bad]
    h += ["</ul><h3>Claims this run cannot decide (inconclusive)</h3><ul>"]
    h += [f"<li>{e(w)}: {e(v['claim'])} — {e(v['measured'])}. {e(v['note'])}</li>" for w, v in open_]
    h += ["</ul>"]
    if skipped:
        h += ["<h3>Not run</h3><ul>"] + [f"<li>Fig {e(f['id'])}: {e(f['skipped'])}</li>" for f in skipped] + ["</ul>"]
    h += ["<h2>Figures</h2>"]
    for fig in data["figures"]:
        h.append(f"<h3>Fig {e(fig['id'])}: {e(fig['title'])}</h3>")
        if fig["skipped"]:
            h.append(f"<p>Skipped: {e(fig['skipped'])}.</p>")
            continue
        pair = f"{fig['id']}-constants"
        if fig["id"] in images and pair in images:
            h.append(f"<div class='pair'><img src='{e(images[fig['id']])}' alt='Fig {e(fig['id'])}'>"
                     f"<img src='{e(images[pair])}' alt='Fig {e(fig['id'])}, identified constants'></div>")
        elif fig["id"] in images:
            h.append(f"<img src='{e(images[fig['id']])}' alt='Fig {e(fig['id'])}'>")
        if _constants(fig):
            head_c, rows_c, caption = _constants_table(fig)
            h.append(f"<p><small>{e(caption)}</small></p><table><tr>"
                     + "".join(f"<th>{e(x)}</th>" for x in head_c) + "</tr>")
            h += ["<tr>" + "".join(f"<td>{e(x)}</td>" for x in r) + "</tr>" for r in rows_c]
            h.append("</table>")
        if fig["verdicts"]:
            h.append("<table><tr><th>thesis</th><th>vehid</th><th>verdict</th><th>explanation</th></tr>")
            for v in fig["verdicts"]:
                h.append(
                    f"<tr><td>{e(v['claim'])}</td><td>{e(v['measured'])}</td>"
                    f"<td>{mark(_verdict(v))}</td><td>{e(v['note'])}</td></tr>"
                )
            h.append("</table>")
        h.append(f"<p><small>Assumptions: {e(fig['assumptions'])}</small></p>")
    h += _beyond_html(data, images)
    h.append("<h2>Tables</h2>")
    for t in data["tables"]:
        h.append(f"<h3>{e(t['title'])}</h3><p><small>{e(t['method'])}</small></p>")
        h.append("<table><tr><th></th><th>thesis</th><th>vehid</th><th>verdict</th><th>explanation</th></tr>")
        for r in t["rows"]:
            h.append(
                f"<tr><td>{e(r['label'])}</td><td>{e(r['thesis'])}</td><td>{e(r['vehid'])}</td>"
                f"<td>{mark(_verdict(r))}</td><td>{e(r['note'])}</td></tr>"
            )
        h.append("</table>")
    h.append("</body></html>")
    return "\n".join(h)


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {v}")
    return v


#: The largest seed the core takes (a 64-bit unsigned integer).
SEED_MAX = 2**64 - 1


def _seed(text: str) -> int:
    """``--seed``: a whole number the core's 64-bit seed holds.

    >>> _seed("1986")
    1986
    >>> _seed("-1")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: expected a whole number from 0 to 18446744073709551615 (2**64 - 1), got -1
    """
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if not 0 <= v <= SEED_MAX:
        raise argparse.ArgumentTypeError(f"expected a whole number from 0 to {SEED_MAX} (2**64 - 1), got {v}")
    return v


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The ``vehid reproduce`` options."""
    p.add_argument("--quick", action="store_true",
                   help="5 seeds, at most 10,000 iterations per curve (under 2 minutes)")
    p.add_argument("--out", default="report/", help="output directory (default report/)")
    p.add_argument("--only", default=None, metavar="IDS",
                   help="comma-separated figure ids, e.g. 4-2,4-5 (default: all)")
    p.add_argument("--seed", type=_seed, default=1986, help="base seed (default 1986)")
    p.add_argument("--seeds", type=_positive_int, default=None, help="seeds per curve (default 5 quick, 16 full)")
    p.add_argument("--max-iterations", type=_positive_int, default=None, help="cap the iterations of every curve")
    p.add_argument("--threads", type=_positive_int, default=None, help="worker threads (default: all cores)")
    p.add_argument("--no-tables", action="store_true", help="skip Eq 4.28/4.32/4.34 and Table I")
    p.add_argument("--quiet", action="store_true", help="no progress line")


def command(args: argparse.Namespace) -> int:
    """Runs ``vehid reproduce`` with parsed arguments; prints the report's path."""
    only = [s.strip() for s in args.only.split(",") if s.strip()] if args.only else None
    t0 = time.perf_counter()
    data = run(
        quick=args.quick,
        only=only,
        seed=args.seed,
        seeds=args.seeds,
        max_iterations=args.max_iterations,
        threads=args.threads,
        tables=not args.no_tables,
        progress=not args.quiet,
    )
    argv = ["vehid", "reproduce"] + (["--quick"] if args.quick else []) + (["--only", args.only] if args.only else [])
    path = write_report(data, Path(args.out), " ".join(argv), started=t0)
    if not args.quiet:
        print(
            f"reproduce: {_counts(_claim_rows(data))}, in {time.perf_counter() - t0:.1f} s",
            file=sys.stderr,
        )
    print(path)
    return 0

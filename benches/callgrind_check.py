"""Regression gate on instructions per update, counted by valgrind's callgrind.

Wall-clock benches drift on a shared machine; the number of instructions a given binary
executes on a given input does not. For each key bench this script runs
``target/release/count_updates BENCH N`` and ``... BENCH 0`` under
``valgrind --tool=callgrind``, takes ``(Ir(N) − Ir(0)) / N`` as the instructions per update
(the 0 run subtracts process start-up and the seeded data generation), and compares it with
the checked-in ``benches/callgrind_baseline.json``. It fails (exit 1) when any count is more than
5 % above its baseline (or a bench has no baseline); a count more than 5 % *below* passes with a
hint to update the baseline so that the gain is kept.

Usage::

    make bench-check                              # build (release) and check every bench
    python3 benches/callgrind_check.py            # the same
    python3 benches/callgrind_check.py --bench quarter_rows --bench half_rows
    python3 benches/callgrind_check.py --update   # rewrite the baseline (deliberately!)

Updating the baseline deliberately: when a change is *meant* to cost more instructions (a new
check, a more robust form) or has made things faster, run ``make bench-check-update`` (that is
``python3 benches/callgrind_check.py --update``), look at the printed old → new counts, and
commit ``benches/callgrind_baseline.json`` together with the change, saying why in the commit
message. The counts depend on the compiler (rustc version, target, release profile) and the
valgrind version, both recorded in the baseline: after a toolchain upgrade, re-baseline in a
commit of its own. ``--update`` with ``--bench`` rewrites only those entries.

A deliberately slowed build fails the gate, for example (opt-level 1, every count grows
1.6–8.8×)::

    CARGO_TARGET_DIR=target/slowed CARGO_PROFILE_RELEASE_OPT_LEVEL=1 \
        cargo build --release -p vehid-benches --bin count_updates
    python3 benches/callgrind_check.py --no-build --binary target/slowed/release/count_updates

The comparison itself (:func:`compare`) is a pure function, unit-tested by
``tests/test_bench_check.py`` against doctored baselines.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence

ROOT = Path(__file__).resolve().parent.parent
BASELINE = Path(__file__).resolve().parent / "callgrind_baseline.json"
# The Cargo profile the binaries are built in: release, or the one `make test` builds everything
# with (VEHID_CARGO_PROFILE=ci: the test profile's settings, so its counts are not release's;
# `make test` uses it only to check the gate itself and to build the golden-θ binary).
PROFILE = os.environ.get("VEHID_CARGO_PROFILE", "release")
BINARY = ROOT / "target" / PROFILE / "count_updates"
TOLERANCE = 0.05
N_UPDATES = 20_000
# The key benches (names of count_updates); criterion's counterparts in parentheses.
BENCHES = [
    "quarter_rows",       # update_f64/quarter/kalman_rows
    "half_rows",          # update_f64/half/kalman_rows
    "quarter_rows_vec",   # update_f64/quarter/kalman_rows_vec (Python's quarter car)
    "half_rows_vec",      # update_f64/half/kalman_rows_vec (Python's half car)
    "quarter_shared",     # update_f64/quarter/kalman_shared
    "half_shared",        # update_f64/half/kalman_shared
    "quarter_sg_venter",  # update_f64/quarter/sg_venter
    "quarter_sim_exact",  # simulate_f64/quarter/exact
    "quarter_rows_sqrt",  # update_f64/quarter/kalman_rows_sqrt (square-root form)
    "half_rows_sqrt",     # update_f64/half/kalman_rows_sqrt
    "quarter_rows_forget",  # update_f64/quarter/kalman_rows_forget (exponential forgetting)
    "half_rows_forget",   # update_f64/half/kalman_rows_forget
    "quarter_rows_exact",  # update_f64/quarter/kalman_rows_exact (after the exact start)
    "half_rows_exact",    # update_f64/half/kalman_rows_exact
    "quarter_structured_rows",      # update_f64/quarter/structured_rows (target: <= 1.5x quarter_rows_vec)
    "quarter_structured_physical",  # update_f64/quarter/structured_physical
    "quarter_structured_sg",        # update_f64/quarter/structured_sg_venter
    "quarter_iv_rows",              # update_f64/quarter/iv_rows (recursive IV, noisy state sensors)
    "quarter_iv_physical",          # update_f64/quarter/iv_physical
    "quarter_bcls_rows",            # update_f64/quarter/bcls_rows
    "quarter_bcls_screened",        # update_f64/quarter/bcls_screened (Python's default screen in front)
    "quarter_ekf_physical",         # update_f64/quarter/ekf_physical (the joint EKF's cost)
    "quarter_nebcls_rows",          # update_f64/quarter/nebcls_rows (Sigma_w estimated)
    "half_two_axle_physical",       # update_f64/half/two_axle_physical (road cancellation, physical)
    "msd_iv_model",                 # update_f64/msd/iv_model (instruments from the auxiliary model, SRIVC)
    "quarter_health",               # health/monitor_update_f64 (binary count_health)
    "half_health",                  # health/half_monitor_update_f64 (half car; binary count_health)
    "quarter_health_state",         # health/monitor_update_state_f64 (state sensors, measured rate)
    "half_health_state",            # health/half_monitor_update_state_f64 (half car, state sensors)
    "quarter_iv_physical_road",     # update_f64/quarter/iv_physical_road (Differenced: the coloured-road identifier)
    "quarter_iv_physical_drive",    # the same IV without the road model, same samples (binary count_road)
    "quarter_state_filter_realistic",  # update_f64/quarter/state_filter_realistic (binary count_road)
    "full_health",                  # health/full_monitor_update_f64 (full car; binary count_full_health)
    "full_drive",                   # simulate_f64/full/drive (the full car's drive; binary count_full_health)
    "full_two_axle",                # update_f64/full/two_axle_rows (road cancellation; binary count_two_axle)
    "full_corner_filter_realistic",  # update_f64/full/corner_filter_realistic (binary count_corner_filter)
]
# Benches counted by a binary other than count_updates (kept apart so that their code does not
# change how count_updates is compiled).
OTHER_BINARIES = {
    "quarter_health": "count_health",
    "half_health": "count_health",
    "quarter_health_state": "count_health",
    "half_health_state": "count_health",
    "quarter_iv_physical_road": "count_road",
    "quarter_iv_physical_drive": "count_road",
    "quarter_state_filter_realistic": "count_road",
    "full_health": "count_full_health",
    "full_drive": "count_full_health",
    "full_two_axle": "count_two_axle",
    "full_corner_filter_realistic": "count_corner_filter",
}


@dataclass
class Row:
    """One bench's verdict."""

    bench: str
    baseline: Optional[float]
    measured: Optional[float]
    status: str  # "ok", "faster", "REGRESSION", "NO BASELINE", "not measured"

    @property
    def ratio(self) -> Optional[float]:
        if self.baseline is None or self.measured is None or self.baseline == 0:
            return None
        return self.measured / self.baseline

    @property
    def failed(self) -> bool:
        return self.status in ("REGRESSION", "NO BASELINE")


def compare(measured: Mapping[str, float], baseline: Mapping[str, float], tolerance: float = TOLERANCE) -> List[Row]:
    """Compares instructions per update with the baseline counts.

    A bench fails when its count exceeds ``baseline × (1 + tolerance)`` or has no baseline;
    it is ``"faster"`` (a pass) below ``baseline × (1 − tolerance)``. Baseline entries that were
    not measured are listed as ``"not measured"`` (a pass: ``--bench`` selects a subset).
    """
    rows = []
    for bench, value in measured.items():
        base = baseline.get(bench)
        if base is None:
            status = "NO BASELINE"
        elif value > base * (1.0 + tolerance):
            status = "REGRESSION"
        elif value < base * (1.0 - tolerance):
            status = "faster"
        else:
            status = "ok"
        rows.append(Row(bench, base, value, status))
    for bench, base in baseline.items():
        if bench not in measured:
            rows.append(Row(bench, base, None, "not measured"))
    return rows


def passed(rows: Sequence[Row]) -> bool:
    return not any(r.failed for r in rows)


def format_table(rows: Sequence[Row], tolerance: float = TOLERANCE) -> str:
    lines = [f"{'bench':<20} {'baseline':>10} {'measured':>10} {'ratio':>7}  verdict (fail above +{tolerance:.0%})"]
    for r in rows:
        base = "—" if r.baseline is None else f"{r.baseline:.1f}"
        meas = "—" if r.measured is None else f"{r.measured:.1f}"
        ratio = "—" if r.ratio is None else f"{r.ratio:.3f}"
        hint = "  (consider --update to keep the gain)" if r.status == "faster" else ""
        lines.append(f"{r.bench:<20} {base:>10} {meas:>10} {ratio:>7}  {r.status}{hint}")
    return "\n".join(lines)


# ---- measuring ----------------------------------------------------------------------------

def instructions(binary: Path, bench: str, n: int) -> int:
    """Total instructions (Ir) of ``binary bench n`` under callgrind."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "callgrind.out"
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", str(binary), bench, str(n)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
        text = out.read_text()
    m = re.search(r"^(?:summary|totals):\s*(\d+)", text, re.MULTILINE)
    if m is None:
        raise RuntimeError(f"no summary line in the callgrind output of {bench}")
    return int(m.group(1))


def per_update(binary: Path, bench: str, n: int) -> float:
    """Instructions per update: (Ir(n) − Ir(0)) / n."""
    return (instructions(binary, bench, n) - instructions(binary, bench, 0)) / n


def build_bins(names: Sequence[str], timeout: Optional[float] = None) -> Dict[str, Path]:
    """Builds the vehid-benches binaries ``names`` in ``PROFILE`` and returns the executables
    cargo reports for them, by name: the hashed paths of this checkout's build, not
    ``target/<profile>/<name>``, which another checkout sharing the target directory
    (``CARGO_TARGET_DIR``) may have overwritten. (The golden-θ test builds its binary here too.)"""
    cargo = os.environ.get("CARGO", "cargo")
    # vehid-py in the selection only resolves the dependencies' features as the extension's
    # build does (numpy turns on num-traits' and num-complex's defaults), so that vehid-core
    # and its dependencies are that build's artifacts and not compiled a second time; with
    # `--bin` filtering the targets, vehid-py itself is not built.
    cmd = [cargo, "build", "--quiet", "--profile", PROFILE, "-p", "vehid-benches", "-p", "vehid-py"]
    for name in names:
        cmd += ["--bin", name]
    proc = subprocess.run(cmd + ["--message-format=json-render-diagnostics"],
                          cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise SystemExit(f"callgrind_check: {' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-4000:]}")
    found: Dict[str, Path] = {}
    for line in proc.stdout.splitlines():
        msg = json.loads(line)
        name = msg.get("target", {}).get("name")
        if msg.get("reason") == "compiler-artifact" and name in names and msg.get("executable"):
            found[name] = Path(msg["executable"])
    missing = [n for n in names if n not in found]
    if missing:
        raise SystemExit(f"callgrind_check: cargo did not report the executable of {', '.join(missing)}")
    return found


def build() -> Dict[str, Path]:
    """Builds count_updates and the other counting binaries (``build_bins``)."""
    return build_bins(["count_updates", *sorted(set(OTHER_BINARIES.values()))])


def binary_for(bench: str, binaries: Mapping[str, Path]) -> Path:
    """The executable that counts ``bench``."""
    return binaries[OTHER_BINARIES.get(bench, "count_updates")]


def toolchain() -> Dict[str, str]:
    def first_line(cmd: List[str]) -> str:
        try:
            return subprocess.run(cmd, capture_output=True, text=True, check=True).stdout.strip().splitlines()[0]
        except (OSError, subprocess.CalledProcessError, IndexError):
            return "?"

    return {"rustc": first_line(["rustc", "--version"]), "valgrind": first_line(["valgrind", "--version"])}


def load_baseline(path: Path) -> dict:
    if not path.exists():
        return {"counts": {}}
    return json.loads(path.read_text())


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bench", action="append", choices=BENCHES, help="only this bench (repeatable)")
    ap.add_argument("--baseline", type=Path, default=BASELINE,
                    help=f"baseline file (default {BASELINE.relative_to(ROOT)})")
    ap.add_argument("--n", type=int, default=None, help=f"updates per run (default: the baseline's, else {N_UPDATES})")
    ap.add_argument("--tolerance", type=float, default=None,
                    help=f"allowed growth (default: the baseline's, else {TOLERANCE})")
    ap.add_argument("--update", action="store_true", help="rewrite the baseline with the measured counts")
    ap.add_argument("--no-build", action="store_true", help="use the existing target/release/count_updates")
    ap.add_argument("--binary", type=Path, default=BINARY,
                    help="count this count_updates binary instead (with --no-build; the other counting "
                         "binaries are taken from its directory)")
    args = ap.parse_args(argv)

    if shutil.which("valgrind") is None:
        print("callgrind_check: valgrind is not installed", file=sys.stderr)
        return 2
    if args.no_build:
        binaries = {"count_updates": args.binary}
        binaries.update({b: args.binary.parent / b for b in OTHER_BINARIES.values()})
    else:
        binaries = build()
    base = load_baseline(args.baseline)
    n = args.n or int(base.get("n_updates", N_UPDATES))
    tolerance = args.tolerance if args.tolerance is not None else float(base.get("tolerance", TOLERANCE))
    tools = toolchain()
    if not args.update:
        for key, value in base.get("toolchain", {}).items():
            if tools.get(key) != value:
                print(f"note: baseline made with {key} {value!r}, now {tools.get(key)!r}: counts may differ "
                      f"for that reason alone (re-baseline in a commit of its own)")

    benches = args.bench or BENCHES
    measured = {b: per_update(binary_for(b, binaries), b, n) for b in benches}
    rows = compare(measured, base.get("counts", {}), tolerance)
    print(f"instructions per update under callgrind ({n} updates, minus a 0-update run)")
    print(format_table(rows, tolerance))

    if args.update:
        counts = dict(base.get("counts", {}))
        counts.update({b: round(v, 2) for b, v in measured.items()})
        new = {
            "about": "Instructions per update (callgrind Ir) of target/release/count_updates; "
                     "checked by benches/callgrind_check.py (make bench-check), rewritten by --update.",
            "n_updates": n,
            "tolerance": tolerance,
            "toolchain": tools,
            "counts": {b: counts[b] for b in sorted(counts)},
        }
        args.baseline.write_text(json.dumps(new, indent=2) + "\n")
        print(f"baseline rewritten: {args.baseline}")
        return 0
    if passed(rows):
        print("bench-check: ok")
        return 0
    print("bench-check: FAILED (a count grew by more than "
          f"{tolerance:.0%}, or has no baseline); if intended, see --update in the docstring", file=sys.stderr)
    return 1


if __name__ == "__main__":
    raise SystemExit(main())

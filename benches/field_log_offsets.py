"""Channel offsets of 0-20 ms (the field-logs must-show): is the deflection's delay against the
accelerometers estimated within 1 ms, and is the damper's change then found as without it?

For each seed from ``--seed0``: the passenger quarter car's drive at 400 Hz (class C, 15 m/s,
the damper 1500 -> 1350 N s/m at 40 s, 70 s, the default sensors), the deflection delayed by
each offset by an exact FFT phase shift (``tests/field_logs.py``: independent of the estimator),
written as a data logger's CSV (``Time [ms]``, g, mm, at 500 Hz through scipy's polyphase
resampler) and read by ``vehid monitor`` (``vehid.fieldlog``: resampled to 200 Hz, the delay
estimated and removed). Figures per offset: the estimate's error (max, mean absolute), how many
seeds report the damper, and the event time's difference from the same drive without an
offset (median, max). With ``--body`` the offsets are the body accelerometer's instead (the
deflection 4 ms late throughout), estimated from the body equation. ``--json PATH`` writes the
figures.

Reproducible: ``.venv/bin/python benches/field_log_offsets.py --seed0 70000 --seeds 20``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import re
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Dict, List

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import field_logs as F  # noqa: E402  (the tests' writer of field logs)

from vehid import cli  # noqa: E402

OFFSETS_MS = (0.0, 1.0, 2.0, 4.0, 5.0, 7.3, 10.0, 15.0, 20.0)


def monitor(path: Path, cmap: Path, channel: str = "deflection") -> Dict[str, Any]:
    """``vehid monitor`` on the logger CSV: its first event and the delay it removed (ms)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = cli.main(["monitor", str(path), "--columns", str(cmap), "--model", "passenger", "--json"])
    if status != 0:
        raise SystemExit(f"vehid monitor failed: {err.getvalue()}")
    events = [json.loads(line) for line in out.getvalue().splitlines() if line.strip()]
    text = err.getvalue()
    delay = 0.0  # under the tolerance (0.25 ms) the delay is not removed and no note is printed
    m = re.search(rf"note: {channel}: ([0-9.]+) ms (late|early) against", text)
    if m:
        delay = float(m.group(1)) * (1 if m.group(2) == "late" else -1)
    return {"event": events[0] if events else None, "delay_ms": delay, "stderr": text}


def main(argv: List[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seed0", type=int, default=70_000)
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--body", action="store_true", help="offset the body accelerometer instead")
    p.add_argument("--json", default=None, metavar="PATH")
    args = p.parse_args(argv)
    rows: Dict[float, Dict[str, List[float]]] = {o: {"err": [], "dt_event": [], "found": []} for o in OFFSETS_MS}
    t_start = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        cmap = d / "logger.toml"
        cmap.write_text(F.LOGGER_MAP)
        for seed in range(args.seed0, args.seed0 + args.seeds):
            run = F.drive(70.0, changes=[(40.0, {"b": 1350.0})], seed=seed)
            base = None
            for off in OFFSETS_MS:
                if args.body:
                    log = F.logger_csv(d / f"s{seed}_{off}.csv", run, late=0.004, body_late=off * 1e-3)
                else:
                    log = F.logger_csv(d / f"s{seed}_{off}.csv", run, late=off * 1e-3)
                got = monitor(log, cmap, "a_body" if args.body else "deflection")
                ev = got["event"]
                found = ev is not None and ev["parameter"] == "b"
                rows[off]["found"].append(float(found))
                rows[off]["err"].append(got["delay_ms"] - off)
                if off == 0.0:
                    base = ev["t"] if found else None
                if found and base is not None:
                    rows[off]["dt_event"].append(ev["t"] - base)
            print(f"seed {seed} done ({time.time() - t_start:.0f} s)", file=sys.stderr, flush=True)
    figures = {}
    print(f"{'offset ms':>9} {'max |err| ms':>12} {'mean |err|':>10} {'damper found':>12} "
          f"{'event - no-offset event, s: median':>36} {'max |.|':>8}")
    for off, r in rows.items():
        err = np.abs(r["err"])
        dte = np.asarray(r["dt_event"]) if r["dt_event"] else np.asarray([np.nan])
        figures[off] = {"max_abs_err_ms": float(err.max()), "mean_abs_err_ms": float(err.mean()),
                        "found": int(sum(r["found"])), "seeds": len(r["found"]),
                        "event_shift_median_s": float(np.median(dte)),
                        "event_shift_max_abs_s": float(np.max(np.abs(dte)))}
        f = figures[off]
        print(f"{off:9.1f} {f['max_abs_err_ms']:12.3f} {f['mean_abs_err_ms']:10.3f} "
              f"{f['found']:>6}/{f['seeds']:<5} {f['event_shift_median_s']:36.3f} {f['event_shift_max_abs_s']:8.3f}")
    if args.json:
        Path(args.json).write_text(json.dumps({"args": vars(args), "figures": figures}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))

"""Undeclared sensor noise (the field-logs must-show): sensors 0.3-3 times as noisy as the
defaults, the log read by ``vehid monitor`` with the noise declared (``--noise``) and not.

For each seed from ``--seed0`` and each factor: the passenger quarter car's drive at 200 Hz
(class C, 15 m/s, the damper 1500 -> 1350 N s/m at 40 s, 80 s) with every sensor's white noise
(a_body 0.02, a_wheel 0.1 m/s^2, deflection 0.3 mm) times the factor, written as vehid's CSV.
Figures per factor and mode: the damper found (of the seeds), the median delay after the change,
the share of the time judged, and (undeclared) the deflection noise the monitor estimated.

Reproducible: ``.venv/bin/python benches/field_log_noise.py --seed0 80000 --seeds 10``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import re
import sys
import tempfile
from pathlib import Path
from typing import Dict, List

import numpy as np

import vehid
from vehid import cli

FACTORS = (0.3, 0.5, 1.0, 2.0, 3.0)
DEFAULTS = {"a_body": 0.02, "a_wheel": 0.1, "deflection": 3e-4}


def monitor(argv: List[str]) -> Dict[str, object]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = cli.main(["monitor", *argv, "--model", "passenger", "--json"])
    if status != 0:
        raise SystemExit(err.getvalue())
    events = [json.loads(line) for line in out.getvalue().splitlines() if line.strip()]
    judged = re.search(r"judged (\d+) %", err.getvalue())
    est = re.search(r"estimated from the data: ([0-9.]+) mm", err.getvalue())
    return {"events": events, "judged": float(judged.group(1)) if judged else float("nan"),
            "noise_mm": float(est.group(1)) if est else float("nan")}


def main(argv: List[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seed0", type=int, default=80_000)
    p.add_argument("--seeds", type=int, default=10)
    args = p.parse_args(argv)
    print(f"{'factor':>6} {'mode':>10} {'found':>7} {'median delay s':>14} {'judged %':>9} {'est. mm':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        for factor in FACTORS:
            noise = {k: v * factor for k, v in DEFAULTS.items()}
            rows: Dict[str, List[Dict[str, object]]] = {"declared": [], "undeclared": []}
            for seed in range(args.seed0, args.seed0 + args.seeds):
                sim = vehid.Simulator(vehid.QuarterCar.passenger(), dt=0.005, road="iso8608-C", speed=15.0,
                                      changes=[(40.0, {"b": 1350.0})], sensors="realistic", seed=seed,
                                      sensor_noise=noise)
                run = sim.run(16_000)
                path = Path(tmp) / f"{seed}.csv"
                np.savetxt(path, np.column_stack([run.t, run.y]), delimiter=",", header="t,a_body,a_wheel,deflection",
                           comments="", fmt="%.9g")
                decl = ",".join(f"{k}={v:g}" for k, v in noise.items())
                rows["declared"].append(monitor([str(path), "--noise", decl]))
                rows["undeclared"].append(monitor([str(path)]))
            for mode, rs in rows.items():
                delays = [e["t"] - 40.0 for r in rs for e in r["events"][:1] if e["parameter"] == "b"]  # type: ignore
                found = len(delays)
                est_mm = [float(r["noise_mm"]) for r in rs if r["noise_mm"] == r["noise_mm"]]  # type: ignore
                est = float(np.median(est_mm)) if est_mm else float("nan")
                print(f"{factor:6.1f} {mode:>10} {found:>3}/{len(rs):<3} "
                      f"{(np.median(delays) if delays else float('nan')):14.2f} "
                      f"{np.mean([r['judged'] for r in rs]):9.0f} {est:8.3g}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))

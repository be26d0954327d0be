"""One drive written five ways (the field-logs must-show), each read by ``vehid monitor``: vehid's
CSV (200 Hz), an MCAP bag (IMUs at 400 Hz, a JointState at 100 Hz, header stamps), the same bag as
``.db3`` and as a bag folder, a data logger's CSV (500 Hz, ms, g, mm, the deflection 4 ms late)
and Parquet with timestamps. Prints each form's first event and how far apart they are.

The drive: the passenger quarter car, class C, 15 m/s, the damper 1500 -> 1350 N s/m at 40 s,
70 s at 400 Hz (``tests/field_logs.py`` writes the forms). Reproducible:
``.venv/bin/python benches/field_log_five_ways.py --seed 2`` (the test's drive); ``--joint-rates``
adds the bag with its JointState at 400 Hz and at 100 Hz low-passed before it is sampled (the
cause of the bags' 10-75 ms: docs/capabilities/field-logs.md, "One drive, five ways").
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
from pathlib import Path
from typing import List

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import field_logs as F  # noqa: E402  (the tests' writer of field logs)

from vehid import cli  # noqa: E402


def main(argv: List[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seed", type=int, default=2)
    p.add_argument("--joint-rates", action="store_true",
                   help="also the bag with its JointState at 400 Hz, and at 100 Hz low-passed before sampling")
    args = p.parse_args(argv)
    run = F.drive(70.0, changes=[(40.0, {"b": 1350.0})], seed=args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        (d / "bag.toml").write_text(F.BAG_MAP)
        (d / "logger.toml").write_text(F.LOGGER_MAP)
        mcap, db3 = F.bag(d / "mcap", run), F.bag(d / "db3", run, storage="sqlite3")
        forms = {
            "vehid CSV, 200 Hz": [str(F.vehid_csv(d / "drive.csv", run))],
            "MCAP file": [str(next(mcap.glob("*.mcap"))), "--columns", str(d / "bag.toml")],
            "bag folder (MCAP)": [str(mcap), "--columns", str(d / "bag.toml")],
            ".db3 file": [str(next(db3.glob("*.db3"))), "--columns", str(d / "bag.toml")],
            "logger CSV (ms, g, mm, 500 Hz, 4 ms late)": [str(F.logger_csv(d / "logger.csv", run)), "--columns",
                                                          str(d / "logger.toml")],
            "Parquet, timestamps": [str(F.parquet(d / "drive.parquet", run))],
        }
        if args.joint_rates:  # why the bags differ: the JointState's sampling of the deflection
            forms["MCAP, JointState at 400 Hz"] = [str(F.bag(d / "j400", run, joint_every=1)), "--columns",
                                                   str(d / "bag.toml")]
            forms["MCAP, JointState at 100 Hz anti-aliased"] = [str(F.bag(d / "j100aa", run, antialias=True)),
                                                                "--columns", str(d / "bag.toml")]
        times = []
        for name, form in forms.items():
            out, err = io.StringIO(), io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                status = cli.main(["monitor", *form, "--model", "passenger", "--json"])
            if status != 0:
                raise SystemExit(f"{name}: {err.getvalue()}")
            evs = [json.loads(line) for line in out.getvalue().splitlines() if line.strip()]
            ev = evs[0]
            times.append(ev["t"])
            print(f"{name:44s} {ev['parameter']} at {ev['t']:.3f} s: {ev['before']:.0f} -> {ev['after']:.1f} "
                  f"[{ev['low']:.1f}, {ev['high']:.1f}] N s/m ({len(evs)} event{'s' * (len(evs) != 1)})")
        print(f"spread of the event times: {1e3 * (max(times) - min(times)):.1f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))

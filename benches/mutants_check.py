#!/usr/bin/env python3
"""Mutation testing of vehid-core with cargo-mutants: `make mutants`.

Runs ``cargo mutants`` on the files given (default: ``crates/vehid-core/src/identify/**``,
5,187 mutants on 2026-11-26) and reports the fraction of viable mutants the Rust tests catch,
with its 95 % interval, and every surviving mutant. On this 2-core machine a mutant costs one
to two minutes (an incremental rebuild of vehid-core's test targets and their run; the first
build of a run's copy of the tree comes on top: about 20 minutes the first time, 4 minutes
once ``target/mutants/build`` holds the dependencies), so the whole of
``identify/`` is days of work: ``--shard K/N`` (round-robin) takes every N-th mutant of the
list, a systematic sample spread over every file, and a run's figure is an estimate of the
whole with a binomial interval. Shards add up: ``--shard 2/40`` tests other mutants than
``1/40``; and they nest: ``K/N`` is ``K/2N`` and ``(K+N)/2N`` together (``1/40`` = ``1/80`` +
``41/80``), so a shard too long for the time at hand can be run in halves.

A survivor is either a gap in the tests (write the test) or a mutant no test can catch: an
equivalent mutant, unreachable code, or a change of speed only. Those are listed, each with
its reason, in ``benches/mutants_accepted.txt`` (``<mutant as cargo-mutants names it>  #
<reason>``); the run fails (exit 1) when a survivor is not on that list. An entry whose line
and column no longer match (an edit above it moved the mutant) still accepts a survivor with
the same file, change and function when that change is the only one of its kind in the
function now (else it could be another occurrence), and the run says to rename it; ``--iterate`` finds
the first pass's survivors the same way. cargo-mutants
itself shows progress; its full output stays in ``target/mutants/<shard>/mutants.out``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Dict, List, Set, Tuple

ROOT = Path(__file__).resolve().parents[1]
ACCEPTED = ROOT / "benches" / "mutants_accepted.txt"
DEFAULT_FILE = "crates/vehid-core/src/identify/**"


def accepted() -> Dict[str, str]:
    """The accepted survivors: mutant name -> reason."""
    out: Dict[str, str] = {}
    if not ACCEPTED.exists():
        return out
    for line in ACCEPTED.read_text(encoding="utf-8").splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        name, _, reason = line.partition("  # ")
        if not reason.strip():
            raise SystemExit(f"mutants: {ACCEPTED.name}: no reason given for {name!r} (write '<name>  # <reason>')")
        out[name.strip()] = reason.strip()
    return out


def where_free(name: str) -> str:
    """A mutant's name without its line and column (``file: replace X with Y in f``): what
    stays the same when an edit elsewhere in the file moves it."""
    return re.sub(r"^([^:]+):\d+:\d+: ", r"\1: ", name)


def where_free_pattern(name: str) -> str:
    """A regular expression for the mutant ``name`` at any line and column (for cargo-mutants'
    ``--re``; a function with the same change twice matches both, a superset)."""
    file, _, rest = where_free(name).partition(": ")
    return re.escape(file) + r":\d+:\d+: " + re.escape(rest)


def find_accepted(name: str, ok_list: Dict[str, str], unique: Set[str]) -> Tuple[str | None, str | None]:
    """The accepted entry for the survivor ``name``, and its reason: the entry of the same name,
    else the one entry that differs only in line and column (the code above it moved; the
    caller says to rename it), provided that ``name``'s change is the only one of its kind in
    its function (``unique``: the ``where_free`` names that occur once in the current list),
    so that it cannot be another occurrence. ``(None, None)`` otherwise."""
    if name in ok_list:
        return name, ok_list[name]
    key = where_free(name)
    same = [entry for entry in ok_list if where_free(entry) == key]
    if len(same) == 1 and key in unique:
        return same[0], ok_list[same[0]]
    return None, None


def stale_entries(ok_list: Dict[str, str], tested: List[Tuple[str, str]], unique: Set[str]) -> List[str]:
    """The accepted entries this run caught: tested under their own name, or under another line
    when their change is the only one of its kind in its function (``unique``), as
    :func:`find_accepted` matches; never an entry whose function has the same change elsewhere
    (``least_squares.rs:339:40`` caught says nothing of an accepted ``338:85``)."""
    caught = {n for n, s in tested if s != "MissedMutant"}
    missed = {where_free(n) for n, s in tested if s == "MissedMutant"}
    moved = {where_free(n) for n in caught if where_free(n) in unique} - missed
    return sorted(e for e in ok_list if e in caught or where_free(e) in moved)


def unique_changes(file_glob: str) -> Set[str]:
    """The ``where_free`` names that occur once among the mutants cargo-mutants lists now."""
    done = subprocess.run(["cargo", "mutants", "-p", "vehid-core", "--file", file_glob, "--list"],
                          cwd=ROOT, capture_output=True, text=True)
    counts: Dict[str, int] = {}
    for line in done.stdout.splitlines():
        if line.strip():
            counts[where_free(line.strip())] = counts.get(where_free(line.strip()), 0) + 1
    return {k for k, n in counts.items() if n == 1}


def wilson(k: int, n: int, z: float = 1.96) -> Tuple[float, float]:
    """The Wilson score interval of a binomial proportion k / n (95 % by default)."""
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, mid - half), min(1.0, mid + half))


def read_outcomes(path: Path) -> Dict[str, str]:
    """Mutant name -> summary, from a cargo-mutants outcomes.json (the baseline left out)."""
    found: Dict[str, str] = {}
    if path.exists():
        for o in json.loads(path.read_text(encoding="utf-8")).get("outcomes", []):
            scenario = o.get("scenario")
            if isinstance(scenario, dict) and "Mutant" in scenario:
                found[scenario["Mutant"]["name"]] = o.get("summary", "?")
    return found


def outcomes(out_dir: Path) -> List[Tuple[str, str]]:
    """(mutant name, summary) of every mutant of the shard: the shard's run, with the outcome
    of a later ``--iterate`` run (``recheck/``: the same mutants it had not caught, tested
    again) in place of the first where there is one."""
    found = read_outcomes(out_dir / "mutants.out" / "outcomes.json")
    found.update(read_outcomes(out_dir / "recheck" / "mutants.out" / "outcomes.json"))
    return list(found.items())


def main(argv: List[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--file", default=DEFAULT_FILE, help="files to mutate (a glob)")
    ap.add_argument("--shard", default="1/40", help="K/N: every N-th mutant, from the K-th (0-based K < N)")
    ap.add_argument("--jobs", default="1", help="cargo-mutants jobs (each builds on both cores)")
    ap.add_argument("--report-only", action="store_true", help="only read the last run's outcomes")
    ap.add_argument("--skip-baseline", action="store_true",
                    help="do not run the tests on the unmutated tree first (cargo-mutants --baseline=skip: "
                         "saves a whole test build and run, about 16 minutes here; only on a tree whose Rust "
                         "tests are known to pass, e.g. just after make test)")
    ap.add_argument("--iterate", action="store_true",
                    help="test again only the mutants the last run of this shard did not catch")
    args = ap.parse_args(argv)
    if not re.fullmatch(r"\d+/\d+", args.shard):
        raise SystemExit(f"mutants: --shard {args.shard!r}: expected K/N, e.g. 1/40")
    out_dir = ROOT / "target" / "mutants" / args.shard.replace("/", "-of-")
    if args.file != DEFAULT_FILE:
        # Another file set's shard K/N is another sample: its own directory, named after the
        # glob (model/** 0/50: target/mutants/crates_vehid_core_src_model-0-of-50).
        glob = re.sub(r"[^A-Za-z0-9]+", "_", args.file).strip("_")
        out_dir = out_dir.with_name(f"{glob}-{out_dir.name}")
    if not args.report_only:
        out_dir.mkdir(parents=True, exist_ok=True)
        cmd = ["cargo", "mutants", "-p", "vehid-core", "--file", args.file, "--shard", args.shard,
               "--sharding", "round-robin", "--jobs", args.jobs, "--output", str(out_dir)]
        if args.iterate:
            # Exactly the shard's mutants that were missed (not the unviable ones, which do not
            # build; cargo-mutants' own --iterate would shard the list that is left, which is
            # another sample), found by file, change and function at any line (the tests
            # written since may have moved them).
            first = read_outcomes(out_dir / "mutants.out" / "outcomes.json")
            again = sorted(n for n, s in first.items() if s == "MissedMutant")
            if not again:
                print("mutants: nothing left to test again in this shard")
            recheck = out_dir / "recheck"
            recheck.mkdir(exist_ok=True)
            cmd = ["cargo", "mutants", "-p", "vehid-core", "--file", args.file, "--jobs", args.jobs,
                   "--output", str(recheck), "--re", "^(" + "|".join(where_free_pattern(n) for n in again) + ")$"]
        elif (out_dir / "recheck").exists():
            shutil.rmtree(out_dir / "recheck")  # a fresh run of the shard: earlier rechecks are void
        if args.skip_baseline:
            # Without the baseline's time no timeout is derived from it: 20 minutes, well
            # above a test run here (a mutant that runs that long is listed as a timeout).
            cmd += ["--baseline=skip", "--timeout", "1200"]
        print("mutants:", " ".join(cmd)[:300], flush=True)
        env = dict(os.environ)
        if args.jobs == "1":
            # The copy of the tree builds in target/mutants/build, kept from run to run: a run
            # after the first rebuilds only the workspace crates (the copy's path is new), not
            # the dependencies. With them built, shard 2/160's first build took 219 s on a
            # machine loaded by other builds, against 1275 s for shard 1/80's in a target/
            # of its own (2026-11-26). Never the caller's CARGO_TARGET_DIR: a
            # build of the working tree there at the same time would take turns with the
            # copy's, and the two trees' vehid-core share artifact names.
            env["CARGO_TARGET_DIR"] = str(ROOT / "target" / "mutants" / "build")
        else:
            # Several copies building in one directory would overwrite each other's
            # vehid-core: each builds in its own target/.
            env.pop("CARGO_TARGET_DIR", None)
        # cargo-mutants exits 2 when mutants were missed, 3 on timeouts: judged below.
        done = subprocess.run(cmd, cwd=ROOT, env=env)
        if done.returncode not in (0, 2, 3):
            print(f"mutants: cargo mutants failed (status {done.returncode})", file=sys.stderr)
            return 1
    tested = outcomes(out_dir)
    counts: Dict[str, int] = {}
    for _, summary in tested:
        counts[summary] = counts.get(summary, 0) + 1
    caught, missed = counts.get("CaughtMutant", 0), counts.get("MissedMutant", 0)
    timeout, unviable = counts.get("Timeout", 0), counts.get("Unviable", 0)
    viable = caught + missed + timeout
    low, high = wilson(caught + timeout, viable)
    share = (caught + timeout) / viable if viable else float("nan")
    print(f"mutants: {args.file}, shard {args.shard}: {len(tested)} mutants tested: {caught} caught, "
          f"{timeout} timeouts (caught), {missed} missed, {unviable} unviable")
    print(f"mutants: caught {caught + timeout} of {viable} viable = {100 * share:.1f} % "
          f"(95 % interval {100 * low:.1f}-{100 * high:.1f} %)")
    ok_list = accepted()
    unique = unique_changes(args.file) if tested else set()
    new = []
    for name, summary in tested:
        if summary != "MissedMutant":
            continue
        entry, reason = find_accepted(name, ok_list, unique)
        print(f"  missed: {name}" + (f"  [accepted: {reason}]" if reason else "  [NOT ACCEPTED]"))
        if entry is not None and entry != name:
            print(f"    (accepted as {entry.split(': ')[0]}: the line moved; rename the entry in {ACCEPTED.name})")
        if reason is None:
            new.append(name)
    stale = stale_entries(ok_list, tested, unique)
    for name in stale:
        print(f"  accepted but now caught (remove it from {ACCEPTED.name}): {name}")
    if new:
        print(f"mutants: {len(new)} survivor(s) not in {ACCEPTED.name}: write a test, or accept with a reason")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""The mutants on lines no Rust test runs: `make mutants-uncovered`.

cargo-mutants judges a mutant by vehid-core's and vehid-thesis' Rust tests. A mutant on a
line those tests never execute survives for certain, whatever the tests check; finding them
by mutation costs about 40 s each here, by coverage one instrumented test run for all of
them. This script builds the Rust tests with LLVM source-based coverage (`-C
instrument-coverage`, on the workspace crates only, through a `RUSTC_WRAPPER`, in
`target/cov`), runs them, and lists every mutant of `cargo mutants --list` (the same files
as `make mutants`, default `identify/**`) whose line ran zero times, grouped by function,
with the totals. Needs the `llvm-tools` rustup component (installed when missing).

Reproducible: the same tree gives the same list (the tests are seeded). A mutant listed
here is a test to write (or an unreachable line); a mutant not listed can still survive
(executed but not checked): that is what `make mutants` measures.
"""

from __future__ import annotations

import argparse
import collections
import glob
import json
import os
import shutil
import stat
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Dict

ROOT = Path(__file__).resolve().parents[1]
COV = ROOT / "target" / "cov"
DEFAULT_FILE = "crates/vehid-core/src/identify/**"
PACKAGES = ["vehid-core", "vehid-thesis"]

WRAPPER = """#!/bin/sh
# RUSTC_WRAPPER: instrument the workspace crates only (dependencies build as usual).
rustc="$1"; shift
case "$*" in
  *crates/vehid-core/*|*crates/vehid-thesis/*) exec "$rustc" "$@" -C instrument-coverage ;;
esac
exec "$rustc" "$@"
"""


def llvm_bin() -> Path:
    """The rustup toolchain's llvm-tools directory (installing the component when missing)."""
    sysroot = subprocess.run(["rustc", "--print", "sysroot"], capture_output=True, text=True, check=True).stdout.strip()
    found = glob.glob(os.path.join(sysroot, "lib", "rustlib", "*", "bin", "llvm-profdata"))
    if not found:
        print("uncovered: installing the llvm-tools component (rustup)", flush=True)
        subprocess.run(["rustup", "component", "add", "llvm-tools"], check=True)
        found = glob.glob(os.path.join(sysroot, "lib", "rustlib", "*", "bin", "llvm-profdata"))
    if not found:
        raise SystemExit("uncovered: llvm-profdata not found (rustup component add llvm-tools)")
    return Path(found[0]).parent


def line_counts(lcov: str) -> Dict[str, Dict[int, int]]:
    """File (from `crates/` on) -> line -> execution count, from an lcov export."""
    cov: Dict[str, Dict[int, int]] = {}
    cur: Dict[int, int] = {}
    for line in lcov.splitlines():
        if line.startswith("SF:"):
            path = line[3:]
            at = path.find("crates/")
            cur = cov.setdefault(path[at:] if at >= 0 else path, {})
        elif line.startswith("DA:"):
            num, count = line[3:].split(",")[:2]
            cur[int(num)] = max(cur.get(int(num), 0), int(count))
    return cov


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--file", default=DEFAULT_FILE, help="the files to mutate (cargo-mutants --file)")
    ap.add_argument("--out", default=str(COV / "uncovered.txt"), help="where to write the list")
    args = ap.parse_args(argv)
    bindir = llvm_bin()
    COV.mkdir(parents=True, exist_ok=True)
    wrapper = COV / "rustc-wrapper.sh"
    wrapper.write_text(WRAPPER, encoding="utf-8")
    wrapper.chmod(wrapper.stat().st_mode | stat.S_IXUSR)
    env = dict(os.environ, RUSTC_WRAPPER=str(wrapper), CARGO_TARGET_DIR=str(COV))
    # The wrapper is not part of cargo's fingerprint: rebuild the workspace crates so that
    # they are instrumented whatever was built here before.
    subprocess.run(["cargo", "clean", "-q", *sum((["-p", p] for p in PACKAGES), [])], cwd=ROOT, env=env, check=True)
    profiles = Path(tempfile.mkdtemp(prefix="vehid-cov-"))
    env["LLVM_PROFILE_FILE"] = str(profiles / "%p-%m.profraw")
    print("uncovered: building and running the Rust tests with coverage (cargo shows progress)", flush=True)
    test = ["cargo", "test", *sum((["-p", p] for p in PACKAGES), []), "--tests"]
    subprocess.run(test, cwd=ROOT, env=env, check=True)
    listing = subprocess.run(
        [*test, "--no-run", "--message-format=json"], cwd=ROOT, env=env, check=True, capture_output=True, text=True
    ).stdout
    artifacts = [json.loads(line) for line in listing.splitlines()]
    binaries = sorted({a["executable"] for a in artifacts if a.get("executable")})
    merged = profiles / "merged.profdata"
    raw = [str(p) for p in profiles.glob("*.profraw")]
    subprocess.run([str(bindir / "llvm-profdata"), "merge", "-sparse", *raw, "-o", str(merged)], check=True)
    objects = sum((["-object", b] for b in binaries), [])
    lcov = subprocess.run(
        [str(bindir / "llvm-cov"), "export", "-format=lcov", f"-instr-profile={merged}", *objects],
        check=True, capture_output=True, text=True,
    ).stdout
    shutil.rmtree(profiles, ignore_errors=True)
    cov = line_counts(lcov)
    mutants = json.loads(
        subprocess.run(["cargo", "mutants", "-p", "vehid-core", "--file", args.file, "--list", "--json"],
                       cwd=ROOT, check=True, capture_output=True, text=True).stdout
    )
    uncovered = []
    unknown = 0
    for m in mutants:
        lines = cov.get(m["file"], {})
        line = m["span"]["start"]["line"]
        if line not in lines:
            # A mutant inside a multi-line expression: the nearest line with a count above it,
            # within its function.
            first = m["function"]["span"]["start"]["line"] if m.get("function") else line
            above = [k for k in lines if first <= k <= line]
            if not above:
                unknown += 1
                continue
            line = max(above)
        if lines[line] == 0:
            uncovered.append(m)
    by_fn = collections.Counter(
        (m["file"], m["function"]["function_name"] if m.get("function") else "?") for m in uncovered
    )
    by_file = collections.Counter(m["file"] for m in uncovered)
    Path(args.out).write_text("".join(m["name"] + "\n" for m in uncovered), encoding="utf-8")
    for (f, fn), n in sorted(by_fn.items()):
        print(f"{n:4d}  {f.split('src/')[-1]}  {fn}")
    print()
    for f, n in by_file.most_common():
        print(f"{n:4d}  {f.split('src/')[-1]}")
    share = len(uncovered) / max(1, len(mutants))
    print(f"\nuncovered: {len(uncovered)} of {len(mutants)} mutants ({100 * share:.1f} %) on lines no Rust test runs "
          f"({unknown} without line data); list in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

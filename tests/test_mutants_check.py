"""The mutation-testing report (benches/mutants_check.py, benches/uncovered_mutants.py): the
binomial interval, the accepted list's matching of survivors whose line moved, and the
coverage reading. Not a mutation run: names and counts are fed in; `make mutants` runs one.
"""

from __future__ import annotations

import re

from bench_scripts import ROOT, load  # tests/ is on sys.path under pytest

mc = load("mutants_check")
um = load("uncovered_mutants")

NAME = (
    "crates/vehid-core/src/identify/kalman/lanes.rs:1089:58: replace < with <= in "
    "<impl RowGroup<T, N> for RowLanes<T, N, L>>::plan"
)


def test_wilson_interval_matches_its_closed_form():
    # k = 55 of n = 66 at z = 1.96: the Wilson bounds, computed here from the formula.
    k, n, z = 55, 66, 1.96
    p = k / n
    mid = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * (p * (1 - p) / n + z * z / (4 * n * n)) ** 0.5 / (1 + z * z / n)
    low, high = mc.wilson(k, n)
    assert abs(low - (mid - half)) < 1e-12 and abs(high - (mid + half)) < 1e-12
    assert round(100 * low, 1) == 72.6 and round(100 * high, 1) == 90.4  # shard 4/80 in docs/claims.md
    assert mc.wilson(0, 0) == (0.0, 1.0)
    assert mc.wilson(10, 10)[1] == 1.0


def test_a_survivor_whose_line_moved_is_still_accepted_and_named():
    moved = NAME.replace(":1089:58:", ":1101:7:")
    ok = {NAME: "equivalent"}
    unique = {mc.where_free(NAME)}
    assert mc.where_free(moved) == mc.where_free(NAME)
    assert mc.find_accepted(NAME, ok, set()) == (NAME, "equivalent")
    assert mc.find_accepted(moved, ok, unique) == (NAME, "equivalent")
    # The same change twice in the function now: the survivor may be the other one.
    assert mc.find_accepted(moved, ok, set()) == (None, None)
    # Another change, or another function, is another mutant.
    other = moved.replace("with <=", "with ==")
    assert mc.find_accepted(other, ok, {mc.where_free(other)}) == (None, None)
    other = moved.replace("::plan", "::check")
    assert mc.find_accepted(other, ok, {mc.where_free(other)}) == (None, None)
    # Two entries that differ only in line: which one is meant is unknown, so neither.
    twin = NAME.replace(":1089:58:", ":1200:3:")
    assert mc.find_accepted(moved, {NAME: "a", twin: "b"}, unique) == (None, None)


def test_an_accepted_entry_is_stale_only_when_that_mutant_was_caught():
    ok = {NAME: "equivalent"}
    other_line = NAME.replace(":1089:58:", ":1090:40:")
    # Caught under its own name: stale, whatever else the function holds.
    assert mc.stale_entries(ok, [(NAME, "CaughtMutant")], set()) == [NAME]
    # The same change at another line: stale only when the change is unique in its function
    # (then it is this mutant, moved) and it did not also survive there.
    assert mc.stale_entries(ok, [(other_line, "CaughtMutant")], set()) == []
    assert mc.stale_entries(ok, [(other_line, "CaughtMutant")], {mc.where_free(NAME)}) == [NAME]
    assert mc.stale_entries(ok, [(NAME, "MissedMutant")], {mc.where_free(NAME)}) == []


def test_the_recheck_pattern_finds_the_mutant_at_any_line_only():
    pattern = mc.where_free_pattern(NAME)
    assert re.fullmatch(pattern, NAME)
    assert re.fullmatch(pattern, NAME.replace(":1089:58:", ":7:1:"))
    assert not re.fullmatch(pattern, NAME.replace("with <=", "with >"))
    assert not re.fullmatch(pattern, NAME.replace("lanes.rs", "rows.rs"))


def test_every_accepted_entry_has_a_reason_and_the_form_of_a_cargo_mutants_name():
    entries = mc.accepted()
    assert entries, "benches/mutants_accepted.txt is empty"
    shape = re.compile(r"crates/[\w/-]+\.rs:\d+:\d+: \S.*")
    for name, reason in entries.items():
        assert shape.fullmatch(name), name
        assert len(reason) > 20, (name, reason)


def test_coverage_lines_are_read_from_lcov():
    lcov = "\n".join(
        [
            "SF:/work/x/crates/vehid-core/src/identify/a.rs",
            "DA:3,0",
            "DA:4,12",
            "DA:4,0",
            "end_of_record",
            "SF:/elsewhere/lib.rs",
            "DA:1,1",
            "end_of_record",
        ]
    )
    cov = um.line_counts(lcov)
    # The path from `crates/` on; a line seen twice (two instantiations) counts as run when
    # either ran.
    assert cov["crates/vehid-core/src/identify/a.rs"] == {3: 0, 4: 12}
    assert cov["/elsewhere/lib.rs"] == {1: 1}
    assert (ROOT / "benches" / "uncovered_mutants.py").exists()

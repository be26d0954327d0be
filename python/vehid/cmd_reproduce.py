"""``vehid reproduce``: the thesis' figures and tables, regenerated into a report by
:mod:`vehid.reproduce`; this module checks ``--out`` before the work and reports a failure
to write the report in one line.

>>> build = argparse.ArgumentParser().add_subparsers()
>>> add_parser(build)
>>> args = build.choices["reproduce"].parse_args(["--quick"])
>>> args.quick, args.out, args.seed
(True, 'report/', 1986)
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path
from typing import Any

from . import reproduce
from .clitools import CliError


def _check_out_dir(out: str) -> None:
    """Fails now, not after the whole reproduction, when ``--out`` cannot be a directory the
    report can be written into: a probe is created, then removed, in ``--out`` (a file) or,
    when it does not exist yet, in its nearest existing parent (a directory, as ``--out``
    and its parents will be). Nothing is left behind, so an argument error found later
    creates nothing."""
    probe = Path(out)
    while not probe.exists() and probe.parent != probe:
        probe = probe.parent
    if not probe.is_dir():
        raise CliError(f"--out {out}: {probe} is not a directory")
    try:
        if probe == Path(out):
            fd, name = tempfile.mkstemp(prefix=".vehid-probe-", dir=probe)
            os.close(fd)
            os.remove(name)
        else:
            os.rmdir(tempfile.mkdtemp(prefix=".vehid-probe-", dir=probe))
    except OSError as e:
        raise CliError(f"--out {out}: cannot write into {probe} ({e.strerror or e}): choose a writable directory") \
            from None


def cmd_reproduce(args: argparse.Namespace) -> int:
    """Runs ``vehid reproduce`` with parsed arguments (:func:`vehid.reproduce.command`, looked
    up when it runs)."""
    _check_out_dir(args.out)
    try:
        return reproduce.command(args)
    except OSError as e:
        where = f" {e.filename}" if e.filename else ""
        raise CliError(f"--out {args.out}: cannot write the report ({e.strerror or e}{':' if where else ''}{where})") \
            from None


def add_parser(sub: Any) -> None:
    """Adds ``vehid reproduce`` and its options (:func:`vehid.reproduce.add_arguments`) to the
    subparsers ``sub``."""
    rep = sub.add_parser(
        "reproduce",
        help="reproduce the thesis' figures and tables into a report",
        description="Runs the thesis' simulation study (every figure of Ch. III-VI, Monte Carlo over seeds), "
        "writes one PNG per figure (with the plot extra: pip install vehid[plot]) and report/index.md + index.html "
        "comparing each thesis claim with vehid's measurement, and prints the report's path.",
    )
    reproduce.add_arguments(rep)
    rep.set_defaults(func=cmd_reproduce)

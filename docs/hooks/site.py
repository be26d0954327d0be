"""MkDocs hook: what the site needs besides its pages.

- ``vehid`` and ``python`` on PATH for the executed shell examples: shims running this
  Python (``-m vehid``), so that the examples run the same package the API pages describe
  (the one ``import vehid`` finds), whatever else is installed; and an empty working
  directory for them, ``target/docs-examples`` (the blocks' ``workdir``).
- rustdoc: the HTML that ``cargo doc --no-deps -p vehid-core -p vehid-thesis`` wrote into
  ``target/doc`` becomes part of the site under ``rustdoc/``, so that links to it are checked
  like any other. Without it the build warns (and ``--strict`` fails): ``make docs`` runs
  cargo doc first.
"""

from __future__ import annotations

import atexit
import logging
import os
import shutil
import stat
import sys
import tempfile
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

log = logging.getLogger("mkdocs.hooks.site")
RUSTDOC_CRATES = ("vehid_core", "vehid_thesis")


EXAMPLES_DIR = "target/docs-examples"


def on_config(config: Any) -> Any:
    shim = Path(tempfile.mkdtemp(prefix="vehid-docs-bin-"))
    atexit.register(shutil.rmtree, shim, ignore_errors=True)
    for name, args in (("vehid", " -m vehid"), ("python", "")):
        exe = shim / name
        exe.write_text(f'#!/bin/sh\nexec "{sys.executable}"{args} "$@"\n')
        exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    os.environ["PATH"] = f"{shim}{os.pathsep}{os.environ.get('PATH', '')}"
    # the shell examples run in another directory: a relative PYTHONPATH must not break
    if os.environ.get("PYTHONPATH"):
        os.environ["PYTHONPATH"] = os.pathsep.join(
            str(Path(p).resolve()) for p in os.environ["PYTHONPATH"].split(os.pathsep) if p
        )
    work = Path(config.config_file_path).resolve().parent / EXAMPLES_DIR
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    return config


def on_files(files: Files, config: Any) -> Files:
    root = Path(config.config_file_path).resolve().parent
    doc = Path(os.environ.get("CARGO_TARGET_DIR", root / "target")) / "doc"
    missing = [c for c in RUSTDOC_CRATES if not (doc / c / "index.html").is_file()]
    if missing:
        log.warning(
            "rustdoc for %s not found in %s: run `cargo doc --no-deps -p vehid-core -p vehid-thesis` "
            "first (`make docs` does)",
            ", ".join(missing),
            doc,
        )
        return files
    for path in sorted(doc.rglob("*")):
        # rustdoc's .md files (font licences) would become pages: copied after the build
        if path.is_file() and path.name != ".lock" and path.suffix != ".md":
            rel = path.relative_to(doc).as_posix()
            files.append(File.generated(config, f"rustdoc/{rel}", abs_src_path=str(path)))
    _rustdoc["dir"] = doc
    return files


_rustdoc: dict = {}


def on_post_build(config: Any) -> None:
    doc = _rustdoc.get("dir")
    if doc is None:
        return
    for path in doc.rglob("*.md"):
        dest = Path(config.site_dir) / "rustdoc" / path.relative_to(doc)
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, dest)

"""The Python package's layout: no import cycle among its modules, and no private name
crossing from one module to another.

The import graph is read from the source with ``ast``, every ``import`` and ``from ...
import`` counted wherever it stands (at the top, inside a function, under a condition), so
a cycle cannot hide behind a function-local import. An edge goes to the module a statement
loads: ``from . import fieldlog`` to ``vehid.fieldlog``, ``from . import QuarterCar`` to
``vehid`` (its ``__init__``), ``from .io import Column`` to ``vehid.io``. The import of a
package's ``__init__`` that Python performs before any of its submodules is not an edge
(every submodule would then be in a cycle with an ``__init__`` that imports one of them).

Private names: a module may not import a ``_name`` from another vehid module (nor reach one
as ``module._name`` through a module it imported). A private module may be imported only
from inside its own package: the extension ``vehid._vehid`` by every vehid module,
``fleet/_deps.py`` by the fleet's. Dunder names (``__version__``) are public.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Set, Tuple

import pytest

import vehid

PACKAGE = Path(vehid.__file__).resolve().parent


def is_private(name: str) -> bool:
    """``_name`` but not ``__dunder__``.

    >>> is_private("_stdout"), is_private("__version__"), is_private("stdout")
    (True, False, False)
    """
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


@dataclass
class Layout:
    """The modules of a package (dotted name -> file), its import edges and the private
    names that cross modules."""

    modules: Dict[str, Path]
    packages: Set[str]
    edges: Dict[str, Set[str]] = field(default_factory=dict)
    #: (importer, line, what): each private name imported from, or reached in, another module.
    private: List[Tuple[str, int, str]] = field(default_factory=list)


def module_names(root: Path, name: str) -> Tuple[Dict[str, Path], Set[str]]:
    """Every module of the package ``name`` at ``root`` (``.py`` files, ``__init__.py`` as the
    package itself; the extension by its stub), and which of them are packages."""
    modules: Dict[str, Path] = {}
    packages: Set[str] = set()
    for path in sorted(root.rglob("*.py")) + sorted(root.rglob("*.pyi")):
        parts = [name, *path.relative_to(root).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts.pop()
            packages.add(".".join(parts))
        modules.setdefault(".".join(parts), path)
    return modules, packages


def read_layout(root: Path, name: str) -> Layout:
    """The import graph and the private-name crossings of the package ``name`` at ``root``."""
    modules, packages = module_names(root, name)
    layout = Layout(modules, packages)
    for mod, path in modules.items():
        if path.suffix == ".pyi":
            continue
        here = mod if mod in packages else mod.rpartition(".")[0]
        edges = layout.edges.setdefault(mod, set())
        #: Local names bound to a module of the package: their attributes are checked too.
        bound: Dict[str, str] = {}
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    target = loaded(alias.name, modules)
                    if target is None:
                        continue
                    edges.add(target)
                    check_module(layout, mod, node.lineno, target)
                    if alias.asname is not None and alias.name in modules:
                        bound[alias.asname] = alias.name
            elif isinstance(node, ast.ImportFrom):
                base = resolve(here, node.level, node.module)
                if base is None or loaded(base, modules) != base:
                    continue
                check_module(layout, mod, node.lineno, base)
                for alias in node.names:
                    sub = f"{base}.{alias.name}"
                    if sub in modules:  # from . import fieldlog: the submodule
                        edges.add(sub)
                        check_module(layout, mod, node.lineno, sub)
                        bound[alias.asname or alias.name] = sub
                    else:  # from .io import Column: a name of the module
                        edges.add(base)
                        if is_private(alias.name) and base != mod:
                            layout.private.append((mod, node.lineno, f"{base}.{alias.name}"))
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in bound
                    and is_private(node.attr) and f"{bound[node.value.id]}.{node.attr}" not in modules):
                layout.private.append((mod, node.lineno, f"{bound[node.value.id]}.{node.attr}"))
        edges.discard(mod)
    return layout


def loaded(dotted: str, modules: Dict[str, Path]) -> Optional[str]:
    """The module of the package that ``import dotted`` loads (the longest prefix that is one)."""
    parts = dotted.split(".")
    for n in range(len(parts), 0, -1):
        if ".".join(parts[:n]) in modules:
            return ".".join(parts[:n])
    return None


def resolve(here: str, level: int, module: Optional[str]) -> Optional[str]:
    """The absolute module of ``from <level dots><module> import ...`` in package ``here``."""
    if level == 0:
        return module
    parts = here.split(".")
    if level - 1 >= len(parts):
        return None
    base = parts[: len(parts) - (level - 1)]
    return ".".join(base + (module.split(".") if module else []))


def check_module(layout: Layout, importer: str, line: int, target: str) -> None:
    """A private module (``pkg._mod``) may be imported only from inside ``pkg`` (the extension
    ``vehid._vehid``: from anywhere in vehid)."""
    package, _, last = target.rpartition(".")
    if not is_private(last):
        return
    if not (importer == package or importer.startswith(package + ".")):
        layout.private.append((importer, line, target))


def cycles(edges: Dict[str, Set[str]]) -> List[List[str]]:
    """The strongly connected components with more than one module (Tarjan), each as a list
    of modules, sorted."""
    index: Dict[str, int] = {}
    low: Dict[str, int] = {}
    stack: List[str] = []
    on_stack: Set[str] = set()
    found: List[List[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_no_import_cycle() -> None:
    layout = read_layout(PACKAGE, "vehid")
    assert "vehid.cli" in layout.edges and "vehid.clitools" in layout.edges["vehid.cli"]  # the graph was read
    assert cycles(layout.edges) == []


def test_no_private_name_crosses_modules() -> None:
    layout = read_layout(PACKAGE, "vehid")
    assert layout.private == []


def test_the_command_line_is_one_module_per_command() -> None:
    """vehid.cli holds the parser and main(); each command's code lives in its own module,
    which imports nothing from vehid.cli (only ``python -m vehid`` runs it)."""
    layout = read_layout(PACKAGE, "vehid")
    commands = ["vehid.cmd_simulate", "vehid.cmd_identify", "vehid.cmd_demo", "vehid.cmd_reproduce", "vehid.monitor",
                "vehid.inspect_log", "vehid.fleet.cli"]
    assert set(commands) <= layout.edges["vehid.cli"]
    for mod, targets in layout.edges.items():
        if mod != "vehid.__main__":
            assert "vehid.cli" not in targets, f"{mod} imports vehid.cli: import what it needs from vehid.clitools"


# --- the checks catch what they are for ---------------------------------------------------


def make_package(root: Path, files: Dict[str, str]) -> Path:
    pkg = root / "pkg"
    for name, text in {"__init__.py": "", **files}.items():
        path = pkg / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return pkg


@pytest.mark.parametrize("files, cycle", [
    # The cycle vehid.cli <-> vehid.monitor had, hidden in a function.
    ({"cli.py": "from .monitor import run\n", "monitor.py": "def run():\n    from .cli import CliError\n"},
     ["pkg.cli", "pkg.monitor"]),
    # Through a submodule import and a subpackage.
    ({"a.py": "from . import b\n", "b.py": "from .sub.c import x\n", "sub/__init__.py": "",
      "sub/c.py": "import pkg.a\nx = 1\n"}, ["pkg.a", "pkg.b", "pkg.sub.c"]),
    # Through the package's __init__.
    ({"__init__.py": "from .a import f\n", "a.py": "from .b import f\n", "b.py": "from . import Thing\n"},
     ["pkg", "pkg.a", "pkg.b"]),
])
def test_a_cycle_is_found(tmp_path: Path, files: Dict[str, str], cycle: List[str]) -> None:
    layout = read_layout(make_package(tmp_path, files), "pkg")
    assert cycles(layout.edges) == [cycle]


def test_an_acyclic_package_passes(tmp_path: Path) -> None:
    files = {"__init__.py": "from . import a\n", "a.py": "from ._ext import X\n", "b.py": "from . import X\n",
             "_ext.pyi": "X: int\n"}
    layout = read_layout(make_package(tmp_path, files), "pkg")
    assert cycles(layout.edges) == []
    assert layout.edges["pkg"] == {"pkg.a"} and layout.edges["pkg.b"] == {"pkg"}


@pytest.mark.parametrize("text, what", [
    ("from .reproduce import _load_pyplot\n", "pkg.reproduce._load_pyplot"),
    ("def f():\n    from .reproduce import _load_pyplot as lp\n", "pkg.reproduce._load_pyplot"),
    ("from . import reproduce\nreproduce._load_pyplot()\n", "pkg.reproduce._load_pyplot"),
    ("import pkg.reproduce as r\nr._load_pyplot()\n", "pkg.reproduce._load_pyplot"),
    ("from .sub._deps import module\n", "pkg.sub._deps"),
])
def test_a_private_name_crossing_modules_is_found(tmp_path: Path, text: str, what: str) -> None:
    files = {"reproduce.py": "def _load_pyplot(): ...\n", "sub/__init__.py": "", "sub/_deps.py": "module = 1\n",
             "monitor.py": text}
    layout = read_layout(make_package(tmp_path, files), "pkg")
    assert [p[2] for p in layout.private] == [what]


def test_what_may_cross(tmp_path: Path) -> None:
    """The extension, dunder names, a private module inside its own package, and a public name
    bound to a private alias."""
    files = {"_vehid.pyi": "X: int\n", "sub/__init__.py": "", "sub/_deps.py": "module = 1\n",
             "sub/a.py": "from ._deps import module\nfrom .. import _vehid\n",
             "b.py": "from ._vehid import X\nfrom . import __version__\nfrom . import sub as _sub\n"}
    layout = read_layout(make_package(tmp_path, files), "pkg")
    assert layout.private == []

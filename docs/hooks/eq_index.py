"""MkDocs hook: the page "Thesis equations → code", generated at build time.

Scans the comments and docstrings of ``crates/**/*.rs`` and ``python/**/*.py{,i}`` for
references to the thesis' equations ("Eq 4.27", "Eq. 3.17", "Eq 4.3–4.7", "Eq 4.28, 4.32",
"Eq 3.17 / 6.10", "equation (2.14)") and writes, in place of the marker ``<!-- eq-index -->``
of ``equations.md``, one table per chapter: each equation with the items that cite it (file,
line, item) and, apart, the tests that cite it. Ranges are expanded (Eq 4.3–4.7 lists 4.3,
4.4, …, 4.7). Only chapters II–VII count: the thesis has no other (Eq 8.26 is Söderström and
Stoica's).

The build fails (``PluginError``) when the marker is missing, when the scan finds no
reference at all, or when one of ``REQUIRED`` is not found: a renamed folder or a changed
comment style cannot empty the page silently.
"""

from __future__ import annotations

import ast
import os
import re
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Dict, Iterator, List, Optional, Tuple

from mkdocs.exceptions import PluginError

MARKER = "<!-- eq-index -->"
PAGE = "equations.md"
# Equations the library is built on; each must be cited somewhere or the scan is broken.
REQUIRED = ("2.14", "3.17", "4.3", "4.27", "4.36", "5.8", "6.14", "6.16")
# What each equation is (from the thesis; shown beside the number).
TITLES = {
    "2.1": "state equation ẋ = A x + B u",
    "2.2": "regression form ẋ = H θ + B u, H = I ⊗ xᵀ",
    "2.3": "regression form",
    "2.4": "regression form",
    "2.14": "batch least squares θ̂ = (HᵀH)⁻¹ Hᵀ z",
    "2.20": "least-squares bias under state noise",
    "2.56": "stochastic gradient with state-noise bias removal",
    "2.8": "n independent noise-free samples determine θ",
    "3.4": "batch least squares (Ch. III)",
    "3.8": "quarter car",
    "3.9": "quarter car",
    "3.10": "quarter car",
    "3.11": "quarter car",
    "3.12": "quarter car",
    "3.13": "quarter car",
    "3.14": "quarter car: the thesis' values and poles",
    "3.17": "error measure ξ",
    "3.18": "acceptance ξ ≤ 0.08",
    "4.3": "Kalman identifier (θ̂, G, P updates)",
    "4.4": "Kalman identifier (θ̂, G, P updates)",
    "4.5": "Kalman identifier (θ̂, G, P updates)",
    "4.6": "Kalman identifier: covariance update",
    "4.7": "R = R_v + B R_u Bᵀ",
    "4.25": "road autocorrelation (held white noise)",
    "4.27": "output standard deviation under road noise",
    "4.28": "quarter car σ_x / σ_u",
    "4.31": "sensor SNR",
    "4.32": "quarter car SNR",
    "4.33": "per-element noise sensitivity",
    "4.34": "per-element noise sensitivity",
    "4.35": "reinitialization",
    "4.36": "reinitialization rule",
    "4.37": "instrumentation",
    "4.38": "instrumentation",
    "4.39": "instrumentation",
    "5.8": "Venter gain k^(−p)",
    "5.9": "Lyapunov (normalized) gain",
    "5.10": "wheel-row gains",
    "5.15": "Ljung gain",
    "5.16": "Ljung gain",
    "5.17": "Ljung gain",
    "5.18": "Ljung gain",
    "6.1": "half car",
    "6.2": "half car",
    "6.3": "half car",
    "6.4": "half car",
    "6.5": "half car",
    "6.6": "half car",
    "6.7": "half car",
    "6.8": "half car",
    "6.9": "rear input u2(t) = u1(t − L/v)",
    "6.10": "error measure ξ (half car)",
    "6.12": "rear-row bias removal (Eq 6.12–6.14)",
    "6.13": "front-row innovation e1 = z2 − xᵀθ̂_2",
    "6.14": "rear-row innovation minus the delayed front-row innovation",
    "6.16": "decoupled rows",
    "6.17": "decoupled rows",
    "6.18": "decoupled rows",
}
for _i in range(2, 15):
    TITLES.setdefault(f"5.{_i}", "stochastic gradient")
CHAPTERS = {"2": "II", "3": "III", "4": "IV", "5": "V", "6": "VI", "7": "VII"}

_NUM = r"[2-7]\.\d{1,2}(?![\d]|\.\d)"
_ITEM = rf"{_NUM}(?:\s*[–-]\s*{_NUM})?"
EQ_RE = re.compile(rf"\b(?:Eq(?:uations?|s)?\.?)\s*\(?((?:{_ITEM})(?:\s*(?:,|/|and|&)\s*(?:{_ITEM}))*)")
NUM_RE = re.compile(_NUM)
OTHER_SOURCE = re.compile(r"(Stoica|Söderström|Ljung, \*)[^.;]{0,30}$")


@dataclass(frozen=True)
class Site:
    path: str  # relative to the repository root
    line: int
    item: str
    cited: str  # the reference as written, e.g. "4.3–4.7"
    test: bool


def _expand(ref: str) -> List[str]:
    """ "4.3–4.7, 4.36" -> ["4.3", "4.4", ..., "4.7", "4.36"]."""
    out: List[str] = []
    for part in re.split(r"\s*(?:,|/|and|&)\s*", ref.strip()):
        nums = NUM_RE.findall(part)
        if len(nums) == 2 and nums[0].split(".")[0] == nums[1].split(".")[0]:
            ch, a = nums[0].split(".")
            b = int(nums[1].split(".")[1])
            if 0 < b - int(a) <= 20:
                out.extend(f"{ch}.{i}" for i in range(int(a), b + 1))
                continue
        out.extend(nums)
    return out


def _refs(text: str) -> Iterator[Tuple[str, List[str]]]:
    for m in EQ_RE.finditer(text):
        if OTHER_SOURCE.search(text[: m.start()]):
            continue
        yield re.sub(r"\s+", " ", m.group(1)).strip(), _expand(m.group(1))


# --- Rust ---------------------------------------------------------------------------------

_ITEM_RE = re.compile(
    r"^(\s*)(?:pub(?:\([^)]*\))?\s+)?(?:(?:unsafe|const|async|default|extern\s+\"C\")\s+)*"
    r"(fn|struct|enum|trait|mod|impl|union|type|const|static|macro_rules!)\b\s*(.*)$"
)
_FIELD_RE = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?([A-Za-z_]\w*)\s*[:({,]")


def _strip_generics(s: str) -> str:
    depth, out = 0, []
    for ch in s:
        if ch == "<":
            depth += 1
        elif ch == ">":
            depth = max(0, depth - 1)
        elif depth == 0:
            out.append(ch)
    return "".join(out)


def _item_name(kind: str, rest: str) -> str:
    if kind == "impl":
        rest = _strip_generics(rest)
        if " for " in f" {rest} ":
            rest = rest.split(" for ", 1)[1]
        m = re.match(r"\s*&?(?:dyn\s+)?([\w:]+)", rest)
        return m.group(1).split("::")[-1] if m else "impl"
    m = re.match(r"([A-Za-z_]\w*)", rest)
    return m.group(1) if m else kind


def _module_path(rel: str) -> str:
    parts = Path(rel).parts  # crates/<crate>/src/a/b.rs
    crate = parts[1].replace("-", "_")
    if len(parts) > 2 and parts[2] == "src":
        mods = list(parts[3:])
        last = mods.pop()
        if last not in ("lib.rs", "mod.rs", "main.rs"):
            mods.append(last[:-3])
        return "::".join([crate, *mods])
    return f"{crate} ({'/'.join(parts[2:])})"


def _is_test_path(rel: str) -> bool:
    p = Path(rel)
    return "tests" in p.parts[:-1] or p.name == "tests.rs" or p.stem.endswith("_tests") or p.stem.startswith("tests_")


def _scan_rust(root: Path, rel: str) -> Iterator[Tuple[str, Site]]:
    lines = (root / rel).read_text(encoding="utf-8").splitlines()
    stack: List[Tuple[int, str, str]] = []  # (indent, kind, name) of enclosing items
    items: Dict[int, Tuple[int, str, str]] = {}
    # First pass: the item declared on each line, and the chain enclosing each line.
    chain_at: List[List[Tuple[int, str, str]]] = []
    for i, line in enumerate(lines):
        s = line.strip()
        m = _ITEM_RE.match(line) if not s.startswith("//") else None
        indent = len(line) - len(line.lstrip())
        if m:
            name = _item_name(m.group(2), m.group(3))
            while stack and stack[-1][0] >= indent:
                stack.pop()
            items[i] = (indent, m.group(2), name)
        chain_at.append(list(stack))
        if m:
            stack.append(items[i])
    module = _module_path(rel)
    test_file = _is_test_path(rel)

    def qualified(chain: List[Tuple[int, str, str]], last: Optional[str]) -> Tuple[str, bool]:
        names = [n for _, k, n in chain if k != "mod" or n != "tests"]
        in_tests = any(k == "mod" and n in ("tests", "test") for _, k, n in chain)
        if last:
            names.append(last)
        return ("::".join(names) if names else module), in_tests

    for i, line in enumerate(lines):
        s = line.lstrip()
        if not s.startswith("//"):
            # a trailing comment after code
            pos = line.find(" // ")
            if pos < 0 or line.count('"', 0, pos) % 2:
                continue
            text = line[pos + 4 :]
        else:
            text = s.lstrip("/!")
        refs = list(_refs(text))
        if not refs:
            continue
        indent = len(line) - len(s)
        if s.startswith("//!"):
            item, in_tests = module, False
        elif s.startswith("///"):
            # the item documented: the first line below that is neither doc nor attribute
            j = i + 1
            while j < len(lines) and lines[j].lstrip().startswith(("///", "#[", "#![")):
                j += 1
            last = None
            if j in items:
                last = items[j][2]
            elif j < len(lines):
                f = _FIELD_RE.match(lines[j])
                last = f.group(1) if f else None
            encl = [c for c in chain_at[j if j < len(lines) else i] if c[0] < indent]
            item, in_tests = qualified(encl, last)
        else:
            encl = [c for c in chain_at[i] if c[0] < indent]
            if i in items:  # trailing comment on a declaration line
                encl = encl + [items[i]]
            item, in_tests = qualified(encl, None)
        for cited, eqs in refs:
            for eq in eqs:
                yield eq, Site(rel, i + 1, item, cited, test_file or in_tests)


# --- Python -------------------------------------------------------------------------------


def _scan_python(root: Path, rel: str) -> Iterator[Tuple[str, Site]]:
    src = (root / rel).read_text(encoding="utf-8")
    module = ".".join(Path(rel).with_suffix("").parts[1:])  # python/vehid/io.py -> vehid.io
    module = module.removesuffix(".__init__")
    tree = ast.parse(src)
    spans: List[Tuple[int, int, str]] = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = f"{prefix}.{child.name}"
                spans.append((child.lineno, child.end_lineno or child.lineno, name))
                visit(child, name)

    visit(tree, module)
    test = rel.startswith("tests/")
    for i, line in enumerate(src.splitlines(), start=1):
        if "Eq" not in line:
            continue
        inner = [s for s in spans if s[0] <= i <= s[1]]
        item = max(inner, key=lambda s: s[0])[2] if inner else module
        for cited, eqs in _refs(line):
            for eq in eqs:
                yield eq, Site(rel, i, item, cited, test)


# --- the page -----------------------------------------------------------------------------


def scan(root: Path) -> Dict[str, List[Site]]:
    index: Dict[str, List[Site]] = defaultdict(list)
    rust = sorted(p.relative_to(root).as_posix() for p in (root / "crates").rglob("*.rs"))
    py = sorted(
        p.relative_to(root).as_posix()
        for ext in ("*.py", "*.pyi")
        for p in (root / "python").rglob(ext)
        if "__pycache__" not in p.parts
    )
    for rel in rust:
        if "/target/" in rel:
            continue
        for eq, site in _scan_rust(root, rel):
            index[eq].append(site)
    for rel in py:
        for eq, site in _scan_python(root, rel):
            index[eq].append(site)
    return index


def _key(eq: str) -> Tuple[int, int]:
    a, b = eq.split(".")
    return int(a), int(b)


def _source_links(doc: Optional[Path]) -> Callable[[str], Optional[str]]:
    """File -> its page in rustdoc's source view (``rustdoc/src/<crate>/…rs.html``), when
    ``cargo doc`` wrote one (library files of the documented crates only)."""

    def link(path: str) -> Optional[str]:
        parts = Path(path).parts  # crates/<crate>/src/...
        if doc is None or len(parts) < 4 or parts[0] != "crates" or parts[2] != "src":
            return None
        rel = Path("src", parts[1].replace("-", "_"), *parts[3:])
        page = rel.with_name(rel.name + ".html")
        return f"rustdoc/{page.as_posix()}" if (doc / page).is_file() else None

    return link


def _cell(sites: List[Site], link: Callable[[str], Optional[str]]) -> str:
    seen: Dict[Tuple[str, str], Site] = {}
    for s in sites:
        seen.setdefault((s.path, s.item), s)
    parts = []
    for s in seen.values():
        rng = f" (cites {s.cited})" if s.cited != s.cited.split("–")[0] or "," in s.cited else ""
        where = f"{s.path}:{s.line}"
        target = link(s.path)
        if target:
            where = f"[{where}]({target}#{s.line})"
        parts.append(f"`{s.item}` <small>{where}{rng}</small>")
    return "<br>".join(parts) if parts else "—"


def render(index: Dict[str, List[Site]], link: Callable[[str], Optional[str]] = lambda _: None) -> str:
    n_sites = sum(len({(s.path, s.line) for s in v}) for v in index.values())
    out = [
        f"{len(index)} equations, cited at {n_sites} places "
        f"(scanned at build time from `crates/**/*.rs` and `python/**/*.py`).",
        "",
    ]
    by_ch: Dict[str, List[str]] = defaultdict(list)
    for eq in sorted(index, key=_key):
        by_ch[eq.split(".")[0]].append(eq)
    for ch, eqs in by_ch.items():
        out += [f"## Chapter {CHAPTERS[ch]}", "", "| Eq | what | code | tests |", "|---|---|---|---|"]
        for eq in eqs:
            code = [s for s in index[eq] if not s.test]
            tests = [s for s in index[eq] if s.test]
            out.append(f"| {eq} | {TITLES.get(eq, '')} | {_cell(code, link)} | {_cell(tests, link)} |")
        out.append("")
    return "\n".join(out)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    if page.file.src_uri != PAGE:
        return markdown
    if MARKER not in markdown:
        raise PluginError(f"eq_index: {PAGE} lost its marker {MARKER!r}")
    root = Path(config.config_file_path).resolve().parent
    index = scan(root)
    if not index:
        raise PluginError("eq_index: no equation reference found in crates/ or python/ (the scan is broken)")
    missing = [eq for eq in REQUIRED if eq not in index]
    if missing:
        raise PluginError(f"eq_index: no reference found to Eq {', '.join(missing)} (the scan is broken)")
    doc = Path(os.environ.get("CARGO_TARGET_DIR", root / "target")) / "doc"
    return markdown.replace(MARKER, render(index, _source_links(doc if (doc / "src").is_dir() else None)))

"""Equation texts that took the process down raise VehidError promptly instead.

Short texts crashed the parser behind ``vehid.Structure``: deep nesting overflowed its stack
(a segmentation fault), ``(1+1)*(1+1)*...`` aborted on a 30 GB allocation, and 200,000
parameter names took tens of seconds before the parameter count was checked. The same texts
reach the parser from a model file (``vehid identify data.csv --model file.toml``).
"""

import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable, Dict, Sequence

import pytest

import vehid


def structure(text: str, states: Sequence[str] = ("x",), **kw: Any) -> vehid.Structure:
    """A structure whose first state's derivative is ``text``."""
    return vehid.Structure(states=list(states), equations={states[0]: text}, **kw)


def on_small_stack(call: Callable[[], Any]) -> Any:
    """``call()`` on a thread with a 1 MiB stack: a parser that recursed once per level of a
    10,000-byte text would overflow it (it would not always overflow the main thread's 8
    MiB). Returns what ``call`` returns, raises what it raises."""
    out: Dict[str, Any] = {}

    def run() -> None:
        try:
            out["value"] = call()
        except BaseException as e:  # re-raised in the calling thread
            out["error"] = e

    old = threading.stack_size(1 << 20)
    try:
        thread = threading.Thread(target=run)
        thread.start()
    finally:
        threading.stack_size(old)
    thread.join()
    if "error" in out:
        raise out["error"]
    return out["value"]


def raises_promptly(call: Callable[[], Any], match: str) -> vehid.VehidError:
    t0 = time.perf_counter()
    with pytest.raises(vehid.VehidError, match=match) as info:
        on_small_stack(call)
    elapsed = time.perf_counter() - t0
    assert elapsed < 1.0, f"{elapsed:.2f} s"
    assert isinstance(info.value, ValueError)
    return info.value


# The texts of the report, each longer than the 10,000 bytes an equation may have.
REPORTED = {
    "parentheses": "(" * 10_000 + "a*x" + ")" * 10_000,
    "unary-minus": "-" * 20_000 + "a*x",
    "sign-calls": "a*" + "sign(" * 10_000 + "x" + ")" * 10_000,
    "parameter-names": " + ".join(f"p{i}*x" for i in range(200_000)),
}


@pytest.mark.parametrize("text", REPORTED.values(), ids=list(REPORTED))
def test_reported_texts_are_refused_by_length(text: str) -> None:
    raises_promptly(
        lambda: structure(text), rf"^equation for x: the text is {len(text)} bytes long; at most 10000 are supported"
    )


# As deep, within the length limit: the nesting limit stops them (the position is that of
# the 65th level's '(' or '-'; a leading '-' is not a level).
DEEP = {
    "parentheses": ("(" * 4990 + "a*x" + ")" * 4990, 65),
    "unary-minus": ("-" * 9990 + "a*x", 66),
    "sign-calls": ("a*" + "sign(" * 1600 + "x" + ")" * 1600, 2 + 65 * 5),
}


@pytest.mark.parametrize(("text", "position"), DEEP.values(), ids=list(DEEP))
def test_deep_nesting_is_refused(text: str, position: int) -> None:
    assert len(text) <= 10_000
    match = rf"^equation for x: nested more than 64 levels deep at position {position}:"
    e = raises_promptly(lambda: structure(text), match)
    assert text not in str(e)  # the message does not repeat a long text


def test_sixty_four_levels_are_parsed() -> None:
    s = on_small_stack(lambda: structure("(" * 64 + "a*x" + ")" * 64))
    assert s.parameters == ("a",)
    raises_promptly(lambda: structure("(" * 65 + "a*x" + ")" * 65), "nested more than 64 levels deep")


def test_products_are_sized_before_they_are_expanded() -> None:
    # 2^40 products before like terms are merged, one term after: built, promptly.
    t0 = time.perf_counter()
    s = on_small_stack(lambda: structure("*".join(["(1+1)"] * 40) + "*a*x"))
    assert time.perf_counter() - t0 < 1.0
    assert s.parameters == ("a",) and s.derivative([1.0], [1.0]) == [2.0**40]
    # 12 parameters times 9 states: 108 different terms, refused before the expansion.
    states = ["x"] + [f"y{i}" for i in range(1, 9)]
    text = "(a+b+c+d+e+f+g+h+i+j+k+l)*(" + "+".join(states) + ")"
    raises_promptly(lambda: structure(text, states), r"the product ending at position 53 has 12 × 9 terms: at most 96")


def test_many_parameter_names_are_refused_by_count() -> None:
    names = [f"p{i}" for i in range(200_000)]
    raises_promptly(
        lambda: structure("p0*x", parameters=names), r"^parameters: 200000 given; at most 32 are supported"
    )
    raises_promptly(
        lambda: vehid.Structure(states=names, equations={"p0": "a*p0"}), r"^states: 200000 given; at most 16"
    )
    text = " + ".join(f"p{i}*x" for i in range(33))
    raises_promptly(lambda: structure(text), r"^equation for x: 'p32' \(ending at position 249\) would be parameter 33")


def test_cli_reports_a_deeply_nested_model_file_in_one_line(tmp_path: Path) -> None:
    # Set up as tests/test_structure.py's bad model files.
    csv = tmp_path / "d.csv"
    csv.write_text("x,dx\n1,2\n2,3\n3,5\n")
    model = tmp_path / "m.toml"
    model.write_text('states = ["x"]\n[equations]\nx = "' + "(" * 1000 + "a*x" + ")" * 1000 + '"\n')
    out = subprocess.run(
        [sys.executable, "-m", "vehid", "identify", str(csv), "--model", str(model)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in out.stderr, out.stderr
    assert lines[0] == (
        f"vehid: error: {model}: equation for x: nested more than 64 levels deep at position 65: at most 64 levels "
        "of parentheses, function calls and unary minus signs are supported; simplify the expression"
    ), lines[0]

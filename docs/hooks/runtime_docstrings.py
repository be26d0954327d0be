"""Griffe extension: signatures and types from the stub ``vehid/_vehid.pyi``, prose from the
compiled extension.

The stub carries the types but only one-line docstrings; the extension's docstrings (written
beside the pyo3 code in ``crates/vehid-py``) carry the units, shapes and equation numbers.
Griffe reads the stub statically (``allow_inspection: false``); this extension then replaces
each docstring of ``vehid._vehid`` by the runtime one where that is longer, shows a pyo3
class's ``__new__`` parameters as its signature, and keeps the stub's overloaded functions
(which griffe would otherwise drop, a stub having no implementation).
"""

from __future__ import annotations

import importlib
import inspect
from typing import Any

import griffe

MODULE = "vehid._vehid"


def _runtime(root: Any, path: list[str]) -> Any:
    obj = root
    for name in path:
        obj = inspect.getattr_static(obj, name, None) if inspect.isclass(obj) else getattr(obj, name, None)
        if obj is None:
            return None
    return obj


class RuntimeDocstrings(griffe.Extension):
    """Fill the stub's docstrings from the compiled module's."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        if pkg.path != "vehid" or "_vehid" not in pkg.members:
            return
        runtime = importlib.import_module(MODULE)
        self._overloads(pkg.members["_vehid"])
        self._walk(pkg.members["_vehid"], runtime, [])

    def _overloads(self, obj: griffe.Object) -> None:
        """A stub declares an overloaded function by its ``@overload`` variants only; griffe
        keeps those aside, waiting for an implementation that a stub never has. Make each a
        member with the last (most general) variant's signature and the others as overloads."""
        for name, variants in list(getattr(obj, "overloads", {}).items()):
            if name in obj.members or not variants:
                continue
            last = variants[-1]
            func = griffe.Function(
                name,
                parameters=last.parameters,
                returns=last.returns,
                lineno=last.lineno,
                endlineno=last.endlineno,
            )
            func.overloads = list(variants[:-1])
            obj.set_member(name, func)
        for member in obj.members.values():
            if not member.is_alias and member.is_class:
                self._overloads(member)

    def _walk(self, obj: griffe.Object, runtime: Any, path: list[str]) -> None:
        for name, member in list(obj.members.items()):
            if member.is_alias:
                continue
            target = _runtime(runtime, [*path, name])
            doc = getattr(target, "__doc__", None) if target is not None else None
            if isinstance(doc, str) and not (inspect.isclass(target) is False and doc == type(target).__doc__):
                doc = inspect.cleandoc(doc)
                old = member.docstring.value if member.docstring else ""
                if len(doc) > len(old):
                    member.docstring = griffe.Docstring(doc, parent=member)
            if member.is_class:
                self._walk(member, runtime, [*path, name])
                self._constructor(member)

    @staticmethod
    def _constructor(cls: griffe.Object) -> None:
        """pyo3 classes are built by ``__new__``: show its parameters as the class signature."""
        new = cls.members.get("__new__")
        if new is None or "__init__" in cls.members or not new.is_function:
            return
        params = list(new.parameters)
        if params and params[0].name == "cls":
            params[0] = griffe.Parameter("self", kind=params[0].kind)
        init = griffe.Function(
            "__init__", parameters=griffe.Parameters(*params), returns=None, lineno=new.lineno, endlineno=new.endlineno
        )
        cls.set_member("__init__", init)
        del cls.members["__new__"]

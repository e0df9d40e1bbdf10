"""Public names of a package, imported on first use (PEP 562 module ``__getattr__``).

``from robofleet.avoidance import build_cells`` works as always, but ``import robofleet``
(and the command line, which answers ``--version`` or ``validate`` without running
anything) loads no numerical library (numba, scipy, matplotlib, pandas, pyarrow) until a
name that needs one is used. ``tests/test_architecture.py`` checks which libraries the
package and the command line load.

A package writes::

    __all__ = [...]
    __getattr__, __dir__ = exports(__name__, {".cell": ["Cells", "build_cells"], ...})

A public name may equal the name of the submodule that defines it (``avoidance.buffer``,
the function of ``avoidance/buffer.py``): the import system sets a package's attribute to
each submodule it loads, so such a package keeps the public object under that name
(:class:`KeepsPublicNames`).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Iterable, Mapping
from types import ModuleType
from typing import Any


class KeepsPublicNames(ModuleType):
    """A package whose public names that are also submodule names are not rebound to the
    submodule when it is imported (documented module ``__class__`` customisation)."""

    public_submodule_names: frozenset[str] = frozenset()

    def __setattr__(self, name: str, value: Any) -> None:
        if isinstance(value, ModuleType) and name in type(self).public_submodule_names:
            return  # `from .name import name` semantics: the attribute names the public object
        super().__setattr__(name, value)


def exports(package: str, table: Mapping[str, Iterable[str]]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of ``package`` for the names ``table`` lists by
    module (``{".module": ["Name", ...]}``, relative to the package or absolute).

    A name is imported from its module on first use and kept as a package attribute.
    """
    home = {name: module for module, names in table.items() for name in names}
    shadowed = frozenset(name for name, module in home.items() if module == f".{name}")
    if shadowed:
        sys.modules[package].__class__ = type("KeepsPublicNames", (KeepsPublicNames,), {"public_submodule_names": shadowed})

    def __getattr__(name: str) -> Any:
        module = home.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module, package), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(home))

    return __getattr__, __dir__

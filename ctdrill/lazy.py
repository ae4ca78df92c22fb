"""Lazy re-exports for the rooms' ``__init__`` modules (PEP 562), in one place.

Each room keeps one table ``name -> defining module`` and mirrors it with ``TYPE_CHECKING``
imports for mypy (``tests/test_architecture.py`` checks the two agree);
:func:`attach` turns the table into the module-level ``__getattr__`` and ``__dir__``, so a name
imports its module only on first use.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any


def attach(
    package: str, exports: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package`` re-exporting ``exports`` lazily.

    Parameters
    ----------
    package : the package's ``__name__``.
    exports : public name -> the module that defines it.
    """

    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        setattr(sys.modules[package], name, value)  # cached: later lookups skip __getattr__
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(exports))

    return __getattr__, __dir__

"""PySide6 imported, its import hook's per-module check made cheap (imported first by the window).

Once PySide6 is imported, every module imported after it is checked for the text "PySide6"
(``shibokensupport.feature._mod_uses_pyside``, which decides whether ``from __feature__
import ...`` may switch it) through ``inspect.getsource``: its unwrapping, source-file search
and line cache cost about 0.45 ms a module, 0.1-0.2 s of CPU for the window's ~380 modules
imported after Qt (:mod:`ctdrill.app.gui.preload` imports the Qt-free ones before it). For a
module loaded from a ``.py`` file :func:`install` reads that file's bytes instead (the same
answer: the file is what ``getsource`` returns, and "PySide6" is ASCII in any encoding a source
may declare), and an extension module has no source (False, as ``getsource`` fails); any other
module gets PySide6's own check.
"""

from __future__ import annotations

import importlib.machinery
import sys
from collections.abc import Callable
from typing import Any

import PySide6.QtCore  # noqa: F401  (installs PySide6's hook, replaced below)

#: PySide6's module holding the hook's check.
FEATURE_MODULE = "shibokensupport.feature"
_EXTENSIONS = tuple(importlib.machinery.EXTENSION_SUFFIXES)


def reads_pyside(original: Callable[[Any], bool]) -> Callable[[Any], bool]:
    """``original`` (PySide6's check), answered from the module's file where it has one."""

    def uses_pyside(module: Any) -> bool:
        spec = getattr(module, "__spec__", None)
        origin = getattr(spec, "origin", None)
        if isinstance(origin, str) and origin == getattr(module, "__file__", None):
            if origin.endswith(".py"):
                try:
                    with open(origin, "rb") as fh:
                        return b"PySide6" in fh.read()
                except OSError:
                    pass
            elif origin.endswith(_EXTENSIONS):
                return False
        return bool(original(module))

    uses_pyside.ctdrill_original = original  # type: ignore[attr-defined]
    return uses_pyside


def install() -> bool:
    """Replace PySide6's check by :func:`reads_pyside` (once); False where this PySide6 has no
    such hook (nothing to do)."""
    feature = sys.modules.get(FEATURE_MODULE)
    original = getattr(feature, "_mod_uses_pyside", None)
    if feature is None or not callable(original) or hasattr(original, "ctdrill_original"):
        return False
    feature._mod_uses_pyside = reads_pyside(original)  # type: ignore[attr-defined]
    return True


install()

"""``scipy.linalg.cython_blas`` without the ``scipy.linalg`` package, for numba's BLAS check.

numba's first cache load imports ``numba.np.arraymath``, which imports
``scipy.linalg.cython_blas`` to learn whether BLAS is there (``_HAVE_BLAS``); through the
``scipy.linalg`` package that cost about 0.15 s of CPU (SciPy's array-API layer). The first
load (:mod:`ctdrill.jit`) gets that extension module itself, loaded from its file without the
package (:func:`cython_blas_alone`): numba finds the same BLAS, and ``scipy.linalg``, imported
later, gets the same module.
"""

from __future__ import annotations

import contextlib
import importlib.machinery
import importlib.util
import os
import sys
from collections.abc import Iterator

_BLAS_MODULE = "scipy.linalg.cython_blas"


@contextlib.contextmanager
def cython_blas_alone() -> Iterator[None]:
    """Within the block, ``scipy.linalg.cython_blas`` is imported (when ``scipy.linalg`` is
    not yet) by loading its extension file alone, without running the ``scipy.linalg``
    package; afterwards the name is dropped from ``sys.modules`` again, so a later
    ``import scipy.linalg.cython_blas`` goes through the package (CPython hands it the same
    module: an extension is initialised once per process)."""
    if _BLAS_MODULE in sys.modules or "scipy.linalg" in sys.modules:
        yield
        return
    loaded = False
    try:
        spec = importlib.util.find_spec("scipy")
        folders = list(spec.submodule_search_locations or ()) if spec else []
        for folder in folders:
            for suffix in importlib.machinery.EXTENSION_SUFFIXES:
                path = os.path.join(folder, "linalg", "cython_blas" + suffix)
                if os.path.isfile(path):
                    loader = importlib.machinery.ExtensionFileLoader(_BLAS_MODULE, path)
                    bspec = importlib.util.spec_from_file_location(
                        _BLAS_MODULE, path, loader=loader
                    )
                    assert bspec is not None
                    module = importlib.util.module_from_spec(bspec)
                    sys.modules[_BLAS_MODULE] = module
                    loaded = True
                    loader.exec_module(module)
                    break
            if loaded:
                break
    except Exception:  # pragma: no cover - numba then imports it through the package
        if loaded:
            sys.modules.pop(_BLAS_MODULE, None)
        loaded = False
    try:
        yield
    finally:
        if loaded and "scipy.linalg" not in sys.modules:
            sys.modules.pop(_BLAS_MODULE, None)

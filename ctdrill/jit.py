"""Compiled kernels that are never compiled in a user's path (numba, optional at run time).

A :class:`Kernel` wraps a numba function with its exact signatures. Compilation happens only
in :func:`warm_up` (``python -m ctdrill.app.search.warmup``, ``make warmup``, CI), which saves
the machine code in numba's on-disk cache; every other process only *loads* that cache
(:meth:`Kernel.ready`, a few ms) with compilation switched off, so a call can never stall on
the ~20 s compile. When the cache is absent or stale, numba is missing, or
``CTDRILL_NO_JIT=1`` is set, :meth:`Kernel.ready` is False and callers take their NumPy path,
which gives the same answers (the kernels are tested against it).

Where the cache lives: numba's default, ``__pycache__`` beside the module when that folder is
writable (a source checkout), else the user-wide cache (``~/.cache/numba`` or
``$NUMBA_CACHE_DIR``), which is where a wheel installed as root and used by another user
keeps it. Set ``NUMBA_CACHE_DIR`` to choose one (CI runs as root: a cache folder it
restores between runs).

numba itself is imported only when a kernel is first asked for (:meth:`Kernel.ready`): its
import and its first cache load cost a fresh process 0.3-0.5 s of CPU, more than a one-plan
export's whole work on the NumPy paths. Functions marked :func:`helper` stay plain Python
until a kernel is compiled (:meth:`Kernel.compile`, the warm-up), which compiles them and
rebinds them in the modules of the kernels and helpers; a kernel loaded from the cache needs
them not (its machine code holds them), so a kernel run as its own Python
(:attr:`Kernel.interpretable`) calls plain Python helpers also while another thread loads
numba. Inside :func:`job` a job of fewer than :data:`COMPILED_MIN_TRAJECTORIES`
trajectories (a one-plan export) does not load numba, unless it is loaded already: a
trajectory's stop must not depend on the process computing it (a batch row in a worker, the
same row in one process, the window), so every kernel such a job uses gives the compiled bits
without numba, on its NumPy path (the same operations in the same order; tests hold each bit
for bit, Hypothesis on adversarial inputs) or, the clearance rows' kernel
(:attr:`Kernel.interpretable`), as its own Python function.

numba's first cache load would import the ``scipy.linalg`` package for its BLAS check; it gets
the one extension module it needs alone (:func:`ctdrill.blas_alone.cython_blas_alone`).

A process that must show something first (the window) calls :func:`defer`: until
:func:`release` has loaded every kernel in a background thread, no caller loads numba, and
each kernel not loaded yet gives its bits as in a small :func:`job` (NumPy path, or its own
Python); each kernel is used compiled as soon as it is loaded.
"""

from __future__ import annotations

import contextlib
import importlib.util
import itertools
import os
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from ctdrill.blas_alone import cython_blas_alone

#: Environment variable that switches every kernel off (NumPy paths only).
NO_JIT_ENV = "CTDRILL_NO_JIT"
_KERNELS: list[Kernel] = []
#: Functions marked :func:`helper` before numba was loaded (compiled when it is).
_HELPERS: list[Callable[..., Any]] = []
#: numba once imported (``False``: the import failed); ``None``: not tried yet.
_NUMBA: list[Any] = [None]
_NUMBA_LOCK = threading.RLock()


def _numba() -> Any:
    """The numba module, imported on first use (None when it does not import)."""
    with _NUMBA_LOCK:
        if _NUMBA[0] is None:
            try:  # numba is a dependency, but a missing or broken one only costs speed
                import numba
            except Exception:  # pragma: no cover - exercised by CTDRILL_NO_JIT in the tests
                _NUMBA[0] = False
                return None
            _NUMBA[0] = numba
        return _NUMBA[0] or None


#: The :func:`helper` functions are compiled and rebound (:func:`_bind_helpers`).
_BOUND: list[bool] = [False]


def _bind_helpers(numba: Any) -> None:
    """Replace each plain :func:`helper` by its compiled dispatcher in the globals of every
    module that defines a kernel or a helper (where numba resolves the names it calls when it
    compiles a kernel; a kernel loaded from the cache does not look them up)."""
    _BOUND[0] = True
    plain = {id(f): f for f in _HELPERS}
    compiled = {id(f): numba.njit(nogil=True, error_model="numpy")(f) for f in _HELPERS}
    spaces = {id(f.__globals__): f.__globals__ for f in _HELPERS}
    spaces |= {id(k.pyfunc.__globals__): k.pyfunc.__globals__ for k in _KERNELS}
    for space in spaces.values():
        for name, value in list(space.items()):
            if plain.get(id(value)) is value:
                space[name] = compiled[id(value)]
    _HELPERS.clear()


def available() -> bool:
    """``CTDRILL_NO_JIT`` is not set and numba imports (importing it)."""
    return os.environ.get(NO_JIT_ENV, "") in ("", "0") and _numba() is not None


#: A job of fewer trajectories than this (a one-plan export) does not load numba when it is
#: not loaded yet: numba's import and first cache load cost a fresh process 0.3-0.5 s of CPU,
#: more than the whole job's work. Every kernel such a job uses gives the compiled bits
#: without it: on its NumPy path (the same operations in the same order, tests hold them bit
#: for bit) or, an :attr:`Kernel.interpretable` kernel, as its own Python function.
COMPILED_MIN_TRAJECTORIES = 2
#: Trajectories of the job in progress (:func:`job`); ``None``: no job declared.
_JOB: list[int | None] = [None]


def worth_loading() -> bool:
    """The kernels are worth numba's import here: no small :func:`job` is in progress, or
    numba is loaded in this process already; never while loading is deferred (:func:`defer`)."""
    if _DEFERRED[0]:
        return False
    n = _JOB[0]
    return n is None or n >= COMPILED_MIN_TRAJECTORIES or sys.modules.get("numba") is not None


@contextlib.contextmanager
def job(trajectories: int) -> Iterator[None]:
    """Within the block, a job of ``trajectories`` trajectories: below
    :data:`COMPILED_MIN_TRAJECTORIES` numba is not loaded for it (the same bits)."""
    saved = _JOB[0]
    _JOB[0] = int(trajectories)
    try:
        yield
    finally:
        _JOB[0] = saved


class Kernel:
    """A numba function compiled only by :func:`warm_up`, else loaded from the disk cache.

    Parameters
    ----------
    pyfunc : the Python function (numba-compatible, no Python objects).
    signatures : numba signature strings, e.g. ``"void(float64[:, ::1], int64)"``; calls must
        pass exactly these types (the caller converts).
    readonly : positions of the arguments passed as read-only arrays (e.g. a volume's voxels).
    interpretable : in a small :func:`job` without numba, :meth:`usable` is True and a call
        runs ``pyfunc`` itself in Python: the same IEEE operations in the same order, so the
        compiled bits (only +, -, *, /, sqrt, comparisons and stable sorts; fast enough for
        one trajectory). Its callers take :meth:`usable` instead of :meth:`ready`.
    """

    def __init__(
        self,
        pyfunc: Callable[..., Any],
        signatures: Sequence[str],
        *,
        readonly: Sequence[int] = (),
        interpretable: bool = False,
    ) -> None:
        self.pyfunc = pyfunc
        self.signatures = tuple(signatures)
        self.readonly = tuple(readonly)
        self.interpretable = interpretable
        self._dispatcher: Any = None
        self._ready: bool | None = None
        _KERNELS.append(self)

    @property
    def name(self) -> str:
        """The function's qualified name."""
        return f"{self.pyfunc.__module__}.{self.pyfunc.__qualname__}"

    def _dispatch(self) -> Any:
        if self._dispatcher is None:
            numba = _numba()
            assert numba is not None
            self._dispatcher = numba.njit(cache=True, nogil=True, error_model="numpy")(self.pyfunc)
        return self._dispatcher

    def ready(self, *, force: bool = False) -> bool:
        """True when every signature is loaded from the disk cache (never compiles); False
        without loading anything inside a small :func:`job` or while loading is deferred
        (:func:`defer`), unless ``force``."""
        if self._ready is None and not force and not worth_loading():
            return False
        if self._ready is None:
            with _NUMBA_LOCK:  # one load, also when a job and :func:`preload` ask at once
                if self._ready is None:
                    self._ready = available() and self._load()
        return self._ready

    def _arg_types(self) -> list[tuple[Any, ...]]:
        """Each signature as its tuple of argument types (read-only where asked)."""
        from numba.core import sigutils

        out = []
        for sig in self.signatures:
            args, _ = sigutils.normalize_signature(sig)
            args = tuple(
                a.copy(readonly=True) if i in self.readonly else a for i, a in enumerate(args)
            )
            out.append(args)
        return out

    def _load(self) -> bool:
        disp = self._dispatch()
        with _NUMBA_LOCK, cython_blas_alone():
            return self._load_overloads(disp)

    def _load_overloads(self, disp: Any) -> bool:
        for sig in self._arg_types():
            if sig in disp.overloads:
                continue
            cres = disp._cache.load_overload(sig, disp.targetctx)
            if cres is None:
                return False
            if not cres.objectmode:
                disp.targetctx.insert_user_function(cres.entry_point, cres.fndesc, [cres.library])
            disp.add_overload(cres)
        disp.disable_compile()
        return True

    def fixed_args(self, args: Sequence[Any]) -> tuple[Any, ...]:
        """``args`` as the signatures take them: read-only views where asked, copies of
        read-only arrays elsewhere (only inputs are ever read-only)."""
        fixed = []
        for i, arg in enumerate(args):
            if isinstance(arg, np.ndarray):
                if i in self.readonly and arg.flags.writeable:
                    arg = arg.view()
                    arg.flags.writeable = False
                elif i not in self.readonly and not arg.flags.writeable:
                    arg = arg.copy()
            fixed.append(arg)
        return tuple(fixed)

    def interpreted(self) -> bool:
        """A call runs ``pyfunc`` in Python: an :attr:`interpretable` kernel, not loaded, in a
        small :func:`job`, where numba is installed and not switched off (so the bits are
        those a loaded kernel gives; without numba every job takes the NumPy path)."""
        return (
            self.interpretable
            and self._ready is None
            and not worth_loading()
            and os.environ.get(NO_JIT_ENV, "") in ("", "0")
            and importlib.util.find_spec("numba") is not None
        )

    def usable(self) -> bool:
        """:meth:`ready`, or :meth:`interpreted`: a call gives the compiled kernel's bits."""
        return self.ready() or self.interpreted()

    def __call__(self, *args: Any) -> Any:
        """Run the compiled kernel (after :meth:`ready` returned True), or ``pyfunc`` itself
        where :meth:`interpreted`."""
        if self.ready():
            return self._dispatch()(*self.fixed_args(args))
        if self.interpreted():
            return self.pyfunc(*self.fixed_args(args))
        raise RuntimeError(f"kernel {self.name} is not compiled; run the warm-up")

    def compile(self) -> None:
        """Compile every signature and save it in the disk cache (the warm-up's work)."""
        disp = self._dispatch()
        with _NUMBA_LOCK:
            if not _BOUND[0]:
                _bind_helpers(_numba())
        disp._can_compile = True
        for sig in self._arg_types():
            disp.compile(sig)
        self._ready = None


def helper(pyfunc: Callable[..., Any]) -> Any:
    """A function the kernels call (compiled into them; plain Python until numba is loaded,
    then compiled and rebound by :func:`_bind_helpers` when a kernel is compiled)."""
    with _NUMBA_LOCK:
        numba = _NUMBA[0]
        if not _BOUND[0]:
            _HELPERS.append(pyfunc)
            return pyfunc
    if not numba:
        return pyfunc
    return numba.njit(nogil=True, error_model="numpy")(pyfunc)


@contextlib.contextmanager
def switched_off(kernels_: Sequence[Kernel]) -> Iterator[None]:
    """``kernels_`` switched off within the block: :meth:`Kernel.ready` is False and their
    callers take the NumPy path (tests and benchmarks compare the two in one process)."""
    saved = [k._ready for k in kernels_]
    try:
        for k in kernels_:
            k._ready = False
        yield
    finally:
        for k, ready in zip(kernels_, saved, strict=True):
            k._ready = ready


def kernels() -> tuple[Kernel, ...]:
    """Every kernel defined so far (import the modules that define them first)."""
    return tuple(_KERNELS)


def preload() -> None:
    """Load every kernel defined so far in a background thread (once per process), so the
    first job that needs them does not pay numba's first cache load (0.3-0.5 s of CPU); while
    loading is deferred (:func:`defer`), nothing until :func:`release`."""
    if not _DEFERRED[0]:
        release()


def release() -> threading.Thread | None:
    """Load every kernel defined so far in a background thread, deferred or not (the deferral
    ends once they are loaded). Returns the thread (None: loading had begun already)."""
    with _NUMBA_LOCK:
        if _PRELOADING:
            return None
        _PRELOADING.append(True)

    def load() -> None:
        try:
            for k in kernels():
                k.ready(force=True)
        finally:
            _DEFERRED[0] = False  # kernels defined later load on first use, as before

    thread = threading.Thread(target=load, name="ctdrill-jit-preload", daemon=True)
    thread.start()
    return thread


def defer() -> None:
    """Defer numba's import and the kernels' load to :func:`release` (a window draws first):
    meanwhile no caller loads numba, and a kernel not loaded gives its bits without it, as in
    a small :func:`job`. Nothing to defer once loading has begun."""
    with _NUMBA_LOCK:
        if not _PRELOADING and _NUMBA[0] is None:
            _DEFERRED[0] = True


def deferred() -> bool:
    """Loading is deferred (:func:`defer`) and not finished yet."""
    return _DEFERRED[0]


def stop_deferring() -> None:
    """End a deferral without loading anything (kernels load on first use again)."""
    _DEFERRED[0] = False


_PRELOADING: list[bool] = []
_DEFERRED: list[bool] = [False]  # :func:`defer` until :func:`release` has loaded them


def warm_up(kernels_: Sequence[Kernel] | None = None) -> list[str]:
    """Compile (or load) ``kernels_`` (default: all defined) into the disk cache.

    Returns the names compiled; raises RuntimeError when numba is unavailable.
    """
    if not available():
        raise RuntimeError(
            f"numba is not available (not installed, or {NO_JIT_ENV} is set); nothing to warm up"
        )
    out = []
    for k in _KERNELS if kernels_ is None else kernels_:
        if not k.ready():
            k._ready = None
            k.compile()
        if not k.ready():
            raise RuntimeError(f"kernel {k.name}: compiled but not found in the cache")
        out.append(k.name)
    return out


def cpus() -> int:
    """CPUs this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def row_spans(rows: np.ndarray, parts: int | None = None) -> list[tuple[int, int]]:
    """``rows`` (indices) as half-open spans of consecutive rows, each run cut in up to
    ``parts`` (default: the CPUs, at most 8) near-equal pieces for worker threads."""
    parts = max(1, min(8, cpus())) if parts is None else parts
    rows = np.asarray(rows, dtype=np.int64)
    if rows.size == 1:  # the single trajectory: no sorting, no threads
        return [(int(rows[0]), int(rows[0]) + 1)]
    if rows.size == 0:
        return []
    steps = np.diff(rows)
    # consecutive already (the usual call: every row of a batch): no sort needed
    uniq = rows if bool(np.all(steps == 1)) else np.unique(rows)
    breaks = np.flatnonzero(np.diff(uniq) != 1) + 1
    out: list[tuple[int, int]] = []
    for run in np.split(uniq, breaks):
        lo, hi = int(run[0]), int(run[-1]) + 1
        edges = np.linspace(lo, hi, min(parts, hi - lo) + 1).round().astype(np.int64)
        out += [(int(a), int(b)) for a, b in itertools.pairwise(edges) if b > a]
    return out


def run_spans(kernel: Kernel, spans: Sequence[tuple[int, int]], *args: Any) -> None:
    """``kernel(*args, lo, hi)`` for every span, on a thread per span (the kernels drop the
    GIL; each span writes only its own rows)."""
    if len(spans) <= 1:
        for lo, hi in spans:
            kernel(*args, lo, hi)
        return
    pool = _pool()
    # the calling thread takes the first span itself: one thread fewer to wake
    futures = [pool.submit(kernel, *args, lo, hi) for lo, hi in spans[1:]]
    kernel(*args, *spans[0])
    for fut in futures:
        fut.result()


_POOL: ThreadPoolExecutor | None = None


def _pool() -> ThreadPoolExecutor:
    """One pool of worker threads for the process (starting threads per call cost ~2 ms
    each on this VM), created on first use."""
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max(1, min(8, cpus()) - 1), thread_name_prefix="ctdrill-jit")
    return _POOL

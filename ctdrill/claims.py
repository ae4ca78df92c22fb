"""Rows of a compiled kernel claimed one by one by threads walking spans from both ends.

A kernel that computes independent rows of unequal cost (the bone walls' envelope rays:
:mod:`~ctdrill.imaging.sampling.envelope_kernel`) split in static halves leaves one thread
idle while the other finishes; here each row is claimed by whichever thread reaches it first.
:func:`start_claimed` also lets a caller start the rows on the worker threads, do other work
(``plan_path`` computes the drill's path meanwhile), and then lend its own thread to the rows
still free (:meth:`Claimed.join`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ctdrill import jit
from ctdrill.jit import Kernel


class Claimed:
    """Rows ``[0, n)`` of a *claiming* kernel being computed on worker threads
    (:func:`start_claimed`); :meth:`join` lends the calling thread and returns when every row
    is done.

    A claiming kernel's last four arguments are ``taken`` (uint8, one a row: 0 free, 1 taken,
    2 done), ``lo``, ``hi`` and ``backward``: it walks its span up from ``lo`` (or down from
    ``hi - 1``), marks each free row taken, computes it and marks it done, and stops at the
    first row another thread took. Each span is walked from both ends by two threads, so they
    meet wherever the rows' costs put the middle (static halves of rays of unequal lengths
    leave one thread idle). Two threads that take the same row at once both compute it and
    write the same values.
    """

    def __init__(self, kernel: Kernel, n: int, args: tuple[Any, ...], *, min_rows: int = 2) -> None:
        self._kernel = kernel
        self._args = args
        self.taken = np.zeros(n, dtype=np.uint8)
        # jit.cpus looked up at the call: a caller (a benchmark's one-thread row) may set it
        threads = max(1, min(8, jit.cpus())) if n >= min_rows else 1
        parts = min(max(1, (threads + 1) // 2), n)
        self._spans = [(n * i // parts, n * (i + 1) // parts) for i in range(parts)]
        self._futures: list[Any] = []
        if threads > 1 and self._spans:
            pool, run, taken = jit._pool(), kernel._dispatch(), self.taken

            def walk(lo: int, hi: int, backward: bool) -> None:
                run(*args, taken, lo, hi, backward)

            ends = [(lo, hi, False) for lo, hi in self._spans]
            ends += [(lo, hi, True) for lo, hi in self._spans[1:]]
            self._futures = [pool.submit(walk, *end) for end in ends]

    def join(self) -> None:
        """Walk the first span down from its end on this thread (all of it when no worker
        was started), then wait for the rows still being computed."""
        if self._spans:
            lo, hi = self._spans[0]
            self._kernel._dispatch()(*self._args, self.taken, lo, hi, bool(self._futures))
        if self._futures and not bool(np.all(self.taken == 2)):
            for fut in self._futures:
                fut.result()
        self._futures = []

    def cancel(self) -> None:
        """Let no thread take another row (the rows already taken finish on their own)."""
        self.taken[:] = np.maximum(self.taken, 1)
        self._futures = []


def start_claimed(kernel: Kernel, n: int, *args: Any, min_rows: int = 2) -> Claimed:
    """Start rows ``[0, n)`` of the claiming ``kernel`` (see :class:`Claimed`) on the worker
    threads (none when ``n < min_rows`` or one CPU: then all on the thread that joins), and
    return at once: the caller does other work and then calls :meth:`Claimed.join`."""
    if not kernel.ready():
        raise RuntimeError(f"kernel {kernel.name} is not compiled; run the warm-up")
    fixed = kernel.fixed_args(args)
    return Claimed(kernel, n, fixed, min_rows=min_rows)


def run_claimed(kernel: Kernel, n: int, *args: Any, min_rows: int = 2) -> None:
    """Rows ``[0, n)`` of the claiming ``kernel`` on the worker threads and this one."""
    start_claimed(kernel, n, *args, min_rows=min_rows).join()

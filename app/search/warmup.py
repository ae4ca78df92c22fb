"""Compile the search kernels into numba's disk cache: ``python -m ctdrill.app.search.warmup``.

Run once after installing (``ctdrill warmup``, ``make warmup``; CI runs it before the tests).
Without it every call takes the NumPy per-trajectory path (same answers, ~30x slower; ``ctdrill
suggest`` says so); with it each process
loads the kernels from the cache in milliseconds and nothing is ever compiled in a user's path.
"""

from __future__ import annotations

import sys
import time

from ctdrill import jit


def search_kernels() -> tuple[jit.Kernel, ...]:
    """The kernels :func:`ctdrill.engine.batch.evaluate_batch`, the landmarks' clearances to
    a drill or an implant body, the bone walls (and the arch's buccal side), suggest's bone surfaces
    and shells use."""
    from ctdrill.app.search.shell_kernel import SHELL_KERNEL
    from ctdrill.imaging.plan.clearance_kernel import CLEARANCE_KERNEL
    from ctdrill.imaging.plan.segments_kernel import SEGMENTS_KERNEL
    from ctdrill.imaging.sampling.arch_kernel import ARCH_KERNEL
    from ctdrill.imaging.sampling.envelope_kernel import ENVELOPE_KERNEL
    from ctdrill.imaging.sampling.lip_batch import LIP_KERNEL
    from ctdrill.imaging.sampling.points_kernel import POINTS_KERNEL
    from ctdrill.imaging.sampling.surface_kernel import SURFACE_KERNEL
    from ctdrill.model.profile_batch import PROFILE_KERNEL

    return (
        LIP_KERNEL,
        PROFILE_KERNEL,
        CLEARANCE_KERNEL,
        SEGMENTS_KERNEL,
        ENVELOPE_KERNEL,
        SHELL_KERNEL,
        SURFACE_KERNEL,
        POINTS_KERNEL,
        ARCH_KERNEL,
    )


def kernels_ready() -> bool:
    """True when every search kernel loads from the disk cache (the fast path; never compiles)."""
    return all(k.ready() for k in search_kernels())


#: What suggest prints when it must take the NumPy path.
SLOW_PATH_NOTE = (
    "note: the compiled search kernels are not in the cache here, so the search took the NumPy "
    "path (same answers, about 30 times slower); run 'ctdrill warmup' once to compile them"
)


def main(argv: list[str] | None = None) -> int:
    """Compile (or load) every search kernel; print what was done. Exit 2 without numba."""
    t0 = time.perf_counter()
    try:
        names = jit.warm_up(search_kernels())
    except RuntimeError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for name in names:
        print(f"ready: {name}")
    print(f"search kernels ready in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

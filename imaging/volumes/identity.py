"""A file volume's identity: ``sha256:`` + the SHA-256 of its shape, LPS affine and HU voxels.

:func:`content_uid` hashes a loaded volume. :class:`VoxelDigest` gives the same value while the
voxels are read: a reader whose stored bytes are the HU bytes :func:`content_uid` hashes
(int16, unscaled, C order (k, j, i)) feeds each chunk as it lands in the array, and a worker
thread hashes it while the next chunk is read or inflated (``hashlib`` releases the
interpreter lock on large buffers, as ``readinto`` and zlib do), so the voxels are not read a
second time after the load and the hash costs little more than the read. :class:`HuStream`
makes int16 stored voxels HU as they land (an integer ``scl_slope``/``scl_inter``, big-endian
bytes swapped), keeps their range and feeds the digest, so a scaled or big-endian file is not
passed over again either. Same voxels and geometry give the same identity whichever file
format, byte order, scaling or compression held them; one changed voxel gives another.
"""

from __future__ import annotations

import hashlib
import os
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from types import TracebackType
from typing import Any

import numpy as np

#: Prefix of a file volume's content identity.
CONTENT_UID_PREFIX = "sha256:"
#: The stored dtype whose bytes are the hashed HU bytes (``content_uid`` of int16 voxels).
STREAMED_DTYPE = np.dtype("<i2")
#: Voxel bytes at or below which :class:`VoxelDigest` hashes in the caller's thread.
INLINE_HASH_BYTES = 4 << 20
#: Chunks the worker may lag behind the reader before the reader waits for it.
MAX_LAG_CHUNKS = 2
_INT16 = np.iinfo(np.int16)


def content_hasher(shape: tuple[int, ...], dtype: np.dtype, affine_lps: np.ndarray) -> Any:
    """SHA-256 over the identity's header: ``b"ctdrill-volume/1"``, the shape and dtype
    (text) and the affine (float64, little endian); the voxels follow."""
    h = hashlib.sha256(b"ctdrill-volume/1\0")
    h.update(repr(tuple(int(n) for n in shape)).encode() + b"\0" + str(dtype).encode())
    h.update(np.ascontiguousarray(affine_lps, dtype="<f8").tobytes())
    return h


def content_uid(hu: np.ndarray, affine_lps: np.ndarray) -> str:
    """``sha256:`` + the SHA-256 of ``b"ctdrill-volume/1"``, the shape (text), the affine
    (float64, little endian) and the voxels (C order, little endian)."""
    h = content_hasher(hu.shape, hu.dtype, affine_lps)
    h.update(
        np.ascontiguousarray(hu, dtype=hu.dtype.newbyteorder("<")).reshape(-1).view(np.uint8).data
    )
    return CONTENT_UID_PREFIX + h.hexdigest()


def core_to_spare() -> bool:
    """True when the machine has a core to spare for hashing beside the read: the 1-minute
    load average (this process's reading thread included) is under the usable cores less
    one half."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except OSError:  # pragma: no cover - no load average
        return False
    return cores >= 2 and load < cores - 0.5


class VoxelDigest:
    """:func:`content_uid` of int16 voxels computed chunk by chunk as a reader fills them.

    Use as a context manager around the read; :meth:`feed` each filled span of the array in
    order (views, not copies: the array must not change afterwards); :meth:`uid` after the
    last. Where a chunk is hashed (``threaded``):

    - in a worker thread, while the caller reads on, when the voxels are more than
      :data:`INLINE_HASH_BYTES` and a core is to spare (:func:`core_to_spare`); the reader
      waits when the worker lags :data:`MAX_LAG_CHUNKS` behind;
    - else in the caller's thread, right after the chunk was read, while it is still in the
      cache: on a busy machine the worker only adds the cost of moving every chunk between
      cores (about a quarter more CPU for a 150 MiB CT: ``bench/bench_volumes.py``), and a
      small volume arrives in one chunk, with nothing to overlap.

    Parameters
    ----------
    shape, affine_lps : the volume's (k, j, i) shape and (4, 4) affine, hashed first.
    threaded : force the worker thread (True) or the caller's thread (False); None decides
        as above.
    """

    def __init__(
        self, shape: tuple[int, ...], affine_lps: np.ndarray, *, threaded: bool | None = None
    ) -> None:
        self._hash = content_hasher(shape, STREAMED_DTYPE.newbyteorder("="), affine_lps)
        self._pool: ThreadPoolExecutor | None = None
        self._pending: deque[Future[None]] = deque()
        self._expected = int(np.prod(shape, dtype=np.int64)) * STREAMED_DTYPE.itemsize
        self._fed = 0
        if threaded is None:
            threaded = self._expected > INLINE_HASH_BYTES and core_to_spare()
        self.threaded = threaded

    def feed(self, chunk: memoryview) -> None:
        """Hash ``chunk`` (the next bytes of the voxels)."""
        self._fed += chunk.nbytes
        if not self.threaded:
            self._hash.update(chunk)
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ctdrill-hash")
        self._pending.append(self._pool.submit(self._hash.update, chunk))
        while len(self._pending) > MAX_LAG_CHUNKS:
            self._pending.popleft().result()

    def settle(self) -> None:
        """Wait until every chunk fed so far is hashed."""
        while self._pending:
            self._pending.popleft().result()

    def uid(self) -> str:
        """The identity, once every voxel byte was fed (ValueError otherwise)."""
        self.settle()
        if self._fed != self._expected:
            raise ValueError(f"fed {self._fed} voxel bytes of {self._expected}")
        return CONTENT_UID_PREFIX + self._hash.hexdigest()

    def __enter__(self) -> VoxelDigest:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)


def integer_scale(scale: tuple[float, float] | None) -> tuple[int, int] | None:
    """``scale`` (slope, intercept) as integers when both are whole numbers, else None (no
    scale, or a fraction: the HU are then float32, not for :class:`HuStream`)."""
    if scale is None:
        return None
    slope, inter = (float(v) for v in scale)
    if not (slope.is_integer() and inter.is_integer()):
        return None
    return int(slope), int(inter)


@dataclass(frozen=True, eq=False)
class StreamedHu:
    """What :class:`HuStream` made: ``hu`` (k, j, i) int16 native, its identity ``uid``, its
    ``value_range`` (min, max) and its ``sample`` (every ``sample_step``-th value, or None)."""

    hu: np.ndarray
    uid: str
    value_range: tuple[int, int]
    sample: np.ndarray | None


class HuStream:
    """int16 stored voxels made HU, measured and hashed chunk by chunk as a reader fills them.

    :meth:`feed` is the reader's ``on_chunk``: each filled byte span of ``data`` (stored
    int16, either byte order) is taken whole voxels at a time; big-endian voxels are swapped
    in place, an integer ``scale`` (slope, intercept) is applied in place, the range kept and
    the voxels fed to a :class:`VoxelDigest`; with ``sample_step`` every that many-th HU value
    (flat C order, from the first) is kept too, taken while the span is in the cache. The
    first span whose HU would leave int16 stops the scaling and hashing (the HU are then
    float32, made after the read): :meth:`finish` undoes what was scaled and returns None, so
    the caller applies the scale as for any other file.

    Parameters
    ----------
    data : (k, j, i) int16 array the reader fills (C order, either byte order).
    affine_lps : (4, 4) the volume's affine, hashed into the identity.
    scale : integer (slope, intercept), or None.
    threaded : as :class:`VoxelDigest`.
    sample_step : keep ``hu.reshape(-1)[::sample_step]`` (0: none).
    """

    def __init__(
        self,
        data: np.ndarray,
        affine_lps: np.ndarray,
        scale: tuple[int, int] | None,
        *,
        threaded: bool | None = None,
        sample_step: int = 0,
    ) -> None:
        if data.dtype.kind != "i" or data.dtype.itemsize != 2 or not data.flags.c_contiguous:
            raise ValueError("HuStream needs a C-contiguous int16 array")
        self._shape = data.shape
        self._flat = data.reshape(-1).view(np.int16)  # native order once swapped
        self._swap = not data.dtype.isnative
        self._scale = scale
        self._digest = VoxelDigest(data.shape, affine_lps, threaded=threaded)
        self._bytes = 0
        self._done = 0  # voxels swapped (and scaled and hashed while not stopped)
        self._scaled = 0  # voxels scaled and hashed
        self._lo = int(_INT16.max)
        self._hi = int(_INT16.min)
        self._stopped = False
        self._step = int(sample_step)
        self._samples: list[np.ndarray] = []

    def feed(self, chunk: memoryview) -> None:
        """Take the whole voxels of the next filled span (``chunk``'s bytes count)."""
        self._bytes += chunk.nbytes
        end = self._bytes // 2
        if end <= self._done:
            return
        start, part = self._done, self._flat[self._done : end]
        self._done = end
        if self._swap:
            part.byteswap(inplace=True)
        if self._stopped:
            return
        lo, hi = int(part.min()), int(part.max())
        if self._scale is not None:
            slope, inter = self._scale
            lo, hi = sorted((lo * slope + inter, hi * slope + inter))
            if lo < _INT16.min or hi > _INT16.max:
                self._stopped = True
                return
            if slope == 1 and _INT16.min <= inter <= _INT16.max:
                np.add(part, np.int16(inter), out=part)  # no wrap: the range fits
            else:
                part[...] = part.astype(np.int64) * slope + inter
        self._lo, self._hi = min(self._lo, lo), max(self._hi, hi)
        self._scaled = end
        self._digest.feed(part.data)
        if self._step:
            self._samples.append(part[-start % self._step :: self._step].copy())

    def finish(self) -> StreamedHu | None:
        """The HU, their identity, range and sample once every byte was fed; None when the
        HU leave int16 (the stored values are then back in the array, in native order, for
        the caller to scale)."""
        data = self._flat.reshape(self._shape)
        if self._stopped:
            self._digest.settle()  # the worker reads no voxel the undo writes
            if self._scale is not None and self._scaled:
                slope, inter = self._scale
                done = self._flat[: self._scaled]
                done[...] = (done.astype(np.int64) - inter) // slope
            return None
        return StreamedHu(
            hu=data,
            uid=self._digest.uid(),
            value_range=(self._lo, self._hi),
            sample=np.concatenate(self._samples) if self._step else None,
        )

    def __enter__(self) -> HuStream:
        self._digest.__enter__()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._digest.__exit__(exc_type, exc, tb)

"""A file volume's identity: ``sha256:`` + the SHA-256 of its shape, LPS affine and HU voxels.

:func:`content_uid` hashes a loaded volume. :class:`VoxelDigest` gives the same value while the
voxels are read: a reader whose stored bytes are the HU bytes :func:`content_uid` hashes
(int16, little endian, unscaled, C order (k, j, i)) feeds each chunk as it lands in the array,
and a worker thread hashes it while the next chunk is read or inflated (``hashlib`` releases the
interpreter lock on large buffers, as ``readinto`` and zlib do), so the voxels are not read a
second time after the load and the hash costs little more than the read. Same voxels and
geometry give the same identity whichever file format or compression held them; one changed
voxel gives another.
"""

from __future__ import annotations

import hashlib
from concurrent.futures import Future, ThreadPoolExecutor
from types import TracebackType
from typing import Any

import numpy as np

#: Prefix of a file volume's content identity.
CONTENT_UID_PREFIX = "sha256:"
#: The stored dtype whose bytes are the hashed HU bytes (``content_uid`` of int16 voxels).
STREAMED_DTYPE = np.dtype("<i2")


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


class VoxelDigest:
    """:func:`content_uid` of int16 voxels computed chunk by chunk as a reader fills them.

    Use as a context manager around the read; :meth:`feed` each filled span of the array in
    order (views, not copies: the array must not change afterwards); :meth:`uid` after the
    last. A worker thread hashes while the caller reads on.
    """

    def __init__(self, shape: tuple[int, ...], affine_lps: np.ndarray) -> None:
        self._hash = content_hasher(shape, STREAMED_DTYPE.newbyteorder("="), affine_lps)
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ctdrill-hash")
        self._last: Future[None] | None = None
        self._expected = int(np.prod(shape, dtype=np.int64)) * STREAMED_DTYPE.itemsize
        self._fed = 0

    def feed(self, chunk: memoryview) -> None:
        """Hash ``chunk`` (the next bytes of the voxels) in the worker thread."""
        self._fed += len(chunk)
        self._last = self._pool.submit(self._hash.update, chunk)

    def uid(self) -> str:
        """The identity, once every voxel byte was fed (ValueError otherwise)."""
        if self._last is not None:
            self._last.result()
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
        self._pool.shutdown(wait=True)

"""Fault injection: byte mutations of files and structure mutations of JSON documents.

The same mutation functions serve the hypothesis fuzz tests (which draw their arguments) and the
robustness report (which draws them from a seeded ``random.Random`` and counts outcomes).
"""

from __future__ import annotations

import copy
import math
import random
import resource
import struct
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pydicom

#: Byte-level fault kinds.
BYTE_OPS: tuple[str, ...] = ("flip", "insert", "delete", "truncate", "overwrite", "length")
#: JSON structure fault kinds.
JSON_OPS: tuple[str, ...] = ("delete", "replace", "wrap", "stringify", "duplicate", "text")

#: Values a JSON field may be replaced with (types and magnitudes parsers get wrong).
NASTY_VALUES: tuple[Any, ...] = (
    None,
    True,
    0,
    -1,
    2**63,
    10**400,
    1e308,
    -1e308,
    5e-324,
    math.nan,
    math.inf,
    -math.inf,
    "",
    "nan",
    "1.5",
    "\u0000",
    "x" * 10_000,
    [],
    [1, 2],
    [1.0, 2.0, 3.0, 4.0],
    [[1, 2, 3]],
    {},
    {"a": 1},
    [None, None, None],
)


@dataclass(frozen=True)
class ByteMutation:
    """One byte-level fault.

    Attributes
    ----------
    op : one of :data:`BYTE_OPS`. ``length`` overwrites the length field of a data element.
    where : position as a fraction 0..1 of the file (or the element index for ``length``).
    size : bytes affected (inserted, deleted, overwritten) or the bit for ``flip``.
    payload : bytes inserted / written, or the new length for ``length`` (little endian).
    """

    op: str
    where: float
    size: int
    payload: bytes


def element_offsets(data: bytes) -> list[tuple[int, bool]]:
    """Offsets of the top-level data elements of an explicit-VR LE file, with 'long length'.

    Returns
    -------
    list of (offset of the tag, True when the VR has a 4-byte length field).
    """
    import io

    ds = pydicom.dcmread(io.BytesIO(data), force=True)
    out = []
    for elem in ds:
        tag = struct.pack("<HH", elem.tag.group, elem.tag.element)
        at = data.find(tag, 132)
        if at >= 0:
            out.append((at, data[at + 4 : at + 6] in (b"OB", b"OW", b"SQ", b"UN", b"UT", b"OF")))
    return out


def apply_bytes(data: bytes, mutation: ByteMutation, offsets: list[tuple[int, bool]]) -> bytes:
    """Return ``data`` with ``mutation`` applied (pure)."""
    n = len(data)
    pos = min(int(mutation.where * n), max(n - 1, 0))
    buf = bytearray(data)
    if mutation.op == "flip" and n:
        buf[pos] ^= 1 << (mutation.size % 8)
    elif mutation.op == "insert":
        buf[pos:pos] = mutation.payload
    elif mutation.op == "delete":
        del buf[pos : pos + mutation.size]
    elif mutation.op == "truncate":
        del buf[pos:]
    elif mutation.op == "overwrite":
        buf[pos : pos + len(mutation.payload)] = mutation.payload
    elif mutation.op == "length" and offsets:
        at, long = offsets[int(mutation.where * len(offsets)) % len(offsets)]
        value = int.from_bytes(mutation.payload[:4].ljust(4, b"\x00"), "little")
        if long:
            buf[at + 8 : at + 12] = struct.pack("<I", value)
        else:
            buf[at + 6 : at + 8] = struct.pack("<H", value & 0xFFFF)
    return bytes(buf)


def random_byte_mutation(rng: random.Random) -> ByteMutation:
    """A byte mutation drawn from ``rng`` (the report's campaign)."""
    op = rng.choice(BYTE_OPS)
    size = rng.choice([1, 2, 4, 8, 64, 1024])
    payload = rng.choice(
        [
            rng.randbytes(size),
            b"\xff" * size,
            b"\x00" * size,
            struct.pack("<I", rng.choice([0, 1, 0xFFFFFFFF, 0xFFFFFFF0, 0x7FFFFFFF])),
        ]
    )
    return ByteMutation(op, rng.random(), size, payload)


# ----------------------------------------------------------------------------- JSON


def json_paths(doc: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every path (tuple of keys / indices) into ``doc``, the root () included."""
    paths: list[tuple[Any, ...]] = [prefix]
    if isinstance(doc, dict):
        for key, value in doc.items():
            paths += json_paths(value, (*prefix, key))
    elif isinstance(doc, list):
        for i, value in enumerate(doc):
            paths += json_paths(value, (*prefix, i))
    return paths


def _get(doc: Any, path: tuple[Any, ...]) -> Any:
    for key in path:
        doc = doc[key]
    return doc


def apply_json(doc: Any, op: str, path: tuple[Any, ...], value: Any) -> Any:
    """Return a mutated deep copy of ``doc``: ``op`` at ``path`` (``value`` for replace)."""
    out = copy.deepcopy(doc)
    if not path:
        return value if op == "replace" else [out] if op == "wrap" else out
    parent = _get(out, path[:-1])
    key = path[-1]
    if op == "delete":
        del parent[key]
    elif op == "replace":
        parent[key] = value
    elif op == "wrap":
        parent[key] = [parent[key]]
    elif op == "stringify":
        parent[key] = str(parent[key])
    elif op == "duplicate" and isinstance(parent, list):
        parent.insert(key, copy.deepcopy(parent[key]))
    elif op == "duplicate":
        parent[key] = [parent[key], parent[key]]
    return out


def dump_json(doc: Any) -> str:
    """JSON text as a careless writer makes it (NaN/Infinity tokens allowed)."""
    import json

    return json.dumps(doc, allow_nan=True)


def mutate_text(text: str, where: float, insert: str) -> str:
    """Cut ``text`` at fraction ``where`` and append ``insert`` (truncation / garbage)."""
    pos = int(where * len(text))
    return text[:pos] + insert


def random_json_mutation(doc: Any, rng: random.Random) -> str:
    """A mutated JSON text drawn from ``rng`` (the report's campaign)."""
    op = rng.choice(JSON_OPS)
    if op == "text":
        return mutate_text(dump_json(doc), rng.random(), rng.choice(["", "}", "]]", "\x00", "ü"]))
    path = rng.choice(json_paths(doc))
    return dump_json(apply_json(doc, op, path, rng.choice(NASTY_VALUES)))


# ----------------------------------------------------------------------------- limits


def address_space_bytes() -> int:
    """Current virtual size of this process, bytes (``VmSize`` of /proc/self/status)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024
    raise RuntimeError("no VmSize in /proc/self/status")


@contextmanager
def bounded_memory(headroom_bytes: int = 1 << 30) -> Iterator[None]:
    """Lower the soft ``RLIMIT_AS`` to current size + headroom for the block, then restore it.

    An unbounded allocation inside the block raises ``MemoryError`` instead of taking the host.
    """
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = address_space_bytes() + headroom_bytes
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def finite_numbers(obj: Any) -> bool:
    """True if every number in a (nested) dataclass / mapping / sequence / array is finite."""
    if isinstance(obj, bool | str) or obj is None:
        return True
    if isinstance(obj, int | float):
        try:
            return math.isfinite(obj)
        except OverflowError:  # an int beyond float range
            return False
    if isinstance(obj, np.ndarray):
        return obj.dtype.kind not in "fc" or bool(np.isfinite(obj).all())
    if isinstance(obj, dict):
        return all(finite_numbers(v) for v in obj.values())
    if isinstance(obj, list | tuple):
        return all(finite_numbers(v) for v in obj)
    if hasattr(obj, "__dataclass_fields__"):
        return all(finite_numbers(getattr(obj, f)) for f in obj.__dataclass_fields__)
    return True

"""Hostile DICOM cases of issue 15: sequence recursion and lying RLE lengths.

Each builder writes a series (the base 10 x 12 x 8) with one hostile file and returns the
acceptable outcomes, as the builders of :mod:`tests.robustness.corpus_faults`.
"""

from __future__ import annotations

import struct
from pathlib import Path

from tests.robustness.corpus_base import (
    COLS,
    REFUSE,
    ROWS,
    SLICES,
    Expect,
    base_slices,
    load,
    write_all,
)

DIMS = (COLS, ROWS, SLICES)
#: Levels of nesting: 1200 x 36 bytes = 43 KB, past Python's default recursion limit.
NESTED_LEVELS = 1200
#: A length that no 1 kB fragment can hold.
LYING_LENGTH = 0xFFFFFFF0


def nested_undefined_sequences(levels: int, tag: tuple[int, int] = (0x0040, 0xA730)) -> bytes:
    """``levels`` sequences of undefined length, each in an item of undefined length of the
    one before (explicit VR little endian): 36 bytes per level, every one closed properly."""
    group, elem = tag
    opening = struct.pack("<HH2sHI", group, elem, b"SQ", 0, 0xFFFFFFFF)
    opening += struct.pack("<HHI", 0xFFFE, 0xE000, 0xFFFFFFFF)
    closing = struct.pack("<HHI", 0xFFFE, 0xE00D, 0) + struct.pack("<HHI", 0xFFFE, 0xE0DD, 0)
    return opening * levels + closing * levels


def _insert_before_pixels(path: Path, blob: bytes) -> None:
    data = bytearray(path.read_bytes())
    at = data.rfind(b"\xe0\x7f\x10\x00")
    assert at > 0, path
    data[at:at] = blob
    path.write_bytes(bytes(data))


def _nested_undefined(folder: Path) -> tuple[Expect, ...]:
    """A middle slice carries 1200 nested undefined-length sequences before its pixels.

    The file is valid DICOM and its image is right: the loader must read it (the fast header
    reader skipped sequences recursively: RecursionError, a traceback in inspect, export,
    rehearse and the GUI).
    """
    paths = write_all(base_slices(series="nested-undefined"), folder)
    _insert_before_pixels(paths[SLICES // 2], nested_undefined_sequences(NESTED_LEVELS))
    return (load(dims=DIMS),)


def _rle_series(folder: Path, series: str) -> list[Path]:
    from pydicom.uid import RLELossless

    slices = base_slices(series=series)
    for ds in slices:
        ds.compress(RLELossless, ds.pixel_array.copy(), generate_instance_uid=False)
    return write_all(slices, folder)


def _encapsulated_items(path: Path) -> tuple[bytearray, int, int]:
    """The file's bytes, the offset of the basic offset table item and of the first fragment."""
    data = bytearray(path.read_bytes())
    at = data.rfind(b"\xe0\x7f\x10\x00")
    table = at + 12  # tag, "OB", 2 reserved bytes, undefined length
    assert data[table : table + 4] == b"\xfe\xff\x00\xe0", path
    (table_len,) = struct.unpack_from("<I", data, table + 4)
    fragment = table + 8 + table_len
    assert data[fragment : fragment + 4] == b"\xfe\xff\x00\xe0", path
    return data, table, fragment


def _rle_offset_table_bomb(folder: Path) -> tuple[Expect, ...]:
    """One slice's basic offset table declares 0xFFFFFFF0 bytes (pydicom: struct.error)."""
    path = _rle_series(folder, "rle-table-bomb")[SLICES // 2]
    data, table, _ = _encapsulated_items(path)
    struct.pack_into("<I", data, table + 4, LYING_LENGTH)
    path.write_bytes(bytes(data))
    return (REFUSE,)


def _rle_fragment_bomb(folder: Path) -> tuple[Expect, ...]:
    """One slice's fragment declares 0xFFFFFFF0 bytes (decoded from what was there)."""
    path = _rle_series(folder, "rle-fragment-bomb")[SLICES // 2]
    data, _, fragment = _encapsulated_items(path)
    struct.pack_into("<I", data, fragment + 4, LYING_LENGTH)
    path.write_bytes(bytes(data))
    return (REFUSE,)


def _rle_segment_bomb(folder: Path) -> tuple[Expect, ...]:
    """One slice's RLE header declares 0xFFFFFFF0 segments, another a segment offset of
    0xFFFFFFF0 bytes (the first loaded silently; the second failed in a two-line message)."""
    paths = _rle_series(folder, "rle-segment-bomb")
    for path, field in ((paths[2], 0), (paths[5], 2)):
        data, _, fragment = _encapsulated_items(path)
        struct.pack_into("<I", data, fragment + 8 + 4 * field, LYING_LENGTH)
        path.write_bytes(bytes(data))
    return (REFUSE,)

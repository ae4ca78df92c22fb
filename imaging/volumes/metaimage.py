"""MetaImage volumes (``.mha``; ``.mhd`` with its data file), read by a small bounded reader.

Why not SimpleITK: it is a 90 MB dependency for a format of a dozen text fields and one raw or
zlib block, it allocates what a header declares and it cannot hold a sheared grid; this reader
checks every field, bounds every size, and is measured against SimpleITK in ``bench/``
(``make bench``: docs/benchmarks.md) and in the tests (voxels identical, every voxel corner
within 1e-6 mm).

Header fields (``Key = Value`` lines up to ``ElementDataFile``): ``NDims`` 3, ``DimSize``
(fastest axis first), ``ElementType`` (``MET_UCHAR`` ... ``MET_DOUBLE``),
``ElementNumberOfChannels`` 1, ``BinaryData`` True, ``BinaryDataByteOrderMSB`` /
``ElementByteOrderMSB``, ``CompressedData`` (zlib), ``HeaderSize`` (bytes skipped in a data file,
-1: the data end it), ``ElementDataFile`` (``LOCAL`` or one file beside the header).

Geometry, LPS as ITK writes it: ``ElementSpacing`` (required), ``Offset`` (or ``Origin`` /
``Position``; required: the position of voxel 0), ``TransformMatrix`` (or ``Rotation`` /
``Orientation``; identity when absent, as the format defines) stored column by column: its first
three numbers are the direction of the fastest axis. The directions must be unit, perpendicular
vectors (:func:`.grid.check_direction_cosines`). ``AnatomicalOrientation`` is a label ITK does
not use for geometry, and neither does this reader. Two names of one field (``Offset`` and
``Origin``, :data:`ALIASES`) with different values are refused, and ITK must read the same grid
from the header (:mod:`.itk_header`).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ctdrill.imaging.volumes.bounded import (
    MAX_HEADER_BYTES,
    allocate,
    check_available,
    declared_bytes,
    fill_array,
    read_text_header,
)
from ctdrill.imaging.volumes.grid import check_direction_cosines, check_grid
from ctdrill.imaging.volumes.itk_header import check_itk_agrees
from ctdrill.imaging.volumes.types import VolumeData, native
from ctdrill.safeio import open_regular, regular_file_size

_TYPES = {
    "MET_CHAR": "i1",
    "MET_UCHAR": "u1",
    "MET_SHORT": "i2",
    "MET_USHORT": "u2",
    "MET_INT": "i4",
    "MET_UINT": "u4",
    "MET_LONG": "i4",
    "MET_ULONG": "u4",
    "MET_LONG_LONG": "i8",
    "MET_ULONG_LONG": "u8",
    "MET_FLOAT": "f4",
    "MET_DOUBLE": "f8",
}
_LINE = re.compile(r"^\s*([A-Za-z][A-Za-z0-9_]*)\s*=\s*(.*?)\s*$")
_KEYS = ("ObjectType", "NDims", "ObjectSubType", "Comment", "DimSize", "ElementType")
#: Names MetaIO accepts for one field. Two of them with different values are refused: readers
#: differ on which counts (ITK takes ``Origin`` over ``Offset``; ctdrill took ``Offset``).
ALIASES = (
    ("Offset", "Origin", "Position"),
    ("TransformMatrix", "Rotation", "Orientation"),
    ("BinaryDataByteOrderMSB", "ElementByteOrderMSB"),
)

ErrorType = type[Exception]


def is_metaimage(head: bytes) -> bool:
    """True when ``head`` (the file's first bytes) starts a MetaImage header."""
    first = head.lstrip()[:200].split(b"\n", 1)[0].decode("latin-1")
    m = _LINE.match(first)
    return m is not None and m[1] in _KEYS and b"NDims" in head and b"ElementType" in head


def _fields(path: Path, text: str, error: ErrorType) -> dict[str, str]:
    fields: dict[str, str] = {}
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        m = _LINE.match(line)
        if m is None:
            raise error(f"{path}: MetaImage header line {n} is not 'Key = Value'")
        if m[1] in fields:
            raise error(f"{path}: MetaImage field {m[1]} is given twice; which one is meant?")
        fields[m[1]] = m[2]
    for names in ALIASES:
        given = [n for n in names if n in fields]
        if len(given) > 1 and len({" ".join(fields[n].split()).lower() for n in given}) > 1:
            shown = ", ".join(f"{n} = {fields[n]}" for n in given)
            raise error(
                f"{path}: MetaImage fields {' and '.join(given)} both given with different "
                f"values ({shown}); readers differ on which one counts (ITK, hence 3D Slicer, "
                f"does not take the one ctdrill would): keep one and save the file again"
            )
    return fields


def _numbers(
    path: Path, fields: dict[str, str], names: tuple[str, ...], count: int, error: ErrorType
) -> np.ndarray | None:
    for name in names:
        if name in fields:
            try:
                values = np.array([float(v) for v in fields[name].split()], dtype=np.float64)
            except ValueError as exc:
                raise error(f"{path}: {name} {fields[name]!r} is not {count} numbers") from exc
            if values.size != count:
                raise error(f"{path}: {name} holds {values.size} numbers, expected {count}")
            if not np.all(np.isfinite(values)):
                raise error(
                    f"{path}: {name} {fields[name]!r} is not finite; the geometry cannot be known"
                )
            return values
    return None


def _flag(fields: dict[str, str], *names: str) -> bool:
    return any(fields.get(n, "").strip().lower() == "true" for n in names)


def _geometry(
    path: Path, fields: dict[str, str], shape_kji: tuple[int, ...], error: ErrorType
) -> tuple[np.ndarray, float]:
    spacing = _numbers(path, fields, ("ElementSpacing",), 3, error)
    if spacing is None:
        raise error(f"{path}: no ElementSpacing: the voxel size is not known")
    origin = _numbers(path, fields, ("Offset", "Origin", "Position"), 3, error)
    if origin is None:
        raise error(f"{path}: no Offset: where the voxels are is not known")
    matrix = _numbers(path, fields, ("TransformMatrix", "Rotation", "Orientation"), 9, error)
    dirs = np.eye(3) if matrix is None else matrix.reshape(3, 3)  # row n: axis n's direction
    check_direction_cosines(dirs, where=str(path), field="TransformMatrix", error=error)
    affine = np.eye(4)
    affine[:3, :3] = (dirs * spacing[:, None]).T
    affine[:3, 3] = origin
    tilt = check_grid(
        affine,
        shape_kji,
        where=str(path),
        field="ElementSpacing / TransformMatrix / Offset",
        error=error,
    )
    return affine, tilt


def metaimage_data_file(path: Path, fields: dict[str, str], error: ErrorType) -> Path | None:
    """The data file ``ElementDataFile`` names (a regular file), or None for LOCAL data."""
    name = fields.get("ElementDataFile", "").strip()
    if name.upper() == "LOCAL":
        return None
    if not name or name.upper().startswith("LIST") or "%" in name or " " in name:
        raise error(
            f"{path}: ElementDataFile {name!r} is not LOCAL or one file; save the volume as "
            "one .mha file"
        )
    target = Path(name) if os.path.isabs(name) else path.parent / name
    regular_file_size(target, what=f"MetaImage data file named by {path}", error=error)
    return target


def header_fields(path: Path, error: ErrorType) -> dict[str, str]:
    """The header's ``Key = Value`` fields (up to ``ElementDataFile``)."""
    with open_regular(path, what="MetaImage file", error=error) as fh:
        text, _ = read_text_header(fh, where=str(path), error=error, end=b"ElementDataFile")
    return _fields(path, text, error)


def read_metaimage(path: Path, *, max_bytes: int, error: ErrorType) -> VolumeData:
    """One MetaImage volume (module docstring): ``data`` (k, j, i) in native byte order."""
    where = str(path)
    with open_regular(path, what="MetaImage file", error=error) as fh:
        text, offset = read_text_header(fh, where=where, error=error, end=b"ElementDataFile")
        fields = _fields(path, text, error)
        if "ElementDataFile" not in fields:
            raise error(f"{path}: no ElementDataFile line: not a complete MetaImage header")
        if fields.get("NDims", "").strip() != "3":
            raise error(
                f"{path}: NDims {fields.get('NDims')!r}: ctdrill reads 3-D volumes (a 4-D "
                "one: extract the volume you mean)"
            )
        try:
            sizes = [int(v) for v in fields.get("DimSize", "").split()]
        except ValueError as exc:
            raise error(f"{path}: DimSize {fields.get('DimSize')!r} is not whole numbers") from exc
        if len(sizes) != 3:
            raise error(f"{path}: DimSize {fields.get('DimSize')!r} is not 3 sizes")
        kind = fields.get("ElementType", "").strip()
        if kind not in _TYPES:
            raise error(f"{path}: ElementType {kind!r} is not read (one of {', '.join(_TYPES)})")
        if fields.get("ElementNumberOfChannels", "1").strip() != "1":
            raise error(f"{path}: ElementNumberOfChannels is not 1: not a greyscale volume")
        if fields.get("BinaryData", "True").strip().lower() != "true":
            raise error(f"{path}: BinaryData False (text voxels) is not read; save it binary")
        order = ">" if _flag(fields, "BinaryDataByteOrderMSB", "ElementByteOrderMSB") else "<"
        dtype = np.dtype(order + _TYPES[kind])
        shape_kji = (sizes[2], sizes[1], sizes[0])
        nbytes = declared_bytes(
            shape_kji,
            dtype.itemsize,
            max_bytes=max_bytes,
            where=where,
            error=error,
            field="DimSize",
        )
        affine, tilt = _geometry(path, fields, shape_kji, error)
        codec = "zlib" if _flag(fields, "CompressedData") else "raw"
        source = metaimage_data_file(path, fields, error)
        data_what = f"MetaImage data file named by {path}"
        opened = open_regular(source, what=data_what, error=error) if source is not None else fh
        with opened as stream:
            skip = _header_size(path, fields, source is not None, error)
            if skip == -1 and codec == "raw":
                end = stream.seek(0, 2)
                stream.seek(max(0, end - nbytes))
                skip = 0
            elif source is None:
                stream.seek(offset)
            check_available(stream, codec=codec, nbytes=nbytes, skip=skip, where=where, error=error)
            check_itk_agrees(
                fh,
                affine,
                shape_kji,
                fmt="metaimage",
                field="ElementSpacing / TransformMatrix / Offset",
                where=where,
                error=error,
            )
            data = allocate(shape_kji, dtype, where=where, error=error)
            fill_array(stream, data, codec=codec, skip=skip, where=where, error=error)
    return VolumeData(format="MetaImage", data=native(data), affine_lps=affine, tilt_deg=tilt)


def _header_size(path: Path, fields: dict[str, str], detached: bool, error: ErrorType) -> int:
    text = fields.get("HeaderSize", "0").strip()
    try:
        size = int(text)
    except ValueError as exc:
        raise error(f"{path}: HeaderSize {text!r} is not a whole number") from exc
    if not detached and size != 0:
        raise error(f"{path}: HeaderSize {size} with LOCAL data is not read")
    if not -1 <= size <= MAX_HEADER_BYTES or (size == -1 and _flag(fields, "CompressedData")):
        raise error(f"{path}: HeaderSize {size} outside -1..{MAX_HEADER_BYTES}")
    return size

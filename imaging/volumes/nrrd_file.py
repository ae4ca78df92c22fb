"""NRRD volumes (``.nrrd``, a detached ``.nhdr``), 3D Slicer segmentations included.

The text header (at most :data:`.bounded.MAX_HEADER_BYTES`) is parsed by pynrrd; the voxels are
read or inflated by :func:`.bounded.fill_array` into one array of the declared size (pynrrd's
own reader inflates the whole stream first: a gzip bomb fills memory before any size check).

Geometry: ``space`` must be a patient space (``left-posterior-superior``, ``right-anterior-
superior``, ``left-anterior-superior`` or their three-letter forms; converted to LPS); the
spatial axes are those with ``space directions`` (``none`` marks a list axis), exactly three,
their directions the affine's i, j, k columns in file order and ``space origin`` its origin,
a proper grid (:func:`.grid.check_grid`). ``space units``, when given, must be mm. A header with
only ``spacings`` (no orientation, no origin) is refused.

Every field is given once: two spellings of one field (``data file`` and ``datafile``,
``byte skip`` and ``byteskip``) are refused as teem refuses them; ``space origin`` holds exactly
3 numbers; and ITK must read the same grid from the header (:mod:`.itk_header`).

Data: encodings raw, gzip, bzip2 and ascii (parsed block by block, at most 32 bytes of text a
value); ``byte skip`` (-1 for raw: the data end the file)
and ``line skip``. A detached header's ``data file`` must name one regular file (a name
relative to the header, or absolute); ``LIST`` and numbered file patterns are refused.
Non-spatial axes of size 1 are dropped; one more axis (a Slicer segmentation's layers, the
fastest file axis) is kept only when ``layers`` allows it, anything else is 4-D and refused.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import numpy as np

from ctdrill.imaging.volumes.bounded import (
    MAX_HEADER_BYTES,
    allocate,
    check_available,
    declared_bytes,
    fill_array,
    read_text_header,
)
from ctdrill.imaging.volumes.grid import RAS_TO_LPS, check_grid
from ctdrill.imaging.volumes.itk_header import check_itk_agrees
from ctdrill.imaging.volumes.types import VolumeData, native
from ctdrill.safeio import open_regular, regular_file_size

#: NRRD ``space`` values that are patient spaces, and the LPS matrix of each.
_SPACES = {
    "left-posterior-superior": np.eye(4),
    "lps": np.eye(4),
    "right-anterior-superior": RAS_TO_LPS,
    "ras": RAS_TO_LPS,
    "left-anterior-superior": np.diag([1.0, -1.0, 1.0, 1.0]),
    "las": np.diag([1.0, -1.0, 1.0, 1.0]),
}
_CODECS = {"raw": "raw", "gzip": "gzip", "gz": "gzip", "bzip2": "bzip2", "bz2": "bzip2"}
_ASCII = ("ascii", "text", "txt")
#: Lines a ``line skip`` may skip.
_MAX_LINE_SKIP = 10_000
#: Bytes of text an ascii-encoded value may take on average (bounds the text read).
_ASCII_BYTES_PER_VALUE = 32
#: Bytes of ascii text parsed at a time.
_ASCII_BLOCK = 256 * 1024

ErrorType = type[Exception]


def is_nrrd(head: bytes) -> bool:
    """True when ``head`` (the file's first bytes) starts a NRRD header."""
    return head.startswith(b"NRRD000")


def read_nrrd_header(path: Path, fh: IO[bytes], error: ErrorType) -> tuple[dict[str, Any], int]:
    """The parsed header and the byte offset of the attached data (or the header's end)."""
    header, offset, _ = _read_header(path, fh, error)
    return header, offset


def _read_header(path: Path, fh: IO[bytes], error: ErrorType) -> tuple[dict[str, Any], int, str]:
    """The parsed header, the byte offset of the attached data, and the header's text."""
    import nrrd

    text, offset = read_text_header(fh, where=str(path), error=error, end=b"")
    if not text.startswith("NRRD000"):
        raise error(f"{path}: not a NRRD file (no NRRD000x magic line)")
    seen: dict[str, str] = {}
    pairs: set[str] = set()
    for line in text.splitlines()[1:]:
        if ":=" in line.split(": ", 1)[0]:  # a key/value pair (a Slicer segment's name...)
            pair = line.split(":=", 1)[0]
            if pair in pairs:
                raise error(
                    f"{path}: NRRD key {pair!r} is given twice; readers differ on which value "
                    "counts: keep one and save it again"
                )
            pairs.add(pair)
            continue
        if line.startswith("#") or ": " not in line:
            continue
        key = line.split(": ", 1)[0]
        norm = key.replace(" ", "").lower()
        if norm in seen:
            raise error(
                f"{path}: NRRD field {seen[norm]!r} is given twice (as {seen[norm]!r} and "
                f"{key!r}); readers differ on which one counts (teem, hence ITK and 3D Slicer, "
                "refuses the file): keep one and save it again"
            )
        seen[norm] = key
    for line in text.splitlines():
        key, _, value = line.partition(":")
        if key.strip().lower() in ("data file", "datafile") and (
            value.strip().upper().startswith("LIST") or "%" in value
        ):
            raise error(
                f"{path}: data file {value.strip()!r} names several files (LIST or a pattern); "
                "save the volume as one .nrrd file"
            )
    try:
        header = nrrd.read_header(text.splitlines())
    except (nrrd.NRRDError, ValueError, TypeError, KeyError, IndexError) as exc:
        raise error(f"{path}: the NRRD header cannot be read ({exc})") from exc
    return dict(header), offset, text


def _field(header: dict[str, Any], *names: str) -> Any:
    for name in names:
        if name in header:
            return header[name]
    return None


def data_file(path: Path, header: dict[str, Any], error: ErrorType) -> Path | None:
    """The detached data file a header names (a regular file), or None for attached data."""
    name = _field(header, "data file", "datafile")
    if name is None:
        return None
    text = str(name).strip()
    if text.upper().startswith("LIST") or "%" in text or " " in text:
        raise error(
            f"{path}: data file {text!r} names several files (LIST or a pattern); save the "
            "volume as one .nrrd file"
        )
    target = Path(text) if os.path.isabs(text) else path.parent / text
    regular_file_size(target, what=f"NRRD data file named by {path}", error=error)
    return target


def _spatial(
    path: Path, header: dict[str, Any], sizes: list[int], layers: bool, error: ErrorType
) -> tuple[list[int], int | None]:
    """Indices of the three spatial axes (file order) and of the layer axis, if any."""
    dirs = _field(header, "space directions")
    if dirs is None:
        raise error(
            f"{path}: no space directions (only spacings?): the header does not say how its "
            "voxels are oriented in the patient; save it from a tool that writes NRRD space "
            "directions (3D Slicer, SimpleITK)"
        )
    rows = np.asarray(dirs, dtype=np.float64)
    if rows.ndim != 2 or rows.shape != (len(sizes), 3):
        raise error(
            f"{path}: space directions {rows.tolist()} do not give one 3-vector or none per "
            f"axis of the {len(sizes)}"
        )
    spatial = [n for n in range(len(sizes)) if not np.all(np.isnan(rows[n]))]
    others = [n for n in range(len(sizes)) if n not in spatial and sizes[n] != 1]
    if len(spatial) != 3:
        raise error(f"{path}: {len(spatial)} spatial axes (space directions); a volume has 3")
    if others and not (layers and others == [0]):
        raise error(
            f"{path}: a {len(sizes)}-D volume (sizes {sizes}); ctdrill reads one 3-D volume: "
            "extract the one you mean"
        )
    return spatial, (others[0] if others else None)


def _affine(
    path: Path,
    header: dict[str, Any],
    spatial: list[int],
    shape_kji: tuple[int, ...],
    error: ErrorType,
) -> tuple[np.ndarray, float]:
    space = str(_field(header, "space") or "").strip().lower()
    if space not in _SPACES:
        shown = header.get("space", header.get("space dimension"))
        raise error(
            f"{path}: NRRD space {shown!r} is not a patient space (left-posterior-superior, "
            "right-anterior-superior or left-anterior-superior); the geometry cannot be placed"
        )
    units = _field(header, "space units")
    if units is not None and any(str(u).strip().lower() != "mm" for u in units):
        raise error(f"{path}: space units {list(units)}: ctdrill reads mm only; save it in mm")
    origin = _field(header, "space origin")
    if origin is None:
        raise error(f"{path}: no space origin: the header does not say where its voxels are")
    origin_mm = np.asarray(origin, dtype=np.float64).reshape(-1)
    if origin_mm.size != 3:
        raise error(
            f"{path}: space origin holds {origin_mm.size} numbers {origin_mm.tolist()}, the "
            "space has 3; the header is damaged: save it again"
        )
    rows = np.asarray(header["space directions"], dtype=np.float64)[spatial]
    affine = np.eye(4)
    affine[:3, :3] = rows.T
    affine[:3, 3] = origin_mm
    lps: np.ndarray = _SPACES[space] @ affine
    tilt = check_grid(
        lps, shape_kji, where=str(path), field="space directions / space origin", error=error
    )
    return lps, tilt


def _ascii(path: Path, fh: IO[bytes], out: np.ndarray, error: ErrorType) -> None:
    """Fill ``out`` from ascii numbers, parsed block by block (:data:`_ASCII_BLOCK` bytes of
    text at a time): the memory beyond ``out`` is one block's, never the whole text's (a list
    of Python numbers costs about 36 times the declared bytes)."""
    limit = min(out.size * _ASCII_BYTES_PER_VALUE + MAX_HEADER_BYTES, 1 << 32)
    flat = out.reshape(-1)
    filled = 0
    read = 0
    carry = b""
    while True:
        block = fh.read(_ASCII_BLOCK)
        read += len(block)
        if read > limit:
            raise error(
                f"{path}: the ascii data run past {limit} bytes ({_ASCII_BYTES_PER_VALUE} a "
                "value); save the volume raw or gzip"
            )
        text = carry + block
        if block:
            cut = max(text.rfind(b" "), text.rfind(b"\n"), text.rfind(b"\t"), text.rfind(b"\r"))
            text, carry = (text[: cut + 1], text[cut + 1 :]) if cut >= 0 else (b"", text)
            if len(carry) > _ASCII_BYTES_PER_VALUE * 8:
                raise error(f"{path}: the ascii data hold a value longer than {len(carry)} bytes")
        else:
            carry = b""
        words = text.split()
        if filled + len(words) > flat.size:
            raise error(
                f"{path}: the ascii data hold more than the {flat.size} values the header declares"
            )
        if words:
            try:
                values = np.array(words, dtype=np.float64)
            except ValueError as exc:
                raise error(
                    f"{path}: the ascii data hold a value that is not a number ({exc})"
                ) from exc
            with np.errstate(all="ignore"):
                cast = values.astype(out.dtype)
            if not np.array_equal(cast.astype(np.float64), values, equal_nan=True):
                raise error(f"{path}: the ascii data hold values its type {out.dtype} cannot hold")
            flat[filled : filled + len(words)] = cast
            filled += len(words)
        if not block:
            break
    if filled != flat.size:
        raise error(f"{path}: the header declares {flat.size} values, the ascii data hold {filled}")


def read_nrrd(path: Path, *, max_bytes: int, error: ErrorType, layers: bool = False) -> VolumeData:
    """One NRRD volume (module docstring), its size checked before anything is allocated.

    ``data`` is (k, j, i), or (layers, k, j, i) when ``layers`` allows a list axis; native
    byte order. ``description`` is the ``content`` field, ``fields`` every field as text.
    """
    import nrrd

    with open_regular(path, what="NRRD file", error=error) as fh:
        header, offset, text = _read_header(path, fh, error)
        try:
            sizes = [int(n) for n in np.atleast_1d(header["sizes"])]
            dtype = np.dtype(nrrd.reader._determine_datatype(header))
            encoding = str(header["encoding"]).strip().lower()
        except (nrrd.NRRDError, KeyError, TypeError, ValueError) as exc:
            raise error(f"{path}: the NRRD header lacks a field it needs ({exc})") from exc
        if int(header.get("dimension", len(sizes))) != len(sizes):
            raise error(f"{path}: dimension {header.get('dimension')} but {len(sizes)} sizes")
        if dtype.kind not in "uif" or dtype.itemsize > 8:
            raise error(f"{path}: type {header.get('type')!r} is not read (integers or reals)")
        declared_bytes(
            tuple(sizes),
            dtype.itemsize,
            max_bytes=max_bytes,
            where=str(path),
            error=error,
            field="sizes",
        )
        spatial, layer_axis = _spatial(path, header, sizes, layers, error)
        shape_kji = tuple(sizes[n] for n in reversed(spatial))
        affine, tilt = _affine(path, header, spatial, shape_kji, error)
        if encoding not in _CODECS and encoding not in _ASCII:
            raise error(f"{path}: encoding {encoding!r} is not read; save it raw, gzip or bzip2")
        source = data_file(path, header, error)
        data_what = f"NRRD data file named by {path}"
        opened = open_regular(source, what=data_what, error=error) if source is not None else fh
        with opened as stream:

            def itk_agrees() -> None:
                check_itk_agrees(
                    fh,
                    affine,
                    shape_kji,
                    fmt="nrrd",
                    field="space directions / space origin",
                    where=str(path),
                    error=error,
                    data_fh=stream if source is not None else None,
                    header_text=text if source is not None else None,
                )

            if source is None:
                stream.seek(offset)
            _skip_lines(path, stream, header, error)
            data = _read_data(
                path, stream, tuple(reversed(sizes)), dtype, encoding, header, error, itk_agrees
            )
    arr = native(data)
    # C order: file axes reversed. Drop size-1 non-spatial axes; the layer axis goes first.
    keep = set(spatial) | ({layer_axis} if layer_axis is not None else set())
    c_axes = [len(sizes) - 1 - n for n in range(len(sizes))]
    drop = tuple(c for n, c in zip(range(len(sizes)), c_axes, strict=True) if n not in keep)
    arr = arr.reshape([s for c, s in enumerate(arr.shape) if c not in drop])
    if layer_axis is not None:
        arr = np.moveaxis(arr, -1, 0)  # the fastest file axis is the last in C order
    return VolumeData(
        format="NRRD",
        data=arr,
        affine_lps=affine,
        tilt_deg=tilt,
        description=str(header.get("content", "")),
        fields={str(k): str(v) for k, v in header.items()},
    )


def _skip_lines(path: Path, fh: IO[bytes], header: dict[str, Any], error: ErrorType) -> None:
    n = int(_field(header, "line skip", "lineskip") or 0)
    if not 0 <= n <= _MAX_LINE_SKIP:
        raise error(f"{path}: line skip {n} outside 0..{_MAX_LINE_SKIP}")
    for _ in range(n):
        if not fh.readline(MAX_HEADER_BYTES):
            raise error(f"{path}: line skip {n} runs past the end of the data")


def _read_data(
    path: Path,
    fh: IO[bytes],
    shape: tuple[int, ...],
    dtype: np.dtype,
    encoding: str,
    header: dict[str, Any],
    error: ErrorType,
    before_allocating: Callable[[], None],
) -> np.ndarray:
    """The voxels, after the bounded checks and ``before_allocating`` (ITK's agreement)."""
    where = str(path)
    skip = int(_field(header, "byte skip", "byteskip") or 0)
    nbytes = int(np.prod(shape, dtype=object)) * dtype.itemsize
    if encoding in _ASCII:
        count = nbytes // dtype.itemsize
        here = fh.tell()
        left = fh.seek(0, 2) - here
        fh.seek(here)
        if left < 2 * count - 1:  # a digit and a separator per value
            raise error(
                f"{path}: the header declares {count} values, the ascii data hold {left} bytes "
                "(at least two a value); the file is truncated or its header lies"
            )
        before_allocating()
        out = allocate(shape, dtype, where=where, error=error)
        _ascii(path, fh, out, error)
        return out
    codec = _CODECS[encoding]
    if skip == -1 and codec == "raw":
        end = fh.seek(0, 2)
        fh.seek(max(fh.tell() - nbytes, 0))
        if end < nbytes:
            raise error(
                f"{path}: the header declares {nbytes} bytes of voxel data, the file holds "
                f"{end}; the file is truncated or its header lies"
            )
        skip = 0
    elif not 0 <= skip <= MAX_HEADER_BYTES:
        raise error(f"{path}: byte skip {skip} outside 0..{MAX_HEADER_BYTES} (-1 only for raw)")
    check_available(fh, codec=codec, nbytes=nbytes, skip=skip, where=where, error=error)
    before_allocating()
    out = allocate(shape, dtype, where=where, error=error)
    fill_array(fh, out, codec=codec, skip=skip, where=where, error=error)
    return out

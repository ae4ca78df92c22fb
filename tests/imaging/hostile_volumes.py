"""Hostile volume files (NIfTI, NRRD, MetaImage), one per class of lie, and what the refusal names.

Each builder writes one file into a folder and returns ``(path, pattern)``: ``pattern`` is a
regular expression the one-line refusal must match (the field it names). Used through the
Python API (``tests/imaging/test_volume_hostile.py``) and the CLI under an address-space cap
(``tests/robustness/test_volume_bombs.py``). Every file is small; the bombs declare or inflate
to gigabytes.
"""

from __future__ import annotations

import functools
import gzip
import struct
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np

from tests.imaging.volume_writers import (
    edit_text_header,
    oblique_affine,
    ramp,
    write_mha,
    write_nifti,
    write_nrrd,
)

SHAPE = (4, 5, 6)
AFFINE = oblique_affine()
Builder = Callable[[Path], tuple[Path, str]]

#: Zeros that inflate to 128 MiB from about 130 kB of gzip or zlib.
BOMB_BYTES = 128 << 20


@functools.cache
def _zeros(n: int, wbits: int) -> bytes:
    """``n`` zero bytes compressed (wbits 31: gzip, 15: zlib), made once per session."""
    comp = zlib.compressobj(9, zlib.DEFLATED, wbits)
    block = bytes(1 << 20)
    return b"".join(comp.compress(block) for _ in range(n >> 20)) + comp.flush()


def _nifti_patch(path: Path, fmt: str, offset: int, *values: float) -> Path:
    raw = bytearray(path.read_bytes())
    struct.pack_into(fmt, raw, offset, *values)
    path.write_bytes(bytes(raw))
    return path


def _nii(folder: Path, name: str = "ct.nii", **kw: object) -> Path:
    return write_nifti(folder / name, ramp(SHAPE), AFFINE, **kw)  # type: ignore[arg-type]


# NIfTI-1 header offsets (bytes): dim[8] int16 at 40, datatype 70, bitpix 72, pixdim[8] float32
# at 76, vox_offset 108, scl_slope 112, scl_inter 116, qform_code 252, sform_code 254,
# srow_x 280.


def nifti_4d(folder: Path) -> tuple[Path, str]:
    path = _nii(folder)
    _nifti_patch(path, "<h", 40, 4)
    return _nifti_patch(path, "<h", 48, 3), r"4-D volume"


def nifti_nan_spacing(folder: Path) -> tuple[Path, str]:
    path = _nii(folder, sform_code=0)
    return _nifti_patch(path, "<f", 80, float("nan")), r"qform.*not finite"


def nifti_sform_inf(folder: Path) -> tuple[Path, str]:
    path = _nii(folder, qform_code=0)
    return _nifti_patch(path, "<f", 280, float("inf")), r"sform.*not finite"


def nifti_spacing_1e30(folder: Path) -> tuple[Path, str]:
    path = _nii(folder, qform_code=0)
    return _nifti_patch(path, "<f", 280, 1e30), r"sform.*spacing along i"


def nifti_huge_dims(folder: Path) -> tuple[Path, str]:
    path = _nii(folder)
    return _nifti_patch(path, "<hhh", 42, 32767, 32767, 32767), r"dim declares .* more than"


def nifti_truncated(folder: Path) -> tuple[Path, str]:
    path = _nii(folder)
    path.write_bytes(path.read_bytes()[:-20])
    return path, r"declares 240 bytes of voxel data.*holds 220"


def nifti_gz_lying_size(folder: Path) -> tuple[Path, str]:
    path = _nii(folder)
    raw = bytearray(path.read_bytes())
    struct.pack_into("<hhh", raw, 42, 1000, 1000, 500)  # 1 GB of int16 from a few hundred bytes
    gz = folder / "lying.nii.gz"
    gz.write_bytes(gzip.compress(bytes(raw)))
    path.unlink()
    return gz, r"compressed bytes \(at most \d+ once inflated\)"


def nifti_gz_bomb(folder: Path) -> tuple[Path, str]:
    path = _nii(folder)
    bomb = folder / "bomb.nii.gz"  # two gzip members: the header, then the zeros
    bomb.write_bytes(gzip.compress(path.read_bytes()[:352]) + _zeros(BOMB_BYTES, 31))
    path.unlink()
    return bomb, r"hold more than the 240 bytes"


def nifti_slope_inf(folder: Path) -> tuple[Path, str]:
    return _nifti_patch(_nii(folder), "<f", 112, float("inf")), r"scl_slope"


def nifti_complex(folder: Path) -> tuple[Path, str]:
    path = _nii(folder)
    return _nifti_patch(path, "<hh", 70, 32, 64), r"datatype complex"


def nifti_vox_offset(folder: Path) -> tuple[Path, str]:
    return _nifti_patch(_nii(folder), "<f", 108, 1e12), r"vox_offset"


def nifti_no_codes(folder: Path) -> tuple[Path, str]:
    return _nii(folder, sform_code=0, qform_code=0), r"qform_code and sform_code are both 0"


def _nrrd(folder: Path, name: str = "ct.nrrd", **kw: object) -> Path:
    return write_nrrd(folder / name, ramp(SHAPE), AFFINE, **kw)  # type: ignore[arg-type]


def nrrd_gzip_bomb(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    data = path.read_bytes()
    head = data[: data.index(b"\n\n") + 2].replace(b"encoding: raw", b"encoding: gzip")
    path.write_bytes(head + _zeros(BOMB_BYTES, 31))
    return path, r"hold more than the 240 bytes"


def nrrd_spacing_1e300(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    text = path.read_bytes().split(b"\n\n", 1)[0].decode()
    line = next(x for x in text.splitlines() if x.startswith("space directions"))
    edit_text_header(path, line, "space directions: (1e300,0,0) (0,1,0) (0,0,1)")
    return path, r"space directions.*spacing along i is 1e\+300"


def nrrd_nan_origin(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    text = path.read_bytes().split(b"\n\n", 1)[0].decode()
    line = next(x for x in text.splitlines() if x.startswith("space origin"))
    edit_text_header(path, line, "space origin: (nan,0,0)")
    return path, r"space directions / space origin is not finite"


def nrrd_not_patient_space(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    edit_text_header(path, "space: left-posterior-superior", "space: scanner-xyz")
    return path, r"space 'scanner-xyz' is not a patient space"


def nrrd_4d(folder: Path) -> tuple[Path, str]:
    import nrrd

    path = folder / "4d.nrrd"
    header = {
        "space": "left-posterior-superior",
        "space directions": np.vstack([np.full(3, np.nan), AFFINE[:3, :3].T]),
        "space origin": AFFINE[:3, 3],
        "kinds": ["list", "domain", "domain", "domain"],
    }
    nrrd.write(str(path), np.zeros((3, 6, 5, 4), dtype=np.int16), header)
    return path, r"a 4-D volume|a 3-D labelmap, got 4 axes"


def nrrd_huge_sizes(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    edit_text_header(path, "sizes: 6 5 4", "sizes: 60000 60000 60000")
    return path, r"sizes declares .* more than"


def nrrd_truncated(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    path.write_bytes(path.read_bytes()[:-40])
    return path, r"declares 240 bytes of voxel data, the file holds 200"


def nrrd_skewed(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    text = path.read_bytes().split(b"\n\n", 1)[0].decode()
    line = next(x for x in text.splitlines() if x.startswith("space directions"))
    edit_text_header(path, line, "space directions: (1,0,0) (0.1,1,0) (0,0,1)")
    return path, r"i and j axes are not perpendicular"


def nrrd_units_cm(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    edit_text_header(path, "space: left", 'space units: "cm" "cm" "cm"\nspace: left')
    return path, r"space units \['cm', 'cm', 'cm'\]"


def nrrd_data_file_device(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, "ct.nhdr", encoding="raw", detached=True)
    data_name = next(p.name for p in folder.iterdir() if p.name.startswith("ct.") and p != path)
    edit_text_header(path, f"data file: {data_name}", "data file: /dev/zero")
    return path, r"/dev/zero: the NRRD data file named by .*ct\.nhdr is a device"


def nrrd_data_file_list(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, "ct.nhdr", encoding="raw", detached=True)
    data_name = next(p.name for p in folder.iterdir() if p.name.startswith("ct.") and p != path)
    edit_text_header(path, f"data file: {data_name}\n", "data file: LIST\nx.raw\ny.raw\n")
    return path, r"data file 'LIST' names several files"


def nrrd_endless_header(folder: Path) -> tuple[Path, str]:
    path = folder / "endless.nrrd"
    path.write_bytes(b"NRRD0004\n" + b"# comment line of the header\n" * 80000)
    return path, r"header runs past 1048576 bytes"


def seg_100k_segments(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, "many.seg.nrrd", encoding="raw")
    fields = "".join(f"Segment{n}_ID:=S{n}\nSegment{n}_Name:=s{n}\n" for n in range(100_000))
    edit_text_header(path, "space: left", fields + "space: left")
    return path, r"header runs past"


def seg_1001_segments(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, "many.seg.nrrd", encoding="raw")
    fields = "".join(f"Segment{n}_ID:=S{n}\n" for n in range(1001))
    edit_text_header(path, "space: left", fields + "space: left")
    return path, r"declares 1001 segments, more than the 1000"


def _mha(folder: Path, name: str = "ct.mha", **kw: object) -> Path:
    return write_mha(folder / name, ramp(SHAPE), AFFINE, **kw)  # type: ignore[arg-type]


def _mha_line(path: Path, key: str) -> str:
    text = path.read_bytes().split(b"ElementDataFile", 1)[0].decode()
    return next(x for x in text.splitlines() if x.startswith(key))


def mha_4d(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    edit_text_header(path, "NDims = 3", "NDims = 4")
    return path, r"NDims '4'"


def mha_huge(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    edit_text_header(path, "DimSize = 6 5 4", "DimSize = 100000 100000 100000")
    return path, r"DimSize declares .* more than"


def mha_spacing_nan(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    edit_text_header(path, _mha_line(path, "ElementSpacing"), "ElementSpacing = nan 1 1")
    return path, r"ElementSpacing 'nan 1 1' is not finite"


def mha_matrix_x10(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    line = _mha_line(path, "TransformMatrix")
    scaled = " ".join(f"{10 * float(v)!r}" for v in line.split("=")[1].split())
    edit_text_header(path, line, f"TransformMatrix = {scaled}")
    return path, r"TransformMatrix: direction 1 has length 10"


def mha_matrix_skew(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    line = _mha_line(path, "TransformMatrix")
    c, s = float(np.cos(0.1)), float(np.sin(0.1))
    edit_text_header(path, line, f"TransformMatrix = 1 0 0 {s!r} {c!r} 0 0 0 1")
    return path, r"TransformMatrix: directions 1 and 2 are not perpendicular"


def mha_no_offset(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    line = _mha_line(path, "Offset")
    edit_text_header(path, line + "\n", "")
    return path, r"no Offset"


def mha_data_device(folder: Path) -> tuple[Path, str]:
    path = _mha(folder, name="ct.mhd")
    edit_text_header(path, "ElementDataFile = ct.raw", "ElementDataFile = /dev/zero")
    return path, r"/dev/zero: the MetaImage data file named by .*ct\.mhd is a device"


def mha_zlib_bomb(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    data = path.read_bytes()
    at = data.index(b"ElementDataFile = LOCAL\n") + len(b"ElementDataFile = LOCAL\n")
    head = data[:at].replace(b"CompressedData = False", b"CompressedData = True")
    path.write_bytes(head + _zeros(BOMB_BYTES, 15))
    return path, r"hold more than the 240 bytes"


def mha_truncated(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    path.write_bytes(path.read_bytes()[:-10])
    return path, r"declares 240 bytes of voxel data, the file holds 230"


def mha_element_type(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    edit_text_header(path, "ElementType = MET_SHORT", "ElementType = MET_STRING")
    return path, r"ElementType 'MET_STRING' is not read"


def mha_channels(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    edit_text_header(path, "ElementType", "ElementNumberOfChannels = 3\nElementType")
    return path, r"ElementNumberOfChannels is not 1"


# Round four: where ctdrill's reader and ITK's (3D Slicer's) would read one header two ways,
# and the bounds of every codec and header field. Other instances than the ones reported.


def nifti_sheared_sform_over_qform(folder: Path) -> tuple[Path, str]:
    sheared = AFFINE.copy()
    sheared[:3, 2] += np.tan(np.radians(12.0)) * 1.25 * AFFINE[:3, 1] / 0.875  # 12 deg shear
    path = write_nifti(folder / "ct.nii", ramp(SHAPE), sheared, qform_lps=AFFINE)
    # a CT: ITK takes the qform where ctdrill would take the sform; a segmentation: refused
    # already because the two disagree
    return (
        path,
        r"sform \(srow_x/y/z, sform_code 1\): ctdrill reads .* where ITK reads"
        r"|qform .* and the sform .* apart",
    )


def nifti_sheared_sform_only(folder: Path) -> tuple[Path, str]:
    sheared = AFFINE.copy()
    sheared[:3, 2] += 0.05 * AFFINE[:3, 0]
    path = write_nifti(folder / "ct.nii.gz", ramp(SHAPE), sheared, qform_code=0)
    return path, r"ITK .*refuses the header: .*orthonormal"


def nifti_units_code_5(folder: Path) -> tuple[Path, str]:
    path = _nii(folder)
    raw = bytearray(path.read_bytes())
    raw[123] = 5 | 0x08  # spatial code 5 (none), time in seconds
    path.write_bytes(bytes(raw))
    return path, r"xyzt_units 13: spatial unit code 5 is not a length unit"


def nifti_version_2(folder: Path) -> tuple[Path, str]:
    path = write_nifti(folder / "ct.nii", ramp(SHAPE), AFFINE, version=2)
    return path, r"ITK .*refuses the header.*NIfTI-1"


def _gzip_with_field(payload: bytes, flag: int, field: bytes) -> bytes:
    """A gzip member with header flag ``flag`` (0x08 name, 0x10 comment) holding ``field``."""
    head = b"\x1f\x8b\x08" + bytes([flag]) + b"\0\0\0\0\0\xff" + field + b"\0"
    comp = zlib.compressobj(6, zlib.DEFLATED, -15)
    body = comp.compress(payload) + comp.flush()
    tail = struct.pack("<II", zlib.crc32(payload), len(payload) & 0xFFFFFFFF)
    return head + body + tail


def nifti_gz_long_name(folder: Path) -> tuple[Path, str]:
    plain = _nii(folder)
    path = folder / "named.nii.gz"
    path.write_bytes(_gzip_with_field(plain.read_bytes(), 0x08, b"n" * (3 << 20)))
    plain.unlink()
    return path, r"gzip header's file name field runs past 65536 bytes"


def nifti_gz_long_comment(folder: Path) -> tuple[Path, str]:
    plain = _nii(folder)
    path = folder / "commented.nii.gz"
    path.write_bytes(_gzip_with_field(plain.read_bytes(), 0x10, b"c" * (1 << 20)))
    plain.unlink()
    return path, r"gzip header's comment field runs past 65536 bytes"


def nrrd_line_skip_spellings(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    edit_text_header(path, "encoding: raw", "encoding: raw\nline skip: 0\nlineskip: 1")
    return path, r"NRRD field 'line skip' is given twice \(as 'line skip' and 'lineskip'\)"


def nrrd_origin_given_twice(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    edit_text_header(path, "space origin:", "space origin: (0,0,0)\nspace origin:")
    return path, r"NRRD field 'space origin' is given twice"


def nrrd_origin_two_values(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    text = path.read_bytes().split(b"\n\n", 1)[0].decode()
    line = next(x for x in text.splitlines() if x.startswith("space origin:"))
    edit_text_header(path, line, "space origin: (12.5,-30.25)")
    return path, r"space origin holds 2 numbers"


@functools.cache
def _bz2_zeros(n: int) -> bytes:
    """``n`` zero bytes in bzip2 (about 100 bytes for 128 MiB), made once per session."""
    import bz2

    comp = bz2.BZ2Compressor(9)
    block = bytes(1 << 20)
    return b"".join(comp.compress(block) for _ in range(n >> 20)) + comp.flush()


def seg_segment_name_twice(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, "two.seg.nrrd", encoding="raw")
    fields = "Segment0_ID:=S0\nSegment0_Name:=canal\nSegment0_Name:=tooth\n"
    edit_text_header(path, "space: left", fields + "space: left")
    return path, r"NRRD key 'Segment0_Name' is given twice"


def nrrd_bzip2_bomb(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, encoding="raw")
    data = path.read_bytes()
    head = data[: data.index(b"\n\n") + 2].decode()
    head = head.replace("sizes: 6 5 4", "sizes: 512 512 256").replace(
        "encoding: raw", "encoding: bzip2"
    )
    path.write_bytes(head.encode() + _bz2_zeros(128 << 20))
    return path, r"bytes of bzip2 \(more than 1032 times.*decompression bomb"


def nrrd_data_file_proc(folder: Path) -> tuple[Path, str]:
    path = _nrrd(folder, "ct.nhdr", encoding="raw", detached=True)
    data_name = next(p.name for p in folder.iterdir() if p.name.startswith("ct.") and p != path)
    edit_text_header(path, f"data file: {data_name}", "data file: /proc/self/environ")
    return (
        path,
        r"/proc/self/environ: the NRRD data file named by .*ct\.nhdr is a kernel pseudo-file",
    )


def mha_position_and_offset(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    edit_text_header(path, "Offset =", "Position = 0 0 4\nOffset =")
    return path, r"MetaImage fields Offset and Position both given with different values"


def mha_rotation_and_matrix(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    edit_text_header(path, "TransformMatrix =", "Rotation = 1 0 0 0 1 0 0 0 1\nTransformMatrix =")
    return path, r"MetaImage fields TransformMatrix and Rotation both given"


def mha_byte_order_spellings(folder: Path) -> tuple[Path, str]:
    path = _mha(folder)
    edit_text_header(path, "ElementType", "ElementByteOrderMSB = True\nElementType")
    return path, r"BinaryDataByteOrderMSB and ElementByteOrderMSB both given"


def mha_data_proc(folder: Path) -> tuple[Path, str]:
    path = _mha(folder, name="ct.mhd")
    edit_text_header(path, "ElementDataFile = ct.raw", "ElementDataFile = /proc/self/stat")
    return (
        path,
        r"/proc/self/stat: the MetaImage data file named by .*ct\.mhd is a kernel pseudo-file",
    )


HOSTILE: dict[str, Builder] = {
    name: fn
    for name, fn in sorted(globals().items())
    if callable(fn) and name.split("_")[0] in ("nifti", "nrrd", "seg", "mha")
}
#: Cases only a segmentation reader refuses (a CT reads them: their lie is about segments).
MASK_ONLY = ("seg_1001_segments",)
#: Cases that inflate or declare far beyond their size (run under an address-space cap).
BOMBS = (
    "nifti_gz_bomb",
    "nifti_gz_lying_size",
    "nifti_huge_dims",
    "nrrd_gzip_bomb",
    "nrrd_huge_sizes",
    "mha_huge",
    "mha_zlib_bomb",
    "seg_100k_segments",
    "nifti_gz_long_name",
    "nrrd_bzip2_bomb",
)

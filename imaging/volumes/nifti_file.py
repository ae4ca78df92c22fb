"""NIfTI-1 and NIfTI-2 volumes (``.nii``, ``.nii.gz``): the header by nibabel, voxels bounded.

The header is parsed by nibabel from its fixed-size block (extensions are skipped, never read:
they may hold a DICOM header); the voxels are read or inflated into one array of the declared
size (:mod:`.bounded`); for a CT, int16 voxels are made HU (an integer scale), measured and
hashed into the volume's identity as they are read (:class:`.identity.HuStream`). The file
type comes from its content (gzip magic, ``sizeof_hdr`` and the magic string), not its name.

Geometry, in the file RAS and converted to LPS (x, y negated):

- neither ``qform_code`` nor ``sform_code`` set: refused (the header does not say where its
  voxels are; nibabel would fall back to a pixdim-only affine of no known orientation);
- one set: that transform;
- both set and the same grid (every voxel corner within :data:`.grid.SAME_GRID_MM`): the sform,
  nibabel's ``img.affine``;
- both set and different: a CT uses the sform, as nibabel does (it can hold any grid, a tilt's
  shear included, where the qform holds only rotations), and says so (``qform_sform_differ``,
  with the distance); a segmentation (``refuse_ambiguous``) is refused: which of the two a tool
  trusts differs between tools (ITK may take the qform), and a canal must not move with it.

Each coded transform must be a proper grid (:func:`.grid.check_grid`), and ITK must read the
same grid from the header (:mod:`.itk_header`: a sheared sform ITK will not take, or one where
ITK takes the qform, is refused). Spatial units (``xyzt_units``): metres and microns are
converted to mm (as ITK does), unknown (0) is taken as mm (as ITK does), a code that is no
length unit (4..7) is refused.
Scaling: ``scl_slope`` 0 or NaN means none (the NIfTI convention, nibabel's); otherwise the
slope and intercept are returned to be applied; a non-finite slope or intercept is refused.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import IO, Any

import numpy as np

from ctdrill.imaging.provenance import LoadWarning
from ctdrill.imaging.volumes.bounded import (
    allocate,
    check_available,
    declared_bytes,
    fill_array,
    gunzip_prefix,
)
from ctdrill.imaging.volumes.grid import (
    RAS_TO_LPS,
    SAME_GRID_MM,
    check_grid,
    grid_distance_mm,
)
from ctdrill.imaging.volumes.hu_values import tail_step
from ctdrill.imaging.volumes.identity import HuStream, integer_scale
from ctdrill.imaging.volumes.itk_header import check_itk_agrees
from ctdrill.imaging.volumes.types import VolumeData, native
from ctdrill.safeio import open_regular

#: Header sizes of NIfTI-1 and NIfTI-2, bytes (``sizeof_hdr``).
NIFTI1_BYTES = 348
NIFTI2_BYTES = 540
#: Largest offset of the voxel data (header plus extensions) read past, bytes.
MAX_VOX_OFFSET = 16 << 20
#: mm per unit of ``xyzt_units``' spatial code (its low 3 bits): 0 unknown (taken as mm, as
#: ITK does), 1 metre, 2 mm, 3 micron. Codes 4..7 are no length unit: refused.
_UNIT_MM = {0: 1.0, 1: 1000.0, 2: 1.0, 3: 1e-3}

ErrorType = type[Exception]


def nifti_header_bytes(head: bytes) -> int | None:
    """348 or 540 when ``head`` (the first bytes, decompressed) starts a NIfTI header."""
    if len(head) < 4:
        return None
    for order in "<>":
        (size,) = struct.unpack(order + "i", head[:4])
        if size == NIFTI1_BYTES and head[344:348] in (b"n+1\0", b"ni1\0"):
            return size
        if size == NIFTI2_BYTES and head[4:8] in (b"n+2\0", b"ni2\0"):
            return size
    return None


def _codec(fh: IO[bytes]) -> str:
    """``gzip`` or ``raw``: the file's compression, by its first bytes; ``fh`` left at 0."""
    fh.seek(0)
    magic = fh.read(2)
    fh.seek(0)
    return "gzip" if magic == b"\x1f\x8b" else "raw"


def _header(path: Path, fh: IO[bytes], error: ErrorType) -> Any:
    import nibabel

    if _codec(fh) == "gzip":
        head = gunzip_prefix(fh, NIFTI2_BYTES, where=str(path), error=error)
    else:
        head = fh.read(NIFTI2_BYTES)
    fh.seek(0)
    size = nifti_header_bytes(head)
    if size is None:
        raise error(f"{path}: not a NIfTI-1 or NIfTI-2 file (no sizeof_hdr and magic)")
    magic = head[344:348] if size == NIFTI1_BYTES else head[4:8]
    if magic.startswith(b"ni"):
        raise error(
            f"{path}: a NIfTI pair header (magic {magic[:3].decode()}: voxels in a separate "
            ".img file); save the volume as one .nii or .nii.gz file"
        )
    cls = nibabel.Nifti1Header if size == NIFTI1_BYTES else nibabel.Nifti2Header
    try:
        return cls(head[:size], check=False)
    except Exception as exc:  # nibabel raises several types on a malformed block
        raise error(f"{path}: not a readable NIfTI header ({exc})") from exc


def _coded(path: Path, hdr: Any, which: str, error: ErrorType) -> Any:
    """(affine in RAS mm, code) of the qform or sform, checked to be a proper grid."""
    fields = (
        "qform (quatern_b/c/d, qoffset_x/y/z, pixdim)" if which == "qform" else "sform (srow_x/y/z)"
    )
    try:
        with np.errstate(all="ignore"):
            affine, code = (hdr.get_qform if which == "qform" else hdr.get_sform)(coded=True)
    except Exception as exc:  # nibabel: a quaternion that is not one, ...
        raise error(f"{path}: the {fields} cannot be read ({exc}); export the file again") from exc
    if affine is None:
        return None, 0
    return np.asarray(affine, dtype=np.float64), int(code)


def _units_mm(path: Path, hdr: Any, error: ErrorType) -> float:
    code = int(hdr["xyzt_units"]) & 0x07
    if code not in _UNIT_MM:
        raise error(
            f"{path}: xyzt_units {int(hdr['xyzt_units'])}: spatial unit code {code} is not a "
            "length unit (0 unknown, taken as mm; 1 metre; 2 mm; 3 micron); the voxel size is "
            "not known: save the file again with its units in mm"
        )
    return _UNIT_MM[code]


def _geometry(
    path: Path, hdr: Any, shape_kji: tuple[int, ...], refuse_ambiguous: bool, error: ErrorType
) -> tuple[np.ndarray, float, tuple[LoadWarning, ...]]:
    """LPS affine, tilt and warnings (module docstring)."""
    where = str(path)
    scale = np.diag([_units_mm(path, hdr, error)] * 3 + [1.0])
    found = {}
    for which in ("sform", "qform"):
        affine, code = _coded(path, hdr, which, error)
        if affine is not None:
            with np.errstate(all="ignore"):  # a non-finite field is refused by check_grid
                lps = RAS_TO_LPS @ scale @ affine
            field = f"{which} ({which}_code {code})"
            found[which] = (
                lps,
                code,
                check_grid(lps, shape_kji, where=where, field=field, error=error),
            )
    if not found:
        raise error(
            f"{path}: qform_code and sform_code are both 0: the header does not say where its "
            "voxels are in the patient; export the volume again with its orientation (or set "
            "the sform from the scanner's geometry)"
        )
    warnings: tuple[LoadWarning, ...] = ()
    if len(found) == 2:
        (s_aff, s_code, _), (q_aff, q_code, _) = found["sform"], found["qform"]
        apart = grid_distance_mm(s_aff, q_aff, shape_kji)
        if apart > SAME_GRID_MM:
            detail = (
                f"the qform (qform_code {q_code}) and the sform (sform_code {s_code}) place "
                f"voxels up to {apart:.4g} mm apart (tolerance {SAME_GRID_MM:g} mm)"
            )
            if refuse_ambiguous:
                raise error(
                    f"{path}: {detail}; readers differ on which to trust, so the segmentation's "
                    "place is not known: save it again with one geometry (e.g. the qform set "
                    "equal to the sform)"
                )
            warnings = (
                LoadWarning(
                    "qform_sform_differ",
                    f"{detail}; the sform is used, as nibabel does (it holds any grid; the qform "
                    "only rotations): check that the volume sits where the plan expects it",
                ),
            )
    chosen = found.get("sform", found.get("qform"))
    assert chosen is not None
    return chosen[0], chosen[2], warnings


def _field_of(affine: np.ndarray, hdr: Any) -> str:
    """The header fields a chosen geometry came from, for messages."""
    return (
        f"sform (srow_x/y/z, sform_code {int(hdr['sform_code'])})"
        if int(hdr["sform_code"]) > 0
        else f"qform (quatern_b/c/d, qoffset_x/y/z, pixdim; qform_code {int(hdr['qform_code'])})"
    )


def _scale(path: Path, hdr: Any, error: ErrorType) -> tuple[float, float] | None:
    slope, inter = float(hdr["scl_slope"]), float(hdr["scl_inter"])
    if slope == 0.0 or np.isnan(slope):
        return None
    if not (np.isfinite(slope) and np.isfinite(inter)):
        raise error(
            f"{path}: scl_slope {slope!r} / scl_inter {inter!r}: the data scaling is not "
            "finite; fix the header"
        )
    return None if (slope, inter) == (1.0, 0.0) else (slope, inter)


def _text(value: Any) -> str:
    raw = bytes(np.asarray(value).tobytes())
    return raw.split(b"\0", 1)[0].decode("latin-1").strip()


def read_nifti(
    path: Path,
    *,
    max_bytes: int,
    error: ErrorType,
    refuse_ambiguous: bool = False,
    identity: bool = False,
) -> VolumeData:
    """One NIfTI volume, its geometry exact (module docstring) and its size bounded.

    Parameters
    ----------
    path : a regular file (the caller checked it).
    max_bytes : largest voxel data accepted, bytes (checked before allocating).
    error : the exception type raised, naming the file and the field.
    refuse_ambiguous : refuse a qform and sform that disagree (segmentations) instead of
        using the sform with a warning (CT).
    identity : int16 voxels are made HU (an integer scale applied, big-endian swapped),
        measured, sampled and hashed into the volume's identity as they are read
        (:class:`.identity.HuStream`): ``scaled``, ``value_range``, ``tail_sample`` and
        ``content_uid`` set.
    """
    with open_regular(path, what="NIfTI file", error=error) as fh:
        hdr = _header(path, fh, error)
        try:
            shape_f = tuple(int(n) for n in hdr.get_data_shape())
            dtype = np.dtype(hdr.get_data_dtype())
        except Exception as exc:  # nibabel: dim[0] out of range, unknown datatype, ...
            raise error(f"{path}: the NIfTI dim or datatype cannot be read ({exc})") from exc
        if any(n < 1 for n in shape_f):
            raise error(f"{path}: dim {shape_f} declares an empty axis; not a volume")
        if len(shape_f) > 3 and any(n != 1 for n in shape_f[3:]):
            raise error(
                f"{path}: a {len(shape_f)}-D volume (dim {shape_f}); ctdrill reads one 3-D "
                "volume: extract the time point or channel you mean"
            )
        if dtype.kind not in "uif" or dtype.itemsize > 8 or dtype.fields is not None:
            raise error(
                f"{path}: datatype {dtype} is not read (integer or real voxels only); save "
                "the volume as integers or floats"
            )
        shape_kji = tuple(reversed((*shape_f, 1, 1, 1)[:3]))
        nbytes = declared_bytes(
            shape_kji,
            dtype.itemsize,
            max_bytes=max_bytes,
            where=str(path),
            error=error,
            field="dim",
        )
        affine, tilt, warnings = _geometry(path, hdr, shape_kji, refuse_ambiguous, error)
        scale = _scale(path, hdr, error)
        offset = float(hdr["vox_offset"])
        minimum = int(hdr["sizeof_hdr"]) + 4
        if offset == 0.0:
            offset = float(minimum)
        if not (
            np.isfinite(offset) and offset.is_integer() and minimum <= offset <= MAX_VOX_OFFSET
        ):
            raise error(
                f"{path}: vox_offset {offset!r} is not a byte offset from {minimum} to "
                f"{MAX_VOX_OFFSET}; the header is damaged"
            )
        codec = _codec(fh)
        where = str(path)
        check_available(fh, codec=codec, nbytes=nbytes, skip=int(offset), where=where, error=error)
        fh.seek(0)
        prefix = None
        if codec == "gzip":  # ITK reads the header as inflated here (:mod:`.itk_header`)
            prefix = gunzip_prefix(fh, int(offset), where=where, error=error)
            fh.seek(0)
        check_itk_agrees(
            fh,
            affine,
            shape_kji,
            fmt="nifti",
            field=_field_of(affine, hdr),
            where=where,
            error=error,
            gzip=codec == "gzip",
            header_bytes=prefix,
        )
        fh.seek(0)
        data = allocate(shape_kji, dtype, where=where, error=error)
        uid = None
        value_range = None
        sample = None
        scaled = False
        whole = integer_scale(scale)
        if identity and dtype.kind == "i" and dtype.itemsize == 2 and (whole or not scale):
            step = tail_step(int(np.prod(shape_kji, dtype=np.int64)))
            with HuStream(data, affine, whole, sample_step=step) as stream:
                fill_array(
                    fh, data, codec=codec, skip=int(offset), where=where, error=error,
                    on_chunk=stream.feed,
                )  # fmt: skip
                done = stream.finish()
            data = data.view(data.dtype.newbyteorder("="))  # swapped as it was read
            if done is not None:
                data, uid, value_range, sample = done.hu, done.uid, done.value_range, done.sample
                scaled, scale = scale is not None, None
        else:
            fill_array(fh, data, codec=codec, skip=int(offset), where=where, error=error)
            data = native(data)
    return VolumeData(
        format="NIfTI-1" if int(hdr["sizeof_hdr"]) == NIFTI1_BYTES else "NIfTI-2",
        data=data,
        affine_lps=affine,
        scale=scale,
        tilt_deg=tilt,
        warnings=warnings,
        description=_text(hdr["descrip"]),
        content_uid=uid,
        scaled=scaled,
        value_range=None if value_range is None else (float(value_range[0]), float(value_range[1])),
        tail_sample=sample,
    )

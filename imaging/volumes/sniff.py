"""Which format a volume path holds, by its content: a DICOM folder or file, NIfTI, NRRD, MetaImage.

A folder is a DICOM series. A file is recognised by its first bytes, whatever its name:

- NIfTI-1 / NIfTI-2: ``sizeof_hdr`` 348 with magic ``n+1`` at byte 344, or 540 with ``n+2`` at
  byte 4 (either byte order), after gzip inflation when the file starts with ``1f 8b``;
- NRRD: the magic line ``NRRD000x`` (an attached ``.nrrd`` or a detached ``.nhdr``);
- DICOM: ``DICM`` at byte 128, or a data set without its preamble;
- MetaImage: a first line ``Key = Value`` with a MetaImage key, and ``NDims`` and
  ``ElementType`` in the header.

:func:`read_volume_file` reads NIfTI, NRRD and MetaImage into a :class:`.types.VolumeData`.
"""

from __future__ import annotations

from pathlib import Path

from ctdrill.imaging.volumes.bounded import gunzip_prefix
from ctdrill.imaging.volumes.metaimage import is_metaimage, read_metaimage
from ctdrill.imaging.volumes.nifti_file import NIFTI2_BYTES, nifti_header_bytes, read_nifti
from ctdrill.imaging.volumes.nrrd_file import is_nrrd, read_nrrd
from ctdrill.imaging.volumes.types import VolumeData
from ctdrill.safeio import open_regular

#: Bytes read to recognise a text header.
SNIFF_BYTES = 64 * 1024
#: The formats :func:`volume_format` names.
FORMATS = ("dicom", "nifti", "nrrd", "metaimage")

ErrorType = type[Exception]


def volume_format(path: str | Path, *, error: ErrorType, what: str = "CT volume") -> str:
    """``dicom``, ``nifti``, ``nrrd`` or ``metaimage``: what ``path`` holds, by content.

    Raises ``error`` naming the path when it is missing, not a regular file or folder, or a
    file of none of these formats.
    """
    p = Path(path)
    if p.is_dir():
        return "dicom"
    try:
        with open_regular(p, what=what, error=error) as fh:
            head = fh.read(SNIFF_BYTES)
            if head[:2] == b"\x1f\x8b":
                fh.seek(0)
                inner = gunzip_prefix(fh, NIFTI2_BYTES, where=str(p), error=error)
    except OSError as exc:
        raise error(f"{p}: cannot read the {what} ({exc.strerror or exc})") from exc
    if head[:2] == b"\x1f\x8b":
        if nifti_header_bytes(inner) is not None:
            return "nifti"
        raise error(
            f"{p}: a gzip-compressed file that holds no NIfTI header; a CT is read from a DICOM "
            "folder or file, NIfTI (.nii, .nii.gz), NRRD (.nrrd, .nhdr) or MetaImage (.mha, .mhd)"
        )
    if nifti_header_bytes(head) is not None:
        return "nifti"
    if is_nrrd(head):
        return "nrrd"
    if head[128:132] == b"DICM":
        return "dicom"
    if is_metaimage(head):
        return "metaimage"
    if _dicom_without_preamble(head):
        return "dicom"
    raise error(
        f"{p}: not a DICOM, NIfTI, NRRD or MetaImage file (by its content); give a DICOM "
        "folder or file, .nii/.nii.gz, .nrrd/.nhdr or .mha/.mhd (for a .mhd's .raw, name "
        "the .mhd)"
    )


def _dicom_without_preamble(head: bytes) -> bool:
    """A DICOM data set written without the 128-byte preamble: starts with a group 0x0002 or
    0x0008 element, little endian."""
    return len(head) >= 8 and head[1:2] == b"\x00" and head[0] in (0x02, 0x08) and head[3] == 0


def files_read(path: str | Path, *, error: ErrorType) -> tuple[Path, ...]:
    """The files a volume file's read opens: the file, and the data file of a detached NRRD
    (``.nhdr``) or MetaImage (``.mhd``) header. For a DICOM folder or file: ``(path,)`` (the
    caller walks a folder). A fingerprint of the inputs (``ctdrill batch``) covers these."""
    p = Path(path)
    kind = volume_format(p, error=error)
    if kind == "nrrd":
        from ctdrill.imaging.volumes.nrrd_file import data_file, read_nrrd_header

        with open_regular(p, what="NRRD file", error=error) as fh:
            header, _ = read_nrrd_header(p, fh, error)
        extra = data_file(p, header, error)
    elif kind == "metaimage":
        from ctdrill.imaging.volumes.metaimage import header_fields, metaimage_data_file

        extra = metaimage_data_file(p, header_fields(p, error), error)
    else:
        extra = None
    return (p,) if extra is None else (p, extra)


def read_volume_file(
    path: str | Path,
    *,
    max_bytes: int,
    error: ErrorType,
    refuse_ambiguous: bool = False,
    layers: bool = False,
    kind: str | None = None,
    identity: bool = False,
) -> VolumeData:
    """A NIfTI, NRRD or MetaImage file's voxels and geometry (its format by content).

    Parameters
    ----------
    path : the file.
    max_bytes : largest voxel data accepted, bytes, checked before allocating.
    error : the exception type raised, naming the file and the field.
    refuse_ambiguous : a NIfTI qform and sform that disagree are refused (segmentations), not
        warned about (CT).
    layers : a NRRD list axis (a 3D Slicer segmentation's layers) is kept.
    kind : the format when already known (:func:`volume_format`).
    identity : a CT's HU wanted: a NIfTI's int16 voxels are scaled (an integer scale), measured
        and hashed into the volume's identity as they are read (``VolumeData.content_uid``).
    """
    p = Path(path)
    fmt = kind or volume_format(p, error=error, what="volume file")
    try:
        if fmt == "nifti":
            return read_nifti(
                p,
                max_bytes=max_bytes,
                error=error,
                refuse_ambiguous=refuse_ambiguous,
                identity=identity,
            )
        if fmt == "nrrd":
            return read_nrrd(p, max_bytes=max_bytes, error=error, layers=layers)
        if fmt == "metaimage":
            return read_metaimage(p, max_bytes=max_bytes, error=error)
    except OSError as exc:  # a read that fails midway: name the file it failed on
        failed = exc.filename or p
        raise error(
            f"{p}: reading {failed} failed ({exc.strerror or exc}); check the file and its "
            "data file"
        ) from exc
    raise error(f"{p}: a DICOM file, not a NIfTI, NRRD or MetaImage volume")

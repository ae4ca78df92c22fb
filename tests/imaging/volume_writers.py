"""Volume files written by their own libraries (nibabel, pynrrd, SimpleITK) on a known LPS grid.

Shared by the loader, segmentation and CLI tests: each writer takes voxels ``(k, j, i)`` and
the LPS affine ``(i, j, k, 1) -> mm`` and stores them the way the format's reference library
does, so ctdrill's readers are checked against independent implementations.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np

#: LPS <-> RAS.
FLIP = np.diag([-1.0, -1.0, 1.0, 1.0])


def oblique_affine(
    spacing: tuple[float, float, float] = (0.75, 0.875, 1.25),
    origin: tuple[float, float, float] = (12.5, -30.25, -41.0),
    angle_deg: float = 30.0,
) -> np.ndarray:
    """An oblique, anisotropic grid in LPS (rotated about z and x, right-handed)."""
    a, b = np.radians(angle_deg), np.radians(angle_deg / 2)
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    out = np.eye(4)
    out[:3, :3] = rz @ rx @ np.diag(spacing)
    out[:3, 3] = origin
    return out


def ramp(shape_kji: tuple[int, int, int], dtype: Any = np.int16, lo: int = -1000) -> np.ndarray:
    """Distinct values per voxel from ``lo`` (so any axis mix-up shows)."""
    n = int(np.prod(shape_kji))
    return (np.arange(n) + lo).reshape(shape_kji).astype(dtype)


def every_corner_ijk(shape_kji: tuple[int, ...]) -> np.ndarray:
    """(M, 3) continuous indices (i, j, k) of every voxel corner (-1/2 .. n - 1/2)."""
    n_k, n_j, n_i = shape_kji[-3:]
    axes = [np.arange(n + 1) - 0.5 for n in (n_i, n_j, n_k)]
    return np.array(list(itertools.product(*axes)), dtype=np.float64)


def corners_lps(affine_lps: np.ndarray, ijk: np.ndarray) -> np.ndarray:
    """LPS mm of indices ``ijk`` (M, 3) through ``affine_lps``."""
    out: np.ndarray = ijk @ affine_lps[:3, :3].T + affine_lps[:3, 3]
    return out


def sitk_corners_lps(path: Path, ijk: np.ndarray) -> np.ndarray:
    """LPS mm that SimpleITK gives for indices ``ijk`` of the file at ``path``."""
    import SimpleITK as sitk

    reader = sitk.ImageFileReader()
    reader.SetFileName(str(path))
    reader.ReadImageInformation()
    img = sitk.Image([1, 1, 1], sitk.sitkUInt8)
    img.SetOrigin(reader.GetOrigin())
    img.SetSpacing(reader.GetSpacing())
    img.SetDirection(reader.GetDirection())
    return np.array([img.TransformContinuousIndexToPhysicalPoint(p.tolist()) for p in ijk])


def sitk_voxels(path: Path) -> np.ndarray:
    """The voxels SimpleITK reads, (k, j, i)."""
    import SimpleITK as sitk

    return np.asarray(sitk.GetArrayFromImage(sitk.ReadImage(str(path))))


def write_nifti(
    path: Path,
    data_kji: np.ndarray,
    affine_lps: np.ndarray,
    *,
    sform_code: int = 1,
    qform_code: int = 1,
    qform_lps: np.ndarray | None = None,
    slope: float | None = None,
    inter: float | None = None,
    descrip: bytes = b"",
    version: int = 1,
    endian: str = "<",
) -> Path:
    """A NIfTI file by nibabel: sform = ``affine_lps`` (in RAS), qform the same or ``qform_lps``."""
    import nibabel

    cls = nibabel.Nifti1Image if version == 1 else nibabel.Nifti2Image
    hdr_cls = nibabel.Nifti1Header if version == 1 else nibabel.Nifti2Header
    header = hdr_cls(endianness=endian)
    header.set_data_dtype(data_kji.dtype)
    img = cls(np.ascontiguousarray(data_kji.transpose(2, 1, 0)), FLIP @ affine_lps, header=header)
    img.set_sform(FLIP @ affine_lps, code=sform_code)
    img.set_qform(FLIP @ (affine_lps if qform_lps is None else qform_lps), code=qform_code)
    img.header.set_xyzt_units("mm")
    if descrip:
        img.header["descrip"] = descrip
    if slope is not None:
        img.header.set_slope_inter(slope, inter)
    nibabel.save(img, str(path))
    return path


def write_nrrd(
    path: Path,
    data_kji: np.ndarray,
    affine_lps: np.ndarray,
    *,
    space: str = "left-posterior-superior",
    encoding: str = "gzip",
    detached: bool = False,
    extra: dict[str, Any] | None = None,
) -> Path:
    """A NRRD file by pynrrd (``detached``: a .nhdr beside its data file)."""
    import nrrd

    world = affine_lps if space.startswith("left-posterior") else FLIP @ affine_lps
    header: dict[str, Any] = {
        "space": space,
        "space directions": world[:3, :3].T,
        "space origin": world[:3, 3],
        "kinds": ["domain"] * 3,
        "encoding": encoding,
        **(extra or {}),
    }
    nrrd.write(
        str(path), np.ascontiguousarray(data_kji), header, index_order="C", detached_header=detached
    )
    return path


def write_mha(
    path: Path, data_kji: np.ndarray, affine_lps: np.ndarray, *, compress: bool = False
) -> Path:
    """A MetaImage file by SimpleITK (``.mhd`` writes its ``.raw``/``.zraw`` beside)."""
    import SimpleITK as sitk

    img = sitk.GetImageFromArray(np.ascontiguousarray(data_kji))
    spacing = np.linalg.norm(affine_lps[:3, :3], axis=0)
    img.SetSpacing(spacing.tolist())
    img.SetOrigin(affine_lps[:3, 3].tolist())
    img.SetDirection((affine_lps[:3, :3] / spacing).ravel().tolist())
    sitk.WriteImage(img, str(path), useCompression=compress)
    return path


def edit_text_header(path: Path, old: str, new: str) -> None:
    """Replace ``old`` by ``new`` once in a text header (NRRD, MetaImage) before its data."""
    data = path.read_bytes()
    at = data.index(old.encode())
    path.write_bytes(data[:at] + new.encode() + data[at + len(old) :])

"""A witness for the whole test session: ITK agrees with ctdrill on every volume file read.

:func:`install` wraps the three readers ``read_volume_file`` dispatches to (NIfTI, NRRD,
MetaImage). After each file ctdrill *accepts*, SimpleITK reads the same path on its own (by
name, no help from ctdrill) and every voxel corner ctdrill uses must lie where ITK puts it.
``tests/conftest.py`` installs it for every test, so any research-format file any test makes
ctdrill accept is checked, not only the ones written for this purpose.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

#: Voxel corners within this of ITK's, mm (ITK's NIfTI qform is single precision).
WITNESS_TOL_MM = 1e-3
#: Files checked so far (path, format), for the tests that check the witness itself.
SEEN: list[tuple[str, str]] = []


def itk_affine_lps(path: Path) -> tuple[tuple[int, ...], np.ndarray]:
    """(size (i, j, k), (4, 4) LPS affine) SimpleITK reads from ``path``'s header."""
    import SimpleITK as sitk

    reader = sitk.ImageFileReader()
    reader.SetFileName(str(path))
    reader.ReadImageInformation()
    dim = reader.GetDimension()
    direction = np.asarray(reader.GetDirection(), dtype=np.float64).reshape(dim, dim)
    affine = np.eye(4)
    affine[:3, :3] = (direction * np.asarray(reader.GetSpacing()))[:3, :3]
    affine[:3, 3] = reader.GetOrigin()[:3]
    return tuple(int(n) for n in reader.GetSize()), affine


def _corners(affine: np.ndarray, shape_kji: tuple[int, ...]) -> np.ndarray:
    n_k, n_j, n_i = shape_kji
    ijk = np.array(
        [[i, j, k] for i in (-0.5, n_i - 0.5) for j in (-0.5, n_j - 0.5) for k in (-0.5, n_k - 0.5)]
    )
    out: np.ndarray = ijk @ affine[:3, :3].T + affine[:3, 3]
    return out


def check(path: Path, vol: Any) -> None:
    """Assert that ITK reads ``vol``'s grid from ``path`` (names ITK cannot recognise by
    extension are given to it under a recognisable one)."""
    import os
    import tempfile

    name = Path(path).name.lower()
    own = {
        "NIfTI-1": (".nii", ".nii.gz"),
        "NIfTI-2": (".nii", ".nii.gz"),
        "NRRD": (".nrrd", ".nhdr"),
        "MetaImage": (".mha", ".mhd"),
    }
    if name.endswith(own[vol.format]):
        size, affine = itk_affine_lps(path)
    else:  # content decides for ctdrill; ITK goes by the name
        ext = {"NIfTI-1": ".nii", "NRRD": ".nrrd", "MetaImage": ".mha"}[vol.format]
        with open(path, "rb") as fh:
            gz = fh.read(2) == b"\x1f\x8b"
        with tempfile.TemporaryDirectory() as tmp:
            link = os.path.join(tmp, "v" + ext + (".gz" if gz and ext == ".nii" else ""))
            os.symlink(os.path.abspath(path), link)
            size, affine = itk_affine_lps(Path(link))
    shape = vol.shape_kji
    assert size[:3] == tuple(reversed(shape)), f"{path}: ITK reads size {size}, ctdrill {shape}"
    apart = float(
        np.max(np.linalg.norm(_corners(vol.affine_lps, shape) - _corners(affine, shape), axis=1))
    )
    assert apart <= WITNESS_TOL_MM, f"{path}: ITK and ctdrill place voxels {apart} mm apart"
    SEEN.append((str(path), vol.format))


def install() -> Callable[[], None]:
    """Wrap the readers; returns the function that unwraps them."""
    from ctdrill.imaging.volumes import sniff

    originals = {n: getattr(sniff, n) for n in ("read_nifti", "read_nrrd", "read_metaimage")}

    def wrap(reader: Callable[..., Any]) -> Callable[..., Any]:
        def checked(path: Path, **kw: Any) -> Any:
            vol = reader(path, **kw)
            check(path, vol)
            return vol

        return checked

    for name, fn in originals.items():
        setattr(sniff, name, wrap(fn))

    def undo() -> None:
        for name, fn in originals.items():
            setattr(sniff, name, fn)

    return undo

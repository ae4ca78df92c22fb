"""The geometry ITK reads from a volume file's header: the arbiter of NIfTI, NRRD and MetaImage.

3D Slicer, ITK-SNAP and every ITK tool read these formats with ITK; where ctdrill's own reader
and ITK take different geometry from one header (a MetaImage with both ``Offset`` and
``Origin``, a NRRD with ``datafile`` and ``data file``, a NIfTI whose sform ITK will not take),
the surgeon would see the canal in one place in Slicer and be protected at another by ctdrill.
So every file is read twice: by ctdrill's bounded reader (sizes, compression ratio, header
fields bounded, geometry checked: :mod:`.bounded`, :mod:`.grid`) and, only once those checks
pass, by SimpleITK's ``ImageFileReader.ReadImageInformation`` (the header only, never the
voxels). The file is refused, naming the fields, when ITK refuses the header or when the two
grids differ: a different size, or a voxel corner more than :data:`ITK_AGREE_MM` apart.

ITK reads exactly the file ctdrill opened: it is handed ``/proc/self/fd/N`` of ctdrill's own
descriptor (opened without blocking and checked to be a regular file), through a link named
with the format's extension (ITK chooses its reader by name), so a path swapped for a FIFO
after the checks is never opened by ITK. A detached NRRD header is given to ITK with its data
file named the same way (the one ``data file`` line pointing at ctdrill's open data file). A
gzip NIfTI's header is given to ITK as ctdrill inflated it (header and extensions, up to
``vox_offset``), written aside as a ``.nii``: ITK's NIfTI reader reads the header only, but
through gzip it inflated about 3 ms of a small CT's voxels as well. The links and files live
in one private folder per process (created on first use, removed at exit), each call's
names its own.
"""

from __future__ import annotations

import atexit
import contextlib
import itertools
import os
import re
import shutil
import sys
import tempfile
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from ctdrill.imaging.volumes.grid import grid_corners_lps, grid_distance_mm

#: Largest distance between where ctdrill and ITK put a voxel corner, mm. ITK computes a
#: NIfTI qform in single precision: about 1e-5 mm over a CT; a misread field moves voxels by
#: a voxel or more.
ITK_AGREE_MM = 1e-3
#: ITK's reader for each format ctdrill sniffs.
_IMAGE_IO = {"nifti": "NiftiImageIO", "nrrd": "NrrdImageIO", "metaimage": "MetaImageIO"}
_PROC_FD = Path("/proc/self/fd")
#: What to do when ITK refuses a header, per format.
_HINT = {
    "nifti": "save it again as NIfTI-1 (.nii or .nii.gz) from 3D Slicer or SimpleITK",
    "nrrd": "save it again from 3D Slicer or SimpleITK",
    "metaimage": "save it again from 3D Slicer or SimpleITK",
}
#: Serialises the redirection of the process's stderr around ITK's header read.
_STDERR_LOCK = threading.Lock()
#: The process's folder of links and headers for ITK (:func:`_link_folder`), and its lock.
_FOLDER: dict[str, str] = {}
_FOLDER_LOCK = threading.Lock()
_NAMES = itertools.count()


def _link_folder() -> str:
    """The private folder (mode 0700) this process hands ITK its files in, made on first
    use and removed at exit (made again if it was removed meanwhile). A forked worker uses
    its parent's (every name carries the process id): it leaves without running exit
    handlers, so a folder of its own would stay behind."""
    with _FOLDER_LOCK:
        folder = _FOLDER.get("path")
        if folder is None or not os.path.isdir(folder):
            folder = tempfile.mkdtemp(prefix="ctdrill-itk-")
            _FOLDER["path"] = folder
            atexit.register(shutil.rmtree, folder, True)
        return folder


@contextlib.contextmanager
def _stderr_captured() -> Iterator[None]:
    """Descriptor 2 sent to a temporary file while ITK reads: its C libraries (niftilib,
    teem) print their own lines (``** ERROR: nifti_convert_nhdr2nim: bad datatype``) to
    stderr, and bad input gets exactly one ``error:`` line. The exception ITK raises carries
    the reason."""
    with _STDERR_LOCK, tempfile.TemporaryFile() as sink:
        try:
            sys.stderr.flush()
            saved = os.dup(2)
        except (OSError, ValueError, AttributeError):  # no descriptor 2 (embedded): as is
            yield
            return
        try:
            os.dup2(sink.fileno(), 2)
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)


ErrorType = type[Exception]


@dataclass(frozen=True, eq=False)
class ItkGrid:
    """What ITK read: ``size`` (i, j, k, ...), ``affine_lps`` (4, 4), its ``dimension``."""

    size: tuple[int, ...]
    affine_lps: np.ndarray
    dimension: int
    spacing: tuple[float, ...]
    origin: tuple[float, ...]


def _sitk() -> Any:
    import SimpleITK as sitk

    sitk.ProcessObject_SetGlobalWarningDisplay(False)  # ITK warnings go to stderr otherwise
    return sitk


def _fd_path(fh: IO[bytes]) -> str | None:
    if not _PROC_FD.is_dir():
        return None
    return f"{_PROC_FD}/{fh.fileno()}"


def _reason(exc: BaseException, names: dict[str, str]) -> str:
    """ITK's exception as one line: its last message line, temporary names replaced."""
    text = str(exc)
    for tmp, real in names.items():
        text = text.replace(tmp, real)
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    line = lines[-1] if lines else "unknown error"
    for ln in reversed(lines):
        if "ITK ERROR" in ln or "ERROR:" in ln or "[nrrd]" in ln:
            line = ln
            break
    line = re.sub(r"^.*?ITK ERROR:\s*", "", line)
    line = re.sub(r"^\w+ImageIO\(0x[0-9a-fA-F]+\):\s*", "", line)
    line = re.sub(r"^\w+ImageIO:\s*", "", line)
    return line[:300]


def itk_grid(
    fh: IO[bytes],
    *,
    fmt: str,
    where: str,
    error: ErrorType,
    gzip: bool = False,
    data_fh: IO[bytes] | None = None,
    header_text: str | None = None,
    header_bytes: bytes | None = None,
) -> ItkGrid:
    """The grid SimpleITK reads from the header of the open file ``fh`` (no voxels read).

    Parameters
    ----------
    fh : the volume file, opened by :func:`ctdrill.safeio.open_regular`.
    fmt : ``nifti``, ``nrrd`` or ``metaimage`` (ctdrill's sniffed format).
    where : the file's name, for messages.
    error : the exception type raised.
    gzip : a gzip-compressed NIfTI (named ``.nii.gz`` for ITK).
    data_fh, header_text : a detached NRRD's open data file and its header text: ITK is given
        this header with its one data file line naming ``data_fh``.
    header_bytes : a NIfTI's header and extensions (up to ``vox_offset``) as ctdrill read
        them, uncompressed: ITK reads these, written aside as a ``.nii``, instead of ``fh``.

    Raises
    ------
    error : ITK refuses the header (its message, one line).
    """
    sitk = _sitk()
    folder = _link_folder()
    stem = f"v{os.getpid()}-{next(_NAMES)}"
    names: dict[str, str] = {}
    made: list[str] = []
    try:
        if fmt == "nifti":
            name = f"{stem}.nii.gz" if gzip and header_bytes is None else f"{stem}.nii"
        elif fmt == "nrrd":
            name = f"{stem}.nhdr" if data_fh is not None else f"{stem}.nrrd"
        else:
            name = f"{stem}.mhd"
        link = os.path.join(folder, name)
        names[link] = where
        names[folder] = os.path.dirname(where) or "."
        source = _fd_path(fh)
        if header_bytes is not None:
            made.append(link)
            with open(link, "xb") as out:
                out.write(header_bytes)
        elif data_fh is not None and header_text is not None:
            data_source = _fd_path(data_fh)
            text = header_text
            if data_source is not None:
                made.append(os.path.join(folder, f"{stem}.data"))
                os.symlink(data_source, made[-1])
                text = re.sub(
                    r"(?im)^(data ?file)\s*:.*$", rf"\1: {stem}.data", header_text, count=1
                )
            made.append(link)
            with open(link, "w", encoding="latin-1") as out:
                out.write(text.rstrip("\n") + "\n")
        elif source is not None:
            made.append(link)
            os.symlink(source, link)
        else:  # no /proc: ITK opens the path itself
            link = where
        reader = sitk.ImageFileReader()
        reader.SetFileName(link)
        reader.SetImageIO(_IMAGE_IO[fmt])
        try:
            with _stderr_captured():
                reader.ReadImageInformation()
        except RuntimeError as exc:
            raise error(
                f"{where}: ITK (SimpleITK, the reader 3D Slicer uses) refuses the header: "
                f"{_reason(exc, names)}; 3D Slicer would not open this file, so ctdrill does "
                f"not guess where its voxels are: {_HINT[fmt]}"
            ) from None
        dim = int(reader.GetDimension())
        size = tuple(int(n) for n in reader.GetSize())
        spacing = tuple(float(v) for v in reader.GetSpacing())
        origin = tuple(float(v) for v in reader.GetOrigin())
        direction = np.asarray(reader.GetDirection(), dtype=np.float64).reshape(dim, dim)
    finally:
        for path in made:
            with contextlib.suppress(OSError):
                os.unlink(path)
    n = min(dim, 3)
    affine = np.eye(4)
    affine[:n, :n] = (direction * np.asarray(spacing)[None, :])[:n, :n]
    affine[:n, 3] = origin[:n]
    return ItkGrid(size, affine, dim, spacing, origin)


def check_itk_agrees(
    fh: IO[bytes],
    affine_lps: np.ndarray,
    shape_kji: tuple[int, ...],
    *,
    fmt: str,
    field: str,
    where: str,
    error: ErrorType,
    gzip: bool = False,
    data_fh: IO[bytes] | None = None,
    header_text: str | None = None,
    header_bytes: bytes | None = None,
) -> None:
    """Refuse the file unless ITK reads the grid ctdrill read (module docstring).

    Parameters
    ----------
    affine_lps, shape_kji : ctdrill's grid: (4, 4) ``(i, j, k, 1) -> LPS mm`` and (k, j, i).
    field : the header fields ctdrill's geometry came from, named in the refusal.
    The others as :func:`itk_grid`.
    """
    itk = itk_grid(
        fh,
        fmt=fmt,
        where=where,
        error=error,
        gzip=gzip,
        data_fh=data_fh,
        header_text=header_text,
        header_bytes=header_bytes,
    )
    ours_ijk = tuple(int(n) for n in reversed(shape_kji[-3:]))
    itk_ijk = itk.size[:3]
    extra = itk.size[3:]
    if itk.dimension < 3:
        itk_ijk = (*itk.size, *ours_ijk[itk.dimension :])
    if itk_ijk != ours_ijk or any(n != 1 for n in extra):
        raise error(
            f"{where}: ITK (SimpleITK, the reader 3D Slicer uses) reads {itk.size} voxels "
            f"(i, j, k) where ctdrill reads {ours_ijk}; the header is read differently by "
            "different tools: save it again from 3D Slicer or SimpleITK"
        )
    ours = np.asarray(affine_lps, dtype=np.float64)
    theirs = itk.affine_lps.copy()
    if itk.dimension < 3:  # ITK has no third axis: compare the first two and the origin
        theirs[:3, 2] = ours[:3, 2]
        theirs[2, :2] = ours[2, :2]
        theirs[2, 3] = ours[2, 3]
    apart = grid_distance_mm(ours, theirs, shape_kji)
    if apart <= ITK_AGREE_MM:
        return
    ours_sp = np.linalg.norm(ours[:3, :3], axis=0)
    theirs_sp = np.linalg.norm(theirs[:3, :3], axis=0)
    what = []
    if np.max(np.abs(ours[:3, 3] - theirs[:3, 3])) > ITK_AGREE_MM:
        what.append(f"origin {_vec(ours[:3, 3])} where ITK reads {_vec(theirs[:3, 3])}")
    if np.max(np.abs(ours_sp - theirs_sp)) > ITK_AGREE_MM:
        what.append(f"spacing {_vec(ours_sp)} where ITK reads {_vec(theirs_sp)}")
    if not what:
        corner = int(
            np.argmax(
                np.linalg.norm(
                    grid_corners_lps(ours, shape_kji) - grid_corners_lps(theirs, shape_kji), axis=1
                )
            )
        )
        what.append(f"axes that differ from ITK's (farthest at voxel corner {corner})")
    raise error(
        f"{where}: {field}: ctdrill reads {'; '.join(what)} (SimpleITK, the reader 3D Slicer "
        f"uses): voxels up to {apart:.4g} mm apart (tolerance {ITK_AGREE_MM:g} mm); the header "
        "is read differently by different tools, so where the voxels are is not known: save it "
        "again with one unambiguous geometry"
    )


def _vec(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.6g}" for v in np.asarray(values).reshape(-1)) + "]"

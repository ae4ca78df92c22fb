"""What a volume file reader returns, and its input error."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.provenance import LoadWarning

#: Most voxel bytes of a CT volume read from a file (the DICOM loader's default bound).
DEFAULT_MAX_BYTES = 2 * 1024**3


class VolumeFileError(ImagingInputError):
    """A volume file (NIfTI, NRRD, MetaImage) that cannot give an exact, bounded volume."""


@dataclass(frozen=True, eq=False)
class VolumeData:
    """The voxels of one volume file, as stored, and where they are.

    Attributes
    ----------
    format : ``NIfTI-1``, ``NIfTI-2``, ``NRRD`` or ``MetaImage``.
    data : (k, j, i) stored values in native byte order (a NRRD segmentation's layers first:
        (layers, k, j, i)); i is the file's fastest axis.
    affine_lps : (4, 4) ``(i, j, k, 1) -> LPS mm``, a proper grid (:mod:`.grid`).
    scale : ``(slope, intercept)`` the header asks to apply (NIfTI ``scl_slope`` /
        ``scl_inter``), or None.
    tilt_deg : lean of the slice axis off the slice normal, degrees.
    warnings : what the reader noticed (e.g. the NIfTI transform it chose).
    description : free text of the header (NIfTI ``descrip``, NRRD ``content``): may identify
        the patient; outputs carry it only with ``--include-phi``.
    fields : the header's other key/value pairs (NRRD), for segment names; same privacy.
    content_uid : the volume's identity (:func:`.identity.content_uid` of ``data`` and
        ``affine_lps``) when the reader hashed the voxels as it read them (a NIfTI's int16
        voxels, :class:`.identity.HuStream`), else None.
    scaled : ``data`` already holds the header's ``scl_slope``/``scl_inter`` applied (the
        reader applied an integer scale as it read; ``scale`` is then None).
    value_range : (min, max) of ``data`` when the reader measured it as it read, else None.
    tail_sample : ``data.reshape(-1)[::hu_values.tail_step(data.size)]`` when the reader took it
        as it read, else None.
    """

    format: str
    data: np.ndarray
    affine_lps: np.ndarray
    scale: tuple[float, float] | None = None
    tilt_deg: float = 0.0
    warnings: tuple[LoadWarning, ...] = ()
    description: str = ""
    fields: dict[str, str] = field(default_factory=dict)
    content_uid: str | None = None
    scaled: bool = False
    value_range: tuple[float, float] | None = None
    tail_sample: np.ndarray | None = None

    @property
    def shape_kji(self) -> tuple[int, int, int]:
        """The spatial shape (k, j, i)."""
        k, j, i = self.data.shape[-3:]
        return (int(k), int(j), int(i))


def native(arr: np.ndarray) -> np.ndarray:
    """``arr`` in the machine's byte order, swapped in place when it is not."""
    if arr.dtype.isnative:
        return arr
    arr.byteswap(inplace=True)
    return arr.view(arr.dtype.newbyteorder("="))

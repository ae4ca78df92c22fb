"""A grey-to-HU map on the loaded series: built, applied at the boundary, its HU error.

The map itself and its uncertainty belong to :mod:`ctdrill.imaging.dicom.grey`; this module
builds it from the options' :class:`~ctdrill.engine.settings.GreyMapSpec` on the series as
loaded, applies it before any sampling and hands the force band its HU error
(:class:`ctdrill.model.band.HuUncertainty`), with ``--hu-sigma``'s.
"""

from __future__ import annotations

import math

from ctdrill.engine.errors import ExportInputError
from ctdrill.engine.settings import GreyMapSpec
from ctdrill.imaging.dicom.grey import (
    GreyToHu,
    apply_grey_map,
    given_grey_map,
    grey_map_from_regions,
    sphere_region,
)
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.band import HuUncertainty
from ctdrill.numtext import number_text

#: Largest --hu-sigma accepted, HU: beyond it the CT numbers carry no information.
MAX_HU_SIGMA = 1000.0


def _option(spec: GreyMapSpec) -> str:
    """The option that gave ``spec``, with its values."""
    if spec.given is not None:
        return "--grey-to-hu " + ",".join(number_text(v) for v in spec.given)
    return "--grey-ref"


def build_grey_map(volume: CTVolume, spec: GreyMapSpec) -> GreyToHu:
    """The map of ``spec`` on ``volume`` (regions measured on its values as loaded)."""
    try:
        if spec.given is not None:
            g = spec.given
            return given_grey_map(*g) if len(g) == 4 else given_grey_map(g[0], g[1])
        return grey_map_from_regions([sphere_region(volume, c, r, hu) for c, r, hu in spec.regions])
    except ImagingInputError as exc:
        raise ExportInputError(f"--grey-to-hu/--grey-ref: {exc}") from None


def map_volume(volume: CTVolume, spec: GreyMapSpec | None) -> tuple[CTVolume, GreyToHu | None]:
    """``volume`` in HU through the map of ``spec`` (unchanged when None), and the map."""
    if spec is None:
        return volume, None
    grey_map = build_grey_map(volume, spec)
    try:
        return apply_grey_map(volume, grey_map), grey_map
    except ImagingInputError as exc:
        raise ExportInputError(f"{_option(spec)}: {exc}") from None


def hu_sigma_uncertainty(hu_sigma: float | None) -> HuUncertainty | None:
    """``--hu-sigma``'s HU uncertainty (None when not given); a bad value is exit 2."""
    if hu_sigma is None:
        return None
    if not (math.isfinite(hu_sigma) and 0.0 <= hu_sigma <= MAX_HU_SIGMA):
        raise ExportInputError(
            f"--hu-sigma must be a number of HU in [0, {MAX_HU_SIGMA:g}], got {hu_sigma!r}"
        )
    return HuUncertainty.offset(hu_sigma, f"--hu-sigma {hu_sigma:g} HU")


def hu_uncertainty(grey_map: GreyToHu | None, manual: HuUncertainty | None) -> HuUncertainty | None:
    """The HU error of the band: the map's (when known) and ``--hu-sigma``'s, independent."""
    out = manual
    if grey_map is not None:
        cov = grey_map.hu_error_cov()
        if cov is not None:
            mapped = HuUncertainty(cov, "grey-to-HU map")
            out = mapped if out is None else mapped.plus(out)
    return out

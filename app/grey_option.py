"""``--grey-to-hu`` / ``--grey-ref``: parse, build the map on the loaded series, apply it.

The map itself and its uncertainty belong to :mod:`ctdrill.imaging.dicom.grey`; this module
turns the command-line text into it, applies it to the volume at the boundary (before any
sampling) and hands the force band its HU error (:class:`ctdrill.model.band.HuUncertainty`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

from ctdrill.app.errors import AppInputError
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

_REF_RE = re.compile(r"^\s*([^=]+)=\s*(\S+)\s*$")


@dataclass(frozen=True)
class GreyMapSpec:
    """What the options asked for: numbers, or regions ``((x, y, z), r, hu)``."""

    given: tuple[float, ...] | None = None
    regions: tuple[tuple[tuple[float, float, float], float, float], ...] = ()


def _numbers(text: str, option: str, counts: Sequence[int]) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in counts or not all(math.isfinite(v) for v in values):
        raise AppInputError(
            f"{option} {text!r}: give {' or '.join(map(str, counts))} comma-separated numbers"
        )
    return values


def parse_grey_options(
    grey_to_hu: str | None, grey_ref: Sequence[str] | None
) -> GreyMapSpec | None:
    """The spec of ``--grey-to-hu`` or ``--grey-ref`` (None when neither is given)."""
    if grey_to_hu is not None and grey_ref:
        raise AppInputError("give --grey-to-hu or --grey-ref regions, not both")
    if grey_to_hu is not None:
        return GreyMapSpec(given=_numbers(grey_to_hu, "--grey-to-hu", (2, 4)))
    if not grey_ref:
        return None
    regions = []
    for text in grey_ref:
        m = _REF_RE.match(text)
        if m is None:
            raise AppInputError(f"--grey-ref {text!r}: give X,Y,Z,R=HU (LPS mm, radius mm, HU)")
        x, y, z, r = _numbers(m[1], "--grey-ref", (4,))
        (hu,) = _numbers(m[2], "--grey-ref HU", (1,))
        regions.append(((x, y, z), r, hu))
    if len(regions) < 2:
        raise AppInputError("--grey-ref: give at least two regions of known HU (e.g. air, insert)")
    return GreyMapSpec(regions=tuple(regions))


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
        raise AppInputError(f"--grey-to-hu/--grey-ref: {exc}") from None


def map_volume(volume: CTVolume, spec: GreyMapSpec | None) -> tuple[CTVolume, GreyToHu | None]:
    """``volume`` in HU through the map of ``spec`` (unchanged when None), and the map."""
    if spec is None:
        return volume, None
    grey_map = build_grey_map(volume, spec)
    try:
        return apply_grey_map(volume, grey_map), grey_map
    except ImagingInputError as exc:
        raise AppInputError(f"{_option(spec)}: {exc}") from None


def hu_uncertainty(grey_map: GreyToHu | None, manual: HuUncertainty | None) -> HuUncertainty | None:
    """The HU error of the band: the map's (when known) and ``--hu-sigma``'s, independent."""
    out = manual
    if grey_map is not None:
        cov = grey_map.hu_error_cov()
        if cov is not None:
            mapped = HuUncertainty(cov, "grey-to-HU map")
            out = mapped if out is None else mapped.plus(out)
    return out


def grey_line(doc: dict[str, object]) -> str | None:
    """The terminal line recording the map (None without one)."""
    g = doc.get("grey_to_hu")
    if not isinstance(g, dict):
        return None
    se = ""
    if g.get("slope_se") is not None:
        se = f" (SE {g['slope_se']:.3g}, {g['intercept_se']:.3g})"
    return f"grey-to-HU map: HU = {g['slope']:.6g} x grey + {g['intercept']:.6g}{se}; {g['method']}"

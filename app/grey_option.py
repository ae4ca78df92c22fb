"""``--grey-to-hu`` / ``--grey-ref``: the command-line text as a map's spec, and its line.

The spec (:class:`~ctdrill.engine.settings.GreyMapSpec`) is built into the map on the loaded
series and applied by :mod:`ctdrill.engine.grey`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

from ctdrill.app.errors import AppInputError
from ctdrill.engine.settings import GreyMapSpec
from ctdrill.engine.summary import GreyMapInfo

_REF_RE = re.compile(r"^\s*([^=]+)=\s*(\S+)\s*$")


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


def grey_line(grey: GreyMapInfo | None) -> str | None:
    """The terminal line recording the map (None without one)."""
    if grey is None:
        return None
    se = ""
    if grey.slope_se is not None and grey.intercept_se is not None:
        se = f" (SE {grey.slope_se:.3g}, {grey.intercept_se:.3g})"
    return f"grey-to-HU map: HU = {grey.slope:.6g} x grey + {grey.intercept:.6g}{se}; {grey.method}"

"""How outputs name a DICOM series without identifying the patient: the UID's hash.

A SeriesInstanceUID identifies one patient's scan world-wide (it often embeds the site's root,
the scanner and the date), and the study and series descriptions are free text that often
holds a name. No output carries them unless ``--include-phi`` asks: JSON outputs give
``series_uid`` as the SHA-256 that plans record (:func:`ctdrill.imaging.plan.types.
series_uid_hash`, its single owner) and ``series_uid_sha256`` always; text (warnings, errors,
``inspect``) names a series by that hash's first :data:`SHORT_HASH` hex digits, which
``--series`` accepts as it accepts the raw UID.
"""

from __future__ import annotations

import re

#: Hex digits of the hash that name a series in text.
SHORT_HASH = 12
#: Shortest hash prefix ``--series`` accepts.
MIN_PREFIX = 8
_HEX = re.compile(r"[0-9a-f]+")


def _hash(series_uid: str) -> str:
    from ctdrill.imaging.plan.types import series_uid_hash

    return series_uid_hash(series_uid)


def series_identity(series_uid: str, *, include_phi: bool) -> dict[str, str]:
    """``{"series_uid", "series_uid_sha256"}`` for a JSON output: the raw UID only with
    ``include_phi``, the hash otherwise."""
    digest = _hash(series_uid)
    return {"series_uid": series_uid if include_phi else digest, "series_uid_sha256": digest}


def series_label(series_uid: str) -> str:
    """How text names a series: the first :data:`SHORT_HASH` hex digits of its hash."""
    return _hash(series_uid)[:SHORT_HASH]


def matches_series(wanted: str, series_uid: str) -> bool:
    """True when ``wanted`` (``--series``) names ``series_uid``: the UID itself, its hash, or a
    prefix of at least :data:`MIN_PREFIX` hex digits of the hash."""
    text = wanted.strip()
    if text == series_uid:
        return True
    key = text.lower()
    return (
        len(key) >= MIN_PREFIX
        and _HEX.fullmatch(key) is not None
        and _hash(series_uid).startswith(key)
    )

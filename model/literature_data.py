"""The published points behind ``bone-literature``: which rows are fitted, which are not and why.

Reads ``bone_force_points.csv`` (``../shared/literature``; its README says what the points
support). :mod:`ctdrill.model.literature` fits them; every conversion is documented there and in
docs/model.md.
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
import re
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from ctdrill.model.errors import ModelInputError
from ctdrill.safeio import read_bytes_bounded

SET_NAME = "bone-literature"
#: The drill the set is for (the paper's; ctdrill's default drill): 2.0 mm, 900 rpm.
REF_DIAMETER_MM: float = 2.0
REF_RPM: float = 900.0
#: Thrust scales as diameter^p at a given feed per revolution (p = 1: lip length), +- SD.
DIAMETER_EXPONENT: tuple[float, float] = (1.0, 0.2)
#: Where the fit closes the open ends of the bone-density classes, HU: the least dense class
#: (Misch D5, "< 150") starts at water, 0 HU; the densest (D1, "> 1250", the HU assigned to
#: cortical bone, which the thrust studies do not report) ends at 2000 HU, dense cortical bone
#: on clinical CT. A class gets its range's midpoint +- width / sqrt(12).
OPEN_LOW_HU: float = 0.0
OPEN_HIGH_HU: float = 2000.0
#: Cortical thrust points with diameter, feed and speed stated, and why each is used.
THRUST_KEYS: Mapping[str, str] = {
    "MacAvelia2012_human_1000": "human cortical femur, 3.2 mm, 2 mm/s, 1000 rpm",
    "MacAvelia2012_human_1250": "human cortical femur, 3.2 mm, 2 mm/s, 1250 rpm",
    "MacAvelia2012_human_1500": "human cortical femur, 3.2 mm, 2 mm/s, 1500 rpm",
    "HSBD2020_JBSMSE": "bone, 2 mm drill, 0.833 mm/s, 12000 rpm",
    "PorcineFemur2014_min": "porcine cortical femur, 5 mm, 0.5 mm/s, 1200 rpm",
    "PorcineFemur2014_max": "porcine cortical femur, 5 mm, 1.167 mm/s, 500 rpm",
}
#: Drilling torque at Misch classes (bovine rib, one study, r = 0.99 with CT value).
TORQUE_KEYS: tuple[str, ...] = (
    "BovineRib_torque_D2",
    "BovineRib_torque_D3",
    "BovineRib_torque_D4",
    "BovineRib_torque_D5",
)
#: Rows not fitted, by source_key prefix, and why.
EXCLUDED: Mapping[str, str] = {
    "MacAvelia2012_artificial": "artificial femur: not bone",
    "Orelaja2020_artificial": "artificial femur: not bone",
    "Orelaja2020_": "feed rate not stated: the feed per revolution is unknown",
    "PorcineFemur2014_middle": "pooled over 3 speeds x 3 feeds: no single condition",
    "PorcineFemur2014_range": "a range over conditions, not a point",
    "DogJaw_": "a range over unstated speeds, feeds and drill sizes (kept as a check)",
    "Table6_": "secondary range with no drilling conditions",
    "AbouzgiaJames1997": "force-controlled: the load is an input, not a measured response",
    "AppliedLoad_": "applied load (an input), not a measured response",
    "ABJS_feed_ratio": "relative only (no absolute force), speed not stated (kept as a check)",
    "IT_": "implant insertion torque: thread engagement, not drilling",
}
#: Largest literature file read, bytes.
MAX_LITERATURE_BYTES: int = 4 * 1024 * 1024

_TORQUE_RE = re.compile(r"torque\s+([0-9.]+)\s*±\s*([0-9.]+)\s*N·cm")
_SITES_RE = re.compile(r"n\s*=\s*(\d+)\s*sites")


class LiteratureError(ModelInputError):
    """The literature file is missing, unreadable or lacks a point the fit needs."""


def class_hu_ranges(
    bands_hu: Sequence[tuple[str, float, float]],
) -> dict[str, tuple[float, float]]:
    """The density classes as closed HU ranges: ``bands_hu`` (``(class, low HU, high HU)``,
    densest first, the outer ends open, as :data:`ctdrill.imaging.misch.MISCH_BANDS_HU`: the
    bands' one owner, which the caller passes in) with the open ends closed at
    :data:`OPEN_LOW_HU` and :data:`OPEN_HIGH_HU`.

    Raises
    ------
    LiteratureError
        Bands that are not densest first, adjoining, with only the outer ends open.
    """
    if not bands_hu:
        raise LiteratureError("no density classes given")
    ranges: dict[str, tuple[float, float]] = {}
    for i, (name, lo, hi) in enumerate(bands_hu):
        first, last = i == 0, i == len(bands_hu) - 1
        if (math.isinf(hi) and not first) or (math.isinf(lo) and not last) or not lo < hi:
            raise LiteratureError(f"density class {name!r}: HU band ({lo:g}, {hi:g}) out of order")
        if not last and bands_hu[i + 1][2] != lo:
            raise LiteratureError(
                f"density classes {name!r} and {bands_hu[i + 1][0]!r} do not adjoin"
            )
        ranges[name] = (
            OPEN_LOW_HU if math.isinf(lo) else lo,
            OPEN_HIGH_HU if math.isinf(hi) else hi,
        )
    return ranges


@dataclass(frozen=True)
class ThrustPoint:
    key: str
    thrust_n: float
    diameter_mm: float
    feed_mm_s: float
    rpm: float


@dataclass(frozen=True)
class TorquePoint:
    key: str
    misch: str
    torque_ncm: float
    sd_ncm: float
    sites: int


@dataclass(frozen=True)
class LiteratureData:
    """The rows the fit uses and those it leaves out (with reasons)."""

    thrust: tuple[ThrustPoint, ...]
    torque: tuple[TorquePoint, ...]
    excluded: tuple[tuple[str, str], ...]
    sha256: str
    file_name: str


def _float(row: Mapping[str, str], col: str, path: Path) -> float:
    text = (row.get(col) or "").strip()
    try:
        value = float(text)
    except ValueError:
        raise LiteratureError(
            f"{path}: row {row.get('source_key')!r} column {col} must be one number, got "
            f"{text[:30]!r}"
        ) from None
    if not (math.isfinite(value) and value > 0.0):
        raise LiteratureError(f"{path}: row {row.get('source_key')!r} column {col} must be > 0")
    return value


def read_literature(path: str | Path, classes: Collection[str]) -> LiteratureData:
    """Parse ``bone_force_points.csv``: the fitted points and every other row's exclusion.

    ``classes`` are the density classes a torque point may name (the Misch classes).

    Raises
    ------
    LiteratureError
        The file is unreadable, lacks a column or a point of :data:`THRUST_KEYS` /
        :data:`TORQUE_KEYS`, names a class not in ``classes``, or holds a row neither used nor
        excluded.
    """
    p = Path(path)
    raw = read_bytes_bounded(
        p, what="literature file", error=LiteratureError, max_bytes=MAX_LITERATURE_BYTES
    )
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise LiteratureError(f"{p}: not UTF-8 text ({exc.reason})") from None
    rows = list(csv.DictReader(io.StringIO(text)))
    needed = {"source_key", "thrust_n", "diameter_mm", "feed_mm_s", "rpm", "derived_note"}
    if not rows or not needed <= set(rows[0]):
        raise LiteratureError(f"{p}: needs the columns {sorted(needed)}")
    by_key = {r["source_key"]: r for r in rows}
    thrust, torque, excluded = [], [], []
    for key in THRUST_KEYS:
        r = by_key.get(key)
        if r is None:
            raise LiteratureError(f"{p}: no row {key!r}; the fit needs it")
        thrust.append(
            ThrustPoint(
                key,
                _float(r, "thrust_n", p),
                _float(r, "diameter_mm", p),
                _float(r, "feed_mm_s", p),
                _float(r, "rpm", p),
            )
        )
    for key in TORQUE_KEYS:
        r = by_key.get(key)
        if r is None:
            raise LiteratureError(f"{p}: no row {key!r}; the fit needs it")
        m, s = _TORQUE_RE.search(r["derived_note"]), _SITES_RE.search(r.get("material", ""))
        misch = (r.get("density_value") or "").strip()
        if m is None or s is None or misch not in classes:
            raise LiteratureError(
                f"{p}: row {key!r}: torque 'T±SD N·cm', 'n=N sites' or Misch class not found"
            )
        torque.append(TorquePoint(key, misch, float(m[1]), float(m[2]), int(s[1])))
    for key in by_key:
        if key in THRUST_KEYS or key in TORQUE_KEYS:
            continue
        reason = next((why for pre, why in EXCLUDED.items() if key.startswith(pre)), None)
        if reason is None:
            raise LiteratureError(
                f"{p}: row {key!r} is neither fitted nor excluded with a reason; classify it "
                "in ctdrill.model.literature (THRUST_KEYS, TORQUE_KEYS or EXCLUDED)"
            )
        excluded.append((key, reason))
    return LiteratureData(
        tuple(thrust), tuple(torque), tuple(excluded), hashlib.sha256(raw).hexdigest(), p.name
    )

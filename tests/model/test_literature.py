"""bone-literature: the committed set is what the fit gives on ../shared/literature."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ctdrill.hu import AIR_HU
from ctdrill.imaging.misch import BONE_HU, MISCH_BANDS_HU, MISCH_CLASSES
from ctdrill.model.calibration import CALIBRATION_DIR, load_calibration
from ctdrill.model.literature import (
    EXCLUDED,
    OPEN_HIGH_HU,
    OPEN_LOW_HU,
    THRUST_KEYS,
    TORQUE_KEYS,
    LiteratureError,
    class_hu_ranges,
    converted_thrust,
    fit_literature,
    read_literature,
)
from tests.conftest import SHARED
from tests.model.fitcompare import assert_same_fit

LITERATURE = SHARED / "literature" / "bone_force_points.csv"


@pytest.fixture(scope="module")
def fitted() -> dict[str, Any]:
    assert LITERATURE.is_file(), f"literature data missing: {LITERATURE}"
    return fit_literature(LITERATURE, bands_hu=MISCH_BANDS_HU, gate_hu=BONE_HU)


def test_committed_set_is_reproduced_by_the_fit(fitted: dict[str, Any]) -> None:
    committed = json.loads((CALIBRATION_DIR / "bone-literature.json").read_text("utf-8"))
    assert_same_fit(json.loads(json.dumps(fitted)), committed)


def test_set_loads_with_its_covariance_and_standard_errors(fitted: dict[str, Any]) -> None:
    cal = load_calibration("bone-literature")
    assert not cal.illustrative and cal.method is not None and "literature" in cal.method
    cov = cal.covariance
    assert cov is not None and cov.parameters == ("a0.b0", "a0.n", "a0.ke")
    m = cov.array()
    np.testing.assert_array_equal(m, m.T)
    assert np.linalg.eigvalsh(m)[0] > 0.0
    for key in cov.parameters:
        assert cov.stderr(key) == pytest.approx(fitted["fit"][key]["stderr"], rel=1e-5)
    # the set is for the reference drill and the equivalent feeds it was fitted on
    assert cal.feed_range_mm_s == pytest.approx((0.833 * 900 / 12000, 1.167 * 900 / 500), rel=1e-3)


def test_every_row_is_used_or_excluded_with_a_reason() -> None:
    data = read_literature(LITERATURE, MISCH_CLASSES)
    with LITERATURE.open(encoding="utf-8") as fh:
        keys = [r["source_key"] for r in csv.DictReader(fh)]
    used = {p.key for p in data.thrust} | {t.key for t in data.torque}
    assert used == set(THRUST_KEYS) | set(TORQUE_KEYS)
    assert sorted(used | {k for k, _ in data.excluded}) == sorted(keys)
    assert len(keys) == 42 and len(data.excluded) == 32
    assert all(why for _, why in data.excluded)


def test_an_unclassified_row_is_refused(tmp_path: Path) -> None:
    text = LITERATURE.read_text("utf-8")
    rows = list(csv.DictReader(io.StringIO(text)))
    extra = dict(rows[0], source_key="NewStudy2030")
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows([*rows, extra])
    path = tmp_path / "points.csv"
    path.write_text(buf.getvalue(), "utf-8")
    with pytest.raises(LiteratureError, match=r"NewStudy2030.*neither fitted nor excluded"):
        read_literature(path, MISCH_CLASSES)
    missing = tmp_path / "missing.csv"
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows([r for r in rows if r["source_key"] != "HSBD2020_JBSMSE"])
    missing.write_text(buf.getvalue(), "utf-8")
    with pytest.raises(LiteratureError, match=r"HSBD2020_JBSMSE.*the fit needs it"):
        read_literature(missing, MISCH_CLASSES)


def test_conversions_by_hand() -> None:
    data = read_literature(LITERATURE, MISCH_CLASSES)
    mac = next(p for p in data.thrust if p.key == "MacAvelia2012_human_1000")
    assert converted_thrust(mac, 1.0) == pytest.approx((198.4 * 2.0 / 3.2, 2.0 * 900 / 1000))
    pig = next(p for p in data.thrust if p.key == "PorcineFemur2014_max")
    assert converted_thrust(pig, 1.0) == pytest.approx((139.84 * 0.4, 1.167 * 900 / 500))
    d2 = next(t for t in data.torque if t.key == "BovineRib_torque_D2")
    assert (d2.misch, d2.torque_ncm, d2.sd_ncm, d2.sites) == ("D2", 11.2, 3.2, 87)


def test_class_ranges_close_the_open_ends_of_the_bands_given() -> None:
    ranges = class_hu_ranges(MISCH_BANDS_HU)
    assert ranges == {
        "D1": (1250.0, OPEN_HIGH_HU),
        "D2": (850.0, 1250.0),
        "D3": (350.0, 850.0),
        "D4": (150.0, 350.0),
        "D5": (OPEN_LOW_HU, 150.0),
    }
    inf = math.inf
    assert class_hu_ranges((("A", 100.0, inf), ("B", -inf, 100.0))) == {
        "A": (100.0, OPEN_HIGH_HU),
        "B": (OPEN_LOW_HU, 100.0),
    }
    with pytest.raises(LiteratureError, match="do not adjoin"):
        class_hu_ranges((("A", 100.0, inf), ("B", -inf, 90.0)))
    with pytest.raises(LiteratureError, match="out of order"):
        class_hu_ranges((("B", -inf, 100.0), ("A", 100.0, inf)))


def test_the_fit_takes_the_bands_and_the_gate_it_is_given() -> None:
    # the bands are imaging's (imaging/misch.py); moving the D3/D4 edge moves the HU the D3
    # and D4 torque points are assigned, and the gate is the one passed in
    moved = tuple(
        (name, 400.0 if lo == 350.0 else lo, 400.0 if hi == 350.0 else hi)
        for name, lo, hi in MISCH_BANDS_HU
    )
    doc = fit_literature(LITERATURE, bands_hu=moved, gate_hu=BONE_HU + 10.0)
    hu = {p["misch"]: p["hu_assigned"] for p in doc["provenance"]["points_used"] if "misch" in p}
    assert hu == {"D2": 1050.0, "D3": 625.0, "D4": 275.0, "D5": 75.0}
    assert doc["gate_hu"] == BONE_HU + 10.0
    with pytest.raises(LiteratureError, match=r"BovineRib_torque_D2.*Misch class"):
        fit_literature(LITERATURE, bands_hu=moved[2:], gate_hu=BONE_HU)


def test_cortical_assignment_moves_the_level_by_n_dlog10_c(fitted: dict[str, Any]) -> None:
    # Only the thrust points carry the cortical HU, and n comes from the torque slope alone, so
    # shifting the assignment by one SD moves b0 by n * d log10 C' and nothing else.
    lo, hi = class_hu_ranges(MISCH_BANDS_HU)["D1"]
    sd = (hi - lo) / math.sqrt(12.0)
    mid = (lo + hi) / 2.0 - AIR_HU
    n = fitted["a0"]["n"]
    expected = n * (math.log10(mid + sd) - math.log10(mid - sd)) / 2.0
    got = fitted["provenance"]["stderr_systematic"]["cortical_hu"]
    assert got["b0"] == pytest.approx(expected, rel=1e-5)  # stored to 6 digits
    assert got["n"] < 1e-6 and got["ke"] < 1e-6


def test_excluded_reasons_cover_every_prefix_used() -> None:
    data = read_literature(LITERATURE, MISCH_CLASSES)
    prefixes = {next(p for p in EXCLUDED if k.startswith(p)) for k, _ in data.excluded}
    assert prefixes == set(EXCLUDED)

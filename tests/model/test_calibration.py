"""Calibration sets: the bundled numbers, name/path resolution, validation messages."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ctdrill.model import (
    Calibration,
    CalibrationError,
    ModelInputError,
    harmonic_freqs_hz,
    load_calibration,
)
from ctdrill.model.calibration import CALIBRATION_DIR, calibration_from_dict, calibration_to_dict

PINE: dict[str, Any] = {
    "name": "pine-wood-paper",
    "material": "pine wood",
    "source": "seed paper, Tables 2-3, Eq. 20-22",
    "c_prime_range": [100, 1000],
    "gate_hu": -900,
    "gate_width_hu": 50,
    "a0": {"b0": -1.35, "n": 0.77, "ke": 0.25},
    "harmonics": [{"order": 1, "b0": 3.92, "n": -1.91}, {"order": 2, "b0": 1.72, "n": -1.29}],
}


def test_pine_wood_set_is_the_papers_eq_20_22() -> None:
    cal = load_calibration("pine-wood-paper")
    assert cal.c_prime_range == (100.0, 1000.0)
    assert (cal.gate_hu, cal.gate_width_hu) == (-900.0, 50.0)
    assert (cal.a0.b0, cal.a0.n, cal.ke_per_mm_s) == (-1.35, 0.77, 0.25)
    assert [(h.order, h.b0, h.n) for h in cal.harmonics] == [(1, 3.92, -1.91), (2, 1.72, -1.29)]
    assert not cal.illustrative


def test_bone_set_matches_design_and_is_labelled_illustrative() -> None:
    cal = load_calibration("bone-illustrative")
    assert cal.c_prime_range == (1100.0, 3100.0)
    assert (cal.gate_hu, cal.gate_width_hu) == (150.0, 50.0)
    assert (cal.a0.b0, cal.a0.n, cal.ke_per_mm_s) == (-5.9535, 2.0, 0.25)
    assert [(h.order, h.b0, h.n) for h in cal.harmonics] == [
        (1, 5.9638, -1.91),
        (2, 3.1928, -1.29),
    ]
    assert cal.illustrative
    # Anchor of DESIGN.md: 8.0 N for cortical bone (HU 1500, C' 2500) at 0.6 mm/s.
    assert 10**cal.a0.b0 * 2500.0**2 * (1 + 0.25 * 0.6) == pytest.approx(8.0, rel=1e-4)
    # Harmonics keep the pine-wood exponents, and the ratios B/A0 of pine wood at C' = 300
    # hold for bone at the anchor (C' = 2500).
    pine = load_calibration("pine-wood-paper")
    a0_pine = 10**pine.a0.b0 * 300**pine.a0.n
    a0_bone = 10**cal.a0.b0 * 2500**cal.a0.n
    for hp, hb in zip(pine.harmonics, cal.harmonics, strict=True):
        assert hb.n == hp.n
        assert 10**hb.b0 * 2500**hb.n / a0_bone == pytest.approx(
            10**hp.b0 * 300**hp.n / a0_pine, rel=1e-3
        )


def test_bundled_names_resolve_relative_to_the_package() -> None:
    assert (
        Path(__file__).resolve().parents[2] / "assets" / "calibration" == CALIBRATION_DIR.resolve()
    )
    assert {"pine-wood-paper", "bone-illustrative"} <= {p.stem for p in CALIBRATION_DIR.glob("*")}


def test_path_and_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "mine.json"
    path.write_text(json.dumps(calibration_to_dict(load_calibration("pine-wood-paper"))))
    assert load_calibration(path) == load_calibration("pine-wood-paper")
    assert load_calibration(str(path)) == load_calibration("pine-wood-paper")


def test_extra_fit_block_is_accepted(tmp_path: Path) -> None:
    doc = dict(PINE, fit={"a0.n": {"value": 0.77, "stderr_pct": 2.35}})
    path = tmp_path / "fitted.json"
    path.write_text(json.dumps(doc))
    assert load_calibration(path).a0.n == 0.77


def test_harmonic_freqs_from_the_drill() -> None:
    cal = load_calibration("pine-wood-paper")
    np.testing.assert_array_equal(harmonic_freqs_hz(cal, blades=2, rpm=900), [30.0, 60.0])
    np.testing.assert_array_equal(harmonic_freqs_hz(cal, blades=3, rpm=1200), [60.0, 120.0])


@pytest.mark.parametrize(("blades", "rpm"), [(0, 900), (2, 0), (2, -5), (2, float("nan"))])
def test_harmonic_freqs_reject_bad_drill(blades: int, rpm: float) -> None:
    with pytest.raises(ModelInputError, match="drill"):
        harmonic_freqs_hz(load_calibration("pine-wood-paper"), blades=blades, rpm=rpm)


def test_unknown_name_lists_the_available_sets() -> None:
    with pytest.raises(CalibrationError, match="pine-wood-paper") as info:
        load_calibration("no-such-set")
    assert "no-such-set" in str(info.value)


def test_missing_file_names_it(tmp_path: Path) -> None:
    with pytest.raises(CalibrationError, match=r"nothere\.json"):
        load_calibration(tmp_path / "nothere.json")


def test_bad_json_names_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "broken.json"
    path.write_text('{"name": "x",\n "a0": }')
    with pytest.raises(CalibrationError, match=r"broken\.json.*line 2"):
        load_calibration(path)


def _mutated(**changes: Any) -> dict[str, Any]:
    doc = json.loads(json.dumps(PINE))
    for key, value in changes.items():
        if value is None:
            doc.pop(key)
        else:
            doc[key] = value
    return doc


@pytest.mark.parametrize(
    ("doc", "field"),
    [
        (_mutated(c_prime_range=[0, 1000]), "c_prime_range"),
        (_mutated(c_prime_range=[500, 100]), "c_prime_range"),
        (_mutated(c_prime_range=[100]), "c_prime_range"),
        (_mutated(gate_width_hu=0), "gate_width_hu"),
        (_mutated(gate_hu="low"), "gate_hu"),
        (_mutated(gate_hu=None), "gate_hu"),
        (_mutated(material=None), "material"),
        (_mutated(a0={"b0": -1.35, "n": 0.77}), "a0.ke"),
        (_mutated(a0={"b0": -1.35, "n": 0.77, "ke": -1}), "a0.ke"),
        (_mutated(a0={"b0": True, "n": 0.77, "ke": 0.25}), "a0.b0"),
        (_mutated(harmonics=[{"order": 0, "b0": 1, "n": 1}]), "harmonics[0].order"),
        (_mutated(harmonics=[{"order": 1, "b0": 1}]), "harmonics[0].n"),
        (
            _mutated(harmonics=[{"order": 1, "b0": 1, "n": 1}, {"order": 1, "b0": 1, "n": 1}]),
            "harmonics",
        ),
        ([1, 2], "top level"),
    ],
)
def test_invalid_fields_are_named_with_the_file(tmp_path: Path, doc: Any, field: str) -> None:
    path = tmp_path / "bad-set.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(CalibrationError) as info:
        load_calibration(path)
    assert field in str(info.value)
    assert "bad-set.json" in str(info.value)


def test_non_finite_numbers_are_rejected() -> None:
    doc = _mutated(gate_hu=float("inf"))
    with pytest.raises(CalibrationError, match="gate_hu must be finite"):
        calibration_from_dict(doc, source_path="x.json")


def test_harmonics_sorted_by_order() -> None:
    doc = _mutated(harmonics=list(reversed(PINE["harmonics"])))
    cal: Calibration = calibration_from_dict(doc)
    assert [h.order for h in cal.harmonics] == [1, 2]


def test_integer_beyond_float_range_is_refused_in_one_line() -> None:
    with pytest.raises(CalibrationError, match="gate_hu must be finite") as info:
        calibration_from_dict(_mutated(gate_hu=10**400), source_path="big.json")
    assert "\n" not in str(info.value)
    doc = _mutated(harmonics=[{"order": 10**5000, "b0": 1.0, "n": -1.0}])
    with pytest.raises(CalibrationError, match=r"harmonics\[0\]\.order") as info:
        calibration_from_dict(doc, source_path="big.json")
    assert len(str(info.value)) < 300


@pytest.mark.parametrize(
    ("a0", "field"),
    [
        ({"b0": 400.0, "n": 0.77, "ke": 0.25}, "a0"),
        ({"b0": -1.35, "n": 500.0, "ke": 0.25}, "a0"),
        ({"b0": -1.35, "n": 0.77, "ke": 1e308}, "a0.ke"),
    ],
)
def test_laws_that_would_overflow_are_refused(a0: dict[str, float], field: str) -> None:
    with pytest.raises(CalibrationError, match=field):
        calibration_from_dict(_mutated(a0=a0), source_path="x.json")


@pytest.mark.parametrize(
    ("a0", "message"),
    [
        ({"b0": -400.0, "n": 0.77, "ke": 0.25}, "less than 1e-06 N everywhere"),
        ({"b0": -1.35, "n": -400.0, "ke": 0.25}, r"a0\.n must be within \[-50, 50\]"),
        ({"b0": -1.35, "n": -1e308, "ke": 0.25}, r"a0\.n must be within"),
    ],
)
def test_laws_that_vanish_or_have_absurd_exponents_are_refused(
    a0: dict[str, float], message: str
) -> None:
    with pytest.raises(CalibrationError, match=message):
        calibration_from_dict(_mutated(a0=a0), source_path="x.json")


def test_a_vanishing_harmonic_is_refused_by_its_index() -> None:
    doc = _mutated(harmonics=[{"order": 1, "b0": -400.0, "n": -1.91}])
    with pytest.raises(CalibrationError, match=r"harmonics\[0\] gives less than"):
        calibration_from_dict(doc, source_path="x.json")


COV_OK: dict[str, Any] = {
    "parameters": ["a0.b0", "a0.n", "a0.ke"],
    "matrix": [[2.0, -0.5, 0.1], [-0.5, 0.2, 0.0], [0.1, 0.0, 4.0]],
}


def test_old_sets_load_unchanged_without_covariance() -> None:
    for name in ("pine-wood-paper", "bone-illustrative"):
        cal = load_calibration(name)
        assert cal.covariance is None and cal.method is None
        doc = json.loads((CALIBRATION_DIR / f"{name}.json").read_text("utf-8"))
        assert calibration_from_dict(calibration_to_dict(cal)) == cal == calibration_from_dict(doc)
        assert "covariance" not in calibration_to_dict(cal)


def test_covariance_round_trips() -> None:
    doc = dict(PINE, covariance=COV_OK, provenance={"method": "a test", "other": [1, 2]})
    cal = calibration_from_dict(doc)
    assert cal.covariance is not None and cal.method == "a test"
    assert cal.covariance.stderr("a0.n") == pytest.approx(0.2**0.5)
    again = calibration_from_dict(calibration_to_dict(cal))
    assert again == cal


@pytest.mark.parametrize(
    ("cov", "field"),
    [
        ("x", "covariance must be an object"),
        ({"parameters": [], "matrix": []}, "covariance.parameters must be a non-empty list"),
        ({"parameters": ["a0.q"], "matrix": [[1.0]]}, r"covariance.parameters\[0\] names 'a0.q'"),
        ({"parameters": ["a0.n", "a0.n"], "matrix": [[1, 0], [0, 1]]}, "repeats a name"),
        ({"parameters": ["a0.n", "a0.b0"], "matrix": [[1.0, 0.0]]}, "must be a 2 x 2"),
        ({"parameters": ["a0.n", "a0.b0"], "matrix": [[1.0], [0.0, 1.0]]}, r"matrix\[0\] must"),
        ({"parameters": ["a0.n"], "matrix": [["1"]]}, r"matrix\[0\]\[0\] must be a number"),
        ({"parameters": ["a0.n"], "matrix": [[1e400]]}, r"matrix\[0\]\[0\] must be finite"),
        ({"parameters": ["a0.n"], "matrix": [[-1.0]]}, r"matrix\[0\]\[0\] is a variance"),
        (
            {"parameters": ["a0.n", "a0.b0"], "matrix": [[1.0, 0.5], [0.4, 1.0]]},
            r"matrix\[0\]\[1\] \(0.5\) differs from covariance.matrix\[1\]\[0\]",
        ),
        (
            {"parameters": ["a0.n", "a0.b0"], "matrix": [[1.0, 2.0], [2.0, 1.0]]},
            "covariance.matrix is not positive semi-definite",
        ),
    ],
)
def test_malformed_covariance_is_refused_naming_the_field(cov: Any, field: str) -> None:
    with pytest.raises(CalibrationError, match=field):
        calibration_from_dict(dict(PINE, covariance=cov), source_path="x.json")


def test_malformed_provenance_is_refused() -> None:
    with pytest.raises(CalibrationError, match="field provenance must be an object"):
        calibration_from_dict(dict(PINE, provenance=[1]))
    with pytest.raises(CalibrationError, match=r"provenance.method must be a non-empty string"):
        calibration_from_dict(dict(PINE, provenance={"method": ""}))

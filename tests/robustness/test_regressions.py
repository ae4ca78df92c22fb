"""Bugs the fuzzers found that are fixed: each input stays refused with the package's error."""

from __future__ import annotations

import json
from pathlib import Path

import pytest


def _write(tmp_path: Path, name: str, doc: object) -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def test_calibration_with_integer_beyond_float_range_is_refused(tmp_path: Path) -> None:
    """calibration-int-overflow: ``"gate_hu": 10**400`` -> OverflowError in float()."""
    from model import ModelInputError, load_calibration
    from tests.robustness.fuzz import seed_calibration

    doc = {**seed_calibration(), "gate_hu": 10**400}
    with pytest.raises(ModelInputError):
        load_calibration(_write(tmp_path, "cal.json", doc))


@pytest.mark.parametrize(
    ("field", "value"), [("b0", 400.0), ("n", 500.0), ("ke", 1e308)], ids=["b0", "n", "ke"]
)
def test_calibration_whose_law_overflows_is_refused(
    tmp_path: Path, field: str, value: float
) -> None:
    """calibration-law-unbounded: accepted, then A0 is inf (or OverflowError) at every HU.

    DESIGN.md 1.6: no NaN or inf may leave the model for any int16 HU and any finite feed, so a
    set whose A0 or Bk overflow over its own c_prime_range must be refused when it is loaded.
    """
    import numpy as np

    from model import ModelInputError, a0_n, load_calibration
    from tests.robustness.fuzz import seed_calibration

    doc = seed_calibration()
    doc["a0"] = {**doc["a0"], field: value}
    path = _write(tmp_path, "cal.json", doc)
    try:
        cal = load_calibration(path)
    except ModelInputError:
        return
    with np.errstate(all="ignore"):
        try:
            a0 = a0_n(np.array([-1000.0, 0.0, 1000.0]), 0.4, cal)
        except OverflowError:
            pytest.fail(f"a0.{field}={value} accepted, then A0 raises OverflowError")
    assert np.isfinite(a0).all(), f"a0.{field}={value} accepted, A0 = {a0}"

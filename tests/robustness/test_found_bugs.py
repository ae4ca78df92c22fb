"""Bugs found by the robustness tests, each a failing test until fixed (docs/robustness.md).

``KNOWN_BUGS`` lists the signature (exception type and the project function it escapes from) of
each bug whose trigger the fuzzers keep hitting: the fuzz tests tolerate exactly these and fail on
anything new, while the tests below pin each bug with its minimal input. ``BUG_CASES`` are corpus
cases whose outcome is wrong; ``test_corpus.py`` leaves them to this module.
"""

from __future__ import annotations

import json
import traceback
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.robustness.make_corpus import ROOT


@dataclass(frozen=True)
class KnownBug:
    """A reported bug: ``exc_type`` escaping from ``function`` in ``module_path``."""

    key: str
    exc_type: type[BaseException]
    module_path: str
    function: str


KNOWN_BUGS: tuple[KnownBug, ...] = (
    KnownBug("plan-int-overflow", OverflowError, "imaging/plan.py", "number"),
    KnownBug("plan-int-overflow", OverflowError, "imaging/plan.py", "point"),
    KnownBug("plan-kind-unhashable", TypeError, "imaging/plan.py", "_parse_landmark"),
    KnownBug("calibration-int-overflow", OverflowError, "model/calibration.py", "_number"),
    # Parameters accepted although the law overflows over c_prime_range (b0=400, n=500, ke=1e308).
    KnownBug("calibration-law-unbounded", OverflowError, "model/force.py", "a0_n"),
    KnownBug("calibration-law-unbounded", FloatingPointError, "model/force.py", "a0_n"),
    KnownBug("calibration-law-unbounded", OverflowError, "model/force.py", "bk_n"),
    KnownBug("calibration-law-unbounded", FloatingPointError, "model/force.py", "bk_n"),
)

#: Corpus cases whose outcome is wrong (kept out of test_corpus.py, asserted below).
BUG_CASES: frozenset[str] = frozenset()


def known_bug(exc: BaseException) -> str | None:
    """The key of the reported bug ``exc`` comes from, or None if it is a new one."""
    frames = [
        f
        for f in traceback.extract_tb(exc.__traceback__)
        if Path(f.filename).is_relative_to(ROOT) and "/tests/" not in f.filename
    ]
    while frames and frames[-1].name.startswith("<"):  # <genexpr>, <listcomp>, <lambda>
        frames.pop()
    if not frames:
        return None
    where = frames[-1]
    rel = Path(where.filename).relative_to(ROOT).as_posix()
    for bug in KNOWN_BUGS:
        if isinstance(exc, bug.exc_type) and rel == bug.module_path and where.name == bug.function:
            return bug.key
    return None


def _write(tmp_path: Path, name: str, doc: object) -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def _plan(**changes: object) -> dict[str, object]:
    from tests.robustness.fuzz import SEED_PLAN

    return {**json.loads(json.dumps(SEED_PLAN)), **changes}


def test_plan_with_integer_beyond_float_range_is_refused(tmp_path: Path) -> None:
    """plan-int-overflow: an integer 10**400 in ``entry_mm`` -> OverflowError (math.isfinite)."""
    from imaging import ImagingInputError
    from imaging.plan import load_plan

    with pytest.raises(ImagingInputError):
        load_plan(_write(tmp_path, "p.json", _plan(entry_mm=[10**400, 0, 0])))
    with pytest.raises(ImagingInputError):
        load_plan(_write(tmp_path, "q.json", _plan(margin_mm=10**400)))


def test_plan_with_list_as_landmark_kind_is_refused(tmp_path: Path) -> None:
    """plan-kind-unhashable: ``"kind": ["canal"]`` -> TypeError: unhashable type: 'list'."""
    from imaging import ImagingInputError
    from imaging.plan import load_plan

    plan = _plan()
    plan["landmarks"] = [{"name": "c", "kind": ["canal"], "points_mm": [[0, 0, 0], [1, 0, 0]]}]
    with pytest.raises(ImagingInputError):
        load_plan(_write(tmp_path, "p.json", plan))


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

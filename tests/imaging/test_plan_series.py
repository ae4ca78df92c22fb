"""Plans remember the series they were made on: a hash of its SeriesInstanceUID, never the UID."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import SERIES_HASH_KEY, Plan, PlanInputError, series_uid_hash
from ctdrill.imaging.plan.write import save_plan
from tests.conftest import ASSETS

UID = "1.2.826.0.1.3680043.8.498.12345678901234567890"


def _plan() -> Plan:
    canal = CanalLandmark("canal", [[0.0, -5.0, -8.0], [0.0, 5.0, -8.0]], radius_mm=1.0)
    return Plan(entry_lps=[0, 0, 0], target_lps=[0, 0, -5.0], landmarks=(canal,), name="p")


def test_the_hash_is_stable_hex_and_not_the_uid() -> None:
    h = series_uid_hash(UID)
    assert h == series_uid_hash(UID) == series_uid_hash(f" {UID} ")
    assert len(h) == 64 and int(h, 16) >= 0 and UID not in h
    assert series_uid_hash(UID + "1") != h


@pytest.mark.parametrize("name", ["plan.json", "plan.mrk.json"])
def test_saved_plans_record_the_hash_and_read_it_back(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    save_plan(_plan(), path, series_uid=UID)
    text = path.read_text(encoding="utf-8")
    assert series_uid_hash(UID) in text and UID not in text
    assert load_plan(path).series_uid_sha256 == series_uid_hash(UID)
    # re-saving without a series keeps what the plan remembers
    again = tmp_path / ("again-" + name)
    save_plan(load_plan(path), again)
    assert load_plan(again).series_uid_sha256 == series_uid_hash(UID)


def test_old_plans_without_a_hash_still_load(tmp_path: Path) -> None:
    doc = json.loads((ASSETS / "demo" / "plan.json").read_text(encoding="utf-8"))
    assert SERIES_HASH_KEY in doc  # the bundled demo records its phantom series
    del doc[SERIES_HASH_KEY]
    (tmp_path / "old.json").write_text(json.dumps(doc), encoding="utf-8")
    assert load_plan(tmp_path / "old.json").series_uid_sha256 is None
    save_plan(_plan(), tmp_path / "none.json")
    assert SERIES_HASH_KEY not in json.loads((tmp_path / "none.json").read_text())


@pytest.mark.parametrize("bad", ["abc", UID, 12, "A" * 64, None])
def test_a_malformed_hash_is_refused_by_name(tmp_path: Path, bad: object) -> None:
    save_plan(_plan(), tmp_path / "p.json", series_uid=UID)
    doc = json.loads((tmp_path / "p.json").read_text())
    doc[SERIES_HASH_KEY] = bad
    (tmp_path / "p.json").write_text(json.dumps(doc), encoding="utf-8")
    if bad is None:  # JSON null: as if absent
        assert load_plan(tmp_path / "p.json").series_uid_sha256 is None
        return
    with pytest.raises(PlanInputError, match=rf"p\.json: {SERIES_HASH_KEY} must be the 64"):
        load_plan(tmp_path / "p.json")


def test_demo_plan_carries_its_series_hash() -> None:
    from ctdrill.imaging import load_series

    volume = load_series(ASSETS / "demo" / "ct")
    plan = load_plan(ASSETS / "demo" / "plan.json")
    assert plan.series_uid_sha256 == series_uid_hash(volume.info.series_uid)
    assert np.isfinite(plan.planned_depth_mm)

"""Every warning code comes from one registry (ctdrill/warning_codes.py): the codes written in
the source, and those the demo and the engine's cases emit, are registered; the docs and
``WARNING_CODES`` derive from it."""

from __future__ import annotations

import ast
import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ctdrill import warning_codes
from ctdrill.imaging.provenance import WARNING_CODES, LoadWarning
from ctdrill.warning_codes import REGISTRY, SCOPES, UnknownWarningCode, codes, markdown, meaning

ROOT = Path(__file__).resolve().parents[1]
ROOMS = ("app", "engine", "imaging", "model", "haptics", "ctdrill")
_CODE = re.compile(r"^[a-z][a-z0-9]*(_[a-z0-9]+)*$")
#: ``(key, text)`` pairs in the source that are not warnings (a tag and its label, a field
#: and its value, a worker's message kind), by the module that writes them.
NOT_WARNINGS = {
    ("entry", "imaging/plan/write.py"),
    ("name", "imaging/plan/implants.py"),
    ("error", "app/gui/session_process.py"),
    ("assessment", "app/gui/session_process.py"),
    ("state", "app/gui/session_process.py"),
    ("off", "app/readout.py"),
    ("igtl", "app/gui/session_process.py"),
    ("sent", "app/gui/session_process.py"),
    # the rows (item, value) of the report's implant page
    ("implant", "app/report/clinical.py"),
    ("angulation", "app/report/clinical.py"),
    ("accuracy", "app/report/clinical.py"),
    # a device's fault kinds (a rehearsal's ``faults``), not warnings
    ("device_fault", "haptics/watch.py"),
    ("device_clock", "haptics/watch.py"),
}


#: Names a message is held in before it is paired with its code.
MESSAGE_NAMES = {"message", "msg", "note", "text"}


def _emitted_in_source() -> dict[str, set[str]]:
    """code -> modules: the first argument of every ``LoadWarning(...)``, the first item of
    every ``(code, message)`` pair (a code-like string, then a message expression) and every
    constant named ``*_CODE``."""
    found: dict[str, set[str]] = {}
    for room in ROOMS:
        for path in sorted((ROOT / room).rglob("*.py")):
            rel = str(path.relative_to(ROOT))
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                first: ast.expr | None = None
                if (
                    isinstance(node, ast.Assign)
                    and len(node.targets) == 1
                    and getattr(node.targets[0], "id", "").endswith("_CODE")
                ):
                    first = node.value  # a code held in a constant (``NOTE_CODE = "..."``)
                elif isinstance(node, ast.Call) and getattr(node.func, "id", "") == "LoadWarning":
                    first = node.args[0] if node.args else None
                elif isinstance(node, ast.Tuple) and len(node.elts) == 2:
                    msg = node.elts[1]
                    if isinstance(msg, ast.JoinedStr | ast.BinOp | ast.Call) or (
                        isinstance(msg, ast.Name) and msg.id in MESSAGE_NAMES
                    ):
                        first = node.elts[0]
                if not (isinstance(first, ast.Constant) and isinstance(first.value, str)):
                    continue
                if _CODE.match(first.value) and (first.value, rel) not in NOT_WARNINGS:
                    found.setdefault(first.value, set()).add(rel)
    return found


def test_every_code_written_in_the_source_is_registered() -> None:
    found = _emitted_in_source()
    assert {"slice_gap", "plan_violates_margin", "implants_too_close", "out_of_volume"} <= set(
        found
    )  # the scan sees every kind of emitter
    unregistered = {code: sorted(where) for code, where in found.items() if code not in codes()}
    assert unregistered == {}
    # and every registered code is emitted somewhere (none is left over)
    assert set(codes()) - set(found) == set()


def test_the_registry_is_one_entry_per_code_with_a_meaning() -> None:
    names = [w.code for w in REGISTRY]
    assert len(names) == len(set(names))
    assert all(w.scope in SCOPES and len(w.meaning) > 20 for w in REGISTRY)
    assert meaning("padding").startswith("pixels outside")
    with pytest.raises(UnknownWarningCode, match=r"not in ctdrill/warning_codes\.py"):
        LoadWarning("no_such_code", "x")


def test_warning_codes_and_the_docs_derive_from_it() -> None:
    assert codes("series") == WARNING_CODES
    # DESIGN.md section 4's inspect codes are load codes
    design = {"slice_gap", "nonuniform_spacing", "gantry_tilt", "localizer_dropped"}
    design |= {"multiple_series", "duplicate_slice", "padding", "not_hu", "lossy_compression"}
    assert design | {"files_skipped", "files_unreadable"} <= set(WARNING_CODES)
    page = (ROOT / "docs" / "warnings.md").read_text(encoding="utf-8")
    assert page == markdown(), "run: python -m ctdrill.warning_codes > docs/warnings.md"
    assert warning_codes.__doc__ is not None


def test_the_codes_the_demo_and_the_engine_emit_are_registered(tmp_path: Path) -> None:
    from ctdrill.app.export_demo import DEMO_DIR, run_demo
    from ctdrill.engine.path import plan_path
    from ctdrill.engine.plans import plan_calibration
    from ctdrill.imaging import load_series
    from ctdrill.imaging.plan.load import load_plan

    run_demo(tmp_path / "demo")
    doc = json.loads((tmp_path / "demo" / "summary.json").read_text(encoding="utf-8"))
    seen = {w["code"] for w in doc["warnings"]}
    volume = load_series(DEMO_DIR / "ct")
    plan = load_plan(DEMO_DIR / "plan.json")
    cal = plan_calibration(plan)
    cases = [
        replace(plan, landmarks=(), feed_mm_s=80.0, series_uid_sha256="0" * 64),
        replace(plan, target_lps=plan.entry_lps + np.array([40.0, 0.0, -2.0])),  # leaves it
        replace(plan, margin_mm=1.0, implant=None),
    ]
    for case in cases:
        seen |= {w.code for w in plan_path(volume, case, cal).warnings}
    want = {"calibration_illustrative", "plan_violates_margin", "implant_beyond_stop"}
    want |= {"no_landmarks", "feed_outside_model", "plan_other_series", "out_of_volume"}
    want |= {"margin_below_clinical"}
    assert want <= seen
    assert seen <= set(codes())


#: The modules that may list warning codes: the registry, and the plan's verdict (which
#: checks produce which findings).
MAY_LIST_CODES = {"ctdrill/warning_codes.py", "engine/verdict.py"}


def code_lists_in_source() -> list[str]:
    """``module:line`` of every literal tuple, list, set or dict (its keys) of two or more
    strings that are all registered codes, outside :data:`MAY_LIST_CODES`."""
    found = []
    for room in ROOMS:
        for path in sorted((ROOT / room).rglob("*.py")):
            rel = str(path.relative_to(ROOT))
            if rel in MAY_LIST_CODES:
                continue
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                items: list[ast.expr] = []
                if isinstance(node, ast.Tuple | ast.List | ast.Set):
                    items = list(node.elts)
                elif isinstance(node, ast.Dict):
                    items = [k for k in node.keys if k is not None]
                texts = [i.value for i in items if isinstance(i, ast.Constant)]
                if (
                    len(texts) >= 2
                    and len(texts) == len(items)
                    and all(isinstance(t, str) and t in warning_codes.WARNINGS for t in texts)
                ):
                    found.append(f"{rel}:{node.lineno}")
    return found


def test_no_module_but_the_registry_lists_warning_codes() -> None:
    # which codes block suggest, show in the banner, and their words are the registry's fields
    assert code_lists_in_source() == []


def test_the_scan_finds_a_list_of_codes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    room = tmp_path / "app"
    room.mkdir()
    (room / "lists.py").write_text('BLOCKING = ("thin_wall", "cortical_perforation")\n')
    (room / "fine.py").write_text('PAIR = ("thin_wall", "a message")\nONE = ("thin_wall",)\n')
    monkeypatch.setattr(f"{__name__}.ROOT", tmp_path)
    monkeypatch.setattr(f"{__name__}.ROOMS", ("app",))
    assert code_lists_in_source() == ["app/lists.py:1"]


def test_the_registry_says_what_blocks_suggest_and_what_the_banner_shows() -> None:
    ranks = [w.banner for w in REGISTRY if w.banner is not None]
    assert sorted(ranks) == list(range(1, len(ranks) + 1))  # one place each
    assert warning_codes.banner_codes()[0] == "plan_violates_margin"
    assert {"plan_violates_margin", "thin_wall"} <= set(warning_codes.blocking_codes())
    assert all(w.words for w in REGISTRY if w.banner is not None)  # the banner's headings
    assert warning_codes.words("thin_wall") == "thin bone wall"
    assert warning_codes.words("out_of_volume") == "out of volume"


def test_no_warning_is_cut_from_another_warnings_message() -> None:
    """A message is built from the values it reports, never by cutting another message."""
    cuts = ("split", "rsplit", "partition", "rpartition")
    found = []
    for room in ROOMS:
        for path in sorted((ROOT / room).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if (
                    isinstance(node, ast.Call)
                    and isinstance(node.func, ast.Attribute)
                    and node.func.attr in cuts
                    and isinstance(node.func.value, ast.Name)
                    and node.func.value.id in {"message", "msg"}
                ):
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert found == []


def test_every_warning_is_one_type() -> None:
    """A warning is built as the registry's ``LoadWarning`` only: no registered code is paired
    with a message in a bare tuple, and no other record holds a code and a message."""
    assert LoadWarning is warning_codes.LoadWarning
    pairs, records = [], []
    for room in ROOMS:
        for path in sorted((ROOT / room).rglob("*.py")):
            rel = str(path.relative_to(ROOT))
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Tuple) and len(node.elts) == 2:
                    code, msg = node.elts
                    if (
                        isinstance(code, ast.Constant)
                        and code.value in warning_codes.WARNINGS
                        and (code.value, rel) not in NOT_WARNINGS
                        and not isinstance(msg, ast.Constant | ast.Lambda)
                    ):
                        pairs.append(f"{rel}:{node.lineno}")
                if isinstance(node, ast.ClassDef) and node.name != "LoadWarning":
                    fields = {
                        s.target.id
                        for s in node.body
                        if isinstance(s, ast.AnnAssign) and isinstance(s.target, ast.Name)
                    }
                    if fields == {"code", "message"}:
                        records.append(f"{rel}:{node.name}")
    assert pairs == []
    assert records == []


def test_the_outputs_list_warnings_as_code_and_message_objects() -> None:
    from ctdrill.engine.record import from_json, to_json

    w = LoadWarning("thin_wall", "plan 'p': 0.4 mm")
    assert to_json(w) == {"code": "thin_wall", "message": "plan 'p': 0.4 mm"}
    assert from_json(LoadWarning, to_json(w)) == w
    with pytest.raises(UnknownWarningCode):
        LoadWarning("not_a_code", "x")

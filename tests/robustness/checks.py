"""Assertions shared by the corpus tests and the found-bug tests."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from tests.robustness.make_corpus import Case, build_corpus
from tests.robustness.outcomes import (
    Observed,
    error_line_problems,
    inspect_args,
    observe_load,
    run_cli_in_process,
)

#: Keys ``ctdrill inspect --json`` must always print (DESIGN.md section 4).
INSPECT_KEYS = {"dims", "spacing_mm", "affine_lps", "hu_min", "hu_max", "series_uid", "warnings"}

_CORPUS: dict[Path, dict[str, Case]] = {}


def corpus_cases(out_dir: Path) -> dict[str, Case]:
    """The corpus written once per ``out_dir``, by case name."""
    if out_dir not in _CORPUS:
        _CORPUS[out_dir] = {case.name: case for case in build_corpus(out_dir)}
    return _CORPUS[out_dir]


def expectation_text(case: Case) -> str:
    """The acceptable outcomes of ``case`` as text."""
    return " | ".join(e.describe() for e in case.expected)


def check_observed(case: Case, seen: Observed) -> None:
    """Assert that a ``load_series`` observation is one of the case's acceptable outcomes."""
    where = f"{case.name} ({case.path}): expected {expectation_text(case)}"
    assert seen.outcome != "bug", f"{where}; got a non-project exception {seen.message}"
    if seen.outcome == "refuse":
        assert any(e.outcome == "refuse" for e in case.expected), (
            f"{where}; refused with: {seen.message}"
        )
        assert seen.message.strip(), f"{where}; empty error message"
        assert "\n" not in seen.message.strip(), f"{where}; multi-line message {seen.message!r}"
        return
    assert any(e.accepts_load(seen.codes, seen.dims) for e in case.expected), (
        f"{where}; loaded dims {seen.dims} with warnings {list(seen.codes)}"
    )


def check_load(case: Case) -> Observed:
    """Load the case with ``ctdrill.imaging.load_series`` and assert its outcome (and exact
    values)."""
    seen = observe_load(case)
    check_observed(case, seen)
    if seen.outcome == "load" and (case.hu is not None or case.affine_lps is not None):
        from ctdrill.imaging import load_series

        volume = load_series(case.path)
        if case.hu is not None:
            np.testing.assert_array_equal(np.asarray(volume.hu), case.hu)
        if case.affine_lps is not None:
            np.testing.assert_allclose(volume.affine_lps, case.affine_lps, atol=1e-5)
    return seen


def check_inspect(case: Case, seen: Observed) -> None:
    """Run ``ctdrill inspect --json`` in-process and assert it agrees with ``seen``."""
    run = run_cli_in_process(inspect_args(case))
    if seen.outcome == "refuse":
        problems = error_line_problems(run)
        assert not problems, f"{case.name}: {problems}"
        assert run.stdout == "", f"{case.name}: refusal printed on stdout: {run.stdout!r}"
        return
    assert run.code == 0, f"{case.name}: exit {run.code}, stderr {run.stderr!r}"
    doc = run.json()
    assert set(doc) >= INSPECT_KEYS, f"{case.name}: keys missing: {INSPECT_KEYS - set(doc)}"
    assert tuple(doc["dims"]) == seen.dims
    assert sorted(w["code"] for w in doc["warnings"]) == list(seen.codes)
    assert all(w["message"] for w in doc["warnings"])
    # An irregular stack states no affine (docs/geometry.md): every slice's origin instead.
    origins = np.asarray(doc["slice_origins_lps"], dtype=float)
    assert origins.shape == (seen.dims[2], 3) and np.isfinite(origins).all()
    if doc["regular"]:
        assert np.isfinite(np.asarray(doc["affine_lps"], dtype=float)).all()
        assert np.asarray(doc["affine_lps"]).shape == (4, 4)
    else:
        assert doc["affine_lps"] is None
    json.dumps(doc, allow_nan=False)  # strict JSON: no NaN/Infinity

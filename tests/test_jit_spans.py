"""``ctdrill.jit.row_spans``: rows as half-open spans of consecutive rows, split for threads."""

from __future__ import annotations

import numpy as np

from ctdrill.jit import row_spans


def _covered(spans: list[tuple[int, int]]) -> list[int]:
    return [r for lo, hi in spans for r in range(lo, hi)]


def test_consecutive_rows_split_in_parts() -> None:
    assert row_spans(np.arange(10), parts=2) == [(0, 5), (5, 10)]
    assert row_spans(np.arange(3, 6), parts=4) == [(3, 4), (4, 5), (5, 6)]
    assert row_spans(np.array([7])) == [(7, 8)]
    assert row_spans(np.array([], dtype=np.int64)) == []


def test_unsorted_and_repeated_rows_are_each_covered_once() -> None:
    rows = np.array([9, 2, 3, 3, 4, 10, 0])
    spans = row_spans(rows, parts=2)
    assert _covered(spans) == [0, 2, 3, 4, 9, 10]
    assert all(hi > lo for lo, hi in spans)
    rng = np.random.default_rng(1)
    rows = rng.integers(0, 200, 150)
    assert _covered(row_spans(rows, parts=3)) == sorted(set(rows.tolist()))

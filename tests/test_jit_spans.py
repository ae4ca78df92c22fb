"""``ctdrill.jit.row_spans``: rows as half-open spans of consecutive rows, split for threads;
``ctdrill.claims.start_claimed``: rows claimed one by one by threads walking spans from both
ends."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill import claims, jit
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


class _Squares:
    """A claiming kernel in Python (the protocol of :class:`ctdrill.claims.Claimed`): row ``n``
    gets ``n * n``; ``seen`` counts how often each row was computed."""

    name = "squares"

    def __init__(self, n: int) -> None:
        self.out = np.zeros(n)
        self.seen = np.zeros(n, dtype=np.int64)

    def ready(self) -> bool:
        return True

    def fixed_args(self, args: tuple[object, ...]) -> tuple[object, ...]:
        return tuple(args)

    def _dispatch(self) -> object:
        def walk(out: np.ndarray, taken: np.ndarray, lo: int, hi: int, backward: bool) -> None:
            rows = range(hi - 1, lo - 1, -1) if backward else range(lo, hi)
            for n in rows:
                if taken[n] != 0:
                    break
                taken[n] = 1
                out[n] = n * n
                self.seen[n] += 1
                taken[n] = 2

        return walk


def test_claimed_rows_are_each_computed_and_done(monkeypatch: pytest.MonkeyPatch) -> None:
    for cpus in (1, 2, 3, 8):
        monkeypatch.setattr(jit, "cpus", lambda c=cpus: c)
        k = _Squares(1000)
        job = claims.start_claimed(k, 1000, k.out)  # type: ignore[arg-type]
        job.join()
        assert np.array_equal(k.out, np.arange(1000.0) ** 2)
        assert np.all(job.taken == 2)
        # two threads meeting on a row may both compute it; never more, never none
        assert k.seen.min() == 1 and k.seen.max() <= 2


def test_a_walk_stops_at_a_row_another_thread_took() -> None:
    k = _Squares(10)
    walk = k._dispatch()
    taken = np.zeros(10, dtype=np.uint8)
    taken[6] = 1
    walk(k.out, taken, 0, 10, True)  # type: ignore[operator]
    assert taken.tolist() == [0] * 6 + [1, 2, 2, 2]
    walk(k.out, taken, 0, 10, False)  # type: ignore[operator]
    assert taken.tolist() == [2] * 6 + [1, 2, 2, 2]


def test_a_cancelled_job_takes_no_more_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(jit, "cpus", lambda: 1)  # nothing starts before join
    k = _Squares(50)
    job = claims.start_claimed(k, 50, k.out)  # type: ignore[arg-type]
    job.cancel()
    job.join()
    assert k.seen.sum() == 0

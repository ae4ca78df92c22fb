"""A pytest plugin recording each test's CPU and wall time (``-p bench.suite_cpu``).

CPU is the test process's user + system time (every thread) plus that of the child processes
it waited for, read around each test's whole protocol (set-up, call, tear-down); collection is
one more row, ``<collect>``. One JSON object a line is appended to the file named by
:data:`OUT_ENV`. On a shared machine CPU time is the figure to compare: wall time grows with
the load, CPU time barely.
"""

from __future__ import annotations

import json
import os
import resource
import time
from collections.abc import Iterator
from typing import Any

import pytest

#: Environment variable naming the JSON-lines file the rows are appended to.
OUT_ENV = "CTDRILL_SUITE_CPU_OUT"
#: The row that holds the collection (imports of every test module).
COLLECT = "<collect>"

_started: dict[str, float] = {}


def cpu_s() -> tuple[float, float]:
    """User + system seconds of this process (all threads) and of its waited-for children."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime, kids.ru_utime + kids.ru_stime


def _write(nodeid: str, self_s: float, child_s: float, wall_s: float) -> None:
    out = os.environ.get(OUT_ENV)
    if not out:
        return
    row = {"id": nodeid, "self_s": self_s, "child_s": child_s, "wall_s": wall_s}
    row["worker"] = os.environ.get("PYTEST_XDIST_WORKER", "")  # gw0, gw1 under pytest-xdist
    with open(out, "a", encoding="utf-8") as f:
        f.write(json.dumps(row) + "\n")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[Any]:
    """Time one test's set-up, call and tear-down."""
    s0, c0 = cpu_s()
    w0 = time.perf_counter()
    yield
    s1, c1 = cpu_s()
    _write(item.nodeid, s1 - s0, c1 - c0, time.perf_counter() - w0)


def pytest_collection(session: pytest.Session) -> None:
    """Start the collection's clock."""
    _started["self"], _started["child"] = cpu_s()
    _started["wall"] = time.perf_counter()


def pytest_collection_finish(session: pytest.Session) -> None:
    """Write the collection's row."""
    s1, c1 = cpu_s()
    wall = time.perf_counter() - _started["wall"]
    _write(COLLECT, s1 - _started["self"], c1 - _started["child"], wall)

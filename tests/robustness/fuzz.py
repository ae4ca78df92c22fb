"""Shared fuzzing set-up: example counts, per-example time limit, seed documents and strategies."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from tests.robustness.make_corpus import ROOT
from tests.robustness.mutate import (
    BYTE_OPS,
    JSON_OPS,
    NASTY_VALUES,
    ByteMutation,
    apply_json,
    dump_json,
    json_paths,
    mutate_text,
)

#: Examples per fuzz test: short in ``make test``, ``CTDRILL_FUZZ_EXAMPLES`` in ``make fuzz``.
FUZZ_EXAMPLES = int(os.environ.get("CTDRILL_FUZZ_EXAMPLES", "40"))
#: CPU-time limit of one example, s (a parse that works longer counts as a near-hang; CPU time,
#: not wall time: a loaded host delays an example without making it work more).
EXAMPLE_LIMIT_S = 5.0
#: pytest-timeout for a whole fuzz test, s: scales with the example count.
FUZZ_TIMEOUT_S = max(120, int(FUZZ_EXAMPLES * EXAMPLE_LIMIT_S))

fuzz_settings = settings(
    max_examples=FUZZ_EXAMPLES,
    deadline=None,
    derandomize=FUZZ_EXAMPLES <= 100,  # the short run in make test is reproducible
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    database=None,
)

#: A ctdrill-plan/1 document using every field (DESIGN.md section 4).
SEED_PLAN: dict[str, Any] = {
    "format": "ctdrill-plan/1",
    "coordinate_system": "LPS",
    "entry_mm": [10.0, -20.0, 35.0],
    "target_mm": [10.5, -19.0, 23.0],
    "drill": {"diameter_mm": 2.0, "tip_length_mm": 0.6, "blades": 2, "rpm": 900},
    "feed_mm_s": 0.4,
    "calibration": "pine-wood-paper",
    "margin_mm": 2.0,
    "landmarks": [
        {
            "name": "left mandibular canal",
            "kind": "canal",
            "points_mm": [[0.0, -20.0, 15.0], [20.0, -20.0, 14.0], [30.0, -15.0, 14.5]],
            "radius_mm": 1.2,
        },
        {"name": "mental foramen", "kind": "point", "point_mm": [25.0, -25.0, 20.0]},
    ],
}

#: A ctdrill-plan/1 document of several trajectories with implants, a drill sequence and the
#: dental arch (issue 16).
SEED_PLAN_SET: dict[str, Any] = {
    "format": "ctdrill-plan/1",
    "coordinate_system": "RAS",
    "trajectories": [
        {
            "name": "36",
            "entry_mm": [10.0, -20.0, 35.0],
            "target_mm": [10.5, -19.0, 23.0],
            "drill": {"diameter_mm": 2.0},
            "implant": {
                "name": "tapered 4.1 x 10",
                "diameter_mm": 4.1,
                "length_mm": 10.0,
                "apex_diameter_mm": 2.9,
                "apex": "round",
            },
        },
        {
            "name": "37",
            "entry_mm": [20.0, -20.0, 35.0],
            "target_mm": [20.0, -20.0, 24.0],
            "drills": [{"diameter_mm": 2.0}, {"diameter_mm": 2.8}],
            "margin_mm": 1.5,
        },
    ],
    "landmarks": SEED_PLAN["landmarks"],
    "arch_mm": [[0.0, -30.0, 25.0], [15.0, -25.0, 25.0], [30.0, -10.0, 25.5]],
}

#: A 3D Slicer markups document: a Line (trajectory), a Curve (canal), Fiducials.
SEED_MARKUPS: dict[str, Any] = {
    "@schema": "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/"
    "Markups/Resources/Schema/markups-schema-v1.0.3.json#",
    "markups": [
        {
            "type": "Line",
            "name": "implant 36",
            "coordinateSystem": "RAS",
            "description": "diameter_mm=2.0 tip_length_mm=0.6 feed_mm_s=0.4",
            "controlPoints": [
                {"label": "entry", "position": [-10.0, 20.0, 35.0]},
                {"label": "target", "position": [-10.5, 19.0, 23.0]},
            ],
        },
        {
            "type": "Curve",
            "name": "canal",
            "coordinateSystem": "RAS",
            "description": "radius_mm=1.2",
            "controlPoints": [
                {"position": [0.0, 20.0, 15.0]},
                {"position": [-20.0, 20.0, 14.0]},
            ],
        },
        {
            "type": "Fiducial",
            "name": "foramen",
            "coordinateSystem": "RAS",
            "controlPoints": [{"label": "mental foramen", "position": [-25.0, 25.0, 20.0]}],
        },
        {
            "type": "Curve",
            "coordinateSystem": "LPS",
            "controlPoints": [
                {"description": "arch", "position": [0.0, -30.0, 25.0]},
                {"position": [15.0, -25.0, 25.0]},
                {"position": [30.0, -10.0, 25.5]},
            ],
        },
        {
            "type": "Line",
            "coordinateSystem": "LPS",
            "controlPoints": [
                {
                    "description": 'name="37" implant="x" implant_diameter_mm=4.0 '
                    "implant_length_mm=8.0 implant_apex_diameter_mm=3.0 implant_apex=flat",
                    "position": [20.0, -20.0, 35.0],
                },
                {"position": [20.0, -20.0, 24.0]},
            ],
        },
    ],
}


def seed_calibration(name: str = "pine-wood-paper") -> dict[str, Any]:
    """A bundled calibration set as a JSON document."""
    doc: dict[str, Any] = json.loads((ROOT / "assets" / "calibration" / f"{name}.json").read_text())
    return doc


json_values = st.one_of(
    st.sampled_from(NASTY_VALUES),
    st.recursive(
        st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
        lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner),
        max_leaves=8,
    ),
)


@st.composite
def mutated_json(draw: st.DrawFn, doc: Any, *, max_mutations: int = 3) -> str:
    """JSON text of ``doc`` after 1..max_mutations structure (or text) mutations."""
    out = doc
    for _ in range(draw(st.integers(1, max_mutations))):
        op = draw(st.sampled_from(JSON_OPS))
        if op == "text":
            text = dump_json(out)
            cut = draw(st.floats(0.0, 1.0))
            return mutate_text(text, cut, draw(st.sampled_from(["", "}", "]]", "\x00", "ü"])))
        path = draw(st.sampled_from(json_paths(out)))
        out = apply_json(out, op, path, draw(json_values))
    return dump_json(out)


@st.composite
def byte_mutations(draw: st.DrawFn) -> list[ByteMutation]:
    """1..4 byte mutations (flip, insert, delete, truncate, overwrite, element length)."""
    out = []
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(BYTE_OPS))
        where = draw(st.floats(0.0, 1.0, exclude_max=True))
        size = draw(st.sampled_from([1, 2, 3, 4, 7, 8, 64, 1000]))
        payload = draw(
            st.one_of(
                st.binary(min_size=1, max_size=16),
                st.sampled_from(
                    [b"\xff\xff\xff\xff", b"\xf0\xff\xff\xff", b"\x00\x00\x00\x00", b"\xff\xff"]
                ),
            )
        )
        out.append(ByteMutation(op, where, size, payload))
    return out


def timed(limit_s: float, call: Callable[[], Any]) -> Any:
    """Run ``call`` and fail if it works for more than ``limit_s`` of CPU time (a near-hang).

    The work is measured as this process's CPU time, which other processes on the host do not
    inflate; a call that blocks without working is caught by the test's timeout instead.
    """
    start = time.process_time()
    result = call()
    used = time.process_time() - start
    assert used < limit_s, f"worked {used:.1f} s of CPU time (limit {limit_s} s)"
    return result


def write_text(path: Path, text: str) -> Path:
    """Write ``text`` (UTF-8, surrogates replaced) and return ``path``."""
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    return path

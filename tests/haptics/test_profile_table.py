"""ProfileTable: validation, the Profile adapter, and its upload messages."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from ctdrill.haptics.profile_table import MAX_PROFILE_STEPS, ProfileTable, ProfileTableError
from ctdrill.haptics.protocol import MAX_CHUNK_ROWS, ProfileBegin, ProfileChunk, ProfileEnd, crc32
from ctdrill.model.profile import Profile


def _profile(k: int) -> Profile:
    depth = np.arange(5) * 0.25
    return Profile(
        depth_mm=depth,
        s0_n=np.array([0.0, 1.0, 2.0, 3.0, 4.0]),
        sk_n=np.arange(5 * k, dtype=float).reshape(k, 5),
        freqs_hz=np.array([30.0, 60.0, 90.0][:k]),
        s_t=np.ones(5),
        hu_mean=np.zeros(5),
        ke_per_mm_s=0.25,
        n_clipped=0,
        n_samples=1,
        calibration="test",
    )


def test_from_profile_takes_two_harmonics_and_pads() -> None:
    t = ProfileTable.from_profile(_profile(3), 0.8)
    assert t.depth_step_mm == 0.25 and t.n_steps == 5
    assert t.s0_n.tolist() == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert t.s1_n.tolist() == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert t.s2_n.tolist() == [5.0, 6.0, 7.0, 8.0, 9.0]
    assert t.freqs_hz.tolist() == [30.0, 60.0]
    assert t.stop_depth_mm == pytest.approx(0.8, rel=1e-7)  # float32
    t1 = ProfileTable.from_profile(_profile(1), 0.5)
    assert t1.s2_n.tolist() == [0.0] * 5 and t1.freqs_hz.tolist() == [30.0, 0.0]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"s0_n": [1.0, math.nan]}, "NaN"),
        ({"s0_n": [1.0, -1.0]}, ">= 0"),
        ({"s0_n": np.ones(MAX_PROFILE_STEPS + 1)}, "1..4096"),
        ({"s1_n": [1.0]}, "shape"),
        ({"depth_step_mm": 0.0}, "depth_step_mm"),
        ({"stop_depth_mm": math.inf}, "stop_depth_mm"),
        ({"ke_per_mm_s": -0.1}, "ke_per_mm_s"),
        ({"freqs_hz": [30.0]}, "freqs_hz"),
        ({"s2_n": [1e39, 0.0]}, "float32"),
    ],
)
def test_validation(kwargs: dict, match: str) -> None:
    args = {
        "depth_step_mm": 0.05,
        "s0_n": [1.0, 2.0],
        "s1_n": [0.0, 0.0],
        "s2_n": [0.0, 0.0],
        "ke_per_mm_s": 0.25,
        "freqs_hz": [30.0, 60.0],
        "stop_depth_mm": 1.0,
    }
    args.update(kwargs)
    if "s0_n" in kwargs and len(kwargs["s0_n"]) != 2:
        args["s1_n"] = args["s2_n"] = np.zeros(len(kwargs["s0_n"]))
    with pytest.raises(ProfileTableError, match=match):
        ProfileTable(**args)


def test_upload_messages_chunk_the_table_and_carry_its_crc() -> None:
    t = ProfileTable.slab(s0_n=4.0, s1_n=0.5, top_mm=0.0, bottom_mm=2.0, stop_depth_mm=1.5)
    msgs = list(t.upload_messages())
    begin, end = msgs[0], msgs[-1]
    assert isinstance(begin, ProfileBegin) and isinstance(end, ProfileEnd)
    chunks = msgs[1:-1]
    assert all(isinstance(c, ProfileChunk) for c in chunks)
    assert len(chunks) == math.ceil(t.n_steps / MAX_CHUNK_ROWS)
    rows = [row for c in chunks for row in c.rows]  # type: ignore[union-attr]
    assert rows == t.rows()
    blob = struct.pack("<Hfffff", t.n_steps, 0.0625, 0.25, 30.0, 60.0, 1.5)
    blob += b"".join(struct.pack("<fff", *r) for r in rows)
    assert end.crc32 == crc32(blob) and end.n_steps == t.n_steps == 641

"""Hostile volume headers: one input error naming the file and the field, in bounded memory.

Every class of lie of ``tests/imaging/hostile_volumes.py`` (4-D, non-finite or absurd spacing
and positions, skewed or scaled orientation, sizes beyond the bound or beyond the file,
decompression bombs, devices as data files, endless headers, too many segments) is refused by
the CT loader and by the segmentation reader alike, before anything of the declared size is
allocated: the peak of traced allocations stays far below what the bombs declare.
"""

from __future__ import annotations

import re
import tracemalloc
from pathlib import Path

import pytest

from ctdrill.imaging import ImagingInputError, load_ct
from ctdrill.imaging.plan.landmarks import LandmarkInputError
from ctdrill.imaging.plan.segmentation import read_labels
from ctdrill.imaging.volumes.types import VolumeFileError
from tests.imaging.hostile_volumes import BOMB_BYTES, HOSTILE, MASK_ONLY

#: Largest traced allocation while refusing a case, bytes (the bombs declare 240 B .. 2 TB of
#: voxels or inflate to 256 MiB; reading, inflating a step and refusing needs a few MiB).
PEAK_BYTES = 40 << 20


@pytest.mark.parametrize("name", sorted(set(HOSTILE) - set(MASK_ONLY)))
def test_ct_loader_refuses_naming_the_field(tmp_path: Path, name: str) -> None:
    path, pattern = HOSTILE[name](tmp_path)
    tracemalloc.start()
    try:
        with pytest.raises(VolumeFileError) as err:
            load_ct(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    message = str(err.value)
    assert re.search(pattern, message), message
    assert str(path.parent) in message or "/dev/zero" in message, message
    assert "\n" not in message
    assert peak < PEAK_BYTES < BOMB_BYTES, f"{name}: peak {peak} bytes"


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_segmentation_reader_refuses_the_same(tmp_path: Path, name: str) -> None:
    path, pattern = HOSTILE[name](tmp_path)
    with pytest.raises(LandmarkInputError) as err:
        read_labels(path)
    assert re.search(pattern, str(err.value)), str(err.value)
    assert isinstance(err.value, ImagingInputError)

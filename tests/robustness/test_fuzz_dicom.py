"""Fuzz the DICOM loader with byte mutations of one file of a three-slice series.

Seeds: pydicom's bundled ``CT_small.dcm`` (a real scanner header) and three consecutive slices
of the bundled demo phantom (``assets/demo/ct``, written by ``ctdrill.imaging.phantom.io``). One of
the three files is mutated (bit flips, inserts, deletes, truncation, overwrites, element lengths
rewritten); ``load_series`` must load a finite volume or raise ``ImagingInputError``, within
5 s and 1 GiB of extra address space.
"""

from __future__ import annotations

import functools
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.robustness.fuzz import (
    EXAMPLE_LIMIT_S,
    FUZZ_TIMEOUT_S,
    byte_mutations,
    fuzz_settings,
    timed,
)
from tests.robustness.make_corpus import ROOT
from tests.robustness.mutate import ByteMutation, apply_bytes, bounded_memory, element_offsets
from tests.robustness.test_found_bugs import known_bug

pytestmark = [pytest.mark.fuzz, pytest.mark.timeout(FUZZ_TIMEOUT_S)]

SEEDS = ("ct_small", "phantom")


@functools.cache
def seed_series(name: str) -> tuple[bytes, ...]:
    """Three consecutive slices of a seed series, as file bytes (explicit VR little endian)."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if name == "ct_small":
            import pydicom
            from pydicom.data import get_testdata_file

            from tests.robustness.make_corpus import uid

            source = get_testdata_file("CT_small.dcm")
            assert source is not None
            paths = []
            for k in range(3):
                ds = pydicom.dcmread(source)
                ipp = [float(v) for v in ds.ImagePositionPatient]
                ds.ImagePositionPatient = [ipp[0], ipp[1], ipp[2] + 5.0 * k]
                ds.SOPInstanceUID = uid("ct_small", k)
                ds.file_meta.MediaStorageSOPInstanceUID = ds.SOPInstanceUID
                ds.InstanceNumber = k + 1
                paths.append(folder / f"s{k}.dcm")
                ds.save_as(paths[-1], enforce_file_format=True)
        else:  # three consecutive slices of the bundled demo phantom (by position)
            import pydicom

            demo = sorted((ROOT / "assets" / "demo" / "ct").iterdir())
            z = {p: float(pydicom.dcmread(p, stop_before_pixels=True).ImagePositionPatient[2])
                 for p in demo}  # fmt: skip
            paths = sorted(demo, key=z.__getitem__)[38:41]
        assert len(paths) == 3
        return tuple(p.read_bytes() for p in paths)


@functools.cache
def seed_offsets(name: str, index: int) -> list[tuple[int, bool]]:
    """Top-level element offsets of one seed file (for length mutations)."""
    return element_offsets(seed_series(name)[index])


def test_seed_series_load() -> None:
    """Unmutated, both seeds load as three-slice volumes (the fuzzing starts from valid input)."""
    from ctdrill.imaging import load_series

    for name in SEEDS:
        with tempfile.TemporaryDirectory() as tmp:
            for k, data in enumerate(seed_series(name)):
                (Path(tmp) / f"{k}.dcm").write_bytes(data)
            volume = load_series(tmp)
            assert volume.dims[2] == 3
            # real headers with 5 mm slices: coarse for implant planning, nothing else to say
            extra = [w for w in volume.warnings if w.code not in ("padding", "coarse_voxels")]
            assert not extra, volume.warnings


def check_mutated_series(name: str, victim: int, mutations: list[ByteMutation]) -> str:
    """Load the seed series with file ``victim`` mutated; return "load", "refuse" or a bug key."""
    from ctdrill.imaging import WARNING_CODES, ImagingInputError, load_series

    files = list(seed_series(name))
    data = files[victim]
    for mutation in mutations:
        data = apply_bytes(data, mutation, seed_offsets(name, victim))
    files[victim] = data
    with tempfile.TemporaryDirectory() as tmp:
        for k, content in enumerate(files):
            (Path(tmp) / f"{k}.dcm").write_bytes(content)
        try:
            with bounded_memory():
                volume = timed(EXAMPLE_LIMIT_S, lambda: load_series(tmp))
        except ImagingInputError as exc:
            assert str(exc).strip() and "\n" not in str(exc).strip(), repr(str(exc))
            return "refuse"
        except Exception as exc:
            key = known_bug(exc)
            if key is None:
                raise
            return key
    hu = np.asarray(volume.hu)
    assert hu.ndim == 3 and min(hu.shape) >= 1
    assert hu.dtype.kind == "i" or np.isfinite(hu).all()
    assert np.isfinite(volume.affine_lps).all()
    assert set(volume.warning_codes) <= set(WARNING_CODES)
    assert np.isfinite(volume.sample(np.array([[0.0, 0.0, 0.0], [1e9, -1e9, 0.0]]))).all()
    return "load"


@fuzz_settings
@given(
    name=st.sampled_from(SEEDS),
    victim=st.integers(0, 2),
    mutations=byte_mutations(),
)
def test_fuzz_dicom_series(name: str, victim: int, mutations: list[ByteMutation]) -> None:
    check_mutated_series(name, victim, mutations)

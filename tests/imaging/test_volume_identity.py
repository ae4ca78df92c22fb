"""A NIfTI CT's identity hashed as it is read: the definition's value, whatever the path.

``load_ct`` makes int16 NIfTI voxels HU (an integer ``scl_slope``/``scl_inter``, big-endian
bytes swapped), measures and hashes them chunk by chunk as they are read
(:class:`ctdrill.imaging.volumes.identity.HuStream`), in the reading thread or in a worker.
Every path must give :func:`content_uid` of the HU array (the identity's definition, written
out again here), the HU themselves exact, and fall back to float32 HU when the scale leaves
int16 in a late chunk.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from ctdrill.imaging import load_ct
from ctdrill.imaging.volumes import identity
from ctdrill.imaging.volumes.hu_values import LOW_TAIL_PERCENT, low_tail, tail_below, tail_step
from ctdrill.imaging.volumes.identity import HuStream, content_uid
from ctdrill.imaging.volumes.sniff import read_volume_file
from ctdrill.imaging.volumes.types import VolumeFileError
from tests.imaging.volume_writers import write_nifti

AFFINE = np.diag([0.5, 0.25, 1.0, 1.0])
AFFINE[:3, 3] = [-12.5, 30.0, -7.75]
#: 12 x 256 x 200 int16: 1.2 MB, more than one 1 MiB read step.
SHAPE = (12, 256, 200)
#: The real head CT's identity (``../shared/data/vtk_headsq_quarter``), as stored in plans.
HEADSQ_UID = "sha256:0a9d44a43fdeef624f5757e20a8b472ffadb5c677acc4606a761b6f8c426e952"


def _by_hand(hu: np.ndarray, affine_lps: np.ndarray) -> str:
    """The identity's definition: the header text, the affine, the voxels little endian."""
    h = hashlib.sha256(b"ctdrill-volume/1\0" + repr(hu.shape).encode() + b"\0")
    h.update(str(hu.dtype).encode())
    h.update(np.asarray(affine_lps, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(hu).astype(hu.dtype.newbyteorder("<")).tobytes())
    return "sha256:" + h.hexdigest()


def _stored(seed: int = 7) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 3000, size=SHAPE, dtype=np.int16)


@pytest.fixture(params=[False, True], ids=["reading-thread", "worker"])
def threaded(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> bool:
    """Hash in the reading thread or in the worker, whatever the machine's load."""
    monkeypatch.setattr(identity, "core_to_spare", lambda: request.param)
    monkeypatch.setattr(identity, "INLINE_HASH_BYTES", 0)
    return bool(request.param)


@pytest.mark.parametrize(
    ("name", "endian", "slope", "inter"),
    [
        ("ct.nii", "<", 1.0, -1024.0),
        ("ct.nii.gz", "<", 1.0, -1024.0),
        ("ct.nii", ">", None, None),
        ("ct.nii.gz", ">", 2.0, -3000.0),
        ("ct.nii", "<", 1.0, 40000.0),  # an intercept beyond int16 whose HU fit
    ],
)
def test_int16_made_hu_and_hashed_as_read_is_the_definition(
    tmp_path: Path,
    threaded: bool,
    name: str,
    endian: str,
    slope: float | None,
    inter: float | None,
) -> None:
    stored = _stored()
    if inter is not None and inter > 30000:
        stored = stored - 32000
    path = write_nifti(tmp_path / name, stored, AFFINE, slope=slope, inter=inter, endian=endian)
    want = (stored.astype(np.int64) * (slope or 1) + (inter or 0)).astype(np.int16)
    vol = read_volume_file(path, max_bytes=1 << 30, error=VolumeFileError, identity=True)
    assert vol.content_uid is not None and vol.scale is None and vol.data.dtype.isnative
    assert vol.scaled == (slope is not None)
    assert vol.value_range == (float(want.min()), float(want.max()))
    assert vol.tail_sample is not None
    np.testing.assert_array_equal(vol.tail_sample, want.reshape(-1)[:: tail_step(want.size)])
    v = load_ct(path)
    assert v.hu.dtype == np.int16
    np.testing.assert_array_equal(v.hu, want)
    assert v.info.series_uid == _by_hand(want, v.affine_lps) == content_uid(want, v.affine_lps)
    assert v.info.rescale_type == ("scl_slope/scl_inter" if slope is not None else "")
    # one voxel changed, in the last chunk: another identity
    again = stored.copy()
    again[-1, -1, -1] += 1
    other = load_ct(
        write_nifti(tmp_path / ("x" + name), again, AFFINE, slope=slope, inter=inter, endian=endian)
    )
    assert other.info.series_uid != v.info.series_uid


def test_a_scale_leaving_int16_in_a_late_chunk_gives_float32_hu(
    tmp_path: Path, threaded: bool
) -> None:
    stored = _stored()
    stored[-1, -1, -1] = 32000  # only the last chunk's HU leave int16
    path = write_nifti(tmp_path / "ct.nii", stored, AFFINE, slope=1.0, inter=2000.0)
    vol = read_volume_file(path, max_bytes=1 << 30, error=VolumeFileError, identity=True)
    assert vol.content_uid is None and vol.scale == (1.0, 2000.0) and not vol.scaled
    np.testing.assert_array_equal(vol.data, stored)  # the early chunks' scaling undone
    v = load_ct(path)
    want = stored.astype(np.float32) + 2000.0
    assert v.hu.dtype == np.float32
    np.testing.assert_array_equal(v.hu, want)
    assert v.info.series_uid == _by_hand(want, v.affine_lps)


def test_spans_split_inside_a_voxel_are_joined() -> None:
    # an inflate step may end inside a voxel: 1, 2 and 3 bytes at a time
    stored = np.arange(-40, 80, dtype=">i2").reshape(2, 6, 10)
    data = stored.copy()
    raw = memoryview(data.reshape(-1).view(np.uint8))
    with HuStream(data, AFFINE, (3, -7), threaded=False, sample_step=7) as stream:
        at, step = 0, 1
        while at < len(raw):
            stream.feed(raw[at : at + step])
            at, step = at + step, step % 3 + 1
        done = stream.finish()
    assert done is not None
    want = (stored.astype(np.int64) * 3 - 7).astype(np.int16)
    np.testing.assert_array_equal(done.hu, want)
    assert done.uid == _by_hand(want, AFFINE)
    assert done.value_range == (want.min(), want.max()) and done.sample is not None
    np.testing.assert_array_equal(done.sample, want.reshape(-1)[::7])


def test_a_stream_fed_short_refuses_to_name_the_volume() -> None:
    data = np.zeros((2, 2, 2), dtype=np.int16)
    with HuStream(data, AFFINE, None, threaded=False) as stream:
        stream.feed(memoryview(data.reshape(-1).view(np.uint8))[:14])
        with pytest.raises(ValueError, match="fed 14 voxel bytes of 16"):
            stream.finish()


def test_the_real_head_ct_keeps_its_stored_identity(shared_data: Path) -> None:
    # int16 with scl_inter -1024, gzip: made HU and hashed as it is inflated
    v = load_ct(shared_data / "vtk_headsq_quarter" / "headsq_quarter.nii.gz")
    assert v.info.series_uid == HEADSQ_UID == _by_hand(np.asarray(v.hu), v.affine_lps)


def test_the_low_tail_counted_is_numpys_percentile() -> None:
    rng = np.random.default_rng(11)
    for n in [2, 3, 999, 1000, 1001, 4567, 200_000]:
        for values in (
            rng.integers(-32768, 32768, n).astype(np.int16),
            rng.normal(-20.0, 400.0, n).astype(np.int16),
            rng.choice(np.array([-1000, 0, 40, 1200], dtype=np.int16), n),
        ):
            want = float(np.percentile(values, LOW_TAIL_PERCENT))
            assert low_tail(values) == want
            for bound in (-1000.0, -50.0, 0.0, 41.0):
                assert not tail_below(values, bound) or want < bound


def _load_in_child(path: str) -> None:
    load_ct(path)


def test_itk_is_handed_no_file_that_stays(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import multiprocessing
    import tempfile

    from ctdrill.imaging.volumes import itk_header

    for name in ("ct.nii", "ct.nii.gz"):
        load_ct(write_nifti(tmp_path / name, _stored()[:2], AFFINE))
    folder = Path(itk_header._link_folder())
    assert folder.is_dir() and list(folder.iterdir()) == []
    # a forked worker (which leaves without exit handlers) uses this folder, none of its own
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    child = multiprocessing.get_context("fork").Process(
        target=_load_in_child, args=(str(tmp_path / "ct.nii.gz"),)
    )
    child.start()
    child.join(60)
    assert child.exitcode == 0
    assert list((tmp_path / "tmp").iterdir()) == []
    assert list(folder.iterdir()) == []


def test_grey_values_sampled_as_read_are_judged_as_after_the_read(tmp_path: Path) -> None:
    # 2.1 M voxels (a sample of every 2nd, taken across 1 MiB chunks): grey values with air
    # near 0 and a little noise below it: not HU, the low tail named as np.percentile gives it
    from ctdrill.imaging.volumes.hu_values import MIN_HU_LOW_TAIL, hu_problem

    rng = np.random.default_rng(3)
    grey = rng.integers(0, 4000, size=(32, 256, 256), dtype=np.int16)
    grey.reshape(-1)[rng.choice(grey.size, 1500, replace=False)] = -30
    v = load_ct(write_nifti(tmp_path / "grey.nii", grey, AFFINE))
    tail = float(np.percentile(grey.reshape(-1)[:: tail_step(grey.size)], LOW_TAIL_PERCENT))
    assert tail >= MIN_HU_LOW_TAIL and not v.info.is_hu
    (w,) = [w for w in v.warnings if w.code == "not_hu"]
    problem = hu_problem(-30.0, float(grey.max()), tail)
    assert problem is not None and w.message.startswith(problem)
    ct = grey.copy()
    ct[:, :40] = -1000  # air: HU
    assert load_ct(write_nifti(tmp_path / "ct.nii", ct, AFFINE)).info.is_hu

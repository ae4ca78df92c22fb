"""Round four of hostile files: memory, hangs and messages of the volume readers and parsers.

Each class is checked through the Python API (``ctdrill.api``) and through the CLI (one
``error:`` line, exit 2, no traceback, bounded time), with other instances than the ones
first reported: ASCII NRRD data parsed in bounded memory, a file swapped for a FIFO after the
size check, kernel pseudo-files as data files, long gzip header fields, bzip2 bombs, Unicode
digits in an operator spec.
"""

from __future__ import annotations

import os
import threading
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from ctdrill import api
from ctdrill.imaging import ImagingInputError
from ctdrill.safeio import open_regular
from tests.conftest import ASSETS
from tests.imaging.hostile_volumes import AFFINE, HOSTILE
from tests.imaging.volume_writers import ramp, write_mha, write_nrrd
from tests.robustness.outcomes import error_line_problems, run_cli_in_process, run_cli_subprocess
from tests.robustness.test_memory_bombs import BOMB_ADDRESS_SPACE, HANG_S

#: A refusal that must not wait on anything, s.
QUICK_S = 10.0


def _ascii_nrrd(path: Path, n_k: int, n_j: int, n_i: int, *, values: int | None = None) -> Path:
    head = (
        "NRRD0004\ntype: int16\ndimension: 3\n"
        f"sizes: {n_i} {n_j} {n_k}\nencoding: ascii\n"
        "space: left-posterior-superior\n"
        "space directions: (0.5,0,0) (0,0.5,0) (0,0,0.5)\nspace origin: (0,0,0)\n\n"
    )
    count = n_k * n_j * n_i if values is None else values
    body = ("-1000 " * 15 + "-1000\n") * (count // 16) + "-1000\n" * (count % 16)
    path.write_bytes(head.encode() + body.encode())
    return path


def test_ascii_nrrd_is_parsed_in_bounded_memory(tmp_path: Path) -> None:
    # 1 MiB of int16 voxels written as 3.2 MB of text: a list of Python numbers took ~36x
    # the declared bytes; block parsing keeps the peak near the array itself
    from ctdrill.imaging.volumes.sniff import read_volume_file
    from ctdrill.imaging.volumes.types import VolumeFileError

    shape = (16, 128, 256)
    path = _ascii_nrrd(tmp_path / "ascii.nrrd", *shape)
    declared = int(np.prod(shape)) * 2
    volume = api.load_ct(path)  # also imports what the reader needs before measuring
    assert volume.hu.shape == shape and int(volume.hu.max()) == -1000
    tracemalloc.start()
    try:
        read_volume_file(path, max_bytes=declared, error=VolumeFileError)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < declared + (8 << 20), f"peak {peak} bytes for {declared} declared"


def test_ascii_nrrd_holding_too_few_values_is_refused_before_allocating(tmp_path: Path) -> None:
    path = _ascii_nrrd(tmp_path / "short.nrrd", 400, 512, 512, values=1000)
    tracemalloc.start()
    try:
        with pytest.raises(
            ImagingInputError, match=r"short\.nrrd: the header declares 104857600 values"
        ):
            api.load_ct(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 8 << 20
    run = run_cli_subprocess(
        ["inspect", "--ct", str(path)], address_space_bytes=BOMB_ADDRESS_SPACE, timeout_s=HANG_S
    )
    assert not error_line_problems(run), error_line_problems(run)
    assert "short.nrrd" in run.stderr


def test_ascii_nrrd_with_a_value_too_many_is_refused(tmp_path: Path) -> None:
    path = _ascii_nrrd(tmp_path / "long.nrrd", 2, 3, 4, values=25)
    with pytest.raises(
        ImagingInputError, match=r"long\.nrrd: the ascii data hold more than the 24"
    ):
        api.load_ct(path)


def _in_thread(fn: object, timeout_s: float = QUICK_S) -> BaseException | None:
    """Run ``fn`` in a daemon thread; the exception it raised (a hang fails the test)."""
    box: list[BaseException | None] = [None]

    def run() -> None:
        try:
            fn()  # type: ignore[operator]
        except BaseException as exc:
            box[0] = exc

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(timeout_s)
    assert not worker.is_alive(), f"blocked for more than {timeout_s} s"
    return box[0]


def test_open_regular_never_waits_on_a_fifo(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    err = _in_thread(lambda: open_regular(fifo, what="plan file", error=ValueError))
    assert isinstance(err, ValueError) and "named pipe (FIFO)" in str(err), err


def test_a_data_file_swapped_for_a_fifo_after_the_check_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the check by name passes (the file was regular then); the open must look again
    import ctdrill.imaging.volumes.metaimage as metaimage
    import ctdrill.imaging.volumes.nrrd_file as nrrd_file

    monkeypatch.setattr(metaimage, "regular_file_size", lambda *a, **k: 0)
    monkeypatch.setattr(nrrd_file, "regular_file_size", lambda *a, **k: 0)
    mhd = write_mha(tmp_path / "ct.mhd", ramp((4, 5, 6)), AFFINE)
    nhdr = write_nrrd(tmp_path / "ct.nhdr", ramp((4, 5, 6)), AFFINE, detached=True)
    for data in ("ct.raw", "ct.raw.gz"):
        (tmp_path / data).unlink()
        os.mkfifo(tmp_path / data)
    for path, data in ((mhd, "ct.raw"), (nhdr, "ct.raw.gz")):
        err = _in_thread(lambda p=path: api.load_ct(p))
        assert isinstance(err, ImagingInputError), err
        assert f"{data}: the" in str(err) and "named pipe (FIFO)" in str(err), err
        assert path.name in str(err)


def test_a_fifo_named_as_ct_plan_or_mask_is_one_error_line(tmp_path: Path) -> None:
    fifo = tmp_path / "ct.nii"
    os.mkfifo(fifo)
    err = _in_thread(lambda: api.load_ct(fifo))
    assert isinstance(err, ImagingInputError) and "FIFO" in str(err), err
    err = _in_thread(lambda: api.load_plan(fifo))
    assert err is not None and "FIFO" in str(err), err
    started = time.monotonic()
    run = run_cli_subprocess(["inspect", "--ct", str(fifo)], timeout_s=HANG_S)
    assert not error_line_problems(run), error_line_problems(run)
    assert "ct.nii" in run.stderr and time.monotonic() - started < HANG_S


@pytest.mark.parametrize("name", ["mha_data_proc", "nrrd_data_file_proc"])
def test_kernel_pseudo_files_as_data_files_are_named(tmp_path: Path, name: str) -> None:
    path, pattern = HOSTILE[name](tmp_path)
    with pytest.raises(ImagingInputError, match=pattern):
        api.load_ct(path)
    run = run_cli_subprocess(["inspect", "--ct", str(path)], timeout_s=HANG_S)
    assert not error_line_problems(run), error_line_problems(run)
    assert "/proc/self/" in run.stderr and path.name in run.stderr


@pytest.mark.parametrize(
    "name", ["nifti_gz_long_name", "nifti_gz_long_comment", "nrrd_bzip2_bomb", "nifti_version_2"]
)
def test_header_fields_and_ratios_are_bounded_through_the_cli(tmp_path: Path, name: str) -> None:
    path, _ = HOSTILE[name](tmp_path)
    started = time.monotonic()
    run = run_cli_subprocess(
        ["inspect", "--ct", str(path), "--json"],
        address_space_bytes=BOMB_ADDRESS_SPACE,
        timeout_s=HANG_S,
    )
    assert not error_line_problems(run), error_line_problems(run)
    assert path.name in run.stderr and time.monotonic() - started < HANG_S


def test_a_60_mb_gzip_name_is_refused_in_a_fraction_of_a_second(tmp_path: Path) -> None:
    from tests.imaging.hostile_volumes import _gzip_with_field

    plain = HOSTILE["nifti_units_code_5"](tmp_path)[0]
    raw = bytearray(plain.read_bytes())
    raw[123] = 2
    path = tmp_path / "named.nii.gz"
    path.write_bytes(_gzip_with_field(bytes(raw), 0x08, b"x" * (60 << 20)))
    started = time.monotonic()
    with pytest.raises(ImagingInputError, match="file name field runs past 65536 bytes"):
        api.load_ct(path)
    assert time.monotonic() - started < 2.0  # 74 s before: Python's gzip read it byte by byte


@pytest.mark.parametrize("seed", ["\u0663", "\uff11", "1\u00b2", "\u00b9"])
def test_unicode_digits_in_an_operator_spec_are_one_error_line(tmp_path: Path, seed: str) -> None:
    from ctdrill.haptics.session import SessionInputError, parse_operator

    with pytest.raises(SessionInputError, match="seed must be a whole number"):
        parse_operator(f"human:force=12,react_ms=150,seed={seed}")
    with pytest.raises(SessionInputError, match="force must be a finite number"):
        parse_operator("human:force=\u0661\u0662,react_ms=150")
    run = run_cli_in_process(
        [
            "rehearse",
            "--dicom",
            str(ASSETS / "demo" / "ct"),
            "--plan",
            str(ASSETS / "demo" / "plan.json"),
            "--out",
            str(tmp_path / "out"),
            "--operator",
            f"human:force=12,react_ms=150,seed={seed}",
            "--duration-s",
            "1",
        ]
    )
    assert not error_line_problems(run), error_line_problems(run)
    assert "seed" in run.stderr and not (tmp_path / "out").exists()


#: The headers ITK reads otherwise than ctdrill would, one per format and kind of lie.
ITK_DISAGREES = (
    "mha_position_and_offset",
    "mha_rotation_and_matrix",
    "mha_byte_order_spellings",
    "nrrd_line_skip_spellings",
    "nrrd_origin_given_twice",
    "nrrd_origin_two_values",
    "nifti_sheared_sform_over_qform",
    "nifti_sheared_sform_only",
    "nifti_units_code_5",
)


@pytest.mark.parametrize("name", ITK_DISAGREES)
def test_headers_itk_reads_otherwise_are_one_error_line_as_ct_and_as_mask(
    tmp_path: Path, name: str
) -> None:
    import json
    import re

    path, pattern = HOSTILE[name](tmp_path)
    with pytest.raises(ImagingInputError) as err:
        api.load_ct(path)
    assert re.search(pattern, str(err.value)), str(err.value)
    run = run_cli_in_process(["inspect", "--ct", str(path), "--json"])
    assert not error_line_problems(run), error_line_problems(run)
    assert re.search(pattern, run.stderr) and path.name in run.stderr, run.stderr
    doc = json.loads((ASSETS / "demo" / "plan.json").read_text())
    doc["landmarks"] = [{"name": "canal", "kind": "mask", "path": str(path)}]
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps(doc))
    with pytest.raises(ImagingInputError):
        api.load_plan(plan)
    run = run_cli_in_process(
        [
            "export",
            "--ct",
            str(ASSETS / "demo" / "ct"),
            "--plan",
            str(plan),
            "--out",
            str(tmp_path / "o"),
        ]
    )
    assert not error_line_problems(run), error_line_problems(run)
    assert path.name in run.stderr and not (tmp_path / "o").exists()

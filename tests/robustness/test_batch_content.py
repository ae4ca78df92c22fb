"""Resume by content (issue 36): every batch input is identified by its content, whatever its
size; a file replaced by other bytes of the same size with its old modification time
(``cp -p``, ``rsync -t``) is a change, its row redone; the same bytes written again are not."""

from __future__ import annotations

import io
import json
import os
import shutil
from pathlib import Path

import numpy as np

from ctdrill.app.batch.inputs import content_sha256, file_identity, forget_digests
from tests.conftest import ASSETS
from tests.robustness.outcomes import CliRun, run_cli_in_process

DEMO = ASSETS / "demo"
FAST = ["--no-plot", "--rate-hz", "100"]
#: A mask's grid: 1 mm voxels from x = -1 mm (column 0), y 9.., z -36.. (slices far beyond
#: the jaw make the file larger than 4 MiB, the size once identified by size and time only).
MASK_AFFINE = [[1.0, 0, 0, -1.0], [0, 1.0, 0, 9.0], [0, 0, 1.0, -36.0], [0, 0, 0, 1.0]]
MASK_SHAPE = (1100, 40, 100)


def _batch(manifest: Path, out: Path) -> CliRun:
    return run_cli_in_process(["batch", str(manifest), "--out", str(out), *FAST])


def _replace_keeping_size_and_time(path: Path, data: bytes) -> None:
    """``path`` rewritten with ``data`` (the same size), its modification time put back."""
    st = path.stat()
    assert len(data) == st.st_size
    path.write_bytes(data)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert path.stat().st_mtime_ns == st.st_mtime_ns


def _mask(columns: slice) -> bytes:
    grid = np.zeros(MASK_SHAPE, dtype=np.uint8)
    grid[:3, :3, columns] = 1
    buf = io.BytesIO()
    np.save(buf, grid)
    return buf.getvalue()


def test_a_large_mask_replaced_with_its_size_and_time_is_redone(tmp_path: Path) -> None:
    case = tmp_path / "case"
    case.mkdir()
    (case / "mask.npy").write_bytes(_mask(slice(0, 3)))  # x -1..1 mm: far from the drill
    assert (case / "mask.npy").stat().st_size > 4 * 1024 * 1024
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    doc["landmarks"] = [
        {"name": "nerve", "kind": "mask", "path": "mask.npy", "affine_lps": MASK_AFFINE}
    ]
    (case / "plan.json").write_text(json.dumps(doc), encoding="utf-8")
    manifest = tmp_path / "manifest.csv"
    manifest.write_text(f"id,dicom,plan\np,{DEMO / 'ct'},case/plan.json\n", encoding="utf-8")
    out = tmp_path / "out"
    first = _batch(manifest, out)
    assert first.code == 0, first.stderr
    before = json.loads((out / "rows" / "p" / "summary.json").read_text(encoding="utf-8"))
    # the mask moved onto the drill path: same size, old modification time
    _replace_keeping_size_and_time(case / "mask.npy", _mask(slice(32, 35)))
    run = _batch(manifest, out)
    assert run.code == 0 and "1 ok (0 resumed)" in run.stdout, run.stdout
    after = json.loads((out / "rows" / "p" / "summary.json").read_text(encoding="utf-8"))
    assert after["stop_reason"] == "margin" and before["stop_reason"] != "margin"
    # the same bytes again: complete, resumed
    _replace_keeping_size_and_time(case / "mask.npy", (case / "mask.npy").read_bytes())
    assert "1 ok (1 resumed)" in _batch(manifest, out).stdout


def test_a_dicom_slice_edited_in_place_with_its_time_is_redone(tmp_path: Path) -> None:
    ct = tmp_path / "ct"
    shutil.copytree(DEMO / "ct", ct)
    manifest = tmp_path / "manifest.csv"
    manifest.write_text(f"id,dicom,plan\np,ct,{DEMO / 'plan.json'}\n", encoding="utf-8")
    out = tmp_path / "out"
    assert _batch(manifest, out).code == 0
    # a slice's last pixel bytes changed (its size and time kept): another series' data
    victim = sorted(p for p in ct.rglob("*") if p.is_file())[40]
    data = bytearray(victim.read_bytes())
    data[-64:] = bytes(64)
    _replace_keeping_size_and_time(victim, bytes(data))
    run = _batch(manifest, out)
    assert run.code == 0 and "1 ok (0 resumed)" in run.stdout, run.stdout
    os.utime(ct / victim.relative_to(ct))  # a touch: not a change
    assert "1 ok (1 resumed)" in _batch(manifest, out).stdout


def test_identities_are_content_whatever_the_size(tmp_path: Path) -> None:
    big = tmp_path / "big.bin"
    big.write_bytes(b"\1" * (5 * 1024 * 1024))
    first = file_identity(big)
    assert first.startswith(f"{5 * 1024 * 1024}:sha256:") and "mtime" not in first
    forget_digests()
    _replace_keeping_size_and_time(big, b"\2" * (5 * 1024 * 1024))
    assert file_identity(big) != first
    # within a batch the memo holds while the file is the same on disk, and a rewrite (its
    # ctime moves, whatever the mtime says) is hashed again
    digest = content_sha256(big)
    _replace_keeping_size_and_time(big, b"\3" * (5 * 1024 * 1024))
    assert content_sha256(big) != digest

"""Volume files: ``ctdrill.imaging.load_ct`` against SimpleITK, nibabel and pynrrd.

A 512 x 512 x N int16 CT (N = 200; 4 in quick mode; HU noise, so gzip has work) on an oblique
grid is written by SimpleITK as MetaImage (``.mha`` raw and zlib-compressed), by nibabel as
NIfTI (``.nii``, ``.nii.gz``) and by pynrrd as NRRD (raw, gzip). Each file is read warm (page
cache hot) by:

- ``load_ct``: the format by content, the header checked field by field (a proper grid, sizes
  before allocating), the voxels read or inflated into one preallocated array, the content hash
  that names the volume (SHA-256 over the voxels), the HU check;
- the format's reference reader: SimpleITK ``ReadImage`` + ``GetArrayViewFromImage`` (image kept
  alive), nibabel ``load`` + ``np.asarray(img.dataobj)``, pynrrd ``read``.

NIfTI (issue 37: a NIfTI CT in at most :data:`NIFTI_GOAL_X` times nibabel's time) is also read
at 512 x 512 x 300 (``.nii`` and ``.nii.gz``, 150 MiB of voxels) and from the real head CT of
``../shared/data/vtk_headsq_quarter`` (64 x 64 x 93, gzip, ``scl_inter`` -1024), when present,
timed both by the wall clock and by the process's CPU time (every thread), the two readers
alternating. ``load_ct`` makes int16 NIfTI voxels HU, measures and hashes them chunk by chunk
as they are read (:class:`~ctdrill.imaging.volumes.identity.HuStream`), so no voxel is read a
second time; the SHA-256 runs in the reading thread while each 1 MiB chunk is in the cache, or
in a worker beside the read when a core is to spare
(:func:`~ctdrill.imaging.volumes.identity.core_to_spare`: the 1-minute load average under the
cores less one half). nibabel's peer reads into a ``bytearray`` (``mmap=False``).

Also measured: the peak resident memory of refusing a gzip bomb (a 64^3 header over a stream
that inflates to 1 GiB), by ``load_ct`` and by pynrrd's own reader (which inflates everything
before checking the size).
"""

from __future__ import annotations

import gc
import gzip
import os
import tempfile
import time
import zlib
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from bench.report import Section, Timing, headline_row, table, time_pair
from ctdrill.imaging import load_ct

ROWS = COLS = 512
#: Goal for a NIfTI CT: load_ct within this many times nibabel's load of the same file.
NIFTI_GOAL_X = 1.5
#: Slices of the large NIfTI CT (512 x 512 x this).
LARGE_SLICES = 300
ROOT = Path(__file__).resolve().parents[1]
REAL_NII = ROOT.parent / "shared" / "data" / "vtk_headsq_quarter" / "headsq_quarter.nii.gz"
#: The real head CT written again uncompressed: 0.7 MiB read in about a millisecond, so the
#: ratio is the fixed costs of a load (the header checked by ctdrill and by ITK, the hash).
UNCOMPRESSED = "real head CT, uncompressed copy (.nii)"


def _affine() -> np.ndarray:
    a = np.radians(20.0)
    rot = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    out = np.eye(4)
    out[:3, :3] = rot @ np.diag([0.4, 0.4, 0.5])
    out[:3, 3] = (-100.0, -80.0, 20.0)
    return out


def _write(folder: Path, hu: np.ndarray, affine: np.ndarray) -> dict[str, Path]:
    import nibabel
    import nrrd
    import SimpleITK as sitk

    flip = np.diag([-1.0, -1.0, 1.0, 1.0])
    files: dict[str, Path] = {}
    img = sitk.GetImageFromArray(hu)
    img.SetSpacing([0.4, 0.4, 0.5])
    img.SetOrigin(affine[:3, 3].tolist())
    img.SetDirection((affine[:3, :3] / [0.4, 0.4, 0.5]).ravel().tolist())
    for name, compress in (("mha", False), ("mha-zlib", True)):
        files[name] = folder / f"{name}.mha"
        sitk.WriteImage(img, str(files[name]), useCompression=compress)
    nimg = nibabel.Nifti1Image(np.ascontiguousarray(hu.transpose(2, 1, 0)), flip @ affine)
    nimg.set_qform(flip @ affine, code=1)
    for name in ("nii", "nii.gz"):
        files[name] = folder / f"ct.{name}"
        nibabel.save(nimg, str(files[name]))
    header = {
        "space": "left-posterior-superior",
        "space directions": affine[:3, :3].T,
        "space origin": affine[:3, 3],
        "kinds": ["domain"] * 3,
    }
    for name, enc in (("nrrd", "raw"), ("nrrd-gzip", "gzip")):
        files[name] = folder / f"{name}.nrrd"
        nrrd.write(str(files[name]), hu, {**header, "encoding": enc}, index_order="C")
    return files


def _peer(name: str, path: Path) -> tuple[str, Callable[[], object]]:
    if name.startswith("mha"):
        import SimpleITK as sitk

        def sitk_read() -> object:
            image = sitk.ReadImage(str(path))
            arr = sitk.GetArrayViewFromImage(image)
            return int(arr[0, 0, 0]), image

        return "SimpleITK", sitk_read
    if name.startswith("nii"):
        import nibabel

        def nibabel_read() -> object:
            img: Any = nibabel.load(str(path), mmap=False)  # read, not mapped: a fair peer
            return np.asarray(img.dataobj)

        return "nibabel", nibabel_read
    import nrrd

    return "pynrrd", lambda: nrrd.read(str(path), index_order="C")


#: Refuses the bomb in a fresh process and prints its peak resident memory (VmHWM: of this
#: process's own address space; ``ru_maxrss`` would carry the parent's peak over the fork).
_BOMB = """
import sys
from pathlib import Path
path = Path(sys.argv[2])
try:
    if sys.argv[1] == "load_ct":
        from ctdrill.imaging import load_ct
        load_ct(path)
    else:
        import nrrd
        nrrd.read(str(path))
except Exception as exc:
    print(type(exc).__name__, file=sys.stderr)
hwm = next(x for x in open("/proc/self/status") if x.startswith("VmHWM"))
print(int(hwm.split()[1]) // 1024)
"""


def _bomb_peak_mib(folder: Path) -> dict[str, str]:
    import subprocess
    import sys

    path = folder / "bomb.nrrd"
    comp = zlib.compressobj(9, zlib.DEFLATED, 31)
    body = b"".join(comp.compress(bytes(1 << 20)) for _ in range(1024)) + comp.flush()
    path.write_bytes(
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 64 64 64\nencoding: gzip\n"
        b"space: left-posterior-superior\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n"
        b"space origin: (0,0,0)\n\n" + body
    )
    out = {}
    for reader in ("load_ct", "pynrrd"):
        run = subprocess.run(
            [sys.executable, "-c", _BOMB, reader, str(path)],
            capture_output=True,
            text=True,
            check=False,
            timeout=300,
        )
        out[reader] = f"{run.stdout.strip()} MiB ({run.stderr.strip() or 'no error'})"
    return out


def _wall_and_cpu(
    fns: dict[str, Callable[[], object]], repeats: int
) -> dict[str, tuple[Timing, Timing]]:
    """(wall, CPU) timings of each of ``fns``, run round-robin after one warm-up each; CPU is
    the process's (every thread: a worker's hashing counts)."""
    for fn in fns.values():
        fn()
    wall: dict[str, list[float]] = {k: [] for k in fns}
    cpu: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            gc.collect()
            c0, t0 = time.process_time(), time.perf_counter()
            fn()
            wall[name].append(time.perf_counter() - t0)
            cpu[name].append(time.process_time() - c0)
    return {k: (Timing.from_samples(wall[k]), Timing.from_samples(cpu[k])) for k in fns}


def _nifti_rows(
    tmp: Path, n: int, repeats: int
) -> tuple[list[list[str]], list[str], list[tuple[str, float, float, float]]]:
    """The NIfTI goal's rows: a 512 x 512 x ``n`` CT (.nii, .nii.gz) and the real head CT."""
    import nibabel

    from ctdrill.imaging.volumes.identity import core_to_spare

    rng = np.random.default_rng(1)
    hu = rng.integers(-1000, 2000, size=(n, ROWS, COLS), dtype=np.int16)
    flip = np.diag([-1.0, -1.0, 1.0, 1.0])
    nimg = nibabel.Nifti1Image(np.ascontiguousarray(hu.transpose(2, 1, 0)), flip @ _affine())
    nimg.set_qform(flip @ _affine(), code=1)
    files = {}
    for ext in ("nii", "nii.gz"):
        files[f"512 x 512 x {n} .{ext}"] = tmp / f"large.{ext}"
        nibabel.save(nimg, str(files[f"512 x 512 x {n} .{ext}"]))
    del nimg, hu
    if REAL_NII.is_file():
        files["real head CT 64 x 64 x 93 .nii.gz"] = REAL_NII
        raw = tmp / "headsq_quarter.nii"  # the same, uncompressed: the fixed costs alone
        raw.write_bytes(gzip.decompress(REAL_NII.read_bytes()))
        files[UNCOMPRESSED] = raw
    rows, notes, ratios = [], [], []
    for name, path in files.items():
        _, peer = _peer("nii", path)
        v = load_ct(path)
        same = np.array_equal(v.hu, np.asarray(peer()).transpose(2, 1, 0))
        notes.append(f"{name}: voxels identical to nibabel's: {same}")
        spare = core_to_spare()
        got = _wall_and_cpu({"ours": partial(load_ct, path), "nibabel": peer}, repeats)
        (ours, ours_cpu), (theirs, theirs_cpu) = got["ours"], got["nibabel"]
        ratio = ours.median_s / theirs.median_s
        cpu_ratio = ours_cpu.median_s / theirs_cpu.median_s
        where = "worker" if spare and core_to_spare() else "reading thread"
        if name != UNCOMPRESSED:
            ratios.append((name, ratio, cpu_ratio, ours.median_s))
        rows.append(
            [
                name,
                ours.fmt(),
                theirs.fmt(),
                f"{ratio:.2f}",
                ours_cpu.fmt(),
                theirs_cpu.fmt(),
                f"{cpu_ratio:.2f}",
                where,
                f"<= {NIFTI_GOAL_X:g}" if name != UNCOMPRESSED else "(not a goal)",
            ]
        )
    return rows, notes, ratios


def run(quick: bool) -> Section:
    """Time load_ct and each format's reference reader on the same files."""
    n = 4 if quick else 200
    repeats = 2 if quick else 7
    rng = np.random.default_rng(0)
    hu = rng.integers(-1000, 2000, size=(n, ROWS, COLS), dtype=np.int16)
    affine = _affine()
    rows = []
    notes = []
    headline = []
    shortfalls = []
    first_load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-volumes-") as tmp:
        files = _write(Path(tmp), hu, affine)
        for name, path in files.items():
            v = load_ct(path)
            notes.append(
                f"{name}: voxels identical to what was written: {np.array_equal(v.hu, hu)}; "
                f"affine within 1e-6 mm of it: {np.allclose(v.affine_lps, affine, atol=1e-6)}"
            )
            peer_name, peer = _peer(name, path)
            ours, theirs = time_pair(partial(load_ct, path), peer, repeats=repeats)
            ratio = theirs.median_s / ours.median_s
            if ratio < 1.0:
                shortfalls.append(
                    f"{name}: load_ct {ours.fmt()} against {peer_name} {theirs.fmt()} (it also "
                    "checks the geometry, bounds the sizes and hashes the voxels)"
                )
            rows.append(
                [
                    name,
                    f"{path.stat().st_size / 2**20:.0f} MiB",
                    ours.fmt(),
                    peer_name,
                    theirs.fmt(),
                    f"{ratio:.2f}",
                ]
            )
            if name.startswith("mha"):
                headline.append(
                    headline_row(
                        f"read {name} ({n} slices of 512x512)",
                        ours.fmt(),
                        f"SimpleITK {theirs.fmt()}",
                        f"{ratio:.2f}",
                        "a small reader beats SimpleITK (issue 28)",
                    )
                )
        load_before = os.getloadavg()[0]
        nii_rows, nii_notes, nii_ratios = _nifti_rows(
            Path(tmp), 4 if quick else LARGE_SLICES, repeats
        )
        load = 0.5 * (load_before + os.getloadavg()[0])
        bomb = {} if quick else _bomb_peak_mib(Path(tmp))
    for name, ratio, cpu_ratio, ours_s in nii_ratios:
        if ratio > NIFTI_GOAL_X:
            shortfalls.append(
                f"NIfTI {name}: load_ct took {ratio:.2f} x nibabel's time ({ours_s * 1e3:.0f} ms; "
                f"goal <= {NIFTI_GOAL_X:g} x; CPU {cpu_ratio:.2f} x) at load {load:.1f} on the "
                f"{os.cpu_count()} cores (the SHA-256 of the voxels, about 0.6 ms a MiB, is "
                "hashed as they are read)"
            )
    headline.append(
        headline_row(
            f"#37 NIfTI CT 512 x 512 x {4 if quick else LARGE_SLICES} (.nii), load_ct / nibabel",
            nii_rows[0][1],
            f"nibabel {nii_rows[0][2]}",
            f"{nii_rows[0][3]} (load_ct / nibabel)",
            f"<= {NIFTI_GOAL_X:g} x",
        )
    )
    md = [
        __doc__.split("\n\n", 1)[1].strip() if __doc__ else "",
        "",
        f"Volume: {COLS} x {ROWS} x {n} int16 ({n * ROWS * COLS * 2 / 2**20:.0f} MiB); load "
        f"average {0.5 * (first_load + load_before):.1f} on the {os.cpu_count()} cores.",
        "",
        table(["file", "size", "load_ct", "peer", "peer time", "peer / load_ct"], rows),
        "",
        *[f"- {line}" for line in notes],
        "- load_ct's time includes the SHA-256 of the voxels (the volume's identity), hashed "
        "as they are read for int16 NIfTI (made HU as they land), after the read for the "
        "other formats.",
        "",
        f"NIfTI against nibabel (issue 37; load average {load:.1f} on the {os.cpu_count()} "
        "cores; load_ct / nibabel, lower is better; the goal is on the wall clock, the CPU "
        "ratio is what a busy machine converges to; where the SHA-256 ran):",
        "",
        table(
            [
                "file",
                "load_ct",
                "nibabel",
                "load_ct / nibabel",
                "load_ct CPU",
                "nibabel CPU",
                "CPU ratio",
                "hashed in",
                "goal",
            ],
            nii_rows,
        ),
        "",
        *[f"- {line}" for line in nii_notes],
        f"- {UNCOMPRESSED}: not a goal row; 0.7 MiB is read in about a millisecond, so its "
        "ratio is what every load costs beyond nibabel's: ctdrill's header checks, ITK's read "
        "of the header (about 0.4 ms) and the SHA-256 (about 0.45 ms).",
    ]
    if bomb:
        md += ["", "Peak resident memory refusing a gzip bomb (64^3 header, 1 GiB inflated):", ""]
        md += [f"- {k}: {v}" for k, v in bomb.items()]
    return Section(
        title="Loading volume files",
        markdown="\n".join(md),
        shortfalls=tuple(shortfalls),
        headline=tuple(headline),
    )

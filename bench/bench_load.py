"""DICOM series loading: ``ctdrill.imaging.load_series`` against SimpleITK and a raw read of the
bytes.

A 512 x 512 x N CT series (N = 200; 64 in quick mode) is written with
:func:`ctdrill.imaging.phantom.writer.write_series` into a temporary folder, one file per slice,
Explicit VR Little Endian, in two common layouts: signed 16-bit with intercept -1024 (GE style) and
unsigned 12-bit with intercept -1024 (Philips style). Three readers load it:

- ``load_series``: discovery of every file, headers with pydicom, geometry, pixels read at their
  byte offset into one preallocated int16 volume, HU conversion and checks;
- SimpleITK 2.x: ``ImageSeriesReader.GetGDCMSeriesFileNames`` + ``Execute`` with
  ``SetOutputPixelType(sitkInt16)``, then ``GetArrayViewFromImage``;
- raw: the pixel bytes of every file read at a known offset into a preallocated array (the floor:
  no parsing at all).

Warm runs repeat on a hot page cache. Cold runs drop the page cache before each run
(``echo 3 > /proc/sys/vm/drop_caches``) when the process may do so; otherwise only warm figures
are reported and the section says so.
"""

from __future__ import annotations

import os
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bench.report import Section, Timing, table, time_it
from ctdrill.imaging import load_series
from ctdrill.imaging.dicom.discovery import read_headers
from ctdrill.imaging.phantom.writer import write_series

ROWS = COLS = 512


def _can_drop_caches() -> bool:
    try:
        subprocess.run(["sync"], check=True)
        with open("/proc/sys/vm/drop_caches", "w") as fh:
            fh.write("3\n")
    except OSError:
        return False
    return True


def _drop_caches() -> None:
    os.sync()
    with open("/proc/sys/vm/drop_caches", "w") as fh:
        fh.write("3\n")


def _cold(fn: Callable[[], object], repeats: int) -> Timing:
    samples = []
    for _ in range(repeats):
        _drop_caches()
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    arr = np.asarray(samples)
    return Timing(
        median_s=float(np.median(arr)),
        p25_s=float(np.percentile(arr, 25)),
        p75_s=float(np.percentile(arr, 75)),
        min_s=float(arr.min()),
        repeats=repeats,
    )


def _series(folder: Path, n: int, *, unsigned: bool) -> None:
    rng = np.random.default_rng(0)
    hu = rng.integers(-1000, 2000, size=(n, ROWS, COLS), dtype=np.int16)
    aff = np.diag([0.4, 0.4, 0.5, 1.0])
    aff[:3, 3] = (-100.0, -100.0, 0.0)
    write_series(
        folder,
        hu,
        aff,
        unsigned=unsigned,
        bits_stored=12 if unsigned else 16,
        rescale_intercept=-1024.0,
        shuffle_names=True,
    )


def _sitk_reader(folder: Path) -> Callable[[], object]:
    import SimpleITK as sitk

    def read() -> object:
        reader = sitk.ImageSeriesReader()
        reader.SetFileNames(sitk.ImageSeriesReader.GetGDCMSeriesFileNames(str(folder)))
        reader.SetOutputPixelType(sitk.sitkInt16)
        image = reader.Execute()
        arr = sitk.GetArrayViewFromImage(image)
        return int(arr[0, 0, 0]), image  # keep the image alive while the view is used

    return read


def _sitk_array(folder: Path) -> np.ndarray:
    import SimpleITK as sitk

    reader = sitk.ImageSeriesReader()
    reader.SetFileNames(sitk.ImageSeriesReader.GetGDCMSeriesFileNames(str(folder)))
    reader.SetOutputPixelType(sitk.sitkInt16)
    return np.asarray(sitk.GetArrayFromImage(reader.Execute()))


def _raw_reader(folder: Path) -> Callable[[], object]:
    plan = []
    for p in sorted(folder.iterdir()):
        got = read_headers(p)
        assert isinstance(got, list) and got[0].pixel_offset is not None
        plan.append((p, got[0].pixel_offset))
    out = np.empty((len(plan), ROWS, COLS), dtype=np.int16)

    def read() -> object:
        for k, (p, off) in enumerate(plan):
            with p.open("rb") as fh:
                fh.seek(off)
                fh.readinto(out[k].data.cast("B"))
        return out

    return read


def run(quick: bool) -> Section:
    """Time the three readers on both layouts, warm and (if permitted) cold."""
    n = 64 if quick else 200
    repeats = 3 if quick else 7
    cold_ok = _can_drop_caches()
    rows = []
    notes = []
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-load-") as tmp:
        for label, unsigned in (("int16, intercept -1024", False), ("uint 12-bit", True)):
            folder = Path(tmp) / ("u12" if unsigned else "s16")
            _series(folder, n, unsigned=unsigned)
            ours = lambda f=folder: load_series(f)  # noqa: E731
            sitk = _sitk_reader(folder)
            raw = _raw_reader(folder)
            # Same values from both real readers.
            v = load_series(folder)
            ref = _sitk_array(folder)
            same = bool(np.array_equal(ref, v.hu) or np.array_equal(ref[::-1], v.hu))
            notes.append(f"{label}: load_series and SimpleITK voxel values identical: {same}")
            t_ours = time_it(ours, repeats=repeats)
            t_sitk = time_it(sitk, repeats=repeats)
            t_raw = time_it(raw, repeats=repeats)
            rows.append(
                [
                    f"{label}, warm",
                    t_ours.fmt(),
                    t_sitk.fmt(),
                    t_raw.fmt(),
                    f"{t_ours.median_s / t_sitk.median_s:.2f}",
                ]
            )
            if cold_ok:
                c_ours = _cold(ours, max(2, repeats // 2))
                c_sitk = _cold(sitk, max(2, repeats // 2))
                c_raw = _cold(raw, max(2, repeats // 2))
                rows.append(
                    [
                        f"{label}, cold",
                        c_ours.fmt(),
                        c_sitk.fmt(),
                        c_raw.fmt(),
                        f"{c_ours.median_s / c_sitk.median_s:.2f}",
                    ]
                )
    md = [
        __doc__.split("\n\n", 1)[1].strip() if __doc__ else "",
        "",
        f"Series: {COLS} x {ROWS} x {n} ({n * ROWS * COLS * 2 / 2**20:.0f} MiB of int16).",
        "",
        table(
            ["layout", "load_series", "SimpleITK (int16)", "raw bytes", "load_series / SimpleITK"],
            rows,
        ),
        "",
        *[f"- {line}" for line in notes],
        "- Cold runs: "
        + ("page cache dropped before each run." if cold_ok else "not permitted here; warm only."),
    ]
    return Section(title="Loading a DICOM series", markdown="\n".join(md))

"""The synthetic corpus cases: each builder writes one faulty series and returns its outcomes."""

from __future__ import annotations

import os
import shutil
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
from pydicom.dataelem import DataElement
from pydicom.uid import (
    UID,
)

from tests.robustness.corpus_base import (
    COLS,
    INTERCEPT,
    ORIGIN_LPS,
    REFUSE,
    ROWS,
    SLICES,
    Expect,
    add_junk,
    base_hu,
    base_slices,
    colour_slice,
    ct_slice,
    load,
    nested_sequence,
    patch_pixel_length,
    uid,
    write,
    write_all,
)

# --------------------------------------------------------------------------------------------
# Synthetic cases. Each builder writes into ``folder`` and returns the acceptable outcomes.
# --------------------------------------------------------------------------------------------

Builder = Callable[[Path], tuple[Expect, ...]]
DIMS = (COLS, ROWS, SLICES)
#: A corrupt slice may be reported and left out (then its place is a gap) or refuse the series.
SKIP_OR_REFUSE_MIDDLE = (
    REFUSE,
    load("files_skipped", "slice_gap", optional=["nonuniform_spacing"]),
)
SKIP_OR_REFUSE_END = (REFUSE, load("files_skipped", dims=(COLS, ROWS, SLICES - 1)))


def _clean(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="clean"), folder)
    return (load(dims=DIMS),)


def _implicit_vr(folder: Path) -> tuple[Expect, ...]:
    folder.mkdir(parents=True)
    for k, ds in enumerate(base_slices(series="implicit")):
        write(ds, folder / f"{k:03d}.dcm", implicit=True)
    return (load(dims=DIMS),)


def _oblique(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="oblique", orientation=OBLIQUE_IOP), folder)
    return (load(dims=DIMS),)


def _gantry_tilt(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="tilt", orientation=TILT_IOP)
    for k, ds in enumerate(slices):  # positions step along z, not along the tilted normal
        ds.ImagePositionPatient = [ORIGIN_LPS[0], ORIGIN_LPS[1], ORIGIN_LPS[2] + k]
    write_all(slices, folder)
    return (load("gantry_tilt", dims=DIMS),)


def _truncated_pixels(folder: Path) -> tuple[Expect, ...]:
    paths = write_all(base_slices(series="trunc-pix"), folder)
    middle = paths[SLICES // 2]
    middle.write_bytes(middle.read_bytes()[: -(ROWS * COLS)])  # half the pixel bytes gone
    return SKIP_OR_REFUSE_MIDDLE


def _truncated_header(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="trunc-head")
    paths = write_all(slices, folder)
    last = paths[-1]
    last.write_bytes(last.read_bytes()[:300])  # cut inside the data set header
    return SKIP_OR_REFUSE_END


def _short_pixeldata(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="short-pix")
    slices[SLICES // 2].PixelData = slices[SLICES // 2].PixelData[: ROWS * COLS]
    write_all(slices, folder)
    return SKIP_OR_REFUSE_MIDDLE


def _short_pixeldata_all(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="short-pix-all")
    for ds in slices:
        ds.PixelData = ds.PixelData[:64]
    write_all(slices, folder)
    return (REFUSE,)


def _missing(keyword: str) -> Builder:
    def build(folder: Path) -> tuple[Expect, ...]:
        slices = base_slices(series=f"missing-{keyword}")
        for ds in slices:
            delattr(ds, keyword)
        write_all(slices, folder)
        return (REFUSE,)

    return build


def _missing_ipp_one(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="missing-ipp-one")
    del slices[SLICES // 2].ImagePositionPatient
    write_all(slices, folder)
    return SKIP_OR_REFUSE_MIDDLE


def _bad_value(keyword: str, value: object, vr: str | None = None) -> Builder:
    def build(folder: Path) -> tuple[Expect, ...]:
        slices = base_slices(series=f"bad-{keyword}-{value}")
        for ds in slices:
            if vr is None:
                setattr(ds, keyword, value)
            else:
                ds[keyword] = DataElement(ds[keyword].tag, vr, value)
        write_all(slices, folder)
        return (REFUSE,)

    return build


def _rows_wrong_vr(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="rows-ds")
    for ds in slices:
        ds["Rows"] = DataElement(0x00280010, "DS", str(ROWS))
    write_all(slices, folder)
    return (load(dims=DIMS), REFUSE)


def _slope_wrong_vr(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="slope-fd")
    for ds in slices:
        ds["RescaleSlope"] = DataElement(0x00281053, "FD", 1.0)
    write_all(slices, folder)
    return (load(dims=DIMS), REFUSE)


def _duplicate_identical(folder: Path) -> tuple[Expect, ...]:
    paths = write_all(base_slices(series="dup-same"), folder)
    shutil.copyfile(paths[3], folder / "copy_of_slice.dcm")
    return (load("duplicate_slice", dims=DIMS),)


def _duplicate_conflicting(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="dup-conflict")
    write_all(slices, folder)
    other = base_hu()[3] + 500
    ds = ct_slice(other, slices[3].ImagePositionPatient, series="dup-conflict", instance=99)
    write(ds, folder / "other_at_slice3.dcm")
    return (REFUSE,)


def _gap(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="gap")
    del slices[4]
    write_all(slices, folder)
    return (load("slice_gap", optional=["nonuniform_spacing"]),)


def _nonuniform(folder: Path) -> tuple[Expect, ...]:
    z_mm = [0.0, 1.0, 2.0, 2.7, 3.7, 4.7, 5.7, 6.7]
    write_all(base_slices(series="nonuniform", z_mm=z_mm), folder)
    return (load("nonuniform_spacing", dims=DIMS),)


def _two_series(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="series-a"), folder / "a")
    write_all(base_slices(series="series-b", hu=base_hu()[:5]), folder / "b")
    return (load("multiple_series", dims=DIMS),)


def _localizer(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="with-localizer"), folder)
    scout = ct_slice(
        np.zeros((20, 16), np.int16),
        (-40.0, 0.0, 60.0),
        series="with-localizer",
        instance=500,
        orientation=(1.0, 0.0, 0.0, 0.0, 0.0, -1.0),
    )
    scout.ImageType = ["ORIGINAL", "PRIMARY", "LOCALIZER"]
    write(scout, folder / "scout")
    return (load("localizer_dropped", dims=DIMS),)


def _junk_beside(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="junk-beside"), folder)
    add_junk(folder)
    return (load("files_skipped", dims=DIMS),)


def _junk_only(folder: Path) -> tuple[Expect, ...]:
    add_junk(folder)
    return (REFUSE,)


def _empty_dir(folder: Path) -> tuple[Expect, ...]:
    folder.mkdir(parents=True)
    return (REFUSE,)


def _no_such_dir(folder: Path) -> tuple[Expect, ...]:
    return (REFUSE,)  # never created


def _dicomdir(folder: Path, *, with_images: bool) -> tuple[Expect, ...]:
    from pydicom.fileset import FileSet

    slices = base_slices(series="dicomdir")
    staging = folder.parent / f".{folder.name}-staging"
    paths = write_all(slices, staging)
    fileset = FileSet()
    fileset.UID = UID(uid("dicomdir", with_images))
    for path in paths:
        fileset.add(path)
    fileset.write(folder)
    shutil.rmtree(staging)
    if with_images:
        return (load("files_skipped", dims=DIMS), load(dims=DIMS))
    for path in folder.rglob("*"):
        if path.is_file() and path.name != "DICOMDIR":
            path.unlink()
    return (REFUSE,)


def _colour_series(folder: Path) -> tuple[Expect, ...]:
    slices = [
        colour_slice((*ORIGIN_LPS[:2], ORIGIN_LPS[2] + k), series="colour", instance=k)
        for k in range(SLICES)
    ]
    write_all(slices, folder)
    return (REFUSE,)


def _colour_beside(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="colour-beside"), folder)
    write(colour_slice(ORIGIN_LPS, series="colour-capture", instance=0), folder / "capture")
    return (load("files_skipped", dims=DIMS), load("multiple_series", dims=DIMS))


def _not_hu(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="not-hu")
    for ds in slices:
        ds.RescaleType = "US"
    write_all(slices, folder)
    return (load("not_hu", dims=DIMS),)


def _padding(folder: Path) -> tuple[Expect, ...]:
    hu = base_hu()
    hu[:, :2, :] = -3024  # stored 0xF830 below: outside the scan circle
    slices = base_slices(series="padding", hu=hu)
    for ds in slices:
        ds.PixelPaddingValue = -3024 - int(INTERCEPT)
    write_all(slices, folder)
    return (load("padding", dims=DIMS),)


#: A slice unlike the others may be dropped as a stray (localizer_dropped or files_skipped).
STRAY_OR_REFUSE_MIDDLE = (
    *SKIP_OR_REFUSE_MIDDLE,
    load("localizer_dropped", "slice_gap", optional=["nonuniform_spacing"]),
)


def _mixed_dims(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="mixed-dims")
    odd = ct_slice(np.zeros((ROWS + 2, COLS), np.int16), slices[4].ImagePositionPatient,
                   series="mixed-dims", instance=4)  # fmt: skip
    slices[4] = odd
    write_all(slices, folder)
    return STRAY_OR_REFUSE_MIDDLE


def _mixed_orientation(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="mixed-iop")
    slices[4].ImageOrientationPatient = [0.0, 1.0, 0.0, 1.0, 0.0, 0.0]
    write_all(slices, folder)
    return STRAY_OR_REFUSE_MIDDLE


def _deep_nesting(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="deep-nesting")
    slices[-1].ContentSequence = nested_sequence(1500)
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 40000))
    try:
        write_all(slices, folder)
    finally:
        sys.setrecursionlimit(limit)
    return (*SKIP_OR_REFUSE_END, load(dims=DIMS))


def _symlink_loop(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="symlink-loop"), folder)
    (folder / "loop").symlink_to(".", target_is_directory=True)  # relative: reproducible
    return (load(dims=DIMS), load("files_skipped", dims=DIMS), REFUSE)


def _fifo(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="fifo"), folder)
    os.mkfifo(folder / "pipe.dcm")  # a named pipe: open() blocks until a writer comes
    return (load(dims=DIMS), load("files_skipped", dims=DIMS))


def _device_links(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="device-links"), folder)
    (folder / "zero.dcm").symlink_to("/dev/zero")  # endless zeros
    (folder / "random.dcm").symlink_to("/dev/urandom")  # endless noise
    return (load(dims=DIMS), load("files_skipped", dims=DIMS))


def _single_slice(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="single")[:1], folder)
    return (REFUSE, load("single_slice", dims=(COLS, ROWS, 1)))


def _unknown_vr(folder: Path) -> tuple[Expect, ...]:
    for path in write_all(base_slices(series="unknown-vr"), folder):
        data = bytearray(path.read_bytes())
        at = data.find(b"\x18\x00\x50\x00DS")  # SliceThickness
        data[at + 4 : at + 6] = b"D["  # a VR that does not exist
        path.write_bytes(bytes(data))
    return (REFUSE, load(dims=DIMS))


def _meta_misaligned(folder: Path) -> tuple[Expect, ...]:
    for path in write_all(base_slices(series="meta-misaligned"), folder):
        data = path.read_bytes()
        at = data.find(b"1.2.840.10008.1.2.1\x00") + 17  # inside the transfer syntax value
        path.write_bytes(data[:at] + b"\x00" * 4 + data[at:])
    return (REFUSE,)


def _rle_lossless(folder: Path) -> tuple[Expect, ...]:
    from pydicom.uid import RLELossless

    slices = base_slices(series="rle")
    for ds in slices:
        ds.compress(RLELossless, ds.pixel_array.copy(), generate_instance_uid=False)
    write_all(slices, folder)
    return (load(dims=DIMS),)


def _j2k_lossy(folder: Path) -> tuple[Expect, ...]:
    from pydicom.uid import JPEG2000

    size = 64  # JPEG 2000's default six resolutions need at least 32 x 32 pixels
    slices = []
    for k in range(4):
        hu = ((np.arange(size * size).reshape(size, size) * (k + 3)) % 1500 - 1000).astype(np.int16)
        ds = ct_slice(hu, (*ORIGIN_LPS[:2], ORIGIN_LPS[2] + k), series="j2k-lossy", instance=k)
        ds.compress(
            JPEG2000,
            ds.pixel_array.copy(),
            encoding_plugin="pylibjpeg",
            j2k_cr=[20],
            generate_instance_uid=False,
        )
        ds.LossyImageCompression = "01"
        ds.LossyImageCompressionRatio = 20
        ds.LossyImageCompressionMethod = "ISO_15444_1"
        slices.append(ds)
    write_all(slices, folder)
    return (load("lossy_compression", dims=(size, size, 4)),)


def _transfer_syntax(ts_uid: str, expect: Expect = REFUSE) -> Builder:
    def build(folder: Path) -> tuple[Expect, ...]:
        folder.mkdir(parents=True)
        for k, ds in enumerate(base_slices(series=f"ts-{ts_uid}")):
            ds.file_meta.TransferSyntaxUID = UID(ts_uid)
            ds.save_as(
                folder / f"{k:03d}.dcm",
                implicit_vr=False,
                little_endian=True,
                enforce_file_format=True,
            )
        return (expect,)

    return build


def _undefined_root_transfer_syntax(folder: Path) -> tuple[Expect, ...]:
    """TransferSyntaxUID ``1.2.840.10008.1.2.9``: under the DICOM root, defined nowhere.

    pydicom refuses to write it, so the files are written Explicit VR Little Endian and the
    UID's last digit is patched in the file meta (same length, so every offset stays valid).
    """
    folder.mkdir(parents=True)
    for k, ds in enumerate(base_slices(series="ts-undefined-root")):
        path = folder / f"{k:03d}.dcm"
        ds.save_as(path, implicit_vr=False, little_endian=True, enforce_file_format=True)
        data = path.read_bytes()
        old, new = b"1.2.840.10008.1.2.1\x00", b"1.2.840.10008.1.2.9\x00"
        at = data.index(old, 132)
        path.write_bytes(data[:at] + new + data[at + len(old) :])
    return (REFUSE,)


def _bomb_rows_cols(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="bomb-rc")
    for ds in slices:
        ds.Rows = 65535
        ds.Columns = 65535
    write_all(slices, folder)
    return (REFUSE,)


def _bomb_frames(folder: Path) -> tuple[Expect, ...]:
    ds = base_slices(series="bomb-frames")[0]
    ds.NumberOfFrames = 2147483647
    write(ds, folder / "multiframe.dcm")
    return (REFUSE,)


def _bomb_element_length(folder: Path) -> tuple[Expect, ...]:
    for path in write_all(base_slices(series="bomb-length"), folder):
        patch_pixel_length(path, 0xFFFFFFF0)
    return (REFUSE,)


def _bomb_one_element_length(folder: Path) -> tuple[Expect, ...]:
    paths = write_all(base_slices(series="bomb-length-one"), folder)
    patch_pixel_length(paths[-1], 0xFFFFFFF0)
    return SKIP_OR_REFUSE_END


def _bomb_header_element_length(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="bomb-header-length")
    for ds in slices:
        ds.add_new(0x00091010, "OB", b"\x00" * 8)  # a private binary element in the header
    for path in write_all(slices, folder):
        patch_pixel_length(path, 0xFFFFFFF0, tag=b"\x09\x00\x10\x10")
    return (REFUSE,)


OBLIQUE_IOP = (0.8, 0.6, 0.0, -0.6, 0.8, 0.0)
TILT_IOP = (1.0, 0.0, 0.0, 0.0, float(np.cos(np.radians(20))), float(np.sin(np.radians(-20))))

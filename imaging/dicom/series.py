"""Load a DICOM CT series into a :class:`~ctdrill.imaging.volume.CTVolume`.

Discovery (:mod:`ctdrill.imaging.dicom.discovery`) reads headers only; this module picks the series
and its spatial stack, orders and de-duplicates the slices, builds the geometry
(:mod:`ctdrill.imaging.dicom.geometry`), checks the memory needed, then decodes the pixels into one
preallocated array (:mod:`ctdrill.imaging.dicom.pixels`). Every oddity becomes a
:class:`LoadWarning`; what cannot be a trustworthy volume raises an :class:`ImagingInputError`
subclass.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ctdrill.imaging.dicom.discovery import Skipped, SliceHeader, scan
from ctdrill.imaging.dicom.geometry import (
    frame_axes,
    group_positions,
    orientation_key,
    require_geometry,
    stack_geometry,
)
from ctdrill.imaging.dicom.identity import matches_series, series_label
from ctdrill.imaging.dicom.pixels import padding_mask, read_stored, rescale, stored_dtype, to_hu
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.resolution import coarse_voxels_warning, grid_sampling_mm
from ctdrill.imaging.volume import CTVolume, LoadWarning, SeriesInfo

DEFAULT_MAX_BYTES = 2 * 1024**3


class SeriesInputError(ImagingInputError):
    """No usable CT series, or an ambiguous / inconsistent one."""


class MemoryCapError(SeriesInputError):
    """The volume would need more memory than allowed."""


class DuplicateSliceError(SeriesInputError):
    """Two different images claim the same slice position."""


@dataclass(frozen=True)
class SeriesSummary:
    """One candidate CT stack found under a path (for listing and selection)."""

    series_uid: str
    n_slices: int
    n_positions: int
    rows: int
    cols: int
    description: str


@dataclass(frozen=True)
class _Selection:
    planes: tuple[SliceHeader, ...]
    others: tuple[SeriesSummary, ...]
    warnings: tuple[LoadWarning, ...]


def _is_greyscale(h: SliceHeader) -> bool:
    return h.samples_per_pixel == 1 and h.photometric in ("MONOCHROME1", "MONOCHROME2")


def _summary(planes: Sequence[SliceHeader]) -> SeriesSummary:
    h = planes[0]
    n_positions = len(planes)
    if h.iop is not None and all(p.ipp is not None for p in planes):
        with np.errstate(all="ignore"):  # damaged geometry is refused later, with its name
            _, _, normal = frame_axes(h)
            pos = [float(np.asarray(p.ipp) @ normal) for p in planes]
        if all(np.isfinite(pos)):
            n_positions = len({round(x, 2) for x in pos})
    return SeriesSummary(
        h.series_uid,
        len(planes),
        n_positions,
        h.rows,
        h.cols,
        str(h.meta.get("series_description", "")),
    )


def _rank(summary: SeriesSummary) -> tuple[int, int, str]:
    return (-summary.n_positions, -summary.n_slices, summary.series_uid)


def _stacks(
    headers: Sequence[SliceHeader],
) -> tuple[dict[str, list[SliceHeader]], list[SliceHeader], list[Skipped]]:
    """Main stack per series, the localizer planes dropped, and colour planes skipped."""
    by_series: dict[str, list[SliceHeader]] = defaultdict(list)
    localizers: list[SliceHeader] = []
    colour: list[Skipped] = []
    for h in headers:
        if not _is_greyscale(h):
            colour.append(
                Skipped(h.path, f"colour/non-greyscale image ({h.photometric}): not a CT volume")
            )
        elif "LOCALIZER" in h.image_type:
            localizers.append(h)
        else:
            by_series[h.series_uid].append(h)
    stacks: dict[str, list[SliceHeader]] = {}
    for uid, planes in by_series.items():
        groups: dict[object, list[SliceHeader]] = defaultdict(list)
        for h in planes:
            key = None if h.iop is None else (orientation_key(h), h.rows, h.cols)
            groups[key].append(h)
        if None in groups and len(groups) > 1:
            # Planes without IOP in a series that has oriented planes: refuse that plane.
            require_geometry(groups[None][0])
        ranked = sorted(groups.values(), key=len, reverse=True)
        stacks[uid] = ranked[0]
        for other in ranked[1:]:
            localizers.extend(other)
    return stacks, localizers, colour


def _select(path: Path, series_uid: str | None) -> _Selection:
    found = scan(path)
    stacks, localizers, colour = _stacks(found.headers)
    skipped = list(found.skipped) + colour
    summaries = sorted((_summary(p) for p in stacks.values()), key=_rank)
    if not summaries:
        reasons = Counter(s.reason for s in skipped)
        detail = "; ".join(f"{n} x {r}" for r, n in reasons.most_common())
        n_loc = len({h.path for h in localizers})
        extra = f"; {n_loc} localizer file(s)" if n_loc else ""
        if found.unreadable:
            extra += f"; {_unreadable_text(path, found.unreadable)} (check the permissions)"
        raise SeriesInputError(
            f"{path}: no CT image series (not a CT volume): {len(skipped)} DICOM file(s) "
            f"skipped ({detail or 'none'}){extra}, {len(found.not_dicom)} non-DICOM file(s); "
            "point to a folder holding a CT series"
        )
    if series_uid is None:
        chosen = summaries[0]
    else:
        # the UID itself, or its hash (or a hash prefix) as outputs name series
        match = [s for s in summaries if matches_series(series_uid, s.series_uid)]
        if len(match) != 1:
            listing = ", ".join(
                f"{series_label(s.series_uid)} ({s.n_slices} slices)" for s in summaries
            )
            problem = "not found" if not match else "matches several series"
            raise SeriesInputError(
                f"{path}: series {series_uid} {problem}; available CT series (hash of the "
                f"UID): {listing}"
            )
        chosen = match[0]
    others = tuple(s for s in summaries if s.series_uid != chosen.series_uid)
    warnings: list[LoadWarning] = []
    if others:
        listing = ", ".join(f"{series_label(s.series_uid)} ({s.n_slices} slices)" for s in others)
        warnings.append(
            LoadWarning(
                "multiple_series",
                f"loaded {series_label(chosen.series_uid)} ({chosen.n_slices} slices); also "
                f"present: {listing}; select one with --series HASH (series named by the "
                "SHA-256 of their UID)",
            )
        )
    if localizers:
        n_files = len({h.path for h in localizers})
        warnings.append(
            LoadWarning(
                "localizer_dropped",
                f"{n_files} localizer / differently oriented image file(s) left out",
            )
        )
    if skipped:
        reasons = Counter(s.reason for s in skipped)
        detail = "; ".join(f"{n} x {r}" for r, n in reasons.most_common())
        warnings.append(
            LoadWarning("files_skipped", f"{len(skipped)} non-volume DICOM file(s): {detail}")
        )
    if found.unreadable:
        warnings.append(
            LoadWarning(
                "files_unreadable",
                f"{_unreadable_text(path, found.unreadable)}: the series may be incomplete; "
                "check the permissions and load again",
            )
        )
    return _Selection(tuple(stacks[chosen.series_uid]), others, tuple(warnings))


def _unreadable_text(root: Path, paths: Sequence[Path]) -> str:
    """``3 file(s) or folder(s) could not be read (...), e.g. sub/IM1`` (relative to ``root``,
    whose own name may be a patient's)."""
    try:
        first = str(paths[0].relative_to(root)) if paths[0] != root else "the folder itself"
    except ValueError:
        first = paths[0].name
    return (
        f"{len(paths)} file(s) or folder(s) could not be read (permission denied or an I/O "
        f"error), e.g. {first}"
    )


def list_series(path: str | Path) -> tuple[SeriesSummary, ...]:
    """The CT stacks under ``path``, largest first (headers only)."""
    stacks, _, _ = _stacks(scan(Path(path)).headers)
    return tuple(sorted((_summary(p) for p in stacks.values()), key=_rank))


def _where(h: SliceHeader) -> str:
    return f"{h.path.name}" + (f"[frame {h.frame + 1}]" if h.n_frames > 1 else "")


def _dedupe(
    groups: list[list[SliceHeader]], normal: np.ndarray
) -> tuple[list[SliceHeader], list[LoadWarning]]:
    """One plane per position; identical duplicates dropped, conflicting ones refused."""
    kept: list[SliceHeader] = []
    n_dropped = 0
    for group in groups:
        first = group[0]
        if len(group) > 1:
            ref = read_stored(first)
            for other in group[1:]:
                same_ipp = np.allclose(first.ipp, other.ipp, atol=0.01)  # type: ignore[arg-type]
                same_pix = (
                    (other.rows, other.cols) == (first.rows, first.cols)
                    and bool(np.array_equal(read_stored(other), ref))
                    and rescale(other) == rescale(first)
                )
                if not (same_ipp and same_pix):
                    pos = float(np.asarray(first.ipp) @ normal)
                    raise DuplicateSliceError(
                        f"{first.path.parent}: {len(group)} different images at slice "
                        f"position {pos:.3f} mm ({', '.join(_where(h) for h in group)}); "
                        "not a volume - remove the extra images or select one series"
                    )
                n_dropped += 1
        kept.append(first)
    warnings = []
    if n_dropped:
        warnings.append(
            LoadWarning("duplicate_slice", f"{n_dropped} identical duplicate slice(s) left out")
        )
    return kept, warnings


def _require_pixels_and_rescale(h: SliceHeader) -> None:
    """Refuse a plane whose rescale or pixel data cannot give a trustworthy slice."""
    where = _where(h) if h.n_frames > 1 else str(h.path)
    for name, value in (("RescaleSlope", h.slope), ("RescaleIntercept", h.intercept)):
        if value is not None and not np.isfinite(value):
            raise SeriesInputError(f"{where}: {name} {value} is not a finite number; fix the file")
    if h.slope == 0.0:
        raise SeriesInputError(
            f"{where}: RescaleSlope 0 maps every voxel to the intercept; fix the file"
        )
    if h.pixel_offset is None or h.pixel_length is None:
        return
    first = h.pixel_offset - h.frame * h.frame_bytes
    need = h.frame_bytes * h.n_frames
    if h.pixel_length < need:
        raise SeriesInputError(
            f"{where}: PixelData holds {h.pixel_length} bytes but Rows x Columns x "
            f"NumberOfFrames ({h.rows} x {h.cols} x {h.n_frames}) needs {need}; "
            "the file is truncated or its header is wrong"
        )
    if first + h.pixel_length > h.file_size:
        raise SeriesInputError(
            f"{where}: PixelData declares {h.pixel_length} bytes but the file ends "
            f"{h.file_size - first} bytes after its start; the copy is incomplete, copy it again"
        )


def _check_consistent(planes: Sequence[SliceHeader]) -> None:
    first = planes[0]
    assert first.pixel_spacing is not None
    for h in planes[1:]:
        assert h.pixel_spacing is not None
        if not np.allclose(h.pixel_spacing, first.pixel_spacing, rtol=1e-4, atol=1e-6):
            raise SeriesInputError(
                f"{h.path}: PixelSpacing {h.pixel_spacing} differs from {first.path.name} "
                f"{first.pixel_spacing} in the same stack; the series is not one volume"
            )


def _info(planes: Sequence[SliceHeader], n_files: int, is_hu: bool, tilt: float) -> SeriesInfo:
    h = planes[0]
    m = h.meta
    return SeriesInfo(
        series_uid=h.series_uid,
        modality=h.modality,
        is_hu=is_hu,
        study_description=str(m.get("study_description", "")),
        series_description=str(m.get("series_description", "")),
        manufacturer=str(m.get("manufacturer", "")),
        model=str(m.get("model", "")),
        kvp=m.get("kvp"),
        kernel=str(m.get("kernel", "")),
        slice_thickness_mm=m.get("slice_thickness_mm"),
        transfer_syntax=h.transfer_syntax,
        sop_class_uid=h.sop_class_uid,
        rescale_type=h.rescale_type,
        n_files=n_files,
        gantry_tilt_deg=tilt,
        frame_of_reference_uid=str(m.get("frame_of_reference_uid", "")),
    )


def load_series(
    path: str | Path, *, series_uid: str | None = None, max_bytes: int = DEFAULT_MAX_BYTES
) -> CTVolume:
    """Load the CT series under ``path`` (a folder tree or one file).

    Parameters
    ----------
    path : str | Path
        Folder (searched recursively) or a single DICOM file.
    series_uid : str | None
        SeriesInstanceUID to load, or the SHA-256 of it (or the hash's first 8+ hex digits)
        as outputs name series; default the CT stack with the most slices.
    max_bytes : int
        Refuse when the decoded volume (HU plus validity mask) would exceed this, bytes.

    Returns
    -------
    CTVolume
        ``hu`` (slices, rows, cols) int16 where exact else float32, ordered along the normal.

    Raises
    ------
    ImagingInputError
        No CT series, missing geometry, conflicting duplicates, memory cap, undecodable pixels.
    """
    src = Path(path)
    sel = _select(src, series_uid)
    planes = list(sel.planes)
    for h in planes:
        require_geometry(h)
        _require_pixels_and_rescale(h)
    _check_consistent(planes)
    _, _, normal = frame_axes(planes[0])
    ordered, dup_warnings = _dedupe(group_positions(planes, normal), normal)
    geom = stack_geometry(ordered)
    n, rows, cols = len(ordered), ordered[0].rows, ordered[0].cols
    for h in ordered:
        stored_dtype(h)  # refuses unsupported BitsAllocated before any decoding
    integral = all(float(v).is_integer() for h in ordered for v in rescale(h))
    dtype = np.dtype(np.int16 if integral else np.float32)
    has_padding = any(h.padding_value is not None for h in ordered)
    need = n * rows * cols * (dtype.itemsize + (1 if has_padding else 0))
    if need > max_bytes:
        raise MemoryCapError(
            f"{src}: the volume {cols}x{rows}x{n} needs {need / 2**20:.0f} MiB, above the "
            f"limit of {max_bytes / 2**20:.0f} MiB; raise max_bytes or crop the series"
        )
    hu = np.empty((n, rows, cols), dtype=dtype)
    valid = np.ones((n, rows, cols), dtype=bool) if has_padding else None
    scratch: dict[np.dtype, np.ndarray] = {}
    for k, h in enumerate(ordered):
        sdt = stored_dtype(h)
        buf = scratch.setdefault(sdt, np.empty((rows, cols), dtype=sdt))
        stored = read_stored(h, buf)
        if valid is not None:
            pad = padding_mask(stored, h)
            if pad is not None:
                np.logical_not(pad, out=valid[k])
        if not to_hu(stored, h, hu[k]):
            # Integer HU outside int16: promote once and continue in float32.
            hu = hu.astype(np.float32)
            to_hu(stored, h, hu[k])
    warnings = list(sel.warnings) + dup_warnings + list(geom.warnings)
    if valid is not None:
        n_pad = int(valid.size - np.count_nonzero(valid))
        if n_pad:
            pads = sorted({h.padding_value for h in ordered if h.padding_value is not None})
            warnings.append(
                LoadWarning(
                    "padding",
                    f"{n_pad} padding voxels (PixelPaddingValue {pads}) masked invalid",
                )
            )
        else:
            valid = None
    not_hu = [h for h in ordered if h.rescale_type.upper() not in ("", "HU")]
    no_rescale = [h for h in ordered if h.slope is None and h.intercept is None]
    if not_hu:
        warnings.append(
            LoadWarning(
                "not_hu",
                f"RescaleType {not_hu[0].rescale_type!r}: values are not Hounsfield units; "
                "calibrate with calibrate_grey_to_hu before using them as HU",
            )
        )
    elif no_rescale:
        warnings.append(
            LoadWarning(
                "not_hu",
                "no RescaleSlope/RescaleIntercept (typical of CBCT): grey values, not HU; "
                "calibrate with calibrate_grey_to_hu",
            )
        )
    if any(h.lossy for h in ordered):
        warnings.append(
            LoadWarning(
                "lossy_compression",
                "lossy compression (LossyImageCompression or a lossy transfer syntax): "
                "HU values are approximate",
            )
        )
    n_files = len({h.path for h in ordered})
    info = _info(ordered, n_files, not (not_hu or no_rescale), geom.tilt_deg)
    sampling = grid_sampling_mm(geom.affine_lps, geom.positions_mm, info.slice_thickness_mm)
    warnings += [w for w in (coarse_voxels_warning(*sampling),) if w is not None]
    return CTVolume(
        hu=hu,
        affine_lps=geom.affine_lps,
        valid=valid,
        info=info,
        warnings=tuple(warnings),
        slice_positions_mm=geom.positions_mm,
    )

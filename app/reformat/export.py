"""``ctdrill panorama``'s work: the reformats of a plan, their figures and the output folder.

Writes, atomically (the whole folder or nothing): ``panorama.png`` / ``panorama.npz`` and
``cross_section.png`` / ``cross_section.npz`` (arrays ``hu`` (H, W) float64 and ``lps``
(H, W, 3) float64 LPS mm of each pixel's centre sample, plus ``pixel_mm``, ``slab_mm`` and
``arch_lps``), and ``reformat.json`` (each image's geometry and options, the series hash, the
plans, the captions: enough to reproduce them). The cross-section is through the first
trajectory's axis. See docs/panorama.md.
"""

from __future__ import annotations

import io
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from ctdrill.app.errors import AppInputError
from ctdrill.app.records import atomic_output_dir, write_file
from ctdrill.app.reformat.draw import DEFAULT_LEVEL_HU, DEFAULT_WIDTH_HU, draw_reformat
from ctdrill.engine.path import PathResult, plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.types import Plan, series_uid_hash
from ctdrill.imaging.sampling.reformat import Reformat, SlabMode, cross_section, panorama
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.errors import ModelInputError

#: Files ``ctdrill panorama`` writes (an existing --out folder may hold only these).
OUTPUT_FILES = frozenset(
    {"panorama.png", "panorama.npz", "cross_section.png", "cross_section.npz", "reformat.json"}
)
#: Figure resolution, dots per inch (10 pt text is 21 px high).
DPI = 150
#: Width of the image area, inches, and the height range it may take.
_IMAGE_IN = 9.0
_HEIGHT_IN = (3.0, 10.0)


@dataclass(frozen=True)
class ReformatOptions:
    """What the command line chose (None: the documented default)."""

    pixel_mm: float | None = None
    slab_mm: float = 10.0
    slab_mode: SlabMode = "mean"
    height_mm: float | None = None
    cs_slab_mm: float = 1.0
    cs_width_mm: float = 40.0
    cs_height_mm: float = 40.0
    level_hu: float = DEFAULT_LEVEL_HU
    width_hu: float = DEFAULT_WIDTH_HU


def plan_arch(plans: Sequence[Plan], sources: Sequence[Path]) -> np.ndarray:
    """The plans' shared dental arch, or one clear error naming the plan files."""
    for plan in plans:
        if plan.arch_lps is not None:
            return np.asarray(plan.arch_lps, dtype=np.float64)
    names = ", ".join(str(p) for p in sources)
    raise AppInputError(
        f"--plan {names}: the plan has no dental arch; add arch_mm (a list of points along "
        "the teeth or the alveolar ridge on an axial slice, in the plan's coordinate_system) "
        "or a 3D Slicer Curve markup named 'arch'"
    )


def _paths(volume: CTVolume, plans: Sequence[Plan]) -> tuple[list[PathResult | None], list[str]]:
    """Each plan's path result (the drill's stop), or None with the reason as a caption."""
    out: list[PathResult | None] = []
    notes: list[str] = []
    for plan in plans:
        try:
            drilled = plan if plan.earlier_drills else plan.drilled(0)  # to the apex + tip
            out.append(plan_path(volume, drilled, plan_calibration(plan)))
        except (ImagingInputError, ModelInputError) as exc:
            out.append(None)
            notes.append(f"{plan.name}: drill stop not computed ({exc}); planned axis drawn")
    return out, notes


def _figure(reformat: Reformat) -> Figure:
    w_mm, h_mm = reformat.extent_mm
    aspect = h_mm / max(w_mm, 1e-9)
    height = min(max(_IMAGE_IN * aspect, _HEIGHT_IN[0]), _HEIGHT_IN[1])
    width = _IMAGE_IN if _IMAGE_IN * aspect <= _HEIGHT_IN[1] else _HEIGHT_IN[1] / aspect
    return Figure(figsize=(max(width, 5.0) + 1.2, height + 1.6), dpi=DPI, layout="constrained")


def _png(
    reformat: Reformat,
    plans: Sequence[Plan],
    paths: Sequence[PathResult | None],
    options: ReformatOptions,
    title: str,
    at_mm: float | None,
    notes: Sequence[str],
) -> tuple[bytes, list[str]]:
    fig = _figure(reformat)
    ax = fig.add_subplot(1, 1, 1)
    drawing = draw_reformat(
        ax,
        reformat,
        plans,
        paths=paths,
        level_hu=options.level_hu,
        width_hu=options.width_hu,
        cross_section_at_mm=at_mm,
        title=title,
        captions=notes,
    )
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue(), drawing.captions


def _npz(reformat: Reformat) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(
        buf,
        hu=np.asarray(reformat.hu, dtype=np.float64),
        lps=np.asarray(reformat.lps, dtype=np.float64),
        pixel_mm=np.float64(reformat.pixel_mm),
        slab_mm=np.float64(reformat.slab_mm),
        arch_lps=np.asarray(reformat.arch_lps, dtype=np.float64),
    )
    return buf.getvalue()


def build_reformats(
    volume: CTVolume, plans: Sequence[Plan], arch_lps: np.ndarray, options: ReformatOptions
) -> tuple[Reformat, Reformat]:
    """The panorama and the cross-section through the first trajectory's axis."""
    pano = panorama(
        volume,
        arch_lps,
        pixel_mm=options.pixel_mm,
        slab_mm=options.slab_mm,
        slab_mode=options.slab_mode,
        height_mm=options.height_mm,
    )
    first = plans[0]
    try:
        cs = cross_section(
            volume,
            arch_lps,
            axis=(first.entry_lps, first.target_lps),
            width_mm=options.cs_width_mm,
            height_mm=options.cs_height_mm,
            pixel_mm=options.pixel_mm,
            slab_mm=options.cs_slab_mm,
            slab_mode=options.slab_mode,
        )
    except ImagingInputError as exc:
        raise AppInputError(f"--plan {first.source or first.name}: {exc}") from None
    return pano, cs


def export_panorama(
    volume: CTVolume,
    plans: Sequence[Plan],
    plan_sources: Sequence[Path],
    out_dir: Path,
    options: ReformatOptions,
) -> list[Path]:
    """Write the folder (module docstring) and return its files."""
    if not plans:
        raise AppInputError("--plan: no trajectory in the plan files")
    arch = plan_arch(plans, plan_sources)
    pano, cs = build_reformats(volume, plans, arch, options)
    paths, path_notes = _paths(volume, plans)
    first = plans[0]
    pano_png, pano_captions = _png(
        pano, plans, paths, options, "Panoramic reformat", cs.at_arc_mm, path_notes
    )
    cs_title = f"Cross-section through {first.name} at {cs.at_arc_mm:.1f} mm along the arch"
    cs_png, cs_captions = _png(cs, plans, paths, options, cs_title, None, path_notes)
    doc: dict[str, Any] = {
        "format": "ctdrill-reformat/1",
        "series_uid_sha256": series_uid_hash(volume.info.series_uid),
        "plans": [p.name for p in plans],
        "cross_section_trajectory": first.name,
        "window_hu": {"level": options.level_hu, "width": options.width_hu},
        "panorama": pano.metadata() | {"captions": pano_captions},
        "cross_section": cs.metadata() | {"captions": cs_captions},
        "notes": path_notes,
    }
    files: dict[str, bytes | str] = {
        "panorama.png": pano_png,
        "panorama.npz": _npz(pano),
        "cross_section.png": cs_png,
        "cross_section.npz": _npz(cs),
        "reformat.json": json.dumps(doc, indent=1, allow_nan=False) + "\n",
    }
    with atomic_output_dir(out_dir, owned_names=OUTPUT_FILES) as staging:
        for name, data in files.items():
            write_file(staging / name, data)
    return [out_dir / name for name in files]


def finite_or_none(value: float | None, option: str, *, zero_ok: bool = False) -> float | None:
    """A command-line number: None stays None; otherwise finite and positive (or >= 0)."""
    if value is None:
        return None
    ok = math.isfinite(value) and (value >= 0.0 if zero_ok else value > 0.0)
    if not ok:
        limit = ">= 0" if zero_ok else "> 0"
        raise AppInputError(f"{option} {value!r}: give a finite number {limit}")
    return float(value)

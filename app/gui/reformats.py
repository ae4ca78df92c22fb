"""What the panorama and cross-section views compute, headless (no Qt).

The views (:mod:`ctdrill.app.gui.panorama_view`) run these in worker threads and draw the
result with :func:`ctdrill.app.reformat.draw.draw_reformat`, the drawing ``ctdrill panorama``
and the report use. The sampling is :mod:`ctdrill.imaging.sampling.reformat`'s.

A request is a frozen value: two equal requests give the same image, so a view recomputes only
when its request changes (not on every plan edit: a panorama depends on the arch, not on the
trajectories drawn over it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctdrill.imaging import CTVolume
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.arch import ArchCurve
from ctdrill.imaging.sampling.reformat import (
    Reformat,
    SlabMode,
    arc_position_mm,
    cross_section,
    panorama,
)

#: What the views say when the plan has no dental arch.
NO_ARCH = (
    "No dental arch in the plan.\n"
    "Draw one on the axial slice view: choose the Arch tool in the slice toolbar and click "
    "along the jaw, from one end of the arch to the other (two points or more), on a slice "
    "through the alveolar ridge. Or open a plan with an arch (arch_mm, or a Slicer curve "
    "named 'arch')."
)
#: What the views say before a series is open.
NO_SERIES = "Open a DICOM folder (File > Open)."
#: Default slab thickness of the panorama and of the cross-section, mm.
PANORAMA_SLAB_MM = 10.0
CROSS_SLAB_MM = 1.0
#: Cross-section image size (mm, square): an implant, its bone and the canal below.
CROSS_SIZE_MM = 40.0
#: Scroll steps along the arch, mm: one wheel notch or arrow key, and with Shift / Page keys.
STEP_MM = 1.0
BIG_STEP_MM = 5.0


@dataclass(frozen=True, eq=False)
class PanoramaRequest:
    """A panorama to compute: the series, the arch, the slab."""

    volume: CTVolume
    arch_lps: np.ndarray
    slab_mm: float
    slab_mode: SlabMode
    #: Rows: their height and middle's LPS z, mm (None: the volume's whole height).
    height_mm: float | None = None
    centre_z_mm: float | None = None

    def same_as(self, other: PanoramaRequest | None) -> bool:
        """True when ``other`` gives the same image."""
        return (
            other is not None
            and other.volume is self.volume
            and np.array_equal(other.arch_lps, self.arch_lps)
            and (other.slab_mm, other.slab_mode) == (self.slab_mm, self.slab_mode)
            and (other.height_mm, other.centre_z_mm) == (self.height_mm, self.centre_z_mm)
        )

    def compute(self) -> Reformat:
        """The panorama (its rows as asked, the volume's finest pixel)."""
        return panorama(
            self.volume,
            self.arch_lps,
            slab_mm=self.slab_mm,
            slab_mode=self.slab_mode,
            height_mm=self.height_mm,
            centre_z_mm=self.centre_z_mm,
        )


@dataclass(frozen=True, eq=False)
class CrossRequest:
    """A cross-section to compute: at ``at_arc_mm`` along the arch (None: at the implant's
    site), tilted to contain the axis ``(entry, target)`` of the current trajectory when
    there is one."""

    volume: CTVolume
    arch_lps: np.ndarray
    axis: tuple[np.ndarray, np.ndarray] | None
    at_arc_mm: float | None
    slab_mm: float
    slab_mode: SlabMode

    def same_as(self, other: CrossRequest | None) -> bool:
        """True when ``other`` gives the same image."""
        if other is None or other.volume is not self.volume:
            return False
        axes_equal = (self.axis is None) == (other.axis is None) and (
            self.axis is None
            or other.axis is None
            or all(np.array_equal(a, b) for a, b in zip(self.axis, other.axis, strict=True))
        )
        return (
            axes_equal
            and np.array_equal(other.arch_lps, self.arch_lps)
            and (other.at_arc_mm, other.slab_mm, other.slab_mode)
            == (self.at_arc_mm, self.slab_mm, self.slab_mode)
        )

    def compute(self) -> Reformat:
        """The cross-section, :data:`CROSS_SIZE_MM` square."""
        at = self.at_arc_mm
        if at is None and self.axis is None:
            at = site_arc_mm(self.arch_lps, None)
        return cross_section(
            self.volume,
            self.arch_lps,
            at_arc_mm=at,
            axis=self.axis,
            width_mm=CROSS_SIZE_MM,
            height_mm=CROSS_SIZE_MM,
            slab_mm=self.slab_mm,
            slab_mode=self.slab_mode,
        )


def plan_axis(plan: Plan | None) -> tuple[np.ndarray, np.ndarray] | None:
    """The trajectory's ``(entry, target)`` (LPS mm), or None."""
    return None if plan is None else (plan.entry_lps, plan.target_lps)


def arch_length_mm(arch_lps: np.ndarray) -> float:
    """Length of the arch along the panorama (its axial projection), mm."""
    return ArchCurve(np.asarray(arch_lps)).length_mm


def site_arc_mm(arch_lps: np.ndarray, plan: Plan | None) -> float:
    """Where the cross-section starts along the arch, mm: through the middle of the
    trajectory's axis (its implant's site), or the arch's middle without a trajectory."""
    if plan is None:
        return 0.5 * arch_length_mm(arch_lps)
    return arc_position_mm(arch_lps, 0.5 * (plan.entry_lps + plan.target_lps))


def scrolled_arc_mm(at_mm: float, steps: float, length_mm: float, step_mm: float) -> float:
    """The arc position ``steps`` scroll steps of ``step_mm`` from ``at_mm``, kept on the
    arch ``[0, length_mm]``."""
    return float(np.clip(at_mm + steps * step_mm, 0.0, length_mm))


def position_text(at_mm: float | None, length_mm: float, *, at_implant: bool) -> str:
    """The cross-section's position in words (``42.0 mm of 118.3 mm along the arch``)."""
    if at_mm is None:
        return f"arch {length_mm:.1f} mm long"
    where = f"{at_mm:.1f} mm of {length_mm:.1f} mm along the arch"
    return f"{where} (the implant's site)" if at_implant else where

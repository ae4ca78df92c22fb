"""Analytic volumes and affines for imaging tests: every expected value is known exactly."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.imaging.phantom.writer import WrittenSeries, write_series
from ctdrill.imaging.volume import CTVolume, SeriesInfo


def rotation(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """(3, 3) proper rotation from three angles about z, y, x (degrees)."""
    a, b, c = np.radians([yaw_deg, pitch_deg, roll_deg])
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rx = np.array([[1, 0, 0], [0, np.cos(c), -np.sin(c)], [0, np.sin(c), np.cos(c)]])
    return np.asarray(rz @ ry @ rx)


def affine(
    spacing_mm: tuple[float, float, float] = (0.5, 0.5, 1.0),
    *,
    rot: np.ndarray | None = None,
    origin_lps: tuple[float, float, float] = (-20.0, -30.0, 40.0),
    tilt_deg: float = 0.0,
) -> np.ndarray:
    """(4, 4) affine: columns ``rot[:, 0] * sx``, ``rot[:, 1] * sy``, then the k column.

    The k column is ``sz`` along the normal, sheared towards the column direction by
    ``tilt_deg`` (a gantry tilt keeps the normal distance ``sz`` between planes).
    """
    r = np.eye(3) if rot is None else rot
    a = np.eye(4)
    a[:3, 0] = r[:, 0] * spacing_mm[0]
    a[:3, 1] = r[:, 1] * spacing_mm[1]
    a[:3, 2] = r[:, 2] * spacing_mm[2] + r[:, 1] * spacing_mm[2] * np.tan(np.radians(tilt_deg))
    a[:3, 3] = origin_lps
    return a


def linear_hu(
    shape: tuple[int, int, int], *, ci: int = 3, cj: int = 7, ck: int = 50, c0: int = -400
) -> np.ndarray:
    """(slices, rows, cols) int16 ``hu[k, j, i] = ci*i + cj*j + ck*k + c0``."""
    k, j, i = np.indices(shape)
    return (ci * i + cj * j + ck * k + c0).astype(np.int16)


def volume(hu: np.ndarray, aff: np.ndarray, valid: np.ndarray | None = None) -> CTVolume:
    """A CTVolume made directly (no DICOM)."""
    return CTVolume(hu=hu, affine_lps=aff, valid=valid, info=SeriesInfo(series_uid="1.2.3"))


def write(out: Path, hu: np.ndarray, aff: np.ndarray, **kw: Any) -> WrittenSeries:
    """:func:`write_series` with test defaults."""
    return write_series(out, hu, aff, **kw)

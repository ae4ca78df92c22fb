"""The plan's CT along the path as the slave's estimator reads it (its prior).

:func:`plan_prior` turns the plan's profile into plain lists for the 10 kHz loop: the CT
number, where the force gain may learn from it, its maximum nearby (the density-rise stop),
the exit level and the plan's contact (the registration by the contact); docs/teleop.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.model.calibration import Calibration
from ctdrill.model.profile import Profile

#: The low-passed force above which the drill touches material, N (the estimator places the
#: contact behind it, where the force was last free; the plan's contact is where its force
#: at rest first exceeds it).
CONTACT_N = 1.0
#: The plan's CT must be uniform within this many HU ...
PRIOR_UNIFORM_HU = 100.0
#: ... over this far either side of the drill, mm, for the gain to learn there.
PRIOR_WINDOW_MM = 0.15
#: A density rise counts where the plan's CT shows none within this far either side, mm
#: (the registration error it tolerates).
RISE_WINDOW_MM = 3.0
#: The exit level: this fraction of the way from the gate's upper edge up to the softest bone
#: the plan's CT shows along the whole path.
EXIT_LEVEL_FRACTION = 0.5


@dataclass(frozen=True, eq=False)
class Prior:
    """The plan's CT along the path, as the slave's loop reads it (plain lists).

    Built by :func:`plan_prior`; ``origin_mm`` is the slave depth of the plan's depth 0.
    """

    origin_mm: float
    step_mm: float
    log10_c: list[float]
    usable: list[bool]
    window_max_hu: list[float]
    exit_hu: float
    #: Where the plan's force at rest first exceeds :data:`CONTACT_N` (slave depth, mm; NaN:
    #: nowhere): the contact the slave should find there if the plan is registered.
    contact_mm: float = math.nan


def _window(values: np.ndarray, half: int, pad: float) -> np.ndarray:
    padded = np.concatenate([np.full(half, pad), values, np.full(half, pad)])
    return np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)


def plan_prior(profile: Profile, calibration: Calibration, origin_mm: float = 0.0) -> Prior:
    """The plan's profile as the estimator's prior: its CT number, where the gain may learn
    from it (uniform within :data:`PRIOR_WINDOW_MM`, lip fully engaged), its maximum within
    :data:`RISE_WINDOW_MM`, and the exit level (module docstring)."""
    hu = np.asarray(profile.hu_mean, dtype=np.float64)
    step = profile.step_mm
    w = max(1, round(PRIOR_WINDOW_MM / step))
    win = _window(hu, w, math.nan)
    usable = (np.nanmax(win, axis=1) - np.nanmin(win, axis=1) <= PRIOR_UNIFORM_HU) & (
        _window(np.asarray(profile.s_t), w, 0.0).min(axis=1) >= 0.999
    )
    hi = _window(hu, max(1, round(RISE_WINDOW_MM / step)), -math.inf).max(axis=1)
    gate_hi = calibration.gate_hu + 0.5 * calibration.gate_width_hu
    bone = hu[(np.asarray(profile.s_t) >= 0.999) & (hu >= gate_hi)]
    softest = float(bone.min()) if bone.size else gate_hi
    c = np.log10(np.maximum(hu - AIR_HU, 1.0))
    touching = np.flatnonzero(np.asarray(profile.s0_n) > CONTACT_N)
    contact = float(profile.depth_mm[touching[0]]) + origin_mm if touching.size else math.nan
    return Prior(
        origin_mm=origin_mm + float(profile.depth_mm[0]),
        step_mm=step,
        log10_c=[float(v) for v in c],
        usable=[bool(v) for v in usable],
        window_max_hu=[float(v) for v in hi],
        exit_hu=gate_hi + EXIT_LEVEL_FRACTION * (softest - gate_hi),
        contact_mm=contact,
    )

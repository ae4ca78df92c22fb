"""The force table the host uploads to the device (DESIGN 3, docs/protocol.md).

``F(x, v, t) = S0(x) (1 + Ke v) + S1(x) sin(2 pi f1 t) + S2(x) sin(2 pi f2 t)`` with ``S0, S1,
S2`` sampled at ``x = i * depth_step_mm``, plus the stop depth the device enforces. Values are
held as float32, exactly what the device stores.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ctdrill.haptics.errors import HapticsInputError
from ctdrill.haptics.protocol import (
    MAX_CHUNK_ROWS,
    ProfileBegin,
    ProfileChunk,
    ProfileEnd,
    profile_crc32,
)

if TYPE_CHECKING:
    from ctdrill.model.profile import Profile

#: Most rows a device table holds (12 bytes each: 48 KiB).
MAX_PROFILE_STEPS = 4096


class ProfileTableError(HapticsInputError):
    """A profile table that the device would refuse."""


def _f32(values: ArrayLike, name: str) -> np.ndarray:
    arr = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(arr)):
        raise ProfileTableError(f"profile table {name} contains NaN or inf; pass finite forces")
    if arr.size and float(np.max(np.abs(arr))) > float(np.finfo(np.float32).max):
        raise ProfileTableError(f"profile table {name} overflows float32")
    out = arr.astype(np.float32)
    out.flags.writeable = False
    return out


def _finite32(value: float, name: str, *, minimum: float = 0.0) -> float:
    v = float(np.float32(value)) if math.isfinite(value) and abs(value) < 3e38 else math.nan
    if not (math.isfinite(v) and v >= minimum):
        raise ProfileTableError(
            f"profile table {name} must be finite and >= {minimum}, got {value}"
        )
    return v


@dataclass(frozen=True, eq=False)
class ProfileTable:
    """Per-depth force coefficients and the stop depth, as uploaded.

    Attributes
    ----------
    depth_step_mm : float
        Depth of row ``i`` is ``i * depth_step_mm`` from the entry point, mm (> 0).
    s0_n, s1_n, s2_n : ndarray, shape (N,), float32
        DC cutting force at zero feed and the two harmonic amplitudes, N (``s0_n >= 0``).
    ke_per_mm_s : float
        Feed sensitivity ``Ke``, per (mm/s) (>= 0).
    freqs_hz : ndarray, shape (2,)
        Harmonic frequencies ``f1, f2``, Hz.
    stop_depth_mm : float
        The drill never passes this depth, mm (>= 0).
    goal_depth_mm : float or None
        Where the planned osteotomy ends (the guarded stop), mm; None: the stop depth. The
        host's alone (not uploaded): an exam's table runs past it, and the breakthrough a hand
        reacts to is the first at or beyond it
        (:func:`ctdrill.haptics.hands.decisive_breakthrough_mm`).
    """

    depth_step_mm: float
    s0_n: np.ndarray
    s1_n: np.ndarray
    s2_n: np.ndarray
    ke_per_mm_s: float
    freqs_hz: np.ndarray
    stop_depth_mm: float
    goal_depth_mm: float | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        s0 = _f32(self.s0_n, "s0_n")
        n = s0.shape[0] if s0.ndim == 1 else 0
        if s0.ndim != 1 or not 1 <= n <= MAX_PROFILE_STEPS:
            raise ProfileTableError(
                f"profile table s0_n must be 1-D with 1..{MAX_PROFILE_STEPS} rows, got "
                f"shape {s0.shape}; use a coarser depth step"
            )
        if np.any(s0 < 0.0):
            raise ProfileTableError("profile table s0_n must be >= 0 (a force, N)")
        set_(self, "s0_n", s0)
        for name in ("s1_n", "s2_n"):
            arr = _f32(getattr(self, name), name)
            if arr.shape != (n,):
                raise ProfileTableError(f"profile table {name} must have shape ({n},)")
            set_(self, name, arr)
        freqs = _f32(self.freqs_hz, "freqs_hz")
        if freqs.shape != (2,) or np.any(freqs < 0.0):
            raise ProfileTableError("profile table freqs_hz must be 2 frequencies >= 0 Hz")
        set_(self, "freqs_hz", freqs)
        step = _finite32(self.depth_step_mm, "depth_step_mm", minimum=1e-6)
        set_(self, "depth_step_mm", step)
        set_(self, "ke_per_mm_s", _finite32(self.ke_per_mm_s, "ke_per_mm_s"))
        set_(self, "stop_depth_mm", _finite32(self.stop_depth_mm, "stop_depth_mm"))
        if self.goal_depth_mm is not None:
            set_(self, "goal_depth_mm", _finite32(self.goal_depth_mm, "goal_depth_mm"))

    @property
    def goal_mm(self) -> float:
        """The planned osteotomy's end, mm: ``goal_depth_mm``, or the stop without one."""
        return self.stop_depth_mm if self.goal_depth_mm is None else self.goal_depth_mm

    @property
    def n_steps(self) -> int:
        """Rows in the table."""
        return int(self.s0_n.shape[0])

    @property
    def depth_mm(self) -> np.ndarray:
        """(N,) depth of each row, mm."""
        return np.arange(self.n_steps) * float(self.depth_step_mm)

    @classmethod
    def from_profile(
        cls, profile: Profile, stop_depth_mm: float, *, goal_depth_mm: float | None = None
    ) -> ProfileTable:
        """Adapt a :class:`ctdrill.model.profile.Profile` (depth from 0, uniform step);
        ``goal_depth_mm``: where the planned osteotomy ends when the stop is beyond it.

        Harmonics beyond the second are dropped, missing ones are zero.
        """
        depth = np.asarray(profile.depth_mm, dtype=np.float64)
        if depth.shape[0] < 2 or abs(float(depth[0])) > 1e-9:
            raise ProfileTableError("profile depth_mm must start at 0 (the entry point)")
        sk = np.asarray(profile.sk_n, dtype=np.float64).reshape(-1, depth.shape[0])
        freqs = np.asarray(profile.freqs_hz, dtype=np.float64).reshape(-1)
        rows = [sk[k] if k < sk.shape[0] else np.zeros(depth.shape[0]) for k in range(2)]
        f = [float(freqs[k]) if k < freqs.shape[0] else 0.0 for k in range(2)]
        return cls(
            depth_step_mm=float(depth[1] - depth[0]),
            s0_n=profile.s0_n,
            s1_n=rows[0],
            s2_n=rows[1],
            ke_per_mm_s=float(profile.ke_per_mm_s),
            freqs_hz=np.asarray(f),
            stop_depth_mm=stop_depth_mm,
            goal_depth_mm=goal_depth_mm,
        )

    @classmethod
    def slab(
        cls,
        *,
        s0_n: float,
        top_mm: float,
        bottom_mm: float,
        stop_depth_mm: float,
        s1_n: float = 0.0,
        s2_n: float = 0.0,
        ke_per_mm_s: float = 0.25,
        freqs_hz: tuple[float, float] = (30.0, 60.0),
        depth_step_mm: float = 0.0625,
        length_mm: float = 40.0,
    ) -> ProfileTable:
        """A homogeneous slab ``[top_mm, bottom_mm]`` in air (tests, demos, benchmarks)."""
        depth = np.arange(int(length_mm / depth_step_mm) + 1) * depth_step_mm
        inside = (depth >= top_mm) & (depth <= bottom_mm)
        return cls(
            depth_step_mm=depth_step_mm,
            s0_n=np.where(inside, s0_n, 0.0),
            s1_n=np.where(inside, s1_n, 0.0),
            s2_n=np.where(inside, s2_n, 0.0),
            ke_per_mm_s=ke_per_mm_s,
            freqs_hz=np.asarray(freqs_hz),
            stop_depth_mm=stop_depth_mm,
        )

    def rows(self) -> list[tuple[float, float, float]]:
        """``(s0, s1, s2)`` per row as Python floats (float32 values)."""
        return list(
            zip(
                self.s0_n.tolist(),
                self.s1_n.tolist(),
                self.s2_n.tolist(),
                strict=True,
            )
        )

    def begin_message(self) -> ProfileBegin:
        """The PROFILE_BEGIN message for this table."""
        return ProfileBegin(
            n_steps=self.n_steps,
            depth_step_mm=self.depth_step_mm,
            ke_per_mm_s=self.ke_per_mm_s,
            f1_hz=float(self.freqs_hz[0]),
            f2_hz=float(self.freqs_hz[1]),
            stop_depth_mm=self.stop_depth_mm,
        )

    @property
    def crc32(self) -> int:
        """The table's CRC-32 as the device checks it (PROFILE_END), names it (ARM, TELEMETRY)."""
        return profile_crc32(self.begin_message(), self.rows())

    def upload_messages(self) -> Iterator[ProfileBegin | ProfileChunk | ProfileEnd]:
        """PROFILE_BEGIN, the chunks in order, PROFILE_END with the table CRC-32."""
        begin = self.begin_message()
        rows = self.rows()
        yield begin
        for first in range(0, len(rows), MAX_CHUNK_ROWS):
            yield ProfileChunk(first, tuple(rows[first : first + MAX_CHUNK_ROWS]))
        yield ProfileEnd(self.n_steps, profile_crc32(begin, rows))

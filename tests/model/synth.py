"""Synthetic slave-robot recordings from known force-law parameters (calibration tests)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

#: The paper's pine-wood set (Eq. 20-22), the answer the fit must recover.
TRUE_A0 = {"b0": -1.35, "n": 0.77, "ke": 0.25}
TRUE_HARMONICS = ({"b0": 3.92, "n": -1.91}, {"b0": 1.72, "n": -1.29})


def synth_recording(
    hu: float,
    feed_mm_s: float,
    rng: np.random.Generator,
    *,
    rpm: float = 900.0,
    blades: int = 2,
    fs_hz: float = 1000.0,
    depth_end_mm: float = 3.2,
    tip_length_mm: float = 0.6,
    noise_n: float = 0.01,
    scatter: float = 0.005,
    free_running_n: float = 0.05,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``time_s, position_mm, force_n`` of a cut at constant feed into material at ``hu``.

    Force: ``s_t(x) (A0 + B1 sin + B2 sin)`` times a per-recording factor ``1 + N(0, scatter)``
    (material variation), plus the drill's free-running rotation (``rpm / 60`` Hz, amplitude
    ``free_running_n``) and white noise of ``noise_n``.
    """
    cp = hu + 1000.0
    t = np.arange(0.0, depth_end_mm / feed_mm_s, 1.0 / fs_hz)
    x = feed_mm_s * t
    s_t = np.clip(x / tip_length_mm, 0.0, 1.0)
    a0 = 10 ** TRUE_A0["b0"] * cp ** TRUE_A0["n"] * (1 + TRUE_A0["ke"] * feed_mm_s)
    f1 = blades * rpm / 60.0
    force = np.full_like(t, a0)
    for k, h in enumerate(TRUE_HARMONICS, start=1):
        amp = 10 ** h["b0"] * cp ** h["n"]
        force += amp * np.sin(2 * np.pi * k * f1 * t + rng.uniform(0, 2 * np.pi))
    force *= s_t * (1.0 + rng.normal(0.0, scatter))
    force += free_running_n * np.sin(2 * np.pi * (rpm / 60.0) * t + rng.uniform(0, 2 * np.pi))
    force += rng.normal(0.0, noise_n, t.shape)
    return t, x, force


def write_campaign(
    folder: Path,
    *,
    hus: Sequence[float] = (-800.0, -650.0, -500.0, -400.0),
    feeds: Sequence[float] = (0.1, 0.2, 0.3, 0.4, 0.5),
    seed: int = 2024,
    **kwargs: float,
) -> Path:
    """Write one recording per (HU, feed) and ``manifest.csv``; return the manifest path."""
    rng = np.random.default_rng(seed)
    rec_dir = folder / "recordings"
    rec_dir.mkdir(parents=True, exist_ok=True)
    lines = ["file,hu,feed_mm_s"]
    for hu in hus:
        for feed in feeds:
            t, x, f = synth_recording(hu, feed, rng, **kwargs)  # type: ignore[arg-type]
            name = f"hu{int(hu)}_v{feed:.2f}.csv"
            np.savetxt(
                rec_dir / name,
                np.column_stack([t, x, f]),
                delimiter=",",
                header="time_s,position_mm,force_n",
                comments="",
                fmt="%.6f",
            )
            lines.append(f"recordings/{name},{hu:g},{feed:g}")
    manifest = folder / "manifest.csv"
    manifest.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return manifest

"""The cutting vibration made audible: ``S1 sin(2 pi f1 t) + S2 sin(2 pi f2 t)`` at the drill's
depth, while the drill cuts, on the platform's audio output.

Audio goes through ``sounddevice`` (PortAudio): PySide6-Essentials has no QtMultimedia, and
PortAudio plays on Linux (ALSA, PulseAudio, PipeWire through ALSA), macOS and Windows from a
callback that synthesises each block from the current amplitudes. ``sounddevice`` is imported
in the background once a rehearsal can start (:meth:`VibrationSound.prepare`), never at
start-up; where it or an output device is missing (no PortAudio
library, a server without sound, Xvfb) :meth:`VibrationSound.start` says why and the window
goes on silent. Frequencies and amplitudes are the model's (the table's ``S1, S2`` and
``f1, f2``); :data:`FULL_SCALE_N` of vibration is full scale. Small speakers reproduce little
at 30 Hz: a headset carries it.
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

#: Output sample rate, Hz.
SAMPLE_RATE_HZ = 8000
#: Vibration amplitude (N) played at full scale.
FULL_SCALE_N = 2.0
#: Frames per callback (32 ms at 8 kHz).
BLOCK_FRAMES = 256

Opener = Callable[[Callable[..., None]], Any]


def vibration_block(
    frames: int,
    phases: tuple[float, float],
    start: tuple[float, float],
    end: tuple[float, float],
    freqs_hz: tuple[float, float],
    *,
    rate_hz: float = SAMPLE_RATE_HZ,
) -> tuple[np.ndarray, tuple[float, float]]:
    """``frames`` samples of ``a1 sin(phase1) + a2 sin(phase2)``, full scale
    :data:`FULL_SCALE_N`, the amplitudes ramped linearly from ``start`` to ``end`` (N) across
    the block so a change makes no click, the phases carried on; returns the samples
    (float32, clipped to +-1) and the phases after them."""
    n = np.arange(1, frames + 1, dtype=float)
    ramp = n / frames
    out = np.zeros(frames)
    after = []
    for k in range(2):
        w = 2.0 * math.pi * freqs_hz[k] / rate_hz
        amp = start[k] + (end[k] - start[k]) * ramp
        out += amp * np.sin(phases[k] + w * (n - 1))
        after.append(math.fmod(phases[k] + w * frames, 2.0 * math.pi))
    samples = np.clip(out / FULL_SCALE_N, -1.0, 1.0).astype(np.float32)
    return samples, (after[0], after[1])


def _open_default(callback: Callable[..., None]) -> Any:
    import sounddevice  # type: ignore[import-untyped]

    return sounddevice.OutputStream(
        samplerate=SAMPLE_RATE_HZ,
        channels=1,
        dtype="float32",
        blocksize=BLOCK_FRAMES,
        callback=callback,
    )


def _import_backend() -> None:
    # no PortAudio here: start() says so when sound is switched on
    with contextlib.suppress(Exception):
        import sounddevice  # noqa: F401


class VibrationSound:
    """Plays the vibration of :meth:`set_vibration` on the audio output (module docstring).

    Parameters
    ----------
    opener : callable, optional
        Builds the output stream from the callback (default: a ``sounddevice`` stream).
    """

    def __init__(self, opener: Opener | None = None) -> None:
        self._opener = opener or _open_default
        self._stream: Any = None
        self._lock = threading.Lock()
        self._target = (0.0, 0.0)
        self._now = (0.0, 0.0)
        self._freqs = (30.0, 60.0)
        self._phases = (0.0, 0.0)
        self._prepared = False

    def prepare(self) -> None:
        """Load the audio library in a background thread, once (its import finds and starts
        PortAudio: 0.1-0.2 s that would otherwise hold the UI thread when a rehearsal with
        sound starts)."""
        if self._prepared or self._opener is not _open_default:
            return
        self._prepared = True
        threading.Thread(target=_import_backend, name="ctdrill-audio", daemon=True).start()

    @property
    def playing(self) -> bool:
        """An output stream is open."""
        return self._stream is not None

    def start(self) -> str | None:
        """Open the output and start playing (silence until a vibration is set); the reason
        if there is no sound here (then nothing plays, nothing fails)."""
        if self._stream is not None:
            return None
        try:
            stream = self._opener(self._callback)
            stream.start()
        except Exception as exc:  # any failure of the audio stack means silence
            # sounddevice raises OSError without the PortAudio library and PortAudioError
            # (an Exception) without an output device
            return f"no sound here ({' '.join(str(exc).split()) or type(exc).__name__})"
        self._stream = stream
        return None

    def stop(self) -> None:
        """Close the output."""
        stream, self._stream = self._stream, None
        if stream is not None:
            try:
                stream.stop()
                stream.close()
            except Exception:  # closing a failed device must not fail the window
                pass

    def set_vibration(self, s1_n: float, s2_n: float, freqs_hz: tuple[float, float]) -> None:
        """The amplitudes (N) and frequencies (Hz) to play from now on (0, 0: silence)."""
        with self._lock:
            self._target = (max(s1_n, 0.0), max(s2_n, 0.0))
            self._freqs = (float(freqs_hz[0]), float(freqs_hz[1]))

    def _callback(self, outdata: np.ndarray, frames: int, _time: Any, _status: Any) -> None:
        with self._lock:
            target, freqs = self._target, self._freqs
        samples, self._phases = vibration_block(frames, self._phases, self._now, target, freqs)
        self._now = target
        outdata[:, 0] = samples

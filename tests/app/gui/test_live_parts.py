"""The live parts' headless pieces: the vibration's sound and trace, the forces, the words."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.app.gui.gauges import RIPPLE_MEAN_S, ripple
from ctdrill.app.gui.rehearsal_words import live_words, need_here_n, needed_n, predicted_words
from ctdrill.app.gui.sound import FULL_SCALE_N, SAMPLE_RATE_HZ, VibrationSound, vibration_block
from ctdrill.app.readout import GAUGE_FORCES, LiveReadout, gauge_forces
from ctdrill.haptics.profile_table import ProfileTable


def test_the_sound_is_the_model_vibration() -> None:
    # 1 s of S1 = 0.4 N at 30 Hz and S2 = 0.1 N at 60 Hz in blocks: a DFT at 1 Hz resolution
    # finds exactly those two lines, amplitude / full scale, and the phases run on unbroken
    blocks, phases = [], (0.0, 0.0)
    amps = (0.4, 0.1)
    for _ in range(SAMPLE_RATE_HZ // 250):
        samples, phases = vibration_block(250, phases, amps, amps, (30.0, 60.0))
        blocks.append(samples)
    signal = np.concatenate(blocks).astype(float)
    spectrum = np.abs(np.fft.rfft(signal)) * 2.0 / signal.size
    assert spectrum[30] == pytest.approx(0.4 / FULL_SCALE_N, rel=1e-4)
    assert spectrum[60] == pytest.approx(0.1 / FULL_SCALE_N, rel=1e-4)
    others = np.delete(spectrum, [30, 60])
    assert others.max() < 1e-5
    # a change of amplitude is ramped across the block: no click
    ramped, _ = vibration_block(100, (0.0, 0.0), (0.0, 0.0), (1.0, 0.0), (30.0, 60.0))
    assert abs(float(ramped[0])) < 0.01 and np.max(np.abs(np.diff(ramped))) < 0.05


class _Stream:
    def __init__(self, callback: object) -> None:
        self.callback = callback
        self.started = self.closed = False

    def start(self) -> None:
        self.started = True

    def stop(self) -> None:
        pass

    def close(self) -> None:
        self.closed = True


def test_the_player_fills_its_blocks_and_is_silent_where_there_is_no_sound() -> None:
    streams: list[_Stream] = []

    def opener(callback: object) -> _Stream:
        streams.append(_Stream(callback))
        return streams[-1]

    sound = VibrationSound(opener)
    assert sound.start() is None and sound.playing and streams[0].started
    out = np.zeros((256, 1), dtype=np.float32)
    streams[0].callback(out, 256, None, None)  # type: ignore[operator]
    assert not out.any()  # silence until a vibration is set
    sound.set_vibration(0.5, 0.0, (30.0, 60.0))
    for _ in range(2):
        streams[0].callback(out, 256, None, None)  # type: ignore[operator]
    assert np.max(np.abs(out)) == pytest.approx(0.5 / FULL_SCALE_N, rel=0.02)
    sound.stop()
    assert streams[0].closed and not sound.playing

    def no_device(_callback: object) -> _Stream:
        raise OSError("PortAudio library not found")

    silent = VibrationSound(no_device)
    why = silent.start()
    assert why is not None and "PortAudio library not found" in why and not silent.playing
    silent.set_vibration(1.0, 1.0, (30.0, 60.0))  # and nothing fails afterwards
    silent.stop()


def test_the_trace_keeps_the_vibration_and_drops_a_step() -> None:
    t = np.arange(0, 0.5, 0.001)
    wave = 0.3 * np.sin(2 * np.pi * 30.0 * t)
    force = 12.0 + wave + np.where(t > 0.4, -6.0, 0.0)  # the hand lets go at 0.4 s
    times, r = ripple(np.column_stack([t, force]))
    assert times[-1] == pytest.approx(0.499) and times[0] == pytest.approx(0.499 - 0.25)
    inner = (times > 0.25 + RIPPLE_MEAN_S) & (times < 0.4 - RIPPLE_MEAN_S)
    # over whole periods the running mean of the sine is 0: the ripple is the sine itself
    assert np.allclose(r[inner], wave[-times.size :][inner], atol=0.02)
    assert np.max(np.abs(r[times > 0.4 + RIPPLE_MEAN_S])) < 0.35  # the step is gone


def _readout(kind: str, device_n: float, s0_n: float, hand_n: float | None = None) -> LiveReadout:
    return LiveReadout(hand_n, device_n, kind, s0_n, s0_n * 1.1, "engineering words")


def test_the_three_named_forces_and_the_plain_words() -> None:
    assert GAUGE_FORCES == ("hand", "cutting", "wall")
    assert gauge_forces(_readout("cutting", 12.0, 4.7, 12.1)) == {
        "hand": 12.1,
        "cutting": 12.0,
        "wall": 0.0,
    }
    assert gauge_forces(_readout("wall", 13.0, 4.7), push_n=12.0) == {
        "hand": 12.0,
        "cutting": 0.0,
        "wall": 13.0,
    }
    assert gauge_forces(_readout("holding", 6.0, 12.95), 6.0)["cutting"] == 6.0
    # the example: S0 = 12.95 N, a 12 N push
    r = _readout("holding", 12.0, 12.95)
    text, tip = live_words(r, 12.0)
    assert text == "Push harder: 13 N needed to cut here, 1.0 N more than your 12.0 N."
    assert "S0 = 12.95 N" in tip and "engineering words" in tip and "S0" not in text
    assert needed_n(12.95) == 13 and needed_n(13.0) == 14 and need_here_n(r, 12.0) == 13
    stuck = _readout("holding", 13.3, 12.95)  # above S0, held by the friction
    assert need_here_n(stuck, 13.3) == 14
    assert live_words(_readout("wall", 13.0, 4.7), 12.0)[0].startswith("At the stop")
    assert (
        live_words(_readout("free", 0.0, 0.0), 12.0)[0] == "No bone here: the drill moves freely."
    )
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.5, bottom_mm=30.0, stop_depth_mm=2.5)
    # 6 N on 4 N: (6 / 4 - 1) / 0.25 = 2 mm/s over the 2 mm from 0.5 to 2.5 mm: 1 s
    assert predicted_words(table, 6.0)[0] == "At 6 N the drill reaches the stop in about 1.0 s."
    weak = predicted_words(table, 3.0)[0]
    # the push said to reach the stop beats S0 by more than the master's 1 N friction: 6 N
    assert weak == "3 N is too weak: the drill stops at 0.5 mm; 6 N reaches the stop (3.0 N more)."
    # 4.5 N beats S0 within that friction: it may stall from the slab's top
    assert predicted_words(table, 4.5)[0] == (
        "4.5 N is barely enough: from 0.5 mm the drill may stall or creep; 6 N reaches the stop "
        "(1.5 N more)."
    )
    # a push set with the mouse reads to 0.1 N, as the hand's own label shows it
    assert predicted_words(table, 6.0674)[0].startswith("At 6.1 N the drill reaches the stop")

"""The C core against docs/protocol.md byte for byte: every device example replayed on the C
device (double and single precision builds), every frame of the document decoded and encoded
again by the C framing, the check values of both CRCs."""

from __future__ import annotations

import ctypes
import struct
import zlib
from pathlib import Path

import pytest

from ctdrill.haptics.ccore import CDeviceEmulator, Precision, load_core
from ctdrill.haptics.framing import cobs_decode, cobs_encode, crc32c
from tests.haptics.test_protocol_doc import (
    BLOCKS,
    DOC,
    HELLO,
    HOST_BLOCKS,
    _bytes,
    _lines,
    replay_block,
)

PRECISIONS: tuple[Precision, ...] = ("double", "single")
ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("block", BLOCKS, ids=[f"example{i}" for i in range(len(BLOCKS))])
def test_byte_example_replays_on_the_c_core(block: str, precision: Precision) -> None:
    emu = CDeviceEmulator(nonce_seed=0, precision=precision)
    replay_block(block, emu, set_device_seq=emu.set_device_seq)


def _doc_frames() -> list[bytes]:
    """Every wire frame the document writes (device and host examples, the worked example)."""
    frames = []
    for block in (*BLOCKS, *HOST_BLOCKS):
        for kind, arg in _lines(block):
            if kind in "<>":
                data = _bytes(arg)
                frames += [f for f in data.split(b"\x00") if f]
    return frames


def test_every_frame_of_the_document_decodes_and_encodes_byte_for_byte_in_c() -> None:
    lib = load_core("double")
    frames = _doc_frames()
    assert len(frames) > 100
    exact = 0
    raw_buf = ctypes.create_string_buffer(300)
    out_buf = ctypes.create_string_buffer(300)
    for frame in frames:
        n = lib.fw_cobs_decode(frame, len(frame), raw_buf, 300)
        try:
            py_raw = cobs_decode(frame)
        except ValueError:
            assert n < 0
            continue
        assert n == len(py_raw) and raw_buf.raw[:n] == py_raw
        if len(py_raw) < 22 or len(py_raw) > 254:
            continue
        crc_ok = struct.unpack_from("<I", py_raw, len(py_raw) - 4)[0] == crc32c(py_raw[:-4])
        assert lib.fw_crc32c(py_raw[:-4], len(py_raw) - 4) == crc32c(py_raw[:-4])
        # the C encoder repeats the frame byte for byte from its fields
        ln = lib.fw_cobs_encode(py_raw, len(py_raw), out_buf)
        assert out_buf.raw[:ln] == cobs_encode(py_raw) == frame
        if not crc_ok or py_raw[0] != 3:
            continue
        mtype, seq, session, time_us = struct.unpack_from("<BIIQ", py_raw, 1)
        body = py_raw[18:-4]
        ln = lib.fw_encode_frame(mtype, seq, session, time_us, body, len(body), out_buf)
        assert out_buf.raw[:ln] == frame + b"\x00"
        exact += 1
    assert exact > 90


def test_the_worked_example_and_the_check_values() -> None:
    lib = load_core("double")
    assert lib.fw_crc32c(b"123456789", 9) == 0xE3069283
    assert lib.fw_crc32(0, b"123456789", 9) == 0xCBF43926 == zlib.crc32(b"123456789")
    worked = bytes.fromhex(
        "04 03 22 02 01 01 05 ce 07 2c d8 01 01 01 01 01 01 01 05 ae 73 43 f4 00"
    )
    assert "04 03 22 02  01 01 05 ce 07 2c d8" in DOC
    out = ctypes.create_string_buffer(300)
    n = lib.fw_encode_frame(0x22, 2, 0xD82C07CE, 0, b"", 0, out)
    assert out.raw[:n] == worked
    # serial-number arithmetic (RFC 1982)
    assert lib.fw_seq_after(0, 0xFFFFFFFF) and not lib.fw_seq_after(5, 5)
    assert lib.fw_seq_after(0x7FFFFFFF, 0) and not lib.fw_seq_after(0x80000000, 0)


def test_hardware_refuses_the_simulator_messages_but_the_emulator_takes_them() -> None:
    # the host build answers SIM_OPERATOR with nothing when accepted (doc section 7); the
    # doc's refusals of NaN and unknown kinds are replayed above
    emu = CDeviceEmulator(nonce_seed=0)
    emu.receive(HELLO)
    emu.take_output()
    from ctdrill.haptics.protocol import SimOperator, encode

    emu.receive(encode(SimOperator(1, 10.0), seq=2, session=emu.session))
    assert emu.take_output() == b""
    emu.run_ticks(100)
    assert emu.position_mm > 0.0  # the hand pushes the idle stage


@pytest.mark.parametrize("block", BLOCKS[:8], ids=[f"example{i}" for i in range(8)])
def test_the_boards_split_decode_then_poll_gives_the_same_bytes(block: str) -> None:
    # on a board fw_receive decodes in the background and fw_poll handles the frames in the
    # tick; polled before the next tick, the replies are the document's
    emu = CDeviceEmulator(nonce_seed=0)
    lib, h = load_core("double"), emu.handle
    lib.fw_host_set_defer(h, 1)

    def poll() -> None:
        assert emu.take_output() == b""  # nothing handled before the poll
        while lib.fw_host_poll(h, 2):
            pass

    replay_block(block, emu, set_device_seq=emu.set_device_seq, handle=poll)
    assert lib.fw_host_frames_dropped(h) == 0


def test_the_board_and_the_core_compile_clean_for_the_microcontroller() -> None:
    # the ARM toolchain is make firmware's; here the host compiler checks the same sources
    # (C99, pedantic, every warning an error) for both precisions
    import subprocess

    from ctdrill.haptics.ccore import compiler

    cc = compiler()
    assert cc is not None
    fw = ROOT / "firmware"
    sources = [
        "fw_frame.c",
        "fw_render.c",
        "fw_device.c",
        "board/m4f_board.c",
        "board/m4f_start.c",
        "board/m4f_cycles.c",
    ]
    for real in ([], ["-DFW_REAL_FLOAT"]):
        done = subprocess.run(
            [
                cc,
                "-std=c99",
                "-pedantic",
                "-Wall",
                "-Wextra",
                "-Werror",
                "-fsyntax-only",
                "-DFW_NO_MAIN",
                *real,
                *(str(fw / s) for s in sources),
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert done.returncode == 0, done.stderr

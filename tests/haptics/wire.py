"""Byte-level host for tests: HELLO an emulator, then frames with its session and rising seq."""

from __future__ import annotations

from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.protocol import FrameReader, Hello, Message, Packet, Version, encode


class Wire:
    """Talk to a :class:`DeviceEmulator` frame by frame, as a well-behaved host would."""

    def __init__(self, emulator: DeviceEmulator) -> None:
        self.emulator = emulator
        self.seq = 0
        self.session = 0

    def frame(self, message: Message, *, seq: int | None = None) -> bytes:
        """The next frame of this session (or with an explicit ``seq``, e.g. a replay)."""
        if seq is None:
            self.seq += 1
            seq = self.seq
        return encode(message, seq=seq, session=self.session)

    def send(self, message: Message) -> None:
        """Deliver one frame to the device."""
        self.emulator.receive(self.frame(message))

    def hello(self, token: int = 0x5EED) -> Packet:
        """HELLO; takes the session nonce from the device's VERSION (returned)."""
        self.send(Hello(host_token=token))
        for packet in self.packets():
            if isinstance(packet.message, Version):
                self.session = packet.session
                return packet
        raise AssertionError("no VERSION after HELLO")

    def packets(self) -> list[Packet]:
        """Everything the device wrote since the last call, decoded (all must decode)."""
        items = FrameReader().feed(self.emulator.take_output())
        assert all(isinstance(i, Packet) for i in items), items
        return [i for i in items if isinstance(i, Packet)]

"""A pyigtl OpenIGTLink server on a free loopback port that records every message.

pyigtl's server keeps only the newest message per name; :class:`Recorder` keeps them all,
in arrival order, too.
"""

from __future__ import annotations

import contextlib
import signal
import socket
import time
from collections.abc import Iterator
from typing import Any


class Recorder(dict[str, Any]):
    """pyigtl's incoming-message store, keeping every message in arrival order in ``log``."""

    def __init__(self) -> None:
        super().__init__()
        self.log: list[Any] = []

    def __setitem__(self, key: str, value: Any) -> None:
        self.log.append(value)
        super().__setitem__(key, value)

    def wait_for(self, count: int, *, timeout_s: float = 10.0) -> list[Any]:
        """The messages once ``count`` have arrived (or after ``timeout_s``)."""
        end = time.monotonic() + timeout_s
        while len(self.log) < count and time.monotonic() < end:
            time.sleep(0.01)
        return list(self.log)


@contextlib.contextmanager
def igtl_server() -> Iterator[tuple[int, Recorder]]:
    """``(port, recorder)`` of a running server; stopped (and the signal handlers it replaced
    restored) on exit."""
    import pyigtl

    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    server = pyigtl.OpenIGTLinkServer(port=0, local_server=True)  # installs signal handlers
    received = Recorder()
    server.incoming_messages = received
    try:
        yield int(server.server_address[1]), received
    finally:
        server.stop()
        for sig, handler in handlers.items():
            signal.signal(sig, handler)


def free_port() -> int:
    """A loopback port nothing listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])

"""A Dask scheduler address whose peer answers garbage (issue 36): the real command, in its own
process, prints one ``error:`` line and exits 2 at once; nothing follows it (Dask's client,
half made, used to be closed synchronously at exit: 16 s later a traceback)."""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from ctdrill.app.batch.cluster import CLOSE_TIMEOUT_S, CONNECT_TIMEOUT_S

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"


@pytest.fixture
def garbage_peer(request: pytest.FixtureRequest) -> Iterator[str]:
    """A loopback listener that answers every connection with ``request.param``."""
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(8)
    conns: list[socket.socket] = []

    def serve() -> None:
        while True:
            try:
                conn, _ = sock.accept()
                conns.append(conn)
                conn.sendall(request.param)
            except OSError:
                return

    threading.Thread(target=serve, daemon=True).start()
    yield f"tcp://127.0.0.1:{sock.getsockname()[1]}"
    for c in conns:
        c.close()
    sock.close()


@pytest.mark.parametrize(
    "garbage_peer",
    [b"HTTP/1.1 200 OK\r\n\r\nnot a scheduler" * 8],
    indirect=True,
    ids=["http"],
)
def test_garbage_from_the_scheduler_is_one_line_and_nothing_after(
    tmp_path: Path, garbage_peer: str
) -> None:
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"id,dicom,plan\nr1,{DEMO / 'ct'},{DEMO / 'plan.json'}\n")
    start = time.monotonic()
    out = str(tmp_path / "out")
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "ctdrill.app.cli",
            "batch",
            str(manifest),
            "--out",
            out,
            "--scheduler",
            garbage_peer,
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    elapsed = time.monotonic() - start
    assert run.returncode == 2, run.stderr
    assert run.stderr.startswith(f"error: --scheduler {garbage_peer}: cannot connect (")
    assert run.stderr.count("\n") == 1, run.stderr  # no traceback, no "Exception ignored"
    # the connection's bound, the half-made client's brief close and the interpreter's start
    assert elapsed < CONNECT_TIMEOUT_S + CLOSE_TIMEOUT_S + 5.0
    assert not (tmp_path / "out").exists()

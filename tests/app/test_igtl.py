"""``ctdrill rehearse --igtl``: a rehearsal watched through a real OpenIGTLink socket.

The server is pyigtl's own (``OpenIGTLinkServer``) on a free loopback port
(:mod:`tests.app.igtl_server`), recording every message.
"""

from __future__ import annotations

import csv
import json
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.app.igtl.frames import IgtlTarget, StreamGeometry
from ctdrill.app.igtl.stream import IgtlStream
from ctdrill.haptics.device import TelemetrySample
from tests.app.igtl_server import Recorder, free_port, igtl_server

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"
FIELDS = {
    "time_s",
    "state",
    "drill_depth_mm",
    "master_depth_mm",
    "hand_force_n",
    "device_force_n",
    "cutting_force_n",
    "wall_force_n",
}


@pytest.fixture
def server() -> Iterator[tuple[int, Recorder]]:
    with igtl_server() as running:
        yield running


def _rehearse(out: Path, igtl: str, duration: str) -> int:
    return main(
        [
            "rehearse",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(DEMO / "plan.json"),
            "--out",
            str(out),
            "--operator",
            "push:20",
            "--duration-s",
            duration,
            "--igtl",
            igtl,
        ]
    )


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("warning: OpenIGTLink")]


def test_a_rehearsal_streams_poses_and_forces_that_match_the_session(
    tmp_path: Path, server: tuple[int, Recorder], capsys: pytest.CaptureFixture[str]
) -> None:
    port, received = server
    duration_s = 1.5  # the push reaches the stop at 0.97 s: cutting, then the wall
    assert _rehearse(tmp_path / "out", f"127.0.0.1:{port}", str(duration_s)) == 0
    assert not _warnings(capsys.readouterr().err)
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    igtl = summary["igtl"]
    assert (igtl["host"], igtl["port"], igtl["connected"], igtl["error"]) == (
        "127.0.0.1",
        port,
        True,
        None,
    )
    assert igtl["frames"] == round(duration_s / 0.01)  # one per 10 ms block
    assert igtl["sent"] + igtl["dropped"] == igtl["frames"]
    counts = igtl["messages"]
    assert counts["DrillTip"] == counts["Forces"] == igtl["sent"]
    assert counts["Implant"] >= 2  # with the first frame, then once a second
    log = received.wait_for(sum(counts.values()))
    assert len(log) == sum(counts.values())
    assert [m.device_name for m in log[:3]] == ["DrillTip", "Forces", "Implant"]

    # The plan, read here: LPS entry and target; RAS negates x and y.
    plan = json.loads((DEMO / "plan.json").read_text())
    assert plan["coordinate_system"] == "LPS"
    entry, target = np.array(plan["entry_mm"]), np.array(plan["target_mm"])
    axis = (target - entry) / np.linalg.norm(target - entry)
    flip = np.array([-1.0, -1.0, 1.0])
    with (tmp_path / "out" / "session.csv").open(newline="") as f:
        rows = {r["time_s"]: r for r in csv.DictReader(f)}
    tips = [m for m in log if m.device_name == "DrillTip"]
    forces = [m for m in log if m.device_name == "Forces"]
    states = set()
    for tip, force in zip(tips, forces, strict=True):
        doc = json.loads(force.string)
        assert set(doc) == FIELDS and tip.timestamp == force.timestamp
        row = rows[f"{doc['time_s']:.4f}"]  # the frame is a sample of session.csv
        drill_mm = float(row["drill_mm"])
        assert doc["drill_depth_mm"] == pytest.approx(drill_mm, abs=1e-9)
        assert doc["device_force_n"] == pytest.approx(float(row["force_cmd_n"]), abs=1e-9)
        assert doc["state"] == row["state"]
        states.add(doc["state"])
        split = {"cutting": "cutting_force_n", "stopped": "wall_force_n"}.get(doc["state"])
        for key in ("cutting_force_n", "wall_force_n"):
            want = max(doc["device_force_n"], 0.0) if key == split else 0.0
            assert doc[key] == pytest.approx(want, abs=1e-9)
        # the tip: session.csv's drill depth along the plan's axis, in RAS; float32 on the wire
        # (|coordinate| < 64 mm: 4e-6 mm) and 5 decimals in the csv
        matrix = np.asarray(tip.matrix, dtype=np.float64)
        np.testing.assert_allclose(matrix[:3, 3], flip * (entry + drill_mm * axis), atol=2e-5)
        np.testing.assert_allclose(matrix[:3, 2], flip * axis, atol=1e-6)  # z: the drill axis
        np.testing.assert_allclose(matrix[:3, :3].T @ matrix[:3, :3], np.eye(3), atol=1e-6)
    assert {"cutting", "stopped"} <= states
    implants = [m for m in log if m.device_name == "Implant"]
    span_s = tips[-1].timestamp - tips[0].timestamp
    assert len(implants) == counts["Implant"]
    # again with the first frame at least 1 s after the last: one per whole second of the span
    # (a second may slip by the frames' spacing)
    assert len(implants) - 1 in (int(span_s) - 1, int(span_s))
    implant = implants[0]
    np.testing.assert_allclose(np.asarray(implant.matrix)[:3, 3], flip * target, atol=2e-5)

    # Rate: >= 30 frames per second of the header timestamps (100 Hz nominal: the simulator
    # runs at the wall clock's pace; a machine 3x slower than real time would still pass).
    stamps = np.array([m.timestamp for m in tips])
    assert np.all(np.diff(stamps) > 0.0)
    assert (len(stamps) - 1) / (stamps[-1] - stamps[0]) >= 30.0
    assert len(stamps) >= 30.0 * duration_s
    assert igtl["send_rate_hz"] >= 30.0


def test_a_refused_connection_warns_once_and_the_session_goes_on(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    port = free_port()  # nothing listens there
    assert _rehearse(tmp_path / "out", f"127.0.0.1:{port}", "0.3") == 0
    captured = capsys.readouterr()
    assert len(_warnings(captured.err)) == 1 and "refused" in captured.err
    assert "the session goes on without streaming" in captured.err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["complete"] is True and summary["samples"] == 300
    igtl = summary["igtl"]
    assert igtl["connected"] is False and igtl["sent"] == 0 and "refused" in igtl["error"]
    assert igtl["dropped"] == igtl["frames"] == 30
    assert "sent 0 of 30 frames (30 dropped); stopped: cannot connect" in captured.out


class _StalledPeer:
    """Accepts one connection and never reads from it (a tiny receive buffer)."""

    def __init__(self) -> None:
        self.listener = socket.socket()
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1024)
        self.listener.bind(("127.0.0.1", 0))
        self.listener.listen(1)
        self.port = int(self.listener.getsockname()[1])
        self.conns: list[socket.socket] = []
        self.thread = threading.Thread(target=self._accept, daemon=True)
        self.thread.start()

    def _accept(self) -> None:
        conn, _ = self.listener.accept()
        self.conns.append(conn)

    def close(self) -> None:
        for c in [*self.conns, self.listener]:
            c.close()


def test_a_stalled_peer_costs_the_session_nothing_and_is_reported(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    peer = _StalledPeer()
    try:
        assert _rehearse(tmp_path / "out", f"127.0.0.1:{peer.port}", "3") == 0
    finally:
        peer.close()
    captured = capsys.readouterr()
    assert len(_warnings(captured.err)) == 1 and "stopped reading" in captured.err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    # The session ran its course: every sample, no host fault (the watchdog never starved).
    assert summary["complete"] is True and summary["samples"] == 3000
    assert not [f for f in summary["faults"] if f["source"] == "host"]
    igtl = summary["igtl"]
    assert igtl["connected"] is True and "stopped reading" in igtl["error"]
    assert igtl["frames"] == 300 and 0 < igtl["sent"] < 300 and igtl["dropped"] > 0


def _samples(n: int) -> Iterator[list[TelemetrySample]]:
    for k in range(n):
        yield [TelemetrySample(k * 0.01, k * 100, 1.0, k * 0.01, 0.0, 5.0, 6.0, 1, 0, 0)]


def test_a_peer_that_stalls_ends_the_stream_within_its_timeout() -> None:
    peer = _StalledPeer()
    warnings: list[str] = []
    stream = IgtlStream(
        IgtlTarget("127.0.0.1", peer.port),
        StreamGeometry((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
        on_warning=warnings.append,
        stall_timeout_s=0.2,
    )
    try:
        for block in _samples(100_000):  # offered as fast as the loop can: never blocks
            stream.observe(block)
            if stream.report.error is not None:
                break
            time.sleep(0.0005)
        report = stream.close()
    finally:
        peer.close()
    assert report.error is not None and "nothing taken for 0.2 s" in report.error
    assert len(warnings) == 1 and 0 < report.sent < report.frames


def test_a_peer_that_hangs_up_ends_the_stream_with_one_warning() -> None:
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    warnings: list[str] = []
    stream = IgtlStream(
        IgtlTarget("127.0.0.1", int(listener.getsockname()[1])),
        StreamGeometry((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
        on_warning=warnings.append,
    )
    conn, _ = listener.accept()
    end = time.monotonic() + 10.0
    while not stream.report.connected and time.monotonic() < end:  # its connect() returned
        time.sleep(0.005)
    conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
    conn.close()  # a reset: the next sends fail
    listener.close()
    for block in _samples(100_000):  # until the sender has met the reset (not a fixed time)
        stream.observe(block)
        if stream.report.error is not None:
            break
        time.sleep(0.002)
    report = stream.close()
    assert report.connected and report.error is not None and "lost" in report.error
    assert len(warnings) == 1 and report.dropped == report.frames - report.sent > 0


def test_bad_igtl_values_are_one_error_line_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for value, says in (("localhost", "no port"), ("localhost:70000", "1..65535")):
        assert _rehearse(tmp_path / "out", value, "1") == 2
        err = capsys.readouterr().err.splitlines()
        assert len(err) == 1 and err[0].startswith(f"error: --igtl '{value}': ") and says in err[0]
        assert not (tmp_path / "out").exists()


def test_a_drill_sequence_streams_each_drills_session_named_by_drill(
    tmp_path: Path, server: tuple[int, Recorder], capsys: pytest.CaptureFixture[str]
) -> None:
    """Each drill's session streams through the one connection: a ``Drill`` STRING names the
    drill before its first pose, and every frame after it is a row of that drill's
    session.csv, at the tip of that drill's depth on the plan's axis."""
    from ctdrill.imaging.plan.load import load_plan
    from ctdrill.imaging.plan.types import DrillSpec
    from ctdrill.imaging.plan.write import save_plan

    port, received = server
    drills = (DrillSpec(diameter_mm=2.0, tip_length_mm=0.6), DrillSpec(3.0, tip_length_mm=0.9))
    save_plan(load_plan(DEMO / "plan.json").with_drills(drills), tmp_path / "seq.plan.json")
    out = tmp_path / "out"
    code = main(
        [
            "rehearse",
            *("--dicom", str(DEMO / "ct"), "--plan", str(tmp_path / "seq.plan.json")),
            *("--out", str(out), "--operator", "push:20", "--duration-s", "0.5"),
            *("--igtl", f"127.0.0.1:{port}"),
        ]
    )
    captured = capsys.readouterr()
    assert code == 0 and not _warnings(captured.err)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["drills_run"] == 2
    igtl = summary["igtl"]
    assert igtl["connected"] is True and igtl["error"] is None
    assert igtl["frames"] == 2 * 50 and igtl["sent"] + igtl["dropped"] == igtl["frames"]
    counts = igtl["messages"]
    assert counts["DrillTip"] == counts["Forces"] == igtl["sent"] and counts["Drill"] >= 2
    assert "OpenIGTLink 127.0.0.1:" in captured.out
    log = received.wait_for(sum(counts.values()))
    assert len(log) == sum(counts.values())
    assert log[0].device_name == "Drill"  # named before the first pose

    plan = json.loads((DEMO / "plan.json").read_text())
    entry, target = np.array(plan["entry_mm"]), np.array(plan["target_mm"])
    axis = (target - entry) / np.linalg.norm(target - entry)
    flip = np.array([-1.0, -1.0, 1.0])
    rows: dict[str, dict[str, dict[str, str]]] = {}
    for k in (1, 2):
        with (out / f"drill_{k}" / "session.csv").open(newline="") as f:
            rows[f"drill_{k}"] = {r["time_s"]: r for r in csv.DictReader(f)}
    current: dict[str, object] | None = None
    seen: list[int] = []
    pose = None
    frames_per_drill = {1: 0, 2: 0}
    for m in log:
        if m.device_name == "Drill":
            current = json.loads(m.string)
            assert current is not None
            assert current["drills"] == 2
            assert current["diameter_mm"] == drills[int(str(current["drill"])) - 1].diameter_mm
            if not seen or seen[-1] != current["drill"]:
                seen.append(int(str(current["drill"])))
        elif m.device_name == "DrillTip":
            pose = np.asarray(m.matrix, dtype=np.float64)
        elif m.device_name == "Forces":
            assert current is not None and pose is not None
            doc = json.loads(m.string)
            row = rows[str(current["folder"])][f"{doc['time_s']:.4f}"]
            drill_mm = float(row["drill_mm"])
            assert doc["drill_depth_mm"] == pytest.approx(drill_mm, abs=1e-9)
            np.testing.assert_allclose(pose[:3, 3], flip * (entry + drill_mm * axis), atol=2e-5)
            frames_per_drill[int(str(current["drill"]))] += 1
    assert seen == [1, 2]  # drill 1's frames, then drill 2's: never back
    assert frames_per_drill[1] > 0 and frames_per_drill[2] > 0
    # each drill's session time starts at 0 again: its own session.csv's
    assert sum(frames_per_drill.values()) == igtl["sent"]


def _stream_for(port: int, seconds: float) -> tuple[IgtlStream, list[str]]:
    """A stream to ``port`` offered a frame every 10 ms for ``seconds`` (a session's pace)."""
    warnings: list[str] = []
    stream = IgtlStream(
        IgtlTarget("127.0.0.1", port),
        StreamGeometry((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
        on_warning=warnings.append,
    )
    for block in _samples(round(seconds / 0.01)):
        stream.observe(block)
        time.sleep(0.01)
    return stream, warnings


@pytest.mark.parametrize("seconds", [0.4, 1.2])
def test_a_listener_that_never_accepts_is_an_error_not_frames_sent(seconds: float) -> None:
    # The kernel completes the connection and takes bytes into its buffer for the port; no
    # program ever reads them. The stream sees the server's window shrink: an error (and one
    # warning), never "sent N of M frames" as if delivered.
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(4)  # and never accept()
    try:
        stream, warnings = _stream_for(int(listener.getsockname()[1]), seconds)
        report = stream.close()
    finally:
        listener.close()
    assert report.connected and report.error is not None, report
    assert "not reading" in report.error and "never accepts" in report.error
    assert len(warnings) == 1


def test_a_server_that_reads_is_never_taken_for_one_that_does_not(
    server: tuple[int, Recorder],
) -> None:
    port, _ = server
    stream, warnings = _stream_for(port, 1.6)
    report = stream.close()
    assert report.error is None and warnings == [] and report.sent > 100

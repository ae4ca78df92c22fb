"""``ctdrill batch`` against hostile inputs and rough handling (issue 29).

Resume sees every file a row reads (a mask or a calibration beside the plan), a damaged row
output is redone, row ids cannot collide with the runner's own names, Ctrl-C stops the batch
and records the truth, ``kill -9`` leaves no live worker, a manifest cell of ``/`` is refused
before it is walked, and ``--scheduler`` ends every failure with one ``error:`` line.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.batch.manifest import read_manifest
from ctdrill.app.batch.run import EXIT_INTERRUPTED, run_batch
from ctdrill.app.batch.task import ROW_MARKER, is_complete
from ctdrill.app.batch.workers import NOT_RUN
from ctdrill.engine.settings import ExportSettings
from tests.conftest import ASSETS
from tests.robustness.outcomes import CliRun, error_line_problems, run_cli_in_process

DEMO = ASSETS / "demo"
FAST = ["--no-plot", "--rate-hz", "100"]
OPTIONS = ExportSettings(plot=False, rate_hz=100.0)


def _batch(manifest: Path, out: Path, *extra: str) -> CliRun:
    return run_cli_in_process(["batch", str(manifest), "--out", str(out), *FAST, *extra])


def _status(out: Path) -> list[dict[str, str]]:
    import csv

    with (out / "status.csv").open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _summary(out: Path, row_id: str) -> dict[str, object]:
    doc: dict[str, object] = json.loads(
        (out / "rows" / row_id / "summary.json").read_text(encoding="utf-8")
    )
    return doc


def _demo_rows(folder: Path, n: int, *, prefix: str = "r") -> Path:
    manifest = folder / "manifest.csv"
    lines = ["id,dicom,plan"]
    lines += [f"{prefix}{i:02d},{DEMO / 'ct'},{DEMO / 'plan.json'}" for i in range(1, n + 1)]
    manifest.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return manifest


# -- resume covers every file a row reads ----------------------------------------------------


#: The mask's grid: 1 mm voxels from x = -1 mm (column 0) to 38 mm, y 9..11, z -36..-34.
MASK_AFFINE = [[1.0, 0, 0, -1.0], [0, 1.0, 0, 9.0], [0, 0, 1.0, -36.0], [0, 0, 0, 1.0]]


def _mask(folder: Path, columns: slice) -> None:
    """``mask.npy`` on :data:`MASK_AFFINE` labelled in ``columns`` (x = column - 1 mm)."""
    grid = np.zeros((3, 3, 40), dtype=np.uint8)
    grid[:, :, columns] = 1
    np.save(folder / "mask.npy", grid)


def _case(tmp_path: Path) -> tuple[Path, Path]:
    """A plan naming a mask (away from the drill) and a calibration file, both beside it."""
    case = tmp_path / "case"
    case.mkdir()
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    _mask(case, slice(0, 3))  # x -1..1 mm: far from the drill at x = 32 mm
    doc["landmarks"] = [
        {"name": "segmented nerve", "kind": "mask", "path": "mask.npy", "affine_lps": MASK_AFFINE}
    ]
    doc["calibration"] = "cal.json"
    shutil.copy(ASSETS / "calibration" / "bone-illustrative.json", case / "cal.json")
    (case / "plan.json").write_text(json.dumps(doc), encoding="utf-8")
    manifest = tmp_path / "manifest.csv"
    manifest.write_text(f"id,dicom,plan\np,{DEMO / 'ct'},case/plan.json\n", encoding="utf-8")
    return manifest, case


def test_resume_redoes_a_row_when_a_mask_or_calibration_its_plan_names_changes(
    tmp_path: Path,
) -> None:
    manifest, case = _case(tmp_path)
    out = tmp_path / "out"
    assert _batch(manifest, out).code == 0
    assert _summary(out, "p")["stop_reason"] == "planned_depth"
    peak = _summary(out, "p")["peak_force_n"]
    # the same bytes written again (a copy, a touch): still complete
    data = (case / "mask.npy").read_bytes()
    (case / "mask.npy").write_bytes(data)
    os.utime(case / "cal.json")
    run = _batch(manifest, out)
    assert run.code == 0 and "1 ok (1 resumed)" in run.stdout
    # the case: the mask moved onto the drill path, the plan untouched
    _mask(case, slice(32, 35))  # x 31..33 mm, z -36..-34: on the path
    run = _batch(manifest, out)
    assert run.code == 0 and "1 ok (0 resumed)" in run.stdout, run
    moved = _summary(out, "p")
    assert moved["stop_reason"] == "margin" and float(str(moved["stop_depth_mm"])) < 6.0
    plan = str(case / "plan.json")
    fresh = run_cli_in_process(
        ["export", "--dicom", str(DEMO / "ct"), "--plan", plan, "--out", str(tmp_path / "f"), *FAST]
    )
    assert fresh.code == 0, fresh.stderr
    fresh_doc = json.loads((tmp_path / "f" / "summary.json").read_text(encoding="utf-8"))
    assert moved["stop_depth_mm"] == fresh_doc["stop_depth_mm"]
    # the calibration's content changes: redone, other forces
    cal = json.loads((case / "cal.json").read_text(encoding="utf-8"))
    cal["a0"]["b0"] += 0.5
    (case / "cal.json").write_text(json.dumps(cal), encoding="utf-8")
    run = _batch(manifest, out)
    assert run.code == 0 and "1 ok (0 resumed)" in run.stdout
    assert _summary(out, "p")["peak_force_n"] != peak
    # a --calibration file given on the command line is an input too
    other = tmp_path / "other.json"
    shutil.copy(ASSETS / "calibration" / "pine-wood-paper.json", other)
    assert _batch(manifest, out, "--calibration", str(other)).code == 0
    assert "1 resumed" in _batch(manifest, out, "--calibration", str(other)).stdout
    doc = json.loads(other.read_text(encoding="utf-8"))
    doc["gate_hu"] = doc["gate_hu"] + 10
    other.write_text(json.dumps(doc), encoding="utf-8")
    assert "1 ok (0 resumed)" in _batch(manifest, out, "--calibration", str(other)).stdout


# -- damaged outputs are redone ----------------------------------------------------------------


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


DAMAGES = {
    "summary-truncated": lambda row: _truncate(row / "summary.json"),
    "summary-not-an-object": lambda row: (row / "summary.json").write_text("[]"),
    "force-emptied": lambda row: (row / "force.csv").write_bytes(b""),
    "profile-removed": lambda row: (row / "profile.csv").unlink(),
    "profile-bit-flipped": lambda row: (row / "profile.csv").write_bytes(
        (row / "profile.csv").read_bytes().replace(b"1", b"2", 1)
    ),
    "marker-truncated": lambda row: _truncate(row / ROW_MARKER),
    "marker-duplicate-key": lambda row: (row / ROW_MARKER).write_text(
        (row / ROW_MARKER).read_text()[:-2] + ', "fingerprint": "0"}\n'
    ),
    "marker-unsealed": lambda row: (row / ROW_MARKER).write_text(
        json.dumps(
            {k: v for k, v in json.loads((row / ROW_MARKER).read_text()).items() if k != "outputs"}
        )
    ),
}


@pytest.fixture(scope="module")
def one_row(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("damage")
    manifest = _demo_rows(folder, 1)
    out = folder / "out"
    assert _batch(manifest, out).code == 0
    return manifest, out


@pytest.mark.parametrize("damage", sorted(DAMAGES))
def test_a_damaged_row_output_is_redone_not_failed_forever(
    tmp_path: Path, one_row: tuple[Path, Path], damage: str
) -> None:
    manifest, clean = one_row
    out = tmp_path / "out"
    shutil.copytree(clean, out)
    row = out / "rows" / "r01"
    DAMAGES[damage](row)
    run = _batch(manifest, out)
    assert run.code == 0 and "1 ok (0 resumed)" in run.stdout, run
    for path in sorted((clean / "rows" / "r01").iterdir()):
        assert (row / path.name).read_bytes() == path.read_bytes(), path.name
    again = _batch(manifest, out)
    assert "1 ok (1 resumed)" in again.stdout


# -- row ids ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("ids", "fragment"),
    [
        ([".p01.staging-x"], "not start with '.'"),
        ([".z.ctdrill-batch-removed-1"], "not start with '.'"),
        ([".p01.ctdrill-new-1-ab"], "not start with '.'"),
        (["."], "not start with '.'"),
        (["x" * 101], "at most 100 characters"),
        (["Case7", "case7"], "rows 1 and 2 have the same id 'case7' (ignoring case)"),
    ],
)
def test_row_ids_that_could_be_the_runners_names_are_refused(
    tmp_path: Path, ids: list[str], fragment: str
) -> None:
    manifest = tmp_path / "m.csv"
    rows = "".join(f"{i},{DEMO / 'ct'},{DEMO / 'plan.json'}\n" for i in ids)
    manifest.write_text("id,dicom,plan\n" + rows, encoding="utf-8")
    run = _batch(manifest, tmp_path / "out")
    assert not error_line_problems(run), run
    assert fragment in run.stderr and not (tmp_path / "out").exists()


def test_leftovers_of_killed_runs_are_removed_and_rows_are_kept(
    tmp_path: Path, one_row: tuple[Path, Path]
) -> None:
    manifest, clean = one_row
    out = tmp_path / "out"
    shutil.copytree(clean, out)
    rows = out / "rows"
    leftovers = [
        rows / ".r01.staging-x",
        rows / ".r01.ctdrill-new-999999999-abcd",
        rows / ".z.ctdrill-batch-removed-1",
    ]
    for p in leftovers:
        p.mkdir()
    (rows / "r01" / f".{ROW_MARKER}.ctdrill-tmp-999999999-abcd").write_text("x")
    run = _batch(manifest, out)
    assert run.code == 0 and "1 ok (1 resumed)" in run.stdout, run
    assert not any(p.exists() for p in leftovers)
    assert sorted(p.name for p in rows.iterdir()) == ["r01"]
    assert not (rows / "r01" / f".{ROW_MARKER}.ctdrill-tmp-999999999-abcd").exists()


# -- Ctrl-C ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("workers", "after", "presses"), [(1, 2, 1), (2, 2, 1), (2, 1, 2)])
def test_ctrl_c_stops_scheduling_and_records_the_truth(
    tmp_path: Path, workers: int, after: int, presses: int
) -> None:
    """SIGINT when the ``after``-th row is done (``presses`` times): no row starts after it,
    at most the rows running then finish (a second press cancels them), and the tables say
    exactly which rows are complete; the next run resumes them and does the rest."""
    n = 5
    manifest = _demo_rows(tmp_path, n)
    rows = read_manifest(manifest)
    out = tmp_path / "out"

    def progress(done: int, total: int, outcome: object) -> None:
        if done == after:
            for _ in range(presses):
                os.kill(os.getpid(), signal.SIGINT)

    report = run_batch(manifest, rows, out, OPTIONS, workers=workers, progress=progress)
    assert report.interrupted
    ok = [o.row for o in report.outcomes if o.ok]
    not_run = [o.row for o in report.outcomes if o.status == NOT_RUN]
    assert sorted(ok + not_run) == list(range(1, n + 1))  # nothing else happened to a row
    # the rows running at the press may finish (a second press cancels those still running,
    # but one that finished as the presses arrived is complete, and recorded so): never more
    in_flight = workers - 1
    assert after <= len(ok) <= after + in_flight
    status = _status(out)
    for s, o in zip(status, report.outcomes, strict=True):
        folder = out / "rows" / s["id"]
        assert s["status"] == o.status
        if o.ok:
            assert is_complete(folder, _fingerprint(rows[o.row - 1]), manifest.parent)
        else:
            assert not folder.exists()
    import csv

    with (out / "trajectories.csv").open(newline="", encoding="utf-8") as fh:
        assert sorted(int(r["row"]) for r in csv.DictReader(fh)) == sorted(ok)
    batch = json.loads((out / "batch.json").read_text(encoding="utf-8"))
    assert (batch["ok"], batch["not_run"], batch["failed"]) == (len(ok), len(not_run), 0)
    again = run_batch(manifest, rows, out, OPTIONS, workers=workers)
    assert not again.interrupted and all(o.ok for o in again.outcomes)
    assert sum(o.resumed for o in again.outcomes) == len(ok)


def _fingerprint(row: object) -> str | None:
    from ctdrill.app.batch.task import fingerprint

    return fingerprint(row.dicom_path, row.plan_path, OPTIONS)  # type: ignore[attr-defined]


def _start_batch(manifest: Path, out: Path, workers: int) -> subprocess.Popen[str]:
    cmd = [sys.executable, "-m", "ctdrill.app.cli", "batch", str(manifest), "--out", str(out)]
    return subprocess.Popen(
        [*cmd, "--workers", str(workers), *FAST],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
    )


def _wait_for_staging(proc: subprocess.Popen[str], rows: Path) -> None:
    """Until a row is being written (its staging folder exists)."""
    deadline = time.monotonic() + 120
    while not (rows.is_dir() and any(".ctdrill-new-" in p.name for p in rows.iterdir())):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "no row started"
        time.sleep(0.01)


def test_ctrl_c_on_the_command_is_exit_130_and_one_error_line(tmp_path: Path) -> None:
    """The terminal's Ctrl-C reaches the whole process group (workers, forkserver) while the
    first row is being written: exit 130, one ``error:`` line, no traceback from anyone."""
    manifest = _demo_rows(tmp_path, 6)
    out = tmp_path / "out"
    proc = _start_batch(manifest, out, 2)
    _wait_for_staging(proc, out / "rows")
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == EXIT_INTERRUPTED, stderr
    assert stderr.startswith("error: interrupted: ") and stderr.count("\n") == 1, stderr
    assert "Traceback" not in stderr + stdout
    status = _status(out)
    ok = [s for s in status if s["status"] == "ok"]
    assert {s["status"] for s in status} <= {"ok", NOT_RUN}
    assert len(ok) <= 2 and f"{len(status) - len(ok)} not run (interrupted)" in stdout


# -- kill -9 ----------------------------------------------------------------------------------


def _group(pgid: int) -> dict[int, str]:
    """Live processes of the process group ``pgid``: pid -> command line (zombies are dead)."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        state, group = fields[0], int(fields[2])
        if group == pgid and state != "Z":
            found[int(entry.name)] = cmd
    return found


def test_kill_9_of_a_batch_leaves_no_live_worker(tmp_path: Path) -> None:
    manifest = _demo_rows(tmp_path, 6)
    out = tmp_path / "out"
    proc = _start_batch(manifest, out, 2)
    _wait_for_staging(proc, out / "rows")
    before = _group(proc.pid)
    assert any("forkserver" in cmd for cmd in before.values()), before
    assert len(before) >= 4  # the batch, the resource tracker, the forkserver, a worker
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate()
    deadline = time.monotonic() + 60
    while (alive := _group(proc.pid)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive, f"left alive after kill -9: {alive}"


# -- a manifest cell must name a series ------------------------------------------------------


@pytest.mark.parametrize("cell", ["/", "~"])
def test_a_file_system_root_as_a_series_cell_is_a_failed_row_not_a_walk(
    tmp_path: Path, cell: str
) -> None:
    manifest = tmp_path / "m.csv"
    where = os.path.expanduser(cell)
    plan = DEMO / "plan.json"
    manifest.write_text(
        f"id,dicom,plan\nroot,{where},{plan}\nok,{DEMO / 'ct'},{plan}\n", encoding="utf-8"
    )
    run = _batch(manifest, tmp_path / "out")
    assert run.code == 4, run
    status = _status(tmp_path / "out")
    assert "not a series folder" in status[0]["status"] and status[1]["status"] == "ok"


def test_series_folder_check_bounds(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Breadth first, a DICOM file in the top levels before the entry bound makes a series
    folder; a big folder without one is refused; a small one is left to the scan."""
    from ctdrill.imaging.dicom import discovery
    from ctdrill.imaging.dicom.discovery import (
        NEAR_TOP_LEVELS,
        DiscoveryInputError,
        check_series_folder,
    )

    monkeypatch.setattr(discovery, "MAX_ENTRIES_WITHOUT_DICOM", 40)
    slice_file = next(p for p in sorted((DEMO / "ct").iterdir()) if p.is_file())

    def tree(dicom_level: int) -> Path:
        """A DICOM file ``dicom_level`` levels down, then 60 notes one level deeper."""
        top = tmp_path / f"tree{dicom_level}"
        folder = top
        for level in range(1, dicom_level):
            folder = folder / f"level{level}"
        folder.mkdir(parents=True)
        shutil.copy(slice_file, folder / "IM0001")
        (folder / "notes").mkdir()
        for i in range(60):
            (folder / "notes" / f"note{i:02d}.txt").write_text("not dicom")
        return top

    check_series_folder(tree(1))
    check_series_folder(tree(NEAR_TOP_LEVELS))
    with pytest.raises(DiscoveryInputError, match="not a series folder: it holds more than 40"):
        check_series_folder(tree(NEAR_TOP_LEVELS + 1))  # found too deep: not read
    (tree(2) / "level1" / "IM0001").unlink()
    with pytest.raises(DiscoveryInputError, match="no DICOM file in its top"):
        check_series_folder(tmp_path / "tree2")
    small = tmp_path / "small"
    small.mkdir()
    (small / "note.txt").write_text("x")
    check_series_folder(small)  # few entries: the scan says what it found


def test_a_home_folder_with_a_series_near_its_top_is_still_not_a_series_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A series left near the top of the home folder (or of ``/``, say in a temporary folder)
    does not make the home folder a series folder: it would be walked whole."""
    from ctdrill.imaging.dicom.discovery import DiscoveryInputError, check_series_folder

    home = tmp_path / "home"
    series = home / "tmpabc"
    series.mkdir(parents=True)
    slice_file = next(p for p in sorted((DEMO / "ct").iterdir()) if p.is_file())
    shutil.copy(slice_file, series / "IM0000")
    check_series_folder(home)  # not the home folder yet: a DICOM file near the top
    monkeypatch.setenv("HOME", str(home))
    with pytest.raises(DiscoveryInputError, match="root or a home folder"):
        check_series_folder(home)
    check_series_folder(series)  # the series' own folder still is one


# -- --scheduler is bounded -------------------------------------------------------------------


class _Peer:
    """A loopback listener that accepts and then says ``reply`` (nothing: silence)."""

    def __init__(self, reply: bytes) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.reply = reply
        self.conns: list[socket.socket] = []
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    @property
    def address(self) -> str:
        return f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.conns.append(conn)
            if self.reply:
                conn.sendall(self.reply)

    def close(self) -> None:
        for c in self.conns:
            c.close()
        self.sock.close()


@pytest.fixture
def peer(request: pytest.FixtureRequest) -> Iterator[_Peer]:
    p = _Peer(request.param)
    yield p
    p.close()


@pytest.mark.parametrize(
    "peer",
    [
        b"",  # accepts, never speaks
        struct.pack("<Q", 8 << 60),  # a frame header of 8 EiB
        struct.pack("<Q", 1 << 34),  # 16 GiB: allocatable lazily, then nothing comes
        b"\xff" * 64,  # garbage
    ],
    indirect=True,
    ids=["silent", "8-EiB-frame", "16-GiB-frame", "garbage"],
)
def test_a_hostile_scheduler_peer_is_one_error_line_within_the_bound(
    tmp_path: Path, peer: _Peer, monkeypatch: pytest.MonkeyPatch
) -> None:
    from ctdrill.app.batch import cluster

    assert cluster.CONNECT_TIMEOUT_S < 10.0  # the documented bound, whatever the peer does
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 1.5)  # the same code, a shorter wait
    manifest = _demo_rows(tmp_path, 1)
    run = _batch(manifest, tmp_path / "out", "--scheduler", peer.address)
    assert not error_line_problems(run), run
    assert run.stderr.startswith(f"error: --scheduler {peer.address}: cannot connect (")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("address", "fragment"),
    [
        ("ucx://127.0.0.1:8786", "the scheme 'ucx' is not supported"),
        ("ws://127.0.0.1:8786", "the scheme 'ws' is not supported"),
        ("foo://x", "the scheme 'foo' is not supported"),
        ("tls://127.0.0.1:8786", "tls:// needs certificates"),
        ("tcp://", "cannot connect"),
        ("tcp://[::1", "cannot connect"),
    ],
)
def test_unsupported_or_incomplete_scheduler_addresses_are_one_error_line(
    tmp_path: Path, address: str, fragment: str
) -> None:
    manifest = _demo_rows(tmp_path, 1)
    run = _batch(manifest, tmp_path / "out", "--scheduler", address)
    assert not error_line_problems(run), run
    assert fragment in run.stderr and not (tmp_path / "out").exists()


def _openssl(*args: str) -> None:
    subprocess.run(["openssl", *args], check=True, capture_output=True)


def test_tls_works_with_certificates_from_dasks_configuration(tmp_path: Path) -> None:
    """docs/batch.md recommends tls:// across networks: with a CA and certificates in Dask's
    configuration the batch runs on a TLS scheduler as on tcp://."""
    import dask
    from distributed import LocalCluster
    from distributed.security import Security

    d = tmp_path
    pem = {}
    _openssl(
        "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj", "/CN=ctdrill-ca",
        "-keyout", str(d / "ca.key"), "-out", str(d / "ca.pem"),
    )  # fmt: skip
    for who in ("node", "client"):
        _openssl(
            "req", "-newkey", "rsa:2048", "-nodes", "-subj", f"/CN={who}",
            "-keyout", str(d / f"{who}.key"), "-out", str(d / f"{who}.csr"),
        )  # fmt: skip
        (d / "ext.cnf").write_text("subjectAltName=IP:127.0.0.1,DNS:localhost\n")
        _openssl(
            "x509", "-req", "-in", str(d / f"{who}.csr"), "-CA", str(d / "ca.pem"),
            "-CAkey", str(d / "ca.key"), "-CAcreateserial", "-days", "2",
            "-extfile", str(d / "ext.cnf"), "-out", str(d / f"{who}.pem"),
        )  # fmt: skip
        pem[who] = (str(d / f"{who}.pem"), str(d / f"{who}.key"))
    node = Security(
        tls_ca_file=str(d / "ca.pem"),
        tls_scheduler_cert=pem["node"][0],
        tls_scheduler_key=pem["node"][1],
        tls_worker_cert=pem["node"][0],
        tls_worker_key=pem["node"][1],
        tls_client_cert=pem["node"][0],
        tls_client_key=pem["node"][1],
        require_encryption=True,
    )
    manifest = _demo_rows(tmp_path, 2)
    config = {
        "distributed.comm.tls.ca-file": str(d / "ca.pem"),
        "distributed.comm.tls.client.cert": pem["client"][0],
        "distributed.comm.tls.client.key": pem["client"][1],
    }
    with (
        LocalCluster(
            n_workers=1,
            threads_per_worker=1,
            processes=False,
            protocol="tls://",
            host="127.0.0.1",
            security=node,
            dashboard_address=None,
        ) as cluster,
        dask.config.set(config),
    ):
        assert cluster.scheduler_address.startswith("tls://")
        run = _batch(manifest, tmp_path / "out", "--scheduler", cluster.scheduler_address)
    assert run.code == 0, run
    assert "2 ok (0 resumed)" in run.stdout


def test_a_detached_data_file_of_the_ct_or_of_a_mask_is_an_input(tmp_path: Path) -> None:
    """A ``.nhdr``/``.mhd`` header names its voxels' file: replacing that file (the header
    untouched) changes the CT's fingerprint, and a mask's is recorded among the row's inputs."""
    from ctdrill.app.batch.inputs import row_inputs, volume_files
    from ctdrill.app.batch.task import fingerprint
    from tests.imaging.volume_writers import ramp, write_mha, write_nrrd

    affine = np.diag([0.5, 0.5, 0.5, 1.0])
    ct = write_nrrd(tmp_path / "ct.nhdr", ramp((4, 5, 6)), affine, detached=True)
    assert [p.name for p in volume_files(ct)] == ["ct.nhdr", "ct.raw.gz"]
    plan = DEMO / "plan.json"
    before = fingerprint(ct, plan, OPTIONS)
    write_nrrd(tmp_path / "other.nhdr", ramp((4, 5, 6), lo=-900), affine, detached=True)
    (tmp_path / "other.raw.gz").replace(tmp_path / "ct.raw.gz")
    assert fingerprint(ct, plan, OPTIONS) not in (before, None)
    write_mha(tmp_path / "nerve.mhd", np.ones((3, 3, 3), dtype=np.uint8), affine)
    doc = json.loads(plan.read_text(encoding="utf-8"))
    doc["landmarks"] = [{"name": "nerve", "kind": "mask", "path": "nerve.mhd", "label": 1}]
    (tmp_path / "plan.json").write_text(json.dumps(doc), encoding="utf-8")
    names = {p.name for p in row_inputs(tmp_path / "plan.json", None)}
    assert {"nerve.mhd", "nerve.raw", "bone-illustrative.json"} <= names

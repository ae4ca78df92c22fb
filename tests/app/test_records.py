"""app.records: output folders swapped in whole, atomic files, full disks and size limits.

The crash test kills a real writer with SIGKILL at random moments; the full-disk tests write
into a real 1 MiB tmpfs mounted in a private mount namespace (``unshare -m``, or ``-rm`` when
not root), and the size-limit tests set RLIMIT_FSIZE in a subprocess.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from ctdrill.app import records
from ctdrill.app.records import (
    OutputWriteError,
    atomic_output_dir,
    atomic_write_bytes,
    atomic_write_text,
    clean_leftovers,
    write_file,
)


def _tree(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def _siblings(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.parent.iterdir() if p.name != folder.name)


def test_first_output_then_a_replacement_and_no_leftovers(tmp_path: Path) -> None:
    out = tmp_path / "deep" / "out"
    with atomic_output_dir(out) as stage:
        assert stage.parent == out.parent and stage.name.startswith(".out.ctdrill-new-")
        assert not out.exists()  # nothing visible while writing
        write_file(stage / "summary.json", "{}\n")
        (stage / "a").mkdir()
        write_file(stage / "a" / "force.csv", b"x,y\n")
    assert _tree(out) == {"summary.json": b"{}\n", "a/force.csv": b"x,y\n"}
    with atomic_output_dir(out) as stage:
        write_file(stage / "session.csv", "new\n")
    # the whole folder is replaced: a file the new output does not write is gone
    assert _tree(out) == {"session.csv": b"new\n"}
    assert _siblings(out) == []


def test_an_error_leaves_the_old_output_exactly_and_no_staging(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with atomic_output_dir(out) as stage:
        write_file(stage / "summary.json", "old\n")
    before = _tree(out)
    with pytest.raises(RuntimeError, match="boom"), atomic_output_dir(out) as stage:
        write_file(stage / "summary.json", "new\n")
        raise RuntimeError("boom")
    assert _tree(out) == before
    assert _siblings(out) == []


def test_a_folder_of_other_files_is_refused_before_anything_is_written(tmp_path: Path) -> None:
    out = tmp_path / "Desktop"
    out.mkdir()
    (out / "thesis.docx").write_bytes(b"precious")
    (out / "summary.json").write_text("{}", encoding="utf-8")
    refused = pytest.raises(OutputWriteError, match=r"thesis\.docx.*new or empty folder")
    with refused, atomic_output_dir(out, what="--out"):
        raise AssertionError("the block must not run")
    assert (out / "thesis.docx").read_bytes() == b"precious"
    assert _siblings(out) == []
    (tmp_path / "file").write_text("x", encoding="utf-8")
    with (
        pytest.raises(OutputWriteError, match="not a folder"),
        atomic_output_dir(tmp_path / "file"),
    ):
        pass


def test_the_fallback_swap_without_rename_exchange(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "out"
    with atomic_output_dir(out) as stage:
        write_file(stage / "summary.json", "old\n")
    monkeypatch.setattr(records, "_exchange", lambda a, b: False)
    with atomic_output_dir(out) as stage:
        write_file(stage / "summary.json", "new\n")
    assert _tree(out) == {"summary.json": b"new\n"}
    assert _siblings(out) == []


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_leftovers_of_dead_writers_are_cleaned_live_ones_kept_old_restored(tmp_path: Path) -> None:
    out = tmp_path / "out"
    dead = _dead_pid()
    # alive until killed (it waits for its stdin), however long the test takes
    sleeper = subprocess.Popen(
        [sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE
    )
    try:
        stale = tmp_path / f".out.ctdrill-new-{dead}-00aa"
        live = tmp_path / f".out.ctdrill-new-{sleeper.pid}-00bb"
        legacy = tmp_path / ".out.staging-k2j3"  # the earlier export code's staging folders
        aside = tmp_path / f".out.ctdrill-old-{dead}-00cc"
        for folder in (stale, live, legacy, aside):
            folder.mkdir()
            (folder / "summary.json").write_text(folder.name, encoding="utf-8")
        other = tmp_path / ".other.ctdrill-new-1-00dd"  # another output's: not ours to touch
        other.mkdir()
        removed = clean_leftovers(out)
        # the fallback swap died between its renames: the old folder comes back as the output
        assert (out / "summary.json").read_text(encoding="utf-8") == aside.name
        assert sorted(p.name for p in removed) == sorted([stale.name, legacy.name])
        assert live.is_dir() and other.is_dir() and not stale.exists()
    finally:
        sleeper.kill()
        sleeper.wait()


WRITER = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    from ctdrill.app.records import atomic_output_dir, write_file
    out, n_files, size = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
    gen = int(sys.argv[4])
    names = {f"force{i}.csv" for i in range(n_files)} | {"summary.json"}
    while True:
        gen += 1
        with atomic_output_dir(out, owned_names=names) as stage:
            for i in range(n_files):
                sub = stage / f"plan{i % 3}"
                sub.mkdir(exist_ok=True)
                block = f"gen {gen:08d} file {i:03d}\\n".encode()
                write_file(sub / f"force{i}.csv", block * (size // len(block)))
            write_file(stage / "summary.json", f"{gen}\\n")
        print(gen, flush=True)
    """
)


def _check_whole(out: Path, n_files: int, size: int) -> int:
    gen = int((out / "summary.json").read_text(encoding="utf-8"))
    files = sorted(out.rglob("force*.csv"))
    assert len(files) == n_files, f"{len(files)} of {n_files} files"
    for path in files:
        i = int(path.stem.removeprefix("force"))
        block = f"gen {gen:08d} file {i:03d}\n".encode()
        assert path.read_bytes() == block * (size // len(block)), f"{path} mixed or short"
    return gen


def test_kill_9_at_random_moments_leaves_the_old_or_the_new_folder_whole(tmp_path: Path) -> None:
    out = tmp_path / "export"
    n_files, size = 12, 400_000  # 4.8 MB per generation
    rng = random.Random(15)
    gen, kills, seen = 0, 0, set()
    # Each writer is killed after it reports ``done`` finished generations (an event, read from
    # its output) and a random moment more: during start-up, a write, a swap or a clean-up.
    plan = [rng.choice((0, 1, 1, 2)) for _ in range(14)]
    for done in plan:
        proc = subprocess.Popen(
            [sys.executable, "-c", WRITER, str(out), str(n_files), str(size), str(gen)],
            stdout=subprocess.PIPE,
            text=True,
        )
        assert proc.stdout is not None
        for _ in range(done):
            line = proc.stdout.readline()
            assert line.strip().isdigit(), f"the writer died on its own: {proc.communicate()}"
        time.sleep(rng.uniform(0.0, 0.4))
        proc.send_signal(signal.SIGKILL)
        proc.communicate()
        kills += 1
        if out.exists():
            gen = _check_whole(out, n_files, size)
            seen.add(gen)
    # every writer that reported a generation left a newer whole one than the writer before
    assert kills == 14 and len(seen) >= sum(d > 0 for d in plan), (seen, plan)
    # the next write cleans every leftover of the killed writers
    names = {f"force{i}.csv" for i in range(n_files)} | {"summary.json"}
    with atomic_output_dir(out, owned_names=names) as stage:
        write_file(stage / "summary.json", "done\n")
    assert _siblings(out) == []


def test_atomic_write_replaces_whole_and_keeps_permissions(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "cal.json"
    assert atomic_write_text(path, "one\n") == path
    os.chmod(path, 0o640)
    atomic_write_bytes(path, b"two\n")
    assert path.read_bytes() == b"two\n" and (path.stat().st_mode & 0o777) == 0o640
    assert sorted(p.name for p in path.parent.iterdir()) == ["cal.json"]
    with pytest.raises(OutputWriteError, match="is a folder"):
        atomic_write_text(tmp_path / "sub", "x")


def _namespace_prefix() -> list[str]:
    """unshare: a private mount namespace, the tmpfs vanishes with the process."""
    return ["unshare", "-m"] if os.geteuid() == 0 else ["unshare", "-rm"]


FULL_DISK = textwrap.dedent(
    """
    import json, os, subprocess, sys
    from pathlib import Path
    from ctdrill.app.records import OutputWriteError, atomic_output_dir, atomic_write_bytes
    from ctdrill.app.records import write_file
    disk = Path(sys.argv[1])
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(disk)], check=True)
    report = {}
    out = disk / "out"
    with atomic_output_dir(out) as stage:
        write_file(stage / "summary.json", "old\\n")
    try:
        with atomic_output_dir(out) as stage:
            write_file(stage / "summary.json", "new\\n")
            write_file(stage / "force.csv", b"x" * 2_000_000)
    except OutputWriteError as exc:
        report["dir_error"] = str(exc)
    report["dir_after"] = (out / "summary.json").read_text()
    report["dir_names"] = sorted(os.listdir(disk))
    cal = disk / "cal.json"
    atomic_write_bytes(cal, b'{"good": true}\\n')
    try:
        atomic_write_bytes(cal, b"{" * 2_000_000)
    except OutputWriteError as exc:
        report["file_error"] = str(exc)
    report["file_after"] = cal.read_text()
    report["names"] = sorted(os.listdir(disk))
    print(json.dumps(report))
    """
)


def test_a_full_disk_is_one_error_naming_the_file_and_the_old_output_stays(
    tmp_path: Path,
) -> None:
    disk = tmp_path / "disk"
    disk.mkdir()
    proc = subprocess.run(
        [*_namespace_prefix(), sys.executable, "-c", FULL_DISK, str(disk)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    final = disk / "out" / "force.csv"
    assert report["dir_error"] == (
        f"{final}: cannot write it: the disk is full (or the quota is used up); "
        "free space or write elsewhere"
    )
    assert report["dir_after"] == "old\n" and report["dir_names"] == ["out"]
    assert report["file_error"].startswith(
        f"{disk / 'cal.json'}: cannot write it: the disk is full"
    )
    assert report["file_after"] == '{"good": true}\n'
    assert report["names"] == ["cal.json", "out"]
    assert not list(disk.iterdir())  # the tmpfs lived in the private namespace only


SIZE_LIMIT = textwrap.dedent(
    """
    import resource, signal, sys
    from pathlib import Path
    from ctdrill.app.records import OutputWriteError, atomic_write_bytes
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, 100_000))
    try:
        atomic_write_bytes(Path(sys.argv[1]), b"y" * 300_000)
    except OutputWriteError as exc:
        print(exc)
    """
)


def test_a_file_size_limit_is_one_error_naming_the_file(tmp_path: Path) -> None:
    path = tmp_path / "big.bin"
    path.write_bytes(b"old")
    proc = subprocess.run(
        [sys.executable, "-c", SIZE_LIMIT, str(path)], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == (
        f"{path}: cannot write it: the file exceeds the file-size limit (ulimit -f / "
        "RLIMIT_FSIZE); raise the limit or write elsewhere\n"
    )
    assert path.read_bytes() == b"old" and sorted(os.listdir(tmp_path)) == ["big.bin"]

"""Building and loading the firmware's C core on the host (:mod:`ctdrill.haptics.ccore`).

The sources are package data (``ctdrill.firmware``: ``firmware/`` in the checkout), so a wheel
carries them; the shared library is compiled on first use into a cache folder
(:func:`cache_dir`: ``$CTDRILL_FIRMWARE_CACHE``, else ``<venv>/var/ctdrill-firmware`` when the
environment is writable, else ``~/.cache/ctdrill/firmware``), keyed by a hash of the sources,
the flags and the compiler, and written aside then renamed. Without a compiler the core cannot
be built: :class:`CoreUnavailableError` says so in one line (``--core python`` still works).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from importlib.resources import as_file, files
from pathlib import Path
from typing import Literal

from ctdrill.haptics.errors import HapticsInputError

Precision = Literal["double", "single"]
#: The core's sources, relative to the package ``ctdrill.firmware``.
SOURCES = ("fw_frame.c", "fw_render.c", "fw_device.c", "host/fw_host.c")
HEADERS = ("fw.h", "fw_law.h")
#: Compiler flags of the host build: C99, no fast-math and no contraction into FMA (the
#: double build repeats Python's float arithmetic operation for operation).
CFLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-ffp-contract=off", "-fno-fast-math", "-Wall")
SANITIZE = (
    "-fsanitize=address,undefined,float-cast-overflow",
    "-fno-sanitize-recover=all",
    "-g",
    "-O1",
)
#: Columns of a per-tick record (``fw_host_run``): plant position (mm), force command (N),
#: drill depth (mm), motor current (A), hand estimate (N), ``state | faults << 8``.
RECORD_COLUMNS = ("position_mm", "force_cmd_n", "drill_mm", "current_a", "hand_est_n", "state")


class CoreUnavailableError(HapticsInputError):
    """The C core cannot be built or loaded here (no compiler, a failed build)."""


def source_dir() -> Path:
    """The folder holding the firmware's C sources (inside the installed package)."""
    with as_file(files("ctdrill.firmware")) as path:
        return Path(path)


def cache_dir() -> Path:
    """Where built cores are kept (module docstring)."""
    env = os.environ.get("CTDRILL_FIRMWARE_CACHE")
    if env:
        return Path(env)
    venv = Path(sys.prefix) / "var" / "ctdrill-firmware"
    if sys.prefix != sys.base_prefix and os.access(sys.prefix, os.W_OK):
        return venv
    return Path.home() / ".cache" / "ctdrill" / "firmware"


def compiler() -> str | None:
    """The C compiler: ``$CC``, else ``cc`` or ``gcc`` on the PATH (None: none found)."""
    env = os.environ.get("CC")
    if env:
        return shutil.which(env) or env
    return shutil.which("cc") or shutil.which("gcc")


def build_core(precision: Precision = "double", *, sanitize: bool = False) -> Path:
    """Compile the host core (once per sources, flags and compiler) and return its path.

    Raises
    ------
    CoreUnavailableError
        No C compiler, or the build failed (its first error line in the message).
    """
    cc = compiler()
    if cc is None:
        raise CoreUnavailableError(
            "--core c: no C compiler found to build the firmware core (install gcc, e.g. "
            "'apt-get install gcc', or set CC), or run with --core python"
        )
    src = source_dir()
    flags = [*CFLAGS, *(SANITIZE if sanitize else ())]
    if precision == "single":
        flags.append("-DFW_REAL_FLOAT")
    digest = hashlib.sha256()
    for name in (*SOURCES, *HEADERS):
        digest.update(name.encode() + b"\0" + (src / name).read_bytes())
    digest.update(" ".join([cc, *flags]).encode())
    try:
        digest.update(subprocess.run([cc, "--version"], capture_output=True, timeout=30).stdout)
    except (OSError, subprocess.SubprocessError) as exc:
        raise CoreUnavailableError(f"--core c: the C compiler {cc} does not run ({exc})") from exc
    tag = f"{precision}{'-san' if sanitize else ''}-{digest.hexdigest()[:16]}"
    out = cache_dir() / f"libctdrill_fw_{tag}.so"
    if out.exists():
        return out
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=out.parent, suffix=".so.part")
        os.close(fd)
    except OSError as exc:
        raise CoreUnavailableError(
            f"--core c: cannot write the built core to {out.parent} ({exc.strerror}); set "
            "CTDRILL_FIRMWARE_CACHE to a writable folder"
        ) from exc
    cmd = [cc, *flags, "-o", tmp, *(str(src / s) for s in SOURCES), "-lm"]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    except (OSError, subprocess.SubprocessError) as exc:
        os.unlink(tmp)
        raise CoreUnavailableError(f"--core c: the C compiler {cc} failed to run ({exc})") from exc
    if done.returncode != 0:
        os.unlink(tmp)
        first = next((ln for ln in done.stderr.splitlines() if "error" in ln), done.stderr[:200])
        raise CoreUnavailableError(f"--core c: building the firmware core failed: {first}")
    os.replace(tmp, out)
    return out


_LIBS: dict[tuple[str, bool], ctypes.CDLL] = {}


def load_core(precision: Precision = "double", *, sanitize: bool = False) -> ctypes.CDLL:
    """The built core, loaded once per process, its functions typed."""
    key = (precision, sanitize)
    lib = _LIBS.get(key)
    if lib is not None:
        return lib
    path = build_core(precision, sanitize=sanitize)
    try:
        lib = ctypes.CDLL(str(path))
    except OSError as exc:
        raise CoreUnavailableError(f"--core c: cannot load the built core {path} ({exc})") from exc
    _declare(lib)
    _LIBS[key] = lib
    return lib


def _declare(lib: ctypes.CDLL) -> None:
    vp, sz, u32, u64, dbl = (
        ctypes.c_void_p,
        ctypes.c_size_t,
        ctypes.c_uint32,
        ctypes.c_uint64,
        ctypes.c_double,
    )
    buf = ctypes.c_char_p
    sig: dict[str, tuple[object, list[object]]] = {
        "fw_host_new": (vp, [dbl, u32]),
        "fw_host_free": (None, [vp]),
        "fw_host_push_nonce": (None, [vp, u32]),
        "fw_host_nonces_queued": (ctypes.c_uint, [vp]),
        "fw_host_receive": (None, [vp, buf, sz]),
        "fw_host_take": (sz, [vp, vp, sz]),
        "fw_host_pending": (sz, [vp]),
        "fw_host_run": (None, [vp, sz, vp]),
        "fw_host_replay": (None, [vp, vp, sz, vp]),
        "fw_host_ticks": (u64, [vp]),
        "fw_host_overruns": (u32, [vp]),
        "fw_host_set_overruns": (None, [vp, u32]),
        "fw_host_set_device_seq": (None, [vp, u32]),
        "fw_host_frames_rejected": (u32, [vp]),
        "fw_host_session": (u32, [vp]),
        "fw_host_state": (ctypes.c_int, [vp]),
        "fw_host_position_mm": (dbl, [vp]),
        "fw_host_real_is_double": (ctypes.c_int, []),
        "fw_rt_stats_size": (sz, []),
        "fw_host_fe_raised": (ctypes.c_int, []),
        "fw_host_set_defer": (None, [vp, ctypes.c_int]),
        "fw_host_poll": (ctypes.c_uint, [vp, ctypes.c_uint]),
        "fw_host_frames_dropped": (u32, [vp]),
        "fw_host_serve": (ctypes.c_int, [vp, ctypes.c_int, ctypes.c_int64, vp, ctypes.c_int]),
        "fw_crc32c": (u32, [buf, sz]),
        "fw_crc32": (u32, [u32, buf, sz]),
        "fw_cobs_encode": (sz, [buf, sz, vp]),
        "fw_cobs_decode": (ctypes.c_int, [buf, sz, vp, sz]),
        "fw_encode_frame": (sz, [ctypes.c_uint8, u32, u32, u64, buf, sz, vp]),
        "fw_seq_after": (ctypes.c_int, [u32, u32]),
    }
    for name, (res, args) in sig.items():
        fn = getattr(lib, name)
        fn.restype = res
        fn.argtypes = args

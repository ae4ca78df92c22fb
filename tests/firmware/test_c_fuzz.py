"""The C core's frame decoder and state machine under Hypothesis with AddressSanitizer and
UndefinedBehaviorSanitizer (tests/firmware/fuzz_core.py, in a subprocess: the ASan runtime
must be loaded before Python's). A few seconds in ``make test``; ``make fuzz``
(``CTDRILL_FUZZ_EXAMPLES``) runs many more examples."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from ctdrill.haptics.ccore import build_core, compiler

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = int(os.environ.get("CTDRILL_FUZZ_EXAMPLES", "40"))

pytestmark = [pytest.mark.fuzz, pytest.mark.timeout(max(300, EXAMPLES // 2))]


def test_frame_decoder_and_state_machine_under_asan_and_ubsan() -> None:
    cc = compiler()
    assert cc is not None, "gcc is a system package of make test (Makefile SYSTEM_PKGS)"
    runtime = subprocess.run(
        [cc, "-print-file-name=libasan.so"], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert os.path.isabs(runtime) and os.path.exists(runtime), runtime
    for precision in ("double", "single"):
        build_core(precision, sanitize=True)  # type: ignore[arg-type]
    env = {
        **os.environ,
        "LD_PRELOAD": runtime,
        "ASAN_OPTIONS": "detect_leaks=0:halt_on_error=1:abort_on_error=0",
        "UBSAN_OPTIONS": "halt_on_error=1:print_stacktrace=1",
        "PYTHONPATH": str(ROOT),
    }
    done = subprocess.run(
        [sys.executable, "-m", "tests.firmware.fuzz_core", str(EXAMPLES)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=max(280, EXAMPLES // 2),
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-6000:]
    assert "fuzzed: no finding" in done.stdout
    assert "runtime error" not in done.stderr and "AddressSanitizer" not in done.stderr

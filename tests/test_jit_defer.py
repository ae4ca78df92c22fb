"""``ctdrill.jit.defer`` / ``release``: a process that defers numba (the window, until its first
series is drawn) computes the window's first path, checks and readout without importing it, the
same bits as once the kernels are loaded in the background; the kernels then run compiled."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def fingerprint(x: Any) -> Any:
    """Every array's dtype, shape and bytes and every other value's repr, through dataclasses,
    tuples, lists and dicts (two results compared bit for bit)."""
    if isinstance(x, np.ndarray):
        return [str(x.dtype), list(x.shape), x.tobytes().hex()]
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        fields = dataclasses.fields(x)
        return [type(x).__name__, *([f.name, fingerprint(getattr(x, f.name))] for f in fields)]
    if isinstance(x, tuple | list):
        return [fingerprint(v) for v in x]
    if isinstance(x, dict):
        return [[repr(k), fingerprint(v)] for k, v in x.items()]
    return repr(x)


CODE = """
import json, sys
import numpy as np
from ctdrill import jit
from ctdrill.app.gui.readouts import implant_readout
from ctdrill.app.gui.results import compute_path_view
from ctdrill.imaging import load_ct
from ctdrill.imaging.plan.load import load_plan_set
from tests.test_jit_defer import fingerprint

jit.defer()
jit.preload()  # what the window's load asks: nothing while deferred
volume = load_ct("assets/demo/ct")
plans = load_plan_set(["assets/demo/plan.json"])


def numbers():
    view = compute_path_view(volume, plans[0], None, plan_set=plans)
    readout = implant_readout(volume, plans[0], view)
    return fingerprint([view, readout])


first = numbers()
before = {"numba": "numba" in sys.modules, "deferred": jit.deferred(),
          "loaded": [k.name for k in jit.kernels() if k._ready]}
thread = jit.release()
thread.join(120)
after = {"numba": "numba" in sys.modules, "deferred": jit.deferred(),
         "ready": all(k.ready() for k in jit.kernels()), "kernels": len(jit.kernels())}
second = numbers()
print(json.dumps([before, after, first == second]))
"""


def test_deferred_kernels_give_the_first_path_without_numba_and_the_same_bits() -> None:
    env = {k: v for k, v in os.environ.items() if k != "CTDRILL_NO_JIT"}
    out = subprocess.run(
        [sys.executable, "-c", CODE],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    before, after, same = json.loads(out.stdout.strip().splitlines()[-1])
    assert before == {"numba": False, "deferred": True, "loaded": []}
    assert after["numba"] and not after["deferred"] and after["kernels"] > 0
    assert after["ready"], "the warm-up's cache is missing: run make warmup"
    assert same


def test_a_deferral_ends_without_loading_when_asked() -> None:
    code = (
        "import sys\n"
        "from ctdrill import jit\n"
        "jit.defer()\n"
        "assert jit.deferred() and not jit.worth_loading()\n"
        "jit.stop_deferring()\n"
        "assert not jit.deferred() and jit.worth_loading()\n"
        "print('numba' in sys.modules)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "False"

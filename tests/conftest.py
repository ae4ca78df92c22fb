"""Shared fixtures: where the real data lives, and the hypothesis profile."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# One BLAS thread per test process (and its subprocesses), set before NumPy is first imported.
# The tests' many small products (points (N, 3) @ (3, 3)) otherwise wake OpenBLAS's second
# thread, which spins: 46x the CPU of one thread for a 59k-point transform beside other work,
# and with ``-n 2`` each worker would contend with the other's BLAS threads for the 2 cores.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]
#: ``../shared`` beside the repository (DESIGN.md, real CT series, the paper), or the folder
#: ``CTDRILL_SHARED`` names (a checkout elsewhere).
SHARED = Path(os.environ.get("CTDRILL_SHARED") or ROOT.parent / "shared")
SHARED_DATA = SHARED / "data"
ASSETS = ROOT / "assets"

# Subprocesses (``python -m ctdrill.app.cli ...``) import ctdrill from this checkout, whatever
# their working folder and whichever checkout the virtual environment was installed from.
os.environ["PYTHONPATH"] = os.pathsep.join(
    p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p
)

settings.register_profile(
    "ctdrill",
    deadline=None,
    # the same examples on every run and host: a CI verdict never hangs on the draw
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
    max_examples=int(os.environ.get("CTDRILL_HYPOTHESIS_EXAMPLES", "100")),
)
settings.load_profile("ctdrill")


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data``; its absence is a failure, not a skip."""
    assert SHARED_DATA.is_dir(), f"real test data missing: {SHARED_DATA} (clone beside ../shared)"
    return SHARED_DATA


@pytest.fixture(scope="session", autouse=True)
def _itk_agrees_on_every_volume_file() -> object:
    """Every NIfTI, NRRD or MetaImage file any test makes ctdrill accept is read again by
    SimpleITK, independently, and must have the same grid (``tests/imaging/itk_witness.py``)."""
    from tests.imaging.itk_witness import install

    undo = install()
    yield
    undo()


@pytest.fixture(scope="session", autouse=True)
def _ctrl_c_as_from_a_terminal() -> object:
    """Ctrl-C reaches the tests as it reaches a command typed in a terminal: a suite started in
    the background by a non-interactive shell (``make test &``) inherits SIGINT ignored, which
    the processes the Ctrl-C tests start would keep (a command started under ``nohup`` rightly
    ignores it), so Python's own handler is put back for the session."""
    import signal

    old = signal.getsignal(signal.SIGINT)
    if old is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    if old is signal.SIG_IGN:
        signal.signal(signal.SIGINT, old)


#: The window tests' folder: one work unit under ``-n 2 --dist loadscope`` (make test).
GUI_TESTS = "tests/app/gui/"


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object:
    """pytest-xdist's ``--dist loadscope`` (make test runs ``-n 2``) with the window tests as
    one work unit: they run one after another in one worker, so two Qt event loops never
    compete for the display and the cores, while the other worker takes the modules one at a
    time (each module a unit, so its module-scoped fixtures are built once). Other ``--dist``
    modes are xdist's own."""
    if config.getvalue("dist") != "loadscope":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class WindowTestsTogether(LoadScopeScheduling):  # type: ignore[misc]
        def _split_scope(self, nodeid: str) -> str:
            return "gui" if nodeid.startswith(GUI_TESTS) else nodeid.split("::", 1)[0]

    return WindowTestsTogether(config, log)

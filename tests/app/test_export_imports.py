"""A one-plan export as a fresh process imports only what it uses (start-up time, issue 37).

``ctdrill export`` of one plan imports no SciPy module of its own (the sampler gives
``map_coordinates``' bits without ``scipy.ndimage``) and not numba (a one-plan job computes
the kernels' bits without it: :mod:`ctdrill.jit`; a process that loads the kernels gets
``scipy.linalg.cython_blas`` for numba's BLAS check without the ``scipy.linalg`` package),
nor any GUI or 3D toolkit, nor matplotlib: ``force.png`` is drawn with Pillow
(:mod:`ctdrill.app.raster_plot`); nor pydicom, for the demo's uncompressed series.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"
#: Top-level packages a one-plan export (with its plot or without) does not need; pydicom
#: neither for an uncompressed little-endian series (the fast header and pixel readers).
NOT_NEEDED = {"matplotlib", "PySide6", "vtk", "vtkmodules", "pyvista", "pydicom"}
#: SciPy modules the export never uses.
NOT_NEEDED_SCIPY = (
    "scipy.ndimage",
    "scipy.interpolate",
    "scipy.spatial",
    "scipy.optimize",
    "scipy.linalg._",  # the package's own modules (numba's check loads cython_blas alone)
    "scipy._lib._array_api",
)


def _run(code: str) -> str:
    env = {k: v for k, v in os.environ.items() if k != "CTDRILL_NO_JIT"}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    return out.stderr.splitlines()[-1]


@pytest.mark.parametrize("plot", [True, False])
def test_a_one_plan_export_imports_no_heavy_module_it_does_not_use(
    tmp_path: Path, plot: bool
) -> None:
    """Not numba either (a one-plan job, :func:`ctdrill.jit.job`), and its files are byte for
    byte those of the same export in a process that had loaded numba and its kernels."""
    files = ("force.csv", "profile.csv", "summary.json") + (("force.png",) if plot else ())
    outputs = []
    for preload in (False, True):
        out_dir = tmp_path / f"out{int(preload)}"
        argv = ["export", "--ct", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
        argv += ["--out", str(out_dir)] + ([] if plot else ["--no-plot"])
        code = (
            "import json, sys\n"
            "from ctdrill import jit\n"
            + ("from ctdrill.app.search.warmup import search_kernels\n" if preload else "")
            + ("assert all(k.ready() for k in search_kernels())\n" if preload else "")
            + "from ctdrill.app.cli import main\n"
            f"code = main({argv!r})\n"
            "sys.stderr.write('\\n' + json.dumps([code, sorted(sys.modules)]))\n"
        )
        exit_code, names = json.loads(_run(code))
        assert exit_code == 0
        assert (out_dir / "force.png").is_file() == plot
        outputs.append({name: (out_dir / name).read_bytes() for name in files})
        if preload:
            assert "numba" in names
            continue
        assert "ctdrill.imaging.dicom.pixels" in names  # the series was read in this process
        assert sorted(n for n in names if n.split(".")[0] in NOT_NEEDED) == []
        assert sorted(n for n in names if n.startswith(NOT_NEEDED_SCIPY)) == []
        assert "numba" not in names and "scipy.linalg" not in names
    assert outputs[0] == outputs[1]


def test_loading_the_kernels_leaves_the_scipy_linalg_package_out() -> None:
    """numba's BLAS check gets ``scipy.linalg.cython_blas`` alone; ``scipy.linalg`` imported
    afterwards works and holds the same module."""
    code = (
        "import json, sys\n"
        "from ctdrill.app.search.warmup import search_kernels\n"
        "ready = all(k.ready() for k in search_kernels())\n"
        "names = sorted(sys.modules)\n"
        "import scipy.linalg, scipy.linalg.cython_blas as blas\n"
        "assert scipy.linalg.cython_blas is blas\n"
        "assert scipy.linalg.solve([[2.0]], [4.0]).tolist() == [2.0]\n"
        "sys.stderr.write('\\n' + json.dumps([ready, names]))\n"
    )
    ready, names = json.loads(_run(code))
    assert ready and "numba.np.arraymath" in names
    assert sorted(n for n in names if n.startswith(NOT_NEEDED_SCIPY)) == []
    assert "scipy.linalg" not in names and "scipy.linalg.cython_blas" not in names

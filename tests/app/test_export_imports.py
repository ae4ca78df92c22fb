"""A one-plan export as a fresh process imports only what it uses (start-up time, issue 37).

``ctdrill export`` of one plan imports no SciPy module of its own (the sampler gives
``map_coordinates``' bits without ``scipy.ndimage``; numba's BLAS check gets
``scipy.linalg.cython_blas`` without the ``scipy.linalg`` package, and every job takes the
kernels: :mod:`ctdrill.jit`),
nor any GUI or 3D toolkit, nor matplotlib: ``force.png`` is drawn with Pillow
(:mod:`ctdrill.app.raster_plot`).
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
#: Top-level packages a one-plan export (with its plot or without) does not need.
NOT_NEEDED = {"matplotlib", "PySide6", "vtk", "vtkmodules", "pyvista"}
#: SciPy modules the export never uses.
NOT_NEEDED_SCIPY = (
    "scipy.ndimage",
    "scipy.interpolate",
    "scipy.spatial",
    "scipy.optimize",
    "scipy.linalg._",  # the package's own modules (numba's check loads cython_blas alone)
    "scipy._lib._array_api",
)


@pytest.mark.parametrize("plot", [True, False])
def test_a_one_plan_export_imports_no_heavy_module_it_does_not_use(
    tmp_path: Path, plot: bool
) -> None:
    argv = ["export", "--ct", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    argv += ["--out", str(tmp_path / "out")] + ([] if plot else ["--no-plot"])
    code = (
        "import json, sys\n"
        "from ctdrill.app.cli import main\n"
        f"code = main({argv!r})\n"
        "names = sorted(sys.modules)\n"
        "import scipy.linalg, scipy.linalg.cython_blas as blas\n"  # still importable, once
        "assert scipy.linalg.cython_blas is blas\n"
        "assert scipy.linalg.solve([[2.0]], [4.0]).tolist() == [2.0]\n"
        "sys.stderr.write('\\n' + json.dumps([code, names]))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "CTDRILL_NO_JIT"}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    exit_code, names = json.loads(out.stderr.splitlines()[-1])
    assert exit_code == 0
    assert (tmp_path / "out" / "summary.json").is_file()
    assert (tmp_path / "out" / "force.png").is_file() == plot
    assert "pydicom" in names  # the series was read in this process
    assert sorted(n for n in names if n.split(".")[0] in NOT_NEEDED) == []
    assert sorted(n for n in names if n.startswith(NOT_NEEDED_SCIPY)) == []
    assert "scipy.linalg" not in names and "scipy.linalg.cython_blas" not in names
    if "numba" in names:  # the kernels were loaded: numba's BLAS check ran
        assert "numba.np.arraymath" in names

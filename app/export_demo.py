"""The bundled demo: export of the mandible phantom (``assets/demo``) into a fresh folder."""

from __future__ import annotations

from pathlib import Path

from ctdrill.app.errors import AppInputError
from ctdrill.app.export_run import export_case
from ctdrill.resources import asset

#: ``assets/demo`` in the installed package: the phantom CT series (``ct/``) and its plan.
DEMO_DIR: Path = asset("demo")
#: File that marks a folder as written by a previous demo (so it may be overwritten).
DEMO_MARKER = ".ctdrill-demo"


def run_demo(out_dir: Path, *, demo_dir: Path = DEMO_DIR) -> list[Path]:
    """Export the demo case into ``out_dir`` and return the written files.

    Refuses a non-empty ``out_dir`` unless a previous demo made it (it holds
    :data:`DEMO_MARKER`); that one is replaced whole (marker included).
    """
    out_dir = Path(out_dir)
    if out_dir.exists():
        if not out_dir.is_dir():
            raise AppInputError(f"--out {out_dir}: exists and is not a folder")
        if any(out_dir.iterdir()) and not (out_dir / DEMO_MARKER).is_file():
            raise AppInputError(
                f"--out {out_dir}: folder is not empty and was not made by 'ctdrill demo'; "
                "choose a new or empty folder"
            )
    marker = {DEMO_MARKER: "written by 'ctdrill demo'; the demo may overwrite this folder\n"}
    written = export_case(demo_dir / "ct", [demo_dir / "plan.json"], out_dir, extra_files=marker)
    return [p for p in written if p.name != DEMO_MARKER]

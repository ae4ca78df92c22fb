"""Package data: the calibration sets and the demo case, inside the installed package.

Found through :mod:`importlib.resources`, so they are there in a wheel, an editable install and
a source checkout alike.
"""

from __future__ import annotations

from importlib.resources import as_file, files
from pathlib import Path


def asset(*parts: str) -> Path:
    """The file system path of ``assets/<parts...>`` inside the installed package.

    Parameters
    ----------
    *parts : path components below ``assets/`` (``"calibration"``, ``"demo"``, ...).

    Returns
    -------
    Path : an existing or missing path; callers check existence and report it.
    """
    ref = files("ctdrill.assets").joinpath(*parts)
    # A wheel installs as plain files, so as_file yields the path itself (no temporary copy).
    with as_file(ref) as path:
        return Path(path)

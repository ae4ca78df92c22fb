"""The optional parameter covariance of a calibration set (``"covariance"`` in its JSON).

::

    "covariance": {"parameters": ["a0.b0", "a0.n", "a0.ke"],
                   "matrix": [[...], [...], [...]]}

``matrix[i][j]`` is the covariance of ``parameters[i]`` and ``parameters[j]`` in the units of
the parameters (``b0`` in log10 N, ``n`` dimensionless, ``ke`` per (mm/s)). A set without it
states no uncertainty (sets written before it stay valid and load unchanged); a set with it must
give a finite, symmetric, positive semi-definite matrix of the right size, otherwise the set is
refused naming the field. :mod:`ctdrill.model.band` propagates it to a force band.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.model.errors import CalibrationError

#: Parameters a covariance may name: those of the DC law A0 = 10^b0 C'^n (1 + Ke v).
COVARIANCE_PARAMETERS: tuple[str, ...] = ("a0.b0", "a0.n", "a0.ke")
#: Relative tolerance of the symmetry check, against sqrt(C_ii C_jj).
SYMMETRY_RTOL: float = 1e-9
#: Eigenvalues down to -PSD_RTOL x the largest are rounding, not a negative variance.
PSD_RTOL: float = 1e-9


@dataclass(frozen=True)
class ParameterCovariance:
    """Covariance of some of a set's parameters.

    Attributes
    ----------
    parameters : tuple of str
        Names from :data:`COVARIANCE_PARAMETERS`, distinct.
    matrix : tuple of tuple of float
        Symmetric positive semi-definite, ``len(parameters)`` square.
    """

    parameters: tuple[str, ...]
    matrix: tuple[tuple[float, ...], ...]

    def array(self) -> np.ndarray:
        """The matrix as a float64 array, shape (P, P)."""
        return np.array(self.matrix, dtype=np.float64).reshape(
            len(self.parameters), len(self.parameters)
        )

    def stderr(self, name: str) -> float:
        """Standard error of ``name`` (0 when the covariance does not list it)."""
        if name not in self.parameters:
            return 0.0
        i = self.parameters.index(name)
        return math.sqrt(max(self.matrix[i][i], 0.0))

    def to_json(self) -> dict[str, Any]:
        """The ``"covariance"`` object of the set's JSON."""
        return {"parameters": list(self.parameters), "matrix": [list(r) for r in self.matrix]}


def _fail(src: Path, field: str, what: str) -> CalibrationError:
    return CalibrationError(f"calibration file {src}: field {field} {what}")


def parse_covariance(data: Mapping[str, Any], src: Path) -> ParameterCovariance | None:
    """The set's ``covariance`` (None when absent), validated.

    Raises
    ------
    CalibrationError
        Not an object, unknown or repeated parameter names, a matrix of the wrong size, a
        non-finite entry, not symmetric or not positive semi-definite: the message names the
        field (``covariance.matrix[1][0]`` ...) and what to do.
    """
    if "covariance" not in data:
        return None
    cov = data["covariance"]
    if not isinstance(cov, Mapping):
        raise _fail(src, "covariance", "must be an object {parameters, matrix} (or leave it out)")
    names = cov.get("parameters")
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise _fail(
            src,
            "covariance.parameters",
            f"must be a non-empty list of names from {list(COVARIANCE_PARAMETERS)}",
        )
    for i, name in enumerate(names):
        if name not in COVARIANCE_PARAMETERS:
            raise _fail(
                src,
                f"covariance.parameters[{i}]",
                f"names {name[:40]!r}, not one of {list(COVARIANCE_PARAMETERS)}",
            )
    if len(set(names)) != len(names):
        raise _fail(src, "covariance.parameters", f"repeats a name: {names}; give each once")
    p = len(names)
    rows = cov.get("matrix")
    if not isinstance(rows, list) or len(rows) != p:
        raise _fail(
            src,
            "covariance.matrix",
            f"must be a {p} x {p} list of rows (one per parameter), "
            f"got {len(rows) if isinstance(rows, list) else type(rows).__name__} rows",
        )
    values: list[list[float]] = []
    for i, row in enumerate(rows):
        if not isinstance(row, list) or len(row) != p:
            raise _fail(src, f"covariance.matrix[{i}]", f"must be a list of {p} numbers")
        out_row = []
        for j, v in enumerate(row):
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise _fail(src, f"covariance.matrix[{i}][{j}]", "must be a number")
            try:
                f = float(v)
            except OverflowError:
                f = math.inf
            if not math.isfinite(f):
                raise _fail(src, f"covariance.matrix[{i}][{j}]", "must be finite")
            out_row.append(f)
        values.append(out_row)
    m = np.array(values, dtype=np.float64)
    for i in range(p):
        if m[i, i] < 0.0:
            raise _fail(
                src,
                f"covariance.matrix[{i}][{i}]",
                f"is a variance and must be >= 0, got {m[i, i]}",
            )
    scale = np.sqrt(np.outer(np.diag(m), np.diag(m)))
    for i in range(p):
        for j in range(i + 1, p):
            if abs(m[i, j] - m[j, i]) > SYMMETRY_RTOL * max(float(scale[i, j]), 1e-300):
                raise _fail(
                    src,
                    f"covariance.matrix[{i}][{j}]",
                    f"({m[i, j]:g}) differs from covariance.matrix[{j}][{i}] ({m[j, i]:g}): "
                    "a covariance matrix is symmetric",
                )
    eig = np.linalg.eigvalsh(m)
    if eig[0] < -PSD_RTOL * max(float(eig[-1]), 0.0) or (eig[-1] <= 0.0 and eig[0] < 0.0):
        raise _fail(
            src,
            "covariance.matrix",
            f"is not positive semi-definite (smallest eigenvalue {eig[0]:.3g}): it implies a "
            "negative variance; recompute it from the fit",
        )
    return ParameterCovariance(
        parameters=tuple(names), matrix=tuple(tuple(float(v) for v in r) for r in values)
    )

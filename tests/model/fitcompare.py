"""Compare a refitted calibration document with the committed one, to the fit's own precision.

The least-squares fit is reproducible to its convergence, not to the last bit: BLAS kernels
differ between hosts (OpenBLAS picks Haswell, SkylakeX or Zen code paths), so a covariance
entry near zero (it should be zero: the parameters it couples are fitted on separate data)
comes out as +-3e-9 on one host and the other sign on another. Every number is therefore
compared on the scale the computation gives it:

- a covariance entry ``C_ij`` to ``REL * sqrt(C_ii C_jj)`` (a correlation of 1e-6);
- a fitted value to ``REL`` times its own standard error;
- a systematic standard error (``provenance.stderr_systematic``: how far a parameter moves
  when an assumption moves) to ``REL`` times that parameter's statistical standard error;
- everything else (standard errors, residuals, conversions) to ``REL`` relative.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

#: The fit's convergence: relative step tolerance of the solver, with a margin.
REL = 1e-6


def _same(a: Any, b: Any, where: str, scale: float | None = None) -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), where
        for k in a:
            _same(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, float | int) and not isinstance(a, bool):
        if scale is None:
            assert b == pytest.approx(a, rel=REL, abs=0.0), where
        else:
            assert abs(b - a) <= REL * scale, f"{where}: {a!r} vs {b!r} (scale {scale:.3g})"
    else:
        assert a == b, where


def assert_same_fit(fitted: dict[str, Any], committed: dict[str, Any]) -> None:
    """``fitted`` equals ``committed`` to the fit's precision (module docstring)."""
    assert fitted.keys() == committed.keys()
    cov = committed.get("covariance")
    stderr = {k: v["stderr"] for k, v in committed.get("fit", {}).items()}
    for key in committed:
        if key == "covariance" and cov is not None:
            names = cov["parameters"]
            assert fitted[key]["parameters"] == names
            m_a, m_b = fitted[key]["matrix"], cov["matrix"]
            assert len(m_a) == len(m_b) == len(names)
            for i in range(len(names)):
                for j in range(len(names)):
                    scale = math.sqrt(m_b[i][i] * m_b[j][j])
                    _same(m_a[i][j], m_b[i][j], f"covariance.matrix[{i}][{j}]", scale)
        elif key == "fit":
            for name, entry in committed["fit"].items():
                _same(fitted["fit"][name]["value"], entry["value"], f"fit.{name}", stderr[name])
                rest_a = {k: v for k, v in fitted["fit"][name].items() if k != "value"}
                rest_b = {k: v for k, v in entry.items() if k != "value"}
                _same(rest_a, rest_b, f"fit.{name}")
        elif key == "a0":
            for name, value in committed["a0"].items():
                err = stderr.get(f"a0.{name}")
                _same(fitted["a0"][name], value, f"a0.{name}", err)
        elif key == "provenance":
            prov_a, prov_b = dict(fitted[key]), dict(committed[key])
            sys_a = prov_a.pop("stderr_systematic", None)
            sys_b = prov_b.pop("stderr_systematic", None)
            _same(prov_a, prov_b, key)
            assert (sys_a is None) == (sys_b is None)
            if sys_b is not None:
                assert sys_a.keys() == sys_b.keys()
                for source, entry in sys_b.items():
                    assert sys_a[source].keys() == entry.keys()
                    for name, value in entry.items():
                        err = stderr[f"a0.{name}"]
                        _same(sys_a[source][name], value, f"{key}.{source}.{name}", err)
        else:
            _same(fitted[key], committed[key], key)

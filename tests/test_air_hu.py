"""Air is -1000 HU in one place, :data:`ctdrill.hu.AIR_HU`; imaging and model agree on it.

Before issue 13 the value was a literal in six places (sampling, the volume, the phantom, grey
calibration, the layered model, the GUI) and the model's ``C' = HU + 1000`` in three more.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from ctdrill.hu import AIR_HU
from ctdrill.imaging.phantom.mandible import make_mandible_phantom
from ctdrill.imaging.volume import CTVolume, SeriesInfo
from ctdrill.model.calibration import load_calibration
from ctdrill.model.force import c_prime
from ctdrill.model.profile import ProfileInputError, build_profile

ROOT = Path(__file__).resolve().parents[1]
ROOMS = ("app", "imaging", "model", "haptics")
#: Parameters that mean "the CT number of air" and must default to AIR_HU.
AIR_PARAMETERS = {"outside_hu", "air_hu"}


def _is_1000(node: ast.AST) -> bool:
    return isinstance(node, ast.Constant) and node.value in (1000, 1000.0)


def _offenders(path: Path) -> list[str]:
    """Air as a literal in ``path``: ``-1000``, ``x +/- 1000``, an air default other than AIR_HU."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.UnaryOp)
            and isinstance(node.op, ast.USub)
            and _is_1000(node.operand)
        ):
            found.append(f"{node.lineno}: -1000")
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add | ast.Sub):
            if _is_1000(node.left) or _is_1000(node.right):
                found.append(f"{node.lineno}: {ast.unparse(node)}")
        elif isinstance(node, ast.FunctionDef):
            args = node.args
            positional = args.posonlyargs + args.args
            pairs = list(
                zip(positional[len(positional) - len(args.defaults) :], args.defaults, strict=True)
            )
            pairs += [
                (a, d)
                for a, d in zip(args.kwonlyargs, args.kw_defaults, strict=True)
                if d is not None
            ]
            for arg, default in pairs:
                if arg.arg in AIR_PARAMETERS and ast.unparse(default) != "AIR_HU":
                    found.append(f"{node.lineno}: {arg.arg}={ast.unparse(default)}")
    return found


def test_no_room_writes_air_as_a_literal() -> None:
    found = {
        str(path.relative_to(ROOT)): _offenders(path)
        for room in ROOMS
        for path in sorted((ROOT / room).rglob("*.py"))
    }
    assert {k: v for k, v in found.items() if v} == {}


def test_the_scan_sees_each_form(tmp_path: Path) -> None:
    sample = tmp_path / "bad.py"
    sample.write_text(
        "def f(x, outside_hu=-1000.0, *, air_hu: float = AIR_HU):\n"
        "    return x + 1000.0, -1000, x * 1000\n"
    )
    assert sorted(_offenders(sample)) == [
        "1: -1000",
        "1: outside_hu=-1000.0",
        "2: -1000",
        "2: x + 1000.0",
    ]


def test_outside_the_volume_is_air_where_the_model_has_no_attenuation() -> None:
    vol = CTVolume(
        hu=np.full((2, 2, 2), 500, dtype=np.int16),
        affine_lps=np.eye(4),
        valid=None,
        info=SeriesInfo(series_uid="1.2.3"),
    )
    outside = vol.sample(np.array([[50.0, 50.0, 50.0], [0.5, 0.5, 0.5]]))
    assert outside[0] == AIR_HU
    assert outside[1] == pytest.approx(500.0)
    # The model's C' = HU + 1000 is attenuation relative to air: exactly 0 for the value
    # imaging samples outside the volume.
    assert c_prime(outside[0]) == 0.0
    assert c_prime(0.0) == -AIR_HU


def test_phantom_air_is_air_hu() -> None:
    phantom = make_mandible_phantom(misch="D4", spacing_mm=1.0)
    assert float(phantom.hu.min()) == AIR_HU  # the corners of the field of view are air


def test_the_model_names_air_in_its_refusal() -> None:
    cal = load_calibration("bone-illustrative")
    hu = np.full((3, 2, 4), np.nan)
    with pytest.raises(ProfileInputError, match=f"finite HU \\({AIR_HU:g}\\)"):
        build_profile(hu, np.full(2, 0.5), np.linspace(0, 1, 3), cal, blades=2, rpm=900)

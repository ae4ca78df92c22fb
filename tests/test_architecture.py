"""The import direction of DESIGN.md section 3, checked statically and at run time."""

from __future__ import annotations

import ast
import importlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("app", "imaging", "model", "haptics")
GUI_MODULES = ("PySide6", "vtk", "vtkmodules", "pyvista", "pyvistaqt", "matplotlib")

#: package -> first-party packages it must not import
FORBIDDEN_FIRST_PARTY = {
    "imaging": {"model", "haptics", "app"},
    "model": {"imaging", "haptics", "app"},
    "haptics": {"imaging", "app"},
    "app": set(),
}


def _root(module: str) -> str:
    """``ctdrill.imaging.x`` -> ``imaging`` (a first-party room); ``numpy.linalg`` -> ``numpy``."""
    parts = module.split(".")
    if parts[0] == "ctdrill" and len(parts) > 1:
        return parts[1]
    return parts[0]


def _imported_roots(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    roots: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            roots.update(_root(alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            roots.add(_root(node.module))
    return roots


def _sources(package: str) -> list[Path]:
    return sorted((ROOT / package).rglob("*.py"))


@pytest.mark.parametrize("package", PACKAGES)
def test_first_party_import_direction(package: str) -> None:
    offenders = {
        str(path.relative_to(ROOT)): sorted(_imported_roots(path) & FORBIDDEN_FIRST_PARTY[package])
        for path in _sources(package)
    }
    assert {k: v for k, v in offenders.items() if v} == {}


@pytest.mark.parametrize("package", ["imaging", "model", "haptics"])
def test_only_app_imports_gui_and_render_modules(package: str) -> None:
    offenders = {
        str(path.relative_to(ROOT)): sorted(_imported_roots(path) & set(GUI_MODULES))
        for path in _sources(package)
    }
    assert {k: v for k, v in offenders.items() if v} == {}


def test_importing_core_packages_loads_no_gui_module() -> None:
    code = (
        "import json, sys, importlib, pkgutil\n"
        "for pkg in ('ctdrill.imaging', 'ctdrill.model', 'ctdrill.haptics'):\n"
        "    mod = importlib.import_module(pkg)\n"
        "    for info in pkgutil.walk_packages(mod.__path__, pkg + '.'):\n"
        "        importlib.import_module(info.name)\n"
        "print(json.dumps(sorted(m for m in sys.modules)))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    loaded = json.loads(out.stdout)
    bad = [m for m in loaded if m.split(".")[0] in GUI_MODULES]
    assert bad == []
    assert {"ctdrill.imaging", "ctdrill.model", "ctdrill.haptics"} <= set(loaded)
    assert not {"app", "imaging", "model", "haptics"} & set(loaded), "no bare top-level names"


def test_the_check_itself_sees_a_forbidden_import(tmp_path: Path) -> None:
    sample = tmp_path / "bad.py"
    sample.write_text("import numpy\nfrom ctdrill.model.force import x\nimport vtkmodules.all\n")
    assert _imported_roots(sample) == {"numpy", "model", "vtkmodules"}


def _type_checking_imports(init: Path) -> dict[str, str]:
    """name -> module of the ``from M import N`` lines under ``if TYPE_CHECKING:`` in ``init``."""
    tree = ast.parse(init.read_text(encoding="utf-8"), filename=str(init))
    found: dict[str, str] = {}
    for node in tree.body:
        if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING":
            for stmt in node.body:
                assert isinstance(stmt, ast.ImportFrom) and stmt.module, ast.unparse(stmt)
                found.update({alias.name: stmt.module for alias in stmt.names})
    return found


@pytest.mark.parametrize("package", ["imaging", "model", "haptics"])
def test_lazy_reexports_agree_with_their_typing_imports_and_resolve(package: str) -> None:
    mod = importlib.import_module(f"ctdrill.{package}")
    exports: dict[str, str] = mod._EXPORTS
    assert _type_checking_imports(ROOT / package / "__init__.py") == exports
    assert sorted(mod.__all__) == sorted(exports)
    for name, module in exports.items():
        assert getattr(mod, name) is getattr(importlib.import_module(module), name), name
    assert set(exports) <= set(dir(mod))
    with pytest.raises(AttributeError, match="no_such_name"):
        _ = mod.no_such_name


def test_importing_a_package_or_its_errors_loads_nothing_heavy() -> None:
    code = (
        "import json, sys\n"
        "import ctdrill.imaging, ctdrill.model, ctdrill.haptics\n"
        "import ctdrill.imaging.errors, ctdrill.model.errors, ctdrill.haptics.errors\n"
        "print(json.dumps(sorted(sys.modules)))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    loaded = json.loads(out.stdout)
    assert [m for m in loaded if m.split(".")[0] in {"numpy", "scipy", "pydicom", "serial"}] == []
    assert sorted(m for m in loaded if m.startswith("ctdrill.")) == [
        "ctdrill.haptics",
        "ctdrill.haptics.errors",
        "ctdrill.imaging",
        "ctdrill.imaging.errors",
        "ctdrill.lazy",
        "ctdrill.model",
        "ctdrill.model.errors",
    ]

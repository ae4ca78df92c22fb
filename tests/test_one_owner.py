"""House rule 2, one owner per rule: the rules most dangerous to spell twice are written once.

The scan reads every first-party module's syntax tree for a number equal to a rule's value
*given to a name that says what it is*: an assignment (``margin_mm = 2.0``), a parameter
default (``iso_hu: float = 300.0``), a keyword argument (``dt_s=1e-4``) or a comparison
(``hu >= 150``). A number in a docstring, a message or an unrelated name is not read, so the
scan raises no false alarm on today's tree: it finds each rule's owner and nothing else.
"""

from __future__ import annotations

import ast
import functools
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from ctdrill.haptics.physics import HAND_MAX_FEED_MM_S
from ctdrill.haptics.renderer import CONTINUOUS_FORCE_N, PEAK_FORCE_N
from ctdrill.haptics.tick import TICK_HZ, TICK_S
from ctdrill.imaging.bounds import MAX_COORDINATE_MM
from ctdrill.imaging.display import BONE_SURFACE_HU
from ctdrill.imaging.misch import MISCH_BANDS_HU
from ctdrill.imaging.plan.clinical import CLINICAL_MARGIN_MM
from ctdrill.imaging.plan.implants import MIN_IMPLANT_DISTANCE_MM
from ctdrill.imaging.plan.types import DEFAULT_FEED_MM_S
from ctdrill.imaging.stack import GAP_FACTOR
from ctdrill.model.cutting import MASTER_MASS_KG

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("app", "engine", "imaging", "model", "haptics", "ctdrill")


@dataclass(frozen=True)
class Rule:
    """A rule's values, the names that would re-spell it, and where it is defined (the module
    whose assignments may hold the value; every other module must import it)."""

    name: str
    values: tuple[float, ...]
    names: str  # regular expression on the lower-case name the number is given to
    owner: str  # path of the owning module, relative to the repository


_BAND_EDGES = tuple(sorted({e for _, lo, hi in MISCH_BANDS_HU for e in (lo, hi) if abs(e) < 1e9}))

RULES = (
    Rule("clinical margin", (CLINICAL_MARGIN_MM,), r"margin", "imaging/plan/clinical.py"),
    Rule(
        "Misch band edges",
        _BAND_EDGES,
        r"(^|_)hu($|_)|bone|gate|cortical|misch|density",
        "imaging/misch.py",
    ),
    Rule("bone surface", (BONE_SURFACE_HU,), r"iso|surface", "imaging/display.py"),
    Rule("control tick", (TICK_S, float(TICK_HZ)), r"(^|_)dt|tick|_hz$|period", "haptics/tick.py"),
    Rule(
        "device force limits",
        (PEAK_FORCE_N, CONTINUOUS_FORCE_N),
        r"(^|_)(force|hand|peak|continuous)|_n$",
        "haptics/renderer.py",
    ),
    Rule("hand feed bound", (HAND_MAX_FEED_MM_S,), r"hand.*feed|feed.*hand", "haptics/physics.py"),
    Rule("slice-gap factor", (GAP_FACTOR,), r"gap", "imaging/stack.py"),
    Rule("implant gap", (MIN_IMPLANT_DISTANCE_MM,), r"implant|between", "imaging/plan/implants.py"),
    Rule("master mass", (MASTER_MASS_KG,), r"mass", "model/cutting.py"),
    Rule("default feed", (DEFAULT_FEED_MM_S,), r"feed", "imaging/plan/types.py"),
    Rule("coordinate bound", (MAX_COORDINATE_MM,), r"coord|world|lps|extent", "imaging/bounds.py"),
)


def _number(node: ast.AST) -> float | None:
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        inner = _number(node.operand)
        return None if inner is None else -inner
    if (
        isinstance(node, ast.Constant)
        and isinstance(node.value, int | float)
        and not isinstance(node.value, bool)
    ):
        return float(node.value)
    return None


def _named_numbers(tree: ast.AST) -> Iterator[tuple[str, float, int]]:
    """``(name, number, line)`` for each number given to a name (see the module docstring)."""
    pairs: list[tuple[str, ast.AST]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign | ast.AnnAssign) and node.value is not None:
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                if isinstance(t, ast.Name | ast.Attribute):
                    pairs.append((t.id if isinstance(t, ast.Name) else t.attr, node.value))
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
            a = node.args
            positional = a.posonlyargs + a.args
            pairs += [
                (arg.arg, d)
                for arg, d in zip(
                    positional[len(positional) - len(a.defaults) :], a.defaults, strict=True
                )
            ]
            pairs += [(arg.arg, d) for arg, d in zip(a.kwonlyargs, a.kw_defaults, strict=True) if d]
        elif isinstance(node, ast.keyword) and node.arg:
            pairs.append((node.arg, node.value))
        elif isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            named = [ast.unparse(s) for s in sides if isinstance(s, ast.Name | ast.Attribute)]
            pairs += [(n, s) for s in sides for n in named]
    for name, value in pairs:
        x = _number(value)
        if x is not None:
            yield name.lower(), x, value.lineno


@functools.cache
def _numbers_in(source: str) -> tuple[tuple[str, float, int], ...]:
    return tuple(_named_numbers(ast.parse(source)))


def _respellings(rule: Rule, source: str) -> list[tuple[str, int]]:
    pattern = re.compile(rule.names)
    return [
        (name, line)
        for name, x, line in _numbers_in(source)
        if abs(x) in rule.values and pattern.search(name)
    ]


@functools.cache
def _sources() -> tuple[tuple[str, str], ...]:
    """``(path relative to the repository, text)`` of every first-party module."""
    paths = sorted(p for package in PACKAGES for p in (ROOT / package).rglob("*.py"))
    return tuple((str(p.relative_to(ROOT)), p.read_text(encoding="utf-8")) for p in paths)


@pytest.mark.parametrize("rule", RULES, ids=lambda r: r.name)
def test_a_rule_is_spelled_only_by_its_owner(rule: Rule) -> None:
    found = {
        f"{path}:{line} {name}"
        for path, text in _sources()
        if path != rule.owner
        for name, line in _respellings(rule, text)
    }
    assert found == set(), f"{rule.name}: import it from {rule.owner}"


@pytest.mark.parametrize(
    "rule", [r for r in RULES if r.name != "Misch band edges"], ids=lambda r: r.name
)
def test_the_scan_finds_each_owner(rule: Rule) -> None:
    # the owner's own definition is a named number: the scan would see a copy of it
    assert _respellings(rule, (ROOT / rule.owner).read_text(encoding="utf-8"))


def test_the_scan_sees_the_usual_respellings_and_ignores_the_rest() -> None:
    sample = (
        "from dataclasses import dataclass\n"
        "MARGIN_MM = 2.0\n"
        "def surface(volume, iso_hu: float = 300.0, *, step_mm=2.0): ...\n"
        "def bone(hu):\n"
        "    return hu >= 150.0, surface(None, iso_hu=300)\n"
        "class Loop:\n"
        "    dt_s: float = 1e-4\n"
        "    hand_max_n = -78.0\n"
        "def text():\n"
        "    return 'a margin of 2.0 mm', 2.0\n"
    )
    by_rule = {r.name: _respellings(r, sample) for r in RULES}
    assert by_rule["clinical margin"] == [("margin_mm", 2)]
    assert by_rule["bone surface"] == [("iso_hu", 3), ("iso_hu", 5)]
    assert by_rule["Misch band edges"] == [("hu", 5)]
    assert by_rule["control tick"] == [("dt_s", 7)]
    assert by_rule["device force limits"] == [("hand_max_n", 8)]
    assert sum(map(len, by_rule.values())) == 6

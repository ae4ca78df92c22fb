"""docs/model.md's A0/B1/B2 tables are the code's numbers (regenerate them if this fails)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ctdrill.model import a0_n, bk_n, gate, load_calibration
from ctdrill.model.force import out_of_range

DOC = Path(__file__).resolve().parents[2] / "docs" / "model.md"


def _rows(set_name: str) -> list[list[str]]:
    text = DOC.read_text(encoding="utf-8")
    start = text.index(f"`{set_name}` (C' range")
    block = text[start:].split("\n\n")[1]
    rows = [line.strip("|").split("|") for line in block.splitlines()[2:]]
    return [[c.strip() for c in row] for row in rows]


@pytest.mark.parametrize("set_name", ["pine-wood-paper", "bone-illustrative", "bone-literature"])
def test_law_tables_match_the_code(set_name: str) -> None:
    cal = load_calibration(set_name)
    rows = _rows(set_name)
    assert len(rows) >= 10
    for hu_cell, cp, g, a0_0, a0_4, b1, b2, clipped in rows:
        hu = float(re.match(r"-?\d+", hu_cell).group())  # type: ignore[union-attr]
        assert float(cp) == hu + 1000
        assert float(g) == pytest.approx(float(gate(hu, cal)), abs=0.005)
        assert float(a0_0) == pytest.approx(float(a0_n(hu, 0.0, cal)), abs=5e-4)
        assert float(a0_4) == pytest.approx(float(a0_n(hu, 0.4, cal)), abs=5e-4)
        bk = bk_n(hu, cal)
        assert float(b1) == pytest.approx(float(bk[0]), abs=5e-5)
        assert float(b2) == pytest.approx(float(bk[1]), abs=5e-5)
        assert (clipped == "yes") == bool(out_of_range(hu, cal))

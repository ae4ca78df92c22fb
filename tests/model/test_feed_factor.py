"""The feed factor ``1 + Ke v`` has one owner (``model.force``): every path that applies it agrees.

Before issue 13 ``force_n`` and ``force_series_n`` capped the feed at ``MAX_FEED_MM_S`` while the
export plot and the GUI's force curve computed ``S0 (1 + Ke v)`` without the cap, so a plan
with a feed above it drew a mean force that ``force.csv`` never reached.
"""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from ctdrill.model.cutting import cut_step, steady_feed_mm_s
from ctdrill.model.force import (
    MAX_FEED_MM_S,
    feed_at_factor_mm_s,
    feed_factor,
    feed_factor_scalar,
)
from ctdrill.model.profile import Profile, force_n, force_series_n

KE = 0.25
#: Feeds across every branch: retraction, NaN, zero, the paper's range, the cap and beyond.
FEEDS = (-5.0, math.nan, 0.0, 0.4, 2.0, MAX_FEED_MM_S - 0.1, MAX_FEED_MM_S, 75.0, 1e300)


def _expected(v: float) -> float:
    """The rule written out: 1 + Ke * clip(v, 0, MAX_FEED_MM_S), NaN as no feed."""
    v = 0.0 if math.isnan(v) else min(max(v, 0.0), MAX_FEED_MM_S)
    return 1.0 + KE * v


def _profile() -> Profile:
    depth = np.linspace(0.0, 4.0, 5)
    s0 = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    return Profile(
        depth_mm=depth,
        s0_n=s0,
        sk_n=np.zeros((0, 5)),
        freqs_hz=np.zeros(0),
        s_t=np.ones(5),
        hu_mean=np.zeros(5),
        ke_per_mm_s=KE,
        n_clipped=0,
        n_samples=5,
        calibration="test",
    )


@pytest.mark.parametrize("feed", FEEDS)
def test_every_path_applies_the_same_feed_factor(feed: float) -> None:
    want = _expected(feed)
    assert feed_factor(feed, ke_per_mm_s=KE) == pytest.approx(want, rel=1e-15)
    assert feed_factor_scalar(feed, KE) == pytest.approx(want, rel=1e-15)
    prof = _profile()
    # S0 = 2 N at depth 2 mm; no harmonics, so the force is S0 times the factor.
    assert force_n(prof, 2.0, feed, 0.0) == pytest.approx(2.0 * want, rel=1e-15)
    series = force_series_n(prof, [2.0, 3.0], feed, [0.0, 0.0])
    np.testing.assert_allclose(series, [2.0 * want, 3.0 * want], rtol=1e-15)
    np.testing.assert_allclose(prof.mean_force_n(feed), prof.s0_n * want, rtol=1e-15)


@pytest.mark.parametrize("feed", [0.0, 0.1, 0.4, 3.0, MAX_FEED_MM_S])
def test_the_yielding_front_inverts_the_same_factor(feed: float) -> None:
    s0 = 4.0
    force = s0 * feed_factor_scalar(feed, KE)
    assert feed_at_factor_mm_s(feed_factor_scalar(feed, KE), KE) == pytest.approx(feed, abs=1e-12)
    assert steady_feed_mm_s(force, s0, KE) == pytest.approx(feed, abs=1e-12)
    # One device tick with the spring holding exactly that force: the front moves v dt and
    # the force it sustained is S0 (1 + Ke v).
    k, dt = 3.2, 1e-4
    front, coupling = cut_step(10.0, 10.0 + force / k, s0, KE, dt, stiffness_n_per_mm=k)
    assert front - 10.0 == pytest.approx(feed * dt, abs=1e-12)
    assert coupling == pytest.approx(force, rel=1e-12)


def _ke_products(path: Path) -> list[int]:
    """Lines of ``path`` that multiply by ``Ke`` (a name or attribute ``ke``/``ke_per_mm_s``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    lines = []
    for node in ast.walk(tree):
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult):
            for side in (node.left, node.right):
                name = side.attr if isinstance(side, ast.Attribute) else getattr(side, "id", "")
                if name in {"ke", "ke_per_mm_s", "self.ke"}:
                    lines.append(node.lineno)
    return lines


def test_only_the_owner_multiplies_by_ke() -> None:
    root = Path(__file__).resolve().parents[2]
    found = {
        str(path.relative_to(root)): _ke_products(path)
        for room in ("app", "imaging", "model", "haptics")
        for path in sorted((root / room).rglob("*.py"))
    }
    found = {k: v for k, v in found.items() if v}
    # model/force.py owns 1 + Ke v; model/fit.py and model/literature.py fit log10(1 + Ke v)
    # with Ke a free parameter.
    assert set(found) <= {"model/force.py", "model/fit.py", "model/literature.py"}, found
    assert "model/force.py" in found  # the scan sees the owner

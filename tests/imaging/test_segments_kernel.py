"""The compiled segment minimisation (``segments_kernel``) against its NumPy twin, bit for bit
(Hypothesis on adversarial segments and solids: a stop must not depend on whether its process
loaded numba), and against the golden section on every segment at once
(``golden_segments_distance_mm``, the independent reference).

Both minimise the same convex distance on each segment by golden section and skip a segment
by the same 1-Lipschitz bound; every value either returns is a distance it evaluated, within
``SEGMENT_TOL_MM`` above the true minimum, so the kernel and the reference differ by at most
``SEGMENT_TOL_MM`` (plus rounding of the axial coordinates, ~1e-13 mm at these sizes).
Cases: the drill solid and every implant body of the library (tapered and parallel, flat and
round apex), canals passing outside, grazing and crossing the solid (negative clearances),
points, degenerate segments, and the demo plan's clearances through the landmarks' own
``clearance_mm``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill import jit
from ctdrill.imaging.plan.distance import (
    SEGMENT_TOL_MM,
    DrillSolid,
    golden_segments_distance_mm,
    segments_distance_mm,
)
from ctdrill.imaging.plan.implant_safety import ImplantBody, implant_clearance
from ctdrill.imaging.plan.implants import load_implant_library
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.safety import clearance_profile_mm
from ctdrill.imaging.plan.segments_kernel import SEGMENTS_KERNEL
from tests.conftest import ASSETS

TOL = SEGMENT_TOL_MM + 1e-11


@pytest.fixture(scope="module", autouse=True)
def kernel() -> None:
    """The kernel as `make warmup` leaves it (compiled here when the cache is missing)."""
    jit.warm_up((SEGMENTS_KERNEL,))
    assert SEGMENTS_KERNEL.ready()


def _both(a: np.ndarray, b: np.ndarray, depth: np.ndarray, solid: object) -> tuple:
    """The kernel's values, and the golden-section reference's; the NumPy twin's bit for bit
    the kernel's."""
    got = segments_distance_mm(a, b, depth, solid)  # type: ignore[arg-type]
    with jit.switched_off((SEGMENTS_KERNEL,)):
        twin = segments_distance_mm(a, b, depth, solid)  # type: ignore[arg-type]
    assert np.array_equal(got.view(np.uint64), twin.view(np.uint64))
    f64 = np.float64
    ref = golden_segments_distance_mm(
        np.asarray(a, f64).reshape(-1, 3),
        np.asarray(b, f64).reshape(-1, 3),
        depth,
        solid,  # type: ignore[arg-type]
    )
    return got, ref


def _polyline(rng: np.random.Generator, centre: np.ndarray, n: int, spread: float) -> np.ndarray:
    steps = rng.normal(0.0, 0.8, (n, 3))
    return centre + spread * rng.normal(0.0, 1.0, 3) + np.cumsum(steps, axis=0)


def _varied(library: tuple) -> list:
    """Parallel flat-apex and tapered round-apex bodies, narrow and wide, short and long."""
    return [s for s in library if s.name.endswith((" 3.3 x 8", " 5 x 13", " 4.1 x 11.5"))]


def _solids() -> list[object]:
    rng = np.random.default_rng(3)
    out: list[object] = [DrillSolid(np.zeros(3), np.array([0.1, -0.2, 1.0]), 1.0, 0.6)]
    out.append(DrillSolid(np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, 1.0]), 1.75, 0.0))
    for spec in _varied(load_implant_library()):
        u = rng.normal(0.0, 1.0, 3)
        out.append(ImplantBody(rng.normal(0.0, 2.0, 3), u, spec, 12.0))
    return out


@pytest.mark.parametrize("solid", _solids(), ids=lambda s: type(s).__name__)
def test_canals_and_points_match_numpy(solid: object) -> None:
    rng = np.random.default_rng(11)
    entry = np.asarray(solid.entry_lps)  # type: ignore[attr-defined]
    axis = np.asarray(solid.direction)  # type: ignore[attr-defined]
    depth = np.array([0.0, 3.5, 8.0, 12.0, 13.7])
    for spread in (0.5, 2.0, 6.0):  # crossing the solid, grazing it, passing by
        pts = _polyline(rng, entry + 10.0 * axis, 40, spread)
        got, ref = _both(pts[:-1], pts[1:], depth, solid)
        assert np.all(np.abs(got - ref) <= TOL), np.abs(got - ref).max()
    # points (degenerate segments), some inside the solid
    pts = entry + rng.uniform(0.0, 14.0, (30, 1)) * axis + rng.normal(0.0, 1.5, (30, 3))
    got, ref = _both(pts, pts, depth, solid)
    assert np.all(np.abs(got - ref) <= TOL)
    assert (got < 0.0).any()  # some points lie inside the solid


def test_negative_clearance_inside() -> None:
    """A canal through the body: both negative, equal within the tolerance."""
    spec = load_implant_library()[0]
    body = ImplantBody(np.zeros(3), np.array([0.0, 0.0, 1.0]), spec, 12.0)
    pts = np.array([[-5.0, 0.1, 8.0], [0.0, 0.2, 8.2], [5.0, -0.1, 8.1]])
    got, ref = _both(pts[:-1], pts[1:], np.array([12.0]), body)
    assert got[0] < 0.0
    assert abs(got[0] - ref[0]) <= TOL


def test_demo_plan_clearances_match_numpy() -> None:
    plan = load_plan(ASSETS / "demo" / "plan.json")
    depth = np.linspace(0.0, plan.planned_depth_mm + 3.0, 31)
    got = clearance_profile_mm(plan, depth_mm=depth)
    imp = implant_clearance(plan)
    with jit.switched_off((SEGMENTS_KERNEL,)):
        ref = clearance_profile_mm(plan, depth_mm=depth)
        imp_ref = implant_clearance(plan)
    assert np.array_equal(got, ref)  # the twin's bits
    assert imp is not None and imp_ref is not None
    assert np.array_equal(imp.clearance_mm, imp_ref.clearance_mm)
    assert imp.binding == imp_ref.binding


_LIBRARY = load_implant_library()
_coord = st.sampled_from([0.0, -0.0, 1.0, -1.0, 0.5, 2.0, 1e-9, 1.75]) | st.floats(-8.0, 8.0)


@st.composite
def _cases(draw: st.DrawFn) -> tuple[object, np.ndarray, np.ndarray, np.ndarray]:
    """Solids on exact or random axes; segments through the axis, on the surface, along
    the axis, of zero length, shared ends; depths at the segments' own axial places."""
    axis = np.array(draw(st.sampled_from([(0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.3, -0.4, 0.8)])))
    axis = axis / np.linalg.norm(axis)
    entry = np.array([draw(_coord), draw(_coord), draw(_coord)])
    kind = draw(st.integers(0, 3))
    if kind == 0:
        solid: object = DrillSolid(entry, axis, 1.0, 0.6)
    elif kind == 1:
        solid = DrillSolid(entry, axis, 1.75, 0.0)
    else:
        spec = _LIBRARY[draw(st.integers(0, len(_LIBRARY) - 1))]
        solid = ImplantBody(entry, axis, spec, float(draw(st.sampled_from([8.0, 12.0]))))
    n = draw(st.integers(1, 6))
    pts = np.array([[draw(_coord) for _ in range(3)] for _ in range(n + 1)])
    pts = entry + pts[:, 2:3] * 1.5 * axis + pts * draw(st.sampled_from([0.0, 0.3, 1.0]))
    if draw(st.booleans()):
        pts[1] = pts[0]  # a point
    depth = np.array([draw(st.sampled_from([0.0, 4.0, 8.0, 12.0, 13.7])) for _ in range(3)])
    depth[0] = float((pts[0] - entry) @ axis)  # the solid's end at a segment's end
    return solid, pts[:-1], pts[1:], depth


@settings(max_examples=200, deadline=None)
@given(_cases())
def test_the_numpy_twin_gives_the_kernels_bits(
    case: tuple[object, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    solid, a, b, depth = case
    got, ref = _both(a, b, depth, solid)
    assert np.all(np.abs(got - ref) <= TOL + 1e-9 * np.abs(ref)) or np.array_equal(got, ref)

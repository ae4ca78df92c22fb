"""Why a trajectory cannot be computed: one message builder per refusal of the engine's own.

The volume's refusals are built where their rule lives (the volume edge,
:func:`ctdrill.imaging.sampling.edge.entry_refusal`; padding and gaps' wording,
:mod:`ctdrill.imaging.sampling.path`; a degenerate axis, the lip sampler's). Each builder
returns the exception; the single path raises it, a batch records its message on the row.
"""

from __future__ import annotations

from collections.abc import Sequence

from ctdrill.engine.grid import MAX_PLANNED_DEPTH_MM
from ctdrill.imaging.bounds import MAX_COORDINATE_MM
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.path import PathInputError, SliceGap


def bad_step(depth_step_mm: float) -> PathInputError:
    """A depth step that is not a positive number."""
    return PathInputError(f"depth_step_mm must be a positive number, got {depth_step_mm!r}")


def bad_coordinate(plan: Plan) -> PathInputError:
    """A point of the trajectory or of a landmark that is not finite or beyond
    :data:`~ctdrill.imaging.bounds.MAX_COORDINATE_MM`."""
    return PathInputError(
        f"plan {plan.name!r}: a coordinate is not finite or beyond {MAX_COORDINATE_MM:g} mm; "
        "check the plan's points (units are mm)"
    )


def too_deep(plan: Plan, planned_depth_mm: float) -> PathInputError:
    """A trajectory longer than :data:`~ctdrill.engine.grid.MAX_PLANNED_DEPTH_MM`."""
    return PathInputError(
        f"plan {plan.name!r}: planned depth {planned_depth_mm:.6g} mm exceeds "
        f"{MAX_PLANNED_DEPTH_MM:g} mm; check the entry and target (units are mm)"
    )


def gap_crossed(plan: Plan, gaps: Sequence[SliceGap]) -> PathInputError:
    """The lip crosses slice gaps and the caller did not ask to interpolate across them."""
    return PathInputError(
        f"plan {plan.name!r}: the drill lip crosses "
        + (f"{len(gaps)} slice gaps, the first: " if len(gaps) > 1 else "")
        + f"{gaps[0].describe()}; the CT holds no "
        "slice there: plan away from it, or interpolate across it explicitly "
        "(--interpolate-gaps; the summary then says so)"
    )


def gap_interpolated_message(plan: Plan, gap: SliceGap) -> str:
    """The warning of a gap interpolated across on request (``gap_interpolated``)."""
    return (
        f"plan {plan.name!r}: the drill lip crosses {gap.describe()}; HU there are "
        "interpolated linearly between the two real slices, as asked"
    )


def drill_sequence(plan: Plan) -> PathInputError:
    """A batch asked for a plan with a drill sequence (its forces need the earlier holes)."""
    sizes = ", ".join(f"{d.diameter_mm:g}" for d in plan.drills)
    return PathInputError(
        f"plan {plan.name!r} drills a sequence ({sizes} mm): evaluate_batch computes one "
        "drill on a full lip, not a drill cutting around earlier holes; pass "
        "plan.for_drill(k) for drill k alone (plan_sequence computes a sequence's forces)"
    )

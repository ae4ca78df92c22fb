"""The engine's batch with its compiled kernels against the single path on the NumPy path (the
kernels switched off), row by row, to 1e-9: the demo phantom, an irregular stack, real tilted
and padded series, random trajectories, canal / point / mask landmarks, refusals. The batch
and the single path are one engine; these hold the kernels and their NumPy fallback equal,
and every row of a batch equal to its one-row case."""

from __future__ import annotations

import contextlib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ctdrill import jit
from ctdrill.app.search.warmup import search_kernels
from ctdrill.engine.batch import BatchResult, evaluate_batch
from ctdrill.engine.path import PathInputError, plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.imaging.dicom.series import load_series
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.distance import SEGMENT_TOL_MM
from ctdrill.imaging.plan.landmarks import CanalLandmark, MaskLandmark, PointLandmark
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.lip import ring_radii_mm
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration, load_calibration
from ctdrill.model.errors import ModelInputError
from ctdrill.model.profile_batch import law_tables
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"
TOL = 1e-9


@pytest.fixture(scope="module", autouse=True)
def kernels() -> None:
    """The compiled kernels, as `make warmup` leaves them (compiled here when the cache is
    missing or stale): these tests check the kernels, the fallback test below the NumPy path."""
    jit.warm_up(search_kernels())
    assert all(k.ready() for k in search_kernels())


@pytest.fixture(scope="module")
def demo() -> tuple[CTVolume, Plan, Calibration]:
    plan = load_plan(DEMO / "plan.json")
    return load_series(DEMO / "ct"), plan, plan_calibration(plan)


def _close(got: np.ndarray, want: np.ndarray, what: str) -> None:
    np.testing.assert_allclose(
        np.asarray(got, dtype=np.float64), want, rtol=0, atol=TOL, err_msg=what
    )


def _close_clearance(got: np.ndarray, want: np.ndarray, what: str) -> None:
    """1e-9 where the drill is outside the landmark (the distance is smooth at its minimum);
    inside it (negative) plan_path's golden section is within SEGMENT_TOL_MM above the exact
    minimum the kernel finds, so there ``0 <= want - got <= SEGMENT_TOL_MM``."""
    got = np.asarray(got, dtype=np.float64)
    want = np.asarray(want, dtype=np.float64)
    outside = ~(want < 0.0)
    _close(got[outside], want[outside], what)
    gap = want[~outside] - got[~outside]
    assert np.all(gap >= -TOL) and np.all(gap <= SEGMENT_TOL_MM + TOL), (what, gap.min(), gap.max())


def numpy_path() -> contextlib.AbstractContextManager[None]:
    """The compiled kernels switched off: the NumPy path computes the same arrays."""
    return jit.switched_off(search_kernels())


def assert_rows_match(
    volume: CTVolume,
    plan: Plan,
    cal: Calibration,
    entries: np.ndarray,
    targets: np.ndarray,
    **kw: object,
) -> BatchResult:
    """Every row of evaluate_batch (compiled kernels) equals plan_path on that trajectory on
    the NumPy path (or its refusal)."""
    got = evaluate_batch(volume, plan, entries, targets, cal, **kw)  # type: ignore[arg-type]
    assert got.size == len(entries)
    n_l = len(plan.landmarks)
    for n, (e, t) in enumerate(zip(entries, targets, strict=True)):
        try:
            with numpy_path():
                want = plan_path(volume, replace(plan, entry_lps=e, target_lps=t), cal, **kw)  # type: ignore[arg-type]
        except (ImagingInputError, ModelInputError) as exc:
            assert got.refusal[n] == str(exc), n
            assert got.n_depths[n] == 0 and np.all(np.isnan(got.s0_n[n]))
            assert got.stop_reason[n] == "" and got.binding_landmark[n] == -1
            continue
        assert got.refusal[n] is None, (n, got.refusal[n])
        m = want.depth_mm.shape[0]
        assert got.n_depths[n] == m
        _close(got.depth_mm[n, :m], want.depth_mm, f"depth row {n}")
        assert np.all(np.isnan(got.depth_mm[n, m:]))
        prof = want.profile
        for name in ("hu_mean", "s_t", "s0_n"):
            _close(getattr(got, name)[n, :m], getattr(prof, name), f"{name} row {n}")
        _close(got.sk_n[n, :, :m], prof.sk_n, f"sk_n row {n}")
        _close(got.freqs_hz, prof.freqs_hz, "freqs")
        assert got.ke_per_mm_s == prof.ke_per_mm_s
        assert got.n_clipped[n] == prof.n_clipped and got.n_samples[n] == prof.n_samples
        radii = ring_radii_mm(plan.drill.diameter_mm, want.lip.radii_mm.size)
        disc = want.lip.hu.astype(np.float64).mean(axis=2) @ (radii / radii.sum())
        _close(got.disc_hu[n, :m], disc, f"disc_hu row {n}")
        _close_clearance(got.clearance_mm[n, :m], want.clearance_mm, f"clearance row {n}")
        _close(got.margins_mm, want.margins_mm, "margins")
        _close(got.max_safe_depth_mm[n], want.max_safe_depth_mm, f"max safe row {n}")
        assert bool(got.max_safe_depth_capped[n]) == want.max_safe_depth_capped
        assert got.binding_landmark[n] == (
            -1 if want.binding_landmark is None else want.binding_landmark
        )
        pc = np.nan if want.plan_clearance_mm is None else want.plan_clearance_mm
        _close_clearance(got.plan_clearance_mm[n], pc, f"plan clearance row {n}")
        oov = np.nan if want.out_of_volume_depth_mm is None else want.out_of_volume_depth_mm
        _close(got.out_of_volume_depth_mm[n], oov, f"out of volume row {n}")
        _close(got.stop_depth_mm[n], want.stop_depth_mm, f"stop row {n}")
        assert got.stop_reason[n] == want.stop_reason, n
        assert got.stop_clearance_mm[n].shape == (n_l,)
        _close_clearance(
            got.stop_clearance_mm[n], want.stop_clearance_mm, f"stop clearance row {n}"
        )
    return got


def random_axes(
    plan: Plan, n: int, seed: int, *, shift_mm: float = 3.0, cone_deg: float = 25.0
) -> tuple[np.ndarray, np.ndarray]:
    """Entries within ``shift_mm`` of the plan's, axes within ``cone_deg`` of it, depths 4-16 mm."""
    rng = np.random.default_rng(seed)
    entries = plan.entry_lps + rng.uniform(-shift_mm, shift_mm, (n, 3))
    tilt = np.deg2rad(rng.uniform(0.0, cone_deg, n))
    az = rng.uniform(0.0, 2 * np.pi, n)
    u = plan.direction
    helper = np.array([1.0, 0.0, 0.0])
    e1 = np.cross(u, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    dirs = np.cos(tilt)[:, None] * u + np.sin(tilt)[:, None] * (
        np.cos(az)[:, None] * e1 + np.sin(az)[:, None] * e2
    )
    depth = rng.uniform(4.0, 16.0, n)
    return entries, entries + depth[:, None] * dirs


def test_demo_random_trajectories_match_plan_path(demo: tuple[CTVolume, Plan, Calibration]) -> None:
    volume, plan, cal = demo
    entries, targets = random_axes(plan, 24, seed=1)
    # The plan itself; one through the canal; one leaving the volume; one entering outside
    # it; a degenerate axis; one too long.
    extra_e = [plan.entry_lps, plan.entry_lps, plan.entry_lps, [500.0, 0.0, 0.0]]
    extra_t = [
        plan.target_lps,
        plan.target_lps + np.array([-4.0, -20.0, -3.0]),
        [70.0, 10.0, -32.0],
    ]
    extra_t += [[500.0, 0.0, -10.0]]
    entries = np.vstack([entries, extra_e, plan.entry_lps, plan.entry_lps])
    targets = np.vstack(
        [targets, extra_t, plan.entry_lps, plan.entry_lps + np.array([0, 0, -300.0])]
    )
    got = assert_rows_match(volume, plan, cal, entries, targets)
    reasons = set(got.stop_reason.tolist())
    assert {"planned_depth", "margin", "out_of_volume", ""} <= reasons
    assert sum(r is not None for r in got.refusal) == 3
    assert np.any(got.clearance_mm[np.isfinite(got.clearance_mm)] < 0.0)  # inside the canal


def test_point_and_mask_landmarks_with_own_margins(
    demo: tuple[CTVolume, Plan, Calibration],
) -> None:
    volume, plan, cal = demo
    mask = np.zeros(volume.hu.shape, dtype=bool)
    # A block of voxels below and beside the planned target (indices k, j, i).
    mask[8:14, 55:62, 62:70] = True
    landmarks = (
        *plan.landmarks,
        PointLandmark("apex", plan.target_lps + np.array([1.5, 0.5, -2.5]), margin_mm=1.0),
        MaskLandmark("block", mask, margin_mm=1.5),
        CanalLandmark("short", np.array([[30.0, 14.0, -40.0]]), radius_mm=0.5),
    )
    plan2 = replace(plan, landmarks=landmarks)
    entries, targets = random_axes(plan2, 12, seed=2)
    got = assert_rows_match(volume, plan2, cal, entries, targets, depth_step_mm=0.1)
    assert got.clearance_mm.shape[2] == 4
    assert len(set(got.binding_landmark[got.ok].tolist())) >= 2


def test_no_landmarks_coarse_lip(demo: tuple[CTVolume, Plan, Calibration]) -> None:
    volume, plan, cal = demo
    plan2 = replace(plan, landmarks=())
    entries, targets = random_axes(plan2, 8, seed=3)
    got = assert_rows_match(volume, plan2, cal, entries, targets, n_rings=3, n_angles=5)
    assert got.clearance_mm.shape[2] == 0 and np.all(got.binding_landmark == -1)
    assert np.all(got.max_safe_depth_capped[got.ok])


def _without_slices(volume: CTVolume, drop: slice) -> CTVolume:
    keep = np.ones(volume.hu.shape[0], dtype=bool)
    keep[drop] = False
    return CTVolume(
        volume.hu[keep],
        volume.affine_lps,
        None,
        volume.info,
        slice_positions_mm=volume.slice_positions_mm[keep],
    )


@pytest.mark.parametrize("interpolate", [False, True])
def test_irregular_stack_with_a_gap(
    demo: tuple[CTVolume, Plan, Calibration], interpolate: bool
) -> None:
    volume, plan, cal = demo
    z = volume.slice_origins_lps[:, 2]
    gone = np.flatnonzero((z > -39.9) & (z < -38.1))
    assert gone.size == 5
    irregular = _without_slices(volume, slice(int(gone[0]), int(gone[-1]) + 1))
    # Also an irregular (non-gap) step: drop single slices elsewhere.
    irregular = _without_slices(irregular, slice(30, 31))
    assert not irregular.regular
    entries, targets = random_axes(plan, 16, seed=4)
    got = assert_rows_match(irregular, plan, cal, entries, targets, interpolate_gaps=interpolate)
    refused = [r for r in got.refusal if r is not None]
    assert bool(refused) != interpolate
    assert all("slice gap" in r for r in refused)


def test_real_tilted_padded_series(shared_data: Path) -> None:
    volume = load_series(shared_data / "dcmqa_ct_GE_head_gantrytilt_varspacing")
    assert volume.valid is not None and not volume.regular
    centre = volume.index_to_lps(np.array(volume.dims, dtype=float) / 2.0 - 0.5)
    rng = np.random.default_rng(5)
    entries = centre + rng.uniform(-60.0, 60.0, (14, 3))
    targets = entries + rng.normal(0.0, 1.0, (14, 3)) * 15.0
    plan = Plan(
        entry_lps=entries[0],
        target_lps=targets[0],
        landmarks=(CanalLandmark("c", np.array([centre, centre + np.array([10.0, 5.0, 0.0])])),),
    )
    cal = plan_calibration(plan)
    for interpolate in (False, True):
        got = assert_rows_match(
            volume, plan, cal, entries, targets, depth_step_mm=0.2, interpolate_gaps=interpolate
        )
        assert got.ok.any()
        assert not got.ok.all()


def test_batch_level_errors_raise_once(demo: tuple[CTVolume, Plan, Calibration]) -> None:
    volume, plan, cal = demo
    e = plan.entry_lps[None, :]
    with pytest.raises(PathInputError, match="depth_step_mm"):
        evaluate_batch(volume, plan, e, e + 1.0, cal, depth_step_mm=0.0)
    with pytest.raises(PathInputError, match=r"\(N, 3\)"):
        evaluate_batch(volume, plan, plan.entry_lps, plan.target_lps, cal)
    with pytest.raises(PathInputError, match="one target per entry"):
        evaluate_batch(volume, plan, e, np.vstack([e, e]), cal)
    empty = evaluate_batch(volume, plan, np.empty((0, 3)), np.empty((0, 3)), cal)
    assert empty.size == 0 and empty.depth_mm.shape == (0, 0)


def test_without_compiled_kernels_the_numpy_path_gives_the_same_rows(
    demo: tuple[CTVolume, Plan, Calibration], monkeypatch: pytest.MonkeyPatch
) -> None:
    volume, plan, cal = demo
    entries, targets = random_axes(plan, 5, seed=6)
    fast = evaluate_batch(volume, plan, entries, targets, cal)
    for kernel in search_kernels():
        monkeypatch.setattr(kernel, "ready", lambda: False)
    slow = assert_rows_match(volume, plan, cal, entries, targets)
    np.testing.assert_allclose(slow.s0_n, fast.s0_n, rtol=0, atol=TOL)
    np.testing.assert_allclose(slow.max_safe_depth_mm, fast.max_safe_depth_mm, rtol=0, atol=TOL)


def test_loaded_kernels_never_compile() -> None:
    for kernel in search_kernels():
        assert kernel.ready()
        assert not kernel._dispatch()._can_compile  # a call with other types raises, not compiles


def test_law_tables_are_the_power_laws_to_1e_10() -> None:
    for name in ("bone-illustrative", "pine-wood-paper"):
        cal = load_calibration(name)
        lo, inv_step, coefs = law_tables(cal)
        hi = cal.c_prime_range[1]
        c = np.concatenate([np.random.default_rng(7).uniform(lo, hi, 100_000), [lo, hi]])
        pos = (c - lo) * inv_step
        j = np.minimum(pos.astype(np.int64), coefs.shape[0] - 1)
        u = pos - j
        for k, law in enumerate([cal.a0, *cal.harmonics]):
            a = coefs[j, k]
            got = a[:, 0] + u * (a[:, 1] + u * (a[:, 2] + u * a[:, 3]))
            want = 10.0**law.b0 * c**law.n
            assert np.max(np.abs(got / want - 1.0)) < 1e-10, (name, k)


def test_stops_only_give_the_full_evaluation_stops(
    demo: tuple[CTVolume, Plan, Calibration],
) -> None:
    """``profiles=False`` (suggest's stage 1): no profile, the clearance on a sparse part of
    the grid, and every stop, max safe depth, binding landmark and refusal of the full
    evaluation (the first broken grid step is the same: the clearance never increases)."""
    volume, plan, cal = demo
    mask = np.zeros(volume.hu.shape, dtype=bool)
    mask[8:14, 55:62, 62:70] = True
    plans = (
        plan,
        replace(
            plan,
            landmarks=(
                *plan.landmarks,
                PointLandmark("apex", plan.target_lps + np.array([1.5, 0.5, -2.5]), margin_mm=1),
                MaskLandmark("block", mask, margin_mm=1.5),
            ),
        ),
        replace(plan, landmarks=()),
    )
    for k, p in enumerate(plans):
        entries, targets = random_axes(p, 24, seed=10 + k)
        entries = np.vstack([entries, plan.entry_lps, [500.0, 0.0, 0.0]])
        targets = np.vstack(
            [targets, plan.target_lps + np.array([-4.0, -20.0, -3.0]), [500, 0, -10.0]]
        )
        full = evaluate_batch(volume, p, entries, targets, cal)
        got = evaluate_batch(volume, p, entries, targets, cal, profiles=False)
        assert got.refusal == full.refusal
        assert got.stop_reason.tolist() == full.stop_reason.tolist()
        assert np.array_equal(got.binding_landmark, full.binding_landmark)
        assert np.array_equal(got.max_safe_depth_capped, full.max_safe_depth_capped)
        for name in ("max_safe_depth_mm", "stop_depth_mm", "out_of_volume_depth_mm"):
            _close(getattr(got, name), getattr(full, name), name)
        for name in ("plan_clearance_mm", "stop_clearance_mm"):
            _close(getattr(got, name), getattr(full, name), name)
        assert np.all(np.isnan(got.s0_n)) and np.all(np.isnan(got.disc_hu))
        if p.landmarks:
            assert {"planned_depth", "margin"} <= set(full.stop_reason.tolist())
            last = got.n_depths[got.ok] - 1
            planned = got.clearance_mm[got.ok][np.arange(last.size), last]
            assert np.all(np.isfinite(planned))


def test_clearance_stops_after_the_first_broken_depth(
    demo: tuple[CTVolume, Plan, Calibration],
) -> None:
    """``ClearanceField.at(stop_slack=...)``: each row the same up to and including its first
    depth whose slack ``clearance - margin - tol`` is negative, NaN after it (the safe-depth
    search reads no later depth)."""
    from ctdrill.imaging.plan.clearance_batch import ClearanceField
    from ctdrill.imaging.plan.safety import margins_mm

    _, plan, _ = demo
    entries, targets = random_axes(plan, 30, seed=21)
    rows = np.arange(30)
    field = ClearanceField.prepare(
        plan.landmarks, plan.drill.radius_mm, plan.drill.tip_length_mm, entries, targets, rows
    )
    assert field.compiled
    depth = np.tile(np.linspace(0.0, 25.0, 101), (30, 1))
    margins = margins_mm(plan)
    full = field.at(rows, depth)
    got = field.at(rows, depth, stop_slack=(margins, SEGMENT_TOL_MM))
    broken = np.any(full - margins - SEGMENT_TOL_MM < 0.0, axis=2)
    assert 0 < broken[:, -1].sum() < 30  # some rows break a margin, some never do
    for n in range(30):
        last = int(np.argmax(broken[n])) if broken[n].any() else depth.shape[1] - 1
        assert np.array_equal(got[n, : last + 1], full[n, : last + 1])
        assert np.all(np.isnan(got[n, last + 1 :]))


def test_a_one_plan_job_without_numba_gives_the_kernels_bits(
    demo: tuple[CTVolume, Plan, Calibration], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A one-plan job in a process without numba (``jit.job``: every kernel's NumPy path, the
    clearance rows' kernel run as its own Python) gives plan_path's arrays bit for bit as the
    loaded kernels do: canal, point, mask and one-point canal landmarks, 12 random axes."""
    volume, plan, cal = demo
    mask = np.zeros(volume.hu.shape, dtype=bool)
    mask[8:14, 55:62, 62:70] = True
    landmarks = (
        *plan.landmarks,
        PointLandmark("apex", plan.target_lps + np.array([1.5, 0.5, -2.5]), margin_mm=1.0),
        MaskLandmark("block", mask, margin_mm=1.5),
        CanalLandmark("short", np.array([[30.0, 14.0, -40.0]]), radius_mm=0.5),
    )
    plan2 = replace(plan, landmarks=landmarks)
    entries, targets = random_axes(plan2, 12, seed=4)
    rows = [
        replace(plan2, entry_lps=e, target_lps=t) for e, t in zip(entries, targets, strict=True)
    ]
    want = [plan_path(volume, p, cal) for p in rows]
    monkeypatch.setattr(jit, "worth_loading", lambda: False)
    for k in search_kernels():
        monkeypatch.setattr(k, "_ready", None)
    assert not any(k.ready() for k in search_kernels())
    from ctdrill.imaging.plan.clearance_kernel import CLEARANCE_KERNEL

    assert CLEARANCE_KERNEL.interpreted()
    for p, w in zip(rows, want, strict=True):
        g = plan_path(volume, p, cal)
        for name in ("depth_mm", "clearance_mm", "margins_mm", "stop_clearance_mm"):
            assert np.array_equal(getattr(g, name), getattr(w, name), equal_nan=True), name
        for name in ("hu_mean", "s_t", "s0_n", "sk_n"):
            assert np.array_equal(getattr(g.profile, name), getattr(w.profile, name)), name
        assert g.stop_depth_mm == w.stop_depth_mm and g.stop_reason == w.stop_reason
        assert g.max_safe_depth_mm == w.max_safe_depth_mm
        assert g.plan_clearance_mm == w.plan_clearance_mm
        assert g.binding_landmark == w.binding_landmark

"""3D view: the bone surface of a large series at full resolution, with the UI thread free.

A synthetic 512 x 512 x 600 head (0.4 mm pixels, 0.3 mm slices: a skull shell and a U-shaped
mandible, 1200 HU in air) written as DICOM is opened in the real window under Xvfb (software
OpenGL, Mesa llvmpipe), with its plan. Measured from ``open_folder`` to the frame that draws the
last piece of the bone surface ("surface shown"): that time, and the longest the UI thread went
without serving a 10 ms heartbeat timer (the longest UI stall). ctdrill's path: in a worker the
series is loaded and contoured at every voxel (``vtkFlyingEdges3D`` on VTK's thread backend,
normals from the voxel gradient), the triangles cut into slab pieces of at most
``PIECE_TRIANGLES``, which the 3D view's render thread adds and draws (its frames reach the
UI thread as images). Peers in the same run and process: the earlier path (the same window with
the coarse surface, strided to 160 samples a side: every 4th slice and pixel), and a plain
``pyvista`` contour of the loaded volume at full resolution, added with smooth shading and drawn
while the UI thread waits, in one step (its stall is that step). The frame time is one render of
the 3D view (on its render thread) with the whole surface shown.
"""

from __future__ import annotations

import functools
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from bench.report import Section, Timing, headline_row, table
from ctdrill.imaging.display import BONE_SURFACE_HU
from ctdrill.imaging.phantom.writer import write_series
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.plan.write import save_plan

#: Heartbeat interval, ms.
TICK_MS = 10
#: The goal: the UI thread never held longer than this, s.
GOAL_STALL_S = 0.100
#: Stride of the earlier coarse surface (samples on the longest side).
OLD_MAX_DIM = 160


def synthetic_head(
    out_dir: Path, shape_kji: tuple[int, int, int], pixel_mm: float, slice_mm: float
) -> Path:
    """Write a skull-and-mandible series and a plan into ``out_dir``; returns the plan path.

    Skull: an ellipsoidal shell (semi-axes 70, 85, 75 mm, 6 mm thick) centred 20 mm above the
    volume's centre; mandible: bone within an ellipse of semi-axes 6 mm (across) and 14 mm
    (height) around a U-shaped arch 60 mm below the centre. The plan drills 12 mm down into
    the front of the mandible, with a canal along the arch 9 mm below its crest.
    """
    nk, nj, ni = shape_kji
    x = (np.arange(ni) - (ni - 1) / 2.0) * pixel_mm
    y = (np.arange(nj) - (nj - 1) / 2.0) * pixel_mm
    z = (np.arange(nk) - (nk - 1) / 2.0) * slice_mm
    scale = min(1.0, x[-1] / 100.0, z[-1] / 90.0)  # toy sizes: shrink the anatomy to fit
    xx, yy = np.meshgrid(x, y, indexing="xy")
    # The arch: y = -45 + 0.012 x^2 (x in mm), |x| <= 45 mm, scaled.
    t = np.linspace(-45.0, 45.0, 400)
    arch = np.stack([t, -45.0 + 0.012 * t**2], axis=1) * scale
    on_arch = np.ones((nj, ni), dtype=bool)
    ci = np.clip(np.round((arch[:, 0] - x[0]) / pixel_mm).astype(int), 0, ni - 1)
    cj = np.clip(np.round((arch[:, 1] - y[0]) / pixel_mm).astype(int), 0, nj - 1)
    on_arch[cj, ci] = False
    d_arch = ndimage.distance_transform_edt(on_arch) * pixel_mm
    skull_c = 20.0 * scale
    semi = np.array([70.0, 85.0, 75.0]) * scale
    inner = semi - 6.0 * scale
    mand_z = -60.0 * scale
    hu = np.full((nk, nj, ni), -1000, dtype=np.int16)
    for k in range(nk):
        dz = z[k] - skull_c
        r_out = (xx / semi[0]) ** 2 + (yy / semi[1]) ** 2 + (dz / semi[2]) ** 2
        r_in = (xx / inner[0]) ** 2 + (yy / inner[1]) ** 2 + (dz / inner[2]) ** 2
        bone = (r_out <= 1.0) & (r_in > 1.0)
        mz = (z[k] - mand_z) / (14.0 * scale)
        if abs(mz) < 1.0:
            bone |= (d_arch / (6.0 * scale)) ** 2 + mz**2 <= 1.0
        hu[k][bone] = 1200
    affine = np.diag([pixel_mm, pixel_mm, slice_mm, 1.0])
    affine[:3, 3] = [x[0], y[0], z[0]]
    write_series(out_dir / "ct", hu, affine)
    top = mand_z + 14.0 * scale
    front = arch[len(arch) // 2]
    canal = np.column_stack([arch, np.full(len(arch), top - 9.0 * scale)])[::20]
    from ctdrill.imaging.plan.landmarks import CanalLandmark

    plan = Plan(
        entry_lps=np.array([front[0], front[1], top + 1.0]),
        target_lps=np.array([front[0], front[1], top - 12.0 * scale]),
        landmarks=(CanalLandmark(name="canal", points_lps=canal, radius_mm=1.2),),
        name="synthetic head",
    )
    save_plan(plan, out_dir / "plan.json")
    return out_dir / "plan.json"


#: (duration s, qualified name) of every UI-thread drawing step (``_time_steps``).
STEPS: list[tuple[float, str]] = []


def _time_steps() -> None:
    """Record every step of the window's step queue (each view's drawing, one per pass)."""
    from ctdrill.app.gui.workers import StepQueue

    if getattr(StepQueue, "_bench_timed", False):
        return
    original = StepQueue._step

    def step(self: StepQueue) -> None:
        fn = self._steps[0] if self._steps else None
        t0 = time.perf_counter()
        original(self)
        if fn is not None:
            STEPS.append((time.perf_counter() - t0, getattr(fn, "__qualname__", "step")))

    StepQueue._step = step  # type: ignore[method-assign]
    StepQueue._bench_timed = True  # type: ignore[attr-defined]


def _longest_steps() -> tuple[float, float, str]:
    """Longest 3D-view step, longest other step and its owner, since ``STEPS`` was cleared."""
    view = [d for d, name in STEPS if name.startswith("View3D")]
    other = [(d, name.split(".")[0]) for d, name in STEPS if not name.startswith("View3D")]
    worst = max(other, default=(0.0, ""))
    return max(view, default=0.0), worst[0], worst[1]


def _open_until_surface(window: object, ct_dir: Path) -> tuple[float, float, float, int, int]:
    """Open ``ct_dir`` in ``window`` and wait until the 3D view's surface is settled (the
    first one shown and, where the frame time affords it, the finer one after it).

    Returns (time to the first surface shown, time to the settled surface shown, longest
    gap between heartbeat ticks from the open to then, first and settled triangles)."""
    from PySide6.QtCore import QEventLoop, QTimer

    from ctdrill.app.gui.main_window import MainWindow

    assert isinstance(window, MainWindow)
    view = window.view3d
    ticks: list[float] = []
    first: list[tuple[float, int]] = []
    ticker = QTimer()
    ticker.setInterval(TICK_MS)
    ticker.timeout.connect(lambda: ticks.append(time.perf_counter()))

    def shown() -> None:
        if not first and view.surface is not None:
            first.append((view.surface_shown_s, int(view.surface.n_cells)))

    loop = QEventLoop()
    view.surface_shown.connect(shown)
    view.surface_settled.connect(loop.quit)
    QTimer.singleShot(300_000, loop.quit)
    STEPS.clear()
    ticker.start()
    t0 = time.perf_counter()
    window.open_folder(ct_dir)
    loop.exec()
    ticker.stop()
    view.surface_settled.disconnect(loop.quit)
    view.surface_shown.disconnect(shown)
    end = view.surface_shown_s
    if not first or not np.isfinite(view.settled_s):
        raise RuntimeError("the bone surface was not shown within 300 s")
    stall = float(np.max(np.diff([t0, *[t for t in ticks if t <= end], end])))
    n_tri = 0 if view.surface is None else int(view.surface.n_cells)
    return first[0][0] - t0, end - t0, stall, first[0][1], n_tri


def _plain_contour_on_ui_thread(window: object) -> tuple[float, int]:
    """The plain peer: contour the open volume at every voxel with ``pyvista`` and draw it
    with ``add_mesh`` on the UI thread; returns the duration of that one step (s) and its
    triangles."""
    import pyvista as pv

    from ctdrill.app.gui.main_window import MainWindow

    assert isinstance(window, MainWindow)
    volume = window.doc.volume
    assert volume is not None
    rt = window.view3d.rt  # the view's render thread: the UI thread waits for the frame
    t0 = time.perf_counter()
    nk, nj, ni = volume.hu.shape
    grid = pv.ImageData(dimensions=(ni, nj, nk))
    grid.point_data["hu"] = np.asarray(volume.hu, dtype=np.float32).ravel()
    surf = grid.contour([BONE_SURFACE_HU], scalars="hu", method="flying_edges")

    def draw(stage: Any) -> Any:
        actor = stage.add_mesh(
            surf, name="plain", color=(1.0, 1.0, 1.0), smooth_shading=True, opacity=0.45
        )
        rt.render_once(stage)
        return actor

    actor = rt.call(draw)
    dt = time.perf_counter() - t0
    rt.call(lambda stage: (stage.remove_actor(actor), rt.render_once(stage)))
    return dt, int(surf.n_cells)


def _error_mm(window: object) -> tuple[float, float, str, int]:
    """How far the shown surface's vertices lie from the every-voxel surface's (nearest
    vertex: an upper bound of the distance to that surface), max and 99th percentile, mm;
    the block it was contoured at; the every-voxel surface's triangles."""
    from scipy.spatial import cKDTree

    from ctdrill.app.gui.main_window import MainWindow
    from ctdrill.app.gui.surface import bone_surface

    assert isinstance(window, MainWindow)
    volume, shown = window.doc.volume, window.view3d.surface
    assert volume is not None and shown is not None
    full = bone_surface(
        volume.hu, volume.affine_lps, valid=volume.valid, index_to_lps=volume.index_to_lps
    )
    dist = np.asarray(cKDTree(np.asarray(full.points)).query(np.asarray(shown.points))[0])
    block = "x".join(str(int(b)) for b in shown.field_data["block"])
    return float(dist.max()), float(np.percentile(dist, 99)), block, int(full.n_cells)


Run = tuple[float, float, float, int, int]


def _measure(ct_dir: Path, plan_path: Path, repeats: int, scratch: Path) -> dict[str, object]:
    from PySide6.QtCore import QSettings

    from ctdrill.app.gui import compute
    from ctdrill.app.gui.app import application, make_window

    _time_steps()
    app = application()
    settings = QSettings(str(scratch / "settings.ini"), QSettings.Format.IniFormat)
    window = make_window(settings)
    window.unattended = True
    full_load = compute.load_case
    coarse_load = functools.partial(compute.load_case, max_dim=OLD_MAX_DIM)
    samples: dict[str, list[Run]] = {"full": [], "coarse": []}
    steps: dict[str, list[tuple[float, float, str]]] = {"full": [], "coarse": []}
    plain: list[tuple[float, int]] = []
    try:
        window.open_plan(plan_path)
        app.processEvents()
        for _ in range(repeats):  # round robin: coarse, full (last: its surface stays), plain
            for name, loader in (("coarse", coarse_load), ("full", full_load)):
                compute.load_case = loader
                try:
                    samples[name].append(_open_until_surface(window, ct_dir))
                    steps[name].append(_longest_steps())
                finally:
                    compute.load_case = full_load
            rt = window.view3d.rt  # frames drawn on the view's render thread, waited for
            frames = []
            for _ in range(5):
                t0 = time.perf_counter()
                rt.call(rt.render_once)
                frames.append(time.perf_counter() - t0)
            plain.append(_plain_contour_on_ui_thread(window))
        error = _error_mm(window)
        size = rt.call(lambda stage: tuple(stage.window.GetSize()))
    finally:
        compute.load_case = full_load
        window.close()
    return {
        "samples": samples,
        "steps": steps,
        "plain": plain,
        "frames": frames,
        "size": size,
        "error": error,
    }


def run(quick: bool) -> Section:
    """Open the synthetic head in the window, full-resolution surface against the peers."""
    repeats = 1 if quick else 3
    shape = (100, 128, 128) if quick else (600, 512, 512)
    pixel_mm, slice_mm = (1.6, 1.8) if quick else (0.4, 0.3)
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-gui3d-") as tmp:
        t0 = time.perf_counter()
        plan_path = synthetic_head(Path(tmp), shape, pixel_mm, slice_mm)
        write_s = time.perf_counter() - t0
        got = _measure(Path(tmp) / "ct", plan_path, repeats, Path(tmp))
    samples = got["samples"]
    assert isinstance(samples, dict)
    dims = "x".join(str(d) for d in shape[::-1])
    error = got["error"]
    assert isinstance(error, tuple)
    err_max, err_p99 = float(error[0]), float(error[1])
    block, full_tri = str(error[2]), int(error[3])
    rows = []
    timing: dict[str, tuple[Timing, Timing, Timing]] = {}
    for name, label in (
        ("full", "ctdrill: worker, coarse first, then the finest the frame time affords"),
        ("coarse", f"peer: earlier coarse surface (strided to {OLD_MAX_DIM} a side)"),
    ):
        runs: list[Run] = samples[name]
        first = Timing.from_samples([r[0] for r in runs])
        settled = Timing.from_samples([r[1] for r in runs])
        stall = Timing.from_samples([r[2] for r in runs])
        timing[name] = (first, settled, stall)
        tris = f"{runs[-1][3]:,}" + (f" then {runs[-1][4]:,}" if runs[-1][4] != runs[-1][3] else "")
        st = got["steps"][name]  # type: ignore[index]
        view_step = Timing.from_samples([x[0] for x in st])
        other = max(st, key=lambda x: x[1])
        rows.append(
            [
                label,
                tris,
                first.fmt("s"),
                settled.fmt("s"),
                stall.fmt("ms"),
                view_step.fmt("ms"),
                f"{1e3 * other[1]:.0f} ms ({other[2]})",
            ]
        )
    plain_runs: list[tuple[float, int]] = got["plain"]  # type: ignore[assignment]
    plain = Timing.from_samples([p[0] for p in plain_runs])
    rows.append(
        [
            "peer: plain pyvista contour of every voxel + add_mesh, on the UI thread",
            f"{plain_runs[-1][1]:,}",
            "(after the load)",
            "",
            plain.fmt("ms"),
            plain.fmt("ms"),
            "",
        ]
    )
    frame = Timing.from_samples(got["frames"])  # type: ignore[arg-type]
    size = "x".join(str(s) for s in got["size"])  # type: ignore[attr-defined]
    full_stall = timing["full"][2].median_s
    ratio = plain.median_s / full_stall if full_stall > 0 else float("inf")
    shortfalls: list[str] = []
    if not quick and full_stall > GOAL_STALL_S:
        shortfalls.append(
            f"3D view: the longest UI stall while a {dims} series opens is "
            f"{1e3 * full_stall:.0f} ms, over the {1e3 * GOAL_STALL_S:.0f} ms goal"
        )
    if not quick and block != "1x1x1":
        shortfalls.append(
            f"3D view: on this software OpenGL the {dims} surface is drawn from {block} voxel "
            f"blocks, not every voxel ({full_tri:,} triangles would take ~"
            f"{frame.median_s * full_tri / max(samples['full'][-1][4], 1):.1f} s a frame)"
        )
    md = "\n\n".join(
        [
            __doc__.split("\n\n", 1)[1].strip() if __doc__ else "",
            f"{dims} voxels; {repeats} repeats (medians, [quartiles]); the series took "
            f"{write_s:.1f} s to write (not timed). 3D view {size} px.",
            table(
                [
                    "path",
                    "surface triangles",
                    "open to first surface",
                    "open to settled surface",
                    "longest UI stall",
                    "longest 3D-view step",
                    "longest other step (view)",
                ],
                rows,
            ),
            f"The settled surface was contoured on {block} (i x j x k) voxel blocks (block means: "
            f"every voxel counts; slices are merged only where thinner than the block). Its "
            f"vertices lie at most {err_max:.2f} mm (99 %: {err_p99:.2f} mm) from the nearest "
            f"vertex of the every-voxel surface ({full_tri:,} triangles), an upper bound of the "
            f"geometric error the blocks add. One frame of the 3D view with it: {frame.fmt('ms')}"
            " (the frame time the refinement aims below 100 ms). The longest UI stall is the "
            "largest gap between ticks of a 10 ms timer from the open to the settled surface; "
            "the step columns attribute the window's drawing steps (one per event-loop pass): "
            "the 3D view's (surface pieces, frames) and the slowest of the other views' in "
            "that open (slice canvases, depth plots), over the repeats.",
        ]
    )
    return Section(
        title="3D view: full-resolution bone surface (bench_gui3d)",
        markdown=md,
        shortfalls=tuple(shortfalls),
        headline=(
            headline_row(
                f"3D bone surface of a {dims} series: longest UI stall from open to the "
                "settled surface",
                timing["full"][2].fmt("ms"),
                f"{plain.fmt('ms')} (every-voxel pyvista contour on the UI thread)",
                f"{ratio:.0f}x",
                "< 100 ms",
            ),
            headline_row(
                f"3D bone surface of a {dims} series: open to first / settled surface",
                f"{timing['full'][0].fmt('s')} / {timing['full'][1].fmt('s')}",
                f"{timing['coarse'][1].fmt('s')} (strided, every 4th slice)",
                f"{timing['coarse'][1].median_s / timing['full'][1].median_s:.2f}",
            ),
        ),
    )

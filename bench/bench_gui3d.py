"""3D view: the bone surface of a large series at full resolution, with the UI thread free.

A synthetic 512 x 512 x 600 head (0.4 mm pixels, 0.3 mm slices: a skull shell and a U-shaped
mandible, 1200 HU in air) written as DICOM is opened in the real window under Xvfb (software
OpenGL, Mesa llvmpipe), with its plan. Measured from ``open_folder`` to the frame that draws the
last piece of the bone surface ("surface shown"): that time, and the longest the UI thread went
without serving a 10 ms heartbeat timer (the longest UI stall). ctdrill's path: in a worker the
series is loaded and contoured at every voxel (``vtkFlyingEdges3D`` on VTK's thread backend,
normals from the voxel gradient), the triangles cut into slab pieces of at most
``PIECE_TRIANGLES``; on the UI thread one piece is added and drawn per event-loop pass. Peers in
the same run and process: the earlier path (the same window with the coarse surface, strided to
160 samples a side: every 4th slice and pixel), and a plain ``pyvista`` contour of the loaded
volume at full resolution added with ``add_mesh(smooth_shading=True)`` and drawn on the UI
thread in one step (its stall is that step). The frame time is one ``render()`` of the 3D view
with the whole surface shown.
"""

from __future__ import annotations

import functools
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

from bench.report import Section, Timing, headline_row, table
from ctdrill.imaging.phantom.writer import write_series
from ctdrill.imaging.plan.types import Plan, save_plan

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


def _open_until_surface(window: object, ct_dir: Path) -> tuple[float, float, int]:
    """Open ``ct_dir`` in ``window`` and wait until the 3D view shows the whole surface.

    Returns (time to surface shown, longest gap between heartbeat ticks from the open to then,
    surface triangles)."""
    from PySide6.QtCore import QEventLoop, QTimer

    from ctdrill.app.gui.main_window import MainWindow

    assert isinstance(window, MainWindow)
    view = window.view3d
    ticks: list[float] = []
    ticker = QTimer()
    ticker.setInterval(TICK_MS)
    ticker.timeout.connect(lambda: ticks.append(time.perf_counter()))
    loop = QEventLoop()
    view.surface_shown.connect(loop.quit)
    QTimer.singleShot(300_000, loop.quit)
    ticker.start()
    t0 = time.perf_counter()
    window.open_folder(ct_dir)
    loop.exec()
    ticker.stop()
    view.surface_shown.disconnect(loop.quit)
    end = view.surface_shown_s
    if not np.isfinite(end):
        raise RuntimeError("the bone surface was not shown within 300 s")
    stall = float(np.max(np.diff([t0, *[t for t in ticks if t <= end], end])))
    n_tri = 0 if view.surface is None else int(view.surface.n_cells)
    return end - t0, stall, n_tri


def _plain_contour_on_ui_thread(window: object) -> float:
    """The plain peer: contour the open volume at every voxel with ``pyvista`` and draw it
    with ``add_mesh`` on the UI thread; returns the duration of that one step, s."""
    import pyvista as pv

    from ctdrill.app.gui.main_window import MainWindow

    assert isinstance(window, MainWindow)
    volume = window.doc.volume
    assert volume is not None
    plotter = window.view3d.plotter
    t0 = time.perf_counter()
    nk, nj, ni = volume.hu.shape
    grid = pv.ImageData(dimensions=(ni, nj, nk))
    grid.point_data["hu"] = np.asarray(volume.hu, dtype=np.float32).ravel()
    surf = grid.contour([300.0], scalars="hu", method="flying_edges")
    actor = plotter.add_mesh(surf, color="white", smooth_shading=True, opacity=0.45, render=False)
    plotter.render()
    dt = time.perf_counter() - t0
    plotter.remove_actor(actor, render=True)
    return dt


def _measure(ct_dir: Path, plan_path: Path, repeats: int, scratch: Path) -> dict[str, object]:
    from PySide6.QtCore import QSettings

    from ctdrill.app.gui import compute
    from ctdrill.app.gui.app import application, make_window

    app = application()
    settings = QSettings(str(scratch / "settings.ini"), QSettings.Format.IniFormat)
    window = make_window(settings)
    window.unattended = True
    full_load = compute.load_case
    coarse_load = functools.partial(compute.load_case, max_dim=OLD_MAX_DIM)
    samples: dict[str, list[tuple[float, float, int]]] = {"full": [], "coarse": []}
    plain: list[float] = []
    try:
        window.open_plan(plan_path)
        app.processEvents()
        for _ in range(repeats):  # round robin: full, coarse, plain
            for name, loader in (("full", full_load), ("coarse", coarse_load)):
                compute.load_case = loader
                try:
                    samples[name].append(_open_until_surface(window, ct_dir))
                finally:
                    compute.load_case = full_load
            plain.append(_plain_contour_on_ui_thread(window))
        compute.load_case = full_load
        _open_until_surface(window, ct_dir)
        plotter = window.view3d.plotter
        plotter.render()
        frames = []
        for _ in range(5):
            t0 = time.perf_counter()
            plotter.render()
            frames.append(time.perf_counter() - t0)
        size = tuple(plotter.window_size)
    finally:
        compute.load_case = full_load
        window.close()
    return {"samples": samples, "plain": plain, "frames": frames, "size": size}


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
    rows = []
    timing: dict[str, tuple[Timing, Timing, int]] = {}
    for name, label in (
        ("full", "ctdrill: every voxel, worker + pieces"),
        ("coarse", f"peer: earlier coarse surface (max_dim {OLD_MAX_DIM})"),
    ):
        runs = samples[name]
        shown = Timing.from_samples([r[0] for r in runs])
        stall = Timing.from_samples([r[1] for r in runs])
        timing[name] = (shown, stall, runs[-1][2])
        rows.append([label, f"{runs[-1][2]:,}", shown.fmt("s"), stall.fmt("ms")])
    plain = Timing.from_samples(got["plain"])  # type: ignore[arg-type]
    rows.append(
        [
            "peer: plain pyvista contour + add_mesh on the UI thread",
            f"{timing['full'][2]:,} (same level)",
            "(after the load)",
            plain.fmt("ms"),
        ]
    )
    frame = Timing.from_samples(got["frames"])  # type: ignore[arg-type]
    size = "x".join(str(s) for s in got["size"])  # type: ignore[attr-defined]
    full_stall = timing["full"][1].median_s
    ratio = plain.median_s / full_stall if full_stall > 0 else float("inf")
    shortfalls: tuple[str, ...] = ()
    if not quick and full_stall > GOAL_STALL_S:
        shortfalls = (
            f"3D view: the longest UI stall while a {dims} series opens is "
            f"{1e3 * full_stall:.0f} ms, over the {1e3 * GOAL_STALL_S:.0f} ms goal",
        )
    md = "\n\n".join(
        [
            __doc__.split("\n\n", 1)[1].strip() if __doc__ else "",
            f"{dims} voxels; {repeats} repeats (medians, [quartiles]); the series took "
            f"{write_s:.1f} s to write (not timed). 3D view {size} px.",
            table(["path", "surface triangles", "open to surface shown", "longest UI stall"], rows),
            f"One frame of the 3D view with the whole full-resolution surface: {frame.fmt('ms')} "
            "(what each step of a mouse rotation costs on this software OpenGL).",
        ]
    )
    return Section(
        title="3D view: full-resolution bone surface (bench_gui3d)",
        markdown=md,
        shortfalls=shortfalls,
        headline=(
            headline_row(
                f"3D bone surface of a {dims} series, every voxel: longest UI stall from "
                "open to surface shown",
                timing["full"][1].fmt("ms"),
                f"{plain.fmt('ms')} (pyvista contour on the UI thread)",
                f"{ratio:.0f}x",
                "< 100 ms",
            ),
            headline_row(
                f"3D bone surface of a {dims} series: open to surface shown",
                timing["full"][0].fmt("s"),
                f"{timing['coarse'][0].fmt('s')} (coarse, every 4th slice)",
                f"{timing['coarse'][0].median_s / timing['full'][0].median_s:.2f}",
            ),
        ),
    )

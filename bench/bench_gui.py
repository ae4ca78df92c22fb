"""Desktop window: time from choosing a DICOM folder to the first drawn 3D frame, and the 3D
view's frame time.

Cases: the bundled demo phantom (``assets/demo``: 80 x 100 x 80 voxels of 0.4 mm) and a
synthetic 512 x 512 x 300 series (0.3 mm voxels, a bone bar with a cortical shell and a canal)
written with ``ctdrill.imaging.phantom.writer.write_series``. "Open to first frame" runs the
window's own path: in a worker thread list the series, load it, contour the bone surface; on the UI
thread then reslice the four views, plan the path (worker), build the scene and render. The peers
are the same steps called headless one by one in the same run, so the breakdown shows where the
time goes. The frame time is one render of the window's 3D view (on its render thread) at its
on-screen size, without and with 4x MSAA (the peer), on the software OpenGL of Xvfb (Mesa
llvmpipe) when run by ``make bench``.
"""

from __future__ import annotations

import gc
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bench.report import Section, Timing, figure_path, table
from ctdrill.imaging import load_series
from ctdrill.imaging.dicom.series import list_series
from ctdrill.imaging.phantom.writer import write_series
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.plan.write import save_plan

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "assets" / "demo"
FIGURE_NAME = "gui_open.png"


def synthetic_case(
    out_dir: Path,
    shape_kji: tuple[int, int, int],
    spacing_mm: float,
    *,
    canal_below_top_mm: float | None = None,
) -> Path:
    """Write a bone-bar series and its plan into ``out_dir``; returns the plan path.

    The bar runs along x (patient left), elliptical in (y, z): cortical 1500 HU (1.5 mm),
    trabecular 700 HU, a canal of radius 1.2 mm (30 HU) 4 mm below the bar's centre, or
    ``canal_below_top_mm`` below its top (a dental depth). The drill enters 1 mm above the
    top and ends 2.5 mm above the canal's centre.
    """
    nk, nj, ni = shape_kji
    half = np.array([ni, nj, nk]) * spacing_mm / 2.0
    affine = np.eye(4)
    affine[:3, :3] *= spacing_mm
    affine[:3, 3] = -half
    z = -half[2] + spacing_mm * np.arange(nk)
    y = -half[1] + spacing_mm * np.arange(nj)
    zz, yy = np.meshgrid(z, y, indexing="ij")
    semi_y, semi_z = 0.3 * half[1], 0.6 * half[2]
    r = np.hypot(yy / semi_y, zz / semi_z)
    inner = np.hypot(yy / (semi_y - 1.5), zz / (semi_z - 1.5))
    plane = np.full((nk, nj), -1000, dtype=np.int16)
    plane[r <= 1.0] = 1500
    plane[inner <= 1.0] = 700
    canal_z = -4.0 if canal_below_top_mm is None else semi_z - canal_below_top_mm
    plane[np.hypot(yy, zz - canal_z) <= 1.2] = 30
    hu = np.broadcast_to(plane[:, :, None], (nk, nj, ni))
    write_series(out_dir / "ct", np.ascontiguousarray(hu), affine)
    top = semi_z
    plan = Plan(
        entry_lps=np.array([0.0, 0.0, top + 1.0]),
        target_lps=np.array([0.0, 0.0, canal_z + 2.5]),
        landmarks=(
            CanalLandmark(
                name="canal",
                points_lps=np.array([[-half[0] + 1, 0.0, canal_z], [half[0] - 1, 0.0, canal_z]]),
                radius_mm=1.2,
            ),
        ),
        name="synthetic",
    )
    save_plan(plan, out_dir / "plan.json")
    return out_dir / "plan.json"


def _open_to_first_frame(
    window: object, ct_dir: Path, repeats: int, settle_ms: int = 500
) -> tuple[Timing, float]:
    """Median time from ``open_folder`` to the 3D view's first frame with the case drawn, and
    the longest the UI thread went without serving a 5 ms timer (from the open until 0.5 s
    after the frame), median over the repeats, s."""
    from PySide6.QtCore import QEventLoop, QTimer

    from ctdrill.app.gui.main_window import MainWindow

    assert isinstance(window, MainWindow)
    samples = []
    stalls = []
    ticks: list[float] = []
    ticker = QTimer()
    ticker.setInterval(5)
    ticker.timeout.connect(lambda: ticks.append(time.perf_counter()))
    for _ in range(repeats):
        ticks.clear()
        loop = QEventLoop()
        window.path_updated.connect(loop.quit)
        QTimer.singleShot(120_000, loop.quit)
        ticker.start()
        t0 = time.perf_counter()
        window.open_folder(ct_dir)
        loop.exec()
        window.path_updated.disconnect(loop.quit)
        settle = QEventLoop()
        QTimer.singleShot(settle_ms, settle.quit)
        settle.exec()
        ticker.stop()
        samples.append(window.view3d.last_frame_s - t0)
        stalls.append(float(np.max(np.diff([t0, *ticks]))))
    return Timing.from_samples(samples), float(np.median(stalls))


def _timed(fn: Callable[[], object], repeats: int, *, warmup: int = 1) -> Timing:
    """Time ``repeats`` calls after ``warmup`` ones, with one garbage collection before the
    block and the collector paused during it (with the window's Qt and VTK objects alive, a
    collection before every call would cost more than most of the calls)."""
    for _ in range(warmup):
        fn()
    gc.collect()
    gc.disable()
    try:
        samples = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            samples.append(time.perf_counter() - t0)
    finally:
        gc.enable()
    return Timing.from_samples(samples)


def _measure(
    name: str,
    ct_dir: Path,
    plan_path: Path,
    repeats: int,
    scratch: Path,
    frame_repeats: int,
    settle_ms: int,
) -> dict[str, object]:
    from PySide6.QtCore import QSettings

    from ctdrill.app.gui import compute
    from ctdrill.app.gui.app import application, make_window
    from ctdrill.app.gui.results import compute_path_view

    app = application()
    settings = QSettings(str(scratch / f"settings-{name}.ini"), QSettings.Format.IniFormat)
    window = make_window(settings)
    window.unattended = True
    window.ask_series = True
    try:
        window.open_plan(plan_path)
        app.processEvents()
        first, stall_s = _open_to_first_frame(window, ct_dir, repeats, settle_ms=settle_ms)
        volume = load_series(ct_dir)
        plan = load_plan(plan_path)
        steps = {
            "list series": _timed(lambda: list_series(ct_dir), repeats),
            "load series": _timed(lambda: load_series(ct_dir), repeats),
            "bone surface": _timed(
                lambda: compute.volume_surface(volume, max_triangles=compute.FIRST_TRIANGLES),
                repeats,
            ),
            "four slices": _timed(lambda: compute.slice_views(volume, plan), repeats),
            "plan path": _timed(lambda: compute_path_view(volume, plan), repeats),
        }
        rt = window.view3d.rt  # each frame drawn on the view's render thread, waited for

        def render() -> None:
            rt.call(rt.render_once)

        frame = _timed(render, frame_repeats, warmup=2)
        rt.call(lambda stage: stage.window.SetMultiSamples(4))
        frame_msaa = _timed(render, frame_repeats, warmup=2)
        rt.call(lambda stage: stage.window.SetMultiSamples(0))
        size = rt.call(lambda stage: tuple(stage.window.GetSize()))
        n_tri = 0 if window.view3d.surface is None else int(window.view3d.surface.n_cells)
    finally:
        window.close()
    return {
        "name": name,
        "dims": "x".join(str(d) for d in volume.dims),
        "first": first,
        "stall_s": stall_s,
        "steps": steps,
        "frame": frame,
        "frame_msaa": frame_msaa,
        "size": size,
        "triangles": n_tri,
    }


def _figure(results: list[dict[str, object]]) -> str:
    fig = Figure(figsize=(7.0, 3.2))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    labels = [str(r["name"]) for r in results]
    bottom = np.zeros(len(results))
    for step in ("list series", "load series", "bone surface", "four slices", "plan path"):
        vals = np.array([r["steps"][step].median_s for r in results])  # type: ignore[index]
        ax.barh(labels, vals, left=bottom, label=step)
        bottom += vals
    firsts = np.array([r["first"].median_s for r in results])  # type: ignore[attr-defined]
    ax.scatter(firsts, labels, color="black", marker="|", s=400, label="open to first frame")
    ax.set_xlabel("seconds (median)")
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title("GUI: open a series, headless steps vs the window's first 3D frame", fontsize=9)
    fig.tight_layout()
    out = figure_path(FIGURE_NAME)
    fig.savefig(out, dpi=110)
    return f"benchmarks/{FIGURE_NAME}"


def run(quick: bool) -> Section:
    """Benchmark the window on the demo and a synthetic large series."""
    repeats = 2 if quick else 5
    frames = 5 if quick else 20
    settle = 200 if quick else 500  # ms of stall watching after the first frame
    big_shape = (60, 128, 128) if quick else (300, 512, 512)
    results = []
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-gui-") as tmp:
        results.append(
            _measure("demo", DEMO / "ct", DEMO / "plan.json", repeats, Path(tmp), frames, settle)
        )
        t0 = time.perf_counter()
        plan_path = synthetic_case(Path(tmp), big_shape, 0.3)
        write_s = time.perf_counter() - t0
        label_case = "synthetic " + "x".join(str(d) for d in big_shape[::-1])
        results.append(
            _measure(label_case, Path(tmp) / "ct", plan_path, repeats, Path(tmp), frames, settle)
        )
    rows = []
    for r in results:
        steps = r["steps"]
        assert isinstance(steps, dict)
        total = sum(t.median_s for t in steps.values())
        first = r["first"]
        assert isinstance(first, Timing)
        rows.append(
            [
                r["name"],
                r["dims"],
                first.fmt("s"),
                f"{1e3 * float(r['stall_s']):.0f} ms",  # type: ignore[arg-type]
                f"{total:.3g} s",
                *(steps[k].fmt("ms") for k in steps),
            ]
        )
    frame_rows = []
    for r in results:
        f0, f4 = r["frame"], r["frame_msaa"]
        assert isinstance(f0, Timing) and isinstance(f4, Timing)
        frame_rows.append(
            [
                r["name"],
                r["triangles"],
                "x".join(str(s) for s in r["size"]),  # type: ignore[attr-defined]
                f0.fmt("ms"),
                f4.fmt("ms"),
                f"{f4.median_s / f0.median_s:.2f}",
            ]
        )
    md = "\n\n".join(
        [
            __doc__.split("\n\n", 1)[1].strip() if __doc__ else "",
            f"{repeats} repeats; the synthetic series took {write_s:.1f} s to write (not timed).",
            table(
                [
                    "case",
                    "dims",
                    "open to first 3D frame",
                    "longest UI stall",
                    "sum of headless steps",
                    "list series",
                    "load series",
                    "bone surface",
                    "four slices",
                    "plan path",
                ],
                rows,
            ),
            table(
                [
                    "case",
                    "surface triangles",
                    "3D view px",
                    "frame, no MSAA (default)",
                    "frame, 4x MSAA (peer)",
                    "MSAA / default",
                ],
                frame_rows,
            ),
            "The difference between the first column and the sum of the headless steps is the "
            "UI thread's share (scene build, slice and plot drawing, the render) plus queueing. "
            "The longest UI stall is the largest gap between ticks of a 5 ms timer on the UI "
            "thread during the open (median over the repeats). The window's drawing runs in a "
            "step queue, one step per event-loop pass (each slice canvas, the depth plots, the "
            "scene build, the 3D frame), so the stall is the longest single step plus what "
            "falls due with it, not the sum of one update's redraws; the goal is 100 ms.",
        ]
    )
    return Section(title="Desktop window (bench_gui)", markdown=md, figures=(_figure(results),))

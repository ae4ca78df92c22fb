"""Start-up: ``ctdrill --help`` against a bare interpreter, and what a one-plan export imports.

Each figure is the median (inter-quartile range) of fresh processes started round-robin with
the peers, so drifting load on the shared VM hits all alike. The floor is ``python -c pass``
(the interpreter and ``site``, which in a development checkout includes the editable-install
finder); ``ctdrill --help`` builds the whole parser (every subcommand's ``register``) and prints
it. Goal (issue 13): under 0.15 s on this machine, loading none of NumPy, SciPy, pydicom,
matplotlib, VTK, pyvista, PySide6 (``tests/test_cli.py`` checks the module list).

An export as a fresh process (issue 37): ``ctdrill export`` of the demo's CT and plan (force.png
included, once with ``--no-plot``, and once with ``CTDRILL_NO_JIT=1``: every kernel switched
off), round-robin with its floor, a fresh
``python -c "import numpy, pydicom"`` (the least an export of a DICOM series must import);
goal: at most :data:`EXPORT_GOAL_X` times it. On the loaded shared machine the ratio is taken
on CPU time (user + sys of the child, from ``getrusage``), which waiting for a core does not
inflate; the wall ratio is given beside it. The timed processes run with bytecode writing on
(``PYTHONDONTWRITEBYTECODE`` removed), so the warm-up run leaves ctdrill's ``.pyc`` files as an
installed wheel has them; otherwise each run would compile ctdrill's ~160 modules from source
while NumPy's and pydicom's come precompiled.

The one-plan export is ``ctdrill demo`` (the bundled 80 x 80 x 100 phantom, one plan) run
with ``python -X importtime``: the import time is the sum of every module's own ("self") time
from that log, grouped by top-level package; the rest of the wall time is the interpreter's
start and the work (load, sample, profile, clearance, CSV/JSON, the plot).
"""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

from bench.report import Section, Timing, table

ROOT = Path(__file__).resolve().parents[1]
HELP_GOAL_S = 0.15
#: Goal for ``ctdrill export`` as a fresh process: at most this many times the import floor.
EXPORT_GOAL_X = 2.0
DEMO = ROOT / "assets" / "demo"
FLOOR = "python -c 'import numpy, pydicom'"
EXPORT = "ctdrill export (demo, one plan)"
EXPORT_NO_PLOT = "ctdrill export --no-plot (demo, one plan)"
EXPORT_NO_JIT = "CTDRILL_NO_JIT=1 ctdrill export (demo, one plan: every kernel off)"


def _env() -> dict[str, str]:
    """The environment of the timed processes: this checkout's ``ctdrill`` first."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # .pyc files as an installed package has them
    return env


def _child_cpu_s() -> float:
    """User + system CPU seconds of every waited-for child so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def time_commands(
    commands: dict[str, list[str]], repeats: int, *, warmup: bool = True
) -> dict[str, Timing]:
    """Wall time of each command (a fresh process each run), started round-robin."""
    return time_commands_cpu(commands, repeats, warmup=warmup)[0]


def time_commands_cpu(
    commands: dict[str, list[str]], repeats: int, *, warmup: bool = True
) -> tuple[dict[str, Timing], dict[str, Timing]]:
    """Wall and CPU (user + sys) time of each command (a fresh process each run), started
    round-robin."""
    env = _env()
    walls: dict[str, list[float]] = {name: [] for name in commands}
    cpus: dict[str, list[float]] = {name: [] for name in commands}
    for cmd in commands.values() if warmup else ():  # warm the page cache and .pyc files
        subprocess.run(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, check=True)
    for _ in range(repeats):
        for name, cmd in commands.items():
            c0, t0 = _child_cpu_s(), time.perf_counter()
            subprocess.run(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, check=True)
            walls[name].append(time.perf_counter() - t0)
            cpus[name].append(_child_cpu_s() - c0)
    return (
        {name: Timing.from_samples(values) for name, values in walls.items()},
        {name: Timing.from_samples(values) for name, values in cpus.items()},
    )


def import_self_times_s(log: str) -> dict[str, float]:
    """Seconds of import spent in each top-level package, from a ``-X importtime`` log.

    Sums every module's own time ("self", the first column), so the groups partition the
    whole import time; ``ctdrill.x.y`` counts as ``ctdrill``.
    """
    out: dict[str, float] = defaultdict(float)
    for line in log.splitlines():
        if not line.startswith("import time:"):
            continue
        parts = line[len("import time:") :].split("|")
        if len(parts) != 3 or not parts[0].strip().isdigit():
            continue  # the header line
        name = parts[2].strip()
        out[name.split(".")[0]] += int(parts[0]) * 1e-6
    return dict(out)


def demo_phases(repeats: int, *, warmup: bool = True) -> tuple[Timing, Timing, dict[str, float]]:
    """Wall and import time of ``ctdrill demo`` under ``-X importtime``; imports by package."""
    env = _env()
    walls, imports = [], []
    groups: dict[str, list[float]] = defaultdict(list)
    skip = 1 if warmup else 0  # a warm-up run fills the page cache and is not counted
    for _ in range(repeats + skip):
        with tempfile.TemporaryDirectory(prefix="ctdrill-bench-") as tmp:
            cmd = [sys.executable, "-X", "importtime", "-m", "ctdrill.app.cli", "demo"]
            t0 = time.perf_counter()
            proc = subprocess.run(
                [*cmd, "--out", str(Path(tmp) / "out")],
                cwd=ROOT,
                env=env,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                text=True,
                check=True,
            )
            wall = time.perf_counter() - t0
        by_package = import_self_times_s(proc.stderr)
        walls.append(wall)
        imports.append(sum(by_package.values()))
        for key, seconds in by_package.items():
            groups[key].append(seconds)
    walls, imports = walls[skip:], imports[skip:]
    medians = {k: statistics.median(v[skip:]) for k, v in groups.items() if v[skip:]}
    return Timing.from_samples(walls), Timing.from_samples(imports), medians


def _rows(timings: dict[str, Timing], floor: Timing) -> Sequence[Sequence[object]]:
    return [
        (
            f"`{name}`",
            t.fmt("ms"),
            f"{(t.median_s - floor.median_s) * 1e3:.0f} ms",
            f"{t.min_s * 1e3:.0f} ms",
        )
        for name, t in timings.items()
    ]


def run(quick: bool) -> Section:
    """Time the peers and the demo export; state the goal."""
    py = sys.executable
    commands = {
        "python -c pass": [py, "-c", "pass"],
        "python -c 'import numpy'": [py, "-c", "import numpy"],
        "ctdrill --help": [py, "-m", "ctdrill.app.cli", "--help"],
        "ctdrill export --help": [py, "-m", "ctdrill.app.cli", "export", "--help"],
    }
    repeats = 2 if quick else 20
    timings = time_commands(commands, repeats, warmup=not quick)
    floor = timings["python -c pass"]
    help_t = timings["ctdrill --help"]
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-export-") as tmp:
        export_cmd = [py, "-m", "ctdrill.app.cli", "export", "--ct", str(DEMO / "ct")]
        export_cmd += ["--plan", str(DEMO / "plan.json"), "--out", str(Path(tmp) / "out")]
        exports, export_cpu = time_commands_cpu(
            {
                FLOOR: [py, "-c", "import numpy, pydicom"],
                EXPORT: export_cmd,
                EXPORT_NO_PLOT: [*export_cmd, "--no-plot"],
                EXPORT_NO_JIT: ["env", "CTDRILL_NO_JIT=1", *export_cmd],
            },
            2 if quick else 9,
            warmup=not quick,
        )
    load = 0.5 * (load_before + os.getloadavg()[0])
    import_floor, floor_cpu = exports[FLOOR], export_cpu[FLOOR]
    export_t, cpu_t = exports[EXPORT], export_cpu[EXPORT]
    export_x = cpu_t.median_s / floor_cpu.median_s
    wall_x = export_t.median_s / import_floor.median_s
    no_plot_x = export_cpu[EXPORT_NO_PLOT].median_s / floor_cpu.median_s
    no_jit_x = export_cpu[EXPORT_NO_JIT].median_s / floor_cpu.median_s
    wall, imports, by_package = demo_phases(1 if quick else 5, warmup=not quick)
    start_s = floor.median_s
    rest_s = wall.median_s - imports.median_s - start_s
    top = sorted(by_package.items(), key=lambda kv: -kv[1])[:8]

    md = [
        f"{repeats} runs of each command, round-robin (median [IQR], and the median above "
        "the `python -c pass` floor); every process may write its `.pyc` files "
        "(`PYTHONDONTWRITEBYTECODE` unset, as for an installed wheel), so after the warm-up "
        "run no module is compiled from source:",
        "",
        table(["command", "wall", "above the floor", "fastest run"], _rows(timings, floor)),
        "",
        f"`ctdrill --help`: median {help_t.median_s * 1e3:.0f} ms against the goal of "
        f"{HELP_GOAL_S * 1e3:.0f} ms; {(help_t.median_s - floor.median_s) * 1e3:.0f} ms of it "
        "is ctdrill's (argparse, the command modules and the four error modules), the rest "
        "is the interpreter's start.",
        "",
        f"An export as a fresh process, {export_t.repeats} runs round-robin with its floor "
        f"(load average {load:.1f} on the 2 cores; CPU = user + sys of the process):",
        "",
        table(
            ["command", "CPU", "CPU / floor", "wall", "wall / floor"],
            [
                (
                    f"`{name}`",
                    export_cpu[name].fmt("ms"),
                    f"{export_cpu[name].median_s / floor_cpu.median_s:.2f}",
                    exports[name].fmt("ms"),
                    f"{exports[name].median_s / import_floor.median_s:.2f}",
                )
                for name in (FLOOR, EXPORT, EXPORT_NO_PLOT, EXPORT_NO_JIT)
            ],
        ),
        "",
        f"Goal: the export <= {EXPORT_GOAL_X:g} x its import floor; measured "
        f"{export_x:.2f} x in CPU time ({wall_x:.2f} x wall) with force.png, "
        f"{no_plot_x:.2f} x with `--no-plot`. force.png is drawn with Pillow "
        "(`app/raster_plot.py`, no matplotlib import). A one-plan export does not load numba "
        "(`ctdrill.jit.job`): every kernel it uses gives the compiled bits without it (the "
        "NumPy paths of the sampler, arch, lip, profile, segments and walls, held bit for bit "
        "by tests; the clearance rows' kernel run as its own Python function), so its files "
        "are byte for byte those of a process that loaded the kernels "
        "(`tests/app/test_export_imports.py`). With every kernel switched off "
        f"(`CTDRILL_NO_JIT=1`: the clearance rows by golden section) {no_jit_x:.2f} x. What "
        "lies above the floor: ctdrill's own modules, reading the series, the work on the "
        "NumPy paths and the plot.",
        "",
        f"One-plan export (`ctdrill demo`, {wall.repeats} runs under `-X importtime`): wall "
        f"{wall.fmt('s')}, of which imports {imports.fmt('s')}, the interpreter's start "
        f"about {start_s:.2f} s (the floor above) and the work about {rest_s:.2f} s.",
        "",
        "Import time by top-level package (median of the runs; own time of every module):",
        "",
        table(["package", "import time"], [(f"`{k}`", f"{v * 1e3:.0f} ms") for k, v in top]),
        "",
        "Every package here is used by the export (pydicom to read the series, Pillow for "
        "`force.png`; no numba: a process that loads the kernels gets "
        "`scipy.linalg.cython_blas` for numba's BLAS check without the `scipy.linalg` "
        "package). The CT is sampled with `map_coordinates`' bits "
        "without `scipy.ndimage` (`tests/app/test_export_imports.py` checks the module "
        "list); pydicom itself imports `requests` (its data-download module) on "
        "`import pydicom`.",
    ]
    shortfalls = []
    if help_t.median_s > HELP_GOAL_S:
        shortfalls.append(
            f"`ctdrill --help` took {help_t.median_s * 1e3:.0f} ms (median), over the "
            f"{HELP_GOAL_S * 1e3:.0f} ms goal; the bare interpreter took "
            f"{floor.median_s * 1e3:.0f} ms in the same run."
        )
    if export_x > EXPORT_GOAL_X:
        shortfalls.append(
            f"`ctdrill export` (one plan, force.png) as a fresh process took {export_x:.1f} x "
            f"the CPU time of a fresh `import numpy, pydicom` ({cpu_t.median_s:.2f} s against "
            f"{floor_cpu.median_s:.2f} s; wall {export_t.median_s:.2f} s, {wall_x:.1f} x; goal "
            f"<= {EXPORT_GOAL_X:g} x) at load {load:.1f}; with `--no-plot` {no_plot_x:.1f} x: "
            "ctdrill's modules, the series' read, the work on the NumPy paths and the plot lie "
            f"above the goal (numba is not loaded); with every kernel off {no_jit_x:.1f} x."
        )
    if imports.median_s > rest_s:
        shortfalls.append(
            f"`ctdrill demo` spent {imports.median_s:.2f} s importing against about "
            f"{rest_s:.2f} s of work."
        )
    return Section(
        title="Start-up: `ctdrill --help` and a one-plan export's imports",
        markdown="\n".join(md),
        shortfalls=tuple(shortfalls),
    )

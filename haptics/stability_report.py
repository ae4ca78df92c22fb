"""The numbers of docs/haptics-stability.md, computed.

Run ``python -m ctdrill.haptics.stability_report`` to print them.

:func:`coupling_report` evaluates the z-plane poles of the linearised loop
(:mod:`ctdrill.haptics.stability`) at the coupling's operating points and simulates the coupled
master (:mod:`ctdrill.haptics.stability_sim`); :func:`report_markdown` renders the tables the
document carries between its ``<!-- stability-report -->`` markers (a test checks they agree).
"""

from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

from ctdrill.haptics.physics import HAND_DAMPING_N_S_PER_MM, HAND_STIFFNESS_N_PER_MM
from ctdrill.haptics.renderer import (
    PEAK_FORCE_N,
    RELEASE_DAMPING_N_S_PER_MM,
    STOP_GLIDE_MM_S,
    STOP_WALL_DAMPING_N_S_PER_MM,
    STOP_WALL_N_PER_MM,
)
from ctdrill.haptics.stability import (
    Loop,
    colgate_terms,
    damping_limit_n_s_per_mm,
    dominant_pole,
    release_excursion_bound_mm,
    release_speed_bound_mm_s,
    spectral_radius,
    stiffness_limit_n_per_mm,
)
from ctdrill.haptics.stability_sim import release_account, simulate_push
from ctdrill.haptics.tick import TICK_S
from ctdrill.model.cutting import (
    DEFAULT_DAMPING_N_S_PER_MM,
    DEFAULT_STIFFNESS_N_PER_MM,
    MASTER_KP_PER_S2,
    MASTER_MASS_KG,
)

#: The coupling before this analysis: the paper's position gain on the master mass (Table 4).
PREVIOUS_STIFFNESS_N_PER_MM = MASTER_MASS_KG * MASTER_KP_PER_S2 / 1000.0
#: The stop wall before the rigid one: 20 N/mm, no damper of its own, anchored where the master
#: met it (no glide).
PREVIOUS_WALL_N_PER_MM = 20.0
#: Operator forces simulated for the passivity table, N (0 to the device's peak).
REPORT_PUSHES_N = (0.0, 4.0, 10.0, 30.0, 60.0, 70.0, PEAK_FORCE_N)
#: The hand push whose offset past the stopped drill the issue quotes, N.
OFFSET_PUSH_N = 30.0
#: The simulator's hand in FEED mode (:mod:`ctdrill.haptics.emulator`), N/mm and N s/mm.
FEED_HAND = (HAND_STIFFNESS_N_PER_MM, HAND_DAMPING_N_S_PER_MM)
#: Cutting operating points: ``S0`` (N) with ``Ke = 0.25`` per (mm/s).
CUT_S0_N = (2.0, 8.0, 20.0)
CUT_KE = 0.25
#: Hands that let go (the slab of :func:`simulate_push`, S0 = 4 N): while cutting (the stop
#: 20 mm deep, let go at 0.25 s) and at the stop (1 mm deep, let go at 0.5 s), N.
RELEASE_CUTTING_N = (10.0, 20.0, 40.0)
RELEASE_AT_STOP_N = (10.0, 20.0, 40.0, 60.0, 70.0)
RELEASE_CUTTING = (20.0, 0.25)
RELEASE_AT_STOP = (1.0, 0.5)
#: Each release is simulated this long (1 s after the hand let go at the stop).
RELEASE_RUN_S = 1.5


def _pole_row(name: str, loop: Loop) -> dict[str, Any]:
    pole = dominant_pole(loop)
    k = loop.stiffness_n_per_mm
    limit = stiffness_limit_n_per_mm(loop) if k > 0.0 else None
    b_limit = damping_limit_n_s_per_mm(loop)
    return {
        "operating point": name,
        "stiffness_n_per_mm": k,
        "damping_n_s_per_mm": loop.damping_n_s_per_mm,
        "spectral_radius": spectral_radius(loop),
        "pole_hz": pole["frequency_hz"],
        "damping_ratio": pole["damping_ratio"],
        "limit_n_per_mm": limit,
        "margin": None if limit is None else limit / k,
        "damping_limit_n_s_per_mm": b_limit,
        "damping_margin": b_limit / loop.damping_n_s_per_mm,
    }


def _release_row(push_n: float, at_stop: bool) -> dict[str, Any]:
    """A hand letting go of ``push_n``, with the release damper and without (before it)."""
    stop_mm, release_s = RELEASE_AT_STOP if at_stop else RELEASE_CUTTING
    runs = {}
    for name, b_release in (("before", 0.0), ("now", RELEASE_DAMPING_N_S_PER_MM)):
        run = simulate_push(
            push_n,
            stop_depth_mm=stop_mm,
            release_at_s=release_s,
            duration_s=RELEASE_RUN_S,
            release_damping_n_s_per_mm=b_release,
        )
        runs[name] = (run, release_account(run, release_s))
    now_run, now = runs["now"]
    before = runs["before"][1]
    damping = DEFAULT_DAMPING_N_S_PER_MM + RELEASE_DAMPING_N_S_PER_MM
    if now.at_stop:
        damping += STOP_WALL_DAMPING_N_S_PER_MM
    speed_bound = release_speed_bound_mm_s(now.push_n, damping)
    return {
        "where": "at the stop" if now.at_stop else "cutting",
        "push_n": now.push_n,
        "before_speed_mm_s": before.peak_back_mm_s,
        "before_behind_mm": before.behind_mm,
        "before_travel_end": before.travel_end,
        "speed_mm_s": now.peak_back_mm_s,
        "speed_bound_mm_s": speed_bound,
        "behind_mm": now.behind_mm,
        "behind_bound_mm": release_excursion_bound_mm(speed_bound, RELEASE_DAMPING_N_S_PER_MM),
        "final_speed_mm_s": now.final_speed_mm_s,
        "rest_mm": now.rest_mm,
        "travel_end": now.travel_end,
        "stored_j": now.stored_j,
        "returned_j": now.returned_j,
        "min_energy_in_j": float(now_run.energy_in_j.min()),
    }


def _hand_offset_mm(
    stiffness_n_per_mm: float, wall: tuple[float, float, float], release_n_s_per_mm: float
) -> float:
    """Where a 30 N hand holds the master past the stop once settled, mm; ``wall`` is the stop
    wall's stiffness (N/mm), damping (N s/mm) and glide speed (mm/s), ``release_n_s_per_mm``
    the release damper (0 for the designs before it)."""
    run = simulate_push(
        OFFSET_PUSH_N,
        stiffness_n_per_mm=stiffness_n_per_mm,
        stop_wall_n_per_mm=wall[0],
        stop_wall_damping_n_s_per_mm=wall[1],
        stop_glide_mm_s=wall[2],
        release_damping_n_s_per_mm=release_n_s_per_mm,
    )
    return float(run.master_mm[-1]) - 1.0


def max_past_stopped_mm(run: Any) -> float:
    """The hand's largest offset past the drill over the ticks the front stood at the stop,
    mm (0: it never got there)."""
    stopped = run.front_mm >= run.front_mm.max() - 1e-12
    if not math.isfinite(run.stop_reached_s) or not stopped.any():
        return 0.0
    return float(max(0.0, (run.master_mm[stopped] - run.front_mm[stopped]).max()))


def coupling_report() -> dict[str, Any]:
    """Poles, margins, Colgate's terms and the simulated passivity of the coupling."""
    k = DEFAULT_STIFFNESS_N_PER_MM
    b = DEFAULT_DAMPING_N_S_PER_MM
    wall = k + STOP_WALL_N_PER_MM
    wall_b = b + STOP_WALL_DAMPING_N_S_PER_MM
    old_wall = k + PREVIOUS_WALL_N_PER_MM
    rows = [
        _pole_row("at rest (front fixed, F < S0)", Loop(k, b)),
        _pole_row("at the stop (coupling + wall)", Loop(wall, wall_b)),
        _pole_row(
            "at the stop, FEED hand (5 N/mm, 0.05 N s/mm)",
            Loop(
                wall,
                wall_b,
                hand_stiffness_n_per_mm=FEED_HAND[0],
                hand_damping_n_s_per_mm=FEED_HAND[1],
            ),
        ),
        *(
            _pole_row(
                f"cutting, S0 = {s0:g} N (c = S0 Ke = {s0 * CUT_KE:g} N s/mm)",
                Loop(k, b, material_damping_n_s_per_mm=s0 * CUT_KE),
            )
            for s0 in CUT_S0_N
        ),
        _pole_row("at the stop without the wall's damper", Loop(wall, b)),
        _pole_row(
            f"previous wall ({PREVIOUS_WALL_N_PER_MM:g} N/mm), at the stop", Loop(old_wall, b)
        ),
        _pole_row(
            f"previous {PREVIOUS_STIFFNESS_N_PER_MM:g} N/mm coupling, at the stop",
            Loop(PREVIOUS_STIFFNESS_N_PER_MM + PREVIOUS_WALL_N_PER_MM, b),
        ),
        _pole_row("at the stop, semi-implicit Euler plant", Loop(wall, wall_b, zoh_plant=False)),
        _pole_row(
            "let go, in contact (coupling + release damper)",
            Loop(k, b + RELEASE_DAMPING_N_S_PER_MM),
        ),
        _pole_row(
            "let go at the stop (coupling + wall + release damper)",
            Loop(wall, wall_b + RELEASE_DAMPING_N_S_PER_MM),
        ),
        _pole_row(
            "let go, out of contact (release damper alone)", Loop(0.0, RELEASE_DAMPING_N_S_PER_MM)
        ),
    ]
    wall_limit = rows[1]["limit_n_per_mm"]
    pushes = []
    for push in REPORT_PUSHES_N:
        run = simulate_push(push)
        pushes.append(
            {
                "push_n": push,
                "final_force_n": float(run.force_n[-1]),
                "max_force_n": float(run.force_n.max()),
                "hand_past_drill_mm": float(run.master_mm[-1] - run.front_mm[-1]),
                "max_past_drill_mm": max_past_stopped_mm(run),
                "settled_range_mm": run.settled_range_mm(),
                "min_energy_in_j": float(run.energy_in_j.min()),
                "min_dissipated_j": None if run.clipped else float(run.dissipated_j.min()),
                "glide_j": float(run.glide_j[-1]),
                "clipped": run.clipped,
            }
        )
    beyond = []
    for factor in (0.8, 1.25, 2.0):
        # the wall's own loop (no release damper), with and without friction; then as rendered
        for coulomb, release in ((0.0, 0.0), (None, 0.0), (None, RELEASE_DAMPING_N_S_PER_MM)):
            run = simulate_push(
                OFFSET_PUSH_N,
                stiffness_n_per_mm=factor * wall_limit - STOP_WALL_N_PER_MM,
                coulomb_n=coulomb,
                release_damping_n_s_per_mm=release,
            )
            beyond.append(
                {
                    "factor": factor,
                    "friction": "none" if coulomb == 0.0 else "1.0 N",
                    "release_n_s_per_mm": release,
                    "settled_range_mm": run.settled_range_mm(),
                    "min_energy_in_j": float(run.energy_in_j.min()),
                    "min_dissipated_j": float(run.dissipated_j.min()),
                    "peak_limit": run.clipped,
                }
            )
    releases = [_release_row(push, False) for push in RELEASE_CUTTING_N]
    releases += [_release_row(push, True) for push in RELEASE_AT_STOP_N]
    previous = (PREVIOUS_WALL_N_PER_MM, 0.0, 0.0)
    now = (STOP_WALL_N_PER_MM, STOP_WALL_DAMPING_N_S_PER_MM, STOP_GLIDE_MM_S)
    return {
        "stiffness_n_per_mm": k,
        "damping_n_s_per_mm": b,
        "stop_wall_n_per_mm": STOP_WALL_N_PER_MM,
        "stop_wall_damping_n_s_per_mm": STOP_WALL_DAMPING_N_S_PER_MM,
        "poles": rows,
        "colgate_at_stop": colgate_terms(wall, wall_b, TICK_S),
        "hand_offset_mm": [
            (
                PREVIOUS_STIFFNESS_N_PER_MM,
                previous,
                _hand_offset_mm(PREVIOUS_STIFFNESS_N_PER_MM, previous, 0.0),
            ),
            (k, previous, _hand_offset_mm(k, previous, 0.0)),
            (k, now, _hand_offset_mm(k, now, RELEASE_DAMPING_N_S_PER_MM)),
        ],
        "pushes": pushes,
        "beyond_limit": beyond,
        "releases": releases,
    }


def _g(value: float | None, digits: int = 4) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if math.isinf(value):
        return "inf"
    return f"{value:.{digits}g}"


def report_markdown(report: dict[str, Any]) -> str:
    """The document's tables for ``report``."""
    lines = [
        "| operating point | K (N/mm) | B (N s/mm) | spectral radius | dominant pole (Hz) "
        "| damping ratio | unstable from K (N/mm) | margin | unstable from B (N s/mm) "
        "| B margin |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in report["poles"]:
        margin = "-" if r["margin"] is None else f"{_g(r['margin'], 3)}x"
        lines.append(
            f"| {r['operating point']} | {_g(r['stiffness_n_per_mm'])} "
            f"| {_g(r['damping_n_s_per_mm'])} "
            f"| {r['spectral_radius']:.6f} | {_g(r['pole_hz'], 3)} | {_g(r['damping_ratio'], 3)} "
            f"| {_g(r['limit_n_per_mm'])} | {margin} | {_g(r['damping_limit_n_s_per_mm'], 3)} "
            f"| {_g(r['damping_margin'], 3)}x |"
        )
    c = report["colgate_at_stop"]
    lines += [
        "",
        f"Colgate at the stop: K T / 2 = {_g(c['kt_half_n_s_per_mm'], 3)} N s/mm, "
        f"K T / 2 + |B| = {_g(c['required_b_n_s_per_mm'], 3)} N s/mm of physical damping "
        "required; the master has none (the DOB cancels its friction).",
        "",
        "| coupling (N/mm) | stop wall (N/mm, N s/mm, glide mm/s) "
        "| 30 N hand past the stopped drill (mm) |",
        "|---|---|---|",
    ]
    for k, (kw, bw, glide), offset in report["hand_offset_mm"]:
        lines.append(f"| {_g(k)} | {_g(kw)}, {_g(bw)}, {_g(glide)} | {offset:.2f} |")
    lines += [
        "",
        "| push (N) | final force (N) | max force (N) | hand past the drill (mm) "
        "| at most, while stopped (mm) "
        "| motion in the last 0.1 s (mm) | min E(n) (J) | min D(n) (J) | G (J) "
        "| force limit acted |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for p in report["pushes"]:
        lines.append(
            f"| {_g(p['push_n'])} | {p['final_force_n']:.2f} | {p['max_force_n']:.2f} "
            f"| {p['hand_past_drill_mm']:.3f} | {p['max_past_drill_mm']:.3f} "
            f"| {_g(p['settled_range_mm'], 3)} "
            f"| {_g(p['min_energy_in_j'], 3)} | {_g(p['min_dissipated_j'], 3)} "
            f"| {_g(p['glide_j'], 3)} | {_g(p['clipped'])} |"
        )
    lines += [
        "",
        "| K / limit at the stop | friction | release damper (N s/mm) "
        "| motion in the last 0.1 s (mm) | min E(n) (J) | min D(n) (J) | peak limit hit |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in report["beyond_limit"]:
        lines.append(
            f"| {r['factor']:g} | {r['friction']} | {_g(r['release_n_s_per_mm'])} "
            f"| {_g(r['settled_range_mm'], 3)} "
            f"| {_g(r['min_energy_in_j'], 3)} | {_g(r['min_dissipated_j'], 3)} "
            f"| {_g(r['peak_limit'])} |"
        )
    lines += [
        "",
        "| let go | push (N) | before: fastest back (mm/s) | before: behind the drill (mm) "
        "| before: travel end | fastest back (mm/s) | bound (mm/s) | behind the drill (mm) "
        "| bound (mm) | speed at the end (mm/s) | rests past the drill (mm) | travel end "
        "| springs held (mJ) | given back (mJ) | min E(n) (J) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in report["releases"]:
        lines.append(
            f"| {r['where']} | {_g(r['push_n'])} | {r['before_speed_mm_s']:.1f} "
            f"| {r['before_behind_mm']:.2f} | {_g(r['before_travel_end'])} "
            f"| {r['speed_mm_s']:.1f} | {r['speed_bound_mm_s']:.1f} | {r['behind_mm']:.3f} "
            f"| {r['behind_bound_mm']:.3f} | {r['final_speed_mm_s']:.2f} | {r['rest_mm']:.4f} "
            f"| {_g(r['travel_end'])} | {r['stored_j'] * 1e3:.2f} | {r['returned_j'] * 1e3:.2f} "
            f"| {_g(r['min_energy_in_j'], 3)} |"
        )
    return "\n".join(lines) + "\n"


def main() -> int:
    """Print the tables."""
    np.set_printoptions(precision=6)
    sys.stdout.write(report_markdown(coupling_report()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The teleoperation figure: both robots' depths, the force felt and the force cut, and the
estimated CT number over the CT's along the path (the window's teleoperation page and tests).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from ctdrill.haptics.bilateral.loop import STOPPED, TeleopRun

#: Colours: master, slave, cut front; felt, cut; CT, estimate.
COLOURS = {
    "master": "tab:blue",
    "slave": "tab:orange",
    "front": "0.5",
    "ct": "0.2",
    "est": "tab:red",
    "felt": "tab:blue",
    "cut": "tab:orange",
}


def draw_teleop(fig: Figure, run: TeleopRun, figures: dict[str, Any]) -> None:
    """Draw ``run`` (and its summary ``figures``) on ``fig``, replacing what was there."""
    fig.clear()
    ax_d, ax_f, ax_h = fig.subplots(3, 1)
    t = run.time_s
    ax_d.plot(t, run.master_mm, color=COLOURS["master"], lw=1.2, label="master")
    ax_d.plot(t, run.slave_mm, color=COLOURS["slave"], lw=1.2, ls="--", label="slave")
    ax_d.plot(t, run.front_mm, color=COLOURS["front"], lw=0.8, label="cut front")
    stop = figures.get("stop_depth_mm")
    if stop is not None and math.isfinite(run.stop_time_s):
        ax_d.axvline(run.stop_time_s, color="k", lw=0.8, ls=":")
        ax_d.annotate(
            f"stop: {figures.get('stop_reason')}",
            (run.stop_time_s, stop),
            fontsize=8,
            xytext=(4, -12),
            textcoords="offset points",
        )
    ax_d.set_ylabel("depth, mm")
    ax_d.invert_yaxis()
    ax_d.legend(loc="upper right", fontsize=7, ncol=3)
    ax_f.plot(t, run.env_force_n, color=COLOURS["cut"], lw=0.6, label="cut (slave)")
    ax_f.plot(t, run.hand_n, color=COLOURS["felt"], lw=0.9, label="felt (hand)")
    ax_f.set_ylabel("force, N")
    ax_f.set_xlabel("time, s")
    ax_f.legend(loc="upper right", fontsize=7, ncol=2)
    cut = run.state != STOPPED
    order = np.argsort(run.front_mm[cut], kind="stable")
    depth = run.front_mm[cut][order]
    ax_h.plot(depth, run.hu_ct[cut][order], color=COLOURS["ct"], lw=1.2, label="CT (lip mean)")
    est = run.hu_est[cut][order]
    ax_h.plot(depth, est, color=COLOURS["est"], lw=0.9, label="estimated from force")
    ax_h.set_xlabel("depth of the cut front, mm")
    ax_h.set_ylabel("CT number, HU")
    ax_h.legend(loc="lower right", fontsize=7, ncol=2)
    rmse = ", ".join(
        f"{d['layer']} {d['rmse_hu']:.0f} HU" for d in figures.get("hu_rmse_by_layer", [])
    )
    ax_h.set_title(f"RMS error: {rmse or '-'}", fontsize=8)
    fig.tight_layout()

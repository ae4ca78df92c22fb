"""Figures of one teleoperation run: transparency, passivity, estimation, stop (docs/teleop.md).

* **Transparency** per phase (``free``: no contact, ``cutting``, ``stop``: from
  :data:`SETTLE_S` after the slave was braked): the position tracking error
  ``x_m alpha - x_s`` (max and RMS, um) and the force reproduction, the paper's Fig. 14 figures:
  the mean error ``|mean F_h - mean beta F_e| / mean beta F_e`` and the mean absolute error
  ``mean |F_h - beta F_e| / mean beta F_e`` (with the vibration), %.
* **Passivity**: the observer's energy (:mod:`.loop`), passive when its minimum over the run
  stays above ``-PASSIVITY_TOL_J``.
* **Estimation**: the CT's layers along the cut front (``not cut`` below the gate's centre,
  ``trabecular``, ``cortex`` from the cortical threshold), per layer the RMS error and bias of
  the estimate along the path (one sample per :data:`DEPTH_BIN_MM` of depth) on its plateau,
  where the lip lies wholly in the layer now and a low-pass
  window earlier (:data:`PLATEAU_HU`; the transitions are what the boundary lag measures); at
  each boundary the lag (mm of front, ms) of the estimate's crossing of the mid-level between
  the layers' means against the CT's;
  ``boundary_lag_*`` is the worst delay, ``boundary_lead_mm`` the worst crossing ahead of the
  CT's (the contact state of Eq. 2 reads the material at the tip before the lip's mean);
  a boundary is detected when the estimate crosses within :data:`DETECT_TOL_MM` of it (an exit
  into material that is not cut also by the force-based stop); false alarms are changes of the
  estimate's layer (with :data:`HYSTERESIS_HU`) away from every boundary, per 10 mm cut.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ctdrill.haptics.bilateral.loop import CUTTING, FREE, STOPPED, TeleopRun
from ctdrill.model.profile import Profile, force_series_n

#: The stop phase starts this long after the brake, s.
SETTLE_S = 0.3
#: The passivity observer may dip this far below 0, J. The four-channel law shows the hand an
#: apparent mass of ``2 Mn / Kf`` = 0.83 kg for the 2.0 kg of both stages (and the hand's): the
#: motors supply the rest of the kinetic energy on an approach, and an impact gives it to the
#: environment, so the observer dips by up to that share of the approach's kinetic energy
#: without any instability (2-8 mJ measured for a 15 N push from 0.5 mm, no delay). A delay's
#: activity is 10-1000 times larger (docs/teleop.md, the stability map).
PASSIVITY_TOL_J = 0.01
#: A layer change counts as detected within this depth of the boundary, mm.
DETECT_TOL_MM = 0.5
#: Hysteresis of the estimate's layer, HU.
HYSTERESIS_HU = 50.0
LAYER_NAMES = ("not cut", "trabecular", "cortex")
#: The paper's Fig. 14 compares forces over cutting depths 1-8 mm, here past the first contact.
FIG14_WINDOW_MM = (1.0, 8.0)
#: The per-layer error takes one sample per this much front advance, mm.
DEPTH_BIN_MM = 0.01
#: A layer's plateau: where the CT's lip-mean number is within this of the layer's median, HU
#: (the lip lies wholly in the layer).
PLATEAU_HU = 100.0


@dataclass(frozen=True)
class Boundary:
    """One layer boundary the front crossed."""

    depth_mm: float
    from_layer: str
    to_layer: str
    level_hu: float
    detected: bool
    lag_mm: float
    lag_ms: float


def _phase(run: TeleopRun, mask: np.ndarray, alpha: float) -> dict[str, Any]:
    if not mask.any():
        return {"samples": 0}
    err_um = (run.master_mm[mask] * alpha - run.slave_mm[mask]) * 1e3
    out: dict[str, Any] = {
        "samples": int(mask.sum()),
        "tracking_max_um": float(np.max(np.abs(err_um))),
        "tracking_rms_um": float(np.sqrt(np.mean(err_um**2))),
    }
    fe = run.env_force_n[mask] * run.force_scale
    fh = run.hand_n[mask]
    mean_fe = float(np.mean(fe))
    if mean_fe > 0.0:
        out["force_error_pct"] = 100.0 * abs(float(np.mean(fh)) - mean_fe) / mean_fe
        out["force_mae_pct"] = 100.0 * float(np.mean(np.abs(fh - fe))) / mean_fe
        out["force_error_n"] = float(np.mean(fh)) - mean_fe
        out["force_mae_n"] = float(np.mean(np.abs(fh - fe)))
        out["mean_env_force_n"] = mean_fe
        t = run.time_s[mask]
        if t.size > 1 and t[-1] > t[0]:
            out["mean_feed_mm_s"] = float(
                np.sum(np.clip(np.diff(run.front_mm), 0.0, None)[mask[1:]])
                / (mask.sum() * _dt(run))
            )
    else:
        out["hand_force_rms_n"] = float(np.sqrt(np.mean(fh**2)))
    return out


def _dt(run: TeleopRun) -> float:
    return float(run.time_s[1] - run.time_s[0]) if run.time_s.size > 1 else 1.0


def fig14(run: TeleopRun, profile: Profile, origin_mm: float) -> dict[str, float]:
    """The paper's Fig. 14 figures over its depth window (:data:`FIG14_WINDOW_MM` past the
    first contact, cutting samples): the mean error (N, % of the mean cutting force) and the
    mean absolute error with the vibration (N) of

    * ``hand_*``: the force the hand feels (``hand_n``) against the slave's cutting force;
    * ``model_*``: Eq. 19 on ``profile`` (the plan's, its depth 0 at slave depth
      ``origin_mm``) at the slave's cut depth and feed (the front's mean over one low-pass
      window), the paper's reproduction, against the slave's cutting force.
    """
    cutting = run.state == CUTTING
    out: dict[str, float] = {}
    if not cutting.any():
        return out
    first = float(run.front_mm[np.argmax(cutting)])
    lo, hi = FIG14_WINDOW_MM
    mask = cutting & (run.front_mm >= first + lo) & (run.front_mm <= first + hi)
    if not mask.any():
        return out
    n = max(1, round(run.window_s / _dt(run)))
    front = run.front_mm
    back = np.concatenate([np.full(n, front[0]), front[:-n]])
    feed = (front - back) / (n * _dt(run))
    env = run.env_force_n[mask] * run.force_scale
    mean_env = float(np.mean(env))
    out["mean_force_n"] = mean_env
    for name, series in (
        ("hand", run.hand_n[mask]),
        ("model", force_series_n(profile, front - origin_mm, feed, run.time_s)[mask]),
    ):
        err = float(np.mean(series)) - mean_env
        out[f"{name}_error_n"] = err
        out[f"{name}_error_pct"] = 100.0 * abs(err) / mean_env if mean_env > 0.0 else math.nan
        out[f"{name}_mae_n"] = float(np.mean(np.abs(series - env)))
    return out


def layer_of(hu: np.ndarray, *, gate_hu: float, cortical_hu: float) -> np.ndarray:
    """0 not cut, 1 trabecular, 2 cortex."""
    return np.where(hu < gate_hu, 0, np.where(hu < cortical_hu, 1, 2)).astype(np.int8)


def _crossing(values: np.ndarray, level: float, falling: bool, start: int) -> int:
    seg = values[start:]
    hit = np.flatnonzero(seg <= level if falling else seg >= level)
    return start + int(hit[0]) if hit.size else -1


def teleop_metrics(
    run: TeleopRun,
    *,
    gate_hu: float,
    cortical_hu: float,
    tip_length_mm: float,
    exit_mm: float | None,
    position_scale: float = 1.0,
) -> dict[str, Any]:
    """The summary figures of ``run`` (module docstring); ``exit_mm`` is the true first
    breakthrough in slave depth (None: the path has none)."""
    alpha = position_scale
    stopped = run.state == STOPPED
    settle = stopped & (run.time_s >= run.stop_time_s + SETTLE_S)
    phases = {
        "free": _phase(run, run.state == FREE, alpha),
        "cutting": _phase(run, run.state == CUTTING, alpha),
        "stop": _phase(run, settle, alpha),
    }
    # estimation along the front while it advanced (before the brake)
    before = ~stopped
    truth_layer = layer_of(run.hu_ct, gate_hu=gate_hu, cortical_hu=cortical_hu)
    idx = np.flatnonzero(before)
    runs: list[tuple[int, int, int]] = []  # (class, first sample, last sample)
    for i in idx:
        c = int(truth_layer[i])
        if runs and runs[-1][0] == c:
            runs[-1] = (c, runs[-1][1], int(i))
        else:
            runs.append((c, int(i), int(i)))
    # a run thinner than the lip between two others is the lip crossing a boundary
    layers: list[tuple[int, int, int]] = []
    for c, i0, i1 in runs:
        thick = run.front_mm[i1] - run.front_mm[i0] >= tip_length_mm
        if layers and layers[-1][0] == c:
            layers[-1] = (c, layers[-1][1], i1)
        elif thick or not layers or i1 == idx[-1]:
            layers.append((c, i0, i1))
    counts: dict[int, int] = {}
    rmse: list[dict[str, Any]] = []
    names: list[str] = []
    for c, i0, i1 in layers:
        counts[c] = counts.get(c, 0) + 1
        name = LAYER_NAMES[c] + (f" {counts[c]}" if counts[c] > 1 else "")
        names.append(name)
        if c == 0:
            continue
        sel = np.arange(i0, i1 + 1)
        plateau = np.abs(run.hu_ct[sel] - np.median(run.hu_ct[sel])) <= PLATEAU_HU
        # ... and was a window earlier (the low-pass reads the last window)
        lag = max(1, round(run.window_s / float(run.time_s[1] - run.time_s[0])))
        earlier = np.zeros_like(plateau)
        earlier[lag:] = plateau[:-lag]
        sel = sel[
            plateau
            & earlier
            & run.hu_valid[sel]
            & (run.state[sel] == CUTTING)
            & np.isfinite(run.hu_est[sel])
        ]
        # one sample per DEPTH_BIN_MM of front advance: the error along the path, not in time
        # (a drill resting on the cortex would otherwise weigh as much as a millimetre cut)
        _, first = np.unique(np.floor(run.front_mm[sel] / DEPTH_BIN_MM), return_index=True)
        sel = sel[np.sort(first)]
        if sel.size == 0:
            continue
        err = run.hu_est[sel] - run.hu_ct[sel]
        rmse.append(
            {
                "layer": name,
                "rmse_hu": float(np.sqrt(np.mean(err**2))),
                "bias_hu": float(np.mean(err)),
                "samples": int(sel.size),
                "from_mm": float(run.front_mm[sel[0]]),
                "to_mm": float(run.front_mm[sel[-1]]),
            }
        )
    boundaries: list[Boundary] = []
    est = np.where(np.isfinite(run.hu_est), run.hu_est, np.nan)
    for j in range(1, len(layers)):
        (c0, a0, b0), (c1, a1, b1) = layers[j - 1], layers[j]
        # a layer that is not cut reads as the gate to the estimate (it cannot tell air from
        # soft tissue): its side of the level is the gate's
        m0 = float(np.mean(run.hu_ct[a0 : b0 + 1]))
        m1 = float(np.mean(run.hu_ct[a1 : b1 + 1]))
        m0 = max(m0, gate_hu) if c0 == 0 else m0
        m1 = max(m1, gate_hu) if c1 == 0 else m1
        level = 0.5 * (m0 + m1)
        falling = m1 < m0
        ct = run.hu_ct[a0 : b1 + 1]
        old_side = np.flatnonzero(ct > level if falling else ct < level)
        t_truth = a0 + int(old_side[old_side < a1 - a0 + 1][-1]) + 1 if old_side.size else a1
        t_truth = min(t_truth, b1)
        # the estimate's crossing: its first sample on the new side once the front is within
        # the tolerance of the boundary (the front only advances before the brake)
        near = np.flatnonzero(run.front_mm[a0 : b1 + 1] >= run.front_mm[t_truth] - DETECT_TOL_MM)
        search = a0 + int(near[0]) if near.size else t_truth
        filled = np.nan_to_num(est, nan=m0)
        t_est = _crossing(filled[: b1 + 1], level, falling, search)
        if c1 == 0 and run.stop_reason == "cortex_exit":
            stop_i = int(np.searchsorted(run.time_s, run.stop_time_s))
            t_est = stop_i if t_est < 0 else min(t_est, stop_i)
        b_mm = float(run.front_mm[t_truth])
        if t_est < 0:
            boundaries.append(
                Boundary(b_mm, names[j - 1], names[j], level, False, math.nan, math.nan)
            )
            continue
        lag_mm = float(run.front_mm[t_est]) - b_mm
        lag_ms = 1e3 * float(run.time_s[t_est] - run.time_s[t_truth])
        boundaries.append(
            Boundary(
                b_mm, names[j - 1], names[j], level, abs(lag_mm) <= DETECT_TOL_MM, lag_mm, lag_ms
            )
        )
    # a force stop on the lip's way out: the CT's lip-mean number crossed the mid-level to the
    # gate before the brake, but never reached the gate (the class of the layer beyond), so
    # the boundary has no samples of its own; its lag is the stop's
    if run.stop_reason == "cortex_exit" and layers and layers[-1][0] != 0:
        c0, a0, b0 = layers[-1]
        stop_i = min(int(np.searchsorted(run.time_s, run.stop_time_s)), len(run.hu_ct) - 1)
        m0 = float(np.mean(run.hu_ct[a0 : b0 + 1]))
        level = 0.5 * (m0 + gate_hu)
        ct = run.hu_ct[a0 : stop_i + 1]
        past = np.flatnonzero(ct <= level)
        if past.size and b0 <= stop_i:
            t_truth = a0 + int(past[0])
            b_mm = float(run.front_mm[t_truth])
            t_est = _crossing(np.nan_to_num(est, nan=m0)[: stop_i + 1], level, True, a0)
            t_est = stop_i if t_est < 0 else min(t_est, stop_i)
            lag_mm = float(run.front_mm[t_est]) - b_mm
            lag_ms = 1e3 * float(run.time_s[t_est] - run.time_s[t_truth])
            name = LAYER_NAMES[0] + (f" {counts[0] + 1}" if counts.get(0) else "")
            boundaries.append(
                Boundary(b_mm, names[-1], name, level, abs(lag_mm) <= DETECT_TOL_MM, lag_mm, lag_ms)
            )
    # false alarms: changes of the estimate's layer away from every true boundary
    false_alarms = 0
    alarm_mm: list[float] = []
    cur = -1
    cut_mm = 0.0
    if idx.size:
        cut_mm = float(np.sum(np.clip(np.diff(run.front_mm[idx]), 0.0, None)))
    bdepths = np.array([b.depth_mm for b in boundaries])
    for i in idx:
        if not run.hu_valid[i]:
            continue
        h = float(run.hu_est[i])
        c = int(layer_of(np.array([h]), gate_hu=gate_hu, cortical_hu=cortical_hu)[0])
        if cur < 0:
            cur = c
            continue
        if c != cur:
            hc = int(
                layer_of(
                    np.array([h + (HYSTERESIS_HU if c < cur else -HYSTERESIS_HU)]),
                    gate_hu=gate_hu,
                    cortical_hu=cortical_hu,
                )[0]
            )
            if hc == c:
                close = bool(bdepths.size) and bool(
                    np.min(np.abs(bdepths - run.front_mm[i])) <= DETECT_TOL_MM
                )
                if not close:
                    false_alarms += 1
                    alarm_mm.append(float(run.front_mm[i]))
                cur = c
    detected = sum(b.detected for b in boundaries)
    lags = [b for b in boundaries if b.detected]
    overshoot = None
    if exit_mm is not None and math.isfinite(exit_mm):
        overshoot = run.deepest_front_mm - exit_mm
    return {
        "tracking_rms_um": phases["cutting"].get("tracking_rms_um"),
        "tracking_max_um": phases["cutting"].get("tracking_max_um"),
        "force_error_pct": phases["cutting"].get("force_error_pct"),
        "force_mae_pct": phases["cutting"].get("force_mae_pct"),
        "transparency": phases,
        "passivity_energy_min_j": run.energy_min_j,
        "passivity_energy_end_j": float(run.energy_j[-1]) if run.energy_j.size else 0.0,
        "passive": bool(run.energy_min_j >= -PASSIVITY_TOL_J),
        "hu_rmse_by_layer": rmse,
        "boundaries": [
            {
                "depth_mm": b.depth_mm,
                "from": b.from_layer,
                "to": b.to_layer,
                "level_hu": b.level_hu,
                "detected": b.detected,
                "lag_mm": None if math.isnan(b.lag_mm) else b.lag_mm,
                "lag_ms": None if math.isnan(b.lag_ms) else b.lag_ms,
            }
            for b in boundaries
        ],
        "boundary_lag_mm": max((max(b.lag_mm, 0.0) for b in lags), default=None),
        "boundary_lag_ms": max((max(b.lag_ms, 0.0) for b in lags), default=None),
        "boundary_lead_mm": max((max(-b.lag_mm, 0.0) for b in lags), default=None),
        "layers_detected": int(detected),
        "layers_missed": len(boundaries) - int(detected),
        "false_alarms": int(false_alarms),
        "false_alarm_depths_mm": alarm_mm,
        "false_alarms_per_10mm": 10.0 * false_alarms / cut_mm if cut_mm > 0.0 else 0.0,
        "stop_depth_mm": None if math.isnan(run.stop_depth_mm) else run.stop_depth_mm,
        "stop_reason": run.stop_reason or "none",
        "stop_time_s": None if math.isnan(run.stop_time_s) else run.stop_time_s,
        "deepest_front_mm": run.deepest_front_mm,
        "exit_depth_mm": exit_mm,
        "overshoot_mm": overshoot,
        "packets_lost": run.packets_lost,
    }

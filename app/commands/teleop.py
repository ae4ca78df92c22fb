"""``ctdrill teleop``: the slave cuts the patient's CT along the plan under bilateral control."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ctdrill.app.commands.options import add_ct_option, add_plan_option


def register(subparsers: Any) -> None:
    """Add the ``teleop`` subcommand."""
    p = subparsers.add_parser(
        "teleop",
        help="teleoperate the simulated slave robot cutting the CT along the plan",
        description=(
            "Simulate the paper's master and slave under four-channel bilateral control "
            "(10 kHz): the slave cuts the CT along the plan, the master lets the simulated "
            "hand feel it, the CT number is estimated from the slave's force and the slave "
            "stops on the cortex exit. Writes OUT/session.csv and OUT/summary.json, replacing "
            "OUT whole (docs/teleop.md)."
        ),
    )
    add_ct_option(p, required=True)
    add_plan_option(p, required=True)
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument(
        "--operator",
        required=True,
        help="push:N, feed:V, script:FILE or human:force=N,react_ms=T[,noise_n=S,seed=K] "
        "(as rehearse; a human lets go T ms after the slave stopped)",
    )
    p.add_argument("--duration-s", type=float, default=5.0, help="simulated time, s (5)")
    p.add_argument(
        "--hand-damping",
        type=float,
        default=20.0,
        metavar="N_S_PER_M",
        help="the hand's damping on the handle, N s/m (20: a firm hand)",
    )
    p.add_argument("--delay-ms", type=float, default=0.0, metavar="MS", help="one-way delay")
    p.add_argument("--jitter-ms", type=float, default=0.0, metavar="MS", help="uniform jitter")
    p.add_argument("--loss", type=float, default=0.0, help="packet loss probability (0)")
    p.add_argument(
        "--model-error",
        type=float,
        default=0.0,
        metavar="FRACTION",
        help="the slave's true force law is the model's times 1 + FRACTION",
    )
    p.add_argument(
        "--misregister-mm",
        type=float,
        default=0.0,
        metavar="MM",
        help="the CT the slave cuts is the plan's shifted this far against the drill's "
        "direction (anatomy shallower)",
    )
    p.add_argument("--seed", type=int, default=0, metavar="K", help="seed (channel, hand)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the teleoperation and print one line."""
    from ctdrill.app.teleop import teleop

    s = teleop(
        ct=args.dicom,
        plan=args.plan,
        out=args.out,
        operator=args.operator,
        duration_s=args.duration_s,
        hand_damping_n_s_per_m=args.hand_damping,
        delay_ms=args.delay_ms,
        jitter_ms=args.jitter_ms,
        loss=args.loss,
        model_error=args.model_error,
        misregister_mm=args.misregister_mm,
        seed=args.seed,
    )
    stop = s.get("stop_depth_mm")
    where = "no stop" if stop is None else f"stopped at {stop:.2f} mm ({s['stop_reason']})"
    sys.stdout.write(
        f"teleop: {where}; tracking {s.get('tracking_rms_um') or 0.0:.2f} um RMS, force error "
        f"{s.get('force_error_pct') or 0.0:.2f} %, passive {s['passive']}, layers "
        f"{s['layers_detected']} detected / {s['layers_missed']} missed; wrote {args.out}\n"
    )
    return 0

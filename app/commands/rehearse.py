"""``ctdrill rehearse``: a simulated or real haptic rehearsal of one planned osteotomy."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ctdrill.app.commands.options import (
    add_ct_option,
    add_grey_map_options,
    add_hu_sigma_option,
    add_interpolate_gaps_option,
    add_plan_option,
)


def register(subparsers: Any) -> None:
    """Add the ``rehearse`` subcommand."""
    p = subparsers.add_parser(
        "rehearse",
        help="rehearse a planned osteotomy on the haptic device (or its simulator)",
        description=(
            "Compute the force table along the plan, upload it with the stop depth to the "
            "device, drive it with a simulated operator and log the session. Writes "
            "OUT/session.csv (time_s, master_mm, drill_mm, force_cmd_n, state) and "
            "OUT/summary.json, replacing OUT whole. The host watches the telemetry: a drill "
            "past the stop, a silent or faulted device or its own error ends the session with "
            "STOP and DISARM, the fault recorded in summary.json and exit code 3. A plan with "
            "a drill sequence (drills) runs one session per drill into OUT/drill_1/, "
            "OUT/drill_2/ ... with a summary.json listing them."
        ),
    )
    add_ct_option(p, required=True)
    add_plan_option(p, required=True)
    p.add_argument(
        "--trajectory",
        metavar="NAME|N",
        help="which trajectory to rehearse when the plan files hold several: its name, or "
        "its number (1-based, in the order ctdrill export lists them)",
    )
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument(
        "--operator",
        required=True,
        help="push:N (constant hand force, N), feed:V (constant feed, mm/s), script:FILE "
        "(CSV time_s,force_n) or human:force=N,react_ms=T[,noise_n=S,seed=K] (a person who "
        "lets go T ms after a breakthrough or the wall; docs/rehearse.md)",
    )
    p.add_argument("--duration-s", type=float, required=True, help="session length, s")
    p.add_argument("--device", default="sim", help="sim (default) or serial:PORT")
    p.add_argument(
        "--fault",
        action="append",
        default=[],
        help="link-loss@T, garbage@T, delay@T:MS or reset@T (repeatable)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of injected garbage (default 0)")
    p.add_argument(
        "--exam",
        action="store_true",
        help="exam mode: no wall at the margin; the simulator's stop 10 mm beyond the planned "
        "depth (the drill can enter the margin zone and the canal), the robot's at the canal's "
        "surface (serial:...); the summary's assessment records any breach (docs/rehearse.md)",
    )
    p.add_argument(
        "--aids",
        metavar="LEVEL",
        default=None,
        help="a level of the stop-yourself exercise (all-aids, no-plots, no-readout, "
        "no-gauges, no-wall: exam mode); the summary's mode is stop-yourself:LEVEL "
        "(docs/exercises.md)",
    )
    p.add_argument(
        "--igtl",
        metavar="HOST:PORT",
        help="stream the session live to an OpenIGTLink server, e.g. 3D Slicer's "
        "OpenIGTLinkIF on localhost:18944: transforms DrillTip and Implant (RAS), the "
        "forces as JSON in the string Forces; the simulator then runs at the wall clock's "
        "pace; summary.json igtl says what was sent (docs/slicer.md)",
    )
    add_interpolate_gaps_option(p)
    add_hu_sigma_option(p)
    add_grey_map_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the rehearsal and print a one-line summary; 3 if it ended on a device fault."""
    from ctdrill.app.exercise.aids import aid_level
    from ctdrill.app.grey_option import grey_line, parse_grey_options
    from ctdrill.app.readout import readout_lines
    from ctdrill.app.rehearse import ending_message, exit_code, rehearse
    from ctdrill.app.summary_lines import band_line, calibration_line
    from ctdrill.engine.record import from_json
    from ctdrill.engine.summary import CalibrationInfo, ForceBandPeak, GreyMapInfo

    aids = None if args.aids is None else aid_level(args.aids)
    s = rehearse(
        aids=aids,
        dicom=args.dicom,
        plan=args.plan,
        out=args.out,
        operator=args.operator,
        duration_s=args.duration_s,
        device=args.device,
        faults=args.fault,
        seed=args.seed,
        interpolate_gaps=args.interpolate_gaps,
        hu_sigma=args.hu_sigma,
        grey=parse_grey_options(args.grey_to_hu, args.grey_ref),
        trajectory=args.trajectory,
        exam=args.exam,
        notice=lambda line: print(line, flush=True),
        igtl=args.igtl,
        on_warning=_warn,
    )
    if s.get("format") == "ctdrill-rehearsal-sequence/1":
        from ctdrill.app.rehearse_sequence import sequence_lines

        sys.stdout.write("".join(line + "\n" for line in sequence_lines(s, args.out)))
    else:
        _single_line(s, args.out)
    # a sequence: the last drill run's calibration, band and readouts
    band = None if s.get("force_band") is None else from_json(ForceBandPeak, s["force_band"])
    note = str(s.get("force_band_note", ""))
    sys.stdout.write(
        f"{calibration_line(from_json(CalibrationInfo, s))}\n{band_line(band, note)}\n"
    )
    sys.stdout.write(readout_lines(s))
    if "assessment" in s:
        from ctdrill.app.trainee.words import assessment_line

        sys.stdout.write(assessment_line(s) + "\n")
    if "igtl" in s:
        from ctdrill.app.igtl.stream import stream_line

        sys.stdout.write(stream_line(s["igtl"]) + "\n")
    grey_map = s.get("grey_to_hu")
    grey = grey_line(None if grey_map is None else from_json(GreyMapInfo, grey_map))
    if grey is not None:
        sys.stdout.write(grey + "\n")
    if any(w["code"] == "no_landmarks" for w in s["warnings"]):
        sys.stderr.write(
            "warning: the plan has no landmark: no safety margin was enforced, the drill "
            "stopped only at the planned depth or the volume's end\n"
        )
    code = exit_code(s)
    if code != 0:
        sys.stderr.write(f"error: {ending_message(s)}; see {args.out}/summary.json\n")
    return code


def _warn(message: str) -> None:
    sys.stderr.write(f"warning: {message}\n")
    sys.stderr.flush()


def _single_line(s: dict[str, Any], out: Path) -> None:
    from ctdrill.engine.stop import stop_words

    exam = s.get("exam", {})
    why = (
        f"exam: {exam['stop_basis']}"
        if exam.get("enabled")
        else stop_words(s["stop_reason"], form="code")
    )
    sys.stdout.write(
        f"stop depth {s['stop_depth_mm']:.2f} mm ({why}), max drill depth "
        f"{s['max_drill_mm']:.2f} mm, final state {s['final_state']}, "
        f"{len(s['faults'])} fault events; wrote {out}/session.csv and summary.json\n"
    )

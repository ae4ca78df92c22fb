"""``ctdrill gui``: the desktop window (3D view, slices, plots, planning, rehearsal)."""

from __future__ import annotations

import argparse
import os
import socket
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ctdrill.app.commands.options import (
    add_ct_option,
    add_hu_sigma_option,
    add_implants_option,
    add_plan_option,
)
from ctdrill.app.errors import AppInputError

#: Upper bound on a ``--screenshot`` run when ``--quit-after-s`` is not given, s.
SCREENSHOT_TIMEOUT_S = 120.0
#: Qt platforms that draw no window (the embedded 3D view cannot render on them).
HEADLESS_PLATFORMS = ("offscreen", "minimal")
NO_DISPLAY_HINT = (
    "run it in a desktop session, or under a virtual display: xvfb-run -a ctdrill gui ..."
)


def display_problem(env: Mapping[str, str], platform: str = sys.platform) -> str | None:
    """Why Qt could not open a window with this environment (None: it can try).

    Checked before Qt starts, because Qt aborts the process (exit 134) when it finds no
    display. On Linux and the BSDs a window needs ``DISPLAY`` (X11) or ``WAYLAND_DISPLAY``;
    ``QT_QPA_PLATFORM`` may name the one Qt must use. macOS and Windows always have one.
    """
    if not platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return None
    qpa = env.get("QT_QPA_PLATFORM", "").split(":", 1)[0].strip()
    x11, wayland = env.get("DISPLAY", ""), env.get("WAYLAND_DISPLAY", "")
    if qpa in HEADLESS_PLATFORMS:
        return f"QT_QPA_PLATFORM={qpa} draws no window (the 3D view needs one)"
    if qpa == "xcb" and not x11:
        return "QT_QPA_PLATFORM=xcb but DISPLAY is not set (no X11 display)"
    if qpa.startswith("wayland") and not wayland:
        return f"QT_QPA_PLATFORM={qpa} but WAYLAND_DISPLAY is not set (no Wayland display)"
    if not qpa and not x11 and not wayland:
        return "no display: neither DISPLAY nor WAYLAND_DISPLAY is set"
    if x11 and not wayland and qpa in ("", "xcb") and not x11_reachable(x11):
        return f"cannot connect to the X display DISPLAY={x11} (no X server answers there)"
    return None


def x11_reachable(display: str, timeout_s: float = 1.0) -> bool:
    """True if an X server accepts connections for ``display`` (``[host]:N[.S]``): the local
    socket ``/tmp/.X11-unix/XN`` (or its abstract twin) or TCP port 6000 + N on ``host``.
    A display name of another form is assumed reachable (Qt will say)."""
    host, sep, rest = display.rpartition(":")
    number = rest.split(".", 1)[0]
    if not sep or not (number.isascii() and number.isdigit()):
        return True
    if host in ("", "unix"):
        targets: list[tuple[int, Any]] = [
            (socket.AF_UNIX, f"/tmp/.X11-unix/X{number}"),
            (socket.AF_UNIX, f"\0/tmp/.X11-unix/X{number}"),
        ]
    else:
        targets = [(socket.AF_INET, (host, 6000 + int(number)))]
    for family, address in targets:
        try:
            with socket.socket(family, socket.SOCK_STREAM) as sock:
                sock.settimeout(timeout_s)
                sock.connect(address)
            return True
        except OSError:
            continue
    return False


def register(subparsers: Any) -> None:
    """Add the ``gui`` subcommand."""
    p = subparsers.add_parser(
        "gui",
        help="open the desktop window",
        description="Open the ctdrill window: plan on the CT, see force and clearance, rehearse.",
    )
    add_ct_option(p, required=False)
    add_plan_option(p, required=False)
    add_hu_sigma_option(p)
    add_implants_option(p)
    p.add_argument("--screenshot", type=Path, help="save the window as PNG once drawn, then quit")
    p.add_argument(
        "--quit-after-s", type=float, default=None, help="close the window after this many seconds"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Validate the arguments, then run the window (SIGTERM and SIGHUP end it as before:
    a Qt event loop has no place to take them as Ctrl-C)."""
    from ctdrill.interrupts import uninstall

    uninstall()
    if args.dicom is not None and not args.dicom.exists():
        raise AppInputError(
            f"--ct/--dicom {args.dicom}: no such folder or file; give a DICOM folder or a CT file"
        )
    for plan in args.plan or ():
        if not plan.exists():
            raise AppInputError(f"--plan {plan}: no such file; give a plan JSON or .mrk.json")
    if args.quit_after_s is not None and not args.quit_after_s > 0:
        raise AppInputError(
            f"--quit-after-s {args.quit_after_s}: give a positive number of seconds"
        )
    if args.screenshot is not None:
        parent = args.screenshot.resolve().parent
        if not parent.is_dir():
            raise AppInputError(f"--screenshot {args.screenshot}: folder {parent} does not exist")
        if args.screenshot.suffix.lower() != ".png":
            raise AppInputError(f"--screenshot {args.screenshot}: the file name must end in .png")
    quit_after = args.quit_after_s
    if args.screenshot is not None and quit_after is None:
        quit_after = SCREENSHOT_TIMEOUT_S
    from ctdrill.engine.grey import hu_sigma_uncertainty

    hu = hu_sigma_uncertainty(args.hu_sigma)
    plans: tuple[Any, ...] = ()
    if args.plan is not None:  # a plan that cannot be read is refused before any window
        from ctdrill.imaging.plan.load import load_plan_set

        plans = load_plan_set(args.plan)  # every trajectory: the first is current
    library = None
    if args.implants is not None:  # a library that cannot be read is refused before any window
        from ctdrill.imaging.plan.implants import load_implant_library

        library = load_implant_library(args.implants)
    problem = display_problem(os.environ)
    if problem is not None:
        raise AppInputError(f"ctdrill gui: {problem}; {NO_DISPLAY_HINT}")
    from ctdrill.app.gui.preload import import_window

    import_window()  # the Qt-free modules first (PySide6's import hook), the collector paused
    from ctdrill.app.gui.app import run_gui  # Qt loads only when the window is really wanted

    return run_gui(
        dicom=args.dicom,
        plans=plans,
        implants=library,
        screenshot=args.screenshot,
        quit_after_s=quit_after,
        hu_uncertainty=hu,
        instructor=args.key is not None,  # the command line checked the key (cli.main)
    )

"""The window's rehearsal streamed to 3D Slicer over OpenIGTLink (the panel's setting)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.rehearsal import SIMULATOR
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import open_case
from tests.app.igtl_server import free_port, igtl_server

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)


def test_the_panel_streams_the_session_and_reports_a_refused_server(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    panel = window.rehearsal
    panel.device.setCurrentText(SIMULATOR)
    panel.duration_s = 30.0  # the session ends at the auto-stop
    panel.hand.set_push(20.0)

    panel.igtl.setText("localhost")  # no port: refused before anything runs
    panel.start()
    assert panel.run is None
    assert panel.message.text().startswith("error: stream to Slicer 'localhost': no port")

    panel.realtime = False
    panel.igtl.setText(f"127.0.0.1:{free_port()}")  # nothing listens
    with qtbot.waitSignal(panel.finished, timeout=60_000):
        panel.start()
    run = panel.run
    assert run is not None and run.session is not None and run.session["complete"]
    assert run.igtl is not None and "refused" in run.igtl["error"] and run.igtl["sent"] == 0
    assert run.igtl_warning is not None and "refused" in run.igtl_warning
    assert "stopped: cannot connect (refused" in panel.message.text()  # the end's line

    panel.realtime = True  # the simulator at the wall clock's pace, as a student drills
    with igtl_server() as (port, received):
        panel.igtl.setText(f"127.0.0.1:{port}")
        with qtbot.waitSignal(panel.finished, timeout=60_000):
            panel.start()
            assert f"streaming to OpenIGTLink 127.0.0.1:{port}" in panel.message.text()
            assert not panel.igtl.isEnabled()  # not changed under a running session
        run = panel.run
        assert run is not None and run.session is not None and run.igtl is not None
        report = run.igtl
        assert report["connected"] and report["error"] is None and report["sent"] > 30
        log = received.wait_for(sum(report["messages"].values()))
    assert {m.device_name for m in log} == {"DrillTip", "Forces", "Implant"}
    assert f"OpenIGTLink 127.0.0.1:{port}: sent {report['sent']} of" in panel.message.text()
    assert run.summary()["igtl"] == report
    # the last frame is the session's last row: its drill depth on the plan's axis, in RAS
    plan = window.plan
    assert plan is not None
    last_tip = [m for m in log if m.device_name == "DrillTip"][-1]
    last_forces = json.loads([m for m in log if m.device_name == "Forces"][-1].string)
    t, _master, drill_mm, _force, _state, _hand = run.rows[-1]
    assert last_forces["time_s"] == pytest.approx(t, abs=1e-4)
    tip_lps = plan.entry_lps + drill_mm * plan.direction
    np.testing.assert_allclose(
        np.asarray(last_tip.matrix)[:3, 3], tip_lps * [-1.0, -1.0, 1.0], atol=2e-5
    )

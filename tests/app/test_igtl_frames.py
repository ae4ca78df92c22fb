"""OpenIGTLink frames: the target's grammar, the poses (LPS -> RAS), the Forces document."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.app.errors import AppInputError
from ctdrill.app.igtl.frames import (
    StreamDrill,
    StreamGeometry,
    axis_frame_lps,
    forces_doc,
    frame_messages,
    parse_target,
)
from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.protocol import DeviceState


@pytest.mark.parametrize(
    ("spec", "host", "port"),
    [
        ("localhost:18944", "localhost", 18944),
        ("192.168.1.20:1", "192.168.1.20", 1),
        ("[::1]:65535", "::1", 65535),
        (" slicer.lab:18944 ", "slicer.lab", 18944),
    ],
)
def test_targets_parse(spec: str, host: str, port: int) -> None:
    target = parse_target(spec)
    assert (target.host, target.port) == (host, port)
    assert parse_target(target.text) == target


@pytest.mark.parametrize(
    ("spec", "says"),
    [
        ("localhost", "no port"),
        (":18944", "no host"),
        ("[]:18944", "no host"),
        ("local host:18944", "no host"),
        ("localhost:", "1..65535"),
        ("localhost:0", "1..65535"),
        ("localhost:65536", "1..65535"),
        ("localhost:-5", "1..65535"),
        ("localhost:18944.0", "1..65535"),
        ("localhost:١٢", "1..65535"),
    ],
)
def test_bad_targets_are_refused_naming_the_option(spec: str, says: str) -> None:
    with pytest.raises(AppInputError) as info:
        parse_target(spec)
    assert str(info.value).startswith(f"--igtl {spec!r}: ") and says in str(info.value)
    assert "localhost:18944" in str(info.value)  # what to give instead


def test_a_vertical_drill_into_the_jaw_in_ras() -> None:
    # LPS: entry (32, 10, -29), drilling inferior (-z). RAS flips x and y: the tip at depth d
    # is (-32, -10, -29 - d); z follows the drill (inferior), x is the patient's right (RAS +x).
    geometry = StreamGeometry((32.0, 10.0, -29.0), (0.0, 0.0, -1.0), (32.0, 10.0, -41.0))
    pose = geometry.tip_pose_ras(2.5)
    expected = np.array(
        [
            [1.0, 0.0, 0.0, -32.0],
            [0.0, -1.0, 0.0, -10.0],
            [0.0, 0.0, -1.0, -31.5],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )
    np.testing.assert_allclose(pose, expected, atol=1e-12)
    implant = geometry.implant_pose_ras()
    assert implant is not None
    np.testing.assert_allclose(implant[:3, 3], [-32.0, -10.0, -41.0], atol=1e-12)
    np.testing.assert_allclose(implant[:3, :3], expected[:3, :3], atol=1e-12)
    assert StreamGeometry((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)).implant_pose_ras() is None


def test_an_axis_along_right_left_takes_anterior_as_x() -> None:
    frame = axis_frame_lps([1.0, 0.0, 0.0])  # towards the patient's left
    np.testing.assert_allclose(frame[:, 2], [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(frame[:, 0], [0.0, -1.0, 0.0], atol=1e-12)  # anterior (LPS -y)


unit = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(st.tuples(unit, unit, unit).filter(lambda v: math.hypot(*v) > 1e-3))
def test_the_axis_frame_is_a_rotation_whose_z_is_the_drill_axis(v: tuple[float, ...]) -> None:
    d = np.asarray(v) / np.linalg.norm(v)
    frame = axis_frame_lps(d)
    np.testing.assert_allclose(frame.T @ frame, np.eye(3), atol=1e-12)
    assert np.linalg.det(frame) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(frame[:, 2], d, atol=1e-12)
    # x leans to the patient's right (LPS -x) unless the axis is within 45 deg of right-left
    right = -frame[0, 0]
    near_x = abs(d[0]) - math.cos(math.radians(45.0))
    if near_x < -1e-9:
        assert right == pytest.approx(math.sqrt(1.0 - d[0] ** 2), abs=1e-12)
    elif near_x > 1e-9:  # anterior (LPS -y) made perpendicular instead
        assert -frame[1, 0] == pytest.approx(math.sqrt(1.0 - d[1] ** 2), abs=1e-12)
    # RAS of the pose: the same rotation with rows x and y negated, still a rotation
    ras = StreamGeometry((0.0, 0.0, 0.0), tuple(d)).tip_pose_ras(1.0)  # type: ignore[arg-type]
    np.testing.assert_allclose(ras[:3, :3], np.diag([-1.0, -1.0, 1.0]) @ frame, atol=1e-12)
    np.testing.assert_allclose(ras[:3, 3], [-d[0], -d[1], d[2]], atol=1e-12)
    assert np.linalg.det(ras[:3, :3]) == pytest.approx(1.0, abs=1e-12)


def _sample(state: DeviceState, force_n: float, *, drill_mm: float = 3.0) -> TelemetrySample:
    return TelemetrySample(
        time_s=12.3456789,
        tick=123456,
        master_mm=drill_mm + 0.4,
        drill_mm=drill_mm,
        velocity_mm_s=0.5,
        force_cmd_n=force_n,
        force_est_n=9.87654,
        state=int(state),
        faults=0,
        overruns=0,
    )


def test_forces_name_their_units_and_split_cutting_from_the_wall() -> None:
    fields = [
        "time_s",
        "state",
        "drill_depth_mm",
        "master_depth_mm",
        "hand_force_n",
        "device_force_n",
        "cutting_force_n",
        "wall_force_n",
    ]
    cutting = forces_doc(_sample(DeviceState.CUTTING, 8.125), 1.23456)
    assert list(cutting) == fields
    assert cutting["time_s"] == 1.2346 and cutting["state"] == "cutting"
    assert (cutting["cutting_force_n"], cutting["wall_force_n"]) == (8.125, 0.0)
    assert cutting["hand_force_n"] == 9.8765 and cutting["drill_depth_mm"] == 3.0
    wall = forces_doc(_sample(DeviceState.STOPPED, 21.0), 2.0)
    assert (wall["cutting_force_n"], wall["wall_force_n"]) == (0.0, 21.0)
    safe = forces_doc(_sample(DeviceState.SAFE, 0.0), 3.0)
    assert safe["state"] == "safe" and safe["cutting_force_n"] == safe["wall_force_n"] == 0.0


def test_a_frame_packs_the_three_named_messages() -> None:
    import pyigtl

    geometry = StreamGeometry((32.0, 10.0, -29.0), (0.0, 0.0, -1.0), (32.0, 10.0, -41.0))
    sample = _sample(DeviceState.CUTTING, math.inf)
    messages = frame_messages(geometry, sample, 0.5, timestamp=1.7e9, with_implant=True)
    assert [m.device_name for m in messages] == ["DrillTip", "Forces", "Implant"]
    assert [type(m) for m in messages] == [
        pyigtl.TransformMessage,
        pyigtl.StringMessage,
        pyigtl.TransformMessage,
    ]
    doc = json.loads(messages[1].string)
    assert doc["device_force_n"] is None  # non-finite: null, never an invalid JSON 'Infinity'
    assert all(m.timestamp == 1.7e9 for m in messages)
    assert len(frame_messages(geometry, sample, 0.5, timestamp=0.0, with_implant=False)) == 2


def test_a_drill_of_a_sequence_is_named_first_in_its_frame() -> None:
    import pyigtl

    geometry = StreamGeometry((32.0, 10.0, -29.0), (0.0, 0.0, -1.0))
    drill = StreamDrill(2, 3, 2.8, "drill_2")
    sample = _sample(DeviceState.CUTTING, 1.0)
    messages = frame_messages(geometry, sample, 0.5, timestamp=5.0, with_implant=True, drill=drill)
    assert [m.device_name for m in messages] == ["Drill", "DrillTip", "Forces"]  # no implant
    assert isinstance(messages[0], pyigtl.StringMessage) and messages[0].timestamp == 5.0
    # the packed bytes decode as the JSON object docs/slicer.md shows
    packed = messages[0].pack()
    assert packed[2:14] == b"STRING\0\0\0\0\0\0" and packed[14:19] == b"Drill"
    doc = json.loads(packed[58 + 4 :].decode("utf-8"))
    assert doc == {"drill": 2, "drills": 3, "diameter_mm": 2.8, "folder": "drill_2"}

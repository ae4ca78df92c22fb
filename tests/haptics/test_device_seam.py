"""The device seam: physics injected into the emulator, device cores by name, a DeviceSpec
instead of the text ``sim``, simulator-only operations off the hardware Protocol."""

from __future__ import annotations

import inspect

import pytest

from ctdrill.haptics.core import CORES, make_core
from ctdrill.haptics.device import Device, SimulatorControls, simulator_controls
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.errors import HapticsInputError
from ctdrill.haptics.physics import MasterPhysics, Physics
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import NakReason
from ctdrill.haptics.run import run_session
from ctdrill.haptics.session import parse_operator
from ctdrill.haptics.sim import SimulatedDevice
from ctdrill.haptics.spec import DeviceSpec


class FeedRobot:
    """A position-controlled robot: it advances at ``feed_mm_s`` whatever the force (a slave
    at constant feed), reads its speed exactly and holds the rendered force."""

    def __init__(self, feed_mm_s: float, dt_s: float) -> None:
        self.feed_mm_s = feed_mm_s
        self.dt_s = dt_s
        self.x_mm = 0.0
        self.engaged: list[bool] = []
        self.last_force_n = 0.0
        self.operator: tuple[int, float] | None = None

    @property
    def travel_mm(self) -> tuple[float, float]:
        return (-5.0, 25.0)

    @property
    def velocity_mm_s(self) -> float:
        return self.feed_mm_s

    @property
    def hand_est_n(self) -> float:
        return self.last_force_n

    @property
    def hand_n(self) -> float:
        return self.last_force_n

    @property
    def at_end_stop(self) -> bool:
        return False

    def encoder_mm(self) -> float:
        return self.x_mm

    def step(self, force_cmd_n: float, *, engaged: bool) -> None:
        self.engaged.append(engaged)
        self.last_force_n = force_cmd_n
        if engaged:
            self.x_mm += self.feed_mm_s * self.dt_s

    def set_operator(self, kind: int, value: float) -> NakReason | None:
        self.operator = (kind, value)
        return None

    def power_cycle(self) -> None:
        """Nothing to restart."""


def test_a_second_mechanism_plugs_into_the_emulator_unedited() -> None:
    robot = FeedRobot(2.0, 1e-4)
    physics: Physics = robot  # it is a Physics (mypy checks the Protocol)
    device = SimulatedDevice(physics=physics)
    table = ProfileTable.slab(s0_n=4.0, top_mm=0.0, bottom_mm=20.0, stop_depth_mm=3.0)
    info = device.hello()
    assert (info.limits.travel_min_mm, info.limits.travel_max_mm) == (-5.0, 25.0)
    rows: list[tuple[float, float, float, float, str]] = []
    result = run_session(device, table, parse_operator("push:5"), 1.0, sink=rows.extend)
    assert result.complete
    assert robot.operator == (1, 5.0)  # the simulated hand's input reached the physics
    # engaged (rendering) while armed, about 1 s of 10 kHz ticks: it advanced at 2 mm/s
    assert robot.engaged.count(True) == pytest.approx(10_000, rel=0.02)
    master = [r[1] for r in rows if 0.4 <= r[0] <= 0.9]
    times = [r[0] for r in rows if 0.4 <= r[0] <= 0.9]
    feed = (master[-1] - master[0]) / (times[-1] - times[0])
    assert feed == pytest.approx(2.0, rel=0.02)
    assert all(r[4] == "cutting" for r in rows if 0.4 <= r[0] <= 0.9)


def test_the_default_physics_is_the_masters() -> None:
    emu = DeviceEmulator(nonce_seed=0)
    assert isinstance(emu.physics, MasterPhysics)
    assert emu.plant is emu.physics.plant and emu.controller is emu.physics.controller
    other = DeviceEmulator(nonce_seed=0, physics=FeedRobot(1.0, emu.dt_s))
    with pytest.raises(AttributeError, match="not the master"):
        _ = other.plant


def test_cores_by_name() -> None:
    assert "python" in CORES
    core = make_core("python", start_mm=1.5, nonce_seed=0)
    assert isinstance(core, DeviceEmulator) and core.start_mm == 1.5
    with pytest.raises(KeyError, match="python"):
        make_core("no-such-core")


def test_simulator_only_operations_are_off_the_hardware_protocol() -> None:
    hardware = {n for n, _ in inspect.getmembers(Device, inspect.isfunction) if n[0] != "_"}
    simulator = {
        n for n, _ in inspect.getmembers(SimulatorControls, inspect.isfunction) if n[0] != "_"
    }
    assert simulator == {"set_operator", "write_raw", "sim_reset"}
    assert not hardware & simulator
    assert simulator_controls(SimulatedDevice()) is not None


@pytest.mark.parametrize(
    ("text", "simulated", "paced", "label"),
    [
        ("sim", True, False, "sim"),
        ("serial:/dev/ttyUSB0", False, True, "serial:/dev/ttyUSB0"),
        ("serial:loop://", False, True, "serial:loop://"),
    ],
)
def test_device_spec(text: str, simulated: bool, paced: bool, label: str) -> None:
    spec = DeviceSpec.parse(text)
    assert (spec.simulated, spec.paced, spec.label) == (simulated, paced, label)
    assert spec.host_paces is False
    assert DeviceSpec.simulator(paced=True).host_paces


@pytest.mark.parametrize(
    "text", ["", "simulator", "serial", "serial:", "usb:/dev/x", "SIM", "sim:x"]
)
def test_a_device_spec_that_names_nothing_is_refused(text: str) -> None:
    with pytest.raises(HapticsInputError, match="use sim or serial:PORT"):
        DeviceSpec.parse(text)


def test_a_new_simulated_device_is_one_kind(monkeypatch: pytest.MonkeyPatch) -> None:
    """A device with its own physics: its Physics class and one entry of KINDS."""
    from ctdrill.haptics import spec

    def open_feedbot(device: DeviceSpec, seed: int) -> SimulatedDevice:
        return SimulatedDevice(seed=seed, physics=FeedRobot(2.0, 1e-4))

    kind = spec.DeviceKind(simulated=True, needs_port=False, opener=open_feedbot)
    monkeypatch.setitem(spec.KINDS, "feedbot", kind)
    device_spec = DeviceSpec.parse("feedbot")
    assert device_spec.simulated and device_spec.label == "feedbot"
    device = device_spec.open(seed=0)
    assert isinstance(device, SimulatedDevice) and isinstance(device.emulator.physics, FeedRobot)
    with pytest.raises(HapticsInputError, match="use sim or serial:PORT or feedbot"):
        DeviceSpec.parse("feedbot:x")

"""What one OpenIGTLink frame says: the target, the poses and the forces (pure functions).

A frame is the newest telemetry sample of a session's block, sent as

- ``TRANSFORM "DrillTip"``: the drill tip's pose at the sample's drill depth;
- ``STRING "Forces"``: :func:`forces_doc` as JSON (UTF-8);
- ``TRANSFORM "Implant"``: the plan's implant when it has one (where
  :func:`ctdrill.imaging.plan.implants.implant_placement` puts it), with the first frame and
  then once a second;
- ``STRING "Drill"`` (a drill sequence only, first in its frame): :class:`StreamDrill` as
  JSON, with a session's first frame (the drill changed) and then with ``Implant``.

Poses are computed in LPS (the world frame) and converted to RAS, 3D Slicer's frame, only in
:func:`to_ras` (x and y negated). The axis frame of both transforms (:func:`axis_frame_lps`):
``z`` is the drill axis pointing into the bone (entry to target); ``x`` is the patient's right
made perpendicular to the axis (anterior instead when the axis is within 45 degrees of
right-left); ``y = z x x``. The drill tip's origin is the tip point, the implant's its apex: a
tool model drawn with its tip at the origin and its body along ``-z`` sits where it should.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from ctdrill.app.errors import AppInputError
from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.session import STATE_NAMES

if TYPE_CHECKING:
    from pyigtl import MessageBase

    from ctdrill.imaging.plan.types import Plan

#: The port 3D Slicer's OpenIGTLinkIF connector listens on by default.
SLICER_PORT = 18944
#: Message names (device names) of a frame: fixed (issue 28's contract).
DRILL_TIP = "DrillTip"
IMPLANT = "Implant"
FORCES = "Forces"
#: A drill sequence's ``STRING`` naming the drill whose session streams (``StreamDrill``).
DRILL = "Drill"
#: ``Forces`` JSON fields, in order (``forces_doc``).
FORCE_FIELDS = (
    "time_s",
    "state",
    "drill_depth_mm",
    "master_depth_mm",
    "hand_force_n",
    "device_force_n",
    "cutting_force_n",
    "wall_force_n",
)
#: LPS -> RAS (and back): x and y negated.
LPS_TO_RAS = np.diag([-1.0, -1.0, 1.0, 1.0])
#: Beyond this |cos| between the axis and right-left, ``x`` follows anterior instead.
_AXIS_NEAR_X_COS = math.cos(math.radians(45.0))


@dataclass(frozen=True)
class IgtlTarget:
    """An OpenIGTLink server to stream to (``--igtl HOST:PORT``)."""

    host: str
    port: int

    @property
    def text(self) -> str:
        """``HOST:PORT`` (an IPv6 host in brackets)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{host}:{self.port}"


def parse_target(spec: str, *, option: str = "--igtl") -> IgtlTarget:
    """``HOST:PORT`` (``localhost:18944``, ``192.168.1.20:18944``, ``[::1]:18944``).

    Raises
    ------
    AppInputError
        No host, no port, or a port that is not a whole number in 1..65535.
    """
    hint = f"give HOST:PORT, e.g. localhost:{SLICER_PORT} (3D Slicer's OpenIGTLinkIF port)"
    host, sep, port_text = spec.strip().rpartition(":")
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if not sep:
        raise AppInputError(f"{option} {spec!r}: no port; {hint}")
    if not host or any(c.isspace() or c in "[]/" for c in host):
        raise AppInputError(f"{option} {spec!r}: no host name or address before the port; {hint}")
    if not (port_text.isascii() and port_text.isdigit() and 1 <= int(port_text) <= 65535):
        raise AppInputError(
            f"{option} {spec!r}: the port must be a whole number in 1..65535; {hint}"
        )
    return IgtlTarget(host, int(port_text))


@dataclass(frozen=True)
class StreamDrill:
    """Which drill of a sequence a session rehearses (the ``Drill`` message).

    Attributes
    ----------
    number : 1-based, in drilling order.
    count : the sequence's drills.
    diameter_mm : the drill's diameter, mm.
    folder : the session's records (``drill_k``, beside ``session.csv``).
    """

    number: int
    count: int
    diameter_mm: float
    folder: str

    def to_json(self) -> dict[str, Any]:
        """The ``Drill`` message's JSON object: ``drill``, ``drills``, ``diameter_mm``,
        ``folder``."""
        return {
            "drill": self.number,
            "drills": self.count,
            "diameter_mm": self.diameter_mm,
            "folder": self.folder,
        }


@dataclass(frozen=True)
class StreamGeometry:
    """Where the plan puts the drill axis and the implant (LPS, mm).

    Attributes
    ----------
    entry_lps : (3,) depth 0 on the axis.
    direction_lps : (3,) unit vector from the entry to the target.
    implant_apex_lps : (3,) the implant's apex, or None (the plan places no implant).
    """

    entry_lps: tuple[float, float, float]
    direction_lps: tuple[float, float, float]
    implant_apex_lps: tuple[float, float, float] | None = None

    @classmethod
    def of_plan(cls, plan: Plan) -> StreamGeometry:
        """The axis and implant of a plan (a drill sequence: one drill's, ``Plan.drilled``)."""
        from ctdrill.imaging.plan.implants import implant_placement

        placement = implant_placement(plan)
        return cls(
            _triple(plan.entry_lps),
            _triple(plan.direction),
            None if placement is None else _triple(placement.apex_lps),
        )

    def tip_lps(self, depth_mm: float) -> np.ndarray:
        """(3,) the drill tip at ``depth_mm`` along the axis, LPS mm."""
        return np.add(self.entry_lps, depth_mm * np.asarray(self.direction_lps))

    @cached_property
    def _entry_pose_ras(self) -> np.ndarray:
        """(4, 4) the pose at depth 0 (made once: the axis frame is the session's)."""
        return to_ras(pose_lps(self.direction_lps, self.entry_lps))

    def tip_pose_ras(self, depth_mm: float) -> np.ndarray:
        """(4, 4) ``DrillTip``: the tip's pose at ``depth_mm``, RAS mm (the pose at the entry
        moved along its own z, the drill axis)."""
        pose = self._entry_pose_ras.copy()
        pose[:3, 3] += depth_mm * pose[:3, 2]
        return pose

    def implant_pose_ras(self) -> np.ndarray | None:
        """(4, 4) ``Implant``: the implant's pose (origin at its apex), RAS mm; None without."""
        if self.implant_apex_lps is None:
            return None
        return to_ras(pose_lps(self.direction_lps, self.implant_apex_lps))


@dataclass(frozen=True)
class StreamSetup:
    """What a session streams and where (picklable: the window's session process gets it)."""

    target: IgtlTarget
    geometry: StreamGeometry

    @classmethod
    def of_plan(cls, target: IgtlTarget, plan: Plan) -> StreamSetup:
        """``target`` and the axis and implant of ``plan``."""
        return cls(target, StreamGeometry.of_plan(plan))


def _triple(v: Any) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=np.float64).reshape(3)
    return (float(a[0]), float(a[1]), float(a[2]))


def axis_frame_lps(direction_lps: Any) -> np.ndarray:
    """(3, 3) rotation whose columns are the axis frame's x, y, z in LPS (module docstring).

    ``z`` is ``direction_lps`` normalised; ``x`` the patient's right (LPS ``-x``) minus its
    component along ``z``, or anterior (LPS ``-y``) when the axis is within 45 degrees of
    right-left; ``y = z x x``. Right-handed (determinant +1).
    """
    z = np.asarray(direction_lps, dtype=np.float64).reshape(3)
    norm = float(np.linalg.norm(z))
    if not (math.isfinite(norm) and norm > 0.0):
        raise ValueError(f"the drill axis must be a finite non-zero vector, got {z.tolist()}")
    z = z / norm
    ref = np.array([-1.0, 0.0, 0.0])  # the patient's right
    if abs(float(z @ ref)) > _AXIS_NEAR_X_COS:
        ref = np.array([0.0, -1.0, 0.0])  # anterior
    x = ref - (ref @ z) * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def pose_lps(direction_lps: Any, origin_lps: Any) -> np.ndarray:
    """(4, 4) pose in LPS: :func:`axis_frame_lps` of the direction, translated to the origin."""
    pose = np.eye(4)
    pose[:3, :3] = axis_frame_lps(direction_lps)
    pose[:3, 3] = np.asarray(origin_lps, dtype=np.float64).reshape(3)
    return pose


def to_ras(pose_lps_: np.ndarray) -> np.ndarray:
    """(4, 4) a pose in LPS expressed in RAS (the boundary: x and y negated)."""
    out: np.ndarray = LPS_TO_RAS @ pose_lps_
    return out


def forces_doc(sample: TelemetrySample, time_s: float) -> dict[str, Any]:
    """The ``Forces`` message's JSON object (:data:`FORCE_FIELDS`).

    ``time_s`` is the session time (``session.csv``'s, rounded as there to 0.1 ms); ``state``
    the device state; depths in mm; forces in N: ``hand_force_n`` the device's reading of
    the hand (its reaction-force observer), ``device_force_n`` the force it renders (> 0
    opposes the advance; < 0 only from the release damper braking a released handle), split
    by state into ``cutting_force_n`` (while cutting: the
    material's resistance through the coupling) and ``wall_force_n`` (while stopped: the
    stop's wall), 0 otherwise.
    """
    state = STATE_NAMES.get(sample.state, "?")
    device = float(sample.force_cmd_n)
    pushing = max(device, 0.0)
    return {
        "time_s": round(float(time_s), 4),
        "state": state,
        "drill_depth_mm": round(float(sample.drill_mm), 5),
        "master_depth_mm": round(float(sample.master_mm), 5),
        "hand_force_n": round(float(sample.force_est_n), 4),
        "device_force_n": round(device, 4),
        "cutting_force_n": round(pushing, 4) if state == "cutting" else 0.0,
        "wall_force_n": round(pushing, 4) if state == "stopped" else 0.0,
    }


def frame_messages(
    geometry: StreamGeometry,
    sample: TelemetrySample,
    time_s: float,
    *,
    timestamp: float,
    with_implant: bool,
    drill: StreamDrill | None = None,
) -> list[MessageBase]:
    """One frame's messages: ``Drill`` when given (a drill sequence: the drill whose session
    this is), ``DrillTip``, ``Forces``, then ``Implant`` when asked and known.

    ``timestamp`` (s since 1970) is each message's header timestamp: when the host received
    the sample. A non-finite value of the JSON is sent as ``null``; the caller skips samples
    whose drill depth is not finite (no pose can be made of them).
    """
    import pyigtl  # lazily: only a streaming session needs it

    doc = forces_doc(sample, time_s)
    text = json.dumps({k: (v if _finite(v) else None) for k, v in doc.items()})
    messages: list[MessageBase] = []
    if drill is not None:
        drill_text = json.dumps(drill.to_json())
        messages.append(pyigtl.StringMessage(drill_text, timestamp=timestamp, device_name=DRILL))
    messages += [
        pyigtl.TransformMessage(
            geometry.tip_pose_ras(sample.drill_mm), timestamp=timestamp, device_name=DRILL_TIP
        ),
        pyigtl.StringMessage(text, timestamp=timestamp, device_name=FORCES),
    ]
    implant = geometry.implant_pose_ras() if with_implant else None
    if implant is not None:
        messages.append(pyigtl.TransformMessage(implant, timestamp=timestamp, device_name=IMPLANT))
    return messages


def _finite(value: Any) -> bool:
    return not isinstance(value, float) or math.isfinite(value)

"""The stop-yourself exercise: the aids fade level by level, from all of them to none.

Each level is an exercise of its own (its name is the session's ``mode``, e.g.
``stop-yourself:no-gauges``) with a pass mark. The aids, in the order they go:

* ``plots``: the live force and HU plots;
* ``clearance``: the clearance readout (how far the drill is from the margin);
* ``gauges``: the force and depth gauges of the hand;
* ``wall``: the device's wall at the margin. Without it the wall moves to the canal's surface
  (exam mode, :mod:`ctdrill.app.trainee.exam`): the device never lets the drill into the canal,
  the breach of the margin is measured.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ctdrill.app.errors import AppInputError

#: The exercise's name; a level's mode is ``stop-yourself:LEVEL``.
STOP_YOURSELF = "stop-yourself"
#: The aids, in the order they fade.
AIDS = ("plots", "clearance", "gauges", "wall")


@dataclass(frozen=True)
class AidLevel:
    """One level: which aids are on, and the score that passes it."""

    name: str
    plots: bool
    clearance: bool
    gauges: bool
    wall: bool
    pass_mark: float

    @property
    def mode(self) -> str:
        """The sessions' ``mode`` at this level."""
        return f"{STOP_YOURSELF}:{self.name}"

    def aids(self) -> tuple[str, ...]:
        """The aids on at this level, in :data:`AIDS` order."""
        return tuple(a for a in AIDS if getattr(self, a))

    def summary(self) -> dict[str, Any]:
        """A session's ``summary.json`` keys at this level: ``mode`` and ``aids``."""
        return {"mode": self.mode, "aids": {"level": self.name, "on": list(self.aids())}}

    def describe(self) -> str:
        """The level in words."""
        on = self.aids()
        off = [a for a in AIDS if a not in on]
        wall = (
            ""
            if self.wall
            else "; exam mode: no wall at the margin (on the robot the wall stands at the "
            "canal's surface)"
        )
        return f"aids on: {', '.join(on) or 'none'}; off: {', '.join(off) or 'none'}{wall}"


#: The levels, from all aids to none. The pass marks rise as the aids go: the score's scale
#: (docs/rehearse.md) puts every session that kept the margin at 50 or more.
AID_LEVELS: tuple[AidLevel, ...] = (
    AidLevel("all-aids", True, True, True, True, 70.0),
    AidLevel("no-plots", False, True, True, True, 70.0),
    AidLevel("no-readout", False, False, True, True, 70.0),
    AidLevel("no-gauges", False, False, False, True, 65.0),
    AidLevel("no-wall", False, False, False, False, 60.0),
)


def aid_level(name: str) -> AidLevel:
    """The level named ``name``.

    Raises
    ------
    AppInputError
        An unknown name (the message lists the levels).
    """
    for level in AID_LEVELS:
        if level.name == name:
            return level
    names = ", ".join(level.name for level in AID_LEVELS)
    raise AppInputError(f"--aids {name!r}: not an aid level; use one of {names}")

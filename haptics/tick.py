"""The device's control tick, defined once.

The paper's master runs its control loop at 10 kHz (0.1 ms, DESIGN.md sections 3 and 5): the
renderer, the force controller around it, the emulator and the loop's stability analysis all
step at this rate unless told otherwise.
"""

from __future__ import annotations

#: Control ticks per second, Hz.
TICK_HZ = 10_000
#: One control tick, s.
TICK_S = 1.0 / TICK_HZ

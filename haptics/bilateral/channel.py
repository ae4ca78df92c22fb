"""A one-way link between the robots: delay, jitter and loss, deterministic from a seed.

A packet sent at tick ``k`` arrives at tick ``k + round((delay + U(0, jitter)) / dt)``, never
before the packet sent before it (a link keeps order), unless it is lost (probability
``loss``); the receiver holds the last packet that arrived. All randomness comes from one
:class:`random.Random` seeded by the caller, so a run replays bit for bit.
"""

from __future__ import annotations

import random
from collections import deque

from ctdrill.haptics.bilateral.params import ChannelSpec

Packet = tuple[float, float, float]


class Channel:
    """A FIFO link of :class:`ChannelSpec` ticking at ``tick_hz``.

    Parameters
    ----------
    spec : ChannelSpec
    tick_hz : float
    seed : int
        Seeds the jitter and the loss.
    initial : tuple of float
        What the receiver holds before the first packet arrives.
    """

    def __init__(self, spec: ChannelSpec, tick_hz: float, seed: int, initial: Packet) -> None:
        self._delay = spec.delay_ms * 1e-3 * tick_hz
        self._jitter = spec.jitter_ms * 1e-3 * tick_hz
        self._loss = spec.loss
        self._rng = random.Random(seed)
        self._queue: deque[tuple[int, Packet]] = deque()
        self._last_arrival = -1
        self.held: Packet = initial
        self.sent = 0
        self.lost = 0

    def send(self, tick: int, packet: Packet) -> None:
        """Send ``packet`` at ``tick``."""
        self.sent += 1
        jitter = self._rng.random() * self._jitter if self._jitter > 0.0 else 0.0
        if self._loss > 0.0 and self._rng.random() < self._loss:
            self.lost += 1
            return
        arrival = tick + round(self._delay + jitter)
        if arrival < self._last_arrival:
            arrival = self._last_arrival
        self._last_arrival = arrival
        self._queue.append((arrival, packet))

    def receive(self, tick: int) -> Packet:
        """The newest packet arrived by ``tick`` (held: the last one before)."""
        q = self._queue
        while q and q[0][0] <= tick:
            self.held = q.popleft()[1]
        return self.held

"""Typed events of plain objects: ``connect``, ``disconnect``, ``emit``; no Qt.

An :class:`Event` declared on a class (``plan_changed = Event(object)``) gives every instance
its own :class:`BoundEvent`; ``emit`` calls the connected callbacks at once, in the order they
were connected, with the values it is given (their count and types checked against the
declaration: a wrong emit is a bug, raised at the emitter).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any


class BoundEvent:
    """One object's event: the callbacks connected to it."""

    def __init__(self, name: str, types: tuple[type, ...]) -> None:
        self.name = name
        self.types = types
        self._callbacks: list[Callable[..., Any]] = []

    def connect(self, callback: Callable[..., Any]) -> None:
        """Call ``callback`` with the event's values on every :meth:`emit`."""
        self._callbacks.append(callback)

    def disconnect(self, callback: Callable[..., Any] | None = None) -> None:
        """Stop calling ``callback`` (every callback when None); an unknown one is ignored."""
        if callback is None:
            self._callbacks.clear()
        else:
            self._callbacks = [c for c in self._callbacks if c != callback]

    def emit(self, *values: Any) -> None:
        """Call every connected callback with ``values`` (checked against the event's types:
        ``float`` takes an ``int``, ``object`` anything)."""
        if len(values) != len(self.types):
            raise TypeError(f"{self.name} takes {len(self.types)} values, {len(values)} given")
        for value, tp in zip(values, self.types, strict=True):
            ok = tp is object or isinstance(value, tp)
            if not ok and tp is float and isinstance(value, int) and not isinstance(value, bool):
                ok = True
            if not ok:
                raise TypeError(f"{self.name}: {value!r} is not a {tp.__name__}")
        for callback in list(self._callbacks):
            callback(*values)


class Event:
    """An event declared on a class; each instance gets its own :class:`BoundEvent`."""

    def __init__(self, *types: type) -> None:
        self.types = types
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: object, owner: type | None = None) -> Any:
        if obj is None:
            return self
        bound = BoundEvent(self.name, self.types)
        obj.__dict__[self.name] = bound  # found there from now on (a non-data descriptor)
        return bound


def events_of(cls: type) -> tuple[str, ...]:
    """The names of the :class:`Event` attributes of ``cls`` (its bases' included), in order."""
    seen: dict[str, None] = {}
    for klass in reversed(cls.__mro__):
        for name, value in vars(klass).items():
            if isinstance(value, Event):
                seen[name] = None
    return tuple(seen)

"""The clock a CAN bus runs on, declared here so that ``can_bus`` stands alone.

Any object with an integer ``now`` (ticks) and ``at(when, fn, *args)`` returning something
with ``cancel()`` will do: the project's discrete-event scheduler, a real-time scheduler, or a
test's own. A clock may also offer ``at_top(when, fn, *args)``, for an event that runs before
every other event of its tick (the project's scheduler does); the wheel's 1 ms steps use it
when it is there. Bit timing says how many ticks a bit takes, so the tick rate is a parameter of
:class:`~can_bus.bits.BitTiming` (``tick_hz``), not a property of the clock.
"""
from __future__ import annotations

from typing import Any, Callable, Protocol

__all__ = ["Cancellable", "Clock", "DEFAULT_TICK_HZ"]

DEFAULT_TICK_HZ = 16_000_000
"""Ticks per second when nothing else is said: the MB90F549's 16 MHz machine clock."""


class Cancellable(Protocol):
    """A scheduled callback that can be called off; ``when`` is its tick (the bus looks at
    it to keep an arbitration already due)."""

    when: int

    def cancel(self) -> None: ...


class Clock(Protocol):
    """Integer-tick time: ``now`` only moves forward; ``at`` runs ``fn(*args)`` at ``when``."""

    @property
    def now(self) -> int: ...

    def at(self, when: int, fn: Callable[..., Any], *args: Any) -> Cancellable: ...

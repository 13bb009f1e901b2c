"""Integer-tick discrete-event scheduler: the 16 MHz machine clock of every simulated part.

Time is a Python ``int`` count of ticks (62.5 ns at 16 MHz). Events at the same tick run in the
order they were scheduled (FIFO), which makes every run with the same inputs identical.
Cancelling is lazy: a cancelled entry stays in the heap and is skipped when it comes up, so
re-arming a timer costs one heap push and nothing else.
"""
from __future__ import annotations

import heapq
from typing import Any, Callable


class Event:
    """A scheduled callback. ``cancel()`` makes it a no-op; ``when`` is its tick."""

    __slots__ = ("when", "fn", "args", "cancelled")

    def __init__(self, when: int, fn: Callable[..., Any], args: tuple) -> None:
        self.when = when
        self.fn = fn
        self.args = args
        self.cancelled = False

    def cancel(self) -> None:
        self.cancelled = True

    def __repr__(self) -> str:  # pragma: no cover - debugging aid
        state = " cancelled" if self.cancelled else ""
        return f"<Event t={self.when} {getattr(self.fn, '__qualname__', self.fn)}{state}>"


class Scheduler:
    """A heap of (tick, sequence, Event). ``now`` only moves forward."""

    __slots__ = ("now", "_heap", "_seq")

    def __init__(self, start: int = 0) -> None:
        self.now = start
        self._heap: list[tuple[int, int, Event]] = []
        self._seq = 0

    def at(self, when: int, fn: Callable[..., Any], *args: Any) -> Event:
        """Run ``fn(*args)`` at tick ``when`` (which must not be in the past)."""
        if when < self.now:
            raise ValueError(f"cannot schedule at tick {when}: now is tick {self.now}")
        ev = Event(when, fn, args)
        self._seq += 1
        heapq.heappush(self._heap, (when, self._seq, ev))
        return ev

    def after(self, delay: int, fn: Callable[..., Any], *args: Any) -> Event:
        """Run ``fn(*args)`` ``delay`` ticks from now."""
        return self.at(self.now + delay, fn, *args)

    def next_time(self) -> int | None:
        """Tick of the earliest live event, or None when nothing is scheduled."""
        heap = self._heap
        while heap and heap[0][2].cancelled:
            heapq.heappop(heap)
        return heap[0][0] if heap else None

    def run_until(self, end: int) -> None:
        """Run every event with tick <= ``end``; afterwards ``now == end``."""
        heap = self._heap
        pop = heapq.heappop
        while heap and heap[0][0] <= end:
            when, _, ev = pop(heap)
            if ev.cancelled:
                continue
            self.now = when
            ev.fn(*ev.args)
        if end > self.now:
            self.now = end

    def step(self) -> bool:
        """Run the next live event; False when there is none."""
        t = self.next_time()
        if t is None:
            return False
        when, _, ev = heapq.heappop(self._heap)
        self.now = when
        ev.fn(*ev.args)
        return True

    def __len__(self) -> int:
        return sum(1 for _, _, ev in self._heap if not ev.cancelled)

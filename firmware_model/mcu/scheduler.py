"""Integer-tick discrete-event scheduler: the 16 MHz machine clock of every simulated part.

Time is a Python ``int`` count of ticks (62.5 ns at 16 MHz). Events at the same tick run in the
order they were scheduled (FIFO), which makes every run with the same inputs identical.
Cancelling is lazy: a cancelled entry stays in the heap and is skipped when it comes up, so
re-arming a timer costs one heap push and nothing else.

A part of the world may run as a *domain* (the simulator runs a child's CAN side so): its
events, scheduled with :meth:`Scheduler.at_first`, run before every other event of the same
tick (FIFO among themselves). That makes the order of simultaneous events in independent parts
a rule rather than an accident of when each was scheduled, so a domain can be taken out of
the heap (:meth:`Scheduler.take`) and put back (:meth:`Scheduler.put_back`) without changing
what runs first.

A physical step of a model (a wheel's 1 ms control step) may be scheduled with
:meth:`Scheduler.at_top`: it runs before every other event of its tick, so whatever looks at
that model during tick T sees the state after the step at T. That is what lets a model skip
its steps while they only repeat (a cruising wheel) and give the state at any tick in closed
form: no observer's place in the tick depends on when it was scheduled.
"""
from __future__ import annotations

import heapq
from typing import Any, Callable, Protocol


_FIRST = 1 << 62
"""Subtracted from a domain event's sequence number once per rank: rank 1 (a domain's event)
sorts before every rank-0 event at its tick, rank 2 (a step, :meth:`Scheduler.at_top`)
before every rank-1 and rank-0 event."""


class Event:
    """A scheduled callback. ``cancel()`` makes it a no-op; ``when`` is its tick."""

    __slots__ = ("when", "fn", "args", "cancelled", "owner", "rank")

    def __init__(self, when: int, fn: Callable[..., Any], args: tuple,
                 owner: object = None, rank: int = 0) -> None:
        self.when = when
        self.fn = fn
        self.args = args
        self.cancelled = False
        self.owner = owner
        self.rank = rank
        """0: an ordinary event, 1: a domain's, 2: a step's (module docstring)."""

    def cancel(self) -> None:
        self.cancelled = True

    def __repr__(self) -> str:  # pragma: no cover - debugging aid
        state = " cancelled" if self.cancelled else ""
        return f"<Event t={self.when} {getattr(self.fn, '__qualname__', self.fn)}{state}>"


class Clock(Protocol):
    """What a part that only schedules needs of its clock (ticks): ``now``, and ``at(when,
    fn, *args)`` giving the :class:`Event`. A :class:`Scheduler` is one; so is the clock of a
    domain the simulator runs apart (hil/sim/quiet_can.py's ``DomainClock``)."""

    @property
    def now(self) -> int: ...

    def at(self, when: int, fn: Callable[..., Any], *args: Any) -> Event: ...


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

    def at_first(self, owner: object, when: int, fn: Callable[..., Any], *args: Any) -> Event:
        """Like :meth:`at`, for an event of the domain ``owner``: at its tick it runs before
        every event scheduled with :meth:`at` (module docstring)."""
        if when < self.now:
            raise ValueError(f"cannot schedule at tick {when}: now is tick {self.now}")
        ev = Event(when, fn, args, owner, 1)
        self._seq += 1
        heapq.heappush(self._heap, (when, self._seq - _FIRST, ev))
        return ev

    def at_top(self, when: int, fn: Callable[..., Any], *args: Any,
               owner: object = None) -> Event:
        """Like :meth:`at`, for a model's physical step: at its tick it runs before every
        other event, domain events included (module docstring). ``owner``: the domain the
        step belongs to, if any."""
        if when < self.now:
            raise ValueError(f"cannot schedule at tick {when}: now is tick {self.now}")
        ev = Event(when, fn, args, owner, 2)
        self._seq += 1
        heapq.heappush(self._heap, (when, self._seq - 2 * _FIRST, ev))
        return ev

    def pending(self, owner: object) -> list[Event]:
        """``owner``'s live events, in the order they will run."""
        return [e[2] for e in self._mine(owner)]

    def _mine(self, owner: object) -> list[tuple[int, int, Event]]:
        return sorted((e for e in self._heap if e[2].owner is owner and not e[2].cancelled),
                      key=lambda e: (e[0], e[1]))

    def take(self, owner: object) -> list[Event]:
        """Remove ``owner``'s live events from the heap; they come back in the order they
        would have run."""
        mine = self._mine(owner)
        if mine:
            # in place: run_until holds the list
            self._heap[:] = [e for e in self._heap if e[2].owner is not owner]
            heapq.heapify(self._heap)
        return [e[2] for e in mine]

    def put_back(self, events: list[Event]) -> None:
        """Schedule events of a domain again (after :meth:`take`), at their ``when``, in the
        given order among events of the same rank."""
        for ev in events:
            if ev.when < self.now:
                raise ValueError(f"cannot put back an event at tick {ev.when}: now is "
                                 f"tick {self.now}")
            self._seq += 1
            heapq.heappush(self._heap, (ev.when, self._seq - ev.rank * _FIRST, ev))

    def skip_to(self, tick: int) -> None:
        """Move ``now`` on to ``tick`` without running anything: for a model that took its
        events out (:meth:`take`), moved itself and them on by whole periods of a state that
        only repeats itself, and puts them back after (hil/sim/quiet_ring.py). Refused if a
        live event would be left behind in the past."""
        nxt = self.next_time()
        if tick < self.now or (nxt is not None and nxt < tick):
            raise ValueError(f"cannot skip from tick {self.now} to {tick}: "
                             f"an event is due at tick {nxt}")
        self.now = tick

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

"""The simulator's scheduler: the firmware's tick kernel (firmware_model/mcu/scheduler.py) and
the *domains* the fast paths need (docs/fast-paths.md).

A part of the world may run as a domain (the simulator runs a child's CAN side so): its
events, scheduled with :meth:`SimScheduler.at_first`, run before every other event of the same
tick but a model's step (``Scheduler.at_top``): the domains in the order of their owners'
``order`` (a child's ID), each domain's FIFO. That makes the order of simultaneous events in
independent parts a rule rather than an accident of when each was scheduled, so a domain can
be taken out of the heap (:meth:`SimScheduler.take`) and put back (:meth:`SimScheduler.put_back`)
without changing what runs first, whenever other domains were put back (two children's CAN
frames ending at one tick are traced child 1's first, however their sides woke), and the clock
moved on past events taken out (:meth:`SimScheduler.skip_to`): hil/sim/quiet_can.py and
quiet_ring.py.
"""
from __future__ import annotations

import heapq
from typing import Any, Callable

from firmware_model.mcu.scheduler import _FIRST, Event, PlacedScheduler, Scheduler

__all__ = ["PlacedSimScheduler", "SimScheduler"]

_DOMAIN = 1 << 52
"""Added to a domain's event's sequence number per unit of its owner's ``order``: a domain's
events at a tick after those of every domain of a lower order (fewer than 2^52 events a run)."""


def _order(owner: object) -> int:
    """A domain owner's place among the domains at a tick (0 when it names none)."""
    return getattr(owner, "order", 0) * _DOMAIN


class SimScheduler(Scheduler):
    """The kernel's heap with domains: events by owner, taken out and put back."""

    __slots__ = ()

    def at_first(self, owner: object, when: int, fn: Callable[..., Any], *args: Any) -> Event:
        """Like :meth:`at`, for an event of the domain ``owner``: at its tick it runs before
        every event scheduled with :meth:`at`, after those of domains whose owner's ``order``
        is lower (module docstring)."""
        if when < self.now:
            raise ValueError(f"cannot schedule at tick {when}: now is tick {self.now}")
        ev = Event(when, fn, args, owner, 1)
        self._seq += 1
        heapq.heappush(self._heap, (when, self._seq - _FIRST + _order(owner), ev))
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
        self.settle_later()            # (a stand-in keeps its place only in this heap)
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
            key = self._seq - ev.rank * _FIRST + (_order(ev.owner) if ev.rank == 1 else 0)
            heapq.heappush(self._heap, (ev.when, key, ev))

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


class PlacedSimScheduler(PlacedScheduler, SimScheduler):
    """The simulator's scheduler for worlds on the CPU model: domains, and stand-ins
    (``PlacedScheduler.at_later``: a lone handler's one event)."""

    __slots__ = ()

"""Integer-tick discrete-event scheduler: the 16 MHz machine clock of every simulated part.

Time is a Python ``int`` count of ticks (62.5 ns at 16 MHz). Events at the same tick run in the
order they were scheduled (FIFO), which makes every run with the same inputs identical.
Cancelling is lazy: a cancelled entry stays in the heap and is skipped when it comes up, so
re-arming a timer costs one heap push and nothing else.

A simulator may run a part of the world as a *domain* whose events come first at their tick
and that it can take out of the heap and put back: hil/sim/domains.py's ``SimScheduler`` adds
that to this kernel, which the firmware and the bench need no more of.

A physical step of a model (a wheel's 1 ms control step) may be scheduled with
:meth:`Scheduler.at_top`: it runs before every other event of its tick, so whatever looks at
that model during tick T sees the state after the step at T. That is what lets a model skip
its steps while they only repeat (a cruising wheel) and give the state at any tick in closed
form: no observer's place in the tick depends on when it was scheduled.

:class:`PlacedScheduler` also knows where the run is (the tick and the running event's
sequence number), so that an event scheduled now may stand in for one that would be
scheduled later, in its place among the events of its tick (:meth:`PlacedScheduler.at_later`:
the CPU model's lone handler, one event where the general path has two).
"""
from __future__ import annotations

import heapq
from heapq import heappush as _heappush
from typing import Any, Callable, Protocol


_FIRST = 1 << 62
"""Subtracted from an event's sequence number once per rank: rank 1 (a simulator domain's
event, hil/sim/domains.py) sorts before every rank-0 event at its tick, rank 2 (a step,
:meth:`Scheduler.at_top`) before every rank-1 and rank-0 event."""


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


Later = tuple
"""A stand-in (:meth:`PlacedScheduler.at_later`): (``after``, ``seq``, the event, ``met``)."""

_WATCHED = 32
"""Ticks of stand-ins kept before those past are dropped (``at_later``; then twice as many
as are left)."""


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

    positions = False
    """No event stands in for one scheduled later (:class:`PlacedScheduler` has them)."""

    def __init__(self, start: int = 0) -> None:
        self.now = start
        self._heap: list[tuple[int, int, Event]] = []
        self._seq = 0

    def at(self, when: int, fn: Callable[..., Any], *args: Any) -> Event:
        """Run ``fn(*args)`` at tick ``when`` (which must not be in the past)."""
        if when < self.now:
            raise ValueError(f"cannot schedule at tick {when}: now is tick {self.now}")
        ev = Event(when, fn, args)
        seq = self._seq = self._seq + 1
        _heappush(self._heap, (when, seq, ev))
        return ev

    def settle_later(self) -> None:
        """No stand-ins here (:meth:`PlacedScheduler.settle_later`)."""

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

    def at_before(self, when: int, fn: Callable[..., Any], first: Callable[[Event], bool],
                  *args: Any) -> Event:
        """Like :meth:`at`, but before the first live ordinary event due at ``when`` for which
        ``first(event)`` holds: for an event that stands for one scheduled earlier (a CPU's
        milestone, firmware_model/mcu/cpu.py ``Cpu._reti_in_place``). The events due then
        from that one on keep their order after it."""
        heap = self._heap
        due = sorted((e for e in heap if e[0] == when and e[2].rank == 0
                      and not e[2].cancelled), key=lambda e: e[1])
        i = next((i for i, e in enumerate(due) if first(e[2])), None)
        if i is None:
            return self.at(when, fn, *args)
        moved = {id(e[2]) for e in due[i:]}
        heap[:] = [e for e in heap if id(e[2]) not in moved]      # in place: run_until holds it
        heapq.heapify(heap)
        ev = self.at(when, fn, *args)
        for _, _, e in due[i:]:
            self._seq += 1
            heapq.heappush(heap, (when, self._seq, e))
        return ev

    def reserve(self) -> int:
        """A sequence number taken now, for events scheduled later (:meth:`at_seq`) that must
        run, among the events due at their tick, where events scheduled now would: after
        those scheduled before, before those scheduled after."""
        self._seq += 1
        return self._seq

    def at_seq(self, when: int, seq: int, fn: Callable[..., Any], *args: Any) -> Event:
        """Like :meth:`at`, in the place of sequence number ``seq`` (:meth:`reserve`); the
        caller has at most one event pending per tick under one ``seq``. (It meets no
        stand-in, :meth:`PlacedScheduler.at_later`: ``seq`` was taken where one would have
        been met.)"""
        if when < self.now:
            raise ValueError(f"cannot schedule at tick {when}: now is tick {self.now}")
        ev = Event(when, fn, args)
        heapq.heappush(self._heap, (when, seq, ev))
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


class PlacedScheduler(Scheduler):
    """A :class:`Scheduler` that knows where the run is (``now`` and ``cur``, the running
    event's sequence number), so that an event may stand in for one to be scheduled later
    (:meth:`at_later`): the CPU model's (firmware_model/mcu/cpu.py, a lone handler). Each
    scheduling looks for stand-ins due at its tick; the ideal CPU's worlds run on the plain
    :class:`Scheduler`, which does not."""

    __slots__ = ("cur", "_later", "_watched")

    positions = True

    def __init__(self, start: int = 0) -> None:
        super().__init__(start)
        self.cur = 0
        """The sequence number of the event running (with ``now``, where the run is)."""
        self._later: dict[int, list[Later]] = {}
        """Stand-ins (:meth:`at_later`) by tick, while their places may differ from those of
        the events they stand in for (and some whose events have run, dropped in time)."""
        self._watched = _WATCHED

    def at(self, when: int, fn: Callable[..., Any], *args: Any) -> Event:
        """Run ``fn(*args)`` at tick ``when`` (which must not be in the past)."""
        if when < self.now:
            raise ValueError(f"cannot schedule at tick {when}: now is tick {self.now}")
        ev = Event(when, fn, args)
        seq = self._seq = self._seq + 1
        _heappush(self._heap, (when, seq, ev))
        if when in self._later:
            self._met(when, None)
        return ev

    def at_later(self, when: int, after: int, fn: Callable[..., Any],
                 met: Callable[[int, Scheduler], None], *args: Any) -> Later:
        """Run ``fn(*args)`` at tick ``when``, in the place among the events due then of an
        event that would be scheduled at the run's position (``after``, s), s a sequence
        number taken now: a stand-in scheduled now, which saves the event that would schedule
        the other (a CPU's lone handler: its body's end, scheduled at its entry's end,
        firmware_model/mcu/cpu.py). The two places are one unless an ordinary event due at
        ``when`` is scheduled before the run reaches (``after``, s) (the event at another
        stand-in's position counts, as scheduled when that stand-in is), or another stand-in
        for ``when`` whose position comes earlier: then ``met(s, self)`` is called at once,
        and the caller replaces the stand-in by the event at (``after``, s) (:meth:`at_seq`)
        if the run has not reached that position (``reached``). ``met`` may be called again
        (a later meeting, :meth:`settle_later`): the caller ignores a stand-in it replaced
        or whose event ran. Returns (``after``, s, the event, ``met``)."""
        if when < self.now:
            raise ValueError(f"cannot schedule at tick {when}: now is tick {self.now}")
        seq = self._seq = self._seq + 1
        ev = Event(when, fn, args)
        _heappush(self._heap, (when, seq, ev))
        later = (after, seq, ev, met)
        watch = self._later
        if after in watch:
            self._met(after, None)     # the event at (after, seq) is scheduled now, in effect
        mates = watch.get(when)
        if mates is None:
            if len(watch) >= self._watched:
                self._drop_past()
                self._watched = max(_WATCHED, 2 * len(watch))
            watch[when] = [later]
        else:
            self._met(when, later)
            mates.append(later)
        return later

    def passed(self, when: int) -> None:
        """A stand-in due at ``when`` runs now: every stand-in due then has reached its
        position (earlier than ``when``), none is watched any longer."""
        self._later.pop(when, None)

    def settle_later(self) -> None:
        """Every stand-in (:meth:`at_later`) met now, as if an event due at its tick had been
        scheduled: one whose position the run has reached is its event from now on, the others
        replaced. Before the heap's events are taken out or compared (hil/sim/quiet_ring.py)."""
        watch = self._later
        self._later = {}
        for mates in watch.values():
            for later in mates:
                later[3](later[1], self)

    def reached(self, tick: int, seq: int) -> bool:
        """Has the run reached the position (``tick``, ``seq``) of an ordinary event (the
        event running now comes before it if its own is earlier)?"""
        return self.now > tick or (self.now == tick and self.cur > seq)

    def _met(self, when: int, new: Later | None) -> None:
        """An event due at ``when`` was just scheduled, at the run's position, or ``new``, a
        stand-in at its own: each stand-in due then whose position the run has not reached
        and comes after that one's is met (:meth:`at_later`)."""
        for later in self._later[when]:
            if not self.reached(later[0], later[1]) and (new is None or later[0] > new[0]):
                later[3](later[1], self)

    def reserve(self) -> int:
        """:meth:`Scheduler.reserve`; every stand-in whose position the run has not reached
        is met (:meth:`at_later`): an event in the place of this number may be scheduled
        after the run reached it."""
        self._seq += 1
        if self._later:
            # (the ticks before now first: their stand-ins' positions are reached, and every
            # reservation, one a late byte on the CPU model, would walk them again)
            self._drop_past()
            for mates in self._later.values():
                for later in mates:
                    if not self.reached(later[0], later[1]):
                        later[3](later[1], self)
        return self._seq

    def _drop_past(self) -> None:
        """Forget the stand-ins due before now: each ran, or was replaced or given up."""
        watch, now = self._later, self.now
        for tick in [t for t in watch if t < now]:
            del watch[tick]

    def run_until(self, end: int) -> None:
        """:meth:`Scheduler.run_until`, noting each event's sequence number (``cur``): the
        kernel's loop with one store more, kept apart so that the plain kernel's stays as
        it is."""
        heap = self._heap
        pop = heapq.heappop
        while heap and heap[0][0] <= end:
            when, seq, ev = pop(heap)
            if ev.cancelled:
                continue
            self.now = when
            self.cur = seq
            ev.fn(*ev.args)
        if end > self.now:
            self.now = end

    def step(self) -> bool:
        """:meth:`Scheduler.step`, noting the event's sequence number (``cur``)."""
        if self.next_time() is None:
            return False
        self.cur = self._heap[0][1]
        return super().step()

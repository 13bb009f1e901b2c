"""The F2MC-16LX core as the firmware sees it: interrupt levels, nesting and the time handlers
take, on the integer-tick scheduler (one machine cycle = one tick at 16 MHz).

What is modelled (F2MC-16LX hardware manuals, "Interrupts": MB90420/5 §6.4.5, MB90560 §6.7):

* **Levels.** Each interrupt source has a level 0-7 in its ICR register (0 the highest, 7 =
  never accepted). The CPU accepts a request whose level is below the interrupt level mask
  ILM; accepting it sets ILM to that level, so only a higher level (a lower number) can
  interrupt the handler: handlers nest. Requests at one level wait for the running one and
  are then taken in interrupt-number order (the lower number first).
* **Cost.** Accepting an interrupt takes ``entry`` machine cycles (saving the dedicated
  registers and fetching the vector: 24 + 6 x Z, Z = 0 for a stack in internal RAM at an even
  address) and returning takes ``reti`` cycles (RETI: 11 + 6 x Z). Both are atomic: a request
  arriving then is accepted when they end. Between them the handler's body runs for the cycles
  the cost table charges it (firmware_model/cycle_costs.py).
* **The main loop** runs below every interrupt (ILM 7). Work queued for it (``task``) runs in
  order, and any accepted interrupt preempts it.

How a handler's effects show: its ``enter`` callback (the register reads at the start of the
body, e.g. taking the byte out of the UART's receive register) runs when the entry sequence
ends; its main callback (everything else it does: the bytes it sends, the CAN frames it
requests) runs when its body's cycles are done, however often it was preempted in between.
The running instruction's remaining cycles before a request is sampled are not simulated (the
model runs no instructions); ``CycleCosts.sample_wait_max`` bounds them in the report.

``Cpu(sched, None)`` is the ideal CPU: every handler runs in zero ticks on the tick of its
request, exactly as the firmware model ran before there was a CPU (the paper's timing).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any, Callable

from .scheduler import Clock, Event

MAIN_LEVEL = 7
"""ILM while the main loop runs: every enabled interrupt (levels 0-6) is accepted."""


@dataclass(frozen=True)
class Vector:
    """One interrupt source as the firmware programs it: its ICR level (0 highest, 7
    disabled) and its interrupt number (the lower wins among requests of one level)."""

    name: str
    level: int
    number: int

    def __post_init__(self) -> None:
        if not 0 <= self.level <= 7:
            raise ValueError(f"{self.name}: interrupt level must be 0-7 (ICR IL2-IL0), "
                             f"got {self.level}")


class HandlerStats:
    """What one handler cost: calls, busy cycles (entry, body and RETI, preemptions not
    included), latency (request to acceptance) and response (request to its effects): ticks,
    counted per value (a few distinct values however long the run)."""

    STEADY_COUNTERS = ("calls",)
    """Handler calls: counts only (hil/sim/steady.py)."""

    __slots__ = ("name", "level", "calls", "busy", "latency", "response", "worst_latency",
                 "worst_response")

    def __init__(self, name: str, level: int) -> None:
        self.name = name
        self.level = level
        self.calls = 0
        self.busy = 0
        self.latency: Counter[int] = Counter()
        self.response: Counter[int] = Counter()
        self.worst_latency = 0
        self.worst_response = 0


class _Frame:
    """A handler (or main-loop task) on the CPU: its milestones in cycles of its own work."""

    __slots__ = ("stats", "level", "enter", "fn", "args", "entry", "body_end", "end", "done",
                 "since", "requested", "phase")

    def __init__(self, stats: HandlerStats, level: int, enter, fn, args, entry: int,
                 body: int, reti: int, requested: int) -> None:
        self.stats = stats
        self.level = level
        self.enter = enter
        self.fn = fn
        self.args = args
        self.entry = entry
        self.body_end = entry + body
        self.end = entry + body + reti
        self.done = 0          # cycles of its own work done
        self.since = 0         # tick it last resumed
        self.requested = requested
        self.phase = 0         # 0 entry, 1 body, 2 RETI

    def next_milestone(self) -> int:
        return (self.entry, self.body_end, self.end)[self.phase]

    def atomic(self) -> bool:
        """The entry sequence and RETI cannot be interrupted."""
        return self.phase != 1


class Cpu:
    """One F2MC-16LX core on ``sched``. ``costs`` None is the ideal (zero-time) CPU."""

    def __init__(self, sched: Clock, costs: Any = None, name: str = "CPU") -> None:
        self.sched = sched
        self.costs = costs
        self.name = name
        self.ideal = costs is None
        self.entry = 0 if costs is None else costs.entry.cycles
        self.reti = 0 if costs is None else costs.reti.cycles
        self.stats: dict[str, HandlerStats] = {}
        self._pending: list[tuple[int, int, int, int, Vector, int, Any, Any, tuple]] = []
        self._stack: list[_Frame] = []
        self._tasks: list[tuple[str, int, Any, tuple, int]] = []
        self._ev: Event | None = None
        self._seq = 0
        self._in_callback = False
        self.started = sched.now
        self.busy = 0

    # -- requests ------------------------------------------------------------------------

    def _stats(self, name: str, level: int) -> HandlerStats:
        s = self.stats.get(name)
        if s is None:
            s = self.stats[name] = HandlerStats(name, level)
        return s

    def irq(self, vector: Vector, body: int, fn: Callable[..., None], *args: Any,
            enter: Callable[[], None] | None = None) -> None:
        """The peripheral raises ``vector``'s request now; its handler's body costs ``body``
        cycles. ``enter()`` runs when the handler starts, ``fn(*args)`` when its body ends."""
        if vector.level == MAIN_LEVEL:
            return                      # ICR level 7: the request is never accepted
        if self.ideal:
            s = self.stats.get(vector.name)
            if s is None:
                s = self._stats(vector.name, vector.level)
            s.calls += 1
            if enter is not None:
                enter()
            fn(*args)
            return
        now = self.sched.now
        self._seq += 1
        self._pending.append((vector.level, vector.number, self._seq, now, vector, body,
                              enter, fn, args))
        self._dispatch()

    def task(self, name: str, body: int, fn: Callable[..., None], *args: Any) -> None:
        """Queue work for the main loop: ``fn(*args)`` runs once ``body`` cycles of main-loop
        time have passed for it (after the tasks queued before it)."""
        if self.ideal:
            self._stats(name, MAIN_LEVEL).calls += 1
            fn(*args)
            return
        self._tasks.append((name, body, fn, args, self.sched.now))
        self._dispatch()

    # -- the core ------------------------------------------------------------------------

    @property
    def ilm(self) -> int:
        """The interrupt level mask: the running handler's level, 7 in the main loop."""
        for f in reversed(self._stack):
            if f.level < MAIN_LEVEL:
                return f.level
        return MAIN_LEVEL

    def _progress(self, now: int) -> None:
        """Credit the running frame with the cycles since it last resumed."""
        if self._stack:
            top = self._stack[-1]
            top.done += now - top.since
            top.since = now
        if self._ev is not None:
            self._ev.cancel()
            self._ev = None

    def _dispatch(self) -> None:
        now = self.sched.now
        stack = self._stack
        if self._in_callback or (stack and stack[-1].atomic()):
            return                     # the entry sequence / RETI ends first (its event)
        self._progress(now)
        if self._pending:
            best = min(self._pending, key=lambda p: (p[0], p[1], p[2]))
            if best[0] < self.ilm:
                self._pending.remove(best)
                level, _, _, req, vec, body, enter, fn, args = best
                s = self._stats(vec.name, level)
                s.calls += 1
                lat = now - req
                s.latency[lat] += 1
                if lat > s.worst_latency:
                    s.worst_latency = lat
                stack.append(_Frame(s, level, enter, fn, args, self.entry, body, self.reti,
                                    req))
                stack[-1].since = now
                self._schedule()
                return
        if not stack and self._tasks:
            name, body, fn, args, req = self._tasks.pop(0)
            s = self._stats(name, MAIN_LEVEL)
            s.calls += 1
            s.latency[now - req] += 1
            s.worst_latency = max(s.worst_latency, now - req)
            f = _Frame(s, MAIN_LEVEL, None, fn, args, 0, body, 0, req)
            f.phase = 1
            f.since = now
            stack.append(f)
        self._schedule()

    def _schedule(self) -> None:
        if self._stack:
            top = self._stack[-1]
            self._ev = self.sched.at(top.since + top.next_milestone() - top.done,
                                     self._milestone)

    def _milestone(self) -> None:
        now = self.sched.now
        self._ev = None
        top = self._stack[-1]
        top.done += now - top.since
        top.since = now
        self._in_callback = True         # requests made by a callback wait for it to return
        try:
            if top.phase == 0:
                top.phase = 1
                if top.enter is not None:
                    top.enter()
            elif top.phase == 1:
                fn = top.fn
                if fn is not None:
                    top.fn = None
                    resp = now - top.requested
                    s = top.stats
                    s.response[resp] += 1
                    if resp > s.worst_response:
                        s.worst_response = resp
                    fn(*top.args)
                if top.done >= top.body_end:     # extend() may have moved the body's end
                    top.phase = 2
        finally:
            self._in_callback = False
        if top.phase == 2 and top.done >= top.end:
            self._stack.pop()
            top.stats.busy += top.end
            self.busy += top.end
            if self._stack:
                self._stack[-1].since = now
        elif top.atomic():
            self._schedule()           # RETI runs on; a request now waits for its end
            return
        self._dispatch()

    def extend(self, cycles: int) -> None:
        """Called by a running handler: it goes on for ``cycles`` more after its effects
        (work whose outputs are not time-critical, e.g. the MAC's bookkeeping on a frame)."""
        if self.ideal or not self._stack or cycles <= 0:
            return
        top = self._stack[-1]
        top.body_end += cycles
        top.end += cycles

    # -- figures -------------------------------------------------------------------------

    def load(self, now: int | None = None) -> float:
        """Share of the machine cycles since the start spent in handlers and tasks."""
        now = self.sched.now if now is None else now
        span = now - self.started
        return self.busy / span if span > 0 else 0.0

    @property
    def idle(self) -> bool:
        return not self._stack and not self._pending and not self._tasks

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

**A handler alone on the CPU** (``irq(..., alone=True)``: its ``enter`` only reads what
nothing but its own body looks at) that finds the CPU idle runs without the dispatcher: an
event at its body's end, in the place of the one the general path schedules at the entry's
end (``PlacedScheduler.at_later``; an event at the entry's end where that place differs, or
on a scheduler that does not keep places), and its
RETI counted when the CPU is next asked anything. Whatever touches
the CPU while it runs (a request, a task, ``extend``) first puts it on the stack in the phase
it has reached, so what follows is the general path's to the tick. Bytes received while the
CPU is idle may be handled late, all at once (``lone_past``, Uart.receive's ``late_ok``).
A request whose handler nothing can meet (``defer``: the CPU idle, no byte handed over late
due before its RETI ends) is taken without an event: counted as run alone when the CPU is
next touched after its RETI, or, touched earlier, made the lone handler from its tick
(``irq``'s ``at``). ``fuse = False`` keeps every handler on the general path
(docs/fast-paths.md; the two are compared by tests/firmware_model/mcu/test_cpu_fused.py).

``Cpu(sched, None)`` is the ideal CPU: every handler runs in zero ticks on the tick of its
request, exactly as the firmware model ran before there was a CPU (the paper's timing).
"""
from __future__ import annotations

from typing import Any, Callable

from .handler import MAIN_LEVEL, HandlerStats, Vector, _Frame
from .scheduler import Clock, Event

__all__ = ["MAIN_LEVEL", "Cpu", "HandlerStats", "Vector"]


class Cpu:
    """One F2MC-16LX core on ``sched``. ``costs`` None is the ideal (zero-time) CPU."""

    STEADY_COUNTERS = ("_busy",)
    """Busy cycles: a count only (hil/sim/steady.py)."""

    fuse = True
    """Run a lone handler on an idle CPU without the dispatcher (module docstring); False:
    every handler on the general path (the fast-paths switch, hil/sim/config.py)."""

    def __init__(self, sched: Clock, costs: Any = None, name: str = "CPU",
                 order: int = 0) -> None:
        self.sched = sched
        self.costs = costs
        self.name = name
        self.order = order
        """Its robot's place among the radios (hil/sim/air.py: the receivers of one byte
        request their handlers in this order, ``_reti_in_place``)."""
        self.ideal = costs is None
        self.entry = 0 if costs is None else costs.entry.cycles
        self.reti = 0 if costs is None else costs.reti.cycles
        self.stats: dict[str, HandlerStats] = {}
        self._pending: list[tuple[int, int, int, Vector, int, Any, Any, tuple, bool, bool]] = []
        """Requests waiting, in the order they came: (level, number, tick, ..., alone,
        enter_now)."""
        self._stack: list[_Frame] = []
        self._tasks: list[tuple[str, int, Any, tuple, int]] = []
        self._ev: Event | None = None
        self._in_callback = False
        self.started = sched.now
        self._busy = 0
        self._alone: _Frame | None = None
        """The lone handler running without the dispatcher (module docstring), or None."""
        self._alone_ev: Event | None = None
        self._alone_later: tuple | None = None
        """Its body's end standing in for its entry's (``_alone_start``), or None."""
        self._later_ok = getattr(sched, "positions", False)
        """The scheduler keeps places (``PlacedScheduler``; a station's CPU moved to another
        scheduler moves to one of its kind: hil/sim/quiet_ring.py)."""
        self._alone_t = 0          # the tick it was accepted at
        self._enter_now = False    # its ``enter`` runs at the entry's end (``irq``)
        self.on_touch: Callable[[int, bool], None] | None = None
        """Set by a UART whose received bytes may be handed over late (``lone_past``):
        ``on_touch(now, busy)`` runs before anything asks the CPU for something (``busy``:
        a request or a task, so bytes must come at their ticks from now on) or reads its
        figures (``busy`` False)."""
        self._touching = False
        self._deferred: list[tuple[int, Vector, int, Any]] = []
        """Requests taken without an event (``defer``), in the order they came: (tick,
        vector, body cycles, owner); none but the last may still run."""
        self.late_clear: Callable[[int, int], bool] | None = None
        """Set by a UART whose handlers may be counted late (``lone_past``):
        ``late_clear(now, until)`` says none of them runs at ``now`` or is requested by
        ``until`` (``defer``)."""
        self.entered = 0
        """The tick the entry sequence of the handler whose ``enter`` runs ended (for an
        ``enter`` that notes the time: it may run later, ``alone``)."""

    # -- requests ------------------------------------------------------------------------

    def _stats(self, name: str, level: int) -> HandlerStats:
        s = self.stats.get(name)
        if s is None:
            s = self.stats[name] = HandlerStats(name, level)
        return s

    def irq(self, vector: Vector, body: int, fn: Callable[..., None], *args: Any,
            enter: Callable[[], None] | None = None, alone: bool = False,
            at: int | None = None, enter_now: bool = False) -> None:
        """The peripheral raises ``vector``'s request now; its handler's body costs ``body``
        cycles. ``enter()`` runs when the handler starts, ``fn(*args)`` when its body ends.
        ``alone``: nothing but this handler's body reads what ``enter`` changes, so on an idle
        CPU both may run at the body's end, without the dispatcher (module docstring). ``at``: the
        request came at that earlier tick, the CPU idle since (``lone_past``'s last byte).
        ``enter_now`` (with ``alone``): others see what ``enter`` does, so alone it runs at
        the entry's end, as on the general path."""
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
        self._touch(True)
        now = self.sched.now
        f = self._alone
        if f is not None:              # (``_settle``'s count of one that is over, inlined)
            if f.fn is None and now > self._alone_t + f.end:
                self._alone = None
                f.stats.busy += f.end
                self._busy += f.end
            else:
                self._settle(now)
        if alone and self.fuse and not self._stack and not self._pending and \
                not self._tasks and not self._in_callback and \
                not (enter_now and at is not None):
            t = now if at is None else at
            s = self.stats.get(vector.name)
            if s is None:
                s = self._stats(vector.name, vector.level)
            s.calls += 1
            s.latency[0] += 1
            f = _Frame(s, vector.level, enter, fn, args, self.entry, body, self.reti, t)
            self._alone = f
            self._alone_t = t
            self._enter_now = enter_now
            # the entry's end, then the body's, each scheduled when the general path would
            # schedule its milestone, so that events due at the same tick keep their order
            # (the body's alone, standing in for both, where the two places are one)
            if t + f.entry > now:
                self._alone_start(f, t)
            else:
                f.phase = 1
                f.body_at = now
                self._alone_ev = self.sched.at(t + f.body_end, self._alone_body)
            return
        assert at is None, "a request in the past needs an idle CPU (lone_past)"
        self._pending.append((vector.level, vector.number, now, vector, body, enter, fn,
                              args, alone, enter_now))
        self._dispatch()

    def task(self, name: str, body: int, fn: Callable[..., None], *args: Any) -> None:
        """Queue work for the main loop: ``fn(*args)`` runs once ``body`` cycles of main-loop
        time have passed for it (after the tasks queued before it)."""
        if self.ideal:
            self._stats(name, MAIN_LEVEL).calls += 1
            fn(*args)
            return
        self._touch(True)
        if self._alone is not None:
            self._settle(self.sched.now)
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
            # the level, then the interrupt number; of equal ones the first to come (min
            # keeps the first of equal keys, and the list is in order of arrival)
            best = min(self._pending, key=_rank)
            if best[0] < self.ilm:
                self._pending.remove(best)
                level, _, req, vec, body, enter, fn, args, alone, enter_now = best
                s = self._stats(vec.name, level)
                s.calls += 1
                lat = now - req
                s.latency[lat] += 1
                if lat > s.worst_latency:
                    s.worst_latency = lat
                if alone and not stack and not self._pending and not self._tasks and \
                        self.fuse:
                    # the CPU idle once it is taken: alone from now (``irq``'s lone handler)
                    f = _Frame(s, level, enter, fn, args, self.entry, body, self.reti, req)
                    self._alone = f
                    self._alone_t = now
                    self._enter_now = enter_now
                    self._alone_start(f, now)
                    return
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
            if top.phase == 1:
                top.body_at = self.sched.now
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
                    self.entered = now
                    top.enter()
            elif top.phase == 1:
                fn = top.fn
                if fn is not None:
                    top.fn = None
                    top.stats.responded(now - top.requested)
                    fn(*top.args)
                if top.done >= top.body_end:     # extend() may have moved the body's end
                    top.phase = 2
        finally:
            self._in_callback = False
        if top.phase == 2 and top.done >= top.end:
            self._stack.pop()
            top.stats.busy += top.end
            self._busy += top.end
            if self._stack:
                self._stack[-1].since = now
        elif top.atomic():
            self._schedule()           # RETI runs on; a request now waits for its end
            return
        self._dispatch()

    # -- a lone handler, without the dispatcher --------------------------------------------

    def _alone_start(self, f: _Frame, t: int) -> None:
        """The lone handler ``f``, accepted at ``t``, its entry still to end: an event at its
        entry's end, or, where its ``enter`` waits for the body (not ``enter_now``) and the
        scheduler keeps places (``PlacedScheduler.at_later``), one at its body's end standing in
        for the one its entry's end would schedule (``_alone_met``: not where the two
        places differ)."""
        sched = self.sched
        if self._enter_now or not self._later_ok:
            self._alone_ev = sched.at(t + f.entry, self._alone_entry)
            return
        f.body_at = t + f.entry
        later = sched.at_later(t + f.body_end, t + f.entry,   # type: ignore[attr-defined]
                               self._alone_body, self._alone_met)
        self._alone_later = later
        self._alone_ev = later[2]

    def _alone_met(self, seq: int, sched: Any) -> None:
        """The body's end may stand where the event its entry's end would schedule does not
        (``PlacedScheduler.at_later``, on ``sched``): before the entry's end, that becomes an
        event in its own place; after it, the stand-in is the body's event."""
        later = self._alone_later
        if later is None or later[1] != seq:
            return                     # (replaced, or the lone handler it stood for is over)
        ev = self._alone_unstand(sched)
        if ev is not None:
            self._alone_ev = ev

    def _alone_unstand(self, sched: Any) -> Event | None:
        """The stand-in given up: before the run reached the entry's end, the entry's event
        in its own place (returned); after, the stand-in is the body's event (phase 1)."""
        later = self._alone_later
        assert later is not None and self._alone is not None
        self._alone_later = None
        if sched.reached(later[0], later[1]):
            self._alone.phase = 1
            return None
        later[2].cancel()
        return sched.at_seq(later[0], later[1], self._alone_entry)

    def _alone_entry(self) -> None:
        """The lone handler's entry sequence ends: its ``enter`` waits for the body's end,
        unless others see what it does (``irq``'s ``enter_now``): then it runs now, and the
        body's end is scheduled after it, as on the general path."""
        f = self._alone
        assert f is not None
        f.phase = 1
        enter = f.enter
        if self._enter_now and enter is not None:
            f.enter = None
            self._alone_ev = None
            self.entered = self.sched.now
            self._in_callback = True     # requests made by it wait for it to return
            try:
                enter()
            finally:
                self._in_callback = False
            if self._alone is not f:
                # it asked for the CPU: f went on the stack (``_settle``), and from here the
                # general path's own steps after an entry
                self._dispatch()
                return
        f.body_at = self.sched.now
        self._alone_ev = self.sched.at(self._alone_t + f.body_end, self._alone_body)

    def _alone_body(self) -> None:
        """The lone handler's body ends: its ``enter`` and ``fn`` run now, as on the general
        path ``fn`` does (``enter`` is the general path's at the entry's end, which nothing
        but the body observes). Its RETI (or a body ``extend`` made longer) runs on without
        an event while nothing else wants the CPU."""
        f = self._alone
        assert f is not None
        self._alone_ev = None
        now = self.sched.now
        if self._alone_later is not None:
            self._alone_later = None
            f.phase = 1
            self.sched.passed(now)               # type: ignore[attr-defined]
        self._in_callback = True
        try:
            if f.enter is not None:
                self.entered = self._alone_t + f.entry
                f.enter()
            fn = f.fn
            f.fn = None
            f.stats.responded(now - f.requested)
            assert fn is not None
            fn(*f.args)
        finally:
            self._in_callback = False
        if self._alone is not f:
            # fn asked for the CPU (a request, a task): f went on the stack; from here the
            # general path's own steps after a body's effects
            if self._ev is not None:
                self._ev.cancel()
                self._ev = None
            f.done = now - self._alone_t
            f.since = now
            if f.done >= f.body_end:
                f.phase = 2
                self._schedule()       # RETI runs on; a request now waits for its end
            else:
                f.phase = 1
                self._dispatch()

    def _settle(self, now: int, final: bool = False) -> None:
        """Before anything else touches the CPU at ``now``: a lone handler that ended before
        now is counted; one still running goes on the stack in the phase it has reached, its
        next milestone an event, as the general path would have it. One whose RETI ends at
        ``now`` is still running, as the general path's RETI event (scheduled at the body's
        end) runs after whatever was scheduled earlier for this tick; ``final``: the run
        stops at ``now``, and every event of the tick has run (World._advance)."""
        f = self._alone
        assert f is not None
        t = self._alone_t
        if self._alone_over(now) or (final and f.fn is None and now == t + f.end):
            self._alone = None
            f.stats.busy += f.end
            self._busy += f.end
            return
        ev = self._alone_ev
        self._alone_ev = None
        if self._alone_later is not None:
            # its body's end a stand-in: in its entry, the entry's end becomes the milestone
            ev = self._alone_unstand(self.sched) or ev
        self._alone = None
        f.since = t
        self._stack.append(f)
        if ev is None and f.fn is not None:
            return                     # asked from its ``enter`` (``_alone_entry``), running
        if f.fn is not None:
            # before its effects: its pending event is the general path's milestone (the
            # entry's end in phase 0, the body's in phase 1), scheduled when that path
            # schedules it, so it becomes that milestone and keeps its place among the
            # events due at its tick
            if f.phase == 1 and f.enter is not None:
                self.entered = t + f.entry
                f.enter()              # (read by nothing before the body ends)
                f.enter = None
            assert ev is not None
            ev.fn = self._milestone
            self._ev = ev
        elif now - t < f.body_end:
            f.phase = 1
            self._schedule()
        else:
            f.phase = 2
            self._reti_in_place(f)

    def _reti_in_place(self, f: _Frame) -> None:
        """Schedule the RETI of ``f``, a lone handler whose effects came, put on the stack by a
        touch in its RETI (``_settle``), where the general path's RETI event is among the
        events due at its end: that one was scheduled at the body's end, by the body's event,
        made at ``f.body_at`` (its entry's end: nothing touched the CPU since the request).
        Scheduled now, it would come after the RETIs of other CPUs scheduled since (two
        receivers of one byte whose handlers end at one tick, the other's body moved on by a
        request in it): it comes before each RETI whose body's event was made later, or at
        the same tick by a robot later in the radios' order (which requests one byte's
        handlers first)."""
        mine = (f.body_at, self.order)

        def later(ev: Event) -> bool:
            cpu = getattr(ev.fn, "__self__", None)
            if not isinstance(cpu, Cpu) or cpu is self or cpu._ev is not ev or not cpu._stack:
                return False
            top = cpu._stack[-1]
            return top.phase == 2 and (top.body_at, cpu.order) > mine

        at_before = getattr(self.sched, "at_before", None)
        if at_before is None:
            self._schedule()
            return
        self._ev = at_before(f.since + f.end - f.done, self._milestone, later)

    def settle(self, read: bool = True, final: bool = False) -> None:
        """Count a lone handler that has ended (``busy`` and the handlers' figures are then
        final for now); called by whoever reads them (``read``: the bytes handed over late
        first) or a register a lone handler's entry reads (``read`` False); ``final``: the
        run stops now, every event of this tick done (``_settle``)."""
        if read:
            self._touch(False)
        if self._alone is not None:
            self._settle(self.sched.now, final)

    def _touch(self, busy: bool) -> None:
        """``on_touch``, if set, unless it is running already (it may ask the CPU itself);
        then a deferred request (``defer``), after the bytes handed over late before it."""
        if self.on_touch is not None and not self._touching:
            self._touching = True
            try:
                self.on_touch(self.sched.now, busy)
            finally:
                self._touching = False
        if self._deferred:
            self._resolve()

    def fits_alone(self, body: int, ticks: int) -> bool:
        """Would a handler of ``body`` cycles, run alone, be over (RETI done) within ``ticks``
        of its request, with the lone handlers on (``fuse``)? Then its handlers may be counted
        late, one every ``ticks`` (Uart: bytes and TDREs)."""
        return self.fuse and self.entry + body + self.reti < ticks

    def runs_alone(self, fn: Callable[..., None]) -> bool:
        """Is the lone handler (``irq``'s ``alone``) ``fn``'s, its effects still to come?"""
        f = self._alone
        return f is not None and f.fn == fn

    def handles(self, fn: Callable[..., None]) -> bool:
        """Is a handler whose effects are ``fn`` requested, running or deferred, its effects
        still to come?"""
        return self.runs_alone(fn) or any(f.fn == fn for f in self._stack) or \
            any(p[6] == fn for p in self._pending)

    def _alone_over(self, now: int) -> bool:
        """The lone handler's effects came and its RETI ended before ``now`` (at ``now`` it
        still runs: ``_settle``)."""
        f = self._alone
        return f is not None and f.fn is None and now > self._alone_t + f.end

    def quiescent(self, now: int) -> bool:
        """Nothing runs or waits on the CPU at ``now`` (a lone handler's RETI done too): a
        reception that begins now may hand its bytes over late (``lone_past``)."""
        if self._alone is not None and not self._alone_over(now):
            return False
        if self._deferred and self._deferred[-1][0] <= now <= self._deferred_end():
            return False
        return not self._stack and not self._pending and not self._tasks

    def lone_past(self, vector: Vector, body: int, t0: int, dt: int, n: int) -> None:
        """Count ``n`` lone handlers of ``vector`` requested at ``t0 + i * dt`` (i < n), each
        on an idle CPU, whose effects (at ``entry + body`` cycles after each request) are due
        by now: the bytes of a reception handed over late, nothing having asked the CPU for
        anything since before ``t0`` (the caller's invariant). The last one's RETI may still
        be running: it is then the lone handler, counted when it ends (``_settle``)."""
        if self._deferred and self._deferred[0][0] < t0:
            self._resolve(t0)          # over before t0: nothing comes late in their time
        if self._alone is not None:
            self._settle(t0)           # the previous byte's handler ended before this one
        assert self._alone is None and self.quiescent(t0), "lone_past needs an idle CPU"
        self._ran_alone(vector, body, t0, dt, n)

    def _ran_alone(self, vector: Vector, body: int, t0: int, dt: int, n: int) -> None:
        """Count ``n`` handlers of ``vector`` that ran alone from their requests at ``t0 + i
        * dt``, their effects come by now; the last one, if its RETI still runs, is the lone
        handler (``lone_past``, ``_resolve``)."""
        now = self.sched.now
        s = self._stats(vector.name, vector.level)
        e = self.entry + body
        whole = e + self.reti
        s.calls += n
        s.latency[0] += n
        s.responded(e, n)
        last = t0 + (n - 1) * dt
        assert last + e < now
        done = n if last + whole < now else n - 1
        s.busy += done * whole
        self._busy += done * whole
        if done < n:
            f = _Frame(s, vector.level, None, None, (), self.entry, body, self.reti, last)
            f.fn = None
            f.body_at = last + self.entry      # (its body's event, had it had one)
            self._alone = f
            self._alone_t = last

    def defer(self, vector: Vector, body: int, owner: Any) -> bool:
        """Take ``vector``'s request now without an event, if its handler may run alone
        (``irq``'s ``alone``) and nothing can meet it: the CPU is idle now, and no handler
        counted late (``late_clear``) runs now or is requested before this one's RETI ends.
        Until the CPU is next touched nothing asks it for anything (a request, a task, a
        read: each touches it first), so then, if its RETI has ended, it ran alone: counted
        so, and ``owner.ran_alone(tick)`` told when its ``enter`` and effects came; else it
        becomes the lone handler from its tick (``irq``'s ``at``), with ``owner.enter`` and
        ``owner.fn``. False: not taken (ask ``irq``)."""
        if not self.fuse or self.ideal or vector.level == MAIN_LEVEL or self._in_callback:
            return False
        now = self.sched.now
        if self._deferred and now <= self._deferred_end():
            return False
        if self._alone is not None:
            if not self._alone_over(now):
                return False
            self._settle(now)
        if self._stack or self._pending or self._tasks:
            return False
        clear = self.late_clear
        if clear is not None and not clear(now, now + self.entry + body + self.reti):
            return False
        self._deferred.append((now, vector, body, owner))
        return True

    def _deferred_end(self) -> int:
        """The tick the last deferred request's RETI ends (none before it still runs)."""
        t, _, body, _ = self._deferred[-1]
        return t + self.entry + body + self.reti

    def resolve(self) -> None:
        """A deferred request counted or made the lone handler now (``defer``), as if the
        CPU were touched, nothing else done."""
        if self._deferred:
            self._resolve()

    def _resolve(self, before: int | None = None) -> None:
        """The CPU is touched now (or asked to count handlers from tick ``before`` on): each
        deferred request (requested before ``before``) ran alone if its RETI has ended (or
        is the lone handler in its RETI), else it is the lone handler from its tick, its
        effects still to come (``defer``)."""
        now = self.sched.now
        deferred = self._deferred
        while deferred and (before is None or deferred[0][0] < before):
            t, vector, body, owner = deferred.pop(0)
            e = self.entry + body
            if now <= t + e:           # its effects are still to come (as Uart._replay's)
                self.irq(vector, body, owner.fn, enter=owner.enter, alone=True, at=t)
                continue
            self._ran_alone(vector, body, t, 0, 1)
            self.entered = t + self.entry
            owner.ran_alone(t + e)

    @property
    def busy(self) -> int:
        """Machine cycles spent in handlers and tasks that have ended (RETI done)."""
        self._touch(False)
        f = self._alone
        if f is not None and self._alone_over(self.sched.now):
            return self._busy + f.end
        return self._busy

    def extend(self, cycles: int) -> None:
        """Called by a running handler: it goes on for ``cycles`` more after its effects
        (work whose outputs are not time-critical, e.g. the MAC's bookkeeping on a frame)."""
        if self.ideal or cycles <= 0:
            return
        f = self._alone
        if f is not None:
            f.body_end += cycles      # called from its fn: the RETI moves on
            f.end += cycles
            return
        if not self._stack:
            return
        top = self._stack[-1]
        top.body_end += cycles
        top.end += cycles

    # -- figures -------------------------------------------------------------------------

    def load(self, now: int | None = None) -> float:
        """Share of the machine cycles since the start spent in handlers and tasks, those
        still running included (a handler longer than the run kept the CPU busy all of it,
        though its cycles are not yet in ``busy``)."""
        now = self.sched.now if now is None else now
        span = now - self.started
        return (self.busy + self.running(now)) / span if span > 0 else 0.0

    def running(self, now: int) -> int:
        """Cycles done by ``now`` of the handlers and tasks still running (not in ``busy``)."""
        return sum(done for _, done, _ in self.unfinished(now))

    def unfinished(self, now: int) -> list[tuple[HandlerStats, int, int]]:
        """The handlers and tasks still running at ``now`` (their RETI not done): (their
        figures, cycles done, ticks since their request)."""
        out = [(f.stats, f.done, now - f.requested) for f in self._stack]
        if out:
            top = self._stack[-1]
            out[-1] = (top.stats, top.done + now - top.since, now - top.requested)
        f = self._alone
        if f is not None and not self._alone_over(now):
            out.append((f.stats, min(now - self._alone_t, f.end), now - f.requested))
        return out

    @property
    def idle(self) -> bool:
        self._touch(False)
        return self.quiescent(self.sched.now)


def _rank(request: tuple) -> tuple[int, int]:
    """A waiting request's rank: its level (0 first), then its interrupt number."""
    return request[0], request[1]

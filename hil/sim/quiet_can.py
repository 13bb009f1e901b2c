"""A child's CAN side on its own clock, run in whole status periods while nothing happens there.

An idle child's CAN side repeats itself: each of its six submodules sends the same status
frame every 100 ms (:data:`~can_bus.submodules.STATUS_PERIOD_TICKS`), the bus carries the same
bits at the same offsets, the controller, the CAN driver and the dispatcher note the same
things. Running that frame by frame costs the simulator most of a ``--can`` run
(docs/performance.md). So the simulator runs each child's CAN side as a *domain*:

* Its parts (bus, 82C250, controller, CAN driver, dispatcher timer, submodules) are built on a
  :class:`DomainClock`. Their events run before the other events of the same tick
  (``SimScheduler.at_first``, hil/sim/domains.py), which makes the order of simultaneous
  radio and CAN events a rule (CAN first) instead of an accident of when each was scheduled.
* Once a period (at the phase the status grid started on) a probe takes a snapshot of the
  domain (hil/sim/state_walk.py: every attribute of every part, and the domain's pending
  events). If nothing outside listens to the bus (no trace, capture, sniffer) and two
  snapshots a period apart differ only by ticks moved on by exactly the period and by counters
  (:data:`COUNTERS`), the domain is *quiet*: its events leave the scheduler and it stops.
* Anything that touches the domain (a message the radio delivers to the child, a fault, the
  end of ``World.run``, a summary) calls :meth:`QuietCan.wake` first. The domain moves on by
  the whole periods that passed (ticks and counters, in one step) and runs the last partial
  period's events on a private scheduler up to the tick now (its events run first at a tick),
  then its events go back into the world's scheduler. If a latest status changed from one
  period to the next, or may change later (a cruising wheel), the last whole period runs on
  the private scheduler too, and rewrites it as the skipped periods would have.
* News (a reply, a ``done()`` or ``fail()`` notice) reaching a child that has nothing under
  way is only noted, in the dispatcher's log (``notes_only``): it reads nothing a
  period changes and changes nothing a period moves, so it does not wake the domain. Nor does
  an order message the dispatcher refuses whole at once, from the order and the commanded pose
  alone (out of reach, outside a joint's limits: ``refuses_only``): the log and
  the failure replies, which go to the radio, are all it changes.
* At the first probe after a wake, if what woke it left the domain exactly on the orbit it
  slept on, moved on by whole periods (ticks moved by their steps, counters up, logs of any
  length: :func:`~hil.sim.state_walk.on_orbit`), it sleeps again at once, on the same
  steps, instead of comparing two snapshots a period apart (an order the dispatcher refuses
  costs one snapshot, not two).

* On the CPU model (``--cpu estimated``) the CAN side's interrupts share the CPU with the
  radio's: a sleeping domain's are raised on the CPU all the same, as ghosts that cost what
  its handlers would (hil/sim/can_ghosts.py).

The result is the run the frame-by-frame simulation gives, to the tick: the state is the same
after k periods whether they ran or were added up, because the snapshot covers all of it
(tests/hil/sim/test_quiet_can.py compares the two on seeded runs with orders, faults, byte errors
and load, part by part).
"""
from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING, Any, Callable

from can_bus.submodules import STATUS_PERIOD_TICKS
from firmware_model.dispatcher import REQUEST_TYPES, NodeView
from firmware_model.mcu.scheduler import Event

from .can_ghosts import CanCpuPort, Footprint
from .domains import SimScheduler

from .steady import CAN_PARTS, counters, records
from .state_walk import (Snapshot, Unwalkable, advance, latest_moved, on_orbit, period_steps,
                         snapshot, writable)

if TYPE_CHECKING:
    from firmware_model.child import ChildFirmware
    from firmware_model.radio.mac import Deliver

__all__ = ["COUNTERS", "LATEST", "PERIOD", "RECORDS", "DomainClock", "QuietCan",
           "nothing_under_way", "notes_only", "refuses_only"]

PERIOD = STATUS_PERIOD_TICKS
"""1,600,000 ticks (100 ms): the submodules' status period, the domain's period."""

PAYBACK_PERIODS = 8
"""Periods a sleep must last to pay for the two snapshots that began it: a snapshot of a
child's CAN side costs about what three of its periods run frame by frame do
(docs/performance.md, "Sleeping CAN sides under load"). A domain woken sooner than this,
sleep after sleep (orders every few periods), probes ever less often: after ``n`` short
sleeps in a row it skips ``2**n - 1`` probes (at most :data:`SHORT_BACKOFF_MAX` - 1) after
each wake and each job. Skipping a probe can only cost a sleep, never change the run."""

SHORT_BACKOFF_MAX = 32
"""The longest back-off after short sleeps, in periods (3.2 s)."""

COUNTERS = counters(CAN_PARTS)
"""Attributes that only count what happened, as the domain's classes declare them
(``STEADY_COUNTERS``; hil/sim/steady.py): they may grow by any amount a period without making
the domain other than periodic (nothing reads them to decide what to do)."""


RECORDS = records(CAN_PARTS)
"""Append-only lists of what happened that nothing in the model reads, as declared
(``STEADY_RECORDS``: the dispatcher's log, a submodule's events): a snapshot takes their length
only (hil/sim/state_walk.py)."""

LATEST: tuple[type, ...] = (NodeView,)
"""Types holding only the latest of something each period rewrites before anything in a
sleeping domain reads it: the dispatcher's record of a submodule's last status frame (each
status frame sets all of it; with no job running, only the radio side reads it, and a
message wakes the domain first). A cruising wheel's odometer changes it every period, or every
few periods at a low speed: such a domain sleeps all the same, and at every wake runs its last
whole period frame by frame, which writes the values the skipped periods would have left
(hil/sim/state_walk.py, free positions; :attr:`QuietCan.drifting`)."""


class DomainClock:
    """The clock a domain's parts are built on (the :class:`~can_bus.clock.Clock` protocol):
    the world's scheduler, with the domain's events first at a tick, or, while the domain
    catches up, a private scheduler."""

    __slots__ = ("world", "owner", "private", "at", "at_top", "_sched")

    def __init__(self, world: SimScheduler, owner: object) -> None:
        self.world = world
        self.owner = owner
        self.private: SimScheduler | None = None
        self._sched = world                     # the scheduler that runs the domain now
        self.at: Callable[..., Event] = partial(world.at_first, owner)
        """``at(when, fn, *args)``: schedule on whichever scheduler runs the domain now."""
        self.at_top: Callable[..., Event] = partial(world.at_top, owner=owner)
        """``at_top(when, fn, *args)``: a step of a domain's part (``Scheduler.at_top``)."""

    def use(self, private: SimScheduler | None) -> None:
        """Run the domain on ``private`` (None: on the world's scheduler again)."""
        self.private = private
        sched = self._sched = private if private is not None else self.world
        self.at = partial(sched.at_first, self.owner)
        self.at_top = partial(sched.at_top, owner=self.owner)

    @property
    def now(self) -> int:
        return self._sched.now

    def after(self, delay: int, fn: Callable[..., Any], *args: Any) -> Event:
        return self.at(self.now + delay, fn, *args)


class QuietCan:
    """One child's CAN domain: probes for quiet, sleeps, wakes (module docstring).

    ``roots``: the domain's parts; ``boundary``: objects they refer to that are not theirs
    (the radio station); ``may_sleep()``: False while something outside watches the bus or
    the domain is plainly busy (a job running), which saves the snapshot."""

    def __init__(self, world: SimScheduler, name: str = "CAN", order: int = 0) -> None:
        self.name = name
        self.order = order
        """Its place among the domains' events at one tick (hil/sim/domains.py): the child's
        ID."""
        self.world = world
        self.clock = DomainClock(world, self)
        self.roots: list[Any] = []
        self.boundary: list[Any] = []
        self.may_sleep: Callable[[], bool] = lambda: True
        self.drifting: Callable[[], bool] = lambda: False
        """True while a part's latest values may change without two snapshots a period
        apart showing it: a wheel cruising at 3 mm/s reports the same odometer (whole mm) for
        three periods, then the next. Every wake then runs the last whole period frame by
        frame (a random hunt found it: the dispatcher's record of such a wheel
        kept the odometer of the period the domain fell asleep in)."""
        self.enabled = True
        self.asleep = False
        self.periods_skipped = 0
        """Periods the domain did not run frame by frame (figures for docs/performance.md)."""
        self.sleeps = 0
        self._last_snap: Snapshot | None = None
        self._moved: list[tuple[Any, Any, int]] = []
        self._orbit: Snapshot | None = None     # the snapshot it last fell asleep on
        self._steps: dict[int, int] = {}        # how a period moves that snapshot on
        self._replay = False                    # run the last whole period at the wake
        self.replays = 0
        """Wakes that ran the last whole period frame by frame (a latest status changed)."""
        self.resleeps = 0
        """Sleeps taken at the first probe after a wake, the state back on the orbit."""
        self.one_shots = 0
        """Sleeps refused because an event of the domain was not moved by the period."""
        self.noted = 0
        """Messages the child only noted while the domain slept, without waking it (news:
        ``notes_only``)."""
        self.refused = 0
        """Messages whose every order the child refused at once while the domain slept,
        without waking it (``refuses_only``)."""
        self._since = 0
        self._events: list[Event] = []
        self._misses = 0          # probes in a row that found the domain not periodic
        self._skip = 0            # probes left to skip (backing off while it is busy)
        self._after_busy = False  # may_sleep() said no at the last probe
        self._short = 0           # sleeps in a row shorter than PAYBACK_PERIODS
        self.port: CanCpuPort | None = None
        """On the CPU model: the CAN driver's way to the CPU, which raises the sleeping
        domain's interrupts as ghosts (hil/sim/can_ghosts.py)."""

    def start(self, phase: int) -> None:
        """Probe every period from tick ``phase`` on (a tick the status grid is idle at)."""
        self.clock.at(phase, self._probe)

    @property
    def _last(self) -> Snapshot | None:
        """The snapshot the next probe compares with (None: it takes one to compare later).
        The CPU model's port notes the domain's interrupts while there is one."""
        return self._last_snap

    @_last.setter
    def _last(self, snap: Snapshot | None) -> None:
        self._last_snap = snap
        port = self.port
        if port is not None:
            port.note(snap is not None)

    def touched(self) -> None:
        """Something from outside the domain reached it while it is awake (a message handed
        to the child, a fault): the snapshot taken before proves nothing about a period. A
        message the child only notes adds one to its main loop's handler calls, a counter, and
        two snapshots that straddle it would say the counter grows by one a period: a sleep
        would then add one for every period it skipped (a random hunt found it)."""
        if not self.asleep:
            self._last = None

    def disable(self) -> None:
        """Never sleep again (something now watches every frame: a capture)."""
        self.wake()
        self.enabled = False

    def _probe(self) -> None:
        clock = self.clock
        clock.at(clock.now + PERIOD, self._probe)
        # the interrupts the CAN side raised on the CPU model since the last probe
        port = self.port
        footprint = port.begin() if port is not None else ()
        if clock.private is not None or not self.enabled:
            self._last = None
            self._misses = self._skip = 0
            return
        if not self.may_sleep():
            self._last = None
            self._misses = self._skip = 0
            self._after_busy = True
            return
        if self._after_busy:
            # The first period after a job: its last frames (an EVENT, a command) moved the
            # last frame's ticks, so a snapshot now would rarely match the next one (191 of
            # about 250 such comparisons failed, docs/performance.md): begin a period later,
            # or later still while sleeps keep being short.
            self._after_busy = False
            self._skip = self._short_backoff()
            return
        if self._skip:
            self._skip -= 1
            return
        if port is not None and not port.cpu_quiet():
            self._last = None     # a handler (its own, perhaps) runs: compare afresh next
            return
        try:
            snap = snapshot([*self.roots, self.world.pending(self)],
                            [*self.boundary, clock, self], records=RECORDS, latest=LATEST)
        except Unwalkable:
            self.enabled = False
            return
        last, self._last = self._last, snap
        if last is None:
            orbit, steps = self._orbit, self._steps
            periods = (clock.now - self._since) // PERIOD
            if port is not None and self.drifting():
                return      # (the CPU model: a cruising wheel's interrupts, from this period)
            if orbit is None or not on_orbit(orbit, steps, periods, snap, COUNTERS):
                return
            # Back on the orbit it slept on (what woke it left nothing that a period does not
            # move on): sleep again now rather than one period later.
            self.resleeps += 1
            self._sleep(snap, steps, self._replay or latest_moved(orbit, snap, steps, periods),
                        port.footprint if port is not None else ())
            return
        found = period_steps(last, snap, PERIOD, COUNTERS)
        if found is None:
            # busy in a way may_sleep does not see (it knows jobs and moving nodes only): look
            # again in 1, 2, 4 ... 16 periods, and compare with the snapshot then
            self._misses += 1
            self._skip = min(1 << (self._misses - 1), 16) - 1
            if self._skip:
                self._last = None
            return
        if footprint is None:
            return      # a CAN handler met the radio on the CPU this period: not its orbit
        self._sleep(snap, found, latest_moved(last, snap, found), footprint)

    def _sleep(self, snap: Snapshot, steps: dict[int, int], replay: bool,
               footprint: Footprint) -> None:
        port = self.port
        if port is not None and not port.plan(footprint, self.clock.now):
            return      # (a cruising wheel whose status interrupt cannot be placed)
        moved = writable(snap, steps)
        stepped = {id(holder) for holder, key, _ in moved if key == "when"}
        if any(id(ev) not in stepped for ev in self.world.pending(self)):
            # an event of its own that a period does not move (a one-shot: a recovery, a
            # stall timer) ends the repetition at its tick: stay awake
            self.one_shots += 1
            return
        self._misses = 0
        self._replay = replay or self.drifting()
        self._events = self.world.take(self)
        self._moved = moved
        self._orbit, self._steps = snap, steps
        self._since = self.clock.now
        self.asleep = True
        self.sleeps += 1
        if port is not None:
            port.sleep(footprint, self._since)

    def replay_last(self) -> None:
        """A latest value drifted while the domain sleeps (a late ghost, hil/sim/can_ghosts.py):
        the wake runs the last whole period frame by frame, as for a drifting part."""
        self._replay = True

    def _short_backoff(self) -> int:
        """Probes to skip now, after ``_short`` short sleeps in a row (``PAYBACK_PERIODS``)."""
        if not self._short:
            return 0
        return min(1 << self._short, SHORT_BACKOFF_MAX) - 1

    def wake(self, work: bool = False) -> None:
        """Bring the domain up to the tick now (the world's), before anything touches it.
        ``work``: it is woken to do something (a message, a fault), not to be read (a
        summary, the end of a run): a sleep that ends so is weighed against
        :data:`PAYBACK_PERIODS`."""
        if not self.asleep:
            return
        self.asleep = False
        self._last = None
        now = self.world.now
        k = (now - self._since) // PERIOD
        if work:
            self._short = self._short + 1 if k < PAYBACK_PERIODS else 0
            self._skip = self._short_backoff()
        if self._replay and k:
            k -= 1                    # the last whole period runs frame by frame (LATEST)
            self.replays += 1
        advance(self._moved, k)       # the pending events' ticks are among the moved ints
        self.periods_skipped += k
        private = SimScheduler(self._since + k * PERIOD)
        private.put_back(self._events)
        self._events = []
        self.clock.use(private)
        port = self.port
        if port is not None:
            port.wake()
            port.catching_up = True
        try:
            private.run_until(now)
        finally:
            self.clock.use(None)
            if port is not None:
                port.catching_up = False
        self.world.put_back(private.take(self))
        if port is not None:
            port.woken()


# -- what reaches a sleeping child without waking it -------------------------------------------
# Questions the simulator asks of a child's firmware (firmware_model/child.py), which need not
# know them: each reads the child's state and changes nothing.

def notes_only(child: "ChildFirmware", d: "Deliver") -> bool:
    """Would handling ``d`` only note it? True for information (Types '3' and '4': a reply, a
    ``done()`` or ``fail()`` notice, docs/protocol.md §3) reaching a child with
    :func:`nothing_under_way`: the dispatcher appends it to its log and counts a call, and
    nothing else changes, whatever the tick of its CAN side (a sleeping domain need not wake
    for it)."""
    return d.type not in REQUEST_TYPES and nothing_under_way(child)


def refuses_only(child: "ChildFirmware", d: "Deliver") -> bool:
    """Would handling ``d`` only refuse it? True for a request whose every order the
    dispatcher refuses at once (``Dispatcher.refuses_all``: out of reach, outside a joint's
    limits, out of range) reaching a child with :func:`nothing_under_way`: the dispatcher
    logs and answers each order with its failure, which goes to the radio, and nothing of the
    CAN side is read or changed (a sleeping domain need not wake)."""
    return (child.dispatcher.refuses_all(d.dst, d.commands, d.type)
            and nothing_under_way(child))


def nothing_under_way(child: "ChildFirmware") -> bool:
    """No job (so no job deadline), no output waiting, no CAN supervision pending, the
    dispatcher's timer stopped, no action sequence, and no message waiting for the main loop
    (the CPU model hands a message to the main loop, which dispatches it later:
    ``ChildFirmware.cpu_work``)."""
    disp = child.dispatcher
    return (child.sequence is None and not child.cpu_work and not disp.jobs
            and not disp.has_output() and child.timer.expiry is None
            and child.can.deadline() is None)


"""A sleeping CAN side's interrupts on the CPU model: *ghosts* that take the CPU as its real
handlers would, so that the radio's handlers meet them to the tick.

On the CPU model a child's CAN and radio handlers share one CPU (firmware_model/mcu/cpu.py):
a CAN handler that meets a radio handler moves both. So a child's CAN side may sleep
(hil/sim/quiet_can.py) only if its CPU still sees every request it would have raised:

* **Awake**, the CAN driver raises its interrupts through a :class:`CanCpuPort`, which hands
  them to the CPU unchanged and notes, for the period the probe compares, each request's tick,
  vector and cycles, and whether each handler's effects came when a handler alone on the CPU
  has them (``entry + body`` cycles after its request: *on time*).
* **It sleeps** only if every one of that period came on time, the CPU is idle at the probe
  (none of them still runs) and no work of the CAN side waits on the CPU (a message for the
  main loop, the dispatcher timer's interrupt: ``ChildFirmware.cpu_work``). The port then
  raises the same requests at the same ticks a period later and every period on (an event
  each, first at its tick as the driver's frame end was), each with a ghost handler: the same
  vector and cycles, so it costs the CPU what the real one would, on the same path, and the
  CPU's figures are the real ones. One that nothing can meet the CPU takes without an event
  of its own (``Cpu.defer``), most of them.
* A cruising wheel's odometer changes its status frame from period to period, and with it
  the frame's stuff bits and the tick its receive interrupt comes: that ghost comes where the
  frame's length puts it (:class:`CruisingWheel`).
* A ghost whose effects come on time stands for the real handler: the domain's state moves
  on by whole periods as the probe found. When its ``enter`` ran does not matter (nothing but
  its body reads what it takes, ``Cpu.irq``'s ``alone``).
* A ghost whose effects come late met the radio on the CPU (a radio handler held it, or
  preempted it). If its handler's effects are only the latest of what each period rewrites
  (:data:`LATE_OK`) and come before the next request, the domain sleeps on: the catch-up at
  its wake runs them at the tick they came, and the last whole period frame by frame.
  Otherwise it wakes the domain (:meth:`QuietCan.wake`): the catch-up runs the CAN side up to
  the tick now, and when its driver raises the request the ghost stands for, the ghost takes
  the real handler's ``enter`` and effects, and from then on is the real handler, where the
  CPU has it.
* No request of a catch-up reaches the CPU (the ghosts did): a request whose ghost stood for
  it has its effects run at their ticks on the catch-up's own scheduler.

The run is the frame-by-frame one to the tick, the CPU's figures included
(tests/hil/sim/test_can_ghosts.py; ``scripts/sleep_hunt.py --cpu``).
"""
from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING, Any, Callable

from can_bus import dbc
from can_bus.bits import frame_length_bits
from can_bus.submodules import STATUS_PERIOD_TICKS as PERIOD, WheelNode
from firmware_model.interrupts import CAN0_RX
from firmware_model.mcu.cpu import Cpu, Vector
from firmware_model.mcu.scheduler import Event

if TYPE_CHECKING:
    from .quiet_can import QuietCan

__all__ = ["CanCpuPort", "CruisingWheel", "Footprint"]

Footprint = tuple[tuple[int, Vector, int, bool], ...]
"""A period's requests: (ticks after the period's start, vector, body cycles, alone)."""

KEEP_PERIODS = 3
"""Periods a ghost is kept for a catch-up to find: a catch-up replays at most the last whole
period and the part of a period since (QuietCan.wake)."""


LATE_OK = frozenset({CAN0_RX.name})
"""Handlers whose effects on a child whose CAN side sleeps are only the latest of what every
period rewrites, read by nothing of that side before the rewrite: the CAN receive handler,
which there only takes a submodule's status frame (the driver's ``last_rx``, the dispatcher's
record of the node, a ``LATEST`` type: hil/sim/quiet_can.py). Its ghost may come late (the radio
held the CPU) and the domain sleep on: the catch-up runs its effects at the tick they came
and, as after any drift of a latest value, the last whole period frame by frame
(``QuietCan.replay_last``), which leaves what the skipped periods would have. It must come
before the footprint's next request, which may read what it does (the next frame into its
buffer); later, it wakes the domain."""


_WHEEL_STATUS, _WHEEL_RAISE = -1, -2     # CanCpuPort._guards' keys beside the requests'

SHIFT_BITS = 32
"""Bits a cruising wheel's status frame may grow or shrink by from period to period (its
odometer's stuff bits: a few), kept free before the next request when a late ghost's effects
are allowed to come (LATE_OK)."""


class CruisingWheel:
    """A child's wheel as the port asks about it while it cruises: its status frames' ticks.
    A cruising wheel's odometer changes from period to period, so its status frame's stuff
    bits do, and the frame's end, its receive interrupt, moves by whole bits (``tpb`` ticks a
    bit); the bus is idle for it (the status frames are 10 ms apart)."""

    def __init__(self, wheel: WheelNode, tpb: int, max_bits: int = 160) -> None:
        self.node = wheel
        self.tpb = tpb
        self.max_bits = max_bits

    def bits_at(self, tick: int) -> int:
        """SOF-to-EOF bits on the wire of its status frame sent at ``tick``."""
        node = self.node
        f = dbc.encode_raw_values(node.status_name, node.status_values_at(tick))
        return frame_length_bits(f.id, f.data, f.rtr, include_ifs=False, dlc=f.dlc)

    def plan(self, footprint: Footprint, mark: int) -> tuple[int, int, int, int] | None:
        """For a footprint noted from tick ``mark``: (the request its last status frame
        raised, its next status tick, ticks from a status tick to that request, that frame's
        bits), or None if it sent none, or was not cruising then."""
        node = self.node
        if node.is_silent:         # (no frames: nothing to find)
            return None
        due = node.status_due
        last = due - PERIOD
        for i, (off, vector, _, _) in enumerate(footprint):
            since = mark + off - last
            if vector is CAN0_RX and 0 < since <= self.max_bits * self.tpb:
                try:
                    return i, due, since, self.bits_at(last)
                except ValueError:
                    return None
        return None


class _Ghost:
    """One request raised for a sleeping CAN side: ``due`` (a tick) is when a lone handler's
    effects come, ``limit`` the tick of the footprint's next request; ``real`` the handler it
    became once a catch-up gave it; ``entered_at`` / ``effects_at`` when its ``enter`` and
    effects came, while it stood for the real handler."""

    __slots__ = ("port", "key", "due", "limit", "late_ok", "real", "entered", "entered_at",
                 "effects_at")

    def __init__(self, port: "CanCpuPort", key: tuple[int, str], due: int, limit: int,
                 late_ok: bool) -> None:
        self.port = port
        self.key = key           # (the tick of its request, its vector's name)
        self.due = due
        self.limit = limit
        self.late_ok = late_ok
        self.real: tuple[Callable[[], None] | None, Callable[..., None], tuple] | None = None
        self.entered = False     # the real enter has run
        self.entered_at: int | None = None
        self.effects_at: int | None = None

    def ran_alone(self, due: int) -> None:
        """Taken without an event (``Cpu.defer``), it ran alone: its ``enter`` and effects
        came at ``due``, as a lone handler's do (``Cpu._alone_body``)."""
        assert self.real is None and due == self.due
        self.entered_at = self.effects_at = due

    def enter(self) -> None:
        if self.real is None:
            self.entered_at = self.port.now()
            return
        self._enter_real()

    def fn(self) -> None:
        port = self.port
        if self.real is None:
            now = port.now()
            if now == self.due:
                self.effects_at = now
                return
            if self.late_ok and now < self.limit:
                # late, its effects only the latest of what each period rewrites: the catch-up
                # runs them at this tick (LATE_OK)
                self.effects_at = now
                port.late += 1
                port.quiet.replay_last()
                return
            port.meet(self)
        self._enter_real()
        assert self.real is not None
        _, fn, args = self.real
        fn(*args)

    def _enter_real(self) -> None:
        if not self.entered:
            self.entered = True
            assert self.real is not None
            enter = self.real[0]
            if enter is not None:
                enter()


class CanCpuPort:
    """The CAN driver's way to its child's CPU (``irq`` and ``settle`` as the CPU's): hands
    requests over while the domain is awake, raises ghosts while it sleeps (module
    docstring)."""

    @property
    def order(self) -> int:
        """Its ghosts' place among the domains' events at a tick: its domain's
        (hil/sim/domains.py)."""
        return self.quiet.order

    def __init__(self, quiet: "QuietCan") -> None:
        self.quiet = quiet
        self.cpu: Cpu | None = None
        self.irq: Callable[..., None] = _nothing
        """``irq(vector, body, fn, *args, enter=None, alone=False)``, as ``Cpu.irq``: the
        CPU's own while nothing is noted, so that a busy side pays no call of the port's."""
        self.settle: Callable[..., None] = _nothing
        """``settle(read=True, final=False)``, as ``Cpu.settle`` (nothing in a catch-up)."""
        self._catching_up = False
        self._noting = False
        self.meetings = 0
        """Ghosts that met the radio on the CPU and woke the domain."""
        self.ghosts_raised = 0
        self.deferred = 0
        """Ghosts the CPU took without an event (``Cpu.defer``): nothing could meet them."""
        self.late = 0
        """Ghosts whose effects came late (the radio held the CPU) without waking the domain
        (LATE_OK)."""
        self._log: list[tuple[int, Vector, int, bool]] = []
        self._clean = True
        self._mark = 0
        self._guards: dict[int, Event] = {}
        """The asleep domain's pending events: each footprint request's next raise, by its
        index, and a cruising wheel's status tick and its next raise (_WHEEL_STATUS,
        _WHEEL_RAISE)."""
        self.wheel: CruisingWheel | None = None
        """The child's wheel (the world's), whose status frames change while it cruises."""
        self._wheel_plan: tuple[int, int, int, int] | None = None
        self.footprint: Footprint = ()
        """The requests it raises asleep (those of the period it fell asleep after)."""
        self._gaps: list[int] = []
        self._ghosts: dict[tuple[int, str], _Ghost] = {}
        self._order: deque[_Ghost] = deque()

    def attach(self, cpu: Cpu) -> "CanCpuPort":
        """Stand between ``cpu`` and the CAN driver (ChildFirmware's ``can_cpu``)."""
        self.cpu = cpu
        self._route()
        return self

    def now(self) -> int:
        assert self.cpu is not None
        return self.cpu.sched.now

    def _route(self) -> None:
        cpu = self.cpu
        assert cpu is not None
        if self._catching_up:
            self.irq, self.settle = self._replayed_irq, _nothing
        elif self._noting:
            self.irq, self.settle = self._noted_irq, cpu.settle
        else:
            self.irq, self.settle = cpu.irq, cpu.settle

    @property
    def catching_up(self) -> bool:
        """A catch-up runs the domain: its requests reach no CPU (:meth:`_replayed`)."""
        return self._catching_up

    @catching_up.setter
    def catching_up(self, on: bool) -> None:
        self._catching_up = on
        self._route()

    def note(self, on: bool) -> None:
        """Note the requests of the period now running (the next probe compares it with the
        last: QuietCan), or stop."""
        if on != self._noting:
            self._noting = on
            self._route()

    def cpu_quiet(self) -> bool:
        """Nothing runs or waits on the CPU now: none of the CAN side's handlers either."""
        cpu = self.cpu
        assert cpu is not None
        return cpu.quiescent(cpu.sched.now)

    # -- the CPU's interface, as the CAN driver uses it -----------------------------------

    def _noted_irq(self, vector: Vector, body: int, fn: Callable[..., None], *args: Any,
                   enter: Callable[[], None] | None = None, alone: bool = False) -> None:
        """``irq`` in a period the next probe compares: the request noted, and whether its
        effects come on time."""
        cpu = self.cpu
        assert cpu is not None
        t = cpu.sched.now
        self._log.append((t, vector, body, alone))
        cpu.irq(vector, body, self._timed, t + cpu.entry + body, fn, args, enter=enter,
                alone=alone)

    def _timed(self, due: int, fn: Callable[..., None], args: tuple) -> None:
        if self.now() != due:
            self._clean = False
        fn(*args)

    def _replayed_irq(self, vector: Vector, body: int, fn: Callable[..., None], *args: Any,
                      enter: Callable[[], None] | None = None, alone: bool = False) -> None:
        self._replayed(vector, body, fn, args, enter)

    # -- the probe's questions -------------------------------------------------------------

    def begin(self) -> Footprint | None:
        """A probe now: the requests noted since the last one as a footprint (None if a
        handler's effects came late), and begin anew."""
        fp = None
        if self._clean:
            fp = tuple((t - self._mark, v, b, a) for t, v, b, a in self._log)
        self._log = []
        self._clean = True
        self._mark = self.quiet.clock.now
        return fp

    # -- asleep ----------------------------------------------------------------------------

    def plan(self, footprint: Footprint, start: int) -> bool:
        """May the domain sleep at tick ``start`` (a probe's), the period before it having
        raised ``footprint``? Yes, but with a cruising wheel whose status frame's receive
        interrupt cannot be found among them (:class:`CruisingWheel`)."""
        self._wheel_plan = None
        wheel = self.wheel
        if wheel is not None and self.quiet.drifting():
            self._wheel_plan = wheel.plan(footprint, start - PERIOD)
            return self._wheel_plan is not None
        return True

    def sleep(self, footprint: Footprint, start: int) -> None:
        """The domain sleeps at tick ``start``, a probe's, the period before it having raised
        ``footprint`` (:meth:`plan` said yes): raise those requests from ``start`` on, every
        period; a cruising wheel's status interrupt where its frame's length puts it."""
        world = self.quiet.world
        self.footprint = footprint
        plan = self._wheel_plan
        shifted = plan[0] if plan is not None else -1
        self._guards = {i: world.at_first(self, start + off, self._raise, i, True)
                        for i, (off, _, _, _) in enumerate(footprint) if i != shifted}
        if plan is not None:
            i, due, since_status, bits = plan
            self._guards[_WHEEL_STATUS] = world.at_first(self, due, self._wheel_status, i,
                                                         since_status, bits)
        # how long after each request the next one comes (ticks), less what a wheel's frame
        # may move: a ghost whose effects come later than that must wake the domain (the
        # next frame may read what they do)
        offs = sorted(off for off, _, _, _ in footprint)
        wheel = self.wheel
        slack = 0 if plan is None or wheel is None else SHIFT_BITS * wheel.tpb
        self._gaps = [min(((o - off) % PERIOD or PERIOD) for o in offs) - slack
                      for off, _, _, _ in footprint]

    def _wheel_status(self, i: int, since_status: int, bits: int) -> None:
        """The cruising wheel's status tick: its frame's receive interrupt comes
        ``since_status`` ticks later, moved by the bits its frame has more or fewer than the
        footprint's had (stuff bits: the odometer changes)."""
        wheel = self.wheel
        assert wheel is not None
        world = self.quiet.world
        now = world.now
        self._guards[_WHEEL_STATUS] = world.at_first(self, now + PERIOD, self._wheel_status, i,
                                                     since_status, bits)
        end = now + since_status + (wheel.bits_at(now) - bits) * wheel.tpb
        self._guards[_WHEEL_RAISE] = world.at_first(self, end, self._raise, i, False)

    def _raise(self, i: int, again: bool) -> None:
        """A ghost's request, at the tick the driver's would come (an event first at it);
        ``again``: the same a period later."""
        cpu = self.cpu
        assert cpu is not None
        _, vector, body, alone = self.footprint[i]
        world = self.quiet.world
        now = world.now
        if again:
            self._guards[i] = world.at_first(self, now + PERIOD, self._raise, i, True)
        order = self._order
        while order and order[0].key[0] < now - KEEP_PERIODS * PERIOD:
            old = order.popleft()
            del self._ghosts[old.key]
        g = _Ghost(self, (now, vector.name), now + cpu.entry + body, now + self._gaps[i],
                   vector.name in LATE_OK)
        self._ghosts[g.key] = g
        order.append(g)
        self.ghosts_raised += 1
        if alone and cpu.defer(vector, body, g):
            self.deferred += 1
        else:
            cpu.irq(vector, body, g.fn, enter=g.enter, alone=alone)

    def meet(self, ghost: _Ghost) -> None:
        """``ghost`` met the radio on the CPU: wake the domain, whose catch-up makes it real."""
        self.meetings += 1
        self.quiet.wake()
        if ghost.real is None:
            raise RuntimeError(f"{self.quiet.name}: the catch-up raised no request for the "
                               f"ghost of tick {ghost.key[0]} ({ghost.key[1]})")

    def wake(self) -> None:
        """The domain wakes: no more ghosts; the catch-up that follows runs with
        ``catching_up`` set (:meth:`_replayed`), and finds a ghost the CPU took without an
        event counted, or running (``Cpu.defer``)."""
        cpu = self.cpu
        if cpu is not None:
            cpu.resolve()
        for ev in self._guards.values():
            ev.cancel()
        self._guards = {}

    def woken(self) -> None:
        """The catch-up is over: every ghost raised up to now stood for a request it raised."""
        now = self.now()
        for g in self._order:
            if g.real is None and g.effects_at is None and g.key[0] <= now:
                raise RuntimeError(f"{self.quiet.name}: the catch-up raised no request for "
                                   f"the ghost of tick {g.key[0]} ({g.key[1]})")
        self._ghosts.clear()
        self._order.clear()

    def _replayed(self, vector: Vector, body: int, fn: Callable[..., None], args: tuple,
                  enter: Callable[[], None] | None) -> None:
        """The catch-up's driver raised a request: its ghost's by now."""
        clock = self.quiet.clock
        t = clock.now
        g = self._ghosts.get((t, vector.name))
        if g is None:
            raise RuntimeError(f"{self.quiet.name}: the catch-up raised {vector.name} at tick "
                               f"{t}, which no ghost stood for")
        if g.effects_at is not None:
            # it stood for the real handler: its effects at their ticks, on the catch-up's
            # scheduler
            private = clock.private
            assert private is not None
            at = g.effects_at
            if g.entered_at is not None and g.entered_at < at and enter is not None:
                private.at(g.entered_at, enter)
                enter = None
            private.at(at, _effects, enter, fn, args)
        else:
            g.real = (enter, fn, args)


def _nothing(*args: Any, **kwargs: Any) -> None:
    pass


def _effects(enter: Callable[[], None] | None, fn: Callable[..., None], args: tuple) -> None:
    if enter is not None:
        enter()
    fn(*args)

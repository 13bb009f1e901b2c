"""The radio ring moved on in whole cycles while it only repeats itself.

An idle ring repeats itself: with every robot of the team a member, no message queued and no
fault under way, each robot sends the same heartbeat at the same offset every cycle, and every
radio, UART, deframer, MAC and timer notes the same things, ticks moved on by the cycle. Run
frame by frame, a long idle stretch costs as much as a busy one. So the world (hil/sim/world.py)
looks for that repetition the way a child's CAN side does (hil/sim/quiet_can.py), at the scale
of the whole radio side:

* Every ``every`` transmissions of one robot (the *anchor*: the lowest ID at first; the
  sender of a transmission after three silent 7-robot rounds of the anchor's), a probe runs
  at the tick that transmission ended, after the events already due then. ``every`` is
  ``poll_every`` (4 turns: a period holds whole polling rounds), or with the father's standby
  PC lcm(poll_every, :data:`~firmware_model.radio.mac.PC2_CHECK_EVERY`) = 28, whole rounds of
  PC2's checks too. If nothing was reported since the last probe (no MAC action: delivery,
  miss, mode change ...; no collision, no injected burst), it takes a snapshot of the world
  (hil/sim/state_walk.py: every attribute of every part, and every pending event), random
  generators by their state.
* If two snapshots a probe apart differ only by ticks moved on by exactly the time between
  them (an even number of ticks: the reload timers count the machine clock / 2), by counters
  nothing reads (:data:`COUNTERS`) and, with the standby PC, by ``turns``, which the MAC then
  reads modulo 7 (:data:`MODULAR`), the ring is periodic. The probe then moves every moved
  tick and counter on by k whole periods in one step (the pending events' ticks among them),
  and the scheduler's clock with them: the state the frame-by-frame run has k periods later,
  to the tick, counters included.
* k keeps every moved event before the first event the period does not move (a fault, a
  message arrival, a robot's power-on: a *horizon*) and within the ``World.run`` under way;
  the rest runs frame by frame, so every such event happens in the state and at the place
  among the tick's events it has in the frame-by-frame run.
* The children's CAN sides must all be asleep (hil/sim/quiet_can.py: a domain with an event
  in the scheduler is awake, and no probe runs then). A sleeping domain is a closed box: its
  state is its orbit and the tick it fell asleep at, and when something wakes it, it moves on
  by the periods that passed whatever the ring did meanwhile; so its parts are left out of the
  snapshot (``boundary``), and a leap leaves them as they are.
* A robot whose radio is dead (a ``fail`` fault, or not powered on yet) hears nothing, is
  heard by nobody and touches nothing of the air's, but its MAC keeps a cycle of its own (it
  claims the silent channel and sends its heartbeats to nobody). Its station is left out of
  the snapshot like a sleeping CAN side, and at a leap its events run on a scheduler of their
  own across the cycles leapt over, frame by frame (``RadioStation.use_scheduler``): the ring
  reports nothing meanwhile, so whatever the deaf station reports keeps its place. A lone
  deaf station leaps over its own cycles there, the same way (snapshots after its frames,
  compared over the last few dozen: :func:`_run_alone`). With a trace, a deaf station's
  events keep the ring from leaping (they would be written twice).
* A trace and an event callback get the events of the cycles leapt over, and a capture
  (hil/sim/pcap.py) their packets: those of the period before the leap, their ticks
  (:data:`TICK_KEYS`) moved on by one period, k times. The probe checks that rule on the run
  itself first: the events and packets of the last period must be those of the period before
  it, ticks moved on by the period and nothing else changed; otherwise no leap. So a traced
  or captured run writes the frame-by-frame run's trace and capture, byte for byte.
* Nothing else may be watching the frames: no hook of someone else's on the air's
  transmissions or collisions or on a station's actions (each would miss the frames leapt
  over); the MAC must be the rotational one.
* On the CPU model (firmware_model/mcu/cpu.py) the CPUs are parts like the rest: what a
  handler costs is counted (``Cpu._busy``, each handler's calls, cycles and latency and
  response counts: counters the leap moves on), a handler running at the probe is a frame
  with ticks. Not with CAN sides there (their interrupts, ghosts or real, meet the radio's
  on the CPU at ticks no ring cycle repeats: hil/sim/can_ghosts.py) nor with a listener
  (the world's per-second CPU loads, World._cpu_second, never repeat with the ring). A
  run's end settles the CPUs (``Cpu.settle``), which hands a UART the bytes of a reception
  it would have had late, a count (``Uart.bytes_late``) no period repeats: the next
  snapshot is then compared with none (:meth:`QuietRing.forget`).
* A snapshot with an object whose inside it cannot see (anything but this project's
  classes, plain values and containers, bytearrays and random generators) never leads to a
  leap.

A snapshot that finds no repetition backs off (1, 2, 4 ... 64 probes), and so does one whose
period leaves no leap of :data:`MIN_LEAP_TICKS` before the next event it does not move (a
loaded ring's next message: the snapshots would cost more than the stretch run frame by
frame); a busy ring takes none at all (something is reported every period). A snapshot leaves
the run's records out (``World.records``: the accounting, which only what the MACs report
grows, and that stops the probes first), so its cost is the ring's state, not the run's
length. A ring that does not repeat itself pays little for the probes.
tests/hil/sim/test_quiet_ring.py compares runs with and without leaps, whole
world and summary, on seeded rings with faults, power-on times, the standby father, CAN sides
and stops between, and on random rings.
"""
from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING, Any

from firmware_model.mcu.scheduler import Event

from .domains import SimScheduler
from firmware_model.radio.mac import PC2_CHECK_EVERY

from .state_walk import Unwalkable, advance, period_steps, snapshot, writable
from .steady import RING_PARTS, counters, modular

if TYPE_CHECKING:
    from firmware_model.station import RadioStation

    from .reception import Transmission
    from .world import World

__all__ = ["COUNTERS", "MODULAR", "GRAIN", "TICK_KEYS", "QuietRing"]

COUNTERS = counters(RING_PARTS)
"""Attributes (or dict/list names) that only count what happened, as the ring's classes declare
them (``STEADY_COUNTERS``; hil/sim/steady.py): they may grow by any amount a period (nothing
reads them to decide what to do). The world's own are added per ring (``World`` imports this
module)."""

MODULAR = modular(RING_PARTS)
"""Counters the model reads only modulo a number, as declared (``STEADY_MODULAR``: ``turns``,
the standby PC2's checks, mac_turns.py): a period must move them by a multiple. Without a
standby PC nothing reads ``turns``: it is one of the counters then."""

TICK_KEYS = frozenset({"end"})
"""Keys of a capture's packet (``PcapWriter.radio``'s arguments) that hold ticks: moved on by
the period when the packets of a cycle leapt over are written (a trace event moves its own:
``TraceEvent.shifted``)."""

GRAIN = 2
"""Ticks a period must be a multiple of: the MAC's reload timer and the stall timer count the
machine clock / 2 (firmware_model/mcu/reload_timer.py), so a deadline's rounding depends on
the tick's parity."""

_BACKOFF_MAX = 64
MIN_LEAP_TICKS = 2 * 16_000_000
"""A leap shorter than this (2 s) is not taken (ticks): the snapshots that found the period cost
more than running that stretch frame by frame (a 2-robot ring runs a simulated second in
about 3 ms; a snapshot of it takes about 5 ms, more as the run's records grow)."""
LOADED_LEAP_TICKS = 8 * 16_000_000
"""The load's next message must be at least this far (8 s, ticks) for a probe to take a
snapshot: a leap ends at that message, needs two snapshots a period apart first (about 10 ms
for a 2-robot ring, the cost of running 3.3 simulated s of it), so a shorter one costs more
than it saves. Measured: a 2-robot ring at a message a second cost 13 % more instructions
with its probes taking snapshots on a 2 s horizon than without the quiet ring at all
(benchmarks/instructions.py, ``loaded``)."""
_ALONE_HISTORY = 4 * 7 * 3
"""Frames of a deaf station a snapshot is compared back over: its cycle is ``poll_every`` (4)
times the rounds of the ring it believes in (up to 7 turns each), and its polling position."""
_ANCHOR_LOST = 3 * 7
"""Transmissions of others after which a silent anchor is replaced."""


class QuietRing:
    """Probes the world's radio side and leaps over the cycles it only repeats (module
    docstring). ``until``: the last tick of the ``World.run`` under way (None outside one:
    no leap then)."""

    def __init__(self, world: "World", anchor: int, poll_every: int, paired: bool) -> None:
        self.world = world
        self.boundary: list[Any] = []
        """Objects the snapshot does not enter: the children's CAN domains and their parts."""
        self.anchor = anchor
        ours = COUNTERS | counters([type(world)])
        if paired:
            self.every = poll_every * PC2_CHECK_EVERY // math.gcd(poll_every, PC2_CHECK_EVERY)
            self.counters, self.modular = ours, MODULAR
        else:
            self.every = poll_every
            self.counters, self.modular = ours | set(MODULAR), {}
        self.enabled = True
        self.until: int | None = None
        self.probes = 0
        self.leaps = 0
        self.ticks_skipped = 0
        """Simulated ticks the ring did not run frame by frame (docs/performance.md)."""
        self.alone_ticks_skipped = 0
        """Of the deaf stations carried across the ring's leaps, the ticks a lone one leapt
        over on its own (module docstring)."""
        self._count = 0
        self._others = 0                       # transmissions since the anchor's last
        self._last: Any = None
        self._last_at = 0
        self._prev: tuple[Any, int] | None = None
        """The snapshot taken before ``_last`` and its tick, if ``_last`` followed it: a cycle
        of an odd number of ticks (the CPU model's handlers start at RDRF, an odd number of
        ticks before a PC's byte ends) is compared over two (GRAIN), untraced."""
        self._misses = 0
        self._skip = 0
        self._hold_until = 0
        """No probe before this tick (the load's next message, while it was too near for a
        leap to pay: only its arrival can move the next one further off)."""
        self._activity: tuple[int, ...] = ()
        self._own_hooks = world.hooks()      # the world's own wiring, as built
        # trace events since the last probe (only while a World.run is under way), and those
        # of the interval before the last snapshot: (tick it began, events)
        self._rec: list[tuple] = []
        self._rec_from: int | None = None
        self._last_events: tuple[int | None, list[tuple]] = (None, [])

    def start_run(self, until: int) -> None:
        """A ``World.run`` up to tick ``until`` begins."""
        self.until = until

    def end_run(self) -> None:
        """It ended: no leap, and no event noted, until the next one."""
        self.until = None
        self._rec, self._rec_from = [], None

    def forget(self) -> None:
        """Compare the next snapshot with none before it: something no period repeats
        happened since the last (World._advance: a run's end that hands a CPU model's UART
        the bytes of a reception it would have had late, which moves ``Uart.bytes_late``
        by other amounts than a period does)."""
        self._last = None

    def note(self, ev: Any, sink: str = "trace") -> None:
        """Something the world wrote out: an event to its listeners (``sink`` "trace", a
        TraceEvent), or a packet to its capture ("pcap": the arguments of
        ``PcapWriter.radio``)."""
        if self.until is not None:
            self._rec.append((sink, ev if sink == "trace" else tuple(ev.items())))

    def heard(self, tx: "Transmission") -> None:
        """A transmission ended (the air's ``on_transmission``); probe after every
        ``every``-th of the anchor's."""
        r = tx.radio.robot
        if r != self.anchor or not self.enabled:
            if r >= 0:
                self._others += 1
                if self._others > _ANCHOR_LOST:    # the anchor is silent: take this robot
                    self.anchor, self._count, self._others, self._last = r, 0, 0, None
            return
        self._others = 0
        self._count += 1
        if self._count % self.every == 0 and self.until is not None:
            sched = self.world.sched
            if sched.now >= self._hold_until:
                sched.at(sched.now, self._probe)

    def _watched(self) -> bool:
        """Does anything outside the world see frames or actions one by one (but the trace,
        the event callback and the capture, which get what the cycles leapt over wrote)?"""
        return self.world.hooks() != self._own_hooks

    def _expiries(self) -> list[int]:
        """The first tick at which a message a station holds may fail ``expired`` on the next
        frame it hears (a station that takes no turns, standing by or listening, fails what is
        older than ``max_age`` there: RotationalMac._expire, clause 50). No event says so, and
        the held message looks like a part that repeats: a leap across it failed a standby's
        message at 145 s where the frame-by-frame run fails it at 60 s."""
        w = self.world
        sb = w.standby_station
        out = []
        for st in (*w.stations.values(), *w.extra_stations.values(),
                   *((sb,) if sb is not None else ())):
            mac = st.mac
            held = [m.submitted for m in (*getattr(mac, "_queue", ()),
                                          getattr(mac, "_inflight", None)) if m is not None]
            if held:
                out.append(min(held) + mac.cfg.max_age + 1)
        return out

    def _back_off(self) -> None:
        """A snapshot that led to no leap: after the n-th in a row, the next 2^(n-1) - 1 probes
        (at most 63) take none."""
        self._misses += 1
        self._skip = min(1 << (self._misses - 1), _BACKOFF_MAX) - 1
        if self._skip:
            self._last = None

    def _probe(self) -> None:
        now = self.world.sched.now
        recorded, rec_from = self._rec, self._rec_from
        self._rec, self._rec_from = [], now
        if self.until is None or self._watched():
            self._last = None
            return
        activity = self.world.activity()
        if activity != self._activity:         # something reported: not repeating itself
            self._activity = activity
            self._last = None
            return
        if self._skip:
            self._skip -= 1
            return
        due = self.world.load.next_arrival()
        if due is not None and due < now + LOADED_LEAP_TICKS:
            # a message arrives (the load's next draw, never part of a cycle) before a leap
            # could repay its snapshots: none taken, nor any probe until it has arrived
            self._last = None
            self._hold_until = due
            return
        sched = self.world.sched
        sched.settle_later()           # the CPUs' lone handlers as the general path has them
        events = sched.pending(None)
        if len(events) != len(sched):          # another owner's events (a domain): not ours
            self._last = None
            return
        deaf = self.world.deaf_stations()
        clocked = {id(p) for st in deaf for p in st.clocked_parts()}
        carried = False
        if clocked:                            # theirs run on alone, carried across a leap
            ring = [e for e in events if id(getattr(e.fn, "__self__", None)) not in clocked]
            carried, events = len(ring) < len(events), ring
        self.probes += 1
        try:
            # the trace writer and the capture are outside: what they were given is
            # checked below, event by event and packet by packet
            sinks = [x for x in (self.world.trace, self.world.pcap) if x is not None]
            walls = [part for st in deaf for part in _own_parts(st)]
            snap = snapshot([self.world, events],
                            [sched, self, *sinks, *self.boundary, *walls,
                             *self.world.records()], rng_state=True)
        except Unwalkable:                     # an iterator somewhere: its state is hidden
            self.enabled = False
            return
        if any(type(x) is tuple and x and x[0] == "id" for x in snap.shape):
            self.enabled = False               # something whose state it cannot see
            return
        last, at = self._last, self._last_at
        prev = self._prev
        before = self._last_events
        self._prev = (last, at) if last is not None else None
        self._last, self._last_at = snap, now
        self._last_events = (rec_from, recorded)
        if last is None:
            return
        period = now - at
        w = self.world
        traced = bool(w.listeners) or w.pcap is not None
        if period % GRAIN and not traced:
            if prev is None:
                return                 # compared over two at the next probe: not a miss
            if (now - prev[1]) % GRAIN == 0:
                last, at = prev
                period = now - at
        steps = period_steps(last, snap, period, self.counters, self.modular) \
            if period > 0 and period % GRAIN == 0 else None
        if steps is None:
            self._back_off()
            return
        moved = writable(snap, steps)
        stepped = {id(h) for h, key, _ in moved if key == "when" and type(h) is Event}
        horizon = min([e.when for e in events if id(e) not in stepped] + [self.until + 1]
                      + self._expiries())
        reach = max([e.when for e in events if id(e) in stepped] + [now])
        # every moved event stays before the horizon: strictly, so that one due at the
        # horizon's tick keeps its place among that tick's events
        k = (horizon - 1 - reach) // period
        if k * period < MIN_LEAP_TICKS:
            # periodic, but the next event it does not move is too near for a leap to pay
            # for the snapshots (a loaded ring's next message): backed off as a miss
            self._back_off()
            return
        self._misses = 0
        if traced and (carried or not (rec_from == at and before[0] == at - period and
                                    _shifted(before[1], period) == recorded)):
            # the events do not repeat (yet), or a deaf station's would be written twice
            # (replayed with the ring's, and by its own run across the leap): no leap
            return
        taken = sched.take(None)
        advance(moved, k)
        target = now + k * period
        if carried:
            taken = _carry(self, deaf, clocked, taken, now, target)
        sched.skip_to(target)
        sched.put_back(taken)
        if traced:
            for j in range(1, k + 1):
                for sink, item in _shifted(recorded, j * period):
                    w.replay(item if sink == "trace" else dict(item), sink)
        self._rec_from = sched.now
        self.leaps += 1
        self.ticks_skipped += k * period
        self._last = None


def _own_parts(st: "RadioStation") -> list[Any]:
    """A station and everything of its own (its radio too): a deaf station keeps a cycle of
    its own, which the ring's snapshot leaves out (a closed box, like a sleeping CAN side)."""
    return [st, st.uart, st.uart.line, st.txen, st.mac, st.deframer, *st.clocked_parts()]


def _carry(ring: QuietRing, deaf: list["RadioStation"], clocked: set[int],
           taken: list[Event], start: int, end: int) -> list[Event]:
    """Run the deaf stations' events (among ``taken``, the world's events out of its heap)
    from ``start`` up to tick ``end`` on a scheduler of their own, as the frame-by-frame run
    does meanwhile: they hear nothing, are heard by nobody and touch nothing of the air's, and
    the ring whose cycles are leapt over reports nothing, so whatever a deaf station reports
    keeps its place. A lone deaf station with events leaps over the cycles of its own it only
    repeats (:func:`_run_alone`). Returns ``taken`` with their events as they are at
    ``end``."""
    world = ring.world
    mine = [e for e in taken if id(getattr(e.fn, "__self__", None)) in clocked]
    if not mine:
        return taken
    ids = {id(e) for e in mine}
    private = type(world.sched)(start)    # (the CPU model's keeps places: PlacedScheduler)
    private.put_back(mine)
    selves = {id(getattr(e.fn, "__self__", None)) for e in mine}
    owners = [st for st in deaf if any(id(p) in selves for p in st.clocked_parts())]
    for st in deaf:
        st.use_scheduler(private)
    try:
        if len(owners) == 1:
            ring.alone_ticks_skipped += _run_alone(owners[0], private, end, ring)
        private.run_until(end)
    finally:
        for st in deaf:
            st.use_scheduler(world.sched)
    return [e for e in taken if id(e) not in ids] + private.take(None)


def _run_alone(st: "RadioStation", private: SimScheduler, end: int, ring: QuietRing) -> int:
    """Run a lone deaf station on ``private`` toward tick ``end``, leaping over its own
    cycles. After every frame it sends (to nobody), a snapshot of the station and its pending
    events is compared with those after each of its last :data:`_ALONE_HISTORY` frames (its
    cycle is whole rounds of the ring it still believes in: 1-7 turns, and its polling every
    ``poll_every`` of them); one that differs from an earlier one only by ticks moved on by
    the time between them and by counters, with nothing reported to the world meanwhile
    (``World.activity``; counters as the ring's, ``turns`` modulo 7 beside a standby PC), and
    it moves on by whole cycles, every moved event staying before
    ``end`` and before any event the cycle does not move. Stops short of ``end`` (the caller
    runs the rest). Returns the ticks it leapt over."""
    skipped = 0
    world = ring.world
    walls = [private, world.sched, world.air, world]
    sent = st.mac.frames_sent
    history: deque = deque(maxlen=_ALONE_HISTORY)
    while True:
        t = private.next_time()
        if t is None or t > end:
            return skipped
        private.step()
        if st.mac.frames_sent == sent:
            continue
        sent = st.mac.frames_sent
        now = private.now
        activity = world.activity()
        private.settle_later()
        events = private.pending(None)
        try:
            snap = snapshot([_own_parts(st), events], walls, rng_state=True)
        except Unwalkable:
            return skipped
        for last, last_at, last_activity in reversed(history):
            period = now - last_at
            if last_activity != activity or period % GRAIN:
                continue
            steps = period_steps(last, snap, period, ring.counters, ring.modular)
            if steps is None:
                continue
            moved = writable(snap, steps)
            stepped = {id(h) for h, key, _ in moved if key == "when" and type(h) is Event}
            horizon = min([e.when for e in events if id(e) not in stepped] + [end + 1])
            reach = max([e.when for e in events if id(e) in stepped] + [now])
            k = (horizon - 1 - reach) // period
            if k >= 1:
                taken = private.take(None)
                advance(moved, k)
                private.skip_to(now + k * period)
                private.put_back(taken)
                history.clear()
                skipped += k * period
                break
        else:
            history.append((snap, now, activity))


def _shifted(events: list[tuple], by: int) -> list[tuple]:
    """``events`` (each (sink, a TraceEvent or a packet's items)) with their ticks moved on
    by ``by``."""
    return [(sink, item.shifted(by) if sink == "trace" else
             tuple((k, v + by) if k in TICK_KEYS and type(v) is int else (k, v)
                   for k, v in item)) for sink, item in events]

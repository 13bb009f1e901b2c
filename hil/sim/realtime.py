"""A real-time scheduler: the simulation Scheduler's API, with ``now`` following the wall clock.

The same firmware objects run on it unchanged (``at``/``after``/``now`` in 16 MHz ticks). Time
zero is the moment the scheduler starts; a scheduled event runs when the monotonic clock
reaches its tick and sees ``now`` equal to that tick, so the firmware's relative timing is
exact even when the operating system wakes us late (the lateness is measured: ``max_late``).
Other threads (python-can readers, serial readers) hand work in with ``post`` (or
``post_at``, with the tick the input really arrived at when the poster knows an earlier one:
a CAN frame's kernel timestamp); it runs in the scheduler's thread, in tick
order with the due events, as an MCU takes a receive interrupt before a timer due after it: a
timer never judges "nothing came" when something came before it was due and only the process
was late to take it in. A late wake (the process got no CPU for a while) first gives the reader
threads a moment to hand in what came meanwhile. An input runs with ``now`` at the wall-clock
tick it was posted at (``now`` never goes back).

A process that did not run for a while (SIGSTOP and SIGCONT, a machine that gave it no CPU, a
handler blocked in a write) must not replay its past: with ``watch_stalls(ticks, fn)``, once
the loop notices that it (or a due event) is more than ``ticks`` late, it sets ``now`` to the
wall clock, calls ``fn(late, now)`` before anything else runs (the bench's stations drop what
they heard meanwhile and listen for the ring again), and runs the overdue events at that
``now``, as a late interrupt sees the time it runs at, not the time it was due. A heartbeat
thread tells a stopped process from an idle one. Functions given to ``on_start`` run first
of all when running starts, at tick 0, before anything posted.
"""
from __future__ import annotations

import collections
import heapq
import queue
import threading
import time
from typing import Any, Callable

from firmware_model.timing import TICK_HZ

from .domains import SimScheduler

_NS_PER_TICK_NUM = TICK_HZ          # ticks = ns * TICK_HZ / 1e9

MAX_WAIT_S = 60.0
"""Longest single wait for the next event or a post; the loop then looks again. An event or
an end far in the future (a drop at 10**7 s, a ``--duration`` of 1e300 s) is still waited for,
without asking the OS for a timeout it cannot represent (``threading.TIMEOUT_MAX``)."""
_MAX_WAIT_TICKS = round(MAX_WAIT_S * TICK_HZ)

LATE_WAKE_TICKS = TICK_HZ // 1000
"""A due event this late (1 ms) means the process was not running for a while: before it runs,
the reader threads get ``READERS_S`` to hand in what arrived meanwhile."""
READERS_S = 0.001

LATE_NOTE_TICKS = 20 * TICK_HZ // 1000
"""A due event this late (20 ms: the real-time set's quiet gap, a quarter of its Tslot) is
noted (``lates``): the bench's margins absorb it, but a few of them in a row leave a station's
turn too little of its margin (docs/guarantees.md, "What the host must give")."""
LATES_KEPT = 1024


class RealTimeScheduler(SimScheduler):
    """Runs events at their wall-clock tick; ``post`` is the thread-safe way in."""

    __slots__ = ("_t0", "_inbox", "_stop", "max_late", "late_events", "_started", "epoch_ns",
                 "_at_start", "stall_ticks", "stalls", "_on_stall", "_beat", "_stalled",
                 "_beater", "_beat_stop", "_settled", "_pending", "_seq", "late_ticks", "lates",
                 "_on_late")

    def __init__(self) -> None:
        super().__init__(0)
        self._t0 = time.monotonic_ns()
        self._started = False
        self.epoch_ns: int | None = None
        """The wall clock (``time.time_ns()``) at tick 0, fixed when running starts; None
        before (a capture stamps its packets ``epoch_ns`` + their tick in ns)."""
        self._inbox: queue.SimpleQueue = queue.SimpleQueue()
        self._stop = threading.Event()
        self.max_late = 0
        self.late_events = 0
        self._at_start: list[Callable[[], None]] = []
        self.stall_ticks: int | None = None
        """A stall longer than this (ticks) is handled (``watch_stalls``); None: not watched."""
        self.stalls: list[tuple[int, int]] = []
        """(tick it was noticed at, how late the process was) for every stall handled."""
        self._on_stall: list[Callable[[int, int], None]] = []
        self._beat = 0                  # the heartbeat thread's last wall tick
        self._stalled = 0               # a gap the heartbeat saw in itself, not yet handled
        self._beater: threading.Thread | None = None
        self._beat_stop = threading.Event()   # ends the heartbeat when running ends
        self._settled = 0               # the tick the last stall was handled at
        self._pending: list = []        # posts taken in: (arrival, seq, posted, fn, args)
        self._seq = 0
        self.late_ticks = LATE_NOTE_TICKS
        """A due event that runs more than this late (ticks), though not a stall, is noted in
        ``lates`` and told to ``watch_late``'s functions."""
        self.lates: collections.deque[tuple[int, int]] = collections.deque(maxlen=LATES_KEPT)
        """(tick the event was due at, how late it ran) for the latest events run more than
        ``late_ticks`` late: lateness the margins must absorb, short of a stall."""
        self._on_late: list[Callable[[int, int], None]] = []

    def on_start(self, fn: Callable[[], None]) -> None:
        """Run ``fn()`` in the scheduler's thread when running starts, before anything posted
        (a serial port is flushed then, and a station powered on: bytes that came before it
        listened are not heard)."""
        if self._started:
            self.post(fn)
        else:
            self._at_start.append(fn)

    def watch_stalls(self, ticks: int, fn: Callable[[int, int], None]) -> None:
        """Call ``fn(late, now)`` in the scheduler's thread whenever the process turns out to
        have not run for more than ``ticks`` (the smallest threshold given is used)."""
        self.stall_ticks = ticks if self.stall_ticks is None else min(ticks, self.stall_ticks)
        self._on_stall.append(fn)

    def watch_late(self, fn: Callable[[int, int], None]) -> None:
        """Call ``fn(late, due)`` in the scheduler's thread whenever a due event runs more than
        ``late_ticks`` late (and the lateness is no stall: those go to ``watch_stalls``)."""
        self._on_late.append(fn)

    def _heartbeat(self) -> None:
        """Beats every quarter of the threshold; a beat that came more than the threshold
        after the last means the whole process was stopped (SIGSTOP) or starved of CPU."""
        assert self.stall_ticks is not None    # (started only when stalls are watched)
        period = self.stall_ticks / 4 / TICK_HZ
        prev = self.wall()
        while not self._beat_stop.wait(period):
            w = self.wall()
            if w - prev > self.stall_ticks and prev >= self._settled:
                # (set before the beat, so the loop sees one or the other; a gap that began
                # before the last stall was handled is that stall, seen again)
                self._stalled = w - prev
            prev = w
            self._beat = w

    def _check_stall(self, wall: int, due: int | None = None) -> None:
        """Handle a stall if the heartbeat saw one, it has not beaten for too long, or the
        event due at ``due`` is too late (an event due before the last stall was handled
        is not late again)."""
        assert self.stall_ticks is not None    # (called only when stalls are watched)
        late = max(self._stalled, wall - max(self._beat, self._settled),
                   0 if due is None else wall - max(due, self._settled))
        if late <= self.stall_ticks:
            return
        self._stalled = 0
        self._beat = wall
        self._settled = wall
        if wall > self.now:
            self.now = wall
        self.stalls.append((self.now, late))
        for fn in self._on_stall:
            fn(late, self.now)

    def wall(self) -> int:
        """The wall-clock tick now (since the scheduler started)."""
        return (time.monotonic_ns() - self._t0) * _NS_PER_TICK_NUM // 1_000_000_000

    def post(self, fn: Callable[..., Any], *args: Any) -> None:
        """Run ``fn(*args)`` in the scheduler's thread as soon as possible (thread-safe), in
        order with the events due up to now (its tick is the wall clock's now)."""
        w = self.wall()
        self._inbox.put((w, w, fn, args))

    def post_at(self, tick: int, fn: Callable[..., Any], *args: Any) -> None:
        """``post`` for an input that arrived at ``tick`` (thread-safe): events due after
        ``tick`` run after it, even if the process takes it in later; it runs with ``now`` at
        the tick of this call."""
        w = self.wall()
        self._inbox.put((min(tick, w), w, fn, args))

    def stop(self) -> None:
        """Make ``run_forever``/``run_for`` return (thread-safe)."""
        self._stop.set()
        self._inbox.put(None)

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def run_for(self, seconds: float) -> None:
        """Run for ``seconds`` of wall-clock time (or until ``stop()``); a span too long to
        count in ticks (``inf``, 1e300 s) runs until ``stop()``."""
        ticks = seconds * TICK_HZ
        if ticks == float("inf"):
            self._run(None)
            return
        self._run((self.wall() if self._started else self.now) + round(ticks))

    def run_forever(self) -> None:
        self._run(None)

    def run_until(self, end: int) -> None:
        """Run until the wall clock reaches tick ``end`` (the simulation API, in real time)."""
        self._run(end)

    def _run(self, end: int | None) -> None:
        if not self._started:
            # The wall clock starts when running starts (building the world takes time).
            self._started = True
            since_0 = self.now * 1_000_000_000 // _NS_PER_TICK_NUM
            self._t0 = time.monotonic_ns() - since_0
            self.epoch_ns = time.time_ns() - since_0
            for fn in self._at_start:
                fn()
            self._at_start.clear()
        watch = self.stall_ticks is not None
        if watch:
            # the heartbeat beats while running runs (a run in steps starts one each time)
            self._beat = self.wall()
            self._beat_stop.clear()
            self._beater = threading.Thread(target=self._heartbeat, name="heartbeat",
                                            daemon=True)
            self._beater.start()
        try:
            self._loop(end, watch)
        finally:
            if self._beater is not None:
                self._beat_stop.set()
                self._beater.join(timeout=1.0)
                self._beater = None

    def _take_inbox(self) -> None:
        """Move what other threads posted into the pending heap (``stop()``'s None ends it:
        the loop sees the stop flag)."""
        inbox = self._inbox
        while True:
            try:
                item = inbox.get_nowait()
            except queue.Empty:
                return
            if item is None:
                return
            self._pend(item)

    def _pend(self, item: tuple) -> None:
        """One posted item into the pending heap. (A tick taken before running started counts
        from the scheduler's creation, not from tick 0: it is no later than the wall now.)"""
        w = self.wall()
        self._seq += 1
        heapq.heappush(self._pending, (min(item[0], w), self._seq, min(item[1], w), item[2],
                                       item[3]))

    def _loop(self, end: int | None, watch: bool) -> None:
        heap = self._heap
        inbox = self._inbox
        pending = self._pending
        while not self._stop.is_set():
            wall = self.wall()
            if end is not None and wall >= end:
                break
            if watch:
                self._check_stall(wall, heap[0][0] if heap else None)
            self._take_inbox()
            if heap and wall - heap[0][0] > LATE_WAKE_TICKS:
                # a late wake: the readers (woken with us) hand in what came meanwhile first
                time.sleep(READERS_S)
                self._take_inbox()
                wall = self.wall()
            # due events and posted inputs, in tick order (an input first on a tie: it came
            # before the timer fired); each event sees its own tick, an input the tick it
            # was posted at (``now`` never goes back; after a stall: the tick it was noticed
            # at, as a late interrupt sees the time it runs at)
            while True:
                if pending and (not heap or heap[0][0] > wall or pending[0][0] <= heap[0][0]):
                    _, _, posted, fn, args = heapq.heappop(pending)
                    if watch:
                        self._check_stall(self.wall())
                    if posted > self.now:
                        self.now = posted
                    fn(*args)
                    continue
                if not heap or heap[0][0] > wall:
                    break
                when, _, ev = heapq.heappop(heap)
                if ev.cancelled:
                    continue
                if watch:
                    assert self.stall_ticks is not None
                    w = self.wall()             # (``wall`` is stale if a handler blocked)
                    if w - max(when, self._settled) > self.stall_ticks:
                        self._check_stall(w, when)
                if when > self.now:
                    self.now = when
                late = wall - when
                if late > self.max_late:
                    self.max_late = late
                if late > TICK_HZ // 1000:
                    self.late_events += 1
                    if late > self.late_ticks and when >= self._settled:
                        self.lates.append((when, late))
                        for fn in self._on_late:
                            fn(late, when)
                ev.fn(*ev.args)
            if self._stop.is_set():
                break
            # then wait for the next event, an input or the end
            wait = _MAX_WAIT_TICKS          # whole ticks: no float of a far tick overflows
            nxt = self.next_time()
            wall = self.wall()
            if nxt is not None:
                wait = min(wait, nxt - wall)
            if end is not None:
                wait = min(wait, end - wall)
            timeout = max(0, wait) / TICK_HZ
            try:
                item = inbox.get(timeout=timeout) if timeout > 0 else inbox.get_nowait()
            except queue.Empty:
                continue
            if item is None:
                break
            self._pend(item)
        if end is not None and self.now < end and not self._stop.is_set():
            self.now = max(self.now, min(end, self.wall()))

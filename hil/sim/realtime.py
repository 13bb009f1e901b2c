"""A real-time scheduler: the simulation Scheduler's API, with ``now`` following the wall clock.

The same firmware objects run on it unchanged (``at``/``after``/``now`` in 16 MHz ticks). Time
zero is the moment the scheduler starts; a scheduled event runs when the monotonic clock
reaches its tick and sees ``now`` equal to that tick, so the firmware's relative timing is
exact even when the operating system wakes us late (the lateness is measured: ``max_late``).
Other threads (python-can readers, serial readers) hand work in with ``post``; it runs in the
scheduler's thread with ``now`` set to the wall-clock tick of its arrival.
"""
from __future__ import annotations

import heapq
import queue
import threading
import time
from typing import Any, Callable

from firmware_model.mcu.scheduler import Scheduler
from firmware_model.timing import TICK_HZ

_NS_PER_TICK_NUM = TICK_HZ          # ticks = ns * TICK_HZ / 1e9

MAX_WAIT_S = 60.0
"""Longest single wait for the next event or a post; the loop then looks again. An event or
an end far in the future (a drop at 10**7 s, a ``--duration`` of 1e300 s) is still waited for,
without asking the OS for a timeout it cannot represent (``threading.TIMEOUT_MAX``)."""
_MAX_WAIT_TICKS = round(MAX_WAIT_S * TICK_HZ)


class RealTimeScheduler(Scheduler):
    """Runs events at their wall-clock tick; ``post`` is the thread-safe way in."""

    __slots__ = ("_t0", "_inbox", "_stop", "max_late", "late_events", "_started", "epoch_ns")

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

    def wall(self) -> int:
        """The wall-clock tick now (since the scheduler started)."""
        return (time.monotonic_ns() - self._t0) * _NS_PER_TICK_NUM // 1_000_000_000

    def post(self, fn: Callable[..., Any], *args: Any) -> None:
        """Run ``fn(*args)`` in the scheduler's thread as soon as possible (thread-safe)."""
        self._inbox.put((fn, args))

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
        heap = self._heap
        inbox = self._inbox
        while not self._stop.is_set():
            wall = self.wall()
            if end is not None and wall >= end:
                break
            # due events first, in tick order, each seeing its own tick
            while heap and heap[0][0] <= wall:
                when, _, ev = heapq.heappop(heap)
                if ev.cancelled:
                    continue
                if when > self.now:
                    self.now = when
                late = wall - when
                if late > self.max_late:
                    self.max_late = late
                if late > TICK_HZ // 1000:
                    self.late_events += 1
                ev.fn(*ev.args)
            # then whatever other threads handed in
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
            while item is not None:
                fn, args = item
                w = self.wall()
                if w > self.now:
                    self.now = w
                fn(*args)
                try:
                    item = inbox.get_nowait()
                except queue.Empty:
                    break
        if end is not None and self.now < end and not self._stop.is_set():
            self.now = max(self.now, min(end, self.wall()))

"""A simulated CAN bus with test nodes that record what the bus tells them (ticks of the
16 MHz scheduler), for the bus's tests (test_can_bus.py, test_can_local_errors.py)."""
from __future__ import annotations

from can_bus.bits import BitTiming
from can_bus.bus import CanBus
from can_bus.frames import CanFrame
from firmware_model.mcu.scheduler import Scheduler

TPB = 32  # default BitTiming: 500 kbit/s at 16 MHz


class Node:
    """Test node using the bus-kept queue (no pending())."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.rx: list[tuple[CanFrame, int, int]] = []
        self.done: list[tuple[CanFrame, int]] = []
        self.lost: list[CanFrame] = []
        self.errors = []
        self.states: list[tuple[str, str, int]] = []

    def on_frame(self, frame, start, end):
        self.rx.append((frame, start, end))

    def on_tx_done(self, frame, end):
        self.done.append((frame, end))

    def on_arbitration_lost(self, frame):
        self.lost.append(frame)

    def on_error(self, ev):
        self.errors.append(ev)

    def on_state_change(self, old, new, tick):
        self.states.append((old.value, new.value, tick))

    def __repr__(self):
        return self.name


class QueueNode(Node):
    """Node keeping its own priority queue, offered through pending()."""

    def __init__(self, name):
        super().__init__(name)
        self.q: list[CanFrame] = []

    def pending(self):
        return min(self.q, key=lambda f: (f.id, f.rtr)) if self.q else None

    def on_tx_done(self, frame, end):
        super().on_tx_done(frame, end)
        self.q.remove(frame)


def make(n=2, timing=None, cls=Node):
    sched = Scheduler()
    bus = CanBus(sched, timing or BitTiming())
    nodes = [cls(chr(ord("a") + i)) for i in range(n)]
    for x in nodes:
        bus.attach(x)
    log = []
    errs = []
    bus.trace = lambda f, s, e, w: log.append((f, s, e, w))
    bus.error_trace = lambda *a: errs.append(a)
    return sched, bus, nodes, log, errs

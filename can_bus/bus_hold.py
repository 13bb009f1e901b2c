"""A bus held dominant (can_bus.bus, ``hold_dominant``): the error flag it starts, the counters
it moves every 8 dominant bits, and the bus idle again after the release.
Plain functions bound as methods of :class:`~can_bus.bus.CanBus`."""
from __future__ import annotations

from typing import TYPE_CHECKING

from can_bus.bits import ERROR_DELIMITER_BITS, ERROR_FLAG_BITS, IFS_BITS, SUSPEND_TRANSMISSION_BITS
from can_bus.bus_state import (_ELEVEN, _FRAME, _HELD, _IDLE, _TAIL, ACTIVE, BUS_OFF, PASSIVE,
                               CanErrorEvent, _Hold)

if TYPE_CHECKING:
    from can_bus.bus import CanBus


def _hold_start(self: CanBus) -> None:
    now = self.sched.now
    h = self._hold
    if h is not None:  # re-held before a short release was processed
        h.released = None
        return
    if self._arb_ev is not None:
        self._arb_ev.cancel()
        self._arb_ev = None
    if self._seg_ev is not None:
        self._seg_ev.cancel()
        self._seg_ev = None
    if self._phase == _FRAME:
        tx, rx, flag = self._cur_tx, self._cur_rx, now
        for ns in tx:
            ns.entry = None
    else:
        if self._phase == _IDLE:
            self._start_segment(now)
        tx, flag = [], now + ERROR_FLAG_BITS * self.tpb
        rx = [ns for ns in self._nodes if ns.state is not BUS_OFF]
    self._phase = _HELD
    self._busy_until = None
    self._hold = _Hold(flag, tx, rx)
    self._hold_schedule()


def _hold_release(self: CanBus) -> None:
    h = self._hold
    if h is None:
        return
    now = self.sched.now
    h.released = now
    self._settle(now)
    if h.step > 0:
        self._hold_finish()
    else:
        self._hold_schedule()


def _hold_tick_time(self: CanBus, step: int) -> int:
    h = self._hold
    assert h is not None                  # the bus is held dominant
    if step == 0:
        return h.flag
    if step == 1:
        return h.flag + 7 * self.tpb
    return h.flag + (14 + 8 * (step - 2)) * self.tpb


def _can_change(self: CanBus) -> bool:
    h = self._hold
    assert h is not None                  # the bus is held dominant
    return any(ns.state is not BUS_OFF for ns in h.tx) or any(ns.state is ACTIVE for ns in h.rx)


def _settle(self: CanBus, upto: int) -> None:
    h = self._hold
    assert h is not None                  # the bus is held dominant
    tpb = self.tpb
    limit = upto if h.released is None else min(upto, h.released)
    while True:
        s = h.step
        t = self._hold_tick_time(s)
        if t > (upto if s == 0 else limit):
            return
        if s >= 2 and not self._can_change():
            bits = (limit - h.flag) // tpb
            total = 1 + (bits - 14) // 8
            more = total - (s - 2)
            for ns in h.rx:
                if ns.state is not BUS_OFF:
                    ns.rec += 8 * more
            h.step += more
            return
        h.step = s + 1
        if s == 0:
            self._count(h.tx, 8, 0, t)
            self._count(h.rx, 0, 1, t)
            frame = self._cur_frame if h.tx else None
            for ns in h.tx:
                if ns.on_error is not None and ns.attached:
                    ns.on_error(CanErrorEvent("bit", t, frame, True, ns.tec, ns.rec, ns.state))
            for ns in h.rx:
                if ns.on_error is not None and ns.attached and ns.state is not BUS_OFF:
                    ns.on_error(CanErrorEvent("stuff", t, frame, False, ns.tec, ns.rec,
                                              ns.state))
            self.error_frames += 1
            if self.error_trace is not None:
                self.error_trace("bit" if h.tx else "stuff", frame,
                                 self._cur_start if h.tx else t - ERROR_FLAG_BITS * tpb, t,
                                 None, h.tx[0].node if h.tx else None)
        else:
            if s >= 2:
                self._count(h.tx, 8, 0, t)
            self._count(h.rx, 0, 8, t)


def _count(self: CanBus, nodes: list, tec: int, rec: int, t: int) -> None:
    """Add to the error counters of every node in ``nodes`` that is not bus-off."""
    for ns in nodes:
        if ns.state is not BUS_OFF:
            ns.tec += tec
            ns.rec += rec
            self._update(ns, t)


def _hold_schedule(self: CanBus) -> None:
    h = self._hold
    assert h is not None                  # the bus is held dominant
    if h.ev is not None:
        h.ev.cancel()
        h.ev = None
    if h.step == 0:
        t = h.flag
    elif self._can_change():
        t = self._hold_tick_time(h.step)
        if h.released is not None and t > h.released:
            return
    else:
        return
    h.ev = self.sched.at(max(t, self.sched.now), self._hold_tick)


def _hold_tick(self: CanBus) -> None:
    h = self._hold
    assert h is not None                  # the bus is held dominant
    h.ev = None
    self._settle(self.sched.now)
    if h.released is not None:
        self._hold_finish()
    else:
        self._hold_schedule()


def _hold_finish(self: CanBus) -> None:
    h = self._hold
    assert h is not None and h.released is not None     # held, then released
    if h.ev is not None:
        h.ev.cancel()
    tpb = self.tpb
    idle_at = (max(h.released, h.flag + ERROR_FLAG_BITS * tpb)
               + (ERROR_DELIMITER_BITS + IFS_BITS) * tpb)
    for ns in h.tx:
        if ns.state is PASSIVE:
            ns.suspend_until = idle_at + SUSPEND_TRANSMISSION_BITS * tpb
            self._watch = True
    self._hold = None
    self._phase = _TAIL
    self._busy_until = idle_at
    self._seg_ev = self.sched.at(idle_at, self._segment_end, _ELEVEN)

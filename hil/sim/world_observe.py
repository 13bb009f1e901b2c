"""What the MACs report, as the world takes it: the accounting first (hil/sim/ledger.py), then
the typed event (hil/sim/events.py) when someone listens. Plain functions bound as methods of
:class:`hil.sim.world.World` (``_observe``: every station's observer, the simulator's hot path).
"""
from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

from firmware_model.radio.deframer import FrameFailed
from firmware_model.radio.mac import (
    BadContent, Deliver, Disable, Duplicate, DuplicateId, ForeignRing, Join, Message, Miss,
    ModeChange, NumberBehind, Outcome, Refused, Transmit, TxEnable,
)
from firmware_model.station import RadioStation

from . import events as E

if TYPE_CHECKING:
    from .world import World

STANDBY = 100
"""Key of the father's standby PC (PC2, also ID 0 on the air) in ``World.radios``."""


def _observe(self: World, st: RadioStation, a: Any, now: int) -> None:
    """``a``: any action of a MAC (firmware_model/radio/mac_events.py), told apart by its
    exact type in a chain of ``is``: the simulator's hot path, so ``a`` is typed Any
    rather than narrowed branch by branch. The accounting comes first; the event is built
    only when someone listens."""
    r = st.id
    if self._extra_of:
        k = self._extra_of.get(st)
        if k is not None:
            if type(a) is not Transmit and type(a) is not TxEnable:
                self._observe_extra(st, k, a)
            return
    pc = None                      # both PCs are ID 0: the tag tells them apart
    if st is self.standby_station:
        if type(a) is ModeChange:
            self.observed += 1
            if self.listeners:
                self._emit(E.Mode(t=self.sched.now, robot=0, pc=2, mode=a.mode,
                                  reason=a.reason))
            return
        pc = 2
    t = type(a)
    if t is Transmit:
        return
    listened = bool(self.listeners)
    if t is TxEnable:
        if listened:
            self._emit(E.TxenEdge(t=self.sched.now, robot=r, on=a.on, pc=pc))
        return
    self.observed += 1
    ev: E.TraceEvent | None = None
    if t is Miss:
        # Counted once per turn, and only by observers that can hear the air (PC2 by its
        # own radio: it once went by PC1's, both being robot 0).
        if self.radios[STANDBY if st is self.standby_station else r].alive:
            self.ledger.missed(now, a.robot)
        if listened:
            ev = E.Miss(t=self.sched.now, robot=a.robot, by=r, pc=pc)
    elif t is Disable:
        self.ledger.membership_change("disable", a.robot, now)
        if listened:
            ev = E.Disable(t=self.sched.now, robot=a.robot, by=r, pc=pc)
    elif t is Join:
        self.ledger.membership_change("rejoin" if a.again else "join", a.robot, now)
        if listened:
            ev = (E.Rejoin if a.again else E.Join)(t=self.sched.now, robot=a.robot, by=r,
                                                   pc=pc)
    elif t is ModeChange:
        self.ledger.membership_change(a.mode, r, now, observed=False)
        if listened:
            ev = E.Mode(t=self.sched.now, robot=r, mode=a.mode, reason=a.reason)
    elif t is Deliver:
        intact = self.ledger.delivered_to(a, r)
        if listened:
            ev = E.Delivery(t=self.sched.now, src=a.src, dst=a.dst, num=a.num,
                            type=a.type, to=r, intact=intact, pc=pc)
    elif t is Duplicate:
        self.stats[r].duplicates += 1
        if listened:
            ev = E.Duplicate(t=self.sched.now, src=a.src, num=a.num, to=r, pc=pc)
    elif t is Refused:
        self.stats[r].refused_frames += 1
        if listened:
            ev = E.Refused(t=self.sched.now, src=a.src, num=a.num, to=r, reason=a.reason,
                           pc=pc)
    elif t is NumberBehind:
        self.stats[r].numbers_behind += 1
        if listened:
            ev = E.Behind(t=self.sched.now, src=a.src, num=a.num, last=a.last, to=r,
                          refused=a.refused, pc=pc)
    elif t is DuplicateId:
        said = E.DuplicateId(t=self.sched.now, robot=r, yielding=a.yielding)
        self.identity.append(said.record())
        ev = said if pc is None else replace(said, pc=pc)
    elif t is ForeignRing:
        heard = E.ForeignRing(t=self.sched.now, robot=r, robots=tuple(a.robots),
                              member=a.member)
        self.identity.append(heard.record())
        ev = heard if pc is None else replace(heard, pc=pc)
    elif t is FrameFailed:
        self.stats[r].bad_frames += 1
        if listened:
            ev = E.BadFrame(t=self.sched.now, to=r, field=a.error.field,
                            reason=str(a.error), pc=pc)
    elif t is BadContent:
        if listened:
            ev = E.BadContent(t=self.sched.now, src=a.src, num=a.num, to=r,
                              reason=str(a.error), pc=pc)
    elif t is Outcome:
        m = a.message
        ended = self.ledger.ended(a, now)
        if not listened:
            pass
        elif ended == "delivered":
            ev = E.Delivered(t=self.sched.now, src=m.src, dst=m.dst, num=m.num,
                             attempts=m.attempts, pc=pc)
        else:                              # sent (unacknowledged) or fail
            ev = (E.Sent if ended == "sent" else E.Failed)(
                t=self.sched.now, src=m.src, dst=m.dst, num=m.num, reason=a.reason, pc=pc)
        if self.cfg.load == "saturate":
            self.load.refill(r)
    elif t is Message:
        self.ledger.submitted(a)
        if listened:
            ev = E.Submit(t=self.sched.now, src=a.src, dst=a.dst, num=a.num, type=a.type,
                          len=len(a.content), pc=pc)
    if ev is not None and listened:
        self._emit(ev)


def _observe_extra(self: World, st: RadioStation, k: int, a: Any) -> None:
    """An event of an ``extra`` robot: traced with ``extra`` k, counted nowhere (the
    run's statistics are the ring's)."""
    t = type(a)
    r = st.id
    now = self.sched.now
    self.observed += 1
    ev: E.TraceEvent
    if t is DuplicateId:
        ev = E.DuplicateId(t=now, robot=r, yielding=a.yielding, extra=k)
        self.identity.append(ev.record())
    elif t is ForeignRing:
        ev = E.ForeignRing(t=now, robot=r, robots=tuple(a.robots), member=a.member,
                           extra=k)
        self.identity.append(ev.record())
    elif not self.listeners:
        return
    elif t is ModeChange:
        ev = E.Mode(t=now, robot=r, mode=a.mode, reason=a.reason, extra=k)
    elif t is Deliver:
        ev = E.Delivery(t=now, src=a.src, dst=a.dst, num=a.num, type=a.type, to=r,
                        intact=self.ledger.intact(a), extra=k)
    elif t is Join:
        ev = (E.Rejoin if a.again else E.Join)(t=now, robot=a.robot, by=r, extra=k)
    elif t is Disable:
        ev = E.Disable(t=now, robot=a.robot, by=r, extra=k)
    elif t is Refused:
        ev = E.Refused(t=now, src=a.src, num=a.num, to=r, reason=a.reason, extra=k)
    elif t is NumberBehind:
        ev = E.Behind(t=now, src=a.src, num=a.num, last=a.last, to=r, refused=a.refused,
                      extra=k)
    else:
        return
    if self.listeners:
        self._emit(ev)

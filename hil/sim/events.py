"""Typed trace events: the kinds of docs/trace.md's Events table that the world writes from what
the robots' MACs report (hil/sim/world.py ``_observe``), one dataclass each, its fields the keys
of its row in the table's order.

``to_dict(t, **tags)`` gives the very dict the trace writes and the event callbacks get: ``t``
and ``ev`` first, then the fields (``mode``'s ``pc``, the standby PC's, only when set), then
the tags given (``pc`` for the father's standby PC, ``extra`` for a robot outside the ring),
so a seeded trace stays byte-identical (tests/test_trace_digests.py).

The world's other events (``meta``, ``power``, ``frame``, ``interference``, ``txen``,
``collision``, ``fault``, ``action``, ``can``, ``dispatch``, ``cpu``) are still written as
dicts where they happen; ``frame``, ``txen`` and ``can`` come with every transmission or CAN
frame of a traced run, where a dict literal is what costs least.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, ClassVar


class Event:
    """A trace event: ``ev`` names its kind, ``_keys`` are its fields in order (both set by
    :func:`event`)."""

    __slots__ = ()
    ev: ClassVar[str]
    _keys: ClassVar[tuple[str, ...]]

    def to_dict(self, t: int, **tags: Any) -> dict[str, Any]:
        d: dict[str, Any] = {"t": t, "ev": self.ev}
        for k in self._keys:
            d[k] = getattr(self, k)
        if tags:
            d.update(tags)
        return d

    def __repr__(self) -> str:
        body = ", ".join(f"{k}={getattr(self, k)!r}" for k in self._keys)
        return f"{type(self).__name__}({body})"


def event(ev: str):
    """A dataclass of kind ``ev`` (an :class:`Event`). Without the generated ``__repr__``
    and ``__eq__`` (an event is written, not compared) and without slots: each of those
    costs the import time of every ``rprs sim`` (about 0.4 ms of CPU a class for the two
    methods, 0.1 ms for the slotted copy of the class)."""
    def make(cls):
        cls = dataclass(repr=False, eq=False)(cls)
        cls.ev = ev
        cls._keys = tuple(f.name for f in fields(cls))
        return cls
    return make


@event("miss")
class Miss(Event):
    robot: int
    by: int


@event("disable")
class Disable(Event):
    robot: int
    by: int


@event("join")
class Join(Event):
    robot: int
    by: int


@event("rejoin")
class Rejoin(Event):
    robot: int
    by: int


@event("mode")
class Mode(Event):
    robot: int
    mode: str
    reason: str
    pc: int | None = None

    def to_dict(self, t: int, **tags: Any) -> dict[str, Any]:
        if self.pc is None:
            d = {"t": t, "ev": "mode", "robot": self.robot, "mode": self.mode,
                 "reason": self.reason}
        else:                                   # the table's order: pc before mode
            d = {"t": t, "ev": "mode", "robot": self.robot, "pc": self.pc, "mode": self.mode,
                 "reason": self.reason}
        if tags:
            d.update(tags)
        return d


@event("submit")
class Submit(Event):
    src: int
    dst: int
    num: int
    type: int
    len: int


@event("deliver")
class Deliver(Event):
    src: int
    dst: int
    num: int
    type: int
    to: int
    intact: bool


@event("duplicate")
class Duplicate(Event):
    src: int
    num: int
    to: int


@event("refused")
class Refused(Event):
    src: int
    num: int
    to: int
    reason: str


@event("behind")
class Behind(Event):
    src: int
    num: int
    last: int
    to: int
    refused: bool


@event("duplicate_id")
class DuplicateId(Event):
    robot: int
    yielding: bool


@event("foreign_ring")
class ForeignRing(Event):
    robot: int
    robots: list
    member: bool


@event("bad_frame")
class BadFrame(Event):
    to: int
    field: str
    reason: str


@event("bad_content")
class BadContent(Event):
    src: int
    num: int
    to: int
    reason: str


@event("delivered")
class Delivered(Event):
    src: int
    dst: int
    num: int
    attempts: int


@event("sent")
class Sent(Event):
    src: int
    dst: int
    num: int
    reason: str


@event("fail")
class Fail(Event):
    src: int
    dst: int
    num: int
    reason: str


ENDED = {"delivered": Delivered, "sent": Sent, "fail": Fail}
"""The event of each way a message ends (``Ledger.ended``)."""

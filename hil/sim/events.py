"""The trace's events, typed: one frozen dataclass a kind (docs/trace.md lists them).

The world (hil/sim/world.py) hands each event to its listeners (``World.add_listener``: the
trace writer, the waveform writer, the monitor, the demo); :meth:`TraceEvent.record` gives the
JSON line's object, keys in the order the fields are declared (``t`` and ``ev`` first), so a
seed's trace stays byte for byte what it was; :func:`from_record` reads one back, checking
every field's type, and is what ``rprs vcd``, ``rprs plot`` and the tests read files with.

Ticks are machine-clock ticks (16 MHz, docs/trace.md). A field whose metadata says ``tag`` is
left out of the record when it is None: ``pc`` (2 for the father's standby PC), ``extra`` (the
k-th ``--extra`` robot), a fault's ``spec`` and the meta's ``can_bitrate``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any, Callable, ClassVar, Iterable, Iterator, TypeVar

__all__ = ["TraceEvent", "Meta", "KINDS", "from_record", "meta_from_record", "typed",
           "TraceError", "Listener", "RecordListener", "OtherEvent"]


class TraceError(ValueError):
    """A trace, or an event of one, that cannot be read: says which event (the meta line is
    1) and why (a missing key, a value of the wrong type, ...)."""


Listener = Callable[["TraceEvent"], None]
"""What a world's listener is: called with every event, in the order they happen."""

_TAG: dict[str, Any] = {"tag": True}


def _tag() -> Any:
    """A field left out of the record when it is None (and None when a record lacks it)."""
    return field(default=None, metadata=_TAG)


# -- checks of a field read back, by the annotation's text -----------------------------------

def _is_int(v: object) -> bool:
    return type(v) is int


_CHECKS: dict[str, Callable[[object], bool]] = {
    "int": _is_int,
    "int | None": lambda v: v is None or type(v) is int,
    "bool": lambda v: type(v) is bool,
    "str": lambda v: type(v) is str,
    "str | None": lambda v: v is None or type(v) is str,
    "float": lambda v: type(v) in (int, float),
    "float | None": lambda v: v is None or type(v) in (int, float),
    "tuple[int, ...]": lambda v: type(v) is list and all(type(x) is int for x in v),
    "dict[str, int]": lambda v: type(v) is dict and all(type(x) is int for x in v.values()),
}
_WHAT = {"int": "an integer", "int | None": "an integer or null", "bool": "true or false",
         "str": "a string", "str | None": "a string or null", "float": "a number",
         "float | None": "a number or null", "tuple[int, ...]": "a list of integers",
         "dict[str, int]": "an object of integers"}


@dataclass(frozen=True, slots=True, kw_only=True)
class TraceEvent:
    """An event at tick ``t``. Subclasses set ``KIND`` (the record's ``ev``) and ``TICKS`` (the
    fields that hold ticks: moved on together when a leap writes a cycle it skipped)."""

    t: int
    KIND: ClassVar[str] = ""
    TICKS: ClassVar[tuple[str, ...]] = ("t",)
    _KEYS: ClassVar[tuple[tuple[str, bool], ...]] = ()
    _TYPES: ClassVar[tuple[tuple[str, str, bool], ...]] = ()

    def record(self) -> dict[str, Any]:
        """The JSON line's object: ``t``, ``ev``, then the fields in order, tags only when
        set; tuples as lists."""
        d: dict[str, Any] = {"t": self.t, "ev": self.KIND}
        for name, tag in self._KEYS:
            v = getattr(self, name)
            if v is None and tag:
                continue
            d[name] = list(v) if type(v) is tuple else v
        return d

    def shifted(self, by: int) -> "TraceEvent":
        """The same event ``by`` ticks later (each of its :attr:`TICKS` that is set)."""
        return replace(self, **{k: getattr(self, k) + by for k in self.TICKS
                                if getattr(self, k) is not None})


KINDS: dict[str, type[TraceEvent]] = {}
"""Each kind's class, by its record's ``ev``."""

E = TypeVar("E", bound=type)


def _kind(name: str, ticks: tuple[str, ...] = ("t",)) -> Callable[[E], E]:
    """Register an event class under ``name``, with the fields that hold ticks."""
    def register(cls: E) -> E:
        own = [f for f in fields(cls) if f.name != "t"]
        cls.KIND, cls.TICKS = name, ticks                             # type: ignore[attr-defined]
        cls._KEYS = tuple((f.name, bool(f.metadata.get("tag"))) for f in own)  # type: ignore
        cls._TYPES = tuple((f.name, str(f.type), bool(f.metadata.get("tag")))   # type: ignore
                           for f in own)
        KINDS[name] = cls
        return cls
    return register


# -- the kinds (docs/trace.md, "Events") ------------------------------------------------------

@_kind("power")
@dataclass(frozen=True, slots=True, kw_only=True)
class Power(TraceEvent):
    """The robot powered on (starts in LISTEN)."""
    robot: int
    pc: int | None = _tag()
    extra: int | None = _tag()


@_kind("frame", ("t", "start", "end"))
@dataclass(frozen=True, slots=True, kw_only=True)
class FrameOnAir(TraceEvent):
    """A robot's transmission: ``start`` (first bit of the Header) to ``end`` (last bit of
    End), ticks; the parsed fields None when its bytes do not parse."""
    src: int
    dst: int | None
    num: int | None
    type: int | None
    len: int | None
    kind: str | None
    start: int
    end: int
    bytes: int
    collided: bool
    aborted: bool
    paused: bool | None = _tag()
    continued: bool | None = _tag()
    pc: int | None = _tag()
    extra: int | None = _tag()


@_kind("interference", ("t", "start", "end"))
@dataclass(frozen=True, slots=True, kw_only=True)
class Interference(TraceEvent):
    """Bytes on air from a transmitter that is no robot, ``start`` to ``end`` (ticks)."""
    start: int
    end: int
    bytes: int
    collided: bool


@_kind("txen")
@dataclass(frozen=True, slots=True, kw_only=True)
class TxenEdge(TraceEvent):
    """The robot's TXEN pin rose (``on``) or fell."""
    robot: int
    on: bool
    pc: int | None = _tag()


@_kind("collision")
@dataclass(frozen=True, slots=True, kw_only=True)
class Collision(TraceEvent):
    """Two or more transmissions overlap from ``t``: the transmitters (-1: no robot)."""
    robots: tuple[int, ...]


@dataclass(frozen=True, slots=True, kw_only=True)
class _Membership(TraceEvent):
    robot: int
    by: int
    pc: int | None = _tag()
    extra: int | None = _tag()


@_kind("miss")
@dataclass(frozen=True, slots=True, kw_only=True)
class Miss(_Membership):
    """Observer ``by`` did not hear ``robot``'s Header by its deadline (E + Tmax)."""


@_kind("disable")
@dataclass(frozen=True, slots=True, kw_only=True)
class Disable(_Membership):
    """``by`` dropped ``robot`` after three consecutive misses."""


@_kind("join")
@dataclass(frozen=True, slots=True, kw_only=True)
class Join(_Membership):
    """``by`` admitted ``robot`` to its ring, the first time."""


@_kind("rejoin")
@dataclass(frozen=True, slots=True, kw_only=True)
class Rejoin(_Membership):
    """``by`` admitted ``robot`` again after a drop."""


@_kind("mode")
@dataclass(frozen=True, slots=True, kw_only=True)
class Mode(TraceEvent):
    """The robot went to ``listen`` or became a ``member``, and why."""
    robot: int
    pc: int | None = _tag()
    mode: str
    reason: str
    extra: int | None = _tag()


@_kind("submit")
@dataclass(frozen=True, slots=True, kw_only=True)
class Submit(TraceEvent):
    """A message was queued at ``src``: Number ``num``, ``len`` Content bytes."""
    src: int
    dst: int
    num: int
    type: int
    len: int
    pc: int | None = _tag()


@_kind("deliver")
@dataclass(frozen=True, slots=True, kw_only=True)
class Delivery(TraceEvent):
    """Robot ``to`` accepted the message (once); ``intact``: ground truth."""
    src: int
    dst: int
    num: int
    type: int
    to: int
    intact: bool
    pc: int | None = _tag()
    extra: int | None = _tag()


@_kind("duplicate")
@dataclass(frozen=True, slots=True, kw_only=True)
class Duplicate(TraceEvent):
    """A retransmission ``to`` had already delivered: acknowledged again only."""
    src: int
    num: int
    to: int
    pc: int | None = _tag()


@_kind("refused")
@dataclass(frozen=True, slots=True, kw_only=True)
class Refused(TraceEvent):
    """Robot ``to`` refused a well-formed frame, for ``reason``."""
    src: int
    num: int
    to: int
    reason: str
    pc: int | None = _tag()
    extra: int | None = _tag()


@_kind("behind")
@dataclass(frozen=True, slots=True, kw_only=True)
class Behind(TraceEvent):
    """A message frame whose Number ``num`` is 1-8 behind ``last`` (clause 48a)."""
    src: int
    num: int
    last: int
    to: int
    refused: bool
    pc: int | None = _tag()
    extra: int | None = _tag()


@_kind("duplicate_id")
@dataclass(frozen=True, slots=True, kw_only=True)
class DuplicateId(TraceEvent):
    """``robot`` heard its own ID from another robot (clause 38.2)."""
    robot: int
    yielding: bool
    pc: int | None = _tag()
    extra: int | None = _tag()


@_kind("foreign_ring")
@dataclass(frozen=True, slots=True, kw_only=True)
class ForeignRing(TraceEvent):
    """``robot`` hears good frames from ``robots`` outside its team (clause 38.1)."""
    robot: int
    robots: tuple[int, ...]
    member: bool
    pc: int | None = _tag()
    extra: int | None = _tag()


@_kind("bad_frame")
@dataclass(frozen=True, slots=True, kw_only=True)
class BadFrame(TraceEvent):
    """Robot ``to`` received bytes that are no frame: ``field`` holds the first bad byte."""
    to: int
    field: str
    reason: str
    pc: int | None = _tag()


@_kind("bad_content")
@dataclass(frozen=True, slots=True, kw_only=True)
class BadContent(TraceEvent):
    """A frame whose Content does not parse: nothing delivered."""
    src: int
    num: int
    to: int
    reason: str
    pc: int | None = _tag()


@_kind("delivered")
@dataclass(frozen=True, slots=True, kw_only=True)
class Delivered(TraceEvent):
    """The sender got every acknowledgement, after ``attempts`` sendings."""
    src: int
    dst: int
    num: int
    attempts: int
    pc: int | None = _tag()


@dataclass(frozen=True, slots=True, kw_only=True)
class _Ended(TraceEvent):
    src: int
    dst: int
    num: int
    reason: str
    pc: int | None = _tag()


@_kind("sent")
@dataclass(frozen=True, slots=True, kw_only=True)
class Sent(_Ended):
    """``--profile paper``: sent once, ends unacknowledged (docs/protocol.md §9.1)."""


@_kind("fail")
@dataclass(frozen=True, slots=True, kw_only=True)
class Failed(_Ended):
    """The message ended failed, with the reason."""


@_kind("fault")
@dataclass(frozen=True, slots=True, kw_only=True)
class FaultEdge(TraceEvent):
    """An injected fault ``start``s or its window ``end``s (``phase``); ``robot`` None for the
    air's; ``spec`` as written, at the start of a kind with one."""
    robot: int | None
    kind: str
    phase: str
    spec: str | None = _tag()


@_kind("action")
@dataclass(frozen=True, slots=True, kw_only=True)
class Action(TraceEvent):
    """A child's action (paper Fig. 11) ``start``s or is ``done``."""
    robot: int
    phase: str
    name: str


@_kind("can", ("t", "start", "end"))
@dataclass(frozen=True, slots=True, kw_only=True)
class CanFrameOnBus(TraceEvent):
    """A CAN frame on child ``bus``'s bus: hex ``data``, ticks of SOF and end of EOF."""
    bus: int
    id: int
    data: str
    start: int
    end: int


@_kind("dispatch", ("t", "end", "sof"))
@dataclass(frozen=True, slots=True, kw_only=True)
class Dispatch(TraceEvent):
    """An order's first CAN command frame: ``sof`` - ``end`` = ``latency`` ticks."""
    robot: int
    end: int
    sof: int
    latency: int


@_kind("cpu")
@dataclass(frozen=True, slots=True, kw_only=True)
class CpuLoad(TraceEvent):
    """The share of child ``robot``'s machine cycles its firmware took in the last second."""
    robot: int
    load: float


@dataclass(frozen=True, slots=True, kw_only=True)
class Meta(TraceEvent):
    """The trace's first line: the run's settings (docs/trace.md, "First line"); it has no
    tick (``t`` 0, not written)."""
    KIND: ClassVar[str] = "meta"
    t: int = 0
    version: int
    tick_hz: int
    byte_ticks: dict[str, int] | None = None
    ttrans: int
    tmax: int
    twin: int | None = None
    tslot: int | None = None
    miss_limit: int | None = None
    robots: tuple[int, ...]
    seed: int | None = None
    mac: str | None = None
    ber: float | None = None
    noise: bool | None = None
    load: Any = None
    duration_ticks: int | None = None
    can_bitrate: int | None = _tag()

    def record(self) -> dict[str, Any]:
        d: dict[str, Any] = {"ev": "meta"}
        for f in fields(self)[1:]:
            v = getattr(self, f.name)
            if v is None and f.metadata.get("tag"):
                continue
            d[f.name] = list(v) if type(v) is tuple else v
        return d


def meta_from_record(d: Any) -> Meta:
    """The meta line read back: ``robots`` a non-empty list of IDs 0-6, ``tick_hz``, ``tmax``
    and ``ttrans`` positive integers (what the tools need); TraceError if not."""
    if not isinstance(d, dict) or d.get("ev") != "meta":
        raise TraceError("the first event must be the meta event")
    robots = d.get("robots")
    if (not isinstance(robots, list) or not robots
            or not all(type(r) is int and 0 <= r <= 6 for r in robots)):
        raise TraceError(f"meta: robots is {robots!r}, not a list of IDs 0-6")
    for k in ("tick_hz", "tmax", "ttrans"):
        if k not in d:
            raise TraceError(f"event 1 (meta): missing '{k}'")
        if type(d[k]) is not int:
            raise TraceError(f"event 1 (meta): '{k}' is {d[k]!r}, not an integer")
        if d[k] <= 0:
            raise TraceError(f"meta: {k} must be positive, got {d[k]}")
    known = {f.name for f in fields(Meta)}
    kw = {k: v for k, v in d.items() if k in known}
    kw["robots"] = tuple(robots)
    kw.setdefault("version", 1)
    return Meta(**kw)


@dataclass(frozen=True, slots=True)
class OtherEvent:
    """A record of a kind this version does not know (a newer trace's): kept, not read."""
    t: int
    kind: str
    fields: dict[str, Any]


def from_record(d: Any, n: int = 0) -> TraceEvent | OtherEvent:
    """The event a JSON line's object holds (not the meta line: :func:`meta_from_record`).
    ``n``: its number in the trace, for the error. TraceError names the event and the
    key that is missing or of the wrong type."""
    if not isinstance(d, dict) or "ev" not in d:
        raise TraceError(f"event {n}: not a trace event (no 'ev')")
    kind = d["ev"]
    t = d.get("t")
    if type(t) is not int:
        raise TraceError(f"event {n} ({kind}): "
                              + ("missing 't'" if "t" not in d else f"'t' is {t!r}, not an "
                                 "integer"))
    cls = KINDS.get(kind)
    if kind == "meta":
        raise TraceError(f"event {n}: a second meta event")
    if cls is None:
        return OtherEvent(t, str(kind), {k: v for k, v in d.items() if k not in ("t", "ev")})
    kw: dict[str, Any] = {"t": t}
    for name, typ, tag in cls._TYPES:
        if name not in d:
            if tag:
                continue
            raise TraceError(f"event {n} ({kind}): missing '{name}'")
        v = d[name]
        check = _CHECKS.get(typ)
        if check is not None and not check(v):
            raise TraceError(f"event {n} ({kind}): '{name}' is {v!r}, not "
                                  f"{_WHAT[typ]}")
        kw[name] = tuple(v) if type(v) is list else v
    return cls(**kw)


class RecordListener:
    """A listener that hands each event on as its record (the JSON line's object): for
    callers that keep or compare records (``World(on_event=...)``). Picklable when ``fn`` is
    (a list's ``append``), as a world copied for a search must be."""

    __slots__ = ("fn",)

    def __init__(self, fn: Callable[[dict[str, Any]], None]) -> None:
        self.fn = fn

    def __call__(self, ev: TraceEvent) -> None:
        self.fn(ev.record())


def typed(items: Iterable[Any]) -> Iterator[TraceEvent | OtherEvent]:
    """Events from records or events: the meta first (TraceError if not), each record read
    by :func:`from_record` with its number in the trace; an event passes as it is."""
    n = 0
    for n, item in enumerate(items, 1):
        if n == 1:
            yield item if isinstance(item, Meta) else meta_from_record(item)
        elif isinstance(item, (TraceEvent, OtherEvent)):
            if isinstance(item, Meta):
                raise TraceError(f"event {n}: a second meta event")
            yield item
        else:
            yield from_record(item, n)
    if n == 0:
        raise TraceError("empty trace: no meta line")

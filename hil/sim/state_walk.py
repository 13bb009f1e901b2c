"""The state of a part of the simulation as a flat list of leaves, read in one fixed order.

Used to see that a part is periodic and to move it on by whole periods (hil/sim/quiet_can.py):
two snapshots one period apart that differ only by ticks moved on by exactly the period and by
counters mean the part will go on repeating itself, and :func:`advance` moves those ticks and
counters on by any number of periods.

What a snapshot holds: everything reachable from the roots through instance attributes
(``__dict__`` and ``__slots__``), lists, dicts and tuples, for objects of this project's
classes (``can_bus``, ``firmware_model``, ``hil``). Other things are values: numbers,
strings, bytes, enums, sets and frozen dataclasses (a CAN frame) by ``==``, a bytearray (a
deframer's buffer) by its bytes; functions, bound
methods and objects of other libraries by identity (a function is the same function; a foreign
object's inside is not looked at, so a part whose state hides in one, a random generator, is
refused by :func:`snapshot`). A ``boundary`` object (the world's scheduler, the radio station
a child talks to) is compared by identity and not entered. An object reached twice is a
reference to its first visit, so sharing is part of the shape; a tuple is walked wherever it
is reached, and a frozen dataclass taken as a value wherever it is reached (neither can
change, so only their values matter, not whether a memo handed out one object or two equal
ones), and an int inside a tuple is written
by replacing the tuple in its holder (:class:`InTuple`): a tick in ``(robot, end)`` or in an
event's arguments moves on like any other.

A class may name slots that are no state of its own in ``NOT_STATE``: the scheduler's
bookkeeping (a sequence number it holds for events to come, hil/sim/reception.py), which two
runs of one world number differently and a period does not move on; they are not walked.

An object of a ``latest`` type holds the latest of something the part rewrites every period
before it reads it (a record of a submodule's last status frame): its fields are *free*
positions. Two snapshots whose free values differ are still periodic, but the period's own
run is then needed to know them (:func:`latest_moved`): the sleeping part runs its last
period frame by frame when it wakes (hil/sim/quiet_can.py).
"""
from __future__ import annotations

import bisect
import dataclasses
import operator
import random
import types
from enum import Enum
from types import MethodType
from typing import Any, Iterable

__all__ = ["InTuple", "Snapshot", "Unwalkable", "snapshot", "period_delta", "period_steps",
           "on_orbit", "latest_moved", "writable", "advance", "portable"]

_OURS = ("can_bus", "firmware_model", "hil")
_VALUE_TYPES = (bool, float, str, bytes, type(None), Enum, frozenset, set)
_FN_TYPES = (types.FunctionType, types.BuiltinFunctionType, types.MethodType,
             types.BuiltinMethodType)


class Unwalkable(Exception):
    """The part holds state a snapshot cannot see (a random generator, an iterator)."""


@dataclasses.dataclass
class Snapshot:
    """``shape``: every position's kind and value (ints included), in walk order;
    ``int_pos``: the positions of the ints in ``shape``, ascending; ``int_spots``: for each of
    them, three entries in a row, the (holder, key, name) of that int (holder an
    :class:`InTuple` inside a tuple; None inside a tuple that is a root: it cannot be written;
    :meth:`spot`, :attr:`ints`); ``alive``: every object whose identity the shape records,
    kept alive with the snapshot so that no other object can take its id while the snapshot
    may still be compared; ``free``: the positions inside objects of a ``latest`` type
    (module docstring).

    A snapshot makes no container object of its own per int and shares its markers (the
    ``("obj", type)``, ``("ref", position)`` ... tuples) with earlier snapshots: a probe keeps
    one or two snapshots for a period or a whole sleep, and a thousand tuples each were the
    most of what Python's cyclic garbage collector found to walk in a soak
    (docs/fast-paths.md, "The collector")."""

    shape: list
    int_pos: list[int]
    int_spots: list
    alive: list = dataclasses.field(default_factory=list, repr=False)
    free: frozenset[int] = frozenset()

    def spot(self, pos: int) -> tuple[Any, Any, str] | None:
        """(holder, key, name) of the int at ``pos`` in ``shape``, or None if no int is there."""
        ip = self.int_pos
        j = bisect.bisect_left(ip, pos)
        if j == len(ip) or ip[j] != pos:
            return None
        sp = self.int_spots
        return sp[3 * j], sp[3 * j + 1], sp[3 * j + 2]

    @property
    def ints(self) -> dict[int, tuple[Any, Any, str]]:
        """Position in ``shape`` -> (holder, key, name) of every int, in walk order."""
        sp = self.int_spots
        return {pos: (sp[3 * j], sp[3 * j + 1], sp[3 * j + 2])
                for j, pos in enumerate(self.int_pos)}


class InTuple:
    """The holder of an int inside a tuple: the tuple is ``holder[key]`` (or the attribute
    ``key`` of ``holder``), itself perhaps an :class:`InTuple`'s tuple. Writing the int
    replaces the whole tuple there."""

    __slots__ = ("holder", "key")

    def __init__(self, holder: Any, key: Any) -> None:
        self.holder = holder
        self.key = key


def _read(holder: Any, key: Any) -> Any:
    if type(holder) is InTuple:
        return _read(holder.holder, holder.key)[key]
    if isinstance(holder, (list, dict)):
        return holder[key]
    return getattr(holder, key)


def _write(holder: Any, key: Any, value: Any) -> None:
    if type(holder) is InTuple:
        t = _read(holder.holder, holder.key)
        _write(holder.holder, holder.key, t[:key] + (value,) + t[key + 1:])
    elif isinstance(holder, (list, dict)):
        holder[key] = value
    else:
        setattr(holder, key, value)


def _all_slots(cls: type) -> tuple[str, ...]:
    names: list[str] = []
    for c in reversed(cls.__mro__):
        s = c.__dict__.get("__slots__", ())
        names.extend((s,) if isinstance(s, str) else s)
    return tuple(n for n in names if n not in ("__dict__", "__weakref__"))


_INT, _VALUE, _FN, _TUPLE, _LIST, _DICT, _RNG, _ITER, _OBJ, _FOREIGN, _BYTES = (
    "int", "value", "fn", "tuple", "list", "dict", "rng", "iterator", "object", "foreign",
    "bytearray")
_ABSENT = object()
_NO_RECORDS: frozenset[str] = frozenset()
_KINDS: dict[type, str] = {int: _INT, float: _VALUE, str: _VALUE, bool: _VALUE, bytes: _VALUE,
                           type(None): _VALUE}
"""How :func:`snapshot` takes a value of each type (decided once per type, :func:`_kind`)."""
_FIELDS: dict[type, tuple[tuple, bool, tuple[str, ...], Any]] = {}
"""How :func:`snapshot` reads the fields of an object of each of this project's types
(:func:`_fields_plan`, decided once per type)."""
_MARKS: dict[tuple, tuple] = {}
"""Every marker tuple a snapshot has held, each by itself: snapshots share them rather than
keep equal copies (:class:`Snapshot`). Emptied when it reaches :data:`_MARKS_MAX`."""
_MARKS_MAX = 65_536


def _fields_plan(t: type) -> tuple[tuple, bool, tuple[str, ...], Any]:
    """(its marker ``("obj", t)``, may have a ``__dict__``, slot names in walk order, a getter
    of all slots at once or None). An object of a type that has slots only has no
    ``__dict__``: asking for it would cost an AttributeError per object."""
    plain = t.__getattribute__ is object.__getattribute__ and not hasattr(t, "__getattr__")
    has_dict = not plain or any("__dict__" in vars(c) for c in t.__mro__)
    skip = getattr(t, "NOT_STATE", ())
    slots = tuple(n for n in _all_slots(t) if n not in skip)
    getter = operator.attrgetter(*slots) if len(slots) > 1 else None
    return ("obj", t), has_dict, slots, getter


def _kind(t: type) -> str:
    if t is int:
        k = _INT
    elif issubclass(t, _VALUE_TYPES):
        k = _VALUE
    elif issubclass(t, _FN_TYPES):
        k = _FN
    elif t is tuple:
        k = _TUPLE
    elif issubclass(t, bytearray):
        k = _BYTES
    elif issubclass(t, list):
        k = _LIST
    elif issubclass(t, dict):
        k = _DICT
    elif dataclasses.is_dataclass(t) and (
            t.__dataclass_params__.frozen):  # type: ignore[attr-defined]  # not in typeshed
        k = _VALUE                # a frozen dataclass is a value: equal ones are the same
    elif issubclass(t, random.Random):
        k = _RNG
    elif hasattr(t, "__next__"):
        k = _ITER
    elif t.__module__.split(".")[0] in _OURS:
        k = _OBJ
        _FIELDS[t] = _fields_plan(t)
    else:
        k = _FOREIGN
    _KINDS[t] = k
    return k


def snapshot(roots: Iterable[Any], boundary: Iterable[Any] = (),
             rng_state: bool = False, records: frozenset[str] = frozenset(),
             latest: tuple[type, ...] = ()) -> Snapshot:
    """Walk ``roots`` (module docstring). ``rng_state``: a random generator is its state
    (to compare two runs) instead of a reason to refuse. ``records``: attributes that are
    append-only lists nothing in the model reads (a log): only their length is taken, so a
    long run's log does not make every snapshot longer (a part whose log grew is still not
    periodic). ``latest``: the types whose fields are free positions (module docstring)."""
    shape: list = []
    int_pos: list[int] = []
    spots: list = []
    seen: dict[int, int] = {}
    stop = {id(b) for b in boundary}
    keep: list[Any] = []            # objects whose ids the shape holds (Snapshot.alive)
    free: list[range] = []
    append = shape.append
    hold = keep.append
    at_int = int_pos.append
    spot = spots.append
    kinds = _KINDS
    plans = _FIELDS
    marks = _MARKS
    if len(marks) >= _MARKS_MAX:
        marks.clear()
    mark = marks.setdefault       # mark(m, m): the one marker equal to m

    # A snapshot costs about a period's frames, so the walk is written for speed: the kind
    # of every type and the fields of every class are decided once (_kind, _fields_plan),
    # and one loop takes every value; only a container seen for the first time costs a call.
    def items(pairs: Iterable[tuple[Any, Any]], holder: Any, name: str, by_key: bool,
              recs: frozenset[str]) -> None:
        """The values of ``pairs``, each ``holder[key]`` (or the attribute ``key``)."""
        for k, v in pairs:
            t = type(v)
            try:
                kind = kinds[t]
            except KeyError:
                kind = _kind(t)
            if kind is _INT:
                at_int(len(shape))
                spot(holder)
                spot(k)
                spot(k if by_key and isinstance(k, str) else name)
                append(v)
            elif kind is _VALUE:
                append(v)
            elif kind is _FN:
                if t is MethodType:
                    self_ = v.__self__
                    fn = v.__func__
                else:
                    self_ = getattr(v, "__self__", None)
                    fn = getattr(v, "__func__", v)
                hold(fn)
                hold(self_)
                m: tuple[Any, ...] = ("fn", id(fn), id(self_),
                                      getattr(v, "__qualname__", t.__name__))
                append(mark(m, m))
            elif kind is _TUPLE:        # walked wherever reached (module docstring)
                m = ("tuple", len(v))
                append(mark(m, m))
                if v:
                    items(enumerate(v), None if holder is None else InTuple(holder, k),
                          k if by_key and isinstance(k, str) else name, False, _NO_RECORDS)
            elif recs and t is list and k in recs:
                m = ("record", len(v))
                append(mark(m, m))
            else:
                i = id(v)
                if i in stop:
                    m = ("boundary", i, None, t.__name__)
                    append(mark(m, m))
                    continue
                first = seen.get(i)
                if first is not None:
                    m = ("ref", first)
                    append(mark(m, m))
                    continue
                seen[i] = len(shape)
                hold(v)
                n = k if by_key and isinstance(k, str) else name
                if kind is _OBJ:
                    fields(v, t)
                elif kind is _LIST:
                    m = ("list", len(v))
                    append(mark(m, m))
                    if v:
                        items(enumerate(v), v, n, False, _NO_RECORDS)
                elif kind is _DICT:
                    append(("dict", tuple(v)))
                    if v:
                        items(v.items(), v, n, True, _NO_RECORDS)
                else:
                    other(v, t, kind, i, n)

    def fields(x: Any, t: type) -> None:
        """An object of this project's type ``t``: its attributes, then its slots."""
        obj, has_dict, slots, getter = plans[t]
        append(obj)
        start = len(shape)
        if has_dict:
            d = getattr(x, "__dict__", None)
            if d is not None:
                items(d.items(), x, "", True, records)
        if slots:
            pairs: Iterable[tuple[str, Any]]
            if getter is not None:
                try:
                    pairs = zip(slots, getter(x))
                except AttributeError:          # a slot not set
                    getter = None
            if getter is None:
                pairs = [(k, v) for k in slots if (v := getattr(x, k, _ABSENT)) is not _ABSENT]
            items(pairs, x, "", True, _NO_RECORDS)
        if t in latest:
            free.append(range(start, len(shape)))

    def other(x: Any, t: type, kind: str, i: int, name: str) -> None:
        """A value of none of the common kinds (``i``: its id)."""
        if kind is _BYTES:
            append(("bytearray", bytes(x)))
        elif kind is _RNG and rng_state:
            append(("rng", x.getstate()))
        elif kind is _RNG or kind is _ITER or hasattr(x, "__next__"):
            raise Unwalkable(f"{name}: a {t.__name__} keeps state a snapshot cannot see")
        else:
            m = ("id", i, None, t.__name__)
            append(mark(m, m))

    try:
        items([(None, root) for root in roots], None, "root", False, _NO_RECORDS)
    finally:
        # items and fields call each other through their closures' cells: a reference
        # cycle that would hold the whole walk (shape, ints, the objects kept alive) until
        # the cyclic garbage collector ran. Emptying the cells frees it all by reference
        # counting when the snapshot is dropped.
        items = fields = other = None  # type: ignore[assignment]
    return Snapshot(shape, int_pos, spots, keep, frozenset(p for r in free for p in r))


def period_delta(before: Snapshot, after: Snapshot, period: int,
                 counters: frozenset[str]) -> list[tuple[Any, Any, int]] | None:
    """How one period moved the part on, or None if it is not periodic: (holder, key, delta)
    of every int of ``after`` that moved, each either a tick moved by exactly ``period`` or a
    counter (an attribute or key named in ``counters``) moved by any amount. Everything else
    must be equal, but for free positions (module docstring), which may hold anything."""
    steps = period_steps(before, after, period, counters)
    return None if steps is None else writable(after, steps)


def period_steps(before: Snapshot, after: Snapshot, period: int,
                 counters: frozenset[str],
                 modular: dict[str, int] | None = None) -> dict[int, int] | None:
    """:func:`period_delta` by position in the shape: {position: delta}. A free position
    that moved as a tick or a counter does is a step; one that changed otherwise is allowed
    and is not (:func:`latest_moved` tells whether there is one). ``modular``: counters the
    model reads only modulo a number (``turns % 7``), by name: one is a step if it moved up by
    a multiple of its number."""
    a, b = before.shape, after.shape
    if len(a) != len(b) or before.free != after.free:
        return None
    free = after.free
    int_at = after.spot
    steps: dict[int, int] = {}
    for pos, (x, y) in enumerate(zip(a, b)):
        if x == y and type(x) is type(y):
            continue
        spot = int_at(pos) if type(y) is int else None
        if spot is None or type(x) is not int or type(y) is not int:
            if pos in free:
                continue
            return None
        holder, _, name = spot
        d = y - x
        if holder is None or not (d == period or (name in counters and d > 0) or (
                modular is not None and name in modular and d > 0 and d % modular[name] == 0)):
            if pos in free:
                continue
            return None
        steps[pos] = d
    return steps


def on_orbit(orbit: Snapshot, steps: dict[int, int], periods: int, now: Snapshot,
             counters: frozenset[str]) -> bool:
    """Is ``now`` the state of a periodic part ``periods`` whole periods after ``orbit``, as far
    as its future goes? ``steps``: how one period moves it (:func:`period_steps` of two
    snapshots a period apart, the second being ``orbit``). Every tick that a period moves on
    must have moved by exactly ``periods`` of its steps; a counter (named in ``counters``) may
    have moved by any amount, up, and a record (an append-only log nothing reads) may have any
    length, as neither is read by the model; a free position may hold anything (the period's
    own run rewrites it before anything reads it: :func:`latest_moved`); everything else must be
    equal. Then the part goes on exactly as the orbit would: it may sleep again at once, moved
    on by ``steps``."""
    a, b = orbit.shape, now.shape
    if len(a) != len(b) or periods < 1 or orbit.free != now.free:
        return False
    free = now.free
    int_at = now.spot

    def counter(pos: int) -> bool:
        spot = int_at(pos)
        return spot is not None and spot[0] is not None and spot[2] in counters

    for pos, (x, y) in enumerate(zip(a, b)):
        if pos in free:
            continue
        d = steps.get(pos)
        if d is not None and not counter(pos):
            if type(y) is not int or y - x != d * periods:
                return False
            continue
        if x == y and type(x) is type(y):
            continue
        if type(x) is int and type(y) is int and y > x and counter(pos):
            continue
        if type(x) is tuple and type(y) is tuple and len(x) == len(y) == 2 \
                and x[0] == y[0] == "record":
            continue
        return False
    return True


def latest_moved(before: Snapshot, after: Snapshot, steps: dict[int, int],
                 periods: int = 1) -> bool:
    """Did a free position of ``after`` (``periods`` periods after ``before``, which
    :func:`period_steps` or :func:`on_orbit` accepted) change other than by ``periods`` of its
    step? Then moving ``before`` on by ``steps`` does not give those values: the part must run
    its last period frame by frame to have them."""
    a, b = before.shape, after.shape
    for pos in after.free:
        x, y = a[pos], b[pos]
        d = steps.get(pos)
        if d is not None:
            if type(y) is not int or y - x != d * periods:   # a free value may be anything
                return True
        elif x != y or type(x) is not type(y):
            return True
    return False


def writable(snap: Snapshot, steps: dict[int, int]) -> list[tuple[Any, Any, int]]:
    """(holder, key, delta) of every position in ``steps``, in ``snap``'s objects."""
    out = []
    for pos, d in sorted(steps.items()):
        spot = snap.spot(pos)
        assert spot is not None           # (steps are ints' positions)
        holder, key, _ = spot
        out.append((holder, key, d))
    return out


def advance(moved: list[tuple[Any, Any, int]], periods: int) -> None:
    """Move the part on by ``periods`` more periods (``moved`` from :func:`period_delta`)."""
    if periods <= 0:
        return
    for holder, key, d in moved:
        if isinstance(holder, (list, dict)):
            holder[key] += d * periods
        elif type(holder) is InTuple:
            _write(holder, key, _read(holder, key) + d * periods)
        else:
            setattr(holder, key, getattr(holder, key) + d * periods)


_ID_MIN = 1 << 46
"""An int in a set at least this large is taken for an object's identity (CPython's ids are
addresses, about 2^47; a tick count reaches it after 51 simulated days)."""


def portable(snap: Snapshot) -> list:
    """``snap.shape`` without object identities (a function by its name, a foreign or
    boundary object by its type, a dict by its size, a set's objects and ids by their
    kind): two worlds built alike compare equal with it."""
    out = []
    for x in snap.shape:
        t = type(x)
        if t is tuple and x and x[0] in ("fn", "boundary", "id"):
            out.append(x[:1] + ((x[3],) if len(x) > 3 else ()))
        elif t is tuple and x and x[0] == "dict":
            out.append(("dict", len(x[1])))        # keys may be ids (a bus's nodes)
        elif t is set or t is frozenset:
            # members may be objects (a twin's radio) or ids (a CAN bus's deaf nodes)
            out.append(("set", sorted(map(_portable_member, x))))
        else:
            out.append(x)
    return out


def _portable_member(v: Any) -> str:
    """A set's member as :func:`portable` compares it."""
    if type(v) is int:
        return "id" if v >= _ID_MIN else repr(v)
    if isinstance(v, (bool, float, str, bytes, Enum, type(None))):
        return repr(v)
    return f"<{type(v).__name__}>"

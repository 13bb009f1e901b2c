"""The state walker's snapshot (hil/sim/state_walk.py, written for speed) against a plain
reference walker: the plain walk, one call per value.

Every field must be the same: the shape entry by entry (type and value), the ints' (holder,
key, name) (an InTuple by the chain of holders it stands for, and shared where the reference
shares it), the free positions, and the objects kept alive, in order. The worlds: CAN sides
idle, with orders and load, with CAN faults, a soak's random faults, the ring's leaps; every
snapshot the simulator takes in them is compared, and the whole world's state at cuts.
"""
from __future__ import annotations

import dataclasses
import enum
import functools
import random
import types
from enum import Enum
from typing import Any, Iterable

import pytest

import hil.sim.quiet_can as quiet_can
import hil.sim.quiet_ring as quiet_ring
from hil.sim.faults import parse_fault
from hil.sim.soak import random_faults
from hil.sim.state_walk import InTuple, Snapshot, Unwalkable, snapshot
from hil.sim.world import SimConfig, World

# -- the reference: the plain walk, one call of visit per value -------------------------------

_OURS = ("can_bus", "firmware_model", "hil")
_VALUE_TYPES = (bool, float, str, bytes, type(None), Enum, frozenset, set)
_FN_TYPES = (types.FunctionType, types.BuiltinFunctionType, types.MethodType,
             types.BuiltinMethodType)


_SLOTS: dict[type, list[str]] = {}


def _slot_names(cls: type) -> list[str]:
    names = _SLOTS.get(cls)
    if names is None:
        names = _SLOTS[cls] = _all_slots(cls)
    return names


def _all_slots(cls: type) -> list[str]:
    names: list[str] = []
    for c in reversed(cls.__mro__):
        s = c.__dict__.get("__slots__", ())
        names.extend((s,) if isinstance(s, str) else s)
    skip = getattr(cls, "NOT_STATE", ())        # the scheduler's bookkeeping, not state
    return [n for n in names if n not in ("__dict__", "__weakref__") and n not in skip]


_INT, _VALUE, _FN, _TUPLE, _LIST, _DICT, _FROZEN, _RNG, _ITER, _OBJ, _FOREIGN, _BYTES = (
    "int", "value", "fn", "tuple", "list", "dict", "frozen", "rng", "iterator", "object",
    "foreign", "bytearray")
_PLAIN = frozenset({float, str, bool, bytes, type(None)})
"""Value types taken as they are without asking :func:`_kind` (the commonest leaves)."""
_ABSENT = object()
_KINDS: dict[type, str] = {}
"""How :func:`snapshot` takes a value of each type (decided once per type)."""


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
    elif dataclasses.is_dataclass(t) and t.__dataclass_params__.frozen:
        k = _FROZEN
    elif issubclass(t, random.Random):
        k = _RNG
    elif hasattr(t, "__next__"):
        k = _ITER
    elif t.__module__.split(".")[0] in _OURS:
        k = _OBJ
    else:
        k = _FOREIGN
    _KINDS[t] = k
    return k


def reference_snapshot(roots: Iterable[Any], boundary: Iterable[Any] = (),
             rng_state: bool = False, records: frozenset[str] = frozenset(),
             latest: tuple[type, ...] = ()) -> Snapshot:
    """Walk ``roots`` (module docstring). ``rng_state``: a random generator is its state
    (to compare two runs) instead of a reason to refuse. ``records``: attributes that are
    append-only lists nothing in the model reads (a log): only their length is taken, so a
    long run's log does not make every snapshot longer (a part whose log grew is still not
    periodic). ``latest``: the types whose fields are free positions (module docstring)."""
    shape: list = []
    ints: dict[int, tuple[Any, Any, str]] = {}
    seen: dict[int, int] = {}
    stop = {id(b) for b in boundary}
    keep: list[Any] = []            # objects whose ids the shape holds (Snapshot.alive)
    free: list[range] = []

    append = shape.append

    # Ints and plain values, most of the leaves, are taken in the loop below without a call
    # of visit (the same entries visit would make: a snapshot costs about a period's frames).
    def items_of(pairs: Iterable[tuple[Any, Any]], holder: Any, name: str, by_key: bool,
                 recs: frozenset[str] = frozenset()) -> None:
        for k, v in pairs:
            tv = type(v)
            n = k if by_key and isinstance(k, str) else name
            if tv is int:
                ints[len(shape)] = (holder, k, n)
                append(v)
            elif tv in _PLAIN:
                append(v)
            elif tv is list and k in recs:
                append(("record", len(v)))
            else:
                visit(v, holder, k, n)

    def fields_of(x: Any, t: type) -> None:
        d = getattr(x, "__dict__", None)
        if d is not None:
            items_of(d.items(), x, "", True, records)
        slots = _slot_names(t)
        if slots:
            items_of([(k, v) for k in slots if (v := getattr(x, k, _ABSENT)) is not _ABSENT],
                     x, "", True)

    def visit(x: Any, holder: Any, key: Any, name: str) -> None:
        t = type(x)
        kind = _KINDS.get(t)
        if kind is None:
            kind = _kind(t)
        if kind is _INT:
            ints[len(shape)] = (holder, key, name)
            shape.append(x)
            return
        if kind is _VALUE:
            shape.append(x)
            return
        if kind is _FN:
            self_ = getattr(x, "__self__", None)
            fn = getattr(x, "__func__", x)
            keep.append(fn)
            keep.append(self_)
            shape.append(("fn", id(fn), id(self_),
                          getattr(x, "__qualname__", t.__name__)))
            return
        if kind is _FROZEN:           # a value: equal ones are the same, shared or not
            shape.append(x)
            return
        if kind is _TUPLE:            # walked wherever reached (module docstring)
            shape.append(("tuple", len(x)))
            items_of(enumerate(x), None if holder is None else InTuple(holder, key), name,
                     False)
            return
        i = id(x)
        if i in stop:
            shape.append(("boundary", i, None, t.__name__))
            return
        if i in seen:
            shape.append(("ref", seen[i]))
            return
        seen[i] = len(shape)
        keep.append(x)
        if kind is _OBJ:
            shape.append(("obj", t))
            if t in latest:
                start = len(shape)
                fields_of(x, t)
                free.append(range(start, len(shape)))
                return
            fields_of(x, t)
        elif kind is _LIST:
            shape.append(("list", len(x)))
            items_of(enumerate(x), x, name, False)
        elif kind is _DICT:
            shape.append(("dict", tuple(x)))
            items_of(x.items(), x, name, True)
        elif kind is _BYTES:
            shape.append(("bytearray", bytes(x)))
        elif kind is _RNG and rng_state:
            shape.append(("rng", x.getstate()))
        elif kind is _RNG or kind is _ITER or hasattr(x, "__next__"):
            raise Unwalkable(f"{name}: a {t.__name__} keeps state a snapshot cannot see")
        else:
            shape.append(("id", i, None, t.__name__))

    for root in roots:
        visit(root, None, None, "root")
    spots = [part for spot in ints.values() for part in spot]
    return Snapshot(shape, list(ints), spots, keep, frozenset(p for r in free for p in r))


# -- the comparison --------------------------------------------------------------------------

def _equal(x: Any, y: Any) -> bool:
    """The same entry: the same object, or of the same type and equal (tuples item by item,
    so that 1 and True, 1 and 1.0 differ)."""
    if x is y:
        return True
    if type(x) is not type(y):
        return False
    if type(x) is tuple:
        return len(x) == len(y) and all(map(_equal, x, y))
    return x == y


def _holder(h: Any) -> Any:
    """What a holder stands for: an object by identity, an InTuple by its chain."""
    if type(h) is InTuple:
        return ("in tuple", _holder(h.holder), h.key)
    return ("object", id(h))


def _assert_same(new: Snapshot, ref: Snapshot) -> None:
    assert len(new.shape) == len(ref.shape)
    for pos, (x, y) in enumerate(zip(new.shape, ref.shape)):
        assert _equal(x, y), f"shape[{pos}]: {x!r} != {y!r}"
    assert list(new.ints) == list(ref.ints)
    for pos, (a, b) in zip(new.ints, zip(new.ints.values(), ref.ints.values())):
        assert _holder(a[0]) == _holder(b[0]) and _equal(a[1], b[1]) and _equal(a[2], b[2]), \
            f"ints[{pos}]: {a!r} != {b!r}"

    def sharing(s: Snapshot) -> list[int]:     # which ints share one InTuple holder
        first: dict[int, int] = {}
        return [first.setdefault(id(h), pos) for pos, (h, _, _) in s.ints.items()
                if type(h) is InTuple]
    assert sharing(new) == sharing(ref)
    assert new.free == ref.free and type(new.free) is frozenset
    assert len(new.alive) == len(ref.alive)
    assert all(a is b for a, b in zip(new.alive, ref.alive))


def _compare(*args: Any, **kw: Any) -> Snapshot:
    """:func:`snapshot` and the reference on the same arguments: the same result or the same
    refusal."""
    try:
        ref = reference_snapshot(*args, **kw)
    except Unwalkable as e:
        with pytest.raises(Unwalkable) as got:
            snapshot(*args, **kw)
        assert str(got.value) == str(e)
        raise
    new = snapshot(*args, **kw)
    _assert_same(new, ref)
    return new


# -- values and objects of every kind --------------------------------------------------------

def _ours(cls: type) -> type:
    cls.__module__ = "hil.tests_state_walk"   # a class of this project's package (hil)
    return cls


@_ours
class _Plain:
    pass


@_ours
class _Slots:
    __slots__ = ("a", "b", "c")


@_ours
class _MoreSlots(_Slots):
    __slots__ = "d"                           # a single name, as a str


@_ours
class _Both(_Slots):                          # slots below, a __dict__ here
    pass


@_ours
class _OneSlot:
    __slots__ = ("only", "__weakref__")


@_ours
class _Lazy:                                  # a __getattr__: even __dict__ is asked for
    __slots__ = ("x",)

    def __getattr__(self, name: str) -> Any:
        if name == "__dict__":
            return {"made_up": 5}
        raise AttributeError(name)


@_ours
@dataclasses.dataclass(frozen=True)
class _Frozen:
    a: int
    b: tuple


@_ours
@dataclasses.dataclass
class _Mutable:
    a: int
    b: list


@_ours
class _Latest:
    pass


class _Color(enum.IntEnum):
    RED = 1


class _Foreign:
    pass


class _MyInt(int):
    pass


def _zoo() -> tuple[list, list]:
    """Roots holding every kind of value, shared and nested, and a boundary."""
    wall = _Plain()
    wall.inside = [1, 2, 3]                   # not walked: a boundary
    p = _Plain()
    p.when, p.sent, p.level, p.name, p.ratio, p.on = 100, 4, -7, "x", 0.25, True
    p.nothing, p.raw, p.buf, p.frozen = None, b"\x00\x01", bytearray(b"ab"), frozenset({3})
    p.colors = {1, 2}
    p.color, p.myint = _Color.RED, _MyInt(9)
    p.tup = (1, (2, (3, "x")), 4)
    p.empty, p.empties = (), [[], {}, ()]
    p.frame = _Frozen(5, (6, 7))
    p.mutable = _Mutable(8, [9, (10, 11)])
    p.log = [(t, "note") for t in range(50)]   # a record, by its length
    p.log_tuple = (1, 2)                     # named like a record but not a list
    p.nested = {"a": 1, 2: 3, (4, 5): [6, {"b": 7}], "log": [1, 2]}
    p.fn, p.lam = _Plain.__init__, (lambda: 1)
    p.method, p.builtin, p.bound_builtin = p.__repr__, len, [].append
    p.partial = functools.partial(max, 1)
    p.wall, p.wall_too = wall, [wall, (wall, 3)]
    s = _MoreSlots()
    s.a, s.c, s.d = 1, [2, p], 3             # s.b not set: skipped
    b = _Both()
    b.a, b.b, b.extra = 1, 2, (3, 4)
    o = _OneSlot()
    o.only = (5, 6)
    lazy = _Lazy()
    lazy.x = 1
    latest = _Latest()
    latest.odo, latest.seen = 3, {"odo": (3, 4)}
    p.shared = [s, s, b, o, lazy, latest, p, p.tup, p.tup]
    p.foreign = _Foreign()
    p.sets = [set(), frozenset()]
    p.by_int = {10: 1, 11: (12, 13), "k": {14: 15}}
    p.floats = [float("nan"), 1.0, 1, True]
    return [p, (1, 2, (3, 4)), 7, [8, (9,)], s, wall], [wall]


def test_every_kind_of_value_gives_the_reference_snapshot():
    roots, boundary = _zoo()
    snap = _compare(roots, boundary, records=frozenset({"log", "log_tuple"}),
                    latest=(_Latest,))
    assert snap.free and len(snap.ints) > 30
    _compare(roots)                           # no boundary: it is walked
    _compare(roots, boundary)                 # logs walked whole
    _compare([roots[0], roots[0]], [roots[1]])
    _compare([])


def test_refusals_are_the_reference_refusals():
    p = _Plain()
    p.rng = random.Random(1)
    with pytest.raises(Unwalkable):
        _compare([p])
    snap = _compare([p, [p.rng, p.rng]], rng_state=True)
    assert ("rng", random.Random(1).getstate()) in snap.shape
    p.rng, p.it = None, iter([1, 2])
    with pytest.raises(Unwalkable, match="it"):
        _compare([p])
    q = _Plain()
    q.gen = (x for x in range(3))
    with pytest.raises(Unwalkable, match="gen"):
        _compare([[q]])


def test_a_slot_that_comes_and_goes_is_the_reference_walk():
    """A type's fields are planned once; a slot unset in one object, set in the next, and a
    __dict__ grown later must still be walked as the reference walks them."""
    a, b = _Slots(), _Slots()
    a.a, a.b, a.c = 1, 2, 3
    b.b = 5
    _compare([a, b, a])
    del a.b
    b.a, b.c = (7, 8), None
    _compare([a, b])
    c = _Both()
    _compare([c])
    c.a, c.late = 1, [2]
    _compare([c, _Both()])


# -- the simulator's own snapshots, and whole worlds ------------------------------------------

@pytest.fixture
def compared(monkeypatch) -> list[int]:
    """Every snapshot the simulator takes is compared with the reference's; the list counts
    them."""
    calls: list[int] = []

    def both(*args: Any, **kw: Any) -> Snapshot:
        calls.append(1)
        return _compare(*args, **kw)

    monkeypatch.setattr(quiet_can, "snapshot", both)
    monkeypatch.setattr(quiet_ring, "snapshot", both)
    return calls


def _whole(w: World) -> Snapshot:
    """The whole world, as scripts/sleep_hunt.py compares two of them."""
    parts = [p for _, q in sorted(w.quiet.items()) for p in q.roots]
    stations = [w.stations[r] for r in sorted(w.stations)]
    boundary = [w.sched, *w.quiet.values(), *(q.clock for q in w.quiet.values())]
    events = [w.sched.pending(q) for q in w.quiet.values()]
    return _compare([*parts, stations, w.air, events], boundary, rng_state=True)


F = lambda *s: tuple(parse_fault(x) for x in s)  # noqa: E731
WORLDS = {
    "CAN idle": SimConfig(robots=(0, 1, 2), duration=8, can=True, seed=1),
    "CAN with jobs": SimConfig(robots=(0, 1, 2, 3), duration=8, can=True, seed=2, load=1),
    "CAN faults": SimConfig(robots=(0, 1, 2, 3), duration=10, can=True, seed=2, faults=F(
        "busoff:2@3", "stuck:3@4-5", "stall:1.JOINT1@4", "silent:2.WHEEL@6-7",
        "noisy:1.PAW@7-7.5")),
    "ring leaps": SimConfig(robots=(0, 1, 2, 3), duration=20, seed=3),
}


@pytest.mark.parametrize("name", list(WORLDS))
def test_the_simulators_snapshots_are_the_reference_snapshots(name, compared):
    w = World(WORLDS[name])
    for stop in (0.37, 0.61, 1.0):
        w.run(round(w.end_tick * stop))
        _whole(w)
    assert len(compared) > 5


def test_a_soak_like_world_mid_run_gives_the_reference_snapshots(compared):
    """The soak's random faults, orders under load, wakes: snapshots taken all along."""
    robots = (0, 1, 2, 3)
    faults = random_faults(random.Random(11), robots, 40 / 3600 + 0.04, True, False,
                           mean_gap_s=8)
    w = World(SimConfig(robots=robots, duration=40, can=True, seed=11, load=0.3,
                        load_until=30, faults=tuple(f for f in faults if f.at < 40)))
    for stop in (0.2, 0.45, 0.7, 1.0):
        (w.run if stop == 1.0 else w._advance)(round(w.end_tick * stop))
        _whole(w)
    assert len(compared) > 20


@pytest.mark.parametrize("spec", [
    dict(robots=(1, 2), can=True, faults=("noisy:2.JOINT1@0.5-3",)),   # a bus's deaf ids
    dict(robots=(1, 2), extra=((1, 0.5, None),)),                      # a twin's radio
])
def test_two_worlds_built_alike_have_the_same_portable_state(spec):
    """The hunts compare two worlds by ``portable`` snapshots: a CAN bus's set of deaf nodes
    (their ids, while a ``noisy`` fault lasts) and the air's set of a twin's radios (objects)
    made two identical worlds differ."""
    from hil.sim.faults import parse_fault
    from hunt import sleep_hunt
    hunt = sleep_hunt()
    kw = dict(spec)
    faults = tuple(parse_fault(f) for f in kw.pop("faults", ()))
    cfg = SimConfig(duration=2.0, seed=1, can_sleep=False, ring_sleep=False, faults=faults,
                    **kw)
    a, b = World(cfg), World(cfg)
    a.run()
    b.run()
    assert hunt.state(a) == hunt.state(b)


def test_a_slot_named_not_state_is_not_walked():
    """A reception's reserved sequence number (hil/sim/reception.py) is the scheduler's
    bookkeeping: two runs of one world number their events differently (a leap puts events
    back with new numbers), so it is no state to compare and no int a period moves on."""
    from hil.sim.reception import Reception
    a, b, c = (Reception(b"ab", 0, 10, 2) for _ in range(3))
    a.seq, b.seq, c.seq = 100, 73_000, 100
    c.pos = 1
    assert snapshot([a]).shape == snapshot([b]).shape
    assert snapshot([a]).int_pos == snapshot([b]).int_pos
    assert snapshot([c]).shape != snapshot([a]).shape

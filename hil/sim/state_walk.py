"""The state of a part of the simulation as a flat list of leaves, read in one fixed order.

Used to see that a part is periodic and to move it on by whole periods (hil/sim/quiet_can.py):
two snapshots one period apart that differ only by ticks moved on by exactly the period and by
counters mean the part will go on repeating itself, and :func:`advance` moves those ticks and
counters on by any number of periods.

What a snapshot holds: everything reachable from the roots through instance attributes
(``__dict__`` and ``__slots__``), lists, dicts and tuples, for objects of this project's
classes (``can_bus``, ``firmware_model``, ``hil``). Other things are values: numbers,
strings, bytes, enums, sets and frozen dataclasses (a CAN frame) by ``==``; functions, bound
methods and objects of other libraries by identity (a function is the same function; a foreign
object's inside is not looked at, so a part whose state hides in one, a random generator, is
refused by :func:`snapshot`). A ``boundary`` object (the world's scheduler, the radio station
a child talks to) is compared by identity and not entered. An object reached twice is a
reference to its first visit, so sharing is part of the shape.
"""
from __future__ import annotations

import dataclasses
import random
import types
from enum import Enum
from typing import Any, Iterable

__all__ = ["Snapshot", "Unwalkable", "snapshot", "period_delta", "advance", "portable"]

_OURS = ("can_bus", "firmware_model", "hil")
_VALUE_TYPES = (bool, float, str, bytes, type(None), Enum, frozenset, set)
_FN_TYPES = (types.FunctionType, types.BuiltinFunctionType, types.MethodType,
             types.BuiltinMethodType)


class Unwalkable(Exception):
    """The part holds state a snapshot cannot see (a random generator, an iterator)."""


@dataclasses.dataclass
class Snapshot:
    """``shape``: every position's kind and value (ints included), in walk order;
    ``ints``: (position in shape, holder, key, name) of every int a period may move on
    (holder None inside a tuple: it cannot be written)."""

    shape: list
    ints: list[tuple[int, Any, Any, str]]


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
    return [n for n in names if n not in ("__dict__", "__weakref__")]


def snapshot(roots: Iterable[Any], boundary: Iterable[Any] = (),
             rng_state: bool = False, records: frozenset[str] = frozenset()) -> Snapshot:
    """Walk ``roots`` (module docstring). ``rng_state``: a random generator is its state
    (to compare two runs) instead of a reason to refuse. ``records``: attributes that are
    append-only lists nothing in the model reads (a log): only their length is taken, so a
    long run's log does not make every snapshot longer (a part whose log grew is still not
    periodic)."""
    shape: list = []
    ints: list[tuple[int, Any, Any, str]] = []
    seen: dict[int, int] = {}
    stop = {id(b) for b in boundary}
    keep: list[Any] = []            # objects seen, alive until the walk ends (stable ids)

    def visit(x: Any, holder: Any, key: Any, name: str) -> None:
        t = type(x)
        if t is int:
            ints.append((len(shape), holder, key, name))
            shape.append(x)
            return
        if isinstance(x, _VALUE_TYPES):
            shape.append(x)
            return
        if isinstance(x, _FN_TYPES):
            self_ = getattr(x, "__self__", None)
            shape.append(("fn", id(getattr(x, "__func__", x)), id(self_),
                          getattr(x, "__qualname__", type(x).__name__)))
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
        if t is tuple:
            shape.append(("tuple", len(x)))
            for j, v in enumerate(x):
                visit(v, None, j, name)
        elif isinstance(x, list):
            shape.append(("list", len(x)))
            for j, v in enumerate(x):
                visit(v, x, j, name)
        elif isinstance(x, dict):
            shape.append(("dict", tuple(x)))
            for k, v in x.items():
                visit(v, x, k, k if isinstance(k, str) else name)
        elif dataclasses.is_dataclass(x) and x.__dataclass_params__.frozen:
            shape.append(x)
        elif rng_state and isinstance(x, random.Random):
            shape.append(("rng", x.getstate()))
        elif isinstance(x, random.Random) or hasattr(x, "__next__"):
            raise Unwalkable(f"{name}: a {t.__name__} keeps state a snapshot cannot see")
        elif t.__module__.split(".")[0] in _OURS:
            shape.append(("obj", t))
            d = getattr(x, "__dict__", None)
            if d is not None:
                for k, v in d.items():
                    if k in records and type(v) is list:
                        shape.append(("record", len(v)))
                    else:
                        visit(v, x, k, k)
            for k in _slot_names(t):
                if hasattr(x, k):
                    visit(getattr(x, k), x, k, k)
        else:
            shape.append(("id", i, None, t.__name__))

    for root in roots:
        visit(root, None, None, "root")
    return Snapshot(shape, ints)


def period_delta(before: Snapshot, after: Snapshot, period: int,
                 counters: frozenset[str]) -> list[tuple[Any, Any, int]] | None:
    """How one period moved the part on, or None if it is not periodic: (holder, key, delta)
    of every int of ``after`` that moved, each either a tick moved by exactly ``period`` or a
    counter (an attribute or key named in ``counters``) moved by any amount. Everything else
    must be equal."""
    a, b = before.shape, after.shape
    if len(a) != len(b):
        return None
    int_at = {pos: (holder, key, name) for pos, holder, key, name in after.ints}
    moved: list[tuple[Any, Any, int]] = []
    for pos, (x, y) in enumerate(zip(a, b)):
        if x == y and type(x) is type(y):
            continue
        spot = int_at.get(pos)
        if spot is None or type(x) is not int or type(y) is not int:
            return None
        holder, key, name = spot
        d = y - x
        if holder is None or not (d == period or (name in counters and d > 0)):
            return None
        moved.append((holder, key, d))
    return moved


def advance(moved: list[tuple[Any, Any, int]], periods: int) -> None:
    """Move the part on by ``periods`` more periods (``moved`` from :func:`period_delta`)."""
    if periods <= 0:
        return
    for holder, key, d in moved:
        if isinstance(holder, (list, dict)):
            holder[key] += d * periods
        else:
            setattr(holder, key, getattr(holder, key) + d * periods)


def portable(snap: Snapshot) -> list:
    """``snap.shape`` without object identities (a function by its name, a foreign or
    boundary object by its type, a dict by its size): two worlds built alike compare equal
    with it."""
    out = []
    for x in snap.shape:
        if type(x) is tuple and x and x[0] in ("fn", "boundary", "id"):
            out.append(x[:1] + ((x[3],) if len(x) > 3 else ()))
        elif type(x) is tuple and x and x[0] == "dict":
            out.append(("dict", len(x[1])))        # keys may be ids (a bus's nodes)
        else:
            out.append(x)
    return out

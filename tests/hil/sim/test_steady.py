"""The steady-state contracts (hil/sim/steady.py) hold: each walked class that holds a declared
name declares it, and no model code reads a declared counter or record.

The fast paths move a counter on by whole periods and take only a record's length, so a
model that read one to decide anything would leap to a state the frame-by-frame run never
reaches. The walker matches these names wherever a snapshot finds them; these tests are what
keeps a name from meaning a counter in one class and a state in another.
"""
from __future__ import annotations

import ast
import inspect
import textwrap

import pytest

from hil.sim import steady
from hil.sim.config import SimConfig
from hil.sim.quiet_can import COUNTERS as CAN_COUNTERS, RECORDS as CAN_RECORDS
from hil.sim.quiet_ring import COUNTERS as RING_COUNTERS, MODULAR
from hil.sim.state_walk import snapshot
from hil.sim.world import World

DECLARED = RING_COUNTERS | CAN_COUNTERS | CAN_RECORDS | set(MODULAR) | {"transmissions"}

READS = {
    ("_Submodule", "_order"): "its queue's tie-break: compared only with its own values",
    ("Air", "_noise_gen"): "a generation number: compared only with its own copies",
    ("World", "transmissions"): "copied into the action sequence's report (action_turns), "
                                "which nothing in the model reads",
    ("Dispatcher", "log"): "its length, to drop the oldest half of a full log (a tail kept)",
    ("_Submodule", "events"): "its length, to drop the oldest half when full (a tail kept)",
    ("Cpu", "_busy"): "the figure Cpu.busy reports (loads, the CPU report), never a decision",
}
"""Reads of a declared counter that decide nothing by its amount (the only exceptions)."""


def _walked_types() -> set[type]:
    """Every class of ours a snapshot of whole worlds walks: a ring with the standby PC, byte
    errors and load, and children with their CAN sides and the CPU model."""
    out: set[type] = set()
    for cfg in (SimConfig(robots=(0, 1, 2, 3), duration=3, seed=1, can=True,
                          father_standby=True, noise=True, ber=1e-3, load=1.0),
                SimConfig(robots=(1, 2), duration=3, seed=2, can=True, cpu=None)):
        w = World(cfg)
        w.run()
        snap = snapshot([w], [w.sched], rng_state=True)
        out |= {x[1] for x in snap.shape if type(x) is tuple and x and x[0] == "obj"}
    return out


def _assigned(cls: type) -> set[str]:
    """The attributes ``cls`` (its own body, not its bases') assigns on ``self``, and its
    slots."""
    names = set(cls.__dict__.get("__slots__", ()))
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError):
        return names
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store) and \
                isinstance(node.value, ast.Name) and node.value.id == "self":
            names.add(node.attr)
    return names


def _declared(cls: type) -> set[str]:
    return {n for c in cls.__mro__ for attr in ("STEADY_COUNTERS", "STEADY_RECORDS",
                                                "STEADY_MODULAR")
            for n in getattr(c, attr, ())}


@pytest.fixture(scope="module")
def walked() -> set[type]:
    return _walked_types()


def test_every_walked_class_holding_a_declared_name_declares_it(walked):
    holders = {(c, n) for t in walked for c in t.__mro__ if c.__module__.split(".")[0] in
               ("firmware_model", "can_bus", "hil") for n in _assigned(c) & DECLARED}
    undeclared = sorted(f"{c.__module__}.{c.__qualname__}.{n}" for c, n in holders
                        if n not in _declared(c))
    assert not undeclared, ("a walked class holds a name another declares as a counter or "
                            "record, without declaring it: " + ", ".join(undeclared))
    assert {c.__name__ for c, _ in holders} >= {"Air", "RotationalMac", "Uart", "CanBus"}


def test_the_fast_paths_sets_are_the_declarations():
    assert RING_COUNTERS == steady.counters(steady.RING_PARTS)
    assert CAN_COUNTERS == steady.counters(steady.CAN_PARTS)
    assert CAN_RECORDS == steady.records(steady.CAN_PARTS) == {"log", "events"}
    assert MODULAR == {"turns": 7}


def _reads(cls: type) -> list[str]:
    """Where a method of ``cls`` reads ``self.NAME`` for a name it declares, other than to add
    to it (``+=``, ``self.x[k] = self.x.get(k, 0) + 1``) or append to it; a modular name
    only as ``self.NAME % N`` with its declared N."""
    counted = set(getattr(cls, "STEADY_COUNTERS", ())) | set(getattr(cls, "STEADY_RECORDS", ()))
    mods: dict[str, int] = dict(getattr(cls, "STEADY_MODULAR", {}))
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    parent = {ch: node for node in ast.walk(tree) for ch in ast.iter_child_nodes(node)}
    found = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and
                node.value.id == "self" and isinstance(node.ctx, ast.Load)):
            continue
        name, up = node.attr, parent.get(node)
        if name in mods:
            ok = (isinstance(up, ast.BinOp) and isinstance(up.op, ast.Mod) and up.left is node
                  and isinstance(up.right, ast.Name) and
                  _constant(cls, up.right.id) == mods[name])
        elif name in counted:
            ok = (isinstance(up, ast.AugAssign) and up.target is node) or \
                (isinstance(up, ast.Subscript) and isinstance(parent.get(up), ast.AugAssign)) \
                or (isinstance(up, ast.Subscript) and isinstance(up.ctx, ast.Store)) \
                or (isinstance(up, ast.Attribute) and up.attr in ("append", "extend")) or \
                _increment(node, up, parent) or (cls.__name__, name) in READS
        else:
            continue
        if not ok:
            found.append(f"{cls.__name__}.{name}: {ast.unparse(up)}")
    return found


def _increment(node: ast.Attribute, up: ast.AST | None, parent: dict) -> bool:
    """``self.x[k] = self.x.get(k, 0) + n``: the dict counter's own increment."""
    call = parent.get(up) if isinstance(up, ast.Attribute) and up.attr == "get" else None
    add = parent.get(call) if call is not None else None
    stmt = parent.get(add) if isinstance(add, ast.BinOp) else None
    return isinstance(stmt, ast.Assign) and any(
        isinstance(t, ast.Subscript) and ast.dump(t.value) == ast.dump(node)
        for t in stmt.targets)


def _constant(cls: type, name: str) -> object:
    module = inspect.getmodule(cls)
    return getattr(module, name, None)


def test_no_model_code_reads_a_declared_counter_or_record():
    classes = {c for c in (*steady.RING_PARTS, *steady.CAN_PARTS, World)
               for c in c.__mro__ if hasattr(c, "STEADY_COUNTERS") or
               hasattr(c, "STEADY_RECORDS") or hasattr(c, "STEADY_MODULAR")}
    read = [r for c in sorted(classes, key=lambda c: c.__name__) for r in _reads(c)]
    assert not read, "model code reads what the fast paths may move on: " + "; ".join(read)


def test_the_read_check_catches_a_read():
    class Probe:
        STEADY_COUNTERS = ("hits",)

        def __init__(self) -> None:
            self.hits = 0

        def decide(self) -> bool:
            self.hits += 1
            return self.hits > 3
    assert _reads(Probe) == ["Probe.hits: self.hits > 3"]

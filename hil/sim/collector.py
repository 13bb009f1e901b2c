"""Python's cyclic garbage collector while the simulator runs: its youngest generation
collected every 10,000 new objects instead of every 700.

CPython runs its cyclic collector on the youngest generation whenever the objects that need
it (containers: tuples, lists, instances) allocated and not yet freed since the last
collection pass ``gc.get_threshold()[0]``, 700 by default, and on the older ones every 10 of
those. The simulator makes containers at a high rate (an event, its heap entry, its arguments,
a CAN frame, a radio frame, each a few microseconds of simulated work), most of them freed by
reference counting a moment later, and keeps a few alive for longer (a pending event, a
probe's snapshot for a period, the world's record of every message's outcome). With the
default, a soak ran the young collection every few hundred events, each walking what happened
to be alive then and promoting it, and the older generations' walks grew with the run: 7 % of
a 0.5 h soak's CPU time, 13 % of a 1 h one's (measured with ``gc.callbacks``,
docs/fast-paths.md, "The collector").

:func:`fewer_collections` raises the youngest generation's threshold to
:data:`YOUNG_THRESHOLD` for the length of a ``with`` block (``World.run`` runs in one) and
puts back whatever was set before; the older generations keep their rules. Nothing in the
model depends on when the collector runs (the model makes few reference cycles, and no
result reads an object's lifetime), so every trace is the same either way; the cost is at
most 10,000 more objects waiting for a collection (about a megabyte).

The threshold is the interpreter's, not the block's: another thread running Python code
meanwhile is collected on the same threshold.
"""
from __future__ import annotations

import gc
from contextlib import contextmanager
from typing import Iterator

__all__ = ["YOUNG_THRESHOLD", "fewer_collections"]

YOUNG_THRESHOLD = 10_000
"""New containers (objects) between two collections of the youngest generation while the
simulator runs (CPython's default: 700)."""


@contextmanager
def fewer_collections(young: int = YOUNG_THRESHOLD) -> Iterator[None]:
    """Collect the youngest generation every ``young`` new containers inside the block (never
    more often than the threshold set before it), then restore the threshold set before."""
    before = gc.get_threshold()
    if before[0] == 0 or before[0] >= young:      # collector off, or already as rare
        yield
        return
    gc.set_threshold(young, *before[1:])
    try:
        yield
    finally:
        gc.set_threshold(*before)

"""The steady-state contracts the fast paths rely on, read from the classes that declare them.

A part of the simulation is periodic when two snapshots a period apart differ only by ticks
moved on by the period and by values nothing in the model reads (hil/sim/state_walk.py). Which
attributes those are is declared on the class that holds them, next to the code that writes
them:

- ``STEADY_COUNTERS``: names of ints (or dicts/lists of ints) that only count what happened:
  written ``+= n``, read by reports, never by the model to decide anything. A leap or a
  domain's sleep may move them on by any amount.
- ``STEADY_RECORDS``: names of append-only lists nothing in the model reads (a log): a
  snapshot takes their length only.
- ``STEADY_MODULAR``: name -> N, a counter the model reads only modulo N: a period must move it
  by a multiple of N.

The walker matches attributes by name wherever it finds them, so a name declared by one class
binds every class the same snapshot walks: ``tests/hil/sim/test_steady.py`` checks that every
walked class holding a declared name declares it too, and that no model code reads a declared
counter or record (but the modular ones, modulo their N).
"""
from __future__ import annotations

from typing import Any, Iterable, Mapping

from can_bus.bus import CanBus
from can_bus.submodules.node import _Submodule
from firmware_model.dispatcher import Dispatcher
from firmware_model.mcu.can_controller import CanController
from firmware_model.mcu.cpu import Cpu, HandlerStats
from firmware_model.mcu.uart import Uart
from firmware_model.radio.mac import RotationalMac
from firmware_model.station import RadioStation

from .air import Air
from .ledger import Tally

__all__ = ["CAN_PARTS", "RING_PARTS", "counters", "modular", "records"]

RING_PARTS: tuple[type, ...] = (Air, RotationalMac, RadioStation, Uart, Cpu, HandlerStats)
"""The classes of a ring leap's snapshot that declare a contract (and ``World``: its
module imports this one, so hil/sim/quiet_ring.py adds it)."""

CAN_PARTS: tuple[type, ...] = (_Submodule, CanBus, CanController, HandlerStats, Tally,
                               Dispatcher)
"""The classes of a sleeping CAN domain's snapshot that declare a contract."""


def _names(classes: Iterable[type], attr: str) -> frozenset[str]:
    return frozenset(n for c in classes for n in getattr(c, attr, ()))


def counters(classes: Iterable[type]) -> frozenset[str]:
    """Every name ``classes`` declare in ``STEADY_COUNTERS``."""
    return _names(classes, "STEADY_COUNTERS")


def records(classes: Iterable[type]) -> frozenset[str]:
    """Every name ``classes`` declare in ``STEADY_RECORDS``."""
    return _names(classes, "STEADY_RECORDS")


def modular(classes: Iterable[type]) -> dict[str, int]:
    """Every name -> N ``classes`` declare in ``STEADY_MODULAR``."""
    out: dict[str, int] = {}
    for c in classes:
        decl: Mapping[str, Any] = getattr(c, "STEADY_MODULAR", {})
        out.update(decl)
    return out

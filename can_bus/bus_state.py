"""The simulated CAN bus's state (can_bus.bus): error states and events, a node's counters and
hooks as the bus holds them, a dominant hold, and the frame facts the bus caches."""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from functools import lru_cache
from typing import Any


from can_bus.bits import (
    BUS_IDLE_RECESSIVE_BITS,
    BUS_OFF_RECOVERY_SEQUENCES,
    ERROR_DELIMITER_BITS,
    ERROR_FLAG_BITS,
    IFS_BITS,
    TRAILER_BITS,
    _wire,
)
from can_bus.clock import Cancellable as Event
from can_bus.frames import CanFrame
from can_bus.physical import loop_delay_s

ERROR_FRAME_TOTAL_BITS = ERROR_FLAG_BITS + ERROR_DELIMITER_BITS + IFS_BITS
"""17: bus time from the start of a (superposed) error flag to the next possible SOF."""

_REC_AFTER_PASSIVE_RX = 127
_NO_DEAF: frozenset[int] = frozenset()  # no node lost the frame to its own local error
_ELEVEN = BUS_IDLE_RECESSIVE_BITS
_RECOVERY = BUS_OFF_RECOVERY_SEQUENCES


class ErrorState(str, Enum):
    ACTIVE = "error-active"
    PASSIVE = "error-passive"
    BUS_OFF = "bus-off"


ACTIVE, PASSIVE, BUS_OFF = ErrorState.ACTIVE, ErrorState.PASSIVE, ErrorState.BUS_OFF


@lru_cache(maxsize=8192)
def _frame_info(frame: CanFrame) -> tuple[tuple[int, ...], int, int]:
    """(wire bits without IFS, stuffed SOF..CRC length, trailing recessive bits of that part)."""
    wire = _wire(frame.id, frame.data, frame.rtr, frame.dlc)
    n = len(wire) - TRAILER_BITS
    tail = 0
    while tail < n and wire[n - 1 - tail] == 1:
        tail += 1
    return wire, n, tail


@dataclass(frozen=True)
class CanErrorEvent:
    """One error seen by one node. ``kind``: 'bit', 'stuff' or 'ack'. Counters after update."""

    kind: str
    tick: int
    frame: CanFrame | None
    transmitter: bool
    tec: int
    rec: int
    state: ErrorState


@dataclass(frozen=True)
class NodeStatus:
    tec: int
    rec: int
    state: ErrorState


class _Node:
    __slots__ = (
        "node", "tec", "rec", "state", "suspend_until", "occ", "recover_ev", "queue", "seq",
        "pending_fn", "on_frame", "on_tx_done", "on_lost", "on_error", "on_state", "attached",
        "entry", "counting", "count_from", "loop", "after_request", "asked", "rx_ids",
        "always_acks",
    )

    def __init__(self, node: Any) -> None:
        self.node = node
        self.tec = 0
        self.rec = 0
        self.state = ACTIVE
        self.suspend_until = 0
        self.occ = 0
        self.counting = True                 # bus-off: counting the 128 x 11 recessive bits
        self.count_from: int | None = None   # ... from this tick, if it began in idle time
        self.recover_ev: Event | None = None
        self.queue: list[tuple[int, bool, int, CanFrame]] = []
        self.seq = 0
        self.entry: tuple[int, bool, int, CanFrame] | None = None
        self.pending_fn = getattr(node, "pending", None)
        self.after_request = bool(getattr(node, "pending_after_request", False))
        self.asked = True           # pending() may return a frame (cleared when it had none)
        self.on_frame = getattr(node, "on_frame", None)
        ids = getattr(node, "rx_ids", None)
        self.rx_ids: frozenset[int] | None = None if ids is None else frozenset(ids)
        self.always_acks = not hasattr(node, "acknowledges")
        self.on_tx_done = getattr(node, "on_tx_done", None)
        self.on_lost = getattr(node, "on_arbitration_lost", None)
        self.on_error = getattr(node, "on_error", None)
        self.on_state = getattr(node, "on_state_change", None)
        self.attached = True
        self.loop = _HS_LOOP_S               # TXD-to-RXD loop delay (s)


_HS_LOOP_S = loop_delay_s(0)


class _Hold:
    __slots__ = ("flag", "tx", "rx", "released", "step", "ev")

    def __init__(self, flag: int, tx: list[_Node], rx: list[_Node]) -> None:
        self.flag = flag
        self.tx = tx
        self.rx = rx
        self.released: int | None = None
        self.step = 0
        self.ev: Event | None = None


_IDLE, _FRAME, _TAIL, _HELD = range(4)


@lru_cache(maxsize=4096)
def _arbitration_end(wire: tuple[int, ...]) -> int:
    """Wire index of the RTR bit (the arbitration field's last bit): SOF, 11 identifier bits
    and RTR are 13 bits before stuffing; a bit after five equal ones is a stuff bit."""
    run, last, real = 0, None, 0
    for i, bit in enumerate(wire):
        stuffed = run == 5
        run = run + 1 if bit == last and not stuffed else 1
        last = bit
        if not stuffed:
            real += 1
            if real == 13:
                return i
    return len(wire) - 1


def _prio(cand: tuple[CanFrame, Any]) -> tuple[int, bool]:
    return cand[0].id, cand[0].rtr

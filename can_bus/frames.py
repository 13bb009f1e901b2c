"""The CAN 2.0A frame as every part of ``can_bus`` (and the firmware's controller) passes it.

:class:`CanFrame` is a value: an 11-bit identifier, up to 8 data bytes, the RTR bit and the
DLC, checked when it is made. It converts to and from a python-can ``can.Message`` (the
bridge, the bench's logs). Its bit-level form (stuffing, CRC, length) is :mod:`can_bus.bits`;
the bus that carries it is :mod:`can_bus.bus`.
"""
from __future__ import annotations

from dataclasses import dataclass

import can

from can_bus.bits import _check

__all__ = ["CAN_EFF_FLAG", "CAN_ERR_FLAG", "CAN_ERR_MASK", "CAN_RTR_FLAG", "CANFD_BRS",
           "CANFD_ESI", "CANFD_FDF", "CanFrame", "fd_flags"]

CAN_EFF_FLAG, CAN_RTR_FLAG, CAN_ERR_FLAG = 0x80000000, 0x40000000, 0x20000000
CAN_ERR_MASK = 0x1FFFFFFF
"""SocketCAN's identifier flags and an error frame's class bits (linux/can.h), as a capture
(LINKTYPE_CAN_SOCKETCAN) and a ``candump -L`` log write them."""
CANFD_BRS, CANFD_ESI, CANFD_FDF = 0x01, 0x02, 0x04
"""A CAN FD frame's flags (linux/can.h); FDF (kernel 6.2 on) is set on every CAN FD frame
SocketCAN hands over, so ``candump -L`` writes a CAN FD frame with ``##5`` where python-can
wrote ``##1``."""


def fd_flags(msg: can.Message) -> int:
    """A CAN FD ``msg``'s flags byte as SocketCAN gives it: FDF, with BRS and ESI if set."""
    return CANFD_FDF | (CANFD_BRS if msg.bitrate_switch else 0) | (
        CANFD_ESI if msg.error_state_indicator else 0)


@dataclass(frozen=True)
class CanFrame:
    """A CAN 2.0A data or remote frame. ``dlc`` defaults to ``len(data)`` (0 for remote)."""

    id: int
    data: bytes = b""
    rtr: bool = False
    dlc: int | None = None

    def __post_init__(self) -> None:
        data = bytes(self.data)
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "rtr", bool(self.rtr))
        object.__setattr__(self, "dlc", _check(self.id, data, self.rtr, self.dlc))

    def to_message(self, timestamp: float = 0.0) -> can.Message:
        return can.Message(
            timestamp=timestamp,
            arbitration_id=self.id,
            is_extended_id=False,
            is_remote_frame=self.rtr,
            dlc=self.dlc,
            data=self.data,
        )

    @classmethod
    def from_message(cls, msg: can.Message) -> "CanFrame":
        if msg.is_extended_id:
            raise ValueError("extended (29-bit) identifiers are not CAN 2.0A")
        if msg.is_fd or msg.is_error_frame:
            raise ValueError("only classical data/remote frames convert to CanFrame")
        if msg.is_remote_frame:
            return cls(msg.arbitration_id, b"", True, msg.dlc)
        data = bytes(msg.data or b"")
        return cls(msg.arbitration_id, data, False, msg.dlc if msg.dlc is not None else len(data))

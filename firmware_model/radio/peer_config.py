"""The peer MACs' policy (docs/peer-macs.md): frame size, slot, window, backoffs and sensing
(:class:`PeerConfig`), and the slack the slotted MAC allows its timer (ticks)."""
from __future__ import annotations

from dataclasses import dataclass

from ..timing import FRAME_OVERHEAD, PC_BYTE_TICKS

__all__ = ["MIN_FRAME_BYTES", "PeerConfig", "default_slot"]

_ACK_TEXT_MAX = len("ack(6,99)")
MIN_FRAME_BYTES = FRAME_OVERHEAD + _ACK_TEXT_MAX
"""The smallest ``frame_bytes`` (23): a frame that holds one ack."""
_GUARD_TICKS = 64
"""Slack added to a slot (and to waits) for the reload timer's even-tick rounding."""

_LATE_TICKS = 40_000
"""How late (ticks, 2.5 ms: half the paper's Ttrans) a slotted station's timer handler may
come and still send in the slot it was armed for (:class:`SlottedAlohaMac`): its frame
starts as late, and ends before the next slot's first byte (a slot holds Ttrans after its
longest frame)."""


def default_slot(frame_bytes: int, ttrans: int) -> int:
    """A slot for frames of up to ``frame_bytes``: the longest such frame at the slower (father
    PC) byte rate, plus Ttrans (the next slot's sender switches while this frame ends), plus a
    small guard for timer rounding."""
    return frame_bytes * PC_BYTE_TICKS + ttrans + _GUARD_TICKS


@dataclass(frozen=True, slots=True)
class PeerConfig:
    """Policy of the peer MACs (times in ticks; the rest of the timing is the ``MacConfig``)."""

    frame_bytes: int = 80
    """Largest frame the load makes (overhead included). Sets the slot, the ack wait and the
    backoff unit; an ack is piggybacked on a data frame only if the sum fits."""
    slot: int | None = None
    """Slotted ALOHA slot (ticks); default :func:`default_slot` of ``frame_bytes``."""
    window: int = 4
    """Messages a robot may have sent and not yet acknowledged (1 = stop and wait)."""
    backoff: float = 8.0
    """Retransmission backoff: uniform in [0, backoff) frame times (slotted: whole slots)."""
    sense_backoff: float = 2.0
    """CSMA: after sensing busy, wait uniform in (0, sense_backoff) frame times."""
    sense_bytes: int = 2
    """CSMA: a byte heard within this many byte times means busy."""
    sense: str = "bytes"
    """CSMA: ``"bytes"`` (any byte, the default) or ``"frame"`` (only a frame whose Header
    was recognised; the choice that still works with the PTR2000's idle noise on)."""
    ack_guard: bool = True
    """CSMA: after a data frame for another robot, count the channel busy until its ack can
    have started (Ttrans + 2 bytes later), so the ack is not hit by a deferred station."""
    lifetime: int | None = None
    """Most ticks between a message's first and last transmission (default: enough for
    ``max_attempts`` attempts at the longest waits, see ``PeerMac.__init__``)."""

    def __post_init__(self) -> None:
        if not MIN_FRAME_BYTES <= self.frame_bytes <= 576:
            raise ValueError(f"frame_bytes must be {MIN_FRAME_BYTES}-576, "
                             f"got {self.frame_bytes}")
        if self.window < 1:
            raise ValueError(f"window must be at least 1, got {self.window}")
        if self.backoff < 0 or self.sense_backoff <= 0:
            raise ValueError("backoff must be >= 0 and sense_backoff > 0")
        if self.sense not in ("bytes", "frame"):
            raise ValueError(f"sense must be 'bytes' or 'frame', got {self.sense!r}")

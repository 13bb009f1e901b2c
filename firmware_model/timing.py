"""Time base shared by every model: integer MB90F549 machine-clock ticks.

One tick is one cycle of the 16 MHz machine clock (62.5 ns). docs/protocol.md §2 gives the
defaults.
"""
from __future__ import annotations

TICK_HZ = 16_000_000
"""Machine clock of the MB90F549 child (ticks per second)."""

UART_BIT_TICKS_9600 = 1664
"""Bit time of the MB90F549 UART at nominal 9600 baud: 16 MHz / (16 x 104) = 9615.38 bit/s."""

BITS_PER_BYTE_8N1 = 10
"""Start bit, eight data bits, stop bit."""

CHILD_BYTE_TICKS = UART_BIT_TICKS_9600 * BITS_PER_BYTE_8N1
"""16640 ticks: one 8N1 byte on air from a child at "9600"."""

PC_BYTE_TICKS = 16_667
"""One 8N1 byte from the father PC's 16550-style UART at exact 9600 baud.

10/9600 s = 16666.67 ticks, rounded to the nearest whole tick (error 0.33 tick a byte, 21 ns).
"""

TTRANS_TICKS = 80_000
"""Ttrans, 5 ms: the protocol's hand-over guard (paper §IV.C, Fig. 7): the next sender raises
TXEN at the previous frame's End and sends Ttrans later. It is longer than either switch time
of the part (PTR2000_TX_READY_TICKS, PTR2000_RX_READY_TICKS): the margin is the protocol's."""

PTR2000_TX_READY_TICKS = 16_000
"""1 ms: the PTR2000's RX->TX switch time, TXEN high to the first bit it sends. nRF401 product
specification (the PTR2000's radio chip), Table 5 "Switching times for nRF401" (t_RT) and
"Switching TX <-> RX", Figure 4(a): data (DIN) may not be sent before TXEN has been high for
at least 1 ms."""

PTR2000_RX_READY_TICKS = 48_000
"""3 ms: the PTR2000's TX->RX switch time, TXEN low to the first bit it hears. nRF401 product
specification, Table 5 "Switching times for nRF401" (t_TR) and "Switching TX <-> RX",
Figure 4(b): the receiver may not receive data (DOUT) before TXEN has been low for at least
3 ms."""

TMAX_TICKS = 9_600_000
"""Tmax, 600 ms: most time one robot may hold the channel; also the takeover timeout."""

MISS_LIMIT = 3
"""Consecutive missed turns after which every member drops the robot (paper §IV.C)."""

FRAME_OVERHEAD = 14
"""Header 3 + Destination 1 + Source 1 + Number 2 + Type 1 + Length 4 + End 2 bytes."""


def ms_to_ticks(ms: float) -> int:
    """Milliseconds to whole ticks (rounded to nearest)."""
    return round(ms * TICK_HZ / 1000)


def s_to_ticks(seconds: float) -> int:
    """Seconds to whole ticks (rounded to nearest)."""
    return round(seconds * TICK_HZ)


def ticks_to_ms(ticks: int) -> float:
    """Ticks to milliseconds."""
    return ticks * 1000 / TICK_HZ


def ticks_to_s(ticks: int) -> float:
    """Ticks to seconds."""
    return ticks / TICK_HZ


def max_frame_bytes(byte_ticks: int, tmax: int = TMAX_TICKS) -> int:
    """Largest frame (bytes, overhead included) whose air time fits in Tmax (docs/protocol.md
    §7.1).

    576 at the child's 16640 ticks a byte; 575 for the father's 16667.
    """
    return tmax // byte_ticks


def max_content_bytes(byte_ticks: int, tmax: int = TMAX_TICKS) -> int:
    """Largest Content (bytes) one turn can carry at ``byte_ticks`` a byte: 562 for a child at
    the defaults, 561 for the father."""
    return max_frame_bytes(byte_ticks, tmax) - FRAME_OVERHEAD


def protocol_max_content(tmax: int = TMAX_TICKS) -> int:
    """Largest Length any station may send, so the largest every receiver accepts (bytes).

    Bounded by the fastest legal sender, a child at 16640 ticks a byte: 562 at the defaults
    (docs/protocol.md §3.1, clause 11). A slower station (the father PC, 561) sends less but
    accepts this much; a station whose clock runs fast never sends more than this."""
    return max_content_bytes(min(CHILD_BYTE_TICKS, PC_BYTE_TICKS), tmax)

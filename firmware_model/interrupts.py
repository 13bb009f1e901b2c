"""The child firmware's interrupt plan: each source it uses, its vector on the MB90540/545
series (the MB90F549's family) and the ICR level the firmware gives it.

Vector numbers and the ICR each one uses are the part's: Fujitsu's MB90540/545 project
template (``VECTORS.C`` with ``mb90540.h``, V30L10), whose vector table lists the resources by
number and whose ``InitIrqLevels`` says "Two resource interrupts always share one ICR
register": ICRn sets the level of vectors 11 + 2n and 12 + 2n (ICR00 = CAN0 RX and CAN0
TX/NS, ICR13 = UART0 RX and UART0 TX). So two vectors of one ICR have one level, and CAN0's
transmission complete and node status transition are one vector (#12) with one handler, which
serves one cause an entry (a TCR bit, then CSR.NT). :func:`check_plan` refuses a plan the part
cannot hold.

Levels are the firmware's choice (0 highest; 7 would disable the source), by deadline: a
received UART byte must be read within one byte time (1.04 ms at "9600") or the next is lost,
and UART0's transmission shares its ICR; the End's timer channel lowers TXEN within half a bit
of the End; the MAC's timers decide when this robot transmits (to the tick, docs/protocol.md);
the CAN handlers have a frame time (>= 47 bits, 94 us at 500 kbit/s) per buffer; TMR1 runs the
dispatcher's deadlines, tens of milliseconds. Requests of one level go the lower number first.
Which resource serves the End's timer and the receive watch is the firmware's choice too: the
I/O timer's output compares 0 and 1 (the reload timers serve the MAC and the dispatcher).
"""
from __future__ import annotations

from .mcu.cpu import Vector

FIRST_ICR_VECTOR, LAST_ICR_VECTOR = 11, 42
"""The resource vectors that an ICR governs: ICR00 (11, 12) to ICR15 (41, 42)."""


def icr_of(number: int) -> int:
    """The ICR (0-15) that sets the level of resource vector ``number`` (11-42)."""
    if not FIRST_ICR_VECTOR <= number <= LAST_ICR_VECTOR:
        raise ValueError(f"vector {number} is no resource interrupt of the MB90540/545 "
                         f"series ({FIRST_ICR_VECTOR}-{LAST_ICR_VECTOR})")
    return (number - FIRST_ICR_VECTOR) // 2


CAN0_RX = Vector("CAN0 RX", level=4, number=11)
CAN0_TX_NS = Vector("CAN0 TX/NS", level=4, number=12)
"""Transmission complete (TCR) and node status transition (CSR.NT): one vector."""
TMR0 = Vector("TMR0 MAC", level=3, number=17)
"""16-bit reload timer 0: the MAC's timer (Ttrans, Tmax, the stagger)."""
TX_END = Vector("TX END", level=2, number=32)
"""Output compare 0, armed by the transmit handler for the End's stop bit (the UART has no
transmission-complete interrupt): TXEN must drop within half a bit of the End."""
RXWATCH = Vector("RXWATCH", level=3, number=33)
"""Output compare 1: the receive watch (a frame's bytes stopped for the stall gap)."""
TMR1 = Vector("TMR1", level=5, number=36)
"""16-bit reload timer 1: the dispatcher's deadlines and the CAN supervision."""
UART0_RX = Vector("UART0 RX", level=1, number=37)
UART0_TX = Vector("UART0 TX", level=1, number=38)
"""TDRE: SODR is empty, the next byte must be written within a byte time or the frame gets a
gap. ICR13 with UART0 RX: the same level, and reception first (the lower number)."""

ALL = (UART0_RX, UART0_TX, TX_END, TMR0, RXWATCH, CAN0_RX, CAN0_TX_NS, TMR1)


def check_plan(vectors: tuple[Vector, ...]) -> None:
    """ValueError unless each vector is a resource vector of the part, none twice, and the
    vectors of one ICR have one level."""
    seen: dict[int, Vector] = {}
    for v in vectors:
        icr = icr_of(v.number)
        other = seen.get(icr)
        if other is not None and other.number == v.number:
            raise ValueError(f"{v.name} and {other.name} are both vector {v.number}")
        if other is not None and other.level != v.level:
            raise ValueError(f"{v.name} (vector {v.number}) and {other.name} (vector "
                             f"{other.number}) share ICR{icr:02d}: one level, not {v.level} "
                             f"and {other.level}")
        seen[icr] = v


check_plan(ALL)

DISPATCH_TASK = "main loop"
"""The main loop's work: parsing a delivered message and planning its motion."""
AUTH_TASK = "auth_tag"
"""The main loop's SHA-256 work on a frame's tag (the authenticated profile)."""

COSTED_BY: dict[str, tuple[str, ...]] = {
    UART0_RX.name: ("uart_rx_byte", "mac_frame"),
    UART0_TX.name: ("uart_tx_byte",),
    TX_END.name: ("uart_tx_done",),
    TMR0.name: ("mac_timer",),
    RXWATCH.name: ("mac_timer",),
    CAN0_RX.name: ("can_rx",),
    CAN0_TX_NS.name: ("can_tx", "can_status"),
    TMR1.name: ("dispatcher_timer",),
    DISPATCH_TASK: ("content_byte", "command", "can_frame_out", "f_add", "f_mul", "f_div",
                    "f_sin", "f_cos", "f_atan2", "f_acos", "f_hypot", "f_round", "mul16",
                    "div32"),
    AUTH_TASK: ("sha256_block",),
}
"""Each handler's (and main-loop task's) rows of the cycle-cost table (cycle_costs.py), besides
``entry`` and ``reti``: ``mac_frame`` is UART0 RX's at a frame's End byte; CAN0 TX/NS costs
``can_tx`` for a finished transmission and ``can_status`` for a node status transition."""
VECTORS = {v.name: v for v in ALL}
"""Each handler's vector, by its name."""

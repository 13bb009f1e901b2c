"""The child firmware's interrupt map: the ICR level the firmware gives each source it uses.

Levels are the firmware's choice (0 highest; 7 would disable the source). The order follows
the deadlines: a received UART byte must be read within one byte time (1.04 ms at "9600") or
the next one is lost, so UART0 reception comes first; the MAC's timers decide when this robot
transmits (to the tick, docs/protocol.md); the CAN handlers have a frame time (>= 47 bits,
94 us at 500 kbit/s) per buffer; TMR1 runs the dispatcher's deadlines, which are in tens of
milliseconds. Interrupt numbers only order requests of one level (the lower first); they
follow the MB90F549's peripheral order as the model lists it, and are not the part's vector
numbers, which this model does not need.
"""
from __future__ import annotations

from .mcu.cpu import Vector

UART0_RX = Vector("UART0 RX", level=1, number=1)
TX_END = Vector("TX END", level=2, number=0)
"""The timer channel the transmit handler arms for the End's stop bit (the UART has no
transmission-complete interrupt): TXEN must drop within half a bit of the End, so it goes
first among level 2."""
TMR0 = Vector("TMR0 MAC", level=2, number=2)
RXWATCH = Vector("RXWATCH", level=2, number=3)
UART0_TX = Vector("UART0 TX", level=3, number=4)
"""TDRE: SODR is empty, the next byte must be written within a byte time or the frame gets a
gap."""
CAN_RX = Vector("CAN RX", level=4, number=5)
CAN_TX = Vector("CAN TX", level=4, number=6)
CAN_STATUS = Vector("CAN status", level=4, number=7)
TMR1 = Vector("TMR1", level=5, number=8)

ALL = (UART0_RX, TX_END, TMR0, RXWATCH, UART0_TX, CAN_RX, CAN_TX, CAN_STATUS, TMR1)

DISPATCH_TASK = "main loop"
"""The main loop's work: parsing a delivered message and planning its motion."""

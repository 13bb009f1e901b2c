"""PTR2000 (nRF401-based) 433 MHz half-duplex radio module, as the RPRS robots wire it.

TXEN high: the module switches to transmit, which takes Ttrans (5 ms); bytes the UART sends
before then never reach the air. TXEN low: it switches back and hears the air again Ttrans
later. While transmitting or switching it is deaf. With nobody transmitting, a real module
outputs random bytes; the channel model decides what the receiver hears (hil.sim.air). A dead
module (``alive = False``, fault injection) neither sends nor hears.
"""
from __future__ import annotations

from typing import Any

from ..timing import TTRANS_TICKS

NEVER = 1 << 62


class Ptr2000:
    """One radio module. ``channel`` is the air (set by the world); ``uart`` receives bytes."""

    __slots__ = ("robot", "ttrans", "txen", "tx_ready", "rx_from", "alive", "channel", "uart",
                 "rx", "noise_from", "lost_tx", "idx")

    def __init__(self, robot: int, ttrans: int = TTRANS_TICKS) -> None:
        self.robot = robot
        self.ttrans = ttrans
        self.txen = False
        self.tx_ready = NEVER
        self.rx_from = 0
        self.alive = True
        self.channel: Any = None
        self.uart: Any = None
        self.rx: Any = None          # the reception in progress (owned by the channel)
        self.noise_from = 0          # idle noise generated up to this tick (channel bookkeeping)
        self.lost_tx = 0             # bursts sent before Ttrans elapsed or with TXEN low
        self.idx = 0

    def set_txen(self, level: bool, now: int) -> None:
        """The TXEN pin changed (wired to the MCU's GPIO)."""
        level = bool(level)
        if level == self.txen:
            return
        if level:
            if self.channel is not None:
                self.channel.deafen(self, now)     # takes what was heard up to now first
            self.txen = True
            self.tx_ready = now + self.ttrans
            self.rx_from = NEVER
        else:
            self.txen = False
            self.tx_ready = NEVER
            self.rx_from = now + self.ttrans
            if self.channel is not None:
                off = getattr(self.channel, "carrier_off", None)
                if off is not None:
                    off(self, now)
                self.channel.rx_restart(self, self.rx_from)

    def listening(self, t: int) -> bool:
        """True when the module hears the air at tick ``t``."""
        return self.alive and t >= self.rx_from

    # -- the UART side ---------------------------------------------------------------------

    def transmit(self, data: bytes, t0: int, byte_ticks: int) -> None:
        if not self.txen or t0 < self.tx_ready:
            self.lost_tx += 1
            return
        if self.alive and self.channel is not None:
            self.channel.transmit(self, data, t0, byte_ticks)

    def pause(self, now: int) -> None:
        """The UART ran dry mid-frame at ``now``: the burst on air stops (a gap follows)."""
        if self.channel is not None and self.txen:
            pause = getattr(self.channel, "pause", None)
            if pause is not None:
                pause(self, now)

    def sync(self, now: int) -> None:
        if self.channel is not None:
            self.channel.sync(self, now)

    def rx_started(self, now: int) -> int | None:
        """Start tick of a byte this module is putting out on its data pin right now, if any
        (the air knows; a channel without that knowledge says None)."""
        ch = self.channel
        query = getattr(ch, "rx_started", None)
        return query(self, now) if query is not None else None

    def deliver(self, data: bytes, t0: int, dt: int) -> None:
        """Bytes heard from the air (called by the channel)."""
        if self.uart is not None:
            self.uart.receive(data, t0, dt)

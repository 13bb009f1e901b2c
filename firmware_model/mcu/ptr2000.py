"""PTR2000 (nRF401-based) 433 MHz half-duplex radio module, as the RPRS robots wire it.

TXEN high: the module switches to transmit, which takes its TX-ready delay (``tx_ready_delay``,
1 ms on the part); bytes the UART sends before then never reach the air. TXEN low: it switches
back and hears the air again its RX-ready delay later (``rx_ready_delay``, 3 ms on the part).
While transmitting or switching it is deaf. Both delays are the part's, from the nRF401 product
specification (the PTR2000's radio chip), Table 5 "Switching times for nRF401" and "Switching
TX <-> RX", Figure 4 (firmware_model/timing.py PTR2000_TX_READY_TICKS, PTR2000_RX_READY_TICKS),
and can be set per module. They are not the protocol's Ttrans (5 ms), the guard the MAC waits
between TXEN and its first byte and between a frame's End and the next Header: the hand-over
margin is Ttrans less these, 2 ms on the part for the previous sender to hear the next Header.
With nobody transmitting, a real module outputs random bytes; the channel model decides what
the receiver hears (hil.sim.air). A dead module (``alive = False``, fault injection) neither
sends nor hears.
"""
from __future__ import annotations

from typing import Any

from ..timing import PTR2000_RX_READY_TICKS, PTR2000_TX_READY_TICKS

NEVER = 1 << 62


class Ptr2000:
    """One radio module. ``channel`` is the air (set by the world); ``uart`` receives bytes."""

    __slots__ = ("robot", "tx_ready_delay", "rx_ready_delay", "txen", "tx_ready", "rx_from",
                 "alive", "channel", "uart", "rx", "noise_from", "lost_tx", "idx")

    def __init__(self, robot: int, tx_ready_delay: int = PTR2000_TX_READY_TICKS,
                 rx_ready_delay: int = PTR2000_RX_READY_TICKS) -> None:
        if tx_ready_delay < 0 or rx_ready_delay < 0:
            raise ValueError(f"PTR2000 switch times must be >= 0 ticks, got TX-ready "
                             f"{tx_ready_delay} and RX-ready {rx_ready_delay}")
        self.robot = robot
        self.tx_ready_delay = tx_ready_delay   # TXEN high to the first bit it sends (ticks)
        self.rx_ready_delay = rx_ready_delay   # TXEN low to the first bit it hears (ticks)
        self.txen = False
        self.tx_ready = NEVER
        self.rx_from = 0
        self.alive = True
        self.channel: Any = None
        self.uart: Any = None
        self.rx: Any = None          # the reception in progress (owned by the channel)
        self.noise_from = 0          # idle noise generated up to this tick (channel bookkeeping)
        self.lost_tx = 0             # bursts sent before the TX-ready delay or with TXEN low
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
            self.tx_ready = now + self.tx_ready_delay
            self.rx_from = NEVER
        else:
            self.txen = False
            self.tx_ready = NEVER
            self.rx_from = now + self.rx_ready_delay
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

    def rx_fall(self, after: int, now: int) -> int | None:
        """First falling edge in ticks (``after``, ``now``] on this module's data pin, inside
        the byte it is putting out at ``now`` (the air knows; a channel without that
        knowledge says None)."""
        query = getattr(self.channel, "rx_fall", None)
        return query(self, after, now) if query is not None else None

    def deliver(self, data: bytes, t0: int, dt: int, late_ok: bool = False,
                lead: int = 0) -> None:
        """Bytes heard from the air (called by the channel; ``late_ok``, ``lead``:
        Uart.receive's)."""
        if self.uart is not None:
            if late_ok or lead:
                self.uart.receive(data, t0, dt, late_ok, lead)
            else:
                self.uart.receive(data, t0, dt)

    def late_until(self, now: int) -> int | None:
        """The tick by which the bytes of the reception under way that may still come late
        have all completed, if any (hil/sim/air.py, ``Reception.quiet``), else None."""
        query = getattr(self.channel, "late_until", None)
        return query(self, now) if query is not None else None

    def late_around(self, now: int) -> tuple[int | None, int | None]:
        """The ticks the bytes that may come late are handed over (their RDRF) around
        ``now``: the last by ``now``, the next after it (hil/sim/air.py,
        ``Reception.quiet``)."""
        query = getattr(self.channel, "late_around", None)
        return query(self, now) if query is not None else (None, None)

    def on_time(self, now: int) -> None:
        """The bytes still to come each at its tick (the CPU has work: Uart._cpu_touched)."""
        on_time = getattr(self.channel, "on_time", None)
        if on_time is not None:
            on_time(self, now)

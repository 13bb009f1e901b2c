"""MB90F549 UART (UART0, asynchronous 8N1) with its dedicated baud-rate generator.

At a 16 MHz machine clock the generator gives 9615.38 bit/s for "9600": 1664 ticks a bit,
16640 ticks a byte (start + 8 data + stop). The firmware's transmit ISR reloads the data register
while the previous byte shifts out, so a frame leaves back to back with no idle bits between
bytes; the model therefore hands the transmitter a whole burst and raises the
transmission-complete interrupt when the last stop bit ends. Received bytes arrive from the
radio with the tick at which each stop bit ended.

With a CPU model attached (``attach_cpu``), reception is what the part does: each byte's stop
bit sets RDRF and requests the receive interrupt; the handler reads the byte (clearing RDRF)
when its entry sequence ends. A byte whose stop bit ends while RDRF is still set is an
overrun: SSR.ORE is set and the byte is lost (MB90F549 UART, "reception": the data register
is not overwritten). Without a CPU model the bytes go to ``on_rx`` as they come, in bursts.
"""
from __future__ import annotations

from typing import Callable, Protocol

from ..timing import BITS_PER_BYTE_8N1, TICK_HZ
from .scheduler import Scheduler

BAUD_DIVISORS = {1200: 13312, 2400: 6656, 4800: 3328, 9600: 1664, 19200: 832, 38400: 416}
"""Nominal baud -> ticks a bit (16 x the dedicated generator's count at 16 MHz)."""


class SerialLine(Protocol):
    """What the UART's TX pin drives (the PTR2000's data input)."""

    def transmit(self, data: bytes, t0: int, byte_ticks: int) -> None: ...

    def sync(self, now: int) -> None: ...

    def rx_started(self, now: int) -> int | None: ...


class Uart:
    """One UART channel. Set ``line`` (TX side), ``on_rx`` and ``on_tx_done`` before use."""

    __slots__ = ("sched", "bit_ticks", "byte_ticks", "line", "on_rx", "on_tx_done",
                 "busy_until", "bytes_sent", "bytes_received", "name", "cpu", "rx_vector",
                 "rx_cycles", "tx_vector", "tx_cycles", "rdr", "overruns", "_read")

    def __init__(self, sched: Scheduler, baud: int = 9600, byte_ticks: int | None = None,
                 name: str = "UART0") -> None:
        self.sched = sched
        self.name = name
        if byte_ticks is None:
            if baud not in BAUD_DIVISORS:
                raise ValueError(f"the MB90F549 baud generator has no {baud} baud setting; "
                                 f"choose one of {sorted(BAUD_DIVISORS)}")
            self.bit_ticks = BAUD_DIVISORS[baud]
            byte_ticks = self.bit_ticks * BITS_PER_BYTE_8N1
        else:
            self.bit_ticks = byte_ticks / BITS_PER_BYTE_8N1
        self.byte_ticks = byte_ticks
        self.line: SerialLine | None = None
        self.on_rx: Callable[[bytes, int, int], None] | None = None
        self.on_tx_done: Callable[[int], None] | None = None
        self.busy_until = 0
        self.bytes_sent = 0
        self.bytes_received = 0
        self.cpu = None
        self.rx_vector = self.tx_vector = None
        self.rx_cycles = self.tx_cycles = 0
        self.rdr: list[tuple[int, int]] = []   # (byte, stop-bit tick); RDRF while non-empty
        self.overruns = 0
        self._read: list[tuple[int, int]] = []

    def attach_cpu(self, cpu, rx_vector, rx_cycles: int, tx_vector, tx_cycles: int) -> None:
        """Run the receive and transmission-complete handlers on ``cpu`` (mcu/cpu.py), with
        bodies of ``rx_cycles`` a byte and ``tx_cycles``."""
        self.cpu = cpu
        self.rx_vector, self.rx_cycles = rx_vector, rx_cycles
        self.tx_vector, self.tx_cycles = tx_vector, tx_cycles

    @property
    def baud(self) -> float:
        """The real bit rate (bit/s)."""
        return TICK_HZ / self.bit_ticks

    def send(self, data: bytes) -> int:
        """Shift ``data`` out from now; returns the tick the last stop bit ends."""
        now = self.sched.now
        if now < self.busy_until:
            raise RuntimeError(f"{self.name}: transmitter busy until tick {self.busy_until}")
        end = now + len(data) * self.byte_ticks
        self.busy_until = end
        self.bytes_sent += len(data)
        if self.line is not None:
            self.line.transmit(data, now, self.byte_ticks)
        self.sched.at(end, self._tx_complete, end)
        return end

    def _tx_complete(self, end: int) -> None:
        if self.on_tx_done is None:
            return
        if self.cpu is None:
            self.on_tx_done(end)
        else:
            # the handler's first act is the MAC's end-of-frame rule (TXEN low): the radio
            # must be back on receive Ttrans after the End, when the next sender may begin
            done = self.on_tx_done
            self.cpu.irq(self.tx_vector, self.tx_cycles, _nothing, enter=lambda: done(end))

    def receive(self, data: bytes, t0: int, dt: int) -> None:
        """Bytes from the line: byte i's stop bit ended at tick ``t0 + i * dt``."""
        self.bytes_received += len(data)
        if self.on_rx is None:
            return
        if self.cpu is None:
            self.on_rx(data, t0, dt)
            return
        now = self.sched.now
        for i, b in enumerate(data):
            t = t0 + i * dt
            if self.rdr and t >= now:
                # RDRF still set when this stop bit ends: ORE, the byte is lost. (A byte the
                # line hands over late, idle noise delivered in a burst, cannot be judged.)
                self.overruns += 1
                continue
            self.rdr.append((b, t))     # more than one only for bytes handed over late
            self.cpu.irq(self.rx_vector, self.rx_cycles, self._rx_isr, dt,
                         enter=self._take_rdr)

    def _take_rdr(self) -> None:
        """The receive handler reads SIDR: RDRF clears, the next byte may come."""
        if self.rdr:
            self._read.append(self.rdr.pop(0))

    def _rx_isr(self, dt: int) -> None:
        if self._read and self.on_rx is not None:
            b, t = self._read.pop(0)
            self.on_rx(bytes((b,)), t, dt)

    def sync(self, now: int) -> None:
        """Take every byte whose stop bit ended by ``now`` (before a timer ISR reads state)."""
        if self.line is not None:
            self.line.sync(now)

    def rx_started(self, now: int) -> int | None:
        """Tick at which the start bit of a byte still being received began, else None.

        The firmware sees it as the falling edge on SIN0 (wired to an external-interrupt pin
        as well), before the byte is complete; a line that cannot tell returns None."""
        query = getattr(self.line, "rx_started", None)
        return query(now) if query is not None else None


def _nothing() -> None:
    """The rest of a handler whose effects all happen on entry."""


def sample_byte(value: int, tx_bt: int, rx_bt: int,
                following: int | None = None) -> tuple[int, bool, bool]:
    """What an 8N1 UART whose byte time is ``rx_bt`` ticks makes of ``value`` sent at
    ``tx_bt`` ticks a byte (``following``: the byte sent right after it, if any).

    The receiver starts at the start bit's falling edge and samples each of its ten bits in
    the middle of its own bit time: sample m at (m + 1/2) x rx_bt/10. Each sample reads the
    sender's bit cell it falls in (start 0, data LSB first, stop 1; then the next byte's start
    bit and bits, or the idle line). Returns (the byte read, framing error: the stop-bit sample
    read 0, ready: the receiver was waiting again by the next byte's start edge, at its
    stop-bit sample). At equal rates every sample is mid-cell; the byte survives a rate
    difference up to about 5 % (half a bit over 9.5 bits) whatever its value, and beyond that
    depending on its bits."""
    bits = [0] + [(value >> i) & 1 for i in range(8)] + [1]
    nxt = None if following is None else [0] + [(following >> i) & 1 for i in range(8)] + [1]

    def level(m: int) -> int:
        cell = (2 * m + 1) * rx_bt // (2 * tx_bt)      # the sender's bit the sample falls in
        if cell <= 9:
            return bits[cell]
        if nxt is None or cell >= 20:
            return 1                                   # the idle line
        return nxt[cell - 10]

    got = 0
    for m in range(1, 9):
        got |= level(m) << (m - 1)
    framing = level(0) != 0 or level(9) == 0
    ready = following is None or 19 * rx_bt <= 20 * tx_bt
    return got, framing, ready


def rates_agree(tx_bt: int, rx_bt: int) -> bool:
    """True when every byte sent at ``tx_bt`` ticks is read unchanged at ``rx_bt``: each
    sample falls in its own bit cell and the receiver is ready for the next start edge."""
    return all((2 * m + 1) * rx_bt // (2 * tx_bt) == m for m in range(10)) and \
        19 * rx_bt <= 20 * tx_bt

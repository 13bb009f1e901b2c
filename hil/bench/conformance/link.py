"""The kit's radio and clock (the :class:`TesterLink` seam, a serial port on the wall clock),
and the protocol's times in ticks as the kit uses them (the real-time margin set)."""
from __future__ import annotations

import select
import time
from typing import Protocol

from firmware_model.timing import PC_BYTE_TICKS, TICK_HZ

from ..runner import REALTIME_MARGINS
from ..serial_radio import TXEN_LINES, PortError, open_port, txen_low

MS = TICK_HZ // 1000
TTRANS = 5 * MS
TMAX = 600 * MS
TWIN = REALTIME_MARGINS["twin"]
TSLOT = REALTIME_MARGINS["tslot"]
QUIET_GAP = REALTIME_MARGINS["quiet_gap"]
BYTE = PC_BYTE_TICKS
MISS_LIMIT = 3
INVITE_EVERY = 4
"""P: a member invites an absent team robot of its gap in every P-th of its turns
(docs/protocol.md clause 5's table, clause 32)."""
POLL_WAIT = 3 * TICK_HZ // 10_000
"""How long the kit idles between looks at the air while it waits for a frame (0.3 ms)."""
POLL_SEND = 2 * TICK_HZ // 10_000
"""... and while it waits for the tick to send at (0.2 ms)."""


class TesterLink(Protocol):
    """The kit's radio and clock: the one seam between the scripted station and the world
    it runs in. :class:`SerialLink` is a serial port (or a radio-hub pty) on the wall clock,
    what ``rprs conformance`` uses; ``hil.bench.conformance_sim.SimLink`` is a station on the
    simulator's air, the robot under test a firmware model, in simulated time."""

    def now(self) -> int:
        """The tick now (16 MHz), counted from the link's start."""
        ...

    def read(self) -> list[tuple[bytes, int, int]]:
        """What was heard since the last read, as runs of back-to-back bytes: (bytes, the
        tick the first one was complete, ticks a byte)."""
        ...

    def write(self, data: bytes) -> int:
        """Put ``data`` on air now at the PC's byte time; the tick its first bit goes out."""
        ...

    def idle(self, ticks: int) -> None:
        """Let up to ``ticks`` pass (the wall clock waits, and may return early when a byte
        comes; a simulated world runs on): callers poll, and look at :meth:`now`."""
        ...

    def close(self) -> None:
        ...


class SerialLink:
    """The kit on serial port ``port`` and the wall clock: bytes are stamped when this PC
    reads them (the last one now, those before it a byte time apart). Reading never waits
    (a read that waited for a byte held the kit past the instant its turn was due, by up to
    the port's 50 ms timeout); :meth:`idle` waits for the time given or the next byte,
    whichever comes first, so bytes are read, and stamped, as they come."""

    lead = 0
    """Ticks before a frame's first bit that :meth:`write` must be called: Ttrans with a TXEN
    line (the radio is keyed then), else 0 (a self-switching module, the pty hub)."""

    def __init__(self, port: str, txen: str = "none") -> None:
        self.port = open_port(port)
        self.txen = txen
        if txen != "none":
            if txen not in TXEN_LINES:
                raise PortError(f"TXEN line must be one of {', '.join(TXEN_LINES)}, got "
                                f"{txen!r}")
            try:
                txen_low(self.port, txen)
            except PortError:
                self.port.close()
                raise
            self.lead = TTRANS
        self.t0 = time.monotonic_ns()
        try:
            self._fd: int | None = self.port.fileno()
        except (AttributeError, OSError, ValueError):   # a port with no descriptor (a URL's)
            self._fd = None

    def now(self) -> int:
        return (time.monotonic_ns() - self.t0) * TICK_HZ // 1_000_000_000

    def read(self) -> list[tuple[bytes, int, int]]:
        waiting = self.port.in_waiting
        if not waiting:
            return []
        data = self.port.read(waiting)
        if not data:
            return []
        return [(data, self.now() - (len(data) - 1) * BYTE, BYTE)]

    def write(self, data: bytes) -> int:
        """Put ``data`` on air; the tick its first bit goes out. With a TXEN line: the line
        up now, the bytes Ttrans later (the radio's switch, docs/protocol.md clause 23), the
        line down once they have left the UART (the kit is deaf meanwhile, as its radio)."""
        if self.txen == "none":
            start = self.now()
            self.port.write(data)
            return start
        setattr(self.port, self.txen, True)
        due = self.now() + TTRANS
        while self.now() < due:
            time.sleep(max(0, due - self.now()) / TICK_HZ)
        start = self.now()
        try:
            self.port.write(data)
            self.port.flush()                 # every byte out of the UART, then the line down
        finally:
            setattr(self.port, self.txen, False)
        return start

    def idle(self, ticks: int) -> None:
        if self._fd is None:
            time.sleep(ticks / TICK_HZ)
        else:
            select.select([self._fd], [], [], ticks / TICK_HZ)

    def close(self) -> None:
        if self.txen != "none":
            try:
                setattr(self.port, self.txen, False)
            except (OSError, ValueError):
                pass
        self.port.close()

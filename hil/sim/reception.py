"""What one radio hears of one transmission on the virtual air (hil/sim/air.py): the radio's
side of the air (``AirRadio``), a transmission on air, a reception and its delivery to the
radio's UART, a seeded stream of random bytes (garbage, noise), and where a UART that starts
listening in the middle of a transmission picks it up. Ticks throughout (16 MHz)."""
from __future__ import annotations

import random
from typing import Any, Callable, Protocol

from firmware_model.mcu.ptr2000 import Ptr2000
from firmware_model.mcu.uart import Uart


class AirRadio(Protocol):
    """What the air drives of a radio: a PTR2000 model (``firmware_model.mcu.ptr2000``), the
    hub's pty node, the conformance kit's tester. The air owns ``idx``, ``rx``,
    ``noise_from`` and ``rx_from``; ``uart.byte_ticks`` is the radio's byte time (ticks)."""

    robot: int
    idx: int
    alive: bool
    rx_from: int
    rx: Any
    noise_from: int
    uart: Any
    channel: Any

    def listening(self, t: int) -> bool: ...

    def deliver(self, data: bytes, t0: int, dt: int, late_ok: bool = False,
                lead: int = 0) -> None:
        """Bytes heard, byte i dated ``t0 + i * dt`` (its stop bit's end), handed over
        ``lead`` ticks before that (``late_ok``, ``lead``: for a CPU model's UART,
        Uart.receive; never for a radio without one)."""


class ByteStream:
    """A seeded source of random bytes, consumed in order whatever the request sizes."""

    __slots__ = ("rng", "buf", "pos", "last")

    def __init__(self, rng: random.Random) -> None:
        self.rng = rng
        self.buf = b""
        self.pos = 0
        self.last = 0
        """The last byte taken (a byte handed over at its RDRF, its stop bit still on air)."""

    def _fill(self, n: int) -> None:
        if len(self.buf) - self.pos < n:
            need = max(4096, n)
            self.buf = self.buf[self.pos:] + self.rng.randbytes(need)
            self.pos = 0

    def peek(self, n: int) -> bytes:
        self._fill(n)
        return self.buf[self.pos:self.pos + n]

    def take(self, n: int) -> bytes:
        self._fill(n)
        out = self.buf[self.pos:self.pos + n]
        self.pos += n
        if n:
            self.last = out[-1]
        return out


class Transmission:
    """One burst on air from ``radio``: byte i occupies [t0 + i*bt, t0 + (i+1)*bt)."""

    __slots__ = ("radio", "data", "t0", "bt", "end", "collided", "aborted", "n", "paused",
                 "continued")

    def __init__(self, radio: AirRadio, data: bytes, t0: int, bt: int) -> None:
        self.radio = radio
        self.data = data
        self.t0 = t0
        self.bt = bt
        self.n = len(data)
        self.end = t0 + len(data) * bt
        self.collided = False
        self.aborted = False
        """Cut short: its sender's radio died, or (``paused``) its UART ran dry mid-frame."""
        self.paused = False
        """Cut by a pause, not a death: the sender's transmit handler was late, its carrier
        stays on and the frame goes on in the sender's next transmission (``continued``)."""
        self.continued = False
        """The rest of a paused frame."""


class Reception:
    """Bytes one radio hears, byte i complete at ``t0 + (i+1)*bt`` and handed over ``lead``
    ticks before (its receiver's RDRF, at the stop bit's sample: Uart.rx_lead); ``pos``
    delivered so far.

    ``data`` is None for collision garbage (drawn from the radio's garbage stream)."""

    __slots__ = ("data", "t0", "bt", "pos", "n", "tx", "stream", "holes", "quiet", "lazy",
                 "lead", "seq")
    NOT_STATE = ("seq",)
    """The scheduler's sequence number is its bookkeeping, not the reception's state
    (hil/sim/state_walk.py)."""

    def __init__(self, data: bytes | None, t0: int, bt: int, n: int,
                 tx: Transmission | None = None, stream: ByteStream | None = None,
                 holes: frozenset[int] | None = None, quiet: int = 0, lead: int = 0) -> None:
        self.data = data
        self.t0 = t0
        self.bt = bt
        self.lead = lead
        self.seq: int | None = None
        """The scheduler's sequence number reserved when the reception began, for its bytes
        that may yet come one by one (:meth:`at_byte_place`), or None."""
        self.pos = 0
        self.n = n
        self.tx = tx
        self.stream = stream
        self.holes = holes            # byte indices the receiver's UART lost (overrun)
        self.quiet = quiet
        """Bytes before this index are received as sent and the receiver's CPU model had
        nothing to do since the reception began: they may be handed over late (``late_ok``,
        Uart.receive). ``Air.on_time`` ends that while the CPU has work."""
        self.lazy = quiet
        """The clean prefix's end: how far ``quiet`` may reach again once the CPU is idle."""


    def at_byte_place(self, sched: Any, when: int, fn: Callable[..., Any], *args: Any) -> None:
        """``fn(*args)`` at ``when``, in the place the frame-by-frame run's byte events have
        among the events of that tick (``seq``: scheduled as the reception began): one
        byte's receivers in the radios' order, not in the order their CPUs were first asked
        for something (hil/sim/air.py ``Air.on_time``)."""
        if self.seq is None:
            sched.at(when, fn, *args)
        else:
            sched.at_seq(when, self.seq, fn, *args)
    def flush(self, radio: AirRadio, now: int) -> None:
        """Deliver every byte handed over by ``now`` (its stop bit ended, less ``lead``)."""
        pos = self.pos
        lead = self.lead
        k = (now + lead - self.t0) // self.bt
        if k > self.n:
            k = self.n
        if k > pos:
            self.pos = k
            if self.data is not None:
                data = self.data[pos:k]
            else:
                assert self.stream is not None      # (garbage comes with its stream)
                data = self.stream.take(k - pos)
            holes = self.holes
            if holes is None:
                q = self.quiet
                if q > pos:                   # a clean prefix, the CPU idle: late is fine
                    m = q if q < k else k
                    radio.deliver(data[:m - pos], self.t0 + (pos + 1) * self.bt, self.bt,
                                  True, lead)
                    if k > m:
                        self._give(radio, data[m - pos:], m)
                    return
                self._give(radio, data, pos)
                return
            start = None                      # deliver the runs between lost bytes
            for i in range(pos, k + 1):
                if i < k and i not in holes:
                    if start is None:
                        start = i
                elif start is not None:
                    self._give(radio, data[start - pos:i - pos], start)
                    start = None

    def _give(self, radio: AirRadio, data: bytes, i: int) -> None:
        """Hand over ``data``, from byte ``i`` on, at their ticks."""
        if self.lead:
            radio.deliver(data, self.t0 + (i + 1) * self.bt, self.bt, False, self.lead)
        else:
            radio.deliver(data, self.t0 + (i + 1) * self.bt, self.bt)

    @property
    def last_at(self) -> int:
        """The tick the last byte is handed over (its stop bit's end, less ``lead``)."""
        return self.t0 + self.n * self.bt - self.lead

    def late_until(self) -> int | None:
        """The tick the last byte that may still come late completes, or None (Air)."""
        if self.quiet <= self.pos:
            return None
        return self.t0 + min(self.quiet, self.n - 1) * self.bt - self.lead

    def around(self, now: int) -> tuple[int | None, int | None]:
        """The hand-over tick (each byte's stop bit's end less ``lead``) of the last byte due
        by ``now`` not handed over yet, and of the next byte that may come late after it,
        each None if none (Air.late_around)."""
        k = min((now + self.lead - self.t0) // self.bt, self.n)   # bytes due by now (flush)
        last = self.t0 + k * self.bt - self.lead if k > self.pos else None
        i = max(k, self.pos)
        nxt = self.t0 + (i + 1) * self.bt - self.lead if i < min(self.quiet, self.n) else None
        return last, nxt

    def finish(self, radio: AirRadio) -> None:
        """Deliver every byte not delivered yet, the last one due now: ``flush`` at
        ``last_at``, in one hand-over of the whole ``data`` when no byte went before and none
        was lost (most receptions)."""
        if self.pos == 0 and self.holes is None and self.data is not None and \
                self.quiet in (0, self.n):
            self.pos = self.n
            if self.quiet:
                radio.deliver(self.data, self.t0 + self.bt, self.bt, True, self.lead)
            elif self.lead:
                radio.deliver(self.data, self.t0 + self.bt, self.bt, False, self.lead)
            else:
                radio.deliver(self.data, self.t0 + self.bt, self.bt)
        else:
            self.flush(radio, self.last_at)


def first_byte_heard(t0: int, bt: int, when: int, rx_bt: int) -> int:
    """Index of the first byte a UART that starts listening at ``when`` decodes, of bytes
    sent back to back from ``t0``, ``bt`` ticks each (8N1, 10 bits).

    The UART takes the line's first low level as a start-bit edge and samples each bit in
    the middle of its own bit time (``rx_bt / 10``) from there. A byte already under way is
    decoded if every sample still falls inside its bit cell: for bit m (start 0 .. stop 9),
    ``t0 + m*B < when + (m + 1/2)*Brx < t0 + (m+1)*B``. Joining a little late in a start
    bit (less than half a bit at equal rates) still gets the byte; later, the model takes the
    next whole byte (the resynchronisation a UART finds after a framing error)."""
    k = (when - t0) // bt                 # the byte under way at ``when``
    s = t0 + k * bt
    if s == when:
        return k
    d = when - s
    for m in range(10):
        # everything times 20 to stay in integers: bit cell [m*bt*2, (m+1)*bt*2) of 20*...
        sample = 20 * d + (2 * m + 1) * rx_bt
        if not (2 * m * bt <= sample < 2 * (m + 1) * bt):
            return k + 1
    return k


def flush_ends(ends: list) -> None:
    """``(tick, radio, reception)`` of one transmission's receivers, their last bytes each at
    its RDRF (one tick for all: every receiver's RDRF leads its stop bit alike), in radio
    order: what an event each, scheduled one after the other with nothing between them, does
    (hil/sim/air.py, ``Air.ends_together``)."""
    for t, r, rx in ends:
        if r.rx is rx:
            rx.flush(r, t)


def hand_over_end(tx: Transmission, radios: list,
                  idle_from: Callable[[Any, int], None] | None) -> None:
    """``tx`` ended without a collision: each radio receiving it gets the rest of it
    (``Reception.finish``) and hears the air idle from its end (``idle_from``: the air's, with
    idle noise; else only ``noise_from`` moves on). A whole clean reception to a PTR2000 whose
    UART has no CPU model (the ideal CPU) goes straight to the firmware's ``on_rx``, as
    ``finish`` -> ``Ptr2000.deliver`` -> ``Uart.receive`` would give it (docs/fast-paths.md,
    "The air's direct hand-over")."""
    now = tx.end
    for r in radios:
        rx = r.rx
        if rx is not None and rx.tx is tx:
            data = rx.data
            u = r.uart if type(r) is Ptr2000 else None
            if not rx.pos and not rx.quiet and not rx.lead and rx.holes is None and \
                    data is not None and type(u) is Uart and u.cpu is None:
                rx.pos = rx.n
                u.bytes_received += len(data)
                if u.on_rx is not None:
                    u.on_rx(data, rx.t0 + rx.bt, rx.bt)
            else:
                rx.finish(r)
            r.rx = None
            if idle_from is not None:
                idle_from(r, now)
            elif now > r.noise_from:
                r.noise_from = now

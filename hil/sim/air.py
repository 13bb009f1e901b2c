"""The virtual air: one shared 433 MHz channel for every PTR2000 in the simulated world.

What a receiver hears (docs/protocol.md §1, clause 2):
* a transmission reaches every radio that is listening when its first bit goes out, each byte
  at the tick its stop bit ends at the sender's rate (a CPU model's UART takes it at its RDRF,
  the stop bit's sample: ``Reception.lead``, Uart.rx_lead); a radio that starts listening in the
  middle of a transmission (its TXEN fell, or it revived) hears the rest of it from the first
  byte whose start bit comes after it listens (its UART cannot frame a byte it joined midway),
  and the garbage of a collision still on air;
* when two transmissions overlap, every listening radio hears garbage (random bytes at its own
  UART rate) from the start of the overlap until the channel is clear; bytes completed before
  the overlap are heard intact; the transmitters themselves are deaf and notice nothing;
* with ``ber`` each byte a receiver hears is corrupted (one bit flipped) with that probability,
  independently per receiver;
* with ``noise`` a listening radio hears random bytes, back to back at its UART rate, whenever
  no transmission reaches it (a PTR2000 outputs noise with no carrier).

Speed without changing a tick: bytes exactly as sent cannot make the firmware act before the
frame's last byte (the deframer only reports a frame at its End), so a clean reception is
delivered in one burst at the end of the transmission, or up to ``now`` whenever the firmware
looks at its UART first (its timer interrupt calls ``sync``). Bytes that differ from what was
sent — corrupted by ``ber``, collision garbage, idle noise that contains a header — can make
the firmware act at any byte, so they are delivered one by one at their own ticks. Idle noise
without a header is delivered in bursts (it can only be discarded), but to a UART on the CPU
model, where each byte is an interrupt, a byte at its tick. Every random draw comes from a
per-radio stream consumed in byte order. ``byte_by_byte=True`` delivers every byte at its
own tick; the tests check both give the same trace.

Over 500 lines on purpose: receptions, collisions, idle noise and aborted senders share each
radio's reception state and its delivery order (split apart, it would have to be public).
``Reception``, ``AirRadio``: hil/sim/reception.py."""
from __future__ import annotations

import math
import random
from typing import Callable

from firmware_model.mcu.ptr2000 import NEVER, Ptr2000
from firmware_model.mcu.uart import first_fall, rates_agree, sample_byte
from firmware_model.mcu.scheduler import Scheduler
from firmware_model.timing import PC_BYTE_TICKS

from .reception import (AirRadio, ByteStream, Reception, Transmission, first_byte_heard,
                        flush_ends, hand_over_end)


HEADER = b"\x0f\x0a\x05"
NOISE_LOOKAHEAD = 1024
"""Bytes of a radio's noise stream scanned ahead for a header (then re-scanned)."""
FOREIGN_BYTE_TICKS = PC_BYTE_TICKS
"""Byte time of a transmitter that is no robot (bursts, ``foreign`` faults, forged frames):
8N1 at exact 9600 baud, 16667 ticks."""


class Air:
    """The shared channel. ``attach`` radios, then let their UARTs transmit."""

    STEADY_COUNTERS = ("occupations", "sent", "_noise_gen")
    """Count only: frames on air and transmissions per robot (reports); ``_noise_gen``, a
    generation number compared only with its own copies (hil/sim/steady.py)."""

    def __init__(self, sched: Scheduler, seed: int = 0, ber: float = 0.0, noise: bool = False,
                 byte_by_byte: bool = False) -> None:
        if not 0.0 <= ber < 1.0:
            raise ValueError(f"byte error rate must be in [0, 1), got {ber}")
        self.sched = sched
        self.seed = seed
        self.ber = ber
        self._log1mp = math.log1p(-ber) if ber > 0 else 0.0
        self.noise = noise
        self.byte_by_byte = byte_by_byte
        self._ends: list = []
        self.radios: list[AirRadio] = []
        self.active: list[Transmission] = []
        self.collision_until = -1
        self._garbage: list[ByteStream] = []
        self._noise: list[ByteStream] = []
        self._noise_gen: list[int] = []
        self._noise_last: list[int] = []     # start tick of the last noise byte handed over
        self._err_rng: list[random.Random] = []
        self.drop = 0.0
        self._drop_rng: list[random.Random] = []
        self._skew: dict[int, float] = {}
        self._clean_by_bt: dict[int, list[bool]] = {}
        self._phantom: AirRadio | None = None
        self.bursts = 0
        self.occupations = 0
        self.sent: dict[int, int] = {}      # transmissions started, per robot
        self.uncounted: set[AirRadio] = set()   # radios ``sent`` leaves out (a twin's)
        self.collisions = 0
        self.carrier: set[AirRadio] = set()   # senders paused mid-frame (a gap between bytes)
        self.on_transmission: Callable[[Transmission], None] | None = None
        self.on_collision: Callable[[int, list[int]], None] | None = None

    def attach(self, radio: AirRadio) -> None:
        radio.channel = self
        radio.idx = len(self.radios)
        self.radios.append(radio)
        self._clean_by_bt.clear()
        name = f"{self.seed}:{radio.robot}"
        self._garbage.append(ByteStream(random.Random(f"{name}:garbage")))
        self._noise.append(ByteStream(random.Random(f"{name}:noise")))
        self._noise_gen.append(0)
        self._noise_last.append(-1)
        self._err_rng.append(random.Random(f"{name}:ber"))
        self._drop_rng.append(random.Random(f"{name}:drop"))
        self._idle_from(radio, self.sched.now)

    # -- fault injection (hil.sim.faults drives these) -----------------------------------------

    def set_ber(self, ber: float) -> None:
        """Byte error rate from now on (each received byte, per receiver)."""
        if not 0.0 <= ber < 1.0:
            raise ValueError(f"byte error rate must be in [0, 1), got {ber}")
        self.ber = ber
        self._log1mp = math.log1p(-ber) if ber > 0 else 0.0

    def set_drop(self, p: float) -> None:
        """Probability that a receiver's UART loses a byte (overrun), from now on."""
        if not 0.0 <= p < 1.0:
            raise ValueError(f"byte drop probability must be in [0, 1), got {p}")
        self.drop = p

    def set_noise(self, on: bool) -> None:
        """Idle noise on or off from now on."""
        now = self.sched.now
        if on == self.noise:
            return
        for r in self.radios:
            if self.noise:
                self.sync(r, now)                # noise heard up to now is delivered
                self._noise_gen[r.idx] += 1      # pending noise scans become no-ops
            r.noise_from = max(r.noise_from, now)
        self.noise = on
        if on:
            for r in self.radios:
                if r.rx is None:
                    self._idle_from(r, now)

    def set_skew(self, radio: AirRadio, eps: float) -> None:
        """``radio``'s UART runs ``eps`` (fraction) off the others' rate (a record: what a
        receiver reads follows from the two byte times, firmware_model.mcu.uart.sample_byte)."""
        self._skew[radio.idx] = eps

    def _clean_for(self, tx_bt: int) -> list[bool]:
        """Does every byte sent at ``tx_bt`` reach each radio's UART unchanged? By ``r.idx``,
        computed once per byte time (a radio's UART is wired before it is attached, and its
        rate never changes; ``attach`` forgets the table)."""
        got = self._clean_by_bt.get(tx_bt)
        if got is None:
            got = self._clean_by_bt[tx_bt] = [
                rates_agree(tx_bt, r.uart.byte_ticks if r.uart is not None else tx_bt)
                for r in self.radios]
        return got

    def burst(self, seconds: float, byte_ticks: int = FOREIGN_BYTE_TICKS) -> None:
        """A burst of interference now: random bytes on air for ``seconds`` from a transmitter
        that is no robot; it collides with whatever else is sent meanwhile."""
        n = max(1, round(seconds * 16_000_000 / byte_ticks))
        self.bursts += 1
        self.inject(self._burst_rng().randbytes(n), byte_ticks)

    def _burst_rng(self) -> random.Random:
        if not hasattr(self, "_brng"):
            self._brng = random.Random(f"{self.seed}:burst")
        return self._brng

    def inject(self, data: bytes, byte_ticks: int = FOREIGN_BYTE_TICKS) -> None:
        """Put ``data`` on air now from a transmitter that is no robot (forged frames,
        interference, ``foreign`` faults); ``sent[-1]`` counts these."""
        if self._phantom is None:
            self._phantom = Ptr2000(-1)
            self._phantom.idx = -1
            self._phantom.alive = False     # never a receiver
        self.transmit(self._phantom, data, self.sched.now, byte_ticks)

    # -- the radios' side -----------------------------------------------------------------

    def transmit(self, radio: AirRadio, data: bytes, t0: int, bt: int) -> None:
        tx = Transmission(radio, data, t0, bt)
        if radio in self.carrier:            # the frame goes on after a gap
            self.carrier.discard(radio)
            tx.continued = True
            for r in self.radios:
                if r.noise_from < t0:
                    r.noise_from = t0
        self.occupations += 1
        if radio not in self.uncounted:
            self.sent[radio.robot] = self.sent.get(radio.robot, 0) + 1
        overlapping = [a for a in self.active if a.end > t0] if self.active else []
        if overlapping or t0 < self.collision_until:
            self.active.append(tx)
            self._collide(tx, overlapping, t0)
        else:
            self.active.append(tx)
            plain = self.ber == 0.0 and self.drop == 0.0 and not self.byte_by_byte
            noise = self.noise
            clean = self._clean_for(bt) if plain else None
            # receptions' last bytes, one event a tick (ends_together)
            ends = self._ends if self.ends_together and not self.byte_by_byte else None
            phantom = radio is self._phantom
            for r in self.radios:
                if r is radio or not r.alive or t0 < r.rx_from:
                    continue
                old = r.rx
                if old is not None:          # a frame that ended exactly at t0: take it all
                    old.flush(r, t0)         # (its end event has not run yet)
                    if r.noise_from < t0:    # and no idle noise while it was heard
                        r.noise_from = t0
                if noise:
                    self._noise_upto(r, t0)
                    self._noise_gen[r.idx] += 1
                if clean is not None and clean[r.idx]:
                    cpu = getattr(r.uart, "cpu", None)
                    if cpu is None or cpu.ideal:
                        r.rx = Reception(data, t0, bt, tx.n, tx)
                        if phantom and self._acts_before_end(r, data):
                            self._bytewise(r, r.rx, 0, tx.n - 1)
                    else:
                        rx = r.rx = Reception(data, t0, bt, tx.n, tx, lead=r.uart.rx_lead(bt))
                        late = self._lazy(r, rx, tx.n, data, t0)
                        rx.seq = self.sched.reserve() if late else None    # (on_time)
                        # late: only the last byte has an event (at its RDRF)
                        self._bytewise(r, rx, tx.n if late else 0, tx.n - 1, ends)
                else:
                    r.rx = self._reception(r, tx, ends=ends)
            if ends:       # their order kept: nothing else this loop schedules comes then
                groups: dict[int, list] = {}
                for e in ends:
                    groups.setdefault(e[0], []).append(e)
                ends.clear()
                for t in groups:
                    self.sched.at(t, flush_ends, groups[t])
        self.sched.at(tx.end, self._end, tx)

    def _acts_before_end(self, r: AirRadio, data: bytes) -> bool:
        """Would ``r``'s firmware act on ``data`` from no robot (interference, forged frames),
        received as sent, before its last byte, so that each byte must come at its tick? Only
        if they are not one good frame for it (``Uart.rx_quiet``: the MAC hears garbage as it
        comes). A robot sends one good frame, after a quiet gap in which its receivers' stall
        timers closed whatever they held: ``transmit`` asks only for the bytes of no robot."""
        quiet = getattr(r.uart, "rx_quiet", None) if r.uart is not None else None
        return quiet is not None and not quiet(data)

    def sync(self, radio: AirRadio, now: int) -> None:
        """Bring what ``radio`` has heard up to ``now`` (before its firmware looks)."""
        rx = radio.rx
        if rx is not None:
            rx.flush(radio, now)
        elif self.noise and radio.listening(now):
            self._noise_upto(radio, now)

    def rx_fall(self, radio: AirRadio, after: int, now: int) -> int | None:
        """First falling edge in ticks (``after``, ``now``] on ``radio``'s data output inside
        the byte it is receiving at ``now`` (its start bit begun, its stop bit not over): a
        transmission's byte as sent, collision garbage or idle noise; else None. What the
        firmware sees of a byte before it is complete (Uart.rx_fall: INT0's edge flag): the
        miss rule asks whether a Header has *begun*. Bits a bit error flips are not looked
        at: the edges are the sent byte's."""
        rx = radio.rx
        if rx is not None:
            k = (now - rx.t0) // rx.bt           # bytes complete by now
            if not 0 <= k < rx.n:
                return None
            if rx.data is not None:
                value = rx.data[k]
            else:                                # garbage: byte k of its stream
                assert rx.stream is not None
                rx.flush(radio, now)
                # taken already if handed over at its RDRF, its stop bit still on air
                value = rx.stream.last if rx.pos > k else rx.stream.peek(k - rx.pos + 1)[-1]
            return first_fall(value, rx.t0 + k * rx.bt, rx.bt, after, now)
        if not (self.noise and not self.carrier and radio.listening(now)):
            return None
        self._noise_upto(radio, now)
        bt = radio.uart.byte_ticks
        last = self._noise_last[radio.idx]
        stream = self._noise[radio.idx]
        if last <= now < last + bt:              # handed over at its RDRF, still on air
            return first_fall(stream.last, last, bt, after, now)
        start = max(radio.noise_from, radio.rx_from)
        if start > now:
            return None
        return first_fall(stream.peek(1)[0], start, bt, after, now)

    def deafen(self, radio: AirRadio, now: int) -> None:
        """``radio`` stops hearing at ``now`` (TXEN raised or radio dead). A dead radio heard
        nothing since it died (``kill`` deafened it): nothing to do, and nothing of the air's
        is touched, so a station whose radio is dead runs on its own (hil/sim/quiet_ring.py)."""
        if not radio.alive:
            return
        self.sync(radio, now)
        radio.rx = None
        self._noise_gen[radio.idx] += 1

    def rx_restart(self, radio: AirRadio, when: int) -> None:
        """``radio`` hears the air again from tick ``when`` (TXEN lowered). Not a dead radio:
        it hears nothing until ``revive``, which starts its listening itself (a join scheduled
        now would find it deaf and do nothing)."""
        if not radio.alive:
            return
        self._idle_from(radio, when)
        self.sched.at(when, self._join, radio, when)

    def _join(self, r: AirRadio, when: int) -> None:
        """``r`` starts listening at ``when``, perhaps in the middle of a transmission: it
        hears the rest of it (a transmission that starts at ``when`` reaches it anyway)."""
        if r.rx is not None or not r.listening(when):
            return
        if when < self.collision_until:
            bt = r.uart.byte_ticks
            n = (self.collision_until - when) // bt
            if n > 0:
                self._noise_upto(r, when)
                self._noise_gen[r.idx] += 1
                r.rx = Reception(None, when, bt, n, None, self._garbage[r.idx],
                                 lead=self._lead(r, bt))
                self._bytewise(r, r.rx, 0, n - 1)
            return
        for tx in self.active:
            if tx.collided or tx.aborted or tx.radio is r or not tx.t0 < when < tx.end:
                continue
            k = first_byte_heard(tx.t0, tx.bt, when, r.uart.byte_ticks)
            if k < tx.n:
                self._noise_upto(r, when)
                self._noise_gen[r.idx] += 1
                r.rx = self._reception(r, tx, k, bytewise=True)
            return

    def pause(self, radio: AirRadio, now: int) -> None:
        """``radio``'s UART ran dry at ``now`` (a byte boundary) mid-frame, its transmit
        handler late: the burst stops there, its carrier (an idle line) on, so the others
        hear no byte or noise until the frame goes on (``transmit``) or TXEN drops."""
        for tx in self.active:
            if tx.radio is radio and not tx.aborted and tx.t0 < now < tx.end:
                self.carrier.add(radio)
                self._abort(tx, now, carrier=True)
                return

    def carrier_off(self, radio: AirRadio, now: int) -> None:
        """``radio`` stops transmitting (TXEN low, or dead): a paused frame's carrier ends."""
        if radio in self.carrier:
            self.carrier.discard(radio)
            for r in self.radios:
                if r is not radio and r.rx is None and r.listening(now):
                    self._idle_from(r, now)

    def kill(self, radio: AirRadio, now: int) -> None:
        """Fault injection: the radio goes silent (mid-frame too) and deaf."""
        self.carrier_off(radio, now)
        self.deafen(radio, now)
        radio.alive = False
        for tx in list(self.active):
            if tx.radio is radio and not tx.aborted:
                self._abort(tx, now)

    def revive(self, radio: AirRadio, now: int) -> None:
        radio.alive = True
        when = now if radio.rx_from == NEVER else max(now, radio.rx_from)
        self._idle_from(radio, when)
        self.sched.at(when, self._join, radio, when)

    # -- receptions -----------------------------------------------------------------------

    def _reception(self, r: AirRadio, tx: Transmission, k: int = 0,
                   bytewise: bool = False, ends: list | None = None) -> Reception:
        """What ``r`` hears of ``tx`` from its byte ``k`` on."""
        data = tx.data[k:] if k else tx.data
        n = tx.n - k
        first_bad = n
        if self.ber > 0.0:
            rng = self._err_rng[r.idx]
            pos = -1
            buf = None
            while True:
                pos += 1 + int(math.log(1.0 - rng.random()) / self._log1mp)
                if pos >= n:
                    break
                if buf is None:
                    buf = bytearray(data)
                    first_bad = pos
                buf[pos] ^= 1 << rng.randrange(8)
            if buf is not None:
                data = bytes(buf)
        holes = None
        if self.drop > 0.0:
            rng = self._drop_rng[r.idx]
            lost = [i for i in range(n) if rng.random() < self.drop]
            if lost:
                holes = frozenset(lost)
                first_bad = min(first_bad, lost[0])
        if not self._clean_for(tx.bt)[r.idx]:
            # the two UARTs' rates differ enough for the receiver's mid-bit samples to fall in
            # the wrong bit cells: what it reads depends on the bits (sample_byte); a byte
            # whose start edge it was not ready for is misframed
            rx_bt = r.uart.byte_ticks
            out = bytearray()
            missed = False
            for i, b in enumerate(data):
                if missed:
                    out += self._garbage[r.idx].take(1)
                    missed = False
                    continue
                v, _, ready = sample_byte(b, tx.bt, rx_bt, data[i + 1] if i + 1 < n else None)
                out.append(v)
                missed = not ready
            bad = next((i for i in range(n) if out[i] != data[i]), n)
            first_bad = min(first_bad, bad)
            data = bytes(out)
        rx = Reception(data, tx.t0 + k * tx.bt, tx.bt, n, tx, holes=holes,
                       lead=self._lead(r, tx.bt))
        lo = 0 if self.byte_by_byte or bytewise else first_bad
        if lo and tx.radio is self._phantom and self._acts_before_end(r, data):
            lo = 0
        cpu = getattr(r.uart, "cpu", None)
        if lo and cpu is not None and not cpu.ideal:
            if holes is not None or k or not self._lazy(r, rx, lo, tx.data, self.sched.now):
                lo = 0                        # every handler at its byte's tick
        self._bytewise(r, rx, lo, n - 1, ends)
        return rx

    def _lazy(self, r: AirRadio, rx: Reception, lo: int, data: bytes, now: int) -> bool:
        """May ``rx``'s clean prefix (``lo`` bytes of the frame ``data``, beginning ``now``)
        come late (``Reception.quiet``; ``Uart.may_come_late``)? On a CPU that has work now,
        byte by byte until one finds it idle, then late, as after a touch (``on_time``)."""
        if r.uart.may_come_late(data, rx.bt, now):
            rx.quiet = rx.lazy = lo
            return True
        if r.uart.late_once_idle(data, rx.bt, now):
            rx.lazy = lo
            self._on_time_next(r, rx)
            return True
        return False

    def late_until(self, radio: AirRadio, now: int) -> int | None:
        """The tick the last byte of ``radio``'s reception that may still come late completes
        (its last byte always comes at its tick), if any bytes are still to come late."""
        return None if radio.rx is None else radio.rx.late_until()

    def late_around(self, radio: AirRadio, now: int) -> tuple[int | None, int | None]:
        """What ``radio``'s firmware would be handed first if its CPU were asked for something
        now (``sync``), and what may come late without an event (``Reception.around``). Idle
        noise is handed over when asked (``_noise_upto``): then ``(now, None)``."""
        rx = radio.rx
        if rx is not None:
            return rx.around(now)
        return (now, None) if self.noise and radio.listening(now) else (None, None)

    def on_time(self, radio: AirRadio, now: int) -> None:
        """``radio``'s CPU model has work from ``now`` (Uart._cpu_touched, after a sync): the
        bytes of its reception still to come go one by one at their ticks, as their
        receive handlers may now meet other handlers."""
        rx = radio.rx
        if rx is not None and rx.quiet > rx.pos:
            rx.quiet = rx.pos
            self._on_time_next(radio, rx)

    def _on_time_next(self, r: AirRadio, rx: Reception) -> None:
        """The next byte of ``rx``'s clean prefix at its tick (not its last byte: the end
        event delivers that)."""
        if rx.pos < min(rx.lazy, rx.n - 1):
            rx.at_byte_place(self.sched, rx.t0 + (rx.pos + 1) * rx.bt - rx.lead,
                             self._on_time_byte, r, rx)

    def _on_time_byte(self, r: AirRadio, rx: Reception) -> None:
        """A byte of a clean prefix completes now: at its tick if the receiver's CPU is still
        busy; on an idle CPU it and the rest may come late again (``Reception.quiet``)."""
        if r.rx is not rx:
            return
        now = self.sched.now
        cpu = r.uart.cpu              # (a lazy reception's receiver has a CPU model)
        if cpu.quiescent(now):
            rx.quiet = rx.lazy
            return
        rx.flush(r, now)
        self._on_time_next(r, rx)

    def _bytewise(self, r: AirRadio, rx: Reception, lo: int, hi: int,
                  ends: list | None = None) -> None:
        """Deliver bytes lo..hi-1 (0-based) each at its own tick; the last byte of a reception
        is delivered by the end-of-transmission event, in radio order, in every mode, unless
        the receiver takes it before its stop bit ends (``Reception.lead``): then by an event
        of its own at its tick, with whatever came late before it (``ends``: noted there for
        one event at that tick, ``flush_ends``)."""
        at = self.sched.at
        t0, bt, lead = rx.t0, rx.bt, rx.lead
        for i in range(lo + 1, hi + 1):
            t = t0 + i * bt - lead
            at(t, self._sync_rx, r, rx, t)
        if lead:
            t = t0 + (hi + 1) * bt - lead
            if ends is None:
                at(t, self._sync_rx, r, rx, t)
            else:
                ends.append((t, r, rx))

    ends_together = True
    """The last bytes of one transmission's receptions by one event a tick (``flush_ends``);
    False, or byte by byte (--every-frame on the CPU model): an event each, the reference."""

    @staticmethod
    def _lead(r: AirRadio, bt: int) -> int:
        """How long before a byte's stop bit ends (sent at ``bt`` ticks a byte) ``r``'s UART
        takes it (Uart.rx_lead; 0 for a radio without one)."""
        query = getattr(r.uart, "rx_lead", None)
        return query(bt) if query is not None else 0

    def _sync_rx(self, r: AirRadio, rx: Reception, t: int) -> None:
        if r.rx is rx:
            rx.flush(r, t)

    # -- idle noise -----------------------------------------------------------------------

    def _idle_from(self, r: AirRadio, t: int) -> None:
        r.noise_from = max(r.noise_from, t)
        if self.noise:
            self._noise_gen[r.idx] += 1
            self._scan_noise(r, r.noise_from)

    def _scan_noise(self, r: AirRadio, start: int) -> None:
        """Find the next header in the noise this radio will hear from ``start`` and make sure
        it is delivered byte by byte (it can make the firmware act); re-scan further on. A
        UART on the CPU model (``_lead``) hears every noise byte at its own tick: each is an
        interrupt that meets the others on its CPU, and noise handed over in a burst would
        queue a request a byte at once (a backlog the part never has)."""
        bt = r.uart.byte_ticks
        gen = self._noise_gen[r.idx]
        lead = self._lead(r, bt)
        if lead:
            self.sched.at(start + bt - lead, self._noise_each, r, gen)
            return
        ahead = self._noise[r.idx].peek(NOISE_LOOKAHEAD)
        k = ahead.find(HEADER)
        if k < 0:
            self.sched.at(start + (NOISE_LOOKAHEAD - 2) * bt, self._noise_rescan, r, gen)
        else:
            self.sched.at(start + (k + 1) * bt, self._noise_header, r, gen)

    def _noise_each(self, r: AirRadio, gen: int) -> None:
        """A noise byte at its RDRF (a CPU model's UART), then the next one's."""
        now = self.sched.now
        if gen != self._noise_gen[r.idx] or r.rx is not None or not self.noise or \
                not r.listening(now):
            return
        self._noise_upto(r, now)
        bt = r.uart.byte_ticks
        self.sched.at(max(r.noise_from, r.rx_from) + bt - self._lead(r, bt), self._noise_each,
                      r, gen)

    def _noise_rescan(self, r: AirRadio, gen: int) -> None:
        if gen != self._noise_gen[r.idx] or r.rx is not None or not r.listening(self.sched.now):
            return
        self._noise_upto(r, self.sched.now)
        self._noise_gen[r.idx] += 1
        self._scan_noise(r, r.noise_from)

    def _noise_header(self, r: AirRadio, gen: int) -> None:
        if gen != self._noise_gen[r.idx] or r.rx is not None or not r.listening(self.sched.now):
            return
        now = self.sched.now
        self._noise_upto(r, now)
        # A header in the noise: the rest of this idle period goes byte by byte (bounded by a
        # maximum frame), then bursts again.
        bt = r.uart.byte_ticks
        for i in range(1, 600):
            self.sched.at(now + i * bt, self._noise_byte, r, gen)
        self.sched.at(now + 600 * bt, self._noise_rescan, r, gen)

    def _noise_byte(self, r: AirRadio, gen: int) -> None:
        if gen == self._noise_gen[r.idx] and r.rx is None and r.listening(self.sched.now):
            self._noise_upto(r, self.sched.now)

    def _noise_upto(self, r: AirRadio, t: int) -> None:
        if not self.noise:
            return
        if self.carrier:                     # a paused sender's carrier: no noise heard
            if r.noise_from < t:
                r.noise_from = t
            return
        start = r.noise_from
        if r.rx_from > start:
            start = r.rx_from
        bt = r.uart.byte_ticks
        lead = self._lead(r, bt)
        n = (t + lead - start) // bt
        if n > 0:
            r.noise_from = start + n * bt
            self._noise_last[r.idx] = start + (n - 1) * bt
            if lead:
                r.deliver(self._noise[r.idx].take(n), start + bt, bt, False, lead)
            else:
                r.deliver(self._noise[r.idx].take(n), start + bt, bt)

    # -- collisions and ends --------------------------------------------------------------

    def _collide(self, tx: Transmission, overlapping: list[Transmission], t0: int) -> None:
        self.collisions += 1
        for a in overlapping:
            a.collided = True
        tx.collided = True
        cend = max([a.end for a in overlapping] + [tx.end, self.collision_until])
        extended = cend > self.collision_until
        if extended:
            self.collision_until = cend
            self.sched.at(cend, self._collision_end, cend)
        for r in self.radios:
            if r is tx.radio:
                continue
            rx = r.rx
            if rx is not None and rx.data is None:     # already hearing garbage: extend it
                rx.flush(r, t0)
                old = rx.n
                rx.n = (cend - rx.t0) // rx.bt
                # its old last byte is no longer the last: bytes still ahead go one by one
                # (one taken before its stop bit ended had its own event already)
                lo = max(old if rx.lead else old - 1, rx.pos)
                self._bytewise(r, rx, lo, rx.n - 1)
                continue
            if not r.listening(t0):
                continue
            if rx is not None:
                rx.flush(r, t0)
            else:
                self._noise_upto(r, t0)
            self._noise_gen[r.idx] += 1
            bt = r.uart.byte_ticks
            g = Reception(None, t0, bt, (cend - t0) // bt, None, self._garbage[r.idx],
                          lead=self._lead(r, bt))
            r.rx = g
            self._bytewise(r, g, 0, g.n - 1)
        if self.on_collision is not None:
            involved = overlapping + [tx]
            self.on_collision(t0, sorted({a.radio.robot for a in involved}))

    def _collision_end(self, cend: int) -> None:
        """The channel is clear again: receivers stop hearing garbage."""
        if cend != self.collision_until:
            return  # the collision was extended; a later event ends it
        for r in self.radios:
            rx = r.rx
            if rx is not None and rx.data is None:
                rx.flush(r, cend)
                r.rx = None
                self._idle_from(r, cend)

    def _abort(self, tx: Transmission, now: int, carrier: bool = False) -> None:
        """The sender died at ``now`` (``carrier``: paused, its carrier on): bytes complete by
        then were on air."""
        tx.aborted = True
        tx.paused = carrier
        for r in self.radios:
            rx = r.rx
            if rx is not None and rx.tx is tx:
                rx.flush(r, now)
                rx.n = rx.pos
                r.rx = None
                if not carrier:
                    self._idle_from(r, now)
                elif r.noise_from < now:
                    r.noise_from = now
        self.active.remove(tx)
        tx.end = now
        if carrier:
            tx.n = (now - tx.t0) // tx.bt
            tx.data = tx.data[:tx.n]
        if tx.collided:
            # The collision lasts only as long as the transmissions still on air.
            rest = [a.end for a in self.active if a.collided]
            until = max(rest) if rest else now
            if until < self.collision_until:
                self.collision_until = until
                for r in self.radios:
                    g = r.rx
                    if g is not None and g.data is None:
                        g.n = min(g.n, (until - g.t0) // g.bt)
                if until == now:
                    self._collision_end(now)
                else:
                    self.sched.at(until, self._collision_end, until)
        if self.on_transmission is not None:
            self.on_transmission(tx)

    def _end(self, tx: Transmission) -> None:
        if tx.aborted:
            return
        self.active.remove(tx)
        if not tx.collided:
            hand_over_end(tx, self.radios, self._idle_from if self.noise else None)
        if self.on_transmission is not None:
            self.on_transmission(tx)

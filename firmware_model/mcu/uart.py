"""MB90F549 UART (UART0, asynchronous 8N1) with its dedicated baud-rate generator.

At a 16 MHz machine clock the generator gives 9615.38 bit/s for "9600": 1664 ticks a bit,
16640 ticks a byte (start + 8 data + stop). Without a CPU model (the ideal, zero-time
firmware) the transmit handler reloads the data register while the previous byte shifts out,
so a frame leaves back to back: the model hands the line a whole burst and tells the firmware
(``on_tx_done``) on the tick the last stop bit ends. Received bytes arrive from the radio with
the tick at which each stop bit ended.

With a CPU model attached (``attach_cpu``), reception is what the part does: each byte's stop
bit, sampled in the middle of its cell (9.5 of this UART's bits after the start edge, as
MAME's model of the F2MC-16 UART samples), sets RDRF and requests the receive interrupt
(``rx_lead``: 832 ticks before a child's byte ends); the handler reads the byte (clearing
RDRF) when its entry sequence ends. A byte sampled while RDRF is still set is an overrun:
SSR.ORE is set and the byte is lost (MB90F549 UART, "reception": the data register is not
overwritten). The firmware is given each byte's stop-bit end as its tick (docs/protocol.md
§2). Without a CPU model the bytes go to ``on_rx`` at their ends, in bursts.

Transmission with a CPU model is what the part does too. The UART has an output data
register (SODR) in front of its shift register, and one transmit flag, TDRE (SSR0 bit 3;
SSR0 has TIE, RIE, TDRE, RDRF, FRE, ORE, PE and no transmission-complete flag): TDRE sets,
and with TIE requests the transmit interrupt, when SODR's byte moves into the shift register,
at the start of its start bit. The firmware writes the first byte (it moves at once), and each
transmit interrupt's handler writes the next one when its body is done. A byte written before
the one shifting out ends follows it back to back; one written later starts when it is
written, leaving a gap of idle line (mark) in the frame (``gaps``, ``gap_ticks``). At the
last byte's TDRE the handler clears TIE and, the UART having no transmission-complete
interrupt, arms a timer channel for the End's stop bit: one byte time from the TDRE request,
which it takes to be its own entry less the entry cycles. That timer's handler (``end
vector``) lowers TXEN and runs the MAC's end-of-frame rules (``on_tx_done`` with that tick),
so a transmit handler that was preempted before its entry drops TXEN late by as much.

On an idle CPU the simulator may count the receive handlers of a good frame's bytes late
(``receive``'s ``late_ok``) and the transmit handlers of a frame's bytes but the last two
(``_late_tdre``, one event for them all), each as it ran, to the tick (docs/fast-paths.md,
"Late bytes on an idle CPU").
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Callable, Protocol

from ..timing import BITS_PER_BYTE_8N1, TICK_HZ
from .scheduler import Event, Scheduler

if TYPE_CHECKING:
    from .cpu import Cpu, Vector

BAUD_DIVISORS = {1200: 13312, 2400: 6656, 4800: 3328, 9600: 1664, 19200: 832, 38400: 416}
"""Nominal baud -> ticks a bit (16 x the dedicated generator's count at 16 MHz)."""


class SerialLine(Protocol):
    """What the UART's TX pin drives (the PTR2000's data input)."""

    def transmit(self, data: bytes, t0: int, byte_ticks: int) -> None: ...

    def sync(self, now: int) -> None: ...

    def rx_fall(self, after: int, now: int) -> int | None: ...


class Uart:
    """One UART channel. Set ``line`` (TX side), ``on_rx`` and ``on_tx_done`` before use."""

    STEADY_COUNTERS = ("bytes_sent", "bytes_received", "bytes_late")
    """Count only (reports; hil/sim/steady.py)."""

    __slots__ = ("sched", "bit_ticks", "byte_ticks", "line", "on_rx", "on_tx_done",
                 "busy_until", "bytes_sent", "bytes_received", "name", "cpu", "rx_vector",
                 "rx_cycles", "tx_vector", "tx_cycles", "end_vector", "end_cycles", "rdr",
                 "overruns", "_read", "gaps", "gap_ticks", "_tx", "_tx_len", "_tx_next",
                 "_sodr", "_shift", "_tdre_entry", "_gap_from", "rx_quiet",
                 "bytes_late", "_late_tdre", "_late_from", "_shift_ev", "_end_at", "_held")

    def __init__(self, sched: Scheduler, baud: int = 9600, byte_ticks: int | None = None,
                 name: str = "UART0") -> None:
        self.sched = sched
        self.name = name
        if byte_ticks is None:
            if baud not in BAUD_DIVISORS:
                raise ValueError(f"the MB90F549 baud generator has no {baud} baud setting; "
                                 f"choose one of {sorted(BAUD_DIVISORS)}")
            self.bit_ticks: float = BAUD_DIVISORS[baud]
            byte_ticks = BAUD_DIVISORS[baud] * BITS_PER_BYTE_8N1
        else:
            self.bit_ticks = byte_ticks / BITS_PER_BYTE_8N1
        self.byte_ticks = byte_ticks
        self.line: SerialLine | None = None
        self.on_rx: Callable[..., None] | None = None
        """``on_rx(data, t0, dt, now=None, held=None)``: bytes received, byte i's stop bit at
        ``t0 + i * dt``; with a CPU model ``now``, the tick of their handlers' effects if
        earlier than the scheduler's (bytes handed over late), and ``held``, the tick of the
        effects of all but the last, which came late and are given with the last's
        (``_rx_isr``): the receiver must end as if given them apart (firmware_model/station.py)."""
        self.bytes_late = 0
        """Bytes handed over late on an idle CPU and counted as handled at their ticks
        (``_replay``)."""
        self._end_at = 0          # the End's stop-bit tick, as the TX END timer reckoned it
        self.rx_quiet: Callable[[bytes], bool] | None = None
        """Set by the receiving firmware: True if handing it all but the last byte of these
        bytes, in any chunks, makes it report nothing (a good frame, nothing held): then
        they may come late on an idle CPU (``receive``'s ``late_ok``, hil/sim/air.py)."""
        self.on_tx_done: Callable[[int], None] | None = None
        self.busy_until = 0
        self.bytes_sent = 0
        self.bytes_received = 0
        self.cpu: Cpu | None = None          # attach_cpu: the handlers run on the CPU model
        self.rx_vector: Vector | None = None
        self.tx_vector: Vector | None = None
        self.rx_cycles = self.tx_cycles = 0
        self.rdr: list[tuple[int, int]] = []   # (byte, stop-bit tick); RDRF while non-empty
        self.overruns = 0
        self._read: list[tuple[int, int]] = []
        self.end_vector: Vector | None = None
        self.end_cycles = 0
        self.gaps = 0                # times the shift register ran dry inside a frame
        self.gap_ticks = 0           # idle line those gaps left inside frames (ticks)
        self._tx: bytes | None = None    # the frame being sent (CPU model)
        self._tx_len = 0
        self._gap_from = 0
        self._tx_next = 0            # index of the next byte the handler writes to SODR
        self._sodr: int | None = None    # index of the byte waiting in SODR
        self._shift: tuple[int, int] | None = None   # (index, stop-bit end) shifting out
        self._tdre_entry = 0
        self._late_tdre: int | None = None
        """The first TDRE tick of a run of transmit handlers counted late, one a byte time
        (on an idle CPU: ``_may_send_late``), else None; ``_late_from`` its byte."""
        self._late_from = 0
        self._shift_ev: Event | None = None
        """The event at ``_shift``'s stop-bit end."""
        self._held: tuple[bytes, int, int, int] | None = None
        """Bytes handed over late whose effects wait for the next byte's, which a lone
        handler gives (``_replay``): (bytes, the first's stop-bit tick, ticks a byte, the
        tick their effects came), given at that handler's body end or whenever the CPU or
        this UART is asked anything first."""

    def attach_cpu(self, cpu: Cpu, rx_vector: Vector, rx_cycles: int, tx_vector: Vector,
                   tx_cycles: int, end_vector: Vector, end_cycles: int) -> None:
        """Run the handlers on ``cpu`` (mcu/cpu.py): reception (``rx_cycles`` a byte), the
        transmit interrupt (TDRE, ``tx_cycles`` a byte) and the timer that marks the End's
        stop bit (``end_cycles``: TXEN low and the MAC's end-of-frame rules)."""
        self.cpu = cpu
        cpu.on_touch = self._cpu_touched
        cpu.late_clear = self._late_clear
        self.rx_vector, self.rx_cycles = rx_vector, rx_cycles
        self.tx_vector, self.tx_cycles = tx_vector, tx_cycles
        self.end_vector, self.end_cycles = end_vector, end_cycles

    @property
    def baud(self) -> float:
        """The real bit rate (bit/s)."""
        return TICK_HZ / self.bit_ticks

    def send(self, data: bytes) -> int:
        """Shift ``data`` out from now; returns the tick the last stop bit ends (with a CPU
        model: the earliest, if no byte is written late)."""
        now = self.sched.now
        if now < self.busy_until or self._tx is not None:
            raise RuntimeError(f"{self.name}: transmitter busy until tick {self.busy_until}")
        if self.cpu is not None and data:
            self._tx = data
            self._tx_len = len(data)
            self._tx_next = 1
            self._sodr = None
            self.bytes_sent += len(data)
            self._shift_in(0, now, True)
            return now + len(data) * self.byte_ticks
        end = now + len(data) * self.byte_ticks
        self.busy_until = end
        self.bytes_sent += len(data)
        if self.line is not None:
            self.line.transmit(data, now, self.byte_ticks)
        self.sched.at(end, self._tx_complete, end)
        return end

    def _tx_complete(self, end: int) -> None:
        if self.on_tx_done is not None:
            self.on_tx_done(end)

    # -- transmission with a CPU model: SODR, the shift register and TDRE ----------------

    def _shift_in(self, k: int, now: int, new_burst: bool) -> None:
        """Byte ``k`` moves into the shift register at ``now``: TDRE, the transmit request.
        ``new_burst``: the line was idle before it (the frame's first byte, or after a gap)."""
        bt = self.byte_ticks
        cpu = self.cpu
        assert cpu is not None and self.tx_vector is not None     # send() takes this path
        self._shift = (k, now + bt)
        self._shift_ev = self.sched.at(now + bt, self._shift_done)
        if k == self._tx_len - 1:
            self.busy_until = now + bt
        if new_burst and self.line is not None:
            # the rest of the frame, back to back as far as the handler keeps up; cut short
            # (``pause``) where the shift register runs dry
            assert self._tx is not None                           # the frame being sent
            self.line.transmit(self._tx[k:], now, bt)
        self._tdre_request()

    def _tdre_request(self, at: int | None = None) -> None:
        """TDRE requests the transmit interrupt (``at``: it did at that earlier tick, the CPU
        idle since: a late handler the CPU is now asked past)."""
        assert self.cpu is not None and self.tx_vector is not None
        self.cpu.irq(self.tx_vector, self.tx_cycles, self._tdre_isr, enter=self._tdre_enter,
                     alone=True, at=at)

    def _tdre_enter(self) -> None:
        """The handler's entry has ended (the End's timer counts from there; only its body
        reads it, so it may run alone)."""
        assert self.cpu is not None
        self._tdre_entry = self.cpu.entered

    def _tdre_isr(self) -> None:
        """The transmit handler's write: the next byte to SODR, or, after the last, TIE off
        and the End's timer armed."""
        if self._tx is None:
            return
        now = self.sched.now
        j = self._tx_next
        if j < self._tx_len:
            self._tx_next = j + 1
            if self._shift is None:           # the shift register ran dry: the gap ends
                self.gap_ticks += now - self._gap_from
                self._shift_in(j, now, True)
            else:
                self._sodr = j
            return
        self._tx = None
        assert self.cpu is not None                   # the handler runs on it
        end = self._tdre_entry - self.cpu.entry + self.byte_ticks
        self.sched.at(max(end, now), self._end_timer, end)

    def _shift_done(self) -> None:
        """The byte in the shift register has sent its stop bit (the last of a run of late
        handlers' bytes: ``_late_tdre``)."""
        now = self.sched.now
        assert self._shift is not None                # _shift_in scheduled this
        self._shift_ev = None
        k = self._shift[0]
        if self._late_tdre is not None:       # its handlers ran late: over by now
            self._late_tdre_done(k)
        self._shift = None
        j = self._sodr
        if j is not None:                     # SODR was written in time: back to back
            self._sodr = None
            if j + 1 < self._tx_len and self._may_send_late(now):
                # TDREs of the bytes but the last: their handlers run late, each over before
                # the next TDRE, one event at the end of them (the last's arms the End's
                # timer at its tick); anything that asks the CPU meanwhile cuts the run
                # (_tx_touched)
                m = self._tx_len - 2
                end = now + (m - j + 1) * self.byte_ticks
                self._shift = (m, end)
                self._shift_ev = self.sched.at(end, self._shift_done)
                self._late_tdre, self._late_from = now, j
            else:
                self._shift_in(j, now, False)
        elif k + 1 < self._tx_len:            # written late: the line idles, a gap
            self.gaps += 1
            self._gap_from = now
            pause = getattr(self.line, "pause", None)
            if pause is not None:
                pause(now)

    # -- transmit handlers counted late while the CPU has nothing else to do -------------

    def _may_send_late(self, now: int) -> bool:
        """May the transmit handler of the byte whose TDRE is now run late? Only on an idle
        CPU whose handler, run alone, is over before the next TDRE: it then writes SODR in
        time and nothing else looks at it (docs/fast-paths.md, "Late bytes on an idle CPU")."""
        cpu = self.cpu
        assert cpu is not None
        return cpu.fits_alone(self.tx_cycles, self.byte_ticks) and cpu.quiescent(now)

    def _late_tdre_done(self, k: int) -> None:
        """The late handlers of the run's bytes up to ``k`` (TDREs a byte time apart from
        ``_late_tdre``) are over: counted as run alone, and the last one's write done: byte
        ``k + 1`` in SODR."""
        t = self._late_tdre
        cpu, vector = self.cpu, self.tx_vector
        assert t is not None and cpu is not None and vector is not None
        n = k - self._late_from + 1
        self._late_tdre, self._late_from = None, 0
        cpu.lone_past(vector, self.tx_cycles, t, self.byte_ticks, n)
        self._tdre_entry = t + (n - 1) * self.byte_ticks + cpu.entry
        self._sodr, self._tx_next = k + 1, k + 2

    def _late_now(self, now: int) -> tuple[int, int]:
        """The byte of the late run in the shift register at ``now`` and its TDRE tick (at
        a byte's stop-bit end, that byte: its event is the one that ends it)."""
        t = self._late_tdre
        assert t is not None
        bt = self.byte_ticks
        i = max(0, now - t - 1) // bt
        return self._late_from + i, t + i * bt

    def _tx_touched(self, now: int) -> None:
        """The CPU is asked for something while late transmit handlers run or have run: the
        run ends with the byte now in the shift register, its event at that byte's stop-bit
        end; its handler counted and its write done if its effects came before now, else it
        goes on as a lone handler (Cpu.irq's ``at``)."""
        cpu = self.cpu
        assert self._late_tdre is not None and cpu is not None and self._shift is not None
        k, t = self._late_now(now)
        if self._shift[0] != k:
            assert self._shift_ev is not None
            self._shift_ev.cancel()
            self._shift = (k, t + self.byte_ticks)
            self._shift_ev = self.sched.at(t + self.byte_ticks, self._shift_done)
        if t + cpu.entry + self.tx_cycles < now:
            self._late_tdre_done(k)
            return
        if k > self._late_from:
            self._late_tdre_done(k - 1)       # (writes byte k; its own handler runs on)
        self._late_tdre, self._late_from = None, 0
        self._sodr, self._tx_next = None, k + 1
        self._tdre_request(at=t)

    def _end_timer(self, end: int) -> None:
        if self.on_tx_done is not None:
            assert self.cpu is not None and self.end_vector is not None   # set with the timer
            self._end_at = end
            self.cpu.irq(self.end_vector, self.end_cycles, _nothing, enter=self._end_entered,
                         alone=True, enter_now=True)

    def _end_entered(self) -> None:
        """TX END's handler begins: TXEN falls (``on_tx_done``), given the End's stop-bit tick
        as the timer reckoned it. (A method, not a closure over the tick: a ring's snapshot
        sees and moves ``_end_at``, hil/sim/quiet_ring.py.)"""
        assert self.on_tx_done is not None
        self.on_tx_done(self._end_at)

    def rx_lead(self, tx_byte_ticks: int) -> int:
        """Ticks before the end of a byte's stop bit (the byte sent at ``tx_byte_ticks`` a
        byte) at which RDRF sets: the stop bit's sample, 9.5 of this UART's own bits after the
        start edge (the receiver counts from the edge it saw, at its own rate), so half a bit
        (832 ticks) for a byte at its own rate and 859 for a PC's. 0 on the ideal CPU, which
        takes each byte at its end as the protocol dates it (docs/protocol.md §2). Never
        negative: a byte from a sender over 5 % faster than this UART (a foreign burst), whose
        samples this UART misreads anyway, is taken at its end."""
        cpu = self.cpu
        if cpu is None or cpu.ideal:
            return 0
        return max(0, tx_byte_ticks - (19 * self.byte_ticks) // 20)

    def receive(self, data: bytes, t0: int, dt: int, late_ok: bool = False,
                lead: int = 0) -> None:
        """Bytes from the line: byte i's stop bit ended at tick ``t0 + i * dt`` (its date,
        what the firmware is given), RDRF set ``lead`` ticks earlier (``rx_lead``: the line
        hands each byte over at that tick). ``late_ok``: the bytes whose RDRF came before
        now are a clean prefix of a frame handed over late, the CPU idle since before the
        first (the air's lazy reception, hil/sim/air.py): their handlers are counted as they
        ran (``Cpu.lone_past``) and their effects happen now, in one burst, as the ideal
        CPU's do."""
        self.bytes_received += len(data)
        if self.on_rx is None:
            return
        if self.cpu is None:
            # the simulator's air takes these two steps itself for a whole clean frame
            # (docs/fast-paths.md, "The air's direct hand-over")
            self.on_rx(data, t0, dt)
            return
        now = self.sched.now
        cpu = self.cpu
        if self._held is not None:         # (bytes before these, whose byte never came)
            self._give_held()
        if late_ok and t0 - lead < now:
            k = min(len(data), (now - t0 + lead - 1) // dt + 1)     # RDRFs before now
            self._replay(data[:k], t0, dt, lead, hold=k < len(data))
            data = data[k:]
            t0 += k * dt
        held, self._held = self._held, None
        cpu.settle(read=False)        # a handler running alone has read SIDR by now, or not
        for i, b in enumerate(data):
            t = t0 + i * dt
            if self.rdr and t - lead >= now:
                # RDRF still set at this byte's stop-bit sample: ORE, the byte is lost. (A
                # byte the line hands over late, idle noise delivered in a burst, cannot be
                # judged.)
                self.overruns += 1
                continue
            self.rdr.append((b, t))     # more than one only for bytes handed over late
            self._rx_request(dt)
        if held is not None:
            # bytes handed over late, all their effects due, and this byte after them (a
            # frame's End): if its handler runs alone, nothing looks at theirs before its
            # effects or before the CPU or this UART is asked anything, so they come with its,
            # in one call (``_rx_isr``): a frame's all at once at its End
            self._held = held
            if len(data) != 1 or len(self.rdr) != 1 or not cpu.runs_alone(self._rx_isr):
                self._give_held()

    def may_come_late(self, data: bytes, dt: int, now: int) -> bool:
        """Could ``data``, a byte every ``dt`` ticks from a reception beginning ``now``, be
        handed over late (``receive``'s ``late_ok``)? Only on a CPU with nothing to do now,
        whose receive handler, run alone, is over before the next byte comes, and if the
        receiving firmware reports nothing before the last byte (``rx_quiet``)."""
        return self._late_fits(data, dt, now, True)

    def _late_fits(self, data: bytes, dt: int, now: int, idle: bool) -> bool:
        """``data`` may come late on this CPU, idle now or not as ``idle`` says: a receive
        handler that, alone, is over before the next byte, and a receiving firmware that
        reports nothing before the last byte (``rx_quiet``)."""
        cpu = self.cpu
        return cpu is not None and self.rx_quiet is not None and \
            cpu.fits_alone(self.rx_cycles, dt) and cpu.quiescent(now) == idle and \
            self.rx_quiet(data)

    def late_once_idle(self, data: bytes, dt: int, now: int) -> bool:
        """Could ``data`` (as ``may_come_late``), from a reception beginning ``now`` on a CPU
        that has work now, be handed over late from the first byte that finds the CPU idle
        (hil/sim/air.py, ``Air.on_time``'s way back)? Only if nothing of this UART's receive
        path is still to run (no byte in RDR or read and not yet handled, none held, no
        receive handler on the CPU), so that ``rx_quiet`` judges the deframer as the first
        byte's handler finds it."""
        return not self.rdr and not self._read and self._held is None and \
            self.cpu is not None and not self.cpu.handles(self._rx_isr) and \
            self._late_fits(data, dt, now, False)

    def _replay(self, chunk: bytes, t0: int, dt: int, lead: int, hold: bool = False) -> None:
        """Bytes handed over late with an idle CPU (``receive``'s ``late_ok``): each byte's
        handler ran alone from its RDRF (``lead`` ticks before its date); those whose effects
        are due by now give them now, in one call, at the tick the last of them had them; a
        last byte whose body is still running becomes the lone handler and gives its effects
        at its body's end. ``hold``: a byte comes right after them (``receive``), so bytes
        whose effects are all due wait for it in ``_held``."""
        cpu, vector = self.cpu, self.rx_vector
        assert cpu is not None and vector is not None and self.on_rx is not None
        now = self.sched.now
        e = cpu.entry + self.rx_cycles
        n = len(chunk)
        last = t0 + (n - 1) * dt
        due = n if last - lead + e < now else n - 1   # effects due now: after what came first
        if due:
            self.bytes_late += due
            cpu.lone_past(vector, self.rx_cycles, t0 - lead, dt, due)
            at = t0 - lead + (due - 1) * dt + e
            if hold and due == n:
                self._held = (chunk, t0, dt, at)      # (receive gives them, or holds them)
            else:
                self.on_rx(chunk[:due], t0, dt, at)
        if due < n:
            self.rdr.append((chunk[-1], last))
            self._rx_request(dt, at=last - lead)

    def _rx_request(self, dt: int, at: int | None = None) -> None:
        """RDRF requests the receive interrupt (``at``: it did at that earlier tick, the CPU
        idle since: ``_replay``'s last byte)."""
        assert self.cpu is not None and self.rx_vector is not None
        self.cpu.irq(self.rx_vector, self.rx_cycles, self._rx_isr, dt, enter=self._take_rdr,
                     alone=True, at=at)

    def _give_held(self) -> None:
        """The held bytes' effects (``_held``), with the tick they came."""
        held = self._held
        assert held is not None and self.on_rx is not None
        self._held = None
        data, t0, dt, at = held
        self.on_rx(data, t0, dt, at)

    def _cpu_touched(self, now: int, busy: bool) -> None:
        """The CPU is asked for something (``busy``) or read: the bytes heard by now first
        (``Cpu.on_touch``); a request or task means the bytes still to come must each come at
        its tick (``on_time``), as their handlers now meet others."""
        if self._late_tdre is not None:    # (sending: nothing held, the radio deaf)
            self._tx_touched(now)
        # ``sync``, inlined (every request on the CPU model comes here)
        if self._held is not None:
            self._give_held()
        line = self.line
        if line is not None:
            line.sync(now)
            if self._held is not None:
                self._give_held()
            if busy:
                on_time = getattr(line, "on_time", None)
                if on_time is not None:
                    on_time(now)

    def _late_clear(self, now: int, until: int) -> bool:
        """No handler of this UART counted late (a late TDRE's, a byte handed over late)
        runs at ``now`` or is requested by ``until`` (``Cpu.defer``)."""
        cpu = self.cpu
        assert cpu is not None
        if self._late_tdre is not None:
            k, t = self._late_now(now)
            if t + cpu.entry + self.tx_cycles + cpu.reti >= now:
                return False                  # its handler runs
            if k < self._tx_len - 2 and t + self.byte_ticks <= until:
                return False                  # the next one is requested by then
        query = getattr(self.line, "late_around", None)
        if query is None:
            return True
        last, nxt = query(now)
        if last is not None and last + cpu.entry + self.rx_cycles + cpu.reti >= now:
            return False
        return nxt is None or nxt > until

    def _take_rdr(self) -> None:
        """The receive handler reads SIDR: RDRF clears, the next byte may come."""
        if self.rdr:
            self._read.append(self.rdr.pop(0))

    def _rx_isr(self, dt: int) -> None:
        if self._read and self.on_rx is not None:
            b, t = self._read.pop(0)
            held = self._held
            if held is not None:                # the bytes before this one, with it
                data, t0, _, at = held
                assert t == t0 + len(data) * dt  # (receive holds them for this byte only)
                self._held = None
                self.on_rx(data + bytes((b,)), t0, dt, None, at)
                return
            self.on_rx(bytes((b,)), t, dt)

    def sync(self, now: int) -> None:
        """Take every byte handed over by ``now`` (before a timer ISR reads state)."""
        if self._held is not None:
            self._give_held()
        if self.line is not None:
            self.line.sync(now)
            if self._held is not None:
                self._give_held()

    def rx_fall(self, after: int, now: int) -> int | None:
        """First falling edge on SIN0 in ticks (``after``, ``now``] inside the byte still
        being received at ``now``, else None (a line that cannot tell says None).

        The firmware sees it as INT0's edge flag (EIRR bit 0): SIN0 is wired to the INT0 pin
        as well, falling-edge detection on, its interrupt off, so the flag is only polled;
        the receive handler clears it once it has read a byte (``after``: that tick).
        Falling edges are the start bit's and any 1-to-0 step between data bits
        (:func:`first_fall`)."""
        query = getattr(self.line, "rx_fall", None)
        return query(after, now) if query is not None else None


def first_fall(value: int, start: int, byte_ticks: int, after: int, now: int) -> int | None:
    """First falling edge in ticks (``after``, ``now``] of the 8N1 byte ``value`` whose start
    bit begins at tick ``start``, ``byte_ticks`` ticks a byte, else None. The line is high
    before the start bit (idle, or the previous byte's stop bit), so the start bit's edge is
    always one; bit cell ``i`` (0 the start bit, 1-8 the data bits LSB first) begins at
    ``start + i * byte_ticks // 10``."""
    prev = 1
    for i in range(9):
        level = 0 if i == 0 else (value >> (i - 1)) & 1
        if prev and not level:
            t = start + i * byte_ticks // 10
            if t > now:
                return None
            if t > after:
                return t
        prev = level
    return None


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

"""The radio half of the firmware: UART -> deframer -> rotational MAC -> UART and TXEN.

This is the code a child's MB90F549 runs in its UART and reload-timer interrupt handlers, and
the code the father PC runs: only the peripherals handed in differ (simulated on a Scheduler,
or real ones in the bench). It knows nothing about the world it runs in.

Interrupt order at one tick: UART bytes handed over by tick t (their stop bit ended; on the CPU
model, their RDRF set: Uart.rx_lead) are taken before a timer interrupt at tick t reads any
state (``on_timer`` first brings the UART up to date). A byte's tick, as the MAC gets it, is
its stop bit's end (docs/protocol.md §2).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Callable, NamedTuple

from .interrupts import AUTH_TASK, RXWATCH
from .mcu.gpio import OutputPin
from .mcu.ptr2000 import Ptr2000
from .mcu.reload_timer import ReloadTimer
from .mcu.scheduler import Scheduler
from .mcu.uart import Uart
from .radio.deframer import Deframer, FrameFailed, FrameReceived, Garbage
from .radio.mac import (SEND, BadChecksum, Deliver, MacConfig, NumberBehind, Refused,
                         RotationalMac, Transmit, TxEnable)
from .radio.station_mac import StationMac

if TYPE_CHECKING:
    from .cycle_costs import CycleCosts
    from .mcu.cpu import Cpu

Observer = Callable[["RadioStation", object, int], None]


class Stalled(NamedTuple):
    """The station ran ``late`` ticks late (its interrupts were not taken for that long) and
    resynchronised (``RadioStation.resync``): told to the observer."""
    late: int


class RadioStation:
    """One robot's radio firmware on its peripherals (UART0, TXEN pin, reload timer 0)."""

    STEADY_COUNTERS = ("frames_heard",)
    """Frames it took: counts only (reports; hil/sim/steady.py)."""

    def __init__(self, robot_id: int, sched: Scheduler, uart: Uart, txen: OutputPin,
                 config: MacConfig | None = None, observer: Observer | None = None) -> None:
        cfg = config or MacConfig()
        if cfg.byte_ticks != uart.byte_ticks:
            from dataclasses import replace
            cfg = replace(cfg, byte_ticks=uart.byte_ticks)
        self.id = robot_id
        self.sched = sched
        self.uart = uart
        self.txen = txen
        rotational = RotationalMac(robot_id, cfg)
        self.mac: StationMac = rotational
        """The paper's MAC; a peer MAC may take its place (radio/peer_macs.py): the station
        uses only what :class:`~firmware_model.radio.station_mac.StationMac` lists."""
        self.deframer = Deframer(max_content=rotational.rx_max_content,
                                 byte_ticks=uart.byte_ticks)
        self.timer = ReloadTimer(sched, self._on_timer)
        self.stall_timer = ReloadTimer(sched, self._on_stall, name="RXWATCH")
        """Watches a frame coming in: its bytes stopped for the stall gap (the sender died).
        A second timer channel besides the MAC's TMR0 (the child's dispatcher has TMR1): which
        MB90F549 timer serves it on a board (the free-running timer's compare, say) is for the
        peripheral map of issue 13; the model times it exactly like a reload timer."""
        self._observers: tuple[Observer, ...] = () if observer is None else (observer,)
        self._notify: Observer | None = observer
        """What the handlers call: None, the one observer, or one that tells them all."""
        self.report_io = True
        """Pass TxEnable/Transmit actions to the observer too (a trace wants them; a fast
        simulation without a trace does not)."""
        self._apps: tuple[Callable[[Deliver, int], None], ...] = ()
        """The application side (the child's dispatcher; ``add_app``): told every message
        delivered to this robot, in order, before the observers."""
        self.garbage_bytes = 0
        self.frames_heard = 0
        self.frames_failed = 0
        self.refused: dict[str, int] = {}
        """Frames the MAC refused, by kind: ``forged`` and ``replayed`` (the authenticated
        profile), ``out_of_turn`` (clause 39), ``own_id`` (clause 38.2), ``behind`` (clause
        48a, with the checksum), ``ring`` (the ring's other rules, clause 38)."""
        self.behind = 0
        """Message frames whose Number went backwards (clause 48a), refused or not."""
        self.bad_checksum = 0
        """Frames whose crc() was missing or wrong (with the checksum extension: clause 43,
        failed frames; ``frames_heard`` counts them too, as the deframer took them whole)."""
        self._stall = max(cfg.stall_gap, 2 * uart.byte_ticks)
        self._promise: int | None = None
        """The End a failed frame's Length promised, while its turn is to close there: if its
        bytes stop for the stall gap before it, the frame is over then (clause 41)."""
        self._resync_after_tx = False
        self._edge_cleared = -1
        """Tick the receive handler last cleared INT0's edge flag (EIRR bit 0), having read a
        byte: a falling edge on SIN0 after it means a byte has begun (Uart.rx_fall)."""
        self._edge_seen: int | None = None
        """The edge the flag showed at the MAC timer's last look, no Header byte in yet."""
        self.cpu: Cpu | None = None          # run_on: the handlers run on the CPU model
        self._frame_cycles = 0
        self._block_cycles = 0
        """Authenticated profile on the CPU model: the cycles of one SHA-256 compression, run
        for every frame heard and sent (auth.sha256_blocks)."""
        uart.on_rx = self._on_rx
        uart.on_tx_done = self._on_tx_done
        uart.rx_quiet = self.deframer.quiet_for

    def clocked_parts(self) -> tuple:
        """The parts that schedule events of their own (UART0, the two timer channels, the
        CPU model if any): every event of the station is a bound method of one of them."""
        parts = (self.uart, self.timer, self.stall_timer)
        return parts if self.cpu is None else parts + (self.cpu,)

    def use_scheduler(self, sched: Scheduler) -> None:
        """Schedule on ``sched`` from now on, the station and each of its clocked parts: a
        simulator runs a station whose radio is dead on a scheduler of its own for a while
        (hil/sim/quiet_ring.py: it cannot hear or be heard, so it runs on alone)."""
        self.sched = sched
        for part in self.clocked_parts():
            part.sched = sched

    def run_on(self, cpu: Cpu, costs: CycleCosts) -> None:
        """Run the handlers on a CPU model (mcu/cpu.py) with bodies from ``costs``
        (cycle_costs.py): UART0 reception and transmission a byte at a time, the End's
        timer, and the two timer channels, at the levels of interrupts.py."""
        from .interrupts import TMR0, TX_END, UART0_RX, UART0_TX
        self.cpu = cpu
        self._frame_cycles = costs.mac_frame.cycles
        self._block_cycles = costs.sha256_block.cycles if self.mac.cfg.auth is not None else 0
        self.uart.attach_cpu(cpu, UART0_RX, costs.uart_rx_byte.cycles, UART0_TX,
                             costs.uart_tx_byte.cycles, TX_END, costs.uart_tx_done.cycles)
        timer_cycles = costs.mac_timer.cycles
        self.timer.on_expiry = lambda now: cpu.irq(TMR0, timer_cycles, self._on_timer_isr,
                                                   alone=True)
        self.stall_timer.on_expiry = lambda now: self._stall_expired(now, timer_cycles)
        self.stall_timer.guard = self._stall_guard

    def _hash(self, frame) -> None:
        """The authenticated profile's tag of ``frame`` on the CPU model: its SHA-256 blocks
        (the key's padded blocks are hashed once, at start-up), a main-loop task below every
        interrupt, as the firmware runs it (a compression takes ms: in a handler it would
        hold off UART0 and lose bytes). The model's MAC decides at the End regardless; the
        report's latency of ``auth_tag`` says whether the tag is done in time (11 bytes,
        11.4 ms after its covered bytes, docs/cpu.md)."""
        if self._block_cycles:
            from .radio.auth import covered_len, sha256_blocks
            assert self.cpu is not None                   # _block_cycles is set with it
            self.cpu.task(AUTH_TASK, self._block_cycles *
                          sha256_blocks(covered_len(len(frame.content))), _nothing)

    def _stall_guard(self, now: int) -> int | None:
        """The stall timer is due, a frame in progress: if the air is still to hand over
        bytes of it that came late (a good frame's, each of which re-armed the timer on its
        own tick), look again one stall gap after the last of them (ReloadTimer.guard): the
        earliest the timer it re-armed can be due. Bytes handed over before that (a touch,
        a collision or an abort flushes them) re-arm it earlier themselves."""
        if not self.deframer.in_frame:
            return None
        late_until = getattr(self.uart.line, "late_until", None)
        until = late_until(now) if late_until is not None else None
        return until + self._stall if until is not None and until > now else None

    def _stall_expired(self, now: int, cycles: int) -> None:
        """The stall timer's compare matched: its interrupt, unless bytes handed over late
        (Uart.receive's ``late_ok``) re-armed it first, as each had on its own tick."""
        self.uart.sync(now)
        if self.stall_timer.expiry is None:
            assert self.cpu is not None
            self.cpu.irq(RXWATCH, cycles, self._on_stall_isr, alone=True)

    def _on_timer_isr(self) -> None:
        self._on_timer(self.sched.now)

    def _on_stall_isr(self) -> None:
        self._on_stall(self.sched.now)

    # -- interrupt handlers ----------------------------------------------------------------

    def power_on(self) -> None:
        self._apply(self.mac.power_on(self.sched.now))

    def _on_rx(self, data: bytes, t0: int, dt: int, now: int | None = None,
               held: int | None = None) -> None:
        """Bytes from the UART, byte i's stop bit at ``t0 + i * dt``; ``now``: the tick of
        their handler's effects when earlier than the scheduler's (Uart._replay); ``held``:
        all but the last came late, their effects at that tick, given with the last's
        (Uart._rx_isr), as if given apart."""
        if now is None:
            now = self.sched.now
        mac = self.mac
        d = self.deframer
        end = t0 + (len(data) - 1) * dt
        # the last byte's handler clears INT0's edge flag: on the ideal CPU at that byte's
        # tick (bytes handed over in a burst too), else at its effects
        self._edge_cleared = end if self.cpu is None else now
        frame = d.known_frame(data, end)
        if held is not None:
            if frame is None:
                self._on_rx(data[:-1], t0, dt, held)
                self._on_rx(data[-1:], end, dt, now)
                return
            # all but the End in a frame in progress had armed the stall timer, which the
            # End's handler stopped
            stall = end - dt + self._stall + 1
            self.stall_timer.programmed(stall + (stall & 1), held)
        if frame is not None:
            self._promise = None
            self.frames_heard += 1
            if self._frame_cycles:
                assert self.cpu is not None               # _frame_cycles is set with it
                self.cpu.extend(self._frame_cycles)
                self._hash(frame)
            # ``_apply``, inlined: a good frame, every receiver, every frame
            acts = mac.on_frame(frame, t0, end, now)
            if acts:
                self._act(acts)
            dl = mac.deadline
            timer = self.timer
            if dl is None:
                if timer.expiry is not None:
                    timer.stop()
            elif dl != timer.expiry:
                timer.arm_at(dl)
            return
        evs = d.feed(data, t0, dt)
        for ev in evs:
            if type(ev) is FrameReceived:
                self._promise = None
                self.frames_heard += 1
                if self._frame_cycles:
                    assert self.cpu is not None           # _frame_cycles is set with it
                    self.cpu.extend(self._frame_cycles)
                    self._hash(ev.frame)
                self._apply(mac.on_frame(ev.frame, ev.first, ev.end, now), ev)
            elif type(ev) is Garbage:
                self.garbage_bytes += ev.count
                self._apply(mac.on_garbage(ev.first, ev.last, now))
            elif type(ev) is FrameFailed:
                self.frames_failed += 1
                # A frame that fails where its End should be while bytes keep coming had its
                # Length corrupted downwards: its promised end is early, so do not trust it.
                exp = None if ev.error.field == "end" else ev.expected_end
                if self._notify is not None:
                    self._notify(self, ev, now)
                self._apply(mac.on_corrupt(ev.first, ev.src, exp, now), ev)
                self._promise = exp if exp is not None and exp > now else None
        if d.in_frame or self._promise is not None:
            # A frame is coming in (or the rest of one that failed, its turn to close at the
            # End it promised): if its bytes stop it is over one stall gap after the last, and
            # its turn closes then (clause 41; rule R-stagger follows), not at the MAC's next
            # deadline (which may be E + Tmax) nor at the promised End. Its own timer channel,
            # so that the MAC's timer runs the same whether bytes come one by one or in bursts.
            last = d.last_tick
            assert last is not None                       # bytes came in this call
            stall = last + self._stall + 1
            promise = self._promise
            if d.in_frame or (promise is not None and stall < promise):
                # programmed by the last byte's handler: on the ideal CPU at that byte's tick
                # (bytes that came in a burst too), else at its effects (``now``); the timer
                # counts machine clock / 2, so the tick it is programmed at rounds the expiry
                self.stall_timer.arm_at(stall + (stall & 1), now if self.cpu is not None
                                        else last)
                return
            self._promise = None       # the promised End comes first
        if self.stall_timer.expiry is not None:
            self.stall_timer.stop()

    def _on_timer(self, now: int) -> None:
        self.uart.sync(now)
        d = self.deframer
        busy = False
        if d.in_frame:
            if d.last_tick is not None and now - d.last_tick <= self._stall:
                busy = True
            else:
                self._abandon(now)
        hs = d.header_since
        if hs is not None and (d.last_tick is None or now - d.last_tick > self._stall):
            hs = None          # a partial Header whose next byte never came is no Header
        if hs is not None:
            # the Header's first byte is in: its start bit began a byte before it, as far as
            # this UART's byte time tells; or at the edge the flag showed at the last look, if
            # that byte is this one (a foreign 9600 byte is 27 ticks longer than ours)
            began: int | None = hs - self.uart.byte_ticks
            seen = self._edge_seen
            if seen is not None and seen < hs <= seen + 2 * self.uart.byte_ticks:
                began = seen
        else:
            # INT0's edge flag: a falling edge on SIN0 since the last byte was read, so a
            # byte has begun (at that edge's tick: docs/fidelity.md says what the part adds)
            began = self.uart.rx_fall(self._edge_cleared, now)
        self._edge_seen = began
        self._apply(self.mac.on_timer(now, busy, d.last_tick, began))

    def _on_stall(self, now: int) -> None:
        self.uart.sync(now)
        d = self.deframer
        if d.last_tick is None or now - d.last_tick <= self._stall:
            return
        if d.in_frame:
            self._abandon(now)
        elif self._promise is not None:
            promise, self._promise = self._promise, None
            if now < promise:           # a failed frame's bytes stopped before its End
                self._apply(self.mac.on_frame_over(now))

    def _abandon(self, now: int) -> None:
        """The frame coming in stalled: its bytes stopped for the stall gap. It is over now,
        whatever its Length promised (clause 41): closing its turn at the promised End would
        let a cut-off Header (12 bytes promising 562) hold every member for 594 ms. Every
        member hears the bytes stop alike, so they all close the turn at the stall."""
        self._promise = None
        ev = self.deframer.abort(now)
        if ev is not None:
            self.frames_failed += 1
            end = None if ev.expected_end is None else min(ev.expected_end, now)
            self._apply(self.mac.on_corrupt(ev.first, ev.src, end, now), ev)

    def _on_tx_done(self, end: int) -> None:
        self._apply(self.mac.on_tx_done(end))
        if self._resync_after_tx:
            self._resync_after_tx = False
            self._apply(self.mac.resync(self.sched.now))

    def resync(self, late: int) -> None:
        """The firmware's interrupts were not taken for ``late`` ticks, more than the margins
        allow (a bench process stopped or starved; on an MCU, interrupts held off): what it
        knew of the air is stale. A frame half received is dropped (its bytes came before the
        gap), and the MAC listens again before it takes a turn (``RotationalMac.resync``); a
        frame being sent ends first (its bytes are out). Whoever feeds the UART drops what was
        heard during the gap."""
        now = self.sched.now
        self.deframer.reset()
        if self.stall_timer.expiry is not None:
            self.stall_timer.stop()
        if self._notify is not None:
            self._notify(self, Stalled(late), now)
        if self.uart.busy_until > now or self.mac.phase == SEND:
            self._resync_after_tx = True
            return
        self._apply(self.mac.resync(now))

    # -- observers ---------------------------------------------------------------------------

    @property
    def observers(self) -> tuple[Observer, ...]:
        """Who is told every action and observation, in the order they are told."""
        return self._observers

    @property
    def observer(self) -> Observer | None:
        """The one callable that tells every observer (None with none): stable until the list
        changes, so a watcher can tell whether someone else has hooked in."""
        return self._notify

    def add_observer(self, fn: Observer, first: bool = False) -> None:
        """Tell ``fn`` too, after the observers already there (``first``: before them)."""
        self._observers = (fn, *self._observers) if first else (*self._observers, fn)
        self._notify = _told_by(self._observers)

    def remove_observer(self, fn: Observer) -> None:
        """Stop telling ``fn`` (ValueError if it is not an observer)."""
        obs = list(self._observers)
        obs.remove(fn)
        self._observers = tuple(obs)
        self._notify = _told_by(self._observers)

    # -- the application side --------------------------------------------------------------

    @property
    def apps(self) -> tuple[Callable[[Deliver, int], None], ...]:
        """Who is told each message delivered here, ``app(deliver, now)``, in this order."""
        return self._apps

    def add_app(self, fn: Callable[[Deliver, int], None], first: bool = False) -> None:
        """Tell ``fn`` each message delivered, after those already told (``first``: before
        them: the simulator wakes a sleeping CAN side before the firmware acts)."""
        self._apps = (fn, *self._apps) if first else (*self._apps, fn)

    def remove_app(self, fn: Callable[[Deliver, int], None]) -> None:
        """Stop telling ``fn`` (ValueError if it is not told)."""
        apps = list(self._apps)
        apps.remove(fn)
        self._apps = tuple(apps)

    def submit(self, dst: int, commands, type: int = 2):
        """Queue a message for the radio (see RotationalMac.submit)."""
        msg = self.mac.submit(dst, commands, self.sched.now, type)
        if self._notify is not None:
            self._notify(self, msg, self.sched.now)
        self._apply(())
        return msg

    def force_turn(self) -> None:
        """Fault injection: this robot wrongly takes the turn now (see RotationalMac)."""
        self.uart.sync(self.sched.now)      # bytes complete by now are taken first
        self._apply(self.mac.force_turn(self.sched.now))

    # -- actions ---------------------------------------------------------------------------

    def _apply(self, actions, cause=None) -> None:
        if actions:
            self._act(actions)
        dl = self.mac.deadline
        if dl is None:
            if self.timer.expiry is not None:
                self.timer.stop()
        elif dl != self.timer.expiry:
            self.timer.arm_at(dl)

    def _act(self, actions) -> None:
        now = self.sched.now
        obs = self._notify
        for a in actions:
            t = type(a)
            if t is TxEnable:
                self.txen.set(a.on, now)
                if obs is not None and self.report_io:
                    obs(self, a, now)
            elif t is Transmit:
                self.uart.send(a.data)
                if self._block_cycles:
                    self._hash(a.frame)
                if obs is not None and self.report_io:
                    obs(self, a, now)
            else:
                if t is Deliver:
                    for app in self._apps:
                        app(a, now)
                elif t is Refused:
                    k = a.kind or "ring"
                    self.refused[k] = self.refused.get(k, 0) + 1
                elif t is NumberBehind:
                    self.behind += 1
                elif t is BadChecksum:
                    self.bad_checksum += 1
                if obs is not None:
                    obs(self, a, now)


def _nothing() -> None:
    pass


def _told_by(observers: tuple[Observer, ...]) -> Observer | None:
    """One callable for ``observers``: None, the only one, or one that calls each in turn."""
    if not observers:
        return None
    if len(observers) == 1:
        return observers[0]

    def tell_all(st: RadioStation, a: object, now: int) -> None:
        for fn in observers:
            fn(st, a, now)
    return tell_all


def build_station(robot_id: int, sched: Scheduler, byte_ticks: int | None = None,
                  config: MacConfig | None = None,
                  observer: Observer | None = None,
                  radio_switch: tuple[int, int] | None = None) -> tuple[RadioStation, Ptr2000]:
    """A station on simulated peripherals: UART0 at "9600" (or ``byte_ticks``), TXEN on P40,
    wired to a PTR2000 model. Returns the station and its radio (to attach to a channel).
    ``radio_switch``: the module's (TX-ready, RX-ready) switch times in ticks; default the
    data sheet's (firmware_model/mcu/ptr2000.py), whatever the MAC's Ttrans."""
    uart = Uart(sched, byte_ticks=byte_ticks) if byte_ticks else Uart(sched, baud=9600)
    cfg = config or MacConfig()
    radio = Ptr2000(robot_id, *radio_switch) if radio_switch is not None else Ptr2000(robot_id)
    radio.uart = uart
    uart.line = radio
    txen = OutputPin("P40/TXEN")
    txen.listeners.append(radio.set_txen)
    station = RadioStation(robot_id, sched, uart, txen, cfg, observer)
    return station, radio

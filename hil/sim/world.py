"""The simulated world: N robots' radio firmware on one virtual air, driven as fast as the CPU
goes by one integer-tick scheduler.

Everything random (noise, byte errors, load) is drawn from streams seeded by ``seed``, so the
same configuration gives the same trace to the tick.

The world wires robots, air, CAN sides, load and faults and feeds the accounting; the parts
live elsewhere: the settings and their checks in config.py, the load in load.py, the
accounting and the summary in ledger.py, the air in air.py, the faults in faults.py.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import replace
from typing import Any, Callable, Iterable, Iterator, cast

from can_bus.bits import BitTiming
from can_bus.bus import CanBus
from can_bus.dbc import STATE_MOVING
from can_bus.submodules import make_submodules
from can_bus.transceiver import Transceiver82C250
from firmware_model.child import ChildFirmware
from firmware_model.kinematics import HOME
from firmware_model.mcu.can_controller import CanController
from firmware_model.mcu.cpu import Cpu
from firmware_model.mcu.scheduler import Event
from firmware_model.sequence import ACTION_NAMES
from firmware_model.radio.content import Command, frame_kind
from firmware_model.radio.mac import (
    MacConfig, Message, Outcome, RotationalMac, SubmitError,
)
from firmware_model.radio.station_mac import StationMac
from firmware_model.station import RadioStation, build_station
from firmware_model.timing import CHILD_BYTE_TICKS, PC_BYTE_TICKS, TICK_HZ, s_to_ticks

from .air import Air
from .reception import Transmission
from . import world_faults, world_observe
from .world_observe import STANDBY
from .collector import fewer_collections
from .config import ConfigError, SimConfig
from .faults import Fault, schedule as schedule_fault, skewed_mac
from .ledger import Ledger, Tally, summary
from .load import Load
from .can_ghosts import CanCpuPort, CruisingWheel
from .quiet_can import PERIOD as CAN_PERIOD, QuietCan, notes_only, refuses_only
from .quiet_ring import QuietRing
from .domains import PlacedSimScheduler, SimScheduler
from . import events as E
from .events import Listener, RecordListener
from .realtime import RealTimeScheduler
from .trace import TRACE_VERSION, TraceWriter

__all__ = ["World", "SimConfig", "ConfigError", "Fault", "CAN_TIMING", "STANDBY", "EXTRA",
           "RecordsNotKept"]
"""The world, and the names its users take from here: the config, its error, a fault."""


class RecordsNotKept(RuntimeError):
    """A run record read from a world that does not keep them (``SimConfig.keep_records``)."""


CAN_TIMING = BitTiming()
"""500 kbit/s: 2 ticks a time quantum, 16 quanta a bit (docs/can.md)."""


EXTRA = 200
"""``World.radios`` holds the k-th of ``SimConfig.extra`` at EXTRA + k."""


class World:
    """Robots, air and scheduler; ``run()`` advances simulated time."""

    STEADY_COUNTERS = ("transmissions",)
    """Counts only (reports): the fast paths may move it on by any amount (hil/sim/steady.py)."""

    def __init__(self, config: SimConfig, trace: TraceWriter | None = None,
                 on_event: Callable[[dict], None] | None = None,
                 listeners: Iterable[Listener] = ()) -> None:
        """``trace`` writes the run's events to its file; ``listeners`` get each event
        (hil/sim/events.py), the meta first; ``on_event`` gets each as its record, the JSON
        line's object (:class:`hil.sim.events.RecordListener`)."""
        config.validate()
        self.cfg = config
        # (on the CPU model, a lone handler's one event stands in for two: PlacedScheduler)
        self.sched = RealTimeScheduler() if config.realtime else \
            PlacedSimScheduler() if config.cpu is not None else SimScheduler()
        self.trace = trace
        self.listeners: list[Listener] = []
        """Called with every event, in order (python-can's ``Notifier`` is the model): the
        trace writer first, then ``on_event``'s, then ``listeners``; :meth:`add_listener`."""
        if trace is not None:
            self.listeners.append(trace.write)
        if on_event is not None:
            self.listeners.append(RecordListener(on_event))
        self.listeners.extend(listeners)
        self.quiet_ring: QuietRing | None = None
        self.pcap = None
        # On the CPU model every received byte is its own interrupt: the air hands each byte
        # over on its stop-bit tick, or, while the receiver's CPU has nothing else to do, a
        # clean prefix late (docs/fast-paths.md, "Late bytes on an idle CPU"); with the fast
        # paths off, every byte at its tick
        self.air = Air(self.sched, seed=config.seed, ber=config.ber, noise=config.noise,
                       byte_by_byte=config.byte_by_byte or
                       (config.cpu is not None and not config.fast_paths))
        self.air.on_transmission = self._on_transmission
        self.air.on_collision = self._on_collision
        base = config.mac or MacConfig()
        base = replace(base, team=frozenset(config.robots))
        if config.noise:     # a radio that outputs noise without a carrier is never quiet
            base = replace(base, quiet_channel=False)
        if not config.fast_paths:
            base = replace(base, fast_path=False)
        self.mac_config = base
        self.stations: dict[int, RadioStation] = {}
        self.children: dict[int, ChildFirmware] = {}
        self.cpus: dict[int, Cpu] = {}
        self._dispatch_latency: list[tuple[int, int, int]] | None = \
            [] if config.keep_records else None       # (robot, End tick, SOF tick)
        self.dispatch_latency_ticks: Counter[int] = Counter()
        """The dispatcher latencies (ticks from a radio End to its order's first CAN SOF),
        counted per value."""
        self.can_buses: dict[int, CanBus] = {}
        self.submodules: dict[int, dict] = {}
        self._can_tally: dict[int, Tally] = {}
        self.quiet: dict[int, QuietCan] = {}
        """Each child's CAN side as a domain that sleeps while it only repeats itself
        (hil/sim/quiet_can.py; on the CPU model its interrupts still come, as ghosts:
        hil/sim/can_ghosts.py)."""
        self.actions: list[tuple[int, int, int, str]] = []   # (tick, robot, action, phase)
        self.transmissions = 0
        """Transmissions started on the air so far (a count: a 24-hour run keeps no list)."""
        self.action_turns: list[int] = []
        """``transmissions`` when each entry of ``actions`` happened."""
        self.radios = {}
        self.ledger = ledger = Ledger(config.robots, keep=config.keep_records,
                                      same_turn=base.tmax // 2)
        """The run's accounting (hil/sim/ledger.py); its parts are the world's too."""
        self.stats, self.membership, self.identity = ledger.stats, ledger.membership, \
            ledger.identity
        self.collisions = 0
        self.observed = 0
        """Actions the MACs reported to the world (a count: :meth:`activity`)."""
        self.load = Load(config, self.sched, self.stations, self.submit)
        """The configured load (hil/sim/load.py)."""
        self.byte_ticks = {r: (PC_BYTE_TICKS if r == 0 else CHILD_BYTE_TICKS)
                           for r in config.robots}
        skew = {f.robot: f.value for f in config.faults        # (a skew names both: faults.py)
                if f.kind == "skew" and f.robot is not None and f.value is not None}
        for r, eps in skew.items():
            self.byte_ticks[r] = round(self.byte_ticks[r] * (1 + eps))
        for r in sorted(config.robots):
            cfg = replace(base, byte_ticks=self.byte_ticks[r],
                          paired=r == 0 and config.father_standby)
            if r in skew:
                cfg = skewed_mac(cfg, skew[r])
            st, radio = build_station(r, self.sched, byte_ticks=self.byte_ticks[r], config=cfg,
                                      observer=self._observe,
                                      radio_switch=config.radio_switch.get(r))
            if config.mac_kind != "rotational":
                from firmware_model.radio.peer_macs import make_mac
                st.mac = make_mac(config.mac_kind, r, st.mac.cfg, seed=config.seed,
                                  peer=config.peer)
            st.report_io = bool(self.listeners)
            self.air.attach(radio)
            if r in skew:
                self.air.set_skew(radio, skew[r])   # its PTR2000 switches as the part does
            radio.alive = False
            self.stations[r] = st
            self.radios[r] = radio
            if config.can and r != 0:
                self._build_can_side(r, st)
            elif config.cpu is not None and r != 0:
                self.cpus[r] = Cpu(self.sched, config.cpu, name=f"MB90F549-R{r}", order=r)
                self.cpus[r].fuse = config.fast_paths
                st.run_on(self.cpus[r], config.cpu)
            self.sched.at(s_to_ticks(config.power_on.get(r, 0.0)), self._power_on, r)
        self.standby_station: RadioStation | None = None
        if config.father_standby:
            cfg = replace(base, byte_ticks=PC_BYTE_TICKS, standby=True, pc=2, paired=True)
            st, radio = build_station(0, self.sched, byte_ticks=PC_BYTE_TICKS, config=cfg,
                                      observer=self._observe)
            self.air.attach(radio)
            radio.alive = False
            self.standby_station = st
            self.radios[STANDBY] = radio
            self.stations_extra = {STANDBY: st}
            self.sched.at(s_to_ticks(config.power_on.get(0, 0.0)), self._power_on_standby)
        self.extra_stations: dict[int, RadioStation] = {}
        """The ``extra`` robots by ``EXTRA + k`` (k from 1), their radios in ``radios``."""
        # keyed by the object (identity), never by id(): a pickled world keeps no ids
        self._extra_of: dict[RadioStation, int] = {}
        self._extra_radio: dict[object, int] = {}
        for k, (r, t, team) in enumerate(config.extra, 1):
            bt = PC_BYTE_TICKS if r == 0 else CHILD_BYTE_TICKS
            cfg = replace(base, byte_ticks=bt, seed=base.seed + k)
            if team is not None:
                cfg = replace(cfg, team=frozenset(team))
            st, radio = build_station(r, self.sched, byte_ticks=bt, config=cfg,
                                      observer=self._observe)
            st.report_io = bool(self.listeners)
            self.air.attach(radio)
            self.air.uncounted.add(radio)         # its frames are no ring robot's
            radio.alive = False
            self.extra_stations[EXTRA + k] = st
            self._extra_of[st] = k
            self._extra_radio[radio] = k
            self.radios[EXTRA + k] = radio
            self.sched.at(s_to_ticks(t), self._power_on_extra, k)
        self._cpu_busy: dict[int, int] = {}
        self._cpu_clock: Event | None = None
        self._io_reported()                    # (the CPU loads, while someone listens)
        self.fault_count: dict[str, int] = {}
        for f in config.faults:
            if f.kind != "skew":
                schedule_fault(self.sched, f, self._fault, self._fault_end)
        self.end_tick = s_to_ticks(config.duration)
        # The radio side as a whole, moved on in whole cycles while it only repeats itself
        # (hil/sim/quiet_ring.py; the trace and the event callback get the events of the
        # cycles leapt over); none on the wall's clock, nor with CAN sides that a trace keeps
        # awake (QuietCan.may_sleep): it could never leap there; nor with the authenticated
        # profile, whose frames never repeat (a new freshness each). On the CPU model, only
        # without CAN sides (their interrupts meet the radio's on the CPU at ticks no ring
        # cycle repeats, asleep or not) and untraced (the per-second CPU loads never repeat
        # with the ring).
        watched = bool(self.listeners)
        if config.ring_sleep and config.fast_paths and config.mac_kind == "rotational" \
                and not config.realtime \
                and base.auth is None \
                and not (config.cpu is not None and (config.can or watched)) \
                and not (watched and self.quiet) and not config.extra:
            ring = self.quiet_ring = QuietRing(self, min(config.robots), base.poll_every,
                                               config.father_standby)
            for q in self.quiet.values():
                ring.boundary += [q, q.clock, *q.roots]
        self.meta = E.Meta(
            version=TRACE_VERSION, tick_hz=TICK_HZ,
            byte_ticks={str(r): self.byte_ticks[r] for r in sorted(config.robots)},
            ttrans=base.ttrans, tmax=base.tmax, twin=base.twin, tslot=base.tslot,
            miss_limit=base.miss_limit, robots=tuple(sorted(config.robots)), seed=config.seed,
            mac=config.mac_kind, ber=config.ber, noise=config.noise, load=config.load,
            duration_ticks=self.end_tick,
            can_bitrate=int(CAN_TIMING.bitrate) if config.can else None)
        """The run's settings, the trace's first line (given to the listeners first)."""
        for fn in self.listeners:
            fn(self.meta)

    def _build_can_side(self, r: int, st: RadioStation) -> None:
        quiet = QuietCan(self.sched, name=f"R{r} CAN", order=r)
        clock = quiet.clock
        bus = CanBus(clock, CAN_TIMING)
        ctrl = CanController(clock, CAN_TIMING)
        xcvr = Transceiver82C250(bus, ctrl, name=f"82C250-R{r}")
        # on the CPU model, the CAN side's interrupts go through a port that raises them as
        # ghosts while it sleeps (hil/sim/can_ghosts.py)
        port = quiet.port = CanCpuPort(quiet) if self.cfg.cpu is not None else None
        child = ChildFirmware(st, ctrl, xcvr, costs=self.cfg.cpu, clock=clock,
                              can_cpu=port.attach if port is not None else None)
        self.children[r] = child
        if self.cfg.cpu is not None:
            self.cpus[r] = child.cpu
            child.cpu.fuse = self.cfg.fast_paths
        child.on_action = self._on_action
        if self.cfg.sequence is not None and r in self.cfg.sequence[0]:
            child.run_sequence(*self.cfg.sequence)
        self.can_buses[r] = bus
        self.submodules[r] = make_submodules(clock, bus, initial_angles=HOME)
        if port is not None:
            port.wheel = CruisingWheel(self.submodules[r]["WHEEL"], bus.tpb)
        tally = self._can_tally[r] = Tally()
        bus.trace = lambda frame, start, end, winner, r=r, tally=tally: \
            self._on_can(r, tally, frame, start, end)
        self._make_domain(r, quiet, st, [bus, ctrl, xcvr, child, self.submodules[r], tally])

    def _make_domain(self, r: int, quiet: QuietCan, st: RadioStation, parts: list) -> None:
        """Child ``r``'s CAN side sleeps while it only repeats itself; whatever reaches it
        from the radio wakes it first."""
        bus, child, nodes = self.can_buses[r], self.children[r], self.submodules[r]
        world_trace = bus.trace
        quiet.roots = parts
        quiet.boundary = [st, self.sched]
        if quiet.port is not None:       # the CPU model's: the radio's as much as the CAN's
            quiet.boundary += [child.cpu, quiet.port]
        quiet.enabled = (self.cfg.can_sleep and self.cfg.fast_paths and not self.cfg.realtime
                         and self.cfg.sequence is None)
        quiet.may_sleep = lambda: (
            not self.listeners and self.pcap is None
            and bus.trace is world_trace and bus.error_trace is None
            and not child.dispatcher.jobs and not child.cpu_work
            and all(n.state != STATE_MOVING or n.cruising for n in nodes.values()))
        quiet.drifting = lambda: any(n.cruising for n in nodes.values())

        def wake_for(d, now: int) -> None:
            """Told before the firmware: its CAN side is up to the tick when it acts."""
            quiet.touched()
            if quiet.asleep and notes_only(child, d):
                quiet.noted += 1             # news only noted: the CAN side sleeps on
            elif quiet.asleep and refuses_only(child, d):
                quiet.refused += 1           # orders refused at once: it sleeps on too
            else:
                quiet.wake(work=True)
        st.add_app(wake_for, first=True)
        self.quiet[r] = quiet
        quiet.start(self.sched.now + CAN_PERIOD)

    def wake_can(self) -> None:
        """Bring every child's CAN side up to the tick now (before reading it)."""
        for q in self.quiet.values():
            q.wake()

    @property
    def can_frames(self) -> int:
        """CAN frames sent without error, on every child's bus."""
        self.wake_can()
        return sum(t.frames for t in self._can_tally.values())

    def capture(self, sink) -> None:
        """Send every transmission and CAN frame to ``sink`` (hil.sim.pcap.PcapWriter's
        methods ``radio``, ``can``, ``can_error``), keyed as ``capture_interfaces`` names."""
        self.pcap = sink
        for q in self.quiet.values():
            q.disable()
        self._radio_key = {radio: key for key, radio in self.radios.items()}
        for r, bus in self.can_buses.items():
            bus.error_trace = (lambda kind, frame, start, now, idle, tx, r=r:
                               sink.can_error(r, now, kind, f"error frame ({kind}) in "
                                              f"{frame.id:#05x}" if frame else kind))

    def capture_interfaces(self) -> tuple[dict[object, str], dict[int, str]]:
        """(radio key -> interface name, CAN bus -> interface name) for a capture."""
        radios: dict[object, str] = {key: ("PC2 (standby father)" if key == STANDBY else
                        "father 0" if key == 0 else f"R{key}") + " radio"
                  for key in self.radios}
        radios["foreign"] = "foreign transmitters"
        return radios, {r: f"R{r} CAN" for r in self.can_buses}

    def _cpu_second(self, first: bool) -> None:
        """Each simulated second while someone listens: every child's CPU load over that
        second (the share of its machine cycles spent in handlers and main-loop work), in the
        trace. ``first``: the clock started during the second now ending, which gives only
        the figures the next second is counted from. Nobody listening, no clock: the figures
        a leap over an idle ring moves on are the CPU's own (``Cpu.busy``, its handlers'
        counts), and a second's tick, never a multiple of the ring's period, would keep
        it from leaping (hil/sim/quiet_ring.py)."""
        for r, cpu in sorted(self.cpus.items()):
            busy = cpu.busy
            if not first:
                self._emit(E.CpuLoad(t=self.sched.now, robot=r,
                                     load=round((busy - self._cpu_busy[r]) / TICK_HZ, 6)))
            self._cpu_busy[r] = busy
        self._cpu_clock = self.sched.after(TICK_HZ, self._cpu_second, False)

    def _on_action(self, robot: int, action: int, phase: str, now: int) -> None:
        self.actions.append((now, robot, action, phase))
        self.action_turns.append(self.transmissions)
        if self.listeners:
            self._emit(E.Action(t=self.sched.now, robot=robot, phase=phase,
                                name=ACTION_NAMES.get(action, str(action))))

    def _on_can(self, r: int, tally: Tally, frame, start: int, end: int) -> None:
        tally.frames += 1
        if self.pcap is not None:
            self.pcap.can(r, end, frame.id, frame.data, frame.rtr, frame.dlc)
        child = self.children.get(r)
        lat = child.latency_from if child is not None else None
        if lat is not None and (frame.id, bytes(frame.data)) == lat[1:]:
            # an order's first CAN frame on the bus: the dispatcher's latency
            assert child is not None               # (lat is its latency_from)
            cause, child.latency_from = lat[0], None
            self.dispatch_latency_ticks[start - cause] += 1
            if self._dispatch_latency is not None:
                self._dispatch_latency.append((r, cause, start))
            if self.listeners:
                self._emit(E.Dispatch(t=self.sched.now, robot=r, end=cause, sof=start,
                                      latency=start - cause))
        if self.listeners:
            self._emit(E.CanFrameOnBus(t=self.sched.now, bus=r, id=frame.id,
                                       data=frame.data.hex(), start=start, end=end))

    # -- running --------------------------------------------------------------------------

    def run(self, until: int | None = None) -> None:
        """Advance to tick ``until`` (default: the configured duration), every child's CAN
        side brought up to that tick, so that any part may be read at once."""
        self._advance(until)
        self.wake_can()

    def run_in_steps(self, step: int) -> Iterator[int]:
        """Run to the end ``step`` ticks at a time, yielding the tick reached after each (for
        a progress bar, which reads only the clock); at the end as :meth:`run` leaves it.
        Between steps a sleeping CAN side sleeps on (hil/sim/quiet_can.py): a step costs no
        more than the stretch it runs."""
        while self.now < self.end_tick:
            self._advance(self.now + step)
            yield self.now
        self.wake_can()

    def _advance(self, until: int | None = None) -> None:
        """Advance to tick ``until`` without waking a sleeping CAN side (the radio side and
        the clock are up to date; :meth:`wake_can`, :meth:`summary` and whatever reads a CAN
        part wake it): for callers in this package that read only the radio side between
        steps (the soak's ring check)."""
        end = self.end_tick if until is None else min(until, self.end_tick)
        ring = self.quiet_ring
        if ring is not None:
            ring.start_run(end)
        try:
            with fewer_collections():
                self.sched.run_until(end)
        finally:
            if ring is not None:
                ring.end_run()
        if not self.cpus:
            return
        if ring is not None and any(self.air.late_until(radio, end) is not None
                                    for radio in self.radios.values()):
            ring.forget()                # the settling below hands those bytes over now
        for cpu in self.cpus.values():   # every event of tick ``end`` has run (Cpu._settle)
            cpu.settle(final=True)

    @property
    def now(self) -> int:
        return self.sched.now

    @property
    def corrupt_deliveries(self) -> int:
        """Deliveries of what no sender submitted (the ledger's count)."""
        return self.ledger.corrupt_deliveries

    @property
    def wrong_deliveries(self) -> int:
        """Deliveries to a robot the message was not for (the ledger's count)."""
        return self.ledger.wrong_deliveries

    # -- events from the parts ------------------------------------------------------------

    def add_listener(self, fn: Listener) -> None:
        """Call ``fn`` with every event from now on (after those already listening). It
        misses the meta event, given at construction: a listener that needs it (a waveform
        writer) is one of the constructor's ``listeners``, or reads :attr:`meta`."""
        self.listeners.append(fn)
        self._io_reported()

    def _io_reported(self) -> None:
        """The stations report their radio's switching (TXEN), and the CPUs their load each
        second (:meth:`_cpu_second`: from the start, or from the first whole second after the
        first listener came), only while someone listens."""
        sb = self.standby_station
        for st in [*self.stations.values(), *self.extra_stations.values(),
                   *([sb] if sb is not None else [])]:
            st.report_io = bool(self.listeners)
        if not self.cpus:
            return
        if self.listeners and self._cpu_clock is None:
            now = self.sched.now
            if now == 0:
                self._cpu_busy = {r: 0 for r in self.cpus}
                self._cpu_clock = self.sched.at(TICK_HZ, self._cpu_second, False)
            else:
                self._cpu_clock = self.sched.at(-(-now // TICK_HZ) * TICK_HZ,
                                                self._cpu_second, True)
        elif not self.listeners and self._cpu_clock is not None:
            self._cpu_clock.cancel()
            self._cpu_clock = None

    def remove_listener(self, fn: Listener) -> None:
        """Stop calling ``fn`` (ValueError if it is not listening)."""
        self.listeners.remove(fn)
        self._io_reported()

    def _emit(self, ev: E.TraceEvent) -> None:
        """Give ``ev`` to every listener; callers build it only when there is one."""
        for fn in self.listeners:
            fn(ev)
        ring = self.quiet_ring
        if ring is not None:
            ring.note(ev)

    def replay(self, ev: Any, sink: str = "trace") -> None:
        """Give the listeners an event the ring did not run but whose place it knows (a cycle
        it leapt over, shifted: hil/sim/quiet_ring.py), or with ``sink`` "pcap" write a packet
        to the capture (``ev``: ``PcapWriter.radio``'s arguments)."""
        if sink == "pcap":
            assert self.pcap is not None           # (a packet is replayed only to a capture)
            self.pcap.radio(**ev)
            return
        for fn in self.listeners:
            fn(ev)

    def _power_on(self, r: int) -> None:
        radio = self.radios[r]
        self.air.revive(radio, self.sched.now)
        if self.listeners:
            self._emit(E.Power(t=self.sched.now, robot=r))
        self.stations[r].power_on()
        self.load.start(r)

    def _power_on_extra(self, k: int) -> None:
        self.air.revive(self.radios[EXTRA + k], self.sched.now)
        if self.listeners:
            self._emit(E.Power(t=self.sched.now, robot=self.extra_stations[EXTRA + k].id,
                               extra=k))
        self.extra_stations[EXTRA + k].power_on()

    def _power_on_standby(self) -> None:
        self.air.revive(self.radios[STANDBY], self.sched.now)
        if self.listeners:
            self._emit(E.Power(t=self.sched.now, robot=0, pc=2))
        assert self.standby_station is not None   # (scheduled only when there is one)
        self.standby_station.power_on()

    _fault = world_faults._fault
    _fault_end = world_faults._fault_end
    _fault_act = world_faults._fault_act
    inject = world_faults.inject
    inject_bytes = world_faults.inject_bytes

    def _on_transmission(self, tx: Transmission) -> None:
        r = tx.radio.robot
        self.transmissions += 1
        if self.quiet_ring is not None:
            self.quiet_ring.heard(tx)
        if self.pcap is not None:
            sent = tx.data if not tx.aborted else tx.data[:(tx.end - tx.t0) // tx.bt]
            marks = [w for w, on in (
                ("continued: the rest of a paused frame", tx.continued),
                ("collided", tx.collided),
                ("aborted: the sender's radio died", tx.aborted and not tx.paused),
                ("paused: the sender's transmit handler was late; the frame goes on in its "
                 "next packet", tx.paused)) if on]
            if r < 0:
                marks.insert(0, "a transmitter that is no robot")
            packet = {"key": self._radio_key.get(tx.radio, "foreign"), "end": tx.end,
                      "data": sent, "comment": "; ".join(marks) or None}
            self.pcap.radio(**packet)
            if self.quiet_ring is not None:
                self.quiet_ring.note(packet, "pcap")
        if not self.listeners:
            return
        if r < 0:                      # injected bytes or interference, not a robot
            self._emit(E.Interference(t=self.sched.now, start=tx.t0, end=tx.end,
                                      bytes=(tx.end - tx.t0) // tx.bt, collided=tx.collided))
            return
        d = tx.data
        dst: int | None
        num: int | None
        typ: int | None
        n: int | None
        kind: str | None
        try:
            dst, num, typ, n = d[3] - 48, int(d[5:7]), d[7] - 48, int(d[8:12])
            kind = frame_kind(typ, d[12:12 + n])
        except (IndexError, ValueError):
            dst = num = typ = n = kind = None
        pc = extra = None
        if tx.radio is self.radios.get(STANDBY):
            pc = 2
        elif self._extra_of and tx.radio.robot in self.cfg.robots:
            extra = self._extra_radio.get(tx.radio)  # a twin's: the src of a ring robot
        self._emit(E.FrameOnAir(
            t=self.sched.now, src=r, dst=dst, num=num, type=typ, len=n, kind=kind,
            start=tx.t0, end=tx.end,
            bytes=len(d) if not tx.aborted else (tx.end - tx.t0) // tx.bt,
            collided=tx.collided, aborted=tx.aborted and not tx.paused,
            paused=True if tx.paused else None, continued=True if tx.continued else None,
            pc=pc, extra=extra))

    def _on_collision(self, t0: int, robots: list[int]) -> None:
        self.collisions += 1
        if self.listeners:
            self._emit(E.Collision(t=self.sched.now, robots=tuple(robots)))

    def activity(self) -> tuple[int, ...]:
        """Changes whenever a MAC reports something (any action but its own I/O), two
        transmissions collide, bytes are injected or a run record grows (:meth:`records`): a
        ring that only repeats itself leaves it as it was (hil/sim/quiet_ring.py)."""
        led = self.ledger
        return (self.observed, self.air.collisions, self.air.bursts, led.submitted_count,
                led.ended_count, len(led.membership), self.dispatch_latency_ticks.total())

    def records(self) -> list[object]:
        """The run's records: the accounting (hil/sim/ledger.py) and the dispatcher latencies.
        They only grow, what the MACs report grows them (:meth:`activity` changes then), and no
        part of the model reads them to act: a snapshot of the ring leaves them out, so its
        cost stays that of the ring's state, however long the run."""
        led = self.ledger
        return [x for x in (led, led.membership, led.identity, self.dispatch_latency_ticks,
                            self._dispatch_latency) if x is not None]

    def _kept(self, records: Any, name: str) -> Any:
        if records is None:
            raise RecordsNotKept(f"this run keeps no {name}: SimConfig(keep_records=True) keeps "
                                 f"every message, outcome, delivery and dispatcher latency")
        return records

    @property
    def messages(self) -> list[Message]:
        """Every message submitted, in order (``keep_records``; else RecordsNotKept)."""
        return self._kept(self.ledger.messages, "messages")

    @property
    def outcomes(self) -> list[Outcome]:
        """Every message's outcome, in order (``keep_records``)."""
        return self._kept(self.ledger.outcomes, "outcomes")

    @property
    def deliveries(self) -> Counter:
        """(src, num, submit serial, receiver) -> deliveries (``keep_records``)."""
        return self._kept(self.ledger.deliveries, "deliveries")

    @property
    def dispatch_latency(self) -> list[tuple[int, int, int]]:
        """(robot, End tick, SOF tick) of every order's first CAN frame (``keep_records``;
        the summary's figures come from :attr:`dispatch_latency_ticks`)."""
        return self._kept(self._dispatch_latency, "dispatcher latencies")

    _observe = world_observe._observe
    _observe_extra = world_observe._observe_extra

    # -- the world's parts ----------------------------------------------------------------

    def hooks(self) -> tuple:
        """What is called with each transmission, collision and station action: the world's
        own handlers as built, unless someone has put a hook of their own in (quiet_ring.py
        does not leap then: the hook would miss the frames leapt over)."""
        sb = self.standby_station
        stations = [*self.stations.values(), *([sb] if sb is not None else [])]
        return (self.air.on_transmission, self.air.on_collision,
                *(st.observer for st in stations))

    def deaf_stations(self) -> list[RadioStation]:
        """Stations whose radio is dead now (a ``fail`` fault, or not powered on yet): they
        neither hear nor are heard, and touch nothing of the air's (hil/sim/air.py), so each
        runs on alone (hil/sim/quiet_ring.py carries them across the ring's leaps)."""
        out = [st for r, st in self.stations.items() if not self.radios[r].alive]
        sb = self.standby_station
        if sb is not None and not self.radios[STANDBY].alive:
            out.append(sb)
        return out

    def station_of(self, robot: int) -> RadioStation:
        """The station that speaks for ``robot`` now (for the father: its active PC)."""
        st = self.stations[robot]
        sb = self.standby_station
        if robot == 0 and sb is not None and _paired(st).standby and not _paired(sb).standby:
            return sb
        return st

    def submit(self, src: int, dst: int, commands: Iterable[Command], type: int = 2):
        """Submit a message at ``src`` now; a refused one is counted and re-raised."""
        try:
            return self.station_of(src).submit(dst, list(commands), type)
        except SubmitError:
            self.stats[src].refused += 1
            raise

    # -- results --------------------------------------------------------------------------

    def alive(self) -> tuple[int, ...]:
        """Robots whose radio works now (the father counts if either PC's does)."""
        out = [r for r in self.cfg.robots if self.radios[r].alive]
        if 0 in self.cfg.robots and 0 not in out and STANDBY in self.radios and \
                self.radios[STANDBY].alive:
            out.append(0)
        return tuple(sorted(out))

    def ring_complete(self) -> bool:
        """Every robot whose radio works is a member of a ring of exactly those robots (for
        the father: exactly one of its PCs is active)."""
        alive = self.alive()
        for r in alive:
            if r == 0 and self.standby_station is not None:
                pcs = ((_paired(self.stations[0]), self.radios[0]),
                       (_paired(self.standby_station), self.radios[STANDBY]))
                macs: list[StationMac] = [m for m, radio in pcs
                                          if radio.alive and not m.standby]
                if len(macs) != 1:
                    return False
            else:
                macs = [self.stations[r].mac]
            if any(m.mode != "member" or m.ring != alive for m in macs):
                return False
        return True

    def ring_views(self) -> dict[int, tuple[int, ...]]:
        """Each robot's current ring (empty while it listens)."""
        return {r: st.mac.ring for r, st in self.stations.items()}

    def summary(self) -> dict:
        """The figures of the paper's simulator (Fig. 9) and the delivery accounting
        (hil/sim/ledger.py)."""
        return summary(self)


def _paired(st: RadioStation) -> RotationalMac:
    """The MAC of a station of a ring with the father's PC pair: the rotational MAC
    (hil/sim/config.py refuses a standby PC with the peer MACs)."""
    return cast(RotationalMac, st.mac)

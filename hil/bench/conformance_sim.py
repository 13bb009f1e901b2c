"""The conformance kit in simulated time: the tester a station on the simulator's air, the
robot under test the project's child firmware model, in one deterministic run.

:class:`SimLink` is a :class:`hil.bench.conformance.TesterLink`. It builds what ``rprs child
--id ID --radio PORT --team TEAM --profile PROFILE`` runs (the station with the real-time
margins, ``hil.bench.runner.realtime_config``, and the radio-only child that answers orders
``fail(42)``) on a :class:`firmware_model.mcu.scheduler.Scheduler`, its PTR2000 on a
:class:`hil.sim.air.Air`; the tester's radio is a node on the same air, as the radio hub
attaches a pty (hil/bench/radio_hub.py): its bytes go on air when written, at the PC's byte
time (16 667 ticks), and it is deaf while they are on air and for the PTR2000's RX-ready
delay after. ``idle(ticks)`` runs the scheduler on; ``now()`` is its tick; what the tester
hears comes back with the tick each byte was complete. The same seed gives the same run.

The child powers on at tick 0 and the tester starts ``lead_s`` later (a user starts the kit
once the robot runs); ``now()`` counts from tick 0.
"""
from __future__ import annotations

import io
from dataclasses import replace
from typing import Callable

from firmware_model.child import RadioOnlyChild
from firmware_model.mcu.ptr2000 import NEVER
from firmware_model.mcu.scheduler import Event, Scheduler
from firmware_model.radio.auth import RingKey
from firmware_model.radio.mac import MacConfig
from firmware_model.station import RadioStation, build_station
from firmware_model.timing import CHILD_BYTE_TICKS, PC_BYTE_TICKS, PTR2000_RX_READY_TICKS, \
    s_to_ticks

from ..sim.air import Air
from .runner import _events_printer, realtime_config


class _Uart:
    __slots__ = ("byte_ticks",)

    def __init__(self, byte_ticks: int) -> None:
        self.byte_ticks = byte_ticks


class _PcRadio:
    """The tester's radio on the air (the interface hil.sim.air.Air drives, as the hub's pty
    nodes): what it hears is kept for :meth:`SimLink.read`."""

    __slots__ = ("robot", "idx", "alive", "rx_from", "rx", "noise_from", "uart", "channel",
                 "heard")

    def __init__(self, robot: int) -> None:
        self.robot = robot
        self.idx = 0
        self.alive = True
        self.rx_from = 0
        self.rx = None
        self.noise_from = 0
        self.uart = _Uart(PC_BYTE_TICKS)
        self.channel = None
        self.heard: list[tuple[bytes, int, int]] = []

    def listening(self, t: int) -> bool:
        return self.alive and t >= self.rx_from

    def deliver(self, data: bytes, t0: int, dt: int, late_ok: bool = False,
                lead: int = 0) -> None:
        self.heard.append((data, t0, dt))


class SimLink:
    """The tester (ID ``tester``) and robot ``robot`` on one simulated air.

    ``profile``, ``team``: the robot's (``--profile``, ``--team``); ``seed``: the air's and
    the robot's MAC's random draws; ``lead_s``: seconds the robot runs before the tester
    starts. ``key``: the ring key (``--auth-key``, the authenticated profile); the robot's
    freshness counter starts at 0 (a bench process seeds it from its clock: only rising
    matters). ``checksum``: the robot's checksum extension (``--checksum``, clause 20).
    ``patch``: called with the station and its child once they are built and before the
    robot powers on (a test breaks a rule of the robot's there). ``events``: the robot's
    MAC events as JSON lines, as ``rprs child --events`` prints them. ``transmissions``: every
    transmission that left the air, ``(ID, first tick, End tick, collided)``, the tester's
    and the robot's, in the order they ended."""

    def __init__(self, robot: int, profile: str = "rprs", team: tuple[int, ...] = tuple(range(7)),
                 tester: int = 0, seed: int = 1, lead_s: float = 1.0,
                 patch: Callable[[RadioStation, RadioOnlyChild | None], None] | None = None,
                 key: RingKey | None = None, checksum: bool = False) -> None:
        self.sched = Scheduler()
        self.air = Air(self.sched, seed=seed)
        self.transmissions: list[tuple[int, int, int, bool]] = []
        self.air.on_transmission = lambda tx: self.transmissions.append(
            (tx.radio.robot, tx.t0, tx.end, tx.collided))
        # rprs child's configuration, but its MAC's seed from ``seed``, not from the OS
        cfg = realtime_config(MacConfig(team=frozenset(team), profile=profile,
                                        seed=1000 + seed, auth=key, checksum=checksum))
        self.events = io.StringIO()
        # robot 0 is what ``rprs father`` runs: a PC's byte time, no submodule to answer
        byte = PC_BYTE_TICKS if robot == 0 else CHILD_BYTE_TICKS
        self.station, radio = build_station(
            robot, self.sched, byte_ticks=byte, config=replace(cfg, byte_ticks=byte),
            observer=_events_printer(self.events, robot, err=io.StringIO()))
        self.child = RadioOnlyChild(self.station) if robot else None
        self.air.attach(radio)
        self.radio = _PcRadio(tester)
        self.air.attach(self.radio)
        if patch is not None:
            patch(self.station, self.child)
        self.sched.at(0, self.station.power_on)
        self._tx_end = 0
        self._rx_back: Event | None = None
        self.sent = 0                          # transmissions of the tester's
        self.sched.run_until(s_to_ticks(lead_s))
        self.read()          # as a port opened now: what came before is stale, not heard

    def now(self) -> int:
        return self.sched.now

    def read(self) -> list[tuple[bytes, int, int]]:
        self.air.sync(self.radio, self.sched.now)     # bytes complete by now, not later
        out, self.radio.heard = self.radio.heard, []
        return out

    def write(self, data: bytes) -> int:
        """``data`` on air from now (back to back after our bytes still on air): its radio is
        deaf from then until the PTR2000's RX-ready delay after its End."""
        t0 = max(self.sched.now, self._tx_end)
        r = self.radio
        if r.rx_from != NEVER:
            self.air.deafen(r, t0)
            r.rx_from = NEVER
        if self._rx_back is not None:
            self._rx_back.cancel()
        self.air.transmit(r, data, t0, PC_BYTE_TICKS)
        self.sent += 1
        self._tx_end = t0 + len(data) * PC_BYTE_TICKS
        self._rx_back = self.sched.at(self._tx_end, self._hear_again)
        return t0

    def _hear_again(self) -> None:
        self._rx_back = None
        r = self.radio
        r.rx_from = self.sched.now + PTR2000_RX_READY_TICKS
        self.air.rx_restart(r, r.rx_from)

    def idle(self, ticks: int) -> None:
        self.sched.run_until(self.sched.now + ticks)

    def close(self) -> None:
        pass

    def event_lines(self, last: int = 12) -> str:
        """The robot's last ``last`` MAC events, one JSON object a line (for a message)."""
        return "\n".join(self.events.getvalue().splitlines()[-last:])

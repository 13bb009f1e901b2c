"""Coverage-guided fuzz target: a RotationalMac driven through a RadioStation
(firmware_model.station).

Run:  .venv/bin/python fuzz/fuzz_station.py -atheris_runs=100000 [CORPUS_DIR ...]

One station (``build_station``, simulated UART/TXEN/reload timer/PTR2000, robot ID 0-6, with or
without ``MacConfig(checksum=True)``) hears a fuzzed sequence of receptions on a stand-in for
the air (:class:`FuzzAir`): each reception starts a fuzzed gap after the previous one, carries
wire bytes (raw fuzz, Header/End fragments, real frames aimed at this station -- heartbeats,
``poll(id,mask)`` invitations, ``ack``, application commands -- possibly sealed, damaged or cut
short) at a child's or the PC's byte rate, or 1 tick apart. Each plan hands receptions to the
UART either byte by byte at each byte's own tick (as the firmware's UART interrupt takes them)
or ``late``: in fuzzed chunks or all at the last byte, as a driver with latency would; the
firmware's timer interrupt also syncs the UART up to ``now``. The application may submit
messages at fuzzed ticks. The radio hears nothing while it transmits (PTR2000 half duplex);
with ``RPRS_FUZZ_RAW=1`` plans may also let the bytes reach the UART regardless (an input the
real radio cannot produce). The scheduler then runs every event -- receptions, timer
expiries, end of transmission -- up to a horizon after the last reception. Properties
(:func:`check_station`):

1. nothing raises;
2. after every event, the MAC's ``deadline`` is None or not in the past (``>= now``; one tick
   less while the reload timer, which rounds odd delays up, is still due), and the timer is
   armed for it (expiry = deadline, or deadline + 1). Late handing-over excuses a deadline in
   the past (the MAC anchors deadlines to the real ticks of what it heard, so it means
   "expire at once"), but then the timer must expire at once;
3. every Deliver is for this robot or broadcast, comes from another robot, at or after the End
   of a frame that was really received (found independently by scanning every byte the UART
   got for a Header and parsing with ``parse_frame``), with exactly that frame's Destination,
   Source, Number, Type and application commands;
4. with the checksum on, that frame's checksum is good (``integrity.check``), and every frame
   the station transmits carries a good checksum;
5. what the station transmits is one whole frame (``parse_frame(data) == frame``).
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # _harness, fuzz_deframer
from _harness import atheris, instrumented  # noqa: E402

with instrumented(__name__ == "__main__"):
    from firmware_model.mcu.scheduler import Scheduler
    from firmware_model.radio.content import Command, parse_content, split_layers
    from firmware_model.radio.errors import ContentError, FrameError
    from firmware_model.radio.frame import HEADER, Frame, parse_frame
    from firmware_model.radio.integrity import check as crc_ok
    from firmware_model.radio.integrity import seal
    from firmware_model.radio.integrity import strip as strip_crc
    from firmware_model.radio.mac import Deliver, MacConfig, Transmit
    from firmware_model.station import build_station
    from firmware_model.timing import CHILD_BYTE_TICKS, PC_BYTE_TICKS

from fuzz_deframer import FdpSource, draw_content, draw_frame_bytes, draw_wire  # noqa: E402

__all__ = ["FuzzAir", "Reception", "draw_station_plan", "check_station", "TestOneInput", "main"]

BT = CHILD_BYTE_TICKS
_CFG = MacConfig()
GAPS = (
    0, 1, BT, 2 * BT, 4 * BT, _CFG.ttrans, _CFG.ttrans + 4 * BT, _CFG.twin, _CFG.tslot,
    _CFG.tmax // 2, _CFG.tmax - BT, _CFG.tmax, _CFG.tmax + _CFG.twin, 2 * _CFG.tmax,
    _CFG.claim_ticks(0), _CFG.claim_ticks(6) + _CFG.tslot,
)
MAX_EVENTS = 12
MAX_SUBMITS = 4


# --------------------------------------------------------------------------------------------
# A stand-in for the air (hil.sim.air's delivery rules, one radio, no other transmitters)


class Reception:
    """Bytes heard by the radio, byte i complete at ``t0 + (i+1)*dt``; ``pos`` delivered."""

    __slots__ = ("data", "t0", "dt", "pos")

    def __init__(self, data: bytes, t0: int, dt: int) -> None:
        self.data, self.t0, self.dt, self.pos = data, t0, dt, 0

    def flush(self, radio, now: int) -> int:
        """Hand the UART every byte complete by ``now``; returns how many."""
        k = min(len(self.data), (now - self.t0) // self.dt)
        if k <= self.pos:
            return 0
        pos, self.pos = self.pos, k
        radio.deliver(self.data[pos:k], self.t0 + (pos + 1) * self.dt, self.dt)
        return k - pos


class FuzzAir:
    """The channel the station's PTR2000 is attached to: fuzzed receptions, its own sends logged.

    ``deaf``: a reception reaches the UART only if the radio listens when it starts, and it is cut
    when TXEN rises (PTR2000 half duplex). Otherwise every byte reaches the UART."""

    def __init__(self, sched: Scheduler, radio, deaf: bool) -> None:
        self.sched = sched
        self.radio = radio
        self.deaf = deaf
        self.rx: Reception | None = None
        self.sent: list[tuple[int, bytes]] = []
        self.late = False  # set when a flush handed over bytes completed before ``now``
        radio.channel = self

    def _flush(self, rx: Reception, now: int) -> None:
        if rx.flush(self.radio, now) > 1:
            self.late = True

    # -- called by the PTR2000 --
    def transmit(self, radio, data: bytes, t0: int, bt: int) -> None:
        self.sent.append((t0, data))

    def sync(self, radio, now: int) -> None:
        if self.rx is not None:
            self._flush(self.rx, now)

    def deafen(self, radio, now: int) -> None:
        self.sync(radio, now)
        if self.deaf:
            self.rx = None

    def rx_restart(self, radio, when: int) -> None:
        pass

    # -- driven by the plan --
    def begin(self, rx: Reception) -> None:
        if self.rx is not None:
            self._flush(self.rx, self.sched.now)
        self.rx = rx if (not self.deaf or self.radio.listening(rx.t0)) else None

    def deliver_upto(self, rx: Reception, t: int) -> None:
        if self.rx is rx:
            self._flush(rx, t)


# --------------------------------------------------------------------------------------------
# The plan


def _frame_for(src, robot: int, checksum: bool) -> bytes:
    """A frame aimed at ``robot``: heartbeat, invitation, ack, or application message."""
    sid = src.pick([r for r in range(7) if r != robot] + [robot])
    dst = src.pick((robot, 7, robot, 7, src.int(0, 9)))
    num, typ = src.int(0, 99), src.pick((3, 2, 3, 5, 0, 1, 4, src.int(0, 9)))
    parts = []
    kind = src.int(0, 4)
    if kind == 1:
        parts.append(Command("poll", (src.pick((robot, src.int(0, 6))), src.int(0, 127))).text())
    elif kind == 2:
        parts.append(Command("ack", (src.pick((robot, src.int(0, 6))), src.int(0, 99))).text())
    elif kind == 3:
        parts.append(Command("movex", (src.int(-500, 500),)).text())
        if src.bool():
            parts.append(Command("poll", (src.int(0, 6), src.int(0, 127))).text())
    elif kind == 4:
        parts.append(draw_content(src).decode("ascii"))
    body = "".join(parts).encode("ascii")
    sealed = checksum if src.int(0, 7) else not checksum
    frame = seal(dst, sid, num, typ, body) if sealed else Frame(dst, sid, num, typ, body)
    data = frame.encode()
    if src.int(0, 5) == 0:
        i = src.int(0, len(data) - 1)
        data = data[:i] + bytes([src.int(0, 255)]) + data[i + 1:]
    return data


def draw_station_plan(src, *, raw: bool = False) -> tuple[int, bool, bool, bool, list]:
    """(robot, checksum, deaf, late, events).

    ``deaf``: the radio hears nothing while it transmits (always, unless ``raw``). ``late``:
    receptions are handed to the UART in chunks (at their last byte, or at fuzzed cut points),
    as a driver with latency would; otherwise byte by byte at each byte's own tick, as the
    firmware's UART interrupt takes them. Events:
    ``("rx", gap, data, dt, cuts)``: a reception starting ``gap`` ticks after the previous
    event, delivered after every byte count in ``cuts`` and at its last byte (None: byte by
    byte); ``("submit", gap, dst, x)``: the application submits ``movex(x)`` to ``dst``."""
    robot = src.int(0, 6)
    checksum = src.bool()
    deaf = src.bool() if raw else True
    late = src.int(0, 2) == 0
    events = []
    submits = 0
    while len(events) < MAX_EVENTS and src.more():
        gap = src.pick(GAPS) + src.pick((0, 0, 1, BT // 2, BT)) * src.int(0, 3)
        if submits < MAX_SUBMITS and src.int(0, 7) == 0:
            submits += 1
            events.append(("submit", gap, src.pick((7, src.int(0, 7))), src.int(-99, 99)))
            continue
        parts = []
        for _ in range(src.int(1, 3)):
            if src.int(0, 2):
                parts.append(_frame_for(src, robot, checksum))
            elif src.bool():
                parts.append(draw_frame_bytes(src, sealed=checksum))
            else:
                parts.append(draw_wire(src))
        data = b"".join(parts)
        dt = src.pick((BT, BT, PC_BYTE_TICKS, 1))
        if not late:
            cuts = None
        elif not data or src.bool():
            cuts = ()
        else:
            cuts = tuple(sorted({src.int(1, len(data)) for _ in range(src.int(1, 4))}))
        events.append(("rx", gap, data, dt, cuts))
    return robot, checksum, deaf, late, events


# --------------------------------------------------------------------------------------------
# The properties


def _valid_frames(stream: bytes, ticks: list[int], max_content: int, checksum: bool) -> dict:
    """Every frame in the received bytes, independently of the deframer:
    (dst, src, num, type, app commands) -> earliest End tick."""
    found: dict = {}
    j = stream.find(HEADER)
    while j >= 0:
        digits = stream[j + 8: j + 12]
        if len(digits) == 4 and digits.isdigit():
            e = j + 14 + int(digits)
            try:
                f = parse_frame(stream[j:e], max_content)
            except FrameError:
                f = None
            if f is not None and (not checksum or crc_ok(f)):
                content = strip_crc(f.content) if checksum else f.content
                try:
                    app = split_layers(parse_content(content))[1]
                except ContentError:
                    app = None
                if app is not None:
                    key = (f.dst, f.src, f.num, f.type, app)
                    found.setdefault(key, ticks[e - 1])
        j = stream.find(HEADER, j + 1)
    return found


def check_station(robot: int, checksum: bool, deaf: bool, late: bool, events,
                  horizon_extra: int | None = None) -> dict:
    """Run the plan on a fresh station and assert the properties (module docstring).
    Returns counters for the caller (events run, bytes heard, frames delivered and sent).
    ``late`` is informational: deliveries follow each event's ``cuts``."""
    sched = Scheduler()
    cfg = MacConfig(checksum=checksum)
    actions: list[tuple[int, object]] = []
    station, radio = build_station(robot, sched, config=cfg,
                                   observer=lambda st, a, now: actions.append((now, a)))
    air = FuzzAir(sched, radio, deaf)
    mac = station.mac

    stream = bytearray()
    ticks: list[int] = []
    uart_rx = station.uart.on_rx

    def on_rx(data: bytes, t0: int, dt: int) -> None:
        assert not ticks or t0 > ticks[-1], "bytes out of order"
        assert t0 + (len(data) - 1) * dt <= sched.now, "bytes from the future"
        stream.extend(data)
        ticks.extend(t0 + i * dt for i in range(len(data)))
        uart_rx(data, t0, dt)

    station.uart.on_rx = on_rx

    def submit(dst: int, x: int) -> None:
        if dst == robot or mac.pending >= cfg.max_queue:
            return
        station.submit(dst, [Command("movex", (x,))])

    # Lay the plan out on the scheduler.
    t = 0
    for ev in events:
        if ev[0] == "submit":
            _, gap, dst, x = ev
            t += gap
            sched.at(t, submit, dst, x)
            continue
        _, gap, data, dt, cuts = ev
        t0 = t + gap
        rx = Reception(data, t0, dt)
        sched.at(t0, air.begin, rx)
        if data:
            steps = range(1, len(data) + 1) if cuts is None else sorted(set(cuts) | {len(data)})
            for k in steps:
                sched.at(t0 + k * dt, air.deliver_upto, rx, t0 + k * dt)
        t = t0 + len(data) * dt
    horizon = t + (cfg.claim_ticks(robot) + 2 * cfg.tmax if horizon_extra is None
                   else horizon_extra)

    excused: list = [None]   # a past deadline already excused, until the MAC changes it

    def check_deadline() -> None:
        dl = mac.deadline
        now = sched.now
        late, air.late = air.late, False
        if dl is None:
            excused[0] = None
            return
        exp = station.timer.expiry
        # The reload timer counts machine clock / 2, so it may expire one tick after an odd
        # deadline; an event in that tick sees deadline == now - 1 with the timer still due.
        if dl >= now or (dl == now - 1 and exp == now):
            excused[0] = None
            assert exp is not None and dl <= exp <= dl + 1, (dl, exp, now)
            return
        if dl != excused[0]:
            # Only bytes handed over after they completed (a driver with latency) excuse it:
            # the MAC anchors its deadlines to the real ticks of what it heard, so a deadline
            # may then fall before ``now``, meaning "expire at once".
            assert late, f"deadline {dl} in the past at {now} ({mac.mode}/{mac.phase})"
            excused[0] = dl
        # A past deadline must at least make the timer expire at once.
        assert exp == now, (dl, exp, now)

    station.power_on()
    check_deadline()
    steps = 0
    while True:
        nt = sched.next_time()
        if nt is None or nt > horizon:
            break
        sched.step()
        steps += 1
        check_deadline()

    # Deliveries come from frames that were really received (and had a good checksum).
    valid = _valid_frames(bytes(stream), ticks, mac.max_content, checksum)
    delivered = 0
    sent = 0
    for now, a in actions:
        if type(a) is Deliver:
            delivered += 1
            assert a.dst in (robot, 7), a
            assert a.src != robot, a
            key = (a.dst, a.src, a.num, a.type, a.commands)
            assert key in valid, f"delivered {a} at {now}: no such frame received"
            assert valid[key] <= now, (a, valid[key], now)
        elif type(a) is Transmit:
            sent += 1
            assert parse_frame(a.data, 9999) == a.frame
            assert a.frame.encode() == a.data
            if checksum:
                assert crc_ok(a.frame), a.frame
    return {"steps": steps, "bytes": len(stream), "delivered": delivered, "sent": sent,
            "heard": station.frames_heard, "mode": mac.mode}


RAW = os.environ.get("RPRS_FUZZ_RAW") == "1"
"""Also fuzz a radio that hears while it transmits (impossible for a PTR2000; see README)."""


def TestOneInput(data: bytes) -> None:
    check_station(*draw_station_plan(FdpSource(atheris.FuzzedDataProvider(data)), raw=RAW))


def main(argv: list[str] | None = None) -> None:
    if atheris is None:
        sys.exit("atheris is not installed: .venv/bin/pip install atheris")
    atheris.Setup(sys.argv if argv is None else argv, TestOneInput)
    atheris.Fuzz()


if __name__ == "__main__":
    main()

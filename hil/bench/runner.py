"""The real-time runner: the same firmware objects as the simulator, on wall-clock ticks, a
real serial port for the radio and a python-can bus for CAN.

``rprs child --id N --radio PORT --can INTERFACE:CHANNEL``   a child robot
``rprs submodules --can INTERFACE:CHANNEL``                  its six executive submodules
``rprs father --radio PORT [--standby]``                     the father station (ID 0)

Ctrl-C or SIGTERM stops cleanly: the radio's TXEN is released, ports and buses are closed, and
a one-line summary is printed. Events are printed as one JSON object a line on stdout when
``--events`` is given (the format of the simulator's trace, docs/trace.md), and the father
prints what it receives.
"""
from __future__ import annotations

import json
import logging
import os
import signal
import sys
import threading
import time
from dataclasses import replace
from typing import Any, Callable, NamedTuple, Protocol, TextIO

from can_bus.bridge import CanOpenError, PythonCanBus, open_bus, parse_spec
from can_bus.submodules import make_submodules
from can_bus.transceiver import Transceiver82C250
from firmware_model.child import ChildFirmware, RadioOnlyChild
from firmware_model.kinematics import HOME
from firmware_model.mcu.can_controller import CanController
from firmware_model.radio.content import parse_content
from firmware_model.radio.errors import WireError
from firmware_model.radio.mac import (
    UNACKNOWLEDGED, BadChecksum, Deliver, Disable, DuplicateId, ForeignRing, Join, MacConfig,
    Message, Miss, ModeChange, NumberBehind, Outcome, Refused, RotationalMac, SubmitError,
    Transmit, TxEnable,
)
from firmware_model.radio.auth import FreshnessExhausted, clock_freshness
from firmware_model.station import RadioStation, Stalled, build_station
from firmware_model.timing import CHILD_BYTE_TICKS, PC_BYTE_TICKS, TICK_HZ

from ..sim.realtime import RealTimeScheduler
from .serial_radio import PortError, SerialChannel, open_port
from .stdout import StdoutFailed

LOG = logging.getLogger("rprs.bench")
"""The bench processes' log (``rprs child -v``: what was opened; ``-vv``: every frame sent and
heard and every action of the MAC, stamped with the station's tick)."""


def _log_actions(st: RadioStation, a: object, now: int) -> None:
    """A station's observer at debug level: each action of its MAC, one line."""
    if isinstance(a, Transmit):
        LOG.debug("t=%d robot %d sends %s", now, st.id, a.frame)
    elif type(a) is not TxEnable:
        LOG.debug("t=%d robot %d: %s", now, st.id, a)


REALTIME_MARGINS = {
    "twin": 50 * TICK_HZ // 1000,
    "tslot": 80 * TICK_HZ // 1000,
    "quiet_gap": 20 * TICK_HZ // 1000,
    "stall_gap": 20 * TICK_HZ // 1000,
    "standby_watch": 30 * TICK_HZ // 1000,
}
"""MAC margins for robots on PCs (docs/bench.md): bytes reach a PC program milliseconds late
(USB-serial latency, pty and scheduler), so the invitation window, the ID stagger and the
quiet/stall gaps are widened. Tslot only to 80 ms: robot 6's R-stagger Header (6 x Tslot +
Ttrans + 4 bytes after an uncertain closure) must be heard before the others' closure + Tmax
with a PC's latency to spare (docs/protocol.md §7.6; at 100 ms a healthy robot 6 was counted
missing after every burst). Every robot of one ring must use the same values; a flashed
MB90F549 on a bench with PCs is built with them too (the simulator keeps the MCU-exact
defaults)."""


def realtime_config(config: MacConfig | None = None) -> MacConfig:
    """``config`` with the real-time margins (fields left at their defaults only), and, if
    its ``seed`` is the default, one of this process's own: two processes started with one
    ID must not draw alike (docs/protocol.md clause 38.2)."""
    cfg = config or MacConfig()
    base = MacConfig()
    changes: dict[str, Any] = {k: v for k, v in REALTIME_MARGINS.items()
                               if getattr(cfg, k) == getattr(base, k)}
    if cfg.seed == base.seed:
        changes["seed"] = int.from_bytes(os.urandom(4), "big")
    return replace(cfg, **changes)


def identity_line(robot: int, a: object) -> str | None:
    """The one line a bench process prints on stderr when its ID is on the air from another
    robot, or robots outside its team hold the channel (docs/protocol.md clause 38)."""
    if type(a) is DuplicateId:
        return (f"robot {robot}: another robot on the air has ID {a.robot}: "
                + ("this one yields (listens, answers no invitation while it is heard)"
                   if a.yielding else "both send"))
    if type(a) is ForeignRing:
        who = ",".join(str(r) for r in a.robots)
        return (f"robot {robot}: robot(s) {who} outside the team hold the channel"
                + ("" if a.member else ": this one cannot claim it and is never invited "
                   "(check --team)"))
    return None


class RunError(Exception):
    """A setup problem the user can fix (port, bus, arguments): one line."""


class TextSink(Protocol):
    """Where JSON lines go: stdout, or a tee of it and ``--log FILE`` (write and flush)."""

    def write(self, s: str, /) -> object: ...

    def flush(self) -> object: ...


def _events_printer(out: TextSink | None, robot: int,
                    on_closed: Callable[[], None] | None = None,
                    err: TextIO | None = None,
                    on_failed: Callable[[str], None] | None = None,
                    ) -> Callable[[RadioStation, object, int], None]:
    """An observer turning the station's outputs into trace-like JSON lines. When ``out``'s
    reader has gone away (``| head -1``: BrokenPipeError), nothing more is written and
    ``on_closed`` runs once (the runner's ``stop``: the process stops quietly); when it cannot
    be written otherwise (a full disk), ``on_failed(why)`` runs once (the runner's ``fail``:
    its summary, then one line). A duplicate ID or a foreign ring is also said in one line on
    ``err`` (stderr), with --events or not."""
    closed = False

    def emit(ev: dict) -> None:
        nonlocal closed
        if out is None or closed:
            return
        try:
            out.write(json.dumps(ev, separators=(",", ":")) + "\n")
            out.flush()
        except BrokenPipeError:
            closed = True
            if on_closed is not None:
                on_closed()
        except (OSError, StdoutFailed) as exc:
            closed = True
            why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            if on_failed is None:
                raise
            on_failed(f"cannot write the events: {why}")

    crc_said = forged_said = False

    def say(line: str | None) -> None:
        if line is None:
            return
        try:
            (err or sys.stderr).write(f"rprs: {line}\n")
            (err or sys.stderr).flush()
        except (BrokenPipeError, ValueError):
            pass

    def observe(st: RadioStation, a: object, now: int) -> None:
        nonlocal crc_said, forged_said
        if isinstance(a, Transmit):
            f = a.frame
            emit({"t": now, "ev": "tx", "robot": robot, "dst": f.dst, "num": f.num,
                  "type": f.type, "len": len(f.content)})
        elif isinstance(a, Miss):
            emit({"t": now, "ev": "miss", "robot": a.robot, "by": robot})
        elif isinstance(a, Disable):
            emit({"t": now, "ev": "disable", "robot": a.robot, "by": robot})
        elif isinstance(a, Join):
            emit({"t": now, "ev": "rejoin" if a.again else "join", "robot": a.robot,
                  "by": robot})
        elif isinstance(a, ModeChange):
            emit({"t": now, "ev": "mode", "robot": robot, "mode": a.mode, "reason": a.reason})
        elif isinstance(a, Deliver):
            emit({"t": now, "ev": "deliver", "src": a.src, "dst": a.dst, "num": a.num,
                  "type": a.type, "to": robot,
                  "content": "".join(c.text() for c in a.commands)})
        elif isinstance(a, Outcome):
            m = a.message
            ev = "delivered" if a.delivered else "sent" if m.state == UNACKNOWLEDGED else "fail"
            emit({"t": now, "ev": ev, "src": m.src, "dst": m.dst, "num": m.num,
                  "reason": a.reason})
        elif isinstance(a, Message):
            emit({"t": now, "ev": "submit", "src": a.src, "dst": a.dst, "num": a.num,
                  "type": a.type, "len": len(a.content)})
        elif isinstance(a, Stalled):
            emit({"t": now, "ev": "stall", "robot": robot, "late": a.late})
        elif isinstance(a, Late):
            emit({"t": now, "ev": "late", "robot": robot, "late": a.late})
        elif isinstance(a, (DuplicateId, ForeignRing)):
            say(identity_line(robot, a))
            if isinstance(a, DuplicateId):
                emit({"t": now, "ev": "duplicate_id", "robot": robot, "yielding": a.yielding})
            else:
                emit({"t": now, "ev": "foreign_ring", "robot": robot, "robots": list(a.robots),
                      "member": a.member})
        elif isinstance(a, BadChecksum):
            if not crc_said and st.bad_checksum >= CRC_SAY_AFTER and \
                    st.bad_checksum == st.frames_heard:
                crc_said = True
                say(f"robot {robot}: the {st.bad_checksum} frames heard all failed the "
                    f"checksum (--checksum: a missing or wrong crc(), docs/protocol.md clause "
                    f"20): does the ring run without the checksum extension?")
        elif isinstance(a, Refused):
            emit({"t": now, "ev": "refused", "src": a.src, "num": a.num, "to": robot,
                  "reason": a.reason, **({"kind": a.kind} if a.kind else {})})
            forged = st.refused.get("forged", 0)
            if a.kind == "forged" and not forged_said and forged >= CRC_SAY_AFTER and \
                    forged == st.frames_heard:
                forged_said = True
                say(f"robot {robot}: the {forged} frames heard all failed the authentication "
                    f"tag (--auth-key, docs/protocol.md clause 53): does the ring run with "
                    f"another key, or without the authenticated profile?")
        elif isinstance(a, NumberBehind):
            emit({"t": now, "ev": "behind", "src": a.src, "num": a.num, "last": a.last,
                  "to": robot, "refused": a.refused})
    return observe


CRC_SAY_AFTER = 3
"""Frames heard, every one failing the checksum (or the authentication tag), before a station
with ``--checksum`` (``--auth-key``) says that the ring may run without the extension (with
another key, or without the profile), once a run."""


class Late(NamedTuple):
    """A timer of the station ran ``late`` ticks after its tick (more than the scheduler's
    ``late_ticks``, 20 ms, though less than a stall): the process waited that long for a core.
    Told to the observer at the tick the timer was due (event ``late``)."""
    late: int


STOP_SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP")
                      if hasattr(signal, n))
"""What stops a bench process cleanly: Ctrl-C, SIGTERM, and its terminal closed."""


def take_stop_signals(handler: Callable[[int, Any], None]) -> dict[int, Any]:
    """Put ``handler`` on each of :data:`STOP_SIGNALS` the process does not ignore, and give
    back the handlers to restore. An ignored one stays ignored: a process started under
    ``nohup`` (SIGHUP ignored) must outlive the terminal it was started from, and one started
    in the background by a shell without job control ignores SIGINT."""
    old = {}
    for sig in STOP_SIGNALS:
        if signal.getsignal(sig) is not signal.SIG_IGN:
            old[sig] = signal.signal(sig, handler)
    return old


class Runner:
    """One real-time process: a scheduler, the things it owns, and clean shutdown."""

    def __init__(self) -> None:
        self.sched = RealTimeScheduler()
        self._closers: list[Callable[[], None]] = []
        self._stopping = threading.Event()
        self.troubles = 0
        """Troubles the process went on through (:meth:`warn`); the command's exit status
        is 1 if there were any."""
        self.failure: str | None = None   # why the run stopped by itself (a lost port)
        self.finished = threading.Event()  # run() has returned
        self.stdout_closed = False
        """Standard output's reader went away (``--events | head -1``): the run stopped for
        it (:meth:`stdout_gone`), and the command ends as every rprs command then ends."""

    def warn(self, line: str) -> None:
        """A trouble the process goes on through (a CAN interface taken down, a CAN log that
        could not be written): one line now, and exit status 1 at the end."""
        self.troubles += 1
        print(f"rprs: {line}", file=sys.stderr, flush=True)

    def note(self, line: str) -> None:
        """Something a bench user should know that is no trouble (a stall the process
        recovered from): one line on stderr; the exit status stays 0."""
        print(f"rprs: {line}", file=sys.stderr, flush=True)

    def on_close(self, fn: Callable[[], None], last: bool = False) -> None:
        """Run ``fn`` when the runner stops (in reverse order; ``last``: after all others)."""
        if last:
            self._closers.insert(0, fn)
        else:
            self._closers.append(fn)

    def stop(self, *_: Any) -> None:
        self._stopping.set()
        self.sched.stop()

    def stdout_gone(self) -> None:
        """Standard output's reader has gone away: stop (hil/cli/common.py says how the
        command then ends)."""
        self.stdout_closed = True
        self.stop()

    def fail(self, why: str) -> None:
        """Stop because the run cannot go on (one line, kept in ``failure``)."""
        if self.failure is None:
            self.failure = why
        self.stop()

    def run(self, seconds: float | None = None,
            ready: Callable[[], None] | None = None) -> None:
        """Run until Ctrl-C/SIGTERM (or ``seconds``), then close everything. ``ready`` runs
        once Ctrl-C and SIGTERM are handled (the command's "running ..." line: a signal sent
        when it is seen stops the process cleanly)."""
        old = {}
        if threading.current_thread() is threading.main_thread():
            # SIGHUP: the terminal it ran in closed; it used to kill the process, its --pcap
            # and --can-log cut off where their buffers were
            old = take_stop_signals(self.stop)
        try:
            if ready is not None:
                ready()
            if seconds is None:
                self.sched.run_forever()
            else:
                self.sched.run_for(seconds)
        except FreshnessExhausted as exc:
            # (a PC's counter ran out while it ran: it may send nothing more under this key)
            self.fail(str(exc))
        finally:
            for sig, h in old.items():
                signal.signal(sig, h)
            for fn in reversed(self._closers):
                try:
                    fn()
                except BrokenPipeError:
                    pass       # stdout's reader has gone: the command ends as every one then
                except Exception as exc:   # noqa: BLE001 - closing must go on, and says so
                    self.warn(f"while closing: {type(exc).__name__}: {exc}")
            self.finished.set()


def _radio_station(runner: Runner, robot: int, port_spec: str, txen: str, byte_ticks: int,
                   config: MacConfig, observer) -> tuple[RadioStation, SerialChannel]:
    try:
        port = open_port(port_spec)
    except PortError as exc:
        raise RunError(str(exc)) from None
    station, radio = build_station(robot, runner.sched, byte_ticks=byte_ticks,
                                   config=replace(config, byte_ticks=byte_ticks),
                                   observer=observer)
    if config.auth is not None:
        # A bench process keeps nothing across restarts: its freshness counter starts from
        # the clock, above every value it sent before (docs/protocol.md clause 52).
        mac = station.mac
        assert isinstance(mac, RotationalMac)   # (a station is built with the paper's MAC)
        try:
            mac.auth_tx = clock_freshness(time.time(), config.auth.epoch)
        except FreshnessExhausted as exc:
            port.close()
            raise RunError(str(exc)) from None
    try:
        channel = SerialChannel(runner.sched, port, txen)
    except PortError as exc:
        port.close()
        raise RunError(str(exc)) from None
    channel.attach(radio)
    LOG.info("robot %d: radio on %s, TXEN %s, %d ticks a byte; margins twin %d, tslot %d, "
             "quiet gap %d, stall gap %d ticks", robot, port_spec, txen, byte_ticks,
             config.twin, config.tslot, config.quiet_gap, config.stall_gap)
    if LOG.isEnabledFor(logging.DEBUG):
        station.add_observer(_log_actions)
    channel.on_lost = lambda why: runner.fail(f"the radio port {port_spec} went away ({why})")
    channel.on_error = runner.warn       # a frame that could not be written: lost, said
    channel.start()
    # Nothing that waited in the port, or that the reader read before the station runs, is
    # heard: the station powers on listening to the air from then on.
    runner.sched.on_start(channel.flush)
    runner.sched.on_start(station.power_on)

    def stalled(late: int, now: int) -> None:
        channel.flush()                  # what came during the stall describes the past
        if channel.tap is not None:      # (its --pcap: the gap said, not false stamps)
            channel.tap.gap(late)
        station.resync(late)
        runner.note(f"robot {robot} stalled: it did not run for {late / TICK_HZ:.2f} s "
                    f"(more than the margins allow); what it heard meanwhile is dropped and "
                    f"it listens for the ring again before it transmits")
    runner.sched.watch_stalls(stall_threshold(config), stalled)
    runner.sched.watch_late(lambda late, due: observer(station, Late(late), due))
    runner.on_close(channel.close)
    runner.on_close(lambda: station.txen.set(False, runner.sched.now))
    return station, channel


def stall_threshold(config: MacConfig) -> int:
    """How late a bench station may wake before it resynchronises (ticks): Tslot of its
    margin set (docs/protocol.md clause 5; 80 ms in the real-time set). A station later than
    that may take a turn another has taken meanwhile: the ID stagger, which keeps two members
    that both think the turn is theirs apart, is one Tslot per ID."""
    return config.tslot


def _can_bus(runner: Runner, spec: str, log: str | None) -> PythonCanBus:
    if log and os.path.isdir(log):
        raise RunError(f"cannot write CAN log {log}: it is a directory")
    try:
        raw = open_bus(spec)
    except CanOpenError as exc:
        raise RunError(str(exc)) from None
    try:
        bus = PythonCanBus(runner.sched, raw, log=log, channel=parse_spec(spec)[1],
                           on_error=runner.warn)
    except (OSError, ValueError, CanOpenError, NotImplementedError, ImportError) as exc:
        # NotImplementedError: python-can's .mf4 writer without asammdf
        raw.shutdown()                 # else python-can warns at exit, a second line
        raise RunError(f"cannot write CAN log {log}: {exc}") from None
    bus.on_lost = runner.fail        # the interface removed: it cannot go on (status 1)
    runner.on_close(bus.close)
    LOG.info("CAN bus %s open%s", spec, f", logging to {log}" if log else "")
    return bus


def _capture(runner: Runner, pcap: str | None, robot: int | None,
             channel: SerialChannel | None, bus: PythonCanBus | None, can: str | None) -> None:
    """``--pcap``: tap the serial port and the CAN bus (hil/bench/capture.py)."""
    if not pcap:
        return
    if pcap == "-":
        raise RunError("--pcap -: a bench process's stdout is its console; give a file, or a "
                       "FIFO for a live view (mkfifo f; wireshark -k -i f)")
    from .capture import open_capture
    try:
        cap = open_capture(runner.sched, pcap, robot, channel is not None,
                           parse_spec(can)[1] if bus is not None and can else None)
    except OSError as exc:
        raise RunError(f"cannot write capture {pcap}: {exc.strerror or exc}") from None
    if channel is not None:
        channel.tap = cap
    if bus is not None:
        bus.trace = cap.can_frame
        bus.trace_other = cap.can_other
    runner.on_close(cap.close, last=True)     # after the port and the bus are closed


def build_child(runner: Runner, robot: int, radio: str | None, can: str | None,
                txen: str = "none", config: MacConfig | None = None, can_log: str | None = None,
                events: TextSink | None = None,
                pcap: str | None = None) -> tuple[RadioStation, ChildFirmware | RadioOnlyChild]:
    """A child on real ports (either may be None: radio only, or CAN only)."""
    if not 1 <= robot <= 6:
        raise RunError(f"a child's ID is 1-6, got {robot}")
    cfg = realtime_config(config)
    observer = _events_printer(events, robot, on_closed=runner.stdout_gone,
                               on_failed=runner.fail)
    channel = bus = None
    if radio:
        station, channel = _radio_station(runner, robot, radio, txen, CHILD_BYTE_TICKS, cfg,
                                          observer)
    else:
        station, _ = build_station(robot, runner.sched, config=cfg, observer=observer)
    child: ChildFirmware | RadioOnlyChild
    if can:
        bus = _can_bus(runner, can, can_log)
        ctrl = CanController(runner.sched)
        firmware = ChildFirmware(station, ctrl, Transceiver82C250(bus, ctrl))
        # a stall is nobody's silence: no order fails 30+n for reports it kept unread
        runner.sched.watch_stalls(stall_threshold(cfg),
                                  lambda late, now: firmware.on_stall(late))
        child = firmware
    else:
        child = RadioOnlyChild(station)      # answers orders fail(42): no CAN side
    _capture(runner, pcap, robot, channel, bus, can)
    return station, child


def build_submodules(runner: Runner, can: str, can_log: str | None = None,
                     pcap: str | None = None) -> dict:
    bus = _can_bus(runner, can, can_log)
    _capture(runner, pcap, None, None, bus, can)
    return make_submodules(runner.sched, bus, initial_angles=HOME)


def build_father(runner: Runner, radio: str, txen: str = "none", standby: bool = False,
                 config: MacConfig | None = None, events: TextSink | None = None,
                 pc: int | None = None, pcap: str | None = None) -> RadioStation:
    # --standby or --pc says the father is a pair of PCs (docs/protocol.md §4.9)
    cfg = replace(realtime_config(config), standby=standby, pc=pc or (2 if standby else 1),
                  paired=standby or pc is not None)
    station, channel = _radio_station(runner, 0, radio, txen, PC_BYTE_TICKS, cfg,
                                      _events_printer(events, 0, on_closed=runner.stdout_gone,
                                                      on_failed=runner.fail))
    _capture(runner, pcap, 0, channel, None, None)
    return station


def parse_order(line: str) -> tuple[int, list]:
    """``DST COMMANDS`` (e.g. ``2 movex(10)``, ``7 act(1,0)``) -> (dst, commands); DST is a
    child (1-6) or 7 (every robot), never the father (0) that sends it."""
    dst_text, _, text = line.strip().partition(" ")
    try:
        dst = int(dst_text)
    except ValueError:
        raise ValueError(f"start with the destination ID (1-7), e.g. '2 movex(10)'; "
                         f"got {dst_text!r}") from None
    if not 1 <= dst <= 7:
        raise ValueError(f"destination must be 1-6 (a child) or 7 (every robot), got {dst}"
                         + (": 0 is the father itself" if dst == 0 else ""))
    if not text.strip():
        raise ValueError("no commands after the destination")
    text = text.strip()
    if not text.isascii():
        bad = next(c for c in text if not c.isascii())
        # a byte the input's encoding could not read comes as a lone surrogate: name the byte
        what = (f"byte 0x{ord(bad) - 0xDC00:02x}" if 0xDC80 <= ord(bad) <= 0xDCFF else
                repr(bad))
        raise ValueError(f"{what} is not ASCII: Content is ASCII text such as 'movex(10)' "
                         f"(docs/protocol.md §3.3)")
    try:
        commands = list(parse_content(text.encode("ascii")))
    except WireError as exc:
        raise ValueError(str(exc)) from None
    from firmware_model.dispatcher import ORDER_NAMES, is_order
    for c in commands:
        if c.spec.layer != "mac" and not is_order(c):     # (a MAC command: SubmitError)
            raise ValueError(
                f"{c.text()} is news a robot reports, not an order: no child carries it out"
                + (f" (start action {c.args[0]} with act({c.args[0]},0))" if c.name == "act"
                   else f"; orders: {', '.join(sorted(ORDER_NAMES - {'act'}))}, act(n,0)"))
    return dst, commands


HISTORY_FILE = "~/.rprs_father_history"
"""Where an interactive ``rprs father`` keeps its order history (readline)."""


def _typed_lines(prompt: str = "order> "):
    """Lines typed at a terminal, with readline's editing and a history kept between runs."""
    import os
    try:
        import readline
    except ImportError:                 # not on every platform: plain input() then
        readline = None  # type: ignore[assignment]
    path = os.path.expanduser(HISTORY_FILE)
    if readline is not None:
        try:
            readline.read_history_file(path)
        except OSError:
            pass
    try:
        while True:
            try:
                yield input(prompt) + "\n"
            except EOFError:
                return
    finally:
        if readline is not None:
            try:
                readline.set_history_length(1000)
                readline.write_history_file(path)
            except OSError:
                pass


RETRY_TICKS = 50 * TICK_HZ // 1000
"""How often an order from piped input that found the queue full is offered again."""


def take_order(runner: Runner, station: RadioStation, book: Any, line: str, patient: bool,
               done: threading.Event | None = None) -> None:
    """In the runner's thread: submit the order ``line`` (``DST COMMANDS``), or give it a record
    in ``book`` (hil/bench/orders.py) that ends ``refused`` with the reason: a bad line, a
    refusal by the MAC (a standby PC, a message too long). A full queue refuses it too unless
    ``patient`` (input that is not a terminal: a script's orders wait for room, back pressure);
    then it is offered again every :data:`RETRY_TICKS`. ``done`` is set once the line is
    submitted or refused."""
    from firmware_model.radio.mac import QueueFull
    text = line.strip()
    now = runner.sched.now
    try:
        dst, commands = parse_order(text)
    except ValueError as exc:
        book.refused(text, None, f"bad order: {exc}", now)
    else:
        try:
            station.submit(dst, commands)
        except QueueFull as exc:
            if patient and not runner._stopping.is_set():
                runner.sched.after(RETRY_TICKS, take_order, runner, station, book, line,
                                   patient, done)
                return
            book.refused("".join(c.text() for c in commands), dst, str(exc), now)
        except SubmitError as exc:
            book.refused("".join(c.text() for c in commands), dst, str(exc), now)
    if done is not None:
        done.set()


def feed_orders(runner: Runner, station: RadioStation, book: Any, stream: TextIO,
                on_eof: Callable[[], None] | None = None,
                on_help: Callable[[], None] | None = None) -> threading.Thread:
    """Read ``DST COMMANDS`` lines from ``stream`` (at a terminal: with line editing and
    history) and hand each to :func:`take_order` in the runner's thread, one at a time: the
    next line is read once this one is submitted or refused, so input that is not a terminal
    waits while the queue is full. Blank lines and ``#`` comments are skipped; ``help`` or
    ``?`` calls ``on_help`` instead. ``on_eof`` runs in the runner's thread when the input
    ends."""
    def loop() -> None:
        tty = stream.isatty()
        lines = _typed_lines() if tty else stream
        for line in lines:
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            if on_help is not None and line.strip().lower() in ("help", "?"):
                on_help()
                continue
            done = threading.Event()
            runner.sched.post(take_order, runner, station, book, line, not tty, done)
            while not done.wait(0.2):
                if runner.finished.is_set():
                    return
        if on_eof is not None:
            runner.sched.post(on_eof)

    t = threading.Thread(target=loop, name="orders", daemon=True)
    t.start()
    return t


def summary_line(station: RadioStation) -> str:
    """A bench station's closing line; with the bytes its port brought while its radio was
    sending or switching (deaf: dropped, as the PTR2000 hears nothing then), if any: a peer
    that answers before this station's frame has left its radio (a port without the air's
    pacing) is heard by nobody, and this says why."""
    m = station.mac
    r = station.refused
    auth = f"forged {r.get('forged', 0)}, replayed {r.get('replayed', 0)}, " \
        if m.cfg.auth is not None else ""
    crc = f" (checksum failed {station.bad_checksum})" if m.cfg.checksum else ""
    line = (f"robot {station.id}: {m.mode}, ring {list(m.ring)}, frames sent {m.frames_sent}, "
            f"heard {station.frames_heard}, bad frames {station.frames_failed}{crc}, "
            f"refused {sum(r.values())} ({auth}out of turn {r.get('out_of_turn', 0)}, own ID "
            f"{r.get('own_id', 0)}), numbers behind {station.behind}, pending {m.pending}")
    deaf = getattr(getattr(station.uart.line, "channel", None), "bytes_deaf", 0)
    if deaf:
        line += (f", {deaf} byte{'s' if deaf != 1 else ''} came while its radio sent or "
                 f"switched (deaf: dropped)")
    return line


TICKS_PER_MS = TICK_HZ // 1000

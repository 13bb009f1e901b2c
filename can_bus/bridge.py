"""The bridge to python-can: our CAN nodes on any python-can bus, in real time.

``PythonCanBus`` offers the node interface of the simulated ``can_bus.bus.CanBus`` (``attach``,
``request``; nodes' ``pending``/``on_frame``/``on_tx_done``), so the MB90F549 controller model
and the submodule nodes run unchanged on SocketCAN (``socketcan:vcan0``), python-can's
``virtual`` bus, ``udp_multicast`` or a real adapter. The wire does the arbitration; local
nodes sharing one ``PythonCanBus`` also hear each other's frames, as on a real bus.

It needs a scheduler with ``post`` (``hil.sim.realtime.RealTimeScheduler``): a reader thread
hands every received frame to the scheduler's thread, with ``post_at`` if the scheduler has it,
at the tick the frame arrived (its python-can timestamp when that is a wall-clock time of the
last second: SocketCAN's kernel stamp), so that a timer due after the frame (the submodules'
300 ms silence) runs after it even when this process takes the frame in late. A receive or
send error (an interface taken down) is reported in one line through ``on_error`` and the bus
goes on. ``log`` writes every frame sent or received with python-can's writers, chosen by the
file's extension
(candump ``.log``, ``.asc``, ``.blf``, ``.csv``, ``.trc``), the frames no node here takes too
(extended IDs, error frames, CAN FD: counted in ``not_ours``), so that the log holds what
candump shows.
"""
from __future__ import annotations

import collections
import copy
import errno
import logging
import threading
import time
from typing import Any, Callable

import can

from .bits import BitTiming, frame_length_bits
from .candump_log import open_log
from .bus import ErrorState, NodeStatus
from .frames import CanFrame
from .node import check_node


class CanOpenError(Exception):
    """A CAN interface that cannot be opened; the message says which and why, in one line."""


KNOWN_INTERFACES = ("socketcan", "virtual", "rprs_unix", "udp_multicast", "pcan", "kvaser", "slcan",
                    "vector", "ixxat", "gs_usb", "serial", "neovi", "nican", "seeedstudio",
                    "usb2can", "cantact", "canalystii", "systec", "etas", "socketcand")


def parse_spec(spec: str) -> tuple[str, str]:
    """``INTERFACE:CHANNEL`` (e.g. ``socketcan:vcan0``, ``virtual:bench``) -> the two parts."""
    interface, sep, channel = spec.partition(":")
    if not sep or not interface or not channel:
        raise CanOpenError(f"CAN bus {spec!r} is not INTERFACE:CHANNEL, e.g. socketcan:vcan0 "
                           f"or virtual:bench")
    if interface not in can.VALID_INTERFACES:
        raise CanOpenError(f"unknown python-can interface {interface!r}; one of "
                           f"{', '.join(i for i in KNOWN_INTERFACES if i in can.VALID_INTERFACES)}")
    return interface, channel


IFF_UP = 0x1
ARPHRD_CAN = 280
"""The link type of a CAN interface (``/sys/class/net/NAME/type``; linux/if_arp.h)."""


def socketcan_missing(channel: str = "vcan0") -> str | None:
    """Why SocketCAN on ``channel`` cannot be used on this machine, or None if it can."""
    import socket
    if not hasattr(socket, "AF_CAN"):
        return "no AF_CAN in this Python/platform"
    try:
        sock = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    except OSError as exc:
        return f"no AF_CAN in this kernel ({exc.strerror})"
    sock.close()
    try:
        socket.if_nametoindex(channel)
    except OSError:
        return f"no {channel} interface"
    try:
        with open(f"/sys/class/net/{channel}/type") as f:
            kind = int(f.read())
        if kind != ARPHRD_CAN:
            return f"{channel} is not a CAN interface (link type {kind})"
    except (OSError, ValueError):
        pass
    try:
        with open(f"/sys/class/net/{channel}/flags") as f:
            if not int(f.read(), 16) & IFF_UP:
                return f"{channel} interface is down"
    except (OSError, ValueError):
        pass
    return None


IFNAME_MAX = 15
"""Longest Linux network interface name (IFNAMSIZ 16, with its terminating NUL)."""


def _socketcan_hint(channel: str, why: str) -> str:
    """What to do about ``socketcan_missing(channel)``'s reason ``why``."""
    if why == f"no {channel} interface":
        if len(channel) > IFNAME_MAX:
            return f"a network interface's name has at most {IFNAME_MAX} characters"
        return f"create it with: ip link add dev {channel} type vcan && ip link set up {channel}"
    if why == f"{channel} interface is down":
        return f"bring it up with: ip link set up {channel}"
    if "not a CAN interface" in why:
        return "name a CAN interface (ip -details link show type can, or type vcan)"
    return ("load the can and can-raw modules; without SocketCAN, processes share a bus with "
            "rprs_unix:DIR (virtual:NAME stays inside one process; docs/vcan.md)")


def open_bus(spec: str, bitrate: int | None = None, **kwargs: Any) -> can.BusABC:
    """Open a python-can bus from ``INTERFACE:CHANNEL`` with one-line errors."""
    interface, channel = parse_spec(spec)
    if interface == "socketcan":
        why = socketcan_missing(channel)
        if why is not None:
            hint = _socketcan_hint(channel, why)
            raise CanOpenError(f"cannot open CAN bus {spec}: {why}; {hint}")
    if interface == "virtual":
        kwargs.setdefault("receive_own_messages", False)
    if interface == "socketcan":
        # CAN FD frames too: a classic-only socket never sees them (the kernel hands CAN FD
        # frames only to sockets that asked), so they were missing from the log that holds
        # what candump shows, and from the count of frames no node takes
        kwargs.setdefault("fd", True)
    if bitrate is not None and interface not in ("virtual", "socketcan", "udp_multicast"):
        kwargs["bitrate"] = bitrate
    held, log = _HeldLog(), logging.getLogger("can")
    log.addHandler(held)
    propagate, log.propagate = log.propagate, False
    try:
        try:
            bus = can.Bus(interface=interface, channel=channel, **kwargs)
        except can.CanError as exc:
            why = str(exc)
        except OSError as exc:
            why = "no such device" if exc.errno == errno.ENODEV else exc.strerror or str(exc)
        except (ImportError, ValueError, TypeError) as exc:
            why = str(exc)
        except Exception as exc:  # noqa: BLE001 - a driver's own failure, e.g. python-can's
            # kvaser without Kvaser's canlib raises NameError: still one line, naming it
            why = f"python-can's {interface} driver failed: {type(exc).__name__}: {exc}"
        else:
            why = None
    finally:             # the half-built bus is gone by now, with its "not shut down" warning
        log.removeHandler(held)
        log.propagate = propagate
    if why is None:
        held.replay()
        return bus
    said = "; ".join(held.said(why))
    raise CanOpenError(f"cannot open CAN bus {spec}: {why}" + (f" ({said})" if said else ""))


class _HeldLog(logging.Handler):
    """python-can's log records while a bus opens: its warnings ("Kvaser canlib is
    unavailable.") join our one-line error when opening fails, and are logged as usual when
    it works."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)

    def said(self, why: str) -> list[str]:
        """What python-can said that ``why`` does not, less the half-built bus's warning."""
        out = []
        for r in self.records:
            text = r.getMessage()
            if r.msg != "%s was not properly shut down" and text not in out and \
                    str(why) not in text:
                out.append(text.rstrip("."))
        return out

    def replay(self) -> None:
        for r in self.records:
            logging.getLogger(r.name).handle(r)


def kernel_drops(bus: can.BusABC) -> int | None:
    """Frames the kernel dropped for ``bus``'s SocketCAN socket because its receive queue was
    full (the socket's drop count, ``SO_MEMINFO``), or None where that cannot be read (not
    SocketCAN, or a kernel before 4.6)."""
    import socket
    import struct
    sock = getattr(bus, "socket", None)
    if not isinstance(sock, socket.socket):
        return None
    try:
        info = sock.getsockopt(socket.SOL_SOCKET, SO_MEMINFO, 4 * SK_MEMINFO_VARS)
    except OSError:
        return None
    if len(info) < 4 * (SK_MEMINFO_DROPS + 1):
        return None
    return struct.unpack_from("I", info, 4 * SK_MEMINFO_DROPS)[0]


SO_MEMINFO = 55
"""linux/socket.h: a socket's memory figures, u32[SK_MEMINFO_VARS] (linux/sock_diag.h)."""
SK_MEMINFO_VARS = 9
SK_MEMINFO_DROPS = 8


SHARED_IDS = frozenset({0x010})
"""Identifiers any node may send besides this process without a clash: ESTOP (an operator's
``cansend vcan0 010#01`` as much as the child's)."""


ECHO_LOOKAHEAD = 64
"""How far behind the oldest own frame not yet heard back an echo may be matched (its
predecessors' echoes lost): a bus hands frames back in order."""


def _echoes_own_frames(bus: can.BusABC) -> bool:
    """Whether ``bus`` hands this process back the frames it sends: python-can's
    ``udp_multicast`` does (multicast loopback, which the other processes on the machine need;
    python-can cannot turn it off for one socket: ``receive_own_messages`` is refused)."""
    try:
        from can.interfaces.udp_multicast import UdpMulticastBus
    except ImportError:
        return False
    return isinstance(bus, UdpMulticastBus)


GONE_ERRNOS = frozenset({errno.ENODEV, errno.ENXIO})
"""What SocketCAN answers once the interface under a socket is removed (``ip link del vcan0``,
a USB adapter unplugged): ENODEV from the first receive, ENXIO from every send after. The
socket is unbound for good: a new interface of the same name is another interface."""


def _errno(exc: BaseException) -> int | None:
    code = getattr(exc, "error_code", None)
    if code is None and isinstance(exc, OSError):
        code = exc.errno
    if code is None and isinstance(exc.__cause__, OSError):
        code = exc.__cause__.errno
    return code


def _classic(msg: can.Message) -> bool:
    """A CAN 2.0A data or remote frame, what the nodes here take (not an extended ID, an
    error frame or CAN FD)."""
    return not (msg.is_error_frame or msg.is_extended_id or msg.is_fd)


class PythonCanBus:
    """Local CAN nodes on a python-can bus (real time)."""

    RETRY_S = 0.1
    """Seconds the reader waits after a receive error before it reads again."""
    DROPS_EVERY_S = 0.25
    """How often the reader looks at the kernel's drop count (SocketCAN)."""

    def __init__(self, sched: Any, bus: can.BusABC, timing: BitTiming | None = None,
                 log: str | None = None, channel: str | None = None,
                 on_error: Callable[[str], None] | None = None) -> None:
        """``log``: a python-can log file (.log .asc .blf ...) of every frame sent and
        received, stamped with the wall clock (seconds since the epoch, like SocketCAN's
        receive stamps and candump's), own frames marked as sent (``T``/``Tx``), each with
        ``channel`` (the bus's channel, e.g. ``vcan0`` or the ``rprs_unix`` directory).
        ``on_error``: called in the scheduler's thread with one line for each receive error
        and for the first of a run of failed sends (an interface taken down or removed);
        reading and sending go on either way, as an MCU's controller does."""
        self.sched = sched
        self._post_at = getattr(sched, "post_at", None)   # (a RealTimeScheduler's)
        self.bus = bus
        self.channel = channel
        self.timing = timing or BitTiming()
        self.nodes: list[Any] = []
        self._sinks: list[tuple[Any, Callable[[CanFrame, int, int], None]]] = []
        """(node, its ``on_frame``) of each node that takes frames, looked up at ``attach``
        (as :class:`~can_bus.bus.CanBus` does: no ``hasattr`` per frame)."""
        self._queues: dict[int, list[CanFrame]] = {}
        self._busy: set[int] = set()
        self.sent = 0
        self.received = 0
        self.not_ours = 0
        """Frames heard that are not CAN 2.0A data or remote frames (extended IDs, error
        frames, CAN FD): logged, handed to no node."""
        self.malformed = 0
        """Frames heard that no CAN 2.0A frame can be (an id above 0x7FF without the extended
        flag, a DLC that disagrees with the data, more than 8 bytes): what a buggy peer on a
        software bus sends. Logged, handed to no node; the first is reported."""
        self.send_errors = 0
        self.receive_errors = 0
        self.lost = 0
        """Frames the kernel dropped before this process read them (SocketCAN: a receive
        queue that overflowed under a flood); each is missing from the nodes and the log."""
        self.on_error = on_error
        self.on_lost: Callable[[str], None] | None = None
        """Called once, in the scheduler's thread, with why the interface is gone for good
        (removed: ``GONE_ERRNOS``); reading and sending stop then. None: said through
        ``on_error`` instead."""
        self.gone: str | None = None
        self._sent_ids: set[int] = set()
        self._echoes: collections.deque | None = (collections.deque()
                                                  if _echoes_own_frames(bus) else None)
        """Own frames sent and not yet heard back, on a bus that hands a process its own
        frames (``udp_multicast``: multicast loopback); None on the others."""
        self.echoes_lost = 0
        """Own frames that never came back (``_echo``)."""
        self.clashes: set[int] = set()
        """Identifiers this process sends that another node sent too (data frames): two
        nodes of one kind on the bus, e.g. a second ``rprs child`` on it. Said once each."""
        self._send_failing = False
        # (frame, start, end, node) of each frame, like CanBus.trace
        self.trace: Callable[[CanFrame, int, int, Any], None] | None = None
        self.trace_other: Callable[[can.Message, int], None] | None = None
        """(message, tick) of each frame received that no CAN 2.0A node takes (an extended
        id, CAN FD, an error frame): for a capture, which shows what the bus carried."""
        self.log = log
        self._writer = open_log(log) if log else None
        self._blf = isinstance(self._writer, can.BLFWriter)
        self._log_stamp = 0.0
        """The latest stamp logged: a frame logged after a later-stamped one takes its stamp
        (an own frame sent as another's came in, stamped apart), so no format's stamps go
        back (python-can's ASC and BLF writers write them as given)."""
        self._drops0 = kernel_drops(bus)
        self._drops_seen = self._drops0
        self._in_flight: dict[int, can.Message] = {}
        """Frames read and handed to the scheduler, not yet taken there (by ``id``, in the
        order read): what ``close`` still logs if the scheduler stopped first."""
        self._closing = threading.Event()
        self._reader = threading.Thread(target=self._read, name=f"can-reader {channel or ''}",
                                        daemon=True)
        self._reader.start()

    # -- what a transceiver model reads of its bus ------------------------------------------

    @property
    def tpb(self) -> int:
        """Ticks a bit at the configured bit rate."""
        return self.timing.ticks_per_bit

    idle = True          # the wire's state is not visible through python-can
    held = False
    frame_on_air = None  # ... nor the frame on it (an 82C250 in standby asks, to wake at SOF)

    def status(self, node: Any) -> NodeStatus:
        """Error counters are the adapter's business; python-can does not report them."""
        return NodeStatus(0, 0, ErrorState.ACTIVE)

    def error_state(self, node: Any) -> ErrorState:
        """``status(node).state``: always error-active (python-can reports no counters)."""
        return ErrorState.ACTIVE

    def hold_dominant(self, node: Any, on: bool = True) -> None:
        raise NotImplementedError("a stuck-dominant TXD can only be injected on the simulated "
                                  "bus (can_bus.bus.CanBus)")

    def inject_bit_error(self, node: Any = None, count: int = 1, bit: int | None = None) -> None:
        raise NotImplementedError("bit errors can only be injected on the simulated bus")

    def start_recovery(self, node: Any) -> None:
        """Bus-off is the adapter's business (``status`` always reads error-active)."""

    # -- the CanBus node interface --------------------------------------------------------

    def attach(self, node: Any) -> None:
        check_node(node)                # a misspelt hook is refused, as by CanBus.attach
        self.nodes.append(node)
        on_frame = getattr(node, "on_frame", None)
        if on_frame is not None:
            self._sinks.append((node, on_frame))

    def detach(self, node: Any) -> None:
        if node in self.nodes:
            self.nodes.remove(node)
            self._sinks = [(n, fn) for n, fn in self._sinks if n is not node]

    def request(self, node: Any, frame: CanFrame | can.Message | None = None) -> None:
        """``node`` has something to send (its ``pending()``, or ``frame``)."""
        if frame is not None and not hasattr(node, "pending"):
            if isinstance(frame, can.Message):
                frame = CanFrame.from_message(frame)
            self._queues.setdefault(id(node), []).append(frame)
        if id(node) not in self._busy:
            self._send_next(node)

    # -- sending ----------------------------------------------------------------------------

    def _next_frame(self, node: Any) -> CanFrame | None:
        if hasattr(node, "pending"):
            return node.pending()
        q = self._queues.get(id(node))
        if not q:
            return None
        q.sort(key=lambda f: (f.id, f.rtr))
        return q[0]

    def _send_next(self, node: Any) -> None:
        frame = self._next_frame(node)
        if frame is None:
            self._busy.discard(id(node))
            return
        self._busy.add(id(node))
        now = self.sched.now
        msg = frame.to_message(timestamp=time.time())
        msg.is_rx = False
        msg.channel = self.channel
        if self.gone is not None:
            return
        try:
            self.bus.send(msg, timeout=0.1)
        except can.CanError as exc:
            self.send_errors += 1
            if _errno(exc) in GONE_ERRNOS:
                self._interface_gone(exc)
                return
            if not self._send_failing:
                self._send_failing = True
                self._report(f"sending failed, retrying every 1 ms: {exc}")
            self.sched.after(16_000, self._send_next, node)    # retry in 1 ms
            return
        self._send_failing = False
        self.sent += 1
        if not frame.rtr:
            self._sent_ids.add(frame.id)
        if self._echoes is not None:
            self._echoes.append(frame)
        end = now + frame_length_bits(frame.id, frame.data, frame.rtr, include_ifs=False) \
            * self.timing.ticks_per_bit
        if self._writer is not None:
            self._log(msg)
        if self.trace is not None:
            self.trace(frame, now, end, node)
        for other, on_frame in self._sinks:      # local nodes hear it too, at its end
            if other is not node:
                self.sched.at(end, on_frame, frame, now, end)
        self.sched.at(end, self._tx_done, node, frame, end)

    def _tx_done(self, node: Any, frame: CanFrame, end: int) -> None:
        if hasattr(node, "pending"):
            if hasattr(node, "on_tx_done"):
                node.on_tx_done(frame, end)
        else:
            q = self._queues.get(id(node))
            if q and frame in q:
                q.remove(frame)
            if hasattr(node, "on_tx_done"):
                node.on_tx_done(frame, end)
        self._send_next(node)

    # -- receiving --------------------------------------------------------------------------

    def _read(self) -> None:
        """The reader thread: every frame to ``_from_thread``; an error (SocketCAN's ENETDOWN
        when the interface goes down) is reported and reading goes on."""
        next_look = time.monotonic() + self.DROPS_EVERY_S
        while not self._closing.is_set():
            if self._drops0 is not None and time.monotonic() >= next_look:
                next_look = time.monotonic() + self.DROPS_EVERY_S
                self._look_for_drops()
            try:
                msg = self.bus.recv(0.05)
            except Exception as exc:  # noqa: BLE001 - any driver's error: report, read on
                if self._closing.is_set():
                    return
                if _errno(exc) in GONE_ERRNOS:      # removed: nothing will ever come
                    self.sched.post(self._interface_gone, exc)
                    return
                self.sched.post(self._receive_failed, exc)
                self._closing.wait(self.RETRY_S)
                continue
            if msg is not None:
                self._from_thread(msg)

    def _unread(self, most: int = 10_000) -> list[can.Message]:
        """What the socket holds unread now (``most`` at most: a flood does not hold up
        closing); a driver's error ends it."""
        out: list[can.Message] = []
        while len(out) < most:
            try:
                msg = self.bus.recv(0)
            except Exception:  # noqa: BLE001 - any driver's error: nothing more to read
                break
            if msg is None:
                break
            out.append(msg)
        return out

    def _look_for_drops(self) -> None:
        """The kernel's drop count went up since last looked: those frames are lost (the
        reader thread, or ``close``)."""
        drops = kernel_drops(self.bus)
        if drops is None or self._drops_seen is None or drops <= self._drops_seen:
            return
        new, self._drops_seen = drops - self._drops_seen, drops
        if self._closing.is_set():
            self._lost_frames(new)
        else:
            self.sched.post(self._lost_frames, new)

    def _lost_frames(self, n: int) -> None:
        first = self.lost == 0
        self.lost += n
        if first:
            self._report(f"{n} frame{'s' if n > 1 else ''} lost: this process read them too "
                         f"slowly and the kernel's receive queue overflowed (a flood?); all "
                         f"lost frames are counted in the closing line")

    def _interface_gone(self, exc: Exception) -> None:
        """The interface was removed: say so once; ``on_lost`` ends the process."""
        if self.gone is not None:
            return
        why = f"{exc}".removeprefix("Error receiving: ").removeprefix("Failed to transmit: ")
        why = why.split(" [Error Code")[0]
        self.gone = (f"the CAN interface {self.channel or self.bus.channel_info} went away "
                     f"({why}): removed (ip link del, an adapter unplugged); start again once "
                     f"it is back")
        if self.on_lost is not None:
            self.on_lost(self.gone)
        else:
            self._report(self.gone)

    def _receive_failed(self, exc: Exception) -> None:
        self.receive_errors += 1
        self._report(f"receiving failed: {exc}")

    def _report(self, what: str) -> None:
        if self.on_error is not None:
            self.on_error(f"CAN bus {self.channel or self.bus.channel_info}: {what}")

    def _from_thread(self, msg: can.Message) -> None:
        # every frame, ours or not, at the tick it arrived: the log keeps the bus's order
        handler = self._deliver if _classic(msg) else self._not_ours
        self._in_flight[id(msg)] = msg
        post_at = self._post_at
        if post_at is None:
            self.sched.post(handler, msg)
            return
        ago = time.time() - (msg.timestamp or 0.0)
        wall = self.sched.wall()
        # a stamp from the last second is the wall clock's (an adapter's own clock is not)
        post_at(wall - round(ago * self.timing.tick_hz) if 0.0 <= ago <= 1.0 else wall,
                handler, msg)

    def _not_ours(self, msg: can.Message) -> None:
        """A frame no node here takes: counted and logged, as candump would show it."""
        self.not_ours += 1
        self._in_flight.pop(id(msg), None)
        if self._writer is not None:
            self._log_received(msg)
        if self.trace_other is not None:
            self.trace_other(msg, self.sched.now)

    def _deliver(self, msg: can.Message) -> None:
        self._in_flight.pop(id(msg), None)
        try:
            frame = CanFrame.from_message(msg)
        except ValueError as e:
            # No node takes it (the firmware would crash on it), and the bus goes on.
            self.malformed += 1
            if self.malformed == 1:
                self._report(f"a frame no CAN 2.0A node can send was ignored ({e}); more "
                             f"are counted")
            if self._writer is not None:
                self._log_received(msg)
            return
        if self._echo(frame):
            return
        end = self.sched.now
        start = end - frame_length_bits(frame.id, frame.data, frame.rtr, include_ifs=False) \
            * self.timing.ticks_per_bit
        self.received += 1
        if not frame.rtr and frame.id in self._sent_ids and frame.id not in self.clashes \
                and frame.id not in SHARED_IDS:
            self.clashes.add(frame.id)
            self._report(f"another node sends {frame.id:03X}, which this process sends too: "
                         f"two nodes of one kind share the bus (a second rprs child or rprs "
                         f"submodules on it?); their commands and reports mix, and on a real "
                         f"bus their frames would collide")
        if self._writer is not None:
            self._log_received(msg)
        if self.trace is not None:
            self.trace(frame, start, end, None)
        for _node, on_frame in self._sinks:
            on_frame(frame, start, end)

    def _own_echo(self, msg: can.Message) -> bool:
        """``msg`` (read, not yet taken) is our own frame back; a frame no CAN 2.0A node can
        send (an 11-bit id above 0x7FF, a DLC its data disagree with) is none: logged as
        received, as ``_deliver`` logs it."""
        if not _classic(msg):
            return False
        try:
            frame = CanFrame.from_message(msg)
        except ValueError:
            return False
        return self._echo(frame)

    def _echo(self, frame: CanFrame) -> bool:
        """``frame`` is our own frame back (in order): sent, not heard. One that comes back
        after later ones of ours were heard back is lost (a multicast datagram the socket's
        buffer dropped): those before it are forgotten (``echoes_lost``), or every later
        frame of ours would be taken for another node's, a clash."""
        echoes = self._echoes
        if not echoes:
            return False
        if frame == echoes[0]:
            echoes.popleft()
            return True
        for k in range(1, min(len(echoes), ECHO_LOOKAHEAD)):
            if frame == echoes[k]:
                for _ in range(k):
                    echoes.popleft()
                echoes.popleft()
                self.echoes_lost += k
                return True
        return False

    # -- the log ------------------------------------------------------------------------------

    def _log_received(self, msg: can.Message) -> None:
        if msg.channel is None:
            msg.channel = self.channel
        # Whatever reaches this bus object came from another one: received. (SocketCAN
        # flags every frame sent from this host, another process's too, as not received.)
        msg.is_rx = True
        self._log(msg)

    def _log(self, msg: can.Message) -> None:
        """``msg`` to the log; a write that fails (a full disk) ends the log in one line, and
        the bus goes on."""
        assert self._writer is not None           # the callers check that there is a log
        ts = msg.timestamp or 0.0
        if ts < self._log_stamp:
            msg = copy.copy(msg)                  # (the nodes keep the frame as it came)
            msg.timestamp = self._log_stamp
        else:
            self._log_stamp = ts
        if self._blf:
            # a .blf numbers channels 1-65535 from the name's digits ("rprs_unix:/tmp/can70000"
            # gave 70001 and a struct.error that ended the log): others are its default, 1
            ch = can.util.channel2int(msg.channel)
            if ch is not None and not 0 <= ch < 65535:
                msg = copy.copy(msg)
                msg.channel = None
        try:
            self._writer.on_message_received(msg)
        except (OSError, ValueError) as exc:
            self._end_log(exc)

    def _end_log(self, exc: Exception | None = None) -> None:
        """Close the log (its last buffered lines are written now); a failure, or ``exc``
        that ended it early, is reported once."""
        writer, self._writer = self._writer, None
        assert writer is not None                 # the callers check that there is a log
        try:
            writer.stop()
        except (OSError, ValueError) as late:
            exc = exc or late
        if exc is not None:
            why = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
            self._report(f"cannot write the log {self.log}: {why}; the log ends here")

    def close(self) -> None:
        """Stop reading and close the bus (after the scheduler stopped). The log ends with
        the frames the socket had received that no node took in time (read and not yet
        taken, or still queued in the socket): it holds what candump shows up to now."""
        self._closing.set()
        self._reader.join()
        if self._writer is not None:
            for msg in [*self._in_flight.values(), *self._unread()]:
                if self._writer is None:
                    break                        # (the log ended: a full disk)
                if self._own_echo(msg):
                    continue
                self._log_received(msg)
        self._in_flight.clear()
        if self._drops0 is not None:
            self._look_for_drops()               # the last ones, counted (``lost``)
        try:
            if self._writer is not None:
                self._end_log()
        finally:
            self.bus.shutdown()

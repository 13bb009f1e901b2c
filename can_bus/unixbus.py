"""A root-free CAN bus shared by several processes on one machine: python-can interface
``rprs_unix``.

There is no server: the channel is a directory, and every bus instance binds an ``AF_UNIX``
``SOCK_DGRAM`` socket ``<dir>/<pid>-<n>.sock`` in it. ``send`` writes the frame to every other
``*.sock`` in the directory, ``recv`` reads the own socket. Nothing leaves the machine (no
network interface, no multicast), no privileges are needed, and peers come and go freely::

    bus = can.Bus(interface="rprs_unix", channel="/tmp/rprs-can")

Wire format (one datagram per frame, little endian)::

    float64 timestamp       sender's msg.timestamp (the receiver stamps time.time() instead)
    uint32  arbitration_id
    uint8   flags           bit0 extended, 1 remote, 2 error, 3 fd, 4 brs, 5 esi
    uint8   dlc
    uint8   data length     0..64
    data    (data length bytes)

Flow control: the kernel queues only ``net.unix.max_dgram_qlen`` (often 10) datagrams per
receiving socket. A sender that finds a peer's queue full waits for it (kernel-woken, up to
``timeout`` or ``tx_retry_timeout`` per ``send`` call in total), then drops the frame for that
peer and counts it in ``tx_dropped``; a peer that stays full is then only tried without
waiting until it reads again, so one stalled process cannot slow the bus down. Keep a reader
running (``can.Notifier``) on every bus that receives. Sockets of dead processes
(``ECONNREFUSED``/``ENOENT``) are unlinked and forgotten on the next send.
"""
from __future__ import annotations

import collections
import errno
import itertools
import logging
import os
import select
import socket
import stat
import struct
import threading
import time
from typing import Any, Optional

import can
from can import BusABC, CanInitializationError, CanOperationError, Message
from can.typechecking import CanFilters

LOG = logging.getLogger(__name__)

HEADER = struct.Struct("<dIBBB")
MAX_DATA = 64
SUFFIX = ".sock"

F_EXTENDED, F_REMOTE, F_ERROR, F_FD, F_BRS, F_ESI = (1 << i for i in range(6))

#: sun_path holds 108 bytes including the terminating NUL
_SUN_PATH_MAX = 107
#: a cached peer list is trusted only once the directory's mtime is this old (ns): mtimes are
#: coarse (a kernel tick), so a peer binding right after our scan may not change it
_MTIME_SETTLE_NS = 100_000_000
#: rescan the directory at least this often (s) whatever its mtime says
_RESCAN_PERIOD = 2.0

_counter = itertools.count(1)
_counter_lock = threading.Lock()


def encode(msg: Message) -> bytes:
    """One frame -> one datagram (see the module docstring)."""
    data = bytes(msg.data or b"")[:MAX_DATA] if not msg.is_remote_frame else b""
    flags = ((F_EXTENDED if msg.is_extended_id else 0) | (F_REMOTE if msg.is_remote_frame else 0)
             | (F_ERROR if msg.is_error_frame else 0) | (F_FD if msg.is_fd else 0)
             | (F_BRS if msg.bitrate_switch else 0)
             | (F_ESI if msg.error_state_indicator else 0))
    return HEADER.pack(float(msg.timestamp or 0.0), msg.arbitration_id & 0xFFFFFFFF, flags,
                       min(int(msg.dlc), 255), len(data)) + data


def decode(datagram: bytes, timestamp: float | None = None, channel: Any = None,
           is_rx: bool = True) -> Optional[Message]:
    """One datagram -> a frame stamped ``timestamp`` (default: the sender's), or None if the
    datagram is not a well-formed frame."""
    if len(datagram) < HEADER.size:
        return None
    ts, arb_id, flags, dlc, length = HEADER.unpack_from(datagram)
    if length > MAX_DATA or len(datagram) != HEADER.size + length:
        return None
    return Message(timestamp=ts if timestamp is None else timestamp, arbitration_id=arb_id,
                   is_extended_id=bool(flags & F_EXTENDED), is_remote_frame=bool(flags & F_REMOTE),
                   is_error_frame=bool(flags & F_ERROR), is_fd=bool(flags & F_FD),
                   bitrate_switch=bool(flags & F_BRS),
                   error_state_indicator=bool(flags & F_ESI), dlc=dlc,
                   data=datagram[HEADER.size:], channel=channel, is_rx=is_rx)


class UnixDatagramBus(BusABC):
    """A CAN bus over ``AF_UNIX`` datagram sockets in one directory (python-can ``rprs_unix``).

    :param channel: the bus directory, created (mode 0700) if missing, but not its parents: a
        mistyped path is refused (one line naming the missing parent), not built into a bus
        nobody else is on (as ``rprs radio-hub --link-dir`` does); every bus instance on the
        same directory, in any process of the same user, is on the same bus.
    :param receive_own_messages: also deliver the frames this instance sends to itself.
    :param tx_retry_timeout: the longest one ``send(msg)`` without ``timeout`` waits for full
        peer queues (s) before dropping the frame for them.
    :param fd: report CAN FD as the protocol (FD frames are carried either way).
    :param can_filters: python-can software filters.
    """

    def __init__(self, channel: Any = None, can_filters: Optional[CanFilters] = None,
                 receive_own_messages: bool = False, tx_retry_timeout: float = 0.1,
                 fd: bool = False, **kwargs: Any) -> None:
        if channel is None or channel == "":
            raise CanInitializationError("rprs_unix needs a channel: the bus directory, e.g. "
                                         "channel='/tmp/rprs-can'")
        try:
            directory = os.path.abspath(os.fsdecode(os.fspath(channel)))
        except TypeError:
            raise CanInitializationError(
                f"rprs_unix channel must be a directory path, not {channel!r}") from None
        parent = os.path.dirname(directory)
        if not os.path.isdir(directory) and not os.path.isdir(parent) \
                and not os.path.lexists(parent):
            raise CanInitializationError(
                f"rprs_unix channel {directory}: its parent directory {parent} does not exist "
                f"(the bus makes only the last directory)")
        self._made_directory = False
        """This bus made the directory: it removes it at shutdown if no other bus is in it."""
        try:
            os.mkdir(directory, mode=0o700)
            self._made_directory = True
        except FileExistsError:
            pass
        except OSError as exc:
            raise CanInitializationError(
                f"rprs_unix channel {directory} is not a usable directory: "
                f"{exc.strerror or exc}") from None
        if not os.path.isdir(directory):
            raise CanInitializationError(f"rprs_unix channel {directory} is not a directory")
        if not os.access(directory, os.R_OK | os.W_OK | os.X_OK):
            raise CanInitializationError(f"rprs_unix channel {directory} is not readable, "
                                         f"writable and searchable by this user")

        self.channel = str(channel)
        self.directory = directory
        self.receive_own_messages = bool(receive_own_messages)
        self.tx_retry_timeout = float(tx_retry_timeout)
        self._can_protocol = can.CanProtocol.CAN_FD if fd else can.CanProtocol.CAN_20
        #: frames not delivered to some peer (its queue stayed full, or it could not be reached)
        self.tx_dropped = 0
        #: datagrams received that were not frames
        self.rx_errors = 0

        # long directories: address the sockets through /proc/self/fd/<dirfd>/ (Linux)
        self._dirfd: Optional[int] = None
        prefix = directory + os.sep
        if len(os.fsencode(prefix)) + 32 > _SUN_PATH_MAX:
            if not os.path.isdir("/proc/self/fd"):
                raise CanInitializationError(
                    f"rprs_unix channel {directory} is too long for a unix socket address")
            self._dirfd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
            prefix = f"/proc/self/fd/{self._dirfd}/"
        self._prefix = prefix

        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        try:
            self._name = self._bind()
        except OSError as exc:
            self._sock.close()
            self._close_dirfd()
            raise CanInitializationError(
                f"rprs_unix cannot bind a socket in {directory}: {exc.strerror or exc}") from None
        self._sndtimeo_ok = hasattr(socket, "SO_SNDTIMEO")
        self._poller = select.poll()
        self._poller.register(self._sock.fileno(), select.POLLIN)

        self._send_lock = threading.Lock()
        self._peers: list[str] = []
        self._peers_mtime: Optional[int] = None
        self._peers_scanned = 0.0
        self._congested: set[str] = set()
        self._own_backlog: collections.deque[bytes] = collections.deque()
        self._warned: set[str] = set()
        super().__init__(channel=channel, can_filters=can_filters, **kwargs)

    # -- setup / teardown -------------------------------------------------------------------

    def _bind(self) -> str:
        pid = os.getpid()
        name = ""
        retake = False
        remade = 0
        while True:
            if not retake:
                with _counter_lock:
                    n = next(_counter)
                name = f"{pid}-{n}{SUFFIX}"
            try:
                self._sock.bind(self._prefix + name)
                break
            except OSError as exc:
                remade += 1
                if exc.errno == errno.ENOENT and self._dirfd is None and remade <= 3:
                    # the bus that made the directory removed it as it shut down: again
                    try:
                        os.mkdir(self.directory, mode=0o700)
                        self._made_directory = True
                    except FileExistsError:
                        pass
                    continue
                if exc.errno != errno.EADDRINUSE:
                    raise
                # a socket left by a dead process that had our pid: take its name over once
                retake = not retake and self._is_stale(name)
                if retake:
                    self._unlink(name)
        try:
            os.chmod(os.path.join(self.directory, name), 0o600)
        except OSError:
            pass
        return name

    def _is_stale(self, name: str) -> bool:
        probe = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        try:
            probe.connect(self._prefix + name)
        except OSError as exc:
            return exc.errno == errno.ECONNREFUSED
        finally:
            probe.close()
        return False

    def _unlink(self, name: str) -> None:
        path = os.path.join(self.directory, name)
        try:
            if stat.S_ISSOCK(os.lstat(path).st_mode):
                os.unlink(path)
        except OSError:
            pass

    def _close_dirfd(self) -> None:
        if self._dirfd is not None:
            try:
                os.close(self._dirfd)
            except OSError:
                pass
            self._dirfd = None

    def shutdown(self) -> None:
        if self._is_shutdown:
            return
        super().shutdown()
        name = getattr(self, "_name", None)
        if name is not None:
            try:
                os.unlink(os.path.join(self.directory, name))
            except OSError:
                pass
        if getattr(self, "_made_directory", False):
            try:
                os.rmdir(self.directory)           # only if empty: no other bus is in it
            except OSError:
                pass
        try:
            self._sock.shutdown(socket.SHUT_RDWR)      # wakes a reader blocked in poll()
        except OSError:
            pass
        self._sock.close()
        self._close_dirfd()

    # -- information -------------------------------------------------------------------------

    @property
    def channel_info(self) -> str:  # type: ignore[override]
        return f"rprs_unix {self.directory} ({getattr(self, '_name', 'unbound')})"

    @property
    def socket_path(self) -> str:
        """This instance's socket file."""
        return os.path.join(self.directory, self._name)

    def fileno(self) -> int:
        return self._sock.fileno()

    # -- sending -------------------------------------------------------------------------------

    def _refresh_peers(self, force: bool = False) -> None:
        try:
            mtime = os.stat(self.directory).st_mtime_ns
        except OSError as exc:
            raise CanOperationError(f"rprs_unix bus directory {self.directory} is gone: "
                                    f"{exc.strerror}") from None
        now = time.monotonic()
        if (not force and mtime == self._peers_mtime
                and now - self._peers_scanned < _RESCAN_PERIOD):
            return
        try:
            names = sorted(e.name for e in os.scandir(self.directory)
                           if e.name.endswith(SUFFIX) and e.name != self._name)
        except OSError as exc:
            raise CanOperationError(f"rprs_unix cannot list {self.directory}: "
                                    f"{exc.strerror}") from None
        self._peers = names
        self._congested &= set(names)
        self._peers_scanned = now
        # trust this list only once the mtime has settled (see _MTIME_SETTLE_NS)
        settled = time.time_ns() - mtime > _MTIME_SETTLE_NS
        self._peers_mtime = mtime if settled else None

    def _set_sndtimeo(self, seconds: float) -> bool:
        if not self._sndtimeo_ok:
            return False
        sec = int(seconds)
        usec = max(1, int((seconds - sec) * 1e6)) if seconds > 0 else 0
        try:
            self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO,
                                  struct.pack("@ll", sec, usec))
            return True
        except (OSError, struct.error):
            self._sndtimeo_ok = False
            return False

    def _send_waiting(self, datagram: bytes, addr: str, deadline: float) -> bool:
        """Send to a full peer, waiting for room until ``deadline``; True if sent."""
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            if self._set_sndtimeo(min(left, 1.0)):
                try:
                    self._sock.sendto(datagram, addr)      # blocks in the kernel, woken on room
                    return True
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError as exc:
                    if exc.errno in (errno.EAGAIN, errno.ENOBUFS, errno.EWOULDBLOCK):
                        if exc.errno == errno.ENOBUFS:
                            time.sleep(min(0.001, max(left, 0)))
                        continue
                    raise
            else:
                time.sleep(min(0.001, left))
                try:
                    self._sock.sendto(datagram, socket.MSG_DONTWAIT, addr)
                    return True
                except OSError as exc:
                    if exc.errno not in (errno.EAGAIN, errno.ENOBUFS, errno.EWOULDBLOCK):
                        raise

    def send(self, msg: Message, timeout: Optional[float] = None) -> None:
        """Send ``msg`` to every other bus instance on the directory.

        Never blocks for long: peers whose queue is full get up to ``timeout`` (default
        ``tx_retry_timeout``) seconds in total to make room; for the others the frame is
        dropped and counted in ``tx_dropped``. Raises ``CanOperationError`` only if the bus is
        shut down or the directory is gone.
        """
        if self._is_shutdown:
            raise CanOperationError("rprs_unix bus is shut down")
        if len(msg.data or b"") > MAX_DATA:
            raise ValueError(f"CAN frame data is {len(msg.data)} bytes, more than {MAX_DATA}")
        datagram = encode(msg)
        budget = self.tx_retry_timeout if timeout is None else max(0.0, float(timeout))
        with self._send_lock:
            self._refresh_peers()
            deadline: Optional[float] = None
            stale = False
            for name in self._peers:
                addr = self._prefix + name
                try:
                    self._sock.sendto(datagram, socket.MSG_DONTWAIT, addr)
                    if self._congested:
                        self._congested.discard(name)
                    continue
                except OSError as exc:
                    err = exc.errno
                    if err in (errno.ECONNREFUSED, errno.ENOENT, errno.ENOTSOCK):
                        stale = True
                        if err != errno.ENOENT:
                            self._unlink(name)
                        continue
                    if err not in (errno.EAGAIN, errno.EWOULDBLOCK, errno.ENOBUFS):
                        stale = True                 # e.g. EACCES: rescan, report once
                        self.tx_dropped += 1
                        if name not in self._warned:
                            self._warned.add(name)
                            LOG.warning("rprs_unix: cannot send to %s: %s", name,
                                        exc.strerror or exc)
                        continue
                # the peer's queue is full
                sent = False
                if name not in self._congested and budget > 0:
                    if deadline is None:
                        deadline = time.monotonic() + budget
                    try:
                        sent = self._send_waiting(datagram, addr, deadline)
                    except OSError as exc:
                        if exc.errno in (errno.ECONNREFUSED, errno.ENOENT):
                            stale = True
                            self._unlink(name)
                            continue
                        sent = False
                if sent:
                    self._congested.discard(name)
                else:
                    self._congested.add(name)
                    self.tx_dropped += 1
                    LOG.debug("rprs_unix: %s is not reading, frame dropped for it", name)
            if stale:
                self._refresh_peers(force=True)
            if self.receive_own_messages:
                self._echo(datagram)

    def _echo(self, datagram: bytes) -> None:
        if not self._own_backlog:
            try:
                self._sock.sendto(datagram, socket.MSG_DONTWAIT, self._prefix + self._name)
                return
            except OSError:
                pass
        self._own_backlog.append(datagram)           # own queue full: keep it here, in order

    # -- receiving -----------------------------------------------------------------------------

    def _recv_internal(self, timeout: Optional[float]) -> tuple[Optional[Message], bool]:
        if self._is_shutdown:
            raise CanOperationError("rprs_unix bus is shut down")
        deadline = None if timeout is None else time.monotonic() + max(0.0, timeout)
        own = self._name
        while True:
            try:
                datagram, addr = self._sock.recvfrom(HEADER.size + MAX_DATA + 1,
                                                     socket.MSG_DONTWAIT)
            except (BlockingIOError, InterruptedError):
                datagram = None
            except OSError as exc:
                if self._is_shutdown:
                    raise CanOperationError("rprs_unix bus is shut down") from None
                if exc.errno in (errno.EAGAIN, errno.EWOULDBLOCK):
                    datagram = None
                else:
                    raise CanOperationError(f"rprs_unix receive failed: {exc}") from None
            if datagram is None and self._own_backlog:
                datagram, addr = self._own_backlog.popleft(), own
            if datagram is not None:
                if self._is_shutdown and not datagram:
                    raise CanOperationError("rprs_unix bus is shut down")
                is_rx = not (addr == own or (isinstance(addr, str)
                                             and addr.endswith("/" + own)))
                msg = decode(datagram, time.time(), self.channel, is_rx=is_rx)
                if msg is not None:
                    return msg, False
                if datagram:
                    self.rx_errors += 1
                continue
            if deadline is None:
                wait_ms = None
            else:
                left = deadline - time.monotonic()
                if left <= 0:
                    return None, False
                wait_ms = max(1, int(left * 1000 + 0.999))
            try:
                self._poller.poll(wait_ms)
            except (OSError, ValueError):
                if self._is_shutdown:
                    raise CanOperationError("rprs_unix bus is shut down") from None
                raise
            if self._is_shutdown:
                raise CanOperationError("rprs_unix bus is shut down")

    def __repr__(self) -> str:
        return f"UnixDatagramBus(channel={self.channel!r}, socket={getattr(self, '_name', None)!r})"


__all__ = ["UnixDatagramBus", "encode", "decode", "HEADER"]

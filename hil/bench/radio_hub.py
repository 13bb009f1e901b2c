"""The pty radio hub: one pseudo-terminal per robot, and the shared air between them.

Each node gets a pty whose slave side (``/dev/pts/N``) any serial program opens like a serial
port: a robot process (``rprs child --radio /dev/pts/N``), screen, minicom, pyserial. The hub
holds the master sides and plays the one half-duplex 9600-baud channel of docs/protocol.md
§1-2 with the simulator's own :class:`hil.sim.air.Air` (``byte_by_byte=True``) running on a
:class:`hil.sim.realtime.RealTimeScheduler`, so collisions, byte errors, idle noise and their seeded
random streams are exactly the simulator's:

* bytes a node writes go on air at the hub's byte time (16667 ticks, 1.0417 ms, at 9600 8N1);
  a write arriving while the node's previous bytes are still on air continues the same burst
  back to back (it is not a collision with itself);
* every other node whose link is up receives each byte at the tick its stop bit ends (it is
  written to that node's pty master then); a node never hears its own bytes;
* a node is deaf while its own bytes are on air and for the PTR2000's RX-ready delay (3 ms, the
  nRF401 data sheet's TX->RX switch time, firmware_model/mcu/ptr2000.py; not the protocol's
  Ttrans guard) after its burst ends on the air's timeline, as a PTR2000 is while TXEN is high
  and while it switches back: it never hears the garbage of a collision with its own frame,
  however late its process dated its End;
* two nodes on air at once: every node that is listening hears garbage until the air is
  clear; ``ber``: each byte corrupted with that probability per receiver; ``noise``: random
  bytes at the byte rate to every listening node while nothing reaches it;
* ``drops``: (node, start_s, end_s) windows, in seconds after ``start()``, during which the
  node's link is down: its writes vanish (counted as ``lost``), it hears nothing, and a burst it
  had on air stops where it was.

A pty has no TXEN line, so the hub takes a node's radio to switch to transmit when its bytes
go on air and back when they end: each robot process still runs its own PTR2000 model (TXEN,
its switch times) on its own clock and ignores what that model could not have heard.

Threads: a reader thread ``poll``s the masters and ``post``s (node, bytes) into the
scheduler, whose thread owns all air state. An exception in either thread stops the whole hub
(``error``, ``failure()``; ``run_forever`` raises :class:`HubError`, the command exits with one
line): a hub whose air or reader died must not go on looking alive. Writes to masters are
non-blocking: bytes a slow reader has no room for are dropped and counted (``dropped``). The
hub holds only the masters, so a master reports POLLHUP while no program has its slave open:
bytes for such a node are not written at all (nothing stale waits for a program that opens it
later) and are counted apart (``not_open``). A node writing faster than the air carries stops
being read once ``BACKLOG_LIMIT`` bytes wait, so its writer blocks as on a real serial port
instead of the hub buffering without bound. The hub keeps every slave raw: a program that
turns echo or line editing on (which would echo the air back onto it) is set back before the
hub writes to its node and at least every ``POLL_S`` (``raw_restored``).

The hub's settings (bounds, parsing), its ptys' raw mode and its nodes' radios are in
hil/bench/hub_parts.py; its command, ``rprs radio-hub``, in hil/cli/hub.py.
"""
from __future__ import annotations

import errno
import fcntl
import os
import select
import termios
import threading
import time
from typing import Any, Sequence, cast

from firmware_model.mcu.ptr2000 import NEVER
from firmware_model.timing import (
    PTR2000_RX_READY_TICKS,
    TICK_HZ,
    s_to_ticks,
)

from ..sim.realtime import RealTimeScheduler
from .hub_parts import (MAX_BURST, BACKLOG_LIMIT, READ_SIZE, POLL_S, raw_attrs, byte_ticks_for,
                        check_args, check_fault, HubError, _where, _Node, _HubAir)


def _poll(fds: list[int], timeout_s: float) -> list[tuple[int, int]]:
    """``(fd, revents)`` of ``fds`` ready for reading (or hung up) within ``timeout_s``."""
    p = select.poll()
    for fd in fds:
        p.register(fd, select.POLLIN)
    return p.poll(timeout_s * 1000)


class RadioHub:
    """N ptys sharing one simulated half-duplex radio channel (see the module docstring)."""

    @property
    def _sched(self) -> RealTimeScheduler:
        """The running hub's scheduler (set by ``start``)."""
        assert self.sched is not None, "the hub is not started"
        return self.sched

    @property
    def _air(self) -> _HubAir:
        """The running hub's air (set by ``start``)."""
        assert self.air is not None, "the hub is not started"
        return self.air

    def __init__(self, nodes: int, baud: int = 9600, ber: float = 0.0, noise: bool = False,
                 seed: int = 0, link_dir: str | None = None,
                 drops: Sequence[tuple[int, float, float]] = (),
                 faults: Sequence[Any] = ()) -> None:
        windows = [tuple(d) for d in drops]
        check_args(nodes, baud, ber, windows)     # (so each is (node, start s, end s))
        for f in faults:
            check_fault(f, nodes)
        self.faults = list(faults)
        self.nodes = nodes
        self.baud = baud
        self.ber = float(ber)
        self.noise = bool(noise)
        self.seed = seed
        self.drops = cast("list[tuple[int, float, float]]", windows)
        self.byte_ticks = byte_ticks_for(baud)
        self.link_dir = link_dir
        self.links: list[str] = []
        self.masters: list[int] = []
        self.paths: list[str] = []
        self._hup: list[Any] = []    # per node: a poll object on its master (POLLHUP: not open)
        self._made_dir = False
        self._dir_lock = -1          # the link directory, flock'ed while the hub runs
        self._lock = threading.Lock()
        self._raw_lock = threading.Lock()
        self._backlog = [0] * nodes
        self.bytes_in = [0] * nodes
        self.bytes_out = [0] * nodes
        self.dropped = [0] * nodes
        self.not_open = [0] * nodes
        self.raw_restored = [0] * nodes
        self.lost = [0] * nodes
        self.noise_bytes = [0] * nodes
        self.collisions = 0
        self._clear_at = -1
        self.sched: RealTimeScheduler | None = None
        self.air: _HubAir | None = None
        self._radios: list[_Node] = []
        self._pending = [bytearray() for _ in range(nodes)]
        self._tx_end = [0] * nodes
        self._tx_event: list[Any] = [None] * nodes
        self._rx_event: list[Any] = [None] * nodes   # per node: its burst's end (radio to RX)
        self._threads: list[threading.Thread] = []
        self._stopping = threading.Event()
        self._started = False
        self._closed = False
        self._wake_r = self._wake_w = -1
        self._t_start = 0.0
        self.pcap: Any = None
        self.capture_error: str | None = None
        self.error: BaseException | None = None
        """The exception that stopped the hub from one of its threads, or None."""
        self._error_thread = ""
        self._cap: list[tuple[int, bytearray, set[str]] | None] = [None] * nodes
        try:
            for _ in range(nodes):
                master, slave = os.openpty()
                self.masters.append(master)
                try:
                    attrs = raw_attrs(termios.tcgetattr(slave))
                    attrs[6][termios.VMIN], attrs[6][termios.VTIME] = 1, 0
                    termios.tcsetattr(slave, termios.TCSANOW, attrs)
                    self.paths.append(os.ttyname(slave))
                finally:
                    # the hub holds only the master: while no program has the slave open,
                    # the master reports POLLHUP (``_is_open``)
                    os.close(slave)
                os.set_blocking(master, False)
                hup = select.poll()
                hup.register(master, select.POLLIN)
                self._hup.append(hup)
            if link_dir is not None:
                self._make_links(link_dir)
            self._wake_r, self._wake_w = os.pipe()
            os.set_blocking(self._wake_r, False)
            os.set_blocking(self._wake_w, False)
        except BaseException:
            self._release()
            raise

    # -- setup and teardown ---------------------------------------------------------------

    def _make_links(self, link_dir: str) -> None:
        """``link_dir/nodeN`` symlinks to the ptys. The directory is made if missing (and
        removed at close), but not its parents: a mistyped path is refused, not built. A hub
        holds a lock on the directory while it runs: links there are a running hub's (refused)
        or stale (replaced). Raises ValueError with a one-line reason."""
        if os.path.lexists(link_dir) and not os.path.isdir(link_dir):
            raise ValueError(f"--link-dir {link_dir}: not a directory (a file is there)")
        try:
            if not os.path.isdir(link_dir):
                os.mkdir(link_dir)
                self._made_dir = True
            self._lock_dir(link_dir)
            for i, path in enumerate(self.paths):
                link = os.path.join(link_dir, f"node{i}")
                if os.path.islink(link):
                    os.unlink(link)      # a stale link from a hub that did not exit cleanly
                elif os.path.lexists(link):
                    raise ValueError(f"{link} exists and is not a symlink; not replacing it")
                os.symlink(path, link)
                self.links.append(link)
        except FileNotFoundError:
            parent = os.path.dirname(os.path.abspath(link_dir))
            raise ValueError(f"--link-dir {link_dir}: its parent directory {parent} does "
                             f"not exist (the hub makes only the last directory)") from None
        except OSError as exc:
            raise ValueError(f"--link-dir {link_dir}: {exc.strerror}") from None

    def _lock_dir(self, link_dir: str) -> None:
        """flock ``link_dir`` for as long as the hub runs (released when its fd closes, also
        when the process is killed); ValueError if another hub holds it."""
        fd = os.open(link_dir, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise ValueError(f"--link-dir {link_dir}: another radio hub is using it (its "
                             f"links are live); stop that hub or give another directory") \
                from None
        except OSError:
            pass                     # no locks on this file system: links are replaced as before
        self._dir_lock = fd

    def _release(self) -> None:
        for link in self.links:
            try:
                if os.path.islink(link):
                    os.unlink(link)
            except OSError:
                pass
        self.links = []
        if self._made_dir and self.link_dir is not None:
            try:
                os.rmdir(self.link_dir)
            except OSError:
                pass
            self._made_dir = False
        for fd in self.masters + [self._wake_r, self._wake_w, self._dir_lock]:
            if fd >= 0:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self.masters, self._hup = [], []
        self._wake_r = self._wake_w = self._dir_lock = -1

    def _setup(self) -> None:
        if self._closed:
            raise RuntimeError("the radio hub is closed")
        if self._started or self._stopping.is_set():
            raise RuntimeError("the radio hub runs only once")
        self._started = True
        self.sched = RealTimeScheduler()
        self._t_start = time.monotonic()
        self.air = _HubAir(self.sched, seed=self.seed, ber=self.ber, noise=self.noise,
                           byte_by_byte=True)
        self.air.on_collision = self._on_collision
        if self.pcap is not None:
            self.pcap.follow(self.sched)    # stamps: the wall clock of the air's tick 0
            self.air.on_transmission = self._on_transmission
        for i in range(self.nodes):
            r = _Node(self, i, self.byte_ticks)
            self._radios.append(r)
            self.air.attach(r)
        for node, start, end in self.drops:
            self.sched.at(s_to_ticks(start), self._link_down, node)
            self.sched.at(s_to_ticks(end), self._link_up, node)
        self._pumping = self.noise
        if self.noise:
            self.sched.at(self.byte_ticks, self._pump)
        from ..sim.faults import schedule as schedule_fault
        for f in self.faults:       # the simulator's fault mechanism, on the hub's air
            schedule_fault(self.sched, f, self._fault_start, self._fault_end)
        reader = threading.Thread(target=self._reader, name="radio-hub-reader", daemon=True)
        self._threads.append(reader)
        reader.start()

    def start(self) -> "RadioHub":
        """Run the hub in a background thread; returns at once."""
        self._setup()
        t = threading.Thread(target=self._run_sched, name="radio-hub-air", daemon=True)
        self._threads.append(t)
        t.start()
        return self

    def run_forever(self) -> None:
        """Run the hub in the calling thread until ``stop()`` (from another thread or a
        signal handler). Raises HubError if one of its threads failed."""
        self._setup()
        try:
            self._run_sched()
        finally:
            self.stop()
        if self.error is not None:
            raise HubError(self.failure()) from self.error

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until the hub stops (``stop()``, or a thread that failed: see ``error``);
        True if it has."""
        return self._stopping.wait(timeout)

    def failure(self) -> str | None:
        """One line for the exception that stopped the hub, or None if none did."""
        exc = self.error
        if exc is None:
            return None
        text = str(exc).splitlines()[0] if str(exc) else ""
        return (f"the radio hub stopped: its {self._error_thread} thread failed with "
                f"{type(exc).__name__}{': ' + text if text else ''} (at {_where(exc)})")

    def _fail(self, exc: BaseException, thread: str) -> None:
        """A thread of the hub raised ``exc``: keep the first such exception and stop the
        hub (from that thread: it does not join itself)."""
        with self._lock:
            if self.error is None:
                self.error, self._error_thread = exc, thread
        self._stopping.set()
        if self.sched is not None:
            self.sched.stop()
        self._wake()

    def _run_sched(self) -> None:
        try:
            self._sched.run_forever()
        except Exception as exc:            # noqa: BLE001 - any bug stops the hub, loudly
            self._fail(exc, "air")
        finally:
            self._stopping.set()
            self._wake()

    def stop(self) -> None:
        """Stop the air and the reader; join the threads (idempotent, thread-safe)."""
        self._stopping.set()
        if self.sched is not None:
            self.sched.stop()
        self._wake()
        me = threading.current_thread()
        for t in self._threads:
            if t is not me:
                t.join(timeout=5.0)

    def close(self) -> None:
        """``stop()``, then close every fd and remove the links."""
        if self._closed:
            return
        self.stop()
        self._closed = True
        for i, cur in enumerate(self._cap):     # bursts whose continuation never came
            if cur is not None and self.sched is not None:
                self._cap[i] = None
                self._write_packet(i, cur[0] + len(cur[1]) * self.byte_ticks, bytes(cur[1]),
                                   cur[2] | {"the hub stopped"})
        self._release()

    def __enter__(self) -> "RadioHub":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _wake(self) -> None:
        if self._wake_w >= 0:
            try:
                os.write(self._wake_w, b"x")
            except OSError:
                pass

    # -- the reader thread ----------------------------------------------------------------

    def _reader(self) -> None:
        try:
            self._read_loop()
        except Exception as exc:            # noqa: BLE001 - any bug stops the hub, loudly
            self._fail(exc, "reader")

    def _read_loop(self) -> None:
        masters = list(self.masters)
        index = {fd: i for i, fd in enumerate(masters)}
        wake = self._wake_r
        sched = self._sched
        next_raw = 0.0
        while not self._stopping.is_set():
            now = time.monotonic()
            if now >= next_raw:          # a program may have turned its node's echo on
                next_raw = now + POLL_S
                for i in range(len(masters)):
                    self._keep_raw(i)
            with self._lock:
                fds = [fd for i, fd in enumerate(masters) if self._backlog[i] < BACKLOG_LIMIT]
            try:
                # a master whose slave no program has open reports POLLHUP at once, every
                # time: find those without waiting, and wait on the others (and the wake
                # pipe); they are looked at again in the next pass, within POLL_S
                idle = {fd for fd, ev in _poll(fds, 0)
                        if ev & select.POLLHUP and not ev & select.POLLIN}
                ready = _poll([fd for fd in fds if fd not in idle] + [wake], POLL_S)
            except (OSError, ValueError):
                if self._stopping.is_set():
                    return                 # the fds were closed under us: the hub stops
                raise
            if self._stopping.is_set():
                return
            for fd, ev in ready:
                if ev & select.POLLNVAL:
                    if self._stopping.is_set():
                        return
                    raise OSError(errno.EBADF, f"fd {fd} of the hub was closed under it")
                if fd == wake:
                    try:
                        os.read(wake, 64)
                    except OSError:
                        pass
                    continue
                i = index[fd]
                try:
                    data = os.read(fd, READ_SIZE)
                except BlockingIOError:
                    continue
                except OSError as e:
                    if e.errno == errno.EIO:   # its last program closed it: nothing to read
                        continue
                    if self._stopping.is_set():
                        return
                    raise
                if data:
                    with self._lock:
                        self._backlog[i] += len(data)
                    sched.post(self._on_write, i, data)

    def _is_open(self, i: int) -> bool:
        """A program has node ``i``'s pty open (its master does not report POLLHUP)."""
        return not any(ev & select.POLLHUP for _, ev in self._hup[i].poll(0))

    def _keep_raw(self, i: int) -> None:
        """Set node ``i``'s pty raw again if a program has turned echo, line editing or
        translation on (termios on a master is its slave's, on Linux)."""
        fd = self.masters[i]
        with self._raw_lock:         # the reader and the air's thread: count each time once
            try:
                attrs = termios.tcgetattr(fd)
                raw = raw_attrs(attrs)
                if raw == attrs:
                    return
                termios.tcsetattr(fd, termios.TCSANOW, raw)
            except (termios.error, OSError):
                return               # closed under us as the hub stops
            self.raw_restored[i] += 1

    # -- the air (scheduler thread only) --------------------------------------------------

    def _on_write(self, i: int, data: bytes) -> None:
        self.bytes_in[i] += len(data)
        r = self._radios[i]
        if not r.alive:
            self.lost[i] += len(data)
            self._consumed(i, len(data))
            return
        self._pending[i] += data
        if self._tx_event[i] is None:
            if self._tx_end[i] > self._sched.now:
                self._tx_event[i] = self._sched.at(self._tx_end[i], self._send, i)
            else:
                self._send(i)

    def _send(self, i: int) -> None:
        self._tx_event[i] = None
        pend = self._pending[i]
        if not pend:
            return
        chunk = bytes(pend[:MAX_BURST])
        del pend[:MAX_BURST]
        now = self._sched.now
        t0 = max(now, self._tx_end[i])
        r = self._radios[i]
        if r.rx_from != NEVER:
            # Its radio switches to transmit: deaf from now until the RX-ready delay after the
            # burst ends on air (the process's own End comes earlier: its bytes reach the air
            # late).
            self._air.deafen(r, t0)
            r.rx_from = NEVER
        if self._rx_event[i] is not None:
            self._rx_event[i].cancel()
            self._rx_event[i] = None
        self._air.transmit(r, chunk, t0, self.byte_ticks)
        self._tx_end[i] = t0 + len(chunk) * self.byte_ticks
        self._consumed(i, len(chunk))
        if pend:
            self._tx_event[i] = self._sched.at(self._tx_end[i], self._send, i)
        else:
            self._rx_event[i] = self._sched.at(self._tx_end[i], self._rx_back, i)

    def _rx_back(self, i: int) -> None:
        """Node ``i``'s burst ended on air and nothing follows it back to back: its radio
        switches back and hears the air again the PTR2000's RX-ready delay later."""
        self._rx_event[i] = None
        r = self._radios[i]
        r.rx_from = self._sched.now + PTR2000_RX_READY_TICKS
        self._air.rx_restart(r, r.rx_from)

    def _consumed(self, i: int, n: int) -> None:
        with self._lock:
            before = self._backlog[i]
            self._backlog[i] = before - n
        if before >= BACKLOG_LIMIT > before - n:
            self._wake()                 # the reader may read this node again

    def _deliver(self, i: int, data: bytes) -> None:
        if self._air.in_noise:
            self.noise_bytes[i] += len(data)
        if not self._is_open(i):
            self.not_open[i] += len(data)     # no program to hear them: not written
            return
        self._keep_raw(i)                     # echo on would send them back on air
        try:
            n = os.write(self.masters[i], data)
        except BlockingIOError:
            n = 0
        except OSError:
            n = 0
        self.bytes_out[i] += n
        self.dropped[i] += len(data) - n

    # -- the capture (scheduler thread only) ----------------------------------------------

    def capture(self, writer: Any) -> None:
        """Write every transmission to ``writer`` (hil.sim.pcap.PcapWriter with
        ``capture_interfaces()``), wall-clock timestamps. Call before ``start``."""
        if self._started:
            raise RuntimeError("start the capture before the hub")
        self.pcap = writer

    def capture_interfaces(self) -> tuple[dict[object, str], dict[int, str]]:
        """(radio key -> interface name, no CAN buses) for a capture of this hub."""
        radios: dict[object, str] = {i: f"node {i} radio" for i in range(self.nodes)}
        radios["foreign"] = "foreign transmitters"
        return radios, {}

    def _on_transmission(self, tx: Any) -> None:
        """A burst ended on air. A node's bursts that follow each other back to back (a frame
        written in pieces) are one packet, written when its last burst ends."""
        sent = tx.data if not tx.aborted else tx.data[:(tx.end - tx.t0) // tx.bt]
        marks = {w for w, on in (("collided", tx.collided),
                                 ("aborted: the node's link went down", tx.aborted)) if on}
        i = tx.radio.robot
        if not 0 <= i < self.nodes:
            self._write_packet("foreign", tx.end, sent,
                               {"a transmitter that is no robot"} | marks)
            return
        cur = self._cap[i]
        if cur is None:
            cur = self._cap[i] = (tx.t0, bytearray(), set())
        cur[1].extend(sent)
        cur[2].update(marks)
        if not tx.aborted and (self._tx_event[i] is not None or self._tx_end[i] > tx.end):
            return                       # the node's next burst follows back to back
        self._cap[i] = None
        self._write_packet(i, tx.end, bytes(cur[1]), cur[2])

    def _write_packet(self, key: object, tick: int, data: bytes, marks: set[str]) -> None:
        if self.pcap is None:
            return
        try:
            self.pcap.radio(key, tick, data, "; ".join(sorted(marks)) or None)
        except (OSError, ValueError) as e:          # the reader of a pipe went away
            self.capture_error = f"capture stopped: {e}"
            self.pcap = None

    def _on_collision(self, t0: int, robots: list[int]) -> None:
        if t0 >= self._clear_at:
            self.collisions += 1         # a new collision, not the extension of one
        self._clear_at = self._air.collision_until

    def _pump(self) -> None:
        """Idle noise reaches the ptys byte by byte, not in the Air's lazy bursts."""
        now = self._sched.now
        for r in self._radios:
            if r.rx is None and r.alive:
                self._air.sync(r, now)
        self._sched.at(max(now, self._sched.wall()) + self.byte_ticks, self._pump)

    def _fault_start(self, f: Any) -> None:
        self._fault(f, "start")

    def _fault_end(self, f: Any) -> None:
        self._fault(f, "end")

    def _fault(self, f: Any, phase: str) -> None:
        from ..sim.faults import apply_air_fault
        if f.kind == "fail":
            self._link_down(f.robot)
        elif f.kind == "recover":
            self._link_up(f.robot)
        else:
            apply_air_fault(self.air, self._radios.__getitem__, f, phase, self.ber, self.noise,
                            foreign_byte_ticks=self.byte_ticks)
            if f.kind == "noise" and phase == "start" and not self._pumping:
                self._pumping = True
                self._sched.at(self._sched.now + self.byte_ticks, self._pump)

    def _link_down(self, i: int) -> None:
        r = self._radios[i]
        r.down += 1
        if r.down == 1:
            self._air.kill(r, self._sched.now)
            n = len(self._pending[i])
            if n:
                self.lost[i] += n
                self._pending[i].clear()
                self._consumed(i, n)
            if self._tx_event[i] is not None:
                self._tx_event[i].cancel()
                self._tx_event[i] = None
            if self._rx_event[i] is not None:
                self._rx_event[i].cancel()
                self._rx_event[i] = None
            r.rx_from = 0                # sends nothing now: hears as soon as its link is up
            self._tx_end[i] = min(self._tx_end[i], self._sched.now)

    def _link_up(self, i: int) -> None:
        r = self._radios[i]
        r.down -= 1
        if r.down == 0:
            self._air.revive(r, self._sched.now)

    # -- reporting ------------------------------------------------------------------------

    def stats(self) -> dict[str, Any]:
        """Counters so far (callable from any thread)."""
        air = self.air
        sent = dict(air.sent) if air is not None else {}
        per_node = [{
            "node": i,
            "path": self.paths[i] if i < len(self.paths) else None,
            "bytes_in": self.bytes_in[i],       # written by the node's program
            "bytes_out": self.bytes_out[i],     # heard by it (written to its pty)
            "transmissions": sent.get(i, 0),
            "dropped": self.dropped[i],         # heard, but its reader had no room
            "not_open": self.not_open[i],       # heard while no program had its pty open
            "raw_restored": self.raw_restored[i],  # times a program had made it non-raw
            "lost": self.lost[i],               # written while its link was down
            "noise": self.noise_bytes[i],
        } for i in range(self.nodes)]
        return {
            "nodes": self.nodes,
            "bytes_in": sum(self.bytes_in),
            "bytes_out": sum(self.bytes_out),
            "transmissions": sum(sent.values()),
            "collisions": self.collisions,
            "dropped": sum(self.dropped),
            "not_open": sum(self.not_open),
            "raw_restored": sum(self.raw_restored),
            "lost": sum(self.lost),
            "noise": sum(self.noise_bytes),
            "seconds": (time.monotonic() - self._t_start) if self._started else 0.0,
            "max_late_ms": (self.sched.max_late * 1000 / TICK_HZ) if self.sched else 0.0,
            "per_node": per_node,
        }

"""A robot's radio on a real serial port: a pty of the radio hub, a USB-serial PTR2000, or any
pyserial URL (``rfc2217://``, ``socket://``, ``loop://``).

``SerialChannel`` takes the place of the simulated air for one robot: the firmware's UART
sends through the PTR2000 model to ``port.write``; bytes read from the port (by a reader
thread) are posted into the real-time scheduler and reach the UART if the radio model is
listening (TXEN low for at least its RX-ready delay, 3 ms). With a real radio module, TXEN can
be wired to the USB-serial adapter's RTS or DTR line (``txen="rts"|"dtr"``); ``"none"`` is for
modules that switch themselves (and for the pty hub, which has no modem lines). The firmware
waits Ttrans (the protocol's guard, 5 ms, longer than the part's 1 ms) after raising TXEN
before its first byte, as on the MB90F549.

Only bytes heard while the station listens count: ``flush()`` (when the process starts running,
and after a stall) drops what waited in the port and whatever the reader had read before, so a
station never acts on bytes from before it listened (docs/guarantees.md, "Stalls and restarts
at the bench").
"""
from __future__ import annotations

import os
import threading
from typing import Any

import serial

from firmware_model.mcu.ptr2000 import Ptr2000


class PortError(Exception):
    """A serial port that cannot be used; one line saying which and why."""


TXEN_LINES = ("none", "rts", "dtr")


def open_port(spec: str, baud: int = 9600) -> serial.Serial:
    """Open a serial port or pyserial URL with one-line errors. (Typed ``serial.Serial``:
    every port class pyserial opens, a device's, ``socket://``'s and ``loop://``'s, has its
    ``in_waiting`` and ``reset_input_buffer``, which its base class does not declare.)"""
    if not spec:
        raise PortError("no radio port given (e.g. /dev/ttyUSB0, /dev/pts/5, socket://host:port)")
    if "://" not in spec and not os.path.exists(spec):
        if os.path.islink(spec):
            raise PortError(f"serial port {spec} is a symlink to nothing (a dangling link, or "
                            f"a loop of links)")
        raise PortError(f"serial port {spec} does not exist")
    scheme = next((s for s in ("socket://", "rfc2217://") if spec.startswith(s)), None)
    if scheme is not None:
        # pyserial says "'debug|info|warning|error'" of a port out of range or missing
        # (socket://), or compares None with a number (rfc2217://)
        host, _, rest = spec[len(scheme):].partition(":")
        port_text = rest.split("?", 1)[0].rstrip("/")
        if not (port_text.isdigit() and 0 < int(port_text) < 65536):
            raise PortError(f"cannot open serial port {spec}: {scheme} needs HOST:PORT with "
                            f"PORT 1-65535 (e.g. {scheme}localhost:7777), got {port_text!r}")
    try:
        port = serial.serial_for_url(spec, baudrate=baud, bytesize=8, parity="N", stopbits=1,
                                     timeout=0.05, write_timeout=2.0, exclusive=True) \
            if "://" not in spec else serial.serial_for_url(spec, baudrate=baud, timeout=0.05,
                                                            write_timeout=2.0)
    except serial.SerialException as exc:
        msg = str(exc)
        if "busy" in msg.lower() or "lock" in msg.lower():
            raise PortError(f"serial port {spec} is busy (another program has it open)") from None
        code = getattr(exc, "errno", None)
        if code:                  # pyserial's "[Errno 21] could not open port X: [Errno 21] ..."
            msg = os.strerror(code)
        elif "Could not configure port" in msg:       # a file or device, but no terminal
            msg = "not a serial port (it takes no serial settings)"
        raise PortError(f"cannot open serial port {spec}: {msg.splitlines()[0]}") from None
    except (ValueError, OSError) as exc:
        raise PortError(f"cannot open serial port {spec}: {exc}") from None
    try:
        port.reset_input_buffer()       # whatever arrived before we listened is stale
    except (serial.SerialException, OSError, AttributeError):
        pass
    return port


def txen_low(port: serial.Serial, txen: str) -> None:
    """Drive ``port``'s TXEN line (``rts`` or ``dtr``) low: the radio listens. PortError,
    one line, for a port that has no such line (a pty: a radio hub node)."""
    try:
        setattr(port, txen, False)
    except (serial.SerialException, OSError, ValueError) as exc:
        why = getattr(exc, "strerror", None) or str(exc)
        raise PortError(f"--txen {txen}: {port.name} has no {txen.upper()} line to "
                        f"drive ({why}); a pty, such as a radio hub node, has no "
                        f"modem lines: use --txen none") from None


class SerialChannel:
    """The air as one robot's serial port sees it. ``attach(radio)`` wires a Ptr2000 model."""

    def __init__(self, sched: Any, port: serial.Serial, txen: str = "none") -> None:
        if txen not in TXEN_LINES:
            raise PortError(f"TXEN line must be one of {', '.join(TXEN_LINES)}, got {txen!r}")
        self.sched = sched
        self.port = port
        self.txen = txen
        if txen != "none":             # a port without modem lines (a pty) is refused now
            txen_low(port, txen)
        self.radio: Ptr2000 | None = None
        self.bytes_out = 0
        self.bytes_in = 0
        self.bytes_deaf = 0          # heard while the radio model was switching or sending
        self.bytes_stale = 0         # read before the last flush(): dropped, never heard
        self._gen = 0                # flush() count: what the reader read before is stale
        self.errors: list[str] = []
        self.write_errors = 0        # frames (or parts) that could not be written: lost
        self.on_error: Any = None    # called with one line at the first failure of a run
        self._failing = False
        self.tap: Any = None         # a capture (hil.bench.capture): sent() and heard()
        self.lost: str | None = None     # why the port went away (a read failed), if it did
        self.on_lost: Any = None     # called with that reason; default: stop the scheduler
        self._stop = threading.Event()
        self._reader = threading.Thread(target=self._read_loop, name="radio-rx", daemon=True)

    def attach(self, radio: Ptr2000) -> None:
        radio.channel = self
        self.radio = radio
        if self.txen != "none":
            self._set_line(False)

    def start(self) -> None:
        self._reader.start()

    def flush(self) -> None:
        """Drop what waited in the port and what the reader has read so far (the scheduler's
        thread: at start, after a stall). A read begun before this is dropped whole, and the
        reader empties the port before its next read (itself: a flush from this thread while
        it reads makes a pty read return nothing, which pyserial takes for a lost port)."""
        self._gen += 1

    def close(self) -> None:
        self._stop.set()
        if self._reader.is_alive():
            self._reader.join(timeout=1.0)
        try:
            if self.txen != "none":
                self._set_line(False)
            self.port.close()
        except (serial.SerialException, OSError):
            pass

    # -- what the Ptr2000 model calls ---------------------------------------------------------

    def transmit(self, radio: Ptr2000, data: bytes, t0: int, bt: int) -> None:
        try:
            self.port.write(data)
            self.bytes_out += len(data)
        except (serial.SerialException, OSError) as exc:
            self.write_errors += 1
            self._trouble(f"cannot write: {exc}; the frame is lost (said once until a write "
                          f"works again)")
            return
        self._failing = False
        if self.tap is not None:
            self.tap.sent(data, t0, bt)

    def sync(self, radio: Ptr2000, now: int) -> None:
        """Bytes arrive by themselves (the reader thread posts them)."""

    def deafen(self, radio: Ptr2000, now: int) -> None:
        """TXEN raised: assert the TXEN line of a real module."""
        if self.txen != "none":
            self._set_line(True)

    def rx_restart(self, radio: Ptr2000, when: int) -> None:
        """TXEN lowered: wait until the UART has really sent everything, then release TXEN."""
        if self.txen != "none":
            try:
                self.port.flush()
            except (serial.SerialException, OSError):
                pass
            self._set_line(False)

    def _set_line(self, level: bool) -> None:
        try:
            if self.txen == "rts":
                self.port.rts = level
            elif self.txen == "dtr":
                self.port.dtr = level
        except (serial.SerialException, OSError, ValueError) as exc:
            self._trouble(f"cannot drive {self.txen.upper()}: {exc}")

    def _trouble(self, what: str) -> None:
        """A write that failed: kept in ``errors``; the first of a run is said through
        ``on_error`` (the runner's warning: a line, and exit status 1)."""
        self.errors.append(what)
        if not self._failing:
            self._failing = True
            if self.on_error is not None:
                self.on_error(f"the radio port {self.port.name}: {what}")

    # -- receiving ------------------------------------------------------------------------------

    def _read_loop(self) -> None:
        port = self.port
        flushed = self._gen
        while not self._stop.is_set():
            gen = self._gen
            if gen != flushed:
                flushed = gen
                try:
                    port.reset_input_buffer()     # what waited there came before flush()
                except Exception:   # noqa: BLE001 - termios.error too: the read says it
                    pass
            try:
                data = port.read(max(1, port.in_waiting))
            except (serial.SerialException, OSError, TypeError) as exc:
                if not self._stop.is_set():
                    self.errors.append(f"read failed: {exc}")
                    self.sched.post(self._lost, str(exc))
                return
            if data:
                self.sched.post(self._arrived, data, gen)

    def _arrived(self, data: bytes, gen: int | None = None) -> None:
        if gen is not None and gen != self._gen:
            self.bytes_stale += len(data)       # read before the last flush()
            return
        radio = self.radio
        self.bytes_in += len(data)
        if radio is None:
            return
        now = self.sched.now
        if self.tap is not None:
            self.tap.heard(data, now, radio.uart.byte_ticks)
        if not radio.listening(now):
            self.bytes_deaf += len(data)
            return
        bt = radio.uart.byte_ticks
        radio.deliver(data, now - (len(data) - 1) * bt, bt)

    def _lost(self, why: str) -> None:
        """The port went away (the radio hub stopped, a USB adapter was pulled)."""
        self.lost = why
        if self.on_lost is not None:
            self.on_lost(why)
        else:
            self.sched.stop()

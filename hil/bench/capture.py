"""``--pcap FILE`` for the bench processes (``rprs child``, ``rprs father``, ``rprs
submodules``): what crosses this process's own serial port and CAN bus, as pcapng for
Wireshark (docs/wireshark.md).

Interfaces (hil.sim.pcap): ``R<id> radio, sent`` (each frame this process wrote to its
radio's serial port, one packet, stamped when its last stop bit ends), ``R<id> radio, heard``
(the bytes its serial port received, one packet per burst: a burst ends after two byte times
without a byte; noise and cut frames stay in, the dissector flags them), and one CAN interface
(each frame sent or received on the python-can bus). Timestamps are the wall clock, in ns.
A FIFO works as FILE (``mkfifo f; wireshark -k -i f``) for a live view.
"""
from __future__ import annotations

import time
from typing import Any, BinaryIO

from firmware_model.timing import TICK_HZ

from ..sim.pcap import PcapWriter

GAP_BYTES = 2
"""A heard burst ends after this many byte times without a byte."""


class BenchCapture:
    """A capture of one bench process. ``radio``: the robot ID whose serial port is tapped
    (None: no radio); ``can``: the CAN bus's name (None: no CAN bus)."""

    def __init__(self, sched: Any, stream: BinaryIO, robot: int | None, radio: bool,
                 can: str | None) -> None:
        self.sched = sched
        radios = {} if not radio else {"sent": f"R{robot} radio, sent",
                                       "heard": f"R{robot} radio, heard"}
        buses = {} if can is None else {0: f"CAN {can}"}
        self.writer = PcapWriter(stream, radios, buses, tsresol=9)
        # the scheduler's tick 0 on the wall clock, in ns
        self.writer.epoch_units = time.time_ns() - sched.wall() * 1_000_000_000 // TICK_HZ
        self.stream = stream
        self._heard = bytearray()
        self._heard_end = 0
        self._flush_ev: Any = None
        self._bt = 16_640
        self.error: str | None = None

    # -- the serial port --------------------------------------------------------------------

    def sent(self, data: bytes, t0: int, bt: int) -> None:
        """Bytes the UART model wrote to the port from tick ``t0``, ``bt`` ticks each."""
        self._write("sent", t0 + len(data) * bt, bytes(data))

    def heard(self, data: bytes, now: int, bt: int) -> None:
        """Bytes the port received (the last one complete at ``now``)."""
        self._bt = bt
        self._heard += data
        self._heard_end = now
        if self._flush_ev is not None:
            self._flush_ev.cancel()
        self._flush_ev = self.sched.at(now + GAP_BYTES * bt, self._flush_heard)

    def _flush_heard(self) -> None:
        self._flush_ev = None
        if self._heard:
            data, self._heard = bytes(self._heard), bytearray()
            self._write("heard", self._heard_end, data)

    # -- the CAN bus ------------------------------------------------------------------------

    def can_frame(self, frame: Any, start: int, end: int, node: Any) -> None:
        """``PythonCanBus.trace``: a frame sent (``node`` set) or received, ending at ``end``."""
        if self.error is None:
            try:
                self.writer.can(0, end, frame.id, frame.data)
            except (OSError, ValueError) as e:
                self.error = f"capture stopped: {e}"

    def _write(self, key: str, tick: int, data: bytes) -> None:
        if self.error is None:
            try:
                self.writer.radio(key, tick, data)
            except (OSError, ValueError) as e:
                self.error = f"capture stopped: {e}"

    def close(self) -> None:
        """Write a burst still being heard, then close the file."""
        if self._flush_ev is not None:
            self._flush_ev.cancel()
            self._flush_ev = None
        self._flush_heard()
        try:
            self.stream.close()
        except OSError:
            pass


def open_capture(sched: Any, path: str, robot: int | None, radio: bool,
                 can: str | None) -> BenchCapture:
    """A capture to ``path``; OSError (with ``strerror``) when it cannot be written."""
    stream = open(path, "wb")
    try:
        return BenchCapture(sched, stream, robot, radio, can)
    except BaseException:
        stream.close()
        raise

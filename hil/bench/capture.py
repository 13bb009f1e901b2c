"""``--pcap FILE`` for the bench processes (``rprs child``, ``rprs father``, ``rprs
submodules``): what crosses this process's own serial port and CAN bus, as pcapng for
Wireshark (docs/wireshark.md).

Interfaces (hil.sim.pcap): ``R<id> radio, sent`` (each frame this process wrote to its
radio's serial port, one packet, stamped when its last stop bit ends), ``R<id> radio, heard``
(the bytes its serial port received, cut where a frame begins and ends, as the robot's own
deframer reads them: each frame one packet, what came between two frames (noise, garbage)
one packet, a frame cut short a packet when nothing more came for :data:`QUIET_BYTES` byte
times; the dissector flags all but the frames), and one CAN interface
(each frame sent or received on the python-can bus). Timestamps are the wall clock, in ns.
A FIFO works as FILE (``mkfifo f; wireshark -k -i f``) for a live view.
"""
from __future__ import annotations

from collections import deque
from typing import Any, BinaryIO

from firmware_model.radio.deframer import Deframer, FrameFailed, FrameReceived
from firmware_model.timing import TICK_HZ

from ..sim.pcap import PcapWriter

QUIET_BYTES = 20
"""Byte times (about 35 ms at 9600 baud) without a byte after which a frame still open is
written as it is, cut. Bytes reach the process in chunks, as late as a USB-serial adapter's
latency timer (16 ms by default) and the machine's load make them, so arrival gaps cannot tell
where frames end (a gap of two byte times once cut a third of the frames heard in two); the
deframer's reading of the bytes does."""


class BenchCapture:
    """A capture of one bench process. ``radio``: the robot ID whose serial port is tapped
    (None: no radio); ``can``: the CAN bus's name (None: no CAN bus)."""

    def __init__(self, sched: Any, stream: BinaryIO, robot: int | None, radio: bool,
                 can: str | None, listener: str | None = None) -> None:
        """``listener``: a listen-only capture (``rprs capture``): one interface,
        ``<listener>, heard``, and no robot of its own."""
        self.sched = sched
        radios: dict[object, str] = {} if not radio else {"sent": f"R{robot} radio, sent",
                                       "heard": f"R{robot} radio, heard"}
        if listener is not None:
            radios = {"heard": f"{listener}, heard"}
        buses = {} if can is None else {0: f"CAN {can}"}
        self.writer = PcapWriter(stream, radios, buses, tsresol=9, live=True)
        self.writer.follow(sched)       # stamps: the wall clock of the scheduler's tick 0
        self.stream = stream
        self._deframer = Deframer()
        self._heard = bytearray()       # bytes heard and not yet in a packet
        self._base = 0                  # their offset in everything heard
        self._chunks: deque[tuple[int, int, int]] = deque()   # (end offset, tick, byte ticks)
        self._flush_ev: Any = None
        self.error: str | None = None
        self.gaps = 0                   # stalls: heard bytes dropped, their times unknown
        self._note: str | None = None   # the comment of the next packet (a gap before it)
        self.close_error: str | None = None
        """Why the file could not be finished at the end (its last bytes not written), or None."""
        self.on_error: Any = None
        self.reader_gone = False
        """The capture stopped because the reader of its pipe went away (``--pcap - | ...``)."""
        """Called with the error once, when the capture stops (its reader went away, the disk
        filled): ``rprs capture``, which has nothing else to do, stops then."""

    # -- the serial port --------------------------------------------------------------------

    def sent(self, data: bytes, t0: int, bt: int) -> None:
        """Bytes the UART model wrote to the port from tick ``t0``, ``bt`` ticks each."""
        self._write("sent", t0 + len(data) * bt, bytes(data))

    def heard(self, data: bytes, now: int, bt: int) -> None:
        """Bytes the port received (the last one complete at ``now``, ``bt`` ticks each)."""
        if not data:
            return
        offset = self._base + len(self._heard)
        self._heard += data
        self._chunks.append((offset + len(data), now, bt))
        # the deframer counts in bytes here: an event's ticks are offsets in the stream
        self._cut(self._deframer.feed(bytes(data), offset, 1))
        if self._flush_ev is not None:
            self._flush_ev.cancel()
            self._flush_ev = None
        if self._heard:                  # a frame (or a partial Header) still open
            self._flush_ev = self.sched.at(now + QUIET_BYTES * bt, self._flush_heard)

    def _cut(self, events: list) -> None:
        """A frame (good or failed) is a packet, and what came before it since the last one
        (noise, garbage) another; garbage waits for the next frame or the quiet time, so
        that noise read in several chunks is one packet."""
        for ev in events:
            if isinstance(ev, FrameReceived):
                stop = ev.end + 1
            elif isinstance(ev, FrameFailed):
                stop = ev.at                 # the byte that broke it is read again
            else:                            # Garbage: stays until the next frame
                continue
            self._packet(ev.first)
            self._packet(stop, frame=True)

    def _packet(self, stop: int, frame: bool = False) -> None:
        """Write the heard bytes before offset ``stop`` as one packet, stamped with the tick
        its last byte completed: for a ``frame`` (its bytes back to back on the air), of the
        estimates its chunks give (each read's tick, plus the byte times between the chunk's
        last byte and the frame's), the earliest; else the last chunk's (noise comes when it
        comes).
        A read is never early, only late (a loaded machine, a USB adapter's latency timer),
        so the earliest is the nearest: a frame whose last chunk was read 2 ms late was
        stamped 2 ms late, and the hand-over after it looked 2 ms short ("early")."""
        n = stop - self._base
        if n <= 0:
            return
        data, self._heard = bytes(self._heard[:n]), self._heard[n:]
        first, last = self._base, stop - 1
        chunks = self._chunks
        best: int | None = None
        while chunks[0][0] <= last:
            end, tick, bt = chunks.popleft()
            if frame and end > first:    # (its bytes end inside this frame)
                est = tick + (last - (end - 1)) * bt
                best = est if best is None else min(best, est)
        end, tick, bt = chunks[0]
        est = tick - (end - 1 - last) * bt
        self._base = stop
        self._write("heard", est if best is None else min(best, est), data)

    def _flush_heard(self) -> None:
        """Nothing heard for a while: what is open was cut short; write it as it is."""
        self._flush_ev = None
        failed = self._deframer.abort(self._base + len(self._heard))
        if failed is not None:
            self._cut([failed])
        self._packet(self._base + len(self._heard))
        self._deframer.reset()

    # -- the CAN bus ------------------------------------------------------------------------

    def can_frame(self, frame: Any, start: int, end: int, node: Any) -> None:
        """``PythonCanBus.trace``: a frame sent (``node`` set) or received, ending at ``end``."""
        if self.error is None:
            try:
                self.writer.can(0, end, frame.id, frame.data, frame.rtr, frame.dlc)
            except (OSError, ValueError) as e:
                self._stopped(e)

    def can_other(self, msg: Any, tick: int) -> None:
        """``PythonCanBus.trace_other``: a frame no CAN 2.0A node takes (an extended id, CAN
        FD, an error frame), received at ``tick``: in the capture as SocketCAN has it."""
        if self.error is None:
            from ..sim.pcap import socketcan_message
            try:
                self.writer.can_raw(0, tick, socketcan_message(msg))
            except (OSError, ValueError) as e:
                self._stopped(e)

    def gap(self, late: int) -> None:
        """The process did not run for ``late`` ticks (a stall: SIGSTOP, Ctrl-Z, a starved
        machine): what the port took in meanwhile was dropped, its times being unknown (read
        late, its bytes would be stamped as if heard at once). What was open before it is
        written as it is, cut short, and the next packet says there is a gap before it."""
        if self._flush_ev is not None:
            self._flush_ev.cancel()
            self._flush_ev = None
        self._flush_heard()
        self.gaps += 1
        self._note = (f"the capture stalled {late / TICK_HZ:.2f} s before this packet: what "
                      f"the radio heard then is not in it")

    def _write(self, key: str, tick: int, data: bytes) -> None:
        if self.error is None:
            note, self._note = self._note, None
            try:
                self.writer.radio(key, tick, data, note)
            except (OSError, ValueError) as e:
                self._stopped(e)

    def _stopped(self, e: Exception) -> None:
        self.reader_gone = isinstance(e, BrokenPipeError)
        self.error = f"capture stopped: {e}"
        if self.on_error is not None:
            self.on_error(self.error)

    def close(self) -> None:
        """Write a burst still being heard, then close the file."""
        if self._flush_ev is not None:
            self._flush_ev.cancel()
            self._flush_ev = None
        self._flush_heard()
        try:
            self.stream.close()
        except OSError as e:
            self.close_error = e.strerror or str(e)


def open_capture(sched: Any, path: str, robot: int | None, radio: bool,
                 can: str | None) -> BenchCapture:
    """A capture to ``path``; OSError (with ``strerror``) when it cannot be written."""
    stream = open(path, "wb")
    try:
        return BenchCapture(sched, stream, robot, radio, can)
    except BaseException:
        stream.close()
        raise

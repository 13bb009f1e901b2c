"""CAN traffic as ``candump -L`` writes it: the ``.log`` of ``--can-log FILE.log`` (python-can's
writers for ``.asc`` and ``.blf``), docs/bench.md."""
from __future__ import annotations

import gzip
from typing import TYPE_CHECKING, Any

import can

from .frames import CAN_ERR_FLAG, CAN_ERR_MASK, fd_flags

if TYPE_CHECKING:
    from can.io.generic import MessageWriter


class CandumpLogWriter(can.CanutilsLogWriter):
    """python-can's candump ``.log`` writer (its file handling), every line written as
    ``candump -L`` writes it (can-utils lib.c ``sprint_canframe``), which python-can's own
    line did not in five ways:

    * a remote frame keeps its DLC (``101#R6``), one above 8 as ``R8_C`` (its raw DLC); a
      classic data frame with a raw DLC above 8 ends ``_C`` the same way;
    * a CAN FD frame carries FDF in its flags, as SocketCAN's do from kernel 6.2 (``101##5``);
    * an error frame keeps its error class (``20000020#...``: ``CAN_ERR_ACK``; python-can wrote
      every class as a bus error, ``20000080``);
    * a timestamp never goes back (python-can's writer meant to hold it, but kept the first
      one only): a frame written after one with a later stamp takes that one's;
    * a frame no CAN interface can carry (an 11-bit id above 0x7FF, a DLC that disagrees with
      the data: a buggy peer on a software bus) has no candump line: it is left out
      (``unwritable``), where its line stopped ``log2asc`` and python-can's LogReader.

    Each line is flushed as it is written: a process killed by SIGKILL leaves its log
    whole up to its last frame."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._last = 0.0
        self.unwritable = 0
        """Frames left out: no candump line holds them (the class docstring)."""

    def on_message_received(self, msg: can.Message) -> None:
        line = self._line(msg)
        if line is None:
            self.unwritable += 1
            return
        self.file.write(line)
        self.file.flush()

    def _line(self, msg: can.Message) -> str | None:
        ts = msg.timestamp or 0.0
        if ts < self._last:
            ts = self._last
        channel = msg.channel if msg.channel is not None else self.channel
        if isinstance(channel, int) or (isinstance(channel, str) and channel.isdigit()):
            channel = f"can{channel}"
        data = bytes(msg.data)
        if msg.is_error_frame:
            text = f"{CAN_ERR_FLAG | (msg.arbitration_id & CAN_ERR_MASK):08X}#{data.hex().upper()}"
            eol = ""
        else:
            eol = " R" if msg.is_rx else " T"
            ident = f"{msg.arbitration_id:08X}" if msg.is_extended_id else \
                f"{msg.arbitration_id:03X}"
            if not msg.is_extended_id and msg.arbitration_id > 0x7FF:
                return None
            if msg.is_fd:
                text = f"{ident}##{fd_flags(msg):X}{data.hex().upper()}"
            elif msg.is_remote_frame:
                dlc = msg.dlc or 0
                if dlc > 15:
                    return None
                text = f"{ident}#R" + ("" if dlc == 0 else f"{dlc:X}" if dlc <= 8 else
                                       f"8_{dlc:X}")
            else:
                dlc = len(data) if msg.dlc is None else msg.dlc
                if len(data) > 8 or (dlc != len(data) and not (len(data) == 8 and
                                                                 8 < dlc <= 15)):
                    return None
                text = f"{ident}#{data.hex().upper()}" + (f"_{dlc:X}" if dlc > 8 else "")
        self._last = ts
        return f"({ts:f}) {channel} {text}{eol}\n"


def open_log(path: str) -> MessageWriter:
    """A python-can log writer for ``path``, chosen by its extension; a ``.log`` is written as
    ``candump -L`` writes (``CandumpLogWriter``), and so is a ``.log.gz``, through gzip (where
    python-can's compressed writer would write its own lines)."""
    lower = path.lower()
    if lower.endswith(".log"):
        return CandumpLogWriter(path)
    if lower.endswith(".log.gz"):
        return CandumpLogWriter(gzip.open(path, "wt", encoding="ascii"))
    return can.Logger(path)

"""pcapng captures of the radio and the CAN buses, for Wireshark and tshark (issue 15).

One file per run, written with python-pcapng. One interface per radio (``LINKTYPE_USER0``,
147: the bytes on air as one packet per transmission, dissected by the plugin
``hil/wireshark/rprs.lua``), one for transmitters that are no robot (interference, forged
frames), and one per child's CAN bus (``LINKTYPE_CAN_SOCKETCAN``, 227, which Wireshark decodes
natively). Timestamps are the tick a packet ends (the last stop bit, the end of EOF; an error
frame: its flag's first bit) at ``if_tsresol`` 10^-10 s, so a 62.5 ns tick is 625 units
exactly. Nothing is dropped: collided, aborted and interference transmissions are kept, with a
packet comment saying which; CAN error frames are SocketCAN error frames (``CAN_ERR_FLAG``).
"""
from __future__ import annotations

import io
import struct
from typing import IO, TYPE_CHECKING, Any

import pcapng
from pcapng import blocks

from can_bus.frames import CAN_EFF_FLAG, CAN_ERR_FLAG, CAN_ERR_MASK, CAN_RTR_FLAG, fd_flags
from firmware_model.timing import TICK_HZ

if TYPE_CHECKING:
    import can

LINKTYPE_USER0 = 147
LINKTYPE_CAN_SOCKETCAN = 227
TSRESOL = 10
"""if_tsresol: timestamps in units of 10^-10 s."""
UNITS_PER_TICK = 10**TSRESOL // TICK_HZ          # 625
_TS_AT = 12
"""Offset of an Enhanced Packet Block's timestamp (upper then lower 32 bits) after its block
type, total length and interface ID (pcapng, draft-ietf-opsawg-pcapng, 4.3)."""
_DISTINCT_BLOCKS = 1 << 16
"""Distinct packets whose bytes a writer keeps (then it starts again: memory stays bounded)."""

CAN_ERR_PROT = 0x00000008
CAN_ERR_ACK = 0x00000020
PROT_TYPES = {"bit": 0x01, "form": 0x02, "stuff": 0x04}
"""data[2] of a protocol-violation error frame (linux/can/error.h, CAN_ERR_PROT_*)."""


def socketcan_frame(can_id: int, data: bytes, rtr: bool = False,
                    dlc: int | None = None) -> bytes:
    """16 bytes of LINKTYPE_CAN_SOCKETCAN (linux/can.h ``struct can_frame``): the identifier
    and flags in network byte order, the length, two padding bytes, the raw DLC where it is
    above 8 (``len8_dlc``), eight data bytes. A remote frame (``rtr``) has CAN_RTR_FLAG and,
    for its length, the bytes it asks for (its DLC), and no data."""
    dlc = (0 if rtr else len(data)) if dlc is None else dlc
    if rtr:
        can_id |= CAN_RTR_FLAG
        data = b""
    length = min(dlc, 8) if rtr else len(data)
    raw = dlc if 8 < dlc <= 15 and length == 8 else 0
    return struct.pack(">IB2xB8s", can_id, length, raw, bytes(data))


def socketcan_message(msg: "can.Message") -> bytes:
    """A frame python-can received that is no CAN 2.0A node's (an extended id, CAN FD, an error
    frame) as LINKTYPE_CAN_SOCKETCAN: ``struct can_frame`` with CAN_EFF_FLAG or CAN_ERR_FLAG
    (and its error class), or ``struct canfd_frame`` (72 bytes, CANFD_FDF and the BRS/ESI
    flags in its flags byte)."""
    can_id = msg.arbitration_id
    if msg.is_error_frame:
        return struct.pack(">IB3x8s", CAN_ERR_FLAG | (can_id & CAN_ERR_MASK),
                           min(len(msg.data), 8), bytes(msg.data[:8]))
    if msg.is_extended_id:
        can_id |= CAN_EFF_FLAG
    if msg.is_fd:
        return struct.pack(">IBB2x64s", can_id, len(msg.data), fd_flags(msg), bytes(msg.data))
    return socketcan_frame(can_id, bytes(msg.data), msg.is_remote_frame, msg.dlc)


def error_frame(kind: str) -> bytes:
    """A SocketCAN error frame for a bus error of ``kind`` (can_bus.bus ``error_trace``):
    ``ack`` is ``CAN_ERR_ACK``; ``bit``, ``stuff`` and ``form`` are ``CAN_ERR_PROT`` with that
    type in data[2]; ``local`` (one node's disturbed stub, a ``noisy`` fault: only that node
    sees the cause, the others a bit, stuff or form error of its flag) is ``CAN_ERR_PROT``
    with no type, ``CAN_ERR_PROT_UNSPEC`` (docs/wireshark.md, "Interfaces")."""
    if kind == "ack":
        return socketcan_frame(CAN_ERR_FLAG | CAN_ERR_ACK, bytes(8))
    data = bytearray(8)
    data[2] = PROT_TYPES.get(kind, 0)
    return socketcan_frame(CAN_ERR_FLAG | CAN_ERR_PROT, bytes(data))


class PcapWriter:
    """Write a run's traffic to ``stream`` (a binary file object). ``radios``: interface name
    per radio key, ``buses``: interface name per CAN bus key; both fixed before the first
    packet (pcapng declares interfaces up front).

    Timestamps are ``epoch_units + tick`` in units of 10^-``tsresol`` s: a simulation starts
    at 0 with ``tsresol`` 10 (a tick exactly); a bench capture takes ``epoch_units`` from the
    wall clock of its real-time scheduler's tick 0 (:meth:`follow`) and uses ``tsresol`` 9
    (ns: the Unix epoch at 10^-10 s would overflow pcapng's 64 bits in 2028). ``live``:
    flush after every packet (a pipe to ``wireshark -k -i -``)."""

    def __init__(self, stream: IO[bytes], radios: dict[object, str], buses: dict[int, str],
                 tsresol: int = TSRESOL, epoch_units: int = 0, live: bool = False) -> None:
        self.stream = stream
        self.tsresol = tsresol
        self.epoch_units = epoch_units
        self.live = live
        self.shb = blocks.SectionHeader(options={"shb_userappl": "rprs"})
        self._ifaces: dict[tuple[str, object], int] = {}
        for key, name in radios.items():
            self._add(("radio", key), LINKTYPE_USER0, name,
                      "RPRS radio channel, 9600 baud (rprs.lua)")
        for key, name in buses.items():
            self._add(("can", key), LINKTYPE_CAN_SOCKETCAN, name, "CAN 2.0A, 500 kbit/s")
        self.writer = pcapng.FileWriter(stream, self.shb)
        self.packets = 0
        # The library builds each distinct packet once (its bytes with timestamp 0); a packet
        # seen before is those bytes with its timestamp put in (a heartbeat's bytes repeat
        # every cycle, and python-pcapng takes ~100 us to build a block).
        self._scratch = io.BytesIO()
        self._encoder = pcapng.FileWriter(self._scratch, self.shb)
        self._header = self._scratch.tell()
        self._blocks: dict[tuple[int, bytes, str | None], bytes] = {}
        self._ts = struct.Struct(self.shb.endianness + "II")
        self._clock: Any = None
        if live:
            stream.flush()

    def _add(self, key: tuple[str, object], link: int, name: str, descr: str) -> None:
        idb = self.shb.new_member(blocks.InterfaceDescription, link_type=link, snaplen=65535,
                                  options={"if_name": name, "if_description": descr,
                                           "if_tsresol": bytes((self.tsresol,))})
        self._ifaces[key] = idb.interface_id

    def follow(self, clock: Any) -> None:
        """Stamp packets on the wall clock of ``clock``'s tick 0 (a
        :class:`~hil.sim.realtime.RealTimeScheduler`'s ``epoch_ns``), read at the first
        packet: the scheduler fixes it when it starts running, after its process has built
        what it runs (a stamp taken earlier put every packet that much too early). A clock
        without a wall clock (a simulated scheduler) leaves the stamps ticks from 0."""
        self._clock = clock if hasattr(clock, "epoch_ns") else None

    def _packet(self, key: tuple[str, object], tick: int, data: bytes,
                comment: str | None) -> None:
        scale = 10 ** self.tsresol
        if self._clock is not None and self._clock.epoch_ns is not None:
            self.epoch_units = self._clock.epoch_ns * scale // 1_000_000_000
            self._clock = None
        ts = self.epoch_units + (tick * scale * 2 + TICK_HZ) // (2 * TICK_HZ)
        memo = (self._ifaces[key], bytes(data), comment or None)
        block = self._blocks.get(memo)
        if block is None:
            block = self._blocks[memo] = self._encode(*memo)
            if len(self._blocks) > _DISTINCT_BLOCKS:
                self._blocks.clear()
        self.stream.write(block[:_TS_AT] + self._ts.pack(ts >> 32, ts & 0xFFFFFFFF) +
                          block[_TS_AT + 8:])
        self.packets += 1
        if self.live:
            self.stream.flush()

    def _encode(self, interface: int, data: bytes, comment: str | None) -> bytes:
        """The Enhanced Packet Block python-pcapng writes for this packet at timestamp 0.
        python-pcapng refuses an empty packet, which pcapng allows (a radio that died within
        its first byte sent no whole byte): that block is the one-byte packet's with the
        lengths 0 and without the data's 4 padded bytes."""
        if not data:
            one = self._encode(interface, b"\0", comment)
            size = struct.pack(self.shb.endianness + "I", len(one) - 4)
            return (one[:4] + size + one[8:_TS_AT + 8] + bytes(8) + one[_TS_AT + 20:-4] +
                    size)
        opts = {"opt_comment": comment} if comment else {}
        epb = self.shb.new_member(blocks.EnhancedPacket, interface_id=interface,
                                  timestamp_high=0, timestamp_low=0, packet_data=data,
                                  options=opts)
        scratch = self._scratch
        scratch.seek(self._header)
        scratch.truncate()
        self._encoder.write_block(epb)
        return scratch.getvalue()[self._header:]

    def radio(self, key: object, end: int, data: bytes, comment: str | None = None) -> None:
        """A transmission on air, ending at tick ``end``: the bytes its sender sent."""
        self._packet(("radio", key), end, data, comment)

    def can(self, bus: int, tick: int, can_id: int, data: bytes, rtr: bool = False,
            dlc: int | None = None) -> None:
        """A CAN 2.0A frame on ``bus`` that ended (EOF) at ``tick`` (``rtr``: a remote frame,
        asking for ``dlc`` bytes)."""
        self._packet(("can", bus), tick, socketcan_frame(can_id, data, rtr, dlc), None)

    def can_raw(self, bus: int, tick: int, packet: bytes) -> None:
        """A LINKTYPE_CAN_SOCKETCAN packet on ``bus`` at ``tick`` (``socketcan_message``)."""
        self._packet(("can", bus), tick, packet, None)

    def can_error(self, bus: int, tick: int, kind: str, comment: str) -> None:
        """An error frame on ``bus`` whose flag started at ``tick``."""
        self._packet(("can", bus), tick, error_frame(kind), comment)

"""CAN 2.0A (11-bit identifier) bit level: CRC-15, bit stuffing, exact frame lengths, bit timing.

Everything here follows Bosch CAN 2.0 part A / ISO 11898-1 (classical CAN). Bits are ints,
``0`` = dominant, ``1`` = recessive, most significant bit first as on the wire.

Data/remote frame layout (unstuffed)::

    SOF(1) ID(11) RTR(1) IDE(1)=0 r0(1)=0 DLC(4) DATA(8*n) CRC(15)
    \\______________ stuffed, CRC covered (CRC not) ______________/

    then CRCdel(1) ACK(1) ACKdel(1) EOF(7)
         \\___ fixed form, not stuffed ___/

followed on the bus by the 3-bit intermission (IFS) before the next SOF may start.
Unstuffed length without IFS is ``44 + 8*n`` bits; with IFS ``47 + 8*n``.

Stuffing: after five consecutive equal bits the transmitter inserts one complementary bit; the
stuff bit counts as the first bit of the next run. Stuffing covers SOF through the last CRC bit,
so a stuff bit *is* inserted after the last CRC bit when the CRC ends a run of five (that is
what makes the classic worst-case bound ``floor((34 + 8n - 1) / 4)`` stuff bits).

Error and overload frames (constants below): an active error flag is 6 dominant bits; because
the other nodes answer the first flag with their own flags, superposition makes the dominant
part 6..12 bits on the wire. The error delimiter is 8 recessive bits. An overload frame is
built the same way (6 flag bits, 6..12 superposed, 8 delimiter bits).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Iterable, Sequence

from can_bus.clock import DEFAULT_TICK_HZ

__all__ = [
    "CRC15_POLY",
    "MAX_ID",
    "SOF_TO_CRC_OVERHEAD_BITS",
    "FRAME_OVERHEAD_BITS",
    "CRC_DELIM_BITS",
    "ACK_BITS",
    "EOF_BITS",
    "IFS_BITS",
    "TRAILER_BITS",
    "ERROR_FLAG_BITS",
    "ERROR_FLAG_MAX_BITS",
    "ERROR_DELIMITER_BITS",
    "ERROR_FRAME_BITS",
    "OVERLOAD_FLAG_BITS",
    "OVERLOAD_FLAG_MAX_BITS",
    "OVERLOAD_DELIMITER_BITS",
    "OVERLOAD_FRAME_BITS",
    "SUSPEND_TRANSMISSION_BITS",
    "BUS_IDLE_RECESSIVE_BITS",
    "BUS_OFF_RECOVERY_SEQUENCES",
    "StuffError",
    "crc15",
    "frame_bits",
    "stuff",
    "unstuff",
    "stuff_count",
    "wire_bits",
    "frame_length_bits",
    "worst_case_length_bits",
    "min_length_bits",
    "dlc_to_len",
    "BitTiming",
]

CRC15_POLY = 0x4599
"""x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1 with the x^15 term implicit."""

MAX_ID = 0x7FF

SOF_TO_CRC_OVERHEAD_BITS = 34
"""SOF 1 + ID 11 + RTR 1 + IDE 1 + r0 1 + DLC 4 + CRC 15: the stuffed region minus the data."""

CRC_DELIM_BITS = 1
ACK_BITS = 2
"""ACK slot + ACK delimiter."""
EOF_BITS = 7
IFS_BITS = 3
"""Intermission between frames."""
TRAILER_BITS = CRC_DELIM_BITS + ACK_BITS + EOF_BITS
"""10 fixed-form bits after the CRC sequence (never stuffed)."""
FRAME_OVERHEAD_BITS = SOF_TO_CRC_OVERHEAD_BITS + TRAILER_BITS
"""44: unstuffed frame length without data and without IFS."""

ERROR_FLAG_BITS = 6
"""Error flag sent by one node (active: dominant; passive: recessive)."""
ERROR_FLAG_MAX_BITS = 12
"""Longest superposition of error flags on the wire (each node flags within 6 bits of the first)."""
ERROR_DELIMITER_BITS = 8
ERROR_FRAME_BITS = ERROR_FLAG_BITS + ERROR_DELIMITER_BITS
"""14: error frame with all flags superposed exactly (no IFS)."""
OVERLOAD_FLAG_BITS = 6
OVERLOAD_FLAG_MAX_BITS = 12
OVERLOAD_DELIMITER_BITS = 8
OVERLOAD_FRAME_BITS = OVERLOAD_FLAG_BITS + OVERLOAD_DELIMITER_BITS
"""14: overload frame with flags superposed exactly (no IFS)."""
SUSPEND_TRANSMISSION_BITS = 8
"""Extra recessive bits an error-passive node waits after IFS following its own transmission."""
BUS_IDLE_RECESSIVE_BITS = 11
"""A bus-off node counts sequences of this many consecutive recessive bits ..."""
BUS_OFF_RECOVERY_SEQUENCES = 128
"""... and becomes error-active again after this many of them."""
ERROR_PASSIVE_LIMIT = 128
"""A node whose TEC or REC reaches this is error-passive (ISO 11898-1 fault confinement)."""
BUS_OFF_LIMIT = 256
"""A node whose TEC reaches this (exceeds 255) is bus-off (ISO 11898-1 fault confinement)."""


class StuffError(ValueError):
    """Six consecutive equal bits found inside a stuffed bit stream."""

    def __init__(self, index: int, value: int) -> None:
        super().__init__(f"stuff error: sixth consecutive {value!s} at bit index {index}")
        self.index = index
        self.value = value


def crc15(bits: Iterable[int]) -> int:
    """CAN CRC-15 (poly 0x4599, init 0, no reflection, no final xor) over a bit sequence.

    Feed it the unstuffed bits from SOF through the end of the data field. The catalogue check
    value (ASCII "123456789", MSB first) is 0x059E.
    """
    crc = 0
    for b in bits:
        nxt = (crc >> 14) ^ (b & 1)
        crc = (crc << 1) & 0x7FFF
        if nxt:
            crc ^= CRC15_POLY
    return crc


def dlc_to_len(dlc: int) -> int:
    """Data bytes meant by a DLC (ISO 11898-1: 9..15 mean 8)."""
    return dlc if dlc <= 8 else 8


def _check(can_id: int, data: bytes, rtr: bool, dlc: int | None) -> int:
    """Validate and return the DLC to put on the wire."""
    if not isinstance(can_id, int) or isinstance(can_id, bool):
        raise TypeError(f"CAN id must be an int, not {type(can_id).__name__}")
    if not 0 <= can_id <= MAX_ID:
        raise ValueError(f"CAN 2.0A id must be in 0..0x7FF, got {can_id:#x}")
    if len(data) > 8:
        raise ValueError(f"a CAN 2.0A frame carries at most 8 data bytes, got {len(data)}")
    if rtr:
        if data:
            raise ValueError("a remote (RTR) frame has no data field; pass its length as dlc")
        if dlc is None:
            return 0
    elif dlc is None:
        return len(data)
    if not isinstance(dlc, int) or isinstance(dlc, bool) or not 0 <= dlc <= 15:
        raise ValueError(f"DLC must be an int in 0..15 (9..15 mean 8 bytes), got {dlc!r}")
    if not rtr and dlc_to_len(dlc) != len(data):
        raise ValueError(f"DLC {dlc} means {dlc_to_len(dlc)} data bytes but {len(data)} were given")
    return dlc


def _int_bits(value: int, width: int) -> list[int]:
    return [(value >> i) & 1 for i in range(width - 1, -1, -1)]


def _frame_bits(can_id: int, data: bytes, rtr: bool, dlc: int) -> list[int]:
    bits = [0]
    bits += _int_bits(can_id, 11)
    bits.append(1 if rtr else 0)
    bits += (0, 0)  # IDE (base format), r0
    bits += _int_bits(dlc, 4)
    for byte in data:
        bits += _int_bits(byte, 8)
    bits += _int_bits(crc15(bits), 15)
    return bits


def frame_bits(can_id: int, data: bytes = b"", rtr: bool = False,
               dlc: int | None = None) -> list[int]:
    """Unstuffed SOF, ID, RTR, IDE, r0, DLC, data, CRC (34 + 8n bits). Dominant = 0."""
    data = bytes(data)
    return _frame_bits(can_id, data, rtr, _check(can_id, data, rtr, dlc))


def stuff(bits: Sequence[int]) -> list[int]:
    """Insert a complementary bit after every five equal consecutive bits (stuff bits count)."""
    out: list[int] = []
    last = -1
    run = 0
    for b in bits:
        out.append(b)
        if b == last:
            run += 1
        else:
            last = b
            run = 1
        if run == 5:
            last ^= 1
            out.append(last)
            run = 1
    return out


def stuff_count(bits: Sequence[int]) -> int:
    """Number of stuff bits ``stuff(bits)`` would insert."""
    n = 0
    last = -1
    run = 0
    for b in bits:
        if b == last:
            run += 1
        else:
            last = b
            run = 1
        if run == 5:
            n += 1
            last ^= 1
            run = 1
    return n


def unstuff(bits: Sequence[int]) -> list[int]:
    """Remove stuff bits; raise :class:`StuffError` on six equal consecutive bits.

    A stream that ends right after five equal bits (its stuff bit cut off) is accepted.
    """
    out: list[int] = []
    last = -1
    run = 0
    expect_stuff = False
    for i, b in enumerate(bits):
        if expect_stuff:
            if b == last:
                raise StuffError(i, b)
            expect_stuff = False
            last = b
            run = 1
            continue
        out.append(b)
        if b == last:
            run += 1
        else:
            last = b
            run = 1
        if run == 5:
            expect_stuff = True
    return out


def _crc15_byte_table() -> tuple[int, ...]:
    """``crc15`` of eight zero bits from the register ``i << 7``, for each top byte ``i``:
    one data byte then costs a table lookup instead of eight shifts (the result is the same)."""
    table = []
    for i in range(256):
        crc = i << 7
        for _ in range(8):
            top = crc >> 14
            crc = (crc << 1) & 0x7FFF
            if top:
                crc ^= CRC15_POLY
        table.append(crc)
    return tuple(table)


_CRC15_BYTE = _crc15_byte_table()
_TRAILER = b"\x01" * TRAILER_BITS  # CRC delimiter, ACK slot (recessive as sent), ACK delimiter, EOF


@lru_cache(maxsize=1024)
def _header_crc(header: int) -> int:
    """CRC-15 register after the 19 header bits (SOF, ID, RTR, IDE, r0, DLC)."""
    return crc15(_int_bits(header, 19))


_START = 10
"""Stuffing state before the first bit; states 0-9 are ``last * 5 + run - 1``: the last bit
sent and how many equal bits end the output (1-4, stuff bits counted; a fifth is followed
by its stuff bit at once, as :func:`stuff` does)."""


@lru_cache(maxsize=None)
def _stuff_table(width: int) -> tuple[tuple[bytes, int], ...]:
    """For every state and every ``width``-bit chunk (MSB first), at ``state << width |
    chunk``: the chunk stuffed as :func:`stuff` would go on from that state (bits as bytes
    0/1), and the state after it. Built at first use (a few ms)."""
    table = []
    for state in range(_START + 1):
        last, run = (-1, 0) if state == _START else divmod(state, 5)
        run += state != _START
        for chunk in range(1 << width):
            out = bytearray()
            b_last, b_run = last, run
            for i in range(width - 1, -1, -1):
                b = chunk >> i & 1
                out.append(b)
                if b == b_last:
                    b_run += 1
                else:
                    b_last, b_run = b, 1
                if b_run == 5:
                    b_last ^= 1
                    out.append(b_last)
                    b_run = 1
            table.append((bytes(out), b_last * 5 + b_run - 1))
    return tuple(table)


def _stuff_int(value: int, nbits: int) -> bytes:
    """``stuff`` of the ``nbits``-bit big-endian ``value``, as bytes 0/1 (the same bits, tested
    against it), a byte at a time by table lookups instead of bit by bit: a frame's SOF..CRC
    field is 34 + 8 x DLC bits, so its first 2 bits go through the 2-bit table, then whole
    bytes."""
    head = nbits & 7
    shift = nbits - head
    state = _START
    parts = []
    if head:
        part, state = _stuff_table(head)[state << head | value >> shift]
        parts.append(part)
    table = _stuff_table(8)
    while shift:
        shift -= 8
        part, state = table[state << 8 | (value >> shift) & 0xFF]
        parts.append(part)
    return b"".join(parts)


@lru_cache(maxsize=4096)
def _wire(can_id: int, data: bytes, rtr: bool, dlc: int) -> tuple[int, ...]:
    """``stuff(frame_bits(...))`` and the 10 trailer bits, as a tuple. A status frame whose data
    changes misses the cache (nearly every frame of a moving joint does), so this is computed
    from integers, a byte at a time (the same bits as the bit-by-bit functions above, tested
    against them) rather than lists of bits."""
    header = can_id << 7 | (bool(rtr) << 6) | dlc   # SOF 0, ID, RTR, IDE 0, r0 0, DLC
    crc = _header_crc(header)
    table = _CRC15_BYTE
    for byte in data:
        crc = ((crc << 8) & 0x7FFF) ^ table[((crc >> 7) ^ byte) & 0xFF]
    n = 8 * len(data)
    value = ((header << n | int.from_bytes(data, "big")) << 15) | crc
    return tuple(_stuff_int(value, 34 + n) + _TRAILER)


def wire_bits(can_id: int, data: bytes = b"", rtr: bool = False,
              dlc: int | None = None) -> list[int]:
    """The transmitted bit sequence: stuffed(SOF..CRC) + CRCdel + ACK slot(1) + ACKdel + EOF.

    The ACK slot is shown as the transmitter sends it (recessive); acknowledging receivers
    overwrite it with a dominant bit on the bus. The intermission is not included.
    """
    data = bytes(data)
    return list(_wire(can_id, data, rtr, _check(can_id, data, rtr, dlc)))


@lru_cache(maxsize=None)
def _stuff_len_table(width: int) -> tuple[int, ...]:
    """:func:`_stuff_table` as lengths: at the same index, the stuffed chunk's length << 4 |
    the state after it (states are 0-10)."""
    return tuple(len(part) << 4 | state for part, state in _stuff_table(width))


@lru_cache(maxsize=1024)
def _header_run(header: int) -> tuple[int, int, int]:
    """(CRC-15 register, stuffed length, stuffing state) after the 19 header bits."""
    n, state = 0, _START
    for width, chunk in ((3, header >> 16), (8, header >> 8 & 0xFF), (8, header & 0xFF)):
        e = _stuff_len_table(width)[state << width | chunk]
        n += e >> 4
        state = e & 15
    return _header_crc(header), n, state


@lru_cache(maxsize=8192)
def _length(can_id: int, data: bytes, rtr: bool, dlc: int) -> int:
    """``len(_wire(...))`` without building the bits (the bus needs only the length of a
    frame nothing goes wrong in, and a moving joint's status frames are new nearly every
    time): the same CRC, and the stuffed lengths of the header, each data byte and the CRC
    from the tables (tested against :func:`_wire`)."""
    crc, n, state = _header_run(can_id << 7 | (bool(rtr) << 6) | dlc)
    table = _CRC15_BYTE
    lens = _stuff_len_table(8)
    for byte in data:
        crc = ((crc << 8) & 0x7FFF) ^ table[((crc >> 7) ^ byte) & 0xFF]
        e = lens[state << 8 | byte]
        n += e >> 4
        state = e & 15
    e = _stuff_len_table(7)[state << 7 | crc >> 8]
    return n + (e >> 4) + (lens[(e & 15) << 8 | crc & 0xFF] >> 4) + TRAILER_BITS


def frame_length_bits(
    can_id: int,
    data: bytes = b"",
    rtr: bool = False,
    include_ifs: bool = True,
    dlc: int | None = None,
) -> int:
    """Exact bits on the wire, stuff bits included, +3 intermission bits when ``include_ifs``."""
    data = bytes(data)
    n = _length(can_id, data, rtr, _check(can_id, data, rtr, dlc))
    return n + IFS_BITS if include_ifs else n


def _dlc_bytes(dlc: int) -> int:
    if not isinstance(dlc, int) or isinstance(dlc, bool) or not 0 <= dlc <= 15:
        raise ValueError(f"DLC must be an int in 0..15, got {dlc!r}")
    return dlc_to_len(dlc)


def worst_case_length_bits(dlc: int, include_ifs: bool = True) -> int:
    """Upper bound on a data frame's length with ``dlc`` bytes: ``8n + 47 + floor((34+8n-1)/4)``.

    The stuffed region has ``g = 34 + 8n`` bits; the first stuff bit needs 5 bits, each later
    one can come after 4 (the stuff bit starts the next run), hence ``floor((g - 1) / 4)``
    (Davis, Burns, Bril, Lukkien 2007, correcting Tindell's ``/5``). 135 bits for 8 bytes,
    55 for 0 bytes, IFS included. Real frames never exceed it; the CRC makes it not always
    reachable.
    """
    n = _dlc_bytes(dlc)
    g = SOF_TO_CRC_OVERHEAD_BITS + 8 * n
    total = g + TRAILER_BITS + (g - 1) // 4
    return total + IFS_BITS if include_ifs else total


def min_length_bits(dlc: int, include_ifs: bool = True) -> int:
    """Length with no stuff bit at all: ``44 + 8n`` (+3 IFS): 111 bits for 8 bytes with IFS."""
    n = _dlc_bytes(dlc)
    total = FRAME_OVERHEAD_BITS + 8 * n
    return total + IFS_BITS if include_ifs else total


@dataclass(frozen=True)
class BitTiming:
    """Nominal bit timing in MB90F549-controller style settings, in clock ticks.

    ``tick_hz``: ticks per second of the clock the bus runs on (default 16 MHz, the MB90F549's
    machine clock). ``prescaler``: clock ticks per time quantum (1..64). A bit is
    ``1 (sync) + tseg1 + tseg2`` quanta; ``tseg1`` (2..16) is propagation + phase-1 segment,
    ``tseg2`` (2..8) the phase-2 segment, ``sjw`` (1..4, at most ``tseg1`` and ``tseg2``) the
    resynchronisation jump width. The sample point is at the end of tseg1.

    The lower bounds are the F2MC-16LX hardware manual's conditions for correct operation
    (chapter 21 "CAN controller", bit timing register BTR, p. 464): TSEG1 >= 2 TQ, TSEG2 >= 2 TQ,
    both >= RSJW; with PSC = 0 (one clock tick a quantum) TSEG1 >= 5 TQ. The register fields
    can hold a one-quantum segment; the part does not work with one, so it is refused.

    The default is 500 kbit/s: 2 ticks a quantum, 1 + 11 + 4 = 16 quanta, 32 ticks a bit,
    sample point 75 %. Bit rates above 1 Mbit/s (CAN 2.0 / 82C250 limit) are rejected.
    """

    prescaler: int = 2
    tseg1: int = 11
    tseg2: int = 4
    sjw: int = 1
    tick_hz: int = DEFAULT_TICK_HZ

    def __post_init__(self) -> None:
        for name, lo, hi in (("prescaler", 1, 64), ("tseg1", 1, 16), ("tseg2", 1, 8),
                             ("sjw", 1, 4)):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
                raise ValueError(f"BitTiming.{name} must be an int in {lo}..{hi}, got {v!r}")
        min_tseg1 = 5 if self.prescaler == 1 else 2  # F2MC-16LX manual ch. 21, BTR, p. 464
        if self.tseg1 < min_tseg1 or self.tseg2 < 2:
            raise ValueError(
                f"BitTiming tseg1={self.tseg1}, tseg2={self.tseg2} with prescaler "
                f"{self.prescaler}: "
                f"the CAN controller needs tseg1 >= {min_tseg1} and tseg2 >= 2 quanta "
                f"(F2MC-16LX hardware manual, BTR conditions)"
            )
        if self.sjw > self.tseg2 or self.sjw > self.tseg1:
            raise ValueError(
                f"BitTiming.sjw ({self.sjw}) must not exceed tseg1 ({self.tseg1}) or tseg2 "
                f"({self.tseg2})"
            )
        if not isinstance(self.tick_hz, int) or self.tick_hz < 1_000_000:
            raise ValueError(f"BitTiming.tick_hz must be an int of at least 1 MHz, got "
                             f"{self.tick_hz!r}")
        if self.tick_hz > 1_000_000 * self.ticks_per_bit:     # exact: no rounding of the rate
            raise ValueError(
                f"bit time of {self.ticks_per_bit} ticks is faster than 1 Mbit/s, the CAN 2.0 limit"
            )

    @property
    def tq_per_bit(self) -> int:
        return 1 + self.tseg1 + self.tseg2

    @property
    def ticks_per_tq(self) -> int:
        return self.prescaler

    @property
    def ticks_per_bit(self) -> int:
        return self.prescaler * (1 + self.tseg1 + self.tseg2)

    @property
    def bitrate(self) -> float:
        """Bits per second (exact when ``tick_hz`` divides evenly)."""
        return self.tick_hz / self.ticks_per_bit

    @property
    def sample_point(self) -> float:
        """Sample point as a fraction of the bit time (0.75 for the default)."""
        return (1 + self.tseg1) / self.tq_per_bit

    @property
    def sample_point_ticks(self) -> int:
        """Ticks from the start of a bit to its sample point."""
        return (1 + self.tseg1) * self.prescaler

    @classmethod
    def from_bitrate(cls, bitrate: int, tq_per_bit: int = 16, sample_point: float = 0.75,
                     sjw: int = 1, tick_hz: int = DEFAULT_TICK_HZ) -> "BitTiming":
        """Settings giving exactly ``bitrate`` with ``tq_per_bit`` quanta from a ``tick_hz``
        clock; ValueError if impossible."""
        for name, v in (("bitrate", bitrate), ("tq_per_bit", tq_per_bit), ("tick_hz", tick_hz)):
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ValueError(f"BitTiming.from_bitrate: {name} must be a positive int, "
                                 f"got {v!r}")
        ticks = tick_hz / bitrate
        if ticks != int(ticks) or int(ticks) % tq_per_bit:
            raise ValueError(f"{bitrate} bit/s is not reachable with {tq_per_bit} quanta from "
                             f"{tick_hz} Hz")
        tseg1 = round(sample_point * tq_per_bit) - 1
        return cls(int(ticks) // tq_per_bit, tseg1, tq_per_bit - 1 - tseg1, sjw, tick_hz)

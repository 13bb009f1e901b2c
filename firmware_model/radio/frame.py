"""The RPRS radio frame (paper Fig. 8, docs/protocol.md §3.1), byte exact.

    Header  Dst  Src  Number  Type  Length  Content   End
    0F0A05  '2'  '1'  '05'    '2'   '0009'  movex(10) 17 19

Header 3 bytes, Destination/Source/Type one ASCII digit each, Number two ASCII decimal digits,
Length four ASCII decimal digits (Content bytes), Content printable ASCII, End 2 bytes: 14 bytes
of overhead. ``FRAME_FORMAT`` is the one ``construct`` declaration of that layout; ``encode`` and
``parse_frame`` both go through it, compiled by construct (:func:`frame_codec`). ``parse_frame``
first walks the bytes in wire order so the
FIRST bad byte is reported as a :class:`FrameError` with its offset and field, never as a
``construct`` exception.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from enum import IntEnum

from construct import (
    Adapter,
    Bytes,
    Const,
    ConstructError,
    Rebuild,
    Struct,
    ValidationError,
    len_,
    this,
)

from firmware_model.radio.errors import FrameError, describe_byte
from firmware_model.timing import CHILD_BYTE_TICKS, FRAME_OVERHEAD, max_content_bytes

__all__ = [
    "HEADER",
    "END",
    "BROADCAST",
    "FATHER",
    "CHILD_IDS",
    "ROBOT_IDS",
    "MAX_CONTENT",
    "MAX_LENGTH_FIELD",
    "CONTENT_OFFSET",
    "FrameError",
    "FrameType",
    "Frame",
    "FRAME_FORMAT",
    "frame_codec",
    "AsciiDecimal",
    "PrintableAscii",
    "parse_frame",
    "parse_frame_cached",
    "built_frame",
    "field_at",
    "frame_byte_error",
    "length_limits",
]

HEADER = b"\x0f\x0a\x05"
"""Frame start (paper Fig. 8)."""
END = b"\x17\x19"
"""Frame end (paper Fig. 8)."""
BROADCAST = 7
"""Destination '7': every member (docs/protocol.md §3.1, clause 7)."""
FATHER = 0
"""Robot ID of the father PC."""
CHILD_IDS = range(1, 7)
"""Robot IDs of the children, 1-6."""
ROBOT_IDS = range(0, 7)
"""Every robot ID that may appear as Source, 0-6."""

MAX_CONTENT = max_content_bytes(CHILD_BYTE_TICKS)
"""562 bytes: largest Content a child's frame can carry inside Tmax (docs/protocol.md §7.1)."""
MAX_LENGTH_FIELD = 9999
"""Largest value four ASCII digits of Length can hold."""
CONTENT_OFFSET = 12
"""Offset of the first Content byte in a frame (Header 3 + Dst 1 + Src 1 + Number 2 + Type 1 +
Length 4)."""

assert CONTENT_OFFSET + len(END) == FRAME_OVERHEAD


class FrameType(IntEnum):
    """Type digit (docs/protocol.md §3.1, clause 10). Digits 5-9 are allowed on the wire as project
    extensions."""

    SEEK_HELP = 0
    INVITATION = 1
    INSTRUCTION = 2
    BROADCAST_INFO = 3
    FAILURE = 4
    BOOT = 5
    """Extension (docs/mac.md): the heartbeat of a robot that has just powered on. Its Numbers
    restart at '00', so receivers forget the duplicates they remember from it."""
    JOIN = 6
    """Extension (docs/mac.md): the frame with which an invited robot answers an invitation
    (only such a frame, or a BOOT frame, admits a robot in an invitation window)."""


# --------------------------------------------------------------------------------------------
# The construct declaration
# --------------------------------------------------------------------------------------------


class AsciiDecimal(Adapter):
    """``width`` ASCII decimal digits '0'-'9' <-> int in 0..hi, zero padded, most significant
    first."""

    def __init__(self, width: int, hi: int | None = None) -> None:
        super().__init__(Bytes(width))
        self.width = width
        self.hi = 10**width - 1 if hi is None else hi

    def _decode(self, obj: bytes, context, path) -> int:
        if not obj.isdigit():  # bytes.isdigit is ASCII-only
            raise ValidationError(f"{obj!r} is not {self.width} ASCII decimal digit(s)", path=path)
        value = int(obj)
        if value > self.hi:
            raise ValidationError(f"{value} is above {self.hi}", path=path)
        return value

    def _encode(self, obj: int, context, path) -> bytes:
        if not 0 <= obj <= self.hi:
            raise ValidationError(f"{obj} is outside 0..{self.hi}", path=path)
        return b"%0*d" % (self.width, obj)


class PrintableAscii(Adapter):
    """Bytes that must all be printable ASCII 0x20-0x7E (Content, docs/protocol.md §3.1,
    clause 12)."""

    def _decode(self, obj: bytes, context, path) -> bytes:
        if not _is_printable(obj):
            raise ValidationError("Content is not printable ASCII", path=path)
        return obj

    _encode = _decode


FRAME_FORMAT = Struct(
    "header" / Const(HEADER),
    "dst" / AsciiDecimal(1),  # '0' father, '1'-'6' children, '7' broadcast, '8' '9' reserved
    "src" / AsciiDecimal(1, hi=max(ROBOT_IDS)),  # '0'-'6'
    "num" / AsciiDecimal(2),  # '00'-'99', per source
    "type" / AsciiDecimal(1),  # FrameType digit, 5-9 extensions
    "length" / Rebuild(AsciiDecimal(4), len_(this.content)),  # '0000'-'9999' Content bytes
    "content" / PrintableAscii(Bytes(this.length)),
    "end" / Const(END),
)
"""Whole frame, parse and build (paper Fig. 8). ``length`` is rebuilt from ``content``."""


@functools.cache
def frame_codec():
    """``FRAME_FORMAT`` compiled by construct (``Struct.compile``: the declaration turned into
    Python code once, on first use, ~40 ms), which :meth:`Frame.encode` and :func:`parse_frame`
    run: the same bytes and fields as the declaration (tests/firmware_model/radio/test_frame.py),
    parse about 5x and build about 2x faster (~15 and ~30 us a frame; docs/fast-paths.md,
    "Caches")."""
    return FRAME_FORMAT.compile()


# --------------------------------------------------------------------------------------------
# Frame
# --------------------------------------------------------------------------------------------

_PRINTABLE_DELETE = bytes(range(0x20, 0x7F))


def _is_printable(data: bytes) -> bool:
    """True when every byte is printable ASCII 0x20-0x7E."""
    return not data.translate(None, _PRINTABLE_DELETE)


def _is_int(v: object) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


@dataclass(frozen=True, slots=True)
class Frame:
    """One radio frame with integer fields (docs/protocol.md §3.1; §5: IDs are ints in code).

    ``dst`` 0-9, ``src`` 0-6, ``num`` 0-99, ``type`` 0-9 (see :class:`FrameType`),
    ``content`` printable ASCII, at most 9999 bytes. Bad values raise :class:`FrameError` whose
    offset is where the field sits in the encoded frame.
    """

    dst: int
    src: int
    num: int
    type: int
    content: bytes = b""

    def __post_init__(self) -> None:
        for name, field, offset, hi in (
            ("dst", "destination", 3, 9),
            ("src", "source", 4, 6),
            ("num", "number", 5, 99),
            ("type", "type", 7, 9),
        ):
            v = getattr(self, name)
            if not _is_int(v) or not 0 <= v <= hi:
                raise FrameError(f"{name}={v!r} is not an integer 0-{hi}", field=field,
                                 offset=offset)
        c = self.content
        if not isinstance(c, bytes):
            if isinstance(c, (bytearray, memoryview)):
                c = bytes(c)
                object.__setattr__(self, "content", c)
            else:
                raise FrameError(f"content must be bytes, got {type(c).__name__}", field="content")
        if len(c) > MAX_LENGTH_FIELD:
            raise FrameError(
                f"{len(c)} Content bytes do not fit the 4-digit Length (max {MAX_LENGTH_FIELD})",
                field="length",
                offset=8,
            )
        if not _is_printable(c):
            i = next(i for i, b in enumerate(c) if not 0x20 <= b <= 0x7E)
            raise FrameError(
                f"{describe_byte(c[i])} is not printable ASCII 0x20-0x7E",
                field="content",
                offset=CONTENT_OFFSET + i,
                byte=c[i],
            )

    @property
    def length(self) -> int:
        """Content bytes (the Length field)."""
        return len(self.content)

    @property
    def nbytes(self) -> int:
        """Bytes on air: 14 + Length."""
        return FRAME_OVERHEAD + len(self.content)

    @property
    def frame_type(self) -> FrameType | None:
        """The Type as a :class:`FrameType`, or None for an extension digit 5-9."""
        try:
            return FrameType(self.type)
        except ValueError:
            return None

    def encode(self) -> bytes:
        """The frame's bytes on the wire, built by ``FRAME_FORMAT`` (cached per frame)."""
        data = _ENCODED.get(self)
        return data if data is not None else _encode_new(self)


def _encode_new(frame: Frame) -> bytes:
    """:meth:`Frame.encode` for a frame not in the current generation of the cache: taken
    from the one before if it is there, else built; then remembered both ways."""
    data = _OLDER.get(frame)
    if data is None:
        data = frame_codec().build(dict(dst=frame.dst, src=frame.src, num=frame.num,
                                        type=frame.type, content=frame.content))
    if type(frame.dst) is not int or type(frame.src) is not int or type(frame.num) is not int \
            or type(frame.type) is not int or type(frame.content) is not bytes:
        # An IntEnum Type (the MAC's FrameType.BROADCAST_INFO, ...): a receiver is given the
        # frame parse_frame would give, plain ints and bytes, equal to this one.
        frame = Frame(int(frame.dst), int(frame.src), int(frame.num), int(frame.type),
                      bytes(frame.content))
    _remember(frame, data)
    return data


def _remember(frame: Frame, data: bytes) -> None:
    """Put ``frame`` (plain ints and bytes) and its bytes in the current generation, both
    ways; a full generation becomes the older one and the one before it is dropped."""
    global _ENCODED, _BUILT, _OLDER, _OLDER_BUILT
    if len(_ENCODED) >= _CACHE_MAX:
        _OLDER, _OLDER_BUILT, _ENCODED, _BUILT = _ENCODED, _BUILT, {}, {}
    _ENCODED[frame] = data
    _BUILT[data] = frame


_ENCODED: dict[Frame, bytes] = {}
"""Frames encoded in this generation -> their bytes (what :meth:`Frame.encode` looks up)."""
_BUILT: dict[bytes, Frame] = {}
"""The same generation the other way: bytes -> the frame they encode, with plain int and bytes
fields: a receiver of a new frame takes it here instead of parsing the bytes back
(:func:`built_frame`). Filled and emptied together with ``_ENCODED``, so every frame encoded in
this generation is found here. Module-level, never a field, like the deframer's cache
(snapshots walk fields only)."""
_OLDER: dict[Frame, bytes] = {}
_OLDER_BUILT: dict[bytes, Frame] = {}
"""The generation before, both ways: a frame from it encoded again, or its bytes looked up
again (a sender that keeps its heartbeat's bytes sends them without a new encode), comes
back into the current generation. So a frame sent again and again stays found."""
_CACHE_MAX = 4096
"""Frames in one generation (at most twice this many remembered)."""


def built_frame(data: bytes, max_content: int = MAX_CONTENT) -> Frame | None:
    """The frame whose :meth:`Frame.encode` gave exactly ``data``, if still remembered and its
    Length is at most ``max_content`` (bytes): then ``parse_frame(data, max_content)`` would
    return a frame equal to it, field for field, and this returns it without parsing. Else
    None (parse the bytes)."""
    frame = _BUILT.get(data)
    if frame is None:
        frame = _OLDER_BUILT.get(data)
        if frame is None:
            return None
        _remember(frame, data)
    return frame if len(frame.content) <= max_content else None


# --------------------------------------------------------------------------------------------
# Byte-level checks shared with the deframer
# --------------------------------------------------------------------------------------------


def field_at(offset: int, length: int | None) -> str:
    """Name of the field at ``offset`` of a frame whose Length is ``length`` (None: not known
    yet)."""
    if offset < 3:
        return "header"
    if offset < 8:
        return ("destination", "source", "number", "number", "type")[offset - 3]
    if offset < CONTENT_OFFSET:
        return "length"
    if length is None:
        return "content"
    if offset < CONTENT_OFFSET + length:
        return "content"
    if offset < CONTENT_OFFSET + length + 2:
        return "end"
    return "trailing"


@functools.lru_cache(maxsize=64)
def length_limits(max_content: int) -> tuple[int, int, int, int]:
    """Per Length digit k (0-3): the largest value of the first k+1 digits that can still be <=
    max_content.

    A Length digit is the first bad byte as soon as the digits so far make the value exceed
    ``max_content`` whatever follows (docs/protocol.md §3.1, clause 11: the deframer checks the
    length bound).
    """
    return (max_content // 1000, max_content // 100, max_content // 10, max_content)


def frame_byte_error(
    offset: int,
    b: int,
    *,
    length: int | None = None,
    partial_length: int = 0,
    max_content: int = MAX_CONTENT,
) -> FrameError:
    """The :class:`FrameError` for byte ``b``, already known to be bad, at ``offset`` of a frame.

    ``length`` is the parsed Length (for offsets past the Length field), ``partial_length`` the
    value of the Length digits including ``b`` when ``b`` is a Length digit.
    """
    field = field_at(offset, length)
    d = describe_byte(b)
    if field == "header":
        reason = f"{d} is not Header byte 0x{HEADER[offset]:02x}"
    elif field == "destination":
        reason = f"{d} is not a destination digit '0'-'9'"
    elif field == "source":
        reason = f"{d} is not a robot ID '0'-'6'"
    elif field == "number":
        reason = f"{d} is not an ASCII decimal digit of Number"
    elif field == "type":
        reason = f"{d} is not a Type digit '0'-'9'"
    elif field == "length":
        if 0x30 <= b <= 0x39:
            k = offset - 8
            least = partial_length * 10 ** (3 - k)
            reason = (f"{d} makes Length at least {least:04d}, above the {max_content}-byte "
                      "Content limit")
        else:
            reason = f"{d} is not an ASCII decimal digit of Length"
    elif field == "content":
        reason = f"{d} is not printable ASCII 0x20-0x7E"
    elif field == "end":
        want = END[offset - CONTENT_OFFSET - (length or 0)]
        reason = f"{d} is not End byte 0x{want:02x}"
    else:
        reason = f"{d} follows the End (expected exactly one frame)"
    return FrameError(reason, field=field, offset=offset, byte=b)


def _first_error(data: bytes, max_content: int) -> FrameError | None:
    """Walk ``data`` in wire order and return the error for the first bad byte, or None."""
    n = len(data)
    for i in range(min(n, 3)):
        if data[i] != HEADER[i]:
            return frame_byte_error(i, data[i])
    for i in range(3, min(n, 8)):
        b = data[i]
        hi = 0x36 if i == 4 else 0x39
        if not 0x30 <= b <= hi:
            return frame_byte_error(i, b)
    limits = length_limits(max_content)
    partial = 0
    for i in range(8, min(n, CONTENT_OFFSET)):
        b = data[i]
        if not 0x30 <= b <= 0x39:
            return frame_byte_error(i, b)
        partial = partial * 10 + b - 0x30
        if partial > limits[i - 8]:
            return frame_byte_error(i, b, partial_length=partial, max_content=max_content)
    if n < CONTENT_OFFSET:
        return FrameError(
            f"frame truncated after {n} bytes, before its Length was complete",
            field=field_at(n, None),
            offset=n,
        )
    length = partial
    stop = CONTENT_OFFSET + length
    content = data[CONTENT_OFFSET : min(n, stop)]
    if not _is_printable(content):
        i = next(i for i, b in enumerate(content) if not 0x20 <= b <= 0x7E)
        return frame_byte_error(CONTENT_OFFSET + i, content[i], length=length)
    for i in range(stop, min(n, stop + 2)):
        if data[i] != END[i - stop]:
            return frame_byte_error(i, data[i], length=length)
    total = stop + 2
    if n < total:
        return FrameError(
            f"frame truncated after {n} bytes, Length {length} needs {total}",
            field=field_at(n, length),
            offset=n,
        )
    if n > total:
        return frame_byte_error(total, data[total], length=length)
    return None


def parse_frame(data: bytes, max_content: int = MAX_CONTENT) -> Frame:
    """Parse exactly one whole frame (docs/protocol.md §3.1).

    Raises :class:`FrameError` naming the offset and field of the first bad byte: Header,
    digits, Length above ``max_content`` (bytes), non-printable Content, End, a truncated frame
    (offset = len(data), byte None) or bytes after the End (field 'trailing').
    """
    if not isinstance(data, bytes):
        data = bytes(data)
    err = _first_error(data, max_content)
    if err is not None:
        raise err
    try:
        c = frame_codec().parse(data)
    except ConstructError as exc:  # pragma: no cover - _first_error catches everything first
        raise FrameError(f"construct rejected the frame: {exc}", field="frame") from None
    return Frame(dst=c.dst, src=c.src, num=c.num, type=c.type, content=c.content)


def parse_frame_cached(data: bytes, max_content: int = MAX_CONTENT) -> Frame:
    """:func:`parse_frame`, memoised: the simulator hands the same heartbeat bytes to many
    receivers, and bytes a sender built in this process are known already (:func:`built_frame`).

    Only successful parses are cached; errors are raised afresh every time.
    """
    frame = built_frame(data, max_content)
    return frame if frame is not None else _parse_frame_lru(data, max_content)


@functools.lru_cache(maxsize=4096)
def _parse_frame_lru(data: bytes, max_content: int) -> Frame:
    return parse_frame(data, max_content)

"""Byte-at-a-time radio receiver (docs/protocol.md §3.2, clause 15), with a bulk fast path that
gives the same events.

The deframer hunts for the Header ``0F 0A 05``, then checks every field as its byte arrives:
Destination '0'-'9', Source '0'-'6', Number two digits, Type one digit, Length four digits whose
value may not exceed ``max_content`` (a Length digit is bad as soon as no later digits could
bring the value back under the limit), Content printable 0x20-0x7E, End ``17 19``. On the first
bad byte it reports :class:`FrameFailed` and treats that byte as a fresh hunting byte. A real
frame's leading 0x0F is never valid inside a frame (not a digit, not printable, not End), so a
frame in progress can never swallow the start of a later good frame.

Ticks are integers (docs/protocol.md §2); a byte's tick is the tick at which its stop bit
completed.

Garbage (bytes discarded while hunting, partial Headers included) is reported as one
:class:`Garbage` event per run of consecutive discarded bytes, emitted when a Header is
confirmed (its 3rd byte accepted), by :meth:`Deframer.flush`, and at the end of every
:meth:`Deframer.feed` call. :meth:`Deframer.feed_byte` does not flush, so
``feed(data, t0, dt)`` returns exactly ``feed_byte(b_i, t0 + i*dt)`` for each byte, then
``flush()``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Union

from firmware_model.radio.errors import FrameError
from firmware_model.radio.frame import (
    CONTENT_OFFSET,
    HEADER,
    MAX_CONTENT,
    MAX_LENGTH_FIELD,
    Frame,
    built_frame,
    frame_byte_error,
    length_limits,
    parse_frame_cached,
)
from firmware_model.timing import CHILD_BYTE_TICKS

__all__ = ["FrameReceived", "Garbage", "FrameFailed", "DeframerEvent", "Deframer"]

_H0, _H1, _H2 = HEADER
_E0, _E1 = 0x17, 0x19
_E1_BYTE = bytes((_E1,))
_PRINTABLE = bytes(range(0x20, 0x7F))
"""The bytes a Content may hold (0x20-0x7E, docs/protocol.md §3.1)."""

_WHOLE: dict[int, dict[bytes, Frame]] = {}
"""Per Length limit: byte strings known to be exactly one good frame (the fast path's cache).
Shared by every deframer of the process, so no deframer holds it in a field: the simulator's
snapshots (hil/sim/state_walk.py) walk a world's fields, and walked this cache too, while the
world of another thread (a Dask worker's second thread in a campaign) added to it: "dictionary
changed size during iteration"."""
_WHOLE_MAX = 8192


@dataclass(frozen=True, slots=True)
class FrameReceived:
    """A good frame. ``first``: tick its first Header byte completed; ``end``: tick its last End
    byte completed."""

    frame: Frame
    first: int
    end: int


@dataclass(frozen=True, slots=True)
class Garbage:
    """``count`` consecutive bytes discarded while hunting, the first completed at tick ``first``,
    the last at ``last``."""

    count: int
    first: int
    last: int


@dataclass(frozen=True, slots=True)
class FrameFailed:
    """A validated Header whose frame then broke (bad byte, or :meth:`Deframer.abort`).

    ``first``: tick of the first Header byte; ``at``: tick of the bad byte (or of the abort);
    ``src``/``length``: those fields if already parsed; ``expected_end``: tick the last End
    byte would have completed, ``first + (13 + length) * byte_ticks``, when Length is known.
    """

    error: FrameError
    first: int
    at: int
    src: int | None
    length: int | None
    expected_end: int | None


DeframerEvent = Union[FrameReceived, Garbage, FrameFailed]


class Deframer:
    """Receiver state machine for one radio (docs/protocol.md §3.2, clause 15).

    ``max_content``: largest Length accepted (bytes, default 562 = child at Tmax);
    ``byte_ticks``: ticks a byte takes on air, only used for ``FrameFailed.expected_end``.

    Public state: ``in_frame`` (True from the 3rd Header byte until the frame completes or
    fails), ``first`` (tick of the first Header byte of the frame in progress, else None; a
    partial Header does not count), ``last_tick`` (tick of the last byte received, any byte).
    """

    __slots__ = (
        "max_content",
        "byte_ticks",
        "in_frame",
        "first",
        "last_tick",
        "_pos",
        "_hdr_t",
        "_raw",
        "_src",
        "_len",
        "_partial",
        "_limits",
        "_g_count",
        "_g_first",
        "_g_last",
    )

    def __init__(self, max_content: int = MAX_CONTENT, byte_ticks: int = CHILD_BYTE_TICKS) -> None:
        if not 0 <= max_content <= MAX_LENGTH_FIELD:
            raise ValueError(f"max_content must be 0..{MAX_LENGTH_FIELD}, got {max_content}")
        self.max_content = max_content
        self.byte_ticks = byte_ticks
        self._limits = length_limits(max_content)
        _WHOLE.setdefault(max_content, {})
        self.reset()

    def reset(self) -> None:
        """Forget everything: partial Header, frame in progress, pending garbage, ``last_tick``."""
        self.in_frame = False
        self.first: int | None = None
        self.last_tick: int | None = None
        self._pos = 0  # hunting: Header bytes matched (0-2); in frame: offset of the next byte
        self._hdr_t = 0  # tick of the (tentative) first Header byte
        self._raw = bytearray()
        self._src: int | None = None
        self._len: int | None = None
        self._partial = 0
        self._g_count = 0
        self._g_first = 0
        self._g_last = 0

    @property
    def buffered(self) -> int:
        """Bytes held and not yet reported: a partial Header, or the frame in progress."""
        return self._pos

    @property
    def header_since(self) -> int | None:
        """Tick at which the first byte of a Header being received ended (a partial Header of
        one or two bytes, or a frame in progress), else None. Its start bit began one byte
        time earlier: the MAC's miss rule asks whether a Header had *begun* by E + Tmax."""
        return self._hdr_t if self._pos else None

    # ---------------------------------------------------------------- internals

    def _garbage(self, count: int, first: int, last: int) -> None:
        if not self._g_count:
            self._g_first = first
        self._g_count += count
        self._g_last = last

    def _emit_garbage(self, out: list) -> None:
        if self._g_count:
            out.append(Garbage(self._g_count, self._g_first, self._g_last))
            self._g_count = 0

    def _fail(self, b: int, t: int, out: list) -> None:
        """Byte ``b`` at tick ``t`` broke the frame in progress: report, then hunt from ``b``."""
        pos = self._pos
        length = self._len
        err = frame_byte_error(
            pos, b, length=length, partial_length=self._partial, max_content=self.max_content
        )
        first = self.first
        assert first is not None                      # a frame is in progress
        expected = None if length is None else first + (13 + length) * self.byte_ticks
        out.append(FrameFailed(err, first, t, self._src, length, expected))
        self.in_frame = False
        self.first = None
        if b == _H0:
            self._hdr_t = t
            self._pos = 1
        else:
            self._pos = 0
            self._garbage(1, t, t)

    def _step(self, b: int, t: int, out: list) -> None:
        pos = self._pos
        if pos < 3:  # hunting for 0F 0A 05
            if b == HEADER[pos]:
                if pos == 0:
                    self._hdr_t = t
                elif pos == 2:
                    self._emit_garbage(out)
                    self.in_frame = True
                    self.first = self._hdr_t
                    raw = self._raw
                    raw.clear()
                    raw += HEADER
                    self._src = None
                    self._len = None
                    self._partial = 0
                self._pos = pos + 1
            else:
                if pos:  # the partial Header was garbage after all
                    assert self.last_tick is not None     # its bytes came before this one
                    self._garbage(pos, self._hdr_t, self.last_tick)
                if b == _H0:  # ... and this byte may start a new one
                    self._hdr_t = t
                    self._pos = 1
                else:
                    self._pos = 0
                    self._garbage(1, t, t)
            self.last_tick = t
            return

        self.last_tick = t
        if pos >= CONTENT_OFFSET:
            # past the Length field, so _len is set (a check here would cost every byte)
            stop = CONTENT_OFFSET + self._len  # type: ignore[operator]
            if pos < stop:
                if 0x20 <= b <= 0x7E:
                    self._raw.append(b)
                    self._pos = pos + 1
                    return
            elif pos == stop:
                if b == _E0:
                    self._raw.append(b)
                    self._pos = pos + 1
                    return
            elif b == _E1:
                self._raw.append(b)
                self._complete(t, out)
                return
        elif pos >= 8:  # Length digits
            if 0x30 <= b <= 0x39:
                partial = self._partial * 10 + b - 0x30
                self._partial = partial
                if partial <= self._limits[pos - 8]:
                    self._raw.append(b)
                    pos += 1
                    if pos == CONTENT_OFFSET:
                        self._len = partial
                    self._pos = pos
                    return
        elif 0x30 <= b <= (0x36 if pos == 4 else 0x39):
            if pos == 4:
                self._src = b - 0x30
            self._raw.append(b)
            self._pos = pos + 1
            return
        self._fail(b, t, out)

    def _all_but_last(self, data: bytes, t0: int, end: int) -> bool:
        """The second fast door: nothing held, and ``data`` is a known good frame (as
        :meth:`known_frame` knows them) but its last byte, as a receiver on a CPU model gets
        it (the End byte's handler runs apart: firmware_model/mcu/uart.py). Takes the bytes
        as :meth:`_step` would, one by one (the frame in progress, nothing reported; the first
        completed at tick ``t0``, the last at ``end``) and returns True; else changes nothing
        and returns False."""
        if self._pos or self._g_count:
            return False
        whole = data + _E1_BYTE
        frame = _WHOLE[self.max_content].get(whole) or built_frame(whole, self.max_content)
        if frame is None:
            return False
        self.in_frame = True
        self.first = self._hdr_t = t0
        self._raw = bytearray(data)
        self._pos = len(data)
        self._src = frame.src
        self._len = self._partial = len(frame.content)
        self.last_tick = end
        return True

    def _fixed(self, data: bytes, i: int, t0: int, dt: int, out: list) -> int:
        """In a Header (a whole one at ``i`` if ``_pos`` is 0) or a frame's fixed fields: take
        every byte from ``i`` up to the Content (or the chunk's end) at once, if that completes
        the Header and every byte is one :meth:`_step` accepts (Header, digits, Source '0'-'6',
        the Length's value within ``_limits``), leaving the state (and the garbage flushed at
        the Header) that stepping each would leave. Returns the next index, or ``i`` with
        nothing changed (a bad byte, fewer than 2 bytes): then :meth:`_step` reports it."""
        pos = self._pos
        m = len(data) - i
        if m > CONTENT_OFFSET - pos:
            m = CONTENT_OFFSET - pos
        stop = pos + m
        if m < 2 or stop < 3:
            return i
        run = data[i:i + m]
        d = 3 - pos if pos < 3 else 0                 # run[d:] are digit fields
        if (d and run[:d] != HEADER[pos:]) or (stop > 3 and not run[d:].isdigit()) \
                or (pos <= 4 < stop and run[4 - pos] > 0x36):
            return i
        if stop > 8:
            # all Length prefixes are within their limits iff the last is (limits[k + 1] is at
            # most 10 * limits[k] + 9: length_limits), so one check does
            digits = run[8 - pos:] if pos < 8 else run
            partial = (self._partial if pos > 8 else 0) * 10 ** len(digits) + int(digits)
            if partial > self._limits[stop - 9]:
                return i
        if d:
            if not pos:
                self._hdr_t = t0 + i * dt
            self._emit_garbage(out)
            self.in_frame = True
            self.first = self._hdr_t
            raw = self._raw
            raw.clear()
            raw += HEADER[:pos]
            raw += run
            self._src = self._len = None
            self._partial = 0
        else:
            self._raw += run
        if pos <= 4 < stop:
            self._src = run[4 - pos] - 0x30
        if stop > 8:
            self._partial = partial
            if stop == CONTENT_OFFSET:
                self._len = partial
        self._pos = stop
        self.last_tick = t0 + (i + m - 1) * dt
        return i + m

    def _advance(self, data: bytes, i: int, t0: int, dt: int, out: list) -> int:
        """Take ``data[i]`` as :meth:`_step` does (byte ``j`` completed at ``t0 + j*dt``), or
        several bytes at once, as :meth:`_step` would take each, without a call a byte: in a
        Header or the fixed fields, those up to the Content if all are good (:meth:`_fixed`);
        in a frame's Content, every byte up to the Content's end if all are printable. Returns
        the index of the next byte."""
        pos = self._pos
        if pos < CONTENT_OFFSET:
            if pos < CONTENT_OFFSET - 1 and len(data) - i > 1:
                k = self._fixed(data, i, t0, dt, out)
                if k != i:
                    return k
        else:
            m = CONTENT_OFFSET + self._len - pos        # type: ignore[operator]
            if m > len(data) - i:
                m = len(data) - i
            if m > 1:
                run = data[i:i + m]
                if not run.translate(None, _PRINTABLE):
                    self._raw += run
                    self._pos = pos + m
                    self.last_tick = t0 + (i + m - 1) * dt
                    return i + m
        self._step(data[i], t0 + i * dt, out)
        return i + 1

    def _clean(self) -> None:
        """Forget the last frame's Header tick, bytes, Source and Length: a frame taken
        whole (:meth:`known_frame`) and one fed byte by byte leave the same state."""
        self._hdr_t = 0
        self._raw.clear()
        self._src = self._len = None
        self._partial = 0

    def _complete(self, t: int, out: list) -> None:
        raw = bytes(self._raw)
        first = self.first
        assert first is not None                      # the frame now complete
        self.in_frame = False
        self.first = None
        self._pos = 0
        src, length = self._src, self._len
        self._clean()
        try:
            frame = parse_frame_cached(raw, self.max_content)
        except FrameError as err:  # pragma: no cover - every byte was checked already
            out.append(FrameFailed(err, first, t, src, length, t))
            return
        out.append(FrameReceived(frame, first, t))

    # ---------------------------------------------------------------- public API

    def feed_byte(self, b: int, t: int) -> list[DeframerEvent]:
        """One byte that completed at tick ``t``. Never raises on any byte value 0-255.

        Pending garbage is not flushed here (see :meth:`flush`).
        """
        out: list[DeframerEvent] = []
        self._step(b & 0xFF, t, out)
        return out

    def flush(self) -> list[DeframerEvent]:
        """Report the pending garbage run, if any (a partial Header stays pending)."""
        out: list[DeframerEvent] = []
        self._emit_garbage(out)
        return out

    def known_frame(self, data: bytes, end: int) -> Frame | None:
        """The fast door for a receiver that gets whole transmissions: if nothing is held (no
        partial Header, no garbage pending) and ``data`` is a byte string already known to be
        exactly one good frame, take it (``last_tick`` becomes ``end``, the tick of its last
        byte) and return the frame; else return None and change nothing (then :meth:`feed`
        the bytes). Same outcome as a :meth:`feed` that reports one :class:`FrameReceived`."""
        if self._pos or self._g_count:
            return None
        whole = _WHOLE[self.max_content]
        frame = whole.get(data)
        if frame is None:
            # Bytes a sender of this process built are one good frame if their Length fits.
            frame = built_frame(data, self.max_content)
            if frame is None:
                return None
            if len(whole) >= _WHOLE_MAX:
                whole.clear()
            whole[data] = frame
        if self._hdr_t or self._raw:
            self._clean()
        self.last_tick = end
        return frame

    def quiet_for(self, data: bytes) -> bool:
        """True if feeding all but the last byte of ``data``, in any chunks, reports nothing:
        nothing is held (no partial Header, no garbage pending) and ``data`` is exactly one
        good frame for this receiver (its Length fits). Changes nothing."""
        if self._pos or self._g_count:
            return False
        return data in _WHOLE[self.max_content] or \
            built_frame(data, self.max_content) is not None

    def feed(self, data: bytes, t0: int, dt: int) -> list[DeframerEvent]:
        """Bytes ``data``, byte i completed at tick ``t0 + i*dt``; garbage is flushed at the end.

        Same events as :meth:`feed_byte` on each byte followed by :meth:`flush`. Fast path:
        while hunting, ``bytes.find`` locates the Header and a complete frame in the chunk is
        parsed in one go by :func:`parse_frame_cached`; anything else goes through
        :meth:`_advance`, in runs of good bytes where it can, else byte by byte.
        """
        if not isinstance(data, bytes):
            data = bytes(data)
        n = len(data)
        # Fastest path: the chunk is exactly one frame already seen (the simulator hands every
        # receiver the same bytes; heartbeats repeat). Same events as the long way.
        end = t0 + (n - 1) * dt
        frame = self.known_frame(data, end)
        if frame is not None:
            return [FrameReceived(frame, t0, end)]
        if n > CONTENT_OFFSET and data[-1] == _E0 and self._all_but_last(data, t0, end):
            return []
        clean = not self._pos and not self._g_count
        out: list[DeframerEvent] = []
        i = 0
        step = self._step
        advance = self._advance
        find = data.find
        max_content = self.max_content
        while i < n:
            if self._pos:
                i = advance(data, i, t0, dt, out)
                continue
            j = find(HEADER, i)
            if j < 0:
                # No Header in data[i:]: all of it is garbage except possibly a partial Header
                # in the last two bytes, which the state machine sorts out.
                k = n - 2
                if k > i:
                    self._garbage(k - i, t0 + i * dt, t0 + (k - 1) * dt)
                    i = k
                while i < n:
                    step(data[i], t0 + i * dt, out)
                    i += 1
                break
            if j > i:
                self._garbage(j - i, t0 + i * dt, t0 + (j - 1) * dt)
                i = j
            c = j + CONTENT_OFFSET
            if c <= n:
                digits = data[j + 8 : c]
                if digits.isdigit():
                    length = int(digits)
                    e = c + length + 2
                    if length <= max_content and e <= n:
                        try:
                            frame = parse_frame_cached(data[j:e], max_content)
                        except FrameError:
                            frame = None
                        if frame is not None:
                            self._emit_garbage(out)
                            out.append(FrameReceived(frame, t0 + j * dt, t0 + (e - 1) * dt))
                            i = e
                            continue
            # Slow path: by runs or bytes until the machine is hunting with nothing held again.
            while i < n:
                i = advance(data, i, t0, dt, out)
                if not self._pos:
                    break
        if n:
            self.last_tick = t0 + (n - 1) * dt
        self._emit_garbage(out)
        if clean and len(out) == 1 and not self._pos and type(out[0]) is FrameReceived \
                and out[0].first == t0 and out[0].end == self.last_tick:
            whole = _WHOLE[self.max_content]
            if len(whole) >= _WHOLE_MAX:
                whole.clear()
            whole[data] = out[0].frame
        return out

    def abort(self, now: int) -> FrameFailed | None:
        """Abandon the frame in progress (the sender went quiet mid-frame); error field 'stall'.

        Returns None when no frame is in progress; a partial Header is then turned into pending
        garbage.
        """
        pos = self._pos
        if not self.in_frame:
            if pos:
                assert self.last_tick is not None     # the partial Header's bytes came
                self._garbage(pos, self._hdr_t, self.last_tick)
                self._pos = 0
            return None
        length = self._len
        total = f" of {CONTENT_OFFSET + 2 + length}" if length is not None else ""
        err = FrameError(
            f"sender went quiet after {pos}{total} bytes (frame aborted at tick {now})",
            field="stall",
            offset=pos,
        )
        first = self.first
        assert first is not None                      # in_frame
        expected = None if length is None else first + (13 + length) * self.byte_ticks
        ev = FrameFailed(err, first, now, self._src, length, expected)
        self.in_frame = False
        self.first = None
        self._pos = 0
        return ev

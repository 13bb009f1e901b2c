"""Errors raised for bad bytes on the radio wire (docs/protocol.md §3.2).

Every error says where it went wrong: ``offset`` is the byte offset in the frame (FrameError) or
in the Content (ContentError), ``field`` names the field, ``byte`` is the offending byte value when
there is one. The message repeats all of it, e.g.
``byte 4 (source): 0x39 '9' is not a robot ID '0'-'6'``.
"""
from __future__ import annotations

__all__ = ["WireError", "FrameError", "ContentError", "describe_byte"]


def describe_byte(b: int) -> str:
    """``0x39 '9'`` for a printable ASCII byte, ``0x0f`` otherwise."""
    if 0x20 <= b <= 0x7E:
        return f"0x{b:02x} {chr(b)!r}"
    return f"0x{b:02x}"


def _rebuild(cls: type, reason: str, field: str, offset: int | None, byte: int | None) -> WireError:
    return cls(reason, field=field, offset=offset, byte=byte)


class WireError(ValueError):
    """A frame or Content that breaks the wire format.

    ``reason`` is the human text without the location prefix; ``str(err)`` adds
    ``"<where> <offset> (<field>): "`` in front. Errors compare equal when type, reason, field,
    offset and byte are equal (so deframer events holding them can be compared in tests).
    """

    where = "byte"
    """Word used in front of the offset in the message."""

    def __init__(
        self,
        reason: str,
        *,
        field: str,
        offset: int | None = None,
        byte: int | None = None,
    ) -> None:
        self.reason = reason
        self.field = field
        self.offset = offset
        self.byte = byte
        if offset is None:
            message = f"{field}: {reason}"
        else:
            message = f"{self.where} {offset} ({field}): {reason}"
        super().__init__(message)

    def __reduce__(self):  # keyword-only constructor: pickle through a helper
        return (_rebuild, (type(self), self.reason, self.field, self.offset, self.byte))

    def _key(self) -> tuple:
        return (type(self), self.reason, self.field, self.offset, self.byte)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, WireError):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())


class FrameError(WireError):
    """Bad frame: ``offset`` counts from the first Header byte (0) (docs/protocol.md §3.1)."""


class ContentError(WireError):
    """Bad Content: ``offset`` counts from the first Content byte (0) (docs/protocol.md §3.3)."""

    where = "content byte"

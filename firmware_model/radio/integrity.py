"""Opt-in frame checksum that stays inside the paper's frame (docs/protocol.md §3.4, clause 20;
designed here).

With the extension on, the sender ends Content with ``crc(NNNNN)``: CRC-16/CCITT-FALSE
(polynomial 0x1021, initial 0xFFFF, no reflection, no final XOR; ``binascii.crc_hqx``) over the
frame from Destination through the last Content byte before ``crc(``, as five decimal digits.
Length counts the ``crc(...)`` command, so the checksum also covers the Length digits. A
receiver with the extension on refuses a frame whose checksum is missing or wrong. Off by
default: a bench against paper-format radios still interoperates.

Check value: CRC-16/CCITT-FALSE of b"123456789" is 0x29B1 (10673).
"""
from __future__ import annotations

from binascii import crc_hqx
from functools import lru_cache

from .frame import CONTENT_OFFSET, Frame

CRC_TEXT_LEN = len(b"crc(00000)")
"""Bytes the checksum command adds to Content."""

_HEAD = 3   # the CRC starts at Destination, after the 3 Header bytes


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of ``data``."""
    return crc_hqx(data, 0xFFFF)


def seal(dst: int, src: int, num: int, type: int, body: bytes) -> Frame:
    """The frame carrying ``body`` followed by its checksum command."""
    n = len(body) + CRC_TEXT_LEN
    covered = b"%d%d%02d%d%04d" % (dst, src, num, type, n) + body
    return Frame(dst=dst, src=src, num=num, type=type,
                 content=body + b"crc(%05d)" % crc16(covered))


@lru_cache(maxsize=1024)
def check(frame: Frame) -> bool:
    """True when ``frame`` ends with a ``crc(NNNNN)`` matching its bytes (memoised: every
    receiver of a transmission checks the same frame)."""
    c = frame.content
    if len(c) < CRC_TEXT_LEN or c[-CRC_TEXT_LEN:-6] != b"crc(" or c[-1:] != b")":
        return False
    digits = c[-6:-1]
    if not digits.isdigit():
        return False
    data = frame.encode()
    covered = data[_HEAD:CONTENT_OFFSET + len(c) - CRC_TEXT_LEN]
    return crc16(covered) == int(digits)


def strip(content: bytes) -> bytes:
    """Content without its trailing checksum command."""
    return content[:-CRC_TEXT_LEN]

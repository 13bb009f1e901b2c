"""The opt-in authenticated profile (docs/protocol.md §4.11, clauses 52-54; designed here, in
the spirit of AUTOSAR SecOC for CAN).

With the profile on, every frame a station sends ends its Content with
``auth(FFFFFFFF,TTTTTTTT)``: FFFFFFFF the sender's freshness value (a per-sender counter, eight
lowercase hex digits, one more for every frame it sends, kept across its reboots), TTTTTTTT
the first 4 bytes of HMAC-SHA256 (RFC 2104, FIPS 180-4) under the ring's pre-shared key, in
lowercase hex, over the frame's bytes from Destination up to and including the ``,`` after
the freshness (so over Length, every Content byte before ``auth(`` and the freshness).
Length counts the ``auth(...)`` command. A receiver refuses a frame whose tag is missing or
wrong (*forged*) and one whose freshness is not greater than the last it accepted from that
Source (*replayed*).

The tag is the command's last 9 bytes before the End: a receiver that hashes the bytes as
they come has the tag, the ``)`` and the End (11 bytes, 11.4 ms) to finish the last two
SHA-256 blocks, and a sender knows every covered byte when it builds the frame.

The PC side uses the standard library's ``hmac`` and ``hashlib``: no crypto is written here.
"""
from __future__ import annotations

import datetime
import hmac
import re
from dataclasses import dataclass
from functools import lru_cache
from hashlib import sha256
from pathlib import Path

from .frame import CONTENT_OFFSET, Frame

KEY_BYTES = 16
"""A ring key is 128 bits."""
FRESH_DIGITS = 8
TAG_DIGITS = 8
AUTH_TEXT_LEN = len(b"auth(") + FRESH_DIGITS + 1 + TAG_DIGITS + 1
"""Bytes the command adds to Content: 23."""
FRESH_MAX = 16 ** FRESH_DIGITS - 1
_HEAD = 3                        # the tag covers from Destination, after the 3 Header bytes
_TAIL = TAG_DIGITS + 1           # the tag and ")" are not covered
_HEX = frozenset(b"0123456789abcdef")
SHA256_BLOCK = 64

CLOCK_EPOCH = 1_767_225_600
"""2026-01-01 00:00 UTC: a station with no flash (a PC) seeds its freshness counter from its
clock, ``CLOCK_RATE`` a second since its key's epoch (clause 52), this instant unless the key
file gives another (``epoch = YYYY-MM-DD``, clause 54)."""
CLOCK_RATE = 32
"""Freshness values a second of a clock-seeded counter: more than the frames any station can
send in a second (a lone member, the fastest, sends one every 55 ms or more), so a restarted
PC always starts above every value it sent before."""


KEY_FILE_MAX = 64 * 1024
"""Bytes a key file may hold at most (a key line and comments): a longer one, or a device
that never ends (``/dev/zero``), is refused, not read into memory."""


class KeyFileError(ValueError):
    """A key file that cannot be used: one line saying which file and what is wrong."""


class FreshnessExhausted(RuntimeError):
    """A station can give no fresh value under its key: its counter passed ``ffffffff`` (a
    value would repeat: the ring key must be rotated, clause 54), or, a PC, its clock is
    before the key's epoch (its clock-seeded values would start again at 0 every time it
    starts, clause 52)."""


@dataclass(frozen=True)
class RingKey:
    """The ring's pre-shared key (16 bytes) and the inner and outer HMAC states it gives;
    ``epoch``: the instant (Unix seconds, a UTC midnight) from which a PC's clock-seeded
    freshness counter counts under this key (clause 54's ``epoch =`` line; if none,
    2026-01-01 00:00 UTC)."""

    key: bytes
    epoch: int = CLOCK_EPOCH

    def __post_init__(self) -> None:
        if len(self.key) != KEY_BYTES:
            raise ValueError(f"a ring key is {KEY_BYTES} bytes, got {len(self.key)}")

    def tag(self, covered: bytes) -> bytes:
        """The 8 lowercase hex digits of the truncated HMAC-SHA256 of ``covered``."""
        return hmac.new(self.key, covered, sha256).hexdigest()[:TAG_DIGITS].encode()

    def __repr__(self) -> str:          # never print a key
        return "RingKey(<16 bytes>)"


_KEY_LINE = re.compile(r"key[ \t]*=[ \t]*([0-9A-Fa-f]{32})\Z")
_EPOCH_LINE = re.compile(r"epoch[ \t]*=[ \t]*([0-9]{4}-[0-9]{2}-[0-9]{2})\Z")


def load_key(path: str | Path) -> RingKey:
    """The ring key from a key file (clause 54): lines ``#`` comments or blank, and exactly one
    line ``key = `` followed by 32 hex digits. Raises KeyFileError with one line."""
    p = Path(path)
    try:
        with p.open("rb") as fh:
            raw = fh.read(KEY_FILE_MAX + 1)
        if len(raw) > KEY_FILE_MAX:
            raise KeyFileError(f"key file {p}: longer than {KEY_FILE_MAX} bytes: not a key "
                               f"file")
        text = raw.decode("ascii")      # (no newline translation: clause 54's)
    except FileNotFoundError:
        raise KeyFileError(f"key file {p}: no such file") from None
    except IsADirectoryError:
        raise KeyFileError(f"key file {p}: is a directory") from None
    except UnicodeDecodeError:
        raise KeyFileError(f"key file {p}: not ASCII text") from None
    except OSError as exc:
        raise KeyFileError(f"key file {p}: cannot read it ({exc.strerror or exc})") from None
    keys = []
    epochs = []
    # exactly clause 54: lines end with LF or CRLF (no other line break), stripped of spaces
    # and tabs only
    for n, line in enumerate(text.split("\n"), 1):
        s = line.removesuffix("\r").strip(" \t")
        if not s or s.startswith("#"):
            continue
        m = _KEY_LINE.match(s)
        if m is not None:
            keys.append(bytes.fromhex(m.group(1)))
            continue
        e = _EPOCH_LINE.match(s)
        if e is None:
            raise KeyFileError(f"key file {p}, line {n}: expected 'key = ' and 32 hex digits "
                               f"(a 128-bit key), 'epoch = YYYY-MM-DD', or a # comment")
        try:
            day = datetime.date.fromisoformat(e.group(1))
        except ValueError:
            raise KeyFileError(f"key file {p}, line {n}: epoch {e.group(1)} is no date") \
                from None
        epochs.append(int(datetime.datetime(day.year, day.month, day.day,
                                            tzinfo=datetime.timezone.utc).timestamp()))
    if len(keys) != 1:
        raise KeyFileError(f"key file {p}: " + ("no 'key = ' line" if not keys else
                                                f"{len(keys)} 'key = ' lines, one expected"))
    if len(epochs) > 1:
        raise KeyFileError(f"key file {p}: {len(epochs)} 'epoch = ' lines, one at most")
    return RingKey(keys[0], epochs[0] if epochs else CLOCK_EPOCH)


def clock_freshness(unix_time: float, epoch: int = CLOCK_EPOCH) -> int:
    """The first freshness value of a station with no flash started at ``unix_time``, under
    a key whose epoch is ``epoch`` (clause 52). Raises FreshnessExhausted from
    ``epoch`` + 4.25 years on, when the values left would not last (the key is due for
    rotation, clause 54), and before ``epoch`` (the values would repeat at every start)."""
    if unix_time < epoch:
        day = datetime.datetime.fromtimestamp(epoch, datetime.timezone.utc).date()
        now = datetime.datetime.fromtimestamp(unix_time, datetime.timezone.utc)
        raise FreshnessExhausted(
            f"this PC's clock ({now:%Y-%m-%d %H:%M} UTC) is before the ring key's epoch "
            f"({day} 00:00 UTC): its freshness values would start at 0 again every time it "
            f"starts, and be refused as replayed; set the clock, or give the key file the "
            f"'epoch = ' line of a day that has begun in UTC (docs/protocol.md clauses 52, 54)")
    fresh = int((unix_time - epoch) * CLOCK_RATE)
    if fresh >= FRESH_MAX:
        day = datetime.datetime.fromtimestamp(epoch, datetime.timezone.utc).date()
        raise FreshnessExhausted(
            f"the ring key's freshness values ran out: a PC's counter counts {CLOCK_RATE} a "
            f"second from the key's epoch ({day}) and has passed ffffffff; rotate the key, "
            f"its file with a new 'epoch = ' line (docs/protocol.md clause 54)")
    return fresh


def seal(key: RingKey, dst: int, src: int, num: int, type: int, body: bytes,
         fresh: int) -> Frame:
    """The frame carrying ``body`` followed by ``auth(fresh,tag)``; FreshnessExhausted for
    a value past ``ffffffff`` (it would not fit its 8 digits, and the counter must not
    wrap: clause 52)."""
    if not 0 <= fresh <= FRESH_MAX:
        if fresh > FRESH_MAX:
            raise FreshnessExhausted(
                "the freshness counter passed ffffffff under this ring key: nothing more may "
                "be sent under it; rotate the key (docs/protocol.md clause 54)")
        raise ValueError(f"a freshness value is 0..{FRESH_MAX:x}, got {fresh}")
    n = len(body) + AUTH_TEXT_LEN
    covered = b"%d%d%02d%d%04d" % (dst, src, num, type, n) + body + b"auth(%08x," % fresh
    return Frame(dst=dst, src=src, num=num, type=type,
                 content=body + covered[-(FRESH_DIGITS + 6):] + key.tag(covered) + b")")


@lru_cache(maxsize=1024)
def _check(key: RingKey, frame: Frame) -> int | None:
    c = frame.content
    if len(c) < AUTH_TEXT_LEN or c[-1:] != b")":
        return None
    cmd = c[-AUTH_TEXT_LEN:]
    if cmd[:5] != b"auth(" or cmd[5 + FRESH_DIGITS] != 0x2C:
        return None
    fresh, tag = cmd[5:5 + FRESH_DIGITS], cmd[6 + FRESH_DIGITS:-1]
    if not (set(fresh) <= _HEX and set(tag) <= _HEX):
        return None
    data = frame.encode()
    covered = data[_HEAD:CONTENT_OFFSET + len(c) - _TAIL]
    if not hmac.compare_digest(key.tag(covered), tag):
        return None
    return int(fresh, 16)


def check(key: RingKey, frame: Frame) -> int | None:
    """The freshness value of ``frame`` if it ends with a well-formed ``auth(...)`` whose tag
    is right under ``key``, else None (memoised: every receiver checks the same frame)."""
    return _check(key, frame)


def strip(content: bytes) -> bytes:
    """Content without its trailing ``auth(...)`` command."""
    return content[:-AUTH_TEXT_LEN]


def sha256_blocks(covered_len: int) -> int:
    """SHA-256 compressions a receiver or sender runs for a tag over ``covered_len`` bytes,
    with the key's inner and outer padded blocks hashed once when the key is loaded: the
    message after the inner pad (padding: 1 byte 0x80 and the 8-byte length), then the outer
    hash of the 32-byte inner digest (one block)."""
    return (covered_len + 9 + SHA256_BLOCK - 1) // SHA256_BLOCK + 1


def covered_len(content_len: int) -> int:
    """Bytes a tag covers in a frame of ``content_len`` Content bytes (auth included)."""
    return CONTENT_OFFSET - _HEAD + content_len - _TAIL

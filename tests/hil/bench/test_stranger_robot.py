"""docs/protocol.md tested as a stranger would: a small robot written from the spec alone.

``StrangerRobot`` below knows nothing but docs/protocol.md: plain pyserial, no import from this
project (``test_the_robot_imports_nothing_from_the_project`` checks the whole file). It is a
*joiner* (docs/protocol.md §10): it never claims, so it needs a ring to exist. The harness starts
``rprs radio-hub`` and two ``rprs child`` processes (team {1, 2, 4}), waits for their ring, and
lets the stranger, robot 4, join it by answering an invitation (clause 34), ask child 1 for its
``status()``, get the acknowledgement (clause 47) and the reply, leave by falling silent and come
back with JOIN (clause 49). The children's ``--events`` say what they saw: the stranger admitted
by both, its message delivered once, its acknowledgement of the reply heard, no turn missed while
it was a member, three misses then a clean drop by both once it left, the ring going on without
it, and its JOIN taken as a rejoin by both. The scenario runs three times: plain, with the
checksum (clause 20) and with the authenticated profile (§4.11, clauses 52-54: the children run
``--auth-key`` and the stranger seals, checks and reads the key file from the clauses' words,
with ``hmac`` and ``hashlib`` from the standard library).
"""
from __future__ import annotations

import ast
import hashlib
import hmac
import json
import os
import re
import select
import subprocess
import sys
import threading
import time
from datetime import datetime, timezone
from pathlib import Path

import pytest
from paths import ROOT

serial = pytest.importorskip("serial")


# ==============================================================================================
# The stranger: docs/protocol.md and nothing else
# ==============================================================================================

# §2 and clause 5: a ring with a station on a PC uses the real-time margin set.
TTRANS = 0.005
TMAX = 0.600
TWIN = 0.050
TSLOT = 0.080
QUIET_GAP = 0.020
STALL_GAP = 0.020
MISS_LIMIT = 3
P_EVERY = 4                   # clause 32
A_ATTEMPTS = 4                # clause 46
ANNOUNCE_LIMIT = 6            # clause 36
BYTE = 10 / 9600              # clause 3: a PC at 9600 bit/s, 8N1
MAX_CONTENT_SENT = 561        # clause 14: a PC's frame fits in Tmax
MAX_LENGTH = 562              # clause 11
CRC_BYTES, AUTH_BYTES = 10, 23    # clauses 20, 52: what the seal adds to Content and Length
AUTH_EPOCH = datetime(2026, 1, 1, tzinfo=timezone.utc).timestamp()  # clause 52's clock rule

HEADER = b"\x0f\x0a\x05"      # clause 6
END = b"\x17\x19"
BROADCAST = 7                 # clause 7
BOOT, JOIN = 5, 6             # clause 10
APP = {"movex": "n", "movey": "n", "movez": "n", "moveto": "nnn", "joint": "in", "wheel": "n",
       "paw": "i", "act": "ii", "stop": "", "status": "", "fail": "i", "done": ""}  # clause 16
MAC = {"ack": "ii", "poll": "ii", "ring": "i", "crc": "i"}
BOUNDS = {("joint", 0): (1, 4), ("paw", 0): (0, 1), ("act", 0): (0, 99), ("act", 1): (0, 1),
          ("fail", 0): (0, 999), ("ack", 0): (0, 6), ("ack", 1): (0, 99), ("poll", 0): (0, 6),
          ("poll", 1): (0, 127), ("ring", 0): (0, 127), ("crc", 0): (0, 65535)}


class Unreadable(ValueError):
    """Content that does not match clause 16."""


def parse_content(text: str) -> list[tuple[str, tuple]]:
    """Clause 16: ``name(params)`` repeated, nothing between; numbers as the grammar says."""
    out, i = [], 0
    while i < len(text):
        j = text.find("(", i)
        k = text.find(")", j + 1) if j >= 0 else -1
        if j < 0 or k < 0:
            raise Unreadable(text)
        name, params = text[i:j], text[j + 1:k]
        kinds = APP.get(name, MAC.get(name))
        if kinds is None:
            raise Unreadable(f"unknown command {name!r}")
        values = params.split(",") if params else []
        if len(values) != len(kinds):
            raise Unreadable(f"{name} takes {len(kinds)} parameters")
        args = []
        for n, (v, kind) in enumerate(zip(values, kinds)):
            body = v[1:] if v.startswith("-") else v
            whole, dot, frac = body.partition(".")
            if len(v) > 12 or not whole.isdigit() or not whole.isascii() or \
                    (dot and (kind == "i" or not frac.isdigit() or len(frac) > 3)):
                raise Unreadable(f"bad number {v!r} in {name}")
            x = float(v) if dot else int(v)
            lo, hi = BOUNDS.get((name, n), (None, None))
            if lo is not None and not lo <= x <= hi:
                raise Unreadable(f"{name} parameter {n} out of bounds")
            args.append(x)
        out.append((name, tuple(args)))
        i = k + 1
    return out


def encode(dst: int, src: int, num: int, typ: int, content: str, checksum: bool = False,
           key: bytes | None = None, fresh: int = 0) -> bytes:
    """Clause 6, byte by byte; with ``checksum``, Content ends with ``crc(NNNNN)`` (clause 20);
    with ``key``, with ``auth(fresh,tag)`` (clause 52)."""
    c = content.encode("ascii")
    if key is not None:
        if checksum:
            raise ValueError("the profile and the checksum are never on together (clause 52)")
        body = b"%d%d%02d%d%04d" % (dst, src, num, typ, len(c) + AUTH_BYTES) + c \
            + b"auth(%08x," % fresh
        return HEADER + body + auth_tag(key, body) + b")" + END
    if not checksum:
        return HEADER + b"%d%d%02d%d%04d" % (dst, src, num, typ, len(c)) + c + END
    body = b"%d%d%02d%d%04d" % (dst, src, num, typ, len(c) + CRC_BYTES) + c
    return HEADER + body + b"crc(%05d)" % crc16(body) + END


def crc16(data: bytes) -> int:
    """Clause 20: CRC-16/CCITT-FALSE (polynomial 0x1021, initial 0xFFFF, no reflection, no
    final XOR)."""
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = (crc << 1) ^ 0x1021 if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc


def sealed(raw: bytes) -> bool:
    """Clause 20: the Content of the whole frame ``raw`` ends with the right ``crc(NNNNN)``."""
    tail = raw[-12:-2]
    return (tail[:4] == b"crc(" and tail[-1:] == b")" and tail[4:9].isdigit()
            and int(tail[4:9]) == crc16(raw[3:-12]))


def auth_tag(key: bytes, covered: bytes) -> bytes:
    """Clause 52: the first four bytes of HMAC-SHA256 of ``covered`` (Destination up to the
    ``,`` after the freshness value) under the key, as eight lowercase hex digits."""
    return hmac.new(key, covered, hashlib.sha256).digest()[:4].hex().encode("ascii")


AUTH_TAIL = re.compile(rb"auth\(([0-9a-f]{8}),([0-9a-f]{8})\)")      # clause 16's grammar


def authentic(raw: bytes, key: bytes) -> int | None:
    """Clause 53.1: the freshness value of the whole frame ``raw`` if its Content ends with
    ``auth(fresh,tag)`` of the grammar and the tag clause 52 gives; None if forged."""
    if int(raw[8:12]) < AUTH_BYTES:
        return None
    m = AUTH_TAIL.fullmatch(raw[-2 - AUTH_BYTES:-2])
    if m is None or not hmac.compare_digest(m[2], auth_tag(key, raw[3:-11])):
        return None
    return int(m[1], 16)


def clock_freshness(now: float | None = None) -> int:
    """Clause 52, a station without non-volatile memory: floor(32 x the seconds, with their
    fraction, since 2026-01-01 00:00 UTC)."""
    return int(32 * ((time.time() if now is None else now) - AUTH_EPOCH))


KEY_LINE = re.compile(r"key[ \t]*=[ \t]*([0-9A-Fa-f]{32})")


def read_key(path: str | os.PathLike) -> bytes:
    """Clause 54: ASCII; blank lines and lines beginning with ``#`` ignored; exactly one line
    ``key = `` and 32 hex digits, either case. Anything else: ValueError naming the file."""
    try:
        text = Path(path).read_bytes().decode("ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: unreadable key file: {exc}") from None
    keys = []
    for n, line in enumerate(text.splitlines(), 1):
        line = line.strip(" \t\r")          # clause 54: stripped of spaces and tabs
        if not line or line.startswith("#"):
            continue
        m = KEY_LINE.fullmatch(line)
        if m is None:
            raise ValueError(f"{path}: line {n} is neither blank, a comment nor 'key = ' "
                             "and 32 hex digits")
        keys.append(bytes.fromhex(m[1]))
    if len(keys) != 1:
        raise ValueError(f"{path}: {len(keys)} 'key = ' lines, not exactly one")
    return keys[0]


class Frame:
    __slots__ = ("dst", "src", "num", "type", "content", "began", "end", "raw")

    def __init__(self, raw: bytes, began: float, end: float) -> None:
        self.raw = raw
        self.dst, self.src = raw[3] - 48, raw[4] - 48
        self.num, self.type = int(raw[5:7]), raw[7] - 48
        self.content = raw[12:-2].decode("ascii")
        self.began, self.end = began, end     # clause 15.5: Header began; E

    def __repr__(self) -> str:
        return f"<{self.dst}{self.src}{self.num:02d}{self.type} {self.content!r}>"


class Receiver:
    """Clause 15: hunt, check each byte, the first bad byte starts a new hunt."""

    def __init__(self) -> None:
        self.buf = bytearray()
        self.first = 0.0               # arrival of the first Header byte
        self.last = None               # arrival of the last byte heard, any byte

    def feed(self, b: int, t: float, out: list) -> None:
        self.last = t
        buf, n = self.buf, len(self.buf)
        if n < 3:
            if b == HEADER[n]:
                if n == 0:
                    self.first = t
                buf.append(b)
            else:
                if n:
                    out.append(("garbage", t))
                buf.clear()
                if b == HEADER[0]:
                    self.first = t
                    buf.append(b)
                else:
                    out.append(("garbage", t))
            return
        ok = False
        if n in (3, 5, 6, 7):
            ok = 0x30 <= b <= 0x39
        elif n == 4:
            ok = 0x30 <= b <= 0x36
        elif n < 12:
            ok = 0x30 <= b <= 0x39 and int(bytes(buf[8:n]) + bytes([b]) + b"0" * (11 - n)) \
                <= MAX_LENGTH
        else:
            length = int(bytes(buf[8:12]))
            if n < 12 + length:
                ok = 0x20 <= b <= 0x7E
            else:
                ok = b == END[n - 12 - length]
        if not ok:
            out.append(("failed", t, buf[4] - 48 if n > 4 else None))
            buf.clear()
            self.feed(b, t, out)                  # the bad byte is a fresh hunting byte
            return
        buf.append(b)
        if n >= 12 and n + 1 == 14 + int(bytes(buf[8:12])):
            out.append(("frame", Frame(bytes(buf), self.first - BYTE, t)))
            buf.clear()

    def in_frame(self) -> bool:
        return len(self.buf) >= 3

    def header_began(self) -> float | None:
        """When a Header being received began (clause 15.4-5), else None."""
        if not self.buf or self.last is None:
            return None
        return self.first - BYTE


class StrangerRobot:
    """A station of docs/protocol.md, version 3.5, that joins rings: clauses 1-19a, 21-27,
    29-49 and 51, the jam case of clause 44 simplified (its stagger runs from the quiet
    closure), and with ``checksum`` clause 20 (every frame it sends sealed, a frame without
    the right seal a failed frame, clause 43); with ``key`` (read by ``read_key``, clause 54)
    the authenticated profile, clauses 52-53: every frame it sends carries ``auth(fresh,tag)``,
    its freshness from the clock (it has no non-volatile memory), and a forged or replayed
    frame is refused as a failed frame whose Source was not read. It reads ``done()``
    (version 3.0) and obeys no message (clause 19a: it has no submodule). Not 28 (it never
    claims: a joiner, §10), 48a (a report, not a rule of the wire) or 50 (it is no
    father)."""

    def __init__(self, port: str, robot: int, team: set[int], checksum: bool = False,
                 key: bytes | None = None) -> None:
        if checksum and key is not None:
            raise ValueError("the profile and the checksum are never on together (clause 52)")
        self.id, self.team, self.checksum, self.key = robot, set(team), checksum, key
        self.seal_bytes = AUTH_BYTES if key is not None else CRC_BYTES if checksum else 0
        self.fresh = clock_freshness()          # clause 52: our next frame's freshness value
        self.freshness: dict[int, int] = {}     # clause 53.2: last accepted, per Source
        self.refused: list[tuple[str, Frame]] = []
        self.port = serial.serial_for_url(port, 9600, bytesize=8, parity="N", stopbits=1,
                                          timeout=0, rtscts=False, xonxoff=False)
        self.port.reset_input_buffer()
        self.rx = Receiver()
        self.mode = "LISTEN"
        self.phase = None
        self.ring: list[int] = []
        self.owner = self.poller = None
        self.turn_start = 0.0
        self.deadline: float | None = None
        self.limit = 0.0               # E + Tmax (WAIT) or E + Twin (WINDOW): clauses 24, 33
        self.quiet_limit = 0.0         # QUIET ends by this at the latest (clause 41)
        self.misses: dict[int, int] = {}
        self.outsiders: dict[int, tuple[int, float]] = {}
        self.booted = False            # our BOOT has been acknowledged by every member
        self.answering = False
        self.announcing = None         # (Type, Number) of our BOOT/JOIN until acknowledged
        self.awaiting: set[int] = set()
        self.announced_frames = 0
        self.next_num = 1              # clause 45: messages from '01'
        self.last_sent_num = 0
        self.outbox: list[dict] = []
        self.inflight: dict | None = None
        self.acks_owed: list[tuple[int, int]] = []
        self.last_rx: dict[int, int] = {}
        self.booting_peers: set[int] = set()
        self.turns_since_poll = P_EVERY
        self.poll_ptr = 0
        self.sent_poll = None
        self.heard_since_tx = True
        self.silent = 0                # consecutive misses with no good frame heard (clause 40)
        self.tell_view = False         # our next frame carries ring(mask) (clause 51)
        self.left = False
        self.inbox: list[tuple[int, int, int, list]] = []     # (src, dst, num, app commands)
        self.outcomes: list[tuple[dict, bool, str]] = []
        self.heard: list[Frame] = []
        self.sent: list[tuple[float, bytes]] = []
        self.log: list[str] = []

    # -- the ring --------------------------------------------------------------------------

    def succ(self, r: int) -> int:
        later = [m for m in self.ring if m > r]
        return later[0] if later else self.ring[0]

    def gap(self) -> list[int]:
        """Team IDs strictly between us and our successor, cyclically, not in the ring."""
        nxt, out, i = self.succ(self.id), [], (self.id + 1) % 7
        while i != nxt and i != self.id:
            if i in self.team and i not in self.ring:
                out.append(i)
            i = (i + 1) % 7
        return out

    def next_turn(self, after: int, start: float, uncertain: bool = False) -> None:
        """Clauses 23, 26, 44: the turn after ``after`` begins at ``start``."""
        if not self.ring:
            return
        nxt = self.succ(after)
        if nxt == self.id and self.ring == [self.id]:      # clause 31: a lone member pauses
            self.phase, self.owner = "HOLD", self.id
            self.deadline = start + TWIN + self.id * TSLOT
        elif nxt == self.id:
            self.phase, self.owner = "HOLD", self.id
            self.deadline = start + (self.id * TSLOT if uncertain else 0.0)
        else:
            self.phase, self.owner, self.turn_start = "WAIT", nxt, start
            self.deadline = self.limit = start + TMAX

    def miss(self, robot: int) -> None:
        """Clauses 24, 25."""
        self.misses[robot] = self.misses.get(robot, 0) + 1
        self.silent += 1
        self.tell_view = True                              # clause 51.1
        self.log.append(f"miss {robot} ({self.misses[robot]})")
        if self.misses[robot] >= MISS_LIMIT:
            self.drop(robot)

    def drop(self, robot: int) -> None:
        self.ring.remove(robot)
        self.misses.pop(robot, None)
        self.tell_view = True                              # clause 51.1
        self.log.append(f"dropped {robot}")
        self.awaiting.discard(robot)
        m = self.inflight
        if m is not None and robot in m["awaiting"]:
            m["awaiting"].discard(robot)
            if m["dst"] == robot or not m["awaiting"]:
                self.finish(m, m["dst"] == BROADCAST and bool(m["acked"]), "dropped")

    def to_listen(self, why: str) -> None:
        self.log.append(f"LISTEN: {why}")
        self.mode, self.phase, self.ring, self.deadline = "LISTEN", None, [], None
        self.announcing, self.acks_owed = None, []

    def finish(self, m: dict, delivered: bool, why: str) -> None:
        self.inflight = None
        self.outcomes.append((m, delivered, why))

    # -- what arrives ----------------------------------------------------------------------

    def on_frame(self, f: Frame) -> None:
        self.heard.append(f)
        if self.left:
            return
        self.heard_since_tx = True
        self.silent = 0
        if self.mode == "MEMBER" and self.ring == [self.id] and not (
                self.phase == "WINDOW" and f.src == self.owner and f.type in (BOOT, JOIN)):
            self.to_listen(f"heard robot {f.src} while alone")          # clause 31
        try:
            cmds = parse_content(f.content)
            unreadable = False
        except Unreadable:
            cmds, unreadable = [], True
        polls = [a for n, a in cmds if n == "poll"]
        if self.mode == "LISTEN":                                   # clause 34
            for k, mask in polls:
                if k == self.id:
                    self.mode = "MEMBER"
                    self.ring = sorted({i for i in range(7) if mask >> i & 1} | {f.src, self.id})
                    self.misses = {r: 0 for r in self.ring}
                    self.answering = True
                    self.log.append(f"invited by {f.src}, ring {self.ring}")
                    self.phase, self.owner, self.deadline = "HOLD", self.id, f.end
                    return
            return
        if f.src == self.id:                                        # clause 38.2
            return
        if f.src not in self.team:                                  # clause 38.1
            self.failed(f.src, known_end=f.end)
            return
        answering = self.phase == "WINDOW" and f.src == self.owner and f.type in (BOOT, JOIN)
        if f.src not in self.ring:
            if answering:                                           # clause 35
                self.ring = sorted(self.ring + [f.src])
                self.misses[f.src] = 0
                self.log.append(f"admitted {f.src}")
            elif any(mask == 1 << f.src for _, mask in polls):      # clause 38.4
                self.next_turn(f.src, f.end)
                return
            else:                                                   # clause 38.3
                n, last = self.outsiders.get(f.src, (0, f.end))
                n = 1 if f.end - last > (len(self.ring) + 1) * TMAX else n + 1
                if n >= MISS_LIMIT:
                    self.outsiders.pop(f.src, None)
                    self.ring = sorted(self.ring + [f.src])
                    self.misses[f.src] = 0
                else:
                    self.outsiders[f.src] = (n, f.end)
                self.next_turn(f.src, f.end)
                return
        elif self.phase in ("WAIT", "WINDOW") and f.src != self.owner and not answering:
            if any(mask == 1 << f.src for _, mask in polls):        # clauses 38.4, 39
                self.next_turn(f.src, f.end)
                return
            if not self.takeover(f):                                # clause 39
                self.misses[f.src] = 0
                self.tell_view = True                               # clause 51.1
                if self.phase == "WAIT" and self.owner in self.ring:
                    self.miss(self.owner)
                self.next_turn(f.src, f.end)
                return
        self.misses[f.src] = 0
        for _k, mask in polls:                                      # clause 37
            if mask != 1 << f.src and not mask >> self.id & 1:
                self.to_listen(f"left out of {f.src}'s ring")
                return self.on_frame_again(f)
        for name, args in cmds:                                     # clause 51.3
            if name == "ring":
                view = {i for i in range(7) if args[0] >> i & 1}
                if self.id not in view:
                    self.to_listen(f"left out of {f.src}'s ring")
                    return self.on_frame_again(f)
                for r in sorted(view - set(self.ring)):
                    if r in self.team:
                        self.ring = sorted(self.ring + [r])
                        self.misses[r] = 0
                        self.log.append(f"admitted {r} ({f.src}'s ring)")
                for r in sorted(set(self.ring) - view - {self.id, f.src}):
                    if self.misses.get(r, 0) > 0:
                        self.drop(r)
                if set(self.ring) != view:
                    self.tell_view = True
                break
        if f.type in (BOOT, JOIN):                                  # clause 36
            self.acks_owed.append((f.src, f.num))
            if f.type == BOOT and f.src not in self.booting_peers:  # clause 30
                self.booting_peers.add(f.src)
                self.last_rx[f.src] = f.num
                m = self.inflight
                if m is not None and m["dst"] == f.src and m["attempts"]:
                    self.finish(m, False, f"robot {f.src} restarted")
        else:
            self.booting_peers.discard(f.src)
        if not unreadable:                                          # clause 43
            for name, args in cmds:
                if name == "ack" and args[0] == self.id:
                    self.on_ack(f.src, args[1])
            app = [(n, a) for n, a in cmds if n in APP]           # clause 19
            if app:                                                 # clauses 47, 48
                fresh = self.last_rx.get(f.src) != f.num
                self.last_rx[f.src] = f.num
                if f.dst in (self.id, BROADCAST):
                    self.acks_owed.append((f.src, f.num))
                    if fresh:
                        self.inbox.append((f.src, f.dst, f.num, app))
        invited = [k for k, _ in polls if k not in self.ring]
        if invited:                                                 # clause 33
            self.phase, self.owner, self.poller = "WINDOW", invited[0], f.src
            self.turn_start = f.end
            self.deadline = self.limit = f.end + TWIN
        else:
            self.next_turn(f.src, f.end)

    def on_frame_again(self, f: Frame) -> None:
        """After going to LISTEN on a frame, the same frame may invite us (clause 37)."""
        self.heard.pop()
        self.on_frame(f)

    def takeover(self, f: Frame) -> bool:
        """Clause 39: a takeover seen with a slower clock?"""
        elapsed = f.began - self.turn_start
        if self.phase == "WINDOW":
            return f.src == self.succ(self.poller) and elapsed >= 0.95 * (TWIN + TTRANS)
        skipped, o = [], self.owner
        while o != f.src and len(skipped) <= len(self.ring):
            skipped.append(o)
            o = self.succ(o)
        if o != f.src or self.id in skipped or elapsed < 0.95 * len(skipped) * TMAX:
            return False
        for r in skipped:
            self.miss(r)
        return True

    def on_ack(self, src: int, num: int) -> None:
        if self.announcing is not None and num == self.announcing[1]:    # clause 36
            self.awaiting.discard(src)
            if not self.awaiting:
                self.announcing, self.booted = None, True
            return
        m = self.inflight
        if m is not None and m["num"] == num and src in m["awaiting"]:    # clause 46
            m["awaiting"].discard(src)
            m["acked"].add(src)
            if not m["awaiting"]:
                self.finish(m, True, "")

    def failed(self, src: int | None, known_end: float | None = None) -> None:
        """Clauses 41-43: a broken frame used its turn; the closure is uncertain."""
        if self.mode != "MEMBER" or self.left or self.phase not in ("WAIT", "WINDOW", "QUIET"):
            return
        after = src if src in self.ring else self.owner
        self.tell_view = True                              # clause 51.1
        if known_end is not None:
            self.next_turn(after, known_end, uncertain=True)
        else:
            self.phase, self.owner = "QUIET", after
            self.quiet_limit = self.rx.first + TMAX
            self.deadline = time.monotonic() + QUIET_GAP

    # -- timers ----------------------------------------------------------------------------

    def on_deadline(self, now: float) -> None:
        began = self.rx.header_began()
        if began is not None and now - self.rx.last > STALL_GAP:
            began = None                                   # clause 15.4: no Header after all
        if self.phase == "WAIT":                           # clause 24
            if began is not None and began <= self.limit:
                self.deadline = now + BYTE
                return
            o = self.owner
            self.miss(o)
            if len(self.ring) >= 2 and self.silent >= max(MISS_LIMIT, len(self.ring) - 1):
                self.to_listen("heard nobody for a whole round")          # clause 40
                return
            self.next_turn(o, self.limit, uncertain=not self.heard_since_tx)
        elif self.phase == "WINDOW":                       # clause 33
            if began is not None and began <= self.limit:
                self.deadline = now + BYTE
                return
            self.next_turn(self.poller, self.limit)
        elif self.phase == "QUIET":                        # clauses 41, 42
            if self.rx.last is not None and now - self.rx.last < QUIET_GAP and \
                    now < self.quiet_limit:
                self.deadline = self.rx.last + QUIET_GAP
                return
            self.next_turn(self.owner, now, uncertain=True)
        elif self.phase == "HOLD":                         # our turn: TXEN (none on a pty)
            if self.rx.in_frame():
                self.deadline = now + 2 * BYTE             # someone is sending: hear it first
                return
            self.phase, self.deadline = "SWITCH", now + TTRANS
        elif self.phase == "SWITCH":                       # clause 23: Header at E + Ttrans
            self.send(now)

    # -- our turn --------------------------------------------------------------------------

    def build(self) -> tuple[int, int, int, str]:
        """This turn's one frame: (Destination, Number, Type, Content)."""
        acks = "".join(f"ack({s},{n})" for s, n in self.acks_owed)
        if self.answering:                                 # clause 34: the answer, empty
            self.answering = False
            if self.booted:
                num, kind = self.next_num, JOIN
                self.next_num = (self.next_num + 1) % 100
            else:
                num, kind = 0, BOOT
            self.announcing, self.announced_frames = (kind, num), 1
            self.awaiting = set(self.ring) - {self.id}
            if not self.awaiting:
                self.announcing, self.booted = None, True
            return BROADCAST, num, kind, ""
        if self.announcing is not None:                    # clause 36: repeat, acks only
            self.announced_frames += 1
            self.acks_owed = []
            kind, num = self.announcing
            return BROADCAST, num, kind, acks
        m = self.inflight
        if m is not None and m["attempts"] >= A_ATTEMPTS:  # clause 46
            self.finish(m, False, f"no acknowledgement after {A_ATTEMPTS} attempts")
            m = None
        if m is None and self.outbox and (self.outbox[0]["dst"] in self.ring or
                                          self.outbox[0]["dst"] == BROADCAST):
            m = self.inflight = self.outbox.pop(0)
            m["awaiting"] = {m["dst"]} if m["dst"] != BROADCAST else set(self.ring) - {self.id}
        poll = ""
        self.sent_poll = None
        self.turns_since_poll += 1
        gap = self.gap()
        if gap and (self.turns_since_poll >= P_EVERY or self.ring == [self.id]):  # 31, 32
            k = gap[self.poll_ptr % len(gap)]
            self.poll_ptr += 1
            self.turns_since_poll = 0
            mask = sum(1 << r for r in self.ring)
            poll, self.sent_poll = f"poll({k},{mask})", k
            self.tell_view = False
        elif self.tell_view and self.ring != [self.id]:    # clause 51.2
            poll, self.tell_view = f"ring({sum(1 << r for r in self.ring)})", False
        self.acks_owed = []
        if m is not None:
            m["attempts"] += 1
            self.last_sent_num = m["num"]
            content = m["content"] + acks + poll           # clause 18
            assert len(content) + self.seal_bytes <= MAX_CONTENT_SENT
            return m["dst"], m["num"], m["type"], content
        return BROADCAST, self.last_sent_num, 3, acks + poll   # clause 23, 45

    def send(self, now: float) -> None:
        dst, num, kind, content = self.build()
        data = encode(dst, self.id, num, kind, content, self.checksum, self.key, self.fresh)
        if self.key is not None:                           # clauses 52, 53.2: ours too
            self.freshness[self.id] = self.fresh
            self.fresh += 1
        self.port.write(data)                              # clause 3: back to back
        self.sent.append((now, data))
        end = now + len(data) * BYTE
        self.heard_since_tx = False
        if self.announcing is not None and self.announced_frames >= ANNOUNCE_LIMIT:
            self.to_listen("members never acknowledged our BOOT/JOIN")
            return
        if self.sent_poll is not None:
            self.phase, self.owner, self.poller = "WINDOW", self.sent_poll, self.id
            self.turn_start = end
            self.deadline = self.limit = end + TWIN
        else:
            self.next_turn(self.id, end)

    # -- the application side -------------------------------------------------------------

    def submit(self, dst: int, content: str, kind: int = 2) -> dict:
        """Clause 45: the next Number; the message waits for its turn."""
        parse_content(content)
        m = {"dst": dst, "num": self.next_num, "type": kind, "content": content,
             "attempts": 0, "awaiting": set(), "acked": set()}
        self.next_num = (self.next_num + 1) % 100
        self.outbox.append(m)
        return m

    def leave(self) -> None:
        """Clause 49: no leave message; we stop transmitting (and keep listening)."""
        self.left = True
        self.mode, self.phase, self.deadline = "LEFT", None, None

    def come_back(self) -> None:
        """Clause 49: not in the old slot (clause 38.3 would refuse it) but from LISTEN, by
        answering the next invitation; with JOIN, as our BOOT was acknowledged (clause 34)."""
        self.left = False
        self.to_listen("coming back")
        self.misses, self.outsiders, self.silent = {}, {}, 0

    @property
    def member(self) -> bool:
        return self.mode == "MEMBER" and self.announcing is None and not self.answering

    # -- the loop --------------------------------------------------------------------------

    def run_until(self, done, timeout: float) -> bool:
        """Serve the protocol until ``done()`` or ``timeout`` seconds; True if done."""
        stop = time.monotonic() + timeout
        fd = self.port.fileno()
        while not done():
            now = time.monotonic()
            if now >= stop:
                return False
            wait = stop - now
            if self.deadline is not None:
                wait = min(wait, max(0.0, self.deadline - now))
            if self.rx.in_frame():
                wait = min(wait, max(0.0, self.rx.last + STALL_GAP - now) + 0.001)
            ready, _, _ = select.select([fd], [], [], wait)
            if ready:
                data = self.port.read(self.port.in_waiting or 1)
                self.hear(data, time.monotonic())
            now = time.monotonic()
            if self.rx.in_frame() and now - self.rx.last > STALL_GAP:    # clause 15.4
                src = self.rx.buf[4] - 48 if len(self.rx.buf) > 4 else None
                self.rx.buf.clear()
                self.failed(src)
            if self.deadline is not None and now >= self.deadline:
                self.on_deadline(now)
        return True

    def hear(self, data: bytes, t: float) -> None:
        """Bytes read together at ``t`` (dated as clause 15.5 says), through the receiver."""
        events: list = []
        if self.phase != "SWITCH":                         # clause 2: deaf while switching
            for i, b in enumerate(data):
                self.rx.feed(b, t - (len(data) - 1 - i) * BYTE, events)
        for ev in events:
            if ev[0] == "frame":
                self.take(ev[1])
            elif ev[0] == "failed":
                self.failed(ev[2])
            elif ev[0] == "garbage" and self.phase == "WAIT" and not self.left and \
                    ev[1] > self.turn_start + TTRANS:
                self.failed(None)                          # clause 42

    def take(self, f: Frame) -> None:
        """A good frame: its seal judged before any other rule reads it (clauses 53, 43),
        then the seal taken off its Content."""
        if self.key is not None:
            fresh = authentic(f.raw, self.key)
            if fresh is None:
                return self.refuse("forged", f)
            if fresh <= self.freshness.get(f.src, -1):
                return self.refuse("replayed", f)
            self.freshness[f.src] = fresh
            f.content = f.content[:-AUTH_BYTES]
        elif self.checksum:
            if not sealed(f.raw):
                return self.refuse("bad crc", f)
            f.content = f.content[:-CRC_BYTES]
        self.on_frame(f)

    def refuse(self, why: str, f: Frame) -> None:
        """Clauses 43, 53: acted on in nothing; a failed frame whose Source was not read, its
        end known."""
        self.refused.append((why, f))
        self.log.append(f"refused ({why}) {f!r}")
        self.silent = 0                     # still a good frame heard (clauses 40, 53)
        self.failed(None, known_end=f.end)

    def close(self) -> None:
        self.port.close()


# ==============================================================================================
# The harness (it may use the project, as any bench would: as processes)
# ==============================================================================================

TEAM = "1,2,4"


def _ptys_available() -> str | None:
    try:
        master, slave = os.openpty()
    except (OSError, AttributeError) as exc:
        return f"pseudo-terminals are unavailable here: {exc}"
    os.close(master)
    os.close(slave)
    return None


def _spawn(*args: str, stdout=subprocess.PIPE) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "hil.cli", *args], cwd=ROOT,
                            stdout=stdout, stderr=subprocess.PIPE, text=True)


class Events:
    """The JSON lines a ``rprs child --events`` prints, collected by a thread."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.lines: list[dict] = []
        self._t = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self._t.start()

    def _read(self, proc: subprocess.Popen) -> None:
        with proc.stdout:                        # the reader closes it, at the end
            for line in proc.stdout:
                try:
                    self.lines.append(json.loads(line))
                except ValueError:
                    pass

    def find(self, **kw) -> list[dict]:
        return [e for e in list(self.lines) if all(e.get(k) == v for k, v in kw.items())]


def _wait(pred, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.05)
    return pred()


def _stop(procs) -> None:
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
        p.stderr.close()                         # stdout: its reader closes it (Events)


def test_the_robot_imports_nothing_from_the_project():
    tree = ast.parse(Path(__file__).read_text(encoding="utf-8"))
    names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert not [m for m in names if m.split(".")[0] in ("firmware_model", "can_bus", "hil")]


def test_the_strangers_seal_is_clause_20s():
    """The clause's check value, a sealed frame the stranger's receiver accepts, and one digit
    of the seal or of the sealed bytes changed: refused."""
    assert crc16(b"123456789") == 0x29B1
    data = encode(1, 4, 3, 2, "status()", checksum=True)
    assert data.endswith(b")" + END) and b"0018status()crc(" in data and sealed(data)
    for i in (len(data) - 4, 12):                 # the seal's last digit; a Content byte
        bad = bytearray(data)
        bad[i] = ord("9") if bad[i] != ord("9") else ord("8")
        assert not sealed(bytes(bad))


AUTH_KEY = bytes.fromhex("000102030405060708090a0b0c0d0e0f")     # §4.11's worked examples


def fresh_of(raw: bytes) -> int:
    """The freshness value of a frame sealed by clause 52."""
    return int(raw[-20:-12], 16)


def test_the_strangers_seal_is_clause_52s():
    """§4.11's two worked examples, byte for byte, taken by the stranger's check (clause 53.1)
    with their freshness values; one changed digit of the tag or of the covered bytes, another
    key, or no ``auth`` at all: forged."""
    heartbeat = bytes.fromhex("0f0a05 37 31 3030 33 30303233 "
                              "617574682830303030303030302c366534363765636529 1719")
    status = bytes.fromhex("0f0a05 31 34 3031 32 30303331 "
                           "7374617475732829617574682830303030303032612c333438623164646529 1719")
    assert encode(7, 1, 0, 3, "", key=AUTH_KEY, fresh=0) == heartbeat
    assert encode(1, 4, 1, 2, "status()", key=AUTH_KEY, fresh=0x2A) == status
    assert heartbeat[3:-11] == b"710030023auth(00000000,"
    assert status[3:-11] == b"140120031status()auth(0000002a,"
    assert heartbeat[12:-2] == b"auth(00000000,6e467ece)" and fresh_of(status) == 0x2A
    assert authentic(heartbeat, AUTH_KEY) == 0 and authentic(status, AUTH_KEY) == 0x2A
    for i in (len(status) - 4, 12, 4):             # the tag's last digit; Content; the Source
        bad = bytearray(status)
        bad[i] = ord("9") if bad[i] != ord("9") else ord("8")
        assert authentic(bytes(bad), AUTH_KEY) is None
    assert authentic(status, bytes(16)) is None
    assert authentic(encode(1, 4, 1, 2, "status()"), AUTH_KEY) is None
    upper = status.replace(b"348b1dde", b"348B1DDE")              # clause 16: lowercase hex
    assert authentic(upper, AUTH_KEY) is None


def test_the_strangers_freshness_and_key_file_are_clauses_52_and_54s(tmp_path):
    """Clause 52's clock rule; clause 54's file: comments and blank lines skipped, either case;
    a file with no, two or a bad ``key = `` line, another line, or none at all: refused,
    naming the file."""
    assert clock_freshness(AUTH_EPOCH) == 0 and clock_freshness(AUTH_EPOCH + 2.9) == 92
    assert clock_freshness(AUTH_EPOCH + 86400) == 32 * 86400
    good = tmp_path / "ring.key"
    good.write_text("# the ring's key\n\nkey = 000102030405060708090A0B0C0D0E0f\n# end\n")
    assert read_key(good) == AUTH_KEY
    spaced = tmp_path / "spaced.key"            # clause 54: CRLF, spaces and tabs, indented #
    spaced.write_bytes(b"  # a comment\r\n \t\r\n\tkey\t=000102030405060708090a0b0c0d0e0f \r\n")
    assert read_key(spaced) == AUTH_KEY
    for name, text in [("none", "# no key\n"),
                       ("inline", "key = " + "0" * 32 + " # the ring's\n"),
                       ("short", "key = " + "0" * 31 + "\n"),
                       ("two", "key = " + "0" * 32 + "\nkey = " + "1" * 32 + "\n"),
                       ("colon", "key: " + "0" * 32 + "\n"), ("hexless", "key = " + "g" * 32),
                       ("other", "ring = 1\nkey = " + "0" * 32 + "\n")]:
        bad = tmp_path / f"{name}.key"
        bad.write_text(text)
        with pytest.raises(ValueError, match=f"{name}.key"):
            read_key(bad)
    with pytest.raises(ValueError, match="missing.key"):
        read_key(tmp_path / "missing.key")


def test_the_stranger_refuses_forged_and_replayed_frames():
    """Clause 53 through the stranger's receive path (its own encoder makes the frames; a
    ``loop://`` port, nothing sent): a forged or replayed invitation is not answered and a
    replayed message not acknowledged again; neither moves the freshness kept per Source."""
    robot = StrangerRobot("loop://", 4, {1, 2, 4}, key=AUTH_KEY)
    try:
        def hear(raw: bytes) -> str:
            n = len(robot.refused)
            robot.hear(raw, time.monotonic())
            return robot.refused[n][0] if len(robot.refused) > n else "accepted"

        def invite(fresh: int, key: bytes = AUTH_KEY) -> bytes:
            return encode(7, 2, 0, 3, "poll(4,6)", key=key, fresh=fresh)

        heartbeat = encode(7, 2, 0, 3, "", key=AUTH_KEY, fresh=10)
        assert hear(heartbeat) == "accepted" and robot.freshness == {2: 10}
        wrong_tag = bytearray(invite(11))
        wrong_tag[-4] = ord("0") if wrong_tag[-4] != ord("0") else ord("1")
        assert hear(bytes(wrong_tag)) == "forged"
        assert hear(invite(11, key=bytes(16))) == "forged"
        assert hear(encode(7, 2, 0, 3, "poll(4,6)")) == "forged"            # no auth at all
        assert hear(heartbeat) == "replayed"
        assert hear(invite(10)) == "replayed" and hear(invite(9)) == "replayed"
        assert robot.mode == "LISTEN" and robot.freshness == {2: 10}, robot.log
        assert hear(invite(11)) == "accepted"                                # clause 34
        assert robot.mode == "MEMBER" and robot.ring == [1, 2, 4] and robot.answering
        assert robot.freshness == {2: 11}

        reply = encode(4, 1, 1, 3, "fail(30)status()", key=AUTH_KEY, fresh=500)
        assert hear(reply) == "accepted"
        assert robot.inbox == [(1, 4, 1, [("fail", (30,)), ("status", ())])]
        assert robot.acks_owed == [(1, 1)]                                   # clause 47
        robot.acks_owed = []
        assert hear(reply) == "replayed"             # clause 48 would acknowledge it again
        assert robot.acks_owed == [] and len(robot.inbox) == 1
        assert robot.freshness == {1: 500, 2: 11}
        assert [w for w, _ in robot.refused] == ["forged"] * 3 + ["replayed"] * 4
    finally:
        robot.close()


@pytest.mark.timing
@pytest.mark.parametrize("profile", ["plain", "checksum", "auth"])
def test_a_stranger_robot_joins_talks_and_leaves(tmp_path, profile):
    """The module's scenario; with ``checksum`` every station seals its frames (clause 20):
    the children run ``--checksum``, the stranger its own CRC from the clause; with ``auth``
    every station runs the authenticated profile (clauses 52-54): the children run
    ``--auth-key FILE``, the stranger reads the same file and seals and checks from the
    clauses. A run that fails and that the host disturbed (a child's ``stall`` or ``late``
    event, or the host's scheduling latency past ``processes.HOST_LATE_MS``: a frame of the
    stranger's missed on a busy host costs it a turn) is run again, up to
    ``processes.ATTEMPTS`` runs; a failure in an undisturbed run fails at once."""
    why = _ptys_available()
    if why:
        pytest.skip(why)
    from hostload import SchedulingLatency
    from processes import ATTEMPTS, disturbed
    for attempt in range(ATTEMPTS):
        run_dir = tmp_path / f"run{attempt}"
        run_dir.mkdir()
        ev: dict[int, Events] = {}
        probe = SchedulingLatency().__enter__()
        try:
            _stranger_scenario(run_dir, profile, ev)
        except AssertionError:
            host = disturbed([e.lines for e in ev.values()], (), probe)
            if not host or attempt == ATTEMPTS - 1:
                raise
            print(f"run {attempt + 1} failed, disturbed: {host}; run again")
        else:
            probe.stop()
            return


def _stranger_scenario(tmp_path: Path, profile: str, ev: dict) -> None:
    """One run of the scenario in ``tmp_path``; ``ev`` gets each child's ``Events``."""
    checksum, key, sealing = profile == "checksum", None, []
    if checksum:
        sealing = ["--checksum"]
    elif profile == "auth":
        key_file = tmp_path / "ring.key"
        key_file.write_text("# the bench's ring key (clause 54)\n\n"
                            "key = 00112233445566778899AABBCCDDEEFF\n", encoding="ascii")
        key, sealing = read_key(key_file), ["--auth-key", str(key_file)]

    def framed(sent: bytes, dst: int, num: int, typ: int, content: str) -> bytes:
        """The frame the stranger should have sent as ``sent`` (with the freshness it gave)."""
        fresh = fresh_of(sent) if key is not None else 0
        return encode(dst, 4, num, typ, content, checksum, key, fresh)
    air = tmp_path / "air"
    hub = _spawn("radio-hub", "--nodes", "3", "--link-dir", str(air), "--seed", "1",
                 stdout=subprocess.DEVNULL)      # nobody reads it
    procs = [hub]
    robot = None
    try:
        assert _wait(lambda: all((air / f"node{i}").exists() for i in range(3)), 15), \
            hub.stderr.read() if hub.poll() is not None else "the hub made no ptys"
        kids = {1: _spawn("child", "--id", "1", "--radio", str(air / "node0"), "--team", TEAM,
                          "--can", f"virtual:stranger{os.getpid()}", "--events", *sealing),
                2: _spawn("child", "--id", "2", "--radio", str(air / "node1"), "--team", TEAM,
                          "--events", *sealing)}
        procs += kids.values()
        ev.update({r: Events(p) for r, p in kids.items()})
        # the children's ring {1, 2}; then the only absent team robot, 4, is in 2's gap
        assert _wait(lambda: ev[1].find(ev="join", robot=2) or ev[2].find(ev="join", robot=1),
                     25), [p.stderr.read() for p in kids.values() if p.poll() is not None]

        before = {r: len(ev[r].lines) for r in kids}    # the ring's formation is not ours
        opened = time.time()
        robot = StrangerRobot(str(air / "node2"), 4, {1, 2, 4}, checksum, key)
        first_fresh = robot.fresh
        t0 = time.monotonic()
        assert robot.run_until(lambda: robot.member, 10), robot.log
        assert robot.ring == [1, 2, 4] and robot.sent[0][1] == framed(robot.sent[0][1], 7, 0,
                                                                      BOOT, "")
        joined = time.monotonic() - t0

        msg = robot.submit(1, "status()")
        assert robot.run_until(lambda: robot.outcomes and any(
            s == 1 and d == 4 for s, d, _, _ in robot.inbox), 10), (robot.log, robot.outcomes)
        assert robot.outcomes == [(msg, True, "")]               # acknowledged by child 1
        (src, dst, num, reply), = [m for m in robot.inbox if m[0] == 1]
        # child 1's CAN bus has no submodule on it: its truthful answer is that none answers
        # (docs/dispatcher.md, code 30), with the order it could not serve
        assert reply == [("fail", (30,)), ("status", ())], reply
        # a few more turns, so that child 1 hears our acknowledgement of its reply
        turns = len(robot.sent)
        assert robot.run_until(lambda: len(robot.sent) >= turns + 3, 5), robot.log
        assert any(f"ack(1,{num})" in d.decode() for _, d in robot.sent[turns - 1:])
        assert _wait(lambda: ev[1].find(ev="delivered", src=1, dst=4, num=num), 5)

        robot.leave()
        t_left = time.monotonic()
        assert robot.run_until(lambda: all(ev[r].find(ev="disable", robot=4) for r in kids), 8), \
            [e for r in kids for e in ev[r].lines if e["ev"] in ("miss", "disable")]
        dropped = time.monotonic() - t_left
        n_heard = len(robot.heard)
        assert robot.run_until(lambda: len(robot.heard) >= n_heard + 8, 5)
        after = list(robot.heard[n_heard:])

        n_sent = len(robot.sent)
        robot.come_back()
        t_back = time.monotonic()
        assert robot.run_until(lambda: robot.member, 10), robot.log
        back = time.monotonic() - t_back
        assert robot.ring == [1, 2, 4], robot.log
        # the answer is JOIN with the next Number: status() had 01 (clause 45), so 02
        assert robot.sent[n_sent][1] == framed(robot.sent[n_sent][1], 7, msg["num"] + 1, JOIN,
                                               ""), robot.sent
        turns = len(robot.sent)
        assert robot.run_until(lambda: len(robot.sent) >= turns + 3, 5), robot.log
        assert _wait(lambda: all(ev[r].find(ev="rejoin", robot=4) for r in kids), 5), \
            [e for r in kids for e in ev[r].lines if e["ev"] in ("join", "rejoin")]
    finally:
        if robot is not None:
            robot.close()
        _stop(procs)

    # the children's view, from the moment the stranger opened its port
    for r in kids:
        seen = ev[r].lines[before[r]:]
        assert [(e["ev"], e["robot"]) for e in seen if e["ev"] in ("join", "rejoin")] == \
            [("join", 4), ("rejoin", 4)], seen
        assert not [e for e in seen if e["ev"] == "mode"]         # the ring never broke
        assert [e["robot"] for e in seen if e["ev"] == "disable"] == [4]
        assert [e["robot"] for e in seen if e["ev"] == "miss"] == [4, 4, 4]   # after it left
    assert len(ev[1].find(ev="deliver", src=4, dst=1, content="status()")) == 1
    assert not ev[2].find(ev="deliver", src=4)
    # after the drop, the ring is 1 -> 2 -> 1 ..., and 2 invites 4 again (clause 32)
    assert all(b.src == 3 - a.src for a, b in zip(after, after[1:])), after
    polls = [f.content for f in robot.heard if f.src == 2 and "poll(4," in f.content]
    assert polls and all("poll(4,6)" in c for c in polls)
    assert joined < 5 and dropped < 5 and back < 5, (joined, dropped, back)
    if key is not None:
        # clause 52: from the clock when the stranger started, +1 a frame, JOIN and BOOT too
        assert clock_freshness(opened) <= first_fresh <= clock_freshness(opened + 1)
        assert [fresh_of(d) for _, d in robot.sent] == \
            list(range(first_fresh, first_fresh + len(robot.sent)))
        # clause 53: nobody found a frame forged or replayed, the stranger nor the children
        assert not robot.refused, robot.refused
        assert set(robot.freshness) == {1, 2, 4}, robot.freshness     # every sender's tag right
        for r in kids:
            assert not [e for e in ev[r].lines if e["ev"] == "refused" and any(
                str(v).startswith(("forged", "replayed")) for v in e.values())], ev[r].lines

"""A robot that knows only the paper (Zhang et al., ROBIO 2006, §IV.C-D), written from the
paper's rules alone: plain pyserial, nothing imported from this project
(``test_paper_profile.py`` checks that). Its ring is the whole team, fixed; the turns go in
ascending ID, each owner sends one frame (a message or an empty heartbeat, Type '3' to '7')
Ttrans after the previous End; an owner whose frame has not begun by E + Tmax has missed, and
the next robot takes the turn; three misses in a row and the robot is disabled; the owner is
whoever actually sends. No acknowledgement, no start-up or rejoin rule. Times in seconds.

The paper-profile tests (``test_paper_profile.py``) and the conformance kit's tests
(``test_conformance.py``) run it.
"""
from __future__ import annotations

import time

import serial

# ==============================================================================================
# A robot that knows only the paper
# ==============================================================================================

TTRANS = 0.005               # paper §IV.C: switch time
TMAX = 0.600                 # paper §IV.C: the longest a robot may use the channel
DISABLE_AFTER = 3            # paper §IV.C: "three times continuously"
BYTE = 10 / 9600
HEADER, END = b"\x0f\x0a\x05", b"\x17\x19"
PAPER_TYPES = set(range(5))  # paper §IV.D: '0' seek help ... '4' failure information


def paper_frame(dst: int, src: int, num: int, typ: int, content: str) -> bytes:
    """Paper §IV.D, Fig. 8: Header, Destination, Source, Number, Type, Length, Content, End."""
    c = content.encode("ascii")
    return HEADER + b"%d%d%02d%d%04d" % (dst, src, num, typ, len(c)) + c + END


class PaperRobot:
    """The paper's rotation on a serial port, polled with ``step()``."""

    def __init__(self, port: str, robot: int, team: set[int]) -> None:
        self.id = robot
        self.ring = sorted(team)
        self.misses = {r: 0 for r in self.ring}
        self.port = serial.Serial(port, 9600, timeout=0)
        self.port.reset_input_buffer()
        self.buf = bytearray()
        self.last_byte = 0.0
        self.heard: list[tuple[int, int, int, int, str, float]] = []  # dst src num type content E
        self.inbox: list[tuple[int, str]] = []
        self.outbox: list[tuple[int, str]] = []
        self.sent: list[bytes] = []
        self.sent_at_heard: list[int] = []
        self.disabled: list[int] = []
        self.num = 0
        now = time.monotonic()
        self.deaf_until = 0.0
        self._owner(self.ring[0], now)                 # the lowest ID's turn begins now

    def succ(self, r: int) -> int:
        later = [x for x in self.ring if x > r]
        return later[0] if later else self.ring[0]

    def _owner(self, owner: int, start: float) -> None:
        """``owner``'s turn begins at ``start``: it sends at start + Ttrans (paper §IV.C)."""
        self.owner, self.turn_start = owner, start
        self.send_at = start + TTRANS if owner == self.id else None

    def _turn(self, after: int, start: float) -> None:
        self._owner(self.succ(after), start)

    def step(self) -> None:
        now = time.monotonic()
        data = self.port.read(1024)
        if data and now >= self.deaf_until:
            self.last_byte = now
            for b in data:
                self._feed(b, now)
        if self.send_at is not None and now >= self.send_at:
            self._send(now)
        elif self.send_at is None and now >= self.turn_start + TMAX and not (
                self.buf and self.last_byte > self.turn_start):
            o = self.owner                              # no Header by E + Tmax: a miss
            nxt = self.succ(o)
            self.misses[o] = self.misses.get(o, 0) + 1
            if self.misses[o] >= DISABLE_AFTER and len(self.ring) > 1:
                self.ring.remove(o)                     # disabled (paper §IV.C)
                self.disabled.append(o)
            self._owner(nxt, self.turn_start + TMAX)

    def _feed(self, b: int, now: float) -> None:
        buf = self.buf
        buf.append(b)
        if len(buf) <= 3:
            if bytes(buf) != HEADER[:len(buf)]:
                buf.clear()
                if b == HEADER[0]:
                    buf.append(b)
            return
        if len(buf) < 12:
            if not chr(b).isdigit():
                buf.clear()
            return
        length = int(buf[8:12])
        if length > 562:                               # more than fits in Tmax: no frame
            buf.clear()
            return
        if len(buf) == 12 + length + 2:
            raw = bytes(buf)
            buf.clear()
            if raw[-2:] == END:
                self._frame(raw, now)

    def _frame(self, raw: bytes, end: float) -> None:
        dst, src, num, typ = raw[3] - 48, raw[4] - 48, int(raw[5:7]), raw[7] - 48
        content = raw[12:-2].decode("ascii", "replace")
        self.heard.append((dst, src, num, typ, content, end))
        self.sent_at_heard.append(len(self.sent))      # our frames sent before this one
        if src == self.id or src > 6:
            return
        if src not in self.ring:                       # the owner is whoever sends
            self.ring = sorted(self.ring + [src])
        self.misses[src] = 0
        if content and dst in (self.id, 7):
            self.inbox.append((src, content))
        self._turn(src, end)

    def _send(self, now: float) -> None:
        if self.outbox:
            dst, content = self.outbox.pop(0)
            self.num = (self.num + 1) % 100
            data = paper_frame(dst, self.id, self.num, 2, content)
        else:
            data = paper_frame(7, self.id, self.num, 3, "")
        self.port.write(data)
        self.sent.append(data)
        end = now + len(data) * BYTE
        self.deaf_until = end                          # half duplex: deaf while sending
        self._turn(self.id, end)

    def run_for(self, seconds: float, until=None) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.step()
            if until is not None and until():
                return True
            time.sleep(0.0005)
        return until() if until is not None else True

    def close(self) -> None:
        self.port.close()

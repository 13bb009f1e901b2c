"""The scripted station of the conformance kit and the order of its checks (:meth:`Tester.run`);
the steps are in joining.py, refusals.py, ring_of_three.py and silence.py."""
from __future__ import annotations

import statistics
import time
from functools import partial
from typing import Any, Callable

from firmware_model.radio.auth import check as auth_check, clock_freshness
from firmware_model.radio.auth import seal as auth_seal, strip as auth_strip
from firmware_model.radio.content import parse_content
from firmware_model.radio.deframer import Deframer, FrameFailed, FrameReceived, Garbage
from firmware_model.radio.errors import ContentError
from firmware_model.radio.frame import BROADCAST, HEADER, Frame, FrameType
from firmware_model.radio.integrity import check as crc_check, seal as crc_seal
from firmware_model.timing import TICK_HZ

from . import joining, own_counter, refusals, ring_of_three, silence
from .frames import _app, _at_turn, _forger, _succ
from .link import (BYTE, MISS_LIMIT, MS, POLL_SEND, POLL_WAIT, QUIET_GAP, TMAX, TSLOT, TTRANS,
                   TWIN, SerialLink, TesterLink)
from .report import Check, ConformanceError, Heard, Report


class Tester:
    """The scripted station on ``port`` (a serial port's name, or a :class:`TesterLink`)
    and the checks, run by :meth:`run`."""

    __test__ = False                  # not a pytest class
    key = None                        # the ring key (the authenticated profile), or None
    checksum = False                  # the checksum extension (clause 20)

    def __init__(self, port: str | TesterLink, robot: int, profile: str = "rprs",
                 tester: int | None = None, tolerance_ms: float = 15.0, turns: int = 20,
                 progress: Callable[[str], None] | None = None, key=None,
                 team: tuple[int, ...] = tuple(range(7)), checksum: bool = False,
                 wrap: bool = False, txen: str = "none") -> None:
        if not 0 <= robot <= 6:
            raise ValueError(f"robot ID must be 0-6, got {robot}")
        self.robot = robot
        self.me = tester if tester is not None else (0 if robot != 0 else 1)
        if self.me == robot or not 0 <= self.me <= 6:
            raise ValueError(f"the tester's ID must be 0-6 and not the robot's, got {self.me}")
        self.forger = _forger(robot, self.me)
        others = [i for i in team if i not in (robot, self.me)]
        self.third: int | None = min(others) if others else None
        """The team robot this PC also plays as a third member (clauses 51.3, 40), or None
        when the team has none besides the robot and us (then those checks are n/a)."""
        self.third_acks: list[tuple[int, int]] = []     # what the third member owes
        self.third_num = 0                                # its last message's Number
        # paper profile: the static ring is the robot's whole team; the absent robots
        # between it and us keep their turns (Tmax each) until dropped after three misses
        self.absent = {i: 0 for i in team if i not in (robot, self.me)}
        self.team = tuple(team)
        self.profile = profile
        self.tol = int(tolerance_ms * MS)
        self.turns = turns
        self.progress = progress or (lambda s: None)
        self.link: TesterLink = SerialLink(port, txen) if isinstance(port, str) else port

        self.deframer = Deframer(byte_ticks=BYTE)
        self.heard: list[Heard] = []
        self.bad = 0                      # failed frames heard (not in our own air time)
        self.collided = 0                 # failed frames that overlapped one of ours
        self.garbage = 0                  # bytes that formed no frame
        self.on_air: list[tuple[int, int]] = []   # our transmissions (first bit, End), ticks
        self.rx_bytes = 0
        self.num = 0
        self.last_end = 0                 # our own last End (estimated)
        self.acks: list[tuple[int, int]] = []
        self.report = Report(robot, profile)
        self._mark = (0, 0, 0)            # rx_bytes, bad, garbage when the last wait began
        self._mark_collided = 0           # len(collisions) then
        self.first_failure: str | None = None   # why the first failed frame failed
        self.key = key                    # the ring key: the authenticated profile (§4.11)
        if key is not None and profile == "paper":
            raise ValueError("the paper profile has no authenticated profile")
        # our next freshness value (FreshnessExhausted, a ValueError's kin, is said in one
        # line by the command: the key is due for rotation)
        self.fresh = clock_freshness(time.time(), key.epoch) if key is not None else 0
        self.rx_fresh: int | None = None  # the robot's last freshness value
        self.auth_bad: list[str] = []     # the robot's frames with a wrong tag or stale value
        self.checksum = checksum          # the checksum extension (clause 20)
        if checksum and (profile == "paper" or key is not None):
            raise ValueError("the checksum extension is for the rprs profile without "
                             "--auth-key (the tag vouches for every byte: one or the other)")
        self.crc_bad: list[str] = []      # the robot's frames without a right crc(NNNNN)
        self.wrap = wrap                  # run its own Number past '99' too (own_counter.py)
        self.sent: list[bytes] = []       # every frame we sent, as sent
        self.strangers: dict[int, int] = {}       # good frames heard from any other Source
        self.collisions: list[int] = []           # each collided frame's start - our End
        self.last_rx = -QUIET_GAP         # tick the last byte arrived
        self.misses: list[str] = []       # the robot's missed turns, which we took over

    # -- time, air -----------------------------------------------------------------------

    def now(self) -> int:
        return self.link.now()

    def _secs(self) -> float:
        """The link's clock in seconds (what a check took is measured on it)."""
        return self.now() / TICK_HZ

    def _poll_rx(self) -> None:
        for data, first, dt in self.link.read():
            self._heard_bytes(data, first, dt)

    def _heard_bytes(self, data: bytes, first: int, dt: int) -> None:
        """Bytes heard back to back, the first complete at tick ``first``."""
        self.rx_bytes += len(data)
        before, self.last_rx = self.last_rx, first + (len(data) - 1) * dt
        for ev in self.deframer.feed(data, first, dt):
            if isinstance(ev, FrameReceived):
                f = ev.frame
                start = ev.end - f.nbytes * BYTE
                if f.src not in (self.robot, self.me):
                    # another station's frame: counted (the run stops), its tag not
                    # checked (clause 52 judges the robot's frames only)
                    self.strangers[f.src] = self.strangers.get(f.src, 0) + 1
                elif self.key is not None:
                    f = self._authenticated(f)
                elif self.checksum and f.src == self.robot and not crc_check(f):
                    self.crc_bad.append(f"Number {f.num:02d}: " + (
                        "a wrong crc" if b"crc(" in f.content else "no crc(NNNNN)"))
                self.heard.append(Heard(f, start, ev.end))
            elif isinstance(ev, Garbage):
                self.garbage += ev.count
            elif isinstance(ev, FrameFailed):
                i = (ev.at - first) // dt
                if 0 <= i < len(data) and data[i] == HEADER[0]:
                    # Broken by the first byte of a later Header: its bytes stopped after
                    # the last one heard before it (a gap, or the Header came at once)
                    stop = first + (i - 1) * dt if i else before
                    self._failed(ev, stop if ev.at - stop > 2 * dt else ev.at)
                else:
                    self._failed(ev, ev.at)

    def _failed(self, ev: FrameFailed, at: int) -> None:
        """A frame that broke at tick ``at``: one we stepped on (:meth:`_ours_overlap`), or
        the robot's. A frame whose bytes stopped broke where they stopped, not at the later
        Header that showed it: a frame cut by ours (we hear nothing while on air) was once
        judged at the robot's next Header, R-stagger after our End (105 ms for robot 1),
        beyond the tolerance, and failed clause 15 against the robot."""
        if self._ours_overlap(ev.first, at):
            self.collided += 1
            before = [e for _, e in self.on_air if e <= ev.first]
            if before:          # where its Header began, from our End before it
                self.collisions.append(ev.first - before[-1])
            return
        self.bad += 1
        if self.first_failure is None:
            self.first_failure = str(ev.error)
            if "(content): 0x17 " in self.first_failure:
                # the End's first byte where the Length promised more Content
                self.first_failure += " (the End came early: a Length longer than the Content)"

    def _authenticated(self, f: Frame) -> Frame:
        """The robot's frame ``f`` with its ``auth(...)`` taken off, its tag and freshness
        checked (clauses 52-53). A frame that fails is noted for clause 52's verdict and, as
        every member refuses it (clause 53), judged for its timing only: it becomes a control
        frame with nothing in it, so that no other check credits what it carries (an answer
        to an invitation, an ack, a reply)."""
        assert self.key is not None       # (called only in an authenticated ring)
        fresh = auth_check(self.key, f)
        if fresh is None:
            self.auth_bad.append(f"Number {f.num:02d}: no valid tag")
            return _refused_frame(f)
        if self.rx_fresh is not None and fresh <= self.rx_fresh:
            self.auth_bad.append(f"Number {f.num:02d}: freshness {fresh:08x} after "
                                 f"{self.rx_fresh:08x}")
            return _refused_frame(f)
        self.rx_fresh = fresh
        return Frame(dst=f.dst, src=f.src, num=f.num, type=f.type, content=auth_strip(f.content))

    def _ours_overlap(self, first: int, at: int) -> bool:
        """A frame of the robot's whose Header began (tick ``first``) before one of our
        transmissions, or within the tolerance after it began, and that broke (tick ``at``)
        while ours was on air, or within the tolerance after its End: we stepped on it (a
        collision we caused, or a race neither side can order: both are stamps of this PC,
        late by its latency, and a takeover of ours can meet the robot's own), so it says
        nothing of the robot's frames. A frame that began later than that is judged: the
        robot spoke while we were on air. (A takeover race once failed clause 15 on a frame
        of the robot's cut after 4 bytes, its Header stamped a few ms after ours began.)"""
        return any(first < s + self.tol and s <= at <= e + self.tol
                   for s, e in self.on_air[-4:])

    @property
    def lead(self) -> int:
        """Ticks our writes come before our Headers (a radio keyed by a TXEN line: Ttrans;
        a link without one, as the simulator's, 0)."""
        return getattr(self.link, "lead", 0)

    def _write(self, data: bytes) -> int:
        """Put ``data`` on air now; the tick its End leaves the air. Our radio is deaf from
        then on: a frame still arriving is cut by ours and broke now (:meth:`_failed`); of
        one whose bytes we read only after this, the bytes stopped in our air time."""
        start = self.link.write(data)
        if self.key is not None:
            self.sent.append(data)
        self.last_end = start + len(data) * BYTE
        self.on_air.append((start, self.last_end))
        cut = self.deframer.abort(start)
        if cut is not None:
            self._failed(cut, start)
        return self.last_end

    def wait_frame(self, after: int, timeout_ticks: int, src: int | None = None) -> Heard | None:
        """The first frame (from ``src``) whose End arrived after tick ``after``, waiting up
        to ``timeout_ticks`` past ``after`` (or past now, if later): ``after`` is often our
        own End, still ahead while our bytes leave."""
        deadline = max(self.now(), after) + timeout_ticks
        self._mark = (self.rx_bytes, self.bad, self.garbage)
        self._mark_collided = len(self.collisions)
        seen = 0
        while True:
            self._alone()
            for h in self.heard[seen:]:
                if h.end > after and (src is None or h.frame.src == src):
                    return h
            seen = len(self.heard)
            if self.now() >= deadline:
                return None
            self._poll_rx()
            self.link.idle(POLL_WAIT)

    def _alone(self) -> None:
        """Stop the run if the channel carries a third station: the kit checks a ring of two
        (this PC and the robot), and on a shared channel every verdict would blame the robot
        for the others' frames and collisions."""
        if self.strangers:
            who = ", ".join(f"robot {s} ({n} frames)" for s, n in sorted(self.strangers.items()))
            raise ConformanceError(
                f"the channel is not a ring of two: besides robot {self.robot} and this PC "
                f"(ID {self.me}) it carries {who}; give the robot and this PC a channel of "
                f"their own (a hub of two nodes, or the other robots off)", shared=True)

    def listen(self, ticks: int) -> None:
        """Only listen for ``ticks`` (stops if a third station is heard)."""
        deadline = self.now() + ticks
        while self.now() < deadline:
            self._poll_rx()
            self._alone()
            self.link.idle(POLL_WAIT)

    def _quiet(self, what: str) -> ConformanceError:
        """The run stops: the robot sent no good frame ``what``; with what this port heard
        since ``_mark`` (silence, broken frames, or garbage), not just "stopped sending"."""
        b, f, g = (now - was for now, was in zip((self.rx_bytes, self.bad, self.garbage),
                                                 self._mark))
        heard = "nothing" if not b else f"{b} bytes: {f} failed frames, {g} garbage bytes"
        col = getattr(self, "collisions", [])[getattr(self, "_mark_collided", 0):]
        if col:             # name the cause: its frames began where ours were due
            heard += (f", and {len(col)} of its frames broke in collisions with ours: their "
                      f"Headers began {statistics.median(col) / MS:+.0f} ms (median) after "
                      f"our End before them, where E + Ttrans = {TTRANS / MS:.0f} ms is due")
        return ConformanceError(f"robot {self.robot} sent no good frame {what}; this port "
                                f"heard {heard} while it waited")

    after_miss = False                # the robot's last frame came after a missed turn
    last_rx = -QUIET_GAP

    def send(self, frame: Frame, at: int) -> int:
        """Send ``frame`` with its first bit at tick ``at`` (Ttrans after TXEN); its End."""
        while self.now() < at:
            self._poll_rx()
            self.link.idle(POLL_SEND)
        return self._write(frame.encode())

    def _busy(self) -> bool:
        """A frame is arriving: a Header began and its last byte came within the quiet gap."""
        return self.deframer.in_frame and self.now() - self.last_rx < QUIET_GAP

    def _arriving(self, at: int) -> Heard | None:
        """Wait until tick ``at``; if a frame of the robot's is arriving then, wait for it
        and return it (sent then, ours would cut it), else None: the channel is clear.
        (Callers have just looked at the air: a serial port's read waits up to its timeout,
        50 ms, on a quiet channel, and one more look here put our invitation that much
        later, onto a lone member's next frame.)"""
        while self.now() < at:
            self._poll_rx()
            self.link.idle(POLL_SEND)
        h = None
        while h is None and self._busy():
            h = self.wait_frame(self.last_rx - 1, QUIET_GAP, self.robot)
        return h

    def _takeover_at(self, end: int, robot_end: int) -> int:
        """When our Header begins if the robot's has not begun in its turn after our frame
        ending at ``end`` (its last frame we accepted ended at ``robot_end``): as a member of
        the ring of two does (clause 24), at E + Tmax, with R-stagger and R-pair in the rprs
        profile (clause 44: nothing heard since our frame), plus our tolerance (its Header
        reaches this PC late by the port's latency)."""
        if self.profile == "rprs":
            txen = max(end + TMAX + self.me * TSLOT,
                       robot_end + TMAX + self.robot * TSLOT + TTRANS + 4 * BYTE)
        else:
            txen = end + TMAX
        return txen + TTRANS + self.tol

    def _exchange(self, h: Heard, data: Callable[[], bytes], at: int | None = None,
                  again: Callable[[], bytes] | None = None) -> tuple[Heard, int, bool]:
        """Our turn after the robot's frame ``h``: ``data()`` put on air with its Header at
        ``at`` (default :meth:`_turn_at`), then the robot's next frame. Returns that frame,
        our End before it, and whether a turn was missed on the way (then the frame is no
        sample of what followed ``data``).

        The ring is carried on past a missed turn, as a member of it does: a robot on a
        busy PC can be starved past a Tslot, drop what it heard meanwhile and listen for the
        ring again (docs/protocol.md clause 5); it then sends nothing until it hears a frame.
        If its Header has not begun by our takeover instant (:meth:`_takeover_at`), we count
        the miss and take the turn over with ``again()`` (default ``data()``: a message it
        may not have heard is sent again, a retransmission), and wait for it once more. Only
        ``MISS_LIMIT`` misses in a row stop the run: a member drops it then (clause 25).
        If this PC itself woke after the robot took our turn over (its frame, or a Header,
        came first), we send nothing and take its frame (a turn missed too)."""
        at = self._turn_at(h) if at is None else at
        while self.now() < at - self.lead:          # (a keyed radio: TXEN Ttrans before)
            self._poll_rx()
            self.link.idle(POLL_SEND)
        self._poll_rx()
        if self._busy() or any(x.end > h.end and x.frame.src == self.robot
                               for x in self.heard[-3:]):
            self.misses.append(f"ours after its frame ending at {h.end / MS:.0f} ms (this PC "
                               f"woke {(self.now() - at) / MS:.0f} ms late; it took over)")
            nxt = self.wait_frame(h.end, 2 * TMAX + 8 * TSLOT, self.robot)
            if nxt is None:
                raise self._quiet(f"after its frame ending at {h.end / MS:.0f} ms")
            return nxt, self.last_end, True
        end = self._write(data())
        mark, missed = None, 0
        while True:
            due = self._takeover_at(end, h.end)
            nxt = self.wait_frame(end, max(0, due - max(self.now(), end)), self.robot)
            while nxt is None and self._busy():        # a Header begun in time: waited for
                nxt = self.wait_frame(end, QUIET_GAP, self.robot)
            mark = mark or self._mark
            if nxt is not None:
                return nxt, end, missed > 0
            missed += 1
            self.misses.append(f"after our frame ending at {end / MS:.0f} ms")
            self.progress(f"robot {self.robot} missed its turn after our frame ending at "
                          f"{end / MS:.0f} ms: we take it over (miss {missed} in a row)")
            if missed == MISS_LIMIT:
                self._mark = mark
                raise self._quiet(f"in {MISS_LIMIT} turns in a row, the last after our frame "
                                  f"ending at {end / MS:.0f} ms (a member drops it then, "
                                  f"clause 25)")
            end = self._write((again or data)())

    def _encoded(self, content: bytes = b"", **fields: Any) -> bytes:
        """Our next frame's bytes (a Number, a freshness counter taken only when it is
        built: at the moment it goes on air)."""
        return self.frame(content, **fields).encode()

    def frame(self, content: bytes = b"", dst: int = BROADCAST, type_: int = 3,
              num: int | None = None, src: int | None = None) -> Frame:
        src = self.me if src is None else src
        num = self.num if num is None else num
        if self.key is not None:
            self.fresh += 1
            return auth_seal(self.key, dst, src, num, type_, content, self.fresh - 1)
        if self.checksum:
            return crc_seal(dst, src, num, type_, content)
        return Frame(dst=dst, src=src, num=num, type=type_, content=content)

    def _acks_content(self) -> bytes:
        if self.profile != "rprs":
            return b""
        out = b"".join(b"ack(%d,%d)" % a for a in self.acks)
        self.acks.clear()
        return out

    def check(self, clause: str, name: str, passed: bool, figure: str, t0: float,
              applicable: bool = True) -> None:
        """Record a verdict; ``applicable`` False when nothing was there to check (then
        ``figure`` says why, and ``passed`` is ignored)."""
        c = Check(clause, name, bool(passed) or not applicable, figure,
                  self._secs() - t0, applicable)
        self.report.checks.append(c)
        self.progress(f"clause {clause}: {c.verdict} {name}: {figure}")

    # -- the run -------------------------------------------------------------------------

    def run(self) -> Report:
        """Every check in order; a run that stops (ConformanceError) still judges clause 15
        on what it heard, so a robot whose frames all fail is told so (``n/a`` if it sent
        no frame at all)."""
        stopped, shared = True, False
        try:
            last = self._start()
            last = self._rotation(last)
            last = self._late(last)
            last = self._message(last)
            if self.wrap:
                last = self._own_wrap(last)
            last = self._forged(last)
            if self.key is not None:
                last = self._forged_tag(last)
                last = self._replayed(last)
            if self.checksum:
                last = self._wrong_crc(last)
            last = self._broken(last)
            if self.profile == "rprs":
                last = self._left_out(last)
                last = self._three(last)
            self._silence(last)
            stopped = False
        except ConformanceError as exc:
            shared = exc.shared
            self.report.stopped = str(exc)
            raise
        finally:
            self.link.close()
            if self.misses:
                theirs = [m for m in self.misses if not m.startswith("ours")]
                self.report.notes.append(
                    f"turns missed: {len(theirs)} of the robot's (we took each over, as a "
                    f"member of the ring does), {len(self.misses) - len(theirs)} of ours; "
                    f"turns after a miss are not timed: " + "; ".join(self.misses[:5]) +
                    ("; ..." if len(self.misses) > 5 else ""))
            frames = [h for h in self.heard if h.frame.src == self.robot]
            why = f"; the first failed at {self.first_failure}" if self.first_failure else ""
            t0 = self._secs()
            # a run that stopped before any frame, good or failed, has nothing to judge
            ours = (f", {self.collided} broken in a collision with ours (not judged)"
                    if self.collided else "")
            if shared:      # failed frames may be anyone's: the robot is not judged on them
                self.check("15", "every frame from the robot is a good frame", False,
                           "the channel is not a ring of two: failed frames may be the "
                           "other stations'", t0, applicable=False)
            else:
                self.check("15", "every frame from the robot is a good frame",
                           self.bad == 0 and bool(frames),
                           f"{len(frames)} good frames, {self.bad} failed frames{ours}, "
                           f"{self.garbage} garbage bytes{why}" + (
                               ": the run stopped before the robot sent a frame"
                               if stopped and not frames and not self.bad else ""), t0,
                           applicable=not (stopped and not frames and not self.bad))
            if self.checksum and frames and not shared:
                self.check("20", "every frame from the robot ends with a right crc(NNNNN)",
                           not self.crc_bad,
                           f"{len(frames)} frames, {len(self.crc_bad)} not: "
                           f"{'; '.join(self.crc_bad[:3])}" if self.crc_bad else
                           f"{len(frames)} frames, all right", t0)
            if self.key is not None and frames and not shared:
                self.check("52", "every frame from the robot has a right tag and a rising "
                           "freshness value", not self.auth_bad,
                           f"{len(frames)} frames, {len(self.auth_bad)} not: "
                           f"{'; '.join(self.auth_bad[:3])}" if self.auth_bad else
                           f"{len(frames)} frames, all right", t0)
        return self.report

    def _turn_at(self, h: Heard) -> int:
        """When our turn after the robot's frame ``h`` lets our Header begin: Ttrans after
        its End, or later where the ring puts a turn between (called once per frame):

        - rprs: ``h`` invites an absent robot (clause 33): its window runs to E + Twin, and a
          frame of ours in it is out of turn (clause 39, refused with the acks it carries);
        - paper: the static ring holds the robot's whole team; the first absent robot after
          it keeps its turn until it has missed three (clauses 24, 25), and we send at its
          takeover, E + Tmax + Ttrans, in the next one's turn (the paper profile accepts
          whoever sends). Sent at once, our frame would follow the robot's before its
          successor's turn, which the paper profile takes for a collision (twice: the robot
          goes to LISTEN); sent after every absent robot's takeover, it lets the robot count
          more misses in a row without a good frame, and the cut-off (clause 40) comes
          sooner."""
        if self.profile == "rprs":
            try:
                cmds = parse_content(h.frame.content) if h.frame.content else []
            except ContentError:
                cmds = []
            if any(c.name == "poll" and c.args[0] not in (self.me, self.robot) for c in cmds):
                return h.end + TWIN + TTRANS
            return h.end + TTRANS
        between = [i for i, n in self.absent.items() if n < 3 and
                   _succ(self.robot, (self.robot, self.me, i)) == i]
        if not between:
            return h.end + TTRANS
        first = min(between, key=lambda i: (i - self.robot) % 7)
        self.absent[first] += 1
        return h.end + TMAX + TTRANS

    def _answer_turn(self, h: Heard, content: bytes = b"", **kw) -> int:
        """Our turn after the robot's frame ``h`` (:meth:`_turn_at`)."""
        return self.send(self.frame(content + self._acks_content(), **kw), self._turn_at(h))

    def _note_acks(self, h: Heard) -> None:
        """Acknowledge what the robot sent that needs it (rprs: BOOT, JOIN, messages to us)."""
        f = h.frame
        if self.profile != "rprs":
            return
        if f.type in (5, 6):
            self.acks.append((f.src, f.num))
        elif f.dst in (self.me, BROADCAST) and f.content and _app(f.content):
            self.acks.append((f.src, f.num))

    def _turns(self, h: Heard, n: int, first: tuple[bytes, dict] | None = None,
               on_frame: Callable[[Heard, int], None] | None = None,
               until_acked: bytes | None = None) -> Heard:
        """``n`` hand-overs from the robot's frame ``h``: our frame (the first one carrying
        ``first``: Content and fields), then its next; ``on_frame(h, i)`` sees each of its
        frames. ``until_acked``: ``first`` (a message with its Number in its fields) goes out
        again in each of our turns until a frame of the robot carries these bytes (its
        acknowledgement), as a station retransmits a message whose frame the robot did not
        hear (a busy host loses one now and then). Returns its last frame, not yet
        answered."""
        pending = first is not None
        for i in range(n):
            self._note_acks(h)
            content, kw = first if (first and pending) else (b"", {})
            content += self._acks_content()
            h, _, self.after_miss = self._exchange(h, partial(self._encoded, content, **kw))
            pending = until_acked is not None and until_acked not in h.frame.content
            if on_frame is not None:
                on_frame(h, i)
        return h

    def _once_heard(self, h: Heard, data: bytes, name: str,
                    clause: str) -> tuple[Heard, int]:
        """In our turn after ``h``, ``data`` (a frame that breaks, or one to refuse) instead
        of our frame; the robot's next frame and our End before it. A turn missed after it
        leaves nothing to judge of it (we took the turn over with our plain frame): it is
        sent again in a later turn, up to ``MISS_LIMIT`` times; ``clause`` says why such a
        frame still closes our turn."""
        for _ in range(MISS_LIMIT):
            self._note_acks(h)
            acks = self._acks_content()
            nxt, end, missed = self._exchange(h, lambda: data,
                                              again=partial(self._encoded, acks))
            if not missed:
                return nxt, end
            h = nxt
        raise ConformanceError(f"robot {self.robot} missed its turn after {name} "
                               f"{MISS_LIMIT} times in a row (clause {clause}: such a frame "
                               f"still closes our turn, and the next is its)")

    REPLY_TURNS = 30
    """Turns we wait at most for the robot's reply to a status() (a busy PC, or a CAN side
    that waits for its submodules, can take longer than a few turns)."""

    def _until(self, h: Heard, seen: Callable[[], list], watch: Callable[[Heard, int], None],
               done: int = 6) -> Heard:
        """More turns from ``h`` (``done`` were taken), each of its frames shown to
        ``watch`` with its index, until ``seen()`` is not empty (at most ``REPLY_TURNS``)."""
        for k in range(done, done + self.REPLY_TURNS):
            if seen():
                break
            h = self._turns(h, 1, None, partial(_at_turn, watch, k))
        return h

    def _in_a_row(self, frames: Callable[[], list[bytes]]) -> Callable[[], bytes]:
        """``data`` for :meth:`_exchange` when this PC sends for more than one member in a
        turn: every frame ``frames()`` builds but the last put on air, each Header Ttrans
        after the End before it (the ring's rhythm); the last is returned, for
        :meth:`_exchange` to write."""
        def data() -> bytes:
            built = frames()
            for f in built[:-1]:
                end = self._write(f)
                while self.now() < end + TTRANS - self.lead:
                    self._poll_rx()
                    self.link.idle(POLL_SEND)
            return built[-1]
        return data

    PHANTOM = "a takeover half a Tmax early is out of turn: refused, not acted on"

    DROP = "drops a member a ring view leaves out that it counted missing too"

    SILENCES = 3
    """Times we fall silent at most, until the robot took three turns in a row for us."""

    # -- the steps (plain functions in their own modules, bound here) -------------------

    _start = joining._start
    _stops_announcing = joining._stops_announcing
    _invite = joining._invite
    _air = joining._air
    _paper_join = joining._paper_join
    _lone = joining._lone
    _rotation = joining._rotation
    _invitations = joining._invitations
    _late = joining._late

    _refused = refusals._refused
    _forged_tag = refusals._forged_tag
    _wrong_crc = refusals._wrong_crc
    _replayed = refusals._replayed
    _message = refusals._message
    _forged = refusals._forged
    _broken = refusals._broken
    _left_out = refusals._left_out

    _own_wrap = own_counter._own_wrap

    _ours_after = ring_of_three._ours_after
    _three_note = ring_of_three._three_note
    _acks_of = ring_of_three._acks_of
    _three_turn = ring_of_three._three_turn
    _three = ring_of_three._three
    _phantom = ring_of_three._phantom
    _cut_off = ring_of_three._cut_off
    _three_turns = ring_of_three._three_turns
    _drop_third = ring_of_three._drop_third

    _invites = silence._invites
    _silence = silence._silence
    _fall_silent = silence._fall_silent
    _dropped = silence._dropped
    _rejoin = silence._rejoin


def _refused_frame(f: Frame) -> Frame:
    """What a member makes of the robot's frame ``f`` that it refuses (a wrong tag, a stale
    freshness: clause 53): its timing and its Source, nothing it carries (a control frame,
    no Content)."""
    return Frame(dst=BROADCAST, src=f.src, num=f.num, type=FrameType.BROADCAST_INFO, content=b"")

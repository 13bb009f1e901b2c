"""The conformance kit: a PC in a ring of two with one robot under test, checking it against
docs/protocol.md clause by clause (``rprs conformance``; issue 11, item 3).

The tester is scripted, not a MAC: it plays one station (ID ``tester``) and, when a check needs
it, a forger. It invites the robot (profile ``rprs``) or starts the static ring (profile
``paper``), then runs the checks in order on the wall clock:

===========  ================================================================================
clause        what is checked, and the figure reported
===========  ================================================================================
15, 6-13      every frame from the robot is a good frame (bytes heard, frames, failures);
              a frame of the robot's that we stepped on (it broke while our frame, begun
              after its Header, was on air) is counted apart and not held against it
34, 29, 36    it answers an invitation with BOOT ('5', Number '00') or JOIN ('6') at
              E + Ttrans, and stops announcing once acknowledged (rprs); 29 is n/a (not
              applicable, JUnit "skipped") when the answer is not a BOOT frame
23            its Header begins Ttrans after our End (median and worst gap over the turns)
26            with our frames 300 ms late, still Ttrans after our End: it resynchronises
21            a frame with nothing to say is an empty heartbeat (or, rprs, a control frame)
32            it invites the absent team robots of its gap, one poll every P = 4 of its turns,
              in turn, with the ring's mask (rprs; n/a when its gap holds none)
47, 48        our message is acknowledged in its next frame; a retransmission (same Number)
              is acknowledged again but not acted on again (its status() answered once)
              (rprs); in the paper profile nothing is acknowledged
45            its reply to our next status() takes the Number after its first reply's (rprs)
38            a frame with a forged Source (a team robot outside the ring) is not acted on
              (rprs; n/a in the paper profile, which admits any team robot that sends)
20            with ``checksum``: our status() with a wrong crc(NNNNN) is not acted on; and
              every frame of the robot's ends with a right one
41, 15, 11    frames that break (a bad digit in the Number; Length 9999) are not acted on,
              and close our turn: the robot takes the next
44            ... after R-stagger: id x Tslot after the closure (rprs)
51            ... and its next frame tells its ring (ring(mask) or a poll's mask) (rprs)
51, 34, 49    our ring(mask) without its bit sends it back to LISTEN; invited, it answers
              JOIN (rprs)
24, 44        when we fall silent it takes the turn: Tmax after its own End, plus R-stagger and
              R-pair in a ring of two (rprs), or at its End + Tmax + Ttrans (paper)
25            after our third missed turn it drops us (its masks lack us; paper: its turns
              come at its lone cadence)
===========  ================================================================================

A turn the robot misses (a bench process starved past a Tslot listens for the ring again) is
taken over as a member of the ring does, and the run goes on: the frame after it is no sample
(another is taken); three missed turns in a row stop the run (clause 25).

Times are the arrival of bytes at this PC: a Header's start is estimated as its End minus its
bytes at 9600 bit/s, so every measured gap includes the port's latency; ``tolerance`` (default
15 ms) bounds the median hand-over, and twice that 9 hand-overs in 10. The robot must run
with the real-time margins (``rprs child`` does; a flashed board on a PC bench must too,
docs/bench.md) and a team that holds both IDs. The channel must carry only the two: a frame
from any other Source stops the run (nothing is judged then).
"""
from __future__ import annotations

import select
import statistics
import time
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Callable, Protocol
from xml.etree import ElementTree as ET

from firmware_model.radio.auth import AUTH_TEXT_LEN, check as auth_check, clock_freshness
from firmware_model.radio.auth import seal as auth_seal, strip as auth_strip
from firmware_model.radio.content import parse_content
from firmware_model.radio.deframer import Deframer, FrameFailed, FrameReceived, Garbage
from firmware_model.radio.errors import ContentError
from firmware_model.radio.frame import BROADCAST, HEADER, Frame
from firmware_model.radio.integrity import check as crc_check, seal as crc_seal
from firmware_model.timing import PC_BYTE_TICKS, TICK_HZ

from ..runner import REALTIME_MARGINS
from ..scripts import percentile
from ..serial_radio import open_port

MS = TICK_HZ // 1000
TTRANS = 5 * MS
TMAX = 600 * MS
TWIN = REALTIME_MARGINS["twin"]
TSLOT = REALTIME_MARGINS["tslot"]
QUIET_GAP = REALTIME_MARGINS["quiet_gap"]
BYTE = PC_BYTE_TICKS
MISS_LIMIT = 3
INVITE_EVERY = 4
"""P: a member invites an absent team robot of its gap in every P-th of its turns
(docs/protocol.md clause 5's table, clause 32)."""
POLL_WAIT = 3 * TICK_HZ // 10_000
"""How long the kit idles between looks at the air while it waits for a frame (0.3 ms)."""
POLL_SEND = 2 * TICK_HZ // 10_000
"""... and while it waits for the tick to send at (0.2 ms)."""


class TesterLink(Protocol):
    """The kit's radio and clock: the one seam between the scripted station and the world
    it runs in. :class:`SerialLink` is a serial port (or a radio-hub pty) on the wall clock,
    what ``rprs conformance`` uses; ``hil.bench.conformance_sim.SimLink`` is a station on the
    simulator's air, the robot under test a firmware model, in simulated time."""

    def now(self) -> int:
        """The tick now (16 MHz), counted from the link's start."""
        ...

    def read(self) -> list[tuple[bytes, int, int]]:
        """What was heard since the last read, as runs of back-to-back bytes: (bytes, the
        tick the first one was complete, ticks a byte)."""
        ...

    def write(self, data: bytes) -> int:
        """Put ``data`` on air now at the PC's byte time; the tick its first bit goes out."""
        ...

    def idle(self, ticks: int) -> None:
        """Let up to ``ticks`` pass (the wall clock waits, and may return early when a byte
        comes; a simulated world runs on): callers poll, and look at :meth:`now`."""
        ...

    def close(self) -> None:
        ...


class SerialLink:
    """The kit on serial port ``port`` and the wall clock: bytes are stamped when this PC
    reads them (the last one now, those before it a byte time apart). Reading never waits
    (a read that waited for a byte held the kit past the instant its turn was due, by up to
    the port's 50 ms timeout); :meth:`idle` waits for the time given or the next byte,
    whichever comes first, so bytes are read, and stamped, as they come."""

    def __init__(self, port: str) -> None:
        self.port = open_port(port)
        self.t0 = time.monotonic_ns()
        try:
            self._fd: int | None = self.port.fileno()
        except (AttributeError, OSError, ValueError):   # a port with no descriptor (a URL's)
            self._fd = None

    def now(self) -> int:
        return (time.monotonic_ns() - self.t0) * TICK_HZ // 1_000_000_000

    def read(self) -> list[tuple[bytes, int, int]]:
        waiting = self.port.in_waiting
        if not waiting:
            return []
        data = self.port.read(waiting)
        if not data:
            return []
        return [(data, self.now() - (len(data) - 1) * BYTE, BYTE)]

    def write(self, data: bytes) -> int:
        start = self.now()
        self.port.write(data)
        return start

    def idle(self, ticks: int) -> None:
        if self._fd is None:
            time.sleep(ticks / TICK_HZ)
        else:
            select.select([self._fd], [], [], ticks / TICK_HZ)

    def close(self) -> None:
        self.port.close()


@dataclass
class Check:
    """One verdict: the clause, what was checked, passed or not, and the measured figure.
    ``applicable`` False: nothing was there to check (a robot that answered with JOIN has no
    BOOT frame for clause 29); the verdict is ``n/a``, ``figure`` says why, and it counts as
    no failure."""

    clause: str
    name: str
    passed: bool
    figure: str
    seconds: float = 0.0
    applicable: bool = True

    @property
    def verdict(self) -> str:
        """``pass``, ``FAIL`` or ``n/a``."""
        return "n/a" if not self.applicable else "pass" if self.passed else "FAIL"


@dataclass
class Heard:
    frame: Frame
    start: int          # estimated tick the Header's first bit began
    end: int            # tick the End's last byte arrived


@dataclass
class Report:
    robot: int
    profile: str
    checks: list[Check] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)    # what no clause judges: missed turns

    @property
    def passed(self) -> bool:
        """Something was checked and every clause passed or was not applicable."""
        return any(c.applicable for c in self.checks) and \
            all(c.passed or not c.applicable for c in self.checks)

    def junit(self) -> bytes:
        """JUnit XML: one testcase per clause, a failure element where it failed, a skipped
        element with the reason where it was not applicable."""
        suite = ET.Element("testsuite", name=f"rprs conformance robot {self.robot} "
                           f"({self.profile})", tests=str(len(self.checks)),
                           failures=str(sum(c.verdict == "FAIL" for c in self.checks)),
                           skipped=str(sum(c.verdict == "n/a" for c in self.checks)))
        if self.notes:
            ET.SubElement(suite, "system-out").text = "\n".join(self.notes)
        for c in self.checks:
            case = ET.SubElement(suite, "testcase", classname=f"clause {c.clause}",
                                 name=c.name, time=f"{c.seconds:.3f}")
            ET.SubElement(case, "system-out").text = c.figure
            if c.verdict == "FAIL":
                ET.SubElement(case, "failure", message=c.figure)
            elif c.verdict == "n/a":
                ET.SubElement(case, "skipped", message=f"not applicable: {c.figure}")
        return ET.tostring(suite, encoding="utf-8", xml_declaration=True)


class ConformanceError(Exception):
    """The run could not go on (no answer at all, a port that broke): one line. ``shared``:
    it stopped because the channel carries other stations (nothing is judged then)."""

    def __init__(self, message: str, shared: bool = False) -> None:
        super().__init__(message)
        self.shared = shared


class Tester:
    """The scripted station on ``port`` (a serial port's name, or a :class:`TesterLink`)
    and the checks, run by :meth:`run`."""

    __test__ = False                  # not a pytest class
    key = None                        # the ring key (the authenticated profile), or None
    checksum = False                  # the checksum extension (clause 20)

    def __init__(self, port: str | TesterLink, robot: int, profile: str = "rprs",
                 tester: int | None = None, tolerance_ms: float = 15.0, turns: int = 20,
                 progress: Callable[[str], None] | None = None, key=None,
                 team: tuple[int, ...] = tuple(range(7)), checksum: bool = False) -> None:
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
        self.link: TesterLink = SerialLink(port) if isinstance(port, str) else port
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
        self.fresh = clock_freshness(time.time())   # our next freshness value
        self.rx_fresh: int | None = None  # the robot's last freshness value
        self.auth_bad: list[str] = []     # the robot's frames with a wrong tag or stale value
        self.checksum = checksum          # the checksum extension (clause 20)
        if checksum and (profile == "paper" or key is not None):
            raise ValueError("the checksum extension is for the rprs profile without "
                             "--auth-key (the tag vouches for every byte: one or the other)")
        self.crc_bad: list[str] = []      # the robot's frames without a right crc(NNNNN)
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
        checked (clauses 52-53); a frame that fails keeps its Content (it reads as
        unreadable) and is noted for clause 52's verdict."""
        assert self.key is not None       # (called only in an authenticated ring)
        fresh = auth_check(self.key, f)
        if fresh is None:
            self.auth_bad.append(f"Number {f.num:02d}: no valid tag")
            return f
        if self.rx_fresh is not None and fresh <= self.rx_fresh:
            self.auth_bad.append(f"Number {f.num:02d}: freshness {fresh:08x} after "
                                 f"{self.rx_fresh:08x}")
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
        while self.now() < at:
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

    def _refused(self, h: Heard, data: bytes, clause: str, name: str, num: int,
                 t0: float) -> Heard:
        """In our turn, ``data`` (status() for the robot with Number ``num``) instead of our
        frame: the robot must act on nothing in it (no ack, no status reply) and go on with
        the ring (clause 53: a failed frame, its turn closed uncertainly)."""
        nxt, end = self._once_heard(h, data, name)
        acted = []

        def watch(x: Heard, i: int) -> None:
            c = x.frame.content
            if f"ack({self.me},{num})".encode() in c or (x.frame.dst == self.me and
                                                        (b"joint(" in c or b"fail(" in c)):
                acted.append(i)
        watch(nxt, -1)
        h = self._turns(nxt, 3, None, watch)
        self.check(clause, name, not acted, f"its next frame {(nxt.start - end) / MS:.0f} ms "
                   f"after; frames acting on it: {len(acted)}", t0)
        return h

    def _forged_tag(self, h: Heard) -> Heard:
        """Our status() for the robot with a tag that is wrong by one digit."""
        t0 = self._secs()
        data = _last_digit_changed(self.frame(b"status()", dst=self.robot, type_=2,
                                             num=43).encode())
        return self._refused(h, data, "53", "a frame with a wrong tag is not acted on", 43, t0)

    def _wrong_crc(self, h: Heard) -> Heard:
        """Our status() for the robot with its checksum wrong in one digit (clauses 20, 43:
        a failed frame, its turn closed uncertainly)."""
        t0 = self._secs()
        data = _last_digit_changed(self.frame(b"status()", dst=self.robot, type_=2,
                                             num=44).encode())
        return self._refused(h, data, "20", "a frame with a wrong checksum is not acted on",
                             44, t0)

    def _replayed(self, h: Heard) -> Heard:
        """The very bytes of our first status() for the robot, sent again."""
        t0 = self._secs()
        first = next(d for d in self.sent if b"status()auth(" in d and
                     d[3] == 0x30 + self.robot)
        return self._refused(h, first, "53", "a replay of our earlier message is not acted "
                             "on", int(first[5:7]), t0)

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

    def _start(self) -> Heard:
        t0 = self._secs()
        if self.profile == "paper":
            h, first, turns = self._paper_join(t0)
            self.check("23", "joins the static ring (paper profile)", True,
                       f"its first frame {first:.1f} ms after our End; in step after "
                       f"{turns} turns", t0)
            return h
        # Listen before we invite: a live ring (a third station) turns at least every
        # Tmax + Ttrans, and our invitations would land in its turns.
        self.listen(TMAX + TTRANS + 2 * self.tol)
        h, end = self._invite(-1)
        f = h.frame
        gap = (h.start - end - TTRANS) / MS
        # One answer, one sample: judged like the 90th percentile of the hand-overs (twice
        # the tolerance), as one stall of this PC or the hub can make one stamp late.
        self.check("34", "answers an invitation Ttrans after its End", f.type in (5, 6) and
                   abs(gap) * MS <= 2 * self.tol, f"Type '{f.type}', Header {gap:+.1f} ms "
                   f"from E + Ttrans (tolerance {2 * self.tol / MS:g} ms)", t0)
        # clause 29 is about BOOT frames: a JOIN (or anything else) leaves nothing to check
        self.check("29", "a BOOT frame is Number '00'", f.num == 0,
                   f"Type '{f.type}', Number '{f.num:02d}'" + (
                       "" if f.type == 5 else ": not a BOOT frame"), t0,
                   applicable=f.type == 5)
        self._note_acks(h)
        t0 = self._secs()
        announcing = []

        def watch(h: Heard, i: int) -> None:
            if h.frame.type in (5, 6):
                announcing.append(i)
        h = self._turns(h, 4, None, watch)
        self.check("36", "stops its BOOT/JOIN once acknowledged", not announcing,
                   f"{len(announcing)} more BOOT/JOIN frames after our ack", t0)
        return h

    def _invite(self, since: int, mask: int | None = None) -> tuple[Heard, int]:
        """As a lone member, invite the robot (``poll(id,mask)``, clauses 31, 34) until it
        answers; its answer and our End before it. ``mask``: the ring our poll names (default
        us alone). A lone member's frame of its own is no answer: if we heard one after tick
        ``since``, our first invitation goes after its next frame.

        No invitation goes out while a frame of the robot's is arriving (its claim, clause 28,
        can begin as we stop listening; a lone member's frame as an invitation's window runs
        out): we wait for that frame and, if it is no answer, invite Ttrans after its End,
        in the lone member's pause. Sent on it, an invitation cut a frame of the signed
        robot (38.5 ms against a plain heartbeat's 14.6) and the run failed clause 15."""
        mask = 1 << self.me if mask is None else mask
        end, at = 0, self.now()
        lone = [x for x in self.heard if x.frame.src == self.robot and x.end > since]
        if lone:
            # It claimed the silent channel before us: a lone member, a frame every Twin +
            # id x Tslot (clause 31). Our first invitation goes Ttrans after one of its frames,
            # not onto the next; hearing it, the robot listens again, and answers the next.
            # (its poll and room to spare: 64 bytes, signed 87)
            nxt = self.wait_frame(lone[-1].end, TWIN + self.robot * TSLOT + TTRANS +
                                  self._air(50) + 2 * self.tol, self.robot)
            at = (nxt or lone[-1]).end + TTRANS
        broken = 0                         # invitations in a row answered by failed frames
        for _ in range(400):               # a lone member inviting the robot (clause 31, 34)
            at = max(self.now(), at, end + TWIN + self.me * TSLOT)
            h = self._arriving(at)
            if h is None:
                end = self.send(self.frame(b"poll(%d,%d)" % (self.robot, mask)), at)
                # Wait for an answer whose Header began as late as E + Twin to end (a BOOT
                # or JOIN, signed with the authenticated profile) and reach us: a late answer
                # is then measured (clause 34 fails with its offset), not run over by our
                # next invitation. (wait_frame counts from our End, still ahead while our
                # bytes leave.) A frame still arriving then is waited for.
                bad = self.bad
                h = self.wait_frame(end, TWIN + self._air(0) + 2 * self.tol, self.robot)
                while h is None and self._busy():
                    h = self.wait_frame(end, QUIET_GAP, self.robot)
                if h is not None and (h.frame.type in (5, 6) or
                                      _mask_of(h.frame) != 1 << self.robot):
                    break                  # its answer
            if h is not None:
                # No answer: a frame that was arriving when our invitation was due (its
                # claim, a BOOT), or a lone member's frame (its poll's mask only its own
                # bit) in the window, so it did not hear our invitation (hearing it, it
                # listens). Its next frame comes Twin + id x Tslot after this one: we invite
                # Ttrans after this one, in its pause.
                at = h.end + TTRANS
                continue
            broken = broken + 1 if self.bad > bad else 0
            if broken == 5:                # it answers, but no answer is a good frame
                raise ConformanceError(
                    f"robot {self.robot} answered 5 invitations in a row with failed frames "
                    f"(clause 15), the first failed at {self.first_failure}")
        else:
            self._mark, self._mark_collided = (0, 0, 0), 0
            raise self._quiet("answering our invitations (is it on the channel, listening, "
                              "with both IDs in its team?)")
        return h, end

    def _air(self, content: int) -> int:
        """Ticks a frame with ``content`` bytes of Content takes on air, signed (its
        ``auth(...)`` too) with the authenticated profile."""
        return (14 + content + (AUTH_TEXT_LEN if self.key is not None else 0)) * BYTE

    def _paper_join(self, t0: float, since: int = -1) -> tuple[Heard, float, int]:
        """Paper profile: join the robot's static ring (its frames after tick ``since``);
        its frame once it follows ours at once, the gap before its first answer (ms), the
        turns it took."""
        # The static ring of the robot's team: we take our turns; the robot must join the
        # rotation. Listen before we talk: a robot alone in the ring already takes its
        # turns (one a cycle, each absent robot's turn taken over at Tmax), so our first
        # frame comes in our turn after one of its frames (:meth:`_turn_at`) instead of
        # landing on one. Alone for a whole cycle it is cut off (clause 40) and listens
        # until Tclaim of silence: we listen that long (sending would keep it silent).
        n = len(self.absent) + 2
        listen = 3 * n * TMAX + 7 * TSLOT
        h, end = None, since
        for _ in range(3):
            h = self.wait_frame(end, listen, self.robot)
            if h is None:
                break
            h = self._lone(h, h.end + listen)
            end = self.send(self.frame(), self._turn_at(h))
            h = self.wait_frame(end, (len(self.absent) + 1) * TMAX + TTRANS + self._air(0) +
                                2 * self.tol, self.robot)
            if h is not None:
                break
        if h is None:
            self._mark, self._mark_collided = (0, 0, 0), 0
            raise self._quiet(f"in its static ring (team of {n}) in {listen / MS / 1000:.1f}"
                              f" s of listening, or after our frame, three times")
        first = (h.start - end) / MS
        # The static ring is the whole team: until the robot has dropped every absent
        # team robot between us (three misses each, Tmax apart), its turn after ours
        # comes a takeover or more late. The timing checks begin once it follows our
        # frames at once three times in a row.
        prompt, turns, missed = 0, 0, 0
        while prompt < 3:
            if turns == 40:
                self.check("23", "joins the static ring (paper profile)", False,
                           f"its first frame {first:.1f} ms after our End; not in step "
                           f"(3 prompt turns in a row) after 40 turns", t0)
                raise ConformanceError(f"robot {self.robot} did not settle into the "
                                       f"static ring with us in 40 turns")
            end = self._answer_turn(h)
            nxt = self.wait_frame(end, 7 * TMAX, self.robot)
            turns += 1
            if nxt is None:              # it missed its turn: ours again (a takeover)
                missed += 1
                self.misses.append(f"after our frame ending at {end / MS:.0f} ms, "
                                   f"joining the static ring")
                if missed == MISS_LIMIT:
                    raise self._quiet("in its turn after ours, while joining the static "
                                      f"ring, {MISS_LIMIT} times in a row")
                prompt = 0
                continue
            h, missed = nxt, 0
            prompt = prompt + 1 if h.start - end < TMAX // 2 else 0
        return h, first, turns

    def _lone(self, h: Heard, until: int) -> Heard:
        """Paper profile, before our first frame: listen (to tick ``until`` at most) until
        the robot runs alone in its static ring; its frame to answer. While the ring holds
        other members (the absent team robots, and us) it waits Tmax for each before its
        next frame, and a robot alone drops them all in the same round, after three rounds
        (docs/protocol.md §9.1): from then on its frames come at its lone pause, Twin + id x
        Tslot, sooner than Tmax. Once such a frame came, every absent robot is dropped and
        our turn is at once after its frame. If it never did by ``until``, its last frame:
        we take our turns after the absent robots' takeovers (:meth:`_turn_at`), which
        holds only if the robot had counted no miss of theirs before we started. (The kit
        once sent after the first frame it heard: a robot that had counted misses before
        the kit started dropped the absent robots sooner than the kit counted, took our
        turn over at the instant our frame began, dropped us after three such collisions
        and, hearing us again, listened for good: the paper has no rejoin.)"""
        while any(n < 3 for n in self.absent.values()):
            nxt = self.wait_frame(h.end, max(0, until - max(self.now(), h.end)), self.robot)
            if nxt is None:
                return h
            if nxt.start - h.end < TMAX:
                for i in self.absent:
                    self.absent[i] = 3
            h = nxt
        return h

    def _rotation(self, h: Heard) -> Heard:
        t0 = self._secs()
        gaps, kinds = [], set()
        polls: list[tuple[list[tuple[int, int]], bool]] = []   # each frame's, after a miss

        def watch(h: Heard, i: int) -> None:
            if not self.after_miss:          # after a missed turn: no hand-over to time
                gaps.append(h.start - self.last_end - TTRANS)
            kinds.add(_kind(h.frame))
            polls.append((_polls_of(h.frame), self.after_miss))
        for _ in range(3):                   # until as many hand-overs as asked are timed
            h = self._turns(h, self.turns - len(gaps), None, watch)
            if len(gaps) >= self.turns:
                break
        if not gaps:
            raise ConformanceError(f"robot {self.robot}: no hand-over to time, it missed "
                                   f"turns throughout")
        med, worst = statistics.median(gaps) / MS, max(gaps, key=abs) / MS
        p90 = percentile([abs(g) for g in gaps], 90) / MS
        # The median and 9 turns in 10 are judged: one late turn in a run can be this PC or
        # the hub descheduled (a stalled frame the robot rightly abandons), not the robot.
        self.check("23", "hands over: its Header Ttrans after our End",
                   abs(med) * MS <= self.tol and p90 * MS <= 2 * self.tol,
                   f"{len(gaps)} turns, Header {med:+.1f} ms (median), {p90:.1f} ms (90th "
                   f"percentile, absolute), {worst:+.1f} ms (worst) from E + Ttrans; tolerance "
                   f"{self.tol / MS:g} ms (median), {2 * self.tol / MS:g} ms (90th)", t0)
        allowed = {"heartbeat", "control"} if self.profile == "rprs" else {"heartbeat"}
        self.check("21", "nothing to say: an empty heartbeat" + (" or a control frame"
                   if self.profile == "rprs" else ""), kinds <= allowed,
                   f"frame kinds: {', '.join(sorted(kinds))}", t0)
        if self.profile == "rprs":
            self._invitations(polls, t0)
        return h

    def _invitations(self, frames: list[tuple[list[tuple[int, int]], bool]],
                     t0: float) -> None:
        """Clause 32 on the robot's frames of the hand-overs (``frames``: each frame's
        ``poll(k,mask)`` and whether a missed turn came before it): it invites the absent
        team robots of its gap (the IDs after it, before us), one in every P-th of its turns,
        in turn (ascending, wrapping), each with the ring's mask (it and us), at most one a
        frame. Spacings across a missed turn are not judged."""
        name = "invites the absent team robots of its gap, one every P = 4 of its turns"
        gap, i = [], (self.robot + 1) % 7
        while i != self.me:
            if i in self.team:
                gap.append(i)
            i = (i + 1) % 7
        if not gap:
            self.check("32", name, True, "nothing to invite: no team robot between it and us "
                       "(its gap)", t0, applicable=False)
            return
        mask = (1 << self.robot) | (1 << self.me)
        at = [n for n, (p, _) in enumerate(frames) if p]
        invited = [p[0][0] for p, _ in frames if p]
        spacings = [b - a for a, b in zip(at, at[1:])
                    if not any(frames[j][1] for j in range(a + 1, b + 1))]
        wrong: list[str] = []
        if len(at) < 2:
            wrong.append(f"{len(at)} invitation{'s' if len(at) != 1 else ''} in "
                         f"{len(frames)} of its turns (was this kit given the robot's own "
                         f"--team? it was told {','.join(map(str, self.team))})")
        if any(len(p) > 1 for p, _ in frames):
            wrong.append("more than one poll in a frame")
        strays = sorted({k for p, _ in frames for k, _ in p if k not in gap})
        if strays:
            wrong.append(f"invited {', '.join(map(str, strays))}, outside its gap's absent "
                         f"team robots")
        masks = sorted({m for p, _ in frames for _, m in p if m != mask})
        if masks:
            wrong.append(f"mask {masks[0]}, not {mask} (it and us)")
        if any(sp != INVITE_EVERY for sp in spacings):
            wrong.append(f"invitations {', '.join(map(str, spacings))} turns apart, not "
                         f"every {INVITE_EVERY}")
        if any(a in gap and b != gap[(gap.index(a) + 1) % len(gap)]
               for a, b in zip(invited, invited[1:])):
            wrong.append("not in turn (ascending, wrapping)")
        seen = (f"{len(frames)} turns: invited {', '.join(map(str, invited)) or 'nobody'} "
                f"of its gap's {', '.join(map(str, gap))}")
        self.check("32", name, not wrong,
                   f"{seen}; " + "; ".join(wrong) if wrong else
                   f"{seen}, every {INVITE_EVERY} turns, mask {mask}", t0)

    def _late(self, h: Heard) -> Heard:
        """Our frames 300 ms late (within Tmax): the robot must time its turn from the End of
        the frame it heard, not from its own clock (clause 26: resynchronise on every frame)."""
        t0 = self._secs()
        gaps = []
        for _ in range(3 * MISS_LIMIT):
            self._note_acks(h)
            content = self._acks_content()
            h, end, missed = self._exchange(h, partial(self._encoded, content),
                                            at=self._turn_at(h) + 300 * MS)
            if not missed:                   # after a missed turn: no sample
                gaps.append(h.start - end - TTRANS)
            if len(gaps) == 3:
                break
        if not gaps:
            raise ConformanceError(f"robot {self.robot} missed its turn after each of our "
                                   f"late frames ({3 * MISS_LIMIT})")
        med = statistics.median(gaps) / MS
        self.check("26", "times its turn from the End it heard (our frames 300 ms late)",
                   abs(med) * MS <= self.tol, f"Header {med:+.1f} ms (median of "
                   f"{len(gaps)}) from our late End + Ttrans", t0)
        return h

    def _turns(self, h: Heard, n: int, first: tuple[bytes, dict] | None = None,
               on_frame: Callable[[Heard, int], None] | None = None) -> Heard:
        """``n`` hand-overs from the robot's frame ``h``: our frame (the first one carrying
        ``first``: Content and fields), then its next; ``on_frame(h, i)`` sees each of its
        frames. Returns its last frame, not yet answered."""
        for i in range(n):
            self._note_acks(h)
            content, kw = first if (first and i == 0) else (b"", {})
            content += self._acks_content()
            h, _, self.after_miss = self._exchange(h, partial(self._encoded, content, **kw))
            if on_frame is not None:
                on_frame(h, i)
        return h

    def _once_heard(self, h: Heard, data: bytes, name: str) -> tuple[Heard, int]:
        """In our turn after ``h``, ``data`` (a frame that breaks, or one to refuse) instead
        of our frame; the robot's next frame and our End before it. A turn missed after it
        leaves nothing to judge of it (we took the turn over with our plain frame): it is
        sent again in a later turn, up to ``MISS_LIMIT`` times."""
        for _ in range(MISS_LIMIT):
            self._note_acks(h)
            acks = self._acks_content()
            nxt, end, missed = self._exchange(h, lambda: data,
                                              again=partial(self._encoded, acks))
            if not missed:
                return nxt, end
            h = nxt
        raise ConformanceError(f"robot {self.robot} missed its turn after {name} "
                               f"{MISS_LIMIT} times in a row (clause 41: a frame that breaks "
                               f"closes our turn, and the next is its)")

    def _message(self, h: Heard) -> Heard:
        """Our status() to the robot, then the same message again (a retransmission), then a
        new one. rprs: they are Numbers 99 and 00, so the robot must take the wrap of our
        counter ('99' then '00', clause 45) for a new message (clause 48), not a duplicate."""
        t0 = self._secs()
        if self.profile == "rprs":
            self.num = 98                 # a station that has sent 98 messages since power-on
        self.num = (self.num + 1) % 100
        num = self.num
        ack = f"ack({self.me},{num})".encode()
        seen: dict[str, list] = {"acked": [], "replies": [], "again": []}

        def watch(h: Heard, i: int) -> None:
            if ack in h.frame.content:
                seen["acked"].append(i)
            if h.frame.dst == self.me and (b"joint(" in h.frame.content or
                                           b"fail(" in h.frame.content) and \
                    h.frame.num not in seen["replies"][-1:]:
                # the status, or why there is none; the same Number again is its message
                # retransmitted (our ack was lost to it, e.g. while it stalled), no new reply
                seen["replies"].append(h.frame.num)
            elif h.frame.dst == self.me and (b"joint(" in h.frame.content or
                                             b"fail(" in h.frame.content):
                seen["again"].append(h.frame.num)
        ask = (b"status()", {"dst": self.robot, "type_": 2})
        h = self._turns(h, 6, ask, watch)
        if self.profile == "rprs":       # (the paper has no status(): none is awaited)
            h = self._until(h, lambda: seen["replies"], watch)
        acked, replies = seen["acked"], list(seen["replies"])
        if self.profile == "paper":
            self.check("47", "paper profile: nothing is acknowledged", not acked,
                       f"acks: {len(acked)}; status() answered {len(replies)} time(s) (the "
                       f"paper has no status(): not required)", t0)
            return h
        self.check("47", "acknowledges our message in its next frame", acked[:1] == [0],
                   "ack in its next frame" if acked[:1] == [0] else
                   f"first ack in its frame {acked[0] + 1}" if acked else "no ack", t0)
        t0 = self._secs()
        seen["acked"].clear()
        h = self._turns(h, 4, (b"status()", {"dst": self.robot, "type_": 2, "num": num}),
                        watch)
        more = len(seen["replies"]) - len(replies)
        self.check("48", "a retransmission is acknowledged again and not acted on again",
                   bool(seen["acked"]) and more == 0 and len(replies) == 1,
                   f"re-acknowledged: {'yes' if seen['acked'] else 'no'}; status replies: "
                   f"{len(replies)}, then {more} more", t0)
        # A new message (the next Number): its reply is a new message of the robot's, with
        # the Number after its first reply's (clause 45), which we acknowledge.
        t0 = self._secs()
        self.num = (self.num + 1) % 100
        before = list(seen["replies"])
        h = self._turns(h, 6, (b"status()", {"dst": self.robot, "type_": 2}), watch)
        h = self._until(h, lambda: seen["replies"][len(before):], watch)
        new = seen["replies"][len(before):]
        ok = len(before) == 1 and len(new) == 1 and new[0] == (before[0] + 1) % 100
        again = seen["again"]
        self.check("45", "its next message takes the next Number (ours wrapped, 99 then 00)",
                   ok, f"its replies' Numbers: {', '.join(f'{n:02d}' for n in before + new)}, "
                   f"to our {num:02d} and {self.num:02d}" +
                   (f" (sent again: {', '.join(f'{n:02d}' for n in again)})" if again else "") +
                   ("" if new else f"; no new reply in {6 + self.REPLY_TURNS} turns"), t0)
        return h

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

    def _forged(self, h: Heard) -> Heard:
        """In our turn, first a frame from a forger (a team robot outside the ring) carrying
        status() for the robot, then our own frame: the robot must refuse the forged one."""
        t0 = self._secs()
        if self.profile == "paper":
            self.check("38", "a forged Source is refused", True, "the paper profile admits "
                       "any team robot that sends (docs/protocol.md §9.1)", t0,
                       applicable=False)
            return h
        self._note_acks(h)
        forged = self.frame(b"status()", dst=self.robot, type_=2, num=42,
                            src=self.forger).encode()
        acks = self._acks_content()
        ours = self.frame(acks).encode()
        # A team robot outside the ring still sets the timing (clause 38.3): the next turn is
        # succ(forger) in the ring {us, robot}. Ours when the forger lies between the robot
        # and us in ring order (then our frame follows the forged one); else the robot's, and
        # we leave it its turn: sending ours as well would collide with its rightful frame.
        if _succ(self.forger, (self.me, self.robot)) == self.me:
            # the forged frame first, ours Ttrans after it
            h, _, _ = self._exchange(h, self._in_a_row(lambda: [forged, ours]),
                                     again=lambda: ours)
        else:
            h, _, _ = self._exchange(h, lambda: forged, again=lambda: ours)
        bad = f"ack({self.forger},42)".encode()
        acted = []

        def watch(h: Heard, i: int) -> None:
            if bad in h.frame.content or (h.frame.dst == self.forger and h.frame.content):
                acted.append(i)
        watch(h, -1)
        h = self._turns(h, 4, None, watch)
        self.check("38", f"a forged Source ({self.forger}, outside the ring) is not acted on",
                   not acted, f"{len(acted)} of its frames acted on it", t0)
        return h

    def _broken(self, h: Heard) -> Heard:
        """In our turn, instead of our frame, a frame that breaks: status() for the robot with
        a bad digit in its Number, then (next turn) with a Length beyond the protocol's bound.
        Neither may be acted on (clauses 15, 11, 43), and each still closes our turn (41): the
        robot takes the next one."""
        t0 = self._secs()
        good = self.frame(b"status()", dst=self.robot, type_=2, num=77).encode()
        bad_digit = good[:5] + b"x" + good[6:]                        # Number '7x'
        oversize = good[:8] + b"9999" + good[12:]                      # Length 9999
        acted, figures, staggers = 0, [], []
        told: list[int | None] = []          # the mask its next frame gave, each time
        for name, data in (("a bad Number digit", bad_digit), ("Length 9999", oversize)):
            try:
                nxt, end = self._once_heard(h, data, f"a frame with {name}")
            except ConformanceError:
                self.check("41", "a frame that breaks is not acted on and closes the turn",
                           False, f"after {name}: it missed its turn {MISS_LIMIT} times", t0)
                raise
            figures.append(f"{name}: its next frame {(nxt.start - end) / MS:.0f} ms after")
            staggers.append(nxt.start - end - (QUIET_GAP + self.robot * TSLOT + TTRANS))
            told.append(_mask_of(nxt.frame))
            h = nxt
            watch_acts: list[int] = []

            def watch(x: Heard, i: int, acts: list[int] = watch_acts) -> None:
                c = x.frame.content
                if f"ack({self.me},77)".encode() in c or (x.frame.dst == self.me and
                                                          b"joint(" in c):
                    acts.append(i)
            watch(h, -1)
            h = self._turns(h, 3, None, watch)
            acted += len(watch_acts)
        self.check("41", "frames that break (bad digit, oversize Length) are not acted on and "
                   "close the turn", acted == 0, "; ".join(figures) + f"; frames acting on "
                   f"them: {acted}", t0)
        # Each closure is uncertain: the turn closes when our bytes stop (the quiet and stall
        # gaps are equal in the real-time set) and the robot waits id x Tslot more (R-stagger,
        # clause 44). One of the two on time is enough: a stall of this PC delays one stamp;
        # a robot without R-stagger comes id x Tslot early both times.
        offs = [o / MS for o in staggers]
        if self.profile == "rprs":
            self.check("44", "after a frame that broke, waits R-stagger (id x Tslot)",
                       min(abs(o) for o in offs) * MS <= 2 * self.tol,
                       f"its Header {', '.join(f'{o:+.1f}' for o in offs)} ms from our End + "
                       f"quiet gap + {self.robot} x Tslot + Ttrans; tolerance "
                       f"{2 * self.tol / MS:g} ms", t0)
            # a failed frame in a turn: its view may differ, so its next frame tells its ring
            # (clause 51.1-2: ring(mask), or a poll, whose mask tells the same)
            mask = (1 << self.robot) | (1 << self.me)
            self.check("51", "after a failed frame it tells its ring in its next frame",
                       all(m == mask for m in told),
                       "masks in its next frames: " + ", ".join(
                           "none" if m is None else str(m) for m in told) +
                       f" (its ring, it and us: {mask})", t0)
        return h

    def _left_out(self, h: Heard) -> Heard:
        """Our frame carries ``ring(mask)`` without the robot's bit (our ring: us alone): it
        has been dropped by us and goes back to LISTEN, sending nothing in its turn (clause
        51.3); invited, it answers with JOIN, as a station that left and did not power off
        (clauses 34, 49), which we acknowledge, and the ring goes on."""
        t0 = self._secs()
        name = "a mask without its bit sends it back to LISTEN; invited, it answers JOIN"
        mask = 1 << self.me
        not_answers: list[int] = []
        for _ in range(MISS_LIMIT):
            self._note_acks(h)
            end = self.send(self.frame(self._acks_content() + b"ring(%d)" % mask),
                            self._turn_at(h))
            # a member would take its turn at our End + Ttrans: Tmax is more than enough to
            # see it (and less than a lone listener's claim wait, so it does not claim)
            kept = self.wait_frame(end, TMAX + 2 * self.tol, self.robot)
            if kept is not None:
                self.check("51", name, False, f"it kept its turn: its frame "
                           f"{(kept.start - end) / MS:.0f} ms after our ring({mask})", t0)
                return kept
            answer, _ = self._invite(self.now())
            if answer.frame.type in (5, 6):
                break
            # a member's frame, not an answer: it did not hear our ring (a robot on a busy PC
            # stalled through it, and resynchronised on our invitation); once more
            not_answers.append(answer.frame.type)
            h = answer
        kind = {5: "BOOT", 6: "JOIN"}.get(answer.frame.type, "no BOOT or JOIN")
        again = (f" (before that, {len(not_answers)} frame(s) of a member, Type "
                 f"{', '.join(repr(str(t)) for t in not_answers)}: it had not heard our ring; "
                 f"our ring sent again)" if not_answers else "")
        h = self._turns(answer, 4)                # acknowledged: back in the ring
        self.check("51", name, answer.frame.type == 6,
                   f"silent after our ring({mask}); answered our invitation with Type "
                   f"'{answer.frame.type}' ({kind}){again}", t0)
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
                while self.now() < end + TTRANS:
                    self._poll_rx()
                    self.link.idle(POLL_SEND)
            return built[-1]
        return data

    def _ours_after(self, ring: tuple[int, ...], src: int) -> list[int]:
        """The members this PC plays (us, and the third member) whose turns follow a frame
        from ``src`` in ``ring``, up to the robot's."""
        out, x = [], _succ(src, ring)
        while x != self.robot and x not in out:
            out.append(x)
            x = _succ(x, ring)
        return out

    def _three_note(self, h: Heard) -> None:
        """Acknowledgements the robot's frame ``h`` needs: ours (:meth:`_note_acks`) and the
        third member's (a message for it, or for every member)."""
        self._note_acks(h)
        f = h.frame
        if f.type in (5, 6) or (f.dst in (self.third, BROADCAST) and f.content and
                                _app(f.content)):
            self.third_acks.append((f.src, f.num))

    def _three_turn(self, h: Heard, ring: tuple[int, ...], first: dict[int, bytes],
                    watch: Callable[[Heard, int], None], i: int) -> Heard:
        """Our frames after the robot's frame ``h`` in ``ring`` (each member we play, in
        turn; ``first``: Content a member's frame carries this turn), then the robot's
        next frame, shown to ``watch`` as ``i``."""
        self._three_note(h)

        def frames() -> list[bytes]:
            out = []
            for m in self._ours_after(ring, h.frame.src):
                acks = self._acks_content() if m == self.me else b"".join(
                    b"ack(%d,%d)" % a for a in self.third_acks)
                if m != self.me:
                    self.third_acks.clear()
                content = first.get(m, b"") + acks
                kw: dict[str, Any] = {"src": m}
                if m == self.third:
                    # T's one message is Number 01; its other frames repeat the Number of
                    # the last message it sent, '00' before any (clause 45)
                    if b"status()" in content:
                        self.third_num = 1
                        kw.update(dst=self.robot, type_=2)
                    kw["num"] = self.third_num
                out.append(self.frame(content, **kw).encode())
            return out
        h, _, self.after_miss = self._exchange(h, self._in_a_row(frames))
        watch(h, i)
        return h

    def _three(self, h: Heard) -> Heard:
        """A ring of three: this PC plays a third member, T (a team robot of the robot's,
        neither us nor it), beside its own ID.

        * Clause 51.3: our frame carries ``ring(mask)`` with T's bit. The robot admits T
          (we vouch for it) and keeps T's turn from then on: T's frames, in its turns, carry
          ``status()`` for the robot, which it acknowledges and answers as a member's.
        * Clause 39, a phantom takeover: of the two turns after the robot's, the first (ours
          or T's) stays silent and the second's frame comes half a Tmax in, with
          ``status()`` for the robot: too early for a takeover (0.95 Tmax), so it is out of
          turn: refused, nothing in it acted on (no acknowledgement, no reply), and the next
          turn is the robot's.
        * Clause 40: then neither we nor T send. The robot misses both turns, takes its own,
          misses the next: max(3, n - 1) = 3 misses with no good frame heard in a ring of
          three, before any member has missed three (clause 25), so it concludes its radio
          is cut off and goes to LISTEN: no frame of its where its next turn would be
          (within 2 Tmax + 8 Tslot), and it answers our invitation, with JOIN. The
          invitation names T too: the ring of three again.
        * Clause 51.3, the drop: T misses a turn, and our next frame carries ``ring(mask)``
          without T. The robot counted that miss too, so it drops T: its next frame tells the
          ring of two (the miss made its view one that may differ, 51.1), and comes at our End
          + Ttrans. A robot that kept T tells the ring of three.

        ``n/a`` when its team has no robot besides it and us (``--team 0,ID``)."""
        t0 = self._secs()
        t = self.third
        if t is None:
            why = f"its team {self.team} has no robot besides it and us to play as a third"
            self.check("51", "admits the robot a ring view names, and keeps its turn", True,
                       why, t0, applicable=False)
            self.check("40", "cut off: 3 misses with nothing heard in a ring of three "
                       "send it to LISTEN", True, why, t0, applicable=False)
            self.check("51", self.DROP, True, why, t0, applicable=False)
            self.check("39", self.PHANTOM, True, why, t0, applicable=False)
            return h
        ring = tuple(sorted((self.me, self.robot, t)))
        mask = sum(1 << i for i in ring)
        acked: list[int] = []
        replies: list[int] = []
        masks: list[int | None] = []
        ack = f"ack({t},1)".encode()

        def watch(x: Heard, i: int) -> None:
            c = x.frame.content
            if ack in c:
                acked.append(i)
            if x.frame.dst == t and (b"joint(" in c or b"fail(" in c) and \
                    x.frame.num not in replies[-1:]:
                replies.append(x.frame.num)
            masks.append(_mask_of(x.frame))
        # our ring(mask) in our turn of the ring of two; if T's turn follows ours in the ring
        # of three, T's frame follows it, as the robot now waits for T
        self._three_note(h)

        def vouch() -> list[bytes]:
            out = [self.frame(self._acks_content() + b"ring(%d)" % mask).encode()]
            if _succ(self.me, ring) == t:
                out.append(self.frame(src=t, num=self.third_num).encode())
            return out
        h, _, _ = self._exchange(h, self._in_a_row(vouch))
        watch(h, 0)
        h = self._three_turn(h, ring, {t: b"status()"}, watch, 1)
        for i in range(2, 2 + self.REPLY_TURNS):
            if acked and replies and i >= 5:
                break
            h = self._three_turn(h, ring, {}, watch, i)
        told = sorted({m for m in masks if m is not None})
        self.check("51", f"admits the robot a ring view names (T = {t}), and keeps its turn",
                   bool(acked) and bool(replies) and acked[0] <= 2,
                   (f"T's status() acknowledged in its frame {acked[0]} after T's" if acked
                    else "T's status() never acknowledged") +
                   f"; replies to T: {len(replies)}; masks in its frames: "
                   f"{', '.join(map(str, told)) or 'none'} (the ring of three: {mask})", t0)
        h = self._phantom(h, ring)
        h = self._cut_off(h, ring)
        return self._drop_third(h, ring)

    PHANTOM = "a takeover half a Tmax early is out of turn: refused, not acted on"

    def _phantom(self, h: Heard, ring: tuple[int, ...]) -> Heard:
        """Clause 39 in the ring of three (:meth:`_three`): the member after the robot is
        silent, and the next one's frame, ``status()`` for the robot, begins Tmax / 2 into
        that turn."""
        t0 = self._secs()
        silent, early = self._ours_after(ring, self.robot)
        if early == self.me:
            self.num = (self.num + 1) % 100
            num = self.num
        else:
            self.third_num += 1
            num = self.third_num
        self._three_note(h)

        def data() -> bytes:
            acks = self._acks_content() if early == self.me else b"".join(
                b"ack(%d,%d)" % a for a in self.third_acks)
            if early != self.me:
                self.third_acks.clear()
            return self.frame(b"status()" + acks, dst=self.robot, type_=2, num=num,
                              src=early).encode()
        nxt, end, _ = self._exchange(h, data, at=h.end + TTRANS + TMAX // 2)
        acted: list[int] = []
        bad = f"ack({early},{num})".encode()

        def watch(x: Heard, i: int) -> None:
            c = x.frame.content
            if bad in c or (x.frame.dst == early and (b"joint(" in c or b"fail(" in c)):
                acted.append(i)
        watch(nxt, 0)
        h = nxt
        for i in range(1, 4):
            h = self._three_turn(h, ring, {}, watch, i)
        self.check("39", self.PHANTOM, not acted,
                   f"{early}'s frame {TMAX // 2 / MS:.0f} ms into {silent}'s turn; its next "
                   f"frame {(nxt.start - end) / MS:.0f} ms after; frames acting on it: "
                   f"{len(acted)}", t0)
        return h

    def _cut_off(self, h: Heard, ring: tuple[int, ...]) -> Heard:
        """Clause 40 in the ring of three (:meth:`_three`): we and T fall silent after the
        robot's frame ``h``; then our invitation brings it back into the ring of three. The
        robot's frame after a few turns in it."""
        t0 = self._secs()
        name = "cut off: 3 misses with nothing heard in a ring of three send it to LISTEN"
        self._three_note(h)
        took = self.wait_frame(h.end, 2 * TMAX + 8 * TSLOT, self.robot)
        mask = sum(1 << i for i in ring if i != self.robot)
        if took is None:
            self.check("40", name, False, "it did not take its own turn after our and T's "
                       f"missed turns (nothing in {(2 * TMAX + 8 * TSLOT) / MS:.0f} ms)", t0)
            answer, _ = self._invite(self.now(), mask)
            return self._three_turns(answer, ring, 4)
        more = self.wait_frame(took.end, 2 * TMAX + 8 * TSLOT, self.robot)
        answer, _ = self._invite(self.now(), mask)
        kind = {5: "BOOT", 6: "JOIN"}.get(answer.frame.type, "no BOOT or JOIN")
        self.check("40", name, more is None and answer.frame.type == 6,
                   f"its takeover {(took.start - h.end) / MS:.0f} ms after its frame; then " +
                   ("nothing for " f"{(2 * TMAX + 8 * TSLOT) / MS:.0f} ms"
                    if more is None else f"its next frame {(more.start - took.end) / MS:.0f} "
                    f"ms after (still a member)") +
                   f"; answered our invitation with Type '{answer.frame.type}' ({kind})", t0)
        return self._three_turns(answer, ring, 4)

    def _three_turns(self, h: Heard, ring: tuple[int, ...], n: int) -> Heard:
        """``n`` rounds of the ring of three from the robot's frame ``h``: our frames and T's
        (acknowledging what needs it), then its next."""
        for i in range(n):
            h = self._three_turn(h, ring, {}, lambda x, k: None, i)
        return h

    DROP = "drops a member a ring view leaves out that it counted missing too"

    def _drop_third(self, h: Heard, ring: tuple[int, ...]) -> Heard:
        """Clause 51.3, the third rule (:meth:`_three`): T misses a turn, then our
        ``ring(mask)`` leaves it out; the robot's frame after ours must tell the ring of two."""
        t0 = self._secs()
        t = self.third
        mask = (1 << self.me) | (1 << self.robot)
        self._three_note(h)
        if _succ(self.robot, ring) == t:
            # T's turn first, and T is silent: we take the turn over at its start + Tmax, as
            # the next member does (clause 24), with our ring(mask)
            nxt, end, _ = self._exchange(h, lambda: self.frame(
                self._acks_content() + b"ring(%d)" % mask).encode(), at=h.end + TMAX + TTRANS)
        else:
            # our frame, then T's turn, silent: the robot counts the miss and takes its turn
            h = self._turns(h, 1)
            self._note_acks(h)
            nxt, end, _ = self._exchange(h, lambda: self.frame(
                self._acks_content() + b"ring(%d)" % mask).encode())
        told = _mask_of(nxt.frame)
        self.check("51", self.DROP, told == mask,
                   f"its frame {(nxt.start - end) / MS:.0f} ms after our ring({mask}) told "
                   f"{'no ring' if told is None else f'ring {told}'} (the ring of two: {mask}; "
                   f"of three: {sum(1 << i for i in ring)})", t0)
        return self._turns(nxt, 2)

    SILENCES = 3
    """Times we fall silent at most, until the robot took three turns in a row for us."""

    def _invites(self, f: Frame) -> bool:
        """``f`` invites a robot outside the ring of two (a ``poll(k,...)``, clause 32)."""
        return any(k not in (self.robot, self.me) for k, _ in _polls_of(f))

    def _silence(self, h: Heard) -> None:
        """We stop sending: the robot's takeovers, then our drop (clauses 24, 25, 44).

        Each of our three missed turns is a takeover by the robot, timed from the End before
        it. Clause 24 is judged on the median of the offsets: a stamp that came late
        because this PC stalled (one run measured +34.5 ms, then -34 ms on the next, as the
        late stamp shortened the following gap) does not decide it. A robot on a busy PC can
        be starved past a Tslot while alone and then listen for the ring (clause 5): it
        stops sending before it has dropped us. We then bring it back into the ring (an
        invitation, or in the paper profile our frame in its static ring) and fall silent
        again, up to ``SILENCES`` times: clause 24 is judged on every takeover measured (at
        least three), clause 25 on the first silence it kept turning through."""
        t0 = self._secs()
        if self.profile == "rprs":
            rule = "max(its End + Tmax + id x Tslot, our End + Tmax + our id x Tslot + Ttrans + " \
                   "4 B) + Ttrans (R-stagger, R-pair; its End + Twin after a frame of its that " \
                   "invited a robot, clause 33)"
        else:
            rule = "its End + Tmax + Ttrans"
        offs: list[float] = []
        fig25: tuple[bool, str] | None = None
        cut: list[int] = []                  # frames heard before the robot stopped, each time
        for attempt in range(self.SILENCES):
            frames = self._fall_silent(h)
            our_end = self.last_end
            if self.profile == "rprs":
                def expect(prev_end: int, our_end: int = our_end) -> int:
                    return max(prev_end + TMAX + self.robot * TSLOT,
                               our_end + TMAX + self.me * TSLOT + TTRANS + 4 * BYTE) + TTRANS
            else:
                def expect(prev_end: int, our_end: int = our_end) -> int:
                    return prev_end + TMAX + TTRANS
            # after a frame of its that invited a robot outside the ring our turn begins at
            # its End + Twin (clause 33), and its takeover of our turn counts from there
            offs += [(b.start - expect(a.end + (TWIN if self._invites(a.frame) else 0))) / MS
                     for a, b in zip(frames, frames[1:4])]
            if len(frames) == 7 and fig25 is None:
                fig25 = self._dropped(frames[1:])
            else:
                cut.append(len(frames) - 1)
            if len(offs) >= 3 and fig25 is not None:
                break
            if attempt < self.SILENCES - 1:
                self.progress(f"robot {self.robot} stopped sending after {len(frames) - 1} "
                              f"frames while we were silent: we bring it back and fall "
                              f"silent again")
                h = self._rejoin()
        stops = (f"; it stopped sending after {', '.join(map(str, cut))} frames in "
                 f"{len(cut)} of our silences" if cut else "")
        if not offs:
            self.check("24", "takes the turn when we fall silent", False, "no frame in "
                       f"{(2 * TMAX + 8 * TSLOT) / MS:.0f} ms" + stops, t0)
            return
        mid = statistics.median(offs)
        self.check("24", "takes the turn when we fall silent",
                   len(offs) >= 3 and abs(mid) * MS <= self.tol,
                   f"Header {mid:+.1f} ms (median of {len(offs)} takeovers: "
                   f"{', '.join(f'{o:+.1f}' for o in offs)}) from {rule}" + (
                       "" if len(offs) >= 3 else "; fewer than 3 takeovers") + stops, t0)
        t0 = self._secs()
        ok, fig = fig25 if fig25 is not None else (
            False, f"it never kept turning alone for 6 frames{stops}")
        self.check("25", "drops us after our third missed turn", ok, fig, t0)

    def _fall_silent(self, h: Heard) -> list[Heard]:
        """We send nothing more: the robot's frame ``h`` and up to six more, each within
        2 Tmax + 8 Tslot of the one before (fewer if it stops sending)."""
        frames = [h]
        for _ in range(6):
            nxt = self.wait_frame(frames[-1].end, 2 * TMAX + 8 * TSLOT, self.robot)
            if nxt is None:
                break
            frames.append(nxt)
        return frames

    def _dropped(self, after: list[Heard]) -> tuple[bool, str]:
        """Clause 25 on the robot's frames ``after`` we fell silent: passed, and the figure."""
        if self.profile == "rprs":
            masks = [_mask_of(f.frame) for f in after]
            lacks = [i for i, m in enumerate(masks) if m is not None and not m >> self.me & 1]
            ok = bool(lacks) and lacks[0] == 2
            return ok, (f"first frame whose mask lacks us: its frame {lacks[0] + 1} after we "
                        f"fell silent (3 expected: one turn per miss, the third miss drops us)"
                        if lacks else "no frame of its ring or poll without us")
        # Its lone pause (clause 31, kept by the paper profile) is Twin + id x Tslot to
        # TXEN, the takeover's Tmax: for robot 6 in the real-time set 535 against 605 ms
        # End to Header. Each gap is taken for the nearer of the two rhythms.
        lone_gap, takeover_gap = TWIN + self.robot * TSLOT + TTRANS, TMAX + TTRANS
        gaps = [b.start - a.end for a, b in zip(after, after[1:])]
        lone = [i for i, g in enumerate(gaps) if abs(g - lone_gap) < abs(g - takeover_gap)]
        ok = bool(lone) and lone[0] == 2
        return ok, (f"gaps between its frames (ms): {', '.join(f'{g / MS:.0f}' for g in gaps)}"
                    f"; lone {lone_gap / MS:.0f} (Twin + {self.robot} x Tslot + Ttrans), "
                    f"takeover {takeover_gap / MS:.0f} (Tmax + Ttrans)")

    def _rejoin(self) -> Heard:
        """Back into a ring with the robot after it stopped sending while we were silent
        (it listens for the ring, or was sent back to LISTEN): our invitation (rprs), or our
        frame in its static ring (paper); then a few turns, so that it counts us a member
        again before we fall silent once more."""
        if self.profile == "paper":
            h, _, _ = self._paper_join(self._secs(), since=self.now())
        else:
            h, _ = self._invite(self.now())
        return self._turns(h, 4)


def _app(content: bytes) -> bool:
    try:
        return any(c.spec.layer == "app" for c in parse_content(content))
    except ContentError:
        return False


def _kind(f: Frame) -> str:
    if not f.content:
        return "heartbeat"
    try:
        cmds = parse_content(f.content)
    except ContentError:
        return "unreadable"
    return "control" if all(c.spec.layer == "mac" for c in cmds) else "message"


def _last_digit_changed(frame: bytes) -> bytes:
    """An encoded frame whose Content ends ``...N)`` with that last digit N changed (a tag's
    or a checksum's): the End (2 bytes) and ``)`` follow it."""
    i = len(frame) - 4
    return frame[:i] + (b"0" if frame[i:i + 1] != b"0" else b"1") + frame[i + 1:]


def _polls_of(f: Frame) -> list[tuple[int, int]]:
    """The ``poll(k,mask)`` commands of ``f``'s Content, as (k, mask)."""
    try:
        cmds = parse_content(f.content) if f.content else []
    except ContentError:
        return []
    return [(c.args[0], c.args[1]) for c in cmds if c.name == "poll"]


def _mask_of(f: Frame) -> int | None:
    try:
        cmds = parse_content(f.content) if f.content else []
    except ContentError:
        return None
    for c in cmds:
        if c.name == "ring":
            return c.args[0]
        if c.name == "poll":
            return c.args[1]
    return None


def _succ(src: int, ring: tuple[int, ...]) -> int:
    """The member whose turn follows a frame from ``src`` (in the ring or not): the next ID
    of ``ring`` after ``src`` in ascending order, wrapping (clauses 22, 26, 38.3)."""
    after = sorted(i for i in ring if i > src)
    return after[0] if after else min(ring)


def _forger(robot: int, me: int) -> int:
    """The forged Source for clause 38: a robot outside the ring {robot, me}, preferably one
    after which our turn comes (so our own frame follows the forged one, as in the ring's
    own rhythm); when none lies between the robot and us in ring order (robot 6, tester 0),
    the lowest other ID, after which the robot's turn comes."""
    others = [i for i in range(7) if i not in (robot, me)]
    ours = [i for i in others if _succ(i, (robot, me)) == me]
    return (ours or others)[0]


def _at_turn(watch: Callable[[Heard, int], None], k: int, h: Heard, i: int) -> None:
    """``watch`` shown the robot's frame ``h`` as the ``k``-th of a run of turns (``i``, the
    index within one call of :meth:`Tester._turns`, is not used)."""
    watch(h, k)

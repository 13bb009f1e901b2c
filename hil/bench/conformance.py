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
47, 48        our message is acknowledged in its next frame; a retransmission (same Number)
              is acknowledged again but not acted on again (its status() answered once)
              (rprs); in the paper profile nothing is acknowledged
45            its reply to our next status() takes the Number after its first reply's (rprs)
38            a frame with a forged Source (a team robot outside the ring) is not acted on
              (rprs; n/a in the paper profile, which admits any team robot that sends)
41, 15, 11    frames that break (a bad digit in the Number; Length 9999) are not acted on,
              and close our turn: the robot takes the next
24, 44        when we fall silent it takes the turn: Tmax after its own End, plus R-stagger and
              R-pair in a ring of two (rprs), or at its End + Tmax + Ttrans (paper)
25            after our third missed turn it drops us (its masks lack us; paper: its turns
              come at its lone cadence)
===========  ================================================================================

Times are the arrival of bytes at this PC: a Header's start is estimated as its End minus its
bytes at 9600 bit/s, so every measured gap includes the port's latency; ``tolerance`` (default
15 ms) bounds the median hand-over, and twice that 9 hand-overs in 10. The robot must run
with the real-time margins (``rprs child`` does; a flashed board on a PC bench must too,
docs/bench.md) and a team that holds both IDs.
"""
from __future__ import annotations

import statistics
import time
from dataclasses import dataclass, field
from typing import Callable
from xml.etree import ElementTree as ET

from firmware_model.radio.auth import AUTH_TEXT_LEN, check as auth_check, clock_freshness
from firmware_model.radio.auth import seal as auth_seal, strip as auth_strip
from firmware_model.radio.content import parse_content
from firmware_model.radio.deframer import Deframer, FrameFailed, FrameReceived, Garbage
from firmware_model.radio.errors import ContentError
from firmware_model.radio.frame import BROADCAST, Frame
from firmware_model.timing import PC_BYTE_TICKS, TICK_HZ

from .runner import REALTIME_MARGINS
from .scripts import percentile
from .serial_radio import open_port

MS = TICK_HZ // 1000
TTRANS = 5 * MS
TMAX = 600 * MS
TWIN = REALTIME_MARGINS["twin"]
TSLOT = REALTIME_MARGINS["tslot"]
BYTE = PC_BYTE_TICKS


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
        for c in self.checks:
            case = ET.SubElement(suite, "testcase", classname=f"clause {c.clause}",
                                 name=c.name, time=f"{c.seconds:.3f}")
            ET.SubElement(case, "system-out").text = c.figure
            if c.verdict == "FAIL":
                ET.SubElement(case, "failure", message=c.figure)
            elif c.verdict == "n/a":
                ET.SubElement(case, "skipped", message=f"not applicable: {c.figure}")
        return ET.tostring(ET.ElementTree(suite).getroot(), encoding="utf-8",
                           xml_declaration=True)


class ConformanceError(Exception):
    """The run could not go on (no answer at all, a port that broke): one line."""


class Tester:
    """The scripted station on ``port`` and the checks, run by :meth:`run`."""

    __test__ = False                  # not a pytest class
    key = None                        # the ring key (the authenticated profile), or None

    def __init__(self, port: str, robot: int, profile: str = "rprs", tester: int | None = None,
                 tolerance_ms: float = 15.0, turns: int = 20,
                 progress: Callable[[str], None] | None = None, key=None) -> None:
        if not 0 <= robot <= 6:
            raise ValueError(f"robot ID must be 0-6, got {robot}")
        self.robot = robot
        self.me = tester if tester is not None else (0 if robot != 0 else 1)
        if self.me == robot or not 0 <= self.me <= 6:
            raise ValueError(f"the tester's ID must be 0-6 and not the robot's, got {self.me}")
        self.forger = min(set(range(7)) - {robot, self.me})
        self.profile = profile
        self.tol = int(tolerance_ms * MS)
        self.turns = turns
        self.progress = progress or (lambda s: None)
        self.port = open_port(port)
        self.deframer = Deframer(byte_ticks=BYTE)
        self.t0 = time.monotonic_ns()
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
        self.first_failure: str | None = None   # why the first failed frame failed
        self.key = key                    # the ring key: the authenticated profile (§4.11)
        if key is not None and profile == "paper":
            raise ValueError("the paper profile has no authenticated profile")
        self.fresh = clock_freshness(time.time())   # our next freshness value
        self.rx_fresh: int | None = None  # the robot's last freshness value
        self.auth_bad: list[str] = []     # the robot's frames with a wrong tag or stale value
        self.sent: list[bytes] = []       # every frame we sent, as sent

    # -- time, air -----------------------------------------------------------------------

    def now(self) -> int:
        return (time.monotonic_ns() - self.t0) * TICK_HZ // 1_000_000_000

    def _poll_rx(self) -> None:
        data = self.port.read(max(1, self.port.in_waiting))
        if not data:
            return
        t = self.now()
        self.rx_bytes += len(data)
        for ev in self.deframer.feed(data, t - (len(data) - 1) * BYTE, BYTE):
            if isinstance(ev, FrameReceived):
                f = ev.frame
                start = ev.end - f.nbytes * BYTE
                if self.key is not None:
                    f = self._authenticated(f)
                self.heard.append(Heard(f, start, ev.end))
            elif isinstance(ev, Garbage):
                self.garbage += ev.count
            elif isinstance(ev, FrameFailed):
                if self._ours_overlap(ev.first, ev.at):
                    self.collided += 1
                    continue
                self.bad += 1
                if self.first_failure is None:
                    self.first_failure = str(ev.error)

    def _authenticated(self, f: Frame) -> Frame:
        """The robot's frame ``f`` with its ``auth(...)`` taken off, its tag and freshness
        checked (clauses 52-53); a frame that fails keeps its Content (it reads as
        unreadable) and is noted for clause 52's verdict."""
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
        transmissions and that broke (tick ``at``) while it was on air, or within the
        tolerance after its End: we stepped on it (a collision we caused), so it says
        nothing of the robot's frames. A frame that began after ours began is judged: the
        robot spoke while we were on air. Both are stamps of this PC, late by its latency."""
        return any(first < s <= at <= e + self.tol for s, e in self.on_air[-4:])

    def _write(self, data: bytes) -> int:
        """Put ``data`` on the port now; the tick its End leaves the air."""
        start = self.now()
        self.port.write(data)
        if self.key is not None:
            self.sent.append(data)
        self.last_end = start + len(data) * BYTE
        self.on_air.append((start, self.last_end))
        return self.last_end

    def wait_frame(self, after: int, timeout_ticks: int, src: int | None = None) -> Heard | None:
        """The first frame (from ``src``) whose End arrived after tick ``after``."""
        deadline = self.now() + timeout_ticks
        self._mark = (self.rx_bytes, self.bad, self.garbage)
        seen = 0
        while True:
            for h in self.heard[seen:]:
                if h.end > after and (src is None or h.frame.src == src):
                    return h
            seen = len(self.heard)
            if self.now() >= deadline:
                return None
            self._poll_rx()
            time.sleep(0.0003)

    def _quiet(self, what: str) -> ConformanceError:
        """The run stops: the robot sent no good frame ``what``; with what this port heard
        since ``_mark`` (silence, broken frames, or garbage), not just "stopped sending"."""
        b, f, g = (now - was for now, was in zip((self.rx_bytes, self.bad, self.garbage),
                                                 self._mark))
        heard = "nothing" if not b else f"{b} bytes: {f} failed frames, {g} garbage bytes"
        return ConformanceError(f"robot {self.robot} sent no good frame {what}; this port "
                                f"heard {heard} while it waited")

    def send(self, frame: Frame, at: int) -> int:
        """Send ``frame`` with its first bit at tick ``at`` (Ttrans after TXEN); its End."""
        while self.now() < at:
            self._poll_rx()
            time.sleep(0.0002)
        return self._write(frame.encode())

    def frame(self, content: bytes = b"", dst: int = BROADCAST, type_: int = 3,
              num: int | None = None, src: int | None = None) -> Frame:
        src = self.me if src is None else src
        num = self.num if num is None else num
        if self.key is not None:
            self.fresh += 1
            return auth_seal(self.key, dst, src, num, type_, content, self.fresh - 1)
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
                  time.monotonic() - t0, applicable)
        self.report.checks.append(c)
        self.progress(f"clause {clause}: {c.verdict} {name}: {figure}")

    # -- the run -------------------------------------------------------------------------

    def run(self) -> Report:
        """Every check in order; a run that stops (ConformanceError) still judges clause 15
        on what it heard, so a robot whose frames all fail is told so (``n/a`` if it sent
        no frame at all)."""
        stopped = True
        try:
            last = self._start()
            last = self._rotation(last)
            last = self._late(last)
            last = self._message(last)
            last = self._forged(last)
            if self.key is not None:
                last = self._forged_tag(last)
                last = self._replayed(last)
            last = self._broken(last)
            self._silence(last)
            stopped = False
        finally:
            self.port.close()
            frames = [h for h in self.heard if h.frame.src == self.robot]
            why = f"; the first failed at {self.first_failure}" if self.first_failure else ""
            t0 = time.monotonic()
            # a run that stopped before any frame, good or failed, has nothing to judge
            ours = (f", {self.collided} broken in a collision with ours (not judged)"
                    if self.collided else "")
            self.check("15", "every frame from the robot is a good frame", self.bad == 0 and
                       frames, f"{len(frames)} good frames, {self.bad} failed frames{ours}, "
                       f"{self.garbage} garbage bytes{why}" + (
                           ": the run stopped before the robot sent a frame"
                           if stopped and not frames and not self.bad else ""), t0,
                       applicable=not (stopped and not frames and not self.bad))
            if self.key is not None and frames:
                self.check("52", "every frame from the robot has a right tag and a rising "
                           "freshness value", not self.auth_bad,
                           f"{len(frames)} frames, {len(self.auth_bad)} not: "
                           f"{'; '.join(self.auth_bad[:3])}" if self.auth_bad else
                           f"{len(frames)} frames, all right", t0)
        return self.report

    def _refused(self, h: Heard, data: bytes, clause: str, name: str, num: int,
                 t0: float) -> Heard:
        """In our turn, ``data`` (status() for the robot with Number ``num``) instead of our
        frame: the robot must act on nothing in it (no ack, no status reply) and go on with
        the ring (clause 53: a failed frame, its turn closed uncertainly)."""
        self._note_acks(h)
        at = h.end + TTRANS
        while self.now() < at:
            self._poll_rx()
            time.sleep(0.0002)
        end = self._write(data)
        nxt = self.wait_frame(end, 2 * TMAX + 8 * TSLOT, self.robot)
        if nxt is None:
            self.check(clause, name, False, "no frame from the robot after it", t0)
            raise self._quiet(f"after {name}")
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
        t0 = time.monotonic()
        good = self.frame(b"status()", dst=self.robot, type_=2, num=43).encode()
        i = len(good) - 4                          # the tag's last digit
        data = good[:i] + (b"0" if good[i:i + 1] != b"0" else b"1") + good[i + 1:]
        return self._refused(h, data, "53", "a frame with a wrong tag is not acted on", 43, t0)

    def _replayed(self, h: Heard) -> Heard:
        """The very bytes of our first status() for the robot, sent again."""
        t0 = time.monotonic()
        first = next(d for d in self.sent if b"status()auth(" in d and
                     d[3] == 0x30 + self.robot)
        return self._refused(h, first, "53", "a replay of our earlier message is not acted "
                             "on", int(first[5:7]), t0)

    def _answer_turn(self, h: Heard, content: bytes = b"", **kw) -> int:
        """Our turn after the robot's frame ``h``: a frame Ttrans after its End."""
        return self.send(self.frame(content + self._acks_content(), **kw), h.end + TTRANS)

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
        t0 = time.monotonic()
        if self.profile == "paper":
            # A static ring {me, robot}: we take our turns; the robot must join the rotation.
            # Listen before we talk: a robot alone in the ring already takes its turns (one
            # every Tmax + Ttrans), so our first frame follows one of its Ends by Ttrans, as
            # our turn would, instead of landing on its frame (and then, both timing out
            # from that collision, on its next one too). We listen for two of its cycles:
            # the first frame may begin just before we do and end after one cycle would.
            h = self.wait_frame(-1, 2 * (TMAX + TTRANS + self.tol), self.robot)
            end = self.send(self.frame(), h.end + TTRANS if h is not None else self.now())
            h = None
            for _ in range(40):
                h = self.wait_frame(end, TMAX + TTRANS + 2 * self.tol, self.robot)
                if h is not None:
                    break
                end = self.send(self.frame(), self.now())
            if h is None:
                self._mark = (0, 0, 0)
                raise self._quiet("in 40 of our turns")
            self.check("23", "joins the static ring (paper profile)", True,
                       f"its first frame {(h.start - end) / MS:.1f} ms after our End", t0)
            return h
        mask = 1 << self.me
        end = 0
        for _ in range(400):               # a lone member inviting the robot (clause 31, 34)
            end = self.send(self.frame(b"poll(%d,%d)" % (self.robot, mask)),
                            max(self.now(), end + TWIN + self.me * TSLOT))
            # (With the profile our poll and the robot's BOOT are 23 bytes longer each: wait
            # from our End, as written, to the End of an answer that began within Twin.)
            longer = max(0, end - self.now()) + AUTH_TEXT_LEN * BYTE if self.key else 0
            h = self.wait_frame(end, TWIN + self.tol + longer, self.robot)
            if h is not None:
                break
        else:
            self._mark = (0, 0, 0)
            raise self._quiet("answering our invitations (is it on the channel, listening, "
                              "with both IDs in its team?)")
        f = h.frame
        gap = (h.start - end - TTRANS) / MS
        self.check("34", "answers an invitation Ttrans after its End", f.type in (5, 6) and
                   abs(gap) * MS <= self.tol, f"Type '{f.type}', Header {gap:+.1f} ms from "
                   f"E + Ttrans", t0)
        # clause 29 is about BOOT frames: a JOIN (or anything else) leaves nothing to check
        self.check("29", "a BOOT frame is Number '00'", f.num == 0,
                   f"Type '{f.type}', Number '{f.num:02d}'" + (
                       "" if f.type == 5 else ": not a BOOT frame"), t0,
                   applicable=f.type == 5)
        self._note_acks(h)
        t0 = time.monotonic()
        announcing = []

        def watch(h: Heard, i: int) -> None:
            if h.frame.type in (5, 6):
                announcing.append(i)
        h = self._turns(h, 4, None, watch)
        self.check("36", "stops its BOOT/JOIN once acknowledged", not announcing,
                   f"{len(announcing)} more BOOT/JOIN frames after our ack", t0)
        return h

    def _rotation(self, h: Heard) -> Heard:
        t0 = time.monotonic()
        gaps, kinds = [], set()

        def watch(h: Heard, i: int) -> None:
            gaps.append(h.start - self.last_end - TTRANS)
            kinds.add(_kind(h.frame))
        h = self._turns(h, self.turns, None, watch)
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
        return h

    def _late(self, h: Heard) -> Heard:
        """Our frames 300 ms late (within Tmax): the robot must time its turn from the End of
        the frame it heard, not from its own clock (clause 26: resynchronise on every frame)."""
        t0 = time.monotonic()
        gaps = []
        for _ in range(3):
            self._note_acks(h)
            end = self.send(self.frame(self._acks_content()), h.end + TTRANS + 300 * MS)
            h = self.wait_frame(end, TMAX + 4 * TSLOT, self.robot)
            if h is None:
                raise self._quiet("after a late frame of ours")
            gaps.append(h.start - end - TTRANS)
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
            end = self._answer_turn(h, content, **kw)
            h = self.wait_frame(end, TMAX + 4 * TSLOT, self.robot)
            if h is None:
                raise self._quiet(f"in its turn after our frame ending at {end / MS:.0f} ms")
            if on_frame is not None:
                on_frame(h, i)
        return h

    def _message(self, h: Heard) -> Heard:
        """Our status() to the robot, then the same message again (a retransmission)."""
        t0 = time.monotonic()
        self.num = (self.num + 1) % 100
        num = self.num
        ack = f"ack({self.me},{num})".encode()
        seen: dict[str, list] = {"acked": [], "replies": []}

        def watch(h: Heard, i: int) -> None:
            if ack in h.frame.content:
                seen["acked"].append(i)
            if h.frame.dst == self.me and (b"joint(" in h.frame.content or
                                           b"fail(" in h.frame.content):
                seen["replies"].append(h.frame.num)    # the status, or why there is none
        ask = (b"status()", {"dst": self.robot, "type_": 2})
        h = self._turns(h, 6, ask, watch)
        acked, replies = seen["acked"], list(seen["replies"])
        if self.profile == "paper":
            self.check("47", "paper profile: nothing is acknowledged", not acked,
                       f"acks: {len(acked)}; status() answered {len(replies)} time(s) (the "
                       f"paper has no status(): not required)", t0)
            return h
        self.check("47", "acknowledges our message in its next frame", acked[:1] == [0],
                   "ack in its next frame" if acked[:1] == [0] else
                   f"first ack in its frame {acked[0] + 1}" if acked else "no ack", t0)
        t0 = time.monotonic()
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
        t0 = time.monotonic()
        self.num = (self.num + 1) % 100
        before = list(seen["replies"])
        h = self._turns(h, 6, (b"status()", {"dst": self.robot, "type_": 2}), watch)
        new = seen["replies"][len(before):]
        ok = len(before) == 1 and len(new) == 1 and new[0] == (before[0] + 1) % 100
        self.check("45", "its next message takes the next Number",
                   ok, f"its replies' Numbers: {', '.join(f'{n:02d}' for n in before + new)}",
                   t0)
        return h

    def _forged(self, h: Heard) -> Heard:
        """In our turn, first a frame from a forger (a team robot outside the ring) carrying
        status() for the robot, then our own frame: the robot must refuse the forged one."""
        t0 = time.monotonic()
        if self.profile == "paper":
            self.check("38", "a forged Source is refused", True, "the paper profile admits "
                       "any team robot that sends (docs/protocol.md §9.1)", t0,
                       applicable=False)
            return h
        self._note_acks(h)
        forged = self.frame(b"status()", dst=self.robot, type_=2, num=42, src=self.forger)
        end = self.send(forged, h.end + TTRANS)
        end = self.send(self.frame(self._acks_content()), end + TTRANS)
        h = self.wait_frame(end, TMAX + 4 * TSLOT, self.robot)
        if h is None:
            raise self._quiet("after a forged frame")
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
        t0 = time.monotonic()
        good = self.frame(b"status()", dst=self.robot, type_=2, num=77).encode()
        bad_digit = good[:5] + b"x" + good[6:]                        # Number '7x'
        oversize = good[:8] + b"9999" + good[12:]                      # Length 9999
        acted, figures = 0, []
        for name, data in (("a bad Number digit", bad_digit), ("Length 9999", oversize)):
            self._note_acks(h)
            at = h.end + TTRANS
            while self.now() < at:
                self._poll_rx()
                time.sleep(0.0002)
            end = self._write(data)
            nxt = self.wait_frame(end, 2 * TMAX + 8 * TSLOT, self.robot)
            if nxt is None:
                self.check("41", "a frame that breaks is not acted on and closes the turn",
                           False, f"after {name}: no frame from the robot", t0)
                raise self._quiet(f"after a frame with {name}")
            figures.append(f"{name}: its next frame {(nxt.start - end) / MS:.0f} ms after")
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
        return h

    def _silence(self, h: Heard) -> None:
        """We stop sending: the robot's takeovers, then our drop (clauses 24, 25, 44).

        Each of our three missed turns is a takeover by the robot, timed from the End before
        it. Clause 24 is judged on the median of the three offsets: a stamp that came late
        because this PC stalled (one run measured +34.5 ms, then -34 ms on the next, as the
        late stamp shortened the following gap) does not decide it."""
        t0 = time.monotonic()
        our_end = self.last_end
        if self.profile == "rprs":
            def expect(prev_end: int) -> int:
                return max(prev_end + TMAX + self.robot * TSLOT,
                           our_end + TMAX + self.me * TSLOT + TTRANS + 4 * BYTE) + TTRANS
            rule = "max(its End + Tmax + id x Tslot, our End + Tmax + our id x Tslot + Ttrans + " \
                   "4 B) + Ttrans (R-stagger, R-pair)"
        else:
            def expect(prev_end: int) -> int:
                return prev_end + TMAX + TTRANS
            rule = "its End + Tmax + Ttrans"
        frames = [h]
        for _ in range(6):
            nxt = self.wait_frame(frames[-1].end, 2 * TMAX + 8 * TSLOT, self.robot)
            if nxt is None:
                break
            frames.append(nxt)
        takeovers = frames[1:4]
        if not takeovers:
            self.check("24", "takes the turn when we fall silent", False, "no frame in "
                       f"{(2 * TMAX + 8 * TSLOT) / MS:.0f} ms", t0)
            return
        offs = [(b.start - expect(a.end)) / MS for a, b in zip(frames, takeovers)]
        mid = statistics.median(offs)
        self.check("24", "takes the turn when we fall silent", abs(mid) * MS <= self.tol,
                   f"Header {mid:+.1f} ms (median of {len(offs)} takeovers: "
                   f"{', '.join(f'{o:+.1f}' for o in offs)}) from {rule}", t0)
        t0 = time.monotonic()
        after = frames[1:]
        if self.profile == "rprs":
            masks = [_mask_of(f.frame) for f in after]
            lacks = [i for i, m in enumerate(masks) if m is not None and not m >> self.me & 1]
            ok = bool(lacks) and lacks[0] == 2
            fig = (f"first frame whose mask lacks us: its frame {lacks[0] + 1} after we fell "
                   f"silent (3 expected: one turn per miss, the third miss drops us)"
                   if lacks else "no frame of its ring or poll without us")
        else:
            gaps = [(b.start - a.end) / MS for a, b in zip(after, after[1:])]
            lone = [i for i, g in enumerate(gaps) if g < TMAX / MS / 2]
            ok = bool(lone) and lone[0] == 2
            fig = f"gaps between its frames (ms): {', '.join(f'{g:.0f}' for g in gaps)}"
        self.check("25", "drops us after our third missed turn", ok, fig, t0)


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

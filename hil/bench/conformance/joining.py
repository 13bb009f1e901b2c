"""The kit's first steps: the invitation and the robot's answer (clauses 34, 29, 36), or the
paper profile's static ring; the hand-overs (23, 21, 32) and our late frames (26).

Plain functions bound as methods of :class:`.tester.Tester` (its class body names them).
"""
from __future__ import annotations

import statistics
from functools import partial
from typing import TYPE_CHECKING

from firmware_model.radio.auth import AUTH_TEXT_LEN
from firmware_model.timing import TICK_HZ

from ..scripts import percentile
from .frames import _at_turn, _kind, _mask_of, _polls_of
from .link import BYTE, INVITE_EVERY, MISS_LIMIT, MS, QUIET_GAP, TMAX, TSLOT, TTRANS, TWIN
from .report import ConformanceError, Heard

if TYPE_CHECKING:
    from .tester import Tester


def _start(self: Tester) -> Heard:
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
    return self._stops_announcing(h)


def _stops_announcing(self: Tester, h: Heard) -> Heard:
    """Clause 36 after its answer ``h``, which we acknowledge: no more BOOT/JOIN frames in
    its next four. The frame after a turn it missed is excused: a robot on a busy PC that
    was starved past a Tslot dropped what it heard meanwhile, our ack with it (clause 5), and
    announces again; our next frame acknowledges that one too, and two more turns show
    whether it stops."""
    self._note_acks(h)
    t0 = self._secs()
    if h.frame.type not in (5, 6):
        # no BOOT/JOIN answer (clause 34: none, or one every member refuses, clause 53):
        # nothing of its was acknowledged, so there is nothing to stop
        self.check("36", "stops its BOOT/JOIN once acknowledged", True,
                   f"its answer was no BOOT/JOIN frame (Type '{h.frame.type}'): nothing "
                   f"acknowledged", t0, applicable=False)
        return h
    announcing: list[int] = []
    excused: list[int] = []

    def watch(h: Heard, i: int) -> None:
        if h.frame.type in (5, 6):
            (excused if self.after_miss else announcing).append(i)
    h = self._turns(h, 4, None, watch)
    if excused and excused[-1] == 3:          # its last frame: announced again after a miss
        h = self._turns(h, 2, None, partial(_at_turn, watch, 4))
    self.check("36", "stops its BOOT/JOIN once acknowledged", not announcing,
               f"{len(announcing)} more BOOT/JOIN frames after our ack" + (
                   f" ({len(excused)} more after a turn it missed, not counted: it had not "
                   f"heard our ack)" if excused else ""), t0)
    return h


INVITATIONS = 400
"""How many times the kit invites the robot before it stops (about 50 s of lone turns)."""


def _invite(self: Tester, since: int, mask: int | None = None) -> tuple[Heard, int]:
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
    told = self.now()
    self.progress(f"inviting robot {self.robot} (poll({self.robot},{mask}) in our lone turns, "
                  f"up to {INVITATIONS}): waiting for its BOOT or JOIN")
    for k in range(INVITATIONS):       # a lone member inviting the robot (clause 31, 34)
        if self.now() - told >= 10 * TICK_HZ:      # no answer for a while: say so
            told = self.now()
            self.progress(f"still inviting robot {self.robot}: {k} invitations, no answer "
                          f"yet ({len(self.heard)} good frames heard, {self.bad} failed)")
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
                          "with both IDs in its team" + (", signing with this --auth-key"
                                                         if self.key is not None else "")
                          + "?)")
    return h, end


def _air(self: Tester, content: int) -> int:
    """Ticks a frame with ``content`` bytes of Content takes on air, signed (its
    ``auth(...)`` too) with the authenticated profile."""
    return (14 + content + (AUTH_TEXT_LEN if self.key is not None else 0)) * BYTE


def _paper_join(self: Tester, t0: float, since: int = -1) -> tuple[Heard, float, int]:
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


def _lone(self: Tester, h: Heard, until: int) -> Heard:
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


def _rotation(self: Tester, h: Heard) -> Heard:
    t0 = self._secs()
    gaps, kinds = [], set()
    polls: list[tuple[list[tuple[int, int]], bool]] = []   # each frame's, after a miss

    def watch(h: Heard, i: int) -> None:
        if not self.after_miss:          # after a missed turn: no hand-over to time
            gaps.append(h.start - self.last_end - TTRANS)
        kinds.add(_kind(h.frame, sealed=self.key is not None))
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


def _invitations(self: Tester, frames: list[tuple[list[tuple[int, int]], bool]],
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


def _late(self: Tester, h: Heard) -> Heard:
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

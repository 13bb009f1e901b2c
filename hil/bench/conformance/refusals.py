"""Messages and what the robot must refuse: our status() and its retransmission (47, 48, 45),
a forged Source (38), a wrong tag or checksum and a replay (53, 20), frames that break (41,
44, 51), and our ring(mask) without its bit (51, 34, 49).

Plain functions bound as methods of :class:`.tester.Tester` (its class body names them).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .frames import _last_digit_changed, _mask_of, _succ
from .link import MISS_LIMIT, MS, QUIET_GAP, TMAX, TSLOT, TTRANS
from .report import ConformanceError, Heard

if TYPE_CHECKING:
    from .tester import Tester


def _refused(self: Tester, h: Heard, data: bytes, clause: str, name: str, num: int,
             t0: float) -> Heard:
    """In our turn, ``data`` (status() for the robot with Number ``num``) instead of our
    frame: the robot must act on nothing in it (no ack, no status reply) and go on with
    the ring (clause 53: a failed frame, its turn closed uncertainly)."""
    try:
        nxt, end = self._once_heard(h, data, name, clause)
    except ConformanceError:
        # the clause's own verdict, before the run stops: a robot that never takes the
        # turn after a refused frame does not go on with the ring
        self.check(clause, name, False, f"it missed its turn after it {MISS_LIMIT} times in "
                   f"a row", t0)
        raise
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


def _forged_tag(self: Tester, h: Heard) -> Heard:
    """Our status() for the robot with a tag that is wrong by one digit."""
    t0 = self._secs()
    data = _last_digit_changed(self.frame(b"status()", dst=self.robot, type_=2,
                                         num=43).encode())
    return self._refused(h, data, "53", "a frame with a wrong tag is not acted on", 43, t0)


def _wrong_crc(self: Tester, h: Heard) -> Heard:
    """Our status() for the robot with its checksum wrong in one digit (clauses 20, 43:
    a failed frame, its turn closed uncertainly)."""
    t0 = self._secs()
    data = _last_digit_changed(self.frame(b"status()", dst=self.robot, type_=2,
                                         num=44).encode())
    return self._refused(h, data, "20", "a frame with a wrong checksum is not acted on",
                         44, t0)


def _replayed(self: Tester, h: Heard) -> Heard:
    """The very bytes of our first status() for the robot, sent again."""
    t0 = self._secs()
    first = next(d for d in self.sent if b"status()auth(" in d and
                 d[3] == 0x30 + self.robot)
    return self._refused(h, first, "53", "a replay of our earlier message is not acted "
                         "on", int(first[5:7]), t0)


def _message(self: Tester, h: Heard) -> Heard:
    """Our status() to the robot, then the same message again (a retransmission), then a
    new one. rprs: they are Numbers 99 and 00, so the robot must take the wrap of our
    counter ('99' then '00', clause 45) for a new message (clause 48), not a duplicate."""
    t0 = self._secs()
    if self.profile == "rprs":
        self.num = 98                 # a station that has sent 98 messages since power-on
    self.num = (self.num + 1) % 100
    num = self.num
    ack = f"ack({self.me},{num})".encode()
    seen: dict[str, list] = {"acked": [], "replies": [], "again": [], "forms": []}

    def watch(h: Heard, i: int) -> None:
        if ack in h.frame.content:
            seen["acked"].append(i)
        if h.frame.dst == self.me and (b"joint(" in h.frame.content or
                                       b"fail(" in h.frame.content) and \
                h.frame.num not in seen["replies"][-1:]:
            # the status, or why there is none; the same Number again is its message
            # retransmitted (our ack was lost to it, e.g. while it stalled), no new reply
            seen["replies"].append(h.frame.num)
            seen["forms"].append((h.frame.type, h.frame.content))
        elif h.frame.dst == self.me and (b"joint(" in h.frame.content or
                                         b"fail(" in h.frame.content):
            seen["again"].append(h.frame.num)
    ask = (b"status()", {"dst": self.robot, "type_": 2})
    h = self._turns(h, 6, ask, watch)
    if self.profile == "rprs" and self.robot != 0:   # (the paper has no status(), the
        h = self._until(h, lambda: seen["replies"], watch)   # father no submodule: no reply)
    acked, replies = seen["acked"], list(seen["replies"])
    if self.profile == "paper":
        self.check("47", "paper profile: nothing is acknowledged", not acked,
                   f"acks: {len(acked)}; status() answered {len(replies)} time(s) (the "
                   f"paper has no status(): not required)", t0)
        return h
    self.check("47", "acknowledges our message in its next frame", acked[:1] == [0],
               "ack in its next frame" if acked[:1] == [0] else
               f"first ack in its frame {acked[0] + 1}" if acked else "no ack", t0)
    if self.robot != 0:
        _reply_form(self, seen["forms"], t0)
    t0 = self._secs()
    seen["acked"].clear()
    h = self._turns(h, 4, (b"status()", {"dst": self.robot, "type_": 2, "num": num}),
                    watch)
    more = len(seen["replies"]) - len(replies)
    if self.robot == 0:
        return _fathers_message(self, h, bool(seen["acked"]), len(replies) + more, t0)
    self.check("48", "a retransmission is acknowledged again and not acted on again",
               bool(seen["acked"]) and more == 0 and len(replies) == 1,
               f"re-acknowledged: {'yes' if seen['acked'] else 'no'}; status replies: "
               f"{len(replies)}, then {more} more", t0)
    # A new message (the next Number): its reply is a new message of the robot's, with
    # the Number after its first reply's (clause 45), which we acknowledge.
    t0 = self._secs()
    self.num = (self.num + 1) % 100
    before = list(seen["replies"])
    h = self._turns(h, 6, (b"status()", {"dst": self.robot, "type_": 2, "num": self.num}),
                    watch, until_acked=f"ack({self.me},{self.num})".encode())
    h = self._until(h, lambda: seen["replies"][len(before):], watch)
    new = seen["replies"][len(before):]
    ok = len(before) == 1 and len(new) == 1 and new[0] == (before[0] + 1) % 100
    again = seen["again"]
    self.check("45", "its next message takes the next Number (ours wrapped, 99 then 00)",
               ok, f"its replies' Numbers: "
               f"{', '.join(f'{n:02d}' for n in before + new) or 'none'}, "
               f"to our {num:02d} and {self.num:02d}" +
               (f" (sent again: {', '.join(f'{n:02d}' for n in again)})" if again else "") +
               ("" if new else f"; no new reply in {6 + self.REPLY_TURNS} turns"), t0)
    return h


def _reply_form(self: Tester, forms: list[tuple[int, bytes]], t0: float) -> None:
    """Clause 19a: a child answers status() with a message of Type '3' holding its values
    (``joint(1,a)...``), or of Type '4', ``fail(code)status()``, when it has none (the
    command table, docs/protocol.md). A reply of another Type passed: it was counted by
    its commands alone."""
    if not forms:
        self.check("19a", "answers status() as the command table says (Type '3' values, "
                   "or Type '4' fail(code)status())", False, "no reply", t0)
        return
    type_, content = forms[0]
    text = content.decode("ascii", "replace")
    if b"joint(" not in content:               # no values: why (fail(code)status())
        ok = type_ == 4 and b"fail(" in content and b"status()" in content
        want = "Type '4' fail(code)status()"
    else:
        ok = type_ == 3
        want = "Type '3' joint(1,a)..."
    self.check("19a", "answers status() as the command table says (Type '3' values, or "
               "Type '4' fail(code)status())", ok,
               f"its reply: Type '{type_}' {text[:40]}" + ("" if ok else f"; want {want}"),
               t0)


FATHER = ("the father (ID 0) has no submodule: it carries out and answers no order "
          "(clause 19a)")


def _fathers_message(self: Tester, h: Heard, reacked: bool, replies: int, t0: float) -> Heard:
    """Clauses 48 and 45 for the father: it acknowledges our retransmission again, but a
    PC with no submodule answers no status(), so nothing on the air shows whether it acted on
    a message once or twice, nor makes it send a message of its own (its operator does)."""
    self.check("48", "a retransmission is acknowledged again and not acted on again",
               reacked and replies == 0,
               f"re-acknowledged: {'yes' if reacked else 'no'}; "
               + (f"{FATHER}: only the acknowledgement is seen" if replies == 0 else
                  f"status replies: {replies}, though {FATHER}"), t0)
    t0 = self._secs()
    self.check("45", "its next message takes the next Number (ours wrapped, 99 then 00)",
               True, f"{FATHER}: nothing makes it send a message of its own", t0,
               applicable=False)
    return h


def _forged(self: Tester, h: Heard) -> Heard:
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


def _broken(self: Tester, h: Heard) -> Heard:
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
            nxt, end = self._once_heard(h, data, f"a frame with {name}", "41")
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


def _left_out(self: Tester, h: Heard) -> Heard:
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

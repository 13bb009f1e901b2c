"""A ring of three, this PC playing a third team robot T beside its own ID: the ring view
that admits T (51.3), a phantom takeover (39), the cut-off (40), and the ring view that drops
T (51.3).

Plain functions bound as methods of :class:`.tester.Tester` (its class body names them).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

from firmware_model.radio.frame import BROADCAST

from .frames import _app, _mask_of, _succ
from .link import MS, TMAX, TSLOT, TTRANS
from .report import Heard

if TYPE_CHECKING:
    from .tester import Tester


def _ours_after(self: Tester, ring: tuple[int, ...], src: int) -> list[int]:
    """The members this PC plays (us, and the third member) whose turns follow a frame
    from ``src`` in ``ring``, up to the robot's."""
    out, x = [], _succ(src, ring)
    while x != self.robot and x not in out:
        out.append(x)
        x = _succ(x, ring)
    return out


def _three_note(self: Tester, h: Heard) -> None:
    """Acknowledgements the robot's frame ``h`` needs: ours (:meth:`_note_acks`) and the
    third member's (a message for it, or for every member)."""
    self._note_acks(h)
    f = h.frame
    if f.type in (5, 6) or (f.dst in (self.third, BROADCAST) and f.content and
                            _app(f.content)):
        self.third_acks.append((f.src, f.num))


def _acks_of(self: Tester, member: int) -> bytes:
    """The acknowledgements ``member`` (us, or T) owes, for its frame now (taken once)."""
    if member == self.me:
        return self._acks_content()
    out = b"".join(b"ack(%d,%d)" % a for a in self.third_acks)
    self.third_acks.clear()
    return out


def _three_turn(self: Tester, h: Heard, ring: tuple[int, ...], first: dict[int, bytes],
                watch: Callable[[Heard, int], None], i: int) -> Heard:
    """Our frames after the robot's frame ``h`` in ``ring`` (each member we play, in
    turn; ``first``: Content a member's frame carries this turn), then the robot's
    next frame, shown to ``watch`` as ``i``."""
    self._three_note(h)

    def frames() -> list[bytes]:
        out = []
        for m in self._ours_after(ring, h.frame.src):
            content = first.get(m, b"") + self._acks_of(m)
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


def _three(self: Tester, h: Heard) -> Heard:
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
    answers = self.robot != 0         # the father answers no status() (clause 19a)
    for i in range(2, 2 + self.REPLY_TURNS):
        if acked and (replies or not answers) and i >= 5:
            break
        h = self._three_turn(h, ring, {}, watch, i)
    told = sorted({m for m in masks if m is not None})
    self.check("51", f"admits the robot a ring view names (T = {t}), and keeps its turn",
               bool(acked) and bool(replies) == answers and acked[0] <= 2,
               (f"T's status() acknowledged in its frame {acked[0]} after T's" if acked
                else "T's status() never acknowledged") +
               f"; replies to T: {len(replies)}" + ("" if answers else " (the father "
               "answers none)") + "; masks in its frames: "
               f"{', '.join(map(str, told)) or 'none'} (the ring of three: {mask})", t0)
    h = self._phantom(h, ring)
    h = self._cut_off(h, ring)
    return self._drop_third(h, ring)


def _phantom(self: Tester, h: Heard, ring: tuple[int, ...]) -> Heard:
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
        return self.frame(b"status()" + self._acks_of(early), dst=self.robot, type_=2,
                          num=num, src=early).encode()
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


def _cut_off(self: Tester, h: Heard, ring: tuple[int, ...]) -> Heard:
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


def _three_turns(self: Tester, h: Heard, ring: tuple[int, ...], n: int) -> Heard:
    """``n`` rounds of the ring of three from the robot's frame ``h``: our frames and T's
    (acknowledging what needs it), then its next."""
    for i in range(n):
        h = self._three_turn(h, ring, {}, lambda x, k: None, i)
    return h


def _drop_third(self: Tester, h: Heard, ring: tuple[int, ...]) -> Heard:
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

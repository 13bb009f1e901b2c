"""The rotational MAC's membership (docs/protocol.md §4.3-§4.5, §4.8): who is in the ring, and
what a frame that is not the expected owner's does to it: robots admitted and dropped, frames
refused in a slot, our own ID or a foreign ring on the air, a slot that keeps failing, views
reconciled, and the way back to LISTEN. Functions of a ``RotationalMac``, bound as its methods
in mac.py."""
from __future__ import annotations

from bisect import bisect_right
from typing import TYPE_CHECKING

from . import auth as _auth
from .errors import ContentError
from .frame import Frame
from .integrity import check as crc_ok, strip as strip_crc
from .mac_config import FAILING_SLOT_LIMIT, LET_PASS_MAX, TWIN_FRAMES
from .mac_events import Disable, DuplicateId, ForeignRing, Join, Miss, ModeChange, Refused
from .mac_frames import _layers, _unmask
from .mac_phases import HOLD, LISTEN, MEMBER, QUIET, WAIT, WATCH, WINDOW

if TYPE_CHECKING:
    from .mac import RotationalMac


def _admit(self: RotationalMac, robot: int, out: list) -> None:
    again = robot in self.ever_member
    self.ring = tuple(sorted(set(self.ring) | {robot}))
    self.ever_member.add(robot)
    self.misses[robot] = 0
    self._rx_armed.discard(robot)     # it may have restarted unheard: clause 48a waits
    if self._lone_boot:
        # A lone claimer whose ring grows: the robots it admits heard its frames and
        # answered them; its former Numbers are not in their memory unless one of them
        # was cut off from the ring it had left (docs/guarantees.md, "Stalls and restarts
        # at the bench"). Its BOOT is done: a later answer is JOIN (else the members would
        # forget its Numbers and take a retransmission for a new message).
        self._lone_boot = False
        self._booting = False
    out.append(Join(robot, again))


def _refuse_in_slot(self: RotationalMac, src: int, num: int, reason: str, end: int, now: int,
                    out: list, kind: str = "", miss: bool = True) -> None:
    """A clean frame refused in someone else's slot (out of turn, or with our own ID):
    nothing in it is acted on, but it sets the timing (clause 39). ``miss``: the slot's
    owner missed its turn (not so for the other PC's frame, clause 50)."""
    out.append(Refused(src, num, reason, kind))
    self._tell_view = True                 # our views may differ (rule R-view)
    o = self.owner
    if miss and self.phase == WAIT and o in self.ring and o != self.id:
        # A clean frame in o's slot means o did not send (its frame would have collided
        # with this one): o missed its turn, as at E + Tmax. Otherwise a member that never
        # heard o join could take o's slot for ever.
        n = self.misses.get(o, 0) + 1
        self.misses[o] = n
        out.append(Miss(o))
        self._missed_on_a_frame()
        if n >= self.cfg.miss_limit:
            self._drop(o, out)
    self._next_turn(src, end, now, out)    # the owner is whoever is sending


def _own_id_heard(self: RotationalMac, num: int, end: int, now: int, out: list) -> None:
    """A frame with our own Source that we did not send (clause 38.2): refused. In LISTEN
    the channel is busy (the claim wait restarts); as a member it closes the slot it was
    sent in, as any frame refused there does, so we stay in step with those who heard it.

    Heard in ``TWIN_FRAMES`` frames each less than Tclaim after the previous one, another
    robot has our ID: said once an episode (``DuplicateId``),
    and a member yields: back to LISTEN, where it answers no invitation while our ID is
    heard, so the robot that holds the ID keeps it and nothing is done twice. (The other
    PC of a father's pair is no twin: clause 50 settles which PC is active.)"""
    n = 0 if self.id == 0 and self._pair else self._twin_frame(end)
    twin = n >= TWIN_FRAMES
    yielding = twin and not self._paper
    if twin and not self._twin_said:
        self._twin_said = True
        out.append(DuplicateId(self.id, yielding))
    if yielding and self.mode == MEMBER:
        out.append(Refused(self.id, num, "our own robot ID from the air", "own_id"))
        self._to_listen(out, now, f"another robot sends with our ID {self.id}: yielding "
                        f"the ring to it")
        return
    if self.mode == LISTEN:
        out.append(Refused(self.id, num, "our own robot ID from the air", "own_id"))
        self.deadline = now + self._claim_ticks()
        return
    if self.phase in (WAIT, WINDOW, QUIET, HOLD, WATCH):
        # WATCH: PC1 on probation heard the other PC's whole frame while it watched its
        # turn; the members took it as ID 0's, so the next turn is robot succ(0)'s. The
        # other PC's frame is ID 0's turn to the members, whatever slot we thought it was:
        # its owner did not miss it (we were deaf, or out of step; clause 50).
        self._refuse_in_slot(self.id, num, "our own robot ID from the air", end, now, out,
                             "own_id", miss=not (self.id == 0 and self._pair))
    else:
        out.append(Refused(self.id, num, "our own robot ID from the air", "own_id"))


def _twin_frame(self: RotationalMac, end: int) -> int:
    """Count a frame with our own ID that we did not send: how many this episode (frames
    each less than Tclaim(id) after the previous one; a longer silence starts again)."""
    n, last = self._own_heard or (0, end)
    if end - last > self._claim_ticks():
        n = 0
        self._twin_said = False
    n += 1
    self._own_heard = (n, end)
    return n


def _foreign_heard(self: RotationalMac, src: int, end: int, out: list) -> None:
    """A good frame from robot ``src`` outside our team (clause 38.1): say which robots
    outside the team hold the channel, once, and again when that set changes. The set is
    those heard within the longest cycle a ring can make (8 Tmax), taken when a robot is
    heard again (its ring has gone round once since)."""
    if not 0 <= src <= 6:
        return                             # no robot ID: a forger's, or noise
    horizon = end - 8 * self.cfg.tmax
    again = self._foreign.get(src, horizon - 1) >= horizon
    self._foreign[src] = end
    if not again:
        return
    robots = tuple(sorted(r for r, t in self._foreign.items() if t >= horizon))
    if robots != self._foreign_said:
        self._foreign_said = robots
        out.append(ForeignRing(robots, self.mode == MEMBER))


def _slot_failed(self: RotationalMac, robot: int | None, out: list) -> None:
    """Clause 41a: ``robot``'s turn closed on a failed frame (or garbage). Its turns
    failing ``FAILING_SLOT_LIMIT`` times in a row, with good frames heard in between and
    no other member's turn failing, is no noise: two robots with its ID send in lock-step
    (each deaf to the other), or its transmitter garbles. It is dropped, and the ring mask
    that follows tells it so. Only in a ring of three or more (in a ring of two nobody
    else's frames tell a failing slot from a bad channel)."""
    if robot is None or robot == self.id or robot not in self.ring or len(self.ring) < 3 \
            or self._paper:
        return
    run = self._fail_run
    if run is not None and run[0] == robot:
        if not self._good_since_fail:
            return                         # nothing good heard since: a jam, not its slot
        n = run[1] + 1
    else:
        n = 1
    self._good_since_fail = False
    if n >= FAILING_SLOT_LIMIT:
        self._fail_run = None
        self._drop(robot, out)
    else:
        self._fail_run = (robot, n)


def _refuse_outsider(self: RotationalMac, src: int, num: int, end: int, now: int,
                     out: list) -> None:
    """A frame from a team robot that is not in our ring and answers no invitation."""
    n, last = self._heard_disabled.get(src, (0, end))
    if end - last > (len(self.ring) + 1) * self.cfg.tmax:
        n = 0                              # not heard for a whole cycle: start again
    n += 1
    if n < self.cfg.miss_limit:
        self._heard_disabled[src] = (n, end)
        why = f"robot {src} was disabled and not invited back" if src in \
            self.ever_member else f"robot {src} is not a member and was not invited"
    else:
        self._heard_disabled.pop(src, None)
        self._admit(src, out)
        self.misses[src] = 0
        why = f"robot {src} admitted after {n} frames; this one is not acted on"
    out.append(Refused(src, num, why))
    self._next_turn(src, end, now, out)


def _reconcile(self: RotationalMac, src: int, mask: int, now: int, out: list) -> None:
    """Rule R-view (docs/protocol.md §4.4, clause 51): member ``src``'s frame says its ring
    is ``mask``. Left out of it, we go back to LISTEN (as for a poll mask, clause 37). A
    robot it has and we do not, it vouches for: admitted. A robot we have and it does not
    that missed its last turn in our view too: dropped, as ``src`` did. Otherwise, or if the
    views still differ, our next frame tells ours, so that ``src`` learns of the robot.
    Two members whose views differ transmit in each other's slots and may never hear each
    other again (found by the stateful hunt): one clean frame with a mask repairs that."""
    view = _unmask(mask)
    if self.id not in view:
        self._to_listen(out, now, f"left out of robot {src}'s ring (its ring mask)",
                        let_pass=self._unheard_answer())
        return
    for r in sorted(view - set(self.ring)):
        if r in self.cfg.team:
            self._admit(r, out)
    for r in sorted(set(self.ring) - view - {self.id, src}):
        if self.misses.get(r, 0) > 0:
            self._drop(r, out)
    if set(self.ring) != view:
        self._tell_view = True


def _drop(self: RotationalMac, robot: int, out: list) -> None:
    self.ring = tuple(r for r in self.ring if r != robot)
    self._rx_armed.discard(robot)
    self._tell_view = True
    self.misses.pop(robot, None)
    if self._announcing is not None:
        self._ann_awaiting.discard(robot)
        if not self._ann_awaiting:
            self._announced()
    out.append(Disable(robot))
    m = self._inflight
    if m is not None:
        self._unawait(m, robot, f"destination {robot} dropped from the ring after "
                      f"{m.attempts} attempt(s)",
                      "no member left to acknowledge the broadcast", out)


def _announced(self: RotationalMac) -> None:
    """Every member acknowledged our BOOT/JOIN frame: we are in everyone's ring."""
    self._announcing = None
    self._booting = False


def _unheard_answer(self: RotationalMac) -> bool:
    """Our BOOT/JOIN is out and no member has acknowledged it: nobody may have heard it
    (a twin's answer collided with ours, clause 38.2)."""
    return self._announcing is not None and \
        self._ann_awaiting >= set(self.ring) - {self.id}


def _to_listen(self: RotationalMac, out: list, now: int, reason: str,
               let_pass: bool = False) -> None:
    """Back to LISTEN. ``let_pass``: our BOOT/JOIN was never acknowledged (or we were left
    out before anyone acknowledged it): we may be one of two robots with one ID that
    answered an invitation together (their answers collide) and would again: let a seeded
    0-LET_PASS_MAX invitations pass first (clause 38.2)."""
    if let_pass and not self._paper:
        self._let_pass = self._rng.randint(0, LET_PASS_MAX)
    self.mode = LISTEN
    self.ring = ()
    self.phase = WAIT
    self.owner = None
    self.misses = {}
    self._rx_armed.clear()            # robots may restart unheard while we listen
    self._silent = 0
    self._acks.clear()
    self._announcing = None           # a BOOT not acknowledged is sent again
    self._passed_invite = False
    self._check_turns = 0             # back only invited (no PC is ID 0) or as a standby
    self._deaf_check = False
    self._forget_held()               # our acknowledgements are not sent: not ours to deliver
    self._fail_run = None             # clause 41a counts again from our next ring
    self._rejoining = False
    self.deadline = now + self._claim_ticks()
    out.append(ModeChange(LISTEN, reason))


def _left_out_while_stalled(self: RotationalMac, src: int, now: int, out: list) -> None:
    """Our first turn after a stall (``resync``), watched before we send, and robot ``src``
    sends in it: the ring left us out while we did not run (three missed turns, clause 40),
    and the turn was ``src``'s. Back to LISTEN, to be invited (clause 5): nothing sent on the
    stale view, and nobody counted missing for it."""
    self._to_listen(out, now, f"robot {src} sent in our first turn after a stall: the ring "
                    f"left us out meanwhile")


def _auth_refusal(self: RotationalMac, frame: Frame) -> tuple[str, str] | None:
    """Authenticated profile (clause 53): None for a genuine fresh frame (its freshness is
    then remembered as its Source's last), else (kind, reason)."""
    assert self._key is not None                   # called in the authenticated profile
    fresh = _auth.check(self._key, frame)
    if fresh is None:
        return "forged", "forged: no valid authentication tag"
    last = self._auth_rx.get(frame.src)
    if last is not None and fresh <= last:
        return "replayed", f"replayed: freshness {fresh:08x} not above {last:08x}"
    self._auth_rx[frame.src] = fresh
    return None


def _active_frame(self: RotationalMac, frame: Frame, end: int, now: int, out: list,
                  silent: int) -> list:
    """A frame with ID 0 that we did not send: the active PC of the father's pair.
    ``silent``: the misses counted before it with no good frame heard (clause 40)."""
    content = strip_crc(frame.content) if self.cfg.checksum and crc_ok(frame) \
        else frame.content
    if self._key is not None:
        # Genuine and fresh (checked in on_frame). The other PC of the pair sends as ID 0
        # too: our counter goes on from its values, so that a takeover's frames are fresh
        # to every member (clause 53).
        self.auth_tx = max(self.auth_tx, self._auth_rx[0] + 1)
        content = _auth.strip(content)
    try:
        mac_cmds, app_cmds = _layers(content) if content else ((), ())
    except ContentError:
        mac_cmds, app_cmds = (), ()
    if app_cmds:                           # the other PC's own message: its Number is taken
        self._others_number(frame.num, out)
    if not self.standby:
        lone_other = any(c.name == "poll" and c.args[1] == 1 for c in mac_cmds)
        if self.mode == MEMBER and not self.lone and lone_other:
            # The other PC claimed alone (back from a deaf radio, say): it will listen once
            # it hears a member. The children only resynchronise on a lone member's frame
            # (clause 31), so we do too, or we wait for a turn they have passed on and count
            # its healthy owner missing (clause 50).
            self._next_turn(self.id, end, now, out)
            return out
        if self.mode == LISTEN or self.lone or self.cfg.pc > 1 or (
                self.phase == WATCH and self._deaf_check):
            if self.lone:
                self._to_listen(out, now, "another PC is active as ID 0")
            elif self.mode == MEMBER:      # keep the ring we know; follow the other PC
                out.append(ModeChange(MEMBER, "another PC is active as ID 0: standing by"))
            self.standby = True            # the other PC is active: stand by for it
            self._check_turns = 0          # a standby keeps the Numbers (clause 50)
            self._deaf_check = False
            self._forget_held()            # not delivered, so not acknowledged (clause 50)
        else:
            # PC1 stays active (a PC2 that is active too will yield); the frame, PC2's or
            # a forger's, is refused and closes the slot it was sent in. Heard after a miss
            # with no frame accepted since, it says we were deaf while PC2 took over: on
            # probation we leave new messages to PC2 (clause 50), or both deliver them.
            if silent:
                self._check_turns = 3
            # our Numbers go on after the other PC's (its message's, or its control frame's,
            # which repeats its last message's, clause 45): a PC that stalled while the other
            # took over reused one of its Numbers, and the members took its next message for
            # a duplicate (clause 48), acknowledged and never delivered
            if 0 < (frame.num - self._last_num) % 100 < 50:
                self._last_num = frame.num
                self._next_num = self._number_after_others(frame.num)
            self._own_id_heard(frame.num, end, now, out)
            return out
    if self.mode == LISTEN:
        horizon = end - self.cfg.claim_ticks(0)
        members = {r for r, t in self._seen.items() if t >= horizon} | {self.id}
        self.mode = MEMBER
        self.ring = tuple(sorted(members))
        self.misses = {r: 0 for r in self.ring}
        self.ever_member |= set(self.ring)
        self._booting = False
        out.append(ModeChange(MEMBER, "standing by for the active PC (ID 0)"))
    sent_acks = {(c.args[0], c.args[1]) for c in mac_cmds if c.name == "ack"}
    self._acks = [a for a in self._acks if a not in sent_acks]
    if self._held:                         # the active PC delivered these (clause 50)
        self._held = [d for d in self._held if (d.src, d.num) not in sent_acks]
    if app_cmds:                           # keep our Numbers after the active PC's
        self._last_num = frame.num
        self._next_num = self._number_after_others(frame.num)
    self.misses[self.id] = 0
    self._silent = 0
    invited = [c.args[0] for c in mac_cmds if c.name == "poll" and c.args[0] not in self.ring]
    if invited:
        self._window(invited[0], self.id, end, now)
    else:
        ring = self.ring
        i = bisect_right(ring, self.id)
        nxt = ring[i] if i < len(ring) else ring[0]
        if nxt == self.id:
            self._hold(end + self.cfg.twin + self.id * self.cfg.tslot, now, out)
        else:
            self.phase = WAIT
            self.owner = nxt
            self.turn_start = end
            self.deadline = end + self.cfg.tmax
    return out

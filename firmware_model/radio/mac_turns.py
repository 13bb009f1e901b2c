"""The rotational MAC's turn machinery (paper §IV.C; docs/protocol.md §4.2, §4.6): whose turn
comes next and when (rules R-stagger and R-pair), poll windows, the pause before a turn, our own
turn (TXEN, Ttrans, the frame), a takeover heard with a slower clock, and the watch a father PC
keeps on ID 0's turn. Functions of a ``RotationalMac``, bound as its methods in mac.py."""
from __future__ import annotations

from typing import TYPE_CHECKING

from .mac_config import PC2_CHECK_EVERY, TAKEOVER_TOLERANCE
from .mac_events import TX_ON, Deliver, Miss, Transmit
from .mac_phases import HOLD, MEMBER, SEND, SWITCH, WAIT, WATCH, WINDOW

if TYPE_CHECKING:
    from .mac import RotationalMac


def _watch_ticks(self: RotationalMac) -> int:
    """How long after a turn begins we listen for the other PC's header (docs/mac.md).

    An active PC2 checking for PC1 waits W past Ttrans; a standby waits Ttrans +
    (pc + 2) W, longer than a checking PC2 needs to raise TXEN, wait Ttrans and get its
    header out, so a standby never takes a turn from a live active PC."""
    w = max(4 * self.cfg.byte_ticks, self.cfg.standby_watch)
    if self.standby:
        return 2 * self.cfg.ttrans + (self.cfg.pc + 2) * w
    if (self._deaf_check or self._check_turns) and self.cfg.pc == 1:
        # PC1 back from a possible deafness, or on probation, watches past the Header of a
        # PC2 that watches its own turn first (TXEN at Ttrans + W, Header Ttrans later), and
        # still sends early enough for a standby PC2 to hear it (2 Ttrans + 4 W). With the
        # same watch, two PCs on probation would send at one tick, each deaf to the other.
        return 2 * (self.cfg.ttrans + w)
    return self.cfg.ttrans + w


def _heard_after_tx(self: RotationalMac, first: int, good: bool,
                    last: int | None = None) -> None:
    """Something was heard, its first byte in at ``first``: a good frame (``good``), or a
    failed one or garbage, its last byte in by ``last`` (a good frame is told here only when
    it is the first since our own). Heard by an active PC of a pair after more silence than
    a live successor's Header can take (Ttrans + 6 Tslot + 5 B: its latest R-stagger, clause
    44, and a byte), counted from the last thing heard (our own frame's End, the last
    accepted frame's End, or the quiet after the last failed reception: its last byte and
    the quiet gap, where that turn closes, clause 42), it says our radio may have been deaf
    while the other PC took over (a radio that died in the middle of a frame hears it fail,
    then nothing; one back in the middle of a frame hears garbage): we check (clause 50)."""
    cfg = self.cfg
    heard = self._last_heard
    if self._active_pc_of_pair() and first - max(self._tx_end, self._rx_quiet + cfg.quiet_gap,
                        0 if heard is None else heard[1]) > \
            cfg.ttrans + 6 * cfg.tslot + 5 * cfg.byte_ticks:
        self._deaf_check = True
    if good:
        self._heard_since_tx = True
    else:
        self._noise_since_tx = True
        self._rx_quiet = max(self._rx_quiet, first if last is None else last)


def _deliver(self: RotationalMac, d: Deliver, out: list) -> None:
    """Deliver a new message, or hold it (clause 50): while we check after a possible
    deafness, until our watched turn finds no other PC on the air and our acknowledgement
    goes out; as a standby, as a replica, which the active PC's acknowledgement on the air
    drops; one it never acknowledged, a takeover neither delivers nor acknowledges but
    forgets (``_forget_held``), so the sender retries: no PC acknowledges a message it did
    not deliver. What we held of a sender's earlier message went as its next one came
    (``_message_heard``)."""
    if self._deaf_check or self.standby:
        self._held.append(d)
    else:
        out.append(d)


def _message_heard(self: RotationalMac, src: int, num: int) -> bool:
    """A message frame from ``src`` (to anyone) accepted: is it new, not a retransmission?
    A sender keeps one message in flight, so a retransmission repeats the Number of the
    last message frame heard from it, whoever it was for; and its new message means the
    last one ended at the sender, so a delivery we held of it goes (clause 50)."""
    fresh = self._last_rx.get(src) != num
    self._last_rx[src] = num
    self._rx_armed.add(src)
    if fresh and self._held:
        self._held = [d for d in self._held if d.src != src]
    return fresh


def _forget_held(self: RotationalMac) -> None:
    """Drop the deliveries we held (clause 50) with the acknowledgements we owed for them,
    and forget having received them: their senders retry, and a retry must be new to us,
    not a duplicate acknowledged and never delivered."""
    if not self._held:
        return
    held = {(d.src, d.num) for d in self._held}
    self._acks = [a for a in self._acks if a not in held]
    for d in self._held:
        if self._last_rx.get(d.src) == d.num:
            del self._last_rx[d.src]
            self._rx_armed.discard(d.src)
    self._held = []


def _takeover(self: RotationalMac, src: int, first: int) -> list[int] | None:
    """Is a frame from ``src`` (not the robot we wait for) a rightful takeover seen with a
    slower clock? Yes when ``src`` follows the expected owner(s) in ring order and its
    header came at least one Tmax per skipped robot (one Twin for an unanswered
    invitation) after the turn began, within TAKEOVER_TOLERANCE: returns the skipped
    robots, to be counted as missed as our own timer would have (rule 3 of docs/mac.md,
    clause 39); None when it is no takeover (the frame is out of turn)."""
    if self.owner is None:
        return []                  # resynchronising (``resync``): any member's frame
    cfg = self.cfg
    elapsed = first - cfg.byte_ticks - self.turn_start
    slack = 1.0 - TAKEOVER_TOLERANCE
    if self.phase == WINDOW:
        assert self.poller is not None             # WINDOW: someone opened it
        # The poller's successor raises TXEN at the window's end, E + Twin, so its Header
        # begins at E + Twin + Ttrans by its clock (clause 39; 0.95 x Twin once let a
        # forged frame 9.6 ms after a poll pass for it, issue 42).
        ok = src == self.succ(self.poller) and elapsed >= (cfg.twin + cfg.ttrans) * slack
        return [] if ok else None
    skipped: list[int] = []
    o = self.owner
    assert o is not None                           # called with a turn's owner known
    while o != src and len(skipped) <= len(self.ring):
        skipped.append(o)
        o = self.succ(o)
    if o != src or elapsed < len(skipped) * cfg.tmax * slack or self.id in skipped:
        return None
    return skipped


def _count_skipped(self: RotationalMac, skipped: list[int], out: list) -> None:
    """A takeover seen late: the robots it skipped missed their turns (clause 39)."""
    cfg = self.cfg
    self._missed_on_a_frame()
    for r in skipped:
        n = self.misses.get(r, 0) + 1
        self.misses[r] = n
        out.append(Miss(r))
        if n >= cfg.miss_limit:
            self._drop(r, out)


def _missed_on_a_frame(self: RotationalMac) -> None:
    """A robot counted missing on a frame heard in its slot or after it (clause 39). An
    active PC of a pair that has accepted no frame since its own may have been deaf: its
    radio back in the middle of a frame (garbage, then a robot later than the one awaited),
    or in its own watched turn, while the other PC took over and ended its probation. Both
    would send in ID 0's slot, each deaf to the other: we check our next turn (clause 50)."""
    heard = self._last_heard
    if self._active_pc_of_pair() and (heard is None or heard[1] <= self._tx_end):
        self._deaf_check = True


def _active_pc_of_pair(self: RotationalMac) -> bool:
    """An active member PC of the father's pair: the one that checks after a possible
    deafness (clause 50; a lone father has nobody to deliver twice with)."""
    return self.id == 0 and self.cfg.paired and not self.standby and self.mode == MEMBER


def force_turn(self: RotationalMac, now: int) -> list:
    """Fault injection: believe the turn is ours right now (a member that missed a frame
    and wrongly takes over). Used to force collisions in tests and fault studies."""
    out: list = []
    if self.mode == MEMBER and self.phase in (WAIT, WINDOW, HOLD):
        self._my_turn(now, now, out)
    return out


def _pair_floor(self: RotationalMac, other: int) -> int | None:
    """Rule R-pair (clause 44): in a ring of two, after our own frame and silence, the
    other member may not have heard our frame either; then it takes the turn at its last
    End + Tmax + other x Tslot (R-stagger). We raise TXEN no earlier than that plus the
    time to hear its Header (Ttrans + 4 bytes), so one of us always hears the other:
    otherwise a turn one Tslot long (a heartbeat) cancels the stagger and both transmit
    within a byte time (found by the token-lost scenarios)."""
    heard = self._last_heard
    if heard is None or heard[0] != other or self._paper:
        return None
    cfg = self.cfg
    return heard[1] + cfg.tmax + other * cfg.tslot + cfg.ttrans + 4 * cfg.byte_ticks


def _next_turn(self: RotationalMac, after: int, start: int, now: int, out: list,
               uncertain: bool = False, not_before: int | None = None) -> None:
    """The turn after ``after`` begins at ``start``: its owner may raise TXEN then.

    ``uncertain``: the turn closed on something other than a good frame (bytes that formed
    none, a frame that failed) or on a miss right after our own frame. Two members can
    each believe the other's turn just closed (a foreign burst over a hand-over, a
    collision): the owner then waits ``id`` x Tslot more, listening, so of two such
    members the higher ID hears the lower's Header before it raises TXEN (docs/protocol.md
    §4.6, clause 44: R-stagger). ``not_before``: our turn does not start before this tick
    (rule R-pair, ``_pair_floor``)."""
    if not self.ring:
        return
    if self.lone and after == self.id:
        self._hold(start + self.cfg.twin + self.id * self.cfg.tslot, now, out)
        return
    nxt = self.succ(after)
    if nxt == self.id:
        if uncertain and not self._paper:      # the paper: the turn at E + Tmax, no more
            if self.cfg.quiet_channel:
                self._hold_ref = start
                self.phase = HOLD
                self.owner = self.id
                self.deadline = max(now, start + self.id * self.cfg.tslot,
                                    not_before or 0)
                return
            start += self.id * self.cfg.tslot
            if not_before is not None and not_before > start:
                start = not_before
        self._my_turn(start, now, out)
    else:
        self.phase = WAIT
        self.owner = nxt
        self.turn_start = start
        self.deadline = start + self.cfg.tmax


def _window(self: RotationalMac, invited: int, poller: int, end: int, now: int) -> None:
    self.phase = WINDOW
    self.owner = invited
    self.poller = poller
    self.turn_start = end
    self.deadline = end + self.cfg.twin


def _after_window(self: RotationalMac, poller: int, now: int, out: list) -> None:
    if self.lone:
        self._hold(self.turn_start + self.cfg.twin + self.id * self.cfg.tslot, now, out)
    else:
        self._next_turn(poller, now, now, out)


def _hold(self: RotationalMac, start: int, now: int, out: list) -> None:
    self._hold_ref = None
    if start <= now:
        self._my_turn(now, now, out)
    else:
        self.phase = HOLD
        self.owner = self.id
        self.deadline = start


def _my_turn(self: RotationalMac, start: int, now: int, out: list) -> None:
    if start > now:
        self._hold(start, now, out)
        return
    if self.standby or self._rejoining or (not self._watched and self.id == 0 and (
            self._check_turns > 0 or self._deaf_check or
            self.cfg.pc > 1 and self.turns % PC2_CHECK_EVERY == 0)):
        # The active PC's header starts at start + Ttrans and is complete 3 bytes later.
        # A PC that took over watches its first turns (PC1 too: otherwise its probation,
        # which leaves messages undelivered, never ended), and an active PC2 one turn
        # in PC2_CHECK_EVERY: if PC1 were active too, both would send in the same slot,
        # each deaf to the other, for ever. Our first turn after a stall is watched alike:
        # the ring may have left us out meanwhile and given it to the next robot (clause 5).
        self.phase = WATCH
        self.owner = self.id
        self.turn_start = start
        self.deadline = start + self._watch_ticks()
        return
    self.phase = SWITCH
    self.owner = self.id
    self.turn_start = now
    self.deadline = now + self.cfg.ttrans
    out.append(TX_ON)


def _send(self: RotationalMac, now: int, out: list) -> None:
    frame, data = self._build_frame(now, out)
    self.phase = SEND
    self.deadline = None
    self.turns += 1
    out.append(Transmit(frame, data))

"""What the rotational MAC's one deadline means in each state (docs/protocol.md §4.2-§4.6,
§4.9): LISTEN claims a silent channel, WAIT counts a miss, WINDOW ends an invitation, HOLD and
SWITCH start and send our turn, QUIET closes a failed frame's turn, WATCH follows or replaces
the active father PC. Functions of a ``RotationalMac``, bound as its methods in mac.py, and
dispatched per phase by ``DEADLINE_HANDLERS`` there (the rows of ``mac_table.TRANSITIONS``
with event "deadline")."""
from __future__ import annotations

from typing import TYPE_CHECKING

from .mac_events import Miss, ModeChange
from .mac_phases import MEMBER, WAIT

if TYPE_CHECKING:
    from .mac import RotationalMac


def _deadline_listen(self: RotationalMac, now: int, rx_busy: bool, out: list) -> None:
    """LISTEN: silence for Tclaim(id): claim the channel, a ring of one (start-up)."""
    if rx_busy:
        self.deadline = now + 2 * self.cfg.byte_ticks  # someone is on air: not silent
        return
    if self._paper:                # a silent channel: the static ring starts again
        out.extend(self._paper_power_on(now)[1:])
        return
    self.mode = MEMBER
    self.ring = (self.id,)
    self.misses = {self.id: 0}
    self.ever_member.add(self.id)
    self._silent = 0
    self._turns_since_poll = self.cfg.poll_every
    out.append(ModeChange(MEMBER, "claimed the silent channel"))
    self._my_turn(now, now, out)


def _deadline_watch(self: RotationalMac, now: int, rx_busy: bool, last_rx: int | None,
                    rx_began: int | None, out: list) -> None:
    """WATCH (father failover): the active PC's Header came, follow it; else take the turn.
    Our first turn after a stall: a Header in it is another robot's, to which the ring gave
    the turn after leaving us out (``_left_out_while_stalled``); else the ring still has us."""
    if self._rejoining:
        if rx_busy:
            # (its Source is not read yet: the ring's successor, the one robot it can be)
            self._to_listen(out, now, "a robot sent in our first turn after a stall: the "
                            "ring left us out meanwhile")
            return
        self._rejoining = False
    if rx_busy and self._deaf_check and not self.standby:
        # Checking after a possible deafness: whose frame is it? The other PC's stands us by
        # (``_active_frame``); a member's is followed, and our next turn is watched again.
        self.deadline = now + 2 * self.cfg.byte_ticks
        return
    if rx_busy or self._heard_since_tx:
        # Watched with a radio that hears: the check is done. The deliveries it held go out
        # with our acknowledgements, or, if the other PC is sending, are its to make.
        self._deaf_check = False
        if not self.standby:       # (a standby's replicas stay, or go at a takeover below)
            if rx_busy:
                self._forget_held()
            else:
                out.extend(self._held)
                self._held = []
    if rx_busy:                    # the active PC is sending: follow it
        if not self.standby:
            self.standby = True
            self._check_turns = 0
            out.append(ModeChange(MEMBER, "the other PC is still active: standing by"))
        self.phase = WAIT
        self.deadline = self.turn_start + self.cfg.tmax
        return
    if self.standby:
        self.standby = False
        self._check_turns = 3      # probation: a takeover may have been mistaken
        # What the active PC never acknowledged on the air is not ours to acknowledge: on
        # probation we deliver nothing new, and an acknowledgement without a delivery is a
        # message lost; forgotten, it is retried, and new to us (clause 50).
        self._forget_held()
        out.append(ModeChange(MEMBER, "took over ID 0's turn: the active PC is silent"))
    elif self._check_turns > 0:
        self._check_turns -= 1
    self._watched = True
    self._my_turn(now, now, out)
    self._watched = False


def _deadline_switch(self: RotationalMac, now: int, rx_busy: bool, last_rx: int | None,
                     rx_began: int | None, out: list) -> None:
    """SWITCH: Ttrans after TXEN rose, the radio transmits: send the frame (paper §IV)."""
    self._send(now, out)


def _deadline_hold(self: RotationalMac, now: int, rx_busy: bool, last_rx: int | None,
                   rx_began: int | None, out: list) -> None:
    """HOLD: our turn starts, unless a frame is coming in, or a jam that followed an
    uncertain closure has not yet been quiet for id x Tslot (rule R-stagger)."""
    if rx_busy:
        self.deadline = now + 2 * self.cfg.byte_ticks  # someone is sending: hear it
        return
    ref = self._hold_ref
    if ref is not None and last_rx is not None and last_rx > ref and \
            now < ref + 2 * self.cfg.tmax:
        # Bytes kept coming after the turn closed (a jam): the stagger runs from the
        # moment the channel fell quiet, the one instant every member hears alike.
        talk = last_rx + self.cfg.quiet_gap + self.id * self.cfg.tslot
        if talk > now:
            self.deadline = min(talk, ref + 2 * self.cfg.tmax)
            return
    self._hold_ref = None
    self._my_turn(now, now, out)


def _deadline_quiet(self: RotationalMac, now: int, rx_busy: bool, last_rx: int | None,
                    rx_began: int | None, out: list) -> None:
    """QUIET: a frame failed before its Length; the turn closes when the channel falls
    quiet (rule R-stagger follows), or, if only noise was ever heard, at E + Tmax as a
    miss (paper §IV.C)."""
    if rx_busy:
        self.deadline = now + 2 * self.cfg.byte_ticks  # a header is in; let it finish
        return
    gap = self.cfg.quiet_gap
    quiet = last_rx is None or now - last_rx >= gap
    if self._quiet_miss and not quiet and now >= self._quiet_limit:
        self.phase = WAIT                              # only noise: a real miss
        self._quiet_miss = False
        self._deadline_wait(now, rx_busy, last_rx, None, out)
        return
    if quiet or now >= self._quiet_limit:
        owner = self.owner
        assert owner is not None                   # QUIET is an owner's slot
        garbled = owner if self._quiet_miss else None
        self._quiet_miss = False
        self._slot_failed(owner, out)
        self._next_turn(owner, now, now, out, uncertain=True)  # the frame is over
        if garbled is not None and self.phase == WAIT:
            self._garbled = (garbled, self.turn_start, self.owner)
    else:
        assert last_rx is not None                 # not quiet: bytes were heard
        self.deadline = min(last_rx + gap, self._quiet_limit)


def _header_coming(self: RotationalMac, now: int, rx_busy: bool, rx_began: int | None,
                   limit: int) -> bool:
    """A Header is being received, or had begun by ``limit`` (paper §IV.C: a miss is a
    Header that "has not begun by E + Tmax"): look again when its next byte is in."""
    if rx_busy:
        self.deadline = now + 2 * self.cfg.byte_ticks  # a header is in; let it finish
        return True
    if rx_began is not None and rx_began <= limit:
        self.deadline = now + self.cfg.byte_ticks
        return True
    return False


def _deadline_window(self: RotationalMac, now: int, rx_busy: bool, last_rx: int | None,
                     rx_began: int | None, out: list) -> None:
    """WINDOW: the invited robot did not answer by E + Twin: the poller's successor's turn
    (or a lone member's next pause)."""
    if not self._header_coming(now, rx_busy, rx_began, self.turn_start + self.cfg.twin):
        assert self.poller is not None             # WINDOW: someone opened it
        self._after_window(self.poller, now, out)


def _deadline_wait(self: RotationalMac, now: int, rx_busy: bool, last_rx: int | None,
                   rx_began: int | None, out: list) -> None:
    """WAIT: the owner's Header has not begun by E + Tmax: a miss, the next robot's turn
    (paper §IV.C); the third miss in a row drops it (paper §IV.C)."""
    o = self.owner
    if o is None:                  # resynchronising after a stall (``resync``)
        if rx_busy:
            self.deadline = now + 2 * self.cfg.byte_ticks
            return
        self._to_listen(out, now, "heard no ring since this station stalled")
        return
    if self._header_coming(now, rx_busy, rx_began, self.turn_start + self.cfg.tmax):
        return
    n = self.misses.get(o, 0) + 1
    self.misses[o] = n
    out.append(Miss(o))
    if o not in self._unheard:
        # the cut-off (clause 40) counts misses of robots heard since the static ring
        # began (paper profile, docs/protocol.md §9.1): a team robot never heard is no
        # evidence that our radio is cut off
        self._silent += 1
    self._tell_view = True
    # An active father PC that missed two turns with nothing at all heard since its own
    # frame may have been deaf while its standby took ID 0's turn (clause 50): if its radio
    # comes back before it goes to LISTEN, both PCs are active and both would deliver.
    pair = self._active_pc_of_pair()
    deaf = pair and self._silent >= 2 and not self._heard_since_tx and \
        not self._noise_since_tx
    if pair and not self._heard_since_tx and \
            now - max(self._tx_end, self._rx_quiet) >= self.cfg.tmax:
        # An active PC that missed a turn with no good frame since its own and nothing at
        # all heard for Tmax (a radio that died in the middle of a frame heard it fail) may
        # have been deaf while the other PC took over (clause 50): it delivers nothing new
        # until it has watched its next turn for the other PC's Header.
        self._deaf_check = True
    if n >= self.cfg.miss_limit:
        self._drop(o, out)
    if len(self.ring) >= 2 and \
            self._silent >= max(self.cfg.miss_limit, len(self.ring) - 1):
        self._to_listen(out, now, "heard nobody for a whole round")
        return
    if deaf:
        self._check_turns = 3      # probation, as after a takeover (clause 50)
    # The paper's takeover at E + Tmax, except when nobody was heard since our own
    # frame: then we may be one of two members that sent together, each waiting for
    # the other (rule R-stagger).
    floor = None
    if not self._heard_since_tx and len(self.ring) == 2:
        floor = self._pair_floor(o)
    self._next_turn(o, now, now, out, uncertain=not self._heard_since_tx, not_before=floor)

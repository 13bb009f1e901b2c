"""The rotational MAC's paper profile (``MacConfig(profile="paper")``, docs/protocol.md §9): a
static ring of the whole team from power-on, good frames taken as the paper takes them, and the
paper's frames (a message sent once, or an empty heartbeat). Functions of a ``RotationalMac``,
bound as its methods in mac.py; the rest of the profile is the branches on ``_paper`` there."""
from __future__ import annotations

from typing import TYPE_CHECKING

from .errors import ContentError
from .frame import BROADCAST, Frame, FrameType
from .mac_config import TAKEOVER_TOLERANCE
from .mac_events import TX_OFF, UNACKNOWLEDGED, BadContent, Deliver, ModeChange, Outcome, Refused
from .mac_frames import _layers
from .mac_phases import LISTEN, MEMBER, WAIT

if TYPE_CHECKING:
    from .mac import RotationalMac


def _paper_power_on(self: RotationalMac, now: int) -> list:
    out: list = [TX_OFF]
    self._last_num = 0
    self._next_num = 0                 # the paper: a robot's first message is '00'

    self.mode = MEMBER
    self.ring = tuple(sorted(set(self.cfg.team) | {self.id}))
    self.misses = {r: 0 for r in self.ring}
    self.ever_member = set(self.ring)
    self._unheard = set(self.ring) - {self.id}
    self._booting = False
    self._announcing = None
    self._silent = 0
    self._rejected = 0
    out.append(ModeChange(MEMBER, "a member of the static ring of the team (paper profile)"))
    first = self.ring[0]
    if first == self.id:
        self._my_turn(now, now, out)
    else:                              # paper §IV.C: first's turn; takeover at + Tmax
        self.phase = WAIT
        self.owner = first
        self.turn_start = now
        self.deadline = now + self.cfg.tmax
    return out


def _paper_frame(self: RotationalMac, frame: Frame, first: int, end: int, now: int) -> list:
    """A good frame, in the paper profile (paper §IV.C-D): the owner is whoever sends (a
    team robot outside the ring is back in it), and a message for us is delivered. No MAC
    command is obeyed, nothing is acknowledged, and, as no paper robot retransmits, no
    message is taken for a duplicate."""
    out: list = []
    src = frame.src
    after_own = not self._heard_since_tx
    self._heard_since_tx = True
    if src == self.id:
        self._own_id_heard(frame.num, end, now, out)
        return out
    if src not in self.cfg.team:
        self._foreign_heard(src, end, out)
        out.append(Refused(src, frame.num, f"robot {src} is not in the team"))
        out.extend(self.on_corrupt(first, None, end, now))
        return out
    if self.mode == LISTEN:            # out of the ring while it talks: no rejoin
        self.deadline = now + self._claim_ticks()
        return out
    if after_own and not self._noise_since_tx and src != self.succ(self.id) and \
            first - self._tx_end < (1.0 - TAKEOVER_TOLERANCE) * self.cfg.tmax:
        # The first thing heard after our frame is someone sending in our successor's
        # slot without waiting Tmax for it: our frame was not heard (it collided with a
        # robot that has our slot; garbage first would mean a collision of others). Twice
        # in a row means the ring dropped us, and the paper has no way back in: stay out.
        self._rejected += 1
        if self._rejected >= 2:
            self._to_listen(out, now, "our slot is taken: the ring dropped us (the "
                            "paper profile has no rejoin)")
            return out
    elif after_own:
        self._rejected = 0
    if src not in self.ring:
        self._admit(src, out)
    elif self.phase == WAIT and src != self.owner:
        skipped = self._takeover(src, first)
        if skipped is None:
            # Not a takeover by its timing (it came sooner than a Tmax a robot skipped): the
            # owner is whoever sends all the same, and the robots it passed over, but us, did
            # not send in their turns. Else a robot powered on after the others, whose ring
            # still held a robot they had dropped, waited for that robot for ever, never
            # counting it missing, and never had a turn (a silent "member").
            skipped = _passed_over(self, src)
        if skipped:
            self._count_skipped(skipped, out)
    self._last_heard = (src, end)
    self.misses[src] = 0
    self._silent = 0
    if self._unheard:
        self._unheard.discard(src)
    if frame.dst == self.id or frame.dst == BROADCAST:
        try:
            app_cmds = _layers(frame.content)[1] if frame.content else ()
            if app_cmds:
                out.append(Deliver(src, frame.dst, frame.num, frame.type, app_cmds))
        except ContentError as exc:
            out.append(BadContent(src, frame.num, exc))
    self._next_turn(src, end, now, out)
    return out


def _paper_build(self: RotationalMac, now: int, out: list) -> tuple[Frame, bytes]:
    """The paper profile's frame: the next message, sent once (it ends ``sent``: nothing
    acknowledges it), or an empty heartbeat (Type '3', Destination '7')."""
    m = self._pick_message(now, out)
    if m is not None:
        self._inflight = None
        m.attempts = 1
        m.state = UNACKNOWLEDGED
        m.reason = "sent once; the paper profile has no acknowledgement"
        self._last_num = m.num
        out.append(Outcome(m, False, m.reason))
        frame = self._frame(m.dst, m.num, m.type, m.content)
        return frame, frame.encode()
    frame = self._frame(BROADCAST, self._last_num, FrameType.BROADCAST_INFO, b"")
    return frame, frame.encode()


def _passed_over(self: RotationalMac, src: int) -> list[int]:
    """The ring's robots from the owner we waited for up to ``src`` (not included), but us:
    those whose turns ``src``'s frame passed over (paper profile)."""
    out: list[int] = []
    o = self.owner
    while o is not None and o != src and len(out) <= len(self.ring):
        if o != self.id:
            out.append(o)
        o = self.succ(o)
    return out if o == src else []

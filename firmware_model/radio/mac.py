"""The rotational TDMA MAC (paper §IV.C, Figs. 6-7; docs/protocol.md §4) as a sans-IO state
machine.

Events go in (``on_frame``, ``on_corrupt``, ``on_timer``, ``on_tx_done``, ``submit``), actions and
observations come out as lists, and the single timer the MAC needs is exposed as ``deadline`` (a
tick, or None). The MAC owns no clock and does no I/O: the child firmware, the father station and
the tests drive it. Every time is an integer tick of the 16 MHz machine clock.

The same machine as a table (state x event -> next state, with the rule each row follows) is
``firmware_model/radio/mac_table.py``; tests/firmware_model/radio/test_mac_table.py checks the two
agree, and a deadline is dispatched per state through ``DEADLINE_HANDLERS``.

Rules, with the paper's part and this project's designed part (docs/mac.md gives the bounds):

* Ring order is ascending ID over the live members; the owner of a turn sends exactly one frame.
  When a turn closes at tick E the next member raises TXEN at E and sends at E + Ttrans.
* If the owner's header has not been heard by E + Tmax, that turn is a *miss*; the next member
  raises TXEN at E + Tmax (and so on, E + 2 Tmax ...). After ``miss_limit`` consecutive misses a
  robot is *disabled* (dropped) by every member at the same tick.
* Any valid frame resynchronises the hearer: the turn belongs to whoever actually sent it.
* Designed here — start-up: a robot powers on in LISTEN and never transmits until it is invited
  (polled) or has heard nothing for ``claim_ticks`` (longer than any silence a live ring makes,
  staggered by ID), when it *claims* the channel as a ring of one.
* Designed here — join/rejoin: the member whose turn precedes a gap of absent team IDs invites
  one of them (Content command ``poll(id,mask)``; mask = the ring as a bit mask) at most every
  ``poll_every`` of its turns (every turn while it is alone). After a polling frame every member
  waits a short window ``Twin``; the invited robot answers by sending its frame at E + Ttrans and
  is then a member for everyone who hears it. A member that reads its own ID missing from a poll
  mask knows it was dropped and goes back to LISTEN.
* Designed here — collisions and corruption: a frame that fails after a valid header still
  closes the turn (at the end its Length promises, or E + Tmax when unknown); it is not a miss.
  A member that hears nobody for a whole round of misses concludes its radio is cut off and goes
  back to LISTEN; a lone member that hears another robot goes back to LISTEN too. A lone member
  waits ``Twin + id * Tslot`` between its frames, so two robots that claimed together drift
  apart by at least one Tslot and the later one hears the earlier.
* Designed here — delivery: each message gets the sender's next Number; it is acknowledged by
  its destination (by every member, for a broadcast) with ``ack(src,num)`` piggybacked in the
  destination's next frame; the sender retransmits with the same Number at each of its turns
  until acknowledged, at most ``max_attempts`` times, then reports it failed with a reason.
  Receivers deliver once per (Source, Number) and re-acknowledge duplicates.

Over 500 lines on purpose: the MAC is one state machine over one state. This module holds that
state, the events in (``on_frame`` with its fast path, ``on_timer``, ``on_tx_done``, ``resync``)
and the queries; the rest is in modules of its own, as functions of a ``RotationalMac`` bound
here as its methods: the failed receptions (mac_failed.py), the outbox (mac_outbox.py), one
deadline handler per state (mac_deadlines.py), the turn machinery (mac_turns.py), membership
(mac_membership.py), frame building (mac_frames.py) and the paper profile (mac_paper.py). What
it hands out is mac_events.py, its configuration mac_config.py, its modes and phases
mac_phases.py; its readable form, the transition table, is mac_table.py.
"""
from __future__ import annotations

import random
from bisect import bisect_right
from typing import Any, Sequence

from ..timing import (max_content_bytes, protocol_max_content,  # the rest importable here,
    CHILD_BYTE_TICKS as CHILD_BYTE_TICKS,                        # as before MacConfig moved
    MISS_LIMIT as MISS_LIMIT,
    PC_BYTE_TICKS as PC_BYTE_TICKS,
    TMAX_TICKS as TMAX_TICKS,
    TTRANS_TICKS as TTRANS_TICKS,
)
from .errors import ContentError
from .frame import BROADCAST, Frame, FrameType
from . import auth as _auth
from .integrity import CRC_TEXT_LEN, check as crc_ok, strip as strip_crc
# The MAC's records and configuration live in modules of their own; every public name stays
# importable from here (``from firmware_model.radio.mac import MacConfig, Deliver``).
from .mac_config import (
    BEHIND_WINDOW,
    FAILING_SLOT_LIMIT,
    LET_PASS_MAX,
    PC2_CHECK_EVERY,
    PROFILES,
    TAKEOVER_TOLERANCE,
    TWIN_FRAMES,
    MacConfig,
    check_submission,
)
from . import (
    mac_deadlines as _deadlines,
    mac_failed as _failed,
    mac_frames as _frames,
    mac_membership as _members,
    mac_outbox as _outbox,
    mac_paper as _paper,
    mac_turns as _turns,
)
from .mac_frames import _layers, _unmask
from .mac_phases import (
    HOLD, LISTEN, MEMBER, QUIET, SEND, SWITCH, WAIT, WATCH, WINDOW, Phase,
)
from .mac_events import (
    TX_OFF,
    TX_ON,
    UNACKNOWLEDGED,
    BadChecksum,
    BadContent,
    Deliver,
    Disable,
    Duplicate,
    DuplicateId,
    ForeignRing,
    Join,
    Message,
    Miss,
    ModeChange,
    NumberBehind,
    Outcome,
    QueueFull,
    Refused,
    StandingBy,
    SubmitError,
    Transmit,
    TxEnable,
)

__all__ = [
    "RotationalMac", "DEADLINE_HANDLERS", "LISTEN", "MEMBER", "Phase", "WAIT", "WINDOW", "HOLD",
    "SWITCH", "SEND", "QUIET", "WATCH", "MacConfig", "check_submission", "PROFILES",
    "PC2_CHECK_EVERY", "TAKEOVER_TOLERANCE", "TWIN_FRAMES", "BEHIND_WINDOW", "FAILING_SLOT_LIMIT",
    "LET_PASS_MAX", "TxEnable", "TX_ON", "TX_OFF", "Transmit", "Miss", "Disable", "Join",
    "ModeChange", "Deliver", "Duplicate", "BadContent", "Refused", "NumberBehind", "DuplicateId",
    "ForeignRing", "BadChecksum", "Outcome", "Message", "UNACKNOWLEDGED", "SubmitError",
    "QueueFull", "StandingBy",
]

_NOTHING: tuple = ()


class RotationalMac:
    """One robot's MAC. Create, call ``power_on(now)``, then feed it events."""

    STEADY_COUNTERS = ("frames_sent",)
    """Frames it sent: counts only (reports; hil/sim/steady.py)."""
    STEADY_MODULAR = {"turns": PC2_CHECK_EVERY}
    """``turns`` is read only modulo ``PC2_CHECK_EVERY`` (the standby PC2's checks,
    mac_turns.py); without a standby PC nothing reads it (hil/sim/steady.py)."""

    def __init__(self, robot_id: int, config: MacConfig | None = None) -> None:
        if not 0 <= robot_id <= 6:
            raise ValueError(f"robot ID must be 0-6, got {robot_id}")
        self.id = robot_id
        self.cfg = cfg = config or MacConfig()
        self.max_content = min(max_content_bytes(cfg.byte_ticks, cfg.tmax),
                               protocol_max_content(cfg.tmax))
        """Largest Content this robot sends: what fits in Tmax at its own byte time, never
        more than the protocol's Length bound (which every receiver accepts)."""
        self.rx_max_content = protocol_max_content(cfg.tmax)
        """Largest Length this robot accepts: the protocol's bound (docs/protocol.md §3.1,
        clause 11)."""
        self.mode = LISTEN
        self.phase: Phase = WAIT
        self.ring: tuple[int, ...] = ()
        self.owner: int | None = None     # whose header we wait for (WAIT/WINDOW)
        self.poller: int | None = None    # who opened the current WINDOW
        self.turn_start = 0
        self.deadline: int | None = None
        self.misses: dict[int, int] = {}
        self.ever_member: set[int] = set()
        self._silent = 0                  # consecutive misses with no frame heard at all
        self._unheard: set[int] = set()   # paper profile: static-ring robots not heard yet
        self._queue: list[Message] = []
        self._inflight: Message | None = None
        self._next_num = 0
        self._last_num = 0               # Number a control frame repeats: the last one sent
        self._acks: list[tuple[int, int]] = []
        self._failed_sent: dict[int, int] = {}   # robot -> our last Number to it failed sent
        self._acks_deferred = False
        self._last_rx: dict[int, int] = {}
        self._rx_armed: set[int] = set()
        """Sources whose clause-48 Number we heard while they stayed in our ring and we stayed
        a member since: only theirs can be judged *behind* (clause 48a)."""
        self._turns_since_poll = 0
        self._poll_ptr: dict[int, int] = {}
        self._sent_poll: int | None = None
        self._quiet_limit = 0
        self._quiet_miss = False          # QUIET entered on garbage: no header seen yet
        self._hold_ref: int | None = None   # HOLD after an uncertain closure: its reference
        self._garbled: tuple[int, int, int | None] | None = None
        """(o, the tick o's turn closed, the owner then) after o's turn closed on garbage
        (clause 42): until the next turn begins, a good frame from o is o's frame, late."""
        self._promised: tuple[int, str, int | None] | None = None
        """A failed frame's turn closes at the End its Length promised: (that End, and the
        phase and deadline on_corrupt left), until the frame is over sooner (on_frame_over)."""
        self._booting = False             # powered on and not yet acknowledged by the ring
        self._lone_boot = False           # our BOOT went out as a lone claimer: nobody acked it
        self._announcing: int | None = None  # BOOT or JOIN: sent, awaiting acknowledgements
        self._ann_num = 0                 # the Number our BOOT/JOIN frames carry
        self._ann_awaiting: set[int] = set()   # members yet to acknowledge it
        self._ann_turns = 0               # BOOT/JOIN frames sent so far
        self._heard_since_tx = True       # a valid frame was heard since our own last one
        self._tell_view = False           # our next frame carries ring(mask) (rule R-view)
        self._last_heard: tuple[int, int] | None = None   # (Source, End) of the last accepted
        self._booting_peers: set[int] = set()   # robots whose BOOT frames we are hearing
        self._answering = False           # next frame answers an invitation (Type '6')
        self._passed_invite = False       # PC2 in LISTEN let one invitation of ID 0 pass
        self.standby = self.cfg.standby      # a replica of ID 0 that does not transmit
        self._watched = False
        self._check_turns, self._deaf_check, self._held = 0, False, list[Deliver]()  # clause 50
        self._rejoining = False             # after a stall: our first turn is watched first
        self._seen: dict[int, int] = {}      # LISTEN: source -> tick last heard
        # disabled robot -> (frames heard since, the End of the last)
        self._heard_disabled: dict[int, tuple[int, int]] = {}
        self.frames_sent = 0
        self.turns = 0
        self._hb_cache: dict[tuple, tuple[Frame, bytes]] = {}
        self._paper = cfg.profile == "paper"
        self._hb_len = CRC_TEXT_LEN if cfg.checksum else 0   # a heartbeat's Content (bytes)
        self._key = cfg.auth                # the ring key (authenticated profile) or None
        self._ext_len = _auth.AUTH_TEXT_LEN if cfg.auth is not None else self._hb_len
        if cfg.auth is not None or not cfg.fast_path:
            self._hb_len = -1               # no fast path (with auth: every frame's tag is checked)
        self.auth_tx = 0
        """The freshness value of our next frame (authenticated profile): kept in flash across
        reboots on a child; a PC seeds it from its clock (auth.clock_freshness)."""
        self._auth_rx: dict[int, int] = {}  # Source -> freshness of the last frame accepted
        self._tx_end = self._rx_quiet = 0  # End of our own last frame, of a failed one heard
        self._noise_since_tx = False      # garbage or a failed frame heard since our frame
        self._rejected = 0                # paper profile: our frames not heard, in a row
        self._own_heard: tuple[int, int] | None = None   # (frames, last End) with our own ID
        self._twin_said = False           # DuplicateId said in this episode
        self._let_pass = 0                # invitations to let pass before answering one
        self._rng = random.Random(f"{cfg.seed}:{robot_id}")
        self._pair = cfg.paired or cfg.standby or cfg.pc > 1
        """One of the father's two PCs: another ID 0 on the air is the other PC (clause 50),
        not a twin (clause 38.2)."""
        self._foreign: dict[int, int] = {}   # robot outside the team -> End last heard
        self._foreign_said: tuple[int, ...] = ()
        self._fail_run: tuple[int, int] | None = None   # (member, its failed turns in a row)
        self._good_since_fail = False     # a good frame accepted since (clause 41a)

    # -- queries ---------------------------------------------------------------------------

    @property
    def lone(self) -> bool:
        return self.mode == MEMBER and self.ring == (self.id,)

    @property
    def outbox(self) -> tuple[Message, ...]:
        """Messages not yet ended, the one awaiting acknowledgement first, then the queue."""
        head = (self._inflight,) if self._inflight is not None else ()
        return head + tuple(self._queue)

    @property
    def inflight(self) -> Message | None:
        """The message sent and awaiting acknowledgement, if any (stop-and-wait)."""
        return self._inflight

    @property
    def pending(self) -> int:
        """Messages submitted and not yet ended (queued or awaiting acknowledgement)."""
        return len(self._queue) + (1 if self._inflight is not None else 0)

    def succ(self, robot: int, ring: tuple[int, ...] | None = None) -> int:
        """The member after ``robot`` in ascending cyclic ID order (``robot`` need not be one)."""
        ring = self.ring if ring is None else ring
        i = bisect_right(ring, robot)
        return ring[i] if i < len(ring) else ring[0]

    # -- events in ---------------------------------------------------------------------------

    def general_path_only(self) -> None:
        """From now on every frame takes the general path (as ``MacConfig.fast_path`` False
        would have built it): how the fast path's check gets its reference MAC from a copy
        (tests/firmware_model/radio/test_mac_fast_path.py)."""
        self._hb_len = -1               # no Content has this length: never the fast path

    def power_on(self, now: int) -> list:
        """Start in LISTEN; claim after ``claim_ticks`` of silence (docs/protocol.md §4.3,
        clause 28). In the paper profile: a member of the static ring of the whole team at
        once, the lowest ID's turn beginning now (docs/protocol.md §9)."""
        if self._paper:
            return self._paper_power_on(now)
        self.mode = LISTEN
        self._rejoining = False
        self._booting = True
        self._lone_boot = False
        self._announcing = None
        self._last_num = 0                 # the BOOT frame is Number '00' ...
        self._next_num = 1                 # ... and messages start at '01'
        self.deadline = now + self._claim_ticks()
        return [TX_OFF]

    def _claim_ticks(self) -> int:
        # A standby claims after every other robot would have (the active PC claims first).
        extra = 7 * self.cfg.tslot if self.standby else 0
        return self.cfg.claim_ticks(self.id) + extra

    def on_frame(self, frame: Frame, first: int, end: int, now: int) -> Sequence[Any]:
        """A valid frame was heard; its first header byte ended at ``first``, its End at ``end``."""
        src = frame.src
        phase = self.phase
        if phase != WAIT and (phase == SWITCH or phase == SEND):   # (WAIT first: most frames)
            return _NOTHING            # deaf while switching or sending (only raw input gets here)
        self._promised = None          # a good frame: the turn is whoever sends it
        if self._paper:
            return self._paper_frame(frame, first, end, now)
        if self.standby and (self._queue or self._inflight is not None):
            # A standby takes no turns and a live ring never lets its deadlines pass: what it
            # held when it stood by expires on the frames it hears, as in LISTEN (clause 50).
            ended: list = []
            self._expire(now, ended)
            if ended:
                return ended + list(self.on_frame(frame, first, end, now))
        if not self._heard_since_tx:       # (the first good frame since ours: clause 50)
            self._heard_after_tx(first, good=True)
        if src == self.owner and phase == WAIT and frame.type == 3 and src != self.id and (
                not frame.content if not self._hb_len
                else len(frame.content) == self._hb_len and crc_ok(frame)):
            # Fast path, the expected owner's heartbeat (empty Content, or only its checksum
            # when the extension is on): hand the turn on, as the general path below does.
            self._last_heard = (src, end)
            if self._booting_peers:
                self._booting_peers.discard(src)
            self.misses[src] = 0
            self._silent = 0
            if self._unheard:
                self._unheard.discard(src)
            if self._fail_run is not None:
                self._good_since_fail = True
                if self._fail_run[0] == src:
                    self._fail_run = None
            ring = self.ring
            i = bisect_right(ring, src)
            nxt = ring[i] if i < len(ring) else ring[0]
            if nxt == self.id:
                mine: list = []
                self._my_turn(end, now, mine)
                return mine
            self.phase = WAIT
            self.owner = nxt
            self.turn_start = end
            self.deadline = end + self.cfg.tmax
            return _NOTHING
        out: list = []
        # a good frame, even one refused below: our radio hears (the cut-off, clause 40)
        silent, self._silent = self._silent, 0
        if self._key is not None:
            why = self._auth_refusal(frame)
            if why is not None:
                # Forged or replayed, whatever its Source: never acted on, and every member
                # treats it alike, as a frame that failed (clause 53): the turn closes
                # uncertainly (R-stagger), as after a burst.
                out.append(Refused(src, frame.num, why[1], why[0]))
                out.extend(self.on_corrupt(first, None, end, now))
                return out
        if self.cfg.checksum and not crc_ok(frame):
            # A failed frame whose Source was not read (clause 43): a byte error may have made
            # it our own ID or a robot outside the team, so the checksum is judged first.
            out.append(BadChecksum(first, end))
            out.extend(self.on_corrupt(first, None, end, now))
            return out
        if src == self.id:
            # Our own ID from the air (we are deaf while sending): another PC is ID 0, or a
            # robot with our ID, or a forger. Refused; it still sets the timing. A father that
            # is no PC pair has no other PC: another ID 0 is a twin, as for a child.
            if self.id != 0 or not self._pair:
                self._own_id_heard(frame.num, end, now, out)
                return out
            return self._active_frame(frame, end, now, out, silent)
        if src not in self.cfg.team:
            self._foreign_heard(src, end, out)
            out.append(Refused(src, frame.num, f"robot {src} is not in the team"))
            out.extend(self.on_corrupt(first, None, end, now))
            return out
        if self._rejoining and self.phase == WATCH:
            self._left_out_while_stalled(src, now, out)
            return out
        content = frame.content
        if self.cfg.checksum:
            content = strip_crc(content)              # checked above
        elif self._key is not None:
            content = _auth.strip(content)    # checked above
        try:
            mac_cmds, app_cmds = _layers(content) if content else ((), ())
            bad = None
        except ContentError as exc:
            mac_cmds, app_cmds, bad = (), (), exc
        polls = [c for c in mac_cmds if c.name == "poll"]

        answering = self.phase == WINDOW and src == self.owner and \
            frame.type in (FrameType.BOOT, FrameType.JOIN)
        if not answering and self.mode == MEMBER and self.lone and self.phase == HOLD and \
                src == self._sent_poll and frame.type in (FrameType.BOOT, FrameType.JOIN):
            # A lone member's invitation answered late, before its next frame (a PC that heard
            # the poll late, clause 31): the answerer counts us a member already.
            answering = True
        if self.mode == MEMBER and self.lone and not answering:
            self._to_listen(out, now, "heard another robot while alone")
        skipped: list[int] | None = None
        out_of_turn = False
        if self.mode == MEMBER and src in self.ring and self.phase in (WAIT, WINDOW) and \
                self.owner is not None and src != self.owner and not answering:
            if self.phase == WAIT and self._garbled == (src, self.turn_start, self.owner):
                # The garbage we took for src's broken frame was not its frame: src's Header
                # came late (a PC's), the next owner was still in its R-stagger wait and
                # follows this frame too (clause 42). src's frame, not out of turn.
                skipped = []
            else:
                skipped = self._takeover(src, first)
                out_of_turn = skipped is None
        behind = None
        if app_cmds and not out_of_turn and src in self._rx_armed and self.mode == MEMBER \
                and src in self.ring and self._key is None:
            last = self._last_rx[src]
            back = (last - frame.num) % 100
            if back and back <= BEHIND_WINDOW:
                # A Number that went backwards (clause 48a; no genuine sender's does): a replay
                # or a forger's. Reported; with the checksum refused as an unreadable frame is
                # (clause 43), for the timing only, so members that judge it otherwise agree.
                refuse = self.cfg.checksum
                out.append(NumberBehind(src, frame.num, last, refuse))
                if refuse:
                    behind = Refused(src, frame.num, f"behind: Number {frame.num:02d} is {back}"
                                     f" behind {last:02d}, robot {src}'s last message",
                                     "behind")
                    mac_cmds, app_cmds, polls = (), (), []
        if self.mode == MEMBER and src in self.ring and not out_of_turn:
            # A frame accepted from a member (clauses 37, 51; not one refused out of turn):
            # its poll or ring mask says whether it still has us, and which ring it has.
            for p in polls:
                if p.args[1] == 1 << src and not (p.args[0] == self.id and self._announcing
                                                  is None and set(self.ring) <= {self.id, src}):
                    continue    # a lone claimer's mask says nothing about our ring (clause 37)
                if not (p.args[1] >> self.id & 1):
                    self._to_listen(out, now, f"left out of robot {src}'s ring (its poll mask)",
                            let_pass=self._unheard_answer())
                    break
            else:
                for c in mac_cmds:
                    if c.name == "ring":
                        self._reconcile(src, c.args[0], now, out)
                        break
        if self.mode == LISTEN:
            self._seen[src] = end
            self.deadline = now + self._claim_ticks()
            if self._queue or self._inflight is not None:
                self._expire(now, out)
            for p in polls:
                if p.args[0] == self.id:
                    if self._own_heard is not None and \
                            end - self._own_heard[1] <= self._claim_ticks():
                        break              # our ID is on the air: the invitation is not ours
                    if self._let_pass:
                        self._let_pass -= 1    # left out, maybe a twin: let this one pass
                        break
                    if self.id == 0 and self.cfg.pc > 1 and not self._passed_invite:
                        # The father's PC2 lets the first invitation of ID 0 pass: PC1 may
                        # be listening too and answer it, and two PCs answering together
                        # collide for ever (found by the soak). PC2 then hears PC1's answer
                        # and stands by; if PC1 is dead, PC2 answers the next invitation.
                        self._passed_invite = True
                        break
                    members = _unmask(p.args[1]) | {self.id, src}
                    self.mode = MEMBER
                    self.ring = tuple(sorted(members))
                    self.misses = {r: 0 for r in self.ring}
                    self.ever_member |= set(self.ring)
                    self._silent = 0
                    self._turns_since_poll = self.cfg.poll_every
                    self._answering = True
                    out.append(ModeChange(MEMBER, f"invited by robot {src}"))
                    self._my_turn(end, now, out)
                    break
            return out

        # MEMBER from here on.
        invited_now = answering
        if src not in self.ring:
            if any(p.args[1] == 1 << src for p in polls):
                # A robot that claimed the channel alone: it is not in our ring and must be
                # invited (it goes back to LISTEN when it hears us). Resynchronise only.
                self._next_turn(src, end, now, out)
                return out
            if not invited_now:
                # Not a member and not answering an invitation: refused, never acted on; its
                # frame still sets the timing (the owner is whoever sends). Heard in
                # ``miss_limit`` frames a cycle or less apart (two rings that meet, a robot we
                # dropped that never noticed), it is admitted, and acted on from its next frame.
                self._refuse_outsider(src, frame.num, end, now, out)
                return out
            self._heard_disabled.pop(src, None)
            self._admit(src, out)
        elif out_of_turn and any(p.args[1] == 1 << src for p in polls):
            self._next_turn(src, end, now, out)   # a lone member's frame: resync (clause 31)
            return out
        elif out_of_turn:
            self.misses[src] = 0
            self._refuse_in_slot(src, frame.num, f"out of turn: it was robot {self.owner}'s "
                                 f"turn", end, now, out, "out_of_turn")
            return out
        if skipped:
            self._count_skipped(skipped, out)
        self._last_heard = (src, end)
        self.misses[src] = 0
        self._silent = 0
        if self._unheard:
            self._unheard.discard(src)
        if self._fail_run is not None:
            self._good_since_fail = True
            if self._fail_run[0] == src:
                self._fail_run = None
        if frame.type == FrameType.BOOT or frame.type == FrameType.JOIN:
            self._acks.append((src, frame.num))     # every BOOT/JOIN frame is acknowledged
            if frame.type == FrameType.BOOT and src not in self._booting_peers:
                self._booting_peers.add(src)        # the first BOOT heard means a restart
                self._rebooted(src, frame.num, out)
        elif self._booting_peers:
            self._booting_peers.discard(src)
        if bad is not None:
            out.append(BadContent(src, frame.num, bad))
        elif behind is not None:
            out.append(behind)
        else:
            for c in mac_cmds:
                if c.name == "ack" and c.args[0] == self.id:
                    self._on_ack(src, c.args[1], now, out)
            if app_cmds and not self._check_turns:
                # (A PC2 on probation after a takeover leaves new messages alone: PC1 may still
                # be active and take them; the sender retries if nobody acknowledges.)
                fresh = self._message_heard(src, frame.num)      # (a retransmission: not)
                if frame.dst == self.id or frame.dst == BROADCAST:
                    self._acks.append((src, frame.num))
                    if not fresh:
                        out.append(Duplicate(src, frame.num))
                    else:      # delivered, or held (a standby, a check: clause 50)
                        self._deliver(Deliver(src, frame.dst, frame.num, frame.type, app_cmds), out)

        invited = [p.args[0] for p in polls if p.args[0] not in self.ring]
        if invited:
            self._window(invited[0], src, end, now)
        else:
            self._next_turn(src, end, now, out)
        return out

    def on_timer(self, now: int, rx_busy: bool = False, last_rx: int | None = None,
                 rx_began: int | None = None) -> list:
        """The deadline expired. ``rx_busy``: a frame is being received right now;
        ``last_rx``: tick of the last byte heard (any byte); ``rx_began``: tick at which a
        Header still being received began (one or two Header bytes in), or a byte whose
        stop bit has not come yet did, as the receiver tells it (a station: the first
        falling edge on its RX pin since it last read a byte, Uart.rx_fall), else None.

        What a deadline means depends on the state: one handler per state, looked up in
        ``DEADLINE_HANDLERS`` (the rows of ``mac_table.TRANSITIONS`` with event "deadline")."""
        out: list = []
        if self.deadline is None or now < self.deadline:
            return out
        self._promised = None          # the phase on_corrupt left is over
        if self.mode == LISTEN:
            self._deadline_listen(now, rx_busy, out)
            return out
        if self.standby and (self._queue or self._inflight is not None):
            self._expire(now, out)
        DEADLINE_HANDLERS[self.phase](self, now, rx_busy, last_rx, rx_began, out)
        return out

    def resync(self, now: int) -> list:
        """Our station was not running for longer than the margins allow (docs/protocol.md
        clause 5; a bench process stopped or starved): every deadline it had is stale and
        what it heard meanwhile is gone. It must not act on that view (a turn taken on it
        collides): in LISTEN the claim wait starts again from now; a member lowers TXEN if it
        had raised it, keeps its ring and listens, the owner unknown, until it hears a good
        frame, which gives the next turn as any frame does; heard nothing for Tclaim, it goes
        back to LISTEN (docs/guarantees.md, "Stalls and restarts at the bench")."""
        out: list = []
        if self.mode == LISTEN:
            self.deadline = now + self._claim_ticks()
            return out
        if self.phase == SEND:             # the frame is out: the station resyncs after it
            return out
        if self.phase == SWITCH:
            out.append(TX_OFF)             # a turn taken on a stale view is not sent
        # The ring may have left us out meanwhile (three missed turns): our first turn on the
        # old view is watched first, as a checking PC's (WATCH); another robot's Header in it
        # means it did, and we go back to LISTEN to be invited, having sent nothing.
        self._rejoining = not self._paper and not self.standby
        self.phase = WAIT
        self.owner = None
        self.poller = None
        self._hold_ref = None
        self._quiet_miss = False
        self.turn_start = now
        self.deadline = now + self._claim_ticks()
        return out

    def on_tx_done(self, now: int) -> list:
        """The last bit of our End left the radio: our turn closes at ``now``."""
        out: list = [TX_OFF]
        self.frames_sent += 1
        self._heard_since_tx = False
        self._noise_since_tx = False
        self._tx_end = now
        if self.mode != MEMBER:
            return out
        if self._announcing is not None and self._ann_turns >= 2 * self.cfg.miss_limit:
            # Members that never acknowledged our BOOT/JOIN did not hear us join, and did not
            # admit us on evidence either (3 frames): they give our slot to someone else.
            # Back to LISTEN, to be invited again.
            missing = ",".join(str(r) for r in sorted(self._ann_awaiting))
            self._to_listen(out, now, f"robot(s) {missing} never acknowledged our "
                            f"{'BOOT' if self._announcing == FrameType.BOOT else 'JOIN'}",
                            let_pass=True)
            return out
        if self._sent_poll is not None:
            self._window(self._sent_poll, self.id, now, now)
        else:
            self._next_turn(self.id, now, now, out)
        return out

    # The rest of the machine is in modules of its own: functions of a RotationalMac,
    # bound here as its methods (a method so bound costs what one defined here does).

    # -- events in: failed frames and garbage (mac_failed.py) --------------------------------

    on_corrupt = _failed.on_corrupt
    on_frame_over = _failed.on_frame_over
    on_garbage = _failed.on_garbage

    # -- the outbox (mac_outbox.py) ----------------------------------------------------------

    submit = _outbox.submit
    _on_ack = _outbox._on_ack
    _finish = _outbox._finish
    _expire = _outbox._expire
    _unawait = _outbox._unawait
    _rebooted, _others_number = _outbox._rebooted, _outbox._others_number
    _number_after_others = _outbox._number_after_others

    # -- deadlines, one handler per state (mac_deadlines.py) ---------------------------------

    _deadline_listen = _deadlines._deadline_listen
    _deadline_watch = _deadlines._deadline_watch
    _deadline_switch = _deadlines._deadline_switch
    _deadline_hold = _deadlines._deadline_hold
    _deadline_quiet = _deadlines._deadline_quiet
    _header_coming = _deadlines._header_coming
    _deadline_window = _deadlines._deadline_window
    _deadline_wait = _deadlines._deadline_wait

    # -- turn machinery (mac_turns.py) -------------------------------------------------------

    force_turn = _turns.force_turn
    _watch_ticks, _heard_after_tx, _deliver, _forget_held, _message_heard = (
        _turns._watch_ticks, _turns._heard_after_tx, _turns._deliver, _turns._forget_held,
        _turns._message_heard)
    _takeover, _count_skipped, _pair_floor = (_turns._takeover, _turns._count_skipped,
                                              _turns._pair_floor)
    _next_turn, _missed_on_a_frame = _turns._next_turn, _turns._missed_on_a_frame
    _active_pc_of_pair = _turns._active_pc_of_pair
    _window = _turns._window
    _after_window = _turns._after_window
    _hold = _turns._hold
    _my_turn = _turns._my_turn
    _send = _turns._send

    # -- membership (mac_membership.py) ------------------------------------------------------

    _auth_refusal = _members._auth_refusal
    _active_frame = _members._active_frame
    _admit = _members._admit
    _refuse_in_slot = _members._refuse_in_slot
    _own_id_heard = _members._own_id_heard
    _twin_frame = _members._twin_frame
    _foreign_heard = _members._foreign_heard
    _slot_failed = _members._slot_failed
    _refuse_outsider = _members._refuse_outsider
    _reconcile = _members._reconcile
    _drop = _members._drop
    _announced = _members._announced
    _unheard_answer = _members._unheard_answer
    _to_listen = _members._to_listen
    _left_out_while_stalled = _members._left_out_while_stalled

    # -- frame building (mac_frames.py) ------------------------------------------------------

    _pick_message = _frames._pick_message
    _poll_target = _frames._poll_target
    _build_frame = _frames._build_frame
    _frame = _frames._frame

    # -- the paper profile (mac_paper.py) ----------------------------------------------------

    _paper_power_on = _paper._paper_power_on
    _paper_frame = _paper._paper_frame
    _paper_build = _paper._paper_build


DEADLINE_HANDLERS = {
    WATCH: RotationalMac._deadline_watch,
    SWITCH: RotationalMac._deadline_switch,
    HOLD: RotationalMac._deadline_hold,
    QUIET: RotationalMac._deadline_quiet,
    WINDOW: RotationalMac._deadline_window,
    WAIT: RotationalMac._deadline_wait,
}
"""What a deadline means in each MEMBER phase (LISTEN has its own: claim)."""

"""The rotational TDMA MAC (paper §IV.C, Figs. 6-7; docs/protocol.md §4) as a sans-IO state
machine.

Events go in (``on_frame``, ``on_corrupt``, ``on_timer``, ``on_tx_done``, ``submit``), actions and
observations come out as lists, and the single timer the MAC needs is exposed as ``deadline`` (a
tick, or None). The MAC owns no clock and does no I/O: the child firmware, the father station and
the tests drive it. Every time is an integer tick of the 16 MHz machine clock.

The same machine as a table (state x event -> next state, with the rule each row follows) is
``firmware_model/radio/mac_table.py``; tests/test_mac_table.py checks the two agree, and a
deadline is dispatched per state through ``DEADLINE_HANDLERS``.

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

Over 500 lines on purpose: the MAC is one state machine over one state; its readable form, the
transition table, is mac_table.py.
"""
from __future__ import annotations

import random
from bisect import bisect_right
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Iterable, Sequence

from ..timing import (
    CHILD_BYTE_TICKS,
    FRAME_OVERHEAD,
    MISS_LIMIT,
    PC_BYTE_TICKS,
    TMAX_TICKS,
    TTRANS_TICKS,
    max_content_bytes,
    protocol_max_content,
)
from .content import Command, cmd, format_content, parse_content, split_layers
from .errors import ContentError
from .frame import BROADCAST, Frame, FrameType
from . import auth as _auth
from .integrity import CRC_TEXT_LEN, check as crc_ok, seal, strip as strip_crc

LISTEN = "listen"
MEMBER = "member"
PROFILES = ("rprs", "paper")
"""``rprs``: docs/protocol.md in full. ``paper``: only the paper's rules on the wire (a static ring
from the team, empty heartbeats, no BOOT, JOIN, poll, ring, ack or crc; docs/protocol.md §9)."""
UNACKNOWLEDGED = "unacknowledged"
"""A message's final state in the paper profile: sent once, never acknowledged."""
_NOTHING: tuple = ()
PC2_CHECK_EVERY = 7
"""An active PC2 listens for PC1 on one of its turns in this many (docs/mac.md, failover). Odd:
in a ring of two with both PCs active PC2 sends twice a cycle, and an even period (8) always
listened on the same one of the two, the one PC1 does not send in, so they never met
(docs/guarantees.md)."""
TAKEOVER_TOLERANCE = 0.05
"""Clock difference (fraction of Tmax) between robots within which a takeover heard before
our own timer expires is still taken as one (a fast clock's Tmax ends first)."""

TWIN_FRAMES = 2
"""Frames with our own ID that we did not send, each heard less than Tclaim(id) after the
previous one, that say another robot has our ID (docs/protocol.md clause 38.2): one forged
frame is never enough."""
BEHIND_WINDOW = 8
"""A message frame whose Number is 1 to this many behind the last one heard from its Source
(modulo 100) is *behind* (docs/protocol.md clause 48a): reported, and refused when the
checksum extension vouches for the Number, for no genuine sender's Number goes backwards. A
genuine Number looks behind only after a member stayed in the ring with its Source and heard
none of its next 100 - 8 - 1 = 91 messages."""
FAILING_SLOT_LIMIT = 8
"""Turns of one member in a row that end in a failed frame while the other members' frames are
heard good in between, after which every member drops it (docs/protocol.md clause 41a): two
robots with one ID that send in lock-step, or a transmitter that only garbles."""
LET_PASS_MAX = 3
"""A robot whose BOOT or JOIN was never acknowledged (or that was left out before it was) lets
0 to this many invitations pass (a seeded draw) before it answers one: twins that answer
together collide every time (docs/protocol.md clause 38.2)."""

# Phases while MEMBER.
WAIT = "wait"        # waiting for the header of ``owner`` until ``deadline``
WINDOW = "window"    # a poll window for the invited ``owner`` until ``deadline``
HOLD = "hold"        # my turn starts at ``deadline`` (after a corrupted frame or a lone pause)
SWITCH = "switch"    # TXEN is high; my frame starts at ``deadline`` (= turn start + Ttrans)
SEND = "send"        # my frame is on air; ``on_tx_done`` ends the turn
QUIET = "quiet"      # a frame failed before its Length: wait for the channel to fall quiet
WATCH = "watch"      # hot standby: ID 0's turn; is the active PC's header coming?


class SubmitError(ValueError):
    """A message the MAC refuses at submission (too long for one turn, bad destination, full)."""


class QueueFull(SubmitError):
    """The queue holds ``max_queue`` messages: nothing more is taken until one ends (which
    needs a turn of the ring, so not before the caller's next event)."""


class StandingBy(SubmitError):
    """A father PC standing by refuses new messages at once (docs/protocol.md clause 50): the
    active PC sends ID 0's frames, and a message held here would go out only if this PC took
    over, at an hour nobody chose."""


# ---------------------------------------------------------------------------------------------
# Actions (for the driver) and observations (for traces, tests and the application)


@dataclass(frozen=True, slots=True)
class TxEnable:
    """Drive the PTR2000's TXEN pin: True = switch to transmit, False = back to receive."""

    on: bool


TX_ON = TxEnable(True)
TX_OFF = TxEnable(False)
"""The two TXEN actions (frozen: one object each serves every turn)."""


@dataclass(frozen=True, slots=True)
class Transmit:
    """Send these bytes now (the radio has been in TX for Ttrans)."""

    frame: Frame
    data: bytes


@dataclass(frozen=True, slots=True)
class Miss:
    """``robot``'s header was not heard by the turn's deadline (observer's view)."""

    robot: int


@dataclass(frozen=True, slots=True)
class Disable:
    """``robot`` missed ``miss_limit`` consecutive turns and is dropped from the ring."""

    robot: int


@dataclass(frozen=True, slots=True)
class Join:
    """``robot`` became a member in this observer's view (``again``: it had been dropped)."""

    robot: int
    again: bool


@dataclass(frozen=True, slots=True)
class ModeChange:
    """This robot changed mode (LISTEN/MEMBER) for ``reason``."""

    mode: str
    reason: str


@dataclass(frozen=True, slots=True)
class Deliver:
    """A message for this robot (or broadcast) accepted once: hand it to the application."""

    src: int
    dst: int
    num: int
    type: int
    commands: tuple[Command, ...]


@dataclass(frozen=True, slots=True)
class Duplicate:
    """A retransmission of a message already delivered: re-acknowledged, not delivered again."""

    src: int
    num: int


@dataclass(frozen=True, slots=True)
class BadContent:
    """A frame whose Content does not parse: the turn counts, nothing is delivered or acked."""

    src: int
    num: int
    error: ContentError


@dataclass(frozen=True, slots=True)
class Refused:
    """A frame refused and never acted on (docs/mac.md, spoofing and bounds): its Source is
    not in the team, not the robot whose turn it is, our own ID, or a robot we disabled."""

    src: int
    num: int
    reason: str
    kind: str = ""
    """``forged`` or ``replayed`` for a frame the authenticated profile refuses (clause 53);
    ``out_of_turn`` (clause 39), ``own_id`` (clause 38.2) or ``behind`` (a Number that went
    backwards, clause 48a) for the forgers a ring sees without it; empty for the ring's other
    refusals (a Source outside the team or the ring)."""


@dataclass(frozen=True, slots=True)
class NumberBehind:
    """A message frame from ``src`` whose Number ``num`` is behind ``last``, the Number of the
    last message frame heard from it (docs/protocol.md clause 48a): a recorded frame sent
    again, or a forger's. ``refused``: not acted on (the checksum extension is on, so the
    Number is the one sent; a ``Refused`` of kind ``behind`` comes with it); otherwise only
    reported, for a byte error can move a Number, and clause 48 delivers it."""

    src: int
    num: int
    last: int
    refused: bool


@dataclass(frozen=True, slots=True)
class DuplicateId:
    """Another robot sends with our own ID ``robot`` (docs/protocol.md clause 38.2): said once
    an episode (until our ID has not been heard for Tclaim). ``yielding``: we leave the ring to
    it (back to LISTEN, or staying there) and answer no invitation while our ID is heard."""

    robot: int
    yielding: bool


@dataclass(frozen=True, slots=True)
class ForeignRing:
    """Good frames from robots outside our team are on the air (docs/protocol.md clause 38.1):
    ``robots``, those heard within the last 8 Tmax, said again when the set changes. A robot in
    LISTEN that hears them cannot claim the channel and is never invited by them."""

    robots: tuple[int, ...]
    member: bool


@dataclass(frozen=True, slots=True)
class BadChecksum:
    """A frame refused because its checksum was missing or wrong (checksum extension on)."""

    first: int
    end: int


@dataclass(frozen=True, slots=True)
class Outcome:
    """A submitted message ended: ``delivered`` (acknowledged) or failed with ``reason``."""

    message: "Message"
    delivered: bool
    reason: str


@dataclass(eq=False, slots=True)
class Message:
    """A message submitted to the MAC, from submission to its outcome."""

    src: int
    dst: int
    num: int
    type: int
    commands: tuple[Command, ...]
    content: bytes
    submitted: int
    attempts: int = 0
    waited: int = 0
    awaiting: set[int] = field(default_factory=set)
    acked: set[int] = field(default_factory=set)
    state: str = "queued"   # queued | sent | delivered | failed | unacknowledged (paper profile)
    reason: str = ""


@dataclass(frozen=True, slots=True)
class MacConfig:
    """MAC timing (ticks) and policy. Defaults are the paper's experiment (docs/protocol.md §2)."""

    ttrans: int = TTRANS_TICKS
    tmax: int = TMAX_TICKS
    miss_limit: int = MISS_LIMIT
    byte_ticks: int = CHILD_BYTE_TICKS
    twin: int = 160_000
    """Poll window (10 ms): an invited robot's header must be heard by E + twin.
    It starts at E + Ttrans, so its 3 header bytes end by E + 80000 + 3 x 16667 = E + 130001."""
    tslot: int = 320_000
    """ID stagger (20 ms) for claims, lone pauses and rule R-stagger: at least twice (Ttrans +
    4 bytes), and small enough that robot 6's stagger, 6 x tslot + Ttrans + 4 bytes, ends
    before Tmax (docs/protocol.md §7.6; tests/test_margin_bounds.py)."""
    team: frozenset[int] = frozenset(range(7))
    """The robots that may ever join: only these are invited."""
    poll_every: int = 4
    """A member with absent team robots in its gap invites one of them every this many turns."""
    quiet_gap: int = 2 * CHILD_BYTE_TICKS
    """No byte for this long after a frame failed before its Length: the frame is over.
    (A frame's bytes are back to back; idle noise keeps the channel from ever going quiet,
    and then the wait ends at Tmax after the failed header.)"""
    stall_gap: int = 2 * CHILD_BYTE_TICKS
    """A frame whose bytes stop coming for this long is abandoned (the sender died)."""
    max_attempts: int = 4
    """Transmissions of a message (first + retries) before it fails."""
    max_age: int = 60 * 16_000_000
    """A message not delivered this many ticks after submission fails as expired."""
    max_queue: int = 32
    mac_reserve: int = 64
    """Content bytes the MAC keeps free for its own commands when a load fills frames."""
    pc: int = 1
    """Which of the father's PCs this is (1 or 2): on ID 0's turn a standby PC waits
    ``pc`` x ``standby_watch`` for the active PC's header, and if two active PCs ever hear
    each other, the higher number stands by."""
    standby_watch: int = 4 * 16_667
    """How long after Ttrans a standby waits for the active PC's header before it takes the
    turn (ticks): 4 bytes in simulation; a PC on a USB adapter needs tens of ms."""
    standby: bool = False
    """Hot standby for the father (docs/protocol.md §4.9, clause 50; paper's PC1/PC2): follow the
    ring as a replica of ID 0 and take ID 0's turn only when the active PC's header does not
    come (docs/mac.md)."""
    paired: bool = False
    """One of the father's two PCs (the other exists): an active PC that may have been deaf
    while the other took over goes on probation (clause 50). A lone father need not: nobody
    else delivers as ID 0, and the probation would only delay its messages."""
    quiet_channel: bool = True
    """The radio gives no bytes without a carrier (the pty hub; a radio with squelch). Then an
    owner whose turn follows an uncertain closure waits for the channel to fall quiet before
    its ``id`` x Tslot stagger runs (rule R-stagger: a jam is the one thing two members hear in
    common). False for a radio that outputs idle noise (a bare PTR2000, ``--idle-noise``):
    that channel never falls quiet."""
    checksum: bool = False
    """Opt-in integrity extension (firmware_model.radio.integrity): every frame sent ends
    with ``crc(NNNNN)`` and frames received without a good one are refused."""
    seed: int = 0
    """Seeds the MAC's one random choice: how many invitations a robot whose JOIN was never
    acknowledged lets pass (LET_PASS_MAX; docs/protocol.md clause 38.2). Two robots with one
    ID must not share it, or they answer together for ever: the simulator and the bench
    processes pass their own."""
    auth: "_auth.RingKey | None" = None
    """The opt-in authenticated profile (firmware_model.radio.auth, docs/protocol.md §4.11): the
    ring key. Every frame sent ends with ``auth(freshness,tag)``; a frame received with a
    missing or wrong tag, or a freshness not above the last accepted from its Source, is
    refused and never acted on."""
    profile: str = "rprs"
    """``rprs`` (the whole of docs/protocol.md) or ``paper``: only the paper's rules, to share a
    ring with robots that implement only the paper (docs/protocol.md §9, the paper profile)."""

    def __post_init__(self) -> None:
        if self.profile not in PROFILES:
            raise ValueError(f"profile must be one of {', '.join(PROFILES)}, "
                             f"got {self.profile!r}")
        if self.profile == "paper" and (self.checksum or self.standby):
            raise ValueError("the paper profile has no checksum extension and no standby PC "
                             "(both are this project's extensions)")
        if self.profile == "paper" and self.auth is not None:
            raise ValueError("the paper profile has no authenticated profile (this project's "
                             "extension)")
        if self.checksum and self.auth is not None:
            raise ValueError("the authenticated profile's tag already detects every changed "
                             "byte: use it or the checksum, not both")

    def claim_ticks(self, robot: int) -> int:
        """Silence after which a listening robot claims the channel (start-up).

        Longer than any silence a live ring of this team can make (every other member missing
        one turn each: (|team|-1) x Tmax), plus one Tmax, staggered by ID so the lowest claims
        first."""
        return len(self.team) * self.tmax + robot * self.tslot

    def silent_drop_ticks(self, ring: Iterable[int]) -> int:
        """The longest time from a member's radio failing to its drop, in an idle ring of the
        members ``ring`` (docs/protocol.md §7.3, each term with its clause there).

        The worst failure cuts the robot's frame after its Header, before its Length: the
        others abandon it one stall gap after its last byte and close its turn a quiet gap
        later (clause 41; 2 ticks for the stall timer's resolution); the robot after it
        waits its R-stagger (clause 44), at worst the highest ID's; then three rounds of the
        others' turns, each frame with ``ring(mask)`` (clause 51), and three times Tmax
        (clauses 24, 25). In a ring of two every miss follows the survivor's own frame, so
        each adds its R-stagger. A team with IDs outside the ring adds each member's one
        invitation in those turns (clauses 32, 33). B is a PC's byte, the slower."""
        ring = tuple(sorted(set(ring)))
        n = len(ring)
        if n < 2:
            raise ValueError(f"a silent robot is dropped by the others: give 2 or more "
                             f"members, got {list(ring)}")
        b, m = PC_BYTE_TICKS, self.miss_limit
        cut = max(self.stall_gap, 2 * b) + self.quiet_gap + 2
        if self.profile == "paper":    # no ring(mask), no R-stagger (§9.1): heartbeats
            return cut + m * ((n - 1) * (self.ttrans + FRAME_OVERHEAD * b) + self.tmax)
        sealed = (CRC_TEXT_LEN if self.checksum else 0) + \
            (_auth.AUTH_TEXT_LEN if self.auth is not None else 0)
        told = self.ttrans + (FRAME_OVERHEAD + len("ring(127)") + sealed) * b
        stagger = max(ring) * self.tslot
        # A member whose gap holds team IDs outside the ring invites one every poll_every of
        # its turns: poll(k,127) is 2 bytes longer than ring(127), and a window of Twin follows
        inviters = sum(1 for i, r in enumerate(ring) if any(
            (r + d) % 7 in self.team for d in range(1, (ring[(i + 1) % n] - r) % 7)))
        polls = min(inviters, n - 1) * -(-m // self.poll_every) * (self.twin + 2 * b)
        if n == 2:
            return cut + polls + m * (told + self.tmax + stagger)
        return cut + polls + stagger + m * ((n - 1) * told + self.tmax)


def check_submission(robot: int, dst: int, commands: Iterable[Command],
                     type: int) -> tuple[tuple[Command, ...], bytes]:
    """The checks every MAC makes when a message is submitted (a destination other than the
    sender, a Type digit, no MAC commands); returns the commands and their Content."""
    commands = tuple(commands)
    if not 0 <= dst <= BROADCAST or dst == robot:
        raise SubmitError(f"destination must be a robot ID 0-6 other than {robot}, "
                          f"or {BROADCAST} (broadcast); got {dst}")
    if not 0 <= int(type) <= 4:
        raise SubmitError(f"a message's Type must be 0-4 (5 BOOT and 6 JOIN are the MAC's own, "
                          f"7-9 are reserved: docs/protocol.md), got {type}")
    mac_cmds = [c for c in commands if c.spec.layer == "mac"]
    if mac_cmds:
        raise SubmitError(f"{mac_cmds[0].name}() is a MAC command and cannot be submitted")
    return commands, format_content(commands)


@lru_cache(maxsize=2048)
def _layers(content: bytes) -> tuple[tuple[Command, ...], tuple[Command, ...]]:
    """Parse Content once per distinct byte string: every receiver of a frame shares it."""
    return split_layers(parse_content(content))


@lru_cache(maxsize=1024)
def _ack_len(ack: tuple[int, int]) -> int:
    """Content bytes of ``ack(src,num)``."""
    return len(cmd("ack", ack[0], ack[1]).text())


def _mask(ids: Iterable[int]) -> int:
    m = 0
    for i in ids:
        m |= 1 << i
    return m


def _unmask(mask: int) -> set[int]:
    return {i for i in range(7) if mask >> i & 1}


class RotationalMac:
    """One robot's MAC. Create, call ``power_on(now)``, then feed it events."""

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
        self.phase = WAIT
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
        self._check_turns = 0               # PC2 after a takeover: turns still to watch
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
        if cfg.auth is not None:
            self._hb_len = -1               # no fast path: every frame's tag is checked
        self.auth_tx = 0
        """The freshness value of our next frame (authenticated profile): kept in flash across
        reboots on a child; a PC seeds it from its clock (auth.clock_freshness)."""
        self._auth_rx: dict[int, int] = {}  # Source -> freshness of the last frame accepted
        self._tx_end = 0                  # End of our own last frame
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

    def power_on(self, now: int) -> list:
        """Start in LISTEN; claim after ``claim_ticks`` of silence (docs/protocol.md §4.3,
        clause 28). In the paper profile: a member of the static ring of the whole team at
        once, the lowest ID's turn beginning now (docs/protocol.md §9)."""
        if self._paper:
            return self._paper_power_on(now)
        self.mode = LISTEN
        self._booting = True
        self._lone_boot = False
        self._announcing = None
        self._last_num = 0                 # the BOOT frame is Number '00' ...
        self._next_num = 1                 # ... and messages start at '01'
        self.deadline = now + self._claim_ticks()
        return [TX_OFF]

    def _paper_power_on(self, now: int) -> list:
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

    def _claim_ticks(self) -> int:
        # A standby claims after every other robot would have (the active PC claims first).
        extra = 7 * self.cfg.tslot if self.standby else 0
        return self.cfg.claim_ticks(self.id) + extra

    def submit(self, dst: int, commands: Iterable[Command], now: int,
               type: int = FrameType.INSTRUCTION) -> Message:
        """Queue a message; raises SubmitError if it can never be sent in one turn."""
        commands, content = check_submission(self.id, dst, commands, type)
        limit = self.max_content - self._ext_len
        if len(content) > limit:
            raise SubmitError(
                f"Content of {len(content)} bytes makes a "
                f"{len(content) + FRAME_OVERHEAD + self.max_content - limit}-byte frame, longer "
                f"than one turn allows ({self.max_content + FRAME_OVERHEAD} bytes fit in Tmax"
                f"{', checksum included' if self.cfg.checksum else ''}"
                f"{', auth included' if self._key is not None else ''}); "
                f"split the message")
        if self.standby:
            pc = self.cfg.pc
            other = f"PC{3 - pc}" if self.cfg.paired else "another father PC on ID 0"
            raise StandingBy(f"PC{pc} is standing by: the active PC is {other}; give orders "
                             f"there, or here once this PC has taken over")
        if self.pending >= self.cfg.max_queue:
            raise QueueFull(f"queue full ({self.cfg.max_queue} messages pending)")
        msg = Message(self.id, dst, self._next_num, int(type), commands, content, now)
        self._next_num = (self._next_num + 1) % 100
        self._queue.append(msg)
        return msg

    def on_frame(self, frame: Frame, first: int, end: int, now: int) -> Sequence[Any]:
        """A valid frame was heard; its first header byte ended at ``first``, its End at ``end``."""
        src = frame.src
        phase = self.phase
        if phase == SWITCH or phase == SEND:
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
        self._heard_since_tx = True
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
            # A lone member's invitation answered after its window, before its next frame:
            # the answer of a PC that heard the poll late (clause 31). The answerer already
            # counts us a member; going back to LISTEN would cost it our turns, as misses.
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
                # A message Number that went backwards (clause 48a): no genuine sender's does
                # (stop and wait, +1 a message). A recorded frame sent again, or a forger's.
                # Reported; with the checksum (the Number is the one sent) refused, taken as
                # an unreadable frame is (clause 43), for the timing only, so members that
                # judge it otherwise stay in step.
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
                if p.args[1] == 1 << src:
                    continue           # a lone claimer's mask says nothing about our ring
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
                # A sender keeps one message in flight, so a retransmission repeats the Number
                # of the last message frame heard from it, whoever that frame was for.
                fresh = self._last_rx.get(src) != frame.num
                self._last_rx[src] = frame.num
                self._rx_armed.add(src)
                if frame.dst == self.id or frame.dst == BROADCAST:
                    self._acks.append((src, frame.num))
                    if not fresh:
                        out.append(Duplicate(src, frame.num))
                    elif not self.standby:     # the active PC delivers; its standby only
                        out.append(Deliver(src, frame.dst, frame.num, frame.type, app_cmds))

        invited = [p.args[0] for p in polls if p.args[0] not in self.ring]
        if invited:
            self._window(invited[0], src, end, now)
        else:
            self._next_turn(src, end, now, out)
        return out

    def _auth_refusal(self, frame: Frame) -> tuple[str, str] | None:
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

    def _paper_frame(self, frame: Frame, first: int, end: int, now: int) -> list:
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

    def on_corrupt(self, first: int, src: int | None, expected_end: int | None,
                   now: int) -> list:
        """A frame failed after a valid header: the turn is used (not a miss) and closes at the
        end its Length promised, or ``first + Tmax`` when the Length was never read."""
        out: list = []
        if self.phase == SWITCH or self.phase == SEND:
            return out
        self._noise_since_tx = True
        if self.mode == LISTEN:
            self.deadline = now + self._claim_ticks()
            return out
        if self.phase not in (WAIT, WINDOW, QUIET, WATCH):
            return out
        self._tell_view = True
        after = src if src is not None and src != self.id and (
            src in self.ring or src == self.owner) else self.owner
        if after is None:
            return out                 # resynchronising (``resync``): wait for a good frame
        if expected_end is None:
            # The Length was never read: the frame is over when no byte has come for
            # ``quiet_gap`` ticks, and at the latest Tmax after its header began.
            if self.phase != QUIET or self._quiet_miss:
                self._quiet_limit = first + self.cfg.tmax
            self._quiet_miss = False
            self.phase = QUIET
            self.owner = after
            self.deadline = min(now + self.cfg.quiet_gap, max(self._quiet_limit, now))
            return out
        self._quiet_miss = False
        self._slot_failed(after, out)
        self._next_turn(after, max(expected_end, now), now, out, uncertain=True)
        self._promised = (expected_end, self.phase, self.deadline) if expected_end > now and \
            self.phase in (WAIT, HOLD) else None
        return out

    def on_frame_over(self, now: int) -> Sequence[Any]:
        """The frame that failed after its Length (``on_corrupt`` with the End it promised) is
        over sooner: its bytes stopped for the stall gap before that End (the sender died, or a
        Header cut off on purpose: 12 bytes that promise 562). Its turn closes now instead
        (docs/protocol.md clause 41), uncertain as before: the next owner's R-stagger runs from
        now (clause 44). Nothing changes if anything else moved the MAC on meanwhile."""
        promised, self._promised = self._promised, None
        if promised is None or self.mode != MEMBER:
            return _NOTHING
        end, phase, deadline = promised
        if now >= end or self.phase != phase or self.deadline != deadline:
            return _NOTHING
        if phase == WAIT and self.turn_start == end:
            self.turn_start = now
            self.deadline = now + self.cfg.tmax
        elif phase == HOLD:
            assert deadline is not None                # HOLD always has its deadline
            self.deadline = deadline - (end - now)
            if self._hold_ref == end:
                self._hold_ref = now
        return _NOTHING

    def on_garbage(self, first: int, last: int, now: int) -> Sequence[Any]:
        """Bytes that form no frame were heard. In the owner's slot they are probably its frame
        with a corrupted Header: if the channel then falls quiet the turn closes (no miss);
        if it never does (idle noise), the owner misses at E + Tmax as usual."""
        self._noise_since_tx = True
        if self.mode == MEMBER and self.phase == WAIT and self.owner is not None and \
                last > self.turn_start + self.cfg.ttrans:
            self._tell_view = True
            self.phase = QUIET
            self._quiet_miss = True
            self._quiet_limit = self.turn_start + self.cfg.tmax
            self.deadline = max(now, min(last + self.cfg.quiet_gap, self._quiet_limit))
        return _NOTHING

    def on_timer(self, now: int, rx_busy: bool = False, last_rx: int | None = None,
                 rx_began: int | None = None) -> list:
        """The deadline expired. ``rx_busy``: a frame is being received right now;
        ``last_rx``: tick of the last byte heard (any byte); ``rx_began``: tick at which the
        start bit of a Header still being received began (one or two Header bytes, or a
        byte whose stop bit has not come yet), else None.

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
        self.phase = WAIT
        self.owner = None
        self.poller = None
        self._hold_ref = None
        self._quiet_miss = False
        self.turn_start = now
        self.deadline = now + self._claim_ticks()
        return out

    def _deadline_listen(self, now: int, rx_busy: bool, out: list) -> None:
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

    def _deadline_watch(self, now: int, rx_busy: bool, last_rx: int | None,
                        rx_began: int | None, out: list) -> None:
        """WATCH (father failover): the active PC's Header came, follow it; else take the turn."""
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
            out.append(ModeChange(MEMBER, "took over ID 0's turn: the active PC is silent"))
        elif self._check_turns > 0:
            self._check_turns -= 1
        self._watched = True
        self._my_turn(now, now, out)
        self._watched = False

    def _deadline_switch(self, now: int, rx_busy: bool, last_rx: int | None,
                         rx_began: int | None, out: list) -> None:
        """SWITCH: Ttrans after TXEN rose, the radio transmits: send the frame (paper §IV)."""
        self._send(now, out)

    def _deadline_hold(self, now: int, rx_busy: bool, last_rx: int | None,
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

    def _deadline_quiet(self, now: int, rx_busy: bool, last_rx: int | None,
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

    def _header_coming(self, now: int, rx_busy: bool, rx_began: int | None,
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

    def _deadline_window(self, now: int, rx_busy: bool, last_rx: int | None,
                         rx_began: int | None, out: list) -> None:
        """WINDOW: the invited robot did not answer by E + Twin: the poller's successor's turn
        (or a lone member's next pause)."""
        if not self._header_coming(now, rx_busy, rx_began, self.turn_start + self.cfg.twin):
            assert self.poller is not None             # WINDOW: someone opened it
            self._after_window(self.poller, now, out)

    def _deadline_wait(self, now: int, rx_busy: bool, last_rx: int | None,
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
        deaf = self.id == 0 and self.cfg.paired and not self.standby and \
            self._silent >= 2 and not self._heard_since_tx and not self._noise_since_tx
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

    def _watch_ticks(self) -> int:
        """How long after a turn begins we listen for the other PC's header (docs/mac.md).

        An active PC2 checking for PC1 waits W past Ttrans; a standby waits Ttrans +
        (pc + 2) W, longer than a checking PC2 needs to raise TXEN, wait Ttrans and get its
        header out, so a standby never takes a turn from a live active PC."""
        w = max(4 * self.cfg.byte_ticks, self.cfg.standby_watch)
        if self.standby:
            return 2 * self.cfg.ttrans + (self.cfg.pc + 2) * w
        return self.cfg.ttrans + w

    def _takeover(self, src: int, first: int) -> list[int] | None:
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

    def _count_skipped(self, skipped: list[int], out: list) -> None:
        """A takeover seen late: the robots it skipped missed their turns (clause 39)."""
        cfg = self.cfg
        for r in skipped:
            n = self.misses.get(r, 0) + 1
            self.misses[r] = n
            out.append(Miss(r))
            if n >= cfg.miss_limit:
                self._drop(r, out)

    def _active_frame(self, frame: Frame, end: int, now: int, out: list,
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
        if not self.standby:
            lone_other = any(c.name == "poll" and c.args[1] == 1 for c in mac_cmds)
            if self.mode == MEMBER and not self.lone and lone_other:
                return out                     # the other PC claimed alone: it will listen
            if self.mode == LISTEN or self.lone or self.cfg.pc > 1:
                if self.lone:
                    self._to_listen(out, now, "another PC is active as ID 0")
                elif self.mode == MEMBER:      # keep the ring we know; follow the other PC
                    out.append(ModeChange(MEMBER, "another PC is active as ID 0: standing by"))
                self.standby = True            # the other PC is active: stand by for it
                self._check_turns = 0          # a standby keeps the Numbers (clause 50)
            else:
                # PC1 stays active (a PC2 that is active too will yield); the frame, PC2's or
                # a forger's, is refused and closes the slot it was sent in. Heard after a miss
                # with no frame accepted since, it says we were deaf while PC2 took over: on
                # probation we leave new messages to PC2 (clause 50), or both deliver them.
                if silent:
                    self._check_turns = 3
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
        if app_cmds:                           # keep our Numbers after the active PC's
            self._last_num = frame.num
            self._next_num = (frame.num + 1) % 100
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

    def force_turn(self, now: int) -> list:
        """Fault injection: believe the turn is ours right now (a member that missed a frame
        and wrongly takes over). Used to force collisions in tests and fault studies."""
        out: list = []
        if self.mode == MEMBER and self.phase in (WAIT, WINDOW, HOLD):
            self._my_turn(now, now, out)
        return out

    # -- turn machinery ----------------------------------------------------------------------

    def _pair_floor(self, other: int) -> int | None:
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

    def _next_turn(self, after: int, start: int, now: int, out: list,
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

    def _window(self, invited: int, poller: int, end: int, now: int) -> None:
        self.phase = WINDOW
        self.owner = invited
        self.poller = poller
        self.turn_start = end
        self.deadline = end + self.cfg.twin

    def _after_window(self, poller: int, now: int, out: list) -> None:
        if self.lone:
            self._hold(self.turn_start + self.cfg.twin + self.id * self.cfg.tslot, now, out)
        else:
            self._next_turn(poller, now, now, out)

    def _hold(self, start: int, now: int, out: list) -> None:
        self._hold_ref = None
        if start <= now:
            self._my_turn(now, now, out)
        else:
            self.phase = HOLD
            self.owner = self.id
            self.deadline = start

    def _my_turn(self, start: int, now: int, out: list) -> None:
        if start > now:
            self._hold(start, now, out)
            return
        if self.standby or (not self._watched and self.id == 0 and (
                self._check_turns > 0 or
                self.cfg.pc > 1 and self.turns % PC2_CHECK_EVERY == 0)):
            # The active PC's header starts at start + Ttrans and is complete 3 bytes later.
            # A PC that took over watches its first turns (PC1 too: otherwise its probation,
            # which leaves messages undelivered, never ended), and an active PC2 one turn
            # in PC2_CHECK_EVERY: if PC1 were active too, both would send in the same slot,
            # each deaf to the other, for ever.
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

    def _send(self, now: int, out: list) -> None:
        frame, data = self._build_frame(now, out)
        self.phase = SEND
        self.deadline = None
        self.turns += 1
        out.append(Transmit(frame, data))

    # -- membership --------------------------------------------------------------------------

    def _admit(self, robot: int, out: list) -> None:
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

    def _refuse_in_slot(self, src: int, num: int, reason: str, end: int, now: int,
                        out: list, kind: str = "") -> None:
        """A clean frame refused in someone else's slot (out of turn, or with our own ID):
        nothing in it is acted on, but it sets the timing (clause 39)."""
        out.append(Refused(src, num, reason, kind))
        self._tell_view = True                 # our views may differ (rule R-view)
        o = self.owner
        if self.phase == WAIT and o in self.ring and o != self.id:
            # A clean frame in o's slot means o did not send (its frame would have collided
            # with this one): o missed its turn, as at E + Tmax. Otherwise a member that never
            # heard o join could take o's slot for ever.
            n = self.misses.get(o, 0) + 1
            self.misses[o] = n
            out.append(Miss(o))
            if n >= self.cfg.miss_limit:
                self._drop(o, out)
        self._next_turn(src, end, now, out)    # the owner is whoever is sending

    def _own_id_heard(self, num: int, end: int, now: int, out: list) -> None:
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
            # turn; the members took it as ID 0's, so the next turn is robot succ(0)'s
            self._refuse_in_slot(self.id, num, "our own robot ID from the air", end, now, out,
                                 "own_id")
        else:
            out.append(Refused(self.id, num, "our own robot ID from the air", "own_id"))

    def _twin_frame(self, end: int) -> int:
        """Count a frame with our own ID that we did not send: how many this episode (frames
        each less than Tclaim(id) after the previous one; a longer silence starts again)."""
        n, last = self._own_heard or (0, end)
        if end - last > self._claim_ticks():
            n = 0
            self._twin_said = False
        n += 1
        self._own_heard = (n, end)
        return n

    def _foreign_heard(self, src: int, end: int, out: list) -> None:
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

    def _slot_failed(self, robot: int | None, out: list) -> None:
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

    def _refuse_outsider(self, src: int, num: int, end: int, now: int, out: list) -> None:
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

    def _reconcile(self, src: int, mask: int, now: int, out: list) -> None:
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

    def _rebooted(self, src: int, num: int, out: list) -> None:
        """``src`` sent a BOOT frame: it powered on, so its Numbers restart ('00' is the BOOT
        frame's own) and it forgot every Number it had heard (its BOOT frames are
        acknowledged: it sends no message before every member has). A message of ours in
        flight to it may have been delivered before the reboot and would be delivered again:
        it fails."""
        self._last_rx[src] = num
        m = self._inflight
        if m is not None and m.attempts:
            self._unawait(m, src, f"destination {src} restarted before acknowledging (after "
                          f"{m.attempts} attempt(s))", f"robot {src} restarted before "
                          f"acknowledging", out)

    def _unawait(self, m: Message, robot: int, unicast_reason: str, broadcast_reason: str,
                 out: list) -> None:
        """``robot`` will never acknowledge ``m``: a unicast to it fails; a broadcast ends
        once nobody else is awaited (delivered if anyone acknowledged)."""
        if robot not in m.awaiting:
            return
        m.awaiting.discard(robot)
        if m.dst == robot:
            self._finish(m, False, unicast_reason, out)
        elif not m.awaiting:
            self._finish(m, bool(m.acked), "" if m.acked else broadcast_reason, out)

    def _drop(self, robot: int, out: list) -> None:
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

    def _announced(self) -> None:
        """Every member acknowledged our BOOT/JOIN frame: we are in everyone's ring."""
        self._announcing = None
        self._booting = False

    def _unheard_answer(self) -> bool:
        """Our BOOT/JOIN is out and no member has acknowledged it: nobody may have heard it
        (a twin's answer collided with ours, clause 38.2)."""
        return self._announcing is not None and \
            self._ann_awaiting >= set(self.ring) - {self.id}

    def _to_listen(self, out: list, now: int, reason: str, let_pass: bool = False) -> None:
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
        self._fail_run = None             # clause 41a counts again from our next ring
        self.deadline = now + self._claim_ticks()
        out.append(ModeChange(LISTEN, reason))

    # -- delivery ----------------------------------------------------------------------------

    def _on_ack(self, src: int, num: int, now: int, out: list) -> None:
        if self._announcing is not None and num == self._ann_num:
            self._ann_awaiting.discard(src)
            if not self._ann_awaiting:
                self._announced()
            return
        m = self._inflight
        if m is None or m.num != num or src not in m.awaiting:
            return
        m.awaiting.discard(src)
        m.acked.add(src)
        if not m.awaiting:
            self._finish(m, True, "", out)

    def _finish(self, m: Message, delivered: bool, reason: str, out: list) -> None:
        m.state = "delivered" if delivered else "failed"
        m.reason = reason
        if self._inflight is m:
            self._inflight = None
        elif m in self._queue:
            self._queue.remove(m)
        out.append(Outcome(m, delivered, reason))

    def _expire(self, now: int, out: list) -> None:
        """Fail what is too old, also while this robot takes no turns (listening, standing
        by): every message ends within ``max_age`` whatever happens to the robot."""
        limit = now - self.cfg.max_age
        m = self._inflight
        if m is not None and m.submitted < limit:
            self._finish(m, False, f"expired: not acknowledged within "
                         f"{self.cfg.max_age // 16_000} ms", out)
        while self._queue and self._queue[0].submitted < limit:
            self._finish(self._queue[0], False, f"expired: not sent within "
                         f"{self.cfg.max_age // 16_000} ms", out)

    def _pick_message(self, now: int, out: list) -> Message | None:
        """The message to carry this turn (retransmission first), failing what must fail."""
        cfg = self.cfg
        m = self._inflight
        if m is not None:
            if now - m.submitted > cfg.max_age:
                self._finish(m, False, f"expired: not acknowledged within "
                             f"{cfg.max_age // 16_000} ms", out)
            elif m.attempts >= cfg.max_attempts:
                missing = ",".join(str(r) for r in sorted(m.awaiting))
                self._finish(m, False, f"no acknowledgement from {missing} after "
                             f"{m.attempts} attempts", out)
            else:
                return m
        while self._queue:
            m = self._queue[0]
            if now - m.submitted > cfg.max_age:
                self._finish(m, False, f"expired: not sent within {cfg.max_age // 16_000} ms",
                             out)
                continue
            if m.dst != BROADCAST and m.dst not in self.ring:
                m.waited += 1
                if m.waited >= cfg.max_attempts:
                    self._finish(m, False, f"destination {m.dst} not in the ring", out)
                    continue
                return None
            if m.dst == BROADCAST and len(self.ring) < 2:
                m.waited += 1
                if m.waited >= cfg.max_attempts:
                    self._finish(m, False, "broadcast with no other member in the ring", out)
                    continue
                return None
            self._queue.pop(0)
            m.awaiting = {m.dst} if m.dst != BROADCAST else set(self.ring) - {self.id}
            self._inflight = m
            return m
        return None

    def _poll_target(self) -> int | None:
        """An absent team robot in the gap after me to invite this turn, if one is due."""
        cfg = self.cfg
        self._turns_since_poll += 1
        if not self.lone and self._turns_since_poll < cfg.poll_every:
            return None
        ring = self.ring
        nxt = self.succ(self.id)
        gap = []
        i = (self.id + 1) % 7
        while i != nxt and i != self.id:
            if i in cfg.team and i not in ring:
                gap.append(i)
            i = (i + 1) % 7
        if self.lone:
            gap = [r for r in sorted(cfg.team) if r != self.id]
            gap = [r for r in gap if r > self.id] + [r for r in gap if r < self.id]
        if not gap:
            self._turns_since_poll = 0     # nobody to invite: look again in poll_every turns
            return None
        k = self._poll_ptr.get(nxt, 0) % len(gap)
        self._poll_ptr[nxt] = k + 1
        self._turns_since_poll = 0
        return gap[k]

    def _build_frame(self, now: int, out: list) -> tuple[Frame, bytes]:
        """This turn's one frame: a message (or a heartbeat) plus acks and an invitation."""
        if self._paper:
            return self._paper_build(now, out)
        kind: int                               # a FrameType, or the Type announced
        if self._answering or (self._booting and self._announcing is None and
                               not self._lone_boot):
            # The answer to an invitation, or a lone claimer's first frame: nothing else in it.
            # A BOOT frame is Number '00'; a JOIN frame takes the next Number, so that its
            # acknowledgement cannot be mistaken for a message's (docs/protocol.md §4.4,
            # clause 34).
            self._answering = False
            self._sent_poll = None
            if self._booting:
                kind, num = FrameType.BOOT, 0
            else:
                kind, num = FrameType.JOIN, self._next_num
                self._next_num = (num + 1) % 100
            self._announcing, self._ann_num, self._ann_turns = kind, num, 1
            self._ann_awaiting = set(self.ring) - {self.id}
            if not self._ann_awaiting and kind == FrameType.BOOT:
                # A lone claimer's BOOT: nobody acknowledged it, so nobody forgot our old
                # Numbers. It stays unacknowledged (clause 34): the answer to the invitation
                # that brings us into a ring is BOOT, not JOIN, or a member that remembers
                # our last Number from before the restart takes our message with that Number
                # for a duplicate (found on the bench: a father restarted on a live ring).
                self._announcing = None
                self._lone_boot = True
            elif not self._ann_awaiting:
                self._announced()
            frame = self._frame(BROADCAST, num, kind, b"")
            return frame, frame.encode()
        if self._announcing is not None:
            # BOOT/JOIN frames until every member has acknowledged: a BOOT so that no message
            # of ours comes before every receiver forgot our old Numbers; a JOIN so that we
            # know every member heard us join (else we would share a slot with someone).
            self._ann_turns += 1
            self._expire(now, out)
            msg, poll_to = None, None
        else:
            msg = self._pick_message(now, out)
            poll_to = self._poll_target()
        crc_room = self._ext_len
        extra: list[Command] = []
        if poll_to is not None:
            extra.append(cmd("poll", poll_to, _mask(self.ring)))
        elif self._tell_view and self._announcing is None and not self.lone:
            extra.append(cmd("ring", _mask(self.ring)))
        acks = self._acks
        room = self.max_content - crc_room - (len(msg.content) if msg is not None else 0)
        if msg is not None and (acks and self._acks_deferred or room < 0 or
                                room < sum(_ack_len(a) for a in acks)):
            # Acknowledgements never wait behind a message: a sender that heard no ack by its
            # next turn retransmits its whole frame (up to Tmax of air). Our message goes
            # next turn instead (docs/protocol.md §4.7).
            msg = None
            room = self.max_content - crc_room
        carried: list[Command] = []
        used = sum(len(c.text()) for c in extra) if extra else 0
        if used > room:
            extra, used, poll_to = [], 0, None
        elif extra:
            self._tell_view = False            # a poll's mask tells our view too
        kept = []
        for a in acks:
            n = _ack_len(a)
            if used + n <= room:
                carried.append(cmd("ack", a[0], a[1]))
                used += n
            else:
                kept.append(a)
        self._acks = kept
        self._acks_deferred = bool(kept)
        self._sent_poll = poll_to
        mac_part = carried + extra
        if msg is not None:
            msg.attempts += 1
            msg.state = "sent"
            self._last_num = msg.num           # control frames repeat it from now on
            content = msg.content + (format_content(mac_part) if mac_part else b"")
            frame = self._frame(msg.dst, msg.num, msg.type, content)
            return frame, frame.encode()
        num = self._last_num
        content = format_content(mac_part) if mac_part else b""
        kind = FrameType.BROADCAST_INFO
        if self._announcing is not None:
            kind, num = self._announcing, self._ann_num
        if self._key is not None:           # every frame differs: its own freshness
            frame = self._frame(BROADCAST, num, kind, content)
            return frame, frame.encode()
        key = (num, content, kind)
        hit = self._hb_cache.get(key)
        if hit is None:
            frame = self._frame(BROADCAST, num, kind, content)
            hit = (frame, frame.encode())
            if len(self._hb_cache) < 256:
                self._hb_cache[key] = hit
        return hit

    def _paper_build(self, now: int, out: list) -> tuple[Frame, bytes]:
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

    def _frame(self, dst: int, num: int, type: int, content: bytes) -> Frame:
        if self._key is not None:
            fresh = self.auth_tx
            self.auth_tx = fresh + 1
            self._auth_rx[self.id] = fresh     # a replay of our own frame is stale too
            return _auth.seal(self._key, dst, self.id, num, int(type), content, fresh)
        if self.cfg.checksum:
            return seal(dst, self.id, num, int(type), content)
        return Frame(dst=dst, src=self.id, num=num, type=type, content=content)


DEADLINE_HANDLERS = {
    WATCH: RotationalMac._deadline_watch,
    SWITCH: RotationalMac._deadline_switch,
    HOLD: RotationalMac._deadline_hold,
    QUIET: RotationalMac._deadline_quiet,
    WINDOW: RotationalMac._deadline_window,
    WAIT: RotationalMac._deadline_wait,
}
"""What a deadline means in each MEMBER phase (LISTEN has its own: claim)."""

"""The rotational MAC's configuration (``MacConfig``: timing in ticks and policy, with the bounds
derived from it) and its policy constants, and the checks every MAC makes at submission
(``check_submission``, shared with the peer MACs). The state machine is in mac.py."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

from ..timing import (
    CHILD_BYTE_TICKS,
    FRAME_OVERHEAD,
    MISS_LIMIT,
    PC_BYTE_TICKS,
    TMAX_TICKS,
    TTRANS_TICKS,
)
from . import auth as _auth
from .content import Command, format_content
from .frame import BROADCAST
from .integrity import CRC_TEXT_LEN
from .mac_events import SubmitError


PROFILES = ("rprs", "paper")
"""``rprs``: docs/protocol.md in full. ``paper``: only the paper's rules on the wire (a static ring
from the team, empty heartbeats, no BOOT, JOIN, poll, ring, ack or crc; docs/protocol.md §9)."""
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
    before Tmax (docs/protocol.md §7.6; tests/docs/test_margin_bounds.py)."""
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
    fast_path: bool = True
    """The expected owner's heartbeat takes the MAC's short path, which hands the turn on with
    exactly the actions of the general path (tests/firmware_model/radio/test_mac_fast_path.py
    compares them). False: every frame takes the general path (the simulator's
    ``fast_paths=False``, to show the two are the same)."""
    profile: str = "rprs"
    """``rprs`` (the whole of docs/protocol.md) or ``paper``: only the paper's rules, to share a
    ring with robots that implement only the paper (docs/protocol.md §9, the paper profile)."""

    def __post_init__(self) -> None:
        if self.profile not in PROFILES:
            raise ValueError(f"profile must be one of {', '.join(PROFILES)}, "
                             f"got {self.profile!r}")
        if self.profile == "paper" and (self.checksum or self.standby or self.paired):
            raise ValueError("the paper profile has no checksum extension and no father pair "
                             "(a standby PC, --pc: both are this project's extensions)")
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
    if not commands:
        raise SubmitError("a message needs at least one command: an empty Content is a "
                          "heartbeat (docs/protocol.md clause 21), which nobody acknowledges")
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

"""What the rotational MAC (``firmware_model.radio.mac``) hands out: the actions for its driver
(``TxEnable``, ``Transmit``), the observations for traces, tests and the application (``Miss``,
``Deliver``, ``Refused`` ...), the ``Message`` a submission becomes and its ``Outcome``, and the
errors a submission raises. Plain frozen records: the MAC's state machine is in mac.py."""
from __future__ import annotations

from dataclasses import dataclass, field

from .content import Command
from .errors import ContentError
from .frame import Frame


UNACKNOWLEDGED = "unacknowledged"
"""A message's final state in the paper profile: sent once, never acknowledged."""


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
class LateAck:
    """``src`` acknowledged our message ``num`` after it had failed unacknowledged (its
    acknowledgements lost, or we deaf): ``src`` has it after all, and may answer it."""

    src: int
    num: int


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

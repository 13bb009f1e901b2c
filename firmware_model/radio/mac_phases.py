"""The rotational MAC's modes and, while a member, its phases (``RotationalMac.mode`` and
``.phase``; the states of mac_table.py). Their values are what traces and tests read."""
from __future__ import annotations

from enum import Enum

# Modes.
LISTEN = "listen"    # not in a ring: waits for an invitation, or claims a silent channel
MEMBER = "member"    # in a ring: takes its turns


class Phase(str, Enum):
    """A member's phase. Each is also the plain string it was before it was an enum member
    (``Phase.WAIT == "wait"``, with the same hash and the same text in a trace or an
    f-string), so tables, traces and tests that use the strings read it unchanged."""

    WAIT = "wait"        # waiting for the header of ``owner`` until ``deadline``
    WINDOW = "window"    # a poll window for the invited ``owner`` until ``deadline``
    HOLD = "hold"        # my turn starts at ``deadline`` (after a corrupted frame or a lone pause)
    SWITCH = "switch"    # TXEN is high; my frame starts at ``deadline`` (= turn start + Ttrans)
    SEND = "send"        # my frame is on air; ``on_tx_done`` ends the turn
    QUIET = "quiet"      # a frame failed before its Length: wait for the channel to fall quiet
    WATCH = "watch"      # hot standby: ID 0's turn; is the active PC's header coming?

    def __str__(self) -> str:
        return str.__str__(self)       # "wait", not "Phase.WAIT"

    def __format__(self, spec: str) -> str:
        return str.__format__(self, spec)


WAIT = Phase.WAIT
WINDOW = Phase.WINDOW
HOLD = Phase.HOLD
SWITCH = Phase.SWITCH
SEND = Phase.SEND
QUIET = Phase.QUIET
WATCH = Phase.WATCH

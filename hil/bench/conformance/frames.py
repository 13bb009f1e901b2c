"""Small readings of frames the kit's steps share: a frame's kind, its polls and ring mask,
whose turn follows whose (clauses 22, 26, 38.3), the forger for clause 38."""
from __future__ import annotations

from typing import Callable

from firmware_model.radio.content import parse_content
from firmware_model.radio.errors import ContentError
from firmware_model.radio.frame import Frame

from .report import Heard


def _app(content: bytes) -> bool:
    try:
        return any(c.spec.layer == "app" for c in parse_content(content))
    except ContentError:
        return False


def _kind(f: Frame, sealed: bool = False) -> str:
    """Clause 21's kind of the robot's frame ``f``; ``sealed``: its ``auth(...)`` already
    taken off (the authenticated profile has no heartbeat: its idle frame is a control
    frame)."""
    if not f.content:
        return "control" if sealed else "heartbeat"
    try:
        cmds = parse_content(f.content)
    except ContentError:
        return "unreadable"
    return "control" if all(c.spec.layer == "mac" for c in cmds) else "message"


def _last_digit_changed(frame: bytes) -> bytes:
    """An encoded frame whose Content ends ``...N)`` with that last digit N changed (a tag's
    or a checksum's): the End (2 bytes) and ``)`` follow it."""
    i = len(frame) - 4
    return frame[:i] + (b"0" if frame[i:i + 1] != b"0" else b"1") + frame[i + 1:]


def _polls_of(f: Frame) -> list[tuple[int, int]]:
    """The ``poll(k,mask)`` commands of ``f``'s Content, as (k, mask)."""
    try:
        cmds = parse_content(f.content) if f.content else []
    except ContentError:
        return []
    return [(c.args[0], c.args[1]) for c in cmds if c.name == "poll"]


def _mask_of(f: Frame) -> int | None:
    try:
        cmds = parse_content(f.content) if f.content else []
    except ContentError:
        return None
    for c in cmds:
        if c.name == "ring":
            return c.args[0]
        if c.name == "poll":
            return c.args[1]
    return None


def _succ(src: int, ring: tuple[int, ...]) -> int:
    """The member whose turn follows a frame from ``src`` (in the ring or not): the next ID
    of ``ring`` after ``src`` in ascending order, wrapping (clauses 22, 26, 38.3)."""
    after = sorted(i for i in ring if i > src)
    return after[0] if after else min(ring)


def _forger(robot: int, me: int) -> int:
    """The forged Source for clause 38: a robot outside the ring {robot, me}, preferably one
    after which our turn comes (so our own frame follows the forged one, as in the ring's
    own rhythm); when none lies between the robot and us in ring order (robot 6, tester 0),
    the lowest other ID, after which the robot's turn comes."""
    others = [i for i in range(7) if i not in (robot, me)]
    ours = [i for i in others if _succ(i, (robot, me)) == me]
    return (ours or others)[0]


def _at_turn(watch: Callable[[Heard, int], None], k: int, h: Heard, i: int) -> None:
    """``watch`` shown the robot's frame ``h`` as the ``k``-th of a run of turns (``i``, the
    index within one call of :meth:`Tester._turns`, is not used)."""
    watch(h, k)

"""The rotational MAC's failed receptions (docs/protocol.md §4.5, clauses 41-43): a frame that
failed after a valid Header (its turn closes at the End its Length promised, or when the
channel falls quiet), such a frame over sooner, and bytes that form no frame. Functions of a
``RotationalMac``, bound as its methods in mac.py."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

from .mac_phases import HOLD, LISTEN, MEMBER, QUIET, SEND, SWITCH, WAIT, WATCH, WINDOW

if TYPE_CHECKING:
    from .mac import RotationalMac

_NOTHING: tuple = ()


def on_corrupt(self: RotationalMac, first: int, src: int | None, expected_end: int | None,
               now: int) -> list:
    """A frame failed after a valid header: the turn is used (not a miss) and closes at the
    end its Length promised, or ``first + Tmax`` when the Length was never read."""
    out: list = []
    if self.phase == SWITCH or self.phase == SEND:
        return out
    self._heard_after_tx(first, good=False, last=now)
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


def on_frame_over(self: RotationalMac, now: int) -> Sequence[Any]:
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


def on_garbage(self: RotationalMac, first: int, last: int, now: int) -> Sequence[Any]:
    """Bytes that form no frame were heard. In the owner's slot they are probably its frame
    with a corrupted Header: if the channel then falls quiet the turn closes (no miss);
    if it never does (idle noise), the owner misses at E + Tmax as usual."""
    self._heard_after_tx(first, good=False, last=last)
    if self.mode == MEMBER and self.phase == WAIT and self.owner is not None and \
            last > self.turn_start + self.cfg.ttrans:
        self._tell_view = True
        self.phase = QUIET
        self._quiet_miss = True
        self._quiet_limit = self.turn_start + self.cfg.tmax
        self.deadline = max(now, min(last + self.cfg.quiet_gap, self._quiet_limit))
    return _NOTHING

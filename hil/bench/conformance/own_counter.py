"""The kit's opt-in long step (``rprs conformance --wrap``): the robot's own message counter
runs past '99' (docs/protocol.md clause 45: "+1 modulo 100, '99' then '00'").

The default run sees two or three of the robot's messages, so it checks how the robot *reads*
a wrapped Number (ours, clause 48), never how it *writes* one: that needs about a hundred
messages of its own. Here every turn of ours carries a new ``status()`` for it (once our last
one is acknowledged: one message in flight, clause 46) and the acknowledgement of its last
reply, so it sends a new message, Type '3' or '4', in about every turn of its own.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .frames import _app
from .refusals import FATHER
from .report import Heard

if TYPE_CHECKING:
    from .tester import Tester

NAME = "its own Number counter runs '99' then '00', each message the next"

WRAP_SLACK_TURNS = 60
"""Turns allowed beyond two a message (a reply may take more than one turn: a busy PC, a CAN
side that waits for its submodules) before the step gives up."""


def _own_wrap(self: Tester, h: Heard) -> Heard:
    """New ``status()`` orders until the robot's replies have passed Number '99'; pass when
    each reply's Number is the one after the reply before it (clause 45), '00' after '99'.
    n/a in the paper profile (it has no status(): nothing makes the robot send)."""
    t0 = self._secs()
    if self.profile != "rprs" or self.robot == 0:
        self.check("45", NAME, True, "the paper profile has no status(): nothing makes the "
                   "robot send a message of its own" if self.robot else
                   f"{FATHER}: nothing makes it send a message of its own", t0,
                   applicable=False)
        return h
    nums: list[int] = []          # its new messages to us, in order (a resent one once)
    ours_acked = [True]

    def watch(h: Heard, i: int) -> None:
        f = h.frame
        if b"ack(%d,%d)" % (self.me, self.num) in f.content:
            ours_acked[0] = True
        if f.dst == self.me and f.type in (3, 4) and _app(f.content) and \
                f.num not in nums[-1:]:
            nums.append(f.num)

    def wrapped() -> bool:
        return 99 in nums and nums.index(99) < len(nums) - 1

    def wrong() -> int | None:
        """The index of the first reply whose Number is not the one after the last's."""
        return next((i for i in range(1, len(nums))
                     if nums[i] != (nums[i - 1] + 1) % 100), None)

    budget = 2 * 101 + WRAP_SLACK_TURNS
    turns = 0
    while turns < budget and not wrapped() and wrong() is None:
        if ours_acked[0]:             # a new message; else ours again, same Number (cl. 46)
            self.num = (self.num + 1) % 100
            ours_acked[0] = False
        h = self._turns(h, 1, (b"status()", {"dst": self.robot, "type_": 2,
                                             "num": self.num}), watch)
        turns += 1
    h = self._turns(h, 1, None, watch)          # (the acknowledgement of its last reply)
    bad = wrong()
    if bad is not None:
        figure = (f"after '{nums[bad - 1]:02d}' its next message was '{nums[bad]:02d}', not "
                  f"'{(nums[bad - 1] + 1) % 100:02d}'" +
                  (" ('99' wraps to '00')" if nums[bad - 1] == 99 else ""))
    elif wrapped():
        figure = (f"{len(nums)} messages, '{nums[0]:02d}' to '{nums[-1]:02d}', each the "
                  f"next; '99' then '00'")
    else:
        figure = (f"{len(nums)} replies to our status() in {turns} turns, the last "
                  f"'{nums[-1]:02d}'" if nums else f"no reply to our status() in {turns} "
                  "turns") + ": its counter never passed '99'"
    self.check("45", NAME, bad is None and wrapped(), figure, t0)
    return h

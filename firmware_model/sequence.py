"""The paper's multi-robot experiment (§V.B, Fig. 11) as each child runs it.

Robots R1..Rn stand in a row. R1 announces an action and turns its end link to the left; when
it is done it tells the others; then R2 does the same, then R3. Then each returns to its
initial pose in the same order. That is one action cycle; the experiment repeats it. A joint
motion takes longer than Tmax, so the action cycle runs asynchronously to the ring.

Every robot holds the same plan and follows it from the notices it hears on the radio: the
broadcast ``act(n,1)`` that a robot sends when its action n is done. The robot whose step comes
next starts when it hears (or makes) the previous step's notice; R1 starts the first step when
every robot of the row is in its ring.
"""
from __future__ import annotations

from dataclasses import dataclass, field

END_LINK_LEFT = 1
RETURN = 0
ACTION_NAMES = {0: "return", 1: "end-link-left", 2: "end-link-right"}


@dataclass
class ActionSequence:
    """The plan of one robot (``me``) in a row ``order`` for ``cycles`` action cycles."""

    me: int
    order: tuple[int, ...]
    cycles: int = 1
    plan: list[tuple[int, int]] = field(init=False)     # (action, robot), in order
    step: int = field(init=False, default=0)            # the next step not yet done
    started: bool = field(init=False, default=False)    # has this robot begun the sequence

    def __post_init__(self) -> None:
        if self.me not in self.order:
            raise ValueError(f"robot {self.me} is not in the row {list(self.order)}")
        if self.cycles < 1:
            raise ValueError(f"cycles must be at least 1, got {self.cycles}")
        self.plan = [(action, r) for _ in range(self.cycles)
                     for action in (END_LINK_LEFT, RETURN) for r in self.order]

    @property
    def finished(self) -> bool:
        return self.step >= len(self.plan)

    def kickoff(self, ring: tuple[int, ...]) -> int | None:
        """The action to start now, if this robot is R1 and the whole row is in the ring."""
        if self.started or self.step or self.me != self.order[0] or \
                not set(self.order) <= set(ring):
            return None
        self.started = True
        return self.plan[0][0]

    def on_done(self, robot: int, action: int) -> int | None:
        """A done notice (``act(action,1)`` from ``robot``, or our own completion): advance,
        and return the action this robot must start now, if any."""
        if self.finished or self.plan[self.step] != (action, robot):
            return None
        self.step += 1
        if not self.finished and self.plan[self.step][1] == self.me:
            self.started = True
            return self.plan[self.step][0]
        return None

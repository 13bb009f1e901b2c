"""One interrupt handler on the CPU model (firmware_model/mcu/cpu.py): the interrupt source
that requests it, the figures it leaves (cycles and ticks) and its frame while it runs
(milestones in machine cycles of its own work)."""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

MAIN_LEVEL = 7
"""ILM while the main loop runs: every enabled interrupt (levels 0-6) is accepted."""


@dataclass(frozen=True)
class Vector:
    """One interrupt source as the firmware programs it: its ICR level (0 highest, 7
    disabled) and its interrupt number (the lower wins among requests of one level)."""

    name: str
    level: int
    number: int

    def __post_init__(self) -> None:
        if not 0 <= self.level <= 7:
            raise ValueError(f"{self.name}: interrupt level must be 0-7 (ICR IL2-IL0), "
                             f"got {self.level}")


class HandlerStats:
    """What one handler cost: calls, busy cycles (entry, body and RETI, preemptions not
    included), latency (request to acceptance) and response (request to its effects): ticks,
    counted per value (a few distinct values however long the run)."""

    STEADY_COUNTERS = ("calls", "busy", "latency", "response")
    """Handler calls, their cycles and their latency and response counts: counts only
    (hil/sim/steady.py); the worst figures are values, which a steady ring no longer moves."""

    __slots__ = ("name", "level", "calls", "busy", "latency", "response", "worst_latency",
                 "worst_response")

    def __init__(self, name: str, level: int) -> None:
        self.name = name
        self.level = level
        self.calls = 0
        self.busy = 0
        self.latency: Counter[int] = Counter()
        self.response: Counter[int] = Counter()
        self.worst_latency = 0
        self.worst_response = 0

    def responded(self, ticks: int, n: int = 1) -> None:
        """``n`` calls whose effects came ``ticks`` after their request."""
        self.response[ticks] += n
        if ticks > self.worst_response:
            self.worst_response = ticks


class _Frame:
    """A handler (or main-loop task) on the CPU: its milestones in cycles of its own work."""

    __slots__ = ("stats", "level", "enter", "fn", "args", "entry", "body_end", "end", "done",
                 "since", "requested", "phase", "body_at")

    def __init__(self, stats: HandlerStats, level: int, enter, fn, args, entry: int,
                 body: int, reti: int, requested: int) -> None:
        self.stats = stats
        self.level = level
        self.enter = enter
        self.fn = fn
        self.args = args
        self.entry = entry
        self.body_end = entry + body
        self.end = entry + body + reti
        self.done = 0          # cycles of its own work done
        self.since = 0         # tick it last resumed
        self.requested = requested
        self.phase = 0         # 0 entry, 1 body, 2 RETI
        self.body_at = -1      # the tick its body's end was last scheduled (its event made)

    def next_milestone(self) -> int:
        return (self.entry, self.body_end, self.end)[self.phase]

    def atomic(self) -> bool:
        """The entry sequence and RETI cannot be interrupted."""
        return self.phase != 1

"""A GPIO output pin of the MB90F549 (port data register bit), e.g. P40 driving PTR2000 TXEN."""
from __future__ import annotations

from typing import Callable


class OutputPin:
    """An output pin; ``listeners`` are called as ``fn(level, tick)`` when the level changes."""

    __slots__ = ("name", "level", "listeners", "changed_at")

    def __init__(self, name: str, level: bool = False) -> None:
        self.name = name
        self.level = level
        self.listeners: list[Callable[[bool, int], None]] = []
        self.changed_at = 0

    def set(self, level: bool, now: int) -> None:
        level = bool(level)
        if level == self.level:
            return
        self.level = level
        self.changed_at = now
        for fn in self.listeners:
            fn(level, now)

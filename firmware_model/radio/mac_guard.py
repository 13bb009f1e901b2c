"""The transition table as a guard: with :func:`table_guard` on, every event the rotational MAC
takes (``power_on``, ``on_frame``, ``on_corrupt``, ``on_garbage``, ``on_timer``, ``on_tx_done``,
``force_turn``) must move it along a row of ``mac_table.TRANSITIONS``, or it raises
:class:`TransitionError` naming the state, the event and where the MAC went.

Off by default: the firmware pays nothing for it. The test suite turns it on for the whole run
(tests/conftest.py), in its own process and, through ``RPRS_MAC_TABLE_GUARD=1`` in the
environment, in every ``rprs`` process it starts (hil/cli reads it), so every simulated ring,
bench child and conformance run the tests make is checked against the table, not only the runs
tests/firmware_model/radio/test_mac_table.py observes.
"""
from __future__ import annotations

import os
from contextlib import contextmanager
from functools import wraps
from typing import Any, Callable, Iterator

from .mac import LISTEN, RotationalMac
from .mac_table import TRANSITIONS

__all__ = ["ENV", "EVENTS_OF", "TransitionError", "enabled", "install_from_environment",
           "state_of", "table_guard", "unguarded"]

ENV = "RPRS_MAC_TABLE_GUARD"
"""The environment variable that turns the guard on in an ``rprs`` process (``1``)."""

EVENTS_OF: dict[str, str] = {
    "power_on": "power on", "on_frame": "frame", "on_corrupt": "failed frame",
    "on_garbage": "garbage", "on_timer": "deadline", "on_tx_done": "tx done",
    "force_turn": "steal"}
"""Each entry point of the MAC and the table's name for its event."""

ROWS = frozenset((t.state, t.event, t.next) for t in TRANSITIONS)


class TransitionError(AssertionError):
    """The MAC moved along no row of the transition table."""


def state_of(mac: RotationalMac) -> str:
    """The table's name of ``mac``'s state: ``LISTEN``, or its phase as a member."""
    return "LISTEN" if mac.mode == LISTEN else str(mac.phase).upper()


def _guarded(name: str, event: str, method: Callable[..., Any]) -> Callable[..., Any]:
    @wraps(method)
    def guarded(self: RotationalMac, *args: Any, **kw: Any) -> Any:
        if event == "deadline" and (self.deadline is None or args[0] < self.deadline):
            return method(self, *args, **kw)     # a timer before the deadline: no event
        before = state_of(self)
        out = method(self, *args, **kw)
        after = state_of(self)
        if (before, event, after) not in ROWS:
            raise TransitionError(
                f"robot {self.id}: {before} --{event}--> {after} is no row of the transition "
                f"table (firmware_model/radio/mac_table.py); {name} made it")
        return out
    guarded.__guarded__ = True          # type: ignore[attr-defined]
    return guarded


def _is_guarded(method: Any) -> bool:
    return getattr(method, "__guarded__", False)


def enabled() -> bool:
    """Whether the guard is on (every entry point is wrapped)."""
    return all(_is_guarded(RotationalMac.__dict__[name]) for name in EVENTS_OF)


@contextmanager
def table_guard() -> Iterator[None]:
    """The guard on for the ``with`` block (nested blocks leave it on until the outermost
    ends)."""
    if enabled():
        yield
        return
    saved = _install()
    try:
        yield
    finally:
        for name, method in saved.items():
            setattr(RotationalMac, name, method)


def _install() -> dict[str, Callable[..., Any]]:
    """Wrap the entry points not wrapped yet (one wrapped twice would be checked twice, and
    one layer taken off would leave it guarded); the methods they replaced."""
    saved = {name: RotationalMac.__dict__[name] for name in EVENTS_OF
             if not _is_guarded(RotationalMac.__dict__[name])}
    for name, method in saved.items():
        setattr(RotationalMac, name, _guarded(name, EVENTS_OF[name], method))
    return saved


def unguarded(set_attr: Callable[[Any, str, Any], None] = setattr) -> None:
    """The MAC's entry points without the guard, set with ``set_attr`` (pytest's
    ``monkeypatch.setattr`` puts the guard back after the test): for a MAC broken on purpose,
    whose transitions the table need not hold."""
    for name in EVENTS_OF:
        method = RotationalMac.__dict__[name]
        if _is_guarded(method):
            while _is_guarded(method):
                method = method.__wrapped__
            set_attr(RotationalMac, name, method)


def install_from_environment() -> None:
    """Turn the guard on for the rest of this process if ``RPRS_MAC_TABLE_GUARD=1``."""
    if os.environ.get(ENV) == "1" and not enabled():
        _install()

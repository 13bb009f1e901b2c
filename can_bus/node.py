"""What a node on a CAN bus provides: the hooks :class:`~can_bus.bus.CanBus` calls.

Every hook is optional (a node that only listens has ``on_frame`` alone), so the bus looks
each one up once, at :meth:`~can_bus.bus.CanBus.attach`, and keeps the bound method (its hot
path calls no ``getattr``). What each hook means is in :mod:`can_bus.bus` ("Nodes").

Roles
-----
The hooks come in four roles, each a :class:`~typing.Protocol`. A node's class names the
roles it plays among its bases, ``class Transceiver82C250(CanNode)``, so that mypy holds its
hooks to these signatures: a hook with the wrong parameters is an ``[override]`` error, and a
hook left out or misspelled leaves the role's member abstract, an error where mypy sees the
class made (or, for a ``@final`` class, at the class itself).

* :class:`FrameSource`: ``pending()`` and ``on_tx_done(frame, end)``: the node keeps its own
  queue of frames to send and takes a frame off it when it went.
* :class:`FrameSink`: ``on_frame(frame, start, end)``.
* :class:`ArbitrationLoser`: ``on_arbitration_lost(frame)``.
* :class:`ErrorListener`: ``on_error(event)`` and ``on_state_change(old, new, tick)``.
* :class:`CanNode`: all four (the 82C250, and the MB90F549 controller behind it).

Values, read by the bus (each optional, see :mod:`can_bus.bus`): ``pending_after_request``
(bool), ``rx_ids`` (the identifiers ``on_frame`` acts on), ``acknowledges`` (bool, read at
each frame), ``recovers_on_request`` (bool, read at bus-off).

A node need not name any role (a test's node, a bench script's listener): the bus takes any
object. :func:`check_node`, which ``attach`` runs, refuses what would otherwise fail in
silence: a node that names a role and lacks one of its hooks, a hook that is not callable,
and a public name one typo away from a hook (``on_frames``, ``on_tx_don``), which the bus
would never call.
"""
from __future__ import annotations

import difflib
from functools import lru_cache
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from can_bus.bits import BitTiming
    from can_bus.bus import CanErrorEvent, ErrorState
    from can_bus.frames import CanFrame

__all__ = [
    "ArbitrationLoser",
    "CanNode",
    "ErrorListener",
    "FrameSink",
    "FrameSource",
    "HOOKS",
    "NodeBus",
    "check_node",
]


class FrameSource(Protocol):
    """A node that keeps its own queue: the bus asks ``pending()`` at each arbitration."""

    __slots__ = ()

    def pending(self) -> CanFrame | None:
        """The node's highest-priority frame waiting to be sent, or None."""
        ...

    def on_tx_done(self, frame: CanFrame, end: int) -> None:
        """``frame`` was sent and acknowledged (its last EOF bit at ``end``)."""
        ...


class FrameSink(Protocol):
    """A node that receives frames."""

    __slots__ = ()

    def on_frame(self, frame: CanFrame, start: int, end: int) -> None:
        """A frame was received (SOF at ``start``, the end of its last EOF bit at ``end``)."""
        ...


class ArbitrationLoser(Protocol):
    """A node told when another node's frame beat its own."""

    __slots__ = ()

    def on_arbitration_lost(self, frame: CanFrame) -> None:
        """Called at the SOF tick of the frame that beat ``frame``."""
        ...


class ErrorListener(Protocol):
    """A node told of the errors it detects and of its error state."""

    __slots__ = ()

    def on_error(self, ev: CanErrorEvent) -> None:
        """The node detected an error (its counters already updated)."""
        ...

    def on_state_change(self, old: ErrorState, new: ErrorState, tick: int) -> None:
        """Error-active, error-passive, bus-off: ``old`` became ``new`` at ``tick``."""
        ...


class CanNode(FrameSource, FrameSink, ArbitrationLoser, ErrorListener, Protocol):
    """A node with every hook: a CAN controller, or the transceiver in front of one."""

    __slots__ = ()


class NodeBus(Protocol):
    """What a node sees of the bus it is on: the simulator's ``CanBus``, or the bench's
    ``PythonCanBus`` (can_bus/bridge.py) in front of a real or virtual bus."""

    timing: BitTiming

    def attach(self, node: object) -> None:
        """Put ``node`` on the bus (its hooks are checked: ``check_node``)."""
        ...

    def request(self, node: FrameSource) -> None:
        """``node`` has a frame to send: the bus asks its ``pending`` when it may."""
        ...


ROLES: tuple[type, ...] = (FrameSource, FrameSink, ArbitrationLoser, ErrorListener)
METHOD_HOOKS = ("pending", "on_tx_done", "on_frame", "on_arbitration_lost", "on_error",
                "on_state_change")
VALUE_HOOKS = ("pending_after_request", "rx_ids", "acknowledges", "recovers_on_request")
HOOKS = METHOD_HOOKS + VALUE_HOOKS
"""Every name the bus looks for on a node."""

_NEAR = 0.85
"""How alike (difflib's ratio) a name must be to a hook's to be taken for its misspelling:
``on_frames``, ``pendng``, ``rx_id``, ``recover_on_request`` are (0.91 and more); ``on_wake``,
``on_timer``, ``error_state`` are not (0.7 and less)."""


@lru_cache(maxsize=1024)
def _misspelt(names: tuple[str, ...]) -> tuple[tuple[str, str], ...]:
    """(name, the hook it is a typo of) for each such name; cached: the nodes of one class
    have the same names."""
    found = []
    for name in names:
        if name.startswith("_") or name in HOOKS:
            continue
        near = difflib.get_close_matches(name, HOOKS, 1, _NEAR)
        if near:
            found.append((name, near[0]))
    return tuple(found)


_CHECKED: dict[type, tuple[str, ...]] = {}


def _class_problems(cls: type) -> tuple[str, ...]:
    """What is wrong with a node class, decided once per class."""
    known = _CHECKED.get(cls)
    if known is not None:
        return known
    problems = []
    mro = cls.__mro__
    for role in ROLES:
        if role in mro and cls not in ROLES and cls is not CanNode:
            for hook in METHOD_HOOKS:
                if hook in role.__dict__ and getattr(cls, hook) is role.__dict__[hook]:
                    problems.append(f"{cls.__name__} names the role {role.__name__} but does "
                                    f"not define {hook}()")
    for name, hook in _misspelt(tuple(dir(cls))):
        problems.append(f"{cls.__name__} has {name!r}, which no CAN bus calls: a misspelt "
                        f"{hook!r}?")
    _CHECKED[cls] = found = tuple(problems)
    return found


def check_node(node: object) -> None:
    """Raise TypeError, saying why, if ``node`` names a role without one of its hooks, has a
    hook that is not callable, or has a public name that looks like a misspelt hook (the
    hooks: :data:`HOOKS`, their meaning: :mod:`can_bus.bus`)."""
    problems = list(_class_problems(type(node)))
    own = getattr(node, "__dict__", None)
    if own:
        problems += [f"{node!r} has {name!r}, which no CAN bus calls: a misspelt {hook!r}?"
                     for name, hook in _misspelt(tuple(own))]
    for hook in METHOD_HOOKS:
        fn = getattr(node, hook, None)
        if fn is not None and not callable(fn):
            problems.append(f"{node!r}.{hook} is a {type(fn).__name__}, not a method")
    if problems:
        raise TypeError("; ".join(problems) + " (the hooks a CAN node may have: "
                        "can_bus/node.py)")

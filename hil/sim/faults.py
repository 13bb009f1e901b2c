"""Fault injection: one grammar and one seeded mechanism for the simulator and the radio hub.

A fault is written ``KIND[:TARGET]@WHEN[:VALUE]`` (times in seconds from the start):

=========================  ===============================================================
``fail:R@T``               robot R's radio goes silent at T (mid-frame too); R=0: the father
``recover:R@T``            robot R's radio comes back
``steal:R@T``              robot R wrongly takes the turn at T (two robots both believe they
                           own it: a forced collision)
``ber@T1-T2:P``            byte error rate P between T1 and T2
``noise@T1-T2``            idle noise (random bytes when nobody transmits) between T1 and T2
``burst@T:S``              interference: S seconds of random bytes on air from T
``foreign@T:N``            a transmitter that is no robot sends N random bytes from T (tick
                           ``s_to_ticks(T)``), 8N1 at 9600 (16667 ticks a byte); the bytes
                           come from a stream seeded by the run's seed and this spec
``foreign@T:xHEX``         the same with exactly these bytes, e.g. ``foreign@2.5:x0f0a05``
                           (an even number of hex digits after ``x``; a count never starts
                           with ``x``, so the two forms cannot be confused)
``drop@T1-T2:P``           each received byte is lost (UART overrun) with probability P
``skew:R:E``               robot R's clock runs E slow (0 <= E < 0.2, e.g. 0.02): its byte
                           time and every interval it times (UART, timers) are (1 + E) times
                           nominal; its PTR2000's switch times are the part's. A clock
                           that runs fast (E < 0) is refused: not modelled
``busoff:R@T``             child R's CAN controller driven bus-off (bit errors on its frames)
``stuck:R@T1-T2``          child R's 82C250 TXD stuck dominant from T1 to T2
``silent:R.NODE@T1-T2``    submodule NODE (JOINT1-4, WHEEL, PAW) of child R stops answering
``stall:R.NODE@T[-T2]``    joint or wheel NODE of child R stalls at T (cleared at T2)
``noisy:R.NODE@T1-T2``     a disturbance on NODE's stub of child R's CAN bus (NODE: JOINT1-4,
                           WHEEL, PAW or MCU, the child's own controller): every frame NODE
                           receives gets an error NODE alone sees, T1 to T2
=========================  ===============================================================

Times are seconds, each mapped to one exact tick (``s_to_ticks``); ``Fault.spec()`` writes
them with the 10 decimals a tick (62.5 ns) needs, so a spec round-trips to the same tick.

Air faults (``ber``, ``noise``, ``burst``, ``foreign``, ``drop``, ``fail``/``recover`` of a
node) act on ``hil.sim.air.Air``, which both the simulator and the pty radio hub use, so the same
spec means the same thing on both. Randomness comes from the air's and the world's seeded
streams. ``rprs inject --random N --seed S --at T`` writes into a port the very bytes that
``foreign@T:N`` under seed S puts on air (``foreign_bytes``).
"""
from __future__ import annotations

import random
import re
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from firmware_model.timing import PC_BYTE_TICKS, TICK_HZ, s_to_ticks

if TYPE_CHECKING:
    from firmware_model.radio.mac import MacConfig

KINDS = ("fail", "recover", "steal", "ber", "noise", "burst", "foreign", "drop", "skew",
         "busoff", "stuck", "silent", "stall", "noisy")
AIR_KINDS = ("fail", "recover", "ber", "noise", "burst", "foreign", "drop")
CAN_KINDS = ("busoff", "stuck", "silent", "stall", "noisy")
NODES = ("JOINT1", "JOINT2", "JOINT3", "JOINT4", "WHEEL", "PAW")
FOREIGN_MAX = 65_536
"""Most bytes one ``foreign`` fault sends (68 s of air at 9600 baud)."""


class FaultError(ValueError):
    """A fault spec that does not parse or cannot apply; one line."""


@dataclass(frozen=True)
class Fault:
    """One fault: ``kind`` on ``robot`` (None for the air) from ``at`` to ``until`` seconds;
    ``data``: the exact bytes of a ``foreign`` fault (else ``value`` is its byte count)."""

    kind: str
    robot: int | None = None
    at: float = 0.0
    until: float | None = None
    value: float | None = None
    node: str | None = None
    data: bytes | None = None

    @property
    def end(self) -> float:
        """When the fault stops acting (s): a burst's and a foreign transmitter's when their
        bytes leave the air; other instantaneous faults when they happen."""
        if self.kind == "burst" and self.value is not None:
            return self.at + self.value
        if self.kind == "foreign":
            n = len(self.data) if self.data is not None else int(self.value or 0)
            return self.at + n * PC_BYTE_TICKS / TICK_HZ
        return self.until if self.until is not None else self.at

    def spec(self) -> str:
        """The spec text this fault parses back from."""
        def num(x: float) -> str:
            return f"{x:.10f}".rstrip("0").rstrip(".")
        target = "" if self.robot is None else f":{self.robot}" + (
            f".{self.node}" if self.node else "")
        if self.kind == "skew":
            assert self.value is not None      # (a skew is its fraction)
            return f"skew{target}:{num(self.value)}"
        when = f"@{num(self.at)}" + (f"-{num(self.until)}" if self.until is not None else "")
        val = f":x{self.data.hex()}" if self.data is not None else \
            f":{num(self.value)}" if self.value is not None else ""
        return f"{self.kind}{target}{when}{val}"


_NUM = r"[0-9]+(?:\.[0-9]*)?"
_SPEC = re.compile(rf"^(?P<kind>[a-z]+)(?::(?P<robot>-?[0-9]+)(?:\.(?P<node>[A-Z0-9]+))?)?"
                   rf"(?:@(?P<at>{_NUM})(?:-(?P<until>{_NUM}))?)?"
                   rf"(?::(?:x(?P<hex>\S*)|(?P<value>-?{_NUM})))?$")


def parse_fault(text: str) -> Fault:
    """Parse one ``KIND[:TARGET]@WHEN[:VALUE]`` spec (see the module docstring)."""
    m = _SPEC.match(text.strip())
    if not m:
        raise FaultError(f"{text!r} is not a fault spec like fail:1@5, ber@10-20:0.01, "
                         f"burst@12:0.05, foreign@3:x0f0a05, stuck:2@3-6 or "
                         f"silent:1.JOINT2@4-8")
    kind = m["kind"]
    if kind not in KINDS:
        raise FaultError(f"unknown fault kind {kind!r}; one of {', '.join(KINDS)}")
    if m["hex"] is not None and kind != "foreign":
        raise FaultError(f"{kind} takes no bytes (only foreign@T:xHEX does)")
    robot = int(m["robot"]) if m["robot"] is not None else None
    if robot is not None and (not 0 <= robot <= 6 or m["robot"] != str(robot)):
        raise FaultError(f"{text!r}: robot {m['robot']} is no robot ID (0 the father, 1-6 "
                         f"the children)")
    node = m["node"]
    at = float(m["at"]) if m["at"] is not None else None
    until = float(m["until"]) if m["until"] is not None else None
    value = float(m["value"]) if m["value"] is not None else None
    if any(x == float("inf") for x in (at, until, value)):
        raise FaultError(f"{text!r}: a number too large to be finite (times are seconds, "
                         f"each mapped to a whole tick)")
    needs_robot = kind in ("fail", "recover", "steal", "skew", "busoff", "stuck", "silent",
                           "stall", "noisy")
    if needs_robot and robot is None:
        raise FaultError(f"{kind} needs a robot: {kind}:ID@...")
    if not needs_robot and robot is not None:
        raise FaultError(f"{kind} acts on the air, not on one robot: {kind}@...")
    if kind == "noisy":
        if node not in NODES + ("MCU",):
            raise FaultError(f"noisy needs a node on the CAN bus: noisy:ROBOT.NODE@T1-T2, "
                             f"NODE one of {', '.join(NODES + ('MCU',))}")
    elif kind in ("silent", "stall"):
        if node not in NODES:
            raise FaultError(f"{kind} needs a submodule: {kind}:ROBOT.NODE@..., NODE one of "
                             f"{', '.join(NODES)}")
        if kind == "stall" and node == "PAW":
            raise FaultError("the paw cannot stall; stall a joint or the wheel")
    elif node is not None:
        raise FaultError(f"{kind} takes no submodule")
    if kind in CAN_KINDS and robot == 0:
        raise FaultError(f"{kind} needs a child (1-6): the father has no CAN bus")
    if kind == "skew":
        if at is not None or value is None:
            raise FaultError("skew is for the whole run: skew:ID:FRACTION, e.g. skew:2:0.02")
        return Fault(kind, robot, 0.0, None, check_skew(value))
    if at is None:
        raise FaultError(f"{kind} needs a time: {kind}...@SECONDS")
    ranged = kind in ("ber", "noise", "drop", "stuck", "silent", "noisy")
    if ranged and until is None:
        raise FaultError(f"{kind} needs a window: @START-END")
    if not ranged and until is not None and kind != "stall":
        raise FaultError(f"{kind} happens at one instant: @SECONDS")
    if until is not None and until <= at:
        raise FaultError(f"the window {at:g}-{until:g} is empty")
    if kind in ("ber", "drop"):
        if value is None or not 0.0 < value < 1.0:
            raise FaultError(f"{kind} needs a probability in (0, 1): {kind}@T1-T2:P")
    elif kind == "burst":
        if value is None or not 0.0 < value <= 10.0:
            raise FaultError("burst needs a duration in seconds (0-10]: burst@T:SECONDS")
    elif kind == "foreign":
        return foreign_fault(at, value, m["hex"])
    elif value is not None:
        raise FaultError(f"{kind} takes no value")
    return Fault(kind, robot, at, until, value, node)


SKEW_MAX = 0.2
"""A ``skew`` is below this fraction."""


def check_skew(value: float) -> float:
    """``value`` if it is a skew the model takes (0 <= E < SKEW_MAX: the clock that much
    slow), else FaultError. A clock that runs fast is refused, not modelled."""
    if value < 0:
        raise FaultError(f"skew {value:g}: a clock that runs fast (E < 0) is not modelled; "
                         f"E is how much slower the robot's clock runs, 0 <= E < {SKEW_MAX:g}")
    if not value < SKEW_MAX:
        raise FaultError(f"skew {value:g} is not a small fraction: 0 <= E < {SKEW_MAX:g}")
    return value


def skewed_mac(cfg: MacConfig, eps: float) -> MacConfig:
    """A robot whose clock runs ``eps`` slow (``skew:R:E``, 0 <= E < 0.2): every interval it
    times is that much longer in true ticks (rounded up to the reload timer's even ticks)."""
    def k(t: int) -> int:
        v = round(t * (1 + eps))
        return v + (v & 1)
    return replace(cfg, ttrans=k(cfg.ttrans), tmax=k(cfg.tmax), twin=k(cfg.twin),
                   tslot=k(cfg.tslot), quiet_gap=k(cfg.quiet_gap))


def foreign_fault(at: float, count: float | None = None, hexdata: str | None = None) -> Fault:
    """A ``foreign`` fault at ``at`` seconds: ``count`` random bytes, or exactly the bytes
    written in ``hexdata``; FaultError (one line) if that is not 1 to FOREIGN_MAX bytes."""
    if (count is None) == (hexdata is None):
        raise FaultError("foreign needs a byte count or the bytes: foreign@T:N or "
                         "foreign@T:xHEX, e.g. foreign@2:14 or foreign@2:x0f0a05")
    if not (0 <= at < float("inf")):
        raise FaultError(f"foreign needs a finite time in seconds >= 0, got {at!r}")
    if hexdata is not None:
        if not hexdata or len(hexdata) % 2 or any(c not in "0123456789abcdefABCDEF"
                                                  for c in hexdata):
            raise FaultError(f"foreign bytes must be pairs of hex digits, e.g. 0f0a05 "
                             f"(foreign@T:x0f0a05), got {hexdata!r}")
        data = bytes.fromhex(hexdata)
        if len(data) > FOREIGN_MAX:
            raise FaultError(f"foreign sends at most {FOREIGN_MAX} bytes, got {len(data)}")
        return Fault("foreign", None, at, data=data)
    assert count is not None                   # (one of the two, checked above)
    if count != int(count) or not 1 <= count <= FOREIGN_MAX:
        raise FaultError(f"foreign needs a whole number of bytes, 1-{FOREIGN_MAX}: "
                         f"foreign@T:N, got {count:.15g}")
    return Fault("foreign", None, at, None, float(count))


def foreign_bytes(fault: Fault, seed: int) -> bytes:
    """What a ``foreign`` fault transmits: its exact bytes, or its N bytes drawn from a stream
    seeded by ``seed`` and the fault's spec (same seed and spec, same bytes: in the simulator,
    on the radio hub and from ``rprs inject``)."""
    if fault.data is not None:
        return fault.data
    assert fault.value is not None             # (a foreign fault is its bytes or its count)
    return random.Random(f"{seed}:{fault.spec()}").randbytes(int(fault.value))


def apply_air_fault(air, radio_of, fault: Fault, phase: str, base_ber: float = 0.0,
                    base_noise: bool = False,
                    foreign_byte_ticks: int = PC_BYTE_TICKS) -> None:
    """Start (``phase='start'``) or end (``'end'``) an air fault on ``air``; ``radio_of(id)``
    finds a robot's radio. ``foreign_byte_ticks``: the byte time of a ``foreign``
    transmitter (ticks; default 9600 8N1, the radio hub gives its own ``--baud``'s)."""
    now = air.sched.now
    k = fault.kind
    if k == "fail":
        air.kill(radio_of(fault.robot), now)
    elif k == "recover":
        air.revive(radio_of(fault.robot), now)
    elif k == "ber":
        air.set_ber(fault.value if phase == "start" else base_ber)
    elif k == "drop":
        air.set_drop(fault.value if phase == "start" else 0.0)
    elif k == "noise":
        air.set_noise(True if phase == "start" else base_noise)
    elif k == "burst":
        air.burst(fault.value)
    elif k == "foreign":
        air.inject(foreign_bytes(fault, air.seed), foreign_byte_ticks)
    else:
        raise FaultError(f"{k} is not an air fault")


def schedule(sched, fault: Fault, start, end=None) -> None:
    """Call ``start(fault)`` at its time and ``end(fault)`` when its window closes."""
    sched.at(max(s_to_ticks(fault.at), sched.now), start, fault)
    if fault.until is not None and end is not None:
        sched.at(s_to_ticks(fault.until), end, fault)

"""The faults of a simulated world (hil/sim/faults.py's kinds): each one's start and end as
the world's parts see it, and ``inject`` for tests. Plain functions bound as methods of
:class:`hil.sim.world.World`."""
from __future__ import annotations

from typing import TYPE_CHECKING

from firmware_model.timing import TICK_HZ

from .config import ConfigError
from .events import FaultEdge
from .faults import AIR_KINDS, KINDS, Fault, apply_air_fault

if TYPE_CHECKING:
    from .world import World


def _fault(self: World, f: Fault) -> None:
    self.fault_count[f.kind] = self.fault_count.get(f.kind, 0) + 1
    if self.listeners:
        self._emit(FaultEdge(t=self.sched.now, robot=f.robot, kind=f.kind, phase="start",
                             spec=f.spec() if f.kind not in ("fail", "recover", "steal")
                             else None))
    self._fault_act(f, "start")

def _fault_end(self: World, f: Fault) -> None:
    if self.listeners:
        self._emit(FaultEdge(t=self.sched.now, robot=f.robot, kind=f.kind, phase="end"))
    self._fault_act(f, "end")

def _fault_act(self: World, f: Fault, phase: str) -> None:
    k = f.kind
    q = self.quiet.get(f.robot) if f.robot is not None else None
    if q is not None:
        q.wake(work=True)
        q.touched()
    if k in AIR_KINDS:
        apply_air_fault(self.air, self.radios.__getitem__, f, phase, self.cfg.ber,
                        self.cfg.noise)
        return
    r = f.robot
    assert r is not None               # every other kind names a robot (hil/sim/faults.py)
    if k == "steal":
        self.stations[r].force_turn()
    elif k == "busoff":
        child = self.children[r]
        self.can_buses[r].inject_bit_error(child.can.xcvr, count=32)
    elif k == "stuck":
        self.children[r].can.xcvr.stick_txd(phase == "start")
    elif k == "silent":
        self.submodules[r][f.node].silent(phase == "start")
    elif k == "stall":
        node = self.submodules[r][f.node]
        node.stall() if phase == "start" else node.clear_fault()
    elif k == "noisy":
        target = self.children[r].can.xcvr if f.node == "MCU" else \
            self.submodules[r][f.node]
        self.can_buses[r].disturb(target, phase == "start")

def inject(self: World, kind: str, robot: int | None, at_tick: int, until_tick: int | None = None,
           value: float | None = None, node: str | None = None) -> None:
    """Schedule a fault at a tick (tests): any kind of hil.sim.faults."""
    if kind not in KINDS or kind == "skew":
        raise ConfigError(f"unknown fault {kind!r}; one of {', '.join(KINDS)}")
    f = Fault(kind, robot, at_tick / TICK_HZ,
              until_tick / TICK_HZ if until_tick is not None else None, value, node)
    self.sched.at(at_tick, self._fault, f)
    if until_tick is not None:
        self.sched.at(until_tick, self._fault_end, f)

def inject_bytes(self: World, data: bytes, at_tick: int) -> None:
    """Put raw bytes on air at a tick from a transmitter that is no robot (forged frames,
    out-of-turn or spoofed Sources, over-long Lengths)."""
    self.sched.at(at_tick, self.air.inject, data)

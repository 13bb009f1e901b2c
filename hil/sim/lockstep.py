"""A search for lock-step: a foreign transmitter's burst at every byte offset of a cycle.

No MAC rule may let two members transmit at the same instant after the same observation
(docs/mac.md, rule R-stagger). For a formed idle ring, this puts a burst of random bytes from
a radio that is no robot on the air at each byte offset across one whole cycle, for each
burst length asked, and checks what follows the burst:

* nobody is dropped (no ``disable``);
* no collision between robots starts after the burst has ended;
* a good frame starts within ``Tmax`` plus one idle cycle of the burst's end.

Each case runs on a copy of one formed world (pickled once, unpickled per case: three times
faster than ``copy.deepcopy``, and the same run as the original world:
``test_a_pickled_world_runs_as_the_original``), so a case costs about two simulated seconds.
``python scripts/lockstep_search.py`` runs the full search (every length
from 1 to 600 bytes); the test suite runs a sample of lengths at every offset.
"""
from __future__ import annotations

import pickle
import random
from dataclasses import dataclass

from firmware_model.timing import CHILD_BYTE_TICKS, PC_BYTE_TICKS, TMAX_TICKS, TTRANS_TICKS, \
    s_to_ticks
from hil.sim.air import FOREIGN_BYTE_TICKS
from hil.sim.events import Collision, Disable, FrameOnAir, TraceEvent
from hil.sim.world import SimConfig, World

__all__ = ["FOREIGN_BYTE_TICKS", "Case", "Verdict", "formed_world", "idle_cycle_ticks",
           "run_case", "search"]

PICKLE = pickle.HIGHEST_PROTOCOL


@dataclass(frozen=True)
class Case:
    """One burst: ``length`` bytes starting ``offset`` byte times after a cycle began."""

    robots: tuple[int, ...]
    offset: int
    length: int
    seed: int


@dataclass(frozen=True)
class Verdict:
    case: Case
    collisions_after: int
    dropped: tuple[int, ...]
    resume_ticks: int | None
    """Ticks from the burst's end to the start of the next good (uncollided) frame."""
    bound_ticks: int

    @property
    def ok(self) -> bool:
        return not self.collisions_after and not self.dropped and \
            self.resume_ticks is not None and self.resume_ticks <= self.bound_ticks


def idle_cycle_ticks(robots: tuple[int, ...]) -> int:
    """One idle cycle of this ring: each member's heartbeat (14 bytes) plus Ttrans."""
    return sum(14 * (PC_BYTE_TICKS if r == 0 else CHILD_BYTE_TICKS) + TTRANS_TICKS
               for r in robots)


def formed_world(robots: tuple[int, ...], seed: int = 0) -> World:
    """An idle ring of ``robots``, run until every member has every other in its ring."""
    events: list[TraceEvent] = []
    w = World(SimConfig(robots=robots, duration=3600.0, seed=seed), listeners=[events.append])
    limit = s_to_ticks(30.0)

    def formed() -> bool:
        return all(v == robots for v in w.ring_views().values()) and w.ring_complete()
    while not formed() and w.now < limit:
        w.run(w.now + s_to_ticks(0.5))
    if not formed():
        raise RuntimeError(f"ring {robots} did not form in 30 s: {w.ring_views()}")
    w.run(w.now + s_to_ticks(1.0))
    return w


def run_case(base: World | bytes, case: Case) -> Verdict:
    """One burst on a copy of ``base`` (a formed world, or its pickle)."""
    w = pickle.loads(base if isinstance(base, bytes) else pickle.dumps(base, PICKLE))
    evs = w.listeners[0].__self__                  # the copy's own event list
    evs.clear()
    t0 = w.now + case.offset * FOREIGN_BYTE_TICKS
    data = random.Random(f"{case.seed}:{case.offset}:{case.length}").randbytes(case.length)
    w.inject_bytes(data, t0)
    t_end = t0 + case.length * FOREIGN_BYTE_TICKS
    bound = TMAX_TICKS + idle_cycle_ticks(case.robots)
    w.run(t_end + bound + 2 * idle_cycle_ticks(case.robots) + TMAX_TICKS)
    cols = [e for e in evs if type(e) is Collision and e.t > t_end and -1 not in e.robots]
    dropped = tuple(sorted({e.robot for e in evs if type(e) is Disable}))
    good = [e.start for e in evs if type(e) is FrameOnAir and e.start >= t_end and
            not e.collided]
    return Verdict(case, len(cols), dropped, (good[0] - t_end) if good else None, bound)


def search(robots: tuple[int, ...], lengths, seed: int = 0) -> list[Verdict]:
    """Every byte offset across one idle cycle, for each burst length in ``lengths``."""
    base = pickle.dumps(formed_world(robots, seed), PICKLE)
    offsets = range(idle_cycle_ticks(robots) // FOREIGN_BYTE_TICKS + 1)
    return [run_case(base, Case(robots, off, n, seed)) for n in lengths for off in offsets]

"""The lock-step search (hil/sim/lockstep.py): a foreign burst at every byte offset across a whole
idle cycle, for ring sizes 2 to 7 with and without the father. The suite samples burst
lengths; ``python scripts/lockstep_search.py`` runs every length from 1 to 600 bytes."""
from __future__ import annotations

import pytest

from hil.sim.lockstep import FOREIGN_BYTE_TICKS, idle_cycle_ticks, search

RINGS = [tuple(range(1, n + 1)) for n in range(2, 7)] + \
        [tuple(range(0, n)) for n in range(2, 8)]
LENGTHS = (1, 3, 14, 150, 600)
"""Rings of 2 and 3 robots take every length here; larger rings (slower to simulate) take
the heartbeat-long burst and the jam longer than Tmax."""
LARGE_RING_LENGTHS = (14, 600)


FAST_RINGS = {(1, 2), (0, 1)}
"""The rings of two the fast tier searches (a few seconds each); the larger rings, up to half
a minute each, are the slow tier (``pytest -m slow``)."""


@pytest.mark.parametrize("robots", [r if r in FAST_RINGS else
                                    pytest.param(r, marks=pytest.mark.slow) for r in RINGS],
                         ids=lambda r: ",".join(map(str, r)))
def test_no_lock_step_after_a_foreign_burst_at_any_offset(robots):
    lengths = LENGTHS if len(robots) <= 3 else LARGE_RING_LENGTHS
    verdicts = search(robots, lengths)
    # every byte offset of a whole idle cycle, for every length
    offsets = {v.case.offset for v in verdicts}
    assert offsets == set(range(max(offsets) + 1))
    assert (max(offsets) + 1) * FOREIGN_BYTE_TICKS > idle_cycle_ticks(robots)
    assert len(verdicts) == len(offsets) * len(lengths)
    bad = [v for v in verdicts if not v.ok]
    assert not bad, bad[:5]


def test_a_pickled_world_runs_as_the_original():
    """The search runs each case on an unpickled copy: it must behave as the world it copies
    (a MAC comparing phases with ``is`` once made unpickled copies collide where the
    original did not)."""
    import pickle
    import random

    from firmware_model.timing import TMAX_TICKS
    from hil.sim.lockstep import formed_world

    def collisions(w):
        evs = w.listeners[0].__self__             # the copy's own event list (typed)
        evs.clear()
        t0 = w.now + 4 * FOREIGN_BYTE_TICKS
        w.inject_bytes(random.Random(4).randbytes(1), t0)
        w.run(t0 + 3 * TMAX_TICKS)
        return [(e.KIND, e.t) for e in evs if e.KIND in ("collision", "frame")]

    base = formed_world((1, 2))
    copy_ = pickle.loads(pickle.dumps(base, pickle.HIGHEST_PROTOCOL))
    assert collisions(copy_) == collisions(base)

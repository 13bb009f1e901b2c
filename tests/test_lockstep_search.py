"""The lock-step search (hil/lockstep.py): a foreign burst at every byte offset across a whole
idle cycle, for ring sizes 2 to 7 with and without the father. The suite samples burst
lengths; ``python scripts/lockstep_search.py`` runs every length from 1 to 600 bytes."""
from __future__ import annotations

import pytest

from hil.lockstep import FOREIGN_BYTE_TICKS, idle_cycle_ticks, search

RINGS = [tuple(range(1, n + 1)) for n in range(2, 7)] + \
        [tuple(range(0, n)) for n in range(2, 8)]
LENGTHS = (1, 3, 14, 150, 600)


@pytest.mark.parametrize("robots", RINGS, ids=lambda r: ",".join(map(str, r)))
def test_no_lock_step_after_a_foreign_burst_at_any_offset(robots):
    verdicts = search(robots, LENGTHS)
    # every byte offset of a whole idle cycle, for every length
    offsets = {v.case.offset for v in verdicts}
    assert offsets == set(range(max(offsets) + 1))
    assert (max(offsets) + 1) * FOREIGN_BYTE_TICKS > idle_cycle_ticks(robots)
    assert len(verdicts) == len(offsets) * len(LENGTHS)
    bad = [v for v in verdicts if not v.ok]
    assert not bad, bad[:5]

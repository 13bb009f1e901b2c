"""Seeded traces stay byte-identical (issue 14: every speed-up keeps them): each run of
tests/trace_digests.py against the digest recorded in tests/data/trace_digests.txt."""
from __future__ import annotations

import pytest

from trace_digests import RUNS, digest, read_recorded


@pytest.mark.parametrize("name", list(RUNS))
def test_a_seeded_trace_is_the_recorded_one(name):
    recorded = read_recorded()
    assert name in recorded, \
        f"no digest recorded for {name!r}: python scripts/trace_digest.py --write"
    assert digest(RUNS[name]) == recorded[name], (
        f"the trace of {name!r} ({RUNS[name]}) changed. A change meant to keep behaviour must "
        f"not; if this one changes it on purpose, record the digests again "
        f"(python scripts/trace_digest.py --write) and say why in the commit")


@pytest.mark.parametrize("name", list(RUNS))
def test_a_seeded_trace_is_the_same_with_every_fast_path_off(name):
    """``--every-frame`` (SimConfig.fast_paths=False): no ring leaps, no sleeping CAN side, no
    heartbeat short path in any MAC; the trace is the recorded one to the byte."""
    assert digest(RUNS[name] + " --every-frame") == read_recorded()[name], (
        f"the trace of {name!r} differs with the fast paths off: one of them changes behaviour")

"""The cyclic garbage collector's threshold while the simulator runs (hil/sim/collector.py)."""
from __future__ import annotations

import gc

import pytest

from firmware_model.timing import s_to_ticks
from hil.sim.collector import YOUNG_THRESHOLD, fewer_collections
from hil.sim.world import SimConfig, World


@pytest.fixture
def threshold():
    """Run with CPython's default thresholds and put back whatever was set before."""
    before = gc.get_threshold()
    gc.set_threshold(700, 10, 10)
    yield
    gc.set_threshold(*before)


def test_the_young_threshold_is_raised_inside_and_restored_after(threshold) -> None:
    with fewer_collections():
        assert gc.get_threshold() == (YOUNG_THRESHOLD, 10, 10)
    assert gc.get_threshold() == (700, 10, 10)


def test_it_is_restored_when_the_block_raises(threshold) -> None:
    with pytest.raises(RuntimeError):
        with fewer_collections():
            raise RuntimeError("a run that failed")
    assert gc.get_threshold() == (700, 10, 10)


def test_a_rarer_threshold_or_a_collector_set_to_never_run_is_left_alone(threshold) -> None:
    gc.set_threshold(50_000, 5, 5)
    with fewer_collections():
        assert gc.get_threshold() == (50_000, 5, 5)
    gc.set_threshold(0, 10, 10)
    with fewer_collections():
        assert gc.get_threshold() == (0, 10, 10)
    assert gc.get_threshold() == (0, 10, 10)


def test_a_world_runs_with_the_raised_threshold_and_puts_the_old_one_back(threshold) -> None:
    w = World(SimConfig(robots=(0, 1, 2), duration=2.0, seed=3))
    seen: list[tuple[int, int, int]] = []
    w.sched.at(s_to_ticks(1.0), lambda: seen.append(gc.get_threshold()))
    w.run()
    assert seen == [(YOUNG_THRESHOLD, 10, 10)]
    assert gc.get_threshold() == (700, 10, 10)

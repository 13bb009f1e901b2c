"""benchmarks/soak_breakdown.py: the soak's time by what ran it, and its jobs' lengths."""
from __future__ import annotations

import importlib.util

from firmware_model.dispatcher import Dispatcher
from firmware_model.mcu.scheduler import Scheduler
from hil.sim.quiet_can import QuietCan
from hil.sim.soak import MIN_HOURS, run_soak
from paths import ROOT

_spec = importlib.util.spec_from_file_location("soak_breakdown",
                                               ROOT / "benchmarks" / "soak_breakdown.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)


def test_the_breakdown_charges_the_soak_and_changes_nothing_of_it():
    originals = (Scheduler.run_until, QuietCan.wake, Dispatcher._drive_joints,
                 Dispatcher._job_done, Dispatcher._next_seq)
    b = bench.measure(MIN_HOURS, 11)
    # the instruments are gone afterwards
    assert (Scheduler.run_until, QuietCan.wake, Dispatcher._drive_joints,
            Dispatcher._job_done, Dispatcher._next_seq) == originals
    # the same run as without them: accounting and invariants
    plain = run_soak(MIN_HOURS, 11)
    assert b.result.summary == plain.summary and b.result.invariants == plain.invariants
    # the soak's traffic is orders that move joints: radio, jobs and probes all ran
    for cat in ("radio and world", "CAN, job and a moving node", "probes"):
        assert b.seconds[cat] > 0 and b.events[cat] > 0, cat
    assert set(b.seconds) <= set(bench.CATEGORIES)
    assert 0 < sum(b.seconds.values()) <= b.total_s
    assert 0 < b.wake_s < b.seconds["radio and world"] and b.wakes > 0
    assert b.jobs and min(b.jobs) >= 0 and b.superseded and min(b.superseded) >= 0
    # a job lasts no longer than the soak
    assert max(b.jobs + b.superseded) * 0.1 <= MIN_HOURS * 3600
    text = bench.report(b, MIN_HOURS, 11)
    assert f"joint jobs done: {len(b.jobs):,}" in text and "| probes |" in text

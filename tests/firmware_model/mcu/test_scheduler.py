"""The tick kernel (firmware_model/mcu/scheduler.py): what the firmware and the bench schedule
on, and nothing the simulator's fast paths alone need (hil/sim/domains.py has that)."""
from __future__ import annotations

from firmware_model.mcu.scheduler import Scheduler
from hil.sim.domains import SimScheduler

DOMAIN_API = {"at_first", "pending", "take", "put_back", "skip_to"}


def test_the_kernel_has_no_domain_api_and_the_simulators_scheduler_adds_it():
    assert not DOMAIN_API & set(vars(Scheduler)), "the domain API belongs to hil/sim/domains.py"
    assert DOMAIN_API <= set(vars(SimScheduler))


def test_same_tick_events_run_in_order_and_steps_first():
    s = Scheduler()
    out: list[str] = []
    s.at(10, out.append, "a")
    s.at(10, out.append, "b")
    s.at_top(10, out.append, "step")
    s.after(5, out.append, "early")
    s.run_until(20)
    assert out == ["early", "step", "a", "b"] and s.now == 20

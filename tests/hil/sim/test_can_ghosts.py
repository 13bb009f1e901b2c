"""A sleeping CAN side on the CPU model raises its interrupts as ghosts (hil/sim/can_ghosts.py):
the run is the one whose CAN sides never sleep, to the tick and to every handler's figure."""
from __future__ import annotations

from dataclasses import replace

import pytest

from firmware_model.cycle_costs import DEFAULT_COSTS
from firmware_model.mcu.cpu import Cpu
from hil.sim import can_ghosts
from hil.sim.config import SimConfig
from hil.sim.world import World
from hunt import sleep_hunt

HUNT = sleep_hunt()


def _same(cfg: SimConfig, cuts=()) -> tuple[World, World]:
    """The world whose CAN sides sleep and the one whose never do, both run (cut alike)."""
    slow = World(replace(cfg, can_sleep=False))
    fast = World(cfg)
    for w in (slow, fast):
        for tick in cuts:
            w.run(tick)
        w.run()
    assert HUNT.summary(fast) == HUNT.summary(slow)
    assert HUNT.cpu_figures(fast) == HUNT.cpu_figures(slow)
    assert HUNT.cpu_state(fast) == HUNT.cpu_state(slow)
    return fast, slow


IDLE = SimConfig(robots=(0, 1, 2, 3), duration=40, can=True, seed=1, cpu=DEFAULT_COSTS)


def test_an_idle_childs_can_side_sleeps_on_the_cpu_model_and_its_cpu_sees_every_interrupt():
    fast, slow = _same(IDLE, cuts=(123_456_789, 400_000_001))
    for r, q in fast.quiet.items():
        # asleep nearly all the run (it first sleeps after two periods of probing)
        assert q.periods_skipped >= 390, (r, q.periods_skipped)
        # six status frames a period, each a CAN receive interrupt: raised as ghosts
        assert q.port.ghosts_raised >= 6 * 390
    rx = {r: c.stats["CAN0 RX"].calls for r, c in fast.cpus.items()}
    assert rx == {r: 6 * 400 for r in (1, 2, 3)}
    # the radio met them on the CPU: late ghosts, their effects run at the wake
    assert sum(q.port.late for q in fast.quiet.values()) > 0
    # most met nothing: the CPU took them without an event (Cpu.defer), the rest as
    # requests
    deferred = sum(q.port.deferred for q in fast.quiet.values())
    raised = sum(q.port.ghosts_raised for q in fast.quiet.values())
    assert 0.8 * raised < deferred < raised


def test_ghosts_the_cpu_takes_without_an_event_are_the_same_run_as_ghosts_it_is_asked(
        monkeypatch):
    """``Cpu.defer`` refused, every ghost a request: the same run as with it."""
    monkeypatch.setattr(Cpu, "defer", lambda self, vector, body, owner: False)
    fast, _ = _same(IDLE, cuts=(123_456_789,))
    assert sum(q.port.deferred for q in fast.quiet.values()) == 0
    assert sum(q.port.ghosts_raised for q in fast.quiet.values()) > 0


def test_ghosts_that_meet_the_radio_wake_the_can_side_and_it_is_still_the_same_run(
        monkeypatch):
    """Every late ghost waking its CAN side (no handler's effects taken as only the latest):
    the catch-up makes each the real handler where the CPU holds it."""
    monkeypatch.setattr(can_ghosts, "LATE_OK", frozenset())
    fast, _ = _same(IDLE)
    assert sum(q.port.meetings for q in fast.quiet.values()) > 0
    assert sum(q.port.late for q in fast.quiet.values()) == 0
    assert all(q.periods_skipped > 200 for q in fast.quiet.values())


@pytest.mark.parametrize("seed", [
    4,     # cruising wheels: their reports' stuff bits move their frames' interrupts
    11,    # an order waiting for the main loop when a probe comes: it stays awake
    # a ghost and a byte heard on time request the CPU at one tick: the byte first, as a
    # real request hands the bytes due first (Air.late_around)
    pytest.param(23, marks=pytest.mark.slow),
])
def test_named_worlds_of_the_hunt_run_alike_asleep_or_not(seed):
    cfg, cuts, _ = HUNT.random_world(seed)
    assert HUNT.same_sleeping_cpu_run(cfg, cuts), (cfg, cuts)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(12, 18))
def test_random_worlds_run_alike_asleep_or_not_on_the_cpu_model(seed):
    """A few more seeds of ``scripts/sleep_hunt.py --cpu``."""
    cfg, cuts, _ = HUNT.random_world(seed)
    assert HUNT.same_sleeping_cpu_run(cfg, cuts), (cfg, cuts)


def test_an_order_waiting_for_the_main_loop_keeps_the_can_side_awake(monkeypatch):
    """A message handed to the main loop wakes the CAN side, but the dispatcher reads it only
    when its task runs: a probe between the two must not put the side back to sleep (here
    every task takes 125 ms, more than a probe's period, so a probe always comes between)."""
    import firmware_model.child as child_module
    monkeypatch.setattr(child_module, "message_cycles", lambda commands, costs: 2_000_000)
    cfg = SimConfig(robots=(0, 1, 2), duration=20, can=True, seed=3, load=0.3,
                    cpu=DEFAULT_COSTS)
    fast, _ = _same(cfg)
    assert sum(q.periods_skipped for q in fast.quiet.values()) > 0
    assert sum(c.stats["main loop"].calls for c in fast.cpus.values()) > 0


def test_news_and_orders_refused_at_once_leave_a_sleeping_side_asleep_on_the_cpu_model():
    """A done() or fail() notice, and an order refused whole, reach the main loop later than
    the radio hands them over: the CAN side sleeps on through both, and the run is the one
    whose CAN sides never sleep. An order wakes it."""
    from firmware_model.radio.content import cmd
    from firmware_model.radio.frame import FrameType
    cfg = SimConfig(robots=(0, 1, 2), duration=12, can=True, seed=6, cpu=DEFAULT_COSTS)
    sent = ((4.0, (cmd("done"), cmd("movex", 8)), FrameType.BROADCAST_INFO),
            (5.5, (cmd("movex", 123456789),), FrameType.INSTRUCTION),
            (6.5, (cmd("fail", 3), cmd("moveto", 900, 0, 0)), FrameType.FAILURE),
            (9.0, (cmd("joint", 1, 20),), FrameType.INSTRUCTION))
    worlds = []
    for sleep in (False, True):
        w = World(replace(cfg, can_sleep=sleep))
        for t, commands, type_ in sent:
            w.sched.at(round(t * 16_000_000),
                       lambda w=w, c=commands, ty=type_: w.submit(0, 1, c, int(ty)))
        worlds.append(w)
    slow, fast = worlds
    q = fast.quiet[1]
    asleep_after = []
    for until in (5.0, 7.5):
        fast._advance(round(until * 16_000_000))
        asleep_after.append(q.asleep)
        slow.run(round(until * 16_000_000))
    slow.run()
    fast.run()
    assert asleep_after == [True, True] and q.noted == 2 and q.refused == 1
    assert fast.children[1].dispatcher.target[0] == 20       # the order woke it and ran
    assert HUNT.summary(fast) == HUNT.summary(slow)
    assert HUNT.cpu_figures(fast) == HUNT.cpu_figures(slow)
    assert HUNT.cpu_state(fast) == HUNT.cpu_state(slow)


@pytest.mark.parametrize("speed", [80, -45, 3])
def test_a_cruising_wheels_status_interrupt_moves_with_its_frames_length(speed):
    """A cruising wheel's odometer changes its status frame, and with it the frame's stuff
    bits and the tick of the receive interrupt it raises: the ghost comes where the frame's
    length puts it (at 3 mm/s the odometer stays for three periods, then moves)."""
    from firmware_model.radio.content import cmd
    cfg = SimConfig(robots=(0, 1, 2), duration=20, can=True, seed=9, cpu=DEFAULT_COSTS)
    worlds = []
    for sleep in (False, True):
        w = World(replace(cfg, can_sleep=sleep))
        w.sched.at(16_000_000, lambda w=w: w.submit(0, 1, [cmd("wheel", speed)]))
        w.sched.at(9 * 16_000_000, lambda w=w: w.submit(0, 1, [cmd("status")]))
        worlds.append(w)
    slow, fast = worlds
    fast._advance(5 * 16_000_000)          # (run() would wake the CAN sides at its end)
    assert fast.submodules[1]["WHEEL"].cruising and fast.quiet[1].asleep
    for w in worlds:
        w.run()
    assert HUNT.summary(fast) == HUNT.summary(slow)
    assert HUNT.cpu_figures(fast) == HUNT.cpu_figures(slow)
    assert HUNT.cpu_state(fast) == HUNT.cpu_state(slow)
    assert fast.quiet[1].periods_skipped > 120

"""The tick kernel (firmware_model/mcu/scheduler.py): what the firmware and the bench schedule
on, and nothing the simulator's fast paths alone need (hil/sim/domains.py has that)."""
from __future__ import annotations

from firmware_model.mcu.scheduler import PlacedScheduler, Scheduler
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


# -- an event standing in for one scheduled later (Scheduler.at_later) --------------------

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_OP = st.tuples(st.sampled_from(("plain", "lone", "reserve", "settle")), st.integers(0, 6),
                st.integers(0, 4), st.integers(1, 4))
"""(kind, the tick its first event runs at, a delay, another delay): small ticks, so that
events meet at one tick."""


def _run(ops: list[tuple[str, int, int, int]], stand_in: bool,
         by_step: bool = False) -> list[tuple[int, str]]:
    """Run ``ops``, each a first event at its tick that: ``plain``, ``d1`` ticks on runs an
    event that schedules an output ``d2 - 1`` ticks further (0: at its own tick); ``lone``, a
    lone handler whose entry ends ``d1`` ticks on and schedules its body's output ``d2``
    after that, and another a tick later (``stand_in``: the body scheduled at once with
    ``at_later``, replaced by the entry's event where it is met, as the CPU model does);
    ``reserve``, takes a sequence number and ``d1`` ticks on schedules an output ``d2``
    further in its place (``at_seq``); ``settle``, ``d1`` ticks on meets every stand-in
    (``settle_later``, as a probe of the ring does). Run to tick 100, or ``by_step``, an
    event at a time. Returns the outputs in the order they ran."""
    s = PlacedScheduler()
    out: list[tuple[int, str]] = []

    def emit(label: str) -> None:
        out.append((s.now, label))

    def done(i: int, stood_in: bool = False) -> None:
        if stood_in:
            s.passed(s.now)            # (as the CPU's lone handler does)
        emit(f"body {i}")
        s.at(s.now + 1, emit, f"after {i}")

    def lone(i: int, d1: int, d2: int) -> None:
        entry, body = s.now + d1, s.now + d1 + d2

        def entered() -> None:
            s.at(body, done, i)
        if not stand_in:
            s.at(entry, entered)
            return
        held: dict = {}

        def met(seq: int, sched: PlacedScheduler) -> None:
            later = held.pop("later", None)
            if later is None or sched.reached(entry, seq):
                return
            later[2].cancel()
            sched.at_seq(entry, seq, entered)
        held["later"] = s.at_later(body, entry, done, met, i, True)

    def reserve(i: int, d1: int, d2: int) -> None:
        seq = s.reserve()
        s.at(s.now + d1, lambda: s.at_seq(s.now + d2, seq, emit, f"seq {i}"))

    for i, (kind, t, d1, d2) in enumerate(ops):
        if kind == "plain":
            s.at(t, lambda i=i, d1=d1, d2=d2: s.at(
                s.now + d1, lambda: s.at(s.now + d2 - 1, emit, f"plain {i}")))
        elif kind == "lone":
            s.at(t, lone, i, d1, d2)
        elif kind == "reserve":
            s.at(t, reserve, i, d1, d2)
        else:
            s.at(t, lambda d1=d1: s.at(s.now + d1, s.settle_later))
    if by_step:
        while s.step():
            pass
    else:
        s.run_until(100)
    return out


@settings(max_examples=1500, deadline=None)
@given(st.lists(_OP, min_size=1, max_size=12))
def test_a_stand_in_runs_where_the_event_it_stands_for_would(ops):
    """Events meeting at a tick in every order: an event scheduled with ``at_later`` (and
    replaced where it is met) runs where the one scheduled at its position would, among
    ordinary events, sequence numbers taken early and other stand-ins."""
    assert _run(ops, True) == _run(ops, False) == _run(ops, True, by_step=True)


def test_a_stand_in_met_by_an_event_scheduled_before_its_position_is_replaced():
    ops = [("lone", 0, 3, 2), ("plain", 1, 0, 5)]      # the plain output at 5, before 3
    assert _run(ops, True) == _run(ops, False) == [(5, "plain 1"), (5, "body 0"),
                                                   (6, "after 0")]
    ops = [("lone", 0, 3, 2), ("plain", 4, 0, 2)]      # scheduled after 3: after the body
    assert _run(ops, True) == [(5, "body 0"), (5, "plain 1"), (6, "after 0")]


def test_settling_the_stand_ins_meets_each_and_keeps_none():
    s = PlacedScheduler()
    out: list[str] = []
    mets: list[int] = []
    later = s.at_later(10, 4, out.append, lambda seq, sched: mets.append(seq), "body")
    s.at(2, s.settle_later)
    s.run_until(3)
    assert mets == [later[1]] and not s._later


def test_a_stand_in_replaced_by_its_entry_meets_another_due_at_that_tick():
    """Lone handler 0 (entry's end at 2, body's at 5) and 1 (at 5 and 6); an event due at 6,
    scheduled at tick 1, meets 1's stand-in, whose entry's event then comes at 5, where it
    was scheduled before 0's entry ended: so before 0's body, which meets it too (the body
    1's entry schedules comes before the event 0's body schedules)."""
    ops = [("lone", 0, 2, 3), ("lone", 1, 4, 1), ("plain", 1, 0, 6)]
    assert _run(ops, True) == _run(ops, False) == [(5, "body 0"), (6, "plain 2"),
                                                   (6, "body 1"), (6, "after 0"),
                                                   (7, "after 1")]


def test_settling_a_stand_in_whose_position_the_run_passed_at_its_tick_keeps_it():
    """Lone handler 0: entry's end at 2, body's at 4. At tick 2, after 0's entry would have
    ended, an event schedules an output at 4 (after the body, as on the general path), and
    then the stand-ins are settled: 0's stays where it is."""
    ops = [("lone", 0, 2, 2), ("plain", 1, 1, 3), ("settle", 1, 1, 1)]
    assert _run(ops, True) == _run(ops, False) == [(4, "body 0"), (4, "plain 1"),
                                                   (5, "after 0")]


def test_only_the_cpu_models_worlds_keep_places():
    """The ideal CPU's worlds schedule on the plain kernel (no look for stand-ins at each
    scheduling); the CPU model's keep places, and its private schedulers too."""
    from firmware_model.cycle_costs import DEFAULT_COSTS
    from hil.sim.world import SimConfig, World
    assert not World(SimConfig(robots=(1, 2))).sched.positions
    assert World(SimConfig(robots=(1, 2), cpu=DEFAULT_COSTS)).sched.positions


def test_a_reservation_drops_the_stand_ins_long_over():
    """A stand-in replaced by its entry's event never runs to drop its tick (``passed``):
    the first reservation after that tick drops it, so that reservations, one per late byte
    on the CPU model, do not walk ever more ticks of stand-ins over."""
    s = PlacedScheduler()
    out: list[str] = []

    def met(seq: int, sched: PlacedScheduler) -> None:
        later[2].cancel()
        sched.at_seq(4, seq, out.append, "entry")
    later = s.at_later(10, 4, out.append, met, "body")
    s.at(1, lambda: s.at(10, out.append, "plain"))     # due at 10, before the position 4
    s.run_until(12)
    assert out == ["entry", "plain"] and 10 in s._later
    seq = s.reserve()
    assert seq > later[1] and not s._later

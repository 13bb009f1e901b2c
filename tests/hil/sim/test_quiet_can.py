"""A child's CAN side sleeps while it only repeats itself (hil/sim/quiet_can.py): the run is
the frame-by-frame run to the tick, and it is faster.

The reference is the same world with sleeping switched off: the summaries and the whole state
of every part (each child's CAN side, every radio station, the air) must be equal, at the end
and at every step of runs cut at awkward ticks (on a status frame's SOF, on its end of frame).
"""
from __future__ import annotations

import random
from dataclasses import replace

import pytest

from can_bus.submodules import STATUS_STAGGER_TICKS
from firmware_model.cycle_costs import DEFAULT_COSTS
from firmware_model.timing import TICK_HZ
from hil.sim.domains import SimScheduler
from firmware_model.radio.content import cmd
from firmware_model.radio.frame import FrameType
from firmware_model.radio.mac import Deliver, MacConfig
from hil.sim.faults import parse_fault
from hil.sim.quiet_can import PERIOD, notes_only, refuses_only
from hil.sim.state_walk import (Unwalkable, advance, latest_moved, on_orbit, period_delta,
                                period_steps, snapshot)
from hil.sim.world import SimConfig, World
from hunt import sleep_hunt


# -- the scheduler's domain events -----------------------------------------------------------

def test_domain_events_run_first_at_their_tick_and_in_order_among_themselves():
    s = SimScheduler()
    out: list[str] = []
    owner = object()
    s.at(10, out.append, "world a")
    s.at_first(owner, 10, out.append, "domain 1")
    s.at(10, out.append, "world b")
    s.at_first(owner, 10, out.append, "domain 2")
    s.at_first(owner, 9, out.append, "domain early")
    s.run_until(10)
    assert out == ["domain early", "domain 1", "domain 2", "world a", "world b"]


def test_take_and_put_back_keep_the_order_and_work_while_running():
    s = SimScheduler()
    owner = object()
    out: list[str] = []
    for name in "abc":
        s.at_first(owner, 50, out.append, name)
    s.at(50, out.append, "world")
    taken: list = []
    # an event that takes the domain's events out and puts them back later, from inside
    # run_until (which holds the heap list)
    s.at(20, lambda: taken.extend(s.take(owner)))
    s.at(30, lambda: s.put_back(taken))
    s.run_until(100)
    assert out == ["a", "b", "c", "world"]
    assert s.pending(owner) == [] and s.take(owner) == []


def test_steps_run_before_domain_events_and_keep_their_rank_when_put_back():
    """``at_top`` (a wheel's 1 ms step): first at its tick, before the domains' events and the
    world's, whenever each was scheduled; taking a domain out and putting it back keeps it so."""
    s = SimScheduler()
    owner = object()
    out: list[str] = []
    s.at_first(owner, 50, out.append, "domain")
    s.at(50, out.append, "world")
    s.at_top(50, out.append, "step", owner=owner)
    s.at_first(owner, 50, out.append, "domain 2")
    taken: list = []
    s.at(20, lambda: taken.extend(s.take(owner)))
    s.at(25, lambda: s.at_first(owner, 50, out.append, "domain, while taken"))
    s.at(30, lambda: s.put_back(taken))
    s.run_until(100)
    assert out == ["step", "domain, while taken", "domain", "domain 2", "world"]
    with pytest.raises(ValueError):
        s.at_top(99, out.append, "the past")


class _Domain:
    def __init__(self, order: int) -> None:
        self.order = order


def test_two_domains_at_one_tick_run_in_their_owners_order_however_they_were_scheduled():
    """Child 2's CAN side woke before child 1's (a listener added mid-run wakes them all) and
    put its events back first: two status frames ending at one tick were traced bus 2 first,
    where ``--every-frame`` traced bus 1 first. Domains at a tick go by their ``order``."""
    s = SimScheduler()
    one, two = _Domain(1), _Domain(2)
    out: list[str] = []
    s.at_first(two, 50, out.append, "2a")
    s.at(50, out.append, "world")
    s.at_first(one, 50, out.append, "1a")
    s.at_first(two, 50, out.append, "2b")
    s.at_first(one, 50, out.append, "1b")
    taken: list = []
    s.at(20, lambda: taken.extend(s.take(one) + s.take(two)))
    s.at(30, lambda: s.put_back(taken[2:]))            # child 2's first, then child 1's
    s.at(31, lambda: s.put_back(taken[:2]))
    s.run_until(100)
    assert out == ["1a", "1b", "2a", "2b", "world"]


def test_a_listener_added_mid_run_hears_what_every_frame_run_would():
    """The attack's case: ring 1, 2 with CAN sides under load, untraced to 7.3 s (the sides
    sleep), then a listener: the same events in the same order as with the fast paths off."""
    from hil.sim.events import RecordListener

    def run(fast: bool) -> tuple[list, dict]:
        ev: list = []
        w = World(SimConfig(robots=(1, 2), duration=8.0, seed=1, can=True, load=1.0,
                            fast_paths=fast))
        w.run(int(7.3 * TICK_HZ) + 1)
        w.add_listener(RecordListener(ev.append))
        w.run()
        return ev, w.summary()

    fast, slow = run(True), run(False)
    can = [(e["t"], e["bus"]) for e in fast[0] if e["ev"] == "can"]
    assert len({t for t, _ in can}) < len(set(can))     # two buses' frames end at one tick
    assert fast == slow


def test_put_back_refuses_the_past():
    s = SimScheduler()
    owner = object()
    ev = s.at_first(owner, 5, lambda: None)
    s.take(owner)
    s.run_until(10)
    with pytest.raises(ValueError, match="tick 5"):
        s.put_back([ev])


# -- snapshots -------------------------------------------------------------------------------

class _Part:          # a class of this project's package (hil), as the walker requires
    pass


_Part.__module__ = "hil.tests_quiet_can"


def _part(when: int, sent: int, level: int) -> _Part:
    p = _Part()
    p.when, p.sent, p.level, p.queue = when, sent, level, [("id", 3)]
    return p


def test_period_delta_tells_ticks_counters_and_change_apart():
    a, b = _part(100, 4, 7), _part(100 + PERIOD, 10, 7)
    moved = period_delta(snapshot([a]), snapshot([b]), PERIOD, frozenset({"sent"}))
    assert sorted((k, d) for _, k, d in moved) == [("sent", 6), ("when", PERIOD)]
    advance(moved, 3)
    assert (b.when, b.sent, b.level) == (100 + 4 * PERIOD, 28, 7)
    # a level that changed, a tick moved by something else, a counter not named: not periodic
    for c in (_part(100 + PERIOD, 10, 8), _part(101 + PERIOD, 10, 7)):
        assert period_delta(snapshot([a]), snapshot([c]), PERIOD, frozenset({"sent"})) is None
    assert period_delta(snapshot([a]), snapshot([b]), PERIOD, frozenset()) is None


def test_a_record_is_taken_by_its_length_and_still_must_not_grow():
    """A loaded child's dispatcher log grows all run long: walking it would make every probe
    of a 24-hour run slower than the last."""
    a, b = _part(100, 4, 7), _part(100 + PERIOD, 10, 7)
    a.log = [(t, "refused movex") for t in range(5000)]
    b.log = list(a.log)
    records = frozenset({"log"})
    sa, sb = snapshot([a], records=records), snapshot([b], records=records)
    assert len(sa.shape) < 20
    assert period_delta(sa, sb, PERIOD, frozenset({"sent"})) is not None
    b.log.append((5000, "refused movex"))
    assert period_delta(sa, snapshot([b], records=records), PERIOD,
                        frozenset({"sent"})) is None


def test_back_on_its_orbit_after_a_wake_a_part_may_sleep_at_once():
    """A part fell asleep on ``orbit`` (a period moves ``when`` by PERIOD and ``sent`` by 6);
    something woke it and left a grown log and more sent frames: k periods later it is the
    orbit moved on, as far as its future goes. Anything else is not."""
    records, counters = frozenset({"log"}), frozenset({"sent"})
    a, b = _part(100, 4, 7), _part(100 + PERIOD, 10, 7)
    a.log, b.log = [1], [1]
    steps = period_steps(snapshot([a], records=records), orbit := snapshot([b], records=records),
                         PERIOD, counters)
    assert steps is not None

    def now(when: int, sent: int, level: int, log: list) -> object:
        p = _part(when, sent, level)
        p.log = log
        return snapshot([p], records=records)
    assert on_orbit(orbit, steps, 3, now(100 + 4 * PERIOD, 25, 7, [1, 2, 3]), counters)
    assert on_orbit(orbit, steps, 3, now(100 + 4 * PERIOD, 10, 7, [1]), counters)
    for wrong in (now(100 + 4 * PERIOD + 2, 25, 7, [1]),     # a tick off the grid
                  now(100 + 3 * PERIOD, 25, 7, [1]),         # ... or a period behind
                  now(100 + 4 * PERIOD, 25, 8, [1]),         # a level changed
                  now(100 + 4 * PERIOD, 9, 7, [1])):         # a counter went down
        assert not on_orbit(orbit, steps, 3, wrong, counters)
    assert not on_orbit(orbit, steps, 0, orbit, counters)


class _Latest:        # a record of the last of something, rewritten every period
    pass


_Latest.__module__ = "hil.tests_quiet_can"


def test_a_latest_record_may_change_and_then_asks_for_the_last_period_to_run():
    """A part whose record of the last status changed (a cruising wheel's odometer) is still
    periodic, but moving it on does not give that record: latest_moved says so. Everything
    outside the record is held as before, and the records must sit at the same places."""
    def part(when: int, sent: int, odo: int, seen: int, level: int = 7) -> _Part:
        p = _part(when, sent, level)
        p.view = _Latest()
        p.view.odometer, p.view.last_seen, p.view.extra = odo, seen, {"odometer": odo}
        return p

    def snap(p: _Part):
        return snapshot([p], latest=(_Latest,))

    counters = frozenset({"sent"})
    a = snap(part(100, 4, 39, 90))
    assert sorted(a.shape[pos] for pos in a.free if type(a.shape[pos]) is int) == [39, 39, 90]
    assert a.shape.index(7) not in a.free                # the level is outside the record
    # the record moved as a tick does: a step, no need to run the period
    b = snap(part(100 + PERIOD, 10, 39, 90 + PERIOD))
    steps = period_steps(a, b, PERIOD, counters)
    assert steps is not None and not latest_moved(a, b, steps)
    # the odometer and the frame's end moved otherwise: periodic, but the period must run
    c = snap(part(100 + PERIOD, 10, 43, 93 + PERIOD))
    steps = period_steps(a, c, PERIOD, counters)
    assert steps is not None and latest_moved(a, c, steps)
    assert on_orbit(c, steps, 2, snap(part(100 + 3 * PERIOD, 20, 50, 7)), counters)
    # on the orbit a free value may be anything, even where a period stepped it: to be run
    b_steps = period_steps(a, b, PERIOD, counters)
    gone = snap(part(100 + 3 * PERIOD, 20, 39, None))
    assert on_orbit(b, b_steps, 2, gone, counters) and latest_moved(b, gone, b_steps, 2)
    # outside the record nothing else may change, and a record is not free without its type
    assert period_steps(a, snap(part(100 + PERIOD, 10, 43, 93, level=8)), PERIOD,
                        counters) is None
    assert not on_orbit(c, steps, 2, snap(part(100 + 3 * PERIOD, 20, 50, 7, level=8)),
                        counters)
    plain = snapshot([part(100 + PERIOD, 10, 43, 93 + PERIOD)])
    assert not plain.free and period_steps(snapshot([part(100, 4, 39, 90)]), plain, PERIOD,
                                           counters) is None


def test_a_random_generator_is_state_a_snapshot_cannot_see():
    p = _part(0, 0, 0)
    p.rng = random.Random(1)
    with pytest.raises(Unwalkable, match="rng"):
        snapshot([p])
    assert ("rng", random.Random(1).getstate()) in snapshot([p], rng_state=True).shape


# -- the world, sleeping or not --------------------------------------------------------------

HUNT = sleep_hunt()
"""scripts/sleep_hunt.py: its whole-world state and summary are what these tests compare."""
_state = HUNT.state
_summary = HUNT.summary


def _pair(cfg: SimConfig) -> tuple[World, World]:
    return World(replace(cfg, can_sleep=False)), World(cfg)


ORDERS = {
    # the father asks for status, moves a joint, drives the wheel, at set times
    "orders": ((2.0, 1, cmd("status")), (3.3, 2, cmd("joint", 1, 20)),
               (6.1, 3, cmd("wheel", 50)), (9.0, 3, cmd("wheel", 0)),
               (12.5, 1, cmd("status")), (12.5, 2, cmd("paw", 0))),
    # wheels cruising for seconds (their odometers change every status frame), asked for
    # status meanwhile, a joint moving beside one, then stopped
    "cruising wheels": ((1.0, 1, cmd("wheel", 80)), (3.0, 2, cmd("wheel", -45)),
                        (5.0, 1, cmd("status")), (9.37, 1, cmd("status")),
                        (11.0, 2, cmd("joint", 1, 20)), (13.61, 2, cmd("status")),
                        (16.0, 1, cmd("wheel", 0)), (17.2, 1, cmd("status"))),
}


def _orders(w: World, name: str = "orders") -> None:
    for t, r, c in ORDERS[name]:
        w.sched.at(round(t * 16_000_000), lambda r=r, c=c: w.submit(0, r, [c]))


F = lambda *s: tuple(parse_fault(x) for x in s)  # noqa: E731
SCENARIOS = {
    "idle": SimConfig(robots=(0, 1, 2, 3), duration=20, can=True, seed=1),
    "orders": SimConfig(robots=(0, 1, 2, 3), duration=20, can=True, seed=8),
    "load": SimConfig(robots=(0, 1, 2, 3), duration=15, can=True, seed=2, load=1),
    "byte errors": SimConfig(robots=(0, 1, 2, 3), duration=15, can=True, seed=3, ber=0.001),
    "CAN faults": SimConfig(robots=(0, 1, 2, 3), duration=15, can=True, seed=2, faults=F(
        "busoff:2@4", "stuck:3@6-7", "stall:1.JOINT1@5", "silent:2.WHEEL@8-9",
        "noisy:1.PAW@10-10.5")),
    "saturated": SimConfig(robots=(0, 1, 2, 3), duration=15, can=True, seed=4,
                           load="saturate"),
    "no father": SimConfig(robots=(1, 2, 3), duration=15, can=True, seed=5, load=0.3),
    "cruising wheels": SimConfig(robots=(0, 1, 2, 3), duration=20, can=True, seed=9),
    # news the child only notes (one more call of its main loop, a counter) reaching it
    # between the two snapshots of a probe: the sleep took the one call for a period's
    # growth and added it for every period it skipped (a random hunt found it)
    "news while awake": SimConfig(robots=(0, 3, 4), duration=40, can=True, seed=248942,
                                  load=0.2, load_until=30, mac=MacConfig(checksum=False)),
    # a wheel cruising at 3 mm/s: its odometer (whole mm) stays the same for three periods,
    # so two snapshots a period apart may not see it change; the dispatcher's record of it
    # kept a value 10 s old when the domain woke without a replay (a random hunt found it)
    "slow wheel": SimConfig(robots=(0, 3, 4), duration=60, can=True, seed=3, load=0.2,
                            load_until=50, mac=MacConfig(checksum=False)),
}


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_a_sleeping_can_side_gives_the_frame_by_frame_run(name):
    slow, fast = _pair(SCENARIOS[name])
    if name in ORDERS:
        _orders(slow, name), _orders(fast, name)
    slow.run()
    fast.run()
    assert _summary(fast) == _summary(slow)
    assert _state(fast) == _state(slow)
    assert all(q.periods_skipped == 0 for q in slow.quiet.values())
    assert sum(q.periods_skipped for q in fast.quiet.values()) > 0
    if name == "orders":                   # woken by orders, asleep again at once
        assert sum(q.resleeps for q in fast.quiet.values()) > 0
    if name == "saturated":                # every order out of reach: refused, still asleep
        assert sum(q.refused for q in fast.quiet.values()) > 0
        assert sum(q.refused for q in slow.quiet.values()) == 0
    if name == "cruising wheels":
        # asleep while its wheel cruises; each wake ran the last period to learn the odometer
        assert fast.quiet[1].periods_skipped > 0.5 * 20 * 16_000_000 // PERIOD
        assert fast.quiet[1].replays > 0 and slow.quiet[1].replays == 0


@pytest.mark.parametrize("name", ["orders", "cruising wheels"])
def test_woken_at_awkward_ticks_it_is_still_the_same_run(name):
    """Runs cut on status SOFs, just after them, at frame ends, and at random ticks: every
    cut wakes every CAN side, and the state must match the frame-by-frame run at each."""
    slow, fast = _pair(SCENARIOS[name])
    _orders(slow, name), _orders(fast, name)
    rng = random.Random(5)
    cuts, t = [], 0
    while t < 19 * 16_000_000:
        t += PERIOD * rng.randint(2, 9) + rng.choice(
            [STATUS_STAGGER_TICKS * rng.randint(1, 6), STATUS_STAGGER_TICKS + 1,
             STATUS_STAGGER_TICKS * 3 + 230 * 32, rng.randrange(PERIOD)])
        cuts.append(t)
    for t in cuts:
        slow.run(t)
        fast.run(t)
        assert _state(fast) == _state(slow), f"different at tick {t}"
    assert _summary(fast) == _summary(slow)
    assert sum(q.sleeps for q in fast.quiet.values()) >= len(cuts)
    assert sum(q.resleeps for q in fast.quiet.values()) > len(cuts) // 2


def test_stepping_without_waking_leaves_it_asleep_and_the_same_run():
    """The soak and the progress bar run in steps and read only the radio side between them
    (``World.run_in_steps``): a sleeping CAN side sleeps on across the steps."""
    slow, fast = _pair(SCENARIOS["cruising wheels"])
    _orders(slow, "cruising wheels"), _orders(fast, "cruising wheels")
    asleep_at_steps = 0
    for now in fast.run_in_steps(PERIOD * 5 // 2):
        slow.run(now)
        asleep_at_steps += sum(q.asleep for q in fast.quiet.values())
    assert asleep_at_steps > 50
    assert not any(q.asleep for q in fast.quiet.values())   # woken at the end, as run()
    assert _summary(fast) == _summary(slow)
    assert _state(fast) == _state(slow)


def test_an_event_a_period_does_not_move_keeps_the_domain_awake_until_it_has_run():
    """A one-shot event of the domain (a recovery, a stall timer: none is left pending by an
    idle child today) is the same tick in two snapshots a period apart, so the snapshots
    alone call the domain periodic; asleep, the event would be skipped or put back in the
    past. The domain stays awake until it has run, then sleeps."""
    w = World(SimConfig(robots=(0, 1), duration=6, can=True, seed=1))
    q = w.quiet[1]
    at, fired = round(4.05 * 16_000_000), []
    q.clock.at(at, lambda: fired.append(q.clock.now))
    w.run(at - 1)
    assert q.periods_skipped == 0 and q.one_shots > 0 and not q.asleep
    w.run()
    assert fired == [at] and q.periods_skipped > 0


def test_a_child_woken_every_few_periods_backs_off_and_is_still_the_same_run(monkeypatch):
    """Orders every few periods (5 robots, 2 messages a second each): sleeps shorter than
    PAYBACK_PERIODS make a domain probe ever less often, so it takes fewer snapshots than it
    would without the back-off (each costs about four periods run frame by frame), and the
    run is the frame-by-frame run all the same."""
    import hil.sim.quiet_can as quiet_can
    cfg = SimConfig(robots=(0, 1, 2, 3, 4), duration=30, can=True, seed=1, load=2)
    taken = {"n": 0}
    real = quiet_can.snapshot

    def counted(*a, **k):
        taken["n"] += 1
        return real(*a, **k)

    monkeypatch.setattr(quiet_can, "snapshot", counted)
    slow, fast = _pair(cfg)
    slow.run()
    fast.run()
    with_backoff = taken["n"]
    assert _summary(fast) == _summary(slow)
    assert _state(fast) == _state(slow)
    assert sum(q._short for q in fast.quiet.values()) > 0      # short sleeps were seen
    taken["n"] = 0
    monkeypatch.setattr(quiet_can, "PAYBACK_PERIODS", 0)        # no sleep is short
    plain = World(cfg)
    plain.run()
    assert _summary(plain) == _summary(slow)
    assert with_backoff < 0.7 * taken["n"], (with_backoff, taken["n"])


def test_an_idle_ring_sleeps_most_of_the_time():
    w = World(SimConfig(robots=(0, 1, 2, 3, 4, 5, 6), duration=30, can=True, seed=1))
    w.run()
    periods = 30 * 16_000_000 // PERIOD
    for r, q in w.quiet.items():
        assert q.periods_skipped >= 0.9 * periods, (r, q.periods_skipped)
    assert w.summary()["can_frames"] == 6 * 6 * 10 * 30        # 6 children, 6 nodes, 10 Hz


def test_nothing_sleeps_when_someone_watches_the_frames(tmp_path):
    cfg = SimConfig(robots=(0, 1, 2), duration=3, can=True, seed=1)
    seen: list = []
    w = World(cfg, on_event=seen.append)
    w.run()
    assert all(q.periods_skipped == 0 for q in w.quiet.values())
    assert sum(1 for e in seen if e.get("ev") == "can") == w.can_frames
    # a sniffer on one bus (the acceptance tests' model DUT does this)
    w = World(cfg)
    bus = w.can_buses[1]
    prev, frames = bus.trace, []
    bus.trace = lambda *a: (prev(*a), frames.append(a))
    w.run()
    assert w.quiet[1].periods_skipped == 0 and w.quiet[2].periods_skipped > 0
    assert len(frames) == 6 * 10 * 3


# -- news: noted without waking ----------------------------------------------------------------

def _news(done_at: float = 4.0) -> tuple:
    return ((done_at, (cmd("done"), cmd("movex", 8)), FrameType.BROADCAST_INFO),
            (6.5, (cmd("fail", 3), cmd("moveto", 900, 0, 0)), FrameType.FAILURE),
            (9.0, (cmd("status"),), FrameType.INSTRUCTION))


def test_news_reaching_a_sleeping_child_is_noted_and_it_sleeps_on():
    """A done() or fail() notice (the soak's children get about one a second, half of what
    woke them) only goes into the dispatcher's log: the child's CAN side sleeps on through
    it, and the run is still the frame-by-frame run. An order wakes it."""
    slow, fast = _pair(SimConfig(robots=(0, 1, 2), duration=12, can=True, seed=6,
                                 keep_records=True))
    asleep_after: list[bool] = []
    for w in (slow, fast):
        for t, commands, type_ in _news():
            w.sched.at(round(t * 16_000_000),
                       lambda w=w, c=commands, ty=type_: w.submit(0, 1, c, int(ty)))
    q = fast.quiet[1]
    for until in (5.0, 7.5):            # each notice delivered by then
        fast._advance(round(until * 16_000_000))
        asleep_after.append(q.asleep)
    slow.run()
    fast.run()
    assert asleep_after == [True, True] and q.noted == 2
    assert [text for _, text in fast.children[1].dispatcher.log[-2:]] == [
        "robot 0: done()", "robot 0: fail(3)"]
    assert _summary(fast) == _summary(slow)
    assert _state(fast) == _state(slow)
    assert slow.quiet[1].noted == 0 and q.periods_skipped > 0.5 * 12 * 16_000_000 // PERIOD


def test_orders_refused_at_once_leave_a_sleeping_child_asleep():
    """Orders the dispatcher refuses from the order alone (out of reach, a joint outside its
    limits) are answered with failures while the CAN side sleeps on; the run is still the
    frame-by-frame run. A message with one order it can carry out wakes it."""
    orders = ((4.0, (cmd("movex", 123456789), cmd("joint", 2, 500))),
              (6.5, (cmd("moveto", 900, 0, 0),)),
              (9.0, (cmd("movex", 123456789), cmd("joint", 1, 20))))
    slow, fast = _pair(SimConfig(robots=(0, 1, 2), duration=12, can=True, seed=6,
                                 keep_records=True))
    for w in (slow, fast):
        for t, commands in orders:
            w.sched.at(round(t * 16_000_000), lambda w=w, c=commands: w.submit(0, 1, c))
    q = fast.quiet[1]
    asleep_after, sleeps = [], []
    for until in (6.0, 8.5, 11.0):      # each message delivered by then
        fast._advance(round(until * 16_000_000))
        asleep_after.append(q.asleep)
        sleeps.append(q.sleeps)
    slow.run()
    fast.run()
    assert asleep_after[:2] == [True, True] and sleeps[0] == sleeps[1] and q.refused == 2
    assert sleeps[2] > sleeps[1]        # the last one woke it: it moved joint 1, then slept
    assert fast.children[1].dispatcher.target[0] == 20
    failures = [m.content for m in fast.messages if m.src == 1]
    assert [c.split(b")")[0] for c in failures[:3]] == [b"fail(1", b"fail(2", b"fail(1"]
    assert _summary(fast) == _summary(slow)
    assert _state(fast) == _state(slow)
    assert slow.quiet[1].refused == 0


def _child_with(condition: str):
    w = World(SimConfig(robots=(0, 1), duration=5, can=True, seed=1,
                        cpu=DEFAULT_COSTS if "CPU model" in condition
                        or "main loop" in condition else None))
    w.run(2 * 16_000_000)
    child, now = w.children[1], w.now
    if condition == "an order under way":
        child.dispatcher.on_message(0, 1, (cmd("joint", 1, 20),), now)
        child.dispatcher.take_can()
    elif condition == "a reply waiting":
        child.dispatcher.on_message(0, 1, (cmd("status"),), now)
    elif condition == "its timer armed":
        child.timer.arm_at(now + 16_000)
    elif condition == "CAN supervision pending":
        child.can.isolate(now)
    elif condition == "an action sequence":
        child.run_sequence((2, 1), 1)      # its turn comes after robot 2's: nothing starts
    elif condition == "a message waiting for the main loop":
        child._on_message(Deliver(0, 1, 4, int(FrameType.BROADCAST_INFO), (cmd("done"),)),
                          now)
        assert child.cpu_work == 1
    return child


@pytest.mark.parametrize("condition", ["nothing", "an order under way", "a reply waiting",
                                       "its timer armed",
                                       "CAN supervision pending", "an action sequence",
                                       "nothing, on the CPU model",
                                       "a message waiting for the main loop"])
def test_only_news_to_a_child_with_nothing_under_way_is_only_noted(condition):
    """What handling news does otherwise depends on ticks a sleeping CAN side has not moved on
    (a job's deadline, the supervision's, the timer) or on a message the main loop has not
    dispatched yet (the CPU model's)."""
    child = _child_with(condition)
    notice = Deliver(0, 1, 5, int(FrameType.BROADCAST_INFO), (cmd("done"), cmd("movex", 8)))
    order = Deliver(0, 1, 6, int(FrameType.INSTRUCTION), (cmd("movex", 8),))
    idle = condition.startswith("nothing")
    assert notes_only(child, notice) is idle
    assert not notes_only(child, order)
    refused = Deliver(0, 1, 7, int(FrameType.INSTRUCTION), (cmd("movex", 123456789),))
    assert refuses_only(child, refused) is idle
    assert not refuses_only(child, order) and not refuses_only(child, notice)


def _random_ring(seed: int) -> tuple[SimConfig, list[int]]:
    """A seeded ring of 2-6 children (the father in most), load, CAN faults and a dead radio
    at random ticks, and three random cuts."""
    rng = random.Random(seed)
    robots = tuple(sorted({0} | set(rng.sample(range(1, 7), rng.randint(2, 5)))))
    if rng.random() < 0.2:
        robots = robots[1:]
    children = [r for r in robots if r]
    faults = []
    for _ in range(rng.randint(0, 3)):
        t, r = rng.uniform(3, 12), rng.choice(children)
        faults += {
            "busoff": [f"busoff:{r}@{t:.2f}"],
            "stall": [f"stall:{r}.JOINT{rng.randint(1, 4)}@{t:.2f}"],
            "silent": [f"silent:{r}.WHEEL@{t:.2f}-{t + 1:.2f}"],
            "stuck": [f"stuck:{r}@{t:.2f}-{t + 0.5:.2f}"],
            "fail": [f"fail:{r}@{t:.2f}", f"recover:{r}@{t + 3:.2f}"],
        }[rng.choice(["busoff", "stall", "silent", "stuck", "fail"])]
    cfg = SimConfig(robots=robots, duration=18, can=True, seed=seed,
                    load=rng.choice([0.3, 0.7, 1.5]), faults=F(*faults))
    return cfg, sorted(rng.randrange(1, 18 * 16_000_000) for _ in range(3))


@pytest.mark.parametrize("seed", range(6))
def test_random_rings_with_faults_asleep_and_cut_are_the_frame_by_frame_run(seed):
    """Rings nobody chose: children sending each other orders (and so news), CAN faults, a
    radio failing; state compared at three random cuts and at the end."""
    cfg, cuts = _random_ring(seed)
    slow, fast = _pair(cfg)
    for t in [*cuts, None]:
        slow.run(t)
        fast.run(t)
        assert _state(fast) == _state(slow), f"different at tick {t}"
    assert _summary(fast) == _summary(slow)
    assert sum(q.periods_skipped for q in fast.quiet.values()) > 0


@pytest.mark.parametrize("seed", range(4))
def test_random_worlds_run_alike_with_the_fast_paths_or_without(seed):
    """A few seeds of scripts/sleep_hunt.py (random rings, faults, loads, byte errors, run
    segments; ``python scripts/sleep_hunt.py --runs N`` draws more)."""
    cfg, cuts, traced = HUNT.random_world(seed, durations=(30,))
    assert HUNT.same_run(cfg, cuts, traced), (cfg, cuts, traced)

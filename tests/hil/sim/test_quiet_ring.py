"""The ring moved on in whole cycles while it only repeats itself (hil/sim/quiet_ring.py): the
same run, to the tick, as frame by frame.

Each scenario runs twice from the same config, once with the ring's leaps and once without,
stopping at the same ticks; at every stop the whole world (every attribute of every part, the
pending events, the random generators' states) and the summary must be the same. The idle
scenarios must also have leapt, so that the comparison is not between two frame-by-frame runs.
"""
from __future__ import annotations

import dataclasses
import json
import random
from dataclasses import replace

import pytest

from firmware_model.cycle_costs import DEFAULT_COSTS
from hil.sim.domains import SimScheduler
from firmware_model.radio.mac import MacConfig
from firmware_model.radio.content import cmd
from firmware_model.timing import s_to_ticks
from hil.sim.faults import parse_fault
from hil.sim.pcap import PcapWriter
from hil.sim.quiet_ring import QuietRing
from hil.sim.state_walk import InTuple, advance, period_steps, portable, snapshot, writable
from hil.sim.trace import TraceWriter
from hil.sim.world import SimConfig, World

F = lambda *s: tuple(parse_fault(x) for x in s)  # noqa: E731
RING = (0, 1, 2, 3, 4, 5, 6)

SCENARIOS = {
    # name: (config, stops in s, least share of the run leapt over; 0.0: no leap at all)
    "idle ring": (SimConfig(robots=RING, duration=60, seed=1), (7.3, 30.0, 60), 0.7),
    # a deaf robot's MAC keeps a cycle of its own beside the ring's: it is carried across
    # each leap, run on its own (0.49 of this run leapt over before, 0.81 since)
    "a robot fails and comes back": (
        SimConfig(robots=(0, 1, 2, 3), duration=60, seed=2,
                  faults=F("fail:2@15", "recover:2@31.5")), (14.0, 15.2, 40.0, 60), 0.7),
    # the same for PC1 (0.15 before, 0.63 since)
    "standby father, PC1 fails": (
        SimConfig(robots=(0, 1, 2, 3), duration=60, seed=3, father_standby=True,
                  faults=F("fail:0@20")), (19.0, 60), 0.5),
    "late power-on": (
        SimConfig(robots=(0, 1, 2, 5), duration=50, seed=4, power_on={5: 24.0}),
        (23.99, 24.5, 50), 0.4),
    "no father": (SimConfig(robots=(1, 2, 3, 4, 5, 6), duration=40, seed=5), (40,), 0.5),
    "light load": (SimConfig(robots=(0, 1, 2), duration=80, seed=6, load=0.02), (80,), 0.1),
    "skewed clock": (
        SimConfig(robots=(0, 1, 2, 3), duration=40, seed=7, faults=F("skew:2:0.01")),
        (40,), 0.5),
    "steal and burst": (
        SimConfig(robots=(0, 1, 2, 3), duration=40, seed=8,
                  faults=F("steal:1@12", "burst@25:0.3", "foreign@30:20")), (12.0, 40), 0.3),
    "byte errors for a while": (
        SimConfig(robots=(0, 1, 2), duration=40, seed=9, faults=F("ber@10-20:0.002")),
        (40,), 0.3),
    # on the CPU model (without CAN sides: a child's CAN side never sleeps there), the
    # handlers' figures and the UARTs' late bytes moved on with the rest
    "idle ring on the CPU model": (SimConfig(robots=RING, duration=60, seed=1, cpu=DEFAULT_COSTS),
                                   (7.3, 30.0, 60), 0.7),
    # a child the anchor: its probes come with its TX END handler running
    "no father on the CPU model": (
        SimConfig(robots=(1, 2, 3, 4, 5, 6), duration=40, seed=5, cpu=DEFAULT_COSTS), (40,),
        0.5),
    "a robot fails and comes back on the CPU model": (
        SimConfig(robots=(0, 1, 2, 3), duration=60, seed=2, cpu=DEFAULT_COSTS,
                  faults=F("fail:2@15", "recover:2@31.5")), (14.0, 15.2, 40.0, 60), 0.7),
    "standby father on the CPU model": (
        SimConfig(robots=(0, 1, 2, 3), duration=60, seed=3, father_standby=True,
                  cpu=DEFAULT_COSTS, faults=F("fail:0@20")), (19.0, 60), 0.5),
    "steal and burst on the CPU model": (
        SimConfig(robots=(0, 1, 2, 3), duration=40, seed=8, cpu=DEFAULT_COSTS,
                  faults=F("steal:1@12", "burst@25:0.3", "foreign@30:20")), (12.0, 40), 0.3),
    "idle ring with CAN sides": (SimConfig(robots=RING, duration=60, seed=15, can=True),
                                 (10.0, 33.3, 60), 0.5),
    "CAN faults": (
        SimConfig(robots=(0, 1, 2, 3), duration=60, seed=16, can=True,
                  faults=F("busoff:2@20", "stall:1.JOINT1@35", "silent:3.WHEEL@45-46")),
        (19.9, 40.0, 60), 0.2),
    # the byte errors draw on the air's random streams every frame: never the same state
    "byte errors throughout": (SimConfig(robots=(0, 1, 2), duration=20, seed=10, ber=0.001),
                               (20,), 0.0),
    # (0.12 before the deaf robot was carried across the leaps, 0.81 since)
    "a robot gone for good": (
        SimConfig(robots=(0, 1, 2, 3), duration=40, seed=11, faults=F("fail:3@8")), (40,),
        0.7),
    "two robots gone, CAN sides, one back": (
        SimConfig(robots=(0, 1, 2, 3, 4), duration=120, seed=12, can=True,
                  faults=F("fail:2@5", "fail:4@30", "recover:2@70")), (29.9, 50.0, 70.1, 120),
        0.5),
}


def _state(w: World) -> list:
    """The whole world but its ring prober: every part (the CAN sides' too), every pending
    event, and what each CAN domain did (not the snapshots it keeps to compare)."""
    parts = {k: v for k, v in vars(w).items() if k not in ("quiet_ring", "cfg", "quiet")}
    domains = [(q.asleep, q.sleeps, q.periods_skipped, q.replays, q.resleeps, q.noted,
                q.refused) for q in w.quiet.values()]
    boundary = [w.sched, *w.quiet.values(), *(q.clock for q in w.quiet.values())]
    events = [w.sched.pending(owner) for owner in (None, *w.quiet.values())]
    shape = portable(snapshot([parts, events, domains], boundary, rng_state=True))
    # a frozen record (an Outcome) holds its Message, equal only to itself: compare its text
    return [repr(x) if dataclasses.is_dataclass(x) else x for x in shape]


def _twins(cfg: SimConfig) -> tuple[World, World]:
    """(frame by frame, leaping): the same world twice."""
    plain = World(replace(cfg, ring_sleep=False))
    assert plain.quiet_ring is None
    return plain, World(cfg)


@pytest.mark.parametrize("name", SCENARIOS)
def test_leaping_ring_is_the_frame_by_frame_ring(name):
    cfg, stops, least = SCENARIOS[name]
    plain, leaping = _twins(cfg)
    for s in stops:
        for w in (plain, leaping):
            w.run(until=s_to_ticks(s))
        assert leaping.now == plain.now == s_to_ticks(s)
        assert _state(leaping) == _state(plain), f"{name}: the worlds differ at {s} s"
    assert json.dumps(leaping.summary(), sort_keys=True) == \
        json.dumps(plain.summary(), sort_keys=True)
    ring = leaping.quiet_ring
    share = ring.ticks_skipped / leaping.now
    if least == 0.0:
        assert ring.leaps == 0, f"{name}: a ring that never repeats itself leapt"
    else:
        assert share >= least, f"{name}: only {share:.0%} leapt over"


def _random_config(rng: random.Random) -> SimConfig:
    """A seeded ring of 1-7 robots with a few faults of the air, perhaps CAN sides, the
    standby father, the paper's profile, the checksum, light load, late power-on and the CPU
    model."""
    robots = tuple(sorted(rng.sample(range(7), rng.randint(1, 7))))
    dur = rng.choice([30, 60, 90])
    specs: list[str] = []
    for _ in range(rng.randint(0, 3)):
        kind = rng.choice(["fail", "steal", "burst", "foreign", "ber", "drop", "skew", "noise"])
        t = round(rng.uniform(2, dur - 5), 3)
        until = round(t + rng.uniform(0.5, 5), 3)
        r = rng.choice(robots)
        if kind == "fail":
            specs.append(f"fail:{r}@{t}")
            if rng.random() < 0.7:
                specs.append(f"recover:{r}@{round(t + rng.uniform(0.1, 15), 3)}")
        elif kind == "skew":
            if not any(x.startswith(f"skew:{r}:") for x in specs):
                specs.append(f"skew:{r}:{rng.choice([0.005, 0.01, 0.02])}")
        else:
            specs.append({"steal": f"steal:{r}@{t}",
                          "burst": f"burst@{t}:{round(rng.uniform(0.01, 0.5), 3)}",
                          "foreign": f"foreign@{t}:{rng.randint(1, 40)}",
                          "ber": f"ber@{t}-{until}:0.003", "drop": f"drop@{t}-{until}:0.003",
                          "noise": f"noise@{t}-{until}"}[kind])
    children = [r for r in robots if r]
    can = bool(children) and rng.random() < 0.3
    if can and rng.random() < 0.5:
        specs.append(f"busoff:{rng.choice(children)}@{round(rng.uniform(2, dur - 5), 2)}")
    standby = 0 in robots and rng.random() < 0.3
    profile = "paper" if not standby and rng.random() < 0.15 else "rprs"
    return SimConfig(
        robots=robots, duration=dur, seed=rng.randint(0, 999), can=can, father_standby=standby,
        faults=tuple(sorted(F(*specs), key=lambda f: (f.at, f.kind))),
        load=rng.choice(["idle", "idle", "idle", 0.05]),
        power_on={r: round(rng.uniform(0, dur / 2), 2) for r in robots if rng.random() < 0.2},
        mac=MacConfig(checksum=profile == "rprs" and rng.random() < 0.4, profile=profile),
        cpu=DEFAULT_COSTS if rng.random() < 0.3 else None)


@pytest.mark.parametrize("seed", range(16))
def test_random_rings_leap_to_the_same_state(seed):
    """Random rings (``_random_config``), stopped at random ticks: the same world with and
    without leaps. (Seeds 16-455 of the same generator, run by hand, give the same state
    too.)"""
    rng = random.Random(seed)
    cfg = _random_config(rng)
    plain, leaping = _twins(cfg)
    for s in sorted({round(rng.uniform(1, cfg.duration), 2), cfg.duration}):
        for w in (plain, leaping):
            w.run(until=s_to_ticks(s))
        assert _state(leaping) == _state(plain), f"{cfg}: the worlds differ at {s} s"
    assert json.dumps(leaping.summary(), sort_keys=True) == \
        json.dumps(plain.summary(), sort_keys=True)


@pytest.mark.parametrize("seed", range(100, 106))
def test_random_traced_rings_write_the_same_trace(seed, tmp_path):
    """Random rings (``_random_config``) with a trace and an event callback: the same trace,
    byte for byte, with and without leaps. (Seeds 106-305, run by hand, give the same trace
    too.)"""
    cfg = _random_config(random.Random(seed))
    _, want, want_events = _traced(replace(cfg, ring_sleep=False), tmp_path / "a.jsonl")
    _, got, got_events = _traced(cfg, tmp_path / "b.jsonl")
    assert got == want and got_events == want_events


def test_orders_submitted_between_runs_end_the_repetition():
    """A message submitted from outside between two runs (the bench, a test) is a change the
    next snapshot sees: the ring runs it frame by frame, delivered as without leaps."""
    plain, leaping = _twins(SimConfig(robots=(0, 1, 2), duration=60, seed=12))
    for t, dst in ((10.0, 1), (25.0, 2), (25.0, 1), (41.3, 2)):
        for w in (plain, leaping):
            w.run(until=s_to_ticks(t))
            w.submit(0, dst, [cmd("status")])
    for w in (plain, leaping):
        w.run()
    assert _state(leaping) == _state(plain)
    assert leaping.summary() == plain.summary()
    assert leaping.summary()["delivered"] == 4
    assert leaping.quiet_ring.ticks_skipped > s_to_ticks(20)


def test_orders_to_children_whose_can_sides_sleep():
    """Orders that wake a child's CAN side (a wheel driven, then stopped, a joint moved) and
    news that does not: the ring leaps only while every CAN side sleeps, and the children's
    buses carry the same frames as without leaps."""
    cfg = SimConfig(robots=(0, 1, 2, 3), duration=60, seed=17, can=True)
    plain, leaping = _twins(cfg)
    orders = ((5.0, 1, cmd("wheel", 80)), (20.0, 1, cmd("status")), (31.7, 2, cmd("joint", 1, 20)),
              (40.0, 1, cmd("wheel", 0)), (52.0, 3, cmd("status")))
    for w in (plain, leaping):
        for t, r, c in orders:
            w.sched.at(s_to_ticks(t), lambda w=w, r=r, c=c: w.submit(0, r, [c]))
    for s in (12.0, 33.0, 60):
        for w in (plain, leaping):
            w.run(until=s_to_ticks(s))
        assert _state(leaping) == _state(plain), f"the worlds differ at {s} s"
    assert leaping.summary() == plain.summary()
    assert leaping.can_frames == plain.can_frames > 0
    assert leaping.quiet_ring.ticks_skipped > s_to_ticks(10)


def test_events_scheduled_from_outside_bound_the_leaps():
    """An event someone schedules on the world's clock (here a message at 33.3 s) is not moved
    by the period: the ring leaps only up to it, and the event runs at its tick."""
    plain, leaping = _twins(SimConfig(robots=(0, 1, 2, 3), duration=50, seed=13))
    seen = {}
    for w in (plain, leaping):
        w.sched.at(s_to_ticks(33.3), lambda w=w: seen.setdefault(id(w), (
            w.now, w.submit(0, 3, [cmd("status")]).num)))
        w.run()
    assert seen[id(plain)] == seen[id(leaping)]
    assert seen[id(leaping)][0] == s_to_ticks(33.3)
    assert _state(leaping) == _state(plain)
    assert leaping.quiet_ring.leaps >= 2


def _traced(cfg: SimConfig, path, stops=()) -> tuple[World, bytes, list]:
    """Run ``cfg`` with a trace to ``path`` and an event callback, stopping at ``stops``
    (s); returns the world, the trace's bytes and the events the callback got."""
    got: list = []
    tw = TraceWriter(str(path))
    w = World(cfg, trace=tw, on_event=got.append)
    for s in stops:
        w.run(until=s_to_ticks(s))
    w.run()
    tw.close()
    return w, path.read_bytes(), got


@pytest.mark.parametrize("cfg,least", [
    (SimConfig(robots=(0, 1, 2), duration=40, seed=14), 0.5),
    # the standby PC's period is 28 turns, and the faults leave little room
    (SimConfig(robots=RING, duration=60, seed=20, father_standby=True,
               faults=F("fail:3@20", "recover:3@24.5", "burst@41:0.2")), 0.03),
    (SimConfig(robots=(2, 5), duration=45, seed=21, mac=MacConfig(profile="paper"),
               power_on={5: 7.5}), 0.3),
], ids=["idle", "faults and the standby father", "the paper's profile"])
def test_a_traced_run_leaps_and_writes_the_same_trace(cfg, least, tmp_path):
    """A trace and an event callback get the events of the cycles leapt over: the trace is
    the frame-by-frame run's, byte for byte, stopped and started again or not."""
    plain, want, want_events = _traced(replace(cfg, ring_sleep=False), tmp_path / "a.jsonl")
    for stops in ((), (7.77, 30.0)):
        leaping, got, got_events = _traced(cfg, tmp_path / "b.jsonl", stops)
        assert got == want
        assert got_events == want_events
        assert leaping.quiet_ring.ticks_skipped > least * leaping.now
    assert b'"ev":"frame"' in want


def _captured(cfg: SimConfig, path, stops=()) -> tuple[World, bytes]:
    """Run ``cfg`` with a pcapng capture to ``path`` (hil/sim/pcap.py), stopping at
    ``stops`` (s); returns the world and the capture's bytes."""
    with open(path, "wb") as f:
        w = World(cfg)
        w.capture(PcapWriter(f, *w.capture_interfaces()))
        for s in stops:
            w.run(until=s_to_ticks(s))
        w.run()
    return w, path.read_bytes()


@pytest.mark.parametrize("cfg,least", [
    (SimConfig(robots=(0, 1, 2), duration=40, seed=14), 0.5),
    (SimConfig(robots=RING, duration=60, seed=20, father_standby=True,
               faults=F("fail:3@20", "recover:3@24.5", "burst@41:0.2", "foreign@50:12")),
     0.03),
    # a capture keeps the CAN sides awake (it sees every CAN frame): no leap, the same bytes
    (SimConfig(robots=(0, 1, 2), duration=20, seed=22, can=True), 0.0),
], ids=["idle", "faults, foreign bytes and the standby father", "CAN sides"])
def test_a_captured_run_leaps_and_writes_the_same_capture(cfg, least, tmp_path):
    """A capture gets the packets of the cycles leapt over, as the trace gets their events:
    the pcapng file is the frame-by-frame run's, byte for byte."""
    plain, want = _captured(replace(cfg, ring_sleep=False), tmp_path / "a.pcapng")
    for stops in ((), (7.77, 15.0)):
        leaping, got = _captured(cfg, tmp_path / "b.pcapng", stops)
        assert got == want
        assert leaping.transmissions == plain.transmissions
        if least:
            assert leaping.quiet_ring.ticks_skipped > least * leaping.now
        else:
            assert leaping.quiet_ring.leaps == 0
    assert plain.transmissions > 100


def test_no_ring_where_it_could_never_leap():
    """On the wall's clock; on the CPU model with CAN sides (which never sleep there) or a
    trace (its per-second CPU loads never repeat with the ring); and where a trace keeps the
    CAN sides awake: no ring. The CPU model alone leaps."""
    cfg = SimConfig(robots=(0, 1, 2), duration=20, seed=14)
    for ok in (cfg, replace(cfg, cpu=DEFAULT_COSTS)):
        idle = World(ok)
        idle.run()
        assert idle.quiet_ring.leaps >= 1
    for other in (replace(cfg, realtime=True), replace(cfg, can=True, cpu=DEFAULT_COSTS)):
        assert World(other).quiet_ring is None
    assert World(replace(cfg, cpu=DEFAULT_COSTS), on_event=lambda ev: None).quiet_ring is None
    # a trace keeps the CAN sides awake (QuietCan.may_sleep): the ring could never leap
    assert World(replace(cfg, can=True), on_event=lambda ev: None).quiet_ring is None
    assert World(replace(cfg, can=True)).quiet_ring is not None


def test_on_the_cpu_model_a_childs_can_and_radio_handlers_meet():
    """Why no ring leap on the CPU model with CAN sides: a child's CAN receive handlers (its
    sleeping side's ghosts too, hil/sim/can_ghosts.py) and its radio handlers share one CPU
    and meet there, each meeting moving the latencies of both, at ticks no ring cycle repeats
    (docs/performance.md)."""
    w = World(SimConfig(robots=RING, duration=20, seed=1, can=True, cpu=DEFAULT_COSTS))
    w.run()
    met = {r: sum(n for lat, n in cpu.stats["CAN0 RX"].latency.items() if lat > 0)
           for r, cpu in w.cpus.items()}
    assert sum(met.values()) >= 20, met       # about 0.6 a second a child: some 70 expected


def test_no_leap_while_a_hook_of_someone_elses_sees_the_frames():
    """A hook on the air's transmissions or on a station's actions (a benchmark's, a test's)
    would miss the frames leapt over: it sees every one of them instead."""
    cfg = SimConfig(robots=(0, 1, 2), duration=30, seed=18)
    plain = World(replace(cfg, ring_sleep=False))
    plain.run()
    hooked = World(cfg)
    ends = []
    world_hook = hooked.air.on_transmission

    def both(tx):
        ends.append(tx.end)
        world_hook(tx)
    hooked.air.on_transmission = both
    hooked.run()
    assert hooked.quiet_ring.leaps == 0 and len(ends) == plain.transmissions
    observed = World(cfg)
    st = observed.stations[1]
    st.add_observer(lambda *a: None)
    observed.run()
    assert observed.quiet_ring.leaps == 0
    unhooked = World(cfg)
    unhooked.run()
    assert unhooked.quiet_ring.leaps >= 1


def test_state_a_snapshot_cannot_see_stops_the_leaps_not_the_run():
    """Something in the world whose state hides from a snapshot (an iterator, a foreign
    object) ends the ring's leaps; the run goes on frame by frame, the same run."""
    cfg = SimConfig(robots=(0, 1, 2), duration=30, seed=19)
    plain = World(replace(cfg, ring_sleep=False))
    plain.run()
    for hidden in (iter(range(3)), __import__("collections").deque([1])):
        w = World(cfg)
        w.stations[1].mac.extra = hidden
        w.run()
        assert not w.quiet_ring.enabled and w.quiet_ring.leaps == 0
        assert w.summary() == plain.summary()


def test_a_leap_moves_ticks_inside_tuples():
    """A tick held in a tuple (a MAC's ``_last_heard``, an event's arguments) moves with the
    rest: the tuple is replaced in its holder."""

    h = {"pair": (3, 100), "nested": {"k": (1, (2, 500))}, "same": (7, 7)}
    a = snapshot([h])
    h["pair"] = (3, 110)
    h["nested"]["k"] = (1, (2, 510))
    b = snapshot([h])
    steps = period_steps(a, b, 10, frozenset())
    moved = writable(b, steps)
    assert len(moved) == 2 and {type(holder) for holder, _, _ in moved} == {InTuple}
    advance(moved, 5)
    assert h == {"pair": (3, 160), "nested": {"k": (1, (2, 560))}, "same": (7, 7)}
    # a tuple that is itself a root has no holder to be written in: not periodic
    assert period_steps(snapshot([(1, 100)]), snapshot([(1, 110)]), 10, frozenset()) is None


def test_scheduler_refuses_to_skip_over_an_event():
    s = SimScheduler()
    s.at(100, lambda: None)
    with pytest.raises(ValueError, match="event is due at tick 100"):
        s.skip_to(101)
    s.skip_to(100)
    assert s.now == 100
    with pytest.raises(ValueError):
        s.skip_to(50)


def test_the_period_holds_whole_rounds_of_pc2_checks():
    """With the standby PC the MAC reads ``turns`` modulo 7: a period must be a multiple of
    28 anchor turns; without it, 4 (whole polling rounds)."""
    assert World(SimConfig(robots=(0, 1), father_standby=True)).quiet_ring.every == 28
    assert World(SimConfig(robots=(0, 1))).quiet_ring.every == 4
    assert isinstance(World(SimConfig(robots=(1, 2))).quiet_ring, QuietRing)


@pytest.mark.parametrize("cfg", [
    SimConfig(robots=(0, 1, 2, 3), duration=300, seed=22, faults=F("fail:3@5")),
    SimConfig(robots=(0, 1, 2), duration=300, seed=23, can=True, faults=F("fail:0@5")),
    SimConfig(robots=(0, 1, 2, 3), duration=300, seed=24, father_standby=True,
              faults=F("fail:0@8")),
], ids=["a child", "the father, CAN sides", "PC1 beside its standby"])
def test_a_robot_gone_for_good_leaps_over_its_own_cycles(cfg):
    """A deaf robot's MAC claims the silent channel and keeps a cycle of its own: carried
    across the ring's leaps, it leaps over its own cycles too, and both worlds are the
    frame-by-frame run at every stop."""
    plain, leaping = _twins(cfg)
    for s in (4.9, 30.0, 222.2, 300):
        for w in (plain, leaping):
            w.run(until=s_to_ticks(s))
        assert _state(leaping) == _state(plain), f"the worlds differ at {s} s"
    assert json.dumps(leaping.summary(), sort_keys=True) == \
        json.dumps(plain.summary(), sort_keys=True)
    ring = leaping.quiet_ring
    assert ring.ticks_skipped > 0.9 * leaping.now
    assert ring.alone_ticks_skipped > 0.8 * leaping.now


def _module_containers() -> dict[int, str]:
    """Every dict, list, set and bytearray at module level in the model's packages (and the
    dicts directly inside a module-level dict): caches every world of the process shares."""
    import sys
    out = {}
    for name, mod in list(sys.modules.items()):
        if name.split(".")[0] not in ("firmware_model", "can_bus", "hil"):
            continue
        for attr, v in list(vars(mod).items()):
            inner = list(v.values()) if isinstance(v, dict) else []
            for i, x in enumerate([v, *inner]):
                if isinstance(x, (dict, list, set, bytearray)):
                    out[id(x)] = f"{name}.{attr}" + (f"[{i - 1}]" if i else "")
    return out


def test_the_snapshots_walk_no_cache_the_worlds_of_a_process_share(monkeypatch):
    """A snapshot walked the deframers' cache of whole frames, one dict for the process: a
    campaign's Dask worker runs two worlds on two threads, and one world's snapshot broke
    with "dictionary changed size during iteration" while the other added a frame to it
    (tests/hil/test_campaign.py, test_a_broken_run_is_recorded_and_reported_not_lost, failed so
    now and then, more often with the CPU loaded). What a snapshot walks is one world's own
    state."""
    import hil.sim.quiet_can as quiet_can
    import hil.sim.quiet_ring as quiet_ring
    walked: dict[int, object] = {}

    def spy(*args, **kw):
        snap = snapshot(*args, **kw)
        walked.update((id(x), x) for x in snap.alive)
        return snap

    monkeypatch.setattr(quiet_ring, "snapshot", spy)
    monkeypatch.setattr(quiet_can, "snapshot", spy)
    for cfg in (SimConfig(robots=(0, 1, 2), duration=30, seed=3, load=0.5),
                SimConfig(robots=(0, 1, 2), duration=30, seed=4, can=True)):
        World(cfg).run()
    assert len(walked) > 100                       # the leaps took their snapshots
    shared = _module_containers()
    assert [shared[i] for i in walked if i in shared] == []


def test_a_loaded_rings_snapshots_leave_its_records_out_and_back_off():
    """A 2-robot ring at a message a second never repeats itself for long: its probes used to
    snapshot the whole world, run records included (the ledger's messages, outcomes and
    deliveries grow all run), so each snapshot cost more as the run went on, and a period
    found between two messages reset the backoff though no leap fitted before the next one.
    The default mode took 18.9 s for 480 simulated s against 1.4 s frame by frame. Now a
    snapshot leaves the records out (``World.records``: only what the MACs report grows
    them, and that stops the probes first), and a leap shorter than ``MIN_LEAP_TICKS`` is a
    miss: the snapshots stay as small late in the run as early, and few."""
    from hil.sim import quiet_ring as qr

    sizes: list[int] = []
    real = qr.snapshot

    def counted(*args, **kw):
        snap = real(*args, **kw)
        sizes.append(len(snap.shape))
        return snap
    # a message each 10 s a robot on average: the probes snapshot between messages (8 s
    # of quiet: LOADED_LEAP_TICKS)
    w = World(SimConfig(robots=(1, 2), duration=960, seed=1, load=0.1, keep_records=True))
    import firmware_model.radio.mac_frames as frames
    cache_max, frames.HB_CACHE_MAX = frames.HB_CACHE_MAX, 8    # bounded: full early on
    qr.snapshot = counted
    try:
        w.run(s_to_ticks(480))
        early = list(sizes)
        w.run()
    finally:
        qr.snapshot = real
        frames.HB_CACHE_MAX = cache_max
    assert len(w.messages) > 150 and early and len(sizes) > len(early)   # records grew all run
    # the second half of the run: the same size (a MAC's heartbeat cache, bounded, is all
    # that grew in the first)
    assert max(sizes) <= 1.1 * max(early), (max(early), max(sizes))
    assert len(sizes) < 100, len(sizes)                    # about one in 64 probes, at most


def test_a_probe_takes_no_snapshot_while_the_loads_next_message_is_near():
    """The load's next arrival (``Load.next_arrival``) is no event a period moves: while it
    is due within ``LOADED_LEAP_TICKS`` no leap could pay for its snapshots, so the probe
    takes none (and asks the load, not the scheduler's whole heap)."""
    from hil.sim import quiet_ring as qr

    w = World(SimConfig(robots=(1, 2), duration=480, seed=1, load=0.1))
    taken: list[tuple[int, int | None]] = []
    real = qr.snapshot

    def watched(*args, **kw):
        taken.append((w.sched.now, w.load.next_arrival()))
        return real(*args, **kw)
    qr.snapshot = watched
    try:
        w.run()
    finally:
        qr.snapshot = real
    assert taken and len(taken) == w.quiet_ring.probes
    assert all(due is None or due >= now + qr.LOADED_LEAP_TICKS for now, due in taken), taken
    assert w.quiet_ring.leaps > 0


def test_a_leap_stops_where_a_standby_pc_fails_what_it_held():
    """A soak's seed 39 (an outside check): PC1's radio died with messages queued, came back
    and stood by holding them; the idle ring then leapt across their 60 s, and they failed
    "expired" up to 145 s after they were submitted, where the frame-by-frame run fails them
    at 60 s (a standby fails what is too old on the frames it hears: no event says when)."""
    from hil.sim import events as E
    from hil.sim.faults import Fault
    cfg = SimConfig(robots=(0, 1, 2), duration=120.0, seed=0, load=2.0, load_until=8.0,
                    father_standby=True, mac=MacConfig(checksum=True),
                    faults=(Fault("fail", 0, 5.0), Fault("recover", 0, 7.6)))
    ends = {}
    for leap in (False, True):
        w = World(replace(cfg, ring_sleep=leap))
        got = ends[leap] = []
        w.add_listener(lambda ev, got=got: got.append((ev.t, ev.num, ev.reason))
                       if isinstance(ev, E.Failed) and ev.src == 0 else None)
        w.run()
        if leap:
            assert w.quiet_ring.leaps > 0                 # (it does leap, before and after)
    late = [f for f in ends[False] if f[2].startswith("expired")]
    assert len(late) >= 3 and all(t < s_to_ticks(68) for t, _, _ in late)
    assert ends[True] == ends[False]

"""The rotational MAC in the simulated world: the paper's scenarios, timed to the tick."""
from __future__ import annotations

import random

import pytest

from firmware_model.radio.content import cmd
from firmware_model.radio.mac import MacConfig, SubmitError
from firmware_model.timing import (
    CHILD_BYTE_TICKS, PC_BYTE_TICKS, TICK_HZ, TMAX_TICKS, TTRANS_TICKS, s_to_ticks,
)
from hil.sim.world import Fault, SimConfig, World
from contents import content_of

MAC = MacConfig()


def run(robots=(1, 2, 3, 4), duration=10.0, until=None, **kw):
    evs: list[dict] = []
    w = World(SimConfig(robots=robots, duration=duration, **kw), on_event=evs.append)
    w.run(until)
    return w, evs


def frames(evs, after=0):
    return [e for e in evs if e["ev"] == "frame" and e["start"] >= after]


def formed_at(evs, robots):
    """Tick from which every robot is a member of a ring holding all of them."""
    views = {r: set() for r in robots}
    t_all = None
    for e in evs:
        if e["ev"] in ("join", "rejoin"):
            views[e["by"]].add(e["robot"])
        elif e["ev"] == "disable":
            views[e["by"]].discard(e["robot"])
        elif e["ev"] == "mode":
            views[e["robot"]] = {e["robot"]} if e["mode"] == "member" else set()
            if e["mode"] == "member" and e["reason"].startswith("invited"):
                views[e["robot"]] = None  # learnt from the poll mask: known complete
        ok = all(v is None or v >= set(robots) for v in views.values()) and all(
            v is not None or True for v in views.values())
        if ok and t_all is None and e["ev"] != "meta":
            t_all = e.get("t", -1)
        elif not ok:
            t_all = None
    return t_all


def test_idle_turns_are_frame_bytes_times_16640_plus_ttrans():
    w, evs = run(duration=8.0)
    assert all(v == (1, 2, 3, 4) for v in w.ring_views().values())
    fs = frames(evs, after=s_to_ticks(4.0))
    assert len(fs) > 40
    for a, b in zip(fs, fs[1:]):
        assert a["len"] == 0 and a["bytes"] == 14          # heartbeats: Type '3', dst '7'
        assert (a["type"], a["dst"]) == (3, 7)
        assert b["start"] - a["start"] == 14 * CHILD_BYTE_TICKS + TTRANS_TICKS == 312_960
        assert b["src"] == {1: 2, 2: 3, 3: 4, 4: 1}[a["src"]]
    # four robots: 78.24 ms a cycle (docs/protocol.md §7.2)
    ones = [f for f in fs if f["src"] == 1]
    assert ones[1]["start"] - ones[0]["start"] == 4 * 312_960 == s_to_ticks(0.07824)


@pytest.mark.parametrize("cpu,txen,header", [(None, 0, TTRANS_TICKS),
                                              ("estimated", 834, TTRANS_TICKS + 1_142)])
def test_the_hand_over_on_each_cpu_is_the_same_every_turn(cpu, txen, header):
    """docs/protocol.md clause 23: on the ideal CPU the next owner raises TXEN at E and
    begins its Header at E + Ttrans to the tick; on the MB90F549 model it learns of E when the
    End's receive handler has run (TXEN at E + 834 ticks) and its timer's handler writes the
    first byte Ttrans after TXEN and its own entry and body later (E + 81,142): an idle turn
    of 314,102 ticks (19.63 ms, §7.2), every turn."""
    from firmware_model.cycle_costs import DEFAULT_COSTS
    kw = {} if cpu is None else {"cpu": DEFAULT_COSTS}
    _, evs = run(robots=(1, 2, 3), duration=6.0, **kw)
    after = s_to_ticks(3.0)
    fs = frames(evs)
    assert not any(f["collided"] for f in fs)
    ends = [f["end"] for f in fs]
    # each TXEN from the last End at or before it (at one tick the frame's event may follow)
    txens = [e["t"] - max(x for x in ends if x <= e["t"]) for e in evs
             if e["ev"] == "txen" and e["on"] and e["t"] >= after]
    turns = [(b["start"] - a["end"], b["end"] - a["end"]) for a, b in zip(fs, fs[1:])
             if b["start"] >= after]
    assert len(turns) > 100 and len(txens) > 100
    assert set(txens) == {txen} and {t[0] for t in turns} == {header}
    assert {t[1] for t in turns} == {header + 14 * CHILD_BYTE_TICKS}
    assert (header + 14 * CHILD_BYTE_TICKS) * 1_000_000 // TICK_HZ == \
        (19_560 if cpu is None else 19_631)           # µs: §7.2's idle turn on each CPU


def test_father_turn_uses_the_pc_uart_byte_time():
    w, evs = run(robots=(0, 1, 2), duration=8.0)
    fs = frames(evs, after=s_to_ticks(5.0))
    for a, b in zip(fs, fs[1:]):
        bt = PC_BYTE_TICKS if a["src"] == 0 else CHILD_BYTE_TICKS
        assert b["start"] - a["start"] == a["bytes"] * bt + TTRANS_TICKS


def _last_frame_of(evs, src, before):
    return [f for f in frames(evs) if f["src"] == src and f["end"] <= before][-1]


def test_paper_simulation_r1_dies_three_misses_then_dropped():
    """Paper §V.A / Fig. 9: four robots; R1 fails; after exactly three missed turns every
    member drops it at the same tick and the ring is R2 -> R3 -> R4."""
    probe, pevs = run(duration=5.0)
    e1 = _last_frame_of(pevs, 1, s_to_ticks(5.0))["end"]
    # R1's radio dies just after one of its turns, so the next three are missed.
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 3, 4), duration=12.0), on_event=evs.append)
    w.inject("fail", 1, e1 + 1)
    w.run()
    after = [e for e in evs if e.get("t", -1) > e1]
    misses = [e for e in after if e["ev"] == "miss" and e["robot"] == 1]
    disables = [e for e in after if e["ev"] == "disable"]
    assert {e["by"] for e in disables} == {2, 3, 4} and {e["robot"] for e in disables} == {1}
    t_drop = disables[0]["t"]
    assert all(e.get("t", -1) == t_drop for e in disables)    # every member at the same tick
    for observer in (2, 3, 4):
        mine = [e.get("t", -1) for e in misses if e["by"] == observer and e.get("t", -1) <= t_drop]
        assert len(mine) == 3                                   # exactly three misses
    miss_ticks = sorted({e.get("t", -1) for e in misses if e.get("t", -1) <= t_drop})
    assert miss_ticks[-1] == t_drop
    fs = frames(evs, after=e1)
    for t_miss in miss_ticks:
        # E = end of R4's frame before R1's turn; the miss is at E + Tmax, and R2 takes over
        # at E + Tmax + Ttrans, to the tick.
        e4 = max(f["end"] for f in fs if f["src"] == 4 and f["end"] < t_miss)
        assert t_miss == e4 + TMAX_TICKS
        nxt = min((f for f in fs if f["start"] > t_miss), key=lambda f: f["start"])
        assert nxt["src"] == 2 and nxt["start"] == e4 + TMAX_TICKS + TTRANS_TICKS
    # afterwards the ring is R2 -> R3 -> R4 in everybody's view, and R1 is never waited for
    later = frames(evs, after=t_drop + s_to_ticks(0.5))
    assert {f["src"] for f in later} == {2, 3, 4}
    assert [w.ring_views()[r] for r in (2, 3, 4)] == [(2, 3, 4)] * 3
    assert not [e for e in evs if e["ev"] == "miss" and e.get("t", -1) > t_drop and e["by"] != 1]


def test_two_silent_robots_take_over_at_e_plus_2_tmax():
    probe, pevs = run(duration=5.0)
    e2 = _last_frame_of(pevs, 2, s_to_ticks(5.0))["end"]
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 3, 4), duration=7.0), on_event=evs.append)
    w.inject("fail", 3, e2 + 1)
    w.inject("fail", 4, e2 + 1)
    w.run()
    nxt = frames(evs, after=e2)[0]
    assert nxt["src"] == 1 and nxt["start"] == e2 + 2 * TMAX_TICKS + TTRANS_TICKS
    live = [e for e in evs if e["ev"] == "miss" and e["by"] in (1, 2) and e["t"] < nxt["start"]]
    assert sorted((e["t"], e["robot"]) for e in live) == [
        (e2 + TMAX_TICKS, 3), (e2 + TMAX_TICKS, 3),
        (e2 + 2 * TMAX_TICKS, 4), (e2 + 2 * TMAX_TICKS, 4)]


def predicted_claims(robots, power):
    """The first claim of a silent channel, from the rule alone (docs/mac.md, start-up): robot
    r powered on at p_r claims at p_r + |team| x Tmax + r x Tslot unless it has heard a frame
    in progress by then. The earliest claimer raises TXEN at t1; the next claimer collides
    with it iff its own claim comes before t1's Header is complete (Ttrans + 3 bytes later).
    Returns (first claimer, t1, collides)."""
    n = len(robots)
    claims = sorted((s_to_ticks(p) + n * MAC.tmax + r * MAC.tslot, r) for r, p in power.items())
    (t1, r1), (t2, _) = claims[0], claims[1]
    byte = PC_BYTE_TICKS if r1 == 0 else CHILD_BYTE_TICKS
    return r1, t1, t2 < t1 + MAC.ttrans + 3 * byte


FORM_BOUND_S = 1.0
"""A ring of up to 7 robots is whole within this long after the later of the first claim and
the last power-on (measured worst 0.85 s over 200 random orders, docs/mac.md)."""


@pytest.mark.parametrize("seed", list(range(24)) + [41, 44])   # 41 and 44 collide
def test_startup_in_random_power_on_orders(seed):
    rng = random.Random(seed)
    robots = tuple(sorted(rng.sample(range(7), rng.randint(2, 7))))
    power = {r: round(rng.uniform(0.0, 3.0), 6) for r in robots}
    last = s_to_ticks(max(power.values()))
    w, evs = run(robots=robots, duration=max(power.values()) + 6.0, power_on=power)
    first, t1, collides = predicted_claims(robots, power)
    tx = [e for e in evs if e["ev"] == "txen" and e["on"]]
    assert (tx[0]["robot"], tx[0]["t"]) == (first, t1)          # to the tick
    cols = [e for e in evs if e["ev"] == "collision"]
    assert len(cols) == (1 if collides else 0), (robots, power, cols)
    views = w.ring_views()
    assert all(v == robots for v in views.values()), (robots, power, views)
    joined = max(e.get("t", -1) for e in evs if e["ev"] in ("join", "rejoin", "mode"))
    assert joined - max(t1, last) <= s_to_ticks(FORM_BOUND_S)
    assert not [e for e in evs if e["ev"] == "disable"]


def test_simultaneous_claims_collide_once_and_recover():
    # Robot 1 powers on one Tslot after robot 2: both claim the silent channel at the same tick.
    w, evs = run(robots=(1, 2), duration=8.0,
                 power_on={1: MAC.tslot / TICK_HZ, 2: 0.0})
    cols = [e for e in evs if e["ev"] == "collision"]
    assert len(cols) == 1
    assert w.ring_views() == {1: (1, 2), 2: (1, 2)}
    assert max(f["start"] for f in frames(evs)) > cols[0]["t"] + s_to_ticks(4.0)


def test_forced_collision_recovers_without_dropping_anyone():
    probe, pevs = run(duration=5.0)
    e1 = _last_frame_of(pevs, 1, s_to_ticks(5.0))["end"]
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 3, 4), duration=9.0), on_event=evs.append)
    w.inject("steal", 3, e1)      # R3 wrongly believes it owns the turn R2 now starts
    w.run()
    cols = [e for e in evs if e["ev"] == "collision"]
    assert len(cols) == 1 and cols[0]["robots"] == [2, 3]
    assert not [e for e in evs if e["ev"] in ("disable", "mode") and e.get("t", -1) > e1]
    assert all(v == (1, 2, 3, 4) for v in w.ring_views().values())
    # the ring is back in order within 2 Tmax + a cycle
    clean = [f for f in frames(evs, after=cols[0]["t"]) if not f["collided"]]
    assert clean[0]["start"] <= cols[0]["t"] + 2 * MAC.tmax + 4 * 312_960
    seq = [f["src"] for f in clean[-12:]]
    assert all(b == {1: 2, 2: 3, 3: 4, 4: 1}[a] for a, b in zip(seq, seq[1:]))


def test_rejoin_of_a_recovered_robot_within_bound():
    w, evs = run(duration=20.0, faults=(Fault("fail", 2, 5.0), Fault("recover", 2, 11.0)))
    drops = [e for e in evs if e["ev"] == "disable" and e["robot"] == 2]
    assert {e["by"] for e in drops} == {1, 3, 4}
    back = [e for e in evs if e["ev"] == "rejoin" and e["robot"] == 2]
    assert {e["by"] for e in back} == {1, 3, 4}
    t_back = min(e.get("t", -1) for e in back)
    # bound (docs/mac.md): a lone pause + poll_every turns of its predecessor + one window
    assert s_to_ticks(11.0) < t_back <= s_to_ticks(11.0) + s_to_ticks(2.0)
    assert all(v == (1, 2, 3, 4) for v in w.ring_views().values())


@pytest.mark.parametrize("ber", [1e-3, 1e-2])
def test_delivery_accounting_under_byte_errors_with_checksum(ber):
    """With the checksum extension: every message ends delivered or failed with a reason,
    nothing is delivered twice, to the wrong robot, or corrupted."""
    w, evs = run(robots=(0, 1, 2, 3, 4), duration=120.0, seed=3, ber=ber, load=2.0,
                 load_until=45.0, mac=MacConfig(checksum=True))
    s = w.summary()
    assert s["submitted"] > 200
    assert s["pending"] == 0
    assert s["submitted"] == s["delivered"] + s["failed"]
    assert s["duplicate_deliveries"] == 0
    assert s["corrupt_deliveries"] == 0
    for e in evs:
        if e["ev"] == "deliver":
            assert e["dst"] in (e["to"], 7) and e["src"] != e["to"] and e["intact"]
        if e["ev"] == "fail":
            assert e["reason"]
    # every acknowledged unicast was delivered at its destination
    got = {(e["src"], e["num"], e["to"]) for e in evs if e["ev"] == "deliver"}
    for e in evs:
        if e["ev"] == "delivered" and e["dst"] != 7:
            assert (e["src"], e["num"], e["dst"]) in got
    if ber <= 1e-3:
        assert s["failed"] == 0


def test_paper_format_accounting_under_byte_errors():
    """Without the checksum (the paper's frame) accounting still closes, but a corrupted frame
    can be acted on: the world counts those deliveries from ground truth."""
    w, evs = run(robots=(0, 1, 2, 3, 4), duration=120.0, seed=3, ber=5e-3, load=2.0,
                 load_until=45.0)
    s = w.summary()
    assert s["pending"] == 0 and s["submitted"] == s["delivered"] + s["failed"]
    assert s["corrupt_deliveries"] == sum(1 for e in evs if e["ev"] == "deliver"
                                          and not e["intact"]) > 0


def test_saturated_ring_delivers_full_size_messages():
    w, evs = run(robots=(1, 2, 3), duration=40.0, load="saturate")
    s = w.summary()
    assert s["delivered"] > 10 and s["duplicate_deliveries"] == 0
    sizes = [f["bytes"] for f in frames(evs, after=s_to_ticks(5.0))]
    assert max(sizes) <= 576 and max(sizes) >= 500


def test_submission_refuses_a_frame_longer_than_tmax():
    w = World(SimConfig(robots=(0, 1, 2), duration=1.0))
    child, father = w.stations[1], w.stations[0]
    child.submit(2, content_of(562))                       # 576 bytes x 16640 <= Tmax
    father.submit(1, content_of(561))                      # 575 bytes x 16667 <= Tmax
    with pytest.raises(SubmitError, match="577-byte frame"):
        child.submit(2, content_of(563))
    with pytest.raises(SubmitError, match="576-byte frame"):
        father.submit(1, content_of(562))
    with pytest.raises(SubmitError, match="destination"):
        child.submit(1, [cmd("stop")])                      # to itself
    with pytest.raises(SubmitError, match="MAC command"):
        child.submit(2, [cmd("ack", 1, 5)])
    with pytest.raises(SubmitError, match="an empty Content is a heartbeat"):
        child.submit(2, [])       # was queued, sent as a heartbeat and failed unacknowledged
    with pytest.raises(SubmitError, match="an empty Content is a heartbeat"):
        w.submit(1, 2, [])
    for reserved in (5, 6, 7, 9):                           # BOOT, JOIN, reserved
        with pytest.raises(SubmitError, match="Type must be 0-4"):
            child.submit(2, [cmd("stop")], type=reserved)


def test_same_seed_same_trace_bytes(tmp_path):
    from hil.sim.trace import TraceWriter
    paths = []
    for i in range(2):
        p = tmp_path / f"t{i}.jsonl"
        tw = TraceWriter(str(p))
        w = World(SimConfig(robots=(0, 1, 2, 3), duration=20.0, seed=11, ber=2e-3, noise=True,
                            load=3.0, faults=(Fault("fail", 2, 6.0), Fault("recover", 2, 12.0))),
                  tw)
        w.run()
        tw.close()
        paths.append(p.read_bytes())
    assert paths[0] == paths[1] and len(paths[0]) > 10_000
    tw = TraceWriter(str(tmp_path / "other.jsonl"))
    w = World(SimConfig(robots=(0, 1, 2, 3), duration=20.0, seed=12, ber=2e-3, noise=True,
                        load=3.0), tw)
    w.run()
    tw.close()
    assert (tmp_path / "other.jsonl").read_bytes() != paths[0]


@pytest.mark.parametrize("ber,noise", [(0.0, False), (3e-3, False), (3e-3, True)])
def test_batched_delivery_equals_byte_by_byte(ber, noise):
    def trace(bb):
        evs: list[dict] = []
        w = World(SimConfig(robots=(0, 1, 2, 3), duration=25.0, seed=5, ber=ber, noise=noise,
                            load=3.0, byte_by_byte=bb,
                            faults=(Fault("fail", 1, 7.3), Fault("recover", 1, 14.1))),
                  on_event=evs.append)
        w.inject("steal", 3, s_to_ticks(18.0))
        w.run()
        return evs
    fast, slow = trace(False), trace(True)
    assert len(fast) > 500
    assert fast == slow


def test_batched_delivery_equals_byte_by_byte_when_a_frame_stops_in_a_random_world():
    """A world of scripts/sleep_hunt.py (7 robots with CAN sides, the standby father, fail and
    recover, noise, bursts, byte errors) where a frame's bytes stop and the stall timer ends
    it: the timer is programmed by its last byte's handler, which the ideal CPU runs at that
    byte's tick, also when the byte came in a burst; programmed at the burst's tick instead, it
    rounded its expiry (machine clock / 2) the other way and a miss 57 s in came a tick late."""
    from dataclasses import replace as _replace
    from hunt import sleep_hunt
    cfg, _, _ = sleep_hunt().random_world(20)
    cfg = _replace(cfg, duration=60)

    def trace(bb):
        evs: list[dict] = []
        World(_replace(cfg, byte_by_byte=bb), on_event=evs.append).run()
        return evs
    fast, slow = trace(False), trace(True)
    assert any(e["ev"] == "miss" and e["t"] == 910_921_868 for e in slow)
    assert fast == slow


def test_batched_delivery_equals_byte_by_byte_after_a_burst_of_interference():
    """A world of scripts/sleep_hunt.py with bursts of interference (foreign bytes, no frame):
    the MAC hears their garbage byte by byte and polls for a quiet channel, so the air hands
    them over at their ticks, not in one burst at their end; in one burst, the father's MAC
    went quiet only at the burst's end, programmed its timer from there and raised TXEN a
    tick early 41.8 s in."""
    from dataclasses import replace as _replace
    from hunt import sleep_hunt
    cfg, _, _ = sleep_hunt().random_world(71)
    cfg = _replace(cfg, duration=45, cpu=None)

    def trace(bb):
        evs: list[dict] = []
        World(_replace(cfg, byte_by_byte=bb), on_event=evs.append).run()
        return evs
    fast, slow = trace(False), trace(True)
    assert any(e["ev"] == "txen" and e["robot"] == 0 and e["t"] == 669_656_392 for e in slow)
    assert fast == slow


def test_father_failover_takes_id0s_turn_without_a_miss():
    """Paper §III.A: PC1 and PC2 back each other up. PC2 (hot standby) takes ID 0's turn when
    PC1 dies, before anyone misses it; PC1, back, becomes the standby."""
    evs: list[dict] = []
    w = World(SimConfig(robots=(0, 1, 2, 3), duration=26.0, father_standby=True, load=1.0,
                        faults=(Fault("fail", 0, 10.0), Fault("recover", 0, 18.0))),
              on_event=evs.append)
    w.run()
    fail_t = s_to_ticks(10.0)
    takeover = [e for e in evs if e["ev"] == "mode" and e.get("pc") == 2 and "took over" in
                e["reason"]]
    assert len(takeover) == 1 and fail_t < takeover[0]["t"] < fail_t + s_to_ticks(0.5)
    # nobody who can hear misses robot 0, and robot 0 is never dropped
    assert not [e for e in evs if e["ev"] == "miss" and e["robot"] == 0 and e["by"] != 0]
    assert not [e for e in evs if e["ev"] == "disable" and e["robot"] == 0]
    # ID 0's turn came right after robot 3's, later only by PC2's watch: 2 Ttrans + 4 x 4
    # bytes (MacConfig: a standby waits (pc + 2) x 4 bytes past 2 Ttrans), then its Ttrans
    fs = frames(evs, after=fail_t)
    first0 = next(f for f in fs if f["src"] == 0)
    before = max(f["end"] for f in frames(evs) if f["end"] < first0["start"])
    assert first0["start"] == before + 3 * TTRANS_TICKS + 4 * 4 * PC_BYTE_TICKS
    assert sum(1 for f in fs if f["src"] == 0) > 100
    # PC1 back: it hears ID 0 on the air and stands by
    back = [e for e in evs if e["ev"] == "mode" and e.get("pc") is None and e["robot"] == 0
            and e["t"] > s_to_ticks(18.0)]
    assert any("standing by" in e["reason"] for e in back)
    assert w.stations[0].mac.standby and not w.standby_station.mac.standby
    s = w.summary()
    assert s["duplicate_deliveries"] == 0
    assert s["submitted"] == s["delivered"] + s["failed"] + s["pending"]


@pytest.mark.parametrize("robots,back,kw", [
    ((1, 4), 4, dict(power_on={4: 1.0}, duration=8.0, seed=0,
                     faults=(Fault("fail", 4, 1.5), Fault("recover", 4, 3.6)))),
    ((0, 4), 4, dict(duration=10.0, seed=2,
                     faults=(Fault("fail", 4, 3.933), Fault("recover", 4, 5.879))))])
def test_a_ring_of_two_takes_back_its_member_without_counting_the_healthy_one_missing(
        robots, back, kw):
    """docs/protocol.md §8.2 and clause 37: the robot whose radio comes back with fewer than
    three misses counted still holds the ring of two, and hears its only other member, alone,
    invite it. It answered nothing (a lone claimer's mask "says nothing about our ring"),
    sent a frame into the window, sent the healthy claimer to LISTEN and counted it missing
    three times. Now it goes to LISTEN and answers at once."""
    _, evs = run(robots=robots, **kw)
    healthy = next(r for r in robots if r != back)
    recovered = next(e["t"] for e in evs if e["ev"] == "fault" and e.get("kind") == "recover")
    after = [e for e in evs if e.get("t", -1) >= recovered]
    assert [e for e in after if e["ev"] in ("miss", "disable") and e["robot"] == healthy] == []
    assert [e for e in after if e["ev"] == "mode" and e["robot"] == healthy] == []
    rejoined = [e for e in after if e["ev"] == "rejoin" and e["robot"] == back]
    assert rejoined and rejoined[0]["t"] - recovered < 16_000_000 // 2     # within 0.5 s

"""hil/sim/ledger.py, the accounting the invariants are checked on, on its own: a delivery is
checked against what its sender submitted (a Number that wrapped, a corrupted command, a robot
it was not for), a missed turn is counted once however many robots saw it, and a membership
change is listed once."""
from __future__ import annotations

import dataclasses
import json

import pytest

from firmware_model.radio.content import cmd
from firmware_model.radio.frame import BROADCAST
from firmware_model.radio.mac import Deliver, Message, Outcome
from hil.sim.ledger import KEYED, RETIRE_TICKS, Ledger


def message(src: int, dst: int, num: int, x: int) -> Message:
    return Message(src, dst, num, 2, (cmd("movex", x),), b"", 0)


def deliver(m: Message, commands=None) -> Deliver:
    return Deliver(m.src, m.dst, m.num, m.type, m.commands if commands is None else commands)


@pytest.mark.parametrize("keep", [True, False])
def test_a_delivery_is_checked_against_what_its_sender_submitted(keep):
    led = Ledger((1, 2, 3), keep=keep)
    first, again = message(1, 2, 5, 10), message(1, 2, 5, 20)   # Number 5 again (it wrapped)
    led.submitted(first)
    led.submitted(again)
    assert led.delivered_to(deliver(again), 2)
    assert led.delivered_to(deliver(again), 2)                  # the same message twice
    assert led.delivered_to(deliver(first), 2)
    assert led.duplicate_deliveries == 1
    assert led.deliveries == ({(1, 5, 2, 2): 2, (1, 5, 1, 2): 1} if keep else None)
    assert not led.delivered_to(deliver(first, (cmd("movex", 11),)), 2)   # corrupted
    assert led.corrupt_deliveries == 1 and led.wrong_deliveries == 0
    assert led.delivered_to(deliver(first), 3)                  # not for robot 3
    assert led.wrong_deliveries == 1
    bcast = message(2, BROADCAST, 1, 1)
    led.submitted(bcast)
    assert led.delivered_to(deliver(bcast), 3) and led.wrong_deliveries == 1
    assert led.stats[2].received == 4 and led.stats[3].received == 2
    assert led.stats[1].submitted == 2 and led.stats[2].submitted == 1
    assert led.intact(deliver(first)) and not led.intact(deliver(first, ()))
    assert led.stats[2].received == 4                           # intact() counts nothing


def test_only_the_latest_messages_of_a_number_are_kept():
    led = Ledger((1, 2))
    old = message(1, 2, 7, 0)
    led.submitted(old)
    for x in range(1, KEYED + 1):
        led.submitted(message(1, 2, 7, x))
    assert not led.intact(deliver(old))
    assert led.intact(deliver(message(1, 2, 7, 1)))


def test_how_a_message_ended_is_counted_at_its_sender():
    led = Ledger((1, 2), keep=True)
    m = message(1, 2, 1, 0)
    m.state = "delivered"
    assert led.ended(Outcome(m, True, ""), 16_000 * 37 + 15_999) == "delivered"
    u = message(1, 2, 2, 0)
    u.state = "unacknowledged"
    assert led.ended(Outcome(u, False, "paper profile"), 10**9) == "sent"
    f = message(2, 1, 1, 0)
    f.state = "failed"
    assert led.ended(Outcome(f, False, "retries"), 10**9) == "fail"
    s1, s2 = led.stats[1], led.stats[2]
    assert (s1.delivered, s1.unacknowledged, s1.failed, s2.failed) == (1, 1, 0, 1)
    assert len(led.outcomes) == 3
    # submitted at tick 0: 37.999 ms later, in the 37 ms bin; only delivered ones counted
    assert led.latency_ms == {37: 1}


def test_a_miss_and_a_membership_change_count_once_however_many_saw_them():
    led = Ledger((1, 2, 3))
    for _ in range(2):                       # robots 1 and 3 both saw robot 2 miss its turn
        led.missed(100, 2)
        led.membership_change("disable", 2, 100)
    led.missed(200, 2)
    led.missed(200, 6)                       # a robot outside the ring: no count
    led.membership_change("join", 2, 300)
    assert led.stats[2].missed == 2
    assert led.membership == [(100, "disable", 2), (300, "join", 2)]


def test_the_observers_reports_of_one_happening_a_few_ticks_apart_count_once():
    """On the CPU model each observer's timer handler has its effects a few hundred cycles
    after another's (and the father's PC is another CPU): reports of one robot's miss, drop or
    join within ``same_turn`` ticks of the first are that one happening, at the first's tick;
    a report later than that is the next. A robot's own change of mode is every one listed."""
    led = Ledger((1, 2, 3), same_turn=4_800_000)             # half of Tmax, as the world's
    for t in (1000, 1001, 1309):             # robots 3 and 1, then the father, saw robot 2
        led.missed(t, 2)
        led.membership_change("disable", 2, t)
    led.missed(1002, 3)                      # another robot's miss, at once: its own
    led.missed(1000 + 4_800_000, 2)          # within half of Tmax of the first: the same
    led.missed(1001 + 4_800_000, 2)          # later than that: the next turn's
    led.membership_change("join", 2, 2000)   # a join is not a drop
    # an observer that never had robot 2 in its ring says "join" where the others say
    # "rejoin": one admission, listed as its first report says
    led.membership_change("rejoin", 2, 2001)
    for t in (3000, 3000, 3001):
        led.membership_change("listen", 2, t, observed=False)
    assert led.stats[2].missed == 2 and led.stats[3].missed == 1
    assert led.membership == [(1000, "disable", 2), (2000, "join", 2), (3000, "listen", 2),
                              (3000, "listen", 2), (3001, "listen", 2)]


def test_a_robot_admitted_again_is_listed_once_whoever_calls_it_a_join(capsys):
    """Robot 3 is dropped, robot 2 powers on after that (it never had 3 in its ring) and 3
    comes back: robots 0 and 1 report a rejoin, robot 2 a join, of one admission; the summary
    listed both."""
    from hil.sim.faults import parse_fault
    from hil.sim.world import SimConfig, World
    events: list = []
    w = World(SimConfig(robots=(0, 1, 2, 3), duration=16.0, seed=1, power_on={2: 8.0},
                        faults=(parse_fault("fail:3@4"), parse_fault("recover:3@12"))),
              on_event=events.append)
    w.run()
    said = {(e["ev"], e["by"]) for e in events if e["ev"] in ("join", "rejoin")
            and e["robot"] == 3 and e["t"] > 12 * 16_000_000}
    assert ("rejoin", 1) in said and ("join", 2) in said           # the two views
    back = [(kind, r) for t, kind, r in w.membership if r == 3 and kind in ("join", "rejoin")
            and t > 12 * 16_000_000]
    assert back == [("rejoin", 3)]


@pytest.mark.parametrize("cpu", ["ideal", "estimated"])
def test_a_silent_robot_misses_three_turns_and_is_dropped_once_on_either_cpu(cpu):
    """``rprs sim --fail 1@8`` on the CPU model (the command line's default) counted R1's
    three missed turns as 6 and listed its drop twice: the observers' reports came a tick or a
    PC's handler apart, and only reports at one tick were taken as one. Either CPU: 3 misses,
    one drop, one join a robot, with and without the father."""
    from firmware_model.cycle_costs import DEFAULT_COSTS
    from hil.sim.faults import parse_fault
    from hil.sim.world import SimConfig, World
    for robots in ((1, 2, 3, 4), (0, 1, 2, 3, 4)):
        w = World(SimConfig(robots=robots, duration=14.0, faults=(parse_fault("fail:1@8"),),
                            cpu=DEFAULT_COSTS if cpu == "estimated" else None))
        w.run()
        assert w.stats[1].missed == 3
        kinds = [(kind, r) for _, kind, r in w.membership if kind in ("join", "disable")]
        assert kinds.count(("disable", 1)) == 1
        assert sorted(kinds) == sorted({*kinds})                # nothing listed twice
        assert {r for kind, r in kinds if kind == "join"} == set(robots) - {min(robots)}


def test_a_streaming_ledger_forgets_what_ended_long_enough_ago_and_keeps_its_counts():
    """Without ``keep`` a message is checked against until RETIRE_TICKS after its outcome,
    then forgotten, its duplicate deliveries kept as a count: 10,000 messages leave a few."""
    led = Ledger((1, 2))
    step = RETIRE_TICKS // 20
    for i in range(10_000):
        m = message(1, 2, i % 65536, i)
        m.submitted = i * step
        led.submitted(m)
        assert led.delivered_to(deliver(m), 2)
        if i % 1000 == 0:
            assert led.delivered_to(deliver(m), 2)              # a duplicate delivery
        m.state = "delivered"
        led.ended(Outcome(m, True, ""), i * step + 1)
    assert led.duplicate_deliveries == 10
    assert led.stats[2].received == 10_010 and led.corrupt_deliveries == 0
    assert len(led._live) <= 22 and len(led._received) <= 22 and len(led._by_key) <= 22
    last = m
    assert led.intact(deliver(last))                      # ended 1 tick ago: still checked
    assert led.messages is None and led.outcomes is None and led.deliveries is None


def _summary(cfg) -> str:
    from hil.sim.world import World
    w = World(cfg)
    w.run()
    return json.dumps(w.summary(), sort_keys=True), w


@pytest.mark.parametrize("name", ["faults", "standby father", "can", "aloha", "paper"])
def test_a_run_that_keeps_no_records_has_the_summary_of_one_that_keeps_them(name):
    """The summary (deliveries checked, duplicates, latencies, dispatcher latency) is the same
    with and without ``keep_records``, and the streaming run holds only the messages still
    open or ended less than RETIRE_TICKS ago."""
    from hil.sim.config import SimConfig
    from hil.sim.faults import parse_fault
    from firmware_model.radio.mac import MacConfig
    F = lambda *s: tuple(parse_fault(x) for x in s)  # noqa: E731
    cfg = {
        "faults": SimConfig(robots=(0, 1, 2, 3), duration=120, seed=3, load=2.0,
                            faults=F("ber@10-40:0.003", "drop@50-60:0.01", "fail:2@70",
                                     "recover:2@90", "burst@100:0.3")),
        "standby father": SimConfig(robots=(0, 1, 2), duration=90, seed=4, load=1.0,
                                    father_standby=True, faults=F("fail:0@40")),
        "can": SimConfig(robots=(0, 1, 2), duration=40, seed=5, load=1.0, can=True),
        "aloha": SimConfig(robots=(1, 2, 3), duration=60, seed=6, load=2.0, mac_kind="aloha"),
        "paper": SimConfig(robots=(0, 1, 2), duration=60, seed=7, load=1.0,
                           mac=MacConfig(profile="paper")),
    }[name]
    kept, _ = _summary(dataclasses.replace(cfg, keep_records=True))
    streamed, w = _summary(cfg)
    assert streamed == kept
    s = json.loads(streamed)
    assert s["delivered"] + s["failed"] + s["unacknowledged"] > 50
    open_now = s["pending"] + 8 * len(w.stations)
    assert len(w.ledger._live) <= open_now + 40, len(w.ledger._live)


def test_a_record_the_run_does_not_keep_says_how_to_keep_it():
    from hil.sim.config import SimConfig
    from hil.sim.world import RecordsNotKept, World
    w = World(SimConfig(robots=(0, 1), duration=2, seed=1))
    w.run()
    for name in ("messages", "outcomes", "deliveries", "dispatch_latency"):
        with pytest.raises(RecordsNotKept, match="keep_records=True"):
            getattr(w, name)
    kept = World(SimConfig(robots=(0, 1), duration=2, seed=1, keep_records=True))
    kept.run()
    assert kept.messages == [] and kept.dispatch_latency == []


def test_a_copied_ledger_retires_its_own_messages_and_no_other():
    """A world is copied by pickling (hil/sim/lockstep.py, the stateful MAC hunt): in the
    copy, a message that ends is retired RETIRE_TICKS later and one still open is checked
    as before. (Keyed by ``id()``, the copy kept the original's ids: its messages were never
    retired, and one whose new id was an old one's retired that other message instead, so its
    delivery after RETIRE_TICKS counted as corrupted.)"""
    import pickle
    led = Ledger((1, 2))
    first, second = message(1, 2, 1, 10), message(1, 2, 2, 20)
    led.submitted(first)
    led.submitted(second)
    copy = pickle.loads(pickle.dumps(led))
    done, open_ = (m for m in copy._live.values())
    done.state = "delivered"
    copy.ended(Outcome(done, True, ""), 1)
    later = message(1, 2, 3, 30)
    later.submitted = RETIRE_TICKS + 2
    copy.submitted(later)                  # (a submission retires what ended long enough ago)
    assert list(copy._live.values()) == [open_, later]
    assert copy.delivered_to(deliver(open_), 2) and copy.corrupt_deliveries == 0

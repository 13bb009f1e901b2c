"""hil/sim/ledger.py, the accounting the invariants are checked on, on its own: a delivery is
checked against what its sender submitted (a Number that wrapped, a corrupted command, a robot
it was not for), a missed turn is counted once however many robots saw it, and a membership
change is listed once."""
from __future__ import annotations

from firmware_model.radio.content import cmd
from firmware_model.radio.frame import BROADCAST
from firmware_model.radio.mac import Deliver, Message, Outcome
from hil.sim.ledger import KEYED, Ledger


def message(src: int, dst: int, num: int, x: int) -> Message:
    return Message(src, dst, num, 2, (cmd("movex", x),), b"", 0)


def deliver(m: Message, commands=None) -> Deliver:
    return Deliver(m.src, m.dst, m.num, m.type, m.commands if commands is None else commands)


def test_a_delivery_is_checked_against_what_its_sender_submitted():
    led = Ledger((1, 2, 3))
    first, again = message(1, 2, 5, 10), message(1, 2, 5, 20)   # Number 5 again (it wrapped)
    led.submitted(first)
    led.submitted(again)
    assert led.delivered_to(deliver(again), 2)
    assert led.delivered_to(deliver(again), 2)                  # the same message twice
    assert led.delivered_to(deliver(first), 2)
    assert led.deliveries == {(1, 5, 2, 2): 2, (1, 5, 1, 2): 1}
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
    led = Ledger((1, 2))
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

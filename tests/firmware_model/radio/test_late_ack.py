"""An acknowledgement of a message that had already failed unacknowledged (the father's
order book needs it: the robot has the order after all and its answer is that order's)."""
from __future__ import annotations

from firmware_model.radio.content import cmd
from firmware_model.radio.mac import MacConfig, RotationalMac
from firmware_model.radio.mac_events import LateAck


def test_an_ack_of_a_message_that_failed_after_going_out_is_a_late_ack_once():
    mac = RotationalMac(0, MacConfig(team=frozenset({0, 1, 2})))
    m = mac.submit(1, [cmd("status")], 0)
    m.attempts = 2                                   # it went out, twice
    out: list = []
    mac._finish(m, False, "destination 1 dropped from the ring after 2 attempt(s)", out)
    out.clear()
    mac._on_ack(2, m.num, 0, out)                    # another robot: nothing
    mac._on_ack(1, (m.num + 1) % 100, 0, out)        # another Number: nothing
    assert out == []
    mac._on_ack(1, m.num, 0, out)
    assert out == [LateAck(1, m.num)]
    out.clear()
    mac._on_ack(1, m.num, 0, out)                    # (a duplicate acknowledgement)
    assert out == []


def test_a_message_that_never_went_out_gets_no_late_ack():
    mac = RotationalMac(0, MacConfig(team=frozenset({0, 1})))
    m = mac.submit(1, [cmd("status")], 0)
    out: list = []
    mac._finish(m, False, "expired: not sent within 60000 ms", out)
    out.clear()
    mac._on_ack(1, m.num, 0, out)
    assert out == []

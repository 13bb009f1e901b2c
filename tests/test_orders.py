"""The father's order book (hil/bench/orders.py) on its own: state changes from MAC actions."""
from __future__ import annotations

from firmware_model.radio.content import cmd
from firmware_model.radio.frame import FrameType
from firmware_model.radio.mac import Deliver, Message, Outcome
from hil.bench.orders import OrderBook


def _book():
    seen = []
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state, now)))
    msg = Message(src=0, dst=1, num=1, type=2, commands=(cmd("joint", 1, 20),), content=b"",
                  submitted=0)
    book.submitted(msg, 0)
    return book, msg, seen


def test_an_order_goes_acknowledged_then_done():
    book, msg, seen = _book()
    book.observe(Outcome(msg, True, ""), 100)
    book.observe(Deliver(1, 0, 5, int(FrameType.BROADCAST_INFO),
                         (cmd("done"), cmd("joint", 1, 20))), 200)
    assert seen == [(1, "queued", 0), (1, "acknowledged", 100), (1, "done", 200)]


def test_a_done_notice_before_the_ack_still_says_the_order_arrived():
    """A lossy channel: the robot's ack was lost and the done() notice came first. The order
    arrived (the robot answered about it): acknowledged, then done, on that tick."""
    book, msg, seen = _book()
    book.observe(Deliver(1, 0, 5, int(FrameType.BROADCAST_INFO),
                         (cmd("done"), cmd("joint", 1, 20))), 200)
    book.observe(Outcome(msg, True, ""), 300)          # the late ack changes nothing
    assert seen == [(1, "queued", 0), (1, "acknowledged", 200), (1, "done", 200)]

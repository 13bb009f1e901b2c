"""The father's order book (hil/bench/orders.py) on its own: state changes from MAC actions."""
from __future__ import annotations

from firmware_model.radio.content import cmd
from firmware_model.radio.frame import Frame, FrameType
from firmware_model.radio.mac import Deliver, Message, Outcome, Transmit
from firmware_model.timing import TICK_HZ
from hil.bench.orders import OrderBook


def _book():
    seen = []
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state, now)))
    msg = Message(src=0, dst=1, num=1, type=2, commands=(cmd("joint", 1, 20),), content=b"",
                  submitted=0)
    book.submitted(msg, 0)
    return book, msg, seen


def _sent(book, msg, at, to=(1,)):
    """The station sends ``msg``'s first frame (a broadcast to the robots ``to``)."""
    msg.awaiting = set(to) if msg.dst == 7 else {msg.dst}
    book.observe(Transmit(Frame(dst=msg.dst, src=0, num=msg.num, type=2, content=b""), b""), at)


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
    _sent(book, msg, 100)
    book.observe(Deliver(1, 0, 5, int(FrameType.BROADCAST_INFO),
                         (cmd("done"), cmd("joint", 1, 20))), 200)
    book.observe(Outcome(msg, True, ""), 300)          # the late ack changes nothing
    assert seen == [(1, "queued", 0), (1, "sent", 100), (1, "acknowledged", 200),
                    (1, "done", 200)]


def _order(*commands, dst=1):
    seen = []
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state, now, o.reason)))
    msg = Message(src=0, dst=dst, num=1, type=2, commands=tuple(commands), content=b"",
                  submitted=0)
    book.submitted(msg, 0)
    return book, msg, seen


def _said(book, *commands, at):
    book.observe(Deliver(1, 0, 5, int(FrameType.BROADCAST_INFO), tuple(commands)), at)


def test_an_order_of_several_commands_ends_when_the_robot_has_reported_each():
    """The child reports each command of a message on its own (docs/dispatcher.md): the
    order of joint(1,20)joint(2,30) ends at the second done(), not never (an rprs father
    --exit-when-done once waited for it for ever)."""
    book, msg, seen = _order(cmd("joint", 1, 20), cmd("joint", 2, 30))
    book.observe(Outcome(msg, True, ""), 100)
    _said(book, cmd("done"), cmd("joint", 2, 30), at=200)
    assert book.open_orders()
    _said(book, cmd("done"), cmd("joint", 1, 20), at=300)
    assert [s[:3] for s in seen] == [(1, "queued", 0), (1, "acknowledged", 100),
                                     (1, "done", 300)]


def test_a_status_with_a_move_ends_replied_once_both_are_reported():
    book, msg, seen = _order(cmd("status"), cmd("joint", 3, -80))
    book.observe(Outcome(msg, True, ""), 100)
    _said(book, cmd("joint", 1, 0), cmd("joint", 2, 45), cmd("joint", 3, -90),
          cmd("joint", 4, 45), cmd("wheel", 0), cmd("paw", 1), at=150)
    _said(book, cmd("done"), cmd("joint", 3, -80), at=400)
    assert seen[-1][:3] == (1, "replied", 400) and not book.open_orders()
    assert book.orders[0].reply.startswith("joint 1 0 deg")


def test_one_failed_command_fails_the_order_and_names_the_command():
    book, msg, seen = _order(cmd("joint", 1, 20), cmd("joint", 2, 200))
    book.observe(Outcome(msg, True, ""), 100)
    _said(book, cmd("fail", 2), cmd("joint", 2, 200), at=120)
    assert seen[-1] == (1, "failed", 120, "fail(2): outside a joint's limits: joint(2,200)")


def test_a_radio_only_child_fails_a_message_of_several_orders_once():
    """fail(42) comes once, with the message's first order (docs/dispatcher.md)."""
    book, msg, seen = _order(cmd("status"), cmd("status"))
    book.observe(Outcome(msg, True, ""), 100)
    _said(book, cmd("fail", 42), cmd("status"), at=120)
    assert seen[-1][1] == "failed" and not book.open_orders()


def test_stop_is_done_when_the_robot_reports_it_and_failed_when_it_could_not():
    """stop() ended ``done`` at its acknowledgement, though a child with no CAN side answers
    ``fail(42)stop()`` (an outside check): the father said done, then showed the failure as
    news, and exited 0. The child reports ``done()stop()`` once carried out."""
    book, msg, seen = _order(cmd("stop"))
    book.observe(Outcome(msg, True, ""), 100)
    assert seen[-1][1] == "acknowledged"
    _said(book, cmd("done"), cmd("stop"), at=120)
    assert seen[-1][:3] == (1, "done", 120)
    book, msg, seen = _order(cmd("stop"))
    book.observe(Outcome(msg, True, ""), 100)
    _said(book, cmd("fail", 42), cmd("stop"), at=120)
    assert seen[-1][1] == "failed" and "fail(42)" in seen[-1][3]


def test_an_order_the_robot_never_reports_on_ends_unreported():
    """A move to where the arm already is, or one a newer order replaced, is never reported
    (docs/dispatcher.md): REPORT_WITHIN_S after its acknowledgement it ends ``unreported``,
    so ``rprs father --exit-when-done`` ends; an order not yet acknowledged waits on."""
    from firmware_model.timing import TICK_HZ
    from hil.bench.orders import REPORT_WITHIN_S, TERMINAL
    book, msg, seen = _order(cmd("movex", 0))
    other = Message(src=0, dst=2, num=2, type=2, commands=(cmd("joint", 1, 5),), content=b"",
                    submitted=0)
    book.submitted(other, 0)                           # never acknowledged
    acked = 3 * TICK_HZ
    book.observe(Outcome(msg, True, ""), acked)
    book.expire(acked + int(REPORT_WITHIN_S * TICK_HZ) - 1)
    assert seen[-1][1] == "acknowledged" and len(book.open_orders()) == 2
    book.expire(acked + int(REPORT_WITHIN_S * TICK_HZ))
    assert seen[-1][:2] == (1, "unreported") and "no report within 60 s" in seen[-1][3]
    assert "unreported" in TERMINAL and [o.id for o in book.open_orders()] == [2]
    book.expire(acked + 10 * int(REPORT_WITHIN_S * TICK_HZ), within_s=1.0)
    assert [o.id for o in book.open_orders()] == [2]
    late = Deliver(1, 0, 5, int(FrameType.BROADCAST_INFO), (cmd("done"), cmd("movex", 0)))
    book.observe(late, acked + 70 * TICK_HZ)            # too late: the order has ended
    assert seen[-1][:2] == (1, "unreported")


def test_every_order_ends_once_and_only_done_replied_or_sent_only_succeed():
    """The closing line counts each final state, and ``--exit-when-done`` exits 0 only when
    every order succeeded: an order refused before it reached the MAC (a bad line, a standby
    PC) is a record of its own that ends ``refused``, and fails the run like ``failed``."""
    book, msg, seen = _book()
    book.observe(Outcome(msg, True, ""), 100)
    book.observe(Deliver(1, 0, 5, int(FrameType.BROADCAST_INFO),
                         (cmd("done"), cmd("joint", 1, 20))), 200)
    assert book.all_succeeded()
    bad = book.refused("bogus", None, "bad order: start with the destination ID", 300)
    assert bad.finished and bad.id == 2 and seen[-1] == (2, "refused", 300)
    assert not book.all_succeeded()
    assert book.closing_line() == ("orders: 2 (done 1, replied 0, sent-only 0, failed 0, "
                                   "unreported 0, refused 1, open 0)")
    book.submitted(Message(src=0, dst=1, num=2, type=2, commands=(cmd("status"),),
                           content=b"", submitted=400), 400)
    assert book.counts()["open"] == 1


def test_a_father_that_stands_by_says_new_orders_are_refused_and_what_becomes_of_held_ones():
    """A father PC that stands by (it heard the other PC) tells the person at once: new orders
    are refused there, and those it holds go out only if it takes over, else expire."""
    import io
    from types import SimpleNamespace

    from firmware_model.radio.mac import MacConfig, ModeChange
    from hil.view.father import FatherConsole
    out = io.StringIO()
    mac = SimpleNamespace(ring=(0, 1), standby=True, pending=2, cfg=MacConfig())
    FatherConsole(out, "human").ring(SimpleNamespace(mac=mac),
                                     ModeChange("member", "another PC is active as ID 0: "
                                                "standing by"), 16_000_000)
    line = out.getvalue()
    assert "new orders are refused until this PC takes over" in line, line
    assert "2 held here go out if it does, else fail (expired) 60 s after each" in line, line


def test_a_broadcast_status_ends_sent_only_and_each_robots_reply_is_news():
    """A broadcast ``status()`` ended ``replied`` with the first robot's values (its reply,
    a unicast message, was taken for the answer to the broadcast), where a broadcast ends
    ``sent-only`` (docs/bench.md): every robot answers it, and no one reply is the answer.
    A broadcast ``act(n,0)`` alike: each robot's ``act(n,1)`` is news."""
    news = []
    book, msg, seen = _order(cmd("status"), dst=7)
    book.on_news = lambda d, now: news.append((d.src, now))
    _sent(book, msg, 50, to=(1, 2))
    reply = tuple(cmd("joint", i, 0) for i in range(1, 5)) + (cmd("wheel", 0), cmd("paw", 1))
    book.observe(Deliver(1, 0, 5, 2, reply), 100)
    book.observe(Deliver(2, 0, 5, 2, reply), 110)
    book.observe(Outcome(msg, False, "broadcast"), 120)
    assert [s[1] for s in seen] == ["queued", "sent", "sent-only"]
    assert news == [(1, 100), (2, 110)]
    # a done()/fail() from one robot is no report on a broadcast order either
    book, msg, seen = _order(cmd("joint", 1, 20), dst=7)
    _sent(book, msg, 50)
    _said(book, cmd("fail", 42), cmd("joint", 1, 20), at=100)
    book.observe(Outcome(msg, False, "broadcast"), 120)
    assert [s[1] for s in seen] == ["queued", "sent", "sent-only"]
    book, msg, seen = _order(cmd("act", 3, 0), dst=7)
    book.on_news = lambda d, now: news.append((d.src, now))
    _sent(book, msg, 50, to=(2,))
    book.observe(Deliver(2, 7, 5, 2, (cmd("act", 3, 1),)), 100)
    assert seen[-1][1] == "sent" and news[-1] == (2, 100)


def _msg(book, num, *commands, dst=1):
    m = Message(src=0, dst=dst, num=num, type=2, commands=tuple(commands), content=b"",
                submitted=0)
    book.submitted(m, 0)
    return m


STATUS = tuple(cmd("joint", i, 0) for i in range(1, 5)) + (cmd("wheel", 0), cmd("paw", 1))


def test_a_reply_answers_no_order_still_queued_and_a_broadcast_is_answered_first():
    """``7 status()``, ``2 status()``, ``2 status()``, ``1 status()`` (an outside check): the
    last, never sent, ended ``replied`` with R1's answer to the broadcast, and #2 took R2's;
    the father exited 0 with messages still queued. A robot answers its orders in the order
    it has them: its first reply after a broadcast is the broadcast's (news), and an order
    still queued has no answer."""
    seen, news = [], []
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state)),
                     on_news=lambda d, now: news.append(d.src))
    b = _msg(book, 1, cmd("status"), dst=7)
    m2 = _msg(book, 2, cmd("status"), dst=2)
    m3 = _msg(book, 3, cmd("status"), dst=2)
    _msg(book, 4, cmd("status"), dst=1)
    _sent(book, b, 10, to=(1, 2))
    b.awaiting = set()                                     # every member acknowledged it
    book.observe(Outcome(b, True, ""), 20)                 # (a broadcast: sent-only)
    _sent(book, m2, 30)
    book.observe(Deliver(1, 0, 5, 3, STATUS), 40)         # R1's answer to the broadcast
    book.observe(Deliver(2, 0, 5, 3, STATUS), 50)         # R2's answer to the broadcast
    assert news == [1, 2] and {i for i, st in seen if st == "replied"} == set()
    book.observe(Deliver(2, 0, 6, 3, STATUS), 60)         # R2's answer to #2
    assert (2, "replied") in seen and (3, "replied") not in seen
    assert [o.id for o in book.open_orders()] == [3, 4]   # still queued: open
    assert m3.num == 3


def test_a_status_reply_that_starts_with_a_silent_joint_is_the_reply():
    """Joint 1 silent: the child answers ``fail(31)joint(2,45)...paw(1)`` (docs/dispatcher.md).
    It was taken for a failure report about ``joint(2,45)...`` and shown as news; the order
    ended ``unreported`` a minute later."""
    book, msg, seen = _order(cmd("status"), dst=1)
    book.observe(Outcome(msg, True, ""), 100)
    reply = (cmd("fail", 31),) + STATUS[1:]
    _said(book, *reply, at=200)
    assert seen[-1][1] == "replied"
    assert book.orders[0].reply.startswith("fail(31): joint 1 did not respond, joint 2")


def test_a_report_ends_an_older_order_it_replaced_and_a_repeat_gets_its_own_report():
    """``2 joint(2,-5)``, ``2 joint(2,100)``, then later ``2 joint(2,-5)``: the first was
    replaced (no report), and the third's done() went to it, the third ending unreported.
    The second's report shows the first was replaced: it ends unreported then."""
    seen = []
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state, o.reason)))
    ms = [_msg(book, k, cmd("joint", 2, a), dst=2) for k, a in ((1, -5), (2, 100), (3, -5))]
    for k, m in enumerate(ms[:2]):
        _sent(book, m, 10 + k)
        book.observe(Outcome(m, True, ""), 20 + k)
    book.observe(Deliver(2, 0, 5, 3, (cmd("done"), cmd("joint", 2, 100))), 30)
    assert (1, "unreported") in [s[:2] for s in seen] and (2, "done") in [s[:2] for s in seen]
    assert "replaced by #2" in next(r for i, st, r in seen if i == 1 and st == "unreported")
    _sent(book, ms[2], 40)
    book.observe(Outcome(ms[2], True, ""), 50)
    book.observe(Deliver(2, 0, 6, 3, (cmd("done"), cmd("joint", 2, -5))), 60)
    assert seen[-1][:2] == (3, "done") and not book.open_orders()


def test_an_order_replaced_after_its_robot_was_dropped_says_the_drop():
    """``1 joint(1,150)``; robot 1 restarts mid-move (dropped, rejoins), its submodules carry
    the move out; then ``1 joint(1,0)``, reported: the first order was said "replaced ...
    before it was carried out", though it was carried out and only its report was lost. The
    drop, which the father saw first, is its reason."""
    from firmware_model.radio.mac import Disable
    seen = []
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state, o.reason)))
    first = _msg(book, 1, cmd("joint", 1, 150), dst=1)
    _sent(book, first, 10)
    book.observe(Outcome(first, True, ""), 20)
    book.observe(Disable(1), 100)                          # dropped after acknowledging it
    second = _msg(book, 2, cmd("joint", 1, 0), dst=1)
    _sent(book, second, 200)
    book.observe(Outcome(second, True, ""), 210)
    book.observe(Deliver(1, 0, 5, 3, (cmd("done"), cmd("joint", 1, 0))), 300)
    reason = next(r for i, st, r in seen if i == 1 and st == "unreported")
    assert "the ring dropped robot 1 after it acknowledged it" in reason, reason
    assert "replaced" not in reason


def test_an_order_left_unreported_says_what_the_father_saw():
    """A move cut by ``stop()``, and one whose robot the ring dropped, ended ``unreported``
    with "a move to where the arm already is, or ... replaced": false in both cases."""
    from firmware_model.radio.mac import Disable
    book = OrderBook()
    move = _msg(book, 1, cmd("joint", 1, -100), dst=1)
    stop = _msg(book, 2, cmd("stop"), dst=1)
    other = _msg(book, 3, cmd("joint", 1, 90), dst=2)
    for k, m in enumerate((move, stop, other)):
        book.observe(Outcome(m, True, ""), 10 + k)
    book.observe(Disable(2), 100)
    book.expire(61 * TICK_HZ)
    reasons = {o.id: (o.state, o.reason) for o in book.orders}
    assert reasons[1][0] == "unreported" and "#2's stop() stopped it" in reasons[1][1]
    assert reasons[3][0] == "unreported" and "the ring dropped robot 2" in reasons[3][1]


def test_a_broadcast_answer_that_never_comes_takes_no_later_report():
    """``7 joint(1,20)``, robot 1 already there (no report, as documented): its owed answer
    to the broadcast stayed owed, and took the report of a later ``1 joint(1,20)``, which
    ended unreported. A later report on the same submodule, or report-within, ends the
    debt."""
    seen, news = [], []
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state)),
                     on_news=lambda d, now: news.append(d.src))
    b = _msg(book, 1, cmd("joint", 1, 20), dst=7)
    m2 = _msg(book, 2, cmd("joint", 1, 0), dst=1)
    m3 = _msg(book, 3, cmd("joint", 1, 20), dst=1)
    _sent(book, b, 10, to=(1,))
    b.awaiting = set()
    book.observe(Outcome(b, True, ""), 20)
    for k, m in enumerate((m2, m3)):
        _sent(book, m, 30 + k)
        book.observe(Outcome(m, True, ""), 40 + k)
    book.observe(Deliver(1, 0, 5, 3, (cmd("done"), cmd("joint", 1, 0))), 50)
    book.observe(Deliver(1, 0, 6, 3, (cmd("done"), cmd("joint", 1, 20))), 60)
    assert (2, "done") in seen and (3, "done") in seen and news == []
    # and without a report between: report-within ends the debt
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state)))
    b = _msg(book, 1, cmd("joint", 1, 20), dst=7)
    _sent(book, b, 10, to=(1,))
    book.expire(61 * TICK_HZ)
    assert book.orders[0].expect == {}


def test_a_broadcast_act_owes_no_answer_and_the_next_act_gets_its_own():
    """``7 act(1,0)`` then ``1 act(1,0)`` (an outside check, 3 runs of 3): a broadcast act is
    a notice no robot carries out (clause 19a), yet each robot was owed an act(1,1) for it,
    and R1's answer to #2 went to the broadcast: #2 ended unreported, the father exit 1."""
    seen, news = [], []
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state)),
                     on_news=lambda d, now: news.append(d.src))
    b = _msg(book, 1, cmd("act", 1, 0), dst=7)
    m2 = _msg(book, 2, cmd("act", 1, 0), dst=1)
    _sent(book, b, 10, to=(1, 2))
    b.awaiting = set()
    book.observe(Outcome(b, True, ""), 20)
    _sent(book, m2, 30)
    book.observe(Outcome(m2, True, ""), 40)
    book.observe(Deliver(1, 7, 5, 3, (cmd("act", 1, 1),)), 50)
    assert (2, "done") in seen and news == []


def test_the_first_thing_the_father_saw_explains_a_missing_report():
    """``1 act(1,0)``, ``1 act(0,0)`` (done), a ``stop()`` seconds later: #1 was blamed on the
    stop, though #2 had replaced it long before. And an order whose report came while the
    father itself was out of the ring (stalled, left out) was said to be a move to where the
    arm already was."""
    from firmware_model.radio.mac import ModeChange
    book = OrderBook()
    a1 = _msg(book, 1, cmd("act", 1, 0), dst=1)
    a0 = _msg(book, 2, cmd("act", 0, 0), dst=1)
    st = _msg(book, 3, cmd("stop"), dst=1)
    j = _msg(book, 4, cmd("joint", 1, 160), dst=2)
    q = _msg(book, 5, cmd("status"), dst=2)
    for k, m in enumerate((a1, a0)):
        book.observe(Outcome(m, True, ""), 10 + k)
    book.observe(Outcome(j, True, ""), 15)
    book.observe(Outcome(q, True, ""), 16)                # a status() replaces no move
    book.observe(ModeChange("listen", "stalled 3.02 s"), 20)
    book.observe(Outcome(st, True, ""), 4 * TICK_HZ)
    book.expire(70 * TICK_HZ)
    why = {o.id: (o.state, o.reason) for o in book.orders}
    assert why[1][0] == "unreported" and "#2 (act(0,0)) came before it was reported" in why[1][1]
    assert "the father itself was out of the ring" in why[4][1] and "stalled 3.02 s" in why[4][1]


def test_orders_open_when_the_father_stops_each_get_a_final_state():
    """The radio port went away with three orders open: the closing line said ``open 3`` and
    none got an end line, where every order line gets exactly one final state."""
    seen = []
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state, o.reason)))
    m1 = _msg(book, 1, cmd("joint", 1, 160), dst=1)
    _msg(book, 2, cmd("status"), dst=1)
    book.observe(Outcome(m1, True, ""), 10)
    book.close(100, "the radio port /tmp/air/node0 went away (read failed)")
    ends = {i: (st, r) for i, st, r in seen if st in ("unreported", "failed")}
    assert ends[1] == ("unreported", "the radio port /tmp/air/node0 went away (read failed) "
                                     "before the robot reported on it")
    assert ends[2][0] == "failed" and ends[2][1].startswith("never sent: the radio port")
    assert book.counts()["open"] == 0
    book.close(200, "again")                              # once only
    assert len([s for s in seen if s[1] in ("unreported", "failed")]) == 2


def test_an_order_open_at_the_stop_names_the_drop_the_father_saw_first():
    """An order acknowledged, its robot killed and dropped by the ring, then the radio hub
    gone: the order ended "the radio port ... went away before the robot reported on it",
    the drop that explains it unsaid. It says both now, the stop first."""
    from firmware_model.radio.mac import Disable
    seen = []
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state, o.reason)))
    m = _msg(book, 1, cmd("joint", 1, 0), dst=1)
    book.observe(Outcome(m, True, ""), 10)
    book.observe(Disable(1), 3 * TICK_HZ)
    book.close(9 * TICK_HZ, "the radio port /tmp/air/node0 went away (read failed)")
    (end,) = [r for i, st, r in seen if st == "unreported"]
    assert end.startswith("the radio port /tmp/air/node0 went away (read failed) before the "
                          "robot reported on it; before that, the ring dropped robot 1 after "
                          "it acknowledged it"), end


def test_an_answer_to_a_failed_order_acknowledged_late_is_news_not_the_next_orders():
    """A USB adapter stalled 2 s: #2 ``status()`` failed (R1 dropped after 2 attempts), yet
    R1 had it and answered; that answer ended #3 ``status()``, whose own answer then came as
    news (with a CAN side, #3 would show #2's older values). R1's acknowledgement of #2,
    heard late (the MAC's ``LateAck``), marks #2 owed its answer: the first answer is news,
    #3 gets its own."""
    from firmware_model.radio.mac_events import LateAck
    seen = []
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state, o.reason, now)))
    first = _msg(book, 2, cmd("status"))
    _sent(book, first, 10)
    first.state = "failed"
    book.observe(Outcome(first, False, "destination 1 dropped from the ring after 2 "
                                       "attempt(s)"), 100)
    second = _msg(book, 3, cmd("status"))
    _sent(book, second, 110)
    book.observe(LateAck(1, 2), 150)
    book.observe(Outcome(second, True, ""), 160)
    answer = (cmd("joint", 1, 0), cmd("joint", 2, 45), cmd("joint", 3, -90),
              cmd("joint", 4, 45), cmd("wheel", 0), cmd("paw", 1))
    old = (cmd("joint", 1, 10),) + answer[1:]
    book.observe(Deliver(1, 0, 4, 4, old), 200)          # #2's answer
    book.observe(Deliver(1, 0, 5, 4, answer), 300)       # #3's
    ends = {i: (st, t) for i, st, _, t in seen if st in ("replied", "failed")}
    assert ends[1][0] == "failed" and ends[2] == ("replied", 300), seen
    assert "joint 1 0 deg" in book.orders[1].reply, book.orders[1].reply
    # without the late acknowledgement, as before, the first answer is #3's
    seen.clear()
    book = OrderBook(on_change=lambda o, now: seen.append((o.id, o.state, o.reason, now)))
    first = _msg(book, 2, cmd("status"))
    _sent(book, first, 10)
    first.state = "failed"
    book.observe(Outcome(first, False, "dropped"), 100)
    second = _msg(book, 3, cmd("status"))
    _sent(book, second, 110)
    book.observe(Outcome(second, True, ""), 160)
    book.observe(Deliver(1, 0, 4, 4, old), 200)
    assert ("replied", 200) in [(st, t) for i, st, _, t in seen if i == 2]

"""Content commands in, DBC-encoded CAN frames out, through a simulated child (``--can``)."""
from __future__ import annotations

import pytest

from can_bus import dbc
from can_bus.frames import CanFrame
from firmware_model.kinematics import HOME, forward, inverse
from firmware_model.radio.content import cmd
from firmware_model.timing import s_to_ticks
from hil.sim.world import SimConfig, World

START = s_to_ticks(4.0)        # the ring has formed by then


def child_world(duration=14.0, robots=(0, 1)):
    evs: list[dict] = []
    w = World(SimConfig(robots=robots, duration=duration, can=True, keep_records=True),
              on_event=evs.append)
    w.run(START)
    return w, evs


def can_frames(evs, bus=1, since=0, ids=None):
    out = []
    for e in evs:
        if e.get("ev") == "can" and e["bus"] == bus and e["start"] >= since:
            if ids is None or e["id"] in ids:
                name, sig = dbc.decode(CanFrame(e["id"], bytes.fromhex(e["data"])))
                out.append((e["t"], name, sig))
    return out


def replies(evs, to=0):
    return [e for e in evs if e.get("ev") == "deliver" and e["to"] == to]


def send(w, commands, dst=1):
    return w.submit(0, dst, commands)


def commands_after(evs, since):
    return [(n, s) for _, n, s in can_frames(evs, since=since) if n.endswith("_CMD")
            or n == "ESTOP"]


@pytest.mark.parametrize("command,dx,dy,dz", [
    (cmd("movex", 20), 20, 0, 0), (cmd("movey", -15), 0, -15, 0),
    (cmd("movez", 10), 0, 0, 10)])
def test_relative_moves_become_joint_commands_from_the_kinematics(command, dx, dy, dz):
    w, evs = child_world()
    send(w, [command])
    w.run()
    p = forward(HOME)
    want = inverse(p.x + dx, p.y + dy, p.z + dz, p.phi)
    sent = {n: s for n, s in commands_after(evs, START)}
    for i, a in enumerate(want, 1):
        if abs(a - HOME[i - 1]) >= 0.005:
            assert sent[f"JOINT{i}_CMD"]["angle"] == pytest.approx(a, abs=0.005)
            assert sent[f"JOINT{i}_CMD"]["mode"] == 0
        else:
            assert f"JOINT{i}_CMD" not in sent
    for i, a in enumerate(want, 1):             # the joints got there and said so
        assert w.submodules[1][f"JOINT{i}"].angle_deg == pytest.approx(a, abs=0.01)
    done = [s for _, n, s in can_frames(evs, since=START) if n.startswith("EVENT")]
    assert done and all(s["kind"] == 1 for s in done)
    # success is reported once: a done() notice (Type '3') to the sender, no failure
    assert [(e["src"], e["type"]) for e in replies(evs)] == [(1, 3)]


def test_moveto_and_joint_and_wheel_and_paw_reach_their_submodules():
    w, evs = child_world()
    send(w, [cmd("moveto", 200, 50, 120), cmd("joint", 4, 30)])
    w.run(START + s_to_ticks(4))
    t1 = w.now
    send(w, [cmd("wheel", -120), cmd("paw", 0)])
    w.run()
    first = dict(commands_after(evs, START))
    q = inverse(200, 50, 120, forward(HOME).phi)
    assert first["JOINT1_CMD"]["angle"] == pytest.approx(q[0], abs=0.005)
    assert first["JOINT4_CMD"]["angle"] in (pytest.approx(q[3], abs=0.005), 30)
    last_j4 = [s for n, s in commands_after(evs, START) if n == "JOINT4_CMD"][-1]
    assert last_j4["angle"] == 30
    later = dict(commands_after(evs, t1))
    assert later["WHEEL_CMD"]["speed"] == -120 and later["WHEEL_CMD"]["distance"] == 0
    assert later["PAW_CMD"]["action"] == 0
    subs = w.submodules[1]
    assert subs["JOINT4"].angle_deg == pytest.approx(30, abs=0.01)
    assert subs["WHEEL"].odometer_mm < -100
    assert subs["PAW"].opening_units == 0 or subs["PAW"].grip == 0


@pytest.mark.parametrize("command,code", [
    (cmd("moveto", 900, 0, 0), 1),            # out of reach
    (cmd("movez", -200), 2),                  # reachable only past a joint limit
    (cmd("joint", 2, 150), 2),                # joint 2 is -10..120 deg
    (cmd("wheel", 500), 3),                   # 300 mm/s at most
])
def test_impossible_commands_come_back_as_type_4_failures(command, code):
    w, evs = child_world()
    send(w, [command])
    w.run()
    back = replies(evs)
    assert len(back) == 1
    r = back[0]
    assert r["src"] == 1 and r["type"] == 4
    msgs = [m for m in w.messages if m.src == 1]
    assert [c.text() for c in msgs[0].commands] == [f"fail({code})", command.text()]
    assert not [n for n, _ in commands_after(evs, START) if n != "ESTOP"]


def test_a_long_move_does_not_block_the_ring():
    w, evs = child_world(duration=16.0, robots=(0, 1, 2))
    send(w, [cmd("act", 1, 0)])                # 90 deg of base yaw: 1.5 s at 60 deg/s
    w.run()
    frames = [e for e in evs if e.get("ev") == "frame" and e["start"] > START]
    gaps = [b["start"] - a["end"] for a, b in zip(frames, frames[1:])]
    assert max(gaps) == 80_000                  # every turn handed on after Ttrans
    notices = [e for e in evs if e.get("ev") == "deliver" and e["src"] == 1 and e["dst"] == 7]
    texts = [[c.text() for c in m.commands] for m in w.messages if m.src == 1]
    assert ["act(1,0)"] in texts and ["act(1,1)"] in texts
    assert {e["to"] for e in notices} == {0, 2}
    starts = [m.submitted for m in w.messages if m.src == 1]
    assert starts[1] - starts[0] >= s_to_ticks(1.5)    # done only when the joint got there
    assert w.submodules[1]["JOINT1"].angle_deg == pytest.approx(90, abs=0.01)


def test_stop_holds_the_joints_and_stops_the_wheel():
    w, evs = child_world()
    send(w, [cmd("wheel", 200), cmd("act", 2, 0)])
    w.run(START + s_to_ticks(1.0))
    t = w.now
    send(w, [cmd("stop")])
    w.run()
    sent = dict(commands_after(evs, t))
    assert all(sent[f"JOINT{i}_CMD"]["mode"] == 1 for i in range(1, 5))
    assert sent["WHEEL_CMD"]["speed"] == 0
    assert abs(w.submodules[1]["JOINT1"].angle_deg) < 90
    assert w.submodules[1]["WHEEL"].v_ums == 0


def test_stop_holds_a_joint_that_reported_past_its_limit_at_the_limit():
    """Joint 2 reports -10.5 deg (an overshoot, or any node on the bus: the status frame
    carries it), below its limit of -10. ``stop()`` used to command the hold at the reported
    angle, which JOINT2_CMD cannot carry: DbcError, and the child died (a traceback at the
    bench). It holds the joint at the limit now, and every command goes out."""
    from firmware_model.dispatcher import Dispatcher
    d = Dispatcher(1)
    d.on_can(dbc.encode_raw("JOINT2_STATUS", angle=-1050, speed=0, state=2, seq=0), 1000)
    d.on_message(5, 1, (cmd("stop"),), 2000)
    sent = [dbc.decode(f) for f in d.take_can()]
    assert [name for name, _ in sent] == [f"JOINT{i}_CMD" for i in range(1, 5)] + ["WHEEL_CMD"]
    assert sent[1][1]["mode"] == 1 and sent[1][1]["angle"] == -10.0 and d.target[1] == -10.0


def test_status_reply_reports_the_joints():
    w, evs = child_world()
    send(w, [cmd("status")])
    w.run()
    msg = [m for m in w.messages if m.src == 1][0]
    assert msg.dst == 0 and msg.type == 3
    got = {c.args[0]: c.args[1] for c in msg.commands if c.name == "joint"}
    assert got == {i: pytest.approx(HOME[i - 1], abs=0.01) for i in range(1, 5)}


def test_a_stalled_joint_is_reported_over_the_radio():
    w, evs = child_world()
    w.submodules[1]["JOINT1"].stall()
    send(w, [cmd("act", 1, 0)])
    w.run()
    fails = [m for m in w.messages if m.src == 1 and m.type == 4]
    assert fails and fails[0].commands[0].text() == "fail(11)"
    assert fails[0].dst == 0


def test_a_silent_joint_is_reported_as_not_responding():
    w, evs = child_world()
    w.submodules[1]["JOINT3"].silent(True)
    send(w, [cmd("act", 0, 0)] if False else [cmd("joint", 3, -60)])
    w.run()
    fails = [m for m in w.messages if m.src == 1 and m.type == 4]
    assert fails and fails[0].commands[0].text() == "fail(33)"


def test_stuck_txd_blocks_the_bus_and_the_child_isolates_itself():
    w, evs = child_world(duration=12.0)
    send(w, [cmd("act", 1, 0)])
    w.run(START + s_to_ticks(1.0))
    child = w.children[1]
    xcvr = child.can.xcvr
    t_stuck = w.now
    xcvr.stick_txd(True)                       # the 82C250 has no TXD dominant time-out
    w.run(t_stuck + s_to_ticks(0.5))
    assert child.can.isolated and child.can.isolations == 1
    assert xcvr.mode.value == "standby"
    fails = [m for m in w.messages if m.src == 1 and m.type == 4]
    assert fails and fails[-1].commands[0].text() == "fail(41)"
    # with the faulty transmitter off the bus, the submodules talk again
    t_iso = w.now
    w.run(t_iso + s_to_ticks(0.5))
    status = [f for f in can_frames(evs, since=t_iso) if f[1].endswith("_STATUS")]
    assert len(status) >= 20
    # the fault goes away: the next retry brings the child back onto the bus
    xcvr.stick_txd(False)
    w.run(t_iso + s_to_ticks(2.5))
    assert not child.can.isolated
    send(w, [cmd("joint", 2, 60)])
    w.run()
    assert w.submodules[1]["JOINT2"].angle_deg == pytest.approx(60, abs=0.01)


def test_can_trace_events_and_meta_bitrate(tmp_path):
    from hil.sim.trace import TraceWriter, read_trace
    p = tmp_path / "t.jsonl"
    tw = TraceWriter(str(p))
    w = World(SimConfig(robots=(1, 2), duration=3.0, can=True), tw)
    w.run()
    tw.close()
    evs = list(read_trace(str(p)))
    assert evs[0]["can_bitrate"] == 500_000
    cans = [e for e in evs if e["ev"] == "can"]
    assert {e["bus"] for e in cans} == {1, 2}
    e = cans[0]
    f = CanFrame(e["id"], bytes.fromhex(e["data"]))
    from can_bus.bits import frame_length_bits
    assert e["end"] - e["start"] == frame_length_bits(f.id, f.data, include_ifs=False) * 32


def test_isolation_with_a_frame_on_the_blocked_bus_retries_without_reloading_it(monkeypatch):
    """The 2-hour soak found it: a child isolated itself while its own frame was on the
    blocked bus, so the controller could not cancel it (TCANR: "the frame may be on the bus");
    at the retry the driver loaded that buffer again and the controller refused ("a transmit
    request pending"). A request that may be on the wire now stays in its buffer across the
    isolation and goes once the bus is back; the frames queued behind it were for the jobs
    that failed at the isolation (fail(41)), and are dropped: an order reported failed is
    not carried out after all."""
    from can_bus.bus import CanBus
    from can_bus.transceiver import Transceiver82C250
    from firmware_model.child import RETRY, CanDriver
    from firmware_model.mcu.can_controller import CanController
    from firmware_model.mcu.scheduler import Scheduler
    sched = Scheduler()
    bus = CanBus(sched)
    sent = []
    bus.trace = lambda f, s, e, w: sent.append((f.id, f.data))
    ctl = CanController(sched, name="CAN0")
    xcvr = Transceiver82C250(bus, ctl)
    peer = CanController(sched, name="PEER")      # a node that acknowledges
    Transceiver82C250(bus, peer)
    peer.start()
    drv = CanDriver(sched, ctl, xcvr, on_frame=lambda f, t: None, on_fault=lambda c, t: None)
    xcvr.standby(True)                             # off the bus: requests stay pending
    drv.send(CanFrame(0x101, b"\x01"))
    drv.send(CanFrame(0x101, b"\x02"))            # waits behind the first in the driver
    assert ctl.TREQR == 1 << 1
    # the controller's answer while the frame may be on the wire: it cannot cancel it now
    monkeypatch.setattr(CanController, "cancel", lambda self, buf: False)
    drv.isolate(sched.now)
    monkeypatch.undo()
    sched.run_until(sched.now + RETRY)
    drv.on_timer(sched.now)                        # the retry: back on the bus
    sched.run_until(sched.now + 16_000)
    assert not drv.isolated
    assert sent == [(0x101, b"\x01")]
    drv.send(CanFrame(0x101, b"\x03"))            # a command after the retry goes as ever
    sched.run_until(sched.now + 16_000)
    assert sent == [(0x101, b"\x01"), (0x101, b"\x03")]


def _status_frame(n: int, value: float):
    if n <= 4:
        return dbc.encode(f"JOINT{n}_STATUS", angle=value, speed=0, state=0, seq=0)
    if n == 5:
        return dbc.encode("WHEEL_STATUS", speed=value, odometer=0, state=0, seq=0)
    return dbc.encode("PAW_STATUS", opening=value, grip=0, state=0, seq=0)


def test_status_reports_only_fresh_values_and_says_which_are_not():
    """status() once answered stale angles after the submodules died, and all zeros when none
    had ever spoken. Now a value is given only if its submodule spoke within 300 ms; the
    others are fail(30+n) in their place; with none fresh the answer is fail(30)status()."""
    from firmware_model.dispatcher import SILENCE, Dispatcher
    from firmware_model.radio.frame import FrameType
    d = Dispatcher(1)
    d.on_message(0, 1, (cmd("status"),), 0)
    assert d.take_radio() == [(0, (cmd("fail", 30), cmd("status")), int(FrameType.FAILURE))]
    values = {1: 10.0, 2: 45.0, 3: -90.0, 4: 45.0, 5: 120, 6: 100}
    for n, v in values.items():
        d.on_can(_status_frame(n, v), 1000)
    d.on_can(_status_frame(2, 50.0), SILENCE)          # joint 2 keeps talking, the rest stop
    now = SILENCE + 1000                                 # 300 ms after the others' last frame
    d.on_message(0, 1, (cmd("status"),), now - 1)
    (dst, reply, kind), = d.take_radio()
    assert (dst, kind) == (0, int(FrameType.BROADCAST_INFO))
    assert reply == (cmd("joint", 1, 10.0), cmd("joint", 2, 50.0), cmd("joint", 3, -90.0),
                     cmd("joint", 4, 45.0), cmd("wheel", 120), cmd("paw", 1))
    d.on_message(0, 1, (cmd("status"),), now)
    (_, reply, kind), = d.take_radio()
    assert kind == int(FrameType.BROADCAST_INFO)
    assert reply == (cmd("fail", 31), cmd("joint", 2, 50.0), cmd("fail", 33), cmd("fail", 34),
                     cmd("fail", 35), cmd("fail", 36))
    d.on_message(0, 1, (cmd("status"),), 2 * SILENCE)
    assert d.take_radio() == [(0, (cmd("fail", 30), cmd("status")), int(FrameType.FAILURE))]


def test_a_radio_only_child_answers_orders_with_a_failure():
    """rprs child without --can acknowledged orders and silently did nothing. Now each order
    addressed to it comes back as fail(42) with the order, a broadcast order too (a child with
    its CAN side answers one: the father owes the answer to the broadcast, and an answer never
    sent took a later order's); news (replies, failures, a broadcast act) is not answered."""
    from firmware_model.child import RadioOnlyChild
    from firmware_model.radio.frame import FrameType
    from firmware_model.radio.mac import Deliver
    from firmware_model.station import build_station
    from hil.sim.realtime import RealTimeScheduler
    station, _ = build_station(2, RealTimeScheduler())
    sent = []
    station.submit = lambda dst, commands, type_: sent.append((dst, commands, type_))
    child = RadioOnlyChild(station)
    (deliver,) = station.apps
    deliver(Deliver(0, 2, 5, 2, (cmd("joint", 1, 12),)), 0)
    deliver(Deliver(0, 2, 6, 2, (cmd("status"),)), 0)
    deliver(Deliver(0, 7, 7, 2, (cmd("act", 1, 0),)), 0)             # broadcast
    deliver(Deliver(3, 2, 8, 3, (cmd("joint", 1, 5.0),)), 0)          # a reply: news
    deliver(Deliver(3, 2, 9, 4, (cmd("fail", 42), cmd("status"))), 0)  # a failure: news
    deliver(Deliver(0, 2, 10, 2, (cmd("paw", 1), cmd("wheel", 40))), 0)  # one failure a message
    deliver(Deliver(0, 7, 11, 2, (cmd("status"),)), 0)               # a broadcast order
    deliver(Deliver(0, 2, 12, 2, (cmd("act", 1, 1),)), 0)            # a notice: no order
    assert sent == [(0, (cmd("fail", 42), cmd("joint", 1, 12)), int(FrameType.FAILURE)),
                    (0, (cmd("fail", 42), cmd("status")), int(FrameType.FAILURE)),
                    (0, (cmd("fail", 42), cmd("paw", 1)), int(FrameType.FAILURE)),
                    (0, (cmd("fail", 42), cmd("status")), int(FrameType.FAILURE))]
    assert child.refused == 4
    assert child.replies_dropped == 0
    # the radio's queue full: the failure is counted dropped, not lost unsaid
    from firmware_model.radio.mac import QueueFull

    def full(dst, commands, type_):
        raise QueueFull("queue full: 32 messages wait")
    station.submit = full
    deliver(Deliver(0, 2, 13, 2, (cmd("joint", 2, 10),)), 0)
    assert child.refused == 5 and child.replies_dropped == 1


def test_a_finished_order_is_reported_done_to_its_sender():
    """Moves report completion (protocol 3.0): done() and the order, Type '3', to the
    sender, once every submodule it moved reported done; a failed order gets fail(code)
    instead, a replaced one neither, and the paper profile sends none."""
    from firmware_model.dispatcher import Dispatcher
    from firmware_model.radio.frame import FrameType

    def finish(d, node, now):
        seq = d._seq[node]
        d.on_can(dbc.encode(f"EVENT{node}", kind="done", seq=seq, code=0), now)
    d = Dispatcher(1)
    d.on_message(0, 1, (cmd("joint", 1, 20),), 0)
    d.on_message(3, 1, (cmd("paw", 1),), 0)
    d.on_message(0, 1, (cmd("wheel", 100),), 0)
    assert d.take_radio() == []
    finish(d, 1, 10)
    finish(d, 6, 20)
    finish(d, 5, 30)
    info = int(FrameType.BROADCAST_INFO)
    assert d.take_radio() == [(0, (cmd("done"), cmd("joint", 1, 20)), info),
                              (3, (cmd("done"), cmd("paw", 1)), info),
                              (0, (cmd("done"), cmd("wheel", 100)), info)]
    d.on_message(0, 1, (cmd("joint", 2, 60),), 40)
    d.on_message(0, 1, (cmd("joint", 2, 70),), 50)      # replaces the first
    finish(d, 2, 60)
    assert d.take_radio() == [(0, (cmd("done"), cmd("joint", 2, 70)), info)]
    d.report_done = False                                # the paper profile
    d.on_message(0, 1, (cmd("joint", 3, -60),), 70)
    finish(d, 3, 80)
    assert d.take_radio() == [] and not d.jobs


def test_notices_and_replies_are_never_acted_on():
    """A done() or fail() notice quotes the order it is about, and a status reply is made of
    joint()/wheel()/paw(): none of them is an order. Two children that ordered each other
    once bounced 'done()movex(8)' back and forth for ever (each notice moved the arm again)."""
    from firmware_model.dispatcher import Dispatcher
    from firmware_model.radio.frame import FrameType
    d = Dispatcher(1)
    d.on_message(3, 1, (cmd("done"), cmd("movex", 8)), 0, int(FrameType.BROADCAST_INFO))
    d.on_message(3, 1, (cmd("fail", 1), cmd("moveto", 900, 0, 0)), 0, int(FrameType.FAILURE))
    d.on_message(3, 1, (cmd("joint", 1, 12), cmd("wheel", 5), cmd("paw", 1)), 0,
                 int(FrameType.BROADCAST_INFO))
    assert d.take_can() == [] and d.take_radio() == [] and not d.jobs
    assert [text for _, text in d.log] == ["robot 3: done()", "robot 3: fail(1)"]
    d.on_message(3, 1, (cmd("movex", 8),), 0, int(FrameType.INSTRUCTION))   # an order
    assert d.take_can() and d.jobs


def test_a_remembered_plan_answers_as_a_fresh_one():
    """The dispatcher remembers its kinematics (pure functions): the same order from the same
    pose, refused or accepted, gets the answer the kinematics gives afresh."""
    from firmware_model.dispatcher import Dispatcher
    from firmware_model.kinematics import Unreachable, forward, inverse
    d = Dispatcher(1)
    for _ in range(2):
        d.on_message(0, 1, (cmd("movex", 123456789),), 0)
    first, second = d.take_radio()
    assert first == second and first[1][0] == cmd("fail", 1)
    p = forward(HOME)
    with pytest.raises(Unreachable) as ei:
        inverse(p.x + 123456789, p.y, p.z, p.phi)
    assert [text for _, text in d.log] == [f"movex(123456789): {ei.value}"] * 2
    want = inverse(p.x + 10, p.y, p.z, p.phi)
    for _ in range(2):
        d.on_message(0, 1, (cmd("movex", 10),), 0)
        assert d.target == list(want)
        d.on_message(0, 1, (cmd("movex", -10),), 0)


@pytest.mark.parametrize("command", [
    cmd("moveto", 900, 0, 0), cmd("movez", -200), cmd("movex", 123456789), cmd("movey", -5),
    cmd("joint", 2, 150), cmd("joint", 1, 20), cmd("wheel", 500),
    cmd("wheel", -300), cmd("paw", 1), cmd("status"), cmd("stop"), cmd("act", 1, 0),
])
def test_a_refusal_is_exactly_what_handling_the_order_does(command):
    """``Dispatcher.refusal`` decides a sleeping CAN side need not wake (hil/sim/quiet_can.py):
    it must say refused exactly when handling the order only logs it and answers a failure,
    with that code, and nothing else of the dispatcher changes."""
    from firmware_model.dispatcher import Dispatcher
    d = Dispatcher(1)
    before = (list(d.target), dict(d._seq), d.deadline)
    refused = d.refusal(command)
    d.on_message(0, 1, (command,), 0)
    radio, can = d.take_radio(), d.take_can()
    if refused is None:     # it goes to the submodules, or (status) reads what they sent
        assert can or command.name == "status"
    else:
        assert radio == [(0, (cmd("fail", refused[0]), command), 4)] and not can
        assert (list(d.target), dict(d._seq), d.deadline) == before and not d.jobs
        assert len(d.log) == (0 if refused[1] is None else 1)


def test_only_a_request_to_this_robot_of_refused_orders_is_refused_whole():
    from firmware_model.dispatcher import Dispatcher
    from firmware_model.radio.frame import BROADCAST, FrameType
    d = Dispatcher(1)
    far, near = cmd("movex", 123456789), cmd("movex", 5)
    order = int(FrameType.INSTRUCTION)
    assert d.refuses_all(1, (far, cmd("joint", 2, 150)), order)
    assert not d.refuses_all(1, (far, near), order)                  # one it can carry out
    assert not d.refuses_all(1, (), order)                           # nothing to refuse
    assert not d.refuses_all(BROADCAST, (far,), order)               # a broadcast order
    assert not d.refuses_all(1, (far,), int(FrameType.FAILURE))      # news is only noted


def test_a_full_queue_ends_the_childs_replies_for_the_moment_and_says_so():
    """Both MACs refuse a message with QueueFull (a SubmitError) while ``max_queue`` wait;
    the child then stops offering the rest of its replies, which would be refused too (the
    queue drains only in turns: the saturated ring used to offer 28,000 in 600 s). They were
    dropped unsaid: now counted (``replies_dropped``) and noted in the dispatcher's log."""
    from firmware_model.radio.frame import FrameType
    from firmware_model.radio.mac import MacConfig, QueueFull, RotationalMac, SubmitError
    from firmware_model.radio.peer_macs import AlohaMac
    for mac in (RotationalMac(1, MacConfig(max_queue=2)), AlohaMac(1, MacConfig(max_queue=2))):
        mac.submit(0, [cmd("status")], 0)
        mac.submit(0, [cmd("status")], 0)
        with pytest.raises(QueueFull, match="queue full"):
            mac.submit(0, [cmd("status")], 0)
        assert issubclass(QueueFull, SubmitError)
    w, evs = child_world()
    child = w.children[1]
    offered = []
    real = child.station.submit

    def submit(dst, commands, type_=2):
        offered.append(commands)
        return real(dst, commands, type_)
    child.station.submit = submit
    mac = child.station.mac
    while mac.pending < mac.cfg.max_queue:
        mac.submit(0, [cmd("status")], w.now)
    before = mac.pending
    d = child.dispatcher
    d.on_message(0, 1, (cmd("movex", 123456789),) * 3, w.now, int(FrameType.INSTRUCTION))
    child._pump()
    assert mac.pending == before and len(offered) == 1      # one refused, the rest not offered
    assert not d.has_output()
    assert d.replies_dropped == 3
    assert d.log[-1][1] == "3 replies dropped: the radio's queue is full"


def test_the_logs_keep_a_tail_not_a_days_record(monkeypatch):
    """The dispatcher's log and each submodule's events keep their latest entries (between
    the bound and twice it), so a day's loaded run does not grow them without end."""
    from can_bus.submodules import node
    from firmware_model.dispatcher import Dispatcher
    d = Dispatcher(1)
    for i in range(3 * Dispatcher.LOG_KEEP + 5):
        d._note((i, "x"))
    assert Dispatcher.LOG_KEEP <= len(d.log) < 2 * Dispatcher.LOG_KEEP
    assert d.log[-1] == (3 * Dispatcher.LOG_KEEP + 4, "x")
    monkeypatch.setattr(node, "EVENTS_KEEP", 4)
    w = World(SimConfig(robots=(0, 1, 2), duration=40, seed=3, can=True, load=2.0))
    w.run()
    events = [ev for nodes in w.submodules.values() for n in nodes.values() for ev in n.events]
    assert events and all(len(n.events) < 8 for nodes in w.submodules.values()
                          for n in nodes.values())
    assert max(t for t, *_ in events) > 30 * 16_000_000      # the latest kept


def test_a_burst_of_replies_beyond_the_radios_queue_is_counted_dropped():
    """A message of 33 ``status()`` orders, then one more: 34 replies, and the radio's queue
    holds 32 messages, so some are dropped (a child cannot answer faster than its turns carry
    the answers). They were dropped unsaid; every reply is now sent or counted dropped."""
    w = World(SimConfig(robots=(0, 1, 2), duration=40.0, can=True, seed=1,
                        keep_records=True))
    w.run(s_to_ticks(5.0))
    w.submit(0, 1, [cmd("status")] * 33)
    w.run(s_to_ticks(5.3))
    w.submit(0, 1, [cmd("status")])
    w.run()
    sent = [m for m in w.messages if m.src == 1 and m.dst == 0]
    dropped = w.children[1].dispatcher.replies_dropped
    assert dropped > 0 and len(sent) + dropped == 34
    assert w.stats[1].delivered == len(sent) and w.summary()["pending"] == 0


# -- orders that overlap, restarts and lost events (outside checks of the order book) ------

def _status(d, i, angle, state, seq, now):
    """Joint ``i`` says where it is: its STATUS frame (state 1 moving, 2 holding)."""
    d.on_can(dbc.encode_raw(f"JOINT{i}_STATUS", angle=round(angle * 100), speed=0,
                            state=state, seq=seq), now)


def _event_done(d, i, now):
    d.on_can(dbc.encode(f"EVENT{i}", kind="done", seq=d._seq[i], code=0), now)


def test_a_move_one_of_whose_joints_a_newer_order_takes_is_not_reported_done():
    """``movez(60)`` then ``joint(4,-30)``: the move never reaches its pose, yet it was
    reported done() when its other joints arrived. It is superseded as a whole now: no
    report; the newer order is reported when joint 4 arrives."""
    from firmware_model.dispatcher import Dispatcher
    d = Dispatcher(1)
    d.on_message(0, 1, (cmd("movez", 60),), 0)
    moved = sorted(d.jobs[0].waiting)
    assert 4 in moved and len(moved) > 1
    d.on_message(0, 1, (cmd("joint", 4, -30),), 10)
    for i in moved:
        _event_done(d, i, 20)
    assert d.take_radio() == [(0, (cmd("done"), cmd("joint", 4, -30)), 3)]


def test_the_same_action_ordered_again_mid_motion_is_announced_when_it_arrives():
    """A second ``act(1,0)`` while action 1 runs: every joint already sent there, so it
    used to announce ``act(1,1)`` at once, mid-motion. It waits for the same arrival now:
    both orders are announced when the joints report done, not before."""
    from firmware_model.dispatcher import Dispatcher
    d = Dispatcher(1)
    d.on_message(0, 1, (cmd("act", 1, 0),), 0)
    d.on_message(0, 1, (cmd("act", 1, 0),), 10)
    assert [c for _, c, _ in d.take_radio()] == [(cmd("act", 1, 0),)] * 2   # no act(1,1)
    assert len(d.jobs) == 2
    for i in sorted(d.jobs[0].waiting):
        _event_done(d, i, 20)
    assert [c for _, c, _ in d.take_radio()] == [(cmd("act", 1, 1),)] * 2


def test_a_joint_not_where_it_was_sent_is_moved_there_again():
    """The submodules restarted (their joints at rest) after joint 1 was sent to 40 deg: a
    new ``joint(1,40)`` was taken for a move to where the arm already is (no command, no
    report, ``unreported``). A fresh status that says otherwise makes it a move."""
    from firmware_model.dispatcher import Dispatcher
    d = Dispatcher(1)
    d.on_message(0, 1, (cmd("joint", 1, 40),), 0)
    _event_done(d, 1, 10)
    d.take_radio(), d.take_can()
    _status(d, 1, 0.0, 0, 0, 20)                     # restarted: at rest, its seq 0
    d.on_message(0, 1, (cmd("joint", 1, 40),), 30)
    sent = [dbc.decode(f) for f in d.take_can()]
    assert [(n, m["angle"]) for n, m in sent] == [("JOINT1_CMD", 40.0)]
    _status(d, 1, 40.0, 2, 0, 40)                    # where it was sent: already there
    d.jobs.clear()
    d.on_message(0, 1, (cmd("joint", 1, 40),), 50)
    assert d.take_can() == [] and d.jobs == []


def test_a_joint_holding_after_the_command_finishes_the_order_its_done_event_lost():
    """A bench child stalled mid-move on a software bus that dropped frames meanwhile: the
    joint's done EVENT was lost, and the order failed fail(31) though the status said the
    joint held its target. A status frame holding with the command's seq finishes it."""
    from firmware_model.dispatcher import Dispatcher
    d = Dispatcher(1)
    d.on_message(0, 1, (cmd("joint", 1, 100),), 0)
    seq = d._seq[1]
    _status(d, 1, 50.0, 1, seq, 10)                   # moving: not yet
    assert d.take_radio() == []
    _status(d, 1, 100.0, 2, seq - 1, 20)              # holding, an older command's: not yet
    assert d.take_radio() == []
    _status(d, 1, 100.0, 2, seq, 30)
    assert d.take_radio() == [(0, (cmd("done"), cmd("joint", 1, 100)), 3)]


def test_an_order_for_one_joint_waits_for_no_other():
    """``joint(2,45)`` (where joint 2 already is) while joint 1 still moves: it waited for
    joint 1's arrival and was reported done (the arm's whole commanded pose was taken for its
    concern). It is about joint 2 alone: a move to where it already is, no report."""
    from firmware_model.dispatcher import Dispatcher
    d = Dispatcher(1)
    _status(d, 2, 45.0, 0, 0, 0)
    d.on_message(0, 1, (cmd("joint", 1, 20),), 10)
    _status(d, 1, 5.0, 1, d._seq[1], 20)               # joint 1 on its way
    d.on_message(0, 1, (cmd("joint", 2, 45),), 30)
    assert [j.command for j in d.jobs] == [cmd("joint", 1, 20)]
    _event_done(d, 1, 40)
    assert d.take_radio() == [(0, (cmd("done"), cmd("joint", 1, 20)), 3)]


def _replies(w, since=0):
    return [(m.submitted, "".join(c.text() for c in m.commands)) for m in w.messages
            if m.src == 1 and m.dst == 0 and m.submitted >= since]


def test_status_is_answered_again_once_the_blocked_bus_is_back():
    """One blocked second (a stuck TXD), then the bus works (the next order is carried out
    and reported done), yet every later status() was answered fail(41): the dispatcher's
    flag was never cleared by the driver's retry."""
    w, evs = child_world(duration=12.0)
    xcvr = w.children[1].can.xcvr
    xcvr.stick_txd(True)
    w.run(START + s_to_ticks(1.0))
    xcvr.stick_txd(False)
    w.run(START + s_to_ticks(3.0))                 # the retry, a second after the isolation
    send(w, [cmd("joint", 1, 30)])
    w.run(START + s_to_ticks(5.0))
    t = w.now
    send(w, [cmd("status")])
    w.run(t + s_to_ticks(1.0))
    after = [r for _, r in _replies(w, since=t)]
    assert len(after) == 1 and after[0].startswith("joint(1,30)"), _replies(w)
    assert any(r == "done()joint(1,30)" for _, r in _replies(w))


def test_a_bus_off_is_no_blocked_bus_and_its_failed_order_is_not_carried_out_later():
    """A bus-off on a joint command: fail(40) for the order, then 49 ms later fail(41) (the
    blocked-bus watch took the halted controller's silence for a blocked bus) and a second in
    standby, after which the failed order's command went out and the joint moved."""
    w, evs = child_world(duration=10.0)
    w.inject("busoff", 1, w.now + s_to_ticks(0.5), None)
    w.run(w.now + s_to_ticks(1.0))
    t = w.now
    send(w, [cmd("joint", 1, 30)])
    w.run(t + s_to_ticks(3.0))
    replies = [r for _, r in _replies(w, since=t)]
    assert replies == ["fail(40)joint(1,30)"], replies
    assert w.children[1].can.isolations == 0
    assert not [s for n, s in commands_after(evs, t) if n == "JOINT1_CMD"]
    assert w.submodules[1]["JOINT1"].angle_deg == pytest.approx(0, abs=0.01)
    send(w, [cmd("joint", 1, 20)])                  # restarted: the next order is done
    w.run()
    assert w.submodules[1]["JOINT1"].angle_deg == pytest.approx(20, abs=0.01)
    assert _replies(w)[-1][1] == "done()joint(1,20)"


@pytest.mark.parametrize("after", [[cmd("movey", 0)], [cmd("movez", 10)]])
def test_relative_moves_after_stop_start_where_the_arm_stopped(after):
    """``joint(1,90)``, ``stop()`` mid-motion, then ``movey(0)``: the hold was recorded at the
    last status (up to 100 ms old, 57.13 deg where the joint stopped at 59.58), so movey(0)
    moved the tip 10.7 mm and movez(10) moved it sideways too."""
    from firmware_model.kinematics import forward
    w, evs = child_world(duration=10.0)
    send(w, [cmd("joint", 1, 90)])
    w.run(START + s_to_ticks(1.0))
    send(w, [cmd("stop")])
    w.run(START + s_to_ticks(3.0))
    subs = w.submodules[1]
    before = forward(tuple(subs[f"JOINT{i}"].angle_deg for i in range(1, 5)))
    send(w, after)
    w.run()
    end = forward(tuple(subs[f"JOINT{i}"].angle_deg for i in range(1, 5)))
    dz = 10.0 if after[0].name == "movez" else 0.0
    assert (end.x - before.x, end.y - before.y, end.z - before.z) == pytest.approx(
        (0.0, 0.0, dz), abs=0.05)

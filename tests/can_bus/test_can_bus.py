"""Simulated CAN bus on the tick scheduler: timing, arbitration, fault confinement, faults."""
from __future__ import annotations

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from can_bus.bits import BitTiming, frame_length_bits, wire_bits
from can_bus.bus import CanBus, ErrorState
from can_bus.frames import CanFrame
from firmware_model.mcu.scheduler import Scheduler

from can_testbed import TPB, Node, QueueNode, make


def flen(f: CanFrame, ifs=True) -> int:
    return frame_length_bits(f.id, f.data, f.rtr, include_ifs=ifs, dlc=f.dlc)


def nstuffed(f: CanFrame) -> int:
    return len(wire_bits(f.id, f.data, f.rtr, f.dlc)) - 10


# ---------------------------------------------------------------- frames
def test_canframe_message_round_trip():
    f = CanFrame(0x123, b"\x01\x02\x03")
    m = f.to_message()
    assert isinstance(m, can.Message)
    assert (m.arbitration_id, m.is_extended_id, m.is_remote_frame, m.dlc, bytes(m.data)) == (
        0x123, False, False, 3, b"\x01\x02\x03")
    assert CanFrame.from_message(m) == f
    r = CanFrame(0x7FF, rtr=True, dlc=4)
    assert CanFrame.from_message(r.to_message()) == r
    assert CanFrame(5).dlc == 0 and CanFrame(5, bytearray(b"ab")).data == b"ab"
    with pytest.raises(ValueError):
        CanFrame.from_message(can.Message(arbitration_id=0x123, is_extended_id=True))
    with pytest.raises(ValueError):
        CanFrame(0x800)
    with pytest.raises(ValueError):
        CanFrame(1, bytes(9))


# ---------------------------------------------------------------- timing
def test_single_frame_exact_ticks():
    sched, bus, (a, b), log, _ = make()
    f = CanFrame(0x000, bytes(8))  # 127 bits with IFS (hand-checked in test_can_bits)
    bus.request(a, f)
    bus.request(a, f)
    sched.run_until(10_000)
    assert [(s, e) for _, s, e, _ in log] == [(0, 124 * TPB), (127 * TPB, 251 * TPB)]
    assert a.done == [(f, 124 * TPB), (f, 251 * TPB)]
    assert b.rx == [(f, 0, 3968), (f, 4064, 8032)]
    assert bus.idle and bus.frames_ok == 2


@settings(max_examples=40, deadline=None)
@given(
    st.integers(0, 0x7FF),
    st.binary(max_size=8),
    st.sampled_from([BitTiming(), BitTiming.from_bitrate(125_000),
                     BitTiming.from_bitrate(1_000_000)]),
)
def test_frame_takes_length_times_ticks_per_bit(can_id, data, timing):
    sched, bus, (a, b), log, _ = make(timing=timing)
    f = CanFrame(can_id, data)
    sched.run_until(1000)
    bus.request(a, f)
    bus.request(a, f)
    sched.run_until(10**6)
    tpb = timing.ticks_per_bit
    (_, s1, e1, _), (_, s2, e2, _) = log
    assert s1 == 1000
    assert e1 - s1 == e2 - s2 == flen(f, ifs=False) * tpb
    assert s2 - s1 == flen(f) * tpb


# ---------------------------------------------------------------- arbitration
def test_three_simultaneous_senders():
    sched, bus, (a, b, c), log, _ = make(3)
    fa, fb, fc = CanFrame(0x300, b"\x01"), CanFrame(0x100, b"\x02\x03"), CanFrame(0x200)
    assert (flen(fb), flen(fc), flen(fa)) == (67, 51, 59)
    bus.request(a, fa)
    bus.request(b, fb)
    bus.request(c, fc)
    sched.run_until(100_000)
    assert [(f, s, e, w) for f, s, e, w in log] == [
        (fb, 0, 64 * TPB, b),          # 0x100 wins at tick 0, ends 2048
        (fc, 67 * TPB, 115 * TPB, c),  # 0x200 starts 2144, ends 3680
        (fa, 118 * TPB, 174 * TPB, a),  # 0x300 starts 3776, ends 5568
    ]
    assert a.lost == [fa, fa] and c.lost == [fc] and b.lost == []
    assert [x[0] for x in a.rx] == [fb, fc]


def test_data_frame_beats_remote_frame_and_late_joiner():
    sched, bus, (a, b, c), log, _ = make(3)
    remote, data = CanFrame(0x050, rtr=True, dlc=2), CanFrame(0x050, b"\xAA\xBB")
    bus.request(a, remote)
    bus.request(b, data)
    sched.run_until(5 * TPB)       # data frame on the bus now
    bus.request(c, CanFrame(0x010))  # joins at the next idle and beats the waiting remote frame
    sched.run_until(100_000)
    assert [f for f, *_ in log] == [data, CanFrame(0x010), remote]
    assert log[1][1] == flen(data) * TPB
    assert log[2][1] == (flen(data) + flen(CanFrame(0x010))) * TPB


def test_pending_style_nodes_and_priority_inside_a_node():
    sched, bus, (a, b), log, _ = make(2, cls=QueueNode)
    a.q += [CanFrame(0x400), CanFrame(0x020, b"x")]
    b.q += [CanFrame(0x030)]
    bus.request(a)
    sched.run_until(100_000)
    assert [f.id for f, *_ in log] == [0x020, 0x030, 0x400]
    assert a.q == [] and b.q == []


def test_identical_frames_merge_and_same_id_collision():
    sched, bus, (a, b, c), log, errs = make(3)
    f = CanFrame(0x111, b"\x01")
    bus.request(a, f)
    bus.request(b, f)
    sched.run_until(10_000)
    assert len(log) == 1 and a.done and b.done and c.rx[0][0] == f
    # Same id, different data (forbidden): bit error for both transmitters at the first
    # differing wire bit; they keep colliding until both are bus-off.
    sched2, bus2, (a2, b2, c2), log2, errs2 = make(3)
    bus2.request(a2, CanFrame(0x111, b"\x01"))
    bus2.request(b2, CanFrame(0x111, b"\x03"))
    sched2.run_until(10_000)
    w1, w2 = wire_bits(0x111, b"\x01"), wire_bits(0x111, b"\x03")
    k = next(i for i, (x, y) in enumerate(zip(w1, w2)) if x != y)
    assert errs2[0][0] == "bit" and errs2[0][3] == (k + 1) * TPB
    assert bus2.tec(a2) == bus2.tec(b2) > 0 and bus2.rec(c2) > 0 and not log2


# ---------------------------------------------------------------- error confinement
def test_error_walk_to_passive_bus_off_and_recovery():
    sched, bus, (a, b), log, errs = make(2)
    f = CanFrame(0x123, b"\x11\x22")
    n = nstuffed(f)
    assert n == 52 and flen(f) == 65
    bus.inject_bit_error(a, count=32)  # default bit: last bit of the stuffed CRC field
    bus.request(a, f)
    sched.run_until(200_000)

    starts, flags, idles = [], [], []
    s = 0
    for i in range(1, 33):
        e = s + n * TPB           # error flag starts right after bit n-1
        idle = e + 17 * TPB       # 6 flag + 8 delimiter + 3 intermission
        starts.append(s)
        flags.append(e)
        idles.append(idle)
        s = idle + (8 * TPB if i >= 16 else 0)  # error-passive: suspend transmission
    assert [x[2] for x in errs] == starts
    assert [x[3] for x in errs] == flags
    assert [x[4] for x in errs] == idles
    assert [ev.tec for ev in a.errors] == [8 * i for i in range(1, 33)]
    assert [ev.rec for ev in b.errors] == list(range(1, 33))
    recovery = idles[-1] + 127 * 11 * TPB  # 1397 idle bits (error delim + IFS was the 1st 11)
    assert (flags[15], flags[31], idles[31], recovery) == (34784, 74208, 74752, 119456)
    assert a.states == [
        ("error-active", "error-passive", flags[15]),
        ("error-passive", "bus-off", flags[31]),
        ("bus-off", "error-active", recovery),
    ]
    # The frame is still pending and goes out the moment the node is back.
    assert log == [(f, recovery, recovery + 62 * TPB, a)]
    assert (bus.tec(a), bus.rec(a), bus.rec(b)) == (0, 0, 31)
    assert b.rx == [(f, recovery, recovery + 62 * TPB)]


def test_bus_off_node_cannot_send_or_receive_and_recovers_later_if_bus_busy():
    # a goes bus-off (injected errors), b then keeps the bus busy with back-to-back frames:
    # every frame gives a only one 11-recessive-bit occurrence.
    sched, bus, (a, b, c), log, errs = make(3)
    fa = CanFrame(0x100)
    bus.inject_bit_error(a, count=32)
    bus.request(a, fa)
    sched.run_until(1)
    while len(errs) < 32:
        sched.step()
    idle0 = errs[-1][4]
    fb = CanFrame(0x200, bytes(8))
    for _ in range(200):
        bus.request(b, fb)
    sched.run_until(idle0 - 1)
    assert bus.error_state(a) is ErrorState.BUS_OFF
    sched.run_until(idle0 + 500 * flen(fb) * TPB)
    b_frames = [x for x in log if x[0] == fb]
    # b's frames start at idle0 back to back; a counted 1 (error frame) + 1 per frame of b.
    assert b_frames[0][1] == idle0
    assert all(y[1] - x[1] == flen(fb) * TPB for x, y in zip(b_frames[:127], b_frames[1:127]))
    a_frames = [x for x in log if x[0] == fa]
    # After 127 of b's frames a has 128 occurrences: it recovers at the end of the 127th
    # frame's intermission and wins the next arbitration (0x100 < 0x200).
    assert a_frames[0][1] == idle0 + 127 * flen(fb) * TPB
    assert a.states[-1] == ("bus-off", "error-active", a_frames[0][1])
    assert b_frames[127][1] == a_frames[0][1] + flen(fa) * TPB
    assert len([x for x in a.rx if x[1] < a_frames[0][1]]) == 0  # bus-off: nothing received


def test_ack_error_when_alone_then_passive_forever():
    sched, bus, (a,), log, errs = make(1)
    f = CanFrame(0x123, b"\x11\x22")
    n = nstuffed(f)
    bus.request(a, f)
    starts, s = [], 0
    for i in range(1, 41):
        starts.append(s)
        e = s + (n + 2) * TPB  # ACK slot recessive -> flag from the ACK delimiter
        s = e + 17 * TPB + (8 * TPB if i >= 16 else 0)
    sched.run_until(starts[-1] + 10)
    assert [x[2] for x in errs] == starts[:39] and all(x[0] == "ack" for x in errs)
    assert [ev.tec for ev in a.errors] == [min(8 * i, 128) for i in range(1, 40)]
    assert bus.status(a).state is ErrorState.PASSIVE and bus.tec(a) == 128
    assert a.states == [("error-active", "error-passive", starts[15] + (n + 2) * TPB)]
    # A second node attached mid-frame is not a receiver of this attempt; the next one succeeds.
    b = Node("b")
    bus.attach(b)
    sched.run_until(s + 100 * TPB)
    assert len(errs) == 40
    assert log == [(f, s, s + (n + 10) * TPB, a)]
    assert (bus.tec(a), bus.error_state(a)) == (127, ErrorState.ACTIVE)


def test_suspend_transmission_yields_to_other_node():
    sched, bus, (a,), log, errs = make(1)
    f = CanFrame(0x001)
    bus.request(a, f)
    sched.run_until(1)
    while len(errs) < 16:
        sched.step()
    idle = errs[-1][4]  # a is error-passive and suspended until idle + 8 bits
    b = Node("b")
    bus.attach(b)
    sched.run_until(idle + 3 * TPB)
    g = CanFrame(0x7F0)
    bus.request(b, g)  # b starts during a's suspension although a has the lower id
    sched.run_until(idle + 1000 * TPB)
    assert [(x[0], x[1]) for x in log] == [(g, idle + 3 * TPB), (f, idle + 3 * TPB + flen(g) * TPB)]


# ---------------------------------------------------------------- stuck dominant
def test_stuck_dominant_blocks_everyone():
    sched, bus, (a, b, c), log, errs = make(3)
    fa, fb = CanFrame(0x100, b"\x01"), CanFrame(0x080, b"\x02")
    bus.request(a, fa)
    H = 10 * TPB + 5  # mid-frame, not on a bit boundary
    sched.run_until(H)
    bus.hold_dominant(c, True)
    F = H  # frame in flight: error flag from the hold tick
    sched.run_until(20 * TPB)
    bus.request(b, fb)
    bus.request(c, CanFrame(0x001))
    sched.run_until(H + 1000 * TPB)
    assert log == [] and not a.done and not b.done
    assert [(e.kind, e.tick, e.transmitter) for e in a.errors] == [("bit", F, True)]
    assert [(e.kind, e.tick, e.transmitter) for e in b.errors] == [("stuff", F, False)]
    assert [(e.kind, e.tick) for e in c.errors] == [("stuff", F)]
    # TEC 8 at F, +8 at the 14th dominant bit and every 8 after: > 255 at F + 254 bits.
    assert a.states == [("error-active", "error-passive", F + 126 * TPB),
                        ("error-passive", "bus-off", F + 254 * TPB)]
    # REC 1 at F, 9 at F + 7 bits, 129 at F + 126 bits.
    assert b.states == c.states == [("error-active", "error-passive", F + 126 * TPB)]
    bits = (sched.now - F) // TPB
    assert bus.rec(b) == 1 + 8 + 8 * (1 + (bits - 14) // 8)
    assert bus.error_state(a) is ErrorState.BUS_OFF and bus.held and not bus.idle

    R = H + 1000 * TPB + 7
    sched.run_until(R)
    bus.hold_dominant(c, False)
    idle = R + 11 * TPB  # error delimiter 8 + intermission 3
    sched.run_until(idle + 2000 * TPB)
    f1 = CanFrame(0x001)
    # c (0x001) and b (0x080) compete at idle; a stays bus-off.
    assert [(fr, s_) for fr, s_, *_ in log[:2]] == [(f1, idle), (fb, idle + flen(f1) * TPB)]
    idle_b = idle + (flen(f1) + flen(fb)) * TPB
    # a counted 1 occurrence at each of the 2 SOFs (11 recessive bits before each), so it
    # needs 126 more: the 11 trailing bits of b's frame + 125 * 11 idle bits. Its aborted frame
    # is still pending and is sent at once.
    recovery = idle_b + (126 * 11 - 11) * TPB
    assert a.states[-1] == ("bus-off", "error-active", recovery)
    assert log[2][:2] == (fa, recovery)
    assert bus.status(b).state is ErrorState.ACTIVE  # REC set to 127 on reception


def test_stuck_dominant_on_idle_bus_and_short_glitch():
    sched, bus, (a, b), log, errs = make(2)
    H = 1000
    sched.run_until(H)
    bus.hold_dominant(a, True)
    sched.run_until(H + 2 * TPB)
    bus.request(b, CanFrame(0x42))
    bus.hold_dominant(a, False)  # released before anyone detected the error
    sched.run_until(H + 200 * TPB)
    F = H + 6 * TPB  # SOF + 5 dominant bits: stuff error at the 6th
    assert [(e.kind, e.tick) for e in a.errors] == [("stuff", F)]
    assert [(e.kind, e.tick) for e in b.errors] == [("stuff", F)]
    assert (bus.rec(a), bus.rec(b)) == (0, 1)  # a received b's frame afterwards: 1 -> 0
    assert log[0][1] == F + (6 + 11) * TPB  # own flags 6 + delimiter 8 + intermission 3
    with pytest.raises(ValueError):
        bus.hold_dominant(Node("x"), True)


# ---------------------------------------------------------------- random fault mix
op_st = st.tuples(
    st.integers(0, 3000),                      # ticks to advance first
    st.sampled_from(["req", "req", "req", "inject", "hold", "release"]),
    st.integers(0, 3),                         # node index (mod node count)
    st.integers(0, 0x1FF),                     # id bits / count
    st.binary(max_size=8),
)


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 4), st.lists(op_st, max_size=40))
def test_random_traffic_and_faults_keep_invariants(n_nodes, ops):
    sched, bus, nodes, log, errs = make(n_nodes)
    t = requested = 0
    for dt, op, i, x, data in ops:
        t += dt
        sched.run_until(t)
        node = nodes[i % n_nodes]
        if op == "req":
            # disjoint ids per node: same id with different data is a (modelled) bus fault
            bus.request(node, CanFrame(x * 4 + nodes.index(node), data))
            requested += 1
        elif op == "inject":
            bus.inject_bit_error(node if x & 1 else None, count=x % 40,
                                 bit=None if x & 2 else x % 130)
        else:
            bus.hold_dominant(node, op == "hold")
        for m in nodes:
            s = bus.status(m)
            assert s.tec >= 0 and s.rec >= 0
    for m in nodes:
        bus.hold_dominant(m, False)
    sched.run_until(t + 10**8)
    assert bus.idle
    assert sum(len(m.done) for m in nodes) == requested  # all sent once faults are gone
    spans = sorted([(s_, e + 3 * TPB) for _, s_, e, _ in log]
                   + [(e[2], e[4]) for e in errs if e[4] is not None])
    assert all(q[0] >= p[1] for p, q in zip(spans, spans[1:]))  # nothing overlaps on the wire


class CountingNode(QueueNode):
    """A QueueNode that counts how often the bus asks it for a frame."""

    def __init__(self, name):
        super().__init__(name)
        self.asked = 0

    def pending(self):
        self.asked += 1
        return super().pending()


class AfterRequestNode(CountingNode):
    pending_after_request = True


def test_a_node_pending_after_request_is_asked_again_only_after_its_request():
    # Node a sends three frames; b has nothing the whole time. b without the promise is asked
    # at every arbitration (at each request and at each frame's end); with it, only at the
    # first one, then never again until it requests (can_bus/bus.py, Nodes).
    for cls, b_asked in ((CountingNode, 6), (AfterRequestNode, 1)):
        sched, bus, (a, b), log, _ = make(2, cls=cls)
        for k in range(3):
            sched.at(k * 3000, lambda k=k, a=a, bus=bus: (a.q.append(CanFrame(0x100 + k, b"x")),
                                                          bus.request(a)))
        sched.run_until(10_000)
        assert [f.id for f, *_ in log] == [0x100, 0x101, 0x102]
        assert b.asked == b_asked, cls.__name__
        # a frame b queues is sent once b asks the bus, however long b was left alone
        b.q.append(CanFrame(0x050, b"y"))
        sched.at(12_000, bus.request, b)
        sched.run_until(15_000)
        assert [f.id for f, *_ in log][-1] == 0x050
        assert b.done and b.done[-1][0].id == 0x050


class FilteringNode(Node):
    """A node that acts only on identifier 0x120 and says so (``rx_ids``)."""

    rx_ids = frozenset({0x120})


class DeafNode(Node):
    acknowledges = False


def test_a_passive_transmitters_ack_error_is_no_error_for_receivers_that_cannot_ack():
    """a sends to c alone, which cannot drive the ACK slot (a halted controller, a transceiver
    in standby). While a is error-active its flag destroys the frame (c's REC + 1 each time);
    from TEC 128 on its flag is recessive, so c sees a whole frame, takes it at each retry and
    works its REC off (ISO 11898-1 exception 1). c's REC used to climb past 127 (error-passive
    with no error of its own) and it never received the frame."""
    sched = Scheduler()
    bus = CanBus(sched, BitTiming())
    a, c = Node("a"), DeafNode("c")
    bus.attach(a)
    bus.attach(c)
    bus.request(a, CanFrame(0x123, b"\x01"))
    sched.run_until(2_000_000)
    assert bus.tec(a) == 128 and set(e.kind for e in a.errors) == {"ack"}
    assert len(c.rx) > 20 and all(f.id == 0x123 for f, *_ in c.rx)
    assert bus.rec(c) == 0 and bus.error_state(c) is ErrorState.ACTIVE


def _filter_run(b_cls):
    """a sends 0x110, 0x120, 0x130 (the first one destroyed by a local error at b), then
    0x140 once b is gone; c cannot acknowledge."""
    sched = Scheduler()
    bus = CanBus(sched, BitTiming())
    a, b, c = Node("a"), b_cls("b"), DeafNode("c")
    for x in (a, b, c):
        bus.attach(x)
    log = []
    bus.trace = lambda f, s_, e, w: log.append((f, s_, e, w.name))
    bus.inject_local_error(b)
    for k, fid in enumerate((0x110, 0x120, 0x130)):
        sched.at(k * 3000, bus.request, a, CanFrame(fid, b"x"))
    sched.run_until(20_000)
    seen = (log[:], [(f.id, t) for f, t in a.done], [e.kind for e in a.errors],
            bus.rec(b), bus.tec(a), list(c.rx))
    bus.detach(b)
    sched.at(sched.now, bus.request, a, CanFrame(0x140, b"y"))
    sched.run_until(sched.now + 3000)
    return seen, b.rx, [e.kind for e in a.errors]


def test_a_node_with_rx_ids_hears_only_those_and_the_bus_runs_as_without_them():
    """``rx_ids`` only spares the calls: b still acknowledges every frame (c cannot, so
    without b a frame ends in an ACK error), its REC follows every frame, the timing is the
    same."""
    plain, plain_rx, _ = _filter_run(Node)
    filtered, filtered_rx, errors = _filter_run(FilteringNode)
    assert filtered == plain
    assert [f.id for f, *_ in plain_rx] == [0x110, 0x120, 0x130]
    assert [f.id for f, *_ in filtered_rx] == [0x120]
    log, done, _, rec, _, c_rx = plain
    assert [i for i, _ in done] == [0x110, 0x120, 0x130] and len(c_rx) == 3
    assert rec > 0                         # the local error, partly worked off
    assert errors[-1] == "ack"             # 0x140 with nobody able to acknowledge it


@pytest.mark.parametrize("bit", [1, 3, 7, 12])
def test_a_bit_error_injected_in_the_arbitration_field_comes_after_it(bit):
    """A transmitter reading dominant on its recessive identifier bit has lost arbitration,
    which is no error (ISO 11898-1): an error injected there gave it TEC + 8 at that bit. It
    comes, as a local error does, at the first bit after the arbitration field."""
    from can_bus.bus_state import _arbitration_end, _frame_info
    f = CanFrame(0x7FF, b"\x00")
    after = _arbitration_end(_frame_info(f)[0]) + 1
    assert bit < after
    sched, bus, (a, b), log, errs = make(2)
    bus.inject_bit_error(a, 1, bit=bit)
    bus.request(a, f)
    sched.run_until(400 * TPB)
    assert [(e.kind, e.tick // TPB) for e in a.errors] == [("bit", after + 1)]
    assert [e.tick // TPB for e in b.errors] == [after + 1]
    assert len(log) == 1 and bus.tec(a) == 7                 # +8, then -1 for the retry

"""Regression tests for the promises that failed under attack from outside (issue: "every
promise holds under attack"). Each test reproduces one finding in the simulator, to the tick,
and failed before the fix it names. docs/guarantees.md lists them with their bounds."""
from __future__ import annotations

import random

import pytest

from firmware_model.radio.content import cmd
from firmware_model.radio.frame import Frame, FrameType
from firmware_model.radio.mac import (
    MEMBER, Deliver, Duplicate, MacConfig, ModeChange, Outcome, RotationalMac, StandingBy,
    Transmit,
)
from firmware_model.timing import (
    CHILD_BYTE_TICKS, PC_BYTE_TICKS, TMAX_TICKS, TTRANS_TICKS, protocol_max_content, s_to_ticks,
)
from hil.sim.faults import Fault, parse_fault
from hil.sim.world import SimConfig, World
from contents import content_of

B = PC_BYTE_TICKS          # a foreign transmitter's byte time (9600 baud)


def _run_until_txen(w, evs, robot, after):
    """Run ``w`` until ``robot`` raises TXEN at or after tick ``after``; return that tick."""
    while True:
        w.run(w.now + 1000)
        on = [e["t"] for e in evs if e["ev"] == "txen" and e["robot"] == robot and e["on"]
              and e["t"] >= after]
        if on:
            return on[0]


def _frames(evs, after=0):
    return [e for e in evs if e["ev"] == "frame" and e["start"] >= after]


# -- finding 1: no lock-step after a foreign burst over a hand-over --------------------------

def two_bursts_over_a_handover(robots=(1, 2), seed=1):
    """A foreign transmitter garbles R1's frame and goes on past its End (R2 hears garbage in
    R1's slot), and a second burst starts once R1 listens again (R1 hears garbage in R2's
    slot): each member believes the other's turn just closed on a corrupted frame."""
    evs: list[dict] = []
    w = World(SimConfig(robots=robots, duration=7.0, seed=seed), on_event=evs.append)
    w.run(s_to_ticks(4.0))
    start = _run_until_txen(w, evs, 1, s_to_ticks(4.0)) + TTRANS_TICKS
    end = start + 14 * CHILD_BYTE_TICKS                # R1's heartbeat
    w.inject_bytes(random.Random(1).randbytes(15), end - 5 * B)
    w.inject_bytes(random.Random(2).randbytes(6), end + 6 * B)
    w.run()
    return w, evs, end + 12 * B


def test_two_members_never_transmit_together_after_a_foreign_burst():
    w, evs, burst_end = two_bursts_over_a_handover()
    after = [e for e in evs if e["ev"] == "collision" and e["t"] > burst_end]
    assert after == [], after
    assert not [e for e in evs if e["ev"] in ("miss", "disable") and e["t"] > burst_end]
    good = [f for f in _frames(evs, burst_end) if not f["collided"]]
    # good frames resume within Tmax plus one idle cycle of the two-member ring
    assert good and good[0]["start"] - burst_end < TMAX_TICKS + 2 * (
        14 * CHILD_BYTE_TICKS + TTRANS_TICKS)
    assert w.ring_views() == {1: (1, 2), 2: (1, 2)}


def test_the_lower_id_goes_first_after_a_turn_closes_on_garbage():
    """Rule R-stagger: both believed the turn was theirs; R1 (lower ID) raises TXEN one Tslot
    after the channel fell quiet, R2 would have waited two: it hears R1's Header first."""
    w, evs, burst_end = two_bursts_over_a_handover()
    first = [f for f in _frames(evs, burst_end)][0]
    assert first["src"] == 1 and not first["collided"]


# -- finding 2: a forged frame from a team robot that was never a member --------------------

def test_a_forged_frame_from_a_never_member_is_refused_and_not_acted_on():
    probe_evs: list[dict] = []
    cfg = dict(robots=(1, 2, 3, 4), can=True, power_on={4: 60.0})   # R4 never powers on
    probe = World(SimConfig(duration=5.0, **cfg), on_event=probe_evs.append)
    probe.run()
    e2 = [e for e in probe_evs if e["ev"] == "frame" and e["src"] == 2][-1]["end"]
    evs: list[dict] = []
    w = World(SimConfig(duration=9.0, **cfg), on_event=evs.append)
    w.inject("fail", 2, e2 + 1)                       # R2's radio dies after its turn
    w.run(e2 + s_to_ticks(0.1))                       # R3 and R1 take their turns
    e1 = [e for e in evs if e["ev"] == "frame" and e["src"] == 1][-1]["end"]
    joints_before = [e for e in evs if e["ev"] == "can" and e["bus"] == 3 and
                     0x101 <= e["id"] <= 0x104]
    forged = Frame(dst=3, src=4, num=42, type=2, content=b"joint(1,80)").encode()
    w.inject_bytes(forged, e1 + s_to_ticks(0.1))      # in R2's silent slot
    w.run()
    assert not [e for e in evs if e["ev"] in ("join", "rejoin") and e["robot"] == 4]
    assert not [e for e in evs if e["ev"] == "deliver" and e["src"] == 4]
    refused = [e for e in evs if e["ev"] == "refused" and e["src"] == 4]
    assert {e["to"] for e in refused} == {1, 3}
    assert all("not a member" in e["reason"] for e in refused)
    joints_after = [e for e in evs if e["ev"] == "can" and e["bus"] == 3 and
                    0x101 <= e["id"] <= 0x104]
    assert joints_after == joints_before               # R3's arm never moved
    assert all(4 not in v for v in w.ring_views().values())


# -- finding 3: the largest legal frame between every pair, father included -----------------

def test_every_station_receives_the_largest_frame_any_station_may_send():
    assert protocol_max_content() == 562
    w = World(SimConfig(robots=(0, 1, 2), duration=8.0))
    w.run(s_to_ticks(4.5))
    msgs = [w.submit(1, 0, content_of(562)),       # a child's largest, to the father
            w.submit(2, 1, content_of(562)),       # ... to another child
            w.submit(0, 2, content_of(561))]       # the father's own limit: 561
    w.run()
    assert [m.state for m in msgs] == ["delivered"] * 3, [m.reason for m in msgs]


def test_a_station_never_sends_more_than_the_protocol_bound():
    fast = RotationalMac(1, MacConfig(byte_ticks=16_000))     # a clock running 4 % fast
    assert fast.max_content == protocol_max_content()
    assert RotationalMac(0, MacConfig(byte_ticks=PC_BYTE_TICKS)).max_content == 561


# -- finding 4: a Header that has begun by E + Tmax is not a miss ----------------------------

def header_near_the_deadline(offset_ticks, cpu=None):
    """R2 dies after its turn; R3's slot then opens at R2's End E. A frame from R3 is put on
    air so that its first start bit begins at E + Tmax - ``offset_ticks`` (R3 itself is
    silent: this is R3's frame arriving late)."""
    probe_evs: list[dict] = []
    probe = World(SimConfig(robots=(1, 2, 3), duration=5.0, cpu=cpu), on_event=probe_evs.append)
    probe.run()
    e3 = [e for e in probe_evs if e["ev"] == "frame" and e["src"] == 3][-1]["end"]
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 3), duration=8.0, cpu=cpu), on_event=evs.append)
    w.inject("fail", 3, e3 + 1)
    w.run(e3 + s_to_ticks(0.05))
    e2 = [e for e in evs if e["ev"] == "frame" and e["src"] == 2][-1]["end"]
    late = Frame(dst=7, src=3, num=0, type=3, content=b"").encode()
    t = e2 + TMAX_TICKS - offset_ticks
    w.inject_bytes(late, t)
    w.run(t + s_to_ticks(0.5))
    return evs, e2, t


def test_a_header_beginning_one_byte_before_e_plus_tmax_is_not_a_miss():
    evs, e2, t = header_near_the_deadline(B)
    assert not [e for e in evs if e["ev"] == "miss" and e["robot"] == 3 and e["t"] > e2]
    assert not [e for e in evs if e["ev"] == "collision" and e["t"] >= t]
    nxt = [f for f in _frames(evs, t) if f["src"] == 1]
    assert nxt and nxt[0]["start"] == t + 14 * B + TTRANS_TICKS   # R1's turn after R3's frame


def test_a_header_beginning_half_a_byte_before_e_plus_tmax_is_not_a_miss():
    evs, e2, t = header_near_the_deadline(B // 2)
    assert not [e for e in evs if e["ev"] == "miss" and e["robot"] == 3 and e["t"] > e2]
    assert not [e for e in evs if e["ev"] == "collision" and e["t"] >= t]


def test_a_header_beginning_after_e_plus_tmax_is_a_miss_and_the_takeover_is_on_time():
    evs, e2, t = header_near_the_deadline(-1)
    misses = [e for e in evs if e["ev"] == "miss" and e["robot"] == 3 and e["t"] > e2]
    assert {e["t"] for e in misses} == {e2 + TMAX_TICKS}
    nxt = [f for f in _frames(evs, e2 + 1) if f["src"] == 1]
    assert nxt[0]["start"] == e2 + TMAX_TICKS + TTRANS_TICKS


def _late_header_on_the_cpu_model(offset):
    """header_near_the_deadline with every robot on the CPU model (SimConfig's default is the
    ideal CPU)."""
    from firmware_model.cycle_costs import DEFAULT_COSTS
    return header_near_the_deadline(offset, cpu=DEFAULT_COSTS)


@pytest.mark.parametrize("offset", [B, B // 2, 1])
def test_on_the_cpu_model_a_header_begun_by_the_deadline_is_not_a_miss(offset):
    """The timer handler runs some microseconds after E + Tmax (its latency and body); the
    flag it polls was set by the start bit before the deadline."""
    assert SimConfig().cpu is None                           # the Python API's ideal CPU
    evs, e2, t = _late_header_on_the_cpu_model(offset)
    assert not [e for e in evs if e["ev"] == "miss" and e["robot"] == 3 and e["t"] > e2]
    nxt = [f for f in _frames(evs, t) if f["src"] == 1]
    late = nxt[0]["start"] - (t + 14 * B + TTRANS_TICKS)
    assert 0 <= late < 2_000          # R1's turn after R3's frame, late by R1's handlers


@pytest.mark.parametrize("offset", [-1, -B])
def test_on_the_cpu_model_a_header_begun_after_the_deadline_is_a_miss(offset):
    evs, e2, t = _late_header_on_the_cpu_model(offset)
    misses = [e for e in evs if e["ev"] == "miss" and e["robot"] == 3 and e["t"] > e2]
    assert misses and all(e2 + TMAX_TICKS < e["t"] < t + B for e in misses)
    nxt = [f for f in _frames(evs, e2 + 1) if f["src"] == 1]
    assert nxt and nxt[0]["start"] > e2 + TMAX_TICKS + TTRANS_TICKS


def test_a_header_begun_one_tick_before_the_deadline_by_a_9600_sender_is_not_a_miss():
    """The father's byte (16 667 ticks) is 27 ticks longer than a child's: reckoned back from
    the Header's first byte with the child's own byte time, its start bit came after
    E + Tmax. The edge the flag showed at the deadline is what counts (the ideal CPU)."""
    evs, e2, t = header_near_the_deadline(1)
    assert not [e for e in evs if e["ev"] == "miss" and e["robot"] == 3 and e["t"] > e2]
    nxt = [f for f in _frames(evs, t) if f["src"] == 1]
    assert nxt and nxt[0]["start"] == t + 14 * B + TTRANS_TICKS


# -- finding 5: a rebooted robot whose BOOT frame is lost -----------------------------------

def test_a_lost_boot_frame_does_not_make_the_first_message_a_duplicate():
    """R3 sends R1 a message, then reboots (its Numbers restart). R1 loses R3's first BOOT
    frame. R3's first message after the reboot carries the Number R1 remembers: it must still
    be delivered, never acknowledged as a duplicate."""
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 3), duration=30.0), on_event=evs.append)
    w.run(s_to_ticks(5.0))
    before = w.submit(3, 1, [cmd("movex", 10)])
    w.run(s_to_ticks(6.0))
    assert before.state == "delivered"
    r1 = w.stations[1].mac
    lost = {"boot": 0}
    real_on_frame = r1.on_frame

    def lossy(frame, first, end, now):
        if frame.src == 3 and frame.type == FrameType.BOOT and not lost["boot"]:
            lost["boot"] += 1
            return r1.on_corrupt(first, 3, end, now)    # R1 heard it garbled
        return real_on_frame(frame, first, end, now)

    r1.on_frame = lossy
    st3 = w.stations[3]
    st3.mac = RotationalMac(3, st3.mac.cfg)            # R3 restarts: a new firmware state
    st3.deframer.reset()
    st3.power_on()
    w.run(s_to_ticks(16.0))                            # dropped, invited back, BOOT lost once
    assert lost["boot"] == 1
    after = w.submit(3, 1, [cmd("movex", 20)])
    assert after.num == before.num                     # the Number R1 remembers
    w.run()
    assert after.state == "delivered"
    got = [e for e in evs if e["ev"] == "deliver" and e["src"] == 3 and e["to"] == 1]
    assert len(got) == 2
    assert not [e for e in evs if e["ev"] == "duplicate" and e["src"] == 3 and
                e["t"] > s_to_ticks(6.0)]


def test_a_boot_frame_is_repeated_until_every_member_acknowledges_it():
    mac = RotationalMac(2)
    mac.power_on(0)
    out = mac.on_frame(Frame(dst=7, src=1, num=5, type=3,
                             content=b"poll(2,2)"), 0, 1000, 1000)     # invited by R1
    assert mac.ring == (1, 2)
    assert any(type(a).__name__ == "TxEnable" for a in out)
    sent = mac.on_timer(mac.deadline)                  # Ttrans later: the answer goes out
    frames = [a.frame for a in sent if type(a).__name__ == "Transmit"]
    assert frames[0].type == FrameType.BOOT and frames[0].num == 0
    mac.on_tx_done(mac.deadline or 2_000_000)
    mac.submit(1, [cmd("movex", 1)], 2_000_000)
    # R1's next frame does not acknowledge the BOOT: R2's next frame is BOOT again, no message
    t = 3_000_000
    mac.on_frame(Frame(dst=7, src=1, num=5, type=3, content=b""), t, t + 1000, t + 1000)
    sent = mac.on_timer(mac.deadline)
    frames = [a.frame for a in sent if type(a).__name__ == "Transmit"]
    assert frames[0].type == FrameType.BOOT and not frames[0].content
    mac.on_tx_done(mac.deadline or t + 2_000_000)
    # R1 acknowledges it: the message goes out with Number '01'
    t += 4_000_000
    mac.on_frame(Frame(dst=7, src=1, num=5, type=3, content=b"ack(2,0)"), t, t + 1000,
                 t + 1000)
    sent = mac.on_timer(mac.deadline)
    frames = [a.frame for a in sent if type(a).__name__ == "Transmit"]
    assert frames[0].type == FrameType.INSTRUCTION and frames[0].num == 1


# -- finding 5, again: a restart whose lone BOOT nobody heard --------------------------------

def test_a_restart_whose_lone_boot_nobody_heard_answers_its_invitation_with_boot():
    """R3 sends R1 two messages (Numbers 01, 02) and restarts while its radio is dead: it
    claims the silent channel alone, and its BOOT reaches nobody. Back on the air it hears the
    ring, goes back to LISTEN and is invited. It answered with JOIN (Number 01), so R1 kept
    its old Numbers and took R3's next message, Number 02, for a duplicate: acknowledged,
    never delivered (found on the bench: a father restarted on a live ring, its order ended
    unreported). Its BOOT was never acknowledged, so it answers with BOOT (clause 34)."""
    evs: list[dict] = []
    cfg = SimConfig(robots=(1, 2, 3), duration=30.0, seed=1,
                    faults=(parse_fault("fail:3@6"), parse_fault("recover:3@10")))
    w = World(cfg, on_event=evs.append)
    w.run(s_to_ticks(4.0))
    old = [w.submit(3, 1, [cmd("movex", 10)]), w.submit(3, 1, [cmd("movex", 11)])]
    w.run(s_to_ticks(6.2))
    assert [m.state for m in old] == ["delivered", "delivered"] and old[1].num == 2
    st3 = w.stations[3]
    st3.mac = RotationalMac(3, st3.mac.cfg)            # R3 restarts, its radio still dead
    st3.deframer.reset()
    st3.power_on()
    w.run(s_to_ticks(20.0))
    mac3 = st3.mac
    assert mac3.mode == MEMBER and 1 in mac3.ring and mac3.pending == 0
    claims = [e for e in evs if e["ev"] == "mode" and e["robot"] == 3 and e["t"] > s_to_ticks(6.2)]
    assert "claimed the silent channel" in claims[0]["reason"]        # the lone claim
    after = w.submit(3, 1, [cmd("movex", 20)])
    w.run(s_to_ticks(25.0))
    assert after.state == "delivered", after
    got = [e for e in evs if e["ev"] == "deliver" and e["src"] == 3 and e["to"] == 1]
    assert len(got) == 3
    assert not [e for e in evs if e["ev"] == "duplicate" and e["src"] == 3]
    answers = [e for e in evs if e["ev"] == "frame" and e["src"] == 3 and
               e["start"] > s_to_ticks(10.0) and e["type"] in (FrameType.BOOT, FrameType.JOIN)]
    assert answers and answers[0]["type"] == FrameType.BOOT


# -- finding 7: what a heartbeat is ----------------------------------------------------------

def test_heartbeats_are_empty_and_mac_commands_ride_on_control_frames():
    """docs/protocol.md §3.5, clause 21: a heartbeat is a Type '3' frame to '7' with empty
    Content; a frame that carries only MAC commands (ack, poll, crc) is a control frame. The
    trace says which."""
    for checksum in (False, True):
        evs: list[dict] = []
        w = World(SimConfig(robots=(1, 2, 3), duration=12.0, load=1.0, seed=4,
                            mac=MacConfig(checksum=checksum)), on_event=evs.append)
        w.run()
        kinds = {}
        for f in _frames(evs):
            kinds.setdefault(f["kind"], []).append(f)
            if f["kind"] == "heartbeat":
                assert f["type"] == 3 and f["dst"] == 7 and f["len"] == 0
            elif f["kind"] == "control":
                assert f["type"] == 3 and f["dst"] == 7 and f["len"] > 0
        if checksum:
            assert "heartbeat" not in kinds          # every frame carries crc(): control
        else:
            assert kinds["heartbeat"] and kinds["control"]
        assert kinds["message"]


def test_the_duplicate_rule_uses_the_last_message_number_heard_from_the_source():
    """A receiver compares a message's Number with the last message frame heard from its
    source, whoever it was for: a new message never repeats it (stop-and-wait), so Numbers
    wrapping past a receiver that got no message for a while cannot fake a duplicate."""
    r1 = RotationalMac(1)
    r1.mode, r1.ring, r1.phase = "member", (1, 2, 3), "wait"
    r1.owner, r1.turn_start, r1.deadline = 3, 0, TMAX_TICKS

    def hear(dst, num, t):
        r1.owner, r1.phase = 3, "wait"
        return r1.on_frame(Frame(dst=dst, src=3, num=num, type=2, content=b"movex(1)"),
                           t, t + 100, t + 100)
    assert any(type(a) is Deliver for a in hear(1, 7, 1000))
    for n in range(8, 107):                         # 99 messages for R2, Numbers wrap to 06
        hear(2, n % 100, 1000 + n)
    out = hear(1, 7, 5000)                          # a new message for R1 with Number 07
    assert any(type(a) is Deliver for a in out) and not any(type(a) is Duplicate for a in out)


# -- a robot that dies while it transmits: a partial Header is no Header --------------------

def _death_mid_frame(k_bytes):
    """R1's radio dies ``k_bytes`` byte times after its frame began (its Header bytes, if
    any, are all the others ever hear of it). Returns the events and the kill tick."""
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 3, 4), duration=9.0), on_event=evs.append)
    start = _run_until_txen(w, evs, 1, s_to_ticks(4.0)) + TTRANS_TICKS
    kill = start + k_bytes * CHILD_BYTE_TICKS + CHILD_BYTE_TICKS // 2
    w.inject("fail", 1, kill)
    w.run()
    return w, evs, kill


@pytest.mark.parametrize("k_bytes", [0, 1, 2, 3, 5, 13])
def test_a_robot_dying_mid_frame_is_dropped_and_the_ring_goes_on(k_bytes):
    """Before: a dead robot's one or two Header bytes held the others' miss rule ("a Header
    had begun") for ever; the ring stalled with every member in WAIT."""
    w, evs, kill = _death_mid_frame(k_bytes)
    drops = {e["by"]: e["t"] - kill for e in evs
             if e["ev"] == "disable" and e["robot"] == 1 and e["t"] > kill}
    assert set(drops) == {2, 3, 4}, drops               # every survivor dropped R1
    # docs/guarantees.md: 3 x ((n-1) idle turns + Tmax) + one turn; a frame whose Header was
    # complete is a failed frame, not a miss (paper §IV.C), so that turn counts once more.
    idle_turn = 14 * CHILD_BYTE_TICKS + TTRANS_TICKS
    cycle = 3 * idle_turn + TMAX_TICKS + TTRANS_TICKS
    misses_to_wait = 3 if k_bytes < 3 else 4
    assert max(drops.values()) <= misses_to_wait * cycle + idle_turn, drops
    assert max(drops.values()) > (misses_to_wait - 1) * cycle, drops
    later = {f["src"] for f in _frames(evs, kill + s_to_ticks(2.5)) if not f["collided"]}
    assert later == {2, 3, 4}
    assert {r: v for r, v in w.ring_views().items() if r != 1} == {r: (2, 3, 4) for r in (2, 3, 4)}


# -- found by the 2-hour soak: both father PCs answering one invitation, for ever -----------

def test_two_father_pcs_in_listen_never_answer_the_same_invitation():
    """PC1 recovered while PC2 had taken over; the children dropped ID 0, both PCs went to
    LISTEN on the same poll mask and both answered the next invitation of ID 0 together. Their
    JOIN frames collided with each other at every invitation: 5948 collisions in one soak hour
    and ID 0 never back. PC2 now lets the first invitation pass: PC1 answers it, PC2 hears
    that and stands by; with PC1 dead, PC2 answers the next invitation."""
    def listening(pc):
        m = RotationalMac(0, MacConfig(team=frozenset(range(5)), pc=pc))
        m.power_on(0)
        return m
    invite = Frame(dst=7, src=4, num=3, type=3, content=cmd("poll", 0, 0b11110).text().encode())
    t = 10_000_000
    pc1, pc2 = listening(1), listening(2)
    a1 = pc1.on_frame(invite, t, t + 1000, t + 1000)
    a2 = pc2.on_frame(invite, t, t + 1000, t + 1000)
    assert pc1.mode == "member" and any(type(a) is ModeChange for a in a1)
    assert pc2.mode == "listen" and not a2                      # PC2 let it pass
    join = Frame(dst=7, src=0, num=1, type=FrameType.JOIN, content=b"")
    pc2.on_frame(join, t + 200_000, t + 300_000, t + 300_000)   # PC1's answer
    assert pc2.mode == "member" and pc2.standby                 # a replica, silent
    # PC1 dead: the next invitation is answered by PC2
    lone = listening(2)
    lone.on_frame(invite, t, t + 1000, t + 1000)
    assert lone.mode == "listen"
    later = t + 4 * TMAX_TICKS
    lone.on_frame(invite, later, later + 1000, later + 1000)
    assert lone.mode == "member" and not lone.standby


def _live_idle_ring(mac, start, until):
    """Heartbeats of ID 0 (the other, active PC), R1 and R2 in turn, one idle turn (14 bytes +
    Ttrans) apart, as a live ring sends them to ``mac`` from ``start`` to ``until``; the MAC's
    own deadlines run when they come before a frame's End. Returns every action."""
    out, t, i = [], start, 0
    turn = 14 * CHILD_BYTE_TICKS + TTRANS_TICKS
    while t < until:
        end = t + turn
        while mac.deadline is not None and mac.deadline < end:
            out += mac.on_timer(mac.deadline, rx_busy=mac.deadline > end - 14 * CHILD_BYTE_TICKS)
        src = (0, 1, 2)[i % 3]
        out += mac.on_frame(Frame(dst=7, src=src, num=0, type=3, content=b""),
                            end - 13 * CHILD_BYTE_TICKS, end, end)
        t, i = end, i + 1
    return out


def test_a_standby_pc_refuses_a_new_message_at_once_and_names_the_active_pc():
    """An order typed into a standby PC showed ``queued`` and then nothing, for ever (issue
    40): a standby sends nothing, and only its own deadlines, which a live ring never lets
    pass, expired its queue. A standby now refuses a new message at once (clause 50)."""
    mac = RotationalMac(0, MacConfig(team=frozenset((0, 1, 2)), pc=2, paired=True))
    mac.power_on(0)
    _live_idle_ring(mac, TMAX_TICKS, 2 * TMAX_TICKS)
    assert mac.mode == "member" and mac.standby
    with pytest.raises(StandingBy, match="PC2 is standing by: the active PC is PC1"):
        mac.submit(1, [cmd("status")], mac.deadline)
    assert mac.pending == 0


def test_what_a_pc_held_when_it_stood_by_expires_within_max_age_on_a_live_ring():
    """A father PC listening with a message queued (restarted while the other PC is active, or
    stalled) hears the active PC and stands by: the message stayed queued for ever on a live
    ring. It now ends ``failed`` (expired) within ``max_age`` of its submission, as in
    LISTEN: every message at every station ends (docs/guarantees.md)."""
    cfg = MacConfig(team=frozenset((0, 1, 2)), pc=2, paired=True)
    mac = RotationalMac(0, cfg)
    mac.power_on(0)
    msg = mac.submit(1, [cmd("status")], 0)
    out = _live_idle_ring(mac, TMAX_TICKS, cfg.max_age + 2 * TMAX_TICKS)
    assert mac.standby and mac.mode == "member"
    ends = [a for a in out if type(a) is Outcome]
    assert [(a.message, a.delivered) for a in ends] == [(msg, False)]
    assert msg.reason.startswith("expired") and mac.pending == 0
    assert not any(type(a) is Transmit for a in out)        # a standby sends nothing


def test_a_father_pc1_that_took_over_ends_its_probation_and_delivers():
    """Found by the 2-hour soak: PC1 stood by (it had heard PC2 active), then took ID 0's turn
    when PC2 went silent. A takeover starts a 3-turn probation during which new messages are
    left alone; only PC2 ever counted those turns down, so PC1 stayed on probation for good
    and every message to the father failed ("no acknowledgement from 0": 650 in half an
    hour). PC1 now watches its probation turns too, and delivers after them."""
    mac = RotationalMac(0, MacConfig(team=frozenset((0, 1)), pc=1, standby=True))
    mac.power_on(0)
    mac.mode, mac.ring, mac.misses = "member", (0, 1), {0: 0, 1: 0}
    mac.phase, mac.owner, mac.turn_start, mac.deadline = "wait", 1, 0, TMAX_TICKS
    t = 1_000_000
    heartbeat = Frame(dst=7, src=1, num=0, type=3, content=b"")

    def r1_sends(frame):
        """R1's frame ends at t; run our turn to its end; return what we delivered."""
        nonlocal t
        out = list(mac.on_frame(frame, t - 200_000, t, t))
        while mac.phase != "send":
            now = mac.deadline
            out += mac.on_timer(now)        # the active PC (PC2) is silent: nothing heard
        t = now + 300_000
        out += mac.on_tx_done(t)
        t += 400_000
        return out
    r1_sends(heartbeat)                     # the standby takes ID 0's turn
    assert not mac.standby and mac._check_turns == 3
    for _ in range(3):
        r1_sends(heartbeat)                 # its probation turns, each watched
    assert mac._check_turns == 0
    msg = Frame(dst=0, src=1, num=5, type=2, content=b"movex(1)")
    assert any(type(a) is Deliver for a in r1_sends(msg))


def test_pc1_on_probation_that_hears_the_other_pcs_frame_while_it_watches_yields_the_slot():
    """Clause 50 with the real-time margins: PC1, on probation after hearing the other PC
    after a miss, watches its turn for W past Ttrans (35 ms). The other PC's heartbeat begins
    and ends inside that watch (19.6 ms): the members take it as ID 0's frame, and robot 1's
    Header is due at its End + Ttrans. PC1 refused it as our own ID but kept watching, then
    raised TXEN at 35 ms, over robot 1's frame. The frame closes ID 0's slot for PC1 too: it
    waits for robot 1, and sends nothing in that turn."""
    from firmware_model.radio.mac import TxEnable
    from hil.bench.runner import realtime_config
    cfg = realtime_config(MacConfig(team=frozenset({0, 1, 2}), paired=True, pc=1))
    mac = RotationalMac(0, cfg)
    mac.power_on(0)
    t = 100 * B
    mac.on_frame(Frame(7, 1, 0, 3, b"poll(0,2)"), t - 23 * B, t, t)   # invited: ring {0, 1}
    mac.on_timer(mac.deadline)                                         # SWITCH -> SEND
    mac.on_tx_done(mac.turn_start + cfg.ttrans + 20 * B)
    mac.on_timer(mac.deadline)                       # robot 1 missed: our turn, R-stagger
    e = mac.turn_start + 40 * B
    mac.on_frame(Frame(7, 0, 0, 3, b""), e - 14 * B, e, e)   # the other PC: probation
    e = mac.turn_start + 80 * B
    mac.on_frame(Frame(7, 1, 0, 3, b""), e - 14 * B, e, e)   # robot 1; our turn, watched
    assert mac.phase == "watch" and mac._check_turns
    start = e + cfg.ttrans                           # the other PC's heartbeat, 14 bytes
    other_end = start + 14 * B
    out = list(mac.on_frame(Frame(7, 0, 1, 3, b""), start + B, other_end, other_end))
    assert (mac.phase, mac.owner) == ("wait", 1), (mac.phase, mac.owner, out)
    assert mac.deadline == other_end + cfg.tmax
    assert not any(isinstance(a, TxEnable) for a in out)
    assert not any(isinstance(a, TxEnable) for a in mac.on_timer(start + 35 * 16_000))


def _pc1_outage(seed: int, back: float, duration: float, checksum: bool):
    """``rprs sim --robots 0,1,2 --father-standby --fault fail:0@2 --recover 0@BACK --load 1``:
    the world run, and its events."""
    evs: list[dict] = []
    w = World(SimConfig(robots=(0, 1, 2), duration=duration, seed=seed, load=1.0,
                        father_standby=True, mac=MacConfig(checksum=checksum),
                        faults=(Fault("fail", 0, 2.0), Fault("recover", 0, back))),
              on_event=evs.append)
    w.run()
    return w, evs


# -- found by seeded failover runs: a father PC back from a short outage delivered twice -----

@pytest.mark.parametrize("seed, checksum, back", [(0, True, 3.0), (3, False, 3.0),
                                                  (15, True, 4.0)])
def test_a_father_pc_back_from_a_short_outage_leaves_delivery_to_the_active_pc(
        seed, checksum, back):
    """``rprs sim --robots 0,1,2 --father-standby --fault fail:0@2 --recover 0@3 --load 1``:
    PC2 took ID 0's turn and ended its probation; PC1's radio came back before PC1 had heard
    nobody long enough to go to LISTEN, so PC1 was still active, off probation, and both PCs
    delivered the same broadcast at one tick (1 duplicate, also with the checksum). The trace
    could not tell them apart: PC2's ``deliver`` events carried no ``"pc": 2``. A father PC
    that missed two turns with nothing at all heard, or that hears the other PC after a miss
    with no frame accepted since, is now on probation (clause 50): it stands by for PC2."""
    w, evs = _pc1_outage(seed, back, 30.0, checksum)
    assert w.summary()["duplicate_deliveries"] == 0
    took = next(e["t"] for e in evs if e["ev"] == "mode" and e.get("pc") == 2
                and "took over" in e["reason"])
    # PC1's radio is dead until ``back``: what ID 0 delivers meanwhile is PC2's, and says so
    meanwhile = [e for e in evs if e["ev"] == "deliver" and e["to"] == 0
                 and took < e["t"] < s_to_ticks(back)]
    assert meanwhile and all(e.get("pc") == 2 for e in meanwhile)
    # PC1, back, stands by for PC2
    assert any(e["ev"] == "mode" and e["robot"] == 0 and "pc" not in e
               and e["t"] > s_to_ticks(back) and "standing by" in e["reason"] for e in evs)


@pytest.mark.parametrize("seed, back", [(6, 3.0), (9, 5.0), (29, 5.0)])
def test_a_father_pc_back_from_an_outage_costs_no_healthy_robot_a_miss(seed, back):
    """``rprs sim --robots 0,1,2 --father-standby --fault fail:0@2 --recover 0@BACK --load 1
    --checksum``. Back at 3 s, PC1 (still active, waiting for robot 1's turn) heard PC2's
    frame and counted robot 1 missing; the members had taken it as ID 0's turn (clause 50).
    Back at 5 s, PC1 had dropped everyone and claimed alone: its lone frames landed in robot
    2's slot, and PC2, which ignored them, or robot 1, which refused one as out of turn,
    counted robot 2 missing, where the others resynchronised on them (clause 31). Nobody's
    radio failed but PC1's: no robot is counted missing once it is back."""
    w, evs = _pc1_outage(seed, back, 8.0, True)
    after = s_to_ticks(back)
    assert [e for e in evs if e["ev"] == "miss" and e["t"] > after] == []
    assert w.summary()["duplicate_deliveries"] == 0
    # PC1 came back into the ring's turns: it stands by for PC2
    assert any(e["ev"] == "mode" and e["robot"] == 0 and "pc" not in e and e["t"] > after
               and "standing by" in e["reason"] for e in evs)


@pytest.mark.parametrize("ring, seed, faults", [
    ((0, 1, 2), 135, (Fault("fail", 0, 8.461), Fault("recover", 0, 9.988))),
    ((0, 1, 2, 3), 20, (Fault("fail", 0, 13.868), Fault("recover", 0, 15.99)))])
def test_no_father_pc_acknowledges_a_message_it_did_not_deliver(ring, seed, faults):
    """``rprs sim --robots 0,1,2 --father-standby --duration 20 --seed 135 --load 1 --checksum
    --fault fail:0@8.461 --fault recover:0@9.988``: PC1's radio died, PC2, standing by, heard
    R1's message 13 and delivered nothing (clause 50), then took over and sent the
    acknowledgement it had replicated: R1 was told ``delivered``, and neither PC delivered it.
    The PC that takes over now forgets what the other never acknowledged on the air; the
    sender retries, and the retry is delivered (or fails at the sender, said so)."""
    evs: list[dict] = []
    w = World(SimConfig(robots=ring, duration=20.0, seed=seed, load=1.0, father_standby=True,
                        mac=MacConfig(checksum=True), faults=faults), on_event=evs.append)
    w.run()
    to_father = {(e["src"], e["num"]) for e in evs if e["ev"] == "submit" and e["dst"] == 0}
    told = [(e["src"], e["num"]) for e in evs
            if e["ev"] == "delivered" and (e["src"], e["num"]) in to_father]
    given = {(e["src"], e["num"]) for e in evs if e["ev"] == "deliver" and e["to"] == 0}
    assert told and [m for m in told if m not in given] == []
    assert w.summary()["duplicate_deliveries"] == 0


@pytest.mark.parametrize("ring, seed, fail, back, cpu", [
    ((0, 1, 2, 3), 118, 11.532, 12.243, False),   # a frame from a robot after the one awaited
    ((0, 1, 2, 3), 58, 9.969, 10.745, False),     # the same, after PC1's own frame collided
    ((0, 1, 2), 221, 5.946, 6.408, False),        # garbage long after the frame that failed
    ((0, 1, 2), 655, 12.838, 13.566, False),      # a miss at E + Tmax after a frame failed
    ((0, 1, 2, 3), 218, 6.604, 7.109, True)])     # garbage long after a good frame (CPU model)
def test_a_father_pc_whose_radio_died_in_a_frame_checks_before_it_delivers(ring, seed, fail,
                                                                            back, cpu):
    """The father-pair runs of ``python benchmarks/father_pair.py`` (``--checksum --load 1``,
    ID 0's radio failing at FAIL and back at BACK) where both PCs delivered the same
    messages: PC2 took over and ended its probation, and PC1, back, was still active and sent
    in ID 0's slot at the tick PC2 did, each deaf to the other, until PC2's listening turn.
    PC1 never checked (clause 50): its radio died in the middle of a frame, which failed, so
    it had "heard something" since its own frame; or back in the middle of another robot's
    frame, it took a later robot's frame for the one awaited and counted a miss, which a
    frame does not make a sign of deafness. A PC with no good frame since its own now checks
    after a miss with nothing heard for Tmax, after silence before garbage or a failed frame
    longer than a live Header can take (also after a good frame: seed 218 on the CPU model,
    whose radio died after a frame heard since its own), and after a miss counted on a frame."""
    from firmware_model.cycle_costs import DEFAULT_COSTS
    evs: list[dict] = []
    w = World(SimConfig(robots=ring, duration=20.0, seed=seed, load=1.0, father_standby=True,
                        mac=MacConfig(checksum=True), cpu=DEFAULT_COSTS if cpu else None,
                        faults=(Fault("fail", 0, fail), Fault("recover", 0, back))),
              on_event=evs.append)
    w.run()
    to_father: dict[tuple[int, int], int] = {}
    for e in evs:
        if e["ev"] == "submit" and e["dst"] == 0:
            to_father[(e["src"], e["num"])] = 0
        elif e["ev"] == "deliver" and e["to"] == 0 and (e["src"], e["num"]) in to_father:
            to_father[(e["src"], e["num"])] += 1
    assert sum(n > 0 for n in to_father.values()) >= 10
    assert [m for m, n in to_father.items() if n > 1] == []
    # PC1, back, stands by for PC2 (which had taken over while PC1 was deaf)
    assert any(e["ev"] == "mode" and e["robot"] == 0 and "pc" not in e
               and e["t"] > s_to_ticks(back) and "standing by" in e["reason"] for e in evs)


def _father_told_delivered_unsent(evs: list[dict]) -> list[tuple]:
    """The father's messages (either PC's) that ended ``delivered`` with no delivery from a
    frame of the PC that sent them: (PC, Number, destination). Both PCs are ID 0; a frame
    and the deliveries it causes share its End's tick, and PC2's carry ``"pc": 2``."""
    sent_by = {}
    for e in evs:
        if e["ev"] == "frame" and e["src"] == 0:
            sent_by.setdefault((e["t"], e["num"]), set()).add(e.get("pc", 1))
    given = {(pc, e["num"], e["to"]) for e in evs if e["ev"] == "deliver" and e["src"] == 0
             for pc in sent_by.get((e["t"], e["num"]), ())}
    return [(e.get("pc", 1), e["num"], e["dst"]) for e in evs
            if e["ev"] == "delivered" and e["src"] == 0
            and not any(pc == e.get("pc", 1) and num == e["num"] and e["dst"] in (to, 7)
                        for pc, num, to in given)]


@pytest.mark.parametrize("ring, seed, load, faults", [
    ((0, 1), 199, 2.0, (Fault("fail", 0, 7.612), Fault("recover", 0, 9.365))),
    ((0, 1, 2), 1, 1.0, (Fault("fail", 0, 4.612), Fault("recover", 0, 7.185)))])
def test_no_father_pc_takes_the_other_pcs_acknowledgement_for_its_own(ring, seed, load,
                                                                      faults):
    """``rprs sim --robots 0,1 --father-standby --duration 20 --seed 199 --load 2 --checksum
    --fault fail:0@7.612 --fault recover:0@9.365 --cpu ideal``: PC1 queued its message 09
    while its radio was deaf (sent twice, never on the air), came back and stood by; PC2,
    numbering after PC1's last frame it heard (08), sent its own 09, and R1's ack(0,09) ended
    both ``delivered``: PC1's never reached R1 (the father pair's seed 1: PC1's 06 so, by
    PC2's broadcast 06). The pair shares ID 0's Numbers: a PC that hears the other PC's
    message of Number N now fails its own N (clause 50)."""
    evs: list[dict] = []
    w = World(SimConfig(robots=ring, duration=20.0, seed=seed, load=load,
                        father_standby=True, mac=MacConfig(checksum=True), faults=faults),
              on_event=evs.append)
    w.run()
    assert any(e["ev"] == "delivered" and e["src"] == 0 for e in evs)
    assert _father_told_delivered_unsent(evs) == []
    clash = [e for e in evs if e["ev"] == "fail" and e["src"] == 0 and "pc" not in e
             and "the other PC sent its own message" in e["reason"]]
    assert clash and all(e["t"] > s_to_ticks(faults[1].at) for e in clash)


def test_two_father_pcs_on_probation_do_not_send_at_one_tick():
    """``rprs sim --robots 0,1,2,3,4,5,6 --duration 30 --seed 2095 --checksum --father-standby
    --cpu ideal --load 2`` with noise and byte errors, no fault on the father: PC1, a turn
    behind after losing R5's frame in noise, heard PC2's takeover frame after the miss and
    went on probation while still active. Both PCs on probation watched their turn for
    Ttrans + W and sent at one tick, each deaf to the other, and both delivered for 5 s (6
    messages twice). PC1 on probation now watches 2 (Ttrans + W), as when it may have been
    deaf, and hears PC2 (clause 50)."""
    faults = tuple(parse_fault(f) for f in (
        "skew:2:0.012", "noise@15.535-18.911", "noise@14.017-20.299",
        "ber@4.398-8.13:0.0027", "drop@10.328-17.804:0.0071", "noise@3.159-8.011"))
    evs: list[dict] = []
    w = World(SimConfig(robots=tuple(range(7)), duration=30.0, seed=2095, load=2.0,
                        father_standby=True, cpu=None, mac=MacConfig(checksum=True),
                        faults=faults), on_event=evs.append)
    w.run()
    s = w.summary()
    assert s["duplicate_deliveries"] == 0 and s["collisions"] <= 2
    modes = [e for e in evs if e["ev"] == "mode" and e["robot"] == 0]
    late = [e for e in modes if e["t"] > s_to_ticks(18.0)]
    # PC2 takes over at 18.12 s; PC1 (no "pc" key) hears it within a second and stands by
    assert [("pc" in e, e["reason"]) for e in late] == [
        (True, "took over ID 0's turn: the active PC is silent"),
        (False, "the other PC is still active: standing by")]
    assert late[1]["t"] - late[0]["t"] < s_to_ticks(1.5)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_two_active_father_pcs_in_a_ring_of_two_meet(seed):
    """``--robots 0,1 --father-standby --fault fail:0@5 --recover 0@5.4 --load 1 --checksum``:
    both PCs active, PC2 sends twice a cycle, and its listening turn (one in 8) always fell on
    the one PC1 does not send in: they never met, both delivered (seed 1: 164 collisions and
    both active to the end). One turn in 7 alternated between the two: PC2 heard PC1 and
    stood by. Now PC1, back from its deafness, checks its first turn and stands by."""
    evs: list[dict] = []
    w = World(SimConfig(robots=(0, 1), duration=30.0, seed=seed, load=1.0,
                        father_standby=True, mac=MacConfig(checksum=True),
                        faults=(Fault("fail", 0, 5.0), Fault("recover", 0, 5.4))),
              on_event=evs.append)
    w.run()
    s = w.summary()
    assert s["duplicate_deliveries"] == 0 and s["collisions"] <= 2
    # PC1, back, checks its first turn (clause 50: it heard nothing for longer than a live
    # successor's Header takes) and stands by for PC2, which stays active
    assert any(e["ev"] == "mode" and e["robot"] == 0 and "pc" not in e
               and e["t"] > s_to_ticks(5.4) and "standing by" in e["reason"] for e in evs)


def test_the_standby_pc_counts_the_turns_it_sees_missed_by_its_own_radio():
    """PC1's radio dead, PC2 active, then R1 falls silent: PC2 is the only one to hear R1 miss
    its three turns, and they count (they were judged by PC1's dead radio, both being robot
    0, and the summary said R1 missed nothing)."""
    w = World(SimConfig(robots=(0, 1), duration=20.0, seed=5, load=1.0, father_standby=True,
                        faults=(Fault("fail", 0, 5.0), Fault("fail", 1, 10.0))))
    w.run()
    assert w.stats[1].missed == 3

"""Spoofing and bounds: forged or out-of-bounds input is refused, counted, traced, never acted
on (docs/mac.md). Frames are forged by putting raw bytes on the air in a silent robot's slot,
so they do not collide with anyone."""
from __future__ import annotations

from firmware_model.radio.frame import Frame
from firmware_model.timing import TMAX_TICKS, s_to_ticks
from hil.sim.world import SimConfig, World


def ring_with_silent_r1(extra_ms=100, **kw):
    """Robots 1-4 with CAN; R1's radio dies after its turn at ~5 s. Returns the world, the
    event list and a tick inside R1's next (silent) slot."""
    probe_evs: list[dict] = []
    probe = World(SimConfig(robots=(1, 2, 3, 4), duration=5.0, can=True),
                  on_event=probe_evs.append)
    probe.run()
    e1 = [e for e in probe_evs if e["ev"] == "frame" and e["src"] == 1][-1]["end"]
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 3, 4), duration=9.0, can=True, keep_records=True, **kw),
              on_event=evs.append)
    w.inject("fail", 1, e1 + 1)
    w.run(e1 + 1)
    # R2, R3, R4 take their turns (~3 x 20 ms); R1's slot starts at R4's End
    w.run(e1 + s_to_ticks(0.12))
    e4 = [e for e in evs if e["ev"] == "frame" and e["src"] == 4][-1]["end"]
    return w, evs, e4 + s_to_ticks(extra_ms / 1000)


def next_silent_slot(w, evs, before_src=4, extra_ms=100):
    """Run until ``before_src`` ends a turn after now; the slot after it is silent."""
    t0 = w.now
    while True:
        w.run(w.now + s_to_ticks(0.01))
        ends = [e["end"] for e in evs if e["ev"] == "frame" and e["src"] == before_src
                and e["end"] > t0]
        if ends:
            return ends[0] + s_to_ticks(extra_ms / 1000)


def joint_commands(evs, bus):
    return [e for e in evs if e["ev"] == "can" and e["bus"] == bus and 0x101 <= e["id"] <= 0x104]


def forged(src, dst, content, num=42, type=2):
    return Frame(dst=dst, src=src, num=num, type=type, content=content).encode()


def test_a_frame_from_the_wrong_source_in_a_turn_is_refused_and_not_acted_on():
    w, evs, t = ring_with_silent_r1()
    n0 = len(joint_commands(evs, 3))
    w.inject_bytes(forged(2, 3, b"joint(1,80)"), t)       # R1's turn, but Source says 2
    w.run()
    refused = [e for e in evs if e["ev"] == "refused"]
    assert {e["to"] for e in refused} >= {3, 4}
    assert all("out of turn" in e["reason"] or "own robot ID" in e["reason"] for e in refused)
    assert not [e for e in evs if e["ev"] == "deliver" and e["num"] == 42]
    assert len(joint_commands(evs, 3)) == n0                   # R3's arm never moved
    assert w.summary()["robots"][3]["refused_frames"] >= 1
    # the ring went on: R3 took its turn after the forged frame (the owner is who sends)
    assert any(e["ev"] == "frame" and e["src"] == 3 and e["start"] > t for e in evs)


def test_a_frame_from_an_unknown_id_is_refused():
    w, evs, t = ring_with_silent_r1()
    w.inject_bytes(forged(6, 3, b"joint(1,80)"), t)         # robot 6 is not in the team
    w.run()
    refused = [e for e in evs if e["ev"] == "refused" and e["src"] == 6]
    assert {e["to"] for e in refused} == {2, 3, 4}
    assert all("not in the team" in e["reason"] for e in refused)
    assert not [e for e in evs if e["ev"] == "deliver" and e["src"] == 6]


def test_a_frame_from_a_disabled_robot_is_refused_until_invited():
    w, evs, _ = ring_with_silent_r1()
    w.run(w.now + 3 * TMAX_TICKS + s_to_ticks(0.3))          # R1 is dropped by now
    assert all(1 not in w.stations[r].mac.ring for r in (2, 3, 4))
    # silence R2 too, so its slot is free, and forge a frame as R1 in it
    w.inject("fail", 2, w.now + 1)
    t = next_silent_slot(w, evs, before_src=4)
    w.inject_bytes(forged(1, 3, b"joint(1,80)"), t)
    w.run(t + s_to_ticks(0.2))
    refused = [e for e in evs if e["ev"] == "refused" and e["src"] == 1 and e["t"] >= t]
    assert refused and all("disabled" in e["reason"] or "out of turn" in e["reason"]
                           for e in refused)
    assert not [e for e in evs if e["ev"] == "deliver" and e["src"] == 1 and e["t"] >= t]


def test_a_length_beyond_the_turn_limit_is_refused_by_the_deframer():
    w, evs, t = ring_with_silent_r1()
    too_long = b"\x0f\x0a\x05" + b"3" + b"1" + b"42" + b"2" + b"0600" + b"movex(1)" * 3
    w.inject_bytes(too_long, t)
    w.run()
    bad = [e for e in evs if e["ev"] == "bad_frame" and e["t"] >= t]
    assert {e["to"] for e in bad} == {2, 3, 4} and all(e["field"] == "length" for e in bad)
    assert not [e for e in evs if e["ev"] == "deliver" and e["t"] >= t and e["src"] == 1]


def test_wrong_arity_and_joint_limits_are_refused_in_the_owners_own_slot():
    """Without authentication a frame with the right Source in the right slot is believed; the
    Content rules still refuse a wrong arity, and the dispatcher a target out of the limits."""
    w, evs, t = ring_with_silent_r1()
    n0 = len(joint_commands(evs, 3))
    w.inject_bytes(forged(1, 3, b"moveto(1,2)", num=50), t)   # moveto takes 3 parameters
    w.run(t + s_to_ticks(0.25))
    bad = [e for e in evs if e["ev"] == "bad_content" and e["to"] == 3]
    assert bad and "moveto takes 3 parameters" in bad[0]["reason"]
    # R1's next slot: joint 2 beyond its 120 deg limit
    t2 = next_silent_slot(w, evs, before_src=4)
    w.inject_bytes(forged(1, 3, b"joint(2,150)", num=51), t2)
    w.run()
    assert len(joint_commands(evs, 3)) == n0                   # nothing reached the arm
    fails = [m for m in w.messages if m.src == 3 and m.type == 4]
    assert fails and [c.text() for c in fails[0].commands] == ["fail(2)", "joint(2,150)"]

"""The paper profile (docs/protocol.md §9.1) in the simulator: tick-exact and seeded. Beside a
robot written from the paper alone, on the pty hub: tests/hil/bench/test_paper_profile.py."""
from __future__ import annotations

from firmware_model.radio.mac import MacConfig
from firmware_model.timing import s_to_ticks
from hil.sim.faults import Fault
from hil.sim.world import SimConfig, World


def _paper_world(**kw):
    evs: list[dict] = []
    cfg = dict(robots=(0, 1, 2, 3), duration=12.0, seed=3, load=2.0,
               mac=MacConfig(profile="paper"))
    cfg.update(kw)
    return World(SimConfig(**cfg), on_event=evs.append), evs


def test_in_simulation_only_the_papers_frame_is_on_the_air():
    """Every robot a member of the whole team's ring from power-on; frames are heartbeats
    (Type '3', '7', empty) or messages with nothing after their commands (no ack, poll, ring,
    crc; no BOOT or JOIN); each message goes on the air once, is delivered once to its
    destination and ends ``unacknowledged``."""
    w, evs = _paper_world()
    w.run(1)
    assert set(w.ring_views().values()) == {(0, 1, 2, 3)}
    w.run()
    frames = [e for e in evs if e["ev"] == "frame"]
    assert frames and {e["kind"] for e in frames} == {"heartbeat", "message"}
    assert {e["type"] for e in frames} <= {0, 1, 2, 3, 4}
    size = {(e["src"], e["num"]): e["len"] for e in evs if e["ev"] == "submit"}
    sent = [e for e in frames if e["kind"] == "message"]
    assert all(e["len"] == size[e["src"], e["num"]] for e in sent)
    assert len({(e["src"], e["num"]) for e in sent}) == len(sent)        # each once
    s = w.summary()
    assert s["delivered"] == s["failed"] == 0 and s["unacknowledged"] == len(sent) > 10
    deliveries = [e for e in evs if e["ev"] == "deliver"]
    assert len(deliveries) == len([e for e in sent if e["dst"] != 7]) + \
        3 * len([e for e in sent if e["dst"] == 7])
    assert s["collisions"] == 0 and s["duplicate_deliveries"] == 0


def test_in_simulation_a_silent_robot_is_disabled_and_stays_out_when_it_returns():
    """Paper §IV.C: R2's radio dead from 3 s; every member disables it at the same tick after
    three misses. R2, hearing nobody for a whole round, went to LISTEN (clause 40); back at 6 s
    it stays there, silent, while the ring talks (the paper has no rejoin): no collision."""
    w, evs = _paper_world(faults=(Fault("fail", 2, 3.0), Fault("recover", 2, 6.0)))
    w.run()
    drops = [e for e in evs if e["ev"] == "disable" and e["robot"] == 2]
    assert {e["by"] for e in drops} == {0, 1, 3} and len({e["t"] for e in drops}) == 1
    assert [e for e in evs if e["ev"] == "collision"] == []
    assert w.ring_views()[2] == () and all(w.ring_views()[r] == (0, 1, 3) for r in (0, 1, 3))
    assert [e["reason"] for e in evs if e["ev"] == "mode" and e["robot"] == 2] == \
        ["a member of the static ring of the team (paper profile)",
         "heard nobody for a whole round"]


def test_in_simulation_a_robot_powered_on_after_its_drop_tries_its_slot_twice():
    """R1 powered on at 4 s, after the others dropped it: it takes its slot as a static member,
    collides with R2 (who holds it now), and after the second such frame (the first frame it
    hears after its own comes from a robot other than its successor, early) it stays out."""
    w, evs = _paper_world(power_on={1: 4.0}, duration=10.0)
    w.run()
    assert len([e for e in evs if e["ev"] == "collision"]) == 2
    assert w.ring_views() == {0: (0, 2, 3), 1: (), 2: (0, 2, 3), 3: (0, 2, 3)}
    assert [e["reason"] for e in evs if e["ev"] == "mode" and e["robot"] == 1] == \
        ["a member of the static ring of the team (paper profile)",
         "our slot is taken: the ring dropped us (the paper profile has no rejoin)"]


def test_a_late_robot_whose_predecessor_was_dropped_takes_its_slot_and_stays_out():
    """R4 powered on at 5 s in a ring whose R3 never came (R1 and R2 dropped it): its ring
    still held R3, and R1, sending at once after R2, was no takeover by its timing, so R4
    counted R3 missing never, waited for it for ever and was a silent "member" (sent 0,
    every order pending). The owner is whoever sends (paper §IV.C): R3 is counted missing
    when passed over, dropped after three turns, and R4 then tries its slot twice, colliding,
    and stays out, as §9.1 says of a robot powered on after the others."""
    w, evs = _paper_world(robots=(1, 2, 3, 4), power_on={4: 5.0}, duration=20.0, load=0.2,
                          faults=(Fault("fail", robot=3, at=0.0),))
    w.run()
    assert [e for e in evs if e["ev"] == "miss" and e.get("by") == 4 and
            e["robot"] == 3][:3], "R4 never counted R3 missing"
    assert len([e for e in evs if e["ev"] == "collision"]) == 2
    assert [e["reason"] for e in evs if e["ev"] == "mode" and e["robot"] == 4][-1] == \
        "our slot is taken: the ring dropped us (the paper profile has no rejoin)"
    assert w.ring_views()[1] == w.ring_views()[2] == (1, 2)


def test_in_simulation_the_same_seed_gives_the_same_trace():
    a = _paper_world()[0]
    b = _paper_world()[0]
    a.run()
    b.run()
    assert a.summary() == b.summary()


def test_the_papers_action_sequence_runs_in_the_paper_profile(capsys):
    """The paper's experiment (Fig. 11) with every robot in the paper profile: the static ring
    starts it (the first robot kicks off once the row is in its ring) and both cycles finish."""
    from hil.cli import main
    assert main(["demo", "action-sequence", "--profile", "paper"]) == 0
    out = capsys.readouterr().out
    assert "2 cycle(s) done" in out and "collisions 0" in out


def test_in_simulation_a_lone_paper_robot_of_a_team_of_seven_keeps_its_ring():
    """R1 on, the six others of its team never (issue 43: "a lone paper robot sent back to
    listening after 3.6 s by a team of 7"). The misses of robots it never heard counted
    towards the cut-off (clause 40): six in its first round and it went to LISTEN, then
    restarted the static ring after Tclaim, and again, silent half the time. It now keeps its
    ring: it disables each absent robot at its third miss and goes on alone, never in LISTEN."""
    w, evs = _paper_world(robots=(0, 1, 2, 3, 4, 5, 6), duration=18.0, load="idle",
                          power_on={r: 17.9 for r in (0, 2, 3, 4, 5, 6)})
    w.run(s_to_ticks(17.5))                     # the others are not yet on
    modes = [e["reason"] for e in evs if e["ev"] == "mode" and e["robot"] == 1]
    assert modes == ["a member of the static ring of the team (paper profile)"]
    assert sorted(e["robot"] for e in evs if e["ev"] == "disable") == [0, 2, 3, 4, 5, 6]
    assert w.ring_views()[1] == (1,)
    sent = [e["t"] for e in evs if e["ev"] == "frame" and e["src"] == 1]
    assert sent and max(b - a for a, b in zip(sent, sent[1:])) < 4 * 16_000_000

"""Named scenarios, after the token-bus implementations' own suites (issue 9, "What to build"
item 4): each test names one situation, states the rule it checks (docs/mac.md, the paper's
section) and asserts the exact outcome the rule gives: who misses and who is dropped (and at
which tick), the tick of a takeover, collisions after a point, delivery exactly once.

Scenarios that already have a test elsewhere are not repeated here:

* two robots believing they own the turn, in a ring of four (fault ``steal``):
  ``tests/hil/sim/test_ring.py::test_forced_collision_recovers_without_dropping_anyone`` (here: the
  ring of two, where lock-step is the danger);
* a robot dying 0-13 bytes into its own heartbeat:
  ``tests/hil/sim/test_promises.py::test_a_robot_dying_mid_frame_is_dropped_and_the_ring_goes_on``
  (here: dying during its predecessor's frame, and in the middle of a long message);
* a Header beginning one byte (and half a byte) before E + Tmax, and one tick after:
  ``tests/hil/sim/test_promises.py::test_a_header_beginning_one_byte_before_e_plus_tmax_is_not_a_miss``,
  ``..._half_a_byte_before_...``, ``..._after_e_plus_tmax_is_a_miss_and_the_takeover_is_on_time``;
* forged Sources: a team ID that was never a member (one frame):
  ``tests/hil/sim/test_promises.py::test_a_forged_frame_from_a_never_member_is_refused_and_not_acted_on``;
  a disabled robot:
  ``tests/firmware_model/radio/test_spoofing.py::test_a_frame_from_a_disabled_robot_is_refused_until_invited``;
  another member's ID out of turn: ``tests/firmware_model/radio/test_spoofing.py::``
  ``test_a_frame_from_the_wrong_source_in_a_turn_is_refused_and_not_acted_on``
  (here: a Source that is no robot ID, one outside the team, our own ID, the father's ID, and a
  never-member repeating its forgery up to the admission rule);
* the largest frame from a child to the father, a child to a child and the father to a child:
  ``tests/hil/sim/test_promises.py::test_every_station_receives_the_largest_frame_any_station_may_send``
  (here: every ordered pair, each sender at its own ``mac.max_content``);
* a lost BOOT frame:
  ``tests/hil/sim/test_promises.py::test_a_lost_boot_frame_does_not_make_the_first_message_a_duplicate``.

Every run is seeded and tick-exact. A scenario is set up in two runs of the same
configuration: a probe finds the tick to act at, and a fresh world acts at exactly that tick.
"""
from __future__ import annotations

import random
from dataclasses import replace

import pytest

from firmware_model.radio.content import cmd
from firmware_model.radio.mac import MacConfig
from firmware_model.station import build_station
from firmware_model.timing import (
    CHILD_BYTE_TICKS, PC_BYTE_TICKS, TMAX_TICKS, TTRANS_TICKS, protocol_max_content, s_to_ticks,
)
from hil.sim.faults import parse_fault
from hil.sim.world import SimConfig, World
from contents import content_of

B = CHILD_BYTE_TICKS
FOREIGN_B = PC_BYTE_TICKS        # a transmitter that is no robot sends at exact 9600 baud
TSLOT = 320_000                  # MacConfig().tslot
TWIN = 160_000                   # MacConfig().twin


def bt(robot):
    return PC_BYTE_TICKS if robot == 0 else CHILD_BYTE_TICKS


def idle_turn(robot):
    return 14 * bt(robot) + TTRANS_TICKS


def world(setup=None, until=None, **cfg):
    """A world of ``cfg``; ``setup(w)`` schedules the scenario's acts before it runs."""
    evs: list[dict] = []
    w = World(SimConfig(**cfg), on_event=evs.append)
    if setup is not None:
        setup(w)
    w.run(until)
    return w, evs


def frames(evs, after=0, src=None):
    return [e for e in evs if e["ev"] == "frame" and e["start"] >= after and
            (src is None or e["src"] == src)]


def txen_on(evs, robot, after=0):
    return [e["t"] for e in evs if e["ev"] == "txen" and e["robot"] == robot and e["on"] and
            e["t"] >= after]


def events(evs, kind, after=0, **match):
    return [e for e in evs if e["ev"] == kind and e.get("t", -1) >= after and
            all(e.get(k) == v for k, v in match.items())]


def collisions(evs, after=0, robots_only=False):
    return [e for e in evs if e["ev"] == "collision" and e["t"] > after and
            not (robots_only and -1 in e["robots"])]


# -- token lost -------------------------------------------------------------------------------

LOST = [
    pytest.param((1, 2, 3, 4), 2, True, id="ring 1-4, R2's message frame lost"),
    pytest.param((1, 2, 3, 4), 2, False, id="ring 1-4, R2's heartbeat lost"),
    pytest.param((0, 1, 2), 0, True, id="ring 0-2, the father's message frame lost"),
    pytest.param((1, 2), 2, True, id="ring 1-2, R2's message frame lost"),
    pytest.param((1, 2), 2, False, id="ring 1-2, R2's heartbeat lost"),
    pytest.param((1, 2), 1, True, id="ring 1-2, R1's message frame lost"),
    pytest.param((1, 2), 1, False, id="ring 1-2, R1's heartbeat lost"),
    pytest.param((0, 1), 0, False, id="ring 0-1, the father's heartbeat lost"),
]


@pytest.mark.parametrize("robots,owner,message", LOST)
def test_token_lost_the_owners_frame_heard_by_nobody(robots, owner, message):
    """Token lost: the owner sends its frame (a heartbeat, or a message) but no receiver hears
    any of it. Paper §IV.C / docs/mac.md rule 3: every other member counts one miss at E + Tmax
    (E: the End that opened the owner's turn), exactly once; in a ring of three or more the
    next member's Header starts at E + Tmax + Ttrans; in a ring of two the survivor's miss
    comes right after its own frame with nothing heard since, so rule R-stagger adds id x
    Tslot, and rule R-pair makes it wait, too, until the owner's Header would have been heard
    had the owner not heard the survivor's frame (the owner's previous End + Tmax + owner x
    Tslot + Ttrans + 4 bytes). Either way one hears the other: nobody is dropped, no collision
    follows, and a lost message is retransmitted at the owner's next turn and delivered
    exactly once. (Without R-pair a lost heartbeat from the lower of two adjacent IDs made
    both transmit 7040 ticks apart: a heartbeat turn is within Ttrans + 3 bytes of one Tslot.)"""
    cfg = dict(robots=robots, duration=12.0)
    _, pevs = world(until=s_to_ticks(5.2), **cfg)
    t = txen_on(pevs, owner, s_to_ticks(5.0))[0]
    end = t + TTRANS_TICKS + (14 + (8 if message else 0)) * bt(owner)   # 'movex(5)': 8 bytes
    dst = next(r for r in robots if r != owner)
    held = {}

    def setup(w):
        if message:
            w.sched.at(t, lambda: held.setdefault("m", w.submit(owner, dst, [cmd("movex", 5)])))
        w.inject("fail", owner, t + 1)       # its radio neither sends nor hears ...
        w.inject("recover", owner, end)      # ... until its own End: the frame is lost
    w, evs = world(setup, **cfg)
    e_prev = max(f["end"] for f in frames(evs) if f["end"] <= t)
    assert e_prev == t                       # the owner's turn opened at the End before it
    assert all(f["start"] >= end for f in frames(evs, t, src=owner))   # none of it on air
    misses = events(evs, "miss", t, robot=owner)
    assert {(e["by"], e["t"]) for e in misses if e["t"] < end + TMAX_TICKS} == \
        {(r, e_prev + TMAX_TICKS) for r in robots if r != owner}
    assert collisions(evs, end) == []
    nxt = [f for f in frames(evs, end) if not f["collided"]][0]
    if len(robots) > 2:
        assert nxt["src"] == robots[(robots.index(owner) + 1) % len(robots)]
        assert nxt["start"] == e_prev + TMAX_TICKS + TTRANS_TICKS
    else:
        assert nxt["src"] == dst
        owner_prev = max(f["end"] for f in frames(evs, src=owner) if f["end"] < e_prev)
        floor = owner_prev + TMAX_TICKS + owner * TSLOT + TTRANS_TICKS + 4 * bt(dst)
        assert nxt["start"] == max(e_prev + TMAX_TICKS + dst * TSLOT, floor) + TTRANS_TICKS
    assert events(evs, "disable") == []
    if message:
        m = held["m"]
        assert m.state == "delivered" and m.attempts == 2
        got = events(evs, "deliver", src=owner, num=m.num)
        assert [(e["to"], e["intact"]) for e in got] == [(dst, True)]


# -- two robots believing they own the turn ---------------------------------------------------

@pytest.mark.parametrize("robots", [(1, 2), (0, 1)], ids=["ring 1-2", "ring 0-1"])
def test_two_robots_believing_they_own_the_turn_in_a_ring_of_two(robots):
    """Fault steal: the lower ID, one tick after its own End, wrongly takes the turn the other
    member is starting: both transmit, one collision. Each then waits Tmax after its own
    (collided) frame, counts the other's miss with nothing heard since its own frame, and rule
    R-stagger (docs/mac.md) makes it wait id x Tslot more: the lower ID raises TXEN at its End
    + Tmax + id x Tslot, the higher one hears that Header first and follows. Exactly one
    collision, one miss each, nobody dropped. (Ring of four:
    tests/hil/sim/test_ring.py::test_forced_collision_recovers_without_dropping_anyone.)"""
    lo, hi = robots
    cfg = dict(robots=robots, duration=10.0)
    _, pevs = world(until=s_to_ticks(5.0), **cfg)
    e_lo = frames(pevs, s_to_ticks(4.5), src=lo)[0]["end"]
    w, evs = world(lambda w: w.inject("steal", lo, e_lo + 1), **cfg)
    cols = collisions(evs, e_lo)
    assert [c["robots"] for c in cols] == [[lo, hi]]
    mine = [f for f in frames(evs, e_lo) if f["collided"]]
    assert sorted(f["src"] for f in mine) == [lo, hi]
    lo_end = next(f["end"] for f in mine if f["src"] == lo)
    assert txen_on(evs, lo, lo_end)[0] == lo_end + TMAX_TICKS + lo * TSLOT
    first = [f for f in frames(evs, lo_end) if not f["collided"]][0]
    assert first["src"] == lo and first["start"] == lo_end + TMAX_TICKS + lo * TSLOT + \
        TTRANS_TICKS
    assert sorted((e["by"], e["robot"]) for e in events(evs, "miss", e_lo)) == [(lo, hi), (hi, lo)]
    assert events(evs, "disable") == [] and w.ring_views() == {lo: robots, hi: robots}


# -- the successor vanishes mid-frame ---------------------------------------------------------

def test_the_successor_vanishes_during_its_predecessors_frame():
    """R2's radio dies in the middle of R1's frame, so R2 never takes the turn R1's End hands
    it. Paper §IV.C: R3 raises TXEN at E1 + Tmax (its Header at + Ttrans), each survivor counts
    R2's miss at E1 + Tmax, and after the third consecutive miss every survivor drops R2 at the
    same tick (§IV.D); the ring is R1 -> R3 -> R4 from then on."""
    cfg = dict(robots=(1, 2, 3, 4), duration=10.0)
    _, pevs = world(until=s_to_ticks(4.2), **cfg)
    t1 = txen_on(pevs, 1, s_to_ticks(4.0))[0]
    w, evs = world(lambda w: w.inject("fail", 2, t1 + TTRANS_TICKS + 7 * B), **cfg)
    e1 = frames(evs, t1, src=1)[0]["end"]
    assert frames(evs, e1)[0]["src"] == 3
    assert frames(evs, e1)[0]["start"] == e1 + TMAX_TICKS + TTRANS_TICKS
    first_misses = events(evs, "miss", e1, robot=2)[:3]
    assert {(e["by"], e["t"]) for e in first_misses} == {(r, e1 + TMAX_TICKS) for r in (1, 3, 4)}
    drops = events(evs, "disable", robot=2)
    assert {e["by"] for e in drops} == {1, 3, 4} and len({e["t"] for e in drops}) == 1
    assert all(len([m for m in events(evs, "miss", e1, robot=2, by=r)
                    if m["t"] <= drops[0]["t"]]) == 3 for r in (1, 3, 4))
    assert collisions(evs, e1) == []
    assert {r: w.ring_views()[r] for r in (1, 3, 4)} == {r: (1, 3, 4) for r in (1, 3, 4)}


def _vanish_mid_message():
    """R2 sends a 320-byte message to R4 and its radio dies 100 bytes into it. Returns the
    world, its events, R1's End that opened R2's turn, and the End R2's Length promised."""
    cfg = dict(robots=(1, 2, 3, 4), duration=12.0)
    _, pevs = world(until=s_to_ticks(4.2), **cfg)
    t2 = txen_on(pevs, 2, s_to_ticks(4.0))[0]
    held = {}

    def setup(w):
        w.sched.at(t2, lambda: held.setdefault(
            "m", w.submit(2, 4, [cmd("movex", 123456789)] * 20)))
        w.inject("fail", 2, t2 + TTRANS_TICKS + 100 * B + 1)
    w, evs = world(setup, **cfg)
    promised = t2 + TTRANS_TICKS + (14 + len(held["m"].content)) * B
    return w, evs, t2, promised, held["m"]


def test_the_successor_vanishes_mid_message_nothing_is_delivered_and_it_is_dropped():
    """R2 dies 100 bytes into a 334-byte frame carrying a message for R4. A frame that fails
    after a valid Header used the turn: it is not a miss (docs/mac.md, corrupted frames); the
    truncated message is delivered to nobody; R2 then misses its next three turns and every
    survivor drops it at the same tick; no collision."""
    w, evs, e1, promised, m = _vanish_mid_message()
    assert len(m.content) == 320
    assert events(evs, "deliver", src=2) == [] and events(evs, "duplicate", src=2) == []
    drops = events(evs, "disable", robot=2)
    assert {e["by"] for e in drops} == {1, 3, 4} and len({e["t"] for e in drops}) == 1
    before = [e for e in events(evs, "miss", e1, robot=2) if e["t"] <= drops[0]["t"]]
    assert len({e["t"] for e in before}) == 3           # three turns missed ...
    assert min(e["t"] for e in before) > e1 + TMAX_TICKS   # ... and not the failed frame's
    assert collisions(evs, e1) == []
    assert {r: w.ring_views()[r] for r in (1, 3, 4)} == {r: (1, 3, 4) for r in (1, 3, 4)}


def test_the_successor_vanishes_mid_message_the_turn_closes_at_the_stall():
    """docs/protocol.md clause 41: a frame whose bytes stop (no byte for the stall gap) closes
    its turn then, not at the End its Length promised (2.4 s later here); the turn closed on a
    failed frame, so rule R-stagger makes the next owner (R3) wait 3 x Tslot more: TXEN at
    (R2's death, where its last bytes reach R3) + the stall gap + 3 Tslot, to the reload timer's
    resolution (it counts machine clock / 2, so a delay armed at an odd tick ends a tick late,
    as on the MCU)."""
    w, evs, e1, promised, m = _vanish_mid_message()
    died = e1 + TTRANS_TICKS + 100 * B + 1
    stall = MacConfig().stall_gap
    assert txen_on(evs, 3, e1)[0] - (died + stall + 3 * TSLOT) in (1, 2, 3)
    assert txen_on(evs, 3, e1)[0] < promised


CUT_OFF = bytes.fromhex("0f0a05373230303330353632")
"""Issue 40, finding 5: a Header whose Length promises 562 bytes, then nothing (12 bytes)."""


@pytest.mark.parametrize("data", [CUT_OFF, CUT_OFF + b"\x01"],
                         ids=["stalled after its Length", "a bad Content byte, then silence"])
def test_a_cut_off_header_in_an_invitation_window_costs_its_bytes_not_its_promise(data):
    """Issue 40, finding 5: a foreign transmitter answers R4's invitation of the absent R5 with
    a Header that promises 562 bytes and stops after 12 (or breaks the frame with a 13th byte
    that is no Content, then stops). Closing the turn at the promised End held every member for
    594 ms (sent in every window for 37 s, it cut good frames by 67 %). The bytes stop: one
    stall gap after the last, every member takes the frame to be over and its turn closes there
    (clause 41); it closed uncertainly, so the next owner, R1 (the invited R5's successor),
    waits 1 x Tslot (R-stagger, clause 44) and begins: within the stall gap + R-stagger of the
    last byte, not at the promised End. Nobody is missed or dropped."""
    cfg = dict(robots=(1, 3, 4, 5), duration=6.0, faults=(parse_fault("fail:5@0"),))
    _, pevs = world(until=s_to_ticks(4.5), **cfg)
    polls = [f for f in frames(pevs, s_to_ticks(4.0), src=4) if f["kind"] == "control"]
    at = polls[0]["end"] + TTRANS_TICKS              # the invited robot's slot
    foreign = parse_fault(f"foreign@{at / 16e6!r}:x{data.hex()}")
    w, evs = world(**{**cfg, "faults": cfg["faults"] + (foreign,)})
    inter = events(evs, "interference")
    assert [(e["start"], e["bytes"]) for e in inter] == [(at, len(data))]
    last = at + len(data) * FOREIGN_B
    promised = at + (14 + 562) * B
    nxt = min(t for r in (1, 3, 4) for t in txen_on(evs, r, at))
    assert txen_on(evs, 1, at)[0] == nxt             # R1 takes the turn ...
    stall = MacConfig().stall_gap
    assert nxt - (last + stall + TSLOT) in (1, 2, 3)  # ... at the stall + 1 x Tslot
    assert nxt < promised - s_to_ticks(0.5)
    assert events(evs, "miss", at) == [] and events(evs, "disable", at) == []
    assert collisions(evs, at, robots_only=True) == []
    assert all(v == (1, 3, 4) for r, v in w.ring_views().items() if r != 5)


# -- the owner returns during a takeover -------------------------------------------------------

@pytest.mark.parametrize("missed", [1, 2, 3])
@pytest.mark.parametrize("offset", [-1, 0, 1], ids=["1 tick early", "exactly", "1 tick late"])
def test_the_owner_returns_as_the_next_robot_takes_its_turn(missed, offset):
    """R2's radio dies as R1 raises TXEN and comes back at the tick R3 takes over R2's turn for
    the ``missed``-th time (E + Tmax, paper §IV.C), or one tick either side. R2 must not speak
    out of turn when it returns: R3's Header starts at E + Tmax + Ttrans and no collision ever
    follows. With one or two misses R2 stays a member of every ring and is never dropped; at
    the third, every survivor drops it at that very tick (§IV.D) and it is invited back:
    rejoined by all three within the invitation bound (P x gap turns + a window; docs/mac.md:
    0.4-1.2 s measured)."""
    cfg = dict(robots=(1, 2, 3, 4), duration=14.0)
    _, pevs = world(until=s_to_ticks(4.2), **cfg)
    t1 = txen_on(pevs, 1, s_to_ticks(4.0))[0]
    _, pevs = world(lambda w: w.inject("fail", 2, t1), until=s_to_ticks(9.0), **cfg)
    takeovers = sorted({e["t"] for e in events(pevs, "miss", robot=2, by=3)})
    back = takeovers[missed - 1]
    # rule 3: each takeover is Tmax after the End of R1's frame that opened R2's turn
    assert back == max(f["end"] for f in frames(pevs, src=1) if f["end"] < back) + TMAX_TICKS

    def setup(w):
        w.inject("fail", 2, t1)
        w.inject("recover", 2, back + offset)
    w, evs = world(setup, **cfg)
    assert txen_on(evs, 3, back)[0] == back
    assert frames(evs, back)[0]["src"] == 3
    assert frames(evs, back)[0]["start"] == back + TTRANS_TICKS
    assert collisions(evs) == []
    drops = events(evs, "disable")
    if missed < 3:
        assert drops == []
        assert all(v == (1, 2, 3, 4) for v in w.ring_views().values())
        # R2 is heard again at its next turn: a clean frame one cycle later
        assert any(f["src"] == 2 for f in frames(evs, back) if f["start"] < back + s_to_ticks(0.2))
    else:
        assert {(e["by"], e["robot"], e["t"]) for e in drops} == {(r, 2, back) for r in (1, 3, 4)}
        rejoined = events(evs, "rejoin", back, robot=2)
        assert {e["by"] for e in rejoined} == {1, 3, 4}
        assert max(e["t"] for e in rejoined) - back <= s_to_ticks(1.2)
        assert all(v == (1, 2, 3, 4) for v in w.ring_views().values())


# -- two robots with the same ID ---------------------------------------------------------------

def _second_radio(w, robot, on_tick):
    """A second robot configured with ``robot``'s ID, on the same air, powered on at
    ``on_tick``. Returns its station and the list its MAC's actions are recorded in."""
    log: list = []
    cfg = replace(w.mac_config, byte_ticks=bt(robot))
    st, radio = build_station(robot, w.sched, byte_ticks=bt(robot), config=cfg,
                              observer=lambda s, a, now: log.append((now, type(a).__name__, a)))
    w.air.attach(radio)
    radio.alive = False

    def on():
        w.air.revive(radio, w.sched.now)
        st.power_on()
    w.sched.at(on_tick, on)
    return st, log


def test_a_second_robot_with_a_members_id_listens_and_never_transmits():
    """Two robots with the same ID, the second powered on while the first is a member: it
    starts in LISTEN (docs/mac.md, start-up), is never invited (its ID is not absent from the
    ring) and never claims (the ring is never silent for Tclaim); every frame from the other R2
    is refused by it as 'our own robot ID from the air'. It never transmits and never
    delivers, so nothing is delivered twice; the ring of three carries its traffic."""
    w = World(SimConfig(robots=(1, 2, 3), duration=20.0, seed=1, load=1.0, load_until=15.0),
              on_event=(evs := []).append)
    clone, log = _second_radio(w, 2, s_to_ticks(5.0))
    w.run()
    assert clone.mac.mode == "listen" and clone.mac.frames_sent == 0
    assert not [a for _, n, a in log if n in ("Transmit", "Deliver", "TxEnable") and
                getattr(a, "on", True)]
    refused = [a for _, n, a in log if n == "Refused"]
    assert refused and all(a.src == 2 and a.reason == "our own robot ID from the air"
                           for a in refused)
    assert collisions(evs) == [] and events(evs, "disable") == []
    s = w.summary()
    assert s["submitted"] > 30 and s["pending"] == 0
    assert s["delivered"] == s["submitted"] and s["duplicate_deliveries"] == 0
    assert all(v == (1, 2, 3) for v in w.ring_views().values())


def test_two_robots_with_the_same_id_do_not_take_the_others_down():
    """Two robots with the same ID powered on together can never both be members; but the
    robots with unique IDs must keep their ring: R1 and R3 never drop each other and every
    message between them is delivered (docs/guarantees.md: every message delivered or failed,
    and a ring whose robots' radios work is whole)."""
    w = World(SimConfig(robots=(1, 2, 3), duration=30.0, seed=1), on_event=(evs := []).append)
    _second_radio(w, 2, 0)
    sent = []
    for k in range(24):                       # a message each way every 0.5 s from 6 s
        t = s_to_ticks(6.0 + 0.5 * k)
        src, dst = (1, 3) if k % 2 == 0 else (3, 1)
        w.sched.at(t, lambda s=src, d=dst, k=k: sent.append(w.submit(s, d, [cmd("movex", k)])))
    w.run()
    assert not [e for e in events(evs, "disable") if {e["by"], e["robot"]} == {1, 3}]
    assert [m.state for m in sent] == ["delivered"] * 24, [m.reason for m in sent]


# -- forged Sources ----------------------------------------------------------------------------

def _raw_frame(src: str, dst=b"3", num=b"42", type_=b"2", content=b"joint(1,80)") -> bytes:
    """Frame bytes with any Source digit (Frame itself refuses a Source that is no robot ID)."""
    return b"\x0f\x0a\x05" + dst + src.encode() + num + type_ + b"%04d" % len(content) + \
        content + b"\x17\x19"


FORGED = [
    pytest.param("9", "source", None, id="not a robot ID '9'"),
    pytest.param("5", "refused", {r: "robot 5 is not in the team" for r in (0, 2, 3, 4)},
                 id="outside the team '5'"),
    pytest.param("3", "refused", {0: "out of turn: it was robot 1's turn",
                                  2: "out of turn: it was robot 1's turn",
                                  3: "our own robot ID from the air",
                                  4: "out of turn: it was robot 1's turn"},
                 id="our own ID, a child's '3'"),
    pytest.param("0", "refused", {0: "our own robot ID from the air",
                                  2: "out of turn: it was robot 1's turn",
                                  3: "out of turn: it was robot 1's turn",
                                  4: "out of turn: it was robot 1's turn"},
                 id="our own ID, the father's '0'"),
]


@pytest.mark.parametrize("src,how,reasons", FORGED)
def test_a_forged_source_is_refused_not_acted_on_and_desynchronises_nobody(src, how, reasons):
    """A frame for R3 with ``joint(1,80)`` and a forged Source is put on the air in R1's silent
    slot (R1's radio died after its turn). docs/mac.md (refused frames; guarantees.md, spoofing):
    every member refuses it, counts and traces it (a Source that is no robot ID fails in the
    deframer: ``bad_frame`` at the source byte), and nothing is acted on: R3's arm receives no
    joint command. It must not split the ring's timing either: the silent R1 is dropped by
    every member at the same tick (paper §IV.D), and no member refuses a legitimate frame."""
    cfg = dict(robots=(0, 1, 2, 3, 4), duration=10.0, can=True)
    _, pevs = world(until=s_to_ticks(5.0), **cfg)
    e1 = frames(pevs, src=1)[-1]["end"]
    _, pevs = world(lambda w: w.inject("fail", 1, e1 + 1), until=e1 + s_to_ticks(0.15), **cfg)
    t = frames(pevs, e1, src=0)[-1]["end"] + s_to_ticks(0.1)      # inside R1's silent slot
    data = _raw_frame(src)

    def setup(w):
        w.inject("fail", 1, e1 + 1)
        w.inject_bytes(data, t)
    w, evs = world(setup, **cfg)
    end = t + len(data) * FOREIGN_B
    live = (0, 2, 3, 4)
    if how == "source":
        # at the Source byte's end (byte 4), as each byte comes at its tick
        bad = events(evs, "bad_frame", t)
        assert {(e["to"], e["field"]) for e in bad if e["t"] == t + 5 * FOREIGN_B} == \
            {(r, "source") for r in live}
        assert events(evs, "refused", t) == []
    else:
        got = {e["to"]: e["reason"] for e in events(evs, "refused", t, src=int(src), num=42)}
        assert got == reasons
    assert events(evs, "deliver", t, num=42) == []
    assert [e for e in evs if e["ev"] == "can" and e["bus"] == 3 and 0x101 <= e["id"] <= 0x104
            and e["t"] >= t] == []
    drops = events(evs, "disable", robot=1)
    assert {e["by"] for e in drops} == set(live) and len({e["t"] for e in drops}) == 1
    legit = [e for e in events(evs, "refused", end + 1) if e["src"] in live]
    assert legit == []
    assert collisions(evs, t) == []


def test_a_forged_never_member_is_admitted_only_on_its_third_frame_and_never_acted_on():
    """docs/mac.md, refused frames: a team robot outside the ring that answers no invitation is
    refused; heard in 3 frames, each less than a cycle after the last, it is admitted, and
    acted on only from its next frame. So forged frames 'from R5' (in the team, never powered
    on) in R1's silent slot: the first two are refused ('not a member and was not invited') by
    every member, the third admits R5 (join, by every member) without acting on it; R3's arm
    never moves. R5 then never sends: 3 misses, dropped by every member at the same tick."""
    cfg = dict(robots=(1, 2, 3, 4, 5), duration=14.0, can=True, power_on={5: 1000.0})
    _, pevs = world(until=s_to_ticks(5.0), **cfg)
    e1 = frames(pevs, src=1)[-1]["end"]
    w, evs = world(lambda w: w.inject("fail", 1, e1 + 1), until=e1 + 1, **cfg)
    forged_at = []
    for k in range(3):                         # the next three silent slots of R1
        t0 = w.now
        while not frames(evs, t0, src=4):
            w.run(w.now + s_to_ticks(0.01))
        t = frames(evs, t0, src=4)[0]["end"] + s_to_ticks(0.1)
        w.inject_bytes(_raw_frame("5", num=b"%02d" % (50 + k)), t)
        forged_at.append(t)
        w.run(t + s_to_ticks(0.05))
    w.run()
    members = (2, 3, 4)
    for k, t in enumerate(forged_at):
        got = {e["to"]: e["reason"] for e in events(evs, "refused", t, src=5, num=50 + k)}
        want = "robot 5 is not a member and was not invited" if k < 2 else \
            "robot 5 admitted after 3 frames; this one is not acted on"
        assert got == {r: want for r in members}
    joins = events(evs, "join", robot=5)
    assert {e["by"] for e in joins} == set(members)
    assert {e["t"] for e in joins} == {forged_at[2] + len(_raw_frame("5")) * FOREIGN_B}
    assert events(evs, "deliver", src=5) == []
    assert [e for e in evs if e["ev"] == "can" and e["bus"] == 3 and 0x101 <= e["id"] <= 0x104
            and e["t"] >= forged_at[0]] == []
    drops = events(evs, "disable", forged_at[2], robot=5)
    assert {e["by"] for e in drops} == set(members) and len({e["t"] for e in drops}) == 1


# -- an interferer inside a poll window --------------------------------------------------------

def _poll_window(data_at):
    """Robots 1-3 in a ring, robot 4 in the team but never powered on: R3 invites it every 4 of
    its turns, and every member waits for its answer until E + Twin (E: the End of R3's polling
    frame). ``data_at(E)`` gives (bytes, tick) to put on the air. Returns events and E."""
    cfg = dict(robots=(1, 2, 3, 4), duration=9.0, power_on={4: 1000.0})
    _, pevs = world(until=s_to_ticks(6.0), **cfg)
    polls = [f for f in frames(pevs, s_to_ticks(4.5), src=3) if f["kind"] == "control"]
    E = polls[0]["end"]
    data, at = data_at(E)
    w, evs = world(lambda w: w.inject_bytes(data, at), **cfg)
    assert any(e["ev"] == "frame" and e["end"] == E and e["src"] == 3 for e in evs)
    return w, evs, E, at + len(data) * FOREIGN_B


def _window_outcome(w, evs, E, burst_end):
    assert events(evs, "join", robot=4) == [] and events(evs, "rejoin", robot=4) == []
    assert events(evs, "disable") == [] and events(evs, "miss", E) == []
    assert collisions(evs, burst_end) == []
    assert all(v == (1, 2, 3) for r, v in w.ring_views().items() if r != 4)


def test_foreign_bytes_inside_a_poll_window_do_not_move_the_window_end():
    """Three foreign bytes that form no Header, wholly inside the window (E + 20000 to E +
    70001). docs/mac.md, invitations: if the invited robot's Header is not heard by E + Twin,
    the poller's successor (R1) raises TXEN at E + Twin, to the tick; nobody misses, nobody
    is admitted, no collision."""
    w, evs, E, burst_end = _poll_window(lambda E: (random.Random(7).randbytes(3), E + 20_000))
    assert burst_end < E + TWIN
    _window_outcome(w, evs, E, burst_end)
    assert txen_on(evs, 1, E)[0] == E + TWIN
    assert frames(evs, E)[0]["src"] == 1 and frames(evs, E)[0]["start"] == E + TWIN + TTRANS_TICKS


def test_a_bare_header_beginning_inside_a_poll_window_closes_it_as_a_failed_frame():
    """A foreign Header (0F 0A 05 and nothing more) whose start bit falls 1000 ticks before E +
    Twin. docs/mac.md: a Header that had begun by E + Twin is waited for; it completes but the
    frame never comes, so the turn closes as on a failed frame when the channel falls quiet and
    rule R-stagger applies: the poller's successor R1 goes first (not before the Header's end +
    Tslot), nobody else transmits before it, nobody misses or is admitted, no collision."""
    w, evs, E, burst_end = _poll_window(lambda E: (b"\x0f\x0a\x05", E + TWIN - 1000))
    _window_outcome(w, evs, E, burst_end)
    first = frames(evs, E)[0]
    assert first["src"] == 1 and not first["collided"]
    assert txen_on(evs, 1, E)[0] >= burst_end + TSLOT
    assert txen_on(evs, 2, E)[0] >= first["end"] and txen_on(evs, 3, E)[0] >= first["end"]


@pytest.mark.parametrize("n", [20, 40, 300])
def test_a_foreign_burst_across_the_end_of_a_poll_window(n):
    """``n`` random foreign bytes starting inside the window (E + 20000) and running past E +
    Twin. Lock-step rule (docs/guarantees.md, the lock-step search's bounds): nobody is
    dropped, no collision between robots (or with the burst) starts after the burst ends, and
    a good frame starts within Tmax + one idle cycle of its end; the invited robot is not
    admitted and nobody's miss is counted for the window."""
    w, evs, E, burst_end = _poll_window(lambda E: (random.Random(n).randbytes(n), E + 20_000))
    assert burst_end > E + TWIN
    assert events(evs, "join", robot=4) == [] and events(evs, "disable") == []
    assert collisions(evs, burst_end) == []
    good = [f for f in frames(evs, burst_end) if not f["collided"]]
    assert good[0]["start"] - burst_end <= TMAX_TICKS + sum(idle_turn(r) for r in (1, 2, 3))
    assert all(v == (1, 2, 3) for r, v in w.ring_views().items() if r != 4)


# -- the largest frame between every pair ------------------------------------------------------

def _largest_between_every_pair():
    robots = (0, 1, 2)
    w = World(SimConfig(robots=robots, duration=14.0), on_event=(evs := []).append)
    w.run(s_to_ticks(4.5))
    assert w.ring_complete()
    msgs = {(s, d): w.submit(s, d, content_of(w.stations[s].mac.max_content))
            for s in robots for d in robots if s != d}
    w.run()
    return w, evs, msgs


def test_the_largest_frame_between_every_pair_father_included():
    """docs/mac.md (frame bounds): each sender sends at most what its own byte time fits in
    Tmax (``mac.max_content``: 562 for a child, 561 for the father), and every receiver
    accepts Length up to ``timing.protocol_max_content()`` (562). Every ordered pair of the
    father and two children exchanges a message of exactly the sender's maximum, all submitted
    at once: each frame is exactly 14 + that many bytes and on the air for at most Tmax, and
    each message is delivered exactly once, intact, to its destination only."""
    w, evs, msgs = _largest_between_every_pair()
    robots = (0, 1, 2)
    assert {r: w.stations[r].mac.max_content for r in robots} == {0: 561, 1: 562, 2: 562}
    assert {w.stations[r].mac.rx_max_content for r in robots} == {protocol_max_content()}
    for (s, d), m in msgs.items():
        assert m.state == "delivered", (s, d, m.reason)
        got = events(evs, "deliver", src=s, num=m.num)
        assert [(e["to"], e["intact"]) for e in got] == [(d, True)]
        sent = [f for f in frames(evs, src=s) if f["num"] == m.num and f["kind"] == "message"]
        assert len(sent) == m.attempts
        assert all(f["len"] == w.stations[s].mac.max_content and
                   f["bytes"] == f["len"] + 14 and f["end"] - f["start"] <= TMAX_TICKS
                   for f in sent)
    s = w.summary()
    assert s["duplicate_deliveries"] == 0 and s["wrong_robot_deliveries"] == 0
    assert s["delivered"] == 6 and s["failed"] == 0


def test_the_largest_frame_is_acknowledged_within_one_cycle():
    """docs/mac.md, delivery accounting: a message is acknowledged by its destination on the
    acknowledger's next frame, within one cycle; so with no loss each of the six largest
    messages goes on the air once."""
    w, evs, msgs = _largest_between_every_pair()
    assert {k: m.attempts for k, m in msgs.items()} == {k: 1 for k in msgs}


# -- Number wrap 99 -> 00 ----------------------------------------------------------------------

def _lose_once(mac, match):
    """The next frame ``match(frame)`` accepts is heard garbled by ``mac``'s robot (its End
    failed: the turn counts, the frame is not acted on). Returns a counter of frames lost."""
    lost = {"n": 0}
    real = mac.on_frame

    def lossy(frame, first, end, now):
        if not lost["n"] and match(frame):
            lost["n"] += 1
            return mac.on_corrupt(first, frame.src, end, now)
        return real(frame, first, end, now)
    mac.on_frame = lossy
    return lost


def test_number_wrap_99_to_00_with_retransmissions_across_the_wrap():
    """docs/mac.md, delivery accounting: Numbers go '00'...'99' and wrap; a receiver delivers
    once per (Source, Number), comparing with the last message Number heard from the source.
    R1 sends R2 messages '01'...'98'; then message '99' is delivered but R2's acknowledgement is
    lost at R1, so '99' is retransmitted and R2 re-acknowledges it as a duplicate without
    delivering it again; then the first transmission of message '00' (after the wrap) is lost
    at R2, so '00' is retransmitted and delivered once, not taken for a duplicate of '99' nor
    of the BOOT frame's '00'; '01' follows. Every message is delivered exactly once."""
    w = World(SimConfig(robots=(1, 2, 3), duration=60.0), on_event=(evs := []).append)
    w.run(s_to_ticks(4.5))
    assert w.ring_complete()

    def send(k):
        m = w.submit(1, 2, [cmd("movex", k)])
        while m.state in ("queued", "sent"):
            w.run(w.now + s_to_ticks(0.02))
        return m
    early = [send(k) for k in range(1, 99)]
    assert [m.num for m in early] == list(range(1, 99))
    assert all(m.state == "delivered" and m.attempts == 1 for m in early)
    acks_lost = _lose_once(w.stations[1].mac, lambda f: f.src == 2 and b"ack(1,99)" in f.content)
    m99 = send(99)
    assert acks_lost["n"] == 1 and m99.num == 99
    assert (m99.state, m99.attempts) == ("delivered", 2)
    first_lost = _lose_once(w.stations[2].mac, lambda f: f.src == 1 and f.num == 0 and
                            f.type == 2)
    m00 = send(100)
    assert first_lost["n"] == 1 and m00.num == 0
    assert (m00.state, m00.attempts) == ("delivered", 2)
    m01 = send(101)
    assert m01.num == 1 and (m01.state, m01.attempts) == ("delivered", 1)
    got = [(e["num"], e["intact"]) for e in events(evs, "deliver", src=1, to=2)]
    assert got == [(n, True) for n in range(1, 100)] + [(0, True), (1, True)]
    dups = [e["num"] for e in events(evs, "duplicate", src=1, to=2)]
    assert dups == [99]
    s = w.summary()
    assert s["duplicate_deliveries"] == 0 and s["corrupt_deliveries"] == 0

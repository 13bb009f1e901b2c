"""Every bound docs/protocol.md derives (§7, and clause 5's table), evaluated for every margin
set the code ships: the MCU-exact defaults (``MacConfig()``), the real-time set
(``hil/bench/runner.py REALTIME_MARGINS``), and both again in the paper profile. A margin change
that breaks a bound fails here, naming the bound and the set.

Each set must also keep its bounds with the latency it allows a PC to spare:
L = Twin - (Ttrans + 3 B), the lateness its own invitation window tolerates in an invited
robot's Header (clause 34, §7.5): 1.9 ms in the exact set, 41.9 ms in the real-time set. A bound
that only holds for a station with no latency at all would fail on the bench (issue 40: with a
real-time Tslot of 100 ms, robot 6's R-stagger put its Header 5 ms after the others' E + Tmax,
and a healthy robot 6 was counted missing after every burst).
"""
from __future__ import annotations

import re
from dataclasses import replace

import pytest

from firmware_model.radio.auth import AUTH_TEXT_LEN, RingKey
from firmware_model.radio.integrity import CRC_TEXT_LEN
from firmware_model.radio.mac import MacConfig
from firmware_model.timing import (
    CHILD_BYTE_TICKS, PC_BYTE_TICKS, TICK_HZ, max_frame_bytes, protocol_max_content,
)
from hil.bench.runner import REALTIME_MARGINS, realtime_config
from paths import ROOT

DOC = ROOT / "docs" / "protocol.md"
MS = TICK_HZ // 1000
B = PC_BYTE_TICKS                # the slower byte: every bound below holds for it
MAX_ID = 6                       # clause 1: the highest robot ID

SETS = {
    "exact": MacConfig(),
    "real time": realtime_config(MacConfig()),
    "paper, exact": MacConfig(profile="paper"),
    "paper, real time": realtime_config(MacConfig(profile="paper")),
}


def latency(cfg: MacConfig) -> int:
    """L: how late a PC's Header may be heard, by the set's own invitation window (§7.5)."""
    return cfg.twin - (cfg.ttrans + 3 * B)


def bounds(cfg: MacConfig) -> dict[str, tuple[int, int]]:
    """Every inequality of §7 for ``cfg``, as (smaller, larger): smaller < larger must hold
    with at least L to spare where a PC's lateness counts (the names say which)."""
    team = len(cfg.team)
    header = cfg.ttrans + 3 * B                     # TXEN to a complete Header
    heard = cfg.ttrans + 4 * B                      # ... with a byte of slack (§7.6)
    watch2 = 2 * cfg.ttrans + (2 + 2) * cfg.standby_watch    # a standby's wait, pc = 2
    return {
        # §7.1: the largest frame a station sends fits in Tmax; every receiver accepts 562
        "7.1 child frame in Tmax": (max_frame_bytes(CHILD_BYTE_TICKS, cfg.tmax)
                                    * CHILD_BYTE_TICKS, cfg.tmax + 1),
        "7.1 PC frame in Tmax": (max_frame_bytes(PC_BYTE_TICKS, cfg.tmax) * PC_BYTE_TICKS,
                                 cfg.tmax + 1),
        # §7.4: no claim over a live ring; the first claimer is heard before the next claims
        "7.4 live ring silence < claim": ((team - 1) * cfg.tmax + cfg.ttrans,
                                          team * cfg.tmax),
        "7.4 claim stagger (+L)": (header + latency(cfg), cfg.tslot),
        # §7.5: an invited robot's Header is complete inside the window
        "7.5 invited Header < Twin": (header, cfg.twin),
        # §7.6: of two members after an uncertain closure the higher hears the lower first
        "7.6 Tslot > 2 (Ttrans + 4 B)": (2 * heard, cfg.tslot),
        "7.6 Tslot > Ttrans + 4 B (+L)": (heard + latency(cfg), cfg.tslot),
        # §7.6: the highest ID's R-stagger Header is heard before the others' E + Tmax ...
        "7.6 6 Tslot + Ttrans + 4 B < Tmax (+L)": (MAX_ID * cfg.tslot + heard + latency(cfg),
                                                   cfg.tmax),
        # ... also when a jam the others took for nothing (its bytes within Ttrans of the
        # closure, clause 42) moves the stagger to the quiet instant (clause 44)
        "7.6 Ttrans + quiet gap + 6 Tslot + Ttrans + 4 B < Tmax (+L)": (
            cfg.ttrans + cfg.quiet_gap + MAX_ID * cfg.tslot + heard + latency(cfg), cfg.tmax),
        # ... and when the closure is a stall (clause 41): every member closes at the stall
        "7.6 stall gap >= 2 B": (2 * CHILD_BYTE_TICKS - 1, cfg.stall_gap),
        # §7.8: the standby's takeover is no miss, and never steals a live active PC's turn
        "7.8 standby takeover < Tmax (+L)": (watch2 + latency(cfg), cfg.tmax),
        "7.8 checking PC2 before standby": (cfg.ttrans + cfg.standby_watch + header, watch2),
    }


CASES = [(name, bound) for name, cfg in SETS.items() for bound in bounds(cfg)]


@pytest.mark.parametrize("name, bound", CASES, ids=[f"{n}: {b}" for n, b in CASES])
def test_every_bound_of_section_7_holds_for_every_shipped_margin_set(name, bound):
    small, large = bounds(SETS[name])[bound]
    assert small < large, (f"{name} margins break §7 bound {bound!r}: "
                           f"{small / MS:.3f} ms is not below {large / MS:.3f} ms")


def test_the_real_time_set_is_the_runners():
    rt = SETS["real time"]
    assert {k: getattr(rt, k) for k in REALTIME_MARGINS} == REALTIME_MARGINS
    assert rt.tslot < MacConfig().tmax // MAX_ID      # the bound issue 40 found broken


def test_the_largest_content_is_562_for_every_set():
    for cfg in SETS.values():
        assert protocol_max_content(cfg.tmax) == 562


def test_the_bounds_fail_for_the_old_real_time_tslot():
    """The test can fail: 100 ms, the real-time Tslot before issue 40, breaks §7.6."""
    from dataclasses import replace
    old = bounds(replace(SETS["real time"], tslot=100 * MS))
    broken = [k for k, (side, limit) in old.items() if not side < limit]
    assert broken == ["7.6 6 Tslot + Ttrans + 4 B < Tmax (+L)",
                      "7.6 Ttrans + quiet gap + 6 Tslot + Ttrans + 4 B < Tmax (+L)"]


def _clause5_row(first: str) -> list[str]:
    text = DOC.read_text(encoding="utf-8")
    text = text[text.index("**Clause 5 "):]
    m = re.search(rf"^\| {re.escape(first)} \|(.*)\|$", text, flags=re.M)
    assert m, f"no row {first!r} in clause 5's table"
    return [c.strip() for c in m.group(1).split("|")]


def test_clause_5s_tclaim_row_is_the_codes_for_both_sets():
    exact, real = _clause5_row("Tclaim(id) for a team of n")
    for text, cfg in ((exact, SETS["exact"]), (real, SETS["real time"])):
        assert text == f"n × {cfg.tmax // MS} ms + id × {cfg.tslot // MS} ms"
        assert cfg.claim_ticks(3) == len(cfg.team) * cfg.tmax + 3 * cfg.tslot



# -- the simulator: issue 40's bench scenario -----------------------------------------------

def test_no_healthy_robot_is_counted_missing_with_real_time_margins_and_bursts():
    """Issue 40, finding 2 at the bench, in the simulator: children 1, 2 and 6 with the
    real-time margins and a 4 ms burst every 0.73 s for 28 s. Each burst that breaks a frame
    closes a turn uncertainly (clause 41), and when robot 6's turn follows, its R-stagger
    (6 x Tslot) must still put its Header on the air before the others' closure + Tmax. With
    Tslot 100 ms robot 6 was counted missing 12 times by each of the others (and robot 1 12
    times by robot 2, which then took 6's late frame for one out of turn:
    ``python benchmarks/stagger_and_cutoff.py stagger --tslot-ms 100``); now nobody is, and no
    two robots ever collide."""
    from hil.sim.faults import parse_fault
    from hil.sim.world import SimConfig, World
    team = frozenset((1, 2, 6))
    faults = tuple(parse_fault(f"burst@{2 + 0.73 * k:.2f}:0.004") for k in range(39))
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 6), duration=30.0, seed=1, faults=faults,
                        mac=realtime_config(MacConfig(team=team))), on_event=evs.append)
    w.run()
    assert w.fault_count == {"burst": 39}
    broken = [e for e in evs if e["ev"] == "collision" and -1 in e["robots"]]
    assert len(broken) >= 20                 # the bursts did break frames ...
    assert [e for e in evs if e["ev"] == "miss"] == []     # ... and nobody was missed
    assert [e for e in evs if e["ev"] == "disable"] == []
    assert [e for e in evs if e["ev"] == "collision" and -1 not in e["robots"]] == []
    assert all(v == (1, 2, 6) for v in w.ring_views().values())


def test_no_robot_is_counted_missing_after_a_burst_over_a_frame_end():
    """What the pty hub's test of issue 40 (tests/hil/bench/test_bench_processes.py, a burst over a
    frame's end) must match: a 6 ms burst from 1.3 ms before a robot's frame ends on the air
    to 62.5 us before that robot's Ttrans is over, 40 times. The sender's radio is deaf until
    3 ms after its last byte, so it hears only the burst's tail, before its successor could
    have begun (clause 42: not its successor's frame); the others hear the frame broken,
    close its turn uncertainly and let the successor begin after its R-stagger.
    Nobody is counted missing, nobody is dropped."""
    from hil.sim.world import SimConfig, World
    team = frozenset((1, 2, 6))
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 6), duration=22.0, seed=1, ring_sleep=False,
                        mac=realtime_config(MacConfig(team=team))), on_event=evs.append)
    at: list[int] = []
    transmit = w.air.transmit

    def burst_over_the_end(radio, data, t0, bt):
        transmit(radio, data, t0, bt)
        end = t0 + len(data) * bt
        if radio.robot in team and t0 >= 4 * TICK_HZ and len(at) < 40 and \
                (not at or end >= at[-1] + 2 * TICK_HZ // 5):
            at.append(end)
            w.sched.at(end - 21_002, w.air.burst, 0.006)     # 6 B: to end + 79,000 ticks
    w.air.transmit = burst_over_the_end
    w.run()
    assert len(at) == 40 and w.air.bursts == 40
    hits = [e for e in evs if e["ev"] == "collision"]
    assert len(hits) == 40 and all(-1 in e["robots"] for e in hits)   # each broke its frame
    assert [e for e in evs if e["ev"] in ("miss", "disable")] == []


def test_a_late_header_after_garbage_in_its_slot_is_its_owners_frame():
    """Issue 40 at the bench, the misses after a burst in a hand-over: a burst heard after
    robot 1's turn began (and Ttrans more) is taken for robot 1's frame with a broken Header,
    and its turn closes when the channel falls quiet (clause 42). On the bench robot 1's
    Header can begin more than the real-time quiet gap after that garbage (a PC's bytes reach
    the air late, and each process reads the air late by its own amount): robot 6, then
    waiting for robot 2's staggered turn, refused robot 1's clean frame as out of turn and
    counted robot 2 missing, while robot 2, in its R-stagger wait, followed the frame. Here
    robot 1's frame reaches the air 30 ms after the garbage, as a PC's can: every member
    takes it for robot 1's frame, nobody is counted missing, the ring goes on in step."""
    from firmware_model.timing import TTRANS_TICKS
    from hil.sim.world import SimConfig, World
    team = frozenset((1, 2, 6))
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 6), duration=8.0, seed=1, ring_sleep=False,
                        mac=realtime_config(MacConfig(team=team))), on_event=evs.append)
    w.run(4 * TICK_HZ)
    while not [e for e in evs if e["ev"] == "frame" and e["src"] == 6 and
               e["start"] >= 4 * TICK_HZ]:
        w.run(w.now + 1000)
    e6 = [e for e in evs if e["ev"] == "frame" and e["src"] == 6][-1]["end"]
    assert w.now < e6 + TTRANS_TICKS                 # robot 1 has not sent a byte yet
    garbage = e6 + TTRANS_TICKS + 2 * MS             # 4 bytes, after robot 1 could begin
    late = garbage + 4 * B + 30 * MS                 # more than the quiet gap after them
    transmit = w.air.transmit
    delayed: list[int] = []

    def late_on_air(radio, data, t0, bt):
        if radio.robot == 1 and not delayed:     # robot 1's frame reaches the air late
            delayed.append(t0)
            w.sched.at(late, on_air_late, radio, bytes(data), bt)
            return
        transmit(radio, data, t0, bt)

    def on_air_late(radio, data, bt):
        # as the pty hub does: the node is deaf while its bytes are on the air, and its
        # radio's RX-ready delay (3 ms) after
        w.air.deafen(radio, late)
        radio.rx_from = end = late + len(data) * bt + radio.rx_ready_delay
        w.air.inject(data, bt)
        w.sched.at(end, w.air.rx_restart, radio, end)
    w.air.transmit = late_on_air
    w.sched.at(garbage, w.air.burst, 4 * B / TICK_HZ)
    w.run()
    assert delayed == [e6 + TTRANS_TICKS]            # robot 1 began on time, by its clock
    after = [e for e in evs if e.get("t", 0) >= garbage]
    on_air = [e for e in after if e["ev"] == "interference"]
    assert [(e["start"], e["bytes"], e["collided"]) for e in on_air[:2]] == \
        [(garbage, 4, False), (late, 14, False)]    # the garbage, then robot 1's heartbeat
    assert [e for e in after if e["ev"] in ("miss", "disable", "refused")] == []
    assert all(v == (1, 2, 6) for v in w.ring_views().values())


def test_a_jams_tail_taken_for_the_next_owners_frame_costs_nobody_a_miss(tmp_path):
    """The same rule in a ring of MCUs (exact margins): a 300 ms burst garbles the father's
    frame and goes on past its End. Robot 1, next, waits for the jam to fall quiet and then
    its R-stagger (clause 44); the father and robot 3 took the jam's tail, heard after robot
    1's turn began, for robot 1's broken frame and closed its turn (clause 42). When robot
    1's staggered Header came, both refused it as out of turn and counted robot 2 missing,
    while robot 2 followed it. Now every member takes it for robot 1's frame (the seeded run
    of tests/data/trace_digests.txt, "collision, burst, checksum")."""
    import json

    from hil.cli import main
    trace = tmp_path / "t.jsonl"
    assert main(["sim", "--robots", "0,1,2,3", "--duration", "8", "--seed", "4", "--checksum",
                 "--load", "1", "--fault", "steal:2@3", "--fault", "burst@6:0.3",
                 "--trace", str(trace), "--no-progress", "--json"]) == 0
    evs = [json.loads(line) for line in trace.read_text().splitlines()]
    burst = 6 * TICK_HZ
    after = [e for e in evs if e.get("t", 0) >= burst]
    assert [e for e in after if e["ev"] == "collision"]      # the burst broke a frame
    assert [e for e in after if e["ev"] in ("miss", "disable", "refused")] == []
    assert [e for e in after if e["ev"] == "deliver" and e["src"] == 1 and e["to"] == 0]


def test_a_lone_members_invitation_answered_late_admits_the_answerer():
    """Issue 40, the misses while the ring forms at the bench: robot 1, alone, invites robot 2;
    robot 2's BOOT reaches the air 60 ms after the poll (a loaded PC: more than the real-time
    Twin). Robot 1 had closed the window and, in its lone pause, took the BOOT for another
    robot heard while alone: back to LISTEN (clause 31), while robot 2, a member of {1, 2},
    counted robot 1 missing until it dropped it. A BOOT or JOIN from the robot it invited,
    heard before its own next frame, is now the answer: both have the ring {1, 2}, nobody is
    counted missing."""
    from firmware_model.timing import TTRANS_TICKS
    from hil.sim.world import SimConfig, World
    team = frozenset((1, 2))
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2), duration=8.0, seed=1, ring_sleep=False,
                        mac=realtime_config(MacConfig(team=team))), on_event=evs.append)
    transmit = w.air.transmit
    delayed: list[int] = []

    def late_on_air(radio, data, t0, bt):
        if radio.robot == 2 and not delayed:     # robot 2's answer reaches the air late
            delayed.append(t0)
            w.sched.at(t0 + 55 * MS, on_air_late, radio, bytes(data), bt, t0 + 55 * MS)
            return
        transmit(radio, data, t0, bt)

    def on_air_late(radio, data, bt, late):
        w.air.deafen(radio, late)                # deaf while its bytes are on the air
        radio.rx_from = end = late + len(data) * bt + radio.rx_ready_delay
        w.air.inject(data, bt)
        w.sched.at(end, w.air.rx_restart, radio, end)
    w.air.transmit = late_on_air
    w.run()
    assert len(delayed) == 1
    polls = [e for e in evs if e["ev"] == "frame" and e["src"] == 1 and e["end"] < delayed[0]]
    assert delayed[0] - polls[-1]["end"] == TTRANS_TICKS   # robot 2 answered on time
    assert [e for e in evs if e["ev"] in ("miss", "disable")] == []
    assert [(e["robot"], e["mode"]) for e in evs if e["ev"] == "mode"] == \
        [(1, "member"), (2, "member")]
    assert w.ring_views() == {1: (1, 2), 2: (1, 2)}


# -- §7.3: a silent robot, dropped in the simulator -----------------------------------------

def _drop_after(ring: tuple[int, ...], victim: int, at: float, cfg: MacConfig,
                absent: tuple[int, ...] = ()) -> int:
    """Ticks from ``victim``'s radio failing at ``at`` s to the first member dropping it, in
    an idle ring of ``ring`` whose team also holds ``absent`` (IDs never heard: powered on
    only after the drop). Checks the ring was whole and idle when the radio failed, and that
    every other member drops the victim and counts nobody else missing."""
    from hil.sim.faults import Fault
    from hil.sim.world import SimConfig, World
    end = at + 1.5 * cfg.silent_drop_ticks(ring) / TICK_HZ     # the drop comes well before
    evs: list[dict] = []
    w = World(SimConfig(robots=tuple(sorted(ring + absent)), duration=end, mac=cfg,
                        power_on={a: end - 0.1 for a in absent},
                        faults=(Fault("fail", victim, at),)), on_event=evs.append)
    w.run()
    t0 = next(e["t"] for e in evs if e["ev"] == "fault")
    before = [e for e in evs if t0 - TICK_HZ <= e.get("t", e.get("start", 0)) < t0]
    assert {e["src"] for e in before if e["ev"] == "frame"} == set(ring)
    assert not [e for e in before if e["ev"] in ("miss", "disable", "join", "rejoin", "mode")]
    after = [e for e in evs if e.get("t", 0) >= t0 and e["ev"] in ("miss", "disable")
             and e["by"] != victim]           # the victim, deaf, counts everyone missing
    assert {e["robot"] for e in after} == {victim}
    drops = {e["by"]: e["t"] for e in after if e["ev"] == "disable"}
    assert set(drops) == set(ring) - {victim}
    return min(drops.values()) - t0


def _instants(ring: tuple[int, ...], cfg: MacConfig, runs: int) -> list[float]:
    """``runs`` failure instants spread evenly over one idle cycle, a second after the ring
    formed. At 7 ms apart or less one of them cuts the victim's frame between its Header and
    the end of its Length (9 bytes, 9.4 ms), where the worst case lies."""
    heartbeat = 14 + (CRC_TEXT_LEN if cfg.checksum else 0) + \
        (AUTH_TEXT_LEN if cfg.auth is not None else 0)
    cycle = len(ring) * (cfg.ttrans + heartbeat * B) / TICK_HZ
    return [7.0 + cycle * k / runs for k in range(runs)]


def _dense(ring: tuple[int, ...], cfg: MacConfig) -> list[float]:
    """Failure instants 7 ms apart or less over one idle cycle (see ``_instants``)."""
    heartbeat = 14 + (CRC_TEXT_LEN if cfg.checksum else 0) + \
        (AUTH_TEXT_LEN if cfg.auth is not None else 0)
    cycle = len(ring) * (cfg.ttrans + heartbeat * B)
    return _instants(ring, cfg, -(-cycle // (7 * MS)))


RINGS = {n: tuple(range(1, n + 1)) if n < 7 else tuple(range(7)) for n in range(2, 8)}


@pytest.mark.parametrize("n", sorted(RINGS))
def test_a_silent_robot_is_dropped_within_the_bound_of_section_7_3(n):
    """Issue 43: §7.3 said 3 x ((n - 1) idle turns + Tmax) + one turn, and the simulator took
    longer (2.357 s against 2.113 s in a ring of 6). The worst failure cuts the robot's frame
    after its Header and before its Length: the others close that turn only a stall gap and
    a quiet gap after its last byte (clause 41), the next robot then waits its R-stagger
    (clause 44), and every frame after carries ``ring(mask)`` (clause 51). Here robot n - 1
    (the one before the highest ID, whose stagger is the longest) fails at 20 instants over
    one cycle, children 1..n (0..6 for 7): every drop comes within the corrected bound, and
    the worst within 1 % of it. What the 1 % leaves is the byte the failure cut short (at
    most 1 B) and shorter masks (``ring(6)`` is 2 bytes shorter than the ``ring(127)`` the
    bound counts, 6 ms in a ring of two): a bound 1 % looser counts something the rules never
    add (a Tslot too many is 20 ms, 1 % of a ring of two's)."""
    ring = RINGS[n]
    cfg = MacConfig(team=frozenset(ring))
    victim = ring[-2]
    bound = cfg.silent_drop_ticks(ring)
    took = [_drop_after(ring, victim, at, cfg) for at in _instants(ring, cfg, 20)]
    assert max(took) <= bound, (f"{max(took) / MS:.2f} ms > {bound / MS:.2f} ms")
    assert max(took) >= 0.99 * bound, (f"{max(took) / MS:.2f} ms, bound {bound / MS:.2f} ms")


SLOW_SETS = {**SETS, "checksum": MacConfig(checksum=True),
             "authenticated": MacConfig(auth=RingKey(bytes(range(16)))),
             "checksum, real time": realtime_config(MacConfig(checksum=True))}
SLOW_RINGS = (*RINGS.values(), (5, 6), (0, 6), (2, 4, 6), (0, 1, 6))


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SLOW_SETS))
def test_a_silent_robot_is_dropped_within_the_bound_for_every_set_ring_and_victim(name):
    """The fast test's twin: every shipped margin set in both profiles, and with the checksum
    or the authenticated profile (longer frames); rings of 2..7 and rings whose highest ID is
    not their size; every member as the victim at 6 instants, and the one before the highest
    ID (the worst: its successor staggers longest) at instants 7 ms apart. The worst of each
    ring comes within 1 % of the bound (what is left: the byte the failure cut short, masks
    shorter than ``ring(127)``, a child's bytes where the bound counts a PC's)."""
    for ring in SLOW_RINGS:
        cfg = replace(SLOW_SETS[name], team=frozenset(ring))
        bound = cfg.silent_drop_ticks(ring)
        took = [_drop_after(ring, v, at, cfg) for v in ring for at in _instants(ring, cfg, 6)]
        took += [_drop_after(ring, ring[-2], at, cfg) for at in _dense(ring, cfg)]
        assert 0.99 * bound <= max(took) <= bound, (name, ring, max(took) / MS, bound / MS)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["exact", "real time"])
def test_a_silent_robot_in_a_team_with_absent_ids_is_dropped_within_the_bound(name):
    """Team IDs outside the ring: members with such IDs in their gap invite one of them every
    4 of their turns (clause 32), a `poll` 2 bytes longer than `ring(mask)` and a window of
    Twin (clause 33); without that term the ring {1, 3, 5} in a team of 7 took 2.084 s against
    2.078 s (exact set). Whether an invitation falls between the misses depends on the
    failure instant, so the worst comes within 10 % of the bound, not 1 %."""
    team = tuple(range(7))
    for ring in ((1, 2), (1, 3, 5), (1, 2, 3, 4, 5)):
        cfg = replace(SETS[name], team=frozenset(team))
        absent = tuple(i for i in team if i not in ring)
        bound = cfg.silent_drop_ticks(ring)
        assert bound > replace(cfg, team=frozenset(ring)).silent_drop_ticks(ring)
        worst = max(_drop_after(ring, v, at, cfg, absent) for v in ring
                    for at in _dense(ring, cfg))
        assert 0.9 * bound <= worst <= bound, (name, ring, worst / MS, bound / MS)


def _section_7_3_table() -> dict[int, list[str]]:
    text = DOC.read_text(encoding="utf-8")
    text = text[text.index("### 7.3 A silent robot"):text.index("### 7.4 ")]
    return {int(m.group(1)): [c.strip() for c in m.group(2).split("|")]
            for m in re.finditer(r"^\| (\d) \|(.*)\|$", text, flags=re.M)}


def test_section_7_3s_figures_are_the_codes_bound():
    """§7.3's table is ``MacConfig.silent_drop_ticks`` for a ring of n holding robot 6, in the
    exact set, the real-time set and the paper profile."""
    table = _section_7_3_table()
    assert sorted(table) == list(range(2, 8))
    for n, cells in table.items():
        ring = tuple(range(7 - n, 7))
        sets = (SETS["exact"], SETS["real time"], SETS["paper, exact"])
        want = [f"{replace(c, team=frozenset(ring)).silent_drop_ticks(ring) / TICK_HZ:.3f} s"
                for c in sets]
        assert cells == want, n

"""The MAC's transition table (firmware_model/radio/mac_table.py) against the MAC itself.

Every transition the MAC makes in a set of simulated runs (a loaded ring, collisions, bursts,
deaths and recoveries, byte errors with idle noise, father failover, staggered power-on,
twins), and in a few rare paths driven on one MAC (``_rare_paths``), must be a row of the
table, and every row must be taken at least once: the table is neither wrong nor padded.
docs/mac.md must hold the diagram and table generated from it."""
from __future__ import annotations

import json
from collections import Counter

import pytest

from firmware_model.radio import mac as M
from firmware_model.radio.frame import Frame
from firmware_model.radio.integrity import seal
from firmware_model.radio.mac_table import EVENTS, STATES, TRANSITIONS, docs_section
from firmware_model.timing import CHILD_BYTE_TICKS as B
from hil.sim.faults import parse_fault
from hil.sim.world import SimConfig, World
from paths import ROOT

RUNS = [
    dict(robots=(0, 1, 2, 3, 4, 5, 6), duration=30, seed=1, load=2.0),
    dict(robots=(0, 1, 2, 3), duration=30, seed=2, load=1.0, faults=tuple(map(parse_fault, [
        "steal:2@3", "burst@6:0.3", "fail:1@8", "recover:1@12", "fail:3@14.0005"]))),
    dict(robots=(1, 2, 3, 4), duration=20, seed=3, ber=0.002, noise=True, load=1.0),
    dict(robots=(0, 1, 2), duration=20, seed=2, father_standby=True, load=1.0,
         faults=(parse_fault("fail:0@6"), parse_fault("recover:0@10"))),
    dict(robots=(1, 2, 3, 4, 5), duration=20, seed=6, power_on={3: 1.5, 1: 0.7}, ber=0.001),
    # twins of R2 powered on together: they answer together until a seeded draw parts them
    dict(robots=(1, 2, 3), duration=20, seed=1, extra=((2, 0.0, None),)),
    # the paper profile: the static ring of the whole team, robot 4 never on and 2 dying
    dict(robots=(1, 2, 3), duration=20, seed=4, load=1.0, ber=0.001,
         mac=M.MacConfig(profile="paper", team=frozenset({1, 2, 3, 4})),
         faults=(parse_fault("fail:2@6"), parse_fault("recover:2@11"))),
]


def _answer(me: int, team: set[int], poller: int, mask: int, **kw) -> tuple[M.RotationalMac, int]:
    """Robot ``me`` powers on, answers ``poller``'s invitation and sends its answer: the MAC
    (in WAIT or WINDOW) and the tick its frame ended."""
    cfg = M.MacConfig(team=frozenset(team), **kw)
    mac = M.RotationalMac(me, cfg)
    mac.power_on(0)
    poll = f"poll({me},{mask})".encode()
    t = 1000 * B
    mac.on_frame(seal(7, poller, 0, 3, poll) if cfg.checksum else Frame(7, poller, 0, 3, poll),
                 t - 20 * B, t, t)
    mac.on_timer(mac.deadline)                 # SWITCH: Ttrans after TXEN, the frame goes out
    t = mac.turn_start + cfg.ttrans + 15 * B
    mac.on_tx_done(t)
    return mac, t


def _rare_paths() -> None:
    """Paths the runs above seldom or never take, each driven on one MAC: the claim wait
    restarted by a failed frame and held off by a frame in progress (clause 28); a BOOT no
    member acknowledges, given up after the announcement limit (clause 36); a bad checksum in
    the slot before ours (clauses 43, 44) and while we hold (clause 43); frames that fail in
    an invitation's window and while a broken frame is being waited out (clause 41); a poll
    and a mask without us heard then (clauses 33, 37), and a poll while we hold."""
    mac = M.RotationalMac(1, M.MacConfig(team=frozenset({1, 2})))
    mac.power_on(0)
    mac.on_corrupt(100 * B, 2, 120 * B, 120 * B)
    mac.on_timer(mac.deadline, rx_busy=True)

    mac, t = _answer(1, {1, 2, 3}, 2, 0b1100)
    for _ in range(100):                       # 2 and 3 never acknowledge our BOOT
        if mac.mode != M.MEMBER:
            break
        if mac.phase == M.WAIT:
            t += 60 * B
            mac.on_frame(Frame(7, mac.owner, 0, 3, b""), t - 14 * B, t, t)
        else:
            mac.on_timer(mac.deadline)
            t = mac.turn_start + mac.cfg.ttrans + 15 * B
            mac.on_tx_done(t)
    assert mac.frames_sent == 2 * M.MISS_LIMIT

    mac, t = _answer(3, {1, 2, 3}, 2, 0b0110, checksum=True)
    t += 50 * B
    mac.on_frame(seal(7, 1, 0, 3, b""), t - 14 * B, t, t)            # robot 2's turn next
    t += 50 * B
    mac.on_frame(Frame(7, 2, 0, 3, b"crc(00000)"), t - 14 * B, t, t)  # its frame, bad crc
    assert mac.phase == M.HOLD
    mac.on_frame(Frame(7, 1, 0, 3, b"crc(00000)"), t, t + 14 * B, t + 14 * B)

    for me, poller, mask, length in ((1, 2, 0b0100, None), (1, 2, 0b0100, 20), (2, 1, 0b0010, 20)):
        mac, t = _answer(me, {1, 2, 3}, poller, mask)     # ring {1, 2}; the other polls 3
        t += 50 * B
        mac.on_frame(_hb(poller, t, b"poll(3,6)"), t - 23 * B, t, t)
        assert mac.phase == M.WINDOW
        end = None if length is None else t + length * B
        mac.on_corrupt(t + 5 * B, None, end, t + 8 * B)   # QUIET; HOLD (succ(3) is 1); WAIT

    # a frame breaks in o's slot before its Length (QUIET), then: a failed frame with its
    # Length, in the slot before ours or not; a bad checksum before ours; a poll; a poll
    # mask that lacks us
    for me, team, poller, mask, then in (
            (1, {1, 2, 3}, 2, 0b0100, "failed"), (1, {1, 2, 3, 4}, 2, 0b1100, "failed"),
            (1, {1, 2, 3}, 2, 0b0100, "bad crc"), (1, {1, 2, 3, 4}, 2, 0b1100, "poll(4,14)"),
            (1, {1, 2, 3, 4}, 2, 0b1100, "poll(4,12)")):
        mac, t = _answer(me, team, poller, mask, checksum=then == "bad crc")
        t += 50 * B
        mac.on_corrupt(t - 10 * B, None, None, t)
        assert mac.phase == M.QUIET
        if then == "failed":
            mac.on_corrupt(t + 5 * B, None, t + 20 * B, t + 8 * B)
        elif then == "bad crc":
            mac.on_frame(Frame(7, mac.owner, 0, 3, b"crc(00000)"), t, t + 14 * B, t + 14 * B)
        else:
            mac.on_frame(_hb(2, t, then.encode()), t, t + 24 * B, t + 24 * B)

    # a frame that polls while we hold after an uncertain closure
    mac, t = _answer(3, {1, 2, 3, 4}, 2, 0b0110, checksum=True)
    t += 50 * B
    mac.on_frame(seal(7, 1, 0, 3, b""), t - 14 * B, t, t)
    t += 50 * B
    mac.on_frame(Frame(7, 2, 0, 3, b"crc(00000)"), t - 14 * B, t, t)
    assert mac.phase == M.HOLD
    mac.on_frame(seal(7, 1, 0, 3, b"poll(4,14)"), t + 3 * B, t + 33 * B, t + 33 * B)


def _sent(mac: M.RotationalMac) -> int:
    """From SWITCH: the frame goes out; the tick its End left."""
    mac.on_timer(mac.deadline)
    t = mac.turn_start + mac.cfg.ttrans + 20 * B
    mac.on_tx_done(t)
    return t


def _window_paths() -> None:
    """Frames that end an invitation's window otherwise than clause 35 says: another robot's
    frame in a lone member's window (clause 31), a twin's second frame (clause 38), and a
    takeover by the poller's successor late enough (clause 39) that polls (clause 33) or
    whose mask lacks us (clause 37); and the cut-off (clause 40) reached on noise in QUIET."""
    mac = M.RotationalMac(2, M.MacConfig(team=frozenset({1, 2, 3})))
    mac.power_on(0)
    mac.on_timer(mac.deadline)                           # the claim
    _sent(mac)                                           # BOOT, no poll: HOLD
    mac.on_timer(mac.deadline)
    t = _sent(mac)                                       # poll(3,4): WINDOW
    assert mac.phase == M.WINDOW
    mac.on_frame(_hb(1, 0), t - 4 * B, t + 10 * B, t + 10 * B)
    assert mac.mode == M.LISTEN

    mac, t = _answer(1, {1, 2, 3}, 2, 0b0100)            # ring {1, 2}
    mac.on_frame(_hb(1, 0), t + 26 * B, t + 40 * B, t + 40 * B)   # our ID: refused
    t += 80 * B
    mac.on_frame(_hb(2, 0, b"poll(3,6)"), t - 23 * B, t, t)      # WINDOW
    mac.on_frame(_hb(1, 0), t + 26 * B, t + 40 * B, t + 40 * B)   # our ID again: a twin
    assert mac.mode == M.LISTEN

    for mask, phase in ((0b1110, M.WINDOW), (0b1100, None)):
        mac, t = _answer(1, {1, 2, 3, 4, 5}, 2, 0b1100)  # ring {1, 2, 3}
        t += 40 * B
        mac.on_frame(_hb(2, 0, b"poll(4,14)"), t - 24 * B, t, t)  # the window of 4
        poll = f"poll(5,{mask})".encode()
        mac.on_frame(_hb(3, 0, poll), t + 20 * B, t + 44 * B, t + 44 * B)
        assert (mac.phase if mac.mode == M.MEMBER else None) == phase

    mac, t = _answer(1, {1, 2, 3, 4}, 2, 0b1100)         # ring {1, 2, 3}: 3 misses cut off
    for _ in range(20):
        if mac.mode != M.MEMBER:
            break
        if mac.phase == M.WAIT:                          # noise in the owner's slot, no frame
            g = mac.turn_start + mac.cfg.ttrans + 5 * B
            mac.on_garbage(g - B, g, g)
            limit = mac.turn_start + mac.cfg.tmax
            mac.on_timer(limit, False, limit - B)
        elif mac.phase == M.SEND:
            mac.on_tx_done(mac.turn_start + mac.cfg.ttrans + 20 * B)
        else:
            mac.on_timer(mac.deadline)
    assert mac.mode == M.LISTEN


def _steal_paths() -> None:
    """Fault injection (``force_turn``, the ``steal`` fault) in every state: a member waiting
    for a turn (WAIT, WINDOW, HOLD) takes it at once; in the others there is none to take.
    And what a radio hears while ours switches or sends (a bench port is not deaf) changes
    nothing."""
    def deaf(mac: M.RotationalMac, state: str, t: int) -> None:
        mac.on_frame(_hb(2, t), t - 14 * B, t, t)
        mac.on_garbage(t + B, t + 2 * B, t + 2 * B)
        mac.on_corrupt(t + 3 * B, 2, t + 20 * B, t + 5 * B)
        assert _state(mac) == state

    def steal(mac: M.RotationalMac, state: str, now: int) -> None:
        assert _state(mac) == state
        mac.force_turn(now)
        assert _state(mac) == (state if state in ("LISTEN", "SWITCH", "SEND", "QUIET", "WATCH")
                               else "SWITCH")

    mac = M.RotationalMac(1, M.MacConfig(team=frozenset({1, 2})))
    mac.power_on(0)
    steal(mac, "LISTEN", 10 * B)
    mac.on_timer(mac.deadline)                           # the claim: SWITCH
    steal(mac, "SWITCH", mac.deadline - B)
    deaf(mac, "SWITCH", mac.deadline - 4 * B)
    mac.on_timer(mac.deadline)                           # on air: SEND
    steal(mac, "SEND", mac.turn_start + mac.cfg.ttrans + 5 * B)
    deaf(mac, "SEND", mac.turn_start + mac.cfg.ttrans + 6 * B)

    mac, t = _answer(1, {1, 2}, 2, 0b0100)               # waits for 2
    steal(mac, "WAIT", t + 10 * B)
    mac, t = _answer(1, {1, 2, 3}, 2, 0b0100)
    mac.on_frame(_hb(2, t, b"poll(3,6)"), t + 27 * B, t + 50 * B, t + 50 * B)
    steal(mac, "WINDOW", t + 60 * B)
    mac, t = _answer(1, {1, 2}, 2, 0b0100)
    mac.on_corrupt(t + 10 * B, None, None, t + 12 * B)   # broke before its Length
    steal(mac, "QUIET", t + 14 * B)
    mac.on_timer(mac.deadline)                           # quiet: our turn, R-stagger
    steal(mac, "HOLD", mac.deadline - B)

    mac = M.RotationalMac(0, M.MacConfig(team=frozenset({0, 1}), paired=True, pc=2,
                                         standby=True))
    mac.power_on(0)
    mac.on_timer(mac.deadline)                           # a standby claims: watches first
    steal(mac, "WATCH", mac.deadline - B)


def _id0_failed_paths() -> None:
    """ID 0's R-stagger is 0: on a channel with idle noise (no hold for the channel to fall
    quiet), a frame that failed after its Length in the slot before its turn leaves it nothing
    to wait: its turn at once, from WAIT, an invitation's WINDOW and QUIET (clauses 41, 44)."""
    for state in ("WAIT", "WINDOW", "QUIET"):
        mac, t = _answer(0, {0, 1, 2}, 1, 0b0010, quiet_channel=False)   # ring {0, 1}
        if state == "WINDOW":
            mac.on_frame(_hb(1, t, b"poll(2,3)"), t + 27 * B, t + 50 * B, t + 50 * B)
            t += 50 * B
        elif state == "QUIET":
            mac.on_corrupt(t + 10 * B, None, None, t + 12 * B)
            t += 12 * B
        assert _state(mac) == state
        end = t + 40 * B                                     # its promised end, now past
        mac.on_corrupt(t + 10 * B, 1 if state == "WAIT" else None, end, end + 3 * B)
        assert _state(mac) == "SWITCH", state


def _hb(src: int, t: int, content: bytes = b"") -> Frame:
    return Frame(7, src, 0, 3, content)


def _father_paths() -> None:
    """The father's PCs (clause 50), driven on one MAC: a standby that hears the active PC's
    invitation from LISTEN, that claims (and watches first), that hears garbage and failed
    frames while it watches, that follows the active PC's poll from WATCH, that watches after
    a miss or an unanswered window; PC2 answering its second invitation on a check turn; PC1
    on probation refusing the other PC's frame while it watches (the slot closes)."""
    def pc2(standby: bool = True) -> M.RotationalMac:
        cfg = M.MacConfig(team=frozenset({0, 1, 2, 3}), paired=True, pc=2, standby=standby)
        mac = M.RotationalMac(0, cfg)
        mac.power_on(0)
        return mac

    def heard(mac: M.RotationalMac, src: int, t: int, content: bytes = b"") -> None:
        mac.on_frame(_hb(src, t, content), t - (14 + len(content)) * B, t, t)

    mac = pc2()
    heard(mac, 0, 100 * B, b"poll(3,7)")                 # LISTEN -> WINDOW
    mac = pc2()
    mac.on_timer(mac.deadline)                           # LISTEN -> WATCH
    mac.on_garbage(mac.deadline - 10 * B, mac.deadline - 5 * B, mac.deadline - 5 * B)

    def follower() -> tuple[M.RotationalMac, int]:       # a standby in a ring {0, 1}
        mac = pc2()
        heard(mac, 1, 100 * B)
        heard(mac, 0, 140 * B)                           # LISTEN -> WAIT for robot 1
        return mac, 140 * B

    mac, t = follower()
    mac.force_turn(t + 10 * B)                           # the steal fault: WAIT -> WATCH
    assert mac.phase == M.WATCH
    mac = M.RotationalMac(0, M.MacConfig(team=frozenset({0, 1, 2, 3}), paired=True, pc=2,
                                         standby=True, quiet_channel=False))
    mac.power_on(0)                                      # idle noise: no hold for quiet
    heard(mac, 1, 100 * B)
    heard(mac, 0, 140 * B)                               # a standby following 0 -> 1
    mac.on_corrupt(150 * B, None, None, 152 * B)         # 1's frame breaks: WAIT -> QUIET
    mac.on_timer(mac.deadline)                           # quiet: ID 0's turn, watched first
    assert mac.phase == M.WATCH
    mac, t = follower()
    mac.on_timer(mac.deadline)                           # 1 missed: WAIT -> WATCH
    mac.on_corrupt(mac.turn_start + 8 * B, None, None, mac.turn_start + 10 * B)   # QUIET
    mac, t = follower()
    heard(mac, 1, t + 40 * B)                            # WAIT -> WATCH
    mac.on_corrupt(t + 45 * B, None, t + 60 * B, t + 48 * B)                      # WAIT
    mac, t = follower()
    heard(mac, 1, t + 40 * B)
    heard(mac, 0, t + 70 * B, b"poll(3,3)")              # WATCH -> WINDOW
    mac, t = follower()
    heard(mac, 1, t + 40 * B, b"poll(3,3)")              # WAIT -> WINDOW
    mac.on_timer(mac.deadline)                           # no answer: WINDOW -> WATCH
    mac = pc2(standby=False)
    for i in range(2):                                   # the first invitation passes
        heard(mac, 1, (100 + 100 * i) * B, b"poll(0,2)")  # LISTEN -> WATCH
    assert mac.phase == M.WATCH

    # PC1, which heard the other PC after a miss: on probation it watches its turns, and
    # refuses the other PC's frame heard then (clause 50)
    mac = M.RotationalMac(0, M.MacConfig(team=frozenset({0, 1, 2}), paired=True, pc=1))
    mac.power_on(0)
    heard(mac, 1, 100 * B, b"poll(0,2)")                 # invited: ring {0, 1}
    _sent(mac)
    mac.on_timer(mac.deadline)                           # robot 1 missed: our turn, R-stagger
    heard(mac, 0, mac.turn_start + 40 * B)               # the other PC: probation; WAIT for 1
    heard(mac, 1, mac.turn_start + 80 * B)               # our turn, watched
    assert mac.phase == M.WATCH
    heard(mac, 0, mac.turn_start + 30 * B)               # refused, closes the slot: -> WAIT
    assert (mac.phase, mac.owner) == (M.WAIT, 1) and not mac.standby


HOOKS = {"on_frame": "frame", "on_corrupt": "failed frame", "on_garbage": "garbage",
         "on_timer": "deadline", "on_tx_done": "tx done", "power_on": "power on",
         "force_turn": "steal"}


def _state(mac) -> str:
    return "LISTEN" if mac.mode == M.LISTEN else mac.phase.upper()


@pytest.fixture(scope="module")
def observed():
    seen: Counter = Counter()
    mp = pytest.MonkeyPatch()

    def hook(name, event):
        orig = getattr(M.RotationalMac, name)

        def recorded(self, *a, **k):
            before = _state(self)
            out = orig(self, *a, **k)
            seen[(before, event, _state(self))] += 1
            return out
        mp.setattr(M.RotationalMac, name, recorded)
    for name, event in HOOKS.items():
        hook(name, event)
    try:
        for kw in RUNS:
            World(SimConfig(**kw)).run()
        _rare_paths()
        _father_paths()
        _window_paths()
        _steal_paths()
        _id0_failed_paths()
    finally:
        mp.undo()
    return seen


def test_every_transition_the_mac_makes_is_in_the_table(observed):
    rows = {(t.state, t.event, t.next) for t in TRANSITIONS}
    missing = sorted(set(observed) - rows)
    assert not missing, f"transitions the table does not list: {missing}"


def test_every_row_of_the_table_is_taken(observed):
    unused = [t for t in TRANSITIONS if (t.state, t.event, t.next) not in observed]
    assert not unused, f"rows no run takes (wrong, or a run is missing): {unused}"


def test_the_table_names_only_known_states_and_events():
    assert {t.state for t in TRANSITIONS} | {t.next for t in TRANSITIONS} <= set(STATES)
    assert {t.event for t in TRANSITIONS} <= set(EVENTS)
    assert set(M.DEADLINE_HANDLERS) | {M.SEND} == {s.lower() for s in STATES} - {"listen"}


def test_the_phases_are_an_enum_whose_members_are_the_old_strings():
    """``mac_phases.Phase``: one member per MEMBER state of the table, each equal to the string
    it was before (same hash, same text in an f-string or JSON), so traces and tables keep it."""
    assert {p.value for p in M.Phase} == {s.lower() for s in STATES} - {"listen"}
    for p in M.Phase:
        assert p == p.value and hash(p) == hash(p.value) and {p.value: 1}[p] == 1
        assert str(p) == f"{p}" == p.value and json.dumps(p) == f'"{p.value}"'
    mac = M.RotationalMac(1)
    mac.power_on(0)
    assert isinstance(mac.phase, M.Phase)

def test_docs_hold_the_generated_diagram_and_table():
    text = (ROOT / "docs" / "mac.md").read_text()
    begin, end = "<!-- mac-table:begin -->\n", "<!-- mac-table:end -->"
    assert begin in text and end in text, "docs/mac.md lacks the mac-table markers"
    held = text.split(begin, 1)[1].split(end, 1)[0]
    assert held == docs_section(), \
        "docs/mac.md is stale: python -m firmware_model.radio.mac_table prints the section"

"""The MAC's transition table (firmware_model/radio/mac_table.py) against the MAC itself.

Every transition the MAC makes in a set of simulated runs (a loaded ring, collisions, bursts,
deaths and recoveries, byte errors with idle noise, father failover, staggered power-on,
twins), and in a few rare paths driven on one MAC (``_rare_paths``), must be a row of the
table, and every row must be taken at least once: the table is neither wrong nor padded.
docs/mac.md must hold the diagram and table generated from it."""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from firmware_model.radio import mac as M
from firmware_model.radio.frame import Frame
from firmware_model.radio.integrity import seal
from firmware_model.radio.mac_table import EVENTS, STATES, TRANSITIONS, docs_section
from firmware_model.timing import CHILD_BYTE_TICKS as B
from hil.sim.faults import parse_fault
from hil.sim.world import SimConfig, World

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
    the slot before ours (clauses 43, 44) and while we hold (clause 43); a frame that fails
    in an invitation's window (clause 41)."""
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

    mac, t = _answer(1, {1, 2, 3}, 2, 0b0100)  # ring {1, 2}
    t += 50 * B
    mac.on_frame(Frame(7, 2, 0, 3, b"poll(3,6)"), t - 23 * B, t, t)
    assert mac.phase == M.WINDOW
    mac.on_corrupt(t + 5 * B, None, None, t + 8 * B)


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


def test_docs_hold_the_generated_diagram_and_table():
    text = (Path(__file__).resolve().parent.parent / "docs" / "mac.md").read_text()
    begin, end = "<!-- mac-table:begin -->\n", "<!-- mac-table:end -->"
    assert begin in text and end in text, "docs/mac.md lacks the mac-table markers"
    held = text.split(begin, 1)[1].split(end, 1)[0]
    assert held == docs_section(), \
        "docs/mac.md is stale: python -m firmware_model.radio.mac_table prints the section"

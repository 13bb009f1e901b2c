"""The MAC's transition table (firmware_model/radio/mac_table.py) against the MAC itself.

Every transition the MAC makes in a set of simulated runs (a loaded ring, collisions, bursts,
deaths and recoveries, byte errors with idle noise, father failover, staggered power-on,
twins) must be a row of the table, and every row must be taken at least once: the table is
neither wrong nor padded. docs/mac.md must hold the diagram and table generated from it."""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from firmware_model.radio import mac as M
from firmware_model.radio.mac_table import EVENTS, STATES, TRANSITIONS, docs_section
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

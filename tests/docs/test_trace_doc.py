"""docs/trace.md against the simulator: seeded short runs with faults of every kind, load, byte
errors, CAN, the CPU model, the action sequence, the paper profile and a peer MAC write every
kind of trace event; each kind and each key written must be in the document's table, in the
order written, and each kind and key the table lists must be written by some run. So the
table cannot drift from hil/sim/world.py."""
from __future__ import annotations

import re
from dataclasses import replace

import pytest

from firmware_model.cycle_costs import DEFAULT_COSTS, Cost
from firmware_model.radio.mac import MacConfig
from hil.sim.events import KINDS as EVENT_KINDS, from_record, meta_from_record
from hil.sim.faults import KINDS, parse_fault
from hil.sim.world import SimConfig, World
from paths import ROOT

DOC = ROOT / "docs" / "trace.md"


def faults(*specs: str):
    return tuple(parse_fault(s) for s in specs)


RUNS = {
    # byte errors and load: bad_frame, bad_content, duplicate, fail; the air's faults, the
    # standby PC (pc), a robot's own radio failing (miss, disable) and coming back (rejoin)
    "air": SimConfig(robots=(0, 1, 2, 3), duration=8.0, seed=1, ber=0.01, load=5.0,
                     father_standby=True,
                     faults=faults("fail:2@2.5", "recover:2@6", "steal:1@2", "foreign@2.5:30",
                                   "burst@3:0.05", "noise@3.5-4", "drop@4-4.5:0.01",
                                   "ber@5-5.5:0.02", "skew:3:0.01")),
    "rejoin": SimConfig(robots=(1, 2, 3), duration=7.0, seed=1,
                        faults=faults("fail:2@2.5", "recover:2@6")),
    # the CAN side, its faults and the CPU model: can, dispatch, cpu
    "can": SimConfig(robots=(1, 2), duration=3.0, seed=1, can=True, load=1.0,
                     cpu=DEFAULT_COSTS,
                     faults=faults("busoff:1@1", "stuck:2@1-1.2", "silent:1.JOINT2@1-2",
                                   "stall:1.JOINT1@1-2", "noisy:2.MCU@1.5-2")),
    "sequence": SimConfig(robots=(1, 2), duration=3.0, seed=1, can=True, sequence=((1, 2), 1)),
    # a transmit handler slower than a byte time: frames go out in pieces (paused, continued)
    "paused": SimConfig(robots=(0, 1, 2), duration=3.0, seed=1, load=1.0,
                        cpu=replace(DEFAULT_COSTS, uart_tx_byte=Cost(20_000, "test", "test"))),
    "paper": SimConfig(robots=(1, 2, 3), duration=3.0, seed=1, load=2.0,
                       mac=MacConfig(profile="paper")),
    "aloha": SimConfig(robots=(1, 2, 3), duration=3.0, seed=1, load=2.0, mac_kind="aloha"),
    # robots outside the ring (extra): twins of R2 at power-on and of R3 later (duplicate_id),
    # a robot of another team that hears the ring, and a ring that hears another team's
    # lone claimer (foreign_ring)
    "identity": SimConfig(robots=(1, 2, 3), duration=8.0, seed=1, load=1.0,
                          extra=((2, 0.0, None), (5, 1.0, (5, 6)), (3, 5.0, None))),
    "foreign": SimConfig(robots=(2, 3), duration=3.0, seed=1, extra=((6, 0.0, (6,)),)),
    # a father order with an older Number (02, after 03) sent in the dead father's slot, 20 ms
    # after robot 2's frame: behind (clause 48a)
    "behind": SimConfig(robots=(0, 1, 2), duration=4.0, seed=1, load=1.0,
                        faults=faults("fail:0@3", "foreign@3.04146675:x0f0a05" +
                                      b"100220008status()".hex() + "1719")),
}


@pytest.fixture(scope="module")
def events() -> list[dict]:
    """Every event of every run."""
    evs: list[dict] = []
    for cfg in RUNS.values():
        World(cfg, on_event=evs.append).run()
    return evs


@pytest.fixture(scope="module")
def written(events) -> dict[str, list[tuple[str, ...]]]:
    """{event kind: every distinct key tuple written (without t and ev)}, over all runs."""
    out: dict[str, list[tuple[str, ...]]] = {}
    for e in events:
        keys = tuple(k for k in e if k not in ("t", "ev"))
        seen = out.setdefault(e["ev"], [])
        if keys not in seen:
            seen.append(keys)
    return out


def table() -> dict[str, list[str]]:
    """{event kind: its keys in the table's order} from docs/trace.md's Events table."""
    out = {}
    for line in DOC.read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 3 or not cells[0].startswith("`"):
            continue
        keys = re.findall(r"`([a-z_]+)`", cells[1])
        for kind in re.findall(r"`([a-z_]+)`", cells[0]):
            out[kind] = keys
    return out


def test_every_event_kind_written_is_in_the_table_and_no_other(written):
    kinds = set(written) - {"meta"}
    assert kinds == set(table()), (sorted(kinds - set(table())), sorted(set(table()) - kinds))


def test_every_key_written_is_in_the_table_in_its_order(written):
    """``pc`` (the standby PC's events) and ``extra`` (an extra robot's) may end any event
    whose row does not list it: the text under the table says so."""
    doc = table()
    for kind, key_sets in written.items():
        if kind == "meta":
            continue
        for tag in ("pc", "extra"):
            if tag not in doc[kind]:
                key_sets = [ks[:-1] if ks and ks[-1] == tag else ks for ks in key_sets]
        for keys in key_sets:
            assert set(keys) <= set(doc[kind]), (kind, keys, doc[kind])
            assert list(keys) == [k for k in doc[kind] if k in keys], (kind, keys, doc[kind])
        assert {k for ks in key_sets for k in ks} == set(doc[kind]), (kind, key_sets)


def test_the_meta_example_has_the_keys_written(written):
    text = DOC.read_text(encoding="utf-8")
    example = re.search(r"```json\n(.*?)```", text, flags=re.S)[1]
    keys = re.findall(r'"([a-z_]+)":', example)
    keys = [k for k in keys if not k.isdigit()]
    optional = {"can_bitrate"}                      # with --can, said under the table
    for meta in written["meta"]:
        assert [k for k in keys if k != "ev"] == [k for k in meta if k not in optional]
    assert any("can_bitrate" in m for m in written["meta"]) and "`can_bitrate`" in text


def test_the_fault_row_names_every_kind_and_every_kind_but_skew_has_events(events):
    row = next(line for line in DOC.read_text(encoding="utf-8").splitlines()
               if line.startswith("| `fault` |"))
    assert set(KINDS) <= set(re.findall(r"`([a-z]+)`", row))   # skew: said to have none
    faults = [e for e in events if e["ev"] == "fault"]
    assert {e["kind"] for e in faults} == set(KINDS) - {"skew"}
    air = {"ber", "noise", "burst", "foreign", "drop"}
    assert all((e["robot"] is None) == (e["kind"] in air) for e in faults)
    assert all(("spec" in e) == (e["phase"] == "start" and
                                 e["kind"] not in ("fail", "recover", "steal")) for e in faults)


def test_the_standby_pcs_events_carry_pc_2_and_the_text_says_so(events):
    tagged = [e for e in events if "pc" in e]
    assert tagged and all(e["pc"] == 2 for e in tagged)
    assert {"frame", "txen", "mode"} <= {e["ev"] for e in tagged}
    assert 'carry `"pc": 2`' in DOC.read_text(encoding="utf-8")


def test_an_extra_robots_events_carry_extra_and_the_text_says_so(events):
    tagged = [e for e in events if "extra" in e]
    assert {"power", "frame", "mode", "duplicate_id", "foreign_ring"} <= {e["ev"] for e in tagged}
    assert all(e["extra"] >= 1 for e in tagged)
    assert 'carry `"extra": k`' in DOC.read_text(encoding="utf-8")


def test_each_kind_in_the_table_has_its_typed_event_with_those_fields():
    """hil/sim/events.py declares one class a kind, its fields those of the table's row in
    the same order (``pc`` and ``extra`` where the row does not list them: tags)."""
    doc = table()
    assert set(EVENT_KINDS) - {"meta"} == set(doc), sorted(set(EVENT_KINDS) ^ set(doc))
    for kind, cls in EVENT_KINDS.items():
        if kind == "meta":
            continue
        declared = [name for name, _tag in cls._KEYS
                    if name in doc[kind] or name not in ("pc", "extra")]
        assert declared == doc[kind], (kind, declared, doc[kind])


def test_every_record_written_reads_back_as_the_event_that_wrote_it():
    """The typed events of every run: each record read back (from_record, every field's type
    checked) is the same event, and the meta's too."""
    for cfg in RUNS.values():
        evs: list = []
        w = World(cfg, listeners=[evs.append])
        w.run()
        meta, rest = evs[0], evs[1:]
        assert meta_from_record(meta.record()) == meta == w.meta
        assert rest and all(from_record(e.record(), n) == e for n, e in enumerate(rest, 2))

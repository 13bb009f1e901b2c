"""A foreign transmitter: the ``foreign`` fault of hil/sim/faults.py, its grammar and the simulator
(the radio hub and ``rprs inject``: tests/hil/bench/test_radio_hub.py; the air:
tests/hil/sim/test_air.py)."""
from __future__ import annotations

import pytest

from firmware_model.mcu.scheduler import Scheduler
from firmware_model.timing import s_to_ticks
from hil.sim.air import FOREIGN_BYTE_TICKS
from hil.sim.faults import (
    FOREIGN_MAX, Fault, FaultError, foreign_bytes, parse_fault, schedule,
)
from hil.sim.world import SimConfig, World

HEX = "0f0a0530313233343536373839ff00"


# -- the grammar -------------------------------------------------------------------------------

@pytest.mark.parametrize("text, spec, data, count", [
    ("foreign@1.5:x0F0a05", "foreign@1.5:x0f0a05", b"\x0f\x0a\x05", None),
    ("foreign@2.000:14", "foreign@2:14", None, 14),
    ("foreign@0:x00", "foreign@0:x00", b"\x00", None),
    (f"foreign@3:{FOREIGN_MAX}", f"foreign@3:{FOREIGN_MAX}", None, FOREIGN_MAX),
    ("foreign@1.0000000625:3", "foreign@1.0000000625:3", None, 3),   # one tick past 1 s
])
def test_foreign_spec_parses_and_round_trips(text, spec, data, count):
    f = parse_fault(text)
    assert (f.kind, f.robot, f.until, f.data) == ("foreign", None, None, data)
    assert f.value == count
    assert f.spec() == spec
    assert parse_fault(f.spec()) == f


@pytest.mark.parametrize("seconds, tick", [(1.5, 24_000_000), (1.0000000625, 16_000_001),
                                           (0.0000000625, 1), (7.0137, 112_219_200)])
def test_foreign_time_maps_to_one_exact_tick_through_its_spec(seconds, tick):
    f = parse_fault(Fault("foreign", None, seconds, None, 4.0).spec())
    s = Scheduler()
    fired = []
    schedule(s, f, lambda f: fired.append(s.now))
    s.run_until(tick + 100)
    assert fired == [tick] == [s_to_ticks(seconds)]


@pytest.mark.parametrize("text, needle", [
    ("foreign@1", "byte count or the bytes"),
    ("foreign@1:0", "whole number of bytes"),
    ("foreign@1:2.5", "whole number of bytes"),
    (f"foreign@1:{FOREIGN_MAX + 1}", "whole number of bytes"),
    ("foreign@1:x", "pairs of hex digits"),
    ("foreign@1:x0", "pairs of hex digits"),
    ("foreign@1:xzz", "pairs of hex digits"),
    ("foreign@1:x0f:3", "pairs of hex digits"),
    (f"foreign@1:x{'00' * (FOREIGN_MAX + 1)}", "at most"),
    ("foreign:1@2:3", "acts on the air"),
    ("foreign@1-2:3", "one instant"),
    ("foreign:x0f", "needs a time"),
    ("burst@1:x0f", "takes no bytes"),
    ("noise@1-2:x0f", "takes no bytes"),
])
def test_bad_foreign_specs_are_one_line_errors(text, needle):
    with pytest.raises(FaultError, match=needle) as e:
        parse_fault(text)
    assert "\n" not in str(e.value)


def test_random_foreign_bytes_come_from_a_stream_of_the_seed_and_spec():
    f = parse_fault("foreign@2:40")
    a = foreign_bytes(f, 3)
    assert len(a) == 40 and a == foreign_bytes(parse_fault("foreign@2.0:40"), 3)
    assert a != foreign_bytes(f, 4)
    assert a != foreign_bytes(parse_fault("foreign@2.5:40"), 3)[:40]
    assert foreign_bytes(parse_fault(f"foreign@2:x{HEX}"), 3) == bytes.fromhex(HEX)


# -- the simulator ---------------------------------------------------------------------------

def _sim(faults, seed=5):
    evs: list[dict] = []
    w = World(SimConfig(robots=(1, 2, 3), duration=4.0, seed=seed, faults=tuple(faults)),
              on_event=evs.append)
    txs = []
    record = w.air.on_transmission

    def both(tx):
        txs.append(tx)
        record(tx)
    w.air.on_transmission = both
    w.run()
    return w, evs, [(tx.data, tx.t0, tx.bt) for tx in txs if tx.radio.robot < 0]


def test_sim_foreign_fault_puts_exactly_its_bytes_on_air_at_its_tick():
    exact = parse_fault(f"foreign@1.5:x{HEX}")
    rand = parse_fault("foreign@2.0000000625:25")
    w, evs, phantom = _sim([exact, rand])
    data = bytes.fromhex(HEX)
    assert phantom == [(data, 24_000_000, FOREIGN_BYTE_TICKS),
                       (foreign_bytes(rand, 5), 32_000_001, FOREIGN_BYTE_TICKS)]
    assert w.air.sent[-1] == 2 and w.fault_count == {"foreign": 2}
    inter = [(e["start"], e["bytes"]) for e in evs if e["ev"] == "interference"]
    assert inter == [(24_000_000, len(data)), (32_000_001, 25)]
    assert [e["spec"] for e in evs if e["ev"] == "fault"] == [exact.spec(), rand.spec()]


def test_sim_foreign_fault_keeps_same_seed_same_trace():
    faults = [parse_fault("foreign@1.2:30"), parse_fault(f"foreign@2.7:x{HEX}")]
    _, a, pa = _sim(faults, seed=9)
    _, b, pb = _sim(faults, seed=9)
    _, c, pc = _sim(faults, seed=10)
    assert a == b and pa == pb
    assert pa[0][0] != pc[0][0] and pa[1] == pc[1]     # random bytes follow the seed only
